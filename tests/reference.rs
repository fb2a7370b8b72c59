//! The reference tracer against answers known in closed form.
//!
//! - Depth 1 sees only emission: exactly the light's radiance from its front,
//!   exactly 0 from behind it (emission is one-sided) and through the open
//!   front of the Cornell box.
//! - A furnace: a closed cube whose inward faces all emit `E` and reflect
//!   with albedo `a`. Every path stays inside and every bounce sees `E`, so the
//!   estimator at max depth `D` has mean `E·(1 + a + … + a^(D-1))` — exactly
//!   `E` at depth 1. Means are checked against that within 5 standard errors
//!   estimated from the data (pixels at 1 sample per pixel are independent
//!   samples: each has its own random stream); every sample is also checked
//!   against the hard bounds that `cos θ ∈ [0, 1]` puts on it.
//! - No emission anywhere: every pixel is exactly 0.

mod common;

use glam::Vec3;
use wavetrace::film::{FIXED_POINT_SCALE, Film};
use wavetrace::integrator::Counters;
use wavetrace::integrator::reference::ReferenceTracer;
use wavetrace::integrator::sampler::{Independent, PathRng, Sampler};
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::{Integrator, Scene, file};

/// The Cornell light's radiance (shared/scenes/cornell-dh2323.json).
const LIGHT: Vec3 = Vec3::splat(10.0);
/// The light's plane (y down: just below the ceiling at y = -1).
const LIGHT_Y: f32 = -0.996_396_4;

fn trace(tracer: &ReferenceTracer, o: Vec3, d: Vec3, seed: u32) -> (Vec3, u64) {
    let sampler = Independent::new(42);
    let mut path = sampler.start(seed, 0);
    let mut counters = Counters::default();
    let l = tracer.trace_path(&sampler, &mut path, (o, d.normalize()), 0, &mut counters);
    (l, counters.rays)
}

fn bits(v: Vec3) -> [u32; 3] {
    v.to_array().map(f32::to_bits)
}

/// Points on the light's interior and origins in the room below it.
fn light_rays(n: u32) -> Vec<(Vec3, Vec3)> {
    let mut rng = PathRng::new(7, 7, 7);
    (0..n)
        .map(|_| {
            // The light spans x, z in [-0.45, 0.45]; stay inside its edges.
            let target = Vec3::new(
                rng.next_f32() * 0.8 - 0.4,
                LIGHT_Y,
                rng.next_f32() * 0.8 - 0.4,
            );
            // Origins in the open space above the blocks (y < -0.2 is above
            // the tall block's top at y = -0.189), inside the room.
            let origin = Vec3::new(
                rng.next_f32() * 1.6 - 0.8,
                -0.25 - rng.next_f32() * 0.6,
                rng.next_f32() * 1.6 - 0.8,
            );
            (origin, target - origin)
        })
        .collect()
}

#[test]
fn depth_1_looking_at_the_light_returns_its_radiance_exactly() {
    let scene = Scene::cornell();
    let tracer = ReferenceTracer::new(&scene, 1);
    // Straight up (the lab's y points down) from the centre of the box.
    let (l, rays) = trace(&tracer, Vec3::ZERO, Vec3::NEG_Y, 0);
    assert_eq!(bits(l), bits(LIGHT), "got {l}");
    assert_eq!(rays, 1);
    for (i, (o, d)) in light_rays(2_000).into_iter().enumerate() {
        let (l, rays) = trace(&tracer, o, d, i as u32);
        assert_eq!(bits(l), bits(LIGHT), "from {o} along {d}: {l}");
        assert_eq!(rays, 1);
    }
}

#[test]
fn depth_2_looking_at_the_light_still_returns_exactly_its_radiance() {
    // The light cannot see itself, and nothing else emits: the bounce off
    // the light adds exactly 0.
    let tracer = ReferenceTracer::new(&Scene::cornell(), 2);
    for (i, (o, d)) in light_rays(2_000).into_iter().enumerate() {
        let (l, rays) = trace(&tracer, o, d, i as u32);
        assert_eq!(bits(l), bits(LIGHT), "from {o} along {d}: {l}");
        assert_eq!(rays, 2);
    }
}

#[test]
fn the_light_does_not_emit_backwards() {
    // From the gap between the ceiling (y = -1) and the light (y ≈ -0.9964),
    // looking down (+y) at the light's back.
    let tracer = ReferenceTracer::new(&Scene::cornell(), 1);
    for (x, z) in [(0.0, 0.0), (0.3, -0.2), (-0.4, 0.4)] {
        let (l, rays) = trace(&tracer, Vec3::new(x, -0.999, z), Vec3::Y, 0);
        assert_eq!(bits(l), [0; 3], "back of the light at ({x}, {z}): {l}");
        assert_eq!(rays, 1, "the ray must hit the light's back");
    }
    // A small scene: one emitting square facing +z, seen from both sides.
    let text = r#"
        [camera]
        position = [0.0, 0.0, -3.0]
        forward = [0.0, 0.0, 1.0]
        up = [0.0, 1.0, 0.0]
        vfov_deg = 40.0
        width = 8
        height = 8
        [materials.lamp]
        reflectance = [0.5, 0.5, 0.5]
        emission = [3.0, 2.0, 1.0]
        [[quad]]
        material = "lamp"
        vertices = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]]
    "#;
    let scene = file::parse(text, "lamp.toml").unwrap();
    assert_eq!(scene.triangles[0].normal, Vec3::Z);
    for depth in [1, 3] {
        let tracer = ReferenceTracer::new(&scene, depth);
        // From the front (+z side, looking along -z): its radiance. The
        // bounce leaves into empty space, adding exactly 0.
        let (l, _) = trace(&tracer, Vec3::new(0.2, 0.1, 2.0), -Vec3::Z, 1);
        assert_eq!(bits(l), bits(Vec3::new(3.0, 2.0, 1.0)), "front: {l}");
        // From behind: nothing.
        let (l, rays) = trace(&tracer, Vec3::new(0.2, 0.1, -2.0), Vec3::Z, 1);
        assert_eq!(bits(l), [0; 3], "back at depth {depth}: {l}");
        assert!(rays >= 1);
    }
}

#[test]
fn depth_1_sees_nothing_but_emitters() {
    // Looking at the floor, the walls and the blocks at depth 1: exactly 0.
    let tracer = ReferenceTracer::new(&Scene::cornell(), 1);
    for d in [Vec3::Y, Vec3::X, Vec3::NEG_X, Vec3::Z] {
        let (l, rays) = trace(&tracer, Vec3::new(0.0, -0.5, -0.9), d, 0);
        assert_eq!(bits(l), [0; 3], "along {d}: {l}");
        assert_eq!(rays, 1);
    }
}

#[test]
fn rays_out_of_the_open_front_return_zero() {
    let tracer = ReferenceTracer::new(&Scene::cornell(), 3);
    let (l, rays) = trace(&tracer, Vec3::ZERO, Vec3::NEG_Z, 0);
    assert_eq!(bits(l), [0; 3]);
    assert_eq!(rays, 1, "one ray, which escapes");
    // From in front of the blocks towards every part of the open face z = -1.
    let mut rng = PathRng::new(3, 3, 3);
    for i in 0..2_000 {
        let o = Vec3::new(
            rng.next_f32() * 1.8 - 0.9,
            rng.next_f32() * 1.8 - 0.9,
            -0.95,
        );
        let target = Vec3::new(
            rng.next_f32() * 1.98 - 0.99,
            rng.next_f32() * 1.98 - 0.99,
            -1.0,
        );
        let (l, rays) = trace(&tracer, o, target - o, i);
        assert_eq!(bits(l), [0; 3], "from {o} to {target}: {l}");
        assert_eq!(rays, 1);
    }
    // And from the camera, looking away from the box.
    let (l, rays) = trace(&tracer, Vec3::new(0.0, 0.0, -3.0), Vec3::NEG_Z, 0);
    assert_eq!((bits(l), rays), ([0; 3], 1));
}

/// A closed cube [-1, 1]^3 of 6 quads whose front (counter-clockwise) sides
/// face inwards, all of material `wall`; the camera inside.
fn furnace_toml(reflectance: [f32; 3], emission: [f32; 3], size: u32) -> String {
    let mut quads = String::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for sign in [-1.0f32, 1.0] {
            // (e_u, e_v) turns counter-clockwise about +e_axis; the face at
            // -1 faces +e_axis (inwards) in that order, the face at +1 needs
            // the reverse order.
            let mut corners: Vec<[f32; 3]> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                .iter()
                .map(|&(a, b)| {
                    let mut p = [0.0; 3];
                    p[axis] = sign;
                    p[u] = a;
                    p[v] = b;
                    p
                })
                .collect();
            if sign > 0.0 {
                corners.reverse();
            }
            quads += &format!(
                "[[quad]]\nmaterial = \"wall\"\nvertices = {:?}\n\n",
                corners
                    .iter()
                    .map(|p| p.map(|c| c as f64))
                    .collect::<Vec<_>>()
            );
        }
    }
    format!(
        r#"name = "furnace"

[camera]
position = [0.2, -0.3, 0.1]
look_at = [0.5, 0.4, 1.0]
up = [0.0, 1.0, 0.0]
vfov_deg = 120.0
width = {size}
height = {size}

[materials.wall]
reflectance = {reflectance:?}
emission = {emission:?}

{quads}"#
    )
}

fn furnace(reflectance: [f32; 3], emission: [f32; 3]) -> Scene {
    let text = furnace_toml(reflectance, emission, 128);
    let scene = file::parse(&text, "furnace.toml").unwrap_or_else(|e| panic!("{e}\n{text}"));
    // The set-up itself: 12 triangles, all facing the centre.
    assert_eq!(scene.triangles.len(), 12);
    for t in &scene.triangles {
        assert!(t.normal.dot(-t.v[0]) > 0.0, "{t:?} faces outwards");
    }
    scene
}

/// Every integrator.
const INTEGRATORS: [Integrator; 3] = [Integrator::Report, Integrator::Bsdf, Integrator::Nee];

/// Renders `scene` at 1 sample per pixel, max depth `depth`, with the
/// reference tracer and `integrator`; returns its film and its counters.
/// The wavefront engine renders it too and must trace the same paths: the
/// same counts, and every pixel within 1e-5 (relative) of the reference.
fn render(scene: &Scene, depth: u32, seed: u64, integrator: Integrator) -> (Film, Counters) {
    let run = |engine| {
        let mut settings = RenderSettings::for_scene(scene);
        settings.integrator = integrator;
        settings.spp = 1;
        settings.max_depth = depth;
        settings.seed = seed;
        settings.threads = 2;
        settings.engine = engine;
        let (film, mut counters, _) = Renderer::new(scene, &settings).unwrap().render();
        assert_eq!(film.invalid_samples, 0);
        counters.stages = Default::default();
        (film, counters)
    };
    let reference = run(Engine::Reference);
    let wavefront = run(Engine::Wavefront);
    assert_eq!(reference.1, wavefront.1, "{integrator:?}");
    for (a, b) in reference.0.to_rgb().iter().zip(wavefront.0.to_rgb()) {
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() <= 1e-5 * a[c].abs().max(b[c].abs()) + 1e-6);
        }
    }
    reference
}

/// Checks the furnace's per-channel mean against `E·Σ a^k (k < depth)`
/// for every integrator, and every sample against what the estimator can
/// give: within `[E, E·Σ (2a)^k]` for the report's (cos θ ∈ [0, 1], pdf
/// 1/2π); exactly the mean for `bsdf` (cosine sampling of a diffuse BRDF
/// weighs every bounce by exactly `a`), save paths that escape; at least
/// `E` for `nee` (the camera ray's emission is never weighted).
fn check_furnace(a: [f32; 3], e: [f32; 3], depth: u32, seed: u64) {
    let scene = furnace(a, e);
    for integrator in INTEGRATORS {
        let (film, counters) = render(&scene, depth, seed, integrator);
        let n = film.sums.len();
        assert_eq!(counters.paths, n as u64);
        // Closed: every path should bounce to the full depth. A ray that
        // leaves a surface within rounding of an edge may start just
        // behind the neighbouring face and leave the cube through the
        // gap: bounded here so that a real leak (a larger offset, a crack
        // in the intersection) fails.
        let full = counters.paths * depth as u64;
        let rays = counters.rays - counters.shadow_rays;
        assert!(
            rays <= full && (full - rays) * 1000 <= full,
            "{integrator:?}: {} of {full} rays escaped the closed furnace",
            full - rays
        );
        // Next-event estimation: a shadow ray from every vertex but the
        // last, save those towards a point in the vertex's own plane.
        let shadow_max = counters.paths * (depth as u64 - 1);
        match integrator {
            Integrator::Nee => assert!(
                counters.shadow_rays <= shadow_max && counters.shadow_rays * 2 >= shadow_max,
                "{} shadow rays of at most {shadow_max}",
                counters.shadow_rays
            ),
            _ => assert_eq!(counters.shadow_rays, 0),
        }
        let pixels = film.to_rgb();
        for c in 0..3 {
            let (a, e) = (a[c] as f64, e[c] as f64);
            let expected: f64 = (0..depth).map(|k| e * a.powi(k as i32)).sum();
            let upper: f64 = (0..depth).map(|k| e * (2.0 * a).powi(k as i32)).sum();
            let xs: Vec<f64> = pixels.iter().map(|p| p[c] as f64).collect();
            let mut off = 0;
            for &x in &xs {
                assert!(
                    x >= e * (1.0 - 1e-6),
                    "{integrator:?} channel {c}, depth {depth}: sample {x} below {e}"
                );
                match integrator {
                    Integrator::Report => assert!(
                        x <= upper * (1.0 + 1e-5),
                        "channel {c}, depth {depth}: sample {x} above {upper}"
                    ),
                    Integrator::Bsdf => off += ((x - expected).abs() > 1e-5 * expected) as usize,
                    Integrator::Nee => {}
                }
            }
            assert!(off * 1000 <= xs.len(), "bsdf: {off} samples off the mean");
            let mean = xs.iter().sum::<f64>() / n as f64;
            let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            let se = (var / n as f64).sqrt().max(1e-6 * expected);
            assert!(
                (mean - expected).abs() <= 5.0 * se,
                "{integrator:?} channel {c} (a = {a}, E = {e}), depth {depth}: mean {mean}, \
                 expected {expected} ± {} (5 standard errors)",
                5.0 * se
            );
        }
    }
}

#[test]
fn furnace_depth_1_is_exactly_the_emission() {
    let e = [1.0, 0.5, 2.25];
    let scene = furnace([0.25, 0.5, 0.8], e);
    for integrator in INTEGRATORS {
        let (film, counters) = render(&scene, 1, 1, integrator);
        assert_eq!(counters.rays, counters.paths);
        for (i, s) in film.sums.iter().enumerate() {
            let want = e.map(|c| (c as f64 * FIXED_POINT_SCALE) as u128);
            assert_eq!(*s, want, "pixel {i}");
        }
        for p in film.to_rgb() {
            assert_eq!(p, e);
        }
    }
}

#[test]
fn furnace_depth_2_mean_is_e_times_1_plus_a() {
    check_furnace([0.25, 0.5, 0.8], [1.0, 0.5, 2.25], 2, 2);
}

#[test]
fn furnace_depth_3_mean_is_e_times_1_plus_a_plus_a_squared() {
    check_furnace([0.25, 0.5, 0.8], [1.0, 0.5, 2.25], 3, 3);
    // A different seed and albedos near the ends of [0, 1].
    check_furnace([0.0, 0.05, 0.95], [1.5, 1.0, 0.75], 3, 4);
}

#[test]
fn grey_furnace_with_albedo_1_gains_exactly_e_per_bounce() {
    // Albedo 1 conserves energy: each bounce adds E on average, never more.
    check_furnace([1.0; 3], [1.0; 3], 3, 5);
    check_furnace([1.0; 3], [0.5; 3], 5, 6);
}

#[test]
fn a_scene_without_emission_renders_exactly_black() {
    let mut scene = Scene::cornell();
    for m in &mut scene.materials {
        m.emission = Vec3::ZERO;
    }
    for engine in [Engine::Reference, Engine::Wavefront] {
        let mut settings = common::settings(&scene, 24, 24, 4);
        settings.threads = 2;
        settings.engine = engine;
        let (film, counters, _) = Renderer::new(&scene, &settings).unwrap().render();
        assert_eq!(counters.paths, 24 * 24 * 4);
        assert!(counters.rays >= counters.paths);
        assert_eq!(film.invalid_samples, 0);
        assert!(film.sums.iter().all(|s| *s == [0; 3]), "{engine:?}");
    }
    // The same furnace: a closed box with no emission is black too.
    let scene = furnace([1.0; 3], [0.0; 3]);
    for integrator in INTEGRATORS {
        let (film, _) = render(&scene, 3, 1, integrator);
        assert!(film.sums.iter().all(|s| *s == [0; 3]));
    }
}

#[test]
fn the_lit_cornell_box_is_not_black() {
    // The counterpart of the test above, so that it cannot pass vacuously:
    // with the light on, the same render has light in every channel, and the
    // pixels looking at the light hold exactly 10 at depth 1.
    let scene = Scene::cornell();
    for engine in [Engine::Reference, Engine::Wavefront] {
        for integrator in INTEGRATORS {
            lit_cornell_box_at_depth_1(&scene, engine, integrator);
        }
    }
}

fn lit_cornell_box_at_depth_1(scene: &Scene, engine: Engine, integrator: Integrator) {
    let mut settings = common::settings(scene, 24, 24, 4);
    settings.integrator = integrator;
    settings.max_depth = 1;
    settings.threads = 2;
    settings.engine = engine;
    let (film, _, _) = Renderer::new(scene, &settings).unwrap().render();
    let rgb = film.to_rgb();
    // Every depth-1 pixel is a mix of exactly-10 and exactly-0 samples.
    for p in &rgb {
        let k = p[0] / 10.0 * 4.0;
        assert_eq!(k, k.round(), "pixel {p:?} is not a multiple of 10/4");
        assert!(p[0] == p[1] && p[1] == p[2]);
    }
    // Where the light is in the image: the focal length is the image height
    // (24 px), so row v looks along y/z = (v - 12)/24 from z = -3. The light
    // (y = -0.9964, x and z in [-0.45, 0.45]) covers rows 2.6 to 5.1 and, in
    // them, columns 12 ± 3.1 at least: pixels (9..=14, 3..=4) see only light.
    let at = |x: usize, y: usize| rgb[y * 24 + x][0];
    for y in 3..=4 {
        for x in 9..=14 {
            assert_eq!(at(x, y), 10.0, "pixel ({x}, {y}) should see only the light");
        }
    }
    for y in 12..24 {
        for x in 0..24 {
            assert_eq!(at(x, y), 0.0, "light at ({x}, {y})");
        }
    }
}
