//! The scene: camera, materials and triangles.
//!
//! Scenes are read from TOML files ([`file`](mod@file)); the DH2323 Cornell box is
//! built in ([`Scene::cornell`]) and is the default scene.

pub mod aov;
pub mod asset;
pub mod asset_scene;
pub mod builder;
pub mod camera;
pub mod draco;
pub mod environment;
pub mod file;
pub mod format;
pub mod gltf;
pub mod light_check;
pub mod material;
pub mod mesh;
pub mod mesh_source;
pub mod meshopt;
pub mod obj;
pub mod options;
pub mod ply;
pub mod punctual;
pub mod texture;
pub mod views_job;

use camera::Camera;
use glam::Vec3;

pub use aov::{Aov, AovDef, AovSet};
pub use builder::{Origin, SceneBuilder, SceneError};
pub use light_check::{LightWarning, UnreachedLights};
pub use material::{Material, Model};
pub use options::{Adaptive, Integrator, RenderOptions, SamplerKind};

/// The source of the built-in default scene, `scenes/cornell.toml`.
pub const CORNELL_TOML: &str = include_str!("../../scenes/cornell.toml");

/// The least `|a × b|`, relative to the longer edge's largest coordinate
/// squared, of a triangle that is not degenerate: far below what any
/// triangle of f32 vertices that is not a sliver or collinear has.
const MIN_RELATIVE_AREA: f32 = 1e-12;

/// Bytes handed to the content hash at a time ([`Scene::content_hash`]).
const HASH_CHUNK: usize = 1 << 16;

/// `normalize(a × b)`, or zero when `a` and `b` span no area. The test is
/// relative, so a triangle's size does not matter, only its shape: when
/// `a × b` overflows or its length underflows (edges longer than about
/// 10^9 or shorter than about 10^-11), the edges are first scaled so their
/// largest coordinate is 1, and the triangle is kept if the scaled cross
/// product is at least [`MIN_RELATIVE_AREA`]. Every other triangle's normal
/// is computed as before, bit for bit.
fn unit_normal(a: Vec3, b: Vec3) -> Vec3 {
    let n = a.cross(b);
    if n.is_finite() {
        let u = n.normalize_or_zero();
        if u != Vec3::ZERO {
            return u;
        }
    }
    let m = a.abs().max_element().max(b.abs().max_element());
    if !(m > 0.0 && m.is_finite()) {
        return Vec3::ZERO;
    }
    let n = (a / m).cross(b / m);
    if n.is_finite() && n.length() >= MIN_RELATIVE_AREA {
        n.normalize_or_zero()
    } else {
        Vec3::ZERO
    }
}

/// The shading normal at `p` of a triangle of vertices `v`, vertex normals
/// `n` and geometric front normal `front`: the vertex normals weighted by
/// the barycentric coordinates of `p` (computed here from `p`, clamped to
/// the triangle, so a hit point rounded just outside it stays sensible),
/// normalised, and turned to the front side (vertex normals that disagree
/// with the winding are flipped, so the shading normal always lies on the
/// geometric front). Degenerate results (zero or not finite) give `front`.
///
/// The one scalar routine both engines call for smooth triangles, so they
/// shade with the same bits.
pub fn interpolate_normal(v: [Vec3; 3], n: [Vec3; 3], front: Vec3, p: Vec3) -> Vec3 {
    let [b0, b1, b2] = barycentric(v, p);
    let m = n[0] * b0 + n[1] * b1 + n[2] * b2;
    let m = if m.dot(front) < 0.0 { -m } else { m };
    let u = m.normalize_or_zero();
    if u == Vec3::ZERO || !u.is_finite() {
        front
    } else {
        u
    }
}

/// The barycentric coordinates `[b0, b1, b2]` of the point `p` on the
/// triangle of vertices `v`, computed from `p` and clamped to the
/// triangle (a hit point rounded just outside it stays inside). The one
/// routine every per-vertex attribute is interpolated with (normals,
/// texture coordinates, colours), in both engines.
#[inline]
pub fn barycentric(v: [Vec3; 3], p: Vec3) -> [f32; 3] {
    let (e1, e2, ep) = (v[1] - v[0], v[2] - v[0], p - v[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (dp1, dp2) = (ep.dot(e1), ep.dot(e2));
    let denom = d11 * d22 - d12 * d12;
    let b1 = ((d22 * dp1 - d12 * dp2) / denom).clamp(0.0, 1.0);
    let b2 = ((d11 * dp2 - d12 * dp1) / denom).clamp(0.0, 1.0);
    let (b1, b2) = if b1 + b2 > 1.0 {
        let s = b1 + b2;
        (b1 / s, b2 / s)
    } else {
        (b1, b2)
    };
    let b0 = 1.0 - b1 - b2;
    [b0, b1, b2]
}

/// The texture coordinates at barycentric coordinates `b` of a triangle
/// whose vertices have `uv`: `uv0 b0 + uv1 b1 + uv2 b2`, per coordinate.
#[inline]
pub fn interpolate_uv(uv: [[f32; 2]; 3], [b0, b1, b2]: [f32; 3]) -> [f32; 2] {
    [0, 1].map(|c| uv[0][c] * b0 + uv[1][c] * b1 + uv[2][c] * b2)
}

/// A triangle with a material; its front side is the side `normal` points to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// The three vertices.
    pub v: [Vec3; 3],
    /// Unit geometric normal on the front (emitting) side.
    pub normal: Vec3,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// An analytic sphere with a material; its front (emitting) side is the
/// outside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// The center.
    pub center: Vec3,
    /// The radius (positive).
    pub radius: f32,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

impl Triangle {
    /// A triangle whose front is the counter-clockwise side:
    /// `normal = normalize((v1 - v0) × (v2 - v0))`.
    pub fn ccw(v: [Vec3; 3], material: u32) -> Self {
        let normal = unit_normal(v[1] - v[0], v[2] - v[0]);
        Self {
            v,
            normal,
            material,
        }
    }

    /// A triangle whose front is the clockwise side:
    /// `normal = normalize((v2 - v0) × (v1 - v0))`, the DH2323 lab's rule.
    pub fn cw(v: [Vec3; 3], material: u32) -> Self {
        let normal = unit_normal(v[2] - v[0], v[1] - v[0]);
        Self {
            v,
            normal,
            material,
        }
    }
}

/// The texture coordinates of a triangle's three vertices, for coordinate
/// sets 0 and 1: `[set][vertex] = [u, v]`.
pub type TriangleUv = [[[f32; 2]; 3]; 2];

/// Texture coordinates of triangles' vertices (glTF's `TEXCOORD_0` and
/// `TEXCOORD_1`, PLY's `u, v`, OBJ's `vt`), in the convention of
/// [`texture`]: `(0, 0)` is the top-left corner of an image.
///
/// Empty when no triangle has any (every scene without textures), else
/// one entry per triangle, in the order of [`Scene::triangles`], with
/// zeros for a triangle without. Spheres have none (their texture
/// coordinates are zero).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Texturing {
    /// Per triangle, the coordinates of its vertices `v[0..3]`, for
    /// coordinate sets 0 and 1 (set 1 is zero where the file has none).
    pub uv: Vec<TriangleUv>,
    /// Per triangle, its vertices' colours (glTF's `COLOR_0`, linear
    /// RGBA), which multiply its material's base colour; empty when no
    /// triangle has any, else white for a triangle without.
    pub colours: Vec<[[f32; 4]; 3]>,
    /// Per triangle, its vertices' world-space tangents `(x, y, z, w)`
    /// (glTF's `TANGENT`, or MikkTSpace's; `w = ±1`: the bitangent is
    /// `w · (normal × tangent)`), for normal textures; empty when no
    /// triangle has any, else zero for a triangle without.
    pub tangents: Vec<[[f32; 4]; 3]>,
    /// The images materials' [`Maps`](material::Maps) refer to, decoded
    /// (shared by the engines, not copied).
    pub textures: std::sync::Arc<Vec<texture::Texture>>,
}

impl Texturing {
    /// Whether no triangle has texture coordinates or colours, and there
    /// are no textures.
    pub fn is_empty(&self) -> bool {
        self.uv.is_empty() && self.colours.is_empty() && self.textures.is_empty()
    }
}

/// What the assets placed in a scene held, before their instances were
/// flattened into triangles (for `--stats`): zero for a scene of TOML
/// triangles, spheres and `[[mesh]]` entries alone.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AssetCounts {
    /// Meshes of the assets, each counted once (a glTF mesh primitive,
    /// a PLY file, an OBJ material group).
    pub meshes: usize,
    /// Placements of those meshes.
    pub instances: usize,
    /// Triangles counting each mesh once.
    pub unique_triangles: usize,
    /// Triangles counting each instance (what flattening made).
    pub instanced_triangles: usize,
}

/// Everything a render needs to know about the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// A short name for logs and stats.
    pub name: String,
    /// The camera and its default resolution.
    pub camera: Camera,
    /// Materials, referenced by index from the triangles.
    pub materials: Vec<Material>,
    /// The triangles.
    pub triangles: Vec<Triangle>,
    /// Per-vertex shading normals of smooth-mesh triangles (OBJ `vn`):
    /// empty when no triangle has them (every flat scene, so they cost
    /// nothing there), else one entry per triangle, in the order of
    /// `triangles`, with `[Vec3::ZERO; 3]` for a flat triangle. Unit,
    /// world-space, each vertex's normal for `v[k]`; see
    /// [`Scene::shading_normal`].
    pub vertex_normals: Vec<[Vec3; 3]>,
    /// Per-vertex texture coordinates and what textured materials read
    /// ([`Texturing`]); empty in scenes without them, where they cost
    /// nothing.
    pub texturing: Texturing,
    /// The analytic spheres. They follow the triangles in the primitive
    /// numbering of hits: sphere `k` is primitive `triangles.len() + k`.
    pub spheres: Vec<Sphere>,
    /// Default maximum path depth (the camera ray is depth 0).
    pub max_depth: u32,
    /// What the scene's `[integrator]` table asks for besides the depth.
    pub options: RenderOptions,
    /// The files the scene was read from: its scene file first, then its
    /// meshes and assets with every file they read (MTL files, a glTF's
    /// external buffers and images), in the order they were read; empty
    /// for text parsed from memory. Outputs must never be written over one
    /// of them ([`crate::fs::check_outputs`]).
    pub sources: Vec<std::path::PathBuf>,
    /// The light from infinitely far away that rays leaving the scene see
    /// (`None`: they see black).
    pub environment: Option<environment::Environment>,
    /// Sun, point and spot lights ([`punctual`]).
    pub lights: Vec<punctual::PunctualLight>,
    /// The scene's objects, for the object_id AOV: what each primitive
    /// belongs to, and their names.
    pub objects: Objects,
    /// What its assets held before flattening.
    pub assets: AssetCounts,
    /// The meshes its assets place more than once, and where
    /// (the accelerator may trace them two-level).
    pub instancing: Instancing,
}

/// The meshes an asset places more than once, kept once in their own
/// (object) space, and their placements: what a two-level accelerator
/// traces instead of the flattened triangles
/// ([`accel::scene_bvh`](crate::accel::scene_bvh) decides by a counted
/// rule). The flattened triangles stay in [`Scene::triangles`] (shading
/// and lights read them): placement `p`'s triangle `j` is
/// `triangles[p.global(j)]` (`p.first + j` but where the flattening kept
/// other slivers), the mesh's triangle `j` placed by `p.to_world` (and
/// wound the other way where it mirrors). Empty in a
/// scene with no mesh placed twice.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Instancing {
    /// Each mesh's triangles in its own space (the vertices as the file
    /// has them, counter-clockwise from the front), those of no area left
    /// out as the flattening leaves them out.
    pub meshes: Vec<Vec<[Vec3; 3]>>,
    /// The placements, in the order of their triangles.
    pub instances: Vec<PlacedMesh>,
}

/// One placement of a mesh of [`Instancing`].
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedMesh {
    /// Index into [`Instancing::meshes`].
    pub mesh: u32,
    /// The index in [`Scene::triangles`] of its first triangle.
    pub first: u32,
    /// How many triangles the flattening made of it (from `first` on).
    pub count: u32,
    /// Object to world.
    pub to_world: glam::Affine3A,
    /// Where the flattening kept other triangles than those of
    /// [`Instancing::meshes`] (a sliver of no area in one space and some
    /// in the other): empty where mesh triangle `j` is `first + j`; else
    /// entries `(j, g)` in increasing `j`, each saying that from mesh
    /// triangle `j` on (up to the next entry) triangle `j + i` is
    /// `triangles[g + i]`, or, where `g` is `u32::MAX`, that triangle `j`
    /// alone was left out of the flattening. Flattened triangles that no
    /// mesh triangle names are traced as the rest of the scene is.
    pub remap: Vec<(u32, u32)>,
}

impl PlacedMesh {
    /// The index in [`Scene::triangles`] of mesh triangle `j` of this
    /// placement, or `None` where the flattening left it out.
    pub fn global(&self, j: u32) -> Option<u32> {
        global_of(self.first, &self.remap, j)
    }
}

/// [`PlacedMesh::global`] of a placement's `first` and `remap`.
#[inline]
pub fn global_of(first: u32, remap: &[(u32, u32)], j: u32) -> Option<u32> {
    match remap.partition_point(|e| e.0 <= j).checked_sub(1) {
        None => Some(first + j),
        Some(k) => {
            let (from, g) = remap[k];
            // A left-out entry covers `from` alone: the next starts at
            // `from + 1`.
            (g != u32::MAX).then(|| g + (j - from))
        }
    }
}

impl Instancing {
    /// Triangles counting each mesh once.
    pub fn unique_triangles(&self) -> usize {
        self.meshes.iter().map(Vec::len).sum()
    }

    /// Triangles counting each placement.
    pub fn placed_triangles(&self) -> usize {
        self.instances.iter().map(|p| p.count as usize).sum()
    }
}

/// A scene's objects (what the object_id AOV tells apart): one per entry
/// of a scene file (`[[triangle]]`, `[[quad]]`, `[[sphere]]`, `[[mesh]]`,
/// `[[generate]]`, named by their `name`, else `quad[3]`…) and one per
/// node of a glTF asset (every primitive of its mesh), numbered from 1 in
/// the order they are read (0 is the background).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Objects {
    /// Object `k`'s name is `names[k - 1]`: an entry's `name`, else
    /// `sphere[2]`, `mesh[0]`…; `FILE/NODE` for a node of an `[[asset]]`;
    /// a glTF node's name (else its mesh's, else `node N`).
    pub names: Vec<String>,
    /// The id of each primitive's object, triangles then spheres (the
    /// primitive numbering of hits).
    pub of_primitive: Vec<u32>,
}

impl Objects {
    /// The id → name legend: `(id, name)` for every object.
    pub fn legend(&self) -> impl Iterator<Item = (u32, &str)> {
        (self.names.iter())
            .enumerate()
            .map(|(k, n)| (k as u32 + 1, n.as_str()))
    }

    /// The name of object `id` (`None` for 0, the background, or an id
    /// beyond the last).
    pub fn name(&self, id: u32) -> Option<&str> {
        let k = (id as usize).checked_sub(1)?;
        self.names.get(k).map(String::as_str)
    }
}

impl Scene {
    /// The DH2323 Cornell box (`scenes/cornell.toml`, built in).
    pub fn cornell() -> Self {
        file::parse(CORNELL_TOML, "scenes/cornell.toml")
            .expect("the built-in Cornell box scene parses")
    }

    /// Read a scene from a TOML file.
    pub fn load(path: &std::path::Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            mesh: None,
            file: path.display().to_string(),
            line: 0,
            column: 0,
            field: None,
            message: format!("cannot read the scene file: {e}"),
        })?;
        let mut scene = file::parse(&text, &path.display().to_string())?;
        scene.sources.insert(0, path.to_path_buf());
        Ok(scene)
    }

    /// Whether the environment is not visible to camera rays (`visible =
    /// false`, or [`make_transparent`](Self::make_transparent)): renders
    /// of such a scene record the alpha AOV
    /// ([`crate::render::RenderSettings::for_scene`]).
    pub fn has_transparent_background(&self) -> bool {
        self.environment.as_ref().is_some_and(|e| !e.visible)
    }

    /// Make the background transparent (`--transparent`): the environment
    /// (if any) lights the scene but camera rays that leave it see black,
    /// and the scene's AOVs include alpha.
    pub fn make_transparent(&mut self) {
        if let Some(env) = &mut self.environment {
            env.visible = false;
        }
        self.options.aov = Some(self.options.aov.unwrap_or_default().with(Aov::Alpha));
    }

    /// The corners of the box around the scene's triangles and spheres
    /// (the origin alone for an empty scene).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (mut lo, mut hi) = (Vec3::ZERO, Vec3::ZERO);
        let mut first = true;
        let mut add = |a: Vec3, b: Vec3| {
            if first {
                (lo, hi, first) = (a, b, false);
            } else {
                (lo, hi) = (lo.min(a), hi.max(b));
            }
        };
        for t in &self.triangles {
            for v in t.v {
                add(v, v);
            }
        }
        for s in &self.spheres {
            add(s.center - s.radius, s.center + s.radius);
        }
        (lo, hi)
    }

    /// Light the scene by `env` (replacing its environment), its image
    /// file counted among the scene's sources.
    pub fn set_environment(&mut self, env: environment::Environment) {
        if let Some(path) = &env.file
            && !self.sources.contains(path)
        {
            self.sources.push(path.clone());
        }
        self.environment = Some(env);
    }

    /// The largest absolute coordinate of any vertex (at least 1).
    pub fn extent(&self) -> f32 {
        let spheres = self
            .spheres
            .iter()
            .map(|s| (s.center.abs() + s.radius).max_element());
        self.triangles
            .iter()
            .flat_map(|t| t.v)
            .map(|v| v.abs().max_element())
            .chain(spheres)
            .fold(1.0, f32::max)
    }

    /// The number of primitives of every kind (triangles, then spheres,
    /// as hits number them).
    pub fn primitive_count(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }

    /// The material of primitive `i` (triangles, then spheres).
    pub fn primitive_material(&self, i: usize) -> u32 {
        match self.triangles.get(i) {
            Some(t) => t.material,
            None => self.spheres[i - self.triangles.len()].material,
        }
    }

    /// Balls (center, radius) that hold primitive `i`'s points, for the
    /// light check ([`Scene::light_warning`]): a triangle's vertices
    /// (radius 0), a sphere itself.
    pub fn primitive_balls(&self, i: usize) -> impl Iterator<Item = (Vec3, f32)> + '_ {
        let (triangle, sphere) = match self.triangles.get(i) {
            Some(t) => (Some(t), None),
            None => (None, Some(&self.spheres[i - self.triangles.len()])),
        };
        let vertices = triangle.into_iter().flat_map(|t| t.v.map(|v| (v, 0.0)));
        vertices.chain(sphere.map(|s| (s.center, s.radius)))
    }

    /// Whether some point of the ball of center `p` and radius `r` lies
    /// more than `eps` in front of primitive `i`'s front (emitting) side:
    /// in front of a triangle's plane, outside a sphere.
    pub fn in_front_of(&self, i: usize, (p, r): (Vec3, f32), eps: f32) -> bool {
        match self.triangles.get(i) {
            Some(t) => t.normal.dot(p - t.v[0]) + r > eps,
            None => {
                let s = &self.spheres[i - self.triangles.len()];
                (p - s.center).length() + r > s.radius + eps
            }
        }
    }

    /// The scale of primitive `i` (triangles, then spheres, as hits number
    /// them): the largest absolute coordinate of a triangle's vertices, or
    /// of a sphere's points (`|center| + radius`, per axis). What the
    /// rounding of a hit on it is proportional to, beside the ray's own
    /// coordinates ([`crate::integrator::offset`]).
    pub fn primitive_scale(&self, i: usize) -> f32 {
        match self.triangles.get(i) {
            Some(t) => {
                t.v.iter()
                    .map(|v| v.abs().max_element())
                    .fold(0.0, f32::max)
            }
            None => {
                let s = &self.spheres[i - self.triangles.len()];
                (s.center.abs() + s.radius).max_element()
            }
        }
    }

    /// The shading normal of triangle `i` at the point `p` on it, on its
    /// front side: its vertex normals interpolated ([`interpolate_normal`]),
    /// or `None` for a flat triangle (then the geometric normal shades).
    #[inline]
    pub fn shading_normal(&self, i: usize, p: Vec3) -> Option<Vec3> {
        let n = self.vertex_normals.get(i)?;
        if *n == [Vec3::ZERO; 3] {
            return None;
        }
        let t = &self.triangles[i];
        Some(interpolate_normal(t.v, *n, t.normal, p))
    }

    /// The texture coordinates (sets 0 and 1) of triangle `i` at the point
    /// `p` on it: its vertices' coordinates interpolated at the
    /// [`barycentric`] coordinates of `p`, or `None` where the scene has
    /// none (then they are zero).
    #[inline]
    pub fn texcoords(&self, i: usize, p: Vec3) -> Option<[[f32; 2]; 2]> {
        let uv = self.texturing.uv.get(i)?;
        let b = barycentric(self.triangles[i].v, p);
        Some(uv.map(|set| interpolate_uv(set, b)))
    }

    /// A 128-bit hash of everything in the scene that changes an image:
    /// geometry, materials and camera (not the name).
    pub fn content_hash(&self) -> u128 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        // The numbers go to the hash 64 KiB at a time: XXH3's digest does
        // not depend on how its input is cut, and an `update` per number
        // cost more than reading a 100k-triangle glTF file.
        let mut buf = Vec::with_capacity(HASH_CHUNK);
        let mut put = |v: Vec3| {
            for c in v.to_array() {
                buf.extend_from_slice(&c.to_bits().to_le_bytes());
            }
            if buf.len() >= HASH_CHUNK {
                h.update(&buf);
                buf.clear();
            }
        };
        let c = &self.camera;
        for v in [c.position, c.forward, c.up, c.right] {
            put(v);
        }
        put(Vec3::new(
            c.focal_length_px,
            c.width as f32,
            c.height as f32,
        ));
        for m in &self.materials {
            put(m.reflectance);
            put(m.emission);
            m.model_words().into_iter().for_each(&mut put);
        }
        for t in &self.triangles {
            for v in t.v {
                put(v);
            }
            put(t.normal);
            put(Vec3::splat(t.material as f32));
        }
        // (Scenes without vertex normals hash as before they existed.)
        for n in &self.vertex_normals {
            for v in n {
                put(*v);
            }
        }
        // (Scenes without texture coordinates hash as before they existed.)
        for sets in &self.texturing.uv {
            for set in sets {
                put(Vec3::new(set[0][0], set[0][1], set[1][0]));
                put(Vec3::new(set[1][1], set[2][0], set[2][1]));
            }
        }
        for c in &self.texturing.colours {
            for v in c {
                put(Vec3::new(v[0], v[1], v[2]));
                put(Vec3::new(v[3], -2.0, 0.0));
            }
        }
        for c in &self.texturing.tangents {
            for v in c {
                put(Vec3::new(v[0], v[1], v[2]));
                put(Vec3::new(v[3], -3.0, 0.0));
            }
        }
        // (Scenes without spheres hash as before spheres existed.)
        for s in &self.spheres {
            put(s.center);
            put(Vec3::new(s.radius, s.material as f32, -1.0));
        }
        h.update(&buf);
        for t in self.texturing.textures.iter() {
            for k in [t.width() as u64, t.height() as u64, t.is_srgb() as u64] {
                h.update(&k.to_le_bytes());
            }
            t.for_each_row(|row| h.update(row));
        }
        // (Scenes without an environment hash as before it existed.)
        if let Some(e) = &self.environment {
            e.hash_into(&mut h);
        }
        // (Scenes without punctual lights hash as before they existed.)
        for l in &self.lights {
            l.hash_into(&mut h);
        }
        // (Scenes that leave the light tree to the counted rule hash as
        // before it existed.)
        if let Some(tree) = self.options.light_tree {
            h.update(if tree {
                b"light tree on"
            } else {
                b"light tree of"
            });
        }
        h.digest128()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The content hash is fed in chunks ([`HASH_CHUNK`]): a number in
    /// the first, a middle or the last (partial) chunk still changes it.
    #[test]
    fn content_hash_sees_every_number_however_it_is_chunked() {
        let mut scene = Scene::cornell();
        let t = scene.triangles[0];
        // 15 numbers of 4 bytes per triangle: a few chunks and a part.
        let n = 3 * HASH_CHUNK / 60 + 7;
        scene.triangles.extend((0..n).map(|i| Triangle {
            v: t.v.map(|v| v + Vec3::splat(i as f32)),
            ..t
        }));
        let h = scene.content_hash();
        for i in [0, scene.triangles.len() / 2, scene.triangles.len() - 1] {
            let mut moved = scene.clone();
            moved.triangles[i].v[2].x += 1.0;
            assert_ne!(moved.content_hash(), h, "triangle {i} is not hashed");
        }
    }
}
