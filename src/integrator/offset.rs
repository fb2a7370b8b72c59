//! Where a ray leaves a surface: the hit point moved off the surface by a
//! bound on its rounding error, a bound local to the hit.
//!
//! A hit point `p = o + t·d` is only as exact as the rounding of `o`, `d`,
//! `t` and the primitive allows: Möller–Trumbore's `t = (c·n)/(d·n)`, with
//! `c = v0 - o`, is off by a few ulps of `|c|` along the normal, and a
//! sphere's roots by a few ulps of its center and radius. So the error of
//! `p` across the surface is at most a few `ε · s`, with `ε` f32's epsilon
//! and `s` the largest coordinate of the ray's origin, of `p`, and of the
//! primitive itself ([`Scene::primitive_scale`](crate::scene::Scene::primitive_scale):
//! a large triangle hit near the origin is as inexact as its far
//! vertices). A ray leaving `p` starts [`error_bound`] away from it along
//! the geometric normal, on the side it leaves to ([`spawn`]), and counts
//! every hit at `t > 0`: it cannot find the surface it left, and nothing
//! anywhere else in the scene changes where it starts — pbrt-v4's
//! `OffsetRayOrigin`, and Embree's tutorials' `32 ε max(|P|, t)` offset,
//! with the primitive's own scale as a third term.
//!
//! A shadow ray ends short of its point on the emitter by the same bound
//! taken at that point ([`crate::integrator::nee::connect_shaded`]).
//!
//! Written once over [`Real`], so one lane and eight compute the same bits.

use crate::math::{Real, V3};

/// The bound, in units of `ε · s` (see the module documentation). In
/// `tests/offset.rs`'s fuzzing (triangles, slivers and spheres from 10⁻³
/// to 10⁶, hit from near and far) rays find the surface they leave at 2
/// and never at 4: 64 leaves a factor 16, and is still only 2⁻¹⁷ of the
/// scale (no light leaks through a corner).
pub const OFFSET_EPSILONS: f32 = 64.0;

/// A bound on the distance between the computed hit point `p` of a ray
/// from `o` and the surface of a primitive of scale `scale`.
#[inline(always)]
pub fn error_bound<R: Real>(o: V3<R>, p: V3<R>, scale: R) -> R {
    let s = o.max_abs().max(p.max_abs()).max(scale);
    s * R::splat(OFFSET_EPSILONS * f32::EPSILON)
}

/// The origin of a ray that leaves the point `p` (within `err` of the
/// surface, [`error_bound`]) of geometric unit normal `n` in the direction
/// `w`: `p` moved by `err` along `n`, to the side `w` points to.
#[inline(always)]
pub fn spawn<R: Real>(p: V3<R>, n: V3<R>, w: V3<R>, err: R) -> V3<R> {
    let off = R::select(n.dot(w).lt(R::splat(0.0)), -err, err);
    n.mul_add(off, p)
}
