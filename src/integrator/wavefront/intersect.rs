//! Stage *intersect*: the closest hit of every ray in the queue.

use super::Ctx;
use super::queue::{NO_HIT, PathQueue};
use crate::integrator::sampler::Sampler;
use crate::math::V3;

/// Fill `queue.t` and `queue.hit` with each ray's closest hit at `t > 0`
/// (smallest `(t, triangle)`; rays leave surfaces from points moved off
/// them, [`crate::integrator::offset`]), through the hierarchy: 8 or 16 triangles at
/// a time, a batch of rays interleaved on scenes larger than the caches.
/// The hierarchy reads the queue's columns and writes its hits in place.
/// In a scene with cut-outs, a hit that lets its ray through
/// ([`Tables::passes`](crate::integrator::tables::Tables::passes)) is
/// replaced by the closest hit beyond it, one ray at a time, as the
/// reference tracer does.
pub fn intersect<S: Sampler>(queue: &mut PathQueue<S::Path>, ctx: &Ctx<S>) {
    let n = queue.len();
    let o = queue.o.each_ref().map(|c| &c[..n]);
    let d = queue.d.each_ref().map(|c| &c[..n]);
    let (t, hit) = (&mut queue.t[..n], &mut queue.hit[..n]);
    ctx.bvh
        .closest_hits_columns(o, d, (0.0, f32::INFINITY), t, hit);
    if ctx.tables.has_cutouts() {
        for i in 0..n {
            let ray = (
                V3::new(o[0][i], o[1][i], o[2][i]),
                V3::new(d[0][i], d[1][i], d[2][i]),
            );
            while hit[i] != NO_HIT && ctx.tables.passes(hit[i] as usize, ray, t[i]) {
                let next = (ctx.bvh).closest_hit(ray.0.into(), ray.1.into(), t[i], f32::INFINITY);
                (hit[i], t[i]) = next.map_or((NO_HIT, f32::INFINITY), |h| (h.triangle, h.t));
            }
        }
    }
}
