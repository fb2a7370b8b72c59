//! Stage *intersect*: the closest hit of every ray in the queue.

use super::queue::PathQueue;
use crate::accel::bvh::Bvh;

/// Working memory of the intersect stage. None is needed today (the
/// hierarchy reads the queue's columns and writes its hits in place); the
/// type stays so the engine's per-thread scratch keeps its shape.
#[derive(Debug, Default)]
pub struct RayBatch {
    _none: (),
}

/// Fill `queue.t` and `queue.hit` with each ray's closest hit
/// (smallest `(t, triangle)`), through the hierarchy: 8 or 16 triangles at
/// a time, a batch of rays interleaved on scenes larger than the caches.
pub fn intersect<P>(queue: &mut PathQueue<P>, bvh: &Bvh, epsilon: f32, _batch: &mut RayBatch) {
    let n = queue.len();
    let o = queue.o.each_ref().map(|c| &c[..n]);
    let d = queue.d.each_ref().map(|c| &c[..n]);
    let (t, hit) = (&mut queue.t[..n], &mut queue.hit[..n]);
    bvh.closest_hits_columns(o, d, (epsilon, f32::INFINITY), t, hit);
}
