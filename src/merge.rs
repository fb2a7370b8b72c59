//! `wavetrace merge`: partial files of shards in, the whole render out.
//!
//! Every partial file (see [`crate::shard`]) holds exact per-pixel sums of
//! some sample ranges, the render's samples per pixel, and a hash of the
//! scene and the settings that change the image. Merging adds the sums up
//! — integer sums, so the result is the same film, bit for bit, as one run
//! of the whole sample range — after checking that the parts belong
//! together and fit: the same hash and size, no sample index twice, and
//! (unless `--allow-partial`) every sample of `0..spp` present. A refused
//! merge names the file at fault, or the samples and shards that are
//! missing, and writes nothing.

use crate::error::{Error, Result};
use crate::film::{AccMeta, Film, MergeError};
use crate::output::check_writable;
use crate::shard::{check_output_format, check_partial_path, write_output};
use clap::Args;
use std::fmt;
use std::ops::Range;
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
    #[arg(long, value_name = "FILE")]
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
}

/// Samples of `0..spp` that none of the parts hold.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct MissingSamples {
    /// The render's samples per pixel.
    pub spp: u32,
    /// The missing sample ranges, sorted.
    pub missing: Vec<Range<u32>>,
    /// The shard count of the parts, when they were rendered as shards.
    pub shard_count: Option<u32>,
    /// The shards (indices below `shard_count`) with missing samples: the
    /// Slurm array task IDs to rerun.
    pub missing_shards: Vec<u32>,
}

impl MissingSamples {
    /// What is missing, in words: ranges, and the shards when known.
    pub fn describe(&self) -> String {
        let held = self.spp - self.missing.iter().map(|r| r.end - r.start).sum::<u32>();
        let ranges: Vec<String> = self
            .missing
            .iter()
            .map(|r| format!("{}..{}", r.start, r.end))
            .collect();
        let mut s = format!(
            "missing samples {} of 0..{} (the parts hold {held} of {} samples per pixel)",
            ranges.join(", "),
            self.spp,
            self.spp
        );
        if let Some(n) = self.shard_count {
            let ids: Vec<String> = self.missing_shards.iter().map(u32::to_string).collect();
            s += &format!(
                "; missing shard(s) {} of {n}: rerun them (Slurm: sbatch --array={} ...) and merge again",
                ids.join(", "),
                ids.join(",")
            );
        } else {
            s += ": render them (--samples A..B --partial FILE) and merge again";
        }
        s
    }
}

impl fmt::Display for MissingSamples {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}; or pass --allow-partial to write what is there",
            self.describe()
        )
    }
}

/// The result of merging partial files.
#[derive(Clone, Debug, PartialEq)]
pub struct Merged {
    /// The sum of the parts.
    pub film: Film,
    /// The merged film's header: the parts' hash and spp, no shard.
    pub meta: AccMeta,
    /// What is missing of `0..spp`, if anything.
    pub missing: Option<MissingSamples>,
}

/// Load and merge partial files. `spp` is the render's samples per pixel
/// when the parts do not record it (or to check that they do). With
/// `allow_partial`, missing samples are reported in [`Merged::missing`]
/// instead of refused. Errors name the file at fault.
pub fn merge_files(paths: &[PathBuf], spp: Option<u32>, allow_partial: bool) -> Result<Merged> {
    let Some(first_path) = paths.first() else {
        return Err(Error::Settings("merge: no partial files given".into()));
    };
    let mut merged: Option<(Film, AccMeta)> = None;
    let mut spp_from: Option<(u32, &Path)> = spp.map(|s| (s, Path::new("--spp")));
    let mut shard_count: Option<u32> = None;
    let mut mixed_counts = false;
    // Every range merged so far and the file it came from.
    let mut origins: Vec<(Range<u32>, &Path)> = Vec::new();
    for path in paths {
        let bad = |message: String| Error::Accumulation {
            path: path.clone(),
            message,
        };
        let (film, meta) = Film::load_with_meta(path, None)?;
        if let Some((_, first_meta)) = &merged
            && meta.settings_hash != first_meta.settings_hash
        {
            return Err(bad(format!(
                "made by a render of another scene or other settings than {} (settings hash {:032x}, expected {:032x})",
                first_path.display(),
                meta.settings_hash,
                first_meta.settings_hash
            )));
        }
        if let Some(part_spp) = meta.spp {
            match spp_from {
                Some((s, from)) if s != part_spp => {
                    return Err(bad(format!(
                        "is part of a render of {part_spp} samples per pixel, but {} says {s}",
                        from.display()
                    )));
                }
                Some(_) => {}
                None => spp_from = Some((part_spp, path)),
            }
        }
        // The count the parts were sharded by; parts of different counts
        // give no advice on which shards to rerun (it would be wrong).
        if let Some((_, n)) = meta.shard {
            match shard_count {
                None if !mixed_counts => shard_count = Some(n),
                Some(m) if m != n => {
                    shard_count = None;
                    mixed_counts = true;
                }
                _ => {}
            }
        }
        for r in &film.ranges {
            if let Some(&(ref other, from)) = origins
                .iter()
                .find(|(o, _)| r.start < o.end && o.start < r.end)
            {
                return Err(bad(format!(
                    "samples {}..{} overlap samples {}..{} of {} (was a part given twice, or are shards of different counts mixed?)",
                    r.start,
                    r.end,
                    other.start,
                    other.end,
                    from.display()
                )));
            }
        }
        origins.extend(film.ranges.iter().map(|r| (r.clone(), path.as_path())));
        match &mut merged {
            None => merged = Some((film, meta)),
            Some((total, _)) => {
                total.merge(&film).map_err(|e| match e {
                    MergeError::Size { .. } => {
                        bad(format!("{e} (the size of {})", first_path.display()))
                    }
                    MergeError::Overlap { .. } => bad(e.to_string()),
                })?;
            }
        }
    }
    let (film, first_meta) = merged.expect("at least one part");
    let Some((spp, _)) = spp_from else {
        return Err(Error::Settings(
            "merge: the parts do not record the render's samples per pixel, so missing samples cannot be found; pass --spp N".into(),
        ));
    };
    if let Some(last) = film.ranges.last()
        && last.end > spp
    {
        let (_, from) = origins
            .iter()
            .find(|(r, _)| r.end > spp)
            .expect("some part holds the range");
        return Err(Error::Accumulation {
            path: from.to_path_buf(),
            message: format!("holds samples up to {}, beyond --spp {spp}", last.end),
        });
    }
    let missing = missing_ranges(&film.ranges, spp);
    let missing = (!missing.is_empty()).then(|| {
        let missing_shards = shard_count.map_or_else(Vec::new, |n| {
            (0..n)
                .filter(|&i| {
                    crate::shard::shard_range(i, n, spp)
                        .is_ok_and(|r| missing.iter().any(|m| m.start < r.end && r.start < m.end))
                })
                .collect()
        });
        MissingSamples {
            spp,
            missing,
            shard_count,
            missing_shards,
        }
    });
    if let Some(m) = &missing
        && !allow_partial
    {
        return Err(Error::Incomplete(m.clone()));
    }
    let meta = AccMeta {
        settings_hash: first_meta.settings_hash,
        spp: Some(spp),
        shard: None,
    };
    Ok(Merged {
        film,
        meta,
        missing,
    })
}

/// The parts of `0..spp` that the sorted, disjoint `ranges` do not cover.
pub fn missing_ranges(ranges: &[Range<u32>], spp: u32) -> Vec<Range<u32>> {
    let mut missing = Vec::new();
    let mut at = 0;
    for r in ranges {
        if r.start > at {
            missing.push(at..r.start.min(spp));
        }
        at = at.max(r.end);
    }
    if at < spp {
        missing.push(at..spp);
    }
    missing.retain(|r| r.start < r.end);
    missing
}

/// Run `wavetrace merge`: check the outputs, merge, then write.
pub fn run(args: MergeArgs) -> Result<()> {
    check_output_format(&args.out)?;
    check_writable(&args.out)?;
    if let Some(p) = &args.partial {
        check_partial_path(p)?;
        check_writable(p)?;
    }
    let merged = merge_files(&args.parts, args.spp, args.allow_partial)?;
    if let Some(m) = &merged.missing {
        eprintln!("warning: --allow-partial: {}", m.describe());
    }
    write_output(&args.out, &merged.film, &merged.meta)?;
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

#[cfg(test)]
// Films hold lists of sample ranges; a list of one range is what is meant.
#[allow(clippy::single_range_in_vec_init)]
mod tests {
    use super::*;

    #[test]
    fn missing_ranges_are_the_complement() {
        assert_eq!(missing_ranges(&[0..64], 64), vec![]);
        assert_eq!(missing_ranges(&[], 64), vec![0..64]);
        assert_eq!(
            missing_ranges(&[16..32, 48..60], 64),
            vec![0..16, 32..48, 60..64]
        );
    }

    #[test]
    fn missing_samples_name_the_shards() {
        let m = MissingSamples {
            spp: 64,
            missing: vec![16..32, 48..64],
            shard_count: Some(4),
            missing_shards: vec![1, 3],
        };
        let text = m.to_string();
        assert!(text.contains("16..32, 48..64"), "{text}");
        assert!(text.contains("shard(s) 1, 3 of 4"), "{text}");
        assert!(text.contains("--array=1,3"), "{text}");
        assert!(text.contains("--allow-partial"), "{text}");
    }
}
