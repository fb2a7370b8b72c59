//! The command line: `wavetrace render ...` (the default command).

use crate::error::{Error, Result};
use crate::output::{check_writable, write_atomic};
use crate::profile::Profile;
use crate::render::{Engine, RenderSettings, Renderer};
use crate::scene::Scene;
use crate::stats::RenderStats;
use clap::{Args, Parser, Subcommand};
use std::io::Write;
use std::path::PathBuf;

/// wavetrace: a fast, reproducible CPU path tracer.
#[derive(Debug, Parser)]
#[command(
    name = "wavetrace",
    version,
    about,
    args_conflicts_with_subcommands = true
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
    /// Merge the partial files of shards into the image of the whole render.
    Merge(crate::merge::MergeArgs),
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
    /// Worker threads (default: SLURM_CPUS_PER_TASK if set, else all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Path tracer.
    #[arg(long, value_enum)]
    pub engine: Option<Engine>,
    /// Output image: .png (8-bit sRGB), .exr or .pfm (linear float), or
    /// .wtacc for a partial file. Default: the scene file's name with .png
    /// (cornell.png), or none when --partial is given.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the render's figures as JSON to this file.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Farm options: sample ranges, shards, partial files.
    #[command(flatten)]
    pub farm: crate::shard::ShardArgs,
}

/// Run the command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        None => render(cli.render),
        Some(Command::Render(args)) => render(args),
        Some(Command::Merge(args)) => crate::merge::run(args),
    }
}

/// The settings, scene and output a render command asks for, all checked.
struct Job {
    scene: Scene,
    settings: RenderSettings,
    out: Option<PathBuf>,
    stats: Option<PathBuf>,
    work: crate::shard::SampleWork,
    partial: Option<PathBuf>,
    check: bool,
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
    let env = |name: &str| std::env::var(name).ok();
    settings.threads = match args.threads {
        Some(threads) => threads,
        None => crate::shard::threads_from_env(&env)?.unwrap_or(settings.threads),
    };
    settings.engine = args.engine.or(profile_engine).unwrap_or(settings.engine);
    settings.validate()?;
    let work = args.farm.resolve(settings.spp, &env)?;
    let partial = args.farm.partial.clone();
    if work.range != (0..settings.spp) && args.out.is_none() && partial.is_none() {
        return Err(Error::Settings(format!(
            "rendering samples {}..{} only: name the partial file to write with --partial FILE.wtacc",
            work.range.start, work.range.end
        )));
    }

    let default_out = (args.out.is_none() && partial.is_none()).then(|| {
        let stem = args
            .scene
            .as_ref()
            .and_then(|p| p.file_stem())
            .map_or("cornell".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from(format!("{stem}.png"))
    });
    let out = args.out.or(default_out);
    if let Some(out) = &out {
        crate::shard::check_output_format(out)?;
        check_writable(out)?;
    }
    if let Some(partial) = &partial {
        crate::shard::check_partial_path(partial)?;
        check_writable(partial)?;
    }
    if let Some(stats) = &args.stats {
        check_writable(stats)?;
    }
    Ok(Job {
        scene,
        settings,
        out,
        stats: args.stats,
        work,
        partial,
        check: args.farm.check,
    })
}

fn render(args: RenderArgs) -> Result<()> {
    let job = plan(args)?;
    let s = &job.settings;
    let w = &job.work;
    let part = match w.shard {
        _ if w.range == (0..s.spp) => String::new(),
        Some((i, n)) => format!(
            " (samples {}..{}: shard {i}/{n})",
            w.range.start, w.range.end
        ),
        None => format!(" (samples {}..{})", w.range.start, w.range.end),
    };
    eprintln!(
        "wavetrace: {} at {}x{}, {} spp{part}, max depth {}, seed {}, {} thread(s), {} engine",
        job.scene.name,
        s.width,
        s.height,
        s.spp,
        s.max_depth,
        s.seed,
        s.threads,
        s.engine.name()
    );
    let renderer = Renderer::new(&job.scene, s)?;
    if job.check {
        println!("check: ok, nothing rendered");
        return Ok(());
    }
    let mut film = renderer.new_film();
    let start = std::time::Instant::now();
    let counters = renderer.render_samples(w.range.clone(), &mut film);
    let seconds = start.elapsed().as_secs_f64();
    let meta = crate::film::AccMeta {
        settings_hash: s.image_hash(&job.scene),
        spp: Some(s.spp),
        shard: w.shard,
    };
    if let Some(out) = &job.out {
        crate::shard::write_output(out, &film, &meta)?;
    }
    if let Some(partial) = &job.partial {
        film.save_with_meta(partial, &meta)?;
    }
    let written = job
        .out
        .as_ref()
        .or(job.partial.as_ref())
        .expect("an output");

    let stats = RenderStats {
        version: env!("CARGO_PKG_VERSION"),
        scene: job.scene.name.clone(),
        width: s.width,
        height: s.height,
        spp: film.samples_per_pixel(),
        max_depth: s.max_depth,
        seed: s.seed,
        threads: s.threads,
        engine: s.engine.name(),
        seconds,
        paths: counters.paths,
        rays: counters.rays,
        rays_per_second: counters.rays as f64 / seconds,
        paths_per_second: counters.paths as f64 / seconds,
        invalid_samples: film.invalid_samples,
        output: Some(written.display().to_string()),
    };
    if film.invalid_samples > 0 {
        eprintln!(
            "warning: {} sample(s) were NaN, infinite or negative and were left out of the image",
            film.invalid_samples
        );
    }
    println!(
        "rendered in {:.3} s: {} paths ({:.3} M paths/s), {} rays ({:.2} M rays/s) -> {}",
        seconds,
        counters.paths,
        stats.paths_per_second / 1e6,
        counters.rays,
        stats.rays_per_second / 1e6,
        written.display()
    );
    if let Some(path) = &job.stats {
        write_atomic(path, |w| w.write_all(stats.to_json().as_bytes()))?;
    }
    Ok(())
}

impl From<clap::Error> for Error {
    fn from(e: clap::Error) -> Self {
        Error::Settings(e.to_string())
    }
}
