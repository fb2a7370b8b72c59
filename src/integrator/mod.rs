//! What a path does at each vertex, and the two engines that trace paths.
//!
//! - [`sampler`]: the numbers every path uses, by dimension;
//! - [`bsdf`]: one scattering routine per material model, written once for
//!   scalar and 8-wide code;
//! - [`reference`](mod@reference): the scalar recursive reference tracer
//!   (the oracle);
//! - [`wavefront`]: the SIMD wavefront engine (the default);
//! - [`offset`]: where a ray leaves a surface (both engines);
//! - [`surface`]: the surface at a hit, computed once per hit for every
//!   consumer, from the shapes' columns in [`tables`];
//! - [`aov`]: the auxiliary outputs (albedo, normal, depth, variance):
//!   what each one is, and where the engines record them.
//!
//! Both engines render a [`TileJob`] — samples of a run of pixels into
//! those pixels' sums — and count their work in [`Counters`]. The two differ
//! in control flow only: they share the camera, the sampler, the scattering
//! routines and the acceleration structure, so they trace the very same
//! paths.

pub mod aov;
pub mod bsdf;
pub mod environment;
pub mod light_tree;
pub mod lights;
pub mod nee;
pub mod offset;
pub mod punctual;
pub mod reference;
pub mod sampler;
pub mod surface;
pub mod tables;
pub mod texture;
pub mod wavefront;

use crate::film::{AovSample, AovTile, PixelSum, accumulate_with_aovs};
use crate::scene::Scene;
use crate::scene::camera::RasterCamera;
use std::ops::Range;

/// What both engines make of a scene besides its hierarchy: its columns
/// ([`tables::Tables`]) and its lights ([`lights::Lights`]). Neither needs
/// the other nor the hierarchy, so all three can be built side by side.
pub struct SceneData {
    /// The scene's primitives and materials, as columns.
    pub tables: tables::Tables,
    /// The emitters and the environment, for light sampling.
    pub lights: lights::Lights,
}

impl SceneData {
    /// The tables and the lights of `scene`, built side by side on the
    /// current rayon pool (each is a pure function of the scene).
    pub fn new(scene: &Scene) -> Self {
        let (tables, lights) =
            rayon::join(|| tables::Tables::new(scene), || lights::Lights::new(scene));
        Self { tables, lights }
    }
}

/// What every tile of a render shares: the camera at the render's size,
/// the seed and the batch size.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// The camera, set up for the image's size.
    pub camera: RasterCamera,
    /// Image width in pixels (pixel `p` is at `(p % width, p / width)`).
    pub width: u32,
    /// The seed of every random number.
    pub seed: u64,
    /// Paths per wavefront batch (does not change the image).
    pub batch_size: usize,
}

/// One unit of work for a thread: samples `samples` of the pixels
/// `pixels` (row-major indices), added to `sums` (one per pixel of the
/// run, `sums[0]` is pixel `pixels.start`) and, when the render
/// accumulates AOVs, to `aov` (laid out the same way).
pub struct TileJob<'a> {
    /// The render's constants.
    pub frame: &'a Frame,
    /// The pixels, row-major indices.
    pub pixels: Range<u32>,
    /// The sample indices of every pixel.
    pub samples: Range<u32>,
    /// The pixels' sums.
    pub sums: &'a mut [PixelSum],
    /// The pixels' AOV sums (every column empty when the render has none).
    pub aov: AovTile<'a>,
    /// Which of the pixels take the samples (one flag per pixel of the
    /// run; `None`: all of them): a round of adaptive sampling
    /// ([`crate::render::Adaptive`]) traces only the pixels still noisy.
    pub active: Option<&'a [bool]>,
}

impl TileJob<'_> {
    /// Whether pixel `pixel` (a row-major index within the tile) takes the
    /// job's samples.
    #[inline]
    pub fn is_active(&self, pixel: u32) -> bool {
        self.active
            .is_none_or(|a| a[(pixel - self.pixels.start) as usize])
    }

    /// The sums of pixel `pixel` (a row-major index within the tile).
    #[inline]
    pub fn sum_of(&mut self, pixel: u32) -> &mut PixelSum {
        &mut self.sums[(pixel - self.pixels.start) as usize]
    }

    /// Whether the render accumulates AOVs (then every finished sample
    /// goes through [`add_sample`](Self::add_sample)).
    #[inline]
    pub fn has_aovs(&self) -> bool {
        !self.aov.is_empty()
    }

    /// Add a finished sample of pixel `pixel` (a row-major index within
    /// the tile): its radiance `rgb` and its AOVs `aov`
    /// ([`accumulate_with_aovs`]). Returns false for an invalid radiance
    /// sample.
    #[inline]
    pub fn add_sample(&mut self, pixel: u32, rgb: glam::Vec3, aov: &AovSample) -> bool {
        let i = (pixel - self.pixels.start) as usize;
        accumulate_with_aovs(&mut self.sums[i], (&mut self.aov, i), rgb, aov)
    }

    /// Pixel `pixel`'s column and row.
    #[inline]
    pub fn xy(&self, pixel: u32) -> (u32, u32) {
        (pixel % self.frame.width, pixel / self.frame.width)
    }
}

/// The stages of the wavefront engine, in the order a path meets them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Camera rays for a batch of (pixel, sample) pairs.
    Generate,
    /// Closest hits.
    Intersect,
    /// Emission seen at the hits (and the AOVs recorded there).
    Shade,
    /// Finished paths added to the film, and dropped from the queue.
    Retire,
    /// The live paths grouped by material model.
    Sort,
    /// Next-event estimation: points on emitters, and shadow rays to them.
    Light,
    /// Occlusion of the shadow rays; the light of those that arrive.
    Shadow,
    /// Next directions and throughputs.
    Bounce,
}

impl Stage {
    /// Every stage, in order.
    pub const ALL: [Stage; 8] = [
        Stage::Generate,
        Stage::Intersect,
        Stage::Shade,
        Stage::Retire,
        Stage::Sort,
        Stage::Light,
        Stage::Shadow,
        Stage::Bounce,
    ];

    /// The stage's name in stats.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Generate => "generate",
            Stage::Intersect => "intersect",
            Stage::Shade => "shade",
            Stage::Retire => "retire",
            Stage::Sort => "sort",
            Stage::Light => "light",
            Stage::Shadow => "shadow",
            Stage::Bounce => "bounce",
        }
    }
}

/// Seconds spent in each wavefront stage, summed over threads; and, of
/// those, the seconds spent looking textures up ([`texture::timed`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageSeconds {
    stages: [f64; Stage::ALL.len()],
    textures: f64,
}

impl StageSeconds {
    /// Run `f` as (part of) stage `stage`, adding its wall-clock time.
    #[inline]
    pub fn time<T>(&mut self, stage: Stage, f: impl FnOnce() -> T) -> T {
        let start = std::time::Instant::now();
        let out = f();
        self.stages[stage as usize] += start.elapsed().as_secs_f64();
        out
    }

    /// The seconds of one stage.
    pub fn of(&self, stage: Stage) -> f64 {
        self.stages[stage as usize]
    }

    /// Of the stages' seconds, those spent in texture lookups and the
    /// material parameters they make (inside *light*, *bounce* and
    /// *shade*: not a stage of its own).
    pub fn textures(&self) -> f64 {
        self.textures
    }

    /// Add `seconds` of texture lookups (already inside the stages' time).
    pub fn add_textures(&mut self, seconds: f64) {
        self.textures += seconds;
    }

    /// The stages by name, for the stats file; empty when nothing was
    /// timed (the reference engine has no stages). The texture lookups'
    /// share of them is [`textures`](Self::textures), apart.
    pub fn by_name(&self) -> std::collections::BTreeMap<&'static str, f64> {
        if self.stages.iter().all(|s| *s == 0.0) {
            return Default::default();
        }
        Stage::ALL.iter().map(|s| (s.name(), self.of(*s))).collect()
    }
}

impl std::ops::AddAssign for StageSeconds {
    fn add_assign(&mut self, o: Self) {
        for (a, b) in self.stages.iter_mut().zip(o.stages) {
            *a += b;
        }
        self.textures += o.textures;
    }
}

/// Work counted while rendering.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counters {
    /// Camera paths traced.
    pub paths: u64,
    /// Rays cast: closest-hit queries and shadow rays.
    pub rays: u64,
    /// Of those, the shadow rays of next-event estimation.
    pub shadow_rays: u64,
    /// Samples refused as NaN, infinite or negative.
    pub invalid_samples: u64,
    /// Time per wavefront stage (zero for the reference engine).
    pub stages: StageSeconds,
}

impl std::ops::AddAssign for Counters {
    fn add_assign(&mut self, o: Self) {
        self.paths += o.paths;
        self.rays += o.rays;
        self.shadow_rays += o.shadow_rays;
        self.invalid_samples += o.invalid_samples;
        self.stages += o.stages;
    }
}

impl std::ops::Add for Counters {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self += o;
        self
    }
}

/// The version of the estimator: bump it whenever a change alters the
/// samples a path produces in a way [`estimator_fingerprint`]'s probes
/// would not see (the order random numbers are drawn in, say).
pub const ESTIMATOR_VERSION: u32 = 1;

/// A fingerprint of how this build computes samples: [`ESTIMATOR_VERSION`]
/// and the bits of a few probes of the shared kernels — random draws,
/// a scattered direction, `sin_cos_2pi`, a Möller–Trumbore hit, where a
/// ray leaves a surface ([`offset`]), the environment's angle
/// ([`environment::atan2`]), the film's fixed-point scale. A change to any
/// of them changes some image's bits,
/// and so changes this fingerprint (and the settings hash that checkpoints
/// and shards are checked against).
pub fn estimator_fingerprint() -> u64 {
    use crate::accel::triangle::{TriangleEdges, V3Tri, moller_trumbore};
    use crate::math::{V3, sin_cos_2pi};
    use sampler::{Independent, Sampler};
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    let mut put = |x: f32| h.update(&x.to_bits().to_le_bytes());
    let independent = Independent::new(0x5EED);
    let mut path = independent.start(7, 11);
    for _ in 0..4 {
        put(independent.next(&mut path));
    }
    let d = bsdf::diffuse::sample_uniform(
        V3::new(0.6f32, -0.48, 0.64),
        V3::new(1.0, 1.0, 1.0),
        [0.3, 0.7],
    )
    .wi;
    [d.x, d.y, d.z].into_iter().for_each(&mut put);
    let (sin, cos) = sin_cos_2pi(0.123f32);
    put(sin);
    put(cos);
    let tri = TriangleEdges::new(
        glam::Vec3::new(-1.0, -1.0, 2.0),
        glam::Vec3::new(1.5, -1.0, 2.5),
        glam::Vec3::new(0.0, 1.0, 1.5),
    );
    let o = V3::new(0.1f32, 0.2, -0.3);
    let (_, t) = moller_trumbore(o, V3::new(0.0, 0.0, 1.0), &V3Tri::from(&tri), 0.0);
    put(t);
    let p = V3::new(0.3f32, -0.2, 2.1);
    let from = offset::spawn(p, V3::new(0.0, 0.6, 0.8), d, offset::error_bound(o, p, 2.5));
    [from.x, from.y, from.z].into_iter().for_each(&mut put);
    put(environment::atan2(0.3f32, -0.7));
    h.update(&crate::film::FIXED_POINT_SCALE.to_bits().to_le_bytes());
    h.update(&ESTIMATOR_VERSION.to_le_bytes());
    h.digest()
}
