//! Stage 2, *intersect*: the closest hit of every ray in the queue.

use super::World;
use super::queue::{MISS, PathQueue};
use crate::geometry::LaneHits;
use crate::real::V3;
use wide::f32x8;

/// Fill `queue.t` and `queue.hit` with each ray's closest hit
/// (smallest `(t, triangle)`), testing 8 triangles at a time.
pub fn intersect(queue: &mut PathQueue, world: &World) {
    let n = queue.len();
    let t_min = f32x8::splat(world.epsilon);
    let [ox, oy, oz] = &queue.o;
    let [dx, dy, dz] = &queue.d;
    let rays = ox[..n]
        .iter()
        .zip(&oy[..n])
        .zip(&oz[..n])
        .zip(dx[..n].iter().zip(&dy[..n]).zip(&dz[..n]));
    let hits = queue.t[..n].iter_mut().zip(&mut queue.hit[..n]);
    for ((((ox, oy), oz), ((dx, dy), dz)), (t, hit)) in rays.zip(hits) {
        let o = V3::new(f32x8::splat(*ox), f32x8::splat(*oy), f32x8::splat(*oz));
        let d = V3::new(f32x8::splat(*dx), f32x8::splat(*dy), f32x8::splat(*dz));
        let mut best = LaneHits::new(f32::INFINITY);
        for pack in &world.packs {
            pack.intersect(&o, &d, t_min, &mut best);
        }
        match best.closest() {
            Some(h) => (*t, *hit) = (h.t, h.triangle),
            None => *hit = MISS,
        }
    }
}
