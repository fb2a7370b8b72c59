//! One numeric source for scalar and 8-wide code.
//!
//! The reference tracer works on `f32`, the wavefront engine on `f32x8`
//! (8 lanes). Every kernel that both engines need — ray/triangle
//! intersection, hemisphere sampling, the hit point — is written once, generic
//! over [`Real`], and instantiated for both. Because each lane of an `f32x8`
//! operation is the same IEEE-754 operation as its `f32` twin — including
//! fused multiply-add, which is correctly rounded (one rounding) on every
//! instruction set — the two instantiations agree bit for bit.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Sub};
use wide::f32x8;

/// A float type: `f32` (one lane) or `f32x8` (eight lanes).
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// The result of a lane-wise comparison.
    type Mask: Copy + BitAnd<Output = Self::Mask> + BitOr<Output = Self::Mask>;
    /// An index per lane (of a primitive, of a material).
    type Id: Copy + std::fmt::Debug;
    /// The same value in every lane.
    fn splat(x: f32) -> Self;
    /// `self · a + b` with a single rounding (fused multiply-add).
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// Correctly rounded square root.
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Round to the nearest integer, ties to even.
    fn round_ties_even(self) -> Self;
    /// `self < rhs` lane-wise (false where either is NaN).
    fn lt(self, rhs: Self) -> Self::Mask;
    /// `self <= rhs` lane-wise (false where either is NaN).
    fn le(self, rhs: Self) -> Self::Mask;
    /// `self == rhs` lane-wise.
    fn eq(self, rhs: Self) -> Self::Mask;
    /// `self != rhs` lane-wise (true where either is NaN).
    fn ne(self, rhs: Self) -> Self::Mask;
    /// `if mask { a } else { b }` lane-wise.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;

    /// The same truth value in every lane.
    #[inline(always)]
    fn splat_mask(b: bool) -> Self::Mask {
        let z = Self::splat(0.0);
        if b { z.eq(z) } else { z.ne(z) }
    }
    /// The larger of the two, lane-wise: `if self < rhs { rhs } else { self }`
    /// — one definition for every instantiation (so a NaN in `rhs`, and
    /// the sign of a zero, resolve the same way in scalar and SIMD code).
    #[inline(always)]
    fn max(self, rhs: Self) -> Self {
        Self::select(self.lt(rhs), rhs, self)
    }
    /// The smaller of the two, lane-wise: `if rhs < self { rhs } else { self }`
    /// (see [`Real::max`]).
    #[inline(always)]
    fn min(self, rhs: Self) -> Self {
        Self::select(rhs.lt(self), rhs, self)
    }
}

impl Real for f32 {
    type Mask = bool;
    type Id = u32;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        // One `vfmadd` instruction where FMA is enabled (x86-64-v3);
        // a correctly rounded library call elsewhere.
        f32::mul_add(self, a, b)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn round_ties_even(self) -> Self {
        f32::round_ties_even(self)
    }
    #[inline(always)]
    fn lt(self, rhs: Self) -> bool {
        self < rhs
    }
    #[inline(always)]
    fn le(self, rhs: Self) -> bool {
        self <= rhs
    }
    #[inline(always)]
    fn eq(self, rhs: Self) -> bool {
        self == rhs
    }
    #[inline(always)]
    fn ne(self, rhs: Self) -> bool {
        self != rhs
    }
    #[inline(always)]
    fn select(mask: bool, a: Self, b: Self) -> Self {
        if mask { a } else { b }
    }
}

impl Real for f32x8 {
    type Mask = f32x8;
    type Id = [u32; 8];
    #[inline(always)]
    fn splat(x: f32) -> Self {
        f32x8::splat(x)
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        if cfg!(target_feature = "fma") {
            f32x8::mul_add(self, a, b)
        } else {
            // `wide` would round twice here; keep the single rounding (and so
            // the agreement with `f32::mul_add`) lane by lane.
            let (x, a, b) = (self.to_array(), a.to_array(), b.to_array());
            f32x8::from(std::array::from_fn::<f32, 8, _>(|l| {
                x[l].mul_add(a[l], b[l])
            }))
        }
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32x8::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x8::abs(self)
    }
    #[inline(always)]
    fn round_ties_even(self) -> Self {
        f32x8::round_ties_even(self)
    }
    #[inline(always)]
    fn lt(self, rhs: Self) -> f32x8 {
        self.simd_lt(rhs)
    }
    #[inline(always)]
    fn le(self, rhs: Self) -> f32x8 {
        self.simd_le(rhs)
    }
    #[inline(always)]
    fn eq(self, rhs: Self) -> f32x8 {
        self.simd_eq(rhs)
    }
    #[inline(always)]
    fn ne(self, rhs: Self) -> f32x8 {
        self.simd_ne(rhs)
    }
    #[inline(always)]
    fn select(mask: f32x8, a: Self, b: Self) -> Self {
        mask.select(a, b)
    }
}

/// A 3-vector of [`Real`]s: `V3<f32>` is one vector, `V3<f32x8>` eight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct V3<R> {
    /// x component.
    pub x: R,
    /// y component.
    pub y: R,
    /// z component.
    pub z: R,
}

/// Eight 3-vectors in structure-of-arrays form, one per lane.
pub type Vec3x8 = V3<f32x8>;

impl<R: Real> V3<R> {
    /// A vector from its components.
    #[inline(always)]
    pub fn new(x: R, y: R, z: R) -> Self {
        Self { x, y, z }
    }
    /// The same scalar vector in every lane.
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> Self {
        Self::new(R::splat(v.x), R::splat(v.y), R::splat(v.z))
    }
    /// Dot product: `x·x' + (y·y' + z·z')` with fused multiply-adds.
    #[inline(always)]
    pub fn dot(self, o: Self) -> R {
        self.x.mul_add(o.x, self.y.mul_add(o.y, self.z * o.z))
    }
    /// Cross product, each component `a·b - c·d` as one fused
    /// multiply-add.
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y.mul_add(o.z, -(self.z * o.y)),
            self.z.mul_add(o.x, -(self.x * o.z)),
            self.x.mul_add(o.y, -(self.y * o.x)),
        )
    }
    /// `self · s + b`, component-wise, with fused multiply-adds.
    #[inline(always)]
    pub fn mul_add(self, s: R, b: Self) -> Self {
        Self::new(
            self.x.mul_add(s, b.x),
            self.y.mul_add(s, b.y),
            self.z.mul_add(s, b.z),
        )
    }
    /// The largest absolute value of the components (the ∞-norm).
    #[inline(always)]
    pub fn max_abs(self) -> R {
        self.x.abs().max(self.y.abs()).max(self.z.abs())
    }
    /// Each component times `s`.
    #[inline(always)]
    pub fn scale(self, s: R) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
    /// Each component times the matching component of `o` (an RGB tint,
    /// say).
    #[inline(always)]
    pub fn mul_comp(self, o: Self) -> Self {
        Self::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    /// Lane-wise `if mask { a } else { b }`.
    #[inline(always)]
    pub fn select(mask: R::Mask, a: Self, b: Self) -> Self {
        Self::new(
            R::select(mask, a.x, b.x),
            R::select(mask, a.y, b.y),
            R::select(mask, a.z, b.z),
        )
    }
}

impl<R: Real> Add for V3<R> {
    type Output = Self;
    /// Component-wise sum.
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl<R: Real> Sub for V3<R> {
    type Output = Self;
    /// Component-wise difference.
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl<R: Real> Neg for V3<R> {
    type Output = Self;
    /// The vector pointing the other way (exact).
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}

impl From<glam::Vec3> for V3<f32> {
    fn from(v: glam::Vec3) -> Self {
        Self::new(v.x, v.y, v.z)
    }
}

impl From<V3<f32>> for glam::Vec3 {
    fn from(v: V3<f32>) -> Self {
        glam::Vec3::new(v.x, v.y, v.z)
    }
}

/// `(sin 2πx, cos 2πx)` for `x` in `[0, 1)`, to within a few ulps.
///
/// A polynomial rather than the platform's `sinf`/`cosf`, so that scalar and
/// SIMD code compute the very same bits. `x` is split into a quadrant
/// `q = round(4x)` and a remainder `r = x - q/4` in `[-1/8, 1/8]`; the
/// polynomials evaluate `sin` and `cos` of `a = 2πr` in `[-π/4, π/4]`, and
/// the quadrant rotates the pair.
#[inline(always)]
pub fn sin_cos_2pi<R: Real>(x: R) -> (R, R) {
    let q = (x * R::splat(4.0)).round_ties_even();
    let r = q.mul_add(R::splat(-0.25), x);
    let a = r * R::splat(std::f32::consts::TAU);
    let a2 = a * a;
    // Taylor series to degree 9 / 8: the truncation error at |a| = π/4 is
    // below 2e-9 for sin and 2e-8 for cos, under f32's half-ulp.
    let one = R::splat(1.0);
    let s = a * a2.mul_add(
        a2.mul_add(
            a2.mul_add(
                a2.mul_add(R::splat(1.0 / 362_880.0), R::splat(-1.0 / 5040.0)),
                R::splat(1.0 / 120.0),
            ),
            R::splat(-1.0 / 6.0),
        ),
        one,
    );
    let c = a2.mul_add(
        a2.mul_add(
            a2.mul_add(
                a2.mul_add(R::splat(1.0 / 40_320.0), R::splat(-1.0 / 720.0)),
                R::splat(1.0 / 24.0),
            ),
            R::splat(-0.5),
        ),
        one,
    );
    // Quadrant q (mod 4) rotates (s, c) by q·π/2; q = 4 is quadrant 0.
    let q1 = q.eq(R::splat(1.0));
    let q2 = q.eq(R::splat(2.0));
    let q3 = q.eq(R::splat(3.0));
    let sin = R::select(q1, c, R::select(q2, -s, R::select(q3, -c, s)));
    let cos = R::select(q1, -s, R::select(q2, -c, R::select(q3, s, c)));
    (sin, cos)
}

/// `acos x` for `x` in `[-1, 1]` (clamped), to within about 2e-7.
///
/// Cephes' `acosf`, as a polynomial and selects rather than the
/// platform's `acosf`, so that scalar and SIMD code compute the very same
/// bits: `asin` of `s` is `s + s z P(z)` with `z = s²`, `P` of degree 4,
/// for `s ≤ 1/2`; `acos a = π/2 − asin a` for `a = |x| ≤ 1/2`, else
/// `2 asin √((1 − a)/2)`; and `acos x = π − acos |x|` for `x < 0`.
#[inline(always)]
pub fn acos<R: Real>(x: R) -> R {
    let (zero, half, one) = (R::splat(0.0), R::splat(0.5), R::splat(1.0));
    let a = x.abs().min(one);
    let big = half.lt(a);
    let z = R::select(big, half * (one - a), a * a);
    let s = R::select(big, z.sqrt(), a);
    let p = z.mul_add(R::splat(4.216_32e-2), R::splat(2.418_131_2e-2));
    let p = z.mul_add(p, R::splat(4.547_002_5e-2));
    let p = z.mul_add(p, R::splat(7.495_300_5e-2));
    let p = z.mul_add(p, R::splat(1.666_675_2e-1));
    let asin = (s * z).mul_add(p, s);
    let half_pi = R::splat(std::f32::consts::FRAC_PI_2);
    let acos_a = R::select(big, asin + asin, half_pi - asin);
    R::select(x.lt(zero), R::splat(std::f32::consts::PI) - acos_a, acos_a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn acos_matches_libm_closely() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -1.0 + i as f32 / 100_000.0;
            worst = worst.max((acos(x) as f64 - (x as f64).acos()).abs());
        }
        assert!(worst < 3e-7, "worst error {worst}");
        assert_eq!(acos(2.0f32), 0.0);
        assert!((acos(-2.0f32) - std::f32::consts::PI).abs() < 1e-6);
    }

    #[test]
    fn acos_simd_equals_scalar_bitwise() {
        for i in 0..10_000 {
            let xs: [f32; 8] =
                std::array::from_fn(|l| (((i * 8 + l) as f32 * 0.618_034) % 2.0) - 1.0);
            let a8 = acos(f32x8::from(xs)).to_array();
            for (l, &x) in xs.iter().enumerate() {
                assert_eq!(acos(x).to_bits(), a8[l].to_bits(), "acos({x})");
            }
        }
    }

    #[test]
    fn sin_cos_matches_libm_closely() {
        let mut worst = 0.0f64;
        for i in 0..100_000 {
            let x = i as f32 / 100_000.0;
            let (s, c) = sin_cos_2pi(x);
            let a = std::f64::consts::TAU * x as f64;
            worst = worst.max((s as f64 - a.sin()).abs());
            worst = worst.max((c as f64 - a.cos()).abs());
        }
        assert!(worst < 4e-7, "worst error {worst}");
    }

    /// The scalar definitions (`accel::simd`'s tests hold 8 and 16 lanes to
    /// them, bit for bit, on the same awkward values).
    #[test]
    fn max_min_and_masks_follow_their_definitions() {
        let vals = [
            0.0f32,
            -0.0,
            1.0,
            -2.5,
            f32::NAN,
            f32::INFINITY,
            1e-40,
            -1e30,
        ];
        for &a in &vals {
            for &b in &vals {
                // The documented definitions.
                let want = if a < b { b } else { a };
                assert_eq!(Real::max(a, b).to_bits(), want.to_bits(), "max({a}, {b})");
                let want = if b < a { b } else { a };
                assert_eq!(Real::min(a, b).to_bits(), want.to_bits(), "min({a}, {b})");
            }
        }
        assert!(<f32 as Real>::splat_mask(true) && !<f32 as Real>::splat_mask(false));
        assert!(<f32x8 as Real>::splat_mask(true).all());
        assert!(!<f32x8 as Real>::splat_mask(false).any());
    }

    #[test]
    fn sin_cos_simd_equals_scalar_bitwise() {
        for i in 0..10_000 {
            let xs: [f32; 8] = std::array::from_fn(|l| ((i * 8 + l) as f32 * 0.618_034) % 1.0);
            let (s8, c8) = sin_cos_2pi(f32x8::from(xs));
            for (l, &x) in xs.iter().enumerate() {
                let (s, c) = sin_cos_2pi(x);
                assert_eq!(s.to_bits(), s8.to_array()[l].to_bits());
                assert_eq!(c.to_bits(), c8.to_array()[l].to_bits());
            }
        }
    }
}
