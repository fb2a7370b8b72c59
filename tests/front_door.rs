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
    for (file, what) in [
        ("crate.obj", "a Wavefront OBJ mesh"),
        ("m.ply", "a PLY mesh"),
        ("s.gltf", "a glTF"),
        ("s.glb", "a glTF"),
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
