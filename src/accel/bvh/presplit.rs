//! Pre-splitting: the triangles whose box is much larger than their area
//! warrants (long thin triangles across an axis, as in CAD models) go to
//! the build as several references, each the box of the part of the
//! triangle inside a smaller region (Karras and Aila 2013, "Fast Parallel
//! Construction of High-Quality Bounding Volume Hierarchies"; Embree's
//! pre-splits). Every reference keeps its triangle's index, so a leaf's
//! lanes report the same `(t, index)` whichever reference the walk meets
//! it by (see "Exactness" in the module above).
//!
//! Opt-in ([`Bvh::build_shapes_presplit`](super::Bvh::build_shapes_presplit)):
//! measured on the CAD model it was made for, it costs more build than
//! it saves in the walk (`docs/performance.md`).
//!
//! # The counted rule
//!
//! - A triangle's priority is `(2^b · (A_box − A_ideal))^(1/3)`, where
//!   `A_box` is its box's half area, `A_ideal` the sum of its projected
//!   areas on the three axis planes (what the boxes of infinitely many
//!   pieces would sum to), and `b` the level of the coarsest plane of a
//!   `2^10`-cell grid over the scene that its box crosses (a triangle
//!   across the scene's middle counts most). A triangle whose box is no
//!   more than [`MIN_RATIO`] times its ideal area has priority 0.
//! - The extra references are at most `floor(share · N)` for `N`
//!   primitives (`share`: the build's parameter), each
//!   triangle getting `min(floor(p / λ), MAX_PIECES − 1)` of them (`p` its
//!   priority), with `λ` the smallest threshold, found by 32 halvings of
//!   `[0, max p]`, whose extra references sum to at most that budget (a
//!   sum of integers: the same on any thread count). At most
//!   [`MAX_PIECES`] pieces per triangle.
//! - A triangle is cut into that many pieces recursively: each region is
//!   cut at the coarsest grid plane inside it (the axis whose plane is
//!   coarsest, the longest on a tie; the middle of the longest axis where
//!   no grid plane falls inside), its pieces shared between the two sides
//!   by length.
//!
//! # Covering
//!
//! A piece's box is the box of the triangle's vertices on its side of the
//! plane and of the points where its edges cross the plane, intersected
//! with the region being cut (itself within the triangle's own box).
//! The crossing points are computed in `f64` and rounded outward, by a
//! margin of `2^-40` of the edge's larger coordinate and then one `f32`
//! step, which covers the `f64` rounding: each box contains the part of
//! the triangle inside its region, and the two sides of every cut share
//! the plane, so the boxes together cover the whole triangle, as its own
//! box did. The padding of the tree's boxes then covers the same
//! rounding in the kernels as before. A side whose box comes out empty
//! holds no part of the triangle and is dropped.

use super::build::{Aabb, Prim};
use glam::Vec3A;
use rayon::prelude::*;

/// Most pieces one triangle is cut into.
pub const MAX_PIECES: u32 = 16;

/// A triangle whose box's half area is at most this many times its ideal
/// area is not split.
pub const MIN_RATIO: f32 = 2.0;

/// The grid's cells per axis, as a power of two.
const GRID_BITS: u32 = 10;

/// The grid of split planes over the scene's box.
#[derive(Clone, Copy)]
struct Grid {
    lo: Vec3A,
    /// Cells per unit length (0 on a flat axis).
    scale: Vec3A,
    /// Cell size.
    cell: Vec3A,
}

impl Grid {
    fn new(b: &Aabb) -> Self {
        let ext = b.hi - b.lo;
        let n = (1u32 << GRID_BITS) as f32;
        let s = |e: f32| if e > 0.0 && e.is_finite() { n / e } else { 0.0 };
        Self {
            lo: b.lo,
            scale: Vec3A::new(s(ext.x), s(ext.y), s(ext.z)),
            cell: ext / n,
        }
    }

    fn cell_of(&self, x: f32, a: usize) -> u32 {
        let c = (x - self.lo[a]) * self.scale[a];
        (c.max(0.0) as u32).min((1 << GRID_BITS) - 1)
    }

    /// The level of the coarsest grid plane `b` crosses on axis `a` and
    /// that plane's cell number, or `None` where it crosses none.
    fn plane(&self, b: &Aabb, a: usize) -> Option<(u32, u32)> {
        let (l, h) = (self.cell_of(b.lo[a], a), self.cell_of(b.hi[a], a));
        let diff = l ^ h;
        (diff != 0).then(|| {
            let level = 31 - diff.leading_zeros();
            (level, h >> level << level)
        })
    }

    /// The coarsest level of plane `b` crosses on any axis (0 where none).
    fn level(&self, b: &Aabb) -> u32 {
        (0..3)
            .filter_map(|a| self.plane(b, a).map(|p| p.0 + 1))
            .max()
            .unwrap_or(0)
    }

    /// Where to cut region `b`: an axis and a position strictly inside it,
    /// or `None` where it has no extent.
    fn cut(&self, b: &Aabb) -> Option<(usize, f32)> {
        let ext = b.hi - b.lo;
        let mut best: Option<(u32, f32, usize, f32)> = None;
        for a in 0..3 {
            if let Some((level, k)) = self.plane(b, a) {
                let x = self.lo[a] + k as f32 * self.cell[a];
                let better =
                    best.is_none_or(|(l, e, _, _)| level > l || (level == l && ext[a] > e));
                if x > b.lo[a] && x < b.hi[a] && better {
                    best = Some((level, ext[a], a, x));
                }
            }
        }
        if let Some((_, _, a, x)) = best {
            return Some((a, x));
        }
        let a = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let x = 0.5 * (b.lo[a] + b.hi[a]);
        (x > b.lo[a] && x < b.hi[a]).then_some((a, x))
    }
}

/// The sum of a triangle's projected areas on the axis planes, halved as
/// [`Aabb::half_area`] is.
fn ideal_area(v: &[Vec3A; 3]) -> f32 {
    let c = (v[1] - v[0]).cross(v[2] - v[0]);
    0.5 * (c.x.abs() + c.y.abs() + c.z.abs())
}

/// `b` and `c`'s common part (empty where some `lo > hi`).
fn meet(b: &Aabb, c: &Aabb) -> Aabb {
    Aabb {
        lo: b.lo.max(c.lo),
        hi: b.hi.min(c.hi),
    }
}

fn is_empty(b: &Aabb) -> bool {
    b.lo.cmpgt(b.hi).any()
}

/// The boxes of the parts of triangle `v` on either side of the plane
/// `x` on axis `a` (conservative: see the module's "Covering").
fn clip(v: &[Vec3A; 3], a: usize, x: f32) -> (Aabb, Aabb) {
    let (mut l, mut r) = (Aabb::EMPTY, Aabb::EMPTY);
    for i in 0..3 {
        let (p, q) = (v[i], v[(i + 1) % 3]);
        if p[a] <= x {
            l.grow_point(p);
        }
        if p[a] >= x {
            r.grow_point(p);
        }
        if (p[a] < x && q[a] > x) || (p[a] > x && q[a] < x) {
            let (pd, qd) = (p.as_dvec3(), q.as_dvec3());
            let s = (x as f64 - pd[a]) / (qd[a] - pd[a]);
            let at = pd + (qd - pd) * s;
            let m = pd.abs().max(qd.abs()) * f64::powi(2.0, -40);
            let mut lo = Vec3A::new(
                ((at.x - m.x) as f32).next_down(),
                ((at.y - m.y) as f32).next_down(),
                ((at.z - m.z) as f32).next_down(),
            );
            let mut hi = Vec3A::new(
                ((at.x + m.x) as f32).next_up(),
                ((at.y + m.y) as f32).next_up(),
                ((at.z + m.z) as f32).next_up(),
            );
            lo[a] = x;
            hi[a] = x;
            for b in [&mut l, &mut r] {
                b.grow_point(lo);
                b.grow_point(hi);
            }
        }
    }
    (l, r)
}

/// Cut triangle `v`'s part in `region` into `n` pieces, pushing their
/// boxes (as `prim`'s references) to `out`.
fn cut(v: &[Vec3A; 3], region: Aabb, n: u32, grid: &Grid, prim: &Prim, out: &mut Vec<Prim>) {
    let plane = if n > 1 { grid.cut(&region) } else { None };
    let Some((a, x)) = plane else {
        out.push(Prim {
            b: region,
            piece: true,
            ..*prim
        });
        return;
    };
    let (l, r) = clip(v, a, x);
    let (l, r) = (meet(&l, &region), meet(&r, &region));
    match (is_empty(&l), is_empty(&r)) {
        (false, false) => {
            let share = (x - region.lo[a]) / (region.hi[a] - region.lo[a]);
            let nl = ((n as f32 * share).round() as u32).clamp(1, n - 1);
            cut(v, l, nl, grid, prim, out);
            cut(v, r, n - nl, grid, prim, out);
        }
        (false, true) => cut(v, l, n, grid, prim, out),
        (true, false) => cut(v, r, n, grid, prim, out),
        // Unreachable for a finite triangle (its vertices lie on one side
        // or the other); kept whole.
        (true, true) => out.push(Prim {
            b: region,
            piece: true,
            ..*prim
        }),
    }
}

/// The extra pieces of a triangle of priority `p` at threshold `lambda`.
#[inline]
fn extra(p: f32, lambda: f64) -> u32 {
    if lambda.is_finite() {
        (p as f64 / lambda).floor().min((MAX_PIECES - 1) as f64) as u32
    } else {
        0
    }
}

/// The smallest threshold `lambda` (of 32 halvings between the largest
/// priority and 0) whose extra pieces sum to at most `budget`; infinite
/// where none is found.
fn threshold(priorities: &[f32], budget: u64) -> f64 {
    let top = priorities.iter().fold(0.0f32, |m, &p| m.max(p)) as f64;
    // `top` is a maximum from 0 (`f32::max` skips NaN): never NaN.
    if top <= 0.0 {
        return f64::INFINITY;
    }
    let count = |lambda: f64| -> u64 {
        priorities
            .par_iter()
            .with_min_len(1 << 14)
            .map(|&p| extra(p, lambda) as u64)
            .sum()
    };
    // `count(hi) <= budget` throughout (0 at the top priority).
    let (mut lo, mut hi) = (0.0f64, top * 1.000_001);
    for _ in 0..32 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if count(mid) <= budget {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// `prims` with the triangles the counted rule picks (see the module)
/// cut into pieces: each cut triangle's first piece in its place, the
/// others after all the primitives, in order. `verts(p)` gives a
/// triangle's vertices (as its box was computed from them), `None` for
/// another kind. At most `floor(share · prims.len())` references are
/// added. Deterministic: the same list whatever the thread count.
pub(crate) fn presplit(
    mut prims: Vec<Prim>,
    share: f32,
    verts: impl Fn(&Prim) -> Option<[Vec3A; 3]> + Sync,
) -> Vec<Prim> {
    let budget = (share.max(0.0) as f64 * prims.len() as f64).floor();
    if budget < 1.0 {
        return prims;
    }
    let scene = prims
        .par_iter()
        .fold(
            || Aabb::EMPTY,
            |mut a, p| {
                a.grow(&p.b);
                a
            },
        )
        .reduce(
            || Aabb::EMPTY,
            |mut a, b| {
                a.grow(&b);
                a
            },
        );
    let grid = Grid::new(&scene);
    let priority = |p: &Prim| -> f32 {
        let Some(v) = verts(p) else { return 0.0 };
        let (area, ideal) = (p.b.half_area(), ideal_area(&v));
        if area.partial_cmp(&(MIN_RATIO * ideal)) != Some(std::cmp::Ordering::Greater) {
            return 0.0;
        }
        let level = grid.level(&p.b) as i32;
        (f32::powi(2.0, level) * (area - ideal)).cbrt()
    };
    let priorities: Vec<f32> = prims.par_iter().map(priority).collect();
    let lambda = threshold(&priorities, budget as u64);
    let pieces = |p: f32| -> u32 { extra(p, lambda) + 1 };
    let cuts: Vec<(usize, Vec<Prim>)> = prims
        .par_iter()
        .zip(priorities.par_iter())
        .enumerate()
        .filter(|(_, (_, p))| pieces(**p) > 1)
        .map(|(i, (prim, &p))| {
            let v = verts(prim).expect("a triangle has vertices");
            let mut out = Vec::with_capacity(pieces(p) as usize);
            cut(&v, prim.b, pieces(p), &grid, prim, &mut out);
            (i, out)
        })
        .collect();
    let extra: usize = cuts.iter().map(|(_, c)| c.len() - 1).sum();
    prims.reserve(extra);
    for (i, c) in cuts {
        prims[i] = c[0];
        prims.extend_from_slice(&c[1..]);
    }
    prims
}
