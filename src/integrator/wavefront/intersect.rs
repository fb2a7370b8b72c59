//! Stage *intersect*: the closest hit of every ray in the queue.

use super::Ctx;
use super::queue::PathQueue;
use crate::integrator::sampler::Sampler;

/// Fill `queue.t` and `queue.hit` with each ray's closest hit
/// (smallest `(t, triangle)`), through the hierarchy: 8 or 16 triangles at
/// a time, a batch of rays interleaved on scenes larger than the caches.
/// The hierarchy reads the queue's columns and writes its hits in place.
pub fn intersect<S: Sampler>(queue: &mut PathQueue<S::Path>, ctx: &Ctx<S>) {
    let n = queue.len();
    let o = queue.o.each_ref().map(|c| &c[..n]);
    let d = queue.d.each_ref().map(|c| &c[..n]);
    let (t, hit) = (&mut queue.t[..n], &mut queue.hit[..n]);
    let range = (ctx.tables.epsilon, f32::INFINITY);
    ctx.bvh.closest_hits_columns(o, d, range, t, hit);
}
