//! The emitters of a scene, for next-event estimation: an emitter is
//! chosen in proportion to its power, then a point on it uniformly by area.
//!
//! Every emissive triangle is an emitter. Its power is proportional to
//! `area × mean(emitted radiance)` (a one-sided Lambertian emitter sends
//! `π · area · L` into its hemisphere). The density of a sampled point, per
//! unit area, is `P(emitter) / area`; seen from a point `x` at distance `r`,
//! with the emitter's normal at angle `θ_l` to the direction back to `x`,
//! it is `P(emitter) / area · r² / cos θ_l` per unit solid angle.

use crate::math::{Real, V3};
use crate::scene::Scene;
use wide::f32x8;

/// The scene's emitters, with what sampling them needs.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Primitive index of each emitter (triangles, then spheres).
    triangle: Vec<u32>,
    /// Running sums of the emitters' powers, normalised to end at 1.
    cdf: Vec<f32>,
    /// Each emitter's geometry and radiance.
    emitters: Vec<Emitter>,
    /// `P(emitter) / area` of each emitter, by *primitive* index (0 for
    /// primitives that do not emit), so a hit can look it up.
    pdf_area_of_triangle: Vec<f32>,
    /// Whether some emitters are spheres.
    has_spheres: bool,
}

/// One emitter (`R = f32`) or eight (`R = f32x8`): a triangle or a
/// sphere, its radiance and its sampling density.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Emitter<R = f32> {
    /// Vertex 0 (a sphere: its center).
    pub v0: V3<R>,
    /// `v1 - v0`.
    pub e1: V3<R>,
    /// `v2 - v0`.
    pub e2: V3<R>,
    /// Front-side unit normal (a sphere: unused).
    pub normal: V3<R>,
    /// The radiance it emits towards its front.
    pub emission: V3<R>,
    /// The density of its points per unit area: `P(emitter) / area`.
    pub pdf_area: R,
    /// 0 for a triangle; a sphere's radius.
    pub radius: R,
}

/// The largest `f32` below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

const ZERO: V3<f32> = V3 {
    x: 0.0,
    y: 0.0,
    z: 0.0,
};

impl Emitter {
    /// The emitter's 16 floats, in field order.
    #[inline(always)]
    fn floats(&self) -> [f32; 17] {
        let v = |v: V3<f32>| [v.x, v.y, v.z];
        let [a, b, c, d, e] = [self.v0, self.e1, self.e2, self.normal, self.emission].map(v);
        [
            a[0],
            a[1],
            a[2],
            b[0],
            b[1],
            b[2],
            c[0],
            c[1],
            c[2],
            d[0],
            d[1],
            d[2],
            e[0],
            e[1],
            e[2],
            self.pdf_area,
            self.radius,
        ]
    }

    /// No emitter: a point sampled on it never carries light (its normal
    /// is zero, so it faces nothing).
    pub const NONE: Emitter = Emitter {
        v0: ZERO,
        e1: ZERO,
        e2: ZERO,
        normal: ZERO,
        emission: ZERO,
        pdf_area: 0.0,
        radius: 0.0,
    };
}

impl Emitter<f32x8> {
    /// Eight emitters, one per lane.
    #[inline(always)]
    pub fn lanes(e: [&Emitter; 8]) -> Self {
        // Transposed field by field: an emitter is 16 plain floats.
        let mut cols = [[0.0f32; 8]; 17];
        for (l, e) in e.iter().enumerate() {
            for (col, x) in cols.iter_mut().zip(e.floats()) {
                col[l] = x;
            }
        }
        let c = cols.map(f32x8::from);
        let v3 = |k: usize| V3::new(c[k], c[k + 1], c[k + 2]);
        Self {
            v0: v3(0),
            e1: v3(3),
            e2: v3(6),
            normal: v3(9),
            emission: v3(12),
            pdf_area: c[15],
            radius: c[16],
        }
    }
}

/// A point on an emitter, as next-event estimation uses it: one
/// (`R = f32`) or eight (`R = f32x8`).
#[derive(Clone, Copy, Debug)]
pub struct LightPoint<R> {
    /// The point.
    pub point: V3<R>,
    /// The emitter's front-side unit normal.
    pub normal: V3<R>,
    /// The radiance it emits towards its front.
    pub emission: V3<R>,
    /// The point's density per unit area.
    pub pdf_area: R,
}

impl<R: Real> LightPoint<R> {
    /// The point `u` (two numbers) of the emitter `e`, uniform by area
    /// ([`square_to_triangle`]).
    #[inline(always)]
    pub fn on(e: &Emitter<R>, u: [R; 2]) -> Self {
        Self::on_triangle(e, u)
    }

    /// The point [`LightPoint::on`] gives on a triangle emitter, or on a
    /// sphere emitter (a lane whose `radius` is positive) a point uniform
    /// on its surface by area: `z = 1 - 2 u0`, azimuth `2π u1`.
    #[inline(always)]
    pub fn on_any(e: &Emitter<R>, u: [R; 2]) -> Self {
        let t = Self::on_triangle(e, u);
        let one = R::splat(1.0);
        let z = R::splat(-2.0).mul_add(u[0], one);
        let r = (-z).mul_add(z, one).max(R::splat(0.0)).sqrt();
        let (sin, cos) = crate::math::sin_cos_2pi(u[1]);
        let dir = V3::new(r * cos, r * sin, z);
        let sphere = R::splat(0.0).lt(e.radius);
        Self {
            point: V3::select(sphere, dir.mul_add(e.radius, e.v0), t.point),
            normal: V3::select(sphere, dir, t.normal),
            ..t
        }
    }

    #[inline(always)]
    fn on_triangle(e: &Emitter<R>, u: [R; 2]) -> Self {
        let [b1, b2] = square_to_triangle(u);
        Self {
            point: e.e1.mul_add(b1, e.e2.mul_add(b2, e.v0)),
            normal: e.normal,
            emission: e.emission,
            pdf_area: e.pdf_area,
        }
    }
}

impl Lights {
    /// The emitters of `scene`: its triangles whose material emits and
    /// whose area is not zero.
    pub fn new(scene: &Scene) -> Self {
        let mut lights = Lights {
            pdf_area_of_triangle: vec![0.0; scene.triangles.len() + scene.spheres.len()],
            has_spheres: false,
            ..Lights::default()
        };
        let mut powers = Vec::new();
        let mut areas = Vec::new();
        for (i, t) in scene.triangles.iter().enumerate() {
            let emission = scene.materials[t.material as usize].emission;
            let (e1, e2) = (t.v[1] - t.v[0], t.v[2] - t.v[0]);
            let area = 0.5 * e1.cross(e2).length();
            let power = area * emission.element_sum() / 3.0;
            if !(power > 0.0 && power.is_finite()) {
                continue;
            }
            lights.triangle.push(i as u32);
            lights.emitters.push(Emitter {
                v0: t.v[0].into(),
                e1: e1.into(),
                e2: e2.into(),
                normal: t.normal.into(),
                emission: emission.into(),
                pdf_area: 0.0,
                radius: 0.0,
            });
            powers.push(power as f64);
            areas.push(area as f64);
        }
        let first_sphere = scene.triangles.len();
        for (k, sphere) in scene.spheres.iter().enumerate() {
            let emission = scene.materials[sphere.material as usize].emission;
            let area = 4.0 * std::f64::consts::PI * (sphere.radius as f64).powi(2);
            let power = area * emission.element_sum() as f64 / 3.0;
            if !(power > 0.0 && power.is_finite()) {
                continue;
            }
            lights.has_spheres = true;
            lights.triangle.push((first_sphere + k) as u32);
            lights.emitters.push(Emitter {
                v0: sphere.center.into(),
                e1: ZERO,
                e2: ZERO,
                normal: ZERO,
                emission: emission.into(),
                pdf_area: 0.0,
                radius: sphere.radius,
            });
            powers.push(power);
            areas.push(area);
        }
        let total: f64 = powers.iter().sum();
        let mut sum = 0.0;
        for (k, p) in powers.iter().enumerate() {
            sum += p;
            lights.cdf.push((sum / total) as f32);
            let pdf_area = ((p / total) / areas[k]) as f32;
            lights.emitters[k].pdf_area = pdf_area;
            lights.pdf_area_of_triangle[lights.triangle[k] as usize] = pdf_area;
        }
        if let Some(last) = lights.cdf.last_mut() {
            *last = 1.0;
        }
        lights
    }

    /// Whether the scene has no emitter.
    pub fn is_empty(&self) -> bool {
        self.triangle.is_empty()
    }

    /// Number of emitters.
    pub fn len(&self) -> usize {
        self.triangle.len()
    }

    /// The emitter that `u0` in `[0, 1)` chooses, by power, and `u0`
    /// stretched back to `[0, 1)` over that emitter's share of the unit
    /// interval ([`Emitter::NONE`] when the scene has none). A 2D point
    /// `(u0, u1)` thus picks an emitter and a point on it: stratified
    /// points stay stratified over all the emitters together, and a
    /// sample needs no number of its own to pick with.
    #[inline]
    pub fn pick(&self, u0: f32) -> (&Emitter, f32) {
        let k = match self.cdf.len() {
            0 => return (&Emitter::NONE, u0),
            1 => return (&self.emitters[0], u0),
            // The first emitter whose running sum exceeds `u0`.
            n => self.cdf.partition_point(|&c| c <= u0).min(n - 1),
        };
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let u = (u0 - lo) / (self.cdf[k] - lo);
        (&self.emitters[k], u.clamp(0.0, ONE_MINUS_EPSILON))
    }

    /// A point on an emitter: `u[0]` chooses the emitter by power (and is
    /// reused, [`pick`](Self::pick)), `u` places the point on it, uniformly
    /// by area. `None` when the scene has no emitter.
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Option<LightPoint<f32>> {
        if self.is_empty() {
            return None;
        }
        let (emitter, u0) = self.pick(u[0]);
        Some(self.point_on(emitter, [u0, u[1]]))
    }

    /// The point on `emitter` (one lane or eight) for the numbers `u`:
    /// [`LightPoint::on`], or [`LightPoint::on_any`] where the scene has
    /// emissive spheres.
    #[inline(always)]
    pub fn point_on<R: Real>(&self, emitter: &Emitter<R>, u: [R; 2]) -> LightPoint<R> {
        if self.has_spheres {
            LightPoint::on_any(emitter, u)
        } else {
            LightPoint::on(emitter, u)
        }
    }

    /// The density per unit area with which [`Lights::sample`] picks a
    /// point on primitive `triangle` (triangles, then spheres; 0 for one
    /// that does not emit).
    #[inline]
    pub fn pdf_area(&self, triangle: u32) -> f32 {
        self.pdf_area_of_triangle[triangle as usize]
    }
}

/// Barycentric coordinates `(b1, b2)` (weights of vertices 1 and 2) of a
/// point uniform on a triangle, from a point of the unit square: Heitz's
/// low-distortion map ("A Low-Distortion Map Between Triangle and Square",
/// 2019), which keeps stratified points stratified.
#[inline(always)]
pub fn square_to_triangle<R: Real>([u0, u1]: [R; 2]) -> [R; 2] {
    let half = R::splat(0.5);
    let below = u0.lt(u1);
    let (h0, h1) = (u0 * half, u1 * half);
    let b0 = R::select(below, h0, u0 - h1);
    let b1 = R::select(below, u1 - h0, h1);
    // Weights of vertices 0, 1, 2 are (b0, b1, 1 - b0 - b1).
    [b1, R::splat(1.0) - b0 - b1]
}

/// The power heuristic (β = 2) weight of a strategy of density `a` against
/// one of density `b`: `a² / (a² + b²)`, 1 when `b` is 0.
#[inline(always)]
pub fn power_heuristic<R: Real>(a: R, b: R) -> R {
    let (a2, b2) = (a * a, b * b);
    R::select(b2.eq(R::splat(0.0)), R::splat(1.0), a2 / (a2 + b2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampler::PathRng;

    #[test]
    fn square_to_triangle_is_uniform_on_the_triangle() {
        // Points land inside; each of the 4 sub-triangles of the midpoint
        // subdivision gets a quarter of them (within 4 sigma).
        let mut rng = PathRng::new(1, 2, 3);
        let n = 200_000;
        let mut counts = [0u32; 4];
        for _ in 0..n {
            let [b1, b2] = square_to_triangle([rng.next_f32(), rng.next_f32()]);
            let b0 = 1.0 - b1 - b2;
            assert!(b0 >= 0.0 && b1 >= 0.0 && b2 >= 0.0, "{b0} {b1} {b2}");
            let k = if b0 > 0.5 {
                0
            } else if b1 > 0.5 {
                1
            } else if b2 > 0.5 {
                2
            } else {
                3
            };
            counts[k] += 1;
        }
        let (mean, sigma) = (n as f64 / 4.0, (n as f64 * 0.25 * 0.75).sqrt());
        for c in counts {
            assert!((c as f64 - mean).abs() < 4.0 * sigma, "{counts:?}");
        }
    }

    #[test]
    fn emitters_are_picked_by_power() {
        // The Cornell box's light is two triangles of equal area: each half.
        let scene = Scene::cornell();
        let lights = Lights::new(&scene);
        assert_eq!(lights.len(), 2);
        let area = |e: &Emitter| 0.5 * glam::Vec3::from(e.e1).cross(e.e2.into()).length();
        let total_area: f32 = lights.emitters.iter().map(area).sum();
        for (k, e) in lights.emitters.iter().enumerate() {
            let p = lights.pdf_area(lights.triangle[k]) * area(e);
            assert!((p - area(e) / total_area).abs() < 1e-6, "{p}");
            assert_eq!(e.pdf_area, lights.pdf_area(lights.triangle[k]));
        }
        // Picks follow the running sums of the powers, and stretch the
        // number back over the emitter's share.
        let pick = |u: f32| {
            let (e, u) = lights.pick(u);
            (std::ptr::eq(e, &lights.emitters[0]), u)
        };
        assert_eq!(pick(0.0), (true, 0.0));
        assert_eq!(pick(0.25), (true, 0.5));
        assert_eq!(pick(0.75), (false, 0.5));
        let (first, u) = pick(0.999_999_9);
        assert!(!first && u < 1.0 && u > 0.999_99);
        // Non-emitters have density 0; samples lie on the light's plane.
        assert_eq!(lights.pdf_area(0), 0.0);
        let y = scene.triangles[lights.triangle[0] as usize].v[0].y;
        let mut rng = PathRng::new(4, 4, 4);
        for _ in 0..1000 {
            let s = lights.sample([rng.next_f32(), rng.next_f32()]).unwrap();
            assert!((s.point.y - y).abs() < 1e-6);
            assert_eq!([s.emission.x, s.emission.y, s.emission.z], [10.0; 3]);
        }
        // No emitter, no sample.
        let mut dark = scene.clone();
        dark.materials
            .iter_mut()
            .for_each(|m| m.emission = glam::Vec3::ZERO);
        assert!(Lights::new(&dark).sample([0.5, 0.5]).is_none());
    }

    #[test]
    fn eight_lanes_sample_the_points_one_lane_does() {
        let lights = Lights::new(&Scene::cornell());
        let mut rng = PathRng::new(8, 8, 8);
        for _ in 0..1000 {
            let u: [[f32; 2]; 8] = std::array::from_fn(|_| [rng.next_f32(), rng.next_f32()]);
            let picked = u.map(|u| lights.pick(u[0]));
            let e = Emitter::lanes(picked.map(|p| p.0));
            let u0 = f32x8::from(picked.map(|p| p.1));
            let p8 = LightPoint::on(&e, [u0, f32x8::from(u.map(|u| u[1]))]);
            for (l, &u) in u.iter().enumerate() {
                let p = lights.sample(u).unwrap();
                let lane = |v: f32x8| v.to_array()[l].to_bits();
                assert_eq!(
                    [p.point.x, p.point.y, p.point.z].map(f32::to_bits),
                    [lane(p8.point.x), lane(p8.point.y), lane(p8.point.z)]
                );
                assert_eq!(p.pdf_area.to_bits(), lane(p8.pdf_area));
            }
        }
    }

    #[test]
    fn power_heuristic_weights_sum_to_one() {
        for (a, b) in [(1.0, 1.0), (2.0, 0.5), (1e-3, 7.0)] {
            let w = power_heuristic(a, b) + power_heuristic(b, a);
            assert!((w - 1.0).abs() < 1e-6);
        }
        assert_eq!(power_heuristic(3.0, 0.0), 1.0);
    }
}
