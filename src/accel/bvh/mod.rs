//! A bounding volume hierarchy with 8-wide nodes and leaves of primitive
//! packs, answering closest-hit and any-hit (occlusion) queries.
//!
//! # Layout
//!
//! Every inner node holds the boxes of up to eight children in
//! structure-of-arrays form, so one ray is tested against all eight boxes
//! with a handful of AVX2 instructions. A child reference is a node, a
//! leaf, or nothing; a leaf's reference carries its primitive kind
//! ([`PrimKind`]) and its run of 1 to [`MAX_LEAF_PACKS`] packs in that
//! kind's pack list. Triangles come in packs of 8 or 16 ([`SimdWidth`]):
//! the very SoA packs and the very Möller–Trumbore kernel of
//! [`closest_hit_packs`](crate::accel::triangle::closest_hit_packs).
//! Analytic spheres ([`Sphere`]) come in packs of the same width
//! ([`SpherePack`]), tested by the robust
//! kernel [`intersect_sphere`](crate::accel::sphere::intersect_sphere).
//!
//! # Primitive indices
//!
//! [`Bvh::build_prims`] takes triangles and spheres; a hit names one
//! primitive by one global index: triangle `i` is `i`, sphere `j` is
//! `T + j` (`T` the number of triangles). [`Hit::triangle`] holds that
//! index; with no spheres it is the triangle's own index, as ever.
//!
//! # Build
//!
//! [`build`]: binned SAH over the primitives' boxes, whatever their kind
//! ([`BuildPrim`]); then each leaf's primitives are packed by their kind.
//! Adding a kind (triangles and analytic spheres today) takes a
//! [`PrimKind`] variant, its packs beside the others, their kernel
//! (`intersect` and `occludes`, behind the walk's one `PackKernel` trait, so
//! every query handles every kind with one body), and its arm where the
//! walk dispatches on a leaf's kind.
//!
//! # Queries
//!
//! One walk (`walk`) serves every query: it tests a node's boxes, visits
//! the children the ray enters (nearest first for closest hits), and hands
//! each leaf to the query, which keeps the closest hit ([`Bvh::closest_hit`],
//! [`Bvh::closest_hits`]) or stops at the first ([`Bvh::occluded`],
//! [`Bvh::occluded_batch`]). Batches of rays walk interleaved on large
//! trees, with prefetches, so memory latency overlaps.
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
//! the sphere kernel's rounding. The result is the same primitive and the
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
mod small;
mod walk;

pub use build::{BuildParams, BuildPrim, SAH_DEPTH_LIMIT};
pub use node::PrimKind;
pub use walk::{BATCH, WalkStats};

use crate::accel::simd::{Lanes, SimdWidth};
use crate::accel::sphere::{Sphere, SpherePack};
use crate::accel::triangle::{Hit, NO_PRIM, TriangleEdges, TrianglePack};
use build::{Aabb, Prim};
use glam::{Vec3, Vec3A};
use node::{Child, Node8};
use rayon::prelude::*;
use std::time::Instant;
use walk::{AnyHitKind, ClosestKind, CountingKind, Pack, QueryKind};
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
    /// The lanes of the triangle and sphere packs (and of the kernels that
    /// test them). A width the CPU lacks falls back to [`SimdWidth::W8`].
    pub width: SimdWidth,
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

/// The leaves' packs at one width.
#[derive(Clone, Debug)]
pub(crate) struct Packs<R: Lanes> {
    /// Triangle packs, leaf after leaf.
    pub triangles: Vec<Pack<TrianglePack<R>>>,
    /// Triangles tested against every ray before the walk: those with a
    /// non-finite coordinate (they have no box), and a scene's occluders
    /// or large triangles when it has them in front of its tree (`small`).
    pub unbounded: Vec<Pack<TrianglePack<R>>>,
    /// Sphere packs, leaf after leaf (lanes carry global indices).
    pub spheres: Vec<Pack<SpherePack<R>>>,
    /// Spheres with a non-finite center, radius or box: as `unbounded`.
    pub unbounded_spheres: Vec<Pack<SpherePack<R>>>,
}

/// The packs of one kind's leaves: `topo`'s leaves of `kind`, each packed
/// by `pack` from its run of prims, in parallel.
fn pack_leaves<T: Copy + Send + Sync>(
    topo: &build::Topology,
    kind: PrimKind,
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
    fn empty() -> Self {
        Self {
            triangles: Vec::new(),
            unbounded: Vec::new(),
            spheres: Vec::new(),
            unbounded_spheres: Vec::new(),
        }
    }

    fn count(&self) -> usize {
        self.triangles.len()
            + self.unbounded.len()
            + self.spheres.len()
            + self.unbounded_spheres.len()
    }

    fn bytes(&self) -> usize {
        (self.triangles.len() + self.unbounded.len()) * size_of::<Pack<TrianglePack<R>>>()
            + (self.spheres.len() + self.unbounded_spheres.len()) * size_of::<Pack<SpherePack<R>>>()
    }

    /// Pack `topo`'s leaves and the unbounded primitives. A sphere prim's
    /// index is its index among the spheres; its lanes carry
    /// `tris.len()` more.
    fn new(
        topo: &build::Topology,
        tris: &[TriangleEdges],
        unbounded: &[(u32, TriangleEdges)],
        spheres: &[Sphere],
        unbounded_spheres: &[(u32, Sphere)],
    ) -> Self {
        let lanes = R::LANES;
        let triangles = pack_leaves(topo, PrimKind::Triangle, lanes, |prims| {
            let lanes: Vec<(u32, TriangleEdges)> = prims
                .iter()
                .map(|p| (p.index, tris[p.index as usize]))
                .collect();
            Pack(TrianglePack::pack(&lanes))
        });
        let offset = tris.len() as u32;
        let sphere_packs = pack_leaves(topo, PrimKind::Sphere, lanes, |prims| {
            let lanes: Vec<(u32, Sphere)> = prims
                .iter()
                .map(|p| (offset + p.index, spheres[p.index as usize]))
                .collect();
            Pack(SpherePack::pack(&lanes))
        });
        Self {
            triangles,
            unbounded: unbounded
                .chunks(lanes)
                .map(|c| Pack(TrianglePack::pack(c)))
                .collect(),
            spheres: sphere_packs,
            unbounded_spheres: unbounded_spheres
                .chunks(lanes)
                .map(|c| Pack(SpherePack::pack(c)))
                .collect(),
        }
    }
}

/// A bounding volume hierarchy over a triangle list and, optionally, a
/// sphere list ([`Bvh::build_prims`]), answering closest-hit queries
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
    triangles: usize,
    spheres: usize,
    build_seconds: f64,
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
    /// `tris.len() + j`. With no spheres this is [`Bvh::build_with`]: the
    /// same tree and the same hits. Uses the current rayon thread pool.
    ///
    /// # Panics
    ///
    /// With 2^29 or more primitives in all.
    pub fn build_prims(tris: &[TriangleEdges], spheres: &[Sphere], options: &BvhOptions) -> Bvh {
        let started = Instant::now();
        assert!(
            tris.len() + spheres.len() < (1 << 29),
            "a Bvh holds fewer than 2^29 primitives"
        );
        let width = if options.width.is_available() {
            options.width
        } else {
            SimdWidth::W8
        };
        let mut bvh = if tris.len() + spheres.len() <= small::MAX_PRIMS {
            small::build(tris, spheres, width)
        } else {
            // Big scenes: their largest triangles, if they dwarf the rest,
            // in front of the tree (no candidates built: too slow).
            let first = small::large_triangles(tris, width.lanes());
            let params = BuildParams {
                root_node: !first.is_empty(),
                ..BuildParams::for_lanes(width.lanes())
            };
            let mut bvh = Self::assemble(tris, spheres, &first, width, &params);
            // The wavefront's batches test those in ray packets, where that
            // counts cheaper, and walk the tree only for the rays that
            // reach its box.
            let finite = || tris.iter().all(TriangleEdges::is_finite);
            if !first.is_empty()
                && spheres.is_empty()
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

    /// The hierarchy over `tris` and `spheres` at `width`, built with
    /// `params`, but for the triangles in `first` (indices, increasing):
    /// those are tested before the walk, by every ray.
    fn assemble(
        tris: &[TriangleEdges],
        spheres: &[Sphere],
        first: &[u32],
        width: SimdWidth,
        params: &BuildParams,
    ) -> Bvh {
        let is_first = |i: usize| first.binary_search(&(i as u32)).is_ok();
        let mut prims: Vec<Prim> = tris
            .par_iter()
            .enumerate()
            .filter(|&(i, t)| t.is_finite() && !is_first(i))
            .map(|(i, t)| Prim {
                b: triangle_box(t),
                index: i as u32,
                kind: PrimKind::Triangle as u8,
            })
            .collect();
        let unbounded: Vec<(u32, TriangleEdges)> = tris
            .iter()
            .enumerate()
            .filter(|&(i, t)| !t.is_finite() || is_first(i))
            .map(|(i, t)| (i as u32, *t))
            .collect();
        // Spheres after the triangles, indexed among the spheres (the packs
        // add the triangles' count).
        prims.par_extend(spheres.par_iter().enumerate().filter_map(|(j, s)| {
            let (lo, hi) = s.bounds()?;
            Some(Prim {
                b: Aabb {
                    lo: lo.into(),
                    hi: hi.into(),
                },
                index: j as u32,
                kind: PrimKind::Sphere as u8,
            })
        }));
        let offset = tris.len() as u32;
        let unbounded_spheres: Vec<(u32, Sphere)> = spheres
            .iter()
            .enumerate()
            .filter(|(_, s)| s.bounds().is_none())
            .map(|(j, s)| (offset + j as u32, *s))
            .collect();
        let topo = build::build(prims, params);
        let mut bvh = Bvh {
            nodes: Vec::new(),
            root: topo.root,
            width,
            packs8: Packs::empty(),
            #[cfg(target_arch = "x86_64")]
            packs16: Packs::empty(),
            interleave: false,
            in_order: false,
            packets: packet::Plan::default(),
            triangles: tris.len(),
            spheres: spheres.len(),
            build_seconds: 0.0,
        };
        let (u, s, us) = (&unbounded, spheres, &unbounded_spheres);
        match width {
            SimdWidth::W8 => bvh.packs8 = Packs::new(&topo, tris, u, s, us),
            #[cfg(target_arch = "x86_64")]
            SimdWidth::W16 => bvh.packs16 = Packs::new(&topo, tris, u, s, us),
            #[cfg(not(target_arch = "x86_64"))]
            SimdWidth::W16 => unreachable!("16 lanes are x86-64 only"),
        }
        bvh.in_order = !topo.root.is_node() && unbounded.is_empty() && unbounded_spheres.is_empty();
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

    /// The closest hit of the ray `o + t·d` with `t_min < t < t_max`: the
    /// smallest `(t, primitive index)`, bit for bit what
    /// [`closest_hit_brute_force_prims`](crate::accel::sphere::closest_hit_brute_force_prims)
    /// returns (with no spheres:
    /// [`closest_hit_brute_force`](crate::accel::triangle::closest_hit_brute_force)).
    #[inline(never)]
    pub fn closest_hit(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        as_hit(self.one::<ClosestKind>(o, d, t_min, t_max))
    }

    /// Whether anything lies on the segment `o + t·d`, `t_min < t < t_max`:
    /// exactly when [`Bvh::closest_hit`] would find a hit there. Stops at
    /// the first primitive found (for shadow rays).
    #[inline(never)]
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
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
        out: impl FnMut(usize, bool),
    ) {
        self.many::<AnyHitKind>(n, ray, t_min, true, out);
    }

    /// [`Bvh::closest_hit`] (`occlusion = false`) or [`Bvh::occluded`]
    /// (`true`), counting the nodes, leaves and packs the walk visits: for
    /// tuning and benchmarks.
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

    /// The SIMD width of the packs and kernels in use.
    pub fn simd_width(&self) -> SimdWidth {
        self.width
    }

    /// Number of triangles the hierarchy was built over.
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// Number of spheres the hierarchy was built over (their primitive
    /// indices follow the triangles').
    pub fn sphere_count(&self) -> usize {
        self.spheres
    }

    /// Number of primitives, triangles and spheres.
    pub fn prim_count(&self) -> usize {
        self.triangles + self.spheres
    }

    /// Number of inner (8-wide) nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Number of packs (of 8 or 16; triangles and spheres) in the leaves.
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
            SimdWidth::W8 => self.packs8.unbounded.len(),
            #[cfg(target_arch = "x86_64")]
            SimdWidth::W16 => self.packs16.unbounded.len(),
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
        self.in_order && self.root.kind() == PrimKind::Triangle as u32
    }

    /// Test ray packets by `plan` in [`Bvh::closest_hits_columns`].
    fn set_packet_plan(&mut self, plan: packet::Plan) {
        self.packets = plan;
    }
}

/// A triangle's box (finite for a finite triangle).
#[inline]
fn triangle_box(t: &TriangleEdges) -> Aabb {
    let v0 = Vec3A::from(t.v0);
    let (v1, v2) = (v0 + Vec3A::from(t.e1), v0 + Vec3A::from(t.e2));
    Aabb {
        lo: v0.min(v1).min(v2),
        hi: v0.max(v1).max(v2),
    }
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
