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
