//! glTF's metallic-roughness material with `KHR_materials_transmission`:
//! the extension replaces the diffuse base of the dielectric part by a
//! mix of the diffuse lobe and a specular transmission lobe of the same
//! roughness, tinted by the base colour,
//!
//! ```text
//! dielectric_brdf = fresnel_mix(base  = mix(diffuse_brdf(base),
//!                                           specular_btdf(α) · base,
//!                                           transmission),
//!                               layer = specular_brdf(α))
//! material        = mix(dielectric_brdf, metal_brdf, metallic)
//! ```
//!
//! Expanding the mixes, the transmitting share is one whole dielectric
//! interface (`F · specular_brdf + (1 − F) · specular_btdf · base`):
//! with `w = transmission · (1 − metallic)`,
//!
//! ```text
//! material = (1 − w) · metallic_roughness(base, metallic / (1 − w), α)
//!          + w       · dielectric(base, α, ior, thin or solid)
//! ```
//!
//! — [`metallic_roughness`](super::metallic_roughness) (Appendix B, exactly as the opaque model) and
//! [`dielectric`] (Walter et al.'s rough dielectric, exact Fresnel of the
//! index, thin-walled or a solid's boundary as `KHR_materials_volume`
//! says). The interface's Fresnel term is the exact one of the index
//! (as pbrt-v4's `DielectricBxDF` and Blender's Principled BSDF have it),
//! not Appendix B's Schlick approximation: with it, a smooth solid is
//! [`glass`](super::glass) to the bit of its math, and light inside a
//! solid is totally reflected beyond the critical angle.
//!
//! **Sampling.** The first number picks the interface with probability
//! `w` and is stretched back to `[0, 1)` for the chosen part. Where the
//! interface is smooth and chosen, the sample is its delta sample;
//! otherwise its value and density are the mixtures
//! `(1 − w) f_mr + w f_d` and `(1 − w) p_mr + w p_d` at the direction (the
//! smooth interface has neither value nor density there), so the weight
//! is that of one-sample MIS between the parts. A direction the chosen
//! part absorbs stays absorbed.
//!
//! Every function takes the *facing* unit normal `n` (on the side of
//! `wo`).

use super::metallic_roughness as mr;
use super::surface::{Bsdf, Texels, lanes, lanes3};
use super::{BsdfSample, dielectric};
use crate::math::{Real, V3};
use crate::scene::{Material, Model};
use wide::f32x8;

/// The transmission model ([`Model::Transmission`]).
pub struct Transmission;

/// Its parameters: [`Params`] but the side, which is the hit's.
#[derive(Clone, Copy, Debug)]
pub struct Factors<R: Real> {
    /// The base colour: the reflectance times the colour textures.
    pub base: V3<R>,
    /// The metalness.
    pub metallic: R,
    /// The GGX α: the roughness squared.
    pub alpha: R,
    /// The index of refraction.
    pub ior: R,
    /// The transmission factor (× texture).
    pub transmission: R,
    /// 1 where the surface is thin-walled, 0 where it bounds a solid.
    pub thin: R,
    /// `KHR_materials_specular`'s strength.
    pub specular: R,
    /// The dielectric `F0` colour before the strength.
    pub f0: V3<R>,
}

impl<R: Real> Factors<R> {
    /// The parameters, `wo` on the geometric front where `front`.
    #[inline(always)]
    fn at(&self, front: R::Mask) -> Params<R> {
        Params {
            base: self.base,
            metallic: self.metallic,
            alpha: self.alpha,
            ior: self.ior,
            transmission: self.transmission,
            thin: R::splat(0.5).lt(self.thin),
            front,
            f0: self.f0,
            specular: self.specular,
        }
    }
}

impl Bsdf for Transmission {
    const MODEL: Model = Model::Transmission;
    type Params<R: Real> = Factors<R>;

    #[inline]
    fn params(m: &Material, at: &impl Texels) -> Factors<f32> {
        let (metallic, roughness) = mr::metallic_roughness(m, at);
        let (specular, f0) = mr::specular(m, at);
        Factors {
            base: V3::from(m.reflectance * at.colour()),
            metallic,
            alpha: roughness * roughness,
            ior: m.ior,
            transmission: m.transmission * at.channel(m.maps.transmission.as_ref(), 0),
            thin: f32::from(u8::from(m.thin)),
            specular,
            f0,
        }
    }

    #[inline(always)]
    fn gather(table: &[Factors<f32>], rows: &[usize; 8]) -> Factors<f32x8> {
        Factors {
            base: lanes3(rows, |i| table[i].base),
            metallic: lanes(rows, |i| table[i].metallic),
            alpha: lanes(rows, |i| table[i].alpha),
            ior: lanes(rows, |i| table[i].ior),
            transmission: lanes(rows, |i| table[i].transmission),
            thin: lanes(rows, |i| table[i].thin),
            specular: lanes(rows, |i| table[i].specular),
            f0: lanes3(rows, |i| table[i].f0),
        }
    }

    #[inline(always)]
    fn sample<R: Real>(
        p: &Factors<R>,
        (front, n): (R::Mask, V3<R>),
        wo: V3<R>,
        u: [R; 2],
        _uniform: bool,
    ) -> BsdfSample<R> {
        sample(n, wo, &p.at(front), u)
    }

    /// Light sampling reaches the side of `wo` only.
    #[inline(always)]
    fn eval<R: Real>(
        p: &Factors<R>,
        n: V3<R>,
        wo: V3<R>,
        wi: V3<R>,
        front: R::Mask,
    ) -> (V3<R>, R, R) {
        let p = p.at(front);
        let f = eval(n, wo, wi, &p);
        let cos = n.dot(wi).max(R::splat(0.0));
        (f.scale(cos), cos, pdf(n, wo, wi, &p))
    }

    /// 0 after a delta sample (a smooth interface) and after a
    /// transmission (light sampling connects only on the side of `ng`).
    #[inline(always)]
    fn mis_pdf<R: Real>(_p: &Factors<R>, s: &BsdfSample<R>, ng: V3<R>) -> R {
        let zero = R::splat(0.0);
        let through = s.wi.dot(ng).le(zero);
        R::select(s.delta | through, zero, s.pdf)
    }
}

/// The largest `f32` below 1.
const BELOW_ONE: f32 = 1.0 - f32::EPSILON / 2.0;

/// The material at a point, lane by lane.
#[derive(Clone, Copy, Debug)]
pub struct Params<R: Real> {
    /// The base colour (linear RGB, in `[0, 1]`).
    pub base: V3<R>,
    /// The metalness, in `[0, 1]`.
    pub metallic: R,
    /// The GGX α: the glTF roughness squared.
    pub alpha: R,
    /// The index of refraction of the material (the outside is 1).
    pub ior: R,
    /// The transmission factor (× texture), in `[0, 1]`.
    pub transmission: R,
    /// Whether the surface is thin-walled (else a solid's boundary).
    pub thin: R::Mask,
    /// Whether `wo` is on the geometric front (outside) of the surface.
    pub front: R::Mask,
    /// `KHR_materials_specular`'s `min(F0(ior) × specularColor, 1)`
    /// (the dielectric `F0` colour before its strength;
    /// [`dielectric_f0`](crate::scene::material::dielectric_f0)).
    pub f0: V3<R>,
    /// `KHR_materials_specular`'s strength `specular` (1 by default).
    pub specular: R,
}

/// [`f0_of_ior`](crate::scene::material::f0_of_ior), lane by lane, with
/// its bits.
#[inline(always)]
pub fn f0_of_ior<R: Real>(ior: R) -> R {
    let one = R::splat(1.0);
    let r = (ior - one) / (ior + one);
    let default = ior.eq(R::splat(crate::scene::material::DEFAULT_IOR));
    R::select(default, R::splat(mr::DIELECTRIC_F0), r * r)
}

impl<R: Real> Params<R> {
    /// `(w, the metallic-roughness part, the interface seen from wo)`.
    #[inline(always)]
    pub fn split(&self) -> (R, mr::Params<R>, dielectric::Params<R>) {
        let (zero, one) = (R::splat(0.0), R::splat(1.0));
        let w = self.transmission * (one - self.metallic);
        let rest = one - w;
        let metallic = R::select(zero.lt(rest), self.metallic / rest, zero).min(one);
        let solid_eta = R::select(self.front, self.ior, one / self.ior);
        let eta = R::select(self.thin, self.ior, solid_eta);
        (
            w,
            mr::Params {
                base: self.base,
                metallic,
                alpha: self.alpha,
                f0: self.f0.scale(self.specular),
                f90: self.specular,
            },
            dielectric::Params {
                tint: self.base,
                alpha: self.alpha,
                eta,
                thin: self.thin,
                specular: (f0_of_ior(self.ior), self.f0, self.specular),
            },
        )
    }
}

/// `(f, pdf)` of the mixture for the pair of directions.
#[inline(always)]
fn eval_pdf<R: Real>(
    n: V3<R>,
    wo: V3<R>,
    wi: V3<R>,
    (w, q, d): &(R, mr::Params<R>, dielectric::Params<R>),
) -> (V3<R>, R, R, R) {
    let rest = R::splat(1.0) - *w;
    let fm = mr::eval(n, wo, wi, q);
    let pm = mr::pdf(n, wo, wi, q);
    let fd = dielectric::eval(n, wo, wi, d);
    let pd = dielectric::pdf(n, wo, wi, d);
    let f = V3::new(
        fm.x.mul_add(rest, fd.x * *w),
        fm.y.mul_add(rest, fd.y * *w),
        fm.z.mul_add(rest, fd.z * *w),
    );
    (f, pm.mul_add(rest, pd * *w), pm, pd)
}

/// The BSDF value `f(wo, wi)` per RGB channel (without the cosine): the
/// mixture's rough parts (see the module documentation).
#[inline(always)]
pub fn eval<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, p: &Params<R>) -> V3<R> {
    eval_pdf(n, wo, wi, &p.split()).0
}

/// The density [`sample`] draws a non-delta `wi` with, per unit solid
/// angle.
#[inline(always)]
pub fn pdf<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, p: &Params<R>) -> R {
    eval_pdf(n, wo, wi, &p.split()).1
}

/// A direction drawn from the material, from two uniform numbers `u` in
/// `[0, 1)` (see the module documentation and [`BsdfSample`]).
#[inline(always)]
pub fn sample<R: Real>(n: V3<R>, wo: V3<R>, p: &Params<R>, u: [R; 2]) -> BsdfSample<R> {
    let (zero, one) = (R::splat(0.0), R::splat(1.0));
    let parts = p.split();
    let (w, q, d) = &parts;
    let pick_d = u[0].lt(*w);
    let ud = (u[0] / *w).max(zero).min(R::splat(BELOW_ONE));
    let um = ((u[0] - *w) / (one - *w))
        .max(zero)
        .min(R::splat(BELOW_ONE));
    let ds = dielectric::sample(n, wo, d, [R::select(pick_d, ud, zero), u[1]]);
    let ms = mr::sample(n, wo, q, [R::select(pick_d, zero, um), u[1]]);
    let wi = V3::select(pick_d, ds.wi, ms.wi);
    let (f, pdf, pm, pd) = eval_pdf(n, wo, wi, &parts);
    let own = R::select(pick_d, ds.cos * pd, ms.cos * pm);
    let valid = zero.lt(own) & zero.lt(pdf);
    let delta = pick_d & d.smooth();
    let z3 = V3::new(zero, zero, zero);
    BsdfSample {
        wi,
        f: V3::select(delta, ds.f, V3::select(valid, f, z3)),
        cos: R::select(delta, one, R::select(valid, n.dot(wi).abs(), zero)),
        pdf: R::select(delta, one, R::select(valid, pdf, one)),
        delta,
    }
}
