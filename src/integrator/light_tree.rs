//! A light BVH: many emitters picked by their importance at the shading
//! point — Conty Estevez and Kulla, "Importance Sampling of Many Lights
//! with Adaptive Tree Splitting" (HPG 2018), as pbrt-v4's
//! `BVHLightSampler` builds and walks it.
//!
//! Each node bounds its emitters by a [`LightBounds`]: a box, their total
//! power `φ`, and a cone of the directions they emit in — their normals
//! lie within `θ_o` of the axis `w`, and each emits up to `θ_e` past its
//! normal (`π/2` for a one-sided surface; a sphere's normals fill the
//! sphere, `θ_o = π`). Its [`importance`](LightBounds::importance) at a
//! point `p` bounds what the node's emitters could send to `p`:
//!
//! ```text
//! I(p) = φ · cos θ' / d²,   θ' = max(0, θ_w − θ_o − θ_b),   0 where θ' ≥ θ_e
//! ```
//!
//! with `d` the distance from `p` to the box's centre (at least the radius
//! of the box's bounding sphere), `θ_w` the angle between `w` and the
//! direction from the centre to `p`, and `θ_b` the half-angle of the
//! bounding sphere seen from `p` (π inside it). A node whose emitters all
//! face away from `p` has importance 0: none of them can light it.
//!
//! A walk from the root picks, at each inner node, one child with
//! probability proportional to its importance, and stretches the one
//! number it was given back over `[0, 1)` (as the power running sums do),
//! so that a pick consumes the same single number. The probability of an
//! emitter is the product of the choices on its way from the root; each
//! emitter keeps its way as a trail of bits (bit `d` set: the second child
//! at depth `d`), so [`LightTree::pmf`] walks straight down to it, computing
//! the very same products — the density a BSDF-sampled ray that hits the
//! emitter is weighed against is the sample's, bit for bit.
//!
//! The tree is built by pbrt-v4's rule: each node splits its emitters at
//! the bucket boundary (12 buckets of box centroids per axis) that
//! minimises the sum over the two sides of `φ · M_Ω · area(box) · K_r`
//! (`M_Ω` the cone's orientation measure, `K_r` the box's longest extent
//! over its extent along the axis), down to one emitter per leaf.

use glam::{DVec3, Vec3};

/// The light tree is used where a scene has more than this many emitters
/// (triangles, parallelograms, spheres; the environment and punctual
/// lights are not counted): below it the emitters are picked by power
/// alone, as they always were. See docs/lights.md for why 16.
pub const TREE_MIN_EMITTERS: usize = 16;

/// What a node's emitters send, bounded: where (a box), how much (total
/// power) and in which directions (a cone of normals, and how far past
/// its normal each emits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    /// The box's low corner.
    pub lo: Vec3,
    /// The box's high corner.
    pub hi: Vec3,
    /// The cone's axis (unit).
    pub w: Vec3,
    /// Total power of the emitters (`area × mean radiance` summed).
    pub phi: f32,
    /// `cos θ_o`: every emitter's normal lies within `θ_o` of `w`.
    pub cos_o: f32,
    /// `cos θ_e`: each emitter sends light up to `θ_e` past its normal.
    pub cos_e: f32,
}

/// `cos(a − b)` for angles `a`, `b` in `[0, π]` given by their sines and
/// cosines, `a − b` clamped at 0 (then 1).
#[inline(always)]
fn cos_sub_clamped((sin_a, cos_a): (f32, f32), (sin_b, cos_b): (f32, f32)) -> f32 {
    if cos_a > cos_b {
        1.0
    } else {
        cos_a * cos_b + sin_a * sin_b
    }
}

/// `sin(a − b)`, `a − b` clamped at 0 (then 0); see [`cos_sub_clamped`].
#[inline(always)]
fn sin_sub_clamped((sin_a, cos_a): (f32, f32), (sin_b, cos_b): (f32, f32)) -> f32 {
    if cos_a > cos_b {
        0.0
    } else {
        sin_a * cos_b - cos_a * sin_b
    }
}

/// `√(1 − c²)`, 0 where rounding makes `c²` exceed 1.
#[inline(always)]
fn sin_of(c: f32) -> f32 {
    (1.0 - c * c).max(0.0).sqrt()
}

impl LightBounds {
    /// The bounds of one emitter: its box, power, normal (a sphere:
    /// `one_sided = false`, normals in every direction) — emitting up to
    /// `π/2` past its normal.
    pub fn emitter(lo: Vec3, hi: Vec3, phi: f32, normal: Vec3, one_sided: bool) -> Self {
        let (w, cos_o) = if one_sided {
            (normal, 1.0)
        } else {
            (Vec3::Z, -1.0)
        };
        Self {
            lo,
            hi,
            w,
            phi,
            cos_o,
            cos_e: 0.0,
        }
    }

    /// The importance of the bounded emitters at the point `p` (see the
    /// module documentation): an upper bound of what they send there, up
    /// to a factor; 0 where none of them faces `p`.
    pub fn importance(&self, p: Vec3) -> f32 {
        Walked::of(self).importance(p)
    }
}

/// [`LightBounds`] as the walk reads them: what does not depend on the
/// shading point computed once.
#[derive(Clone, Copy, Debug)]
struct Walked {
    /// The box's centre.
    centre: Vec3,
    /// The radius of the box's bounding sphere, and its square.
    r: f32,
    r2: f32,
    w: Vec3,
    phi: f32,
    cos_o: f32,
    sin_o: f32,
    cos_e: f32,
}

impl Walked {
    fn of(b: &LightBounds) -> Self {
        let r2 = (b.hi - b.lo).length_squared() * 0.25;
        Self {
            centre: (b.lo + b.hi) * 0.5,
            r: r2.sqrt(),
            r2,
            w: b.w,
            phi: b.phi,
            cos_o: b.cos_o,
            sin_o: sin_of(b.cos_o),
            cos_e: b.cos_e,
        }
    }

    /// [`LightBounds::importance`].
    #[inline(always)]
    fn importance(&self, p: Vec3) -> f32 {
        let to_p = p - self.centre;
        let dist2 = to_p.length_squared();
        if dist2 <= self.r2 {
            // Inside the bounding sphere: every direction may be seen.
            return self.phi / self.r2.max(f32::MIN_POSITIVE);
        }
        let inv_dist = 1.0 / dist2.sqrt();
        let cos_w = self.w.dot(to_p) * inv_dist;
        if cos_w > self.cos_o {
            // `p` lies within the cone of normals: θ' = 0.
            return self.phi / dist2;
        }
        let w = (sin_of(cos_w), cos_w);
        let o = (self.sin_o, self.cos_o);
        // θ_b: the bounding sphere's half-angle seen from `p`.
        let sin_b = self.r * inv_dist;
        let b = (sin_b, sin_of(sin_b));
        // θ_x = θ_w − θ_o, then θ' = θ_x − θ_b (each clamped at 0).
        let x = (sin_sub_clamped(w, o), cos_sub_clamped(w, o));
        let cos_p = cos_sub_clamped(x, b);
        if cos_p <= self.cos_e {
            return 0.0;
        }
        self.phi * cos_p / dist2
    }
}

/// The union of two direction cones (axis, half-angle in radians), in
/// `f64`: the smallest cone pbrt-v4's rule gives that holds both.
fn cone_union((wa, ta): (DVec3, f64), (wb, tb): (DVec3, f64)) -> (DVec3, f64) {
    use std::f64::consts::PI;
    let td = wa.angle_between(wb);
    if (td + tb).min(PI) <= ta {
        return (wa, ta);
    }
    if (td + ta).min(PI) <= tb {
        return (wb, tb);
    }
    let to = (ta + td + tb) / 2.0;
    let axis = wa.cross(wb);
    if to >= PI || axis.length_squared() == 0.0 {
        return (DVec3::Z, PI);
    }
    let w = glam::DQuat::from_axis_angle(axis.normalize(), to - ta) * wa;
    (w.normalize(), to)
}

/// Bounds being built (in `f64`, the cone by its angles).
#[derive(Clone, Copy, Debug)]
struct Building {
    lo: Vec3,
    hi: Vec3,
    w: DVec3,
    /// `θ_o` (radians).
    theta_o: f64,
    /// `θ_e` (radians).
    theta_e: f64,
    phi: f64,
}

/// How far (radians) a built cone is widened beyond the union of its
/// emitters' cones: the rounding of its axis and angle must never leave an
/// emitter's normal outside (an importance of 0 where light arrives would
/// be bias; a wider cone only costs a little variance).
const CONE_SLACK: f64 = 1e-5;

impl Building {
    fn of(b: &LightBounds, phi: f64) -> Self {
        Self {
            lo: b.lo,
            hi: b.hi,
            w: b.w.as_dvec3(),
            theta_o: f64::from(b.cos_o).clamp(-1.0, 1.0).acos(),
            theta_e: f64::from(b.cos_e).clamp(-1.0, 1.0).acos(),
            phi,
        }
    }

    fn union(self, o: Self) -> Self {
        let (w, theta_o) = cone_union((self.w, self.theta_o), (o.w, o.theta_o));
        Self {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            w,
            theta_o,
            theta_e: self.theta_e.max(o.theta_e),
            phi: self.phi + o.phi,
        }
    }

    /// pbrt-v4's cost of a node of these bounds split along `axis` of
    /// the parent's box of extent `extent`: `φ · M_Ω · area · K_r`.
    fn cost(&self, extent: DVec3, axis: usize) -> f64 {
        use std::f64::consts::PI;
        let (to, te) = (self.theta_o, self.theta_e);
        let tw = (to + te).min(PI);
        let (sin_o, cos_o) = to.sin_cos();
        let m_omega = 2.0 * PI * (1.0 - cos_o)
            + PI / 2.0 * (2.0 * tw * sin_o - (to - 2.0 * tw).cos() - 2.0 * to * sin_o + cos_o);
        let d = (self.hi - self.lo).as_dvec3();
        let area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
        let kr = extent.max_element() / extent[axis].max(f64::MIN_POSITIVE);
        self.phi * m_omega * area * kr
    }

    /// The bounds as the walk reads them (the cone widened by
    /// [`CONE_SLACK`]).
    fn finish(&self) -> LightBounds {
        let theta_o = self.theta_o + if self.theta_o > 0.0 { CONE_SLACK } else { 0.0 };
        LightBounds {
            lo: self.lo,
            hi: self.hi,
            w: self.w.as_vec3(),
            phi: self.phi as f32,
            cos_o: theta_o.min(std::f64::consts::PI).cos() as f32,
            cos_e: self.theta_e.cos() as f32,
        }
    }
}

/// One node: an emitter (a leaf) or two children, the first right after
/// it.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Walked,
    /// A leaf: its emitter's index; an inner node: its second child's.
    index: u32,
    leaf: bool,
}

/// A binary tree over a scene's emitters, for picking one by its
/// importance at a shading point (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    nodes: Vec<Node>,
    /// Each emitter's way from the root (bit `d`: the second child at
    /// depth `d`).
    trails: Vec<u64>,
}

/// Buckets per axis of a split's search.
const BUCKETS: usize = 12;

/// Below this depth splits follow the cost; from it on, the emitters are
/// halved by count, so no trail is longer than 64 bits.
const FORCED_HALVING_DEPTH: u32 = 32;

/// The largest `f32` below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

impl LightTree {
    /// The tree over emitters `0..bounds.len()` of these bounds (each of
    /// positive power).
    pub fn new(bounds: &[LightBounds]) -> Self {
        let mut tree = Self {
            nodes: Vec::with_capacity(2 * bounds.len()),
            trails: vec![0; bounds.len()],
        };
        let mut items: Vec<(Building, u32)> = (bounds.iter().enumerate())
            .map(|(k, b)| (Building::of(b, f64::from(b.phi)), k as u32))
            .collect();
        if !items.is_empty() {
            tree.build(&mut items, 0, 0);
        }
        tree
    }

    /// Number of emitters.
    pub fn len(&self) -> usize {
        self.trails.len()
    }

    /// Whether it has no emitter.
    pub fn is_empty(&self) -> bool {
        self.trails.is_empty()
    }

    /// The subtree of `items` at depth `depth` whose way from the root is
    /// `trail`; its bounds.
    fn build(&mut self, items: &mut [(Building, u32)], trail: u64, depth: u32) -> Building {
        if let [(b, k)] = items {
            self.trails[*k as usize] = trail;
            self.nodes.push(Node {
                bounds: Walked::of(&b.finish()),
                index: *k,
                leaf: true,
            });
            return *b;
        }
        let mid = split(items, depth);
        let at = self.nodes.len();
        self.nodes.push(Node {
            bounds: Walked::of(&items[0].0.finish()),
            index: 0,
            leaf: false,
        });
        let (first, second) = items.split_at_mut(mid);
        let a = self.build(first, trail, depth + 1);
        self.nodes[at].index = self.nodes.len() as u32;
        let b = self.build(second, trail | (1 << depth), depth + 1);
        let both = a.union(b);
        self.nodes[at].bounds = Walked::of(&both.finish());
        both
    }

    /// The probability of the first child of the inner node `at` for a
    /// shading point `p`: its share of the two children's importance
    /// (`None` where neither has any, or it is not a number).
    #[inline(always)]
    fn first_child_probability(&self, at: usize, p: Vec3) -> Option<f32> {
        let first = self.nodes[at + 1].bounds.importance(p);
        let second = self.nodes[self.nodes[at].index as usize]
            .bounds
            .importance(p);
        let sum = first + second;
        (sum > 0.0 && sum.is_finite()).then(|| first / sum)
    }

    /// The emitter the number `u` in `[0, 1)` picks for the shading point
    /// `p`, its probability, and `u` stretched back over `[0, 1)`; `None`
    /// where no emitter faces `p`.
    #[inline]
    pub fn sample(&self, p: Vec3, mut u: f32) -> Option<(u32, f32, f32)> {
        let (mut at, mut pmf) = (0, 1.0f32);
        loop {
            let node = &self.nodes[at];
            if node.leaf {
                return Some((node.index, pmf, u));
            }
            let p0 = self.first_child_probability(at, p)?;
            if u < p0 {
                (at, pmf, u) = (at + 1, pmf * p0, u / p0);
            } else {
                let p1 = 1.0 - p0;
                (at, pmf, u) = (node.index as usize, pmf * p1, (u - p0) / p1);
            }
            u = u.min(ONE_MINUS_EPSILON);
        }
    }

    /// The probability that [`sample`](Self::sample) picks `emitter` for
    /// the shading point `p`: the walk down its trail, the same products.
    #[inline]
    pub fn pmf(&self, p: Vec3, emitter: u32) -> f32 {
        let trail = self.trails[emitter as usize];
        let (mut at, mut pmf, mut depth) = (0, 1.0f32, 0);
        loop {
            let node = &self.nodes[at];
            if node.leaf {
                return pmf;
            }
            let Some(p0) = self.first_child_probability(at, p) else {
                return 0.0;
            };
            if trail >> depth & 1 == 0 {
                (at, pmf) = (at + 1, pmf * p0);
            } else {
                (at, pmf) = (node.index as usize, pmf * (1.0 - p0));
            }
            depth += 1;
        }
    }
}

/// Order `items` (at least two) into a first and a second child and return
/// how many go first: at the cheapest bucket boundary by
/// [`Building::cost`], or halved by count where no boundary separates
/// their centroids (or from [`FORCED_HALVING_DEPTH`] on).
fn split(items: &mut [(Building, u32)], depth: u32) -> usize {
    let half = items.len() / 2;
    let centroid = |b: &Building| (b.lo + b.hi).as_dvec3() * 0.5;
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    let (mut box_lo, mut box_hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for (b, _) in items.iter() {
        (lo, hi) = (lo.min(centroid(b)), hi.max(centroid(b)));
        (box_lo, box_hi) = (box_lo.min(b.lo), box_hi.max(b.hi));
    }
    let extent = (box_hi - box_lo).as_dvec3();
    let bucket = |b: &Building, axis: usize| {
        let f = (centroid(b)[axis] - lo[axis]) / (hi[axis] - lo[axis]);
        ((f * BUCKETS as f64) as usize).min(BUCKETS - 1)
    };
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        if depth >= FORCED_HALVING_DEPTH || hi[axis] <= lo[axis] {
            continue;
        }
        let mut buckets: [Option<Building>; BUCKETS] = [None; BUCKETS];
        for (b, _) in items.iter() {
            let slot = &mut buckets[bucket(b, axis)];
            *slot = Some(slot.map_or(*b, |s| s.union(*b)));
        }
        for cut in 1..BUCKETS {
            let side = |r: std::ops::Range<usize>| {
                buckets[r].iter().flatten().copied().reduce(Building::union)
            };
            let (Some(a), Some(b)) = (side(0..cut), side(cut..BUCKETS)) else {
                continue;
            };
            let cost = a.cost(extent, axis) + b.cost(extent, axis);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, cut));
            }
        }
    }
    match best {
        Some((_, axis, cut)) => {
            items.sort_by_key(|(b, k)| (bucket(b, axis) >= cut, *k));
            items.iter().filter(|(b, _)| bucket(b, axis) < cut).count()
        }
        None => {
            // Halved by count, in the order of the longest axis.
            let axis = (hi - lo).max_position();
            items.sort_by(|(a, ka), (b, kb)| {
                centroid(a)[axis]
                    .total_cmp(&centroid(b)[axis])
                    .then(ka.cmp(kb))
            });
            half
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A light's bounds at `c`, a square of side `s` facing `n`.
    fn quad(c: Vec3, s: f32, n: Vec3, phi: f32) -> LightBounds {
        let h = Vec3::splat(s * 0.5);
        LightBounds::emitter(c - h, c + h, phi, n.normalize(), true)
    }

    #[test]
    fn a_light_facing_away_has_no_importance() {
        let b = quad(Vec3::ZERO, 0.1, Vec3::Y, 1.0);
        assert!(b.importance(Vec3::new(0.3, 1.0, 0.0)) > 0.0);
        assert_eq!(b.importance(Vec3::new(0.3, -1.0, 0.0)), 0.0);
        // Closer is more important, by 1/d².
        let (near, far) = (
            b.importance(Vec3::new(0.0, 1.0, 0.0)),
            b.importance(Vec3::new(0.0, 2.0, 0.0)),
        );
        assert!((near / far - 4.0).abs() < 0.05, "{near} {far}");
    }

    #[test]
    fn the_union_of_cones_holds_both() {
        let a = (DVec3::Y, 0.1);
        let b = (DVec3::new(1.0, 1.0, 0.0).normalize(), 0.2);
        let (w, t) = cone_union(a, b);
        for (wc, tc) in [a, b] {
            assert!(w.angle_between(wc) + tc <= t + 1e-9, "{w} {t}");
        }
        assert_eq!(
            cone_union((DVec3::Y, 0.0), (-DVec3::Y, 0.0)).1,
            std::f64::consts::PI
        );
    }

    #[test]
    fn every_emitter_has_its_trail_and_the_pmfs_sum_to_one() {
        let bounds: Vec<LightBounds> = (0..100)
            .map(|k| {
                let f = k as f32;
                let c = Vec3::new((f * 0.37).sin() * 3.0, 2.0 + (f * 0.11).cos(), f * 0.05);
                quad(
                    c,
                    0.1,
                    Vec3::new((f * 1.3).sin(), -1.0, (f * 0.7).cos()),
                    1.0 + f,
                )
            })
            .collect();
        let tree = LightTree::new(&bounds);
        assert_eq!(tree.nodes.len(), 199);
        // Where every emitter faces the point, the walk never ends in a
        // node whose two children face away: the pmfs sum to 1. Elsewhere
        // they sum to less (the rest: no light is picked).
        for (p, all) in [
            (Vec3::new(0.0, -50.0, 0.0), true),
            (Vec3::ZERO, false),
            (Vec3::new(-3.0, 2.0, 1.0), false),
        ] {
            let faces = bounds.iter().all(|b| b.importance(p) > 0.0);
            assert_eq!(faces, all, "{p}");
            let sum: f64 = (0..100).map(|k| f64::from(tree.pmf(p, k))).sum();
            assert!(sum < 1.0 + 1e-5 && (!all || sum > 1.0 - 1e-5), "{p}: {sum}");
        }
    }
}
