//! `wavetrace converge`: error against samples per pixel for several
//! estimators, the diminishing-returns point, plots and crops.

use crate::cli::render::named;
use crate::error::{Error, Result};
use crate::output::{read_radiance, write_image};
use crate::render::{DEFAULT_INTEGRATOR, DEFAULT_SAMPLER, RenderSettings};
use crate::run::converge::{
    Crop, Curve, DEFAULT_JND, Setting, reference_settings, render_reference, study, to_csv,
};
use crate::run::plot::{XAxis, crop_strip_png, plot_png, plot_svg, write_file};
use crate::scene::{Integrator, SamplerKind, Scene};
use clap::Args;
use indicatif::{ProgressDrawTarget, ProgressStyle};
use serde::Serialize;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

/// Options of `wavetrace converge`.
#[derive(Debug, Args)]
pub struct ConvergeArgs {
    /// Scene file (TOML); the built-in Cornell box when omitted.
    pub scene: Option<PathBuf>,
    /// The converged image to measure against (.exr or .pfm, of the
    /// render's size).
    #[arg(long, value_name = "IMAGE", required_unless_present = "reference_spp")]
    pub reference: Option<PathBuf>,
    /// Render the reference first, with this many samples per pixel, the
    /// default integrator and sampler, and the complement of --seed (so it
    /// shares no sample with the study); it is also written as
    /// PREFIX-reference.exr.
    #[arg(long, value_name = "N", conflicts_with = "reference")]
    pub reference_spp: Option<u32>,
    /// Image width in pixels [default: the scene's].
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels [default: the scene's].
    #[arg(long)]
    pub height: Option<u32>,
    /// The most samples per pixel: errors are measured at 1, 2, 4, … and
    /// this.
    #[arg(long, default_value_t = 1024)]
    pub spp: u32,
    /// Maximum path depth (the camera ray is depth 0) [default: the scene's].
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Random seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Worker threads (default: SLURM_CPUS_PER_TASK if set, else all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Integrators to compare, comma-separated [default: report and the
    /// default integrator].
    #[arg(long, value_delimiter = ',', value_parser = named(Integrator::NAMES, Integrator::from_name))]
    pub integrator: Option<Vec<Integrator>>,
    /// Samplers to compare, comma-separated [default: the default sampler];
    /// every integrator runs with every sampler.
    #[arg(long, value_delimiter = ',', value_parser = named(SamplerKind::NAMES, SamplerKind::from_name))]
    pub sampler: Option<Vec<SamplerKind>>,
    /// The diminishing-returns threshold: the point reported is the
    /// smallest spp from which every doubling lowers the mean FLIP by less
    /// than this (absolute, FLIP's 0-1 scale).
    #[arg(long, default_value_t = DEFAULT_JND)]
    pub jnd: f64,
    /// Folder for the files written (`.`: the current folder).
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub out_dir: PathBuf,
    /// Start of the written files' names (a plain name: the files go in
    /// `--out-dir`).
    #[arg(long, default_value = "converge", value_parser = plain_name)]
    pub prefix: String,
    /// Magnification of the crops in the strip [default: the smallest
    /// that makes them at least 128 pixels wide].
    #[arg(long)]
    pub zoom: Option<u32>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// The JSON file of a study.
#[derive(Serialize)]
struct Report<'a> {
    scene: &'a str,
    width: u32,
    height: u32,
    spp: u32,
    max_depth: u32,
    seed: u64,
    threads: usize,
    /// The reference file read, or the one rendered.
    reference: String,
    reference_spp: Option<u32>,
    reference_seed: Option<u64>,
    jnd: f64,
    crop: Crop,
    curves: &'a [Curve],
}

/// Run `wavetrace converge`.
pub fn run(args: ConvergeArgs) -> Result<()> {
    let scene = match &args.scene {
        Some(path) => crate::cli::load_scene(path, None)?,
        None => Scene::cornell(),
    };
    let mut base = RenderSettings::for_scene(&scene);
    base.width = args.width.unwrap_or(base.width);
    base.height = args.height.unwrap_or(base.height);
    base.spp = args.spp;
    base.max_depth = args.max_depth.unwrap_or(base.max_depth);
    base.seed = args.seed;
    let env = |name: &str| std::env::var(name).ok();
    base.threads = match args.threads {
        Some(t) => t,
        None => crate::run::shard::threads_from_env(&env)?.unwrap_or(base.threads),
    };
    base.rr_depth = None;
    base.validate()?;
    if !(args.jnd.is_finite() && args.jnd > 0.0) {
        return Err(Error::Settings("--jnd must be a positive number".into()));
    }
    if args.zoom.is_some_and(|z| z == 0 || z > 16) {
        return Err(Error::Settings("--zoom must be between 1 and 16".into()));
    }
    if args.reference_spp == Some(0) {
        return Err(Error::Settings("--reference-spp must be at least 1".into()));
    }
    let integrators = args
        .integrator
        .clone()
        .unwrap_or_else(|| vec![Integrator::Report, DEFAULT_INTEGRATOR]);
    let samplers = args
        .sampler
        .clone()
        .unwrap_or_else(|| vec![DEFAULT_SAMPLER]);
    let mut settings: Vec<Setting> = Vec::new();
    for &integrator in &integrators {
        for &sampler in &samplers {
            let s = Setting {
                integrator,
                sampler,
            };
            if !settings.contains(&s) {
                settings.push(s);
            }
        }
    }
    // The reference, read and checked before any work or file.
    let read = match &args.reference {
        Some(path) => {
            let image = read_radiance(path, "the reference")?;
            if (image.width, image.height) != (base.width, base.height) {
                return Err(Error::Settings(format!(
                    "{}: the reference is {}x{}, the study {}x{} (set --width and --height)",
                    path.display(),
                    image.width,
                    image.height,
                    base.width,
                    base.height
                )));
            }
            Some((path.clone(), image.rgb))
        }
        None => None,
    };
    let file = |suffix: &str| args.out_dir.join(format!("{}{suffix}", args.prefix));
    let outputs = [
        ".csv",
        ".json",
        "-spp.png",
        "-spp.svg",
        "-time.png",
        "-time.svg",
        "-crops.png",
    ];
    // No file written may be an input (the scene, a mesh, the reference)
    // or another output; checked before the folder is made.
    let mut files: Vec<PathBuf> = outputs.iter().map(|o| file(o)).collect();
    if args.reference_spp.is_some() {
        files.push(file("-reference.exr"));
    }
    let mut inputs = crate::cli::render::scene_inputs(&scene, args.scene.as_deref());
    if let Some(reference) = &args.reference {
        inputs.push(("--reference", reference));
    }
    let named: Vec<(&str, &std::path::Path)> = files
        .iter()
        .map(|p| ("a file of converge --out-dir", p.as_path()))
        .collect();
    crate::fs::check_outputs(&inputs, &named)?;
    std::fs::create_dir_all(&args.out_dir)
        .map_err(|e| Error::Settings(format!("{}: cannot create: {e}", args.out_dir.display())))?;
    for path in &files {
        crate::fs::check_writable(path)?;
    }

    let show = !args.quiet && std::io::stderr().is_terminal();
    let bar = if show {
        indicatif::ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
    } else {
        indicatif::ProgressBar::hidden()
    };
    let total = settings.len() as u64 * base.spp as u64 + args.reference_spp.unwrap_or(0) as u64;
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{wide_bar}] {pos}/{len} spp  {msg}")
            .expect("the progress template is valid")
            .progress_chars("=> "),
    );
    bar.set_length(total);
    bar.enable_steady_tick(Duration::from_millis(250));

    let (reference_name, reference, reference_seed) = match read {
        Some((path, rgb)) => (path.display().to_string(), rgb, None),
        None => {
            let spp = args.reference_spp.expect("clap requires one of the two");
            let rs = reference_settings(&base, spp);
            bar.set_message(format!(
                "reference: {} / {}",
                rs.integrator.name(),
                rs.sampler.name()
            ));
            let rgb = render_reference(&scene, &rs, &mut |n: u32| bar.inc(n as u64))?;
            let path = file("-reference.exr");
            write_image(&path, base.width, base.height, &rgb)?;
            (path.display().to_string(), rgb, Some(rs.seed))
        }
    };

    let crop = Crop::default_for(base.width, base.height);
    let mut curves = Vec::new();
    for s in &settings {
        bar.set_message(s.label());
        let curve = study(
            &scene,
            &base,
            *s,
            &reference,
            crop,
            args.jnd,
            &mut |n: u32| bar.inc(n as u64),
        )?;
        curves.push(curve);
    }
    bar.finish_and_clear();

    // The files.
    let report = Report {
        scene: &scene.name,
        width: base.width,
        height: base.height,
        spp: base.spp,
        max_depth: base.max_depth,
        seed: base.seed,
        threads: base.threads,
        reference: reference_name.clone(),
        reference_spp: args.reference_spp,
        reference_seed,
        jnd: args.jnd,
        crop,
        curves: &curves,
    };
    let io = |e: std::io::Error| Error::Settings(format!("cannot draw the plots: {e}"));
    write_file(&file(".csv"), to_csv(&curves).as_bytes())?;
    let json = serde_json::to_string_pretty(&report).expect("the report serialises");
    write_file(&file(".json"), json.as_bytes())?;
    let what = format!(
        "{} {}x{}, depth {}, seed {}",
        scene.name, base.width, base.height, base.max_depth, base.seed
    );
    for (x, name, title) in [
        (
            XAxis::Spp,
            "-spp",
            format!("error vs samples per pixel: {what}"),
        ),
        (
            XAxis::Seconds,
            "-time",
            format!("error vs render time ({} threads): {what}", base.threads),
        ),
    ] {
        write_file(
            &file(&format!("{name}.png")),
            &plot_png(&curves, x, &title).map_err(io)?,
        )?;
        write_file(
            &file(&format!("{name}.svg")),
            plot_svg(&curves, x, &title).map_err(io)?.as_bytes(),
        )?;
    }
    let reference_crop = crop.cut(&reference, base.width);
    let zoom = args
        .zoom
        .unwrap_or(128u32.div_ceil(crop.width).clamp(1, 16));
    write_file(
        &file("-crops.png"),
        &crop_strip_png(&curves, &reference_crop, (crop.width, crop.height), zoom).map_err(io)?,
    )?;

    // The summary.
    println!("converge: {what}, reference {reference_name}");
    println!(
        "{:<22} {:>6} {:>9} {:>11} {:>11} {:>9}",
        "setting", "spp", "seconds", "MSE", "relMSE", "mean FLIP"
    );
    for c in &curves {
        for p in &c.points {
            println!(
                "{:<22} {:>6} {:>9.3} {:>11.4e} {:>11.4e} {:>9.4}",
                c.label(),
                p.spp,
                p.seconds,
                p.mse,
                p.relmse,
                p.mean_flip
            );
        }
    }
    for c in &curves {
        match c.diminishing_returns_spp {
            Some(n) => println!(
                "diminishing returns: {} at {n} spp (from there each doubling lowers mean FLIP by < {})",
                c.label(),
                args.jnd
            ),
            None => println!(
                "diminishing returns: {} not reached by {} spp (the last doubling still lowered mean FLIP by >= {}); try a larger --spp",
                c.label(),
                base.spp,
                args.jnd
            ),
        }
    }
    let written: Vec<String> = outputs
        .iter()
        .map(|o| file(o).display().to_string())
        .collect();
    println!("written: {}", written.join(", "));
    Ok(())
}

/// `--prefix`: a plain file name — not empty, no slash or backslash, not `.` or
/// `..`, no NUL — so that every file lands in `--out-dir` (an absolute
/// prefix wrote beside it, anywhere).
fn plain_name(s: &str) -> Result<String, String> {
    let plain = !s.is_empty() && s != "." && s != ".." && !s.contains(['/', '\\', '\0']);
    if plain {
        Ok(s.to_string())
    } else {
        Err(format!(
            "must be a plain file name (the files go in --out-dir), not {s:?}"
        ))
    }
}
