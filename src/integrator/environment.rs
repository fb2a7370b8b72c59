//! The environment light as the integrators see it: the radiance a
//! direction looks up, and directions drawn in proportion to it.
//!
//! Lookup follows [`crate::scene::environment`] (Blender's
//! equirectangular mapping, +Y up, bilinear, `u` wrapped, `v` clamped,
//! the content turned right-handed about +Y).
//!
//! Sampling: a piecewise-constant 2D distribution over the `(u, v)` unit
//! square on a grid of cells (the image's texels, subdivided to at least
//! [`MIN_ROWS`] rows), each cell weighted by the largest luminance the
//! bilinear lookup can return inside it times `sin θ` at its centre (the
//! solid angle of a row of cells is proportional to it). A row is drawn
//! from the marginal distribution, then a cell of the row, then a point
//! uniform in the cell. With `θ = π v` and `φ = 2π (u − ½)`, the density
//! per unit solid angle of a direction is `p(u, v) / (2π² sin θ)`.
//!
//! A direction's `(u, v)` is one generic function ([`EnvLight::uv_of`],
//! over [`Real`]: one `f32` or 8 or 16 lanes), with this module's own
//! [`atan2`] (a polynomial, at most 3.0·10⁻⁷ rad from the true angle: no
//! call into the system's maths library, whose `atan2f` and `acosf` cost
//! ~230 instructions per escaping ray, and whose last bits are the
//! library's, not this program's).
//! The reference tracer looks up one direction at a time, the wavefront
//! engine eight ([`EnvLight::radiance_and_pdf_lanes`]); each lane does the
//! scalar lookup's operations, so the two compute the same bits.

use crate::accel::simd::Lanes;
use crate::math::{Real, V3};
use crate::scene::environment::Environment;
use std::f32::consts::{FRAC_PI_2, PI};

/// The sampling grid has at least this many rows (a small image's texels
/// are subdivided): `sin θ` varies across a row of cells by little.
pub const MIN_ROWS: usize = 32;

/// An environment ready to be looked up and sampled.
#[derive(Clone, Debug)]
pub struct EnvLight {
    width: usize,
    height: usize,
    /// Radiance × strength, row-major, row 0 at the top.
    texels: Vec<[f32; 3]>,
    /// `cos R`, `sin R` of the rotation.
    cos_r: f32,
    sin_r: f32,
    /// Whether camera rays see it.
    pub visible: bool,
    /// The sampling grid's columns and rows.
    cols: usize,
    rows: usize,
    /// Each cell's density over the unit square (row-major).
    density: Vec<f32>,
    /// Running sums of the rows' weights, ending at 1.
    marginal: Vec<f32>,
    /// Per row, running sums of its cells' weights, ending at 1.
    conditional: Vec<f32>,
    /// The mean over the sphere of the radiance's RGB mean, by solid
    /// angle: what its power (against other emitters) is made of.
    pub mean_radiance: f64,
}

/// A direction drawn from the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvSample {
    /// Unit direction, world space.
    pub dir: V3<f32>,
    /// The radiance arriving from it.
    pub radiance: V3<f32>,
    /// Its density per unit solid angle (positive).
    pub pdf: f32,
}

/// `atan(a) / a = P(a²)` on `a ∈ [0, 1]`, lowest power first: fitted to
/// the relative error (Lawson's iteration; 1.5·10⁻⁸ in exact arithmetic).
const ATAN: [f32; 9] = [
    1.0,
    -0.33333072,
    0.1999262,
    -0.14203642,
    0.10640927,
    -0.07504278,
    0.04269131,
    -0.016068494,
    0.0028498548,
];

/// The angle of `(x, y)` from +X towards +Y, in `[−π, π]`, lane by lane:
/// `atan2(y, x)`, for finite arguments at most 3.0·10⁻⁷ rad from the
/// true angle (measured 2.75·10⁻⁷, glibc's `atan2f` 2.47·10⁻⁷;
/// `tests::atan2_is_within_its_bound` sweeps the circle densely, the axes
/// and the seam included). The ratio
/// of the smaller to the larger of `|x|`, `|y|` goes through `ATAN`'s
/// polynomial, then the octant is restored: `(0, 0)` gives 0, `y = ±0`
/// with `x < 0` gives `+π`. The environment's one angle function: the
/// `(u, v)` of both engines' lookups and of the sampling density's.
#[inline(always)]
pub fn atan2<R: Real>(y: R, x: R) -> R {
    let zero = R::splat(0.0);
    let (ax, ay) = (x.abs(), y.abs());
    let (big, small) = (ax.max(ay), ax.min(ay));
    let a = R::select(big.eq(zero), zero, small / big);
    let t = a * a;
    let mut p = R::splat(ATAN[8]);
    for &c in ATAN[..8].iter().rev() {
        p = p.mul_add(t, R::splat(c));
    }
    let mut r = a * p;
    r = R::select(ax.lt(ay), R::splat(FRAC_PI_2) - r, r);
    r = R::select(x.lt(zero), R::splat(PI) - r, r);
    R::select(y.lt(zero), -r, r)
}

/// `⌊x⌋` lane by lane, exactly `f32::floor` (NaN stays NaN): the nearest
/// integer, less one where it is above `x`.
#[inline(always)]
fn floor<R: Real>(x: R) -> R {
    let r = x.round_ties_even();
    R::select(x.lt(r), r - R::splat(1.0), r)
}

/// Luminance (Rec. 709) of a linear RGB triple.
fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The index of the first running sum above `u` (`cdf` ends at 1), and
/// `u` stretched back to `[0, 1)` over its share.
fn pick(cdf: &[f32], u: f32) -> (usize, f32) {
    let k = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
    let lo = if k == 0 { 0.0 } else { cdf[k - 1] };
    let t = (u - lo) / (cdf[k] - lo);
    (k, t.clamp(0.0, 1.0 - f32::EPSILON / 2.0))
}

impl EnvLight {
    /// Turn it to `rotation_deg` (what [`EnvLight::new`] of the same
    /// environment at that rotation gives, bit for bit: the sampling
    /// tables are of the unturned image; a direction is turned when it is
    /// looked up or drawn).
    pub fn turn(&mut self, rotation_deg: f32) {
        (self.sin_r, self.cos_r) = rotation_deg.to_radians().sin_cos();
    }

    /// The light of `env`.
    pub fn new(env: &Environment) -> Self {
        let (width, height) = (env.width as usize, env.height as usize);
        let texels: Vec<[f32; 3]> = env
            .texels
            .iter()
            .map(|t| t.map(|c| c * env.strength))
            .collect();
        let (sin_r, cos_r) = env.rotation_deg.to_radians().sin_cos();
        let k = MIN_ROWS.div_ceil(height).max(1);
        let (cols, rows) = (width * k, height * k);
        // Each cell: the largest luminance among the texels the bilinear
        // lookup reads inside it, times sin θ at its centre.
        // The texels' luminances, and each column's texel columns (wrapped),
        // found once rather than per cell: the same maxima, taken in the
        // same order.
        let lum: Vec<f32> = texels.iter().map(|&t| luminance(t)).collect();
        let touched = |c: usize| {
            let lo = ((c as f64 / k as f64) - 0.5).floor() as i64;
            let hi = (((c + 1) as f64 / k as f64) - 0.5).floor() as i64 + 1;
            (lo, hi)
        };
        let col_texels: Vec<Vec<usize>> = (0..cols)
            .map(|c| {
                let (lo, hi) = touched(c);
                (lo..=hi)
                    .map(|i| i.rem_euclid(width as i64) as usize)
                    .collect()
            })
            .collect();
        let mut weight = vec![0.0f64; cols * rows];
        let mut mean = 0.0f64;
        for r in 0..rows {
            let theta = (r as f64 + 0.5) / rows as f64 * std::f64::consts::PI;
            let sin = theta.sin();
            // Texel rows touched: the cell's v-range in texel units, less ½.
            let (lo, hi) = touched(r);
            let row_texels: Vec<&[f32]> = (lo..=hi)
                .map(|j| {
                    let j = j.clamp(0, height as i64 - 1) as usize;
                    &lum[j * width..(j + 1) * width]
                })
                .collect();
            for (c, is) in col_texels.iter().enumerate() {
                let mut most = 0.0f32;
                for row in &row_texels {
                    for &i in is {
                        most = most.max(row[i]);
                    }
                }
                weight[r * cols + c] = f64::from(most) * sin;
            }
        }
        for (j, row) in texels.chunks(width).enumerate() {
            let theta0 = j as f64 / height as f64 * std::f64::consts::PI;
            let theta1 = (j + 1) as f64 / height as f64 * std::f64::consts::PI;
            let band = theta0.cos() - theta1.cos(); // solid angle / (2π) of the row
            let sum: f64 = row
                .iter()
                .map(|t| t.iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0)
                .sum();
            mean += sum / width as f64 * band / 2.0;
        }
        let total: f64 = weight.iter().sum();
        let (density, marginal, conditional) = if total > 0.0 && total.is_finite() {
            let cells = (cols * rows) as f64;
            let density = weight.iter().map(|w| (w / total * cells) as f32).collect();
            let mut marginal = Vec::with_capacity(rows);
            let mut conditional = Vec::with_capacity(cols * rows);
            let mut run = 0.0;
            for row in weight.chunks(cols) {
                let sum: f64 = row.iter().sum();
                run += sum;
                marginal.push((run / total) as f32);
                let mut r = 0.0;
                for w in row {
                    r += w;
                    // A row of zero weight is never drawn; its sums are uniform.
                    conditional.push(if sum > 0.0 { (r / sum) as f32 } else { 0.0 });
                }
                if let Some(last) = conditional.last_mut() {
                    *last = 1.0;
                }
            }
            if let Some(last) = marginal.last_mut() {
                *last = 1.0;
            }
            (density, marginal, conditional)
        } else {
            (vec![0.0; cols * rows], Vec::new(), Vec::new())
        };
        Self {
            width,
            height,
            texels,
            cos_r,
            sin_r,
            visible: env.visible,
            cols,
            rows,
            density,
            marginal,
            conditional,
            mean_radiance: mean,
        }
    }

    /// Whether no direction has light (nothing to sample).
    pub fn is_black(&self) -> bool {
        self.marginal.is_empty()
    }

    /// `(u, v)` of the world direction `d` (unit).
    #[inline]
    pub fn uv(&self, d: V3<f32>) -> [f32; 2] {
        self.uv_of(d)
    }

    /// `(u, v)` of the world directions `d` (unit), lane by lane (one
    /// `f32` is one lane): `d` turned into the image's frame by `R_y(−R)`,
    /// then `u = ½ + φ/2π` with `φ = atan2(z, x)`, and `v = θ/π` with
    /// `θ = acos y = atan2(√((1 − y)(1 + y)), y)` (`y` clamped to
    /// `[−1, 1]`; the factors keep `θ` accurate at the poles).
    #[inline(always)]
    pub fn uv_of<R: Real>(&self, d: V3<R>) -> [R; 2] {
        let (c, s) = (R::splat(self.cos_r), R::splat(self.sin_r));
        let (x, z) = (d.x * c - d.z * s, d.x * s + d.z * c);
        let one = R::splat(1.0);
        let u = R::splat(0.5) + atan2(z, x) * R::splat(0.5 / PI);
        let y = d.y.max(-one).min(one);
        let sin = ((one - y) * (one + y)).sqrt();
        let v = atan2(sin, y) * R::splat(1.0 / PI);
        [u, v]
    }

    /// The radiance arriving from the world direction `d` (unit): the
    /// image looked up bilinearly at [`uv`](Self::uv)`(d)`.
    #[inline]
    pub fn radiance(&self, d: V3<f32>) -> V3<f32> {
        self.radiance_at(self.uv(d))
    }

    /// The radiance and the density of [`sample`](Self::sample) in the
    /// world direction `d` (unit): [`radiance`](Self::radiance) and
    /// [`pdf`](Self::pdf), with the direction's `(u, v)` computed once.
    #[inline]
    pub fn radiance_and_pdf(&self, d: V3<f32>) -> (V3<f32>, f32) {
        let uv = self.uv(d);
        (self.radiance_at(uv), self.pdf_at(uv, d))
    }

    /// The image looked up bilinearly at `(u, v)`.
    #[inline]
    fn radiance_at(&self, [u, v]: [f32; 2]) -> V3<f32> {
        let x = u * self.width as f32 - 0.5;
        let y = v * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let w = self.width as i64;
        let h = self.height as i64 - 1;
        let (i0, j0) = (x0 as i64, y0 as i64);
        // `rem_euclid` (a division) only off the image: `u` in [0, 1]
        // gives `i0` in [−1, w − 1].
        let wrap = |i: i64| {
            if (0..w).contains(&i) {
                i
            } else {
                i.rem_euclid(w)
            }
        };
        let i = [wrap(i0) as usize, wrap(i0 + 1) as usize];
        let j = [j0.clamp(0, h) as usize, (j0 + 1).clamp(0, h) as usize];
        let t = |i: usize, j: usize| self.texels[j * self.width + i];
        let (a, b, c, e) = (t(i[0], j[0]), t(i[1], j[0]), t(i[0], j[1]), t(i[1], j[1]));
        let mix = |k: usize| {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bottom = c[k] + (e[k] - c[k]) * fx;
            top + (bottom - top) * fy
        };
        V3::new(mix(0), mix(1), mix(2))
    }

    /// [`radiance_and_pdf`](Self::radiance_and_pdf) of the world
    /// directions `d` (unit) in the first `n` lanes, at 8 or 16 lanes:
    /// the same bits in each lane. The arithmetic is in lanes; the texel
    /// and density reads, one lane at a time (lanes past `n` read
    /// nothing and hold zeros).
    #[inline(always)]
    pub fn radiance_and_pdf_lanes<L: Lanes>(&self, d: V3<L>, n: usize) -> (V3<L>, L) {
        const MAX: usize = 16;
        assert!(L::LANES <= MAX && n <= L::LANES);
        let [u, v] = self.uv_of(d);
        // The bilinear lookup (`radiance_at`).
        let x = u * L::splat(self.width as f32) - L::splat(0.5);
        let y = v * L::splat(self.height as f32) - L::splat(0.5);
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        let (mut xs, mut ys) = ([0.0f32; MAX], [0.0f32; MAX]);
        x0.write_to(&mut xs[..L::LANES]);
        y0.write_to(&mut ys[..L::LANES]);
        // The four texels, channel by channel: a, b on the top row, c, e
        // below (as `radiance_at` names them).
        let mut texel = [[[0.0f32; MAX]; 3]; 4];
        let (w, h) = (self.width as i64, self.height as i64 - 1);
        let wrap = |i: i64| {
            if (0..w).contains(&i) {
                i
            } else {
                i.rem_euclid(w)
            }
        };
        for l in 0..n {
            let (i0, j0) = (xs[l] as i64, ys[l] as i64);
            let i = [wrap(i0) as usize, wrap(i0 + 1) as usize];
            let j = [j0.clamp(0, h) as usize, (j0 + 1).clamp(0, h) as usize];
            for (k, (i, j)) in [(i[0], j[0]), (i[1], j[0]), (i[0], j[1]), (i[1], j[1])]
                .into_iter()
                .enumerate()
            {
                let t = self.texels[j * self.width + i];
                for c in 0..3 {
                    texel[k][c][l] = t[c];
                }
            }
        }
        let lanes = |c: &[f32; MAX]| L::from_slice(&c[..L::LANES], 0.0);
        let mix = |c: usize| {
            let [a, b, cc, e] = [0, 1, 2, 3].map(|k| lanes(&texel[k][c]));
            let top = a + (b - a) * fx;
            let bottom = cc + (e - cc) * fx;
            top + (bottom - top) * fy
        };
        let radiance = V3::new(mix(0), mix(1), mix(2));
        // The density (`pdf_at`).
        if self.is_black() {
            return (radiance, L::splat(0.0));
        }
        let zero = L::splat(0.0);
        let s2 = L::splat(1.0) - d.y * d.y;
        let sin = L::select(zero.lt(s2), s2, zero).sqrt();
        let (mut us, mut vs) = ([0.0f32; MAX], [0.0f32; MAX]);
        (u * L::splat(self.cols as f32)).write_to(&mut us[..L::LANES]);
        (v * L::splat(self.rows as f32)).write_to(&mut vs[..L::LANES]);
        let mut density = [0.0f32; MAX];
        for l in 0..n {
            let c = (us[l] as usize).min(self.cols - 1);
            let r = (vs[l] as usize).min(self.rows - 1);
            density[l] = self.density[r * self.cols + c];
        }
        let pdf = lanes(&density) / (L::splat(2.0 * PI * PI) * sin);
        (radiance, L::select(zero.lt(sin), pdf, zero))
    }

    /// The density per unit solid angle with which [`sample`](Self::sample)
    /// draws the world direction `d` (unit).
    #[inline]
    pub fn pdf(&self, d: V3<f32>) -> f32 {
        if self.is_black() {
            return 0.0;
        }
        self.pdf_at(self.uv(d), d)
    }

    /// [`pdf`](Self::pdf) of the direction `d` whose `(u, v)` is given.
    #[inline]
    fn pdf_at(&self, [u, v]: [f32; 2], d: V3<f32>) -> f32 {
        if self.is_black() {
            return 0.0;
        }
        let sin = (1.0 - d.y * d.y).max(0.0).sqrt();
        if sin <= 0.0 {
            return 0.0;
        }
        let c = ((u * self.cols as f32) as usize).min(self.cols - 1);
        let r = ((v * self.rows as f32) as usize).min(self.rows - 1);
        self.density[r * self.cols + c] / (2.0 * PI * PI * sin)
    }

    /// A direction drawn for the numbers `[u0, u1]` in `[0, 1)`, with the
    /// radiance from it and its density; `None` when the environment is
    /// black or the direction is a pole (density unbounded).
    #[inline]
    pub fn sample(&self, [u0, u1]: [f32; 2]) -> Option<EnvSample> {
        if self.is_black() {
            return None;
        }
        let (r, fv) = pick(&self.marginal, u0);
        let row = &self.conditional[r * self.cols..(r + 1) * self.cols];
        let (c, fu) = pick(row, u1);
        let u = (c as f32 + fu) / self.cols as f32;
        let v = (r as f32 + fv) / self.rows as f32;
        // φ = 2π(u − ½), as a fraction of a turn in [0, 1).
        let turn = if u < 0.5 { u + 0.5 } else { u - 0.5 };
        let (sin_phi, cos_phi) = crate::math::sin_cos_2pi(turn);
        // θ = πv, a fraction v/2 of a turn.
        let (sin_t, cos_t) = crate::math::sin_cos_2pi(v * 0.5);
        if sin_t <= 0.0 {
            return None;
        }
        let l = V3::new(sin_t * cos_phi, cos_t, sin_t * sin_phi);
        // To the world: R_y(R)·l.
        let (cr, sr) = (self.cos_r, self.sin_r);
        let dir = V3::new(l.x * cr + l.z * sr, l.y, l.z * cr - l.x * sr);
        let pdf = self.density[r * self.cols + c] / (2.0 * PI * PI * sin_t);
        // The radiance where the direction was drawn, at its own `(u, v)`
        // (not mapped back from `dir`: no arc tangent, no arc cosine).
        (pdf > 0.0).then(|| EnvSample {
            dir,
            radiance: self.radiance_at([u, v]),
            pdf,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::environment::{EnvSource, Environment};
    use std::sync::Arc;

    fn image(width: u32, height: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> Environment {
        let mut env = Environment::load(&EnvSource::Constant([1.0; 3]), 1.0, 0.0, true).unwrap();
        env.texels = Arc::new(
            (0..height)
                .flat_map(|j| (0..width).map(move |i| (i, j)))
                .map(|(i, j)| f(i, j))
                .collect(),
        );
        (env.width, env.height) = (width, height);
        env
    }

    #[test]
    fn the_mapping_is_blenders() {
        // An image whose texel (i, j) holds (i, j, 0): the lookup at a
        // texel's centre direction returns that texel.
        let env = EnvLight::new(&image(8, 4, |i, j| [i as f32, j as f32, 0.0]));
        let dir = |u: f32, v: f32| {
            let (phi, theta) = (2.0 * PI * (u - 0.5), PI * v);
            V3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            )
        };
        for j in 0..4 {
            for i in 1..7 {
                let (u, v) = ((i as f32 + 0.5) / 8.0, (j as f32 + 0.5) / 4.0);
                let l = env.radiance(dir(u, v));
                assert!(
                    (l.x - i as f32).abs() < 1e-4 && (l.y - j as f32).abs() < 1e-4,
                    "{i} {j}: {l:?}"
                );
            }
        }
        // The centre column faces +X, u = ¼ faces −Z, the top row is +Y.
        let [u, v] = env.uv(V3::new(1.0, 0.0, 0.0));
        assert!((u - 0.5).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
        let [u, _] = env.uv(V3::new(0.0, 0.0, -1.0));
        assert!((u - 0.25).abs() < 1e-6);
        assert_eq!(env.uv(V3::new(0.0, 1.0, 0.0))[1], 0.0);
        // Wrapping in u: halfway between the last column and the first.
        let l = env.radiance(dir(0.0, 0.375));
        assert!((l.x - 3.5).abs() < 1e-4, "{l:?}");
        // Clamped in v: the top row above its centres.
        let l = env.radiance(dir(0.3, 0.01));
        assert!(l.y.abs() < 1e-6, "{l:?}");
    }

    /// χ² of directions drawn from `env` against its density, over 16 × 8
    /// bins of world azimuth × polar angle (each bin's expected share is
    /// the exact integral of the piecewise-constant density over it), and
    /// the degrees of freedom. `pdf_of` is the density the test holds the
    /// samples to.
    fn chi2_of(env: &EnvLight, rotation_deg: f32, pdf_of: impl Fn(usize) -> f64) -> (f64, usize) {
        let (bu, bv) = (16usize, 8usize);
        assert_eq!(env.rows % bv, 0);
        let mut expected = vec![0.0f64; bu * bv];
        let tau = std::f64::consts::TAU;
        let rot = f64::from(rotation_deg).to_radians();
        for r in 0..env.rows {
            for c in 0..env.cols {
                let p = pdf_of(r * env.cols + c);
                // The cell's world azimuth range, as a fraction of a turn
                // from −π: φ_world = φ_local − R.
                let lo = (c as f64 / env.cols as f64) - rot / tau;
                let hi = lo + 1.0 / env.cols as f64;
                let bin_v = r * bv / env.rows;
                for b in 0..bu {
                    // Overlap of [lo, hi) with bin b's [b/bu, (b+1)/bu), mod 1.
                    let (b0, b1) = (b as f64 / bu as f64, (b + 1) as f64 / bu as f64);
                    let mut overlap = 0.0;
                    for shift in [-2.0, -1.0, 0.0, 1.0, 2.0] {
                        overlap += ((hi + shift).min(b1) - (lo + shift).max(b0)).max(0.0);
                    }
                    // (p over the unit square) × du × dv.
                    expected[bin_v * bu + b] += p * overlap / env.rows as f64;
                }
            }
        }
        let n = 200_000;
        let mut counts = vec![0u32; bu * bv];
        let mut rng = crate::integrator::sampler::PathRng::new(12, 34, 56);
        for _ in 0..n {
            let Some(s) = env.sample([rng.next_f32(), rng.next_f32()]) else {
                continue;
            };
            let phi = f64::from(s.dir.z).atan2(f64::from(s.dir.x));
            let u = 0.5 + phi / tau;
            let v = f64::from(s.dir.y).clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
            let b = ((u * bu as f64) as usize).min(bu - 1);
            let j = ((v * bv as f64) as usize).min(bv - 1);
            counts[j * bu + b] += 1;
        }
        let total: f64 = expected.iter().sum();
        assert!((total - 1.0).abs() < 1e-6, "{total}");
        let chi2 = counts
            .iter()
            .zip(&expected)
            .filter(|(_, e)| **e > 0.0)
            .map(|(&c, &e)| (c as f64 - n as f64 * e).powi(2) / (n as f64 * e))
            .sum();
        (chi2, bu * bv - 1)
    }

    #[test]
    fn directions_follow_the_density_rotation_included() {
        // A sky with a bright sun-like spot and a gradient, turned by 37°.
        // χ² with 127 degrees of freedom: mean 127, sd 16; 220 is far
        // out in the tail.
        let f = |i: u32, j: u32| {
            let spot = if (i, j) == (11, 3) { 500.0 } else { 0.0 };
            [1.0 + i as f32 * 0.1 + spot, 0.5 + j as f32, 2.0]
        };
        let mut e = image(16, 8, f);
        e.rotation_deg = 37.0;
        let env = EnvLight::new(&e);
        let (chi2, dof) = chi2_of(&env, 37.0, |k| f64::from(env.density[k]));
        assert!(chi2 < 220.0, "chi2 {chi2} ({dof} dof)");
        // The same test rejects a density that forgot the rotation...
        let (wrong, _) = chi2_of(&env, 0.0, |k| f64::from(env.density[k]));
        assert!(wrong > 220.0, "the rotation was not needed: chi2 {wrong}");
        // ...and a uniform one.
        let (wrong, _) = chi2_of(&env, 37.0, |_| 1.0);
        assert!(wrong > 220.0, "a uniform density passed: chi2 {wrong}");
        // The density of a drawn direction, looked up from the direction
        // alone (what a scattered ray's MIS weight uses), is the one the
        // sample carries.
        let mut rng = crate::integrator::sampler::PathRng::new(1, 2, 3);
        for _ in 0..10_000 {
            let s = env.sample([rng.next_f32(), rng.next_f32()]).unwrap();
            let p = env.pdf(s.dir);
            assert!((p - s.pdf).abs() <= 1e-3 * s.pdf, "{p} {}", s.pdf);
        }
    }

    #[test]
    fn a_drawn_direction_carries_the_radiance_seen_from_it() {
        // Every texel distinct, turned by 23°: the radiance a sample
        // carries (looked up at its own (u, v)) is the radiance looked up
        // from its direction, to rounding; and the direction is unit.
        let f = |i: u32, j: u32| [1.0 + i as f32 * 0.37, 2.0 + j as f32 * 1.3, (i * j) as f32];
        let mut e = image(24, 12, f);
        e.rotation_deg = 23.0;
        let env = EnvLight::new(&e);
        let mut rng = crate::integrator::sampler::PathRng::new(4, 5, 6);
        for _ in 0..20_000 {
            let Some(s) = env.sample([rng.next_f32(), rng.next_f32()]) else {
                continue;
            };
            let seen = env.radiance(s.dir);
            for (a, b) in [
                (s.radiance.x, seen.x),
                (s.radiance.y, seen.y),
                (s.radiance.z, seen.z),
            ] {
                assert!((a - b).abs() <= 1e-3 * b.abs().max(1.0), "{a} against {b}");
            }
            let len = s.dir.dot(s.dir).sqrt();
            assert!((len - 1.0).abs() < 1e-6, "length {len}");
        }
    }

    /// The bits of a vector.
    fn bits(v: V3<f32>) -> [u32; 3] {
        [v.x, v.y, v.z].map(f32::to_bits)
    }

    /// The largest distance of [`atan2`] from `f64`'s over a dense sweep
    /// of the circle (2²⁰ angles, at three radii), the axes, the seam
    /// (`x < 0`, `y` tiny of either sign) and the octants' borders.
    fn atan2_worst(f: impl Fn(f32, f32) -> f32) -> f64 {
        let mut points = Vec::new();
        let n = 1 << 20;
        for k in 0..n {
            let a = -std::f64::consts::PI + std::f64::consts::TAU * (k as f64 + 0.5) / n as f64;
            for r in [1e-3, 1.0, 7e3] {
                points.push(((a.sin() * r) as f32, (a.cos() * r) as f32));
            }
        }
        for y in [1e-30f32, 1e-7, 1e-3] {
            for s in [1.0f32, -1.0] {
                points.push((s * y, -1.0));
                points.push((s * y, 1.0));
                points.push((1.0, s * y));
                points.push((-1.0, s * y));
            }
        }
        for (y, x) in [
            (1.0f32, 0.0f32),
            (-1.0, 0.0),
            (0.0, 1.0),
            (1.0, 1.0),
            (-1.0, -1.0),
        ] {
            points.push((y, x));
            points.push((y.next_up(), x));
        }
        let mut worst = 0.0f64;
        for (y, x) in points {
            let want = f64::from(y).atan2(f64::from(x));
            worst = worst.max((f64::from(f(y, x)) - want).abs());
        }
        // The seam and the origin, exactly: +π for y = ±0 with x < 0.
        assert_eq!(f(0.0, -1.0), PI);
        assert_eq!(f(-0.0, -1.0), PI);
        assert_eq!(f(0.0, 0.0), 0.0);
        worst
    }

    #[test]
    fn atan2_is_within_its_bound() {
        let worst = atan2_worst(atan2::<f32>);
        assert!(worst <= 3.0e-7, "atan2 is {worst:e} rad off");
    }

    #[test]
    fn a_shorter_polynomial_misses_the_bound() {
        // The test above fails for an atan2 with one term fewer.
        let short = |y: f32, x: f32| {
            let (ax, ay) = (x.abs(), y.abs());
            let (big, small) = (ax.max(ay), ax.min(ay));
            let a = if big == 0.0 { 0.0 } else { small / big };
            let t = a * a;
            let mut p = ATAN[7];
            for &c in ATAN[..7].iter().rev() {
                p = p.mul_add(t, c);
            }
            let mut r = a * p;
            if ax < ay {
                r = FRAC_PI_2 - r;
            }
            if x < 0.0 {
                r = PI - r;
            }
            if y < 0.0 { -r } else { r }
        };
        let worst = atan2_worst(short);
        assert!(worst > 3.0e-7, "{worst:e}");
    }

    #[test]
    fn floor_is_f32_floor() {
        for x in [
            -2.5f32,
            -1.5,
            -1.0,
            -0.7,
            -0.5,
            -0.0,
            0.0,
            0.3,
            0.5,
            1.5,
            2.5,
            511.5,
            -0.5000001,
            8388607.5,
            1e9,
            -1e9,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
        ] {
            assert_eq!(floor(x).to_bits(), x.floor().to_bits(), "{x}");
        }
        assert!(floor(f32::NAN).is_nan());
    }

    /// Directions over the sphere (a Fibonacci spiral), the poles, just
    /// off them, and the seam behind the image's centre (`−X` locally).
    fn directions(rotation_deg: f32) -> Vec<V3<f32>> {
        let mut out = Vec::new();
        let n = 20_000;
        for k in 0..n {
            let y = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).sqrt();
            let phi = k as f64 * 2.399963229728653;
            out.push(V3::new(
                (r * phi.cos()) as f32,
                y as f32,
                (r * phi.sin()) as f32,
            ));
        }
        let (s, c) = f64::from(rotation_deg).to_radians().sin_cos();
        for (x, y, z) in [
            (0.0f64, 1.0, 0.0),
            (0.0, -1.0, 0.0),
            (1e-4, 1.0, 0.0),
            (0.0, -1.0, -1e-4),
            (-1.0, 0.0, 0.0),
            (-1.0, 0.3, 1e-9),
            (-1.0, -0.3, -1e-9),
        ] {
            // Local (x, y, z) to the world: R_y(R).
            let n = (x * x + y * y + z * z).sqrt();
            let (x, y, z) = (x / n, y / n, z / n);
            out.push(V3::new(
                (x * c + z * s) as f32,
                y as f32,
                (z * c - x * s) as f32,
            ));
        }
        out
    }

    #[test]
    fn uv_is_within_its_bound_of_the_exact_mapping() {
        // Against f64 `atan2` and `acos` of the turned direction (turned
        // as the lookup turns it, in f32).
        let mut e = image(16, 8, |i, j| [i as f32, j as f32, 1.0]);
        e.rotation_deg = 37.0;
        let env = EnvLight::new(&e);
        let (mut worst_u, mut worst_v) = (0.0f64, 0.0f64);
        for d in directions(37.0) {
            let [u, v] = env.uv(d);
            let (c, s) = (env.cos_r, env.sin_r);
            let (x, z) = (d.x * c - d.z * s, d.x * s + d.z * c);
            let u_want = 0.5 + f64::from(z).atan2(f64::from(x)) / std::f64::consts::TAU;
            let v_want = f64::from(d.y).clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
            // The seam: u = 0 and u = 1 are one meridian.
            let du = (f64::from(u) - u_want).abs();
            worst_u = worst_u.max(du.min((du - 1.0).abs()));
            worst_v = worst_v.max((f64::from(v) - v_want).abs());
        }
        assert!(worst_u <= 1.2e-7, "u is {worst_u:e} off");
        assert!(worst_v <= 1.5e-7, "v is {worst_v:e} off");
    }

    /// [`EnvLight::radiance_and_pdf_lanes`] at `L`'s width against the
    /// scalar lookup, lane by lane, bit for bit (with `n` lanes of
    /// `L::LANES` in use).
    fn lanes_equal_scalar<L: Lanes>(env: &EnvLight, dirs: &[V3<f32>]) {
        for (k, chunk) in dirs.chunks(L::LANES).enumerate() {
            let n = chunk.len().min(L::LANES - k % 3);
            let col = |f: fn(&V3<f32>) -> f32| {
                let c: Vec<f32> = chunk[..n].iter().map(f).collect();
                L::from_slice(&c, 0.0)
            };
            let d = V3::new(col(|d| d.x), col(|d| d.y), col(|d| d.z));
            let (l, p) = env.radiance_and_pdf_lanes(d, n);
            let (lx, ly, lz, p) = (l.x.to_vec(), l.y.to_vec(), l.z.to_vec(), p.to_vec());
            for (i, &d) in chunk[..n].iter().enumerate() {
                let (want, want_pdf) = env.radiance_and_pdf(d);
                let got = V3::new(lx[i], ly[i], lz[i]);
                assert_eq!(bits(got), bits(want), "{d:?}");
                assert_eq!(p[i].to_bits(), want_pdf.to_bits(), "{d:?}");
            }
        }
    }

    fn lanes_cases() -> Vec<(EnvLight, Vec<V3<f32>>)> {
        let f = |i: u32, j: u32| {
            let spot = if (i, j) == (11, 3) { 500.0 } else { 0.0 };
            [1.0 + i as f32 * 0.1 + spot, 0.5 + j as f32, (i * j) as f32]
        };
        let mut cases = Vec::new();
        for (w, h, deg) in [(16, 8, 37.0), (5, 3, -201.5), (64, 32, 0.0)] {
            let mut e = image(w, h, f);
            e.rotation_deg = deg;
            cases.push((EnvLight::new(&e), directions(deg)));
        }
        // A black one: no density.
        cases.push((
            EnvLight::new(&image(4, 2, |_, _| [0.0; 3])),
            directions(0.0),
        ));
        cases
    }

    #[test]
    fn lane_lookups_are_the_scalar_bits_at_8_and_16_lanes() {
        for (env, dirs) in lanes_cases() {
            lanes_equal_scalar::<wide::f32x8>(&env, &dirs);
            #[cfg(target_arch = "x86_64")]
            if crate::accel::simd::SimdWidth::W16.is_available() {
                // SAFETY: the CPU has AVX-512 (checked just above).
                unsafe { lanes_equal_scalar_16(&env, &dirs) };
            }
        }
    }

    /// [`lanes_equal_scalar`] at 16 lanes, compiled for AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,fma")]
    unsafe fn lanes_equal_scalar_16(env: &EnvLight, dirs: &[V3<f32>]) {
        lanes_equal_scalar::<crate::accel::simd::F32x16>(env, dirs);
    }

    #[test]
    fn turning_a_built_light_is_building_it_turned() {
        let mut e = image(16, 8, |i, j| [(i * j) as f32, 1.0 + i as f32, 0.5]);
        e.rotation_deg = 0.0;
        let mut turned = EnvLight::new(&e);
        for deg in [37.0f32, -201.5, 90.0] {
            e.rotation_deg = deg;
            let built = EnvLight::new(&e);
            turned.turn(deg);
            let mut rng = crate::integrator::sampler::PathRng::new(1, 2, 3);
            for _ in 0..1000 {
                let u = [rng.next_f32(), rng.next_f32()];
                let (a, b) = (built.sample(u).unwrap(), turned.sample(u).unwrap());
                assert_eq!(bits(a.dir), bits(b.dir));
                assert_eq!(a.pdf.to_bits(), b.pdf.to_bits());
                let radiance = |l: &EnvLight| bits(l.radiance(a.dir));
                assert_eq!(radiance(&built), radiance(&turned));
                assert_eq!(built.pdf(a.dir).to_bits(), turned.pdf(a.dir).to_bits());
            }
        }
    }

    #[test]
    fn the_density_integrates_to_one_over_the_sphere() {
        // ∫ pdf dω by the midpoint rule in (φ, cos θ).
        let env = EnvLight::new(&image(16, 8, |i, j| [(i * j) as f32, 1.0, 0.0]));
        let (m, mut sum) = (400, 0.0f64);
        for a in 0..m {
            for b in 0..m {
                let phi = (a as f32 + 0.5) / m as f32 * 2.0 * PI;
                let z = 1.0 - 2.0 * (b as f32 + 0.5) / m as f32;
                let r = (1.0 - z * z).sqrt();
                let d = V3::new(r * phi.cos(), z, r * phi.sin());
                sum += f64::from(env.pdf(d)) * 4.0 * std::f64::consts::PI / (m * m) as f64;
            }
        }
        assert!((sum - 1.0).abs() < 5e-3, "{sum}");
    }

    #[test]
    fn rotation_turns_the_content_right_handed_about_y() {
        // What was seen in d is seen in R_y(90°)·d: +X's texel is then
        // seen towards −Z.
        let f = |i: u32, j: u32| [i as f32 + 10.0 * j as f32, 0.0, 0.0];
        let plain = EnvLight::new(&image(16, 8, f));
        let mut turned = image(16, 8, f);
        turned.rotation_deg = 90.0;
        let turned = EnvLight::new(&turned);
        for d in [
            V3::new(1.0f32, 0.0, 0.0),
            V3::new(0.6, 0.0, 0.8),
            V3::new(0.0, 0.6, -0.8),
        ] {
            let rotated = V3::new(d.z, d.y, -d.x); // R_y(90°)·d
            let (a, b) = (plain.radiance(d), turned.radiance(rotated));
            assert!((a.x - b.x).abs() < 1e-3, "{d:?}: {a:?} {b:?}");
        }
    }
}
