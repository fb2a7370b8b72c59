//! The rough dielectric interface of glTF's `KHR_materials_transmission`:
//! GGX microfacet reflection and transmission with the exact unpolarised
//! Fresnel term of the index of refraction, after Walter et al.,
//! "Microfacet Models for Refraction through Rough Surfaces" (2007), in
//! the form of pbrt-v4's `DielectricBxDF` (height-correlated Smith
//! masking–shadowing `G2`, generalised half vector). The transmitted light
//! is tinted by `tint` (glTF's base colour); reflection is not.
//!
//! Two geometries, as `KHR_materials_volume` decides:
//!
//! - **Solid** (a volume boundary, `thickness > 0`): light refracts by
//!   Snell's law about each microfacet, with `η = n_t / n_i` (the index on
//!   the far side over the index on the side of `wo`). With
//!   `h = normalize(wo + η wi)` (turned to the side of `n`), the BTDF is
//!   `(1 − F(wo·h)) · tint · D(h) G2 |wi·h| |wo·h| / (|n·wi| |n·wo| (wi·h + wo·h/η)²) / η²`,
//!   the last factor the radiance scaling of [`glass`](super::glass)
//!   (a camera path carries radiance). Its density carries the Jacobian
//!   `|wi·h| / (wi·h + wo·h/η)²` of the generalised half vector.
//! - **Thin-walled** (no volume, or thickness 0): the ray enters and
//!   leaves at the same surface, so there is no refraction on average. The
//!   transmission lobe is the reflection lobe mirrored through the surface
//!   (the specification's `H_T = normalize(V − 2 (N·L) N + L)`): a
//!   transmitted `wi` has the value `(1 − F) · tint · D G2 / (4 |n·wo| |n·wi|)`
//!   of its mirror image `wi − 2 (n·wi) n`, with `F` the Fresnel term of
//!   the index (`η = ior` from either side) and no radiance scaling (the
//!   ray goes back into the medium it came from).
//!
//! The reflection lobe is the same for both: `F(wo·h) · D(h) G2 / (4 |n·wo| |n·wi|)`,
//! `h = normalize(wo + wi)`.
//!
//! **Smooth.** Below [`SMOOTH_ALPHA`] (glTF roughness below about 0.03)
//! the interface is smooth and both lobes are delta lobes, sampled
//! exactly (as [`glass`](super::glass) does): reflection with
//! probability `F(n·wo)`, else the refracted direction (solid, weight
//! `tint / η²`) or the straight-through `−wo` (thin, weight `tint`).
//! [`eval`] and [`pdf`] are 0 there. An index-matched solid interface
//! (`η = 1`) is smooth too (it does not deviate light).
//!
//! **Sampling.** The lobe is chosen before the microfacet normal, with
//! probability `P_r = min(F(n·wo), 0.9)` for reflection (the first number
//! picks it and is stretched back to `[0, 1)`), then a visible normal `h`
//! is drawn ([`metal`]'s spherical caps) and `wo` is reflected or
//! refracted (or reflected and mirrored, thin) about it. The density of a
//! direction is `P_r · D_wo(h)/(4 wo·h)` above the surface and
//! `(1 − P_r) · D_wo(h) · |wi·h| / (wi·h + wo·h/η)²` below (solid; the
//! mirrored reflection density, thin). The cap at 0.9 keeps transmission
//! possible inside a solid beyond the critical angle, where some
//! microfacets still let light out. Directions that land on the wrong side
//! (a refraction about a microfacet that totally reflects, a reflection
//! below the horizon) are absorbed.
//!
//! Every function takes the *facing* unit normal `n` (on the side of `wo`)
//! and the [`Params`] as seen from `wo`.

use super::glass::{fresnel_dielectric, refract};
use super::metal::{self, clamp_alpha, smith_s};
use super::{BsdfSample, local_to_world, reflect, tangents};
use crate::math::{Real, V3};

pub use crate::scene::material::SMOOTH_ALPHA;

/// The largest probability of choosing the reflection lobe (see the
/// module documentation).
pub const MAX_REFLECT_PROBABILITY: f32 = 0.9;

/// The largest `f32` below 1.
const BELOW_ONE: f32 = 1.0 - f32::EPSILON / 2.0;

/// The interface at a point, seen from `wo`, lane by lane.
#[derive(Clone, Copy, Debug)]
pub struct Params<R: Real> {
    /// The transmission tint (glTF's base colour), linear RGB.
    pub tint: V3<R>,
    /// The GGX α (glTF roughness squared).
    pub alpha: R,
    /// `η = n_t / n_i`: the index on the far side over that on the side of
    /// `wo` (solid: `ior` entering, `1/ior` leaving; thin: `ior`).
    pub eta: R,
    /// Whether the surface is thin-walled (else a solid's boundary).
    pub thin: R::Mask,
    /// `KHR_materials_specular` on the interface: `(F0(ior), F0 colour,
    /// strength)` — the index's own normal-incidence reflectance
    /// ([`f0_of_ior`](crate::scene::material::f0_of_ior) of the
    /// material's index), the specification's `min(F0(ior) ×
    /// specularColor, 1)` and its `specular`. The reflectance is the
    /// index's exact Fresnel term `F` remapped so that it starts from the
    /// colour's `F0` and still reaches 1 at grazing angles, times the
    /// strength ([`Params::reflectance`]); transmission takes
    /// `1 − max(reflectance)`. With the default (`F0 colour = F0(ior)`,
    /// strength 1) the reflectance is `F` itself, bit for bit.
    pub specular: (R, V3<R>, R),
}

impl<R: Real> Params<R> {
    /// The default specular of an index (`KHR_materials_specular`
    /// absent): the reflectance is the exact Fresnel term.
    #[inline(always)]
    pub fn plain_specular() -> (R, V3<R>, R) {
        let (zero, one) = (R::splat(0.0), R::splat(1.0));
        (zero, V3::new(zero, zero, zero), one)
    }

    /// `(reflectance per channel, 1 − its largest channel)` of the
    /// interface where its exact Fresnel term is `f`: with `F0 = F0(ior)`,
    /// `s = (f − F0) / (1 − F0)` (0 at normal incidence, 1 at grazing and
    /// beyond the critical angle), the specification's `fresnel_mix`
    /// with the shape of the exact term: `strength × (F0c + (1 − F0c) s)`
    /// `= strength × (f + (F0c − F0)(1 − s))` per channel `c`.
    #[inline(always)]
    pub fn reflectance(&self, f: R) -> (V3<R>, R) {
        let one = R::splat(1.0);
        let (f0, c, strength) = self.specular;
        let rest = one - (f - f0) / (one - f0);
        let r = |c: R| (c - f0).mul_add(rest, f) * strength;
        let rgb = V3::new(r(c.x), r(c.y), r(c.z));
        (rgb, one - rgb.x.max(rgb.y).max(rgb.z))
    }
}

impl<R: Real> Params<R> {
    /// Whether the interface is smooth (delta lobes), lane by lane.
    #[inline(always)]
    pub fn smooth(&self) -> R::Mask {
        // `!(SMOOTH_ALPHA ≤ α)`: a NaN α is smooth.
        let rough = R::splat(SMOOTH_ALPHA).le(self.alpha);
        let matched = self.eta.eq(R::splat(1.0)) & not::<R>(self.thin);
        not::<R>(rough) | matched
    }
}

/// `!mask`, lane by lane.
#[inline(always)]
fn not<R: Real>(mask: R::Mask) -> R::Mask {
    R::select(mask, R::splat(0.0), R::splat(1.0)).eq(R::splat(1.0))
}

/// The probability of choosing the reflection lobe at `co = n · wo`:
/// `min(F(co, η), 0.9)` (NaN-safe: 0.9).
#[inline(always)]
pub fn reflect_probability<R: Real>(co: R, eta: R) -> R {
    let (f, _) = fresnel_dielectric(co, eta);
    R::splat(MAX_REFLECT_PROBABILITY).min(f)
}

/// What [`eval`] and [`pdf`] share: `(f, pdf)` of the rough lobes for
/// the pair of directions, 0 for smooth lanes and for pairs the lobes do
/// not connect.
#[inline(always)]
fn eval_pdf<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, p: &Params<R>) -> (V3<R>, R) {
    let (zero, one, two) = (R::splat(0.0), R::splat(1.0), R::splat(2.0));
    let a = clamp_alpha(p.alpha);
    let a2 = a * a;
    let (co, ci) = (n.dot(wo), n.dot(wi));
    let above = zero.lt(ci);
    let below = ci.lt(zero);
    // Thin transmission: the mirror image of `wi`, above the surface.
    let mirrored = n.mul_add(-(ci * two), wi);
    let solid_t = below & not::<R>(p.thin);
    let wr = V3::select(above, wi, mirrored);
    let h = V3::select(solid_t, wi.mul_add(p.eta, wo), wo + wr);
    let h = V3::select(n.dot(h).lt(zero), -h, h);
    let hl2 = h.dot(h);
    let m = h.scale(one / hl2.sqrt());
    // `wi`, or its mirror image for a thin transmission.
    let iw = V3::select(solid_t, wi, wr);
    let (om, im) = (wo.dot(m), iw.dot(m));
    // Microfacets seen from both directions on their own sides.
    let facing_ok = zero.lt(om) & zero.lt(R::select(solid_t, -im, im));
    let valid = zero.lt(co) & (above | below) & zero.lt(hl2) & facing_ok & not::<R>(p.smooth());
    let d = metal::ndf(n, h, a);
    let aci = ci.abs();
    let (so, si) = (smith_s(co, a2), smith_s(aci, a2));
    // D G2 / (4 co ci) = D / (2 (co S(ci) + ci S(co))).
    let dg = d / ((co * si + aci * so) * two);
    let (fr, _) = fresnel_dielectric(om, p.eta);
    let pr = reflect_probability(co, p.eta);
    // The visible-normal density of `m` over 4 (wo·m): D / (2 (co + S(co))).
    let vis = d / ((co + so) * two);
    // Solid transmission: Walter's Jacobian.
    let inv_eta = one / p.eta;
    let denom = om.mul_add(inv_eta, im);
    let denom2 = denom * denom;
    let jac = im.abs() / denom2;
    let t_value = dg * R::splat(4.0) * im.abs() * om / denom2 * inv_eta * inv_eta;
    let t_pdf = vis * R::splat(4.0) * om * jac;
    let (rgb, t_weight) = p.reflectance(fr);
    let (value, density) = (
        R::select(solid_t, t_value, dg),
        R::select(solid_t, t_pdf, vis),
    );
    let lobe = R::select(above, pr, one - pr);
    let tint = V3::select(above, V3::new(one, one, one), p.tint);
    let pdf = R::select(valid, density * lobe, zero);
    let weight = |c: R| R::select(above, c, t_weight);
    let f = |c: R| R::select(valid, value * weight(c), zero);
    (
        V3::new(tint.x * f(rgb.x), tint.y * f(rgb.y), tint.z * f(rgb.z)),
        pdf,
    )
}

/// The BSDF value `f(wo, wi)` per RGB channel (without the cosine) of the
/// rough lobes: reflection where `wi` is above the surface, transmission
/// below (see the module documentation); 0 for smooth lanes.
#[inline(always)]
pub fn eval<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, p: &Params<R>) -> V3<R> {
    eval_pdf(n, wo, wi, p).0
}

/// The density [`sample`] draws `wi` with, per unit solid angle (0 for
/// smooth lanes).
#[inline(always)]
pub fn pdf<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, p: &Params<R>) -> R {
    eval_pdf(n, wo, wi, p).1
}

/// A direction from the interface, from two uniform numbers `u` in
/// `[0, 1)`: for rough lanes, the lobe by [`reflect_probability`] and a
/// visible microfacet normal (value and density from [`eval`] and
/// [`pdf`], `cos = |n · wi|`; absorbed where the direction lands on the
/// wrong side); for smooth lanes, a delta sample (see the module
/// documentation).
#[inline(always)]
pub fn sample<R: Real>(n: V3<R>, wo: V3<R>, p: &Params<R>, u: [R; 2]) -> BsdfSample<R> {
    let (zero, one, two) = (R::splat(0.0), R::splat(1.0), R::splat(2.0));
    let co = n.dot(wo);
    let inv_eta = one / p.eta;
    // Smooth: reflection with probability F(co).
    let (fc, cos_t) = fresnel_dielectric(co, p.eta);
    let smooth_r = u[0].lt(fc) | not::<R>(fc.le(one));
    let mirror = reflect(wo, n);
    let straight = refract(wo, n, co, inv_eta, cos_t);
    let through = V3::select(p.thin, -wo, straight);
    let scale = R::select(p.thin, one, inv_eta * inv_eta);
    // The reflectance over the probability of each choice (1 by
    // default): `F` chose reflection, the exact term.
    let (rgb, t_weight) = p.reflectance(fc);
    let chosen = zero.lt(fc) & fc.le(one);
    let r_weight = V3::select(
        chosen,
        V3::new(rgb.x / fc, rgb.y / fc, rgb.z / fc),
        V3::new(one, one, one),
    );
    let t_ratio = R::select(fc.lt(one), t_weight / (one - fc), one);
    let smooth = BsdfSample {
        wi: V3::select(smooth_r, mirror, through),
        f: V3::select(smooth_r, r_weight, p.tint.scale(scale).scale(t_ratio)),
        cos: one,
        pdf: one,
        delta: R::splat_mask(true),
    };
    // Rough: the lobe, then a visible normal.
    let pr = reflect_probability(co, p.eta);
    let pick_r = u[0].lt(pr);
    let us = R::select(pick_r, u[0] / pr, (u[0] - pr) / (one - pr))
        .max(zero)
        .min(R::splat(BELOW_ONE));
    let a = clamp_alpha(p.alpha);
    let frame = tangents(n);
    let (nt, nb) = frame;
    let wo_local = V3::new(nb.dot(wo), co, nt.dot(wo));
    let (ml, _, n2) = metal::sample_visible_normal(wo_local, a, [us, u[1]]);
    let m = local_to_world(n, frame, ml.x, ml.y, ml.z);
    let om = wo.dot(m);
    let wr = reflect(wo, m);
    let (fm, cos_tm) = fresnel_dielectric(om, p.eta);
    let wt = refract(wo, m, om, inv_eta, cos_tm);
    let thin_t = n.mul_add(-(n.dot(wr) * two), wr);
    let wi = V3::select(pick_r, wr, V3::select(p.thin, thin_t, wt));
    let ci = n.dot(wi);
    let (f, pdf) = eval_pdf(n, wo, wi, p);
    let side = R::select(pick_r, ci, -ci);
    // A solid refraction about a microfacet that totally reflects has no
    // direction (`refract` is meaningless there).
    let tir = one.le(fm) & not::<R>(pick_r | p.thin);
    let valid = zero.lt(side) & zero.lt(pdf) & zero.lt(n2) & not::<R>(tir);
    let rough = BsdfSample {
        wi,
        f: V3::select(valid, f, V3::new(zero, zero, zero)),
        cos: R::select(valid, ci.abs(), zero),
        pdf: R::select(valid, pdf, one),
        delta: R::splat_mask(false),
    };
    let s = p.smooth();
    BsdfSample {
        wi: V3::select(s, smooth.wi, rough.wi),
        f: V3::select(s, smooth.f, rough.f),
        cos: R::select(s, smooth.cos, rough.cos),
        pdf: R::select(s, smooth.pdf, rough.pdf),
        delta: s,
    }
}
