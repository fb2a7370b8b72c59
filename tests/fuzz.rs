//! Property-based fuzzing of every input wavetrace reads: scene files
//! (TOML), meshes (OBJ and MTL), accumulation files (`.wtacc`) and EXR
//! images; and of command lines whose outputs name their inputs.
//!
//! Valid inputs are mutated (numbers swapped for hostile ones, lines
//! deleted, duplicated or inserted, bytes flipped, files truncated), and
//! accumulation files are also forged outright, with valid checksums. For
//! every case: no panic, a bounded time, and either a usable result or an
//! error naming the file (and a line within it, where it gives one); a
//! refused merge or resume leaves its inputs as they were and writes
//! nothing.
//!
//! The loaders run in-process; a share of the `.wtacc` cases also run the
//! binary (`merge`, `render --resume`), which must exit 0 or 1, never
//! crash.
//!
//! `WAVETRACE_FUZZ_CASES=N` sets the cases per property (default
//! [`DEFAULT_CASES`], a few seconds in release mode); e.g.
//! `WAVETRACE_FUZZ_CASES=5000 cargo test --release --test fuzz` for a long
//! run. Failures are not persisted to files; proptest prints the shrunk
//! input.

mod common;

use common::*;
use proptest::prelude::*;
use proptest::sample::select;
use proptest::test_runner::Config;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use wavetrace::film::{AccMeta, Film};
use wavetrace::render::Renderer;
use wavetrace::scene::{CORNELL_TOML, Scene, obj};

/// Cases per property unless `WAVETRACE_FUZZ_CASES` says otherwise.
const DEFAULT_CASES: u32 = 96;

/// The most one case may take (generous: CI machines are slow and busy).
const CASE_TIME: Duration = Duration::from_secs(20);

fn config() -> Config {
    let cases = std::env::var("WAVETRACE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(DEFAULT_CASES);
    Config {
        cases,
        failure_persistence: None,
        max_shrink_iters: 256,
        ..Config::default()
    }
}

/// Tokens a hostile number can be.
const HOSTILE_NUMBERS: &[&str] = &[
    "0",
    "-0.0",
    "-1",
    "1",
    "0.5",
    "2",
    "1e39",
    "-1e39",
    "3.4e38",
    "1e-45",
    "1e-300",
    "nan",
    "inf",
    "-inf",
    "1025",
    "65535",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551615",
    "\"x\"",
    "[]",
    "[1, 2, 3, 4]",
    "[[1, 2, 3]]",
    "true",
    "{}",
];

/// Lines a hostile scene file may gain.
const HOSTILE_LINES: &[&str] = &[
    "emission = [10, 10, 10, -1]",
    "reflectance = [0.5, 0.5]",
    "width = 0",
    "height = 4294967295",
    "max_depth = 4294967295",
    "rr_depth = 0",
    "name = \"\\u0000\"",
    "[[quad]]",
    "[[triangle]]",
    "[[mesh]]",
    "[[generate]]",
    "kind = \"sphere\"",
    "kind = \"terrain\"",
    "triangles = 18446744073709551615",
    "triangles = 50000001",
    "triangles = 64",
    "material = \"floor\"",
    "material = \"nonexistent\"",
    "file = \"/nonexistent.obj\"",
    "file = \"\"",
    "scale = 0",
    "scale = [1e30, 1e30, 1e30]",
    "scale = [1, 1, 1, 1]",
    "translate = [3e38, 3e38, 3e38]",
    "rotate_deg = [nan, 0, 0]",
    "vertices = [[0, 0, 0], [0, 0, 0], [0, 0, 0]]",
    "vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 2, 2]]",
    "look_at = [0, 0, 0]",
    "vfov_deg = 180",
    "focal_length_px = -1",
    "[camera]",
    "[integrator]",
    "name = \"sobol\"",
    "sampler = \"sobol\"",
    "x = 1",
    "= 1",
    "[",
    "\"",
    "'''",
];

/// One edit of a scene file's text.
#[derive(Clone, Debug)]
enum Edit {
    /// Replace the `n`-th number (mod the count) with `to`.
    Number(usize, &'static str),
    DeleteLine(usize),
    DuplicateLine(usize),
    InsertLine(usize, &'static str),
    /// Flip bit `bit` of byte `at` (mod the length): may leave bad UTF-8.
    FlipBit(usize, u8),
    Truncate(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (any::<usize>(), select(HOSTILE_NUMBERS)).prop_map(|(n, t)| Edit::Number(n, t)),
        1 => any::<usize>().prop_map(Edit::DeleteLine),
        1 => any::<usize>().prop_map(Edit::DuplicateLine),
        3 => (any::<usize>(), select(HOSTILE_LINES)).prop_map(|(n, l)| Edit::InsertLine(n, l)),
        1 => (any::<usize>(), 0u8..8).prop_map(|(a, b)| Edit::FlipBit(a, b)),
        1 => any::<usize>().prop_map(Edit::Truncate),
    ]
}

fn apply(text: &[u8], e: &Edit) -> Vec<u8> {
    let lines =
        |t: &[u8]| -> Vec<Vec<u8>> { t.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect() };
    let join = |ls: Vec<Vec<u8>>| ls.join(&b'\n');
    match *e {
        Edit::Number(n, to) => {
            // Spans of number tokens: digits with signs, dots and exponents.
            let mut spans = Vec::new();
            let mut i = 0;
            while i < text.len() {
                if text[i].is_ascii_digit() {
                    let mut s = i;
                    while s > 0 && matches!(text[s - 1], b'-' | b'+' | b'.') {
                        s -= 1;
                    }
                    let mut e = i;
                    while e < text.len()
                        && (text[e].is_ascii_alphanumeric()
                            || matches!(text[e], b'.' | b'-' | b'+'))
                    {
                        e += 1;
                    }
                    spans.push((s, e));
                    i = e;
                } else {
                    i += 1;
                }
            }
            if spans.is_empty() {
                return text.to_vec();
            }
            let (s, e) = spans[n % spans.len()];
            [&text[..s], to.as_bytes(), &text[e..]].concat()
        }
        Edit::DeleteLine(n) => {
            let mut ls = lines(text);
            let k = n % ls.len();
            ls.remove(k);
            join(ls)
        }
        Edit::DuplicateLine(n) => {
            let mut ls = lines(text);
            let k = n % ls.len();
            let l = ls[k].clone();
            ls.insert(k, l);
            join(ls)
        }
        Edit::InsertLine(n, l) => {
            let mut ls = lines(text);
            let k = n % (ls.len() + 1);
            ls.insert(k, l.as_bytes().to_vec());
            join(ls)
        }
        Edit::FlipBit(at, bit) => {
            let mut t = text.to_vec();
            if !t.is_empty() {
                let k = at % t.len();
                t[k] ^= 1 << bit;
            }
            t
        }
        Edit::Truncate(at) => text[..at % (text.len() + 1)].to_vec(),
    }
}

/// Renders `scene` at 4x4 pixels, 1 sample, 1 thread, if the settings
/// allow; nothing may panic.
fn render_tiny(scene: &Scene) {
    if scene.triangles.len() > 20_000 {
        return;
    }
    let mut s = wavetrace::render::RenderSettings::for_scene(scene);
    // The scene's own size is checked (not rendered).
    let _ = s
        .validate()
        .and_then(|()| s.check_memory(scene.triangles.len()));
    (s.width, s.height, s.spp, s.threads) = (4, 4, 1, 1);
    if s.max_depth > 64 {
        s.max_depth = 64;
    }
    if let Ok(r) = Renderer::new(scene, &s) {
        let (film, _, _) = r.render();
        assert_eq!(film.samples_per_pixel(), 1);
    }
}

/// A mesh for scene files to load: a quad with a material.
const MESH_OBJ: &str =
    "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl glow\nf 1 2 3 4\n";
const MESH_MTL: &str = "newmtl glow\nKd 0.5 0.5 0.5\nKe 1 1 1\n";

/// The Cornell box plus a mesh, a generated sphere and integrator options:
/// every kind of entry, for mutations to hit.
fn scene_base() -> String {
    format!(
        "{CORNELL_TOML}\n[[mesh]]\nfile = \"quad.obj\"\nmtl = true\nmaterial = \"floor\"\n\
         scale = 0.2\nrotate_deg = [180, 0, 0]\ntranslate = [0.1, 0.2, 0.3]\n\n\
         [[generate]]\nkind = \"sphere\"\ntriangles = 80\nmaterial = \"floor\"\n\
         center = [0.2, 0.5, 0.2]\nradius = 0.2\n\n\
         [[generate]]\nkind = \"terrain\"\ntriangles = 32\nmaterial = \"left_wall\"\n\
         size = [0.5, 0.5]\nheight = 0.05\nseed = 3\n"
    )
}

proptest! {
    #![proptest_config(config())]

    /// Scene files, mutated: refused naming the file (and a line in it),
    /// or loaded and rendered.
    #[test]
    fn scene_files(edits in proptest::collection::vec(edit(), 1..5)) {
        let dir = TempDir::new("fuzz-scene");
        std::fs::write(dir.join("quad.obj"), MESH_OBJ).unwrap();
        std::fs::write(dir.join("quad.mtl"), MESH_MTL).unwrap();
        let mut text = scene_base().into_bytes();
        for e in &edits {
            text = apply(&text, e);
        }
        let path = dir.join("scene.toml");
        std::fs::write(&path, &text).unwrap();
        let t = Instant::now();
        match Scene::load(&path) {
            Err(e) => {
                let shown = e.to_string();
                let named = e.file == path.display().to_string()
                    || e.file.ends_with("quad.obj")
                    || e.file.ends_with("quad.mtl");
                prop_assert!(named, "{shown}");
                prop_assert!(shown.starts_with(&e.file), "{shown}");
                if e.file == path.display().to_string() {
                    let lines = text.split(|&b| b == b'\n').count();
                    prop_assert!(e.line <= lines, "line {} of {lines}: {shown}", e.line);
                }
            }
            Ok(scene) => render_tiny(&scene),
        }
        prop_assert!(t.elapsed() < CASE_TIME, "{:?}", t.elapsed());
    }
}

// --- OBJ and MTL ---

fn coordinate() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (-10.0f32..10.0).prop_map(|x| x.to_string()),
        1 => any::<f32>().prop_map(|x| format!("{x:e}")),
        1 => select(&["nan", "inf", "-inf", "1e39", "1e-45", "", "x", "1,5", "0x10", "--1"][..]).prop_map(String::from),
    ]
}

fn index() -> impl Strategy<Value = String> {
    prop_oneof![
        6 => (1i64..8).prop_map(|i| i.to_string()),
        2 => (-8i64..0).prop_map(|i| i.to_string()),
        1 => Just("0".to_string()),
        1 => select(&["99999999999", "-99999999999", "18446744073709551616", "x", "", "1.5"][..]).prop_map(String::from),
    ]
}

fn corner() -> impl Strategy<Value = String> {
    (index(), 0u8..5, index(), index()).prop_map(|(v, form, t, n)| match form {
        0 | 1 => v,
        2 => format!("{v}/{t}"),
        3 => format!("{v}//{n}"),
        _ => format!("{v}/{t}/{n}"),
    })
}

/// Bytes of a comment or a name: ASCII, Latin-1 and stray UTF-8 bytes.
fn odd_bytes() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(
        prop_oneof![3 => 0x20u8..0x7f, 1 => 0x80u8..=0xff, 1 => Just(0u8), 1 => Just(b'\r')],
        0..12,
    )
}

fn obj_line() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        6 => proptest::collection::vec(coordinate(), 0..5).prop_map(|c| format!("v {}", c.join(" ")).into_bytes()),
        1 => proptest::collection::vec(coordinate(), 0..4).prop_map(|c| format!("vt {}", c.join(" ")).into_bytes()),
        1 => proptest::collection::vec(coordinate(), 0..4).prop_map(|c| format!("vn {}", c.join(" ")).into_bytes()),
        6 => proptest::collection::vec(corner(), 0..7).prop_map(|c| format!("f {}", c.join(" ")).into_bytes()),
        1 => proptest::collection::vec(index(), 0..3).prop_map(|c| format!("l {}", c.join(" ")).into_bytes()),
        1 => proptest::collection::vec(index(), 0..3).prop_map(|c| format!("p {}", c.join(" ")).into_bytes()),
        2 => prop_oneof![Just(b"m".to_vec()), Just(b"Mat\xe9riau".to_vec()), Just(b"missing".to_vec()), odd_bytes()]
            .prop_map(|n| [b"usemtl ".to_vec(), n].concat()),
        1 => select(&["mtllib mesh.mtl", "mtllib missing.mtl", "mtllib", "mtllib mesh.mtl mesh.mtl"][..]).prop_map(|s| s.as_bytes().to_vec()),
        1 => odd_bytes().prop_map(|b| [b"# ".to_vec(), b].concat()),
        1 => odd_bytes().prop_map(|b| [b"o ".to_vec(), b].concat()),
        1 => odd_bytes().prop_map(|b| [b"g ".to_vec(), b].concat()),
        1 => Just(b"s off".to_vec()),
        1 => odd_bytes(),
    ]
}

fn mtl_line() -> impl Strategy<Value = Vec<u8>> {
    let colour = |key: &'static str| {
        proptest::collection::vec(coordinate(), 0..5)
            .prop_map(move |c| format!("{key} {}", c.join(" ")).into_bytes())
    };
    prop_oneof![
        3 => prop_oneof![Just(b"m".to_vec()), Just(b"Mat\xe9riau".to_vec()), odd_bytes()]
            .prop_map(|n| [b"newmtl ".to_vec(), n].concat()),
        3 => colour("Kd"),
        2 => colour("Ke"),
        1 => colour("Ks"),
        1 => colour("Ns"),
        1 => colour("d"),
        1 => Just(b"map_Kd tex.png".to_vec()),
        1 => odd_bytes(),
    ]
}

fn lines_text(lines: &[Vec<u8>]) -> Vec<u8> {
    lines.join(&b'\n')
}

proptest! {
    #![proptest_config(config())]

    /// OBJ and MTL files of valid vertices and then anything: loaded, or
    /// refused naming the OBJ or the MTL and a line within it.
    #[test]
    fn obj_and_mtl_files(
        head in proptest::collection::vec(proptest::collection::vec(-5.0f32..5.0, 3), 3..8),
        body in proptest::collection::vec(obj_line(), 0..24),
        mtl in proptest::collection::vec(mtl_line(), 0..10),
        with_mtl in any::<bool>(),
        through_scene in 0u8..4,
    ) {
        let dir = TempDir::new("fuzz-obj");
        let mut obj_lines: Vec<Vec<u8>> = vec![b"mtllib mesh.mtl".to_vec()];
        obj_lines.extend(head.iter().map(|v| format!("v {} {} {}", v[0], v[1], v[2]).into_bytes()));
        obj_lines.extend(body);
        let obj_text = lines_text(&obj_lines);
        let mtl_text = lines_text(&mtl);
        let (obj_path, mtl_path) = (dir.join("mesh.obj"), dir.join("mesh.mtl"));
        std::fs::write(&obj_path, &obj_text).unwrap();
        std::fs::write(&mtl_path, &mtl_text).unwrap();
        let t = Instant::now();
        match obj::load(&obj_path, with_mtl) {
            Err(e) => {
                let count = |t: &[u8]| t.split(|&b| b == b'\n').count();
                let lines = if e.file == obj_path {
                    count(&obj_text)
                } else if e.file == mtl_path {
                    count(&mtl_text)
                } else {
                    // An `mtllib` that names a file that is not there.
                    prop_assert_eq!(e.file.parent(), Some(dir.path()), "{}", e);
                    prop_assert!(e.message.contains("cannot read"), "{}", e);
                    0
                };
                prop_assert!(e.line <= lines, "line {} of {}: {}", e.line, lines, e);
                prop_assert!(e.to_string().starts_with(&e.file.display().to_string()));
            }
            Ok(mesh) => {
                prop_assert_eq!(mesh.triangles.len(), mesh.material.len());
                for t in &mesh.triangles {
                    prop_assert!(t.iter().all(|v| v.is_finite()));
                }
                for m in mesh.material.iter().flatten() {
                    prop_assert!(*m < mesh.materials.len());
                }
            }
        }
        // A share of the cases go through a scene file and a render.
        if through_scene == 0 {
            let scene = format!(
                "{CORNELL_TOML}\n[[mesh]]\nfile = \"mesh.obj\"\nmtl = {with_mtl}\nmaterial = \"floor\"\nscale = 0.1\n"
            );
            let scene_path = dir.join("scene.toml");
            std::fs::write(&scene_path, scene).unwrap();
            match Scene::load(&scene_path) {
                Err(e) => prop_assert!(
                    e.file.ends_with(".obj") || e.file.ends_with(".mtl") || e.file.ends_with("scene.toml"),
                    "{}", e
                ),
                Ok(scene) => render_tiny(&scene),
            }
        }
        prop_assert!(t.elapsed() < CASE_TIME, "{:?}", t.elapsed());
    }
}

// --- Accumulation files ---

/// A valid film: its size, ranges and sums (each below what its samples
/// can make).
fn film() -> impl Strategy<Value = (Film, AccMeta)> {
    (
        1u32..5,
        1u32..5,
        proptest::collection::vec((0u32..6, 1u32..4), 0..4),
        any::<u64>(),
        0u8..3,
    )
        .prop_map(|(w, h, gaps, seed, shard)| {
            let mut film = Film::new(w, h);
            let mut at = 0;
            for (gap, len) in gaps {
                film.add_range(at + gap..at + gap + len);
                at += gap + len;
            }
            let held = film.samples_per_pixel() as u128;
            let mut x = seed as u128 | 1;
            for s in film.sums.iter_mut().flatten() {
                x = x
                    .wrapping_mul(0x9E37_79B9_7F4A_7C15_F39C_C060_5CED_C835)
                    .wrapping_add(1);
                *s = if held == 0 { 0 } else { x % (held << 63) };
            }
            let spp = at.max(1) + shard as u32;
            let meta = AccMeta {
                settings_hash: 0x5eed,
                spp: (shard > 0).then_some(spp),
                shard: (shard == 2).then_some((0, 1)),
            };
            (film, meta)
        })
}

/// Header values a forger may write.
fn forged_number() -> impl Strategy<Value = u64> {
    prop_oneof![
        4 => 0u64..6,
        1 => select(&[u32::MAX as u64, u32::MAX as u64 - 1, 1 << 16, 1 << 31, u32::MAX as u64 + 1, u64::MAX][..]),
        1 => any::<u32>().prop_map(u64::from),
    ]
}

/// How a file is made hostile.
#[derive(Clone, Debug)]
enum Hostile {
    /// Bytes flipped; resealed with a valid checksum or not.
    Flip(Vec<(usize, u8)>, bool),
    /// Cut short; resealed or not.
    Truncate(usize, bool),
    /// A header forged from scratch, data of `data_pixels` pixels (or the
    /// header's, when `None`), valid checksum.
    Forged {
        width: u64,
        height: u64,
        ranges: Vec<[u64; 2]>,
        spp: Option<u64>,
        shard: Option<[u64; 2]>,
        data_pixels: Option<u8>,
    },
    /// The header's JSON edited like a scene file; valid checksum.
    HeaderEdit(Vec<Edit>),
}

fn hostile() -> impl Strategy<Value = Hostile> {
    prop_oneof![
        2 => (proptest::collection::vec((any::<usize>(), 1u8..=255), 1..4), any::<bool>())
            .prop_map(|(f, seal)| Hostile::Flip(f, seal)),
        1 => (any::<usize>(), any::<bool>()).prop_map(|(at, seal)| Hostile::Truncate(at, seal)),
        4 => (
            forged_number(),
            forged_number(),
            proptest::collection::vec((forged_number(), forged_number()).prop_map(|(a, b)| [a, b]), 0..5),
            proptest::option::of(forged_number()),
            proptest::option::of((forged_number(), forged_number()).prop_map(|(a, b)| [a, b])),
            proptest::option::of(0u8..20),
        )
            .prop_map(|(width, height, ranges, spp, shard, data_pixels)| Hostile::Forged {
                width, height, ranges, spp, shard, data_pixels,
            }),
        2 => proptest::collection::vec(edit(), 1..4).prop_map(Hostile::HeaderEdit),
    ]
}

fn make_hostile(valid: &[u8], h: &Hostile, hash: u128) -> Vec<u8> {
    let body = &valid[..valid.len() - 16];
    match h {
        Hostile::Flip(flips, seal) => {
            let mut b = if *seal { body.to_vec() } else { valid.to_vec() };
            for &(at, mask) in flips {
                let k = at % b.len();
                b[k] ^= mask;
            }
            if *seal { forge::seal(b) } else { b }
        }
        Hostile::Truncate(at, seal) => {
            if *seal {
                forge::seal(body[..at % (body.len() + 1)].to_vec())
            } else {
                valid[..at % valid.len()].to_vec()
            }
        }
        Hostile::Forged {
            width,
            height,
            ranges,
            spp,
            shard,
            data_pixels,
        } => {
            let header = forge::header(*width, *height, ranges, *spp, *shard, hash);
            let pixels = match data_pixels {
                Some(n) => *n as usize,
                None => (*width).saturating_mul(*height).min(64) as usize,
            };
            forge::file(header.as_bytes(), &vec![0; pixels * 48])
        }
        Hostile::HeaderEdit(edits) => {
            let (mut header, data) = forge::split(valid);
            for e in edits {
                header = apply(&header, e);
            }
            forge::file(&header, &data)
        }
    }
}

/// A loaded film is consistent whatever the file said.
fn check_film(film: &Film) -> Result<(), TestCaseError> {
    prop_assert!(film.width >= 1 && film.height >= 1);
    prop_assert_eq!(film.sums.len(), film.width as usize * film.height as usize);
    for w in film.ranges.windows(2) {
        prop_assert!(w[0].end < w[1].start, "{:?}", film.ranges);
    }
    prop_assert!(film.ranges.iter().all(|r| r.start < r.end));
    let _ = film.to_rgb();
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    /// Accumulation files flipped, truncated, forged: refused naming the
    /// file, or loaded consistent; merges and resumes refuse them leaving
    /// every input as it was and writing nothing.
    #[test]
    fn accumulation_files((film, meta) in film(), how in hostile(), cli in 0u8..8) {
        let dir = TempDir::new("fuzz-wtacc");
        let good = dir.join("good.wtacc");
        // The hash of the render `cli_cases` resumes, so resuming gets past
        // the hash check to everything else.
        let mut settings = wavetrace::render::RenderSettings::for_scene(&Scene::cornell());
        (settings.width, settings.height) = (film.width, film.height);
        let meta = AccMeta { settings_hash: settings.image_hash(&Scene::cornell()), ..meta };
        film.save_with_meta(&good, &meta).unwrap();
        let valid = std::fs::read(&good).unwrap();
        let bad_bytes = make_hostile(&valid, &how, meta.settings_hash);
        let bad = dir.join("bad.wtacc");
        std::fs::write(&bad, &bad_bytes).unwrap();
        let t = Instant::now();

        match Film::load_with_meta(&bad, None) {
            Err(e) => prop_assert!(e.to_string().starts_with(&bad.display().to_string()), "{}", e),
            Ok((f, _)) => check_film(&f)?,
        }
        for parts in [vec![good.clone(), bad.clone()], vec![bad.clone(), good.clone()]] {
            match wavetrace::run::merge::merge_files(&parts, Some(64), true) {
                Err(e) => {
                    let shown = e.to_string();
                    prop_assert!(
                        shown.contains("bad.wtacc") || shown.contains("good.wtacc") || shown.contains("--spp"),
                        "{}", shown
                    );
                }
                Ok(m) => check_film(&m.film)?,
            }
        }
        if cli == 0 {
            cli_cases(&dir, &good, &bad, &valid, &bad_bytes, &film)?;
        }
        prop_assert!(t.elapsed() < CASE_TIME, "{:?}", t.elapsed());
    }
}

/// `merge` and `render --resume` with the hostile file: exit 0 or 1 (never
/// a crash), and after a refusal the inputs are unchanged and nothing new
/// is in the directory.
fn cli_cases(
    dir: &Path,
    good: &Path,
    bad: &Path,
    valid: &[u8],
    bad_bytes: &[u8],
    film: &Film,
) -> Result<(), TestCaseError> {
    let before = dir_listing(dir);
    let (w, h) = (film.width.to_string(), film.height.to_string());
    let runs: [Vec<&str>; 3] = [
        vec!["merge", p(good), p(bad), "--out", "m.pfm", "--spp", "64"],
        vec![
            "merge",
            p(bad),
            "--out",
            "m.wtacc",
            "--spp",
            "64",
            "--allow-partial",
        ],
        vec![
            "--width",
            &w,
            "--height",
            &h,
            "--spp",
            "64",
            "--resume",
            p(bad),
            "--out",
            "r.png",
        ],
    ];
    for (k, args) in runs.iter().enumerate() {
        let o = run_with_limit(dir, args, CASE_TIME);
        let code = o.status.code();
        prop_assert!(matches!(code, Some(0 | 1)), "{:?}: {}", args, text(&o));
        if code == Some(1) {
            let e = stderr(&o);
            prop_assert!(!e.contains("panicked"), "{}", e);
            prop_assert_eq!(&dir_listing(dir), &before, "{:?}: {}", args, e);
        }
        prop_assert_eq!(std::fs::read(good).unwrap(), valid);
        // A resume that succeeds checkpoints into the file it resumed.
        if !(k == 2 && code == Some(0)) {
            prop_assert_eq!(std::fs::read(bad).unwrap(), bad_bytes);
        }
        for out in ["m.pfm", "m.wtacc", "r.png"] {
            let _ = std::fs::remove_file(dir.join(out));
        }
    }
    Ok(())
}

fn dir_listing(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

// --- Far-away geometry ---

/// A black object (scene-file text) away from the Cornell box (`[-1, 1]³`)
/// and its camera (at `z = -3`): everything within 4 of the origin:
/// a triangle 10² to 10⁷ away, 10⁻⁵ to 10⁻¹ of that across (smaller ones
/// round to no area); or a sphere 1 to 10⁷ away, either around the whole
/// box or clear of it.
fn far_object() -> impl Strategy<Value = String> {
    let dir = (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
        .prop_filter("a direction", |(x, y, z)| x * x + y * y + z * z > 0.01)
        .prop_map(|(x, y, z)| glam::Vec3::new(x, y, z).normalize());
    let v3 = |v: glam::Vec3| format!("[{:e}, {:e}, {:e}]", v.x, v.y, v.z);
    prop_oneof![
        (
            dir.clone(),
            2.0f32..7.0,
            -5.0f32..-1.0,
            dir.clone(),
            dir.clone()
        )
            .prop_map(move |(at, far, size, a, b)| {
                let (c, s) = (at * 10f32.powf(far), 10f32.powf(far + size));
                format!(
                    "[[triangle]]\nmaterial = \"far\"\nvertices = [{}, {}, {}]\n",
                    v3(c),
                    v3(c + a * s),
                    v3(c + b * s)
                )
            }),
        (dir, 0.0f32..7.0, any::<bool>(), 0.01f32..0.99).prop_map(move |(at, far, around, k)| {
            let d = 10f32.powf(far);
            let (c, r) = if around {
                (at * d, d + 4.0 + d * k)
            } else {
                (at * (d + 4.0), (d * k).max(1e-3))
            };
            format!(
                "[[sphere]]\nmaterial = \"far\"\ncenter = {}\nradius = {r:e}\n",
                v3(c)
            )
        }),
    ]
}

proptest! {
    #![proptest_config(config())]

    /// Black objects far from the Cornell box (or around it) leave its
    /// image as it is, bit for bit: rays leave surfaces by an offset local
    /// to the hit, so the paths in the box are the same paths, and those
    /// that leave it add nothing either way.
    #[test]
    fn far_geometry(objects in proptest::collection::vec(far_object(), 1..4), wavefront in any::<bool>()) {
        let text = format!("{CORNELL_TOML}\n[materials.far]\nreflectance = [0, 0, 0]\n{}", objects.concat());
        let scene = wavetrace::scene::file::parse(&text, "far.toml").unwrap();
        let render = |scene: &Scene| {
            let mut s = wavetrace::render::RenderSettings::for_scene(scene);
            (s.width, s.height, s.spp, s.threads) = (12, 12, 2, 1);
            s.integrator = wavetrace::scene::Integrator::Nee;
            if !wavefront {
                s.engine = wavetrace::render::Engine::Reference;
            }
            Renderer::new(scene, &s).unwrap().render().0
        };
        let want = render(&Scene::cornell());
        prop_assert!(render(&scene).sums == want.sums, "{}", objects.concat());
    }
}

// --- Materials at extreme values ---

/// A number at an extreme: huge, tiny, at the edge of a range, or not one.
fn extreme() -> impl Strategy<Value = String> {
    prop_oneof![
        select(
            &[
                "1e20",
                "1e-20",
                "3.4e38",
                "1e-45",
                "0",
                "-0.0",
                "1",
                "0.1",
                "10",
                "10.000001",
                "0.099999",
                "nan",
                "inf",
                "-1"
            ][..]
        )
        .prop_map(String::from),
        (-40i32..40).prop_map(|e| format!("1e{e}")),
        any::<f32>().prop_map(|x| format!("{x:e}")),
    ]
}

proptest! {
    #![proptest_config(config())]

    /// The Cornell box with its short block's material made glass or metal
    /// with extreme numbers (index of refraction, roughness, colours,
    /// emission): refused naming the material's field, or rendered by
    /// both engines with no panic and no NaN sample.
    #[test]
    fn materials_at_extreme_values(
        glass in any::<bool>(),
        x in extreme(),
        y in extreme(),
    ) {
        let material = if glass {
            format!("model = \"glass\"\nior = {x}\ntransmittance = [{y}, 0.5, 0.5]\n")
        } else {
            format!("model = \"metal\"\nalpha = {x}\nreflectance = [{y}, 1, 1]\n")
        };
        let text = CORNELL_TOML.replace(
            "[materials.short_block]\nreflectance = [0.75, 0.15, 0.15]\n",
            &format!("[materials.short_block]\n{material}"),
        );
        prop_assert!(text != CORNELL_TOML);
        match wavetrace::scene::file::parse(&text, "m.toml") {
            Err(e) => prop_assert!(
                e.to_string().contains("materials.short_block."),
                "{e}"
            ),
            Ok(scene) => {
                for engine in [wavetrace::render::Engine::Reference, wavetrace::render::Engine::Wavefront] {
                    let mut s = wavetrace::render::RenderSettings::for_scene(&scene);
                    (s.width, s.height, s.spp, s.threads, s.engine) = (8, 8, 2, 1, engine);
                    let (film, _, _) = Renderer::new(&scene, &s).unwrap().render();
                    prop_assert_eq!(film.invalid_samples, 0, "{}", material);
                }
            }
        }
    }
}

// --- Outputs that name inputs ---

/// Every file under `dir` (recursively) and its bytes, links as their
/// targets.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
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

/// The inputs of the fixture of [`outputs_naming_inputs`], and the
/// arguments that make a command read each: (file, command line before
/// the output flag). Render reads the scene, its mesh and MTL file, a
/// profile, a reference, an environment image and a checkpoint to
/// resume; denoise its image; merge its parts; converge its scene and
/// reference.
const INPUTS: &[(&str, &[&str])] = &[
    ("s.toml", &["s.toml"]),
    ("obj.toml", &["obj.toml"]),
    ("meshes/crate.obj", &["obj.toml"]),
    ("meshes/crate.mtl", &["obj.toml"]),
    ("p.toml", &["s.toml", "--profile", "p.toml"]),
    ("r.pfm", &["s.toml", "--reference", "r.pfm"]),
    ("in.exr", &["s.toml", "--env", "in.exr"]),
    (
        "m.wtacc",
        &["s.toml", "--resume", "m.wtacc", "--checkpoint", "c.wtacc"],
    ),
    ("r.pfm", &["denoise", "r.pfm"]),
    ("in.exr", &["denoise", "in.exr"]),
    ("m.wtacc", &["merge", "m.wtacc"]),
    ("s.toml", &["converge", "s.toml", "--reference", "r.pfm"]),
    ("r.pfm", &["converge", "s.toml", "--reference", "r.pfm"]),
];

/// How an output names its input: the same path, spelled otherwise
/// (`./x`, `meshes/../x`, absolute), or through a symbolic or hard link.
#[derive(Clone, Copy, Debug)]
enum Naming {
    Same,
    Dotted,
    Detour,
    Absolute,
    Symlink,
    HardLink,
}

proptest! {
    #![proptest_config(config())]

    /// A random output flag of a command naming a random one of its
    /// inputs, spelled any way or through a link: refused (exit 1) before
    /// any work, the error naming the output, and every file as it was.
    #[test]
    fn outputs_naming_inputs(
        input in 0..INPUTS.len(),
        flag in 0usize..6,
        naming in select(&[Naming::Same, Naming::Dotted, Naming::Detour, Naming::Absolute, Naming::Symlink, Naming::HardLink][..]),
    ) {
        let dir = fixture();
        let (file, reads) = INPUTS[input];
        let command = reads[0];
        // A resumed render's checkpoint is given already (and may be the
        // file it resumes): --stats names it instead.
        let flag = if reads.contains(&"--resume") && flag == 5 { 0 } else { flag };
        // The output's extension where the flag wants one.
        let ext = match (command, flag) {
            ("denoise", _) | ("merge", _) | (_, 1) => Some("pfm"),
            ("converge", _) => Some("csv"),
            (_, 2) => Some("wtacc"),
            (_, 3) => Some("pfm"),
            _ => None,
        };
        let fits = ext.is_none_or(|e| file.ends_with(e));
        let link = |name: &str| {
            let at = dir.join(name);
            if matches!(naming, Naming::HardLink) {
                std::fs::hard_link(dir.join(file), &at).unwrap();
            } else {
                std::os::unix::fs::symlink(dir.join(file), &at).unwrap();
            }
            name.to_string()
        };
        // An AOV file of --out a.pfm: render's (--aov albedo), merge's and
        // denoise's of an EXR (any AOV the parts or layers may hold).
        let aov = flag == 4 && !(command == "denoise" && file == "r.pfm");
        let flag = if command == "denoise" && file == "r.pfm" && flag == 4 { 1 } else { flag };
        // For converge the name is a --prefix whose CSV is the input.
        let named = if command == "converge" {
            link("k.csv");
            "k".to_string()
        } else if aov {
            link("a.albedo.pfm"); // the AOV file of --out a.pfm
            "a.pfm".to_string()
        } else {
            match naming {
                _ if !fits => link(&format!("l.{}", ext.unwrap())),
                Naming::Same => file.to_string(),
                Naming::Dotted => format!("./{file}"),
                Naming::Detour => format!("meshes/../{file}"),
                Naming::Absolute => p(&dir.join(file)).to_string(),
                Naming::Symlink | Naming::HardLink => {
                    link(&format!("l.{}", ext.unwrap_or("json")))
                }
            }
        };
        let small = ["--width", "8", "--height", "8", "--spp", "1"];
        let mut args: Vec<&str> = reads.to_vec();
        match (command, flag) {
            ("denoise", _) | ("merge", _) => args.extend(["--out", &named]),
            ("converge", _) => args.extend(["--prefix", &named]),
            (_, 0) => args.extend(["--out", "o.png", "--stats", &named]),
            (_, 1) => args.extend(["--out", &named]),
            (_, 2) => args.extend(["--out", "o.png", "--partial", &named]),
            (_, 3) => args.extend(["--out", "o.png", "--denoise", "--keep-noisy", &named]),
            (_, 4) => args.extend(["--out", &named, "--aov", "albedo"]),
            _ => args.extend(["--out", "o.png", "--checkpoint", &named]),
        }
        if command != "denoise" && command != "merge" {
            args.extend(small);
        }
        let before = snapshot(&dir);
        let o = run_with_limit(&dir, &args, CASE_TIME);
        let e = stderr(&o);
        prop_assert_eq!(o.status.code(), Some(1), "{:?}: {}", args, text(&o));
        prop_assert!(!e.contains("panicked"), "{:?}: {}", args, e);
        let shown = match command {
            "converge" => "k.csv",
            _ if aov => "a.albedo.pfm",
            _ => named.as_str(),
        };
        prop_assert!(e.contains(shown), "{:?}: {}", args, e);
        prop_assert!(snapshot(&dir) == before, "{:?}: a file changed", args);
    }
}

/// The fixture of [`outputs_naming_inputs`]: the Cornell box, the OBJ
/// scene with its mesh and MTL, a profile, 8x8 images (PFM and EXR) and a
/// partial file of the box.
fn fixture() -> TempDir {
    let dir = TempDir::new("out-in");
    std::fs::copy("scenes/cornell.toml", dir.join("s.toml")).unwrap();
    std::fs::copy("scenes/cornell-obj.toml", dir.join("obj.toml")).unwrap();
    std::fs::create_dir(dir.join("meshes")).unwrap();
    for f in ["crate.obj", "crate.mtl"] {
        std::fs::copy(format!("scenes/meshes/{f}"), dir.join("meshes").join(f)).unwrap();
    }
    std::fs::write(dir.join("p.toml"), "spp = 1\n").unwrap();
    let rgb = vec![[0.25f32; 3]; 64];
    wavetrace::output::write_image(&dir.join("r.pfm"), 8, 8, &rgb).unwrap();
    wavetrace::output::write_image(&dir.join("in.exr"), 8, 8, &rgb).unwrap();
    let mut s = wavetrace::render::RenderSettings::for_scene(&Scene::cornell());
    (s.width, s.height, s.spp, s.threads) = (8, 8, 1, 1);
    let film = Renderer::new(&Scene::cornell(), &s).unwrap().new_film();
    film.save(&dir.join("m.wtacc"), 0).unwrap();
    dir
}

// --- Hostile EXR headers ---

/// The system allocator, recording the largest single allocation each
/// thread asks for, so that a test can check what reading a file
/// allocated.
struct Measured;

thread_local! {
    static LARGEST: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

// SAFETY: every call is passed to the system allocator unchanged; the
// bookkeeping only reads and writes a thread-local counter (no allocation).
unsafe impl std::alloc::GlobalAlloc for Measured {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        let _ = LARGEST.try_with(|m| m.set(m.get().max(layout.size())));
        // SAFETY: the caller's contract, passed on.
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        let _ = LARGEST.try_with(|m| m.set(m.get().max(layout.size())));
        // SAFETY: the caller's contract, passed on.
        unsafe { std::alloc::System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, size: usize) -> *mut u8 {
        let _ = LARGEST.try_with(|m| m.set(m.get().max(size)));
        // SAFETY: the caller's contract, passed on.
        unsafe { std::alloc::System.realloc(ptr, layout, size) }
    }
}

#[global_allocator]
static ALLOCATOR: Measured = Measured;

/// The largest single allocation `f` made on this thread.
fn largest_allocation<T>(f: impl FnOnce() -> T) -> (T, usize) {
    LARGEST.with(|m| m.set(0));
    let out = f();
    (out, LARGEST.with(|m| m.get()))
}

/// Where attribute `name`'s size field and value lie in an EXR header:
/// (offset of the 4-byte size, offset of the value, the size).
fn exr_attribute(bytes: &[u8], name: &str) -> Option<(usize, usize, usize)> {
    let key = format!("{name}\0");
    let at = bytes.windows(key.len()).position(|w| w == key.as_bytes())?;
    let type_end = at + key.len() + bytes[at + key.len()..].iter().position(|&b| b == 0)?;
    let size_at = type_end + 1;
    let size = i32::from_le_bytes(bytes.get(size_at..size_at + 4)?.try_into().ok()?);
    Some((size_at, size_at + 4, size.max(0) as usize))
}

/// A way to make a valid EXR hostile.
#[derive(Clone, Debug)]
enum ExrEdit {
    /// dataWindow or displayWindow set to these corners.
    Window(bool, [i32; 4]),
    /// The compression byte.
    Compression(u8),
    /// A byte of the channel list set (names, pixel types, sampling).
    Channels(usize, u8),
    /// An attribute's size field set.
    AttributeSize(usize, i32),
    /// A byte anywhere in the first 400 (the header, the offset table).
    Byte(usize, u8),
    /// The file cut short.
    Truncate(usize),
    /// Zero bytes appended (room for a forged window's offset table).
    Pad(usize),
}

fn hostile_i32() -> impl Strategy<Value = i32> {
    prop_oneof![
        select(
            &[
                0,
                -1,
                1,
                7,
                8,
                29_999,
                65_535,
                1 << 20,
                i32::MAX,
                i32::MIN,
                i32::MAX - 1
            ][..]
        ),
        any::<i32>(),
    ]
}

fn exr_edit() -> impl Strategy<Value = ExrEdit> {
    prop_oneof![
        3 => (any::<bool>(), proptest::array::uniform4(hostile_i32())).prop_map(|(d, c)| ExrEdit::Window(d, c)),
        1 => any::<u8>().prop_map(ExrEdit::Compression),
        2 => (any::<usize>(), any::<u8>()).prop_map(|(i, b)| ExrEdit::Channels(i, b)),
        1 => (0usize..8, hostile_i32()).prop_map(|(i, s)| ExrEdit::AttributeSize(i, s)),
        2 => (0usize..400, any::<u8>()).prop_map(|(i, b)| ExrEdit::Byte(i, b)),
        1 => any::<usize>().prop_map(ExrEdit::Truncate),
        2 => (0usize..1 << 18).prop_map(ExrEdit::Pad),
    ]
}

fn apply_exr(bytes: &mut Vec<u8>, e: &ExrEdit) {
    match *e {
        ExrEdit::Window(data, corners) => {
            let name = if data { "dataWindow" } else { "displayWindow" };
            if let Some((_, at, 16)) = exr_attribute(bytes, name)
                && at + 16 <= bytes.len()
            {
                bytes[at..at + 16].copy_from_slice(&corners.map(i32::to_le_bytes).concat());
            }
        }
        ExrEdit::Compression(c) => {
            if let Some((_, at, 1)) = exr_attribute(bytes, "compression")
                && at < bytes.len()
            {
                bytes[at] = c;
            }
        }
        ExrEdit::Channels(i, b) => {
            if let Some((_, at, size)) = exr_attribute(bytes, "channels")
                && size > 0
                && at + size <= bytes.len()
            {
                bytes[at + i % size] = b;
            }
        }
        ExrEdit::AttributeSize(i, s) => {
            let names = [
                "channels",
                "compression",
                "dataWindow",
                "displayWindow",
                "lineOrder",
                "pixelAspectRatio",
                "screenWindowCenter",
                "screenWindowWidth",
            ];
            if let Some((size_at, _, _)) = exr_attribute(bytes, names[i]) {
                bytes[size_at..size_at + 4].copy_from_slice(&s.to_le_bytes());
            }
        }
        ExrEdit::Byte(i, b) => {
            if i < bytes.len() {
                bytes[i] = b;
            }
        }
        ExrEdit::Truncate(at) => bytes.truncate(at % bytes.len().max(1)),
        ExrEdit::Pad(n) => bytes.resize(bytes.len() + n, 0),
    }
}

proptest! {
    #![proptest_config(config())]

    /// A valid 8x8 EXR with its header mutated or forged (huge, negative
    /// or inverted windows, unknown compressions, broken channel lists,
    /// attribute sizes past the file, truncations): read in-process as an
    /// image, a reference and an AOV layer, and a share by the binary
    /// (`denoise`, `--reference`), no case panics or allocates past its
    /// file's worth; each is an image of the size it claims or an error
    /// naming the file, and the file is never written.
    #[test]
    fn hostile_exr_headers(edits in proptest::collection::vec(exr_edit(), 1..4), cli in 0u8..6) {
        let dir = TempDir::new("exr");
        let path = dir.join("h.exr");
        let rgb = vec![[0.5f32; 3]; 64];
        wavetrace::output::write_image(&path, 8, 8, &rgb).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        for e in &edits {
            apply_exr(&mut bytes, e);
        }
        std::fs::write(&path, &bytes).unwrap();
        let start = Instant::now();
        let (read, largest) = largest_allocation(|| wavetrace::output::read_image(&path));
        match read {
            Ok(image) => prop_assert_eq!(image.rgb.len(), (image.width * image.height) as usize),
            Err(e) => prop_assert!(e.to_string().contains("h.exr"), "{}", e),
        }
        // No more than the file can hold: its bytes at its compression's
        // largest ratio (docs/hostile-input.md), twice over for 16-bit
        // samples read as 32-bit ones, and a megabyte of the reader's own.
        let ratio = match exr_attribute(&bytes, "compression").and_then(|(_, at, _)| bytes.get(at)) {
            Some(0) => 1,
            Some(1) => 64,
            Some(2 | 3 | 5) => 2064,
            Some(6) => 3,
            Some(7) => 11,
            _ => 65536,
        };
        let most = bytes.len() * ratio * 2 + (1 << 20);
        prop_assert!(largest <= most, "{:?}: allocated {} bytes for a file of {}", edits, largest, bytes.len());
        if let Err(e) = wavetrace::output::read_radiance(&path, "the reference") {
            prop_assert!(e.to_string().contains("h.exr"), "{}", e);
        }
        if let Err(e) = wavetrace::output::read_exr_layer(&path, "albedo", &["R", "G", "B"]) {
            prop_assert!(e.to_string().contains("h.exr"), "{}", e);
        }
        prop_assert!(start.elapsed() < CASE_TIME, "{:?}", edits);
        let args: Option<Vec<&str>> = match cli {
            0 => Some(vec!["denoise", "h.exr", "--out", "d.pfm"]),
            1 => Some(vec!["--reference", "h.exr", "--width", "8", "--height", "8", "--spp", "1", "--out", "o.png"]),
            _ => None,
        };
        if let Some(args) = args {
            let o = run_with_limit(&dir, &args, CASE_TIME);
            prop_assert!(matches!(o.status.code(), Some(0 | 1)), "{:?}: {}", edits, text(&o));
            prop_assert!(!stderr(&o).contains("panicked"), "{}", text(&o));
        }
        prop_assert!(std::fs::read(&path).unwrap() == bytes, "h.exr changed");
    }
}

// --- glTF and PLY assets ---

/// The shipped textured GLB, split into its JSON and its binary chunk.
fn textured_glb() -> (serde_json::Value, Vec<u8>) {
    split_glb(
        &std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textured.glb")).unwrap(),
    )
}

/// CRC-32 (ISO-HDLC, as PNG's chunks use).
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// Sets the width and height in every PNG header (`IHDR`) in `bytes`,
/// with a correct checksum.
fn forge_png_size(bytes: &mut [u8], w: u32, h: u32) {
    let mut at = 0;
    while let Some(k) = bytes[at..].windows(4).position(|x| x == b"IHDR") {
        let k = at + k;
        if k + 4 + 13 + 4 > bytes.len() {
            return;
        }
        bytes[k + 4..k + 8].copy_from_slice(&w.to_be_bytes());
        bytes[k + 8..k + 12].copy_from_slice(&h.to_be_bytes());
        let crc = crc32(&bytes[k..k + 17]);
        bytes[k + 17..k + 21].copy_from_slice(&crc.to_be_bytes());
        at = k + 4;
    }
}

/// Every place in a JSON value: a path of keys and indices.
fn json_paths(
    v: &serde_json::Value,
    path: &mut Vec<serde_json::Value>,
    out: &mut Vec<Vec<serde_json::Value>>,
) {
    out.push(path.clone());
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                path.push(k.clone().into());
                json_paths(x, path, out);
                path.pop();
            }
        }
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                path.push(i.into());
                json_paths(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn json_at<'v>(
    v: &'v mut serde_json::Value,
    path: &[serde_json::Value],
) -> Option<&'v mut serde_json::Value> {
    path.iter().try_fold(v, |v, k| match k {
        serde_json::Value::String(s) => v.get_mut(s.as_str()),
        serde_json::Value::Number(n) => v.get_mut(n.as_u64()? as usize),
        _ => None,
    })
}

/// Values a hostile glTF field can take.
fn hostile_json() -> impl Strategy<Value = serde_json::Value> {
    use serde_json::json;
    select(vec![
        json!(-1),
        json!(0),
        json!(1),
        json!(2),
        json!(3),
        json!(4),
        json!(7),
        json!(255),
        json!(256),
        json!(65_535),
        json!(1 << 26),
        json!(1u64 << 31),
        json!(u32::MAX),
        json!(1u64 << 32),
        json!(1u64 << 53),
        json!(u64::MAX),
        json!(i64::MIN),
        json!(0.5),
        json!(1e300),
        json!(-1e300),
        json!("x"),
        json!(null),
        json!([]),
        json!([1, 2]),
        json!({}),
        json!(true),
    ])
}

/// One way to make a glTF hostile.
#[derive(Clone, Debug)]
enum GltfEdit {
    /// The `n`-th numeric field (mod their count) set to a hostile value.
    Number(usize, serde_json::Value),
    /// Any value (an object, an array, a field) replaced: wrong types.
    Replace(usize, serde_json::Value),
    /// A named field of every element of an array set.
    Field(&'static str, &'static str, usize, serde_json::Value),
    /// A value removed (a required property gone).
    Remove(usize),
    /// Node `a` made a child of node `b` (cycles, shared children).
    Child(usize, usize),
    /// The buffer or an image read from a file that is not there, or a
    /// bad data URI.
    Uri(bool, &'static str),
    /// `POSITION` component `k` of the binary set to NaN, ±inf or huge.
    Position(usize, f32),
    /// Every embedded PNG declares this size (valid checksum).
    PngSize(u32, u32),
    /// A bit of the GLB flipped.
    Flip(usize, u8),
    /// The GLB cut short.
    Truncate(usize),
}

fn gltf_edit() -> impl Strategy<Value = GltfEdit> {
    let field = select(vec![
        ("accessors", "count"),
        ("accessors", "byteOffset"),
        ("accessors", "bufferView"),
        ("accessors", "componentType"),
        ("accessors", "type"),
        ("bufferViews", "byteOffset"),
        ("bufferViews", "byteLength"),
        ("bufferViews", "byteStride"),
        ("bufferViews", "buffer"),
        ("buffers", "byteLength"),
        ("meshes", "primitives"),
        ("nodes", "mesh"),
        ("nodes", "children"),
        ("nodes", "scale"),
        ("textures", "source"),
        ("images", "bufferView"),
        ("images", "mimeType"),
        ("materials", "emissiveFactor"),
        ("scenes", "nodes"),
    ]);
    prop_oneof![
        3 => (any::<usize>(), hostile_json()).prop_map(|(n, v)| GltfEdit::Number(n, v)),
        2 => (any::<usize>(), hostile_json()).prop_map(|(n, v)| GltfEdit::Replace(n, v)),
        4 => (field, any::<usize>(), hostile_json()).prop_map(|((a, f), i, v)| GltfEdit::Field(a, f, i, v)),
        1 => any::<usize>().prop_map(GltfEdit::Remove),
        2 => (0usize..8, 0usize..8).prop_map(|(a, b)| GltfEdit::Child(a, b)),
        1 => (any::<bool>(), select(vec!["missing.bin", "data:application/octet-stream;base64,@@@", "data:,x", "http://example.com/x", "../../etc/passwd", ""]))
            .prop_map(|(b, u)| GltfEdit::Uri(b, u)),
        2 => (0usize..12, select(vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 3e38, -3e38, 1e-45]))
            .prop_map(|(k, x)| GltfEdit::Position(k, x)),
        3 => (select(vec![0u32, 1, 4096, 8192, 16_384, 16_385, 65_535, 1 << 20, 1_000_000_000, u32::MAX]),
              select(vec![0u32, 1, 4096, 8192, 16_384, 16_385, 65_535, 1 << 20, 1_000_000_000, u32::MAX]))
            .prop_map(|(w, h)| GltfEdit::PngSize(w, h)),
        2 => (any::<usize>(), 0u8..8).prop_map(|(a, b)| GltfEdit::Flip(a, b)),
        1 => any::<usize>().prop_map(GltfEdit::Truncate),
    ]
}

/// `edits` applied to the textured GLB: the file's bytes.
fn hostile_glb(edits: &[GltfEdit]) -> Vec<u8> {
    let (mut json, mut bin) = textured_glb();
    let mut bytes_edits = Vec::new();
    for e in edits {
        let mut paths = Vec::new();
        json_paths(&json, &mut Vec::new(), &mut paths);
        match e {
            GltfEdit::Number(n, v) => {
                let numbers: Vec<_> = paths
                    .iter()
                    .filter(|p| json_at(&mut json.clone(), p).is_some_and(|x| x.is_number()))
                    .cloned()
                    .collect();
                if let Some(p) = numbers.get(n % numbers.len().max(1)) {
                    *json_at(&mut json, p).unwrap() = v.clone();
                }
            }
            GltfEdit::Replace(n, v) => {
                let p = &paths[n % paths.len()];
                if !p.is_empty() {
                    *json_at(&mut json, p).unwrap() = v.clone();
                }
            }
            GltfEdit::Field(array, field, i, v) => {
                if let Some(a) = json.get_mut(*array).and_then(|a| a.as_array_mut())
                    && !a.is_empty()
                {
                    let k = i % a.len();
                    if let Some(o) = a[k].as_object_mut() {
                        o.insert(field.to_string(), v.clone());
                    }
                }
            }
            GltfEdit::Remove(n) => {
                let p = &paths[n % paths.len()];
                if let Some((last, parent)) = p.split_last()
                    && let Some(x) = json_at(&mut json, parent)
                {
                    match (x, last) {
                        (serde_json::Value::Object(m), serde_json::Value::String(k)) => {
                            m.remove(k);
                        }
                        (serde_json::Value::Array(a), serde_json::Value::Number(i)) => {
                            a.remove(i.as_u64().unwrap() as usize);
                        }
                        _ => {}
                    }
                }
            }
            GltfEdit::Child(a, b) => {
                if let Some(nodes) = json.get_mut("nodes").and_then(|n| n.as_array_mut())
                    && !nodes.is_empty()
                {
                    let (a, b) = (a % nodes.len(), b % nodes.len());
                    if let Some(o) = nodes[b].as_object_mut() {
                        let c = o.entry("children").or_insert(serde_json::json!([]));
                        if let Some(c) = c.as_array_mut() {
                            c.push(a.into());
                        }
                    }
                }
            }
            GltfEdit::Uri(buffer, uri) => {
                let (array, at) = if *buffer {
                    ("buffers", 0)
                } else {
                    ("images", 0)
                };
                if let Some(o) = json
                    .get_mut(array)
                    .and_then(|a| a.get_mut(at))
                    .and_then(|o| o.as_object_mut())
                {
                    o.remove("bufferView");
                    o.insert("uri".into(), (*uri).into());
                }
            }
            GltfEdit::Position(k, x) => {
                // The first accessor is the floor's POSITION, at the start of
                // buffer view 3.
                let at =
                    json["bufferViews"][3]["byteOffset"].as_u64().unwrap_or(0) as usize + 4 * k;
                if at + 4 <= bin.len() {
                    bin[at..at + 4].copy_from_slice(&x.to_le_bytes());
                }
            }
            GltfEdit::PngSize(w, h) => forge_png_size(&mut bin, *w, *h),
            GltfEdit::Flip(..) | GltfEdit::Truncate(_) => bytes_edits.push(e.clone()),
        }
    }
    let mut out = glb(&json, &bin);
    for e in bytes_edits {
        match e {
            GltfEdit::Flip(at, bit) => {
                let k = at % out.len();
                out[k] ^= 1 << bit;
            }
            GltfEdit::Truncate(at) => out.truncate(at % (out.len() + 1)),
            _ => {}
        }
    }
    out
}

/// Loads the asset at `path` (as `wavetrace render FILE` does), measuring
/// the largest allocation; then renders it tiny. An error must name the
/// file; nothing may panic, allocate more than `most` bytes at once or
/// take longer than [`CASE_TIME`].
fn load_asset_case(
    path: &Path,
    most: usize,
    what: &dyn std::fmt::Debug,
) -> Result<(), TestCaseError> {
    let start = Instant::now();
    let (loaded, largest) = largest_allocation(|| wavetrace::scene::asset_scene::load(path, None));
    prop_assert!(
        largest <= most,
        "{:?}: allocated {} bytes at once (at most {})",
        what,
        largest,
        most
    );
    match loaded {
        Err(e) => {
            prop_assert_eq!(&e.file, &path.display().to_string(), "{:?}: {}", what, e);
            prop_assert!(e.to_string().starts_with(&e.file), "{}", e);
        }
        Ok((scene, _)) => render_tiny(&scene),
    }
    prop_assert!(
        start.elapsed() < CASE_TIME,
        "{:?}: {:?}",
        what,
        start.elapsed()
    );
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    /// The shipped textured GLB (five meshes, three embedded PNGs, a
    /// camera) with its JSON mutated — out-of-range indices, counts,
    /// offsets and strides, huge and negative numbers, wrong types,
    /// removed properties, nodes made their own ancestors or shared,
    /// missing or unreadable buffers and images, NaN and infinite
    /// positions, PNG headers declaring up to 2³² × 2³² texels — and its
    /// bytes flipped or cut short: each loads and renders, or is refused
    /// naming the file; no panic, no allocation beyond 64 MiB (the file is
    /// 8 KB), within the case time.
    #[test]
    fn hostile_gltf(edits in proptest::collection::vec(gltf_edit(), 1..4), text_form in 0u8..4) {
        let dir = TempDir::new("fuzz-gltf");
        let bytes = hostile_glb(&edits);
        // A share as a .gltf whose buffer is a file beside it.
        let path = if text_form == 0 && bytes.len() > 20 {
            let (mut json, bin) = textured_glb();
            let _ = &mut json;
            let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
            let mut json: serde_json::Value = match bytes.get(20..20 + json_len).and_then(|j| serde_json::from_slice(j).ok()) {
                Some(j) => j,
                None => json,
            };
            if let Some(b) = json.get_mut("buffers").and_then(|b| b.get_mut(0)).and_then(|b| b.as_object_mut())
                && !b.contains_key("uri")
            {
                b.insert("uri".into(), "m.bin".into());
            }
            std::fs::write(dir.join("m.bin"), &bin).unwrap();
            let path = dir.join("m.gltf");
            std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
            path
        } else {
            let path = dir.join("m.glb");
            std::fs::write(&path, &bytes).unwrap();
            path
        };
        load_asset_case(&path, 64 << 20, &edits)?;
    }
}

/// A small PLY mesh: a grid of `n × n` vertices (position, normal,
/// texture coordinates, 8-bit colour) and its quads, and an element of
/// another kind to be read past.
#[derive(Clone, Debug)]
struct PlyMesh {
    vertices: Vec<[f32; 8]>,
    colours: Vec<[u8; 3]>,
    faces: Vec<Vec<i64>>,
}

fn ply_mesh(n: usize) -> PlyMesh {
    let mut m = PlyMesh {
        vertices: Vec::new(),
        colours: Vec::new(),
        faces: Vec::new(),
    };
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32 / (n - 1) as f32, j as f32 / (n - 1) as f32);
            m.vertices.push([x, y, 0.1 * (x * y), 0.0, 0.0, 1.0, x, y]);
            m.colours.push([(255.0 * x) as u8, (255.0 * y) as u8, 128]);
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let k = (j * n + i) as i64;
            m.faces.push(vec![k, k + 1, k + 1 + n as i64, k + n as i64]);
        }
    }
    m
}

/// How a PLY file is made hostile.
#[derive(Clone, Debug)]
enum PlyEdit {
    /// Element `e`'s declared count (0 vertex, 1 face, 2 edge) set.
    Count(usize, &'static str),
    /// Property `p` (mod their count) declared with another type.
    Type(usize, &'static str),
    /// Face `f`'s list length written as `n` (its indices unchanged).
    ListLength(usize, u32),
    /// Face `f`'s corner `c` set to index `i`.
    Index(usize, usize, i64),
    /// Vertex value `k` set to `x` (NaN, infinities, huge).
    Value(usize, f32),
    /// A header line inserted.
    HeaderLine(usize, &'static str),
    /// A header line removed.
    DeleteHeaderLine(usize),
    Flip(usize, u8),
    Truncate(usize),
}

fn ply_edit() -> impl Strategy<Value = PlyEdit> {
    prop_oneof![
        3 => (0usize..3, select(vec!["0", "1", "15", "17", "65536", "67108864", "1000000000", "4294967296", "18446744073709551615", "99999999999999999999", "-1", "x"]))
            .prop_map(|(e, c)| PlyEdit::Count(e, c)),
        2 => (any::<usize>(), select(vec!["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint32", "float64", "bogus", "list uchar int", "list int float", "list float int"]))
            .prop_map(|(p, t)| PlyEdit::Type(p, t)),
        2 => (any::<usize>(), select(vec![0u32, 1, 2, 3, 5, 255, 65_535, u32::MAX])).prop_map(|(f, n)| PlyEdit::ListLength(f, n)),
        2 => (any::<usize>(), 0usize..4, select(vec![-1i64, 16, 17, 1 << 31, u32::MAX as i64, i64::MAX])).prop_map(|(f, c, i)| PlyEdit::Index(f, c, i)),
        2 => (any::<usize>(), select(vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 3e38, -1e-45])).prop_map(|(k, x)| PlyEdit::Value(k, x)),
        1 => (any::<usize>(), select(vec!["element vertex 1000000000", "element face 4294967295", "property float x", "property list uint uint vertex_indices", "format ascii 1.0", "format binary_big_endian 1.0", "format binary_little_endian 2.0", "comment hostile", "obj_info x", "end_header", "element empty 1000000000"]))
            .prop_map(|(k, l)| PlyEdit::HeaderLine(k, l)),
        1 => any::<usize>().prop_map(PlyEdit::DeleteHeaderLine),
        2 => (any::<usize>(), 0u8..8).prop_map(|(a, b)| PlyEdit::Flip(a, b)),
        1 => any::<usize>().prop_map(PlyEdit::Truncate),
    ]
}

/// `m` written as PLY in `format` (0 ASCII, 1 binary little-endian, 2
/// big-endian), with `edits`.
fn hostile_ply(m: &PlyMesh, format: u8, edits: &[PlyEdit]) -> Vec<u8> {
    let mut m = m.clone();
    let mut lengths: Vec<u32> = m.faces.iter().map(|f| f.len() as u32).collect();
    let mut header: Vec<String> = vec![
        "ply".into(),
        [
            "format ascii 1.0",
            "format binary_little_endian 1.0",
            "format binary_big_endian 1.0",
        ][format as usize]
            .into(),
        "comment wavetrace fuzz".into(),
        format!("element vertex {}", m.vertices.len()),
    ];
    for p in ["x", "y", "z", "nx", "ny", "nz", "u", "v"] {
        header.push(format!("property float {p}"));
    }
    for p in ["red", "green", "blue"] {
        header.push(format!("property uchar {p}"));
    }
    header.push(format!("element face {}", m.faces.len()));
    header.push("property list uchar int vertex_indices".into());
    header.push("element edge 1".into());
    header.push("property int vertex1".into());
    header.push("property int vertex2".into());
    header.push("end_header".into());
    let mut bytes_edits = Vec::new();
    for e in edits {
        match e {
            PlyEdit::Count(el, c) => {
                let name = ["element vertex", "element face", "element edge"][*el];
                if let Some(l) = header.iter_mut().find(|l| l.starts_with(name)) {
                    *l = format!("{name} {c}");
                }
            }
            PlyEdit::Type(p, t) => {
                let props: Vec<usize> = (0..header.len())
                    .filter(|&i| header[i].starts_with("property"))
                    .collect();
                let i = props[p % props.len()];
                let name = header[i].rsplit(' ').next().unwrap().to_string();
                header[i] = format!("property {t} {name}");
            }
            PlyEdit::ListLength(f, n) => {
                let k = f % lengths.len();
                lengths[k] = *n;
            }
            PlyEdit::Index(f, c, i) => {
                let k = f % m.faces.len();
                let c = c % m.faces[k].len();
                m.faces[k][c] = *i;
            }
            PlyEdit::Value(k, x) => {
                let n = m.vertices.len() * 8;
                let k = k % n;
                m.vertices[k / 8][k % 8] = *x;
            }
            PlyEdit::HeaderLine(k, l) => {
                let k = 1 + k % header.len();
                header.insert(k.min(header.len()), l.to_string());
            }
            PlyEdit::DeleteHeaderLine(k) => {
                header.remove(k % header.len());
            }
            PlyEdit::Flip(..) | PlyEdit::Truncate(_) => bytes_edits.push(e.clone()),
        }
    }
    let mut out = (header.join("\n") + "\n").into_bytes();
    let be = format == 2;
    let f32b = |x: f32| if be { x.to_be_bytes() } else { x.to_le_bytes() };
    let i32b = |x: i32| if be { x.to_be_bytes() } else { x.to_le_bytes() };
    for (v, c) in m.vertices.iter().zip(&m.colours) {
        if format == 0 {
            let vs: Vec<String> = v.iter().map(|x| x.to_string()).collect();
            out.extend(format!("{} {} {} {}\n", vs.join(" "), c[0], c[1], c[2]).bytes());
        } else {
            for &x in v {
                out.extend(f32b(x));
            }
            out.extend(c);
        }
    }
    for (f, &n) in m.faces.iter().zip(&lengths) {
        if format == 0 {
            let is: Vec<String> = f.iter().map(|i| i.to_string()).collect();
            out.extend(format!("{n} {}\n", is.join(" ")).bytes());
        } else {
            out.push(n as u8);
            for &i in f {
                out.extend(i32b(i as i32));
            }
        }
    }
    if format == 0 {
        out.extend(b"0 1\n");
    } else {
        out.extend(i32b(0));
        out.extend(i32b(1));
    }
    for e in bytes_edits {
        match e {
            PlyEdit::Flip(at, bit) => {
                let k = at % out.len();
                out[k] ^= 1 << bit;
            }
            PlyEdit::Truncate(at) => out.truncate(at % (out.len() + 1)),
            _ => {}
        }
    }
    out
}

proptest! {
    #![proptest_config(config())]

    /// A 4 × 4 grid written as PLY (ASCII, binary of either byte order)
    /// with positions, normals, texture coordinates, colours, quads and an
    /// element to read past, made hostile — forged element counts up to
    /// 2⁶⁴, properties of other types, list lengths that lie, indices out
    /// of range, NaN and infinite values, header lines added or removed,
    /// bytes flipped, the file cut short: each loads and renders, or is
    /// refused naming the file; no panic, no allocation beyond 256 bytes
    /// for each of the file's (and a megabyte), within the case time.
    #[test]
    fn hostile_ply_files(format in 0u8..3, edits in proptest::collection::vec(ply_edit(), 1..4)) {
        let dir = TempDir::new("fuzz-ply");
        let bytes = hostile_ply(&ply_mesh(4), format, &edits);
        let path = dir.join("m.ply");
        std::fs::write(&path, &bytes).unwrap();
        load_asset_case(&path, 256 * bytes.len() + (1 << 20), &(format, &edits))?;
    }
}

/// A PLY declaring 10⁹ vertices in a couple of hundred bytes (with
/// properties, or none at all, in ASCII and binary of both byte orders)
/// is refused at once, naming the file, the element and the count, having
/// allocated next to nothing. Before the check, the element of no
/// properties made the reader fill 24 GB with empty records (30 s, 24 GB
/// resident); with properties, `ply-rs-bw` read until the end of the file.
#[test]
fn a_ply_declaring_more_elements_than_its_bytes_hold_is_refused_at_once() {
    let dir = TempDir::new("ply-count");
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        for props in ["property float x\nproperty float y\nproperty float z\n", ""] {
            let mut bytes = format!(
                "ply\nformat {format} 1.0\nelement vertex 1000000000\n{props}\
                 element face 0\nproperty list uchar int vertex_indices\nend_header\n"
            )
            .into_bytes();
            bytes.resize(200, b'0');
            let path = dir.join("big.ply");
            std::fs::write(&path, &bytes).unwrap();
            let start = Instant::now();
            let (r, largest) = largest_allocation(|| wavetrace::scene::ply::load(&path));
            let Err(e) = r else {
                panic!("{format}: not refused")
            };
            let shown = e.to_string();
            assert!(
                start.elapsed() < Duration::from_secs(1),
                "{:?}",
                start.elapsed()
            );
            assert!(
                largest < 1 << 16,
                "{format}: allocated {largest} bytes at once"
            );
            assert!(shown.starts_with(&path.display().to_string()), "{shown}");
            assert!(
                shown.contains("element vertex") && shown.contains("1000000000"),
                "{shown}"
            );
        }
    }
}

/// A glTF accessor without a buffer view (zeros) may declare no more
/// elements than the file's buffers have bytes (at least 2¹⁶): 2²² of
/// them in an 8 KB file had been accepted, 64 MiB of `[f32; 4]` colours
/// (and 2²⁶, 1 GiB; now that is past the decoding budget too).
#[test]
fn a_gltf_accessor_without_data_declaring_millions_is_refused() {
    let (mut json, mut bin) = textured_glb();
    // The coloured triangle's COLOR_0 (accessor 11): no data, 2^22 zeros
    // and one sparse value (an index, then an RGBA value, appended).
    let at = bin.len();
    bin.extend(0u32.to_le_bytes());
    bin.extend([1.0f32; 4].iter().flat_map(|c| c.to_le_bytes()));
    json["buffers"][0]["byteLength"] = bin.len().into();
    let views = json["bufferViews"].as_array_mut().unwrap();
    views.push(serde_json::json!({"buffer": 0, "byteOffset": at, "byteLength": 4}));
    views.push(serde_json::json!({"buffer": 0, "byteOffset": at + 4, "byteLength": 16}));
    let n = views.len();
    let acc = json["accessors"][11].as_object_mut().unwrap();
    acc.remove("bufferView");
    acc.insert("count".into(), (1u64 << 22).into());
    acc.insert(
        "sparse".into(),
        serde_json::json!({"count": 1, "indices": {"bufferView": n - 2, "componentType": 5125},
                           "values": {"bufferView": n - 1}}),
    );
    let dir = TempDir::new("gltf-zeros");
    let path = dir.join("z.glb");
    std::fs::write(&path, glb(&json, &bin)).unwrap();
    let (r, largest) = largest_allocation(|| wavetrace::scene::gltf::load(&path));
    let Err(e) = r else { panic!("not refused") };
    let shown = e.to_string();
    assert!(largest < 1 << 20, "allocated {largest} bytes at once");
    assert!(
        shown.contains("meshes[3].primitives[0].attributes.COLOR_0"),
        "{shown}"
    );
    assert!(
        shown.contains("4194304 elements declared without data"),
        "{shown}"
    );
}

/// Primitives that share one accessor decode it once each: a file of 4000
/// primitives over one 240 KB accessor asked for about 1 GB. The decoded
/// data of a file may take at most 64 times its buffers' bytes (plus 64
/// MiB): refused, naming the accessor, after about 80 MB.
#[test]
fn gltf_primitives_sharing_an_accessor_are_bounded() {
    use serde_json::json;
    let n = 20_000usize; // vertices: 240 KB of positions
    let mut bin = Vec::with_capacity(n * 12);
    for k in 0..n {
        for c in [k as f32, (k % 7) as f32, (k % 3) as f32] {
            bin.extend(c.to_le_bytes());
        }
    }
    let primitives: Vec<_> = (0..4000)
        .map(|_| json!({"attributes": {"POSITION": 0}, "mode": 4}))
        .collect();
    let gltf = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [{"buffer": 0, "byteLength": bin.len()}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
                       "min": [0, 0, 0], "max": [n as f32, 6, 2]}],
        "meshes": [{"primitives": primitives}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
    });
    let dir = TempDir::new("gltf-shared");
    let path = dir.join("s.glb");
    std::fs::write(&path, glb(&gltf, &bin)).unwrap();
    let start = Instant::now();
    let Err(e) = wavetrace::scene::gltf::load(&path) else {
        panic!("not refused")
    };
    let shown = e.to_string();
    assert!(
        start.elapsed() < Duration::from_secs(10),
        "{:?}",
        start.elapsed()
    );
    assert!(
        shown.contains(".attributes.POSITION") && shown.contains("64 times"),
        "{shown}"
    );
    // A handful of primitives sharing it is fine.
    let mut few = gltf.clone();
    few["meshes"][0]["primitives"] = json!(vec![json!({"attributes": {"POSITION": 0}}); 8]);
    std::fs::write(&path, glb(&few, &bin)).unwrap();
    let asset = wavetrace::scene::gltf::load(&path).unwrap();
    assert_eq!(asset.meshes.len(), 8);
}

/// An embedded PNG whose header declares 16384 × 16384 texels in a few
/// hundred bytes (16384 is the largest side allowed) is refused from its
/// header, before decoding: the decoder had allocated 1 GiB for it.
#[test]
fn a_png_declaring_more_texels_than_its_bytes_hold_is_refused_before_decoding() {
    let (json, mut bin) = textured_glb();
    forge_png_size(&mut bin, 16_384, 16_384);
    let dir = TempDir::new("gltf-png");
    let path = dir.join("p.glb");
    std::fs::write(&path, glb(&json, &bin)).unwrap();
    let (r, largest) = largest_allocation(|| wavetrace::scene::gltf::load(&path));
    let Err(e) = r else { panic!("not refused") };
    let shown = e.to_string();
    assert!(largest < 1 << 20, "allocated {largest} bytes at once");
    assert!(
        shown.contains("images[0]") && shown.contains("16384 × 16384"),
        "{shown}"
    );
}

// --- Compressed glTF (EXT_meshopt_compression) ---

/// How a compressed GLB is made hostile.
#[derive(Clone, Debug)]
enum MeshoptEdit {
    /// Field `f` of compressed view `k`'s extension object set to `v`.
    Field(usize, &'static str, serde_json::Value),
    /// View `k` declares `count` elements, its `byteLength` agreeing (up
    /// to terabytes: the decoding budget must refuse them).
    Declare(usize, u64),
    /// View `k`'s extension removed (its data on the fallback buffer).
    Uncompress(usize),
    Flip(usize, u8),
    Truncate(usize),
}

fn meshopt_edit() -> impl Strategy<Value = MeshoptEdit> {
    let fields = vec![
        "buffer",
        "byteOffset",
        "byteLength",
        "byteStride",
        "count",
        "mode",
        "filter",
    ];
    let values = vec![
        serde_json::json!(0),
        serde_json::json!(1),
        serde_json::json!(3),
        serde_json::json!(4),
        serde_json::json!(6),
        serde_json::json!(8),
        serde_json::json!(12),
        serde_json::json!(256),
        serde_json::json!(260),
        serde_json::json!(1u64 << 31),
        serde_json::json!(1u64 << 40),
        serde_json::json!(u64::MAX),
        serde_json::json!(-1),
        serde_json::json!(1.5),
        serde_json::json!(null),
        serde_json::json!("ATTRIBUTES"),
        serde_json::json!("TRIANGLES"),
        serde_json::json!("INDICES"),
        serde_json::json!("NONE"),
        serde_json::json!("OCTAHEDRAL"),
        serde_json::json!("QUATERNION"),
        serde_json::json!("EXPONENTIAL"),
        serde_json::json!("ZSTD"),
    ];
    prop_oneof![
        4 => (any::<usize>(), select(fields), select(values))
            .prop_map(|(k, f, v)| MeshoptEdit::Field(k, f, v)),
        2 => (any::<usize>(), select(vec![0u64, 1, 3, 1 << 16, 1 << 20, 1 << 24, 1 << 30, 1 << 40]))
            .prop_map(|(k, n)| MeshoptEdit::Declare(k, n)),
        1 => any::<usize>().prop_map(MeshoptEdit::Uncompress),
        3 => (any::<usize>(), 0u8..8).prop_map(|(a, b)| MeshoptEdit::Flip(a, b)),
        1 => any::<usize>().prop_map(MeshoptEdit::Truncate),
    ]
}

/// `edits` applied to the shipped gltfpack output of the textured GLB
/// (`tests/data/meshopt/textured-meshopt.glb`): the file's bytes.
fn hostile_meshopt_glb(edits: &[MeshoptEdit]) -> Vec<u8> {
    let b = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/meshopt/textured-meshopt.glb"),
    )
    .unwrap();
    let (mut json, mut bin) = split_glb(&b);
    let compressed: Vec<usize> = (json["bufferViews"].as_array().unwrap().iter())
        .enumerate()
        .filter(|(_, v)| v.get("extensions").is_some())
        .map(|(k, _)| k)
        .collect();
    let mut truncate = None;
    for e in edits {
        match e {
            MeshoptEdit::Field(k, f, v) => {
                let k = compressed[k % compressed.len()];
                json["bufferViews"][k]["extensions"]["EXT_meshopt_compression"][*f] = v.clone();
            }
            MeshoptEdit::Declare(k, n) => {
                let k = compressed[k % compressed.len()];
                let ext = &mut json["bufferViews"][k]["extensions"]["EXT_meshopt_compression"];
                ext["count"] = (*n).into();
                let stride = ext["byteStride"].as_u64().unwrap_or(4);
                json["bufferViews"][k]["byteLength"] = n.saturating_mul(stride).into();
            }
            MeshoptEdit::Uncompress(k) => {
                let k = compressed[k % compressed.len()];
                if let Some(v) = json["bufferViews"][k].as_object_mut() {
                    v.remove("extensions");
                }
            }
            MeshoptEdit::Flip(a, bit) => {
                let n = bin.len();
                bin[a % n] ^= 1 << bit;
            }
            MeshoptEdit::Truncate(a) => truncate = Some(a % bin.len()),
        }
    }
    if let Some(t) = truncate {
        bin.truncate(t);
    }
    glb(&json, &bin)
}

proptest! {
    #![proptest_config(config())]

    /// A meshopt-compressed GLB (gltfpack's, with quantized attributes)
    /// with its extension objects mutated — modes, filters, strides and
    /// counts the specification forbids, source ranges outside their
    /// buffer, counts up to terabytes with the view's byteLength
    /// agreeing, views on the fallback buffer left uncompressed — and its
    /// compressed bytes flipped or cut short: each loads and renders, or
    /// is refused naming the file; no panic, no allocation beyond the
    /// decoding budget (64 MiB plus 64 times the file's buffers).
    #[test]
    fn hostile_meshopt_gltf(edits in proptest::collection::vec(meshopt_edit(), 1..4)) {
        let dir = TempDir::new("fuzz-meshopt");
        let bytes = hostile_meshopt_glb(&edits);
        let path = dir.join("m.glb");
        std::fs::write(&path, &bytes).unwrap();
        let budget = wavetrace::scene::gltf::DECODE_ALLOWANCE as usize
            + wavetrace::scene::gltf::DECODE_RATIO as usize * bytes.len();
        load_asset_case(&path, budget, &edits)?;
    }
}

// --- Compressed glTF (KHR_draco_mesh_compression) ---

/// How a Draco-compressed GLB is made hostile.
#[derive(Clone, Debug)]
enum DracoEdit {
    /// Field `f` of Draco primitive `k`'s extension object set to `v`.
    Field(usize, &'static str, serde_json::Value),
    /// Draco primitive `k`'s attribute `name` given unique id `v`.
    Id(usize, &'static str, serde_json::Value),
    /// Field `f` of the `a`-th accessor Draco primitive `k` fills
    /// (indices, then its attributes) set to `v`.
    Accessor(usize, usize, &'static str, serde_json::Value),
    /// Draco primitive `k`'s mode set to `m`.
    Mode(usize, u8),
    Flip(usize, u8),
    Truncate(usize),
}

fn draco_edit() -> impl Strategy<Value = DracoEdit> {
    use serde_json::json;
    let numbers = vec![
        json!(0),
        json!(1),
        json!(2),
        json!(3),
        json!(7),
        json!(99),
        json!(1u64 << 20),
        json!(1u64 << 31),
        json!(1u64 << 40),
        json!(u64::MAX),
        json!(-1),
        json!(1.5),
        json!(null),
        json!("POSITION"),
    ];
    let accessor_values = vec![
        json!(0),
        json!(1),
        json!(2),
        json!(4),
        json!(1u64 << 24),
        json!(1u64 << 31),
        json!(1u64 << 40),
        json!(5120),
        json!(5121),
        json!(5123),
        json!(5125),
        json!(5126),
        json!("SCALAR"),
        json!("VEC2"),
        json!("VEC4"),
        json!("MAT4"),
        json!(true),
    ];
    prop_oneof![
        2 => (any::<usize>(), select(vec!["bufferView", "attributes"]), select(numbers.clone()))
            .prop_map(|(k, f, v)| DracoEdit::Field(k, f, v)),
        2 => (any::<usize>(), select(vec!["POSITION", "TEXCOORD_0", "COLOR_0", "NORMAL"]), select(numbers))
            .prop_map(|(k, f, v)| DracoEdit::Id(k, f, v)),
        3 => (any::<usize>(), any::<usize>(), select(vec!["count", "componentType", "type", "normalized"]), select(accessor_values))
            .prop_map(|(k, a, f, v)| DracoEdit::Accessor(k, a, f, v)),
        1 => (any::<usize>(), 0u8..7).prop_map(|(k, m)| DracoEdit::Mode(k, m)),
        3 => (any::<usize>(), 0u8..8).prop_map(|(a, b)| DracoEdit::Flip(a, b)),
        1 => any::<usize>().prop_map(DracoEdit::Truncate),
    ]
}

/// `edits` applied to gltf-transform's Draco output of the textured GLB
/// (`tests/data/draco/textured-draco.glb`): the file's bytes.
fn hostile_draco_glb(edits: &[DracoEdit]) -> Vec<u8> {
    let b = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/draco/textured-draco.glb"),
    )
    .unwrap();
    let (mut json, mut bin) = split_glb(&b);
    const EXT: &str = "KHR_draco_mesh_compression";
    let n = json["meshes"].as_array().unwrap().len();
    let mut truncate = None;
    for e in edits {
        match e {
            DracoEdit::Field(k, f, v) => {
                json["meshes"][k % n]["primitives"][0]["extensions"][EXT][*f] = v.clone();
            }
            DracoEdit::Id(k, name, v) => {
                let ext = &mut json["meshes"][k % n]["primitives"][0]["extensions"][EXT];
                if ext["attributes"].is_object() {
                    ext["attributes"][*name] = v.clone();
                }
            }
            DracoEdit::Accessor(k, a, f, v) => {
                let p = &json["meshes"][k % n]["primitives"][0];
                let accessors: Vec<u64> = (p["indices"].as_u64().into_iter())
                    .chain(
                        p["attributes"]
                            .as_object()
                            .unwrap()
                            .values()
                            .filter_map(|x| x.as_u64()),
                    )
                    .collect();
                let a = accessors[a % accessors.len()] as usize;
                json["accessors"][a][*f] = v.clone();
            }
            DracoEdit::Mode(k, m) => json["meshes"][k % n]["primitives"][0]["mode"] = (*m).into(),
            DracoEdit::Flip(a, bit) => {
                let n = bin.len();
                bin[a % n] ^= 1 << bit;
            }
            DracoEdit::Truncate(a) => truncate = Some(a % bin.len()),
        }
    }
    if let Some(t) = truncate {
        bin.truncate(t);
    }
    glb(&json, &bin)
}

proptest! {
    #![proptest_config(config())]

    /// A Draco-compressed GLB (gltf-transform's, five primitives) with
    /// its extension objects and the accessors they fill mutated — stream
    /// views out of range or of other primitives, unique ids missing or
    /// huge, counts up to 2⁶⁴, other component types and types, modes —
    /// and its bytes flipped or cut short: each loads and renders, or is
    /// refused naming the file; no panic, no allocation beyond the
    /// decoding budget (64 MiB plus 64 times the file's buffers).
    #[test]
    fn hostile_draco_gltf(edits in proptest::collection::vec(draco_edit(), 1..4)) {
        let dir = TempDir::new("fuzz-draco");
        let bytes = hostile_draco_glb(&edits);
        let path = dir.join("d.glb");
        std::fs::write(&path, &bytes).unwrap();
        let budget = wavetrace::scene::gltf::DECODE_ALLOWANCE as usize
            + wavetrace::scene::gltf::DECODE_RATIO as usize * bytes.len();
        load_asset_case(&path, budget, &edits)?;
    }
}

/// A 40-byte Draco stream declaring a billion triangles and points: with
/// accessors that declare what the file holds, the decoder's limits (the
/// accessors' counts) refuse it; with accessors declaring a billion too,
/// the decoding budget refuses it before the decode. Neither allocates
/// more than a megabyte at once.
#[test]
fn a_draco_stream_declaring_a_billion_triangles_is_refused_before_allocating() {
    use serde_json::json;
    // "DRACO", version 2.2, a triangular mesh, sequential connectivity,
    // no flags; then 10^9 faces and 10^9 points (varints), raw indices.
    let mut stream = b"DRACO\x02\x02\x01\x00\x00\x00".to_vec();
    for _ in 0..2 {
        stream.extend([0x80, 0x94, 0xeb, 0xdc, 0x03]);
    }
    stream.push(1);
    stream.resize(40, 0);
    for (count, why) in [(3u64, "does not decode"), (1_000_000_000, "decoded data")] {
        let gltf = json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["KHR_draco_mesh_compression"],
            "extensionsRequired": ["KHR_draco_mesh_compression"],
            "buffers": [{"byteLength": 40}],
            "bufferViews": [{"buffer": 0, "byteLength": 40}],
            "accessors": [
                {"componentType": 5125, "count": count * 3, "type": "SCALAR"},
                {"componentType": 5126, "count": count, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 1]},
            ],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 1}, "indices": 0,
                "extensions": {"KHR_draco_mesh_compression":
                    {"bufferView": 0, "attributes": {"POSITION": 0}}}}]}],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}],
        });
        let dir = TempDir::new("draco-billion");
        let path = dir.join("b.glb");
        std::fs::write(&path, glb(&gltf, &stream)).unwrap();
        let start = Instant::now();
        let (r, largest) = largest_allocation(|| wavetrace::scene::gltf::load(&path));
        let Err(e) = r else { panic!("not refused") };
        let shown = e.to_string();
        eprintln!(
            "{shown} ({largest} bytes at most at once, {:?})",
            start.elapsed()
        );
        assert!(largest < 1 << 20, "allocated {largest} bytes at once");
        assert!(start.elapsed() < Duration::from_secs(1));
        assert!(
            shown.contains("meshes[0].primitives[0].extensions.KHR_draco_mesh_compression")
                && shown.contains(why),
            "{shown}"
        );
    }
}
