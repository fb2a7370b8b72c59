//! Sun, point and spot lights (docs/lights.md): their light on a plane
//! against the closed forms, a sun's shadow and penumbra where geometry
//! puts them, `nee`'s sampling of a sun's cone against BSDF sampling, the
//! engines against each other, the scene file's `[[light]]` and glTF's
//! `KHR_lights_punctual` with its units.

mod common;

use common::{TempDir, ground_scene, run_ok, stderr};
use glam::Vec3;
use std::f64::consts::PI;
use wavetrace::film::Film;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;
use wavetrace::scene::file::parse;
use wavetrace::scene::options::{Integrator, SamplerKind};
use wavetrace::scene::punctual::LightShape;

fn render(scene: &Scene, f: impl FnOnce(&mut RenderSettings)) -> Film {
    let mut s = RenderSettings::for_scene(scene);
    s.threads = 2;
    f(&mut s);
    let (film, _, _) = Renderer::new(scene, &s).unwrap().render();
    assert_eq!(film.invalid_samples, 0);
    film
}

/// Where the ray of pixel `(x, y)` at the point `u` of the pixel meets the
/// ground (y = 0).
fn ground_point(scene: &Scene, (x, y): (u32, u32), u: [f32; 2]) -> Vec3 {
    let camera = scene
        .camera
        .for_resolution(scene.camera.width, scene.camera.height);
    let (o, d) = camera.pixel_ray(x, y, u);
    o + d * (-o.y / d.y)
}

/// The mean over an 8×8 grid of points of pixel `(x, y)` of `f` at the
/// ground point each one sees.
fn pixel_mean(scene: &Scene, xy: (u32, u32), f: &dyn Fn(Vec3) -> f64) -> f64 {
    let n = 8;
    let mut sum = 0.0;
    for i in 0..n {
        for j in 0..n {
            let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
            sum += f(ground_point(scene, xy, u));
        }
    }
    sum / (n * n) as f64
}

/// glTF's spot falloff (KHR_lights_punctual's sample implementation), in
/// f64, for the cosine `cd` of the angle off the axis.
fn gltf_falloff(cd: f64, inner_deg: f64, outer_deg: f64) -> f64 {
    let (ci, co) = (inner_deg.to_radians().cos(), outer_deg.to_radians().cos());
    let scale = 1.0 / (ci - co).max(0.001);
    let a = (cd * scale - co * scale).clamp(0.0, 1.0);
    a * a
}

#[test]
fn point_and_spot_lights_give_the_closed_form_irradiance() {
    // Radiance of a white diffuse plane lit by a point light of intensity
    // I at height h: I cos θ / (π r²), cos θ = h / r; by a spot light, the
    // same times glTF's falloff of the angle off its axis. Every pixel,
    // against the closed form averaged over the pixel, within 1% (the
    // pixel's jitter is the only noise: delta lights have none).
    let point = (Vec3::new(0.3, 1.5, -0.2), [2.0, 1.0, 0.5]);
    let axis = Vec3::new(0.3, -1.0, 0.1).normalize();
    let spot = (Vec3::new(-0.2, 1.2, 0.1), [3.0, 3.0, 3.0], 15.0, 35.0);
    type Radiance = Box<dyn Fn(Vec3) -> [f64; 3]>;
    let cases: [(&str, String, Radiance); 2] = [
        (
            "point",
            format!(
                "[[light]]\ntype = \"point\"\nposition = {:?}\nintensity = 2.0\ncolor = [1.0, 0.5, 0.25]",
                point.0.to_array()
            ),
            Box::new(move |p: Vec3| {
                let to = (point.0 - p).as_dvec3();
                let e = to.y / to.length() / to.length_squared() / PI;
                point.1.map(|i| i * e)
            }),
        ),
        (
            "spot",
            format!(
                "[[light]]\ntype = \"spot\"\nposition = {:?}\ndirection = {:?}\nintensity = 3.0\ninner_angle = 15.0\nouter_angle = 35.0",
                spot.0.to_array(),
                axis.to_array()
            ),
            Box::new(move |p: Vec3| {
                let to = (spot.0 - p).as_dvec3();
                let cd = -axis.as_dvec3().dot(to.normalize());
                let e = to.y / to.length() / to.length_squared() / PI
                    * gltf_falloff(cd, spot.2, spot.3);
                spot.1.map(|i| i * e)
            }),
        ),
    ];
    for (name, light, expected) in &cases {
        let scene = ground_scene([0.0, 3.0, 0.0], 50.0, (48, 48), light);
        let want: Vec<[f64; 3]> = (0..48 * 48)
            .map(|i| {
                let xy = (i % 48, i / 48);
                [0, 1, 2].map(|c| pixel_mean(&scene, xy, &|p| expected(p)[c]))
            })
            .collect();
        let top = want.iter().flatten().fold(0.0f64, |m, &v| m.max(v));
        for engine in [Engine::Reference, Engine::Wavefront] {
            let film = render(&scene, |s| {
                (s.engine, s.spp, s.sampler) = (engine, 64, SamplerKind::Sobol);
            });
            let mut worst = 0.0f64;
            let mut dark = 0;
            for (got, want) in film.to_rgb().iter().zip(&want) {
                for c in 0..3 {
                    let (g, w) = (got[c] as f64, want[c]);
                    worst = worst.max((g - w).abs() / (w + 0.01 * top));
                    dark += usize::from(w == 0.0 && g == 0.0);
                }
            }
            eprintln!("{name} {engine:?}: worst relative error {worst:.2e}");
            assert!(worst < 0.01, "{name} {engine:?}: worst {worst}");
            if *name == "spot" {
                assert!(dark > 1000, "{name}: outside the cone is black ({dark})");
            }
        }
    }
}

/// The irradiance at the ground point `(x, 0, z)`, `x > 0`, from a sun of
/// irradiance `e` whose light travels along `(sin β, −cos β, 0)`, of
/// angular diameter `angle_deg`, past a wall in the plane `x = 0` of
/// height `h`: the cone's radiance `e / (π sin² δ)` × `cos θ` over its
/// unblocked directions, by quadrature (a fine polar grid).
fn sun_past_a_wall(x: f64, e: f64, beta_deg: f64, angle_deg: f64, h: f64) -> f64 {
    let beta = beta_deg.to_radians();
    let axis = glam::DVec3::new(-beta.sin(), beta.cos(), 0.0); // towards the sun
    let blocked = |w: glam::DVec3| w.x < 0.0 && x * w.y / -w.x < h;
    let delta = angle_deg.to_radians() / 2.0;
    if delta == 0.0 {
        return if blocked(axis) { 0.0 } else { e * axis.y };
    }
    let radiance = e / (PI * delta.sin().powi(2));
    let (t, b) = axis.any_orthonormal_pair();
    let (nr, nphi) = (100, 200);
    let mut sum = 0.0;
    for i in 0..nr {
        // Rings of equal solid angle: cos θ uniform in [cos δ, 1].
        let cos = 1.0 - (i as f64 + 0.5) / nr as f64 * (1.0 - delta.cos());
        let sin = (1.0 - cos * cos).sqrt();
        for j in 0..nphi {
            let phi = 2.0 * PI * (j as f64 + 0.5) / nphi as f64;
            let w = axis * cos + t * (sin * phi.cos()) + b * (sin * phi.sin());
            if !blocked(w) {
                sum += w.y;
            }
        }
    }
    let omega = 2.0 * PI * (1.0 - delta.cos());
    radiance * sum * omega / (nr * nphi) as f64
}

/// The ground beyond a wall at x = 0 of height 1 (long along z), lit by a
/// sun of irradiance 3 shining down at 30° from the vertical towards +X,
/// of diameter `angle` degrees, seen from above: 64 columns over x in
/// about [0.25, 1.15] (the predicted shadow ends at x = tan 30° = 0.577).
fn wall_scene(angle: f32) -> Scene {
    let wall = r#"
[[quad]]
material = "white"
vertices = [[0.0, 0.0, -30.0], [0.0, 0.0, 30.0], [0.0, 1.0, 30.0], [0.0, 1.0, -30.0]]
"#;
    let (s, c) = 30f32.to_radians().sin_cos();
    let sun = format!(
        "[[light]]\ntype = \"sun\"\ndirection = [{s:?}, {:?}, 0.0]\nirradiance = 3.0\nangle = {angle:?}",
        -c
    );
    ground_scene([0.7, 3.0, 0.0], 8.6, (64, 32), &format!("{wall}\n{sun}"))
}

/// Per column of `film`, the mean over its rows (the ground's radiance
/// does not change along z).
fn column_means(film: &Film) -> Vec<f64> {
    let rgb = film.to_rgb();
    let (w, h) = (film.width as usize, film.height as usize);
    (0..w)
        .map(|x| (0..h).map(|y| rgb[y * w + x][1] as f64).sum::<f64>() / h as f64)
        .collect()
}

#[test]
fn a_suns_shadow_and_penumbra_lie_where_geometry_puts_them() {
    // A delta sun (diameter 0): a column wholly inside the predicted
    // shadow is exactly black, one wholly outside is exactly E cos β / π.
    let scene = wall_scene(0.0);
    let edge = 30f64.to_radians().tan();
    let span = |x: u32| {
        let lo = ground_point(&scene, (x, 16), [0.0, 0.5]).x as f64;
        let hi = ground_point(&scene, (x, 16), [1.0, 0.5]).x as f64;
        (lo, hi)
    };
    let lit = 3.0 * 30f64.to_radians().cos() / PI;
    for engine in [Engine::Reference, Engine::Wavefront] {
        let film = render(&scene, |s| (s.engine, s.spp) = (engine, 4));
        let cols = column_means(&film);
        let inside = (0..64).filter(|&x| span(x).1 < edge).max().unwrap();
        let outside = (0..64).filter(|&x| span(x).0 > edge).min().unwrap();
        assert_eq!(outside, inside + 2, "the edge crosses one column");
        assert_eq!(cols[inside as usize], 0.0, "{engine:?}: {cols:?}");
        let got = cols[outside as usize];
        assert!((got - lit).abs() < 1e-5, "{engine:?}: {got} vs {lit}");
        assert!(cols[..inside as usize].iter().all(|&c| c == 0.0));
        assert!(
            cols[outside as usize..]
                .iter()
                .all(|&c| (c - lit).abs() < 1e-5)
        );
    }
    // A sun of 10°: the penumbra spans x from tan 25° to tan 35° (0.466
    // to 0.700); each column's mean against the quadrature of the cone's
    // unblocked light (averaged over the column's width), within 2% of
    // the lit level — with 32 rows × 256 samples a column, the noise is
    // below 0.4%.
    let scene = wall_scene(10.0);
    for engine in [Engine::Reference, Engine::Wavefront] {
        let film = render(&scene, |s| (s.engine, s.spp) = (engine, 256));
        let cols = column_means(&film);
        let mut worst = 0.0f64;
        let mut penumbra = 0;
        for (x, got) in cols.iter().enumerate() {
            // Over the column's width (the light does not change along z).
            let want = (0..8)
                .map(|i| {
                    let p = ground_point(&scene, (x as u32, 16), [(i as f32 + 0.5) / 8.0, 0.5]);
                    sun_past_a_wall(p.x as f64, 3.0, 30.0, 10.0, 1.0) / PI
                })
                .sum::<f64>()
                / 8.0;
            worst = worst.max((got - want).abs() / lit);
            penumbra += usize::from(want > 0.05 * lit && want < 0.95 * lit);
        }
        eprintln!(
            "10° sun {engine:?}: worst error {worst:.4} of the lit level; {penumbra} penumbra columns"
        );
        assert!(worst < 0.02, "{engine:?}: worst {worst}");
        assert!(penumbra >= 10, "the penumbra spans columns ({penumbra})");
    }
}

/// A grey sphere on a ground square under a dim sky, lit by a sun of 8°
/// (and, with `deltas`, a point light, a spot light and a delta sun).
fn sunny_scene(deltas: bool) -> Scene {
    let mut text = String::from(
        r#"
[camera]
position = [0.0, 1.0, 4.0]
look_at = [0.0, 0.6, 0.0]
up = [0.0, 1.0, 0.0]
vfov_deg = 45.0
width = 16
height = 16
[integrator]
max_depth = 4
[materials.grey]
reflectance = [0.6, 0.5, 0.4]
[materials.lamp]
reflectance = [0.0, 0.0, 0.0]
emission = [4.0, 4.0, 4.0]
[[sphere]]
center = [0.0, 0.7, 0.0]
radius = 0.7
material = "grey"
[[quad]]
material = "grey"
vertices = [[-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0], [-3.0, 0.0, -3.0]]
[environment]
color = [0.2, 0.25, 0.3]
[[light]]
type = "sun"
direction = [-0.5, -1.0, -0.4]
irradiance = 2.0
angle = 8.0
color = [1.0, 0.9, 0.7]
"#,
    );
    if deltas {
        text += r#"
[[quad]]
material = "lamp"
vertices = [[-0.3, 2.5, -0.3], [0.3, 2.5, -0.3], [0.3, 2.5, 0.3], [-0.3, 2.5, 0.3]]
[[light]]
type = "point"
position = [1.0, 1.5, 1.0]
intensity = 0.8
[[light]]
type = "spot"
position = [-1.0, 2.0, 0.5]
direction = [0.4, -1.0, -0.2]
intensity = 2.0
inner_angle = 10.0
outer_angle = 25.0
color = [0.3, 0.6, 1.0]
[[light]]
type = "sun"
direction = [0.6, -1.0, 0.2]
irradiance = 0.5
angle = 0.0
"#;
    }
    parse(&text, "sunny.toml").unwrap()
}

/// `K` seeds' images of `scene` by `integrator` at `spp`: per pixel and
/// channel, the mean and the squared standard error of the mean.
fn estimate(scene: &Scene, integrator: Integrator, spp: u32) -> Vec<(f64, f64)> {
    const K: u64 = 16;
    let images: Vec<Vec<f64>> = (0..K)
        .map(|k| {
            let film = render(scene, |s| {
                (s.integrator, s.spp, s.seed) = (integrator, spp, 700 + k);
                s.sampler = SamplerKind::Independent;
            });
            film.to_rgb().iter().flatten().map(|&v| v as f64).collect()
        })
        .collect();
    (0..images[0].len())
        .map(|i| {
            let mean = images.iter().map(|im| im[i]).sum::<f64>() / K as f64;
            let var = images.iter().map(|im| (im[i] - mean).powi(2)).sum::<f64>() / (K - 1) as f64;
            (mean, var / K as f64)
        })
        .collect()
}

#[test]
fn nee_sampling_a_suns_cone_converges_to_bsdfs_image() {
    // The sun's cone is drawn by nee uniformly by solid angle and weighed
    // against BSDF sampling; BSDF-sampled rays that leave the scene in the
    // cone see its radiance, weighed the other way. Per-pixel z-scores of
    // nee against plain BSDF sampling over 16 seeds (as tests/unbiased.rs).
    let scene = sunny_scene(false);
    let bsdf = estimate(&scene, Integrator::Bsdf, 1024);
    let nee = estimate(&scene, Integrator::Nee, 64);
    let z: Vec<f64> = nee
        .iter()
        .zip(&bsdf)
        .map(|(&(ma, va), &(mb, vb))| match va + vb {
            0.0 if ma == mb => 0.0,
            0.0 => f64::INFINITY,
            v => (ma - mb) / v.sqrt(),
        })
        .collect();
    let mean_z2 = z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64;
    let max_z = z.iter().fold(0.0f64, |m, z| z.abs().max(m));
    eprintln!("nee vs bsdf with a sun of 8°: mean z² {mean_z2:.3}, max |z| {max_z:.2}");
    assert!(
        mean_z2 < 1.6 && max_z < 7.0,
        "mean z² {mean_z2:.3}, max |z| {max_z:.2}"
    );
}

#[test]
fn the_wavefront_engine_matches_the_reference_with_every_light_type() {
    // A sun with a cone, a delta sun, a point and a spot light, an
    // emissive quad and an environment, every integrator and sampler.
    let scene = sunny_scene(true);
    for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
        for sampler in [SamplerKind::Independent, SamplerKind::Sobol] {
            let settings = |s: &mut RenderSettings| {
                (s.integrator, s.sampler, s.spp) = (integrator, sampler, 8);
            };
            let a = render(&scene, |s| {
                settings(s);
                s.engine = Engine::Reference;
            });
            let b = render(&scene, settings);
            common::assert_engines_close(
                &format!("{integrator:?} {sampler:?}"),
                &a.to_rgb(),
                &b.to_rgb(),
            );
        }
    }
}

#[test]
fn images_with_punctual_lights_are_a_function_of_the_seed() {
    let scene = sunny_scene(true);
    let bits = |f: &Film| f.sums.clone();
    let base = bits(&render(&scene, |s| s.spp = 8));
    assert!(base.iter().any(|s| s[0] > 0));
    for (threads, batch) in [(1, 7), (3, 4096)] {
        let other = render(&scene, |s| {
            (s.spp, s.threads, s.batch_size) = (8, threads, batch)
        });
        assert_eq!(bits(&other), base, "{threads} threads, batch {batch}");
    }
    for simd in wavetrace::accel::simd::SimdWidth::available() {
        let other = render(&scene, |s| (s.spp, s.simd) = (8, simd));
        assert_eq!(bits(&other), base, "{simd:?}");
    }
}

#[test]
fn a_scene_file_names_its_lights_and_refuses_bad_ones() {
    let scene = sunny_scene(true);
    assert_eq!(scene.lights.len(), 4);
    match scene.lights[2].shape {
        LightShape::Spot {
            direction,
            inner,
            outer,
            ..
        } => {
            assert!((direction - Vec3::new(0.4, -1.0, -0.2).normalize()).length() < 1e-6);
            assert!((inner - 10f32.to_radians()).abs() < 1e-7);
            assert!((outer - 25f32.to_radians()).abs() < 1e-7);
        }
        s => panic!("{s:?}"),
    }
    assert_eq!(scene.lights[2].strength, Vec3::new(0.6, 1.2, 2.0));
    assert!(scene.lights[3].is_delta() && !scene.lights[0].is_delta());
    // The default sun is 0.53° across.
    let base = "[[light]]\ntype = \"sun\"\ndirection = [0, -1, 0]\nirradiance = 1\n";
    let s = ground_scene([0.0, 1.0, 0.0], 40.0, (4, 4), base);
    match s.lights[0].shape {
        LightShape::Sun { angle, .. } => assert!((angle - 0.53f32.to_radians()).abs() < 1e-7),
        s => panic!("{s:?}"),
    }
    // Errors name the file, the line and the field.
    for (light, field) in [
        ("type = \"lamp\"", "light[0].type"),
        (
            "type = \"point\"\nposition = [0, 1, 0]",
            "light[0].intensity",
        ),
        ("type = \"point\"\nintensity = 1", "light[0].position"),
        (
            "type = \"point\"\nposition = [0, 1, 0]\nintensity = -1",
            "light[0].intensity",
        ),
        (
            "type = \"point\"\nposition = [0, 1, 0]\nintensity = 1\ndirection = [0, -1, 0]",
            "light[0].direction",
        ),
        ("type = \"sun\"\nirradiance = 1", "light[0].direction"),
        (
            "type = \"sun\"\ndirection = [0, 0, 0]\nirradiance = 1",
            "light[0].direction",
        ),
        (
            "type = \"sun\"\ndirection = [0, -1, 0]\nirradiance = 1\nangle = 200",
            "light[0].angle",
        ),
        (
            "type = \"sun\"\ndirection = [0, -1, 0]\nintensity = 1",
            "light[0].intensity",
        ),
        (
            "type = \"spot\"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\nintensity = 1\ninner_angle = 30\nouter_angle = 20",
            "light[0].inner_angle",
        ),
        (
            "type = \"spot\"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\nintensity = 1\ncolor = [1, 1]",
            "light[0].color",
        ),
        ("type = \"point\"\nwatts = 3", "watts"),
    ] {
        let text = format!(
            "[camera]\nposition = [0, 1, 3]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nvfov_deg = 40\nwidth = 4\nheight = 4\n\
             [materials.m]\nreflectance = [1, 1, 1]\n[[sphere]]\nmaterial = \"m\"\ncenter = [0, 0, 0]\nradius = 1\n\
             [[light]]\n{light}\n"
        );
        let e = parse(&text, "bad.toml").unwrap_err().to_string();
        assert!(
            e.contains("bad.toml:1") && e.contains(field),
            "{light}: {e}"
        );
    }
}

#[test]
fn render_says_when_delta_lights_are_out_of_an_integrators_reach() {
    let dir = TempDir::new("delta-note");
    std::fs::write(
        dir.join("s.toml"),
        "[camera]\nposition = [0, 1, 3]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nvfov_deg = 40\nwidth = 8\nheight = 8\n\
         [materials.m]\nreflectance = [1, 1, 1]\n[[sphere]]\nmaterial = \"m\"\ncenter = [0, 0, 0]\nradius = 1\n\
         [[light]]\ntype = \"point\"\nposition = [0, 2, 0]\nintensity = 1\n",
    )
    .unwrap();
    for (integrator, warned) in [("nee", false), ("bsdf", true), ("report", true)] {
        let o = run_ok(
            &dir,
            &[
                "render",
                "s.toml",
                "-s",
                "1",
                "--integrator",
                integrator,
                "-o",
                "o.pfm",
            ],
        );
        let e = stderr(&o);
        assert_eq!(e.contains("delta light"), warned, "{integrator}: {e}");
        assert!(!e.contains("has no light"), "{integrator}: {e}");
    }
}

/// A GLB of a 4×4 ground square at y = 0 (non-indexed, white, rough, not
/// metallic) and `lights` (the extension's `lights` array) on the nodes
/// `light_nodes` (JSON of nodes with a `KHR_lights_punctual` extension).
fn glb_with_lights(lights: &str, light_nodes: &[String]) -> Vec<u8> {
    let corners = [
        [-2.0f32, 0.0, 2.0],
        [2.0, 0.0, 2.0],
        [2.0, 0.0, -2.0],
        [-2.0, 0.0, -2.0],
    ];
    let bin: Vec<u8> = [0, 1, 2, 0, 2, 3]
        .iter()
        .flat_map(|&i| corners[i])
        .flat_map(f32::to_le_bytes)
        .collect();
    let mut nodes = vec![r#"{"mesh": 0}"#.to_string()];
    nodes.extend_from_slice(light_nodes);
    let ids: Vec<String> = (0..nodes.len()).map(|i| i.to_string()).collect();
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}},
 "extensionsUsed": ["KHR_lights_punctual"],
 "extensions": {{"KHR_lights_punctual": {{"lights": [{lights}]}}}},
 "buffers": [{{"byteLength": {}}}],
 "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": {}}}],
 "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3", "min": [-2, 0, -2], "max": [2, 0, 2]}}],
 "materials": [{{"pbrMetallicRoughness": {{"metallicFactor": 0.0, "roughnessFactor": 1.0}}}}],
 "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "material": 0}}]}}],
 "nodes": [{}],
 "scenes": [{{"nodes": [{}]}}], "scene": 0}}"#,
        bin.len(),
        bin.len(),
        nodes.join(", "),
        ids.join(", ")
    );
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[test]
fn khr_lights_punctual_is_read_in_watts() {
    // A point light of 683 cd at (0, 1, 0) is 1 W/sr; a spot light of
    // 1366 cd (2 W/sr) and a directional light of 683 lux (1 W/m²),
    // each on a node turned −90° about X (so its −Z points down, −Y).
    let (s, c) = (0.5f32.sqrt(), 0.5f32.sqrt()); // a quarter turn about +X
    let lights = r#"{"type": "point", "intensity": 683, "color": [1.0, 0.5, 0.25]},
      {"type": "spot", "intensity": 1366, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
      {"type": "directional", "intensity": 683, "name": "sun"}"#;
    let nodes = [
        r#"{"translation": [0, 1, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}}"#
            .to_string(),
        format!(
            r#"{{"translation": [2.5, 3, 0], "rotation": [{:?}, 0, 0, {c:?}], "extensions": {{"KHR_lights_punctual": {{"light": 1}}}}}}"#,
            -s
        ),
        format!(
            r#"{{"rotation": [{:?}, 0, 0, {c:?}], "extensions": {{"KHR_lights_punctual": {{"light": 2}}}}}}"#,
            -s
        ),
    ];
    let dir = TempDir::new("khr-lights");
    let path = dir.join("lit.glb");
    std::fs::write(&path, glb_with_lights(lights, &nodes)).unwrap();
    let (scene, warnings) = wavetrace::scene::asset_scene::load(&path, None).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    // Lights, so no default sky.
    assert!(scene.environment.is_none());
    assert_eq!(scene.lights.len(), 3);
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-6;
    let [point, spot, sun] = [0, 1, 2].map(|k| &scene.lights[k]);
    assert!(
        close(point.strength, Vec3::new(1.0, 0.5, 0.25)),
        "{point:?}"
    );
    assert!(
        matches!(point.shape, LightShape::Point { position } if close(position, Vec3::new(0.0, 1.0, 0.0)))
    );
    assert!(close(spot.strength, Vec3::splat(2.0)), "{spot:?}");
    match spot.shape {
        LightShape::Spot {
            position,
            direction,
            inner,
            outer,
        } => {
            assert!(close(position, Vec3::new(2.5, 3.0, 0.0)));
            assert!(close(direction, Vec3::NEG_Y), "{direction}");
            assert_eq!((inner, outer), (0.2, 0.5));
        }
        s => panic!("{s:?}"),
    }
    assert!(close(sun.strength, Vec3::ONE), "{sun:?}");
    assert!(
        matches!(sun.shape, LightShape::Sun { direction, angle: 0.0 } if close(direction, Vec3::NEG_Y))
    );
    assert_eq!(sun.name, "sun");
    // Rendered (nee), seen from straight above: the ground right under
    // the point light has the irradiance 1 W/sr × colour / (1 m)² of the
    // point light + 1 W/m² of the sun (the spot, 40° off its axis there,
    // sends nothing: its outer cone is 0.5 rad), and glTF's rough
    // dielectric reflects it within 10% of a white Lambertian surface
    // (E/π): 1:1 candela would be 683 times too bright, Blender's
    // "compatibility" 4π/683 12 times.
    let mut scene = scene;
    scene.camera = ground_scene([0.0, 0.5, 0.0], 2.0, (1, 1), "").camera;
    let film = render(&scene, |s| (s.spp, s.max_depth) = (1024, 2));
    let got = film.to_rgb()[0];
    let e = [2.0f32, 1.5, 1.25];
    eprintln!("glTF ground under the point light: {got:?}, E = {e:?}");
    for c in 0..3 {
        let ratio = got[c] / (e[c] / std::f32::consts::PI);
        assert!((ratio - 1.0).abs() < 0.1, "{got:?}: {ratio}");
    }
}

#[test]
fn bad_khr_lights_punctual_spots_are_refused_with_their_json_path() {
    let dir = TempDir::new("khr-bad");
    let node = vec![
        r#"{"translation": [0, 2, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}}"#
            .to_string(),
    ];
    for (light, at) in [
        (
            r#"{"type": "spot", "intensity": 1, "spot": {"innerConeAngle": 0.6, "outerConeAngle": 0.5}}"#,
            "lights[0].spot.innerConeAngle",
        ),
        (
            r#"{"type": "spot", "intensity": 1, "spot": {"outerConeAngle": 2.0}}"#,
            "lights[0].spot.outerConeAngle",
        ),
        (
            r#"{"type": "point", "intensity": -1}"#,
            "lights[0].intensity",
        ),
    ] {
        let path = dir.join("bad.glb");
        std::fs::write(&path, glb_with_lights(light, &node)).unwrap();
        let e = wavetrace::scene::asset_scene::load(&path, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("bad.glb") && e.contains(at), "{light}: {e}");
    }
}

/// A ground square under a sky (a gradient with a bright sun, turned by
/// 30°) with `extra` (lamps, punctual lights), seen from above.
fn sky_scene(extra: &str) -> Scene {
    let mut scene = ground_scene(
        [0.0, 5.0, 0.0],
        60.0,
        (8, 8),
        &format!("[environment]\ncolor = [1.0, 1.0, 1.0]\n{extra}"),
    );
    let env = scene.environment.as_mut().unwrap();
    let (w, h) = (24u32, 12u32);
    env.texels = std::sync::Arc::new(
        (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| match (i, j) {
                (17, 3) => [300.0, 280.0, 200.0],
                (_, j) if j >= h / 2 => [0.05, 0.04, 0.03],
                (i, j) => [0.3 + 0.02 * i as f32, 0.5, 0.9 - 0.05 * j as f32],
            })
            .collect(),
    );
    (env.width, env.height, env.rotation_deg) = (w, h, 30.0);
    scene
}

/// `n` small emissive squares in a row above the ground, facing down, and, with
/// `sphere`, an emissive sphere (another kind than triangles); more than
/// 16 emitters are picked by a light tree.
fn lamps(n: usize, sphere: bool) -> String {
    let mut s = String::from(
        "[materials.lamp]\nreflectance = [0.0, 0.0, 0.0]\nemission = [400.0, 300.0, 200.0]\n",
    );
    if sphere {
        s += "[[sphere]]\ncenter = [1.5, 1.0, -1.0]\nradius = 0.3\nmaterial = \"lamp\"\n";
    }
    for k in 0..n {
        let x = -2.0 + 0.25 * k as f32;
        s += &format!(
            "[[quad]]\nmaterial = \"lamp\"\nvertices = [[{x:?}, 2.0, -0.2], [{:?}, 2.0, -0.2], [{:?}, 2.0, 0.0], [{x:?}, 2.0, 0.0]]\n",
            x + 0.2,
            x + 0.2
        );
    }
    s
}

const PUNCTUAL: &str = r#"
[[light]]
type = "point"
position = [1.0, 1.5, 1.0]
intensity = 0.8
[[light]]
type = "spot"
position = [-1.0, 2.0, 0.5]
direction = [0.4, -1.0, -0.2]
intensity = 2.0
inner_angle = 10.0
outer_angle = 25.0
[[light]]
type = "sun"
direction = [-0.5, -1.0, -0.4]
irradiance = 2.0
angle = 8.0
[[light]]
type = "sun"
direction = [0.6, -1.0, 0.2]
irradiance = 0.5
angle = 0.0
"#;

#[test]
fn eight_and_sixteen_lanes_sample_the_lights_one_lane_does() {
    // The wavefront light stage's `sample_8` and `sample_16` against the
    // reference tracer's `sample`, lane by lane, bit for bit, in scenes
    // with an environment or punctual lights: the environment alone (the
    // 2CylinderEngine case), with one lamp (textured.glb's), with lamps of
    // two kinds and every punctual light, with a light tree, and punctual
    // lights without an environment.
    use wavetrace::integrator::lights::{LightPoint, Lights};
    use wavetrace::math::V3;
    use wide::f32x8;
    let no_sky = ground_scene([0.0, 5.0, 0.0], 60.0, (8, 8), &(lamps(2, true) + PUNCTUAL));
    let scenes = [
        ("sky", sky_scene("")),
        ("sky + lamp", sky_scene(&lamps(1, false))),
        (
            "sky + lamps + punctual",
            sky_scene(&(lamps(3, true) + PUNCTUAL)),
        ),
        (
            "sky + tree + punctual",
            sky_scene(&(lamps(20, false) + PUNCTUAL)),
        ),
        ("punctual + lamps", no_sky),
    ];
    let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    let fields = |p: &LightPoint<f32>| {
        let v = |v: V3<f32>| [v.x, v.y, v.z];
        let [a, b, c] = [v(p.point), v(p.normal), v(p.emission)];
        let rest = [p.pdf_area, p.pdf_solid_angle, p.scale, p.prim, p.delta];
        [a.as_slice(), &b, &c, &rest].concat()
    };
    let lane = |p: &LightPoint<f32x8>, l: usize| {
        let a = |x: f32x8| x.to_array()[l];
        let v = |v: V3<f32x8>| V3::new(a(v.x), a(v.y), a(v.z));
        LightPoint {
            point: v(p.point),
            normal: v(p.normal),
            emission: v(p.emission),
            pdf_area: a(p.pdf_area),
            pdf_solid_angle: a(p.pdf_solid_angle),
            scale: a(p.scale),
            prim: a(p.prim),
            delta: a(p.delta),
        }
    };
    for (name, scene) in &scenes {
        let lights = Lights::new(scene);
        let mut rng = wavetrace::integrator::sampler::PathRng::new(5, 6, 7);
        let fixed = [0.0f32, 1.0 - f32::EPSILON / 2.0, 0.5, 0.25, 0.999];
        let (mut hits, mut kinds) = (0, [0usize; 3]);
        for round in 0..400 {
            let u: [[f32; 2]; 16] = std::array::from_fn(|l| {
                let a = if (round + l) % 7 == 0 {
                    fixed[(round + l) % 5]
                } else {
                    rng.next_f32()
                };
                [a, rng.next_f32()]
            });
            let o: [V3<f32>; 16] = std::array::from_fn(|_| {
                V3::new(
                    rng.next_f32() * 4.0 - 2.0,
                    rng.next_f32() * 1.5,
                    rng.next_f32() * 4.0 - 2.0,
                )
            });
            let group = |g: usize| {
                let c =
                    |f: &dyn Fn(usize) -> f32| f32x8::from(std::array::from_fn(|l| f(8 * g + l)));
                (
                    V3::new(c(&|l| o[l].x), c(&|l| o[l].y), c(&|l| o[l].z)),
                    [c(&|l| u[l][0]), c(&|l| u[l][1])],
                )
            };
            let ((oa, ua), (ob, ub)) = (group(0), group(1));
            let live = [8, 1 + round % 8];
            let eight = lights.sample_8(oa, ua, live[0]);
            let sixteen = lights.sample_16([oa, ob], [ua, ub], live);
            for l in 0..16 {
                let (g, k) = (l / 8, l % 8);
                if k >= live[g] {
                    continue;
                }
                let want = fields(&lights.sample(o[l], u[l]).unwrap());
                let mut got = vec![fields(&lane(&sixteen[g], k))];
                if g == 0 {
                    got.push(fields(&lane(&eight, k)));
                }
                for got in got {
                    assert!(
                        got.iter().zip(&want).all(|(&a, &b)| same(a, b)),
                        "{name}: lane {l}, u {:?}, o {:?}:\n{got:?}\n{want:?}",
                        u[l],
                        o[l]
                    );
                }
                hits += 1;
                // Which light it went to: a delta light, an emitter, the
                // rest (a sun's cone, the environment).
                let p = lights.sample(o[l], u[l]).unwrap();
                let emitter = p.prim.to_bits() != f32::MAX.to_bits();
                kinds[if p.delta > 0.0 {
                    0
                } else if emitter {
                    1
                } else {
                    2
                }] += 1;
            }
        }
        assert!(hits > 4000, "{name}: {hits}");
        eprintln!("{name}: {hits} lanes, (delta, emitter, other) {kinds:?}");
    }
}
