//! The material models' math: sampling against densities (χ² goodness of
//! fit, with deliberately broken variants that the test must reject),
//! eval/pdf consistency, energy (white furnaces, GGX albedo against an
//! independent quadrature), reciprocity, Fresnel closed forms, the laws of
//! reflection and refraction, the α → 0 limit of `metal`, and SIMD ≡ scalar
//! bit for bit for every routine.
//!
//! Every random number comes from a fixed seed, so each outcome (and each
//! printed p-value) is deterministic; the significance levels say how
//! unlikely a false failure of a correct sampler would be.

mod chi2;

use chi2::{Domain, Outcome, frame, sidak};
use glam::DVec3;
use std::f64::consts::PI;
use wavetrace::integrator::bsdf::{BsdfSample, diffuse, glass, metal, mirror, reflect};
use wavetrace::integrator::sampler::PathRng;
use wavetrace::math::{Real, V3};
use wide::f32x8;

/// The chance, over all χ² tests of correct samplers in this file, of any
/// false rejection.
const OVERALL_SIGNIFICANCE: f64 = 0.01;
/// How many χ² tests of correct samplers this file runs: 2 uniform + 2
/// cosine diffuse, 16 metal (4 α × 4 incidences), 4 glass.
const CHI2_TESTS: usize = 24;
/// Samples per χ² test of a continuous model.
const CHI2_SAMPLES: usize = 1_000_000;

/// The per-test level, Šidák-corrected for [`CHI2_TESTS`] tests.
fn level() -> f64 {
    sidak(OVERALL_SIGNIFICANCE, CHI2_TESTS)
}

// ---------------------------------------------------------------------------
// Helpers

struct Rng(PathRng);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(PathRng::new(seed, 0, 0))
    }
    fn f(&mut self) -> f32 {
        self.0.next_f32()
    }
    fn d(&mut self) -> f64 {
        // 48 random bits.
        (self.f() as f64 + self.f() as f64 / 16_777_216.0).min(1.0 - 1e-16)
    }
    fn u2(&mut self) -> [f32; 2] {
        [self.f(), self.f()]
    }
    /// A unit vector uniform on the sphere.
    fn unit(&mut self) -> DVec3 {
        let z = 2.0 * self.d() - 1.0;
        let p = 2.0 * PI * self.d();
        let s = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(s * p.cos(), s * p.sin(), z)
    }
}

fn v32(v: DVec3) -> V3<f32> {
    V3::new(v.x as f32, v.y as f32, v.z as f32)
}

fn v64(v: V3<f32>) -> DVec3 {
    DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// A surface for a test: a random unit normal `n` (f32), the test's own
/// frame around it, and `wo` at the given cosine with `n`, at a random
/// azimuth.
struct Setup {
    n: V3<f32>,
    wo: V3<f32>,
    t: DVec3,
    b: DVec3,
    nn: DVec3,
}

impl Setup {
    fn new(rng: &mut Rng, cos_o: f64) -> Self {
        let n = v32(rng.unit());
        let nn = v64(n).normalize();
        let (t, b, _) = frame(nn);
        let p = 2.0 * PI * rng.d();
        let s = (1.0 - cos_o * cos_o).max(0.0).sqrt();
        let wo = if cos_o == 1.0 {
            n
        } else {
            v32(t * (s * p.cos()) + b * (s * p.sin()) + nn * cos_o)
        };
        Self { n, wo, t, b, nn }
    }
    fn local(&self, w: V3<f32>) -> DVec3 {
        let w = v64(w);
        DVec3::new(w.dot(self.t), w.dot(self.b), w.dot(self.nn))
    }
    fn world(&self, l: DVec3) -> V3<f32> {
        v32(self.t * l.x + self.b * l.y + self.nn * l.z)
    }
}

fn check(name: &str, o: &Outcome, expect_pass: bool) {
    eprintln!(
        "chi2 {name}: p = {:.4e}, stat = {:.1}, dof = {}, pooled = {}, mass = {:.5}, impossible = {}",
        o.p, o.stat, o.dof, o.pooled, o.mass, o.impossible
    );
    if expect_pass {
        assert!(
            o.p >= level(),
            "{name}: p = {} below the level {}",
            o.p,
            level()
        );
    } else {
        assert!(
            o.p < level(),
            "{name}: a broken variant passed: p = {} (level {})",
            o.p,
            level()
        );
    }
}

fn white() -> V3<f32> {
    V3::new(1.0, 1.0, 1.0)
}

// ---------------------------------------------------------------------------
// The χ² harness itself

#[test]
fn chi2_distribution_matches_tables() {
    // Upper 5% and 1e-3 points of χ²(k), from standard tables.
    for (x, k, p) in [
        (3.841_459, 1.0, 0.05),
        (18.307_04, 10.0, 0.05),
        (124.342_1, 100.0, 0.05),
        (10.827_57, 1.0, 0.001),
        (76.154, 50.0, 0.01),
        (1_106.97, 1_000.0, 0.01),
        (10.0, 2.0, (-5.0f64).exp()),
    ] {
        let q = chi2::chi2_upper_tail(x, k);
        assert!((q / p - 1.0).abs() < 0.05, "Q({x}, {k}) = {q}, want {p}");
    }
    assert!((chi2::ln_gamma(10.0) - 362_880f64.ln()).abs() < 1e-12);
    assert!((chi2::ln_gamma(0.5) - PI.sqrt().ln()).abs() < 1e-12);
}

// ---------------------------------------------------------------------------
// diffuse

fn diffuse_chi2(
    rng: &mut Rng,
    sample: impl Fn(V3<f32>, [f32; 2]) -> V3<f32>,
    pdf: impl Fn(V3<f32>, V3<f32>) -> f32,
) -> Outcome {
    // The diffuse routines take the facing normal only (wo is on its side).
    let s = Setup::new(rng, 1.0);
    Domain::default().test(
        CHI2_SAMPLES,
        || Some(s.local(sample(s.n, rng.u2()))),
        |l| pdf(s.n, s.world(l)) as f64,
    )
}

#[test]
fn chi2_diffuse_uniform_and_cosine() {
    let mut rng = Rng::new(1);
    for i in 0..2 {
        let o = diffuse_chi2(
            &mut rng,
            |n, u| diffuse::sample_uniform(n, white(), u).wi,
            diffuse::pdf_uniform,
        );
        check(&format!("diffuse uniform #{i}"), &o, true);
        let o = diffuse_chi2(
            &mut rng,
            |n, u| diffuse::sample_cosine(n, white(), u).wi,
            diffuse::pdf_cosine,
        );
        check(&format!("diffuse cosine #{i}"), &o, true);
    }
}

/// Broken: cosine-weighted sampling (Malley's, polar) with the disk radius
/// `X1` instead of `sqrt(X1)` (the classic bug), against the correct
/// density.
fn broken_cosine<R: Real>(n: V3<R>, u: [R; 2]) -> V3<R> {
    let r = u[0];
    let cos = (-r).mul_add(r, R::splat(1.0)).sqrt();
    let (s, c) = wavetrace::math::sin_cos_2pi(u[1]);
    diffuse::to_world(n, r * c, cos, r * s)
}

#[test]
fn chi2_rejects_broken_diffuse() {
    let mut rng = Rng::new(2);
    let o = diffuse_chi2(&mut rng, broken_cosine, diffuse::pdf_cosine);
    check("broken: cosine sampling with r = X1", &o, false);
    // A density off by a factor cos θ (normalised): uniform sampling judged
    // against the cosine density.
    let o = diffuse_chi2(
        &mut rng,
        |n, u| diffuse::sample_uniform(n, white(), u).wi,
        diffuse::pdf_cosine,
    );
    check("broken: uniform sampling, pdf off by cos θ", &o, false);
}

#[test]
fn diffuse_eval_pdf_consistency_and_furnace() {
    let mut rng = Rng::new(3);
    let pi = std::f32::consts::PI;
    let rho = V3::new(0.8f32, 0.5, 0.25);
    let f = V3::new(rho.x / pi, rho.y / pi, rho.z / pi);
    let (mut sum_u, mut sum_c, mut sum2_u) = (0.0f64, 0.0f64, 0.0f64);
    let n_samples = 200_000;
    for _ in 0..n_samples {
        let n = v32(rng.unit());
        for cosine in [false, true] {
            let smp = if cosine {
                diffuse::sample_cosine(n, f, rng.u2())
            } else {
                diffuse::sample_uniform(n, f, rng.u2())
            };
            let (fc, cos) = diffuse::eval(n, f, smp.wi);
            let pdf = if cosine {
                diffuse::pdf_cosine(n, smp.wi)
            } else {
                diffuse::pdf_uniform(n, smp.wi)
            };
            let cos_i = v64(smp.wi).dot(v64(n));
            if cos_i > 1e-6 {
                assert_eq!(smp.f.x.to_bits(), f.x.to_bits());
                // f · cos, with cos the dot product (the sample's cos may
                // differ from it by rounding).
                assert!((fc.x as f64 - f.x as f64 * cos_i).abs() < 2e-7 * f.x as f64);
                assert!((cos as f64 - cos_i).abs() < 1e-6);
                assert!((smp.cos as f64 - cos_i).abs() < 1e-6);
                if cosine {
                    assert!((pdf - smp.pdf).abs() < 1e-7, "{pdf} vs {}", smp.pdf);
                } else {
                    assert_eq!(pdf, smp.pdf);
                }
                // weight = eval · cos / pdf where both are defined.
                let w = smp.weigh(white()).y as f64;
                assert!((w / (fc.y as f64 / pdf as f64) - 1.0).abs() < 1e-3 || cos_i < 1e-3);
            }
            let w = smp.weigh(white());
            // Weight in the red channel with ρ = 0.8: normalise to ρ = 1.
            let w = w.x as f64 / 0.8;
            if cosine {
                assert!((w - 1.0).abs() < 1e-6, "cosine weight {w}");
                sum_c += w;
            } else {
                sum_u += w;
                sum2_u += w * w;
            }
            // Nothing on the other side.
            let below = -smp.wi;
            assert_eq!(diffuse::eval(n, f, below).0.x, 0.0);
            assert_eq!(diffuse::pdf_cosine(n, below), 0.0);
            assert_eq!(diffuse::pdf_uniform(n, below), 0.0);
        }
    }
    let n = n_samples as f64;
    let mean_u = sum_u / n;
    let sigma = ((sum2_u / n - mean_u * mean_u) / n).sqrt();
    eprintln!(
        "diffuse furnace: uniform {mean_u} ± {sigma}, cosine {}",
        sum_c / n
    );
    assert!((mean_u - 1.0).abs() < 5.0 * sigma);
    assert!((sum_c / n - 1.0).abs() < 1e-6);
}

#[test]
fn diffuse_reciprocal() {
    // eval gives f · cos θi for the normal facing wo: f(wo, wi) = eval / cos θi
    // must equal f(wi, wo) = eval(n, f, wo) / cos θo, with n facing wi.
    let mut rng = Rng::new(4);
    let f = V3::new(0.7f32, 0.2, 1.0);
    for _ in 0..100_000 {
        let n = v32(rng.unit());
        let (a, b) = (v32(rng.unit()), v32(rng.unit()));
        let na = if n.dot(a) > 0.0 { n } else { -n };
        let nb = if n.dot(b) > 0.0 { n } else { -n };
        let (fab, cb) = diffuse::eval(na, f, b);
        let (fba, ca) = diffuse::eval(nb, f, a);
        let same_side = v64(n).dot(v64(a)) * v64(n).dot(v64(b)) > 0.0;
        assert_eq!(fab.y > 0.0, same_side && cb > 0.0);
        if fab.y > 0.0 && fba.y > 0.0 {
            let (x, y) = (fab.y as f64 / cb as f64, fba.y as f64 / ca as f64);
            assert!((x / y - 1.0).abs() < 1e-6, "{x} vs {y}");
        } else {
            assert_eq!(fab.y == 0.0, fba.y == 0.0);
        }
    }
}

// ---------------------------------------------------------------------------
// mirror

#[test]
fn mirror_reflects_exactly_with_exact_weight() {
    let mut rng = Rng::new(5);
    let tint = V3::new(0.9f32, 0.6, 0.3);
    for _ in 0..100_000 {
        let s = {
            let c = rng.d();
            Setup::new(&mut rng, c)
        };
        for n in [s.n, -s.n] {
            let smp = mirror::sample(n, s.wo, tint);
            let wi = v64(smp.wi);
            let (wo, nn) = (v64(s.wo), v64(n));
            // Law of reflection: same angle, coplanar, on the same side.
            assert!((wi.dot(nn) - wo.dot(nn)).abs() < 1e-6);
            assert!((wi + wo).cross(nn).length() < 1e-6);
            assert!((wi.length() - 1.0).abs() < 1e-6);
            // Weight exactly the tint.
            let beta = V3::new(0.5f32, 0.25, 1.0);
            let w = smp.weigh(beta);
            assert_eq!(w.x, 0.5 * 0.9);
            assert_eq!(w.y, 0.25 * 0.6);
            assert_eq!(w.z, 0.3);
            assert!(smp.delta);
        }
        // Either orientation of the normal, the same bits.
        let (a, b) = (
            mirror::sample(s.n, s.wo, tint).wi,
            mirror::sample(-s.n, s.wo, tint).wi,
        );
        assert_eq!([a.x, a.y, a.z], [b.x, b.y, b.z]);
    }
}

// ---------------------------------------------------------------------------
// metal

/// The textbook GGX pieces in f64, independent of the library's forms.
mod ggx64 {
    use std::f64::consts::PI;
    pub fn d(alpha: f64, cos_h: f64) -> f64 {
        if cos_h <= 0.0 {
            return 0.0;
        }
        let c2 = cos_h * cos_h;
        let t2 = (1.0 - c2) / c2;
        let a2 = alpha * alpha;
        a2 / (PI * c2 * c2 * (a2 + t2) * (a2 + t2))
    }
    pub fn lambda(alpha: f64, c: f64) -> f64 {
        let t2 = (1.0 - c * c).max(0.0) / (c * c);
        0.5 * (-1.0 + (1.0 + alpha * alpha * t2).sqrt())
    }
    pub fn g1(alpha: f64, c: f64) -> f64 {
        1.0 / (1.0 + lambda(alpha, c))
    }
    pub fn g2(alpha: f64, co: f64, ci: f64) -> f64 {
        1.0 / (1.0 + lambda(alpha, co) + lambda(alpha, ci))
    }
    /// `D G2 / (4 co ci)` (Fresnel 1).
    pub fn f(alpha: f64, n: glam::DVec3, wo: glam::DVec3, wi: glam::DVec3) -> f64 {
        let (co, ci) = (n.dot(wo), n.dot(wi));
        if co <= 0.0 || ci <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize();
        d(alpha, n.dot(h)) * g2(alpha, co, ci) / (4.0 * co * ci)
    }
    /// `∫ g(h) dh` over the hemisphere of `n = z` with `θh = atan(α tan ψ)`
    /// (which puts the nodes where `D` is) by the midpoint rule, φ over
    /// `[0, 2π)`.
    pub fn integrate_h(alpha: f64, nt: usize, np: usize, g: impl Fn(glam::DVec3) -> f64) -> f64 {
        let mut sum = 0.0;
        let dpsi = 0.5 * PI / nt as f64;
        let dphi = 2.0 * PI / np as f64;
        for i in 0..nt {
            let psi = (i as f64 + 0.5) * dpsi;
            let tp = psi.tan();
            let theta = (alpha * tp).atan();
            // dθ/dψ = α sec²ψ / (1 + α² tan²ψ)
            let jac = alpha * (1.0 + tp * tp) / (1.0 + alpha * alpha * tp * tp);
            let (st, ct) = theta.sin_cos();
            for j in 0..np {
                let phi = (j as f64 + 0.5) * dphi;
                let h = glam::DVec3::new(st * phi.cos(), st * phi.sin(), ct);
                sum += g(h) * st * jac;
            }
        }
        sum * dpsi * dphi
    }
}

const METAL_ALPHAS: [f32; 4] = [0.1, 0.3, 0.7, 1.5];
const METAL_COS: [f64; 4] = [1.0, 0.7, 0.3, 0.05];

fn metal_chi2(
    rng: &mut Rng,
    alpha: f32,
    cos_o: f64,
    sample: impl Fn(V3<f32>, V3<f32>, f32, [f32; 2]) -> BsdfSample<f32>,
) -> Outcome {
    let s = Setup::new(rng, cos_o);
    Domain::default().test(
        CHI2_SAMPLES,
        || {
            let smp = sample(s.n, s.wo, alpha, rng.u2());
            (smp.f.x > 0.0).then(|| s.local(smp.wi))
        },
        |l| metal::pdf(s.n, s.wo, s.world(l), alpha) as f64,
    )
}

#[test]
fn chi2_metal_vndf() {
    let mut rng = Rng::new(6);
    for alpha in METAL_ALPHAS {
        for cos_o in METAL_COS {
            let o = metal_chi2(&mut rng, alpha, cos_o, |n, wo, a, u| {
                metal::sample(n, wo, a, white(), u)
            });
            check(&format!("metal α = {alpha}, cos θo = {cos_o}"), &o, true);
        }
    }
}

/// Broken: microfacet normals drawn from `D(h) cos θh` (the NDF, Walter et
/// al. 2007) instead of the visible normals, reported with the VNDF
/// density.
fn broken_ndf_sample(n: V3<f32>, wo: V3<f32>, alpha: f32, u: [f32; 2]) -> BsdfSample<f32> {
    use wavetrace::integrator::bsdf::diffuse::to_world;
    let t2 = alpha * alpha * u[0] / (1.0 - u[0]);
    let cos = 1.0 / (1.0 + t2).sqrt();
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (sp, cp) = wavetrace::math::sin_cos_2pi(u[1]);
    let m = to_world(n, sin * cp, cos, sin * sp);
    let wi = reflect(wo, m);
    let valid = n.dot(wi) > 0.0 && wo.dot(m) > 0.0;
    BsdfSample {
        wi,
        f: if valid {
            metal::eval(n, wo, wi, alpha, white())
        } else {
            V3::new(0.0, 0.0, 0.0)
        },
        cos: n.dot(wi).max(0.0),
        pdf: metal::pdf(n, wo, wi, alpha),
        delta: false,
    }
}

#[test]
fn chi2_rejects_broken_metal() {
    let mut rng = Rng::new(7);
    let o = metal_chi2(&mut rng, 0.5, 0.3, broken_ndf_sample);
    check(
        "broken: GGX sampling the NDF, reporting the VNDF pdf",
        &o,
        false,
    );
    // At normal incidence the VNDF is D(h) cos θh: the NDF sampler is right
    // there, and the test must not reject it.
    let o = metal_chi2(&mut rng, 0.5, 1.0, broken_ndf_sample);
    eprintln!(
        "(NDF sampling at normal incidence equals the VNDF: p = {:.3e})",
        o.p
    );
    assert!(o.p > 1e-6);
    // Broken: the density without its G1(wo) factor.
    let s = Setup::new(&mut rng, 0.3);
    let alpha = 0.5f32;
    let o = Domain::default().test(
        CHI2_SAMPLES,
        || {
            let smp = metal::sample(s.n, s.wo, alpha, white(), rng.u2());
            (smp.f.x > 0.0).then(|| s.local(smp.wi))
        },
        |l| {
            let p = metal::pdf(s.n, s.wo, s.world(l), alpha) as f64;
            p / ggx64::g1(alpha as f64, 0.3)
        },
    );
    check("broken: VNDF pdf without G1(wo)", &o, false);
}

#[test]
fn metal_eval_pdf_consistency_and_reference() {
    let mut rng = Rng::new(8);
    let tint = V3::new(1.0f32, 0.8, 0.5);
    let mut worst = [0.0f64; 4];
    for i in 0..200_000 {
        let alpha = [0.02f32, 0.1, 0.3, 0.7, 1.0, 2.0][i % 6];
        let s = {
            let c = rng.d().max(1e-3);
            Setup::new(&mut rng, c)
        };
        let smp = metal::sample(s.n, s.wo, alpha, tint, rng.u2());
        if smp.f.x == 0.0 {
            assert_eq!((smp.cos, smp.pdf), (0.0, 1.0));
            assert!(v64(smp.wi).dot(v64(s.n)) < 1e-6);
            continue;
        }
        let f = metal::eval(s.n, s.wo, smp.wi, alpha, tint);
        let pdf = metal::pdf(s.n, s.wo, smp.wi, alpha);
        let rel = |a: f32, b: f32| (a as f64 / b as f64 - 1.0).abs();
        worst[0] = worst[0].max(rel(f.y, smp.f.y));
        worst[1] = worst[1].max(rel(pdf, smp.pdf));
        let w = smp.weigh(white());
        let w_eval = f.x as f64 * smp.cos as f64 / pdf as f64;
        worst[2] = worst[2].max((w.x as f64 / w_eval - 1.0).abs());
        // The f64 textbook formula.
        let reference = ggx64::f(alpha as f64, v64(s.n), v64(s.wo), v64(smp.wi)) * 0.8;
        if smp.cos > 1e-3 {
            worst[3] = worst[3].max((f.y as f64 / reference - 1.0).abs());
        }
        assert!(w.x <= 1.0 + 1e-5, "weight {} > 1", w.x);
    }
    eprintln!(
        "metal worst relative differences: f {:.2e}, pdf {:.2e}, weight {:.2e}, vs f64 {:.2e}",
        worst[0], worst[1], worst[2], worst[3]
    );
    assert!(worst.iter().all(|&w| w < 2e-3), "{worst:?}");
}

#[test]
fn metal_reciprocal_bitwise() {
    let mut rng = Rng::new(9);
    let tint = V3::new(0.9f32, 0.7, 0.4);
    let mut nonzero = 0;
    for i in 0..200_000 {
        let alpha = [1e-9f32, 0.01, 0.2, 0.8, 1.7][i % 5];
        let n = v32(rng.unit());
        let (a, b) = (v32(rng.unit()), v32(rng.unit()));
        let (f, g) = (
            metal::eval(n, a, b, alpha, tint),
            metal::eval(n, b, a, alpha, tint),
        );
        assert_eq!(
            [f.x, f.y, f.z].map(f32::to_bits),
            [g.x, g.y, g.z].map(f32::to_bits)
        );
        assert!(f.x.is_finite() && f.x >= 0.0);
        nonzero += (f.x > 0.0) as u32;
    }
    assert!(nonzero > 40_000);
}

#[test]
fn metal_ndf_normalised_and_weak_white_furnace() {
    // ∫ D(h) cos θh dh = 1 and, for every wo, ∫ G1(wo) max(0, wo·h) D(h) / cos θo dh = 1
    // (the VNDF is a density): the library's D, the f64 G1.
    for alpha in [0.05f64, 0.2, 0.6, 1.0, 2.0] {
        let z = V3::new(0.0f32, 0.0, 1.0);
        let d = |h: DVec3| metal::ndf(z, v32(h), alpha as f32) as f64;
        let norm = ggx64::integrate_h(alpha, 2000, 64, |h| d(h) * h.z);
        for cos_o in [1.0f64, 0.5, 0.1] {
            let wo = DVec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            let g1 = ggx64::g1(alpha, cos_o);
            let vis =
                ggx64::integrate_h(alpha, 2000, 256, |h| g1 * wo.dot(h).max(0.0) * d(h) / cos_o);
            eprintln!("α = {alpha}: ∫D cos = {norm:.6}, cos θo = {cos_o}: ∫VNDF = {vis:.6}");
            assert!((vis - 1.0).abs() < 2e-4, "∫VNDF = {vis}");
        }
        assert!((norm - 1.0).abs() < 2e-4, "∫D cos = {norm}");
    }
}

#[test]
fn metal_albedo_below_one_and_matches_quadrature() {
    // Directional albedo E(θo, α) = ∫ f cos θi dωi (Fresnel 1): a Monte Carlo
    // estimate from the sampler's weights against an independent quadrature
    // in h: E = ∫ D(h) G2 (wo·h) / cos θo dh over h with wi above the
    // horizon.
    let mut rng = Rng::new(10);
    for alpha in [0.1f32, 0.3, 0.6, 1.0, 1.5] {
        let mut line = format!("metal albedo α = {alpha}:");
        for cos_o in [1.0f64, 0.7, 0.3, 0.1] {
            let a = alpha as f64;
            let wo = DVec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            let quad = ggx64::integrate_h(a, 1500, 256, |h| {
                let woh = wo.dot(h);
                let wi = 2.0 * woh * h - wo;
                if woh <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                ggx64::d(a, h.z) * ggx64::g2(a, cos_o, wi.z) * woh / cos_o
            });
            let s = Setup::new(&mut rng, cos_o);
            let n_samples = 200_000;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..n_samples {
                let w = metal::sample(s.n, s.wo, alpha, white(), rng.u2())
                    .weigh(white())
                    .x as f64;
                assert!(w <= 1.0 + 1e-5);
                sum += w;
                sum2 += w * w;
            }
            let mean = sum / n_samples as f64;
            let sigma = ((sum2 / n_samples as f64 - mean * mean) / n_samples as f64).sqrt();
            line += &format!(" cos θo {cos_o}: MC {mean:.4} ± {sigma:.1e}, quad {quad:.4};");
            assert!(quad <= 1.0 + 1e-4 && mean <= 1.0);
            assert!((mean - quad).abs() < 5.0 * sigma + 5e-4, "{line}");
        }
        eprintln!("{line}");
    }
}

#[test]
fn metal_approaches_mirror() {
    let mut rng = Rng::new(11);
    let tint = V3::new(0.9f32, 0.8, 0.7);
    for alpha in [1e-4f32, 1e-6, metal::ALPHA_MIN, 1e-12, 0.0, f32::NAN] {
        let a = metal::clamp_alpha(alpha) as f64;
        let mut angles = Vec::new();
        let mut min_weight = f64::INFINITY;
        for _ in 0..50_000 {
            let s = {
                let c = rng.d().max(0.02);
                Setup::new(&mut rng, c)
            };
            let smp = metal::sample(s.n, s.wo, alpha, tint, rng.u2());
            let mirror_dir = v64(mirror::sample(s.n, s.wo, tint).wi);
            let angle = v64(smp.wi)
                .normalize()
                .dot(mirror_dir.normalize())
                .clamp(-1.0, 1.0)
                .acos();
            angles.push(angle);
            let w = smp.weigh(white());
            assert!(w.x.is_finite() && smp.f.x.is_finite() && smp.pdf.is_finite());
            if smp.f.x > 0.0 {
                min_weight = min_weight.min(w.x as f64 / 0.9);
                let f = metal::eval(s.n, s.wo, smp.wi, alpha, tint);
                assert!(f.x.is_finite() && metal::pdf(s.n, s.wo, smp.wi, alpha).is_finite());
            }
        }
        angles.sort_by(f64::total_cmp);
        let median = angles[angles.len() / 2];
        let q99 = angles[angles.len() * 99 / 100];
        eprintln!(
            "metal α = {alpha:e} (used {a:e}): angle to the mirror: median {median:.2e}, 99% {q99:.2e}; min weight / tint {min_weight:.6}"
        );
        // GGX's tails: P(θh > x) ≈ (α/x)², so 99% of the reflected
        // directions lie within 2·10α of the mirror direction.
        assert!(median < 3.0 * a + 1e-6, "median {median}");
        assert!(q99 < 25.0 * a + 1e-6, "99% {q99}");
        assert!(min_weight > 0.999, "min weight {min_weight}");
    }
    // The exact mirror pair at the smallest α: finite.
    let n = V3::new(0.0f32, 0.0, 1.0);
    let wo = V3::new(0.6f32, 0.0, 0.8);
    let wi = mirror::sample(n, wo, tint).wi;
    let f = metal::eval(n, wo, wi, 0.0, tint);
    let p = metal::pdf(n, wo, wi, 0.0);
    assert!(
        f.x.is_finite() && f.x > 0.0 && p.is_finite() && p > 0.0,
        "{f:?} {p}"
    );
}

// ---------------------------------------------------------------------------
// glass

/// The exact unpolarised Fresnel reflectance in f64 from the angles (the
/// sine and tangent forms), independent of the library's cosine form.
fn fresnel64(cos_i: f64, eta: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t = (1.0 - cos_i * cos_i).sqrt() / eta;
    if sin_t >= 1.0 {
        return 1.0;
    }
    let (ti, tt) = (cos_i.acos(), sin_t.asin());
    if ti < 1e-6 {
        return ((eta - 1.0) / (eta + 1.0)).powi(2);
    }
    let rs = (ti - tt).sin() / (ti + tt).sin();
    let rp = (ti - tt).tan() / (ti + tt).tan();
    0.5 * (rs * rs + rp * rp)
}

#[test]
fn glass_fresnel_closed_forms() {
    for eta in [1.5f32, 1.33, 2.4, 1.0, 0.7, 1.0 / 1.5] {
        // Normal incidence: ((η - 1)/(η + 1))².
        let (f, ct) = glass::fresnel_dielectric(1.0f32, eta);
        let e = eta as f64;
        let want = ((e - 1.0) / (e + 1.0)).powi(2);
        assert!(
            (f as f64 - want).abs() < 1e-7,
            "η {eta}: F(0) = {f}, want {want}"
        );
        assert!(
            (ct - 1.0).abs() <= 1.2e-7,
            "cos θt = {ct} at normal incidence"
        );
        // Against the angle forms at many angles.
        for i in 0..=1000 {
            let c = i as f32 / 1000.0;
            let (f, ct) = glass::fresnel_dielectric(c, eta);
            let want = fresnel64(c as f64, e);
            // Near the critical angle F is steep: allow what a rounding of
            // cos²θi (which the f32 form adds to η² - 1) can move it by.
            let (c64, dc) = (c as f64, 1e-7 / (c as f64).max(1e-3) + 2e-7);
            let steep = (fresnel64(c64 + dc, e) - fresnel64((c64 - dc).max(0.0), e)).abs();
            assert!(
                (f as f64 - want).abs() < 2e-6 + steep,
                "η {eta}, cos {c}: {f} vs {want}"
            );
            assert!((0.0..=1.0).contains(&f) && (0.0..=1.0).contains(&ct));
            if f < 1.0 {
                // Snell: η² sin²θt = sin²θi (in squares: cos θt is within
                // an ulp, so sin²θt is within ~1e-7 absolute).
                let si2 = 1.0 - (c as f64).powi(2);
                let st2 = 1.0 - (ct as f64).powi(2);
                assert!(
                    (e * e * st2 - si2).abs() < 3e-7 * e * e,
                    "Snell at cos {c}, η {eta}"
                );
                // Reciprocity of transmission: 1 - F(θi, η) = 1 - F(θt, 1/η).
                let (fb, cb) = glass::fresnel_dielectric(ct, 1.0 / eta);
                // Near grazing, cos θi comes back from 1 - sin²θ and loses
                // digits: the bound grows as η²/cos θi there.
                assert!(
                    (fb - f).abs() < 2e-6 + (eta * eta) * 5e-7 / c,
                    "cos {c}, η {eta}: F(θt, 1/η) = {fb}, F(θi, η) = {f}"
                );
                assert!(
                    (cb - c).abs() < 2e-3 * (1.0 - c).max(1e-3),
                    "cos back {cb} vs {c}"
                );
            }
        }
    }
    // Total internal reflection beyond the critical angle asin(1/ior),
    // leaving glass of ior 1.5 (η = 1/1.5).
    let ior = 1.5f64;
    let crit = (1.0 / ior).asin();
    for k in 1..200 {
        let theta = crit + (PI / 2.0 - crit) * k as f64 / 200.0;
        let (f, ct) = glass::fresnel_dielectric(theta.cos() as f32, (1.0 / ior) as f32);
        assert_eq!((f, ct), (1.0, 0.0), "θ = {theta} beyond the critical angle");
        let theta = crit * k as f64 / 200.0;
        let (f, _) = glass::fresnel_dielectric(theta.cos() as f32, (1.0 / ior) as f32);
        assert!(f < 1.0, "θ = {theta} before the critical angle");
    }
    // F rises to 1 continuously at the cut-off, and glancing entry reflects all.
    let (f, _) = glass::fresnel_dielectric((crit - 1e-4).cos() as f32, (1.0 / ior) as f32);
    assert!(f > 0.9, "just below the critical angle F = {f}");
    assert_eq!(glass::fresnel_dielectric(0.0f32, 1.5).0, 1.0);
}

#[test]
fn glass_directions_and_weights() {
    let mut rng = Rng::new(12);
    let tint = V3::new(0.9f32, 0.8, 0.6);
    let (mut reflected, mut transmitted) = (0, 0);
    for i in 0..200_000 {
        let ior = [1.5f32, 1.33, 2.4, 0.8][i % 4];
        let n = v32(rng.unit());
        let wo = v32(rng.unit());
        let smp = glass::sample(n, wo, ior, tint, rng.f());
        assert!(smp.delta && smp.cos == 1.0 && smp.pdf == 1.0);
        let (nn, wo64, wi) = (v64(n), v64(wo), v64(smp.wi));
        let co = nn.dot(wo64);
        let eta = if co > 0.0 {
            ior as f64
        } else {
            1.0 / ior as f64
        };
        assert!((wi.length() - 1.0).abs() < 1e-6);
        // Coplanar with the normal and wo.
        assert!(nn.cross(wo64).dot(wi).abs() < 1e-6);
        let (si, st) = (nn.cross(wo64).length(), nn.cross(wi).length());
        if co * nn.dot(wi) > 0.0 {
            reflected += 1;
            // Law of reflection, and the tangential parts agree.
            assert!((nn.dot(wi) - co).abs() < 1e-6);
            assert!((wi + wo64).cross(nn).length() < 1e-6);
            assert_eq!([smp.f.x, smp.f.y, smp.f.z], [1.0; 3]);
        } else {
            transmitted += 1;
            // Snell's law; the tangential parts point opposite ways.
            assert!(
                (eta * st - si).abs() < 2e-6,
                "Snell: η {eta}: {} vs {si}",
                eta * st
            );
            let (ti, tt) = (wo64 - nn * co, wi - nn * nn.dot(wi));
            assert!(ti.dot(tt) <= 1e-9);
            // The radiance scaling 1/η².
            let want = 0.8 / (eta * eta);
            assert!(
                (smp.f.y as f64 / want - 1.0).abs() < 1e-6,
                "{} vs {want}",
                smp.f.y
            );
            // Reversibility: refracting wi back gives wo, and the two
            // scalings multiply to 1.
            // (Ill-conditioned near grazing: the bound grows as 1/cos.)
            let back = glass::sample(n, smp.wi, ior, tint, 0.999_999_9);
            let ci = nn.dot(wi).abs();
            if v64(back.wi).dot(nn) * co > 0.0 {
                let tol = 2e-6 / co.abs().min(ci);
                assert!(
                    v64(back.wi).distance(wo64) < tol,
                    "reversed refraction: {} (tolerance {tol})",
                    v64(back.wi).distance(wo64)
                );
                assert!((back.f.y as f64 * smp.f.y as f64 / 0.64 - 1.0).abs() < 1e-5);
            } else {
                // Reflected back: only for a grazing wo, by rounding.
                assert!(co.abs() < 1e-3, "reversed refraction reflected at cos {co}");
            }
        }
    }
    assert!(reflected > 10_000 && transmitted > 100_000);
}

/// The glass χ² test of the reflect/transmit choice: at 64 incidences (32
/// cosines, entering and leaving), 20 000 samples each; the statistic
/// `Σ (R - M F)² / (M F (1 - F))` over incidences with `0 < F < 1` is
/// χ² with that many degrees of freedom (`F` from [`fresnel64`]); under
/// total internal reflection every sample must reflect.
fn glass_chi2(
    rng: &mut Rng,
    ior: f32,
    sample: impl Fn(V3<f32>, V3<f32>, f32) -> V3<f32>,
) -> (f64, f64, usize) {
    let m = 20_000;
    let (mut stat, mut dof, mut tir_failures) = (0.0, 0usize, 0u64);
    for side in [1.0, -1.0] {
        for k in 0..32 {
            let cos_o = (k as f64 + 0.5) / 32.0;
            let s = Setup::new(rng, cos_o);
            let n = if side > 0.0 { s.n } else { -s.n };
            let co = v64(s.wo).dot(v64(n));
            let eta = if co > 0.0 {
                ior as f64
            } else {
                1.0 / ior as f64
            };
            let f = fresnel64(co.abs(), eta);
            let mut r = 0u64;
            for _ in 0..m {
                let wi = sample(n, s.wo, rng.f());
                r += (v64(wi).dot(v64(n)) * co > 0.0) as u64;
            }
            if f >= 1.0 {
                tir_failures += m as u64 - r;
            } else {
                let e = m as f64 * f;
                stat += (r as f64 - e).powi(2) / (e * (1.0 - f));
                dof += 1;
            }
        }
    }
    let p = if tir_failures > 0 {
        0.0
    } else {
        chi2::chi2_upper_tail(stat, dof as f64)
    };
    (p, stat, dof)
}

#[test]
fn chi2_glass_fresnel_choice() {
    let mut rng = Rng::new(13);
    for ior in [1.5f32, 1.33, 2.4, 0.8] {
        let (p, stat, dof) = glass_chi2(&mut rng, ior, |n, wo, u| {
            glass::sample(n, wo, ior, white(), u).wi
        });
        let o = Outcome {
            p,
            stat,
            dof,
            pooled: 0,
            mass: 1.0,
            impossible: 0,
        };
        check(&format!("glass ior {ior}"), &o, true);
    }
}

#[test]
fn chi2_rejects_schlick_glass() {
    // Broken: Schlick's approximation R0 + (1 - R0)(1 - cos)⁵ (with the
    // cosine on the thinner side) in place of the exact Fresnel reflectance.
    let mut rng = Rng::new(14);
    let ior = 1.5f32;
    let (p, stat, dof) = glass_chi2(&mut rng, ior, |n, wo, u| {
        let c = n.dot(wo);
        let eta = if c > 0.0 { ior } else { 1.0 / ior };
        let nf = if c > 0.0 { n } else { -n };
        let (_, cos_t) = glass::fresnel_dielectric(c.abs(), eta);
        let r0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
        let tir = (1.0 - c * c) / (eta * eta) >= 1.0;
        let cos = if eta > 1.0 { c.abs() } else { cos_t };
        let f = if tir {
            1.0
        } else {
            r0 + (1.0 - r0) * (1.0 - cos).powi(5)
        };
        if u < f {
            reflect(wo, nf)
        } else {
            glass::refract(wo, nf, c.abs(), 1.0 / eta, cos_t)
        }
    });
    let o = Outcome {
        p,
        stat,
        dof,
        pooled: 0,
        mass: 1.0,
        impossible: 0,
    };
    check("broken: glass with Schlick's Fresnel", &o, false);
}

#[test]
fn glass_furnace() {
    let mut rng = Rng::new(15);
    // One interface: with the radiance scaling undone (importance
    // transport), every sample carries exactly the energy 1 when both
    // lobes count; with it, the mean is F + (1 - F)/η².
    for ior in [1.5f32, 2.4] {
        let n = V3::new(0.0f32, 0.0, 1.0);
        let cos_o = 0.6f64;
        let wo = v32(DVec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o));
        let (mut sum, m) = (0.0f64, 200_000);
        for _ in 0..m {
            let smp = glass::sample(n, wo, ior, white(), rng.f());
            let w = smp.weigh(white()).x as f64;
            let transmitted = smp.wi.z < 0.0;
            let unscaled = if transmitted {
                w * (ior as f64).powi(2)
            } else {
                w
            };
            assert!((unscaled - 1.0).abs() < 1e-6);
            sum += w;
        }
        let f = fresnel64(cos_o, ior as f64);
        let want = f + (1.0 - f) / (ior as f64).powi(2);
        let sigma = (f * (1.0 - f) / m as f64).sqrt() * (1.0 - 1.0 / (ior as f64).powi(2));
        assert!(
            (sum / m as f64 - want).abs() < 5.0 * sigma,
            "{} vs {want}",
            sum / m as f64
        );
    }
    // A slab (z in [0, 1]) in a white furnace: a camera path that comes in
    // from outside leaves again (no absorption) with weight 1: entering
    // scales by 1/η², leaving by η².
    for ior in [1.5f32, 1.33, 2.4] {
        let mut escaped = 0u32;
        for _ in 0..100_000 {
            let mut d = v32(-rng.unit().abs()); // downwards onto the top face
            let mut beta = white();
            let mut inside = false;
            for _bounce in 0..1_000 {
                // The face the path meets: the top (normal +z) going up or
                // down from outside above, the bottom (normal -z) going down
                // from inside.
                let n = if inside == (d.z < 0.0) {
                    V3::new(0.0, 0.0, -1.0)
                } else {
                    V3::new(0.0, 0.0, 1.0)
                };
                let smp = glass::sample(n, -d, ior, white(), rng.f());
                beta = smp.weigh(beta);
                let crossed = smp.wi.dot(n) * (-d).dot(n) < 0.0;
                inside ^= crossed;
                d = smp.wi;
                if !inside {
                    break;
                }
            }
            assert!(!inside, "a path stayed in the slab");
            escaped += 1;
            assert!((beta.y - 1.0).abs() < 1e-5, "path weight {}", beta.y);
        }
        assert_eq!(escaped, 100_000);
    }
}

// ---------------------------------------------------------------------------
// SIMD ≡ scalar, bit for bit

fn pack(v: [V3<f32>; 8]) -> V3<f32x8> {
    V3::new(
        f32x8::from(v.map(|v| v.x)),
        f32x8::from(v.map(|v| v.y)),
        f32x8::from(v.map(|v| v.z)),
    )
}

fn lane(x: f32x8, l: usize) -> f32 {
    x.to_array()[l]
}

fn lane_v(v: V3<f32x8>, l: usize) -> V3<f32> {
    V3::new(lane(v.x, l), lane(v.y, l), lane(v.z, l))
}

fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits()
}

fn same_v(a: V3<f32>, b: V3<f32>) -> bool {
    same(a.x, b.x) && same(a.y, b.y) && same(a.z, b.z)
}

fn same_sample(s8: &BsdfSample<f32x8>, l: usize, s: &BsdfSample<f32>) -> bool {
    same_v(lane_v(s8.wi, l), s.wi)
        && same_v(lane_v(s8.f, l), s.f)
        && same(lane(s8.cos, l), s.cos)
        && same(lane(s8.pdf, l), s.pdf)
        && (lane(s8.delta, l).to_bits() != 0) == s.delta
}

/// Eight lanes of inputs: normals, `wo`, `wi`, tints, two uniform numbers
/// (with the extremes 0 and the largest below 1 mixed in), and `wo` near
/// grazing, equal to the normal, or on the other side in some lanes.
struct Lanes {
    n: [V3<f32>; 8],
    wo: [V3<f32>; 8],
    wi: [V3<f32>; 8],
    tint: [V3<f32>; 8],
    u: [[f32; 2]; 8],
}

impl Lanes {
    fn new(rng: &mut Rng, k: usize) -> Self {
        let n: [V3<f32>; 8] = std::array::from_fn(|_| v32(rng.unit()));
        let wo: [V3<f32>; 8] = std::array::from_fn(|l| match (k + l) % 11 {
            0 => n[l],
            1 => {
                // Grazing: at cos θ = 1e-4 with n.
                let nn = v64(n[l]).normalize();
                let (t, _, _) = frame(nn);
                v32(t * (1.0f64 - 1e-8).sqrt() + nn * 1e-4)
            }
            _ => {
                let w = v32(rng.unit());
                // Mostly on the side of n.
                if !(k + l).is_multiple_of(5) && v64(w).dot(v64(n[l])) < 0.0 {
                    -w
                } else {
                    w
                }
            }
        });
        let wi = std::array::from_fn(|_| v32(rng.unit()));
        let tint = std::array::from_fn(|_| V3::new(rng.f(), rng.f(), rng.f()));
        let u = std::array::from_fn(|l| match (k * 3 + l) % 13 {
            0 => [0.0, 0.0],
            1 => [0.999_999_94, 0.999_999_94],
            _ => rng.u2(),
        });
        Self { n, wo, wi, tint, u }
    }
    fn u8(&self) -> [f32x8; 2] {
        [
            f32x8::from(self.u.map(|u| u[0])),
            f32x8::from(self.u.map(|u| u[1])),
        ]
    }
}

#[test]
fn simd_equals_scalar_diffuse_and_mirror() {
    let mut rng = Rng::new(16);
    for k in 0..20_000 {
        let x = Lanes::new(&mut rng, k);
        let (n8, wo8, wi8, t8) = (pack(x.n), pack(x.wo), pack(x.wi), pack(x.tint));
        let c8 = diffuse::sample_cosine(n8, t8, x.u8());
        let u8_ = diffuse::sample_uniform(n8, t8, x.u8());
        let (e8, ec8) = diffuse::eval(n8, t8, wi8);
        let p8 = diffuse::pdf_cosine(n8, wi8);
        let q8 = diffuse::pdf_uniform(n8, wi8);
        let m8 = mirror::sample(n8, wo8, t8);
        for l in 0..8 {
            assert!(same_sample(
                &c8,
                l,
                &diffuse::sample_cosine(x.n[l], x.tint[l], x.u[l])
            ));
            assert!(same_sample(
                &u8_,
                l,
                &diffuse::sample_uniform(x.n[l], x.tint[l], x.u[l])
            ));
            let (e, ec) = diffuse::eval(x.n[l], x.tint[l], x.wi[l]);
            assert!(same_v(lane_v(e8, l), e) && same(lane(ec8, l), ec));
            assert!(same(lane(p8, l), diffuse::pdf_cosine(x.n[l], x.wi[l])));
            assert!(same(lane(q8, l), diffuse::pdf_uniform(x.n[l], x.wi[l])));
            assert!(same_sample(
                &m8,
                l,
                &mirror::sample(x.n[l], x.wo[l], x.tint[l])
            ));
        }
    }
}

#[test]
fn simd_equals_scalar_glass() {
    let mut rng = Rng::new(17);
    let iors = [1.5f32, 1.0, 0.7, 2.4, 1.33, 1.000_001, 3.0, 1.1];
    for k in 0..20_000 {
        let x = Lanes::new(&mut rng, k);
        let ior: [f32; 8] = std::array::from_fn(|l| iors[(k + l) % 8]);
        let (n8, wo8, t8) = (pack(x.n), pack(x.wo), pack(x.tint));
        let s8 = glass::sample(n8, wo8, f32x8::from(ior), t8, x.u8()[0]);
        let cos: [f32; 8] = std::array::from_fn(|l| x.u[l][1]);
        let (f8, c8) = glass::fresnel_dielectric(f32x8::from(cos), f32x8::from(ior));
        for l in 0..8 {
            assert!(same_sample(
                &s8,
                l,
                &glass::sample(x.n[l], x.wo[l], ior[l], x.tint[l], x.u[l][0])
            ));
            let (f, c) = glass::fresnel_dielectric(cos[l], ior[l]);
            assert!(same(lane(f8, l), f) && same(lane(c8, l), c));
        }
    }
}

#[test]
fn simd_equals_scalar_metal() {
    let mut rng = Rng::new(18);
    let alphas = [0.0f32, 1e-12, f32::NAN, 1e-4, 0.05, 0.3, 1.0, 2.5];
    for k in 0..20_000 {
        let x = Lanes::new(&mut rng, k);
        let alpha: [f32; 8] = std::array::from_fn(|l| {
            if (k + l) % 3 == 0 {
                rng.f()
            } else {
                alphas[(k + l) % 8]
            }
        });
        let a8 = f32x8::from(alpha);
        let (n8, wo8, wi8, t8) = (pack(x.n), pack(x.wo), pack(x.wi), pack(x.tint));
        let s8 = metal::sample(n8, wo8, a8, t8, x.u8());
        let e8 = metal::eval(n8, wo8, wi8, a8, t8);
        let p8 = metal::pdf(n8, wo8, wi8, a8);
        let h8 = wo8 + wi8;
        let d8 = metal::ndf(n8, h8, a8);
        let co8 = n8.dot(wo8).abs();
        let ci8 = n8.dot(wi8).abs();
        let g8 = metal::g2(co8, ci8, a8);
        for (l, &a) in alpha.iter().enumerate() {
            let (n, wo, wi) = (x.n[l], x.wo[l], x.wi[l]);
            assert!(same_sample(
                &s8,
                l,
                &metal::sample(n, wo, a, x.tint[l], x.u[l])
            ));
            assert!(same_v(lane_v(e8, l), metal::eval(n, wo, wi, a, x.tint[l])));
            assert!(same(lane(p8, l), metal::pdf(n, wo, wi, a)));
            assert!(same(lane(d8, l), metal::ndf(n, wo + wi, a)));
            assert!(same(
                lane(g8, l),
                metal::g2(n.dot(wo).abs(), n.dot(wi).abs(), a)
            ));
        }
    }
}
