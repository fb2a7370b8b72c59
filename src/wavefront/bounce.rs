//! Stage 4, *bounce*: sample each surviving path's next direction, update
//! its throughput, and compact it into the next queue.

use super::World;
use super::queue::PathQueue;
use crate::geometry::hit_point;
use crate::real::{V3, Vec3x8};
use crate::sampling::uniform_hemisphere;
use std::f32::consts::PI;
use wide::f32x8;

/// Bounce the paths in rows `rows` of `cur` off ideal diffuse surfaces, 8 at
/// a time, appending the new rays to `next`.
///
/// For each path: the normal is turned to face the incoming ray (diffuse
/// reflection is two-sided); the new origin is the hit point; the new
/// direction is uniform on the hemisphere (two numbers from the path's
/// stream); and the throughput is multiplied by `(ρ/π) · cos θ / (1/2π)`.
pub fn diffuse(cur: &mut PathQueue, rows: &[u32], world: &World, next: &mut PathQueue) {
    for group in rows.chunks(8) {
        // Gather the group's lanes (a short group is padded with lane 0).
        let lane = |l: usize| group[l.min(group.len() - 1)] as usize;
        let gather = |col: &[f32]| f32x8::from(std::array::from_fn::<f32, 8, _>(|l| col[lane(l)]));
        let gather3 =
            |cols: &[Vec<f32>; 3]| V3::new(gather(&cols[0]), gather(&cols[1]), gather(&cols[2]));
        let o = gather3(&cur.o);
        let d = gather3(&cur.d);
        let t = gather(&cur.t);
        let tri = |l: usize| cur.hit[lane(l)] as usize;
        let normal: Vec3x8 = V3::new(
            f32x8::from(std::array::from_fn::<f32, 8, _>(|l| {
                world.normals[tri(l)][0]
            })),
            f32x8::from(std::array::from_fn::<f32, 8, _>(|l| {
                world.normals[tri(l)][1]
            })),
            f32x8::from(std::array::from_fn::<f32, 8, _>(|l| {
                world.normals[tri(l)][2]
            })),
        );
        let mut x1 = [0.0f32; 8];
        let mut x2 = [0.0f32; 8];
        for (l, &row) in group.iter().enumerate() {
            let rng = &mut cur.rng[row as usize];
            x1[l] = rng.next_f32();
            x2[l] = rng.next_f32();
        }

        let front = d.dot(normal).simd_lt(f32x8::ZERO);
        let n = V3::select(front, normal, V3::new(-normal.x, -normal.y, -normal.z));
        let origin = hit_point(o, d, t);
        let x1 = f32x8::from(x1);
        let dir = uniform_hemisphere(n, x1, f32x8::from(x2));
        let cos_theta = x1; // by construction (see the reference tracer)
        let probability = f32x8::splat(1.0 / (2.0 * PI));

        let origin = [
            origin.x.to_array(),
            origin.y.to_array(),
            origin.z.to_array(),
        ];
        let dir = [dir.x.to_array(), dir.y.to_array(), dir.z.to_array()];
        let mut beta = [[0.0f32; 8]; 3];
        for (c, b) in beta.iter_mut().enumerate() {
            let brdf = f32x8::from(std::array::from_fn::<f32, 8, _>(|l| {
                world.brdf[world.material_of[tri(l)] as usize][c]
            }));
            *b = (gather(&cur.beta[c]) * brdf * cos_theta / probability).to_array();
        }

        for (l, &row) in group.iter().enumerate() {
            let row = row as usize;
            next.pixel.push(cur.pixel[row]);
            next.rng.push(cur.rng[row].clone());
            for c in 0..3 {
                next.o[c].push(origin[c][l]);
                next.d[c].push(dir[c][l]);
                next.beta[c].push(beta[c][l]);
                next.radiance[c].push(cur.radiance[c][row]);
            }
        }
    }
}
