//! The emitters of a scene, for next-event estimation: an emitter is
//! chosen in proportion to its power, then a point on it uniformly by area.
//!
//! Every emissive triangle is an emitter. Its power is proportional to
//! `area × mean(emitted radiance)` (a one-sided Lambertian emitter sends
//! `π · area · L` into its hemisphere). The density of a sampled point, per
//! unit area, is `P(emitter) / area`; seen from a point `x` at distance `r`,
//! with the emitter's normal at angle `θ_l` to the direction back to `x`,
//! it is `P(emitter) / area · r² / cos θ_l` per unit solid angle.

use crate::math::V3;
use crate::scene::Scene;
use glam::Vec3;

/// The scene's emitters, with what sampling them needs.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Triangle index of each emitter.
    triangle: Vec<u32>,
    /// Running sums of the emitters' powers, normalised to end at 1.
    cdf: Vec<f32>,
    /// Vertex 0 and two edges of each emitter.
    v0: Vec<Vec3>,
    e1: Vec<Vec3>,
    e2: Vec<Vec3>,
    /// Front-side unit normal of each emitter.
    normal: Vec<Vec3>,
    /// Emitted radiance of each emitter (towards its front).
    emission: Vec<Vec3>,
    /// `P(emitter) / area` of each emitter, by *triangle* index (0 for
    /// triangles that do not emit), so a hit can look it up.
    pdf_area_of_triangle: Vec<f32>,
}

/// A point sampled on an emitter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// The point.
    pub point: Vec3,
    /// The emitter's front-side unit normal.
    pub normal: Vec3,
    /// The radiance it emits towards its front.
    pub emission: Vec3,
    /// The density of the point per unit area: `P(emitter) / area`.
    pub pdf_area: f32,
}

impl Lights {
    /// The emitters of `scene`: its triangles whose material emits and
    /// whose area is not zero.
    pub fn new(scene: &Scene) -> Self {
        let mut lights = Lights {
            pdf_area_of_triangle: vec![0.0; scene.triangles.len()],
            ..Lights::default()
        };
        let mut powers = Vec::new();
        for (i, t) in scene.triangles.iter().enumerate() {
            let emission = scene.materials[t.material as usize].emission;
            let (e1, e2) = (t.v[1] - t.v[0], t.v[2] - t.v[0]);
            let area = 0.5 * e1.cross(e2).length();
            let power = area * emission.element_sum() / 3.0;
            if !(power > 0.0 && power.is_finite()) {
                continue;
            }
            lights.triangle.push(i as u32);
            lights.v0.push(t.v[0]);
            lights.e1.push(e1);
            lights.e2.push(e2);
            lights.normal.push(t.normal);
            lights.emission.push(emission);
            powers.push(power as f64);
        }
        let total: f64 = powers.iter().sum();
        let mut sum = 0.0;
        for (k, p) in powers.iter().enumerate() {
            sum += p;
            lights.cdf.push((sum / total) as f32);
            let tri = lights.triangle[k] as usize;
            let area = 0.5 * lights.e1[k].cross(lights.e2[k]).length();
            lights.pdf_area_of_triangle[tri] = ((p / total) / area as f64) as f32;
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

    /// A point on an emitter: `pick` in `[0, 1)` chooses the emitter by
    /// power, `u` places the point on it, uniformly by area. `None` when
    /// the scene has no emitter.
    #[inline]
    pub fn sample(&self, pick: f32, u: [f32; 2]) -> Option<LightSample> {
        if self.cdf.is_empty() {
            return None;
        }
        // The first emitter whose running sum exceeds `pick`.
        let k = self
            .cdf
            .partition_point(|&c| c <= pick)
            .min(self.cdf.len() - 1);
        let [b1, b2] = square_to_triangle(u);
        let point = Vec3::from(
            V3::from(self.e1[k])
                .mul_add(b1, V3::from(self.e2[k]).mul_add(b2, V3::from(self.v0[k]))),
        );
        Some(LightSample {
            point,
            normal: self.normal[k],
            emission: self.emission[k],
            pdf_area: self.pdf_area_of_triangle[self.triangle[k] as usize],
        })
    }

    /// The density per unit area with which [`Lights::sample`] picks a
    /// point on triangle `triangle` (0 for a triangle that does not emit).
    #[inline]
    pub fn pdf_area(&self, triangle: u32) -> f32 {
        self.pdf_area_of_triangle[triangle as usize]
    }
}

/// Barycentric coordinates `(b1, b2)` (weights of vertices 1 and 2) of a
/// point uniform on a triangle, from a point of the unit square: Heitz's
/// low-distortion map ("A Low-Distortion Map Between Triangle and Square",
/// 2019), which keeps stratified points stratified.
#[inline]
pub fn square_to_triangle([u0, u1]: [f32; 2]) -> [f32; 2] {
    let (b0, b1) = if u0 < u1 {
        let b0 = u0 / 2.0;
        (b0, u1 - b0)
    } else {
        let b1 = u1 / 2.0;
        (u0 - b1, b1)
    };
    // Weights of vertices 0, 1, 2 are (b0, b1, 1 - b0 - b1).
    [b1, 1.0 - b0 - b1]
}

/// The power heuristic (β = 2) weight of a strategy of density `a` against
/// one of density `b`: `a² / (a² + b²)`, 1 when `b` is 0.
#[inline]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if b2 == 0.0 { 1.0 } else { a2 / (a2 + b2) }
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
        let total_area: f32 = lights
            .e1
            .iter()
            .zip(&lights.e2)
            .map(|(a, b)| 0.5 * a.cross(*b).length())
            .sum();
        for k in 0..2 {
            let tri = lights.triangle[k];
            let area = 0.5 * lights.e1[k].cross(lights.e2[k]).length();
            let p = lights.pdf_area(tri) * area;
            assert!((p - area / total_area).abs() < 1e-6, "{p}");
        }
        // Non-emitters have density 0; samples lie on the light's plane.
        assert_eq!(lights.pdf_area(0), 0.0);
        let mut rng = PathRng::new(4, 4, 4);
        for _ in 0..1000 {
            let s = lights
                .sample(rng.next_f32(), [rng.next_f32(), rng.next_f32()])
                .unwrap();
            assert!((s.point.y - scene.triangles[lights.triangle[0] as usize].v[0].y).abs() < 1e-6);
            assert_eq!(s.emission, Vec3::splat(10.0));
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
