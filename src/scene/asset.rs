//! Assets read from files other renderers write (glTF 2.0, PLY): the one
//! intermediate form both loaders produce, before a scene is built from
//! it.
//!
//! An [`Asset`] keeps each mesh once and places it by [`Instance`]s (a
//! glTF mesh used by several nodes is read once); its materials are glTF's
//! metallic-roughness model with their textures, decoded once at load.
//! Loaders print nothing: what they skipped or ignored comes back in
//! [`Asset::warnings`].

use super::texture::{Texture, TextureRef};
use glam::{Mat4, Vec3};
use std::fmt;

/// Why an asset could not be read: the file, the place in it (a JSON path
/// such as `meshes[0].primitives[1].attributes.POSITION`, or a PLY line),
/// and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AssetError {
    /// The file.
    pub file: String,
    /// Where in the file (a JSON path or `line N`; empty for the whole
    /// file).
    pub at: String,
    /// What is wrong.
    pub message: String,
}

impl AssetError {
    /// An error at `at` in `file`.
    pub fn new(file: &str, at: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            file: file.to_string(),
            at: at.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for AssetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.at.is_empty() {
            write!(f, "{}: {}", self.file, self.message)
        } else {
            write!(f, "{}: {}: {}", self.file, self.at, self.message)
        }
    }
}

impl std::error::Error for AssetError {}

/// A triangle mesh: vertex attributes (all of one length) and triangles
/// of vertex indices (each in range).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AssetMesh {
    /// A name for messages: the file's, or `mesh 3 primitive 1`.
    pub name: String,
    /// Positions (finite).
    pub positions: Vec<Vec3>,
    /// Vertex normals, or empty (then the mesh is flat).
    pub normals: Vec<Vec3>,
    /// Texture coordinates `TEXCOORD_0` (or PLY's `u, v`), or empty.
    pub uv0: Vec<[f32; 2]>,
    /// Texture coordinates `TEXCOORD_1`, or empty.
    pub uv1: Vec<[f32; 2]>,
    /// Tangents `(x, y, z, w)`, `w = ±1` the handedness of the bitangent
    /// `w · (normal × tangent)`, or empty: the file's, or MikkTSpace's
    /// where a normal texture needs them.
    pub tangents: Vec<[f32; 4]>,
    /// Vertex colours `COLOR_0` (linear RGBA), or empty.
    pub colours: Vec<[f32; 4]>,
    /// Triangles, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Index into [`Asset::materials`], or `None` for
    /// [`Asset::default_material`].
    pub material: Option<u32>,
}

/// A mesh placed in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index into [`Asset::meshes`].
    pub mesh: u32,
    /// Object to world (finite).
    pub transform: Mat4,
}

/// How a material's alpha is used.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored: the surface is there.
    #[default]
    Opaque,
    /// The surface is there where alpha ≥ the cutoff.
    Mask(f32),
    /// The surface is there with probability alpha.
    Blend,
}

/// glTF 2.0's metallic-roughness material with the extensions wavetrace
/// reads (`KHR_materials_emissive_strength` folded into
/// [`emissive`](Self::emissive), `KHR_materials_ior`,
/// `KHR_materials_specular`, `KHR_materials_transmission`,
/// `KHR_materials_volume`).
#[derive(Clone, Debug, PartialEq)]
pub struct PbrMaterial {
    /// The file's name for it.
    pub name: String,
    /// Base colour factor (linear RGBA).
    pub base_colour: [f32; 4],
    /// Base colour texture (sRGB; multiplies the factor).
    pub base_colour_texture: Option<TextureRef>,
    /// Metalness factor.
    pub metallic: f32,
    /// Roughness factor (α = roughness²).
    pub roughness: f32,
    /// Metallic-roughness texture (linear; B = metal, G = roughness).
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Normal texture (linear; its `scale` in [`TextureRef::scale`]).
    pub normal_texture: Option<TextureRef>,
    /// Emitted radiance factor, times `KHR_materials_emissive_strength`.
    pub emissive: [f32; 3],
    /// Emissive texture (sRGB; multiplies the factor).
    pub emissive_texture: Option<TextureRef>,
    /// Alpha mode.
    pub alpha_mode: AlphaMode,
    /// Whether both sides are rendered (else back faces are culled).
    pub double_sided: bool,
    /// Index of refraction (`KHR_materials_ior`; 1.5 without).
    pub ior: f32,
    /// `KHR_materials_specular`: specular factor and colour (1 and white
    /// without).
    pub specular: f32,
    /// `KHR_materials_specular`'s colour.
    pub specular_colour: [f32; 3],
    /// `KHR_materials_specular`'s `specularTexture` (linear; A multiplies
    /// the factor).
    pub specular_texture: Option<TextureRef>,
    /// `KHR_materials_specular`'s `specularColorTexture` (sRGB; RGB
    /// multiplies the colour).
    pub specular_colour_texture: Option<TextureRef>,
    /// `KHR_materials_transmission`'s factor (0 without).
    pub transmission: f32,
    /// `KHR_materials_transmission`'s texture (linear; R multiplies the
    /// factor).
    pub transmission_texture: Option<TextureRef>,
    /// `KHR_materials_volume`'s thickness factor (0: thin-walled).
    pub thickness: f32,
    /// `KHR_materials_volume`'s attenuation colour (linear RGB in
    /// `[0, 1]`; white without).
    pub attenuation_colour: [f32; 3],
    /// `KHR_materials_volume`'s attenuation distance (positive; infinite
    /// without: no absorption).
    pub attenuation_distance: f32,
}

impl PbrMaterial {
    /// glTF's default material: white, fully metallic, fully rough.
    pub const DEFAULT: Self = Self {
        name: String::new(),
        base_colour: [1.0; 4],
        base_colour_texture: None,
        metallic: 1.0,
        roughness: 1.0,
        metallic_roughness_texture: None,
        normal_texture: None,
        emissive: [0.0; 3],
        emissive_texture: None,
        alpha_mode: AlphaMode::Opaque,
        double_sided: false,
        ior: 1.5,
        specular: 1.0,
        specular_colour: [1.0; 3],
        specular_texture: None,
        specular_colour_texture: None,
        transmission: 0.0,
        transmission_texture: None,
        thickness: 0.0,
        attenuation_colour: [1.0; 3],
        attenuation_distance: f32::INFINITY,
    };
}

impl Default for PbrMaterial {
    /// [`PbrMaterial::DEFAULT`].
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// A perspective camera from the file.
#[derive(Clone, Debug, PartialEq)]
pub struct AssetCamera {
    /// The file's name for it (or `camera N`).
    pub name: String,
    /// Camera to world: it looks down its −Z axis, +Y up.
    pub transform: Mat4,
    /// The vertical field of view, radians.
    pub yfov: f32,
    /// The aspect ratio the file fixes, if any.
    pub aspect_ratio: Option<f32>,
}

/// What a loader read.
#[derive(Clone, Debug, Default)]
pub struct Asset {
    /// Meshes, each stored once.
    pub meshes: Vec<AssetMesh>,
    /// Placements of the meshes.
    pub instances: Vec<Instance>,
    /// The glTF node of each instance (an index into `node_names`), in
    /// the order of `instances`; empty when the loader has no nodes (OBJ,
    /// PLY). What the object_id AOV tells apart.
    pub instance_nodes: Vec<u32>,
    /// The name of each glTF node (its own, else its mesh's, else
    /// `node N`).
    pub node_names: Vec<String>,
    /// Materials.
    pub materials: Vec<PbrMaterial>,
    /// Textures, decoded.
    pub textures: Vec<Texture>,
    /// Perspective cameras, in the file's order of nodes.
    pub cameras: Vec<AssetCamera>,
    /// Sun, point and spot lights (glTF's `KHR_lights_punctual`), placed
    /// by their nodes, in wavetrace's radiometric units.
    pub lights: Vec<super::punctual::PunctualLight>,
    /// What was skipped or ignored (one line each).
    pub warnings: Vec<String>,
    /// The material of meshes without one: glTF's default (white,
    /// metallic 1, roughness 1) unless the loader sets another.
    pub default_material: PbrMaterial,
    /// The files read besides the asset's own (a glTF's external buffers
    /// and images).
    pub sources: Vec<std::path::PathBuf>,
}

impl Asset {
    /// Triangles counting each mesh once.
    pub fn unique_triangles(&self) -> usize {
        self.meshes.iter().map(|m| m.triangles.len()).sum()
    }

    /// Triangles counting each instance.
    pub fn instanced_triangles(&self) -> usize {
        self.instances
            .iter()
            .map(|i| self.meshes[i.mesh as usize].triangles.len())
            .sum()
    }

    /// The memory the textures take, in bytes.
    pub fn texture_bytes(&self) -> usize {
        self.textures.iter().map(Texture::bytes).sum()
    }

    /// The world-space bounds of every instance's vertices, or `None`
    /// where there are none.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for i in &self.instances {
            for p in &self.meshes[i.mesh as usize].positions {
                let q = i.transform.transform_point3(*p);
                lo = lo.min(q);
                hi = hi.max(q);
            }
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }
}
