//! A whole render of the Cornell box (64x64, 16 spp, depth 3): rays/s and
//! paths/s, wavefront and reference engines, 1 thread and all threads.

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
}

criterion_group!(benches, render);
criterion_main!(benches);
