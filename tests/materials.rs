//! Material models in whole renders: energy in closed furnaces (mirror,
//! metal, glass) for every integrator in both engines, next-event
//! estimation skipping delta surfaces, and the scene format's material
//! fields.

use wavetrace::film::Film;
use wavetrace::integrator::Counters;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::options::Integrator;
use wavetrace::scene::{Scene, file};

/// Six quads of material `material` making the cube `[-h, h]^3`, their
/// counter-clockwise fronts facing inwards (`inwards`) or outwards.
fn cube(h: f32, material: &str, inwards: bool) -> String {
    let mut quads = String::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for sign in [-1.0f32, 1.0] {
            let mut corners: Vec<[f64; 3]> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                .iter()
                .map(|&(a, b)| {
                    let mut p = [0.0; 3];
                    p[axis] = (sign * h) as f64;
                    p[u] = (a * h) as f64;
                    p[v] = (b * h) as f64;
                    p
                })
                .collect();
            // In this order the face at -h faces +axis (inwards).
            if (sign > 0.0) == inwards {
                corners.reverse();
            }
            quads += &format!("[[quad]]\nmaterial = \"{material}\"\nvertices = {corners:?}\n\n");
        }
    }
    quads
}

/// A scene: the camera inside the cube `[-1, 1]^3` of material `wall`
/// (given as TOML fields), plus `extra` TOML.
fn enclosure(wall: &str, extra: &str) -> Scene {
    let text = format!(
        r#"name = "enclosure"

[camera]
position = [0.2, -0.3, -0.8]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
vfov_deg = 90.0
width = 64
height = 64

[materials.wall]
{wall}

{}
{extra}"#,
        cube(1.0, "wall", true)
    );
    file::parse(&text, "enclosure.toml").unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// Renders `scene` at `spp` samples per pixel to `depth` with
/// `integrator` in both engines, which must agree (same counts, pixels
/// within 1e-5); returns the reference's pixels and its counters.
fn render(
    scene: &Scene,
    depth: u32,
    integrator: Integrator,
    spp: u32,
) -> (Vec<[f32; 3]>, Counters) {
    let run = |engine| {
        let mut s = RenderSettings::for_scene(scene);
        (s.spp, s.max_depth, s.integrator, s.engine, s.seed) = (spp, depth, integrator, engine, 3);
        let (film, mut c, _): (Film, Counters, _) = Renderer::new(scene, &s).unwrap().render();
        assert_eq!(film.invalid_samples, 0);
        c.stages = Default::default();
        (film.to_rgb(), c)
    };
    let (a, b) = (run(Engine::Reference), run(Engine::Wavefront));
    assert_eq!(
        a.1, b.1,
        "{integrator:?}: the engines traced different paths"
    );
    for (p, q) in a.0.iter().zip(&b.0) {
        for c in 0..3 {
            assert!((p[c] - q[c]).abs() <= 1e-5 * p[c].abs().max(q[c].abs()) + 1e-6);
        }
    }
    a
}

const INTEGRATORS: [Integrator; 3] = [Integrator::Report, Integrator::Bsdf, Integrator::Nee];

/// A closed mirror room of tint `a` emitting `E`: every sample is exactly
/// `E · Σ a^k`, save the rare path that leaves a surface within rounding
/// of an edge and escapes through the corner (as in the diffuse furnace):
/// those have less, never more. Next-event estimation takes no shadow ray at a mirror.
#[test]
fn a_mirror_furnace_gives_the_closed_form_in_every_sample_that_stays_inside() {
    let (a, e, depth) = (0.5f64, 2.0f64, 4);
    let scene = enclosure(
        "model = \"mirror\"\nreflectance = [0.5, 0.5, 0.5]\nemission = [2.0, 2.0, 2.0]",
        "",
    );
    let expected: f64 = (0..depth).map(|k| e * a.powi(k)).sum();
    for integrator in INTEGRATORS {
        let (pixels, counters) = render(&scene, depth as u32, integrator, 1);
        assert_eq!(counters.shadow_rays, 0, "{integrator:?}");
        let mut off = 0;
        for &x in pixels.iter().flatten() {
            let x = x as f64;
            assert!(
                x <= expected * (1.0 + 1e-5),
                "{integrator:?}: {x} above {expected}"
            );
            off += (x < expected * (1.0 - 1e-5)) as usize;
        }
        assert!(
            off * 200 <= pixels.len() * 3,
            "{integrator:?}: {off} samples off {expected}"
        );
    }
}

/// A closed room of white rough metal (α = 0.1) emitting `E`, to depth
/// `d`: single-scattering microfacets lose a little energy (about 1-2% per
/// bounce at this roughness), never gain, so the image lies just below
/// `E·d` — and the three integrators agree (next-event estimation weighs
/// metal by its own density).
#[test]
fn a_metal_furnace_loses_a_little_energy_and_the_integrators_agree() {
    let (e, depth) = (1.0f64, 3);
    let scene = enclosure(
        "model = \"metal\"\nalpha = 0.1\nreflectance = [1.0, 1.0, 1.0]\nemission = [1.0, 1.0, 1.0]",
        "",
    );
    let upper = e * depth as f64;
    let mut means = vec![];
    for integrator in INTEGRATORS {
        let (pixels, counters) = render(&scene, depth, integrator, 4);
        if integrator == Integrator::Nee {
            assert!(counters.shadow_rays > 0);
        }
        let xs: Vec<f64> = pixels.iter().map(|p| p[1] as f64).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (xs.len() - 1) as f64;
        let se = (var / xs.len() as f64).sqrt();
        eprintln!("{integrator:?}: mean {mean:.4} ± {se:.4} (E·d = {upper})");
        assert!(
            mean <= upper + 4.0 * se,
            "{integrator:?}: {mean} above {upper}"
        );
        assert!(
            mean >= 0.95 * upper,
            "{integrator:?}: {mean} loses too much"
        );
        means.push((mean, se));
    }
    for w in means.windows(2) {
        let ((m1, s1), (m2, s2)) = (w[0], w[1]);
        assert!(
            (m1 - m2).abs() <= 5.0 * (s1 * s1 + s2 * s2).sqrt(),
            "{means:?}"
        );
    }
}

/// A clear glass cube (index 1.5) in a black room that emits `E`: glass
/// absorbs nothing, and the radiance scaling of refraction in and out
/// cancels, so a sample that reaches a wall within the depth is `E` (to
/// rounding); one still inside (total internal reflection) is 0, and the
/// rare one that slips out through an edge of the cube within rounding,
/// unrefracted, keeps its `1/η²` — never more than `E`.
#[test]
fn glass_is_lossless() {
    let scene = enclosure(
        "reflectance = [0.0, 0.0, 0.0]\nemission = [1.0, 1.0, 1.0]",
        &format!(
            "[materials.glass]\nmodel = \"glass\"\nior = 1.5\n\n{}",
            cube(0.4, "glass", false)
        ),
    );
    for integrator in INTEGRATORS {
        let (pixels, _) = render(&scene, 24, integrator, 1);
        let mut exact = 0;
        for p in &pixels {
            let x = p[0] as f64;
            assert!(x <= 1.0 + 1e-5, "{integrator:?}: glass added energy: {x}");
            exact += ((x - 1.0).abs() <= 1e-5) as usize;
        }
        assert!(
            exact * 100 >= pixels.len() * 97,
            "{integrator:?}: only {exact} of {} samples are E",
            pixels.len()
        );
    }
}

/// The scene format's material fields: each model reads its own, and a
/// field another model reads is refused with the file, line and field.
#[test]
fn material_fields_are_checked() {
    let scene = |material: &str| {
        format!(
            "name = \"m\"\n[camera]\nposition = [0.0, 0.0, -3.0]\nlook_at = [0.0, 0.0, 0.0]\n\
             up = [0.0, 1.0, 0.0]\nvfov_deg = 40.0\nwidth = 8\nheight = 8\n\n\
             [materials.m]\n{material}\n\n[[triangle]]\nmaterial = \"m\"\n\
             vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]\n"
        )
    };
    let ok = |m: &str| file::parse(&scene(m), "m.toml").unwrap_or_else(|e| panic!("{m}: {e}"));
    let refused = |m: &str, wanted: &[&str]| {
        let e = file::parse(&scene(m), "m.toml").unwrap_err().to_string();
        for w in wanted {
            assert!(e.contains(w), "{m}: error {e:?} lacks {w:?}");
        }
    };
    let m = ok("model = \"glass\"\nior = 1.33\ntransmittance = [1.0, 0.9, 0.8]");
    assert_eq!(
        (m.materials[0].ior, m.materials[0].transmittance.y),
        (1.33, 0.9)
    );
    assert_eq!(
        ok("model = \"metal\"\nreflectance = [1.0, 1.0, 1.0]\nalpha = 0.25").materials[0].alpha,
        0.25
    );
    ok("model = \"mirror\"\nreflectance = [0.9, 0.9, 0.9]");
    ok("model = \"glass\"");
    refused(
        "reflectance = [0.5, 0.5, 0.5]\nior = 1.5",
        &["m.toml:12:", "materials.m.ior", "glass"],
    );
    refused(
        "model = \"mirror\"\nreflectance = [0.5, 0.5, 0.5]\nalpha = 0.1",
        &["materials.m.alpha", "metal"],
    );
    refused(
        "model = \"glass\"\nreflectance = [0.5, 0.5, 0.5]",
        &["materials.m.reflectance"],
    );
    refused(
        "model = \"glass\"\nior = -1.0",
        &["materials.m.ior", "from 0.1 to 10"],
    );
    refused("model = \"glass\"\nior = 0.0", &["materials.m.ior"]);
    refused(
        "model = \"metal\"\nreflectance = [1.0, 1.0, 1.0]\nalpha = 1.5",
        &["materials.m.alpha"],
    );
    refused("model = \"metal\"", &["materials.m.reflectance"]);
    refused(
        "model = \"glass\"\ntransmittance = [1.5, 1.0, 1.0]",
        &["materials.m.transmittance", "[0, 1]"],
    );
    refused(
        "model = \"phong\"\nreflectance = [1.0, 1.0, 1.0]",
        &["materials.m.model", "diffuse, mirror, glass, metal"],
    );
}

/// A room lit only by an emissive sphere: next-event estimation samples
/// points on the sphere (by area) and converges to the image that BSDF
/// sampling alone finds — with less noise — and the engines agree.
#[test]
fn an_emissive_sphere_is_a_light() {
    let scene = enclosure(
        "reflectance = [0.6, 0.5, 0.4]",
        "[materials.bulb]\nreflectance = [0.5, 0.5, 0.5]\nemission = [4.0, 3.0, 2.0]\n\n\
         [[sphere]]\nmaterial = \"bulb\"\ncenter = [0.3, 0.5, 0.2]\nradius = 0.25\n",
    );
    let (_, counters) = render(&scene, 3, Integrator::Nee, 4);
    assert!(counters.shadow_rays > 0);
    // Per pixel: the mean and spread of 16 seeds of 16 samples.
    let estimate = |integrator| {
        let runs: Vec<Vec<f64>> = (0..16)
            .map(|seed| {
                let mut s = RenderSettings::for_scene(&scene);
                (s.width, s.height, s.spp, s.max_depth, s.seed) = (24, 24, 16, 3, 50 + seed);
                s.integrator = integrator;
                let (film, _, _) = Renderer::new(&scene, &s).unwrap().render();
                film.to_rgb().iter().flatten().map(|&v| v as f64).collect()
            })
            .collect();
        let n = runs[0].len();
        (0..n)
            .map(|i| {
                let m = runs.iter().map(|r| r[i]).sum::<f64>() / 16.0;
                let v = runs.iter().map(|r| (r[i] - m).powi(2)).sum::<f64>() / 15.0;
                (m, v / 16.0)
            })
            .collect::<Vec<_>>()
    };
    let (bsdf, nee) = (estimate(Integrator::Bsdf), estimate(Integrator::Nee));
    let z2: f64 = bsdf
        .iter()
        .zip(&nee)
        .map(|(a, b)| (a.0 - b.0).powi(2) / (a.1 + b.1).max(1e-12))
        .sum::<f64>()
        / bsdf.len() as f64;
    let var = |e: &[(f64, f64)]| e.iter().map(|x| x.1).sum::<f64>();
    eprintln!(
        "mean z² {z2:.3}; variance bsdf {:.3e}, nee {:.3e}",
        var(&bsdf),
        var(&nee)
    );
    assert!(z2 < 1.6, "nee and bsdf disagree: mean z² {z2}");
    assert!(
        var(&nee) * 2.0 < var(&bsdf),
        "light sampling does not reduce noise"
    );
}
