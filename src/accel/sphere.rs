//! Ray/sphere intersection, written once for any [`Real`]; 8-sphere packs
//! ([`Sphere8`]) tested against one ray in SIMD; the hierarchy's sphere
//! packs ([`SpherePack`], 8 or 16 lanes, the same width as its triangle
//! packs); and the brute-force closest hit over triangles and spheres
//! together ([`closest_hit_brute_force_prims`]).
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

use crate::accel::shape::{AreaEmitter, AreaShape, Shape, ShapePack, Shapes};
#[cfg(target_arch = "x86_64")]
use crate::accel::simd::F32x16;
use crate::accel::simd::{Lanes, SimdWidth};
use crate::accel::triangle::{Hit, PackHits, TriangleEdges};
use crate::math::{Real, V3, Vec3x8};
use crate::scene::Scene;
use glam::{Vec3, Vec3A};
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
///
/// The primitive that [`Bvh::build_prims`](crate::accel::bvh::Bvh::build_prims)
/// takes beside the triangles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// The center.
    pub center: Vec3,
    /// The radius (positive).
    pub radius: f32,
}

impl Sphere {
    /// The sphere of center `center` and radius `radius`.
    pub fn new(center: Vec3, radius: f32) -> Self {
        Self { center, radius }
    }

    /// Its bounding box (minimum and maximum corners), or `None` where a
    /// coordinate or the radius is not finite (such a sphere is kept out of
    /// a hierarchy's tree and tested against every ray, as brute force
    /// would).
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let r = Vec3::splat(self.radius.abs());
        let (lo, hi) = (self.center - r, self.center + r);
        (self.radius.is_finite() && lo.is_finite() && hi.is_finite()).then_some((lo, hi))
    }
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

/// [`Lanes::LANES`] spheres (8 or 16) in structure-of-arrays form, with
/// the index each is reported by: the hierarchy's sphere leaves. Unused
/// lanes hold a NaN sphere (which no ray hits) with index `u32::MAX`.
///
/// Each lane runs [`intersect_sphere`], so a lane gives the same bits as
/// the scalar kernel on its sphere alone, at either width.
#[derive(Clone, Copy, Debug)]
pub struct SpherePack<R: Lanes> {
    /// The centers, one per lane.
    pub center: V3<R>,
    /// The radii, one per lane.
    pub radius: R,
    /// Each lane's primitive index (`u32::MAX` for padding), as `i32` bits.
    pub index: R::Index,
}

impl<R: Lanes> SpherePack<R> {
    /// Pack up to [`Lanes::LANES`] spheres with their indices.
    ///
    /// # Panics
    ///
    /// With more than [`Lanes::LANES`] spheres.
    pub fn pack(spheres: &[(u32, Sphere)]) -> Self {
        assert!(spheres.len() <= R::LANES, "too many spheres for a pack");
        let lane = |f: &dyn Fn(&Sphere) -> f32| {
            let v: Vec<f32> = spheres.iter().map(|(_, s)| f(s)).collect();
            R::from_slice(&v, f32::NAN)
        };
        let index: Vec<i32> = spheres.iter().map(|(i, _)| *i as i32).collect();
        Self {
            center: V3::new(
                lane(&|s| s.center.x),
                lane(&|s| s.center.y),
                lane(&|s| s.center.z),
            ),
            radius: lane(&|s| s.radius),
            index: R::index_from_slice(&index, -1),
        }
    }

    /// Test one ray (broadcast to all lanes) against the pack's spheres,
    /// keeping in `best` each lane's smallest `(t, index)`: the same rule
    /// as [`TrianglePack::intersect`](crate::accel::triangle::TrianglePack::intersect),
    /// `IN_INDEX_ORDER` included.
    #[inline(always)]
    pub fn intersect<const IN_INDEX_ORDER: bool>(
        &self,
        o: &V3<R>,
        d: &V3<R>,
        t_min: R,
        best: &mut PackHits<R>,
    ) {
        let (hit, t) = intersect_sphere(*o, *d, self.center, self.radius, t_min);
        best.keep::<IN_INDEX_ORDER>(hit, t, self.index);
    }

    /// Whether the ray hits one of the pack's spheres at a distance
    /// `t_min < t < t_max`: the same test, lane for lane, as
    /// [`SpherePack::intersect`] with `best.t = t_max`.
    #[inline(always)]
    pub fn occludes(&self, o: &V3<R>, d: &V3<R>, t_min: R, t_max: R) -> bool {
        let (hit, t) = intersect_sphere(*o, *d, self.center, self.radius, t_min);
        R::any(hit & t.lt(t_max))
    }

    /// Each lane's `t` (`+∞` where it misses), in lane order, onto `out`.
    #[inline(always)]
    fn lane_ts(&self, o: Vec3, d: Vec3, t_min: f32, out: &mut Vec<f32>) {
        let (_, t) = intersect_sphere(
            V3::splat(o),
            V3::splat(d),
            self.center,
            self.radius,
            R::splat(t_min),
        );
        out.extend_from_slice(&t.to_vec());
    }
}

/// The pack kernel at `R`'s width over `spheres`, [`Lanes::LANES`] at a
/// time: every lane's `t`, padding included.
#[inline(always)]
fn packed_ts<R: Lanes>(spheres: &[Sphere], o: Vec3, d: Vec3, t_min: f32) -> Vec<f32> {
    let indexed: Vec<(u32, Sphere)> = spheres
        .iter()
        .enumerate()
        .map(|(i, s)| (i as u32, *s))
        .collect();
    let mut out = Vec::with_capacity(spheres.len().div_ceil(R::LANES) * R::LANES);
    for c in indexed.chunks(R::LANES) {
        SpherePack::<R>::pack(c).lane_ts(o, d, t_min, &mut out);
    }
    out
}

/// [`packed_ts`] at 16 lanes, compiled with AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn packed_ts16(spheres: &[Sphere], o: Vec3, d: Vec3, t_min: f32) -> Vec<f32> {
    packed_ts::<F32x16>(spheres, o, d, t_min)
}

/// The hierarchy's sphere kernel ([`SpherePack`]) at `width` (8 where the
/// CPU lacks it): the ray `o + t·d` against `spheres`, packed `width` at a
/// time in order, giving every lane's `t` (`+∞` where it misses), the
/// padding lanes of the last pack included. For tests: each lane must give
/// the same bits as [`intersect_sphere`] on its sphere alone.
pub fn intersect_packed(
    width: SimdWidth,
    spheres: &[Sphere],
    o: Vec3,
    d: Vec3,
    t_min: f32,
) -> Vec<f32> {
    match width {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: entered only where the CPU has AVX-512.
        SimdWidth::W16 if width.is_available() => unsafe { packed_ts16(spheres, o, d, t_min) },
        _ => packed_ts::<f32x8>(spheres, o, d, t_min),
    }
}

/// Scalar brute force over triangles and spheres together: the plainest
/// closest-hit query over mixed primitives, the reference the hierarchy
/// matches bit for bit.
///
/// Primitive indices: triangle `i` is `i`, sphere `j` is
/// `tris.len() + j`. The answer is the smallest `(t, index)` with
/// `t_min < t < t_max`:
/// [`closest_hit_brute_force_shapes`](crate::accel::shape::closest_hit_brute_force_shapes)
/// over these two kinds (each triangle by Möller–Trumbore, then each
/// sphere by [`intersect_sphere`], kept when strictly closer: on equal `t`
/// the lower index, which came first, stays).
pub fn closest_hit_brute_force_prims(
    tris: &[TriangleEdges],
    spheres: &[Sphere],
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<Hit> {
    let shapes = Shapes::triangles_and_spheres(tris, spheres);
    crate::accel::shape::closest_hit_brute_force_shapes(&shapes, o, d, t_min, t_max)
}

impl<R: Lanes> ShapePack<R> for SpherePack<R> {
    #[inline(always)]
    fn intersect<const IN_INDEX_ORDER: bool>(
        &self,
        o: &V3<R>,
        d: &V3<R>,
        t_min: R,
        best: &mut PackHits<R>,
    ) {
        SpherePack::intersect::<IN_INDEX_ORDER>(self, o, d, t_min, best)
    }

    #[inline(always)]
    fn occludes(&self, o: &V3<R>, d: &V3<R>, t_min: R, t_max: R) -> bool {
        SpherePack::occludes(self, o, d, t_min, t_max)
    }
}

/// Analytic spheres: the second kind (their primitive indices follow the
/// triangles').
impl Shape for Sphere {
    type Pack<R: Lanes> = SpherePack<R>;
    /// Its center (the normal at a hit is the radius through it).
    type Surface = V3<f32>;

    fn in_scene(scene: &Scene) -> Vec<Self> {
        let sphere = |s: &crate::scene::Sphere| Sphere::new(s.center, s.radius);
        scene.spheres.iter().map(sphere).collect()
    }

    fn materials(scene: &Scene) -> Vec<u32> {
        scene.spheres.iter().map(|s| s.material).collect()
    }

    #[inline]
    fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        let (lo, hi) = Sphere::bounds(self)?;
        Some((lo.into(), hi.into()))
    }

    fn pack<R: Lanes>(shapes: &[(u32, Self)]) -> SpherePack<R> {
        SpherePack::pack(shapes)
    }

    #[inline(always)]
    fn intersect(&self, o: V3<f32>, d: V3<f32>, t_min: f32) -> (bool, f32) {
        intersect_sphere(o, d, V3::from(self.center), self.radius, t_min)
    }

    fn surfaces(scene: &Scene) -> Vec<V3<f32>> {
        scene.spheres.iter().map(|s| V3::from(s.center)).collect()
    }

    #[inline(always)]
    fn flat_normal(_center: &V3<f32>) -> Option<Vec3> {
        None
    }

    #[inline(always)]
    fn front_normal(center: &V3<f32>, o: V3<f32>, d: V3<f32>, t: f32) -> V3<f32> {
        hit_normal(o, d, t, *center)
    }

    fn count(scene: &Scene) -> usize {
        scene.spheres.len()
    }

    /// Each emissive sphere of positive finite power (area `4π r²`).
    fn emitters(scene: &Scene) -> Vec<AreaEmitter> {
        let mut out = Vec::new();
        for (k, sphere) in scene.spheres.iter().enumerate() {
            let emission = scene.materials[sphere.material as usize].emission;
            let area = 4.0 * std::f64::consts::PI * (sphere.radius as f64).powi(2);
            let power = area * emission.element_sum() as f64 / 3.0;
            if !(power > 0.0 && power.is_finite()) {
                continue;
            }
            let zero = V3::from(Vec3::ZERO);
            out.push(AreaEmitter {
                shape: AreaShape {
                    v0: sphere.center.into(),
                    e1: zero,
                    e2: zero,
                    normal: zero,
                    radius: sphere.radius,
                    parallelogram: 0.0,
                },
                prims: [Some(k as u32), None],
                area,
                power,
                emission,
                rectangle: None,
            });
        }
        out
    }

    /// Uniform on the sphere's surface by area: `z = 1 - 2 u0`, azimuth
    /// `2π u1`; the normal is the direction from the center.
    #[inline(always)]
    fn sample_area<R: Real>(e: &AreaShape<R>, u: [R; 2]) -> (V3<R>, V3<R>) {
        let one = R::splat(1.0);
        let z = R::splat(-2.0).mul_add(u[0], one);
        let r = (-z).mul_add(z, one).max(R::splat(0.0)).sqrt();
        let (sin, cos) = crate::math::sin_cos_2pi(u[1]);
        let dir = V3::new(r * cos, r * sin, z);
        (dir.mul_add(e.radius, e.v0), dir)
    }
}
