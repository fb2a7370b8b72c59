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

/// Instancing pays where the placed meshes' triangles, counted per
/// placement, are at least this many times their unique triangles…
pub const INSTANCING_RATIO: usize = 2;

/// …and at least this many (smaller scenes are traced flattened, as
/// they always were).
pub const INSTANCING_MIN_TRIANGLES: usize = 1 << 16;

/// Whether [`scene_bvh`] traces `scene` two-level (instancing): its
/// meshes placed more than once ([`Scene::instancing`]) hold, counted per
/// placement, at least [`INSTANCING_MIN_TRIANGLES`] triangles and at
/// least [`INSTANCING_RATIO`] times their unique triangles.
pub fn instancing_pays(scene: &Scene) -> bool {
    let placed = scene.instancing.placed_triangles();
    placed >= INSTANCING_MIN_TRIANGLES
        && placed >= INSTANCING_RATIO * scene.instancing.unique_triangles()
}

/// The hierarchy over the scene's primitives of every kind: two-level
/// where [`instancing_pays`] (the same primitive indices, and the same
/// hits up to the rounding of the placements' transforms), else one tree
/// over the flattened primitives.
pub fn scene_bvh(scene: &Scene, options: &bvh::BvhOptions) -> bvh::Bvh {
    if instancing_pays(scene)
        && let Some(bvh) = two_level_bvh(scene, options)
    {
        return bvh;
    }
    bvh::Bvh::build_shapes(&shape::OwnedShapes::of_scene(scene).as_shapes(), options)
}

/// The two-level hierarchy of `scene` (whatever [`instancing_pays`]
/// says): its placed meshes ([`Scene::instancing`]) once each, and the
/// rest of its primitives in world space. `None` where it cannot be built
/// (see [`bvh::Bvh::build_two_level`]).
pub fn two_level_bvh(scene: &Scene, options: &bvh::BvhOptions) -> Option<bvh::Bvh> {
    let inst = &scene.instancing;
    // The flattened triangles some placement's tree names.
    let mut placed = vec![false; scene.triangles.len()];
    for p in &inst.instances {
        let n = inst.meshes[p.mesh as usize].len() as u32;
        for g in (0..n).filter_map(|j| p.global(j)) {
            *placed.get_mut(g as usize)? = true;
        }
    }
    let meshes = (inst.meshes.iter())
        .map(|m| {
            (m.iter())
                .map(|v| TriangleEdges::new(v[0], v[1], v[2]))
                .collect()
        })
        .collect();
    let instances = (inst.instances.iter())
        .map(|p| bvh::Placed {
            mesh: p.mesh,
            to_world: p.to_world,
            first: p.first,
            remap: &p.remap,
        })
        .collect();
    // The rest: the triangles of no placement, then every other kind's
    // primitives (global indices from the triangle count on, in order).
    let owned = shape::OwnedShapes::of_scene(scene);
    let all = owned.as_shapes();
    let rest_ids: Vec<u32> = (0..all.triangles.len() as u32)
        .filter(|&i| !placed[i as usize])
        .chain(all.triangles.len() as u32..all.len() as u32)
        .collect();
    let rest_tris: Vec<TriangleEdges> = (all.triangles.iter().zip(&placed))
        .filter(|(_, p)| !**p)
        .map(|(t, _)| *t)
        .collect();
    let rest = Shapes {
        triangles: &rest_tris,
        ..all
    };
    let placements = bvh::Placements {
        meshes,
        instances,
        rest: (!rest_ids.is_empty()).then_some((rest, rest_ids)),
    };
    bvh::Bvh::build_two_level(&placements, all.counts(), options)
}
