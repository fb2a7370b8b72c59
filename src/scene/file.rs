//! The TOML scene format (documented in `scenes/README.md`).
//!
//! Every error names the file, the line and column, and the field. Unknown
//! keys are refused, not ignored: a typo never silently changes a render.

use super::{
    AovSet, Integrator, Material, Model, RenderOptions, SamplerKind, Scene, Sphere, Triangle,
};
use crate::scene::camera::Camera;
use glam::Vec3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use toml::Spanned;

/// A scene file that cannot be used, and where the problem is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct SceneError {
    /// The file (or a label for in-memory text).
    pub file: String,
    /// 1-based line; 0 when the problem has no place in the file.
    pub line: usize,
    /// 1-based column; 0 when unknown.
    pub column: usize,
    /// The dotted path of the offending field, when known.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
    /// The mesh file's own error, when the problem is in a mesh the scene
    /// loads (`file` and `line` are then the mesh file's).
    #[source]
    pub mesh: Option<Box<super::obj::ObjError>>,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if self.line > 0 {
            write!(f, ":{}:{}", self.line, self.column)?;
        }
        if let Some(field) = &self.field {
            write!(f, ": field `{field}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: Option<String>,
    front_face: Option<Spanned<String>>,
    camera: Spanned<CameraFile>,
    #[serde(default)]
    integrator: IntegratorFile,
    materials: BTreeMap<String, Spanned<MaterialFile>>,
    #[serde(default, rename = "triangle")]
    triangles: Vec<Spanned<TriangleFile>>,
    #[serde(default, rename = "quad")]
    quads: Vec<Spanned<QuadFile>>,
    #[serde(default, rename = "sphere")]
    spheres: Vec<Spanned<SphereFile>>,
    #[serde(default, rename = "mesh")]
    meshes: Vec<Spanned<MeshFile>>,
    #[serde(default, rename = "generate")]
    generated: Vec<Spanned<GenerateFile>>,
}

/// A TOML array of exactly `N` elements: serde's arrays read the first `N`
/// and would let a typo's extra component (`[10, 10, 10, -1]`) pass
/// unseen.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Exact<A>(A);

impl<'de> Deserialize<'de> for Exact<f32> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        f32::deserialize(d).map(Exact)
    }
}

impl<'de, T: Copy + Default, const N: usize> Deserialize<'de> for Exact<[T; N]>
where
    Exact<T>: Deserialize<'de>,
{
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit<T, const N: usize>(std::marker::PhantomData<T>);
        impl<'de, T: Copy + Default, const N: usize> serde::de::Visitor<'de> for Visit<T, N>
        where
            Exact<T>: Deserialize<'de>,
        {
            type Value = [T; N];
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of {N} numbers")
            }
            fn visit_seq<S: serde::de::SeqAccess<'de>>(
                self,
                mut seq: S,
            ) -> Result<[T; N], S::Error> {
                let mut out = [T::default(); N];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot = seq
                        .next_element::<Exact<T>>()?
                        .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?
                        .0;
                }
                let mut n = N;
                while seq.next_element::<serde::de::IgnoredAny>()?.is_some() {
                    n += 1;
                }
                if n != N {
                    return Err(serde::de::Error::invalid_length(n, &self));
                }
                Ok(out)
            }
        }
        d.deserialize_seq(Visit::<T, N>(std::marker::PhantomData))
            .map(Exact)
    }
}

/// A uniform or per-axis scale.
#[derive(Deserialize, Clone, Copy)]
#[serde(untagged)]
enum ScaleFile {
    Uniform(f32),
    PerAxis(Exact<[f32; 3]>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshFile {
    #[allow(dead_code)] // a label for people reading the file
    name: Option<String>,
    file: Spanned<String>,
    material: Option<Spanned<String>>,
    #[serde(default)]
    mtl: Option<Spanned<bool>>,
    front_face: Option<Spanned<String>>,
    scale: Option<Spanned<ScaleFile>>,
    rotate_deg: Option<Spanned<Exact<[f32; 3]>>>,
    translate: Option<Spanned<Exact<[f32; 3]>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GenerateFile {
    #[allow(dead_code)] // a label for people reading the file
    name: Option<String>,
    kind: Spanned<String>,
    triangles: Spanned<u64>,
    material: Spanned<String>,
    center: Option<Spanned<Exact<[f32; 3]>>>,
    radius: Option<Spanned<f32>>,
    size: Option<Spanned<Exact<[f32; 2]>>>,
    height: Option<Spanned<f32>>,
    seed: Option<Spanned<u64>>,
    scale: Option<Spanned<ScaleFile>>,
    rotate_deg: Option<Spanned<Exact<[f32; 3]>>>,
    translate: Option<Spanned<Exact<[f32; 3]>>>,
}

/// The most triangles one `[[generate]]` entry may ask for.
pub const MAX_GENERATED_TRIANGLES: u64 = 50_000_000;

/// The most triangles a scene may have, all entries together: checked
/// before each mesh is added and each `[[generate]]` entry is made, so a
/// file of many large entries is refused before it fills the memory.
pub const MAX_SCENE_TRIANGLES: usize = 100_000_000;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    position: Spanned<Exact<[f32; 3]>>,
    forward: Option<Spanned<Exact<[f32; 3]>>>,
    look_at: Option<Spanned<Exact<[f32; 3]>>>,
    up: Spanned<Exact<[f32; 3]>>,
    focal_length_px: Option<Spanned<f32>>,
    vfov_deg: Option<Spanned<f32>>,
    width: Spanned<u32>,
    height: Spanned<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IntegratorFile {
    #[serde(default = "default_max_depth")]
    max_depth: Spanned<u32>,
    name: Option<Spanned<String>>,
    sampler: Option<Spanned<String>>,
    rr_depth: Option<Spanned<u32>>,
    aov: Option<Spanned<Vec<String>>>,
}

impl Default for IntegratorFile {
    fn default() -> Self {
        Self {
            max_depth: Spanned::new(0..0, default_max_depth().into_inner()),
            name: None,
            sampler: None,
            rr_depth: None,
            aov: None,
        }
    }
}

fn default_max_depth() -> Spanned<u32> {
    Spanned::new(0..0, 3)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialFile {
    #[serde(default)]
    model: Option<Spanned<String>>,
    #[serde(default)]
    reflectance: Option<Spanned<Exact<[f32; 3]>>>,
    #[serde(default)]
    emission: Option<Spanned<Exact<[f32; 3]>>>,
    #[serde(default)]
    ior: Option<Spanned<f32>>,
    #[serde(default)]
    transmittance: Option<Spanned<Exact<[f32; 3]>>>,
    #[serde(default)]
    alpha: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereFile {
    #[allow(dead_code)] // a label for people reading the file
    name: Option<String>,
    material: Spanned<String>,
    center: Spanned<Exact<[f32; 3]>>,
    radius: Spanned<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TriangleFile {
    #[allow(dead_code)] // a label for people reading the file
    name: Option<String>,
    material: Spanned<String>,
    vertices: Spanned<Exact<[[f32; 3]; 3]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct QuadFile {
    #[allow(dead_code)] // a label for people reading the file
    name: Option<String>,
    material: Spanned<String>,
    vertices: Spanned<Exact<[[f32; 3]; 4]>>,
}

/// Parse scene text; `file` names it in errors.
pub fn parse(text: &str, file: &str) -> Result<Scene, SceneError> {
    let at = |span: std::ops::Range<usize>, field: &str, message: String| {
        let (line, column) = line_col(text, span.start);
        SceneError {
            mesh: None,
            file: file.to_string(),
            line,
            column,
            field: Some(field.to_string()),
            message,
        }
    };
    let raw: SceneFile = toml::from_str(text).map_err(|e| {
        let (line, column) = e.span().map_or((0, 0), |s| line_col(text, s.start));
        SceneError {
            mesh: None,
            file: file.to_string(),
            line,
            column,
            field: field_at(text, e.span().map(|s| s.start), field_of(e.message())),
            message: e.message().trim().to_string(),
        }
    })?;

    let ccw = match raw.front_face.as_ref().map(|s| s.get_ref().as_str()) {
        None | Some("counterclockwise") => true,
        Some("clockwise") => false,
        Some(other) => {
            let s = raw.front_face.as_ref().unwrap();
            return Err(at(
                s.span(),
                "front_face",
                format!("must be \"counterclockwise\" or \"clockwise\", not {other:?}"),
            ));
        }
    };

    // Camera.
    let cam = raw.camera.get_ref();
    let vec = |s: &Spanned<Exact<[f32; 3]>>, field: &str| -> Result<Vec3, SceneError> {
        let v = Vec3::from_array(s.get_ref().0);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(at(s.span(), field, "must be finite numbers".into()))
        }
    };
    let position = vec(&cam.position, "camera.position")?;
    let forward = match (&cam.forward, &cam.look_at) {
        (Some(f), None) => vec(f, "camera.forward")?,
        (None, Some(l)) => vec(l, "camera.look_at")? - position,
        _ => {
            return Err(at(
                raw.camera.span(),
                "camera",
                "give exactly one of `forward` and `look_at`".into(),
            ));
        }
    };
    let up = vec(&cam.up, "camera.up")?;
    for (s, field) in [(&cam.width, "camera.width"), (&cam.height, "camera.height")] {
        if *s.get_ref() == 0 {
            return Err(at(s.span(), field, "must be at least 1".into()));
        }
    }
    let (width, height) = (*cam.width.get_ref(), *cam.height.get_ref());
    let focal = match (&cam.focal_length_px, &cam.vfov_deg) {
        (Some(f), None) => {
            let v = *f.get_ref();
            if !(v.is_finite() && v > 0.0) {
                return Err(at(
                    f.span(),
                    "camera.focal_length_px",
                    "must be a positive number".into(),
                ));
            }
            v
        }
        (None, Some(a)) => {
            let v = *a.get_ref();
            if !(v > 0.0 && v < 180.0) {
                return Err(at(
                    a.span(),
                    "camera.vfov_deg",
                    "must be between 0 and 180 degrees".into(),
                ));
            }
            Camera::focal_from_vfov(v, height)
        }
        _ => {
            return Err(at(
                raw.camera.span(),
                "camera",
                "give exactly one of `focal_length_px` and `vfov_deg`".into(),
            ));
        }
    };
    let camera = Camera::new(position, forward, up, focal, width, height).ok_or_else(|| {
        at(
            cam.up.span(),
            "camera.up",
            "the viewing direction must be non-zero and not parallel to `up`".into(),
        )
    })?;

    // Materials.
    let mut materials = Vec::new();
    let mut index = BTreeMap::new();
    for (name, m) in &raw.materials {
        let m_ref = m.get_ref();
        let model = match &m_ref.model {
            None => Model::Diffuse,
            Some(model) => match Model::from_name(model.get_ref()) {
                Some(m) => m,
                None => {
                    return Err(at(
                        model.span(),
                        &format!("materials.{name}.model"),
                        format!(
                            "unknown model {:?} (known: {})",
                            model.get_ref(),
                            Model::NAMES.join(", ")
                        ),
                    ));
                }
            },
        };
        // A field the model does not read is refused, not ignored.
        let unused =
            |present: Option<std::ops::Range<usize>>, key: &str, models: &str| match present {
                Some(span) => Err(at(
                    span,
                    &format!("materials.{name}.{key}"),
                    format!("{} materials have no {key} (only {models})", model.name()),
                )),
                None => Ok(()),
            };
        let unit_color = |v: &Spanned<Exact<[f32; 3]>>, key: &str| -> Result<Vec3, SceneError> {
            let field = format!("materials.{name}.{key}");
            let c = vec(v, &field)?;
            if c.min_element() < 0.0 || c.max_element() > 1.0 {
                return Err(at(
                    v.span(),
                    &field,
                    "each component must be in [0, 1]".into(),
                ));
            }
            Ok(c)
        };
        let reflectance = match (&m_ref.reflectance, model) {
            (Some(r), Model::Glass) => {
                unused(Some(r.span()), "reflectance", "diffuse, mirror and metal")?;
                Vec3::ONE
            }
            (Some(r), _) => unit_color(r, "reflectance")?,
            (None, Model::Glass) => Vec3::ONE,
            (None, _) => {
                return Err(at(
                    m.span(),
                    &format!("materials.{name}.reflectance"),
                    format!("a {} material needs a reflectance", model.name()),
                ));
            }
        };
        let emission = match &m_ref.emission {
            None => Vec3::ZERO,
            Some(e) => {
                let field = format!("materials.{name}.emission");
                let v = vec(e, &field)?;
                if v.min_element() < 0.0 {
                    return Err(at(e.span(), &field, "must not be negative".into()));
                }
                v
            }
        };
        let mut material = Material {
            model,
            reflectance,
            emission,
            ..Material::diffuse(name, reflectance, emission)
        };
        if model == Model::Glass {
            if let Some(ior) = &m_ref.ior {
                let v = *ior.get_ref();
                let range = super::material::IOR_RANGE;
                if !range.contains(&v) {
                    return Err(at(
                        ior.span(),
                        &format!("materials.{name}.ior"),
                        format!(
                            "must be an index of refraction from {} to {} (e.g. 1.5 for glass), not {v}",
                            range.start(),
                            range.end()
                        ),
                    ));
                }
                material.ior = v;
            }
            if let Some(t) = &m_ref.transmittance {
                material.transmittance = unit_color(t, "transmittance")?;
            }
        } else {
            unused(m_ref.ior.as_ref().map(|v| v.span()), "ior", "glass")?;
            let t = m_ref.transmittance.as_ref().map(|v| v.span());
            unused(t, "transmittance", "glass")?;
        }
        if model == Model::Metal {
            if let Some(alpha) = &m_ref.alpha {
                let v = *alpha.get_ref();
                if !(0.0..=1.0).contains(&v) {
                    return Err(at(
                        alpha.span(),
                        &format!("materials.{name}.alpha"),
                        "must be a GGX roughness in [0, 1] (0: a mirror)".into(),
                    ));
                }
                material.alpha = v;
            }
        } else {
            unused(m_ref.alpha.as_ref().map(|v| v.span()), "alpha", "metal")?;
        }
        index.insert(name.clone(), materials.len() as u32);
        materials.push(material);
    }

    // Geometry: triangles, then quads (each split into two triangles).
    let mut triangles = Vec::new();
    // Per-vertex normals of the triangles that have them (and zeros for
    // the flat ones before them); filled up to every triangle at the end
    // if any triangle has them.
    let mut vertex_normals: Vec<[Vec3; 3]> = Vec::new();
    let polygons = raw
        .triangles
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let t = t.get_ref();
            let v = t.vertices.get_ref();
            (
                format!("triangle[{i}]"),
                &t.material,
                t.vertices.span(),
                v.0.to_vec(),
            )
        })
        .chain(raw.quads.iter().enumerate().map(|(i, q)| {
            let q = q.get_ref();
            let v = q.vertices.get_ref();
            (
                format!("quad[{i}]"),
                &q.material,
                q.vertices.span(),
                v.0.to_vec(),
            )
        }));
    for (what, material, span, verts) in polygons {
        let m = *index.get(material.get_ref()).ok_or_else(|| {
            at(
                material.span(),
                &format!("{what}.material"),
                format!(
                    "no material named {:?} (the file defines: {})",
                    material.get_ref(),
                    raw.materials.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
            )
        })?;
        let verts: Vec<Vec3> = verts.into_iter().map(Vec3::from_array).collect();
        if verts.iter().any(|v| !v.is_finite()) {
            return Err(at(
                span,
                &format!("{what}.vertices"),
                "must be finite numbers".into(),
            ));
        }
        let fans: &[[usize; 3]] = if verts.len() == 4 {
            &[[0, 1, 2], [0, 2, 3]]
        } else {
            &[[0, 1, 2]]
        };
        for f in fans {
            let v = [verts[f[0]], verts[f[1]], verts[f[2]]];
            let t = if ccw {
                Triangle::ccw(v, m)
            } else {
                Triangle::cw(v, m)
            };
            if t.normal == Vec3::ZERO {
                return Err(at(
                    span.clone(),
                    &format!("{what}.vertices"),
                    "the vertices do not span a triangle (zero area)".into(),
                ));
            }
            triangles.push(t);
        }
    }
    // Meshes: OBJ files, then generated meshes, each in file order.
    let base = std::path::Path::new(file)
        .parent()
        .unwrap_or(std::path::Path::new(""));
    let material_named = |name: &Spanned<String>, field: &str| -> Result<u32, SceneError> {
        index.get(name.get_ref()).copied().ok_or_else(|| {
            at(
                name.span(),
                field,
                format!(
                    "no material named {:?} (the file defines: {})",
                    name.get_ref(),
                    raw.materials.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
            )
        })
    };
    for (i, m) in raw.meshes.iter().enumerate() {
        let what = format!("mesh[{i}]");
        let m = m.get_ref();
        let transform = transform(
            &at,
            &what,
            m.scale.as_ref(),
            m.rotate_deg.as_ref(),
            m.translate.as_ref(),
        )?;
        let mesh_ccw = mesh_front_face(&at, &what, m.front_face.as_ref())?;
        let fallback = m
            .material
            .as_ref()
            .map(|n| material_named(n, &format!("{what}.material")))
            .transpose()?;
        let with_mtl = m.mtl.as_ref().is_some_and(|b| *b.get_ref());
        if fallback.is_none() && !with_mtl {
            return Err(at(
                m.file.span(),
                &what,
                "give a `material`, or `mtl = true` to take materials from the OBJ's MTL files"
                    .into(),
            ));
        }
        let path = base.join(m.file.get_ref());
        let obj = super::obj::load(&path, with_mtl).map_err(|e| {
            let (line, column) = line_col(text, m.file.span().start);
            SceneError {
                mesh: Some(Box::new(e.clone())),
                file: e.file.display().to_string(),
                line: e.line,
                column: if e.line > 0 { 1 } else { 0 },
                field: None,
                message: format!("{} (the mesh of {what}, {file}:{line}:{column})", e.message),
            }
        })?;
        if triangles.len() + obj.triangles.len() > MAX_SCENE_TRIANGLES {
            return Err(at(
                m.file.span(),
                &what,
                format!(
                    "the scene would have more than {MAX_SCENE_TRIANGLES} triangles ({} before this mesh, {} in it)",
                    triangles.len(),
                    obj.triangles.len()
                ),
            ));
        }
        // The OBJ's materials become scene materials named "file:name".
        let mut mtl_index = Vec::new();
        for om in &obj.materials {
            let name = format!("{}:{}", m.file.get_ref(), om.name);
            mtl_index.push(materials.len() as u32);
            materials.push(Material::diffuse(&name, om.diffuse, om.emission));
        }
        // Normals go by the inverse transpose of the transform's linear part.
        let normal_matrix = transform.matrix3.inverse().transpose();
        for ((tri, mat), normals) in obj.triangles.iter().zip(&obj.material).zip(&obj.normals) {
            let mat = match mat.map(|k| mtl_index[k]).or(fallback) {
                Some(mat) => mat,
                None => {
                    return Err(at(
                        m.file.span(),
                        &what,
                        format!(
                            "{}: some faces have no material (no `usemtl`, or one its MTL files \
                             do not define) and the mesh gives no fallback `material`",
                            path.display()
                        ),
                    ));
                }
            };
            let before = triangles.len();
            push_mesh_triangle(&mut triangles, &transform, mesh_ccw, *tri, mat)
                .map_err(|e| at(m.file.span(), &what, e))?;
            if let (Some(n), true) = (normals, triangles.len() > before) {
                // World-space unit normals (a transform that makes one
                // degenerate leaves that vertex's normal zero: the
                // interpolation then falls back to the geometric normal
                // wherever the sum degenerates).
                let n = n.map(|n| {
                    let w = (normal_matrix * glam::Vec3A::from(n)).normalize_or_zero();
                    if w.is_finite() {
                        Vec3::from(w)
                    } else {
                        Vec3::ZERO
                    }
                });
                vertex_normals.resize(before, [Vec3::ZERO; 3]);
                vertex_normals.push(n);
            }
        }
    }
    for (i, g) in raw.generated.iter().enumerate() {
        let what = format!("generate[{i}]");
        let g = g.get_ref();
        let mat = material_named(&g.material, &format!("{what}.material"))?;
        let n = *g.triangles.get_ref();
        if n == 0 || n > MAX_GENERATED_TRIANGLES {
            return Err(at(
                g.triangles.span(),
                &format!("{what}.triangles"),
                format!("must be between 1 and {MAX_GENERATED_TRIANGLES}"),
            ));
        }
        if triangles.len() as u64 + n > MAX_SCENE_TRIANGLES as u64 {
            return Err(at(
                g.triangles.span(),
                &format!("{what}.triangles"),
                format!(
                    "the scene would have more than {MAX_SCENE_TRIANGLES} triangles ({} before this entry)",
                    triangles.len()
                ),
            ));
        }
        let transform = transform(
            &at,
            &what,
            g.scale.as_ref(),
            g.rotate_deg.as_ref(),
            g.translate.as_ref(),
        )?;
        let center = match &g.center {
            Some(c) => vec(c, &format!("{what}.center"))?,
            None => Vec3::ZERO,
        };
        let positive = |v: &Option<Spanned<f32>>, field: &str, default: f32, zero_ok: bool| match v
        {
            None => Ok(default),
            Some(s) => {
                let x = *s.get_ref();
                if x.is_finite() && (x > 0.0 || (zero_ok && x == 0.0)) {
                    Ok(x)
                } else {
                    Err(at(
                        s.span(),
                        &format!("{what}.{field}"),
                        "must be a positive number".into(),
                    ))
                }
            }
        };
        let unused = |present: bool, span: Option<std::ops::Range<usize>>, field: &str| {
            if present {
                Err(at(
                    span.unwrap_or(g.kind.span()),
                    &format!("{what}.{field}"),
                    format!("`{field}` does not apply to kind {:?}", g.kind.get_ref()),
                ))
            } else {
                Ok(())
            }
        };
        let tris = match g.kind.get_ref().as_str() {
            "sphere" => {
                unused(g.size.is_some(), g.size.as_ref().map(|s| s.span()), "size")?;
                unused(
                    g.height.is_some(),
                    g.height.as_ref().map(|s| s.span()),
                    "height",
                )?;
                unused(g.seed.is_some(), g.seed.as_ref().map(|s| s.span()), "seed")?;
                let radius = positive(&g.radius, "radius", 1.0, false)?;
                crate::scene::mesh::geodesic_sphere(center, radius, n as usize)
            }
            "terrain" => {
                unused(
                    g.radius.is_some(),
                    g.radius.as_ref().map(|s| s.span()),
                    "radius",
                )?;
                let size = match &g.size {
                    None => [1.0, 1.0],
                    Some(s) => {
                        let v = s.get_ref().0;
                        if !v.iter().all(|x| x.is_finite() && *x > 0.0) {
                            return Err(at(
                                s.span(),
                                &format!("{what}.size"),
                                "must be two positive numbers".into(),
                            ));
                        }
                        v
                    }
                };
                let height = positive(&g.height, "height", 0.1, true)?;
                let seed = g.seed.as_ref().map_or(0, |s| *s.get_ref());
                crate::scene::mesh::terrain(center, size, height, n as usize, seed)
            }
            other => {
                return Err(at(
                    g.kind.span(),
                    &format!("{what}.kind"),
                    format!("unknown kind {other:?} (known: \"sphere\", \"terrain\")"),
                ));
            }
        };
        for tri in tris {
            push_mesh_triangle(&mut triangles, &transform, true, tri, mat)
                .map_err(|e| at(g.kind.span(), &what, e))?;
        }
    }

    let mut spheres = Vec::new();
    for (i, sp) in raw.spheres.iter().enumerate() {
        let what = format!("sphere[{i}]");
        let sp = sp.get_ref();
        let center = vec(&sp.center, &format!("{what}.center"))?;
        let radius = *sp.radius.get_ref();
        if !(radius.is_finite() && radius > 0.0) {
            return Err(at(
                sp.radius.span(),
                &format!("{what}.radius"),
                "must be a positive, finite number".into(),
            ));
        }
        let material = material_named(&sp.material, &format!("{what}.material"))?;
        spheres.push(Sphere {
            center,
            radius,
            material,
        });
    }

    if triangles.is_empty() && spheres.is_empty() {
        return Err(SceneError {
            mesh: None,
            file: file.to_string(),
            line: 0,
            column: 0,
            field: None,
            message:
                "the scene has no geometry (no [[triangle]], [[quad]], [[sphere]], [[mesh]] or [[generate]])"
                    .into(),
        });
    }

    let max_depth = *raw.integrator.max_depth.get_ref();
    if max_depth == 0 {
        return Err(at(
            raw.integrator.max_depth.span(),
            "integrator.max_depth",
            "must be at least 1".into(),
        ));
    }
    let named = |v: &Option<Spanned<String>>, field: &str, known: &[&str]| match v {
        Some(n) if !known.contains(&n.get_ref().as_str()) => Err(at(
            n.span(),
            field,
            format!(
                "unknown name {:?} (known: {})",
                n.get_ref(),
                known.join(", ")
            ),
        )),
        _ => Ok(v.as_ref().map(|n| n.get_ref().clone())),
    };
    let integrator = named(&raw.integrator.name, "integrator.name", Integrator::NAMES)?;
    let sampler = named(
        &raw.integrator.sampler,
        "integrator.sampler",
        SamplerKind::NAMES,
    )?;
    let aov = match &raw.integrator.aov {
        Some(list) => Some(
            AovSet::from_names(list.get_ref().iter().map(String::as_str))
                .map_err(|message| at(list.span(), "integrator.aov", message))?,
        ),
        None => None,
    };
    let options = RenderOptions {
        integrator: integrator.and_then(|n| Integrator::from_name(&n)),
        sampler: sampler.and_then(|n| SamplerKind::from_name(&n)),
        rr_depth: raw.integrator.rr_depth.as_ref().map(|d| *d.get_ref()),
        aov,
    };
    Ok(Scene {
        name: raw.name.unwrap_or_else(|| {
            std::path::Path::new(file)
                .file_stem()
                .map_or("scene".into(), |s| s.to_string_lossy().into_owned())
        }),
        camera,
        materials,
        vertex_normals: if vertex_normals.is_empty() {
            vertex_normals
        } else {
            let mut v = vertex_normals;
            v.resize(triangles.len(), [Vec3::ZERO; 3]);
            v
        },
        triangles,
        texturing: Default::default(),
        spheres,
        max_depth,
        options,
    })
}

/// Scale, then rotate (about x, then y, then z, in degrees), then translate.
fn transform(
    at: &impl Fn(std::ops::Range<usize>, &str, String) -> SceneError,
    what: &str,
    scale: Option<&Spanned<ScaleFile>>,
    rotate_deg: Option<&Spanned<Exact<[f32; 3]>>>,
    translate: Option<&Spanned<Exact<[f32; 3]>>>,
) -> Result<glam::Affine3A, SceneError> {
    let s = match scale {
        None => Vec3::ONE,
        Some(s) => {
            let v = match *s.get_ref() {
                ScaleFile::Uniform(x) => Vec3::splat(x),
                ScaleFile::PerAxis(v) => Vec3::from_array(v.0),
            };
            if !v.is_finite() || v.x * v.y * v.z == 0.0 {
                return Err(at(
                    s.span(),
                    &format!("{what}.scale"),
                    "must be finite and non-zero".into(),
                ));
            }
            v
        }
    };
    let finite = |v: Option<&Spanned<Exact<[f32; 3]>>>, field: &str| -> Result<Vec3, SceneError> {
        match v {
            None => Ok(Vec3::ZERO),
            Some(v) if Vec3::from_array(v.get_ref().0).is_finite() => {
                Ok(Vec3::from_array(v.get_ref().0))
            }
            Some(v) => Err(at(
                v.span(),
                &format!("{what}.{field}"),
                "must be finite numbers".into(),
            )),
        }
    };
    let r = finite(rotate_deg, "rotate_deg")?;
    let t = finite(translate, "translate")?;
    let rotation = glam::Quat::from_euler(
        glam::EulerRot::ZYX,
        r.z.to_radians(),
        r.y.to_radians(),
        r.x.to_radians(),
    );
    Ok(glam::Affine3A::from_scale_rotation_translation(
        s, rotation, t,
    ))
}

/// A mesh's `front_face` (counter-clockwise unless it says otherwise).
fn mesh_front_face(
    at: &impl Fn(std::ops::Range<usize>, &str, String) -> SceneError,
    what: &str,
    front_face: Option<&Spanned<String>>,
) -> Result<bool, SceneError> {
    match front_face.map(|s| (s, s.get_ref().as_str())) {
        None | Some((_, "counterclockwise")) => Ok(true),
        Some((_, "clockwise")) => Ok(false),
        Some((s, other)) => Err(at(
            s.span(),
            &format!("{what}.front_face"),
            format!("must be \"counterclockwise\" or \"clockwise\", not {other:?}"),
        )),
    }
}

/// Transform a mesh triangle and add it, unless it has no area (skipped:
/// it could never be hit). A mirroring transform swaps the winding, so the
/// front stays the same side of the surface. A vertex the transform makes
/// infinite or NaN is an error, which the caller places in the file.
fn push_mesh_triangle(
    out: &mut Vec<Triangle>,
    transform: &glam::Affine3A,
    ccw: bool,
    v: [Vec3; 3],
    material: u32,
) -> Result<(), String> {
    let p = v.map(|p| transform.transform_point3(p));
    if let Some(q) = p.iter().find(|q| !q.is_finite()) {
        return Err(format!(
            "the transform (scale, rotate_deg, translate) turns a vertex into {q}: \
             the coordinates overflow f32"
        ));
    }
    let mirrored = transform.matrix3.determinant() < 0.0;
    let t = if ccw != mirrored {
        Triangle::ccw(p, material)
    } else {
        Triangle::cw(p, material)
    };
    if t.normal != Vec3::ZERO {
        out.push(t);
    }
    Ok(())
}

/// 1-based line and column of byte `offset` in `text`.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The dotted field of a TOML error at byte `offset` that names `named`
/// (`unknown field `x``, `missing field `x``): the key written there, or
/// `named` inside the table whose header is there; else what is known.
fn field_at(text: &str, offset: Option<usize>, named: Option<String>) -> Option<String> {
    let at_key = offset.and_then(|o| key_at(text, o));
    let header = offset.and_then(|o| {
        let line_start = text[..o.min(text.len())].rfind('\n').map_or(0, |i| i + 1);
        table_header(text[line_start..].lines().next().unwrap_or(""))
    });
    let within = |outer: &str, n: &str| outer == n || outer.ends_with(&format!(".{n}"));
    match (named, at_key, header) {
        (Some(n), Some(k), _) if within(&k, &n) => Some(k),
        (Some(n), _, Some(h)) if within(h, &n) => Some(h.to_string()),
        (Some(n), _, Some(h)) => Some(format!("{h}.{n}")),
        (Some(n), _, _) => Some(n),
        (None, k, _) => k,
    }
}

/// The dotted key whose value holds byte `offset`: the nearest table header
/// above it (`[camera]`, `[[triangle]]`) and the `key =` on its line.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let before = &text[..offset.min(text.len())];
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    // Only the offset's own line: `key = value`.
    let line = text[line_start..].lines().next().unwrap_or("");
    let key = line.split_once('=').map(|(k, _)| k.trim())?;
    if key.is_empty() || key.starts_with(['[', '#']) {
        return None;
    }
    let table = before[..line_start].lines().rev().find_map(table_header);
    Some(match table {
        Some(t) => format!("{t}.{key}"),
        None => key.to_string(),
    })
}

/// The table a header line names (`[camera]`, `[[triangle]]`, with an
/// optional comment), or `None` for any other line — such as the rows of a
/// multi-line array.
fn table_header(line: &str) -> Option<&str> {
    let line = line.split('#').next()?.trim();
    let name = line.strip_prefix('[')?.strip_suffix(']')?;
    let name = name
        .strip_prefix('[')
        .and_then(|n| n.strip_suffix(']'))
        .unwrap_or(name)
        .trim();
    let first = name.chars().next()?;
    let is_key = (first.is_alphabetic() || first == '_' || first == '"')
        && name
            .chars()
            .all(|c| c.is_alphanumeric() || "_-. \"".contains(c));
    is_key.then_some(name)
}

/// The field a serde message is about (`unknown field `x``, `missing field `x``).
fn field_of(message: &str) -> Option<String> {
    let start = message.find("field `")? + "field `".len();
    let len = message[start..].find('`')?;
    Some(message[start..start + len].to_string())
}
