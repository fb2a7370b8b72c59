//! BVH benchmarks: build speed and memory; incoherent closest-hit and
//! occlusion throughput, at 8 and 16 lanes, against the same rays through
//! the `obvhs` crate.
//!
//! The scene at each size is the DH2323 Cornell box (32 triangles) with a
//! geodesic sphere of about N triangles on the short block — the geometry of
//! `scenes/sphere-1m.toml` — made by the same generator the scene files and
//! the tests use. Two sets of incoherent rays, all traced on one thread (so
//! the throughput is per core):
//!
//! - `box`: origins uniform in the box, directions uniform on the sphere —
//!   what a path tracer's bounces in this scene look like (most end on the
//!   walls);
//! - `aimed`: origins uniform in the box, each aimed at a uniform point
//!   inside the sphere — every ray ends on the big mesh, the worst case for
//!   memory.
//!
//! Each set goes through `Bvh::closest_hit` one ray at a time (`single`),
//! through `Bvh::closest_hits` (`batch`: 16 rays interleaved with prefetch),
//! through `Bvh::occluded_batch` (`occl`: the same rays as shadow segments,
//! ending at half or one and a half times the distance to their closest
//! hit, so about half are occluded), at 8 lanes and, where the CPU has
//! AVX-512, 16; and through obvhs's compressed wide BVH (`slow_build`
//! preset, its best quality) with its own triangle test.
//!
//! ```sh
//! cargo bench --bench bvh                         # 1k, 10k, 100k, 1M
//! WAVETRACE_BENCH_10M=1 cargo bench --bench bvh   # adds 10M (needs ~4 GB)
//! ```
//!
//! Before the criterion groups, a summary prints, per size: build time,
//! M triangles/s, bytes/triangle, M rays/s for wavetrace (each mode, each
//! width) and for obvhs, and the ratio obvhs time / wavetrace's best
//! closest-hit time (medians of several runs, rays timed in this thread's
//! CPU time so that other processes on a shared machine do not count), and
//! the 32-triangle Cornell box through brute force, `closest_hit_packs` and
//! the BVH at each width. `WAVETRACE_BENCH_SUMMARY_ONLY=1` stops after the
//! summary; `WAVETRACE_BENCH_SIZES=1000000` picks the sizes.
//!
//! Spheres: the Cornell box with 100 000 random analytic spheres (radii
//! log-uniform in 0.002..0.02, in one hierarchy with the box's triangles,
//! `Bvh::build_prims`), the `box` rays through it: build time and closest
//! hit (single, batch) against occlusion (the same rays as shadow segments)
//! at each width, in the summary and in the criterion group `spheres`.
//! `WAVETRACE_BENCH_SPHERES=N` changes the count.
//!
//! `WAVETRACE_BENCH_ASSET=file.glb` prints, before anything else and then
//! stops, what pre-splitting does to that asset's flattened scene
//! (`Bvh::build_shapes_presplit` at shares 0, 0.1 and 0.25), at each
//! width: build time (median of 3, all cores), packs, nodes, bytes, the
//! tree's SAH cost, and the nodes, leaves and packs a walk visits per ray
//! (`Bvh::walk_stats`) and M rays per CPU-second for three sets of rays:
//! `camera` (64 × 64 pixels of each of 4 orbit views at 25° elevation,
//! 40° field of view, framing the scene's bounding sphere, as the views
//! jobs do), `bounce` (from each camera hit, a uniform direction on the
//! side the ray came from) and `shadow` (from each camera hit towards a
//! uniform direction of the upper hemisphere, occlusion, open-ended).
//! The closest hits of both builds are checked equal.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::{Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::{CwBvh, builder::build_cwbvh_from_tris};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle as OTriangle;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use std::hint::black_box;
use std::time::{Duration, Instant};
use wavetrace::accel::bvh::{Bvh, BvhOptions};
use wavetrace::accel::simd::SimdWidth;
use wavetrace::accel::sphere::Sphere;
use wavetrace::accel::triangle::{
    Hit, Triangle8, TriangleEdges, closest_hit_brute_force, closest_hit_packs,
};
use wavetrace::scene::mesh::{cornell_box, geodesic_sphere};

const RAYS: usize = 1 << 16;
const EPS: f32 = 1e-4;

fn sizes() -> Vec<usize> {
    if let Ok(v) = std::env::var("WAVETRACE_BENCH_SIZES") {
        return v.split(',').filter_map(|x| x.trim().parse().ok()).collect();
    }
    let mut s = vec![1_000, 10_000, 100_000, 1_000_000];
    if std::env::var_os("WAVETRACE_BENCH_10M").is_some() {
        s.push(10_000_000);
    }
    s
}

fn label(n: usize) -> String {
    match n {
        n if n >= 1_000_000 => format!("{}M", n / 1_000_000),
        n => format!("{}k", n / 1_000),
    }
}

/// The Cornell box with a sphere of about `n` triangles (minus the box's 32).
fn scene(n: usize) -> Vec<[Vec3; 3]> {
    let mut t = cornell_box();
    let sphere = geodesic_sphere(SPHERE_CENTER, SPHERE_RADIUS, n.saturating_sub(t.len()));
    t.extend(sphere);
    t
}

fn edges(tris: &[[Vec3; 3]]) -> Vec<TriangleEdges> {
    tris.iter()
        .map(|v| TriangleEdges::from_edges(v[0], v[1] - v[0], v[2] - v[0]))
        .collect()
}

/// How many analytic spheres the sphere scene has.
fn sphere_count() -> usize {
    std::env::var("WAVETRACE_BENCH_SPHERES")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(100_000)
}

/// `n` random spheres inside the Cornell box (radii log-uniform in
/// 0.002..0.02).
fn random_spheres(n: usize) -> Vec<Sphere> {
    let mut g = Pcg64Mcg::new(0x05f3_e7e5);
    let mut f = move || (g.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
    (0..n)
        .map(|_| {
            let c = Vec3::new(f(), f(), f()) * 1.9 - Vec3::splat(0.95);
            Sphere::new(c, 0.002 * 10f32.powf(f()))
        })
        .collect()
}

/// The sphere scene's hierarchy at each width this CPU runs.
fn sphere_builds(tris: &[TriangleEdges], spheres: &[Sphere]) -> Vec<Bvh> {
    SimdWidth::available()
        .into_iter()
        .map(|width| Bvh::build_prims(tris, spheres, &BvhOptions { width }))
        .collect()
}

/// The sphere scene: build, closest hit and occlusion at each width.
fn sphere_summary() {
    let tris = edges(&cornell_box());
    let spheres = random_spheres(sphere_count());
    let rays = rays(false);
    let m = |s: f64| RAYS as f64 / s / 1e6;
    let mut out = vec![None; RAYS];
    let mut occ = vec![false; RAYS];
    eprintln!(
        "\n{:>8} {:>5} {:>8} {:>6} | {:>7} {:>7} {:>7} {:>6}",
        "spheres", "lanes", "build ms", "B/prim", "single", "batch", "occl", "on sph"
    );
    for bvh in sphere_builds(&tris, &spheres) {
        let options = BvhOptions {
            width: bvh.simd_width(),
        };
        let build = wall(3, || {
            black_box(Bvh::build_prims(&tris, &spheres, &options));
        });
        let single = time(5, || {
            black_box(trace(&bvh, &rays));
        });
        let batch = time(5, || {
            black_box(trace_batch(&bvh, &rays, &mut out));
        });
        let on_spheres = out
            .iter()
            .flatten()
            .filter(|h| h.triangle as usize >= tris.len())
            .count();
        let ends = segment_ends(&bvh, &rays);
        let occl = time(5, || {
            black_box(occlude_batch(&bvh, &rays, &ends, &mut occ));
        });
        eprintln!(
            "{:>8} {:>5} {:>8.1} {:>6.1} | {:>7.2} {:>7.2} {:>7.2} {:>5.0}%",
            spheres.len(),
            lanes(&bvh),
            build * 1e3,
            bvh.bytes() as f64 / bvh.prim_count() as f64,
            m(single),
            m(batch),
            m(occl),
            100.0 * on_spheres as f64 / RAYS as f64
        );
    }
    eprintln!(
        "(the Cornell box's 32 triangles and the spheres in one hierarchy; the `box` rays; \
         M rays per CPU-second of one thread; on sph: share of rays whose closest hit is a sphere)"
    );
}

const SPHERE_CENTER: Vec3 = Vec3::new(0.33, 0.105, -0.39);
const SPHERE_RADIUS: f32 = 0.3;

/// `aimed = false`: the `box` rays; `true`: the `aimed` rays.
fn rays(aimed: bool) -> Vec<(Vec3, Vec3)> {
    let mut g = Pcg64Mcg::new(0x5eed);
    // Uniform in [-1, 1).
    let mut f = move || (g.next_u32() >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0;
    (0..RAYS)
        .map(|_| {
            let o = Vec3::new(f(), f(), f()) * 0.999;
            // Uniform in the unit ball.
            let v = loop {
                let v = Vec3::new(f(), f(), f());
                let l = v.length_squared();
                if l > 1e-6 && l <= 1.0 {
                    break v;
                }
            };
            let d = if aimed {
                SPHERE_CENTER + v * SPHERE_RADIUS - o
            } else {
                v
            };
            (o, d.normalize())
        })
        .collect()
}

struct Obvhs {
    bvh: CwBvh,
    tris: Vec<OTriangle>,
}

impl Obvhs {
    fn build(tris: &[[Vec3; 3]]) -> Self {
        let t: Vec<OTriangle> = tris
            .iter()
            .map(|v| OTriangle {
                v0: v[0].into(),
                v1: v[1].into(),
                v2: v[2].into(),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(&t, BvhBuildParams::slow_build(), &mut Duration::default());
        // Triangles in leaf order, as obvhs's own examples do.
        let tris = bvh
            .primitive_indices
            .iter()
            .map(|&i| t[i as usize])
            .collect();
        Self { bvh, tris }
    }

    /// Sum of hit distances (so nothing is optimised away).
    fn trace(&self, rays: &[(Vec3, Vec3)]) -> f64 {
        let mut sum = 0.0f64;
        for &(o, d) in rays {
            let ray = Ray::new(Vec3A::from(o), Vec3A::from(d), EPS, f32::INFINITY);
            let mut hit = RayHit::none();
            if self
                .bvh
                .ray_traverse(ray, &mut hit, |r, id| self.tris[id].intersect(r))
            {
                sum += hit.t as f64;
            }
        }
        sum
    }
}

fn trace(bvh: &Bvh, rays: &[(Vec3, Vec3)]) -> f64 {
    let mut sum = 0.0f64;
    for &(o, d) in rays {
        if let Some(h) = bvh.closest_hit(o, d, EPS, f32::INFINITY) {
            sum += h.t as f64;
        }
    }
    sum
}

fn trace_batch(bvh: &Bvh, rays: &[(Vec3, Vec3)], out: &mut [Option<Hit>]) -> f64 {
    bvh.closest_hits(rays, EPS, f32::INFINITY, out);
    out.iter().flatten().map(|h| h.t as f64).sum()
}

/// Shadow segments on `rays`: each ends at half (even rays) or one and a
/// half (odd rays) times the distance to its closest hit (at 10 when it
/// hits nothing), so about half are occluded.
fn segment_ends(bvh: &Bvh, rays: &[(Vec3, Vec3)]) -> Vec<f32> {
    let mut hits = vec![None; rays.len()];
    bvh.closest_hits(rays, EPS, f32::INFINITY, &mut hits);
    hits.iter()
        .enumerate()
        .map(|(i, h)| h.map_or(10.0, |h| h.t * if i % 2 == 0 { 0.5 } else { 1.5 }))
        .collect()
}

fn occlude_batch(bvh: &Bvh, rays: &[(Vec3, Vec3)], ends: &[f32], out: &mut [bool]) -> usize {
    bvh.occluded_batch(rays, EPS, ends, out);
    out.iter().filter(|&&b| b).count()
}

/// The hierarchy at each width this CPU runs.
fn builds(tris: &[TriangleEdges]) -> Vec<Bvh> {
    SimdWidth::available()
        .into_iter()
        .map(|width| Bvh::build_with(tris, &BvhOptions { width }))
        .collect()
}

fn lanes(bvh: &Bvh) -> usize {
    bvh.simd_width().lanes()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// This thread's CPU time in seconds: on a shared machine, time spent
/// descheduled does not count (wall time would).
fn thread_cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec for the duration of the call.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(r, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID)");
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Median CPU seconds (this thread) of `runs` calls of `f`.
fn time(runs: usize, mut f: impl FnMut()) -> f64 {
    median(
        (0..runs)
            .map(|_| {
                let t = thread_cpu_seconds();
                f();
                thread_cpu_seconds() - t
            })
            .collect(),
    )
}

/// Median wall-clock seconds of `runs` calls of `f`.
fn wall(runs: usize, mut f: impl FnMut()) -> f64 {
    median(
        (0..runs)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

/// The summary tables: build and memory; rays/s for both ray sets; Cornell.
fn summary() {
    // The Cornell box alone: is the BVH ever slower than testing all packs?
    let e = edges(&cornell_box());
    let packs = Triangle8::pack_all(&e);
    let cornell_rays = rays(false);
    let brute = time(5, || {
        for &(o, d) in &cornell_rays {
            black_box(closest_hit_brute_force(&e, o, d, EPS, f32::INFINITY));
        }
    });
    let pk = time(5, || {
        for &(o, d) in &cornell_rays {
            black_box(closest_hit_packs(&packs, o, d, EPS, f32::INFINITY));
        }
    });
    let m = |s: f64| RAYS as f64 / s / 1e6;
    let mut line = format!(
        "cornell (32 tris): brute force {:.2}, packs {:.2}",
        m(brute),
        m(pk)
    );
    let mut out = vec![None; RAYS];
    for bvh in builds(&e) {
        let batch = time(5, || {
            black_box(trace_batch(&bvh, &cornell_rays, &mut out));
        });
        let ends = segment_ends(&bvh, &cornell_rays);
        let mut occ = vec![false; RAYS];
        let occl = time(5, || {
            black_box(occlude_batch(&bvh, &cornell_rays, &ends, &mut occ));
        });
        line += &format!(
            ", bvh x{} {:.2} (occluded {:.2})",
            lanes(&bvh),
            m(batch),
            m(occl)
        );
    }
    eprintln!("{line} M rays/s");
    let sets = [("box", rays(false)), ("aimed", rays(true))];
    eprintln!(
        "\n{:>5} {:>5} {:>8} {:>8} {:>6} {:>7} | {:>5} {:>7} {:>7} {:>7} {:>7} {:>6}",
        "tris",
        "lanes",
        "build ms",
        "Mtris/s",
        "B/tri",
        "nodes",
        "rays",
        "single",
        "batch",
        "occl",
        "obvhs",
        "ratio"
    );
    for n in sizes() {
        let tris = scene(n);
        let e = edges(&tris);
        let ob = Obvhs::build(&tris);
        for bvh in builds(&e) {
            let options = BvhOptions {
                width: bvh.simd_width(),
            };
            let build = wall(3, || {
                black_box(Bvh::build_with(&e, &options));
            });
            for (k, (name, rays)) in sets.iter().enumerate() {
                // Both find the same hits (obvhs's triangle test rounds
                // differently, so compare the sum of t loosely).
                let (a, b) = (trace(&bvh, rays), ob.trace(rays));
                assert!(
                    (a - b).abs() <= 1e-3 * a.abs(),
                    "wavetrace {a} vs obvhs {b}"
                );
                let single = time(5, || {
                    black_box(trace(&bvh, rays));
                });
                let batch = time(5, || {
                    black_box(trace_batch(&bvh, rays, &mut out));
                });
                let ends = segment_ends(&bvh, rays);
                let mut occ = vec![false; RAYS];
                let occl = time(5, || {
                    black_box(occlude_batch(&bvh, rays, &ends, &mut occ));
                });
                let obvhs = time(5, || {
                    black_box(ob.trace(rays));
                });
                let lead = if k == 0 {
                    format!(
                        "{:>5} {:>5} {:>8.1} {:>8.2} {:>6.1} {:>7}",
                        label(n),
                        lanes(&bvh),
                        build * 1e3,
                        tris.len() as f64 / build / 1e6,
                        bvh.bytes() as f64 / tris.len() as f64,
                        bvh.node_count()
                    )
                } else {
                    format!("{:>44}", "")
                };
                eprintln!(
                    "{lead} | {name:>5} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>6.2}",
                    m(single),
                    m(batch),
                    m(occl),
                    m(obvhs),
                    obvhs / single.min(batch),
                );
            }
        }
    }
    eprintln!(
        "(build: wall clock, all cores. rays: M rays per CPU-second of one thread, {RAYS} \
         rays; occl: the same rays as shadow segments, about half occluded; ratio = obvhs \
         time / wavetrace's faster closest-hit mode)"
    );
}

/// The rays of an asset's walk statistics: camera rays, bounces and
/// shadow rays, with `t_min` (see the module doc).
fn asset_rays(tris: &[TriangleEdges]) -> [(&'static str, Vec<(Vec3, Vec3)>); 3] {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for t in tris.iter().filter(|t| t.is_finite()) {
        for v in [t.v0, t.v0 + t.e1, t.v0 + t.e2] {
            (lo, hi) = (lo.min(v), hi.max(v));
        }
    }
    let (c, r) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    let half = 20f32.to_radians();
    let dist = r / half.sin();
    let bvh = Bvh::build(tris);
    let mut g = Pcg64Mcg::new(0x000a_55e7);
    let mut f = move || (g.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
    let mut sphere = move || {
        loop {
            let v = Vec3::new(f(), f(), f()) * 2.0 - Vec3::ONE;
            if (1e-6..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    };
    let (mut camera, mut bounce, mut shadow) = (Vec::new(), Vec::new(), Vec::new());
    let el = 25f32.to_radians();
    for k in 0..4 {
        let az = (15.0 + 90.0 * k as f32).to_radians();
        let eye = c + dist * Vec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin());
        let fwd = (c - eye).normalize();
        let right = fwd.cross(Vec3::Y).normalize();
        let up = right.cross(fwd);
        for j in 0..64 {
            for i in 0..64 {
                let x = (2.0 * (i as f32 + 0.5) / 64.0 - 1.0) * half.tan();
                let y = (1.0 - 2.0 * (j as f32 + 0.5) / 64.0) * half.tan();
                let d = (fwd + x * right + y * up).normalize();
                camera.push((eye, d));
                if let Some(h) = bvh.closest_hit(eye, d, 0.0, f32::INFINITY) {
                    let p = eye + d * h.t;
                    let b = sphere();
                    bounce.push((p, if b.dot(d) > 0.0 { -b } else { b }));
                    let s = sphere();
                    shadow.push((p, if s.y < 0.0 { -s } else { s }));
                }
            }
        }
    }
    [("camera", camera), ("bounce", bounce), ("shadow", shadow)]
}

/// What pre-splitting does to the asset at `path` (see the module doc).
fn asset_summary(path: &str) {
    use wavetrace::accel::shape::OwnedShapes;
    let scene = wavetrace::scene::asset_scene::load(std::path::Path::new(path), None)
        .expect("the asset loads")
        .0;
    let owned = OwnedShapes::of_scene(&scene);
    let shapes = owned.as_shapes();
    let sets = asset_rays(shapes.triangles);
    let eps = 1e-4 * sets[0].1[0].0.abs().max_element().max(1.0);
    eprintln!(
        "{path}: {} triangles; rays: {}",
        shapes.triangles.len(),
        sets.iter()
            .map(|(n, r)| format!("{n} {}", r.len()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    eprintln!(
        "{:>5} {:>5} {:>8} {:>7} {:>7} {:>6} {:>6} | {:>6} {:>6} {:>6} {:>6} {:>7}",
        "split",
        "lanes",
        "build ms",
        "packs",
        "nodes",
        "B/tri",
        "SAH",
        "rays",
        "nodes",
        "leaves",
        "packs",
        "Mrays/s"
    );
    let mut hits: Vec<Vec<Option<(u32, u32)>>> = Vec::new();
    for width in SimdWidth::available() {
        for share in [0.0, 0.1, 0.25] {
            let options = BvhOptions { width };
            let build = wall(3, || {
                black_box(Bvh::build_shapes_presplit(&shapes, &options, share));
            });
            let bvh = Bvh::build_shapes_presplit(&shapes, &options, share);
            let mine: Vec<_> = sets[0]
                .1
                .iter()
                .map(|&(o, d)| bvh.closest_hit(o, d, 0.0, f32::INFINITY))
                .map(|h| h.map(|h| (h.triangle, h.t.to_bits())))
                .collect();
            if let Some(first) = hits.first() {
                assert!(first == &mine, "pre-splitting changed a hit");
            }
            hits.push(mine);
            for (k, (name, rays)) in sets.iter().enumerate() {
                let occlusion = *name == "shadow";
                let t_min = if k == 0 { 0.0 } else { eps };
                let mut s = wavetrace::accel::bvh::WalkStats::default();
                for &(o, d) in rays {
                    s += bvh.walk_stats(o, d, t_min, f32::INFINITY, occlusion);
                }
                let cpu = time(5, || {
                    for &(o, d) in rays {
                        if occlusion {
                            black_box(bvh.occluded(o, d, t_min, f32::INFINITY));
                        } else {
                            black_box(bvh.closest_hit(o, d, t_min, f32::INFINITY));
                        }
                    }
                });
                let n = rays.len() as f64;
                let lead = if k == 0 {
                    format!(
                        "{:>5.2} {:>5} {:>8.1} {:>7} {:>7} {:>6.1} {:>6.1}",
                        share,
                        width.lanes(),
                        build * 1e3,
                        bvh.pack_count(),
                        bvh.node_count(),
                        bvh.bytes() as f64 / shapes.triangles.len() as f64,
                        bvh.sah_cost()
                    )
                } else {
                    format!("{:>52}", "")
                };
                if k == 0 {
                    eprintln!(
                        "share {share}: {} references, {} packs in front, packet plan {:?}",
                        bvh.reference_count(),
                        bvh.first_pack_count(),
                        bvh.packet_plan()
                    );
                    let mut s = wavetrace::accel::bvh::WalkStats::default();
                    let mut m = 0;
                    for &(o, d) in rays {
                        if bvh.closest_hit(o, d, 0.0, f32::INFINITY).is_some() {
                            s += bvh.walk_stats(o, d, 0.0, f32::INFINITY, false);
                            m += 1;
                        }
                    }
                    let m = m as f64;
                    eprintln!(
                        "camera rays that hit ({}): nodes {:.2} leaves {:.2} packs {:.2}",
                        m,
                        s.nodes as f64 / m,
                        s.leaves as f64 / m,
                        s.packs as f64 / m
                    );
                }
                eprintln!(
                    "{lead} | {name:>6} {:>6.2} {:>6.2} {:>6.2} {:>7.2}",
                    s.nodes as f64 / n,
                    s.leaves as f64 / n,
                    s.packs as f64 / n,
                    n / cpu / 1e6
                );
            }
        }
    }
}

fn benches(c: &mut Criterion) {
    if let Ok(path) = std::env::var("WAVETRACE_BENCH_ASSET") {
        asset_summary(&path);
        return;
    }
    if std::env::var_os("WAVETRACE_BENCH_NO_SUMMARY").is_none() {
        summary();
        sphere_summary();
    }
    if std::env::var_os("WAVETRACE_BENCH_SUMMARY_ONLY").is_some() {
        return;
    }
    let mut build = c.benchmark_group("build");
    build.sample_size(10);
    for n in sizes() {
        let e = edges(&scene(n));
        build.throughput(Throughput::Elements(e.len() as u64));
        for width in [SimdWidth::W8, SimdWidth::W16] {
            if !width.is_available() {
                continue;
            }
            let id = BenchmarkId::new(format!("x{}", width.lanes()), label(n));
            build.bench_with_input(id, &e, |b, e| {
                b.iter(|| Bvh::build_with(e, &BvhOptions { width }))
            });
        }
    }
    build.finish();

    for (group, aimed) in [("incoherent-box", false), ("incoherent-aimed", true)] {
        let rays = rays(aimed);
        let mut out = vec![None; RAYS];
        let mut occ = vec![false; RAYS];
        let mut g = c.benchmark_group(group);
        g.throughput(Throughput::Elements(RAYS as u64));
        g.sample_size(10);
        g.warm_up_time(Duration::from_millis(500));
        g.measurement_time(Duration::from_secs(2));
        for n in sizes() {
            let tris = scene(n);
            // Closest hit against occlusion on the same rays, at each width.
            for bvh in builds(&edges(&tris)) {
                let x = lanes(&bvh);
                let ends = segment_ends(&bvh, &rays);
                g.bench_function(BenchmarkId::new(format!("single-x{x}"), label(n)), |b| {
                    b.iter(|| trace(&bvh, &rays))
                });
                g.bench_function(BenchmarkId::new(format!("batch-x{x}"), label(n)), |b| {
                    b.iter(|| trace_batch(&bvh, &rays, &mut out))
                });
                g.bench_function(BenchmarkId::new(format!("occluded-x{x}"), label(n)), |b| {
                    b.iter(|| occlude_batch(&bvh, &rays, &ends, &mut occ))
                });
            }
            let ob = Obvhs::build(&tris);
            g.bench_function(BenchmarkId::new("obvhs", label(n)), |b| {
                b.iter(|| ob.trace(&rays))
            });
        }
        g.finish();
    }

    // Spheres: closest hit against occlusion on the same rays.
    let tris = edges(&cornell_box());
    let spheres = random_spheres(sphere_count());
    let rays = rays(false);
    let mut out = vec![None; RAYS];
    let mut occ = vec![false; RAYS];
    let mut g = c.benchmark_group("spheres");
    g.throughput(Throughput::Elements(RAYS as u64));
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(2));
    let n = label(spheres.len());
    for bvh in sphere_builds(&tris, &spheres) {
        let x = lanes(&bvh);
        let ends = segment_ends(&bvh, &rays);
        g.bench_function(BenchmarkId::new(format!("single-x{x}"), &n), |b| {
            b.iter(|| trace(&bvh, &rays))
        });
        g.bench_function(BenchmarkId::new(format!("batch-x{x}"), &n), |b| {
            b.iter(|| trace_batch(&bvh, &rays, &mut out))
        });
        g.bench_function(BenchmarkId::new(format!("occluded-x{x}"), &n), |b| {
            b.iter(|| occlude_batch(&bvh, &rays, &ends, &mut occ))
        });
    }
    g.finish();
}

criterion_group!(bvh_benches, benches);
criterion_main!(bvh_benches);
