//! `[[asset]]` entries in TOML scenes: a glTF, PLY or OBJ file placed by a
//! transform, through the same mesh-source seam and scene builder as an
//! asset rendered alone.

mod common;

use base64::Engine;
use common::{TempDir, run_ok};
use glam::Vec3;
use std::path::Path;
use wavetrace::scene::{Scene, SceneError, asset_scene};

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The vertical field of view of the glTF's camera, radians.
const YFOV: f32 = 0.7;

/// A glTF of a unit square (in z = 0, indexed) used twice: once by a node
/// that lifts it, turns it about x and gives it an emissive material, once
/// by a node that scales it into a white floor; and a camera node at
/// (0.5, 1, 4) looking down −Z.
fn two_squares_gltf() -> String {
    let mut bin = f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0]);
    bin.extend([0u8, 1, 2, 0, 2, 3, 0, 0]);
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    format!(
        r#"{{"asset": {{"version": "2.0"}},
  "buffers": [{{"byteLength": {len}, "uri": "{uri}"}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 6}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
                {{"bufferView": 1, "componentType": 5121, "count": 6, "type": "SCALAR"}}],
  "materials": [{{"name": "lamp", "pbrMetallicRoughness": {{"baseColorFactor": [0.8, 0.3, 0.2, 1], "metallicFactor": 0}},
                  "emissiveFactor": [1, 0.9, 0.8]}},
                {{"name": "floor", "pbrMetallicRoughness": {{"metallicFactor": 0}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}},
             {{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 1}}]}}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": {YFOV}, "znear": 0.1}}}}],
  "nodes": [{{"mesh": 0, "translation": [0, 1.5, 0], "rotation": [0.38268343, 0, 0, 0.9238795]}},
            {{"mesh": 1, "scale": [3, 3, 3], "rotation": [-0.70710677, 0, 0, 0.70710677], "translation": [-1, 0, 2]}},
            {{"camera": 0, "translation": [0.5, 1, 4]}}],
  "scenes": [{{"nodes": [0, 1, 2]}}], "scene": 0}}"#,
        len = bin.len()
    )
}

/// A TOML scene of the glTF's camera (as the direct render makes it) and
/// depth, placing `asset` with the `[[asset]]` lines `placement`.
fn scene_toml(asset: &str, placement: &str) -> String {
    format!(
        "[camera]\nposition = [0.5, 1, 4]\nforward = [0, 0, -1]\nup = [0, 1, 0]\n\
         vfov_deg = {:?}\nwidth = 640\nheight = 480\n\n[integrator]\nmax_depth = 5\n\n\
         [[asset]]\nfile = \"{asset}\"\n{placement}",
        YFOV.to_degrees()
    )
}

fn load_toml(dir: &Path, text: &str) -> Result<Scene, SceneError> {
    std::fs::write(dir.join("s.toml"), text).unwrap();
    Scene::load(&dir.join("s.toml"))
}

#[test]
fn a_gltf_placed_by_an_asset_entry_renders_as_the_direct_render() {
    let dir = TempDir::new("same");
    std::fs::write(dir.join("two.gltf"), two_squares_gltf()).unwrap();
    let (direct, _) = asset_scene::load(&dir.join("two.gltf"), None).unwrap();
    let placed = load_toml(&dir, &scene_toml("two.gltf", "")).unwrap();
    // The same world: geometry, normals and materials but for their names
    // (`two.gltf:lamp`), and the camera.
    assert_eq!(placed.triangles, direct.triangles);
    assert_eq!(placed.vertex_normals, direct.vertex_normals);
    assert_eq!(placed.camera, direct.camera);
    assert_eq!(placed.content_hash(), direct.content_hash());
    let names: Vec<&str> = placed.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        ["two.gltf:lamp", "two.gltf:floor", "two.gltf:default"]
    );
    assert_eq!(
        placed.sources,
        [dir.join("s.toml"), dir.join("two.gltf")],
        "the files the scene was read from"
    );
    // And the same image, bit for bit, from the command line.
    let args = |scene: &str, out: &str| {
        let a = ["--width", "32", "--height", "24", "--spp", "2", "--quiet"];
        let mut v = vec![scene.to_string(), "-o".into(), out.into()];
        v.extend(a.iter().map(|s| s.to_string()));
        v
    };
    run_ok(&dir, &args("two.gltf", "direct.exr"));
    run_ok(&dir, &args("s.toml", "placed.exr"));
    let (a, b) = (
        std::fs::read(dir.join("direct.exr")).unwrap(),
        std::fs::read(dir.join("placed.exr")).unwrap(),
    );
    assert!(a == b, "the [[asset]] scene renders differently");
}

#[test]
fn an_asset_entry_is_placed_by_its_transform_or_matrix() {
    let dir = TempDir::new("placed");
    std::fs::write(dir.join("two.gltf"), two_squares_gltf()).unwrap();
    let base = load_toml(&dir, &scene_toml("two.gltf", "")).unwrap();
    let vertices = |s: &Scene| -> Vec<Vec3> { s.triangles.iter().flat_map(|t| t.v).collect() };
    let near = |a: &[Vec3], b: &[Vec3]| {
        a.len() == b.len() && a.iter().zip(b).all(|(p, q)| (*p - *q).length() < 1e-5)
    };
    // Scale, then rotate (90° about y: x → −z), then translate.
    let trs = "scale = 2\nrotate_deg = [0, 90, 0]\ntranslate = [1, 2, 3]\n";
    let placed = load_toml(&dir, &scene_toml("two.gltf", trs)).unwrap();
    let expect: Vec<Vec3> = vertices(&base)
        .iter()
        .map(|p| Vec3::new(2.0 * p.z + 1.0, 2.0 * p.y + 2.0, -2.0 * p.x + 3.0))
        .collect();
    assert!(near(&vertices(&placed), &expect));
    // The same placement as a matrix, row by row.
    let rows = "matrix = [[0, 0, 2, 1], [0, 2, 0, 2], [-2, 0, 0, 3], [0, 0, 0, 1]]\n";
    let by_matrix = load_toml(&dir, &scene_toml("two.gltf", rows)).unwrap();
    assert!(near(&vertices(&by_matrix), &expect));
    // Beside the scene's own materials, each triangle keeps the asset's.
    let own = "[materials.red]\nreflectance = [1, 0, 0]\n\n[[sphere]]\nmaterial = \"red\"\n\
               center = [0, 0, 0]\nradius = 0.1\n";
    let mixed = load_toml(&dir, &(scene_toml("two.gltf", rows) + own)).unwrap();
    let names: Vec<&str> = (mixed.triangles.iter())
        .map(|t| mixed.materials[t.material as usize].name.as_str())
        .collect();
    assert_eq!(
        names,
        [&["two.gltf:lamp"; 2][..], &["two.gltf:floor"; 2]].concat()
    );
    assert_eq!(
        mixed.materials[mixed.spheres[0].material as usize].name,
        "red"
    );
    // A mirroring matrix keeps each triangle's front on the same side of
    // the surface: the normals mirror with it.
    let mirror = "matrix = [[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n";
    let mirrored = load_toml(&dir, &scene_toml("two.gltf", mirror)).unwrap();
    for (m, b) in mirrored.triangles.iter().zip(&base.triangles) {
        let n = b.normal * Vec3::new(-1.0, 1.0, 1.0);
        assert!((m.normal - n).length() < 1e-5, "{} vs {}", m.normal, n);
    }
}

#[test]
fn bad_asset_entries_are_refused_with_their_line_and_field() {
    let dir = TempDir::new("bad");
    std::fs::write(dir.join("two.gltf"), two_squares_gltf()).unwrap();
    std::fs::write(dir.join("mesh.stl"), "solid x\nendsolid x\n").unwrap();
    // The [[asset]] table starts on line 12, its `file` on 13.
    let cases: &[(&str, &str, usize, &str, &str)] = &[
        (
            "two.gltf",
            "scale = 0\n",
            14,
            "asset[0].scale",
            "finite and non-zero",
        ),
        (
            "two.gltf",
            "translate = [1, 2]\n",
            14,
            "asset.translate",
            "array of 3",
        ),
        (
            "two.gltf",
            "rotate_deg = [0, nan, 0]\n",
            14,
            "asset[0].rotate_deg",
            "finite numbers",
        ),
        (
            "two.gltf",
            "matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]\n",
            14,
            "asset[0].matrix",
            "last row must be [0, 0, 0, 1]",
        ),
        (
            "two.gltf",
            "matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]\n",
            14,
            "asset[0].matrix",
            "invertible",
        ),
        (
            "two.gltf",
            "translate = [1, 0, 0]\nmatrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n",
            15,
            "asset[0].matrix",
            "not both",
        ),
        (
            "two.gltf",
            "colour = 1\n",
            14,
            "asset.colour",
            "unknown field",
        ),
        (
            "mesh.stl",
            "",
            13,
            "asset[0].file",
            "not a mesh file wavetrace reads",
        ),
    ];
    for (file, placement, line, field, says) in cases {
        let e = load_toml(&dir, &scene_toml(file, placement)).unwrap_err();
        let shown = e.to_string();
        if *file == "mesh.stl" {
            // The mesh file's own error, naming the scene's line.
            assert!(
                shown.contains("mesh.stl") && shown.contains(says),
                "{shown}"
            );
            assert!(shown.contains(&format!("s.toml:{line}:")), "{shown}");
            continue;
        }
        assert_eq!(
            (e.line, e.field.as_deref()),
            (*line, Some(*field)),
            "{shown}"
        );
        assert!(shown.contains(says), "{shown}");
    }
    // A missing file: named, with the scene's line.
    let e = load_toml(&dir, &scene_toml("gone.glb", "")).unwrap_err();
    let shown = e.to_string();
    assert!(
        shown.contains("gone.glb") && shown.contains("s.toml:13:"),
        "{shown}"
    );
    // A transform that sends a vertex past f32.
    let e = load_toml(&dir, &scene_toml("two.gltf", "scale = 3e38\n")).unwrap_err();
    assert_eq!(
        (e.line, e.field.as_deref()),
        (13, Some("asset[0].file")),
        "{e}"
    );
    assert!(e.to_string().contains("not finite"), "{e}");
}

#[test]
fn an_obj_asset_is_the_obj_mesh_with_its_mtl_materials() {
    // The crate with its MTL, once as [[mesh]] (mtl = true) and once as
    // [[asset]]: the same triangles (grouped by material in the asset)
    // and the same colours.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let camera = "[camera]\nposition = [0, 0, -3]\nforward = [0, 0, 1]\nup = [0, 1, 0]\n\
                  focal_length_px = 64\nwidth = 64\nheight = 64\n";
    let parse = |entry: &str| {
        let text = format!("{camera}\n{entry}");
        wavetrace::scene::file::parse(&text, root.join("x.toml").to_str().unwrap()).unwrap()
    };
    let mesh = parse("[[mesh]]\nfile = \"meshes/crate.obj\"\nmtl = true\n");
    let asset = parse("[[asset]]\nfile = \"meshes/crate.obj\"\n");
    let key = |s: &Scene| {
        let mut v: Vec<(String, [[u32; 3]; 3])> = (s.triangles.iter())
            .map(|t| {
                let m = &s.materials[t.material as usize];
                let name = m.name.rsplit(':').next().unwrap().to_string();
                (name, t.v.map(|p| p.to_array().map(f32::to_bits)))
            })
            .collect();
        v.sort();
        v
    };
    assert!(!mesh.triangles.is_empty());
    assert_eq!(key(&asset), key(&mesh));
    for m in &mesh.materials {
        let same = asset.materials.iter().find(|a| a.name == m.name).unwrap();
        // (The model is the asset mapping's: glTF's metallic-roughness,
        // metallic 0 and roughness 1, for an MTL material.)
        assert_eq!(
            (same.reflectance, same.emission),
            (m.reflectance, m.emission),
            "{}",
            m.name
        );
    }
}
