//! The numbers every path uses: a [`Sampler`] gives sample `sample` of
//! pixel `pixel` its numbers in order, dimension by dimension.
//!
//! Every number a path uses is a function of `(seed, pixel, sample index,
//! dimension)` only, so an image depends only on the seed — never on the
//! thread count, the batch size, the sample passes or the order work is
//! scheduled in. A path draws its numbers in a fixed order, and the
//! dimension of a number is how many the path drew before it: the camera
//! takes dimensions 0 and 1 (where in the pixel), and each surface the path
//! bounces from takes the next ones, as many as its integrator uses at a
//! vertex.
//!
//! Two samplers: [`Independent`] (keyed PCG streams) and [`Sobol`]
//! (Owen-scrambled Sobol points by global sample index, Burley 2020; see
//! [`sobol`]).

pub mod sobol;

pub use sobol::{Sobol, SobolPath};

use rand_core::Rng;
use rand_pcg::Pcg32;
use wide::{f32x8, i32x8, u64x4};

/// Where the numbers of every path come from.
pub trait Sampler: Send + Sync {
    /// One path's place in its numbers: plain old data, so the wavefront
    /// queue keeps a column of them.
    type Path: bytemuck::Pod + std::fmt::Debug + Send + Sync;

    /// The numbers of sample `sample` of pixel `pixel`, at dimension 0.
    fn start(&self, pixel: u32, sample: u32) -> Self::Path;

    /// The path's number at its next dimension, in `[0, 1)`.
    fn next(&self, path: &mut Self::Path) -> f32;

    /// Skip the path's next `n` dimensions (numbers it does not use, so
    /// that every dimension keeps one meaning across paths).
    #[inline]
    fn skip(&self, path: &mut Self::Path, n: u32) {
        for _ in 0..n {
            self.next(path);
        }
    }

    /// Up to eight paths' numbers at their next dimension, one path per
    /// lane, each the number [`next`](Self::next) would give it (lanes
    /// past `paths.len()` hold numbers for no path).
    #[inline]
    fn next_8(&self, paths: &mut [Self::Path]) -> f32x8 {
        let mut x = [0.0; 8];
        for (x, p) in x.iter_mut().zip(paths) {
            *x = self.next(p);
        }
        f32x8::from(x)
    }

    /// Up to eight paths' numbers at their next two dimensions, as
    /// [`next_2d`](Self::next_2d) would give them.
    #[inline]
    fn next_2d_8(&self, paths: &mut [Self::Path]) -> [f32x8; 2] {
        let (mut a, mut b) = ([0.0; 8], [0.0; 8]);
        for (l, p) in paths.iter_mut().enumerate() {
            [a[l], b[l]] = self.next_2d(p);
        }
        [f32x8::from(a), f32x8::from(b)]
    }

    /// Skip `n` dimensions of each of up to eight paths, then
    /// [`next_2d_8`](Sampler::next_2d_8): the same numbers, in one pass
    /// over the paths where the sampler can.
    #[inline]
    fn skip_next_2d_8(&self, paths: &mut [Self::Path], n: u32) -> [f32x8; 2] {
        for p in paths.iter_mut() {
            self.skip(p, n);
        }
        self.next_2d_8(paths)
    }

    /// The path's numbers at its next two dimensions.
    #[inline]
    fn next_2d(&self, path: &mut Self::Path) -> [f32; 2] {
        let a = self.next(path);
        [a, self.next(path)]
    }
}

/// Independent uniform numbers: dimension `k` of a path is the `k`-th
/// number of its own PCG stream ([`PathRng`]), keyed by
/// `(seed, pixel, sample)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Independent {
    seed: u64,
}

impl Independent {
    /// The sampler of seed `seed`.
    pub fn new(seed: u64) -> Self {
        Self { seed }
    }
}

impl Sampler for Independent {
    type Path = PathRng;

    #[inline]
    fn start(&self, pixel: u32, sample: u32) -> PathRng {
        PathRng::new(self.seed, pixel, sample)
    }

    #[inline]
    fn next(&self, path: &mut PathRng) -> f32 {
        path.next_f32()
    }

    #[inline]
    fn next_8(&self, paths: &mut [PathRng]) -> f32x8 {
        let [x] = PathRng::draw_8(paths);
        x
    }

    #[inline]
    fn next_2d_8(&self, paths: &mut [PathRng]) -> [f32x8; 2] {
        PathRng::draw_8(paths)
    }
}

/// The random stream of one camera sample: a `rand_pcg::Pcg32` kept as its
/// two plain words (state and stream), so that a queue's column of them is
/// plain old data (`bytemuck::Pod`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct PathRng {
    state: u64,
    stream: u64,
}

impl PathRng {
    /// The stream for sample `sample` of pixel `pixel` under `seed`.
    #[inline]
    pub fn new(seed: u64, pixel: u32, sample: u32) -> Self {
        // A hashed starting state per (seed, pixel, sample) on the seed's
        // stream: a path draws a handful of numbers from a period of 2^64.
        let state = splitmix64(seed ^ splitmix64(((pixel as u64) << 32) | sample as u64));
        Self::from_pcg(&Pcg32::new(state, seed))
    }

    fn from_pcg(pcg: &Pcg32) -> Self {
        Self {
            state: pcg.state(),
            stream: pcg.stream(),
        }
    }

    /// A uniform number in `[0, 1)` with 24 random bits.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        let mut pcg = Pcg32::from_state(self.state, self.stream);
        let bits = pcg.next_u32();
        self.state = pcg.state();
        (bits >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// The next `K` numbers ([`next_f32`](Self::next_f32)) of up to eight
    /// streams, lane `l` from `paths[l]` (lanes past them hold numbers of
    /// no stream). Eight streams step at once in 64-bit vector lanes:
    /// `Pcg32`'s step and output (XSH RR) written out.
    #[inline(always)]
    pub fn draw_8<const K: usize>(paths: &mut [PathRng]) -> [f32x8; K] {
        let Ok(eight) = <&mut [PathRng; 8]>::try_from(&mut *paths) else {
            let mut x = [[0.0; 8]; K];
            for (l, p) in paths.iter_mut().enumerate() {
                for x in &mut x {
                    x[l] = p.next_f32();
                }
            }
            return x.map(f32x8::from);
        };
        let half = |k: usize, f: fn(&PathRng) -> u64| {
            u64x4::from([
                f(&eight[k]),
                f(&eight[k + 1]),
                f(&eight[k + 2]),
                f(&eight[k + 3]),
            ])
        };
        // (No `array::map` here: it is not always inlined.)
        let mut state = [half(0, |p| p.state), half(4, |p| p.state)];
        // `Pcg32::from_state`'s increment: the stream shifted, odd.
        let inc = |k| half(k, |p| p.stream) << 1 | u64x4::ONE;
        let increment = [inc(0), inc(4)];
        let draws = std::array::from_fn(|_| {
            let (a, b) = (
                pcg_step(&mut state[0], increment[0]),
                pcg_step(&mut state[1], increment[1]),
            );
            let bits = [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]];
            i32x8::from(bits).round_float() * f32x8::splat(1.0 / 16_777_216.0)
        });
        for (l, p) in eight.iter_mut().enumerate() {
            p.state = state[l / 4].as_array()[l % 4];
        }
        draws
    }
}

/// The multiplier of `Pcg32`'s LCG (`rand_pcg::Lcg64Xsh32`).
const PCG_MULTIPLIER: u64 = 6_364_136_223_846_793_005;

/// One step of four `Pcg32` streams in 64-bit lanes: each one's output
/// (XSH RR, from the state before the step) shifted to its top 24 bits.
#[inline(always)]
fn pcg_step(state: &mut u64x4, increment: u64x4) -> [i32; 4] {
    let old = *state;
    *state = mul_u64(old, u64x4::splat(PCG_MULTIPLIER)) + increment;
    let low32 = u64x4::splat(u32::MAX.into());
    let xsh = ((old >> 18) ^ old) >> 27 & low32;
    let rot = old >> 59;
    let rotated = (xsh >> rot | xsh << (u64x4::splat(32) - rot)) & low32;
    let top24: u64x4 = rotated >> 8;
    let t = top24.as_array();
    [t[0] as i32, t[1] as i32, t[2] as i32, t[3] as i32]
}

/// `a · b mod 2⁶⁴`, lane by lane, from 32-bit halves (AVX2 multiplies
/// 32 by 32 bits): `lo·lo + ((hi·lo + lo·hi) << 32)`.
#[inline(always)]
fn mul_u64(a: u64x4, b: u64x4) -> u64x4 {
    mul_lo32(a, b) + ((mul_lo32(a >> 32, b) + mul_lo32(a, b >> 32)) << 32)
}

/// The full 64-bit products of the lanes' low 32 bits (LLVM makes the
/// masked product one `vpmuludq`).
#[inline(always)]
fn mul_lo32(a: u64x4, b: u64x4) -> u64x4 {
    let low32 = u64x4::splat(u32::MAX.into());
    (a & low32) * (b & low32)
}

/// The SplitMix64 finaliser: a bijective 64-bit mix.
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_are_rand_pcg_draws() {
        // PathRng keeps Pcg32's words; the numbers are Pcg32's own.
        let mut ours = PathRng::new(42, 7, 3);
        let state = splitmix64(42 ^ splitmix64((7u64 << 32) | 3));
        let mut theirs = Pcg32::new(state, 42);
        for _ in 0..100 {
            let want = (theirs.next_u32() >> 8) as f32 / 16_777_216.0;
            assert_eq!(ours.next_f32().to_bits(), want.to_bits());
        }
    }

    /// Eight streams at once draw each stream's own numbers, full groups
    /// and partial ones alike.
    #[test]
    fn eight_streams_draw_their_own_numbers() {
        let sampler = Independent::new(3);
        for lanes in 0..=8 {
            let start: Vec<PathRng> = (0..lanes).map(|l| sampler.start(l * 977, l + 5)).collect();
            let (mut eight, mut one) = (start.clone(), start);
            for _ in 0..50 {
                let [a, b] = sampler.next_2d_8(&mut eight);
                let c = sampler.next_8(&mut eight);
                for (l, p) in one.iter_mut().enumerate() {
                    let want = [0; 3].map(|_| p.next_f32().to_bits());
                    let got = [a, b, c].map(|v| v.to_array()[l].to_bits());
                    assert_eq!(got, want, "{lanes} lanes, lane {l}");
                }
            }
            assert_eq!(eight, one);
        }
    }

    #[test]
    fn streams_differ_by_pixel_sample_and_seed() {
        let first = |s, p, i| PathRng::new(s, p, i).next_f32();
        let a = first(1, 0, 0);
        assert_ne!(a, first(1, 1, 0));
        assert_ne!(a, first(1, 0, 1));
        assert_ne!(a, first(2, 0, 0));
        assert_eq!(a, first(1, 0, 0));
    }

    #[test]
    fn independent_dimensions_are_the_stream_in_order() {
        let sampler = Independent::new(9);
        let mut path = sampler.start(4, 2);
        let mut rng = PathRng::new(9, 4, 2);
        for _ in 0..10 {
            assert_eq!(sampler.next(&mut path).to_bits(), rng.next_f32().to_bits());
        }
    }
}
