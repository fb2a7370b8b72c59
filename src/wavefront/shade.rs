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
    let n = queue.len();
    // Columns cut to the live rows: the loop below needs no bounds checks.
    let hit = &queue.hit[..n];
    let pixel = &queue.pixel[..n];
    let [dx, dy, dz] = queue.d.each_ref().map(|c| &c[..n]);
    let beta = queue.beta.each_ref().map(|c| &c[..n]);
    let [lr, lg, lb] = queue.radiance.each_mut().map(|c| &mut c[..n]);
    for i in 0..n {
        let tri = hit[i];
        if tri != MISS {
            let t = tri as usize;
            let normal = V3::new(
                world.normals[0][t],
                world.normals[1][t],
                world.normals[2][t],
            );
            let d = V3::new(dx[i], dy[i], dz[i]);
            if d.dot(normal) < 0.0 {
                let e = world.emission[world.material_of[tri as usize] as usize];
                lr[i] += beta[0][i] * e[0];
                lg[i] += beta[1][i] * e[1];
                lb[i] += beta[2][i] * e[2];
            }
            if !last {
                bins.diffuse.push(i as u32);
                continue;
            }
        }
        // Retire: the path's radiance is one sample of its pixel.
        let sum = &mut sums[(pixel[i] - tile_start) as usize];
        if !accumulate(sum, glam::Vec3::new(lr[i], lg[i], lb[i])) {
            invalid += 1;
        }
    }
    invalid
}
