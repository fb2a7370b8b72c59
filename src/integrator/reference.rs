//! The reference tracer: the report's `TracePath`, recursive and scalar.
//!
//! This is the oracle the wavefront engine is tested against, so it stays as
//! plain as the report's pseudocode. With the report's estimator:
//!
//! ```text
//! tracePath(ray, depth):
//!     if depth >= max_depth: return black
//!     hit = closest(ray); if none: return black
//!     new_ray = (hit point, uniform direction on the hemisphere of the normal)
//!     return emittance + (reflectance/π) · tracePath(new_ray, depth+1) · cos θ / (1/2π)
//! ```
//!
//! The other estimators ([`Integrator`]) add to it, in this order at each
//! vertex: emission weighted by multiple importance sampling (`nee`);
//! Russian roulette (with `--rr-depth`); a shadow ray to a point on an
//! emitter (`nee`, when the shadow ray would not exceed the maximum depth);
//! the BSDF-sampled direction (cosine-weighted for `bsdf` and `nee`).
//!
//! Emission is one-sided (towards the triangle's front); reflection is
//! two-sided (the hemisphere is the one the incoming ray came from). New
//! rays start at the hit point moved off its surface by the bound on its
//! rounding ([`crate::integrator::offset`]).
//!
//! Closest hits come from the [`Bvh`] by default; [`ReferenceTracer::with_brute_force`]
//! tests every triangle instead (for tests: both give the same hits, bit for bit).

use crate::accel::bvh::Bvh;
use crate::accel::shape::{
    OwnedShapes, closest_hit_brute_force_filtered, closest_hit_brute_force_shapes,
};
use crate::accel::triangle::Hit;
use crate::film::{AovSample, accumulate};
use crate::integrator::aov::{Vertex, record};
use crate::integrator::bsdf::is_delta;
use crate::integrator::lights::Lights;
use crate::integrator::nee::{
    Estimator, connect_shaded, emission_weight, escaped, survival as survival_of,
};
use crate::integrator::offset::spawn;
use crate::integrator::sampler::Sampler;
use crate::integrator::tables::Tables;
use crate::integrator::{Counters, SceneData, TileJob};
use crate::math::V3;
use crate::scene::aov::When;
use crate::scene::camera::RasterCamera;
use crate::scene::{AovSet, Integrator, Material, Scene};
use glam::Vec3;
use std::sync::Arc;

/// How the tracer finds closest hits.
enum Accel {
    /// Every primitive of every kind, scalar, in index order.
    BruteForce(OwnedShapes),
    /// The bounding volume hierarchy.
    Bvh(Arc<Bvh>),
}

/// The scalar recursive path tracer.
pub struct ReferenceTracer {
    materials: Vec<Material>,
    /// The shapes' columns the surface at a hit is made from.
    tables: Tables,
    accel: Accel,
    estimator: Estimator,
    lights: Lights,
}

impl ReferenceTracer {
    /// A tracer of the report's estimator for `scene`, following paths to
    /// `max_depth`, over a [`Bvh`] built here (on the current rayon pool).
    /// [`with_estimator`](Self::with_estimator) picks another estimator.
    pub fn new(scene: &Scene, max_depth: u32) -> Self {
        Self::with_bvh(
            scene,
            max_depth,
            Arc::new(crate::accel::scene_bvh(scene, &Default::default())),
        )
    }

    /// A tracer over a [`Bvh`] already built from `crate::accel::scene_bvh(scene, ..)`
    /// (so engines can share one).
    pub fn with_bvh(scene: &Scene, max_depth: u32, bvh: Arc<Bvh>) -> Self {
        Self::with_accel(scene, max_depth, Accel::Bvh(bvh))
    }

    /// A tracer that tests every triangle for every ray: slow, and the
    /// plainest possible oracle. Gives the same images as [`ReferenceTracer::new`].
    pub fn with_brute_force(scene: &Scene, max_depth: u32) -> Self {
        Self::with_accel(
            scene,
            max_depth,
            Accel::BruteForce(OwnedShapes::of_scene(scene)),
        )
    }

    /// Rebuild the lights from `scene` (the tracer's scene with another
    /// environment).
    pub fn relight(&mut self, scene: &Scene) {
        self.lights = Lights::new(scene);
    }

    /// Turn the environment to `rotation_deg` ([`Lights::turn_environment`]).
    pub fn turn_environment(&mut self, rotation_deg: f32) {
        self.lights.turn_environment(rotation_deg);
    }

    /// [`with_bvh`](Self::with_bvh) over a scene's prepared tables and
    /// lights ([`SceneData::new`], which can be built beside the
    /// hierarchy).
    pub fn with_data(scene: &Scene, data: SceneData, max_depth: u32, bvh: Arc<Bvh>) -> Self {
        Self {
            accel: Accel::Bvh(bvh),
            tables: data.tables,
            materials: scene.materials.clone(),
            estimator: Estimator::report(max_depth),
            lights: data.lights,
        }
    }

    fn with_accel(scene: &Scene, max_depth: u32, accel: Accel) -> Self {
        Self {
            accel,
            tables: Tables::new(scene),
            materials: scene.materials.clone(),
            estimator: Estimator::report(max_depth),
            lights: Lights::new(scene),
        }
    }

    /// The same tracer with another estimator.
    pub fn with_estimator(mut self, estimator: Estimator) -> Self {
        self.estimator = estimator;
        self
    }

    /// The hierarchy this tracer uses, if any (not in brute-force mode).
    pub fn bvh(&self) -> Option<&Arc<Bvh>> {
        match &self.accel {
            Accel::Bvh(b) => Some(b),
            Accel::BruteForce(..) => None,
        }
    }

    /// The closest hit of the ray `o + t·d` at `t > 0` (rays leave
    /// surfaces from points moved off them: [`crate::integrator::offset`]).
    #[inline]
    pub fn closest_hit(&self, o: Vec3, d: Vec3) -> Option<Hit> {
        self.closest_hit_before(o, d, f32::INFINITY)
    }

    /// The closest hit before `t_max` on a surface that is there: in a
    /// scene with cut-outs, the walk puts each candidate hit on a surface
    /// that may let the ray through to the ray's any-hit filter
    /// ([`Tables::cutouts`]) and goes on past those that pass (brute force
    /// likewise).
    fn closest_hit_before(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
        if self.tables.has_cutouts() {
            let filter = self.tables.cutouts((V3::from(o), V3::from(d)));
            return match &self.accel {
                Accel::Bvh(b) => b.closest_hit_filtered(o, d, (0.0, t_max), &filter),
                Accel::BruteForce(shapes) => closest_hit_brute_force_filtered(
                    &shapes.as_shapes(),
                    o,
                    d,
                    (0.0, t_max),
                    &filter,
                ),
            };
        }
        match &self.accel {
            Accel::Bvh(b) => b.closest_hit(o, d, 0.0, t_max),
            Accel::BruteForce(shapes) => {
                closest_hit_brute_force_shapes(&shapes.as_shapes(), o, d, 0.0, t_max)
            }
        }
    }

    /// The radiance arriving at `o` from direction `-d`, for a ray at
    /// `depth` (camera rays are depth 0), with the path's numbers drawn
    /// from `sampler` at `path`. `counters` counts the rays cast.
    pub fn trace_path<S: Sampler>(
        &self,
        sampler: &S,
        path: &mut S::Path,
        ray: (Vec3, Vec3),
        depth: u32,
        counters: &mut Counters,
    ) -> Vec3 {
        self.trace(sampler, path, ray, depth, (0.0, Vec3::ONE), counters, None)
    }

    /// [`trace_path`](Self::trace_path) of a camera ray (depth 0) that
    /// also records the sample's AOVs in `aov` ([`super::aov`]), for a
    /// camera looking along `forward`: those of the camera ray's hit, and
    /// those of the path's first non-specular vertex (left as they are
    /// where there is none).
    pub fn trace_camera_path<S: Sampler>(
        &self,
        sampler: &S,
        path: &mut S::Path,
        ray: (Vec3, Vec3),
        counters: &mut Counters,
        (aov, forward): (&mut AovSample, Vec3),
    ) -> Vec3 {
        let aov = Some((aov, forward));
        self.trace(sampler, path, ray, 0, (0.0, Vec3::ONE), counters, aov)
    }

    /// [`trace_path`](Self::trace_path) for a ray drawn with density
    /// `bsdf_pdf` (0 for camera rays), by a path of throughput `beta` so
    /// far (what Russian roulette looks at). `aov`, while the path has met
    /// only specular vertices, is where the AOVs of the sample go, with
    /// the camera's forward axis (`None` once recorded, or when not asked
    /// for).
    #[allow(clippy::too_many_arguments)]
    fn trace<S: Sampler>(
        &self,
        sampler: &S,
        path: &mut S::Path,
        (o, d): (Vec3, Vec3),
        depth: u32,
        (bsdf_pdf, beta): (f32, Vec3),
        counters: &mut Counters,
        mut aov: Option<(&mut AovSample, Vec3)>,
    ) -> Vec3 {
        let est = &self.estimator;
        if depth >= est.max_depth {
            return Vec3::ZERO;
        }
        counters.rays += 1;
        let Some(hit) = self.closest_hit(o, d) else {
            let seen = escaped(est, &self.lights, bsdf_pdf, V3::from(d), depth == 0);
            return seen.map_or(Vec3::ZERO, Vec3::from);
        };
        // The surface, once: seen from the front it emits; either side
        // reflects.
        let s = self
            .tables
            .surface(hit.triangle as usize, (V3::from(o), V3::from(d)), hit.t);
        let material = &self.materials[s.material as usize];
        // A ray that crossed an absorbing solid from inside: its
        // transmittance weighs everything from here on.
        let absorbed = self.tables.transmittance(&s, hit.t).map(Vec3::from);
        let beta = absorbed.map_or(beta, |a| beta * a);
        // AOVs: at the camera ray's hit; at the first non-specular vertex.
        if let Some((a, forward)) = aov.as_mut() {
            let ray = (V3::from(o), V3::from(d));
            let v = Vertex::new(&self.tables, hit.triangle, ray, hit.t, *forward).with_surface(s);
            if depth == 0 {
                record(AovSet::EVERY, When::CameraHit, &v, a);
            }
            if !is_delta(material.model) {
                record(AovSet::EVERY, When::FirstNonSpecular, &v, a);
                aov = None;
            }
        }
        let mut radiance = if s.front {
            let cos_light = -Vec3::from(s.ng).dot(d);
            let w = emission_weight(
                est,
                &self.lights,
                (bsdf_pdf, V3::from(o)),
                hit.triangle,
                hit.t,
                cos_light,
            );
            Vec3::from(self.tables.emission_at(s.material, s.uv)) * w
        } else {
            Vec3::ZERO
        };
        if depth + 1 >= est.max_depth {
            return radiance; // the next ray would exceed the maximum depth
        }

        let p = Vec3::from(s.p);
        let surface = self.tables.scattering(&s);
        let mut beta = beta;
        let mut survival = 1.0;
        if let Some(u) = est.roulette_number(sampler, path, depth) {
            survival = survival_of(beta);
            if u >= survival {
                return radiance;
            }
            beta /= survival;
        }
        if est.samples_lights() && is_delta(material.model) {
            est.skip_light_numbers(sampler, path);
        } else if est.samples_lights() {
            let u = est.light_numbers(sampler, path);
            if let Some(mut light) = self.lights.sample(V3::from(p), u) {
                if self.tables.has_emissive_maps()
                    && let Some(e) = self
                        .tables
                        .light_emission(light.prim.to_bits(), light.point)
                {
                    light.emission = V3::new(e[0], e[1], e[2]);
                }
                let vertex = (s.p, s.n, s.ns, V3::from(-d));
                let (valid, shadow) = connect_shaded(&light, s.err, vertex, s.front, &surface);
                if valid {
                    counters.rays += 1;
                    counters.shadow_rays += 1;
                    let (from, dir) = (Vec3::from(shadow.origin), Vec3::from(shadow.dir));
                    if self.closest_hit_before(from, dir, shadow.t_max).is_none() {
                        radiance += Vec3::from(shadow.radiance) / survival;
                    }
                }
            }
        }
        let (_lobe, u) = est.bsdf_numbers(sampler, path);
        let report = est.integrator == Integrator::Report;
        let hit = (s.front, s.n, s.ns);
        let leave = (s.p, s.ng, s.err);
        let s = surface.sample_shaded(hit, V3::from(d), u, report);
        // A delta direction has no density: light sampling could not have
        // found what it hits (MIS weight 1).
        let pdf = surface.mis_pdf(&s, hit.1);
        let next_beta = Vec3::from(s.weigh(V3::from(beta)));
        let from = Vec3::from(spawn(leave.0, leave.1, s.wi, leave.2));
        let incoming = self.trace(
            sampler,
            path,
            (from, Vec3::from(s.wi)),
            depth + 1,
            (pdf, next_beta),
            counters,
            aov,
        );
        let radiance = radiance + Vec3::from(s.f) * incoming * s.cos / s.pdf / survival;
        absorbed.map_or(radiance, |a| radiance * a)
    }

    /// One camera sample of pixel `(x, y)`: jittered uniformly over the
    /// pixel's area, traced from depth 0.
    pub fn sample<S: Sampler>(
        &self,
        camera: &RasterCamera,
        sampler: &S,
        (x, y): (u32, u32),
        sample: u32,
        counters: &mut Counters,
    ) -> Vec3 {
        let mut path = sampler.start(camera.pixel_index(x, y), sample);
        let ray = camera.pixel_ray(x, y, sampler.next_2d(&mut path));
        self.trace_path(sampler, &mut path, ray, 0, counters)
    }

    /// [`sample`](Self::sample), with the sample's AOVs
    /// ([`trace_camera_path`](Self::trace_camera_path)).
    pub fn sample_with_aovs<S: Sampler>(
        &self,
        camera: &RasterCamera,
        sampler: &S,
        (x, y): (u32, u32),
        sample: u32,
        counters: &mut Counters,
    ) -> (Vec3, AovSample) {
        let mut path = sampler.start(camera.pixel_index(x, y), sample);
        let ray = camera.pixel_ray(x, y, sampler.next_2d(&mut path));
        let mut aov = AovSample::NONE;
        let forward = camera.forward();
        let l = self.trace_camera_path(sampler, &mut path, ray, counters, (&mut aov, forward));
        (l, aov)
    }

    /// Render a tile: every sample of every pixel, one path at a time
    /// (with its AOVs when the render accumulates them).
    pub fn render_tile<S: Sampler>(&self, sampler: &S, job: &mut TileJob) -> Counters {
        let mut c = Counters::default();
        let aovs = job.has_aovs();
        for pixel in job.pixels.clone() {
            if !job.is_active(pixel) {
                continue;
            }
            let xy = job.xy(pixel);
            for sample in job.samples.clone() {
                let camera = &job.frame.camera;
                let valid = if aovs {
                    let (l, aov) = self.sample_with_aovs(camera, sampler, xy, sample, &mut c);
                    job.add_sample(pixel, l, &aov)
                } else {
                    let l = self.sample(camera, sampler, xy, sample, &mut c);
                    accumulate(job.sum_of(pixel), l)
                };
                c.paths += 1;
                if !valid {
                    c.invalid_samples += 1;
                }
            }
        }
        c
    }
}
