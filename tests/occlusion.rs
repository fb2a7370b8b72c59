//! Occlusion and SIMD widths on over a million random rays:
//!
//! - a segment is occluded exactly when the closest hit along its ray is
//!   closer than its end (`t_max` at the hit, one ulp either side of it, at
//!   random, and infinite), one ray at a time and batched;
//! - the 16-lane kernels (where the CPU has AVX-512) give the same closest
//!   hits, bit for bit, and the same occlusion answers as the 8-lane ones;
//! - both again on scenes of triangles and analytic spheres together
//!   (rays aimed into spheres, grazing them, starting inside them and on
//!   their surfaces).
//!
//! The closest hit itself is checked against brute force in `tests/bvh.rs`.

use glam::Vec3;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use wavetrace::accel::bvh::{Bvh, BvhOptions};
use wavetrace::accel::simd::SimdWidth;
use wavetrace::accel::sphere::Sphere;
use wavetrace::accel::triangle::{Hit, TriangleEdges};
use wavetrace::scene::mesh::{cornell_box, geodesic_sphere, terrain};

struct Rand(Pcg64Mcg);

impl Rand {
    fn new(seed: u64) -> Self {
        Self(Pcg64Mcg::new(
            0x9e37_79b9_7f4a_7c15_f39c_c060_5ced_c834 ^ seed as u128,
        ))
    }
    fn f(&mut self) -> f32 {
        (self.0.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }
    fn point_in(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        lo + (hi - lo) * Vec3::new(self.f(), self.f(), self.f())
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

fn edges(tris: &[[Vec3; 3]]) -> Vec<TriangleEdges> {
    tris.iter()
        .map(|v| TriangleEdges::from_edges(v[0], v[1] - v[0], v[2] - v[0]))
        .collect()
}

fn key(h: Option<Hit>) -> Option<(u32, u32)> {
    h.map(|h| (h.triangle, h.t.to_bits()))
}

/// `n` rays for `tris`: uniform, aimed at vertices and edges, starting on
/// surfaces, and grazing; with their `t_min`.
fn rays(tris: &[TriangleEdges], n: usize, seed: u64) -> Vec<(Vec3, Vec3, f32)> {
    let mut lo = Vec3::INFINITY;
    let mut hi = Vec3::NEG_INFINITY;
    for t in tris {
        for v in [t.v0, t.v0 + t.e1, t.v0 + t.e2] {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    let grow = (hi - lo) * 0.2 + Vec3::splat(1e-3);
    let eps = 1e-4 * lo.abs().max(hi.abs()).max_element().max(1.0);
    let mut r = Rand::new(seed);
    (0..n)
        .map(|k| {
            let t = &tris[r.below(tris.len())];
            match k % 4 {
                0 => (r.point_in(lo - grow, hi + grow), r.dir(), eps),
                1 => {
                    let target = match k % 3 {
                        0 => t.v0,
                        1 => t.v0 + t.e1 * 0.5,
                        _ => t.v0 + t.e1 * 0.5 + t.e2 * 0.5,
                    };
                    let o = r.point_in(lo - grow, hi + grow);
                    (o, (target - o).normalize_or(Vec3::Z), 0.0)
                }
                2 => {
                    let (mut u, mut v) = (r.f(), r.f());
                    if u + v > 1.0 {
                        (u, v) = (1.0 - u, 1.0 - v);
                    }
                    (t.v0 + t.e1 * u + t.e2 * v, r.dir(), eps)
                }
                _ => {
                    // Grazing: almost in the triangle's plane.
                    let n = t.e1.cross(t.e2).normalize_or(Vec3::Z);
                    let along = (t.e1 + t.e2 * r.f()).normalize_or(Vec3::X);
                    let o = t.v0 - along * 0.5 + n * (r.f() - 0.5) * 1e-4;
                    (o, (along + n * (r.f() - 0.5) * 1e-5).normalize(), eps)
                }
            }
        })
        .collect()
}

/// `n` rays for `spheres` (within the box `lo..hi`): aimed inside one,
/// grazing one (tangent distance `r (1 ± ε)`), starting inside one, and
/// starting on one's surface; with their `t_min`.
fn sphere_rays(
    spheres: &[Sphere],
    lo: Vec3,
    hi: Vec3,
    n: usize,
    seed: u64,
) -> Vec<(Vec3, Vec3, f32)> {
    let grow = (hi - lo) * 0.2 + Vec3::splat(1e-3);
    let eps = 1e-4 * lo.abs().max(hi.abs()).max_element().max(1.0);
    let mut r = Rand::new(seed);
    (0..n)
        .map(|k| {
            let s = &spheres[r.below(spheres.len())];
            match k % 4 {
                0 => {
                    let o = r.point_in(lo - grow, hi + grow);
                    let target = s.center + r.dir() * s.radius * 0.99 * r.f();
                    (o, (target - o).normalize_or(Vec3::Z), eps)
                }
                1 => {
                    let o = r.point_in(lo - grow, hi + grow);
                    let e = (s.center - o).normalize_or(Vec3::X);
                    let p = e.any_orthonormal_vector();
                    let side = (p + e.cross(p) * (r.f() * 2.0 - 1.0)).normalize();
                    let k = 10f32.powf(-9.0 + 7.0 * r.f()) * if r.f() < 0.5 { -1.0 } else { 1.0 };
                    let target = s.center + side * s.radius * (1.0 + k);
                    (o, (target - o).normalize_or(Vec3::Z), eps)
                }
                2 => (
                    s.center + r.dir() * s.radius * 0.999 * r.f().cbrt(),
                    r.dir(),
                    eps,
                ),
                _ => (s.center + r.dir() * s.radius, r.dir(), [0.0, eps][k % 2]),
            }
        })
        .collect()
}

/// Check occlusion against the closest hit, and 16 lanes against 8, for
/// `n` rays; returns (occluded answers checked, how many were occluded).
fn check(tris: &[TriangleEdges], n: usize, seed: u64) -> (usize, usize) {
    check_prims(tris, &[], n, seed)
}

/// [`check`] over triangles and spheres (half the rays aimed at spheres,
/// where there are any).
fn check_prims(tris: &[TriangleEdges], spheres: &[Sphere], n: usize, seed: u64) -> (usize, usize) {
    let build = |width| Bvh::build_prims(tris, spheres, &BvhOptions { width });
    let b8 = build(SimdWidth::W8);
    let b16 = SimdWidth::W16.is_available().then(|| build(SimdWidth::W16));
    let bvhs: Vec<&Bvh> = std::iter::once(&b8).chain(b16.as_ref()).collect();
    let rays = if spheres.is_empty() {
        rays(tris, n, seed)
    } else {
        let mut lo = Vec3::INFINITY;
        let mut hi = Vec3::NEG_INFINITY;
        for s in spheres {
            lo = lo.min(s.center - s.radius);
            hi = hi.max(s.center + s.radius);
        }
        let half = if tris.is_empty() { 0 } else { n / 2 };
        let mut v = sphere_rays(spheres, lo, hi, n - half, seed);
        if half > 0 {
            v.extend(rays(tris, half, seed));
        }
        v
    };
    let mut r = Rand::new(seed ^ 0x5eed);
    let mut segments = Vec::new();
    let (mut checked, mut occluded) = (0, 0);
    for (k, &(o, d, t_min)) in rays.iter().enumerate() {
        let hit = b8.closest_hit(o, d, t_min, f32::INFINITY);
        if let Some(b) = &b16 {
            let h16 = b.closest_hit(o, d, t_min, f32::INFINITY);
            assert_eq!(key(h16), key(hit), "16 lanes vs 8: o={o:?} d={d:?}");
        }
        let t_max = match (hit, k % 5) {
            (Some(h), 0) => h.t,
            (Some(h), 1) => h.t.next_up(),
            (Some(h), 2) => h.t.next_down(),
            (_, 3) => f32::INFINITY,
            _ => r.f() * 4.0,
        };
        let want = hit.is_some_and(|h| h.t < t_max);
        for b in &bvhs {
            assert_eq!(
                b.occluded(o, d, t_min, t_max),
                want,
                "{:?}: o={o:?} d={d:?} t_min={t_min} t_max={t_max}, closest {hit:?}",
                b.simd_width()
            );
        }
        checked += 1;
        occluded += want as usize;
        segments.push((o, d, t_min, t_max, want));
    }
    // Batched, per t_min.
    let mut t_mins: Vec<f32> = segments.iter().map(|s| s.2).collect();
    t_mins.sort_by(f32::total_cmp);
    t_mins.dedup();
    for t_min in t_mins {
        let seg: Vec<_> = segments.iter().filter(|s| s.2 == t_min).collect();
        let rs: Vec<(Vec3, Vec3)> = seg.iter().map(|s| (s.0, s.1)).collect();
        let ends: Vec<f32> = seg.iter().map(|s| s.3).collect();
        for b in &bvhs {
            let mut out = vec![false; rs.len()];
            b.occluded_batch(&rs, t_min, &ends, &mut out);
            for (s, got) in seg.iter().zip(&out) {
                assert_eq!(*got, s.4, "{:?} batch: {s:?}", b.simd_width());
            }
        }
        if let Some(b) = &b16 {
            let mut h8 = vec![None; rs.len()];
            let mut h16 = vec![None; rs.len()];
            b8.closest_hits(&rs, t_min, f32::INFINITY, &mut h8);
            b.closest_hits(&rs, t_min, f32::INFINITY, &mut h16);
            for (a, c) in h8.iter().zip(&h16) {
                assert_eq!(key(*a), key(*c), "16 lanes vs 8, batched");
            }
        }
    }
    (checked, occluded)
}

#[test]
fn occlusion_equals_closest_hit_on_a_million_rays() {
    if !SimdWidth::W16.is_available() {
        eprintln!("note: no AVX-512 on this CPU: 16 lanes are not checked");
    }
    let cornell = edges(&cornell_box());
    let mut soup = Vec::new();
    let mut r = Rand::new(1);
    for _ in 0..5000 {
        let v0 = r.point_in(Vec3::splat(-1.0), Vec3::splat(1.0));
        soup.push(TriangleEdges::from_edges(
            v0,
            r.dir() * 0.2 * r.f(),
            r.dir() * 0.2 * r.f(),
        ));
    }
    let mut sphere = cornell_box();
    sphere.extend(geodesic_sphere(Vec3::new(0.33, 0.105, -0.39), 0.3, 200_000));
    let sphere = edges(&sphere);
    let terrain = edges(&terrain(Vec3::ZERO, [4.0, 4.0], 1.0, 50_000, 5));
    // A small tree: the Cornell box and 40 more triangles.
    let mut small = cornell.clone();
    small.extend(soup[..40].iter().copied());
    let mut total = 0;
    let mut occluded = 0;
    for (i, tris) in [&cornell, &small, &soup, &sphere, &terrain]
        .into_iter()
        .enumerate()
    {
        let (c, o) = check(tris, 220_000, i as u64);
        total += c;
        occluded += o;
    }
    assert!(total >= 1_000_000, "{total} rays");
    assert!(
        occluded > total / 5 && occluded < total * 4 / 5,
        "both answers exercised: {occluded} of {total}"
    );
}

#[test]
fn occlusion_equals_closest_hit_on_mixed_scenes() {
    let mut r = Rand::new(2);
    let spheres = |n: usize, r: &mut Rand, lo: f32, hi: f32| -> Vec<Sphere> {
        (0..n)
            .map(|_| {
                let c = r.point_in(Vec3::splat(-1.0), Vec3::splat(1.0));
                Sphere::new(c, lo * (hi / lo).powf(r.f()))
            })
            .collect()
    };
    let cornell = edges(&cornell_box());
    // The Cornell box with a few spheres, one duplicated.
    let mut few = spheres(5, &mut r, 0.1, 0.4);
    few.push(few[0]);
    // 100k small spheres alone; 20k with a 50k-triangle mesh; 12 spheres
    // alone (one leaf at 16 lanes).
    let many = spheres(100_000, &mut r, 1e-3, 1e-2);
    let mut mesh = cornell_box();
    mesh.extend(geodesic_sphere(Vec3::new(0.33, 0.105, -0.39), 0.3, 50_000));
    let mesh = edges(&mesh);
    let some = spheres(20_000, &mut r, 1e-3, 3e-2);
    let twelve = spheres(12, &mut r, 0.05, 0.5);
    let scenes: [(&[TriangleEdges], &[Sphere]); 4] = [
        (&cornell, &few),
        (&[], &many),
        (&mesh, &some),
        (&[], &twelve),
    ];
    let (mut total, mut occluded) = (0, 0);
    for (i, (tris, spheres)) in scenes.into_iter().enumerate() {
        let (c, o) = check_prims(tris, spheres, 260_000, 10 + i as u64);
        total += c;
        occluded += o;
    }
    assert!(total >= 1_000_000, "{total} rays");
    assert!(
        occluded > total / 5 && occluded < total * 4 / 5,
        "both answers exercised: {occluded} of {total}"
    );
}
