//! Ray packets for small scenes of triangles: each lane a ray, each
//! triangle broadcast to every lane.
//!
//! One ray against packs of 8 or 16 triangles pays, per ray, for
//! broadcasting the ray to every lane and for reducing the lanes' hits to
//! one at the end. Here the lanes hold 8 or 16 *rays* instead, read
//! straight from the wavefront's columns; each triangle is broadcast, and
//! each lane keeps its own ray's closest hit: no reduction, no branch.
//!
//! A [`Plan`] says which triangles each ray tests:
//!
//! - the *first* triangles, tested by every ray, in index order (in the
//!   Cornell box: the room and the light, which nearly every ray reaches);
//! - then *groups* behind boxes (the two blocks). For each group, the rays
//!   of a block of the batch are tested against its box 8 or 16 at a time;
//!   the ones that enter it before their closest hit so far are gathered
//!   into packets of their own (a *stream*: the lanes stay full however
//!   few rays enter), tested against the group's triangles, and their
//!   hits scattered back;
//! - in a big scene whose largest triangles are the plan's (`sphere-1m`:
//!   the room and the blocks), the *tree* of the rest behind its box:
//!   the rays that enter that box before their hit so far are listed, and
//!   the caller walks the tree for them alone.
//!
//! Every lane does exactly what [`closest_hit_brute_force`] does for its
//! ray, on the triangles it tests: [`moller_trumbore`] (the same generic
//! source, so the same IEEE operations), and the smallest `(t, index)`
//! kept (the first triangles in index order, a hit kept only when strictly
//! closer; the groups by [`PackHits::keep`]'s full comparison). A group is
//! skipped only when the ray enters its padded box after its closest hit
//! so far, where none of its triangles can be closer. The answers are the
//! same bits as every other closest-hit query.
//!
//! [`closest_hit_brute_force`]: crate::accel::triangle::closest_hit_brute_force

use super::build::Aabb;
use crate::accel::simd::Lanes;
use crate::accel::triangle::{PackHits, TriangleEdges, V3Tri, moller_trumbore};
use crate::math::V3;

/// Rays handled together: the first triangles, then each group in turn,
/// over this many rays (their columns stay in the L1 cache).
const BLOCK: usize = 256;

/// Most groups behind boxes in a plan.
pub(crate) const MAX_GROUPS: usize = 16;

/// Which triangles the rays test, in which order (see the module's
/// documentation).
#[derive(Clone, Debug, Default)]
pub(crate) struct Plan {
    /// The triangles in the order they are tested: the first ones (by
    /// increasing index), then each group's.
    tris: Vec<TriangleEdges>,
    /// Each one's index in the scene.
    index: Vec<u32>,
    /// How many of `tris` every ray tests.
    first: usize,
    /// The groups, in the order they are tested.
    groups: Vec<Group>,
    /// The box of the tree behind the plan (no triangles of its own here),
    /// where the plan covers only the triangles in front of a tree.
    tree: Option<Group>,
}

/// Triangles behind one box.
#[derive(Clone, Copy, Debug)]
struct Group {
    /// The box's corners, padded as a tree's node boxes are.
    lo: [f32; 3],
    hi: [f32; 3],
    /// The group's triangles: `Plan::tris[start..end]`.
    start: usize,
    end: usize,
}

impl Plan {
    /// Every ray tests `first` (increasing indices), then each group of
    /// `groups` (its box, padded to cover the tests' rounding, and its
    /// triangles) whose box it enters before its closest hit so far.
    pub fn new(tris: &[TriangleEdges], first: &[u32], groups: &[(Aabb, Vec<u32>)]) -> Plan {
        debug_assert!(first.is_sorted(), "the first triangles go in index order");
        let mut plan = Plan {
            tris: first.iter().map(|&i| tris[i as usize]).collect(),
            index: first.to_vec(),
            first: first.len(),
            groups: Vec::with_capacity(groups.len()),
            tree: None,
        };
        assert!(groups.len() <= MAX_GROUPS, "at most {MAX_GROUPS} groups");
        for (b, g) in groups.iter().filter(|(_, g)| !g.is_empty()) {
            let start = plan.tris.len();
            plan.tris.extend(g.iter().map(|&i| tris[i as usize]));
            plan.index.extend(g);
            plan.groups.push(Group {
                lo: b.lo.to_array(),
                hi: b.hi.to_array(),
                start,
                end: plan.tris.len(),
            });
        }
        plan
    }

    /// The plan, with the rays that enter `b` (the padded box of a tree
    /// over the scene's other triangles) before their hit so far listed
    /// by [`closest_hits`] for the caller's walk.
    pub fn with_tree_box(mut self, b: &Aabb) -> Plan {
        let end = self.tris.len();
        self.tree = Some(Group {
            lo: b.lo.to_array(),
            hi: b.hi.to_array(),
            start: end,
            end,
        });
        self
    }

    /// Whether a tree lies behind the plan (see [`Plan::with_tree_box`]).
    pub fn has_tree(&self) -> bool {
        self.tree.is_some()
    }

    /// Whether there is a plan (a scene without one has no triangles here).
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Number of groups behind boxes.
    pub fn group_count(&self) -> usize {
        self.groups.len()
    }

    /// Number of triangles every ray tests.
    pub fn first_count(&self) -> usize {
        self.first
    }
}

/// Rays given as columns (`o[axis][i]`, `d[axis][i]`), `R::LANES` at a
/// time, through `plan`: ray `i`'s closest hit with `t_min < t < t_max`
/// into `t[i]` and `prim[i]` ([`NO_PRIM`](crate::accel::triangle::NO_PRIM)
/// where none; then `t[i]` is `t_max`), among the plan's triangles.
/// Where a tree lies behind the plan, the rays that enter its box before
/// that hit are appended to `behind` (increasing indices).
#[inline(always)]
pub(crate) fn closest_hits<R: Lanes>(
    plan: &Plan,
    (o, d): ([&[f32]; 3], [&[f32]; 3]),
    (t_min, t_max): (f32, f32),
    t: &mut [f32],
    prim: &mut [u32],
    behind: &mut Vec<u32>,
) {
    // Per group (and the tree), the rays of the block that enter its box
    // (with room for a whole packet's indices past the last).
    let mut entering = [[0u32; BLOCK + 16]; MAX_GROUPS + 1];
    let boxes = plan.groups.len() + usize::from(plan.has_tree());
    let entering = &mut entering[..boxes];
    for b in (0..t.len()).step_by(BLOCK) {
        let e = (b + BLOCK).min(t.len());
        let o = o.map(|c| &c[b..e]);
        let d = d.map(|c| &c[b..e]);
        let (t, prim) = (&mut t[b..e], &mut prim[b..e]);
        let counts = first_hits::<R>(plan, (o, d), (t_min, t_max), t, prim, entering);
        for ((g, which), n) in plan.groups.iter().zip(&*entering).zip(counts) {
            group_hits::<R>(plan, g, (o, d), t_min, &which[..n], t, prim);
        }
        if plan.has_tree() {
            let k = plan.groups.len();
            behind.extend(entering[k][..counts[k]].iter().map(|&i| i + b as u32));
        }
    }
}

/// The first triangles, for every ray; then each group's box (and the
/// tree's, last), for every ray: the rays that enter it before their hit
/// so far go into `entering[group]`, and their count is returned.
#[inline(always)]
fn first_hits<R: Lanes>(
    plan: &Plan,
    (o, d): ([&[f32]; 3], [&[f32]; 3]),
    (t_min, t_max): (f32, f32),
    t: &mut [f32],
    prim: &mut [u32],
    entering: &mut [[u32; BLOCK + 16]],
) -> [usize; MAX_GROUPS + 1] {
    let mut counts = [0; MAX_GROUPS + 1];
    let boxes = || plan.groups.iter().chain(&plan.tree);
    let first = &plan.tris[..plan.first];
    for start in (0..t.len()).step_by(R::LANES) {
        let end = (start + R::LANES).min(t.len());
        let lanes = |c: &[f32]| R::from_slice(&c[start..end], 0.0);
        let ray_o = V3::new(lanes(o[0]), lanes(o[1]), lanes(o[2]));
        let ray_d = V3::new(lanes(d[0]), lanes(d[1]), lanes(d[2]));
        // Index -1 is `NO_PRIM` as a u32. The lanes of a short last packet
        // hold the zero ray, which hits nothing and is not written.
        let mut best = PackHits {
            t: R::splat(t_max),
            index: R::index_splat(-1),
        };
        for (tri, &index) in first.iter().zip(&plan.index) {
            let (inside, t_hit) = moller_trumbore(ray_o, ray_d, &splat(tri), R::splat(t_min));
            best.keep::<true>(inside, t_hit, R::index_splat(index as i32));
        }
        best.t.write_to(&mut t[start..end]);
        R::index_write_to(best.index, &mut prim[start..end]);
        if entering.is_empty() {
            continue;
        }
        // The slab test of the tree's nodes (`Node8::intersect`), with
        // both planes of each axis tried, since each lane has its own
        // direction.
        // (No closures here: a closure is compiled apart from this
        // function's instruction set, and its vector code would be calls.)
        let one = R::splat(1.0);
        let inv = [
            one / safe_direction(ray_d.x),
            one / safe_direction(ray_d.y),
            one / safe_direction(ray_d.z),
        ];
        let o_inv = [ray_o.x * inv[0], ray_o.y * inv[1], ray_o.z * inv[2]];
        // Lanes past the end hold the zero ray: not rays.
        let real = (1u32 << (end - start)) - 1;
        for ((g, out), n) in boxes().zip(&mut *entering).zip(&mut counts) {
            let (mut near, mut far) = (R::splat(t_min), best.t);
            for a in 0..3 {
                let t0 = R::splat(g.lo[a]).mul_add(inv[a], -o_inv[a]);
                let t1 = R::splat(g.hi[a]).mul_add(inv[a], -o_inv[a]);
                near = near.max(t0.min(t1));
                far = far.min(t0.max(t1));
            }
            *n += R::compress(R::bits(near.le(far)) & real, start as u32, &mut out[*n..]);
        }
    }
    counts
}

/// `g`'s triangles for the rays `which`, `R::LANES` at a time, gathered
/// from the columns; their hits (where closer) scattered back.
#[inline(always)]
fn group_hits<R: Lanes>(
    plan: &Plan,
    g: &Group,
    (o, d): ([&[f32]; 3], [&[f32]; 3]),
    t_min: f32,
    which: &[u32],
    t: &mut [f32],
    prim: &mut [u32],
) {
    let t_min = R::splat(t_min);
    let tris = &plan.tris[g.start..g.end];
    let index = &plan.index[g.start..g.end];
    for rays in which.chunks(R::LANES) {
        let ray_o = V3::new(gather(o[0], rays), gather(o[1], rays), gather(o[2], rays));
        let ray_d = V3::new(gather(d[0], rays), gather(d[1], rays), gather(d[2], rays));
        let mut so_far = [-1i32; 16];
        for (l, &i) in rays.iter().enumerate() {
            so_far[l] = prim[i as usize] as i32;
        }
        let mut best = PackHits {
            t: gather(t, rays),
            index: R::index_from_slice(&so_far[..R::LANES], -1),
        };
        for (tri, &index) in tris.iter().zip(index) {
            let (inside, t_hit) = moller_trumbore(ray_o, ray_d, &splat(tri), t_min);
            best.keep::<false>(inside, t_hit, R::index_splat(index as i32));
        }
        let (mut t_out, mut prim_out) = ([0.0f32; 16], [0u32; 16]);
        best.t.write_to(&mut t_out[..R::LANES]);
        R::index_write_to(best.index, &mut prim_out[..R::LANES]);
        for (l, &i) in rays.iter().enumerate() {
            t[i as usize] = t_out[l];
            prim[i as usize] = prim_out[l];
        }
    }
}

/// Lane `l` holds `c[rays[l]]` (the zero ray's 0 past the end of `rays`).
#[inline(always)]
fn gather<R: Lanes>(c: &[f32], rays: &[u32]) -> R {
    let mut lanes = [0.0f32; 16];
    for (l, &i) in rays.iter().enumerate() {
        lanes[l] = c[i as usize];
    }
    R::from_slice(&lanes[..R::LANES], 0.0)
}

/// One triangle in every lane.
#[inline(always)]
fn splat<R: Lanes>(tri: &TriangleEdges) -> V3Tri<R> {
    V3Tri {
        v0: V3::splat(tri.v0),
        e1: V3::splat(tri.e1),
        e2: V3::splat(tri.e2),
        n: V3::splat(tri.n),
    }
}

/// A direction component safe to invert in the slab test: as
/// [`NodeRay::new`](super::node::NodeRay::new) makes it, a zero becomes a
/// tiny value of its sign, so `0 · ∞` never makes a NaN.
#[inline(always)]
fn safe_direction<R: Lanes>(x: R) -> R {
    let tiny = R::splat(1e-20);
    // copysign(1e-20, x) where |x| < 1e-20.
    let signed = R::select(R::splat(0.0).le(x), tiny, -tiny);
    R::select(x.abs().lt(tiny), signed, x)
}
