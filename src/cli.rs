//! The command line: `wavetrace render ...` (the default command).

use crate::error::{Error, Result};
use crate::film::Film;
use crate::output::{ImageFormat, check_writable, write_atomic, write_image};
use crate::profile::Profile;
use crate::render::{Engine, RenderSettings, Renderer};
use crate::scene::Scene;
use crate::session::{Interrupt, Session, SessionOptions, Stop};
use crate::stats::RenderStats;
use crate::stats::Stages;
use clap::{Args, Parser, Subcommand};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// wavetrace: a fast, reproducible CPU path tracer.
#[derive(Debug, Parser)]
#[command(
    name = "wavetrace",
    version,
    about,
    args_conflicts_with_subcommands = true,
    after_help = "Exit status: 0 when the image was written (all samples, or as many as \
                  --time-limit allowed); 1 on an error (2 for a malformed command line); 130 (SIGINT) or \
                  143 (SIGTERM) when a signal stopped the render after its current pass, \
                  the checkpoint saved. A second SIGINT/SIGTERM exits at once with status 1, \
                  leaving the last checkpoint as it was."
)]
pub struct Cli {
    /// What to do; `render` when omitted.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// The render options, when no command is given.
    #[command(flatten)]
    pub render: RenderArgs,
}

/// wavetrace's commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a scene to an image.
    Render(RenderArgs),
}

/// Options of `wavetrace render`. Flags override the profile, which
/// overrides the scene's defaults.
#[derive(Debug, Default, Args)]
pub struct RenderArgs {
    /// Scene file (TOML); the built-in Cornell box when omitted.
    pub scene: Option<PathBuf>,
    /// Render preset: a built-in name (preview, default, seed-figure8) or a
    /// path to a profile file.
    #[arg(long, default_value = "default")]
    pub profile: Option<String>,
    /// Image width in pixels.
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels.
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Maximum path depth (the camera ray is depth 0).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Random seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Path tracer.
    #[arg(long, value_enum)]
    pub engine: Option<Engine>,
    /// Output image: .png (8-bit sRGB), .exr or .pfm (linear float).
    /// Default: the scene file's name with .png (cornell.png).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the render's figures as JSON to this file.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Print nothing but the final summary (no banner, no progress bar).
    /// Without a terminal on stderr that is the default.
    #[arg(long, short)]
    pub quiet: bool,
    /// Stop rendering, after whole sample passes, once the next pass would
    /// not fit in this many seconds, and write the image with the samples
    /// done; --spp stays the most that are rendered.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub time_limit: Option<Duration>,
    /// Save the accumulated samples to this file every --checkpoint-every
    /// seconds, on SIGINT or SIGTERM (then exit with status 130 or 143),
    /// and at the end. Refused if the file exists, unless it is the
    /// --resume file.
    #[arg(long, value_name = "FILE")]
    pub checkpoint: Option<PathBuf>,
    /// Seconds between checkpoints [default: 60].
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub checkpoint_every: Option<Duration>,
    /// Continue the render saved in this checkpoint file (made with the
    /// same scene and settings; --spp and --threads may differ), and keep
    /// checkpointing to it unless --checkpoint names another file.
    #[arg(long, value_name = "FILE")]
    pub resume: Option<PathBuf>,
    /// Write the image so far to --out every this many seconds, so a
    /// viewer can watch it converge.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub write_partial: Option<Duration>,
}

/// A positive, finite number of seconds, e.g. `30` or `0.5`.
fn parse_seconds(text: &str) -> std::result::Result<Duration, String> {
    let seconds: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("{text:?} is not a number of seconds"))?;
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(format!("{text:?}: must be a positive number of seconds"));
    }
    Duration::try_from_secs_f64(seconds).map_err(|e| format!("{text:?}: {e}"))
}

/// Run the command line. Returns the process exit status: 0 when the image
/// was written, 128 + the signal number (130 for SIGINT, 143 for SIGTERM)
/// when a signal stopped the render (after saving the checkpoint). Errors
/// are for the caller to print (exit status 1).
pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        None => render(cli.render),
        Some(Command::Render(args)) => render(args),
    }
}

/// The settings, scene and output a render command asks for, all checked.
struct Job {
    scene: Scene,
    settings: RenderSettings,
    /// [`RenderSettings::image_hash`]: what checkpoints are checked against.
    settings_hash: u128,
    out: PathBuf,
    stats: Option<PathBuf>,
    quiet: bool,
    /// The film to continue (`--resume`), already checked.
    resumed: Option<Film>,
    resume: Option<PathBuf>,
    session: SessionOptions,
}

fn plan(args: RenderArgs) -> Result<Job> {
    let scene = match &args.scene {
        Some(path) => Scene::load(path)?,
        None => Scene::cornell(),
    };
    let profile = match &args.profile {
        Some(name) => Profile::load(name)?,
        None => Profile::default(),
    };
    let mut settings = RenderSettings::for_scene(&scene);
    let profile_engine = profile
        .engine
        .as_deref()
        .map(Engine::from_name)
        .transpose()?;
    settings.width = args.width.or(profile.width).unwrap_or(settings.width);
    settings.height = args.height.or(profile.height).unwrap_or(settings.height);
    settings.spp = args.spp.or(profile.spp).unwrap_or(settings.spp);
    settings.max_depth = args
        .max_depth
        .or(profile.max_depth)
        .unwrap_or(settings.max_depth);
    settings.seed = args.seed.or(profile.seed).unwrap_or(settings.seed);
    settings.threads = args.threads.unwrap_or(settings.threads);
    settings.engine = args.engine.or(profile_engine).unwrap_or(settings.engine);
    settings.validate()?;

    let out = args.out.unwrap_or_else(|| {
        let stem = args
            .scene
            .as_ref()
            .and_then(|p| p.file_stem())
            .map_or("cornell".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from(format!("{stem}.png"))
    });
    ImageFormat::from_path(&out)?;
    check_writable(&out)?;
    if let Some(stats) = &args.stats {
        check_writable(stats)?;
    }

    let settings_hash = settings.image_hash(&scene);
    let checkpoint = args.checkpoint.clone().or_else(|| args.resume.clone());
    if args.checkpoint_every.is_some() && checkpoint.is_none() {
        return Err(Error::Settings(
            "--checkpoint-every needs --checkpoint FILE (or --resume FILE)".into(),
        ));
    }
    if let Some(path) = &checkpoint {
        if same_file(path, &out) {
            return Err(Error::Settings(format!(
                "{}: the checkpoint cannot be the output image",
                path.display()
            )));
        }
        let resumes_it = args.resume.as_ref().is_some_and(|r| same_file(r, path));
        if !resumes_it && path.exists() {
            return Err(Error::Settings(format!(
                "{}: the checkpoint file exists and may hold another render's work; \
                 continue it with --resume {0}, or remove it",
                path.display()
            )));
        }
        check_writable(path)?;
    }
    // The checkpoint to continue is read and checked in full before any
    // work: a missing, truncated, corrupt or foreign one is refused here and
    // left as it is.
    let resumed = match &args.resume {
        Some(path) => {
            let (film, _) = Film::load(path, Some(settings_hash))?;
            Some(film)
        }
        None => None,
    };
    if let (Some(film), Some(path)) = (&resumed, &args.resume) {
        crate::session::check_resumable(film, &settings).map_err(|message| {
            Error::Accumulation {
                path: path.clone(),
                message,
            }
        })?;
    }

    let mut session = SessionOptions {
        time_limit: args.time_limit,
        checkpoint,
        checkpoint_every: args
            .checkpoint_every
            .unwrap_or(crate::session::DEFAULT_CHECKPOINT_EVERY),
        ..SessionOptions::default()
    };
    if let Some(every) = args.write_partial {
        session.partial_image = Some(out.clone());
        session.partial_every = every;
    }
    Ok(Job {
        scene,
        settings,
        settings_hash,
        out,
        stats: args.stats,
        quiet: args.quiet,
        resumed,
        resume: args.resume,
        session,
    })
}

/// Whether two paths name the same file (compared as written when either
/// does not exist yet).
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

fn render(args: RenderArgs) -> Result<ExitCode> {
    let load_start = Instant::now();
    let mut job = plan(args)?;
    let mut stages = Stages {
        load: load_start.elapsed().as_secs_f64(),
        ..Stages::default()
    };
    let quiet = job.quiet || !std::io::stderr().is_terminal();
    job.session.progress = !quiet;
    let s = &job.settings;
    if !quiet {
        eprintln!(
            "wavetrace: {} at {}x{}, {} spp, max depth {}, seed {}, {} thread(s), {} engine",
            job.scene.name,
            s.width,
            s.height,
            s.spp,
            s.max_depth,
            s.seed,
            s.threads,
            s.engine.name()
        );
    }
    let setup_start = Instant::now();
    let renderer = Renderer::new(&job.scene, s)?;
    if !quiet {
        let b = renderer.bvh();
        eprintln!(
            "bvh: {} triangles, {} nodes, {:.1} MiB, built in {:.3} s",
            b.triangle_count(),
            b.node_count(),
            b.bytes() as f64 / (1 << 20) as f64,
            b.build_seconds()
        );
    }
    let interrupt = Interrupt::install()?;
    stages.setup = setup_start.elapsed().as_secs_f64();

    let film = job.resumed.take().unwrap_or_else(|| renderer.new_film());
    let mut session = Session::new(&renderer, job.settings_hash, job.session.clone());
    let report = session.run(film, &interrupt)?;
    let film = &report.film;
    stages.render = report.render_seconds;
    stages.partial_images = report.partial_seconds;
    let mut checkpoint_seconds = report.checkpoint_seconds;
    let mut checkpoints_saved = report.checkpoints_saved;
    let mut output = None;

    // The checkpoint is saved first, and both it and the image are tried
    // even if the other fails, so a full disk loses as little as possible.
    let t = Instant::now();
    let saved = session.save_checkpoint(film);
    checkpoint_seconds += t.elapsed().as_secs_f64();
    let image = match report.stop {
        // Stopped by a signal: no final image, only the partial one, brought
        // up to the checkpoint.
        Stop::Signal(_) => job.session.partial_image.clone().map(|p| (p, false)),
        Stop::Complete | Stop::TimeLimit => Some((job.out.clone(), true)),
    };
    let written = image.map(|(path, is_final)| {
        let t = Instant::now();
        let r = write_image(&path, film.width, film.height, &film.to_rgb());
        let secs = t.elapsed().as_secs_f64();
        if is_final {
            stages.output = secs;
        } else {
            stages.partial_images += secs;
        }
        output = r.is_ok().then(|| path.display().to_string());
        r
    });
    if let Some(Err(e)) = written {
        if let Err(c) = saved {
            eprintln!("error: {c}");
        }
        return Err(e);
    }
    checkpoints_saved += saved? as u32;
    stages.checkpoint = checkpoint_seconds;

    let counters = report.counters;
    let seconds = report.render_seconds;
    let per_second = |n: u64| {
        if seconds > 0.0 {
            n as f64 / seconds
        } else {
            0.0
        }
    };
    let stats = RenderStats {
        version: env!("CARGO_PKG_VERSION"),
        git_commit: crate::stats::GIT_COMMIT,
        cpu_model: crate::stats::cpu_model(),
        simd: crate::stats::SIMD,
        scene: job.scene.name.clone(),
        width: s.width,
        height: s.height,
        spp: film.samples_per_pixel(),
        spp_requested: s.spp,
        spp_resumed: report.start_spp,
        max_depth: s.max_depth,
        seed: s.seed,
        threads: s.threads,
        engine: s.engine.name(),
        stop: report.stop.name(),
        time_limit_seconds: job.session.time_limit.map(|d| d.as_secs_f64()),
        passes: report.passes,
        longest_pass_seconds: report.longest_pass_seconds,
        seconds,
        elapsed_seconds: report.elapsed_seconds,
        paths: counters.paths,
        rays: counters.rays,
        rays_per_second: per_second(counters.rays),
        paths_per_second: per_second(counters.paths),
        invalid_samples: film.invalid_samples,
        stages,
        engine_stages: counters.stages.by_name(),
        checkpoint: job
            .session
            .checkpoint
            .as_ref()
            .map(|p| p.display().to_string()),
        checkpoints_saved,
        partial_images: report.partial_images,
        output,
        triangles: job.scene.triangles.len(),
        bvh_nodes: renderer.bvh().node_count(),
        build_seconds: renderer.bvh().build_seconds(),
        bvh_bytes: renderer.bvh().bytes(),
    };
    if film.invalid_samples > 0 {
        eprintln!(
            "warning: {} sample(s) were NaN, infinite or negative and were left out of the image",
            film.invalid_samples
        );
    }
    println!("{}", summary(&job, &report, &stats));
    if let Some(path) = &job.stats {
        write_atomic(path, |w| w.write_all(stats.to_json().as_bytes()))?;
    }
    Ok(ExitCode::from(report.stop.exit_status()))
}

/// The one line a render prints at the end (on stdout).
fn summary(job: &Job, report: &crate::session::SessionReport, stats: &RenderStats) -> String {
    let done = stats.spp;
    let resumed = match (&job.resume, report.start_spp) {
        (Some(path), n) => format!(" (resumed from {} at {n} spp)", path.display()),
        (None, _) => String::new(),
    };
    let speed = format!(
        "{} paths ({:.3} M paths/s), {} rays ({:.2} M rays/s)",
        stats.paths,
        stats.paths_per_second / 1e6,
        stats.rays,
        stats.rays_per_second / 1e6
    );
    match report.stop {
        Stop::Complete | Stop::TimeLimit => {
            let limit = if report.stop == Stop::TimeLimit {
                format!(" of {} (time limit)", stats.spp_requested)
            } else {
                String::new()
            };
            format!(
                "rendered {done} spp{limit}{resumed} in {:.3} s: {speed} -> {}",
                stats.seconds,
                job.out.display()
            )
        }
        Stop::Signal(sig) => {
            let saved = match &job.session.checkpoint {
                Some(path) => format!(
                    "checkpoint saved to {0}; continue with --resume {0}",
                    path.display()
                ),
                None => "no --checkpoint was given, so the samples are lost".into(),
            };
            format!(
                "stopped by {} at {done} of {} spp{resumed} after {:.3} s: {saved}",
                crate::session::signal_name(sig),
                stats.spp_requested,
                stats.seconds
            )
        }
    }
}

impl From<clap::Error> for Error {
    fn from(e: clap::Error) -> Self {
        Error::Settings(e.to_string())
    }
}
