//! Small scenes: a two-level split into occluders, tested first by every
//! ray, and a tree over the rest, whose boxes the occluders' hit culls.
//!
//! In a room like the Cornell box most rays end on a wall: the walls are
//! hit by nearly every ray, the objects inside by few. Testing every pack
//! for every ray (one leaf, no box) spends tests on objects the ray never
//! reaches; a plain SAH tree spends box tests on the walls, whose boxes
//! every ray enters. So a small scene is built a few ways and the cheapest
//! is kept:
//!
//! - the plain build (for a scene that fits in one leaf: that leaf, its
//!   packs tested in index order, no box);
//! - for `k = 1, 2, ...`: the `k·lanes` largest triangles (by area; full
//!   packs) as occluders, and a tree over the rest whose root is a node,
//!   so that a ray that hits an occluder skips every box behind that hit,
//!   with one or up to [`MAX_LEAF_PACKS`](super::MAX_LEAF_PACKS) packs per
//!   leaf.
//!
//! Bigger scenes (more than [`MAX_PRIMS`] primitives) are too big to be
//! built several ways; there the largest triangles go in front of the tree
//! by a rule ([`large_triangles`]): those whose box is at least
//! [`LARGE`] of the scene's (by surface area), at most
//! [`MAX_FIRST_PACKS`] packs of them. In `sphere-1m` those are the box's
//! 32 triangles, and a ray that misses the sphere then tests them and one
//! box (measured: the intersect stage 91 → 64 ns a ray at 16 lanes).
//!
//! "Cheapest" is counted, not timed, so the choice is the same on every
//! run: the mean of `nodes · cost_node + packs · cost_pack` over a fixed
//! set of rays like a path tracer's (from random points on the triangles,
//! in uniformly random directions). Every candidate answers every query
//! exactly (the occluders are one more set of packs whose hits join the
//! lanes' `(t, index)` minimum), so the choice never changes an image.

use super::build::Aabb;
use super::{BuildParams, Bvh, triangle_box};
use crate::accel::simd::SimdWidth;
use crate::accel::sphere::Sphere;
use crate::accel::triangle::TriangleEdges;
use glam::Vec3;
use rand_core::Rng;
use rand_pcg::Pcg32;
use rayon::prelude::*;

/// Scenes with at most this many primitives are built the ways above.
pub const MAX_PRIMS: usize = 256;

/// A big scene's triangle is large, and goes in front of the tree, when
/// its box has at least this share of the scene box's surface area.
pub const LARGE: f32 = 0.01;

/// Most packs of large triangles in front of a big scene's tree.
pub const MAX_FIRST_PACKS: usize = 4;

/// Rays the candidates are counted on.
const RAYS: usize = 2048;

/// Relative cost of one inner node (its box tests and the walk's
/// bookkeeping around them), against [`COST_PACK`] for one pack. Measured
/// on bounce-like rays in the Cornell box at 8 lanes (AMD Zen 4): one pack
/// and no node 10.8 ns a ray, four packs 32 ns (so about 7 ns a pack), a
/// tree of one node with 2.46 packs a ray 40 ns: a node costs what 2.7
/// packs do. (So the Cornell box itself stays one leaf: its four packs
/// cost less than one pack, a node and the 1.46 packs behind it.)
const COST_NODE: f64 = 2.7;
/// Relative cost of one pack's tests.
const COST_PACK: f64 = 1.0;

/// The cheapest of the candidate builds of a small scene.
pub(super) fn build(tris: &[TriangleEdges], spheres: &[Sphere], width: SimdWidth) -> Bvh {
    let rays = sample_rays(tris);
    let mut best: Option<(Bvh, f64)> = None;
    for bvh in candidates(tris, spheres, width) {
        if rays.is_empty() {
            // Nothing to count on: the plain build, the first candidate.
            return bvh;
        }
        let c = cost(&bvh, &rays);
        // Strictly cheaper only: ties keep the earlier, simpler build.
        if best.as_ref().is_none_or(|(_, b)| c < *b) {
            best = Some((bvh, c));
        }
    }
    best.expect("the plain build is a candidate").0
}

/// The candidate builds, the plain one first, then the two-level splits
/// with `k = 1, 2, ...` packs of occluders (as long as some triangles are
/// left for the tree), each with one-pack and with full leaves.
fn candidates<'a>(
    tris: &'a [TriangleEdges],
    spheres: &'a [Sphere],
    width: SimdWidth,
) -> impl Iterator<Item = Bvh> + 'a {
    let lanes = width.lanes();
    let plain = BuildParams::for_lanes(lanes);
    let order = by_area(tris);
    let n = order.len();
    let split = (1..)
        .take_while(move |k| k * lanes < n)
        .flat_map(move |k| {
            let mut first = order[..k * lanes].to_vec();
            first.sort_unstable();
            [1, plain.max_leaf_packs].map(move |leaf_packs| (first.clone(), leaf_packs))
        })
        .map(move |(first, leaf_packs)| {
            let params = BuildParams {
                max_leaf_packs: leaf_packs,
                root_node: true,
                ..plain
            };
            Bvh::assemble(tris, spheres, &first, width, &params)
        });
    std::iter::once_with(move || Bvh::assemble(tris, spheres, &[], width, &plain)).chain(split)
}

/// The large triangles of a big scene (see [`LARGE`]), at most
/// [`MAX_FIRST_PACKS`] packs of `lanes` of them (the largest), by
/// increasing index; none when no triangle is that large.
pub(super) fn large_triangles(tris: &[TriangleEdges], lanes: usize) -> Vec<u32> {
    let scene = tris
        .par_iter()
        .filter(|t| t.is_finite())
        .map(triangle_box)
        .reduce(
            || Aabb::EMPTY,
            |mut a, b| {
                a.grow(&b);
                a
            },
        );
    let limit = LARGE * scene.half_area();
    let mut large: Vec<(f32, u32)> = tris
        .par_iter()
        .enumerate()
        .filter(|(_, t)| t.is_finite())
        .map(|(i, t)| (triangle_box(t).half_area(), i as u32))
        .filter(|&(a, _)| a >= limit && a > 0.0)
        .collect();
    large.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    large.truncate(MAX_FIRST_PACKS * lanes);
    let mut first: Vec<u32> = large.into_iter().map(|(_, i)| i).collect();
    first.sort_unstable();
    first
}

/// The finite triangles, largest first (ties by index).
fn by_area(tris: &[TriangleEdges]) -> Vec<u32> {
    let mut order: Vec<u32> = (0..tris.len() as u32)
        .filter(|&i| tris[i as usize].is_finite())
        .collect();
    order.sort_by(|&a, &b| {
        let area = |i: u32| tris[i as usize].n.length();
        area(b).total_cmp(&area(a)).then(a.cmp(&b))
    });
    order
}

/// The mean counted cost of a closest-hit query over `rays`.
fn cost(bvh: &Bvh, rays: &[(Vec3, Vec3, f32)]) -> f64 {
    let total: f64 = rays
        .iter()
        .map(|&(o, d, t_min)| {
            let s = bvh.walk_stats(o, d, t_min, f32::INFINITY, false);
            s.nodes as f64 * COST_NODE + s.packs as f64 * COST_PACK
        })
        .sum();
    total / rays.len() as f64
}

/// Rays from points on the triangles (chosen by area) in uniformly random
/// directions, with a `t_min` of `1e-4` of the scene's size: a path
/// tracer's bounce rays. None when the triangles have no finite area.
fn sample_rays(tris: &[TriangleEdges]) -> Vec<(Vec3, Vec3, f32)> {
    let finite: Vec<&TriangleEdges> = tris
        .iter()
        .filter(|t| t.is_finite() && t.n.length() > 0.0)
        .collect();
    let mut cdf = Vec::with_capacity(finite.len());
    let mut total = 0.0f64;
    let mut extent = 0.0f32;
    for t in &finite {
        total += 0.5 * t.n.length() as f64;
        cdf.push(total);
        extent = extent.max(t.v0.abs().max_element());
    }
    if !(total > 0.0 && total.is_finite()) {
        return Vec::new();
    }
    let mut rng = Pcg32::new(0x5eed_0f0c_c10d_e5ed, 7);
    let mut u = move || (rng.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0);
    (0..RAYS)
        .map(|_| {
            let x = u() as f64 * total;
            let i = cdf.partition_point(|&c| c <= x).min(finite.len() - 1);
            let t = finite[i];
            let (mut a, mut b) = (u(), u());
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            let o = t.v0 + a * t.e1 + b * t.e2;
            let z = 1.0 - 2.0 * u();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = std::f32::consts::TAU * u();
            let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            (o, d, 1e-4 * extent.max(f32::MIN_POSITIVE))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::sphere::closest_hit_brute_force_prims;
    use crate::scene::Scene;

    fn widths() -> Vec<SimdWidth> {
        [SimdWidth::W8, SimdWidth::W16]
            .into_iter()
            .filter(|w| w.is_available())
            .collect()
    }

    fn scene(name: &str) -> (Vec<TriangleEdges>, Vec<Sphere>) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(name);
        let s = Scene::load(&path).expect("a shipped scene loads");
        let spheres = s.spheres.iter().map(|p| Sphere::new(p.center, p.radius));
        (
            s.triangles.iter().map(TriangleEdges::from).collect(),
            spheres.collect(),
        )
    }

    /// Every candidate of every small shipped scene answers closest-hit
    /// and occlusion queries exactly as brute force does, on rays from the
    /// surfaces (the counted ones, nearly tangent ones included) and from
    /// inside the scene's box, with random segment ends.
    #[test]
    fn every_candidate_equals_brute_force() {
        let scenes = [
            (
                Scene::cornell()
                    .triangles
                    .iter()
                    .map(TriangleEdges::from)
                    .collect(),
                Vec::new(),
            ),
            scene("scenes/cornell-obj.toml"),
            scene("scenes/cornell-spheres.toml"),
            scene("scenes/cornell-materials.toml"),
        ];
        let mut rng = Pcg32::new(42, 54);
        let mut u = move || (rng.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0);
        let (mut built, mut checked, mut split) = (0, 0, 0);
        for (tris, spheres) in &scenes {
            let mut rays = sample_rays(tris);
            for _ in 0..2048 {
                let o = Vec3::new(2.2 * u() - 1.1, 2.2 * u() - 1.1, 4.0 * u() - 3.0);
                let d = Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5).normalize_or(Vec3::Z);
                rays.push((o, d, 1e-4));
            }
            for width in widths() {
                for bvh in candidates(tris, spheres, width) {
                    built += 1;
                    split += usize::from(bvh.first_pack_count() > 0);
                    for &(o, d, t_min) in &rays {
                        let want = closest_hit_brute_force_prims(
                            tris,
                            spheres,
                            o,
                            d,
                            t_min,
                            f32::INFINITY,
                        );
                        let got = bvh.closest_hit(o, d, t_min, f32::INFINITY);
                        assert_eq!(
                            got.map(|h| (h.triangle, h.t.to_bits())),
                            want.map(|h| (h.triangle, h.t.to_bits())),
                            "closest hit of {o} {d}, {} lanes",
                            width.lanes()
                        );
                        let end = 3.0 * u();
                        assert_eq!(
                            bvh.occluded(o, d, t_min, end),
                            want.is_some_and(|h| h.t < end),
                            "occlusion of {o} {d} to {end}"
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert!(split > built / 2, "{split} of {built} builds are two-level");
        assert!(checked > 100_000, "{checked}");
    }

    /// The chooser keeps the plain single leaf for the Cornell box (four
    /// packs cost less than a node in front of fewer) and takes a
    /// two-level split where one pays: the Cornell box around an OBJ crate
    /// at 8 lanes (measured 49 → 41 ns a ray).
    #[test]
    fn chooser_picks_by_counted_cost() {
        let cornell: Vec<TriangleEdges> = Scene::cornell()
            .triangles
            .iter()
            .map(TriangleEdges::from)
            .collect();
        let bvh = build(&cornell, &[], SimdWidth::W8);
        assert_eq!((bvh.node_count(), bvh.first_pack_count()), (0, 0));
        let (tris, spheres) = scene("scenes/cornell-obj.toml");
        let bvh = build(&tris, &spheres, SimdWidth::W8);
        assert!(bvh.first_pack_count() > 0, "the crate's room is split off");
        assert_eq!(bvh.node_count(), 1);
        // The choice is the cheapest by count, and the same every time.
        let rays = sample_rays(&tris);
        let min = candidates(&tris, &spheres, SimdWidth::W8)
            .map(|b| cost(&b, &rays))
            .fold(f64::INFINITY, f64::min);
        assert_eq!(cost(&bvh, &rays), min);
        assert_eq!(sample_rays(&tris), rays);
    }
}
