//! The command line: `wavetrace render ...` (the default command).

use crate::error::{Error, Result};
use crate::output::{ImageFormat, check_writable, write_atomic, write_image};
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
}

/// Run the command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        None => render(cli.render),
        Some(Command::Render(args)) => render(args),
    }
}

/// The settings, scene and output a render command asks for, all checked.
struct Job {
    scene: Scene,
    settings: RenderSettings,
    out: PathBuf,
    stats: Option<PathBuf>,
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
    Ok(Job {
        scene,
        settings,
        out,
        stats: args.stats,
    })
}

fn render(args: RenderArgs) -> Result<()> {
    let job = plan(args)?;
    let s = &job.settings;
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
    let renderer = Renderer::new(&job.scene, s)?;
    if let Some(b) = renderer.bvh() {
        eprintln!(
            "bvh: {} triangles, {} nodes, {:.1} MiB, built in {:.3} s",
            b.triangle_count(),
            b.node_count(),
            b.bytes() as f64 / (1 << 20) as f64,
            b.build_seconds()
        );
    }
    let (film, counters, elapsed) = renderer.render();
    let seconds = elapsed.as_secs_f64();
    write_image(&job.out, film.width, film.height, &film.to_rgb())?;

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
        triangles: job.scene.triangles.len(),
        bvh_nodes: renderer.bvh().map_or(0, |b| b.node_count()),
        build_seconds: renderer.bvh().map_or(0.0, |b| b.build_seconds()),
        bvh_bytes: renderer.bvh().map_or(0, |b| b.bytes()),
        output: Some(job.out.display().to_string()),
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
        job.out.display()
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
