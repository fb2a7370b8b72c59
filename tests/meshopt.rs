//! `EXT_meshopt_compression` and `KHR_mesh_quantization`: compressed
//! glTF files load as their uncompressed sources do.
//!
//! - The shipped `scenes/textured.glb` with every accessor's buffer view
//!   compressed here (attributes, and indices in either index bitstream),
//!   its data moved to a fallback buffer without bytes: the same meshes,
//!   and, with the lossless index bitstream, the same image to the bit in
//!   both engines.
//! - Files made by gltfpack 1.3 and gltf-transform 4.5
//!   (`tests/data/meshopt/`, from the shipped assets, CC0 like them):
//!   quantized positions and texture coordinates
//!   (`KHR_mesh_quantization`), the EXPONENTIAL filter, the OCTAHEDRAL
//!   filter on normals: the same triangles within the quantization step,
//!   both engines alike, an image close to the source's.
//! - The QUATERNION and EXPONENTIAL filters and 16-bit OCTAHEDRAL normals
//!   against the values encoded.
//! - Hostile extension objects refused with their JSON path, before
//!   anything of their declared size is allocated.

mod common;

use common::{TempDir, glb, glb_mutations_never_panic, read_glb as read, scene_of, split_glb};
use glam::{Mat4, Vec3};
use serde_json::{Value, json};
use std::path::Path;
use wavetrace::film::Film;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::asset::Asset;
use wavetrace::scene::{Scene, gltf};

const EXT: &str = "EXT_meshopt_compression";

fn data(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(name)).unwrap()
}

/// `elements` (each `stride` bytes) in the attribute bitstream, version
/// 0 (the extension's: header 0xa0).
fn encode_attributes(bytes: &[u8], stride: usize) -> Vec<u8> {
    fn enc<T: bytemuck::Pod>(bytes: &[u8]) -> Vec<u8> {
        let v: Vec<T> = bytemuck::pod_collect_to_vec(bytes);
        meshopt::encode_vertex_buffer_level(&v, 2, Some(0)).unwrap()
    }
    let out = match stride {
        4 => enc::<[u8; 4]>(bytes),
        8 => enc::<[u8; 8]>(bytes),
        12 => enc::<[u8; 12]>(bytes),
        16 => enc::<[u8; 16]>(bytes),
        s => panic!("stride {s}"),
    };
    assert_eq!(out[0], 0xa0);
    out
}

/// Appends `compressed` to `bin` (4-aligned) and makes buffer view
/// `view` (its data on the fallback buffer 1) point at it.
fn compress_view(json: &mut Value, bin: &mut Vec<u8>, view: usize, ext: Value) {
    bin.resize(bin.len().next_multiple_of(4), 0);
    let v = &mut json["bufferViews"][view];
    v["buffer"] = json!(1);
    let mut ext = ext;
    ext["buffer"] = json!(0);
    ext["byteOffset"] = json!(bin.len());
    v["extensions"] = json!({ EXT: ext });
}

/// `scenes/textured.glb` with every accessor's buffer view compressed:
/// attributes with their element size as stride, indices (`u32`) in
/// `index_mode` (`TRIANGLES` or `INDICES`); the views' own buffer becomes
/// a fallback buffer without data.
fn compressed_textured(index_mode: &str) -> Vec<u8> {
    let (mut json, mut bin) = split_glb(&data("scenes/textured.glb"));
    let accessors = json["accessors"].as_array().unwrap().clone();
    let fallback_len = bin.len();
    for a in &accessors {
        let view = a["bufferView"].as_u64().unwrap() as usize;
        let count = a["count"].as_u64().unwrap() as usize;
        let v = &json["bufferViews"][view];
        let (offset, len) = (
            v["byteOffset"].as_u64().unwrap_or(0) as usize,
            v["byteLength"].as_u64().unwrap() as usize,
        );
        let bytes = bin[offset..offset + len].to_vec();
        let stride = len / count;
        let (compressed, mode) = if a["type"] == "SCALAR" {
            assert_eq!(a["componentType"], 5125);
            let ix: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
            let n = *ix.iter().max().unwrap() as usize + 1;
            let c = if index_mode == "TRIANGLES" {
                meshopt::encode_index_buffer(&ix, n).unwrap()
            } else {
                meshopt::encode_index_sequence(&ix, n).unwrap()
            };
            (c, index_mode)
        } else {
            (encode_attributes(&bytes, stride), "ATTRIBUTES")
        };
        let ext = json!({"byteLength": compressed.len(), "byteStride": stride, "count": count, "mode": mode});
        compress_view(&mut json, &mut bin, view, ext);
        bin.extend_from_slice(&compressed);
        // The source bytes gone: only the decoded ones can be read.
        bin[offset..offset + len].fill(0xee);
    }
    json["buffers"][0]["byteLength"] = json!(bin.len().next_multiple_of(4));
    json["buffers"]
        .as_array_mut()
        .unwrap()
        .push(json!({"byteLength": fallback_len, "extensions": {EXT: {"fallback": true}}}));
    for list in ["extensionsUsed", "extensionsRequired"] {
        let l = json[list].as_array().cloned().unwrap_or_default();
        json[list] = json!(l.into_iter().chain([json!(EXT)]).collect::<Vec<_>>());
    }
    glb(&json, &bin)
}

fn render(scene: &Scene, engine: Engine, spp: u32) -> Film {
    let mut s = RenderSettings::for_scene(scene);
    (s.width, s.height, s.spp, s.threads, s.engine) = (40, 30, spp, 2, engine);
    Renderer::new(scene, &s).unwrap().render().0
}

/// Each triangle of `a` in world space (each instance's transform
/// applied), its vertices rotated to start at the least one.
fn world_triangles(a: &Asset) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for inst in &a.instances {
        let m = &a.meshes[inst.mesh as usize];
        let t: Mat4 = inst.transform;
        for tri in &m.triangles {
            let p = tri.map(|i| t.transform_point3(m.positions[i as usize]));
            let k = (0..3)
                .min_by(|&i, &j| p[i].to_array().partial_cmp(&p[j].to_array()).unwrap())
                .unwrap();
            out.push([p[k], p[(k + 1) % 3], p[(k + 2) % 3]]);
        }
    }
    out
}

/// The largest distance (per coordinate) from a triangle of `a` to its
/// nearest in `b`, matched with the same winding; both have as many.
fn triangle_distance(a: &Asset, b: &Asset) -> f32 {
    let (ta, tb) = (world_triangles(a), world_triangles(b));
    assert_eq!(ta.len(), tb.len(), "triangle counts");
    let d = |x: &[Vec3; 3], y: &[Vec3; 3]| {
        (0..3)
            .map(|i| (x[i] - y[i]).abs().max_element())
            .fold(0.0f32, f32::max)
    };
    ta.iter()
        .map(|x| tb.iter().map(|y| d(x, y)).fold(f32::INFINITY, f32::min))
        .fold(0.0, f32::max)
}

/// The file's compressed views' `(mode, filter)`s, checked to be there.
fn modes(bytes: &[u8]) -> Vec<(String, String)> {
    let (json, _) = split_glb(bytes);
    let out: Vec<_> = json["bufferViews"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|v| v["extensions"].get(EXT))
        .map(|e| {
            (
                e["mode"].as_str().unwrap().to_string(),
                e["filter"].as_str().unwrap_or("NONE").to_string(),
            )
        })
        .collect();
    assert!(!out.is_empty());
    out
}

#[test]
fn compressed_views_load_as_their_source_and_render_the_same_bits_in_both_engines() {
    let source = data("scenes/textured.glb");
    let want = read(&source);
    let dir = TempDir::new("meshopt-bits");
    let original = scene_of(&dir, "source.glb", &source);
    for mode in ["INDICES", "TRIANGLES"] {
        let bytes = compressed_textured(mode);
        assert!(modes(&bytes).iter().any(|(m, _)| m == mode));
        let got = read(&bytes);
        assert_eq!(got.meshes.len(), want.meshes.len());
        for (g, w) in got.meshes.iter().zip(&want.meshes) {
            assert_eq!(g.positions, w.positions, "{mode}");
            assert_eq!(g.uv0, w.uv0, "{mode}");
            assert_eq!(g.colours, w.colours, "{mode}");
            if mode == "INDICES" {
                assert_eq!(g.triangles, w.triangles, "{mode}");
            } else {
                // The triangle bitstream may rotate a triangle's
                // vertices (keeping its winding) and reorders nothing.
                let rotated = |t: &[u32; 3]| {
                    let k = (0..3).min_by_key(|&i| t[i]).unwrap();
                    [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
                };
                let (gr, wr): (Vec<_>, Vec<_>) = (
                    g.triangles.iter().map(rotated).collect(),
                    w.triangles.iter().map(rotated).collect(),
                );
                assert_eq!(gr, wr, "{mode}");
            }
        }
        if mode == "INDICES" {
            let scene = scene_of(&dir, "compressed.glb", &bytes);
            for engine in [Engine::Reference, Engine::Wavefront] {
                let (a, b) = (render(&original, engine, 4), render(&scene, engine, 4));
                assert!(a.sums.iter().any(|s| s != &a.sums[0]));
                assert!(a.sums == b.sums, "{mode} {engine:?}: the images differ");
            }
        }
    }
}

/// gltfpack's output of `scenes/textured.glb`: positions as 14-bit
/// integers (`KHR_mesh_quantization`, dequantized by the node's scale),
/// texture coordinates as normalised 12-bit ones with
/// `KHR_texture_transform`; or, with `-vpf -vtf`, floats through the
/// EXPONENTIAL filter; and gltf-transform's (`meshopt`), normalised
/// 16-bit positions. The same triangles within the quantization step,
/// the engines alike, and an image within noise of the source's.
#[test]
fn encoders_outputs_hold_their_sources_triangles_and_render_alike() {
    let source = data("scenes/textured.glb");
    let want = read(&source);
    let dir = TempDir::new("meshopt-gltfpack");
    let original = scene_of(&dir, "source.glb", &source);
    let reference = render(&original, Engine::Reference, 16).to_rgb();
    for (name, filter, step) in [
        // 14 bits over the scene's 5 m: 5 / 16383 apart, half that off.
        ("textured-meshopt.glb", "NONE", 0.5 * 5.0 / 16383.0),
        // 14-bit mantissas over values up to 2.5 in magnitude.
        ("textured-meshopt-exp.glb", "EXPONENTIAL", 2.5 / 8192.0),
        // gltf-transform 4.5: normalised 16-bit positions scaled by each
        // node, the floor's 2.5 m half-extent over 32767 steps.
        ("textured-meshopt-gltf-transform.glb", "NONE", 2.5 / 32767.0),
    ] {
        let bytes = data(&format!("tests/data/meshopt/{name}"));
        assert!(modes(&bytes).iter().any(|(_, f)| f == filter), "{name}");
        let got = read(&bytes);
        let d = triangle_distance(&want, &got);
        eprintln!("{name}: triangles within {d} of the source's (step {step})");
        assert!(
            d <= step * 1.01,
            "{name}: triangles {d} off (at most {step})"
        );
        let scene = scene_of(&dir, name, &bytes);
        let (a, b) = (
            render(&scene, Engine::Reference, 16).to_rgb(),
            render(&scene, Engine::Wavefront, 16).to_rgb(),
        );
        common::assert_engines_close(name, &a, &b);
        let mean = |img: &[[f32; 3]]| img.iter().flatten().map(|&x| x as f64).sum::<f64>();
        let diff: f64 = a
            .iter()
            .zip(&reference)
            .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs() as f64))
            .sum::<f64>()
            / mean(&reference);
        eprintln!("{name}: mean |image - source's image| / mean = {diff:.4}");
        assert!(diff < 0.005, "{name}: the image is {diff} off the source's");
    }
}

/// gltfpack's output of `scenes/meshes/sphere-smooth.obj` (a unit sphere
/// at the origin, normals radial) with `-cc`: 8-bit normals through the
/// OCTAHEDRAL filter. Each decoded normal is its vertex's direction
/// from the centre, within the filter's step.
#[test]
fn octahedral_normals_decode_to_the_spheres_radial_directions() {
    let bytes = data("tests/data/meshopt/sphere-meshopt-oct.glb");
    assert!(modes(&bytes).iter().any(|(_, f)| f == "OCTAHEDRAL"));
    let a = read(&bytes);
    assert_eq!(a.unique_triangles(), 168);
    let t = a.instances[0].transform;
    let m = &a.meshes[a.instances[0].mesh as usize];
    assert_eq!(m.normals.len(), m.positions.len());
    let mut worst = 0.0f32;
    for (p, n) in m.positions.iter().zip(&m.normals) {
        let radial = t.transform_point3(*p).normalize();
        worst = worst.max(n.angle_between(radial));
    }
    eprintln!("octahedral normals within {worst} rad of radial");
    assert!(
        worst < 0.02,
        "a normal {worst} rad off its radial direction"
    );
}

/// A triangle whose POSITION is floats through the EXPONENTIAL filter,
/// NORMAL 16-bit OCTAHEDRAL and TANGENT unit quaternions (16-bit
/// QUATERNION): each decodes to what was encoded, within its step.
#[test]
fn each_filter_decodes_what_was_encoded() {
    let positions = [
        [0.0f32, 0.0, 0.0, 0.0],
        [1.5, 0.0, -0.25, 0.0],
        [0.0, 3.0e3, 1.0e-3, 0.0],
    ];
    let normals = [
        [0.0f32, 0.0, 1.0, 0.0],
        [0.6, 0.0, 0.8, 0.0],
        [-0.48, 0.64, -0.6, 0.0],
    ];
    let quats = [
        [0.0f32, 0.0, 0.0, 1.0],
        [0.5, -0.5, 0.5, 0.5],
        [0.1, 0.7, -0.1, 0.7],
    ]
    .map(|q| glam::Vec4::from(q).normalize().to_array());
    let exp = meshopt::encode_filter_exp::<3>(
        &positions.map(|p| [p[0], p[1], p[2]]),
        20,
        meshopt::EncodeExpMode::Separate,
    );
    let oct = meshopt::encode_filter_oct::<i16>(&normals, 16);
    let quat = meshopt::encode_filter_quat(&quats, 16);
    let mut bin = Vec::new();
    let mut views = Vec::new();
    for (bytes, stride, filter) in [
        (
            bytemuck::cast_slice::<_, u8>(&exp).to_vec(),
            12,
            "EXPONENTIAL",
        ),
        (
            bytemuck::cast_slice::<_, u8>(&oct).to_vec(),
            8,
            "OCTAHEDRAL",
        ),
        (
            bytemuck::cast_slice::<_, u8>(&quat).to_vec(),
            8,
            "QUATERNION",
        ),
    ] {
        let c = encode_attributes(&bytes, stride);
        views.push(
            json!({"buffer": 1, "byteLength": 3 * stride, "byteStride": stride,
            "extensions": {EXT: {"buffer": 0, "byteOffset": bin.len(), "byteLength": c.len(),
                "byteStride": stride, "count": 3, "mode": "ATTRIBUTES", "filter": filter}}}),
        );
        bin.extend_from_slice(&c);
        bin.resize(bin.len().next_multiple_of(4), 0);
    }
    let json = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": [EXT, "KHR_mesh_quantization"],
        "extensionsRequired": [EXT, "KHR_mesh_quantization"],
        "buffers": [{"byteLength": bin.len()}, {"byteLength": 100, "extensions": {EXT: {"fallback": true}}}],
        "bufferViews": views,
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [-1e4, -1e4, -1e4], "max": [1e4, 1e4, 1e4]},
            {"bufferView": 1, "componentType": 5122, "normalized": true, "count": 3, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5122, "normalized": true, "count": 3, "type": "VEC4"}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TANGENT": 2}}]}],
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]
    });
    let a = read(&glb(&json, &bin));
    let m = &a.meshes[0];
    for k in 0..3 {
        let p = Vec3::from_slice(&positions[k]);
        let d = (m.positions[k] - p).abs().max_element();
        assert!(
            d <= p.abs().max_element() * 2f32.powi(-18),
            "position {k}: {} for {p}",
            m.positions[k]
        );
        let n = Vec3::from_slice(&normals[k]);
        assert!(
            m.normals[k].angle_between(n) < 1e-3,
            "normal {k}: {} for {n}",
            m.normals[k]
        );
        let q = glam::Vec4::from(quats[k]);
        let got = glam::Vec4::from(m.tangents[k]);
        // q and −q are one rotation.
        let d = (got - q)
            .abs()
            .max_element()
            .min((got + q).abs().max_element());
        assert!(d < 1e-3, "quaternion {k}: {got} for {q}");
    }
}

/// Hostile extension objects on the compressed textured file: each
/// refused naming the file and the extension's JSON path, none allocating
/// what it declares (a terabyte view fits no test machine).
#[test]
fn hostile_compressed_views_are_refused_with_their_json_path() {
    let (json, bin) = split_glb(&compressed_textured("INDICES"));
    // View 6: the first cube's 24 positions (stride 12); view 8 its indices.
    let at = "bufferViews[6].extensions.EXT_meshopt_compression";
    let edit = |f: &dyn Fn(&mut Value)| {
        let mut j = json.clone();
        f(&mut j);
        j
    };
    let ext =
        |j: &mut Value, field: &str, v: Value| j["bufferViews"][6]["extensions"][EXT][field] = v;
    let cases: Vec<(Value, Vec<u8>, String, &str)> = vec![
        // A terabyte view, its byteLength agreeing: over the budget.
        (
            edit(&|j| {
                ext(j, "count", json!(100_000_000_000u64));
                j["bufferViews"][6]["byteLength"] = json!(1_200_000_000_000u64);
            }),
            bin.clone(),
            at.into(),
            "more than 64 times",
        ),
        // count × byteStride is not the view's byteLength.
        (
            edit(&|j| ext(j, "count", json!(1u64 << 40))),
            bin.clone(),
            format!("{at}.count"),
            "byteLength of 288",
        ),
        (
            edit(&|j| ext(j, "byteStride", json!(16))),
            bin.clone(),
            format!("{at}.count"),
            "byteLength",
        ),
        // The source range outside its buffer.
        (
            edit(&|j| ext(j, "byteOffset", json!(1u64 << 62))),
            bin.clone(),
            format!("{at}.byteLength"),
            "outside buffer 0",
        ),
        (
            edit(&|j| ext(j, "byteLength", json!(1u64 << 20))),
            bin.clone(),
            format!("{at}.byteLength"),
            "outside buffer 0",
        ),
        (
            edit(&|j| ext(j, "buffer", json!(7))),
            bin.clone(),
            format!("{at}.buffer"),
            "buffer 7 of 2",
        ),
        (
            edit(&|j| ext(j, "buffer", json!(1))),
            bin.clone(),
            format!("{at}.buffer"),
            "fallback",
        ),
        // The specification's rules.
        (
            edit(&|j| ext(j, "mode", json!("ZIP"))),
            bin.clone(),
            at.into(),
            "unknown variant `ZIP`",
        ),
        (
            edit(&|j| ext(j, "filter", json!("QUATERNION"))),
            bin.clone(),
            format!("{at}.byteStride"),
            "12 for the Quaternion filter",
        ),
        (
            edit(&|j| ext(j, "count", json!(-1))),
            bin.clone(),
            at.into(),
            "invalid value",
        ),
        (
            edit(&|j| {
                ext(j, "byteStride", json!(6));
                ext(j, "count", json!(48));
            }),
            bin.clone(),
            format!("{at}.byteStride"),
            "multiple of 4",
        ),
        (
            edit(&|j| j["bufferViews"][6]["byteStride"] = json!(16)),
            bin.clone(),
            format!("{at}.byteStride"),
            "the buffer view's byteStride is 16",
        ),
        (
            edit(&|j| j["bufferViews"][8]["extensions"][EXT]["filter"] = json!("OCTAHEDRAL")),
            bin.clone(),
            "bufferViews[8].extensions.EXT_meshopt_compression.filter".into(),
            "only ATTRIBUTES",
        ),
        (
            edit(&|j| {
                j["bufferViews"][8]["extensions"][EXT]["mode"] = json!("TRIANGLES");
                j["bufferViews"][8]["extensions"][EXT]["count"] = json!(35);
                j["bufferViews"][8]["byteLength"] = json!(140);
            }),
            bin.clone(),
            "bufferViews[8].extensions.EXT_meshopt_compression.count".into(),
            "multiple of 3",
        ),
        // A view on the fallback buffer that is not compressed.
        (
            edit(&|j| {
                j["bufferViews"][6]
                    .as_object_mut()
                    .unwrap()
                    .remove("extensions");
            }),
            bin.clone(),
            "bufferViews[6]".into(),
            "fallback without data",
        ),
    ];
    // Garbage in the compressed bytes: the header broken, then every
    // byte of the first cube's positions.
    let (off, _) = {
        let e = &json["bufferViews"][6]["extensions"][EXT];
        (
            e["byteOffset"].as_u64().unwrap() as usize,
            e["byteLength"].as_u64().unwrap() as usize,
        )
    };
    let mut garbage = bin.clone();
    garbage[off] = 0x00;
    let mut cases = cases;
    cases.push((
        json.clone(),
        garbage,
        at.into(),
        "do not decode as Attributes",
    ));
    for (j, b, path, want) in cases {
        let r = std::panic::catch_unwind(|| gltf::read(&glb(&j, &b), "test.glb", None));
        let e = r.expect("no panic").expect_err(want).to_string();
        eprintln!("refused: {e}");
        assert!(
            e.starts_with(&format!("test.glb: {path}")),
            "want {path}: {e}"
        );
        assert!(e.contains(want), "want {want:?} in: {e}");
    }
}

/// Positions and texture coordinates as integers that are not
/// normalised are read as their values where the file uses
/// `KHR_mesh_quantization`, and refused (naming it) where it does not.
#[test]
fn quantized_integer_attributes_need_khr_mesh_quantization() {
    let bin: Vec<u8> = [0i16, 0, 0, 0, 2, 0, 0, 0, 0, 0, -3, 0]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .chain([0u8, 0, 255, 0, 0, 255])
        .collect();
    let doc = |used: bool| {
        let mut j = json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": bin.len()}],
            "bufferViews": [{"buffer": 0, "byteLength": 24, "byteStride": 8}, {"buffer": 0, "byteOffset": 24, "byteLength": 6}],
            "accessors": [
                {"bufferView": 0, "componentType": 5122, "count": 3, "type": "VEC3", "min": [0, 0, -3], "max": [2, 0, 0]},
                {"bufferView": 1, "componentType": 5121, "count": 3, "type": "VEC2"}
            ],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}}]}],
            "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]
        });
        if used {
            j["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
            j["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
        }
        glb(&j, &bin)
    };
    let a = read(&doc(true));
    assert_eq!(
        a.meshes[0].positions,
        [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -3.0)
        ]
    );
    assert_eq!(a.meshes[0].uv0, [[0.0, 0.0], [255.0, 0.0], [0.0, 255.0]]);
    let e = gltf::read(&doc(false), "test.glb", None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("meshes[0].primitives[0].attributes.POSITION")
            && e.contains("KHR_mesh_quantization"),
        "{e}"
    );
}

/// Every byte of the compressed textured file's binary chunk flipped, and
/// the chunk cut short at each length: loaded or refused naming the file,
/// never a panic.
#[test]
fn flipped_and_truncated_compressed_bytes_never_panic() {
    let (json, bin) = split_glb(&compressed_textured("TRIANGLES"));
    let first = json["bufferViews"][3]["extensions"][EXT]["byteOffset"]
        .as_u64()
        .unwrap() as usize;
    glb_mutations_never_panic("meshopt", &json, &bin, first, &[0x5a]);
}

/// gltfpack 1.3's `-cc -ce khr` output of `scenes/textured.glb`
/// (`tests/data/meshopt/textured-meshopt-khr.glb`): `KHR_meshopt_compression`,
/// the ratified extension, with version 1 attribute bitstreams (header
/// 0xa1) and the COLOR filter on the wedge's 8-bit colours. The same
/// triangles as the source within the quantization step, the colours
/// within two 8-bit steps (YCoCg rounds: 0.1 decodes to 27/255), the
/// engines alike, the image within 0.5 % of the source's. The rules: COLOR is refused under the
/// EXT extension, and with a stride other than 4 or 8; a view may not
/// carry both extensions.
#[test]
fn khr_meshopt_compression_reads_version_1_streams_and_the_color_filter() {
    const KHR: &str = "KHR_meshopt_compression";
    let source = data("scenes/textured.glb");
    let want = read(&source);
    let bytes = data("tests/data/meshopt/textured-meshopt-khr.glb");
    let (json, bin) = split_glb(&bytes);
    assert_eq!(json["extensionsRequired"][1], json!(KHR));
    let views = json["bufferViews"].as_array().unwrap();
    let colour_view = (views.iter())
        .position(|v| v["extensions"][KHR]["filter"] == json!("COLOR"))
        .expect("a COLOR view");
    for v in views
        .iter()
        .filter(|v| v["extensions"][KHR]["mode"] == "ATTRIBUTES")
    {
        let at = v["extensions"][KHR]["byteOffset"].as_u64().unwrap() as usize;
        assert_eq!(bin[at], 0xa1, "a version 1 stream");
    }
    let got = read(&bytes);
    let d = triangle_distance(&want, &got);
    let step = 0.5 * 5.0 / 16383.0;
    eprintln!("KHR: triangles within {d} of the source's (step {step})");
    assert!(d <= step * 1.01, "triangles {d} off");
    // Each source colour against the nearest decoded one (the vertices
    // are renumbered).
    let colours = |a: &Asset| {
        let m = a.meshes.iter().find(|m| !m.colours.is_empty()).unwrap();
        m.colours.clone()
    };
    let (cw, cg) = (colours(&want), colours(&got));
    assert_eq!(cw.len(), cg.len());
    let dist = |x: &[f32; 4], y: &[f32; 4]| (0..4).map(|k| (x[k] - y[k]).abs()).fold(0.0, f32::max);
    let dc = (cw.iter())
        .map(|x| cg.iter().map(|y| dist(x, y)).fold(f32::INFINITY, f32::min))
        .fold(0.0f32, f32::max);
    eprintln!("KHR: colours within {dc} of the source's");
    assert!(dc <= 2.0 / 255.0, "colours {dc} off: {cg:?} for {cw:?}");
    let dir = TempDir::new("meshopt-khr");
    let original = scene_of(&dir, "source.glb", &source);
    let reference = render(&original, Engine::Reference, 16).to_rgb();
    let scene = scene_of(&dir, "khr.glb", &bytes);
    let (a, b) = (
        render(&scene, Engine::Reference, 16).to_rgb(),
        render(&scene, Engine::Wavefront, 16).to_rgb(),
    );
    common::assert_engines_close("khr.glb", &a, &b);
    let total = |img: &[[f32; 3]]| img.iter().flatten().map(|&x| x as f64).sum::<f64>();
    let diff: f64 = (a.iter().zip(&reference))
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs() as f64))
        .sum::<f64>()
        / total(&reference);
    eprintln!("KHR: mean |image - source's image| / mean = {diff:.4}");
    assert!(diff < 0.005, "the image is {diff} off the source's");
    // The rules the KHR extension adds.
    let at = format!("bufferViews[{colour_view}].extensions");
    let refused = |j: &Value, path: &str, why: &str| {
        let e = gltf::read(&glb(j, &bin), "test.glb", None)
            .err()
            .unwrap_or_else(|| panic!("{path}: not refused"))
            .to_string();
        assert!(e.starts_with(&format!("test.glb: {path}")), "{path}: {e}");
        assert!(e.contains(why), "{why:?} in {e}");
    };
    let mut as_ext = json.clone();
    for list in ["extensionsUsed", "extensionsRequired"] {
        for e in as_ext[list].as_array_mut().unwrap() {
            if e == KHR {
                *e = json!(EXT);
            }
        }
    }
    for b in as_ext["buffers"].as_array_mut().unwrap() {
        if let Some(x) = b["extensions"].as_object_mut().and_then(|x| x.remove(KHR)) {
            b["extensions"][EXT] = x;
        }
    }
    for v in as_ext["bufferViews"].as_array_mut().unwrap() {
        if let Some(x) = v["extensions"].as_object_mut().and_then(|x| x.remove(KHR)) {
            v["extensions"][EXT] = x;
        }
    }
    refused(
        &as_ext,
        &format!("{at}.{EXT}.filter"),
        "COLOR is a filter of KHR",
    );
    let mut wide = json.clone();
    wide["bufferViews"][colour_view]["extensions"][KHR]["byteStride"] = json!(12);
    wide["bufferViews"][colour_view]["extensions"][KHR]["count"] = json!(1);
    refused(
        &wide,
        &format!("{at}.{KHR}.byteStride"),
        "12 for the Color filter",
    );
    let mut both = json.clone();
    let x = both["bufferViews"][colour_view]["extensions"][KHR].clone();
    both["bufferViews"][colour_view]["extensions"][EXT] = x;
    refused(
        &both,
        &at,
        "both KHR_meshopt_compression and EXT_meshopt_compression",
    );
}
