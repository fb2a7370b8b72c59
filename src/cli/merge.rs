//! `wavetrace merge`: partial files in, the whole render out.

use crate::cli::ViewArgs;
use crate::error::Result;
use crate::fs::{check_outputs, check_writable};
use crate::output::{aov_path, check_output_format, check_partial_path, write_output_viewed};
use crate::run::merge::merge_files;
use crate::scene::Aov;
use clap::Args;
use std::path::{Path, PathBuf};

/// Options of `wavetrace merge`.
#[derive(Clone, Debug, Args)]
pub struct MergeArgs {
    /// Partial files (.wtacc) of one render, in any order, written by
    /// `wavetrace render --shard ... --partial FILE` (checkpoints are
    /// partial files too).
    #[arg(required = true, value_name = "PART")]
    pub parts: Vec<PathBuf>,
    /// The merged output: an image (.png, .exr, .pfm) or a merged partial
    /// file (.wtacc).
    #[arg(long, short = 'o', value_name = "FILE")]
    pub out: PathBuf,
    /// Also write the merged partial file (.wtacc), e.g. to merge it again
    /// later with more samples.
    #[arg(long, value_name = "FILE.wtacc")]
    pub partial: Option<PathBuf>,
    /// Write the image even if some samples are missing (it is the mean of
    /// the samples present), and say which are missing.
    #[arg(long)]
    pub allow_partial: bool,
    /// The whole render's samples per pixel; needed only for parts that do
    /// not record it (files saved without shard information).
    #[arg(long, value_name = "N")]
    pub spp: Option<u32>,
    /// The PNG view.
    #[command(flatten)]
    pub view: ViewArgs,
}

/// Run `wavetrace merge`: check the outputs, merge, then write.
pub fn run(args: MergeArgs) -> Result<()> {
    check_output_format(&args.out)?;
    let view = args.view.transform(Some(&args.out))?;
    if let Some(p) = &args.partial {
        check_partial_path(p)?;
    }
    // The AOV files beside a PNG or PFM --out: every one the parts might
    // hold (which they hold is known only once they are read).
    let aov_files: Vec<PathBuf> = Aov::EVERY
        .iter()
        .filter_map(|&a| aov_path(&args.out, a))
        .collect();
    let inputs: Vec<(&str, &Path)> = args.parts.iter().map(|p| ("a part", p.as_path())).collect();
    let mut outputs = vec![("--out", args.out.as_path())];
    outputs.extend(
        aov_files
            .iter()
            .map(|f| ("an AOV file of --out", f.as_path())),
    );
    outputs.extend(args.partial.as_deref().map(|p| ("--partial", p)));
    check_outputs(&inputs, &outputs)?;
    check_writable(&args.out)?;
    if let Some(p) = &args.partial {
        check_writable(p)?;
    }
    let merged = merge_files(&args.parts, args.spp, args.allow_partial)?;
    if let Some(m) = &merged.missing {
        eprintln!("warning: --allow-partial: {}", m.describe());
    }
    write_output_viewed(&args.out, &merged.film, &merged.meta, view)?;
    if let Some(p) = &args.partial {
        merged.film.save_with_meta(p, &merged.meta)?;
    }
    if merged.film.invalid_samples > 0 {
        eprintln!(
            "warning: the parts left out {} NaN, infinite or negative sample(s)",
            merged.film.invalid_samples
        );
    }
    let ranges: Vec<String> = merged
        .film
        .ranges
        .iter()
        .map(|r| format!("{}..{}", r.start, r.end))
        .collect();
    println!(
        "merged {} part(s): {}x{}, samples {} of {} per pixel -> {}",
        args.parts.len(),
        merged.film.width,
        merged.film.height,
        if ranges.is_empty() {
            "none".into()
        } else {
            ranges.join(", ")
        },
        merged.meta.spp.unwrap_or(0),
        args.out.display()
    );
    Ok(())
}
