//! The wavefront engine against the reference tracer, the SIMD intersector
//! against the scalar one, and the image against the schedule.

mod common;

use common::TempDir;
use glam::Vec3;
use wavetrace::accel::triangle::{
    Hit, LaneHits, Triangle8, TriangleEdges, closest_hit_brute_force, closest_hit_packs,
};
use wavetrace::film::Film;
use wavetrace::integrator::sampler::PathRng;
use wavetrace::math::V3;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;
use wavetrace::scene::options::{Integrator, SamplerKind};
use wide::f32x8;

fn render(scene: &Scene, f: impl FnOnce(&mut RenderSettings)) -> Film {
    let mut s = RenderSettings::for_scene(scene);
    f(&mut s);
    Renderer::new(scene, &s).unwrap().render().0
}

/// Every scene in `scenes/`, parsed.
fn all_scenes() -> Vec<(String, Scene)> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let mut scenes: Vec<(String, Scene)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // scenes/views-*.toml are `wavetrace views` jobs, not scenes.
        .filter(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("views-"))
        })
        .map(|p| (p.display().to_string(), Scene::load(&p).unwrap()))
        .collect();
    scenes.sort_by(|a, b| a.0.cmp(&b.0));
    assert!(!scenes.is_empty());
    scenes
}

/// Per pixel and channel: `|a - b| <= REL · max(|a|, |b|) + ABS`.
/// The engines trace the very same paths (same hits, same directions, same
/// bits); only the order in which a path's terms are summed differs — the
/// reference adds them on the way back up its recursion, the wavefront
/// engine on the way down — which moves a sample by a few ulps.
const REL: f32 = 1e-5;
const ABS: f32 = 1e-6;

fn assert_close(scene: &str, a: &Film, b: &Film) {
    let (ra, rb) = (a.to_rgb(), b.to_rgb());
    for (i, (pa, pb)) in ra.iter().zip(&rb).enumerate() {
        for c in 0..3 {
            let (x, y) = (pa[c], pb[c]);
            assert!(
                (x - y).abs() <= REL * x.abs().max(y.abs()) + ABS,
                "{scene}: pixel {i} channel {c}: reference {x}, wavefront {y}"
            );
        }
    }
    assert_eq!(a.invalid_samples, b.invalid_samples);
}

/// Every integrator × sampler, and the default estimator with Russian
/// roulette.
fn estimators() -> Vec<(Integrator, SamplerKind, Option<u32>)> {
    let mut all = vec![];
    for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
        for sampler in [SamplerKind::Independent, SamplerKind::Sobol] {
            all.push((integrator, sampler, None));
        }
    }
    all.push((Integrator::Nee, SamplerKind::Sobol, Some(1)));
    all.push((Integrator::Bsdf, SamplerKind::Independent, Some(2)));
    all
}

#[test]
fn wavefront_matches_reference_on_every_scene() {
    for (name, scene) in all_scenes() {
        // Big scenes at a small size; the Cornell box at several settings.
        let combos: &[(u32, u32, u32)] = if scene.triangles.len() > 10_000 {
            &[(16, 2, 3)]
        } else {
            &[(24, 4, 3), (17, 3, 1), (32, 2, 2), (12, 5, 6)]
        };
        for (integrator, sampler, rr_depth) in estimators() {
            for &(size, spp, depth) in combos {
                let set = |s: &mut RenderSettings| {
                    s.width = size;
                    s.height = size + 3;
                    s.spp = spp;
                    s.max_depth = depth;
                    s.seed = 11;
                    (s.integrator, s.sampler, s.rr_depth) = (integrator, sampler, rr_depth);
                };
                let reference = render(&scene, |s| {
                    set(s);
                    s.engine = Engine::Reference;
                });
                let wavefront = render(&scene, |s| {
                    set(s);
                    s.engine = Engine::Wavefront;
                });
                assert_close(
                    &format!(
                        "{name} {integrator:?} {sampler:?} rr {rr_depth:?} {size}px {spp}spp depth {depth}"
                    ),
                    &reference,
                    &wavefront,
                );
            }
        }
    }
}

#[test]
fn depth_one_is_bit_identical_to_reference() {
    // At depth 1 a sample is the emission it sees: no sums to reorder.
    let scene = Scene::cornell();
    let set = |s: &mut RenderSettings| {
        s.width = 40;
        s.height = 40;
        s.spp = 3;
        s.max_depth = 1;
    };
    let a = render(&scene, |s| {
        set(s);
        s.engine = Engine::Reference;
    });
    let b = render(&scene, |s| {
        set(s);
        s.engine = Engine::Wavefront;
    });
    assert_eq!(a, b);
}

#[test]
fn image_is_independent_of_threads_and_batch_size() {
    let scene = Scene::cornell();
    let film = |threads: usize, batch: usize| {
        render(&scene, |s| {
            s.width = 33;
            s.height = 29;
            s.spp = 7;
            s.seed = 5;
            s.threads = threads;
            s.batch_size = batch;
        })
    };
    let base = film(1, 4096);
    for (threads, batch) in [(2, 4096), (3, 4096), (1, 1), (2, 7), (3, 64), (2, 100_000)] {
        assert_eq!(
            base,
            film(threads, batch),
            "threads {threads}, batch {batch}"
        );
    }
    // ...and the same film written as PNG gives the same bytes.
    let dir = TempDir::new("png");
    let png = |f: &Film, name: &str| {
        let p = dir.join(name);
        wavetrace::output::write_image(&p, f.width, f.height, &f.to_rgb()).unwrap();
        std::fs::read(p).unwrap()
    };
    assert_eq!(png(&base, "a.png"), png(&film(2, 13), "b.png"));
}

#[test]
#[allow(clippy::assertions_on_constants)] // a failing test, not a failing build
fn build_pins_the_simd_instruction_set() {
    // The x8 kernels are compared bit for bit with scalar code; the default
    // build must use AVX2 + FMA on x86-64 (`.cargo/config.toml`).
    #[cfg(target_arch = "x86_64")]
    {
        assert!(cfg!(target_feature = "avx2"), "built without AVX2");
        assert!(cfg!(target_feature = "fma"), "built without FMA");
    }
}

/// Random rays of every kind against triangle soups: hits, misses, grazing
/// rays, rays through shared edges and vertices, starts on surfaces.
#[test]
fn simd_intersector_equals_scalar_on_a_million_rays() {
    let mut rng = PathRng::new(99, 0, 0);
    let mut r = move || rng.next_f32();
    let cornell: Vec<TriangleEdges> = Scene::cornell()
        .triangles
        .iter()
        .map(TriangleEdges::from)
        .collect();

    // A grid of triangles sharing edges and vertices, and a random soup of
    // 13 (not a multiple of 8: padded lanes).
    let mut grid = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            let p = |a: i32, b: i32| {
                Vec3::new((i + a) as f32 * 0.5 - 1.0, (j + b) as f32 * 0.5 - 1.0, 0.25)
            };
            for v in [[p(0, 0), p(1, 0), p(1, 1)], [p(0, 0), p(1, 1), p(0, 1)]] {
                grid.push(TriangleEdges::new(v[0], v[1], v[2]));
            }
        }
    }
    let mut soup = Vec::new();
    for _ in 0..13 {
        let mut v = || Vec3::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0);
        let (a, b, c) = (v(), v(), v());
        soup.push(TriangleEdges::new(a, b, c));
    }

    let mut count = 0;
    let mut hits = 0;
    for tris in [&cornell, &grid, &soup] {
        let packs = Triangle8::pack_all(tris);
        for k in 0..350_000 {
            let kind = k % 4;
            let (o, d) = match kind {
                // Anywhere to anywhere.
                0 => {
                    let o = Vec3::new(r() * 4.0 - 2.0, r() * 4.0 - 2.0, r() * 4.0 - 2.0);
                    let d = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize();
                    (o, d)
                }
                // Aimed at a vertex or an edge point of a triangle.
                1 => {
                    let t = &tris[k % tris.len()];
                    let target = match k % 3 {
                        0 => t.v0,
                        1 => t.v0 + t.e1 * 0.5,
                        _ => t.v0 + t.e1 * 0.5 + t.e2 * 0.5,
                    };
                    let o = Vec3::new(r() * 4.0 - 2.0, r() * 4.0 - 2.0, -2.0);
                    (o, (target - o).normalize())
                }
                // Grazing: nearly in a triangle's plane.
                2 => {
                    let t = &tris[k % tris.len()];
                    let n = t.e1.cross(t.e2).normalize();
                    let along = (t.e1 + t.e2 * r()).normalize();
                    let o = t.v0 - along * 0.5 + n * (r() - 0.5) * 1e-4;
                    (o, (along + n * (r() - 0.5) * 1e-5).normalize())
                }
                // Starting on a surface.
                _ => {
                    let t = &tris[k % tris.len()];
                    let (a, b) = (r() * 0.5, r() * 0.5);
                    let o = t.v0 + t.e1 * a + t.e2 * b;
                    let d = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize();
                    (o, d)
                }
            };
            let t_min = if kind == 3 { 1e-4 } else { 0.0 };
            let scalar = closest_hit_brute_force(tris, o, d, t_min, f32::INFINITY);
            let simd = closest_hit_packs(&packs, o, d, t_min, f32::INFINITY);
            let bits = |h: Option<Hit>| h.map(|h| (h.triangle, h.t.to_bits()));
            assert_eq!(bits(scalar), bits(simd), "ray {o} -> {d}");
            // Packs in any order (as a hierarchy visits them) with the
            // general tie-break: still the same hit.
            let any_order = {
                let (o8, d8) = (V3::splat(o), V3::splat(d));
                let mut best = LaneHits::new(f32::INFINITY);
                for p in packs.iter().rev() {
                    p.intersect::<false>(&o8, &d8, f32x8::splat(t_min), &mut best);
                }
                best.closest()
            };
            assert_eq!(
                bits(scalar),
                bits(any_order),
                "reversed packs: ray {o} -> {d}"
            );
            count += 1;
            hits += scalar.is_some() as u32;
        }
    }
    assert!(count >= 1_000_000);
    // Both outcomes were exercised plenty.
    assert!(
        hits > 200_000 && hits < count - 100_000,
        "{hits} hits of {count}"
    );
}

#[test]
fn sample_ranges_ending_at_u32_max_render_exactly_their_samples() {
    // Batches step through the range; near u32::MAX a plain `+` would wrap
    // and start over at sample 0.
    let scene = Scene::cornell();
    let mut s = common::settings(&scene, 3, 2, u32::MAX);
    s.batch_size = 5;
    let range = u32::MAX - 13..u32::MAX;
    let mut films = Vec::new();
    for engine in [Engine::Wavefront, Engine::Reference] {
        s.engine = engine;
        let renderer = Renderer::new(&scene, &s).unwrap();
        let mut film = renderer.new_film();
        let c = renderer.render_samples(range.clone(), &mut film);
        assert_eq!(c.paths, 6 * 13, "{engine:?}");
        assert_eq!(film.ranges, vec![range.clone()]);
        films.push(film);
    }
    assert_close("u32::MAX range", &films[1], &films[0]);
}
