//! The intersect kernel: closest hit of incoherent rays in the Cornell box,
//! scalar brute force against 8-wide packs (rays/s).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use std::hint::black_box;
use wavetrace::accel::triangle::{
    Triangle8, TriangleEdges, closest_hit_brute_force, closest_hit_packs,
};
use wavetrace::integrator::sampler::PathRng;
use wavetrace::scene::Scene;

/// Rays from random points inside the box in random directions.
fn rays(n: usize) -> Vec<(Vec3, Vec3)> {
    let mut rng = PathRng::new(1, 2, 3);
    let mut r = move || rng.next_f32() * 2.0 - 1.0;
    (0..n)
        .map(|_| {
            let o = Vec3::new(r() * 0.95, r() * 0.95, r() * 0.95);
            let d = Vec3::new(r(), r(), r()).normalize_or(Vec3::Z);
            (o, d)
        })
        .collect()
}

fn intersect(c: &mut Criterion) {
    let scene = Scene::cornell();
    let tris: Vec<TriangleEdges> = scene.triangles.iter().map(TriangleEdges::from).collect();
    let packs = Triangle8::pack_all(&tris);
    let eps = 0.0; // rays start off surfaces (`wavetrace::integrator::offset`)
    let rays = rays(100_000);
    let mut group = c.benchmark_group("intersect_cornell");
    group.throughput(Throughput::Elements(rays.len() as u64));
    group.bench_function("scalar", |b| {
        b.iter(|| {
            let mut hits = 0u32;
            for &(o, d) in &rays {
                hits += closest_hit_brute_force(&tris, o, d, eps, f32::INFINITY).is_some() as u32;
            }
            black_box(hits)
        })
    });
    group.bench_function("simd_x8", |b| {
        b.iter(|| {
            let mut hits = 0u32;
            for &(o, d) in &rays {
                hits += closest_hit_packs(&packs, o, d, eps, f32::INFINITY).is_some() as u32;
            }
            black_box(hits)
        })
    });
    group.finish();
}

criterion_group!(benches, intersect);
criterion_main!(benches);
