//! Statistics of the report's hemisphere sampling and of the path streams.
//!
//! For a direction uniform in solid angle on the hemisphere around `n`:
//! `cos θ = d·n` is uniform on [0, 1] (mean 1/2, variance 1/12), and the
//! azimuth `φ` around `n` is uniform on [0, 2π) in *any* tangent frame (the
//! distribution is rotationally symmetric), so the tests measure φ in a frame
//! of their own, not the implementation's.
//!
//! Statistical bounds (all samples come from fixed seeds, so the outcome is
//! deterministic; the bounds say how unlikely a false failure would be for a
//! correct sampler with independent uniform inputs):
//! - mean cos θ within 5 standard errors of 1/2 (σ² = 1/12; two-sided
//!   p ≈ 6e-7);
//! - φ: Pearson chi-square over 32 equal bins, 31 degrees of freedom,
//!   critical value 83.64 (p = 1e-6);
//! - cos θ: Kolmogorov–Smirnov against U(0, 1), critical value
//!   2.6934 / √N (asymptotic, p = 1e-6); and chi-square over 32 bins as for φ.

use glam::Vec3;
use wavetrace::integrator::bsdf::diffuse::uniform_hemisphere;
use wavetrace::integrator::sampler::PathRng;
use wavetrace::math::V3;

const N: usize = 100_000;
const BINS: usize = 32;
/// χ²(31) upper 1e-6 quantile.
const CHI2_CRIT_31: f64 = 83.64;
/// Kolmogorov distribution upper 1e-6 quantile.
const KS_CRIT: f64 = 2.6934;

fn sample(n: Vec3, x1: f32, x2: f32) -> Vec3 {
    Vec3::from(uniform_hemisphere(V3::from(n), x1, x2))
}

/// An orthonormal tangent frame around `n`, independent of the one the
/// sampler uses.
fn my_frame(n: Vec3) -> (Vec3, Vec3) {
    let n = n.as_dvec3();
    let helper = if n.x.abs() < 0.6 {
        glam::DVec3::X
    } else {
        glam::DVec3::Z
    };
    let t = n.cross(helper).normalize();
    let b = n.cross(t);
    (t.as_vec3(), b.as_vec3())
}

fn chi_square(counts: &[u64], n: usize) -> f64 {
    let expected = n as f64 / counts.len() as f64;
    counts
        .iter()
        .map(|&c| (c as f64 - expected).powi(2) / expected)
        .sum()
}

/// Kolmogorov–Smirnov statistic `D` of `xs` against U(0, 1).
fn ks_uniform(xs: &mut [f64]) -> f64 {
    xs.sort_by(|a, b| a.total_cmp(b));
    let n = xs.len() as f64;
    xs.iter()
        .enumerate()
        .map(|(i, &x)| {
            let lo = x - i as f64 / n;
            let hi = (i + 1) as f64 / n - x;
            lo.max(hi)
        })
        .fold(0.0, f64::max)
}

/// The normals to test: every axis direction (the lab's floor normal
/// (0, -1, 0) among them), diagonals, ties between the components the
/// sampler compares, nearly-axis normals, and random ones.
fn normals() -> Vec<Vec3> {
    let mut ns = vec![
        Vec3::X,
        -Vec3::X,
        Vec3::Y,
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::Z,
        -Vec3::Z,
        Vec3::ONE.normalize(),
        Vec3::new(-1.0, 1.0, -1.0).normalize(),
        Vec3::new(1.0, 1.0, 0.0).normalize(), // |x| = |y|
        Vec3::new(0.0, 1.0, -1.0).normalize(),
        Vec3::new(1e-4, -1.0, 1e-4).normalize(),
        Vec3::new(-1.0, 1e-4, 0.0).normalize(),
        // The Cornell box's short block faces.
        Vec3::new(-0.292_825_8, 0.0, -0.956_165_8).normalize(),
        Vec3::new(0.957_826_3, 0.0, -0.287_347_9).normalize(),
    ];
    let mut rng = PathRng::new(12345, 0, 0);
    while ns.len() < 24 {
        let v = Vec3::new(
            rng.next_f32() * 2.0 - 1.0,
            rng.next_f32() * 2.0 - 1.0,
            rng.next_f32() * 2.0 - 1.0,
        );
        let len = v.length();
        if (0.1..=1.0).contains(&len) {
            ns.push(v / len);
        }
    }
    ns
}

struct Samples {
    cos: Vec<f64>,
    phi_bins: [u64; BINS],
}

/// `N` directions around `n`, checked one by one, with their statistics.
fn draw(n: Vec3, stream: u32) -> Samples {
    let (t, b) = my_frame(n);
    let mut rng = PathRng::new(99, stream, 0);
    let mut cos = Vec::with_capacity(N);
    let mut phi_bins = [0u64; BINS];
    for _ in 0..N {
        let (x1, x2) = (rng.next_f32(), rng.next_f32());
        let d = sample(n, x1, x2);
        assert!(d.is_finite(), "n = {n}, X = ({x1}, {x2}): d = {d}");
        assert!(
            (d.length() - 1.0).abs() < 1e-5,
            "n = {n}, X = ({x1}, {x2}): |d| = {}",
            d.length()
        );
        let c = d.dot(n);
        // Rounding in the tangent frame may put a grazing direction (X1
        // near 0) a few ulps below the plane; nothing more.
        assert!(c >= -1e-6, "n = {n}, X = ({x1}, {x2}): d·n = {c}");
        // The report's method: cos θ = X1.
        assert!(
            (c - x1).abs() < 2e-6,
            "n = {n}, X = ({x1}, {x2}): cos θ = {c}, expected X1"
        );
        cos.push(c as f64);
        let phi = (d.dot(b) as f64).atan2(d.dot(t) as f64); // (-π, π]
        let u = (phi / std::f64::consts::TAU).rem_euclid(1.0);
        phi_bins[((u * BINS as f64) as usize).min(BINS - 1)] += 1;
    }
    Samples { cos, phi_bins }
}

#[test]
fn directions_are_unit_and_in_the_hemisphere() {
    // Including the extreme inputs 0 and the largest next_f32 value.
    let top = 1.0 - 1.0 / 16_777_216.0;
    for n in normals() {
        for x1 in [0.0, 1e-7, 0.5, top] {
            for x2 in [0.0, 0.25, 0.5, 0.75, top] {
                let d = sample(n, x1, x2);
                assert!(
                    (d.length() - 1.0).abs() < 1e-5,
                    "n = {n}: |d| = {}",
                    d.length()
                );
                assert!(d.dot(n) >= -1e-6, "n = {n}: d·n = {}", d.dot(n));
            }
        }
    }
}

#[test]
fn axis_normals_stay_exactly_in_the_hemisphere() {
    // For axis-aligned normals (every wall of the Cornell box) the frame is
    // exact, so d·n is never negative, even at X1 = 0.
    let mut rng = PathRng::new(5, 5, 5);
    for n in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
        for i in 0..20_000 {
            let x1 = if i % 2 == 0 { 0.0 } else { rng.next_f32() };
            let d = sample(n, x1, rng.next_f32());
            assert!(d.dot(n) >= 0.0, "n = {n}: d·n = {}", d.dot(n));
        }
    }
}

#[test]
fn mean_cos_theta_is_one_half() {
    let se = (1.0 / 12.0 / N as f64).sqrt();
    for (i, n) in normals().into_iter().enumerate() {
        let s = draw(n, i as u32);
        let mean = s.cos.iter().sum::<f64>() / N as f64;
        assert!(
            (mean - 0.5).abs() < 5.0 * se,
            "n = {n}: mean cos θ = {mean}, expected 0.5 ± {}",
            5.0 * se
        );
        // The second moment too: E[cos² θ] = 1/3 (σ² of cos² θ = 4/45).
        let m2 = s.cos.iter().map(|c| c * c).sum::<f64>() / N as f64;
        let se2 = (4.0 / 45.0 / N as f64).sqrt();
        assert!(
            (m2 - 1.0 / 3.0).abs() < 5.0 * se2,
            "n = {n}: mean cos² θ = {m2}, expected 1/3 ± {}",
            5.0 * se2
        );
    }
}

#[test]
fn phi_is_uniform_around_the_normal() {
    for (i, n) in normals().into_iter().enumerate() {
        let s = draw(n, 100 + i as u32);
        let chi2 = chi_square(&s.phi_bins, N);
        assert!(
            chi2 < CHI2_CRIT_31,
            "n = {n}: φ chi-square {chi2:.2} ≥ {CHI2_CRIT_31} (31 dof, p = 1e-6); bins {:?}",
            s.phi_bins
        );
    }
}

#[test]
fn cos_theta_is_uniform() {
    for (i, n) in normals().into_iter().enumerate() {
        let mut s = draw(n, 200 + i as u32);
        let mut bins = [0u64; BINS];
        for &c in &s.cos {
            bins[((c * BINS as f64) as usize).min(BINS - 1)] += 1;
        }
        let chi2 = chi_square(&bins, N);
        assert!(
            chi2 < CHI2_CRIT_31,
            "n = {n}: cos θ chi-square {chi2:.2} ≥ {CHI2_CRIT_31}; bins {bins:?}"
        );
        let d = ks_uniform(&mut s.cos);
        let crit = KS_CRIT / (N as f64).sqrt();
        assert!(d < crit, "n = {n}: cos θ KS D = {d:.5} ≥ {crit:.5}");
    }
}

#[test]
fn mean_direction_is_half_the_normal() {
    // A check of the whole direction, not of cos θ and φ separately: for a
    // uniform hemisphere, E[d] = n/2 (E[cos θ] = 1/2, and the tangential
    // components average to 0). In a tangent frame (t, b):
    // Var(d·t) = Var(d·b) = E[sin² θ]/2 = 1/3, Var(d·n) = 1/12.
    for (i, n) in normals().into_iter().enumerate() {
        let (t, b) = my_frame(n);
        let mut rng = PathRng::new(31, 300 + i as u32, 0);
        let mut sum = glam::DVec3::ZERO;
        for _ in 0..N {
            let d = sample(n, rng.next_f32(), rng.next_f32());
            sum += glam::DVec3::new(d.dot(t) as f64, d.dot(b) as f64, d.dot(n) as f64);
        }
        let mean = sum / N as f64;
        let se_t = (1.0 / 3.0 / N as f64).sqrt();
        let se_n = (1.0 / 12.0 / N as f64).sqrt();
        assert!(
            mean.x.abs() < 5.0 * se_t && mean.y.abs() < 5.0 * se_t,
            "n = {n}: mean tangential components {mean}, bound {}",
            5.0 * se_t
        );
        assert!(
            (mean.z - 0.5).abs() < 5.0 * se_n,
            "n = {n}: mean d·n {}",
            mean.z
        );
    }
}

#[test]
fn next_f32_is_in_the_unit_interval_and_uniform() {
    let mut bins = [0u64; BINS];
    let mut sum = 0.0f64;
    for p in 0..1_000u32 {
        let mut rng = PathRng::new(7, p, p / 3);
        for _ in 0..200 {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x), "next_f32 gave {x}");
            // 24 random bits: an exact multiple of 2^-24.
            assert_eq!((x * 16_777_216.0).fract(), 0.0, "{x} is not k / 2^24");
            sum += x as f64;
            bins[(x * BINS as f32) as usize] += 1;
        }
    }
    let n = 200_000;
    let se = (1.0 / 12.0 / n as f64).sqrt();
    let mean = sum / n as f64;
    assert!((mean - 0.5).abs() < 5.0 * se, "mean {mean}");
    let chi2 = chi_square(&bins, n);
    assert!(chi2 < CHI2_CRIT_31, "chi-square {chi2:.2}; bins {bins:?}");
}

#[test]
fn streams_of_neighbouring_keys_are_uncorrelated() {
    // The first number of the stream of each (pixel, sample) feeds the
    // camera jitter; neighbouring keys must not give related numbers.
    let n = 100_000u32;
    let xs: Vec<f64> = (0..n)
        .map(|i| PathRng::new(1, i / 4, i % 4).next_f32() as f64)
        .collect();
    let mean = xs.iter().sum::<f64>() / n as f64;
    let cov = xs
        .windows(2)
        .map(|w| (w[0] - mean) * (w[1] - mean))
        .sum::<f64>()
        / (n - 1) as f64;
    // Lag-1 correlation of independent U(0,1): sd 1/√n.
    let corr = cov * 12.0;
    assert!(
        corr.abs() < 5.0 / (n as f64).sqrt(),
        "lag-1 correlation {corr}"
    );
}
