//! `EXT_meshopt_compression` and its ratified successor
//! `KHR_meshopt_compression`: a glTF buffer view whose bytes are stored
//! compressed (in another buffer, at another range) and decoded at load.
//! The two have the same object on a buffer view; the KHR one adds the
//! `COLOR` filter (YCoCg colours, 4 or 8 bytes) and version 1 of the
//! attribute bitstream, which meshoptimizer's decoder (1.3, bundled by the
//! `meshopt` crate) reads as it reads version 0, from the stream's first
//! byte.
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

/// A buffer view's `EXT_meshopt_compression` or `KHR_meshopt_compression`
/// object, as the file has it.
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
    /// RGBA colours in YCoCg (4 or 8 bytes; `KHR_meshopt_compression`
    /// only).
    Color,
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
                if s == 0 || !s.is_multiple_of(4) || s > 256 {
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
                if self.mode == Mode::Triangles && !self.count.is_multiple_of(3) {
                    return Err((
                        "count",
                        format!("{}: TRIANGLES needs a multiple of 3", self.count),
                    ));
                }
            }
        }
        let fits = match self.filter {
            Filter::None | Filter::Exponential => true,
            Filter::Octahedral | Filter::Color => s == 4 || s == 8,
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
    /// must have passed; the caller has bounded the decoded size. The
    /// bytes are decoded in place into one allocation (of words, so that
    /// the filters' views of them as `i8`, `i16` or `u32` are aligned).
    pub fn decode(&self, source: &[u8]) -> Result<Decoded, String> {
        let len = self.decoded_len().ok_or("the decoded size overflows")?;
        let mut words = vec![0u32; len.div_ceil(4)];
        if self.count == 0 {
            return Ok(Decoded { words, len });
        }
        let decoder = match self.mode {
            Mode::Attributes => meshopt::ffi::meshopt_decodeVertexBuffer,
            Mode::Triangles => meshopt::ffi::meshopt_decodeIndexBuffer,
            Mode::Indices => meshopt::ffi::meshopt_decodeIndexSequence,
        };
        // SAFETY: `words` holds at least `count × byteStride` bytes, what
        // the decoder writes; `check` made the decoder's preconditions
        // hold (a stride that is a multiple of 4 in 4..=256 for
        // attributes; 2 or 4 for indices, and a count that is a multiple
        // of 3 for triangles); it reads at most `source.len()` bytes of
        // `source`, and is written to be safe on any bytes there.
        let rc = unsafe {
            decoder(
                words.as_mut_ptr().cast(),
                self.count,
                self.byte_stride,
                source.as_ptr(),
                source.len(),
            )
        };
        if rc != 0 {
            return Err(format!(
                "the compressed bytes do not decode as {:?} (meshoptimizer's error {rc})",
                self.mode
            ));
        }
        self.unfilter(&mut words);
        Ok(Decoded { words, len })
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
            (Filter::Color, 4) => {
                meshopt::decode_filter_color::<u8>(bytemuck::cast_slice_mut(words));
            }
            (Filter::Color, _) => {
                meshopt::decode_filter_color::<u16>(bytemuck::cast_slice_mut(words));
            }
        }
    }
}

/// A buffer view's decoded bytes.
#[derive(Debug, Clone)]
pub struct Decoded {
    words: Vec<u32>,
    len: usize,
}

impl Decoded {
    /// The bytes (in the words' little-endian order, as glTF's buffers).
    pub fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice(&self.words)[..self.len]
    }
}

/// The two extensions' names: the ratified one first.
pub const EXTENSIONS: [&str; 2] = ["KHR_meshopt_compression", "EXT_meshopt_compression"];

/// Whether a buffer's JSON extensions mark it a fallback buffer of either
/// extension (`"fallback": true`): one whose bytes need not be read.
pub fn is_fallback(extensions: &serde_json::Map<String, serde_json::Value>) -> bool {
    EXTENSIONS.iter().any(|name| {
        extensions
            .get(*name)
            .and_then(|e| e.get("fallback"))
            .and_then(|f| f.as_bool())
            .unwrap_or(false)
    })
}
