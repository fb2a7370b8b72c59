//! Smooth meshes: OBJ vertex normals (`vn`) parsed, checked, transformed and
//! interpolated as the shading normal; flat meshes unchanged.

mod common;

use common::TempDir;
use glam::Vec3;
use std::path::Path;
use wavetrace::scene::{Scene, SceneError, interpolate_normal};

const HEAD: &str = "[camera]\nposition = [0.0, 0.0, -3.0]\nforward = [0.0, 0.0, 1.0]\n\
                    up = [0.0, 1.0, 0.0]\nfocal_length_px = 16.0\nwidth = 16\nheight = 16\n\
                    [materials.white]\nreflectance = [0.5, 0.5, 0.5]\n";

fn load(d: &Path, obj: &str, extra: &str) -> Result<Scene, SceneError> {
    std::fs::write(d.join("m.obj"), obj).unwrap();
    let scene = format!("{HEAD}[[mesh]]\nfile = \"m.obj\"\nmaterial = \"white\"\n{extra}\n");
    let path = d.join("s.toml");
    std::fs::write(&path, scene).unwrap();
    Scene::load(&path)
}

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

#[test]
fn vn_parsed_from_v_slash_slash_vn_and_v_vt_vn() {
    let d = TempDir::new("vn");
    let obj = format!(
        "{TRI}vt 0 0\nvn 0 0 2\nvn 1 0 1\nvn 0 1 1\nf 1//1 2//2 3//3\nf 1/1/1 2/1/3 3/1/2\n"
    );
    let s = load(&d, &obj, "").unwrap();
    assert_eq!(s.triangles.len(), 2);
    let r = std::f32::consts::FRAC_1_SQRT_2;
    let n = s.vertex_normals[0];
    assert_eq!(n[0], Vec3::Z);
    assert!((n[1] - Vec3::new(r, 0.0, r)).length() < 1e-6);
    assert!((n[2] - Vec3::new(0.0, r, r)).length() < 1e-6);
    assert_eq!(s.vertex_normals[1][1], n[2]);
    assert_eq!(s.vertex_normals[1][2], n[1]);
}

#[test]
fn flat_meshes_have_no_vertex_normals_and_mixed_files_keep_flat_faces_flat() {
    let d = TempDir::new("flat");
    let s = load(&d, &format!("{TRI}f 1 2 3\n"), "").unwrap();
    assert!(s.vertex_normals.is_empty());
    let s = load(
        &d,
        &format!("{TRI}vn 0 0 1\nf 1 2 3\nf 1//1 2//1 3//1\n"),
        "",
    )
    .unwrap();
    assert_eq!(s.vertex_normals, vec![[Vec3::ZERO; 3], [Vec3::Z; 3]]);
    assert_eq!(s.shading_normal(0, Vec3::new(0.2, 0.2, 0.0)), None);
}

#[test]
fn bad_vertex_normals_are_refused_with_their_line() {
    let d = TempDir::new("badvn");
    for (obj, line, what) in [
        (
            format!("{TRI}vn 0 0 1\nf 1//1 2//2 3//1\n"),
            5,
            "past the 1 normal",
        ),
        (format!("{TRI}f 1//1 2//1 3//1\n"), 4, "past the 0 normal"),
        (format!("{TRI}vn 0 0 1\nf 1//1 2 3//1\n"), 5, "some corners"),
        (format!("{TRI}vn 0 0 1\nf 1//0 2//1 3//1\n"), 5, "index 0"),
        (
            format!("{TRI}vn 0 nan 1\nf 1//1 2//1 3//1\n"),
            4,
            "not finite",
        ),
        (
            format!("{TRI}vn 0 1\nf 1//1 2//1 3//1\n"),
            4,
            "three numbers",
        ),
    ] {
        let e = load(&d, &obj, "").unwrap_err();
        let mesh = e.mesh.as_ref().expect("a mesh error");
        assert_eq!(mesh.line, line, "{obj:?}: {e}");
        assert!(mesh.message.contains(what), "{obj:?}: {e}");
    }
}

#[test]
fn normals_follow_the_inverse_transpose_of_a_non_uniform_scale() {
    let d = TempDir::new("scale");
    // A slanted normal (1, 1, 0)/√2 scaled by (2, 1, 1): the inverse
    // transpose gives (1/2, 1, 0), normalised (the plain scale would give
    // (2, 1, 0), wrong: no longer perpendicular to the scaled surface).
    let obj = "v 0 0 0\nv 0 0 1\nv 1 -1 0\nvn 1 1 0\nf 1//1 2//1 3//1\n";
    let s = load(&d, obj, "scale = [2.0, 1.0, 1.0]").unwrap();
    let want = Vec3::new(0.5, 1.0, 0.0).normalize();
    for n in s.vertex_normals[0] {
        assert!((n - want).length() < 1e-6, "{n}");
        // Perpendicular to the transformed (flat) surface, as the normal
        // was to the original one.
        let t = s.triangles[0];
        assert!(n.dot(t.v[2] - t.v[0]).abs() < 1e-6);
        assert!(n.dot(t.v[1] - t.v[0]).abs() < 1e-6);
    }
}

#[test]
fn interpolation_gives_each_vertex_its_normal_and_blends_between() {
    let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let n = [
        Vec3::Z,
        Vec3::new(1.0, 0.0, 1.0).normalize(),
        Vec3::new(0.0, 1.0, 1.0).normalize(),
    ];
    for k in 0..3 {
        let got = interpolate_normal(v, n, Vec3::Z, v[k]);
        assert!((got - n[k]).length() < 1e-6, "vertex {k}: {got}");
    }
    let mid = interpolate_normal(v, n, Vec3::Z, Vec3::new(0.5, 0.0, 0.0));
    assert!((mid - (n[0] + n[1]).normalize()).length() < 1e-6);
    // Turned to the front side, whatever the vertex normals' orientation.
    let back = interpolate_normal(v, n.map(|x| -x), Vec3::Z, v[1]);
    assert!((back - n[1]).length() < 1e-6);
    // Degenerate sums fall back to the geometric normal.
    let z = interpolate_normal(
        v,
        [Vec3::X, -Vec3::X, Vec3::X],
        Vec3::Z,
        Vec3::new(0.5, 0.0, 0.0),
    );
    assert_eq!(z, Vec3::Z);
}

#[test]
fn flat_content_hash_unchanged_by_the_feature() {
    // A scene with vertex normals hashes differently from its flat copy;
    // the flat one's hash has no contribution from them (the pinned image
    // hashes of tests/determinism.rs and tests/sobol.rs cover the images).
    let d = TempDir::new("hash");
    let flat = load(&d, &format!("{TRI}vn 0 0 1\nf 1 2 3\n"), "").unwrap();
    let plain = load(&d, &format!("{TRI}f 1 2 3\n"), "").unwrap();
    assert_eq!(flat.content_hash(), plain.content_hash());
    let smooth = load(&d, &format!("{TRI}vn 0 0 1\nf 1//1 2//1 3//1\n"), "").unwrap();
    assert_ne!(smooth.content_hash(), plain.content_hash());
}
