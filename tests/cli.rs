//! The `wavetrace` binary, run as a user runs it.
//!
//! Every render here is tiny (16×12 pixels, 2 samples per pixel). Each test
//! works in its own fresh folder (`common::TempDir`).

mod common;

use common::{TINY, TempDir, run, run_ok, run_with_limit, settings, stderr, tiny};
use std::path::Path;
use std::time::Duration;
use wavetrace::render::Renderer;
use wavetrace::scene::Scene;

/// Runs a command that must be refused at once, with `message` in its
/// error, leaving nothing behind in `dir`.
///
/// "At once": unless it sets `--spp` itself, every refusal asks for a render
/// that would take hours (256×256 at 10^6 samples per pixel) if it started
/// before refusing.
fn assert_refused(dir: &TempDir, args: &[&str], message: &str) {
    let mut all = if args.contains(&"--spp") {
        vec![]
    } else {
        vec!["--spp", "1000000"]
    };
    all.extend_from_slice(args);
    let o = run_with_limit(dir, &all, Duration::from_secs(60));
    let err = stderr(&o);
    assert!(!o.status.success(), "wavetrace {all:?} was not refused");
    assert!(
        err.contains(message),
        "wavetrace {all:?}: error {err:?} should contain {message:?}"
    );
    assert!(
        dir.files().is_empty(),
        "wavetrace {all:?} left files behind: {:?}",
        dir.files()
    );
}

#[test]
fn impossible_settings_are_refused_before_any_work() {
    let dir = TempDir::new("refused");
    let out = dir.join("x.png");
    let out = out.to_str().unwrap();
    assert_refused(&dir, &["--spp", "0", "--out", out], "samples per pixel");
    assert_refused(&dir, &["--width", "0", "--out", out], "1x1");
    assert_refused(&dir, &["--height", "0", "--out", out], "1x1");
    assert_refused(
        &dir,
        &["--width", "0", "--height", "0", "--out", out],
        "1x1",
    );
    assert_refused(&dir, &["--max-depth", "0", "--out", out], "max depth");
    assert_refused(&dir, &["--threads", "0", "--out", out], "threads");
    assert_refused(
        &dir,
        &["--profile", "nope", "--out", out],
        "unknown profile",
    );
    assert_refused(&dir, &["--out", "x.jpg"], "unknown image format");
    assert_refused(&dir, &["--out", "x"], "unknown image format");
    let missing = dir.join("no-such-dir/x.png");
    assert_refused(
        &dir,
        &["--out", missing.to_str().unwrap()],
        missing.to_str().unwrap(),
    );
    // The stats file is checked before the render, too: no image appears.
    let stats = dir.join("no-such-dir/stats.json");
    assert_refused(
        &dir,
        &["--out", out, "--stats", stats.to_str().unwrap()],
        stats.to_str().unwrap(),
    );
    // A profile file that does not exist.
    let profile = dir.join("missing-profile.toml");
    assert_refused(
        &dir,
        &["--profile", profile.to_str().unwrap(), "--out", out],
        "missing-profile.toml",
    );
    // Flags the command line does not know.
    assert_refused(&dir, &["--engine", "warp", "--out", out], "warp");
    assert_refused(&dir, &["--samples", "4", "--out", out], "--samples");
    assert_refused(&dir, &["--spp", "-3", "--out", out], "-3");
    assert_refused(&dir, &["--batch-size", "0", "--out", out], "batch size");
    assert_refused(
        &dir,
        &["--batch-size", "18446744073709551615", "--out", out],
        "batch size",
    );
    assert_refused(&dir, &["--max-depth", "100000", "--out", out], "max depth");
    // Two outputs that are one file, however the paths are spelled.
    let stats = dir.join("s.json");
    let stats = stats.to_str().unwrap();
    let dotted = format!("{}/./s.json", dir.join("").display());
    assert_refused(
        &dir,
        &["--out", out, "--stats", stats, "--checkpoint", &dotted],
        "name the same file",
    );
}

#[test]
fn the_stats_file_has_every_field_and_they_agree() {
    let dir = TempDir::new("stats");
    let (out, stats) = (dir.join("img.png"), dir.join("stats.json"));
    let o = run_ok(
        &dir,
        &[
            "render",
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "3",
            "--max-depth",
            "4",
            "--seed",
            "77",
            "--threads",
            "2",
            "--engine",
            "reference",
            "--out",
            out.to_str().unwrap(),
            "--stats",
            stats.to_str().unwrap(),
        ],
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    for field in [
        "scene",
        "width",
        "height",
        "spp",
        "max_depth",
        "seed",
        "threads",
        "engine",
        "seconds",
        "paths",
        "rays",
        "shadow_rays",
        "rays_per_second",
        "paths_per_second",
    ] {
        assert!(j.get(field).is_some(), "stats lack {field:?}: {j}");
    }
    let u = |k: &str| {
        j[k].as_u64()
            .unwrap_or_else(|| panic!("{k} is not a count: {j}"))
    };
    let f = |k: &str| {
        j[k].as_f64()
            .unwrap_or_else(|| panic!("{k} is not a number: {j}"))
    };
    assert_eq!(j["scene"], "cornell-dh2323");
    assert_eq!(j["engine"], "reference");
    assert_eq!(
        (u("width"), u("height"), u("spp"), u("max_depth")),
        (16, 12, 3, 4)
    );
    assert_eq!((u("seed"), u("threads")), (77, 2));
    let (paths, rays, shadow) = (u("paths"), u("rays"), u("shadow_rays"));
    assert_eq!(paths, 16 * 12 * 3);
    // At least the camera ray, at most max_depth closest-hit rays per path,
    // and at most one shadow ray per vertex that scatters.
    let closest = rays - shadow;
    assert!(
        closest >= paths && closest <= paths * 4 && shadow <= paths * 3,
        "rays {rays} ({shadow} shadow), paths {paths}"
    );
    let seconds = f("seconds");
    assert!(seconds > 0.0 && seconds < 60.0, "seconds {seconds}");
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1.0);
    assert!(close(f("rays_per_second"), rays as f64 / seconds), "{j}");
    assert!(close(f("paths_per_second"), paths as f64 / seconds), "{j}");
    // The same counts as the library's renderer with the same settings.
    let scene = Scene::cornell();
    let mut s = settings(&scene, 16, 12, 3);
    (s.max_depth, s.seed, s.threads) = (4, 77, 2);
    let (_, counters, _) = Renderer::new(&scene, &s).unwrap().render();
    assert_eq!((paths, rays), (counters.paths, counters.rays));
    // And the figures are printed.
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains(&paths.to_string()), "{stdout}");
    assert!(stdout.contains(&rays.to_string()), "{stdout}");
    assert!(
        stdout.contains("rays/s") && stdout.contains("paths/s"),
        "{stdout}"
    );
    assert_eq!(dir.files(), ["img.png", "stats.json"]);
}

/// A PFM's size and its pixels, row 0 at the top.
fn read_pfm(path: &Path) -> (usize, usize, Vec<[f32; 3]>) {
    let bytes = std::fs::read(path).unwrap();
    // Three header lines: "PF", "W H", scale (negative: little-endian).
    let mut lines = 0;
    let mut end = 0;
    while lines < 3 {
        if bytes[end] == b'\n' {
            lines += 1;
        }
        end += 1;
    }
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    let h: Vec<&str> = header.split_whitespace().collect();
    assert_eq!(h[0], "PF", "colour PFM");
    let (w, ht): (usize, usize) = (h[1].parse().unwrap(), h[2].parse().unwrap());
    let scale: f32 = h[3].parse().unwrap();
    assert!(scale < 0.0, "little-endian PFM expected, scale {scale}");
    let data = &bytes[end..];
    assert_eq!(data.len(), w * ht * 12, "PFM data length for {w}x{ht}");
    let floats: Vec<f32> = data
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    // PFM rows run bottom to top.
    let mut rgb = Vec::with_capacity(w * ht);
    for row in floats.chunks_exact(w * 3).rev() {
        rgb.extend(row.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
    }
    (w, ht, rgb)
}

fn read_exr(path: &Path) -> (usize, usize, Vec<[f32; 3]>) {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required("R")
        .required("G")
        .required("B")
        .collect_pixels(
            |size: Vec2<usize>,
             _: &(ChannelDescription, ChannelDescription, ChannelDescription)| {
                (size.0, vec![[0.0f32; 3]; size.0 * size.1])
            },
            |(w, px): &mut (usize, Vec<[f32; 3]>), p: Vec2<usize>, (r, g, b): (f32, f32, f32)| {
                px[p.1 * *w + p.0] = [r, g, b];
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .unwrap();
    let layer = &image.layer_data;
    // Stored as 32-bit floats, not halves.
    let (r, g, b) = &layer.channel_data.channels;
    for c in [r, g, b] {
        assert_eq!(c.sample_type, SampleType::F32, "channel {}", c.name);
    }
    let (w, h) = (layer.size.0, layer.size.1);
    (w, h, layer.channel_data.pixels.1.clone())
}

fn srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.0031308 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

#[test]
fn png_exr_and_pfm_outputs_agree_with_each_other_and_the_library() {
    let dir = TempDir::new("formats");
    let flags = [TINY.as_slice(), &["--seed", "3", "--threads", "2"]].concat();
    for name in ["img.png", "img.exr", "img.pfm"] {
        let out = dir.join(name);
        let mut args = flags.clone();
        args.extend(["--out", out.to_str().unwrap()]);
        run_ok(&dir, &args);
    }
    assert_eq!(dir.files(), ["img.exr", "img.pfm", "img.png"]);

    let (w, h, pfm) = read_pfm(&dir.join("img.pfm"));
    assert_eq!((w, h), (16, 12));
    // The linear pixels are the library's film, exactly.
    let scene = Scene::cornell();
    let mut s = tiny(&scene);
    (s.seed, s.threads) = (3, 1);
    let (film, _, _) = Renderer::new(&scene, &s).unwrap().render();
    assert!(pfm == film.to_rgb(), "the PFM is not the film's mean");
    assert!(pfm.iter().any(|p| p[1] > 0.0), "the PFM is black");

    let (ew, eh, exr) = read_exr(&dir.join("img.exr"));
    assert_eq!((ew, eh), (16, 12));
    for (i, (a, b)) in exr.iter().zip(&pfm).enumerate() {
        assert_eq!(
            a.map(f32::to_bits),
            b.map(f32::to_bits),
            "pixel {i}: EXR {a:?} vs PFM {b:?}"
        );
    }

    let png = image::open(dir.join("img.png")).unwrap();
    assert_eq!((png.width(), png.height()), (16, 12));
    let png = png.to_rgb8();
    for (i, (p, f)) in png.pixels().zip(&pfm).enumerate() {
        for (c, (&byte, &linear)) in p.0.iter().zip(f).enumerate() {
            let want = (srgb(linear) * 255.0).round() as i32;
            assert!(
                (byte as i32 - want).abs() <= 1,
                "pixel {i} channel {c}: PNG {byte} vs sRGB of {linear} = {want}"
            );
        }
    }
}

#[test]
fn a_scene_error_names_the_file_and_line() {
    let dir = TempDir::new("scene-error");
    let scene = dir.join("bad.toml");
    let text = wavetrace::scene::CORNELL_TOML.replacen(
        "reflectance = [0.15, 0.75, 0.15]",
        "reflectance = [0.15, 7.5, 0.15]",
        1,
    );
    let line = text
        .lines()
        .position(|l| l.contains("7.5"))
        .expect("the Cornell box's floor reflectance")
        + 1;
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("bad.png");
    let o = run(
        &dir,
        &[
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--spp",
            "1",
        ],
    );
    assert!(!o.status.success());
    let err = stderr(&o);
    let place = format!("{}:{line}:", scene.display());
    assert!(err.contains(&place), "{err:?} should name {place}");
    assert!(err.contains("materials.floor.reflectance"), "{err}");
    assert!(!out.exists());
    // A scene file that does not exist.
    let missing = dir.join("missing.toml");
    let o = run(&dir, &[missing.to_str().unwrap(), "--spp", "1"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains(missing.to_str().unwrap()),
        "{}",
        stderr(&o)
    );
    assert_eq!(dir.files(), ["bad.toml"]);
}

#[test]
fn a_scene_file_renders_to_its_own_name_and_render_is_the_default_command() {
    let dir = TempDir::new("default-out");
    std::fs::write(dir.join("box.toml"), wavetrace::scene::CORNELL_TOML).unwrap();
    // No --out: the image is the scene's name with .png, in the current folder.
    run_ok(&dir, &[["box.toml"].as_slice(), &TINY].concat());
    assert_eq!(dir.files(), ["box.png", "box.toml"]);
    // `render` and no command are the same thing; the file is replaced whole.
    let first = std::fs::read(dir.join("box.png")).unwrap();
    run_ok(&dir, &[["render", "box.toml"].as_slice(), &TINY].concat());
    assert_eq!(std::fs::read(dir.join("box.png")).unwrap(), first);
    assert_eq!(dir.files(), ["box.png", "box.toml"]);
    // And the built-in scene is the same Cornell box.
    run_ok(&dir, &[TINY.as_slice(), &["--out", "builtin.png"]].concat());
    assert_eq!(std::fs::read(dir.join("builtin.png")).unwrap(), first);
}

#[test]
fn flags_override_the_profile_which_overrides_the_scene() {
    let dir = TempDir::new("profile");
    std::fs::write(
        dir.join("mine.toml"),
        "width = 8\nheight = 6\nspp = 3\nmax_depth = 2\nseed = 9\n",
    )
    .unwrap();
    let stats = |args: &[&str]| -> serde_json::Value {
        let mut all = vec!["--out", "x.pfm", "--stats", "s.json"];
        all.extend_from_slice(args);
        run_ok(&dir, &all);
        serde_json::from_str(&std::fs::read_to_string(dir.join("s.json")).unwrap()).unwrap()
    };
    let j = stats(&["--profile", "./mine.toml"]);
    let got = |j: &serde_json::Value, k: &str| j[k].as_u64().unwrap();
    assert_eq!(
        ["width", "height", "spp", "max_depth", "seed"].map(|k| got(&j, k)),
        [8, 6, 3, 2, 9]
    );
    let j = stats(&["--profile", "./mine.toml", "--spp", "1", "--width", "4"]);
    assert_eq!(
        ["width", "height", "spp", "max_depth", "seed"].map(|k| got(&j, k)),
        [4, 6, 1, 2, 9]
    );
    // A built-in profile: preview is 16 spp at the scene's max depth (3).
    let j = stats(&["--profile", "preview", "--width", "4", "--height", "4"]);
    assert_eq!(
        ["width", "height", "spp", "max_depth"].map(|k| got(&j, k)),
        [4, 4, 16, 3]
    );
    // A profile with an unknown key is refused.
    std::fs::write(dir.join("bad.toml"), "spp = 2\nsamples = 3\n").unwrap();
    let o = run(&dir, &["--profile", "./bad.toml", "--out", "y.png"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("samples"), "{}", stderr(&o));
    assert!(!dir.join("y.png").exists());
}

/// `--simd 8` and `--simd 16` (where the CPU has AVX-512) give the same
/// bytes for every integrator, and the stats say which kernels ran; a width
/// the CPU lacks, or one that does not exist, is refused before work
/// starts.
#[test]
fn both_kernel_widths_give_the_same_image() {
    let dir = TempDir::new("simd");
    let has16 = wavetrace::accel::simd::SimdWidth::W16.is_available();
    for integrator in ["report", "bsdf", "nee"] {
        let mut images = vec![];
        for lanes in ["8", "16"] {
            if lanes == "16" && !has16 {
                continue;
            }
            let out = dir.path().join(format!("{integrator}-{lanes}.pfm"));
            let stats = dir.path().join(format!("{integrator}-{lanes}.json"));
            run_ok(
                &dir,
                &[
                    concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/sphere-1m.toml"),
                    "--width",
                    "24",
                    "--height",
                    "16",
                    "--spp",
                    "2",
                    "--integrator",
                    integrator,
                    "--simd",
                    lanes,
                    "--out",
                    out.to_str().unwrap(),
                    "--stats",
                    stats.to_str().unwrap(),
                ],
            );
            let j: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
            assert_eq!(j["kernel_lanes"].as_u64(), Some(lanes.parse().unwrap()));
            images.push(std::fs::read(&out).unwrap());
        }
        assert!(images.windows(2).all(|w| w[0] == w[1]), "{integrator}");
    }
    if !has16 {
        assert_refused(&TempDir::new("simd16"), &["--simd", "16"], "AVX-512");
    }
    let o = run(&dir, &["--simd", "12"]);
    assert!(!o.status.success() && stderr(&o).contains("8 or 16 lanes"));
}
