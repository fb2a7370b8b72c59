//! The perfect mirror: specular reflection tinted by a reflectance, with no
//! Fresnel term (the same tint at every angle).

use super::surface::{Bsdf, Texels, lanes3};
use super::{BsdfSample, reflect};
use crate::math::{Real, V3};
use crate::scene::{Material, Model};
use wide::f32x8;

/// The mirror model ([`Model::Mirror`]).
pub struct Mirror;

/// Its parameter: the tint, the reflectance times the colour textures.
#[derive(Clone, Copy, Debug)]
pub struct Params<R: Real> {
    /// The reflectance per RGB channel.
    pub tint: V3<R>,
}

impl Bsdf for Mirror {
    const MODEL: Model = Model::Mirror;
    const DELTA: bool = true;
    type Params<R: Real> = Params<R>;

    #[inline]
    fn params(m: &Material, at: &impl Texels) -> Params<f32> {
        Params {
            tint: V3::from(m.reflectance * at.colour()),
        }
    }

    #[inline(always)]
    fn gather(table: &[Params<f32>], rows: &[usize; 8]) -> Params<f32x8> {
        Params {
            tint: lanes3(rows, |i| table[i].tint),
        }
    }

    #[inline(always)]
    fn sample<R: Real>(
        p: &Params<R>,
        (_, n): (R::Mask, V3<R>),
        wo: V3<R>,
        _u: [R; 2],
        _uniform: bool,
    ) -> BsdfSample<R> {
        sample(n, wo, p.tint)
    }
}

/// The mirror direction of `wo` about the normal `n` (either orientation:
/// [`reflect`] gives the same bits), a delta lobe: `f = tint`, `cos = 1`,
/// `pdf = 1`, so the throughput update is exactly `β · tint`.
#[inline(always)]
pub fn sample<R: Real>(n: V3<R>, wo: V3<R>, tint: V3<R>) -> BsdfSample<R> {
    let one = R::splat(1.0);
    BsdfSample {
        wi: reflect(wo, n),
        f: tint,
        cos: one,
        pdf: one,
        delta: R::splat_mask(true),
    }
}
