//! A bounding volume hierarchy with 8-wide nodes and leaves of primitive
//! packs, answering closest-hit and any-hit (occlusion) queries.
//!
//! # Layout
//!
//! Every inner node holds the boxes of up to eight children in
//! structure-of-arrays form, so one ray is tested against all eight boxes
//! with a handful of AVX2 instructions. A child reference is a node, a
//! leaf, or nothing; a leaf's reference carries its primitive kind (its
//! number, [`Kind::KIND`]) and its run of
//! 1 to [`MAX_LEAF_PACKS`] packs in that kind's pack list. Every kind
//! ([`Shape`]) comes in packs of 8 or 16 ([`SimdWidth`]), tested by its own
//! kernel ([`ShapePack`](crate::accel::shape::ShapePack)): triangles by
//! the very SoA packs and Möller–Trumbore kernel of
//! [`closest_hit_packs`](crate::accel::triangle::closest_hit_packs),
//! analytic spheres by the robust kernel
//! [`intersect_sphere`](crate::accel::sphere::intersect_sphere).
//!
//! # Primitive indices
//!
//! [`Bvh::build_shapes`] takes the primitives of every kind ([`Shapes`]);
//! a hit names one primitive by one global index, the kinds one after the
//! other in the order of [`Kinds`]: triangle `i` is `i`, sphere `j` is
//! `T + j` (`T` the number of triangles). [`Hit::triangle`] holds that
//! index; with triangles alone it is the triangle's own index, as ever.
//!
//! # Build
//!
//! [`build`]: binned SAH over the primitives' boxes, whatever their kind
//! ([`BuildPrim`]); then each leaf's primitives are packed by their kind.
//! The hierarchy knows no kind by name: it keeps one [`Kinds`] of pack
//! lists, fills it through [`Shape`] (`bounds`, `pack`), and the walk
//! hands a leaf to its query by the leaf's kind number
//! ([`Kinds::by_kind`]), so every query handles every kind with one body.
//! Optionally ([`Bvh::build_shapes_presplit`], not the default) long thin
//! triangles first go in as several references, each the box of the
//! triangle's part in a region (`presplit`, by a counted budget); a leaf
//! keeps one reference per primitive.
//! (Triangles have two extras of their own, for small scenes: occluders
//! tested first, and ray packets: `small`, `packet`.)
//!
//! # Queries
//!
//! One walk (`walk`) serves every query: it tests a node's boxes, visits
//! the children the ray enters (nearest first for closest hits), and hands
//! each leaf to the query, which keeps the closest hit ([`Bvh::closest_hit`],
//! [`Bvh::closest_hits`]) or stops at the first ([`Bvh::occluded`],
//! [`Bvh::occluded_batch`]). Batches of rays walk interleaved on large
//! trees, with prefetches, so memory latency overlaps. The filtered
//! queries ([`Bvh::closest_hit_filtered`], [`Bvh::occluded_filtered`] and
//! their columns) hand each candidate hit on a primitive that may let the
//! ray through to an any-hit filter ([`HitFilter`]) before it counts:
//! alpha-tested surfaces, without the walk knowing what they are.
//!
//! # Exactness
//!
//! The closest hit is the lexicographic minimum of `(t, primitive index)`
//! ([`crate::accel::triangle`]), across kinds: a leaf's lanes keep their
//! own minimum (the same lanes whatever the leaf's kind) and
//! the answer is reduced at the end, so the order in which leaves are
//! visited does not matter, nor the width of the packs (each lane does the
//! same IEEE operations at either width). A child is skipped only when its
//! box starts strictly beyond the best `t` so far (ties are visited, the
//! lower index may be there). Boxes are padded by a small absolute margin
//! (`2^-15` of the scene's largest coordinate) so that rounding in the box
//! test or in Möller–Trumbore cannot cull a triangle that the kernel would
//! report, and a sphere's box (center ± radius) is likewise padded against
//! the sphere kernel's rounding. A pre-split triangle's references have
//! boxes that each contain the triangle's part in their region, computed
//! conservatively and within the triangle's own box, and together cover
//! the whole triangle: every point the kernel could report lies in one
//! of them, padded as a whole triangle's box would be; a ray that meets
//! the triangle through two references gets the same `(t, index)` twice,
//! which leaves the minimum as it is, and an any-hit filter is asked the
//! same question twice (it is a function of the primitive and `t`), so
//! it answers the same. The result is the same primitive and the
//! same `t` bits as
//! [`closest_hit_brute_force`](crate::accel::triangle::closest_hit_brute_force)
//! (triangles only) or
//! [`closest_hit_brute_force_prims`](crate::accel::sphere::closest_hit_brute_force_prims)
//! (triangles and spheres), and a ray is occluded exactly when that closest
//! hit is closer than the segment's end. (A ray that grazes a triangle almost in its plane gets a
//! `t` whose rounding error grows as 1/sin of the angle; were that error
//! ever larger than the padding and the culling slack, the two could
//! differ. The tests fire millions of random rays, grazing ones included,
//! without finding one. A ray grazing a sphere has a `t` off by up to
//! `r·sqrt(2ε|o - c|/r)` near the tangent point, but that point lies well
//! inside the sphere's box, at least `0.4 r` along the ray past where the
//! ray enters it.)

pub mod build;
mod node;
mod packet;
mod presplit;
mod small;
mod two_level;
mod walk;

pub use build::{BuildParams, BuildPrim, SAH_DEPTH_LIMIT};
pub use node::MAX_KINDS;
pub use presplit::MAX_PIECES;
pub use two_level::{Placed, Placements, TwoLevel};
pub use walk::{BATCH, WalkStats};

use crate::accel::hit::HitFilter;
use crate::accel::shape::{Family, Kind, Kinds, Make, Shape, Shapes, Slices, Visit, first_of};
use crate::accel::simd::{Lanes, SimdWidth};
use crate::accel::sphere::Sphere;
use crate::accel::triangle::{Hit, NO_PRIM, TriangleEdges};
use build::{Aabb, Prim};
use glam::{Vec3, Vec3A};
use node::{Child, Node8};
use rayon::prelude::*;
use std::marker::PhantomData;
use std::time::Instant;
use walk::{
    AnyHitKind, ClosestKind, CountingKind, FilteredAnyHitKind, FilteredClosestKind, MakeQuery,
    Pack, QueryKind,
};
use wide::f32x8;

#[cfg(target_arch = "x86_64")]
use crate::accel::simd::F32x16;

/// Most packs in one leaf.
pub const MAX_LEAF_PACKS: usize = Child::MAX_LEAF_PACKS;

/// Trees at least this big (nodes and packs, bytes) walk batches of rays
/// interleaved; smaller ones stay in the caches and walk one ray at a time.
const INTERLEAVE_BYTES: usize = 256 << 10;

/// How to build a [`Bvh`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhOptions {
    /// The lanes of the packs of every kind (and of the kernels that test
    /// them). A width the CPU lacks falls back to [`SimdWidth::W8`].
    pub width: SimdWidth,
}

impl BvhOptions {
    /// [`width`](Self::width), or [`SimdWidth::W8`] where the CPU lacks it.
    pub fn usable_width(&self) -> SimdWidth {
        if self.width.is_available() {
            self.width
        } else {
            SimdWidth::W8
        }
    }
}

impl Default for BvhOptions {
    /// [`SimdWidth::detect`]: the widest width this CPU runs.
    fn default() -> Self {
        Self {
            width: SimdWidth::detect(),
        }
    }
}

/// A lane type the hierarchy keeps packs for.
pub(crate) trait LanesIn: Lanes {
    /// The hierarchy's packs of this width.
    fn packs(bvh: &Bvh) -> &Packs<Self>;
}

impl LanesIn for f32x8 {
    #[inline(always)]
    fn packs(bvh: &Bvh) -> &Packs<Self> {
        &bvh.packs8
    }
}

#[cfg(target_arch = "x86_64")]
impl LanesIn for F32x16 {
    #[inline(always)]
    fn packs(bvh: &Bvh) -> &Packs<Self> {
        &bvh.packs16
    }
}

/// One kind's packs at one width.
#[derive(Clone, Debug)]
pub(crate) struct KindPacks<P> {
    /// The packs of the tree's leaves, leaf after leaf (lanes carry global
    /// primitive indices).
    pub leaves: Vec<Pack<P>>,
    /// Primitives tested against every ray before the walk: those with no
    /// box (a non-finite coordinate), and a scene's occluders or large
    /// triangles when it has them in front of its tree (`small`).
    pub unbounded: Vec<Pack<P>>,
}

impl<P> Default for KindPacks<P> {
    fn default() -> Self {
        Self {
            leaves: Vec::new(),
            unbounded: Vec::new(),
        }
    }
}

/// [`KindPacks`] of every kind, at width `R`.
pub(crate) struct PacksOf<R>(PhantomData<R>);

impl<R: Lanes> Family for PacksOf<R> {
    type Of<S: Shape> = KindPacks<S::Pack<R>>;
}

/// The leaves' packs at one width, kind by kind.
pub(crate) type Packs<R> = Kinds<PacksOf<R>>;

/// The packs of one kind's leaves: `topo`'s leaves of `kind`, each packed
/// by `pack` from its run of prims, in parallel.
fn pack_leaves<T: Copy + Send + Sync>(
    topo: &build::Topology,
    kind: u32,
    lanes: usize,
    pack: impl Fn(&[Prim]) -> T + Sync,
) -> Vec<T> {
    let mut packs = vec![pack(&[]); topo.pack_counts[kind as usize]];
    // Each leaf fills its own run of packs, in parallel.
    let mut jobs = Vec::with_capacity(topo.leaves.len());
    let mut rest = packs.as_mut_slice();
    let mut first = 0;
    for leaf in topo.leaves.iter().filter(|l| l.kind == kind) {
        // Leaves of a kind own consecutive runs of its packs, in order.
        debug_assert_eq!(leaf.first_pack, first);
        first += leaf.len.div_ceil(lanes);
        let (mine, r) = rest.split_at_mut(leaf.len.div_ceil(lanes));
        jobs.push((mine, &topo.prims[leaf.start..leaf.start + leaf.len]));
        rest = r;
    }
    jobs.into_par_iter()
        .with_min_len(256)
        .for_each(|(out, prims)| {
            for (o, c) in out.iter_mut().zip(prims.chunks(lanes)) {
                *o = pack(c);
            }
        });
    packs
}

impl<R: Lanes> Packs<R> {
    /// Packs, leaves and unbounded ones, of every kind: `(count, bytes)`.
    fn size(&self) -> (usize, usize) {
        struct Size(usize, usize);
        impl<R: Lanes> Visit<PacksOf<R>> for Size {
            fn visit<S: Shape>(&mut self, k: &KindPacks<S::Pack<R>>) -> bool {
                let n = k.leaves.len() + k.unbounded.len();
                self.0 += n;
                self.1 += n * size_of::<Pack<S::Pack<R>>>();
                false
            }
        }
        let mut size = Size(0, 0);
        self.any(&mut size);
        (size.0, size.1)
    }

    fn count(&self) -> usize {
        self.size().0
    }

    fn bytes(&self) -> usize {
        self.size().1
    }

    /// Whether some kind has primitives before the walk.
    fn has_unbounded(&self) -> bool {
        struct Any;
        impl<R: Lanes> Visit<PacksOf<R>> for Any {
            fn visit<S: Shape>(&mut self, k: &KindPacks<S::Pack<R>>) -> bool {
                !k.unbounded.is_empty()
            }
        }
        self.any(&mut Any)
    }

    /// Pack `topo`'s leaves (a prim's index is its index among its kind's
    /// primitives; its lanes carry its global index) and each kind's
    /// unbounded primitives (global indices).
    fn build(topo: &build::Topology, shapes: &Shapes<'_>, unbounded: &Unbounded) -> Self {
        struct Packer<'a, 'b> {
            topo: &'a build::Topology,
            shapes: &'a Shapes<'b>,
            unbounded: &'a Unbounded,
            counts: [usize; Shapes::COUNT],
        }
        impl<R: Lanes> Make<PacksOf<R>> for Packer<'_, '_> {
            fn make<S: Shape>(&mut self) -> KindPacks<S::Pack<R>> {
                let list: &[S] = S::of(self.shapes);
                let offset = first_of::<S>(&self.counts) as u32;
                let leaves = pack_leaves(self.topo, S::KIND, R::LANES, |prims| {
                    let lanes: Vec<(u32, S)> = prims
                        .iter()
                        .map(|p| (offset + p.index, list[p.index as usize]))
                        .collect();
                    Pack(S::pack(&lanes))
                });
                let unbounded: &Vec<(u32, S)> = S::of(self.unbounded);
                KindPacks {
                    leaves,
                    unbounded: unbounded
                        .chunks(R::LANES)
                        .map(|c| Pack(S::pack(c)))
                        .collect(),
                }
            }
        }
        Kinds::new(&mut Packer {
            topo,
            shapes,
            unbounded,
            counts: shapes.counts(),
        })
    }
}

/// Each kind's primitives tested before the walk, with their global
/// indices.
type Unbounded = Kinds<IndexedOf>;

/// `(global index, primitive)` lists.
struct IndexedOf;

impl Family for IndexedOf {
    type Of<S: Shape> = Vec<(u32, S)>;
}

/// A bounding volume hierarchy over primitives of every kind
/// ([`Bvh::build_shapes`]), answering closest-hit queries
/// exactly as brute force does, and occlusion queries exactly as that
/// closest hit would.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node8>,
    root: Child,
    width: SimdWidth,
    /// 8-lane packs (empty when the width is 16).
    packs8: Packs<f32x8>,
    /// 16-lane packs (empty when the width is 8).
    #[cfg(target_arch = "x86_64")]
    packs16: Packs<F32x16>,
    /// Walk batches interleaved (the tree is bigger than the caches).
    interleave: bool,
    /// The tree is one leaf whose packs are in index order, and nothing is
    /// unbounded: a walk tests them all, in order.
    in_order: bool,
    /// How [`Bvh::closest_hits_columns`] tests a small scene of triangles
    /// in ray packets (see `packet`); empty where it walks the tree.
    packets: packet::Plan,
    /// Each kind's number of primitives.
    counts: [usize; Shapes::COUNT],
    /// References to primitives in the tree's leaves (pre-split pieces
    /// counted once per leaf they are in).
    references: usize,
    build_seconds: f64,
    /// Instancing: where set, every query goes to this two-level
    /// hierarchy instead (the fields above are empty).
    two_level: Option<Box<TwoLevel>>,
}

impl Bvh {
    /// Build the hierarchy over `tris` with the default options (the
    /// widest SIMD width this CPU runs); triangle `i` is reported as index
    /// `i` in hits. Uses the current rayon thread pool.
    ///
    /// # Panics
    ///
    /// With 2^29 or more triangles.
    pub fn build(tris: &[TriangleEdges]) -> Bvh {
        Self::build_with(tris, &BvhOptions::default())
    }

    /// [`Bvh::build`] with the given options.
    ///
    /// # Panics
    ///
    /// With 2^29 or more triangles.
    pub fn build_with(tris: &[TriangleEdges], options: &BvhOptions) -> Bvh {
        Self::build_prims(tris, &[], options)
    }

    /// Build the hierarchy over triangles and spheres together: triangle
    /// `i` is reported as primitive index `i` in hits, sphere `j` as
    /// `tris.len() + j` ([`Bvh::build_shapes`] with these two kinds).
    ///
    /// # Panics
    ///
    /// With 2^29 or more primitives in all.
    pub fn build_prims(tris: &[TriangleEdges], spheres: &[Sphere], options: &BvhOptions) -> Bvh {
        Self::build_shapes(&Shapes::triangles_and_spheres(tris, spheres), options)
    }

    /// Build the hierarchy over the primitives of every kind: hits report
    /// the kinds' primitives one kind after the other, in the order of
    /// [`Kinds`] (triangle `i` as `i`, sphere `j` as `T + j`). With
    /// triangles alone this is [`Bvh::build_with`]: the same tree and the
    /// same hits. Uses the current rayon thread pool.
    ///
    /// # Panics
    ///
    /// With 2^29 or more primitives in all.
    pub fn build_shapes(shapes: &Shapes<'_>, options: &BvhOptions) -> Bvh {
        Self::build_shapes_presplit(shapes, options, 0.0)
    }

    /// [`Bvh::build_shapes`] with pre-splitting (`presplit`): long thin
    /// triangles go to the build as several references, at most `share`
    /// extra references per primitive in all (`0.0`: none, as
    /// [`Bvh::build_shapes`] builds), in scenes of more than 256
    /// primitives (smaller ones are never split). The same hits whatever
    /// `share`. Not the default: on `2CylinderEngine.glb`, the CAD model
    /// it was made for, 25 % more references cut the closest-hit walk's
    /// instructions by 4 % but cost 1.6 times the build (see
    /// `docs/performance.md`).
    ///
    /// # Panics
    ///
    /// With 2^29 or more primitives in all.
    pub fn build_shapes_presplit(shapes: &Shapes<'_>, options: &BvhOptions, share: f32) -> Bvh {
        let started = Instant::now();
        let tris = shapes.triangles;
        let all = shapes.len();
        assert!(all < (1 << 29), "a Bvh holds fewer than 2^29 primitives");
        let width = options.usable_width();
        let mut bvh = if all <= small::MAX_PRIMS {
            small::build(shapes, width)
        } else {
            // Big scenes: their largest triangles, if they dwarf the rest,
            // in front of the tree (no candidates built: too slow).
            let first = small::large_triangles(tris, width.lanes());
            let params = BuildParams {
                root_node: !first.is_empty(),
                presplit: share,
                ..BuildParams::for_lanes(width.lanes())
            };
            let mut bvh = Self::assemble(shapes, &first, width, &params);
            // The wavefront's batches test those in ray packets, where that
            // counts cheaper, and walk the tree only for the rays that
            // reach its box.
            let finite = || tris.iter().all(TriangleEdges::is_finite);
            if !first.is_empty()
                && all == tris.len()
                && finite()
                && let Some(plan) = small::front_plan(tris, &first, width)
            {
                bvh.set_packet_plan(plan);
            }
            bvh
        };
        bvh.build_seconds = started.elapsed().as_secs_f64();
        bvh
    }

    /// The two-level hierarchy over `placements` (instancing: see
    /// [`TwoLevel`]), answering every query of a [`Bvh`] with the global
    /// primitive indices of the flattened scene; `counts` is each kind's
    /// number of primitives there. `None` where a mesh has a primitive
    /// with no finite box or a transform does not invert. Uses the current
    /// rayon thread pool.
    pub fn build_two_level(
        placements: &Placements<'_>,
        counts: [usize; Shapes::COUNT],
        options: &BvhOptions,
    ) -> Option<Bvh> {
        let started = Instant::now();
        let width = options.usable_width();
        let options = BvhOptions { width };
        let two_level = TwoLevel::build(placements, &options)?;
        Some(Bvh {
            build_seconds: started.elapsed().as_secs_f64(),
            two_level: Some(Box::new(two_level)),
            ..Bvh::empty(Child::EMPTY, width, counts)
        })
    }

    /// The two-level hierarchy this one traces through, where it is one
    /// (instancing).
    pub fn two_level(&self) -> Option<&TwoLevel> {
        self.two_level.as_deref()
    }

    /// A hierarchy of `width` rooted at `root`, of `counts` primitives per
    /// kind, with no nodes, packs or plans yet (the builds fill them in).
    fn empty(root: Child, width: SimdWidth, counts: [usize; Shapes::COUNT]) -> Bvh {
        Bvh {
            nodes: Vec::new(),
            root,
            width,
            packs8: Packs::default(),
            #[cfg(target_arch = "x86_64")]
            packs16: Packs::default(),
            interleave: false,
            in_order: false,
            packets: packet::Plan::default(),
            counts,
            references: 0,
            build_seconds: 0.0,
            two_level: None,
        }
    }

    /// The hierarchy over `shapes` at `width`, built with `params`, but for
    /// the primitives in `first` (global indices, increasing: triangles,
    /// the first kind): those are tested before the walk, by every ray.
    fn assemble(shapes: &Shapes<'_>, first: &[u32], width: SimdWidth, params: &BuildParams) -> Bvh {
        /// Each kind's prims with a box, and its unbounded ones.
        struct Split<'a> {
            first: &'a [u32],
            counts: [usize; Shapes::COUNT],
            prims: Vec<Prim>,
        }
        impl Split<'_> {
            fn is_first(&self, i: usize) -> bool {
                self.first.binary_search(&(i as u32)).is_ok()
            }
        }
        impl<'a> Visit<Slices<'a>> for Split<'_> {
            fn visit<S: Shape>(&mut self, list: &&'a [S]) -> bool {
                // Indexed among the kind's primitives (the packs add the
                // kinds' before it).
                let offset = first_of::<S>(&self.counts);
                let me = &*self;
                let prims = list.par_iter().enumerate().filter_map(|(j, s)| {
                    if me.is_first(offset + j) {
                        return None;
                    }
                    let (lo, hi) = s.bounds()?;
                    Some(Prim {
                        b: Aabb { lo, hi },
                        index: j as u32,
                        kind: S::KIND as u8,
                        piece: false,
                    })
                });
                let prims: Vec<Prim> = prims.collect();
                self.prims.extend(prims);
                false
            }
        }
        struct UnboundedOf<'a, 'b> {
            shapes: &'a Shapes<'b>,
            split: &'a Split<'a>,
        }
        impl Make<IndexedOf> for UnboundedOf<'_, '_> {
            fn make<S: Shape>(&mut self) -> Vec<(u32, S)> {
                let offset = first_of::<S>(&self.split.counts);
                let list: &[S] = S::of(self.shapes);
                list.iter()
                    .enumerate()
                    .filter(|&(j, s)| s.bounds().is_none() || self.split.is_first(offset + j))
                    .map(|(j, s)| ((offset + j) as u32, *s))
                    .collect()
            }
        }
        let counts = shapes.counts();
        let mut split = Split {
            first,
            counts,
            prims: Vec::new(),
        };
        shapes.any(&mut split);
        let mut prims = std::mem::take(&mut split.prims);
        if params.presplit > 0.0 {
            let tris = shapes.triangles;
            prims = presplit::presplit(prims, params.presplit, |p| {
                (p.kind as u32 == TriangleEdges::KIND)
                    .then(|| triangle_vertices(&tris[p.index as usize]))
            });
        }
        let unbounded = Unbounded::new(&mut UnboundedOf {
            shapes,
            split: &split,
        });
        let topo = build::build(prims, params);
        let mut bvh = Bvh::empty(topo.root, width, counts);
        match width {
            SimdWidth::W8 => bvh.packs8 = Packs::build(&topo, shapes, &unbounded),
            #[cfg(target_arch = "x86_64")]
            SimdWidth::W16 => bvh.packs16 = Packs::build(&topo, shapes, &unbounded),
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => unreachable!("16 lanes are x86-64 only"),
        }
        let unbounded = match width {
            SimdWidth::W8 => bvh.packs8.has_unbounded(),
            #[cfg(target_arch = "x86_64")]
            SimdWidth::W16 => bvh.packs16.has_unbounded(),
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => unreachable!("16 lanes are x86-64 only"),
        };
        bvh.in_order = !topo.root.is_node() && !unbounded;
        bvh.references = topo.leaves.iter().map(|l| l.len).sum();
        bvh.nodes = topo.nodes;
        bvh.interleave = bvh.bytes() >= INTERLEAVE_BYTES;
        bvh
    }

    /// One ray through the walk, with query `K`, at this tree's width.
    #[inline(always)]
    fn one<K: QueryKind>(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> K::Output {
        match self.width {
            SimdWidth::W8 => walk::walk_one::<f32x8, K::Q<f32x8>>(self, (o, d), t_min, t_max, true),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: a tree is 16 wide only when the CPU has AVX-512
            // (`build_with` checks `SimdWidth::is_available`).
            SimdWidth::W16 => unsafe { one16::<K>(self, o, d, t_min, t_max) },
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => unreachable!("16 lanes are x86-64 only"),
        }
    }

    /// Rays `0..n` through the walk, with query `K`, at this tree's width
    /// (`front`: as [`walk::walk_many`]'s).
    #[inline(always)]
    fn many<K: QueryKind>(
        &self,
        n: usize,
        ray: impl Fn(usize) -> (Vec3, Vec3, f32),
        t_min: f32,
        front: bool,
        out: impl FnMut(usize, K::Output),
    ) {
        match self.width {
            SimdWidth::W8 => walk::walk_many::<f32x8, K::Q<f32x8>>(self, n, ray, t_min, front, out),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `one`.
            SimdWidth::W16 => unsafe { many16::<K>(self, n, ray, t_min, front, out) },
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => unreachable!("16 lanes are x86-64 only"),
        }
    }

    /// One ray through the walk with the query `m` makes, at this tree's
    /// width.
    #[inline(always)]
    fn one_made<M: MakeQuery>(&self, o: Vec3, d: Vec3, t_min: f32, m: M) -> M::Output {
        match self.width {
            SimdWidth::W8 => walk::walk_one_with(self, (o, d), t_min, m.make::<f32x8>(), true),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `one`.
            SimdWidth::W16 => unsafe { one16_made(self, o, d, t_min, m) },
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => unreachable!("16 lanes are x86-64 only"),
        }
    }

    /// Rays `0..n` through the walk, `ray(i)` giving ray `i` and the query
    /// that it makes, at this tree's width (with the primitives in front of
    /// the tree).
    #[inline(always)]
    fn many_made<M: MakeQuery>(
        &self,
        n: usize,
        ray: impl Fn(usize) -> (Vec3, Vec3, M),
        t_min: f32,
        out: impl FnMut(usize, M::Output),
    ) {
        match self.width {
            SimdWidth::W8 => walk::walk_many_with::<f32x8, M::Q<f32x8>>(
                self,
                n,
                #[inline(always)]
                |i| {
                    let (o, d, m) = ray(i);
                    (o, d, m.make::<f32x8>())
                },
                t_min,
                true,
                out,
            ),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `one`.
            SimdWidth::W16 => unsafe { many16_made(self, n, ray, t_min, out) },
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => unreachable!("16 lanes are x86-64 only"),
        }
    }

    /// [`Bvh::closest_hit`] among the hits that `filter` does not let
    /// through ([`HitFilter`]: alpha-tested surfaces): a candidate hit on
    /// a primitive that may pass is put to the filter before it shortens
    /// the ray, and the walk goes on past those that pass. The smallest
    /// `(t, primitive index)` of the hits that do not pass, bit for bit
    /// what [`closest_hit_brute_force_filtered`](crate::accel::shape::closest_hit_brute_force_filtered)
    /// returns.
    #[inline(never)]
    pub fn closest_hit_filtered<F: HitFilter>(
        &self,
        o: Vec3,
        d: Vec3,
        (t_min, t_max): (f32, f32),
        filter: &F,
    ) -> Option<Hit> {
        if let Some(two) = &self.two_level {
            return as_hit(two.closest_filtered(o, d, t_min, t_max, filter));
        }
        self.tree_closest_filtered(o, d, (t_min, t_max), filter)
    }

    /// [`Bvh::closest_hit_filtered`] through this tree's own walk (not a
    /// two-level hierarchy's: its bottom trees).
    #[inline(always)]
    fn tree_closest_filtered<F: HitFilter>(
        &self,
        o: Vec3,
        d: Vec3,
        (t_min, t_max): (f32, f32),
        filter: &F,
    ) -> Option<Hit> {
        as_hit(self.one_made(o, d, t_min, FilteredClosestKind { t_max, filter }))
    }

    /// [`Bvh::occluded_filtered`] through this tree's own walk.
    #[inline(always)]
    fn tree_occluded_filtered<F: HitFilter>(
        &self,
        o: Vec3,
        d: Vec3,
        (t_min, t_max): (f32, f32),
        filter: &F,
    ) -> bool {
        self.one_made(o, d, t_min, FilteredAnyHitKind { t_max, filter })
    }

    /// [`Bvh::occluded`] among the hits that `filter` does not let
    /// through: whether a primitive that does not pass lies on the
    /// segment (exactly when [`Bvh::closest_hit_filtered`] would find one
    /// there).
    #[inline(never)]
    pub fn occluded_filtered<F: HitFilter>(
        &self,
        o: Vec3,
        d: Vec3,
        (t_min, t_max): (f32, f32),
        filter: &F,
    ) -> bool {
        if let Some(two) = &self.two_level {
            return two.occluded_filtered(o, d, t_min, t_max, filter);
        }
        self.tree_occluded_filtered(o, d, (t_min, t_max), filter)
    }

    /// [`Bvh::closest_hits_columns`] among the hits that `filter(i)` does
    /// not let through, for ray `i` ([`Bvh::closest_hit_filtered`]): the
    /// same hits, bit for bit. The rays walk the tree (interleaved on a
    /// large one), not the ray packets.
    ///
    /// # Panics
    ///
    /// If the columns and outputs differ in length.
    #[inline(never)]
    pub fn closest_hits_columns_filtered<F: HitFilter>(
        &self,
        (o, d): ([&[f32]; 3], [&[f32]; 3]),
        (t_min, t_max): (f32, f32),
        (t, prim): (&mut [f32], &mut [u32]),
        filter: impl Fn(usize) -> F,
    ) {
        let n = t.len();
        assert!(
            prim.len() == n && o.iter().chain(&d).all(|c| c.len() == n),
            "one origin, direction and output per ray"
        );
        if let Some(two) = &self.two_level {
            for i in 0..n {
                let (oi, di) = column_ray((o, d), i);
                let f = filter(i);
                (t[i], prim[i]) = two.closest_filtered(oi, di, t_min, t_max, &f);
            }
            return;
        }
        self.many_made(
            n,
            #[inline(always)]
            |i| {
                let (o, d) = column_ray((o, d), i);
                let filter = filter(i);
                (o, d, FilteredClosestKind { t_max, filter })
            },
            t_min,
            #[inline(always)]
            |i, (ti, p)| (t[i], prim[i]) = (ti, p),
        );
    }

    /// [`Bvh::occluded_columns`] among the hits that `filter(i)` does not
    /// let through, for segment `i` ([`Bvh::occluded_filtered`]).
    ///
    /// # Panics
    ///
    /// If the columns and outputs differ in length.
    #[inline(never)]
    pub fn occluded_columns_filtered<F: HitFilter>(
        &self,
        (o, d): ([&[f32]; 3], [&[f32]; 3]),
        (t_min, t_max): (f32, &[f32]),
        out: &mut [bool],
        filter: impl Fn(usize) -> F,
    ) {
        let n = out.len();
        assert!(
            t_max.len() == n && o.iter().chain(&d).all(|c| c.len() == n),
            "one origin, direction, end and output per segment"
        );
        if let Some(two) = &self.two_level {
            for i in 0..n {
                let (oi, di) = column_ray((o, d), i);
                let f = filter(i);
                out[i] = two.occluded_filtered(oi, di, t_min, t_max[i], &f);
            }
            return;
        }
        self.many_made(
            n,
            #[inline(always)]
            |i| {
                let (o, d) = column_ray((o, d), i);
                let filter = filter(i);
                let t_max = t_max[i];
                (o, d, FilteredAnyHitKind { t_max, filter })
            },
            t_min,
            #[inline(always)]
            |i, b| out[i] = b,
        );
    }

    /// The closest hit of the ray `o + t·d` with `t_min < t < t_max`: the
    /// smallest `(t, primitive index)`, bit for bit what
    /// [`closest_hit_brute_force_prims`](crate::accel::sphere::closest_hit_brute_force_prims)
    /// returns (with no spheres:
    /// [`closest_hit_brute_force`](crate::accel::triangle::closest_hit_brute_force)).
    #[inline(never)]
    pub fn closest_hit(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        if let Some(two) = &self.two_level {
            return as_hit(two.closest(o, d, t_min, t_max));
        }
        as_hit(self.one::<ClosestKind>(o, d, t_min, t_max))
    }

    /// Whether anything lies on the segment `o + t·d`, `t_min < t < t_max`:
    /// exactly when [`Bvh::closest_hit`] would find a hit there. Stops at
    /// the first primitive found (for shadow rays).
    #[inline(never)]
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        if let Some(two) = &self.two_level {
            return two.occluded(o, d, t_min, t_max);
        }
        self.one::<AnyHitKind>(o, d, t_min, t_max)
    }

    /// The closest hits of many rays `(o, d)`, each exactly as
    /// [`Bvh::closest_hit`] would give it, into `out` (same length).
    ///
    /// On a large tree the rays are traced [`BATCH`] at a time,
    /// interleaved: each step of one ray prefetches the node or leaf it
    /// will visit next, and the other rays' steps run while it arrives
    /// from memory (several times faster than one ray at a time on scenes
    /// much larger than the caches).
    ///
    /// # Panics
    ///
    /// If `out.len() != rays.len()`.
    pub fn closest_hits(
        &self,
        rays: &[(Vec3, Vec3)],
        t_min: f32,
        t_max: f32,
        out: &mut [Option<Hit>],
    ) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        self.closest_hits_with(rays.len(), |i| rays[i], t_min, t_max, |i, h| out[i] = h);
    }

    /// [`Bvh::closest_hits`] for rays `0..n` given by `ray(i)` (origin,
    /// direction), handing ray `i`'s hit to `out(i, hit)` (in any order).
    pub fn closest_hits_with(
        &self,
        n: usize,
        ray: impl Fn(usize) -> (Vec3, Vec3),
        t_min: f32,
        t_max: f32,
        mut out: impl FnMut(usize, Option<Hit>),
    ) {
        self.closest_hits_into(n, ray, t_min, t_max, |i, t, prim| out(i, as_hit((t, prim))));
    }

    /// [`Bvh::closest_hits_with`] with each hit as a plain pair:
    /// `out(i, t, primitive)`, the primitive [`NO_PRIM`] where ray `i`
    /// hits nothing (then `t` means nothing). The same hits; no branch per
    /// ray on whether it hit (for the wavefront's intersect stage).
    #[inline(never)]
    pub fn closest_hits_into(
        &self,
        n: usize,
        ray: impl Fn(usize) -> (Vec3, Vec3),
        t_min: f32,
        t_max: f32,
        mut out: impl FnMut(usize, f32, u32),
    ) {
        if let Some(two) = &self.two_level {
            for i in 0..n {
                let (o, d) = ray(i);
                let (t, prim) = two.closest(o, d, t_min, t_max);
                out(i, t, prim);
            }
            return;
        }
        self.many::<ClosestKind>(
            n,
            #[inline(always)]
            |i| {
                let (o, d) = ray(i);
                (o, d, t_max)
            },
            t_min,
            true,
            #[inline(always)]
            |i, (t, prim)| out(i, t, prim),
        );
    }

    /// [`Bvh::closest_hits_into`] for rays given as columns: ray `i` has
    /// origin `(o[0][i], o[1][i], o[2][i])` and direction likewise from
    /// `d`; its hit goes to `t[i]` and `prim[i]` ([`NO_PRIM`] where none).
    /// The same hits, bit for bit.
    ///
    /// In a small scene of triangles (the Cornell box) the rays go 8 or 16
    /// at a time, one per lane, each triangle broadcast to every lane, the
    /// small triangles behind boxes (`packet`): no per-ray set-up or
    /// reduction. In a big scene of triangles whose largest ones are in
    /// front of the tree (`sphere-1m`: the room), those go in packets the
    /// same way, and only the rays that enter the tree's box before their
    /// hit among them walk the tree.
    ///
    /// # Panics
    ///
    /// If the columns and outputs differ in length.
    #[inline(never)]
    pub fn closest_hits_columns(
        &self,
        o: [&[f32]; 3],
        d: [&[f32]; 3],
        (t_min, t_max): (f32, f32),
        t: &mut [f32],
        prim: &mut [u32],
    ) {
        let n = t.len();
        assert!(
            prim.len() == n && o.iter().chain(&d).all(|c| c.len() == n),
            "one origin, direction and output per ray"
        );
        if self.packets.is_empty() {
            self.closest_hits_into(
                n,
                #[inline(always)]
                |i| column_ray((o, d), i),
                t_min,
                t_max,
                #[inline(always)]
                |i, ti, p| (t[i], prim[i]) = (ti, p),
            );
            return;
        }
        let mut q = packet::ClosestHits { t, prim, t_max };
        let behind = self.packets(&mut q, (o, d), t_min);
        let packet::ClosestHits { t, prim, .. } = q;
        if behind.is_empty() {
            return;
        }
        // The tree behind the packets' triangles, for the rays that enter
        // its box before their hit so far: a walk up to and including that
        // hit's t (a tree triangle at the same t with a lower index wins
        // the tie), without the triangles in front of the tree (the
        // packets' own).
        let limit: Vec<f32> = behind
            .iter()
            .map(|&i| {
                let i = i as usize;
                if prim[i] == NO_PRIM {
                    t_max
                } else {
                    t[i].next_up()
                }
            })
            .collect();
        self.many::<ClosestKind>(
            behind.len(),
            #[inline(always)]
            |k| {
                let (o, d) = column_ray((o, d), behind[k] as usize);
                (o, d, limit[k])
            },
            t_min,
            false,
            #[inline(always)]
            |k, (tk, pk)| {
                let i = behind[k] as usize;
                if pk != NO_PRIM && (tk < t[i] || pk < prim[i]) {
                    (t[i], prim[i]) = (tk, pk);
                }
            },
        );
    }

    /// The rays `(o, d)` through the packet plan with query `q`, at this
    /// tree's width; the rays that go on to the tree behind the plan.
    #[inline(always)]
    fn packets<Q>(&self, q: &mut Q, rays: ([&[f32]; 3], [&[f32]; 3]), t_min: f32) -> Vec<u32>
    where
        Q: packet::PacketQuery<f32x8> + PacketQuery16,
    {
        let mut behind = Vec::new();
        match self.width {
            SimdWidth::W8 => packet::trace::<f32x8, Q>(&self.packets, rays, t_min, q, &mut behind),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `one`.
            SimdWidth::W16 => unsafe { packets16(&self.packets, rays, t_min, q, &mut behind) },
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => unreachable!("16 lanes are x86-64 only"),
        }
        behind
    }

    /// [`Bvh::occluded`] for segments given as columns: ray `i` has origin
    /// `(o[0][i], o[1][i], o[2][i])`, direction likewise from `d`, and ends
    /// at `t_max[i]`; whether it is occluded goes to `out[i]`. The same
    /// answers. In a scene traced in ray packets
    /// ([`Bvh::closest_hits_columns`]) the segments go in packets too, and
    /// only those that no packet triangle blocks and that enter the tree's
    /// box walk it.
    ///
    /// # Panics
    ///
    /// If the columns and outputs differ in length.
    #[inline(never)]
    pub fn occluded_columns(
        &self,
        o: [&[f32]; 3],
        d: [&[f32]; 3],
        t_min: f32,
        t_max: &[f32],
        out: &mut [bool],
    ) {
        let n = out.len();
        assert!(
            t_max.len() == n && o.iter().chain(&d).all(|c| c.len() == n),
            "one origin, direction, end and output per segment"
        );
        let ray = |i: usize| {
            let (o, d) = column_ray((o, d), i);
            (o, d, t_max[i])
        };
        if self.packets.is_empty() {
            self.occluded_with(n, ray, t_min, |i, b| out[i] = b);
            return;
        }
        let mut q = packet::AnyHits { t_max, out };
        let behind = self.packets(&mut q, (o, d), t_min);
        let out = q.out;
        // The tree behind the packets' triangles, for the segments they
        // leave open that enter its box.
        self.many::<AnyHitKind>(
            behind.len(),
            #[inline(always)]
            |k| ray(behind[k] as usize),
            t_min,
            false,
            #[inline(always)]
            |k, occluded| out[behind[k] as usize] |= occluded,
        );
    }

    /// [`Bvh::occluded`] for many segments: ray `i` is `rays[i]` up to
    /// `t_max[i]`; its answer goes to `out[i]`. Interleaved on large trees
    /// as [`Bvh::closest_hits`] is.
    ///
    /// # Panics
    ///
    /// If the three slices differ in length.
    pub fn occluded_batch(
        &self,
        rays: &[(Vec3, Vec3)],
        t_min: f32,
        t_max: &[f32],
        out: &mut [bool],
    ) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        assert_eq!(rays.len(), t_max.len(), "one t_max per ray");
        self.occluded_with(
            rays.len(),
            |i| (rays[i].0, rays[i].1, t_max[i]),
            t_min,
            |i, b| out[i] = b,
        );
    }

    /// [`Bvh::occluded_batch`] for segments `0..n` given by `ray(i)`
    /// (origin, direction, `t_max`), handing segment `i`'s answer to
    /// `out(i, occluded)` (in any order).
    #[inline(never)]
    pub fn occluded_with(
        &self,
        n: usize,
        ray: impl Fn(usize) -> (Vec3, Vec3, f32),
        t_min: f32,
        mut out: impl FnMut(usize, bool),
    ) {
        if let Some(two) = &self.two_level {
            for i in 0..n {
                let (o, d, t_max) = ray(i);
                out(i, two.occluded(o, d, t_min, t_max));
            }
            return;
        }
        self.many::<AnyHitKind>(n, ray, t_min, true, out);
    }

    /// [`Bvh::closest_hit`] (`occlusion = false`) or [`Bvh::occluded`]
    /// (`true`), counting the nodes, leaves and packs the walk visits: for
    /// tuning and benchmarks (all zero for a two-level hierarchy, whose
    /// walks are not counted).
    pub fn walk_stats(
        &self,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        t_max: f32,
        occlusion: bool,
    ) -> WalkStats {
        if occlusion {
            self.one::<CountingKind<AnyHitKind>>(o, d, t_min, t_max).1
        } else {
            self.one::<CountingKind<ClosestKind>>(o, d, t_min, t_max).1
        }
    }

    /// The tree's cost by the surface area heuristic, as the build counts
    /// it: each inner node 1 and each pack 1.5, times the chance that a
    /// ray through the root's box enters the box in front of it (the ratio
    /// of their areas); packs in front of the tree count in full. 0 for a
    /// two-level hierarchy.
    pub fn sah_cost(&self) -> f64 {
        if self.two_level.is_some() {
            return 0.0;
        }
        let params = BuildParams::for_lanes(self.width.lanes());
        let area = |(lo, hi): (Vec3A, Vec3A)| Aabb { lo, hi }.half_area() as f64;
        if !self.root.is_node() {
            return self.pack_count() as f64 * params.cost_pack as f64;
        }
        let first = self.first_pack_count() as f64 * params.cost_pack as f64;
        let node_box = |n: usize| {
            let mut b = Aabb::EMPTY;
            for i in 0..8 {
                if self.nodes[n].child[i] != Child::EMPTY {
                    let (lo, hi) = self.nodes[n].child_box(i);
                    b.grow(&Aabb { lo, hi });
                }
            }
            (b.lo, b.hi)
        };
        let mut cost = 0.0;
        let mut stack = vec![(self.root.0 as usize, area(node_box(self.root.0 as usize)))];
        while let Some((n, a)) = stack.pop() {
            cost += params.cost_node as f64 * a;
            for (i, &c) in self.nodes[n].child.iter().enumerate() {
                if c == Child::EMPTY {
                    continue;
                }
                let ca = area(self.nodes[n].child_box(i));
                if c.is_node() {
                    stack.push((c.0 as usize, ca));
                } else {
                    cost += params.cost_pack as f64 * c.packs().1 as f64 * ca;
                }
            }
        }
        first + cost / area(node_box(self.root.0 as usize))
    }

    /// The SIMD width of the packs and kernels in use.
    pub fn simd_width(&self) -> SimdWidth {
        self.width
    }

    /// Number of triangles the hierarchy was built over.
    pub fn triangle_count(&self) -> usize {
        self.count_of::<TriangleEdges>()
    }

    /// Number of primitives of kind `S` the hierarchy was built over
    /// (their primitive indices follow those of the kinds before it).
    pub fn count_of<S: Shape>(&self) -> usize {
        self.counts[S::KIND as usize]
    }

    /// Number of primitives, of every kind.
    pub fn prim_count(&self) -> usize {
        self.counts.iter().sum()
    }

    /// References to primitives in the tree's leaves: each primitive with
    /// a box once, and a pre-split one once for each leaf its pieces are
    /// in (0 for a two-level hierarchy).
    pub fn reference_count(&self) -> usize {
        self.references
    }

    /// Number of inner (8-wide) nodes (with instancing: of every tree,
    /// the top level's binary nodes included).
    pub fn node_count(&self) -> usize {
        if let Some(two) = &self.two_level {
            return two.node_count();
        }
        self.nodes.len()
    }

    /// Number of packs (of 8 or 16, of every kind) in the leaves and in
    /// front of the tree.
    pub fn pack_count(&self) -> usize {
        match self.width {
            SimdWidth::W8 => self.packs8.count(),
            #[cfg(target_arch = "x86_64")]
            SimdWidth::W16 => self.packs16.count(),
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => 0,
        }
    }

    /// Memory held by the nodes and the packs, in bytes.
    pub fn bytes(&self) -> usize {
        if let Some(two) = &self.two_level {
            return two.bytes();
        }
        #[cfg(target_arch = "x86_64")]
        let p16 = self.packs16.bytes();
        #[cfg(not(target_arch = "x86_64"))]
        let p16 = 0;
        self.nodes.len() * size_of::<Node8>() + self.packs8.bytes() + p16
    }

    /// Packs of triangles every ray tests before the walk: the largest
    /// triangles, where the build put them in front of the tree (`small`),
    /// and triangles with no box.
    pub fn first_pack_count(&self) -> usize {
        match self.width {
            SimdWidth::W8 => self.packs8.triangles.unbounded.len(),
            #[cfg(target_arch = "x86_64")]
            SimdWidth::W16 => self.packs16.triangles.unbounded.len(),
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => 0,
        }
    }

    /// Wall-clock seconds [`Bvh::build`] took.
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// Where [`Bvh::closest_hits_columns`] tests ray packets (a small
    /// scene of triangles, or a big one's largest triangles in front of its
    /// tree): how many triangles every ray tests, and how many groups
    /// behind boxes follow. `None` where it walks the tree alone.
    pub fn packet_plan(&self) -> Option<(usize, usize)> {
        (!self.packets.is_empty()).then(|| (self.packets.first_count(), self.packets.group_count()))
    }

    /// The tree is one leaf of triangles in index order, each tested by
    /// every ray.
    fn is_one_leaf_in_order(&self) -> bool {
        self.in_order && self.root.kind() == TriangleEdges::KIND
    }

    /// Test ray packets by `plan` in [`Bvh::closest_hits_columns`].
    fn set_packet_plan(&mut self, plan: packet::Plan) {
        self.packets = plan;
    }
}

/// A triangle's box (finite for a finite triangle).
#[inline]
fn triangle_box(t: &TriangleEdges) -> Aabb {
    let [v0, v1, v2] = triangle_vertices(t);
    Aabb {
        lo: v0.min(v1).min(v2),
        hi: v0.max(v1).max(v2),
    }
}

/// A triangle's vertices as its box is computed from them (`v0`, and
/// `v0 + e1`, `v0 + e2` rounded).
#[inline]
fn triangle_vertices(t: &TriangleEdges) -> [Vec3A; 3] {
    let v0 = Vec3A::from(t.v0);
    [v0, v0 + Vec3A::from(t.e1), v0 + Vec3A::from(t.e2)]
}

/// Ray `i` of rays given as columns: its origin and direction.
#[inline(always)]
fn column_ray((o, d): ([&[f32]; 3], [&[f32]; 3]), i: usize) -> (Vec3, Vec3) {
    (
        Vec3::new(o[0][i], o[1][i], o[2][i]),
        Vec3::new(d[0][i], d[1][i], d[2][i]),
    )
}

/// A closest-hit query's `(t, primitive)` as an optional [`Hit`].
#[inline(always)]
fn as_hit((t, prim): (f32, u32)) -> Option<Hit> {
    (prim != NO_PRIM).then_some(Hit { triangle: prim, t })
}

/// A packet query at 16 lanes too (where there are 16 lanes).
#[cfg(target_arch = "x86_64")]
trait PacketQuery16: packet::PacketQuery<F32x16> {}
#[cfg(target_arch = "x86_64")]
impl<Q: packet::PacketQuery<F32x16>> PacketQuery16 for Q {}
#[cfg(not(target_arch = "x86_64"))]
trait PacketQuery16 {}
#[cfg(not(target_arch = "x86_64"))]
impl<Q> PacketQuery16 for Q {}

/// [`packet::trace`] at 16 lanes, compiled with AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn packets16<Q: packet::PacketQuery<F32x16>>(
    plan: &packet::Plan,
    rays: ([&[f32]; 3], [&[f32]; 3]),
    t_min: f32,
    q: &mut Q,
    behind: &mut Vec<u32>,
) {
    packet::trace::<F32x16, Q>(plan, rays, t_min, q, behind)
}

/// [`Bvh::one`] at 16 lanes, compiled with AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn one16<K: QueryKind>(bvh: &Bvh, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> K::Output {
    walk::walk_one::<F32x16, K::Q<F32x16>>(bvh, (o, d), t_min, t_max, true)
}

/// [`Bvh::many`] at 16 lanes, compiled with AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn many16<K: QueryKind>(
    bvh: &Bvh,
    n: usize,
    ray: impl Fn(usize) -> (Vec3, Vec3, f32),
    t_min: f32,
    front: bool,
    out: impl FnMut(usize, K::Output),
) {
    walk::walk_many::<F32x16, K::Q<F32x16>>(bvh, n, ray, t_min, front, out)
}

/// [`Bvh::one_made`] at 16 lanes, compiled with AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn one16_made<M: MakeQuery>(bvh: &Bvh, o: Vec3, d: Vec3, t_min: f32, m: M) -> M::Output {
    walk::walk_one_with(bvh, (o, d), t_min, m.make::<F32x16>(), true)
}

/// [`Bvh::many_made`] at 16 lanes, compiled with AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn many16_made<M: MakeQuery>(
    bvh: &Bvh,
    n: usize,
    ray: impl Fn(usize) -> (Vec3, Vec3, M),
    t_min: f32,
    out: impl FnMut(usize, M::Output),
) {
    walk::walk_many_with::<F32x16, M::Q<F32x16>>(
        bvh,
        n,
        #[inline(always)]
        |i| {
            let (o, d, m) = ray(i);
            (o, d, m.make::<F32x16>())
        },
        t_min,
        true,
        out,
    )
}
