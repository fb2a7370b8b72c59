//! Texture lookups 8 or 16 lanes at a time, for the wavefront engine:
//! [`Texture::sample`]'s arithmetic in lanes (the wrap, the texel
//! coordinates, the bilinear weights, the filter, in the same order, so
//! every lane gives the scalar lookup's bits), the texels gathered from
//! the texture's tiles ([`texel_address`], the one address computation)
//! and decoded through its table by gathers. (It lives here, not in
//! `scene`, because the lanes are the accelerator layer's [`Lanes`].)
//!
//! The wrap is computed in floats, exactly: texel coordinates are integers
//! below 2²² in magnitude there, and the remainder by the side `n` is
//! `i − n⌊i/n⌋` with the quotient corrected by one either way. Lookups
//! with a coordinate past that (`|u · width| ≥ 2²²`, which the scalar
//! lookup takes to 64-bit integers) go lane by lane through
//! [`Texture::sample`] ([`sample_by_lane`]).

use crate::accel::simd::{Lanes, SimdWidth};
use crate::scene::texture::{
    ColourSpace, Filter, Sampler, TexelIndex, Texture, Wrap, texel_address,
};
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

/// The largest texel coordinate (in magnitude, exclusive) the lanes
/// compute: below it every integer, plus one, is exact in `f32` and the
/// wrap's quotient is off by at most one.
const LANE_LIMIT: f32 = (1 << 22) as f32;

/// [`Texture::sample`] for every lane of `u` and `v` (8 or 16 lanes):
/// the same bits, lane by lane, as channels R, G, B, A.
#[inline(always)]
pub fn sample_lanes<L: Lanes>(texture: &Texture, sampler: Sampler, u: L, v: L) -> [L; 4] {
    // Coordinates that are not finite read as 0.
    let (u, v) = (finite(u), finite(v));
    let (w, h) = (texture.width() as f32, texture.height() as f32);
    match sampler.filter {
        Filter::Nearest => {
            let (x, y) = (u * L::splat(w), v * L::splat(h));
            if far(x, y) {
                return sample_by_lane(texture, sampler, u, v);
            }
            let i = wrap(sampler.wrap_u, x.floor(), w);
            let j = wrap(sampler.wrap_v, y.floor(), h);
            fetch(texture, i, j)
        }
        Filter::Linear => {
            let x = u.mul_add(L::splat(w), L::splat(-0.5));
            let y = v.mul_add(L::splat(h), L::splat(-0.5));
            if far(x, y) {
                return sample_by_lane(texture, sampler, u, v);
            }
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let one = L::splat(1.0);
            let i0 = wrap(sampler.wrap_u, x0, w);
            let i1 = wrap(sampler.wrap_u, x0 + one, w);
            let j0 = wrap(sampler.wrap_v, y0, h);
            let j1 = wrap(sampler.wrap_v, y0 + one, h);
            let (a, b) = (fetch(texture, i0, j0), fetch(texture, i1, j0));
            let (c, d) = (fetch(texture, i0, j1), fetch(texture, i1, j1));
            // (Written out, not through closures, `array::from_fn` or
            // `map`: those may be compiled apart from the AVX-512 function
            // this is inlined into, and called.)
            [
                bilinear(a[0], b[0], c[0], d[0], fx, fy),
                bilinear(a[1], b[1], c[1], d[1], fx, fy),
                bilinear(a[2], b[2], c[2], d[2], fx, fy),
                bilinear(a[3], b[3], c[3], d[3], fx, fy),
            ]
        }
    }
}

/// `x` where it is finite, else 0 (`|x| ≤ MAX` is false for infinities
/// and NaN).
#[inline(always)]
fn finite<L: Lanes>(x: L) -> L {
    L::select(x.abs().le(L::splat(f32::MAX)), x, L::splat(0.0))
}

/// Whether some lane of `x` or `y` is too far out for the lanes
/// ([`LANE_LIMIT`]).
#[inline(always)]
fn far<L: Lanes>(x: L, y: L) -> bool {
    let limit = L::splat(LANE_LIMIT);
    L::any(limit.le(x.abs()) | limit.le(y.abs()))
}

/// The texel index `i` (an integer, `|i| < 2²²`) brought into `[0, n)` by
/// `mode`, as [`Wrap`] defines it (`Wrap::index`), in floats.
#[inline(always)]
fn wrap<L: Lanes>(mode: Wrap, i: L, n: f32) -> L {
    match mode {
        Wrap::Repeat => rem_euclid(i, n),
        Wrap::ClampToEdge => i.max(L::splat(0.0)).min(L::splat(n - 1.0)),
        Wrap::MirroredRepeat => {
            let m = rem_euclid(i, 2.0 * n);
            L::select(m.lt(L::splat(n)), m, L::splat(2.0 * n - 1.0) - m)
        }
    }
}

/// `i mod n` in `[0, n)` for an integer `|i| < 2²²` and `1 ≤ n ≤ 2¹⁵`:
/// `i − n⌊i · (1/n)⌋`, exact (every term is an integer below 2²⁴), with
/// the quotient, off by at most one (the product's error is below ¼),
/// corrected.
#[inline(always)]
fn rem_euclid<L: Lanes>(i: L, n: f32) -> L {
    let nn = L::splat(n);
    let q = (i * L::splat(1.0 / n)).floor();
    let r = (-q).mul_add(nn, i);
    let r = L::select(r.lt(L::splat(0.0)), r + nn, r);
    L::select(nn.le(r), r - nn, r)
}

/// The texels `(i, j)` (integers in range, as floats), gathered and
/// decoded: RGB through the texture's table, alpha linear.
#[inline(always)]
fn fetch<L: Lanes>(texture: &Texture, i: L, j: L) -> [L; 4] {
    let across = L::Index::splat_index(texture.tiles_across() as i32);
    let at = texel_address(i.to_index(), j.to_index(), across);
    let t = L::gather_texels(texture.tiled_texels(), at);
    let alpha = L::index_to_float(t.shr(24)) / L::splat(255.0);
    [
        channel(texture, t, 0),
        channel(texture, t, 8),
        channel(texture, t, 16),
        alpha,
    ]
}

/// The value of the byte at bit `shift` of the texels `t` (red, green or
/// blue): through the texture's table.
#[inline(always)]
fn channel<L: Lanes>(texture: &Texture, t: L::Index, shift: u32) -> L {
    match texture.space() {
        // The linear table is `k as f32 / 255.0`: the same bits without
        // the gathers.
        ColourSpace::Linear => {
            L::index_to_float(t.shr(shift) & L::Index::splat_index(255)) / L::splat(255.0)
        }
        ColourSpace::Srgb => L::gather_table(texture.table(), t.shr(shift)),
    }
}

/// Bilinear between the corners `a`, `b` (the top row) and `c`, `d` (the
/// bottom one) by `fx` across and `fy` down, in [`Texture::sample`]'s
/// order of operations.
#[inline(always)]
fn bilinear<L: Lanes>(a: L, b: L, c: L, d: L, fx: L, fy: L) -> L {
    let top = (b - a).mul_add(fx, a);
    let bottom = (d - c).mul_add(fx, c);
    (bottom - top).mul_add(fy, top)
}

/// [`Texture::sample`] run lane by lane: the lane lookups' oracle (and
/// their way for coordinates too far out to compute in lanes).
#[inline]
pub fn sample_by_lane<L: Lanes>(texture: &Texture, sampler: Sampler, u: L, v: L) -> [L; 4] {
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

/// How [`sample_columns`] looks a chunk of lanes up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LaneLookup {
    /// In lanes ([`sample_lanes`]).
    Lanes,
    /// Lane by lane through [`Texture::sample`] ([`sample_by_lane`]): the
    /// oracle, and the way before the lanes (for benchmarks).
    ByLane,
}

/// `out[c][k] = texture.sample(sampler, u[k], v[k])[c]` for every `k`,
/// `width`'s lanes at a time (16 only where the CPU has AVX-512; else 8).
/// `u`, `v` and the four columns of `out` must be of one length.
pub fn sample_columns(
    texture: &Texture,
    sampler: Sampler,
    (width, how): (SimdWidth, LaneLookup),
    (u, v): (&[f32], &[f32]),
    out: [&mut [f32]; 4],
) {
    assert!(u.len() == v.len() && out.iter().all(|c| c.len() == u.len()));
    #[cfg(target_arch = "x86_64")]
    if width == SimdWidth::W16 && SimdWidth::W16.is_available() {
        #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
        fn at_16(
            t: &Texture,
            s: Sampler,
            how: LaneLookup,
            uv: (&[f32], &[f32]),
            out: [&mut [f32]; 4],
        ) {
            columns::<crate::accel::simd::F32x16>(t, s, how, uv, out);
        }
        // SAFETY: the CPU has AVX-512 (checked just above).
        unsafe { at_16(texture, sampler, how, (u, v), out) };
        return;
    }
    let _ = width;
    columns::<wide::f32x8>(texture, sampler, how, (u, v), out);
}

/// [`sample_columns`] at `L`'s width.
#[inline(always)]
fn columns<L: Lanes>(
    texture: &Texture,
    sampler: Sampler,
    how: LaneLookup,
    (u, v): (&[f32], &[f32]),
    mut out: [&mut [f32]; 4],
) {
    let n = L::LANES;
    for start in (0..u.len()).step_by(n) {
        let end = (start + n).min(u.len());
        let (lu, lv) = (
            L::from_slice(&u[start..end], 0.0),
            L::from_slice(&v[start..end], 0.0),
        );
        let got = match how {
            LaneLookup::Lanes => sample_lanes(texture, sampler, lu, lv),
            LaneLookup::ByLane => sample_by_lane(texture, sampler, lu, lv),
        };
        for (c, col) in got.into_iter().zip(out.iter_mut()) {
            c.write_to(&mut col[start..end]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(target_arch = "x86_64")]
    use crate::accel::simd::F32x16;
    use wide::f32x8;

    /// A `w × h` texture whose texels differ from each other in every
    /// channel (as far as 256 values allow), in colour space `space`.
    fn ramp(w: usize, h: usize, space: ColourSpace) -> Texture {
        let texels = (0..w * h)
            .map(|k| {
                let k = k as u32;
                [k * 17 + 3, 255 - k * 13, k * 7 + 100, 255 - k * 5].map(|c| (c % 256) as u8)
            })
            .collect();
        Texture::from_rgba8(w, h, texels, space).unwrap()
    }

    /// The sizes the lanes are held to: a single texel, single rows and
    /// columns, odd and even sides, whole tiles and part tiles.
    /// (25 and 29, and their doubles for the mirrored wrap, are sides
    /// whose reciprocal rounds down in `f32`.)
    const SIZES: [(usize, usize); 9] = [
        (1, 1),
        (5, 3),
        (1, 7),
        (6, 1),
        (7, 9),
        (16, 8),
        (4, 4),
        (13, 5),
        (25, 29),
    ];

    /// A coordinate of kind `kind` from the random number `r` in [0, 1):
    /// ordinary ones around the image, ones on texel edges and centres,
    /// far ones (past the lanes' limit), and awkward ones.
    fn coordinate(kind: u32, r: f32, side: usize) -> f32 {
        let n = side as f32;
        match kind % 8 {
            0 | 1 => r * 6.0 - 3.0,
            // On a texel's edge or centre, in a few copies of the image.
            2 => ((r * 64.0).floor() - 32.0) / (2.0 * n),
            3 => r * 2e6 - 1e6,
            4 => (r - 0.5) * (LANE_LIMIT / n) * 2.5,
            5 => [
                f32::NAN,
                f32::INFINITY,
                -f32::INFINITY,
                -0.0,
                1e30,
                -1e30,
                f32::MAX,
                1e-40,
            ][(r * 8.0) as usize % 8],
            // Just below and above 0 and 1.
            6 => [0.0f32, 1.0][(r * 2.0) as usize % 2] + (r - 0.5) * 1e-6,
            _ => r,
        }
    }

    fn lanes_equal_scalar<L: Lanes>() {
        let mut k = 0u32;
        let mut next = || {
            k = k.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            k
        };
        let mut checked = 0;
        for (w, h) in SIZES {
            for space in [ColourSpace::Srgb, ColourSpace::Linear] {
                let t = ramp(w, h, space);
                let wraps = [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat];
                for (wrap_u, wrap_v) in wraps.into_iter().flat_map(|a| wraps.map(|b| (a, b))) {
                    for filter in [Filter::Nearest, Filter::Linear] {
                        let s = Sampler {
                            wrap_u,
                            wrap_v,
                            filter,
                        };
                        for round in 0..48 {
                            // Every lane of a kind (so that most vectors
                            // stay in lanes) or each lane its own.
                            let mut coords = |side| -> Vec<f32> {
                                (0..L::LANES)
                                    .map(|_| {
                                        let kind = if round % 2 == 0 { round / 2 } else { next() };
                                        let r = (next() >> 8) as f32 / (1u32 << 24) as f32;
                                        coordinate(kind, r, side)
                                    })
                                    .collect()
                            };
                            let (us, vs) = (coords(w), coords(h));
                            let (u, v) = (L::from_slice(&us, 0.0), L::from_slice(&vs, 0.0));
                            let out = sample_lanes(&t, s, u, v).map(|c| c.to_vec());
                            for l in 0..L::LANES {
                                let want = t.sample(s, us[l], vs[l]);
                                for c in 0..4 {
                                    assert_eq!(
                                        out[c][l].to_bits(),
                                        want[c].to_bits(),
                                        "{} lanes, {w} × {h} {space:?} {s:?}, lane {l} at \
                                         ({}, {}), channel {c}: {} for {}",
                                        L::LANES,
                                        us[l],
                                        vs[l],
                                        out[c][l],
                                        want[c]
                                    );
                                }
                                checked += 1;
                            }
                        }
                    }
                }
            }
        }
        assert_eq!(checked, SIZES.len() * 2 * 9 * 2 * 48 * L::LANES);
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

    /// [`rem_euclid`] in lanes against `i64::rem_euclid`, for sides whose
    /// reciprocal rounds up, down or not at all in `f32` (up to 2¹⁵, the
    /// mirrored wrap's `2n`), at every multiple of the side and its
    /// neighbours across the lanes' range, and at random integers.
    fn remainders_are_exact<L: Lanes>() {
        let sides = [
            1, 2, 3, 5, 7, 25, 29, 31, 41, 50, 97, 100, 1000, 1023, 4097, 16383, 32768,
        ];
        let mut k = 99u32;
        let mut next = || {
            k = k.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            k
        };
        let limit = LANE_LIMIT as i64;
        for n in sides {
            let mut is: Vec<i64> = Vec::new();
            // Every multiple of n (and ±1) for small quotients, then a
            // geometric sweep of quotients to the limit.
            let mut q = 1i64;
            while q * n < limit {
                for d in [-1, 0, 1] {
                    is.extend([q * n + d, -(q * n) + d]);
                }
                q = if q < 4096 { q + 1 } else { q + q / 64 };
            }
            is.extend((0..4096).map(|_| (next() as i64 % (2 * limit - 1)) - (limit - 1)));
            is.retain(|i| i.abs() < limit);
            for chunk in is.chunks(L::LANES) {
                let x: Vec<f32> = chunk.iter().map(|&i| i as f32).collect();
                let got = rem_euclid(L::from_slice(&x, 0.0), n as f32).to_vec();
                for (l, &i) in chunk.iter().enumerate() {
                    assert_eq!(got[l], i.rem_euclid(n) as f32, "{i} mod {n}");
                }
            }
        }
    }

    #[test]
    fn wrapped_indices_are_exact_at_8_and_16() {
        remainders_are_exact::<f32x8>();
        #[cfg(target_arch = "x86_64")]
        if SimdWidth::W16.is_available() {
            #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
            fn at_16() {
                remainders_are_exact::<F32x16>();
            }
            // SAFETY: the CPU has AVX-512 (checked just above).
            unsafe { at_16() };
        }
    }

    #[test]
    fn columns_give_the_scalar_bits_at_every_width_and_length() {
        let t = ramp(7, 9, ColourSpace::Srgb);
        let s = Sampler::default();
        for len in [0, 1, 7, 8, 9, 16, 37] {
            let u: Vec<f32> = (0..len).map(|k| k as f32 * 0.173 - 2.0).collect();
            let v: Vec<f32> = (0..len).map(|k| k as f32 * -0.311 + 1.5).collect();
            for width in [SimdWidth::W8, SimdWidth::W16] {
                for how in [LaneLookup::Lanes, LaneLookup::ByLane] {
                    let mut out = vec![vec![f32::NAN; len]; 4];
                    let [r, g, b, a] = &mut out[..] else {
                        unreachable!()
                    };
                    sample_columns(&t, s, (width, how), (&u, &v), [r, g, b, a]);
                    for k in 0..len {
                        let want = t.sample(s, u[k], v[k]);
                        for c in 0..4 {
                            assert_eq!(
                                out[c][k].to_bits(),
                                want[c].to_bits(),
                                "{width:?} {how:?}, {len} long, row {k}, channel {c}"
                            );
                        }
                    }
                }
            }
        }
    }
}
