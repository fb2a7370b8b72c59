//! The accumulation file (`.wtacc`): a film's exact sums on disk.
//!
//! Checkpoints, shards' partial files and `.wtacc` outputs are all this one
//! format: an 8-byte magic (`WTACC\0\0` and the version byte), the length
//! of a JSON header (`u64`, little-endian), the header ([`AccMeta`] and the
//! film's size, sample ranges and invalid-sample count), the sums (three
//! little-endian `u128` per pixel, row-major), and an XXH3-128 checksum of
//! everything before it.
//!
//! Two versions are read:
//!
//! - **1** (`wavetrace-accumulation/1`): a film without AOVs. Films without
//!   AOVs are still written as version 1, byte for byte as before AOVs
//!   existed (so builds that predate them read them too).
//! - **2** (`wavetrace-accumulation/2`): a film with AOVs. The header also
//!   has `"aov"`, the list of the AOVs held in canonical order (`["albedo",
//!   "normal", "depth", "variance"]` or a part of it), and after the
//!   radiance sums come, for each AOV in that order, its sums for every
//!   pixel, row-major, little-endian: albedo three `u128`, normal three
//!   `i128`, depth a `u128` sum and a `u64` hit count, variance three `u128`
//!   sums of squares, alpha a `u64` hit count, zdepth a `u128` sum and a
//!   `u64` hit count (see [`super::aov`]); object_id, the last when held,
//!   is of variable length: for each pixel a `u32` number of ids, then
//!   that many `u32` id and `u64` count pairs, ids ascending (none 0),
//!   counts at least 1, summing to at most the samples held. Files of the
//!   first four AOVs are what they were before the others existed.
//!
//! A file of another version (a newer wavetrace's) is refused with a
//! message that says so.

use super::aov::{Column, ReadError, bytes_per_pixel};
use super::{AovSums, Film};
use crate::fs::{FileError, write_atomic};
use crate::scene::{Aov, AovSet};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// An accumulation file that cannot be used, and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct WtaccError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong with it.
    pub message: String,
}

impl Film {
    /// Write this film as an accumulation file (atomically): a header, the
    /// sums, and a checksum. `settings_hash` identifies the scene and the
    /// settings that change the image, so files of other renders are refused.
    pub fn save(&self, path: &Path, settings_hash: u128) -> Result<(), FileError> {
        self.save_with_meta(path, &AccMeta::new(settings_hash))
    }

    /// [`Film::save`] with the optional facts of [`AccMeta`] (the whole
    /// render's sample count, the shard) in the header as well.
    pub fn save_with_meta(&self, path: &Path, meta: &AccMeta) -> Result<(), FileError> {
        if self.counts.is_some() {
            let why = "an adaptive render's film (pixels of their own sample counts) has no accumulation file";
            return Err(FileError::new(
                path,
                std::io::Error::new(std::io::ErrorKind::InvalidInput, why),
            ));
        }
        // Version 1 when there is no AOV: the same bytes as before AOVs.
        let version = if self.aov.is_empty() { 1 } else { 2 };
        let header = AccHeader {
            format: format!("{ACC_FORMAT_PREFIX}{version}"),
            width: self.width,
            height: self.height,
            settings_hash: format!("{:032x}", meta.settings_hash),
            ranges: self.ranges.iter().map(|r| [r.start, r.end]).collect(),
            invalid_samples: self.invalid_samples,
            spp: meta.spp,
            shard: meta.shard.map(|(i, n)| [i, n]),
            aov: (version == 2)
                .then(|| self.aovs().names().iter().map(|n| n.to_string()).collect()),
        };
        let header = serde_json::to_vec(&header).expect("header serialises");
        let per_pixel = 48 + self.aovs().iter().map(bytes_per_pixel).sum::<usize>();
        let mut bytes = Vec::with_capacity(16 + header.len() + self.sums.len() * per_pixel + 16);
        bytes.extend_from_slice(ACC_MAGIC_PREFIX);
        bytes.push(version);
        bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&header);
        for s in &self.sums {
            for c in s {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        for (_, column) in &self.aov.columns {
            column.write(&mut bytes);
        }
        let check = xxhash_rust::xxh3::xxh3_128(&bytes);
        bytes.extend_from_slice(&check.to_le_bytes());
        write_atomic(path, |w| w.write_all(&bytes))
    }

    /// Read an accumulation file, refusing a corrupt or truncated one, and
    /// one whose settings hash is not `expected_hash` (when given).
    /// Returns the film and the file's settings hash.
    pub fn load(path: &Path, expected_hash: Option<u128>) -> Result<(Self, u128), WtaccError> {
        Self::load_with_meta(path, expected_hash).map(|(film, meta)| (film, meta.settings_hash))
    }

    /// [`Film::load`], returning the header's [`AccMeta`] as well. A range
    /// beyond the header's `spp`, or a shard whose index is not below its
    /// count, is refused as corrupt.
    pub fn load_with_meta(
        path: &Path,
        expected_hash: Option<u128>,
    ) -> Result<(Self, AccMeta), WtaccError> {
        let bad = |message: String| WtaccError {
            path: path.to_path_buf(),
            message,
        };
        let mut file = std::fs::File::open(path).map_err(|e| bad(format!("cannot read: {e}")))?;
        // Read whole (it is checked whole): refused if it cannot fit.
        let size = file.metadata().map_or(0, |m| m.len());
        if let Some(memory) = crate::fs::system_memory()
            && size > memory / 2
        {
            return Err(bad(format!(
                "{size} bytes: too large to load in this system's memory ({memory} bytes)"
            )));
        }
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes)
            .map_err(|e| bad(format!("cannot read: {e}")))?;
        if bytes.len() < ACC_MAGIC_PREFIX.len() + 1 + 8 + 16 || !bytes.starts_with(ACC_MAGIC_PREFIX)
        {
            return Err(bad("not a wavetrace accumulation file".into()));
        }
        // The version is looked at before anything else a newer version
        // may lay out differently (the checksum included).
        let version = bytes[ACC_MAGIC_PREFIX.len()];
        if !(1..=ACC_VERSION).contains(&version) {
            return Err(bad(format!(
                "accumulation file version {version}: this build of wavetrace reads versions 1 to {ACC_VERSION} (written by a newer wavetrace? render or merge it with that one)"
            )));
        }
        let (body, check) = bytes.split_at(bytes.len() - 16);
        let check: [u8; 16] = check.try_into().unwrap_or_default();
        if xxhash_rust::xxh3::xxh3_128(body) != u128::from_le_bytes(check) {
            return Err(bad(
                "checksum mismatch: the file is truncated or corrupt".into()
            ));
        }
        let header_len = u64::from_le_bytes(body[8..16].try_into().unwrap_or_default());
        let header_len = usize::try_from(header_len).unwrap_or(usize::MAX);
        let header_bytes = body
            .get(16..16usize.saturating_add(header_len))
            .ok_or_else(|| bad("truncated header".into()))?;
        let header: AccHeader = serde_json::from_slice(header_bytes)
            .map_err(|e| bad(format!("unreadable header: {e}")))?;
        let format = format!("{ACC_FORMAT_PREFIX}{version}");
        if header.format != format {
            return Err(bad(format!(
                "format {:?}, expected {format:?} (the magic's version)",
                header.format
            )));
        }
        let aovs = match (version, &header.aov) {
            (1, None) => AovSet::NONE,
            (1, Some(_)) => return Err(bad("a version 1 file cannot hold AOVs".into())),
            (_, None) => return Err(bad(format!("a version {version} file must list its AOVs"))),
            (_, Some(names)) => {
                let set = AovSet::from_names(names.iter().map(String::as_str))
                    .map_err(|e| bad(format!("header: {e}")))?;
                let canonical = set.names();
                if set.is_empty() || canonical != *names {
                    return Err(bad(format!(
                        "header: AOVs {names:?}: expected a non-empty list in the order {:?}",
                        Aov::NAMES
                    )));
                }
                set
            }
        };
        let hash = u128::from_str_radix(&header.settings_hash, 16)
            .map_err(|_| bad("unreadable settings hash".into()))?;
        if let Some(expected) = expected_hash
            && hash != expected
        {
            return Err(bad(
                "made by a render of another scene or other settings (settings hash differs)"
                    .into(),
            ));
        }
        // The size is checked against the data before anything of that
        // size is allocated: a forged header cannot make wavetrace allocate
        // more than the file holds.
        if header.width == 0 || header.height == 0 {
            return Err(bad(format!(
                "the image is {}x{}: width and height must be at least 1",
                header.width, header.height
            )));
        }
        let data = &body[16 + header_len..];
        let per_pixel = 48 + aovs.iter().map(bytes_per_pixel).sum::<usize>() as u64;
        let expected = (header.width as u64)
            .checked_mul(header.height as u64)
            .and_then(|n| n.checked_mul(per_pixel));
        // The object ids' plane is of variable length: at least its size.
        let variable = aovs.contains(Aov::ObjectId);
        let fits = match expected {
            Some(n) if variable => data.len() as u64 >= n,
            n => n == Some(data.len() as u64),
        };
        if !fits {
            return Err(bad(format!(
                "holds {} bytes of sums, expected {} for {}x{}{}",
                data.len(),
                match expected {
                    Some(n) if variable => format!("at least {n}"),
                    Some(n) => n.to_string(),
                    None => "more than 2^64".into(),
                },
                header.width,
                header.height,
                if aovs.is_empty() {
                    String::new()
                } else {
                    format!(" with AOVs {aovs}")
                }
            )));
        }
        let ranges = super::ranges::sorted_disjoint(&header.ranges)
            .map_err(|[a, b]| bad(format!("bad sample range {a}..{b}")))?;
        let held: u64 = ranges.iter().map(|r| (r.end - r.start) as u64).sum();
        // No sample adds 2^63 or more to a sum (see `accumulate`), so a
        // pixel of `held` samples sums to less than held * 2^63: a larger
        // sum is forged, and refusing it keeps every later addition of
        // sums (merges, resumed renders) from overflowing. The AOVs' sums
        // have bounds of their own (`aov::most`).
        let pixels = header.width as usize * header.height as usize;
        let w = header.width as usize;
        let too_large = |what: &str, i: usize| {
            bad(format!(
                "pixel ({}, {}) holds {what} larger than its {held} sample(s) can make",
                i % w,
                i / w
            ))
        };
        let u128_at =
            |b: &[u8], at: usize| u128::from_le_bytes(b[at..at + 16].try_into().unwrap_or([0; 16]));
        let (radiance, mut rest) = data.split_at(pixels * 48);
        let most_radiance = (held as u128) << 63;
        let mut sums = Vec::with_capacity(pixels);
        for (i, p) in radiance.chunks_exact(48).enumerate() {
            let sum: super::PixelSum = std::array::from_fn(|c| u128_at(p, c * 16));
            if sum.iter().any(|&c| c > most_radiance) {
                return Err(too_large("a sum", i));
            }
            sums.push(sum);
        }
        let mut aov = AovSums {
            set: aovs,
            columns: Vec::new(),
        };
        for kind in aovs.iter() {
            let (column, tail) = Column::read(kind, rest, pixels, held).map_err(|e| match e {
                ReadError::TooLarge(i, what) => too_large(&what, i),
                ReadError::Invalid(i, rule) => bad(format!("pixel ({}, {}): {rule}", i % w, i / w)),
                ReadError::Truncated(what) => bad(what),
            })?;
            aov.columns.push((kind, column));
            rest = tail;
        }
        debug_assert!(rest.is_empty());
        let film = Film {
            width: header.width,
            height: header.height,
            sums,
            ranges,
            invalid_samples: header.invalid_samples,
            aov,
            counts: None,
        };
        if let Some(spp) = header.spp
            && let Some(last) = film.ranges.last()
            && last.end > spp
        {
            return Err(bad(format!(
                "holds samples up to {} of a {spp}-sample render",
                last.end
            )));
        }
        if let Some([i, n]) = header.shard
            && (i >= n || header.spp.is_some_and(|spp| n > spp))
        {
            return Err(bad(format!("bad shard {i}/{n}")));
        }
        let meta = AccMeta {
            settings_hash: hash,
            spp: header.spp,
            shard: header.shard.map(|[i, n]| (i, n)),
        };
        Ok((film, meta))
    }
}

/// The magic's first seven bytes; the eighth is the version.
const ACC_MAGIC_PREFIX: &[u8; 7] = b"WTACC\0\0";
/// The newest version this build reads and writes.
const ACC_VERSION: u8 = 2;
/// The header's `format` is this and the version.
const ACC_FORMAT_PREFIX: &str = "wavetrace-accumulation/";

#[derive(serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct AccHeader {
    format: String,
    width: u32,
    height: u32,
    settings_hash: String,
    ranges: Vec<[u32; 2]>,
    invalid_samples: u64,
    /// Added for shards: absent in files that do not say it, so files
    /// without it are byte-for-byte what they were before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    spp: Option<u32>,
    /// Added for shards, like `spp`: `[index, count]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    shard: Option<[u32; 2]>,
    /// Version 2: the AOVs held, in canonical order (absent in version 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    aov: Option<Vec<String>>,
}

/// What an accumulation file's header says besides the film itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AccMeta {
    /// The scene-and-settings hash ([`crate::render::RenderSettings::image_hash`]).
    pub settings_hash: u128,
    /// The samples per pixel of the whole render this film is (part of),
    /// when known: what a merge must cover.
    pub spp: Option<u32>,
    /// `(index, count)` when the film is one shard of `count`.
    pub shard: Option<(u32, u32)>,
}

impl AccMeta {
    /// Just a settings hash, nothing else known.
    pub fn new(settings_hash: u128) -> Self {
        Self {
            settings_hash,
            spp: None,
            shard: None,
        }
    }
}
