//! The surface a ray hit, computed once per hit: where it is, its normals
//! and which side the ray arrived on, its texture coordinates, primitive
//! and material. Every consumer of a hit — emission, AOVs, light sampling,
//! scattering, in both engines — reads this record instead of rebuilding it
//! from `(prim, t)`. Each shape kind gives its own part (its front normal
//! and, for smooth triangles, its shading normal at the point:
//! [`Tables::surface`](super::tables::Tables::surface) for one lane,
//! [`Tables::surface_8`](super::tables::Tables::surface_8) for eight);
//! [`SurfaceHit::new`] does the rest, the same for every kind; the
//! texture coordinates come from the shape too, where the scene has them.

use super::bsdf::{facing, shading_facing};
use super::offset::error_bound;
use crate::accel::triangle::hit_point;
use crate::math::{Real, V3};

/// The surface at a hit, lane by lane.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit<R: Real> {
    /// The hit point `o + t·d`.
    pub p: V3<R>,
    /// A bound on how far `p` lies from the surface ([`error_bound`]): rays
    /// leave from `p` moved this far off it
    /// ([`spawn`](super::offset::spawn)).
    pub err: R,
    /// The geometric unit normal on the shape's front (outward) side.
    pub ng: V3<R>,
    /// Whether the ray arrived on the front side (emitters emit there).
    pub front: R::Mask,
    /// The geometric normal turned towards the ray ([`facing`]).
    pub n: V3<R>,
    /// The shading normal to scatter with, turned towards the ray
    /// ([`shading_facing`]): a smooth triangle's interpolated vertex
    /// normals; `n` itself, bit for bit, on flat surfaces.
    pub ns: V3<R>,
    /// Texture coordinates at the hit, sets 0 and 1 (glTF's `TEXCOORD_0`
    /// and `TEXCOORD_1`): a triangle's vertex coordinates interpolated at
    /// the hit ([`Scene::texcoords`](crate::scene::Scene::texcoords));
    /// zero on spheres, on triangles without any, and in scenes without
    /// any.
    pub uv: [[R; 2]; 2],
    /// The primitive hit, numbered as the hierarchy numbers hits.
    pub prim: R::Id,
    /// The primitive's material.
    pub material: R::Id,
}

impl<R: Real> SurfaceHit<R> {
    /// The surface where the ray `(o, d)` hits a shape at distance `t`,
    /// from what the shape gives there: its front geometric normal `ng`,
    /// its [`Scene::primitive_scale`](crate::scene::Scene::primitive_scale)
    /// `scale`, and, where any surface of the scene is smooth, its front
    /// shading normal `shading` (`ng` itself where the shape is flat;
    /// `None`: no shape of the scene is smooth, and `ns` is `n`).
    #[inline(always)]
    pub fn new(
        (o, d): (V3<R>, V3<R>),
        t: R,
        (prim, material): (R::Id, R::Id),
        (ng, scale): (V3<R>, R),
        shading: Option<V3<R>>,
    ) -> Self {
        let (front, n) = facing(ng, d);
        let ns = match shading {
            Some(s) => shading_facing(front, n, s, -d),
            None => n,
        };
        let zero = R::splat(0.0);
        let p = hit_point(o, d, t);
        Self {
            p,
            err: error_bound(o, p, scale),
            ng,
            front,
            n,
            ns,
            uv: [[zero, zero], [zero, zero]],
            prim,
            material,
        }
    }
}
