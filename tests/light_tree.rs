//! The light tree (docs/lights.md, "Many emitters: the light tree"), on
//! the shipped `scenes/many-lights.toml` (300 small emissive quads of
//! varied power, colour and orientation above a floor): `nee` with the
//! tree converges to the image of `nee` picking by power; the probability
//! a sample is drawn with is the one the MIS lookup recomputes, bit for
//! bit; the tree's picks follow its probabilities (χ²); the tree makes the
//! image less noisy; both engines agree, and the image is a function of
//! the seed alone. Scenes under the counted rule keep their bits
//! (tests/determinism.rs and tests/bench.rs hold their hashes).

use glam::Vec3;
use wavetrace::film::Film;
use wavetrace::integrator::lights::Lights;
use wavetrace::integrator::sampler::PathRng;
use wavetrace::math::V3;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;
use wavetrace::scene::camera::Camera;
use wavetrace::scene::file::parse;
use wavetrace::scene::options::{Integrator, SamplerKind};

const MANY_LIGHTS: &str = include_str!("../scenes/many-lights.toml");

/// The shipped many-light scene, its emitters picked by the tree
/// (`Some(true)`), by power (`Some(false)`) or by the counted rule.
fn many_lights(tree: Option<bool>) -> Scene {
    let mut scene = parse(MANY_LIGHTS, "scenes/many-lights.toml").unwrap();
    scene.options.light_tree = tree;
    scene
}

fn render(scene: &Scene, f: impl FnOnce(&mut RenderSettings)) -> Film {
    let mut s = RenderSettings::for_scene(scene);
    (s.width, s.height, s.threads) = (16, 12, 2);
    f(&mut s);
    let (film, _, _) = Renderer::new(scene, &s).unwrap().render();
    assert_eq!(film.invalid_samples, 0);
    film
}

/// Seeds of each estimate.
const K: u64 = 16;

/// `K` seeds' images of `scene` by `nee` at `spp`: per pixel and channel,
/// the mean and the squared standard error of the mean.
fn estimate(scene: &Scene, spp: u32) -> Vec<(f64, f64)> {
    let images: Vec<Vec<f64>> = (0..K)
        .map(|k| {
            let film = render(scene, |s| {
                (s.integrator, s.spp, s.seed) = (Integrator::Nee, spp, 300 + k);
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

/// Mean z² and largest |z| of `a` against `b` (as tests/unbiased.rs).
fn z_scores(a: &[(f64, f64)], b: &[(f64, f64)]) -> (f64, f64) {
    let z: Vec<f64> = (a.iter().zip(b))
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
fn the_counted_rule_picks_the_tree_for_many_emitters_only() {
    let lights = Lights::new(&many_lights(None));
    assert_eq!(lights.len(), 300);
    assert!(lights.tree().is_some());
    assert!(Lights::new(&many_lights(Some(false))).tree().is_none());
    assert!(Lights::new(&Scene::cornell()).tree().is_none());
    let mut cornell = Scene::cornell();
    cornell.options.light_tree = Some(true);
    assert!(Lights::new(&cornell).tree().is_some());
}

/// (a) Unbiased: `nee` with the tree against `nee` picking by power,
/// per-pixel z-scores over 16 seeds each.
#[test]
fn the_tree_converges_to_the_image_of_picking_by_power() {
    let by_power = estimate(&many_lights(Some(false)), 64);
    let by_tree = estimate(&many_lights(Some(true)), 64);
    let (mean_z2, max_z) = z_scores(&by_tree, &by_power);
    eprintln!("tree vs power: mean z² {mean_z2:.3}, max |z| {max_z:.2}");
    assert!(
        mean_z2 < 1.6 && max_z < 7.0,
        "mean z² {mean_z2:.3}, max |z| {max_z:.2}"
    );
}

/// The tree's purpose: at equal samples its image of the lit floor is
/// less noisy than picking by power (the sum over pixels of the seeds'
/// relative variance), seen from a camera just above the floor, looking
/// down (no light in view: the noise is the light sampling's).
#[test]
fn the_tree_is_less_noisy_than_picking_by_power() {
    let floor = |tree| {
        let mut scene = many_lights(Some(tree));
        let (at, down, up) = (Vec3::new(0.5, 0.55, -0.5), Vec3::NEG_Y, Vec3::Z);
        scene.camera = Camera::new(at, down, up, 5.0, 16, 12).unwrap();
        scene
    };
    let variance = |e: &[(f64, f64)]| e.iter().map(|v| v.1 / (v.0 * v.0)).sum::<f64>();
    let by_power = variance(&estimate(&floor(false), 16));
    let by_tree = variance(&estimate(&floor(true), 16));
    eprintln!("variance, tree / power: {:.3}", by_tree / by_power);
    assert!(by_tree < 0.61 * by_power, "{by_tree} vs {by_power}");
}

/// Shading points on the floor and in the air among the lights.
fn points(n: usize, seed: u32) -> Vec<V3<f32>> {
    let mut rng = PathRng::new(u64::from(seed), seed, seed);
    (0..n)
        .map(|k| {
            let (x, z) = (rng.next_f32() * 12.0 - 6.0, rng.next_f32() * 12.0 - 6.0);
            let y = if k % 2 == 0 {
                0.0
            } else {
                rng.next_f32() * 4.0
            };
            V3::new(x, y, z)
        })
        .collect()
}

/// (b) The density of each light sample is the density the MIS lookup
/// of a BSDF-sampled ray that hits the same point recomputes, bit for
/// bit (by solid angle on a rectangle that looks large, else by area);
/// and the probabilities of all emitters sum to at most 1 — to 1 where
/// the walk can end in no node whose emitters all face away.
#[test]
fn a_samples_density_is_the_one_the_mis_lookup_recomputes() {
    let lights = Lights::new(&many_lights(Some(true)));
    let mut rng = PathRng::new(7, 7, 7);
    let mut checked = 0;
    for o in points(200, 3) {
        for _ in 0..50 {
            let s = lights.sample(o, [rng.next_f32(), rng.next_f32()]).unwrap();
            let Some(_) = lights.emitter_of(s.prim.to_bits()) else {
                continue; // no emitter faced `o`
            };
            let to = Vec3::from(s.point) - Vec3::from(o);
            let (t, cos) = (to.length(), -Vec3::from(s.normal).dot(to.normalize()));
            if cos <= 0.0 {
                continue;
            }
            let by_sample = if s.pdf_solid_angle > 0.0 {
                s.pdf_solid_angle
            } else {
                s.pdf_area * (t * t) / cos
            };
            let by_lookup = lights.pdf_solid_angle(s.prim.to_bits(), o, t, cos);
            assert_eq!(by_sample.to_bits(), by_lookup.to_bits(), "at {o:?}");
            checked += 1;
        }
        let sum: f64 = (0..lights.len())
            .map(|k| f64::from(lights.emitter_probability(k, o)))
            .sum();
        assert!(sum <= 1.0 + 1e-5 && sum > 0.5, "at {o:?}: {sum}");
    }
    assert!(checked > 5000, "{checked}");
    // Where every emitter faces the point (the quads that face down, the
    // others put out, seen from far below) the probabilities sum to 1.
    let mut down = many_lights(Some(true));
    for t in &mut down.triangles {
        if t.normal.y > -0.2 {
            t.material = 0;
        }
    }
    let lights = Lights::new(&down);
    assert!(lights.len() > 100, "{}", lights.len());
    for x in [-3.0, 0.0, 2.5] {
        let o = V3::new(x, -1000.0, 1.0);
        let sum: f64 = (0..lights.len())
            .map(|k| f64::from(lights.emitter_probability(k, o)))
            .sum();
        assert!((sum - 1.0).abs() < 1e-5, "at {o:?}: {sum}");
    }
}

/// (c) χ²: the emitters the tree picks from a point, against its
/// probabilities (emitters expected fewer than 5 times pooled, and the
/// chance that no emitter faces the point one more bin).
#[test]
fn the_trees_picks_follow_its_probabilities() {
    let lights = Lights::new(&many_lights(Some(true)));
    let n = 400_000;
    for (at, o) in points(4, 11).into_iter().enumerate() {
        let mut counts = vec![0u64; lights.len() + 1];
        let mut rng = PathRng::new(13, at as u32, 0);
        for _ in 0..n {
            let s = lights.sample(o, [rng.next_f32(), 0.5]).unwrap();
            let k = lights.emitter_of(s.prim.to_bits()).unwrap_or(lights.len());
            counts[k] += 1;
        }
        let mut pmf: Vec<f64> = (0..lights.len())
            .map(|k| f64::from(lights.emitter_probability(k, o)))
            .collect();
        pmf.push((1.0 - pmf.iter().sum::<f64>()).max(0.0));
        let (mut chi2, mut bins, mut pooled) = (0.0, 0, (0.0, 0u64));
        for (&p, &c) in pmf.iter().zip(&counts) {
            let expected = p * n as f64;
            if p == 0.0 {
                assert_eq!(c, 0, "picked an emitter of probability 0 from {o:?}");
            } else if expected < 5.0 {
                pooled = (pooled.0 + expected, pooled.1 + c);
            } else {
                chi2 += (c as f64 - expected).powi(2) / expected;
                bins += 1;
            }
        }
        if pooled.0 > 0.0 {
            chi2 += (pooled.1 as f64 - pooled.0).powi(2) / pooled.0;
            bins += 1;
        }
        // χ² with `bins - 1` degrees of freedom: mean dof, sd √(2 dof).
        let dof = (bins - 1) as f64;
        eprintln!("from {o:?}: χ² {chi2:.1} over {dof} dof");
        assert!(
            chi2 < dof + 6.0 * (2.0 * dof).sqrt(),
            "from {o:?}: χ² {chi2:.1}, {dof} dof"
        );
    }
}

/// (d) The wavefront engine against the reference tracer, with the tree,
/// every sampler.
#[test]
fn the_wavefront_engine_matches_the_reference_with_the_tree() {
    let scene = many_lights(None);
    for sampler in [SamplerKind::Independent, SamplerKind::Sobol] {
        let settings = |s: &mut RenderSettings| (s.sampler, s.spp) = (sampler, 8);
        let a = render(&scene, |s| {
            settings(s);
            s.engine = Engine::Reference;
        });
        let b = render(&scene, settings);
        assert!(a.to_rgb().iter().flatten().any(|&v| v > 0.0));
        for (i, (pa, pb)) in a.to_rgb().iter().zip(&b.to_rgb()).enumerate() {
            for c in 0..3 {
                let (x, y) = (pa[c], pb[c]);
                assert!(
                    (x - y).abs() <= 1e-5 * x.abs().max(y.abs()) + 1e-6,
                    "{sampler:?}: pixel {i} channel {c}: {x} vs {y}"
                );
            }
        }
    }
}

/// (e) The image is a function of the seed: threads, batch sizes and
/// kernel widths change no bit.
#[test]
fn images_with_the_tree_are_a_function_of_the_seed() {
    let scene = many_lights(None);
    let base = render(&scene, |s| s.spp = 8).sums;
    for (threads, batch) in [(1, 7), (3, 4096)] {
        let other = render(&scene, |s| {
            (s.spp, s.threads, s.batch_size) = (8, threads, batch)
        });
        assert_eq!(other.sums, base, "{threads} threads, batch {batch}");
    }
    for simd in wavetrace::accel::simd::SimdWidth::available() {
        let other = render(&scene, |s| (s.spp, s.simd) = (8, simd));
        assert_eq!(other.sums, base, "{simd:?}");
    }
}
