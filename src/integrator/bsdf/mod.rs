//! Scattering: one routine per material model, each written once over
//! [`Real`] so that the reference tracer (`f32`) and the wavefront engine
//! (`f32x8`) compute the very same bits.
//!
//! A sampling routine returns its direction together with its own weight
//! ([`BsdfSample`]): callers never rely on how a direction was drawn.
//!
//! The models: [`diffuse`] (Lambertian, two-sided), [`mirror`] (perfect
//! specular reflection), [`glass`] (smooth dielectric: Fresnel, Snell, total
//! internal reflection) and [`metal`] (rough conductor: GGX with
//! visible-normal sampling), [`metallic_roughness`] (glTF's Appendix B)
//! and [`transmission`] (glTF's `KHR_materials_transmission`: Appendix B
//! mixed with the rough or smooth, thin or solid dielectric interface of
//! [`dielectric`]). Each is a type implementing [`surface::Bsdf`] (its
//! parameters from a material, constant or textured, its sampling and
//! evaluation); [`surface`] holds the seam, and the list below makes
//! [`Surface`], the one dispatch on the model.
//!
//! Conventions shared by every model:
//!
//! - `wo` points away from the surface towards where the light goes (the
//!   negated ray direction); `wi`, the sampled or evaluated direction, also
//!   points away from the surface. Both are unit vectors, and so are normals.
//! - Each function says which normal it takes: the *facing* normal (turned
//!   towards `wo`, as [`facing`] returns it) or the geometric one.
//! - Directions for which a model has no value give `f = 0` from `eval` and
//!   `0` from `pdf`, never NaN.
//! - A [`BsdfSample`] with `delta` set comes from a specular (Dirac) lobe;
//!   see its documentation for how its factors are chosen.

pub mod dielectric;
pub mod diffuse;
pub mod glass;
pub mod metal;
pub mod metallic_roughness;
pub mod mirror;
pub mod surface;
pub mod transmission;

use crate::math::{Real, V3};

// The scattering models: a variant of `Model` and its type
// (`surface::Bsdf`).
surface::models!(
    Diffuse: diffuse::Diffuse,
    Mirror: mirror::Mirror,
    Glass: glass::Glass,
    Metal: metal::Metal,
    MetallicRoughness: metallic_roughness::MetallicRoughness,
    Transmission: transmission::Transmission,
);

/// A scattered direction and its weight `f · |cos θ| / pdf`, kept as its
/// three factors so that the throughput update is `β · f · cos / pdf`,
/// evaluated left to right the same way by every engine.
///
/// The contract, lane by lane:
///
/// - **Non-delta lobes** (`delta` false: [`diffuse`], [`metal`]): `f` is
///   the BSDF value for `(wo, wi)` (up to rounding, what
///   [`metal::eval`] returns, and what [`diffuse::eval`] returns before its
///   factor `cos θ`), `cos` is `|cos θ|` of `wi` with the normal, and `pdf`
///   is the solid-angle density `wi` was drawn with — the density to use
///   for multiple importance sampling (what [`metal::pdf`],
///   [`diffuse::pdf_cosine`] or [`diffuse::pdf_uniform`] returns).
/// - **Delta lobes** (`delta` true: [`mirror`], [`glass`]): the direction
///   has no density. The factors are chosen so that the weight is exact:
///   `f` is the whole weight (the tint, times any discrete-choice and
///   radiance-scaling factor that does not cancel), `cos = 1` and
///   `pdf = 1`, so `β · f · 1 / 1 = β · f` bit for bit. Next-event
///   estimation takes no shadow ray at such a surface, and a BSDF-sampled
///   hit on an emitter counts in full (MIS weight 1).
/// - **Absorbed samples** (a direction a lobe cannot produce, e.g. a GGX
///   reflection below the horizon): `f = 0`, `cos = 0`, `pdf = 1`, so the
///   weight is exactly zero and never NaN; the path may stop there.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample<R: Real> {
    /// The new direction, a unit vector away from the surface.
    pub wi: V3<R>,
    /// The BSDF's value for the pair of directions, per RGB channel (for a
    /// delta lobe: the sample's whole weight).
    pub f: V3<R>,
    /// `|cos θ|` of `wi` with the (facing) normal (for a delta lobe: 1).
    pub cos: R,
    /// The density `wi` was drawn with, per unit solid angle (for a delta
    /// lobe: 1).
    pub pdf: R,
    /// Whether the direction comes from a delta (specular) lobe.
    pub delta: R::Mask,
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

/// The shading normal to scatter with, turned towards the incoming ray:
/// the shading normal `shading` (on the geometric front side, as
/// [`Scene::shading_normal`](crate::scene::Scene::shading_normal) gives it)
/// turned to the side the ray arrived on by the *geometric* test
/// (`front`, from [`facing`]); where the outgoing direction `wo` lies
/// below that shading hemisphere (`wo · n_s ≤ 0`, possible at grazing
/// angles), the geometric facing normal `ng` instead. So `wo` is always
/// above the normal returned, and scattering never sees a back-facing
/// `wo`. For a flat surface (`shading` the geometric front normal) it
/// returns `ng`, bit for bit.
#[inline(always)]
pub fn shading_facing<R: Real>(front: R::Mask, ng: V3<R>, shading: V3<R>, wo: V3<R>) -> V3<R> {
    let ns = V3::select(front, shading, V3::new(-shading.x, -shading.y, -shading.z));
    V3::select(R::splat(0.0).lt(wo.dot(ns)), ns, ng)
}

/// Whether `wi` leaves on different sides of the surface by the shading
/// normal `ns` and by the geometric one `ng` (both facing the same way):
/// a reflection by the shading frame that would go through the geometry,
/// or a transmission that would not. Such directions are absorbed (light
/// must not leak through a surface by its shading normal). Never true for
/// a flat surface (`ns == ng`).
#[inline(always)]
pub fn leaks<R: Real>(ns: V3<R>, ng: V3<R>, wi: V3<R>) -> R::Mask {
    let zero = R::splat(0.0);
    let (s, g) = (ns.dot(wi), ng.dot(wi));
    (zero.lt(s) & g.le(zero)) | (s.le(zero) & zero.lt(g))
}

/// The mirror image of `w` about the normal `n`: `2 (w · n) n - w`, each
/// component one fused multiply-add. Either orientation of `n` gives the
/// same bits.
#[inline(always)]
pub fn reflect<R: Real>(w: V3<R>, n: V3<R>) -> V3<R> {
    let c2 = w.dot(n) * R::splat(2.0);
    n.mul_add(c2, -w)
}

/// Two unit tangents `(nt, nb)` that make an orthonormal frame with the unit
/// normal `n`: Scratchapixel's (the report's reference \[3\]), a tangent
/// `nt` orthogonal to `n` built from its two largest components, and
/// `nb = n × nt`.
#[inline(always)]
pub fn tangents<R: Real>(n: V3<R>) -> (V3<R>, V3<R>) {
    let zero = R::splat(0.0);
    let use_x = n.y.abs().lt(n.x.abs());
    // One length per lane, `|(x, z)|` or `|(y, z)|` as the lane chose
    // (one square root and one division, not one of each per choice).
    let inv = R::splat(1.0) / R::select(use_x, n.x * n.x + n.z * n.z, n.y * n.y + n.z * n.z).sqrt();
    let nt = V3::select(
        use_x,
        V3::new(n.z * inv, zero, -n.x * inv),
        V3::new(zero, -n.z * inv, n.y * inv),
    );
    let nb = n.cross(nt);
    (nt, nb)
}

/// The world direction with local coordinates `(lx, ly, lz)` in the frame
/// of [`tangents`]: `nb · lx + n · ly + nt · lz` (the normal is the local
/// y axis, as in the report's hemisphere sampling).
#[inline(always)]
pub fn local_to_world<R: Real>(n: V3<R>, (nt, nb): (V3<R>, V3<R>), lx: R, ly: R, lz: R) -> V3<R> {
    nb.mul_add(lx, n.mul_add(ly, nt.scale(lz)))
}
