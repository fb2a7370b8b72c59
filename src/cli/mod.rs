//! The command line: `wavetrace render ...` (the default command).

mod bench;
mod converge;
mod denoise;
mod light;
mod merge;
pub(crate) mod profile;
pub(crate) mod progress;
mod render;
pub(crate) mod stats;
mod view;
mod views;

use crate::error::Result;
use clap::{Parser, Subcommand};
use std::process::ExitCode;

pub use bench::BenchArgs;
pub use converge::ConvergeArgs;
pub use denoise::DenoiseArgs;
pub use merge::MergeArgs;
pub use render::{FarmArgs, RenderArgs};
pub use view::ViewArgs;
pub use views::ViewsArgs;

/// The help's closing section: examples, the exit statuses, where the
/// details are.
const AFTER_HELP: &str = "\
EXAMPLES:
  wavetrace                                  the built-in Cornell box, 256 spp -> cornell.png
  wavetrace -s 16 -o preview.png             fewer samples, another file
  wavetrace scene.toml -s 1024 -o out.exr    a scene of your own, linear EXR
  wavetrace scene.toml --view agx --exposure 1
                                             a PNG with Blender's AgX view, one stop brighter
  wavetrace -s 4096 --time-limit 600 --checkpoint c.wtacc
                                             as many samples as fit in 10 minutes, resumable
  wavetrace -s 1024 --shard 0/4 --partial p0.wtacc
                                             one of four farm shards; then `wavetrace merge`
  wavetrace bench --quick                    benchmark this CPU

Exit status: 0 when the outputs were written; 1 on an error (2 for a malformed
command line); 130 (SIGINT) or 143 (SIGTERM) when a signal stopped the render
after saving the checkpoint.

Every flag is explained in docs/cli.md; the scene format in scenes/README.md.";

/// wavetrace: a fast, reproducible CPU path tracer.
#[derive(Debug, Parser)]
#[command(
    name = "wavetrace",
    version,
    about,
    args_conflicts_with_subcommands = true,
    after_help = AFTER_HELP
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
// Parsed once per process: the size of the render variant does not matter.
#[allow(clippy::large_enum_variant)]
pub enum Command {
    /// Render a scene (or one shard's sample range of it) to an image or
    /// a partial file.
    #[command(after_help = AFTER_HELP)]
    Render(RenderArgs),
    /// Merge the partial files of shards into the image of the whole render.
    Merge(MergeArgs),
    /// Run the verified CPU benchmark suite (or compare its JSON files).
    Bench(BenchArgs),
    /// Measure how the error falls with samples per pixel (MSE, relMSE,
    /// mean FLIP against a reference) and find the diminishing-returns point.
    Converge(ConvergeArgs),
    /// Denoise an image rendered earlier with Intel Open Image Denoise
    /// (guided by its albedo and normal layers when it has them).
    Denoise(DenoiseArgs),
    /// Render many views of many assets (a dataset): colour, AOVs, camera
    /// files (transforms.json, OpenCV), resumable and sharded (docs/views.md).
    Views(ViewsArgs),
}

/// Load the scene file at `path`: a TOML scene, or an asset (glTF, GLB,
/// PLY; its loader's warnings printed; `camera` picks one of a glTF's
/// cameras); a file of another format (an OBJ
/// mesh, pbrt…) is refused with an error that says what it is.
pub(crate) fn load_scene(
    path: &std::path::Path,
    camera: Option<&str>,
) -> Result<crate::scene::Scene> {
    let (scene, warnings) = crate::render::open_scene(path, camera)?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// Run the command line. Returns the process exit status: 0 when the
/// outputs were written, 128 + the signal number (130 for SIGINT, 143 for
/// SIGTERM) when a signal stopped the render (after saving the checkpoint).
/// Errors are for the caller to print (exit status 1).
pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        None => render::run(cli.render),
        Some(Command::Render(args)) => render::run(args),
        Some(Command::Merge(args)) => merge::run(args).map(|()| ExitCode::SUCCESS),
        Some(Command::Bench(args)) => bench::run(args),
        Some(Command::Converge(args)) => converge::run(args).map(|()| ExitCode::SUCCESS),
        Some(Command::Denoise(args)) => denoise::run(args).map(|()| ExitCode::SUCCESS),
        Some(Command::Views(args)) => views::run(args),
    }
}
