//! What both engines do at a path vertex beyond scattering: next-event
//! estimation (a shadow ray to a point on an emitter), the multiple
//! importance sampling weight of emission found by a scattered ray, and
//! Russian roulette. Each is one scalar function, called by both engines,
//! so the two compute the same terms.

use super::bsdf::Surface;
use super::lights::{LightPoint, Lights, power_heuristic};
use super::offset::error_bound;
use super::sampler::Sampler;
use crate::math::{Real, V3};
use crate::scene::Integrator;
use glam::Vec3;
use wide::f32x8;

/// How paths are traced: the estimator, the maximum depth and Russian
/// roulette.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Estimator {
    /// The estimator.
    pub integrator: Integrator,
    /// At most this many segments per path (the camera ray is the first).
    pub max_depth: u32,
    /// Russian roulette may end paths at vertices of this depth and deeper
    /// (the camera ray's hit is depth 0); `None`: never.
    pub rr_depth: Option<u32>,
}

impl Estimator {
    /// The report's estimator, to `max_depth`.
    pub fn report(max_depth: u32) -> Self {
        Self {
            integrator: Integrator::Report,
            max_depth,
            rr_depth: None,
        }
    }

    /// Whether Russian roulette applies at a vertex of depth `depth`: the
    /// vertex then draws one number for it, before its other numbers.
    #[inline]
    pub fn roulette_at(&self, depth: u32) -> bool {
        self.rr_depth.is_some_and(|d| depth >= d)
    }

    /// Whether vertices have a roulette number's slot, drawn or skipped
    /// ([`roulette_number`](Self::roulette_number)): all but the report's.
    #[inline]
    pub fn has_roulette_slot(&self) -> bool {
        self.integrator != Integrator::Report
    }

    /// Whether vertices sample emitters (and weight emission by MIS).
    #[inline]
    pub fn samples_lights(&self) -> bool {
        self.integrator == Integrator::Nee
    }

    // The numbers of a vertex. Every vertex a path scatters from draws the
    // same dimensions for the same purposes, and every 2D draw starts at an
    // even dimension (the camera took dimensions 0 and 1), so that a
    // sampler that stratifies pairs of dimensions (Sobol) stratifies them:
    //
    //   report: [direction 2]                                    2 dims
    //   bsdf:   [roulette, lobe, direction 2]                    4 dims
    //   nee:    [roulette, -, emitter and point 2, lobe, -, direction 2]
    //                                                             8 dims
    //
    // A slot whose number is not needed (no roulette at this depth, the
    // unused one) is skipped, not drawn elsewhere.

    /// The vertex's Russian roulette number, when roulette applies at
    /// depth `depth` (the first number of the vertex).
    #[inline]
    pub fn roulette_number<S: Sampler>(
        &self,
        sampler: &S,
        path: &mut S::Path,
        depth: u32,
    ) -> Option<f32> {
        if !self.has_roulette_slot() {
            return None;
        }
        if self.roulette_at(depth) {
            Some(sampler.next(path))
        } else {
            sampler.skip(path, 1);
            None
        }
    }

    /// The vertex's light-sampling numbers: an emitter and a point on it
    /// ([`Lights::sample`]).
    #[inline]
    pub fn light_numbers<S: Sampler>(&self, sampler: &S, path: &mut S::Path) -> [f32; 2] {
        sampler.skip(path, 1);
        sampler.next_2d(path)
    }

    /// Skip the vertex's light-sampling numbers: a delta surface takes no
    /// shadow ray, and its numbers keep their dimensions.
    #[inline]
    pub fn skip_light_numbers<S: Sampler>(&self, sampler: &S, path: &mut S::Path) {
        sampler.skip(path, 3);
    }

    /// [`light_numbers`](Self::light_numbers) of up to eight paths, one per
    /// lane.
    #[inline]
    pub fn light_numbers_8<S: Sampler>(&self, sampler: &S, paths: &mut [S::Path]) -> [f32x8; 2] {
        sampler.skip_next_2d_8(paths, 1)
    }

    /// [`bsdf_numbers`](Self::bsdf_numbers) of up to eight paths, one per
    /// lane.
    #[inline]
    pub fn bsdf_numbers_8<S: Sampler>(
        &self,
        sampler: &S,
        paths: &mut [S::Path],
    ) -> (f32x8, [f32x8; 2]) {
        match self.integrator {
            Integrator::Report => (f32x8::ZERO, sampler.next_2d_8(paths)),
            Integrator::Bsdf => {
                let lobe = sampler.next_8(paths);
                (lobe, sampler.next_2d_8(paths))
            }
            Integrator::Nee => {
                let lobe = sampler.next_8(paths);
                for p in paths.iter_mut() {
                    sampler.skip(p, 1);
                }
                (lobe, sampler.next_2d_8(paths))
            }
        }
    }

    /// The vertex's scattering numbers: a lobe choice and a direction.
    #[inline]
    pub fn bsdf_numbers<S: Sampler>(&self, sampler: &S, path: &mut S::Path) -> (f32, [f32; 2]) {
        match self.integrator {
            Integrator::Report => (0.0, sampler.next_2d(path)),
            Integrator::Bsdf => {
                let lobe = sampler.next(path);
                (lobe, sampler.next_2d(path))
            }
            Integrator::Nee => {
                let lobe = sampler.next(path);
                sampler.skip(path, 1);
                (lobe, sampler.next_2d(path))
            }
        }
    }
}

/// A shadow ray of next-event estimation: if nothing lies on the segment
/// from `origin` along `dir` up to `t_max`, the path's radiance gains
/// `throughput × radiance`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowRay<R> {
    /// Where the ray starts: the path's vertex, moved off its surface
    /// ([`crate::integrator::offset`]).
    pub origin: V3<R>,
    /// Unit direction towards the point on the emitter.
    pub dir: V3<R>,
    /// The segment ends here, just short of the emitter (by the rounding
    /// error of the point on it, [`crate::integrator::offset`]).
    pub t_max: R,
    /// `f · cos θ · L_e · w / pdf` of the light sample (w its MIS weight).
    pub radiance: V3<R>,
}

/// Next-event estimation at a non-delta vertex `p` of `surface` (a hit
/// point within `err` of the surface, [`error_bound`]), whose normal
/// facing the incoming ray is `n` and whose outgoing direction is `wo`,
/// towards the point `light` on an emitter: the shadow ray, weighted
/// against the surface's own direction sampling by the power heuristic,
/// and whether light can arrive at all (not when the emitter's back faces
/// `p`, nor when the surface does not scatter towards it, nor when the
/// segment is too short to leave both surfaces). Written once for one
/// lane and for eight, so both engines compute the same bits.
///
/// The ray starts `err` from `p` along `n` (the side light must arrive
/// from) and ends short of the point on the emitter by that point's own
/// error bound, measured across the emitter ([`crate::integrator::offset`]).
#[inline(always)]
pub fn connect<R: Real>(
    light: &LightPoint<R>,
    err: R,
    (p, n, wo): (V3<R>, V3<R>, V3<R>),
    front: R::Mask,
    surface: &Surface<R>,
) -> (R::Mask, ShadowRay<R>) {
    connect_shaded(light, err, (p, n, n, wo), front, surface)
}

/// [`connect`] at a smooth surface: the BSDF is evaluated with the shading
/// facing normal `ns` ([`shading_facing`](super::bsdf::shading_facing)),
/// and the emitter must also lie above the geometric facing normal `ng`:
/// light from behind the geometric surface never arrives, whatever the
/// shading normal says. With `ns == ng` it is [`connect`], bit for bit.
#[inline(always)]
pub fn connect_shaded<R: Real>(
    light: &LightPoint<R>,
    err: R,
    (p, ng, n, wo): (V3<R>, V3<R>, V3<R>, V3<R>),
    front: R::Mask,
    surface: &Surface<R>,
) -> (R::Mask, ShadowRay<R>) {
    let zero = R::splat(0.0);
    // Light arrives only on the side of `ng`: the ray leaves towards it.
    let origin = ng.mul_add(err, p);
    let to = light.point - origin;
    let dist2 = to.dot(to);
    let dist = dist2.sqrt();
    let dir = to.scale(R::splat(1.0) / dist);
    // Emission is one-sided: the emitter's front must face the vertex.
    let cos_light = -light.normal.dot(dir);
    // Short of the emitter by its point's error, across its surface.
    let t_max = dist - error_bound(origin, light.point, light.scale) / cos_light;
    let (fcos, cos, pdf_bsdf) = surface.eval(n, wo, dir, front);
    let valid = zero.lt(cos_light) & zero.lt(t_max) & zero.lt(cos) & zero.lt(ng.dot(dir));
    let pdf_light = R::select(
        R::splat(0.0).lt(light.pdf_solid_angle),
        light.pdf_solid_angle,
        light.pdf_area * dist2 / cos_light,
    );
    // A delta light: no other strategy finds it (weight 1).
    let w = R::select(
        zero.lt(light.delta),
        R::splat(1.0),
        power_heuristic(pdf_light, pdf_bsdf),
    );
    let scale = w / pdf_light;
    let radiance = V3::new(
        fcos.x * light.emission.x * scale,
        fcos.y * light.emission.y * scale,
        fcos.z * light.emission.z * scale,
    );
    let ray = ShadowRay {
        origin,
        dir,
        t_max,
        radiance: V3::select(valid, radiance, V3::new(zero, zero, zero)),
    };
    (valid, ray)
}

/// The MIS weight of emission found by a scattered ray: the ray left `o`,
/// drawn with density `bsdf_pdf` (0 for a camera ray or a specular bounce:
/// then light sampling could not have found it, and the weight is 1), and
/// hit triangle `triangle` at distance `t`, whose front faces the ray at
/// cosine `cos_light`.
#[inline]
pub fn emission_weight(
    estimator: &Estimator,
    lights: &Lights,
    (bsdf_pdf, o): (f32, V3<f32>),
    triangle: u32,
    t: f32,
    cos_light: f32,
) -> f32 {
    if !estimator.samples_lights() || bsdf_pdf == 0.0 {
        return 1.0;
    }
    let pdf_light = lights.pdf_solid_angle(triangle, o, t, cos_light);
    power_heuristic(bsdf_pdf, pdf_light)
}

/// The radiance a ray of direction `d` that left the scene brings back:
/// the environment's and that of the suns whose cones hold `d` (`None`
/// where there is neither, or for a camera ray — `camera` — unless the
/// scene has a visible environment: a sun's disc is part of the sky, and
/// a transparent background hides it too), each
/// weighted, when the estimator samples lights and the ray was drawn with
/// density `bsdf_pdf > 0`, against its own sampling by the power
/// heuristic.
#[inline]
pub fn escaped(
    estimator: &Estimator,
    lights: &Lights,
    bsdf_pdf: f32,
    d: V3<f32>,
    camera: bool,
) -> Option<V3<f32>> {
    let env = lights.environment();
    if camera && !env.is_some_and(|e| e.visible) {
        return None;
    }
    let mis = estimator.samples_lights() && bsdf_pdf != 0.0;
    let mut seen = if mis {
        (lights.environment_radiance_and_pdf(d)).map(|(l, pdf)| {
            let w = power_heuristic(bsdf_pdf, pdf);
            V3::new(l.x * w, l.y * w, l.z * w)
        })
    } else {
        env.map(|env| env.radiance(d))
    };
    for (l, pdf) in lights.suns_seen(d) {
        let w = if mis {
            power_heuristic(bsdf_pdf, pdf)
        } else {
            1.0
        };
        let sum = seen.unwrap_or(V3::new(0.0, 0.0, 0.0));
        seen = Some(l.mul_add(w, sum));
    }
    seen
}

/// The probability that Russian roulette lets a path of throughput `beta`
/// go on: its largest component, at most 1.
#[inline]
pub fn survival(beta: Vec3) -> f32 {
    beta.max_element().min(1.0)
}
