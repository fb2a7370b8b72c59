//! The closest hit of a ray, as every kind's kernel keeps it: one ray's
//! ([`Hit`]) and, while packs are tested, one per lane ([`PackHits`]).
//!
//! The closest hit is the smallest `(t, primitive index)` pair, in that
//! order, whatever the primitives' kinds (see [`crate::accel::triangle`]).

use crate::accel::simd::Lanes;
use wide::f32x8;

/// The primitive index that stands for "nothing hit" in
/// [`PackHits::closest_below`] and
/// [`Bvh::closest_hits_into`](crate::accel::bvh::Bvh::closest_hits_into).
pub const NO_PRIM: u32 = u32::MAX;

/// An any-hit filter: which candidate hits of one ray a query keeps.
///
/// A filtered query ([`Bvh::closest_hit_filtered`](crate::accel::bvh::Bvh::closest_hit_filtered),
/// [`Bvh::occluded_filtered`](crate::accel::bvh::Bvh::occluded_filtered)
/// and their batches) asks it about each candidate hit on a primitive
/// that [`may_pass`](Self::may_pass) before the candidate shrinks the
/// ray's interval; a candidate that [`passes`](Self::passes) is as if it
/// were not there, and the walk goes on. The hierarchy knows nothing of
/// what the primitives are made of: the filter (the integrator's, for
/// alpha-tested materials) does. Its answers must depend only on the ray
/// and the candidate, never on the order in which candidates are met, so
/// that the answer is the smallest `(t, index)` among the hits that do
/// not pass, whatever the walk.
pub trait HitFilter {
    /// Whether a hit on primitive `prim` (a global index) may let the ray
    /// through: a cheap flag; hits on other primitives are kept untested.
    fn may_pass(&self, prim: u32) -> bool;
    /// Whether the ray goes through primitive `prim`, hit at `t`.
    fn passes(&self, prim: u32, t: f32) -> bool;
}

impl<F: HitFilter + ?Sized> HitFilter for &F {
    #[inline(always)]
    fn may_pass(&self, prim: u32) -> bool {
        (**self).may_pass(prim)
    }
    #[inline(always)]
    fn passes(&self, prim: u32, t: f32) -> bool {
        (**self).passes(prim, t)
    }
}

/// The filter that keeps every hit (a filtered query with it answers as
/// the plain query does).
#[derive(Clone, Copy, Debug, Default)]
pub struct KeepAll;

impl HitFilter for KeepAll {
    #[inline(always)]
    fn may_pass(&self, _prim: u32) -> bool {
        false
    }
    #[inline(always)]
    fn passes(&self, _prim: u32, _t: f32) -> bool {
        false
    }
}

/// The closest hit of one ray: primitive index and distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index of the primitive hit: the kinds one after the other, in the
    /// order of [`Kinds`](crate::accel::Kinds) — triangles first, then
    /// spheres. Triangle `i` is `i`; in a hierarchy built with spheres
    /// ([`Bvh::build_shapes`](crate::accel::bvh::Bvh::build_shapes)),
    /// sphere `j` is `T + j` with `T` the number of triangles. (The name is
    /// from when triangles were the only primitive.)
    pub triangle: u32,
    /// Distance along the (unit) ray direction.
    pub t: f32,
}

/// The running closest hit of one ray, per lane, while packs are tested.
#[derive(Clone, Copy, Debug)]
pub struct PackHits<R: Lanes> {
    /// Best distance per lane (the ray's `t_max` where nothing was hit).
    pub t: R,
    /// Primitive index per lane (`i32::MAX` where nothing was hit).
    pub index: R::Index,
}

impl<R: Lanes> PackHits<R> {
    /// Keep, lane by lane, the hit `(t, index)` where `hit` is set and it
    /// is smaller than the best so far — by `t`, then by index, unless
    /// `IN_INDEX_ORDER` (the caller tests primitives in increasing index
    /// order, so an equal `t` never wins). Every pack kernel ends here.
    #[inline(always)]
    pub fn keep<const IN_INDEX_ORDER: bool>(&mut self, hit: R::Mask, t: R, index: R::Index) {
        let closer = if IN_INDEX_ORDER {
            hit & t.lt(self.t)
        } else {
            let idx_lt = R::index_lt(index, self.index);
            hit & (t.lt(self.t) | (t.eq(self.t) & idx_lt))
        };
        self.t = R::select(closer, t, self.t);
        self.index = R::index_select(closer, index, self.index);
    }
}

/// [`PackHits`] for 8 lanes.
pub type LaneHits = PackHits<f32x8>;

impl<R: Lanes> PackHits<R> {
    /// No hit yet: every lane at `t_max`.
    #[inline(always)]
    pub fn new(t_max: f32) -> Self {
        Self {
            t: R::splat(t_max),
            index: R::index_splat(i32::MAX),
        }
    }

    /// The smallest `(t, index)` over the lanes, if any lane hit.
    ///
    /// Branch-free: the smallest `t`, then the smallest index among the
    /// lanes holding it. Lanes that hit nothing hold `t_max` (which no hit
    /// reaches) and index `i32::MAX`.
    #[inline(always)]
    pub fn closest(&self) -> Option<Hit> {
        let t = self.t.min_lane();
        let index = self.t.min_index_at(t, self.index);
        (index != i32::MAX).then_some(Hit {
            triangle: index as u32,
            t,
        })
    }

    /// [`PackHits::closest`] below `t_max` as a plain pair, without a
    /// branch: `(t, index)`, or `(t, NO_PRIM)` where no lane holds a hit
    /// closer than `t_max` (a lane can hold one at exactly `t_max`: an
    /// equal `t` with a lower index wins in [`PackHits::keep`]).
    #[inline(always)]
    pub fn closest_below(&self, t_max: f32) -> (f32, u32) {
        let t = self.t.min_lane();
        let index = self.t.min_index_at(t, self.index);
        (t, if t < t_max { index as u32 } else { NO_PRIM })
    }
}
