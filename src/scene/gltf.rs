//! glTF 2.0 (`.gltf` with its buffers and images, or `.glb`) to an
//! [`Asset`].
//!
//! The `gltf` crate parses and validates the JSON (every index in range,
//! every required property there); this module reads the binary data
//! itself, and checks every accessor's offset, stride and size against its
//! buffer view and buffer, with checked arithmetic, before it allocates
//! anything, so that no file can make it panic or allocate what the file
//! does not hold.
//!
//! What it reads, ignores and refuses:
//!
//! - the default scene (or the first; or every root node where the file
//!   has no scene), its node hierarchy with TRS or matrix transforms;
//!   nodes with two parents and cycles are refused;
//! - mesh primitives of mode TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN
//!   (points and lines are skipped, with one warning); indices of `u8`,
//!   `u16` or `u32`; sparse accessors; `POSITION` (finite), `NORMAL`,
//!   `TEXCOORD_0`/`_1`, `TANGENT` (generated with MikkTSpace where a
//!   normal texture needs them and the file has none), `COLOR_0`; float
//!   and normalised integer components, and `KHR_mesh_quantization`'s
//!   integers that are not normalised (positions and texture coordinates);
//! - `EXT_meshopt_compression` and `KHR_meshopt_compression`: every
//!   compressed buffer view is decoded once, before any accessor is read
//!   ([`super::meshopt`]); fallback buffers are not read;
//! - metallic-roughness materials with their textures and
//!   `KHR_texture_transform`, `KHR_materials_emissive_strength`,
//!   `KHR_materials_ior`, `KHR_materials_specular`,
//!   `KHR_materials_transmission`, `KHR_materials_volume` (see
//!   [`PbrMaterial`]); occlusion textures are ignored (a path tracer
//!   computes occlusion);
//! - perspective cameras (orthographic ones are skipped with a warning);
//! - `KHR_lights_punctual` lights (directional, point, spot), placed by
//!   their nodes, their candela and lux divided by 683 lm/W
//!   ([`LUMENS_PER_WATT`]) into W/sr and W/m²;
//! - images in PNG or JPEG, in a buffer view, a data URI or a file beside
//!   the asset;
//! - `KHR_draco_mesh_compression`: each compressed primitive's stream is
//!   decoded once, when the primitive is read, into the bytes its
//!   accessors would have held ([`super::draco`]);
//! - any other required extension is refused by name, any other used one
//!   ignored with a warning.

use super::asset::{AlphaMode, Asset, AssetCamera, AssetError, AssetMesh, Instance, PbrMaterial};
use super::draco;
use super::meshopt::{self, Compressed};
use super::punctual::{LUMENS_PER_WATT, LightShape, PunctualLight};
use super::texture::{ColourSpace, Filter, Sampler, Texture, TextureRef, UvTransform, Wrap};
use base64::Engine;
use glam::{Mat4, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use std::collections::HashMap;
use std::path::Path;

/// The extensions read (the others are ignored, or refused where
/// required).
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_texture_transform",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_lights_punctual",
    "KHR_mesh_quantization",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "KHR_draco_mesh_compression",
];

/// The most elements an accessor without a buffer view (all zeros, then
/// sparse values) may declare; it may declare no more than the file's
/// buffers have bytes either (but always [`MIN_ZERO_ELEMENTS`]).
pub const MAX_ZERO_ELEMENTS: usize = 1 << 26;

/// The elements an accessor without a buffer view may always declare,
/// however small the file's buffers.
pub const MIN_ZERO_ELEMENTS: usize = 1 << 16;

/// What the decoded accessors of one file may take, at most, in all: this
/// many times its buffers' bytes, plus [`DECODE_ALLOWANCE`]. Several
/// primitives may read one accessor (each decodes it again), so without a
/// bound a small file of many primitives sharing one large accessor could
/// ask for any amount of memory.
pub const DECODE_RATIO: u64 = 64;

/// The decoded bytes any file may take, whatever its size (64 MiB).
pub const DECODE_ALLOWANCE: u64 = 1 << 26;

/// The most triangles one asset may have.
pub const MAX_TRIANGLES: usize = 1 << 28;

/// Reads the glTF or GLB file at `path`.
pub fn load(path: &Path) -> Result<Asset, AssetError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path)
        .map_err(|e| AssetError::new(&file, "", format!("cannot read the file: {e}")))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    read(&bytes, &file, Some(dir))
}

/// Reads a glTF or GLB file's bytes; `file` names it in errors, and `dir`
/// is where its external buffers and images are (`None`: refuse them).
pub fn read(bytes: &[u8], file: &str, dir: Option<&Path>) -> Result<Asset, AssetError> {
    let invalid = |e: &dyn std::fmt::Display| {
        AssetError::new(file, "", format!("not a valid glTF 2.0 file: {e}"))
    };
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| invalid(&e))?;
    // Checked before validation, which would index out of range (a
    // panic) on a POSITION accessor that is not there.
    let json = document.as_json();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= json.accessors.len() {
                    return Err(AssetError::new(
                        file,
                        format!("meshes[{m}].primitives[{p}].attributes.{semantic:?}"),
                        format!("accessor {} of {}", index.value(), json.accessors.len()),
                    ));
                }
            }
        }
    }
    // A file that requires an extension wavetrace does not read is refused
    // for that, not for what validation then misses (a Draco mesh's
    // accessors have no buffer views).
    check_required_extensions(&document, file)?;
    // The gltf crate's validation refuses required extensions it does not
    // know itself (KHR_mesh_quantization, EXT_meshopt_compression, which
    // this module reads): those checked above are taken off its list.
    let mut root = document.into_json();
    root.extensions_required
        .retain(|e| !SUPPORTED_EXTENSIONS.contains(&e.as_str()));
    let document = validated(root).map_err(|e| invalid(&e))?;
    let gltf = gltf::Gltf { document, blob };
    let mut r = Reader {
        file,
        dir,
        doc: &gltf.document,
        buffers: Vec::new(),
        asset: Asset::default(),
        textures: HashMap::new(),
        files: Default::default(),
        decoded: Default::default(),
        views: Vec::new(),
        placeholders: Vec::new(),
        draco: HashMap::new(),
    };
    r.warn_unread_extensions();
    r.buffers = r.load_buffers(gltf.blob.as_deref())?;
    r.views = r.decode_compressed_views()?;
    r.read_materials()?;
    r.read_scene()?;
    r.asset.sources = r.files.into_inner();
    Ok(r.asset)
}

/// The `gltf` crate's validation of the JSON, less one rule that
/// `KHR_draco_mesh_compression` breaks by design: the accessors a Draco
/// primitive fills have no buffer view (its stream is their data).
fn validated(root: gltf::json::Root) -> Result<gltf::Document, gltf::Error> {
    use gltf::json::validation::{Error, Validate};
    let draco: std::collections::HashSet<String> = (root.meshes.iter())
        .flat_map(|m| &m.primitives)
        .filter(|p| {
            (p.extensions.as_ref())
                .is_some_and(|e| e.others.contains_key("KHR_draco_mesh_compression"))
        })
        .flat_map(|p| p.indices.iter().chain(p.attributes.values()))
        .map(|i| format!("accessors[{}].bufferView", i.value()))
        .collect();
    let mut errors = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |path, error| {
        let path = path();
        if !(matches!(error, Error::Missing) && draco.contains(path.as_str())) {
            errors.push((path, error));
        }
    });
    if errors.is_empty() {
        Ok(gltf::Document::from_json_without_validation(root))
    } else {
        Err(gltf::Error::Validation(errors))
    }
}

/// Refuses a file that requires an extension wavetrace does not read, by
/// name.
fn check_required_extensions(doc: &gltf::Document, file: &str) -> Result<(), AssetError> {
    for ext in doc.extensions_required() {
        match ext {
            e if SUPPORTED_EXTENSIONS.contains(&e) => {}
            e => {
                return Err(AssetError::new(
                    file,
                    "extensionsRequired",
                    format!("the file requires the extension {e}, which wavetrace does not read"),
                ));
            }
        }
    }
    Ok(())
}

struct Reader<'a> {
    file: &'a str,
    dir: Option<&'a Path>,
    doc: &'a gltf::Document,
    buffers: Vec<Vec<u8>>,
    asset: Asset,
    /// Decoded textures by (image, colour space).
    textures: HashMap<(usize, bool), u32>,
    /// The external files read (buffers, images).
    files: std::cell::RefCell<Vec<std::path::PathBuf>>,
    /// The bytes of the accessors (and compressed views) decoded so far.
    decoded: std::cell::Cell<u64>,
    /// Each buffer view's decoded bytes, where it is compressed
    /// (`EXT_meshopt_compression`, `KHR_meshopt_compression`).
    views: Vec<Option<meshopt::Decoded>>,
    /// Whether each buffer is a placeholder (a meshopt compression
    /// fallback, or a buffer without data that only compressed views
    /// use): not read, and empty in `buffers`.
    placeholders: Vec<bool>,
    /// The accessors the primitive being read fills from its Draco stream
    /// (`KHR_draco_mesh_compression`): their bytes, by accessor index,
    /// read in place of their (absent) buffer views.
    draco: HashMap<usize, Vec<u8>>,
}

impl Reader<'_> {
    fn err(&self, at: impl Into<String>, message: impl Into<String>) -> AssetError {
        AssetError::new(self.file, at, message)
    }

    fn warn_unread_extensions(&mut self) {
        for ext in self.doc.extensions_used() {
            if !SUPPORTED_EXTENSIONS.contains(&ext) {
                self.asset
                    .warnings
                    .push(format!("{}: extension {ext} ignored", self.file));
            }
        }
    }

    /// Bytes from a URI: a base64 data URI, or a file beside the asset.
    fn uri_bytes(&self, uri: &str, at: &str) -> Result<Vec<u8>, AssetError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let (_, data) = rest
                .split_once(";base64,")
                .ok_or_else(|| self.err(at, "a data URI that is not base64"))?;
            return base64::engine::general_purpose::STANDARD
                .decode(data)
                .map_err(|e| self.err(at, format!("bad base64 data: {e}")));
        }
        if uri.contains("://") {
            return Err(self.err(at, format!("a URI wavetrace cannot read: {uri}")));
        }
        let dir = self.dir.ok_or_else(|| {
            self.err(
                at,
                format!("an external file ({uri}) where none can be read"),
            )
        })?;
        let name = percent_decode(uri);
        let path = dir.join(&name);
        self.files.borrow_mut().push(path.clone());
        std::fs::read(&path)
            .map_err(|e| self.err(at, format!("cannot read {}: {e}", path.display())))
    }

    /// Whether buffer `b` is a placeholder for compressed views: marked
    /// as a fallback, or without a URI where the GLB binary chunk cannot
    /// be its data (in a `.gltf`, or past buffer 0) in a file that uses
    /// `EXT_meshopt_compression` or `KHR_meshopt_compression`.
    fn is_placeholder(&self, b: &gltf::Buffer, blob: bool) -> bool {
        let uses = self
            .doc
            .extensions_used()
            .any(|e| meshopt::EXTENSIONS.contains(&e));
        let no_data = matches!(b.source(), gltf::buffer::Source::Bin) && (!blob || b.index() > 0);
        uses && (b.extensions().is_some_and(meshopt::is_fallback) || no_data)
    }

    fn load_buffers(&mut self, blob: Option<&[u8]>) -> Result<Vec<Vec<u8>>, AssetError> {
        let mut out = Vec::new();
        for b in self.doc.buffers() {
            let at = format!("buffers[{}]", b.index());
            let placeholder = self.is_placeholder(&b, blob.is_some());
            self.placeholders.push(placeholder);
            if placeholder {
                out.push(Vec::new());
                continue;
            }
            let data = match b.source() {
                gltf::buffer::Source::Bin => blob
                    .ok_or_else(|| {
                        self.err(&at, "refers to a GLB binary chunk the file does not have")
                    })?
                    .to_vec(),
                gltf::buffer::Source::Uri(uri) => self.uri_bytes(uri, &format!("{at}.uri"))?,
            };
            if data.len() < b.length() {
                return Err(self.err(
                    format!("{at}.byteLength"),
                    format!("{} bytes declared, {} present", b.length(), data.len()),
                ));
            }
            out.push(data);
        }
        Ok(out)
    }

    /// Every meshopt-compressed buffer view decoded (`None` for
    /// the others), once, before any accessor reads them.
    fn decode_compressed_views(&self) -> Result<Vec<Option<meshopt::Decoded>>, AssetError> {
        let mut out = Vec::new();
        for view in self.doc.views() {
            let mut named = (meshopt::EXTENSIONS.iter())
                .filter_map(|&name| Some((name, view.extension_value(name)?)));
            out.push(match (named.next(), named.next()) {
                (Some(_), Some(_)) => {
                    return Err(self.err(
                        format!("bufferViews[{}].extensions", view.index()),
                        "both KHR_meshopt_compression and EXT_meshopt_compression \
                         (the KHR extension must not be used with the EXT one)",
                    ));
                }
                (Some((name, value)), None) => Some(self.decode_view(&view, name, value)?),
                _ => None,
            });
        }
        Ok(out)
    }

    /// One compressed buffer view decoded: the extension's rules checked,
    /// its source range checked against its buffer, and its decoded size
    /// against the view's `byteLength` and the decoding budget, before
    /// anything is allocated.
    fn decode_view(
        &self,
        view: &gltf::buffer::View,
        name: &str,
        value: &serde_json::Value,
    ) -> Result<meshopt::Decoded, AssetError> {
        let at = format!("bufferViews[{}].extensions.{name}", view.index());
        let c = Compressed::parse(value).map_err(|e| self.err(&at, e))?;
        if c.filter == meshopt::Filter::Color && name == "EXT_meshopt_compression" {
            return Err(self.err(
                format!("{at}.filter"),
                "COLOR is a filter of KHR_meshopt_compression, not of EXT_meshopt_compression",
            ));
        }
        c.check()
            .map_err(|(field, m)| self.err(format!("{at}.{field}"), m))?;
        let len = c
            .decoded_len()
            .filter(|&n| n == view.length())
            .ok_or_else(|| {
                self.err(
                    format!("{at}.count"),
                    format!(
                        "{} elements of {} bytes do not make the buffer view's byteLength of {}",
                        c.count,
                        c.byte_stride,
                        view.length()
                    ),
                )
            })?;
        if let Some(stride) = view.stride().filter(|&s| s != c.byte_stride) {
            return Err(self.err(
                format!("{at}.byteStride"),
                format!(
                    "{}, but the buffer view's byteStride is {stride}",
                    c.byte_stride
                ),
            ));
        }
        let source = match self.buffers.get(c.buffer) {
            Some(_) if self.placeholders[c.buffer] => Err(format!(
                "{}: a fallback buffer without data cannot hold compressed bytes",
                c.buffer
            )),
            Some(b) => Ok(b),
            None => Err(format!("buffer {} of {}", c.buffer, self.buffers.len())),
        }
        .map_err(|m| self.err(format!("{at}.buffer"), m))?;
        let end = c
            .byte_offset
            .checked_add(c.byte_length)
            .filter(|&e| e <= source.len())
            .ok_or_else(|| {
                self.err(
                    format!("{at}.byteLength"),
                    format!(
                        "bytes {} + {} lie outside buffer {} of {} bytes",
                        c.byte_offset,
                        c.byte_length,
                        c.buffer,
                        source.len()
                    ),
                )
            })?;
        self.charge(len as u64, &format!("{len} decoded bytes"), &at)?;
        c.decode(&source[c.byte_offset..end])
            .map_err(|e| self.err(&at, e))
    }

    /// Adds `bytes` (`what`: "1024 elements") to the decoded bytes,
    /// refusing them past the budget ([`DECODE_RATIO`] times the file's
    /// buffers' bytes, plus [`DECODE_ALLOWANCE`]).
    fn charge(&self, bytes: u64, what: &str, at: &str) -> Result<(), AssetError> {
        let buffer_bytes: u64 = self.buffers.iter().map(|b| b.len() as u64).sum();
        let decoded = bytes.saturating_add(self.decoded.get());
        let budget = buffer_bytes
            .saturating_mul(DECODE_RATIO)
            .saturating_add(DECODE_ALLOWANCE);
        if decoded > budget {
            return Err(self.err(
                at,
                format!(
                    "{what} would bring the decoded data to {decoded} bytes, \
                     more than {DECODE_RATIO} times the file's {buffer_bytes} bytes of buffers \
                     (plus {DECODE_ALLOWANCE})"
                ),
            ));
        }
        self.decoded.set(decoded);
        Ok(())
    }

    /// The bytes of buffer view `view`, checked against its buffer (or,
    /// where it is compressed, decoded).
    fn view_bytes(&self, view: &gltf::buffer::View, at: &str) -> Result<&[u8], AssetError> {
        if let Some(Some(decoded)) = self.views.get(view.index()) {
            return Ok(decoded.bytes());
        }
        let b = view.buffer().index();
        if self.placeholders[b] {
            return Err(self.err(
                format!("bufferViews[{}]", view.index()),
                format!(
                    "its buffer {b} is a meshopt compression fallback without data, \
                     and the view is not compressed (read for {at})"
                ),
            ));
        }
        let buffer = &self.buffers[b];
        let end = view
            .offset()
            .checked_add(view.length())
            .filter(|&e| e <= buffer.len())
            .ok_or_else(|| {
                self.err(
                    format!("bufferViews[{}]", view.index()),
                    format!(
                        "bytes {} + {} lie outside its buffer of {} bytes (read for {at})",
                        view.offset(),
                        view.length(),
                        buffer.len()
                    ),
                )
            })?;
        Ok(&buffer[view.offset()..end])
    }

    /// `count` elements of `size` bytes each, `stride` apart, from
    /// `offset` in `view`: the bytes of each element, all checked.
    fn elements<'s>(
        &'s self,
        view: &gltf::buffer::View,
        offset: usize,
        count: usize,
        size: usize,
        at: &str,
    ) -> Result<Elements<'s>, AssetError> {
        let bytes = self.view_bytes(view, at)?;
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err(self.err(
                at,
                format!("a byte stride of {stride} for elements of {size} bytes"),
            ));
        }
        if count == 0 {
            return Ok(Elements {
                bytes: &[],
                stride,
                size,
                count,
            });
        }
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(offset))
            .and_then(|x| x.checked_add(size))
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| {
                self.err(
                    at,
                    format!(
                        "{count} elements of {size} bytes, {stride} apart from byte {offset}, \
                         do not fit its buffer view of {} bytes",
                        bytes.len()
                    ),
                )
            })?;
        Ok(Elements {
            bytes: &bytes[offset..end],
            stride,
            size,
            count,
        })
    }

    /// An accessor's elements as `f32` components (`n` of them each;
    /// normalised integers are mapped to `[0, 1]` or `[-1, 1]`; integers
    /// that are not normalised, where `integers` allows them, are read as
    /// their values).
    fn read_floats<const N: usize>(
        &self,
        acc: &gltf::Accessor,
        at: &str,
        allowed: &[Dimensions],
        integers: bool,
    ) -> Result<Vec<[f32; N]>, AssetError> {
        let dims = acc.dimensions();
        if !allowed.contains(&dims) {
            return Err(self.err(
                at,
                format!("an accessor of type {dims:?}, expected one of {allowed:?}"),
            ));
        }
        let m = dims.multiplicity();
        let ty = acc.data_type();
        let normalized = acc.normalized();
        let quantized = integers
            && matches!(
                ty,
                DataType::I8 | DataType::U8 | DataType::I16 | DataType::U16
            );
        if !normalized && ty != DataType::F32 && !matches!(dims, Dimensions::Scalar) && !quantized {
            // Integers that are not normalised are allowed only for
            // positions and texture coordinates, by KHR_mesh_quantization.
            return Err(self.err(
                at,
                format!(
                    "components of type {ty:?} that are not normalised (allowed for \
                     POSITION and TEXCOORD_n where the file uses KHR_mesh_quantization)"
                ),
            ));
        }
        let cs = ty.size();
        let decode = |b: &[u8]| -> f32 {
            match (ty, normalized) {
                (DataType::F32, _) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                (DataType::U8, true) => b[0] as f32 / 255.0,
                (DataType::I8, true) => (b[0] as i8 as f32 / 127.0).max(-1.0),
                (DataType::U16, true) => u16::from_le_bytes([b[0], b[1]]) as f32 / 65_535.0,
                (DataType::I16, true) => {
                    (i16::from_le_bytes([b[0], b[1]]) as f32 / 32_767.0).max(-1.0)
                }
                (DataType::U8, false) => b[0] as f32,
                (DataType::I8, false) => b[0] as i8 as f32,
                (DataType::U16, false) => u16::from_le_bytes([b[0], b[1]]) as f32,
                (DataType::I16, false) => i16::from_le_bytes([b[0], b[1]]) as f32,
                (DataType::U32, _) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            }
        };
        let one = |e: &[u8]| -> [f32; N] {
            std::array::from_fn(|c| if c < m { decode(&e[c * cs..]) } else { 1.0 })
        };
        self.read_elements(acc, at, cs * m, [0.0; N], one)
    }

    /// An accessor's elements, each decoded by `one` from its bytes, with
    /// its sparse substitution.
    fn read_elements<T: Copy>(
        &self,
        acc: &gltf::Accessor,
        at: &str,
        size: usize,
        zero: T,
        one: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, AssetError> {
        let count = acc.count();
        let buffer_bytes: u64 = self.buffers.iter().map(|b| b.len() as u64).sum();
        // The data checked first (it must fit its view, or, without one,
        // be no more than the buffers' bytes), then the decoding budget.
        let data = match (self.draco.get(&acc.index()), acc.view()) {
            (Some(bytes), _) => Some(Elements {
                bytes: bytes.get(..count.saturating_mul(size)).ok_or_else(|| {
                    self.err(at, format!("{count} elements from a shorter Draco stream"))
                })?,
                stride: size,
                size,
                count,
            }),
            (None, Some(view)) => Some(self.elements(&view, acc.offset(), count, size, at)?),
            (None, None) => {
                let most = MAX_ZERO_ELEMENTS.min(MIN_ZERO_ELEMENTS.max(buffer_bytes as usize));
                if count > most {
                    return Err(self.err(
                        at,
                        format!(
                            "{count} elements declared without data (at most {most}: the \
                             file's buffers have {buffer_bytes} bytes)"
                        ),
                    ));
                }
                None
            }
        };
        let bytes = (count as u64).saturating_mul(std::mem::size_of::<T>() as u64);
        self.charge(bytes, &format!("{count} elements"), at)?;
        let mut out = match data {
            Some(elements) => elements.iter().map(&one).collect(),
            None => vec![zero; count],
        };
        if let Some(sparse) = acc.sparse() {
            let n = sparse.count();
            let idx = sparse.indices();
            let isz = idx.index_type().size();
            let indices = self.elements(
                &idx.view(),
                idx.offset(),
                n,
                isz,
                &format!("{at}.sparse.indices"),
            )?;
            let values = self.elements(
                &sparse.values().view(),
                sparse.values().offset(),
                n,
                size,
                &format!("{at}.sparse.values"),
            )?;
            for (i, v) in indices.iter().zip(values.iter()) {
                let k = match isz {
                    1 => i[0] as usize,
                    2 => u16::from_le_bytes([i[0], i[1]]) as usize,
                    _ => u32::from_le_bytes([i[0], i[1], i[2], i[3]]) as usize,
                };
                let slot = out.get_mut(k).ok_or_else(|| {
                    self.err(
                        format!("{at}.sparse.indices"),
                        format!("index {k} of {count} elements"),
                    )
                })?;
                *slot = one(v);
            }
        }
        Ok(out)
    }

    fn read_indices(&self, acc: &gltf::Accessor, at: &str) -> Result<Vec<u32>, AssetError> {
        if acc.dimensions() != Dimensions::Scalar {
            return Err(self.err(at, "indices that are not scalars"));
        }
        let ty = acc.data_type();
        let one = move |b: &[u8]| -> u32 {
            match ty {
                DataType::U8 => b[0] as u32,
                DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as u32,
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            }
        };
        match ty {
            DataType::U8 | DataType::U16 | DataType::U32 => {
                self.read_elements(acc, at, ty.size(), 0, one)
            }
            t => Err(self.err(
                at,
                format!("indices of type {t:?} (u8, u16 or u32 expected)"),
            )),
        }
    }

    fn texture(
        &mut self,
        texture: gltf::Texture,
        tex_coord: u32,
        transform: Option<gltf::texture::TextureTransform>,
        space: ColourSpace,
        scale: f32,
        at: &str,
    ) -> Result<Option<TextureRef>, AssetError> {
        let image = texture.source();
        let key = (image.index(), space == ColourSpace::Srgb);
        let index = match self.textures.get(&key) {
            Some(&i) => i,
            None => {
                let iat = format!("images[{}]", image.index());
                // The gltf crate's `source` unwraps these (a panic).
                let json = &self.doc.as_json().images[image.index()];
                if json.buffer_view.is_some() && json.mime_type.is_none() {
                    return Err(self.err(&iat, "an image in a buffer view needs a mimeType"));
                }
                if json.buffer_view.is_none() && json.uri.is_none() {
                    return Err(self.err(&iat, "an image with neither a uri nor a bufferView"));
                }
                let bytes = match image.source() {
                    gltf::image::Source::View { view, .. } => {
                        self.view_bytes(&view, &iat)?.to_vec()
                    }
                    gltf::image::Source::Uri { uri, .. } => {
                        self.uri_bytes(uri, &format!("{iat}.uri"))?
                    }
                };
                let t =
                    Texture::decode(&bytes, space).map_err(|e| self.err(&iat, e.to_string()))?;
                self.asset.textures.push(t);
                let i = (self.asset.textures.len() - 1) as u32;
                self.textures.insert(key, i);
                i
            }
        };
        let s = texture.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        let filter = match s.mag_filter() {
            Some(gltf::texture::MagFilter::Nearest) => Filter::Nearest,
            _ => Filter::Linear,
        };
        let (tex_coord, transform) = match transform {
            Some(t) => (
                t.tex_coord().unwrap_or(tex_coord),
                UvTransform::new(t.offset(), t.rotation(), t.scale()),
            ),
            None => (tex_coord, UvTransform::IDENTITY),
        };
        if tex_coord > 1 {
            self.asset.warnings.push(format!(
                "{}: {at}: TEXCOORD_{tex_coord} is not read; the texture is ignored",
                self.file
            ));
            return Ok(None);
        }
        Ok(Some(TextureRef {
            texture: index,
            tex_coord,
            sampler: Sampler {
                wrap_u: wrap(s.wrap_s()),
                wrap_v: wrap(s.wrap_t()),
                filter,
            },
            transform,
            scale,
        }))
    }

    fn info(
        &mut self,
        info: Option<gltf::texture::Info>,
        space: ColourSpace,
        at: &str,
    ) -> Result<Option<TextureRef>, AssetError> {
        match info {
            Some(i) => self.texture(
                i.texture(),
                i.tex_coord(),
                i.texture_transform(),
                space,
                1.0,
                at,
            ),
            None => Ok(None),
        }
    }

    /// `KHR_materials_transmission`'s texture of material `m` (at `at`).
    fn transmission_texture(
        &mut self,
        m: &gltf::Material,
        at: &str,
    ) -> Result<Option<TextureRef>, AssetError> {
        self.info(
            m.transmission().and_then(|t| t.transmission_texture()),
            ColourSpace::Linear,
            &format!("{at}.extensions.KHR_materials_transmission.transmissionTexture"),
        )
    }

    /// `KHR_materials_specular`'s `(specularTexture, specularColorTexture)`
    /// of material `m` (at `at`): linear (A read), and sRGB (RGB read).
    fn specular_textures(
        &mut self,
        m: &gltf::Material,
        at: &str,
    ) -> Result<(Option<TextureRef>, Option<TextureRef>), AssetError> {
        let at = format!("{at}.extensions.KHR_materials_specular");
        let s = m.specular();
        let strength = self.info(
            s.as_ref().and_then(|s| s.specular_texture()),
            ColourSpace::Linear,
            &format!("{at}.specularTexture"),
        )?;
        let colour = self.info(
            s.as_ref().and_then(|s| s.specular_color_texture()),
            ColourSpace::Srgb,
            &format!("{at}.specularColorTexture"),
        )?;
        Ok((strength, colour))
    }

    /// `KHR_materials_volume`'s `(attenuationColor, attenuationDistance)`
    /// of material `m` (at `at`): a colour in `[0, 1]` and a positive
    /// distance (infinite: none), else refused.
    fn attenuation(&self, m: &gltf::Material, at: &str) -> Result<([f32; 3], f32), AssetError> {
        let Some(v) = m.volume() else {
            return Ok(([1.0; 3], f32::INFINITY));
        };
        let at = format!("{at}.extensions.KHR_materials_volume");
        let (colour, distance) = (v.attenuation_color(), v.attenuation_distance());
        if !colour.iter().all(|c| (0.0..=1.0).contains(c)) {
            return Err(self.err(
                format!("{at}.attenuationColor"),
                "each component must be in [0, 1]",
            ));
        }
        if distance.is_nan() || distance <= 0.0 {
            return Err(self.err(
                format!("{at}.attenuationDistance"),
                format!("must be a positive distance (infinite: no attenuation), not {distance}"),
            ));
        }
        Ok((colour, distance))
    }

    /// The normal texture of material `m` (at `at`), with its `scale` and
    /// `KHR_texture_transform` (linear).
    fn normal_texture(
        &mut self,
        m: &gltf::Material,
        at: &str,
    ) -> Result<Option<TextureRef>, AssetError> {
        Ok(match m.normal_texture() {
            Some(n) => {
                let transform = n.extension_value("KHR_texture_transform").and_then(|v| {
                    serde_json::from_value::<gltf::json::extensions::texture::TextureTransform>(
                        v.clone(),
                    )
                    .ok()
                });
                let tt = transform.map(|t| (t.offset.0, t.rotation.0, t.scale.0, t.tex_coord));
                let tex_coord = tt.and_then(|t| t.3).unwrap_or(n.tex_coord());
                let r = self.texture(
                    n.texture(),
                    tex_coord,
                    None,
                    ColourSpace::Linear,
                    n.scale(),
                    &format!("{at}.normalTexture"),
                )?;
                r.map(|mut r| {
                    if let Some((o, rot, s, _)) = tt {
                        r.transform = UvTransform::new(o, rot, s);
                    }
                    r
                })
            }
            None => None,
        })
    }

    fn read_materials(&mut self) -> Result<(), AssetError> {
        let finite = |x: f32| x.is_finite();
        for m in self.doc.materials() {
            let i = m.index().unwrap_or(0);
            let at = format!("materials[{i}]");
            let pbr = m.pbr_metallic_roughness();
            let base_colour_texture = self.info(
                pbr.base_color_texture(),
                ColourSpace::Srgb,
                &format!("{at}.baseColorTexture"),
            )?;
            let metallic_roughness_texture = self.info(
                pbr.metallic_roughness_texture(),
                ColourSpace::Linear,
                &format!("{at}.metallicRoughnessTexture"),
            )?;
            let emissive_texture = self.info(
                m.emissive_texture(),
                ColourSpace::Srgb,
                &format!("{at}.emissiveTexture"),
            )?;
            let normal_texture = self.normal_texture(&m, &at)?;
            let transmission_texture = self.transmission_texture(&m, &at)?;
            let (specular_texture, specular_colour_texture) = self.specular_textures(&m, &at)?;
            let (attenuation_colour, attenuation_distance) = self.attenuation(&m, &at)?;
            let strength = m.emissive_strength().unwrap_or(1.0);
            let e = m.emissive_factor();
            let alpha_mode = match m.alpha_mode() {
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5)),
                gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            };
            let material = PbrMaterial {
                name: m
                    .name()
                    .map_or_else(|| format!("material {i}"), str::to_string),
                base_colour: pbr.base_color_factor(),
                base_colour_texture,
                metallic: pbr.metallic_factor(),
                roughness: pbr.roughness_factor(),
                metallic_roughness_texture,
                normal_texture,
                emissive: e.map(|c| c * strength),
                emissive_texture,
                alpha_mode,
                double_sided: m.double_sided(),
                ior: m.ior().unwrap_or(1.5),
                specular: m.specular().map_or(1.0, |s| s.specular_factor()),
                specular_colour: m.specular().map_or([1.0; 3], |s| s.specular_color_factor()),
                specular_texture,
                specular_colour_texture,
                transmission: m.transmission().map_or(0.0, |t| t.transmission_factor()),
                transmission_texture,
                thickness: m.volume().map_or(0.0, |v| v.thickness_factor()),
                attenuation_colour,
                attenuation_distance,
            };
            let scalars = [
                material.metallic,
                material.roughness,
                material.ior,
                material.specular,
                material.transmission,
                material.thickness,
            ];
            let numbers = material
                .base_colour
                .iter()
                .chain(&material.emissive)
                .chain(&material.specular_colour)
                .chain(&scalars);
            if !numbers.copied().all(finite) {
                return Err(self.err(&at, "a factor that is not a finite number"));
            }
            self.asset.materials.push(material);
        }
        Ok(())
    }

    /// Each node's parent, refusing a node with two: the nodes form trees.
    fn parents(&self) -> Result<Vec<Option<usize>>, AssetError> {
        let mut parent = vec![None; self.doc.nodes().len()];
        for n in self.doc.nodes() {
            for c in n.children() {
                if let Some(p) = parent[c.index()] {
                    return Err(self.err(
                        format!("nodes[{}].children", n.index()),
                        format!(
                            "node {} is already a child of node {p}: nodes must form trees",
                            c.index()
                        ),
                    ));
                }
                parent[c.index()] = Some(n.index());
            }
        }
        Ok(parent)
    }

    /// A node's camera, placed by `world`: perspective read,
    /// orthographic skipped with a warning.
    fn read_camera(&mut self, cam: &gltf::Camera, world: Mat4) -> Result<(), AssetError> {
        match cam.projection() {
            gltf::camera::Projection::Perspective(p) => {
                if !(p.yfov() > 0.0 && p.yfov() < std::f32::consts::PI) {
                    return Err(self.err(
                        format!("cameras[{}].perspective.yfov", cam.index()),
                        "a field of view outside (0, π)",
                    ));
                }
                self.asset.cameras.push(AssetCamera {
                    name: cam
                        .name()
                        .map_or_else(|| format!("camera {}", cam.index()), str::to_string),
                    transform: world,
                    yfov: p.yfov(),
                    aspect_ratio: p.aspect_ratio().filter(|a| *a > 0.0 && a.is_finite()),
                });
            }
            gltf::camera::Projection::Orthographic(_) => self.asset.warnings.push(format!(
                "{}: cameras[{}]: orthographic cameras are not supported; skipped",
                self.file,
                cam.index()
            )),
        }
        Ok(())
    }

    /// A node's `KHR_lights_punctual` light, placed by `world` (at the
    /// node's origin, shining along its −Z), its photometric intensity
    /// converted to watts ([`LUMENS_PER_WATT`]): a point or spot light's
    /// candela (lm/sr) to W/sr, a directional light's lux (lm/m²) to
    /// W/m². `range` is ignored (light falls off as 1/r² everywhere).
    fn read_light(&mut self, node: &gltf::Node, world: Mat4) -> Result<(), AssetError> {
        let json = &self.doc.as_json().nodes[node.index()];
        let Some(index) = json
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .map(|l| l.light.value())
        else {
            return Ok(());
        };
        let count = self.doc.lights().map_or(0, |l| l.len());
        if index >= count {
            return Err(self.err(
                format!(
                    "nodes[{}].extensions.KHR_lights_punctual.light",
                    node.index()
                ),
                format!("light {index} of {count}"),
            ));
        }
        let Some(light) = node.light() else {
            return Ok(());
        };
        let at = format!("extensions.KHR_lights_punctual.lights[{index}]");
        let colour = Vec3::from(light.color());
        let intensity = light.intensity();
        if !(colour.is_finite() && colour.min_element() >= 0.0) {
            return Err(self.err(format!("{at}.color"), "must be finite and non-negative"));
        }
        if !(intensity.is_finite() && intensity >= 0.0) {
            return Err(self.err(format!("{at}.intensity"), "must be finite and non-negative"));
        }
        let shape = match light.kind() {
            gltf::khr_lights_punctual::Kind::Directional => LightShape::Sun {
                direction: Vec3::NEG_Z,
                angle: 0.0,
            },
            gltf::khr_lights_punctual::Kind::Point => LightShape::Point {
                position: Vec3::ZERO,
            },
            gltf::khr_lights_punctual::Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let half_pi = std::f32::consts::FRAC_PI_2;
                if !(0.0..=half_pi).contains(&outer_cone_angle) || outer_cone_angle == 0.0 {
                    return Err(self.err(
                        format!("{at}.spot.outerConeAngle"),
                        format!("{outer_cone_angle}: must lie in (0, π/2]"),
                    ));
                }
                if !(0.0..outer_cone_angle).contains(&inner_cone_angle) {
                    return Err(self.err(
                        format!("{at}.spot.innerConeAngle"),
                        format!("{inner_cone_angle}: must lie in [0, outerConeAngle)"),
                    ));
                }
                LightShape::Spot {
                    position: Vec3::ZERO,
                    direction: Vec3::NEG_Z,
                    inner: inner_cone_angle,
                    outer: outer_cone_angle,
                }
            }
        };
        let name = light
            .name()
            .map_or_else(|| format!("light {index}"), str::to_string);
        let local = PunctualLight {
            shape,
            strength: colour * (intensity / LUMENS_PER_WATT),
            name,
        };
        self.asset.lights.push(local.transformed(world));
        Ok(())
    }

    fn read_scene(&mut self) -> Result<(), AssetError> {
        let doc = self.doc;
        let parent = self.parents()?;
        let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
            Some(s) => s.nodes().collect(),
            None => doc
                .nodes()
                .filter(|n| parent[n.index()].is_none())
                .collect(),
        };
        let mut mesh_of: HashMap<(usize, usize), Option<u32>> = HashMap::new();
        self.asset.node_names = (doc.nodes())
            .map(|n| {
                let mesh = n.mesh().and_then(|m| m.name().map(str::to_string));
                (n.name().map(str::to_string).or(mesh))
                    .unwrap_or_else(|| format!("node {}", n.index()))
            })
            .collect();
        let mut visited = vec![false; doc.nodes().len()];
        let mut stack: Vec<(gltf::Node, Mat4)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, Mat4::IDENTITY))
            .collect();
        let mut skipped_modes = 0usize;
        let mut triangles = 0usize;
        while let Some((node, parent_world)) = stack.pop() {
            let at = format!("nodes[{}]", node.index());
            if std::mem::replace(&mut visited[node.index()], true) {
                return Err(self.err(
                    &at,
                    "the node hierarchy has a cycle (a node is its own ancestor)",
                ));
            }
            let local = Mat4::from_cols_array_2d(&node.transform().matrix());
            if !local.is_finite() {
                return Err(self.err(&at, "a transform that is not finite"));
            }
            let world = parent_world * local;
            if let Some(mesh) = node.mesh() {
                for prim in mesh.primitives() {
                    let key = (mesh.index(), prim.index());
                    let id = match mesh_of.get(&key) {
                        Some(&id) => id,
                        None => {
                            let id = match prim.mode() {
                                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => {
                                    let m = self.read_primitive(&mesh, &prim)?;
                                    triangles += m.triangles.len();
                                    if triangles > MAX_TRIANGLES {
                                        return Err(self.err(
                                            &at,
                                            format!("more than {MAX_TRIANGLES} triangles"),
                                        ));
                                    }
                                    self.asset.meshes.push(m);
                                    Some((self.asset.meshes.len() - 1) as u32)
                                }
                                _ => {
                                    skipped_modes += 1;
                                    None
                                }
                            };
                            mesh_of.insert(key, id);
                            id
                        }
                    };
                    if let Some(id) = id {
                        self.asset.instances.push(Instance {
                            mesh: id,
                            transform: world,
                        });
                        self.asset.instance_nodes.push(node.index() as u32);
                    }
                }
            }
            if let Some(cam) = node.camera() {
                self.read_camera(&cam, world)?;
            }
            self.read_light(&node, world)?;
            for c in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((c, world));
            }
        }
        if skipped_modes > 0 {
            self.asset.warnings.push(format!(
                "{}: {skipped_modes} mesh primitive(s) of points or lines skipped",
                self.file
            ));
        }
        Ok(())
    }

    /// Whether the file uses `KHR_mesh_quantization`: positions and
    /// texture coordinates may be integers that are not normalised.
    fn quantization(&self) -> bool {
        self.doc
            .extensions_used()
            .any(|e| e == "KHR_mesh_quantization")
    }

    /// A primitive's attributes other than `POSITION` (at `at`) into
    /// `out`, each as long as its positions.
    fn read_attributes(
        &self,
        prim: &gltf::Primitive,
        at: &str,
        out: &mut AssetMesh,
    ) -> Result<(), AssetError> {
        let attr = |name: &str| format!("{at}.attributes.{name}");
        let quantization = self.quantization();
        let n = out.positions.len();
        let same_len = |len: usize, name: &str| -> Result<(), AssetError> {
            if len == n {
                Ok(())
            } else {
                Err(self.err(attr(name), format!("{len} values for {n} positions")))
            }
        };
        if let Some(a) = prim.get(&gltf::Semantic::Normals) {
            let v = self.read_floats::<3>(&a, &attr("NORMAL"), &[Dimensions::Vec3], false)?;
            same_len(v.len(), "NORMAL")?;
            out.normals = v
                .into_iter()
                .map(|v| Vec3::from(v).try_normalize().unwrap_or(Vec3::ZERO))
                .collect();
        }
        for (set, name) in [(0u32, "TEXCOORD_0"), (1, "TEXCOORD_1")] {
            if let Some(a) = prim.get(&gltf::Semantic::TexCoords(set)) {
                let v =
                    self.read_floats::<2>(&a, &attr(name), &[Dimensions::Vec2], quantization)?;
                same_len(v.len(), name)?;
                let v = v
                    .into_iter()
                    .map(|t| t.map(|c| if c.is_finite() { c } else { 0.0 }))
                    .collect();
                if set == 0 { out.uv0 = v } else { out.uv1 = v }
            }
        }
        if let Some(a) = prim.get(&gltf::Semantic::Tangents) {
            let v = self.read_floats::<4>(&a, &attr("TANGENT"), &[Dimensions::Vec4], false)?;
            same_len(v.len(), "TANGENT")?;
            out.tangents = v;
        }
        if let Some(a) = prim.get(&gltf::Semantic::Colors(0)) {
            let v = self.read_floats::<4>(
                &a,
                &attr("COLOR_0"),
                &[Dimensions::Vec3, Dimensions::Vec4],
                false,
            )?;
            same_len(v.len(), "COLOR_0")?;
            out.colours = v;
        }
        Ok(())
    }

    fn read_primitive(
        &mut self,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
    ) -> Result<AssetMesh, AssetError> {
        let at = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
        self.draco = self.decode_draco(prim, &at)?;
        let out = self.read_primitive_data(mesh, prim, &at);
        self.draco.clear();
        out
    }

    /// A `KHR_draco_mesh_compression` primitive's stream decoded into the
    /// bytes of each accessor it fills, by accessor index (none for a
    /// primitive without the extension). The accessors' counts bound the
    /// decode and are charged to the decoding budget before it; the decoded
    /// counts, components and component types must then be theirs.
    fn decode_draco(
        &self,
        prim: &gltf::Primitive,
        prim_at: &str,
    ) -> Result<HashMap<usize, Vec<u8>>, AssetError> {
        let Some(value) = prim.extension_value("KHR_draco_mesh_compression") else {
            return Ok(HashMap::new());
        };
        let at = format!("{prim_at}.extensions.KHR_draco_mesh_compression");
        let c = draco::Compressed::parse(value).map_err(|e| self.err(&at, e))?;
        let (indices, attrs) = self.draco_accessors(prim, prim_at, &at, &c)?;
        let ix_at = format!("{prim_at}.indices");
        let ity = indices.data_type();
        let points = attrs.iter().map(|a| a.2.count() as u64).max().unwrap_or(0);
        let attribute_bytes = (attrs.iter())
            .map(|a| (a.2.count() as u64).saturating_mul(a.2.size() as u64))
            .fold(0, u64::saturating_add);
        let triangles = indices.count() as u64 / 3;
        let index_bytes = (indices.count() as u64).saturating_mul(ity.size() as u64);
        self.charge(
            attribute_bytes.saturating_add(index_bytes),
            &format!("a Draco stream of {points} points and {triangles} triangles"),
            &at,
        )?;
        let view = (self.doc.views().nth(c.buffer_view)).ok_or_else(|| {
            self.err(
                format!("{at}.bufferView"),
                format!(
                    "buffer view {} of {}",
                    c.buffer_view,
                    self.doc.views().len()
                ),
            )
        })?;
        let stream = self.view_bytes(&view, &format!("{at}.bufferView"))?;
        let bounds = draco::Bounds {
            points,
            triangles,
            attribute_bytes,
        };
        let mesh = draco::decode(stream, bounds).map_err(|e| self.err(&at, e))?;
        if mesh.num_faces().saturating_mul(3) != indices.count() {
            return Err(self.err(
                &ix_at,
                format!(
                    "the accessor declares {} indices, the Draco stream decodes {} triangles",
                    indices.count(),
                    mesh.num_faces()
                ),
            ));
        }
        let mut out = HashMap::new();
        let ix = draco::index_bytes(&mesh, ity).map_err(|e| self.err(&ix_at, e))?;
        out.insert(indices.index(), ix);
        for (at, id, acc) in attrs {
            if acc.count() != mesh.num_points() {
                return Err(self.err(
                    &at,
                    format!(
                        "accessors[{}] declares {} elements, the Draco stream decodes {} points",
                        acc.index(),
                        acc.count(),
                        mesh.num_points()
                    ),
                ));
            }
            let m = acc.dimensions().multiplicity();
            let bytes =
                draco::attribute_bytes(&mesh, id, m, acc.data_type()).map_err(|(field, e)| {
                    match field {
                        "" => self.err(&at, e),
                        f => self.err(&at, format!("accessors[{}].{f}: {e}", acc.index())),
                    }
                })?;
            out.insert(acc.index(), bytes);
        }
        Ok(out)
    }

    /// A Draco primitive's checks before its stream is decoded (its mode,
    /// its indices' type, its extension's attributes among its own): its
    /// indices' accessor and, for each attribute the stream holds, its
    /// JSON path, Draco unique id and accessor.
    #[allow(clippy::type_complexity)]
    fn draco_accessors<'d>(
        &self,
        prim: &gltf::Primitive<'d>,
        prim_at: &str,
        at: &str,
        c: &draco::Compressed,
    ) -> Result<(gltf::Accessor<'d>, Vec<(String, u32, gltf::Accessor<'d>)>), AssetError> {
        if !matches!(prim.mode(), Mode::Triangles | Mode::TriangleStrip) {
            return Err(self.err(
                format!("{prim_at}.mode"),
                format!(
                    "{:?}: a Draco primitive is TRIANGLES or TRIANGLE_STRIP",
                    prim.mode()
                ),
            ));
        }
        let ix_at = format!("{prim_at}.indices");
        let indices = prim.indices().ok_or_else(|| {
            self.err(
                &ix_at,
                "none: a Draco primitive's indices say how many triangles its stream holds",
            )
        })?;
        let ity = indices.data_type();
        if indices.dimensions() != Dimensions::Scalar
            || !matches!(ity, DataType::U8 | DataType::U16 | DataType::U32)
        {
            return Err(self.err(
                &ix_at,
                format!(
                    "{:?} of {ity:?} (indices are scalars of u8, u16 or u32)",
                    indices.dimensions()
                ),
            ));
        }
        let mut attrs = Vec::new();
        for (name, &id) in &c.attributes {
            let acc = (prim.attributes())
                .find(|(s, _)| s.to_string() == *name)
                .map(|(_, a)| a)
                .ok_or_else(|| {
                    self.err(
                        format!("{at}.attributes.{name}"),
                        "not among the primitive's attributes",
                    )
                })?;
            attrs.push((format!("{at}.attributes.{name}"), id, acc));
        }
        Ok((indices, attrs))
    }

    /// A primitive's meshes and attributes (decoded from its Draco stream
    /// where it has one: [`Reader::decode_draco`] has filled `draco`).
    fn read_primitive_data(
        &mut self,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
        at: &str,
    ) -> Result<AssetMesh, AssetError> {
        let attr = |name: &str| format!("{at}.attributes.{name}");
        let pos_acc = prim
            .get(&gltf::Semantic::Positions)
            .ok_or_else(|| self.err(at, "a primitive without POSITION"))?;
        let positions: Vec<Vec3> = self
            .read_floats::<3>(
                &pos_acc,
                &attr("POSITION"),
                &[Dimensions::Vec3],
                self.quantization(),
            )?
            .into_iter()
            .map(Vec3::from)
            .collect();
        if let Some(k) = positions.iter().position(|p| !p.is_finite()) {
            return Err(self.err(
                attr("POSITION"),
                format!("position {k} is not finite: {}", positions[k]),
            ));
        }
        let n = positions.len();
        let mut out = AssetMesh {
            name: format!(
                "{} mesh {} primitive {}",
                self.file,
                mesh.index(),
                prim.index()
            ),
            positions,
            material: prim.material().index().map(|i| i as u32),
            ..AssetMesh::default()
        };
        self.read_attributes(prim, at, &mut out)?;
        let indices = match prim.indices() {
            Some(a) => {
                let v = self.read_indices(&a, &format!("{at}.indices"))?;
                if let Some(&k) = v.iter().find(|&&k| k as usize >= n) {
                    return Err(self.err(
                        format!("{at}.indices"),
                        format!("index {k} of {n} vertices"),
                    ));
                }
                v
            }
            None => (0..n as u32).collect(),
        };
        out.triangles = assemble(&indices, prim.mode());
        let needs_tangents = out
            .material
            .and_then(|m| self.asset.materials.get(m as usize))
            .is_some_and(|m| m.normal_texture.is_some());
        if needs_tangents && out.tangents.is_empty() {
            if out.normals.is_empty() || out.uv0.is_empty() {
                self.asset.warnings.push(format!(
                    "{}: {at}: a normal texture on a mesh without normals or TEXCOORD_0; it is ignored",
                    self.file
                ));
            } else {
                out.tangents = generate_tangents(&out);
            }
        }
        Ok(out)
    }
}

/// `count` elements of `size` bytes, `stride` apart, from the start of
/// `bytes` (which holds them all: checked when it was made).
struct Elements<'s> {
    bytes: &'s [u8],
    stride: usize,
    size: usize,
    count: usize,
}

impl<'s> Elements<'s> {
    fn iter(&self) -> impl Iterator<Item = &'s [u8]> + use<'s> {
        let (bytes, stride, size) = (self.bytes, self.stride, self.size);
        (0..self.count).map(move |k| &bytes[k * stride..k * stride + size])
    }
}

/// Triangles from the indices of a primitive of `mode` (as the glTF
/// specification's section 3.7.2.1 lists them), degenerate ones (two equal
/// indices) dropped.
pub fn assemble(ix: &[u32], mode: Mode) -> Vec<[u32; 3]> {
    let tris: Vec<[u32; 3]> = match mode {
        Mode::Triangles => ix.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        Mode::TriangleStrip => (0..ix.len().saturating_sub(2))
            .map(|i| {
                let k = i % 2;
                [ix[i], ix[i + 1 + k], ix[i + 2 - k]]
            })
            .collect(),
        Mode::TriangleFan => (0..ix.len().saturating_sub(2))
            .map(|i| [ix[i + 1], ix[i + 2], ix[0]])
            .collect(),
        _ => Vec::new(),
    };
    tris.into_iter()
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect()
}

/// MikkTSpace tangents of a mesh with normals and `TEXCOORD_0` (the glTF
/// specification's choice), averaged per vertex over the triangles that
/// share it; vertices MikkTSpace leaves without one get `(1, 0, 0, 1)`.
/// The bitangent `w · (normal × tangent)` points towards decreasing `v`,
/// the image's up, as glTF's normal textures (+Y up) read it.
fn generate_tangents(mesh: &AssetMesh) -> Vec<[f32; 4]> {
    struct Geometry<'m> {
        mesh: &'m AssetMesh,
        out: Vec<[f32; 4]>,
    }
    impl bevy_mikktspace::Geometry for Geometry<'_> {
        fn num_faces(&self) -> usize {
            self.mesh.triangles.len()
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.mesh.positions[self.mesh.triangles[face][vert] as usize].to_array()
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            self.mesh.normals[self.mesh.triangles[face][vert] as usize].to_array()
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            // v flipped: MikkTSpace's bitangent follows increasing v, and
            // glTF's normal textures have +Y up, towards decreasing v
            // (as exporters, which run MikkTSpace on v-up coordinates,
            // write their tangents).
            let [u, v] = self.mesh.uv0[self.mesh.triangles[face][vert] as usize];
            [u, 1.0 - v]
        }
        fn set_tangent(
            &mut self,
            t: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            if let Some(t) = t {
                let v = self.mesh.triangles[face][vert] as usize;
                let tan = t.tangent();
                let w = if t.is_orientation_preserving() {
                    1.0
                } else {
                    -1.0
                };
                let o = &mut self.out[v];
                o[0] += tan[0];
                o[1] += tan[1];
                o[2] += tan[2];
                o[3] = w;
            }
        }
    }
    let mut g = Geometry {
        mesh,
        out: vec![[0.0; 4]; mesh.positions.len()],
    };
    if bevy_mikktspace::generate_tangents(&mut g).is_err() {
        return Vec::new();
    }
    g.out
        .into_iter()
        .map(|t| match Vec3::new(t[0], t[1], t[2]).try_normalize() {
            Some(v) => [v.x, v.y, v.z, if t[3] < 0.0 { -1.0 } else { 1.0 }],
            None => [1.0, 0.0, 0.0, 1.0],
        })
        .collect()
}

/// `%XX` escapes decoded (glTF URIs are URI-encoded relative paths).
fn percent_decode(s: &str) -> String {
    let hex = |c: u8| (c as char).to_digit(16);
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%'
            && i + 2 < b.len()
            && let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2]))
        {
            out.push((h * 16 + l) as u8);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}
