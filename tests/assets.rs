//! glTF and PLY loading: the Khronos sample and broken models of Debian's
//! `assimp-testmodels` (every file loads or is refused cleanly, never a
//! panic), small files written here for each feature (primitive modes,
//! index types, sparse accessors, node transforms, textures, extensions)
//! and hostile mutations of them, and PLY in ASCII and both binary
//! byte orders.

mod common;

use base64::Engine;
use common::{TempDir, run_ok, stderr};
use glam::{Mat4, Vec3};
use std::path::{Path, PathBuf};
use wavetrace::render::{Engine as RenderEngine, RenderSettings, Renderer};
use wavetrace::scene::asset::{AlphaMode, Asset, AssetError};
use wavetrace::scene::asset_scene;
use wavetrace::scene::texture::{Filter, Wrap};
use wavetrace::scene::{gltf, ply};

const ASSIMP_GLTF2: &str = "/usr/share/assimp/models/glTF2";

fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            files_under(&p, out);
        } else if matches!(p.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
            out.push(p);
        }
    }
}

/// The sample models, or `None` (with a visible message) where the
/// package is not installed; under CI it must be.
fn assimp_models() -> Option<Vec<PathBuf>> {
    let dir = Path::new(ASSIMP_GLTF2);
    if !dir.is_dir() {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "{ASSIMP_GLTF2} is missing: CI installs assimp-testmodels (.ci/run)"
        );
        eprintln!("SKIPPED: {ASSIMP_GLTF2} is missing (apt-get install assimp-testmodels)");
        return None;
    }
    let mut files = Vec::new();
    files_under(dir, &mut files);
    Some(files)
}

fn load(path: &Path) -> Result<Asset, AssetError> {
    gltf::load(path)
}

#[test]
fn every_assimp_gltf2_file_loads_or_is_refused_cleanly() {
    let Some(files) = assimp_models() else {
        return;
    };
    assert!(files.len() >= 40, "{} files", files.len());
    let (mut loaded, mut refused) = (0, 0);
    for f in &files {
        let r = std::panic::catch_unwind(|| load(f));
        let r = r.unwrap_or_else(|_| panic!("{} panicked", f.display()));
        match r {
            Ok(a) => {
                loaded += 1;
                eprintln!(
                    "loaded  {}: {} meshes, {} instances, {} triangles, {} textures, {} warnings",
                    f.display(),
                    a.meshes.len(),
                    a.instances.len(),
                    a.instanced_triangles(),
                    a.textures.len(),
                    a.warnings.len()
                );
                common::assert_asset_in_range(&a);
            }
            Err(e) => {
                refused += 1;
                let s = e.to_string();
                eprintln!("refused {s}");
                assert!(s.starts_with(&f.display().to_string()), "{s}");
            }
        }
    }
    eprintln!("{loaded} loaded, {refused} refused");
    // The broken ones are refused, each for its reason.
    let refused_for = |rel: &str, why: &str| {
        let e = load(&Path::new(ASSIMP_GLTF2).join(rel))
            .unwrap_err()
            .to_string();
        assert!(e.contains(why), "{rel}: {e}");
    };
    refused_for("IndexOutOfRange/IndexOutOfRange.gltf", "index");
    refused_for("IndexOutOfRange/AllIndicesOutOfRange.gltf", "index");
    refused_for(
        "BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
        "POSITION",
    );
    refused_for("RecursiveNodes/RecursiveNodes.gltf", "node");
    refused_for("MissingBin/BoxTextured.gltf", "cannot read");
    // draco/2CylinderEngine.gltf loads (tests/draco.rs checks it).
    // And the good ones load as they should.
    let a = load(&Path::new(ASSIMP_GLTF2).join("BoxTextured-glTF/BoxTextured.gltf")).unwrap();
    assert_eq!(
        (a.meshes.len(), a.unique_triangles(), a.textures.len()),
        (1, 12, 1)
    );
    assert!(a.meshes[0].uv0.len() == a.meshes[0].positions.len());
    let t = a.materials[0].base_colour_texture.unwrap();
    assert_eq!(t.texture, 0);
    for rel in [
        "BoxTextured-glTF-Binary/BoxTextured.glb",
        "BoxTextured-glTF-Embedded/BoxTextured.gltf",
    ] {
        let b = load(&Path::new(ASSIMP_GLTF2).join(rel)).unwrap();
        assert_eq!(b.meshes[0].positions, a.meshes[0].positions, "{rel}");
        assert_eq!(b.meshes[0].triangles, a.meshes[0].triangles, "{rel}");
        assert_eq!(b.textures[0], a.textures[0], "{rel}");
    }
    let e = load(&Path::new(ASSIMP_GLTF2).join("2CylinderEngine-glTF-Binary/2CylinderEngine.glb"))
        .unwrap();
    assert!(
        e.instances.len() > e.meshes.len(),
        "instancing: {} {}",
        e.instances.len(),
        e.meshes.len()
    );
    let c = load(&Path::new(ASSIMP_GLTF2).join("cameras/Cameras.gltf")).unwrap();
    assert!(!c.cameras.is_empty());
    let tt =
        load(&Path::new(ASSIMP_GLTF2).join("textureTransform/TextureTransformTest.gltf")).unwrap();
    assert!(
        tt.materials
            .iter()
            .filter_map(|m| m.base_colour_texture)
            .any(|t| !t.transform.is_identity())
    );
    // Primitive modes: points and lines skipped with one warning.
    let modes = Path::new(ASSIMP_GLTF2).join("glTF-Asset-Generator/Mesh_PrimitiveMode");
    let points = load(&modes.join("Mesh_PrimitiveMode_00.gltf")).unwrap();
    assert_eq!(points.unique_triangles(), 0);
    assert_eq!(
        points
            .warnings
            .iter()
            .filter(|w| w.contains("points or lines"))
            .count(),
        1
    );
}

// ---------------------------------------------------------------------------
// Small files written here

/// A buffer of little-endian values as a data URI.
fn data_uri(bytes: &[u8]) -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A glTF with one buffer (`bin`), the given JSON pieces (buffer views,
/// accessors, meshes, nodes and the rest), as bytes.
fn gltf_json(bin: &[u8], rest: &str) -> Vec<u8> {
    format!(
        r#"{{"asset": {{"version": "2.0"}},
            "buffers": [{{"byteLength": {}, "uri": "{}"}}],
            {rest}}}"#,
        bin.len(),
        data_uri(bin)
    )
    .into_bytes()
}

fn read(bytes: &[u8]) -> Result<Asset, AssetError> {
    gltf::read(bytes, "test.gltf", None)
}

/// Four positions of a unit square in z = 0 (bytes 0..48), then `extra`.
fn square(extra: &[u8]) -> Vec<u8> {
    let mut b = f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0]);
    b.extend(extra);
    b
}

/// A mesh of the square's positions with indices of `index_type` at byte
/// 48 (count `n`) in `mode`, placed by `nodes`.
fn indexed(extra: &[u8], index_type: u32, n: usize, mode: u32, nodes: &str) -> Vec<u8> {
    let bin = square(extra);
    gltf_json(
        &bin,
        &format!(
            r#""bufferViews": [{{"buffer": 0, "byteLength": 48}},
                               {{"buffer": 0, "byteOffset": 48, "byteLength": {}}}],
               "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                               "min": [0,0,0], "max": [1,1,0]}},
                             {{"bufferView": 1, "componentType": {index_type}, "count": {n}, "type": "SCALAR"}}],
               "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "mode": {mode}}}]}}],
               {nodes}"#,
            extra.len()
        ),
    )
}

const ONE_NODE: &str = r#""nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0"#;

#[test]
fn index_types_and_primitive_modes_assemble_as_the_specification_lists() {
    let idx = [0u32, 1, 2, 3];
    for (ty, bytes) in [
        (5121u32, idx.iter().map(|&i| i as u8).collect::<Vec<u8>>()),
        (
            5123,
            idx.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect(),
        ),
        (5125, idx.iter().flat_map(|&i| i.to_le_bytes()).collect()),
    ] {
        // TRIANGLE_STRIP 0 1 2 3: (0 1 2), (1 3 2): v_i, v_{i+1+i%2}, v_{i+2-i%2}.
        let a = read(&indexed(&bytes, ty, 4, 5, ONE_NODE)).unwrap();
        assert_eq!(
            a.meshes[0].triangles,
            vec![[0, 1, 2], [1, 3, 2]],
            "type {ty}"
        );
        // TRIANGLE_FAN 0 1 2 3: (1 2 0), (2 3 0).
        let a = read(&indexed(&bytes, ty, 4, 6, ONE_NODE)).unwrap();
        assert_eq!(
            a.meshes[0].triangles,
            vec![[1, 2, 0], [2, 3, 0]],
            "type {ty}"
        );
        // TRIANGLES 0 1 2 (the fourth index left over).
        let a = read(&indexed(&bytes, ty, 4, 4, ONE_NODE)).unwrap();
        assert_eq!(a.meshes[0].triangles, vec![[0, 1, 2]], "type {ty}");
    }
    // Lines: skipped, one warning.
    let a = read(&indexed(&[0, 1, 2, 3], 5121, 4, 1, ONE_NODE)).unwrap();
    assert_eq!((a.unique_triangles(), a.warnings.len()), (0, 1));
}

#[test]
fn node_transforms_and_instancing() {
    // Node 0 (translate x by 10) has child 1 (scale 2, then rotate 90° about z),
    // and node 2 is a matrix node translating y by 5; nodes 1 and 2 share the mesh.
    let nodes = r#""nodes": [
        {"translation": [10, 0, 0], "children": [1]},
        {"mesh": 0, "rotation": [0, 0, 0.70710678, 0.70710678], "scale": [2, 2, 2]},
        {"mesh": 0, "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,5,0,1]}],
        "scenes": [{"nodes": [0, 2]}], "scene": 0"#;
    let a = read(&indexed(&[0, 1, 2], 5121, 3, 4, nodes)).unwrap();
    assert_eq!((a.meshes.len(), a.instances.len()), (1, 2));
    assert_eq!(a.instanced_triangles(), 2);
    let p = a.instances[0].transform.transform_point3(Vec3::X);
    assert!((p - Vec3::new(10.0, 2.0, 0.0)).length() < 1e-5, "{p}");
    let p = a.instances[1].transform.transform_point3(Vec3::X);
    assert!((p - Vec3::new(1.0, 5.0, 0.0)).length() < 1e-6, "{p}");
    let (lo, hi) = a.bounds().unwrap();
    assert!(
        lo.length() < 1e-5 && (hi - Vec3::new(10.0, 6.0, 0.0)).length() < 1e-5,
        "{lo} {hi}"
    );
    let _ = Mat4::IDENTITY;
}

#[test]
fn sparse_accessors_substitute_their_values() {
    // Positions with no buffer view (zeros), then sparse: vertex 1 = (1,0,0), vertex 2 = (0,1,0).
    let mut bin = vec![1u8, 2, 0, 0];
    bin.extend(f32s(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]));
    let json = gltf_json(
        &bin,
        r#""bufferViews": [{"buffer": 0, "byteLength": 2}, {"buffer": 0, "byteOffset": 4, "byteLength": 24}],
           "accessors": [{"componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0],
                          "sparse": {"count": 2, "indices": {"bufferView": 0, "componentType": 5121},
                                     "values": {"bufferView": 1}}}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
           "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]"#,
    );
    let a = read(&json).unwrap();
    assert_eq!(a.meshes[0].positions, vec![Vec3::ZERO, Vec3::X, Vec3::Y]);
    assert_eq!(a.meshes[0].triangles, vec![[0, 1, 2]]);
}

#[test]
fn hostile_files_are_refused_with_their_place() {
    let cases: Vec<(Vec<u8>, &str)> = vec![
        // An index past the vertices.
        (indexed(&[0, 1, 9], 5121, 3, 4, ONE_NODE), "index 9 of 4"),
        // More indices than the view holds.
        (indexed(&[0, 1, 2], 5121, 3_000_000_000, 4, ONE_NODE), "do not fit"),
        // A view past its buffer.
        (
            gltf_json(
                &square(&[]),
                r#""bufferViews": [{"buffer": 0, "byteOffset": 18446744073709551000, "byteLength": 48}],
                   "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}],
                   "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                   "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]"#,
            ),
            "",
        ),
        // A stride that overflows.
        (
            gltf_json(
                &square(&[]),
                r#""bufferViews": [{"buffer": 0, "byteLength": 48, "byteStride": 252}],
                   "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}],
                   "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                   "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]"#,
            ),
            "do not fit",
        ),
        // Terabytes declared and not there.
        (
            format!(
                r#"{{"asset": {{"version": "2.0"}}, "buffers": [{{"byteLength": 4000000000000, "uri": "{}"}}]}}"#,
                data_uri(&[0; 8])
            )
            .into_bytes(),
            "4000000000000 bytes declared",
        ),
        // Zeros without data, 10¹² of them (and one sparse value).
        (
            gltf_json(
                &[0; 16],
                r#""bufferViews": [{"buffer": 0, "byteLength": 16}],
                   "accessors": [{"componentType": 5126, "count": 1000000000000, "type": "VEC3", "min": [0,0,0], "max": [1,1,0],
                                  "sparse": {"count": 1, "indices": {"bufferView": 0, "componentType": 5125},
                                             "values": {"bufferView": 0, "byteOffset": 4}}}],
                   "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                   "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]"#,
            ),
            "without data",
        ),
        // A NaN position.
        (
            gltf_json(
                &f32s(&[0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0, 1.0, 0.0]),
                r#""bufferViews": [{"buffer": 0, "byteLength": 36}],
                   "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}],
                   "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                   "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]"#,
            ),
            "position 1 is not finite",
        ),
        // Positions of the wrong type.
        (
            gltf_json(
                &square(&[]),
                r#""bufferViews": [{"buffer": 0, "byteLength": 48}],
                   "accessors": [{"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC2"}],
                   "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                   "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]"#,
            ),
            "POSITION",
        ),
        // A cycle, and a node with two parents.
        (indexed(&[0, 1, 2], 5121, 3, 4, r#""nodes": [{"mesh": 0, "children": [1]}, {"children": [0]}], "scenes": [{"nodes": [0]}]"#), "node"),
        (indexed(&[0, 1, 2], 5121, 3, 4, r#""nodes": [{"children": [2]}, {"children": [2]}, {"mesh": 0}], "scenes": [{"nodes": [0, 1]}]"#), "nodes must form trees"),
        // Required extensions wavetrace does not read (Draco is read:
        // tests/draco.rs).
        (
            br#"{"asset": {"version": "2.0"}, "extensionsUsed": ["KHR_future_thing"], "extensionsRequired": ["KHR_future_thing"]}"#.to_vec(),
            "requires the extension KHR_future_thing",
        ),
        // External files where none can be read, garbage, a bad GLB.
        (br#"{"asset": {"version": "2.0"}, "buffers": [{"byteLength": 4, "uri": "x.bin"}]}"#.to_vec(), "external file"),
        (b"\x00\x01garbage".to_vec(), "not a valid glTF"),
        (b"glTF\x02\x00\x00\x00\xff\xff\xff\xff\x10\x00\x00\x00JSON".to_vec(), "not a valid glTF"),
    ];
    for (bytes, want) in cases {
        let r = std::panic::catch_unwind(|| read(&bytes));
        let e = r.expect("no panic").expect_err(want).to_string();
        eprintln!("refused: {e}");
        assert!(e.starts_with("test.gltf"), "{e}");
        assert!(e.contains(want), "want {want:?} in: {e}");
    }
    // Every truncation and every byte flipped in a small valid file: no panic.
    let good = indexed(&[0, 1, 2], 5121, 3, 4, ONE_NODE);
    assert!(read(&good).is_ok());
    for k in 0..good.len() {
        let _ = read(&good[..k]);
        let mut b = good.clone();
        b[k] = b[k].wrapping_add(17);
        let _ = read(&b);
    }
}

#[test]
fn materials_textures_and_extensions_are_read() {
    use image::{ImageEncoder, codecs::png::PngEncoder};
    let mut png = Vec::new();
    PngEncoder::new(&mut png)
        .write_image(
            &[255, 0, 0, 255, 0, 255, 0, 255],
            2,
            1,
            image::ExtendedColorType::Rgba8,
        )
        .unwrap();
    let mut bin = square(&[0, 1, 2, 0]);
    let png_offset = bin.len();
    bin.extend(&png);
    let json = gltf_json(
        &bin,
        &format!(
            r#""extensionsUsed": ["KHR_texture_transform", "KHR_materials_emissive_strength", "KHR_materials_ior",
                                  "KHR_materials_transmission", "KHR_materials_specular", "EXT_unknown"],
               "bufferViews": [{{"buffer": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 3}},
                               {{"buffer": 0, "byteOffset": {png_offset}, "byteLength": {}}}],
               "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
                             {{"bufferView": 1, "componentType": 5121, "count": 3, "type": "SCALAR"}}],
               "images": [{{"bufferView": 2, "mimeType": "image/png"}}],
               "samplers": [{{"magFilter": 9728, "wrapS": 33071, "wrapT": 33648}}],
               "textures": [{{"source": 0, "sampler": 0}}],
               "materials": [{{"name": "red", "pbrMetallicRoughness": {{"baseColorFactor": [1, 0.5, 0.25, 1], "metallicFactor": 0.25,
                                  "roughnessFactor": 0.75,
                                  "baseColorTexture": {{"index": 0, "extensions": {{"KHR_texture_transform": {{"offset": [0.5, 0], "scale": [2, 2]}}}}}}}},
                              "emissiveFactor": [1, 1, 0], "alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": true,
                              "extensions": {{"KHR_materials_emissive_strength": {{"emissiveStrength": 4}},
                                             "KHR_materials_ior": {{"ior": 1.33}},
                                             "KHR_materials_transmission": {{"transmissionFactor": 0.5}},
                                             "KHR_materials_specular": {{"specularFactor": 0.5}}}}}}],
               "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
               {ONE_NODE}"#,
            png.len()
        ),
    );
    let a = read(&json).unwrap();
    let m = &a.materials[0];
    assert_eq!(m.name, "red");
    assert_eq!(m.base_colour, [1.0, 0.5, 0.25, 1.0]);
    assert_eq!((m.metallic, m.roughness), (0.25, 0.75));
    assert_eq!(m.emissive, [4.0, 4.0, 0.0]);
    assert_eq!(m.alpha_mode, AlphaMode::Mask(0.3));
    assert!(m.double_sided);
    assert_eq!((m.ior, m.transmission, m.specular), (1.33, 0.5, 0.5));
    let t = m.base_colour_texture.unwrap();
    assert_eq!(t.sampler.filter, Filter::Nearest);
    assert_eq!(
        (t.sampler.wrap_u, t.sampler.wrap_v),
        (Wrap::ClampToEdge, Wrap::MirroredRepeat)
    );
    assert_eq!(t.transform.apply([0.1, 0.2]), [0.7, 0.4]);
    let tex = &a.textures[t.texture as usize];
    assert_eq!((tex.width(), tex.height()), (2, 1));
    assert_eq!(tex.texel(0, 0), [1.0, 0.0, 0.0, 1.0]);
    assert_eq!(
        a.warnings
            .iter()
            .filter(|w| w.contains("EXT_unknown"))
            .count(),
        1
    );
}

// ---------------------------------------------------------------------------
// PLY

fn ply_header(format: &str, extra_vertex: &str) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment a quad and a triangle\nelement vertex 5\n\
         property float x\nproperty float y\nproperty float z\n{extra_vertex}\
         element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    )
}

#[test]
fn ply_ascii_and_binary_in_both_byte_orders_read_alike() {
    let pos = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [2.0, 0.0, 0.0],
    ];
    let uv = [
        [0.0f32, 0.0],
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
        [0.5, 0.5],
    ];
    let col = [
        [255u8, 0, 0],
        [0, 255, 0],
        [0, 0, 255],
        [255, 255, 255],
        [0, 0, 0],
    ];
    let faces: [&[i32]; 2] = [&[0, 1, 2, 3], &[1, 4, 2]];
    let props = "property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n\
                 property uchar red\nproperty uchar green\nproperty uchar blue\n";
    let mut ascii = ply_header("ascii", props);
    for k in 0..5 {
        let (p, t, c) = (pos[k], uv[k], col[k]);
        ascii += &format!(
            "{} {} {} 0 0 2 {} {} {} {} {}\n",
            p[0], p[1], p[2], t[0], t[1], c[0], c[1], c[2]
        );
    }
    for f in faces {
        ascii += &format!(
            "{} {}\n",
            f.len(),
            f.iter()
                .map(|i| i.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    let binary = |big: bool| {
        let fmt = if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut b = ply_header(fmt, props).into_bytes();
        let put_f = |b: &mut Vec<u8>, x: f32| {
            b.extend(if big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            })
        };
        for k in 0..5 {
            for x in pos[k] {
                put_f(&mut b, x);
            }
            for x in [0.0, 0.0, 2.0] {
                put_f(&mut b, x);
            }
            for x in uv[k] {
                put_f(&mut b, x);
            }
            b.extend(col[k]);
        }
        for f in faces {
            b.push(f.len() as u8);
            for &i in f {
                b.extend(if big {
                    i.to_be_bytes()
                } else {
                    i.to_le_bytes()
                });
            }
        }
        b
    };
    let read_ply =
        |bytes: &[u8]| ply::read(std::io::Cursor::new(bytes.to_vec()), "test.ply").unwrap();
    let a = read_ply(ascii.as_bytes());
    let m = &a.meshes[0];
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]]);
    assert_eq!(m.positions[4], Vec3::new(2.0, 0.0, 0.0));
    assert_eq!(m.normals[0], Vec3::Z);
    // v flipped: PLY's v runs up, texture coordinates here run down.
    assert_eq!(m.uv0[3], [0.0, 0.0]);
    assert_eq!(m.colours[1], [0.0, 1.0, 0.0, 1.0]);
    for big in [false, true] {
        let b = read_ply(&binary(big));
        assert_eq!(b.meshes[0], a.meshes[0], "big endian: {big}");
    }
    // Hostile: an index out of range, a NaN, a truncated body, a huge count.
    let bad = [
        ascii.replace("3 1 4 2", "3 1 40 2"),
        ascii.replace("2 0 0 0 0 2", "nan 0 0 0 0 2"),
        ascii[..ascii.len() - 10].to_string(),
        ascii.replace("element vertex 5", "element vertex 5000000000000"),
        "not a ply".to_string(),
    ];
    for s in bad {
        let r = std::panic::catch_unwind(|| {
            ply::read(std::io::Cursor::new(s.clone().into_bytes()), "test.ply")
        });
        let e = r.expect("no panic").expect_err(&s);
        eprintln!("refused: {e}");
        assert!(e.to_string().starts_with("test.ply"));
    }
}

// ---------------------------------------------------------------------------
// Scenes from assets

/// Both engines at 32 × 24 pixels, 2 samples a pixel: they trace the same
/// paths and differ by the order of summation only (as tests/wavefront.rs
/// holds them).
fn engines_agree(name: &str, scene: &wavetrace::scene::Scene) {
    let film = |engine| {
        let mut s = RenderSettings::for_scene(scene);
        (s.width, s.height, s.spp, s.engine) = (32, 24, 2, engine);
        Renderer::new(scene, &s).unwrap().render().0
    };
    let (a, b) = (film(RenderEngine::Reference), film(RenderEngine::Wavefront));
    let (ra, rb) = (a.to_rgb(), b.to_rgb());
    common::assert_engines_close(name, &ra, &rb);
    let sum: f64 = ra.iter().flatten().map(|&x| x as f64).sum();
    assert!(sum > 0.0, "{name}: a black image");
}

#[test]
fn an_asset_becomes_a_scene_both_engines_render_alike() {
    // A PLY quad and triangle, written here.
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
               property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
               0 0 0\n1 0 0\n1 0 -1\n0 0 -1\n4 0 1 2 3\n";
    let asset = ply::read(std::io::Cursor::new(ply.as_bytes().to_vec()), "quad.ply").unwrap();
    let scene = asset_scene::scene_from_asset(&asset, "quad", "quad.ply", None).unwrap();
    // Two triangles, under the default sky (nothing emits).
    assert_eq!(scene.triangles.len(), 2);
    assert!(scene.triangles.iter().all(|t| t.normal.y > 0.99));
    let sky = scene.environment.as_ref().expect("the default sky");
    assert_eq!(sky.source, wavetrace::scene::environment::DEFAULT_SKY);
    assert_eq!(
        (sky.texels[0], sky.strength, sky.visible),
        ([1.0; 3], 1.0, true)
    );
    // The default camera sees every vertex.
    let cam = &scene.camera;
    for t in &scene.triangles[..2] {
        for v in t.v {
            let d = v - cam.position;
            let z = d.dot(cam.forward);
            let (x, y) = (d.dot(cam.right) / z, d.dot(cam.up) / z);
            let half_h = cam.height as f32 * 0.5 / cam.focal_length_px;
            assert!(
                z > 0.0 && y.abs() < half_h && x.abs() < half_h * 4.0 / 3.0,
                "{v}"
            );
        }
    }
    engines_agree("quad.ply", &scene);
    // A mirroring transform keeps the front where the file has it.
    let nodes = r#""nodes": [{"mesh": 0, "scale": [-1, 1, 1]}], "scenes": [{"nodes": [0]}]"#;
    let a = read(&indexed(&[0, 1, 2], 5121, 3, 4, nodes)).unwrap();
    let s = asset_scene::scene_from_asset(&a, "m", "m.gltf", None).unwrap();
    assert!(s.triangles[0].normal.z > 0.99, "{}", s.triangles[0].normal);
    // A camera asked for that the file does not have.
    let e = asset_scene::scene_from_asset(&a, "m", "m.gltf", Some("nope")).unwrap_err();
    assert!(e.to_string().contains("no camera \"nope\""), "{e}");
    let Some(_) = assimp_models() else {
        return;
    };
    for rel in [
        "BoxTextured-glTF-Binary/BoxTextured.glb",
        "2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
        "cameras/Cameras.gltf",
    ] {
        let path = Path::new(ASSIMP_GLTF2).join(rel);
        let (scene, _) = asset_scene::load(&path, None).unwrap();
        if rel.starts_with("BoxTextured") {
            // TEXCOORD_0 reaches the scene, one entry a triangle.
            let uv = &scene.texturing.uv;
            assert_eq!(uv.len(), scene.triangles.len());
            assert_eq!(uv.len(), 12);
            assert!(uv.iter().all(|t| t[0] != [[0.0; 2]; 3]), "{uv:?}");
        }
        engines_agree(rel, &scene);
    }
}

#[test]
fn wavetrace_renders_a_glb_file_directly() {
    let Some(_) = assimp_models() else {
        return;
    };
    let dir = TempDir::new("glb");
    let glb = Path::new(ASSIMP_GLTF2).join("BoxTextured-glTF-Binary/BoxTextured.glb");
    std::fs::copy(&glb, dir.join("box.glb")).unwrap();
    let out = run_ok(&dir, &["box.glb", "--spp", "1", "-o", "box.png", "--quiet"]);
    assert!(dir.join("box.png").exists(), "{}", stderr(&out));
}

#[test]
fn tangents_are_generated_where_a_normal_texture_needs_them() {
    use image::{ImageEncoder, codecs::png::PngEncoder};
    let mut png = Vec::new();
    PngEncoder::new(&mut png)
        .write_image(&[128, 128, 255, 255], 1, 1, image::ExtendedColorType::Rgba8)
        .unwrap();
    // The unit square in z = 0, normals +z, u along +x, v along -y.
    let mut bin = square(&[]);
    bin.extend(f32s(&[0.0, 0.0, 1.0].repeat(4)));
    bin.extend(f32s(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]));
    bin.extend([0u8, 1, 2, 0, 2, 3, 0, 0]);
    let png_offset = bin.len();
    bin.extend(&png);
    let json = gltf_json(
        &bin,
        &format!(
            r#""bufferViews": [{{"buffer": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 48}},
                               {{"buffer": 0, "byteOffset": 96, "byteLength": 32}}, {{"buffer": 0, "byteOffset": 128, "byteLength": 6}},
                               {{"buffer": 0, "byteOffset": {png_offset}, "byteLength": {}}}],
               "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
                             {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"}},
                             {{"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"}},
                             {{"bufferView": 3, "componentType": 5121, "count": 6, "type": "SCALAR"}}],
               "images": [{{"bufferView": 4, "mimeType": "image/png"}}],
               "textures": [{{"source": 0}}],
               "materials": [{{"normalTexture": {{"index": 0, "scale": 0.5}}}}],
               "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}},
                                            "indices": 3, "material": 0}}]}}],
               {ONE_NODE}"#,
            png.len()
        ),
    );
    let a = read(&json).unwrap();
    let m = &a.meshes[0];
    assert_eq!(m.tangents.len(), 4);
    for t in &m.tangents {
        let v = Vec3::new(t[0], t[1], t[2]);
        // MikkTSpace's tangent follows increasing u (+x); v runs along -y,
        // and the bitangent w · (n × t) = w · (+y) points towards
        // decreasing v (the image's up, glTF's +Y of a normal texture),
        // along +y: w = 1.
        assert!((v - Vec3::X).length() < 1e-5, "{t:?}");
        assert_eq!(t[3], 1.0, "{t:?}");
    }
    assert_eq!(a.materials[0].normal_texture.unwrap().scale, 0.5);
    // Without the normal texture, no tangents are made.
    let plain = String::from_utf8(json.clone()).unwrap().replace(
        r#""normalTexture": {"index": 0, "scale": 0.5}"#,
        r#""doubleSided": true"#,
    );
    assert!(
        read(plain.as_bytes()).unwrap().meshes[0]
            .tangents
            .is_empty()
    );
}

#[test]
fn ply_mutations_are_refused_or_read_never_a_panic() {
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
               property float z\nproperty uchar red\nelement face 1\n\
               property list uchar int vertex_indices\nend_header\n0 0 0 9\n1 0 0 9\n0 1 0 9\n3 0 1 2\n";
    let mut binary = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
                       property float y\nproperty float z\nelement face 1\n\
                       property list uchar int vertex_indices\nend_header\n"
        .to_vec();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        binary.extend(f32s(&v));
    }
    binary.push(3);
    for i in [0i32, 1, 2] {
        binary.extend(i.to_le_bytes());
    }
    for good in [ply.as_bytes().to_vec(), binary] {
        let read = |b: &[u8]| ply::read(std::io::Cursor::new(b.to_vec()), "m.ply");
        assert_eq!(read(&good).unwrap().unique_triangles(), 1);
        for k in 0..good.len() {
            let _ = read(&good[..k]);
            for delta in [1u8, 17, 128] {
                let mut b = good.clone();
                b[k] = b[k].wrapping_add(delta);
                if let Err(e) = read(&b) {
                    assert!(e.to_string().starts_with("m.ply"), "{e}");
                }
            }
        }
    }
}

#[test]
fn camera_picks_one_of_the_files_cameras() {
    let Some(_) = assimp_models() else {
        return;
    };
    // One perspective camera (its orthographic one is skipped).
    let path = Path::new(ASSIMP_GLTF2).join("cameras/Cameras.gltf");
    let a = load(&path).unwrap();
    assert_eq!(a.cameras.len(), 1);
    let cam = |which: Option<&str>| asset_scene::load(&path, which).unwrap().0.camera;
    let first = cam(Some("0"));
    assert_eq!(cam(None), first);
    assert_eq!(cam(Some(a.cameras[0].name.as_str())), first);
    // The file's camera, not the default framing.
    let framed = asset_scene::scene_from_asset(
        &Asset {
            cameras: Vec::new(),
            ..a.clone()
        },
        "c",
        "c",
        None,
    )
    .unwrap()
    .camera;
    assert_ne!(first, framed);
    let dir = TempDir::new("camera");
    std::fs::copy(&path, dir.join("c.gltf")).unwrap();
    std::fs::copy(
        Path::new(ASSIMP_GLTF2).join("cameras/simpleSquare.bin"),
        dir.join("simpleSquare.bin"),
    )
    .unwrap();
    run_ok(
        &dir,
        &[
            "c.gltf", "--camera", "0", "--spp", "1", "-o", "c.png", "--quiet",
        ],
    );
    let err = common::run_refused(&dir, &["c.gltf", "--camera", "9", "--spp", "1"]);
    assert!(err.contains("no camera \"9\""), "{err}");
}
