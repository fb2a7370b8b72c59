//! Stage 4, *bounce*: compact the surviving paths, sample each one's next
//! direction and update its throughput.

use super::World;
use super::queue::{PathQueue, load8, store8};
use crate::geometry::hit_point;
use crate::real::{V3, Vec3x8};
use crate::sampling::uniform_hemisphere;
use std::f32::consts::PI;
use wide::f32x8;

/// Bounce the paths in rows `rows` (ascending) of `queue` off ideal diffuse
/// surfaces. They are first compacted to the front of the queue, which then
/// holds just them; then, 8 rows at a time:
///
/// - the normal is turned to face the incoming ray (diffuse reflection is
///   two-sided);
/// - the new origin is the hit point;
/// - the new direction is uniform on the hemisphere (two numbers from the
///   path's stream);
/// - the throughput is multiplied by `(ρ/π) · cos θ / (1/2π)`.
pub fn diffuse(queue: &mut PathQueue, rows: &[u32], world: &World) {
    for (to, &from) in rows.iter().enumerate() {
        if to != from as usize {
            queue.move_row(from as usize, to);
        }
    }
    let live = rows.len();
    queue.set_len(live);

    for i in (0..live).step_by(8) {
        let lanes = (live - i).min(8);
        // Lanes past the last path compute garbage that is never read; they
        // borrow the first lane's triangle so every lookup stays in bounds.
        let tri = |l: usize| queue.hit[i + if l < lanes { l } else { 0 }] as usize;
        let lane = |f: &dyn Fn(usize) -> f32| f32x8::from(std::array::from_fn::<f32, 8, _>(f));
        let normal: Vec3x8 = V3::new(
            lane(&|l| world.normals[tri(l)][0]),
            lane(&|l| world.normals[tri(l)][1]),
            lane(&|l| world.normals[tri(l)][2]),
        );
        let brdf: [f32x8; 3] =
            std::array::from_fn(|c| lane(&|l| world.brdf[world.material_of[tri(l)] as usize][c]));
        let (mut x1, mut x2) = ([0.0f32; 8], [0.0f32; 8]);
        for l in 0..lanes {
            let rng = &mut queue.rng[i + l];
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
