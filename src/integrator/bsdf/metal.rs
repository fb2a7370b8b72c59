//! The rough conductor: a GGX (Trowbridge–Reitz) microfacet BRDF with
//! isotropic roughness `α` (the GGX α itself, not a perceptual roughness),
//! Smith height-correlated masking–shadowing, and a constant Fresnel term
//! (the reflectance, an RGB tint). Directions are drawn by sampling the
//! distribution of visible normals with Dupuy & Benyoub's spherical caps
//! ("Sound and Robust Sampling of the GGX Distribution of Visible Normals",
//! 2023), which draws from exactly Heitz's VNDF (2018).
//!
//! With `ci = n · wi`, `co = n · wo`, `h = wo + wi` and
//! `S(c) = sqrt(c² + α² (1 - c²))` (so that the Smith
//! `Λ(c) = (S(c)/c - 1) / 2`):
//!
//! - `D(h) = α² / (π (α² cos²θh + sin²θh)²)`, computed from the
//!   unnormalised `h` as `α² |h|⁴ / (π (α² (n·h)² + |n×h|²)²)`;
//! - `G2 = 1 / (1 + Λ(co) + Λ(ci))` (height-correlated);
//! - `f = F · D · G2 / (4 co ci) = F · D / (2 (co S(ci) + ci S(co)))`;
//! - the density of a sampled `wi`: `D_wo(h) / (4 wo·h)` with the VNDF
//!   `D_wo(h) = G1(wo) (wo·h) D(h) / co`, which is
//!   `D / (2 (co + S(co)))`;
//! - so the weight `f ci / pdf` is `F · G2 / G1(wo)`, the tint as α → 0.
//!
//! These forms divide by no cosine, so grazing directions stay finite, and
//! [`eval`] is symmetric in `wo` and `wi` bit for bit.
//!
//! **Tiny α.** Every function first clamps α to [`ALPHA_MIN`] (a NaN α also
//! becomes [`ALPHA_MIN`]): below it `α²` and `α⁴` would leave f32's normal
//! range and `D` (up to `1/(πα²)`) could overflow; at `ALPHA_MIN` the lobe
//! is narrower than f32's resolution of directions, so the model is a
//! mirror to within rounding. It is still a non-delta lobe there: MIS with
//! light sampling works, the light samples just get almost no weight.
//!
//! All functions take the *facing* unit normal `n` (on the side of `wo`);
//! the BRDF is zero unless both `wo` and `wi` are strictly above the
//! surface.

use super::surface::{Bsdf, Texels, lanes, lanes3};
use super::{BsdfSample, local_to_world, reflect, tangents};
use crate::math::{Real, V3, sin_cos_2pi};
use crate::scene::{Material, Model};
use std::f32::consts::PI;
use wide::f32x8;

/// The rough conductor model ([`Model::Metal`]).
pub struct Metal;

/// Its parameters.
#[derive(Clone, Copy, Debug)]
pub struct Params<R: Real> {
    /// The GGX α.
    pub alpha: R,
    /// The Fresnel tint: the reflectance times the colour textures.
    pub tint: V3<R>,
}

impl Bsdf for Metal {
    const MODEL: Model = Model::Metal;
    type Params<R: Real> = Params<R>;

    #[inline]
    fn params(m: &Material, at: &impl Texels) -> Params<f32> {
        Params {
            alpha: m.alpha,
            tint: V3::from(m.reflectance * at.colour()),
        }
    }

    #[inline(always)]
    fn gather(table: &[Params<f32>], rows: &[usize; 8]) -> Params<f32x8> {
        Params {
            alpha: lanes(rows, |i| table[i].alpha),
            tint: lanes3(rows, |i| table[i].tint),
        }
    }

    #[inline(always)]
    fn sample<R: Real>(
        p: &Params<R>,
        (_, n): (R::Mask, V3<R>),
        wo: V3<R>,
        u: [R; 2],
        _uniform: bool,
    ) -> BsdfSample<R> {
        sample(n, wo, p.alpha, p.tint, u)
    }

    #[inline(always)]
    fn eval<R: Real>(
        p: &Params<R>,
        n: V3<R>,
        wo: V3<R>,
        wi: V3<R>,
        _front: R::Mask,
    ) -> (V3<R>, R, R) {
        let f = eval(n, wo, wi, p.alpha, p.tint);
        let cos = n.dot(wi).max(R::splat(0.0));
        (f.scale(cos), cos, pdf(n, wo, wi, p.alpha))
    }
}

/// The smallest α the model works with; smaller values (and NaN) are
/// raised to it. See the module documentation.
pub const ALPHA_MIN: f32 = 1e-7;

/// α clamped to `[ALPHA_MIN, ∞)`, NaN to `ALPHA_MIN`.
#[inline(always)]
pub fn clamp_alpha<R: Real>(alpha: R) -> R {
    R::splat(ALPHA_MIN).max(alpha)
}

/// `S(c) = sqrt(c² + α² (1 - c²))` for a cosine `c` (`a2 = α²`): the
/// Smith `Λ(c) = (S(c)/c - 1) / 2` without the division.
#[inline(always)]
pub fn smith_s<R: Real>(c: R, a2: R) -> R {
    let s2 = (-c).mul_add(c, R::splat(1.0)).max(R::splat(0.0));
    a2.mul_add(s2, c * c).sqrt()
}

/// The GGX normal distribution `D` at the direction of the unnormalised,
/// nonzero half vector `h`, for the unit normal `n` and roughness `alpha`
/// (clamped): `α² |h|⁴ / (π (α² (n·h)² + |n×h|²)²)`, which is
/// `α² / (π (α² cos²θh + sin²θh)²)` without normalising `h` and without
/// the cancellation of `1 - cos²θh`. Symmetric in `±h`.
#[inline(always)]
pub fn ndf<R: Real>(n: V3<R>, h: V3<R>, alpha: R) -> R {
    let a = clamp_alpha(alpha);
    ndf_a2(n, h, a * a)
}

/// [`ndf`] with `a2 = α²` given.
#[inline(always)]
fn ndf_a2<R: Real>(n: V3<R>, h: V3<R>, a2: R) -> R {
    let hn = n.dot(h);
    let t = n.cross(h);
    let q = a2.mul_add(hn * hn, t.dot(t));
    let r = h.dot(h) / q;
    a2 * r * r * R::splat(1.0 / PI)
}

/// The Smith height-correlated masking–shadowing `G2` for the cosines `co`,
/// `ci` (both positive) and roughness `alpha` (clamped).
#[inline(always)]
pub fn g2<R: Real>(co: R, ci: R, alpha: R) -> R {
    let a = clamp_alpha(alpha);
    let a2 = a * a;
    let (so, si) = (smith_s(co, a2), smith_s(ci, a2));
    // 1 / (1 + Λo + Λi) = 2 co ci / (co si + ci so).
    R::splat(2.0) * co * ci / (co * si + ci * so)
}

/// The cosines and the validity of a pair of directions.
#[inline(always)]
fn cosines<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>) -> (R::Mask, R, R) {
    let zero = R::splat(0.0);
    let (co, ci) = (n.dot(wo), n.dot(wi));
    (zero.lt(co) & zero.lt(ci), co, ci)
}

/// The BRDF value `f(wo, wi)` per RGB channel, with the constant Fresnel
/// term `tint`: `tint · D · G2 / (4 co ci)`, or 0 unless both directions
/// are strictly above the surface of facing normal `n`. Reciprocal bit for
/// bit: `eval(n, wo, wi, …) == eval(n, wi, wo, …)`.
#[inline(always)]
pub fn eval<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, alpha: R, tint: V3<R>) -> V3<R> {
    let a = clamp_alpha(alpha);
    let a2 = a * a;
    let (valid, co, ci) = cosines(n, wo, wi);
    let d = ndf_a2(n, wo + wi, a2);
    let (so, si) = (smith_s(co, a2), smith_s(ci, a2));
    // Symmetric in (co, so) ↔ (ci, si): the sum's two products commute.
    let v = d / ((co * si + ci * so) * R::splat(2.0));
    tint.scale(R::select(valid, v, R::splat(0.0)))
}

/// The density [`sample`] draws `wi` with, per unit solid angle: the
/// reflected visible-normal density `D / (2 (co + S(co)))`, or 0 unless
/// both directions are strictly above the surface (the sampler's
/// directions below the horizon are absorbed, so this density integrates to
/// less than 1 over the hemisphere where `wo` is near grazing).
#[inline(always)]
pub fn pdf<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, alpha: R) -> R {
    let a = clamp_alpha(alpha);
    let a2 = a * a;
    let (valid, co, _) = cosines(n, wo, wi);
    let d = ndf_a2(n, wo + wi, a2);
    let p = d / ((co + smith_s(co, a2)) * R::splat(2.0));
    R::select(valid, p, R::splat(0.0))
}

/// A visible microfacet normal for `wo`, in the local frame of
/// [`tangents`] (normal along local y), drawn from two uniform numbers in
/// `[0, 1)` with Dupuy & Benyoub's spherical-cap method: stretch `wo` by α
/// (tangential components times α), draw `c` uniformly on the part of the
/// unit sphere with `c_y > -v_y` (`v` the stretched unit `wo`), and
/// un-stretch `h = c + v`.
///
/// Returns the microfacet normal `m` (unit), and `D(m)` computed from the
/// stretched `h` as `(|m'|² / |h|²)² / (π α²)`, where `m'` is the
/// un-normalised microfacet normal — exact for every α, without squaring
/// α twice. `n2 = |m'|²` is returned too: zero means no normal.
#[inline(always)]
pub fn sample_visible_normal<R: Real>(wo_local: V3<R>, a: R, u: [R; 2]) -> (V3<R>, R, R) {
    let one = R::splat(1.0);
    let zero = R::splat(0.0);
    // Stretched, normalised view direction.
    let v = V3::new(a * wo_local.x, wo_local.y, a * wo_local.z);
    let v = v.scale(one / v.dot(v).sqrt());
    // A uniform direction on the spherical cap y > -v.y.
    let (sin_phi, cos_phi) = sin_cos_2pi(u[0]);
    let y = (one - u[1]).mul_add(one + v.y, -v.y);
    let sin_theta = (-y).mul_add(y, one).max(zero).sqrt();
    let h = V3::new(
        sin_theta.mul_add(cos_phi, v.x),
        y + v.y,
        sin_theta.mul_add(sin_phi, v.z),
    );
    // Un-stretch: the microfacet normal is (α hx, hy, α hz), normalised.
    let m = V3::new(a * h.x, h.y.max(zero), a * h.z);
    let n2 = m.dot(m);
    let ratio = n2 / h.dot(h);
    let d = ratio * ratio / (R::splat(PI) * a * a);
    (m.scale(one / n2.sqrt()), d, n2)
}

/// A reflected direction drawn from the visible normals of `wo`, from two
/// uniform numbers `u` in `[0, 1)`, with its BRDF value (Fresnel = `tint`),
/// cosine and density (see [`BsdfSample`]).
///
/// Where the reflection falls on or below the horizon, or `wo` itself is
/// not strictly above it, the sample is absorbed (`f = 0`, `cos = 0`,
/// `pdf = 1`). `D` is computed once, from the sampled normal, for both `f`
/// and `pdf`, so it cancels from the weight (`tint · G2/G1`) even where
/// α is tiny and `D` huge; `f` and `pdf` agree with [`eval`] and [`pdf`]
/// up to rounding.
#[inline(always)]
pub fn sample<R: Real>(n: V3<R>, wo: V3<R>, alpha: R, tint: V3<R>, u: [R; 2]) -> BsdfSample<R> {
    let zero = R::splat(0.0);
    let one = R::splat(1.0);
    let a = clamp_alpha(alpha);
    let a2 = a * a;
    let frame = tangents(n);
    let (nt, nb) = frame;
    let co = n.dot(wo);
    let wo_local = V3::new(nb.dot(wo), co, nt.dot(wo));
    let (m, d, n2) = sample_visible_normal(wo_local, a, u);
    let wi = reflect(wo, local_to_world(n, frame, m.x, m.y, m.z));
    let ci = n.dot(wi);
    let valid = zero.lt(co) & zero.lt(ci) & zero.lt(n2);
    let (so, si) = (smith_s(co, a2), smith_s(ci, a2));
    let two = R::splat(2.0);
    let f = d / ((co * si + ci * so) * two);
    let p = d / ((co + so) * two);
    BsdfSample {
        wi,
        f: tint.scale(R::select(valid, f, zero)),
        cos: R::select(valid, ci, zero),
        pdf: R::select(valid, p, one),
        delta: R::splat_mask(false),
    }
}
