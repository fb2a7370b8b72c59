//! The ideal diffuse (Lambertian) model: BRDF `ρ/π` on both sides of the
//! surface (two-sided: light and viewer on the same side, either side).
//!
//! - [`sample_uniform`]: the report's uniform hemisphere sampling (pdf
//!   `1/2π`), what the engines use today;
//! - [`sample_cosine`]: cosine-weighted sampling (pdf `cos θ/π`, weight `ρ`);
//! - [`eval`], [`pdf`], [`pdf_uniform`]: the BRDF and the two densities for
//!   a given pair of directions (for next-event estimation and MIS).

use super::{BsdfSample, tangents, to_world};
use crate::math::{Real, V3, sin_cos_2pi};
use std::f32::consts::PI;

/// The report's sampling routine: a direction uniform on the hemisphere of
/// `n` (pdf `1/2π`), from two uniform numbers `u = [X1, X2]`, weighted for
/// the BRDF value `f = ρ/π`. The cosine of the direction with `n` is `X1`
/// by construction (see [`uniform_hemisphere`]).
#[inline(always)]
pub fn sample_uniform<R: Real>(n: V3<R>, f: V3<R>, u: [R; 2]) -> BsdfSample<R> {
    BsdfSample {
        wi: uniform_hemisphere(n, u[0], u[1]),
        f,
        // Exactly X1: dot(wi, n) equals it only up to rounding, which can
        // make it -1e-7 and a sample negative.
        cos: u[0],
        pdf: R::splat(1.0 / (2.0 * std::f32::consts::PI)),
        delta: R::splat_mask(false),
    }
}

/// Cosine-weighted sampling (Malley's method): a point uniform on the unit
/// disk (`r = sqrt(X1)`, `φ = 2π·X2`) lifted to the hemisphere of the
/// facing normal `n`, so `cos θ = sqrt(1 - X1)` and the density is
/// `cos θ / π`; the BRDF value is `f = ρ/π` (`rho` divided by `π`, as the
/// engines compute it). The weight `f · cos / pdf` is `ρ` up to rounding.
///
/// `X1` in `[0, 1)` keeps `cos θ` and `pdf` strictly positive. The local
/// frame is [`uniform_hemisphere`]'s.
#[inline(always)]
pub fn sample_cosine<R: Real>(n: V3<R>, rho: V3<R>, u: [R; 2]) -> BsdfSample<R> {
    let one = R::splat(1.0);
    let cos = (one - u[0]).sqrt();
    let r = u[0].sqrt();
    let (sin_phi, cos_phi) = sin_cos_2pi(u[1]);
    BsdfSample {
        wi: to_world(n, tangents(n), r * cos_phi, cos, r * sin_phi),
        f: brdf(rho),
        cos,
        pdf: cos * R::splat(1.0 / PI),
        delta: R::splat_mask(false),
    }
}

/// `ρ/π` per channel, a division by `π` (correctly rounded) as the engines
/// compute the diffuse BRDF.
#[inline(always)]
fn brdf<R: Real>(rho: V3<R>) -> V3<R> {
    let pi = R::splat(PI);
    V3::new(rho.x / pi, rho.y / pi, rho.z / pi)
}

/// The cosines of `wo` and `wi` with `n`, and whether the two lie strictly
/// on the same side of the surface.
#[inline(always)]
fn same_side<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>) -> (R::Mask, R) {
    let zero = R::splat(0.0);
    let (co, ci) = (n.dot(wo), n.dot(wi));
    let same = (zero.lt(co) & zero.lt(ci)) | (co.lt(zero) & ci.lt(zero));
    (same, ci.abs())
}

/// The BRDF value for the pair `(wo, wi)`: `ρ/π` where `wi` lies strictly on
/// the side of `wo` (the model is two-sided), `0` elsewhere (transmission,
/// or either direction in the plane). `n` is either unit normal of the
/// surface: facing or geometric, the answer is the same.
#[inline(always)]
pub fn eval<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>, rho: V3<R>) -> V3<R> {
    let (same, _) = same_side(n, wo, wi);
    let zero = V3::new(R::splat(0.0), R::splat(0.0), R::splat(0.0));
    V3::select(same, brdf(rho), zero)
}

/// The density [`sample_cosine`] draws `wi` with, given `wo`: `|cos θi|/π`
/// on the side of `wo`, `0` elsewhere. `n` as in [`eval`].
#[inline(always)]
pub fn pdf<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>) -> R {
    let (same, cos) = same_side(n, wo, wi);
    R::select(same, cos * R::splat(1.0 / PI), R::splat(0.0))
}

/// The density [`sample_uniform`] draws `wi` with, given `wo`: `1/2π` on
/// the side of `wo`, `0` elsewhere. `n` as in [`eval`].
#[inline(always)]
pub fn pdf_uniform<R: Real>(n: V3<R>, wo: V3<R>, wi: V3<R>) -> R {
    let (same, _) = same_side(n, wo, wi);
    R::select(same, R::splat(1.0 / (2.0 * PI)), R::splat(0.0))
}

/// A direction on the hemisphere around unit normal `n`, uniform in solid
/// angle (pdf `1/2π`), from two uniform numbers — the report's method.
///
/// In the local frame with `n` as the y axis: `cos θ = X1`,
/// `sin θ = sqrt(1 - X1²)`, `φ = 2π·X2`,
/// `(x, y, z) = (sin θ cos φ, X1, sin θ sin φ)`, taken to the world by
/// [`to_world`] in the frame of [`tangents`] (Scratchapixel's, the report's
/// reference \[3\]).
#[inline(always)]
pub fn uniform_hemisphere<R: Real>(n: V3<R>, x1: R, x2: R) -> V3<R> {
    let sin_theta = (-x1).mul_add(x1, R::splat(1.0)).sqrt();
    let (sin_phi, cos_phi) = sin_cos_2pi(x2);
    let (lx, ly, lz) = (sin_theta * cos_phi, x1, sin_theta * sin_phi);
    to_world(n, tangents(n), lx, ly, lz)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampler::PathRng;
    use wide::f32x8;

    #[test]
    fn simd_hemisphere_equals_scalar_bitwise() {
        let mut rng = PathRng::new(7, 3, 9);
        for _ in 0..5_000 {
            let ns: [glam::Vec3; 8] = std::array::from_fn(|_| {
                let v = glam::Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                );
                v.try_normalize().unwrap_or(glam::Vec3::Y)
            });
            let x1: [f32; 8] = std::array::from_fn(|_| rng.next_f32());
            let x2: [f32; 8] = std::array::from_fn(|_| rng.next_f32());
            let n8 = V3::new(
                f32x8::from(ns.map(|n| n.x)),
                f32x8::from(ns.map(|n| n.y)),
                f32x8::from(ns.map(|n| n.z)),
            );
            let d8 = uniform_hemisphere(n8, f32x8::from(x1), f32x8::from(x2));
            for l in 0..8 {
                let d = uniform_hemisphere(V3::from(ns[l]), x1[l], x2[l]);
                assert_eq!(d.x.to_bits(), d8.x.to_array()[l].to_bits());
                assert_eq!(d.y.to_bits(), d8.y.to_array()[l].to_bits());
                assert_eq!(d.z.to_bits(), d8.z.to_array()[l].to_bits());
            }
        }
    }
}
