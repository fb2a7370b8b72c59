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
use std::mem::MaybeUninit;
use std::ops::Range;

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

/// What a packet of rays asks of the plan's triangles, and where the
/// answers go: the closest hit ([`ClosestHits`]) or whether anything lies
/// on the segment ([`AnyHits`]). One lane per ray; [`PacketQuery::State`]
/// is a packet's answer so far. Rays are numbered as in the columns.
pub(crate) trait PacketQuery<R: Lanes> {
    /// A packet's answer so far.
    type State: Copy;
    /// Number of rays.
    fn len(&self) -> usize;
    /// Rays `rows` (a packet, the last one perhaps short) before any test.
    fn start(&self, rows: Range<usize>) -> Self::State;
    /// The answers so far of the rays `rows` (lane `l`: ray `rows[l]`).
    fn gather(&self, rows: &[u32]) -> Self::State;
    /// Fold in triangle `index`'s test, lane by lane. `IN_ORDER`: the
    /// caller tests triangles by increasing index (the first ones).
    fn test<const IN_ORDER: bool>(s: &mut Self::State, inside: R::Mask, t: R, index: u32);
    /// Lane by lane, past what distance nothing more can change the
    /// answer (a box entered later is skipped).
    fn far(s: &Self::State) -> R;
    /// The lanes whose answer is final (bits): their rays enter no box.
    fn settled(s: &Self::State) -> u32;
    /// Write the answers of rays `rows` (after the first triangles).
    fn store(&mut self, rows: Range<usize>, s: Self::State);
    /// Write the answers of the rays `rows` (after a group's triangles).
    fn scatter(&mut self, rows: &[u32], s: Self::State);
}

/// The closest hit: ray `i`'s `(t, primitive)` in `t[i]` and `prim[i]`
/// ([`NO_PRIM`](crate::accel::triangle::NO_PRIM) where none; then `t[i]`
/// is `t_max`).
pub(crate) struct ClosestHits<'a> {
    pub t: &'a mut [f32],
    pub prim: &'a mut [u32],
    pub t_max: f32,
}

impl<R: Lanes> PacketQuery<R> for ClosestHits<'_> {
    type State = PackHits<R>;
    #[inline(always)]
    fn len(&self) -> usize {
        self.t.len()
    }
    #[inline(always)]
    fn start(&self, _: Range<usize>) -> PackHits<R> {
        // Index -1 is `NO_PRIM` as a u32.
        PackHits {
            t: R::splat(self.t_max),
            index: R::index_splat(-1),
        }
    }
    #[inline(always)]
    fn gather(&self, rows: &[u32]) -> PackHits<R> {
        let mut so_far = [-1i32; 16];
        for (l, &i) in rows.iter().enumerate() {
            so_far[l] = self.prim[i as usize] as i32;
        }
        PackHits {
            t: gather(self.t, rows),
            index: R::index_from_slice(&so_far[..R::LANES], -1),
        }
    }
    #[inline(always)]
    fn test<const IN_ORDER: bool>(s: &mut PackHits<R>, inside: R::Mask, t: R, index: u32) {
        s.keep::<IN_ORDER>(inside, t, R::index_splat(index as i32));
    }
    #[inline(always)]
    fn far(s: &PackHits<R>) -> R {
        s.t
    }
    #[inline(always)]
    fn settled(_: &PackHits<R>) -> u32 {
        0
    }
    #[inline(always)]
    fn store(&mut self, rows: Range<usize>, s: PackHits<R>) {
        s.t.write_to(&mut self.t[rows.clone()]);
        R::index_write_to(s.index, &mut self.prim[rows]);
    }
    #[inline(always)]
    fn scatter(&mut self, rows: &[u32], s: PackHits<R>) {
        let (mut t, mut prim) = ([0.0f32; 16], [0u32; 16]);
        s.t.write_to(&mut t[..R::LANES]);
        R::index_write_to(s.index, &mut prim[..R::LANES]);
        for (l, &i) in rows.iter().enumerate() {
            self.t[i as usize] = t[l];
            self.prim[i as usize] = prim[l];
        }
    }
}

/// Any hit: `out[i]` is whether something lies on ray `i` before
/// `t_max[i]` (written after the first triangles, then set where a
/// group's triangle blocks it).
pub(crate) struct AnyHits<'a> {
    pub t_max: &'a [f32],
    pub out: &'a mut [bool],
}

impl<R: Lanes> PacketQuery<R> for AnyHits<'_> {
    /// Each lane's segment end, and whether it is occluded.
    type State = (R, R::Mask);
    #[inline(always)]
    fn len(&self) -> usize {
        self.t_max.len()
    }
    #[inline(always)]
    fn start(&self, rows: Range<usize>) -> (R, R::Mask) {
        // Lanes past the end: the zero ray, with a segment nothing is on.
        (R::from_slice(&self.t_max[rows], 0.0), R::splat_mask(false))
    }
    #[inline(always)]
    fn gather(&self, rows: &[u32]) -> (R, R::Mask) {
        (gather(self.t_max, rows), R::splat_mask(false))
    }
    #[inline(always)]
    fn test<const IN_ORDER: bool>(s: &mut (R, R::Mask), inside: R::Mask, t: R, _: u32) {
        s.1 = s.1 | (inside & t.lt(s.0));
    }
    #[inline(always)]
    fn far(s: &(R, R::Mask)) -> R {
        s.0
    }
    #[inline(always)]
    fn settled(s: &(R, R::Mask)) -> u32 {
        R::bits(s.1)
    }
    #[inline(always)]
    fn store(&mut self, rows: Range<usize>, s: (R, R::Mask)) {
        let bits = R::bits(s.1);
        for (l, out) in self.out[rows].iter_mut().enumerate() {
            *out = bits & (1 << l) != 0;
        }
    }
    #[inline(always)]
    fn scatter(&mut self, rows: &[u32], s: (R, R::Mask)) {
        let bits = R::bits(s.1);
        for (l, &i) in rows.iter().enumerate() {
            self.out[i as usize] |= bits & (1 << l) != 0;
        }
    }
}

/// Rays given as columns (`o[axis][i]`, `d[axis][i]`), `R::LANES` at a
/// time, through `plan`, with query `q` (its answers among the plan's
/// triangles). Where a tree lies behind the plan, the rays that enter its
/// box before their answer is settled (the closest hit so far, the end of
/// an open segment) are appended to `behind` (increasing indices).
#[inline(always)]
pub(crate) fn trace<R: Lanes, Q: PacketQuery<R>>(
    plan: &Plan,
    rays: ([&[f32]; 3], [&[f32]; 3]),
    t_min: f32,
    q: &mut Q,
    behind: &mut Vec<u32>,
) {
    // Per group (and the tree), the rays of the block that enter its box
    // (with room for a whole packet's indices past the last). Only the
    // plan's own rows are zeroed: the whole array, 18 KB, was on every
    // call, for most plans ten times what they use.
    let mut rows = [const { MaybeUninit::<[u32; BLOCK + 16]>::uninit() }; MAX_GROUPS + 1];
    let boxes = plan.groups.len() + usize::from(plan.has_tree());
    for row in &mut rows[..boxes] {
        row.write([0; BLOCK + 16]);
    }
    // SAFETY: the first `boxes` rows were written just above, and
    // `MaybeUninit<T>` has `T`'s layout.
    let entering: &mut [[u32; BLOCK + 16]] =
        unsafe { std::slice::from_raw_parts_mut(rows.as_mut_ptr().cast(), boxes) };
    let n = q.len();
    for b in (0..n).step_by(BLOCK) {
        let block = b..(b + BLOCK).min(n);
        let counts = first_hits::<R, Q>(plan, rays, t_min, block, q, entering);
        for ((g, which), n) in plan.groups.iter().zip(&*entering).zip(counts) {
            group_hits::<R, Q>(plan, g, rays, t_min, &which[..n], q);
        }
        if plan.has_tree() {
            let k = plan.groups.len();
            behind.extend(&entering[k][..counts[k]]);
        }
    }
}

/// The first triangles, for every ray of `block`; then each group's box
/// (and the tree's, last), for every ray whose answer is not settled: the
/// rays that enter it before their answer's `far` go into
/// `entering[group]`, and their count is returned.
#[inline(always)]
fn first_hits<R: Lanes, Q: PacketQuery<R>>(
    plan: &Plan,
    (o, d): ([&[f32]; 3], [&[f32]; 3]),
    t_min: f32,
    block: Range<usize>,
    q: &mut Q,
    entering: &mut [[u32; BLOCK + 16]],
) -> [usize; MAX_GROUPS + 1] {
    let mut counts = [0; MAX_GROUPS + 1];
    let boxes = || plan.groups.iter().chain(&plan.tree);
    let first = &plan.tris[..plan.first];
    for start in block.clone().step_by(R::LANES) {
        let end = (start + R::LANES).min(block.end);
        let lanes = |c: &[f32]| R::from_slice(&c[start..end], 0.0);
        let ray_o = V3::new(lanes(o[0]), lanes(o[1]), lanes(o[2]));
        let ray_d = V3::new(lanes(d[0]), lanes(d[1]), lanes(d[2]));
        // The lanes of a short last packet hold the zero ray, which hits
        // nothing and is not written.
        let mut s = q.start(start..end);
        for (tri, &index) in first.iter().zip(&plan.index) {
            let (inside, t_hit) = moller_trumbore(ray_o, ray_d, &splat(tri), R::splat(t_min));
            Q::test::<true>(&mut s, inside, t_hit, index);
        }
        q.store(start..end, s);
        // Lanes past the end hold the zero ray: not rays.
        let open = ((1u32 << (end - start)) - 1) & !Q::settled(&s);
        if entering.is_empty() || open == 0 {
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
        for ((g, out), n) in boxes().zip(&mut *entering).zip(&mut counts) {
            let (mut near, mut far) = (R::splat(t_min), Q::far(&s));
            for a in 0..3 {
                let t0 = R::splat(g.lo[a]).mul_add(inv[a], -o_inv[a]);
                let t1 = R::splat(g.hi[a]).mul_add(inv[a], -o_inv[a]);
                near = near.max(t0.min(t1));
                far = far.min(t0.max(t1));
            }
            *n += R::compress(R::bits(near.le(far)) & open, start as u32, &mut out[*n..]);
        }
    }
    counts
}

/// `g`'s triangles for the rays `which`, `R::LANES` at a time, gathered
/// from the columns; their answers scattered back.
#[inline(always)]
fn group_hits<R: Lanes, Q: PacketQuery<R>>(
    plan: &Plan,
    g: &Group,
    (o, d): ([&[f32]; 3], [&[f32]; 3]),
    t_min: f32,
    which: &[u32],
    q: &mut Q,
) {
    let t_min = R::splat(t_min);
    let tris = &plan.tris[g.start..g.end];
    let index = &plan.index[g.start..g.end];
    for rays in which.chunks(R::LANES) {
        let ray_o = V3::new(gather(o[0], rays), gather(o[1], rays), gather(o[2], rays));
        let ray_d = V3::new(gather(d[0], rays), gather(d[1], rays), gather(d[2], rays));
        let mut s = q.gather(rays);
        for (tri, &index) in tris.iter().zip(index) {
            let (inside, t_hit) = moller_trumbore(ray_o, ray_d, &splat(tri), t_min);
            Q::test::<false>(&mut s, inside, t_hit, index);
        }
        q.scatter(rays, s);
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
