//! Whole renders with the report's estimator (max depth 3): rays/s and
//! paths/s.
//!
//! - `render_cornell_*`: the Cornell box at 64x64, 16 spp, wavefront and
//!   reference engines, 1 thread and all threads;
//! - `render_sphere1m`: `scenes/sphere-1m.toml` (the box with a sphere of a
//!   million triangles) at 64x64, 16 spp, wavefront engine, 1 thread and all
//!   threads (the hierarchy is built once, outside the timing).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;

fn render(c: &mut Criterion) {
    let scene = Scene::cornell();
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    for (unit, group_name) in [
        ("rays", "render_cornell_rays"),
        ("paths", "render_cornell_paths"),
    ] {
        let mut group = c.benchmark_group(group_name);
        group.sample_size(10);
        for engine in [Engine::Wavefront, Engine::Reference] {
            for threads in [1, all] {
                let mut s = RenderSettings::for_scene(&scene);
                (s.width, s.height, s.spp, s.threads, s.engine) = (64, 64, 16, threads, engine);
                let renderer = Renderer::new(&scene, &s).unwrap();
                // Rays and paths are the same in every run of a seed.
                let (_, counters, _) = renderer.render();
                let n = if unit == "rays" {
                    counters.rays
                } else {
                    counters.paths
                };
                group.throughput(Throughput::Elements(n));
                group.bench_function(format!("{}_{}t", engine.name(), threads), |b| {
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
    for threads in [1, all] {
        let mut s = RenderSettings::for_scene(&scene);
        (s.width, s.height, s.spp, s.threads, s.max_depth) = (64, 64, 16, threads, 3);
        let renderer = Renderer::new(&scene, &s).unwrap();
        let (_, counters, _) = renderer.render();
        group.throughput(Throughput::Elements(counters.rays));
        group.bench_function(format!("wavefront_{threads}t"), |b| {
            b.iter(|| renderer.render())
        });
    }
    group.finish();
}

criterion_group!(benches, render);
criterion_main!(benches);
