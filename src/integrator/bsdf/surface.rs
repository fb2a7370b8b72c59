//! A surface's scattering by its model: the one place that dispatches on
//! [`Model`], for both engines (one lane in the reference tracer, eight
//! paths of one model at a time in the wavefront engine), and the one
//! place that turns a [`Material`] into a model's parameters
//! ([`Surface::of`]).
//!
//! A new model is its routine in a file of [`super`], one variant of
//! [`Model`] (with its name and whether it is a delta lobe), its arms here
//! (parameters, sampling, evaluation), and its fields in the scene format.

use super::metallic_roughness::{self as mr, Params};
use super::transmission as tr;
use super::{BsdfSample, diffuse, facing, glass, leaks, metal, mirror};
use crate::math::{Real, V3};
use crate::scene::material::dielectric_f0;
use crate::scene::{Material, Model};
use std::f32::consts::PI;

/// The scattering of a surface, lane by lane, for one model.
#[derive(Clone, Copy, Debug)]
pub struct Surface<R: Real> {
    /// The model, the same in every lane.
    pub model: Model,
    /// The model's colour: the BRDF `ρ/π` for diffuse; the reflectance for
    /// mirror and metal; the transmittance for glass.
    pub tint: V3<R>,
    /// GGX roughness α (metal, metallic-roughness).
    pub alpha: R,
    /// Index of refraction (glass).
    pub ior: R,
    /// Metalness (metallic-roughness, transmission).
    pub metallic: R,
    /// The transmission factor (transmission).
    pub transmission: R,
    /// 1 where the surface is thin-walled, 0 where it bounds a solid
    /// (transmission).
    pub thin: R,
    /// `KHR_materials_specular`'s strength (metallic-roughness,
    /// transmission; 1 by default).
    pub specular: R,
    /// The dielectric `F0` colour before the strength,
    /// `min(F0(ior) × specularColor, 1)` ([`dielectric_f0`]; 0.04 by
    /// default) (metallic-roughness, transmission).
    pub f0: V3<R>,
}

impl Surface<f32> {
    /// The scattering of `material`, for one lane: each model's parameters
    /// from the material's fields. (Every parameter is a constant of the
    /// material today; a textured one will be looked up here, at the hit's
    /// texture coordinates.)
    #[inline]
    pub fn of(material: &Material) -> Self {
        let tint = match material.model {
            Model::Diffuse => material.reflectance / PI,
            Model::Mirror | Model::Metal | Model::MetallicRoughness | Model::Transmission => {
                material.reflectance
            }
            Model::Glass => material.transmittance,
        };
        let (alpha, metallic) = match material.model {
            Model::MetallicRoughness | Model::Transmission => {
                (material.roughness * material.roughness, material.metallic)
            }
            _ => (material.alpha, 0.0),
        };
        let (transmission, thin) = match material.model {
            Model::Transmission => (material.transmission, f32::from(u8::from(material.thin))),
            _ => (0.0, 0.0),
        };
        let (specular, f0) = Self::specular_of(material, 1.0, glam::Vec3::ONE);
        Surface {
            model: material.model,
            tint: V3::from(tint),
            alpha,
            ior: material.ior,
            metallic,
            transmission,
            thin,
            specular,
            f0,
        }
    }

    /// `(specular, F0 colour)` of `material` where its specular textures
    /// read `s` (A of `specularTexture`) and `c` (RGB of
    /// `specularColorTexture`): the factors times the texture values, the
    /// colour into [`dielectric_f0`] of the material's index; the
    /// defaults (1, 0.04) for models without a dielectric specular.
    #[inline]
    fn specular_of(material: &Material, s: f32, c: glam::Vec3) -> (f32, V3<f32>) {
        match material.model {
            Model::MetallicRoughness | Model::Transmission => (
                material.specular * s,
                V3::from(dielectric_f0(material.ior, material.specular_colour * c)),
            ),
            _ => (1.0, V3::from(dielectric_f0(1.5, glam::Vec3::ONE))),
        }
    }

    /// The scattering of `material` at a point where its textures read
    /// `colour` (what multiplies its reflectance, or glass's
    /// transmittance: base colour texture × vertex colour) and `(m, r)`
    /// (what multiply a metallic-roughness material's metalness and
    /// roughness) and `t` (what multiplies a transmission material's
    /// transmission factor) and `(specular, specular_colour)` (what
    /// multiply `KHR_materials_specular`'s strength and colour). With
    /// white and ones it is [`Surface::of`]'s surface up to rounding (not
    /// bit for bit: constant materials use [`Surface::of`]).
    #[inline]
    pub fn textured(
        material: &Material,
        colour: glam::Vec3,
        (m, r, t): (f32, f32, f32),
        (specular, specular_colour): (f32, glam::Vec3),
    ) -> Self {
        let mut s = Self::of(material);
        (s.specular, s.f0) = Self::specular_of(material, specular, specular_colour);
        let tint = match material.model {
            Model::Diffuse => material.reflectance * colour / PI,
            Model::Mirror | Model::Metal | Model::MetallicRoughness | Model::Transmission => {
                material.reflectance * colour
            }
            Model::Glass => material.transmittance * colour,
        };
        s.tint = V3::from(tint);
        if matches!(
            material.model,
            Model::MetallicRoughness | Model::Transmission
        ) {
            let roughness = material.roughness * r;
            s.alpha = roughness * roughness;
            s.metallic = material.metallic * m;
        }
        if material.model == Model::Transmission {
            s.transmission = material.transmission * t;
        }
        s
    }
}

impl<R: Real> Surface<R> {
    /// A diffuse surface of BRDF `f = ρ/π`.
    #[inline(always)]
    pub fn diffuse(f: V3<R>) -> Self {
        let f0 = R::splat(super::metallic_roughness::DIELECTRIC_F0);
        Self {
            model: Model::Diffuse,
            tint: f,
            alpha: R::splat(0.0),
            ior: R::splat(1.0),
            metallic: R::splat(0.0),
            transmission: R::splat(0.0),
            thin: R::splat(0.0),
            specular: R::splat(1.0),
            f0: V3::new(f0, f0, f0),
        }
    }

    /// The metallic-roughness parameters (base colour the tint).
    #[inline(always)]
    fn params(&self) -> Params<R> {
        Params {
            base: self.tint,
            metallic: self.metallic,
            alpha: self.alpha,
            f0: self.f0.scale(self.specular),
            f90: self.specular,
        }
    }

    /// The transmission parameters, `wo` on the geometric front where
    /// `front`.
    #[inline(always)]
    fn transmission_params(&self, front: R::Mask) -> tr::Params<R> {
        tr::Params {
            base: self.tint,
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

    /// The density to weigh, by multiple importance sampling, the emission
    /// that the direction of sample `s` finds, at a surface of geometric
    /// facing normal `ng` ([`facing`]): 0 where light sampling could not
    /// have found it — after a delta sample (of a delta model, or a smooth
    /// transmission lane), and after a transmission (light sampling
    /// connects only on the side of `ng`) — else the sample's density.
    #[inline(always)]
    pub fn mis_pdf(&self, s: &BsdfSample<R>, ng: V3<R>) -> R {
        let zero = R::splat(0.0);
        match self.model {
            Model::Transmission => {
                let through = s.wi.dot(ng).le(zero);
                R::select(s.delta | through, zero, s.pdf)
            }
            m if m.is_delta() => zero,
            _ => s.pdf,
        }
    }

    /// The scattered direction of a ray of direction `d` that hit the
    /// surface of geometric (front) unit normal `normal`, from the vertex's
    /// two direction numbers `u`. Diffuse surfaces draw uniform hemisphere
    /// directions when `uniform` (the report's estimator), cosine-weighted
    /// ones otherwise; glass chooses reflection or refraction with `u[0]`.
    #[inline(always)]
    pub fn sample(&self, normal: V3<R>, d: V3<R>, u: [R; 2], uniform: bool) -> BsdfSample<R> {
        let (front, n) = facing(normal, d);
        let wo = -d;
        match self.model {
            Model::Diffuse if uniform => diffuse::sample_uniform(n, self.tint, u),
            Model::Diffuse => diffuse::sample_cosine(n, self.tint, u),
            Model::Mirror => mirror::sample(n, wo, self.tint),
            Model::Glass => glass::sample(normal, wo, self.ior, self.tint, u[0]),
            Model::Metal => metal::sample(n, wo, self.alpha, self.tint, u),
            Model::MetallicRoughness => mr::sample(n, wo, &self.params(), u),
            Model::Transmission => tr::sample(n, wo, &self.transmission_params(front), u),
        }
    }

    /// [`sample`](Self::sample) at a smooth surface: `front` and `ng`, the
    /// geometric side and facing normal ([`facing`]), decide the side; the
    /// shading facing normal `ns` ([`shading_facing`](super::shading_facing))
    /// orients the lobe (glass takes it turned outward, to the geometric
    /// front). A direction that [`leaks`] through the geometric surface is
    /// absorbed: `f = 0`, `cos = 0`, `pdf = 1` (weight exactly zero), as
    /// the [`BsdfSample`] contract has absorbed samples. With `ns == ng`
    /// (flat) it is [`sample`](Self::sample), bit for bit.
    #[inline(always)]
    pub fn sample_shaded(
        &self,
        (front, ng, ns): (R::Mask, V3<R>, V3<R>),
        d: V3<R>,
        u: [R; 2],
        uniform: bool,
    ) -> BsdfSample<R> {
        let wo = -d;
        let s = match self.model {
            Model::Diffuse if uniform => diffuse::sample_uniform(ns, self.tint, u),
            Model::Diffuse => diffuse::sample_cosine(ns, self.tint, u),
            Model::Mirror => mirror::sample(ns, wo, self.tint),
            Model::Glass => {
                let outward = V3::select(front, ns, -ns);
                glass::sample(outward, wo, self.ior, self.tint, u[0])
            }
            Model::Metal => metal::sample(ns, wo, self.alpha, self.tint, u),
            Model::MetallicRoughness => mr::sample(ns, wo, &self.params(), u),
            Model::Transmission => tr::sample(ns, wo, &self.transmission_params(front), u),
        };
        let (zero, one) = (R::splat(0.0), R::splat(1.0));
        let leak = leaks(ns, ng, s.wi);
        BsdfSample {
            wi: s.wi,
            f: V3::select(leak, V3::new(zero, zero, zero), s.f),
            cos: R::select(leak, zero, s.cos),
            pdf: R::select(leak, one, s.pdf),
            delta: s.delta,
        }
    }

    /// For light sampling at a non-delta surface of facing unit normal `n`
    /// (turned towards `wo`; `front`: `wo` is on the geometric front):
    /// `(f · cos θ, cos θ, pdf)` for the direction `wi` on the side of
    /// `wo`, with `pdf` the density [`sample`](Self::sample) draws `wi`
    /// with (cosine-weighted for diffuse). Zero where the surface does not
    /// scatter `wo` into `wi`, and for `wi` on the other side; delta models
    /// give zero everywhere.
    #[inline(always)]
    pub fn eval(&self, n: V3<R>, wo: V3<R>, wi: V3<R>, front: R::Mask) -> (V3<R>, R, R) {
        let zero = R::splat(0.0);
        match self.model {
            Model::Diffuse => {
                let (fcos, cos) = diffuse::eval(n, self.tint, wi);
                (fcos, cos, diffuse::pdf_cosine(n, wi))
            }
            Model::Metal => {
                let f = metal::eval(n, wo, wi, self.alpha, self.tint);
                let cos = n.dot(wi).max(zero);
                (f.scale(cos), cos, metal::pdf(n, wo, wi, self.alpha))
            }
            Model::MetallicRoughness => {
                let p = self.params();
                let f = mr::eval(n, wo, wi, &p);
                let cos = n.dot(wi).max(zero);
                (f.scale(cos), cos, mr::pdf(n, wo, wi, &p))
            }
            Model::Transmission => {
                // Light sampling reaches the side of `wo` only.
                let p = self.transmission_params(front);
                let f = tr::eval(n, wo, wi, &p);
                let cos = n.dot(wi).max(zero);
                (f.scale(cos), cos, tr::pdf(n, wo, wi, &p))
            }
            Model::Mirror | Model::Glass => (V3::new(zero, zero, zero), zero, zero),
        }
    }
}
