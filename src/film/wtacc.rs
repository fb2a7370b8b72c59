//! The accumulation file (`.wtacc`): a film's exact sums on disk.
//!
//! Checkpoints, shards' partial files and `.wtacc` outputs are all this one
//! format: an 8-byte magic, the length of a JSON header, the header
//! ([`AccMeta`] and the film's size, sample ranges and invalid-sample
//! count), the sums (three little-endian `u128` per pixel, row-major), and
//! an XXH3-128 checksum of everything before it.

use super::Film;
use crate::fs::{FileError, write_atomic};
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
        let header = AccHeader {
            format: ACC_FORMAT.into(),
            width: self.width,
            height: self.height,
            settings_hash: format!("{:032x}", meta.settings_hash),
            ranges: self.ranges.iter().map(|r| [r.start, r.end]).collect(),
            invalid_samples: self.invalid_samples,
            spp: meta.spp,
            shard: meta.shard.map(|(i, n)| [i, n]),
        };
        let header = serde_json::to_vec(&header).expect("header serialises");
        let mut bytes = Vec::with_capacity(16 + header.len() + self.sums.len() * 48 + 16);
        bytes.extend_from_slice(ACC_MAGIC);
        bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&header);
        for s in &self.sums {
            for c in s {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
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
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .map_err(|e| bad(format!("cannot read: {e}")))?;
        if bytes.len() < ACC_MAGIC.len() + 8 + 16 || &bytes[..8] != ACC_MAGIC {
            return Err(bad("not a wavetrace accumulation file".into()));
        }
        let (body, check) = bytes.split_at(bytes.len() - 16);
        if xxhash_rust::xxh3::xxh3_128(body) != u128::from_le_bytes(check.try_into().unwrap()) {
            return Err(bad(
                "checksum mismatch: the file is truncated or corrupt".into()
            ));
        }
        let header_len = u64::from_le_bytes(body[8..16].try_into().unwrap()) as usize;
        let header_bytes = body
            .get(16..16usize.saturating_add(header_len))
            .ok_or_else(|| bad("truncated header".into()))?;
        let header: AccHeader = serde_json::from_slice(header_bytes)
            .map_err(|e| bad(format!("unreadable header: {e}")))?;
        if header.format != ACC_FORMAT {
            return Err(bad(format!(
                "format {:?}, expected {ACC_FORMAT:?}",
                header.format
            )));
        }
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
        let pixels = header.width as usize * header.height as usize;
        let data = &body[16 + header_len..];
        if data.len() != pixels * 48 {
            return Err(bad(format!(
                "holds {} bytes of sums, expected {} for {}x{}",
                data.len(),
                pixels * 48,
                header.width,
                header.height
            )));
        }
        let sums = data
            .chunks_exact(48)
            .map(|p| {
                std::array::from_fn(|c| {
                    u128::from_le_bytes(p[c * 16..c * 16 + 16].try_into().unwrap())
                })
            })
            .collect();
        let mut film = Film::new(header.width, header.height);
        film.sums = sums;
        film.invalid_samples = header.invalid_samples;
        for [a, b] in header.ranges {
            if a >= b || film.ranges.iter().any(|r| a < r.end && r.start < b) {
                return Err(bad(format!("bad sample range {a}..{b}")));
            }
            film.add_range(a..b);
        }
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
            && i >= n
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

const ACC_MAGIC: &[u8; 8] = b"WTACC\0\0\x01";
const ACC_FORMAT: &str = "wavetrace-accumulation/1";

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
