//! Wavefront OBJ meshes (and their MTL materials) for `[[mesh]]` entries.
//!
//! Loading is done by `tobj`. Before it runs, a quick pass over the file
//! checks what `tobj` does not, or does without saying where: every vertex
//! coordinate is a finite number, and every face index names a vertex
//! defined above it. So a bad file gets an error with its own line number,
//! never a panic and never a silently broken mesh.
//!
//! Files need not be UTF-8: exporters write names and comments in Latin-1
//! and other encodings, so bytes that are not UTF-8 are decoded lossily
//! (each becomes U+FFFD); numbers and keywords are ASCII either way, and a
//! `usemtl` name and its `newmtl` decode the same.

use glam::Vec3;
use std::cell::RefCell;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

/// What is wrong with a mesh file, and where: `file:line` (line 0 when the
/// problem has no line).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}:{line}: {message}", file.display())]
pub struct ObjError {
    /// The OBJ or MTL file.
    pub file: PathBuf,
    /// 1-based line in that file; 0 when unknown.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// A material of an MTL file.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjMaterial {
    /// Its `newmtl` name.
    pub name: String,
    /// `Kd` (black if absent).
    pub diffuse: Vec3,
    /// `Ke` (black if absent; white where only `map_Ke` is given).
    pub emission: Vec3,
    /// `map_Kd`: the image that multiplies `Kd`, and the MTL line naming
    /// it (its path relative to the MTL file's directory).
    pub diffuse_map: Option<MapFile>,
    /// `map_Ke`: the image that multiplies `Ke`.
    pub emissive_map: Option<MapFile>,
}

/// An image an MTL file names (`map_Kd`, `map_Ke`): its path (relative
/// names resolved against the MTL file's directory; the last word of the
/// line, after any options), and where it is named.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFile {
    /// The image file.
    pub path: PathBuf,
    /// The MTL file.
    pub mtl: PathBuf,
    /// The line of the MTL file that names it.
    pub line: usize,
}

/// An OBJ file's polygons, fan-triangulated, in file order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ObjMesh {
    /// Triangles: three positions each, in the file's winding.
    pub triangles: Vec<[Vec3; 3]>,
    /// Per triangle: its corners' unit vertex normals (`vn`, in the order
    /// of its positions), or `None` for a face that gives none (flat).
    pub normals: Vec<Option<[Vec3; 3]>>,
    /// Per triangle: index into `materials`, or `None` (no `usemtl`, or
    /// one that names no material of the MTL files).
    pub material: Vec<Option<usize>>,
    /// Per triangle: its corners' texture coordinates (`vt`, `v` flipped
    /// to the (0, 0)-at-the-top-left convention of
    /// [`texture`](super::texture)), or `None` (a face without, or an
    /// object where some faces have none).
    pub uv: Vec<Option<[[f32; 2]; 3]>>,
    /// The materials of the file's `mtllib`s (empty unless asked for).
    pub materials: Vec<ObjMaterial>,
    /// The files read: the OBJ, then its MTL files (when asked for).
    pub sources: Vec<std::path::PathBuf>,
}

/// Load `path`; with `with_mtl`, also its `mtllib` materials (paths
/// relative to the OBJ's directory).
pub fn load(path: &Path, with_mtl: bool) -> Result<ObjMesh, ObjError> {
    let err = |line: usize, message: String| ObjError {
        file: path.to_path_buf(),
        line,
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| err(0, format!("cannot read the mesh: {e}")))?;
    // Lossy decoding keeps every newline, so line numbers stay the file's.
    let mut bytes = String::from_utf8_lossy(&bytes).into_owned().into_bytes();
    blank_lines_and_points(&mut bytes);
    let faces = precheck_obj(&bytes).map_err(|(line, m)| err(line, m))?;

    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mtl_error: RefCell<Option<ObjError>> = RefCell::new(None);
    let sources = RefCell::new(vec![path.to_path_buf()]);
    let maps: RefCell<Vec<(String, &'static str, MapFile)>> = RefCell::new(Vec::new());
    let loader = |mtl: &Path| -> tobj::MTLLoadResult {
        if !with_mtl {
            return Ok((Vec::new(), Default::default()));
        }
        let mtl_path = dir.join(mtl);
        sources.borrow_mut().push(mtl_path.clone());
        let result = load_mtl(&mtl_path);
        match result {
            Ok((r, found)) => {
                maps.borrow_mut().extend(found);
                r
            }
            Err(e) => {
                mtl_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    let options = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = Lines::new(&bytes);
    let loaded = tobj::load_obj_buf(&mut reader, &options, loader);
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let (models, materials) =
        loaded.map_err(|e| err(reader.line(), format!("malformed OBJ: {e}")))?;
    let materials = if with_mtl {
        materials
            .map_err(|e| err(0, format!("cannot load its materials: {e}")))?
            .into_iter()
            .map(|m| {
                let map = |key: &str| {
                    (maps.borrow().iter().rev())
                        .find(|(name, k, _)| *name == m.name && *k == key)
                        .map(|(_, _, f)| f.clone())
                };
                let emissive_map = map("map_Ke");
                let white = if emissive_map.is_some() {
                    [1.0; 3]
                } else {
                    [0.0; 3]
                };
                ObjMaterial {
                    diffuse: Vec3::from_array(m.diffuse.unwrap_or([0.0; 3])),
                    emission: Vec3::from_array(m.emissive.unwrap_or(white)),
                    diffuse_map: map("map_Kd"),
                    emissive_map,
                    name: m.name,
                }
            })
            .collect()
    } else {
        Vec::new()
    };

    let mut mesh = ObjMesh {
        materials,
        sources: sources.into_inner(),
        ..Default::default()
    };
    let mut file_faces = faces.iter();
    for model in &models {
        add_faces(&mut mesh, model, &mut file_faces, path)?;
    }
    if mesh.triangles.is_empty() {
        return Err(err(
            0,
            "the mesh has no face of three corners or more (`f` lines): nothing to render \
             (an OBJ file is text in UTF-8 or ASCII; UTF-16 or binary files read as no faces)"
                .into(),
        ));
    }
    Ok(mesh)
}

/// Adds the faces of `model`, fan-triangulated, to `mesh`, with their
/// vertex normals from `file_faces` (the precheck's faces of three
/// corners or more, in file order: tobj keeps those, in the same order; its
/// own vertex normals are not used: it makes some up for faces that have
/// none).
fn add_faces(
    mesh: &mut ObjMesh,
    model: &tobj::Model,
    file_faces: &mut std::slice::Iter<Vec<Vec3>>,
    path: &Path,
) -> Result<(), ObjError> {
    let err = |line: usize, message: String| ObjError {
        file: path.to_path_buf(),
        line,
        message,
    };
    let m = &model.mesh;
    let pos = |i: u32| -> Option<Vec3> {
        let i = i as usize * 3;
        Some(Vec3::new(
            *m.positions.get(i)?,
            *m.positions.get(i + 1)?,
            *m.positions.get(i + 2)?,
        ))
    };
    let bad = || {
        err(
            0,
            format!("object {:?}: a face index is out of range", model.name),
        )
    };
    let arities: Vec<u32> = if m.face_arities.is_empty() {
        vec![3; m.indices.len() / 3]
    } else {
        m.face_arities.clone()
    };
    let mat = m.material_id.filter(|&i| i < mesh.materials.len());
    // Texture coordinates where every corner of the object has them.
    let vt = (m.texcoord_indices.len() == m.indices.len()).then_some(&m.texcoord_indices);
    let uv = |k: usize| -> Option<[f32; 2]> {
        let i = *vt?.get(k)? as usize * 2;
        let (u, v) = (*m.texcoords.get(i)?, *m.texcoords.get(i + 1)?);
        let finite = |x: f32| if x.is_finite() { x } else { 0.0 };
        Some([finite(u), finite(1.0 - v)])
    };
    let mut at = 0usize;
    for n in arities {
        let n = n as usize;
        let face = m.indices.get(at..at.saturating_add(n)).ok_or_else(bad)?;
        let first = at;
        at += n;
        if n < 3 {
            continue; // no area (the precheck refuses a face of no vertices)
        }
        let normals = match file_faces.next() {
            Some(f) if f.len() == n || f.is_empty() => f,
            _ => {
                return Err(err(
                    0,
                    "the faces do not match the file's face lines".into(),
                ));
            }
        };
        // Fan from the first vertex: (0, k, k+1).
        let p0 = pos(face[0]).ok_or_else(bad)?;
        for k in 1..n.saturating_sub(1) {
            let p1 = pos(face[k]).ok_or_else(bad)?;
            let p2 = pos(face[k + 1]).ok_or_else(bad)?;
            mesh.triangles.push([p0, p1, p2]);
            let flat = (p1 - p0).cross(p2 - p0).normalize_or_zero();
            let corner = |i: usize| match normals[i] {
                Vec3::ZERO => flat,
                n => n,
            };
            mesh.normals
                .push((!normals.is_empty()).then(|| [corner(0), corner(k), corner(k + 1)]));
            mesh.material.push(mat);
            mesh.uv
                .push(match [uv(first), uv(first + k), uv(first + k + 1)] {
                    [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                    _ => None,
                });
        }
    }
    Ok(())
}

/// Reads the OBJ at `path` with its MTL materials as an [`Asset`](super::asset::Asset) (the
/// mesh-source seam's form; `[[asset]] file = "x.obj"`): one mesh per
/// material, its triangles' corners unshared, each material
/// (metallic 0, roughness 1) of base colour `Kd` and emission `Ke`; faces
/// without a material take the asset's default one. Corners of faces
/// without `vn` get zero normals (flat) in a mesh where others have them.
pub fn load_asset(path: &Path) -> Result<super::asset::Asset, super::asset::AssetError> {
    use super::asset::{Asset, AssetError, AssetMesh, Instance, PbrMaterial};
    let obj = load(path, true).map_err(|e| {
        let at = if e.line > 0 {
            format!("line {}", e.line)
        } else {
            String::new()
        };
        AssetError::new(&e.file.display().to_string(), at, e.message)
    })?;
    let file = path.display().to_string();
    let mut meshes: Vec<AssetMesh> = Vec::new();
    let mut mesh_of: Vec<Option<usize>> = vec![None; obj.materials.len() + 1];
    let faces = (obj.triangles.iter().zip(&obj.material)).zip(obj.normals.iter().zip(&obj.uv));
    for ((tri, mat), (normals, uv)) in faces {
        let slot = mat.unwrap_or(obj.materials.len());
        let k = *mesh_of[slot].get_or_insert_with(|| {
            meshes.push(AssetMesh {
                name: format!("{file} material {slot}"),
                material: mat.map(|m| m as u32),
                ..AssetMesh::default()
            });
            meshes.len() - 1
        });
        let m = &mut meshes[k];
        let base = m.positions.len() as u32;
        m.positions.extend(tri);
        m.triangles.push([base, base + 1, base + 2]);
        if let Some(t) = uv {
            m.uv0.resize(base as usize, [0.0; 2]);
            m.uv0.extend(t);
        }
        match normals {
            Some(n) => {
                m.normals.resize(base as usize, Vec3::ZERO);
                m.normals.extend(n);
            }
            None if !m.normals.is_empty() => m.normals.extend([Vec3::ZERO; 3]),
            None => {}
        }
    }
    for m in &mut meshes {
        if !m.normals.is_empty() {
            m.normals.resize(m.positions.len(), Vec3::ZERO);
        }
        if !m.uv0.is_empty() {
            m.uv0.resize(m.positions.len(), [0.0; 2]);
        }
    }
    let mut textures = Vec::new();
    let mut sources = obj.sources[1..].to_vec();
    let mut materials = Vec::new();
    for m in &obj.materials {
        let mut texture = |f: &Option<MapFile>| match f {
            Some(f) => read_map(f, &mut textures, &mut sources).map(Some),
            None => Ok(None),
        };
        materials.push(PbrMaterial {
            name: m.name.clone(),
            base_colour: [m.diffuse.x, m.diffuse.y, m.diffuse.z, 1.0],
            base_colour_texture: texture(&m.diffuse_map)?,
            metallic: 0.0,
            roughness: 1.0,
            emissive: m.emission.to_array(),
            emissive_texture: texture(&m.emissive_map)?,
            ..PbrMaterial::default()
        });
    }
    let instances = (0..meshes.len() as u32)
        .map(|mesh| Instance {
            mesh,
            transform: glam::Mat4::IDENTITY,
        })
        .collect();
    Ok(Asset {
        meshes,
        instances,
        materials,
        textures,
        // Its MTL files and images (the OBJ is the asset's own file).
        sources,
        ..Asset::default()
    })
}

/// The image `f` names, decoded (sRGB) into `textures` and recorded in
/// `sources`: a texture of the asset that repeats and
/// filters linearly. An image that cannot be read is refused naming the
/// MTL line that names it.
fn read_map(
    f: &MapFile,
    textures: &mut Vec<super::texture::Texture>,
    sources: &mut Vec<PathBuf>,
) -> Result<super::texture::TextureRef, super::asset::AssetError> {
    use super::texture::{ColourSpace, Texture, TextureRef};
    let refuse = |m: String| {
        super::asset::AssetError::new(
            &f.mtl.display().to_string(),
            format!("line {}", f.line),
            format!("{}: {m}", f.path.display()),
        )
    };
    let bytes = std::fs::read(&f.path).map_err(|e| refuse(format!("cannot read: {e}")))?;
    let t = Texture::decode(&bytes, ColourSpace::Srgb).map_err(|e| refuse(e.to_string()))?;
    textures.push(t);
    if !sources.contains(&f.path) {
        sources.push(f.path.clone());
    }
    Ok(TextureRef {
        texture: (textures.len() - 1) as u32,
        tex_coord: 0,
        sampler: Default::default(),
        transform: Default::default(),
        scale: 1.0,
    })
}

/// Blank the polylines (`l`) and points (`p`) of an OBJ file, keeping its
/// newlines (and so its line numbers): they have no area, and `tobj`
/// reads a polyline of three vertices or more as a face.
fn blank_lines_and_points(bytes: &mut [u8]) {
    for line in bytes.split_mut(|&b| b == b'\n') {
        let start = line.iter().take_while(|b| b.is_ascii_whitespace()).count();
        let rest = &line[start..];
        let is =
            |k: u8| rest.first() == Some(&k) && rest.get(1).is_none_or(u8::is_ascii_whitespace);
        if is(b'l') || is(b'p') {
            line.fill(b' ');
        }
    }
}

/// Check the lines `tobj` would accept without a word: vertices and
/// vertex normals with non-finite coordinates,
/// face indices past the vertices defined so far (or 0, or negative past
/// the first), normal indices of faces when the file has no `vn` above
/// them, and faces that give normals to some corners and not others.
///
/// Returns, for every face of three corners or more in file order, its
/// corners' unit vertex normals (empty when it gives none).
fn precheck_obj(bytes: &[u8]) -> Result<Vec<Vec<Vec3>>, (usize, String)> {
    let (mut v, mut vt, mut vn) = (0usize, 0usize, 0usize);
    let mut normals: Vec<Vec3> = Vec::new();
    let mut faces: Vec<Vec<Vec3>> = Vec::new();
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = i + 1;
        let line = String::from_utf8_lossy(raw);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let coords: Vec<&str> = words.take(3).collect();
                if coords.len() < 3 {
                    return Err((line_no, "a vertex needs three coordinates".into()));
                }
                for c in coords {
                    let x: f32 = c.parse().map_err(|_| {
                        (line_no, format!("vertex coordinate {c:?} is not a number"))
                    })?;
                    if !x.is_finite() {
                        return Err((line_no, format!("vertex coordinate {c:?} is not finite")));
                    }
                }
                v += 1;
            }
            Some("mtllib") if words.next().is_none() => {
                return Err((line_no, "`mtllib` names no material file".into()));
            }
            Some("vt") => vt += 1,
            Some("vn") => {
                let c: Vec<f32> = words
                    .take(3)
                    .map(|c| c.parse::<f32>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| (line_no, "a vertex normal needs three numbers".to_string()))?;
                let n = match c[..] {
                    [x, y, z] => Vec3::new(x, y, z),
                    _ => return Err((line_no, "a vertex normal needs three numbers".into())),
                };
                let u = n.normalize_or_zero();
                if !n.is_finite() || !u.is_finite() {
                    return Err((line_no, format!("vertex normal {n} is not finite")));
                }
                // `vn 0 0 0` (common in exports) is kept as zero: the
                // corners that use it take their face's flat normal.
                normals.push(u);
                vn += 1;
            }
            Some("f") => {
                if let Some(face) = precheck_face(words, line_no, (v, vt, vn), &normals)? {
                    faces.push(face);
                }
            }
            _ => {}
        }
    }
    Ok(faces)
}

/// Checks an `f` line's corners (`words`, on line `line_no`) against the
/// `counts` of vertices, texture coordinates and normals defined above it
/// (`normals` the normals); returns the corners' normals (empty when the
/// face gives none) for a face of three corners or more, `None` for one
/// of fewer.
fn precheck_face(
    words: std::str::SplitWhitespace,
    line_no: usize,
    (v, vt, vn): (usize, usize, usize),
    normals: &[Vec3],
) -> Result<Option<Vec<Vec3>>, (usize, String)> {
    let mut corners = 0usize;
    let mut face_normals = Vec::new();
    for corner in words {
        corners += 1;
        let parts = corner.split('/').collect::<Vec<_>>();
        let has_normal = parts.get(2).is_some_and(|p| !p.is_empty());
        if corners > 1 && has_normal == face_normals.is_empty() {
            return Err((
                line_no,
                "a face gives vertex normals (v//vn, v/vt/vn) to some corners and \
                 not others"
                    .into(),
            ));
        }
        for (k, part) in corner.split('/').enumerate() {
            let (what, count) = match k {
                0 => ("vertex", v),
                1 => ("texture coordinate", vt),
                2 => ("normal", vn),
                _ => return Err((line_no, format!("bad face corner {corner:?}"))),
            };
            if part.is_empty() && k > 0 {
                continue;
            }
            let x: i64 = part.parse().map_err(|_| {
                (
                    line_no,
                    format!("face corner {corner:?}: {part:?} is not an index"),
                )
            })?;
            if k == 1 && count == 0 {
                continue; // tobj ignores these when there are none
            }
            let ok = if x > 0 {
                x as u64 <= count as u64
            } else {
                x < 0 && x.unsigned_abs() <= count as u64
            };
            if !ok {
                return Err((
                    line_no,
                    if x == 0 {
                        format!("face {what} index 0 (OBJ indices start at 1)")
                    } else {
                        format!(
                            "face {what} index {x} is past the {count} {what}(s) defined above it"
                        )
                    },
                ));
            }
            if k == 2 {
                let i = if x > 0 {
                    x as usize - 1
                } else {
                    vn - x.unsigned_abs() as usize
                };
                face_normals.push(normals[i]);
            }
        }
    }
    if corners == 0 {
        return Err((line_no, "a face (`f`) with no vertices".into()));
    }
    Ok((corners >= 3).then_some(face_normals))
}

/// What [`load_mtl`] gives: `tobj`'s materials, and the images the
/// materials name (`(material, "map_Kd" or "map_Ke", file)`).
type MtlLoad = (tobj::MTLLoadResult, Vec<(String, &'static str, MapFile)>);

/// Load an MTL file after checking the colours wavetrace reads, and the
/// images its `map_Kd` and `map_Ke` lines name (each must be a file).
fn load_mtl(path: &Path) -> Result<MtlLoad, ObjError> {
    let err = |line: usize, message: String| ObjError {
        file: path.to_path_buf(),
        line,
        message,
    };
    let bytes =
        std::fs::read(path).map_err(|e| err(0, format!("cannot read the material file: {e}")))?;
    // Decoded lossily, like the OBJ (see the module docs).
    let bytes = String::from_utf8_lossy(&bytes).into_owned().into_bytes();
    let dir = path.parent().unwrap_or(Path::new(""));
    let (mut maps, mut material) = (Vec::new(), String::new());
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(raw);
        let mut words = line.split_whitespace();
        let key = words.next();
        if key == Some("newmtl") {
            material = words.clone().collect::<Vec<_>>().join(" ");
        }
        if let Some(key @ ("map_Kd" | "map_Ke")) = key {
            let name = words
                .last()
                .ok_or_else(|| err(i + 1, format!("`{key}` names no image")))?;
            let file = dir.join(name);
            if !file.is_file() {
                return Err(err(
                    i + 1,
                    format!("`{key}` names {}, which is not a file", file.display()),
                ));
            }
            let map = MapFile {
                path: file,
                mtl: path.to_path_buf(),
                line: i + 1,
            };
            maps.push((
                material.clone(),
                if key == "map_Kd" { "map_Kd" } else { "map_Ke" },
                map,
            ));
            continue;
        }
        if matches!(key, Some("Ka" | "Kd" | "Ks" | "Ke" | "Kt" | "Tf")) {
            let key = key.unwrap_or_default();
            let values: Vec<f32> = words
                .take(3)
                .map(|w| w.parse::<f32>())
                .collect::<Result<_, _>>()
                .map_err(|_| err(i + 1, format!("`{key}` needs three numbers")))?;
            if values.len() != 3 || values.iter().any(|x| !x.is_finite()) {
                return Err(err(i + 1, format!("`{key}` needs three finite numbers")));
            }
            if key == "Kd" && values.iter().any(|&x| !(0.0..=1.0).contains(&x)) {
                return Err(err(i + 1, "`Kd` components must be in [0, 1]".into()));
            }
            if key == "Ke" && values.iter().any(|&x| x < 0.0) {
                return Err(err(i + 1, "`Ke` must not be negative".into()));
            }
        }
    }
    let mut reader = Lines::new(&bytes);
    let result = tobj::load_mtl_buf(&mut reader);
    if let Err(e) = &result {
        return Err(err(reader.line(), format!("malformed MTL: {e}")));
    }
    Ok((result, maps))
}

/// A reader over bytes that knows which line it has read up to.
struct Lines<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Lines<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    /// The 1-based line of the last byte consumed.
    fn line(&self) -> usize {
        let done = &self.bytes[..self.pos];
        let newlines = done.iter().filter(|&&b| b == b'\n').count();
        if done.last().is_some_and(|&b| b != b'\n') {
            newlines + 1
        } else {
            newlines.max(1)
        }
    }
}

impl Read for Lines<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = (&self.bytes[self.pos..]).read(buf)?;
        self.pos += n;
        Ok(n)
    }
}

impl BufRead for Lines<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(&self.bytes[self.pos..])
    }
    fn consume(&mut self, n: usize) {
        self.pos = (self.pos + n).min(self.bytes.len());
    }
}
