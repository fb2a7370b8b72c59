//! Scattering: one routine per material model, each written once over
//! [`Real`] so that the reference tracer (`f32`) and the wavefront engine
//! (`f32x8`) compute the very same bits.
//!
//! A sampling routine returns its direction together with its own weight
//! ([`BsdfSample`]): callers never rely on how a direction was drawn.

pub mod diffuse;

use crate::math::{Real, V3};

/// A scattered direction and its weight `f · |cos θ| / pdf`, kept as its
/// three factors so that the throughput update is `β · f · cos / pdf`,
/// evaluated left to right the same way by every engine.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample<R> {
    /// The new direction, a unit vector away from the surface.
    pub wi: V3<R>,
    /// The BSDF's value for the pair of directions, per RGB channel.
    pub f: V3<R>,
    /// `|cos θ|` of `wi` with the (facing) normal.
    pub cos: R,
    /// The density `wi` was drawn with, per unit solid angle.
    pub pdf: R,
}

impl<R: Real> BsdfSample<R> {
    /// The throughput `beta` (RGB) after this bounce: `β · f · cos / pdf`.
    #[inline(always)]
    pub fn weigh(&self, beta: V3<R>) -> V3<R> {
        V3::new(
            beta.x * self.f.x * self.cos / self.pdf,
            beta.y * self.f.y * self.cos / self.pdf,
            beta.z * self.f.z * self.cos / self.pdf,
        )
    }
}

/// The side of a surface that a ray of direction `d` arrives on: whether
/// it is the front (the side the geometric `normal` points to), and the
/// normal turned towards the ray (`-d`).
#[inline(always)]
pub fn facing<R: Real>(normal: V3<R>, d: V3<R>) -> (R::Mask, V3<R>) {
    let front = d.dot(normal).lt(R::splat(0.0));
    let n = V3::select(front, normal, V3::new(-normal.x, -normal.y, -normal.z));
    (front, n)
}
