//! Texture lookups lane by lane, for the wavefront engine: a lookup is a
//! gather, so it runs the scalar [`Texture::sample`] in every lane and
//! gives its bits exactly. (It lives here, not in `scene`, because the
//! lanes are the accelerator layer's [`Lanes`].)

use crate::accel::simd::Lanes;
use crate::scene::texture::{Sampler, Texture};
use std::cell::Cell;
use std::time::Instant;

thread_local! {
    /// This thread's seconds in [`timed`] work since [`take_seconds`].
    static SECONDS: Cell<f64> = const { Cell::new(0.0) };
}

/// Run `f`, a group of texture lookups (and the material parameters they
/// make), adding its wall-clock time to this thread's texture clock: how
/// `--stats` and `wavetrace bench` tell the share of the time textures
/// take. Call it around a group of lanes, not one lookup: a clock reading
/// costs some tens of nanoseconds.
#[inline]
pub fn timed<T>(f: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let out = f();
    let dt = start.elapsed().as_secs_f64();
    SECONDS.with(|s| s.set(s.get() + dt));
    out
}

/// This thread's texture seconds since the last call (and the clock
/// back to zero).
pub fn take_seconds() -> f64 {
    SECONDS.with(|s| s.replace(0.0))
}

/// [`Texture::sample`] for every lane of `u` and `v` (8 or 16 lanes):
/// the same bits, lane by lane, as channels R, G, B, A.
#[inline]
pub fn sample_lanes<L: Lanes>(texture: &Texture, sampler: Sampler, u: L, v: L) -> [L; 4] {
    const MAX: usize = 16;
    assert!(L::LANES <= MAX);
    let (mut us, mut vs) = ([0.0f32; MAX], [0.0f32; MAX]);
    u.write_to(&mut us[..L::LANES]);
    v.write_to(&mut vs[..L::LANES]);
    let mut out = [[0.0f32; MAX]; 4];
    for l in 0..L::LANES {
        let t = texture.sample(sampler, us[l], vs[l]);
        for (c, value) in t.into_iter().enumerate() {
            out[c][l] = value;
        }
    }
    out.map(|c| L::from_slice(&c[..L::LANES], 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(target_arch = "x86_64")]
    use crate::accel::simd::F32x16;
    use crate::accel::simd::SimdWidth;
    use crate::scene::texture::{ColourSpace, Filter, Wrap};
    use wide::f32x8;

    fn ramp() -> Texture {
        // 5 × 3, every texel distinct in every channel.
        let texels = (0..15u8)
            .map(|k| [k * 17, 255 - k * 13, k * 7, 255 - k])
            .collect();
        Texture::from_rgba8(5, 3, texels, ColourSpace::Srgb).unwrap()
    }

    fn lanes_equal_scalar<L: Lanes>() {
        let t = ramp();
        let mut k = 0u32;
        let mut next = || {
            k = k.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (k >> 8) as f32 / (1u32 << 24) as f32 * 6.0 - 3.0
        };
        for wrap in [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat] {
            for filter in [Filter::Nearest, Filter::Linear] {
                let s = Sampler {
                    wrap_u: wrap,
                    wrap_v: wrap,
                    filter,
                };
                for _ in 0..500 {
                    let us: Vec<f32> = (0..L::LANES).map(|_| next()).collect();
                    let vs: Vec<f32> = (0..L::LANES).map(|_| next()).collect();
                    let out = sample_lanes(&t, s, L::from_slice(&us, 0.0), L::from_slice(&vs, 0.0));
                    for l in 0..L::LANES {
                        let want = t.sample(s, us[l], vs[l]);
                        for c in 0..4 {
                            assert_eq!(out[c].to_vec()[l].to_bits(), want[c].to_bits());
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn lanes_give_the_scalar_bits_at_8_and_16() {
        lanes_equal_scalar::<f32x8>();
        #[cfg(target_arch = "x86_64")]
        if SimdWidth::W16.is_available() {
            #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
            fn at_16() {
                lanes_equal_scalar::<F32x16>();
            }
            // SAFETY: the CPU has AVX-512 (checked just above).
            unsafe { at_16() };
        }
    }
}
