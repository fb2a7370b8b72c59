//! Auxiliary outputs (AOVs): what each one is, per camera sample.
//!
//! A render asks for any of them with `--aov albedo,normal,depth,variance`
//! ([`AovSet`]; `--denoise` implies albedo and
//! normal). An AOV is its row in [`Aov::def`] (its name, when a path
//! records it, how its samples are summed, how it is written) and its arm
//! of [`value`] here (what it records): adding one touches those two.
//! Each sample of a pixel records them along its own path, and
//! the film sums them exactly, beside the radiance ([`crate::film::aov`]),
//! so they are the same bits whatever the threads, batches, passes,
//! resumes and shards. Both engines record them, each in its own code:
//!
//! - the [reference tracer](super::reference) in its recursion, at the
//!   vertex where the definition says;
//! - the [wavefront engine](super::wavefront): the path queue has AOV
//!   columns (when a render asks for AOVs), filled in the *shade* stage
//!   (`shade::record_aovs`) and added to the film with the radiance in
//!   *retire*.
//!
//! Both call [`record`] at those vertices, so the values are the same
//! function of the same hit.
//!
//! **Definitions.** A path's *vertices* are the surfaces its rays hit, the
//! camera ray's hit being depth 0, up to the last depth the maximum depth
//! allows (the hit there is a vertex even though the path scatters no
//! further).
//!
//! - **albedo**: at the path's first *non-specular* vertex (a material
//!   whose model is not a delta lobe: diffuse or metal; mirrors and glass
//!   are followed, in the direction the path itself sampled there, as OIDN
//!   expects), the material's reflectance times its base colour texture
//!   and vertex colours there, clamped to [0, 1]
//!   ([`Tables::albedo_at`]).
//!   Lights count as surfaces (their reflectance). A path with no
//!   non-specular vertex — it escapes first, or reaches the maximum depth
//!   (or is ended by Russian roulette) while every vertex so far was
//!   specular — records zero. The image is the mean over *all* the
//!   pixel's samples (zeros included): in [0, 1].
//! - **normal**: at that same vertex, the shading normal facing the ray as
//!   the shading code uses it: the interpolated vertex normal of a smooth
//!   triangle (else the geometric normal, or a sphere's radius), on the
//!   side the ray arrived from ([`shading_facing`](super::bsdf::shading_facing)).
//!   World space; zero where there is no such vertex; the mean is not
//!   renormalised (its length drops below 1 at edges and where some
//!   samples saw nothing).
//! - **depth**: the camera ray's hit distance `t` (world units along the
//!   unit ray direction, from the camera's origin), whatever the surface.
//!   The image is the mean over the samples whose camera ray hit something
//!   (the film keeps a hit count per pixel), and `+inf` where none did.
//! - **alpha**: whether the camera ray hit something (a surface that
//!   cut-outs let through is not a hit: the ray goes on behind it); the
//!   image is the fraction of the pixel's samples that hit, exactly
//!   `hits / n`. The engines record no column of their own for it: a
//!   sample hit when its depth is below `+inf`.
//! - **zdepth**: the camera ray's hit distance along the camera's forward
//!   axis, `t · (d · forward)` ([`zdepth`]): the `z` of the hit point in
//!   camera space (what OpenCV and NeRF datasets call depth), where
//!   `depth` is the distance along the ray. Mean over the samples that
//!   hit, `+inf` where none did, like depth.
//! - **object_id**: the id of the object the camera ray hit (0 for none;
//!   ids and names are the scene's [`Objects`](crate::scene::Objects));
//!   the image is the id most of the pixel's samples saw, the misses
//!   voting for 0, a tie going to the smallest id — from exact per-id
//!   counts, so the same whatever the split of the samples.
//! - **variance**: the per-pixel, per-channel unbiased sample variance of
//!   the radiance samples, `s² = (Σx² − (Σx)²/n) / (n − 1)` (0 for
//!   `n < 2`), from exact sums of the samples and of their squares (see
//!   [`crate::film::aov`]). Samples refused as invalid count as 0, as in
//!   the image. It is the variance of one sample: the variance of the
//!   pixel's mean is `s² / n`.
//!
//! The camera rays, hits, specular directions and so the albedo, normal
//! and depth are the same bits in both engines; the variance follows the
//! radiance, which the engines sum in a different order within a path
//! (a few ulps apart).

use super::surface::SurfaceHit;
use super::tables::Tables;
pub use crate::film::AovSample;
use crate::math::V3;
use crate::scene::aov::When;
use crate::scene::{Aov, AovSet};
use glam::Vec3;
use std::cell::OnceCell;

/// A vertex of a path where AOVs are recorded: the ray `(o, d)` that hit
/// primitive `prim` at distance `t`, and its surface, made when an AOV
/// first asks for it.
pub struct Vertex<'a> {
    tables: &'a Tables,
    prim: u32,
    ray: (V3<f32>, V3<f32>),
    t: f32,
    /// The camera's forward axis (the zdepth's).
    forward: Vec3,
    surface: OnceCell<SurfaceHit<f32>>,
}

impl<'a> Vertex<'a> {
    /// The vertex where `ray` hits primitive `prim` at distance `t`, in a
    /// render whose camera looks along `forward`.
    pub fn new(
        tables: &'a Tables,
        prim: u32,
        ray: (V3<f32>, V3<f32>),
        t: f32,
        forward: Vec3,
    ) -> Self {
        Self {
            tables,
            prim,
            ray,
            t,
            forward,
            surface: OnceCell::new(),
        }
    }

    /// [`Vertex::new`] with the surface already made (by
    /// [`Tables::surface`] of the same hit).
    pub fn with_surface(self, surface: SurfaceHit<f32>) -> Self {
        Self {
            surface: OnceCell::from(surface),
            ..self
        }
    }

    fn surface(&self) -> &SurfaceHit<f32> {
        (self.surface).get_or_init(|| self.tables.surface(self.prim as usize, self.ray, self.t))
    }
}

/// The value AOV `aov` records at vertex `v` (the vertex its
/// [`When`] names), as the definitions above say; an id is the bits of
/// the first channel. The variance records nothing (the film makes it).
#[inline]
pub fn value(aov: Aov, v: &Vertex) -> [f32; 3] {
    let one = |x: f32| [x, 0.0, 0.0];
    match aov {
        Aov::Albedo => v.tables.albedo_at(v.surface()),
        Aov::Normal => {
            let n = v.surface().ns;
            [n.x, n.y, n.z]
        }
        Aov::Depth => one(v.t),
        Aov::Alpha => one(1.0),
        Aov::ZDepth => one(zdepth(v.t, Vec3::from(v.ray.1), v.forward)),
        Aov::ObjectId => one(f32::from_bits(v.tables.object_of(v.prim))),
        Aov::Variance => aov.def().none,
    }
}

/// Record in `sample` the values at `v` of the AOVs of `aovs` recorded
/// `when`.
#[inline]
pub fn record(aovs: AovSet, when: When, v: &Vertex, sample: &mut AovSample) {
    for aov in aovs.iter().filter(|a| a.def().when == when) {
        sample.set(aov, value(aov, v));
    }
}

/// The zdepth AOV of a camera ray of unit direction `d` that hit at
/// distance `t`: the hit's distance along the camera's unit `forward`
/// axis, `t · (d · forward)` (the same operations in both engines).
#[inline]
pub fn zdepth(t: f32, d: Vec3, forward: Vec3) -> f32 {
    t * d.dot(forward)
}
