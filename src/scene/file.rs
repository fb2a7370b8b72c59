//! The TOML scene format (documented in `scenes/README.md`): one front
//! end of the [scene builder](super::builder). Each table is read by a
//! function of its own, which checks its values where they are written and
//! hands them to the builder with their place.
//!
//! Every error names the file, the line and column, and the field. Unknown
//! keys are refused, not ignored: a typo never silently changes a render.

use super::builder::{Origin, Placement, SceneBuilder, View};
use super::{AovSet, Integrator, Material, Model, RenderOptions, SamplerKind, Scene};
use crate::scene::camera::Camera;
use glam::Vec3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

pub use super::builder::{MAX_SCENE_TRIANGLES, SceneError};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: Option<String>,
    front_face: Option<Spanned<String>>,
    camera: Spanned<CameraFile>,
    #[serde(default)]
    integrator: IntegratorFile,
    #[serde(default)]
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
    #[serde(default, rename = "asset")]
    assets: Vec<Spanned<AssetFile>>,
    environment: Option<Spanned<super::environment::EnvironmentFile>>,
    #[serde(default, rename = "light")]
    lights: Vec<Spanned<super::punctual::LightFile>>,
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

/// An `[[asset]]`: a mesh file of any format the mesh-source seam reads,
/// with its materials, placed by TRS or by a matrix.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AssetFile {
    #[allow(dead_code)] // a label for people reading the file
    name: Option<String>,
    file: Spanned<String>,
    scale: Option<Spanned<ScaleFile>>,
    rotate_deg: Option<Spanned<Exact<[f32; 3]>>>,
    translate: Option<Spanned<Exact<[f32; 3]>>>,
    /// Object to world, row by row (the last row `[0, 0, 0, 1]`).
    matrix: Option<Spanned<Exact<[[f32; 4]; 4]>>>,
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
    light_tree: Option<bool>,
}

impl Default for IntegratorFile {
    fn default() -> Self {
        Self {
            max_depth: Spanned::new(0..0, default_max_depth().into_inner()),
            name: None,
            sampler: None,
            rr_depth: None,
            aov: None,
            light_tree: None,
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
    #[serde(default)]
    metallic: Option<Spanned<f32>>,
    #[serde(default)]
    roughness: Option<Spanned<f32>>,
    #[serde(default)]
    transmission: Option<Spanned<f32>>,
    #[serde(default)]
    thin: Option<Spanned<bool>>,
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
    let t = Toml { text, file };
    let raw = t.read()?;
    let ccw = front_face(&t, raw.front_face.as_ref(), "front_face")?;
    let name = raw.name.clone().unwrap_or_else(|| {
        Path::new(file)
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy().into_owned())
    });
    let mut b = SceneBuilder::new(&name);
    camera(&t, &raw.camera, &mut b)?;
    let names = materials(&t, &raw.materials, &mut b)?;
    // Geometry: triangles, then quads, then OBJ meshes, then generated
    // meshes, then assets, then spheres, each in file order.
    polygons(&t, &raw, ccw, &names, &mut b)?;
    for (i, m) in raw.meshes.iter().enumerate() {
        let label = m.get_ref().name.clone();
        b.object(&label.unwrap_or_else(|| format!("mesh[{i}]")));
        mesh(&t, i, m.get_ref(), &names, &mut b)?;
    }
    for (i, g) in raw.generated.iter().enumerate() {
        let label = g.get_ref().name.clone();
        b.object(&label.unwrap_or_else(|| format!("generate[{i}]")));
        generate(&t, i, g.get_ref(), &names, &mut b)?;
    }
    for (i, a) in raw.assets.iter().enumerate() {
        asset(&t, i, a.get_ref(), &mut b)?;
    }
    for (i, s) in raw.spheres.iter().enumerate() {
        let label = s.get_ref().name.clone();
        b.object(&label.unwrap_or_else(|| format!("sphere[{i}]")));
        sphere(&t, i, s.get_ref(), &names, &mut b)?;
    }
    let whole = Origin::file(file);
    if b.is_empty() {
        return Err(whole.error(
            "the scene has no geometry (no [[triangle]], [[quad]], [[sphere]], [[mesh]], [[generate]] or [[asset]])",
        ));
    }
    let (max_depth, options) = integrator(&t, &raw.integrator)?;
    b.settings(max_depth, options);
    let env = super::environment::from_file(raw.environment.as_ref(), file);
    b.environment(env.map_err(|(span, field, m)| t.err(span, &field, m))?);
    for (k, l) in raw.lights.iter().enumerate() {
        let light = super::punctual::from_file(k, l.get_ref());
        b.light(light.map_err(|(span, field, m)| t.err(span, &field, m))?);
    }
    b.finish(&whole)
}

/// The TOML text being read, and places in it for errors.
struct Toml<'a> {
    text: &'a str,
    file: &'a str,
}

impl Toml<'_> {
    /// The text as its tables, or the TOML or serde error at its place.
    fn read(&self) -> Result<SceneFile, SceneError> {
        toml::from_str(self.text).map_err(|e| {
            let (line, column) = e.span().map_or((0, 0), |s| line_col(self.text, s.start));
            SceneError {
                mesh: None,
                file: self.file.to_string(),
                line,
                column,
                field: field_at(self.text, e.span().map(|s| s.start), field_of(e.message())),
                message: e.message().trim().to_string(),
            }
        })
    }

    /// The place of `span`, which holds `field`.
    fn origin(&self, span: Range<usize>, field: &str) -> Origin {
        let (line, column) = line_col(self.text, span.start);
        Origin {
            file: self.file.to_string(),
            line,
            column,
            field: Some(field.to_string()),
        }
    }

    /// The error `message` about `field`, written at `span`.
    fn err(&self, span: Range<usize>, field: &str, message: impl Into<String>) -> SceneError {
        self.origin(span, field).error(message)
    }

    /// A vector of finite numbers.
    fn vec(&self, s: &Spanned<Exact<[f32; 3]>>, field: &str) -> Result<Vec3, SceneError> {
        let v = Vec3::from_array(s.get_ref().0);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err(s.span(), field, "must be finite numbers"))
        }
    }

    /// The directory the file's relative paths start from.
    fn base(&self) -> &Path {
        Path::new(self.file).parent().unwrap_or(Path::new(""))
    }
}

/// A `front_face` (counter-clockwise unless it says otherwise).
fn front_face(t: &Toml, value: Option<&Spanned<String>>, field: &str) -> Result<bool, SceneError> {
    match value.map(|s| (s, s.get_ref().as_str())) {
        None | Some((_, "counterclockwise")) => Ok(true),
        Some((_, "clockwise")) => Ok(false),
        Some((s, other)) => Err(t.err(
            s.span(),
            field,
            format!("must be \"counterclockwise\" or \"clockwise\", not {other:?}"),
        )),
    }
}

/// The `[camera]` table.
fn camera(t: &Toml, raw: &Spanned<CameraFile>, b: &mut SceneBuilder) -> Result<(), SceneError> {
    let cam = raw.get_ref();
    let position = t.vec(&cam.position, "camera.position")?;
    let forward = match (&cam.forward, &cam.look_at) {
        (Some(f), None) => t.vec(f, "camera.forward")?,
        (None, Some(l)) => t.vec(l, "camera.look_at")? - position,
        _ => {
            return Err(t.err(
                raw.span(),
                "camera",
                "give exactly one of `forward` and `look_at`",
            ));
        }
    };
    let up = t.vec(&cam.up, "camera.up")?;
    for (s, field) in [(&cam.width, "camera.width"), (&cam.height, "camera.height")] {
        if *s.get_ref() == 0 {
            return Err(t.err(s.span(), field, "must be at least 1"));
        }
    }
    let (width, height) = (*cam.width.get_ref(), *cam.height.get_ref());
    let focal = focal_length(t, raw, height)?;
    let at = t.origin(cam.up.span(), "camera.up");
    let view = View {
        position,
        forward,
        up,
        focal_px: focal,
        width,
        height,
    };
    b.camera(view, &at)
}

/// The camera's focal length in pixels: given, or from its vertical field
/// of view and the image height.
fn focal_length(t: &Toml, raw: &Spanned<CameraFile>, height: u32) -> Result<f32, SceneError> {
    let cam = raw.get_ref();
    match (&cam.focal_length_px, &cam.vfov_deg) {
        (Some(f), None) => {
            let v = *f.get_ref();
            if !(v.is_finite() && v > 0.0) {
                return Err(t.err(
                    f.span(),
                    "camera.focal_length_px",
                    "must be a positive number",
                ));
            }
            Ok(v)
        }
        (None, Some(a)) => {
            let v = *a.get_ref();
            if !(v > 0.0 && v < 180.0) {
                return Err(t.err(
                    a.span(),
                    "camera.vfov_deg",
                    "must be between 0 and 180 degrees",
                ));
            }
            Ok(Camera::focal_from_vfov(v, height))
        }
        _ => Err(t.err(
            raw.span(),
            "camera",
            "give exactly one of `focal_length_px` and `vfov_deg`",
        )),
    }
}

/// The `[materials]` table's names, and the index each is given.
struct Names<'a> {
    index: BTreeMap<&'a str, u32>,
}

impl Names<'_> {
    /// The index of the material `name` refers to, written as `field`.
    fn get(&self, t: &Toml, name: &Spanned<String>, field: &str) -> Result<u32, SceneError> {
        self.index
            .get(name.get_ref().as_str())
            .copied()
            .ok_or_else(|| {
                t.err(
                    name.span(),
                    field,
                    format!(
                        "no material named {:?} (the file defines: {})",
                        name.get_ref(),
                        self.index.keys().copied().collect::<Vec<_>>().join(", ")
                    ),
                )
            })
    }
}

/// The `[materials]` table, added in name order.
fn materials<'a>(
    t: &Toml,
    raw: &'a BTreeMap<String, Spanned<MaterialFile>>,
    b: &mut SceneBuilder,
) -> Result<Names<'a>, SceneError> {
    let mut index = BTreeMap::new();
    for (name, m) in raw {
        let material = material(t, name, m)?;
        index.insert(name.as_str(), b.material(material));
    }
    Ok(Names { index })
}

/// One material of the `[materials]` table.
fn material(t: &Toml, name: &str, m: &Spanned<MaterialFile>) -> Result<Material, SceneError> {
    let f = m.get_ref();
    let model = match &f.model {
        None => Model::Diffuse,
        Some(model) => Model::from_name(model.get_ref()).ok_or_else(|| {
            t.err(
                model.span(),
                &format!("materials.{name}.model"),
                format!(
                    "unknown model {:?} (known: {})",
                    model.get_ref(),
                    Model::NAMES.join(", ")
                ),
            )
        })?,
    };
    let fields = MaterialFields { t, name, model };
    let reflectance = match (&f.reflectance, model.reads("reflectance")) {
        (Some(r), false) => {
            fields.unused(Some(r.span()), "reflectance")?;
            Vec3::ONE
        }
        (Some(r), true) => fields.unit_color(r, "reflectance")?,
        (None, false) => Vec3::ONE,
        (None, true) => {
            return Err(t.err(
                m.span(),
                &format!("materials.{name}.reflectance"),
                format!("a {} material needs a reflectance", model.name()),
            ));
        }
    };
    let emission = match &f.emission {
        None => Vec3::ZERO,
        Some(e) => {
            let field = format!("materials.{name}.emission");
            let v = t.vec(e, &field)?;
            if v.min_element() < 0.0 {
                return Err(t.err(e.span(), &field, "must not be negative"));
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
    fields.glass(f, &mut material)?;
    fields.metal(f, &mut material)?;
    fields.metallic_roughness(f, &mut material)?;
    fields.transmission(f, &mut material)?;
    Ok(material)
}

/// The fields of material `name`, of model `model`.
struct MaterialFields<'a> {
    t: &'a Toml<'a>,
    name: &'a str,
    model: Model,
}

impl MaterialFields<'_> {
    /// Refuses a field the model does not read (`present`: where it is
    /// written), rather than ignoring it.
    fn unused(&self, present: Option<Range<usize>>, key: &str) -> Result<(), SceneError> {
        if self.model.reads(key) {
            return Ok(());
        }
        let models = Model::readers(key);
        match present {
            Some(span) => Err(self.t.err(
                span,
                &format!("materials.{}.{key}", self.name),
                format!(
                    "{} materials have no {key} (only {models})",
                    self.model.name()
                ),
            )),
            None => Ok(()),
        }
    }

    /// A colour of components in [0, 1].
    fn unit_color(&self, v: &Spanned<Exact<[f32; 3]>>, key: &str) -> Result<Vec3, SceneError> {
        let field = format!("materials.{}.{key}", self.name);
        let c = self.t.vec(v, &field)?;
        if c.min_element() < 0.0 || c.max_element() > 1.0 {
            return Err(self
                .t
                .err(v.span(), &field, "each component must be in [0, 1]"));
        }
        Ok(c)
    }

    /// `ior` and `transmittance` (each refused on models that do not
    /// read it).
    fn glass(&self, f: &MaterialFile, material: &mut Material) -> Result<(), SceneError> {
        self.unused(f.transmittance.as_ref().map(|v| v.span()), "transmittance")?;
        self.unused(f.ior.as_ref().map(|v| v.span()), "ior")?;
        if let Some(ior) = &f.ior {
            let v = *ior.get_ref();
            let range = super::material::IOR_RANGE;
            if !range.contains(&v) {
                return Err(self.t.err(
                    ior.span(),
                    &format!("materials.{}.ior", self.name),
                    format!(
                        "must be an index of refraction from {} to {} (e.g. 1.5 for glass), not {v}",
                        range.start(),
                        range.end()
                    ),
                ));
            }
            material.ior = v;
        }
        if let Some(tr) = &f.transmittance {
            material.transmittance = self.unit_color(tr, "transmittance")?;
        }
        Ok(())
    }

    /// `alpha` (refused on models that do not read it).
    fn metal(&self, f: &MaterialFile, material: &mut Material) -> Result<(), SceneError> {
        self.unused(f.alpha.as_ref().map(|v| v.span()), "alpha")?;
        if let Some(alpha) = &f.alpha {
            let v = *alpha.get_ref();
            if !(0.0..=1.0).contains(&v) {
                return Err(self.t.err(
                    alpha.span(),
                    &format!("materials.{}.alpha", self.name),
                    "must be a GGX roughness in [0, 1] (0: a mirror)",
                ));
            }
            material.alpha = v;
        }
        Ok(())
    }

    /// `metallic` and `roughness`, each in [0, 1] (refused on models that
    /// do not read them).
    fn metallic_roughness(
        &self,
        f: &MaterialFile,
        material: &mut Material,
    ) -> Result<(), SceneError> {
        for (key, value, slot) in [
            ("metallic", &f.metallic, &mut material.metallic),
            ("roughness", &f.roughness, &mut material.roughness),
        ] {
            let Some(value) = value else { continue };
            self.unused(Some(value.span()), key)?;
            let v = *value.get_ref();
            if !(0.0..=1.0).contains(&v) {
                return Err(self.t.err(
                    value.span(),
                    &format!("materials.{}.{key}", self.name),
                    "must be in [0, 1]",
                ));
            }
            *slot = v;
        }
        Ok(())
    }
}

impl MaterialFields<'_> {
    /// `transmission` (in [0, 1], 1 by default) and `thin` (false by
    /// default: the surface bounds a solid), refused on models that do
    /// not read them.
    fn transmission(&self, f: &MaterialFile, material: &mut Material) -> Result<(), SceneError> {
        self.unused(f.transmission.as_ref().map(|v| v.span()), "transmission")?;
        self.unused(f.thin.as_ref().map(|v| v.span()), "thin")?;
        if !self.model.reads("transmission") {
            return Ok(());
        }
        material.transmission = 1.0;
        if let Some(value) = &f.transmission {
            let v = *value.get_ref();
            if !(0.0..=1.0).contains(&v) {
                return Err(self.t.err(
                    value.span(),
                    &format!("materials.{}.transmission", self.name),
                    "must be in [0, 1]",
                ));
            }
            material.transmission = v;
        }
        material.thin = f.thin.as_ref().is_some_and(|t| *t.get_ref());
        Ok(())
    }
}

/// The `[[triangle]]`s, then the `[[quad]]`s (each split in two).
fn polygons(
    t: &Toml,
    raw: &SceneFile,
    ccw: bool,
    names: &Names,
    b: &mut SceneBuilder,
) -> Result<(), SceneError> {
    let triangles = raw.triangles.iter().enumerate().map(|(i, tr)| {
        let tr = tr.get_ref();
        let v = &tr.vertices;
        let what = format!("triangle[{i}]");
        let label = tr.name.clone().unwrap_or_else(|| what.clone());
        (what, label, &tr.material, v.span(), v.get_ref().0.to_vec())
    });
    let quads = raw.quads.iter().enumerate().map(|(i, q)| {
        let q = q.get_ref();
        let v = &q.vertices;
        let what = format!("quad[{i}]");
        (
            what.clone(),
            q.name.clone().unwrap_or(what),
            &q.material,
            v.span(),
            v.get_ref().0.to_vec(),
        )
    });
    for (what, label, material, span, verts) in triangles.chain(quads) {
        let m = names.get(t, material, &format!("{what}.material"))?;
        let verts: Vec<Vec3> = verts.into_iter().map(Vec3::from_array).collect();
        b.object(&label);
        b.polygon(&verts, ccw, m, &t.origin(span, &format!("{what}.vertices")))?;
    }
    Ok(())
}

/// One `[[mesh]]`: an OBJ file, its MTL materials (named `file:name`)
/// added to the scene's when asked for.
fn mesh(
    t: &Toml,
    i: usize,
    m: &MeshFile,
    names: &Names,
    b: &mut SceneBuilder,
) -> Result<(), SceneError> {
    let what = format!("mesh[{i}]");
    let transform = transform(t, &what, &m.scale, &m.rotate_deg, &m.translate)?;
    let ccw = front_face(t, m.front_face.as_ref(), &format!("{what}.front_face"))?;
    let place = Placement::new(transform, ccw);
    let fallback = m
        .material
        .as_ref()
        .map(|n| names.get(t, n, &format!("{what}.material")))
        .transpose()?;
    let with_mtl = m.mtl.as_ref().is_some_and(|b| *b.get_ref());
    let at = t.origin(m.file.span(), &what);
    if fallback.is_none() && !with_mtl {
        return Err(at.error(
            "give a `material`, or `mtl = true` to take materials from the OBJ's MTL files",
        ));
    }
    let path = t.base().join(m.file.get_ref());
    let obj = super::obj::load(&path, with_mtl).map_err(|e| SceneError {
        mesh: Some(Box::new(e.clone())),
        file: e.file.display().to_string(),
        line: e.line,
        column: if e.line > 0 { 1 } else { 0 },
        field: None,
        message: format!(
            "{} (the mesh of {what}, {}:{}:{})",
            e.message, at.file, at.line, at.column
        ),
    })?;
    for file in &obj.sources {
        b.source(file);
    }
    b.room_for(obj.triangles.len() as u64, "mesh", &at)?;
    let mtl_index: Vec<u32> = (obj.materials.iter())
        .map(|om| {
            let name = format!("{}:{}", m.file.get_ref(), om.name);
            b.material(Material::diffuse(&name, om.diffuse, om.emission))
        })
        .collect();
    let faces = obj.triangles.iter().zip(&obj.material).zip(&obj.normals);
    for ((tri, mat), normals) in faces {
        let mat = mat.map(|k| mtl_index[k]).or(fallback).ok_or_else(|| {
            at.error(format!(
                "{}: some faces have no material (no `usemtl`, or one its MTL files \
                 do not define) and the mesh gives no fallback `material`",
                path.display()
            ))
        })?;
        b.soup_triangle(*tri, *normals, mat, &place, &at)?;
    }
    Ok(())
}

/// One `[[generate]]` entry: a mesh made here.
fn generate(
    t: &Toml,
    i: usize,
    g: &GenerateFile,
    names: &Names,
    b: &mut SceneBuilder,
) -> Result<(), SceneError> {
    let what = format!("generate[{i}]");
    let mat = names.get(t, &g.material, &format!("{what}.material"))?;
    let n = *g.triangles.get_ref();
    let count = t.origin(g.triangles.span(), &format!("{what}.triangles"));
    if n == 0 || n > MAX_GENERATED_TRIANGLES {
        return Err(count.error(format!("must be between 1 and {MAX_GENERATED_TRIANGLES}")));
    }
    b.room_for(n, "entry", &count)?;
    let place = Placement::new(
        transform(t, &what, &g.scale, &g.rotate_deg, &g.translate)?,
        true,
    );
    let center = match &g.center {
        Some(c) => t.vec(c, &format!("{what}.center"))?,
        None => Vec3::ZERO,
    };
    let tris = generated(t, &what, g, center, n as usize)?;
    let at = t.origin(g.kind.span(), &what);
    for tri in tris {
        b.soup_triangle(tri, None, mat, &place, &at)?;
    }
    Ok(())
}

/// The triangles of `[[generate]]` entry `g` (called `what`): at least
/// `n`, of its kind, around `center`.
fn generated(
    t: &Toml,
    what: &str,
    g: &GenerateFile,
    center: Vec3,
    n: usize,
) -> Result<Vec<[Vec3; 3]>, SceneError> {
    let positive = |v: &Option<Spanned<f32>>, field: &str, default: f32, zero_ok: bool| match v {
        None => Ok(default),
        Some(s) => {
            let x = *s.get_ref();
            if x.is_finite() && (x > 0.0 || (zero_ok && x == 0.0)) {
                Ok(x)
            } else {
                let field = format!("{what}.{field}");
                Err(t.err(s.span(), &field, "must be a positive number"))
            }
        }
    };
    // A field the kind does not read is refused, not ignored.
    let unused = |span: Option<Range<usize>>, field: &str| match span {
        Some(span) => Err(t.err(
            span,
            &format!("{what}.{field}"),
            format!("`{field}` does not apply to kind {:?}", g.kind.get_ref()),
        )),
        None => Ok(()),
    };
    match g.kind.get_ref().as_str() {
        "sphere" => {
            unused(g.size.as_ref().map(|s| s.span()), "size")?;
            unused(g.height.as_ref().map(|s| s.span()), "height")?;
            unused(g.seed.as_ref().map(|s| s.span()), "seed")?;
            let radius = positive(&g.radius, "radius", 1.0, false)?;
            Ok(super::mesh::geodesic_sphere(center, radius, n))
        }
        "terrain" => {
            unused(g.radius.as_ref().map(|s| s.span()), "radius")?;
            let size = match &g.size {
                None => [1.0, 1.0],
                Some(s) => {
                    let v = s.get_ref().0;
                    if !v.iter().all(|x| x.is_finite() && *x > 0.0) {
                        let field = format!("{what}.size");
                        return Err(t.err(s.span(), &field, "must be two positive numbers"));
                    }
                    v
                }
            };
            let height = positive(&g.height, "height", 0.1, true)?;
            let seed = g.seed.as_ref().map_or(0, |s| *s.get_ref());
            Ok(super::mesh::terrain(center, size, height, n, seed))
        }
        other => Err(t.err(
            g.kind.span(),
            &format!("{what}.kind"),
            format!("unknown kind {other:?} (known: \"sphere\", \"terrain\")"),
        )),
    }
}

/// One `[[asset]]`: a mesh file read through the mesh-source seam
/// ([`mesh_source`](super::mesh_source)), its materials added to the
/// scene's (named `file:name`, mapped as an asset rendered alone maps
/// them) and its meshes placed by the entry's transform after the file's
/// own. The file's cameras and lights are not used: the scene has its own.
fn asset(t: &Toml, i: usize, a: &AssetFile, b: &mut SceneBuilder) -> Result<(), SceneError> {
    let what = format!("asset[{i}]");
    let placement = asset_placement(t, &what, a)?;
    let at = t.origin(a.file.span(), &format!("{what}.file"));
    let path = t.base().join(a.file.get_ref());
    let asset = super::mesh_source::load(&path).map_err(|e| {
        let mut err = super::asset_scene::scene_error(e);
        err.message = format!(
            "{} (the asset of {what}, {}:{}:{})",
            err.message, at.file, at.line, at.column
        );
        err
    })?;
    b.source(&path);
    b.room_for(asset.instanced_triangles() as u64, "asset", &at)?;
    super::asset_scene::place(b, &asset, placement, a.file.get_ref(), &at)
}

/// An `[[asset]]`'s placement: its `matrix` (rows; affine and
/// invertible), or its scale, rotation and translation; `None` where it
/// gives none (the file's own placement is kept exactly).
fn asset_placement(t: &Toml, what: &str, a: &AssetFile) -> Result<Option<glam::Mat4>, SceneError> {
    let trs = [
        a.scale.as_ref().map(|s| s.span()),
        a.rotate_deg.as_ref().map(|s| s.span()),
        a.translate.as_ref().map(|s| s.span()),
    ];
    let Some(matrix) = &a.matrix else {
        if trs.iter().all(Option::is_none) {
            return Ok(None);
        }
        let affine = transform(t, what, &a.scale, &a.rotate_deg, &a.translate)?;
        return Ok(Some(glam::Mat4::from(affine)));
    };
    let field = format!("{what}.matrix");
    let err = |m: &str| Err(t.err(matrix.span(), &field, m));
    if trs.iter().any(Option::is_some) {
        return err("give either `matrix` or `scale`, `rotate_deg` and `translate`, not both");
    }
    let rows = matrix.get_ref().0;
    if !rows.iter().flatten().all(|x| x.is_finite()) {
        return err("must be finite numbers");
    }
    if rows[3] != [0.0, 0.0, 0.0, 1.0] {
        return err("the last row must be [0, 0, 0, 1] (an affine transform)");
    }
    let m = glam::Mat4::from_cols_array_2d(&rows).transpose();
    if !(m.determinant() != 0.0 && m.determinant().is_finite()) {
        return err("must be invertible (its determinant is 0)");
    }
    Ok(Some(m))
}

/// One `[[sphere]]`.
fn sphere(
    t: &Toml,
    i: usize,
    sp: &SphereFile,
    names: &Names,
    b: &mut SceneBuilder,
) -> Result<(), SceneError> {
    let what = format!("sphere[{i}]");
    let center = t.vec(&sp.center, &format!("{what}.center"))?;
    let radius = *sp.radius.get_ref();
    if !(radius.is_finite() && radius > 0.0) {
        return Err(t.err(
            sp.radius.span(),
            &format!("{what}.radius"),
            "must be a positive, finite number",
        ));
    }
    let material = names.get(t, &sp.material, &format!("{what}.material"))?;
    b.sphere(center, radius, material);
    Ok(())
}

/// The `[integrator]` table: the maximum depth and the other options.
fn integrator(t: &Toml, raw: &IntegratorFile) -> Result<(u32, RenderOptions), SceneError> {
    let max_depth = *raw.max_depth.get_ref();
    if max_depth == 0 {
        return Err(t.err(
            raw.max_depth.span(),
            "integrator.max_depth",
            "must be at least 1",
        ));
    }
    let named = |v: &Option<Spanned<String>>, field: &str, known: &[&str]| match v {
        Some(n) if !known.contains(&n.get_ref().as_str()) => Err(t.err(
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
    let integrator = named(&raw.name, "integrator.name", Integrator::NAMES)?;
    let sampler = named(&raw.sampler, "integrator.sampler", SamplerKind::NAMES)?;
    let aov = match &raw.aov {
        Some(list) => Some(
            AovSet::from_names(list.get_ref().iter().map(String::as_str))
                .map_err(|message| t.err(list.span(), "integrator.aov", message))?,
        ),
        None => None,
    };
    let options = RenderOptions {
        integrator: integrator.and_then(|n| Integrator::from_name(&n)),
        sampler: sampler.and_then(|n| SamplerKind::from_name(&n)),
        rr_depth: raw.rr_depth.as_ref().map(|d| *d.get_ref()),
        aov,
        light_tree: raw.light_tree,
    };
    Ok((max_depth, options))
}

/// Scale, then rotate (about x, then y, then z, in degrees), then
/// translate; `what` names the entry.
fn transform(
    t: &Toml,
    what: &str,
    scale: &Option<Spanned<ScaleFile>>,
    rotate_deg: &Option<Spanned<Exact<[f32; 3]>>>,
    translate: &Option<Spanned<Exact<[f32; 3]>>>,
) -> Result<glam::Affine3A, SceneError> {
    let s = match scale {
        None => Vec3::ONE,
        Some(s) => {
            let v = match *s.get_ref() {
                ScaleFile::Uniform(x) => Vec3::splat(x),
                ScaleFile::PerAxis(v) => Vec3::from_array(v.0),
            };
            if !v.is_finite() || v.x * v.y * v.z == 0.0 {
                let field = format!("{what}.scale");
                return Err(t.err(s.span(), &field, "must be finite and non-zero"));
            }
            v
        }
    };
    let finite = |v: &Option<Spanned<Exact<[f32; 3]>>>, field: &str| match v {
        None => Ok(Vec3::ZERO),
        Some(v) => t.vec(v, &format!("{what}.{field}")),
    };
    let r = finite(rotate_deg, "rotate_deg")?;
    let tr = finite(translate, "translate")?;
    let rotation = glam::Quat::from_euler(
        glam::EulerRot::ZYX,
        r.z.to_radians(),
        r.y.to_radians(),
        r.x.to_radians(),
    );
    Ok(glam::Affine3A::from_scale_rotation_translation(
        s, rotation, tr,
    ))
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
