//! The auxiliary outputs' (AOVs') sums, kept exactly like the radiance's.
//!
//! What each AOV means, and where the engines record it, is
//! [`crate::integrator::aov`]'s and [`crate::scene::aov`]'s business; here
//! they are numbers per sample, summed by the kind of their [`Sum`] (one
//! [`Column`] kind per kind of sum, whatever the AOV),
//! into per-pixel integer sums in the film's fixed point (2⁻³² units,
//! [`FIXED_POINT_SCALE`]), so that — like the radiance — they are the same
//! bits however the samples were split across threads, batches, passes,
//! resumes and shards. Only the AOVs a film was made with have sums (and
//! cost memory and time).
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

use super::{FIXED_POINT_SCALE, MAX_SAMPLE, PixelSum, Samples};
use crate::scene::aov::Sum;
use crate::scene::{Aov, AovSet};

/// How many samples of one pixel hit each object: `(id, count)` pairs,
/// ids ascending, each id at most once, counts at least 1 (ids are never
/// 0; the misses are the samples not counted).
pub type ObjectCounts = Vec<(u32, u64)>;

/// Sum of one pixel's values of a [`Sum::HitMean`] AOV (the camera rays'
/// hit distances), and how many samples hit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DepthSum {
    /// The values' sum, fixed point.
    pub sum: u128,
    /// The samples whose camera ray hit something.
    pub hits: u64,
}

/// Bytes per pixel of one AOV's sums, in memory and in `.wtacc` files.
pub fn bytes_per_pixel(aov: Aov) -> usize {
    match aov.def().sum {
        Sum::Mean { .. } | Sum::Squares => 48,
        Sum::HitMean => 24,
        Sum::Count => 8,
        // Variable in files (a count, then 12 bytes per id); the least here.
        Sum::Votes => 4,
    }
}

/// One sample's AOV values as an engine records them, three channels per
/// AOV (indexed by [`Aov`]; an AOV of one value uses the first channel, an
/// id is the bits of the first channel). The variance's comes from the
/// radiance sample itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AovSample {
    /// Each AOV's value, or its [`none`](crate::scene::AovDef::none).
    pub values: [[f32; 3]; Aov::COUNT],
}

impl AovSample {
    /// A sample that recorded nothing: each AOV's `none`.
    pub const NONE: AovSample = AovSample {
        values: {
            let mut values = [[0.0; 3]; Aov::COUNT];
            let mut i = 0;
            while i < Aov::COUNT {
                values[i] = Aov::EVERY[i].def().none;
                i += 1;
            }
            values
        },
    };

    /// The value of `aov`.
    #[inline(always)]
    pub fn get(&self, aov: Aov) -> [f32; 3] {
        self.values[aov as usize]
    }

    /// Set the value of `aov`.
    #[inline(always)]
    pub fn set(&mut self, aov: Aov, value: [f32; 3]) {
        self.values[aov as usize] = value;
    }
}

/// `x` in fixed point (rounded), as the bits of an `i64` (NaN gives 0).
#[inline(always)]
fn fixed(x: f32) -> i64 {
    (x as f64 * FIXED_POINT_SCALE).round() as i64
}

/// One AOV's sums, one entry per pixel (row-major), of its kind of
/// [`Sum`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Column {
    /// [`Sum::Mean`]: each channel's sum (signed, as normals are).
    Mean(Vec<[i128; 3]>),
    /// [`Sum::HitMean`]: the hits' values' sum and their count.
    HitMean(Vec<DepthSum>),
    /// [`Sum::Count`]: the samples counted.
    Count(Vec<u64>),
    /// [`Sum::Votes`]: the votes per id.
    Votes(Vec<ObjectCounts>),
    /// [`Sum::Squares`]: the sums of the squared radiance, R, G, B.
    Squares(Vec<[u128; 3]>),
}

/// A run of pixels (a tile) of a [`Column`], borrowed.
#[derive(Debug)]
pub enum ColumnTile<'a> {
    /// See [`Column::Mean`].
    Mean(&'a mut [[i128; 3]]),
    /// See [`Column::HitMean`].
    HitMean(&'a mut [DepthSum]),
    /// See [`Column::Count`].
    Count(&'a mut [u64]),
    /// See [`Column::Votes`].
    Votes(&'a mut [ObjectCounts]),
    /// See [`Column::Squares`].
    Squares(&'a mut [[u128; 3]]),
}

impl Column {
    /// Zero sums of kind `sum` for `pixels` pixels.
    pub fn zero(sum: Sum, pixels: usize) -> Self {
        match sum {
            Sum::Mean { .. } => Column::Mean(vec![[0; 3]; pixels]),
            Sum::HitMean => Column::HitMean(vec![DepthSum::default(); pixels]),
            Sum::Count => Column::Count(vec![0; pixels]),
            Sum::Votes => Column::Votes(vec![Vec::new(); pixels]),
            Sum::Squares => Column::Squares(vec![[0; 3]; pixels]),
        }
    }

    /// Add `other`'s sums (of the same kind and size) to these.
    fn add(&mut self, other: &Column) {
        match (self, other) {
            (Column::Mean(a), Column::Mean(b)) => {
                for (a, b) in a.iter_mut().zip(b) {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x += y;
                    }
                }
            }
            (Column::HitMean(a), Column::HitMean(b)) => {
                for (a, b) in a.iter_mut().zip(b) {
                    a.sum += b.sum;
                    a.hits += b.hits;
                }
            }
            (Column::Count(a), Column::Count(b)) => {
                for (a, b) in a.iter_mut().zip(b) {
                    *a += b;
                }
            }
            (Column::Votes(a), Column::Votes(b)) => {
                for (a, b) in a.iter_mut().zip(b) {
                    for &(id, count) in b {
                        add_object(a, id, count);
                    }
                }
            }
            (Column::Squares(a), Column::Squares(b)) => {
                for (a, b) in a.iter_mut().zip(b) {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x += y;
                    }
                }
            }
            _ => panic!("AOV columns of different kinds"),
        }
    }

    /// The column cut into runs of `tile` pixels.
    fn tiles_mut(&mut self, tile: usize) -> Vec<ColumnTile<'_>> {
        match self {
            Column::Mean(c) => c.chunks_mut(tile).map(ColumnTile::Mean).collect(),
            Column::HitMean(c) => c.chunks_mut(tile).map(ColumnTile::HitMean).collect(),
            Column::Count(c) => c.chunks_mut(tile).map(ColumnTile::Count).collect(),
            Column::Votes(c) => c.chunks_mut(tile).map(ColumnTile::Votes).collect(),
            Column::Squares(c) => c.chunks_mut(tile).map(ColumnTile::Squares).collect(),
        }
    }

    /// The image (three channels per pixel; one value repeated for the
    /// kinds of one) of a film of `samples` samples per pixel whose
    /// radiance sums are `radiance`.
    fn image(&self, samples: Samples, radiance: &[PixelSum]) -> Vec<[f32; 3]> {
        let n = |i: usize| samples.of(i) as f64;
        let mean = |i: usize| n(i).max(1.0) * FIXED_POINT_SCALE;
        match self {
            Column::Mean(c) => (c.iter().enumerate())
                .map(|(i, s)| s.map(|c| (c as f64 / mean(i)) as f32))
                .collect(),
            Column::HitMean(c) => c.iter().map(|d| [d.mean(); 3]).collect(),
            Column::Count(c) => (c.iter().enumerate())
                .map(|(i, &h)| [(h as f64 / n(i).max(1.0)) as f32; 3])
                .collect(),
            Column::Votes(c) => (c.iter().enumerate())
                .map(|(i, c)| [majority(samples.of(i), c) as f32; 3])
                .collect(),
            Column::Squares(c) => (c.iter().zip(radiance).enumerate())
                .map(|(i, (sq, sum))| std::array::from_fn(|k| variance(n(i), sum[k], sq[k])))
                .collect(),
        }
    }

    /// Append the sums to `bytes`, little-endian, pixel after pixel: three
    /// `u128` (`i128` for a mean) per pixel of a mean or squares, a `u128`
    /// sum and a `u64` count of a hit mean, a `u64` count, and for votes a
    /// `u32` number of ids then that many `u32` id and `u64` count pairs.
    pub fn write(&self, bytes: &mut Vec<u8>) {
        match self {
            Column::Mean(c) => c
                .iter()
                .flatten()
                .for_each(|x| bytes.extend(x.to_le_bytes())),
            Column::Squares(c) => c
                .iter()
                .flatten()
                .for_each(|x| bytes.extend(x.to_le_bytes())),
            Column::HitMean(c) => {
                for d in c {
                    bytes.extend_from_slice(&d.sum.to_le_bytes());
                    bytes.extend_from_slice(&d.hits.to_le_bytes());
                }
            }
            Column::Count(c) => c.iter().for_each(|h| bytes.extend(h.to_le_bytes())),
            Column::Votes(c) => {
                for counts in c {
                    bytes.extend_from_slice(&(counts.len() as u32).to_le_bytes());
                    for (id, count) in counts {
                        bytes.extend_from_slice(&id.to_le_bytes());
                        bytes.extend_from_slice(&count.to_le_bytes());
                    }
                }
            }
        }
    }

    /// Read the sums of `aov` for `pixels` pixels of `held` samples each
    /// from the front of `bytes` ([`write`](Self::write)'s layout),
    /// refusing sums no `held` samples can make (so later additions cannot
    /// overflow). Returns the column and the bytes after it.
    pub fn read(
        aov: Aov,
        bytes: &[u8],
        pixels: usize,
        held: u64,
    ) -> Result<(Column, &[u8]), ReadError> {
        let name = aov.name();
        let article = if name.starts_with(['a', 'e', 'i', 'o', 'u']) {
            "an"
        } else {
            "a"
        };
        let too_large = |i| ReadError::TooLarge(i, format!("{article} {name} sum"));
        let sum = aov.def().sum;
        if sum == Sum::Votes {
            return read_votes(name, bytes, pixels, held);
        }
        let (plane, rest) = bytes.split_at((pixels * bytes_per_pixel(aov)).min(bytes.len()));
        let u128_at =
            |b: &[u8], at: usize| u128::from_le_bytes(b[at..at + 16].try_into().unwrap_or([0; 16]));
        let bound = most(sum, held);
        let column = match sum {
            Sum::Mean { lo, .. } => {
                let least = if lo < 0.0 { -(bound as i128) } else { 0 };
                let mut col = Vec::with_capacity(pixels);
                for (i, p) in plane.chunks_exact(48).enumerate() {
                    let s: [i128; 3] = std::array::from_fn(|c| u128_at(p, c * 16) as i128);
                    if s.iter().any(|&c| c < least || c > bound as i128) {
                        return Err(too_large(i));
                    }
                    col.push(s);
                }
                Column::Mean(col)
            }
            Sum::Squares => {
                let mut col = Vec::with_capacity(pixels);
                for (i, p) in plane.chunks_exact(48).enumerate() {
                    let s: [u128; 3] = std::array::from_fn(|c| u128_at(p, c * 16));
                    if s.iter().any(|&c| c > bound) {
                        return Err(too_large(i));
                    }
                    col.push(s);
                }
                Column::Squares(col)
            }
            Sum::HitMean => {
                let mut col = Vec::with_capacity(pixels);
                for (i, p) in plane.chunks_exact(24).enumerate() {
                    let d = DepthSum {
                        sum: u128_at(p, 0),
                        hits: u64::from_le_bytes(p[16..24].try_into().unwrap_or([0; 8])),
                    };
                    if d.hits > held || d.sum > most(sum, d.hits) {
                        return Err(too_large(i));
                    }
                    col.push(d);
                }
                Column::HitMean(col)
            }
            Sum::Count => {
                let mut col = Vec::with_capacity(pixels);
                for (i, p) in plane.chunks_exact(8).enumerate() {
                    let h = u64::from_le_bytes(p.try_into().unwrap_or([0; 8]));
                    if h > held {
                        return Err(too_large(i));
                    }
                    col.push(h);
                }
                Column::Count(col)
            }
            Sum::Votes => unreachable!("read above"),
        };
        Ok((column, rest))
    }
}

/// Why [`Column::read`] refused a column's bytes.
#[derive(Debug)]
pub enum ReadError {
    /// Pixel `.0` (an index) holds `.1` (say, "a depth sum") larger than
    /// its samples can make.
    TooLarge(usize, String),
    /// Pixel `.0` holds sums that break the rule `.1`.
    Invalid(usize, String),
    /// The bytes end before the column does (`.1` says which).
    Truncated(String),
}

/// [`Column::read`] of votes: for each pixel a `u32` number of ids, then
/// that many `u32` id and `u64` count pairs, ids ascending (none 0),
/// counts at least 1, summing to at most the `held` samples.
fn read_votes<'a>(
    name: &str,
    mut plane: &'a [u8],
    pixels: usize,
    held: u64,
) -> Result<(Column, &'a [u8]), ReadError> {
    let short = || ReadError::Truncated(format!("the {name} sums are truncated"));
    let mut out = Vec::with_capacity(pixels.min(plane.len() / 4));
    for i in 0..pixels {
        let (n, tail) = plane.split_first_chunk::<4>().ok_or_else(short)?;
        let n = u32::from_le_bytes(*n) as usize;
        let bytes = n.checked_mul(12).filter(|&b| b <= tail.len());
        let bytes = bytes.ok_or_else(short)?;
        let (pairs, tail) = tail.split_at(bytes);
        plane = tail;
        let mut counts = Vec::with_capacity(n);
        let mut total = 0u64;
        for p in pairs.chunks_exact(12) {
            let id = u32::from_le_bytes(p[..4].try_into().unwrap_or_default());
            let count = u64::from_le_bytes(p[4..].try_into().unwrap_or_default());
            let ascending = counts.last().is_none_or(|&(last, _)| id > last);
            if id == 0 || count == 0 || !ascending {
                let rule = "counts must be of ids above 0, ascending, each at least 1";
                return Err(ReadError::Invalid(i, format!("{name} {rule}")));
            }
            total = total.saturating_add(count);
            if total > held {
                return Err(ReadError::TooLarge(i, format!("an {name} count")));
            }
            counts.push((id, count));
        }
        out.push(counts);
    }
    Ok((Column::Votes(out), plane))
}

/// The AOV sums of a film: one [`Column`] per AOV of [`set`](Self::set),
/// in canonical order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct AovSums {
    /// The AOVs held.
    pub set: AovSet,
    /// Their sums, in the order of `set`.
    pub columns: Vec<(Aov, Column)>,
}

impl AovSums {
    /// Zero sums of the AOVs `set` for `pixels` pixels.
    pub fn new(set: AovSet, pixels: usize) -> Self {
        let columns = set.iter().map(|a| (a, Column::zero(a.def().sum, pixels)));
        Self {
            set,
            columns: columns.collect(),
        }
    }

    /// Whether no AOV is held.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.set.is_empty()
    }

    /// The sums of `aov`, if held.
    pub fn column(&self, aov: Aov) -> Option<&Column> {
        self.columns.iter().find(|c| c.0 == aov).map(|c| &c.1)
    }

    /// The sums of `aov`, a [`Sum::Mean`] (empty if not held).
    pub fn means(&self, aov: Aov) -> &[[i128; 3]] {
        match self.column(aov) {
            Some(Column::Mean(c)) => c,
            _ => &[],
        }
    }

    /// The sums of `aov`, a [`Sum::HitMean`] (empty if not held).
    pub fn hit_means(&self, aov: Aov) -> &[DepthSum] {
        match self.column(aov) {
            Some(Column::HitMean(c)) => c,
            _ => &[],
        }
    }

    /// The counts of `aov`, a [`Sum::Count`] (empty if not held).
    pub fn counts(&self, aov: Aov) -> &[u64] {
        match self.column(aov) {
            Some(Column::Count(c)) => c,
            _ => &[],
        }
    }

    /// The votes of `aov`, a [`Sum::Votes`] (empty if not held).
    pub fn votes(&self, aov: Aov) -> &[ObjectCounts] {
        match self.column(aov) {
            Some(Column::Votes(c)) => c,
            _ => &[],
        }
    }

    /// The sums of squares of `aov`, a [`Sum::Squares`] (empty if not
    /// held).
    pub fn squares(&self, aov: Aov) -> &[[u128; 3]] {
        match self.column(aov) {
            Some(Column::Squares(c)) => c,
            _ => &[],
        }
    }

    /// Add `other`'s sums (of the same AOVs and size) to these.
    pub fn add(&mut self, other: &AovSums) {
        assert_eq!(self.set, other.set, "AOV sets differ");
        for ((_, a), (_, b)) in self.columns.iter_mut().zip(&other.columns) {
            a.add(b);
        }
    }

    /// The sums cut into runs of `tile` pixels: as many runs as
    /// `pixels.div_ceil(tile)`, each with the columns of its pixels.
    pub fn tiles_mut(&mut self, tile: usize, pixels: usize) -> Vec<AovTile<'_>> {
        let tile = tile.max(1);
        let mut tiles: Vec<AovTile> = (0..pixels.div_ceil(tile))
            .map(|_| AovTile::default())
            .collect();
        for (aov, column) in &mut self.columns {
            for (t, c) in tiles.iter_mut().zip(column.tiles_mut(tile)) {
                let (lo, hi) = match aov.def().sum {
                    Sum::Mean { lo, hi } => (lo, hi),
                    _ => (0.0, 0.0),
                };
                t.columns.push((*aov, lo, hi, c));
            }
        }
        tiles
    }

    /// The AOVs' images (row-major, three channels each; depth, alpha,
    /// zdepth and object_id repeat their one value), in canonical order,
    /// for a film whose pixels hold `samples` samples and whose radiance
    /// sums are `radiance`. An object id is exact as an `f32` up to 2²⁴.
    pub fn images(&self, samples: Samples, radiance: &[PixelSum]) -> Vec<(Aov, Vec<[f32; 3]>)> {
        (self.columns.iter())
            .map(|(aov, c)| (*aov, c.image(samples, radiance)))
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
pub(crate) fn variance(n: f64, sum: u128, squares: u128) -> f32 {
    if n < 2.0 {
        return 0.0;
    }
    let s1 = sum as f64 / FIXED_POINT_SCALE;
    let s2 = squares as f64 / FIXED_POINT_SCALE;
    (((s2 - s1 * s1 / n) / (n - 1.0)).max(0.0)) as f32
}

/// The AOV sums of a run of pixels (a tile), borrowed from [`AovSums`]:
/// each held AOV's column, with a mean's clamp bounds.
#[derive(Debug, Default)]
pub struct AovTile<'a> {
    /// The AOV, its `lo` and `hi` (for a mean), and its pixels' sums.
    pub columns: Vec<(Aov, f32, f32, ColumnTile<'a>)>,
}

impl AovTile<'_> {
    /// Whether the tile holds no AOV.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.columns.is_empty()
    }

    /// Add sample `aov` to pixel `i` (an index in the tile), to each
    /// column present. `radiance` is the radiance sample's fixed-point
    /// value ([`super::to_fixed`]), `None` when it was refused as invalid
    /// (then it adds no square).
    #[inline]
    pub fn add(&mut self, i: usize, sample: &AovSample, radiance: Option<[u64; 3]>) {
        for (aov, lo, hi, column) in &mut self.columns {
            let v = sample.get(*aov);
            match column {
                ColumnTile::Mean(c) => {
                    for (s, x) in c[i].iter_mut().zip(v) {
                        *s += fixed(x.clamp(*lo, *hi)) as i128;
                    }
                }
                ColumnTile::HitMean(c) => {
                    if (0.0..MAX_SAMPLE).contains(&v[0]) {
                        c[i].sum += fixed(v[0]) as u128;
                        c[i].hits += 1;
                    }
                }
                ColumnTile::Count(c) => c[i] += u64::from(v[0] != 0.0),
                ColumnTile::Votes(c) => {
                    let id = v[0].to_bits();
                    if id != 0 {
                        add_object(&mut c[i], id, 1);
                    }
                }
                ColumnTile::Squares(c) => {
                    if let Some(q) = radiance {
                        for (s, q) in c[i].iter_mut().zip(q) {
                            *s += square(q);
                        }
                    }
                }
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

/// The most a sum of `held` samples of kind `sum` can be (per channel; for
/// a hit mean, the values' sum), for refusing forged files: a sum beyond
/// it could not have been made, and later additions could overflow.
pub fn most(sum: Sum, held: u64) -> u128 {
    let held = held as u128;
    match sum {
        Sum::Mean { lo, hi } => (held << 32) * lo.abs().max(hi.abs()).ceil() as u128,
        Sum::HitMean => held << 63,
        Sum::Squares => held << 94,
        Sum::Count | Sum::Votes => held,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A column of every kind reads back what it wrote (leaving the bytes
    /// after it), and refuses sums its samples cannot make: too large for
    /// one sample fewer (but squares), a forged first number, and for
    /// votes an id 0 and a cut plane; a negative albedo sum.
    #[test]
    fn columns_read_back_what_they_wrote_and_refuse_forged_sums() {
        let (pixels, held) = (2, 2);
        let mut sample = AovSample::NONE;
        sample.set(Aov::Albedo, [0.5, 1.0, 0.25]);
        sample.set(Aov::Normal, [-1.0, 0.5, 0.0]);
        sample.set(Aov::Depth, [2.0, 0.0, 0.0]);
        sample.set(Aov::Alpha, [1.0, 0.0, 0.0]);
        sample.set(Aov::ZDepth, [1.5, 0.0, 0.0]);
        sample.set(Aov::ObjectId, [f32::from_bits(3), 0.0, 0.0]);
        for aov in Aov::EVERY {
            let mut sums = AovSums::new(AovSet::of(&[aov]), pixels);
            let mut tiles = sums.tiles_mut(pixels, pixels);
            for _ in 0..held {
                tiles[0].add(0, &sample, Some([1 << 32; 3]));
            }
            drop(tiles);
            let column = &sums.columns[0].1;
            let mut bytes = Vec::new();
            column.write(&mut bytes);
            let data = bytes.len();
            bytes.extend([9, 9]);
            let (back, rest) = Column::read(aov, &bytes, pixels, held).unwrap();
            assert_eq!((&back, rest), (column, &[9u8, 9][..]), "{aov:?}");
            // (A sum of squares' bound is loose: 2⁹⁴ per sample.)
            let fewer = Column::read(aov, &bytes, pixels, held - 1);
            let loose = aov.def().sum == Sum::Squares;
            assert!(
                loose || matches!(fewer, Err(ReadError::TooLarge(0, _))),
                "{aov:?}: {fewer:?}"
            );
            let forged = |at: usize, value: &[u8]| {
                let mut b = bytes.clone();
                b[at..at + value.len()].copy_from_slice(value);
                Column::read(aov, &b, pixels, held).map(|_| ())
            };
            if aov.def().sum == Sum::Votes {
                let e = forged(4, &0u32.to_le_bytes());
                assert!(matches!(e, Err(ReadError::Invalid(0, _))), "{e:?}");
                let e = forged(8, &3u64.to_le_bytes());
                assert!(matches!(e, Err(ReadError::TooLarge(0, _))), "{e:?}");
                let e = Column::read(aov, &bytes[..data - 1], pixels, held);
                assert!(matches!(e, Err(ReadError::Truncated(_))), "{e:?}");
            } else {
                let e = forged(0, &(u128::MAX >> 1).to_le_bytes());
                assert!(
                    matches!(e, Err(ReadError::TooLarge(0, _))),
                    "{aov:?}: {e:?}"
                );
            }
            // A negative sum of a mean of values ≥ 0 (albedo), not of -1..1.
            if let Sum::Mean { lo, .. } = aov.def().sum {
                let e = forged(0, &(-1i128).to_le_bytes());
                assert_eq!(e.is_ok(), lo < 0.0, "{aov:?}: {e:?}");
            }
        }
    }
}
