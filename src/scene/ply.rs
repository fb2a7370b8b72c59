//! PLY (ASCII, binary little- and big-endian) to an [`Asset`], through the
//! `ply-rs-bw` crate (which caps what it allocates ahead of the data it
//! reads).
//!
//! Read: the `vertex` element's `x, y, z` (finite), normals `nx, ny, nz`,
//! texture coordinates under their usual names (`u, v`, `s, t`,
//! `texture_u, texture_v`, `texture_s, texture_t`), colours (`red, green,
//! blue, alpha` or `r, g, b, a`, or `diffuse_red`…; 8-bit values are
//! divided by 255, floats taken as they are, as linear RGB); the `face`
//! element's `vertex_indices` (or `vertex_index`), polygons of any number
//! of sides triangulated as fans. Other elements and properties are read
//! past and ignored.
//!
//! **Declared counts are checked before anything is read.** Every
//! element's count times its smallest record (binary: the sizes of its
//! scalars plus its lists' length fields, at least one byte; ASCII: two
//! bytes a value, a digit and a separator, at least one byte a line) must
//! fit in the bytes after the header ([`check_counts`]): a 200-byte file
//! declaring 10⁹ vertices is refused at once, where it had made the
//! reader fill 24 GB with empty records.

use super::asset::{Asset, AssetError, AssetMesh, Instance, PbrMaterial};
use glam::{Mat4, Vec3};
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    DefaultElement, Encoding, Header, Property, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};
use std::io::BufRead;
use std::path::Path;

/// The material of a PLY file's mesh (PLY has none): a matte grey
/// dielectric (base colour 0.8, metallic 0, roughness 1), which vertex
/// colours multiply.
pub fn ply_material() -> PbrMaterial {
    PbrMaterial {
        base_colour: [0.8, 0.8, 0.8, 1.0],
        metallic: 0.0,
        ..PbrMaterial::DEFAULT
    }
}

/// A vertex's properties, as read.
#[derive(Default)]
struct Vertex {
    p: [f64; 3],
    n: [f64; 3],
    uv: [f64; 2],
    c: [f64; 4],
    /// Which groups were set: 1 normal, 2 uv, 4 colour, 8 alpha.
    has: u8,
}

/// A scalar property's value; 8-bit and 16-bit unsigned colour values
/// are scaled to `[0, 1]` when `colour`.
fn scalar(p: &Property, colour: bool) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64 / if colour { 255.0 } else { 1.0 },
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64 / if colour { 65_535.0 } else { 1.0 },
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Self::default()
    }
    fn set_property(&mut self, name: &str, p: Property) -> PropertyAccessResult {
        let colour = matches!(
            name,
            "red"
                | "green"
                | "blue"
                | "alpha"
                | "r"
                | "g"
                | "b"
                | "a"
                | "diffuse_red"
                | "diffuse_green"
                | "diffuse_blue"
        );
        let Some(v) = scalar(&p, colour) else {
            return PropertyAccessResult::Ignored;
        };
        match name {
            "x" => self.p[0] = v,
            "y" => self.p[1] = v,
            "z" => self.p[2] = v,
            "nx" => (self.n[0], self.has) = (v, self.has | 1),
            "ny" => (self.n[1], self.has) = (v, self.has | 1),
            "nz" => (self.n[2], self.has) = (v, self.has | 1),
            "u" | "s" | "texture_u" | "texture_s" => (self.uv[0], self.has) = (v, self.has | 2),
            "v" | "t" | "texture_v" | "texture_t" => (self.uv[1], self.has) = (v, self.has | 2),
            "red" | "r" | "diffuse_red" => (self.c[0], self.has) = (v, self.has | 4),
            "green" | "g" | "diffuse_green" => (self.c[1], self.has) = (v, self.has | 4),
            "blue" | "b" | "diffuse_blue" => (self.c[2], self.has) = (v, self.has | 4),
            "alpha" | "a" => (self.c[3], self.has) = (v, self.has | 8),
            _ => return PropertyAccessResult::Ignored,
        }
        PropertyAccessResult::Set
    }
}

/// A face's vertex indices (negative ones kept as such, to be refused).
#[derive(Default)]
struct Face {
    indices: Vec<i64>,
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Self::default()
    }
    fn set_property(&mut self, name: &str, p: Property) -> PropertyAccessResult {
        if name != "vertex_indices" && name != "vertex_index" {
            return PropertyAccessResult::Ignored;
        }
        self.indices = match p {
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            _ => return PropertyAccessResult::UnsupportedType,
        };
        PropertyAccessResult::Set
    }
}

/// Reads the PLY file at `path`.
pub fn load(path: &Path) -> Result<Asset, AssetError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path)
        .map_err(|e| AssetError::new(&file, "", format!("cannot read the file: {e}")))?;
    read_bytes(&bytes, &file)
}

/// The bytes of a scalar in a binary file.
fn scalar_size(t: &ScalarType) -> u128 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// Refuses a header whose elements cannot fit in the `left` bytes that
/// follow it: each element's count times its smallest record (binary: its
/// scalars' sizes plus its lists' length fields, lists being empty, and
/// at least one byte; ASCII: two bytes a value, one a line), summed in
/// order, in 128-bit arithmetic. Checked before any record is read, so
/// that a forged count costs nothing.
pub fn check_counts(header: &Header, left: usize, file: &str) -> Result<(), AssetError> {
    let mut need: u128 = 0;
    for element in header.elements.values() {
        let record: u128 = match header.encoding {
            Encoding::Ascii => (2 * element.properties.len() as u128).max(1),
            Encoding::BinaryBigEndian | Encoding::BinaryLittleEndian => element
                .properties
                .values()
                .map(|p| match &p.data_type {
                    PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_size(t),
                })
                .sum::<u128>()
                .max(1),
        };
        need += element.count as u128 * record;
        // An ASCII file's last line may end without a line break.
        let slack = u128::from(header.encoding == Encoding::Ascii);
        if need > left as u128 + slack {
            return Err(AssetError::new(
                file,
                format!("element {}", element.name),
                format!(
                    "{} {} elements declared, but the {left} bytes after the header \
                     cannot hold them (each takes at least {record} bytes)",
                    element.count, element.name
                ),
            ));
        }
    }
    Ok(())
}

/// The mesh of `vertices` (no triangles yet): positions (finite), and
/// normals, texture coordinates and colours where every vertex has them.
fn vertex_attributes(vertices: &[Vertex], file: &str) -> Result<AssetMesh, AssetError> {
    let err = |at: String, m: String| AssetError::new(file, at, m);
    let all = |bit: u8| !vertices.is_empty() && vertices.iter().all(|v: &Vertex| v.has & bit != 0);
    let mut mesh = AssetMesh {
        name: file.to_string(),
        ..AssetMesh::default()
    };
    for (k, v) in vertices.iter().enumerate() {
        let p = Vec3::new(v.p[0] as f32, v.p[1] as f32, v.p[2] as f32);
        if !p.is_finite() {
            return Err(err(
                "element vertex".into(),
                format!("vertex {k} is not finite: {p}"),
            ));
        }
        mesh.positions.push(p);
    }
    if all(1) {
        mesh.normals = vertices
            .iter()
            .map(|v| {
                Vec3::new(v.n[0] as f32, v.n[1] as f32, v.n[2] as f32)
                    .try_normalize()
                    .unwrap_or(Vec3::ZERO)
            })
            .collect();
    }
    if all(2) {
        // PLY's v runs up the image (OpenGL's convention); glTF's runs down.
        mesh.uv0 = vertices
            .iter()
            .map(|v| [v.uv[0] as f32, 1.0 - v.uv[1] as f32])
            .map(|t| t.map(|c| if c.is_finite() { c } else { 0.0 }))
            .collect();
    }
    if all(4) {
        let alpha = all(8);
        mesh.colours = vertices
            .iter()
            .map(|v| {
                let a = if alpha { v.c[3] } else { 1.0 };
                [v.c[0], v.c[1], v.c[2], a].map(|c| (c as f32).clamp(0.0, 1.0))
            })
            .collect();
    }
    Ok(mesh)
}

/// Reads a PLY file from `source` (read whole first); `file` names it in
/// errors.
pub fn read(mut source: impl BufRead, file: &str) -> Result<Asset, AssetError> {
    let mut bytes = Vec::new();
    source
        .read_to_end(&mut bytes)
        .map_err(|e| AssetError::new(file, "", format!("cannot read the file: {e}")))?;
    read_bytes(&bytes, file)
}

/// Reads a PLY file's bytes; `file` names it in errors.
pub fn read_bytes(bytes: &[u8], file: &str) -> Result<Asset, AssetError> {
    let err = |at: String, m: String| AssetError::new(file, at, m);
    let ply_err = |e: ply_rs_bw::parser::ParseError| {
        let at = e.line().map_or_else(String::new, |l| format!("line {l}"));
        AssetError::new(file, at, format!("not a readable PLY file: {e}"))
    };
    let mut reader = Reader::new(std::io::Cursor::new(bytes));
    let vertex_parser = Parser::<Vertex>::new();
    let face_parser = Parser::<Face>::new();
    let other_parser = Parser::<DefaultElement>::new();
    let header = vertex_parser.read_header(&mut reader).map_err(ply_err)?;
    let at = reader.get_ref().position() as usize;
    check_counts(&header, bytes.len().saturating_sub(at), file)?;
    let (mut vertices, mut faces) = (Vec::new(), Vec::new());
    for element in header.elements.values() {
        match element.name.as_str() {
            "vertex" => {
                vertices = vertex_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(ply_err)?
            }
            "face" => {
                faces = face_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(ply_err)?
            }
            _ => {
                other_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(ply_err)?;
            }
        }
    }
    let n = vertices.len();
    let mut mesh = vertex_attributes(&vertices, file)?;
    for (k, f) in faces.iter().enumerate() {
        if let Some(&i) = f.indices.iter().find(|&&i| i < 0 || i as usize >= n) {
            return Err(err(
                "element face".into(),
                format!("face {k} refers to vertex {i} of {n}"),
            ));
        }
        for j in 1..f.indices.len().saturating_sub(1) {
            let t = [f.indices[0], f.indices[j], f.indices[j + 1]].map(|i| i as u32);
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                mesh.triangles.push(t);
            }
        }
    }
    let mut asset = Asset {
        default_material: ply_material(),
        ..Asset::default()
    };
    if mesh.triangles.is_empty() {
        asset
            .warnings
            .push(format!("{file}: no faces: a point cloud is not rendered"));
    }
    asset.meshes.push(mesh);
    asset.instances.push(Instance {
        mesh: 0,
        transform: Mat4::IDENTITY,
    });
    Ok(asset)
}
