//! Stage 2, *intersect*: the closest hit of every ray in the queue.

use super::World;
use super::queue::{MISS, PathQueue};
use crate::geometry::{LaneHits, Triangle8};
use crate::real::V3;
use wide::f32x8;

/// Fill `queue.t` and `queue.hit` with each ray's closest hit
/// (smallest `(t, triangle)`), testing 8 triangles at a time.
pub fn intersect(queue: &mut PathQueue, world: &World) {
    let n = queue.len();
    queue.t.resize(n, 0.0);
    queue.hit.resize(n, MISS);
    let t_min = f32x8::splat(world.epsilon);
    let [ox, oy, oz] = &queue.o;
    let [dx, dy, dz] = &queue.d;
    for i in 0..n {
        let o = V3::new(
            f32x8::splat(ox[i]),
            f32x8::splat(oy[i]),
            f32x8::splat(oz[i]),
        );
        let d = V3::new(
            f32x8::splat(dx[i]),
            f32x8::splat(dy[i]),
            f32x8::splat(dz[i]),
        );
        let mut best = LaneHits::new(f32::INFINITY);
        for pack in &world.packs {
            Triangle8::intersect(pack, &o, &d, t_min, &mut best);
        }
        match best.closest() {
            Some(h) => {
                queue.t[i] = h.t;
                queue.hit[i] = h.triangle;
            }
            None => queue.hit[i] = MISS,
        }
    }
}
