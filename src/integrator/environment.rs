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
//! Every function is scalar: both engines call the same ones, lane by
//! lane, so they compute the same bits.

use crate::math::V3;
use crate::scene::environment::Environment;
use std::f32::consts::PI;

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

    /// `d` in the image's frame: turned by `R_y(−R)`.
    #[inline]
    fn to_local(&self, d: V3<f32>) -> V3<f32> {
        let (c, s) = (self.cos_r, self.sin_r);
        V3::new(d.x * c - d.z * s, d.y, d.x * s + d.z * c)
    }

    /// `(u, v)` of the world direction `d` (unit).
    #[inline]
    pub fn uv(&self, d: V3<f32>) -> [f32; 2] {
        let l = self.to_local(d);
        let u = 0.5 + l.z.atan2(l.x) * (0.5 / PI);
        let v = l.y.clamp(-1.0, 1.0).acos() * (1.0 / PI);
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
