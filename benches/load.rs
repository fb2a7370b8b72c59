//! Asset loading: a generated 1-million-triangle GLB (a UV sphere of 501
//! rings × 1000 segments, 502,502 vertices with normals and texture
//! coordinates, `u32` indices: 1,002,000 triangles, 28 MB) read as
//! `wavetrace render FILE` reads it (`asset_scene::load`: parse, decode,
//! flatten, the scene) and its renderer set up at 2 threads
//! (`Renderer::new`: the BVH and the engine), the two figures `--stats`
//! reports as `stages.load` and `stages.setup`. The issue's target is
//! 1.5 s for both on 2 cores.
//!
//! ```sh
//! cargo bench --bench load
//! WAVETRACE_BENCH_SUMMARY_ONLY=1 cargo bench --bench load   # medians only
//! ```
//!
//! Before the criterion group a summary prints the median of 5 runs of
//! each. `WAVETRACE_LOAD_GLB=path` writes the generated file there too (for
//! timing the command line: `wavetrace render path --stats s.json`).

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::time::Instant;
use wavetrace::render::{RenderSettings, Renderer};
use wavetrace::scene::asset_scene;

const RINGS: usize = 501;
const SEGMENTS: usize = 1001;

/// The GLB of a unit UV sphere of `RINGS` rings and `SEGMENTS - 1`
/// segments (the seam's vertices doubled), with normals and texture
/// coordinates.
pub fn sphere_glb() -> Vec<u8> {
    let (mut pos, mut nor, mut uv) = (Vec::new(), Vec::new(), Vec::new());
    for r in 0..=RINGS {
        let th = std::f32::consts::PI * r as f32 / RINGS as f32;
        for s in 0..SEGMENTS {
            let ph = std::f32::consts::TAU * s as f32 / (SEGMENTS - 1) as f32;
            let p = [th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin()];
            pos.extend(p.iter().flat_map(|c| c.to_le_bytes()));
            nor.extend(p.iter().flat_map(|c| c.to_le_bytes()));
            let t = [s as f32 / (SEGMENTS - 1) as f32, r as f32 / RINGS as f32];
            uv.extend(t.iter().flat_map(|c| c.to_le_bytes()));
        }
    }
    let mut idx = Vec::new();
    for r in 0..RINGS {
        for s in 0..SEGMENTS - 1 {
            let a = (r * SEGMENTS + s) as u32;
            let (b, c, d) = (a + 1, a + SEGMENTS as u32, a + SEGMENTS as u32 + 1);
            for i in [a, c, b, b, c, d] {
                idx.extend(i.to_le_bytes());
            }
        }
    }
    let n = (RINGS + 1) * SEGMENTS;
    let views: Vec<(usize, usize)> = [&pos, &nor, &uv, &idx]
        .iter()
        .scan(0, |at, b| {
            let v = (*at, b.len());
            *at += b.len();
            Some(v)
        })
        .collect();
    let bin = [pos, nor, uv, idx.clone()].concat();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{}}}],"bufferViews":[{}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{n},"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]}},
        {{"bufferView":1,"componentType":5126,"count":{n},"type":"VEC3"}},
        {{"bufferView":2,"componentType":5126,"count":{n},"type":"VEC2"}},
        {{"bufferView":3,"componentType":5125,"count":{},"type":"SCALAR"}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2}},"indices":3}}]}}],
        "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        bin.len(),
        views
            .iter()
            .map(|(o, l)| format!(r#"{{"buffer":0,"byteOffset":{o},"byteLength":{l}}}"#))
            .collect::<Vec<_>>()
            .join(","),
        idx.len() / 4,
    );
    let mut j = json.into_bytes();
    j.resize(j.len().next_multiple_of(4), b' ');
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

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("wavetrace-bench-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("sphere-1m.glb");
    let bytes = sphere_glb();
    std::fs::write(&path, &bytes).unwrap();
    if let Ok(p) = std::env::var("WAVETRACE_LOAD_GLB") {
        std::fs::write(p, &bytes).unwrap();
    }
    let load = || asset_scene::load(&path, None).unwrap().0;
    let setup = |scene: &wavetrace::scene::Scene| {
        let mut s = RenderSettings::for_scene(scene);
        s.threads = 2;
        Renderer::new(scene, &s).unwrap()
    };
    let (mut loads, mut setups) = (Vec::new(), Vec::new());
    let mut triangles = 0;
    for _ in 0..5 {
        let t = Instant::now();
        let scene = load();
        loads.push(t.elapsed().as_secs_f64());
        triangles = scene.triangles.len();
        let t = Instant::now();
        black_box(setup(&scene));
        setups.push(t.elapsed().as_secs_f64());
    }
    let (l, s) = (median(loads), median(setups));
    println!(
        "load 1M GLB ({triangles} triangles, {} MB): load {l:.3} s, setup (BVH) at 2 threads {s:.3} s, \
         together {:.3} s (medians of 5; target 1.5 s)",
        bytes.len() / 1_000_000,
        l + s
    );
    if std::env::var("WAVETRACE_BENCH_SUMMARY_ONLY").is_ok() {
        let _ = std::fs::remove_dir_all(&dir);
        return;
    }
    let mut g = c.benchmark_group("load_1m_glb");
    g.sample_size(10);
    g.bench_function("load", |b| b.iter(|| black_box(load())));
    let scene = load();
    g.bench_function("setup_2_threads", |b| b.iter(|| black_box(setup(&scene))));
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
