//! The auxiliary outputs' (AOVs') sums, kept exactly like the radiance's.
//!
//! What each AOV means, and where the engines record it, is
//! [`crate::integrator::aov`]'s business; here they are numbers per sample,
//! added to per-pixel integer sums in the film's fixed point (2⁻³² units,
//! [`FIXED_POINT_SCALE`]), so that — like the radiance — they are the same
//! bits however the samples were split across threads, batches, passes,
//! resumes and shards. Only the AOVs a film was made with have sums (and
//! cost memory and time); the others' columns are empty.
//!
//! | AOV | per sample | per pixel, summed | image |
//! |---|---|---|---|
//! | albedo | RGB, clamped to [0, 1] | `u128` ×3 | sum / n |
//! | normal | XYZ, clamped to [-1, 1] | `i128` ×3 | sum / n |
//! | depth | distance `t`, when the camera ray hit (`0 ≤ t < 2³¹`) | `u128` + hit count `u64` | sum / hits, `+inf` for no hit |
//! | variance | the radiance sample's square, per channel | `u128` ×3 | s² (below) |
//!
//! `n` is the film's samples per pixel. The sum of squares adds, per valid
//! radiance sample, `round(q² / 2³²)` where `q` is the integer the
//! radiance sum adds (`round(x · 2³²)`, below 2⁶³): the square of exactly
//! the value the film holds, computed exactly in `u128` and kept in the
//! same 2⁻³² units (below 2⁹⁴ per sample, so 2³² samples fit). Samples the
//! radiance refuses as invalid add nothing to either sum: they count as
//! black, as in the image. The variance image is the unbiased sample
//! variance `s² = (Σx² − (Σx)²/n) / (n − 1)` per channel, computed in
//! `f64` from the exact sums and clamped at 0 (0 for `n < 2`).

use super::{FIXED_POINT_SCALE, MAX_SAMPLE, PixelSum};
use crate::scene::{Aov, AovSet};

/// Sums of one pixel's albedo samples, R, G, B.
pub type AlbedoSum = [u128; 3];
/// Sums of one pixel's normal samples, X, Y, Z.
pub type NormalSum = [i128; 3];
/// Sums of one pixel's squared radiance samples, R, G, B.
pub type SquareSum = [u128; 3];

/// Sum of one pixel's camera-ray hit distances, and how many hit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DepthSum {
    /// The distances' sum, fixed point.
    pub sum: u128,
    /// The samples whose camera ray hit something.
    pub hits: u64,
}

/// Bytes per pixel of one AOV's sums, in memory and in `.wtacc` files.
pub fn bytes_per_pixel(aov: Aov) -> usize {
    match aov {
        Aov::Albedo | Aov::Normal | Aov::Variance => 48,
        Aov::Depth => 24,
    }
}

/// One sample's AOV values as an engine records them (the variance's comes
/// from the radiance sample itself).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AovSample {
    /// The albedo at the first non-specular hit; zero if there is none.
    pub albedo: [f32; 3],
    /// The shading normal there; zero if there is none.
    pub normal: [f32; 3],
    /// The camera ray's hit distance; `+inf` if it hit nothing.
    pub depth: f32,
}

impl AovSample {
    /// A sample that saw nothing: zero albedo and normal, no hit.
    pub const NONE: AovSample = AovSample {
        albedo: [0.0; 3],
        normal: [0.0; 3],
        depth: f32::INFINITY,
    };
}

/// `x` in fixed point (rounded), as the bits of an `i64` (NaN gives 0).
#[inline(always)]
fn fixed(x: f32) -> i64 {
    (x as f64 * FIXED_POINT_SCALE).round() as i64
}

/// The AOV sums of a film: one column per AOV in [`set`](Self::set),
/// each with one entry per pixel (row-major); the other columns are empty.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct AovSums {
    /// The AOVs held.
    pub set: AovSet,
    /// Albedo sums (empty unless `set` has [`Aov::Albedo`]).
    pub albedo: Vec<AlbedoSum>,
    /// Normal sums (empty unless `set` has [`Aov::Normal`]).
    pub normal: Vec<NormalSum>,
    /// Depth sums (empty unless `set` has [`Aov::Depth`]).
    pub depth: Vec<DepthSum>,
    /// Sums of squared radiance (empty unless `set` has [`Aov::Variance`]).
    pub squares: Vec<SquareSum>,
}

impl AovSums {
    /// Zero sums of the AOVs `set` for `pixels` pixels.
    pub fn new(set: AovSet, pixels: usize) -> Self {
        let n = |aov| if set.contains(aov) { pixels } else { 0 };
        Self {
            set,
            albedo: vec![[0; 3]; n(Aov::Albedo)],
            normal: vec![[0; 3]; n(Aov::Normal)],
            depth: vec![DepthSum::default(); n(Aov::Depth)],
            squares: vec![[0; 3]; n(Aov::Variance)],
        }
    }

    /// Whether no AOV is held.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.set.is_empty()
    }

    /// Add `other`'s sums (of the same AOVs and size) to these.
    pub fn add(&mut self, other: &AovSums) {
        assert_eq!(self.set, other.set, "AOV sets differ");
        let add3 = |a: &mut [u128; 3], b: &[u128; 3]| {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        };
        for (a, b) in self.albedo.iter_mut().zip(&other.albedo) {
            add3(a, b);
        }
        for (a, b) in self.normal.iter_mut().zip(&other.normal) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
        for (a, b) in self.depth.iter_mut().zip(&other.depth) {
            a.sum += b.sum;
            a.hits += b.hits;
        }
        for (a, b) in self.squares.iter_mut().zip(&other.squares) {
            add3(a, b);
        }
    }

    /// The sums cut into runs of `tile` pixels: as many runs as
    /// `pixels.div_ceil(tile)`, each with the columns of its pixels (the
    /// empty columns stay empty).
    pub fn tiles_mut(&mut self, tile: usize, pixels: usize) -> Vec<AovTile<'_>> {
        let count = pixels.div_ceil(tile.max(1));
        let mut albedo = self.albedo.chunks_mut(tile);
        let mut normal = self.normal.chunks_mut(tile);
        let mut depth = self.depth.chunks_mut(tile);
        let mut squares = self.squares.chunks_mut(tile);
        (0..count)
            .map(|_| AovTile {
                albedo: albedo.next().unwrap_or_default(),
                normal: normal.next().unwrap_or_default(),
                depth: depth.next().unwrap_or_default(),
                squares: squares.next().unwrap_or_default(),
            })
            .collect()
    }

    /// The AOVs' images (row-major, three channels each; depth repeats its
    /// one value), in canonical order, for a film of `samples` samples per
    /// pixel whose radiance sums are `radiance`.
    pub fn images(&self, samples: u64, radiance: &[PixelSum]) -> Vec<(Aov, Vec<[f32; 3]>)> {
        let n = samples as f64;
        let mean = (n.max(1.0)) * FIXED_POINT_SCALE;
        self.set
            .iter()
            .map(|aov| {
                let image: Vec<[f32; 3]> = match aov {
                    Aov::Albedo => (self.albedo.iter())
                        .map(|s| s.map(|c| (c as f64 / mean) as f32))
                        .collect(),
                    Aov::Normal => (self.normal.iter())
                        .map(|s| s.map(|c| (c as f64 / mean) as f32))
                        .collect(),
                    Aov::Depth => (self.depth.iter())
                        .map(|d| {
                            let z = if d.hits == 0 {
                                f32::INFINITY
                            } else {
                                (d.sum as f64 / (d.hits as f64 * FIXED_POINT_SCALE)) as f32
                            };
                            [z; 3]
                        })
                        .collect(),
                    Aov::Variance => (self.squares.iter().zip(radiance))
                        .map(|(sq, sum)| std::array::from_fn(|c| variance(n, sum[c], sq[c])))
                        .collect(),
                };
                (aov, image)
            })
            .collect()
    }
}

/// The unbiased sample variance of `n` samples from the fixed-point sums
/// of the samples and of their squares (0 for `n < 2`; never negative).
fn variance(n: f64, sum: u128, squares: u128) -> f32 {
    if n < 2.0 {
        return 0.0;
    }
    let s1 = sum as f64 / FIXED_POINT_SCALE;
    let s2 = squares as f64 / FIXED_POINT_SCALE;
    (((s2 - s1 * s1 / n) / (n - 1.0)).max(0.0)) as f32
}

/// The AOV sums of a run of pixels (a tile), borrowed from [`AovSums`].
#[derive(Debug, Default)]
pub struct AovTile<'a> {
    /// Albedo sums, or empty.
    pub albedo: &'a mut [AlbedoSum],
    /// Normal sums, or empty.
    pub normal: &'a mut [NormalSum],
    /// Depth sums, or empty.
    pub depth: &'a mut [DepthSum],
    /// Sums of squared radiance, or empty.
    pub squares: &'a mut [SquareSum],
}

impl AovTile<'_> {
    /// Add sample `aov` to pixel `i` (an index in the tile): the AOVs
    /// whose columns are present. `radiance` is the radiance sample's
    /// fixed-point value ([`super::to_fixed`]), `None` when it was refused
    /// as invalid (then it adds no square).
    #[inline]
    pub fn add(&mut self, i: usize, aov: &AovSample, radiance: Option<[u64; 3]>) {
        if let Some(s) = self.albedo.get_mut(i) {
            for (s, x) in s.iter_mut().zip(aov.albedo) {
                *s += fixed(x.clamp(0.0, 1.0)) as u128;
            }
        }
        if let Some(s) = self.normal.get_mut(i) {
            for (s, x) in s.iter_mut().zip(aov.normal) {
                *s += fixed(x.clamp(-1.0, 1.0)) as i128;
            }
        }
        if let Some(s) = self.depth.get_mut(i)
            && (0.0..MAX_SAMPLE).contains(&aov.depth)
        {
            s.sum += fixed(aov.depth) as u128;
            s.hits += 1;
        }
        if let (Some(s), Some(q)) = (self.squares.get_mut(i), radiance) {
            for (s, q) in s.iter_mut().zip(q) {
                *s += square(q);
            }
        }
    }
}

/// `round(q² / 2³²)`, exactly: the square, in 2⁻³² units, of the
/// fixed-point value `q` (< 2⁶³).
#[inline(always)]
pub fn square(q: u64) -> u128 {
    let q = q as u128;
    (q * q + (1 << 31)) >> 32
}

/// The most a sum of `held` samples of `aov` can be (per channel; for
/// depth, the distances' sum), for refusing forged files: a sum beyond it
/// could not have been made, and later additions could overflow.
pub fn most(aov: Aov, held: u64) -> u128 {
    let held = held as u128;
    match aov {
        Aov::Albedo | Aov::Normal => held << 32,
        Aov::Depth => held << 63,
        Aov::Variance => held << 94,
    }
}
