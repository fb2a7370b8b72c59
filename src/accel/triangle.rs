//! Ray/triangle intersection: Möller–Trumbore, written once for any [`Real`].
//!
//! The closest hit of a ray is the smallest `(t, triangle index)` pair, in
//! that order: ties in `t` (a ray through a shared edge) go to the lower
//! index. That makes the answer independent of the order triangles are
//! tested in, so every intersector — scalar brute force, 8-wide packs, a
//! hierarchy — returns the same triangle and the same `t`, bit for bit.

pub use crate::accel::hit::{Hit, LaneHits, NO_PRIM, PackHits};
use crate::accel::shape::{AreaEmitter, AreaShape, Shape, ShapePack};
use crate::accel::simd::Lanes;
use crate::math::{Real, V3};
use crate::scene::{Scene, Triangle};
use glam::{Vec3, Vec3A};
use wide::f32x8;

/// A triangle as the intersection kernel wants it: one vertex, two edges
/// and their cross product.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleEdges {
    /// Vertex 0.
    pub v0: Vec3,
    /// `v1 - v0`.
    pub e1: Vec3,
    /// `v2 - v0`.
    pub e2: Vec3,
    /// `e1 × e2` (not normalised; zero for a degenerate triangle).
    pub n: Vec3,
}

impl TriangleEdges {
    /// The triangle with vertices `v0`, `v1`, `v2`.
    pub fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        Self::from_edges(v0, v1 - v0, v2 - v0)
    }
}

impl TriangleEdges {
    /// Whether every coordinate is finite (a triangle with a box).
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.v0.is_finite() && self.e1.is_finite() && self.e2.is_finite()
    }

    /// The triangle with vertex `v0` and edges `e1 = v1 - v0`,
    /// `e2 = v2 - v0`.
    pub fn from_edges(v0: Vec3, e1: Vec3, e2: Vec3) -> Self {
        Self {
            v0,
            e1,
            e2,
            n: e1.cross(e2),
        }
    }
}

impl From<&Triangle> for TriangleEdges {
    fn from(t: &Triangle) -> Self {
        Self::new(t.v[0], t.v[1], t.v[2])
    }
}

/// Möller–Trumbore with the triangle's `n = e1 × e2` precomputed (as in
/// Embree): the distance `t` along the ray `o + t·d` at which it crosses
/// the triangle, and whether it is inside the triangle (edges included)
/// with `t > t_min`. The caller compares `t` with its own `t_max`.
///
/// With `c = v0 - o` and `w = c × d`, the paper's quantities are
/// `det = -(d · n)`, `u = (e2 · w) / (d · n)`, `v = -(e1 · w) / (d · n)` and
/// `t = (c · n) / (d · n)` — the scalar triple product identities turn the
/// paper's two cross products per test into one.
///
/// A ray parallel to the triangle's plane (`d · n = 0`), or a degenerate
/// triangle, makes `u`, `v` or `t` infinite or NaN, and every comparison
/// with NaN is false: such rays miss.
///
/// `v` is kept as its negation `nv = (e1 · w) / (d · n)` (rounding to
/// nearest is symmetric, so `-nv` is `(-(e1 · w)) / (d · n)` bit for bit):
/// `0 ≤ v` is `nv ≤ 0`, and `u + v` is `u - nv`, one negation fewer.
#[inline(always)]
pub fn moller_trumbore<R: Real>(o: V3<R>, d: V3<R>, tri: &V3Tri<R>, t_min: R) -> (R::Mask, R) {
    let c = tri.v0 - o;
    let w = c.cross(d);
    let inv_den = R::splat(1.0) / d.dot(tri.n);
    let u = tri.e2.dot(w) * inv_den;
    let nv = tri.e1.dot(w) * inv_den;
    let t = c.dot(tri.n) * inv_den;
    let zero = R::splat(0.0);
    let inside = zero.le(u) & nv.le(zero) & (u - nv).le(R::splat(1.0)) & t_min.lt(t);
    (inside, t)
}

/// One triangle (`R = f32`) or eight (`R = f32x8`) for [`moller_trumbore`].
#[derive(Clone, Copy, Debug)]
pub struct V3Tri<R> {
    /// Vertex 0.
    pub v0: V3<R>,
    /// `v1 - v0`.
    pub e1: V3<R>,
    /// `v2 - v0`.
    pub e2: V3<R>,
    /// `e1 × e2`.
    pub n: V3<R>,
}

impl From<&TriangleEdges> for V3Tri<f32> {
    fn from(t: &TriangleEdges) -> Self {
        Self {
            v0: t.v0.into(),
            e1: t.e1.into(),
            e2: t.e2.into(),
            n: t.n.into(),
        }
    }
}

/// Scalar brute force over all triangles: the plainest closest-hit query.
pub fn closest_hit_brute_force(
    tris: &[TriangleEdges],
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<Hit> {
    let (o, d) = (V3::from(o), V3::from(d));
    let mut best: Option<Hit> = None;
    for (i, tri) in tris.iter().enumerate() {
        let limit = best.map_or(t_max, |h| h.t);
        let (inside, t) = moller_trumbore(o, d, &V3Tri::from(tri), t_min);
        // Strictly closer only: on equal t the earlier (lower) index stays.
        if inside && t < limit {
            best = Some(Hit {
                triangle: i as u32,
                t,
            });
        }
    }
    best
}

/// The hit point `o + t·d`, computed the same way by every engine.
#[inline(always)]
pub fn hit_point<R: Real>(o: V3<R>, d: V3<R>, t: R) -> V3<R> {
    d.mul_add(t, o)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> TriangleEdges {
        let t = Triangle::ccw(
            [
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            0,
        );
        TriangleEdges::from(&t)
    }

    fn cast(t: &TriangleEdges, o: Vec3, d: Vec3) -> Option<f32> {
        closest_hit_brute_force(std::slice::from_ref(t), o, d, 1e-4, f32::INFINITY).map(|h| h.t)
    }

    #[test]
    fn hit_inside_returns_distance() {
        let t = cast(&tri(), Vec3::new(0.25, 0.25, 0.0), Vec3::Z);
        assert_eq!(t, Some(1.0));
    }

    #[test]
    fn miss_outside() {
        assert_eq!(cast(&tri(), Vec3::new(0.8, 0.8, 0.0), Vec3::Z), None);
        assert_eq!(cast(&tri(), Vec3::new(-0.1, 0.5, 0.0), Vec3::Z), None);
    }

    #[test]
    fn edges_and_vertices_count_as_hits() {
        for o in [
            Vec3::new(0.5, 0.0, 0.0), // edge v0-v1
            Vec3::new(0.0, 0.5, 0.0), // edge v0-v2
            Vec3::new(0.5, 0.5, 0.0), // hypotenuse
            Vec3::new(0.0, 0.0, 0.0), // vertex
        ] {
            assert_eq!(cast(&tri(), o, Vec3::Z), Some(1.0), "origin {o}");
        }
    }

    #[test]
    fn parallel_ray_misses() {
        // In the triangle's plane and parallel to it above the plane.
        assert_eq!(cast(&tri(), Vec3::new(-1.0, 0.25, 1.0), Vec3::X), None);
        assert_eq!(cast(&tri(), Vec3::new(-1.0, 0.25, 0.5), Vec3::X), None);
    }

    #[test]
    fn triangle_behind_origin_misses() {
        assert_eq!(cast(&tri(), Vec3::new(0.25, 0.25, 2.0), Vec3::Z), None);
    }

    #[test]
    fn both_windings_hit_from_both_sides() {
        let a = tri();
        let b = TriangleEdges::new(a.v0, a.v0 + a.e2, a.v0 + a.e1);
        for t in [a, b] {
            assert_eq!(cast(&t, Vec3::new(0.25, 0.25, 0.0), Vec3::Z), Some(1.0));
            assert_eq!(cast(&t, Vec3::new(0.25, 0.25, 2.0), -Vec3::Z), Some(1.0));
        }
    }

    #[test]
    fn degenerate_triangle_never_hits() {
        let t = TriangleEdges::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0);
        assert_eq!(cast(&t, Vec3::new(0.5, 0.0, -1.0), Vec3::Z), None);
    }

    #[test]
    fn shared_edge_tie_goes_to_lower_index() {
        let a = tri();
        // The mirror image across the hypotenuse shares the edge (1,0)-(0,1).
        let b = TriangleEdges::new(
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
        );
        let o = Vec3::new(0.5, 0.5, 0.0);
        let h = closest_hit_brute_force(&[a, b], o, Vec3::Z, 1e-4, f32::INFINITY).unwrap();
        assert_eq!(h.triangle, 0);
        let h = closest_hit_brute_force(&[b, a], o, Vec3::Z, 1e-4, f32::INFINITY).unwrap();
        assert_eq!(h.triangle, 0);
    }

    #[test]
    fn t_min_skips_the_surface_a_ray_starts_on() {
        let o = Vec3::new(0.25, 0.25, 1.0);
        assert_eq!(cast(&tri(), o, Vec3::Z), None);
        assert_eq!(cast(&tri(), o, -Vec3::Z), None);
    }
}

/// [`Lanes::LANES`] triangles (8 or 16) in structure-of-arrays form, tested
/// against one ray at once by [`TrianglePack::intersect`]. Unused lanes
/// hold an all-zero triangle (which no ray hits) with index `u32::MAX`.
#[derive(Clone, Copy, Debug)]
pub struct TrianglePack<R: Lanes> {
    /// The triangles, one per lane.
    pub tri: V3Tri<R>,
    /// Each lane's triangle index (`u32::MAX` for padding), as `i32` bits.
    pub index: R::Index,
}

/// Eight triangles in one pack: the 8-lane (AVX2) kernel's unit.
pub type Triangle8 = TrianglePack<f32x8>;

impl<R: Lanes> TrianglePack<R> {
    /// Pack up to [`Lanes::LANES`] triangles with their indices.
    pub fn pack(tris: &[(u32, TriangleEdges)]) -> Self {
        assert!(tris.len() <= R::LANES);
        // On the stack: a pack is made per leaf, and a `Vec` per field was
        // a tenth of a 100k-triangle build.
        let lane = |f: &dyn Fn(&TriangleEdges) -> f32| {
            let mut v = [0.0f32; 16];
            for (x, (_, t)) in v.iter_mut().zip(tris) {
                *x = f(t);
            }
            R::from_slice(&v[..tris.len()], 0.0)
        };
        let v3 = |g: &dyn Fn(&TriangleEdges) -> Vec3| {
            V3::new(lane(&|t| g(t).x), lane(&|t| g(t).y), lane(&|t| g(t).z))
        };
        let mut index = [0i32; 16];
        for (x, (i, _)) in index.iter_mut().zip(tris) {
            *x = *i as i32;
        }
        Self {
            tri: V3Tri {
                v0: v3(&|t| t.v0),
                e1: v3(&|t| t.e1),
                e2: v3(&|t| t.e2),
                n: v3(&|t| t.n),
            },
            index: R::index_from_slice(&index[..tris.len()], -1),
        }
    }

    /// Pack a whole triangle list, [`Lanes::LANES`] at a time, in index
    /// order.
    pub fn pack_all(tris: &[TriangleEdges]) -> Vec<Self> {
        let indexed: Vec<(u32, TriangleEdges)> = tris
            .iter()
            .enumerate()
            .map(|(i, t)| (i as u32, *t))
            .collect();
        indexed.chunks(R::LANES).map(Self::pack).collect()
    }

    /// Test one ray (broadcast to all lanes) against the pack's triangles,
    /// keeping in `best` each lane's smallest `(t, index)`.
    ///
    /// `IN_INDEX_ORDER` says the caller tests packs in increasing index
    /// order (a brute-force scan): then a lane's earlier hit always has the
    /// lower index, an equal `t` never wins, and the tie-break compares are
    /// skipped. Any other order (a hierarchy) must pass `false`.
    #[inline(always)]
    pub fn intersect<const IN_INDEX_ORDER: bool>(
        &self,
        o: &V3<R>,
        d: &V3<R>,
        t_min: R,
        best: &mut PackHits<R>,
    ) {
        let (inside, t) = moller_trumbore(*o, *d, &self.tri, t_min);
        best.keep::<IN_INDEX_ORDER>(inside, t, self.index);
    }

    /// Whether the ray hits one of the pack's triangles at a distance
    /// `t_min < t < t_max`: the same test, lane for lane, as
    /// [`TrianglePack::intersect`] with `best.t = t_max`.
    #[inline(always)]
    pub fn occludes(&self, o: &V3<R>, d: &V3<R>, t_min: R, t_max: R) -> bool {
        let (inside, t) = moller_trumbore(*o, *d, &self.tri, t_min);
        R::any(inside & t.lt(t_max))
    }
}

/// Closest hit of one ray against packed triangles, 8 lanes at a time, the
/// packs in increasing index order (as [`TrianglePack::pack_all`] makes
/// them). Returns the same triangle and the same `t` as
/// [`closest_hit_brute_force`], bit for bit.
pub fn closest_hit_packs(
    packs: &[Triangle8],
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<Hit> {
    let (o8, d8) = (V3::splat(o), V3::splat(d));
    let t_min8 = f32x8::splat(t_min);
    let mut best = LaneHits::new(t_max);
    for p in packs {
        p.intersect::<true>(&o8, &d8, t_min8, &mut best);
    }
    best.closest()
}

impl<R: Lanes> ShapePack<R> for TrianglePack<R> {
    #[inline(always)]
    fn intersect<const IN_INDEX_ORDER: bool>(
        &self,
        o: &V3<R>,
        d: &V3<R>,
        t_min: R,
        best: &mut PackHits<R>,
    ) {
        TrianglePack::intersect::<IN_INDEX_ORDER>(self, o, d, t_min, best)
    }

    #[inline(always)]
    fn occludes(&self, o: &V3<R>, d: &V3<R>, t_min: R, t_max: R) -> bool {
        TrianglePack::occludes(self, o, d, t_min, t_max)
    }
}

/// Triangles: the first kind (primitive `i` is triangle `i`).
impl Shape for TriangleEdges {
    type Pack<R: Lanes> = TrianglePack<R>;
    /// Its front unit normal (the scene's [`Triangle::normal`]).
    type Surface = Vec3;

    fn in_scene(scene: &Scene) -> Vec<Self> {
        scene.triangles.iter().map(TriangleEdges::from).collect()
    }

    fn materials(scene: &Scene) -> Vec<u32> {
        scene.triangles.iter().map(|t| t.material).collect()
    }

    #[inline]
    fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        if !self.is_finite() {
            return None;
        }
        let v0 = Vec3A::from(self.v0);
        let (v1, v2) = (v0 + Vec3A::from(self.e1), v0 + Vec3A::from(self.e2));
        Some((v0.min(v1).min(v2), v0.max(v1).max(v2)))
    }

    fn pack<R: Lanes>(shapes: &[(u32, Self)]) -> TrianglePack<R> {
        TrianglePack::pack(shapes)
    }

    #[inline(always)]
    fn intersect(&self, o: V3<f32>, d: V3<f32>, t_min: f32) -> (bool, f32) {
        moller_trumbore(o, d, &V3Tri::from(self), t_min)
    }

    fn surfaces(scene: &Scene) -> Vec<Vec3> {
        scene.triangles.iter().map(|t| t.normal).collect()
    }

    #[inline(always)]
    fn flat_normal(normal: &Vec3) -> Option<Vec3> {
        Some(*normal)
    }

    #[inline(always)]
    fn front_normal(normal: &Vec3, _o: V3<f32>, _d: V3<f32>, _t: f32) -> V3<f32> {
        V3::from(*normal)
    }

    fn count(scene: &Scene) -> usize {
        scene.triangles.len()
    }

    /// The emissive triangles of nonzero area, except that two emissive
    /// triangles of one material that share an edge and together form a
    /// parallelogram (a quad light made of two triangles, as the Cornell
    /// box's) are one emitter (unless their emission is textured: it is
    /// looked up at the point's own triangle); a parallelogram with square
    /// corners is a rectangle.
    fn emitters(scene: &Scene) -> Vec<AreaEmitter> {
        let emissive: Vec<usize> = (0..scene.triangles.len())
            .filter(|&i| {
                let t = &scene.triangles[i];
                let emission = scene.materials[t.material as usize].emission;
                let area = 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length();
                let power = area * emission.element_sum() / 3.0;
                power > 0.0 && power.is_finite()
            })
            .collect();
        let mut partner = parallelogram_partners(&scene.triangles, &emissive);
        // A textured emission is looked up at the point's triangle: such
        // triangles stay emitters of their own.
        for (k, &i) in emissive.iter().enumerate() {
            let m = scene.triangles[i].material as usize;
            if scene.materials[m].maps.emissive.is_some() {
                partner[k] = None;
            }
        }
        let mut out = Vec::new();
        for (k, &i) in emissive.iter().enumerate() {
            let t = &scene.triangles[i];
            let emission = scene.materials[t.material as usize].emission;
            let mut shape = AreaShape {
                v0: t.v[0].into(),
                e1: (t.v[1] - t.v[0]).into(),
                e2: (t.v[2] - t.v[0]).into(),
                normal: t.normal.into(),
                radius: 0.0,
                parallelogram: 0.0,
            };
            let mut area = 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length();
            let (mut second, mut rectangle) = (None, None);
            match partner[k] {
                // The later triangle of a pair: already in its emitter.
                Some((j, _)) if j < i => continue,
                Some((j, corner)) => {
                    // The corner opposite the shared edge, and the edges
                    // from it to the shared edge's ends.
                    let (x, p, q) = (t.v[corner], t.v[(corner + 1) % 3], t.v[(corner + 2) % 3]);
                    shape.v0 = x.into();
                    shape.e1 = (p - x).into();
                    shape.e2 = (q - x).into();
                    shape.parallelogram = 1.0;
                    area = (p - x).cross(q - x).length();
                    let (l1, l2) = ((p - x).length(), (q - x).length());
                    if (p - x).dot(q - x).abs() <= 1e-6 * l1 * l2 {
                        rectangle = Some(([(p - x) / l1, (q - x) / l2], [l1, l2]));
                    }
                    second = Some(j as u32);
                }
                None => {}
            }
            let power = area * emission.element_sum() / 3.0;
            out.push(AreaEmitter {
                shape,
                prims: [Some(i as u32), second],
                area: area as f64,
                power: power as f64,
                emission,
                rectangle,
            });
        }
        out
    }

    /// Uniform by area: on a triangle through [`square_to_triangle`], on a
    /// parallelogram the square mapped linearly; the normal is the
    /// emitter's.
    #[inline(always)]
    fn sample_area<R: Real>(e: &AreaShape<R>, u: [R; 2]) -> (V3<R>, V3<R>) {
        let [t1, t2] = square_to_triangle(u);
        let parallelogram = R::splat(0.0).lt(e.parallelogram);
        let (b1, b2) = (
            R::select(parallelogram, u[0], t1),
            R::select(parallelogram, u[1], t2),
        );
        (e.e1.mul_add(b1, e.e2.mul_add(b2, e.v0)), e.normal)
    }
}

/// Barycentric coordinates `(b1, b2)` (weights of vertices 1 and 2) of a
/// point uniform on a triangle, from a point of the unit square: Heitz's
/// low-distortion map ("A Low-Distortion Map Between Triangle and Square",
/// 2019), which keeps stratified points stratified.
#[inline(always)]
pub fn square_to_triangle<R: Real>([u0, u1]: [R; 2]) -> [R; 2] {
    let half = R::splat(0.5);
    let below = u0.lt(u1);
    let (h0, h1) = (u0 * half, u1 * half);
    let b0 = R::select(below, h0, u0 - h1);
    let b1 = R::select(below, u1 - h0, h1);
    // Weights of vertices 0, 1, 2 are (b0, b1, 1 - b0 - b1).
    [b1, R::splat(1.0) - b0 - b1]
}

/// For each of the triangles `emissive` (indices into `triangles`), the
/// emissive triangle it forms a parallelogram with, if any, and which of
/// its own corners lies opposite their shared edge. Two triangles pair
/// when they share an edge (the same two vertices, bit for bit), have the
/// same material and the same front side, and their corners opposite that
/// edge mirror each other through the edge's midpoint (`x + y = p + q`, to
/// within rounding): then their union is the parallelogram spanned from
/// either corner. A triangle pairs at most once, with the first partner in
/// index order; the result is a function of the scene only.
fn parallelogram_partners(
    triangles: &[crate::scene::Triangle],
    emissive: &[usize],
) -> Vec<Option<(usize, usize)>> {
    use std::collections::HashMap;
    type Key = ([u32; 3], [u32; 3]);
    let bits = |v: glam::Vec3| v.to_array().map(f32::to_bits);
    let edge_key = |a: glam::Vec3, b: glam::Vec3| -> Key {
        let (a, b) = (bits(a), bits(b));
        if a <= b { (a, b) } else { (b, a) }
    };
    let mut partner = vec![None; emissive.len()];
    // Unpaired triangles by edge: (position in `emissive`, opposite corner).
    let mut open: HashMap<Key, (usize, usize)> = HashMap::new();
    for (k, &i) in emissive.iter().enumerate() {
        let t = &triangles[i];
        for corner in 0..3 {
            let (x, p, q) = (t.v[corner], t.v[(corner + 1) % 3], t.v[(corner + 2) % 3]);
            let key = edge_key(p, q);
            let Some(&(m, other_corner)) = open.get(&key) else {
                continue;
            };
            if partner[m].is_some() {
                continue;
            }
            let s = &triangles[emissive[m]];
            let y = s.v[other_corner];
            let scale = [x, y, p, q]
                .iter()
                .map(|v| v.abs().max_element())
                .fold(0.0, f32::max);
            let mirrored = ((x + y) - (p + q)).abs().max_element() <= 4.0 * f32::EPSILON * scale;
            if s.material == t.material && s.normal.dot(t.normal) > 0.999_99 && mirrored {
                partner[m] = Some((i, other_corner));
                partner[k] = Some((emissive[m], corner));
                break;
            }
        }
        if partner[k].is_none() {
            for corner in 0..3 {
                let key = edge_key(t.v[(corner + 1) % 3], t.v[(corner + 2) % 3]);
                open.entry(key).or_insert((k, corner));
            }
        }
    }
    partner
}
