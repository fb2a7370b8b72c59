//! Stage 3, *shade/emit*: add what each hit surface emits, and retire the
//! paths that escaped or reached the last depth.

use super::World;
use super::queue::{MISS, PathQueue};
use crate::film::{PixelSum, accumulate};
use crate::math::V3;

/// For every path: a hit seen from the front adds `throughput × emitted
/// radiance`. A miss retires the path — its radiance is one sample of its
/// pixel — and so does every hit when `last` is set (the next ray would
/// exceed the maximum depth). Retired rows are marked [`MISS`] for the
/// bounce stage to drop. Returns the number of samples refused as invalid.
pub fn shade(
    queue: &mut PathQueue,
    world: &World,
    last: bool,
    tile_start: u32,
    sums: &mut [PixelSum],
) -> u64 {
    let mut invalid = 0;
    let n = queue.len();
    // Columns cut to the live rows: the loop below needs no bounds checks.
    let hit = &mut queue.hit[..n];
    let pixel = &queue.pixel[..n];
    let [dx, dy, dz] = queue.d.each_ref().map(|c| &c[..n]);
    let beta = queue.beta.each_ref().map(|c| &c[..n]);
    let [lr, lg, lb] = queue.radiance.each_mut().map(|c| &mut c[..n]);
    for i in 0..n {
        if hit[i] != MISS {
            let t = hit[i] as usize;
            let e = world.emission[world.material_of[t] as usize];
            let normal = V3::new(
                world.normals[0][t],
                world.normals[1][t],
                world.normals[2][t],
            );
            let d = V3::new(dx[i], dy[i], dz[i]);
            // Most surfaces emit nothing: skip the side test for them.
            if e != [0.0; 3] && d.dot(normal) < 0.0 {
                lr[i] += beta[0][i] * e[0];
                lg[i] += beta[1][i] * e[1];
                lb[i] += beta[2][i] * e[2];
            }
            if !last {
                continue;
            }
            hit[i] = MISS;
        }
        // Retire: the path's radiance is one sample of its pixel.
        let sum = &mut sums[(pixel[i] - tile_start) as usize];
        if !accumulate(sum, glam::Vec3::new(lr[i], lg[i], lb[i])) {
            invalid += 1;
        }
    }
    invalid
}
