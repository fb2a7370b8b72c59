//! Every way a scene file can be wrong gets an error that names the file, the
//! line and (where there is one) the field; and the built-in Cornell box is
//! exactly the shared `cornell-dh2323.json`.
//!
//! Each test breaks one line of a valid scene; the expected line number is
//! found in the broken text itself, so the tests say "the error points at the
//! line that is wrong", whatever the file looks like.

mod common;

use common::TempDir;
use glam::Vec3;
use wavetrace::scene::file::parse;
use wavetrace::scene::{Scene, SceneError};

const FILE: &str = "dir/test.toml";

const BASE: &str = r#"name = "t"
front_face = "counterclockwise"

[camera]
position = [0.0, 0.0, -3.0]
forward = [0.0, 0.0, 1.0]
up = [0.0, 1.0, 0.0]
focal_length_px = 64.0
width = 64
height = 48

[integrator]
max_depth = 3

[materials.white]
reflectance = [0.5, 0.5, 0.5]

[materials.lamp]
reflectance = [0.5, 0.5, 0.5]
emission = [1.0, 1.0, 1.0]

[[triangle]]
name = "t0"
material = "white"
vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]

[[quad]]
material = "lamp"
vertices = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]]
"#;

/// `BASE` with its one line `old` replaced by `new` (which may be several
/// lines, or empty to delete it).
fn with(old: &str, new: &str) -> String {
    replace_line(BASE, old, new)
}

fn replace_line(text: &str, old: &str, new: &str) -> String {
    assert_eq!(
        text.lines().filter(|l| *l == old).count(),
        1,
        "the test's scene must hold the line {old:?} exactly once"
    );
    text.lines()
        .map(|l| if l == old { new } else { l })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

/// The 1-based number of the one line of `text` that contains `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    let found: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.contains(needle))
        .map(|(i, _)| i + 1)
        .collect();
    assert_eq!(found.len(), 1, "{needle:?} must be on exactly one line");
    found[0]
}

fn error(text: &str) -> SceneError {
    match parse(text, FILE) {
        Ok(_) => panic!("this scene was accepted:\n{text}"),
        Err(e) => e,
    }
}

/// Parsing `text` fails at the line holding `needle`, naming `field`; the
/// message says `file:line:` and the field too.
fn assert_error(text: &str, needle: &str, field: Option<&str>) -> SceneError {
    let e = error(text);
    let line = line_of(text, needle);
    assert_eq!(e.file, FILE, "{e}");
    assert_eq!(e.line, line, "expected line {line} ({needle:?}): {e}");
    assert!(e.column >= 1, "{e}");
    let shown = e.to_string();
    assert!(
        shown.starts_with(&format!("{FILE}:{line}:")),
        "{shown:?} should start with {FILE}:{line}:"
    );
    if let Some(field) = field {
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
        assert!(shown.contains(field), "{shown:?} should name {field}");
    }
    assert!(!e.message.is_empty());
    assert!(
        !shown.contains('\n'),
        "the error should be one line: {shown:?}"
    );
    e
}

#[test]
fn the_base_scene_is_valid() {
    let s = parse(BASE, FILE).unwrap();
    assert_eq!(s.triangles.len(), 3);
    assert_eq!(s.materials.len(), 2);
    assert_eq!(s.max_depth, 3);
    assert_eq!((s.camera.width, s.camera.height), (64, 48));
}

#[test]
fn toml_syntax_error() {
    let text = with("width = 64", "width = = 64");
    assert_error(&text, "width = = 64", None);
    // An unclosed table header.
    let text = with("[materials.lamp]", "[materials.lamp");
    let e = assert_error(&text, "[materials.lamp", None);
    // There is no `key =` on that line: any field named must not be pieced
    // together from the lines after it.
    if let Some(field) = &e.field {
        assert!(!field.contains('[') && !field.contains('='), "{e:?}");
    }
}

#[test]
fn errors_after_a_multi_line_array_name_the_right_table() {
    let text = with("material = \"white\"", "").replace(
        "vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
        "vertices = [\n  [0.0, 0.0, 0.0],\n  [1.0, 0.0, 0.0],\n  [0.0, 1.0, 0.0],\n]\nmaterial = 5",
    );
    assert_error(&text, "material = 5", Some("triangle.material"));
}

#[test]
fn duplicate_key() {
    let text = with("max_depth = 3", "max_depth = 3\nmax_depth = 4");
    assert_error(&text, "max_depth = 4", None);
}

#[test]
fn unknown_key_at_top_level() {
    let text = with("name = \"t\"", "name = \"t\"\ncolour = \"red\"");
    let e = assert_error(&text, "colour", Some("colour"));
    assert!(e.message.contains("unknown field"), "{e}");
}

#[test]
fn unknown_key_in_camera() {
    let text = with("up = [0.0, 1.0, 0.0]", "up = [0.0, 1.0, 0.0]\nfov = 40.0");
    assert_error(&text, "fov =", Some("camera.fov"));
}

#[test]
fn unknown_key_in_a_material() {
    let text = with(
        "emission = [1.0, 1.0, 1.0]",
        "emission = [1.0, 1.0, 1.0]\nroughness = 0.5",
    );
    assert_error(&text, "roughness", Some("materials.lamp.roughness"));
}

#[test]
fn unknown_key_in_a_triangle() {
    let text = with("name = \"t0\"", "name = \"t0\"\ncolor = [1.0, 0.0, 0.0]");
    assert_error(&text, "color", Some("triangle.color"));
}

#[test]
fn unknown_table() {
    let text = with("[integrator]", "[integrater]");
    assert_error(&text, "[integrater]", Some("integrater"));
}

#[test]
fn wrong_type_names_the_field() {
    let text = BASE.replace(
        "[materials.white]\nreflectance = [0.5, 0.5, 0.5]",
        "[materials.x]\nreflectance = \"grey\"",
    );
    let text = text.replace("material = \"white\"", "material = \"x\"");
    assert_error(&text, "\"grey\"", Some("materials.x.reflectance"));
    let text = with("width = 64", "width = \"wide\"");
    assert_error(&text, "\"wide\"", Some("camera.width"));
    let text = with("width = 64", "width = -5");
    assert_error(&text, "-5", Some("camera.width"));
    let text = with(
        "vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
        "vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]",
    );
    let e = assert_error(&text, "vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]", None);
    assert!(e.field.as_deref().unwrap_or("").contains("vertices"), "{e}");
}

#[test]
fn missing_camera_field() {
    let text = with("height = 48", "");
    let e = error(&text);
    assert_eq!(e.file, FILE);
    assert!(e.message.contains("height"), "{e}");
    assert_eq!(e.field.as_deref(), Some("camera.height"), "{e}");
    // No line holds the missing key; the error points into the camera table.
    let (start, end) = (line_of(&text, "[camera]"), line_of(&text, "width = 64"));
    assert!(
        (start..=end + 1).contains(&e.line),
        "line {} is not in the camera table (lines {start}..={end}): {e}",
        e.line
    );
}

#[test]
fn missing_camera_table() {
    let text = BASE
        .lines()
        .filter(|l| {
            ![
                "[camera]", "position", "forward", "up =", "focal", "width", "height",
            ]
            .iter()
            .any(|k| l.starts_with(k))
        })
        .collect::<Vec<_>>()
        .join("\n");
    let e = error(&text);
    assert_eq!(e.file, FILE);
    assert!(e.to_string().contains("camera"), "{e}");
}

#[test]
fn undefined_material() {
    let text = with("material = \"white\"", "material = \"whyte\"");
    let e = assert_error(&text, "whyte", Some("triangle[0].material"));
    assert!(e.message.contains("whyte"), "{e}");
    let text = with("material = \"lamp\"", "material = \"lump\"");
    assert_error(&text, "lump", Some("quad[0].material"));
}

#[test]
fn reflectance_out_of_range() {
    let text = BASE.replacen(
        "reflectance = [0.5, 0.5, 0.5]",
        "reflectance = [0.5, 1.01, 0.5]",
        1,
    );
    assert_error(&text, "1.01", Some("materials.white.reflectance"));
    let text = BASE.replacen(
        "reflectance = [0.5, 0.5, 0.5]",
        "reflectance = [-0.01, 0.5, 0.5]",
        1,
    );
    assert_error(&text, "-0.01", Some("materials.white.reflectance"));
    // The ends of [0, 1] are allowed.
    let text = BASE.replacen(
        "reflectance = [0.5, 0.5, 0.5]",
        "reflectance = [0.0, 1.0, 0.0]",
        1,
    );
    parse(&text, FILE).unwrap();
}

#[test]
fn negative_emission() {
    let text = with("emission = [1.0, 1.0, 1.0]", "emission = [1.0, -0.5, 1.0]");
    assert_error(&text, "-0.5", Some("materials.lamp.emission"));
}

#[test]
fn non_finite_numbers() {
    let text = with(
        "vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
        "vertices = [[0.0, 0.0, 0.0], [nan, 0.0, 0.0], [0.0, 1.0, 0.0]]",
    );
    assert_error(&text, "nan", Some("triangle[0].vertices"));
    let text = with(
        "vertices = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]]",
        "vertices = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, inf, 1.0], [0.0, 1.0, 1.0]]",
    );
    assert_error(&text, "inf", Some("quad[0].vertices"));
    // A finite number too large for f32 becomes infinite: refused as well.
    let text = with(
        "vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
        "vertices = [[0.0, 0.0, 0.0], [1e39, 0.0, 0.0], [0.0, 1.0, 0.0]]",
    );
    assert_error(&text, "1e39", Some("triangle[0].vertices"));
    let text = with(
        "position = [0.0, 0.0, -3.0]",
        "position = [0.0, -inf, -3.0]",
    );
    assert_error(&text, "-inf", Some("camera.position"));
    let text = with("emission = [1.0, 1.0, 1.0]", "emission = [1.0, inf, 1.0]");
    assert_error(&text, "inf", Some("materials.lamp.emission"));
}

#[test]
fn zero_area_triangle() {
    let text = with(
        "vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
        "vertices = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]",
    );
    let e = assert_error(&text, "[2.0, 2.0, 2.0]", Some("triangle[0].vertices"));
    assert!(e.message.contains("zero area"), "{e}");
    // A quad with a repeated corner has a zero-area half.
    let text = with(
        "vertices = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]]",
        "vertices = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0]]",
    );
    assert_error(
        &text,
        "[1.0, 1.0, 1.0], [1.0, 1.0, 1.0]",
        Some("quad[0].vertices"),
    );
    // Three equal vertices.
    let text = with(
        "vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]",
        "vertices = [[0.5, 0.5, 0.5], [0.5, 0.5, 0.5], [0.5, 0.5, 0.5]]",
    );
    assert_error(&text, "[0.5, 0.5, 0.5], [0.5", Some("triangle[0].vertices"));
}

#[test]
fn both_forward_and_look_at() {
    let text = with(
        "forward = [0.0, 0.0, 1.0]",
        "forward = [0.0, 0.0, 1.0]\nlook_at = [0.0, 0.0, 0.0]",
    );
    let e = error(&text);
    assert_eq!(e.field.as_deref(), Some("camera"), "{e}");
    assert!(e.message.contains("forward") && e.message.contains("look_at"));
    // The error points at the camera table.
    let (start, end) = (line_of(&text, "[camera]"), line_of(&text, "height = 48"));
    assert!((start..=end).contains(&e.line), "line {}: {e}", e.line);
    // Neither is wrong too.
    let text = with("forward = [0.0, 0.0, 1.0]", "");
    let e = error(&text);
    assert_eq!(e.field.as_deref(), Some("camera"), "{e}");
    // look_at alone works, and means the direction towards it.
    let text = with("forward = [0.0, 0.0, 1.0]", "look_at = [0.0, 0.0, 5.0]");
    let s = parse(&text, FILE).unwrap();
    assert_eq!(s.camera.forward, Vec3::Z);
}

#[test]
fn focal_length_and_field_of_view() {
    // Both, or neither.
    let text = with(
        "focal_length_px = 64.0",
        "focal_length_px = 64.0\nvfov_deg = 40.0",
    );
    assert_eq!(error(&text).field.as_deref(), Some("camera"));
    let text = with("focal_length_px = 64.0", "");
    assert_eq!(error(&text).field.as_deref(), Some("camera"));
    // Out of range.
    let text = with("focal_length_px = 64.0", "focal_length_px = -64.0");
    assert_error(&text, "-64.0", Some("camera.focal_length_px"));
    let text = with("focal_length_px = 64.0", "focal_length_px = 0.0");
    assert_error(
        &text,
        "focal_length_px = 0.0",
        Some("camera.focal_length_px"),
    );
    for bad in ["0.0", "180.0", "-10.0", "nan"] {
        let text = with("focal_length_px = 64.0", &format!("vfov_deg = {bad}"));
        assert_error(&text, "vfov_deg", Some("camera.vfov_deg"));
    }
    // 90 degrees over 48 pixels: f = 24.
    let text = with("focal_length_px = 64.0", "vfov_deg = 90.0");
    let f = parse(&text, FILE).unwrap().camera.focal_length_px;
    assert!((f - 24.0).abs() < 1e-4, "{f}");
}

#[test]
fn up_parallel_to_forward() {
    for up in ["[0.0, 0.0, 2.0]", "[0.0, 0.0, -1.0]", "[0.0, 0.0, 0.0]"] {
        let text = with("up = [0.0, 1.0, 0.0]", &format!("up = {up}"));
        let e = assert_error(&text, "up =", Some("camera.up"));
        assert!(e.message.contains("parallel"), "{e}");
    }
    // A zero viewing direction (look_at the camera's own position).
    let text = with("forward = [0.0, 0.0, 1.0]", "look_at = [0.0, 0.0, -3.0]");
    error(&text);
}

#[test]
fn zero_width_or_height() {
    let text = with("width = 64", "width = 0");
    assert_error(&text, "width = 0", Some("camera.width"));
    let text = with("height = 48", "height = 0");
    assert_error(&text, "height = 0", Some("camera.height"));
}

#[test]
fn bad_front_face() {
    let text = with(
        "front_face = \"counterclockwise\"",
        "front_face = \"sideways\"",
    );
    let e = assert_error(&text, "sideways", Some("front_face"));
    assert!(e.message.contains("clockwise"), "{e}");
    // And the two allowed values flip the normal.
    let ccw = parse(BASE, FILE).unwrap();
    let cw = parse(
        &with(
            "front_face = \"counterclockwise\"",
            "front_face = \"clockwise\"",
        ),
        FILE,
    )
    .unwrap();
    assert_eq!(ccw.triangles[0].normal, Vec3::Z);
    assert_eq!(cw.triangles[0].normal, -Vec3::Z);
}

#[test]
fn no_geometry() {
    let text: String = BASE[..BASE.find("[[triangle]]").unwrap()].into();
    let e = error(&text);
    assert_eq!(e.file, FILE);
    assert!(e.message.contains("no geometry"), "{e}");
    assert!(e.to_string().starts_with(FILE), "{e}");
}

#[test]
fn zero_max_depth() {
    let text = with("max_depth = 3", "max_depth = 0");
    assert_error(&text, "max_depth = 0", Some("integrator.max_depth"));
    // And the default, when [integrator] is left out, is 3.
    let text = with("max_depth = 3", "").replace("[integrator]\n", "");
    assert_eq!(parse(&text, FILE).unwrap().max_depth, 3);
}

#[test]
fn unreadable_file() {
    let dir = TempDir::new("unreadable");
    let path = dir.join("no-such-dir/scene.toml");
    let e = Scene::load(&path).unwrap_err();
    assert_eq!(e.file, path.display().to_string());
    assert!(e.message.contains("cannot read"), "{e}");
    assert!(e.to_string().contains(&path.display().to_string()), "{e}");
}

#[test]
fn a_loaded_file_names_its_path_in_errors() {
    let dir = TempDir::new("loaded");
    let path = dir.join("bad.toml");
    let text = with("max_depth = 3", "max_depth = 0");
    std::fs::write(&path, &text).unwrap();
    let e = Scene::load(&path).unwrap_err();
    let line = line_of(&text, "max_depth = 0");
    assert!(
        e.to_string()
            .starts_with(&format!("{}:{line}:", path.display())),
        "{e}"
    );
}

// --- The built-in Cornell box is the shared JSON, number for number. ---

fn json_vec3(v: &serde_json::Value) -> Vec3 {
    let a: Vec<f32> = v
        .as_array()
        .expect("a JSON array")
        .iter()
        .map(|x| x.as_f64().expect("a number") as f32)
        .collect();
    assert_eq!(a.len(), 3);
    Vec3::from_slice(&a)
}

#[test]
fn the_built_in_cornell_box_is_the_shared_json_exactly() {
    // A copy of the project's shared/scenes/cornell-dh2323.json, kept in
    // the repository so that a fresh clone can run this test.
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/cornell-dh2323.json"
    );
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let scene = Scene::cornell();

    let cam = &json["camera"];
    assert_eq!(scene.camera.position, json_vec3(&cam["position"]));
    assert_eq!(scene.camera.forward, json_vec3(&cam["forward"]));
    assert_eq!(scene.camera.up, json_vec3(&cam["up"]));
    assert_eq!(scene.camera.right, json_vec3(&cam["right"]));
    assert_eq!(
        scene.camera.focal_length_px,
        cam["focal_length_px"].as_f64().unwrap() as f32
    );
    assert_eq!(scene.camera.width as u64, cam["width"].as_u64().unwrap());
    assert_eq!(scene.camera.height as u64, cam["height"].as_u64().unwrap());
    // focal length = image height: the vertical field of view agrees.
    let vfov =
        2.0 * (0.5 * scene.camera.height as f64 / scene.camera.focal_length_px as f64).atan();
    assert!((vfov.to_degrees() - cam["vfov_deg"].as_f64().unwrap()).abs() < 1e-9);
    assert_eq!(
        scene.max_depth as u64,
        json["integrator"]["max_depth"].as_u64().unwrap()
    );

    let tris = json["triangles"].as_array().unwrap();
    assert_eq!(scene.triangles.len(), tris.len());
    for (i, (t, j)) in scene.triangles.iter().zip(tris).enumerate() {
        let name = j["name"].as_str().unwrap_or("?");
        let v = [
            json_vec3(&j["v0"]),
            json_vec3(&j["v1"]),
            json_vec3(&j["v2"]),
        ];
        assert_eq!(t.v, v, "triangle {i} ({name}): vertices");
        let m = &scene.materials[t.material as usize];
        assert_eq!(
            m.reflectance,
            json_vec3(&j["reflectance"]),
            "triangle {i} ({name}): reflectance"
        );
        assert_eq!(
            m.emission,
            json_vec3(&j["emission"]),
            "triangle {i} ({name}): emission"
        );
        let n = json_vec3(&j["normal"]);
        assert!(
            (t.normal - n).abs().max_element() <= 1e-6,
            "triangle {i} ({name}): normal {} vs the JSON's {n}",
            t.normal
        );
    }
    // The light: two triangles of radiance 10, facing down into the room
    // (+y in the lab's y-down frame).
    let lights: Vec<_> = scene
        .triangles
        .iter()
        .filter(|t| scene.materials[t.material as usize].is_emissive())
        .collect();
    assert_eq!(lights.len(), 2);
    for t in lights {
        assert_eq!(t.normal, Vec3::Y);
    }
}
