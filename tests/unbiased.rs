//! Unbiasedness: every integrator × sampler converges to the report
//! estimator's image.
//!
//! Each estimator renders the Cornell box (12×12 pixels, depth 3) with K
//! independent seeds; so does the report's estimator, at many more samples.
//! The seeds' images are independent estimates of each pixel, so their
//! spread gives each mean's standard error, and per pixel and channel
//!
//! ```text
//! z = (mean_a - mean_report) / sqrt(se_a² + se_report²)
//! ```
//!
//! is about standard normal (Student's t with K−1 degrees of freedom per
//! side) when both estimate the same image. The test asks for a mean z² near
//! 1 and no |z| far in the tail — and it is shown to fail for an estimator
//! that converges to a different image (one bounce too many: the bias of a
//! shadow ray counted one depth too deep), below.

use wavetrace::render::{RenderSettings, Renderer};
use wavetrace::scene::Scene;
use wavetrace::scene::options::{Integrator, SamplerKind};

const SIZE: u32 = 12;
const DEPTH: u32 = 3;
const K: u64 = 16;

/// Per pixel and channel, the mean over `K` seeds of `spp`-sample images
/// and the squared standard error of that mean.
fn estimate(
    integrator: Integrator,
    sampler: SamplerKind,
    rr_depth: Option<u32>,
    depth: u32,
    spp: u32,
) -> Vec<(f64, f64)> {
    let scene = Scene::cornell();
    let n = (SIZE * SIZE * 3) as usize;
    let mut images = vec![];
    for k in 0..K {
        let mut s = RenderSettings::for_scene(&scene);
        (s.width, s.height, s.spp, s.max_depth, s.seed) = (SIZE, SIZE, spp, depth, 1000 + k);
        (s.integrator, s.sampler, s.rr_depth) = (integrator, sampler, rr_depth);
        let (film, _, _) = Renderer::new(&scene, &s).unwrap().render();
        assert_eq!(film.invalid_samples, 0);
        let rgb: Vec<f64> = film.to_rgb().iter().flatten().map(|&v| v as f64).collect();
        assert_eq!(rgb.len(), n);
        images.push(rgb);
    }
    (0..n)
        .map(|i| {
            let mean = images.iter().map(|im| im[i]).sum::<f64>() / K as f64;
            let var = images.iter().map(|im| (im[i] - mean).powi(2)).sum::<f64>() / (K - 1) as f64;
            (mean, var / K as f64)
        })
        .collect()
}

/// Mean z² and largest |z| of `a` against `b`. A pixel whose two estimates
/// have no spread at all (it sees only the light) must agree exactly.
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

/// Unbiased: mean z² within what 432 t₁₅-distributed scores give (their
/// variance is 15/13 ≈ 1.15), and no score beyond 7.
fn agrees((mean_z2, max_z): (f64, f64)) -> bool {
    mean_z2 < 1.6 && max_z < 7.0
}

#[test]
fn every_integrator_and_sampler_converges_to_the_reports_image() {
    let report = estimate(
        Integrator::Report,
        SamplerKind::Independent,
        None,
        DEPTH,
        2048,
    );
    let mut combos = vec![];
    for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
        for sampler in [SamplerKind::Independent, SamplerKind::Sobol] {
            combos.push((integrator, sampler, None));
        }
    }
    combos.push((Integrator::Nee, SamplerKind::Sobol, Some(1)));
    combos.push((Integrator::Bsdf, SamplerKind::Sobol, Some(1)));
    for (integrator, sampler, rr) in combos {
        let z = z_scores(&estimate(integrator, sampler, rr, DEPTH, 256), &report);
        eprintln!(
            "{integrator:?} {sampler:?} rr {rr:?}: mean z² {:.3}, max |z| {:.2}",
            z.0, z.1
        );
        assert!(
            agrees(z),
            "{integrator:?} {sampler:?} rr {rr:?}: mean z² {:.3}, max |z| {:.2}",
            z.0,
            z.1
        );
    }
}

/// The test has the power to see a real bug: next-event estimation that
/// lights one vertex too many (the shadow ray counted a depth too deep —
/// here, the whole next bounce) converges to another image, and fails.
#[test]
fn a_biased_estimator_fails_the_test() {
    let report = estimate(
        Integrator::Report,
        SamplerKind::Independent,
        None,
        DEPTH,
        2048,
    );
    for sampler in [SamplerKind::Independent, SamplerKind::Sobol] {
        let z = z_scores(
            &estimate(Integrator::Nee, sampler, None, DEPTH + 1, 256),
            &report,
        );
        eprintln!(
            "one bounce too many, {sampler:?}: mean z² {:.3}, max |z| {:.2}",
            z.0, z.1
        );
        assert!(
            !agrees(z),
            "{sampler:?}: mean z² {:.3}, max |z| {:.2}",
            z.0,
            z.1
        );
    }
}
