//! Sun, point and spot lights ([`crate::scene::punctual`]) as the
//! integrators see them.
//!
//! - A **sun** of angular diameter `α > 0` is a cone of directions of
//!   half-angle `δ = α/2` and solid angle `Ω = 2π (1 − cos δ)`, of uniform
//!   radiance `L = E / (π sin² δ)` (`E` its irradiance): a ray that leaves
//!   the scene within it sees `L`, in every integrator. `nee` draws a
//!   direction uniformly in the cone (`cos θ = 1 − u₀ (1 − cos δ)`,
//!   azimuth `2π u₁`), of density `P(sun) / Ω`, weighted against BSDF
//!   sampling by the power heuristic; an escaping BSDF-sampled ray in the
//!   cone is weighted against the same density.
//! - A sun of diameter 0, a **point** and a **spot** light are delta
//!   lights: `nee` alone reaches them, with weight 1 (no other strategy
//!   can find them). A point light of intensity `I` gives `I / r²` at
//!   distance `r` (times `cos θ` at the surface); a spot light
//!   `I · falloff / r²`, with glTF's falloff
//!   ([`crate::scene::punctual::spot_falloff`]); a delta
//!   sun its irradiance `E`.
//!
//! Each is picked against the scene's other emitters by power, in the
//! units of [`super::lights`] (`area × mean radiance`, the power over
//! `π`): a point light's `4π Ī / π = 4 Ī`, a spot light's
//! `2 (1 − cos θ_outer) Ī` (its cone of the outer angle at full intensity,
//! over `π`), a sun's `Ē r²` (`r` the radius of the scene's bounding
//! sphere: the power `π r² Ē` it sends through the sphere, over `π`); `Ī`
//! and `Ē` are the means of the RGB strengths.
//!
//! Every function is scalar: both engines call the same ones, lane by
//! lane, so they compute the same bits.

use crate::math::{V3, sin_cos_2pi};
use crate::scene::punctual::{LightShape, PunctualLight, spot_falloff};
use glam::Vec3;

/// A point drawn from a sun, point or spot light for a shading point, as
/// next-event estimation uses it (`crate::integrator::lights` makes its
/// light sample of it).
#[derive(Clone, Copy, Debug)]
pub struct PunctualSample {
    /// The point the shadow ray goes to.
    pub point: V3<f32>,
    /// Its normal, facing the shading point (zero where no light leaves
    /// towards it).
    pub normal: V3<f32>,
    /// The radiance arriving (a sun with a cone), or the irradiance at
    /// normal incidence (a delta light: `E`, or `I · falloff / r²`).
    pub emission: V3<f32>,
    /// The density: per unit solid angle for a sun with a cone, else the
    /// probability that the light was picked.
    pub pdf: f32,
    /// Whether it is a delta light.
    pub delta: bool,
}

/// What a [`Punctual`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Sun,
    Point,
    Spot,
}

/// A sun, point or spot light, ready to be sampled.
#[derive(Clone, Debug)]
pub struct Punctual {
    kind: Kind,
    /// Where a point or spot light is.
    position: V3<f32>,
    /// Unit: towards the sun (a sun), the spot's axis (a spot).
    axis: V3<f32>,
    /// Two unit vectors that make a right-handed frame with `axis`.
    tangents: [V3<f32>; 2],
    /// A sun's irradiance, a point or spot light's intensity.
    strength: V3<f32>,
    /// A sun's radiance within its cone, `E / (π sin² δ)` (0 for a delta
    /// sun).
    radiance: V3<f32>,
    /// A sun's `1 − cos δ` (0: a delta sun).
    one_minus_cos: f32,
    /// A spot's falloff: `clamp(cd · scale + offset, 0, 1)²`.
    falloff: (f32, f32),
    /// The density of what [`Punctual::sample`] draws: `P(light) / Ω` per
    /// unit solid angle for a sun with a cone, else `P(light)` (a delta).
    pdf: f32,
    /// Its power against the other emitters (see the module
    /// documentation).
    pub power: f64,
}

impl Punctual {
    /// The light `l` of a scene whose bounding sphere has radius `r`;
    /// `None` when it sends no light.
    pub fn new(l: &PunctualLight, r: f64) -> Option<Self> {
        let mean = f64::from(l.strength.element_sum()) / 3.0;
        if !(mean > 0.0 && mean.is_finite()) {
            return None;
        }
        let frame = |axis: Vec3| {
            let (t, b) = axis.any_orthonormal_pair();
            [V3::from(t), V3::from(b)]
        };
        let mut p = Self {
            kind: Kind::Point,
            position: V3::from(Vec3::ZERO),
            axis: V3::from(Vec3::Y),
            tangents: frame(Vec3::Y),
            strength: V3::from(l.strength),
            radiance: V3::from(Vec3::ZERO),
            one_minus_cos: 0.0,
            falloff: (0.0, 0.0),
            pdf: 0.0,
            power: 4.0 * mean,
        };
        match l.shape {
            LightShape::Sun { direction, angle } => {
                let half = f64::from(angle) / 2.0;
                let sin_half = half.sin();
                p.kind = Kind::Sun;
                p.axis = V3::from(-direction);
                p.tangents = frame(-direction);
                p.power = mean * r * r;
                if half > 0.0 {
                    // 1 − cos δ = 2 sin²(δ/2), without cancellation.
                    p.one_minus_cos = (2.0 * (half / 2.0).sin().powi(2)) as f32;
                    let scale = 1.0 / (std::f64::consts::PI * sin_half * sin_half);
                    p.radiance = V3::from(l.strength * scale as f32);
                }
            }
            LightShape::Point { position } => p.position = V3::from(position),
            LightShape::Spot {
                position,
                direction,
                inner,
                outer,
            } => {
                p.kind = Kind::Spot;
                p.position = V3::from(position);
                p.axis = V3::from(direction);
                p.falloff = spot_falloff(inner, outer);
                p.power = 2.0 * (1.0 - f64::from(outer).cos()) * mean;
            }
        }
        (p.power > 0.0 && p.power.is_finite()).then_some(p)
    }

    /// Set the probability `probability` that it is picked.
    pub fn set_probability(&mut self, probability: f32) {
        self.pdf = if self.one_minus_cos > 0.0 {
            probability / (std::f32::consts::TAU * self.one_minus_cos)
        } else {
            probability
        };
    }

    /// Whether it is a sun with a cone, which rays that leave the scene
    /// can see.
    pub fn is_visible_sun(&self) -> bool {
        self.kind == Kind::Sun && self.one_minus_cos > 0.0
    }

    /// A sun's radiance in the direction `d` (unit) of a ray that left
    /// the scene, and the density with which [`Punctual::sample`] draws
    /// it: `None` outside its cone (`|d − axis|² > 2 (1 − cos δ)`), and
    /// for every other light.
    #[inline]
    pub fn seen(&self, d: V3<f32>) -> Option<(V3<f32>, f32)> {
        if !self.is_visible_sun() {
            return None;
        }
        let off = d - self.axis;
        (off.dot(off) <= 2.0 * self.one_minus_cos).then_some((self.radiance, self.pdf))
    }

    /// The light sample for the shading point `o` and the numbers `u`: a
    /// sun's direction becomes a point `far` away facing back, as an
    /// environment's; a point or spot light's point is its position,
    /// facing `o` (a spot's back to `o` where its falloff is 0, so no
    /// shadow ray is cast).
    #[inline]
    pub fn sample(&self, o: V3<f32>, u: [f32; 2], far: f32) -> PunctualSample {
        let zero = V3::from(Vec3::ZERO);
        if self.kind == Kind::Sun {
            let (dir, emission, delta) = if self.one_minus_cos > 0.0 {
                let h = u[0] * self.one_minus_cos;
                let cos = 1.0 - h;
                let sin = (h * (2.0 - h)).max(0.0).sqrt();
                let (s, c) = sin_cos_2pi(u[1]);
                let [t, b] = self.tangents;
                let dir = self.axis.scale(cos) + t.scale(sin * c) + b.scale(sin * s);
                (dir, self.radiance, false)
            } else {
                (self.axis, self.strength, true)
            };
            return PunctualSample {
                point: dir.mul_add(far, o),
                normal: -dir,
                emission,
                pdf: self.pdf,
                delta,
            };
        }
        let to = self.position - o;
        let r2 = to.dot(to);
        let dir = to.scale(1.0 / r2.sqrt());
        let mut i = self.strength;
        let mut normal = -dir;
        if self.kind == Kind::Spot {
            let cd = -self.axis.dot(dir);
            let a = cd.mul_add(self.falloff.0, self.falloff.1).clamp(0.0, 1.0);
            i = i.scale(a * a);
            if a <= 0.0 {
                normal = zero;
            }
        }
        PunctualSample {
            point: self.position,
            normal,
            emission: i.scale(1.0 / r2),
            pdf: self.pdf,
            delta: true,
        }
    }
}
