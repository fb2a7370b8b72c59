//! Render settings and the driver that runs an engine over sample ranges.

use crate::accel::bvh::{Bvh, BvhOptions};
use crate::accel::simd::SimdWidth;
use crate::error::{Error, Result};
use crate::film::aov::bytes_per_pixel;
use crate::film::{AovSums, Film, PixelSum};
use crate::integrator::nee::Estimator;
use crate::integrator::reference::ReferenceTracer;
use crate::integrator::sampler::{Independent, Sampler, Sobol};
use crate::integrator::wavefront::{Scratch, WavefrontEngine};
use crate::integrator::{Counters, Frame, SceneData, TileJob, estimator_fingerprint};
pub use crate::scene::Adaptive;
use crate::scene::{AovSet, Integrator, SamplerKind, Scene};
use rayon::prelude::*;
use std::any::Any;
use std::ops::Range;
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Which path tracer computes the samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Engine {
    /// The scalar recursive reference tracer (the oracle).
    Reference,
    /// The SIMD wavefront engine (the default).
    Wavefront,
}

impl Engine {
    /// Every engine's name.
    pub const NAMES: &[&str] = &["reference", "wavefront"];

    /// The engine's name as the command line and stats spell it.
    pub fn name(self) -> &'static str {
        match self {
            Engine::Reference => "reference",
            Engine::Wavefront => "wavefront",
        }
    }

    /// The engine named `name`.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "reference" => Ok(Engine::Reference),
            "wavefront" => Ok(Engine::Wavefront),
            _ => Err(Error::Settings(format!(
                "unknown engine {name:?} (known: reference, wavefront)"
            ))),
        }
    }
}

/// Everything about a render that is not the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Maximum path depth; the camera ray is depth 0.
    pub max_depth: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Worker threads.
    pub threads: usize,
    /// The path tracer.
    pub engine: Engine,
    /// Paths per wavefront batch (does not change the image).
    pub batch_size: usize,
    /// The estimator.
    pub integrator: Integrator,
    /// Where the paths' numbers come from.
    pub sampler: SamplerKind,
    /// Russian roulette may end paths from this depth on (`None`: never).
    pub rr_depth: Option<u32>,
    /// Lanes of the intersection kernels (8, or 16 with AVX-512). Never
    /// changes the image: both widths give the same hits bit for bit.
    pub simd: SimdWidth,
    /// The most memory, in bytes, the render may need by its
    /// [`MemoryEstimate`]; `None`: the system's memory
    /// ([`system_memory`]). Does not change the image.
    pub memory_limit: Option<u64>,
    /// The auxiliary outputs to accumulate beside the radiance
    /// ([`crate::integrator::aov`]). Do not change the image (and are not
    /// in [`image_hash`](Self::image_hash): accumulation files record
    /// their AOVs themselves).
    pub aovs: AovSet,
    /// Adaptive sampling: pixels stop taking samples once their error is
    /// low enough (`None`: every pixel takes `spp` samples).
    pub adaptive: Option<Adaptive>,
}

/// Bytes per pixel of a render: the film's sums (48), the sums of the
/// sample pass being rendered (48), the linear image written out (12) and
/// its encoding (up to 16).
pub const FILM_BYTES_PER_PIXEL: u64 = 124;

/// Bytes per pixel an AOV adds to a render: its sums in the film and in the
/// pass being rendered, its image and that image's encoding (12 each).
pub fn aov_bytes_per_pixel(aovs: AovSet) -> u64 {
    aovs.iter()
        .map(|a| 2 * bytes_per_pixel(a) as u64 + 24)
        .sum()
}

/// Bytes per path of a worker thread's wavefront queues: the path queue
/// (about 70), the ray batch and the shadow-ray queue (a bound, not a
/// measurement: the estimate errs high).
pub const QUEUE_BYTES_PER_PATH: u64 = 192;

/// Bytes per triangle of the hierarchy and its build: the triangles'
/// edges, the build's references and bins, the nodes and 8-wide packs.
pub const BVH_BYTES_PER_TRIANGLE: u64 = 256;

/// What a render will allocate, by part, in bytes: checked against a
/// limit before any of it is allocated
/// ([`RenderSettings::check_memory`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// The film and the images made from it (width x height).
    pub film: u64,
    /// Every worker thread's queues (threads x batch size).
    pub queues: u64,
    /// The bounding volume hierarchy (triangles).
    pub bvh: u64,
}

impl MemoryEstimate {
    /// The sum of the parts (saturating: an estimate past 2^64 bytes is
    /// refused like any other too large).
    pub fn total(&self) -> u64 {
        self.film
            .saturating_add(self.queues)
            .saturating_add(self.bvh)
    }
}

pub use crate::fs::system_memory;

/// The limit used where the system's memory cannot be told.
pub const FALLBACK_MEMORY_LIMIT: u64 = 64 << 30;

/// `bytes` in words: "1.5 GiB".
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 7] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut x = bytes as f64;
    let mut unit = 0;
    while x >= 1024.0 && unit + 1 < UNITS.len() {
        x /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{x:.1} {}", UNITS[unit])
    }
}

/// The estimator a render uses unless the scene, a profile or a flag says
/// otherwise.
pub const DEFAULT_INTEGRATOR: Integrator = Integrator::Nee;

/// The sampler a render uses unless the scene, a profile or a flag says
/// otherwise.
pub const DEFAULT_SAMPLER: SamplerKind = SamplerKind::Sobol;

/// Default paths per wavefront batch: the queues stay in the L2 cache.
pub const DEFAULT_BATCH_SIZE: usize = 4096;

/// The largest batch accepted (its queue takes about 70 MiB).
pub const MAX_BATCH_SIZE: usize = 1 << 20;

/// The most worker threads a render starts: far more than any machine's
/// cores today, far fewer than would take the system down. Checked before
/// the thread pool starts.
pub const MAX_THREADS: usize = 4096;

/// The deepest paths accepted: the reference tracer recurses once per
/// bounce, and a uniform hemisphere estimator gains nothing from more.
pub const MAX_DEPTH: u32 = 1024;

impl RenderSettings {
    /// The scene's defaults: its resolution, depth and integrator options,
    /// 1 sample per pixel, seed 0, all cores, the default engine.
    pub fn for_scene(scene: &Scene) -> Self {
        Self {
            width: scene.camera.width,
            height: scene.camera.height,
            spp: 1,
            max_depth: scene.max_depth,
            seed: 0,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            engine: Engine::Wavefront,
            batch_size: DEFAULT_BATCH_SIZE,
            integrator: scene.options.integrator.unwrap_or(DEFAULT_INTEGRATOR),
            sampler: scene.options.sampler.unwrap_or(DEFAULT_SAMPLER),
            rr_depth: scene.options.rr_depth,
            simd: SimdWidth::detect(),
            memory_limit: None,
            aovs: match scene.options.aov.unwrap_or_default() {
                a if scene.has_transparent_background() => a.with(crate::scene::Aov::Alpha),
                a => a,
            },
            adaptive: None,
        }
    }

    /// The AOVs a film of these settings holds: [`aovs`](Self::aovs), and
    /// the variance (the sums of squares) where adaptive sampling needs it.
    pub fn film_aovs(&self) -> AovSet {
        match self.adaptive {
            Some(_) => self.aovs.with(crate::scene::Aov::Variance),
            None => self.aovs,
        }
    }

    /// What a render of `triangles` triangles with these settings will
    /// allocate (see [`MemoryEstimate`]).
    pub fn memory_estimate(&self, triangles: usize) -> MemoryEstimate {
        let pixels = self.width as u64 * self.height as u64;
        let paths = (self.threads as u64).saturating_mul(self.batch_size.div_ceil(8) as u64 * 8);
        MemoryEstimate {
            film: pixels
                .saturating_mul(FILM_BYTES_PER_PIXEL + aov_bytes_per_pixel(self.film_aovs())),
            queues: paths.saturating_mul(QUEUE_BYTES_PER_PATH),
            bvh: (triangles as u64).saturating_mul(BVH_BYTES_PER_TRIANGLE),
        }
    }

    /// Refuse, before anything is allocated, a render of `triangles`
    /// triangles whose [`memory_estimate`](Self::memory_estimate) exceeds
    /// [`memory_limit`](Self::memory_limit) (or the system's memory),
    /// naming the settings of its largest part.
    pub fn check_memory(&self, triangles: usize) -> Result<()> {
        let (limit, whose) = match self.memory_limit {
            Some(limit) => (limit, "the memory limit (WAVETRACE_MAX_MEMORY)"),
            None => match system_memory() {
                Some(m) => (m, "this system's memory"),
                None => (FALLBACK_MEMORY_LIMIT, "the default memory limit"),
            },
        };
        let e = self.memory_estimate(triangles);
        if e.total() <= limit {
            return Ok(());
        }
        let film = format!(
            "film {} for {}x{} pixels",
            human_bytes(e.film),
            self.width,
            self.height
        );
        let queues = format!(
            "queues {} for {} thread(s) x {} paths",
            human_bytes(e.queues),
            self.threads,
            self.batch_size
        );
        let bvh = format!("BVH {} for {triangles} triangles", human_bytes(e.bvh));
        let advice = if e.film >= e.queues && e.film >= e.bvh {
            "lower --width and --height (or the scene's camera.width and camera.height)"
        } else if e.queues >= e.bvh {
            "lower --threads or --batch-size"
        } else {
            "use a scene of fewer triangles"
        };
        Err(Error::Settings(format!(
            "the render would need about {} ({film}, {queues}, {bvh}), more than {whose} ({}); {advice}",
            human_bytes(e.total()),
            human_bytes(limit)
        )))
    }

    /// How paths are traced: the integrator, the depth, Russian roulette.
    pub fn estimator(&self) -> Estimator {
        Estimator {
            integrator: self.integrator,
            max_depth: self.max_depth,
            rr_depth: self.rr_depth,
        }
    }

    /// The report's estimator exactly as the seed wrote it: uniform
    /// hemisphere directions, independent numbers, no Russian roulette.
    pub fn report(mut self) -> Self {
        self.integrator = Integrator::Report;
        self.sampler = SamplerKind::Independent;
        self.rr_depth = None;
        self
    }

    /// Refuse impossible settings, before any work starts.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: &str| Err(Error::Settings(m.into()));
        if self.width == 0 || self.height == 0 {
            return bad("the image must be at least 1x1 pixels");
        }
        if (self.width as u64) * (self.height as u64) > u32::MAX as u64 {
            return bad("the image has more than 2^32 pixels");
        }
        if self.spp == 0 {
            return bad("samples per pixel must be at least 1");
        }
        if self.max_depth == 0 {
            return bad("max depth must be at least 1 (1 = only directly visible emitters)");
        }
        if self.threads == 0 {
            return bad("threads must be at least 1");
        }
        if self.threads > MAX_THREADS {
            return Err(Error::Settings(format!(
                "--threads {}: more than the {MAX_THREADS} worker threads a render may start",
                self.threads
            )));
        }
        if !(1..=MAX_BATCH_SIZE).contains(&self.batch_size) {
            return Err(Error::Settings(format!(
                "the batch size must be between 1 and {MAX_BATCH_SIZE} paths"
            )));
        }
        if self.rr_depth.is_some() && self.integrator == Integrator::Report {
            return bad(
                "Russian roulette (--rr-depth) is not part of the report's estimator; use it with --integrator bsdf or nee",
            );
        }
        if self.rr_depth == Some(0) {
            return bad("--rr-depth must be at least 1 (camera rays are never ended)");
        }
        if !self.simd.is_available() {
            return Err(Error::Settings(format!(
                "{} lanes ({}) need AVX-512 F, VL, DQ and BW, which this CPU lacks; use 8",
                self.simd.lanes(),
                self.simd.name()
            )));
        }
        if let Some(a) = self.adaptive {
            if !Adaptive::threshold_ok(a.threshold) {
                return Err(Error::Settings(format!(
                    "the noise threshold must be a number at least 0, not {}",
                    a.threshold
                )));
            }
            if !Adaptive::min_spp_ok(a.min_spp, self.spp) {
                return Err(Error::Settings(format!(
                    "adaptive sampling's first round (min_spp {}) must take between 2 and the {} samples per pixel",
                    a.min_spp, self.spp
                )));
            }
        }
        if self.max_depth > MAX_DEPTH {
            return Err(Error::Settings(format!(
                "max depth must be at most {MAX_DEPTH} (the reference tracer recurses once per bounce)"
            )));
        }
        Ok(())
    }

    /// A hash of the scene, of every setting that changes the image's bits
    /// (not the sample count, threads or batch size), and of how this build
    /// computes samples ([`estimator_fingerprint`]): partial films of
    /// renders with equal hashes can be combined, and a checkpoint or shard
    /// from a build that samples differently is refused.
    pub fn image_hash(&self, scene: &Scene) -> u128 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(&estimator_fingerprint().to_le_bytes());
        h.update(&scene.content_hash().to_le_bytes());
        h.update(&self.width.to_le_bytes());
        h.update(&self.height.to_le_bytes());
        h.update(&self.max_depth.to_le_bytes());
        h.update(&self.seed.to_le_bytes());
        h.update(self.engine.name().as_bytes());
        // The report's estimator hashes as before integrators existed, so
        // its checkpoints and partial files stay valid.
        if self.clone().report() != *self {
            h.update(self.integrator.name().as_bytes());
            h.update(self.sampler.name().as_bytes());
            h.update(&self.rr_depth.map_or(u32::MAX, |d| d).to_le_bytes());
        }
        // Without adaptive sampling, the hash of before it existed.
        if let Some(a) = self.adaptive {
            h.update(b"adaptive");
            h.update(&a.threshold.to_le_bytes());
            h.update(&a.min_spp.to_le_bytes());
        }
        h.digest128()
    }
}

/// Open the scene file at `path`: a TOML scene, or an asset (glTF, GLB,
/// PLY; `camera` picks one of a glTF's cameras by name or index), with
/// the loader's warnings for the caller to show; a file of another format
/// (an OBJ mesh, pbrt…) is refused with an error that says what it is.
pub fn open_scene(path: &std::path::Path, camera: Option<&str>) -> Result<(Scene, Vec<String>)> {
    if crate::scene::asset_scene::is_asset(path) {
        return Ok(crate::scene::asset_scene::load(path, camera)?);
    }
    if camera.is_some() {
        return Err(Error::Settings(format!(
            "--camera chooses among a glTF asset's cameras; {} is not one",
            path.display()
        )));
    }
    if let Some(foreign) = crate::scene::format::foreign_format(path) {
        return Err(foreign.into());
    }
    Ok((Scene::load(path)?, Vec::new()))
}

/// A scene prepared for one engine and one set of settings, with its pool
/// of worker threads.
pub struct Renderer {
    settings: RenderSettings,
    /// The camera at the render's size, the seed, the batch size.
    frame: Frame,
    pool: rayon::ThreadPool,
    engine: EngineState,
    /// The hierarchy both engines trace against.
    bvh: Arc<Bvh>,
    /// Wavefront queues, one per worker thread (uncontended locks), made
    /// on first use for the sampler's path type.
    scratch: Vec<Mutex<Option<Box<dyn Any + Send>>>>,
}

enum EngineState {
    Reference(ReferenceTracer),
    Wavefront(WavefrontEngine),
}

impl Renderer {
    /// Validate the settings and prepare the scene.
    pub fn new(scene: &Scene, settings: &RenderSettings) -> Result<Self> {
        settings.validate()?;
        settings.check_memory(scene.triangles.len())?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(settings.threads)
            .build()
            .map_err(|e| {
                Error::Settings(format!("cannot start {} threads: {e}", settings.threads))
            })?;
        // One hierarchy, built on the render's threads, shared by the engine.
        let options = BvhOptions {
            width: settings.simd,
        };
        // The engine's tables and lights are built while the hierarchy is
        // (they need neither it nor each other): a build that keeps one
        // thread busy leaves the other to them.
        let (bvh, data) = pool.install(|| {
            rayon::join(
                || crate::accel::scene_bvh(scene, &options),
                || SceneData::new(scene),
            )
        });
        let bvh = Arc::new(bvh);
        let estimator = settings.estimator();
        let engine = match settings.engine {
            Engine::Reference => EngineState::Reference(
                ReferenceTracer::with_data(scene, data, settings.max_depth, bvh.clone())
                    .with_estimator(estimator),
            ),
            Engine::Wavefront => {
                EngineState::Wavefront(WavefrontEngine::with_data(data, estimator, bvh.clone()))
            }
        };
        let frame = Frame {
            camera: scene.camera.for_resolution(settings.width, settings.height),
            width: settings.width,
            seed: settings.seed,
            batch_size: settings.batch_size,
        };
        Ok(Self {
            bvh,
            scratch: (0..settings.threads).map(|_| Mutex::new(None)).collect(),
            settings: settings.clone(),
            frame,
            pool,
            engine,
        })
    }

    /// Point the renderer at another camera (made for the render's width
    /// and height) and seed, keeping everything built from the scene: its
    /// hierarchy, tables, textures and lights. What changes between the
    /// views of one asset (`wavetrace views`): a view renders exactly as a
    /// renderer made for the scene with that camera and seed.
    pub fn set_view(&mut self, camera: &crate::scene::camera::Camera, seed: u64) {
        let s = &mut self.settings;
        s.seed = seed;
        self.frame.camera = camera.for_resolution(s.width, s.height);
        self.frame.seed = seed;
    }

    /// Rebuild the lights (emitters and environment) from `scene`: the
    /// scene this renderer was made for, with another environment (a view
    /// of `wavetrace views` under another sky). Its geometry and materials
    /// must be the ones the renderer was made for.
    pub fn relight(&mut self, scene: &Scene) {
        match &mut self.engine {
            EngineState::Reference(tracer) => tracer.relight(scene),
            EngineState::Wavefront(engine) => engine.relight(scene),
        }
    }

    /// What [`relight`](Self::relight) gives for the scene with only its
    /// environment's rotation changed, to `rotation_deg`, without building
    /// the environment's sampling tables again.
    pub fn turn_environment(&mut self, rotation_deg: f32) {
        match &mut self.engine {
            EngineState::Reference(tracer) => tracer.turn_environment(rotation_deg),
            EngineState::Wavefront(engine) => engine.turn_environment(rotation_deg),
        }
    }

    /// The bounding volume hierarchy the engine traces against.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// The settings this renderer was made for.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// A new, empty film of the right size, with the settings' AOVs.
    pub fn new_film(&self) -> Film {
        let s = &self.settings;
        Film::with_aovs(s.width, s.height, s.film_aovs())
    }

    /// Add samples `range` of every pixel to `film` (which must have the
    /// size and the AOVs of the settings).
    pub fn render_samples(&self, range: Range<u32>, film: &mut Film) -> Counters {
        self.check_film(film);
        let sums = (&mut film.sums[..], &mut film.aov);
        let (counters, complete) = self.render_sums(range.clone(), sums, None, &|| false);
        assert!(complete, "nothing asked to stop");
        film.add_range(range);
        film.invalid_samples += counters.invalid_samples;
        counters
    }

    /// [`render_samples`](Self::render_samples) that gives up, between
    /// tiles, once `stop()` returns true: then it returns `None` and `film`
    /// is exactly as it was (the samples go to a separate accumulator,
    /// added to the film only when every tile is done). A film therefore
    /// only ever holds whole sample ranges.
    pub fn render_samples_or_stop(
        &self,
        range: Range<u32>,
        film: &mut Film,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<Counters> {
        let counters = self.render_pass(range.clone(), None, film, stop)?;
        film.add_range(range);
        Some(counters)
    }

    /// Add samples `range` of the pixels `active` marks (all: `None`) to
    /// `film`'s sums, or nothing if `stop()` ends the pass.
    fn render_pass(
        &self,
        range: Range<u32>,
        active: Option<&[bool]>,
        film: &mut Film,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<Counters> {
        self.check_film(film);
        let mut pass = vec![[0u128; 3]; film.sums.len()];
        let mut pass_aov = AovSums::new(film.aovs(), film.sums.len());
        let (counters, complete) =
            self.render_sums(range, (&mut pass, &mut pass_aov), active, stop);
        if !complete {
            return None;
        }
        for (sum, p) in film.sums.iter_mut().zip(&pass) {
            for (s, p) in sum.iter_mut().zip(p) {
                *s += p;
            }
        }
        film.aov.add(&pass_aov);
        film.invalid_samples += counters.invalid_samples;
        Some(counters)
    }

    /// Render the settings' `spp` samples with adaptive sampling
    /// ([`Adaptive`]; the settings must have it) into `film`, new and
    /// empty: every pixel's first `min_spp` samples, then rounds that
    /// double the samples of the pixels still noisy. The film records each
    /// pixel's count ([`Film::counts`]). `None` (the film then holds
    /// nothing usable) when `stop()` ended it.
    pub fn render_adaptive_or_stop(
        &self,
        film: &mut Film,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<Counters> {
        let a = self.settings.adaptive.expect("adaptive settings");
        let (spp, (w, h)) = (self.settings.spp, (film.width, film.height));
        let first = a.min_spp.clamp(1, spp);
        let mut counters = self.render_samples_or_stop(0..first, film, stop)?;
        let mut counts = vec![first; film.sums.len()];
        let mut n = first;
        while n < spp {
            let next = n.saturating_mul(2).min(spp);
            let errors = pixel_errors(film, &counts);
            let active = still_noisy(&errors, &counts, n, a.threshold, (w, h));
            if !active.contains(&true) {
                break;
            }
            counters += self.render_pass(n..next, Some(&active), film, stop)?;
            for (c, _) in counts.iter_mut().zip(&active).filter(|(_, a)| **a) {
                *c = next;
            }
            n = next;
        }
        film.counts = Some(counts);
        Some(counters)
    }

    fn check_film(&self, film: &Film) {
        assert_eq!(
            (film.width, film.height),
            (self.settings.width, self.settings.height)
        );
        assert_eq!(film.aovs(), self.settings.film_aovs(), "the film's AOVs");
    }

    /// Add samples `range` of every pixel to `sums` (radiance, AOVs), a
    /// tile at a time; tiles not yet started when `stop()` turns true are
    /// skipped. Returns the work counted and whether every tile was
    /// rendered.
    fn render_sums(
        &self,
        range: Range<u32>,
        sums: (&mut [PixelSum], &mut AovSums),
        active: Option<&[bool]>,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> (Counters, bool) {
        let skipped = AtomicBool::new(false);
        let go = || {
            let stopping = stop();
            if stopping {
                skipped.store(true, Ordering::Relaxed);
            }
            !stopping
        };
        let seed = self.settings.seed;
        let counters = match self.settings.sampler {
            SamplerKind::Independent => {
                self.render_tiles(&Independent::new(seed), range, sums, active, &go)
            }
            SamplerKind::Sobol => self.render_tiles(&Sobol::new(seed), range, sums, active, &go),
        };
        (counters, !skipped.load(Ordering::Relaxed))
    }

    /// Every tile of `sums` not skipped by `go`, numbers from `sampler`.
    fn render_tiles<S: Sampler>(
        &self,
        sampler: &S,
        range: Range<u32>,
        (sums, aov): (&mut [PixelSum], &mut AovSums),
        active: Option<&[bool]>,
        go: &(dyn Fn() -> bool + Sync),
    ) -> Counters
    where
        S::Path: 'static,
    {
        let tile = tile_pixels(&self.settings, range.len());
        let aov_tiles = aov.tiles_mut(tile, sums.len());
        self.pool.install(|| {
            sums.par_chunks_mut(tile)
                .zip(aov_tiles)
                .enumerate()
                .filter(|_| go())
                .map(|(i, (sums, aov))| {
                    let start = (i * tile) as u32;
                    let pixels = start..start + sums.len() as u32;
                    let mut job = TileJob {
                        frame: &self.frame,
                        active: active.map(|a| &a[pixels.start as usize..pixels.end as usize]),
                        pixels,
                        samples: range.clone(),
                        sums,
                        aov,
                    };
                    self.render_tile(sampler, &mut job)
                })
                .reduce(Counters::default, |a, b| a + b)
        })
    }

    /// One tile, by whichever engine this renderer runs.
    fn render_tile<S: Sampler>(&self, sampler: &S, job: &mut TileJob) -> Counters
    where
        S::Path: 'static,
    {
        match &self.engine {
            EngineState::Reference(tracer) => tracer.render_tile(sampler, job),
            EngineState::Wavefront(engine) => {
                // Each worker thread reuses its own queues.
                let worker = rayon::current_thread_index().unwrap_or(0);
                let mut slot = self.scratch[worker].lock().expect("scratch lock");
                if !slot.as_ref().is_some_and(|s| s.is::<Scratch<S::Path>>()) {
                    *slot = Some(Box::new(Scratch::<S::Path>::new(
                        self.settings.batch_size,
                        self.settings.aovs,
                    )));
                }
                let scratch = slot
                    .as_mut()
                    .and_then(|s| s.downcast_mut::<Scratch<S::Path>>())
                    .expect("made above");
                engine.render_tile(sampler, scratch, job)
            }
        }
    }

    /// Render samples `0..spp` into a new film, timing it.
    pub fn render(&self) -> (Film, Counters, Duration) {
        let mut film = self.new_film();
        let start = Instant::now();
        let counters = self.render_samples(0..self.settings.spp, &mut film);
        (film, counters, start.elapsed())
    }
}

/// Each pixel's error as [`Adaptive`] defines it, from `film`'s sums
/// and sums of squares, pixel `i` holding `counts[i]` samples.
fn pixel_errors(film: &Film, counts: &[u32]) -> Vec<f32> {
    let squares = film.aov.squares(crate::scene::Aov::Variance);
    (film.sums.iter().zip(squares).zip(counts))
        .map(|((sum, sq), &n)| {
            let n = f64::from(n);
            let e2: f64 = (0..3)
                .map(|k| {
                    let m = sum[k] as f64 / (n * crate::film::FIXED_POINT_SCALE);
                    let var = f64::from(crate::film::aov::variance(n, sum[k], sq[k]));
                    var / n / (m * m + 0.01)
                })
                .sum();
            (e2 / 3.0).sqrt() as f32
        })
        .collect()
}

/// The pixels that take the next round: those that took every round so
/// far (`n` samples) and have a pixel of error above `threshold` among
/// themselves and their eight neighbours.
fn still_noisy(
    errors: &[f32],
    counts: &[u32],
    n: u32,
    threshold: f32,
    (w, h): (u32, u32),
) -> Vec<bool> {
    let (w, h) = (w as usize, h as usize);
    let noisy: Vec<bool> = errors.iter().map(|&e| e > threshold).collect();
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            counts[i] == n
                && (y.saturating_sub(1)..(y + 2).min(h))
                    .any(|y| (x.saturating_sub(1)..(x + 2).min(w)).any(|x| noisy[y * w + x]))
        })
        .collect()
}

/// Pixels per tile (a unit of work for a thread): about one batch of
/// paths, but small enough to give every thread several tiles.
fn tile_pixels(s: &RenderSettings, samples: usize) -> usize {
    let pixels = s.width as usize * s.height as usize;
    let per_batch = (s.batch_size / samples.max(1)).max(1);
    let for_balance = pixels.div_ceil(8 * s.threads).max(1);
    per_batch.min(for_balance)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_noisy_pixel_keeps_its_neighbours_and_a_stopped_pixel_stays_stopped() {
        // 5 x 4 pixels; one noisy pixel at (2, 1); pixel (3, 2) stopped in
        // an earlier round (count 4 against 8).
        let mut errors = vec![0.01f32; 20];
        errors[5 + 2] = 0.5;
        let mut counts = vec![8u32; 20];
        counts[2 * 5 + 3] = 4;
        let active = still_noisy(&errors, &counts, 8, 0.1, (5, 4));
        let want: Vec<bool> = (0..20)
            .map(|i| {
                let (x, y) = (i % 5, i / 5);
                (1..=3).contains(&x) && y <= 2 && (x, y) != (3, 2)
            })
            .collect();
        assert_eq!(active, want);
        // At the threshold is quiet enough.
        assert!(!still_noisy(&[0.1; 4], &[8; 4], 8, 0.1, (2, 2)).contains(&true));
    }

    #[test]
    fn image_hash_follows_exactly_the_settings_that_change_bits() {
        let scene = Scene::cornell();
        let base = RenderSettings::for_scene(&scene);
        let hash = |f: &dyn Fn(&mut RenderSettings)| {
            let mut s = base.clone();
            f(&mut s);
            s.image_hash(&scene)
        };
        let h0 = hash(&|_| {});
        // Settings that never change a sample's bits.
        assert_eq!(h0, hash(&|s| s.spp = 999));
        assert_eq!(h0, hash(&|s| s.threads = 7));
        assert_eq!(h0, hash(&|s| s.batch_size = 3));
        assert_eq!(h0, hash(&|s| s.memory_limit = Some(1 << 30)));
        assert_eq!(h0, hash(&|s| s.aovs = AovSet::ALL));
        // Settings that do.
        assert_ne!(h0, hash(&|s| s.seed = 1));
        assert_ne!(h0, hash(&|s| s.width += 1));
        assert_ne!(h0, hash(&|s| s.height += 1));
        assert_ne!(h0, hash(&|s| s.max_depth += 1));
        assert_ne!(h0, hash(&|s| s.engine = Engine::Reference));
        assert_ne!(h0, hash(&|s| s.integrator = Integrator::Bsdf));
        assert_ne!(h0, hash(&|s| s.sampler = SamplerKind::Independent));
        assert_eq!(h0, hash(&|s| s.simd = crate::accel::simd::SimdWidth::W8));
        assert_ne!(h0, hash(&|s| s.rr_depth = Some(3)));
        // The report's estimator hashes as it did before integrators.
        let report = base.clone().report();
        let mut old = xxhash_rust::xxh3::Xxh3::new();
        old.update(&estimator_fingerprint().to_le_bytes());
        old.update(&scene.content_hash().to_le_bytes());
        for x in [report.width, report.height, report.max_depth] {
            old.update(&x.to_le_bytes());
        }
        old.update(&report.seed.to_le_bytes());
        old.update(b"wavefront");
        assert_eq!(report.image_hash(&scene), old.digest128());
        // And the scene.
        let mut other = scene.clone();
        other.materials[0].reflectance.x *= 0.5;
        assert_ne!(h0, base.image_hash(&other));
        // The estimator's fingerprint is a pure function of the build.
        assert_eq!(estimator_fingerprint(), estimator_fingerprint());
    }
}
