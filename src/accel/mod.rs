//! Acceleration: which surface a ray hits first, built from the scene.
//!
//! - [`triangle`]: Möller–Trumbore, written once for scalar and SIMD
//!   code, and the 8- and 16-triangle packs;
//! - [`bvh`]: the 8-wide bounding volume hierarchy over the packs:
//!   closest hits and occlusion;
//! - [`simd`]: the SIMD width of the kernels (8 lanes, or 16 where the CPU
//!   has AVX-512), chosen at run time;
//! - [`sphere`]: robust ray/sphere intersection, scalar and 8 or 16
//!   spheres at once (the hierarchy's second primitive kind), and the
//!   brute-force closest hit over triangles and spheres.

pub mod bvh;
pub mod simd;
pub mod sphere;
pub mod triangle;

use crate::scene::Scene;
use triangle::TriangleEdges;

/// The scene's triangles as the intersection kernels want them, in index
/// order.
pub fn scene_triangles(scene: &Scene) -> Vec<TriangleEdges> {
    scene.triangles.iter().map(TriangleEdges::from).collect()
}
