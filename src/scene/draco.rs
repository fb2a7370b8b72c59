//! `KHR_draco_mesh_compression`: a glTF mesh primitive whose indices and
//! attributes are stored as one Draco stream, decoded at load.
//!
//! The extension's object on a primitive names the buffer view holding the
//! stream and, for each glTF attribute it holds, the Draco attribute's
//! unique id. The primitive's accessors keep their `count`, `type` and
//! `componentType` (the specification: they "must match the decompressed
//! data") but have no data of their own: the reader fills them from the
//! decoded mesh — the indices from its triangles, each attribute from its
//! values in point order — as the bytes the accessor would have read, so
//! that the accessors' types, normalisation and `KHR_mesh_quantization`
//! are read as everywhere else.
//!
//! The stream is decoded by the `draco-core` crate (pure Rust, no `unsafe`;
//! its decoder refuses malformed streams with an error and bounds what a
//! header's counts may make it reserve). The decode runs under
//! [`DecodeLimits`] taken from the accessors — no more points than the
//! attributes' accessors declare, no more triangles than the indices', no
//! more attribute bytes than twice what those accessors hold plus a
//! mebibyte — so a stream cannot decode more than the file's accessors
//! declare, which the reader has charged to its decoding budget before the
//! decode.

use draco_core::{DataType as DracoType, DecodeLimits, DecoderBuffer, Mesh, MeshDecoder};
use gltf::accessor::DataType;
use serde::Deserialize;
use std::collections::BTreeMap;

/// A primitive's `KHR_draco_mesh_compression` object, as the file has it.
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Compressed {
    /// The buffer view holding the Draco stream.
    pub buffer_view: usize,
    /// Each glTF attribute semantic's Draco unique id.
    pub attributes: BTreeMap<String, u32>,
    /// Ignored, as everywhere in glTF.
    #[serde(default)]
    pub extensions: Option<serde_json::Value>,
    /// Ignored, as everywhere in glTF.
    #[serde(default)]
    pub extras: Option<serde_json::Value>,
}

impl Compressed {
    /// Reads the extension's JSON object; the error names the field.
    pub fn parse(value: &serde_json::Value) -> Result<Compressed, String> {
        Compressed::deserialize(value).map_err(|e| e.to_string())
    }
}

/// The most a stream may decode: points, triangles and attribute bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bounds {
    /// Points (every attribute's accessor declares this many elements).
    pub points: u64,
    /// Triangles (the indices' accessor declares three times as many).
    pub triangles: u64,
    /// The bytes of the attributes' accessors.
    pub attribute_bytes: u64,
}

/// Decodes a Draco mesh stream, refusing one that would decode more than
/// `bounds` before it allocates for it.
pub fn decode(stream: &[u8], bounds: Bounds) -> Result<Mesh, String> {
    let limits = DecodeLimits::default()
        .with_max_points(bounds.points)
        .with_max_faces(bounds.triangles)
        .with_max_decoded_bytes(bounds.attribute_bytes.saturating_mul(2) + (1 << 20));
    let mut buffer = DecoderBuffer::new(stream).with_limits(limits);
    let mut mesh = Mesh::new();
    MeshDecoder::new()
        .decode(&mut buffer, &mut mesh)
        .map_err(|e| format!("the Draco stream does not decode: {e}"))?;
    Ok(mesh)
}

/// The Draco component type of a glTF one.
fn draco_type(t: DataType) -> DracoType {
    match t {
        DataType::I8 => DracoType::Int8,
        DataType::U8 => DracoType::Uint8,
        DataType::I16 => DracoType::Int16,
        DataType::U16 => DracoType::Uint16,
        DataType::U32 => DracoType::Uint32,
        DataType::F32 => DracoType::Float32,
    }
}

/// Draco attribute `id`'s values in point order, as the bytes of a glTF
/// accessor of `components` components of type `ty`, tightly packed.
/// Refused: an id the stream does not have, another number of components
/// or another component type (the error names which).
pub fn attribute_bytes(
    mesh: &Mesh,
    id: u32,
    components: usize,
    ty: DataType,
) -> Result<Vec<u8>, (&'static str, String)> {
    let attr = mesh.attribute_by_unique_id(id).ok_or_else(|| {
        (
            "",
            format!(
                "Draco attribute {id} is not in the stream (it has {})",
                mesh.num_attributes()
            ),
        )
    })?;
    if attr.num_components() as usize != components {
        return Err((
            "type",
            format!(
                "the accessor has {components} components, Draco attribute {id} decodes {}",
                attr.num_components()
            ),
        ));
    }
    if attr.data_type() != draco_type(ty) {
        return Err((
            "componentType",
            format!(
                "the accessor's components are {ty:?}, Draco attribute {id} decodes {:?}",
                attr.data_type()
            ),
        ));
    }
    let size = components * ty.size();
    let stride = usize::try_from(attr.byte_stride()).unwrap_or(0);
    let data = attr.buffer().data();
    let points = mesh.num_points();
    let mut out = Vec::with_capacity(points.saturating_mul(size));
    for p in 0..points {
        let v = attr.mapped_index(draco_core::PointIndex(p as u32)).0 as usize;
        let value = (v < attr.size())
            .then(|| v.checked_mul(stride))
            .flatten()
            .and_then(|start| data.get(start..start.checked_add(size)?))
            .ok_or_else(|| {
                (
                    "",
                    format!("Draco attribute {id}: point {p} has no value (value {v})"),
                )
            })?;
        out.extend_from_slice(value);
    }
    Ok(out)
}

/// The decoded triangles' point indices, three a triangle, as the bytes of
/// a glTF index accessor of type `ty` (`U8`, `U16` or `U32`). Refused: an
/// index the type cannot hold.
pub fn index_bytes(mesh: &Mesh, ty: DataType) -> Result<Vec<u8>, String> {
    let size = ty.size();
    let mut out = Vec::with_capacity(mesh.num_faces().saturating_mul(3 * size));
    for &k in mesh.faces().iter().flatten() {
        let k = k.0;
        match ty {
            DataType::U8 if k <= u8::MAX as u32 => out.push(k as u8),
            DataType::U16 if k <= u16::MAX as u32 => {
                out.extend_from_slice(&(k as u16).to_le_bytes());
            }
            DataType::U32 => out.extend_from_slice(&k.to_le_bytes()),
            _ => return Err(format!("the Draco stream's index {k} does not fit {ty:?}")),
        }
    }
    Ok(out)
}
