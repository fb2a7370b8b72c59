//! Reproducibility: an image depends on the scene, the settings and the seed,
//! and on nothing else — not the thread count, not how the samples are split
//! into passes, not a round trip through an accumulation file.

mod common;

use common::TempDir;
use wavetrace::film::Film;
use wavetrace::output::write_image;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;

fn settings(seed: u64, threads: usize) -> RenderSettings {
    let scene = Scene::cornell();
    let mut s = common::settings(&scene, 32, 24, 8);
    s.max_depth = 3;
    s.seed = seed;
    s.threads = threads;
    s
}

fn render(seed: u64, threads: usize) -> Film {
    render_with(seed, threads, Engine::Wavefront)
}

fn render_with(seed: u64, threads: usize, engine: Engine) -> Film {
    let mut s = settings(seed, threads);
    s.engine = engine;
    let (film, counters, _) = Renderer::new(&Scene::cornell(), &s).unwrap().render();
    assert_eq!(counters.paths, 32 * 24 * 8);
    film
}

fn assert_same_film(a: &Film, b: &Film, what: &str) {
    assert_eq!((a.width, a.height), (b.width, b.height), "{what}");
    assert_eq!(a.ranges, b.ranges, "{what}");
    assert_eq!(a.invalid_samples, b.invalid_samples, "{what}");
    let differing = a.sums.iter().zip(&b.sums).filter(|(x, y)| x != y).count();
    assert_eq!(differing, 0, "{what}: {differing} pixels differ");
}

#[test]
fn the_same_seed_gives_the_same_film_and_the_same_image_bytes() {
    let dir = TempDir::new("bytes");
    let a = render(11, 2);
    let b = render(11, 2);
    assert_same_film(&a, &b, "two renders with seed 11");
    // Not vacuous: the image has light in it and varies across pixels.
    assert!(a.sums.iter().any(|s| s[0] > 0));
    assert!(a.sums.iter().any(|s| s != &a.sums[0]));
    for ext in ["png", "pfm", "exr"] {
        let (pa, pb) = (dir.join(format!("a.{ext}")), dir.join(format!("b.{ext}")));
        write_image(&pa, a.width, a.height, &a.to_rgb()).unwrap();
        write_image(&pb, b.width, b.height, &b.to_rgb()).unwrap();
        let (ba, bb) = (std::fs::read(&pa).unwrap(), std::fs::read(&pb).unwrap());
        assert!(!ba.is_empty());
        assert!(ba == bb, "the .{ext} files differ");
    }
    // Written atomically: nothing but the six images is left in the folder.
    assert_eq!(
        dir.files(),
        ["a.exr", "a.pfm", "a.png", "b.exr", "b.pfm", "b.png"]
    );
}

#[test]
fn the_thread_count_does_not_change_the_film() {
    for engine in [Engine::Wavefront, Engine::Reference] {
        let one = render_with(5, 1, engine);
        for threads in [2, 3] {
            assert_same_film(
                &one,
                &render_with(5, threads, engine),
                &format!("{engine:?}: 1 vs {threads} threads"),
            );
        }
    }
    // The settings hash that guards accumulation files ignores threads too.
    let scene = Scene::cornell();
    assert_eq!(
        settings(5, 1).image_hash(&scene),
        settings(5, 3).image_hash(&scene)
    );
}

#[test]
fn a_different_seed_gives_a_different_film() {
    let a = render(1, 2);
    let b = render(2, 2);
    // Pixels that no path of either render lit are 0 in both; every lit
    // pixel's samples change with the seed, and equal sums of different
    // random samples would be a coincidence (pixels that see only the light
    // at every sample, exactly 10 each time, are the rare exception).
    let lit = a
        .sums
        .iter()
        .zip(&b.sums)
        .filter(|(x, y)| **x != [0; 3] || **y != [0; 3])
        .count();
    let differing = a.sums.iter().zip(&b.sums).filter(|(x, y)| x != y).count();
    assert!(lit > a.sums.len() / 4, "only {lit} pixels lit");
    assert!(
        differing * 10 >= lit * 9,
        "only {differing} of {lit} lit pixels differ between seeds 1 and 2"
    );
    let scene = Scene::cornell();
    assert_ne!(
        settings(1, 2).image_hash(&scene),
        settings(2, 2).image_hash(&scene)
    );
}

#[test]
fn splitting_the_samples_into_passes_changes_nothing() {
    let scene = Scene::cornell();
    let renderer = Renderer::new(&scene, &settings(9, 2)).unwrap();
    let mut whole = renderer.new_film();
    let c_whole = renderer.render_samples(0..8, &mut whole);

    let mut split = renderer.new_film();
    let c1 = renderer.render_samples(0..3, &mut split);
    let c2 = renderer.render_samples(3..8, &mut split);
    assert_same_film(&whole, &split, "0..8 vs 0..3 + 3..8");
    assert_eq!(c_whole.paths, c1.paths + c2.paths);
    assert_eq!(c_whole.rays, c1.rays + c2.rays);

    // In reverse order, and one sample at a time.
    let mut reversed = renderer.new_film();
    renderer.render_samples(5..8, &mut reversed);
    renderer.render_samples(0..5, &mut reversed);
    assert_same_film(&whole, &reversed, "5..8 then 0..5");
    let mut singles = renderer.new_film();
    for s in (0..8).rev() {
        renderer.render_samples(s..s + 1, &mut singles);
    }
    assert_same_film(&whole, &singles, "8 single samples");

    // The whole render is the same as render() and as another thread count.
    let (film, _, _) = renderer.render();
    assert_same_film(&whole, &film, "render_samples(0..8) vs render()");
}

#[test]
fn an_accumulation_file_round_trip_continues_the_render_exactly() {
    let dir = TempDir::new("acc");
    let scene = Scene::cornell();
    let s = settings(4, 2);
    let hash = s.image_hash(&scene);
    let renderer = Renderer::new(&scene, &s).unwrap();
    let mut whole = renderer.new_film();
    renderer.render_samples(0..8, &mut whole);

    let path = dir.join("part.acc");
    let mut first = renderer.new_film();
    renderer.render_samples(0..3, &mut first);
    first.save(&path, hash).unwrap();
    let (mut loaded, h) = Film::load(&path, Some(hash)).unwrap();
    assert_eq!(h, hash);
    assert_same_film(&first, &loaded, "saved vs loaded");
    renderer.render_samples(3..8, &mut loaded);
    assert_same_film(&whole, &loaded, "0..3 saved, loaded, + 3..8");

    // A file of another render (other seed) is refused when a hash is given.
    let other = settings(5, 2).image_hash(&scene);
    assert!(Film::load(&path, Some(other)).is_err());
    // A corrupt or truncated file is refused.
    let bytes = std::fs::read(&path).unwrap();
    let mut corrupt = bytes.clone();
    let mid = corrupt.len() / 2;
    corrupt[mid] ^= 1;
    std::fs::write(&path, &corrupt).unwrap();
    let e = Film::load(&path, Some(hash)).unwrap_err().to_string();
    assert!(e.contains("part.acc"), "{e}");
    std::fs::write(&path, &bytes[..bytes.len() - 5]).unwrap();
    assert!(Film::load(&path, Some(hash)).is_err());
    // And no temporary files are left beside it.
    assert_eq!(dir.files(), ["part.acc"]);
}

#[test]
fn a_pass_stopped_part_way_leaves_the_film_as_it_was() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    for engine in [Engine::Wavefront, Engine::Reference] {
        let mut s = settings(9, 2);
        s.engine = engine;
        let renderer = Renderer::new(&Scene::cornell(), &s).unwrap();
        let mut film = renderer.new_film();
        renderer.render_samples(0..3, &mut film);
        let before = film.clone();
        // Stop after a few tiles (rows, for the reference) have started.
        let calls = AtomicUsize::new(0);
        let stop = || calls.fetch_add(1, Ordering::SeqCst) >= 3;
        assert!(
            renderer
                .render_samples_or_stop(3..8, &mut film, &stop)
                .is_none()
        );
        assert!(calls.load(Ordering::SeqCst) > 3, "{engine:?}: never asked");
        assert_eq!(film, before, "{engine:?}: a stopped pass changed the film");
        // Not stopped: the same as rendering in place.
        let c = renderer.render_samples_or_stop(3..8, &mut film, &|| false);
        let mut direct = before.clone();
        let d = renderer.render_samples(3..8, &mut direct);
        assert_eq!((c.unwrap().paths, c.unwrap().rays), (d.paths, d.rays));
        assert_eq!(film, direct, "{engine:?}");
    }
}

/// Every integrator × sampler (and Russian roulette) gives the same film
/// whatever the thread count, the split of the samples into passes (which
/// is what sample-range shards are), the order of the passes, or a round
/// trip through an accumulation file — in both engines.
#[test]
fn every_estimator_is_reproducible_across_threads_passes_and_resumes() {
    use wavetrace::scene::options::{Integrator, SamplerKind};
    let dir = TempDir::new("estimators");
    let scene = Scene::cornell();
    let mut combos = vec![];
    for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
        for sampler in [SamplerKind::Independent, SamplerKind::Sobol] {
            for rr_depth in [None, Some(1)] {
                if integrator != Integrator::Report || rr_depth.is_none() {
                    combos.push((integrator, sampler, rr_depth));
                }
            }
        }
    }
    for (integrator, sampler, rr_depth) in combos {
        for engine in [Engine::Wavefront, Engine::Reference] {
            let what = format!("{integrator:?} {sampler:?} rr {rr_depth:?} {engine:?}");
            let at = |threads| {
                let mut s = settings(21, threads);
                (s.integrator, s.sampler, s.rr_depth, s.engine) =
                    (integrator, sampler, rr_depth, engine);
                s.batch_size = 100 * threads; // a batch size that splits tiles unevenly
                Renderer::new(&scene, &s).unwrap()
            };
            let (one, two) = (at(1), at(2));
            let mut whole = one.new_film();
            one.render_samples(0..8, &mut whole);
            assert!(whole.sums.iter().any(|s| s[0] > 0), "{what}: black");

            let mut passes = two.new_film();
            two.render_samples(5..8, &mut passes);
            two.render_samples(0..2, &mut passes);
            let path = dir.join("part.wtacc");
            let hash = two.settings().image_hash(&scene);
            passes.save(&path, hash).unwrap();
            let (mut resumed, _) = Film::load(&path, Some(hash)).unwrap();
            std::fs::remove_file(&path).unwrap();
            at(3).render_samples(2..5, &mut resumed);
            assert_same_film(&whole, &resumed, &what);
        }
    }
}

/// The scenes with mirrors, glass, metal and spheres (where the wavefront
/// engine sorts paths by model) give the same film at any thread count and
/// batch size, in both engines.
#[test]
fn scenes_of_every_model_are_reproducible_across_threads() {
    for name in ["cornell-spheres.toml", "cornell-materials.toml"] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        let scene = Scene::load(&path).unwrap();
        for engine in [Engine::Wavefront, Engine::Reference] {
            let at = |threads: usize, batch: usize| {
                let mut s = common::settings(&scene, 32, 24, 8);
                (s.threads, s.batch_size, s.engine, s.seed) = (threads, batch, engine, 13);
                Renderer::new(&scene, &s).unwrap().render().0
            };
            let one = at(1, 4096);
            assert!(one.sums.iter().any(|s| s[0] > 0), "{name}: black");
            assert_same_film(&one, &at(3, 77), &format!("{name} {engine:?}"));
        }
    }
}

/// The Cornell box (its open front towards the suns) with every kind of
/// punctual light (a sun with a cone, a delta sun, a point and a spot
/// light) beside its emissive quad: the same film
/// whatever the thread count, batch size, SIMD width (8 and 16 lanes),
/// and split of the samples into passes (sample-range shards), every
/// estimator, both engines.
#[test]
fn punctual_lights_are_reproducible_across_threads_widths_and_passes() {
    use wavetrace::accel::simd::SimdWidth;
    use wavetrace::scene::options::Integrator;
    let mut text = wavetrace::scene::CORNELL_TOML.to_string();
    text += r#"
[[light]]
type = "sun"
direction = [0.3, 0.5, 1.0]
irradiance = 2.0
angle = 5.0
[[light]]
type = "sun"
direction = [-0.3, 0.4, 1.0]
irradiance = 1.0
angle = 0.0
[[light]]
type = "point"
position = [0.2, -0.5, -0.3]
intensity = 0.5
[[light]]
type = "spot"
position = [-0.5, -0.8, 0.0]
direction = [0.3, 1.0, 0.0]
intensity = 1.0
inner_angle = 10.0
outer_angle = 30.0
"#;
    let scene = wavetrace::scene::file::parse(&text, "cornell-lights.toml").unwrap();
    for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
        for engine in [Engine::Wavefront, Engine::Reference] {
            let what = format!("{integrator:?} {engine:?}");
            let at = |threads: usize, batch: usize, simd: Option<SimdWidth>| {
                let mut s = common::settings(&scene, 32, 24, 8);
                (s.threads, s.batch_size, s.engine, s.seed) = (threads, batch, engine, 17);
                (s.integrator, s.max_depth) = (integrator, 3);
                if let Some(w) = simd {
                    s.simd = w;
                }
                Renderer::new(&scene, &s).unwrap()
            };
            let base = at(1, 4096, None);
            let mut whole = base.new_film();
            base.render_samples(0..8, &mut whole);
            assert!(whole.sums.iter().any(|s| s[0] > 0), "{what}: black");
            let mut parts = at(3, 77, None).new_film();
            let split = at(3, 77, None);
            split.render_samples(5..8, &mut parts);
            split.render_samples(0..5, &mut parts);
            assert_same_film(&whole, &parts, &format!("{what}, 3 threads, passes"));
            for w in SimdWidth::available() {
                let r = at(2, 100, Some(w));
                let mut f = r.new_film();
                r.render_samples(0..8, &mut f);
                assert_same_film(&whole, &f, &format!("{what}, {w:?}"));
            }
        }
    }
}
