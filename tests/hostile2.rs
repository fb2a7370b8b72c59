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
    let dir = TempDir::new("polyline");
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nl 1 2 3 4\np 1 2\nf 1 2 3\n  l 2 3 4\nf 2 4 3\n";
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let mesh = wavetrace::scene::obj::load(&dir.join("m.obj"), false).unwrap();
    assert_eq!(mesh.triangles.len(), 2, "the two faces, no polyline");
}

/// A real model with a `vn 0 0 0` (common in exports) was refused where it
/// used to render: the corners that use it take their face's flat normal,
/// the others keep theirs.
#[test]
fn obj_zero_vertex_normals_fall_back_to_the_flat_normal() {
    let dir = TempDir::new("vn0");
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nvn 0.6 0 0.8\nf 1//1 2//2 3//1\n";
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let mesh = wavetrace::scene::obj::load(&dir.join("m.obj"), false).unwrap();
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
