//! Adaptive sampling ([`Adaptive`]): pixels stop taking samples once their
//! estimated error is low. Held to the uniform render (a threshold of 0
//! is it, bit for bit), to itself across threads, batch sizes, kernel
//! widths and engines, and, statistically, to the uniform render's mean.

mod common;

use common::TempDir;
use wavetrace::accel::simd::SimdWidth;
use wavetrace::film::Film;
use wavetrace::render::{Adaptive, Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;

fn settings(spp: u32, seed: u64, adaptive: Option<Adaptive>) -> RenderSettings {
    let scene = Scene::cornell();
    let mut s = common::settings(&scene, 24, 18, spp);
    s.max_depth = 4;
    s.seed = seed;
    s.threads = 2;
    s.adaptive = adaptive;
    s
}

fn adaptive(threshold: f32, min_spp: u32) -> Option<Adaptive> {
    Some(Adaptive { threshold, min_spp })
}

/// The adaptive render of `s` (which must have `adaptive`).
fn render(s: &RenderSettings) -> Film {
    let r = Renderer::new(&Scene::cornell(), s).unwrap();
    let mut film = r.new_film();
    r.render_adaptive_or_stop(&mut film, &|| false).unwrap();
    film
}

fn bits(film: &Film) -> Vec<[u32; 3]> {
    film.to_rgb().iter().map(|p| p.map(f32::to_bits)).collect()
}

#[test]
fn a_threshold_of_zero_is_the_uniform_render_bit_for_bit() {
    let uniform = Renderer::new(&Scene::cornell(), &settings(16, 3, None))
        .unwrap()
        .render()
        .0;
    let film = render(&settings(16, 3, adaptive(0.0, 2)));
    // Every pixel with any noise in its neighbourhood takes every sample;
    // the rest (the black outside the box, seen at the sides) stop after
    // the first round, their mean already exact.
    let counts = film.counts.as_ref().expect("an adaptive film has counts");
    let all = counts.iter().filter(|&&c| c == 16).count();
    assert!(all > counts.len() * 3 / 4, "{counts:?}");
    for (i, c) in counts.iter().enumerate() {
        match c {
            16 => assert_eq!(
                film.sums[i], uniform.sums[i],
                "pixel {i}: rounds 0..2, .., 8..16 sum as 0..16"
            ),
            _ => assert_eq!((*c, film.sums[i]), (2, [0; 3]), "pixel {i}"),
        }
    }
    assert_eq!(bits(&film), bits(&uniform));
    assert_eq!(film.invalid_samples, uniform.invalid_samples);
}

#[test]
fn quiet_pixels_stop_early_and_noisy_ones_take_every_sample() {
    let film = render(&settings(64, 5, adaptive(0.2, 4)));
    let counts = film.counts.as_ref().unwrap();
    // Counts are the rounds' ends: 4, 8, 16, 32, 64.
    assert!(
        counts.iter().all(|c| [4, 8, 16, 32, 64].contains(c)),
        "{counts:?}"
    );
    let at = |n: u32| counts.iter().filter(|&&c| c == n).count();
    assert!(at(64) > 0, "some pixels are noisy to the end: {counts:?}");
    assert!(at(64) < counts.len(), "some stop early: {counts:?}");
    // The ceiling's light is seen directly (no noise) where it fills a
    // pixel and its neighbours: those stop after the first round.
    assert!(at(4) > 0, "{counts:?}");
    // A higher threshold stops more pixels earlier: fewer samples in all.
    let looser = render(&settings(64, 5, adaptive(0.5, 4)));
    let total = |f: &Film| {
        f.counts
            .as_ref()
            .unwrap()
            .iter()
            .map(|&c| c as u64)
            .sum::<u64>()
    };
    assert!(
        total(&looser) < total(&film),
        "{} vs {}",
        total(&looser),
        total(&film)
    );
    // A pixel's error is judged from its own samples: the means are the
    // pixels' sums over their own counts.
    let rgb = film.to_rgb();
    let q = 4_294_967_296.0f64;
    for (i, (s, c)) in film.sums.iter().zip(counts).enumerate() {
        let want = (s[1] as f64 / (*c as f64 * q)) as f32;
        assert_eq!(rgb[i][1].to_bits(), want.to_bits(), "pixel {i}");
    }
}

#[test]
fn the_bytes_do_not_depend_on_threads_batches_or_lanes() {
    let base = settings(32, 9, adaptive(0.15, 4));
    let want = render(&base);
    let mut variants = vec![];
    for threads in [1, 3] {
        variants.push((
            format!("{threads} threads"),
            RenderSettings {
                threads,
                ..base.clone()
            },
        ));
    }
    for batch_size in [1, 61, 100_000] {
        variants.push((
            format!("batch {batch_size}"),
            RenderSettings {
                batch_size,
                ..base.clone()
            },
        ));
    }
    for simd in [SimdWidth::W8, SimdWidth::W16] {
        if simd.is_available() {
            variants.push((
                format!("{simd:?}"),
                RenderSettings {
                    simd,
                    ..base.clone()
                },
            ));
        }
    }
    for (what, s) in variants {
        let film = render(&s);
        assert_eq!(film.counts, want.counts, "{what}");
        assert_eq!(film.sums, want.sums, "{what}");
    }
}

#[test]
fn the_wavefront_engine_takes_the_reference_tracers_samples() {
    let base = settings(32, 2, adaptive(0.15, 4));
    let wavefront = render(&base);
    let reference = render(&RenderSettings {
        engine: Engine::Reference,
        ..base
    });
    assert_eq!(wavefront.counts, reference.counts);
    let (a, b) = (wavefront.to_rgb(), reference.to_rgb());
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        for k in 0..3 {
            let tol = 1e-5 * x[k].abs().max(y[k].abs()) + 1e-6;
            assert!((x[k] - y[k]).abs() <= tol, "pixel {i}: {x:?} vs {y:?}");
        }
    }
}

/// The image's mean radiance (green).
fn mean(film: &Film) -> f64 {
    let rgb = film.to_rgb();
    rgb.iter().map(|p| p[1] as f64).sum::<f64>() / rgb.len() as f64
}

#[test]
fn adaptive_sampling_keeps_the_image_mean_of_the_uniform_render() {
    // Over 12 seeds, the image means of adaptive renders (a loose
    // threshold, so that most pixels stop early) and of uniform renders of
    // the same samples per pixel: the difference of their averages, in
    // standard errors. Stopping a pixel on its own samples may bias it;
    // the test bounds that bias by the noise of 12 images.
    let seeds = 12;
    let (mut ad, mut un) = (vec![], vec![]);
    for seed in 0..seeds {
        ad.push(mean(&render(&settings(32, 100 + seed, adaptive(0.3, 4)))));
        let uniform = Renderer::new(&Scene::cornell(), &settings(32, 200 + seed, None))
            .unwrap()
            .render()
            .0;
        un.push(mean(&uniform));
    }
    let stats = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64;
        (m, var / v.len() as f64)
    };
    let ((ma, va), (mu, vu)) = (stats(&ad), stats(&un));
    let z = (ma - mu) / (va + vu).sqrt();
    assert!(z.abs() < 4.0, "adaptive {ma} vs uniform {mu}: z = {z}");
}

#[test]
fn impossible_settings_are_refused_before_the_render() {
    let scene = Scene::cornell();
    for (a, says) in [
        (adaptive(-0.1, 4), "noise threshold"),
        (adaptive(f32::NAN, 4), "noise threshold"),
        (adaptive(0.1, 1), "min_spp"),
        (adaptive(0.1, 17), "min_spp"),
    ] {
        let err = Renderer::new(&scene, &settings(16, 0, a))
            .err()
            .expect("refused");
        assert!(err.to_string().contains(says), "{err}");
    }
}

#[test]
fn a_views_job_renders_adaptively_and_refuses_bad_fields() {
    let dir = TempDir::new("adaptive-views");
    let glb = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textured.glb");
    let job = |extra: &str| {
        format!(
            "[assets]\nfiles = [\"{}\"]\n[cameras]\nkind = \"orbit\"\nviews = 2\n[render]\nwidth = 24\nheight = 16\nspp = 16\n{extra}\n",
            glb.display()
        )
    };
    let path = dir.path().join("job.toml");
    std::fs::write(&path, job("noise_threshold = 0.1\nmin_spp = 4")).unwrap();
    let out = dir.path().join("out");
    common::run_ok(
        dir.path(),
        &[
            "views",
            common::p(&path),
            "--out-dir",
            common::p(&out),
            "-t",
            "2",
        ],
    );
    let written = common::tree(&out);
    assert!(
        written.keys().any(|p| p.ends_with("textured/1.png")),
        "{:?}",
        written.keys()
    );
    for (extra, says) in [
        ("min_spp = 4", "render.min_spp"),
        ("noise_threshold = -1.0", "render.noise_threshold"),
        ("noise_threshold = 0.1\nmin_spp = 32", "render.min_spp"),
    ] {
        std::fs::write(&path, job(extra)).unwrap();
        let err = common::run_refused(
            dir.path(),
            &["views", common::p(&path), "--out-dir", common::p(&out)],
        );
        assert!(
            err.contains(says) && err.contains("job.toml"),
            "{extra}: {err}"
        );
    }
}
