//! Random numbers and the report's hemisphere sampling.
//!
//! Every random number a path uses comes from its own PCG stream keyed by
//! `(seed, pixel, sample)`, so an image depends only on the seed — never on
//! the thread count, the batch size or the order work is scheduled in. A
//! path draws, in order: two numbers to jitter the camera sample over its
//! pixel, then two numbers (`X1`, `X2`) at every surface it bounces from.

use crate::math::{Real, V3, sin_cos_2pi};
use rand_core::Rng;
use rand_pcg::Pcg32;

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
}

/// The SplitMix64 finaliser: a bijective 64-bit mix.
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A direction on the hemisphere around unit normal `n`, uniform in solid
/// angle (pdf `1/2π`), from two uniform numbers — the report's method.
///
/// In the local frame with `n` as the y axis: `cos θ = X1`,
/// `sin θ = sqrt(1 - X1²)`, `φ = 2π·X2`,
/// `(x, y, z) = (sin θ cos φ, X1, sin θ sin φ)`. The frame around `n` is
/// Scratchapixel's (the report's reference \[3\]): a tangent `nt` orthogonal
/// to `n` built from its two largest components, and `nb = n × nt`.
#[inline(always)]
pub fn uniform_hemisphere<R: Real>(n: V3<R>, x1: R, x2: R) -> V3<R> {
    let sin_theta = (-x1).mul_add(x1, R::splat(1.0)).sqrt();
    let (sin_phi, cos_phi) = sin_cos_2pi(x2);
    let (lx, ly, lz) = (sin_theta * cos_phi, x1, sin_theta * sin_phi);

    let zero = R::splat(0.0);
    let use_x = n.y.abs().lt(n.x.abs());
    let inv_xz = R::splat(1.0) / (n.x * n.x + n.z * n.z).sqrt();
    let inv_yz = R::splat(1.0) / (n.y * n.y + n.z * n.z).sqrt();
    let nt = V3::select(
        use_x,
        V3::new(n.z * inv_xz, zero, -n.x * inv_xz),
        V3::new(zero, -n.z * inv_yz, n.y * inv_yz),
    );
    let nb = n.cross(nt);
    nb.mul_add(lx, n.mul_add(ly, nt.scale(lz)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use wide::f32x8;

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
    fn simd_hemisphere_equals_scalar_bitwise() {
        let mut rng = PathRng::new(7, 3, 9);
        for _ in 0..5_000 {
            let ns: [glam::Vec3; 8] = std::array::from_fn(|_| {
                let v = glam::Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                );
                v.try_normalize().unwrap_or(glam::Vec3::Y)
            });
            let x1: [f32; 8] = std::array::from_fn(|_| rng.next_f32());
            let x2: [f32; 8] = std::array::from_fn(|_| rng.next_f32());
            let n8 = V3::new(
                f32x8::from(ns.map(|n| n.x)),
                f32x8::from(ns.map(|n| n.y)),
                f32x8::from(ns.map(|n| n.z)),
            );
            let d8 = uniform_hemisphere(n8, f32x8::from(x1), f32x8::from(x2));
            for l in 0..8 {
                let d = uniform_hemisphere(V3::from(ns[l]), x1[l], x2[l]);
                assert_eq!(d.x.to_bits(), d8.x.to_array()[l].to_bits());
                assert_eq!(d.y.to_bits(), d8.y.to_array()[l].to_bits());
                assert_eq!(d.z.to_bits(), d8.z.to_array()[l].to_bits());
            }
        }
    }
}
