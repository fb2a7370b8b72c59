//! The `sobol` sampler seen from outside the crate, and a guard that adding
//! it left the `independent` sampler's images byte for byte as they were.

use wavetrace::film::Film;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;

/// An xxh3 of everything a film holds: its size, sums, sample ranges and
/// refused samples.
fn film_hash(film: &Film) -> u64 {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(&film.width.to_le_bytes());
    h.update(&film.height.to_le_bytes());
    for s in &film.sums {
        for c in s {
            h.update(&c.to_le_bytes());
        }
    }
    for r in &film.ranges {
        h.update(&r.start.to_le_bytes());
        h.update(&r.end.to_le_bytes());
    }
    h.update(&film.invalid_samples.to_le_bytes());
    h.digest()
}

fn render(scene: &Scene, engine: Engine, seed: u64, max_depth: u32) -> Film {
    let mut s = RenderSettings::for_scene(scene);
    (s.width, s.height, s.spp, s.max_depth) = (32, 24, 8, max_depth);
    (s.seed, s.threads, s.engine) = (seed, 2, engine);
    Renderer::new(scene, &s).unwrap().render().0
}

/// The films of the `independent` sampler (the only one the integrators
/// use so far) are those of the commit before the sampler module became a
/// directory with `sobol` in it (92df1c6): these hashes were taken there,
/// with this very test. Both engines, two scenes, a short and a deep path.
#[test]
fn independent_images_are_byte_identical_to_before_sobol() {
    const BEFORE: [(&str, Engine, u64, u32, u64); 8] = [
        ("cornell", Engine::Reference, 0, 3, 0xf47371800d87320c),
        ("cornell", Engine::Reference, 7, 12, 0x513eb0155aafcf57),
        ("cornell", Engine::Wavefront, 0, 3, 0xe39feb811de270ba),
        ("cornell", Engine::Wavefront, 7, 12, 0x6cdf1afe5f2923f6),
        ("cornell-obj", Engine::Reference, 0, 3, 0x3b488a04a2e639e0),
        ("cornell-obj", Engine::Reference, 7, 12, 0x3cce4e17654d75e6),
        ("cornell-obj", Engine::Wavefront, 0, 3, 0xcd689bdccdac1a85),
        ("cornell-obj", Engine::Wavefront, 7, 12, 0x493f0fce2d18f909),
    ];
    let cornell = Scene::cornell();
    let obj = Scene::load(std::path::Path::new("scenes/cornell-obj.toml")).unwrap();
    for (name, engine, seed, depth, want) in BEFORE {
        let scene = if name == "cornell" { &cornell } else { &obj };
        let got = film_hash(&render(scene, engine, seed, depth));
        assert_eq!(
            got, want,
            "{name} {engine:?} seed {seed} depth {depth}: {got:#018x}"
        );
    }
    // The settings hash of checkpoints and shards sees the same build.
    assert_eq!(
        wavetrace::integrator::estimator_fingerprint(),
        FINGERPRINT_BEFORE,
        "{:#018x}",
        wavetrace::integrator::estimator_fingerprint()
    );
}

/// `estimator_fingerprint()` at 92df1c6.
const FINGERPRINT_BEFORE: u64 = 0xa1445333b9c5e092;
