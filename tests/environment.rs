//! The environment light (docs/lights.md): every integrator sees it, the
//! engines agree on it, `nee`'s importance sampling of it is unbiased, and
//! images stay a function of the seed.

mod common;

use common::{TempDir, run_ok, run_refused};
use std::sync::Arc;
use wavetrace::film::Film;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;
use wavetrace::scene::environment::Environment;
use wavetrace::scene::file::parse;
use wavetrace::scene::options::{Integrator, SamplerKind};

/// A white diffuse sphere (or, with `ground`, a grey sphere on a ground
/// square, and a small emissive square above) seen from the front.
fn scene(ground: bool, env: &str) -> Scene {
    let mut text = String::from(
        r#"
name = "env-test"
[camera]
position = [0.0, 1.0, 4.0]
look_at = [0.0, 0.6, 0.0]
up = [0.0, 1.0, 0.0]
vfov_deg = 45.0
width = 16
height = 16
[integrator]
max_depth = 4
[materials.white]
reflectance = [1.0, 1.0, 1.0]
[materials.grey]
reflectance = [0.6, 0.5, 0.4]
[materials.lamp]
reflectance = [0.0, 0.0, 0.0]
emission = [4.0, 4.0, 4.0]
"#,
    );
    if ground {
        text += r#"
[[sphere]]
center = [0.0, 0.7, 0.0]
radius = 0.7
material = "grey"
[[quad]]
material = "grey"
vertices = [[-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0], [-3.0, 0.0, -3.0]]
[[quad]]
material = "lamp"
vertices = [[-0.3, 2.5, -0.3], [0.3, 2.5, -0.3], [0.3, 2.5, 0.3], [-0.3, 2.5, 0.3]]
"#;
    } else {
        text += r#"
[[sphere]]
center = [0.0, 0.6, 0.0]
radius = 1.0
material = "white"
"#;
    }
    text += &format!("[environment]\n{env}\n");
    parse(&text, "env-test.toml").unwrap()
}

/// A 32×16 sky: a gradient, a dark lower half and a bright small sun at
/// texel (20, 4), turned by `rotation` degrees.
fn sky(rotation: f32) -> Environment {
    sky_with_sun(rotation, [400.0, 380.0, 300.0])
}

/// [`sky`] with the sun's texel of radiance `sun`.
fn sky_with_sun(rotation: f32, sun: [f32; 3]) -> Environment {
    let mut env = scene(false, "color = [1.0, 1.0, 1.0]").environment.unwrap();
    let (w, h) = (32u32, 16u32);
    env.texels = Arc::new(
        (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| {
                if (i, j) == (20, 4) {
                    sun
                } else if j >= h / 2 {
                    [0.1, 0.08, 0.05]
                } else {
                    [0.3 + 0.02 * i as f32, 0.5, 0.9 - 0.05 * j as f32]
                }
            })
            .collect(),
    );
    (env.width, env.height, env.rotation_deg) = (w, h, rotation);
    env
}

fn render(scene: &Scene, f: impl FnOnce(&mut RenderSettings)) -> Film {
    let mut s = RenderSettings::for_scene(scene);
    s.threads = 2;
    f(&mut s);
    let (film, _, _) = Renderer::new(scene, &s).unwrap().render();
    assert_eq!(film.invalid_samples, 0);
    film
}

#[test]
fn a_white_furnace_is_the_environments_radiance_in_every_pixel() {
    // A white diffuse sphere under a constant environment of radiance
    // 0.5: every path ends in the environment with throughput 1, so every
    // pixel is 0.5 (within noise for the estimators that are not exact
    // here), for every integrator and both engines.
    let scene = scene(false, "color = [0.5, 0.5, 0.5]");
    for engine in [Engine::Wavefront, Engine::Reference] {
        for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
            let film = render(&scene, |s| {
                (s.engine, s.integrator, s.spp, s.max_depth) = (engine, integrator, 256, 64);
            });
            let rgb = film.to_rgb();
            let mean: f64 =
                rgb.iter().flatten().map(|&v| v as f64).sum::<f64>() / (rgb.len() * 3) as f64;
            assert!(
                (mean - 0.5).abs() < 2e-3,
                "{engine:?} {integrator:?}: mean {mean}"
            );
            for (i, p) in rgb.iter().enumerate() {
                for c in p {
                    assert!(
                        (c - 0.5).abs() < 0.04,
                        "{engine:?} {integrator:?}: pixel {i} is {c}"
                    );
                }
            }
        }
    }
}

#[test]
fn an_invisible_environment_lights_the_scene_but_not_the_background() {
    // `visible = false`: camera rays that miss see black (the corners),
    // while the sphere is still lit by the environment (the centre).
    let scene = scene(false, "color = [0.5, 0.5, 0.5]\nvisible = false");
    for engine in [Engine::Wavefront, Engine::Reference] {
        for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
            let film = render(&scene, |s| {
                (s.engine, s.integrator, s.spp) = (engine, integrator, 16);
            });
            let rgb = film.to_rgb();
            let at = |x: usize, y: usize| rgb[y * 16 + x];
            assert_eq!(at(0, 0), [0.0; 3], "{engine:?} {integrator:?}");
            assert_eq!(at(15, 15), [0.0; 3], "{engine:?} {integrator:?}");
            let centre = at(8, 9)[0];
            assert!(
                (centre - 0.5).abs() < 0.1,
                "{engine:?} {integrator:?}: {centre}"
            );
        }
    }
}

/// Per pixel and channel: the engines trace the same paths and sum their
/// terms in another order.
fn assert_close(what: &str, a: &Film, b: &Film) {
    common::assert_engines_close(what, &a.to_rgb(), &b.to_rgb());
}

#[test]
fn the_wavefront_engine_matches_the_reference_under_an_environment() {
    let mut scene = scene(true, "color = [1.0, 1.0, 1.0]");
    scene.environment = Some(sky(37.0));
    for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
        for sampler in [SamplerKind::Independent, SamplerKind::Sobol] {
            let settings = |s: &mut RenderSettings| {
                (s.integrator, s.sampler, s.spp) = (integrator, sampler, 8);
            };
            let a = render(&scene, |s| {
                settings(s);
                s.engine = Engine::Reference;
            });
            let b = render(&scene, settings);
            assert_close(&format!("{integrator:?} {sampler:?}"), &a, &b);
        }
    }
}

#[test]
fn images_under_an_environment_are_a_function_of_the_seed() {
    let mut scene = scene(true, "color = [1.0, 1.0, 1.0]");
    scene.environment = Some(sky(200.0));
    let bits = |f: &Film| {
        f.to_rgb()
            .iter()
            .flatten()
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    let base = bits(&render(&scene, |s| s.spp = 8));
    for (threads, batch) in [(1, 7), (2, 64), (3, 4096)] {
        let other = render(&scene, |s| {
            (s.spp, s.threads, s.batch_size) = (8, threads, batch);
        });
        assert_eq!(bits(&other), base, "{threads} threads, batch {batch}");
    }
    for simd in wavetrace::accel::simd::SimdWidth::available() {
        let other = render(&scene, |s| (s.spp, s.simd) = (8, simd));
        assert_eq!(bits(&other), base, "{simd:?}");
    }
}

/// `K` seeds' images of `scene` by `integrator` at `spp`: per pixel and
/// channel, the mean and the squared standard error of the mean.
fn estimate(scene: &Scene, integrator: Integrator, spp: u32) -> Vec<(f64, f64)> {
    const K: u64 = 16;
    let images: Vec<Vec<f64>> = (0..K)
        .map(|k| {
            let film = render(scene, |s| {
                (s.integrator, s.spp, s.seed) = (integrator, spp, 500 + k);
                s.sampler = SamplerKind::Independent;
            });
            film.to_rgb().iter().flatten().map(|&v| v as f64).collect()
        })
        .collect();
    (0..images[0].len())
        .map(|i| {
            let mean = images.iter().map(|im| im[i]).sum::<f64>() / K as f64;
            let var = images.iter().map(|im| (im[i] - mean).powi(2)).sum::<f64>() / (K - 1) as f64;
            (mean, var / K as f64)
        })
        .collect()
}

/// Mean z² and largest |z| of `a` against `b` (see tests/unbiased.rs).
fn z_scores(a: &[(f64, f64)], b: &[(f64, f64)]) -> (f64, f64) {
    let z: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(&(ma, va), &(mb, vb))| match va + vb {
            0.0 if ma == mb => 0.0,
            0.0 => f64::INFINITY,
            v => (ma - mb) / v.sqrt(),
        })
        .collect();
    let mean_z2 = z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64;
    (mean_z2, z.iter().fold(0.0, |m, z| z.abs().max(m)))
}

#[test]
fn nee_with_environment_sampling_converges_to_bsdfs_image() {
    // A sphere on a ground square under a sky with a small bright sun and
    // a small lamp: nee picks the lamp or the sky by power, samples the
    // sky by its compensated luminance × sin θ, and weighs both against BSDF sampling.
    // It must converge to the image of plain BSDF sampling.
    let mut scene = scene(true, "color = [1.0, 1.0, 1.0]");
    scene.environment = Some(sky(37.0));
    let bsdf = estimate(&scene, Integrator::Bsdf, 1024);
    let nee = estimate(&scene, Integrator::Nee, 128);
    let (mean_z2, max_z) = z_scores(&nee, &bsdf);
    eprintln!("nee vs bsdf under an environment: mean z² {mean_z2:.3}, max |z| {max_z:.2}");
    assert!(
        mean_z2 < 1.6 && max_z < 7.0,
        "mean z² {mean_z2:.3}, max |z| {max_z:.2}"
    );
}

#[test]
fn render_takes_an_environment_for_any_scene() {
    let dir = TempDir::new("env-cli");
    // A colour, on the built-in Cornell box, both engines.
    for engine in ["wavefront", "reference"] {
        let out = dir.join(format!("{engine}.pfm"));
        let o = out.to_str().unwrap();
        run_ok(
            &dir,
            &[
                "render",
                "--env",
                "0.2,0.3,0.4",
                "--env-strength",
                "2",
                "--env-rotation",
                "-30",
                "--engine",
                engine,
                "-s",
                "2",
                "--width",
                "8",
                "--height",
                "8",
                "-o",
                o,
            ],
        );
    }
    // Strength or rotation without an environment, a missing file and
    // a file of another kind are refused, naming what is wrong.
    let e = run_refused(&dir, &["render", "--env-strength", "2", "-s", "1"]);
    assert!(e.contains("--env"), "{e}");
    let e = run_refused(&dir, &["render", "--env", "nowhere.exr", "-s", "1"]);
    assert!(e.contains("nowhere.exr"), "{e}");
    std::fs::write(dir.join("sky.png"), b"not an environment").unwrap();
    let e = run_refused(&dir, &["render", "--env", "sky.png", "-s", "1"]);
    assert!(e.contains("sky.png") && e.contains(".hdr"), "{e}");
    let e = run_refused(
        &dir,
        &[
            "render",
            "--env",
            "1,1,1",
            "--env-strength",
            "-1",
            "-s",
            "1",
        ],
    );
    assert!(e.contains("strength"), "{e}");
}

#[test]
fn a_scene_file_names_its_environment() {
    let dir = TempDir::new("env-toml");
    let base = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell.toml"))
        .unwrap();
    let with = |table: &str| format!("{base}\n[environment]\n{table}\n");
    // A file relative to the scene's directory.
    let texels = [[1.0f32, 2.0, 3.0], [4.0, 5.0, 6.0]];
    exr::prelude::write_rgb_file(dir.join("sky.exr"), 2, 1, |x, _| {
        let t = texels[x];
        (t[0], t[1], t[2])
    })
    .unwrap();
    std::fs::write(
        dir.join("a.toml"),
        with("file = \"sky.exr\"\nrotation = 90\nstrength = 0.5"),
    )
    .unwrap();
    let scene = Scene::load(&dir.join("a.toml")).unwrap();
    assert!(scene.sources.contains(&dir.join("sky.exr")));
    let env = scene.environment.unwrap();
    assert_eq!(
        (env.width, env.height, env.strength, env.rotation_deg),
        (2, 1, 0.5, 90.0)
    );
    assert_eq!(env.texels[1], [4.0, 5.0, 6.0]);
    // Errors name the file, the line and the field.
    for (table, field) in [
        ("color = [1, 2]", "environment.color"),
        ("color = [1, 1, 1]\nfile = \"sky.exr\"", "environment.file"),
        ("color = [1, 1, 1]\nstrength = -2", "environment.strength"),
        ("color = [1, 1, 1]\nbrightness = 2", "brightness"),
        ("file = \"none.hdr\"", "environment.file"),
    ] {
        std::fs::write(dir.join("b.toml"), with(table)).unwrap();
        let e = Scene::load(&dir.join("b.toml")).unwrap_err().to_string();
        assert!(e.contains("b.toml:") && e.contains(field), "{table}: {e}");
    }
}

#[test]
fn a_lit_plane_shows_the_irradiance_of_the_sky_above_it() {
    // A white Lambertian plane seen from above under a sky of a gradient
    // and a sun, direct light only (max depth 2): every pixel's expected
    // value is E/π, E = ∫ L(ω) cos θ dω over the upper hemisphere, here
    // by quadrature of the environment's own lookup. nee draws the sky by
    // its compensated density (the directions no brighter than the sky's
    // mean are left to BSDF sampling) and weighs the two strategies by
    // MIS; both engines must land on E/π. A density that does not match
    // the compensated sampling (the plain one) is 39% too bright (z 152).
    use wavetrace::integrator::environment::EnvLight;
    use wavetrace::math::V3;
    let mut scene = common::ground_scene(
        [0.0, 1.0, 0.0],
        30.0,
        (32, 32),
        "[environment]\ncolor = [1.0, 1.0, 1.0]",
    );
    let env = sky_with_sun(23.0, [40.0, 38.0, 30.0]);
    let light = EnvLight::new(&env);
    scene.environment = Some(env);
    // E by the midpoint rule in (φ, cos θ) over the upper hemisphere.
    let m = 1500;
    let mut e = [0.0f64; 3];
    for a in 0..m {
        for b in 0..m {
            let phi = (a as f64 + 0.5) / m as f64 * std::f64::consts::TAU;
            let z = (b as f64 + 0.5) / m as f64;
            let r = (1.0 - z * z).sqrt();
            let d = V3::new((r * phi.cos()) as f32, z as f32, (r * phi.sin()) as f32);
            let l = light.radiance(d);
            let dw = std::f64::consts::TAU / (m * m) as f64;
            for (e, l) in e.iter_mut().zip([l.x, l.y, l.z]) {
                *e += f64::from(l) * z * dw;
            }
        }
    }
    let expected = e.map(|e| e / std::f64::consts::PI);
    for engine in [Engine::Wavefront, Engine::Reference] {
        let film = render(&scene, |s| {
            (s.engine, s.spp, s.seed) = (engine, 64, 11);
            s.sampler = SamplerKind::Independent;
        });
        let rgb = film.to_rgb();
        for (c, want) in expected.iter().enumerate() {
            let v: Vec<f64> = rgb.iter().map(|p| f64::from(p[c])).collect();
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let se = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
            let z = (mean - want) / se;
            eprintln!("{engine:?} channel {c}: {mean:.5} against {want:.5} (z {z:.2})");
            assert!(
                z.abs() < 4.5,
                "{engine:?} channel {c}: {mean} against {want}, z {z:.2}"
            );
        }
    }
}
