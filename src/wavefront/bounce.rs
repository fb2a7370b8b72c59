//! Stage 4, *bounce*: sample each surviving path's next direction, update
//! its throughput, and compact the live paths to the front of the queue.

use super::World;
use super::queue::{PathQueue, store8};
use crate::geometry::hit_point;
use crate::real::{V3, Vec3x8};
use crate::sampling::uniform_hemisphere;
use std::f32::consts::PI;
use wide::f32x8;

/// Bounce the paths in rows `rows` (ascending) of `queue` off ideal diffuse
/// surfaces, compacting them to the front of the queue, which then holds
/// just them. Eight paths at a time:
///
/// - the normal is turned to face the incoming ray (diffuse reflection is
///   two-sided);
/// - the new origin is the hit point;
/// - the new direction is uniform on the hemisphere (two numbers from the
///   path's stream);
/// - the throughput is multiplied by `(ρ/π) · cos θ / (1/2π)`.
///
/// Group `g` reads rows `rows[8g..8g+8]` and writes rows `8g..8g+8`. The
/// rows are ascending, so `rows[k] >= k`: no row is overwritten before it
/// is read.
pub fn diffuse(queue: &mut PathQueue, rows: &[u32], world: &World) {
    for (g, group) in rows.chunks(8).enumerate() {
        let i = g * 8;
        let lanes = group.len();
        // Lanes past the last path repeat the first one; their results land
        // in rows past the end of the queue and are never read.
        let src: [usize; 8] =
            std::array::from_fn(|l| group[if l < lanes { l } else { 0 }] as usize);
        let gather = |col: &[f32]| gather8(col, &src);
        let gather3 =
            |cols: &[Vec<f32>; 3]| V3::new(gather(&cols[0]), gather(&cols[1]), gather(&cols[2]));

        let tris: [usize; 8] = std::array::from_fn(|l| queue.hit[src[l]] as usize);
        let normal: Vec3x8 = V3::new(
            gather8(&world.normals[0], &tris),
            gather8(&world.normals[1], &tris),
            gather8(&world.normals[2], &tris),
        );
        let brdf = [0, 1, 2].map(|c| gather8(&world.brdf[c], &tris));
        let (mut x1, mut x2) = ([0.0f32; 8], [0.0f32; 8]);
        for l in 0..lanes {
            let rng = &mut queue.rng[src[l]];
            x1[l] = rng.next_f32();
            x2[l] = rng.next_f32();
        }
        let (x1, x2) = (f32x8::from(x1), f32x8::from(x2));
        let o = gather3(&queue.o);
        let d = gather3(&queue.d);
        let t = gather(&queue.t);
        let beta = [0, 1, 2].map(|c| gather(&queue.beta[c]));

        let front = d.dot(normal).simd_lt(f32x8::ZERO);
        let n = V3::select(front, normal, V3::new(-normal.x, -normal.y, -normal.z));
        let origin = hit_point(o, d, t);
        let dir = uniform_hemisphere(n, x1, x2);
        let cos_theta = x1; // by construction (see the reference tracer)
        let probability = f32x8::splat(1.0 / (2.0 * PI));

        // Compact: the group's paths move to rows i..i + lanes.
        for l in 0..lanes {
            queue.pixel[i + l] = queue.pixel[src[l]];
            queue.rng[i + l] = queue.rng[src[l]].clone();
            for col in queue.radiance.iter_mut() {
                col[i + l] = col[src[l]];
            }
        }
        for (col, v) in queue.o.iter_mut().zip([origin.x, origin.y, origin.z]) {
            store8(col, i, v);
        }
        for (col, v) in queue.d.iter_mut().zip([dir.x, dir.y, dir.z]) {
            store8(col, i, v);
        }
        for ((col, beta), brdf) in queue.beta.iter_mut().zip(beta).zip(brdf) {
            store8(col, i, beta * brdf * cos_theta / probability);
        }
    }
    queue.set_len(rows.len());
}

/// `[col[rows[0]], ..., col[rows[7]]]` as eight lanes.
#[inline(always)]
fn gather8(col: &[f32], rows: &[usize; 8]) -> f32x8 {
    let r = rows;
    f32x8::from([
        col[r[0]], col[r[1]], col[r[2]], col[r[3]], col[r[4]], col[r[5]], col[r[6]], col[r[7]],
    ])
}
