//! The hostile-input corpus of issue 13: every reproduction, as a
//! regression test. Each must give a clean error (exit 1, a message naming
//! the file or the setting) or correct output — never a panic, an abort, a
//! thread storm, a quadratic wait or a clobbered file.
//!
//! Files are under `tests/data/hostile/` where they are text; forged
//! accumulation files are made here (with valid checksums, see
//! [`common::forge`]).

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use wavetrace::film::Film;
use wavetrace::scene::Scene;
use wavetrace::scene::obj;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/hostile")
        .join(name)
}

/// The exit status is 1 (an error, not a panic's 101 or a signal).
fn refused_cleanly(o: std::process::Output) -> String {
    let e = refused(o.clone());
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(!e.contains("panicked"), "{e}");
    e
}

/// A tiny render's partial file (samples 0..2 of 4) and its settings hash.
fn real_partial(dir: &Path, name: &str) -> (PathBuf, u128) {
    let path = dir.join(name);
    run_ok(
        dir,
        &[
            "--width",
            "4",
            "--height",
            "3",
            "--spp",
            "4",
            "--samples",
            "0..2",
            "--partial",
            p(&path),
        ],
    );
    let (_, hash) = Film::load(&path, None).unwrap();
    (path, hash)
}

// --- 1. A bare `f` line ---

#[test]
fn obj_face_without_vertices_is_refused_with_its_line() {
    let path = data("bare-face.obj");
    let e = obj::load(&path, false).unwrap_err();
    assert_eq!((e.file.as_path(), e.line), (path.as_path(), 4), "{e}");
    assert!(e.to_string().contains("no vertices"), "{e}");

    // Through a scene and the command line: exit 1, the OBJ and its line named.
    let dir = TempDir::new("bare-face");
    std::fs::copy(&path, dir.join("m.obj")).unwrap();
    std::fs::write(dir.join("s.toml"), scene_with_mesh("m.obj")).unwrap();
    let e = refused_cleanly(run(&dir, &["s.toml", "--check"]));
    assert!(e.contains("m.obj:4"), "{e}");
}

fn scene_with_mesh(obj: &str) -> String {
    format!(
        "[camera]\nposition = [0.5, 0.5, -3]\nforward = [0, 0, 1]\nup = [0, 1, 0]\n\
         vfov_deg = 40\nwidth = 8\nheight = 8\n\n[materials.m]\nreflectance = [0.5, 0.5, 0.5]\n\
         emission = [1, 1, 1]\n\n[[mesh]]\nfile = \"{obj}\"\nmaterial = \"m\"\n"
    )
}

// --- 2. A film too large for memory ---

#[test]
fn huge_image_is_refused_before_allocating_and_by_check() {
    let dir = TempDir::new("huge-image");
    for check in [true, false] {
        let mut args = vec!["--width", "4294967295", "--height", "1", "--spp", "1"];
        if check {
            args.push("--check");
        }
        let t = Instant::now();
        let e = refused_cleanly(run(&dir, &args));
        assert!(t.elapsed() < Duration::from_secs(20));
        assert!(
            e.contains("4294967295x1 pixels") && e.contains("--width"),
            "{e}"
        );
        assert!(e.contains("would need about"), "{e}");
    }
    // The same size from a scene file.
    let text = wavetrace::scene::CORNELL_TOML
        .replace("width = 256", "width = 4294967295")
        .replace("height = 256", "height = 1");
    std::fs::write(dir.join("wide.toml"), text).unwrap();
    let e = refused_cleanly(run(&dir, &["wide.toml", "--check"]));
    assert!(e.contains("camera.width"), "{e}");
    assert!(dir.files() == ["wide.toml"], "{:?}", dir.files());
}

#[test]
fn memory_limit_names_the_largest_part_and_can_be_set() {
    let dir = TempDir::new("memory-limit");
    let o = run_env(&dir, &["--check"], &[("WAVETRACE_MAX_MEMORY", "1M")]);
    let e = refused_cleanly(o);
    assert!(
        e.contains("WAVETRACE_MAX_MEMORY") && e.contains("--width"),
        "{e}"
    );
    let o = run_env(
        &dir,
        &["--check", "--threads", "64", "--batch-size", "1048576"],
        &[("WAVETRACE_MAX_MEMORY", "4G")],
    );
    let e = refused_cleanly(o);
    assert!(e.contains("--threads or --batch-size"), "{e}");
    let o = run_env(&dir, &["--check"], &[("WAVETRACE_MAX_MEMORY", "lots")]);
    assert!(refused_cleanly(o).contains("WAVETRACE_MAX_MEMORY"));
    ok(run_env(
        &dir,
        &["--check"],
        &[("WAVETRACE_MAX_MEMORY", "1G")],
    ));
}

// --- 3. A thread storm ---

#[test]
fn absurd_thread_counts_are_refused_before_any_thread_starts() {
    let dir = TempDir::new("threads");
    let t = Instant::now();
    let e = refused_cleanly(run(&dir, &["--threads", "18446744073709551615", "--check"]));
    assert!(e.contains("--threads 18446744073709551615"), "{e}");
    let e = refused_cleanly(run_env(
        &dir,
        &["--check"],
        &[("SLURM_CPUS_PER_TASK", "100000")],
    ));
    assert!(e.contains("SLURM_CPUS_PER_TASK is 100000"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
    // In the library too.
    let scene = Scene::cornell();
    let mut s = tiny(&scene);
    s.threads = wavetrace::render::MAX_THREADS + 1;
    assert!(wavetrace::render::Renderer::new(&scene, &s).is_err());
}

// --- 4. A forged header whose width x height overflows ---

#[test]
fn forged_overflowing_size_is_refused_by_merge_and_resume() {
    let dir = TempDir::new("overflow");
    let (_, hash) = real_partial(&dir, "real.wtacc");
    for (w, h) in [
        (u32::MAX as u64, u32::MAX as u64),
        (u32::MAX as u64, 2),
        (65536, 65536),
    ] {
        let header = forge::header(w, h, &[[0, 2]], Some(4), None, hash);
        let bytes = forge::file(header.as_bytes(), &[0; 48]);
        let bad = dir.join("forged.wtacc");
        std::fs::write(&bad, &bytes).unwrap();
        let e = Film::load(&bad, None).unwrap_err().to_string();
        assert!(
            e.contains("forged.wtacc") && e.contains("bytes of sums"),
            "{e}"
        );
        let e = refused_cleanly(run(&dir, &["merge", "forged.wtacc", "--out", "m.pfm"]));
        assert!(e.contains("forged.wtacc"), "{e}");
        let e = refused_cleanly(run(
            &dir,
            &[
                "--width",
                "4",
                "--height",
                "3",
                "--spp",
                "4",
                "--resume",
                "forged.wtacc",
            ],
        ));
        assert!(e.contains("forged.wtacc"), "{e}");
        assert_eq!(
            std::fs::read(&bad).unwrap(),
            bytes,
            "the input is unchanged"
        );
    }
    assert_eq!(dir.files(), ["forged.wtacc", "real.wtacc"]);
}

// --- 5. A film of 0 pixels ---

#[test]
fn zero_sized_films_are_refused_and_nothing_is_written() {
    let dir = TempDir::new("zero");
    let (_, hash) = real_partial(&dir, "real.wtacc");
    for (w, h) in [(0, 3), (4, 0), (0, 0)] {
        let header = forge::header(w, h, &[[0, 4]], Some(4), None, hash);
        let bytes = forge::file(header.as_bytes(), &[]);
        std::fs::write(dir.join("zero.wtacc"), &bytes).unwrap();
        for out in ["m.pfm", "m.exr", "m.png", "m.wtacc"] {
            let e = refused_cleanly(run(&dir, &["merge", "zero.wtacc", "--out", out]));
            assert!(e.contains("zero.wtacc") && e.contains("at least 1"), "{e}");
        }
        assert_eq!(
            dir.files(),
            ["real.wtacc", "zero.wtacc"],
            "no output, no temp file"
        );
    }
}

// --- 6. Very many sample ranges ---

#[test]
fn hundreds_of_thousands_of_ranges_load_and_merge_fast() {
    let dir = TempDir::new("ranges");
    let n = 200_000u64;
    let spp = 2 * n;
    let write = |name: &str, odd: u64| {
        let ranges: Vec<[u64; 2]> = (0..n).map(|i| [2 * i + odd, 2 * i + odd + 1]).collect();
        let header = forge::header(2, 1, &ranges, Some(spp), None, 7);
        let path = dir.join(name);
        std::fs::write(&path, forge::file(header.as_bytes(), &[0; 96])).unwrap();
        path
    };
    let (even, odd) = (write("even.wtacc", 0), write("odd.wtacc", 1));
    let t = Instant::now();
    let (film, _) = Film::load(&even, None).unwrap();
    assert_eq!(film.ranges.len(), n as usize);
    let merged =
        wavetrace::run::merge::merge_files(&[even.clone(), odd.clone()], None, false).unwrap();
    assert_eq!(merged.film.ranges, vec![0..spp as u32]);
    // Merged in the other order, and with one part missing (the missing
    // samples are many ranges).
    let partial = wavetrace::run::merge::merge_files(&[odd, even.clone()], None, false).unwrap();
    assert_eq!(partial.film, merged.film);
    let missing = wavetrace::run::merge::merge_files(&[even], None, true).unwrap();
    assert_eq!(missing.missing.unwrap().missing.len(), n as usize);
    assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
}

#[test]
fn overlapping_ranges_in_one_file_are_refused() {
    let dir = TempDir::new("overlap");
    let path = dir.join("o.wtacc");
    for ranges in [
        vec![[0, 4], [2, 3]],
        vec![[5, 6], [0, 8]],
        vec![[3, 3]],
        vec![[4, 2]],
        vec![[1, 2], [1, 2]],
    ] {
        let header = forge::header(1, 1, &ranges, None, None, 1);
        std::fs::write(&path, forge::file(header.as_bytes(), &[0; 48])).unwrap();
        let e = Film::load(&path, None).unwrap_err().to_string();
        assert!(e.contains("o.wtacc: bad sample range"), "{ranges:?}: {e}");
    }
}

// --- 7. A merge that would overwrite its input ---

#[test]
fn merge_refuses_an_output_that_is_one_of_its_inputs() {
    let dir = TempDir::new("merge-clobber");
    let (a, _) = real_partial(&dir, "a.wtacc");
    let b = dir.join("b.wtacc");
    run_ok(
        &dir,
        &[
            "--width",
            "4",
            "--height",
            "3",
            "--spp",
            "4",
            "--samples",
            "2..4",
            "--partial",
            "b.wtacc",
        ],
    );
    let before = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    for args in [
        [
            "merge",
            "a.wtacc",
            "b.wtacc",
            "--out",
            "m.png",
            "--partial",
            "b.wtacc",
        ],
        [
            "merge",
            "a.wtacc",
            "b.wtacc",
            "--out",
            "b.wtacc",
            "--partial",
            "m.wtacc",
        ],
        [
            "merge",
            "a.wtacc",
            "b.wtacc",
            "--out",
            "./a.wtacc",
            "--partial",
            "m.wtacc",
        ],
        [
            "merge",
            "a.wtacc",
            "b.wtacc",
            "--out",
            "m.wtacc",
            "--partial",
            "m.wtacc",
        ],
    ] {
        let e = refused_cleanly(run(&dir, &args));
        assert!(e.contains("overwrite"), "{args:?}: {e}");
    }
    assert_eq!(
        (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap()),
        before
    );
    assert_eq!(dir.files(), ["a.wtacc", "b.wtacc"]);
    ok(run(
        &dir,
        &["merge", "a.wtacc", "b.wtacc", "--out", "m.png"],
    ));
}

// --- Outputs that are not regular files ---

#[cfg(unix)]
#[test]
fn special_files_are_written_in_place_never_replaced() {
    use std::os::unix::fs::FileTypeExt;
    let dir = TempDir::new("special");
    let fifo = dir.join("stats.fifo");
    let c = std::ffi::CString::new(p(&fifo)).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
    };
    ok(run(
        &dir,
        &[&TINY[..], &["--stats", "stats.fifo", "--out", "x.png"]].concat(),
    ));
    let json = reader.join().unwrap();
    assert!(json.contains("\"spp\""), "{json}");
    assert!(
        std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo()
    );

    // A symbolic link to a regular file stays a link; the file is replaced.
    std::fs::write(dir.join("target.json"), "old").unwrap();
    std::os::unix::fs::symlink("target.json", dir.join("link.json")).unwrap();
    ok(run(
        &dir,
        &[&TINY[..], &["--stats", "link.json", "--out", "y.png"]].concat(),
    ));
    assert!(dir.join("link.json").is_symlink());
    assert!(
        std::fs::read_to_string(dir.join("target.json"))
            .unwrap()
            .contains("\"spp\"")
    );

    // A directory is refused before the render.
    std::fs::create_dir(dir.join("d")).unwrap();
    let e = refused_cleanly(run(&dir, &[&TINY[..], &["--stats", "d"]].concat()));
    assert!(e.contains("d: is a directory"), "{e}");
}

// --- Scene files ---

#[test]
fn a_vector_with_a_fourth_component_is_refused_naming_file_line_field() {
    let text = wavetrace::scene::CORNELL_TOML.replacen(
        "[materials.light]",
        "[materials.light]\nemission = [10, 10, 10, -1]",
        1,
    );
    let text = text.replacen("emission = [10.0, 10.0, 10.0]\n", "", 1);
    let e = wavetrace::scene::file::parse(&text, "four.toml").unwrap_err();
    let line = text
        .lines()
        .position(|l| l.starts_with("emission = [10, 10, 10, -1]"))
        .unwrap()
        + 1;
    assert_eq!(e.line, line, "{e}");
    assert_eq!(e.field.as_deref(), Some("materials.light.emission"), "{e}");
    assert!(e.to_string().starts_with("four.toml:"), "{e}");
    assert!(e.message.contains("invalid length 4"), "{e}");
    // Too few, and nested arrays too.
    for (from, to) in [
        ("up = [0.0, -1.0, 0.0]", "up = [0.0, -1.0]"),
        ("vertices = [[", "vertices = [[0.5, "),
    ] {
        assert!(wavetrace::scene::CORNELL_TOML.contains(from));
        let text = wavetrace::scene::CORNELL_TOML.replacen(from, to, 1);
        let e = wavetrace::scene::file::parse(&text, "bad.toml").unwrap_err();
        assert!(e.line > 0 && e.message.contains("invalid length"), "{e}");
    }
}

#[test]
fn latin1_obj_and_mtl_load() {
    let mesh = obj::load(&data("latin1.obj"), true).unwrap();
    assert_eq!(mesh.triangles.len(), 1);
    assert_eq!(mesh.materials.len(), 1);
    assert_eq!(mesh.material, vec![Some(0)], "usemtl finds its newmtl");
    assert_eq!(mesh.materials[0].emission, glam::Vec3::ONE);
}

fn scaled_cornell(factor: f32) -> String {
    let mut out = String::new();
    for line in wavetrace::scene::CORNELL_TOML.lines() {
        if line.starts_with("vertices") || line.starts_with("position") {
            let (key, value) = line.split_once('=').unwrap();
            let mut v = String::new();
            let mut num = String::new();
            for c in value.chars().chain(std::iter::once(' ')) {
                if c.is_ascii_digit() || c == '.' || c == '-' {
                    num.push(c);
                } else {
                    if !num.is_empty() {
                        let x: f32 = num.parse().unwrap();
                        v += &format!("{:e}", x * factor);
                        num.clear();
                    }
                    v.push(c);
                }
            }
            out += &format!("{key}={}\n", v.trim_end());
        } else {
            out += line;
            out.push('\n');
        }
    }
    out
}

#[test]
fn cornell_box_scaled_far_up_or_down_keeps_every_triangle() {
    let cornell = Scene::cornell();
    for factor in [3e9f32, 1e-15, 1e15, 1e-25] {
        let scene = wavetrace::scene::file::parse(&scaled_cornell(factor), "scaled.toml")
            .unwrap_or_else(|e| panic!("x{factor}: {e}"));
        assert_eq!(scene.triangles.len(), cornell.triangles.len(), "x{factor}");
        for (t, c) in scene.triangles.iter().zip(&cornell.triangles) {
            assert!((t.normal - c.normal).length() < 1e-5, "x{factor}");
        }
        // And it renders without a panic.
        let s = common::settings(&scene, 4, 4, 1);
        let (film, _, _) = wavetrace::render::Renderer::new(&scene, &s)
            .unwrap()
            .render();
        assert_eq!(film.samples_per_pixel(), 1);
    }
    // Truly degenerate triangles are still refused, at any scale.
    for scale in [1.0f32, 1e-20, 1e20] {
        let text = wavetrace::scene::CORNELL_TOML.replacen(
            "vertices = [[",
            &format!("vertices = [[0, 0, 0], [{scale:e}, {scale:e}, {scale:e}], [{t:e}, {t:e}, {t:e}]]\n#", t = 2.0 * scale),
            1,
        );
        let e = wavetrace::scene::file::parse(&text, "flat.toml").unwrap_err();
        assert!(e.message.contains("zero area"), "{e}");
    }
}

// --- Beyond the list: forged sums and shard counts ---

#[test]
fn forged_sums_and_shards_are_refused() {
    let dir = TempDir::new("forged-sums");
    let path = dir.join("f.wtacc");
    // A sum no 2 samples can make: it would overflow later additions.
    let mut data = vec![0u8; 48];
    data[..16].copy_from_slice(&u128::MAX.to_le_bytes());
    let header = forge::header(1, 1, &[[0, 2]], Some(4), None, 1);
    std::fs::write(&path, forge::file(header.as_bytes(), &data)).unwrap();
    let e = Film::load(&path, None).unwrap_err().to_string();
    assert!(e.contains("pixel (0, 0) holds a sum larger"), "{e}");
    // A shard count above the samples per pixel.
    let header = forge::header(1, 1, &[[0, 2]], Some(4), Some([0, 4_000_000_000]), 1);
    std::fs::write(&path, forge::file(header.as_bytes(), &[0; 48])).unwrap();
    let e = Film::load(&path, None).unwrap_err().to_string();
    assert!(e.contains("bad shard"), "{e}");
    // A huge (valid) shard count: the missing shards are not listed one by
    // one for minutes.
    let spp = u32::MAX as u64;
    let header = forge::header(1, 1, &[[0, 2]], Some(spp), Some([0, spp]), 1);
    std::fs::write(&path, forge::file(header.as_bytes(), &[0; 48])).unwrap();
    let t = Instant::now();
    let m = wavetrace::run::merge::merge_files(&[path], None, true).unwrap();
    let missing = m.missing.unwrap();
    assert!(missing.missing_shards.len() <= wavetrace::run::merge::MAX_LISTED_SHARDS);
    assert!(t.elapsed() < Duration::from_secs(5));
}

// --- Beyond the list: a reference image with a forged size ---

#[test]
fn reference_exr_with_a_forged_size_is_refused_before_allocating() {
    let dir = TempDir::new("exr");
    let path = dir.join("ref.exr");
    wavetrace::output::write_image(&path, 2, 2, &[[0.5; 3]; 4]).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    // dataWindow: box2i of xmin, ymin, xmax, ymax (i32 each).
    let name = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(name.len())
        .position(|w| w == name)
        .expect("a dataWindow attribute")
        + name.len()
        + 4;
    for (k, v) in [(8, 99_999i32), (12, 99_999)] {
        bytes[at + k..at + k + 4].copy_from_slice(&v.to_le_bytes());
    }
    std::fs::write(&path, &bytes).unwrap();
    let t = Instant::now();
    let e = wavetrace::output::read_image(&path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("ref.exr"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(10));
    let e = refused_cleanly(run(
        &dir,
        &[&TINY[..], &["--reference", "ref.exr", "--check"]].concat(),
    ));
    assert!(e.contains("ref.exr"), "{e}");
}
