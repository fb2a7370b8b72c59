//! Acceleration: which surface a ray hits first, built from the scene.
//!
//! - [`triangle`]: Möller–Trumbore, written once for scalar and 8-wide
//!   code, and the 8-triangle packs;
//! - [`bvh`]: the 8-wide bounding volume hierarchy over the packs;
//! - [`sphere`]: robust ray/sphere intersection, scalar and 8 spheres at
//!   once (not yet in the hierarchy).

pub mod bvh;
pub mod sphere;
pub mod triangle;

use crate::scene::Scene;
use triangle::TriangleEdges;

/// The scene's triangles as the intersection kernels want them, in index
/// order.
pub fn scene_triangles(scene: &Scene) -> Vec<TriangleEdges> {
    scene.triangles.iter().map(TriangleEdges::from).collect()
}
