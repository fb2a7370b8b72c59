//! glTF 2.0's metallic-roughness material, exactly as the specification's
//! Appendix B defines it:
//!
//! ```text
//! material        = mix(dielectric_brdf, metal_brdf, metallic)
//! metal_brdf      = specular_brdf(α) · (base + (1 − base) (1 − |V·H|)⁵)
//! dielectric_brdf = mix(diffuse_brdf(base), specular_brdf(α),
//!                       0.04 + (1 − 0.04) (1 − |V·H|)⁵)
//! diffuse_brdf    = base / π
//! specular_brdf   = D · V   (GGX/Trowbridge–Reitz D, separable Smith V)
//! α               = roughness²
//! ```
//!
//! Schlick's Fresnel is linear in `F0`, so the mix is one Fresnel term with
//! `F0 = mix(0.04, base, metallic)`:
//! `f = (1 − metallic) (1 − F_d) base/π + F · D · V`, with
//! `F_d = 0.04 + 0.96 (1 − |V·H|)⁵` and `F = F0 + (1 − F0)(1 − |V·H|)⁵`.
//! `D` is [`metal::ndf`]; `V = G / (4 |N·L| |N·V|)` with the Appendix's
//! separable Smith `G = G1(L) G1(V)` (not the height-correlated `G2` of
//! [`metal`]), so the specular weight of a visible-normal sample is
//! `F · G1(wi)`.
//!
//! **`KHR_materials_specular`** changes the dielectric Fresnel term:
//! `dielectric_f0 = min(F0(ior) × specularColor, 1) × specular` per
//! channel ([`Params::f0`]), `dielectric_f90 = specular` ([`Params::f90`]),
//! `F_d = F0_d + (F90_d − F0_d)(1 − |V·H|)⁵`, and the diffuse lobe is
//! weighed by `1 − max_value(F_d)` (the extension's `fresnel_mix`); the
//! metal part is unchanged. Schlick's term is linear in `F0` and `F90`,
//! so the material is still one Fresnel term, of
//! `F0 = mix(F0_d, base, metallic)` and `F90 = mix(F90_d, 1, metallic)`:
//! `f = (1 − metallic)(1 − max F_d) base/π + F · D · V`. With the default
//! (`F0_d` = 0.04, `F90_d` = 1: [`Params::new`]) every operation is the
//! one of the plain Appendix B, bit for bit.
//!
//! **Energy.** The Appendix weights the diffuse lobe by `1 − F(V·H)`, and
//! `V·H` depends on the light direction: averaged over the hemisphere it is
//! close to `F0`, while the specular lobe reflects `F` near grazing. So the
//! dielectric part reflects *more* than it receives at grazing view angles
//! on smooth to moderately rough surfaces (a directional albedo up to about
//! 1.45 at `α = 0.05`, `cos θo = 0.05`, white base colour). That is the
//! specification's model, kept as written; the metallic part (and every
//! surface at normal incidence) stays at or below 1. `tests/bsdf.rs`
//! measures it.
//!
//! **Sampling.** One of two lobes, by a Fresnel-weighted probability at
//! `wo` ([`specular_probability`]): the specular lobe by the visible
//! normals of GGX ([`metal::sample`]), the diffuse one cosine-weighted
//! ([`diffuse::sample_cosine`]). The first direction number picks the lobe
//! and is stretched back to `[0, 1)` for it. The density of a direction is
//! the mixture of both ([`pdf`]), whichever lobe drew it, so the weight
//! `f cos / pdf` is that of one-sample MIS between the lobes and
//! multiple importance sampling with lights sees the same density.
//!
//! Every function takes the *facing* unit normal `n` (on the side of
//! `wo`); the BRDF is zero unless both `wo` and `wi` are strictly above
//! the surface. Roughness is given as `α = roughness²`.

use super::surface::{Bsdf, Texels, lanes, lanes3};
use super::{BsdfSample, diffuse, metal};
use crate::math::{Real, V3};
use crate::scene::material::dielectric_f0;
use crate::scene::{Material, Model};
use wide::f32x8;

/// The metallic-roughness model ([`Model::MetallicRoughness`]), its
/// parameters [`Params`].
pub struct MetallicRoughness;

/// `(metalness, roughness)` of `m` where its textures read `at`: the
/// factors times B and G of its metallic-roughness texture.
#[inline(always)]
pub fn metallic_roughness(m: &Material, at: &impl Texels) -> (f32, f32) {
    let (metal, rough) =
        (at.read(m.maps.metallic_roughness.as_ref())).map_or((1.0, 1.0), |c| (c[2], c[1]));
    (m.metallic * metal, m.roughness * rough)
}

/// `(specular, F0 colour)` of `m` where its textures read `at`:
/// `KHR_materials_specular`'s strength (times A of `specularTexture`) and
/// its colour (times RGB of `specularColorTexture`) into
/// [`dielectric_f0`] of the material's index.
#[inline(always)]
pub fn specular(m: &Material, at: &impl Texels) -> (f32, V3<f32>) {
    let s = at.channel(m.maps.specular.as_ref(), 3);
    let c = at.rgb(m.maps.specular_colour.as_ref());
    (
        m.specular * s,
        V3::from(dielectric_f0(m.ior, m.specular_colour * c)),
    )
}

impl Bsdf for MetallicRoughness {
    const MODEL: Model = Model::MetallicRoughness;
    type Params<R: Real> = Params<R>;

    #[inline]
    fn params(m: &Material, at: &impl Texels) -> Params<f32> {
        let (metallic, roughness) = metallic_roughness(m, at);
        let (specular, f0) = specular(m, at);
        Params {
            base: V3::from(m.reflectance * at.colour()),
            metallic,
            alpha: roughness * roughness,
            f0: f0.scale(specular),
            f90: specular,
        }
    }

    #[inline(always)]
    fn gather(table: &[Params<f32>], rows: &[usize; 8]) -> Params<f32x8> {
        Params {
            base: lanes3(rows, |i| table[i].base),
            metallic: lanes(rows, |i| table[i].metallic),
            alpha: lanes(rows, |i| table[i].alpha),
            f0: lanes3(rows, |i| table[i].f0),
            f90: lanes(rows, |i| table[i].f90),
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
        sample(n, wo, p, u)
    }

    #[inline(always)]
    fn eval<R: Real>(
        p: &Params<R>,
        n: V3<R>,
        wo: V3<R>,
        wi: V3<R>,
        _front: R::Mask,
    ) -> (V3<R>, R, R) {
        let f = eval(n, wo, wi, p);
        let cos = n.dot(wi).max(R::splat(0.0));
        (f.scale(cos), cos, pdf(n, wo, wi, p))
    }
}

/// `F0` of the dielectric part at the default index of refraction (1.5)
/// and specular ([`Params::new`]).
pub use crate::scene::material::DIELECTRIC_F0;

/// The parameters of the material at a point, lane by lane.
#[derive(Clone, Copy, Debug)]
pub struct Params<R: Real> {
    /// The base colour (linear RGB, in `[0, 1]`).
    pub base: V3<R>,
    /// The metalness, in `[0, 1]`.
    pub metallic: R,
    /// The GGX α: the glTF roughness squared.
    pub alpha: R,
    /// The dielectric part's `F0` per channel (`KHR_materials_specular`'s
    /// `dielectric_f0 = min(F0(ior) × specularColor, 1) × specular`;
    /// [`DIELECTRIC_F0`] by default).
    pub f0: V3<R>,
    /// The dielectric part's `F90` (`KHR_materials_specular`'s
    /// `specular`; 1 by default).
    pub f90: R,
}

impl<R: Real> Params<R> {
    /// The parameters of base colour `base`, metalness `metallic` and
    /// GGX `alpha`, with the default dielectric Fresnel (`F0` 0.04,
    /// `F90` 1: no `KHR_materials_specular`, index 1.5).
    #[inline(always)]
    pub fn new(base: V3<R>, metallic: R, alpha: R) -> Self {
        let f0 = R::splat(DIELECTRIC_F0);
        Self {
            base,
            metallic,
            alpha,
            f0: V3::new(f0, f0, f0),
            f90: R::splat(1.0),
        }
    }
}

/// `(1 − c)⁵` for `c = |V·H|` (clamped to `[0, 1]`).
#[inline(always)]
fn schlick_weight<R: Real>(c: R) -> R {
    let t = (R::splat(1.0) - c.abs()).max(R::splat(0.0));
    let t2 = t * t;
    t2 * t2 * t
}

/// `(F0, F90)` of the material: `F0 = mix(dielectric F0, base, metallic)`
/// per channel, `F90 = mix(dielectric F90, 1, metallic)` (Schlick's
/// Fresnel is linear in both, so this is the mix of the dielectric and
/// metal Fresnel terms). With the default `F90` of 1 it is exactly 1.
#[inline(always)]
fn f0_f90<R: Real>(p: &Params<R>) -> (V3<R>, R) {
    let mix = |b: R, d: R| (b - d).mul_add(p.metallic, d);
    let f0 = V3::new(
        mix(p.base.x, p.f0.x),
        mix(p.base.y, p.f0.y),
        mix(p.base.z, p.f0.z),
    );
    (f0, mix(R::splat(1.0), p.f90))
}

/// `F0 + (F90 − F0) w` per channel.
#[inline(always)]
fn schlick<R: Real>((f0, f90): (V3<R>, R), w: R) -> V3<R> {
    let s = |f: R| (f90 - f).mul_add(w, f);
    V3::new(s(f0.x), s(f0.y), s(f0.z))
}

/// The largest channel of the dielectric Fresnel term
/// `F0 + (F90 − F0) w` (the specification's `max_value`, which weighs the
/// diffuse lobe): the channel of the largest `F0`, as `w ≤ 1`.
#[inline(always)]
fn dielectric_max<R: Real>(p: &Params<R>, w: R) -> R {
    let f0 = p.f0.x.max(p.f0.y).max(p.f0.z);
    (p.f90 - f0).mul_add(w, f0)
}

/// The BRDF value `f(wo, wi)` per RGB channel (without the cosine), or 0
/// unless both directions are strictly above the surface of facing normal
/// `n`. The specular lobe is the Appendix's `D · V` with the separable
/// Smith visibility `V = 1 / ((|N·L| + S(N·L)) (|N·V| + S(N·V)))`,
/// `S(c) = sqrt(α² + (1 − α²) c²)`. `V·H` is computed as
/// `sqrt((1 + wo·wi) / 2)` (the same for both directions), so the value is
/// reciprocal bit for bit: `eval(n, wo, wi, …) == eval(n, wi, wo, …)`.
#[inline(always)]
pub fn eval<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, p: &Params<R>) -> V3<R> {
    let (zero, half, one) = (R::splat(0.0), R::splat(0.5), R::splat(1.0));
    let a = metal::clamp_alpha(p.alpha);
    let a2 = a * a;
    let (co, ci) = (n.dot(wo), n.dot(wi));
    let valid = zero.lt(co) & zero.lt(ci);
    let d = metal::ndf(n, wo + wi, a);
    let vis = one / ((co + metal::smith_s(co, a2)) * (ci + metal::smith_s(ci, a2)));
    let spec = R::select(valid, d * vis, zero);
    let vh = wo.dot(wi).mul_add(half, half).max(zero).sqrt();
    let w = schlick_weight(vh);
    let f = schlick(f0_f90(p), w);
    let fd = dielectric_max(p, w);
    let kd = R::select(
        valid,
        (one - p.metallic) * (one - fd) * R::splat(std::f32::consts::FRAC_1_PI),
        zero,
    );
    V3::new(
        kd.mul_add(p.base.x, f.x * spec),
        kd.mul_add(p.base.y, f.y * spec),
        kd.mul_add(p.base.z, f.z * spec),
    )
}

/// The probability of choosing the specular lobe at `wo` (`co = n · wo`):
/// `s / (s + d)` with `s` the mean over the channels of Schlick's `F` at
/// `co` and `d = (1 − metallic) (1 − F_d(co)) · mean(base)`, the diffuse
/// lobe's share; 1 where there is no diffuse lobe.
#[inline(always)]
pub fn specular_probability<R: Real>(co: R, p: &Params<R>) -> R {
    let (zero, one) = (R::splat(0.0), R::splat(1.0));
    let third = R::splat(1.0 / 3.0);
    let w = schlick_weight(co);
    let f = schlick(f0_f90(p), w);
    let s = (f.x + f.y + f.z) * third;
    let fd = dielectric_max(p, w);
    let d = (one - p.metallic) * (one - fd) * (p.base.x + p.base.y + p.base.z) * third;
    let d = d.max(zero);
    let sum = s + d;
    R::select(zero.lt(d), s / sum, one)
}

/// The density [`sample`] draws `wi` with, per unit solid angle:
/// `P_s · pdf_VNDF + (1 − P_s) · cos θi / π`, or 0 unless both directions
/// are strictly above the surface.
#[inline(always)]
pub fn pdf<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, p: &Params<R>) -> R {
    let zero = R::splat(0.0);
    let co = n.dot(wo);
    let ps = specular_probability(co, p);
    let spec = metal::pdf(n, wo, wi, p.alpha);
    let dif = diffuse::pdf_cosine(n, wi);
    let valid = zero.lt(co) & zero.lt(n.dot(wi));
    R::select(valid, ps.mul_add(spec - dif, dif), zero)
}

/// The largest `f32` below 1: where a stretched direction number is
/// clamped, so it stays in `[0, 1)`.
const BELOW_ONE: f32 = 1.0 - f32::EPSILON / 2.0;

/// A direction drawn from the lobes by [`specular_probability`] (see the
/// module documentation), from two uniform numbers `u` in `[0, 1)`, with
/// the BRDF value, cosine and mixture density (see [`BsdfSample`]). A
/// direction on or below the horizon, or a `wo` that is not strictly above
/// it, is absorbed (`f = 0`, `cos = 0`, `pdf = 1`).
#[inline(always)]
pub fn sample<R: Real>(n: V3<R>, wo: V3<R>, p: &Params<R>, u: [R; 2]) -> BsdfSample<R> {
    let (zero, one) = (R::splat(0.0), R::splat(1.0));
    let co = n.dot(wo);
    let ps = specular_probability(co, p);
    let pick_spec = u[0].lt(ps);
    // u[0] stretched to [0, 1) within the chosen lobe's share.
    let us = (u[0] / ps).min(R::splat(BELOW_ONE));
    let ud = ((u[0] - ps) / (one - ps))
        .max(zero)
        .min(R::splat(BELOW_ONE));
    let white = V3::new(one, one, one);
    let s = metal::sample(
        n,
        wo,
        p.alpha,
        white,
        [R::select(pick_spec, us, zero), u[1]],
    );
    let d = diffuse::sample_cosine(n, white, [R::select(pick_spec, zero, ud), u[1]]);
    let wi = V3::select(pick_spec, s.wi, d.wi);
    let ci = n.dot(wi);
    let valid = zero.lt(co) & zero.lt(ci);
    let f = eval(n, wo, wi, p);
    let pdf = pdf(n, wo, wi, p);
    let valid = valid & zero.lt(pdf);
    BsdfSample {
        wi,
        f: V3::select(valid, f, V3::new(zero, zero, zero)),
        cos: R::select(valid, ci, zero),
        pdf: R::select(valid, pdf, one),
        delta: R::splat_mask(false),
    }
}
