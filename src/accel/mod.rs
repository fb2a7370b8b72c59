//! Acceleration: which surface a ray hits first, built from the scene.
//!
//! - [`shape`]: the shape kinds behind one trait ([`shape::Shape`]: box,
//!   kernels, the surface at a hit, area sampling); the one list of the
//!   kinds there are is [`Kinds`], below;
//! - [`hit`]: the closest hit, as every kind's kernel keeps it;
//! - [`triangle`]: Möller–Trumbore, written once for scalar and SIMD
//!   code, and the 8- and 16-triangle packs (the first kind);
//! - [`sphere`]: robust ray/sphere intersection, scalar and 8 or 16
//!   spheres at once (the second kind);
//! - [`bvh`]: the 8-wide bounding volume hierarchy over the packs of
//!   every kind: closest hits and occlusion;
//! - [`simd`]: the SIMD width of the kernels (8 lanes, or 16 where the CPU
//!   has AVX-512), chosen at run time.

pub mod bvh;
pub mod hit;
pub mod shape;
pub mod simd;
pub mod sphere;
pub mod triangle;

use crate::scene::Scene;
use shape::{Shape, Shapes};
use sphere::Sphere;
use triangle::TriangleEdges;

// The shape kinds, in the order of their primitive indices: a kind's
// number, its field in a `Kinds`, and its type (`shape::Shape`).
shape::kinds!(0 triangles: TriangleEdges, 1 spheres: Sphere);

impl<'a> Shapes<'a> {
    /// Triangles and spheres, and no primitive of any other kind.
    pub fn triangles_and_spheres(triangles: &'a [TriangleEdges], spheres: &'a [Sphere]) -> Self {
        #[allow(clippy::needless_update, reason = "kinds added later are empty here")]
        Self {
            triangles,
            spheres,
            ..Self::default()
        }
    }
}

/// The scene's triangles as the intersection kernels want them, in index
/// order.
pub fn scene_triangles(scene: &Scene) -> Vec<TriangleEdges> {
    TriangleEdges::in_scene(scene)
}

/// The scene's spheres as the intersection kernels want them, in index
/// order.
pub fn scene_spheres(scene: &Scene) -> Vec<sphere::Sphere> {
    sphere::Sphere::in_scene(scene)
}

/// The hierarchy over the scene's primitives of every kind.
pub fn scene_bvh(scene: &Scene, options: &bvh::BvhOptions) -> bvh::Bvh {
    bvh::Bvh::build_shapes(&shape::OwnedShapes::of_scene(scene).as_shapes(), options)
}
