//! Stage 3, *shade/emit*: add what each hit surface emits, retire the paths
//! that escaped or reached the last depth, and bin the rest by material.

use super::World;
use super::queue::{MISS, PathQueue};
use crate::film::{PixelSum, accumulate};
use crate::real::V3;

/// The paths that go on to the bounce stage, binned by material model. Each
/// model has its own bounce pass; today there is one, ideal diffuse.
#[derive(Clone, Debug, Default)]
pub struct Bins {
    /// Queue rows (ascending) of paths that hit an ideal diffuse surface.
    pub diffuse: Vec<u32>,
}

/// For every path: a miss retires it (its radiance goes to its pixel); a hit
/// seen from the front adds `throughput × emitted radiance`. When `last` is
/// set (the next ray would exceed the maximum depth) every path retires;
/// otherwise the survivors are binned for the bounce stage.
/// Returns the number of samples refused as invalid.
pub fn shade(
    queue: &mut PathQueue,
    world: &World,
    last: bool,
    tile_start: u32,
    sums: &mut [PixelSum],
    bins: &mut Bins,
) -> u64 {
    bins.diffuse.clear();
    let mut invalid = 0;
    for i in 0..queue.len() {
        let tri = queue.hit[i];
        if tri != MISS {
            let n = world.normals[tri as usize];
            let d = V3::new(queue.d[0][i], queue.d[1][i], queue.d[2][i]);
            if d.dot(V3::new(n[0], n[1], n[2])) < 0.0 {
                let e = world.emission[world.material_of[tri as usize] as usize];
                for (c, e) in e.iter().enumerate() {
                    queue.radiance[c][i] += queue.beta[c][i] * e;
                }
            }
            if !last {
                bins.diffuse.push(i as u32);
                continue;
            }
        }
        // Retire: the path's radiance is one sample of its pixel.
        let pixel = (queue.pixel[i] - tile_start) as usize;
        if !accumulate(&mut sums[pixel], queue.radiance_of(i)) {
            invalid += 1;
        }
    }
    invalid
}
