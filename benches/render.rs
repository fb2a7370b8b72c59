//! Whole renders with the report's estimator (uniform hemisphere,
//! independent numbers, max depth 3): rays/s and paths/s.
//!
//! - `render_cornell_rays` / `render_cornell_paths`: the Cornell box at
//!   64x64, 16 spp, wavefront engine at 8 lanes and (where the CPU has
//!   AVX-512) 16 lanes, and the reference engine; 1 thread, 2 threads and
//!   all threads (the thread scaling of the target);
//! - `render_sphere1m_rays`: `scenes/sphere-1m.toml` (the box with a sphere
//!   of a million triangles) at 64x64, 16 spp, wavefront engine at each
//!   width, 1 thread and all threads (the hierarchy is built once, outside
//!   the timing).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use wavetrace::accel::simd::SimdWidth;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;

/// 1, 2 and all threads (each once).
fn thread_counts() -> Vec<usize> {
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut t = vec![1, 2.min(all), all];
    t.dedup();
    t
}

fn render(c: &mut Criterion) {
    let scene = Scene::cornell();
    let mut engines: Vec<(Engine, SimdWidth)> = SimdWidth::available()
        .into_iter()
        .map(|w| (Engine::Wavefront, w))
        .collect();
    engines.push((Engine::Reference, SimdWidth::W8));
    for (unit, group_name) in [
        ("rays", "render_cornell_rays"),
        ("paths", "render_cornell_paths"),
    ] {
        let mut group = c.benchmark_group(group_name);
        group.sample_size(10);
        for &(engine, simd) in &engines {
            for threads in thread_counts() {
                let mut s = RenderSettings::for_scene(&scene).report();
                (s.width, s.height, s.spp, s.threads) = (64, 64, 16, threads);
                (s.engine, s.simd) = (engine, simd);
                let renderer = Renderer::new(&scene, &s).unwrap();
                // Rays and paths are the same in every run of a seed.
                let (_, counters, _) = renderer.render();
                let n = if unit == "rays" {
                    counters.rays
                } else {
                    counters.paths
                };
                group.throughput(Throughput::Elements(n));
                let lanes = match engine {
                    Engine::Wavefront => format!("_x{}", simd.lanes()),
                    Engine::Reference => String::new(),
                };
                group.bench_function(format!("{}{lanes}_{threads}t", engine.name()), |b| {
                    b.iter(|| renderer.render())
                });
            }
        }
        group.finish();
    }

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sphere-1m.toml");
    let scene = Scene::load(&path).unwrap();
    let mut group = c.benchmark_group("render_sphere1m_rays");
    group.sample_size(10);
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    for simd in SimdWidth::available() {
        for threads in [1, all] {
            let mut s = RenderSettings::for_scene(&scene).report();
            (s.width, s.height, s.spp, s.threads, s.max_depth) = (64, 64, 16, threads, 3);
            s.simd = simd;
            let renderer = Renderer::new(&scene, &s).unwrap();
            let (_, counters, _) = renderer.render();
            group.throughput(Throughput::Elements(counters.rays));
            group.bench_function(format!("wavefront_x{}_{threads}t", simd.lanes()), |b| {
                b.iter(|| renderer.render())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, render);
criterion_main!(benches);
