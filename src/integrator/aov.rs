//! Auxiliary outputs (AOVs) for the denoiser: per pixel, the mean albedo
//! and shading normal at the first non-specular hit (through mirrors and
//! glass), over the pixel's first [`aov_samples`] camera samples.
//!
//! The camera positions are the render's own (the sampler's first two
//! dimensions of each `(pixel, sample)`); the delta bounces after them use
//! the sampler's next numbers. Each pixel sums its samples in index order,
//! on its own, so the buffers are the same bits whatever the thread count.
//! They come from the [reference tracer](ReferenceTracer) (scalar), for
//! either engine's render: both trace the same camera rays.
//!
//! Not (yet) carried in checkpoints or partial files: they are computed in
//! one pass at the end of a render.

use crate::integrator::reference::ReferenceTracer;
use crate::integrator::sampler::Sampler;
use crate::scene::camera::RasterCamera;
use glam::Vec3;
use rayon::prelude::*;

/// At most this many camera samples per pixel go into the AOVs.
pub const MAX_AOV_SAMPLES: u32 = 16;

/// The number of samples per pixel the AOVs of a render of `spp` average:
/// `min(spp, 16)` (at least 1).
pub fn aov_samples(spp: u32) -> u32 {
    spp.clamp(1, MAX_AOV_SAMPLES)
}

/// Albedo and normal buffers, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Aovs {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Mean albedo (linear, in [0, 1]); black where no surface was seen.
    pub albedo: Vec<[f32; 3]>,
    /// Mean facing shading normal (world space; not renormalised, zero
    /// where no surface was seen).
    pub normal: Vec<[f32; 3]>,
}

/// The AOVs of a `width`×`height` image of `camera`, over samples
/// `0..samples` of every pixel, numbers from `sampler`; rows in parallel
/// on the current rayon pool.
pub fn compute<S: Sampler>(
    tracer: &ReferenceTracer,
    camera: &RasterCamera,
    sampler: &S,
    (width, height): (u32, u32),
    samples: u32,
) -> Aovs {
    let n = width as usize * height as usize;
    let mut albedo = vec![[0.0f32; 3]; n];
    let mut normal = vec![[0.0f32; 3]; n];
    let scale = 1.0 / samples.max(1) as f32;
    albedo
        .par_chunks_mut(width as usize)
        .zip(normal.par_chunks_mut(width as usize))
        .enumerate()
        .for_each(|(y, (albedo_row, normal_row))| {
            for x in 0..width {
                let (mut a, mut nn) = (Vec3::ZERO, Vec3::ZERO);
                for sample in 0..samples {
                    let mut path = sampler.start(camera.pixel_index(x, y as u32), sample);
                    let ray = camera.pixel_ray(x, y as u32, sampler.next_2d(&mut path));
                    if let Some((sa, sn)) = tracer.first_surface(sampler, &mut path, ray) {
                        a += sa;
                        nn += sn;
                    }
                }
                albedo_row[x as usize] = (a * scale).to_array();
                normal_row[x as usize] = (nn * scale).to_array();
            }
        });
    Aovs {
        width,
        height,
        albedo,
        normal,
    }
}
