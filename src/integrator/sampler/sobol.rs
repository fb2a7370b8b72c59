//! Owen-scrambled Sobol points with hash-based nested scrambling
//! (Burley 2020), by *global* sample index, padded in two-dimensional
//! groups.
//!
//! # What a number is
//!
//! Path dimensions come in groups of [`GROUP`] = 2: dimensions `2g` and
//! `2g + 1` are the two coordinates of one 2D Sobol point. For sample
//! `i` of pixel `p` under seed `seed`, dimension `d = 2g + j` is
//!
//! 1. the *shuffled index* `i' = N(i, h(seed, p, g))`: a nested uniform
//!    (Owen) scramble of the index's bits, the same for both coordinates of
//!    a group and different for every group and pixel;
//! 2. the Sobol point's coordinate `x = C_j · i'` over GF(2), with `C_j`
//!    the generator matrix of Sobol dimension `j` ([`GENERATORS`]);
//! 3. Owen-scrambled: `N(x, h'(seed, p, d))`, its own seed per dimension;
//! 4. its top 24 bits as an `f32` in `[0, 1)` (never 1.0).
//!
//! `N(v, s)` is a nested uniform scramble in base 2: bit `k` of `v`
//! (counted from the most significant) is flipped or not by a hash of `s`
//! and the bits above it. Done on the bit-reversed word it is a
//! Laine–Karras permutation, which needs only carries (additions and
//! multiplications) going up: [`owen_reversed`].
//!
//! # Why it works
//!
//! - Every number is a pure function of `(seed, pixel, sample index,
//!   dimension)`: there is no sample count in it, so sample passes,
//!   resumes and farm shards by sample range make the same image to the
//!   bit. Integer arithmetic only, up to the final conversion.
//! - Scrambling the index this way maps every aligned block of `2^m`
//!   indices `[k 2^m, (k+1) 2^m)` one-to-one onto an aligned block of
//!   `2^m` indices (the index's bits from `m` up are scrambled by
//!   themselves only). The first two Sobol dimensions are a
//!   (0,2)-sequence: every aligned block of `2^m` of its points is a
//!   (0,m,2)-net. So in every pixel, for every group, the samples
//!   `[k 2^m, (k+1) 2^m)` — the first `2^m` ones, or a later pass or shard
//!   of that size — form a (0,m,2)-net: every elementary interval of area
//!   `2^-m` holds one point. The Owen scramble of the coordinates keeps
//!   nets as nets and makes each point uniform within its stratum.
//! - Each group has its own index shuffle, so different groups are paired
//!   at random (Burley's *padding*): any number of dimensions works (a
//!   path may take thousands), with no table of thousands of Sobol
//!   dimensions and none of the correlations of high Sobol dimensions.
//!
//! To have a 2D draw stratified jointly, start it at an even dimension: a
//! pair straddling two groups (`2g + 1`, `2g + 2`) is two independent
//! stratified 1D draws, which is still unbiased.
//!
//! The price of needing no sample count: a shuffle that keeps every
//! power-of-two prefix a net must be a nested permutation, and nested
//! permutations pair two groups' strata less randomly than a uniformly
//! random permutation would. Over a pixel's first 256 samples, `n r²` (`r`
//! the correlation of two dimensions of different groups) averages 1.58
//! where independent numbers give 1.00 — the same with a true per-bit
//! hashed Owen shuffle, so it is the scheme's, not the hash's. A purely
//! multiplicative coupling of two groups then has about 1.6 times the
//! variance of independent sampling; everything the strata capture has
//! far less. (pbrt-v4's `PaddedSobolSampler` pairs by a random permutation
//! of `[0, spp)` instead, which needs the sample count.)
//!
//! Not here: pbrt-v4's `ZSobolSampler` (Morton-ordered indices across
//! pixels for screen-space blue noise). Its blue noise comes from putting
//! `log2(spp)` sample bits below each pixel's Morton code, so that the
//! blocks of neighbouring pixels together form larger nets; that block
//! size is the sample count. A fixed block size larger than the sample
//! count keeps the per-pixel nets but loses the blue noise; putting the
//! pixel bits below the sample bits instead keeps every pixel's samples in
//! one Sobol stratum of width `1/pixels` (no per-pixel convergence at
//! all). Either way a number would depend on the sample count, or the
//! method would lose what it is for.
//!
//! # Sources
//!
//! - B. Burley, "Practical Hash-based Owen Scrambling", *Journal of
//!   Computer Graphics Techniques* 9(4), 2020: the shuffled, scrambled,
//!   padded Sobol sampler, the scrambling by a hash on the reversed bits.
//! - S. Laine and T. Karras, "Stratified Sampling for Stochastic
//!   Transparency", EGSR 2011: the hash permutation.
//! - N. Vegdahl, "Building a Better LK Hash" (psychopath.io, 2021): the
//!   hash of [`owen_reversed`], stronger than Burley's; the one of pbrt-v4's
//!   `FastOwenScrambler` (M. Pharr, W. Jakob, G. Humphreys, *Physically
//!   Based Rendering*, 4th ed., 2023, `util/lowdiscrepancy.h`) and of
//!   Cycles.
//! - S. Joe and F. Y. Kuo, "Constructing Sobol sequences with better
//!   two-dimensional projections", SIAM J. Sci. Comput. 30 (2008), and their
//!   direction numbers `new-joe-kuo-6.21201`: the first two dimensions,
//!   [`JOE_KUO`].
//! - I. M. Sobol', "On the distribution of points in a cube and the
//!   approximate evaluation of integrals", USSR Comput. Math. Math. Phys. 7
//!   (1967).
//! - A. B. Owen, "Randomly permuted (t,m,s)-nets and (t,s)-sequences",
//!   1995: nested uniform scrambling.

use super::{Sampler, splitmix64};
use wide::{f32x8, i32x8, u32x8};

/// Path dimensions per Sobol point: dimensions `2g` and `2g + 1` are the
/// two coordinates of point `g`.
pub const GROUP: u32 = 2;

/// The Sobol dimensions used, as Joe and Kuo give them
/// (`new-joe-kuo-6.21201`): `(s, a, m)` — the degree `s` of the primitive
/// polynomial, its inner coefficients `a` (bit `s - 1 - i` is `a_i`), and
/// the initial direction integers `m_1..m_s`. Sobol dimension 1 is the van
/// der Corput sequence (every `m_k = 1`); dimension 2 is Joe–Kuo's `d = 2`
/// line, `x + 1`, whose matrix is Pascal's triangle mod 2.
pub const JOE_KUO: [(u32, u32, &[u64]); GROUP as usize] = [(0, 0, &[]), (1, 0, &[1])];

/// The generator matrices of the Sobol dimensions, one `u32` column per
/// index bit: column `k` is the direction number `v_{k+1} = m_{k+1} /
/// 2^{k+1}` as a 32-bit fraction (most significant bit first), and the
/// coordinate of index `i` is the XOR of the columns of `i`'s set bits.
pub const GENERATORS: [[u32; 32]; GROUP as usize] = [
    generator(JOE_KUO[0].0, JOE_KUO[0].1, JOE_KUO[0].2),
    generator(JOE_KUO[1].0, JOE_KUO[1].1, JOE_KUO[1].2),
];

/// The columns of one Sobol dimension from its Joe–Kuo parameters (degree
/// 0 means the van der Corput sequence).
const fn generator(s: u32, a: u32, m_init: &[u64]) -> [u32; 32] {
    let mut m = [1u64; 33]; // m[k] for k in 1..=32; m[0] unused
    let mut k = 1;
    while k <= 32 {
        if s == 0 {
            m[k] = 1;
        } else if k <= s as usize {
            m[k] = m_init[k - 1];
        } else {
            // m_k = 2 a_1 m_{k-1} ^ 4 a_2 m_{k-2} ^ ... ^ 2^s m_{k-s} ^ m_{k-s}
            let s = s as usize;
            let mut v = m[k - s] ^ (m[k - s] << s);
            let mut i = 1;
            while i < s {
                if (a >> (s - 1 - i)) & 1 == 1 {
                    v ^= m[k - i] << i;
                }
                i += 1;
            }
            m[k] = v;
        }
        k += 1;
    }
    let mut c = [0u32; 32];
    let mut k = 0;
    while k < 32 {
        c[k] = (m[k + 1] << (31 - k)) as u32;
        k += 1;
    }
    c
}

/// Nested uniform (Owen) scrambling in base 2 of a bit-reversed word:
/// bit `k` is flipped by a function of `seed` and bits `0..k` only (every
/// step carries upwards only). Vegdahl's hash (pbrt-v4's
/// `FastOwenScrambler`, Cycles' `reversed_bit_owen`), an improvement on
/// Burley's Laine–Karras permutation. A bijection for every seed.
#[inline(always)]
pub fn owen_reversed(v: u32, seed: u32) -> u32 {
    owen_lanes(v, seed)
}

/// Nested uniform (Owen) scrambling in base 2 of a 32-bit fraction: bit
/// `k` from the top is flipped by a function of `seed` and the bits above
/// it. Every aligned block of `2^m` values maps onto one.
#[inline]
pub fn nested_scramble(v: u32, seed: u32) -> u32 {
    owen_reversed(v.reverse_bits(), seed).reverse_bits()
}

/// The unscrambled Sobol coordinate of index `index` in Sobol dimension
/// `j < GROUP`, as a 32-bit fraction.
#[inline]
pub fn sobol_bits(index: u32, j: u32) -> u32 {
    let c = &GENERATORS[j as usize];
    (0..32).fold(0, |x, k| x ^ (c[k] & 0u32.wrapping_sub((index >> k) & 1)))
}

/// The top 24 bits of a 32-bit fraction as an `f32` in `[0, 1)`.
#[inline(always)]
pub fn bits_to_f32(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// 32 bits identifying pixel `pixel` under seed `seed`: a bijection of the
/// pixel for every seed, so no two pixels share their numbers.
#[inline]
fn pixel_key(seed: u64, pixel: u32) -> u32 {
    let s = splitmix64(seed);
    // Chris Wellons' `lowbias32`, a bijective 32-bit mix.
    let mut x = pixel ^ s as u32;
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x ^ (s >> 32) as u32
}

/// Salts of the three seeds of a group: its index shuffle, and the
/// scrambles of its two coordinates.
const SALTS: [u32; 3] = [0x5348_5546, 0x5343_5230, 0x5343_5231];

/// Chris Wellons' `lowbias32`: a bijective 32-bit mix with good
/// avalanche, two multiplications.
#[inline(always)]
fn lowbias32<U: Lanes>(mut x: U) -> U {
    x = x.xor(x.shr(16));
    x = x.mul(U::splat(0x7feb_352d));
    x = x.xor(x.shr(15));
    x = x.mul(U::splat(0x846c_a68b));
    x.xor(x.shr(16))
}

/// Seed `which` (0: the index shuffle, 1 and 2: the coordinates'
/// scrambles) of group `group` of the pixel with key `key`.
#[inline(always)]
fn seed<U: Lanes>(key: U, group: U, which: usize) -> U {
    let g = lowbias32(key.xor(group.mul(U::splat(0x9e37_79b9))));
    lowbias32(g.xor(U::splat(SALTS[which])))
}

/// Group `group`'s index shuffle seed and its coordinate 0's scramble
/// seed.
#[cfg(test)]
#[inline(always)]
fn seeds_0(key: u32, group: u32) -> (u32, u32) {
    (seed(key, group, 0), seed(key, group, 1))
}

/// Group `group`'s coordinate 1's scramble seed.
#[cfg(test)]
#[inline(always)]
fn seed_1(key: u32, group: u32) -> u32 {
    seed(key, group, 2)
}

/// What the sampler's arithmetic needs of one lane (`u32`) or eight
/// (`wide::u32x8`): wrapping integer operations, each lane the same as the
/// scalar one, so a number is the same bits however many are drawn at once.
pub(crate) trait Lanes: Copy {
    fn splat(x: u32) -> Self;
    fn xor(self, o: Self) -> Self;
    fn and(self, o: Self) -> Self;
    fn or(self, o: Self) -> Self;
    fn add(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn shr(self, k: u32) -> Self;
    fn shl(self, k: u32) -> Self;
    /// The top 24 bits as a float in `[0, 1)`.
    fn to_unit(self) -> Self::Float;
    type Float;
}

impl Lanes for u32 {
    type Float = f32;
    #[inline(always)]
    fn splat(x: u32) -> Self {
        x
    }
    #[inline(always)]
    fn xor(self, o: Self) -> Self {
        self ^ o
    }
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        self & o
    }
    #[inline(always)]
    fn or(self, o: Self) -> Self {
        self | o
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.wrapping_add(o)
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.wrapping_mul(o)
    }
    #[inline(always)]
    fn shr(self, k: u32) -> Self {
        self >> k
    }
    #[inline(always)]
    fn shl(self, k: u32) -> Self {
        self << k
    }
    #[inline(always)]
    fn to_unit(self) -> f32 {
        bits_to_f32(self)
    }
}

impl Lanes for u32x8 {
    type Float = f32x8;
    #[inline(always)]
    fn splat(x: u32) -> Self {
        u32x8::splat(x)
    }
    #[inline(always)]
    fn xor(self, o: Self) -> Self {
        self ^ o
    }
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        self & o
    }
    #[inline(always)]
    fn or(self, o: Self) -> Self {
        self | o
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self + o
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self * o
    }
    #[inline(always)]
    fn shr(self, k: u32) -> Self {
        self >> k
    }
    #[inline(always)]
    fn shl(self, k: u32) -> Self {
        self << k
    }
    #[inline(always)]
    fn to_unit(self) -> f32x8 {
        // Below 2^24: the conversion through i32 is exact.
        let top: i32x8 = bytemuck::cast(self >> 8);
        top.round_float() * f32x8::splat(1.0 / 16_777_216.0)
    }
}

/// Nested uniform (Owen) scrambling in base 2 of a bit-reversed word, any
/// number of lanes: [`owen_reversed`].
#[inline(always)]
fn owen_lanes<U: Lanes>(mut v: U, seed: U) -> U {
    v = v.xor(v.mul(U::splat(0x3d20_adea)));
    v = v.add(seed);
    v = v.mul(seed.shr(16).or(U::splat(1)));
    v = v.xor(v.mul(U::splat(0x0552_6c56)));
    v.xor(v.mul(U::splat(0x53a2_2864)))
}

/// The bits of `x` in reverse order, any number of lanes.
#[inline(always)]
fn reverse_lanes<U: Lanes>(x: U) -> U {
    let swap = |x: U, k: u32, m: u32| x.shr(k).and(U::splat(m)).or(x.and(U::splat(m)).shl(k));
    let x = swap(x, 1, 0x5555_5555);
    let x = swap(x, 2, 0x3333_3333);
    let x = swap(x, 4, 0x0f0f_0f0f);
    let x = swap(x, 8, 0x00ff_00ff);
    x.shr(16).or(x.shl(16))
}

/// Coordinate `j` of the Sobol point at reversed (shuffled) index `r`,
/// bit-reversed, any number of lanes, computed rather than looked up:
/// dimension 1 (van der Corput) is the index itself, so its reversed
/// coordinate is `reverse(r)`; dimension 2's matrix is Pascal's triangle
/// mod 2, whose entry `(q, k)` is odd exactly when the bits of `q` are a
/// subset of those of `k` (Lucas), so its coordinate's bit `31 - q` is the
/// XOR of the index bits at the supersets of `q`: a superset transform in
/// five shift-and-XOR steps ([`superset_xor`]) of the same `reverse(r)`.
#[inline(always)]
fn sobol_reversed_lanes<U: Lanes>(r: U, j: usize) -> U {
    let index = reverse_lanes(r);
    if j == 0 { index } else { superset_xor(index) }
}

/// Bit `p` of the result is the XOR of the bits of `x` at the positions
/// that contain `p`'s bits (the superset, or zeta, transform over GF(2)).
#[inline(always)]
fn superset_xor<U: Lanes>(mut y: U) -> U {
    const M: [u32; 5] = [
        0x5555_5555,
        0x3333_3333,
        0x0f0f_0f0f,
        0x00ff_00ff,
        0x0000_ffff,
    ];
    for (b, m) in M.into_iter().enumerate() {
        y = y.xor(y.shr(1 << b).and(U::splat(m)));
    }
    y
}

/// Dimension `dim` (coordinate `j` of group `group`) of the samples at
/// pixel keys `key` and reversed indices `reversed`, as a bit-reversed
/// fraction, any number of lanes.
#[inline(always)]
fn reversed_lanes<U: Lanes>(key: U, reversed: U, group: U, j: usize) -> U {
    let r = owen_lanes(reversed, seed(key, group, 0));
    owen_lanes(sobol_reversed_lanes(r, j), seed(key, group, 1 + j))
}

/// Both coordinates of group `group`'s points, bit-reversed (one index
/// shuffle for the two), any number of lanes.
#[inline(always)]
fn reversed_pair_lanes<U: Lanes>(key: U, reversed: U, group: U) -> [U; 2] {
    let index = reverse_lanes(owen_lanes(reversed, seed(key, group, 0)));
    [
        owen_lanes(index, seed(key, group, 1)),
        owen_lanes(superset_xor(index), seed(key, group, 2)),
    ]
}

/// Dimension `dim` of the sample at pixel key `key` and reversed sample
/// index `reversed_sample`, as a bit-reversed 32-bit fraction.
#[inline(always)]
fn reversed_at(key: u32, reversed_sample: u32, dim: u32) -> u32 {
    reversed_lanes(key, reversed_sample, dim / GROUP, (dim % GROUP) as usize)
}

/// Both coordinates of group `group`'s point, bit-reversed.
#[inline(always)]
fn reversed_pair(key: u32, reversed_sample: u32, group: u32) -> [u32; 2] {
    reversed_pair_lanes(key, reversed_sample, group)
}

/// Eight paths' numbers at their next dimension (the first `paths.len()`
/// lanes; the others are for nothing).
#[inline]
fn next_lanes(paths: &mut [SobolPath]) -> f32x8 {
    let (key, reversed, dim) = lanes_of(paths);
    let group = dim >> 1;
    let j = paths[0].dim % GROUP;
    let z = if paths.iter().all(|p| p.dim % GROUP == j) {
        reversed_lanes(key, reversed, group, j as usize)
    } else {
        // Lanes at both coordinates: compute both, keep each lane's own.
        let odd = (dim & u32x8::splat(1)).simd_eq(u32x8::splat(1));
        let [a, b] = reversed_pair_lanes(key, reversed, group);
        odd.select(b, a)
    };
    for p in paths.iter_mut() {
        p.dim = p.dim.wrapping_add(1);
    }
    reverse_lanes(z).to_unit()
}

/// Eight paths' numbers at their next two dimensions.
#[inline]
fn next_2d_lanes(paths: &mut [SobolPath]) -> [f32x8; 2] {
    next_2d_lanes_after(paths, 0)
}

/// Eight paths' numbers at their next two dimensions after skipping
/// `skip`: one pass over the paths (their keys, indices and dimensions
/// read once, the dimensions stepped once), where [`Sampler::skip`] then
/// [`next_2d_lanes`] took three.
#[inline]
fn next_2d_lanes_after(paths: &mut [SobolPath], skip: u32) -> [f32x8; 2] {
    let (key, reversed, dim) = lanes_of(paths);
    let dim = dim + u32x8::splat(skip);
    if !(dim & u32x8::splat(1)).simd_eq(u32x8::ZERO).all() {
        // Straddling a group: two single draws.
        for p in paths.iter_mut() {
            p.dim = p.dim.wrapping_add(skip);
        }
        return [next_lanes(paths), next_lanes(paths)];
    }
    let pair = reversed_pair_lanes(key, reversed, dim >> 1);
    let step = skip.wrapping_add(2);
    for p in paths.iter_mut() {
        p.dim = p.dim.wrapping_add(step);
    }
    pair.map(|z| reverse_lanes(z).to_unit())
}

/// The keys, reversed indices and dimensions of up to eight paths (lanes
/// past the last repeat the first). Eight paths are four vectors of two
/// paths each, transposed by permutations and blends.
#[inline(always)]
fn lanes_of(paths: &[SobolPath]) -> (u32x8, u32x8, u32x8) {
    let Ok(eight) = <&[SobolPath; 8]>::try_from(paths) else {
        let p = |l: usize| paths.get(l).unwrap_or(&paths[0]);
        let f =
            |g: fn(&SobolPath) -> u32| u32x8::from(std::array::from_fn::<u32, 8, _>(|l| g(p(l))));
        return (f(|p| p.key), f(|p| p.reversed_sample), f(|p| p.dim));
    };
    let words: &[[u32; 8]; 4] = bytemuck::cast_ref(eight);
    let v = words.map(u32x8::from);
    // Field `f` of path `2k` is lane `f` of `v[k]`, of path `2k + 1` lane
    // `4 + f`: each `v[k]` permuted to have them at lanes `2k` and
    // `2k + 1`, then the four blended.
    let pairs = |k: usize| {
        u32x8::from(std::array::from_fn::<u32, 8, _>(|l| {
            if l / 2 == k { u32::MAX } else { 0 }
        }))
    };
    let (m0, m1, m2) = (pairs(0), pairs(1), pairs(2));
    let column = |f: u32| {
        let index = u32x8::from([f, 4 + f, f, 4 + f, f, 4 + f, f, 4 + f]);
        let [a, b, c, d] = v.map(|v| v.shuffle(index));
        m0.select(a, m1.select(b, m2.select(c, d)))
    };
    // SobolPath's fields: pixel, reversed_sample, dim, key.
    (column(3), column(1), column(2))
}

/// A bit-reversed 32-bit fraction's top 24 bits as an `f32` in `[0, 1)`:
/// `bits_to_f32(z.reverse_bits())`, by a byte table.
#[inline(always)]
fn reversed_to_f32(z: u32) -> f32 {
    let top = (REV8[(z & 255) as usize] as u32) << 16
        | (REV8[((z >> 8) & 255) as usize] as u32) << 8
        | REV8[((z >> 16) & 255) as usize] as u32;
    top as f32 * (1.0 / 16_777_216.0)
}

/// Every byte, bit-reversed.
static REV8: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = (i as u8).reverse_bits();
        i += 1;
    }
    t
};

/// Owen-scrambled, shuffled, padded Sobol points (Burley 2020): see the
/// [module documentation](self). Dimension `d` of sample `i` of pixel `p`
/// is a function of `(seed, p, i, d)` only.
///
/// ```
/// use wavetrace::integrator::sampler::{Sampler, sobol::Sobol};
/// let sobol = Sobol::new(7);
/// let mut path = sobol.start(42, 3); // pixel 42, sample 3
/// let [u, v] = sobol.next_2d(&mut path); // dimensions 0 and 1
/// assert_eq!(u, sobol.get(42, 3, 0));
/// assert_eq!(v, sobol.get(42, 3, 1));
/// assert!((0.0..1.0).contains(&u));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sobol {
    seed: u64,
}

impl Sobol {
    /// The sampler of seed `seed`.
    pub fn new(seed: u64) -> Self {
        Self { seed }
    }

    /// Dimension `dim` of sample `sample` of pixel `pixel`, in `[0, 1)`:
    /// the number the path `start(pixel, sample)` draws after `dim`
    /// others.
    #[inline]
    pub fn get(&self, pixel: u32, sample: u32, dim: u32) -> f32 {
        reversed_to_f32(reversed_at(
            pixel_key(self.seed, pixel),
            sample.reverse_bits(),
            dim,
        ))
    }

    /// [`get`](Self::get) as the full 32-bit fraction (its top 24 bits are
    /// the `f32`).
    #[inline]
    pub fn bits(&self, pixel: u32, sample: u32, dim: u32) -> u32 {
        reversed_at(pixel_key(self.seed, pixel), sample.reverse_bits(), dim).reverse_bits()
    }
}

/// Where a path is in its Sobol numbers: its pixel, its global sample
/// index (kept bit-reversed, the form the index shuffle takes) and its next
/// dimension, plus the pixel's hashed key, so that a number costs no
/// per-pixel hashing. 16 bytes of plain old data.
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct SobolPath {
    pixel: u32,
    reversed_sample: u32,
    dim: u32,
    key: u32,
}

impl SobolPath {
    /// The path's pixel.
    pub fn pixel(&self) -> u32 {
        self.pixel
    }

    /// The path's global sample index.
    pub fn sample(&self) -> u32 {
        self.reversed_sample.reverse_bits()
    }

    /// The dimension of the path's next number.
    pub fn dim(&self) -> u32 {
        self.dim
    }
}

impl Sampler for Sobol {
    type Path = SobolPath;

    #[inline]
    fn start(&self, pixel: u32, sample: u32) -> SobolPath {
        SobolPath {
            pixel,
            reversed_sample: sample.reverse_bits(),
            dim: 0,
            key: pixel_key(self.seed, pixel),
        }
    }

    #[inline]
    fn next(&self, path: &mut SobolPath) -> f32 {
        let z = reversed_at(path.key, path.reversed_sample, path.dim);
        path.dim = path.dim.wrapping_add(1);
        reversed_to_f32(z)
    }

    #[inline]
    fn skip(&self, path: &mut SobolPath, n: u32) {
        path.dim = path.dim.wrapping_add(n);
    }

    #[inline]
    fn next_8(&self, paths: &mut [SobolPath]) -> f32x8 {
        next_lanes(paths)
    }

    #[inline]
    fn next_2d_8(&self, paths: &mut [SobolPath]) -> [f32x8; 2] {
        next_2d_lanes(paths)
    }

    #[inline]
    fn skip_next_2d_8(&self, paths: &mut [SobolPath], n: u32) -> [f32x8; 2] {
        next_2d_lanes_after(paths, n)
    }

    /// Both coordinates of one point when the path is at an even
    /// dimension (one index shuffle for the two); else two [`next`]s.
    ///
    /// [`next`]: Sampler::next
    #[inline]
    fn next_2d(&self, path: &mut SobolPath) -> [f32; 2] {
        let (key, dim, reversed) = (path.key, path.dim, path.reversed_sample);
        path.dim = dim.wrapping_add(2);
        if dim % GROUP == 0 {
            reversed_pair(key, reversed, dim / GROUP).map(reversed_to_f32)
        } else {
            [
                reversed_to_f32(reversed_at(key, reversed, dim)),
                reversed_to_f32(reversed_at(key, reversed, dim.wrapping_add(1))),
            ]
        }
    }
}

#[cfg(test)]
mod tests {
    //! The sampler's properties, each checked by a test that a deliberately
    //! broken variant of the sampler fails (`Variant`, below): the harness
    //! runs the same statistics on the real sampler and on the variants.

    use super::*;

    // ---- The variants -------------------------------------------------

    /// The sampler as built (`Correct`, checked equal to [`Sobol::bits`])
    /// and deliberately broken versions of it.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    enum Variant {
        Correct,
        /// No Owen scramble of the coordinates (the index shuffle only).
        NoOwen,
        /// A Cranley–Patterson rotation (adding the seed mod 1) instead of
        /// the Owen scramble: random, but not nested.
        RotationNotOwen,
        /// The index shuffled by a full-avalanche bijection (a good hash,
        /// but not nested).
        ShuffleNotNested,
        /// Each dimension's index shuffled by its own seed, so the two
        /// coordinates of a group come from different points.
        ShufflePerDimension,
        /// No index shuffle: every group is the same Sobol point, scrambled.
        NoShuffle,
        /// One index shuffle for every group of a pixel.
        OneShufflePerPixel,
        /// The pixel left out of the seeds: every pixel the same numbers.
        PixelIgnored,
    }
    use Variant::*;

    /// The 32-bit fraction of `variant` at `(seed, pixel, sample, dim)`.
    fn variant_bits(variant: Variant, seed: u64, pixel: u32, sample: u32, dim: u32) -> u32 {
        let pixel = if variant == PixelIgnored { 0 } else { pixel };
        let key = pixel_key(seed, pixel);
        let (group, j) = (dim / GROUP, dim % GROUP);
        let (shuffle, scramble_0) = seeds_0(key, group);
        let scramble = if j == 0 {
            scramble_0
        } else {
            seed_1(key, group)
        };
        let reversed = sample.reverse_bits();
        let r = match variant {
            NoShuffle => reversed,
            ShuffleNotNested => lowbias32(sample ^ shuffle).reverse_bits(),
            ShufflePerDimension => owen_reversed(reversed, seeds_0(key, dim).0),
            OneShufflePerPixel => owen_reversed(reversed, seeds_0(key, 0).0),
            _ => owen_reversed(reversed, shuffle),
        };
        let y = sobol_reversed_lanes(r, j as usize);
        match variant {
            NoOwen => y.reverse_bits(),
            RotationNotOwen => y.reverse_bits().wrapping_add(scramble),
            _ => owen_reversed(y, scramble).reverse_bits(),
        }
    }

    fn lowbias32(mut x: u32) -> u32 {
        x ^= x >> 16;
        x = x.wrapping_mul(0x7feb_352d);
        x ^= x >> 15;
        x = x.wrapping_mul(0x846c_a68b);
        x ^ (x >> 16)
    }

    #[test]
    fn the_correct_variant_is_the_sampler() {
        for seed in [0, 3, u64::MAX] {
            let sobol = Sobol::new(seed);
            for (pixel, sample, dim) in [(0, 0, 0), (5, 9, 1), (77, 1000, 2), (u32::MAX, 1, 4999)] {
                let want = variant_bits(Correct, seed, pixel, sample, dim);
                assert_eq!(sobol.bits(pixel, sample, dim), want);
                assert_eq!(sobol.get(pixel, sample, dim), bits_to_f32(want));
            }
        }
    }

    // ---- The tables -----------------------------------------------------

    #[test]
    fn generators_are_joe_kuo_dimensions_1_and_2() {
        // Dimension 1: van der Corput, the identity in reversed order.
        for (k, &c) in GENERATORS[0].iter().enumerate() {
            assert_eq!(c, 1 << (31 - k));
        }
        // Dimension 2 (x + 1, m_1 = 1): m_k = 1, 3, 5, 15, 17, 51, 85, 255, ...
        let m = [1u32, 3, 5, 15, 17, 51, 85, 255, 257];
        for (k, &m) in m.iter().enumerate() {
            assert_eq!(GENERATORS[1][k], m << (31 - k), "column {k}");
        }
        // ... Pascal's triangle mod 2: bit i of m_{k+1} is C(k, i) mod 2,
        // which is 1 exactly when i's bits are a subset of k's (Lucas).
        for k in 0..32u32 {
            let m = GENERATORS[1][k as usize] >> (31 - k);
            for i in 0..=k {
                assert_eq!((m >> (k - i)) & 1 == 1, i & k == i, "column {k}, bit {i}");
            }
        }
    }

    #[test]
    fn the_generator_recurrence_follows_joe_kuo() {
        // m_k = 2 a_1 m_{k-1} ^ ... ^ 2^s m_{k-s} ^ m_{k-s}, worked by hand:
        // x^2 + x + 1 (s = 2, a = 1, m = 1 3) and x^3 + x + 1 (s = 3,
        // a = 1, m = 1 3 1), Joe and Kuo's dimensions 3 and 4.
        for (s, a, init, want) in [
            (2, 1, &[1u64, 3][..], [1u32, 3, 3, 9, 29, 23]),
            (3, 1, &[1, 3, 1][..], [1, 3, 1, 5, 31, 29]),
        ] {
            let c = generator(s, a, init);
            for (k, &m) in want.iter().enumerate() {
                assert_eq!(c[k], m << (31 - k), "s {s} column {k}");
            }
        }
    }

    #[test]
    fn computed_coordinates_are_the_generators_applied() {
        let mut x = 0x1234_5678u32;
        for _ in 0..10_000 {
            x = lowbias32(x.wrapping_add(1));
            for j in 0..GROUP {
                let want = sobol_bits(x.reverse_bits(), j).reverse_bits();
                assert_eq!(sobol_reversed_lanes(x, j as usize), want);
            }
            assert_eq!(reversed_to_f32(x), bits_to_f32(x.reverse_bits()));
            assert_eq!(reverse_lanes(x), x.reverse_bits());
        }
    }

    #[test]
    fn eight_lanes_draw_the_numbers_one_lane_draws() {
        // Paths at mixed dimensions (even, odd, straddling), every count of
        // lanes: next_8 / next_2d_8 / skip_next_2d_8 give each path its own
        // next numbers.
        let sobol = Sobol::new(17);
        for lanes in 1..=8 {
            for start_dims in [[0u32; 8], [1; 8], [0, 1, 2, 3, 4, 5, 6, 7], [4998; 8]] {
                let mut paths: Vec<SobolPath> = (0..lanes)
                    .map(|l| {
                        let mut p = sobol.start(1000 + l as u32, 3 * l as u32);
                        sobol.skip(&mut p, start_dims[l]);
                        p
                    })
                    .collect();
                let mut one = paths.clone();
                for skip in 0..5 {
                    let x = sobol.next_8(&mut paths).to_array();
                    let [a, b] = sobol.next_2d_8(&mut paths).map(|v| v.to_array());
                    // Skipping `skip` dimensions first, in the same pass.
                    let [e, f] = sobol.skip_next_2d_8(&mut paths, skip).map(|v| v.to_array());
                    for (l, p) in one.iter_mut().enumerate() {
                        assert_eq!(x[l].to_bits(), sobol.next(p).to_bits());
                        let [c, d] = sobol.next_2d(p);
                        assert_eq!([a[l], b[l]].map(f32::to_bits), [c, d].map(f32::to_bits));
                        sobol.skip(p, skip);
                        let [g, h] = sobol.next_2d(p);
                        assert_eq!([e[l], f[l]].map(f32::to_bits), [g, h].map(f32::to_bits));
                    }
                }
                assert_eq!(paths, one);
            }
        }
    }

    // ---- (0,2)-sequences ------------------------------------------------

    /// Whether the points (32-bit fractions) form a (0,m,2)-net, `2^m`
    /// of them: every elementary interval of area `2^-m` holds one.
    fn is_net(points: &[(u32, u32)]) -> bool {
        let n = points.len();
        assert!(n.is_power_of_two());
        let m = n.trailing_zeros();
        let mut seen = vec![false; n];
        (0..=m).all(|a| {
            let b = m - a;
            seen.fill(false);
            points.iter().all(|&(x, y)| {
                let cell = (((x as u64) >> (32 - a)) << b | ((y as u64) >> (32 - b))) as usize;
                !std::mem::replace(&mut seen[cell], true)
            })
        })
    }

    /// How many `(seed, pixel, group, m, block)` of the net test's are not
    /// (0,m,2)-nets under `bits`: the samples `[k 2^m, (k+1) 2^m)` of a
    /// pixel, dimensions `2g` and `2g+1`.
    fn net_failures(bits: impl Fn(u64, u32, u32, u32) -> u32) -> usize {
        let mut failures = 0;
        for seed in [0, 1, 0xDEAD_BEEF_CAFE] {
            for pixel in [0, 1, 65_535, 1 << 20, u32::MAX] {
                for group in [0, 1, 2, 9, 2500, u32::MAX / 2] {
                    let d = group * 2;
                    for m in 0..=12u32 {
                        let n = 1u32 << m;
                        for start in [0, n, 5 * n, 1 << 31, n.wrapping_neg()] {
                            let points: Vec<_> = (start..=start + (n - 1))
                                .map(|i| (bits(seed, pixel, i, d), bits(seed, pixel, i, d + 1)))
                                .collect();
                            failures += !is_net(&points) as usize;
                        }
                    }
                }
            }
        }
        failures
    }

    #[test]
    fn the_net_test_knows_nets() {
        // The unscrambled Sobol pair is a (0,2)-sequence...
        for m in 0..=12 {
            for k in [0, 1, 7] {
                let points: Vec<_> = (k << m..(k + 1) << m)
                    .map(|i| (sobol_bits(i, 0), sobol_bits(i, 1)))
                    .collect();
                assert!(is_net(&points), "m {m} block {k}");
            }
        }
        // ... and a shifted block of it is not.
        let points: Vec<_> = (1..5)
            .map(|i| (sobol_bits(i, 0), sobol_bits(i, 1)))
            .collect();
        assert!(!is_net(&points));
    }

    #[test]
    fn the_first_two_dims_of_every_group_are_0_2_sequences() {
        assert_eq!(net_failures(|s, p, i, d| Sobol::new(s).bits(p, i, d)), 0);
    }

    #[test]
    fn the_net_test_catches_unnested_shuffles_and_scrambles() {
        for variant in [ShuffleNotNested, ShufflePerDimension, RotationNotOwen] {
            let failures = net_failures(|s, p, i, d| variant_bits(variant, s, p, i, d));
            // Of 3 x 5 x 6 x 13 x 5 = 5850 sets; m = 0 always passes.
            assert!(failures > 1000, "{variant:?}: only {failures} sets fail");
        }
        // These are nets still (the other tests catch them).
        for variant in [NoOwen, NoShuffle, OneShufflePerPixel, PixelIgnored] {
            assert_eq!(
                net_failures(|s, p, i, d| variant_bits(variant, s, p, i, d)),
                0
            );
        }
    }

    // ---- Nested scrambling ------------------------------------------------

    #[test]
    fn owen_scrambling_is_nested_and_one_to_one() {
        for seed in [0, 1, 0x8000_0000, 0xDEAD_BEEF, u32::MAX] {
            // Values sharing their top k bits keep sharing them: an aligned
            // block of 2^(32-k) values maps onto one.
            let mut x = seed;
            for _ in 0..2000 {
                x = lowbias32(x ^ 0x9e37_79b9);
                let k = 1 + x % 31;
                let top = u32::MAX << (32 - k);
                let (a, b) = (x, (x & top) | (lowbias32(x) & !top));
                let (sa, sb) = (nested_scramble(a, seed), nested_scramble(b, seed));
                assert_eq!(sa & top, sb & top, "seed {seed:#x} k {k}");
            }
            // One to one: the 2^16 blocks of 2^16 values go to distinct ones.
            let mut seen = vec![false; 1 << 16];
            for top in 0..1u32 << 16 {
                let s = nested_scramble(top << 16, seed) >> 16;
                assert!(!std::mem::replace(&mut seen[s as usize], true));
            }
        }
    }

    // ---- Uniformity across pixels ------------------------------------------

    /// The standard normal's upper tail probability, `P(Z > z)`, to about
    /// 1e-7 (Abramowitz & Stegun 7.1.26).
    fn normal_tail(z: f64) -> f64 {
        let x = z.abs() / std::f64::consts::SQRT_2;
        let t = 1.0 / (1.0 + 0.327_591_1 * x);
        let poly = t
            * (0.254_829_592
                + t * (-0.284_496_736
                    + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
        let erfc = poly * (-x * x).exp();
        if z >= 0.0 {
            erfc / 2.0
        } else {
            1.0 - erfc / 2.0
        }
    }

    /// `P(χ²_k > x)` by Wilson and Hilferty's cube-root normal
    /// approximation (good far into the tail for k of tens or more).
    fn chi2_tail(x: f64, k: f64) -> f64 {
        let v = 2.0 / (9.0 * k);
        normal_tail(((x / k).cbrt() - (1.0 - v)) / v.sqrt())
    }

    /// Pearson's χ² of `values` in `[0, 1)` against the uniform
    /// distribution, 64 bins: its upper tail probability.
    fn chi2_uniform(values: &[f64]) -> f64 {
        let bins = 64;
        let mut count = vec![0u32; bins];
        for &v in values {
            count[(v * bins as f64) as usize] += 1;
        }
        let e = values.len() as f64 / bins as f64;
        let x: f64 = count.iter().map(|&c| (c as f64 - e).powi(2) / e).sum();
        chi2_tail(x, (bins - 1) as f64)
    }

    /// The Kolmogorov–Smirnov statistic `sqrt(n) D_n` of `values` against
    /// the uniform distribution.
    fn ks_uniform(values: &[f64]) -> f64 {
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len() as f64;
        let d = v.iter().enumerate().fold(0.0f64, |d, (i, &x)| {
            d.max((i + 1) as f64 / n - x).max(x - i as f64 / n)
        });
        d * n.sqrt()
    }

    /// The smallest χ² tail probability and the largest KS statistic of
    /// dimensions 0..40 of samples 0, 1, 2, 3, 64 and 1000 over 4096
    /// neighbouring pixels (each set of 4096 numbers tested alone).
    fn uniformity(bits: impl Fn(u64, u32, u32, u32) -> u32) -> (f64, f64) {
        let (mut p_min, mut ks_max) = (1.0f64, 0.0f64);
        for dim in 0..40 {
            for sample in [0, 1, 2, 3, 64, 1000] {
                let values: Vec<f64> = (0..4096)
                    .map(|pixel| bits_to_f32(bits(9, 1000 + pixel, sample, dim)) as f64)
                    .collect();
                assert!(values.iter().all(|v| (0.0..1.0).contains(v)));
                p_min = p_min.min(chi2_uniform(&values));
                ks_max = ks_max.max(ks_uniform(&values));
            }
        }
        (p_min, ks_max)
    }

    /// χ² tail below this (Wilson–Hilferty's z about 5), or a KS statistic
    /// above this (`P ≈ 2 exp(-2 λ²) ≈ 7e-6`), fails a set of numbers.
    const P_FAIL: f64 = 3e-7;
    const KS_FAIL: f64 = 2.5;

    #[test]
    fn every_dimension_is_uniform_across_pixels() {
        let (p, ks) = uniformity(|s, p, i, d| Sobol::new(s).bits(p, i, d));
        assert!(p > P_FAIL && ks < KS_FAIL, "χ² tail {p:e}, KS {ks}");
        // Not trivially passed: the tests see sets far smaller than 240
        // sets' worth of luck would give (p of order 1/240, KS about 1.9).
        assert!(p < 0.05 && ks > 1.0, "χ² tail {p:e}, KS {ks}");
    }

    #[test]
    fn the_uniformity_test_catches_a_sampler_that_ignores_the_pixel() {
        let (p, ks) = uniformity(|s, p, i, d| variant_bits(PixelIgnored, s, p, i, d));
        assert!(p < P_FAIL && ks > KS_FAIL, "χ² tail {p:e}, KS {ks}");
        // The index shuffle alone gives uniform numbers across pixels
        // (a random Sobol index's point is uniform): dropping the Owen
        // scramble passes this test; the next one catches it.
        let (p, ks) = uniformity(|s, p, i, d| variant_bits(NoOwen, s, p, i, d));
        assert!(p > P_FAIL && ks < KS_FAIL, "χ² tail {p:e}, KS {ks}");
    }

    // ---- Owen scrambling: uniform within the strata -------------------------

    /// Samples 0 and 1 (and 2 and 3) of a pixel are a 2-point net of a
    /// dimension: one in each half of [0, 1). Owen-scrambled, each is
    /// uniform within its half and the two are independent. Over 8192
    /// pixels, the pairs' 8 x 8 histogram then has nothing in the 32 cells
    /// of two points in one half, and the other 32 cells uniform: the
    /// smallest χ² tail probability of those 32 cells over a few
    /// dimensions.
    fn within_strata(bits: impl Fn(u64, u32, u32, u32) -> u32) -> f64 {
        let mut p_min = 1.0f64;
        for dim in [0, 1, 2, 5, 38] {
            for first in [0, 2] {
                let mut count = [[0u32; 8]; 8];
                for pixel in 0..8192 {
                    let a = bits(4, pixel, first, dim) >> 29;
                    let b = bits(4, pixel, first + 1, dim) >> 29;
                    count[a as usize][b as usize] += 1;
                }
                let e = 8192.0 / 32.0;
                let mut x = 0.0;
                for (a, row) in count.iter().enumerate() {
                    for (b, &c) in row.iter().enumerate() {
                        if (a < 4) == (b < 4) {
                            if c > 0 {
                                return 0.0; // two samples in one half: not even a net
                            }
                        } else {
                            x += (c as f64 - e).powi(2) / e;
                        }
                    }
                }
                p_min = p_min.min(chi2_tail(x, 31.0));
            }
        }
        p_min
    }

    #[test]
    fn owen_scrambling_makes_points_uniform_within_their_strata() {
        let p = within_strata(|s, p, i, d| Sobol::new(s).bits(p, i, d));
        assert!(p > P_FAIL, "χ² tail {p:e}");
    }

    #[test]
    fn the_strata_test_catches_a_missing_owen_scramble() {
        // Unscrambled, sample 1 is sample 0 plus or minus 1/2 exactly.
        let p = within_strata(|s, p, i, d| variant_bits(NoOwen, s, p, i, d));
        assert!(p < P_FAIL, "χ² tail {p:e}");
    }

    // ---- Independence of groups ---------------------------------------------

    /// The mean and the largest, over the 264 pairs of dimensions
    /// `a < b < 24` of different groups, of the mean over 64 pixels of
    /// `n r²`, `r` the correlation of the two dimensions over a pixel's
    /// first `n` = 256 samples. For independent numbers, or a shuffle by a
    /// uniformly random permutation, `n r²` is about χ²₁: mean 1.00, worst
    /// about 1.5 (measured: 1.00 and 1.60 for `Independent`).
    ///
    /// A shuffle that keeps every power-of-two prefix a net must be a
    /// nested permutation, and then pairs the groups' strata less randomly:
    /// mean 1.58 — for a true (per-bit hashed) Owen shuffle as for the hash
    /// used here (1.58, worst 2.30) — which is the price of needing no
    /// sample count.
    fn cross_group_correlation(bits: impl Fn(u64, u32, u32, u32) -> u32) -> (f64, f64) {
        const N: u32 = 256;
        let (mut worst, mut total, mut pairs) = (0.0f64, 0.0, 0);
        let v: Vec<Vec<Vec<f64>>> = (0..64)
            .map(|pixel| {
                (0..24)
                    .map(|d| {
                        (0..N)
                            .map(|i| bits_to_f32(bits(2, pixel, i, d)) as f64 - 0.5)
                            .collect()
                    })
                    .collect()
            })
            .collect();
        for a in 0..24usize {
            for b in a + 1..24 {
                if a as u32 / GROUP == b as u32 / GROUP {
                    continue;
                }
                let mean: f64 = v
                    .iter()
                    .map(|dims| {
                        let (x, y) = (&dims[a], &dims[b]);
                        let (mx, my) = (
                            x.iter().sum::<f64>() / N as f64,
                            y.iter().sum::<f64>() / N as f64,
                        );
                        let sxy: f64 = x.iter().zip(y).map(|(x, y)| (x - mx) * (y - my)).sum();
                        let sxx: f64 = x.iter().map(|x| (x - mx).powi(2)).sum();
                        let syy: f64 = y.iter().map(|y| (y - my).powi(2)).sum();
                        N as f64 * sxy * sxy / (sxx * syy)
                    })
                    .sum::<f64>()
                    / 64.0;
                worst = worst.max(mean);
                total += mean;
                pairs += 1;
            }
        }
        (total / pairs as f64, worst)
    }

    #[test]
    fn dimensions_of_different_groups_are_uncorrelated() {
        let (mean, worst) = cross_group_correlation(|s, p, i, d| Sobol::new(s).bits(p, i, d));
        assert!(
            mean < 2.0 && worst < 3.0,
            "n r²: mean {mean}, worst {worst}"
        );
    }

    #[test]
    fn the_correlation_test_catches_groups_sharing_a_shuffle() {
        for variant in [NoShuffle, OneShufflePerPixel] {
            let (mean, worst) =
                cross_group_correlation(|s, p, i, d| variant_bits(variant, s, p, i, d));
            assert!(
                worst > 10.0,
                "{variant:?}: n r²: mean {mean}, worst {worst}"
            );
        }
    }
}
