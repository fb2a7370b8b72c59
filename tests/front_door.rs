//! What a new user meets first: a file of another format given as the
//! scene, a scene whose light reaches nothing, the help, the short flags
//! and the PNG view transform.

mod common;

use common::{TempDir, run, run_ok, run_refused, stderr};

/// A floor and a square light above it; `light` lists the light's corners.
fn floor_and_light(light: &str) -> String {
    format!(
        "[camera]\nposition = [0.0, 1.5, -4.0]\nlook_at = [0.0, 0.5, 0.0]\nup = [0.0, 1.0, 0.0]\n\
         vfov_deg = 40.0\nwidth = 32\nheight = 24\n\
         [materials.grey]\nreflectance = [0.7, 0.7, 0.7]\n\
         [materials.lamp]\nreflectance = [0.0, 0.0, 0.0]\nemission = [30.0, 30.0, 30.0]\n\
         [[quad]]\nmaterial = \"grey\"\n\
         vertices = [[-3.0, 0.0, -3.0], [-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0]]\n\
         [[quad]]\nmaterial = \"lamp\"\nvertices = {light}\n"
    )
}
const DOWN: &str = "[[-0.5, 3.0, -0.5], [0.5, 3.0, -0.5], [0.5, 3.0, 0.5], [-0.5, 3.0, 0.5]]";
const UP: &str = "[[-0.5, 3.0, 0.5], [0.5, 3.0, 0.5], [0.5, 3.0, -0.5], [-0.5, 3.0, -0.5]]";

#[test]
fn a_scene_of_another_format_is_named_not_parsed() {
    let dir = TempDir::new("foreign");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(root.join("scenes/meshes/crate.obj"), dir.join("crate.obj")).unwrap();
    std::fs::write(dir.join("m.ply"), "ply\nformat ascii 1.0\nend_header\n").unwrap();
    std::fs::write(dir.join("s.gltf"), "{\"asset\": {\"version\": \"2.0\"}}").unwrap();
    std::fs::write(dir.join("s.glb"), b"glTF\x02\0\0\0").unwrap();
    std::fs::write(dir.join("s.pbrt"), "LookAt 0 0 5 0 0 0 0 1 0\nWorldBegin\n").unwrap();
    std::fs::write(dir.join("s.xml"), "<scene version=\"3.0.0\">\n</scene>\n").unwrap();
    std::fs::write(dir.join("s.blend"), b"BLENDER-v402REND").unwrap();
    // glTF, GLB and PLY files are assets wavetrace renders: these empty
    // ones are refused by their loaders, saying why.
    for (file, why) in [
        ("m.ply", "m.ply: the asset has no triangles to render"),
        ("s.gltf", "s.gltf: the asset has no triangles to render"),
        ("s.glb", "s.glb: not a valid glTF 2.0 file"),
    ] {
        let err = run_refused(&dir, &[file]);
        assert!(err.contains(why), "{file}: {err}");
    }
    for (file, what) in [
        ("crate.obj", "a Wavefront OBJ mesh"),
        ("s.pbrt", "a pbrt scene"),
        ("s.xml", "a Mitsuba scene"),
        ("s.blend", "a Blender"),
    ] {
        for command in [
            &[file][..],
            &["converge", file, "--spp", "1", "--reference-spp", "1"][..],
        ] {
            let err = run_refused(&dir, command);
            assert!(
                err.starts_with(&format!(
                    "error: {file} is {what} file; wavetrace reads TOML scenes"
                )),
                "{command:?}: {err}"
            );
            assert!(!err.contains("expected"), "a parser's error: {err}");
        }
    }
    // Nothing was written.
    assert!(!dir.join("crate.png").exists());
}

#[test]
fn a_light_that_faces_nothing_is_warned_about_before_and_after() {
    let dir = TempDir::new("light");
    std::fs::write(dir.join("up.toml"), floor_and_light(UP)).unwrap();
    std::fs::write(dir.join("down.toml"), floor_and_light(DOWN)).unwrap();
    let up = run_ok(&dir, &["up.toml", "--spp", "2", "--quiet"]);
    let err = stderr(&up);
    let before = err.find("warning: no light faces any surface").expect(&err);
    let after = err
        .find("warning: the image is entirely black")
        .expect(&err);
    assert!(before < after, "{err}");
    assert!(dir.join("up.png").is_file(), "the render still runs");
    // --check says it too.
    let check = run_ok(&dir, &["up.toml", "--check"]);
    assert!(stderr(&check).contains("no light faces any surface"));
    // The same light the right way round: no warning.
    let down = run_ok(&dir, &["down.toml", "--spp", "2", "--quiet"]);
    assert!(!stderr(&down).contains("warning"), "{}", stderr(&down));

    // No light at all.
    let dark = floor_and_light(DOWN).replace("[30.0, 30.0, 30.0]", "[0.0, 0.0, 0.0]");
    std::fs::write(dir.join("dark.toml"), dark).unwrap();
    let o = run(&dir, &["dark.toml", "--spp", "1", "--quiet"]);
    assert!(o.status.success());
    let err = stderr(&o);
    assert!(err.contains("warning: the scene has no light"), "{err}");
    assert!(
        err.contains("warning: the image is entirely black"),
        "{err}"
    );
}

#[test]
fn help_is_grouped_with_short_flags_and_examples_that_run() {
    let dir = TempDir::new("help");
    for command in [&["--help"][..], &["render", "--help"][..]] {
        let o = run_ok(&dir, command);
        let help = String::from_utf8_lossy(&o.stdout).into_owned();
        let mut at = 0;
        for heading in [
            "\nOutput:\n",
            "\nQuality:\n",
            "\nTime:\n",
            "\nFarm:\n",
            "\nTuning:\n",
            "\nEXAMPLES:\n",
        ] {
            let found = help[at..]
                .find(heading)
                .unwrap_or_else(|| panic!("{heading:?} (in order) in {command:?}:\n{help}"));
            at += found;
        }
        for flag in ["-o, --out", "-s, --spp", "-t, --threads", "-q, --quiet"] {
            assert!(help.contains(flag), "{flag} in\n{help}");
        }
        // Each flag is described on its one line.
        let spp = help.lines().find(|l| l.contains("--spp")).unwrap();
        assert!(spp.contains("Samples per pixel"), "{spp}");
    }
    // Every render example of `--help` is a valid command line.
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(root.join("scenes/cornell.toml"), dir.join("scene.toml")).unwrap();
    let help = String::from_utf8_lossy(&run_ok(&dir, &["--help"]).stdout).into_owned();
    let examples = &help[help.find("EXAMPLES:").unwrap()..];
    let mut checked = 0;
    for line in examples.lines() {
        let Some(command) = line.trim_start().strip_prefix("wavetrace") else {
            continue;
        };
        let words: Vec<&str> = command
            .split("  ")
            .next()
            .unwrap()
            .split_whitespace()
            .collect();
        if words
            .first()
            .is_some_and(|w| ["bench", "merge"].contains(w))
        {
            continue;
        }
        let mut args = words.clone();
        args.push("--check");
        let o = run(&dir, &args);
        assert!(o.status.success(), "{line}: {}", stderr(&o));
        checked += 1;
    }
    assert!(checked >= 5, "{checked} examples checked");
}

#[test]
fn short_flags_are_the_long_ones() {
    let dir = TempDir::new("short");
    let size = ["--width", "16", "--height", "12"];
    run_ok(
        &dir,
        &[&size[..], &["-s", "3", "-t", "1", "-o", "a.pfm", "-q"]].concat(),
    );
    run_ok(
        &dir,
        &[
            &size[..],
            &["--spp", "3", "--threads", "2", "--out", "b.pfm"],
        ]
        .concat(),
    );
    let a = std::fs::read(dir.join("a.pfm")).unwrap();
    assert_eq!(a, std::fs::read(dir.join("b.pfm")).unwrap());
}

#[test]
fn png_exposure_and_view_shape_pngs_only() {
    use wavetrace::output::read_image;
    use wavetrace::output::view::{View, ViewTransform};
    let dir = TempDir::new("view");
    let size = ["--width", "24", "--height", "16", "-s", "4"];
    fn with<'a>(size: &[&'a str], extra: &[&'a str]) -> Vec<&'a str> {
        [size, extra].concat()
    }
    let with = |extra: &[&'static str]| with(&size, extra);
    run_ok(&dir, &with(&["-o", "linear.pfm"]));
    let linear = read_image(&dir.join("linear.pfm")).unwrap().rgb;
    let png = |name: &str| image::open(dir.join(name)).unwrap().to_rgb8().into_raw();
    let cases = [
        (vec![], ViewTransform::default()),
        (
            vec!["--view", "agx"],
            ViewTransform {
                exposure: 0.0,
                view: View::Agx,
            },
        ),
        (
            vec!["--exposure", "-1.5", "--view", "standard"],
            ViewTransform {
                exposure: -1.5,
                view: View::Standard,
            },
        ),
        (
            vec!["--exposure", "2", "--view", "agx"],
            ViewTransform {
                exposure: 2.0,
                view: View::Agx,
            },
        ),
    ];
    let mut seen = Vec::new();
    for (i, (flags, view)) in cases.iter().enumerate() {
        let name = format!("v{i}.png");
        let mut args: Vec<&str> = size.to_vec();
        args.extend(["-o", name.as_str()]);
        args.extend(flags.iter().copied());
        run_ok(&dir, &args);
        let bytes = png(&name);
        assert_eq!(bytes, view.bytes(&linear), "{flags:?}");
        assert!(!seen.contains(&bytes), "{flags:?} changed nothing");
        seen.push(bytes);
    }
    // EXR and PFM stay linear: the flags are refused for them.
    for out in ["x.exr", "x.pfm", "x.wtacc"] {
        let err = run_refused(&dir, &with(&["-o", out, "--view", "agx"]));
        assert!(err.contains("PNG images only"), "{err}");
        assert!(!dir.join(out).exists());
    }
    // merge takes them too.
    run_ok(&dir, &with(&["--shard", "0/1", "--partial", "p.wtacc"]));
    run_ok(
        &dir,
        &[
            "merge",
            "p.wtacc",
            "-o",
            "m.png",
            "--view",
            "agx",
            "--exposure",
            "2",
        ],
    );
    assert_eq!(png("m.png"), png("v3.png"));
}

#[test]
fn no_help_line_gives_two_defaults() {
    let dir = TempDir::new("defaults");
    for command in ["render", "merge", "bench", "converge", "denoise"] {
        let o = run_ok(&dir, &[command, "--help"]);
        let help = String::from_utf8_lossy(&o.stdout).into_owned();
        for line in help.lines() {
            assert!(
                line.matches("[default:").count() <= 1,
                "`{command} --help`: {line}"
            );
        }
    }
}
