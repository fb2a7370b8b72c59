//! `wavetrace bench`'s suite: fixed, versioned workloads rendered at fixed
//! settings, timed at several thread counts, and verified against the image
//! hashes shipped with the build.
//!
//! wavetrace's images are bit-exact across machines and thread counts (the
//! film sums samples exactly, see [`crate::film`]), so every workload's
//! image hash is known in advance: [`EXPECTED_HASHES`]. A run whose image
//! has another hash was miscompiled, ran on unstable hardware, or was built
//! from rendering code that changed since the table was made. Library code:
//! it prints nothing; [`BenchObserver`] reports progress.

use crate::error::{Error, Result};
use crate::film::Film;
use crate::integrator::{Stage, StageSeconds};
use crate::render::{DEFAULT_INTEGRATOR, DEFAULT_SAMPLER, Engine, RenderSettings, Renderer};
use crate::run::views::{self, DEFAULT_CHECKPOINT_EVERY, ViewsOptions};
use crate::scene::views_job::ViewsJob;
use crate::scene::{Integrator, SamplerKind, Scene};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Instant;

/// The version of the suite: bumped whenever a workload's scene or
/// settings change, so scores of different suites are never compared as
/// equals. (A change of rendering code changes the hashes, not the suite.)
/// Version 2 added the `asset-views` workload.
pub const SUITE_VERSION: u32 = 2;

/// The source of the million-triangle scene, built in so the suite needs
/// no files.
pub const SPHERE_1M_TOML: &str = include_str!("../../scenes/sphere-1m.toml");

/// The expected image hash ([`film_hash`]) of every workload at every
/// size: `(workload, size, hash)`.
///
/// The one place to refresh when rendering code changes the images on
/// purpose: `cargo test --release --test bench` fails and prints the table
/// to paste here.
pub const EXPECTED_HASHES: &[(&str, SuiteSize, &str)] = &[
    ("cornell-report", SuiteSize::Full, "31c40d25a4996a4a"),
    ("cornell-report", SuiteSize::Quick, "30adfa4491ddb1a1"),
    ("cornell-report", SuiteSize::Tiny, "f36c7125eb61d9e7"),
    ("cornell-default", SuiteSize::Full, "2a5438aac1c5178d"),
    ("cornell-default", SuiteSize::Quick, "a19fe9e377a7195f"),
    ("cornell-default", SuiteSize::Tiny, "408b87ded6f91ee4"),
    ("sphere-1m", SuiteSize::Full, "379cfc6e6825943c"),
    ("sphere-1m", SuiteSize::Quick, "b5069d2f48863aed"),
    ("sphere-1m", SuiteSize::Tiny, "6e99e6a21864153d"),
    ("asset-views", SuiteSize::Full, "7988f285c5d8d70d"),
    ("asset-views", SuiteSize::Quick, "74333e96ece8f39f"),
    ("asset-views", SuiteSize::Tiny, "75216d8375aec32e"),
];

/// How big the suite's renders are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SuiteSize {
    /// The default: about a minute on 2 cores.
    Full,
    /// `--quick`: about 10 seconds on 2 cores.
    Quick,
    /// For tests of the command itself: a fraction of a second per render
    /// (plus loading the million-triangle scene).
    Tiny,
}

impl SuiteSize {
    /// The size's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::Quick => "quick",
            Self::Tiny => "tiny",
        }
    }
}

/// Which scene a workload renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchScene {
    /// The built-in Cornell box ([`Scene::cornell`]).
    Cornell,
    /// `scenes/sphere-1m.toml` ([`SPHERE_1M_TOML`]): the Cornell box and a
    /// geodesic sphere of 1,003,520 triangles, generated on load.
    Sphere1m,
    /// A `wavetrace views` job ([`views_job_toml`]): the shipped textured
    /// asset (`scenes/textured.glb`, [`VIEWS_ASSET`]) under the shipped sky
    /// (`scenes/env/sky.exr`, [`VIEWS_SKY`]), turned by a seeded angle per
    /// view, with depth and normals. A render is the whole job: loading
    /// the asset and building its tables once, then every view.
    AssetViews,
}

/// The views workload's asset, built in so the suite needs no files.
pub const VIEWS_ASSET: &[u8] = include_bytes!("../../scenes/textured.glb");

/// The views workload's environment.
pub const VIEWS_SKY: &[u8] = include_bytes!("../../scenes/env/sky.exr");

/// The views workload's job at `res`² pixels and `spp` samples per pixel:
/// a dozen views (an orbit of six at two elevations) of [`VIEWS_ASSET`],
/// normalised, under [`VIEWS_SKY`] turned by a seeded angle per view.
pub fn views_job_toml(res: u32, spp: u32) -> String {
    format!(
        r#"[assets]
files = ["textured.glb"]
normalize = true

[cameras]
kind = "orbit"
views = 6
elevations = [15.0, 40.0]
fov = 40.0
distance = 1.6

[[environment]]
file = "sky.exr"

[lighting]
random_rotation = true

[render]
width = {res}
height = {res}
spp = {spp}
seed = 1
max_depth = 5

[outputs]
color = ["png"]
aov = ["depth", "normal"]
"#
    )
}

impl BenchScene {
    /// The scene, built or generated; `None` for [`BenchScene::AssetViews`]
    /// (a job, not a scene: see [`Workload::prepare`]).
    pub fn load(self) -> Option<Scene> {
        match self {
            Self::Cornell => Some(Scene::cornell()),
            Self::Sphere1m => Some(
                crate::scene::file::parse(SPHERE_1M_TOML, "scenes/sphere-1m.toml")
                    .expect("the built-in sphere-1m scene parses"),
            ),
            Self::AssetViews => None,
        }
    }
}

/// A workload made ready to time: its scene loaded, or its views job
/// written to a folder of its own (removed when this is dropped).
pub enum Prepared {
    /// A scene rendered as one image.
    Scene(Box<Scene>),
    /// A views job.
    Views(Box<ViewsBench>),
}

/// The views workload's job, read from a temporary folder that holds it,
/// its asset and its environment.
pub struct ViewsBench {
    job: ViewsJob,
    dir: TempFolder,
}

/// A folder removed, with what it holds, when this is dropped.
struct TempFolder(PathBuf);

impl Drop for TempFolder {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl ViewsBench {
    /// Write [`VIEWS_ASSET`], [`VIEWS_SKY`] and the job of `w` to a new
    /// folder in the system's temporary directory, and read the job.
    fn new(w: &Workload) -> Result<Self> {
        static COUNT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "wavetrace-bench-{}-{}",
            std::process::id(),
            COUNT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        // Left over by an earlier process of the same id.
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).map_err(|e| crate::fs::FileError::new(&dir, e))?;
        // Removed when dropped, on an error below too.
        let folder = TempFolder(dir);
        let write = |name: &str, bytes: &[u8]| {
            let path = folder.0.join(name);
            std::fs::write(&path, bytes).map_err(|e| crate::fs::FileError::new(&path, e))
        };
        write("textured.glb", VIEWS_ASSET)?;
        write("sky.exr", VIEWS_SKY)?;
        write("job.toml", views_job_toml(w.width, w.spp).as_bytes())?;
        Ok(Self {
            job: ViewsJob::load(&folder.0.join("job.toml"))?,
            dir: folder,
        })
    }

    /// Run the whole job in memory on `threads` threads: its hash is of
    /// every view's film and AOVs, in order.
    fn render(&self, threads: usize) -> Result<Rendered> {
        let options = ViewsOptions {
            out_dir: self.dir.0.join("out"),
            shard: None,
            threads,
            engine: Engine::Wavefront,
            batch_size: None,
            checkpoint_every: DEFAULT_CHECKPOINT_EVERY,
            pass_samples: None,
        };
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        let mut paths = 0;
        let start = Instant::now();
        let report = views::stream(&self.job, &options, &|| false, &mut |_| {}, &mut |v| {
            h.update(film_hash(v.film).as_bytes());
            for (aov, pixels) in &v.aovs {
                h.update(aov.name().as_bytes());
                for c in pixels.iter().flatten() {
                    h.update(&c.to_le_bytes());
                }
            }
            paths += v.film.width as u64 * v.film.height as u64 * v.film.samples_per_pixel();
            Ok(true)
        })?;
        let seconds = start.elapsed().as_secs_f64();
        if let Some(a) = report.failed().next() {
            return Err(Error::Settings(format!(
                "bench: the views workload's asset failed: {}",
                a.error.as_deref().unwrap_or("unknown")
            )));
        }
        Ok(Rendered {
            hash: format!("{:016x}", h.digest()),
            paths,
            rays: report.assets.iter().map(|a| a.rays).sum(),
            triangles: report.assets.iter().map(|a| a.triangles).sum(),
            stages: report
                .assets
                .iter()
                .fold(StageSeconds::default(), |mut s, a| {
                    s += a.stages;
                    s
                }),
            seconds,
        })
    }
}

/// One timed render of a workload.
#[derive(Clone, Debug, PartialEq)]
pub struct Rendered {
    /// The hash that verifies it ([`film_hash`]; for views, of every
    /// view's film and AOVs).
    pub hash: String,
    /// Camera paths traced.
    pub paths: u64,
    /// Rays cast (closest-hit and shadow rays).
    pub rays: u64,
    /// Triangles in the scene (the asset's, for views).
    pub triangles: usize,
    /// Seconds in each wavefront stage, summed over threads.
    pub stages: StageSeconds,
    /// Seconds: the render's (for views, the whole job's: loading and
    /// building the asset, and every view).
    pub seconds: f64,
}

/// Times one workload on a fixed thread count.
enum Runner<'a> {
    Still(Box<Renderer>, &'a Scene),
    Views(&'a ViewsBench, usize),
}

impl Runner<'_> {
    fn render(&self) -> Result<Rendered> {
        match self {
            Self::Still(renderer, scene) => {
                let (film, c, dt) = renderer.render();
                Ok(Rendered {
                    hash: film_hash(&film),
                    paths: c.paths,
                    rays: c.rays,
                    triangles: scene.triangles.len(),
                    stages: c.stages,
                    seconds: dt.as_secs_f64(),
                })
            }
            Self::Views(bench, threads) => bench.render(*threads),
        }
    }
}

impl Prepared {
    /// What times `w` on `threads` threads (a still scene's renderer is
    /// set up here, untimed).
    fn runner(&self, w: &Workload, threads: usize) -> Result<Runner<'_>> {
        Ok(match self {
            Self::Scene(scene) => Runner::Still(
                Box::new(Renderer::new(scene, &w.settings(scene, threads))?),
                scene,
            ),
            Self::Views(bench) => Runner::Views(bench, threads),
        })
    }
}

/// One render of the suite, at fixed settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Workload {
    /// Short name (a key of [`EXPECTED_HASHES`]).
    pub name: &'static str,
    /// What it measures, in words.
    pub description: &'static str,
    /// The scene.
    pub scene: BenchScene,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Images a render makes (a views job's views; 1 for a scene).
    pub images: u32,
    /// Maximum path depth.
    pub max_depth: u32,
    /// Seed.
    pub seed: u64,
    /// The estimator.
    pub integrator: Integrator,
    /// The sampler.
    pub sampler: SamplerKind,
}

impl Workload {
    /// Load its scene, or write its views job to a temporary folder.
    pub fn prepare(&self) -> Result<Prepared> {
        Ok(match self.scene.load() {
            Some(scene) => Prepared::Scene(Box::new(scene)),
            None => Prepared::Views(Box::new(ViewsBench::new(self)?)),
        })
    }

    /// The render settings of this workload on `threads` threads.
    pub fn settings(&self, scene: &Scene, threads: usize) -> RenderSettings {
        let mut s = RenderSettings::for_scene(scene);
        s.width = self.width;
        s.height = self.height;
        s.spp = self.spp;
        s.max_depth = self.max_depth;
        s.seed = self.seed;
        s.threads = threads;
        s.integrator = self.integrator;
        s.sampler = self.sampler;
        s.rr_depth = None;
        s
    }

    /// Camera paths one render traces.
    pub fn paths(&self) -> u64 {
        self.width as u64 * self.height as u64 * self.spp as u64 * self.images as u64
    }

    /// The shipped hash of this workload's image at `size`, if any.
    pub fn expected_hash(&self, size: SuiteSize) -> Option<&'static str> {
        EXPECTED_HASHES
            .iter()
            .find(|(n, s, _)| *n == self.name && *s == size)
            .map(|(_, _, h)| *h)
    }
}

/// The suite's workloads at `size`. The default integrator workload uses
/// the build's defaults ([`DEFAULT_INTEGRATOR`], [`DEFAULT_SAMPLER`]).
pub fn workloads(size: SuiteSize) -> Vec<Workload> {
    // Samples per pixel of each workload: (report, default, sphere, views).
    let (res, spp) = match size {
        SuiteSize::Full => (256, [384, 288, 192, 24]),
        SuiteSize::Quick => (256, [64, 48, 32, 4]),
        SuiteSize::Tiny => (32, [4, 4, 2, 1]),
    };
    let w = |name, description, scene, spp, integrator, sampler| Workload {
        name,
        description,
        scene,
        width: res,
        height: res,
        spp,
        images: 1,
        max_depth: 3,
        seed: 1,
        integrator,
        sampler,
    };
    vec![
        w(
            "cornell-report",
            "Cornell box, the report's estimator (uniform hemisphere, independent numbers)",
            BenchScene::Cornell,
            spp[0],
            Integrator::Report,
            SamplerKind::Independent,
        ),
        w(
            "cornell-default",
            "Cornell box, the default integrator and sampler",
            BenchScene::Cornell,
            spp[1],
            DEFAULT_INTEGRATOR,
            DEFAULT_SAMPLER,
        ),
        w(
            "sphere-1m",
            "Cornell box with a 1,003,520-triangle sphere, the report's estimator",
            BenchScene::Sphere1m,
            spp[2],
            Integrator::Report,
            SamplerKind::Independent,
        ),
        Workload {
            images: 12,
            max_depth: 5,
            ..w(
                "asset-views",
                "wavetrace views: 12 views of a textured glTF asset under an HDR sky, with depth and normals (load and build included)",
                BenchScene::AssetViews,
                spp[3],
                DEFAULT_INTEGRATOR,
                DEFAULT_SAMPLER,
            )
        },
    ]
}

/// The hash that verifies an image: 64-bit xxh3 of its size, the samples
/// it holds and its exact per-pixel sums, as 16 hex digits.
pub fn film_hash(film: &Film) -> String {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(&film.width.to_le_bytes());
    h.update(&film.height.to_le_bytes());
    h.update(&film.samples_per_pixel().to_le_bytes());
    for p in &film.sums {
        for c in p {
            h.update(&c.to_le_bytes());
        }
    }
    format!("{:016x}", h.digest())
}

/// Render `w` once on `threads` threads, [prepared](Workload::prepare).
pub fn render_workload(w: &Workload, prepared: &Prepared, threads: usize) -> Result<Rendered> {
    prepared.runner(w, threads)?.render()
}

/// The default thread counts on a machine of `cores` cores: 1, the powers
/// of two below `cores`, and `cores`.
pub fn default_thread_counts(cores: usize) -> Vec<usize> {
    let mut t = vec![1];
    let mut n = 2;
    while n < cores {
        t.push(n);
        n *= 2;
    }
    if cores > 1 {
        t.push(cores);
    }
    t
}

/// What the running machine is.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Machine {
    /// The CPU's model name (`/proc/cpuinfo`), or "unknown".
    pub cpu_model: String,
    /// Threads the process may run at once (`available_parallelism`).
    pub cores: usize,
    /// Logical CPUs the kernel lists (`/proc/cpuinfo` processors).
    pub logical_cpus: usize,
    /// SIMD extensions the CPU has (detected at run time).
    pub cpu_simd: Vec<String>,
    /// Physical memory in bytes (`/proc/meminfo`), 0 if unknown.
    pub memory_bytes: u64,
    /// The operating system: `/etc/os-release`'s name and the kernel
    /// release, or the target's OS name.
    pub os: String,
}

impl Machine {
    /// The running machine.
    pub fn detect() -> Self {
        let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let cpu_model = cpuinfo
            .lines()
            .find_map(|line| {
                let (k, v) = line.split_once(':')?;
                (k.trim() == "model name" && !v.trim().is_empty()).then(|| v.trim().to_string())
            })
            .unwrap_or_else(|| "unknown".into());
        let logical_cpus = cpuinfo
            .lines()
            .filter(|l| l.split(':').next().is_some_and(|k| k.trim() == "processor"))
            .count();
        let memory_bytes = std::fs::read_to_string("/proc/meminfo")
            .ok()
            .and_then(|m| {
                let line = m.lines().find(|l| l.starts_with("MemTotal:"))?;
                let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
                Some(kib * 1024)
            })
            .unwrap_or(0);
        let distro = std::fs::read_to_string("/etc/os-release")
            .ok()
            .and_then(|t| {
                t.lines().find_map(|l| {
                    l.strip_prefix("PRETTY_NAME=")
                        .map(|v| v.trim_matches('"').to_string())
                })
            });
        let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease")
            .ok()
            .map(|k| format!("Linux {}", k.trim()));
        let os = match (distro, kernel) {
            (Some(d), Some(k)) => format!("{d}, {k}"),
            (Some(d), None) => d,
            (None, Some(k)) => k,
            (None, None) => std::env::consts::OS.to_string(),
        };
        Self {
            cpu_model,
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            logical_cpus,
            cpu_simd: cpu_simd(),
            memory_bytes,
            os,
        }
    }
}

/// The SIMD extensions the running CPU has, of those wavetrace could use.
fn cpu_simd() -> Vec<String> {
    #[allow(unused_mut)]
    let mut found: Vec<&str> = Vec::new();
    #[cfg(target_arch = "x86_64")]
    {
        macro_rules! detect {
            ($($f:tt),*) => {$(
                if std::arch::is_x86_feature_detected!($f) {
                    found.push($f);
                }
            )*};
        }
        detect!("sse2", "sse4.1", "sse4.2", "avx", "avx2", "fma", "avx512f");
    }
    #[cfg(target_arch = "aarch64")]
    {
        if std::arch::is_aarch64_feature_detected!("neon") {
            found.push("neon");
        }
    }
    found.into_iter().map(String::from).collect()
}

/// What the running build is.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Build {
    /// wavetrace's version.
    pub version: String,
    /// The git commit it was built from, or "unknown".
    pub git_commit: String,
    /// The SIMD target features it was compiled with.
    pub target_features: Vec<String>,
    /// The target's architecture.
    pub arch: String,
}

impl Build {
    /// This build.
    pub fn this() -> Self {
        let mut target_features = Vec::new();
        macro_rules! features {
            ($($f:tt),*) => {$(
                if cfg!(target_feature = $f) {
                    target_features.push($f.to_string());
                }
            )*};
        }
        features!(
            "sse2", "sse4.1", "sse4.2", "avx", "avx2", "fma", "avx512f", "neon", "simd128"
        );
        Self {
            version: env!("CARGO_PKG_VERSION").into(),
            git_commit: env!("WAVETRACE_GIT_COMMIT").into(),
            target_features,
            arch: std::env::consts::ARCH.into(),
        }
    }
}

/// A workload's timings at one thread count.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThreadResult {
    /// Worker threads.
    pub threads: usize,
    /// Render seconds of every repeat, in order.
    pub seconds: Vec<f64>,
    /// Their median.
    pub median_seconds: f64,
    /// Spread of the repeats: `(max - min) / median`.
    pub spread: f64,
    /// Camera paths per render.
    pub paths: u64,
    /// Rays per render (closest-hit and shadow rays).
    pub rays: u64,
    /// Million paths per second, at the median time.
    pub mpaths_per_s: f64,
    /// Million rays per second, at the median time.
    pub mrays_per_s: f64,
    /// Speed-up over 1 thread (medians), when 1 thread was run.
    pub speedup: Option<f64>,
    /// Scaling efficiency: speed-up ÷ threads.
    pub efficiency: Option<f64>,
    /// The share of the machine's CPU time that other processes used
    /// during these repeats (from `/proc/stat`, less this process's own);
    /// `None` where it cannot be read. Above [`BUSY_SHARE`] the timings
    /// were taken on a busy machine.
    #[serde(default)]
    pub others_cpu: Option<f64>,
    /// Where the rendering time went: each wavefront stage's share of
    /// their time, over the repeats (empty for a report from before).
    #[serde(default)]
    pub stages: std::collections::BTreeMap<String, f64>,
    /// Of that time, the share spent looking textures up (inside *light*,
    /// *bounce* and *shade*; 0 without textures or in a report from before).
    #[serde(default)]
    pub texture_share: f64,
}

impl ThreadResult {
    /// Whether other processes used more than [`BUSY_SHARE`] of the CPU
    /// during these repeats.
    pub fn busy(&self) -> bool {
        self.others_cpu.is_some_and(|s| s > BUSY_SHARE)
    }
}

/// The share of the machine's CPU time that other processes may use
/// during a timed run before its figures are marked `BUSY`.
pub const BUSY_SHARE: f64 = 0.05;

/// The fewest clock ticks (of all CPUs together; usually 100 a second
/// each) over which other processes' share is measured: the counts are
/// whole ticks, so a shorter window says little.
pub const MIN_TICKS: u64 = 20;

/// CPU time, in clock ticks: the machine's busy and total time (all CPUs,
/// from `/proc/stat`) and this process's (from `/proc/self/stat`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CpuTimes {
    /// Ticks the CPUs were busy (all but idle and I/O wait).
    pub busy: u64,
    /// All ticks.
    pub total: u64,
    /// Ticks this process ran (user and system).
    pub own: u64,
}

impl CpuTimes {
    /// Now; `None` where `/proc` cannot be read (not Linux).
    pub fn now() -> Option<Self> {
        let machine = std::fs::read_to_string("/proc/stat").ok()?;
        let own = std::fs::read_to_string("/proc/self/stat").ok()?;
        Self::parse(&machine, &own)
    }

    /// From the texts of `/proc/stat` and `/proc/self/stat`.
    pub fn parse(proc_stat: &str, self_stat: &str) -> Option<Self> {
        let line = proc_stat.lines().find(|l| l.starts_with("cpu "))?;
        let ticks: Vec<u64> = line
            .split_whitespace()
            .skip(1)
            .map(|x| x.parse().ok())
            .collect::<Option<_>>()?;
        // user nice system idle iowait irq softirq steal (guest time is
        // already in user and nice).
        let total: u64 = ticks.iter().take(8).sum();
        let idle = ticks.get(3)? + ticks.get(4).copied().unwrap_or(0);
        // Fields after the command name (which may hold spaces and
        // parentheses): state is field 3, utime 14, stime 15.
        let fields: Vec<&str> = self_stat.rsplit_once(')')?.1.split_whitespace().collect();
        let own = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
        Some(Self {
            busy: total.checked_sub(idle)?,
            total,
            own,
        })
    }

    /// The share of the machine's CPU time from `self` to `later` that
    /// other processes used: its busy time less this process's, over all
    /// of it; `None` for a window too short to tell (under [`MIN_TICKS`]).
    pub fn others_share(&self, later: &Self) -> Option<f64> {
        let total = later.total.saturating_sub(self.total);
        if total < MIN_TICKS {
            return None;
        }
        let busy = later.busy.saturating_sub(self.busy);
        let own = later.own.saturating_sub(self.own);
        Some(busy.saturating_sub(own) as f64 / total as f64)
    }
}

/// A workload's results.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorkloadResult {
    /// Its name.
    pub name: String,
    /// What it measures.
    pub description: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Images a render makes (a views job's views; 1 for a scene).
    #[serde(default = "one")]
    pub images: u32,
    /// Maximum path depth.
    pub max_depth: u32,
    /// Seed.
    pub seed: u64,
    /// Integrator name.
    pub integrator: String,
    /// Sampler name.
    pub sampler: String,
    /// Triangles in the scene.
    pub triangles: usize,
    /// The shipped hash, if the build has one for this size.
    pub expected_hash: Option<String>,
    /// Every distinct hash its renders gave (one, on a sound machine).
    pub hashes: Vec<String>,
    /// Whether every render gave the shipped hash.
    pub verified: bool,
    /// Timings by thread count.
    pub runs: Vec<ThreadResult>,
}

/// 1: what reports of suite 1, before views, held.
fn one() -> u32 {
    1
}

/// The overall scores: geometric means over the workloads.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// Mpaths/s on 1 thread (when 1 thread was run).
    pub single_thread_mpaths: Option<f64>,
    /// Mrays/s on 1 thread.
    pub single_thread_mrays: Option<f64>,
    /// The thread count of the all-threads score: the largest run.
    pub all_threads: usize,
    /// Mpaths/s on `all_threads` threads.
    pub all_threads_mpaths: f64,
    /// Mrays/s on `all_threads` threads.
    pub all_threads_mrays: f64,
    /// Mean scaling efficiency at `all_threads` (geometric mean).
    pub efficiency: Option<f64>,
}

/// Everything a bench run found: written by `--json`, read by `--compare`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchReport {
    /// [`SUITE_VERSION`].
    pub suite_version: u32,
    /// The suite's size.
    pub size: SuiteSize,
    /// Repeats per thread count.
    pub repeats: usize,
    /// The machine.
    pub machine: Machine,
    /// The build.
    pub build: Build,
    /// Whether every workload was verified.
    pub verified: bool,
    /// Per-workload results.
    pub workloads: Vec<WorkloadResult>,
    /// The overall scores.
    pub scores: Scores,
    /// Wall-clock seconds of the whole run (loading and setup included).
    pub wall_seconds: f64,
}

/// What the suite reports as it goes.
pub trait BenchObserver {
    /// The suite starts: `total` units of work (paths ÷ threads, summed over
    /// every render, roughly proportional to time).
    fn start(&mut self, total: u64);
    /// Now at `done` units; `what` says what is running.
    fn progress(&mut self, done: u64, what: &str);
    /// The suite is done.
    fn finish(&mut self);
}

/// An observer that reports nothing.
pub struct Silent;

impl BenchObserver for Silent {
    fn start(&mut self, _: u64) {}
    fn progress(&mut self, _: u64, _: &str) {}
    fn finish(&mut self) {}
}

/// The median of `x` (not empty).
pub fn median(x: &[f64]) -> f64 {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The geometric mean of `x` (not empty, positive).
pub fn geometric_mean(x: &[f64]) -> f64 {
    (x.iter().map(|v| v.ln()).sum::<f64>() / x.len() as f64).exp()
}

/// Run the suite: each workload at each of `threads` (sorted, deduplicated),
/// `repeats` times, verifying every image.
pub fn run_suite(
    size: SuiteSize,
    threads: &[usize],
    repeats: usize,
    observer: &mut dyn BenchObserver,
) -> Result<BenchReport> {
    let mut threads = threads.to_vec();
    threads.sort_unstable();
    threads.dedup();
    if threads.is_empty() || threads[0] == 0 {
        return Err(Error::Settings(
            "bench: thread counts must be at least 1".into(),
        ));
    }
    if repeats == 0 {
        return Err(Error::Settings("bench: repeats must be at least 1".into()));
    }
    let start = Instant::now();
    let list = workloads(size);
    let units = |w: &Workload, t: usize| w.paths() / t as u64;
    let total: u64 = list
        .iter()
        .map(|w| threads.iter().map(|&t| units(w, t)).sum::<u64>() * repeats as u64)
        .sum();
    observer.start(total);
    let mut done = 0;
    let mut results = Vec::new();
    for w in &list {
        observer.progress(done, &format!("{}: loading the scene", w.name));
        let prepared = w.prepare()?;
        let expected = w.expected_hash(size);
        let mut hashes: Vec<String> = Vec::new();
        let mut runs = Vec::new();
        let mut t1: Option<f64> = None;
        let mut triangles = 0;
        for &t in &threads {
            observer.progress(done, &format!("{}: {t} thread(s), setting up", w.name));
            let runner = prepared.runner(w, t)?;
            let mut seconds = Vec::new();
            let mut last = None;
            let mut stages = StageSeconds::default();
            let cpu_before = CpuTimes::now();
            for r in 0..repeats {
                observer.progress(
                    done,
                    &format!("{}: {t} thread(s), run {}/{repeats}", w.name, r + 1),
                );
                let rendered = runner.render()?;
                if !hashes.contains(&rendered.hash) {
                    hashes.push(rendered.hash.clone());
                }
                seconds.push(rendered.seconds);
                triangles = rendered.triangles;
                stages += rendered.stages;
                last = Some(rendered);
                done += units(w, t);
                observer.progress(done, w.name);
            }
            let others_cpu = cpu_before
                .zip(CpuTimes::now())
                .and_then(|(a, b)| a.others_share(&b));
            let c = last.expect("at least one repeat");
            let med = median(&seconds);
            let max = seconds.iter().copied().fold(f64::MIN, f64::max);
            let min = seconds.iter().copied().fold(f64::MAX, f64::min);
            if t == 1 {
                t1 = Some(med);
            }
            let speedup = t1.map(|t1| t1 / med);
            runs.push(ThreadResult {
                threads: t,
                spread: (max - min) / med,
                median_seconds: med,
                seconds,
                paths: c.paths,
                rays: c.rays,
                mpaths_per_s: c.paths as f64 / med / 1e6,
                mrays_per_s: c.rays as f64 / med / 1e6,
                speedup,
                efficiency: speedup.map(|s| s / t as f64),
                others_cpu,
                stages: stage_shares(&stages),
                texture_share: texture_share(&stages),
            });
        }
        let verified = expected.is_some_and(|e| hashes.len() == 1 && hashes[0] == e);
        results.push(WorkloadResult {
            name: w.name.into(),
            description: w.description.into(),
            width: w.width,
            height: w.height,
            spp: w.spp,
            images: w.images,
            max_depth: w.max_depth,
            seed: w.seed,
            integrator: w.integrator.name().into(),
            sampler: w.sampler.name().into(),
            triangles,
            expected_hash: expected.map(String::from),
            hashes,
            verified,
            runs,
        });
    }
    observer.finish();
    let scores = scores(&results);
    Ok(BenchReport {
        suite_version: SUITE_VERSION,
        size,
        repeats,
        machine: Machine::detect(),
        build: Build::this(),
        verified: results.iter().all(|w| w.verified),
        workloads: results,
        scores,
        wall_seconds: start.elapsed().as_secs_f64(),
    })
}

/// Each stage's share of the stages' time, by name (empty when nothing
/// was timed).
pub fn stage_shares(stages: &StageSeconds) -> std::collections::BTreeMap<String, f64> {
    let total: f64 = Stage::ALL.iter().map(|s| stages.of(*s)).sum();
    if total <= 0.0 {
        return Default::default();
    }
    (Stage::ALL.iter())
        .map(|s| (s.name().to_string(), stages.of(*s) / total))
        .collect()
}

/// The texture lookups' share of the stages' time
/// ([`StageSeconds::textures`]; 0 when nothing was timed).
pub fn texture_share(stages: &StageSeconds) -> f64 {
    let total: f64 = Stage::ALL.iter().map(|s| stages.of(*s)).sum();
    if total > 0.0 {
        stages.textures() / total
    } else {
        0.0
    }
}

/// The overall scores of `results` (every workload run at the same thread
/// counts).
pub fn scores(results: &[WorkloadResult]) -> Scores {
    fn single(r: &[ThreadResult]) -> Option<&ThreadResult> {
        r.iter().find(|r| r.threads == 1)
    }
    fn all(r: &[ThreadResult]) -> Option<&ThreadResult> {
        r.last()
    }
    let at = |pick: fn(&[ThreadResult]) -> Option<&ThreadResult>,
              f: fn(&ThreadResult) -> Option<f64>| {
        let v: Option<Vec<f64>> = results.iter().map(|w| pick(&w.runs).and_then(f)).collect();
        v.filter(|v| !v.is_empty()).map(|v| geometric_mean(&v))
    };
    Scores {
        single_thread_mpaths: at(single, |r| Some(r.mpaths_per_s)),
        single_thread_mrays: at(single, |r| Some(r.mrays_per_s)),
        all_threads: results
            .first()
            .and_then(|w| w.runs.last())
            .map_or(0, |r| r.threads),
        all_threads_mpaths: at(all, |r| Some(r.mpaths_per_s)).unwrap_or(0.0),
        all_threads_mrays: at(all, |r| Some(r.mrays_per_s)).unwrap_or(0.0),
        efficiency: at(all, |r| r.efficiency),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thread_counts() {
        assert_eq!(default_thread_counts(1), vec![1]);
        assert_eq!(default_thread_counts(2), vec![1, 2]);
        assert_eq!(default_thread_counts(6), vec![1, 2, 4, 6]);
        assert_eq!(default_thread_counts(8), vec![1, 2, 4, 8]);
    }

    #[test]
    fn other_processes_cpu_time_is_read_from_proc() {
        let stat = |user: u64, idle: u64| {
            format!("cpu  {user} 0 100 {idle} 0 0 0 0 0 0\ncpu0 1 2 3 4 5 6 7 8 9 10\n")
        };
        // The command name may hold spaces and parentheses.
        let me = |ticks: u64| {
            format!("1234 (a (b) c) R 1 2 3 4 5 6 7 8 9 10 {ticks} 0 0 0 20 0 1 0 5 6 7")
        };
        let a = CpuTimes::parse(&stat(1000, 5000), &me(300)).unwrap();
        assert_eq!((a.busy, a.total, a.own), (1100, 6100, 300));
        // 1000 ticks later: 600 busy, 400 of them this process's.
        let b = CpuTimes::parse(&stat(1600, 5400), &me(700)).unwrap();
        assert!((a.others_share(&b).unwrap() - 0.2).abs() < 1e-12);
        // Only this process busy: no one else.
        let c = CpuTimes::parse(&stat(1600, 5400), &me(900)).unwrap();
        assert_eq!(a.others_share(&c), Some(0.0));
        // Too short a window to tell.
        let d = CpuTimes::parse(&stat(1005, 5005), &me(300)).unwrap();
        assert_eq!(a.others_share(&d), None);
        assert!(CpuTimes::parse("intr 1 2", &me(1)).is_none());
        #[cfg(target_os = "linux")]
        assert!(CpuTimes::now().is_some());
    }

    #[test]
    fn statistics() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!((geometric_mean(&[1.0, 4.0]) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn every_workload_has_a_hash_at_every_size() {
        for size in [SuiteSize::Full, SuiteSize::Quick, SuiteSize::Tiny] {
            for w in workloads(size) {
                assert!(w.expected_hash(size).is_some(), "{} {size:?}", w.name);
            }
        }
    }
}
