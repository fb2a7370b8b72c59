//! The environment light as the integrators see it: the radiance a
//! direction looks up, and directions drawn in proportion to it.
//!
//! Lookup follows [`crate::scene::environment`] (Blender's
//! equirectangular mapping, +Y up, bilinear, `u` wrapped, `v` clamped,
//! the content turned right-handed about +Y).
//!
//! Sampling: a piecewise-constant 2D distribution over the `(u, v)` unit
//! square on a grid of cells (the image's texels, subdivided to at least
//! [`MIN_ROWS`] rows), each cell weighted by how far the mean luminance of
//! the bilinear lookup over it exceeds the mean over the sphere, times
//! `sin θ` at its centre (the solid angle of a row of cells is
//! proportional to it). The cell's mean (not the largest value the lookup
//! reaches in it, which spread a one-texel sun over nine cells) draws a
//! direction in proportion to the radiance it will see. Weighting by
//! excess over the sphere's mean is *MIS compensation*
//! (Karlík, Šik, Vévoda, Skřivan and Křivánek, "MIS Compensation:
//! Optimizing Sampling Techniques in Multiple Importance Sampling", 2019;
//! pbrt-v4's image infinite light does the same): the directions no
//! brighter than the mean are left to BSDF sampling, which next-event
//! estimation always weighs against this density by MIS (a direction of
//! density 0 gets the BSDF sample's weight 1), and light samples go where
//! the sky is brighter than BSDF sampling alone would see well — under a
//! sky with a sun, more of them to the sun, none below the horizon. An
//! environment with no cell above its mean (a constant colour) keeps the
//! plain weights. A row is drawn
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
//! scalar lookup's operations, so the two compute the same bits. Likewise
//! the reference tracer draws one direction at a time
//! ([`EnvLight::sample`]), the wavefront engine eight
//! ([`EnvLight::sample_lanes`]): the searches of the running sums are
//! binary searches of a fixed number of steps in lanes ([`pick_lanes`]),
//! the texel, density and running-sum reads gathers.

use crate::accel::simd::Lanes;
use crate::math::{Real, V3, sin_cos_2pi};
use crate::scene::environment::Environment;
use crate::scene::texture::TexelIndex;
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
    /// Whether the lane functions read by gathers: every index of the
    /// texels' floats and of the cells fits an `i32` and the sizes are
    /// exact in `f32` (else they go lane by lane through the scalar
    /// functions).
    gathers: bool,
}

/// A direction drawn from the environment: one (`R = f32`), or one per
/// lane ([`EnvLight::sample_lanes`]).
#[derive(Clone, Copy, Debug)]
pub struct EnvSample<R = f32> {
    /// Unit direction, world space.
    pub dir: V3<R>,
    /// The radiance arriving from it.
    pub radiance: V3<R>,
    /// Its density per unit solid angle (positive).
    pub pdf: R,
}

/// The lanes' numbers, `0, 1, 2, …`: which lanes are in use.
const LANE_NUMBERS: [f32; 16] = [
    0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0,
];

/// The largest `f32` below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Sizes up to this are exact in `f32` (2²⁴).
const EXACT: usize = 1 << 24;

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
    (k, t.clamp(0.0, ONE_MINUS_EPSILON))
}

/// The environment's search of running sums (`pick`: the index of the
/// first sum above `u`, and `u` stretched back to `[0, 1)` over its
/// share) lane by lane, each lane over the running sums
/// `table[base .. base + n]` (its own `base`; `n ≥ 1`, the sums never
/// decreasing, NaN-free, `n` at most 2²⁴): the index `k` (as a float),
/// `base + k`, and `u` stretched, the same bits as `pick` in every lane.
///
/// `k` is `partition_point`'s index capped at `n − 1`, which for sorted
/// sums is the number of the first `n − 1` sums that are `≤ u`: found by
/// binary lifting, a fixed `⌊log₂(n − 1)⌋ + 1` steps of one gather each
/// (step `s`, a power of two from the largest below `n` down to 1: add
/// `s` to `k` where the sum at `k + s − 1` is `≤ u` and `k + s ≤ n − 1`).
/// The sum before `k` is the last one found `≤ u` (0 where none was), so
/// the stretch needs one more gather, of the sum at `k`.
#[inline(always)]
pub fn pick_lanes<L: Lanes>(table: &[f32], base: L::Index, n: usize, u: L) -> (L, L::Index, L) {
    debug_assert!((1..=EXACT).contains(&n));
    let last = L::splat((n - 1) as f32);
    let (mut k, mut lo) = (L::splat(0.0), L::splat(0.0));
    if n > 1 {
        let mut step = 1usize << (usize::BITS - 1 - (n - 1).leading_zeros());
        while step > 0 {
            let next = k + L::splat(step as f32);
            let at = base + (next.min(last) - L::splat(1.0)).to_index();
            let sum = L::gather_f32(table, at);
            let take = next.le(last) & sum.le(u);
            k = L::select(take, next, k);
            lo = L::select(take, sum, lo);
            step >>= 1;
        }
    }
    let at = base + k.to_index();
    let t = (u - lo) / (L::gather_f32(table, at) - lo);
    let t = t.max(L::splat(0.0)).min(L::splat(ONE_MINUS_EPSILON));
    (k, at, t)
}

/// Whether `sums` never decrease and hold no NaN (what [`pick_lanes`]
/// needs to find `partition_point`'s index).
pub fn sorted(sums: &[f32]) -> bool {
    sums.iter().all(|s| !s.is_nan()) && sums.windows(2).all(|w| w[0] <= w[1])
}

/// The mean over `[a, b]` (texel units, `a < b`) of the hat function of
/// texel `j` (1 at its centre `j + ½`, 0 from one texel away): texel `j`'s
/// share in the mean of the bilinear lookup over that interval, per axis.
/// The shares of the texels an interval touches sum to 1.
fn hat_share(j: i64, a: f64, b: f64) -> f64 {
    let m = j as f64 + 0.5;
    // ∫ from −∞ to x of max(0, 1 − |u − m|) du.
    let f = |x: f64| {
        let s = x - m;
        if s <= -1.0 {
            0.0
        } else if s <= 0.0 {
            (s + 1.0) * (s + 1.0) / 2.0
        } else if s < 1.0 {
            1.0 - (1.0 - s) * (1.0 - s) / 2.0
        } else {
            1.0
        }
    };
    (f(b) - f(a)) / (b - a)
}

/// MIS compensation of the sampling grid's weights (see the module's
/// documentation): `weight` holds each cell's mean luminance, row by
/// row, `sines[r]` the `sin θ` of row `r`'s centre; each becomes
/// `max(L − L̄, 0) · sin θ`, `L̄` the mean of the cells' luminances by solid
/// angle, or `L · sin θ` where no cell exceeds `L̄`.
fn compensate(weight: &mut [f64], sines: &[f64]) {
    let cols = weight.len() / sines.len().max(1);
    let solid: f64 = sines.iter().sum::<f64>() * cols as f64;
    let sum: f64 = weight
        .chunks(cols.max(1))
        .zip(sines)
        .map(|(row, s)| row.iter().sum::<f64>() * s)
        .sum();
    let mean = sum / solid;
    let above = |l: f64| (l - mean).max(0.0);
    let any = mean.is_finite() && weight.iter().any(|&l| above(l) > 0.0);
    for (row, s) in weight.chunks_mut(cols.max(1)).zip(sines) {
        for l in row {
            *l = if any { above(*l) } else { *l } * s;
        }
    }
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
        // Each cell: the mean luminance of the bilinear lookup over it (per
        // axis, each texel's share is its hat function's mean over the
        // cell: ⅛, ¾, ⅛ where cells are texels). The texels' luminances,
        // and each column's texel columns (wrapped) with their shares, are
        // found once rather than per cell.
        let lum: Vec<f32> = texels.iter().map(|&t| luminance(t)).collect();
        let touched = |c: usize| {
            let lo = ((c as f64 / k as f64) - 0.5).floor() as i64;
            let hi = (((c + 1) as f64 / k as f64) - 0.5).floor() as i64 + 1;
            let (a, b) = (c as f64 / k as f64, (c + 1) as f64 / k as f64);
            (lo..=hi).map(move |j| (j, hat_share(j, a, b)))
        };
        let col_texels: Vec<Vec<(usize, f64)>> = (0..cols)
            .map(|c| {
                touched(c)
                    .map(|(i, w)| (i.rem_euclid(width as i64) as usize, w))
                    .collect()
            })
            .collect();
        let mut weight = vec![0.0f64; cols * rows];
        let mut sines = vec![0.0f64; rows];
        let mut mean = 0.0f64;
        for r in 0..rows {
            let theta = (r as f64 + 0.5) / rows as f64 * std::f64::consts::PI;
            let sin = theta.sin();
            sines[r] = sin;
            // Texel rows touched (clamped) and their shares.
            let row_texels: Vec<(&[f32], f64)> = touched(r)
                .map(|(j, w)| {
                    let j = j.clamp(0, height as i64 - 1) as usize;
                    (&lum[j * width..(j + 1) * width], w)
                })
                .collect();
            for (c, is) in col_texels.iter().enumerate() {
                let mut sum = 0.0f64;
                for &(row, wr) in &row_texels {
                    let across: f64 = is.iter().map(|&(i, wc)| wc * f64::from(row[i])).sum();
                    sum += wr * across;
                }
                // Texels are never negative (the loader clamps them); a
                // NaN among them weighs nothing (`max` drops it).
                weight[r * cols + c] = sum.max(0.0);
            }
        }
        compensate(&mut weight, &sines);
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
        // (The running sums never decrease: sums of weights that are not
        // negative, over a positive total, rounded.)
        debug_assert!(sorted(&marginal) && conditional.chunks(cols).all(sorted));
        let fits = |n: usize| n <= i32::MAX as usize;
        let gathers = fits(texels.len() * 3)
            && fits(cols * rows)
            && [width, height, cols, rows].iter().all(|&n| n <= EXACT);
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
            gathers,
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

    /// The four texels (their indices, row-major) that the bilinear
    /// lookup reads for the texel-space corner `(x0, y0)` (whole numbers,
    /// or NaN): `a`, `b` on the upper row, `c`, `e` below; `u` wrapped,
    /// `v` clamped.
    #[inline]
    fn corners(&self, x0: f32, y0: f32) -> [usize; 4] {
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
        let at = |i: usize, j: usize| j * self.width + i;
        [
            at(i[0], j[0]),
            at(i[1], j[0]),
            at(i[0], j[1]),
            at(i[1], j[1]),
        ]
    }

    /// [`corners`](Self::corners) lane by lane, each index times 3 (the
    /// first of the texel's floats): for corners on the image or one
    /// texel off it (all that a `(u, v)` in `[0, 1]` gives) in lanes,
    /// else lane by lane through [`corners`](Self::corners).
    #[inline(always)]
    fn corners_lanes<L: Lanes>(&self, x0: L, y0: L) -> [L::Index; 4] {
        let (one, zero, below) = (L::splat(1.0), L::splat(0.0), L::splat(-1.0));
        let (w, h) = (
            L::splat(self.width as f32),
            L::splat((self.height - 1) as f32),
        );
        let near = below.le(x0) & x0.lt(w) & below.le(y0) & y0.le(h);
        if L::bits(near) != u32::MAX >> (32 - L::LANES) {
            return self.corners_by_lane(x0, y0);
        }
        // `wrap`: −1 is the last column, `w` the first; `clamp`: −1 is
        // row 0, `h + 1` row `h`.
        let next = x0 + one;
        let i = [
            L::select(x0.lt(zero), x0 + w, x0).to_index(),
            L::select(w.le(next), next - w, next).to_index(),
        ];
        let j = [y0.max(zero).to_index(), (y0 + one).min(h).to_index()];
        let width = L::index_splat(self.width as i32);
        let three = L::index_splat(3);
        let at = |i: L::Index, j: L::Index| TexelIndex::mul(TexelIndex::mul(j, width) + i, three);
        [
            at(i[0], j[0]),
            at(i[1], j[0]),
            at(i[0], j[1]),
            at(i[1], j[1]),
        ]
    }

    /// [`corners_lanes`](Self::corners_lanes) lane by lane (corners off
    /// the image, NaN).
    #[cold]
    #[inline(never)]
    fn corners_by_lane<L: Lanes>(&self, x0: L, y0: L) -> [L::Index; 4] {
        const MAX: usize = 16;
        let (mut xs, mut ys) = ([0.0f32; MAX], [0.0f32; MAX]);
        x0.write_to(&mut xs[..L::LANES]);
        y0.write_to(&mut ys[..L::LANES]);
        let mut at = [[0i32; MAX]; 4];
        for l in 0..L::LANES {
            for (k, t) in self.corners(xs[l], ys[l]).into_iter().enumerate() {
                at[k][l] = (t * 3) as i32;
            }
        }
        at.map(|a| L::index_from_slice(&a[..L::LANES], 0))
    }

    /// The image looked up bilinearly at `(u, v)`.
    #[inline]
    fn radiance_at(&self, [u, v]: [f32; 2]) -> V3<f32> {
        let x = u * self.width as f32 - 0.5;
        let y = v * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let [a, b, c, e] = self.corners(x0, y0).map(|k| self.texels[k]);
        let mix = |k: usize| {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bottom = c[k] + (e[k] - c[k]) * fx;
            top + (bottom - top) * fy
        };
        V3::new(mix(0), mix(1), mix(2))
    }

    /// [`radiance_at`](Self::radiance_at) lane by lane, the same bits in
    /// each lane: the arithmetic in lanes, the four texels' channels read
    /// by gathers (the texels' indices from
    /// [`corners_lanes`](Self::corners_lanes)).
    #[inline(always)]
    fn radiance_at_lanes<L: Lanes>(&self, u: L, v: L) -> V3<L> {
        let x = u * L::splat(self.width as f32) - L::splat(0.5);
        let y = v * L::splat(self.height as f32) - L::splat(0.5);
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        let at = self.corners_lanes(x0, y0);
        let floats: &[f32] = bytemuck::cast_slice(&self.texels);
        let mix = |c: usize| {
            let [a, b, cc, e] = at.map(|at| L::gather_f32(&floats[c..], at));
            let top = a + (b - a) * fx;
            let bottom = cc + (e - cc) * fx;
            top + (bottom - top) * fy
        };
        V3::new(mix(0), mix(1), mix(2))
    }

    /// [`radiance_and_pdf`](Self::radiance_and_pdf) of the world
    /// directions `d` (unit) in the first `n` lanes, at 8 or 16 lanes:
    /// the same bits in each lane. The arithmetic is in lanes, the texel
    /// and density reads are gathers (lanes past `n` hold zeros).
    #[inline(always)]
    pub fn radiance_and_pdf_lanes<L: Lanes>(&self, d: V3<L>, n: usize) -> (V3<L>, L) {
        assert!(L::LANES <= LANE_NUMBERS.len() && n <= L::LANES);
        if !self.gathers {
            return self.radiance_and_pdf_by_lane(d, n);
        }
        let zero = L::splat(0.0);
        let live = L::from_slice(&LANE_NUMBERS[..L::LANES], 0.0).lt(L::splat(n as f32));
        let [u, v] = self.uv_of(d);
        let radiance = self.radiance_at_lanes(u, v);
        let radiance = V3::select(live, radiance, V3::new(zero, zero, zero));
        // The density (`pdf_at`).
        if self.is_black() {
            return (radiance, zero);
        }
        let s2 = L::splat(1.0) - d.y * d.y;
        let sin = L::select(zero.lt(s2), s2, zero).sqrt();
        // `(x as usize).min(n − 1)`: NaN and below 0 are 0.
        let cell = |x: L, n: usize| {
            let x = L::select(zero.lt(x), x, zero).min(L::splat((n - 1) as f32));
            floor(x).to_index()
        };
        let c = cell(u * L::splat(self.cols as f32), self.cols);
        let r = cell(v * L::splat(self.rows as f32), self.rows);
        let at = TexelIndex::mul(r, L::index_splat(self.cols as i32)) + c;
        let pdf = L::gather_f32(&self.density, at) / (L::splat(2.0 * PI * PI) * sin);
        (radiance, L::select(zero.lt(sin) & live, pdf, zero))
    }

    /// [`radiance_and_pdf_lanes`](Self::radiance_and_pdf_lanes) lane by
    /// lane (an image too large to index by gathers).
    #[cold]
    #[inline(never)]
    fn radiance_and_pdf_by_lane<L: Lanes>(&self, d: V3<L>, n: usize) -> (V3<L>, L) {
        const MAX: usize = 16;
        let mut dirs = [[0.0f32; MAX]; 3];
        for (k, c) in [d.x, d.y, d.z].into_iter().enumerate() {
            c.write_to(&mut dirs[k][..L::LANES]);
        }
        let mut out = [[0.0f32; MAX]; 4];
        for l in 0..n {
            let (r, p) = self.radiance_and_pdf(V3::new(dirs[0][l], dirs[1][l], dirs[2][l]));
            for (k, x) in [r.x, r.y, r.z, p].into_iter().enumerate() {
                out[k][l] = x;
            }
        }
        let [x, y, z, p] = out.map(|c| L::from_slice(&c[..L::LANES], 0.0));
        (V3::new(x, y, z), p)
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
        let (sin_phi, cos_phi) = sin_cos_2pi(turn);
        // θ = πv, a fraction v/2 of a turn.
        let (sin_t, cos_t) = sin_cos_2pi(v * 0.5);
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

    /// [`sample`](Self::sample) lane by lane, at 8 or 16 lanes: each
    /// lane's direction, radiance and density, and the lanes where
    /// [`sample`](Self::sample) gives one (the others hold what they
    /// hold); in those lanes the same bits as [`sample`](Self::sample).
    /// The row, then the cell, is picked by [`pick_lanes`]; the angles'
    /// sines and cosines are [`sin_cos_2pi`]'s in lanes; the density and
    /// the texels are gathered.
    #[inline(always)]
    pub fn sample_lanes<L: Lanes>(&self, [u0, u1]: [L; 2]) -> (EnvSample<L>, L::Mask) {
        let zero = L::splat(0.0);
        if self.is_black() {
            let none = V3::new(zero, zero, zero);
            let sample = EnvSample {
                dir: none,
                radiance: none,
                pdf: zero,
            };
            return (sample, zero.lt(zero));
        }
        if !self.gathers {
            return self.sample_by_lane([u0, u1]);
        }
        let (r, row, fv) = pick_lanes(&self.marginal, L::index_splat(0), self.rows, u0);
        let row = TexelIndex::mul(row, L::index_splat(self.cols as i32));
        let (c, cell, fu) = pick_lanes(&self.conditional, row, self.cols, u1);
        let u = (c + fu) / L::splat(self.cols as f32);
        let v = (r + fv) / L::splat(self.rows as f32);
        let half = L::splat(0.5);
        let turn = L::select(u.lt(half), u + half, u - half);
        let (sin_phi, cos_phi) = sin_cos_2pi(turn);
        let (sin_t, cos_t) = sin_cos_2pi(v * half);
        let l = V3::new(sin_t * cos_phi, cos_t, sin_t * sin_phi);
        let (cr, sr) = (L::splat(self.cos_r), L::splat(self.sin_r));
        let dir = V3::new(l.x * cr + l.z * sr, l.y, l.z * cr - l.x * sr);
        let pdf = L::gather_f32(&self.density, cell) / (L::splat(2.0 * PI * PI) * sin_t);
        let sample = EnvSample {
            dir,
            radiance: self.radiance_at_lanes(u, v),
            pdf,
        };
        (sample, zero.lt(sin_t) & zero.lt(pdf))
    }

    /// [`sample_lanes`](Self::sample_lanes) lane by lane (an image too
    /// large to index by gathers).
    #[cold]
    #[inline(never)]
    fn sample_by_lane<L: Lanes>(&self, u: [L; 2]) -> (EnvSample<L>, L::Mask) {
        const MAX: usize = 16;
        let mut us = [[0.0f32; MAX]; 2];
        u[0].write_to(&mut us[0][..L::LANES]);
        u[1].write_to(&mut us[1][..L::LANES]);
        // Direction, radiance, density, and 1 where there is a sample.
        let mut out = [[0.0f32; MAX]; 8];
        for l in 0..L::LANES {
            if let Some(s) = self.sample([us[0][l], us[1][l]]) {
                let (d, e) = (s.dir, s.radiance);
                let all = [d.x, d.y, d.z, e.x, e.y, e.z, s.pdf, 1.0];
                for (k, x) in all.into_iter().enumerate() {
                    out[k][l] = x;
                }
            }
        }
        let [x, y, z, r, g, b, pdf, some] = out.map(|c| L::from_slice(&c[..L::LANES], 0.0));
        let sample = EnvSample {
            dir: V3::new(x, y, z),
            radiance: V3::new(r, g, b),
            pdf,
        };
        (sample, L::splat(0.0).lt(some))
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
                let got = [lx[i], ly[i], lz[i]];
                let want = [want.x, want.y, want.z];
                assert!(
                    (0..3).all(|c| same(got[c], want[c])),
                    "{d:?}: {got:?} {want:?}"
                );
                assert!(same(p[i], want_pdf), "{d:?}: {} {want_pdf}", p[i]);
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
        // One texel wide, one high; black rows and columns.
        for (w, h, deg) in [(1, 4, 12.0), (8, 1, 0.0)] {
            let mut e = image(w, h, f);
            e.rotation_deg = deg;
            cases.push((EnvLight::new(&e), directions(deg)));
        }
        let striped = |i: u32, j: u32| [if i % 3 != 1 && j % 4 != 2 { 1.0 } else { 0.0 }, 0.2, 0.0];
        cases.push((EnvLight::new(&image(12, 8, striped)), directions(0.0)));
        // A black one: no density.
        cases.push((
            EnvLight::new(&image(4, 2, |_, _| [0.0; 3])),
            directions(0.0),
        ));
        // Directions that are no directions: NaN, zero, infinite.
        let odd = [
            V3::new(f32::NAN, 0.0, 1.0),
            V3::new(0.0, f32::NAN, 0.0),
            V3::new(0.0, 0.0, 0.0),
            V3::new(f32::INFINITY, 1.0, 0.0),
            V3::new(1.0, -f32::INFINITY, 0.0),
        ];
        for (_, dirs) in &mut cases {
            dirs.extend(odd);
        }
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

    /// Equal bits, or both NaN (a NaN's payload is the compiler's
    /// choice of operand order).
    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    /// Awkward numbers for the searches of `sums`: 0, the largest below
    /// 1, each sum and its neighbours (ties, zeros), 1 and past it, NaN,
    /// and `extra` more from a generator.
    fn awkward(sums: &[f32], extra: usize) -> Vec<f32> {
        let mut u = vec![0.0f32, -0.0, ONE_MINUS_EPSILON, 1.0, 1.5, f32::NAN];
        for &c in sums {
            u.extend([c, c.next_down(), c.next_up()]);
        }
        let mut rng = crate::integrator::sampler::PathRng::new(9, 8, 7);
        u.extend((0..extra).map(|_| rng.next_f32()));
        u
    }

    /// [`pick_lanes`] at `L`'s width against [`pick`], lane by lane, bit
    /// for bit: every lane searching its own one of `tables` (laid end to
    /// end, as the conditional sums are) for each of `u`.
    fn picks_equal_scalar<L: Lanes>(tables: &[Vec<f32>], u: &[f32]) {
        let n = tables[0].len();
        let all: Vec<f32> = tables.concat();
        for (k, chunk) in u.chunks(L::LANES).enumerate() {
            let rows: Vec<usize> = (0..L::LANES).map(|l| (k + l) % tables.len()).collect();
            let base: Vec<i32> = rows.iter().map(|&r| (r * n) as i32).collect();
            let (at, us) = (L::index_from_slice(&base, 0), L::from_slice(chunk, 0.25));
            let (got_k, got_at, got_t) = pick_lanes(&all, at, n, us);
            let (got_k, got_t) = (got_k.to_vec(), got_t.to_vec());
            let mut got_at_lanes = vec![0u32; L::LANES];
            L::index_write_to(got_at, &mut got_at_lanes);
            let got_at = got_at_lanes;
            for (l, &u) in chunk.iter().enumerate() {
                let (want_k, want_t) = pick(&tables[rows[l]], u);
                assert_eq!(got_k[l], want_k as f32, "u {u}: k in {:?}", tables[rows[l]]);
                assert_eq!(got_at[l] as usize, rows[l] * n + want_k, "u {u}");
                assert!(
                    same(got_t[l], want_t),
                    "u {u}: {} against {want_t}",
                    got_t[l]
                );
            }
        }
    }

    /// Running sums with ties, leading and trailing flats, one entry, two,
    /// a power of two and one past it.
    fn awkward_sums() -> Vec<Vec<Vec<f32>>> {
        let mut rng = crate::integrator::sampler::PathRng::new(1, 1, 2);
        let mut random = |n: usize, zeros: bool| {
            let w: Vec<f32> = (0..n)
                .map(|_| {
                    let x = rng.next_f32();
                    if zeros && x < 0.4 { 0.0 } else { x }
                })
                .collect();
            let total: f32 = w.iter().sum::<f32>().max(f32::MIN_POSITIVE);
            let mut run = 0.0;
            let mut sums: Vec<f32> = w
                .iter()
                .map(|x| {
                    run += x;
                    (run / total).min(1.0)
                })
                .collect();
            *sums.last_mut().unwrap() = 1.0;
            sums
        };
        vec![
            vec![vec![1.0]],
            vec![vec![0.5, 1.0], vec![0.0, 1.0], vec![1.0, 1.0]],
            vec![
                vec![0.0, 0.0, 0.25, 0.25, 0.25, 1.0, 1.0],
                vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 1.0],
            ],
            vec![random(8, true), random(8, false), random(8, true)],
            vec![random(9, true), random(9, true)],
            vec![random(512, true), random(512, false)],
            vec![random(33, true)],
        ]
    }

    #[test]
    fn lane_picks_are_the_scalar_picks_at_8_and_16_lanes() {
        for tables in awkward_sums() {
            let u = awkward(&tables.concat(), 200);
            picks_equal_scalar::<wide::f32x8>(&tables, &u);
            #[cfg(target_arch = "x86_64")]
            if crate::accel::simd::SimdWidth::W16.is_available() {
                // SAFETY: the CPU has AVX-512 (checked just above).
                unsafe { picks_equal_scalar_16(&tables, &u) };
            }
        }
    }

    /// [`picks_equal_scalar`] at 16 lanes, compiled for AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,fma")]
    unsafe fn picks_equal_scalar_16(tables: &[Vec<f32>], u: &[f32]) {
        picks_equal_scalar::<crate::accel::simd::F32x16>(tables, u);
    }

    /// [`EnvLight::sample_lanes`] at `L`'s width against
    /// [`EnvLight::sample`], lane by lane: the same lanes drawn, and in
    /// them the same bits.
    fn samples_equal_scalar<L: Lanes>(env: &EnvLight, u: &[[f32; 2]]) -> usize {
        let mut drawn = 0;
        for chunk in u.chunks(L::LANES) {
            let col =
                |k: usize| L::from_slice(&chunk.iter().map(|u| u[k]).collect::<Vec<_>>(), 0.5);
            let (s, some) = env.sample_lanes([col(0), col(1)]);
            let some = L::bits(some);
            let v = |v: V3<L>| [v.x.to_vec(), v.y.to_vec(), v.z.to_vec()];
            let (dir, radiance, pdf) = (v(s.dir), v(s.radiance), s.pdf.to_vec());
            for (l, &u) in chunk.iter().enumerate() {
                let want = env.sample(u);
                assert_eq!(some & (1 << l) != 0, want.is_some(), "u {u:?}");
                let Some(want) = want else { continue };
                drawn += 1;
                let want_v = |w: V3<f32>| [w.x, w.y, w.z];
                for (got, want) in [(&dir, want_v(want.dir)), (&radiance, want_v(want.radiance))] {
                    for c in 0..3 {
                        assert!(
                            same(got[c][l], want[c]),
                            "u {u:?}: {} against {}",
                            got[c][l],
                            want[c]
                        );
                    }
                }
                assert!(
                    same(pdf[l], want.pdf),
                    "u {u:?}: pdf {} against {}",
                    pdf[l],
                    want.pdf
                );
            }
        }
        drawn
    }

    /// Environments for the lane tests: a sky with a sun (turned), a
    /// small odd one (turned past a turn), one 1 texel wide, one 1 texel
    /// high, one texel, one with black rows and columns (running sums
    /// with ties and rows of no weight), one bright texel on black, and a
    /// black one; each with numbers at its running sums and around them.
    fn sample_cases() -> Vec<(EnvLight, Vec<[f32; 2]>)> {
        let sky = |i: u32, j: u32| {
            let spot = if (i, j) == (11, 3) { 500.0 } else { 0.0 };
            [1.0 + i as f32 * 0.1 + spot, 0.5 + j as f32, (i * j) as f32]
        };
        let striped = |i: u32, j: u32| {
            let on = i % 3 != 1 && j % 4 != 2;
            [if on { 1.0 + (i + j) as f32 } else { 0.0 }, 0.2, 0.0]
        };
        let one = |i: u32, j: u32| {
            if (i, j) == (5, 2) {
                [3.0, 2.0, 1.0]
            } else {
                [0.0; 3]
            }
        };
        type Texels<'a> = &'a dyn Fn(u32, u32) -> [f32; 3];
        let images: Vec<(u32, u32, f32, Texels)> = vec![
            (16, 8, 37.0, &sky),
            (5, 3, -201.5, &sky),
            (1, 4, 12.0, &sky),
            (8, 1, 0.0, &sky),
            (1, 1, 90.0, &sky),
            (12, 8, 0.0, &striped),
            (8, 4, -30.0, &one),
            (4, 2, 0.0, &|_, _| [0.0; 3]),
        ];
        images
            .into_iter()
            .map(|(w, h, deg, f)| {
                let mut e = image(w, h, f);
                e.rotation_deg = deg;
                let env = EnvLight::new(&e);
                let u0 = awkward(&env.marginal, 300);
                let u1 = awkward(&env.conditional, 300);
                let mut rng = crate::integrator::sampler::PathRng::new(3, 1, 4);
                let mut u: Vec<[f32; 2]> = u0.iter().map(|&a| [a, rng.next_f32()]).collect();
                u.extend(u1.iter().map(|&b| [rng.next_f32(), b]));
                u.extend(u0.iter().zip(u1.iter().rev()).map(|(&a, &b)| [a, b]));
                (env, u)
            })
            .collect()
    }

    #[test]
    fn lane_samples_are_the_scalar_bits_at_8_and_16_lanes() {
        for (env, u) in sample_cases() {
            let drawn = samples_equal_scalar::<wide::f32x8>(&env, &u);
            assert_eq!(drawn == 0, env.is_black(), "{} × {}", env.width, env.height);
            #[cfg(target_arch = "x86_64")]
            if crate::accel::simd::SimdWidth::W16.is_available() {
                // SAFETY: the CPU has AVX-512 (checked just above).
                unsafe { samples_equal_scalar_16(&env, &u) };
            }
        }
    }

    /// [`samples_equal_scalar`] at 16 lanes, compiled for AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,fma")]
    unsafe fn samples_equal_scalar_16(env: &EnvLight, u: &[[f32; 2]]) {
        samples_equal_scalar::<crate::accel::simd::F32x16>(env, u);
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
    fn a_nan_or_infinite_texel_leaves_sound_tables() {
        // A NaN texel weighs nothing: the running sums stay sorted and
        // every density finite. An infinite one leaves nothing to sample
        // by (the environment draws no directions), as before.
        let nan = EnvLight::new(&image(16, 8, |i, j| {
            if (i, j) == (3, 2) {
                [f32::NAN, 1.0, 1.0]
            } else {
                [0.5, 1.0 + j as f32, 2.0]
            }
        }));
        assert!(sorted(&nan.marginal) && nan.conditional.chunks(nan.cols).all(sorted));
        assert!(nan.density.iter().all(|d| d.is_finite() && *d >= 0.0));
        assert!(!nan.is_black());
        let inf = EnvLight::new(&image(16, 8, |i, j| {
            if (i, j) == (3, 2) {
                [f32::INFINITY; 3]
            } else {
                [0.5; 3]
            }
        }));
        assert!(inf.is_black() && inf.sample([0.3, 0.6]).is_none());
    }

    #[test]
    fn a_cells_weight_is_the_lookups_mean_over_it() {
        // One bright texel in a black image: its cell and the eight around
        // it share its light as the bilinear lookup spreads it (⅛, ¾, ⅛
        // per axis: (¾)², ¾·⅛ and ⅛² of it), not nine equal shares.
        let share = |j: i64, c: i64| hat_share(j, c as f64, c as f64 + 1.0);
        assert!((share(5, 5) - 0.75).abs() < 1e-12);
        assert!((share(5, 4) - 0.125).abs() < 1e-12 && (share(5, 6) - 0.125).abs() < 1e-12);
        assert_eq!(share(5, 7), 0.0);
        let total: f64 = (-1..=1).map(|d| share(5 + d, 5)).sum();
        assert!((total - 1.0).abs() < 1e-12);
        // Subdivided cells (a 4-row image has 8 sub-rows per texel row).
        let sub: f64 = (-1..=1).map(|d| hat_share(1 + d, 1.25, 1.375)).sum();
        assert!((sub - 1.0).abs() < 1e-12);
        let env = EnvLight::new(&image(64, 32, |i, j| {
            if (i, j) == (20, 10) {
                [1.0; 3]
            } else {
                [0.0; 3]
            }
        }));
        let d = |r: usize, c: usize| f64::from(env.density[r * 64 + c]);
        let sin = |r: usize| ((r as f64 + 0.5) / 32.0 * std::f64::consts::PI).sin();
        // (Compensation takes the sphere's mean, under 10⁻³, off each.)
        let centre = d(10, 20) / sin(10);
        assert!((d(10, 21) / sin(10) / centre - 1.0 / 6.0).abs() < 2e-3);
        assert!((d(9, 21) / sin(9) / centre - 1.0 / 36.0).abs() < 2e-3);
        assert_eq!(d(10, 22), 0.0);
    }

    #[test]
    fn compensation_leaves_the_cells_below_the_mean_to_bsdf_sampling() {
        // Rows brighter towards the top: the cells whose luminance is at
        // most the sphere's mean have density 0, the others density in
        // proportion to (L − mean) sin θ.
        let env = EnvLight::new(&image(4, 32, |_, j| [(32 - j) as f32; 3]));
        let sin = |r: usize| ((r as f64 + 0.5) / 32.0 * std::f64::consts::PI).sin();
        let solid: f64 = (0..32).map(sin).sum();
        // The bilinear lookup's mean over a cell of row r is ⅛, ¾, ⅛ of
        // texel rows r − 1, r, r + 1 (clamped): 32 − r inside, where the
        // rows are linear, and at the clamped ends 31.875 and 1.125; the
        // sphere's mean is of those, by solid angle.
        let cell = |r: usize| match r {
            0 => 31.875,
            31 => 1.125,
            _ => f64::from(32 - r as u32),
        };
        let mean = (0..32).map(|r| cell(r) * sin(r)).sum::<f64>() / solid;
        let want: Vec<f64> = (0..32)
            .map(|r| (cell(r) - mean).max(0.0) * sin(r))
            .collect();
        let total: f64 = want.iter().sum::<f64>() * 4.0;
        for (r, want) in want.iter().enumerate() {
            for c in 0..4 {
                let d = f64::from(env.density[r * 4 + c]);
                let w = want / total * 128.0;
                assert!(
                    (d - w).abs() <= 1e-5 * w.max(1.0),
                    "row {r}: {d} against {w}"
                );
            }
        }
        assert!(env.density[31 * 4] == 0.0 && env.density[0] > 0.0);
        // A constant sky has no cell above its mean: the plain weights.
        let flat = EnvLight::new(&image(4, 32, |_, _| [0.5; 3]));
        for r in 0..32 {
            let w = sin(r) / (0..32).map(sin).sum::<f64>() * 32.0;
            let d = f64::from(flat.density[r * 4]);
            assert!((d - w).abs() <= 1e-5 * w, "row {r}: {d} against {w}");
        }
    }

    #[test]
    fn the_density_integrates_to_one_over_the_sphere() {
        // ∫ pdf dω by the midpoint rule in (φ, cos θ), on a grid fine
        // enough for the compensated density's steps down to 0.
        let env = EnvLight::new(&image(16, 8, |i, j| [(i * j) as f32, 1.0, 0.0]));
        let (m, mut sum) = (3000, 0.0f64);
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
