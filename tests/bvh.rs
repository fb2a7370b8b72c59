//! The BVH answers every closest-hit query exactly as brute force does:
//! the same triangle and the same `t`, bit for bit, at every SIMD width
//! the CPU runs (8 lanes, and 16 where it has AVX-512); and every
//! occlusion query exactly as that closest hit would. The same over
//! triangles and analytic spheres in one hierarchy, against
//! `closest_hit_brute_force_prims` (the same primitive index, triangles
//! first, and the same `t` bits).

use glam::Vec3;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use wavetrace::accel::bvh::{Bvh, BvhOptions};
use wavetrace::accel::simd::SimdWidth;
use wavetrace::accel::sphere::{Sphere, closest_hit_brute_force_prims};
use wavetrace::accel::triangle::{Hit, TriangleEdges, closest_hit_brute_force};
use wavetrace::scene::mesh::{cornell_box, geodesic_sphere, terrain};

fn edges(tris: &[[Vec3; 3]]) -> Vec<TriangleEdges> {
    tris.iter()
        .map(|v| TriangleEdges::from_edges(v[0], v[1] - v[0], v[2] - v[0]))
        .collect()
}

struct Rand(Pcg64Mcg);

impl Rand {
    fn new(seed: u64) -> Self {
        Self(Pcg64Mcg::new(
            0x2360_ED05_1FC6_5DA4_4385_DF64_9FCC_F645 ^ seed as u128,
        ))
    }
    fn f(&mut self) -> f32 {
        (self.0.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f()
    }
    fn point_in(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }
    fn dir(&mut self) -> Vec3 {
        loop {
            let v = self.point_in(Vec3::splat(-1.0), Vec3::splat(1.0));
            let l = v.length_squared();
            if l > 1e-6 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
    fn below(&mut self, n: usize) -> usize {
        (self.0.next_u64() % n as u64) as usize
    }
}

/// The hierarchy over `tris` at every width this CPU runs.
fn builds(tris: &[TriangleEdges]) -> Vec<Bvh> {
    SimdWidth::available()
        .into_iter()
        .map(|width| Bvh::build_with(tris, &BvhOptions { width }))
        .collect()
}

fn key(h: Option<Hit>) -> Option<(u32, u32)> {
    h.map(|h| (h.triangle, h.t.to_bits()))
}

/// The closest hit as every width finds it (they must agree).
fn closest(bvhs: &[Bvh], o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<(u32, u32)> {
    let k = key(bvhs[0].closest_hit(o, d, t_min, t_max));
    for b in &bvhs[1..] {
        assert_eq!(key(b.closest_hit(o, d, t_min, t_max)), k, "widths differ");
    }
    k
}

fn bounds(tris: &[TriangleEdges]) -> (Vec3, Vec3) {
    let mut lo = Vec3::INFINITY;
    let mut hi = Vec3::NEG_INFINITY;
    for t in tris {
        for v in [t.v0, t.v0 + t.e1, t.v0 + t.e2] {
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    (lo, hi)
}

/// Fire `rays` random rays (origins in the scene's box grown by 20%,
/// directions uniform) plus `surface` rays that start on a random triangle
/// and compare with brute force, at every width: closest hits one by one
/// and batched, and occlusion (one by one and batched) with `t_max` at, just
/// before and just after the closest hit and at random. Returns how many
/// hit.
fn check(tris: &[TriangleEdges], rays: usize, surface: usize, seed: u64) -> usize {
    let bvhs = builds(tris);
    let (lo, hi) = bounds(tris);
    let grow = (hi - lo) * 0.2 + Vec3::splat(1e-3);
    let eps = 1e-4 * lo.abs().max(hi.abs()).max_element().max(1.0);
    let mut r = Rand::new(seed);
    let mut hits = 0;
    let mut shadow: Vec<(Vec3, Vec3, f32, f32, bool)> = Vec::new();
    let mut one = |o: Vec3, d: Vec3, t_min: f32, t_max: f32, r: &mut Rand| {
        let want = closest_hit_brute_force(tris, o, d, t_min, t_max);
        for bvh in &bvhs {
            let got = bvh.closest_hit(o, d, t_min, t_max);
            assert_eq!(
                key(got),
                key(want),
                "{:?}: ray o={o:?} d={d:?} t_min={t_min} t_max={t_max}: bvh {got:?}, brute force {want:?}",
                bvh.simd_width()
            );
        }
        // Segments ending at, just before and just after the closest hit,
        // and at a random distance.
        let open = closest_hit_brute_force(tris, o, d, t_min, f32::INFINITY);
        let mut ends = vec![t_max, r.range(0.0, 2.0 * (hi - lo).length())];
        if let Some(h) = open {
            ends.extend([h.t, h.t.next_up(), h.t.next_down()]);
        }
        for end in ends {
            let want = open.is_some_and(|h| h.t < end);
            for bvh in &bvhs {
                assert_eq!(
                    bvh.occluded(o, d, t_min, end),
                    want,
                    "{:?}: occluded o={o:?} d={d:?} t_min={t_min} t_max={end}, closest {open:?}",
                    bvh.simd_width()
                );
            }
            shadow.push((o, d, t_min, end, want));
        }
        hits += want.is_some() as usize;
    };
    for i in 0..rays {
        let o = r.point_in(lo - grow, hi + grow);
        let d = r.dir();
        // Mostly open rays; some with a finite t_max, some with t_min = 0.
        let (t_min, t_max) = match i % 8 {
            0 => (0.0, f32::INFINITY),
            1 => (eps, r.range(0.0, (hi - lo).length())),
            _ => (eps, f32::INFINITY),
        };
        one(o, d, t_min, t_max, &mut r);
    }
    for i in 0..surface {
        let t = &tris[r.below(tris.len())];
        let (mut u, mut v) = (r.f(), r.f());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let o = t.v0 + t.e1 * u + t.e2 * v;
        if !o.is_finite() {
            continue;
        }
        let t_min = if i % 4 == 0 { 0.0 } else { eps };
        one(o, r.dir(), t_min, f32::INFINITY, &mut r);
    }
    // The batch queries give each ray's answer too.
    let mut r2 = Rand::new(seed ^ 0xba7c);
    let batch: Vec<(Vec3, Vec3)> = (0..rays.min(3000))
        .map(|_| (r2.point_in(lo - grow, hi + grow), r2.dir()))
        .collect();
    for bvh in &bvhs {
        let mut out = vec![None; batch.len()];
        bvh.closest_hits(&batch, eps, f32::INFINITY, &mut out);
        for (&(o, d), got) in batch.iter().zip(&out) {
            let want = closest_hit_brute_force(tris, o, d, eps, f32::INFINITY);
            assert_eq!(key(*got), key(want), "batch ray o={o:?} d={d:?}");
        }
        // Rays as columns (ray packets in a scene of one leaf), with a
        // short last packet, and a finite t_max.
        let half = 0.5 * (hi - lo).length();
        for (len, t_min, t_max) in [
            (batch.len(), eps, f32::INFINITY),
            (batch.len().saturating_sub(3), 0.0, half),
        ] {
            let col = |f: &dyn Fn(&(Vec3, Vec3)) -> f32| batch[..len].iter().map(f).collect();
            let o: [Vec<f32>; 3] = [col(&|r| r.0.x), col(&|r| r.0.y), col(&|r| r.0.z)];
            let d: [Vec<f32>; 3] = [col(&|r| r.1.x), col(&|r| r.1.y), col(&|r| r.1.z)];
            let (mut t, mut prim) = (vec![0.0; len], vec![0; len]);
            let (o, d) = (o.each_ref().map(|c| &c[..]), d.each_ref().map(|c| &c[..]));
            bvh.closest_hits_columns(o, d, (t_min, t_max), &mut t, &mut prim);
            for (i, &(o, d)) in batch[..len].iter().enumerate() {
                let want = closest_hit_brute_force(tris, o, d, t_min, t_max);
                let got = (prim[i] != u32::MAX).then_some(Hit {
                    triangle: prim[i],
                    t: t[i],
                });
                assert_eq!(
                    key(got),
                    key(want),
                    "column ray {i} of {len}: o={o:?} d={d:?}"
                );
            }
        }
        for t_min in [0.0, eps] {
            let seg: Vec<_> = shadow.iter().filter(|s| s.2 == t_min).collect();
            let rays: Vec<(Vec3, Vec3)> = seg.iter().map(|s| (s.0, s.1)).collect();
            let ends: Vec<f32> = seg.iter().map(|s| s.3).collect();
            let mut out = vec![false; seg.len()];
            bvh.occluded_batch(&rays, t_min, &ends, &mut out);
            for (s, got) in seg.iter().zip(out) {
                assert_eq!(got, s.4, "batch occluded {s:?}");
            }
            // As columns (in ray packets where the scene has them), the
            // answers starting from the opposite of the right ones.
            let col = |f: &dyn Fn(&(Vec3, Vec3)) -> f32| rays.iter().map(f).collect::<Vec<f32>>();
            let o = [col(&|r| r.0.x), col(&|r| r.0.y), col(&|r| r.0.z)];
            let d = [col(&|r| r.1.x), col(&|r| r.1.y), col(&|r| r.1.z)];
            let mut out: Vec<bool> = seg.iter().map(|s| !s.4).collect();
            let (o, d) = (o.each_ref().map(|c| &c[..]), d.each_ref().map(|c| &c[..]));
            bvh.occluded_columns(o, d, t_min, &ends, &mut out);
            for (s, got) in seg.iter().zip(out) {
                assert_eq!(
                    got,
                    s.4,
                    "{:?}: occluded as columns {s:?}",
                    bvh.simd_width()
                );
            }
        }
    }
    hits
}

fn soup(n: usize, seed: u64, size: f32) -> Vec<TriangleEdges> {
    let mut r = Rand::new(seed);
    (0..n)
        .map(|_| {
            let v0 = r.point_in(Vec3::splat(-1.0), Vec3::splat(1.0));
            TriangleEdges::from_edges(
                v0,
                r.dir() * r.range(0.0, size),
                r.dir() * r.range(0.0, size),
            )
        })
        .collect()
}

#[test]
fn empty_and_single() {
    let bvh = Bvh::build(&[]);
    assert_eq!(
        bvh.closest_hit(Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY),
        None
    );
    assert_eq!(bvh.node_count(), 0);
    check(&soup(1, 1, 0.5), 500, 20, 1);
}

#[test]
fn small_soups() {
    for n in [2, 7, 8, 9, 31, 32, 33, 100, 1000] {
        let hits = check(&soup(n, n as u64, 0.3), 2000, 200, n as u64);
        assert!(hits > 0);
    }
}

#[test]
fn cornell_box_equals_brute_force() {
    let tris = edges(&cornell_box());
    let hits = check(&tris, 20_000, 2000, 3);
    assert!(hits > 10_000, "{hits} hits");
}

#[test]
fn soup_10k() {
    check(&soup(10_000, 10, 0.1), 3000, 1000, 10);
}

#[test]
fn sphere_in_box_100k() {
    let mut tris = cornell_box();
    tris.extend(geodesic_sphere(Vec3::new(0.1, 0.2, 0.0), 0.5, 100_000));
    let tris = edges(&tris);
    assert!(tris.len() > 100_000);
    // The box's triangles dwarf the sphere's: they go in front of the tree
    // (one or two packs, by width), and the hits stay brute force's.
    // Batches of rays as columns test them in ray packets, and walk the
    // tree for the rays that enter its box.
    for bvh in builds(&tris) {
        let lanes = bvh.simd_width().lanes();
        assert_eq!(
            bvh.first_pack_count(),
            32usize.div_ceil(lanes),
            "{lanes} lanes"
        );
        assert!(bvh.packet_plan().is_some(), "{lanes} lanes");
    }
    check(&tris, 1500, 500, 4);
}

/// Columns of rays through `bvh`: each one's `(primitive, t bits)`.
fn column_hits(bvh: &Bvh, rays: &[(Vec3, Vec3)], t_min: f32) -> Vec<Option<(u32, u32)>> {
    let col = |f: &dyn Fn(&(Vec3, Vec3)) -> f32| rays.iter().map(f).collect::<Vec<f32>>();
    let o = [col(&|r| r.0.x), col(&|r| r.0.y), col(&|r| r.0.z)];
    let d = [col(&|r| r.1.x), col(&|r| r.1.y), col(&|r| r.1.z)];
    let (mut t, mut prim) = (vec![0.0; rays.len()], vec![0; rays.len()]);
    let (o, d) = (o.each_ref().map(|c| &c[..]), d.each_ref().map(|c| &c[..]));
    bvh.closest_hits_columns(o, d, (t_min, f32::INFINITY), &mut t, &mut prim);
    let hit = |(&p, &t): (&u32, &f32)| (p != u32::MAX).then_some((p, t.to_bits()));
    prim.iter().zip(&t).map(hit).collect()
}

#[test]
fn ties_between_the_packets_and_the_tree_behind_them() {
    // A floor of two large triangles (in front of the tree, tested in ray
    // packets) and, in its plane, a grid of small right triangles (the
    // tree) over part of it. Every edge is a power of two, so both give
    // a ray the same `t`, bit for bit: the lower index must win, whether
    // that is the floor's (packets) or a small one's (tree), and the walk
    // behind the packets must find the small ones at exactly the packets'
    // `t`. Walls of more large triangles make the room.
    let big = |lo: Vec3, a: Vec3, b: Vec3| {
        [
            TriangleEdges::from_edges(lo, a, b),
            TriangleEdges::from_edges(lo + a + b, -a, -b),
        ]
    };
    let (x, z) = (Vec3::X * 2.0, Vec3::Z * 2.0);
    let room: Vec<TriangleEdges> = [
        big(Vec3::new(-1.0, 0.0, -1.0), x, z),
        big(Vec3::new(-1.0, 2.0, -1.0), x, z),
        big(Vec3::new(-1.0, 0.0, 1.0), x, Vec3::Y * 2.0),
        big(Vec3::new(-1.0, 0.0, -1.0), z, Vec3::Y * 2.0),
    ]
    .concat();
    let small: Vec<TriangleEdges> = (0..32 * 32)
        .map(|k| {
            let corner = Vec3::new(
                -0.5 + (k % 32) as f32 / 32.0,
                0.0,
                -0.5 + (k / 32) as f32 / 32.0,
            );
            TriangleEdges::from_edges(corner, Vec3::X / 32.0, Vec3::Z / 32.0)
        })
        .collect();
    let mut r = Rand::new(31);
    let rays: Vec<(Vec3, Vec3)> = (0..20_000)
        .map(|_| {
            let o = r.point_in(Vec3::new(-0.9, 0.1, -0.9), Vec3::new(0.9, 1.9, 0.9));
            let target = r.point_in(Vec3::new(-0.7, 0.0, -0.7), Vec3::new(0.7, 0.0, 0.7));
            (o, (target - o).normalize())
        })
        .collect();
    // Rays on which the room's closest hit and the small triangles' are
    // at the same `t`.
    let t_of = |tris: &[TriangleEdges], (o, d): (Vec3, Vec3)| {
        closest_hit_brute_force(tris, o, d, 1e-4, f32::INFINITY).map(|h| h.t.to_bits())
    };
    let ties = rays
        .iter()
        .filter(|&&r| t_of(&small, r).is_some_and(|t| Some(t) == t_of(&room, r)))
        .count();
    assert!(ties > 5_000, "{ties} ties of 20000");
    for room_first in [true, false] {
        let tris = if room_first {
            [&room[..], &small[..]].concat()
        } else {
            [&small[..], &room[..]].concat()
        };
        for bvh in builds(&tris) {
            assert!(bvh.packet_plan().is_some(), "the room goes in packets");
            for (i, (&(o, d), got)) in rays.iter().zip(column_hits(&bvh, &rays, 1e-4)).enumerate() {
                let want = key(closest_hit_brute_force(&tris, o, d, 1e-4, f32::INFINITY));
                assert_eq!(got, want, "{:?} ray {i}: o={o:?} d={d:?}", bvh.simd_width());
            }
        }
    }
}

#[test]
fn terrain_100k() {
    let tris = edges(&terrain(Vec3::ZERO, [4.0, 4.0], 1.0, 100_000, 5));
    check(&tris, 1000, 500, 5);
}

#[test]
fn flat_zero_thickness_mesh() {
    // A terrain of height 0: every triangle in the plane y = 0, the BVH's
    // boxes all flat. Rays in the plane, parallel above it, and through it.
    let tris = edges(&terrain(
        Vec3::new(0.3, 0.0, -0.2),
        [3.0, 2.0],
        0.0,
        20_000,
        6,
    ));
    let hits = check(&tris, 3000, 1000, 6);
    assert!(hits > 0);
    let bvh = builds(&tris);
    let mut r = Rand::new(66);
    for _ in 0..2000 {
        let o = r.point_in(Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 0.0, 2.0));
        let mut d = r.dir();
        d.y = 0.0;
        let d = d.normalize();
        for o in [o, o + Vec3::Y * 1e-3, o - Vec3::Y * 1e-7] {
            let want = closest_hit_brute_force(&tris, o, d, 1e-4, f32::INFINITY);
            assert_eq!(closest(&bvh, o, d, 1e-4, f32::INFINITY), key(want));
        }
    }
    // Axis-aligned rays straight down onto the plane, including onto
    // shared edges and vertices of the grid (ties broken by index).
    for i in 0..=40 {
        for j in 0..=40 {
            let o = Vec3::new(
                -1.2 + 0.3 * i as f32 / 4.0,
                1.0,
                -1.2 + 0.2 * j as f32 / 4.0,
            );
            let want = closest_hit_brute_force(&tris, o, -Vec3::Y, 1e-4, f32::INFINITY);
            assert_eq!(closest(&bvh, o, -Vec3::Y, 1e-4, f32::INFINITY), key(want));
        }
    }
}

#[test]
fn degenerate_and_duplicate_triangles() {
    let mut r = Rand::new(7);
    let mut tris = soup(3000, 7, 0.2);
    for i in 0..3000 {
        let v0 = r.point_in(Vec3::splat(-1.0), Vec3::splat(1.0));
        let e = r.dir() * 0.3;
        tris.push(match i % 5 {
            // A point, a segment, a collinear triangle.
            0 => TriangleEdges::from_edges(v0, Vec3::ZERO, Vec3::ZERO),
            1 => TriangleEdges::from_edges(v0, e, Vec3::ZERO),
            2 => TriangleEdges::from_edges(v0, e, e * 2.0),
            // An exact duplicate of an earlier triangle: ties go to the
            // lower index.
            3 => tris[r.below(3000)],
            // A needle: almost degenerate.
            _ => TriangleEdges::from_edges(v0, e, e + Vec3::splat(1e-6)),
        });
    }
    // Non-finite triangles are kept out of the tree but still tested.
    tris.push(TriangleEdges::from_edges(
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::X,
        Vec3::Y,
    ));
    tris.push(TriangleEdges::from_edges(
        Vec3::ZERO,
        Vec3::new(f32::INFINITY, 0.0, 0.0),
        Vec3::Y,
    ));
    check(&tris, 4000, 2000, 7);
}

#[test]
fn many_triangles_sharing_one_point() {
    // 20k triangles fanning out from the origin in every direction, and a
    // second fan around a point they all touch with an edge.
    let mut r = Rand::new(8);
    let mut tris = Vec::new();
    for _ in 0..20_000 {
        tris.push(TriangleEdges::from_edges(
            Vec3::ZERO,
            r.dir() * r.range(0.01, 1.0),
            r.dir() * r.range(0.01, 1.0),
        ));
    }
    check(&tris, 2000, 500, 8);
    // Rays aimed exactly at the shared point.
    let bvh = builds(&tris);
    for _ in 0..500 {
        let o = r.dir() * 2.0;
        let d = (-o).normalize();
        let want = closest_hit_brute_force(&tris, o, d, 1e-4, f32::INFINITY);
        assert_eq!(closest(&bvh, o, d, 1e-4, f32::INFINITY), key(want));
    }
}

#[test]
fn far_and_tiny_scenes() {
    // Coordinates far from the origin, and a scene a thousandth of a unit big.
    let far: Vec<TriangleEdges> = soup(2000, 9, 0.1)
        .into_iter()
        .map(|t| TriangleEdges {
            v0: t.v0 * 10.0 + Vec3::new(1000.0, -500.0, 250.0),
            ..t
        })
        .collect();
    check(&far, 2000, 500, 9);
    let tiny: Vec<TriangleEdges> = soup(2000, 10, 0.1)
        .into_iter()
        .map(|t| TriangleEdges::from_edges(t.v0 * 1e-3, t.e1 * 1e-3, t.e2 * 1e-3))
        .collect();
    check(&tiny, 2000, 500, 10);
}

#[test]
fn axis_aligned_rays_and_boxes() {
    // Axis-aligned quads on a lattice hit by axis-aligned rays: slab tests
    // with zero direction components and rays along box faces.
    let mut tris = Vec::new();
    for i in 0..20 {
        for j in 0..20 {
            let v0 = Vec3::new(i as f32 * 0.1, j as f32 * 0.1, (i + j) as f32 * 0.05);
            tris.push(TriangleEdges::from_edges(v0, Vec3::X * 0.1, Vec3::Y * 0.1));
            tris.push(TriangleEdges::from_edges(
                v0 + Vec3::new(0.1, 0.1, 0.0),
                -Vec3::X * 0.1,
                -Vec3::Y * 0.1,
            ));
        }
    }
    let bvh = builds(&tris);
    for i in 0..=80 {
        for j in 0..=80 {
            let (x, y) = (i as f32 * 0.025, j as f32 * 0.025);
            for (o, d) in [
                (Vec3::new(x, y, -1.0), Vec3::Z),
                (Vec3::new(x, y, 3.0), -Vec3::Z),
                (Vec3::new(-1.0, y, x), Vec3::X),
                (Vec3::new(x, -1.0, y), Vec3::Y),
            ] {
                let want = closest_hit_brute_force(&tris, o, d, 1e-4, f32::INFINITY);
                assert_eq!(closest(&bvh, o, d, 1e-4, f32::INFINITY), key(want));
            }
        }
    }
}

#[test]
fn stats_are_sane() {
    let tris = edges(&geodesic_sphere(Vec3::ZERO, 1.0, 50_000));
    for bvh in builds(&tris) {
        let lanes = bvh.simd_width().lanes();
        assert_eq!(bvh.triangle_count(), tris.len());
        assert!(bvh.node_count() > 0);
        assert!(bvh.pack_count() * lanes >= tris.len());
        // A full pack is 52 bytes per triangle (v0, e1, e2, n and an
        // index); packs mostly full and nodes shared: under 80 bytes per
        // triangle at 8 lanes, 100 at 16.
        let limit = if lanes == 8 { 80 } else { 100 };
        assert!(
            bvh.bytes() < limit * tris.len(),
            "{lanes} lanes: {} bytes",
            bvh.bytes()
        );
        assert!(bvh.build_seconds() > 0.0);
    }
    // The Cornell box is one leaf: no inner node to walk.
    let cornell = edges(&cornell_box());
    for b in builds(&cornell) {
        assert_eq!(b.node_count(), 0);
        assert_eq!(b.pack_count(), 32 / b.simd_width().lanes());
    }
}

// ---------------------------------------------------------------------------
// Triangles and spheres in one hierarchy.

/// The hierarchy over `tris` and `spheres` at every width this CPU runs.
fn builds_prims(tris: &[TriangleEdges], spheres: &[Sphere]) -> Vec<Bvh> {
    SimdWidth::available()
        .into_iter()
        .map(|width| Bvh::build_prims(tris, spheres, &BvhOptions { width }))
        .collect()
}

fn prim_bounds(tris: &[TriangleEdges], spheres: &[Sphere]) -> (Vec3, Vec3) {
    let (mut lo, mut hi) = if tris.is_empty() {
        (Vec3::INFINITY, Vec3::NEG_INFINITY)
    } else {
        bounds(tris)
    };
    for s in spheres {
        if let Some((a, b)) = s.bounds() {
            lo = lo.min(a);
            hi = hi.max(b);
        }
    }
    (lo, hi)
}

/// What the mixed check saw: rays, hits, of which on spheres, and ties
/// (the closest `t` reached by two primitives or more).
#[derive(Debug, Default)]
struct Seen {
    rays: usize,
    hits: usize,
    sphere_hits: usize,
}

/// [`check`] over triangles and spheres: `rays` rays of every kind —
/// uniform, aimed at a sphere's inside, grazing a sphere (aimed at
/// `r (1 ± ε)` from its center, `ε` down to 1e-9), starting inside a
/// sphere, starting on a sphere's surface (with `t_min` 0 or above the
/// noise), starting on a triangle, aimed at a triangle's vertex — each
/// compared with [`closest_hit_brute_force_prims`] at every width (same
/// primitive, same `t` bits), one by one and batched, and occlusion with
/// `t_max` at, one ulp either side of, and away from the closest hit.
fn check_prims(tris: &[TriangleEdges], spheres: &[Sphere], rays: usize, seed: u64) -> Seen {
    let bvhs = builds_prims(tris, spheres);
    for b in &bvhs {
        assert_eq!(b.triangle_count(), tris.len());
        assert_eq!(b.count_of::<Sphere>(), spheres.len());
        assert_eq!(b.prim_count(), tris.len() + spheres.len());
    }
    let (lo, hi) = prim_bounds(tris, spheres);
    let grow = (hi - lo) * 0.2 + Vec3::splat(1e-3);
    let eps = 1e-4 * lo.abs().max(hi.abs()).max_element().max(1.0);
    let bounded: Vec<&Sphere> = spheres.iter().filter(|s| s.bounds().is_some()).collect();
    let mut r = Rand::new(seed);
    let mut seen = Seen::default();
    let mut shadow: Vec<(Vec3, Vec3, f32, f32, bool)> = Vec::new();
    let mut batch: Vec<(Vec3, Vec3, f32)> = Vec::new();
    for i in 0..rays {
        let kind = i % 8;
        let (o, d, t_min) = match kind {
            _ if bounded.is_empty() && kind < 5 => (r.point_in(lo - grow, hi + grow), r.dir(), eps),
            0 => (r.point_in(lo - grow, hi + grow), r.dir(), eps),
            1 => {
                let s = bounded[r.below(bounded.len())];
                let o = r.point_in(lo - grow, hi + grow);
                let target = s.center + r.dir() * s.radius * 0.99 * r.f();
                (o, (target - o).normalize_or(Vec3::Z), eps)
            }
            2 => {
                // Grazing: tangent distance r (1 ± ε).
                let s = bounded[r.below(bounded.len())];
                let o = r.point_in(lo - grow, hi + grow);
                let e = (s.center - o).normalize_or(Vec3::X);
                let p = e.any_orthonormal_vector();
                let q = e.cross(p);
                let a = r.range(0.0, std::f32::consts::TAU);
                let side = p * a.cos() + q * a.sin();
                let k = 10f32.powf(r.range(-9.0, -2.0)) * if r.f() < 0.5 { -1.0 } else { 1.0 };
                let target = s.center + side * s.radius * (1.0 + k);
                (o, (target - o).normalize_or(Vec3::Z), eps)
            }
            3 => {
                // Inside a sphere (t_min 0 or eps).
                let s = bounded[r.below(bounded.len())];
                let o = s.center + r.dir() * s.radius * 0.999 * r.f().cbrt();
                (o, r.dir(), if i % 16 == 3 { 0.0 } else { eps })
            }
            4 => {
                // On a sphere's surface, leaving or entering.
                let s = bounded[r.below(bounded.len())];
                let o = s.center + r.dir() * s.radius;
                (o, r.dir(), if i % 16 == 4 { 0.0 } else { eps })
            }
            5 if !tris.is_empty() => {
                let t = &tris[r.below(tris.len())];
                let (mut u, mut v) = (r.f(), r.f());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                (t.v0 + t.e1 * u + t.e2 * v, r.dir(), eps)
            }
            6 if !tris.is_empty() => {
                let t = &tris[r.below(tris.len())];
                let target = [t.v0, t.v0 + t.e1, t.v0 + t.e1 * 0.5 + t.e2 * 0.5][i % 3];
                let o = r.point_in(lo - grow, hi + grow);
                (o, (target - o).normalize_or(Vec3::Z), 0.0)
            }
            _ => (r.point_in(lo - grow, hi + grow), r.dir(), 0.0),
        };
        if !o.is_finite() || !d.is_finite() {
            continue;
        }
        let t_max = if i % 11 == 0 {
            r.range(0.0, (hi - lo).length())
        } else {
            f32::INFINITY
        };
        let want = closest_hit_brute_force_prims(tris, spheres, o, d, t_min, t_max);
        for bvh in &bvhs {
            let got = bvh.closest_hit(o, d, t_min, t_max);
            assert_eq!(
                key(got),
                key(want),
                "{:?}: ray kind {kind} o={o:?} d={d:?} t_min={t_min} t_max={t_max}: bvh {got:?}, brute force {want:?}",
                bvh.simd_width()
            );
        }
        seen.rays += 1;
        if let Some(h) = want {
            seen.hits += 1;
            seen.sphere_hits += (h.triangle as usize >= tris.len()) as usize;
        }
        let open = closest_hit_brute_force_prims(tris, spheres, o, d, t_min, f32::INFINITY);
        let mut ends = vec![r.range(0.0, 2.0 * (hi - lo).length())];
        if let Some(h) = open {
            ends.push([h.t, h.t.next_up(), h.t.next_down()][i % 3]);
        }
        for end in ends {
            let want = open.is_some_and(|h| h.t < end);
            for bvh in &bvhs {
                assert_eq!(
                    bvh.occluded(o, d, t_min, end),
                    want,
                    "{:?}: occluded kind {kind} o={o:?} d={d:?} t_min={t_min} t_max={end}, closest {open:?}",
                    bvh.simd_width()
                );
            }
            if shadow.len() < 20_000 {
                shadow.push((o, d, t_min, end, want));
            }
        }
        if batch.len() < 20_000 {
            batch.push((o, d, t_min));
        }
    }
    // Batched queries, per t_min.
    for t_min in [0.0, eps] {
        let rs: Vec<(Vec3, Vec3)> = batch
            .iter()
            .filter(|b| b.2 == t_min)
            .map(|b| (b.0, b.1))
            .collect();
        let seg: Vec<_> = shadow.iter().filter(|s| s.2 == t_min).collect();
        let srays: Vec<(Vec3, Vec3)> = seg.iter().map(|s| (s.0, s.1)).collect();
        let ends: Vec<f32> = seg.iter().map(|s| s.3).collect();
        for bvh in &bvhs {
            let mut out = vec![None; rs.len()];
            bvh.closest_hits(&rs, t_min, f32::INFINITY, &mut out);
            for (&(o, d), got) in rs.iter().zip(&out) {
                let want = closest_hit_brute_force_prims(tris, spheres, o, d, t_min, f32::INFINITY);
                assert_eq!(key(*got), key(want), "batch ray o={o:?} d={d:?}");
            }
            let mut out = vec![false; seg.len()];
            bvh.occluded_batch(&srays, t_min, &ends, &mut out);
            for (s, got) in seg.iter().zip(out) {
                assert_eq!(got, s.4, "batch occluded {s:?}");
            }
        }
    }
    seen
}

/// `n` spheres with centers in `[-1, 1]³` and radii log-uniform in
/// `[r_lo, r_hi]`.
fn sphere_soup(n: usize, seed: u64, r_lo: f32, r_hi: f32) -> Vec<Sphere> {
    let mut r = Rand::new(seed);
    (0..n)
        .map(|_| {
            let c = r.point_in(Vec3::splat(-1.0), Vec3::splat(1.0));
            let radius = (r_lo.ln() + (r_hi.ln() - r_lo.ln()) * r.f()).exp();
            Sphere::new(c, radius)
        })
        .collect()
}

#[test]
fn spheres_in_the_cornell_box_equal_brute_force() {
    // Spheres resting on the floor, touching a wall, overlapping, nested,
    // and one duplicated (ties between spheres go to the lower index).
    let tris = edges(&cornell_box());
    let mut spheres = vec![
        Sphere::new(Vec3::new(-0.4, -0.7, -0.3), 0.3),
        Sphere::new(Vec3::new(0.4, -0.75, 0.2), 0.25),
        Sphere::new(Vec3::new(0.5, -0.5, 0.3), 0.2),
        Sphere::new(Vec3::new(0.4, -0.75, 0.2), 0.1),
        Sphere::new(Vec3::new(0.0, 0.3, 0.0), 0.05),
    ];
    spheres.push(spheres[0]);
    let seen = check_prims(&tris, &spheres, 300_000, 21);
    eprintln!("{seen:?}");
    assert!(
        seen.hits > seen.rays / 2 && seen.sphere_hits > seen.rays / 10,
        "{seen:?}"
    );
}

#[test]
fn sphere_and_triangle_soup_equals_brute_force() {
    let tris = soup(600, 22, 0.2);
    let spheres = sphere_soup(600, 22, 1e-3, 0.1);
    let seen = check_prims(&tris, &spheres, 250_000, 22);
    eprintln!("{seen:?}");
    assert!(seen.sphere_hits > seen.rays / 4, "{seen:?}");
}

#[test]
fn overlapping_nested_and_duplicate_spheres() {
    // Concentric shells, many duplicates, spheres of every size: ties and
    // rays starting inside several spheres at once.
    let mut r = Rand::new(23);
    let mut spheres = sphere_soup(300, 23, 1e-3, 0.5);
    for i in 0..150 {
        let s = spheres[r.below(spheres.len())];
        spheres.push(match i % 3 {
            0 => s,
            1 => Sphere::new(s.center, s.radius * 0.5),
            _ => Sphere::new(s.center + r.dir() * s.radius, s.radius),
        });
    }
    let tris = soup(100, 23, 0.3);
    let seen = check_prims(&tris, &spheres, 250_000, 23);
    eprintln!("{seen:?}");
    assert!(seen.sphere_hits > seen.rays / 3, "{seen:?}");
}

#[test]
fn spheres_only_and_small_counts() {
    // A tree of one sphere leaf (tested in index order) and trees of a few
    // leaves, with and without triangles.
    for n in [1, 2, 7, 8, 9, 16, 17, 64, 65, 200] {
        let spheres = sphere_soup(n, 24 + n as u64, 0.05, 0.5);
        check_prims(&[], &spheres, 8_000, n as u64);
        check_prims(&soup(n, n as u64, 0.3), &spheres, 4_000, n as u64);
    }
    let bvh = Bvh::build_prims(&[], &[], &BvhOptions::default());
    assert_eq!(
        bvh.closest_hit(Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY),
        None
    );
}

#[test]
fn many_spheres_and_a_mesh_equal_brute_force() {
    // 30k small spheres around a 30k-triangle geodesic sphere in the box.
    let mut tris = cornell_box();
    tris.extend(geodesic_sphere(Vec3::new(0.1, 0.2, 0.0), 0.5, 30_000));
    let tris = edges(&tris);
    let spheres = sphere_soup(30_000, 25, 1e-3, 2e-2);
    let seen = check_prims(&tris, &spheres, 6_000, 25);
    eprintln!("{seen:?}");
    assert!(seen.sphere_hits > 0);
}

#[test]
fn far_and_tiny_sphere_scenes() {
    let far: Vec<Sphere> = sphere_soup(500, 26, 1e-2, 0.2)
        .into_iter()
        .map(|s| {
            Sphere::new(
                s.center * 10.0 + Vec3::new(1000.0, -500.0, 250.0),
                s.radius * 10.0,
            )
        })
        .collect();
    check_prims(&[], &far, 30_000, 26);
    let tiny: Vec<Sphere> = sphere_soup(500, 27, 1e-2, 0.2)
        .into_iter()
        .map(|s| Sphere::new(s.center * 1e-3, s.radius * 1e-3))
        .collect();
    let tiny_tris: Vec<TriangleEdges> = soup(200, 27, 0.1)
        .into_iter()
        .map(|t| TriangleEdges::from_edges(t.v0 * 1e-3, t.e1 * 1e-3, t.e2 * 1e-3))
        .collect();
    check_prims(&tiny_tris, &tiny, 30_000, 27);
}

#[test]
fn non_finite_and_degenerate_spheres() {
    // Kept out of the tree (no box) but tested against every ray, as brute
    // force does; zero and negative radii are ordinary spheres to both.
    let mut spheres = sphere_soup(200, 28, 0.01, 0.2);
    spheres.extend([
        Sphere::new(Vec3::new(f32::NAN, 0.0, 0.0), 0.5),
        Sphere::new(Vec3::ZERO, f32::INFINITY),
        Sphere::new(Vec3::new(f32::INFINITY, 0.0, 0.0), 1.0),
        Sphere::new(Vec3::new(0.2, 0.1, 0.0), 0.0),
        Sphere::new(Vec3::new(-0.2, 0.1, 0.0), -0.3),
        Sphere::new(Vec3::new(3e38, 0.0, 0.0), 1e38),
    ]);
    check_prims(&soup(100, 28, 0.3), &spheres, 40_000, 28);
}

#[test]
fn ties_across_kinds_go_to_the_lower_index() {
    // A floor of two triangles at y = 0 and spheres resting on it: a ray
    // straight up through the contact point meets both at exactly t = 5.
    let floor = vec![
        TriangleEdges::new(
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, 2.0),
        ),
        TriangleEdges::new(
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(-2.0, 0.0, 2.0),
        ),
    ];
    let mut spheres = Vec::new();
    for i in 0..40 {
        let x = -1.5 + 0.075 * i as f32;
        spheres.push(Sphere::new(Vec3::new(x, 0.5, 0.25), 0.5));
        // A duplicate, and one hanging below the floor (elsewhere in z).
        spheres.push(Sphere::new(Vec3::new(x, 0.5, 0.25), 0.5));
        spheres.push(Sphere::new(Vec3::new(x, -0.5, -0.9), 0.5));
    }
    let mut ties = 0;
    for bvh in builds_prims(&floor, &spheres) {
        for (i, s) in spheres.iter().enumerate() {
            for (o, d) in [
                (s.center - Vec3::Y * 5.5, Vec3::Y),
                (s.center + Vec3::Y * 5.5, -Vec3::Y),
            ] {
                let want =
                    closest_hit_brute_force_prims(&floor, &spheres, o, d, 1e-4, f32::INFINITY)
                        .unwrap();
                let got = bvh.closest_hit(o, d, 1e-4, f32::INFINITY).unwrap();
                assert_eq!(key(Some(got)), key(Some(want)), "sphere {i}, d={d:?}");
                // Which primitives reach that t exactly?
                let at: Vec<u32> = (0..floor.len() + spheres.len())
                    .filter(|&k| {
                        let (t, s) = if k < floor.len() {
                            (std::slice::from_ref(&floor[k]), &[][..])
                        } else {
                            (&[][..], std::slice::from_ref(&spheres[k - floor.len()]))
                        };
                        closest_hit_brute_force_prims(t, s, o, d, 1e-4, f32::INFINITY)
                            .is_some_and(|h| h.t == want.t)
                    })
                    .map(|k| k as u32)
                    .collect();
                assert_eq!(want.triangle, at[0], "the lowest index of {at:?}");
                ties += (at.len() > 1) as usize;
            }
        }
    }
    assert!(ties > 100, "{ties} ties");
}

#[test]
fn ties_between_copies_in_different_leaves() {
    // 300 copies of one sphere and 300 of one triangle through it: more
    // than a leaf holds, so the copies spread over several leaves in no
    // particular order, and a lane meets equal `t`s from different packs.
    // Every hit must be the first copy (of the sphere or the triangle),
    // whichever leaf the walk reaches first.
    let tri = TriangleEdges::new(
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 0.0, -1.0),
        Vec3::new(0.0, 0.0, 1.0),
    );
    let mut tris = soup(50, 29, 0.2);
    let first_tri = tris.len() as u32;
    tris.extend(std::iter::repeat_n(tri, 300));
    let mut spheres = sphere_soup(50, 29, 0.01, 0.1);
    let first_sphere = (tris.len() + spheres.len()) as u32;
    spheres.extend(std::iter::repeat_n(
        Sphere::new(Vec3::new(0.1, 0.3, -0.2), 0.4),
        300,
    ));
    let bvhs = builds_prims(&tris, &spheres);
    let mut r = Rand::new(29);
    let (mut on_tri, mut on_sphere) = (0, 0);
    for _ in 0..20_000 {
        let o = r.point_in(Vec3::splat(-2.0), Vec3::splat(2.0));
        let target = r.point_in(Vec3::new(-0.5, -0.2, -0.6), Vec3::new(0.6, 0.7, 0.3));
        let d = (target - o).normalize();
        let want = closest_hit_brute_force_prims(&tris, &spheres, o, d, 1e-4, f32::INFINITY);
        for bvh in &bvhs {
            let got = bvh.closest_hit(o, d, 1e-4, f32::INFINITY);
            assert_eq!(
                key(got),
                key(want),
                "{:?}: o={o:?} d={d:?}",
                bvh.simd_width()
            );
        }
        match want.map(|h| h.triangle) {
            Some(i) if i == first_tri => on_tri += 1,
            Some(i) if i == first_sphere => on_sphere += 1,
            _ => {}
        }
    }
    assert!(on_tri > 1000 && on_sphere > 1000, "{on_tri} {on_sphere}");
}

// ---------------------------------------------------------------------------
// Pre-splitting: long thin triangles go to the build as several clipped
// references; the hits stay brute force's, bit for bit.

/// A cylinder of `n` sliver quads (two triangles each) along a diagonal
/// axis, each spanning its whole length: boxes far larger than the
/// triangles, as in a CAD model's shafts and fins.
fn sliver_cylinder(n: usize) -> Vec<TriangleEdges> {
    let axis = Vec3::new(1.0, 0.8, 0.6).normalize();
    let u = axis.cross(Vec3::Z).normalize();
    let v = axis.cross(u);
    let (r, len) = (0.05, 2.0);
    let ring = |k: usize| {
        let a = std::f32::consts::TAU * k as f32 / n as f32;
        (u * a.cos() + v * a.sin()) * r
    };
    let mut tris = Vec::new();
    for k in 0..n {
        let (p, q) = (ring(k) - axis, ring(k + 1) - axis);
        let (p2, q2) = (p + axis * len, q + axis * len);
        tris.extend(edges(&[[p, q, p2], [q, q2, p2]]));
    }
    tris
}

/// A fan of `n` long thin triangles from the origin towards random
/// directions, with a soup of small triangles around them.
fn sliver_fan(n: usize, seed: u64) -> Vec<TriangleEdges> {
    let mut r = Rand::new(seed);
    let mut tris: Vec<TriangleEdges> = (0..n)
        .map(|_| {
            let d = r.dir() * r.range(1.0, 2.0);
            let side = r.dir() * 0.01;
            TriangleEdges::from_edges(Vec3::ZERO, d, d + side)
        })
        .collect();
    tris.extend(soup(n, seed ^ 7, 0.05));
    tris
}

/// An any-hit filter that lets some hits through by primitive and `t`
/// (a pure function of both, as alpha cut-outs are).
struct Sieve;

impl wavetrace::accel::hit::HitFilter for Sieve {
    fn may_pass(&self, prim: u32) -> bool {
        !prim.is_multiple_of(3)
    }
    fn passes(&self, prim: u32, t: f32) -> bool {
        (prim ^ t.to_bits()) & 1 == 1
    }
}

/// Rays through `tris`' box and rays aimed at random points of random
/// triangles (so many cross split planes near the slivers).
fn sliver_rays(tris: &[TriangleEdges], n: usize, seed: u64) -> Vec<(Vec3, Vec3)> {
    let (lo, hi) = bounds(tris);
    let grow = (hi - lo) * 0.2;
    let mut r = Rand::new(seed);
    (0..n)
        .map(|i| {
            let o = r.point_in(lo - grow, hi + grow);
            if i % 2 == 0 {
                return (o, r.dir());
            }
            let t = &tris[r.below(tris.len())];
            let (mut a, mut b) = (r.f(), r.f());
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            let p = t.v0 + t.e1 * a + t.e2 * b;
            (o, (p - o).normalize())
        })
        .filter(|(_, d)| d.is_finite())
        .collect()
}

/// Every query of a pre-split hierarchy over `tris` against brute force:
/// closest hits (one ray, batch, columns), occlusion at, just before and
/// just after the closest hit (one ray, batch, columns), and the filtered
/// queries (one ray and columns), at every width. Returns the references
/// beyond one per triangle and how many rays hit.
fn check_presplit(tris: &[TriangleEdges], rays: &[(Vec3, Vec3)]) -> (usize, usize) {
    use wavetrace::accel::shape::Shapes;
    use wavetrace::accel::shape::closest_hit_brute_force_filtered;
    let shapes = Shapes::triangles_and_spheres(tris, &[]);
    let mut extra = usize::MAX;
    let mut hits = 0;
    for width in SimdWidth::available() {
        let options = BvhOptions { width };
        let bvh = Bvh::build_shapes_presplit(&shapes, &options, 0.3);
        let plain = Bvh::build_shapes_presplit(&shapes, &options, 0.0);
        assert_eq!(plain.reference_count(), tris.len());
        extra = extra.min(bvh.reference_count() - tris.len());
        assert!(
            bvh.reference_count() <= tris.len() + (0.3 * tris.len() as f32) as usize,
            "{width:?}: {} references for {} triangles",
            bvh.reference_count(),
            tris.len()
        );
        let n = rays.len();
        let col = |f: &dyn Fn(&(Vec3, Vec3)) -> f32| rays.iter().map(f).collect::<Vec<f32>>();
        let o = [col(&|r| r.0.x), col(&|r| r.0.y), col(&|r| r.0.z)];
        let d = [col(&|r| r.1.x), col(&|r| r.1.y), col(&|r| r.1.z)];
        let cols = (o.each_ref().map(|c| &c[..]), d.each_ref().map(|c| &c[..]));
        let (mut t, mut prim) = (vec![0.0; n], vec![0; n]);
        bvh.closest_hits_columns(cols.0, cols.1, (0.0, f32::INFINITY), &mut t, &mut prim);
        let (mut ft, mut fprim) = (vec![0.0; n], vec![0; n]);
        bvh.closest_hits_columns_filtered(
            cols,
            (0.0, f32::INFINITY),
            (&mut ft, &mut fprim),
            |_| Sieve,
        );
        let mut batch = vec![None; n];
        bvh.closest_hits(rays, 0.0, f32::INFINITY, &mut batch);
        let mut ends = Vec::new();
        for (i, &(o, d)) in rays.iter().enumerate() {
            let want = closest_hit_brute_force(tris, o, d, 0.0, f32::INFINITY);
            let got = bvh.closest_hit(o, d, 0.0, f32::INFINITY);
            assert_eq!(key(got), key(want), "{width:?}: ray {i} o={o} d={d}");
            assert_eq!(key(batch[i]), key(want), "{width:?}: batch ray {i}");
            let column = (prim[i] != u32::MAX).then_some(Hit {
                triangle: prim[i],
                t: t[i],
            });
            assert_eq!(key(column), key(want), "{width:?}: column ray {i}");
            let fwant =
                closest_hit_brute_force_filtered(&shapes, o, d, (0.0, f32::INFINITY), &Sieve);
            let fgot = bvh.closest_hit_filtered(o, d, (0.0, f32::INFINITY), &Sieve);
            assert_eq!(key(fgot), key(fwant), "{width:?}: filtered ray {i}");
            let fcol = (fprim[i] != u32::MAX).then_some(Hit {
                triangle: fprim[i],
                t: ft[i],
            });
            assert_eq!(key(fcol), key(fwant), "{width:?}: filtered column ray {i}");
            hits += usize::from(want.is_some());
            // Segments at, just before and just after the closest hit
            // (the filtered one for the filtered query).
            for (h, f) in [(want, false), (fwant, true)] {
                let Some(h) = h else { continue };
                for end in [h.t, h.t.next_up(), h.t.next_down()] {
                    if f {
                        let want =
                            closest_hit_brute_force_filtered(&shapes, o, d, (0.0, end), &Sieve);
                        let got = bvh.occluded_filtered(o, d, (0.0, end), &Sieve);
                        assert_eq!(
                            got,
                            want.is_some(),
                            "{width:?}: filtered segment {i} to {end}"
                        );
                    } else {
                        let got = bvh.occluded(o, d, 0.0, end);
                        assert_eq!(got, h.t < end, "{width:?}: segment {i} to {end}");
                        ends.push((i, end, h.t < end));
                    }
                }
            }
        }
        // The segments in a batch and as columns.
        let seg: Vec<(Vec3, Vec3)> = ends.iter().map(|e| rays[e.0]).collect();
        let t_end: Vec<f32> = ends.iter().map(|e| e.1).collect();
        let mut out = vec![false; seg.len()];
        bvh.occluded_batch(&seg, 0.0, &t_end, &mut out);
        let scol = |f: &dyn Fn(&(Vec3, Vec3)) -> f32| seg.iter().map(f).collect::<Vec<f32>>();
        let so = [scol(&|r| r.0.x), scol(&|r| r.0.y), scol(&|r| r.0.z)];
        let sd = [scol(&|r| r.1.x), scol(&|r| r.1.y), scol(&|r| r.1.z)];
        let mut out_cols: Vec<bool> = ends.iter().map(|e| !e.2).collect();
        bvh.occluded_columns(
            so.each_ref().map(|c| &c[..]),
            sd.each_ref().map(|c| &c[..]),
            0.0,
            &t_end,
            &mut out_cols,
        );
        for (k, e) in ends.iter().enumerate() {
            assert_eq!(out[k], e.2, "{width:?}: batch segment {k}");
            assert_eq!(out_cols[k], e.2, "{width:?}: column segment {k}");
        }
    }
    // Hits were counted at every width.
    (extra, hits / SimdWidth::available().len())
}

#[test]
fn presplit_slivers_equal_brute_force() {
    for (name, tris, seed) in [
        ("cylinder", sliver_cylinder(300), 1),
        ("fan", sliver_fan(400, 2), 2),
    ] {
        let rays = sliver_rays(&tris, 3000, seed);
        let (extra, hits) = check_presplit(&tris, &rays);
        eprintln!(
            "{name}: {} triangles, {extra} extra references, {hits} of {} rays hit",
            tris.len(),
            rays.len()
        );
        // The split happened (references beyond one per triangle) and
        // the rays meet the slivers.
        assert!(extra > tris.len() / 10, "{name}: {extra} extra references");
        assert!(hits > rays.len() / 4, "{name}: {hits} hits");
    }
}

#[test]
fn presplit_build_is_the_same_on_any_thread_count() {
    use wavetrace::accel::shape::Shapes;
    let tris = sliver_fan(2000, 9);
    let shapes = Shapes::triangles_and_spheres(&tris, &[]);
    let build = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| Bvh::build_shapes_presplit(&shapes, &BvhOptions::default(), 0.3))
    };
    let (a, b) = (build(1), build(3));
    assert!(a.reference_count() > tris.len());
    assert_eq!(a.reference_count(), b.reference_count());
    assert_eq!(a.node_count(), b.node_count());
    assert_eq!(a.pack_count(), b.pack_count());
    assert_eq!(a.sah_cost().to_bits(), b.sah_cost().to_bits());
}
