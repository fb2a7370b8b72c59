//! Shards: rendering one sample range of every pixel, for render farms.
//!
//! A render of `spp` samples per pixel is the sum of the renders of any
//! disjoint sample ranges that cover `0..spp` (the film is exact, see
//! [`crate::film`]). A farm splits `0..spp` into `N` near-equal shards;
//! each task renders one ([`shard_range`]) into a *partial file* (an
//! accumulation file, `.wtacc`), and `wavetrace merge` ([`crate::run::merge`])
//! adds the partial files up into the image a single run would give, byte
//! for byte.
//!
//! `--shard auto` takes the shard from the scheduler's environment:
//!
//! - Slurm job arrays: `SLURM_ARRAY_TASK_ID`. With `--shard-count N`
//!   the task ID *is* the shard index (`0..N`), so failed tasks can be
//!   resubmitted alone (`sbatch --array=3,7 ...`). Without it, the shard is
//!   `SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN` of
//!   `SLURM_ARRAY_TASK_COUNT`, which needs a contiguous array (`--array=1-8`).
//! - Kubernetes Indexed Jobs: `JOB_COMPLETION_INDEX` with `--shard-count N`.
//!
//! When both are set, Slurm's variables win.
//!
//! `SLURM_CPUS_PER_TASK` sets the thread count when `--threads` is not
//! given ([`threads_from_env`]).

use std::ops::Range;

/// A look-up of an environment variable (`std::env::var(..).ok()` in the
/// command; a map in tests).
pub type EnvLookup<'a> = &'a dyn Fn(&str) -> Option<String>;

/// A reason a shard or sample range is refused, before any work starts.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ShardError {
    /// `--samples` is not `A..B` with `A < B`.
    #[error("--samples {0:?}: expected A..B with A < B, sample indices from 0 (e.g. 0..64)")]
    BadSamples(String),
    /// `--samples` reaches beyond the render's samples per pixel.
    #[error(
        "--samples {start}..{end} reaches beyond the {spp} samples per pixel of the render (--spp)"
    )]
    SamplesBeyondSpp {
        /// First sample index asked for.
        start: u32,
        /// One past the last sample index asked for.
        end: u32,
        /// The render's samples per pixel.
        spp: u32,
    },
    /// `--shard` is not `I/N` or `auto`.
    #[error("--shard {0:?}: expected I/N (shard I of N, I from 0) or auto")]
    BadShard(String),
    /// A shard count of 0.
    #[error("the shard count must be at least 1")]
    ZeroCount,
    /// A shard index that is not below the shard count.
    #[error(
        "shard index {index} is not below the shard count {count} (indices run from 0 to {})",
        .count - 1
    )]
    IndexNotBelowCount {
        /// The shard index.
        index: u32,
        /// The shard count.
        count: u32,
    },
    /// More shards than samples: some shards would be empty.
    #[error(
        "{count} shards of {spp} samples per pixel: some shards would be empty; use at most {spp} shards"
    )]
    MoreShardsThanSamples {
        /// The shard count.
        count: u32,
        /// The render's samples per pixel.
        spp: u32,
    },
    /// `--shard auto` found no scheduler index in the environment.
    #[error(
        "--shard auto: neither SLURM_ARRAY_TASK_ID (a Slurm job array) nor JOB_COMPLETION_INDEX (a Kubernetes Indexed Job) is set; use --shard I/N outside a farm"
    )]
    NoSchedulerIndex,
    /// `JOB_COMPLETION_INDEX` without `--shard-count`.
    #[error("--shard auto with JOB_COMPLETION_INDEX needs --shard-count N (the Job's completions)")]
    CountNeeded,
    /// `--shard-count` without `--shard auto`.
    #[error("--shard-count goes with --shard auto only (--shard I/N names its count)")]
    CountWithoutAuto,
    /// An environment variable is missing or not a number.
    #[error("--shard auto: environment variable {name} is {value}")]
    BadEnv {
        /// The variable.
        name: &'static str,
        /// What is wrong with its value.
        value: String,
    },
    /// A Slurm array whose task IDs are not `MIN..=MAX` in steps of 1.
    #[error(
        "--shard auto: the Slurm array's task IDs are not contiguous ({detail}); pass --shard-count N so that task IDs 0..N-1 are the shard indices"
    )]
    SparseArray {
        /// What the environment says.
        detail: String,
    },
}

/// What `--shard` names: a fixed shard, or one taken from the environment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShardSpec {
    /// Shard `index` of `count` (index from 0).
    Fixed {
        /// The shard index, below `count`.
        index: u32,
        /// The number of shards.
        count: u32,
    },
    /// From `SLURM_ARRAY_TASK_*` or `JOB_COMPLETION_INDEX`.
    Auto,
}

impl ShardSpec {
    /// Parse `I/N` or `auto`.
    pub fn parse(text: &str) -> Result<Self, ShardError> {
        if text == "auto" {
            return Ok(Self::Auto);
        }
        let bad = || ShardError::BadShard(text.into());
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        check_index(index, count)?;
        Ok(Self::Fixed { index, count })
    }
}

fn check_index(index: u32, count: u32) -> Result<(), ShardError> {
    if count == 0 {
        return Err(ShardError::ZeroCount);
    }
    if index >= count {
        return Err(ShardError::IndexNotBelowCount { index, count });
    }
    Ok(())
}

/// Parse `--samples A..B` (A < B).
pub fn parse_samples(text: &str) -> Result<Range<u32>, ShardError> {
    let bad = || ShardError::BadSamples(text.into());
    let (a, b) = text.split_once("..").ok_or_else(bad)?;
    let a: u32 = a.trim().parse().map_err(|_| bad())?;
    let b: u32 = b.trim().parse().map_err(|_| bad())?;
    if a >= b {
        return Err(bad());
    }
    Ok(a..b)
}

/// The sample range of shard `index` of `count` over `0..spp`: near-equal
/// ranges (their lengths differ by at most 1) that cover `0..spp` exactly,
/// in order. Refuses an index not below the count and more shards than
/// samples.
pub fn shard_range(index: u32, count: u32, spp: u32) -> Result<Range<u32>, ShardError> {
    check_index(index, count)?;
    if count > spp {
        return Err(ShardError::MoreShardsThanSamples { count, spp });
    }
    let at = |i: u32| (i as u64 * spp as u64 / count as u64) as u32;
    Ok(at(index)..at(index + 1))
}

fn env_number(env: EnvLookup, name: &'static str) -> Result<Option<u32>, ShardError> {
    match env(name) {
        None => Ok(None),
        Some(v) => v.trim().parse().map(Some).map_err(|_| ShardError::BadEnv {
            name,
            value: format!("{v:?}, not a non-negative integer"),
        }),
    }
}

fn env_required(env: EnvLookup, name: &'static str) -> Result<u32, ShardError> {
    env_number(env, name)?.ok_or(ShardError::BadEnv {
        name,
        value: "not set".into(),
    })
}

/// The `(index, count)` that `--shard auto` means in this environment (see
/// the [module docs](self)); `count` is `--shard-count`.
pub fn auto_shard(count: Option<u32>, env: EnvLookup) -> Result<(u32, u32), ShardError> {
    let (index, count) = if let Some(id) = env_number(env, "SLURM_ARRAY_TASK_ID")? {
        match count {
            Some(count) => (id, count),
            None => {
                let n = env_required(env, "SLURM_ARRAY_TASK_COUNT")?;
                let min = env_required(env, "SLURM_ARRAY_TASK_MIN")?;
                let max = env_number(env, "SLURM_ARRAY_TASK_MAX")?;
                let step = env_number(env, "SLURM_ARRAY_TASK_STEP")?;
                let contiguous = id >= min
                    && max.is_none_or(|max| max >= min && max - min + 1 == n)
                    && step.is_none_or(|s| s == 1);
                if !contiguous {
                    let detail = format!(
                        "SLURM_ARRAY_TASK_ID={id}, _MIN={min}, _MAX={}, _COUNT={n}, _STEP={}",
                        max.map_or("unset".into(), |m| m.to_string()),
                        step.map_or("unset".into(), |s| s.to_string())
                    );
                    return Err(ShardError::SparseArray { detail });
                }
                (id - min, n)
            }
        }
    } else if let Some(index) = env_number(env, "JOB_COMPLETION_INDEX")? {
        (index, count.ok_or(ShardError::CountNeeded)?)
    } else {
        return Err(ShardError::NoSchedulerIndex);
    };
    check_index(index, count)?;
    Ok((index, count))
}

/// The thread count `SLURM_CPUS_PER_TASK` asks for, if it is set (Slurm
/// sets it when a job asks for `--cpus-per-task`).
pub fn threads_from_env(env: EnvLookup) -> Result<Option<usize>, ShardError> {
    match env_number(env, "SLURM_CPUS_PER_TASK") {
        Ok(Some(0)) => Err(ShardError::BadEnv {
            name: "SLURM_CPUS_PER_TASK",
            value: "0".into(),
        }),
        Ok(n) => Ok(n.map(|n| n as usize)),
        Err(ShardError::BadEnv { value, .. }) => Err(ShardError::BadEnv {
            name: "SLURM_CPUS_PER_TASK",
            value,
        }),
        Err(e) => Err(e),
    }
}

/// What a render is asked to cover of its samples `0..spp`: a sample
/// range (`--samples A..B`), a shard (`--shard I/N` or `auto`, with
/// `--shard-count`), or, when neither is given, all of them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SampleRequest {
    /// Sample indices `A..B`.
    pub samples: Option<Range<u32>>,
    /// A shard.
    pub shard: Option<ShardSpec>,
    /// The shard count, with [`ShardSpec::Auto`].
    pub shard_count: Option<u32>,
}

/// The samples a render covers, resolved from a [`SampleRequest`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SampleWork {
    /// The sample indices to render, within `0..spp`.
    pub range: Range<u32>,
    /// `(index, count)` when rendering a shard.
    pub shard: Option<(u32, u32)>,
}

impl SampleRequest {
    /// The sample range to render for a render of `spp` samples per pixel,
    /// all checked: `0..spp` when no range or shard is asked for.
    pub fn resolve(&self, spp: u32, env: EnvLookup) -> Result<SampleWork, ShardError> {
        if self.shard_count.is_some() && self.shard != Some(ShardSpec::Auto) {
            return Err(ShardError::CountWithoutAuto);
        }
        let shard = match self.shard {
            None => None,
            Some(ShardSpec::Fixed { index, count }) => Some((index, count)),
            Some(ShardSpec::Auto) => Some(auto_shard(self.shard_count, env)?),
        };
        let range = match (shard, &self.samples) {
            (Some((i, n)), _) => shard_range(i, n, spp)?,
            (None, Some(r)) if r.end > spp => {
                return Err(ShardError::SamplesBeyondSpp {
                    start: r.start,
                    end: r.end,
                    spp,
                });
            }
            (None, Some(r)) => r.clone(),
            (None, None) => 0..spp,
        };
        Ok(SampleWork { range, shard })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn env_of(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: HashMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |k| map.get(k).cloned()
    }

    #[test]
    fn shards_cover_spp_exactly_and_near_equally() {
        for spp in [1, 2, 7, 64, 100, 1000, 32768] {
            for count in [1, 2, 3, 4, 7, 16, 64] {
                if count > spp {
                    assert!(shard_range(0, count, spp).is_err());
                    continue;
                }
                let ranges: Vec<_> = (0..count)
                    .map(|i| shard_range(i, count, spp).unwrap())
                    .collect();
                assert_eq!(ranges[0].start, 0);
                assert_eq!(ranges.last().unwrap().end, spp);
                for w in ranges.windows(2) {
                    assert_eq!(w[0].end, w[1].start);
                }
                let lens: Vec<u32> = ranges.iter().map(|r| r.end - r.start).collect();
                let (lo, hi) = (lens.iter().min().unwrap(), lens.iter().max().unwrap());
                assert!(*lo >= 1 && hi - lo <= 1, "{spp} / {count}: {lens:?}");
            }
        }
    }

    #[test]
    fn parse_shards_and_samples() {
        assert_eq!(
            ShardSpec::parse("2/4"),
            Ok(ShardSpec::Fixed { index: 2, count: 4 })
        );
        assert_eq!(ShardSpec::parse("auto"), Ok(ShardSpec::Auto));
        assert_eq!(
            ShardSpec::parse("4/4"),
            Err(ShardError::IndexNotBelowCount { index: 4, count: 4 })
        );
        assert_eq!(ShardSpec::parse("0/0"), Err(ShardError::ZeroCount));
        assert!(ShardSpec::parse("1-4").is_err());
        assert_eq!(parse_samples("16..32"), Ok(16..32));
        assert!(parse_samples("32..16").is_err());
        assert!(parse_samples("5..5").is_err());
        assert!(parse_samples("5-9").is_err());
    }

    #[test]
    fn auto_shard_from_slurm_and_kubernetes() {
        let slurm = env_of(&[
            ("SLURM_ARRAY_TASK_ID", "3"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "4"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]);
        assert_eq!(auto_shard(None, &slurm), Ok((2, 4)));
        // With --shard-count the task ID is the shard index (reruns).
        let rerun = env_of(&[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_MIN", "2"),
            ("SLURM_ARRAY_TASK_MAX", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "1"),
        ]);
        assert_eq!(auto_shard(Some(4), &rerun), Ok((2, 4)));
        let sparse = env_of(&[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ]);
        assert!(matches!(
            auto_shard(None, &sparse),
            Err(ShardError::SparseArray { .. })
        ));
        let k8s = env_of(&[("JOB_COMPLETION_INDEX", "7")]);
        assert_eq!(auto_shard(Some(8), &k8s), Ok((7, 8)));
        assert_eq!(auto_shard(None, &k8s), Err(ShardError::CountNeeded));
        assert_eq!(
            auto_shard(Some(7), &k8s),
            Err(ShardError::IndexNotBelowCount { index: 7, count: 7 })
        );
        assert_eq!(
            auto_shard(Some(4), &env_of(&[])),
            Err(ShardError::NoSchedulerIndex)
        );
        assert!(matches!(
            auto_shard(None, &env_of(&[("SLURM_ARRAY_TASK_ID", "x")])),
            Err(ShardError::BadEnv { .. })
        ));
    }

    #[test]
    fn threads_follow_slurm_cpus_per_task() {
        assert_eq!(threads_from_env(&env_of(&[])), Ok(None));
        assert_eq!(
            threads_from_env(&env_of(&[("SLURM_CPUS_PER_TASK", "6")])),
            Ok(Some(6))
        );
        assert!(threads_from_env(&env_of(&[("SLURM_CPUS_PER_TASK", "0")])).is_err());
        assert!(threads_from_env(&env_of(&[("SLURM_CPUS_PER_TASK", "two")])).is_err());
    }

    #[test]
    fn resolve_checks_against_spp() {
        let none = env_of(&[]);
        let args = |samples, shard, shard_count| SampleRequest {
            samples,
            shard,
            shard_count,
        };
        assert_eq!(
            args(None, None, None).resolve(64, &none).unwrap().range,
            0..64
        );
        assert_eq!(
            args(Some(10..20), None, None).resolve(64, &none).unwrap(),
            SampleWork {
                range: 10..20,
                shard: None
            }
        );
        assert!(matches!(
            args(Some(10..65), None, None).resolve(64, &none),
            Err(ShardError::SamplesBeyondSpp { .. })
        ));
        let shard = Some(ShardSpec::Fixed { index: 3, count: 4 });
        assert_eq!(
            args(None, shard, None).resolve(64, &none).unwrap(),
            SampleWork {
                range: 48..64,
                shard: Some((3, 4))
            }
        );
        assert!(matches!(
            args(None, shard, None).resolve(3, &none),
            Err(ShardError::MoreShardsThanSamples { .. })
        ));
        assert_eq!(
            args(None, shard, Some(4)).resolve(64, &none),
            Err(ShardError::CountWithoutAuto)
        );
    }
}
