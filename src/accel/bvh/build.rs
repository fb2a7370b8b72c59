//! The build: a tree of 8-wide nodes over primitives of any kind, from
//! their boxes alone.
//!
//! Top-down with the surface area heuristic over 16 bins per axis.
//! Each wide node is made by splitting its largest child (by surface area)
//! until it has eight, or until the heuristic says a leaf is cheaper. A
//! leaf's cost counts whole packs (`ceil(n / lanes)`), so the heuristic
//! fills packs. A leaf holds one kind of primitive: a range the heuristic
//! would leave as a leaf but that mixes kinds is split by kind instead.
//! Subtrees are built in parallel with rayon, and binning of large nodes is
//! parallel too. Past [`SAH_DEPTH_LIMIT`] wide levels (reached only by
//! pathological inputs) the build switches to median splits, which bounds
//! the depth and so the traversal stack.

use super::node::{Child, MAX_KINDS, Node8};
use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use wide::{f32x4, i32x4};

/// Wide levels built with the surface area heuristic before the build falls
/// back to median splits (bounds the depth for pathological inputs).
pub const SAH_DEPTH_LIMIT: u32 = 16;

const BINS: usize = 16;
const _: () = assert!(BINS.is_power_of_two(), "bin_prims masks bin numbers");
/// Nodes with at least this many primitives build their children in
/// parallel.
const PAR_BUILD: usize = 4096;
/// Nodes with at least this many primitives bin in parallel.
const PAR_BIN: usize = 1 << 16;

/// One primitive to build over: its box, its kind, and the index it is
/// reported with (among the primitives of its kind).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildPrim {
    /// Minimum corner of the box (finite).
    pub lo: Vec3,
    /// Maximum corner of the box (finite, `>= lo`).
    pub hi: Vec3,
    /// What it is: its kind's number ([`Kind::KIND`](crate::accel::shape::Kind::KIND)).
    pub kind: u32,
    /// Its index among the primitives of its kind.
    pub index: u32,
}

/// Parameters of the surface area heuristic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildParams {
    /// Primitives per pack (8 or 16): a leaf costs whole packs.
    pub lanes: usize,
    /// Most packs in one leaf.
    pub max_leaf_packs: usize,
    /// Relative cost of testing one node's boxes.
    pub cost_node: f32,
    /// Relative cost of testing one pack.
    pub cost_pack: f32,
    /// The root is an inner node even where one leaf would hold every
    /// primitive, so a walk tests its box (for a tree behind triangles
    /// tested first, whose hit culls that box).
    pub root_node: bool,
    /// Pre-splitting (`presplit`): at most this many extra references
    /// per primitive in all (`0.0`: none, the default; see
    /// [`Bvh::build_shapes_presplit`](super::Bvh::build_shapes_presplit)).
    pub presplit: f32,
}

impl BuildParams {
    /// The parameters used for `lanes`-wide packs.
    pub fn for_lanes(lanes: usize) -> Self {
        Self {
            lanes,
            max_leaf_packs: super::MAX_LEAF_PACKS,
            cost_node: 1.0,
            cost_pack: 1.5,
            root_node: false,
            presplit: 0.0,
        }
    }

    fn max_leaf(&self) -> usize {
        self.lanes * self.max_leaf_packs
    }

    #[inline(always)]
    fn packs(&self, n: usize) -> f32 {
        // A shift for the widths there are (8, 16): the SAH sweep asks
        // this for every bin of every split.
        if self.lanes.is_power_of_two() {
            ((n + self.lanes - 1) >> self.lanes.trailing_zeros()) as f32
        } else {
            n.div_ceil(self.lanes) as f32
        }
    }
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Aabb {
    pub lo: Vec3A,
    pub hi: Vec3A,
}

impl Aabb {
    pub const EMPTY: Self = Self {
        lo: Vec3A::INFINITY,
        hi: Vec3A::NEG_INFINITY,
    };

    #[inline(always)]
    pub fn grow(&mut self, o: &Aabb) {
        self.lo = self.lo.min(o.lo);
        self.hi = self.hi.max(o.hi);
    }

    #[inline(always)]
    pub fn grow_point(&mut self, p: Vec3A) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }

    /// The largest magnitude of its coordinates (at least `1e-30`): the
    /// scale a tree's padding of its boxes ([`PAD`]) is relative to.
    #[inline]
    pub fn extent(&self) -> f32 {
        self.lo.abs().max(self.hi.abs()).max_element().max(1e-30)
    }

    /// Half the surface area (0 for an empty box).
    #[inline(always)]
    pub fn half_area(&self) -> f32 {
        let e = (self.hi - self.lo).max(Vec3A::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

/// A primitive's box, kind and index while building.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prim {
    pub b: Aabb,
    pub index: u32,
    pub kind: u8,
    /// A piece of a pre-split primitive ([`presplit`](super::presplit)):
    /// others may name the same primitive.
    pub piece: bool,
}

impl Prim {
    /// Twice the box's centre.
    #[inline(always)]
    fn centroid2(&self) -> Vec3A {
        self.b.lo + self.b.hi
    }
}

impl From<&BuildPrim> for Prim {
    fn from(p: &BuildPrim) -> Self {
        Prim {
            b: Aabb {
                lo: p.lo.into(),
                hi: p.hi.into(),
            },
            index: p.index,
            kind: p.kind as u8,
            piece: false,
        }
    }
}

/// A contiguous run of prims with its box, centroid box and kinds.
#[derive(Clone, Copy, Debug)]
struct Range {
    start: usize,
    len: usize,
    b: Aabb,
    cb: Aabb,
    /// Bit `k` set: the run holds prims of kind `k`.
    kinds: u8,
    leaf: bool,
}

/// The tree as built, before it is flattened.
enum BuildNode {
    Leaf { start: usize, len: usize },
    Inner(Vec<(Aabb, BuildNode)>),
}

#[derive(Clone, Copy)]
struct Bin {
    b: Aabb,
    n: u32,
}

type Bins = [[Bin; BINS]; 3];

const EMPTY_BINS: Bins = [[Bin {
    b: Aabb::EMPTY,
    n: 0,
}; BINS]; 3];

/// The bin mapping of a centroid box: `bin = (c - lo) * scale`, per axis.
#[derive(Clone, Copy)]
struct Binning {
    lo: Vec3A,
    scale: Vec3A,
}

impl Binning {
    fn new(cb: &Aabb) -> Self {
        let ext = cb.hi - cb.lo;
        let s = |e: f32| {
            if e > 0.0 && e.is_finite() {
                BINS as f32 * 0.999_99 / e
            } else {
                0.0
            }
        };
        Self {
            lo: cb.lo,
            scale: Vec3A::new(s(ext.x), s(ext.y), s(ext.z)),
        }
    }

    #[inline(always)]
    fn bins(&self, c: Vec3A) -> [usize; 3] {
        let b = ((c - self.lo) * self.scale).min(Vec3A::splat((BINS - 1) as f32));
        // Truncated four lanes at once, negatives then raised to 0: what
        // `as usize` gives each lane (a NaN lane is 15 after `min`), without
        // its saturating casts' branches, which were a third of the build.
        let k = f32x4::from(b.extend(0.0).to_array())
            .trunc_int()
            .max(i32x4::ZERO)
            .to_array();
        [k[0] as usize, k[1] as usize, k[2] as usize]
    }
}

fn bin_prims(prims: &[Prim], binning: &Binning) -> Bins {
    let mut bins = EMPTY_BINS;
    for p in prims {
        let k = binning.bins(p.centroid2());
        for a in 0..3 {
            // `k[a] < BINS` already; the mask drops the bounds check.
            let bin = &mut bins[a][k[a] & (BINS - 1)];
            bin.b.grow(&p.b);
            bin.n += 1;
        }
    }
    bins
}

fn merge_bins(mut a: Bins, b: Bins) -> Bins {
    for (x, y) in a.iter_mut().zip(b.iter()) {
        for (p, q) in x.iter_mut().zip(y.iter()) {
            p.b.grow(&q.b);
            p.n += q.n;
        }
    }
    a
}

/// The best SAH split of `prims`: (axis, last bin on the left, cost of the
/// two sides as `area · packs`).
fn find_sah_split(prims: &[Prim], cb: &Aabb, params: &BuildParams) -> Option<(usize, usize, f32)> {
    let binning = Binning::new(cb);
    if binning.scale == Vec3A::ZERO {
        return None;
    }
    let bins = if prims.len() >= PAR_BIN {
        prims
            .par_chunks(PAR_BIN / 4)
            .map(|c| bin_prims(c, &binning))
            .reduce(|| EMPTY_BINS, merge_bins)
    } else {
        bin_prims(prims, &binning)
    };
    let mut best: Option<(usize, usize, f32)> = None;
    for (a, bins) in bins.iter().enumerate() {
        if binning.scale[a] == 0.0 {
            continue;
        }
        // Right sides, from the right: right_cost[i] covers bins i+1.. .
        let mut right_cost = [0.0f32; BINS];
        let mut right_n = [0usize; BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for i in (1..BINS).rev() {
            acc.grow(&bins[i].b);
            n += bins[i].n as usize;
            right_cost[i - 1] = acc.half_area() * params.packs(n);
            right_n[i - 1] = n;
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for i in 0..BINS - 1 {
            acc.grow(&bins[i].b);
            n += bins[i].n as usize;
            if n == 0 || right_n[i] == 0 {
                continue;
            }
            let cost = acc.half_area() * params.packs(n) + right_cost[i];
            if best.is_none_or(|b| cost < b.2) {
                best = Some((a, i, cost));
            }
        }
    }
    best
}

/// Split `r` (whose prims are `prims`) in two, or `None` if it should be a
/// leaf. `median` forces balanced median splits. A run that should be a
/// leaf but holds several kinds is split by kind.
fn split(
    prims: &mut [Prim],
    r: &Range,
    median: bool,
    params: &BuildParams,
) -> Option<(Range, Range)> {
    let leaf = |prims: &mut [Prim]| {
        if r.kinds.count_ones() > 1 {
            let kind = r.kinds.trailing_zeros() as u8;
            Some(partition(prims, r, |p| p.kind == kind))
        } else {
            None
        }
    };
    let n = prims.len();
    if n <= 1 {
        return leaf(prims);
    }
    let max_leaf = params.max_leaf();
    if !median {
        if let Some((axis, bin, cost)) = find_sah_split(prims, &r.cb, params) {
            let area = r.b.half_area();
            let leaf_cost = params.cost_pack * area * params.packs(n);
            let split_cost = params.cost_node * area + params.cost_pack * cost;
            if n <= max_leaf && split_cost >= leaf_cost {
                return leaf(prims);
            }
            let binning = Binning::new(&r.cb);
            return Some(partition(prims, r, |p| {
                binning.bins(p.centroid2())[axis] <= bin
            }));
        }
        if n <= max_leaf {
            return leaf(prims);
        }
    } else if n <= max_leaf {
        return leaf(prims);
    }
    // All centroids in one point, or too deep: split at the median of the
    // widest centroid axis.
    let ext = r.cb.hi - r.cb.lo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = n / 2;
    prims.select_nth_unstable_by(mid, |a, b| {
        a.centroid2()[axis].total_cmp(&b.centroid2()[axis])
    });
    Some(sides(prims, r, mid))
}

/// The box, centroid box and kinds of `prims`, as a range at `start`.
fn range_of(start: usize, prims: &[Prim]) -> Range {
    let (mut b, mut cb, mut kinds) = (Aabb::EMPTY, Aabb::EMPTY, 0u8);
    for p in prims {
        b.grow(&p.b);
        cb.grow_point(p.centroid2());
        kinds |= 1 << p.kind;
    }
    Range {
        start,
        len: prims.len(),
        b,
        cb,
        kinds,
        leaf: false,
    }
}

/// In-place partition of `r`'s prims: those with `left(p)` first. Returns
/// the two sides with their boxes and centroid boxes, computed on the way.
fn partition(prims: &mut [Prim], r: &Range, left: impl Fn(&Prim) -> bool) -> (Range, Range) {
    let (mut lb, mut lcb, mut rb, mut rcb) = (Aabb::EMPTY, Aabb::EMPTY, Aabb::EMPTY, Aabb::EMPTY);
    let (mut lk, mut rk) = (0u8, 0u8);
    let (mut i, mut j) = (0, prims.len());
    while i < j {
        let p = prims[i];
        if left(&p) {
            lb.grow(&p.b);
            lcb.grow_point(p.centroid2());
            lk |= 1 << p.kind;
            i += 1;
        } else {
            // `p` is on the right for good; what comes to `i` is tested next.
            j -= 1;
            rb.grow(&p.b);
            rcb.grow_point(p.centroid2());
            rk |= 1 << p.kind;
            prims.swap(i, j);
        }
    }
    (
        Range {
            start: r.start,
            len: i,
            b: lb,
            cb: lcb,
            kinds: lk,
            leaf: false,
        },
        Range {
            start: r.start + i,
            len: prims.len() - i,
            b: rb,
            cb: rcb,
            kinds: rk,
            leaf: false,
        },
    )
}

/// The two ranges of `r` split at `mid`, with their boxes.
fn sides(prims: &[Prim], r: &Range, mid: usize) -> (Range, Range) {
    let (l, rr) = prims.split_at(mid);
    (range_of(r.start, l), range_of(r.start + mid, rr))
}

/// Build the subtree over `prims`, which start at `base` in the full list.
fn build_node(
    prims: &mut [Prim],
    base: usize,
    whole: Range,
    depth: u32,
    params: &BuildParams,
) -> BuildNode {
    if depth == 0
        && !params.root_node
        && whole.len <= params.max_leaf()
        && whole.kinds.count_ones() == 1
    {
        // A scene that fits in one leaf is one, its prims in index order:
        // testing all its packs beats any node in front of them (measured
        // on the 32-triangle Cornell box: a node's test and the ray's set-up
        // for box tests cost more than the packs they cull).
        prims.sort_unstable_by_key(|p| p.index);
        return BuildNode::Leaf {
            start: base,
            len: whole.len,
        };
    }
    let median = depth >= SAH_DEPTH_LIMIT;
    let mut kids = vec![Range { start: 0, ..whole }];
    while kids.len() < 8 {
        // Split the open child with the largest box (most prims when
        // splitting at medians).
        let pick = kids
            .iter()
            .enumerate()
            .filter(|(_, k)| !k.leaf)
            .max_by(|(_, a), (_, b)| {
                if median {
                    a.len.cmp(&b.len)
                } else {
                    a.b.half_area().total_cmp(&b.b.half_area())
                }
            })
            .map(|(i, _)| i);
        let Some(i) = pick else { break };
        let k = kids[i];
        match split(&mut prims[k.start..k.start + k.len], &k, median, params) {
            Some((l, r)) => {
                kids[i] = l;
                kids.push(r);
            }
            None => kids[i].leaf = true,
        }
    }
    if kids.len() == 1 && kids[0].leaf && !(depth == 0 && params.root_node) {
        return BuildNode::Leaf {
            start: base,
            len: prims.len(),
        };
    }
    kids.sort_by_key(|k| k.start);
    // Disjoint slices for the children, in order.
    let mut slices = Vec::with_capacity(kids.len());
    let mut rest = prims;
    for k in &kids {
        let (s, r) = rest.split_at_mut(k.len);
        slices.push((s, *k));
        rest = r;
    }
    let child = |(s, k): (&mut [Prim], Range)| {
        let node = if k.leaf {
            BuildNode::Leaf {
                start: base + k.start,
                len: k.len,
            }
        } else {
            build_node(
                s,
                base + k.start,
                Range { start: 0, ..k },
                depth + 1,
                params,
            )
        };
        (k.b, node)
    };
    let children = if whole.len >= PAR_BUILD {
        slices.into_par_iter().map(child).collect()
    } else {
        slices.into_iter().map(child).collect()
    };
    BuildNode::Inner(children)
}

/// A leaf: a run of the reordered prims (all of one kind) and where its
/// packs start in that kind's pack list.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LeafRun {
    pub kind: u32,
    pub start: usize,
    pub len: usize,
    pub first_pack: usize,
}

/// A built tree: flattened nodes whose leaf references point into each
/// kind's pack list, and what each leaf holds.
pub(crate) struct Topology {
    pub nodes: Vec<Node8>,
    pub root: Child,
    /// The prims, reordered so that each leaf's are contiguous.
    pub prims: Vec<Prim>,
    pub leaves: Vec<LeafRun>,
    /// Packs per kind.
    pub pack_counts: [usize; MAX_KINDS],
}

/// Boxes are padded by this share of the largest coordinate (see
/// [`build`]).
pub(crate) const PAD: f32 = 1.0 / 32768.0;

/// Build the tree over `prims` (finite boxes) with the current rayon pool.
///
/// Boxes are padded on every side, when they go into the nodes, by `2^-15`
/// of the largest coordinate: that covers rounding in the box test and in
/// the primitives' kernels.
pub(crate) fn build(prims: Vec<Prim>, params: &BuildParams) -> Topology {
    let mut prims = prims;
    let whole = prims
        .par_chunks(PAR_BIN / 4)
        .map(|c| range_of(0, c))
        .reduce(
            || range_of(0, &[]),
            |mut x, y| {
                x.b.grow(&y.b);
                x.cb.grow(&y.cb);
                x.kinds |= y.kinds;
                x.len += y.len;
                x
            },
        );
    let extent = if prims.is_empty() {
        1.0
    } else {
        whole.b.extent()
    };
    let pad = Vec3A::splat(extent * PAD);
    let mut tree = (!prims.is_empty()).then(|| build_node(&mut prims, 0, whole, 0, params));
    if let Some(t) = &mut tree
        && params.presplit > 0.0
    {
        dedup_leaves(t, &mut prims);
    }
    let mut topo = Topology {
        nodes: Vec::new(),
        root: Child::EMPTY,
        prims: Vec::new(),
        leaves: Vec::new(),
        pack_counts: [0; MAX_KINDS],
    };
    if let Some(t) = &tree {
        topo.root = flatten(t, pad, &prims, params, &mut topo);
    }
    topo.prims = prims;
    topo
}

/// Keep one reference per primitive in each leaf: pieces of one
/// pre-split primitive that the build put in the same leaf would fill
/// lanes with the same test. The leaf's other references keep their
/// order; its run shortens (the slots after it are left unused).
fn dedup_leaves(t: &mut BuildNode, prims: &mut [Prim]) {
    match t {
        BuildNode::Leaf { start, len } => {
            let run = &mut prims[*start..*start + *len];
            if run.iter().filter(|p| p.piece).count() < 2 {
                return;
            }
            let mut kept = 0;
            for i in 0..run.len() {
                let p = run[i];
                let seen = || run[..kept].iter().any(|q| q.piece && q.index == p.index);
                if !p.piece || !seen() {
                    run[kept] = p;
                    kept += 1;
                }
            }
            *len = kept;
        }
        BuildNode::Inner(children) => {
            for (_, c) in children {
                dedup_leaves(c, prims);
            }
        }
    }
}

/// Append `t`'s nodes (depth first) and leaves to `topo`; returns its child
/// reference.
fn flatten(
    t: &BuildNode,
    pad: Vec3A,
    prims: &[Prim],
    params: &BuildParams,
    topo: &mut Topology,
) -> Child {
    match t {
        BuildNode::Leaf { start, len } => {
            let kind = prims[*start].kind as u32;
            let n = len.div_ceil(params.lanes);
            debug_assert!((1..=params.max_leaf_packs).contains(&n));
            let first_pack = topo.pack_counts[kind as usize];
            topo.leaves.push(LeafRun {
                kind,
                start: *start,
                len: *len,
                first_pack,
            });
            topo.pack_counts[kind as usize] += n;
            Child::leaf(kind, first_pack, n)
        }
        BuildNode::Inner(children) => {
            let me = topo.nodes.len();
            topo.nodes.push(Node8::EMPTY);
            let mut lo = [[f32::INFINITY; 8]; 3];
            let mut hi = [[f32::NEG_INFINITY; 8]; 3];
            let mut child = [Child::EMPTY; 8];
            for (i, (b, c)) in children.iter().enumerate() {
                for a in 0..3 {
                    lo[a][i] = b.lo[a] - pad[a];
                    hi[a][i] = b.hi[a] + pad[a];
                }
                child[i] = flatten(c, pad, prims, params, topo);
            }
            topo.nodes[me] = Node8::new(lo, hi, child);
            Child::node(me)
        }
    }
}
