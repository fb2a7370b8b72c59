//! The film: per-pixel sums of radiance samples, kept exactly.
//!
//! Each sample's radiance is rounded once to a fixed-point integer
//! (2⁻³² units, [`FIXED_POINT_SCALE`]) and summed in `u128`. Integer sums do
//! not depend on the order of addition, so a film is the same bit for bit
//! however its samples were split — across threads, ray batches, sample
//! passes, checkpoints or cluster shards — and merging partial films is
//! exact. A sample that is NaN, infinite, negative or too large to represent
//! (≥ 2³¹) is not added; it is counted in [`Film::invalid_samples`] and
//! reported, never folded into the image silently.
//!
//! A film may also hold the sums of auxiliary outputs (AOVs: albedo,
//! normal, depth, variance), in the same fixed point ([`aov`]).

pub mod aov;
pub mod ranges;
pub mod wtacc;

pub use aov::{AovSample, AovSums, AovTile};
pub use wtacc::{AccMeta, WtaccError};

use crate::scene::{Aov, AovSet};
use glam::Vec3;
use std::ops::Range;
use wide::{f32x8, u32x8, u64x4};

/// Fixed-point units per unit of radiance.
pub const FIXED_POINT_SCALE: f64 = 4_294_967_296.0;
/// Samples at or above this radiance are refused as invalid.
pub const MAX_SAMPLE: f32 = 2_147_483_648.0;

/// The fixed-point sums of one pixel's samples, R, G, B.
pub type PixelSum = [u128; 3];

/// Add one sample to a pixel's sums. Returns false (and adds nothing) for an
/// invalid sample: NaN, infinite, negative or ≥ [`MAX_SAMPLE`].
#[inline]
pub fn accumulate(sum: &mut PixelSum, rgb: Vec3) -> bool {
    let Some(q) = to_fixed(rgb) else {
        return false;
    };
    accumulate_fixed(sum, q);
    true
}

/// Add a valid sample's fixed-point value ([`to_fixed`]) to a pixel's sums.
#[inline(always)]
pub fn accumulate_fixed(sum: &mut PixelSum, q: [u64; 3]) {
    for (s, q) in sum.iter_mut().zip(q) {
        *s += q as u128;
    }
}

/// A radiance sample in fixed point, as [`accumulate`] adds it: `None`
/// for an invalid sample (NaN, infinite, negative or ≥ [`MAX_SAMPLE`]).
#[inline(always)]
pub fn to_fixed(rgb: Vec3) -> Option<[u64; 3]> {
    let c = rgb.to_array();
    // `contains` is false for NaN as well.
    if c.iter().any(|x| !(0.0..MAX_SAMPLE).contains(x)) {
        return None;
    }
    let [r, g, b] = c;
    Some([fixed_of_valid(r), fixed_of_valid(g), fixed_of_valid(b)])
}

/// [`to_fixed`] of eight samples, one per lane of each channel: the
/// fixed-point values (lane `l` of channel `c` is the `c`-th value of
/// sample `l`; anything for an invalid sample) and the mask of the valid
/// samples (bit `l` for sample `l`). Written to compile to vector
/// instructions: the film's adds at the end of every path are a few
/// instructions each.
#[inline(always)]
pub fn to_fixed_8(rgb: [f32x8; 3]) -> ([[u64; 8]; 3], u8) {
    let ok = |x: f32x8| x.simd_ge(f32x8::ZERO) & x.simd_lt(f32x8::splat(MAX_SAMPLE));
    let valid = ok(rgb[0]) & ok(rgb[1]) & ok(rgb[2]);
    let [r, g, b] = rgb;
    (
        [fixed_8(r), fixed_8(g), fixed_8(b)],
        valid.to_bitmask() as u8,
    )
}

/// [`fixed_of_valid`] of eight lanes: the exponents' shifts in 32-bit
/// lanes, the significands shifted in 64-bit ones.
#[inline(always)]
fn fixed_8(x: f32x8) -> [u64; 8] {
    let bits = bytemuck::cast::<f32x8, u32x8>(x) & u32x8::splat(0x7fff_ffff);
    let e: u32x8 = bits >> 23;
    let implicit = e.simd_gt(u32x8::ZERO) & u32x8::splat(1 << 23);
    let m = (bits & u32x8::splat(0x7f_ffff)) | implicit;
    let up = e.max(u32x8::splat(118)).min(u32x8::splat(157)) - u32x8::splat(118);
    let s = (u32x8::splat(118) - e.min(u32x8::splat(118))).min(u32x8::splat(25));
    let half = (u32x8::ONE << s) >> 1;
    // (No `array::map` here: it is not always inlined.)
    let half_of = |v: u32x8, k: usize| {
        let v = v.as_array();
        u64x4::from([v[k], v[k + 1], v[k + 2], v[k + 3]].map(u64::from))
    };
    let q = |k| ((half_of(m, k) << half_of(up, k)) + half_of(half, k)) >> half_of(s, k);
    bytemuck::cast([q(0), q(4)])
}

/// `x · 2³²` rounded to the nearest integer, halves away from zero — the
/// value of `(x as f64 * FIXED_POINT_SCALE).round()`, which is exact
/// before it rounds — for `0 ≤ x <` [`MAX_SAMPLE`], computed from the
/// bits of `x` with integer shifts alone (so that eight lanes compile to
/// vector shifts; `f64` to `i64` has no AVX2 instruction). `x` is
/// `m · 2^(e − 150)` (`m` the significand with its implicit bit, `e` the
/// biased exponent), so `x · 2³² = m · 2^(e − 118)`: `m` shifted left
/// when `e ≥ 118` (less than 2⁶³ below 2³¹), else `m / 2^s` rounded, with
/// `s = 118 − e`: `(m + 2^(s−1)) >> s`, which is 0 for every `s ≥ 25`
/// (`m < 2²⁴`), so `s` is capped there.
#[inline(always)]
fn fixed_of_valid(x: f32) -> u64 {
    // (-0 is valid: its sign bit goes.)
    let bits = x.to_bits() & 0x7fff_ffff;
    let e = bits >> 23;
    let m = (bits & 0x7f_ffff) as u64 | if e > 0 { 1 << 23 } else { 0 };
    let up = m << (e.clamp(118, 157) - 118);
    let s = 118u32.saturating_sub(e).clamp(1, 25);
    let down = (m + (1 << (s - 1))) >> s;
    if e >= 118 { up } else { down }
}

/// Add one sample to a pixel's sums and its AOV sums (`aovs`, the pixel's
/// index `i` in them): [`accumulate`], and the AOVs present in `aovs`
/// (the square of the radiance only when it is valid). Returns false for
/// an invalid radiance sample, whose radiance and square add nothing (its
/// other AOVs are added: they are valid whatever the radiance).
#[inline]
pub fn accumulate_with_aovs(
    sum: &mut PixelSum,
    (aovs, i): (&mut AovTile<'_>, usize),
    rgb: Vec3,
    aov: &AovSample,
) -> bool {
    let q = to_fixed(rgb);
    if let Some(q) = q {
        accumulate_fixed(sum, q);
    }
    aovs.add(i, aov, q);
    q.is_some()
}

/// An image being accumulated: sums of the samples of some sample ranges.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major per-pixel sums, row 0 at the top.
    pub sums: Vec<PixelSum>,
    /// The sample indices every pixel holds, sorted and disjoint.
    pub ranges: Vec<Range<u32>>,
    /// Samples refused as NaN, infinite, negative or too large.
    pub invalid_samples: u64,
    /// The sums of the AOVs the film holds (none by default).
    pub aov: AovSums,
    /// How many samples each pixel holds, where that differs from pixel
    /// to pixel (an adaptive render, [`crate::render::Adaptive`]: pixel
    /// `i` holds samples `0..counts[i]`, and `ranges` the samples every
    /// pixel holds); `None`: every pixel holds `ranges`.
    pub counts: Option<Vec<u32>>,
}

/// How many samples the pixels of a film hold: as many each, or each its
/// own count.
#[derive(Clone, Copy, Debug)]
pub enum Samples<'a> {
    /// Every pixel holds this many.
    Every(u64),
    /// Pixel `i` holds `counts[i]`.
    Each(&'a [u32]),
}

impl Samples<'_> {
    /// How many samples pixel `i` holds.
    #[inline]
    pub fn of(&self, i: usize) -> u64 {
        match self {
            Samples::Every(n) => *n,
            Samples::Each(c) => u64::from(c[i]),
        }
    }
}

impl Film {
    /// An empty film, without AOVs.
    pub fn new(width: u32, height: u32) -> Self {
        Self::with_aovs(width, height, AovSet::NONE)
    }

    /// An empty film that also accumulates the AOVs `aovs`.
    pub fn with_aovs(width: u32, height: u32, aovs: AovSet) -> Self {
        let pixels = width as usize * height as usize;
        Self {
            width,
            height,
            sums: vec![[0; 3]; pixels],
            ranges: Vec::new(),
            invalid_samples: 0,
            aov: AovSums::new(aovs, pixels),
            counts: None,
        }
    }

    /// The AOVs this film holds.
    pub fn aovs(&self) -> AovSet {
        self.aov.set
    }

    /// The images of the AOVs this film holds, in canonical order
    /// ([`Aov::ALL`]; see [`aov`] for what each pixel is).
    pub fn aov_images(&self) -> Vec<(Aov, Vec<[f32; 3]>)> {
        self.aov.images(self.samples(), &self.sums)
    }

    /// How many samples every pixel holds (at least: an adaptive render's
    /// pixels may hold more, [`samples`](Self::samples)).
    pub fn samples_per_pixel(&self) -> u64 {
        self.ranges.iter().map(|r| (r.end - r.start) as u64).sum()
    }

    /// How many samples each pixel holds.
    pub fn samples(&self) -> Samples<'_> {
        match &self.counts {
            Some(c) => Samples::Each(c),
            None => Samples::Every(self.samples_per_pixel()),
        }
    }

    /// Record that every pixel now also holds the samples in `range`.
    /// Adjacent ranges are joined. Panics if `range` overlaps what is held.
    pub fn add_range(&mut self, range: Range<u32>) {
        if range.is_empty() {
            return;
        }
        // The first held range that ends after `range` starts: the only one
        // it can overlap (held ranges are sorted and disjoint).
        let at = self.ranges.partition_point(|r| r.end <= range.start);
        assert!(
            self.ranges.get(at).is_none_or(|r| range.end <= r.start),
            "sample range {range:?} overlaps {:?}",
            self.ranges
        );
        self.ranges.insert(at, range);
        // Join with the next range, then with the previous one.
        if let Some(next) = self.ranges.get(at + 1).cloned()
            && self.ranges[at].end == next.start
        {
            self.ranges[at].end = next.end;
            self.ranges.remove(at + 1);
        }
        if at > 0 && self.ranges[at - 1].end == self.ranges[at].start {
            self.ranges[at - 1].end = self.ranges[at].end;
            self.ranges.remove(at);
        }
    }

    /// The mean radiance of every pixel, row-major, as linear RGB `f32`.
    pub fn to_rgb(&self) -> Vec<[f32; 3]> {
        let samples = self.samples();
        (self.sums.iter().enumerate())
            .map(|(i, s)| {
                let n = samples.of(i).max(1) as f64 * FIXED_POINT_SCALE;
                s.map(|c| (c as f64 / n) as f32)
            })
            .collect()
    }

    /// Add another film's samples to this one: its sums (AOVs too), its
    /// sample ranges and its invalid-sample count. Exact, like every film
    /// sum: merging the films of disjoint sample ranges gives the same
    /// film, bit for bit, as rendering all of them into one. Refuses
    /// (changing nothing) a film of another size, one of other AOVs, or
    /// one holding a sample index this film already holds.
    pub fn merge(&mut self, other: &Film) -> Result<(), MergeError> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(MergeError::Size {
                theirs: (other.width, other.height),
                ours: (self.width, self.height),
            });
        }
        if self.aovs() != other.aovs() {
            return Err(MergeError::Aovs {
                theirs: other.aovs(),
                ours: self.aovs(),
            });
        }
        if self.counts.is_some() || other.counts.is_some() {
            return Err(MergeError::Adaptive);
        }
        if let Some((theirs, ours)) = ranges::first_overlap(&other.ranges, &self.ranges) {
            return Err(MergeError::Overlap { theirs, ours });
        }
        for (a, b) in self.sums.iter_mut().zip(&other.sums) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
        self.aov.add(&other.aov);
        let all: Vec<[u32; 2]> = self
            .ranges
            .iter()
            .chain(&other.ranges)
            .map(|r| [r.start, r.end])
            .collect();
        self.ranges = ranges::sorted_disjoint(&all).expect("checked disjoint above");
        self.invalid_samples = self.invalid_samples.saturating_add(other.invalid_samples);
        Ok(())
    }
}

/// Why [`Film::merge`] refused a film.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MergeError {
    /// The films are of different sizes.
    #[error("image is {}x{}, expected {}x{}", theirs.0, theirs.1, ours.0, ours.1)]
    Size {
        /// The refused film's width and height.
        theirs: (u32, u32),
        /// The receiving film's width and height.
        ours: (u32, u32),
    },
    /// The films hold different AOVs.
    #[error(
        "holds AOVs {theirs}, expected {ours} (films of different --aov sets cannot be combined)"
    )]
    Aovs {
        /// The refused film's AOVs.
        theirs: AovSet,
        /// The receiving film's AOVs.
        ours: AovSet,
    },
    /// Both films hold some of the same sample indices.
    #[error("samples {}..{} overlap samples {}..{} already merged", theirs.start, theirs.end, ours.start, ours.end)]
    Overlap {
        /// A range of the refused film.
        theirs: Range<u32>,
        /// The range of the receiving film it overlaps.
        ours: Range<u32>,
    },
    /// A film of an adaptive render, whose pixels hold samples of their
    /// own.
    #[error("an adaptive render's film (pixels of their own sample counts) cannot be combined")]
    Adaptive,
}

#[cfg(test)]
// Films hold lists of sample ranges; a list of one range is what is meant.
#[allow(clippy::single_range_in_vec_init)]
mod tests {
    use super::*;

    /// The fixed-point value from the bits is the rounded `f64` product,
    /// for every valid `f32` there is (1.3 billion, on all threads, and -0);
    /// and
    /// eight lanes at a time give the scalar values and validity.
    #[test]
    fn fixed_point_values_are_the_rounded_products_for_every_float() {
        use rayon::prelude::*;
        let end = MAX_SAMPLE.to_bits();
        let wrong = (0..end.div_ceil(1 << 16))
            .into_par_iter()
            .map(|hi| {
                let bits: Vec<u32> = ((hi << 16)..((hi + 1) << 16).min(end)).collect();
                let mut wrong = 0;
                for b in bits.chunks(8) {
                    let x: [f32; 8] = std::array::from_fn(|l| f32::from_bits(b[l % b.len()]));
                    let lanes = fixed_8(f32x8::from(x));
                    for l in 0..8 {
                        let want = (x[l] as f64 * FIXED_POINT_SCALE).round() as u64;
                        wrong += usize::from(fixed_of_valid(x[l]) != want || lanes[l] != want);
                    }
                }
                wrong
            })
            .sum::<usize>();
        assert_eq!(wrong, 0);
        let lanes = [
            [0.0, 1e-10, 2.3283064e-10, 0.5, 1.0, 3.75, 2.1e9, 1e-45],
            [
                f32::NAN,
                -0.0,
                -1.0,
                f32::INFINITY,
                MAX_SAMPLE,
                0.25,
                7.0,
                1e30,
            ],
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0],
        ];
        let (q, mask) = to_fixed_8(lanes.map(f32x8::from));
        for l in 0..8 {
            let rgb = Vec3::new(lanes[0][l], lanes[1][l], lanes[2][l]);
            let want = to_fixed(rgb);
            assert_eq!(mask >> l & 1 == 1, want.is_some(), "lane {l}");
            if let Some(want) = want {
                assert_eq!([q[0][l], q[1][l], q[2][l]], want, "lane {l}");
            }
        }
        assert_eq!(mask, 0b0110_0010);
        assert_eq!(fixed_of_valid(-0.0), 0);
    }

    #[test]
    fn invalid_samples_are_refused() {
        let mut s = [0; 3];
        for bad in [f32::NAN, f32::INFINITY, -1.0, MAX_SAMPLE] {
            assert!(!accumulate(&mut s, Vec3::new(0.5, bad, 0.5)));
        }
        assert_eq!(s, [0; 3]);
        assert!(accumulate(&mut s, Vec3::new(0.5, 1.0, 0.0)));
        assert_eq!(s, [1 << 31, 1 << 32, 0]);
    }

    /// The squares the variance sums are those of the very values the
    /// radiance sums, rounded once; the AOVs' sums add up like the
    /// radiance's.
    #[test]
    fn aov_sums_add_the_fixed_point_values() {
        let mut film = Film::with_aovs(2, 1, AovSet::EVERY);
        let mut tiles = film.aov.tiles_mut(1, 2);
        assert_eq!(tiles.len(), 2);
        let mut s = [0; 3];
        let mut sample = AovSample::NONE;
        sample.set(Aov::Albedo, [0.5, 2.0, -1.0]);
        sample.set(Aov::Normal, [-1.0, 0.25, 1.5]);
        sample.set(Aov::Depth, [3.0, 0.0, 0.0]);
        sample.set(Aov::Alpha, [1.0, 0.0, 0.0]);
        sample.set(Aov::ZDepth, [2.5, 0.0, 0.0]);
        sample.set(Aov::ObjectId, [f32::from_bits(7), 0.0, 0.0]);
        assert!(accumulate_with_aovs(
            &mut s,
            (&mut tiles[1], 0),
            Vec3::new(3.0, 0.5, 0.0),
            &sample
        ));
        assert!(!accumulate_with_aovs(
            &mut s,
            (&mut tiles[1], 0),
            Vec3::NAN,
            &AovSample::NONE
        ));
        drop(tiles);
        let q = 1u128 << 32;
        assert_eq!(s, [3 * q, q / 2, 0]);
        use aov::{Column, DepthSum};
        let column = |a| film.aov.column(a).unwrap().clone();
        let q = q as i128;
        let mean = |v: [i128; 3]| Column::Mean(vec![[0; 3], v]);
        assert_eq!(
            column(Aov::Albedo),
            mean([q / 2, q, 0]),
            "clamped to [0, 1]"
        );
        assert_eq!(
            column(Aov::Normal),
            mean([-q, q / 4, q]),
            "clamped to [-1, 1]"
        );
        let hits = |sum: i128| {
            Column::HitMean(vec![
                DepthSum::default(),
                DepthSum {
                    sum: sum as u128,
                    hits: 1,
                },
            ])
        };
        assert_eq!(column(Aov::Depth), hits(3 * q));
        assert_eq!(column(Aov::ZDepth), hits(5 * q / 2));
        let q = q as u128;
        assert_eq!(
            column(Aov::Variance),
            Column::Squares(vec![[0; 3], [9 * q, q / 4, 0]])
        );
        assert_eq!(
            column(Aov::Alpha),
            Column::Count(vec![0, 1]),
            "one hit, one miss"
        );
        assert_eq!(
            column(Aov::ObjectId),
            Column::Votes(vec![vec![], vec![(7, 1)]])
        );
        // (2^63 - 1)^2 / 2^32 = 2^94 - 2^32 + 2^-32, rounded: no overflow.
        assert_eq!(aov::square(u64::MAX >> 1), (1 << 94) - q);
        assert_eq!(aov::square(3 << 31), 9 << 30); // 1.5^2 = 2.25, exactly
    }

    #[test]
    fn sums_do_not_depend_on_order() {
        let xs: Vec<f32> = (0..1000)
            .map(|i| (i as f32 * 0.7311).sin().abs() * 13.0)
            .collect();
        let (mut a, mut b) = ([0; 3], [0; 3]);
        for &x in &xs {
            accumulate(&mut a, Vec3::splat(x));
        }
        for &x in xs.iter().rev() {
            accumulate(&mut b, Vec3::splat(x));
        }
        assert_eq!(a, b);
    }

    #[test]
    fn ranges_join_and_count() {
        let mut f = Film::new(1, 1);
        f.add_range(4..8);
        f.add_range(0..4);
        f.add_range(10..12);
        assert_eq!(f.ranges, vec![0..8, 10..12]);
        assert_eq!(f.samples_per_pixel(), 10);
    }

    fn film_of(ranges: &[Range<u32>], value: u128) -> Film {
        let mut f = Film::new(2, 1);
        f.sums = vec![[value, value + 1, value + 2], [value * 3, 0, 1]];
        for r in ranges {
            f.add_range(r.clone());
        }
        f
    }

    #[test]
    fn merge_adds_sums_ranges_and_invalid_counts() {
        let mut a = film_of(&[0..4], 10);
        let mut b = film_of(&[4..6, 8..9], 7);
        b.invalid_samples = 2;
        a.merge(&b).unwrap();
        assert_eq!(a.sums, vec![[17, 19, 21], [51, 0, 2]]);
        assert_eq!(a.ranges, vec![0..6, 8..9]);
        assert_eq!(a.invalid_samples, 2);
    }

    #[test]
    fn merge_refuses_overlaps_and_other_sizes_changing_nothing() {
        let mut a = film_of(&[0..4, 8..12], 10);
        let before = a.clone();
        assert_eq!(
            a.merge(&film_of(&[4..9], 1)),
            Err(MergeError::Overlap {
                theirs: 4..9,
                ours: 8..12
            })
        );
        assert!(matches!(
            a.merge(&Film::new(1, 2)),
            Err(MergeError::Size { .. })
        ));
        let depth = AovSet::of(&[Aov::Depth]);
        assert_eq!(
            a.merge(&Film::with_aovs(2, 1, depth)),
            Err(MergeError::Aovs {
                theirs: depth,
                ours: AovSet::NONE
            })
        );
        assert_eq!(a, before);
    }

    #[test]
    fn meta_round_trips_and_plain_saves_are_unchanged() {
        let dir = std::env::temp_dir().join(format!("wavetrace-film-meta-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = film_of(&[16..32], 5);
        let meta = AccMeta {
            settings_hash: 0xabc,
            spp: Some(64),
            shard: Some((1, 4)),
        };
        let (with, plain) = (dir.join("with.wtacc"), dir.join("plain.wtacc"));
        f.save_with_meta(&with, &meta).unwrap();
        f.save(&plain, 0xabc).unwrap();
        assert_eq!(
            Film::load_with_meta(&with, Some(0xabc)).unwrap(),
            (f.clone(), meta)
        );
        let (g, plain_meta) = Film::load_with_meta(&plain, None).unwrap();
        assert_eq!((g, plain_meta), (f.clone(), AccMeta::new(0xabc)));
        // A file without the new fields has none of their keys in its header.
        let bytes = std::fs::read(&plain).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        assert!(!text.contains("\"spp\"") && !text.contains("\"shard\""));
        // A range beyond the header's spp is refused as corrupt.
        let bad = AccMeta {
            spp: Some(20),
            ..meta
        };
        f.save_with_meta(&with, &bad).unwrap();
        let e = Film::load_with_meta(&with, None).unwrap_err().to_string();
        assert!(e.contains("with.wtacc") && e.contains("20-sample"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    #[should_panic(expected = "overlaps")]
    fn overlapping_range_panics() {
        let mut f = Film::new(1, 1);
        f.add_range(0..4);
        f.add_range(3..5);
    }
}
