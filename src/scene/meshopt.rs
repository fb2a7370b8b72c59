//! `EXT_meshopt_compression`: a glTF buffer view whose bytes are stored
//! compressed (in another buffer, at another range) and decoded at load.
//!
//! The extension's object on a buffer view names the compressed bytes
//! (`buffer`, `byteOffset`, `byteLength`) and what they decode to: `count`
//! elements of `byteStride` bytes, in one of three bitstreams (`mode`:
//! `ATTRIBUTES`, `TRIANGLES`, `INDICES`), then, for attributes, a filter
//! (`NONE`, `OCTAHEDRAL`, `QUATERNION`, `EXPONENTIAL`). The decoded bytes
//! are the buffer view's contents, so accessors, sparse substitution and
//! indices read them as they read any view. The bitstreams and filters
//! are decoded by the `meshopt` crate (meshoptimizer's own decoders, which
//! its author writes are safe on untrusted input); this module checks every
//! rule of the extension's specification first, so that the decoders'
//! preconditions always hold.

use serde::Deserialize;

/// A buffer view's `EXT_meshopt_compression` object, as the file has it.
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Compressed {
    /// The buffer holding the compressed bytes.
    pub buffer: usize,
    /// Where they start in it.
    #[serde(default)]
    pub byte_offset: usize,
    /// How many there are.
    pub byte_length: usize,
    /// The size of one decoded element.
    pub byte_stride: usize,
    /// The number of decoded elements.
    pub count: usize,
    /// The bitstream.
    pub mode: Mode,
    /// The filter applied after decoding (attributes only).
    #[serde(default)]
    pub filter: Filter,
    /// Ignored, as everywhere in glTF.
    #[serde(default)]
    pub extensions: Option<serde_json::Value>,
    /// Ignored, as everywhere in glTF.
    #[serde(default)]
    pub extras: Option<serde_json::Value>,
}

/// The compression mode: which bitstream the bytes are in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum Mode {
    /// Vertex attributes (any elements of a multiple of 4 bytes).
    Attributes,
    /// A triangle list's indices (2 or 4 bytes each).
    Triangles,
    /// Any other indices (2 or 4 bytes each).
    Indices,
}

/// The filter applied to decoded attributes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum Filter {
    /// The data as decoded.
    #[default]
    None,
    /// Unit vectors in octahedral encoding (4 or 8 bytes).
    Octahedral,
    /// Unit quaternions in max-component encoding (8 bytes).
    Quaternion,
    /// Floats as an 8-bit exponent and a 24-bit mantissa (4 bytes each).
    Exponential,
}

impl Compressed {
    /// Reads the extension's JSON object; the error names the field.
    pub fn parse(value: &serde_json::Value) -> Result<Compressed, String> {
        Compressed::deserialize(value).map_err(|e| e.to_string())
    }

    /// The decoded size, `count × byteStride` (`None` when it overflows).
    pub fn decoded_len(&self) -> Option<usize> {
        self.count.checked_mul(self.byte_stride)
    }

    /// The specification's rules on `byteStride`, `count` and `filter`
    /// for each mode and filter: the first one broken, as
    /// `(field, message)`.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        let s = self.byte_stride;
        match self.mode {
            Mode::Attributes => {
                if s == 0 || s % 4 != 0 || s > 256 {
                    return Err((
                        "byteStride",
                        format!("{s}: ATTRIBUTES needs a multiple of 4 up to 256"),
                    ));
                }
            }
            Mode::Triangles | Mode::Indices => {
                if s != 2 && s != 4 {
                    return Err(("byteStride", format!("{s}: {:?} needs 2 or 4", self.mode)));
                }
                if self.filter != Filter::None {
                    return Err((
                        "filter",
                        format!(
                            "{:?} on indices (only ATTRIBUTES are filtered)",
                            self.filter
                        ),
                    ));
                }
                if self.mode == Mode::Triangles && self.count % 3 != 0 {
                    return Err((
                        "count",
                        format!("{}: TRIANGLES needs a multiple of 3", self.count),
                    ));
                }
            }
        }
        let fits = match self.filter {
            Filter::None | Filter::Exponential => true,
            Filter::Octahedral => s == 4 || s == 8,
            Filter::Quaternion => s == 8,
        };
        if !fits {
            return Err((
                "byteStride",
                format!("{s} for the {:?} filter", self.filter),
            ));
        }
        Ok(())
    }

    /// Decodes `source` (the compressed bytes) into the view's
    /// `count × byteStride` bytes, the filter applied. [`Compressed::check`]
    /// must have passed; the caller has bounded the decoded size.
    pub fn decode(&self, source: &[u8]) -> Result<Vec<u8>, String> {
        let garbage = |e: meshopt::Error| {
            format!("the compressed bytes do not decode as {:?}: {e}", self.mode)
        };
        let len = self.decoded_len().ok_or("the decoded size overflows")?;
        if self.count == 0 {
            return Ok(Vec::new());
        }
        let s = self.byte_stride;
        match (self.mode, s) {
            (Mode::Triangles, 2) => meshopt::decode_index_buffer::<u16>(source, self.count)
                .map(|v| bytemuck::cast_slice(&v).to_vec())
                .map_err(garbage),
            (Mode::Triangles, _) => meshopt::decode_index_buffer::<u32>(source, self.count)
                .map(|v| bytemuck::cast_slice(&v).to_vec())
                .map_err(garbage),
            (Mode::Indices, 2) => meshopt::decode_index_sequence::<u16>(source, self.count)
                .map(|v| bytemuck::cast_slice(&v).to_vec())
                .map_err(garbage),
            (Mode::Indices, _) => meshopt::decode_index_sequence::<u32>(source, self.count)
                .map(|v| bytemuck::cast_slice(&v).to_vec())
                .map_err(garbage),
            (Mode::Attributes, _) => {
                // Words, so that the filters' views of the bytes (as i8,
                // i16 or u32) are aligned.
                let mut words = vec![0u32; len / 4];
                // SAFETY: `words` holds `count × byteStride` bytes, the
                // decoder's output; `check` made the stride a multiple of 4
                // in 4..=256, as it requires; it reads at most
                // `source.len()` bytes of `source`.
                let rc = unsafe {
                    meshopt::ffi::meshopt_decodeVertexBuffer(
                        words.as_mut_ptr().cast(),
                        self.count,
                        s,
                        source.as_ptr(),
                        source.len(),
                    )
                };
                if rc != 0 {
                    return Err(garbage(meshopt::Error::Native(rc)));
                }
                self.unfilter(&mut words);
                Ok(bytemuck::cast_slice(&words).to_vec())
            }
        }
    }

    /// The filter undone in place on decoded attributes.
    fn unfilter(&self, words: &mut [u32]) {
        match (self.filter, self.byte_stride) {
            (Filter::None, _) => {}
            (Filter::Octahedral, 4) => {
                meshopt::decode_filter_oct::<i8>(bytemuck::cast_slice_mut(words));
            }
            (Filter::Octahedral, _) => {
                meshopt::decode_filter_oct::<i16>(bytemuck::cast_slice_mut(words));
            }
            (Filter::Quaternion, _) => {
                meshopt::decode_filter_quat(bytemuck::cast_slice_mut(words));
            }
            // Each 32-bit component is decoded on its own, whatever the
            // stride.
            (Filter::Exponential, _) => {
                meshopt::decode_filter_exp::<1>(bytemuck::cast_slice_mut(words));
            }
        }
    }
}

/// Whether a buffer's JSON extensions mark it an `EXT_meshopt_compression`
/// fallback buffer (`"fallback": true`): one whose bytes need not be read.
pub fn is_fallback(extensions: &serde_json::Map<String, serde_json::Value>) -> bool {
    extensions
        .get("EXT_meshopt_compression")
        .and_then(|e| e.get("fallback"))
        .and_then(|f| f.as_bool())
        .unwrap_or(false)
}
