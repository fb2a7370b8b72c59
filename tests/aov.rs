//! Auxiliary outputs (issue 15, part 1): albedo, normal, depth and variance,
//! accumulated exactly beside the radiance by both engines.
//!
//! - the same bits whatever the threads, batch sizes, sample passes,
//!   `.wtacc` round trips, shards and merges;
//! - the wavefront engine's albedo, normal and depth are the reference
//!   tracer's, bit for bit, on every shipped scene (the variance follows
//!   the radiance, a few ulps apart between the engines);
//! - oracles: the variance of per-sample images computed by hand, depths,
//!   albedos and normals of scenes whose answers are known, through a
//!   mirror and up to the maximum depth;
//! - files: `.wtacc` version 2 and version 1, an unknown version refused,
//!   multi-layer EXR and PFM side files, the command line.

mod common;

use common::{TempDir, run_ok, run_refused};
use wavetrace::film::{AccMeta, FIXED_POINT_SCALE, Film};
use wavetrace::output::{
    ALBEDO_LAYER, DEPTH_LAYER, NORMAL_LAYER, VARIANCE_LAYER, read_exr_layer, read_image,
    write_output,
};
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::{Aov, AovSet, Scene};

fn scene_file(name: &str) -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    Scene::load(&path).unwrap()
}

fn bits(v: &[[f32; 3]]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.map(f32::to_bits)).collect()
}

/// The image of `aov` in `film`.
fn image(film: &Film, aov: Aov) -> Vec<[f32; 3]> {
    film.aov_images()
        .into_iter()
        .find(|(a, _)| *a == aov)
        .unwrap_or_else(|| panic!("no {aov:?} image"))
        .1
}

fn settings(scene: &Scene, engine: Engine, aovs: AovSet) -> RenderSettings {
    let mut s = common::settings(scene, 24, 18, 8);
    (s.engine, s.aovs, s.seed) = (engine, aovs, 3);
    s
}

/// Films equal in everything, AOV sums included.
fn assert_same_film(a: &Film, b: &Film, what: &str) {
    assert_eq!(a.ranges, b.ranges, "{what}");
    assert_eq!(a.aovs(), b.aovs(), "{what}");
    assert!(a.sums == b.sums, "{what}: radiance sums differ");
    assert!(
        a.aov.means(Aov::Albedo) == b.aov.means(Aov::Albedo),
        "{what}: albedo sums differ"
    );
    assert!(
        a.aov.means(Aov::Normal) == b.aov.means(Aov::Normal),
        "{what}: normal sums differ"
    );
    assert!(
        a.aov.hit_means(Aov::Depth) == b.aov.hit_means(Aov::Depth),
        "{what}: depth sums differ"
    );
    assert!(
        a.aov.squares(Aov::Variance) == b.aov.squares(Aov::Variance),
        "{what}: squares differ"
    );
    assert_eq!(a, b, "{what}");
}

/// Every AOV is the same bits whatever the thread count, the batch size,
/// the split of the samples into passes (in any order), or a round trip
/// through an accumulation file; in both engines, on a scene with a
/// mirror and a glass sphere (paths followed through them) and one of
/// every material model.
#[test]
fn aovs_are_the_same_bits_across_threads_batches_passes_and_resumes() {
    let dir = TempDir::new("resume");
    for name in ["cornell-spheres.toml", "cornell-materials.toml"] {
        let scene = scene_file(name);
        for engine in [Engine::Wavefront, Engine::Reference] {
            let what = format!("{name} {engine:?}");
            let at = |threads: usize, batch: usize| {
                let mut s = settings(&scene, engine, AovSet::ALL);
                (s.threads, s.batch_size) = (threads, batch);
                Renderer::new(&scene, &s).unwrap()
            };
            let one = at(1, 4096);
            let mut whole = one.new_film();
            one.render_samples(0..8, &mut whole);
            // Not vacuous: every AOV has non-zero sums.
            assert!(
                whole.aov.means(Aov::Albedo).iter().any(|s| s[0] > 0),
                "{what}"
            );
            assert!(
                whole.aov.means(Aov::Normal).iter().any(|s| s[2] != 0),
                "{what}"
            );
            assert!(
                whole.aov.hit_means(Aov::Depth).iter().any(|d| d.hits > 0),
                "{what}"
            );
            assert!(
                whole.aov.squares(Aov::Variance).iter().any(|s| s[0] > 0),
                "{what}"
            );
            for threads in [2, 3] {
                let (film, _, _) = at(threads, 4096).render();
                assert_same_film(&whole, &film, &format!("{what}: {threads} threads"));
            }
            // Passes out of order, odd batch sizes, a .wtacc round trip.
            let two = at(2, 77);
            let mut passes = two.new_film();
            two.render_samples(5..8, &mut passes);
            two.render_samples(0..2, &mut passes);
            let path = dir.join("part.wtacc");
            let hash = two.settings().image_hash(&scene);
            passes.save(&path, hash).unwrap();
            let (mut resumed, _) = Film::load(&path, Some(hash)).unwrap();
            assert_same_film(&passes, &resumed, &format!("{what}: saved vs loaded"));
            at(3, 100).render_samples(2..5, &mut resumed);
            assert_same_film(&whole, &resumed, &format!("{what}: passes and a resume"));
            // A pass that may be stopped part-way (its own accumulator).
            let mut stoppable = one.new_film();
            one.render_samples(0..3, &mut stoppable);
            one.render_samples_or_stop(3..8, &mut stoppable, &|| false)
                .unwrap();
            assert_same_film(&whole, &stoppable, &format!("{what}: stoppable pass"));
        }
    }
}

/// Shards' partial files merge into the AOVs of one run, bit for bit; a
/// part with other AOVs is refused, naming the file and both sets.
#[test]
fn merged_shards_have_the_aovs_of_one_run() {
    use wavetrace::run::merge::merge_files;
    let dir = TempDir::new("merge");
    let scene = scene_file("cornell-spheres.toml");
    for engine in [Engine::Wavefront, Engine::Reference] {
        let s = settings(&scene, engine, AovSet::ALL);
        let renderer = Renderer::new(&scene, &s).unwrap();
        let (whole, _, _) = renderer.render();
        let hash = s.image_hash(&scene);
        let mut parts = Vec::new();
        for (i, range) in [(0, 0..3), (1, 3..8)] {
            let mut film = renderer.new_film();
            renderer.render_samples(range, &mut film);
            let meta = AccMeta {
                settings_hash: hash,
                spp: Some(8),
                shard: Some((i, 2)),
            };
            let path = dir.join(format!("part{i}.wtacc"));
            film.save_with_meta(&path, &meta).unwrap();
            parts.push(path);
        }
        parts.reverse();
        let merged = merge_files(&parts, None, false).unwrap();
        assert_same_film(&whole, &merged.film, &format!("{engine:?}: merged"));

        // A part of other AOVs.
        let mut s2 = s.clone();
        s2.aovs = AovSet::DENOISE;
        let other = Renderer::new(&scene, &s2).unwrap();
        let mut film = other.new_film();
        other.render_samples(3..8, &mut film);
        let odd = dir.join("odd.wtacc");
        film.save_with_meta(
            &odd,
            &AccMeta {
                settings_hash: hash,
                spp: Some(8),
                shard: Some((1, 2)),
            },
        )
        .unwrap();
        let e = merge_files(&[parts[1].clone(), odd], None, false)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("odd.wtacc")
                && e.contains("holds AOVs albedo,normal, expected albedo,normal,depth,variance"),
            "{e}"
        );
    }
}

/// Every shipped scene: the wavefront engine's albedo, normal and depth
/// sums are the reference tracer's, bit for bit (the same camera rays,
/// hits, specular directions and arithmetic); its sums of squared radiance
/// within 1e-4 relative (the radiance itself differs by a few ulps: the
/// engines add a path's terms in different orders).
#[test]
fn wavefront_aovs_equal_the_reference_tracers_on_every_scene() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        // scenes/views-*.toml are `wavetrace views` jobs, not scenes.
        .filter(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("views-"))
        })
        .collect();
    names.sort();
    assert!(names.len() >= 6, "{names:?}");
    let mut checked = Vec::new();
    for path in names {
        let scene = Scene::load(&path).unwrap();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let big = scene.triangles.len() > 10_000;
        let film = |engine| {
            let mut s = settings(&scene, engine, AovSet::ALL);
            if big {
                (s.width, s.height, s.spp) = (12, 9, 2);
            }
            Renderer::new(&scene, &s).unwrap().render().0
        };
        let (w, r) = (film(Engine::Wavefront), film(Engine::Reference));
        assert!(
            w.aov.means(Aov::Albedo) == r.aov.means(Aov::Albedo),
            "{name}: albedo differs"
        );
        assert!(
            w.aov.means(Aov::Normal) == r.aov.means(Aov::Normal),
            "{name}: normal differs"
        );
        assert!(
            w.aov.hit_means(Aov::Depth) == r.aov.hit_means(Aov::Depth),
            "{name}: depth differs"
        );
        assert!(
            w.aov.means(Aov::Albedo).iter().any(|s| s[1] > 0),
            "{name}: no albedo"
        );
        for (i, (a, b)) in w
            .aov
            .squares(Aov::Variance)
            .iter()
            .zip(r.aov.squares(Aov::Variance))
            .enumerate()
        {
            for c in 0..3 {
                let (x, y) = (a[c] as f64, b[c] as f64);
                assert!(
                    (x - y).abs() <= 1e-4 * x.max(y) + 64.0,
                    "{name}: pixel {i} channel {c}: squares {x} vs {y}"
                );
            }
        }
        checked.push(name);
    }
    for must in [
        "cornell-spheres.toml",
        "smooth-mesh.toml",
        "cornell-materials.toml",
    ] {
        assert!(checked.iter().any(|n| n == must), "{must} not checked");
    }
}

/// The variance AOV is the unbiased sample variance of the pixel's
/// radiance samples: checked against each sample rendered alone (samples
/// k..k+1 as separate films): the sums of squares exactly, and the image
/// against the textbook two-pass formula in f64.
#[test]
fn variance_equals_the_variance_of_per_sample_images() {
    let scene = Scene::cornell();
    for engine in [Engine::Wavefront, Engine::Reference] {
        let n = 8u32;
        let s = settings(&scene, engine, AovSet::of(&[Aov::Variance]));
        let renderer = Renderer::new(&scene, &s).unwrap();
        let (film, _, _) = renderer.render();
        let mut plain = s.clone();
        plain.aovs = AovSet::NONE;
        let plain = Renderer::new(&scene, &plain).unwrap();
        let singles: Vec<Film> = (0..n)
            .map(|k| {
                let mut f = plain.new_film();
                plain.render_samples(k..k + 1, &mut f);
                f
            })
            .collect();
        let variance = image(&film, Aov::Variance);
        let mut varied = 0;
        for (p, v) in variance.iter().enumerate() {
            for (c, &got) in v.iter().enumerate() {
                // Each sample's fixed-point value, as its film holds it.
                let q: Vec<u128> = singles.iter().map(|f| f.sums[p][c]).collect();
                let squares: u128 = q.iter().map(|&q| (q * q + (1 << 31)) >> 32).sum();
                assert_eq!(
                    film.aov.squares(Aov::Variance)[p][c],
                    squares,
                    "pixel {p} channel {c}"
                );
                assert_eq!(film.sums[p][c], q.iter().sum::<u128>());
                let x: Vec<f64> = q.iter().map(|&q| q as f64 / FIXED_POINT_SCALE).collect();
                let mean = x.iter().sum::<f64>() / n as f64;
                let want = x.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1) as f64;
                let got = got as f64;
                assert!(
                    (got - want).abs() <= 1e-6 * want + 1e-9 * (1.0 + mean * mean),
                    "{engine:?}: pixel {p} channel {c}: variance {got}, by hand {want}"
                );
                varied += (want > 1e-3) as usize;
            }
        }
        assert!(
            varied > variance.len() / 2,
            "only {varied} noisy pixel channels"
        );
        // One sample has no variance.
        let mut one = renderer.new_film();
        renderer.render_samples(0..1, &mut one);
        assert!(
            image(&one, Aov::Variance)
                .iter()
                .flatten()
                .all(|v| *v == 0.0)
        );
    }
}

/// A camera at the origin looking along +z (16×12 pixels, focal length
/// `f` pixels) at the scene's quads.
fn scene_of(f: f32, max_depth: u32, quads: &str) -> Scene {
    let text = format!(
        r#"
[camera]
position = [0.0, 0.0, 0.0]
forward = [0.0, 0.0, 1.0]
up = [0.0, -1.0, 0.0]
focal_length_px = {f:?}
width = 16
height = 12

[integrator]
max_depth = {max_depth}

[materials.paint]
reflectance = [0.5, 0.25, 1.0]

[materials.red]
reflectance = [0.75, 0.125, 0.0625]

[materials.mirror]
model = "mirror"
reflectance = [0.9, 0.9, 0.9]

{quads}
"#
    );
    wavetrace::scene::file::parse(&text, "test scene").unwrap()
}

/// A quad of `material` in the plane z = `z`, over x in `x0..x1` and y in
/// -100..100.
fn quad(material: &str, z: f32, (x0, x1): (f32, f32)) -> String {
    format!(
        "[[quad]]\nmaterial = \"{material}\"\nvertices = [[{x0:?}, -100.0, {z:?}], [{x1:?}, -100.0, {z:?}], [{x1:?}, 100.0, {z:?}], [{x0:?}, 100.0, {z:?}]]\n"
    )
}

fn render_aovs(scene: &Scene, engine: Engine) -> Film {
    let mut s = common::settings(scene, 16, 12, 6);
    (s.engine, s.aovs) = (engine, AovSet::ALL);
    Renderer::new(scene, &s).unwrap().render().0
}

/// Depth, albedo and normal where the answers are known: a plane at z = 5
/// over the left half of the view (its edge through the middle of pixel
/// column 8), nothing on the right. The depth of a pixel is the mean of
/// `5 / d_z` over its camera rays that hit, so it lies between that of the
/// pixel's point nearest the image centre and that of its farthest corner;
/// pixels that see nothing are +inf. The albedo is the plane's
/// reflectance, the normal faces the camera (both times the fraction of
/// the samples that hit).
#[test]
fn depth_albedo_and_normal_of_a_plane_at_a_known_distance() {
    let f = 40.0f32;
    // The edge x = 5 · 0.5 / f: the image-plane column u = 8.5.
    let scene = scene_of(f, 3, &quad("paint", 5.0, (-100.0, 2.5 / f)));
    for engine in [Engine::Wavefront, Engine::Reference] {
        let film = render_aovs(&scene, engine);
        let depth = image(&film, Aov::Depth);
        let albedo = image(&film, Aov::Albedo);
        let normal = image(&film, Aov::Normal);
        let t = |u: f32, v: f32| {
            let (a, b) = (u as f64 - 8.0, v as f64 - 6.0);
            5.0 * (a * a + b * b + (f as f64).powi(2)).sqrt() / f as f64
        };
        for y in 0..12u32 {
            for x in 0..16u32 {
                let i = (y * 16 + x) as usize;
                let z = depth[i][0] as f64;
                assert_eq!(depth[i][0], depth[i][2]);
                let hits = film.aov.hit_means(Aov::Depth)[i].hits;
                if x <= 8 {
                    // Nearest point of [x, x+1] × [y, y+1] to (8, 6).
                    let near = t(
                        (8.0f32).clamp(x as f32, x as f32 + 1.0),
                        (6.0f32).clamp(y as f32, y as f32 + 1.0),
                    );
                    let far = [(0, 0), (0, 1), (1, 0), (1, 1)]
                        .map(|(dx, dy)| t((x + dx) as f32, (y + dy) as f32))
                        .into_iter()
                        .fold(0.0, f64::max);
                    assert!(
                        near * (1.0 - 1e-6) <= z && z <= far * (1.0 + 1e-6),
                        "{engine:?} ({x}, {y}): depth {z} outside {near}..{far}"
                    );
                    let seen = hits as f32 / 6.0;
                    assert_eq!(hits == 6, x < 8, "{engine:?} ({x}, {y}): {hits} hits");
                    assert!(hits > 0, "{engine:?} ({x}, {y})");
                    let close =
                        |a: [f32; 3], b: [f32; 3]| (0..3).all(|c| (a[c] - b[c]).abs() < 1e-6);
                    assert!(
                        close(albedo[i], [0.5 * seen, 0.25 * seen, seen]),
                        "{engine:?} ({x}, {y})"
                    );
                    assert!(close(normal[i], [0.0, 0.0, -seen]), "{engine:?} ({x}, {y})");
                } else {
                    assert_eq!(hits, 0);
                    assert_eq!(z, f64::INFINITY, "{engine:?} ({x}, {y}) sees nothing");
                    assert_eq!(albedo[i], [0.0; 3]);
                    assert_eq!(normal[i], [0.0; 3]);
                }
            }
        }
        // Column 8 is cut by the edge: some of its samples hit, some not.
        let partial = (0..12)
            .filter(|y| film.aov.hit_means(Aov::Depth)[y * 16 + 8].hits < 6)
            .count();
        assert!(partial > 0, "{engine:?}: column 8 all hit");
    }
}

/// Through a mirror: a mirror at z = 5 facing the camera reflects the
/// rays back to a red plane at z = -5 (behind the camera). The albedo and
/// normal are the red plane's (facing the reflected ray: +z), the depth is
/// the mirror's. With a maximum depth of 1 the mirror is the path's only
/// vertex: no non-specular vertex, so albedo and normal are zero.
#[test]
fn albedo_and_normal_are_found_through_a_mirror_within_the_maximum_depth() {
    let quads = quad("mirror", 5.0, (-100.0, 100.0)) + &quad("red", -5.0, (-100.0, 100.0));
    for (max_depth, seen) in [(3, true), (1, false)] {
        let scene = scene_of(40.0, max_depth, &quads);
        for engine in [Engine::Wavefront, Engine::Reference] {
            let film = render_aovs(&scene, engine);
            let (albedo, normal) = (image(&film, Aov::Albedo), image(&film, Aov::Normal));
            let depth = image(&film, Aov::Depth);
            for i in 0..albedo.len() {
                let what = format!("{engine:?} max depth {max_depth} pixel {i}");
                if seen {
                    assert_eq!(albedo[i], [0.75, 0.125, 0.0625], "{what}");
                    assert_eq!(normal[i], [0.0, 0.0, 1.0], "{what}");
                } else {
                    assert_eq!((albedo[i], normal[i]), ([0.0; 3], [0.0; 3]), "{what}");
                }
                assert!((5.0..5.2).contains(&depth[i][0]), "{what}: {:?}", depth[i]);
            }
        }
    }
}

/// An image output with AOVs: an EXR holds them as layers named
/// `albedo.R/G/B`, `normal.X/Y/Z`, `depth.Z`, `variance.R/G/B` beside
/// `R`, `G`, `B` (and nothing else), which read back bit for bit; a PNG
/// or PFM gets `STEM.NAME.pfm` files beside it, bit for bit too.
#[test]
fn outputs_carry_the_aovs_as_exr_layers_or_pfm_files() {
    let dir = TempDir::new("outputs");
    let scene = Scene::cornell();
    let film = Renderer::new(&scene, &settings(&scene, Engine::Wavefront, AovSet::ALL))
        .unwrap()
        .render()
        .0;
    let meta = AccMeta::new(0);
    let exr = dir.join("a.exr");
    write_output(&exr, &film, &meta).unwrap();
    let meta_data = exr::meta::MetaData::read_from_file(&exr, false).unwrap();
    let mut names: Vec<String> = meta_data.headers[0]
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "B",
            "G",
            "R",
            "albedo.B",
            "albedo.G",
            "albedo.R",
            "depth.Z",
            "normal.X",
            "normal.Y",
            "normal.Z",
            "variance.B",
            "variance.G",
            "variance.R"
        ]
    );
    assert_eq!(bits(&read_image(&exr).unwrap().rgb), bits(&film.to_rgb()));
    let layers = [
        (Aov::Albedo, ALBEDO_LAYER),
        (Aov::Normal, NORMAL_LAYER),
        (Aov::Depth, DEPTH_LAYER),
        (Aov::Variance, VARIANCE_LAYER),
    ];
    for (aov, (name, channels)) in layers {
        let read = read_exr_layer(&exr, name, channels).unwrap().unwrap();
        assert_eq!(bits(&read), bits(&image(&film, aov)), "{name}");
    }
    // Some pixels see nothing: their depth is +inf in the file too.
    assert!(
        image(&film, Aov::Depth)
            .iter()
            .any(|d| d[0] == f32::INFINITY)
    );

    for ext in ["png", "pfm"] {
        let out = dir.join(format!("b.{ext}"));
        write_output(&out, &film, &meta).unwrap();
        for aov in Aov::ALL {
            let side = dir.join(format!("b.{}.pfm", aov.name()));
            let read = read_image(&side).unwrap();
            assert_eq!(
                bits(&read.rgb),
                bits(&image(&film, aov)),
                "{}",
                side.display()
            );
        }
    }
    // Without AOVs, only the image.
    let plain = Renderer::new(&scene, &settings(&scene, Engine::Wavefront, AovSet::NONE))
        .unwrap()
        .render()
        .0;
    write_output(&dir.join("c.png"), &plain, &meta).unwrap();
    let mut files = dir.files();
    files.retain(|f| f.starts_with("c."));
    assert_eq!(files, ["c.png"]);
}

/// The bytes of a version 1 accumulation file of `film` (no AOVs), laid
/// out by hand as the format was before AOVs existed.
fn version_1_bytes(film: &Film, hash: u128) -> Vec<u8> {
    let ranges: Vec<String> = film
        .ranges
        .iter()
        .map(|r| format!("[{},{}]", r.start, r.end))
        .collect();
    let header = format!(
        r#"{{"format":"wavetrace-accumulation/1","width":{},"height":{},"settings_hash":"{hash:032x}","ranges":[{}],"invalid_samples":{}}}"#,
        film.width,
        film.height,
        ranges.join(","),
        film.invalid_samples
    );
    let mut bytes = b"WTACC\0\0\x01".to_vec();
    bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for s in &film.sums {
        for c in s {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let check = xxhash_rust::xxh3::xxh3_128(&bytes);
    bytes.extend_from_slice(&check.to_le_bytes());
    bytes
}

/// Replace a file's version byte and checksum.
fn with_version(bytes: &[u8], version: u8) -> Vec<u8> {
    let mut b = bytes[..bytes.len() - 16].to_vec();
    b[7] = version;
    let check = xxhash_rust::xxh3::xxh3_128(&b);
    b.extend_from_slice(&check.to_le_bytes());
    b
}

/// A version 1 file (as wavetrace wrote before AOVs) loads as a film
/// without AOVs, and a film without AOVs is still saved as exactly those
/// bytes; a film with AOVs is saved as version 2 and loads back whole; a
/// file of an unknown (newer) version is refused, saying so.
#[test]
fn accumulation_file_versions() {
    let dir = TempDir::new("versions");
    let scene = Scene::cornell();
    let s = settings(&scene, Engine::Wavefront, AovSet::NONE);
    let hash = s.image_hash(&scene);
    let renderer = Renderer::new(&scene, &s).unwrap();
    let mut plain = renderer.new_film();
    renderer.render_samples(2..5, &mut plain);
    let old = dir.join("old.wtacc");
    std::fs::write(&old, version_1_bytes(&plain, hash)).unwrap();
    let (loaded, h) = Film::load(&old, Some(hash)).unwrap();
    assert_eq!((h, loaded.aovs()), (hash, AovSet::NONE));
    assert_eq!(loaded, plain);
    let again = dir.join("again.wtacc");
    plain.save(&again, hash).unwrap();
    assert!(std::fs::read(&again).unwrap() == std::fs::read(&old).unwrap());

    // Version 2: the AOVs in the header and after the sums.
    let mut s2 = s.clone();
    s2.aovs = AovSet::of(&[Aov::Normal, Aov::Depth]);
    let r2 = Renderer::new(&scene, &s2).unwrap();
    let mut with = r2.new_film();
    r2.render_samples(0..4, &mut with);
    let v2 = dir.join("v2.wtacc");
    with.save(&v2, hash).unwrap();
    let bytes = std::fs::read(&v2).unwrap();
    assert_eq!(&bytes[..8], b"WTACC\0\0\x02");
    let text = String::from_utf8_lossy(&bytes);
    assert!(text.contains(r#""format":"wavetrace-accumulation/2""#));
    assert!(text.contains(r#""aov":["normal","depth"]"#), "{text:.300}");
    assert_eq!(Film::load(&v2, Some(hash)).unwrap().0, with);

    // An unknown version, even with a valid checksum, is refused by name.
    for version in [0, 3, 255] {
        let path = dir.join(format!("v{version}.wtacc"));
        std::fs::write(&path, with_version(&bytes, version)).unwrap();
        let e = Film::load(&path, None).unwrap_err().to_string();
        assert!(
            e.contains(&format!("version {version}")) && e.contains("reads versions 1 to 2"),
            "{e}"
        );
    }
    // Forged AOV sums, checksum and all, are refused: a depth hit count
    // above the samples held (the last 24 bytes of data: the last pixel's
    // depth), and a normal sum beyond what unit normals can make.
    let data_end = bytes.len() - 16;
    let pixels = (with.width * with.height) as usize;
    let forge = |at: usize, value: &[u8]| {
        let mut b = bytes[..data_end].to_vec();
        b[at..at + value.len()].copy_from_slice(value);
        let check = xxhash_rust::xxh3::xxh3_128(&b);
        b.extend_from_slice(&check.to_le_bytes());
        std::fs::write(&v2, &b).unwrap();
        Film::load(&v2, None).unwrap_err().to_string()
    };
    let e = forge(data_end - 8, &5u64.to_le_bytes());
    assert!(
        e.contains("holds a depth sum larger than its 4 sample(s)"),
        "{e}"
    );
    let normal_start = data_end - pixels * (48 + 24);
    let e = forge(normal_start, &(-(5i128 << 32)).to_le_bytes());
    assert!(e.contains("pixel (0, 0) holds a normal sum larger"), "{e}");
    std::fs::write(&v2, &bytes).unwrap();
    assert_eq!(Film::load(&v2, None).unwrap().0, with);
    // A version 2 header on version 1 data, and a truncated AOV plane.
    std::fs::write(&old, with_version(&version_1_bytes(&plain, hash), 2)).unwrap();
    assert!(Film::load(&old, None).is_err());
    let mut cut = bytes[..bytes.len() - 16 - 24].to_vec();
    let check = xxhash_rust::xxh3::xxh3_128(&cut);
    cut.extend_from_slice(&check.to_le_bytes());
    std::fs::write(&v2, &cut).unwrap();
    let e = Film::load(&v2, None).unwrap_err().to_string();
    assert!(
        e.contains("bytes of sums") && e.contains("normal,depth"),
        "{e}"
    );
}

/// The command line: `--aov` (an unknown name refused, naming it), the
/// files a PNG `--out` gets, shards and `merge` giving the single run's
/// EXR byte for byte, and a resume with other AOVs refused before any
/// work, naming both sets.
#[test]
fn the_command_line_renders_merges_and_resumes_aovs() {
    let dir = TempDir::new("cli");
    let small = [
        "--width", "16", "--height", "12", "--spp", "4", "--seed", "5",
    ];
    fn with<'a>(small: &[&'a str], extra: &[&'a str]) -> Vec<&'a str> {
        [small, extra].concat()
    }
    let e = run_refused(
        &dir,
        &with(&small, &["--aov", "albedo,z-depth", "--out", "x.png"]),
    );
    assert!(e.contains("z-depth") && e.contains("variance"), "{e}");

    run_ok(
        &dir,
        &with(&small, &["--aov", "depth,albedo", "--out", "a.png"]),
    );
    let mut files = dir.files();
    files.retain(|f| f.starts_with("a."));
    assert_eq!(files, ["a.albedo.pfm", "a.depth.pfm", "a.png"]);

    let all = ["--aov", "albedo,normal,depth,variance"];
    run_ok(
        &dir,
        &with(&small, &[&all[..], &["--out", "single.exr"]].concat()),
    );
    for i in 0..2 {
        let shard = format!("{i}/2");
        let part = format!("p{i}.wtacc");
        run_ok(
            &dir,
            &with(
                &small,
                &[&all[..], &["--shard", &shard, "--partial", &part]].concat(),
            ),
        );
    }
    run_ok(
        &dir,
        &["merge", "p1.wtacc", "p0.wtacc", "--out", "merged.exr"],
    );
    let (a, b) = (dir.join("single.exr"), dir.join("merged.exr"));
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());
    assert!(
        read_exr_layer(&a, "variance", &["R", "G", "B"])
            .unwrap()
            .is_some()
    );

    // A checkpoint of depth only, resumed asking for albedo: refused, and
    // the checkpoint is left as it was.
    run_ok(
        &dir,
        &with(
            &small,
            &[
                "--aov",
                "depth",
                "--checkpoint",
                "ck.wtacc",
                "--out",
                "ck.png",
            ],
        ),
    );
    let before = std::fs::read(dir.join("ck.wtacc")).unwrap();
    let mut more = with(
        &small,
        &["--aov", "albedo", "--resume", "ck.wtacc", "--out", "ck.png"],
    );
    more[5] = "8";
    let e = run_refused(&dir, &more);
    assert!(
        e.contains("ck.wtacc")
            && e.contains("holds the AOVs depth")
            && e.contains("asks for albedo"),
        "{e}"
    );
    assert!(std::fs::read(dir.join("ck.wtacc")).unwrap() == before);
    // With the same AOVs it continues.
    more[9] = "depth";
    run_ok(&dir, &more);
    assert_eq!(common::spp_of(&dir.join("ck.wtacc")), 8);
}

/// A scene file's `[integrator] aov` and a profile's `aov` ask for AOVs as
/// `--aov` does (the flag wins over the profile, the profile over the
/// scene); an unknown name is refused, naming it.
#[test]
fn scene_files_and_profiles_name_aovs() {
    let text = |aov: &str| {
        format!(
            "[camera]\nposition = [0.0, 0.0, 0.0]\nforward = [0.0, 0.0, 1.0]\nup = [0.0, -1.0, 0.0]\nfocal_length_px = 8.0\nwidth = 8\nheight = 6\n\n[integrator]\naov = {aov}\n\n[materials.paint]\nreflectance = [0.5, 0.5, 0.5]\n\n{}",
            quad("paint", 5.0, (-100.0, 100.0))
        )
    };
    let parse = |aov: &str| wavetrace::scene::file::parse(&text(aov), "s.toml");
    let scene = parse(r#"["depth", "albedo"]"#).unwrap();
    let s = RenderSettings::for_scene(&scene);
    assert_eq!(s.aovs, AovSet::of(&[Aov::Albedo, Aov::Depth]));
    let e = parse(r#"["depth", "bogus"]"#).unwrap_err().to_string();
    assert!(
        e.contains("integrator.aov") && e.contains("\"bogus\""),
        "{e}"
    );

    let dir = TempDir::new("profiles");
    std::fs::write(dir.join("s.toml"), text(r#"["depth"]"#)).unwrap();
    std::fs::write(dir.join("p.toml"), "spp = 2\naov = [\"variance\"]\n").unwrap();
    std::fs::write(dir.join("bad.toml"), "aov = [\"albedo\", \"nope\"]\n").unwrap();
    run_ok(&dir, &["s.toml", "--spp", "2", "--out", "scene.png"]);
    run_ok(
        &dir,
        &["s.toml", "--profile", "p.toml", "--out", "profile.png"],
    );
    run_ok(
        &dir,
        &[
            "s.toml",
            "--profile",
            "p.toml",
            "--aov",
            "normal",
            "--out",
            "flag.png",
        ],
    );
    let e = run_refused(&dir, &["s.toml", "--profile", "bad.toml", "--out", "x.png"]);
    assert!(e.contains("\"nope\""), "{e}");
    let mut files = dir.files();
    files.retain(|f| f.ends_with(".pfm"));
    assert_eq!(
        files,
        ["flag.normal.pfm", "profile.variance.pfm", "scene.depth.pfm"]
    );
}
