//! A scene from an asset file alone (`wavetrace model.glb`, `model.gltf`,
//! `scan.ply`): the asset's instances flattened into world-space
//! triangles, its camera (or one that frames it), and the default
//! environment where it has no light.
//!
//! **Materials.** Each [`PbrMaterial`] becomes a
//! [`Model::MetallicRoughness`] material (glTF's Appendix B, in both
//! engines) of its base colour, metalness and roughness factors, with its
//! base colour and metallic-roughness textures as [`Maps`] and the
//! vertex colours `COLOR_0` (looked up per hit), its `alphaMode` as
//! the material's [`Coverage`] (cut-outs in both engines), and its
//! emissive texture as [`Maps::emissive`] (emission looked up per hit and
//! per light sample; the material's constant emission is the factor ×
//! the texture's mean, what light sampling picks emitters by).
//! `KHR_materials_transmission` makes it a [`Model::Transmission`]
//! material (the same, with a rough or smooth dielectric interface of the
//! `KHR_materials_ior` index and the material's roughness in place of part
//! of the diffuse lobe; the transmission texture's R looked up per hit),
//! thin-walled without `KHR_materials_volume` or with a thickness of 0,
//! the boundary of a solid otherwise; a smooth, fully transmitting,
//! untextured solid of the default specular is [`Model::Glass`], the same
//! scattering as a delta model. `KHR_materials_ior` and
//! `KHR_materials_specular` (factors and textures as [`Maps`]) set the
//! dielectric Fresnel term; `KHR_materials_volume`'s attenuation makes a
//! solid absorb ([`Material::absorbs`]). Normal textures bend the
//! shading normal ([`Maps::normal`]) where the mesh has tangents (the
//! file's, or generated).
//!
//! **Defaults.** Without a camera in the file: one looking at the centre
//! of the bounds from the direction [`DEFAULT_VIEW`] (front, right, above;
//! glTF's +Y is up and +Z faces the viewer), far enough that the bounding
//! sphere fills a vertical field of view of [`DEFAULT_VFOV_DEG`]. Without
//! an emitter: the default environment
//! ([`environment::default_sky`](super::environment::default_sky), a
//! uniform white sky of radiance 1), which the render command announces.
//! Images are [`DEFAULT_HEIGHT`] pixels high, as wide as the camera's
//! aspect ratio (4:3 where the file fixes none).

use super::asset::{AlphaMode, Asset, AssetError, PbrMaterial};
use super::builder::{Origin, SceneBuilder, View};
use super::camera::Camera;
use super::material::{Coverage, IOR_RANGE, Maps, SMOOTH_ALPHA};
use super::texture::TextureRef;
use super::{Material, Model, RenderOptions, Scene, SceneError};
use glam::{Mat4, Vec3};
use std::path::Path;

/// The direction the default camera looks from (towards the asset).
pub const DEFAULT_VIEW: Vec3 = Vec3::new(0.6, 0.5, 1.0);

/// The default camera's vertical field of view, degrees.
pub const DEFAULT_VFOV_DEG: f32 = 40.0;

/// The default image height, pixels.
pub const DEFAULT_HEIGHT: u32 = 480;

/// The maximum path depth of an asset's scene.
pub const ASSET_MAX_DEPTH: u32 = 5;

/// Whether `path` names an asset file rendered alone (by its extension:
/// [`MESH_FORMATS`](super::mesh_source::MESH_FORMATS)).
pub fn is_asset(path: &Path) -> bool {
    super::mesh_source::format_of(path).is_some_and(|f| f.renders_alone)
}

/// The scene error of asset error `e`: its file, and its place in the
/// file (a JSON path or a line) as the field.
pub fn scene_error(e: AssetError) -> SceneError {
    Origin::path(&e.file, &e.at).error(e.message)
}

/// Reads the asset at `path` (glTF, GLB or PLY) and makes its scene, with
/// the camera named or numbered `camera` (the first by default). Returns
/// the loader's warnings beside the scene.
pub fn load(path: &Path, camera: Option<&str>) -> Result<(Scene, Vec<String>), SceneError> {
    let asset = super::mesh_source::load(path).map_err(scene_error)?;
    let name = path
        .file_stem()
        .map_or("asset".into(), |s| s.to_string_lossy().into_owned());
    let mut scene = scene_from_asset(&asset, &name, &path.display().to_string(), camera)?;
    scene.sources.insert(0, path.to_path_buf());
    Ok((scene, asset.warnings))
}

/// The mean decoded colour of texture `t` of `asset` (RGB).
fn texture_mean(asset: &Asset, t: u32) -> Vec3 {
    let tex = &asset.textures[t as usize];
    let mut sum = [0.0f64; 3];
    for j in 0..tex.height() {
        for i in 0..tex.width() {
            let c = tex.texel(i, j);
            for k in 0..3 {
                sum[k] += c[k] as f64;
            }
        }
    }
    let n = (tex.width() * tex.height()) as f64;
    Vec3::new(
        (sum[0] / n) as f32,
        (sum[1] / n) as f32,
        (sum[2] / n) as f32,
    )
}

/// The material of `m`, its textures numbered from `first_texture` in
/// the scene: [`Model::MetallicRoughness`] of its base colour, metalness
/// and roughness factors, with its base colour and metallic-roughness
/// textures as [`Maps`] (looked up per hit by both engines); see the
/// module documentation for what is not yet evaluated per hit.
pub fn material(asset: &Asset, m: &PbrMaterial, first_texture: u32) -> Material {
    let base = Vec3::new(m.base_colour[0], m.base_colour[1], m.base_colour[2]);
    let mut emission = Vec3::from(m.emissive);
    if let Some(t) = m.emissive_texture {
        emission *= texture_mean(asset, t.texture);
    }
    let base = base.clamp(Vec3::ZERO, Vec3::ONE);
    let mut out = Material::diffuse(&m.name, base, emission.max(Vec3::ZERO));
    let scene_ref = |t: TextureRef| TextureRef {
        texture: first_texture + t.texture,
        ..t
    };
    if let Some(t) = m.emissive_texture
        && out.is_emissive()
    {
        out.maps.emissive = Some(scene_ref(t));
        out.maps.emissive_factor = Vec3::from(m.emissive).max(Vec3::ZERO);
    }
    out.maps.normal = m.normal_texture.map(scene_ref);
    out.attenuation_colour = Vec3::from(m.attenuation_colour);
    out.attenuation_distance = m.attenuation_distance;
    if is_plain_glass(m) {
        out.model = Model::Glass;
        out.ior = m.ior;
        out.transmittance = base;
        return out;
    }
    out.model = Model::MetallicRoughness;
    out.metallic = m.metallic.clamp(0.0, 1.0);
    out.roughness = m.roughness.clamp(0.0, 1.0);
    // KHR_materials_ior and _specular: the dielectric Fresnel term (an
    // index of 0 is the specification's F0 = 1).
    out.ior = m.ior.max(0.0);
    out.specular = m.specular.clamp(0.0, 1.0);
    out.specular_colour = Vec3::from(m.specular_colour).max(Vec3::ZERO);
    out.maps = Maps {
        base_colour: m.base_colour_texture.map(scene_ref),
        metallic_roughness: m.metallic_roughness_texture.map(scene_ref),
        specular: m.specular_texture.map(scene_ref),
        specular_colour: m.specular_colour_texture.map(scene_ref),
        ..out.maps
    };
    out.opacity = m.base_colour[3].clamp(0.0, 1.0);
    out.coverage = match m.alpha_mode {
        AlphaMode::Opaque => Coverage::Opaque,
        AlphaMode::Mask(cutoff) => Coverage::Mask(cutoff),
        AlphaMode::Blend => Coverage::Blend,
    };
    if m.transmission > 0.0 && m.ior > 0.0 {
        out.model = Model::Transmission;
        out.transmission = m.transmission.clamp(0.0, 1.0);
        out.ior = m.ior.clamp(*IOR_RANGE.start(), *IOR_RANGE.end());
        out.thin = m.thickness <= 0.0; // (thickness is finite: the loader checks)
        out.maps.transmission = m.transmission_texture.map(scene_ref);
    }
    out
}

/// Whether `m` is a smooth, fully transmitting dielectric solid without
/// textures on its scattering (transmission 1, metalness 0, roughness² below
/// [`SMOOTH_ALPHA`], a `KHR_materials_volume` thickness above 0, an index
/// of refraction in [`IOR_RANGE`], the default `KHR_materials_specular`):
/// [`Model::Glass`] of its index and base
/// colour, which is what [`Model::Transmission`] computes for it, as a
/// delta model (no light sampling at its surface).
fn is_plain_glass(m: &PbrMaterial) -> bool {
    m.transmission >= 1.0
        && m.metallic <= 0.0
        && m.roughness * m.roughness < SMOOTH_ALPHA
        && m.thickness > 0.0
        && IOR_RANGE.contains(&m.ior)
        && m.base_colour_texture.is_none()
        && m.metallic_roughness_texture.is_none()
        && m.transmission_texture.is_none()
        && m.alpha_mode == AlphaMode::Opaque
        && m.specular == 1.0
        && m.specular_colour == [1.0; 3]
        && m.specular_texture.is_none()
        && m.specular_colour_texture.is_none()
}

/// Adds `asset` to the scene `b` builds: its textures, its materials
/// ([`material`]; named `prefix:name` where `prefix` is not empty),
/// then the default material, then every instance's triangles in world
/// space, each instance placed by `placement` after its own transform
/// (`None`: as the file places it). `at` is where the asset is named, for
/// errors.
pub fn place(
    b: &mut SceneBuilder,
    asset: &Asset,
    placement: Option<Mat4>,
    prefix: &str,
    at: &Origin,
) -> Result<(), SceneError> {
    let named = |m: Material| match prefix {
        "" => m,
        p => Material {
            name: format!("{p}:{}", m.name),
            ..m
        },
    };
    for file in &asset.sources {
        b.source(file);
    }
    b.count_asset(asset);
    let first = b.materials().len() as u32;
    let first_texture = b.textures(&asset.textures);
    for m in &asset.materials {
        b.material(named(material(asset, m, first_texture)));
    }
    let default = PbrMaterial {
        name: "default".into(),
        ..asset.default_material.clone()
    };
    let default_material = b.material(named(material(asset, &default, first_texture)));
    // One object per glTF node (its instances are consecutive), or one
    // for the whole asset when the loader has no nodes.
    let mut node = None;
    // Meshes placed more than once are recorded for instancing.
    let first_key = b.mesh_keys(asset.meshes.len());
    let mut uses = vec![0u32; asset.meshes.len()];
    for inst in &asset.instances {
        uses[inst.mesh as usize] += 1;
    }
    for (k, inst) in asset.instances.iter().enumerate() {
        let this = asset.instance_nodes.get(k).copied();
        if k == 0 || this != node {
            node = this;
            let own = this.and_then(|n| asset.node_names.get(n as usize));
            b.object(&match (prefix, own) {
                ("", Some(own)) => own.clone(),
                ("", None) => "asset".into(),
                (p, Some(own)) => format!("{p}/{own}"),
                (p, None) => p.to_string(),
            });
        }
        let mesh = &asset.meshes[inst.mesh as usize];
        let transform = placement.map_or(inst.transform, |p| p * inst.transform);
        let material = mesh.material.map_or(default_material, |m| first + m);
        let key = (uses[inst.mesh as usize] > 1).then_some(first_key + inst.mesh);
        b.instance(mesh, key, transform, material, at)?;
    }
    for light in &asset.lights {
        b.light(placement.map_or_else(|| light.clone(), |p| light.transformed(p)));
    }
    Ok(())
}

/// The scene of `asset`: the asset as [`place`] adds it (a transform that
/// mirrors keeps each triangle's front where the file has it, vertex
/// normals go by the inverse transpose), the camera named or numbered
/// `camera` (else the first, else the default one) and the default sky
/// where nothing emits. `file` names the asset in errors.
pub fn scene_from_asset(
    asset: &Asset,
    name: &str,
    file: &str,
    camera: Option<&str>,
) -> Result<Scene, SceneError> {
    let whole = Origin::file(file);
    let (lo, hi) = asset
        .bounds()
        .ok_or_else(|| whole.error("the asset has no triangles to render"))?;
    let mut b = SceneBuilder::new(name);
    place(&mut b, asset, None, "", &whole)?;
    if !b.has_emitting_triangle() && !b.has_punctual_light() {
        b.environment(Some(super::environment::default_sky()));
    }
    let view = choose_camera(asset, camera, lo, hi).map_err(|m| whole.error(m))?;
    b.camera(view, &whole)?;
    b.settings(ASSET_MAX_DEPTH, RenderOptions::default());
    b.finish(&whole)
}

/// The camera `which` (a name, or an index among the file's cameras), the
/// first, or the default framing of the bounds.
fn choose_camera(asset: &Asset, which: Option<&str>, lo: Vec3, hi: Vec3) -> Result<View, String> {
    let chosen = match which {
        Some(w) => {
            let found = asset
                .cameras
                .iter()
                .position(|c| c.name == w)
                .or_else(|| w.parse::<usize>().ok().filter(|&i| i < asset.cameras.len()));
            match found {
                Some(i) => Some(&asset.cameras[i]),
                None => {
                    let names: Vec<&str> = asset.cameras.iter().map(|c| c.name.as_str()).collect();
                    return Err(format!(
                        "no camera {w:?} in the asset (it has {}: {names:?})",
                        asset.cameras.len()
                    ));
                }
            }
        }
        None => asset.cameras.first(),
    };
    let (camera, aspect, vfov) = match chosen {
        Some(c) => {
            let m = c.transform;
            let position = m.transform_point3(Vec3::ZERO);
            let forward = m.transform_vector3(Vec3::NEG_Z);
            let up = m.transform_vector3(Vec3::Y);
            (
                (position, forward, up),
                c.aspect_ratio.unwrap_or(4.0 / 3.0),
                c.yfov.to_degrees(),
            )
        }
        None => {
            let centre = (lo + hi) * 0.5;
            let radius = ((hi - lo).length() * 0.5).max(1e-3);
            let distance = radius / (DEFAULT_VFOV_DEG.to_radians() * 0.5).sin() * 1.05;
            let dir = DEFAULT_VIEW.normalize();
            (
                (centre + dir * distance, -dir, Vec3::Y),
                4.0 / 3.0,
                DEFAULT_VFOV_DEG,
            )
        }
    };
    let height = DEFAULT_HEIGHT;
    let width = ((height as f32 * aspect).round() as u32).clamp(1, 16 * DEFAULT_HEIGHT);
    let (position, forward, up) = camera;
    Ok(View {
        position,
        forward,
        up,
        focal_px: Camera::focal_from_vfov(vfov, height),
        width,
        height,
    })
}
