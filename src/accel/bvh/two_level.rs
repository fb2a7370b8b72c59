//! Instancing: a two-level hierarchy, for scenes that place one mesh many
//! times. The bottom level is one [`Bvh`] per unique mesh, in the mesh's
//! own (object) space, plus one over the primitives that belong to no
//! placed mesh, in world space (the *rest*); the top level is a binary
//! tree over the placements' world boxes. Memory and build time go with
//! the unique triangles and the number of placements, not with the
//! triangles placed.
//!
//! # Primitive indices
//!
//! A hit names the same primitive the flattened scene has: placement `p`
//! of a mesh reports its triangle `j` as `p.base + j` (the flattened
//! triangles of a placement are consecutive, in the mesh's order), and the
//! rest's primitive `k` as `ids[k]` (its global indices, increasing). Both
//! maps keep the order of indices, so the smallest `(t, local index)` of a
//! bottom tree is the smallest `(t, global index)` among its primitives,
//! and the closest hit over the placements is the smallest
//! `(t, global index)` pair, whatever order the top level visits them in.
//!
//! # The ray in object space
//!
//! A placement's ray is `M⁻¹ o + t · M⁻¹ d` (`M` its object-to-world
//! transform; the direction is not normalised), so `t` is the same
//! parameter in both spaces and hits from different placements compare
//! directly. The arithmetic differs from the flattened triangles' (the
//! transform rounds), so a `t` agrees with the flattened one to a few
//! ulps, not bit for bit, and a ray through a shared edge can name the
//! other triangle of the edge (`tests/instancing.rs` states the
//! tolerance). The rest has no transform: its hits are the flattened
//! ones, bit for bit.

use super::{Bvh, BvhOptions};
use crate::accel::hit::{Hit, HitFilter, NO_PRIM};
use glam::{Affine3A, Vec3, Vec3A};

/// A leaf of the top level holds at most this many placements.
const LEAF_SIZE: usize = 2;

/// One bottom-level tree and how its primitive indices become global.
#[derive(Clone, Debug)]
struct Bottom {
    bvh: Bvh,
    /// The global index of each primitive; empty where it is `base + j`.
    ids: Vec<u32>,
}

/// One entry of the top level: a placement of a mesh, or the rest.
#[derive(Clone, Copy, Debug)]
struct Entry {
    /// World to object (`None`: the rest, in world space).
    to_object: Option<Affine3A>,
    /// Index into [`TwoLevel::bottoms`].
    bottom: u32,
    /// The global index of the bottom's primitive 0 (where it has no
    /// `ids`)…
    base: u32,
    /// …and the run of [`TwoLevel::remaps`] that says where the others
    /// are not `base + j` (start, length).
    remap: (u32, u32),
    /// The world box (padded).
    lo: Vec3,
    hi: Vec3,
}

/// A node of the top level: a box and either two children (`count == 0`:
/// nodes `start` and `start + 1`) or a run of `count` entries from
/// `start`.
#[derive(Clone, Copy, Debug)]
struct TopNode {
    lo: Vec3,
    hi: Vec3,
    start: u32,
    count: u32,
}

/// What the two-level hierarchy is built from.
#[derive(Clone, Debug, Default)]
pub struct Placements<'a> {
    /// Each unique mesh's triangles in its own space.
    pub meshes: Vec<Vec<crate::accel::triangle::TriangleEdges>>,
    /// The placements of the meshes.
    pub instances: Vec<Placed<'a>>,
    /// The primitives of no placement, in world space, and their global
    /// indices (increasing), or `None`.
    pub rest: Option<(crate::accel::shape::Shapes<'a>, Vec<u32>)>,
}

/// One placement of a mesh.
#[derive(Clone, Copy, Debug)]
pub struct Placed<'a> {
    /// Index into [`Placements::meshes`].
    pub mesh: u32,
    /// Object to world.
    pub to_world: Affine3A,
    /// The global index of the mesh's triangle 0…
    pub first: u32,
    /// …and where the others are not `first + j`
    /// ([`PlacedMesh::remap`](crate::scene::PlacedMesh::remap); empty
    /// where they all are).
    pub remap: &'a [(u32, u32)],
}

/// The two-level hierarchy (see the module documentation).
#[derive(Clone, Debug)]
pub struct TwoLevel {
    bottoms: Vec<Bottom>,
    /// The placements' remaps, one run each ([`Entry::remap`]).
    remaps: Vec<(u32, u32)>,
    /// The rest, tested by every ray before the top level.
    rest: Option<Entry>,
    entries: Vec<Entry>,
    nodes: Vec<TopNode>,
}

/// `box` padded by `2^-15` of its largest coordinate (and of its
/// extent), against the rounding of the slab test and of the transform.
fn padded(lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    let m = lo
        .abs()
        .max(hi.abs())
        .max_element()
        .max((hi - lo).max_element());
    let pad = Vec3::splat(m * (1.0 / 32768.0) + f32::MIN_POSITIVE);
    (lo - pad, hi + pad)
}

/// The world box of `to_world` applied to the box `(lo, hi)`: its eight
/// corners' box.
fn world_box(to_world: &Affine3A, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    let mut wlo = Vec3::splat(f32::INFINITY);
    let mut whi = Vec3::splat(f32::NEG_INFINITY);
    for k in 0..8 {
        let c = Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let w = to_world.transform_point3(c);
        wlo = wlo.min(w);
        whi = whi.max(w);
    }
    (wlo, whi)
}

/// The box of a list of triangles, or `None` where it has no finite one.
fn triangles_box(tris: &[crate::accel::triangle::TriangleEdges]) -> Option<(Vec3, Vec3)> {
    let mut lo = Vec3A::splat(f32::INFINITY);
    let mut hi = Vec3A::splat(f32::NEG_INFINITY);
    for t in tris {
        use crate::accel::shape::Shape;
        let (l, h) = t.bounds()?;
        lo = lo.min(l);
        hi = hi.max(h);
    }
    (lo.x <= hi.x).then(|| (lo.into(), hi.into()))
}

impl TwoLevel {
    /// Builds the two levels from `placements` at the width of `options`
    /// (the bottom trees in parallel on the current rayon pool). `None`
    /// where a mesh has a primitive with no finite box or a transform does
    /// not invert (the caller traces the scene flattened).
    pub fn build(placements: &Placements<'_>, options: &BvhOptions) -> Option<TwoLevel> {
        use rayon::prelude::*;
        let boxes: Vec<(Vec3, Vec3)> = (placements.meshes.iter())
            .map(|m| triangles_box(m))
            .collect::<Option<_>>()?;
        let mut bottoms: Vec<Bottom> = (placements.meshes.par_iter())
            .map(|m| Bottom {
                bvh: Bvh::build_with(m, options),
                ids: Vec::new(),
            })
            .collect();
        let mut entries = Vec::with_capacity(placements.instances.len() + 1);
        let mut remaps = Vec::new();
        for p in &placements.instances {
            let (mesh, to_world) = (p.mesh, p.to_world);
            let remap = (remaps.len() as u32, p.remap.len() as u32);
            remaps.extend_from_slice(p.remap);
            let inverse = to_world.inverse();
            if !(inverse.is_finite() && to_world.is_finite()) {
                return None;
            }
            let (lo, hi) = boxes[mesh as usize];
            let (lo, hi) = padded_world(&to_world, lo, hi)?;
            entries.push(Entry {
                to_object: Some(inverse),
                bottom: mesh,
                base: p.first,
                remap,
                lo,
                hi,
            });
        }
        let rest = placements.rest.as_ref().map(|(shapes, ids)| {
            bottoms.push(Bottom {
                bvh: Bvh::build_shapes(shapes, options),
                ids: ids.clone(),
            });
            Entry {
                to_object: None,
                bottom: (bottoms.len() - 1) as u32,
                base: 0,
                remap: (0, 0),
                lo: Vec3::splat(f32::NEG_INFINITY),
                hi: Vec3::splat(f32::INFINITY),
            }
        });
        let mut order: Vec<u32> = (0..entries.len() as u32).collect();
        let mut nodes = vec![TopNode {
            lo: Vec3::ZERO,
            hi: Vec3::ZERO,
            start: 0,
            count: 0,
        }];
        build_top(&entries, &mut order, 0, &mut nodes, 0);
        let entries = order.iter().map(|&k| entries[k as usize]).collect();
        Some(TwoLevel {
            bottoms,
            remaps,
            rest,
            entries,
            nodes,
        })
    }

    /// The closest hit of `o + t·d`, `t_min < t < t_max`: `(t, global
    /// index)`, or `(t_max, NO_PRIM)` where none.
    pub fn closest(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> (f32, u32) {
        self.closest_by(o, d, t_min, t_max, |_, bvh, (oo, dd), limit| {
            bvh.closest_hit(oo, dd, t_min, limit)
        })
    }

    /// [`TwoLevel::closest`] among the hits that `filter` (of global
    /// primitive indices) does not let through
    /// ([`Bvh::closest_hit_filtered`]): each bottom tree is walked with
    /// the filter, its local indices made global. A primitive left out
    /// of the flattened scene passes.
    pub fn closest_filtered<F: HitFilter>(
        &self,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        t_max: f32,
        filter: &F,
    ) -> (f32, u32) {
        self.closest_by(o, d, t_min, t_max, |e, bvh, (oo, dd), limit| {
            let mapped = Mapped {
                two: self,
                e,
                filter,
            };
            bvh.tree_closest_filtered(oo, dd, (t_min, limit), &mapped)
        })
    }

    /// The closest hit over the placements, `cast(entry, bottom tree,
    /// ray in its space, limit)` finding each bottom tree's.
    #[inline(always)]
    fn closest_by(
        &self,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        t_max: f32,
        cast: impl Fn(&Entry, &Bvh, (Vec3, Vec3), f32) -> Option<Hit>,
    ) -> (f32, u32) {
        let mut best = (t_max, NO_PRIM);
        self.walk(o, d, t_min, t_max, |e, best_t| {
            // Up to and including the best t so far: a lower index at the
            // same t wins.
            let limit = if best.1 == NO_PRIM {
                t_max
            } else {
                best.0.next_up()
            };
            let bottom = &self.bottoms[e.bottom as usize];
            if let Some(h) = cast(e, &bottom.bvh, e.ray(o, d), limit)
                && let Some(g) = self.global(e, h.triangle)
                && (h.t < best.0 || (h.t == best.0 && g < best.1))
            {
                best = (h.t, g);
            }
            *best_t = best.0;
            false
        });
        best
    }

    /// Whether anything lies on `o + t·d`, `t_min < t < t_max`.
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        self.occluded_by(o, d, t_min, t_max, |_, bvh, (oo, dd)| {
            bvh.occluded(oo, dd, t_min, t_max)
        })
    }

    /// [`TwoLevel::occluded`] among the hits that `filter` does not let
    /// through (as [`TwoLevel::closest_filtered`]).
    pub fn occluded_filtered<F: HitFilter>(
        &self,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        t_max: f32,
        filter: &F,
    ) -> bool {
        self.occluded_by(o, d, t_min, t_max, |e, bvh, (oo, dd)| {
            let mapped = Mapped {
                two: self,
                e,
                filter,
            };
            bvh.tree_occluded_filtered(oo, dd, (t_min, t_max), &mapped)
        })
    }

    /// Whether some bottom tree's `test(entry, tree, ray in its space)`
    /// finds the segment blocked.
    #[inline(always)]
    fn occluded_by(
        &self,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        t_max: f32,
        test: impl Fn(&Entry, &Bvh, (Vec3, Vec3)) -> bool,
    ) -> bool {
        let mut hit = false;
        self.walk(o, d, t_min, t_max, |e, _| {
            hit = test(e, &self.bottoms[e.bottom as usize].bvh, e.ray(o, d));
            hit
        });
        hit
    }

    /// The top-level walk: every entry whose box the ray enters at or
    /// before the best `t` so far (which `visit(entry, &mut best_t)`
    /// keeps), nearer child first; stops where `visit` returns true.
    #[inline(always)]
    fn walk(
        &self,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        t_max: f32,
        mut visit: impl FnMut(&Entry, &mut f32) -> bool,
    ) {
        let inv = d.recip();
        let mut best_t = t_max;
        if let Some(rest) = &self.rest
            && visit(rest, &mut best_t)
        {
            return;
        }
        if self.entries.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let Some(enter) = slab(o, inv, n.lo, n.hi, t_min, best_t) else {
                continue;
            };
            if enter > best_t {
                continue;
            }
            if n.count == 0 {
                // Push the farther child first (by the entry into each).
                let (a, b) = (n.start, n.start + 1);
                let ta = self.entry_t(a, o, inv, t_min, best_t);
                let tb = self.entry_t(b, o, inv, t_min, best_t);
                let (near, far) = if tb < ta { (b, a) } else { (a, b) };
                if top + 2 > stack.len() {
                    // Deeper than any tree of at most 2^32 entries.
                    unreachable!("top-level stack overflow");
                }
                stack[top] = far;
                stack[top + 1] = near;
                top += 2;
                continue;
            }
            for e in &self.entries[n.start as usize..(n.start + n.count) as usize] {
                if slab(o, inv, e.lo, e.hi, t_min, best_t).is_some() && visit(e, &mut best_t) {
                    return;
                }
            }
        }
    }

    /// Where the ray enters node `k`'s box (infinity where it misses).
    #[inline(always)]
    fn entry_t(&self, k: u32, o: Vec3, inv: Vec3, t_min: f32, t_max: f32) -> f32 {
        let n = &self.nodes[k as usize];
        slab(o, inv, n.lo, n.hi, t_min, t_max).unwrap_or(f32::INFINITY)
    }

    /// Memory held: the bottom trees, their index maps, the entries and
    /// the top nodes, in bytes.
    pub fn bytes(&self) -> usize {
        let bottoms: usize = (self.bottoms.iter())
            .map(|b| b.bvh.bytes() + b.ids.len() * 4)
            .sum();
        bottoms
            + self.remaps.len() * 8
            + self.entries.len() * size_of::<Entry>()
            + self.nodes.len() * size_of::<TopNode>()
    }

    /// Number of placements.
    pub fn instance_count(&self) -> usize {
        self.entries.len()
    }

    /// Nodes of every tree: the top level's and the bottom trees'.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
            + self
                .bottoms
                .iter()
                .map(|b| b.bvh.node_count())
                .sum::<usize>()
    }

    /// Primitives in the bottom trees (each unique mesh once, and the rest).
    pub fn bottom_prim_count(&self) -> usize {
        self.bottoms.iter().map(|b| b.bvh.prim_count()).sum()
    }
}

/// A filter of global primitive indices, asked about a bottom tree's
/// local ones (as placement `e` places them).
struct Mapped<'a, F> {
    two: &'a TwoLevel,
    e: &'a Entry,
    filter: &'a F,
}

impl<F: HitFilter> HitFilter for Mapped<'_, F> {
    #[inline]
    fn may_pass(&self, local: u32) -> bool {
        (self.two.global(self.e, local)).is_none_or(|g| self.filter.may_pass(g))
    }
    #[inline]
    fn passes(&self, local: u32, t: f32) -> bool {
        (self.two.global(self.e, local)).is_none_or(|g| self.filter.passes(g, t))
    }
}

impl Entry {
    /// The ray in this entry's space.
    #[inline(always)]
    fn ray(&self, o: Vec3, d: Vec3) -> (Vec3, Vec3) {
        match &self.to_object {
            Some(m) => (m.transform_point3(o), m.transform_vector3(d)),
            None => (o, d),
        }
    }
}

impl TwoLevel {
    /// The global index of primitive `local` of entry `e`'s bottom tree, or
    /// `None` where the flattening left it out (a sliver of no area in
    /// world space: the hit is ignored, as the flattened scene has no
    /// such triangle; one behind it in the same placement is then not
    /// found, which no ray of nonzero width could tell).
    #[inline(always)]
    fn global(&self, e: &Entry, local: u32) -> Option<u32> {
        let bottom = &self.bottoms[e.bottom as usize];
        if !bottom.ids.is_empty() {
            return Some(bottom.ids[local as usize]);
        }
        if e.remap.1 == 0 {
            return Some(e.base + local);
        }
        let (start, len) = (e.remap.0 as usize, e.remap.1 as usize);
        crate::scene::global_of(e.base, &self.remaps[start..start + len], local)
    }
}

/// The padded world box of a mesh of object box `(lo, hi)` placed by
/// `to_world`, or `None` where it is not finite.
fn padded_world(to_world: &Affine3A, lo: Vec3, hi: Vec3) -> Option<(Vec3, Vec3)> {
    let (lo, hi) = padded(lo, hi);
    let (lo, hi) = world_box(to_world, lo, hi);
    let (lo, hi) = padded(lo, hi);
    (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
}

/// Where the ray `o + t·d` (`inv = 1/d`) enters the box `(lo, hi)` within
/// `[t_min, t_max]`, or `None`. An axis along which `0 · ∞` makes a NaN is
/// left unconstrained (conservative).
#[inline(always)]
fn slab(o: Vec3, inv: Vec3, lo: Vec3, hi: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
    let a = (lo - o) * inv;
    let b = (hi - o) * inv;
    let near = a.min(b);
    let far = a.max(b);
    // `f32::max`/`min` ignore a NaN operand.
    let enter = t_min.max(near.x).max(near.y).max(near.z);
    let exit = t_max.min(far.x).min(far.y).min(far.z);
    (enter <= exit).then_some(enter)
}

/// Builds the top level over `order[..]` (indices into `entries`) into
/// node `at` of `nodes`; `first` is where `order` starts among all
/// entries. Splits at the median of the boxes' centres along the longest
/// axis of their spread.
fn build_top(
    entries: &[Entry],
    order: &mut [u32],
    first: u32,
    nodes: &mut Vec<TopNode>,
    at: usize,
) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    let mut clo = lo;
    let mut chi = hi;
    for &k in order.iter() {
        let e = &entries[k as usize];
        lo = lo.min(e.lo);
        hi = hi.max(e.hi);
        let c = centre(e);
        clo = clo.min(c);
        chi = chi.max(c);
    }
    if order.len() <= LEAF_SIZE {
        nodes[at] = TopNode {
            lo,
            hi,
            start: first,
            count: order.len() as u32,
        };
        return;
    }
    let spread = chi - clo;
    let axis = if spread.x >= spread.y && spread.x >= spread.z {
        0
    } else if spread.y >= spread.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |a, b| {
        let ca = centre(&entries[*a as usize])[axis];
        let cb = centre(&entries[*b as usize])[axis];
        ca.total_cmp(&cb).then(a.cmp(b))
    });
    let children = nodes.len();
    nodes.push(nodes[at]);
    nodes.push(nodes[at]);
    nodes[at] = TopNode {
        lo,
        hi,
        start: children as u32,
        count: 0,
    };
    let (left, right) = order.split_at_mut(mid);
    build_top(entries, left, first, nodes, children);
    build_top(entries, right, first + mid as u32, nodes, children + 1);
}

/// The centre of an entry's box.
fn centre(e: &Entry) -> Vec3 {
    (e.lo + e.hi) * 0.5
}
