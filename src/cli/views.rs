//! `wavetrace views`: datasets of many views of many assets (docs/views.md).

use crate::error::{Error, Result};
use crate::render::Engine;
use crate::run::session::Interrupt;
use crate::run::shard::ShardSpec;
use crate::run::views::{DEFAULT_CHECKPOINT_EVERY, ViewsEvent, ViewsOptions, ViewsReport};
use crate::scene::environment::{EnvSource, Environment};
use crate::scene::punctual::sun_from_words;
use crate::scene::views_job::{
    CameraSet, DEFAULT_SIZE, DEFAULT_SPP, DEFAULT_VFOV_DEG, ViewsJob, ViewsOutputs, ViewsRender,
};
use crate::scene::{AovSet, Integrator};
use clap::Args;
use indicatif::{HumanDuration, ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Options of `wavetrace views`: a job file, or one asset from flags.
#[derive(Debug, Args)]
pub struct ViewsArgs {
    /// The job file (TOML, docs/views.md); or give --asset and the flags below.
    #[arg(conflicts_with = "asset")]
    pub job: Option<PathBuf>,
    /// Where to write: a folder per asset, with its views, camera files and manifest.
    #[arg(long, value_name = "DIR")]
    pub out_dir: PathBuf,
    /// Write the run's figures (per asset and per view times) as JSON.
    #[arg(long, value_name = "FILE")]
    pub stats: Option<PathBuf>,
    /// Print nothing but the summary (and failures); the default without a terminal.
    #[arg(long, short)]
    pub quiet: bool,

    /// Without a job file: the asset (glTF, GLB, PLY, OBJ or TOML scene); repeat for more.
    #[arg(long, value_name = "FILE", help_heading = "Job from flags")]
    pub asset: Vec<PathBuf>,
    /// Centre each asset and scale it to the unit cube.
    #[arg(long, help_heading = "Job from flags")]
    pub normalize: bool,
    /// An orbit of N views per elevation [default: 12].
    #[arg(long, value_name = "N", help_heading = "Job from flags", conflicts_with_all = ["fibonacci", "random", "cameras"])]
    pub orbit: Option<u32>,
    /// The orbit's elevations, degrees, comma-separated [default: 30].
    #[arg(
        long,
        value_name = "DEG,...",
        value_delimiter = ',',
        allow_negative_numbers = true,
        help_heading = "Job from flags"
    )]
    pub elevation: Vec<f32>,
    /// N views spread evenly over the sphere.
    #[arg(long, value_name = "N", help_heading = "Job from flags", conflicts_with_all = ["random", "cameras"])]
    pub fibonacci: Option<u32>,
    /// N seeded random views on a shell around the asset.
    #[arg(
        long,
        value_name = "N",
        help_heading = "Job from flags",
        conflicts_with = "cameras"
    )]
    pub random: Option<u32>,
    /// Cameras from a JSON file (transforms.json's format).
    #[arg(long, value_name = "FILE.json", help_heading = "Job from flags")]
    pub cameras: Option<PathBuf>,
    /// Vertical field of view of generated cameras, degrees [default: 40].
    #[arg(long, value_name = "DEG", help_heading = "Job from flags")]
    pub fov: Option<f32>,
    /// An environment (.exr, .hdr, or R,G,B); repeat for a seeded choice per view.
    #[arg(long, value_name = "FILE|R,G,B", help_heading = "Job from flags")]
    pub env: Vec<String>,
    /// Turn the environment by a seeded random angle per view.
    #[arg(long, help_heading = "Job from flags")]
    pub random_rotation: bool,
    /// A sun: the way its light goes and its irradiance in W/m² (docs/lights.md); repeatable.
    #[arg(
        long,
        value_name = "X,Y,Z,IRRADIANCE",
        allow_hyphen_values = true,
        help_heading = "Job from flags"
    )]
    pub sun: Vec<String>,
    /// Image width [default: 512].
    #[arg(long, value_name = "W", help_heading = "Job from flags")]
    pub width: Option<u32>,
    /// Image height [default: 512].
    #[arg(long, value_name = "H", help_heading = "Job from flags")]
    pub height: Option<u32>,
    /// Samples per pixel [default: 64].
    #[arg(long, short = 's', value_name = "N", help_heading = "Job from flags")]
    pub spp: Option<u32>,
    /// Estimator [default: nee].
    #[arg(long, value_parser = super::render::named(Integrator::NAMES, Integrator::from_name), help_heading = "Job from flags")]
    pub integrator: Option<Integrator>,
    /// The job's seed.
    #[arg(long, value_name = "S", help_heading = "Job from flags")]
    pub seed: Option<u64>,
    /// AOVs to write beside the colour: depth, zdepth, normal, albedo, variance, object_id, alpha (in the colour files).
    #[arg(long, value_name = "LIST", value_parser = AovSet::parse_list, help_heading = "Job from flags")]
    pub aov: Option<AovSet>,
    /// Also write the colour as linear EXR.
    #[arg(long, help_heading = "Job from flags")]
    pub exr: bool,
    /// Denoise the colour (Open Image Denoise).
    #[arg(long, help_heading = "Job from flags")]
    pub denoise: bool,
    /// Adaptive sampling: a pixel stops taking samples once its estimated relative error is at most this (e.g. 0.02).
    #[arg(long, value_name = "ERROR", help_heading = "Job from flags")]
    pub noise_threshold: Option<f32>,
    /// With --noise-threshold: the samples every pixel takes first [default: spp/16, at least 4].
    #[arg(long, value_name = "N", help_heading = "Job from flags")]
    pub min_spp: Option<u32>,

    /// Render shard I of N (from 0) of the (asset, view) pairs, or `auto` from Slurm or Kubernetes.
    #[arg(long, value_name = "I/N|auto", value_parser = ShardSpec::parse, help_heading = "Farm")]
    pub shard: Option<ShardSpec>,
    /// With --shard auto: the number of shards.
    #[arg(long, value_name = "N", help_heading = "Farm")]
    pub shard_count: Option<u32>,
    /// Worker threads [default: SLURM_CPUS_PER_TASK, else all cores].
    #[arg(long, short = 't', value_name = "N", help_heading = "Tuning")]
    pub threads: Option<usize>,
    /// Path tracer: wavefront (fast) or reference (the scalar oracle).
    #[arg(long, value_parser = super::render::named(Engine::NAMES, |n| Engine::from_name(n).ok()), help_heading = "Tuning")]
    pub engine: Option<Engine>,
    /// Save the view in progress this often, in seconds (and when stopped), so a killed run goes on from there [default: 60].
    #[arg(long, value_name = "SECONDS", value_parser = super::render::parse_seconds, help_heading = "Tuning")]
    pub checkpoint_every: Option<Duration>,
    /// Paths per wavefront batch; never changes the images.
    #[arg(long, value_name = "PATHS", help_heading = "Tuning")]
    pub batch_size: Option<usize>,
}

impl ViewsArgs {
    /// `--noise-threshold` and `--min-spp`, checked as a job file's
    /// `render.noise_threshold` and `render.min_spp` are.
    fn adaptive(&self) -> Result<Option<crate::scene::Adaptive>> {
        let spp = self.spp.unwrap_or(DEFAULT_SPP);
        let Some(threshold) = self.noise_threshold else {
            return match self.min_spp {
                Some(_) => Err(Error::Settings(
                    "--min-spp is the first round of adaptive sampling: give --noise-threshold too"
                        .into(),
                )),
                None => Ok(None),
            };
        };
        let a = crate::scene::Adaptive {
            threshold,
            min_spp: (self.min_spp).unwrap_or(crate::scene::Adaptive::default_min_spp(spp)),
        };
        if !crate::scene::Adaptive::threshold_ok(threshold) {
            return Err(Error::Settings(format!(
                "--noise-threshold {threshold}: must be a number at least 0"
            )));
        }
        if !crate::scene::Adaptive::min_spp_ok(a.min_spp, spp) {
            return Err(Error::Settings(format!(
                "--min-spp {}: must be between 2 and --spp ({spp})",
                a.min_spp
            )));
        }
        Ok(Some(a))
    }

    /// Whether any flag of the job-from-flags group is set.
    fn job_flags(&self) -> Vec<&'static str> {
        let set = [
            (self.normalize, "--normalize"),
            (self.orbit.is_some(), "--orbit"),
            (!self.elevation.is_empty(), "--elevation"),
            (self.fibonacci.is_some(), "--fibonacci"),
            (self.random.is_some(), "--random"),
            (self.cameras.is_some(), "--cameras"),
            (self.fov.is_some(), "--fov"),
            (!self.env.is_empty(), "--env"),
            (self.random_rotation, "--random-rotation"),
            (!self.sun.is_empty(), "--sun"),
            (self.width.is_some(), "--width"),
            (self.height.is_some(), "--height"),
            (self.spp.is_some(), "--spp"),
            (self.integrator.is_some(), "--integrator"),
            (self.seed.is_some(), "--seed"),
            (self.aov.is_some(), "--aov"),
            (self.exr, "--exr"),
            (self.denoise, "--denoise"),
            (self.noise_threshold.is_some(), "--noise-threshold"),
            (self.min_spp.is_some(), "--min-spp"),
        ];
        set.iter().filter(|(on, _)| *on).map(|(_, f)| *f).collect()
    }

    /// The job: the job file, or one made from the flags.
    fn job(&self) -> Result<ViewsJob> {
        if let Some(path) = &self.job {
            let flags = self.job_flags();
            if !flags.is_empty() {
                return Err(Error::Settings(format!(
                    "{} set(s) the job from flags; with a job file, write it in {} instead",
                    flags.join(", "),
                    path.display()
                )));
            }
            return Ok(ViewsJob::load(path)?);
        }
        if self.asset.is_empty() {
            return Err(Error::Settings(
                "give a job file (wavetrace views JOB.toml --out-dir DIR) or --asset FILE".into(),
            ));
        }
        self.job_from_flags()
    }

    fn job_from_flags(&self) -> Result<ViewsJob> {
        let settings = |m: String| Error::Settings(m);
        let positive = |v: Option<u32>, flag: &str| match v {
            Some(0) => Err(settings(format!("{flag} 0: must be at least 1"))),
            v => Ok(v),
        };
        let vfov = match self.fov {
            Some(f) if !(f > 0.0 && f < 180.0) => {
                return Err(settings(format!(
                    "--fov {f}: must be strictly between 0 and 180 degrees"
                )));
            }
            f => f.unwrap_or(DEFAULT_VFOV_DEG),
        };
        if self
            .elevation
            .iter()
            .any(|e| !(e.is_finite() && e.abs() < 90.0))
        {
            return Err(settings(
                "--elevation: angles strictly between -90 and 90 degrees".into(),
            ));
        }
        let cameras = if let Some(file) = &self.cameras {
            CameraSet::Explicit(crate::scene::views_job::read_cameras(file)?)
        } else if let Some(n) = positive(self.fibonacci, "--fibonacci")? {
            CameraSet::Fibonacci {
                views: n,
                distance: None,
                vfov_deg: vfov,
            }
        } else if let Some(n) = positive(self.random, "--random")? {
            CameraSet::Random {
                views: n,
                distance: None,
                vfov_deg: [vfov, vfov],
            }
        } else {
            CameraSet::Orbit {
                views: positive(self.orbit, "--orbit")?.unwrap_or(12),
                elevations_deg: if self.elevation.is_empty() {
                    vec![30.0]
                } else {
                    self.elevation.clone()
                },
                azimuth_deg: 0.0,
                distance: None,
                vfov_deg: vfov,
            }
        };
        let mut environments = Vec::new();
        for e in &self.env {
            let env = Environment::load(&EnvSource::parse(e), 1.0, 0.0, true)
                .map_err(|m| settings(format!("--env {e}: {m}")))?;
            environments.push(env);
        }
        let lights = (self.sun.iter())
            .map(|w| sun_from_words(w).map_err(|m| settings(format!("--sun {m}"))))
            .collect::<Result<Vec<_>>>()?;
        let mut assets = Vec::new();
        for a in &self.asset {
            match crate::scene::views_job::expand_glob(a) {
                Some(found) if found.is_empty() => {
                    return Err(settings(format!(
                        "--asset {}: no file matches",
                        a.display()
                    )));
                }
                Some(found) => assets.extend(found),
                None => assets.push(a.clone()),
            }
        }
        Ok(ViewsJob {
            file: "the command line".into(),
            assets,
            normalize: self.normalize,
            cameras,
            target: None,
            environments,
            lights,
            random_rotation: self.random_rotation,
            render: ViewsRender {
                width: positive(self.width, "--width")?.unwrap_or(DEFAULT_SIZE),
                height: positive(self.height, "--height")?.unwrap_or(DEFAULT_SIZE),
                spp: positive(self.spp, "--spp")?.unwrap_or(DEFAULT_SPP),
                max_depth: None,
                integrator: self.integrator,
                seed: self.seed.unwrap_or(0),
                denoise: self.denoise,
                adaptive: self.adaptive()?,
            },
            outputs: ViewsOutputs {
                png: true,
                exr: self.exr,
                aovs: self.aov.unwrap_or_default(),
                camera_normals: false,
            },
        })
    }
}

/// Run `wavetrace views`. Exit status 0 when every view of the share is
/// written; 1 when some asset failed (the rest were rendered); 130 or 143
/// when a signal stopped it (finished views are kept).
pub fn run(args: ViewsArgs) -> Result<ExitCode> {
    let job = args.job()?;
    let env = |name: &str| std::env::var(name).ok();
    let shard = match args.shard {
        None => None,
        Some(ShardSpec::Fixed { index, count }) => Some((index, count)),
        Some(ShardSpec::Auto) => Some(crate::run::shard::auto_shard(args.shard_count, &env)?),
    };
    let threads = match args.threads {
        Some(t) => t,
        None => crate::run::shard::threads_from_env(&env)?
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
    };
    if threads == 0 || threads > crate::render::MAX_THREADS {
        return Err(Error::Settings(format!(
            "--threads {threads}: 1 to {}",
            crate::render::MAX_THREADS
        )));
    }
    if let Some(stats) = &args.stats {
        // The stats may go into the output directory, which the run
        // would create: create it first (a farm's first shard finds none).
        std::fs::create_dir_all(&args.out_dir)
            .map_err(|e| crate::fs::FileError::new(&args.out_dir, e))?;
        crate::fs::check_writable(stats)?;
    }
    let options = ViewsOptions {
        out_dir: args.out_dir.clone(),
        shard,
        threads,
        engine: args.engine.unwrap_or(Engine::Wavefront),
        batch_size: args.batch_size,
        checkpoint_every: args.checkpoint_every.unwrap_or(DEFAULT_CHECKPOINT_EVERY),
        pass_samples: None,
    };
    let quiet = args.quiet || !std::io::stderr().is_terminal();
    let interrupt = Interrupt::install()?;
    let stop = || interrupt.requested().is_some();
    let start = Instant::now();
    let mut bar = Bar::new(!quiet);
    let report = crate::run::views::run(&job, &options, &stop, &mut |e| bar.event(e))?;
    bar.bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    for a in report.failed() {
        eprintln!(
            "failed: {} ({}): {}",
            a.name,
            a.file,
            a.error.as_deref().unwrap_or("")
        );
    }
    if let Some(path) = &args.stats {
        let text = stats_json(&job, &options, &report, seconds);
        crate::fs::write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    }
    println!("{}", summary(&report, seconds, &options));
    if let Some(sig) = interrupt.requested() {
        eprintln!(
            "stopped by {}: finished views are kept; run the same command again to go on",
            crate::run::session::signal_name(sig)
        );
        return Ok(ExitCode::from(128 + sig as u8));
    }
    Ok(match report.failed().count() {
        0 => ExitCode::SUCCESS,
        _ => ExitCode::FAILURE,
    })
}

/// Images per hour at `rendered` views in `seconds`.
fn per_hour(rendered: u64, seconds: f64) -> f64 {
    if seconds > 0.0 {
        rendered as f64 * 3600.0 / seconds
    } else {
        0.0
    }
}

/// The one summary line (stdout).
fn summary(r: &ViewsReport, seconds: f64, o: &ViewsOptions) -> String {
    let loaded: Vec<_> = r.assets.iter().filter(|a| a.views_rendered > 0).collect();
    let mean = |f: &dyn Fn(&crate::run::views::AssetReport) -> f64, n: f64| {
        if n > 0.0 {
            loaded.iter().map(|a| f(a)).sum::<f64>() / n
        } else {
            0.0
        }
    };
    let n_assets = loaded.len() as f64;
    let n_views = r.rendered as f64;
    let shard = o
        .shard
        .map_or(String::new(), |(i, n)| format!(" (shard {i}/{n})"));
    let failed = r.failed().count();
    format!(
        "views: {} rendered, {} skipped (finished earlier) of {}{shard}, {} asset(s){} in {:.3} s: {:.0} images/hour; per asset load {:.3} s, build {:.3} s; per view render {:.3} s, write {:.3} s -> {}",
        r.rendered,
        r.skipped,
        r.views,
        r.assets.len(),
        if failed > 0 {
            format!(", {failed} FAILED")
        } else {
            String::new()
        },
        seconds,
        per_hour(r.rendered, seconds),
        mean(&|a| a.load_seconds, n_assets),
        mean(&|a| a.build_seconds, n_assets),
        mean(&|a| a.render_seconds, n_views),
        mean(&|a| a.write_seconds, n_views),
        o.out_dir.display()
    )
}

/// The `--stats` JSON of a run.
fn stats_json(job: &ViewsJob, o: &ViewsOptions, r: &ViewsReport, seconds: f64) -> String {
    let doc = serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "git_commit": crate::cli::stats::GIT_COMMIT,
        "cpu_model": crate::cli::stats::cpu_model(),
        "job": job.file,
        "out_dir": o.out_dir.display().to_string(),
        "shard": o.shard.map(|(i, n)| [i, n]),
        "threads": o.threads,
        "engine": o.engine.name(),
        "width": job.render.width,
        "height": job.render.height,
        "spp": job.render.spp,
        "views_per_asset": job.view_count(),
        "views": r.views,
        "rendered": r.rendered,
        "skipped": r.skipped,
        "failed": r.failed().map(|a| a.file.clone()).collect::<Vec<_>>(),
        "stopped": r.stopped,
        "seconds": seconds,
        "images_per_hour": per_hour(r.rendered, seconds),
        "assets": r.assets,
    });
    serde_json::to_string_pretty(&doc).expect("JSON") + "\n"
}

/// The bar over views, with images per hour and the time left.
struct Bar {
    bar: indicatif::ProgressBar,
    start: Instant,
    rendered: u64,
}

impl Bar {
    fn new(show: bool) -> Self {
        let bar = if show {
            indicatif::ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
        } else {
            indicatif::ProgressBar::hidden()
        };
        Self {
            bar,
            start: Instant::now(),
            rendered: 0,
        }
    }

    fn event(&mut self, e: ViewsEvent) {
        match e {
            ViewsEvent::Planned { views } => {
                let style = ProgressStyle::with_template(
                    "{elapsed_precise} [{wide_bar}] {human_pos}/{human_len} views  {msg}",
                )
                .expect("the progress template is valid")
                .progress_chars("=> ");
                self.bar.set_style(style);
                self.bar.set_length(views);
                self.bar.enable_steady_tick(Duration::from_millis(250));
            }
            ViewsEvent::View { skipped, .. } => {
                self.bar.inc(1);
                if skipped {
                    return;
                }
                self.rendered += 1;
                let secs = self.start.elapsed().as_secs_f64();
                let left = self
                    .bar
                    .length()
                    .unwrap_or(0)
                    .saturating_sub(self.bar.position());
                let eta = secs / self.rendered as f64 * left as f64;
                self.bar.set_message(format!(
                    "{:.0} images/h  ETA {}",
                    per_hour(self.rendered, secs),
                    HumanDuration(Duration::from_secs_f64(eta))
                ));
            }
            ViewsEvent::Asset(a) => {
                if let Some(e) = &a.error
                    && !self.bar.is_hidden()
                {
                    self.bar
                        .suspend(|| eprintln!("failed: {} ({}): {e}", a.name, a.file));
                }
            }
        }
    }
}
