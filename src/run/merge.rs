//! `wavetrace merge`: partial files of shards in, the whole render out.
//!
//! Every partial file (see [`crate::run::shard`]) holds exact per-pixel sums of
//! some sample ranges, the render's samples per pixel, and a hash of the
//! scene and the settings that change the image. Merging adds the sums up
//! — integer sums, so the result is the same film, bit for bit, as one run
//! of the whole sample range — after checking that the parts belong
//! together and fit: the same hash, size and AOVs, no sample index twice, and
//! (unless `--allow-partial`) every sample of `0..spp` present. A refused
//! merge names the file at fault, or the samples and shards that are
//! missing, and writes nothing.

use crate::error::{Error, Result};
use crate::film::ranges::{MissingSamples, missing_ranges};
use crate::film::{AccMeta, Film, MergeError, WtaccError};
use std::ops::Range;
use std::path::{Path, PathBuf};

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
        let bad = |message: String| {
            Error::from(WtaccError {
                path: path.clone(),
                message,
            })
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
        // `origins` is sorted by start and disjoint, so the one range a
        // range can overlap first is found by binary search.
        for r in &film.ranges {
            let at = origins.partition_point(|(o, _)| o.end <= r.start);
            if let Some(&(ref other, from)) = origins.get(at).filter(|(o, _)| o.start < r.end) {
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
        origins.sort_unstable_by_key(|(r, _)| r.start);
        match &mut merged {
            None => merged = Some((film, meta)),
            Some((total, _)) => {
                total.merge(&film).map_err(|e| match e {
                    MergeError::Size { .. } => {
                        bad(format!("{e} (the size of {})", first_path.display()))
                    }
                    MergeError::Aovs { .. } => {
                        bad(format!("{e} (those of {})", first_path.display()))
                    }
                    MergeError::Overlap { .. } | MergeError::Adaptive => bad(e.to_string()),
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
        return Err(WtaccError {
            path: from.to_path_buf(),
            message: format!("holds samples up to {}, beyond --spp {spp}", last.end),
        }
        .into());
    }
    let missing = missing_ranges(&film.ranges, spp);
    let missing = (!missing.is_empty()).then(|| {
        // Listed only while the list is short enough to act on; a longer
        // one (a forged shard count, say) gives the sample ranges alone.
        let missing_shards = shard_count.and_then(|n| missing_shards(&missing, n, spp));
        MissingSamples {
            spp,
            missing,
            shard_count: missing_shards.as_ref().and(shard_count),
            missing_shards: missing_shards.unwrap_or_default(),
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

/// The most missing shards a merge lists (as Slurm array task IDs).
pub const MAX_LISTED_SHARDS: usize = 10_000;

/// The shards of `count` over `0..spp` that hold some of the `missing`
/// samples (sorted, disjoint), in order; `None` when there are more than
/// [`MAX_LISTED_SHARDS`] or the count is impossible. Time is bounded by
/// the length of the list, not by `count`.
fn missing_shards(missing: &[Range<u32>], count: u32, spp: u32) -> Option<Vec<u32>> {
    if count == 0 || count > spp {
        return None;
    }
    let start_of = |i: u32| (i as u64 * spp as u64 / count as u64) as u32;
    let mut shards: Vec<u32> = Vec::new();
    for m in missing {
        // The shard holding sample m.start: the last i with start_of(i) <= m.start.
        let mut i = (m.start as u64 * count as u64 / spp as u64) as u32;
        while i > 0 && start_of(i) > m.start {
            i -= 1;
        }
        while i + 1 < count && start_of(i + 1) <= m.start {
            i += 1;
        }
        while i < count && start_of(i) < m.end {
            if shards.last() != Some(&i) {
                if shards.len() == MAX_LISTED_SHARDS {
                    return None;
                }
                shards.push(i);
            }
            i += 1;
        }
    }
    Some(shards)
}
