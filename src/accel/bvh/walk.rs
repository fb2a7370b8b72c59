//! The one traversal: a walk through the tree, a node or a leaf per
//! [`Walk::step`], generic over the query (closest hit, any hit) and the
//! lane type (8 or 16). What a query does at a leaf — keep the closest hit,
//! or stop at the first — is its [`Query`] implementation; everything else
//! (box tests, child order, the stack, culling) is shared.

use super::node::{Child, Node8, NodeRay};
use super::{Bvh, KindPacks, LanesIn, PacksOf};
use crate::accel::hit::HitFilter;
use crate::accel::shape::{Shape, ShapePack, Visit, VisitOne};
use crate::accel::simd::{Lanes, prefetch_lines};
use crate::accel::triangle::PackHits;
#[cfg(doc)]
use crate::accel::triangle::{NO_PRIM, TrianglePack};
use crate::math::V3;
use glam::Vec3;
use std::marker::PhantomData;
use std::mem::MaybeUninit;
use wide::{f32x4, f32x8, i32x8};

/// Relative slack on the best `t` when culling boxes.
const T_SLACK: f32 = 1.0 / 1024.0;

/// Traversal stack entries: one group per level, for the deepest possible
/// tree (`SAH_DEPTH_LIMIT` levels, then median splits of 8 for up to 2^32
/// primitives, then a leaf).
const STACK: usize = super::build::SAH_DEPTH_LIMIT as usize + 12;

/// Rays in flight in an interleaved batch.
pub const BATCH: usize = 16;

/// A leaf pack on its own cache lines (an 8-lane triangle pack is 416
/// bytes, 6.5 lines: aligned to 64 it takes exactly seven, never eight; an
/// 8-lane sphere pack is 160 bytes, three lines).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Pack<T>(pub T);

/// A ray for pack tests (broadcast to every lane where a leaf is tested:
/// cheaper than keeping the broadcasts in a walk's state).
pub(crate) struct PackRay<R: Lanes> {
    o: Vec3,
    d: Vec3,
    t_min: f32,
    lanes: PhantomData<R>,
}

impl<R: Lanes> PackRay<R> {
    #[inline(always)]
    fn new(o: Vec3, d: Vec3, t_min: f32) -> Self {
        Self {
            o,
            d,
            t_min,
            lanes: PhantomData,
        }
    }

    /// Origin, direction and `t_min` in every lane.
    #[inline(always)]
    pub fn wide(&self) -> (V3<R>, V3<R>, R) {
        (V3::splat(self.o), V3::splat(self.d), R::splat(self.t_min))
    }
}

/// What a query does at the leaves it reaches.
pub(crate) trait Query<R: Lanes> {
    /// The answer.
    type Output;
    /// Whether children are visited nearest first (worth it when a hit
    /// shortens the ray).
    const ORDERED: bool;
    /// Boxes the ray enters beyond this are skipped.
    fn cull(&self) -> f32;
    /// Test a leaf of packs of one kind (triangles or spheres); `true`
    /// ends the walk (the answer is known). `in_order`: these are all the
    /// packs the walk tests, in increasing index order (a tree of one
    /// leaf).
    fn leaf<P: ShapePack<R>>(&mut self, r: &PackRay<R>, packs: &[Pack<P>], in_order: bool) -> bool;
    /// The answer, once the walk is over.
    fn output(&self) -> Self::Output;
    /// Called at every inner node visited (for statistics).
    #[inline(always)]
    fn node(&mut self) {}
}

/// A query made from its ray's `t_max` alone (not a filtered one).
pub(crate) trait Plain<R: Lanes>: Query<R> {
    /// A query over `t < t_max`.
    fn new(t_max: f32) -> Self;
}

/// A query for both lane types, so a caller can pick the width at run time.
pub(crate) trait QueryKind {
    /// The answer.
    type Output;
    /// The query for lane type `R`.
    type Q<R: LanesIn>: Plain<R, Output = Self::Output>;
}

/// One ray's query, made at whichever lane type the tree has (for queries
/// that carry more than `t_max`: the filtered ones).
pub(crate) trait MakeQuery {
    /// The answer.
    type Output;
    /// The query for lane type `R`.
    type Q<R: LanesIn>: Query<R, Output = Self::Output>;
    /// The query, at lane type `R`.
    fn make<R: LanesIn>(self) -> Self::Q<R>;
}

/// The distance past which a box is skipped, given the best hit's `t`:
/// a little beyond it, for Möller–Trumbore's rounding of `t`.
#[inline(always)]
fn cull_bound(t: f32) -> f32 {
    t + t.abs() * T_SLACK
}

/// The closest hit: the smallest `(t, index)`.
pub(crate) struct Closest<R: Lanes> {
    best: PackHits<R>,
    t_max: f32,
    cull: f32,
}

impl<R: Lanes> Plain<R> for Closest<R> {
    #[inline(always)]
    fn new(t_max: f32) -> Self {
        Self {
            best: PackHits::new(t_max),
            t_max,
            cull: cull_bound(t_max),
        }
    }
}

impl<R: Lanes> Query<R> for Closest<R> {
    /// `(t, primitive)`, with [`NO_PRIM`] for no hit.
    type Output = (f32, u32);
    const ORDERED: bool = true;
    #[inline(always)]
    fn cull(&self) -> f32 {
        self.cull
    }
    #[inline(always)]
    fn leaf<P: ShapePack<R>>(&mut self, r: &PackRay<R>, packs: &[Pack<P>], in_order: bool) -> bool {
        let (o, d, t_min) = r.wide();
        // The running best in registers (stored once, after the packs).
        let mut best = self.best;
        if in_order {
            // The whole walk: no cull distance needed after it.
            for Pack(p) in packs {
                p.intersect::<true>(&o, &d, t_min, &mut best);
            }
            self.best = best;
            return false;
        }
        for Pack(p) in packs {
            p.intersect::<false>(&o, &d, t_min, &mut best);
        }
        self.best = best;
        self.cull = cull_bound(best.t.min_lane());
        false
    }
    #[inline(always)]
    fn output(&self) -> (f32, u32) {
        self.best.closest_below(self.t_max)
    }
}

/// [`Closest`] for any width.
pub(crate) struct ClosestKind;

impl QueryKind for ClosestKind {
    type Output = (f32, u32);
    type Q<R: LanesIn> = Closest<R>;
}

/// Any hit with `t < t_max`: stops at the first.
pub(crate) struct AnyHit<R: Lanes> {
    t_max: R,
    cull: f32,
    hit: bool,
}

impl<R: Lanes> Plain<R> for AnyHit<R> {
    #[inline(always)]
    fn new(t_max: f32) -> Self {
        Self {
            t_max: R::splat(t_max),
            cull: cull_bound(t_max),
            hit: false,
        }
    }
}

impl<R: Lanes> Query<R> for AnyHit<R> {
    type Output = bool;
    const ORDERED: bool = false;
    #[inline(always)]
    fn cull(&self) -> f32 {
        self.cull
    }
    #[inline(always)]
    fn leaf<P: ShapePack<R>>(
        &mut self,
        r: &PackRay<R>,
        packs: &[Pack<P>],
        _in_order: bool,
    ) -> bool {
        let (o, d, t_min) = r.wide();
        for Pack(p) in packs {
            if p.occludes(&o, &d, t_min, self.t_max) {
                self.hit = true;
                return true;
            }
        }
        false
    }
    #[inline(always)]
    fn output(&self) -> bool {
        self.hit
    }
}

/// [`AnyHit`] for any width.
pub(crate) struct AnyHitKind;

impl QueryKind for AnyHitKind {
    type Output = bool;
    type Q<R: LanesIn> = AnyHit<R>;
}

/// The lanes among `candidates` (bits) whose hit `(t, index)` `filter`
/// lets through: those on a primitive that may pass and passes there.
#[inline(never)]
fn passing<R: Lanes, F: HitFilter>(filter: &F, t: R, index: R::Index, candidates: u32) -> u32 {
    let (mut ts, mut prims) = ([0.0f32; 16], [0u32; 16]);
    t.write_to(&mut ts[..R::LANES]);
    R::index_write_to(index, &mut prims[..R::LANES]);
    let (mut pass, mut c) = (0u32, candidates);
    while c != 0 {
        let l = c.trailing_zeros() as usize;
        c &= c - 1;
        if filter.may_pass(prims[l]) && filter.passes(prims[l], ts[l]) {
            pass |= 1 << l;
        }
    }
    pass
}

/// The lanes whose bit is set in `bits`, as a mask.
#[inline(always)]
fn lanes_mask<R: Lanes>(bits: u32) -> R::Mask {
    let set: [i32; 16] = std::array::from_fn(|l| ((bits >> l) & 1) as i32);
    R::index_lt(R::index_splat(0), R::index_from_slice(&set[..R::LANES], 0))
}

/// [`Closest`] among the hits that `F` does not let through: each pack's
/// new best lanes are put to the filter before they count, and a lane that
/// passes keeps its best before the pack. The smallest `(t, index)` of the
/// hits that do not pass, whatever the order of the walk.
pub(crate) struct FilteredClosest<R: Lanes, F> {
    best: PackHits<R>,
    t_max: f32,
    cull: f32,
    filter: F,
}

impl<R: Lanes, F: HitFilter> FilteredClosest<R, F> {
    #[inline(always)]
    pub fn new(t_max: f32, filter: F) -> Self {
        Self {
            best: PackHits::new(t_max),
            t_max,
            cull: cull_bound(t_max),
            filter,
        }
    }
}

impl<R: Lanes, F: HitFilter> Query<R> for FilteredClosest<R, F> {
    type Output = (f32, u32);
    const ORDERED: bool = true;
    #[inline(always)]
    fn cull(&self) -> f32 {
        self.cull
    }
    #[inline(always)]
    fn leaf<P: ShapePack<R>>(
        &mut self,
        r: &PackRay<R>,
        packs: &[Pack<P>],
        _in_order: bool,
    ) -> bool {
        let (o, d, t_min) = r.wide();
        let mut best = self.best;
        for Pack(p) in packs {
            let before = best;
            p.intersect::<false>(&o, &d, t_min, &mut best);
            // A lane's index changes exactly where a primitive of this
            // pack became its best.
            let new = R::bits(
                R::index_lt(best.index, before.index) | R::index_lt(before.index, best.index),
            );
            if new != 0 {
                let pass = passing(&self.filter, best.t, best.index, new);
                if pass != 0 {
                    let m = lanes_mask::<R>(pass);
                    best.t = R::select(m, before.t, best.t);
                    best.index = R::index_select(m, before.index, best.index);
                }
            }
        }
        self.best = best;
        self.cull = cull_bound(best.t.min_lane());
        false
    }
    #[inline(always)]
    fn output(&self) -> (f32, u32) {
        self.best.closest_below(self.t_max)
    }
}

/// [`AnyHit`] among the hits that `F` does not let through: a pack's hits
/// are put to the filter, and the walk stops at the first that does not
/// pass.
pub(crate) struct FilteredAnyHit<R: Lanes, F> {
    t_max: f32,
    wide_t_max: R,
    cull: f32,
    hit: bool,
    filter: F,
}

impl<R: Lanes, F: HitFilter> FilteredAnyHit<R, F> {
    #[inline(always)]
    pub fn new(t_max: f32, filter: F) -> Self {
        Self {
            t_max,
            wide_t_max: R::splat(t_max),
            cull: cull_bound(t_max),
            hit: false,
            filter,
        }
    }
}

impl<R: Lanes, F: HitFilter> Query<R> for FilteredAnyHit<R, F> {
    type Output = bool;
    const ORDERED: bool = false;
    #[inline(always)]
    fn cull(&self) -> f32 {
        self.cull
    }
    #[inline(always)]
    fn leaf<P: ShapePack<R>>(
        &mut self,
        r: &PackRay<R>,
        packs: &[Pack<P>],
        _in_order: bool,
    ) -> bool {
        let (o, d, t_min) = r.wide();
        for Pack(p) in packs {
            if !p.occludes(&o, &d, t_min, self.wide_t_max) {
                continue;
            }
            // Which lanes: the same test, lane for lane.
            let mut h = PackHits::new(self.t_max);
            p.intersect::<false>(&o, &d, t_min, &mut h);
            let hits = R::bits(h.t.lt(self.wide_t_max));
            if passing(&self.filter, h.t, h.index, hits) != hits {
                self.hit = true;
                return true;
            }
        }
        false
    }
    #[inline(always)]
    fn output(&self) -> bool {
        self.hit
    }
}

/// A filtered closest-hit query of one ray, at either width.
pub(crate) struct FilteredClosestKind<F> {
    pub t_max: f32,
    pub filter: F,
}

impl<F: HitFilter> MakeQuery for FilteredClosestKind<F> {
    type Output = (f32, u32);
    type Q<R: LanesIn> = FilteredClosest<R, F>;
    #[inline(always)]
    fn make<R: LanesIn>(self) -> FilteredClosest<R, F> {
        FilteredClosest::new(self.t_max, self.filter)
    }
}

/// A filtered occlusion query of one ray, at either width.
pub(crate) struct FilteredAnyHitKind<F> {
    pub t_max: f32,
    pub filter: F,
}

impl<F: HitFilter> MakeQuery for FilteredAnyHitKind<F> {
    type Output = bool;
    type Q<R: LanesIn> = FilteredAnyHit<R, F>;
    #[inline(always)]
    fn make<R: LanesIn>(self) -> FilteredAnyHit<R, F> {
        FilteredAnyHit::new(self.t_max, self.filter)
    }
}

/// Test the primitives that are outside the tree, kind after kind; true
/// when that already answers the query.
#[inline(always)]
fn start<R: LanesIn, Q: Query<R>>(bvh: &Bvh, r: &PackRay<R>, q: &mut Q) -> bool {
    struct Start<'a, R: Lanes, Q> {
        r: &'a PackRay<R>,
        q: &'a mut Q,
    }
    impl<R: Lanes, Q: Query<R>> Visit<PacksOf<R>> for Start<'_, R, Q> {
        #[inline(always)]
        fn visit<S: Shape>(&mut self, k: &KindPacks<S::Pack<R>>) -> bool {
            !k.unbounded.is_empty() && self.q.leaf(self.r, &k.unbounded, false)
        }
    }
    R::packs(bvh).any(&mut Start { r, q })
}

/// Hand the leaf `leaf` to the query, by its kind; true ends the walk.
/// [`Child::EMPTY`] (kind 3) holds nothing: a ray that reaches it (only a
/// ray no box test can judge would) finds nothing there.
#[inline(always)]
fn visit_leaf<R: LanesIn, Q: Query<R>>(
    bvh: &Bvh,
    r: &PackRay<R>,
    q: &mut Q,
    leaf: Child,
    in_order: bool,
) -> bool {
    struct Leaf<'a, R: Lanes, Q> {
        r: &'a PackRay<R>,
        q: &'a mut Q,
        packs: (usize, usize),
        in_order: bool,
    }
    impl<R: Lanes, Q: Query<R>> VisitOne<PacksOf<R>> for Leaf<'_, R, Q> {
        type Out = bool;
        #[inline(always)]
        fn visit<S: Shape>(self, k: &KindPacks<S::Pack<R>>) -> bool {
            let (first, count) = self.packs;
            self.q
                .leaf(self.r, &k.leaves[first..first + count], self.in_order)
        }
    }
    let packs = leaf.packs();
    let visit = Leaf {
        r,
        q,
        packs,
        in_order,
    };
    R::packs(bvh).by_kind(leaf.kind(), visit).unwrap_or(false)
}

/// The children of one node that a walk has yet to visit: where the ray
/// enters each child's box, and a bit per child still to visit.
#[derive(Clone, Copy, Debug)]
struct Group {
    t_near: f32x8,
    node: u32,
    mask: u32,
}

impl Group {
    const NONE: Group = Group {
        t_near: f32x8::ZERO,
        node: 0,
        mask: 0,
    };
}

/// Whether `(o, d)` is a ray at all: a NaN or infinite coordinate (a
/// direction scattered from hostile numbers, say) makes every box test
/// meaningless, and such a ray misses everything.
#[inline(always)]
fn is_ray(o: Vec3, d: Vec3) -> bool {
    o.is_finite() && d.is_finite()
}

/// The walk's one body: visit `cur` (a node or a leaf), then choose the
/// next child to visit into `cur`; false when the walk is over.
///
/// A node's children that the ray enters become the current [`Group`]
/// (the previous one, if it still has children to visit, goes on the
/// stack). The next child is taken from the current group — the nearest
/// (`Q::ORDERED`) or the first — among those the ray enters before the
/// query's cull distance; an exhausted group is replaced by the one on top
/// of the stack.
#[inline(always)]
fn step<R: LanesIn, Q: Query<R>>(
    bvh: &Bvh,
    r: &PackRay<R>,
    nr: &NodeRay,
    q: &mut Q,
    stack: &mut Stack,
    cur: &mut Child,
    group: &mut Group,
) -> bool {
    let c = *cur;
    if c.is_node() {
        q.node();
        let node = &bvh.nodes[c.0 as usize];
        let (mask, t_near) = node.intersect(nr, q.cull());
        if mask != 0 {
            if group.mask != 0 {
                stack.push(*group);
            }
            *group = Group {
                t_near,
                node: c.0,
                mask,
            };
        }
    } else if c != Child::EMPTY && visit_leaf(bvh, r, q, c, false) {
        return false;
    }
    let cull = f32x8::splat(q.cull());
    loop {
        let live = group.t_near.simd_le(cull).to_bitmask() & group.mask;
        if live != 0 {
            let lane = if Q::ORDERED && live & (live - 1) != 0 {
                nearest(group.t_near, live)
            } else {
                live.trailing_zeros()
            };
            group.mask = live & !(1 << lane);
            *cur = bvh.nodes[group.node as usize].child[lane as usize];
            return true;
        }
        match stack.pop() {
            Some(g) => *group = g,
            None => return false,
        }
    }
}

/// The lane of `live` (two or more bits) with the smallest `t_near` (the
/// lowest such lane on ties).
#[inline(always)]
fn nearest(t_near: f32x8, live: u32) -> u32 {
    const BITS: i32x8 = i32x8::new([1, 2, 4, 8, 16, 32, 64, 128]);
    let in_live: f32x8 = bytemuck::cast((i32x8::splat(live as i32) & BITS).simd_eq(BITS));
    let t = in_live.select(t_near, f32x8::splat(f32::INFINITY));
    let [lo, hi]: [f32x4; 2] = bytemuck::cast(t);
    let [a, b, c, d] = lo.fast_min(hi).to_array();
    let min = |x: f32, y: f32| if x < y { x } else { y };
    let m = min(min(a, b), min(c, d));
    (t.simd_eq(f32x8::splat(m)).to_bitmask() & live).trailing_zeros()
}

/// One ray through the tree, its state in locals. `front`: test the
/// primitives in front of the tree too (false where the caller has).
#[inline(always)]
pub(crate) fn walk_one<R: LanesIn, Q: Plain<R>>(
    bvh: &Bvh,
    (o, d): (Vec3, Vec3),
    t_min: f32,
    t_max: f32,
    front: bool,
) -> Q::Output {
    walk_one_with::<R, Q>(bvh, (o, d), t_min, Q::new(t_max), front)
}

/// [`walk_one`] with the query `q`, made by the caller.
#[inline(always)]
pub(crate) fn walk_one_with<R: LanesIn, Q: Query<R>>(
    bvh: &Bvh,
    (o, d): (Vec3, Vec3),
    t_min: f32,
    mut q: Q,
    front: bool,
) -> Q::Output {
    let r = PackRay::new(o, d, t_min);
    if !is_ray(o, d) || front && start(bvh, &r, &mut q) {
        return q.output();
    }
    let root = bvh.root;
    if !root.is_node() {
        // A tree of one leaf (or none): no box to test.
        if root != Child::EMPTY {
            visit_leaf(bvh, &r, &mut q, root, bvh.in_order);
        }
        return q.output();
    }
    let nr = NodeRay::new(o, d, t_min);
    if bvh.nodes.len() == 1 {
        // One node, whose children are all leaves: no stack, no order.
        let node = &bvh.nodes[0];
        q.node();
        let (mut mask, _) = node.intersect(&nr, q.cull());
        while mask != 0 {
            let lane = mask.trailing_zeros();
            mask &= mask - 1;
            if visit_leaf(bvh, &r, &mut q, node.child[lane as usize], false) {
                break;
            }
        }
        return q.output();
    }
    let mut stack = Stack::new();
    let mut cur = root;
    let mut group = Group::NONE;
    while step(bvh, &r, &nr, &mut q, &mut stack, &mut cur, &mut group) {}
    q.output()
}

/// One ray's walk in an interleaved batch: the state [`walk_one`] keeps in
/// locals.
struct Walk<R: Lanes, Q> {
    r: PackRay<R>,
    nr: NodeRay,
    q: Q,
    stack: Stack,
    /// The node or leaf to visit next.
    cur: Child,
    group: Group,
}

impl<R: LanesIn, Q: Query<R>> Walk<R, Q> {
    #[inline(always)]
    fn new(bvh: &Bvh, o: Vec3, d: Vec3, (t_min, q): (f32, Q), front: bool) -> Self {
        let mut w = Walk {
            r: PackRay::new(o, d, t_min),
            nr: NodeRay::new(o, d, t_min),
            q,
            stack: Stack::new(),
            cur: bvh.root,
            group: Group::NONE,
        };
        if !is_ray(o, d) || front && start(bvh, &w.r, &mut w.q) {
            w.cur = Child::EMPTY;
        }
        w
    }

    /// Start over with another ray, reusing the stack's memory in place.
    #[inline(always)]
    fn reset(&mut self, bvh: &Bvh, o: Vec3, d: Vec3, (t_min, q): (f32, Q), front: bool) {
        self.r = PackRay::new(o, d, t_min);
        self.nr = NodeRay::new(o, d, t_min);
        self.q = q;
        self.stack.len = 0;
        self.cur = bvh.root;
        self.group = Group::NONE;
        if !is_ray(o, d) || front && start(bvh, &self.r, &mut self.q) {
            self.cur = Child::EMPTY;
        }
    }

    #[inline(always)]
    fn step(&mut self, bvh: &Bvh) -> bool {
        step(
            bvh,
            &self.r,
            &self.nr,
            &mut self.q,
            &mut self.stack,
            &mut self.cur,
            &mut self.group,
        )
    }

    /// Ask the memory system for what the next step reads.
    #[inline(always)]
    fn prefetch(&self, bvh: &Bvh) {
        let cur = self.cur;
        if cur.is_node() {
            if let Some(n) = bvh.nodes.get(cur.0 as usize) {
                prefetch_lines(n, size_of::<Node8>() / 64);
            }
        } else if cur != Child::EMPTY {
            /// Prefetch a leaf's packs.
            struct Fetch((usize, usize));
            impl<R: Lanes> VisitOne<PacksOf<R>> for Fetch {
                type Out = ();
                #[inline(always)]
                fn visit<S: Shape>(self, k: &KindPacks<S::Pack<R>>) {
                    let (first, count) = self.0;
                    if let Some(p) = k.leaves.get(first) {
                        prefetch_lines(p, count * size_of::<Pack<S::Pack<R>>>() / 64);
                    }
                }
            }
            R::packs(bvh).by_kind(cur.kind(), Fetch(cur.packs()));
        }
    }
}

/// Rays `0..n` through the tree: `ray(i)` gives ray `i`'s origin, direction
/// and `t_max`; `out(i, answer)` takes its answer (in any order). `front`:
/// test the primitives in front of the tree too (false where the caller
/// has: the ray packets of `packet`).
///
/// On a tree bigger than the caches the rays go [`BATCH`] at a time,
/// interleaved: each step of one ray prefetches the node or leaf it will
/// visit next, and the other rays' steps run while it arrives from memory.
/// A small tree is walked one ray after another.
#[inline(always)]
pub(crate) fn walk_many<R: LanesIn, Q: Plain<R>>(
    bvh: &Bvh,
    n: usize,
    ray: impl Fn(usize) -> (Vec3, Vec3, f32),
    t_min: f32,
    front: bool,
    out: impl FnMut(usize, Q::Output),
) {
    walk_many_with::<R, Q>(
        bvh,
        n,
        #[inline(always)]
        |i| {
            let (o, d, t_max) = ray(i);
            (o, d, Q::new(t_max))
        },
        t_min,
        front,
        out,
    )
}

/// [`walk_many`] with each ray's query made by the caller: `ray(i)` gives
/// ray `i`'s origin, direction and query.
#[inline(always)]
pub(crate) fn walk_many_with<R: LanesIn, Q: Query<R>>(
    bvh: &Bvh,
    n: usize,
    ray: impl Fn(usize) -> (Vec3, Vec3, Q),
    t_min: f32,
    front: bool,
    mut out: impl FnMut(usize, Q::Output),
) {
    if !bvh.interleave || !bvh.root.is_node() {
        for i in 0..n {
            let (o, d, q) = ray(i);
            out(i, walk_one_with::<R, Q>(bvh, (o, d), t_min, q, front));
        }
        return;
    }
    let mut next = 0usize;
    let mut slots: [(usize, Option<Walk<R, Q>>); BATCH] = std::array::from_fn(|_| (0, None));
    let mut live = 0usize;
    for (index, slot) in slots.iter_mut() {
        if next < n {
            let (o, d, q) = ray(next);
            *slot = Some(Walk::new(bvh, o, d, (t_min, q), front));
            *index = next;
            next += 1;
            live += 1;
        }
    }
    while live > 0 {
        for (index, slot) in slots.iter_mut() {
            let Some(w) = slot else { continue };
            if w.step(bvh) {
                w.prefetch(bvh);
                continue;
            }
            out(*index, w.q.output());
            if next < n {
                let (o, d, q) = ray(next);
                w.reset(bvh, o, d, (t_min, q), front);
                w.prefetch(bvh);
                *index = next;
                next += 1;
            } else {
                *slot = None;
                live -= 1;
            }
        }
    }
}

/// The traversal stack: groups of children still to visit, one per level
/// at most.
struct Stack {
    entries: [MaybeUninit<Group>; STACK],
    len: usize,
}

impl Stack {
    #[inline(always)]
    fn new() -> Self {
        Self {
            // An array of `MaybeUninit` needs no initialisation.
            entries: [const { MaybeUninit::uninit() }; STACK],
            len: 0,
        }
    }

    #[inline(always)]
    fn push(&mut self, g: Group) {
        // Bounds-checked: the build bounds the depth so this never fails.
        self.entries[self.len] = MaybeUninit::new(g);
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<Group> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: entries below `len` were all written by `push`.
        Some(unsafe { self.entries[self.len].assume_init() })
    }
}

/// How much work a walk did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WalkStats {
    /// Inner nodes visited (8 box tests each).
    pub nodes: u64,
    /// Leaves visited.
    pub leaves: u64,
    /// Packs tested.
    pub packs: u64,
}

impl std::ops::AddAssign for WalkStats {
    fn add_assign(&mut self, o: Self) {
        self.nodes += o.nodes;
        self.leaves += o.leaves;
        self.packs += o.packs;
    }
}

/// A query that counts what `Q` does.
pub(crate) struct Counting<Q> {
    pub q: Q,
    pub stats: WalkStats,
}

impl<R: Lanes, Q: Plain<R>> Plain<R> for Counting<Q> {
    #[inline(always)]
    fn new(t_max: f32) -> Self {
        Self {
            q: Q::new(t_max),
            stats: WalkStats::default(),
        }
    }
}

impl<R: Lanes, Q: Query<R>> Query<R> for Counting<Q> {
    type Output = (Q::Output, WalkStats);
    const ORDERED: bool = Q::ORDERED;
    #[inline(always)]
    fn cull(&self) -> f32 {
        self.q.cull()
    }
    #[inline(always)]
    fn leaf<P: ShapePack<R>>(&mut self, r: &PackRay<R>, packs: &[Pack<P>], in_order: bool) -> bool {
        self.stats.leaves += 1;
        self.stats.packs += packs.len() as u64;
        self.q.leaf(r, packs, in_order)
    }
    #[inline(always)]
    fn output(&self) -> Self::Output {
        (self.q.output(), self.stats)
    }
    #[inline(always)]
    fn node(&mut self) {
        self.stats.nodes += 1;
    }
}

/// [`Counting`] for any width.
pub(crate) struct CountingKind<K>(std::marker::PhantomData<K>);

impl<K: QueryKind> QueryKind for CountingKind<K> {
    type Output = (K::Output, WalkStats);
    type Q<R: LanesIn> = Counting<K::Q<R>>;
}
