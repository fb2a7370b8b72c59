//! A χ² goodness-of-fit test of a direction sampler against its density,
//! after Mitsuba 3's `chi2` module: the sphere of directions is binned in
//! `(cos θ, φ)` around a normal (equal solid angle per bin), the sampler's
//! histogram is compared with the expected counts (the density integrated
//! numerically over each bin), bins with an expected count below 5 are
//! pooled, and the p-value comes from the χ² distribution's upper tail (a
//! regularised incomplete gamma function, implemented here).

use glam::DVec3;

/// Gauss–Legendre nodes and weights on [-1, 1], 5 points.
const GL_X: [f64; 5] = [
    -0.906_179_845_938_664,
    -0.538_469_310_105_683,
    0.0,
    0.538_469_310_105_683,
    0.906_179_845_938_664,
];
const GL_W: [f64; 5] = [
    0.236_926_885_056_189,
    0.478_628_670_499_366,
    0.568_888_888_888_889,
    0.478_628_670_499_366,
    0.236_926_885_056_189,
];

/// An orthonormal frame `(t, b, n)` around unit `n`, independent of the
/// library's.
pub fn frame(n: DVec3) -> (DVec3, DVec3, DVec3) {
    let helper = if n.x.abs() < 0.6 { DVec3::X } else { DVec3::Y };
    let t = n.cross(helper).normalize();
    (t, n.cross(t), n)
}

/// The histogram domain: `cos θ` in `[cos_lo, 1]` (`cos_lo = 0`: the
/// hemisphere of the normal, `-1`: the sphere) in `nc` bins and `φ` in
/// `[0, 2π)` in `np` bins, integrated with `sub × sub` cells of 5 × 5
/// Gauss–Legendre nodes per bin.
#[derive(Clone, Copy, Debug)]
pub struct Domain {
    pub cos_lo: f64,
    pub nc: usize,
    pub np: usize,
    pub sub: usize,
}

impl Default for Domain {
    fn default() -> Self {
        Self {
            cos_lo: 0.0,
            nc: 20,
            np: 40,
            sub: 4,
        }
    }
}

/// The outcome of a test.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The p-value (0 when samples fell where the density is 0).
    pub p: f64,
    /// The statistic, its degrees of freedom, and the number of pooled
    /// bins.
    pub stat: f64,
    pub dof: usize,
    pub pooled: usize,
    /// Σ expected / N: the density's integral over the domain.
    pub mass: f64,
    /// Samples in bins whose expected count is 0.
    pub impossible: u64,
}

impl Domain {
    fn bin(&self, local: DVec3) -> Option<usize> {
        let z = local.z.clamp(-1.0, 1.0);
        let c = (z - self.cos_lo) / (1.0 - self.cos_lo);
        if c < 0.0 {
            return None;
        }
        let ic = ((c * self.nc as f64) as usize).min(self.nc - 1);
        let mut phi = local.y.atan2(local.x);
        if phi < 0.0 {
            phi += std::f64::consts::TAU;
        }
        let ip = ((phi / std::f64::consts::TAU * self.np as f64) as usize).min(self.np - 1);
        Some(ic * self.np + ip)
    }

    /// Runs the test: `sample` returns a sampled direction in the local
    /// frame (z along the normal), or `None` for an absorbed sample;
    /// `pdf` is the claimed density (per solid angle) of a local
    /// direction. `n` samples are drawn. Directions below `cos_lo` count as
    /// impossible, except those within 1e-5 of it (rounding of a direction
    /// on the horizon).
    pub fn test(
        &self,
        n: usize,
        mut sample: impl FnMut() -> Option<DVec3>,
        pdf: impl Fn(DVec3) -> f64,
    ) -> Outcome {
        let cells = self.nc * self.np;
        let mut observed = vec![0u64; cells];
        let mut impossible = 0u64;
        for _ in 0..n {
            if let Some(mut d) = sample() {
                if d.z < self.cos_lo && d.z > self.cos_lo - 1e-5 {
                    d.z = self.cos_lo;
                }
                match self.bin(d) {
                    Some(b) => observed[b] += 1,
                    None => impossible += 1,
                }
            }
        }
        let expected = self.expected(n, &pdf);
        let mass = expected.iter().sum::<f64>() / n as f64;
        let (stat, dof, pooled, zero_hits) = statistic(&observed, &expected);
        impossible += zero_hits;
        let p = if impossible > 0 {
            0.0
        } else {
            chi2_upper_tail(stat, dof as f64)
        };
        Outcome {
            p,
            stat,
            dof,
            pooled,
            mass,
            impossible,
        }
    }

    /// `n` times the density's integral over each bin: `∫∫ pdf dcosθ dφ`
    /// (the Jacobian of `(cos θ, φ)` to solid angle is 1).
    pub fn expected(&self, n: usize, pdf: &impl Fn(DVec3) -> f64) -> Vec<f64> {
        let dc = (1.0 - self.cos_lo) / self.nc as f64;
        let dp = std::f64::consts::TAU / self.np as f64;
        let (sc, sp) = (dc / self.sub as f64, dp / self.sub as f64);
        let mut out = vec![0.0; self.nc * self.np];
        for ic in 0..self.nc {
            for ip in 0..self.np {
                let mut sum = 0.0;
                for jc in 0..self.sub {
                    for jp in 0..self.sub {
                        let c0 = self.cos_lo + ic as f64 * dc + jc as f64 * sc;
                        let p0 = ip as f64 * dp + jp as f64 * sp;
                        for (xa, wa) in GL_X.iter().zip(GL_W) {
                            let c = c0 + 0.5 * sc * (xa + 1.0);
                            let s = (1.0 - c * c).max(0.0).sqrt();
                            for (xb, wb) in GL_X.iter().zip(GL_W) {
                                let p = p0 + 0.5 * sp * (xb + 1.0);
                                let d = DVec3::new(s * p.cos(), s * p.sin(), c);
                                sum += wa * wb * pdf(d);
                            }
                        }
                    }
                }
                out[ic * self.np + ip] = sum * 0.25 * sc * sp * n as f64;
            }
        }
        out
    }
}

/// Pearson's statistic over the bins, pooling (in increasing order of
/// expectation) bins with an expected count below 5 until each pool reaches
/// 5; a last pool below 5 joins the smallest proper cell. Returns the
/// statistic, the degrees of freedom (cells - 1), the number of bins that
/// were pooled, and the number of samples in bins of expectation 0.
pub fn statistic(observed: &[u64], expected: &[f64]) -> (f64, usize, usize, u64) {
    let mut order: Vec<usize> = (0..observed.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let mut cells: Vec<(f64, f64)> = Vec::new();
    let (mut po, mut pe, mut pooled, mut zero_hits) = (0.0, 0.0, 0usize, 0u64);
    for &i in &order {
        if expected[i] <= 0.0 {
            zero_hits += observed[i];
            continue;
        }
        if expected[i] < 5.0 || pe > 0.0 {
            po += observed[i] as f64;
            pe += expected[i];
            pooled += 1;
            if pe >= 5.0 {
                cells.push((po, pe));
                po = 0.0;
                pe = 0.0;
            }
        } else {
            cells.push((observed[i] as f64, expected[i]));
        }
    }
    if pe > 0.0 {
        match cells.iter_mut().min_by(|a, b| a.1.total_cmp(&b.1)) {
            Some(c) => {
                c.0 += po;
                c.1 += pe;
            }
            None => cells.push((po, pe)),
        }
    }
    let stat = cells.iter().map(|&(o, e)| (o - e) * (o - e) / e).sum();
    (stat, cells.len().saturating_sub(1), pooled, zero_hits)
}

/// `P(X ≥ x)` for `X ~ χ²(k)`: the regularised upper incomplete gamma
/// function `Q(k/2, x/2)`.
pub fn chi2_upper_tail(x: f64, k: f64) -> f64 {
    gamma_q(0.5 * k, 0.5 * x)
}

/// `ln Γ(x)` for `x > 0` (Lanczos, g = 7, n = 9; ~1e-15 relative).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x) Γ(1-x) = π / sin(πx).
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised upper incomplete gamma function `Q(a, x)`: the series
/// of `P` below `x < a + 1`, Lentz's continued fraction above (Numerical
/// Recipes' `gser`/`gcf`).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let ln_pre = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        let (mut ap, mut del) = (a, 1.0 / a);
        let mut sum = del;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * ln_pre.exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        ln_pre.exp() * h
    }
}

/// The per-test significance level that keeps the chance of any false
/// rejection among `tests` tests at `overall` (Šidák's correction).
pub fn sidak(overall: f64, tests: usize) -> f64 {
    1.0 - (1.0 - overall).powf(1.0 / tests as f64)
}
