//! Asset loading, the two figures `--stats` reports as `stages.load`
//! (`asset_scene::load`, as `wavetrace render FILE` reads it: parse,
//! decode, flatten, the scene) and `stages.setup` (`Renderer::new` at 2
//! threads: the BVH and the engine), medians of 5 runs, for two generated
//! GLB files:
//! - a 1-million-triangle UV sphere (501 rings × 1000 segments, 502,502
//!   vertices with normals and texture coordinates, `u32` indices:
//!   1,002,000 triangles, 28 MB); issue 27's target is 1.5 s for both on
//!   2 cores;
//! - a small textured asset, the per-asset overhead of a dataset job: a UV
//!   sphere of 100,172 triangles (159 rings × 316 segments, less the
//!   poles' slivers) with a 1024 × 1024 base colour PNG embedded; issue
//!   30's target is 50 ms for both on 2 cores.
//!
//! ```sh
//! cargo bench --bench load
//! WAVETRACE_BENCH_SUMMARY_ONLY=1 cargo bench --bench load   # medians only
//! ```
//!
//! Before the criterion group a summary prints the medians.
//! `WAVETRACE_LOAD_GLB=path` writes the generated 1M file there too, and
//! `WAVETRACE_SMALL_GLB=path` the small one (for timing the command line:
//! `wavetrace render path --stats s.json`).

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::time::Instant;
use wavetrace::render::{RenderSettings, Renderer};
use wavetrace::scene::asset_scene;

/// The GLB of a unit UV sphere of `rings` rings and `segments - 1`
/// segments (the seam's vertices doubled), with normals and texture
/// coordinates, and where `png` is given, that image as its base colour
/// texture.
pub fn sphere_glb(rings: usize, segments: usize, png: Option<&[u8]>) -> Vec<u8> {
    let (mut pos, mut nor, mut uv) = (Vec::new(), Vec::new(), Vec::new());
    for r in 0..=rings {
        let th = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let ph = std::f32::consts::TAU * s as f32 / (segments - 1) as f32;
            let p = [th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin()];
            pos.extend(p.iter().flat_map(|c| c.to_le_bytes()));
            nor.extend(p.iter().flat_map(|c| c.to_le_bytes()));
            let t = [s as f32 / (segments - 1) as f32, r as f32 / rings as f32];
            uv.extend(t.iter().flat_map(|c| c.to_le_bytes()));
        }
    }
    let mut idx = Vec::new();
    for r in 0..rings {
        for s in 0..segments - 1 {
            let a = (r * segments + s) as u32;
            let (b, c, d) = (a + 1, a + segments as u32, a + segments as u32 + 1);
            for i in [a, c, b, b, c, d] {
                idx.extend(i.to_le_bytes());
            }
        }
    }
    let n = (rings + 1) * segments;
    let indices = idx.len() / 4;
    let mut parts = vec![pos, nor, uv, idx];
    parts.extend(png.map(<[u8]>::to_vec));
    let views: Vec<(usize, usize)> = parts
        .iter()
        .scan(0, |at, b| {
            let v = (*at, b.len());
            *at += b.len();
            Some(v)
        })
        .collect();
    let bin = parts.concat();
    let (material, textured) = if png.is_some() {
        (
            r#","material":0"#,
            r#","materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}],
            "textures":[{"source":0,"sampler":0}],"samplers":[{}],
            "images":[{"bufferView":4,"mimeType":"image/png"}]"#,
        )
    } else {
        ("", "")
    };
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{}}}],"bufferViews":[{}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{n},"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]}},
        {{"bufferView":1,"componentType":5126,"count":{n},"type":"VEC3"}},
        {{"bufferView":2,"componentType":5126,"count":{n},"type":"VEC2"}},
        {{"bufferView":3,"componentType":5125,"count":{indices},"type":"SCALAR"}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2}},"indices":3{material}}}]}}],
        "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0{textured}}}"#,
        bin.len(),
        views
            .iter()
            .map(|(o, l)| format!(r#"{{"buffer":0,"byteOffset":{o},"byteLength":{l}}}"#))
            .collect::<Vec<_>>()
            .join(","),
    );
    let mut j = json.into_bytes();
    j.resize(j.len().next_multiple_of(4), b' ');
    let mut bin = bin;
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + j.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// A `size` × `size` PNG of coloured noise (so it does not compress to
/// nothing, as a photographed texture would not).
fn noise_png(size: u32) -> Vec<u8> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let img = image::RgbImage::from_fn(size, size, |x, y| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let n = (state >> 56) as u8 / 4;
        image::Rgb([(x / 4) as u8 ^ n, (y / 4) as u8 ^ n, 128 + n])
    });
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Medians of 5 runs of loading `path` and setting its renderer up at 2
/// threads, in seconds, and its triangle count.
fn load_and_setup(path: &std::path::Path) -> (f64, f64, usize) {
    let (mut loads, mut setups) = (Vec::new(), Vec::new());
    let mut triangles = 0;
    for _ in 0..5 {
        let t = Instant::now();
        let scene = load(path);
        loads.push(t.elapsed().as_secs_f64());
        triangles = scene.triangles.len();
        let t = Instant::now();
        black_box(setup(&scene));
        setups.push(t.elapsed().as_secs_f64());
    }
    (median(loads), median(setups), triangles)
}

fn load(path: &std::path::Path) -> wavetrace::scene::Scene {
    asset_scene::load(path, None).unwrap().0
}

fn setup(scene: &wavetrace::scene::Scene) -> Renderer {
    let mut s = RenderSettings::for_scene(scene);
    s.threads = 2;
    Renderer::new(scene, &s).unwrap()
}

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("wavetrace-bench-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let big = dir.join("sphere-1m.glb");
    let bytes = sphere_glb(501, 1001, None);
    std::fs::write(&big, &bytes).unwrap();
    let small = dir.join("small-textured.glb");
    let small_bytes = sphere_glb(159, 317, Some(&noise_png(1024)));
    std::fs::write(&small, &small_bytes).unwrap();
    for (var, b) in [
        ("WAVETRACE_LOAD_GLB", &bytes),
        ("WAVETRACE_SMALL_GLB", &small_bytes),
    ] {
        if let Ok(p) = std::env::var(var) {
            std::fs::write(p, b).unwrap();
        }
    }
    let (l, s, triangles) = load_and_setup(&big);
    println!(
        "load 1M GLB ({triangles} triangles, {} MB): load {l:.3} s, setup (BVH) at 2 threads {s:.3} s, \
         together {:.3} s (medians of 5; target 1.5 s)",
        bytes.len() / 1_000_000,
        l + s
    );
    let (l, s, triangles) = load_and_setup(&small);
    println!(
        "small textured GLB ({triangles} triangles, a 1024x1024 PNG, {:.1} MB): load {:.1} ms, \
         setup (BVH) at 2 threads {:.1} ms, together {:.1} ms (medians of 5; target 50 ms)",
        small_bytes.len() as f64 / 1e6,
        l * 1e3,
        s * 1e3,
        (l + s) * 1e3
    );
    if std::env::var("WAVETRACE_BENCH_SUMMARY_ONLY").is_ok() {
        let _ = std::fs::remove_dir_all(&dir);
        return;
    }
    for (name, path) in [("load_1m_glb", &big), ("load_small_textured_glb", &small)] {
        let mut g = c.benchmark_group(name);
        g.sample_size(10);
        g.bench_function("load", |b| b.iter(|| black_box(load(path))));
        let scene = load(path);
        g.bench_function("setup_2_threads", |b| b.iter(|| black_box(setup(&scene))));
        g.finish();
    }
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
