//! The ideal diffuse (Lambertian) model: BRDF `ρ/π` on both sides of the
//! surface.
//!
//! Every function takes the normal facing the incoming ray (the side of
//! `wo`, as [`facing`](super::facing) returns it): reflection happens on
//! that side, and there is none on the other.

use super::surface::{Bsdf, Texels, lanes3};
use super::{BsdfSample, local_to_world, tangents};
use crate::math::{Real, V3, sin_cos_2pi};
use crate::scene::{Material, Model};
use wide::f32x8;

/// The diffuse model ([`Model::Diffuse`]).
pub struct Diffuse;

/// Its parameter: the BRDF `f = ρ/π`, ρ the reflectance times the colour
/// textures.
#[derive(Clone, Copy, Debug)]
pub struct Params<R: Real> {
    /// `ρ/π` per RGB channel.
    pub f: V3<R>,
}

impl Bsdf for Diffuse {
    const MODEL: Model = Model::Diffuse;
    type Params<R: Real> = Params<R>;

    #[inline]
    fn params(m: &Material, at: &impl Texels) -> Params<f32> {
        Params {
            f: V3::from(m.reflectance * at.colour() / std::f32::consts::PI),
        }
    }

    #[inline(always)]
    fn gather(table: &[Params<f32>], rows: &[usize; 8]) -> Params<f32x8> {
        Params {
            f: lanes3(rows, |i| table[i].f),
        }
    }

    #[inline(always)]
    fn of_brdf<R: Real>(brdf: impl FnOnce() -> V3<R>) -> Option<Params<R>> {
        Some(Params { f: brdf() })
    }

    #[inline(always)]
    fn sample<R: Real>(
        p: &Params<R>,
        (_, n): (R::Mask, V3<R>),
        _wo: V3<R>,
        u: [R; 2],
        uniform: bool,
    ) -> BsdfSample<R> {
        if uniform {
            sample_uniform(n, p.f, u)
        } else {
            sample_cosine(n, p.f, u)
        }
    }

    #[inline(always)]
    fn eval<R: Real>(
        p: &Params<R>,
        n: V3<R>,
        _wo: V3<R>,
        wi: V3<R>,
        _front: R::Mask,
    ) -> (V3<R>, R, R) {
        let (fcos, cos) = eval(n, p.f, wi);
        (fcos, cos, pdf_cosine(n, wi))
    }
}

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

/// Cosine-weighted sampling: a direction on the hemisphere of `n` with
/// density `cos θ / π`, from two uniform numbers (Malley's method: a point
/// of the unit disk, by Shirley and Chiu's concentric map, lifted to the
/// hemisphere), weighted for the BRDF value `f = ρ/π`.
#[inline(always)]
pub fn sample_cosine<R: Real>(n: V3<R>, f: V3<R>, u: [R; 2]) -> BsdfSample<R> {
    let (one, zero) = (R::splat(1.0), R::splat(0.0));
    // The square [-1, 1]² to the unit disk: (r, φ) by wedges.
    let a = u[0].mul_add(R::splat(2.0), -one);
    let b = u[1].mul_add(R::splat(2.0), -one);
    let wide = b.abs().lt(a.abs());
    let r = R::select(wide, a, b);
    // φ / 2π: (b/a)/8 in the wedges around ±x, 1/4 - (a/b)/8 around ±y.
    let safe = |x: R| R::select(x.eq(zero), one, x);
    let turn = R::select(
        wide,
        b / safe(a) * R::splat(0.125),
        R::splat(0.25) - a / safe(b) * R::splat(0.125),
    );
    let (sin_phi, cos_phi) = sin_cos_2pi(turn);
    let (dx, dz) = (r * cos_phi, r * sin_phi);
    let cos = (-dx).mul_add(dx, (-dz).mul_add(dz, one));
    let cos = R::select(cos.lt(zero), zero, cos).sqrt();
    // On the rim of the disk the direction grazes the surface (cos θ = 0,
    // density 0): an absorbed sample, weight exactly 0 rather than 0/0.
    let grazing = cos.le(zero);
    BsdfSample {
        wi: to_world(n, dx, cos, dz),
        f: V3::select(grazing, V3::new(zero, zero, zero), f),
        cos,
        pdf: R::select(grazing, one, cos * R::splat(std::f32::consts::FRAC_1_PI)),
        delta: R::splat_mask(false),
    }
}

/// The diffuse BRDF `f = ρ/π` (given as `f`) for the direction `wi`, with
/// `n` the normal facing the incoming ray: `(f · cos θ, cos θ)` on that
/// side, zero on the other (diffuse reflection never transmits).
#[inline(always)]
pub fn eval<R: Real>(n: V3<R>, f: V3<R>, wi: V3<R>) -> (V3<R>, R) {
    let zero = R::splat(0.0);
    let cos = n.dot(wi);
    let cos = R::select(cos.lt(zero), zero, cos);
    (f.scale(cos), cos)
}

/// The density of [`sample_cosine`] for the direction `wi` (`n` the
/// normal facing the incoming ray): `max(0, cos θ) / π`.
#[inline(always)]
pub fn pdf_cosine<R: Real>(n: V3<R>, wi: V3<R>) -> R {
    let zero = R::splat(0.0);
    let cos = n.dot(wi);
    R::select(cos.lt(zero), zero, cos) * R::splat(std::f32::consts::FRAC_1_PI)
}

/// The density of [`sample_uniform`] for the direction `wi` (`n` the
/// normal facing the incoming ray): `1/2π` where `cos θ > 0`, zero
/// elsewhere.
#[inline(always)]
pub fn pdf_uniform<R: Real>(n: V3<R>, wi: V3<R>) -> R {
    let zero = R::splat(0.0);
    let above = zero.lt(n.dot(wi));
    R::select(above, R::splat(1.0 / (2.0 * std::f32::consts::PI)), zero)
}

/// A direction on the hemisphere around unit normal `n`, uniform in solid
/// angle (pdf `1/2π`), from two uniform numbers — the report's method.
///
/// In the local frame with `n` as the y axis: `cos θ = X1`,
/// `sin θ = sqrt(1 - X1²)`, `φ = 2π·X2`,
/// `(x, y, z) = (sin θ cos φ, X1, sin θ sin φ)`. The frame around `n` is
/// Scratchapixel's (the report's reference \[3\]): a tangent `nt` orthogonal
/// to `n` built from its two largest components, and `nb = n × nt`.
#[inline(always)]
pub fn uniform_hemisphere<R: Real>(n: V3<R>, x1: R, x2: R) -> V3<R> {
    let sin_theta = (-x1).mul_add(x1, R::splat(1.0)).sqrt();
    let (sin_phi, cos_phi) = sin_cos_2pi(x2);
    to_world(n, sin_theta * cos_phi, x1, sin_theta * sin_phi)
}

/// The direction with coordinates `(lx, ly, lz)` in the frame of unit
/// normal `n` (its y axis): [`local_to_world`] in the frame of
/// [`tangents`] (Scratchapixel's, the report's reference \[3\]), i.e.
/// `nb·lx + n·ly + nt·lz`.
#[inline(always)]
pub fn to_world<R: Real>(n: V3<R>, lx: R, ly: R, lz: R) -> V3<R> {
    local_to_world(n, tangents(n), lx, ly, lz)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampler::PathRng;
    use wide::f32x8;

    #[test]
    fn a_grazing_cosine_sample_weighs_exactly_nothing() {
        // u = (0, 1/2) is the rim of the disk: cos θ = 0 and density 0.
        let n = V3::new(0.0f32, 1.0, 0.0);
        let s = sample_cosine(n, V3::new(0.5, 0.5, 0.5), [0.0, 0.5]);
        assert_eq!(s.cos, 0.0);
        let w = s.weigh(V3::new(1.0, 1.0, 1.0));
        assert_eq!([w.x, w.y, w.z], [0.0; 3]);
    }

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
