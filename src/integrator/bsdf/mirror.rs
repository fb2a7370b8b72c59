//! The perfect mirror: specular reflection tinted by a reflectance, with no
//! Fresnel term (the same tint at every angle).

use super::{BsdfSample, reflect};
use crate::math::{Real, V3};

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
