//! `KHR_draco_mesh_compression`: Draco-compressed glTF files load as
//! their uncompressed sources do.
//!
//! - gltf-transform 4.5's `draco` output of the shipped
//!   `scenes/textured.glb` (`tests/data/draco/`, CC0 like it), with
//!   edgebreaker and with sequential connectivity: the same triangles
//!   within the quantization step, texture coordinates and colours within
//!   theirs, both engines alike, an image within noise of the source's.
//! - assimp's `draco/2CylinderEngine.gltf` (where `assimp-testmodels` is
//!   installed; CI installs it): 34 primitives, 65,311 triangles, the
//!   bounds and the image of the package's uncompressed copy.
//! - Hostile primitives refused with their JSON path, and every flipped
//!   byte and truncation of the Draco streams: no panic.

mod common;

use common::{TempDir, glb, glb_mutations_never_panic, read_glb as read, scene_of, split_glb};
use glam::{Mat4, Vec3};
use serde_json::{Value, json};
use std::path::Path;
use wavetrace::film::Film;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::asset::Asset;
use wavetrace::scene::{Scene, asset_scene, gltf};

const EXT: &str = "KHR_draco_mesh_compression";
const ASSIMP_DRACO: &str = "/usr/share/assimp/models/glTF2/draco/2CylinderEngine.gltf";
const ASSIMP_PLAIN: &str =
    "/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";

fn data(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(name)).unwrap()
}

fn render(scene: &Scene, engine: Engine, spp: u32) -> Film {
    render_seeded(scene, engine, spp, 0)
}

fn render_seeded(scene: &Scene, engine: Engine, spp: u32, seed: u64) -> Film {
    let mut s = RenderSettings::for_scene(scene);
    (s.width, s.height, s.spp, s.threads, s.engine) = (40, 30, spp, 2, engine);
    s.seed += seed;
    Renderer::new(scene, &s).unwrap().render().0
}

/// Each mesh's triangles as vertex tuples (position, texture coordinates,
/// colour), each rotated to start at its least position, sorted: the
/// mesh as a set of triangles, whatever order and numbering of vertices.
fn triangles(a: &Asset, m: usize) -> Vec<[[f32; 9]; 3]> {
    let m = &a.meshes[m];
    let vertex = |i: u32| {
        let i = i as usize;
        let p = m.positions[i];
        let t = m.uv0.get(i).copied().unwrap_or([0.0; 2]);
        let c = m.colours.get(i).copied().unwrap_or([0.0; 4]);
        [p.x, p.y, p.z, t[0], t[1], c[0], c[1], c[2], c[3]]
    };
    let mut out: Vec<_> = (m.triangles.iter())
        .map(|t| {
            let v = t.map(vertex);
            let k = (0..3)
                .min_by(|&i, &j| v[i][..3].partial_cmp(&v[j][..3]).unwrap())
                .unwrap();
            [v[k], v[(k + 1) % 3], v[(k + 2) % 3]]
        })
        .collect();
    out.sort_by(|x, y| x.partial_cmp(y).unwrap());
    out
}

/// The largest difference between matched triangles of mesh `m` in `a`
/// and `b`, in positions and in texture coordinates and colours (both
/// have as many triangles; each triangle of `a` matched with its nearest
/// in `b`, winding kept).
fn mesh_distance(a: &Asset, b: &Asset, m: usize) -> (f32, f32) {
    let (ta, tb) = (triangles(a, m), triangles(b, m));
    assert_eq!(ta.len(), tb.len(), "mesh {m}: triangle counts");
    let d = |x: &[[f32; 9]; 3], y: &[[f32; 9]; 3], r: std::ops::Range<usize>| {
        (0..3)
            .flat_map(|i| r.clone().map(move |c| (x[i][c] - y[i][c]).abs()))
            .fold(0.0f32, f32::max)
    };
    let mut worst = (0.0f32, 0.0f32);
    for x in &ta {
        let y = (tb.iter())
            .min_by(|p, q| d(x, p, 0..3).partial_cmp(&d(x, q, 0..3)).unwrap())
            .unwrap();
        worst.0 = worst.0.max(d(x, y, 0..3));
        worst.1 = worst.1.max(d(x, y, 3..9));
    }
    worst
}

/// Mean absolute difference of two images over the first one's mean.
fn image_difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let sum = |img: &[[f32; 3]]| img.iter().flatten().map(|&x| x as f64).sum::<f64>();
    let diff: f64 = (a.iter().zip(b))
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs() as f64))
        .sum();
    diff / sum(a)
}

/// The two engines' images of a scene (at `spp`) agree to rounding.
fn engines_agree(scene: &Scene, what: &str, spp: u32) -> Vec<[f32; 3]> {
    let (a, b) = (
        render(scene, Engine::Reference, spp).to_rgb(),
        render(scene, Engine::Wavefront, spp).to_rgb(),
    );
    common::assert_engines_close(what, &a, &b);
    a
}

/// gltf-transform 4.5's `draco` of `scenes/textured.glb` (its defaults:
/// 14-bit positions over each mesh's bounds, 12-bit texture coordinates,
/// 8-bit colours), with edgebreaker and with sequential connectivity:
/// every mesh's triangles those of the source within the quantization
/// steps, the engines alike, the image within noise of the source's:
/// Draco renumbers vertices and reorders triangles (emitters included),
/// so the same seed draws other paths, and the noise is the source's own
/// difference between two seeds.
#[test]
fn draco_files_hold_their_sources_triangles_and_render_alike() {
    let source = data("scenes/textured.glb");
    let want = read(&source);
    let dir = TempDir::new("draco-textured");
    let original = scene_of(&dir, "source.glb", &source);
    let reference = render(&original, Engine::Reference, 64).to_rgb();
    let other_seed = render_seeded(&original, Engine::Reference, 64, 1).to_rgb();
    let noise = image_difference(&reference, &other_seed);
    eprintln!("the source's images of two seeds differ by {noise:.4}");
    // 14 bits over the floor's 5 m, half a step off at most; texture
    // coordinates (within [0, 1] here) over 12 bits, colours over 8.
    let (position_step, other_step) = (0.5 * 5.0 / 16383.0, 0.5 / 255.0);
    for name in ["textured-draco.glb", "textured-draco-sequential.glb"] {
        let bytes = data(&format!("tests/data/draco/{name}"));
        let (json, _) = split_glb(&bytes);
        assert_eq!(json["extensionsRequired"], json!([EXT]), "{name}");
        let got = read(&bytes);
        assert_eq!(got.meshes.len(), want.meshes.len(), "{name}");
        assert_eq!(got.instances.len(), want.instances.len(), "{name}");
        for m in 0..want.meshes.len() {
            assert_eq!(got.meshes[m].material, want.meshes[m].material);
            let (dp, dt) = mesh_distance(&want, &got, m);
            eprintln!("{name} mesh {m}: positions within {dp}, the rest within {dt}");
            assert!(dp <= position_step * 1.01, "{name} mesh {m}: {dp} off");
            assert!(dt <= other_step * 1.01, "{name} mesh {m}: {dt} off");
        }
        let scene = scene_of(&dir, name, &bytes);
        let image = engines_agree(&scene, name, 64);
        let diff = image_difference(&reference, &image);
        eprintln!("{name}: mean |image - source's image| / mean = {diff:.4}");
        assert!(
            diff < 1.25 * noise,
            "{name}: the image is {diff} off the source's (noise {noise})"
        );
    }
}

/// The sample models' Draco engine: 34 primitives, the 65,311 triangles
/// gltf-transform's `inspect` counts, the bounds of the package's
/// uncompressed copy (made from another export: the meshes agree to
/// rounding, not their numbering) and its image, within noise.
#[test]
fn assimps_draco_engine_loads_as_its_uncompressed_copy() {
    if !Path::new(ASSIMP_DRACO).is_file() {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "{ASSIMP_DRACO} is missing: CI installs assimp-testmodels (.ci/run)"
        );
        eprintln!("SKIPPED: {ASSIMP_DRACO} is missing (apt-get install assimp-testmodels)");
        return;
    }
    let start = std::time::Instant::now();
    let a = gltf::load(Path::new(ASSIMP_DRACO)).unwrap();
    eprintln!(
        "2CylinderEngine.gltf (Draco): loaded in {:?}",
        start.elapsed()
    );
    let b = gltf::load(Path::new(ASSIMP_PLAIN)).unwrap();
    assert_eq!(a.meshes.len(), 34);
    assert_eq!(a.unique_triangles(), 65_311);
    // The uncompressed copy has 6 more instanced triangles: Draco merged
    // vertices of a few slivers, which became degenerate and are dropped.
    eprintln!(
        "instanced triangles: {} (Draco), {}",
        a.instanced_triangles(),
        b.instanced_triangles()
    );
    assert!(a.instanced_triangles().abs_diff(b.instanced_triangles()) <= 6);
    let bounds = |x: &Asset| {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = -lo;
        for inst in &x.instances {
            let t: Mat4 = inst.transform;
            for p in &x.meshes[inst.mesh as usize].positions {
                let q = t.transform_point3(*p);
                (lo, hi) = (lo.min(q), hi.max(q));
            }
        }
        (lo, hi)
    };
    let ((la, ha), (lb, hb)) = (bounds(&a), bounds(&b));
    let size = (hb - lb).max_element();
    eprintln!("bounds {la} {ha} and {lb} {hb}");
    assert!((la - lb).abs().max_element() < 1e-3 * size);
    assert!((ha - hb).abs().max_element() < 1e-3 * size);
    for m in &a.meshes {
        assert_eq!(m.normals.len(), m.positions.len(), "{}", m.name);
        assert!(m.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-3));
    }
    let load = |p: &str| asset_scene::load(Path::new(p), None).unwrap().0;
    let (sa, sb) = (load(ASSIMP_DRACO), load(ASSIMP_PLAIN));
    let ia = engines_agree(&sa, "2CylinderEngine (Draco)", 16);
    let ib = render(&sb, Engine::Reference, 16).to_rgb();
    let noise = image_difference(&ib, &render_seeded(&sb, Engine::Reference, 16, 1).to_rgb());
    let diff = image_difference(&ib, &ia);
    eprintln!("2CylinderEngine: |Draco - uncompressed| / mean = {diff:.4} (noise {noise:.4})");
    assert!(
        diff < 1.25 * noise,
        "the image is {diff} off the uncompressed one's"
    );
}

/// The edgebreaker file's JSON with `edit` applied, its bytes otherwise
/// as they are.
fn edited(edit: impl Fn(&mut Value, &mut Vec<u8>)) -> Vec<u8> {
    let (mut json, mut bin) = split_glb(&data("tests/data/draco/textured-draco.glb"));
    edit(&mut json, &mut bin);
    glb(&json, &bin)
}

/// Hostile Draco primitives: each refused naming the file and its JSON
/// path, never a panic, before anything of a declared size is allocated.
#[test]
fn hostile_draco_primitives_are_refused_with_their_json_path() {
    let p3 = "meshes[3].primitives[0]";
    let ext = format!("{p3}.extensions.{EXT}");
    // Mesh 3, the coloured wedge: indices accessor 9, POSITION 10,
    // TEXCOORD_0 11, COLOR_0 12; its stream is buffer view 6.
    type Edit = Box<dyn Fn(&mut Value, &mut Vec<u8>)>;
    let cases: Vec<(Edit, String, &str)> = vec![
        // Counts in the billions, the accessors agreeing with each
        // other: past the decoding budget, before the decode.
        (
            Box::new(|j, _| {
                for a in [10, 11, 12] {
                    j["accessors"][a]["count"] = json!(1u64 << 31);
                }
                j["accessors"][9]["count"] = json!(3u64 << 31);
            }),
            ext.clone(),
            "decoded data",
        ),
        // The stream's points not what POSITION declares.
        (
            Box::new(|j, _| j["accessors"][10]["count"] = json!(4)),
            format!("{ext}.attributes.POSITION"),
            "decodes 3 points",
        ),
        // Fewer points declared than the stream holds.
        (
            Box::new(|j, _| {
                for a in [10, 11, 12] {
                    j["accessors"][a]["count"] = json!(2);
                }
            }),
            format!("{ext}.attributes.COLOR_0"),
            "decodes 3 points",
        ),
        (
            Box::new(|j, _| j["accessors"][9]["count"] = json!(6)),
            format!("{p3}.indices"),
            "decodes 1 triangles",
        ),
        // An attribute id the stream does not have.
        (
            Box::new(|j, _| {
                j["meshes"][3]["primitives"][0]["extensions"][EXT]["attributes"]["COLOR_0"] =
                    json!(7)
            }),
            format!("{ext}.attributes.COLOR_0"),
            "Draco attribute 7 is not in the stream",
        ),
        // An attribute the primitive does not have.
        (
            Box::new(|j, _| {
                j["meshes"][3]["primitives"][0]["extensions"][EXT]["attributes"]["NORMAL"] =
                    json!(1)
            }),
            format!("{ext}.attributes.NORMAL"),
            "not among the primitive's attributes",
        ),
        // The wrong component type, and the wrong number of components.
        (
            Box::new(|j, _| {
                j["accessors"][11]["componentType"] = json!(5123);
                j["accessors"][11]["normalized"] = json!(true);
            }),
            format!("{ext}.attributes.TEXCOORD_0"),
            "accessors[11].componentType",
        ),
        (
            Box::new(|j, _| j["accessors"][12]["type"] = json!("VEC3")),
            format!("{ext}.attributes.COLOR_0"),
            "accessors[12].type",
        ),
        // The stream cut short, and not a stream at all.
        (
            Box::new(|j, _| j["bufferViews"][6]["byteLength"] = json!(40)),
            ext.clone(),
            "does not decode",
        ),
        (
            Box::new(|j, _| {
                j["meshes"][3]["primitives"][0]["extensions"][EXT]["bufferView"] = json!(0)
            }),
            ext.clone(),
            "does not decode",
        ),
        (
            Box::new(|j, _| {
                j["meshes"][3]["primitives"][0]["extensions"][EXT]["bufferView"] = json!(99)
            }),
            format!("{ext}.bufferView"),
            "buffer view 99 of 8",
        ),
        (
            Box::new(|j, _| j["meshes"][3]["primitives"][0]["extensions"][EXT]["bogus"] = json!(1)),
            ext.clone(),
            "bogus",
        ),
        // A fan (points and lines are skipped before), no indices,
        // indices of floats.
        (
            Box::new(|j, _| j["meshes"][3]["primitives"][0]["mode"] = json!(6)),
            format!("{p3}.mode"),
            "TRIANGLES or TRIANGLE_STRIP",
        ),
        (
            Box::new(|j, _| {
                j["meshes"][3]["primitives"][0]
                    .as_object_mut()
                    .unwrap()
                    .remove("indices");
                // Its accessor, now no Draco primitive's, given data.
                j["accessors"][9]["bufferView"] = json!(0);
            }),
            format!("{p3}.indices"),
            "none",
        ),
        (
            Box::new(|j, _| j["accessors"][9]["componentType"] = json!(5126)),
            format!("{p3}.indices"),
            "u8, u16 or u32",
        ),
    ];
    for (k, (edit, path, why)) in cases.into_iter().enumerate() {
        let bytes = edited(edit);
        let r = std::panic::catch_unwind(|| gltf::read(&bytes, "test.glb", None));
        let e = r
            .unwrap_or_else(|_| panic!("case {k}: a panic"))
            .err()
            .unwrap_or_else(|| panic!("case {k}: not refused"))
            .to_string();
        eprintln!("case {k}: {e}");
        assert!(
            e.starts_with(&format!("test.glb: {path}")),
            "case {k}: {path}: {e}"
        );
        assert!(e.contains(why), "case {k}: {why:?} in {e}");
    }
    // Indices declared as u8 (the cube's 24 points fit): read as such.
    let bytes = edited(|j, _| j["accessors"][3]["componentType"] = json!(5121));
    assert!(gltf::read(&bytes, "test.glb", None).is_ok());
}

/// Every byte of the Draco streams flipped, and the binary chunk cut
/// short at each length through them: loaded or refused naming the file,
/// never a panic; what loads is in range.
#[test]
fn flipped_and_truncated_draco_streams_never_panic() {
    for name in ["textured-draco.glb", "textured-draco-sequential.glb"] {
        let (json, bin) = split_glb(&data(&format!("tests/data/draco/{name}")));
        let streams: Vec<usize> = (json["meshes"].as_array().unwrap().iter())
            .map(|m| {
                m["primitives"][0]["extensions"][EXT]["bufferView"]
                    .as_u64()
                    .unwrap() as usize
            })
            .collect();
        let first = streams
            .iter()
            .map(|&v| json["bufferViews"][v]["byteOffset"].as_u64().unwrap() as usize)
            .min()
            .unwrap();
        glb_mutations_never_panic(name, &json, &bin, first, &[0x5a, 0x01]);
    }
}
