//! Stage *intersect*: the closest hit of every ray in the queue.

use super::Ctx;
use super::queue::PathQueue;
use crate::integrator::sampler::Sampler;

/// Fill `queue.t` and `queue.hit` with each ray's closest hit at `t > 0`
/// (smallest `(t, triangle)`; rays leave surfaces from points moved off
/// them, [`crate::integrator::offset`]), through the hierarchy: 8 or 16 triangles at
/// a time, a batch of rays interleaved on scenes larger than the caches.
/// The hierarchy reads the queue's columns and writes its hits in place.
/// In a scene with cut-outs, the walk puts each candidate hit on a surface
/// that may let its ray through to the ray's any-hit filter
/// ([`Tables::cutouts`](crate::integrator::tables::Tables::cutouts)) and
/// goes on past those that pass, as the reference tracer does: the
/// closest hit on a surface that is there.
pub fn intersect<S: Sampler>(queue: &mut PathQueue<S::Path>, ctx: &Ctx<S>) {
    let n = queue.len();
    let o = queue.o.each_ref().map(|c| &c[..n]);
    let d = queue.d.each_ref().map(|c| &c[..n]);
    let (t, hit) = (&mut queue.t[..n], &mut queue.hit[..n]);
    if ctx.tables.has_cutouts() {
        let tables = ctx.tables;
        ctx.bvh
            .closest_hits_columns_filtered((o, d), (0.0, f32::INFINITY), (t, hit), |i| {
                tables.cutouts_of((o, d), i)
            });
        return;
    }
    ctx.bvh
        .closest_hits_columns(o, d, (0.0, f32::INFINITY), t, hit);
}
