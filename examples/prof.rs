use glam::Vec3;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use std::time::Instant;
use wavetrace::bvh::Bvh;
use wavetrace::geometry::TriangleEdges;
use wavetrace::mesh::{cornell_box, geodesic_sphere};
fn main() {
    let n: usize = std::env::args().nth(1).map_or(1_000_000, |s| s.parse().unwrap());
    let mode = std::env::args().nth(2).unwrap_or("trace".into()); let aimed = std::env::args().nth(3).is_some();
    let mut t = cornell_box();
    t.extend(geodesic_sphere(Vec3::new(0.33, 0.105, -0.39), 0.3, n - 32));
    let e: Vec<TriangleEdges> = t.iter().map(|v| TriangleEdges { v0: v[0], e1: v[1] - v[0], e2: v[2] - v[0] }).collect();
    if mode == "build" {
        for _ in 0..5 { let s = Instant::now(); let b = Bvh::build(&e); println!("build {:.3}s nodes {}", s.elapsed().as_secs_f64(), b.node_count()); }
        return;
    }
    let bvh = Bvh::build(&e);
    let mut g = Pcg64Mcg::new(0x5eed);
    let mut f = move || (g.next_u32() >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0;
    let rays: Vec<(Vec3, Vec3)> = (0..1 << 16).map(|_| { let o = Vec3::new(f(), f(), f()) * 0.999; if !aimed { let d = loop { let v = Vec3::new(f(), f(), f()); let l = v.length_squared(); if l > 1e-6 && l <= 1.0 { break v / l.sqrt(); } }; return (o, d); } let p = loop { let v = Vec3::new(f(), f(), f()); if v.length_squared() <= 1.0 { break Vec3::new(0.33, 0.105, -0.39) + v * 0.3; } }; let d = (p - o).normalize(); (o, d) }).collect();
    let cpu = || { let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 }; unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) }; ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9 };
    let mut v = vec![];
    for _ in 0..10 {
        let s = cpu();
        let mut sum = 0.0;
        for &(o, d) in &rays { if let Some(h) = bvh.closest_hit(o, d, 1e-4, f32::INFINITY) { sum += h.t as f64; } }
        v.push(rays.len() as f64 / (cpu() - s) / 1e6); let _ = sum;
    }
    v.sort_by(f64::total_cmp); println!("n={n} cpu Mrays/s median {:.2} max {:.2}", v[5], v[9]);
}
#[allow(dead_code)]
fn x() {}
