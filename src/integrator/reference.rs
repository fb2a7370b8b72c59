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
use crate::integrator::sampler::{PathRng, uniform_hemisphere};
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
    /// `depth` (camera rays are depth 0). `rays` counts the rays cast.
    pub fn trace_path(
        &self,
        o: Vec3,
        d: Vec3,
        depth: u32,
        rng: &mut PathRng,
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
        let front = V3::from(d).dot(V3::from(triangle.normal)) < 0.0;
        let emittance = if front { material.emission } else { Vec3::ZERO };
        let normal = if front {
            triangle.normal
        } else {
            -triangle.normal
        };

        let new_origin = Vec3::from(hit_point(V3::from(o), V3::from(d), hit.t));
        let (x1, x2) = (rng.next_f32(), rng.next_f32());
        let new_dir = Vec3::from(uniform_hemisphere(V3::from(normal), x1, x2));

        let probability = 1.0 / (2.0 * PI);
        // cos θ = X1 by construction; dot(new_dir, normal) equals it up to
        // rounding, which can make it -1e-7 and a sample negative.
        let cos_theta = x1;
        let brdf = material.reflectance / PI;
        let incoming = self.trace_path(new_origin, new_dir, depth + 1, rng, rays);
        emittance + brdf * incoming * cos_theta / probability
    }

    /// One camera sample of pixel `(x, y)`: jittered uniformly over the
    /// pixel's area, traced from depth 0.
    pub fn sample(
        &self,
        camera: &RasterCamera,
        seed: u64,
        (x, y): (u32, u32),
        sample: u32,
        rays: &mut u64,
    ) -> Vec3 {
        let mut rng = PathRng::new(seed, camera.pixel_index(x, y), sample);
        let (o, d) = camera.jittered_ray(&mut rng, x, y);
        self.trace_path(o, d, 0, &mut rng, rays)
    }
}
