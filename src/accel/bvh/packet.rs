//! Ray packets for a scene of one leaf: each lane a ray, each triangle
//! broadcast to every lane.
//!
//! A scene whose triangles all fit in one leaf (the Cornell box: 32
//! triangles) has no box worth testing: every ray tests every triangle
//! (measured: culling with a node costs more than the packs it skips; see
//! `small`). One ray against packs of 8 or 16 triangles then pays, per ray,
//! for broadcasting the ray to every lane and for reducing the lanes' hits
//! to one at the end. Here the lanes hold 8 or 16 *rays* instead, read
//! straight from the wavefront's columns; each triangle is broadcast, and
//! each lane keeps its own ray's closest hit — no reduction, no branch.
//!
//! Every lane does exactly what [`closest_hit_brute_force`] does for its
//! ray: [`moller_trumbore`] (the same generic source, so the same IEEE
//! operations), the triangles in index order, a hit kept only when
//! strictly closer (so on equal `t` the lower index stays). The answers
//! are the same bits as every other closest-hit query.
//!
//! [`closest_hit_brute_force`]: crate::accel::triangle::closest_hit_brute_force

use crate::accel::simd::Lanes;
use crate::accel::triangle::{PackHits, TriangleEdges, V3Tri, moller_trumbore};
use crate::math::V3;

/// Rays given as columns (`o[axis][i]`, `d[axis][i]`), `R::LANES` at a
/// time, against every triangle of `tris` (in index order): ray `i`'s
/// closest hit with `t_min < t < t_max` into `t[i]` and `prim[i]`
/// ([`NO_PRIM`](crate::accel::triangle::NO_PRIM) where none; then `t[i]`
/// is `t_max`).
#[inline(always)]
pub(crate) fn closest_hits<R: Lanes>(
    tris: &[TriangleEdges],
    (o, d): ([&[f32]; 3], [&[f32]; 3]),
    (t_min, t_max): (f32, f32),
    t: &mut [f32],
    prim: &mut [u32],
) {
    let n = t.len();
    let t_min = R::splat(t_min);
    for start in (0..n).step_by(R::LANES) {
        let end = (start + R::LANES).min(n);
        let lanes = |c: &[f32]| R::from_slice(&c[start..end], 0.0);
        let ray_o = V3::new(lanes(o[0]), lanes(o[1]), lanes(o[2]));
        let ray_d = V3::new(lanes(d[0]), lanes(d[1]), lanes(d[2]));
        // Index -1 is `NO_PRIM` as a u32. The lanes of a short last packet
        // hold the zero ray, which hits nothing and is not written.
        let mut best = PackHits {
            t: R::splat(t_max),
            index: R::index_splat(-1),
        };
        for (k, tri) in tris.iter().enumerate() {
            let tri = V3Tri {
                v0: V3::splat(tri.v0),
                e1: V3::splat(tri.e1),
                e2: V3::splat(tri.e2),
                n: V3::splat(tri.n),
            };
            let (inside, t_hit) = moller_trumbore(ray_o, ray_d, &tri, t_min);
            best.keep::<true>(inside, t_hit, R::index_splat(k as i32));
        }
        best.t.write_to(&mut t[start..end]);
        R::index_write_to(best.index, &mut prim[start..end]);
    }
}
