//! The path queue: every live path's state, one plain column per field.

use crate::film::AovSample;
use crate::math::Vec3x8;
use crate::scene::aov::When;
use crate::scene::{Aov, AovSet};
use wide::f32x8;

/// In [`PathQueue::hit`]: the ray hit nothing.
pub const NO_HIT: u32 = crate::accel::triangle::NO_PRIM;

/// In [`PathQueue::hit`]: the path is finished and in the film; the next
/// [`PathQueue::compact`] drops it.
pub const RETIRED: u32 = u32::MAX - 1;

/// The state of a batch of paths in structure-of-arrays form; `P` is the
/// sampler's per-path state ([`crate::integrator::sampler::Sampler::Path`]).
///
/// Every column is plain old data (`bytemuck::Pod`).
///
/// Row `i < len()` of every column belongs to path `i`. Columns are
/// allocated once, for the batch size rounded up to a multiple of 8, so the
/// stages can load and store 8 rows at a time. The intersect stage fills
/// `t` and `hit`; the other columns are the path's state between bounces.
#[derive(Clone, Debug)]
pub struct PathQueue<P> {
    len: usize,
    /// Pixel index (row-major) the path's sample belongs to.
    pub pixel: Vec<u32>,
    /// The path's place in its numbers.
    pub sampler: Vec<P>,
    /// Ray origin, x/y/z columns.
    pub o: [Vec<f32>; 3],
    /// Unit ray direction, x/y/z columns.
    pub d: [Vec<f32>; 3],
    /// Throughput: the product of `f · cos θ / pdf` along the path, RGB.
    pub beta: [Vec<f32>; 3],
    /// Radiance gathered so far, RGB.
    pub radiance: [Vec<f32>; 3],
    /// The density the current ray's direction was drawn with (0 for a
    /// camera ray): what weighs emission it finds against light sampling.
    pub pdf: Vec<f32>,
    /// Distance to the closest hit (intersect stage output).
    pub t: Vec<f32>,
    /// Triangle hit, or [`NO_HIT`] (intersect stage output), or
    /// [`RETIRED`] (retire stage output).
    pub hit: Vec<u32>,
    /// The AOV columns, when the render records AOVs along the paths
    /// (albedo, normal or depth); `None` otherwise, and then they cost
    /// nothing.
    pub aov: Option<AovColumns>,
    /// Working memory of [`PathQueue::compact`]: the rows its moves fill
    /// and the rows they empty.
    moves: [Vec<u32>; 2],
}

/// The AOVs each path records on its way ([`crate::integrator::aov`]):
/// set by the *shade* stage ([`super::shade::record_aovs`]), added to the
/// film by *retire*. One column per AOV a path records (the variance is
/// the film's own).
#[derive(Clone, Debug)]
pub struct AovColumns {
    /// Whether some AOV is recorded at the first non-specular vertex
    /// ([`When::FirstNonSpecular`]).
    pub surface: bool,
    /// 1 while the path has met no non-specular vertex (those AOVs are
    /// still to be recorded), else 0.
    pub pending: Vec<u8>,
    /// Each recorded AOV, when it is recorded, and its value per row (its
    /// `none` until recorded).
    pub values: Vec<(Aov, When, Vec<[f32; 3]>)>,
}

impl AovColumns {
    fn with_rows(rows: usize, aovs: AovSet) -> Self {
        let recorded = aovs.iter().filter(|a| a.def().when != When::Radiance);
        Self {
            surface: aovs.iter().any(|a| a.def().when == When::FirstNonSpecular),
            pending: vec![0; rows],
            values: recorded
                .map(|a| (a, a.def().when, vec![a.def().none; rows]))
                .collect(),
        }
    }

    /// Rows `rows` start new paths: nothing recorded yet.
    pub fn reset(&mut self, rows: std::ops::Range<usize>) {
        self.pending[rows.clone()].fill(1);
        for (aov, _, col) in &mut self.values {
            col[rows.clone()].fill(aov.def().none);
        }
    }

    /// Path `i`'s AOVs, for the film.
    #[inline]
    pub fn sample(&self, i: usize) -> AovSample {
        let mut sample = AovSample::NONE;
        for (aov, _, col) in &self.values {
            sample.set(*aov, col[i]);
        }
        sample
    }

    #[inline]
    fn move_row(&mut self, from: usize, to: usize) {
        self.pending[to] = self.pending[from];
        for (_, _, col) in &mut self.values {
            col[to] = col[from];
        }
    }

    #[inline]
    fn swap_rows(&mut self, a: usize, b: usize) {
        self.pending.swap(a, b);
        for (_, _, col) in &mut self.values {
            col.swap(a, b);
        }
    }
}

impl<P: bytemuck::Pod> PathQueue<P> {
    /// An empty queue with room for `n` paths (rounded up to whole groups
    /// of 8). The float columns have 7 rows more, so that 8 rows can be
    /// loaded from any row (the *sort* stage starts a model's rows
    /// anywhere).
    pub fn with_capacity(n: usize) -> Self {
        let rows = n.div_ceil(8) * 8;
        let col = || vec![0.0f32; rows + 7];
        Self {
            len: 0,
            pixel: vec![0; rows],
            sampler: vec![P::zeroed(); rows],
            o: [col(), col(), col()],
            d: [col(), col(), col()],
            beta: [col(), col(), col()],
            radiance: [col(), col(), col()],
            pdf: col(),
            t: col(),
            hit: vec![NO_HIT; rows],
            aov: None,
            moves: [vec![0; rows], vec![0; rows]],
        }
    }

    /// [`with_capacity`](Self::with_capacity), with AOV columns when
    /// `aovs` asks for AOVs recorded along the paths (all but the
    /// variance, which needs none).
    pub fn with_aovs(n: usize, aovs: AovSet) -> Self {
        let mut q = Self::with_capacity(n);
        if aovs.iter().any(|a| a.def().when != When::Radiance) {
            q.aov = Some(AovColumns::with_rows(q.capacity(), aovs));
        }
        q
    }
}

impl<P> PathQueue<P> {
    /// Room in rows.
    pub fn capacity(&self) -> usize {
        self.pixel.len()
    }

    /// Number of paths.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the queue holds no path.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Set the number of paths (rows past it are free).
    pub fn set_len(&mut self, len: usize) {
        assert!(len <= self.capacity());
        self.len = len;
    }
}

impl<P: Copy> PathQueue<P> {
    /// Every row starts a path: throughput 1, no radiance yet, its ray
    /// drawn by no density (the pixel, numbers and camera ray are set
    /// apart).
    pub fn start_paths(&mut self) {
        let n = self.len;
        for c in 0..3 {
            self.beta[c][..n].fill(1.0);
            self.radiance[c][..n].fill(0.0);
        }
        self.pdf[..n].fill(0.0);
    }

    /// Copy path `from` into row `to` (the intersect outputs too).
    #[inline]
    pub fn move_row(&mut self, from: usize, to: usize) {
        self.pixel[to] = self.pixel[from];
        self.sampler[to] = self.sampler[from];
        for cols in [&mut self.o, &mut self.d, &mut self.beta, &mut self.radiance] {
            for col in cols.iter_mut() {
                col[to] = col[from];
            }
        }
        self.pdf[to] = self.pdf[from];
        self.t[to] = self.t[from];
        self.hit[to] = self.hit[from];
        if let Some(aov) = &mut self.aov {
            aov.move_row(from, to);
        }
    }

    /// Exchange paths `a` and `b` (the intersect outputs too).
    #[inline]
    pub fn swap_rows(&mut self, a: usize, b: usize) {
        self.pixel.swap(a, b);
        self.sampler.swap(a, b);
        for cols in [&mut self.o, &mut self.d, &mut self.beta, &mut self.radiance] {
            for col in cols.iter_mut() {
                col.swap(a, b);
            }
        }
        self.pdf.swap(a, b);
        self.t.swap(a, b);
        self.hit.swap(a, b);
        if let Some(aov) = &mut self.aov {
            aov.swap_rows(a, b);
        }
    }

    /// Path `i`'s AOVs ([`AovSample::NONE`] without AOV columns).
    #[inline]
    pub fn aov_sample(&self, i: usize) -> AovSample {
        self.aov.as_ref().map_or(AovSample::NONE, |a| a.sample(i))
    }

    /// Drop the [`RETIRED`] rows. With `live` rows staying, each retired
    /// row below `live` is filled with a live row at or above it, in
    /// order, so only retired rows cost a move. Both lists are written
    /// without a branch per row (each row written at the list's end, which
    /// moves on when the row belongs to it). The order of the paths
    /// changes, which changes nothing else (each path has its own numbers,
    /// and the film's sums are exact).
    pub fn compact(&mut self) {
        let n = self.len;
        let hit = &self.hit[..n];
        let live = n - hit.iter().filter(|&&h| h == RETIRED).count();
        let [to, from] = &mut self.moves;
        let mut holes = 0;
        for (r, &h) in hit[..live].iter().enumerate() {
            to[holes] = r as u32;
            holes += usize::from(h == RETIRED);
        }
        let mut lives = 0;
        for (r, &h) in hit.iter().enumerate().skip(live) {
            from[lives] = r as u32;
            lives += usize::from(h != RETIRED);
        }
        debug_assert_eq!(holes, lives);
        for k in 0..holes {
            let (to, from) = (self.moves[0][k], self.moves[1][k]);
            self.move_row(from as usize, to as usize);
        }
        self.len = live;
    }
}

/// The rows `r` of a column where `pred(column[r])`, in order, found eight
/// at a time: a mask of eight tests (no branch per row), then its set
/// bits.
#[inline(always)]
pub fn rows_where<T>(column: &[T], pred: impl Fn(&T) -> bool) -> impl Iterator<Item = usize> {
    let groups = column.chunks(8).enumerate();
    groups.flat_map(move |(g, rows)| SetBits(mask_8(rows, &pred)).map(move |l| 8 * g + l))
}

/// The tests of at most eight rows as a mask: bit `l` is `pred(&rows[l])`.
#[inline(always)]
pub fn mask_8<T>(rows: &[T], pred: impl Fn(&T) -> bool) -> u8 {
    (rows.iter().enumerate()).fold(0, |m, (l, x)| m | u8::from(pred(x)) << l)
}

/// The set bits of a mask, lowest first.
pub struct SetBits(pub u8);

impl Iterator for SetBits {
    type Item = usize;

    #[inline(always)]
    fn next(&mut self) -> Option<usize> {
        if self.0 == 0 {
            return None;
        }
        let l = self.0.trailing_zeros() as usize;
        self.0 &= self.0 - 1;
        Some(l)
    }
}

/// Rows `i..i + 8` of a column (in bounds: columns are multiples of 8).
#[inline(always)]
pub fn load8(col: &[f32], i: usize) -> f32x8 {
    let rows: [f32; 8] = col[i..i + 8].try_into().expect("8 rows");
    f32x8::from(rows)
}

/// Store `v` in rows `i..i + 8` of a column.
#[inline(always)]
pub fn store8(col: &mut [f32], i: usize, v: f32x8) {
    col[i..i + 8].copy_from_slice(&v.to_array());
}

/// Store the first `lanes` of eight 3-vectors in rows `i..i + lanes` of
/// three columns.
#[inline(always)]
pub fn store3(cols: &mut [Vec<f32>; 3], i: usize, v: Vec3x8, lanes: usize) {
    store_lanes(&mut cols[0], i, v.x, lanes);
    store_lanes(&mut cols[1], i, v.y, lanes);
    store_lanes(&mut cols[2], i, v.z, lanes);
}

/// Store the first `lanes` of `v` in rows `i..i + lanes` (all eight at
/// once when they are all live: the common case).
#[inline(always)]
pub fn store_lanes(col: &mut [f32], i: usize, v: f32x8, lanes: usize) {
    if lanes == 8 {
        store8(col, i, v);
    } else {
        col[i..i + lanes].copy_from_slice(&v.to_array()[..lanes]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A queue of `n` paths, path `i` marked by `pixel = i` and `t = i`,
    /// and retired where `retired(i)`.
    fn queue(n: usize, retired: impl Fn(usize) -> bool) -> PathQueue<u64> {
        let mut q = PathQueue::with_capacity(n);
        q.set_len(n);
        for i in 0..n {
            q.pixel[i] = i as u32;
            q.sampler[i] = 1000 + i as u64;
            q.t[i] = i as f32;
            q.o[2][i] = -(i as f32);
            q.hit[i] = if retired(i) { RETIRED } else { i as u32 };
        }
        q
    }

    /// Compaction keeps exactly the live paths, each row whole.
    fn check(n: usize, retired: impl Fn(usize) -> bool + Copy) {
        let mut q = queue(n, retired);
        q.compact();
        let mut kept: Vec<u32> = q.pixel[..q.len()].to_vec();
        kept.sort_unstable();
        let want: Vec<u32> = (0..n).filter(|&i| !retired(i)).map(|i| i as u32).collect();
        assert_eq!(kept, want, "n = {n}");
        for r in 0..q.len() {
            let i = q.pixel[r] as usize;
            assert_eq!(q.sampler[r], 1000 + i as u64);
            assert_eq!(q.t[r], i as f32);
            assert_eq!(q.o[2][r], -(i as f32));
            assert_eq!(q.hit[r], i as u32);
        }
    }

    #[test]
    fn compaction_keeps_exactly_the_live_rows() {
        for n in [0, 1, 2, 7, 8, 9, 64, 100] {
            check(n, |_| false);
            check(n, |_| true);
            check(n, |i| i % 2 == 0);
            check(n, |i| i % 2 == 1);
            check(n, |i| i % 3 == 0);
            check(n, |i| i < n / 2);
            check(n, |i| i >= n / 2);
        }
    }

    /// Compaction and swaps move the AOV columns with their rows.
    #[test]
    fn aov_columns_move_with_their_rows() {
        for n in [1, 7, 9, 64, 100] {
            let mut q = queue(n, |i| i % 3 == 1);
            let mut with = PathQueue::<u64>::with_aovs(n, AovSet::ALL);
            assert!(
                PathQueue::<u64>::with_aovs(n, AovSet::of(&[Aov::Variance]))
                    .aov
                    .is_none()
            );
            with.set_len(n);
            (with.pixel, with.hit) = (q.pixel.clone(), q.hit.clone());
            let aov = with.aov.as_mut().unwrap();
            aov.reset(0..n);
            for i in 0..n {
                for (a, _, col) in &mut aov.values {
                    col[i] = [*a as usize as f32, i as f32, -(i as f32)];
                }
                aov.pending[i] = (i % 2) as u8;
            }
            with.swap_rows(0, n - 1);
            with.swap_rows(0, n - 1);
            with.compact();
            q.compact();
            assert_eq!(with.len(), q.len());
            for r in 0..with.len() {
                let i = with.pixel[r] as usize;
                let a = with.aov_sample(r);
                for aov in [Aov::Albedo, Aov::Normal, Aov::Depth] {
                    assert_eq!(a.get(aov), [aov as usize as f32, i as f32, -(i as f32)]);
                }
                assert_eq!(with.aov.as_ref().unwrap().pending[r], (i % 2) as u8);
            }
        }
    }

    #[test]
    fn capacity_is_padded_to_whole_lanes() {
        for (n, rows) in [(1, 8), (8, 8), (9, 16), (4096, 4096)] {
            assert_eq!(PathQueue::<u64>::with_capacity(n).capacity(), rows);
        }
    }
}
