//! SIMD widths for the intersection kernels: 8 lanes (AVX2, every x86-64-v3
//! CPU) or 16 (AVX-512, chosen at run time where the CPU has it).
//!
//! The binary is built for x86-64-v3. The 16-lane kernels live in functions
//! compiled with `#[target_feature(enable = "avx512f,...")]`, entered only
//! after [`SimdWidth::W16`] was found available by
//! `is_x86_feature_detected!`. Both widths run the same generic source
//! ([`moller_trumbore`](crate::accel::triangle::moller_trumbore) over a
//! [`Lanes`] type), so each lane does the same IEEE operations, fused
//! multiply-adds included, and the two give the same hits bit for bit.

use crate::math::Real;
use crate::scene::texture::TexelIndex;
use std::fmt::Debug;
use wide::{f32x4, f32x8, i32x8, u32x8};

/// How many triangles (and, for nodes, boxes) the hot kernels test at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SimdWidth {
    /// 8 lanes: 256-bit AVX2 + FMA, on every CPU this build runs on.
    W8,
    /// 16 lanes: 512-bit AVX-512 (F, VL, DQ, BW), where the CPU has it.
    W16,
}

impl SimdWidth {
    /// The widest width this CPU runs, unless the environment variable
    /// `WAVETRACE_SIMD` is `8` or `16` (for comparisons; a width the CPU
    /// lacks falls back to 8).
    pub fn detect() -> Self {
        match std::env::var("WAVETRACE_SIMD").as_deref() {
            Ok("8") => SimdWidth::W8,
            Ok("16") if SimdWidth::W16.is_available() => SimdWidth::W16,
            _ => Self::widest(),
        }
    }

    /// The widest width this CPU runs.
    pub fn widest() -> Self {
        if SimdWidth::W16.is_available() {
            SimdWidth::W16
        } else {
            SimdWidth::W8
        }
    }

    /// The widths this CPU runs, narrowest first.
    pub fn available() -> Vec<SimdWidth> {
        [SimdWidth::W8, SimdWidth::W16]
            .into_iter()
            .filter(|w| w.is_available())
            .collect()
    }

    /// Whether this CPU runs this width.
    pub fn is_available(self) -> bool {
        match self {
            SimdWidth::W8 => true,
            SimdWidth::W16 => avx512_available(),
        }
    }

    /// The number of lanes: 8 or 16.
    pub fn lanes(self) -> usize {
        match self {
            SimdWidth::W8 => 8,
            SimdWidth::W16 => 16,
        }
    }

    /// How stats and the command line name it: `"avx2"` or `"avx512"`.
    pub fn name(self) -> &'static str {
        match self {
            SimdWidth::W8 => "avx2",
            SimdWidth::W16 => "avx512",
        }
    }

    /// The width with `lanes` lanes (8 or 16).
    pub fn from_lanes(lanes: usize) -> Option<Self> {
        match lanes {
            8 => Some(SimdWidth::W8),
            16 => Some(SimdWidth::W16),
            _ => None,
        }
    }
}

#[cfg(target_arch = "x86_64")]
fn avx512_available() -> bool {
    is_x86_feature_detected!("avx512f")
        && is_x86_feature_detected!("avx512vl")
        && is_x86_feature_detected!("avx512dq")
        && is_x86_feature_detected!("avx512bw")
        && is_x86_feature_detected!("fma")
}

#[cfg(not(target_arch = "x86_64"))]
fn avx512_available() -> bool {
    false
}

/// A [`Real`] with several lanes and the integer lanes that carry triangle
/// indices beside it: what the packs and the hierarchy are generic over.
pub trait Lanes: Real + Debug + Send + Sync + 'static {
    /// The number of lanes.
    const LANES: usize;
    /// One `i32` per lane.
    type Index: Copy + Debug + Send + Sync + TexelIndex;
    /// The lanes from `a` (at most [`Lanes::LANES`] values; the rest are
    /// `fill`). Needs no particular instruction set.
    fn from_slice(a: &[f32], fill: f32) -> Self;
    /// The integer lanes from `a` (the rest are `fill`).
    fn index_from_slice(a: &[i32], fill: i32) -> Self::Index;
    /// The same index in every lane.
    fn index_splat(i: i32) -> Self::Index;
    /// `a < b` lane-wise.
    fn index_lt(a: Self::Index, b: Self::Index) -> Self::Mask;
    /// `if m { a } else { b }` lane-wise.
    fn index_select(m: Self::Mask, a: Self::Index, b: Self::Index) -> Self::Index;
    /// Whether any lane of `m` is set.
    fn any(m: Self::Mask) -> bool;
    /// The lanes of `m` as bits (lane `l` is bit `l`).
    fn bits(m: Self::Mask) -> u32;
    /// `first + l` for each bit `l` set in `bits`, in increasing order,
    /// into the start of `out`; returns how many. May write up to
    /// [`Lanes::LANES`] values (`out` must have room for them).
    fn compress(bits: u32, first: u32, out: &mut [u32]) -> usize;
    /// The smallest lane (no lane may be NaN).
    fn min_lane(self) -> f32;
    /// The smallest index among the lanes whose value is `t`
    /// (`i32::MAX` where none).
    fn min_index_at(self, t: f32, index: Self::Index) -> i32;
    /// The lanes, in order (for tests and debugging).
    fn to_vec(self) -> Vec<f32>;
    /// The first `out.len()` lanes (at most [`Lanes::LANES`]) into `out`.
    fn write_to(self, out: &mut [f32]);
    /// The first `out.len()` integer lanes, as `u32`, into `out`.
    fn index_write_to(i: Self::Index, out: &mut [u32]);
    /// `⌊x⌋` lane-wise, as [`f32::floor`].
    fn floor(self) -> Self;
    /// Each lane, an integer in `(−2³¹, 2³¹)`, as an integer lane.
    fn to_index(self) -> Self::Index;
    /// Each integer lane as a float, as `i32 as f32`.
    fn index_to_float(i: Self::Index) -> Self;
    /// `texels[at]` for each lane (a gather), `at` read as `u32` and
    /// clamped to `texels.len() − 1`, so that no lane reads outside
    /// `texels` (which must not be empty).
    fn gather_texels(texels: &[u32], at: Self::Index) -> Self::Index;
    /// `table[at & 255]` for each lane (a gather).
    fn gather_table(table: &[f32; 256], at: Self::Index) -> Self;
    /// `table[at]` for each lane (a gather), `at` read as `u32` and
    /// clamped to `table.len() − 1`, so that no lane reads outside
    /// `table` (which must not be empty).
    fn gather_f32(table: &[f32], at: Self::Index) -> Self;
}

impl TexelIndex for i32x8 {
    #[inline(always)]
    fn splat_index(k: i32) -> Self {
        i32x8::splat(k)
    }
    #[inline(always)]
    fn shr(self, k: u32) -> Self {
        bytemuck::cast(bytemuck::cast::<i32x8, u32x8>(self) >> k)
    }
    #[inline(always)]
    fn shl(self, k: u32) -> Self {
        self << k
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self * o
    }
}

/// For each 8-bit mask, the numbers of its set bits in increasing order
/// (then zeros): [`Lanes::compress`] at 8 lanes.
static COMPRESS_8: [[u8; 8]; 256] = {
    let mut table = [[0u8; 8]; 256];
    let mut bits = 0;
    while bits < 256 {
        let (mut l, mut n) = (0, 0);
        while l < 8 {
            if bits & (1 << l) != 0 {
                table[bits][n] = l as u8;
                n += 1;
            }
            l += 1;
        }
        bits += 1;
    }
    table
};

impl Lanes for f32x8 {
    const LANES: usize = 8;
    type Index = i32x8;
    #[inline(always)]
    fn from_slice(a: &[f32], fill: f32) -> Self {
        // A whole vector is one load; a short one goes lane by lane.
        if let Some(full) = a.first_chunk::<8>() {
            return f32x8::from(*full);
        }
        f32x8::from(std::array::from_fn::<f32, 8, _>(|l| {
            a.get(l).copied().unwrap_or(fill)
        }))
    }
    #[inline(always)]
    fn index_from_slice(a: &[i32], fill: i32) -> i32x8 {
        if let Some(full) = a.first_chunk::<8>() {
            return i32x8::from(*full);
        }
        i32x8::from(std::array::from_fn::<i32, 8, _>(|l| {
            a.get(l).copied().unwrap_or(fill)
        }))
    }
    #[inline(always)]
    fn index_splat(i: i32) -> i32x8 {
        i32x8::splat(i)
    }
    #[inline(always)]
    fn index_lt(a: i32x8, b: i32x8) -> f32x8 {
        bytemuck::cast(a.simd_lt(b))
    }
    #[inline(always)]
    fn index_select(m: f32x8, a: i32x8, b: i32x8) -> i32x8 {
        bytemuck::cast::<f32x8, i32x8>(m).select(a, b)
    }
    #[inline(always)]
    fn any(m: f32x8) -> bool {
        m.any()
    }
    #[inline(always)]
    fn bits(m: f32x8) -> u32 {
        m.to_bitmask()
    }
    #[inline(always)]
    fn compress(bits: u32, first: u32, out: &mut [u32]) -> usize {
        // The set lanes' numbers, packed low, from a table; then all
        // eight stored at once.
        let packed = COMPRESS_8[(bits & 0xff) as usize].map(i32::from);
        let lanes = i32x8::from(packed) + i32x8::splat(first as i32);
        out[..8].copy_from_slice(&bytemuck::cast::<i32x8, [u32; 8]>(lanes));
        (bits & 0xff).count_ones() as usize
    }
    #[inline(always)]
    fn min_lane(self) -> f32 {
        // A tree of minima: 8 lanes -> 4 -> 2 -> 1 (no lane is NaN).
        let [lo, hi]: [f32x4; 2] = bytemuck::cast(self);
        let [a, b, c, d] = lo.fast_min(hi).to_array();
        let min = |x: f32, y: f32| if x < y { x } else { y };
        min(min(a, b), min(c, d))
    }
    #[inline(always)]
    fn min_index_at(self, t: f32, index: i32x8) -> i32 {
        let at: i32x8 = bytemuck::cast(self.simd_eq(f32x8::splat(t)));
        at.select(index, i32x8::splat(i32::MAX)).reduce_min()
    }
    fn to_vec(self) -> Vec<f32> {
        self.to_array().to_vec()
    }
    #[inline(always)]
    fn write_to(self, out: &mut [f32]) {
        // A whole vector is one store (a copy of a length known only at
        // run time is a call to `memcpy`); a short one is copied.
        match <&mut [_; 8]>::try_from(&mut *out) {
            Ok(full) => *full = self.to_array(),
            Err(_) => out.copy_from_slice(&self.to_array()[..out.len()]),
        }
    }
    #[inline(always)]
    fn index_write_to(i: i32x8, out: &mut [u32]) {
        let lanes: [u32; 8] = bytemuck::cast(i);
        match <&mut [_; 8]>::try_from(&mut *out) {
            Ok(full) => *full = lanes,
            Err(_) => out.copy_from_slice(&lanes[..out.len()]),
        }
    }
    #[inline(always)]
    fn floor(self) -> Self {
        f32x8::floor(self)
    }
    #[inline(always)]
    fn to_index(self) -> i32x8 {
        self.fast_trunc_int()
    }
    #[inline(always)]
    fn index_to_float(i: i32x8) -> Self {
        f32x8::from_i32x8(i)
    }
    #[inline(always)]
    fn gather_texels(texels: &[u32], at: i32x8) -> i32x8 {
        let last = u32x8::splat(texels.len() as u32 - 1);
        let at = bytemuck::cast::<i32x8, u32x8>(at).min(last);
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        {
            use std::arch::x86_64::{__m256i, _mm256_i32gather_epi32};
            // SAFETY: AVX2 is enabled at compile time (the `cfg` above);
            // every lane of `at` is at most `texels.len() − 1` (unsigned,
            // so never negative either), so each lane reads a `u32` inside
            // `texels`.
            unsafe {
                let at = bytemuck::cast::<u32x8, __m256i>(at);
                bytemuck::cast(_mm256_i32gather_epi32::<4>(texels.as_ptr().cast(), at))
            }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
        {
            let at: [u32; 8] = bytemuck::cast(at);
            i32x8::from(at.map(|k| texels[k as usize] as i32))
        }
    }
    #[inline(always)]
    fn gather_table(table: &[f32; 256], at: i32x8) -> Self {
        let at = at & i32x8::splat(255);
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        {
            use std::arch::x86_64::{__m256i, _mm256_i32gather_ps};
            // SAFETY: AVX2 is enabled at compile time (the `cfg` above);
            // every lane of `at` is in `0..256`, so each reads an `f32`
            // inside `table`.
            unsafe {
                let at = bytemuck::cast::<i32x8, __m256i>(at);
                bytemuck::cast(_mm256_i32gather_ps::<4>(table.as_ptr(), at))
            }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
        {
            let at: [i32; 8] = bytemuck::cast(at);
            f32x8::from(at.map(|k| table[k as usize]))
        }
    }
    #[inline(always)]
    fn gather_f32(table: &[f32], at: i32x8) -> Self {
        let last = u32x8::splat(table.len() as u32 - 1);
        let at = bytemuck::cast::<i32x8, u32x8>(at).min(last);
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        {
            use std::arch::x86_64::{__m256i, _mm256_i32gather_ps};
            // SAFETY: AVX2 is enabled at compile time (the `cfg` above);
            // every lane of `at` is at most `table.len() − 1` (unsigned,
            // so never negative either), so each lane reads an `f32`
            // inside `table`.
            unsafe {
                let at = bytemuck::cast::<u32x8, __m256i>(at);
                bytemuck::cast(_mm256_i32gather_ps::<4>(table.as_ptr(), at))
            }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
        {
            let at: [u32; 8] = bytemuck::cast(at);
            f32x8::from(at.map(|k| table[k as usize]))
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use x16::F32x16;

/// 16 lanes of AVX-512.
///
/// # Safety
///
/// Every method here executes AVX-512 instructions. A value of [`F32x16`]
/// is only ever made and used inside the hierarchy's 16-lane kernels, which
/// are reached only through `#[target_feature(enable = "avx512f,...")]`
/// functions, which are called only when [`SimdWidth::W16`] was found
/// available at run time. The methods are `#[inline(always)]`, so they are
/// compiled as part of those functions, with AVX-512 enabled. The type is
/// private to the crate: nothing outside can make one.
#[cfg(target_arch = "x86_64")]
mod x16 {
    use super::Lanes;
    use crate::math::Real;
    use crate::scene::texture::TexelIndex;
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Sub};

    /// Sixteen `f32` lanes in one AVX-512 register.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub(crate) struct F32x16(__m512);

    /// Sixteen `i32` lanes in one AVX-512 register.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub(crate) struct I32x16(__m512i);

    /// A lane mask: one bit per lane.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub(crate) struct Mask16(u16);

    // SAFETY (every `unsafe` block in this module): the instructions are
    // AVX-512F/DQ ones, and this code only runs on a CPU that has them (see
    // the module's documentation). None of the intrinsics touches memory
    // through a pointer except `_mm512_loadu_*`, whose pointers come from
    // arrays of exactly 16 lanes, `_mm512_storeu_si512` in `compress`,
    // whose pointer comes from a slice of exactly 16 lanes, and the gathers
    // of `gather_texels` and `gather_table`, whose lanes are clamped or
    // masked into their slices first (and `gather_f32`'s, clamped).

    impl Add for I32x16 {
        type Output = Self;
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_add_epi32(self.0, o.0) })
        }
    }

    impl BitAnd for I32x16 {
        type Output = Self;
        #[inline(always)]
        fn bitand(self, o: Self) -> Self {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_and_si512(self.0, o.0) })
        }
    }

    impl TexelIndex for I32x16 {
        #[inline(always)]
        fn splat_index(k: i32) -> Self {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_set1_epi32(k) })
        }
        #[inline(always)]
        fn shr(self, k: u32) -> Self {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_srlv_epi32(self.0, _mm512_set1_epi32(k as i32)) })
        }
        #[inline(always)]
        fn shl(self, k: u32) -> Self {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_sllv_epi32(self.0, _mm512_set1_epi32(k as i32)) })
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_mullo_epi32(self.0, o.0) })
        }
    }

    impl BitAnd for Mask16 {
        type Output = Self;
        #[inline(always)]
        fn bitand(self, o: Self) -> Self {
            Mask16(self.0 & o.0)
        }
    }

    impl BitOr for Mask16 {
        type Output = Self;
        #[inline(always)]
        fn bitor(self, o: Self) -> Self {
            Mask16(self.0 | o.0)
        }
    }

    macro_rules! binop {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for F32x16 {
                type Output = Self;
                #[inline(always)]
                fn $f(self, o: Self) -> Self {
                    // SAFETY: see the module's documentation.
                    F32x16(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }
    binop!(Add, add, _mm512_add_ps);
    binop!(Sub, sub, _mm512_sub_ps);
    binop!(Mul, mul, _mm512_mul_ps);
    binop!(Div, div, _mm512_div_ps);

    impl Neg for F32x16 {
        type Output = Self;
        /// Flips the sign bit (as `f32`'s and `f32x8`'s negation do).
        #[inline(always)]
        fn neg(self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe {
                _mm512_castsi512_ps(_mm512_xor_si512(
                    _mm512_castps_si512(self.0),
                    _mm512_set1_epi32(i32::MIN),
                ))
            })
        }
    }

    impl Real for F32x16 {
        type Mask = Mask16;
        type Id = [u32; 16];
        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe { _mm512_set1_ps(x) })
        }
        #[inline(always)]
        fn mul_add(self, a: Self, b: Self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe { _mm512_fmadd_ps(self.0, a.0, b.0) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe { _mm512_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe { _mm512_abs_ps(self.0) })
        }
        /// One `vmaxps`: `max_ps(a, b)` is `if a > b { a } else { b }`,
        /// so `max_ps(rhs, self)` is [`Real::max`]'s definition exactly
        /// (NaNs and signed zeros included).
        #[inline(always)]
        fn max(self, rhs: Self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe { _mm512_max_ps(rhs.0, self.0) })
        }
        /// One `vminps`: `min_ps(rhs, self)` is `if rhs < self { rhs }
        /// else { self }`, [`Real::min`]'s definition.
        #[inline(always)]
        fn min(self, rhs: Self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe { _mm512_min_ps(rhs.0, self.0) })
        }
        #[inline(always)]
        fn round_ties_even(self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe {
                _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(self.0)
            })
        }
        #[inline(always)]
        fn lt(self, rhs: Self) -> Mask16 {
            // SAFETY: see the module's documentation.
            Mask16(unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, rhs.0) })
        }
        #[inline(always)]
        fn le(self, rhs: Self) -> Mask16 {
            // SAFETY: see the module's documentation.
            Mask16(unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, rhs.0) })
        }
        #[inline(always)]
        fn eq(self, rhs: Self) -> Mask16 {
            // SAFETY: see the module's documentation.
            Mask16(unsafe { _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(self.0, rhs.0) })
        }
        #[inline(always)]
        fn ne(self, rhs: Self) -> Mask16 {
            // SAFETY: see the module's documentation.
            Mask16(unsafe { _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(self.0, rhs.0) })
        }
        #[inline(always)]
        fn select(mask: Mask16, a: Self, b: Self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe { _mm512_mask_blend_ps(mask.0, b.0, a.0) })
        }
    }

    impl Lanes for F32x16 {
        const LANES: usize = 16;
        type Index = I32x16;
        #[inline(always)]
        fn from_slice(a: &[f32], fill: f32) -> Self {
            // A whole vector is one load; a short one goes lane by lane.
            let v: [f32; 16] = match a.first_chunk::<16>() {
                Some(full) => *full,
                None => std::array::from_fn(|l| a.get(l).copied().unwrap_or(fill)),
            };
            // SAFETY: `__m512` is 64 bytes that any bit pattern is valid for;
            // a reinterpretation needs no instruction.
            F32x16(unsafe { std::mem::transmute::<[f32; 16], __m512>(v) })
        }
        #[inline(always)]
        fn index_from_slice(a: &[i32], fill: i32) -> I32x16 {
            let v: [i32; 16] = match a.first_chunk::<16>() {
                Some(full) => *full,
                None => std::array::from_fn(|l| a.get(l).copied().unwrap_or(fill)),
            };
            // SAFETY: as in `from_slice`.
            I32x16(unsafe { std::mem::transmute::<[i32; 16], __m512i>(v) })
        }
        #[inline(always)]
        fn index_splat(i: i32) -> I32x16 {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_set1_epi32(i) })
        }
        #[inline(always)]
        fn index_lt(a: I32x16, b: I32x16) -> Mask16 {
            // SAFETY: see the module's documentation.
            Mask16(unsafe { _mm512_cmplt_epi32_mask(a.0, b.0) })
        }
        #[inline(always)]
        fn index_select(m: Mask16, a: I32x16, b: I32x16) -> I32x16 {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_mask_blend_epi32(m.0, b.0, a.0) })
        }
        #[inline(always)]
        fn any(m: Mask16) -> bool {
            m.0 != 0
        }
        #[inline(always)]
        fn bits(m: Mask16) -> u32 {
            m.0 as u32
        }
        #[inline(always)]
        fn compress(bits: u32, first: u32, out: &mut [u32]) -> usize {
            let out = &mut out[..16];
            // SAFETY: see the module's documentation; the store writes the
            // 64 bytes of `out`, 16 lanes long.
            unsafe {
                let lanes = _mm512_add_epi32(
                    _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0),
                    _mm512_set1_epi32(first as i32),
                );
                // The set lanes packed low in a register, then stored
                // whole (a compressing store to memory is slow on Zen 4).
                let packed = _mm512_maskz_compress_epi32(bits as u16, lanes);
                _mm512_storeu_si512(out.as_mut_ptr().cast(), packed);
            }
            bits.count_ones() as usize
        }
        #[inline(always)]
        fn min_lane(self) -> f32 {
            // SAFETY: see the module's documentation. (The minimum of
            // non-NaN values does not depend on the order of the tree.)
            unsafe { _mm512_reduce_min_ps(self.0) }
        }
        #[inline(always)]
        fn min_index_at(self, t: f32, index: I32x16) -> i32 {
            // SAFETY: see the module's documentation.
            unsafe {
                let at = _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(self.0, _mm512_set1_ps(t));
                _mm512_mask_reduce_min_epi32(at, index.0)
            }
        }
        #[inline(always)]
        fn to_vec(self) -> Vec<f32> {
            // SAFETY: `__m512` and `[f32; 16]` are the same 64 bytes; a
            // reinterpretation needs no instruction.
            unsafe { std::mem::transmute::<__m512, [f32; 16]>(self.0) }.to_vec()
        }
        #[inline(always)]
        fn write_to(self, out: &mut [f32]) {
            // SAFETY: as in `to_vec`.
            let lanes = unsafe { std::mem::transmute::<__m512, [f32; 16]>(self.0) };
            // A whole vector is one store (see the 8-lane `write_to`).
            match <&mut [_; 16]>::try_from(&mut *out) {
                Ok(full) => *full = lanes,
                Err(_) => out.copy_from_slice(&lanes[..out.len()]),
            }
        }
        #[inline(always)]
        fn index_write_to(i: I32x16, out: &mut [u32]) {
            // SAFETY: `__m512i` and `[u32; 16]` are the same 64 bytes.
            let lanes = unsafe { std::mem::transmute::<__m512i, [u32; 16]>(i.0) };
            match <&mut [_; 16]>::try_from(&mut *out) {
                Ok(full) => *full = lanes,
                Err(_) => out.copy_from_slice(&lanes[..out.len()]),
            }
        }
        #[inline(always)]
        fn floor(self) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe {
                _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(self.0)
            })
        }
        #[inline(always)]
        fn to_index(self) -> I32x16 {
            // SAFETY: see the module's documentation.
            I32x16(unsafe { _mm512_cvttps_epi32(self.0) })
        }
        #[inline(always)]
        fn index_to_float(i: I32x16) -> Self {
            // SAFETY: see the module's documentation.
            F32x16(unsafe { _mm512_cvtepi32_ps(i.0) })
        }
        #[inline(always)]
        fn gather_texels(texels: &[u32], at: I32x16) -> I32x16 {
            // SAFETY: see the module's documentation; every lane is
            // clamped (unsigned) to `texels.len() − 1` first, so each reads
            // a `u32` inside `texels`.
            I32x16(unsafe {
                let at = _mm512_min_epu32(at.0, _mm512_set1_epi32(texels.len() as i32 - 1));
                _mm512_i32gather_epi32::<4>(at, texels.as_ptr().cast())
            })
        }
        #[inline(always)]
        fn gather_table(table: &[f32; 256], at: I32x16) -> Self {
            // SAFETY: see the module's documentation; every lane is masked
            // into `0..256` first, so each reads an `f32` inside `table`.
            F32x16(unsafe {
                let at = _mm512_and_si512(at.0, _mm512_set1_epi32(255));
                _mm512_i32gather_ps::<4>(at, table.as_ptr())
            })
        }
        #[inline(always)]
        fn gather_f32(table: &[f32], at: I32x16) -> Self {
            // SAFETY: see the module's documentation; every lane is
            // clamped (unsigned) to `table.len() − 1` first, so each reads
            // an `f32` inside `table`.
            F32x16(unsafe {
                let at = _mm512_min_epu32(at.0, _mm512_set1_epi32(table.len() as i32 - 1));
                _mm512_i32gather_ps::<4>(at, table.as_ptr())
            })
        }
    }
}
/// Prefetch `lines` cache lines from `p` on (into all cache levels).
#[inline(always)]
pub(crate) fn prefetch_lines<T>(p: &T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let base = (p as *const T).cast::<i8>();
        for k in 0..lines {
            // SAFETY: a prefetch is only a hint: it never faults and has no
            // effect on program state, whatever the address (and these
            // lines lie within the `T` at `p` and, in the callers, what
            // follows it in the same Vec). Measured: 2-3x faster batches of
            // walks on 1M triangles.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(base.wrapping_add(64 * k)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, lines);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `from_slice`, `index_from_slice`, `write_to` and `index_write_to`
    /// at every length from 0 to a whole vector (and a longer slice to
    /// read from): the slice's values in the first lanes, the fill in the
    /// rest, and exactly the slice's length written back.
    #[inline(always)]
    fn slices_round_trip<R: Lanes>() {
        let n = R::LANES;
        let a: Vec<f32> = (0..n + 3).map(|i| i as f32 + 0.5).collect();
        let ai: Vec<i32> = (0..n as i32 + 3).map(|i| 100 + i).collect();
        for len in 0..=n {
            let v = R::from_slice(&a[..len], -1.0);
            let want: Vec<f32> = (0..n).map(|l| if l < len { a[l] } else { -1.0 }).collect();
            assert_eq!(v.to_vec(), want, "{n} lanes: from_slice of {len}");
            let mut out = vec![9.0f32; n + 2];
            v.write_to(&mut out[..len]);
            assert_eq!(out[..len], a[..len], "{n} lanes: write_to of {len}");
            assert!(
                out[len..].iter().all(|&x| x == 9.0),
                "{n} lanes: wrote past {len}"
            );

            let i = R::index_from_slice(&ai[..len], -7);
            let mut out = vec![9u32; n + 2];
            R::index_write_to(i, &mut out[..n]);
            let want: Vec<u32> = (0..n)
                .map(|l| if l < len { ai[l] as u32 } else { -7i32 as u32 })
                .collect();
            assert_eq!(out[..n], want, "{n} lanes: index_from_slice of {len}");
            let mut out = vec![9u32; n + 2];
            R::index_write_to(i, &mut out[..len]);
            let want: Vec<u32> = ai[..len].iter().map(|&x| x as u32).collect();
            assert_eq!(out[..len], want, "{n} lanes: index_write_to of {len}");
            assert!(
                out[len..].iter().all(|&x| x == 9),
                "{n} lanes: wrote past {len}"
            );
        }
        let whole = R::from_slice(&a, -1.0).to_vec();
        assert_eq!(
            whole,
            a[..n],
            "{n} lanes: a longer slice gives its first lanes"
        );
    }

    /// `Real::min` and `Real::max` of every pair of awkward values (NaN,
    /// signed zeros, infinities, denormals) give the scalar definition's
    /// bits in every lane.
    #[inline(always)]
    fn min_max_as_scalar<R: Lanes>() {
        let vals = [
            0.0f32,
            -0.0,
            1.0,
            -2.5,
            f32::NAN,
            f32::INFINITY,
            -f32::INFINITY,
            1e-40,
            -1e30,
        ];
        for &a in &vals {
            for &b in &vals {
                let (va, vb) = (R::splat(a), R::splat(b));
                let want = |x: f32| vec![x.to_bits(); R::LANES];
                let bits = |v: R| v.to_vec().iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
                assert_eq!(
                    bits(Real::min(va, vb)),
                    want(Real::min(a, b)),
                    "{} lanes: min({a}, {b})",
                    R::LANES
                );
                assert_eq!(
                    bits(Real::max(va, vb)),
                    want(Real::max(a, b)),
                    "{} lanes: max({a}, {b})",
                    R::LANES
                );
            }
        }
    }

    /// `check::<f32x8>()`, then `check::<F32x16>()` where the CPU has
    /// AVX-512 (compiled with it: the 16-lane methods are only ever run
    /// inside such a function).
    macro_rules! at_every_width {
        ($check:ident) => {{
            $check::<f32x8>();
            #[cfg(target_arch = "x86_64")]
            if SimdWidth::W16.is_available() {
                #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
                fn at_16() {
                    $check::<F32x16>();
                }
                // SAFETY: the CPU has AVX-512 (checked just above).
                unsafe { at_16() };
            }
        }};
    }

    #[test]
    fn min_and_max_equal_the_scalar_definition_bitwise() {
        at_every_width!(min_max_as_scalar);
    }

    #[test]
    fn slices_load_and_store_whole_and_short() {
        at_every_width!(slices_round_trip);
    }
}
