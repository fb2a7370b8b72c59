//! The wavefront engine: paths move in batches through named stages.
//!
//! For each batch of (pixel, sample) pairs, *generate* camera rays into a
//! path queue (one plain column per field), then once per depth:
//!
//! 1. *intersect*: the closest hit of every ray (8 triangles at a time);
//! 2. *shade*: the absorption of a path that crossed an absorbing solid
//!    (`KHR_materials_volume`'s attenuation), the emission each path sees
//!    (and, when the render asks for AOVs, what they record at the hit:
//!    [`crate::integrator::aov`]);
//! 3. *retire*: paths that escaped, reached the maximum depth or lost at
//!    Russian roulette go into the film (with their AOVs) and leave the
//!    queue;
//! 4. *sort*: the live paths grouped by the material model they hit (a
//!    scene of one model skips it);
//! 5. *light* (next-event estimation only): a point on an emitter for
//!    every live path at a non-delta surface, and a shadow ray towards it;
//! 6. *shadow*: the shadow rays tested for occlusion (any hit); those that
//!    arrive add their light;
//! 7. *bounce*: each model's paths scatter with its routine: next
//!    direction and throughput, 8 paths at a time.
//!
//! Each stage is one file of this module and one [`Stage`] in the timings;
//! each reads what no stage changes (the sampler, the estimator, the
//! scene's tables and lights, the hierarchy) from one [`Ctx`].
//! [`WavefrontEngine::render_tile`]'s depth loop reads as the list above.
//!
//! Threads take tiles of pixels; a tile's batches own their queues and
//! write the tile's pixel sums without locks. Every number a path draws is
//! a function of `(seed, pixel, sample, dimension)` and the film's sums are
//! exact integers, so the image is the same whatever the thread count,
//! the batch size or the schedule.

pub(crate) mod bounce;
pub(crate) mod generate;
pub(crate) mod intersect;
pub(crate) mod light;
pub(crate) mod queue;
pub(crate) mod retire;
pub(crate) mod shade;
pub(crate) mod shadow;
pub(crate) mod sort;

use crate::accel::bvh::Bvh;
use crate::integrator::lights::Lights;
use crate::integrator::nee::Estimator;
use crate::integrator::sampler::Sampler;
use crate::integrator::tables::Tables;
use crate::integrator::{Counters, SceneData, Stage, TileJob};
use crate::scene::{AovSet, Scene};
use queue::PathQueue;
use std::ops::Range;
use std::sync::Arc;

/// Per-thread working memory: the path queue and the shadow rays.
pub struct Scratch<P> {
    queue: PathQueue<P>,
    shadows: shadow::ShadowQueue,
}

impl<P: bytemuck::Pod> Scratch<P> {
    /// Room for batches of `batch_size` paths, with the queue columns the
    /// AOVs `aovs` need.
    pub fn new(batch_size: usize, aovs: AovSet) -> Self {
        Self {
            queue: PathQueue::with_aovs(batch_size, aovs),
            shadows: shadow::ShadowQueue::default(),
        }
    }
}

/// What the stages of a render read and never change: where the numbers
/// come from, the estimator, the scene as tables and lights, and the
/// hierarchy. One value per batch, passed to every stage.
pub struct Ctx<'a, S> {
    /// The numbers of every path.
    pub sampler: &'a S,
    /// What a path does at a vertex: integrator, depths, roulette.
    pub est: &'a Estimator,
    /// The scene's primitives and materials, as columns.
    pub tables: &'a Tables,
    /// The emitters, for light sampling and MIS weights.
    pub lights: &'a Lights,
    /// The closest-hit and any-hit queries.
    pub bvh: &'a Bvh,
}

/// The wavefront path tracer.
pub struct WavefrontEngine {
    tables: Tables,
    lights: Lights,
    bvh: Arc<Bvh>,
    estimator: Estimator,
}

impl WavefrontEngine {
    /// An engine for `scene` tracing paths by `estimator`, against `bvh`
    /// (built from [`crate::accel::scene_triangles`]).
    pub fn new(scene: &Scene, estimator: Estimator, bvh: Arc<Bvh>) -> Self {
        Self::with_data(SceneData::new(scene), estimator, bvh)
    }

    /// An engine over a scene's prepared tables and lights
    /// ([`SceneData::new`], which can be built beside the hierarchy).
    pub fn with_data(data: SceneData, estimator: Estimator, bvh: Arc<Bvh>) -> Self {
        Self {
            tables: data.tables,
            lights: data.lights,
            bvh,
            estimator,
        }
    }

    /// Rebuild the lights from `scene` (the engine's scene with another
    /// environment).
    pub fn relight(&mut self, scene: &Scene) {
        self.lights = Lights::new(scene);
    }

    /// Turn the environment to `rotation_deg` ([`Lights::turn_environment`]).
    pub fn turn_environment(&mut self, rotation_deg: f32) {
        self.lights.turn_environment(rotation_deg);
    }

    /// Render a tile's active pixels ([`TileJob::is_active`]), at most
    /// `frame.batch_size` paths at a time: whole pixels per batch when
    /// they fit, else the pixel's samples split.
    pub fn render_tile<S: Sampler>(
        &self,
        sampler: &S,
        scratch: &mut Scratch<S::Path>,
        job: &mut TileJob,
    ) -> Counters {
        let mut counters = Counters::default();
        let spp = job.samples.end - job.samples.start;
        // (`saturating_add`: ranges may end at u32::MAX.)
        let batch = u32::try_from(job.frame.batch_size).unwrap_or(u32::MAX);
        let pixels_per_batch = (batch / spp.max(1)).max(1) as usize;
        let samples_per_batch = spp.min(batch).max(1);
        let active: Vec<u32> = (job.pixels.clone()).filter(|&p| job.is_active(p)).collect();
        for pixels in active.chunks(pixels_per_batch) {
            let mut s = job.samples.start;
            while s < job.samples.end {
                let samples = s..s.saturating_add(samples_per_batch).min(job.samples.end);
                self.render_batch(
                    sampler,
                    scratch,
                    job,
                    (pixels, samples.clone()),
                    &mut counters,
                );
                s = samples.end;
            }
        }
        counters
    }

    /// One batch through all the stages, depth by depth.
    fn render_batch<S: Sampler>(
        &self,
        sampler: &S,
        scratch: &mut Scratch<S::Path>,
        job: &mut TileJob,
        (pixels, samples): (&[u32], Range<u32>),
        counters: &mut Counters,
    ) {
        let Scratch { queue, shadows } = scratch;
        let ctx = Ctx {
            sampler,
            est: &self.estimator,
            tables: &self.tables,
            lights: &self.lights,
            bvh: &self.bvh,
        };
        let time = &mut counters.stages;
        time.time(Stage::Generate, || {
            generate::generate(queue, &ctx, job.frame, pixels, samples)
        });
        counters.paths += queue.len() as u64;
        for depth in 0..ctx.est.max_depth {
            if queue.is_empty() {
                break;
            }
            let last = depth + 1 == ctx.est.max_depth;
            counters.rays += queue.len() as u64;
            time.time(Stage::Intersect, || intersect::intersect(queue, &ctx));
            time.time(Stage::Shade, || {
                shade::absorb(queue, ctx.tables);
                shade::shade(queue, &ctx);
                if ctx.lights.sees_escapes() {
                    shade::shade_escaped(queue, &ctx, depth);
                }
                shade::record_aovs(queue, ctx.tables, depth, job.frame.camera.forward());
            });
            counters.invalid_samples += time.time(Stage::Retire, || {
                retire::retire(queue, &ctx, depth, last, job)
            });
            if last {
                continue;
            }
            let bins = time.time(Stage::Sort, || sort::sort_by_model(queue, ctx.tables));
            if ctx.est.samples_lights() {
                time.time(Stage::Light, || {
                    light::sample_lights(queue, &bins, &ctx, shadows)
                });
                let shadow_rays = time.time(Stage::Shadow, || {
                    shadow::shadow(queue, shadows, ctx.bvh, ctx.tables)
                });
                counters.rays += shadow_rays;
                counters.shadow_rays += shadow_rays;
            }
            time.time(Stage::Bounce, || bounce::bounce(queue, &bins, &ctx));
        }
        time.add_textures(crate::integrator::texture::take_seconds());
    }
}
