//! glTF's metallic-roughness BRDF (`bsdf::metallic_roughness`): its value
//! against the specification's Appendix B written out independently in
//! f64, sampling against the density (χ² over metallic × roughness, with a
//! broken variant the test must reject), reciprocity, white furnaces, the
//! roughness → 0 limit of a metal (a mirror), and SIMD ≡ scalar bit for
//! bit.

mod chi2;

use chi2::{Domain, Outcome, frame, sidak};
use glam::DVec3;
use std::f64::consts::PI;
use wavetrace::integrator::bsdf::metallic_roughness::{self as mr, Params};
use wavetrace::integrator::bsdf::{diffuse, metal, mirror};
use wavetrace::integrator::sampler::PathRng;
use wavetrace::math::V3;
use wide::f32x8;

const METALLIC: [f32; 3] = [0.0, 0.5, 1.0];
const ROUGHNESS: [f32; 3] = [0.3, 0.6, 1.0];
const COS_O: [f64; 2] = [0.9, 0.3];
/// χ² tests of the correct sampler in this file.
const CHI2_TESTS: usize = METALLIC.len() * ROUGHNESS.len() * COS_O.len();
const CHI2_SAMPLES: usize = 400_000;

fn level() -> f64 {
    sidak(0.01, CHI2_TESTS)
}

struct Rng(PathRng);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(PathRng::new(seed, 0, 0))
    }
    fn f(&mut self) -> f32 {
        self.0.next_f32()
    }
    fn d(&mut self) -> f64 {
        (self.f() as f64 + self.f() as f64 / 16_777_216.0).min(1.0 - 1e-16)
    }
    fn u2(&mut self) -> [f32; 2] {
        [self.f(), self.f()]
    }
    fn unit(&mut self) -> DVec3 {
        let z = 2.0 * self.d() - 1.0;
        let p = 2.0 * PI * self.d();
        let s = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(s * p.cos(), s * p.sin(), z)
    }
}

fn v32(v: DVec3) -> V3<f32> {
    V3::new(v.x as f32, v.y as f32, v.z as f32)
}

fn v64(v: V3<f32>) -> DVec3 {
    DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// A random unit normal, the test's own frame around it, and `wo` at the
/// given cosine.
struct Setup {
    n: V3<f32>,
    wo: V3<f32>,
    t: DVec3,
    b: DVec3,
    nn: DVec3,
}

impl Setup {
    fn new(rng: &mut Rng, cos_o: f64) -> Self {
        let n = v32(rng.unit());
        let nn = v64(n).normalize();
        let (t, b, _) = frame(nn);
        let p = 2.0 * PI * rng.d();
        let s = (1.0 - cos_o * cos_o).max(0.0).sqrt();
        let wo = v32(t * (s * p.cos()) + b * (s * p.sin()) + nn * cos_o);
        Self { n, wo, t, b, nn }
    }
    fn local(&self, w: V3<f32>) -> DVec3 {
        let w = v64(w);
        DVec3::new(w.dot(self.t), w.dot(self.b), w.dot(self.nn))
    }
    fn world(&self, l: DVec3) -> V3<f32> {
        v32(self.t * l.x + self.b * l.y + self.nn * l.z)
    }
}

fn params(base: [f32; 3], metallic: f32, roughness: f32) -> Params<f32> {
    Params::new(
        V3::new(base[0], base[1], base[2]),
        metallic,
        roughness * roughness,
    )
}

const BASE: [f32; 3] = [0.8, 0.5, 0.2];

/// glTF 2.0 Appendix B, written out from the specification in f64 (its
/// `D`, its height-correlated `V`, its Schlick terms and its two mixes),
/// one channel.
fn appendix_b(n: DVec3, v: DVec3, l: DVec3, base: f64, metallic: f64, roughness: f64) -> f64 {
    let (nv, nl) = (n.dot(v), n.dot(l));
    if nv <= 0.0 || nl <= 0.0 {
        return 0.0;
    }
    let h = (v + l).normalize();
    let (nh, vh) = (n.dot(h), v.dot(h));
    let a = roughness * roughness;
    let a2 = a * a;
    let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let vis = 1.0
        / ((nl.abs() + (a2 + (1.0 - a2) * nl * nl).sqrt())
            * (nv.abs() + (a2 + (1.0 - a2) * nv * nv).sqrt()));
    let specular_brdf = vis * d;
    let diffuse_brdf = base / PI;
    let metal_brdf = specular_brdf * (base + (1.0 - base) * (1.0 - vh.abs()).powi(5));
    let fr = 0.04 + (1.0 - 0.04) * (1.0 - vh.abs()).powi(5);
    let dielectric_brdf = diffuse_brdf * (1.0 - fr) + specular_brdf * fr;
    dielectric_brdf * (1.0 - metallic) + metal_brdf * metallic
}

fn check(name: &str, o: &Outcome, expect_pass: bool) {
    eprintln!(
        "chi2 {name}: p = {:.4e}, stat = {:.1}, dof = {}, pooled = {}, mass = {:.5}, impossible = {}",
        o.p, o.stat, o.dof, o.pooled, o.mass, o.impossible
    );
    if expect_pass {
        assert!(o.p >= level(), "{name}: p = {} below {}", o.p, level());
    } else {
        assert!(
            o.p < level(),
            "{name}: a broken variant passed: p = {}",
            o.p
        );
    }
}

fn chi2_case(
    rng: &mut Rng,
    p: &Params<f32>,
    cos_o: f64,
    claimed_pdf: impl Fn(V3<f32>, V3<f32>, V3<f32>) -> f32,
) -> Outcome {
    let s = Setup::new(rng, cos_o);
    Domain::default().test(
        CHI2_SAMPLES,
        || {
            let smp = mr::sample(s.n, s.wo, p, rng.u2());
            (smp.pdf > 0.0 && smp.cos > 0.0).then(|| s.local(smp.wi))
        },
        |l| claimed_pdf(s.n, s.wo, s.world(l)) as f64,
    )
}

#[test]
fn chi2_sampling_matches_the_density_over_metallic_and_roughness() {
    let mut rng = Rng::new(21);
    for metallic in METALLIC {
        for roughness in ROUGHNESS {
            let p = params(BASE, metallic, roughness);
            for cos_o in COS_O {
                let o = chi2_case(&mut rng, &p, cos_o, |n, wo, wi| mr::pdf(n, wo, wi, &p));
                check(
                    &format!("metallic {metallic}, roughness {roughness}, cos θo {cos_o}"),
                    &o,
                    true,
                );
            }
        }
    }
}

#[test]
fn chi2_rejects_a_density_with_the_wrong_lobe_mixture() {
    // Broken: the density as if the lobes were chosen half and half.
    let mut rng = Rng::new(22);
    let p = params(BASE, 0.0, 0.3);
    let o = chi2_case(&mut rng, &p, 0.9, |n, wo, wi| {
        0.5 * metal::pdf(n, wo, wi, p.alpha) + 0.5 * diffuse::pdf_cosine(n, wi)
    });
    check("broken: lobes mixed half and half", &o, false);
    // Broken: the specular density with α = roughness (not roughness²).
    let o = chi2_case(&mut rng, &p, 0.3, |n, wo, wi| {
        let q = Params { alpha: 0.6, ..p };
        mr::pdf(n, wo, wi, &q)
    });
    check("broken: specular density with α = roughness", &o, false);
}

#[test]
fn value_is_appendix_b_and_samples_agree_with_eval_and_pdf() {
    let mut rng = Rng::new(23);
    let mut worst = [0.0f64; 3];
    for i in 0..200_000 {
        let metallic = [0.0f32, 0.3, 1.0][i % 3];
        let roughness = [0.05f32, 0.2, 0.5, 0.8, 1.0][i % 5];
        let p = params(BASE, metallic, roughness);
        let s = {
            let c = rng.d().max(1e-2);
            Setup::new(&mut rng, c)
        };
        let smp = mr::sample(s.n, s.wo, &p, rng.u2());
        if smp.f.x == 0.0 && smp.f.z == 0.0 {
            assert_eq!((smp.cos, smp.pdf), (0.0, 1.0));
            continue;
        }
        let f = mr::eval(s.n, s.wo, smp.wi, &p);
        let pdf = mr::pdf(s.n, s.wo, smp.wi, &p);
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        worst[0] = worst[0].max(rel(f.z as f64, smp.f.z as f64));
        worst[1] = worst[1].max(rel(pdf as f64, smp.pdf as f64));
        if smp.cos > 1e-3 && roughness >= 0.2 {
            for (c, got) in [f.x, f.y, f.z].into_iter().enumerate() {
                let want = appendix_b(
                    v64(s.n),
                    v64(s.wo),
                    v64(smp.wi),
                    BASE[c] as f64,
                    metallic as f64,
                    roughness as f64,
                );
                if rel(got as f64, want) > 1e-3 {
                    eprintln!(
                        "{got} vs {want}: metallic {metallic} roughness {roughness} cos {} {}",
                        smp.cos,
                        v64(s.n).dot(v64(s.wo))
                    );
                }
                worst[2] = worst[2].max(rel(got as f64, want));
            }
        }
    }
    eprintln!(
        "metallic-roughness worst relative differences: f {:.2e}, pdf {:.2e}, vs Appendix B (f64) {:.2e}",
        worst[0], worst[1], worst[2]
    );
    assert!(worst.iter().all(|&w| w < 2e-3), "{worst:?}");
}

#[test]
fn reciprocal_bitwise() {
    let mut rng = Rng::new(24);
    let mut nonzero = 0;
    for i in 0..200_000 {
        let p = params(BASE, [0.0, 0.4, 1.0][i % 3], [0.0, 0.1, 0.5, 1.0][i % 4]);
        let n = v32(rng.unit());
        let (a, b) = (v32(rng.unit()), v32(rng.unit()));
        let (f, g) = (mr::eval(n, a, b, &p), mr::eval(n, b, a, &p));
        for (x, y) in [(f.x, g.x), (f.y, g.y), (f.z, g.z)] {
            assert!(x.is_finite() && x >= 0.0);
            assert_eq!(x.to_bits(), y.to_bits(), "{x} vs {y}");
        }
        nonzero += (f.x > 0.0) as u32;
    }
    assert!(nonzero > 20_000);
}

/// `∫ f cos dωi` for one channel of Appendix B, by the midpoint rule on
/// `(cos θi, φ)`, `wo` at `cos θo` in the xz plane.
fn albedo_quadrature(cos_o: f64, base: f64, metallic: f64, roughness: f64) -> f64 {
    let (nc, np) = (600, 600);
    let n = DVec3::Z;
    let wo = DVec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
    let mut sum = 0.0;
    for i in 0..nc {
        let c = (i as f64 + 0.5) / nc as f64;
        let s = (1.0 - c * c).sqrt();
        for j in 0..np {
            let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
            let wi = DVec3::new(s * phi.cos(), s * phi.sin(), c);
            sum += appendix_b(n, wo, wi, base, metallic, roughness) * c;
        }
    }
    sum / nc as f64 * 2.0 * PI / np as f64
}

#[test]
fn white_furnace() {
    let mut rng = Rng::new(25);
    let mut excess = 0.0f64;
    for metallic in [0.0f32, 0.5, 1.0] {
        for roughness in [0.3f32, 0.6, 1.0] {
            let mut line = format!("furnace metallic {metallic} roughness {roughness}:");
            let p = params([1.0; 3], metallic, roughness);
            for cos_o in [1.0f64, 0.7, 0.3, 0.1] {
                let s = Setup::new(&mut rng, cos_o);
                let n_samples = 200_000;
                let (mut sum, mut sum2) = (0.0f64, 0.0f64);
                for _ in 0..n_samples {
                    let w = mr::sample(s.n, s.wo, &p, rng.u2())
                        .weigh(V3::new(1.0, 1.0, 1.0))
                        .x as f64;
                    assert!(w.is_finite() && w >= 0.0);
                    sum += w;
                    sum2 += w * w;
                }
                let mean = sum / n_samples as f64;
                let sigma = ((sum2 / n_samples as f64 - mean * mean) / n_samples as f64).sqrt();
                let quad = albedo_quadrature(cos_o, 1.0, metallic as f64, roughness as f64);
                line += &format!(" cos θo {cos_o}: MC {mean:.4} ± {sigma:.1e}, quad {quad:.4};");
                assert!((mean - quad).abs() < 5.0 * sigma + 2e-3, "{line}");
                // A metal never reflects more than it receives, nor does any
                // surface at normal incidence.
                if metallic == 1.0 || cos_o == 1.0 {
                    assert!(mean <= 1.0 + 5.0 * sigma && quad <= 1.0 + 1e-3, "{line}");
                } else {
                    excess = excess.max(quad - 1.0);
                }
            }
            eprintln!("{line}");
        }
    }
    eprintln!("Appendix B's dielectric part: largest albedo above 1: {excess:.4}");
}

#[test]
fn a_smooth_metal_tends_to_a_mirror() {
    let mut rng = Rng::new(26);
    for roughness in [1e-2f32, 1e-3, 0.0] {
        let p = params([1.0; 3], 1.0, roughness);
        let a = metal::clamp_alpha(roughness * roughness) as f64;
        let mut angles = Vec::new();
        let mut min_weight = f64::INFINITY;
        for _ in 0..50_000 {
            let s = {
                let c = rng.d().max(0.05);
                Setup::new(&mut rng, c)
            };
            let smp = mr::sample(s.n, s.wo, &p, rng.u2());
            let mirror_dir = v64(mirror::sample(s.n, s.wo, p.base).wi);
            angles.push(
                v64(smp.wi)
                    .normalize()
                    .dot(mirror_dir.normalize())
                    .clamp(-1.0, 1.0)
                    .acos(),
            );
            let w = smp.weigh(V3::new(1.0, 1.0, 1.0)).x as f64;
            assert!(w.is_finite());
            if smp.f.x > 0.0 {
                min_weight = min_weight.min(w);
            }
        }
        angles.sort_by(f64::total_cmp);
        let median = angles[angles.len() / 2];
        eprintln!(
            "roughness {roughness}: median angle to the mirror {median:.2e}, least weight {min_weight:.6}"
        );
        assert!(median < 3.0 * a + 1e-6, "median {median}");
        // White base colour: F = 1 at every angle, so the weight is G2/G1 → 1.
        assert!(
            min_weight > 1.0 - 0.2 * roughness as f64 - 1e-3,
            "{min_weight}"
        );
    }
}

/// One lane's normal, `wo`, `wi`, parameters and direction numbers.
type Lane = (V3<f32>, V3<f32>, V3<f32>, Params<f32>, [f32; 2]);

#[test]
fn simd_equals_scalar_bitwise() {
    let mut rng = Rng::new(27);
    for _ in 0..5_000 {
        let lanes: [Lane; 8] = std::array::from_fn(|_| {
            let n = v32(rng.unit());
            let wo = v32(rng.unit());
            let wi = v32(rng.unit());
            let p = Params {
                // KHR_materials_specular's F0 and F90 in half the lanes.
                f0: match rng.f() < 0.5 {
                    true => V3::new(rng.f(), rng.f(), rng.f()).scale(0.5),
                    false => V3::new(0.04, 0.04, 0.04),
                },
                f90: rng.f().max(0.5),
                ..Params::new(
                    V3::new(rng.f(), rng.f(), rng.f()),
                    rng.f(),
                    rng.f() * rng.f(),
                )
            };
            (n, wo, wi, p, rng.u2())
        });
        let v8 = |g: &dyn Fn(usize) -> V3<f32>| {
            let a: [V3<f32>; 8] = std::array::from_fn(g);
            V3::new(
                f32x8::from(a.map(|v| v.x)),
                f32x8::from(a.map(|v| v.y)),
                f32x8::from(a.map(|v| v.z)),
            )
        };
        let s8 = |g: &dyn Fn(usize) -> f32| f32x8::from(std::array::from_fn::<f32, 8, _>(g));
        let n = v8(&|l| lanes[l].0);
        let wo = v8(&|l| lanes[l].1);
        let wi = v8(&|l| lanes[l].2);
        let p = Params {
            base: v8(&|l| lanes[l].3.base),
            metallic: s8(&|l| lanes[l].3.metallic),
            alpha: s8(&|l| lanes[l].3.alpha),
            f0: v8(&|l| lanes[l].3.f0),
            f90: s8(&|l| lanes[l].3.f90),
        };
        let u = [s8(&|l| lanes[l].4[0]), s8(&|l| lanes[l].4[1])];
        let f8 = mr::eval(n, wo, wi, &p);
        let p8 = mr::pdf(n, wo, wi, &p);
        let smp8 = mr::sample(n, wo, &p, u);
        for (l, (n, wo, wi, p, u)) in lanes.iter().enumerate() {
            let bits = |v: V3<f32>| [v.x, v.y, v.z].map(f32::to_bits);
            let lane =
                |v: V3<f32x8>| V3::new(v.x.to_array()[l], v.y.to_array()[l], v.z.to_array()[l]);
            assert_eq!(bits(mr::eval(*n, *wo, *wi, p)), bits(lane(f8)));
            assert_eq!(
                mr::pdf(*n, *wo, *wi, p).to_bits(),
                p8.to_array()[l].to_bits()
            );
            let s = mr::sample(*n, *wo, p, *u);
            assert_eq!(bits(s.wi), bits(lane(smp8.wi)));
            assert_eq!(bits(s.f), bits(lane(smp8.f)));
            assert_eq!(s.pdf.to_bits(), smp8.pdf.to_array()[l].to_bits());
            assert_eq!(s.cos.to_bits(), smp8.cos.to_array()[l].to_bits());
        }
    }
}

// ---------------------------------------------------------------------------
// KHR_materials_specular

/// A metallic-roughness material with `KHR_materials_ior` and
/// `KHR_materials_specular`, as the asset loader makes it.
fn specular_material(
    base: [f32; 3],
    (metallic, roughness): (f32, f32),
    ior: f32,
    (specular, colour): (f32, [f32; 3]),
) -> wavetrace::scene::Material {
    use wavetrace::scene::{Material, Model};
    let mut m = Material::diffuse("specular", glam::Vec3::from(base), glam::Vec3::ZERO);
    m.model = Model::MetallicRoughness;
    (m.metallic, m.roughness, m.ior) = (metallic, roughness, ior);
    (m.specular, m.specular_colour) = (specular, glam::Vec3::from(colour));
    m
}

/// `KHR_materials_specular`'s BRDF, written out from the extension's
/// text in f64, one channel `c` of three: `dielectric_f0 = min(F0(ior) ×
/// specularColor, 1) × specular`, `dielectric_f90 = specular`, the
/// Fresnel mix of Appendix B with the diffuse lobe weighed by
/// `1 − max_value(dielectric_fresnel)`; the metal part unchanged.
fn khr_specular(
    (n, v, l): (DVec3, DVec3, DVec3),
    c: usize,
    base: [f64; 3],
    (metallic, roughness, ior): (f64, f64, f64),
    (specular, colour): (f64, [f64; 3]),
) -> f64 {
    let (nv, nl) = (n.dot(v), n.dot(l));
    if nv <= 0.0 || nl <= 0.0 {
        return 0.0;
    }
    let h = (v + l).normalize();
    let (nh, vh) = (n.dot(h), v.dot(h));
    let a = roughness * roughness;
    let a2 = a * a;
    let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let vis = 1.0
        / ((nl + (a2 + (1.0 - a2) * nl * nl).sqrt()) * (nv + (a2 + (1.0 - a2) * nv * nv).sqrt()));
    let specular_brdf = vis * d;
    let w = (1.0 - vh.abs()).powi(5);
    let f0_ior = ((ior - 1.0) / (ior + 1.0)).powi(2);
    let fresnel = |k: usize| {
        let f0 = (f0_ior * colour[k]).min(1.0) * specular;
        f0 + (specular - f0) * w
    };
    let max = fresnel(0).max(fresnel(1)).max(fresnel(2));
    let dielectric = fresnel(c) * specular_brdf + (1.0 - max) * base[c] / PI;
    let metal = specular_brdf * (base[c] + (1.0 - base[c]) * w);
    dielectric * (1.0 - metallic) + metal * metallic
}

/// The value of a `KHR_materials_specular` material through the material
/// seam (`Surface::of`, as both engines evaluate it) is the extension's
/// formula written out in f64, over specular strengths and colours
/// (coloured, beyond 1 and clamped), indices (`KHR_materials_ior`, 0
/// included: F0 = 1), metalness and roughness; and the defaults are
/// Appendix B bit for bit.
#[test]
fn specular_is_the_extensions_formula_through_the_material_seam() {
    use wavetrace::integrator::bsdf::Surface;
    let mut rng = Rng::new(41);
    let cases: [(f32, [f32; 3], f32); 6] = [
        (1.0, [1.0, 1.0, 1.0], 1.5),
        (0.5, [1.0, 0.2, 0.6], 1.5),
        (1.0, [2.0, 0.5, 40.0], 1.5),
        (0.8, [1.0, 1.0, 1.0], 1.33),
        (0.3, [0.7, 1.0, 0.1], 2.4),
        (1.0, [0.9, 0.6, 0.3], 0.0),
    ];
    let mut worst = 0.0f64;
    for (k, (specular, colour, ior)) in cases.into_iter().enumerate() {
        for i in 0..20_000 {
            let metallic = [0.0f32, 0.4, 1.0][i % 3];
            let roughness = [0.2f32, 0.5, 1.0][i % 3];
            let m = specular_material(BASE, (metallic, roughness), ior, (specular, colour));
            let surface = Surface::of(&m);
            let c = rng.d().max(0.05);
            let s = Setup::new(&mut rng, c);
            let wi = v32(rng.unit());
            let (fcos, cos, _) = surface.eval(s.n, s.wo, wi, true);
            if cos < 1e-3 {
                continue;
            }
            let got = [fcos.x, fcos.y, fcos.z].map(|x| x as f64 / cos as f64);
            for (c, got) in got.into_iter().enumerate() {
                let want = khr_specular(
                    (v64(s.n), v64(s.wo), v64(wi)),
                    c,
                    BASE.map(f64::from),
                    (metallic as f64, roughness as f64, ior as f64),
                    (specular as f64, colour.map(f64::from)),
                );
                let rel = (got - want).abs() / want.max(1e-3);
                assert!(rel < 2e-3, "case {k} channel {c}: {got} vs {want}");
                worst = worst.max(rel);
            }
            if k == 0 {
                // The defaults: Appendix B's own arithmetic, bit for bit.
                let p = params(BASE, metallic, roughness);
                let plain = mr::eval(s.n, s.wo, wi, &p).scale(cos);
                let bits = |v: V3<f32>| [v.x, v.y, v.z].map(f32::to_bits);
                assert_eq!(bits(plain), bits(fcos));
            }
        }
    }
    eprintln!("KHR_materials_specular vs its formula (f64): worst relative difference {worst:.2e}");
}

/// At normal incidence (`wo = wi = n`: `V·H = 1`, `D = 1/(π α²)`,
/// `V = 1/4`) the value is the closed form
/// `f = min(F0(ior) specularColor, 1) specular / (4π α²) + (1 − max F0) base/π`
/// of a dielectric: the specular colour tints `F0` channel by channel.
#[test]
fn specular_colour_tints_f0_at_normal_incidence() {
    use wavetrace::integrator::bsdf::Surface;
    let n = V3::new(0.0, 0.0, 1.0);
    for (specular, colour, ior, roughness) in [
        (1.0f32, [1.0f32, 0.25, 4.0], 1.5f32, 0.5f32),
        (0.6, [0.5, 1.0, 40.0], 1.7, 0.7),
        (0.0, [1.0, 1.0, 1.0], 1.5, 0.4),
    ] {
        let m = specular_material(BASE, (0.0, roughness), ior, (specular, colour));
        let (fcos, cos, _) = Surface::of(&m).eval(n, n, n, true);
        let a2 = (roughness as f64).powi(4);
        let f0_ior = ((ior as f64 - 1.0) / (ior as f64 + 1.0)).powi(2);
        let f0 = colour.map(|c| (f0_ior * c as f64).min(1.0) * specular as f64);
        let max = f0[0].max(f0[1]).max(f0[2]);
        for (c, got) in [fcos.x, fcos.y, fcos.z].into_iter().enumerate() {
            let want = f0[c] / (4.0 * PI * a2) + (1.0 - max) * BASE[c] as f64 / PI;
            let got = got as f64 / cos as f64;
            assert!(
                (got / want - 1.0).abs() < 1e-5,
                "specular {specular}, colour {colour:?}, ior {ior}: channel {c}: {got} vs {want}"
            );
        }
    }
}

/// `specular = 0` removes the specular lobe: the dielectric is Lambert's
/// `base/π` for every pair of directions, every sample's weight is the
/// base colour exactly (a white furnace of albedo `base`), and a metal is
/// unaffected.
#[test]
fn specular_zero_leaves_the_diffuse_lobe_alone() {
    use wavetrace::integrator::bsdf::Surface;
    let mut rng = Rng::new(42);
    for roughness in [0.1f32, 0.5, 1.0] {
        for colour in [[1.0f32; 3], [0.2, 3.0, 1.0]] {
            let m = specular_material(BASE, (0.0, roughness), 1.5, (0.0, colour));
            let surface = Surface::of(&m);
            let (mut sum, count) = (0.0f64, 20_000);
            for _ in 0..count {
                let c = rng.d().max(0.02);
                let s = Setup::new(&mut rng, c);
                let wi = v32(rng.unit());
                let (fcos, cos, _) = surface.eval(s.n, s.wo, wi, true);
                if cos > 0.0 {
                    let want = BASE[1] as f64 / PI;
                    assert!((fcos.y as f64 / cos as f64 / want - 1.0).abs() < 1e-5);
                }
                let smp = surface.sample(s.n, -s.wo, rng.u2(), false);
                let w = smp.weigh(V3::new(1.0, 1.0, 1.0));
                if smp.cos > 0.0 {
                    for (c, w) in [w.x, w.y, w.z].into_iter().enumerate() {
                        assert!((w - BASE[c]).abs() < 1e-5, "weight {w} vs {}", BASE[c]);
                    }
                }
                sum += w.y as f64;
            }
            let albedo = sum / count as f64;
            eprintln!("specular 0, roughness {roughness}, colour {colour:?}: albedo {albedo:.5}");
            assert!((albedo - BASE[1] as f64).abs() < 1e-3);
        }
    }
    // A metal: the same with any specular.
    let s = Setup::new(&mut rng, 0.6);
    let wi = v32(rng.unit());
    let a = Surface::of(&specular_material(BASE, (1.0, 0.5), 1.5, (0.0, [0.3; 3])));
    let b = Surface::of(&specular_material(BASE, (1.0, 0.5), 1.5, (1.0, [1.0; 3])));
    let (fa, fb) = (a.eval(s.n, s.wo, wi, true).0, b.eval(s.n, s.wo, wi, true).0);
    assert_eq!([fa.x, fa.y, fa.z], [fb.x, fb.y, fb.z]);
}

/// Sampling still draws directions with the density `pdf` claims with
/// `KHR_materials_specular` (χ²), and a density that ignores the
/// extension's Fresnel (the default lobe choice) is rejected.
#[test]
fn chi2_sampling_matches_the_density_with_khr_materials_specular() {
    let mut rng = Rng::new(43);
    let tinted = |specular: f32, colour: [f32; 3], metallic: f32, roughness: f32| {
        let f0 = colour.map(|c| (0.04 * c).min(1.0) * specular);
        Params {
            f0: V3::new(f0[0], f0[1], f0[2]),
            f90: specular,
            ..params(BASE, metallic, roughness)
        }
    };
    for (specular, colour, metallic, roughness, cos_o) in [
        (0.5f32, [1.0f32, 0.2, 6.0], 0.0f32, 0.3f32, 0.9f64),
        (0.2, [1.0, 1.0, 1.0], 0.0, 0.6, 0.3),
        (1.0, [10.0, 25.0, 3.0], 0.5, 0.3, 0.3),
        (0.0, [1.0, 1.0, 1.0], 0.3, 0.6, 0.9),
    ] {
        let p = tinted(specular, colour, metallic, roughness);
        let o = chi2_case(&mut rng, &p, cos_o, |n, wo, wi| mr::pdf(n, wo, wi, &p));
        let name = format!(
            "specular {specular}, colour {colour:?}, metallic {metallic}, roughness {roughness}, cos θo {cos_o}"
        );
        check(&name, &o, true);
    }
    // Broken: the density of the default specular (F0 0.04, F90 1).
    let p = tinted(0.1, [1.0; 3], 0.0, 0.3);
    let o = chi2_case(&mut rng, &p, 0.9, |n, wo, wi| {
        mr::pdf(n, wo, wi, &params(BASE, 0.0, 0.3))
    });
    check("broken: the default specular's density", &o, false);
}
