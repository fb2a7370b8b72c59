//! The wavefront engine: paths move in batches through four stages.
//!
//! For each batch of (pixel, sample) pairs:
//!
//! 1. [`generate`](generate::generate) camera rays into a [`PathQueue`];
//! 2. then, once per depth: [`intersect`](intersect::intersect) every ray
//!    (8 triangles at a time), [`shade`](shade::shade) (emission; retire
//!    the paths that escaped or are done), and [`bounce`](bounce::bounce)
//!    (compact the live paths into bins by material, then each bin's pass:
//!    next direction and throughput, 8 paths at a time).
//!
//! Threads take tiles of pixels; a tile's batches own their queues and
//! write the tile's pixel sums without locks. Every number a path draws comes
//! from its own `(seed, pixel, sample)` stream and the film's sums are
//! exact integers, so the image is the same whatever the thread count,
//! the batch size or the schedule.

pub mod bounce;
pub mod generate;
pub mod intersect;
pub mod queue;
pub mod shade;

use crate::accel::bvh::Bvh;
use crate::film::PixelSum;
use crate::render::{Counters, StageSeconds};
use crate::scene::Scene;
use crate::scene::camera::RasterCamera;
use queue::PathQueue;
use std::f32::consts::PI;
use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

/// The scene as the stages read it: the hierarchy and per-triangle
/// shading data.
pub struct World {
    /// The bounding volume hierarchy over the triangles.
    pub bvh: Arc<Bvh>,
    /// Front-side unit normal of each triangle: x, y, z columns.
    pub normals: [Vec<f32>; 3],
    /// Material index of each triangle.
    pub material_of: Vec<u32>,
    /// Emitted radiance of each material.
    pub emission: Vec<[f32; 3]>,
    /// `reflectance / π` of each triangle's material: R, G, B columns.
    pub brdf: [Vec<f32>; 3],
    /// Smallest hit distance (see [`Scene::ray_epsilon`]).
    pub epsilon: f32,
}

impl World {
    /// Prepare `scene`, whose hierarchy is `bvh`, for the stages.
    pub fn new(scene: &Scene, bvh: Arc<Bvh>) -> Self {
        Self {
            bvh,
            normals: [0, 1, 2].map(|c| scene.triangles.iter().map(|t| t.normal[c]).collect()),
            material_of: scene.triangles.iter().map(|t| t.material).collect(),
            emission: scene
                .materials
                .iter()
                .map(|m| m.emission.to_array())
                .collect(),
            brdf: [0, 1, 2].map(|c| {
                let brdf = |t: &crate::scene::Triangle| {
                    scene.materials[t.material as usize].reflectance / PI
                };
                scene.triangles.iter().map(|t| brdf(t)[c]).collect()
            }),
            epsilon: scene.ray_epsilon(),
        }
    }
}

/// Per-thread working memory: the queue and room for the hierarchy's
/// batched queries.
pub struct Scratch {
    queue: PathQueue,
    rays: intersect::RayBatch,
}

impl Scratch {
    /// Room for batches of `batch_size` paths.
    pub fn new(batch_size: usize) -> Self {
        Self {
            queue: PathQueue::with_capacity(batch_size),
            rays: intersect::RayBatch::default(),
        }
    }
}

/// The wavefront path tracer.
pub struct WavefrontEngine {
    world: World,
    max_depth: u32,
}

impl WavefrontEngine {
    /// An engine for `scene` following paths to `max_depth`, tracing rays
    /// against `bvh` (built from `crate::accel::scene_triangles(scene)`).
    pub fn new(scene: &Scene, max_depth: u32, bvh: Arc<Bvh>) -> Self {
        Self {
            world: World::new(scene, bvh),
            max_depth,
        }
    }

    /// Trace samples `samples` of the pixels `tile` (row-major indices,
    /// whose sums are `sums`), at most `batch_size` paths at a time.
    #[allow(clippy::too_many_arguments)]
    pub fn render_tile(
        &self,
        scratch: &mut Scratch,
        camera: &RasterCamera,
        width: u32,
        seed: u64,
        tile: Range<u32>,
        samples: Range<u32>,
        batch_size: usize,
        sums: &mut [PixelSum],
    ) -> Counters {
        let mut counters = Counters::default();
        let spp = samples.end - samples.start;
        // Whole pixels per batch when they fit; otherwise split the samples.
        // (`saturating_add`: ranges may end at u32::MAX.)
        let batch = u32::try_from(batch_size).unwrap_or(u32::MAX);
        let pixels_per_batch = (batch / spp.max(1)).max(1);
        let samples_per_batch = spp.min(batch).max(1);
        let mut pixel = tile.start;
        while pixel < tile.end {
            let pixels = pixel..pixel.saturating_add(pixels_per_batch).min(tile.end);
            let mut s = samples.start;
            while s < samples.end {
                let batch_samples = s..s.saturating_add(samples_per_batch).min(samples.end);
                self.render_batch(
                    scratch,
                    camera,
                    width,
                    seed,
                    pixels.clone(),
                    batch_samples.clone(),
                    tile.start,
                    sums,
                    &mut counters,
                );
                s = batch_samples.end;
            }
            pixel = pixels.end;
        }
        counters
    }

    /// One batch through all the stages, depth by depth.
    #[allow(clippy::too_many_arguments)]
    fn render_batch(
        &self,
        scratch: &mut Scratch,
        camera: &RasterCamera,
        width: u32,
        seed: u64,
        pixels: Range<u32>,
        samples: Range<u32>,
        tile_start: u32,
        sums: &mut [PixelSum],
        counters: &mut Counters,
    ) {
        let Scratch { queue, rays } = scratch;
        let clock = Instant::now();
        generate::generate(queue, camera, width, seed, pixels, samples);
        counters.paths += queue.len() as u64;
        let mut stages = StageSeconds {
            generate: clock.elapsed().as_secs_f64(),
            ..StageSeconds::default()
        };

        for depth in 0..self.max_depth {
            if queue.is_empty() {
                break;
            }
            let clock = Instant::now();
            counters.rays += queue.len() as u64;
            intersect::intersect(queue, &self.world, rays);
            let t1 = Instant::now();
            let last = depth + 1 >= self.max_depth;
            counters.invalid_samples += shade::shade(queue, &self.world, last, tile_start, sums);
            let t2 = Instant::now();
            if last {
                queue.set_len(0);
            } else {
                bounce::bounce(queue, &self.world);
            }
            let t3 = Instant::now();
            stages.intersect += (t1 - clock).as_secs_f64();
            stages.shade += (t2 - t1).as_secs_f64();
            stages.bounce += (t3 - t2).as_secs_f64();
        }
        counters.stages += stages;
    }
}
