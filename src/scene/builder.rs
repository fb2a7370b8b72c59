//! The one way a [`Scene`] is built, whatever format it is written in.
//!
//! A front end (the TOML format, [`file`](super::file); an asset file
//! rendered alone, [`asset_scene`](super::asset_scene)) reads its text or
//! bytes, checks each value where it stands (so its errors name the line
//! and field, or the JSON path), and hands the scene's parts to a
//! [`SceneBuilder`]: the camera, materials, polygons, spheres and meshes,
//! each with the [`Origin`] it came from. The builder checks what concerns
//! the scene as a whole — triangles with no area, vertices a transform
//! sends past `f32`, the scene's triangle budget — and names that origin
//! when it refuses something. It also keeps the list of files the scene
//! was read from ([`Scene::sources`]).
//!
//! Meshes come in two shapes: triangle soups placed by an affine
//! transform ([`SceneBuilder::soup_triangle`], the TOML `[[mesh]]` and
//! `[[generate]]` entries), and indexed meshes placed by a matrix
//! ([`SceneBuilder::instance`], assets). Each keeps the arithmetic its
//! path has always had, so every scene's triangles come out bit for bit
//! as they did before the builder existed.

use super::asset::AssetMesh;
use super::camera::Camera;
use super::texture::Texture;
use super::{Material, RenderOptions, Scene, Sphere, Texturing, Triangle, TriangleUv};
use glam::{Mat3, Mat4, Vec3};
use std::fmt;
use std::path::{Path, PathBuf};

/// The most triangles a scene may have, all entries together: checked
/// before each mesh is added and each `[[generate]]` entry is made, so a
/// file of many large entries is refused before it fills the memory.
pub const MAX_SCENE_TRIANGLES: usize = 100_000_000;

/// A scene that cannot be used, and where the problem is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct SceneError {
    /// The file (or a label for in-memory text).
    pub file: String,
    /// 1-based line; 0 when the problem has no place in the file.
    pub line: usize,
    /// 1-based column; 0 when unknown.
    pub column: usize,
    /// The dotted path of the offending field (TOML), or the JSON path of
    /// the offending part (glTF), when known.
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

/// Where a part of a scene was written: a file, and in it a line and
/// column with a dotted field (TOML), or a JSON path (glTF), or nothing
/// more precise.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Origin {
    /// The file (or a label for in-memory text).
    pub file: String,
    /// 1-based line; 0 when there is none.
    pub line: usize,
    /// 1-based column; 0 when unknown.
    pub column: usize,
    /// The field or JSON path, when known.
    pub field: Option<String>,
}

impl Origin {
    /// The whole of `file`.
    pub fn file(file: &str) -> Self {
        Self {
            file: file.to_string(),
            ..Self::default()
        }
    }

    /// The part of `file` at JSON path (or other place name) `path`; the
    /// whole file when `path` is empty.
    pub fn path(file: &str, path: &str) -> Self {
        Self {
            file: file.to_string(),
            field: (!path.is_empty()).then(|| path.to_string()),
            ..Self::default()
        }
    }

    /// The error `message` about what is here.
    pub fn error(&self, message: impl Into<String>) -> SceneError {
        SceneError {
            file: self.file.clone(),
            line: self.line,
            column: self.column,
            field: self.field.clone(),
            message: message.into(),
            mesh: None,
        }
    }
}

/// A camera as a front end reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Where it is.
    pub position: Vec3,
    /// The viewing direction (any length but zero).
    pub forward: Vec3,
    /// A direction not parallel to `forward` that is up in the image.
    pub up: Vec3,
    /// The focal length, in pixels of the default resolution.
    pub focal_px: f32,
    /// The default image width, pixels.
    pub width: u32,
    /// The default image height, pixels.
    pub height: u32,
}

/// An affine placement of a triangle soup, with what its triangles need
/// computed once: normals go by the inverse transpose of the linear part,
/// and a mirroring transform swaps the winding, so the front stays the
/// same side of the surface.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    transform: glam::Affine3A,
    normal_matrix: glam::Mat3A,
    mirrored: bool,
    ccw: bool,
}

impl Placement {
    /// `transform`, for triangles whose front is their counter-clockwise
    /// side when `ccw` (else their clockwise side).
    pub fn new(transform: glam::Affine3A, ccw: bool) -> Self {
        Self {
            transform,
            normal_matrix: transform.matrix3.inverse().transpose(),
            mirrored: transform.matrix3.determinant() < 0.0,
            ccw,
        }
    }
}

/// A scene under construction (see the [module documentation](self)).
#[derive(Debug)]
pub struct SceneBuilder {
    name: String,
    camera: Option<Camera>,
    materials: Vec<Material>,
    triangles: Vec<Triangle>,
    /// Per-vertex normals of the triangles that have them, and zeros for
    /// the flat ones before them; filled up to every triangle at the end
    /// if any triangle has them.
    vertex_normals: Vec<[Vec3; 3]>,
    /// Texture coordinates of the triangles that have them, and zeros for
    /// the ones before them; filled up the same way.
    uv: Vec<TriangleUv>,
    /// Vertex colours of the triangles that have them, and white for the
    /// ones before them; filled up the same way.
    colours: Vec<[[f32; 4]; 3]>,
    /// World-space vertex tangents of the triangles that have them, and
    /// zeros for the ones before them; filled up the same way.
    tangents: Vec<[[f32; 4]; 3]>,
    /// The images materials' maps refer to.
    textures: Vec<Texture>,
    spheres: Vec<Sphere>,
    max_depth: u32,
    options: RenderOptions,
    sources: Vec<PathBuf>,
    environment: Option<super::environment::Environment>,
    lights: Vec<super::punctual::PunctualLight>,
    /// The objects' names, and the id of the one being added (0 before
    /// the first [`object`](Self::object)).
    object_names: Vec<String>,
    object: u32,
    /// The object id of every triangle, and of every sphere.
    triangle_objects: Vec<u32>,
    sphere_objects: Vec<u32>,
    assets: super::AssetCounts,
    /// The meshes placed so far by [`instance`](Self::instance) with a
    /// key, and their placements that the flattening kept whole.
    instancing: super::Instancing,
    /// Per mesh key: its index in `instancing.meshes`, and which of its
    /// triangles have an area in its own space.
    mesh_keys: std::collections::HashMap<u32, (u32, Vec<bool>)>,
    /// The next unused mesh key.
    next_key: u32,
}

impl SceneBuilder {
    /// An empty scene called `name` (of maximum path depth 1 until
    /// [`settings`](Self::settings) says otherwise).
    pub fn new(name: &str) -> Self {
        Self {
            name: name.to_string(),
            camera: None,
            materials: Vec::new(),
            triangles: Vec::new(),
            vertex_normals: Vec::new(),
            uv: Vec::new(),
            colours: Vec::new(),
            tangents: Vec::new(),
            textures: Vec::new(),
            spheres: Vec::new(),
            max_depth: 1,
            options: RenderOptions::default(),
            sources: Vec::new(),
            environment: None,
            lights: Vec::new(),
            object_names: Vec::new(),
            object: 0,
            triangle_objects: Vec::new(),
            sphere_objects: Vec::new(),
            assets: super::AssetCounts::default(),
            instancing: super::Instancing::default(),
            mesh_keys: std::collections::HashMap::new(),
            next_key: 0,
        }
    }

    /// Reserves `n` mesh keys for [`instance`](Self::instance); returns
    /// the first. One key names one mesh wherever it is placed.
    pub fn mesh_keys(&mut self, n: usize) -> u32 {
        let first = self.next_key;
        self.next_key += n as u32;
        first
    }

    /// The camera. A viewing direction that is zero or parallel to `up`
    /// is refused at `at`.
    pub fn camera(&mut self, view: View, at: &Origin) -> Result<(), SceneError> {
        let View {
            position,
            forward,
            up,
            focal_px,
            width,
            height,
        } = view;
        let camera =
            Camera::new(position, forward, up, focal_px, width, height).ok_or_else(|| {
                at.error("the viewing direction must be non-zero and not parallel to `up`")
            })?;
        self.camera = Some(camera);
        Ok(())
    }

    /// Adds `material`; returns its index.
    pub fn material(&mut self, material: Material) -> u32 {
        self.materials.push(material);
        (self.materials.len() - 1) as u32
    }

    /// Adds the images `textures`; returns the index of the first (what
    /// the materials that use them add to their indices).
    pub fn textures(&mut self, textures: &[Texture]) -> u32 {
        let first = self.textures.len() as u32;
        self.textures.extend_from_slice(textures);
        first
    }

    /// Counts an asset's meshes, instances and triangles (before
    /// flattening) in the scene's [`AssetCounts`](super::AssetCounts).
    pub fn count_asset(&mut self, asset: &super::asset::Asset) {
        let a = &mut self.assets;
        a.meshes += asset.meshes.len();
        a.instances += asset.instances.len();
        a.unique_triangles += asset.unique_triangles();
        a.instanced_triangles += asset.instanced_triangles();
    }

    /// The materials so far.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// The scene's default maximum path depth (the camera ray is depth
    /// 0) and its other options (integrator, sampler…).
    pub fn settings(&mut self, max_depth: u32, options: RenderOptions) {
        self.max_depth = max_depth;
        self.options = options;
    }

    /// The environment (`None`: rays that leave the scene see black); its
    /// image file, if any, is one of the scene's sources.
    pub fn environment(&mut self, env: Option<super::environment::Environment>) {
        if let Some(path) = env.as_ref().and_then(|e| e.file.clone()) {
            self.source(&path);
        }
        self.environment = env;
    }

    /// Adds a sun, point or spot light.
    pub fn light(&mut self, light: super::punctual::PunctualLight) {
        self.lights.push(light);
    }

    /// Whether some sun, point or spot light sends light.
    pub fn has_punctual_light(&self) -> bool {
        self.lights.iter().any(|l| l.emits())
    }

    /// Records that the scene was read from the file at `path`.
    pub fn source(&mut self, path: &Path) {
        if !self.sources.iter().any(|p| p == path) {
            self.sources.push(path.to_path_buf());
        }
    }

    /// The triangles so far.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Whether nothing that could be hit has been added.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty() && self.spheres.is_empty()
    }

    /// Refuses, at `at`, adding `more` triangles that would take the scene
    /// past [`MAX_SCENE_TRIANGLES`]; `what` names the entry ("mesh").
    pub fn room_for(&self, more: u64, what: &str, at: &Origin) -> Result<(), SceneError> {
        if self.triangles.len() as u64 + more > MAX_SCENE_TRIANGLES as u64 {
            return Err(at.error(format!(
                "the scene would have more than {MAX_SCENE_TRIANGLES} triangles ({} before this {what}, {more} in it)",
                self.triangles.len(),
            )));
        }
        Ok(())
    }

    /// A flat polygon of 3 or 4 `vertices` (a quad is split into two
    /// triangles, 0-1-2 and 0-2-3) whose front is its counter-clockwise
    /// side when `ccw`. Vertices that are not finite, or a triangle of no
    /// area, are refused at `at`.
    pub fn polygon(
        &mut self,
        vertices: &[Vec3],
        ccw: bool,
        material: u32,
        at: &Origin,
    ) -> Result<(), SceneError> {
        if vertices.iter().any(|v| !v.is_finite()) {
            return Err(at.error("must be finite numbers"));
        }
        let fans: &[[usize; 3]] = if vertices.len() == 4 {
            &[[0, 1, 2], [0, 2, 3]]
        } else {
            &[[0, 1, 2]]
        };
        for f in fans {
            let v = f.map(|k| vertices[k]);
            let t = if ccw {
                Triangle::ccw(v, material)
            } else {
                Triangle::cw(v, material)
            };
            if t.normal == Vec3::ZERO {
                return Err(at.error("the vertices do not span a triangle (zero area)"));
            }
            self.push(t, None, None);
        }
        Ok(())
    }

    /// Start a new object called `name`: the primitives added from now on
    /// belong to it ([`super::Objects`]). Returns its id.
    pub fn object(&mut self, name: &str) -> u32 {
        self.object_names.push(name.to_string());
        self.object = self.object_names.len() as u32;
        self.object
    }

    /// A sphere (its center finite and its radius positive, checked by
    /// the front end where they are written).
    pub fn sphere(&mut self, center: Vec3, radius: f32, material: u32) {
        self.sphere_objects.push(self.object);
        self.spheres.push(Sphere {
            center,
            radius,
            material,
        });
    }

    /// One triangle of a soup (object-space vertices `v`, the corners'
    /// unit normals if it has them), placed by `place`. A triangle of no
    /// area is skipped (it could never be hit); a vertex the placement
    /// sends past `f32` is refused at `at`.
    pub fn soup_triangle(
        &mut self,
        v: [Vec3; 3],
        normals: Option<[Vec3; 3]>,
        material: u32,
        place: &Placement,
        at: &Origin,
    ) -> Result<(), SceneError> {
        let p = v.map(|p| place.transform.transform_point3(p));
        if let Some(q) = p.iter().find(|q| !q.is_finite()) {
            return Err(at.error(format!(
                "the transform (scale, rotate_deg, translate) turns a vertex into {q}: \
                 the coordinates overflow f32"
            )));
        }
        let t = if place.ccw != place.mirrored {
            Triangle::ccw(p, material)
        } else {
            Triangle::cw(p, material)
        };
        if t.normal == Vec3::ZERO {
            return Ok(());
        }
        // World-space unit normals (a transform that makes one degenerate
        // leaves that vertex's normal zero: the interpolation then falls
        // back to the geometric normal wherever the sum degenerates).
        let normals = normals.map(|n| {
            n.map(|n| {
                let w = (place.normal_matrix * glam::Vec3A::from(n)).normalize_or_zero();
                if w.is_finite() {
                    Vec3::from(w)
                } else {
                    Vec3::ZERO
                }
            })
        });
        self.push(t, normals, None);
        Ok(())
    }

    /// An indexed mesh placed by `transform` (object to world), every
    /// triangle of material `material`: counter-clockwise triangles are
    /// the front (a mirroring transform keeps each triangle's front where
    /// the mesh has it), vertex normals go by the inverse transpose, and
    /// texture coordinates (sets 0 and 1, zero where the mesh has one set
    /// only) go with their vertices.
    /// Triangles of no area are skipped; a vertex the transform sends past
    /// `f32` is refused at `at`.
    ///
    /// `key` ([`mesh_keys`](Self::mesh_keys)) names the mesh: the
    /// placements of one key are recorded in [`Scene::instancing`] (each
    /// whose flattening kept the same triangles as the mesh has in its own
    /// space), for the accelerator to trace two-level.
    pub fn instance(
        &mut self,
        mesh: &AssetMesh,
        key: Option<u32>,
        transform: Mat4,
        material: u32,
        at: &Origin,
    ) -> Result<(), SceneError> {
        let first = self.triangles.len();
        let mut kept = Vec::new();
        self.flatten(mesh, transform, material, at, &mut kept)?;
        if let Some(key) = key {
            self.record_placement(mesh, key, transform, first, &kept);
        }
        Ok(())
    }

    /// The placement of mesh `key` whose flattened triangles start at
    /// `first`, `kept` saying which of the mesh's triangles the flattening
    /// kept: recorded in the scene's instancing where the transform is
    /// affine (with a [`PlacedMesh::remap`](super::PlacedMesh::remap)
    /// where the flattening kept other triangles than those of area in the
    /// mesh's own space).
    fn record_placement(
        &mut self,
        mesh: &AssetMesh,
        key: u32,
        transform: Mat4,
        first: usize,
        kept: &[bool],
    ) {
        let inst = &mut self.instancing;
        let (index, own) = self.mesh_keys.entry(key).or_insert_with(|| {
            let v = |t: &[u32; 3]| t.map(|i| mesh.positions[i as usize]);
            let own: Vec<bool> = (mesh.triangles.iter())
                .map(|t| Triangle::ccw(v(t), 0).normal != Vec3::ZERO)
                .collect();
            let tris = (mesh.triangles.iter().zip(&own))
                .filter(|(_, k)| **k)
                .map(|(t, _)| v(t))
                .collect();
            inst.meshes.push(tris);
            ((inst.meshes.len() - 1) as u32, own)
        });
        if transform.row(3) != glam::Vec4::W {
            return; // (not affine: flattened)
        }
        inst.instances.push(super::PlacedMesh {
            mesh: *index,
            first: first as u32,
            count: kept.iter().filter(|k| **k).count() as u32,
            to_world: glam::Affine3A::from_mat4(transform),
            remap: remap(own, kept, first as u32),
        });
    }

    /// [`instance`](Self::instance)'s flattening: the mesh's triangles in
    /// world space, `kept[j]` whether its triangle `j` was kept.
    fn flatten(
        &mut self,
        mesh: &AssetMesh,
        transform: Mat4,
        material: u32,
        at: &Origin,
        kept: &mut Vec<bool>,
    ) -> Result<(), SceneError> {
        let normal_matrix = Mat3::from_mat4(transform).inverse().transpose();
        let mirrored = Mat3::from_mat4(transform).determinant() < 0.0;
        let world: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| transform.transform_point3(*p))
            .collect();
        if let Some(p) = world.iter().find(|p| !p.is_finite()) {
            return Err(at.error(format!(
                "{}: a transformed vertex is not finite: {p}",
                mesh.name
            )));
        }
        let normals: Vec<Vec3> = mesh
            .normals
            .iter()
            .map(|n| (normal_matrix * *n).try_normalize().unwrap_or(Vec3::ZERO))
            .collect();
        // Tangents go by the transform itself; a mirroring one turns the
        // bitangent's handedness.
        let hand = if mirrored { -1.0 } else { 1.0 };
        // Room for the mesh at once (not grown by doubling, copy by copy).
        let n = mesh.triangles.len();
        self.triangles.reserve(n);
        self.triangle_objects.reserve(n);
        if !mesh.normals.is_empty() {
            self.vertex_normals.reserve(n);
        }
        if !mesh.uv0.is_empty() || !mesh.uv1.is_empty() {
            self.uv.reserve(n);
        }
        let tangents: Vec<[f32; 4]> = (mesh.tangents.iter())
            .map(|t| {
                let v = transform.transform_vector3(Vec3::new(t[0], t[1], t[2]));
                let v = v.try_normalize().unwrap_or(Vec3::ZERO);
                [v.x, v.y, v.z, if t[3] < 0.0 { -hand } else { hand }]
            })
            .collect();
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| i as usize);
            let (b, c) = if mirrored { (c, b) } else { (b, c) };
            let tri = Triangle::ccw([world[a], world[b], world[c]], material);
            kept.push(tri.normal != Vec3::ZERO);
            if tri.normal == Vec3::ZERO {
                continue;
            }
            let n = (!normals.is_empty()).then(|| [normals[a], normals[b], normals[c]]);
            let set = |coords: &[[f32; 2]]| match coords.is_empty() {
                true => [[0.0; 2]; 3],
                false => [coords[a], coords[b], coords[c]],
            };
            let textured = !mesh.uv0.is_empty() || !mesh.uv1.is_empty();
            let uv = textured.then(|| [set(&mesh.uv0), set(&mesh.uv1)]);
            self.push(tri, n, uv);
            if !mesh.colours.is_empty() {
                let c = [mesh.colours[a], mesh.colours[b], mesh.colours[c]];
                self.colours.resize(self.triangles.len() - 1, [[1.0; 4]; 3]);
                self.colours.push(c);
            }
            if !tangents.is_empty() {
                self.tangents
                    .resize(self.triangles.len() - 1, [[0.0; 4]; 3]);
                self.tangents.push([tangents[a], tangents[b], tangents[c]]);
            }
        }
        Ok(())
    }

    /// Adds a world-space triangle as it is, with its corners' normals and
    /// texture coordinates if it has them.
    pub fn push(&mut self, triangle: Triangle, normals: Option<[Vec3; 3]>, uv: Option<TriangleUv>) {
        if let Some(n) = normals {
            self.vertex_normals
                .resize(self.triangles.len(), [Vec3::ZERO; 3]);
            self.vertex_normals.push(n);
        }
        if let Some(uv) = uv {
            self.uv.resize(self.triangles.len(), [[[0.0; 2]; 3]; 2]);
            self.uv.push(uv);
        }
        self.triangles.push(triangle);
        self.triangle_objects.push(self.object);
    }

    /// The world-space bounds of the triangles so far, or `None` where
    /// there are none.
    pub fn triangle_bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for v in self.triangles.iter().flat_map(|t| t.v) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// Whether any triangle's material emits.
    pub fn has_emitting_triangle(&self) -> bool {
        self.triangles
            .iter()
            .any(|t| self.materials[t.material as usize].is_emissive())
    }

    /// The scene; a scene without a camera or without geometry is refused
    /// at `at` (front ends check both first, to say it their way).
    pub fn finish(self, at: &Origin) -> Result<Scene, SceneError> {
        let camera = self
            .camera
            .ok_or_else(|| at.error("the scene has no camera"))?;
        if self.triangles.is_empty() && self.spheres.is_empty() {
            return Err(at.error("the scene has no geometry"));
        }
        let mut vertex_normals = self.vertex_normals;
        if !vertex_normals.is_empty() {
            vertex_normals.resize(self.triangles.len(), [Vec3::ZERO; 3]);
        }
        let mut uv = self.uv;
        if !uv.is_empty() {
            uv.resize(self.triangles.len(), [[[0.0; 2]; 3]; 2]);
        }
        let mut colours = self.colours;
        if !colours.is_empty() {
            colours.resize(self.triangles.len(), [[1.0; 4]; 3]);
        }
        // Primitives added before any object form one more, "(unnamed)".
        let mut object_names = self.object_names;
        let mut of_primitive = self.triangle_objects;
        of_primitive.extend(self.sphere_objects);
        if of_primitive.contains(&0) {
            object_names.push("(unnamed)".into());
            let id = object_names.len() as u32;
            of_primitive
                .iter_mut()
                .filter(|o| **o == 0)
                .for_each(|o| *o = id);
        }
        let mut tangents = self.tangents;
        if !tangents.is_empty() {
            tangents.resize(self.triangles.len(), [[0.0; 4]; 3]);
        }
        Ok(Scene {
            name: self.name,
            camera,
            materials: self.materials,
            triangles: self.triangles,
            vertex_normals,
            texturing: Texturing {
                uv,
                colours,
                tangents,
                textures: std::sync::Arc::new(self.textures),
            },
            spheres: self.spheres,
            max_depth: self.max_depth,
            options: self.options,
            sources: self.sources,
            environment: self.environment,
            lights: self.lights,
            objects: super::Objects {
                names: object_names,
                of_primitive,
            },
            assets: self.assets,
            instancing: placed_twice(self.instancing),
        })
    }
}

/// `instancing` without the meshes placed (whole) fewer than twice: those
/// are traced flattened.
fn placed_twice(instancing: super::Instancing) -> super::Instancing {
    let mut uses = vec![0usize; instancing.meshes.len()];
    for p in &instancing.instances {
        uses[p.mesh as usize] += 1;
    }
    let mut new_index = vec![u32::MAX; uses.len()];
    let mut meshes = Vec::new();
    for (k, mesh) in instancing.meshes.into_iter().enumerate() {
        if uses[k] >= 2 {
            new_index[k] = meshes.len() as u32;
            meshes.push(mesh);
        }
    }
    let instances = (instancing.instances.into_iter())
        .filter(|p| uses[p.mesh as usize] >= 2)
        .map(|p| super::PlacedMesh {
            mesh: new_index[p.mesh as usize],
            ..p
        })
        .collect();
    super::Instancing { meshes, instances }
}

/// [`PlacedMesh::remap`](super::PlacedMesh::remap) of a placement whose
/// flattened triangles start at `first`: `own[j]` whether the mesh's
/// triangle `j` has an area in its own space (is in its tree), `kept[j]`
/// whether the flattening kept it.
fn remap(own: &[bool], kept: &[bool], first: u32) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    if own == kept {
        return out;
    }
    let (mut local, mut global) = (0u32, first);
    // What the last entry predicts for `local`: `first + local` at first.
    let mut predicted = first;
    for (&o, &k) in own.iter().zip(kept) {
        if o {
            if !k {
                out.push((local, u32::MAX));
            } else if global != predicted {
                out.push((local, global));
            }
            predicted = if k { global + 1 } else { u32::MAX };
            local += 1;
        }
        if k {
            global += 1;
        }
    }
    out
}
