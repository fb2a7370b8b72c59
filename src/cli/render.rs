//! `wavetrace render`: flags, checks, the session, outputs and the summary.

use crate::accel::simd::SimdWidth;
use crate::cli::ViewArgs;
use crate::cli::profile::Profile;
use crate::cli::progress::ProgressBar;
use crate::cli::stats::{RenderStats, Stages};
use crate::denoise::{Aux, Denoiser};
use crate::error::{Error, Result};
use crate::film::{AccMeta, Film, WtaccError};
use crate::fs::{check_outputs, check_writable, same_file, write_atomic};
use crate::metrics::ImageErrors;
use crate::output::view::ViewTransform;
use crate::output::{
    aov_path, check_output_format, check_partial_path, read_radiance, write_image_with_aovs,
    write_output_viewed,
};
use crate::render::{Engine, RenderSettings, Renderer};
use crate::run::session::{Interrupt, Session, SessionOptions, Stop};
use crate::run::shard::{SampleRequest, SampleWork, ShardSpec, parse_samples};
use crate::scene::{Aov, AovSet, Integrator, SamplerKind, Scene};
use clap::Args;
use std::io::{IsTerminal, Write};
use std::ops::Range;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Options of `wavetrace render`. Flags override the profile, which
/// overrides the scene's defaults. Each has a one-line description here;
/// docs/cli.md tells the rest.
#[derive(Debug, Default, Args)]
pub struct RenderArgs {
    /// Scene file (TOML), or an asset (.gltf, .glb, .ply); the built-in
    /// Cornell box when omitted.
    pub scene: Option<PathBuf>,
    /// The camera of a glTF asset to render through: its name or its index
    /// [default: the file's first, else a view that frames the asset].
    #[arg(long, value_name = "NAME|INDEX", help_heading = "Output")]
    pub camera: Option<String>,

    /// The image: .png (8-bit sRGB), .exr or .pfm (linear float), or .wtacc
    /// [default: SCENE.png].
    #[arg(long, short = 'o', value_name = "FILE", help_heading = "Output")]
    pub out: Option<PathBuf>,
    /// Write the render's settings, times and speeds as JSON (docs/stats.md).
    #[arg(long, value_name = "FILE", help_heading = "Output")]
    pub stats: Option<PathBuf>,
    /// Also accumulate these AOVs: albedo, normal, depth, variance (docs/aov.md).
    #[arg(long, value_name = "LIST", value_parser = parse_aovs, help_heading = "Output")]
    pub aov: Option<AovSet>,
    /// A transparent background: rays from the camera that leave the scene
    /// see black, and the image gets the coverage as alpha (docs/aov.md).
    #[arg(long, help_heading = "Output")]
    pub transparent: bool,
    /// Denoise the image with Intel Open Image Denoise (`pip install pyoidn`).
    #[arg(long, help_heading = "Output")]
    pub denoise: bool,
    /// With --denoise: also write the noisy image to this file.
    #[arg(
        long,
        value_name = "FILE",
        requires = "denoise",
        help_heading = "Output"
    )]
    pub keep_noisy: Option<PathBuf>,
    /// The PNG view: --exposure, --view.
    #[command(flatten)]
    pub view: ViewArgs,
    /// Print nothing but the summary line (and warnings); the default
    /// without a terminal.
    #[arg(long, short, help_heading = "Output")]
    pub quiet: bool,

    /// Samples per pixel.
    #[arg(long, short = 's', value_name = "N", help_heading = "Quality")]
    pub spp: Option<u32>,
    /// Image width in pixels [default: the scene's].
    #[arg(long, value_name = "W", help_heading = "Quality")]
    pub width: Option<u32>,
    /// Image height in pixels [default: the scene's].
    #[arg(long, value_name = "H", help_heading = "Quality")]
    pub height: Option<u32>,
    /// A preset: preview, default, seed-figure8, or a profile file.
    #[arg(
        long,
        value_name = "NAME",
        default_value = "default",
        help_heading = "Quality"
    )]
    pub profile: Option<String>,
    /// Maximum path depth (the camera ray is depth 0).
    #[arg(long, value_name = "D", help_heading = "Quality")]
    pub max_depth: Option<u32>,
    /// Random seed: the same seed gives the same image.
    #[arg(long, value_name = "S", help_heading = "Quality")]
    pub seed: Option<u64>,
    /// Estimator [default: nee] (docs/integrators.md).
    #[arg(long, value_parser = named(Integrator::NAMES, Integrator::from_name), help_heading = "Quality")]
    pub integrator: Option<Integrator>,
    /// Sample numbers [default: sobol].
    #[arg(long, value_parser = named(SamplerKind::NAMES, SamplerKind::from_name), help_heading = "Quality")]
    pub sampler: Option<SamplerKind>,
    /// Russian roulette from this depth on [default: off].
    #[arg(long, value_name = "D", help_heading = "Quality")]
    pub rr_depth: Option<u32>,
    /// A converged image (.exr, .pfm): print the result's error against it.
    #[arg(long, value_name = "IMAGE", help_heading = "Quality")]
    pub reference: Option<PathBuf>,

    /// Stop after whole sample passes once the next would not fit in this time.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds, help_heading = "Time")]
    pub time_limit: Option<Duration>,
    /// Save progress to this .wtacc file periodically and on Ctrl-C/SIGTERM.
    #[arg(long, value_name = "FILE", help_heading = "Time")]
    pub checkpoint: Option<PathBuf>,
    /// Seconds between checkpoints [default: 60].
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds, help_heading = "Time")]
    pub checkpoint_every: Option<Duration>,
    /// Continue the render saved in this checkpoint (and keep saving to it).
    #[arg(long, value_name = "FILE", help_heading = "Time")]
    pub resume: Option<PathBuf>,
    /// Rewrite --out with the image so far every this many seconds.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds, help_heading = "Time")]
    pub write_partial: Option<Duration>,

    /// Lighting: an environment for any scene.
    #[command(flatten)]
    pub light: super::light::LightArgs,

    /// Farm options: sample ranges, shards, partial files.
    #[command(flatten)]
    pub farm: FarmArgs,

    /// Worker threads [default: SLURM_CPUS_PER_TASK, else all cores].
    #[arg(long, short = 't', value_name = "N", help_heading = "Tuning")]
    pub threads: Option<usize>,
    /// Path tracer: wavefront (fast) or reference (the scalar oracle).
    #[arg(long, value_parser = named(Engine::NAMES, |n| Engine::from_name(n).ok()), help_heading = "Tuning")]
    pub engine: Option<Engine>,
    /// Lanes of the intersection kernels, 8 or 16 [default: the widest the CPU runs].
    #[arg(long, value_name = "LANES", value_parser = parse_simd, help_heading = "Tuning")]
    pub simd: Option<SimdWidth>,
    /// Paths per wavefront batch [default: 4096]; never changes the image.
    #[arg(long, value_name = "PATHS", help_heading = "Tuning")]
    pub batch_size: Option<usize>,
}

/// A flag whose value is one of `names`, turned into a `T` by `from_name`
/// (`--help` lists the names).
pub(crate) fn named<T: Clone + Send + Sync + 'static>(
    names: &'static [&'static str],
    from_name: fn(&str) -> Option<T>,
) -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(names)
        .map(move |name: String| from_name(&name).expect("one of the possible values"))
}

/// A comma list of AOV names.
fn parse_aovs(text: &str) -> std::result::Result<AovSet, String> {
    AovSet::parse_list(text)
}

/// `8` or `16` lanes.
fn parse_simd(text: &str) -> std::result::Result<SimdWidth, String> {
    text.parse()
        .ok()
        .and_then(SimdWidth::from_lanes)
        .ok_or_else(|| format!("{text:?}: the kernels run 8 or 16 lanes"))
}

/// A positive, finite number of seconds, e.g. `30` or `0.5`.
pub(crate) fn parse_seconds(text: &str) -> std::result::Result<Duration, String> {
    let seconds: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("{text:?} is not a number of seconds"))?;
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(format!("{text:?}: must be a positive number of seconds"));
    }
    Duration::try_from_secs_f64(seconds).map_err(|e| format!("{text:?}: {e}"))
}

/// The farm options of `wavetrace render`: sample ranges, shards, partial
/// files (docs/farm.md).
#[derive(Clone, Debug, Default, Args)]
pub struct FarmArgs {
    /// Render only sample indices A..B of every pixel, out of 0..spp.
    #[arg(long, value_name = "A..B", value_parser = parse_samples, conflicts_with = "shard", help_heading = "Farm")]
    pub samples: Option<Range<u32>>,
    /// Render shard I of N (from 0), or `auto` from Slurm or Kubernetes.
    #[arg(long, value_name = "I/N|auto", value_parser = ShardSpec::parse, help_heading = "Farm")]
    pub shard: Option<ShardSpec>,
    /// With --shard auto: the number of shards.
    #[arg(long, value_name = "N", help_heading = "Farm")]
    pub shard_count: Option<u32>,
    /// Write the partial file (.wtacc) for `wavetrace merge`.
    #[arg(long, value_name = "FILE.wtacc", help_heading = "Farm")]
    pub partial: Option<PathBuf>,
    /// Check the scene, settings and outputs, say what would be rendered, exit.
    #[arg(long, help_heading = "Farm")]
    pub check: bool,
}

impl FarmArgs {
    /// The sample range or shard asked for.
    pub fn request(&self) -> SampleRequest {
        SampleRequest {
            samples: self.samples.clone(),
            shard: self.shard,
            shard_count: self.shard_count,
        }
    }
}

/// The settings, scene and outputs a render command asks for, all checked.
struct Job {
    scene: Scene,
    settings: RenderSettings,
    /// The header of every accumulation file the render writes
    /// (checkpoints, `--partial`, a `.wtacc` `--out`): the settings hash
    /// ([`RenderSettings::image_hash`], what checkpoints and parts are
    /// checked against), `spp` and the shard.
    meta: AccMeta,
    /// The image or `.wtacc` file to write at the end, if any.
    out: Option<PathBuf>,
    /// The partial file (`.wtacc`) to write at the end, if any.
    partial: Option<PathBuf>,
    /// The sample range to render (a shard's, or `0..spp`).
    work: SampleWork,
    /// `--check`: check everything, render nothing.
    check: bool,
    stats: Option<PathBuf>,
    quiet: bool,
    /// The film to continue (`--resume`), already checked.
    resumed: Option<Film>,
    resume: Option<PathBuf>,
    session: SessionOptions,
    /// `--reference`: its path and pixels, checked to be of the render's size.
    reference: Option<(PathBuf, Vec<[f32; 3]>)>,
    /// `--denoise`: the denoiser, loaded before any work starts.
    denoiser: Option<Denoiser>,
    /// `--keep-noisy`.
    keep_noisy: Option<PathBuf>,
    /// The AOVs' files beside a PNG or PFM `--out`.
    aov_files: Vec<PathBuf>,
    /// The exposure and view of a PNG `--out`.
    view: ViewTransform,
}

fn plan(args: RenderArgs) -> Result<Job> {
    let mut scene = match &args.scene {
        Some(path) => crate::cli::load_scene(path, args.camera.as_deref())?,
        None if args.camera.is_some() => {
            return Err(Error::Settings(
                "--camera chooses among a glTF asset's cameras: give the asset".into(),
            ));
        }
        None => Scene::cornell(),
    };
    args.light.apply(&mut scene)?;
    if args.transparent {
        scene.make_transparent();
    }
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
        None => match crate::run::shard::threads_from_env(&env)? {
            Some(n) if n > crate::render::MAX_THREADS => {
                return Err(Error::Settings(format!(
                    "environment variable SLURM_CPUS_PER_TASK is {n}: more than the {} worker threads a render may start; pass --threads N",
                    crate::render::MAX_THREADS
                )));
            }
            n => n.unwrap_or(settings.threads),
        },
    };
    settings.engine = args.engine.or(profile_engine).unwrap_or(settings.engine);
    let named = |name: &Option<String>, what: &str, known: &[&str]| match name {
        Some(n) if !known.contains(&n.as_str()) => Err(Error::Settings(format!(
            "profile: unknown {what} {n:?} (known: {})",
            known.join(", ")
        ))),
        _ => Ok(name.clone()),
    };
    let profile_integrator = named(&profile.integrator, "integrator", Integrator::NAMES)?
        .and_then(|n| Integrator::from_name(&n));
    let profile_sampler = named(&profile.sampler, "sampler", SamplerKind::NAMES)?
        .and_then(|n| SamplerKind::from_name(&n));
    settings.integrator = args
        .integrator
        .or(profile_integrator)
        .unwrap_or(settings.integrator);
    settings.sampler = args.sampler.or(profile_sampler).unwrap_or(settings.sampler);
    settings.rr_depth = args.rr_depth.or(profile.rr_depth).or(settings.rr_depth);
    let profile_aovs = match &profile.aov {
        Some(names) => Some(
            AovSet::from_names(names.iter().map(String::as_str))
                .map_err(|e| Error::Settings(format!("profile: aov: {e}")))?,
        ),
        None => None,
    };
    settings.aovs = args.aov.or(profile_aovs).unwrap_or(settings.aovs);
    if args.denoise {
        settings.aovs = settings.aovs.union(AovSet::DENOISE);
    }
    if args.transparent || scene.has_transparent_background() {
        settings.aovs = settings.aovs.with(Aov::Alpha);
    }
    settings.batch_size = args.batch_size.unwrap_or(settings.batch_size);
    settings.simd = args.simd.unwrap_or(settings.simd);
    settings.memory_limit = memory_limit_from_env(&env)?;
    settings.validate()?;
    // Before anything of the render's size is allocated (and for --check).
    settings.check_memory(scene.triangles.len())?;
    let work = args.farm.request().resolve(settings.spp, &env)?;
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
    let view = args.view.transform(out.as_deref())?;
    // The AOVs' files beside a PNG or PFM --out.
    let mut aov_files = Vec::new();
    if let Some(out) = &out {
        check_output_format(out)?;
        aov_files.extend(settings.aovs.iter().filter_map(|a| aov_path(out, a)));
    }
    if let Some(partial) = &partial {
        check_partial_path(partial)?;
    }
    if args.denoise {
        match &out {
            Some(out) if !crate::output::is_partial_path(out) => {}
            _ => {
                return Err(Error::Settings(
                    "--denoise needs --out IMAGE (.exr, .pfm or .png), not a partial file".into(),
                ));
            }
        }
    }
    if let Some(noisy) = &args.keep_noisy {
        check_output_format(noisy)?;
    }

    let meta = AccMeta {
        settings_hash: settings.image_hash(&scene),
        spp: Some(settings.spp),
        shard: work.shard,
    };
    let checkpoint = args.checkpoint.clone().or_else(|| args.resume.clone());
    if args.checkpoint_every.is_some() && checkpoint.is_none() {
        return Err(Error::Settings(
            "--checkpoint-every needs --checkpoint FILE (or --resume FILE)".into(),
        ));
    }
    let resumes_checkpoint = match (&args.resume, &checkpoint) {
        (Some(r), Some(c)) => same_file(r, c),
        _ => false,
    };
    if let Some(path) = &checkpoint {
        if out.as_deref().is_some_and(|out| same_file(path, out)) {
            return Err(Error::Settings(format!(
                "{}: the checkpoint cannot be the output image",
                path.display()
            )));
        }
        if partial.as_deref().is_some_and(|p| same_file(path, p)) {
            return Err(Error::Settings(format!(
                "{}: the checkpoint cannot be the --partial file (a checkpoint is \
                 work in progress, the partial file a finished shard)",
                path.display()
            )));
        }
        if !resumes_checkpoint && path.exists() {
            return Err(Error::Settings(format!(
                "{}: the checkpoint file exists and may hold another render's work; \
                 continue it with --resume {0}, or remove it",
                path.display()
            )));
        }
    }
    // No output may be an input or another output; then each must be
    // writable. Both before any work and before any file is made.
    let mut inputs = scene_inputs(&scene, args.scene.as_deref());
    if let Some(profile) = args.profile.as_deref().and_then(Profile::file) {
        inputs.push(("--profile", profile));
    }
    if let Some(reference) = &args.reference {
        inputs.push(("--reference", reference));
    }
    if let Some(resume) = args.resume.as_deref().filter(|_| !resumes_checkpoint) {
        inputs.push(("--resume", resume));
    }
    let mut outputs: Vec<(&str, &std::path::Path)> = Vec::new();
    outputs.extend(out.as_deref().map(|p| ("--out", p)));
    outputs.extend(
        aov_files
            .iter()
            .map(|f| ("an AOV file of --out", f.as_path())),
    );
    outputs.extend(args.keep_noisy.as_deref().map(|p| ("--keep-noisy", p)));
    outputs.extend(partial.as_deref().map(|p| ("--partial", p)));
    outputs.extend(args.stats.as_deref().map(|p| ("--stats", p)));
    let checkpoint_flag = if args.checkpoint.is_some() {
        "--checkpoint"
    } else {
        "the checkpoint (--resume)"
    };
    outputs.extend(checkpoint.as_deref().map(|p| (checkpoint_flag, p)));
    check_outputs(&inputs, &outputs)?;
    for (_, path) in &outputs {
        check_writable(path)?;
    }
    let denoiser = if args.denoise {
        Some(Denoiser::new()?)
    } else {
        None
    };
    // The checkpoint to continue is read and checked in full before any
    // work: a missing, truncated, corrupt or foreign one is refused here and
    // left as it is. Its samples must lie within this render's sample range
    // (0..spp, or the shard's): a shard's checkpoint resumes that shard.
    let resumed = match &args.resume {
        Some(path) => {
            let (film, saved) = Film::load_with_meta(path, Some(meta.settings_hash))?;
            crate::run::session::check_resumable(&film, &settings, &work.range).map_err(
                |mut message| {
                    if let Some((i, n)) = saved.shard {
                        message += &format!(" (it was saved by shard {i}/{n})");
                    }
                    Error::from(WtaccError {
                        path: path.clone(),
                        message,
                    })
                },
            )?;
            Some(film)
        }
        None => None,
    };

    let reference = match &args.reference {
        Some(path) => {
            let image = read_radiance(path, "the reference")?;
            if (image.width, image.height) != (settings.width, settings.height) {
                return Err(Error::Settings(format!(
                    "{}: the reference is {}x{}, the render {}x{}",
                    path.display(),
                    image.width,
                    image.height,
                    settings.width,
                    settings.height
                )));
            }
            Some((path.clone(), image.rgb))
        }
        None => None,
    };
    let partial_image = match (args.write_partial, &out) {
        (None, _) => None,
        (Some(every), Some(out)) => Some((out.clone(), every)),
        (Some(_), None) => {
            return Err(Error::Settings(
                "--write-partial rewrites the --out file: give --out as well".into(),
            ));
        }
    };
    let mut session = SessionOptions {
        samples: Some(work.range.clone()),
        time_limit: args.time_limit,
        checkpoint,
        checkpoint_every: args
            .checkpoint_every
            .unwrap_or(crate::run::session::DEFAULT_CHECKPOINT_EVERY),
        ..SessionOptions::default()
    };
    if let Some((path, every)) = partial_image {
        session.partial_image = Some(path);
        session.partial_every = every;
    }
    session.view = view;
    Ok(Job {
        scene,
        settings,
        meta,
        out,
        partial,
        work,
        check: args.farm.check,
        stats: args.stats,
        quiet: args.quiet,
        resumed,
        resume: args.resume,
        session,
        reference,
        denoiser,
        keep_noisy: args.keep_noisy,
        aov_files,
        view,
    })
}

/// `WAVETRACE_MAX_MEMORY`: the most memory a render may need, in bytes,
/// or with a binary suffix (`512M`, `16G`, `1T`); unset: the system's.
fn memory_limit_from_env(env: &dyn Fn(&str) -> Option<String>) -> Result<Option<u64>> {
    let Some(text) = env("WAVETRACE_MAX_MEMORY") else {
        return Ok(None);
    };
    let t = text.trim();
    let (digits, shift) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let shift = match c.to_ascii_uppercase() {
                'K' => 10,
                'M' => 20,
                'G' => 30,
                'T' => 40,
                _ => 64,
            };
            (&t[..i], shift)
        }
        _ => (t, 0),
    };
    digits
        .parse::<u64>()
        .ok()
        .filter(|_| shift < 64)
        .and_then(|n| n.checked_mul(1u64 << shift))
        .map(Some)
        .ok_or_else(|| {
            Error::Settings(format!(
                "environment variable WAVETRACE_MAX_MEMORY is {text:?}: expected a number of bytes, optionally with K, M, G or T"
            ))
        })
}

/// The files a loaded scene was read from ([`Scene::sources`]: the scene
/// file given as `scene`, its meshes, assets and environment image), each
/// with its role in messages.
pub(crate) fn scene_inputs<'a>(
    scene: &'a Scene,
    scene_file: Option<&std::path::Path>,
) -> Vec<(&'static str, &'a std::path::Path)> {
    scene
        .sources
        .iter()
        .map(|p| {
            let role = if Some(p.as_path()) == scene_file {
                "the scene"
            } else {
                "a file the scene reads"
            };
            (role, p.as_path())
        })
        .collect()
}

/// Run `wavetrace render`: the exit status, or an error for the caller to
/// print.
pub fn run(args: RenderArgs) -> Result<ExitCode> {
    let load_start = Instant::now();
    let mut job = plan(args)?;
    let mut stages = Stages {
        load: load_start.elapsed().as_secs_f64(),
        ..Stages::default()
    };
    let quiet = job.quiet || !std::io::stderr().is_terminal();
    let s = &job.settings;
    if let Some(warning) = job.scene.light_warning() {
        eprintln!("warning: {warning}");
    }
    if let Some(unreached) = job.scene.unreached_lights(s.integrator) {
        eprintln!("warning: {unreached}");
    }
    if job.check {
        // What would be rendered, on stdout: the scene, settings, shard,
        // resume and outputs are all checked by now (and the engine below).
        Renderer::new(&job.scene, s)?;
        println!(
            "check: ok: would render {}; nothing rendered",
            describe(&job)
        );
        return Ok(ExitCode::SUCCESS);
    }
    if !quiet {
        eprintln!("wavetrace: {}", describe(&job));
    }
    let setup_start = Instant::now();
    let renderer = Renderer::new(&job.scene, s)?;
    if !quiet {
        let b = renderer.bvh();
        let two_level = b.two_level().map_or(String::new(), |t| {
            format!(
                " (two-level: {} placements of {} unique triangles)",
                t.instance_count(),
                job.scene.instancing.unique_triangles()
            )
        });
        eprintln!(
            "bvh: {} triangles{two_level}, {} nodes, {:.1} MiB, built in {:.3} s",
            b.triangle_count(),
            b.node_count(),
            b.bytes() as f64 / (1 << 20) as f64,
            b.build_seconds()
        );
    }
    let interrupt = Interrupt::install()?;
    stages.setup = setup_start.elapsed().as_secs_f64();

    let film = job.resumed.take().unwrap_or_else(|| renderer.new_film());
    let mut session = Session::new(&renderer, job.meta, job.session.clone());
    let mut bar = ProgressBar::new(!quiet);
    let report = session.run(film, &interrupt, &mut bar)?;
    let film = &report.film;
    stages.render = report.render_seconds;
    stages.partial_images = report.partial_seconds;
    let mut checkpoint_seconds = report.checkpoint_seconds;
    let mut checkpoints_saved = report.checkpoints_saved;
    let mut output = None;
    let mut partial_written = None;

    // The checkpoint is saved first, and it and every output are tried even
    // if another fails, so a full disk loses as little as possible.
    let t = Instant::now();
    let saved = session.save_checkpoint(film);
    checkpoint_seconds += t.elapsed().as_secs_f64();
    // (path, final output?, the --partial file?)
    let mut files: Vec<(PathBuf, bool, bool)> = Vec::new();
    match report.stop {
        // Stopped by a signal: no final image or partial file (the
        // checkpoint holds the work), only the --write-partial image,
        // brought up to the checkpoint.
        Stop::Signal(_) => {
            if let Some(p) = &job.session.partial_image {
                files.push((p.clone(), false, false));
            }
        }
        Stop::Complete | Stop::TimeLimit => {
            if let Some(out) = &job.out {
                files.push((out.clone(), true, false));
            }
            if let Some(partial) = &job.partial {
                files.push((partial.clone(), true, true));
            }
        }
    }
    let mut errors = Vec::new();
    // --denoise: the denoised image, for the final --out, guided by the
    // film's albedo and normal AOVs (all its samples).
    let aov_images = match job.denoiser {
        Some(_) => film.aov_images(),
        None => Vec::new(), // written by `write_output`
    };
    let aovs: Vec<(Aov, &[[f32; 3]])> = aov_images.iter().map(|(a, p)| (*a, &p[..])).collect();
    let noisy_rgb = film.to_rgb();
    let denoised = match (&mut job.denoiser, report.stop) {
        (Some(denoiser), Stop::Complete | Stop::TimeLimit) => {
            let t = Instant::now();
            let layer = |aov| aovs.iter().find(|(a, _)| *a == aov).map(|(_, p)| *p);
            let aux = Aux {
                albedo: layer(Aov::Albedo).expect("--denoise accumulates albedo"),
                normal: layer(Aov::Normal).expect("--denoise accumulates normal"),
            };
            let rgb = denoiser.denoise(film.width, film.height, &noisy_rgb, Some(aux))?;
            stages.denoise = t.elapsed().as_secs_f64();
            if !quiet {
                eprintln!(
                    "denoise: with albedo and normal, in {:.3} s ({})",
                    t.elapsed().as_secs_f64(),
                    denoiser.library_path().display()
                );
            }
            if let Some(noisy) = &job.keep_noisy {
                files.insert(0, (noisy.clone(), true, false));
            }
            Some(rgb)
        }
        _ => None,
    };
    for (path, is_final, is_partial_file) in files {
        let t = Instant::now();
        let is_out = is_final && !is_partial_file && job.out.as_ref() == Some(&path);
        let size = (film.width, film.height);
        let r = match &denoised {
            Some(rgb) if is_out => write_image_with_aovs(&path, size, rgb, &aovs, job.view),
            // --keep-noisy: the AOVs as layers of an EXR (a PNG or PFM gets
            // none: they are --out's, and their files would collide).
            Some(_) if is_final && !is_partial_file => {
                let layers = if crate::output::ImageFormat::from_path(&path)?
                    == crate::output::ImageFormat::Exr
                {
                    &aovs[..]
                } else {
                    &[]
                };
                write_image_with_aovs(&path, size, &noisy_rgb, layers, job.view)
            }
            _ => write_output_viewed(&path, film, &job.meta, job.view),
        };
        let secs = t.elapsed().as_secs_f64();
        if is_final {
            stages.output += secs;
        } else {
            stages.partial_images += secs;
        }
        match r {
            Ok(()) if is_partial_file => partial_written = Some(path.display().to_string()),
            Ok(()) => output = Some(path.display().to_string()),
            Err(e) => errors.push(e),
        }
    }
    // `output` names what was written: --out (or the --write-partial image
    // after a signal), or else the --partial file.
    if output.is_none() {
        output.clone_from(&partial_written);
    }
    match saved {
        Ok(saved) => checkpoints_saved += saved as u32,
        Err(e) => errors.insert(0, e),
    }
    if let Some(last) = errors.pop() {
        for e in errors {
            eprintln!("error: {e}");
        }
        return Err(last);
    }
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
    // The errors of the image written (denoised, with --denoise), and with
    // --denoise those of the noisy image too.
    let written = denoised.as_ref().unwrap_or(&noisy_rgb);
    let errors = job
        .reference
        .as_ref()
        .map(|(_, reference)| ImageErrors::of(written, reference));
    let noisy_errors = match (&job.reference, &denoised) {
        (Some((_, reference)), Some(_)) => Some(ImageErrors::of(&noisy_rgb, reference)),
        _ => None,
    };
    let stats = RenderStats {
        version: env!("CARGO_PKG_VERSION"),
        git_commit: crate::cli::stats::GIT_COMMIT,
        cpu_model: crate::cli::stats::cpu_model(),
        simd: crate::cli::stats::SIMD,
        kernel_lanes: s.simd.lanes(),
        scene: job.scene.name.clone(),
        width: s.width,
        height: s.height,
        spp: film.samples_per_pixel(),
        spp_requested: s.spp,
        spp_resumed: report.start_spp,
        samples: [job.work.range.start, job.work.range.end],
        shard: job.work.shard.map(|(i, n)| [i, n]),
        max_depth: s.max_depth,
        seed: s.seed,
        threads: s.threads,
        engine: s.engine.name(),
        integrator: s.integrator.name(),
        sampler: s.sampler.name(),
        rr_depth: s.rr_depth,
        aov: s.aovs.names(),
        stop: report.stop.name(),
        time_limit_seconds: job.session.time_limit.map(|d| d.as_secs_f64()),
        passes: report.passes,
        longest_pass_seconds: report.longest_pass_seconds,
        seconds,
        elapsed_seconds: report.elapsed_seconds,
        paths: counters.paths,
        rays: counters.rays,
        shadow_rays: counters.shadow_rays,
        rays_per_second: per_second(counters.rays),
        paths_per_second: per_second(counters.paths),
        invalid_samples: film.invalid_samples,
        stages,
        engine_stages: counters.stages.by_name(),
        texture_seconds: counters.stages.textures(),
        checkpoint: job
            .session
            .checkpoint
            .as_ref()
            .map(|p| p.display().to_string()),
        checkpoints_saved,
        partial_images: report.partial_images,
        output,
        triangles: job.scene.triangles.len(),
        meshes: job.scene.assets.meshes,
        instances: job.scene.assets.instances,
        unique_triangles: job.scene.assets.unique_triangles,
        instanced_triangles: job.scene.assets.instanced_triangles,
        textures: job.scene.texturing.textures.len(),
        texture_bytes: (job.scene.texturing.textures.iter())
            .map(crate::scene::texture::Texture::bytes)
            .sum(),
        bvh_nodes: renderer.bvh().node_count(),
        bvh_first_packs: renderer.bvh().first_pack_count(),
        packet_first_triangles: renderer.bvh().packet_plan().map(|p| p.0),
        packet_groups: renderer.bvh().packet_plan().map(|p| p.1),
        build_seconds: renderer.bvh().build_seconds(),
        bvh_bytes: renderer.bvh().bytes(),
        bvh_instances: renderer.bvh().two_level().map_or(0, |t| t.instance_count()),
        partial: partial_written,
        reference: job
            .reference
            .as_ref()
            .map(|(path, _)| path.display().to_string()),
        mse: errors.map(|e| e.mse),
        relmse: errors.map(|e| e.relmse),
        denoised: denoised.is_some(),
        noisy_mse: noisy_errors.map(|e| e.mse),
        noisy_relmse: noisy_errors.map(|e| e.relmse),
    };
    if film.invalid_samples > 0 {
        eprintln!(
            "warning: {} sample(s) were NaN, infinite or negative: they add nothing to their pixels (counted as black)",
            film.invalid_samples
        );
    }
    if matches!(report.stop, Stop::Complete | Stop::TimeLimit)
        && written.iter().all(|p| *p == [0.0; 3])
    {
        eprintln!(
            "warning: the image is entirely black: no path found a light{}",
            if job.scene.light_warning().is_some() {
                " (see the warning above)"
            } else {
                "; is the camera inside a closed object, or looking away from the scene?"
            }
        );
    }
    if let Some(path) = &job.stats {
        write_atomic(path, |w| w.write_all(stats.to_json().as_bytes()))?;
    }
    println!("{}", summary(&job, &report, &stats));
    Ok(ExitCode::from(report.stop.exit_status()))
}

/// What a render does, in words: the banner on a terminal, and what
/// `--check` prints.
fn describe(job: &Job) -> String {
    let s = &job.settings;
    let resume = match &job.resume {
        Some(path) => format!(", resuming {}", path.display()),
        None => String::new(),
    };
    format!(
        "{} at {}x{}, {} spp{}, max depth {}, {} integrator{}, {} sampler, seed {}, {} thread(s), {} engine, {}-lane kernels{}{resume} -> {}",
        job.scene.name,
        s.width,
        s.height,
        s.spp,
        range_note(&job.work, s.spp),
        s.max_depth,
        s.integrator.name(),
        s.rr_depth
            .map_or(String::new(), |d| format!(" (roulette from depth {d})")),
        s.sampler.name(),
        s.seed,
        s.threads,
        s.engine.name(),
        s.simd.lanes(),
        if s.aovs.is_empty() {
            String::new()
        } else {
            format!(", AOVs {}", s.aovs)
        },
        outputs(job)
    )
}

/// The files a render writes at the end, comma-separated: `--out` (said
/// to be denoised with `--denoise`), its AOV files, `--keep-noisy`,
/// `--partial` and `--stats`.
fn outputs(job: &Job) -> String {
    let mut files: Vec<String> = Vec::new();
    if let Some(out) = &job.out {
        let denoised = if job.denoiser.is_some() {
            " (denoised)"
        } else {
            ""
        };
        files.push(format!("{}{denoised}", out.display()));
    }
    let noisy = job
        .keep_noisy
        .iter()
        .map(|p| format!("{} (noisy)", p.display()));
    let rest = job.aov_files.iter().chain(&job.partial).chain(&job.stats);
    files.extend(noisy.chain(rest.map(|p| p.display().to_string())));
    files.join(", ")
}

/// " (samples A..B of 0..spp, shard I/N)" when a render does less than
/// `0..spp`; empty for a whole render.
fn range_note(work: &SampleWork, spp: u32) -> String {
    let r = &work.range;
    match work.shard {
        _ if *r == (0..spp) => String::new(),
        Some((i, n)) => format!(
            " (samples {}..{} of 0..{spp}, shard {i}/{n})",
            r.start, r.end
        ),
        None => format!(" (samples {}..{} of 0..{spp})", r.start, r.end),
    }
}

/// The one line a render prints at the end (on stdout).
fn summary(job: &Job, report: &crate::run::session::SessionReport, stats: &RenderStats) -> String {
    let done = stats.spp;
    // The samples per pixel this run was to hold: --spp, or the shard's.
    let wanted = job.work.range.end - job.work.range.start;
    let range = range_note(&job.work, job.settings.spp);
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
                format!(" of {wanted} (time limit)")
            } else {
                String::new()
            };
            let noisy = match stats.noisy_relmse {
                Some(noisy) => format!("; the noisy image's relMSE {noisy:.4e}"),
                None => String::new(),
            };
            let errors = match (stats.relmse, stats.mse) {
                (Some(relmse), Some(mse)) => {
                    let of = if stats.denoised {
                        " of the denoised image"
                    } else {
                        ""
                    };
                    format!(", relMSE{of} {relmse:.4e} (MSE {mse:.4e}{noisy})")
                }
                _ => String::new(),
            };
            format!(
                "rendered {done} spp{limit}{range}{resumed} in {:.3} s: {speed}{errors} -> {}",
                stats.seconds,
                outputs(job)
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
                "stopped by {} at {done} of {wanted} spp{range}{resumed} after {:.3} s: {saved}",
                crate::run::session::signal_name(sig),
                stats.seconds
            )
        }
    }
}
