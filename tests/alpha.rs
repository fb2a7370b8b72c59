//! A transparent background and the AOVs of datasets (issue 28 item 4,
//! issue 29's depth and object-ID outputs): alpha, zdepth and object_id,
//! accumulated exactly beside the radiance by both engines.
//!
//! - alpha is the exact count of the camera rays that hit, against a
//!   brute-force count of the very rays (the sampler's numbers through the
//!   camera) intersected by this test in `f64`;
//! - object_id is the id most of a pixel's samples hit, against the same
//!   brute force, on a scene of two objects; zdepth is the distance along
//!   the camera's axis, against the closed forms for a plane and a sphere;
//! - all three the same bits whatever the threads, batch sizes, kernel
//!   widths, passes, `.wtacc` round trips, shards and engines;
//! - files: an RGBA PNG (straight colour), an EXR with `A`, `zdepth.Z` and
//!   a `u32` `object_id.id`, a 16-bit PNG of the ids; `--transparent` and
//!   `visible = false` on the command line.

mod common;

use common::{TempDir, run_ok};
use glam::DVec3;
use wavetrace::accel::simd::SimdWidth;
use wavetrace::film::{AccMeta, Film};
use wavetrace::integrator::sampler::{Sampler, Sobol};
use wavetrace::output::{OBJECT_ID_LAYER, ZDEPTH_LAYER, read_exr_layer, read_image, write_output};
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::{Aov, AovSet, SamplerKind, Scene};

const W: u32 = 16;
const H: u32 = 12;
const SPP: u32 = 8;
const SEED: u64 = 5;

/// A camera at the origin looking along +z (16×12 pixels, focal length
/// 10 pixels), a sphere of radius 2 at (0.5, 0.3, 6) in front of a quad at
/// z = 8 over x in -30..-1.2, y in -30..30 (quad[0], object 1; sphere[0],
/// object 2), lit by a constant environment (`visible`).
fn two_objects(visible: bool) -> Scene {
    let text = format!(
        r#"
[camera]
position = [0.0, 0.0, 0.0]
forward = [0.0, 0.0, 1.0]
up = [0.0, -1.0, 0.0]
focal_length_px = 10.0
width = {W}
height = {H}

[integrator]
max_depth = 3

[environment]
color = [0.5, 0.75, 1.0]
visible = {visible}

[materials.paint]
reflectance = [0.5, 0.25, 1.0]

[[quad]]
material = "paint"
vertices = [[-30.0, -30.0, 8.0], [-1.2, -30.0, 8.0], [-1.2, 30.0, 8.0], [-30.0, 30.0, 8.0]]

[[sphere]]
center = [0.5, 0.3, 6.0]
radius = 2.0
material = "paint"
"#
    );
    wavetrace::scene::file::parse(&text, "two objects").unwrap()
}

const CENTRE: DVec3 = DVec3::new(0.5, 0.3, 6.0);

/// What the camera ray `(o, d)` hits, by this test's own `f64`
/// arithmetic: `Some(object id, forward distance)` or `None`, and whether
/// the answer is certain (the ray is not within 1e-6 of an edge).
fn brute(o: DVec3, d: DVec3) -> (Option<(u32, f64)>, bool) {
    // The sphere: |o + t d - c|² = r².
    let oc = o - CENTRE;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - 4.0);
    if disc.abs() < 1e-6 * 4.0 {
        return (None, false);
    }
    if disc > 0.0 {
        let t = -b - disc.sqrt();
        return (Some((2, t * d.z)), true);
    }
    // The quad's plane z = 8.
    let t = (8.0 - o.z) / d.z;
    let p = o + t * d;
    let certain = (p.x + 1.2).abs() > 1e-6 * 30.0;
    let inside = p.x > -30.0 && p.x < -1.2 && p.y.abs() < 30.0;
    (inside.then_some((1, t * d.z)), certain)
}

/// Per pixel: the brute-force hit count, per-object counts (ids 1 and 2),
/// the mean forward distance of the hits, and whether every sample was
/// certain; for samples `range` of the Sobol sampler of seed [`SEED`].
struct Truth {
    hits: Vec<u64>,
    objects: Vec<[u64; 3]>,
    zdepth: Vec<f64>,
    certain: Vec<bool>,
}

fn truth(scene: &Scene, range: std::ops::Range<u32>) -> Truth {
    let camera = scene.camera.for_resolution(W, H);
    let sampler = Sobol::new(SEED);
    let n = (W * H) as usize;
    let mut t = Truth {
        hits: vec![0; n],
        objects: vec![[0; 3]; n],
        zdepth: vec![0.0; n],
        certain: vec![true; n],
    };
    for y in 0..H {
        for x in 0..W {
            let i = (y * W + x) as usize;
            for sample in range.clone() {
                let mut path = sampler.start(camera.pixel_index(x, y), sample);
                let (o, d) = camera.pixel_ray(x, y, sampler.next_2d(&mut path));
                let (hit, certain) = brute(o.as_dvec3(), d.as_dvec3());
                t.certain[i] &= certain;
                if let Some((id, z)) = hit {
                    t.hits[i] += 1;
                    t.objects[i][id as usize] += 1;
                    t.zdepth[i] += z;
                }
            }
            if t.hits[i] > 0 {
                t.zdepth[i] /= t.hits[i] as f64;
            }
        }
    }
    t
}

fn settings(scene: &Scene, engine: Engine, aovs: AovSet) -> RenderSettings {
    let mut s = common::settings(scene, W, H, SPP);
    (s.engine, s.aovs, s.seed, s.sampler) = (engine, aovs, SEED, SamplerKind::Sobol);
    s
}

const NEW: [Aov; 3] = [Aov::Alpha, Aov::ZDepth, Aov::ObjectId];

fn image(film: &Film, aov: Aov) -> Vec<[f32; 3]> {
    film.aov_images()
        .into_iter()
        .find(|(a, _)| *a == aov)
        .unwrap()
        .1
}

/// Alpha, zdepth and object_id against the brute force, in both engines:
/// the alpha's hit counts exactly, the object id exactly (the majority,
/// misses voting for 0, ties to the smallest id), the zdepth to 1e-5.
/// Not vacuous: the image has pixels of every kind — empty, partly and
/// wholly covered, sphere, quad, and pixels where they meet.
#[test]
fn alpha_and_object_id_are_the_exact_counts_of_the_camera_rays_hits() {
    let scene = two_objects(false);
    assert_eq!(scene.objects.names, ["quad[0]", "sphere[0]"]);
    let truth = truth(&scene, 0..SPP);
    let uncertain = truth.certain.iter().filter(|c| !**c).count();
    assert!(uncertain <= 2, "{uncertain} pixels with an edge sample");
    let hits = &truth.hits;
    assert!(hits.contains(&0) && hits.contains(&(SPP as u64)));
    assert!(hits.iter().filter(|h| **h > 0 && **h < SPP as u64).count() > 10);
    let both = truth.objects.iter().filter(|o| o[1] > 0 && o[2] > 0);
    assert!(both.count() > 0, "no pixel sees both objects");
    for engine in [Engine::Wavefront, Engine::Reference] {
        let film = Renderer::new(&scene, &settings(&scene, engine, AovSet::of(&NEW)))
            .unwrap()
            .render()
            .0;
        let (alpha, ids) = (image(&film, Aov::Alpha), image(&film, Aov::ObjectId));
        let zdepth = image(&film, Aov::ZDepth);
        for i in 0..(W * H) as usize {
            if !truth.certain[i] {
                continue;
            }
            let what = format!("{engine:?} pixel ({}, {})", i as u32 % W, i as u32 / W);
            assert_eq!(film.aov.counts(Aov::Alpha)[i], hits[i], "{what}: hits");
            assert_eq!(alpha[i][0], (hits[i] as f64 / SPP as f64) as f32, "{what}");
            let o = truth.objects[i];
            let misses = SPP as u64 - hits[i];
            let want = [(0, misses), (1, o[1]), (2, o[2])]
                .into_iter()
                .fold(
                    (0, 0),
                    |best, (id, n)| if n > best.1 { (id, n) } else { best },
                )
                .0;
            assert_eq!(
                ids[i][0], want as f32,
                "{what}: object {o:?}, {misses} misses"
            );
            let counts: Vec<(u32, u64)> = [(1, o[1]), (2, o[2])]
                .into_iter()
                .filter(|c| c.1 > 0)
                .collect();
            assert_eq!(film.aov.votes(Aov::ObjectId)[i], counts, "{what}");
            if hits[i] == 0 {
                assert_eq!(zdepth[i][0], f32::INFINITY, "{what}");
            } else {
                let z = zdepth[i][0] as f64;
                assert!(
                    (z - truth.zdepth[i]).abs() < 1e-5 * truth.zdepth[i],
                    "{what}: zdepth {z}, expected {}",
                    truth.zdepth[i]
                );
            }
        }
    }
}

/// The zdepth of a plane facing the camera at z = 5 is 5 in every pixel
/// (to an ulp or two of `t · cos`), where the ray distance `depth` is
/// `5 / cos`; and the depth's bits are those of a render without zdepth.
#[test]
fn zdepth_of_a_plane_facing_the_camera_is_its_distance() {
    let text = r#"
[camera]
position = [0.0, 0.0, 0.0]
forward = [0.0, 0.0, 1.0]
up = [0.0, -1.0, 0.0]
focal_length_px = 8.0
width = 16
height = 12

[materials.paint]
reflectance = [0.5, 0.5, 0.5]

[[quad]]
material = "paint"
vertices = [[-100.0, -100.0, 5.0], [100.0, -100.0, 5.0], [100.0, 100.0, 5.0], [-100.0, 100.0, 5.0]]
"#;
    let scene = wavetrace::scene::file::parse(text, "plane").unwrap();
    for engine in [Engine::Wavefront, Engine::Reference] {
        let aovs = AovSet::of(&[Aov::Depth, Aov::ZDepth]);
        let film = Renderer::new(&scene, &settings(&scene, engine, aovs))
            .unwrap()
            .render()
            .0;
        let (z, depth) = (image(&film, Aov::ZDepth), image(&film, Aov::Depth));
        for (i, (z, d)) in z.iter().zip(&depth).enumerate() {
            assert!((z[0] - 5.0).abs() < 2e-6, "{engine:?} pixel {i}: {}", z[0]);
            // The corners' rays are at some 45°: depth is far from 5.
            if i == 0 {
                assert!(d[0] > 6.5, "{engine:?}: corner depth {}", d[0]);
            }
        }
        let alone = Renderer::new(&scene, &settings(&scene, engine, AovSet::of(&[Aov::Depth])))
            .unwrap()
            .render()
            .0;
        assert!(
            alone.aov.hit_means(Aov::Depth) == film.aov.hit_means(Aov::Depth),
            "{engine:?}"
        );
    }
}

fn assert_same(a: &Film, b: &Film, what: &str) {
    assert_eq!(a.ranges, b.ranges, "{what}");
    assert!(a.sums == b.sums, "{what}: radiance");
    assert!(
        a.aov.counts(Aov::Alpha) == b.aov.counts(Aov::Alpha),
        "{what}: alpha"
    );
    assert!(
        a.aov.hit_means(Aov::ZDepth) == b.aov.hit_means(Aov::ZDepth),
        "{what}: zdepth"
    );
    assert!(
        a.aov.votes(Aov::ObjectId) == b.aov.votes(Aov::ObjectId),
        "{what}: object_id"
    );
    assert_eq!(a, b, "{what}");
}

/// The same bits whatever the threads, batch sizes and kernel widths, in
/// passes out of order, through `.wtacc` round trips, and as shards
/// merged; and the wavefront engine's are the reference tracer's.
#[test]
fn the_new_aovs_are_the_same_bits_across_threads_batches_widths_passes_and_shards() {
    let dir = TempDir::new("alpha-bits");
    let scene = two_objects(false);
    let aovs = AovSet::of(&NEW);
    let at = |threads: usize, batch: usize, simd: SimdWidth| {
        let mut s = settings(&scene, Engine::Wavefront, aovs);
        (s.threads, s.batch_size, s.simd) = (threads, batch, simd);
        Renderer::new(&scene, &s).unwrap()
    };
    let one = at(1, 4096, SimdWidth::W8);
    let (whole, _, _) = one.render();
    let reference = Renderer::new(&scene, &settings(&scene, Engine::Reference, aovs))
        .unwrap()
        .render()
        .0;
    assert!(
        whole.aov.counts(Aov::Alpha) == reference.aov.counts(Aov::Alpha),
        "engines: alpha"
    );
    assert!(
        whole.aov.hit_means(Aov::ZDepth) == reference.aov.hit_means(Aov::ZDepth),
        "engines: zdepth"
    );
    assert!(
        whole.aov.votes(Aov::ObjectId) == reference.aov.votes(Aov::ObjectId),
        "engines: ids"
    );
    for simd in [SimdWidth::W8, SimdWidth::W16] {
        if !simd.is_available() {
            continue;
        }
        for (threads, batch) in [(2, 4096), (3, 77), (2, 8)] {
            let film = at(threads, batch, simd).render().0;
            assert_same(
                &whole,
                &film,
                &format!("{simd:?} {threads} threads, batch {batch}"),
            );
        }
    }
    // Passes out of order and a resume from a .wtacc file.
    let two = at(2, 50, SimdWidth::W8);
    let mut passes = two.new_film();
    two.render_samples(5..8, &mut passes);
    two.render_samples(0..2, &mut passes);
    let path = dir.join("part.wtacc");
    let hash = two.settings().image_hash(&scene);
    passes.save(&path, hash).unwrap();
    let (mut resumed, _) = Film::load(&path, Some(hash)).unwrap();
    assert_same(&passes, &resumed, "saved and loaded");
    two.render_samples(2..5, &mut resumed);
    assert_same(&whole, &resumed, "passes and a resume");
    // Shards, each saved, loaded and merged.
    let mut parts = Vec::new();
    for (i, range) in [(0u32, 0..3), (1, 3..8)] {
        let mut film = two.new_film();
        two.render_samples(range, &mut film);
        let meta = AccMeta {
            settings_hash: hash,
            spp: Some(SPP),
            shard: Some((i, 2)),
        };
        let p = dir.join(format!("shard{i}.wtacc"));
        film.save_with_meta(&p, &meta).unwrap();
        parts.push(p);
    }
    let merged = wavetrace::run::merge::merge_files(&parts, None, false).unwrap();
    assert_same(&whole, &merged.film, "merged shards");
}

/// The files: a PNG with alpha is RGBA, its colour the straight colour
/// (the premultiplied mean over alpha) and its alpha the coverage; an EXR
/// has `A` (the coverage) beside the premultiplied `R`, `G`, `B`, and
/// `zdepth.Z` and a `u32` `object_id.id`; beside a PNG the ids are a
/// 16-bit grey PNG. A render without them writes RGB, as before.
#[test]
fn alpha_makes_rgba_pngs_and_exrs_with_an_a_channel() {
    let dir = TempDir::new("alpha-files");
    let scene = two_objects(false);
    let film = Renderer::new(
        &scene,
        &settings(&scene, Engine::Wavefront, AovSet::of(&NEW)),
    )
    .unwrap()
    .render()
    .0;
    let (rgb, alpha) = (film.to_rgb(), image(&film, Aov::Alpha));
    let meta = AccMeta::new(0);
    let png = dir.join("a.png");
    write_output(&png, &film, &meta).unwrap();
    let decoded = image::open(&png).unwrap();
    assert_eq!(decoded.color(), image::ColorType::Rgba8);
    let rgba = decoded.to_rgba8();
    let mut partial = 0;
    for (i, p) in rgba.pixels().enumerate() {
        assert_eq!(p[3], (alpha[i][0] * 255.0).round() as u8, "pixel {i}");
        if alpha[i][0] > 0.0 {
            let straight = rgb[i][2] / alpha[i][0];
            let byte = (wavetrace::output::srgb_encode(straight.clamp(0.0, 1.0)) * 255.0).round();
            assert_eq!(p[2], byte as u8, "pixel {i}: straight colour");
            partial += usize::from(alpha[i][0] < 1.0);
        } else {
            assert_eq!(p.0, [0; 4], "pixel {i}");
        }
    }
    assert!(partial > 5);
    let ids = image::open(dir.join("a.object_id.png")).unwrap();
    assert_eq!(ids.color(), image::ColorType::L16);
    let want: Vec<u16> = image(&film, Aov::ObjectId)
        .iter()
        .map(|p| p[0] as u16)
        .collect();
    assert_eq!(ids.to_luma16().into_raw(), want);
    let z = read_image(&dir.join("a.zdepth.pfm")).unwrap();
    assert!(z.rgb == image(&film, Aov::ZDepth));
    assert!(!dir.join("a.alpha.pfm").exists(), "the PNG holds the alpha");

    let exr = dir.join("a.exr");
    write_output(&exr, &film, &meta).unwrap();
    let meta_data = exr::meta::MetaData::read_from_file(&exr, false).unwrap();
    let channels = &meta_data.headers[0].channels.list;
    let mut names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
    names.sort();
    assert_eq!(names, ["A", "B", "G", "R", "object_id.id", "zdepth.Z"]);
    let id = channels
        .iter()
        .find(|c| c.name.to_string() == "object_id.id");
    assert_eq!(
        id.unwrap().sample_type,
        exr::meta::attribute::SampleType::U32
    );
    assert!(read_image(&exr).unwrap().rgb == rgb, "premultiplied colour");
    let a = read_exr_layer(&exr, "", &["A"]).unwrap().unwrap();
    assert!(a == alpha);
    let (name, ch) = ZDEPTH_LAYER;
    assert!(read_exr_layer(&exr, name, ch).unwrap().unwrap() == image(&film, Aov::ZDepth));
    let (name, ch) = OBJECT_ID_LAYER;
    let read = read_exr_layer(&exr, name, ch).unwrap().unwrap();
    assert!(read == image(&film, Aov::ObjectId));
    // A PFM has no alpha: a file beside it.
    let pfm = dir.join("b.pfm");
    write_output(&pfm, &film, &meta).unwrap();
    assert!(read_image(&dir.join("b.alpha.pfm")).unwrap().rgb == alpha);

    // Without alpha: RGB.
    let plain = Renderer::new(&scene, &settings(&scene, Engine::Wavefront, AovSet::NONE))
        .unwrap()
        .render()
        .0;
    write_output(&png, &plain, &meta).unwrap();
    assert_eq!(image::open(&png).unwrap().color(), image::ColorType::Rgb8);
}

/// On the command line: `--transparent` hides a visible environment from
/// the camera (the background is black and transparent, the sphere still
/// lit by it) and writes RGBA; `visible = false` in the scene does the
/// same; without either, the background is the environment, opaque.
#[test]
fn transparent_renders_from_the_command_line() {
    let dir = TempDir::new("alpha-cli");
    for (name, visible) in [("visible.toml", true), ("hidden.toml", false)] {
        std::fs::write(dir.join(name), scene_text(visible)).unwrap();
    }
    let sizes = ["--width", "16", "--height", "12", "--spp", "4"];
    let render = |scene: &str, out: &str, extra: &[&str]| {
        let mut args = vec![scene, "-o", out];
        args.extend(sizes);
        args.extend(extra);
        run_ok(dir.path(), &args);
        image::open(dir.join(out)).unwrap()
    };
    let opaque = render("visible.toml", "opaque.png", &[]);
    assert_eq!(opaque.color(), image::ColorType::Rgb8);
    // The corner sees the environment.
    assert!(opaque.to_rgb8().get_pixel(0, 0)[2] > 200);
    for (scene, out, extra) in [
        ("visible.toml", "t.png", &["--transparent"][..]),
        ("hidden.toml", "h.png", &[][..]),
    ] {
        let img = render(scene, out, extra).to_rgba8();
        assert_eq!(img.get_pixel(0, 0).0, [0; 4], "{out}: corner");
        let centre = img.get_pixel(8, 6).0;
        assert_eq!(centre[3], 255, "{out}: centre");
        assert!(centre[0] > 20, "{out}: the sphere is lit: {centre:?}");
    }
    // The environment is hidden from the camera, not just masked: the
    // EXR's premultiplied colour is black where alpha is 0.
    run_ok(
        dir.path(),
        &[
            &["visible.toml", "-o", "t.exr", "--transparent"][..],
            &sizes[..],
        ]
        .concat(),
    );
    let rgb = read_image(&dir.join("t.exr")).unwrap().rgb;
    let a = read_exr_layer(&dir.join("t.exr"), "", &["A"])
        .unwrap()
        .unwrap();
    assert_eq!((rgb[0], a[0][0]), ([0.0; 3], 0.0), "corner");
    assert_eq!(a[6 * 16 + 8][0], 1.0, "centre");
}

fn scene_text(visible: bool) -> String {
    format!(
        r#"
[camera]
position = [0.0, 0.0, 0.0]
forward = [0.0, 0.0, 1.0]
up = [0.0, -1.0, 0.0]
focal_length_px = 10.0
width = 16
height = 12

[environment]
color = [0.9, 0.9, 0.9]
visible = {visible}

[materials.paint]
reflectance = [0.8, 0.8, 0.8]

[[sphere]]
center = [0.0, 0.0, 6.0]
radius = 2.0
material = "paint"
"#
    )
}

/// The legend of a shipped scene: its entries' names, in file order
/// (quads, then meshes), numbered from 1.
#[test]
fn object_ids_are_named_by_the_scene_files_entries() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/asset-sky.toml");
    let scene = Scene::load(&path).unwrap();
    let legend: Vec<(u32, &str)> = scene.objects.legend().collect();
    assert_eq!(
        legend,
        [
            (1, "ground"),
            (2, "gold_sphere"),
            (3, "clay_sphere"),
            (4, "crate")
        ]
    );
    assert_eq!(scene.objects.name(0), None);
    assert_eq!(scene.objects.name(4), Some("crate"));
    let prims = scene.triangles.len() + scene.spheres.len();
    assert_eq!(scene.objects.of_primitive.len(), prims);
}
