//! The reference tracer: the report's `TracePath`, recursive and scalar.
//!
//! This is the oracle the wavefront engine is tested against, so it stays as
//! plain as the report's pseudocode:
//!
//! ```text
//! tracePath(ray, depth):
//!     if depth >= max_depth: return black
//!     hit = closest(ray); if none: return black
//!     new_ray = (hit point, uniform direction on the hemisphere of the normal)
//!     return emittance + (reflectance/π) · tracePath(new_ray, depth+1) · cos θ / (1/2π)
//! ```
//!
//! Emission is one-sided (towards the triangle's front); reflection is
//! two-sided (the hemisphere is the one the incoming ray came from).
//!
//! Closest hits come from the [`Bvh`] by default; [`ReferenceTracer::with_brute_force`]
//! tests every triangle instead (for tests: both give the same hits, bit for bit).

use crate::accel::bvh::Bvh;
use crate::accel::triangle::{Hit, TriangleEdges, closest_hit_brute_force, hit_point};
use crate::film::accumulate;
use crate::integrator::bsdf::{diffuse, facing};
use crate::integrator::sampler::Sampler;
use crate::integrator::{Counters, TileJob};
use crate::math::V3;
use crate::scene::Scene;
use crate::scene::camera::RasterCamera;
use glam::Vec3;
use std::f32::consts::PI;
use std::sync::Arc;

/// How the tracer finds closest hits.
enum Accel {
    /// Every triangle, scalar, in index order.
    BruteForce(Vec<TriangleEdges>),
    /// The bounding volume hierarchy.
    Bvh(Arc<Bvh>),
}

/// The scalar recursive path tracer.
pub struct ReferenceTracer {
    scene: Scene,
    accel: Accel,
    epsilon: f32,
    max_depth: u32,
}

impl ReferenceTracer {
    /// A tracer for `scene` that follows paths to `max_depth`, over a
    /// [`Bvh`] built here (on the current rayon pool).
    pub fn new(scene: &Scene, max_depth: u32) -> Self {
        Self::with_bvh(
            scene,
            max_depth,
            Arc::new(Bvh::build(&crate::accel::scene_triangles(scene))),
        )
    }

    /// A tracer over a [`Bvh`] already built from `crate::accel::scene_triangles(scene)`
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
            Accel::BruteForce(crate::accel::scene_triangles(scene)),
        )
    }

    fn with_accel(scene: &Scene, max_depth: u32, accel: Accel) -> Self {
        Self {
            accel,
            epsilon: scene.ray_epsilon(),
            scene: scene.clone(),
            max_depth,
        }
    }

    /// The hierarchy this tracer uses, if any (not in brute-force mode).
    pub fn bvh(&self) -> Option<&Arc<Bvh>> {
        match &self.accel {
            Accel::Bvh(b) => Some(b),
            Accel::BruteForce(_) => None,
        }
    }

    /// The closest hit of the ray `o + t·d` beyond the scene's epsilon.
    #[inline]
    pub fn closest_hit(&self, o: Vec3, d: Vec3) -> Option<Hit> {
        match &self.accel {
            Accel::Bvh(b) => b.closest_hit(o, d, self.epsilon, f32::INFINITY),
            Accel::BruteForce(e) => closest_hit_brute_force(e, o, d, self.epsilon, f32::INFINITY),
        }
    }

    /// The radiance arriving at `o` from direction `-d`, for a ray at
    /// `depth` (camera rays are depth 0), with the path's numbers drawn
    /// from `sampler` at `path`. `rays` counts the rays cast.
    pub fn trace_path<S: Sampler>(
        &self,
        sampler: &S,
        path: &mut S::Path,
        (o, d): (Vec3, Vec3),
        depth: u32,
        rays: &mut u64,
    ) -> Vec3 {
        if depth >= self.max_depth {
            return Vec3::ZERO;
        }
        *rays += 1;
        let Some(hit) = self.closest_hit(o, d) else {
            return Vec3::ZERO;
        };
        let triangle = &self.scene.triangles[hit.triangle as usize];
        let material = &self.scene.materials[triangle.material as usize];

        // Seen from the front, the surface emits; either side reflects.
        let (front, normal) = facing(V3::from(triangle.normal), V3::from(d));
        let emittance = if front { material.emission } else { Vec3::ZERO };

        let new_origin = Vec3::from(hit_point(V3::from(o), V3::from(d), hit.t));
        let brdf = V3::from(material.reflectance / PI);
        let s = diffuse::sample_uniform(normal, brdf, sampler.next_2d(path));
        let incoming = self.trace_path(
            sampler,
            path,
            (new_origin, Vec3::from(s.wi)),
            depth + 1,
            rays,
        );
        emittance + Vec3::from(s.f) * incoming * s.cos / s.pdf
    }

    /// One camera sample of pixel `(x, y)`: jittered uniformly over the
    /// pixel's area, traced from depth 0.
    pub fn sample<S: Sampler>(
        &self,
        camera: &RasterCamera,
        sampler: &S,
        (x, y): (u32, u32),
        sample: u32,
        rays: &mut u64,
    ) -> Vec3 {
        let mut path = sampler.start(camera.pixel_index(x, y), sample);
        let ray = camera.pixel_ray(x, y, sampler.next_2d(&mut path));
        self.trace_path(sampler, &mut path, ray, 0, rays)
    }

    /// Render a tile: every sample of every pixel, one path at a time.
    pub fn render_tile<S: Sampler>(&self, sampler: &S, job: &mut TileJob) -> Counters {
        let mut c = Counters::default();
        for pixel in job.pixels.clone() {
            let xy = job.xy(pixel);
            for sample in job.samples.clone() {
                let l = self.sample(&job.frame.camera, sampler, xy, sample, &mut c.rays);
                c.paths += 1;
                if !accumulate(job.sum_of(pixel), l) {
                    c.invalid_samples += 1;
                }
            }
        }
        c
    }
}
