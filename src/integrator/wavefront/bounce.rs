//! Stage 4, *bounce*: compact the live paths into bins by material, then
//! sample each one's next direction and update its throughput, eight paths
//! at a time.

use super::World;
use super::queue::{MISS, PathQueue, load8, store8};
use crate::accel::triangle::hit_point;
use crate::integrator::sampler::uniform_hemisphere;
use crate::math::{V3, Vec3x8};
use std::f32::consts::PI;
use std::ops::Range;
use wide::f32x8;

/// The live paths, grouped by material model into row ranges of the queue.
/// Each model has its own pass; today there is one, ideal diffuse.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bins {
    /// Rows of the paths that hit an ideal diffuse surface.
    pub diffuse: Range<usize>,
}

/// Compact the queue and bounce every live path off its surface.
pub fn bounce(queue: &mut PathQueue, world: &World) {
    let bins = bin(queue);
    diffuse(queue, bins.diffuse, world);
}

/// Drop the retired rows (marked [`MISS`]) and group the live ones by
/// material model. Each hole is filled with the last live row, so only
/// retired rows cost a move; the order of paths does not matter (each has
/// its own random stream, and the film's sums are exact).
pub fn bin(queue: &mut PathQueue) -> Bins {
    let (mut i, mut end) = (0, queue.len());
    loop {
        while i < end && queue.hit[i] != MISS {
            i += 1;
        }
        while i < end && queue.hit[end - 1] == MISS {
            end -= 1;
        }
        if i >= end {
            break;
        }
        queue.move_row(end - 1, i);
        end -= 1;
        i += 1;
    }
    queue.set_len(end);
    // With a second material model, a partition of 0..end by model goes here.
    Bins { diffuse: 0..end }
}

/// Bounce the paths in rows `rows` off ideal diffuse surfaces, eight at a
/// time:
///
/// - the normal is turned to face the incoming ray (diffuse reflection is
///   two-sided);
/// - the new origin is the hit point;
/// - the new direction is uniform on the hemisphere (two numbers from the
///   path's stream);
/// - the throughput is multiplied by `(ρ/π) · cos θ / (1/2π)`.
pub fn diffuse(queue: &mut PathQueue, rows: Range<usize>, world: &World) {
    for i in rows.clone().step_by(8) {
        let lanes = (rows.end - i).min(8);
        // Lanes past the last path compute garbage that is stored past the
        // live rows (the columns are padded to a multiple of 8) and never
        // read; they borrow the first lane's triangle for the lookups.
        let tri = |l: usize| queue.hit[i + if l < lanes { l } else { 0 }] as usize;
        let tris = [
            tri(0),
            tri(1),
            tri(2),
            tri(3),
            tri(4),
            tri(5),
            tri(6),
            tri(7),
        ];
        let normal: Vec3x8 = V3::new(
            gather8(&world.normals[0], &tris),
            gather8(&world.normals[1], &tris),
            gather8(&world.normals[2], &tris),
        );
        let brdf = [
            gather8(&world.brdf[0], &tris),
            gather8(&world.brdf[1], &tris),
            gather8(&world.brdf[2], &tris),
        ];
        let (mut x1, mut x2) = ([0.0f32; 8], [0.0f32; 8]);
        for (l, rng) in queue.rng[i..i + lanes].iter_mut().enumerate() {
            x1[l] = rng.next_f32();
            x2[l] = rng.next_f32();
        }
        let (x1, x2) = (f32x8::from(x1), f32x8::from(x2));
        let load3 = |cols: &[Vec<f32>; 3]| {
            V3::new(load8(&cols[0], i), load8(&cols[1], i), load8(&cols[2], i))
        };
        let o = load3(&queue.o);
        let d = load3(&queue.d);
        let t = load8(&queue.t, i);

        let front = d.dot(normal).simd_lt(f32x8::ZERO);
        let n = V3::select(front, normal, V3::new(-normal.x, -normal.y, -normal.z));
        let origin = hit_point(o, d, t);
        let dir = uniform_hemisphere(n, x1, x2);
        let cos_theta = x1; // by construction (see the reference tracer)
        let probability = f32x8::splat(1.0 / (2.0 * PI));

        for (col, v) in queue.o.iter_mut().zip([origin.x, origin.y, origin.z]) {
            store8(col, i, v);
        }
        for (col, v) in queue.d.iter_mut().zip([dir.x, dir.y, dir.z]) {
            store8(col, i, v);
        }
        for (col, brdf) in queue.beta.iter_mut().zip(brdf) {
            let beta = load8(col, i) * brdf * cos_theta / probability;
            store8(col, i, beta);
        }
    }
}

/// `[col[rows[0]], ..., col[rows[7]]]` as eight lanes.
#[inline(always)]
fn gather8(col: &[f32], rows: &[usize; 8]) -> f32x8 {
    let r = rows;
    f32x8::from([
        col[r[0]], col[r[1]], col[r[2]], col[r[3]], col[r[4]], col[r[5]], col[r[6]], col[r[7]],
    ])
}
