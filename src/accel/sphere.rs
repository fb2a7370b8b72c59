//! Ray/sphere intersection, written once for any [`Real`], and 8-sphere
//! packs ([`Sphere8`]) tested against one ray in SIMD.
//!
//! The formulation is the numerically robust one of Haines, Günther and
//! Akenine-Möller, "Precision Improvements for Ray/Sphere Intersection"
//! (Ray Tracing Gems, chapter 7). For the ray `o + t·d` and the sphere of
//! center `c` and radius `r`, with `f = o - c`, `a = d·d`, `b = -(f·d)`:
//!
//! - the discriminant is taken from the distance of the center to the
//!   ray's line, `Δ = r² - |f + (b/a) d|²`, instead of `b² - a (f·f - r²)`,
//!   which cancels catastrophically when the sphere is small compared with
//!   its distance;
//! - the two roots are `t0 = c'/q` and `t1 = q/a` with
//!   `q = b + sign(b) sqrt(a Δ)` and `c' = f·f - r²`, which never subtracts
//!   two nearly equal numbers (the textbook `(b ± sqrt(…))/a` does for one
//!   of the roots);
//! - `c'` is accumulated with fused multiply-adds ending in `-r²`, so an
//!   origin on the surface gives `c' ≈ 0` (and a root `≈ 0`) to within a
//!   few ulps of `r²`.
//!
//! The hit is the nearer root beyond `t_min`, or the farther one where the
//! nearer is `≤ t_min` (rays that start inside the sphere, or on its
//! surface and go in). A ray that leaves the surface it starts on has a
//! near root of a few ulps of `r` around 0: callers pass a `t_min` above
//! that noise (as for triangles), or the ray hits the sphere it left.

use crate::math::{Real, V3, Vec3x8};
use glam::Vec3;
use wide::f32x8;

/// The distance `t` along the ray `o + t·d` (`d` need not be unit, but not
/// zero) to its first crossing of the sphere of center `c` and radius `r`
/// with `t > t_min`, and whether there is one. Where there is none, `t` is
/// `+∞`. A NaN center or radius never hits (the padding of [`Sphere8`]).
#[inline(always)]
pub fn intersect_sphere<R: Real>(o: V3<R>, d: V3<R>, c: V3<R>, r: R, t_min: R) -> (R::Mask, R) {
    let f = o - c;
    let a = d.dot(d);
    let b = -f.dot(d);
    let l = d.mul_add(b / a, f);
    let r2 = r * r;
    let discr = r2 - l.dot(l);
    let cc = f.x.mul_add(f.x, f.y.mul_add(f.y, f.z.mul_add(f.z, -r2)));
    let s = (a * discr).sqrt();
    let q = R::select(b.lt(R::splat(0.0)), b - s, b + s);
    let (t0, t1) = (cc / q, q / a);
    let near = t0.min(t1);
    let far = t0.max(t1);
    let t = R::select(t_min.lt(near), near, far);
    let hit = R::splat(0.0).le(discr) & t_min.lt(t);
    (hit, R::select(hit, t, R::splat(f32::INFINITY)))
}

/// The outward unit normal of the sphere of center `c` at the hit `t` of the
/// ray `o + t·d`: `(o - c) + t·d` (one fused multiply-add per component,
/// from `o - c` rather than from the rounded hit point), normalised. Its
/// direction is within about `2 ε (|o - c| / r + 1)` radians of the exact
/// radius through the point at `t` (`ε` = f32's epsilon: the rounding of
/// `o - c`).
#[inline(always)]
pub fn hit_normal<R: Real>(o: V3<R>, d: V3<R>, t: R, c: V3<R>) -> V3<R> {
    let p = d.mul_add(t, o - c);
    p.scale(R::splat(1.0) / p.dot(p).sqrt())
}

/// One sphere: its center and radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// The center.
    pub center: Vec3,
    /// The radius (positive).
    pub radius: f32,
}

/// Up to eight spheres in structure-of-arrays form, intersected against one
/// ray at once. Unused lanes hold a NaN sphere, which no ray hits.
#[derive(Clone, Copy, Debug)]
pub struct Sphere8 {
    /// The centers, one per lane.
    pub center: Vec3x8,
    /// The radii, one per lane.
    pub radius: f32x8,
}

impl Sphere8 {
    /// A pack of `spheres` (at most 8) in lanes `0..spheres.len()`.
    ///
    /// # Panics
    /// If there are more than 8 spheres.
    pub fn new(spheres: &[Sphere]) -> Self {
        assert!(spheres.len() <= 8, "a Sphere8 holds at most 8 spheres");
        let lane = |get: &dyn Fn(&Sphere) -> f32| {
            f32x8::from(std::array::from_fn::<f32, 8, _>(|l| {
                spheres.get(l).map_or(f32::NAN, get)
            }))
        };
        Self {
            center: V3::new(
                lane(&|s| s.center.x),
                lane(&|s| s.center.y),
                lane(&|s| s.center.z),
            ),
            radius: lane(&|s| s.radius),
        }
    }

    /// The sphere in lane `l` (NaN for padding).
    pub fn get(&self, l: usize) -> Sphere {
        Sphere {
            center: Vec3::new(
                self.center.x.to_array()[l],
                self.center.y.to_array()[l],
                self.center.z.to_array()[l],
            ),
            radius: self.radius.to_array()[l],
        }
    }

    /// The ray `o + t·d` against all eight spheres: per lane, whether it
    /// hits beyond `t_min` and the distance (`+∞` where it misses), the
    /// same bits as [`intersect_sphere`] on that lane's sphere alone.
    #[inline(always)]
    pub fn intersect(&self, o: Vec3, d: Vec3, t_min: f32) -> (f32x8, f32x8) {
        intersect_sphere(
            V3::splat(o),
            V3::splat(d),
            self.center,
            self.radius,
            f32x8::splat(t_min),
        )
    }

    /// The closest hit with `t_min < t < t_max`: the lane and `t`, ties to
    /// the lower lane.
    pub fn closest(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<(usize, f32)> {
        let (_, t) = self.intersect(o, d, t_min);
        let mut best: Option<(usize, f32)> = None;
        for (l, &t) in t.to_array().iter().enumerate() {
            if t < t_max && best.is_none_or(|(_, b)| t < b) {
                best = Some((l, t));
            }
        }
        best
    }
}
