//! The ray/sphere kernel against a scalar f64 reference on a million random
//! rays — scalar, and the hierarchy's packs at 8 lanes and (where the CPU
//! has AVX-512) 16, which give the scalar kernel's bits lane for lane — and
//! the 8-wide pack against the scalar kernel bit for bit.

use glam::{DVec3, Vec3};
use wavetrace::accel::simd::SimdWidth;
use wavetrace::accel::sphere::{Sphere, Sphere8, hit_normal, intersect_packed, intersect_sphere};
use wavetrace::integrator::sampler::PathRng;
use wavetrace::math::V3;

const EPS: f64 = f32::EPSILON as f64;

struct Rng(PathRng);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(PathRng::new(seed, 1, 2))
    }
    fn f(&mut self) -> f64 {
        self.0.next_f32() as f64
    }
    fn unit(&mut self) -> DVec3 {
        let z = 2.0 * self.f() - 1.0;
        let p = std::f64::consts::TAU * self.f();
        let s = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(s * p.cos(), s * p.sin(), z)
    }
    fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.f()).exp()
    }
}

fn f32v(v: DVec3) -> Vec3 {
    v.as_vec3()
}

/// The reference: the roots of `|o + t d - c|² = r²` in f64 for the f32
/// inputs (exact products, so only f64 rounding), sorted, and the relative
/// discriminant `δ = 1 - dist²/r²` (`dist` the distance of the center from
/// the line). `None` where the line misses.
fn reference(o: Vec3, d: Vec3, c: Vec3, r: f32) -> (f64, Option<(f64, f64)>) {
    let (o, d, c, r) = (o.as_dvec3(), d.as_dvec3(), c.as_dvec3(), r as f64);
    let f = o - c;
    let a = d.dot(d);
    let b = -f.dot(d);
    let l = f + d * (b / a);
    let discr = r * r - l.dot(l);
    let delta = discr / (r * r);
    if discr < 0.0 {
        return (delta, None);
    }
    let q = b + b.signum() * (a * discr).sqrt();
    let (t0, t1) = ((f.dot(f) - r * r) / q, q / a);
    (delta, Some((t0.min(t1), t0.max(t1))))
}

/// A test ray: origin, direction, sphere, t_min, and its kind.
struct Case {
    o: Vec3,
    d: Vec3,
    c: Vec3,
    r: f32,
    t_min: f32,
}

fn make_case(rng: &mut Rng, kind: usize) -> Case {
    let scale = [1.0, 100.0][(rng.f() * 2.0) as usize];
    let c = (DVec3::new(rng.f(), rng.f(), rng.f()) * 2.0 - 1.0) * scale;
    let r = rng.log_uniform(1e-2, 1e2);
    let (o, d, t_min) = match kind {
        // From outside, aimed inside the silhouette.
        0 => {
            let o = c + rng.unit() * r * rng.log_uniform(1.01, 1e3);
            let target = c + rng.unit() * r * 0.99 * rng.f().cbrt();
            (o, (target - o).normalize(), 0.0)
        }
        // Grazing: aimed at a distance r(1 ± ε) from the center.
        1 => {
            let o = c + rng.unit() * r * rng.log_uniform(1.01, 1e3);
            let e = (c - o).normalize();
            let p = e.any_orthonormal_vector();
            let eps = rng.log_uniform(1e-9, 1e-2) * if rng.f() < 0.5 { -1.0 } else { 1.0 };
            let target = c + p * r * (1.0 + eps);
            (o, (target - o).normalize(), 0.0)
        }
        // From inside.
        2 => {
            let o = c + rng.unit() * r * 0.999 * rng.f().cbrt();
            (o, rng.unit(), 0.0)
        }
        // From outside, going away (behind).
        3 => {
            let o = c + rng.unit() * r * rng.log_uniform(1.0001, 1e3);
            let mut d = rng.unit();
            if d.dot(c - o) > 0.0 {
                d = -d;
            }
            (o, d, 0.0)
        }
        // From (the f32 rounding of a point on) the surface, in or out,
        // with a t_min above the self-intersection noise.
        _ => {
            let o = c + rng.unit() * r;
            let t_min = 1e-4 * r.max(o.abs().max_element());
            (o, rng.unit(), t_min)
        }
    };
    // Sometimes a direction that is not unit.
    let d = if rng.f() < 0.2 {
        d * rng.log_uniform(0.1, 10.0)
    } else {
        d
    };
    Case {
        o: f32v(o),
        d: f32v(d),
        c: f32v(c),
        r: r as f32,
        t_min: t_min as f32,
    }
}

/// The widths of the hierarchy's sphere packs this CPU runs.
fn widths() -> Vec<SimdWidth> {
    if !SimdWidth::W16.is_available() {
        eprintln!("note: no AVX-512 on this CPU: 16 lanes are not checked");
    }
    SimdWidth::available()
}

/// The ray against `spheres` through the packed kernel at every width:
/// each lane's `t` has the scalar kernel's bits, and padding lanes miss.
/// Returns the scalar `(hit, t)` of each sphere.
fn packed_equals_scalar(
    widths: &[SimdWidth],
    spheres: &[Sphere],
    o: Vec3,
    d: Vec3,
    t_min: f32,
) -> Vec<(bool, f32)> {
    let scalar: Vec<(bool, f32)> = spheres
        .iter()
        .map(|s| {
            intersect_sphere(
                V3::from(o),
                V3::from(d),
                V3::from(s.center),
                s.radius,
                t_min,
            )
        })
        .collect();
    for &w in widths {
        let ts = intersect_packed(w, spheres, o, d, t_min);
        assert_eq!(ts.len(), spheres.len().div_ceil(w.lanes()) * w.lanes());
        for (l, t) in ts.iter().enumerate() {
            match scalar.get(l) {
                Some(&(_, want)) => assert_eq!(
                    t.to_bits(),
                    want.to_bits(),
                    "{w:?} lane {l}: {t} vs scalar {want} (o={o:?} d={d:?} {:?})",
                    spheres[l]
                ),
                None => assert_eq!(*t, f32::INFINITY, "{w:?}: padding lane {l} hit"),
            }
        }
    }
    scalar
}

/// The tolerance model, from the kernel's rounding (`ε` = f32's epsilon,
/// `f = o - c`): the discriminant `r² - |l|²` is off by about
/// `2 r ε |f|`, i.e. the relative discriminant `δ` by `2 ε |f| / r`, and
/// each root by `ε (|f| + r) / |d|` plus the square-root's amplification
/// `1/sqrt(δ)` near grazing. So:
///
/// - hit/miss must agree except where `|δ| < 4 ε (|f| + r) / r` (grazing)
///   or a root lies within the `t` tolerance of `t_min`;
/// - `|t - t_ref| ≤ 8 ε (|f| + r) / |d| · max(1, 1/sqrt(δ))`.
#[test]
fn kernel_matches_f64_reference_on_a_million_rays() {
    let widths = widths();
    // Spheres of earlier cases, to fill the other lanes of the packs.
    let mut others: Vec<Sphere> = Vec::new();
    let mut rng = Rng::new(42);
    let kinds = ["outside", "grazing", "inside", "behind", "surface"];
    // rays, hits, excused (grazing or at t_min), worst |Δt| / tolerance
    let mut stats = vec![(0u32, 0u32, 0u32, 0.0f64); kinds.len()];
    let mut worst_rel = 0.0f64;
    let mut disagreements = [0u32; 5];
    for i in 0..1_000_000 {
        let kind = i % kinds.len();
        let k = make_case(&mut rng, kind);
        let (hit, t) = intersect_sphere(V3::from(k.o), V3::from(k.d), V3::from(k.c), k.r, k.t_min);
        assert_eq!(hit, t.is_finite(), "t is +∞ exactly where the ray misses");
        // The same bits from the packs, the case's sphere in lane
        // `i % 19` among up to 18 others (so in either pack of two, or
        // alone before padding).
        let sphere = Sphere {
            center: k.c,
            radius: k.r,
        };
        let at = (i % 19).min(others.len());
        let mut set: Vec<Sphere> = others[others.len() - at..].to_vec();
        set.push(sphere);
        let lanes = packed_equals_scalar(&widths, &set, k.o, k.d, k.t_min);
        assert_eq!(lanes[at].1.to_bits(), t.to_bits());
        if others.len() >= 64 {
            others.remove(0);
        }
        others.push(sphere);
        let (delta, roots) = reference(k.o, k.d, k.c, k.r);
        let tm = k.t_min as f64;
        let ref_t = roots.and_then(|(t0, t1)| [t0, t1].into_iter().find(|&t| t > tm));
        let f = (k.o.as_dvec3() - k.c.as_dvec3()).length();
        let r = k.r as f64;
        let t_tol =
            8.0 * EPS * (f + r) / k.d.as_dvec3().length() * (1.0 / delta.abs().sqrt()).max(1.0);
        let grazing = delta.abs() < 4.0 * EPS * (f + r) / r;
        let at_t_min =
            roots.is_some_and(|(t0, t1)| (t0 - tm).abs() < t_tol || (t1 - tm).abs() < t_tol);
        let st = &mut stats[kind];
        st.0 += 1;
        st.1 += hit as u32;
        if grazing || at_t_min {
            st.2 += 1;
            disagreements[kind] += (hit != ref_t.is_some()) as u32;
            continue;
        }
        match ref_t {
            Some(tr) => {
                assert!(
                    hit,
                    "{}: missed, reference t = {tr} (δ = {delta:e})",
                    kinds[kind]
                );
                let e = (t as f64 - tr).abs() / t_tol;
                assert!(
                    e <= 1.0,
                    "{}: t = {t}, reference {tr}, tolerance {t_tol:e}",
                    kinds[kind]
                );
                st.3 = st.3.max(e);
                if delta > 1e-2 {
                    worst_rel = worst_rel.max((t as f64 - tr).abs() / (tr + r));
                }
            }
            None => assert!(
                !hit,
                "{}: hit at {t}, reference misses (δ = {delta:e})",
                kinds[kind]
            ),
        }
    }
    for ((k, s), d) in kinds.iter().zip(&stats).zip(disagreements) {
        eprintln!(
            "{k}: {} rays, {} hits, {} excused (grazing band or a root at t_min), {} of them decided otherwise than the reference, worst |Δt| = {:.2} of the tolerance",
            s.0, s.1, s.2, d, s.3
        );
    }
    eprintln!("worst |Δt| / (t + r) away from grazing (δ > 1e-2): {worst_rel:.2e}");
    assert!(worst_rel < 16.0 * EPS / 0.1);
    // The bands excuse only rays that graze the sphere (by construction or
    // from its surface), a small share of those.
    assert!(stats[0].2 + stats[2].2 + stats[3].2 == 0, "{stats:?}");
    assert!(stats[4].2 < 4_000 && stats[1].2 < 60_000, "{stats:?}");
}

#[test]
fn normals_are_true_and_outward() {
    let mut rng = Rng::new(43);
    let mut worst = 0.0f64;
    for i in 0..200_000 {
        let k = make_case(&mut rng, [0, 2][i % 2]);
        let (o, d, c) = (V3::from(k.o), V3::from(k.d), V3::from(k.c));
        let (hit, t) = intersect_sphere(o, d, c, k.r, k.t_min);
        assert!(hit);
        let n = hit_normal(o, d, t, c);
        let n64 = DVec3::new(n.x as f64, n.y as f64, n.z as f64);
        assert!((n64.length() - 1.0).abs() < 1e-6);
        // Along the exact radius through the exact point at the f32 t, to
        // within the rounding of o - c (ε |o - c| against the radius).
        let p = k.o.as_dvec3() + k.d.as_dvec3() * t as f64 - k.c.as_dvec3();
        let f = (k.o.as_dvec3() - k.c.as_dvec3()).length();
        let angle = n64.cross(p.normalize()).length();
        let tol = 2.0 * EPS * (f / k.r as f64 + 1.0);
        assert!(angle < tol, "normal off by {angle:e} (tolerance {tol:e})");
        worst = worst.max(angle / tol);
        // Outward: against the ray from outside, along it from inside.
        let along = n64.dot(k.d.as_dvec3());
        assert!(if i % 2 == 0 { along < 0.0 } else { along > 0.0 });
    }
    eprintln!("normals: worst angle {worst:.2} of the tolerance");
}

#[test]
fn sphere8_equals_scalar_bitwise_and_closest_is_brute_force() {
    let mut rng = Rng::new(44);
    for i in 0..100_000 {
        let count = 1 + i % 8;
        let spheres: Vec<Sphere> = (0..count)
            .map(|_| {
                let k = make_case(&mut rng, 0);
                Sphere {
                    center: k.c,
                    radius: k.r,
                }
            })
            .collect();
        let pack = Sphere8::new(&spheres);
        // Rays of every kind, against the first sphere's case.
        let k = make_case(&mut rng, i % 5);
        let (o, d) = if i % 3 == 0 {
            (spheres[0].center + (k.o - k.c), k.d)
        } else {
            (k.o, k.d)
        };
        let (m8, t8) = pack.intersect(o, d, k.t_min);
        let mut best: Option<(usize, f32)> = None;
        for l in 0..8 {
            let s = pack.get(l);
            if let Some(want) = spheres.get(l) {
                assert_eq!(&s, want);
            }
            let (hit, t) = intersect_sphere(
                V3::from(o),
                V3::from(d),
                V3::from(s.center),
                s.radius,
                k.t_min,
            );
            assert_eq!(m8.to_array()[l].to_bits() != 0, hit);
            assert_eq!(t8.to_array()[l].to_bits(), t.to_bits());
            assert!(l < count || !hit, "padding lanes never hit");
            if hit && t < 1e30 && best.is_none_or(|(_, b)| t < b) {
                best = Some((l, t));
            }
            // The normal, scalar and 8-wide.
            if hit {
                let n = hit_normal(V3::from(o), V3::from(d), t, V3::from(s.center));
                let n8 = hit_normal(V3::splat(o), V3::splat(d), t8, pack.center);
                assert_eq!(n.x.to_bits(), n8.x.to_array()[l].to_bits());
                assert_eq!(n.y.to_bits(), n8.y.to_array()[l].to_bits());
                assert_eq!(n.z.to_bits(), n8.z.to_array()[l].to_bits());
            }
        }
        assert_eq!(pack.closest(o, d, k.t_min, 1e30), best);
    }
}

/// The textbook roots `(b ± sqrt(b² - a c)) / a` in f32, without the
/// chapter's two fixes.
fn naive(o: Vec3, d: Vec3, c: Vec3, r: f32) -> Option<f32> {
    let f = o - c;
    let a = d.dot(d);
    let b = -f.dot(d);
    let disc = b * b - a * (f.dot(f) - r * r);
    if disc < 0.0 {
        return None;
    }
    let t0 = (b - disc.sqrt()) / a;
    let t1 = (b + disc.sqrt()) / a;
    [t0, t1].into_iter().find(|&t| t > 0.0)
}

/// The reference test has teeth: the textbook formula, on small spheres
/// seen from afar, misses spheres it should hit and gets `t` wrong beyond
/// the tolerance that the robust kernel keeps.
#[test]
fn textbook_formula_fails_the_tolerance() {
    let mut rng = Rng::new(45);
    let (mut wrong_decisions, mut wrong_t) = (0, 0);
    for _ in 0..100_000 {
        let c = (DVec3::new(rng.f(), rng.f(), rng.f()) * 2.0 - 1.0) * 100.0;
        let r = rng.log_uniform(1e-3, 1e-1);
        let o = c + rng.unit() * rng.log_uniform(1e2, 1e3);
        let target = c + rng.unit() * r * 0.9 * rng.f().cbrt();
        let (o, d, c, r) = (f32v(o), f32v((target - o).normalize()), f32v(c), r as f32);
        let (delta, roots) = reference(o, d, c, r);
        let f = (o - c).as_dvec3().length();
        let t_tol = 8.0 * EPS * (f + r as f64) * (1.0 / delta.abs().sqrt()).max(1.0);
        let Some((t0, _)) = roots else { continue };
        match naive(o, d, c, r) {
            None => wrong_decisions += 1,
            Some(t) => wrong_t += ((t as f64 - t0).abs() > t_tol) as u32,
        }
        let (hit, t) = intersect_sphere(V3::from(o), V3::from(d), V3::from(c), r, 0.0);
        assert!(hit && (t as f64 - t0).abs() <= t_tol);
    }
    eprintln!(
        "textbook formula: {wrong_decisions} misses, {wrong_t} hits beyond the tolerance (of 100 000)"
    );
    assert!(wrong_decisions + wrong_t > 10_000);
}
