//! Sample-range algebra: which samples of `0..spp` a set of films holds.

use std::fmt;
use std::ops::Range;

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

/// The ranges `[start, end]` (in any order) as sorted, disjoint ranges,
/// adjacent ones joined; or the first (in sorted order) that is empty or
/// overlaps another. O(n log n), so a file of very many ranges loads fast.
pub fn sorted_disjoint(ranges: &[[u32; 2]]) -> Result<Vec<Range<u32>>, [u32; 2]> {
    let mut sorted = ranges.to_vec();
    sorted.sort_unstable();
    let mut joined: Vec<Range<u32>> = Vec::with_capacity(sorted.len());
    for [a, b] in sorted {
        if a >= b {
            return Err([a, b]);
        }
        match joined.last_mut() {
            Some(last) if a < last.end => return Err([a, b]),
            Some(last) if a == last.end => last.end = b,
            _ => joined.push(a..b),
        }
    }
    Ok(joined)
}

/// The first range of the sorted, disjoint `theirs` that overlaps one of
/// the sorted, disjoint `ours`, with that range: a merge of the two, in
/// O(n + m).
pub fn first_overlap(
    theirs: &[Range<u32>],
    ours: &[Range<u32>],
) -> Option<(Range<u32>, Range<u32>)> {
    let (mut i, mut j) = (0, 0);
    while i < theirs.len() && j < ours.len() {
        let (t, o) = (&theirs[i], &ours[j]);
        if t.start < o.end && o.start < t.end {
            return Some((t.clone(), o.clone()));
        }
        if t.end <= o.start {
            i += 1;
        } else {
            j += 1;
        }
    }
    None
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
