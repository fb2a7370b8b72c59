//! A scene from an asset file alone (`wavetrace model.glb`, `model.gltf`,
//! `scan.ply`): the asset's instances flattened into world-space
//! triangles, its camera (or one that frames it), and a light where it has
//! none.
//!
//! **Interim materials.** Until the engines evaluate textures and glTF's
//! metallic-roughness model (`integrator::bsdf::metallic_roughness`
//! exists, the engines' material seam does not yet reach it), each [`PbrMaterial`] is rendered
//! with the nearest existing model: `metallic ≥ ½` as [`Model::Metal`] of
//! reflectance the base colour and α = roughness², else
//! [`Model::Diffuse`] of reflectance the base colour;
//! `transmission ≥ ½` as [`Model::Glass`] of the material's index. A
//! texture counts as its mean (base colour and emission), so a textured
//! asset renders in its average colours; vertex colours and normal
//! textures are not used yet.
//!
//! **Defaults.** Without a camera in the file: one looking at the centre
//! of the bounds from the direction [`DEFAULT_VIEW`] (front, right, above;
//! glTF's +Y is up and +Z faces the viewer), far enough that the bounding
//! sphere fills a vertical field of view of [`DEFAULT_VFOV_DEG`]. Without
//! an emitter: a square light above the asset ([`default_light`]).
//! Images are [`DEFAULT_HEIGHT`] pixels high, as wide as the camera's
//! aspect ratio (4:3 where the file fixes none).

use super::asset::{Asset, AssetError, PbrMaterial};
use super::camera::Camera;
use super::{Material, Model, RenderOptions, Scene, SceneError, Triangle};
use glam::{Mat3, Vec3};
use std::path::Path;

/// The direction the default camera looks from (towards the asset).
pub const DEFAULT_VIEW: Vec3 = Vec3::new(0.6, 0.5, 1.0);

/// The default camera's vertical field of view, degrees.
pub const DEFAULT_VFOV_DEG: f32 = 40.0;

/// The default image height, pixels.
pub const DEFAULT_HEIGHT: u32 = 480;

/// The maximum path depth of an asset's scene.
pub const ASSET_MAX_DEPTH: u32 = 5;

/// Whether `path` names an asset file this module reads (by extension).
pub fn is_asset(path: &Path) -> bool {
    matches!(
        path.extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref(),
        Some("gltf" | "glb" | "ply")
    )
}

fn scene_error(e: AssetError) -> SceneError {
    SceneError {
        file: e.file,
        line: 0,
        column: 0,
        field: (!e.at.is_empty()).then_some(e.at),
        message: e.message,
        mesh: None,
    }
}

/// Reads the asset at `path` (glTF, GLB or PLY) and makes its scene, with
/// the camera named or numbered `camera` (the first by default). Returns
/// the loader's warnings beside the scene.
pub fn load(path: &Path, camera: Option<&str>) -> Result<(Scene, Vec<String>), SceneError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let asset = match ext.as_deref() {
        Some("ply") => super::ply::load(path),
        _ => super::gltf::load(path),
    }
    .map_err(scene_error)?;
    let name = path
        .file_stem()
        .map_or("asset".into(), |s| s.to_string_lossy().into_owned());
    let scene = scene_from_asset(&asset, &name, &path.display().to_string(), camera)?;
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

/// The interim material of `m` (see the module documentation).
pub fn interim_material(asset: &Asset, m: &PbrMaterial) -> Material {
    let mut base = Vec3::new(m.base_colour[0], m.base_colour[1], m.base_colour[2]);
    if let Some(t) = m.base_colour_texture {
        base *= texture_mean(asset, t.texture);
    }
    let mut emission = Vec3::from(m.emissive);
    if let Some(t) = m.emissive_texture {
        emission *= texture_mean(asset, t.texture);
    }
    let base = base.clamp(Vec3::ZERO, Vec3::ONE);
    let mut out = Material::diffuse(&m.name, base, emission.max(Vec3::ZERO));
    if m.transmission >= 0.5 && m.ior > 0.0 {
        out.model = Model::Glass;
        out.ior = m.ior;
        out.transmittance = base;
    } else if m.metallic >= 0.5 {
        out.model = Model::Metal;
        out.alpha = (m.roughness * m.roughness).clamp(0.0, 1.0);
    }
    out
}

/// The square light added to a scene without emitters: side the bounds'
/// diagonal `d`, centred `d` above the top of the bounds, facing down,
/// radiance 3 (white).
pub fn default_light(lo: Vec3, hi: Vec3) -> [[Vec3; 3]; 2] {
    let c = (lo + hi) * 0.5;
    let d = (hi - lo).length().max(1e-3);
    let y = hi.y + d;
    let h = d * 0.5;
    let p = |x: f32, z: f32| Vec3::new(c.x + x, y, c.z + z);
    // Counter-clockwise seen from below: the front faces down.
    [
        [p(-h, -h), p(h, -h), p(h, h)],
        [p(-h, -h), p(h, h), p(-h, h)],
    ]
}

/// The scene of `asset`: every instance's triangles in world space (a
/// transform that mirrors keeps each triangle's front where the file has
/// it), vertex normals by the inverse transpose, interim materials, the
/// camera named or numbered `camera` (else the first, else the default
/// one) and the default light where nothing emits. `file` names the asset
/// in errors.
pub fn scene_from_asset(
    asset: &Asset,
    name: &str,
    file: &str,
    camera: Option<&str>,
) -> Result<Scene, SceneError> {
    let err = |message: String| SceneError {
        file: file.to_string(),
        line: 0,
        column: 0,
        field: None,
        message,
        mesh: None,
    };
    let (lo, hi) = asset
        .bounds()
        .ok_or_else(|| err("the asset has no triangles to render".into()))?;
    let mut materials: Vec<Material> = asset
        .materials
        .iter()
        .map(|m| interim_material(asset, m))
        .collect();
    let default_material = materials.len() as u32;
    materials.push(interim_material(
        asset,
        &PbrMaterial {
            name: "default".into(),
            ..PbrMaterial::default()
        },
    ));
    let mut triangles = Vec::with_capacity(asset.instanced_triangles());
    let mut vertex_normals = Vec::new();
    let mut smooth = false;
    let mut uv: Vec<super::TriangleUv> = Vec::new();
    let mut textured = false;
    for inst in &asset.instances {
        let mesh = &asset.meshes[inst.mesh as usize];
        let m = inst.transform;
        let normal_matrix = Mat3::from_mat4(m).inverse().transpose();
        let mirrored = Mat3::from_mat4(m).determinant() < 0.0;
        let material = mesh.material.unwrap_or(default_material);
        let world: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| m.transform_point3(*p))
            .collect();
        if let Some(p) = world.iter().find(|p| !p.is_finite()) {
            return Err(err(format!(
                "{}: a transformed vertex is not finite: {p}",
                mesh.name
            )));
        }
        let normals: Vec<Vec3> = mesh
            .normals
            .iter()
            .map(|n| (normal_matrix * *n).try_normalize().unwrap_or(Vec3::ZERO))
            .collect();
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| i as usize);
            let (b, c) = if mirrored { (c, b) } else { (b, c) };
            let tri = Triangle::ccw([world[a], world[b], world[c]], material);
            if tri.normal == Vec3::ZERO {
                continue;
            }
            if normals.is_empty() {
                vertex_normals.push([Vec3::ZERO; 3]);
            } else {
                smooth = true;
                vertex_normals.push([normals[a], normals[b], normals[c]]);
            }
            let set = |coords: &[[f32; 2]]| match coords.is_empty() {
                true => [[0.0; 2]; 3],
                false => [coords[a], coords[b], coords[c]],
            };
            textured |= !mesh.uv0.is_empty() || !mesh.uv1.is_empty();
            uv.push([set(&mesh.uv0), set(&mesh.uv1)]);
            triangles.push(tri);
        }
    }
    if !smooth {
        vertex_normals.clear();
    }
    if !textured {
        uv.clear();
    }
    let emits = triangles
        .iter()
        .any(|t| materials[t.material as usize].is_emissive());
    if !emits {
        let light = materials.len() as u32;
        materials.push(Material::diffuse(
            "default light",
            Vec3::ZERO,
            Vec3::splat(3.0),
        ));
        for v in default_light(lo, hi) {
            triangles.push(Triangle::ccw(v, light));
            if smooth {
                vertex_normals.push([Vec3::ZERO; 3]);
            }
            if textured {
                uv.push([[[0.0; 2]; 3]; 2]);
            }
        }
    }
    let camera = choose_camera(asset, camera, lo, hi).map_err(err)?;
    Ok(Scene {
        name: name.to_string(),
        camera,
        materials,
        triangles,
        vertex_normals,
        texturing: super::Texturing { uv },
        spheres: Vec::new(),
        max_depth: ASSET_MAX_DEPTH,
        options: RenderOptions::default(),
    })
}

/// The camera `which` (a name, or an index among the file's cameras), the
/// first, or the default framing of the bounds.
fn choose_camera(asset: &Asset, which: Option<&str>, lo: Vec3, hi: Vec3) -> Result<Camera, String> {
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
    Camera::new(
        position,
        forward,
        up,
        Camera::focal_from_vfov(vfov, height),
        width,
        height,
    )
    .ok_or_else(|| "the camera's direction is degenerate".to_string())
}
