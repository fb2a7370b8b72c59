//! Inner nodes (eight child boxes in structure-of-arrays form) and child
//! references.

use glam::{Vec3, Vec3A};
use wide::f32x8;

/// Kinds of primitive a leaf reference can tell apart (kind 3 is
/// reserved: it makes the empty reference). A kind's number is its place
/// in [`Kinds`](crate::accel::shape::Kinds).
pub const MAX_KINDS: usize = 3;

/// A child reference, 32 bits:
///
/// - [`Child::EMPTY`] (all ones): no child;
/// - bit 31 clear: an inner node, by index;
/// - bit 31 set: a leaf: its kind ([`Shape::KIND`](crate::accel::shape::Kind::KIND)) in bits 29–30, its number of
///   packs minus one in bits 27–28, and its first pack (in that kind's
///   pack list) in bits 0–26.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(transparent)]
pub(crate) struct Child(pub u32);

const LEAF: u32 = 1 << 31;
const KIND_SHIFT: u32 = 29;
const COUNT_SHIFT: u32 = 27;
const START_MASK: u32 = (1 << COUNT_SHIFT) - 1;

impl Child {
    /// No child.
    pub const EMPTY: Child = Child(u32::MAX);
    /// Packs one kind may have in all (the first pack's field).
    pub const MAX_PACKS: usize = 1 << COUNT_SHIFT;
    /// Most packs in one leaf.
    pub const MAX_LEAF_PACKS: usize = 4;

    /// The inner node `index`.
    pub fn node(index: usize) -> Child {
        assert!(index < LEAF as usize, "too many nodes");
        Child(index as u32)
    }

    /// A leaf of `count` packs of `kind` from `first` on.
    pub fn leaf(kind: u32, first: usize, count: usize) -> Child {
        assert!(
            first + count <= Self::MAX_PACKS,
            "a hierarchy holds at most 2^27 packs of one kind"
        );
        debug_assert!((1..=Self::MAX_LEAF_PACKS).contains(&count));
        debug_assert!((kind as usize) < MAX_KINDS);
        Child(LEAF | (kind << KIND_SHIFT) | (((count - 1) as u32) << COUNT_SHIFT) | first as u32)
    }

    /// Whether this is an inner node.
    #[inline(always)]
    pub fn is_node(self) -> bool {
        self.0 & LEAF == 0
    }

    /// The leaf's kind (3 for [`Child::EMPTY`]).
    #[inline(always)]
    pub fn kind(self) -> u32 {
        (self.0 >> KIND_SHIFT) & 3
    }

    /// The leaf's packs: first index and count.
    #[inline(always)]
    pub fn packs(self) -> (usize, usize) {
        (
            (self.0 & START_MASK) as usize,
            ((self.0 >> COUNT_SHIFT) & 3) as usize + 1,
        )
    }
}

/// Eight child boxes (SoA) and eight child references.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Node8 {
    /// Box planes per child: minimum corners in `planes[0..3]` (x, y, z;
    /// `+inf` for empty slots), maximum corners in `planes[3..6]` (`-inf`
    /// for empty slots).
    planes: [f32x8; 6],
    /// Child references.
    pub child: [Child; 8],
}

impl Node8 {
    /// A node with no children.
    pub const EMPTY: Node8 = Node8 {
        planes: [
            f32x8::splat(f32::INFINITY),
            f32x8::splat(f32::INFINITY),
            f32x8::splat(f32::INFINITY),
            f32x8::splat(f32::NEG_INFINITY),
            f32x8::splat(f32::NEG_INFINITY),
            f32x8::splat(f32::NEG_INFINITY),
        ],
        child: [Child::EMPTY; 8],
    };

    /// A node from its boxes (per axis, per child) and children.
    pub fn new(lo: [[f32; 8]; 3], hi: [[f32; 8]; 3], child: [Child; 8]) -> Self {
        let [lx, ly, lz] = lo.map(f32x8::from);
        let [hx, hy, hz] = hi.map(f32x8::from);
        Self {
            planes: [lx, ly, lz, hx, hy, hz],
            child,
        }
    }

    /// Which children the ray enters before `t_max` (a bit mask), and
    /// where it enters them.
    /// Child `i`'s box (padded), as `(lo, hi)`.
    pub fn child_box(&self, i: usize) -> (Vec3A, Vec3A) {
        let p = self.planes.map(|v| v.to_array()[i]);
        (Vec3A::new(p[0], p[1], p[2]), Vec3A::new(p[3], p[4], p[5]))
    }

    #[inline(always)]
    pub fn intersect(&self, r: &NodeRay, t_max: f32) -> (u32, f32x8) {
        // The box test has no scalar twin to agree with, so it may use fused
        // multiply-subtract: `b·(1/d) - o·(1/d)`. The boxes' padding covers
        // its rounding. The near plane of each axis is picked per ray (by
        // the sign of the direction) without a branch.
        let slab = |a: usize| {
            let near = self.planes[r.near[a] as usize];
            let far = self.planes[r.far[a] as usize];
            let (inv, o_inv) = (f32x8::splat(r.inv[a]), f32x8::splat(r.o_inv[a]));
            (near.mul_sub(inv, o_inv), far.mul_sub(inv, o_inv))
        };
        let (nx, fx) = slab(0);
        let (ny, fy) = slab(1);
        let (nz, fz) = slab(2);
        let t_near = nx.fast_max(ny).fast_max(nz.fast_max(f32x8::splat(r.t_min)));
        let t_far = fx.fast_min(fy).fast_min(fz.fast_min(f32x8::splat(t_max)));
        (t_near.simd_le(t_far).to_bitmask(), t_near)
    }
}

/// A ray prepared for box tests.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NodeRay {
    t_min: f32,
    inv: [f32; 3],
    o_inv: [f32; 3],
    /// Per axis, which of a node's planes the ray meets first and last.
    near: [u8; 3],
    far: [u8; 3],
}

impl NodeRay {
    #[inline(always)]
    pub fn new(o: Vec3, d: Vec3, t_min: f32) -> Self {
        // A zero direction component would make 0 * inf = NaN in the slab
        // test; a tiny one keeps every product finite or infinite.
        let safe = |x: f32| {
            if x.abs() < 1e-20 {
                1e-20f32.copysign(x)
            } else {
                x
            }
        };
        let inv = Vec3A::ONE / Vec3A::new(safe(d.x), safe(d.y), safe(d.z));
        let o_inv = Vec3A::from(o) * inv;
        let near = |x: f32, a: u8| if x < 0.0 { a + 3 } else { a };
        let far = |x: f32, a: u8| if x < 0.0 { a } else { a + 3 };
        Self {
            t_min,
            inv: inv.to_array(),
            o_inv: o_inv.to_array(),
            near: [near(inv.x, 0), near(inv.y, 1), near(inv.z, 2)],
            far: [far(inv.x, 0), far(inv.y, 1), far(inv.z, 2)],
        }
    }
}
