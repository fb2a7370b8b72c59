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
//! | alpha | 1 when the camera ray hit something | hit count `u64` | hits / n |
//! | zdepth | `t · (d · forward)`, when the camera ray hit | `u128` + hit count `u64` | sum / hits, `+inf` for no hit |
//! | object_id | the id of the object the camera ray hit (0: none) | a count per id seen ([`ObjectCounts`]) | the id of most samples, misses counting for 0; ties to the smallest |
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
/// How many of one pixel's camera rays hit each object: `(id, count)`
/// pairs, ids ascending, each id at most once, counts at least 1 (ids
/// are never 0; the misses are the samples not counted).
pub type ObjectCounts = Vec<(u32, u64)>;

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
        Aov::Depth | Aov::ZDepth => 24,
        Aov::Alpha => 8,
        // Variable in files (a count, then 12 bytes per id); the least here.
        Aov::ObjectId => 4,
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
    /// The camera ray's hit distance; `+inf` if it hit nothing (what the
    /// alpha counts: a sample hit when this is below `+inf`).
    pub depth: f32,
    /// The camera ray's hit distance along the camera's forward axis,
    /// `depth · (d · forward)`; `+inf` if it hit nothing.
    pub zdepth: f32,
    /// The id of the object the camera ray hit; 0 if it hit nothing.
    pub object: u32,
}

impl AovSample {
    /// A sample that saw nothing: zero albedo and normal, no hit.
    pub const NONE: AovSample = AovSample {
        albedo: [0.0; 3],
        normal: [0.0; 3],
        depth: f32::INFINITY,
        zdepth: f32::INFINITY,
        object: 0,
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
    /// Camera-ray hit counts (empty unless `set` has [`Aov::Alpha`]).
    pub alpha: Vec<u64>,
    /// Forward-axis depth sums (empty unless `set` has [`Aov::ZDepth`]).
    pub zdepth: Vec<DepthSum>,
    /// Per-object hit counts (empty unless `set` has [`Aov::ObjectId`]).
    pub objects: Vec<ObjectCounts>,
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
            alpha: vec![0; n(Aov::Alpha)],
            zdepth: vec![DepthSum::default(); n(Aov::ZDepth)],
            objects: vec![Vec::new(); n(Aov::ObjectId)],
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
        for (a, b) in (self.depth.iter_mut().zip(&other.depth))
            .chain(self.zdepth.iter_mut().zip(&other.zdepth))
        {
            a.sum += b.sum;
            a.hits += b.hits;
        }
        for (a, b) in self.squares.iter_mut().zip(&other.squares) {
            add3(a, b);
        }
        for (a, b) in self.alpha.iter_mut().zip(&other.alpha) {
            *a += b;
        }
        for (a, b) in self.objects.iter_mut().zip(&other.objects) {
            for &(id, count) in b {
                add_object(a, id, count);
            }
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
        let mut alpha = self.alpha.chunks_mut(tile);
        let mut zdepth = self.zdepth.chunks_mut(tile);
        let mut objects = self.objects.chunks_mut(tile);
        (0..count)
            .map(|_| AovTile {
                albedo: albedo.next().unwrap_or_default(),
                normal: normal.next().unwrap_or_default(),
                depth: depth.next().unwrap_or_default(),
                squares: squares.next().unwrap_or_default(),
                alpha: alpha.next().unwrap_or_default(),
                zdepth: zdepth.next().unwrap_or_default(),
                objects: objects.next().unwrap_or_default(),
            })
            .collect()
    }

    /// The AOVs' images (row-major, three channels each; depth, alpha,
    /// zdepth and object_id repeat their one value), in canonical order,
    /// for a film of `samples` samples per pixel whose radiance sums are
    /// `radiance`. An object id is exact as an `f32` up to 2²⁴.
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
                    Aov::Depth => self.depth.iter().map(|d| [d.mean(); 3]).collect(),
                    Aov::ZDepth => self.zdepth.iter().map(|d| [d.mean(); 3]).collect(),
                    Aov::Alpha => (self.alpha.iter())
                        .map(|&h| [(h as f64 / n.max(1.0)) as f32; 3])
                        .collect(),
                    Aov::ObjectId => (self.objects.iter())
                        .map(|c| [majority(samples, c) as f32; 3])
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

/// The id of the object most of a pixel's `samples` samples hit, from its
/// counts: the misses (the samples not counted) vote for 0; a tie goes to
/// the smallest id.
pub fn majority(samples: u64, counts: &[(u32, u64)]) -> u32 {
    let hits: u64 = counts.iter().map(|c| c.1).sum();
    let mut best = (0, samples.saturating_sub(hits));
    for &(id, count) in counts {
        // Ids ascend: a later id wins only with strictly more samples.
        if count > best.1 {
            best = (id, count);
        }
    }
    best.0
}

/// Add `count` hits of object `id` to a pixel's counts, keeping them
/// sorted by id.
#[inline]
pub fn add_object(counts: &mut ObjectCounts, id: u32, count: u64) {
    match counts.binary_search_by_key(&id, |c| c.0) {
        Ok(k) => counts[k].1 += count,
        Err(k) => counts.insert(k, (id, count)),
    }
}

impl DepthSum {
    /// The mean distance of the hits, `+inf` when there is none.
    pub fn mean(&self) -> f32 {
        if self.hits == 0 {
            f32::INFINITY
        } else {
            (self.sum as f64 / (self.hits as f64 * FIXED_POINT_SCALE)) as f32
        }
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
    /// Camera-ray hit counts, or empty.
    pub alpha: &'a mut [u64],
    /// Forward-axis depth sums, or empty.
    pub zdepth: &'a mut [DepthSum],
    /// Per-object hit counts, or empty.
    pub objects: &'a mut [ObjectCounts],
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
        if let Some(s) = self.alpha.get_mut(i) {
            *s += u64::from(aov.depth < f32::INFINITY);
        }
        if let Some(s) = self.zdepth.get_mut(i)
            && (0.0..MAX_SAMPLE).contains(&aov.zdepth)
        {
            s.sum += fixed(aov.zdepth) as u128;
            s.hits += 1;
        }
        if let Some(s) = self.objects.get_mut(i)
            && aov.object != 0
        {
            add_object(s, aov.object, 1);
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
        Aov::Depth | Aov::ZDepth => held << 63,
        Aov::Variance => held << 94,
        Aov::Alpha | Aov::ObjectId => held,
    }
}
