//! Hostile input, round two (issue 25): every reproduction that fell short
//! — a panic, an input overwritten, a black image, a runaway allocation, a
//! NaN accepted, a flag unbounded — as a regression test: each now ends in
//! a clean error or a correct image, with nothing overwritten.

mod common;

use common::*;
use glam::Vec3;
use std::process::Command;
use wavetrace::accel::bvh::{Bvh, BvhOptions};
use wavetrace::accel::simd::SimdWidth;
use wavetrace::accel::sphere::Sphere;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;

/// A file of the hostile corpus, `tests/data/hostile/NAME`.
fn data(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/hostile")
        .join(name)
}

/// `cornell-spheres.toml` with its glass ball's index of refraction `ior`.
fn spheres_with_ior(ior: &str) -> String {
    let text = std::fs::read_to_string("scenes/cornell-spheres.toml").unwrap();
    assert!(text.contains("ior = 1.5\n"), "the glass ball's index");
    text.replacen("ior = 1.5\n", &format!("ior = {ior}\n"), 1)
}

// --- 1. Glass of extreme index: refused at load; beyond it, no NaN ---

/// `ior = 1e20` (or 1e-20) was accepted and the render panicked (exit 101,
/// `unreachable!` in the hierarchy's walk): now refused naming the file,
/// line, field and the range.
#[test]
fn an_extreme_index_of_refraction_is_refused_naming_the_field() {
    let dir = TempDir::new("ior");
    for ior in ["1e20", "1e-20", "10.5", "0.09", "0"] {
        std::fs::write(dir.join("s.toml"), spheres_with_ior(ior)).unwrap();
        let e = run_refused(&dir, &["s.toml", "--spp", "1", "--out", "o.png"]);
        assert!(
            e.contains("s.toml:")
                && e.contains("materials.glass.ior")
                && e.contains("from 0.1 to 10"),
            "{ior}: {e}"
        );
        assert!(!e.contains("panicked"), "{e}");
        assert!(!dir.join("o.png").exists());
    }
    for ior in ["0.1", "10", "2.42"] {
        std::fs::write(dir.join("s.toml"), spheres_with_ior(ior)).unwrap();
        run_ok(
            &dir,
            &[
                "s.toml", "--spp", "1", "--width", "8", "--height", "8", "--out", "o.png",
            ],
        );
    }
}

/// Glass built in code beyond the range (the loader's range does not hold
/// there) scatters without a NaN direction: every engine and width renders
/// the scene with no invalid sample and no panic.
#[test]
fn glass_beyond_the_range_scatters_without_a_nan_direction() {
    let base = Scene::load(std::path::Path::new("scenes/cornell-spheres.toml")).unwrap();
    for ior in [1e20, 1e-20, f32::MAX, f32::MIN_POSITIVE, 1e-45] {
        let mut scene = base.clone();
        for m in &mut scene.materials {
            m.ior = ior;
        }
        for engine in [Engine::Reference, Engine::Wavefront] {
            for simd in [SimdWidth::W8, SimdWidth::W16] {
                if !simd.is_available() {
                    continue;
                }
                let mut s = RenderSettings::for_scene(&scene);
                (s.width, s.height, s.spp, s.engine, s.simd) = (24, 24, 4, engine, simd);
                let (film, _, _) = Renderer::new(&scene, &s).unwrap().render();
                assert_eq!(film.invalid_samples, 0, "ior {ior}, {engine:?} {simd:?}");
            }
        }
    }
}

/// A ray with a NaN or infinite coordinate misses everything — one ray or
/// columns, closest or any hit, 8 or 16 lanes, in a tree of one node (whose
/// empty child slots such a ray's box test used to "enter", reaching
/// `unreachable!`) and in a deep one.
#[test]
fn a_nan_ray_misses_in_every_query() {
    let cornell = Scene::cornell();
    let small = wavetrace::accel::scene_triangles(&cornell);
    let deep: Vec<_> = (0..2000)
        .map(|i| {
            let c = Vec3::new((i % 13) as f32, (i / 13 % 11) as f32, (i / 143) as f32);
            wavetrace::accel::triangle::TriangleEdges::new(c, c + Vec3::X, c + Vec3::Y)
        })
        .collect();
    let ball = [Sphere::new(Vec3::new(0.2, 0.5, 0.1), 0.3)];
    let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
    // One leaf; one node of two leaves (triangles, a sphere) and six empty
    // slots; many nodes.
    let trees: [(&[_], &[Sphere]); 4] = [
        (&small[..], &[]),
        (&small[..], &ball),
        (&small[..2], &ball),
        (&deep[..], &ball),
    ];
    for (tris, spheres) in trees {
        for width in [SimdWidth::W8, SimdWidth::W16] {
            if !width.is_available() {
                continue;
            }
            let bvh = Bvh::build_prims(tris, spheres, &BvhOptions { width });
            for x in bad {
                for (o, d) in [
                    (Vec3::new(x, 0.0, -3.0), Vec3::Z),
                    (Vec3::new(0.0, 0.0, -3.0), Vec3::new(0.0, x, 1.0)),
                    (Vec3::splat(x), Vec3::splat(x)),
                ] {
                    let at = format!("{} triangles, {width:?}, ({o}, {d})", tris.len());
                    assert_eq!(bvh.closest_hit(o, d, 0.0, f32::INFINITY), None, "{at}");
                    assert!(!bvh.occluded(o, d, 0.0, f32::INFINITY), "{at}");
                    let n = 37;
                    let oc = o.to_array().map(|c| vec![c; n]);
                    let dc = d.to_array().map(|c| vec![c; n]);
                    let (oc, dc) = (oc.each_ref().map(|c| &c[..]), dc.each_ref().map(|c| &c[..]));
                    let (mut t, mut prim) = (vec![0.0; n], vec![0; n]);
                    bvh.closest_hits_columns(oc, dc, (0.0, f32::INFINITY), &mut t, &mut prim);
                    assert!(prim.iter().all(|&p| p == u32::MAX), "{at}: {prim:?}");
                    let mut out = vec![true; n];
                    bvh.occluded_columns(oc, dc, 0.0, &vec![f32::INFINITY; n], &mut out);
                    assert!(out.iter().all(|&b| !b), "{at}");
                }
            }
        }
    }
}

// --- 7. Flags bounded ---

/// `bench --repeats 18446744073709551615` ran forever (its progress total
/// wrapped): a count outside 1..=1000 is refused as a malformed command
/// line, at once.
#[test]
fn bench_repeats_is_bounded() {
    let dir = TempDir::new("repeats");
    for n in ["18446744073709551615", "0", "1001", "x"] {
        let o = run_with_limit(&dir, &["bench", "--tiny", "--repeats", n], PATIENCE);
        assert_eq!(o.status.code(), Some(2), "{n}: {}", text(&o));
        assert!(stderr(&o).contains("from 1 to 1000"), "{n}: {}", text(&o));
    }
}

/// `converge --prefix /abs/path` wrote its files there, outside
/// `--out-dir`: the prefix must be a plain name; nothing is written.
#[test]
fn converge_prefix_is_a_plain_name() {
    let dir = TempDir::new("prefix");
    let away = dir.join("away");
    std::fs::create_dir(&away).unwrap();
    let abs = away.join("p").display().to_string();
    for prefix in [abs.as_str(), "../p", "a/b", "", ".", ".."] {
        let o = run(
            &dir,
            &[
                "converge",
                "--out-dir",
                "out",
                "--prefix",
                prefix,
                "--spp",
                "2",
            ],
        );
        assert_eq!(o.status.code(), Some(2), "{prefix:?}: {}", text(&o));
        assert!(stderr(&o).contains("plain file name"), "{}", text(&o));
    }
    assert_eq!(std::fs::read_dir(&away).unwrap().count(), 0);
    assert!(!dir.join("out").exists());
}

// --- 5, 6. References and images to denoise hold radiance ---

/// `--reference nan.pfm` printed relMSE NaN and wrote `null` into the
/// stats, exit 0; `denoise` passed NaN, infinite and negative pixels to
/// OIDN. Both now refuse the file before any work, naming its first bad
/// pixel, for render, converge and denoise alike.
#[test]
fn references_and_images_to_denoise_must_be_radiance() {
    let dir = TempDir::new("radiance");
    let (w, h) = (4u32, 3u32);
    let cases = [
        ("nan.pfm", f32::NAN, "NaN"),
        ("inf.exr", f32::INFINITY, "inf"),
        ("neg.pfm", -0.5, "-0.5"),
    ];
    for (name, bad, shown) in cases {
        let mut rgb = vec![[0.25f32; 3]; (w * h) as usize];
        rgb[(2 * w + 1) as usize][1] = bad; // pixel (1, 2), green
        wavetrace::output::write_image(&dir.join(name), w, h, &rgb).unwrap();
        let size = ["--width", "4", "--height", "3", "--spp", "1"];
        let runs: [Vec<&str>; 3] = [
            [
                &["--reference", name, "--out", "o.png", "--stats", "s.json"][..],
                &size[..],
            ]
            .concat(),
            [
                &["converge", "--reference", name, "--out-dir", "c"][..],
                &size[..],
            ]
            .concat(),
            vec!["denoise", name, "--out", "d.exr"],
        ];
        for args in runs {
            let e = run_refused(&dir, &args);
            let role = if args[0] == "denoise" {
                "of the image to denoise"
            } else {
                "of the reference"
            };
            assert!(
                e.contains(name)
                    && e.contains(&format!("pixel (1, 2) {role}"))
                    && e.contains(shown)
                    && e.contains("finite and non-negative"),
                "{args:?}: {e}"
            );
            assert!(!e.contains("panicked"), "{e}");
        }
        for out in ["o.png", "s.json", "c", "d.exr"] {
            assert!(!dir.join(out).exists(), "{name}: {out} was written");
        }
    }
    // A clean reference of the same size is accepted.
    let clean = vec![[0.25f32; 3]; (w * h) as usize];
    wavetrace::output::write_image(&dir.join("ok.pfm"), w, h, &clean).unwrap();
    run_ok(
        &dir,
        &[
            "--reference",
            "ok.pfm",
            "--width",
            "4",
            "--height",
            "3",
            "--spp",
            "1",
            "--out",
            "o.png",
        ],
    );
}

// --- 4. An EXR header that declares more than its file can hold ---

/// Set an EXR's `name` box (dataWindow, displayWindow) to `side`² pixels.
fn forge_exr_box(bytes: &mut [u8], name: &str, side: i32) {
    let key = format!("{name}\0box2i\0");
    let at = bytes
        .windows(key.len())
        .position(|w| w == key.as_bytes())
        .unwrap_or_else(|| panic!("{name} in the header"))
        + key.len()
        + 4;
    bytes[at..at + 16]
        .copy_from_slice(&[0i32, 0, side - 1, side - 1].map(i32::to_le_bytes).concat());
}

/// A small EXR whose header declared 30000×30000 pixels made `denoise`,
/// `--reference` and `converge --reference` reserve 10.8 GB: the pixel data
/// the header declares is now checked against what the file's bytes can
/// hold (at the compression's largest ratio) before anything is allocated.
#[test]
fn an_exr_header_larger_than_its_file_is_refused() {
    let dir = TempDir::new("exrsize");
    let rgb = vec![[0.5f32; 3]; 64];
    wavetrace::output::write_image(&dir.join("small.exr"), 8, 8, &rgb).unwrap();
    let mut bytes = std::fs::read(dir.join("small.exr")).unwrap();
    for name in ["dataWindow", "displayWindow"] {
        forge_exr_box(&mut bytes, name, 30000);
    }
    std::fs::write(dir.join("forged.exr"), &bytes).unwrap();
    let size = ["--width", "8", "--height", "8", "--spp", "1"];
    let runs: [Vec<&str>; 3] = [
        [
            &["--reference", "forged.exr", "--out", "o.png"][..],
            &size[..],
        ]
        .concat(),
        [
            &["converge", "--reference", "forged.exr", "--out-dir", "c"][..],
            &size[..],
        ]
        .concat(),
        vec!["denoise", "forged.exr", "--out", "d.exr"],
    ];
    for args in runs {
        let e = run_refused(&dir, &args);
        assert!(
            e.contains("forged.exr") && e.contains("30000x30000") && e.contains("can hold"),
            "{args:?}: {e}"
        );
    }
    for out in ["o.png", "c", "d.exr"] {
        assert!(!dir.join(out).exists(), "{out} was written");
    }
    // The file as written reads back.
    let back = wavetrace::output::read_image(&dir.join("small.exr")).unwrap();
    assert_eq!(back.rgb, rgb);
}

// --- 8. OBJ regressions of the first round ---

/// Polylines (`l a b c …`) and points made a real OBJ refused ("the faces
/// do not match the file's face lines": tobj reads a polyline of three
/// vertices or more as a face): they are skipped, the faces kept.
#[test]
fn obj_polylines_and_points_are_skipped() {
    let mesh = wavetrace::scene::obj::load(&data("polyline.obj"), false).unwrap();
    assert_eq!(mesh.triangles.len(), 2, "the two faces, no polyline");
}

/// A real model with a `vn 0 0 0` (common in exports) was refused where it
/// used to render: the corners that use it take their face's flat normal,
/// the others keep theirs.
#[test]
fn obj_zero_vertex_normals_fall_back_to_the_flat_normal() {
    let mesh = wavetrace::scene::obj::load(&data("zero-normal.obj"), false).unwrap();
    let flat = Vec3::Z; // (1,0,0) × (0,1,0)
    assert_eq!(
        mesh.normals,
        vec![Some([flat, Vec3::new(0.6, 0.0, 0.8), flat])]
    );
}

/// UTF-16 and binary-garbage OBJ files loaded as a mesh of no triangles,
/// without a word: a mesh that yields no face is refused, naming the file.
#[test]
fn an_obj_with_no_face_is_refused() {
    let dir = TempDir::new("noface");
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let utf16: Vec<u8> = [0xFF, 0xFE]
        .into_iter()
        .chain(text.encode_utf16().flat_map(u16::to_le_bytes))
        .collect();
    let garbage: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    for (name, bytes) in [
        ("utf16.obj", utf16),
        ("garbage.obj", garbage),
        ("lines.obj", b"v 0 0 0\nv 1 0 0\nl 1 2\n".to_vec()),
    ] {
        std::fs::write(dir.join(name), &bytes).unwrap();
        match wavetrace::scene::obj::load(&dir.join(name), false) {
            Err(e) => assert!(
                e.to_string().contains(name) && !e.to_string().is_empty(),
                "{name}: {e}"
            ),
            Ok(m) => panic!("{name}: loaded {} triangles", m.triangles.len()),
        }
    }
}

// --- 7. The address-space limit in the memory estimate ---

/// Renders of 7000² to 12000² under `ulimit -v 4G` aborted on allocation:
/// the estimate now includes the process's address-space limit, so they are
/// refused before any work (and the same render without the limit is not).
#[test]
fn the_address_space_limit_bounds_the_memory_estimate() {
    let dir = TempDir::new("rlimit");
    let args = [
        "--width", "8000", "--height", "8000", "--spp", "1", "--check",
    ];
    let mut limited = Command::new("sh");
    limited
        .current_dir(&dir)
        .arg("-c")
        .arg("ulimit -v 4000000 && exec \"$0\" \"$@\"")
        .arg(BIN)
        .args(args);
    let o = limited.output().unwrap();
    assert!(!o.status.success(), "{}", text(&o));
    let e = stderr(&o);
    assert!(e.contains("memory") && !e.contains("panicked"), "{e}");
    run_ok(&dir, &args);
}

// --- 2. No output over an input, nor over another output ---

/// Every file under `dir` (recursively) and its bytes, links as links.
fn snapshot(dir: &std::path::Path) -> Vec<(std::path::PathBuf, Vec<u8>)> {
    let mut all = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let path = e.unwrap().path();
            let meta = std::fs::symlink_metadata(&path).unwrap();
            if meta.is_dir() {
                stack.push(path);
            } else if meta.is_symlink() {
                let to = std::fs::read_link(&path).unwrap();
                all.push((path, to.into_os_string().into_encoded_bytes()));
            } else {
                all.push((path.clone(), std::fs::read(&path).unwrap()));
            }
        }
    }
    all.sort();
    all
}

/// `wavetrace args` in `dir` is refused before any work, with an error
/// that names `flag` and `file`, and leaves every file in `dir` as it was
/// (nothing overwritten, nothing made).
fn refused_keeping_inputs(dir: &std::path::Path, args: &[&str], flag: &str, file: &str) {
    let before = snapshot(dir);
    let e = run_refused(dir, args);
    assert!(
        e.contains(flag) && e.contains(file) && !e.contains("panicked"),
        "{args:?}: expected {flag} and {file} named: {e}"
    );
    assert!(
        snapshot(dir) == before,
        "{args:?}: a file was written or changed"
    );
}

/// A directory with the Cornell box (`s.toml`), the OBJ scene with its
/// mesh and MTL file (`obj.toml`, `meshes/`), a profile and a reference
/// image of 8x8 pixels (`r.pfm`).
fn inputs_dir(name: &str) -> TempDir {
    let dir = TempDir::new(name);
    std::fs::copy("scenes/cornell.toml", dir.join("s.toml")).unwrap();
    std::fs::copy("scenes/cornell-obj.toml", dir.join("obj.toml")).unwrap();
    std::fs::create_dir(dir.join("meshes")).unwrap();
    for f in ["crate.obj", "crate.mtl"] {
        std::fs::copy(format!("scenes/meshes/{f}"), dir.join("meshes").join(f)).unwrap();
    }
    std::fs::write(dir.join("p.toml"), "spp = 1\nwidth = 8\nheight = 8\n").unwrap();
    let rgb = vec![[0.25f32; 3]; 64];
    wavetrace::output::write_image(&dir.join("r.pfm"), 8, 8, &rgb).unwrap();
    // (An environment is an .exr or .hdr image.)
    wavetrace::output::write_image(&dir.join("r.exr"), 8, 8, &rgb).unwrap();
    dir
}

const SMALL: [&str; 6] = ["--width", "8", "--height", "8", "--spp", "1"];

/// `--stats s.toml` replaced the scene with JSON (exit 0); likewise
/// `--stats` naming a mesh, an MTL file or the profile, `--out` naming
/// the reference, an AOV file or `--keep-noisy` naming the scene or the
/// reference, and `--keep-noisy` and `--stats` one file. Each is refused
/// before any work, naming the flag and the file, with every file as it
/// was.
#[test]
fn a_render_refuses_an_output_that_is_an_input() {
    let dir = inputs_dir("render-over-input");
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("s.toml", dir.join("link.png")).unwrap();
        std::os::unix::fs::symlink("s.toml", dir.join("link.albedo.pfm")).unwrap();
        std::os::unix::fs::symlink("r.pfm", dir.join("ref-link.pfm")).unwrap();
        std::fs::hard_link(dir.join("s.toml"), dir.join("hard.png")).unwrap();
        std::fs::hard_link(dir.join("meshes/crate.mtl"), dir.join("mtl.json")).unwrap();
    }
    let with = |extra: &[&'static str]| [&SMALL[..], extra].concat();
    let mut cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (
            with(&["s.toml", "--out", "o.png", "--stats", "s.toml"]),
            "--stats",
            "s.toml",
        ),
        (
            with(&["s.toml", "--out", "o.png", "--stats", "./meshes/../s.toml"]),
            "--stats",
            "s.toml",
        ),
        (
            with(&["obj.toml", "--out", "o.png", "--stats", "meshes/crate.obj"]),
            "--stats",
            "meshes/crate.obj",
        ),
        (
            with(&["obj.toml", "--out", "o.png", "--stats", "meshes/crate.mtl"]),
            "--stats",
            "meshes/crate.mtl",
        ),
        (
            vec![
                "s.toml",
                "--profile",
                "p.toml",
                "--out",
                "o.png",
                "--stats",
                "p.toml",
            ],
            "--stats",
            "p.toml",
        ),
        (
            with(&["s.toml", "--out", "r.pfm", "--reference", "r.pfm"]),
            "--out",
            "r.pfm",
        ),
        (
            with(&[
                "s.toml",
                "--out",
                "o.png",
                "--stats",
                "r.pfm",
                "--reference",
                "r.pfm",
            ]),
            "--stats",
            "r.pfm",
        ),
        (
            with(&[
                "s.toml",
                "--out",
                "ref.pfm",
                "--aov",
                "albedo",
                "--reference",
                "ref.albedo.pfm",
            ]),
            "an AOV file of --out",
            "ref.albedo.pfm",
        ),
        (
            with(&[
                "s.toml",
                "--out",
                "o.pfm",
                "--denoise",
                "--keep-noisy",
                "r.pfm",
                "--reference",
                "r.pfm",
            ]),
            "--keep-noisy",
            "r.pfm",
        ),
        (
            with(&[
                "s.toml",
                "--out",
                "o.pfm",
                "--denoise",
                "--keep-noisy",
                "n.pfm",
                "--stats",
                "n.pfm",
            ]),
            "--keep-noisy",
            "n.pfm",
        ),
    ];
    // The environment image, of the scene or of --env.
    cases.push((
        with(&[
            "s.toml", "--env", "r.exr", "--out", "o.png", "--stats", "r.exr",
        ]),
        "--stats",
        "r.exr",
    ));
    // The reference of the AOV case, named like an AOV file of --out.
    std::fs::copy(dir.join("r.pfm"), dir.join("ref.albedo.pfm")).unwrap();
    for (args, flag, file) in &cases {
        refused_keeping_inputs(&dir, args, flag, file);
    }
    #[cfg(unix)]
    for (args, flag, file) in [
        (with(&["s.toml", "--out", "link.png"]), "--out", "link.png"),
        (with(&["s.toml", "--out", "hard.png"]), "--out", "hard.png"),
        (
            with(&["s.toml", "--out", "link.pfm", "--aov", "albedo"]),
            "an AOV file of --out",
            "s.toml",
        ),
        (
            with(&[
                "s.toml",
                "--out",
                "o.pfm",
                "--denoise",
                "--keep-noisy",
                "link.png",
            ]),
            "--keep-noisy",
            "s.toml",
        ),
        (
            with(&[
                "s.toml",
                "--out",
                "o.png",
                "--reference",
                "ref-link.pfm",
                "--stats",
                "r.pfm",
            ]),
            "--stats",
            "ref-link.pfm",
        ),
        (
            with(&["obj.toml", "--out", "o.png", "--stats", "mtl.json"]),
            "--stats",
            "mtl.json",
        ),
    ] {
        refused_keeping_inputs(&dir, &args, flag, file);
    }
    // The same runs with outputs of their own render.
    run_ok(
        &dir,
        &with(&["obj.toml", "--out", "o.png", "--stats", "st.json"]),
    );
    run_ok(
        &dir,
        &with(&["s.toml", "--out", "o.pfm", "--reference", "r.pfm"]),
    );
}

/// `denoise in.exr --out in.exr` denoised the image over itself; `merge
/// m.albedo.pfm --out m.pfm` wrote the merged albedo over the part; and
/// `converge` wrote its CSV over a scene named `converge.csv`. Refused,
/// naming the flag and the file, with every file as it was.
#[test]
fn denoise_merge_and_converge_refuse_an_output_that_is_an_input() {
    let dir = inputs_dir("commands-over-input");
    let rgb = vec![[0.25f32; 3]; 64];
    wavetrace::output::write_image(&dir.join("in.exr"), 8, 8, &rgb).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink("in.exr", dir.join("o.normal.pfm")).unwrap();
    for (args, flag, file) in [
        (
            vec!["denoise", "in.exr", "--out", "in.exr"],
            "--out",
            "in.exr",
        ),
        (
            vec!["denoise", "in.exr", "--out", "./in.exr"],
            "--out",
            "in.exr",
        ),
        (vec!["denoise", "r.pfm", "--out", "r.pfm"], "--out", "r.pfm"),
    ] {
        refused_keeping_inputs(&dir, &args, flag, file);
    }
    #[cfg(unix)]
    refused_keeping_inputs(
        &dir,
        &["denoise", "in.exr", "--out", "o.pfm"],
        "an AOV file of --out",
        "o.normal.pfm",
    );

    // A part with an albedo AOV, named as the merged image's albedo file.
    run_ok(
        &dir,
        &[
            &SMALL[..],
            &["s.toml", "--aov", "albedo", "--partial", "m.wtacc"],
        ]
        .concat(),
    );
    std::fs::rename(dir.join("m.wtacc"), dir.join("m.albedo.pfm")).unwrap();
    refused_keeping_inputs(
        &dir,
        &["merge", "m.albedo.pfm", "--out", "m.pfm"],
        "an AOV file of --out",
        "m.albedo.pfm",
    );
    // converge: its CSV over the scene (also through a folder that does
    // not exist yet), its JSON (a link) over the reference.
    std::fs::copy(dir.join("s.toml"), dir.join("converge.csv")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink("r.pfm", dir.join("c.json")).unwrap();
    let study = ["--width", "8", "--height", "8", "--spp", "2"];
    for (args, file) in [
        (
            vec!["converge", "converge.csv", "--reference", "r.pfm"],
            "converge.csv",
        ),
        (
            vec![
                "converge",
                "converge.csv",
                "--reference",
                "r.pfm",
                "--out-dir",
                "new/..",
            ],
            "converge.csv",
        ),
        (
            vec![
                "converge",
                "s.toml",
                "--reference",
                "r.pfm",
                "--prefix",
                "c",
            ],
            "c.json",
        ),
    ] {
        let args = [&args[..], &study[..]].concat();
        refused_keeping_inputs(&dir, &args, "--out-dir", file);
    }
}

// --- 8. Outputs that cannot be written ---

/// `--stats /dev/full` was refused only after the render, with the image
/// written: a device other than `/dev/null` or a terminal is now refused
/// as an output before any work, like a directory or a missing folder.
#[cfg(target_os = "linux")]
#[test]
fn an_output_that_cannot_take_a_file_is_refused_before_the_render() {
    let dir = inputs_dir("unwritable");
    std::fs::create_dir(dir.join("d")).unwrap();
    let render = |flag: &'static str, file: &'static str| {
        [&SMALL[..], &["s.toml", "--out", "o.png", flag, file]].concat()
    };
    for (args, file, why) in [
        (render("--stats", "/dev/full"), "/dev/full", "device (1:7)"),
        (render("--stats", "/dev/zero"), "/dev/zero", "device (1:5)"),
        (render("--stats", "/dev/urandom"), "/dev/urandom", "device"),
        (
            vec!["bench", "--tiny", "--json", "/dev/full"],
            "/dev/full",
            "device",
        ),
        (render("--stats", "d"), "d", "is a directory"),
        (render("--stats", "no/s.json"), "no/s.json", ""),
    ] {
        refused_keeping_inputs(&dir, &args, file, why);
    }
    // /dev/null takes any output.
    run_ok(&dir, &render("--stats", "/dev/null"));
}

/// A `--stats` file that fails only when written, after the render (here
/// the file-size limit, `ulimit -f`, as a full disk would), leaves the
/// image written whole, no half-written stats file, and exits 1 naming
/// the file.
#[cfg(target_os = "linux")]
#[test]
fn a_stats_file_that_fails_after_the_render_leaves_the_image() {
    use std::os::unix::process::CommandExt;
    let dir = inputs_dir("late-failure");
    let mut cmd = wavetrace(
        &dir,
        &[
            &SMALL[..],
            &["s.toml", "--out", "o.png", "--stats", "st.json"],
        ]
        .concat(),
    );
    // SAFETY: only async-signal-safe calls (setrlimit, signal) between
    // fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: 1024,
                rlim_max: 1024,
            };
            libc::setrlimit(libc::RLIMIT_FSIZE, &limit);
            // Writing past the limit fails with EFBIG instead of a signal.
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let o = finish(&mut cmd, PATIENCE);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let e = stderr(&o);
    assert!(e.contains("st.json") && e.contains("too large"), "{e}");
    let image = image::open(dir.join("o.png")).unwrap();
    assert_eq!((image.width(), image.height()), (8, 8));
    assert!(!dir.join("st.json").exists());
    assert!(
        !dir.files().iter().any(|f| f.ends_with(".tmp")),
        "{:?}",
        dir.files()
    );
}
