//! The smooth dielectric (glass): an interface between the outside (index
//! of refraction 1) and a medium of index `ior`. Light is reflected with the
//! exact unpolarised Fresnel reflectance `F` or refracted by Snell's law with
//! probability `1 - F`; past the critical angle every ray is reflected
//! (total internal reflection). Both lobes are delta lobes.
//!
//! **Radiance scaling.** Radiance divided by the square of the index is
//! what stays invariant along a refracted ray, so a camera path (which
//! carries importance and gathers radiance) that crosses from index `n_o`
//! (the side of `wo`) to index `n_i` (the side of `wi`) scales its weight by
//! `(n_o / n_i)² = 1/η²` with `η = n_i / n_o`: entering the glass from
//! outside multiplies by `1/ior²`, leaving it by `ior²`. This is pbrt-v4's
//! `TransportMode::Radiance` convention (`ft /= Sqr(etap)`); a light
//! tracer (`TransportMode::Importance`) would leave the factor out. The
//! factors cancel for a path that enters and leaves the same medium.

use super::surface::{Bsdf, Texels, lanes, lanes3};
use super::{BsdfSample, reflect};
use crate::math::{Real, V3};
use crate::scene::{Material, Model};
use wide::f32x8;

/// The smooth dielectric model ([`Model::Glass`]).
pub struct Glass;

/// Its parameters.
#[derive(Clone, Copy, Debug)]
pub struct Params<R: Real> {
    /// The index of refraction of the medium behind the front side.
    pub ior: R,
    /// The transmittance tint of refraction (times the colour textures).
    pub tint: V3<R>,
}

impl Bsdf for Glass {
    const MODEL: Model = Model::Glass;
    const DELTA: bool = true;
    type Params<R: Real> = Params<R>;

    #[inline]
    fn params(m: &Material, at: &impl Texels) -> Params<f32> {
        Params {
            ior: m.ior,
            tint: V3::from(m.transmittance * at.colour()),
        }
    }

    #[inline(always)]
    fn gather(table: &[Params<f32>], rows: &[usize; 8]) -> Params<f32x8> {
        Params {
            ior: lanes(rows, |i| table[i].ior),
            tint: lanes3(rows, |i| table[i].tint),
        }
    }

    /// [`sample`] with the facing normal turned outward (to the geometric
    /// front), as it takes it.
    #[inline(always)]
    fn sample<R: Real>(
        p: &Params<R>,
        (front, n): (R::Mask, V3<R>),
        wo: V3<R>,
        u: [R; 2],
        _uniform: bool,
    ) -> BsdfSample<R> {
        let outward = V3::select(front, n, -n);
        sample(outward, wo, p.ior, p.tint, u[0])
    }
}

/// The unpolarised Fresnel reflectance of a smooth dielectric interface,
/// exact (the mean of the `s` and `p` reflectances), and the cosine of the
/// refracted direction.
///
/// `cos_i` is the cosine of the incident direction with the normal on its
/// own side, in `[0, 1]`; `eta = n_t / n_i` is the index on the far side
/// over the index on the incident side. Where `sin²θt = sin²θi / η² ≥ 1`
/// (total internal reflection, beyond the critical angle `asin η` when
/// `η < 1`), the reflectance is `1` and the returned cosine `0`.
/// Otherwise, with `cos θt = sqrt(1 - sin²θt)`:
/// `r_s = (cos θi - η cos θt) / (cos θi + η cos θt)`,
/// `r_p = (η cos θi - cos θt) / (η cos θi + cos θt)` and
/// `F = (r_s² + r_p²) / 2`.
#[inline(always)]
pub fn fresnel_dielectric<R: Real>(cos_i: R, eta: R) -> (R, R) {
    let zero = R::splat(0.0);
    let one = R::splat(1.0);
    // cos²θt = 1 - sin²θi/η² = ((η - 1)(η + 1) + cos²θi) / η²: no
    // cancellation in 1 - cos²θi, so η = 1 gives θt = θi exactly and
    // grazing angles keep their digits.
    let num = cos_i.mul_add(cos_i, (eta - one) * (eta + one));
    let tir = num.le(zero);
    let cos_t = (num / (eta * eta)).max(zero).sqrt();
    let r_s = (-eta).mul_add(cos_t, cos_i) / eta.mul_add(cos_t, cos_i);
    let r_p = eta.mul_add(cos_i, -cos_t) / eta.mul_add(cos_i, cos_t);
    let f = r_s.mul_add(r_s, r_p * r_p) * R::splat(0.5);
    (R::select(tir, one, f), R::select(tir, zero, cos_t))
}

/// The refracted direction of `wo` through an interface with unit normal
/// `n` on the side of `wo`, where `cos_i = n · wo`, `inv_eta = 1/η` and
/// `cos_t` is the refracted cosine (from [`fresnel_dielectric`]):
/// `wt = -wo/η + (cos θi/η - cos θt) n`, a unit vector on the other side
/// (up to rounding). Meaningless under total internal reflection.
#[inline(always)]
pub fn refract<R: Real>(wo: V3<R>, n: V3<R>, cos_i: R, inv_eta: R, cos_t: R) -> V3<R> {
    let k = cos_i.mul_add(inv_eta, -cos_t);
    n.mul_add(k, (-wo).scale(inv_eta))
}

/// Scattering by the interface, from one uniform number `u` in `[0, 1)`.
///
/// `n` is the *geometric* unit normal, pointing to the outside (index 1);
/// `wo` is on the outside where `n · wo > 0` (the ray arrives on the front,
/// as [`facing`](super::facing) decides it) and inside otherwise (`n · wo = 0`
/// included: a tangent `wo` from inside is totally reflected, onto itself). `ior` is the medium's index (any positive value;
/// below 1 the medium is optically thinner than the outside), `tint` the
/// transmittance tint (white for clear glass).
///
/// With `F` the Fresnel reflectance at `wo` ([`fresnel_dielectric`]):
/// if `u < F` the sample is the mirror direction with weight `f = 1`
/// (reflection is not tinted); otherwise it is the refracted direction with
/// weight `f = tint / η²` (the radiance scaling above; `η = ior` entering,
/// `1/ior` leaving). The probabilities `F` and `1 - F` of the choice cancel
/// the Fresnel factors of the BSDF exactly, so both are delta samples with
/// `cos = 1`, `pdf = 1` (see [`BsdfSample`]). A reflected `wi` is on the
/// side of `wo`, a refracted one on the other side.
///
/// Scene files keep `ior` within [`IOR_RANGE`](crate::scene::material::IOR_RANGE); beyond it
/// (a material built in code), `η²` may overflow and the Fresnel terms
/// turn NaN: the sample is then the mirror direction, the limit of an
/// interface of infinite contrast — never a NaN direction.
#[inline(always)]
pub fn sample<R: Real>(n: V3<R>, wo: V3<R>, ior: R, tint: V3<R>, u: R) -> BsdfSample<R> {
    let one = R::splat(1.0);
    let c = n.dot(wo);
    let front = R::splat(0.0).lt(c);
    let inv_ior = one / ior;
    let eta = R::select(front, ior, inv_ior);
    let inv_eta = R::select(front, inv_ior, ior);
    let nf = V3::select(front, n, -n);
    let cos_i = c.abs();
    let (fr, cos_t) = fresnel_dielectric(cos_i, eta);
    let wr = reflect(wo, nf);
    let wt = refract(wo, nf, cos_i, inv_eta, cos_t);
    // `fr ≤ u` is `!(u < fr)` save where `fr` is NaN (then: reflect).
    let refracts = fr.le(u) & wt.dot(wt).lt(R::splat(f32::INFINITY));
    let scale = inv_eta * inv_eta;
    BsdfSample {
        wi: V3::select(refracts, wt, wr),
        f: V3::select(refracts, tint.scale(scale), V3::new(one, one, one)),
        cos: one,
        pdf: one,
        delta: R::splat_mask(true),
    }
}
