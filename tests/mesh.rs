//! Meshes in scene files: OBJ loading (polygons, negative indices, missing
//! normals, MTL materials), transforms, generated meshes, and an error that
//! names the file and the line for every way a mesh file can be bad.

mod common;

use common::TempDir;
use glam::Vec3;
use std::path::Path;
use wavetrace::integrator::Counters;
use wavetrace::integrator::nee::Estimator;
use wavetrace::integrator::reference::ReferenceTracer;
use wavetrace::integrator::sampler::Independent;
use wavetrace::scene::{Integrator, Scene, SceneError};

const HEADER: &str = r#"
[camera]
position = [0.0, 0.0, -5.0]
forward = [0.0, 0.0, 1.0]
up = [0.0, 1.0, 0.0]
vfov_deg = 40.0
width = 16
height = 16

[materials.white]
reflectance = [0.5, 0.5, 0.5]
"#;

/// Write `files` into `d`, then a scene `scene.toml` with `body` after the
/// header, and load it.
fn load(d: &Path, files: &[(&str, &str)], body: &str) -> Result<Scene, SceneError> {
    for (name, text) in files {
        std::fs::write(d.join(name), text).unwrap();
    }
    let path = d.join("scene.toml");
    std::fs::write(&path, format!("{HEADER}\n{body}")).unwrap();
    Scene::load(&path)
}

fn mesh(file: &str, extra: &str) -> String {
    format!("[[mesh]]\nfile = \"{file}\"\n{extra}\n")
}

#[test]
fn quads_and_polygons_are_fan_triangulated() {
    let d = TempDir::new("fan");
    let obj = "# a quad and a pentagon\n\
               v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
               v 2 0 0\nv 3 0 0\nv 3.5 1 0\nv 2.5 2 0\nv 1.5 1 0\n\
               f 1 2 3 4\nf 5 6 7 8 9\n";
    let s = load(
        &d,
        &[("m.obj", obj)],
        &mesh("m.obj", "material = \"white\""),
    )
    .unwrap();
    assert_eq!(s.triangles.len(), 2 + 3);
    let v = |x: f32, y: f32| Vec3::new(x, y, 0.0);
    // Fans from each polygon's first vertex, in order.
    assert_eq!(s.triangles[0].v, [v(0., 0.), v(1., 0.), v(1., 1.)]);
    assert_eq!(s.triangles[1].v, [v(0., 0.), v(1., 1.), v(0., 1.)]);
    assert_eq!(s.triangles[2].v, [v(2., 0.), v(3., 0.), v(3.5, 1.)]);
    assert_eq!(s.triangles[4].v, [v(2., 0.), v(2.5, 2.), v(1.5, 1.)]);
    // Counter-clockwise seen from +z: the front faces +z.
    assert!(s.triangles.iter().all(|t| t.normal == Vec3::Z));
}

#[test]
fn negative_indices_and_missing_normals() {
    let d = TempDir::new("neg");
    // Relative indices, texture coordinates without normals, v//vn without
    // texture coordinates, and a vertex with a w component.
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0 1.0\nf -3 -2 -1\n\
               vt 0 0\nvt 1 0\nvt 0 1\n\
               v 0 0 1\nv 1 0 1\nv 0 1 1\nf 4/1 5/2 6/3\n\
               vn 0 0 1\nf 1//1 2//1 3//1\n";
    let s = load(
        &d,
        &[("m.obj", obj)],
        &mesh("m.obj", "material = \"white\""),
    )
    .unwrap();
    assert_eq!(s.triangles.len(), 3);
    assert_eq!(s.triangles[0].v[2], Vec3::Y);
    assert_eq!(s.triangles[1].v[0], Vec3::Z);
    assert_eq!(s.triangles[2].v, s.triangles[0].v);
}

#[test]
fn mtl_materials_and_fallback() {
    let d = TempDir::new("mtl");
    let mtl = "newmtl red\nKd 0.8 0.1 0.1\n\nnewmtl lamp\nKd 1 1 1\nKe 5 4 3\n";
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
               f 1 2 3\nusemtl red\nf 2 4 3\nusemtl lamp\nf 1 3 2\n";
    let files = [("m.mtl", mtl), ("m.obj", obj)];
    // The first face has no usemtl: without a fallback that is an error.
    let e = load(&d, &files, &mesh("m.obj", "mtl = true")).unwrap_err();
    assert!(e.message.contains("no material"), "{e}");
    let s = load(
        &d,
        &files,
        &mesh("m.obj", "mtl = true\nmaterial = \"white\""),
    )
    .unwrap();
    assert_eq!(s.triangles.len(), 3);
    let mat = |i: usize| &s.materials[s.triangles[i].material as usize];
    assert_eq!(mat(0).name, "white");
    assert_eq!(mat(1).name, "m.obj:red");
    assert_eq!(mat(1).reflectance, Vec3::new(0.8, 0.1, 0.1));
    assert_eq!(mat(2).emission, Vec3::new(5.0, 4.0, 3.0));
    // Without `mtl = true` the MTL is not even read.
    let s = load(&d, &[], &mesh("m.obj", "material = \"white\"")).unwrap();
    assert!(s.triangles.iter().all(|t| t.material == 0));
}

#[test]
fn transforms_scale_rotate_translate() {
    let d = TempDir::new("xf");
    let obj = "v 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n";
    let body = mesh(
        "m.obj",
        "material = \"white\"\nscale = 2.0\nrotate_deg = [0.0, 0.0, 90.0]\ntranslate = [10.0, 0.0, 0.0]",
    );
    let s = load(&d, &[("m.obj", obj)], &body).unwrap();
    let t = s.triangles[0];
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
    // (1,0,0) -> scale 2 -> rotate 90° about z -> (0,2,0) -> + (10,0,0).
    assert!(close(t.v[0], Vec3::new(10.0, 2.0, 0.0)), "{:?}", t.v);
    assert!(close(t.v[1], Vec3::new(8.0, 0.0, 0.0)), "{:?}", t.v);
    assert!(close(t.v[2], Vec3::new(10.0, 0.0, 2.0)), "{:?}", t.v);
    // A mirror keeps the front on the same side of the surface.
    let plain = load(&d, &[], &mesh("m.obj", "material = \"white\"")).unwrap();
    let mirrored = load(
        &d,
        &[],
        &mesh("m.obj", "material = \"white\"\nscale = [-1.0, 1.0, 1.0]"),
    )
    .unwrap();
    let n0 = plain.triangles[0].normal;
    let n1 = mirrored.triangles[0].normal;
    assert!((n1 - Vec3::new(-n0.x, n0.y, n0.z)).length() < 1e-6);
}

#[test]
fn generated_meshes() {
    let d = TempDir::new("gen");
    let body = "[[generate]]\nkind = \"sphere\"\ntriangles = 5000\nmaterial = \"white\"\n\
                center = [0.0, 1.0, 0.0]\nradius = 0.5\n\n\
                [[generate]]\nkind = \"terrain\"\ntriangles = 2000\nmaterial = \"white\"\n\
                size = [4.0, 4.0]\nheight = 0.5\nseed = 3\n";
    let s = load(&d, &[], body).unwrap();
    assert_eq!(
        s.triangles.len(),
        wavetrace::scene::mesh::sphere_triangle_count(5000)
            + wavetrace::scene::mesh::terrain_triangle_count(2000)
    );
}

/// Load `obj` (and `mtl`) and return the error, checking its file and line.
fn obj_error(test: &str, obj: &str, mtl: Option<&str>, file: &str, line: usize) -> SceneError {
    let d = TempDir::new(test);
    let mut files = vec![("m.obj", obj)];
    if let Some(m) = mtl {
        files.push(("m.mtl", m));
    }
    let extra = if mtl.is_some() {
        "mtl = true\nmaterial = \"white\""
    } else {
        "material = \"white\""
    };
    let e = load(&d, &files, &mesh("m.obj", extra)).unwrap_err();
    assert!(e.file.ends_with(file), "{e}");
    assert_eq!(e.line, line, "{e}");
    // The message says which scene entry loaded the mesh.
    assert!(
        e.message.contains("mesh[0]") && e.message.contains("scene.toml"),
        "{e}"
    );
    e
}

#[test]
fn errors_name_the_file_and_line() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let e = obj_error("e1", &format!("{tri}f 1 2 4\n"), None, "m.obj", 4);
    assert!(e.message.contains("index 4"), "{e}");
    let e = obj_error("e2", &format!("{tri}f -4 -2 -1\n"), None, "m.obj", 4);
    assert!(e.message.contains("-4"), "{e}");
    let e = obj_error("e3", &format!("{tri}f 0 1 2\n"), None, "m.obj", 4);
    assert!(e.message.contains("index 0"), "{e}");
    let e = obj_error(
        "e4",
        "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
        None,
        "m.obj",
        2,
    );
    assert!(e.message.contains("not finite"), "{e}");
    let e = obj_error(
        "e5",
        "v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n",
        None,
        "m.obj",
        3,
    );
    assert!(e.message.contains("not finite"), "{e}");
    let e = obj_error("e6", "v 0 0 0\nv 1 x 0\n", None, "m.obj", 2);
    assert!(e.message.contains("not a number"), "{e}");
    obj_error("e7", "v 0 0\n", None, "m.obj", 1);
    obj_error("e8", &format!("{tri}f 1 2 a\n"), None, "m.obj", 4);
    obj_error(
        "e9",
        &format!("{tri}vt 0 0\nf 1/2 2/1 3/1\n"),
        None,
        "m.obj",
        5,
    );
    let e = obj_error(
        "e10",
        &format!("mtllib m.mtl\n{tri}f 1 2 3\n"),
        Some("newmtl a\nKd 0.5 0.5\n"),
        "m.mtl",
        2,
    );
    assert!(e.message.contains("Kd"), "{e}");
    obj_error(
        "e11",
        &format!("mtllib m.mtl\n{tri}f 1 2 3\n"),
        Some("newmtl a\n\nKd 2 0 0\n"),
        "m.mtl",
        3,
    );
    // Not UTF-8 is not an error (exporters write Latin-1 names): the bytes
    // are decoded lossily, and a bad number on such a line is still named.
    let d = TempDir::new("e12");
    std::fs::write(d.join("m.obj"), b"v 0 0 0\n\xff\xfe\nv 1 0 \xe9\n").unwrap();
    let e = load(&d, &[], &mesh("m.obj", "material = \"white\"")).unwrap_err();
    assert_eq!(e.line, 3, "{e}");
    std::fs::write(
        d.join("m.obj"),
        b"# Mod\xe8le\no Bo\xeete\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let s = load(&d, &[], &mesh("m.obj", "material = \"white\"")).unwrap();
    assert!(!s.triangles.is_empty());
}

#[test]
fn missing_and_unreadable_files() {
    let d = TempDir::new("missing");
    let e = load(&d, &[], &mesh("nope.obj", "material = \"white\"")).unwrap_err();
    assert!(
        e.file.ends_with("nope.obj") && e.message.contains("cannot read"),
        "{e}"
    );
    // A directory where the file should be.
    std::fs::create_dir_all(d.join("dir.obj")).unwrap();
    let e = load(&d, &[], &mesh("dir.obj", "material = \"white\"")).unwrap_err();
    assert!(
        e.file.ends_with("dir.obj") && e.message.contains("cannot read"),
        "{e}"
    );
    // A missing MTL when its materials are asked for.
    let obj = "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let e = load(
        &d,
        &[("m.obj", obj)],
        &mesh("m.obj", "mtl = true\nmaterial = \"white\""),
    )
    .unwrap_err();
    assert!(e.file.ends_with("gone.mtl"), "{e}");
    // A mesh with neither `material` nor `mtl`.
    let e = load(&d, &[], &mesh("m.obj", "")).unwrap_err();
    assert!(e.message.contains("give a `material`"), "{e}");
    assert!(e.line > 0);
}

#[test]
fn bad_generate_entries() {
    let d = TempDir::new("badgen");
    for (body, what) in [
        ("kind = \"cube\"\ntriangles = 10", "generate[0].kind"),
        ("kind = \"sphere\"\ntriangles = 0", "generate[0].triangles"),
        (
            "kind = \"sphere\"\ntriangles = 100000000000",
            "generate[0].triangles",
        ),
        (
            "kind = \"sphere\"\ntriangles = 10\nradius = -1.0",
            "generate[0].radius",
        ),
        (
            "kind = \"sphere\"\ntriangles = 10\nsize = [1.0, 1.0]",
            "generate[0].size",
        ),
        (
            "kind = \"terrain\"\ntriangles = 10\nsize = [0.0, 1.0]",
            "generate[0].size",
        ),
        (
            "kind = \"sphere\"\ntriangles = 10\nscale = 0.0",
            "generate[0].scale",
        ),
    ] {
        let e = load(
            &d,
            &[],
            &format!("[[generate]]\nmaterial = \"white\"\n{body}\n"),
        )
        .unwrap_err();
        assert_eq!(e.field.as_deref(), Some(what), "{e}");
        assert!(e.line > 0, "{e}");
    }
}

#[test]
fn reference_bvh_and_brute_force_render_the_same_bits() {
    let d = TempDir::new("render");
    let mut body = String::from(
        // The lamp faces down, onto the terrain and the sphere.
        "[materials.lamp]\nreflectance = [1.0, 1.0, 1.0]\nemission = [4.0, 4.0, 4.0]\n\n\
         [[quad]]\nmaterial = \"lamp\"\n\
         vertices = [[1.0, 2.0, -1.0], [1.0, 2.0, 1.0], [-1.0, 2.0, 1.0], [-1.0, 2.0, -1.0]]\n\n",
    );
    body.push_str(
        "[[generate]]\nkind = \"terrain\"\ntriangles = 3000\nmaterial = \"white\"\n\
         size = [6.0, 6.0]\nheight = 1.0\ntranslate = [0.0, -1.0, 0.0]\n\n\
         [[generate]]\nkind = \"sphere\"\ntriangles = 2000\nmaterial = \"white\"\nradius = 0.7\n",
    );
    let s = load(&d, &[], &body).unwrap();
    let camera = s.camera.for_resolution(24, 24);
    // Every estimator: next-event estimation's shadow rays go through the
    // hierarchy (or brute force) too.
    for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
        let estimator = Estimator {
            integrator,
            max_depth: 4,
            rr_depth: None,
        };
        let bvh = ReferenceTracer::new(&s, 4).with_estimator(estimator);
        let brute = ReferenceTracer::with_brute_force(&s, 4).with_estimator(estimator);
        assert!(bvh.bvh().is_some() && brute.bvh().is_none());
        let (mut c1, mut c2) = (Counters::default(), Counters::default());
        for y in 0..24 {
            for x in 0..24 {
                for k in 0..4 {
                    let a = bvh.sample(&camera, &Independent::new(9), (x, y), k, &mut c1);
                    let b = brute.sample(&camera, &Independent::new(9), (x, y), k, &mut c2);
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits)
                    );
                }
            }
        }
        assert_eq!(c1, c2);
        // 2304 paths: a good share of their vertices see the lamp.
        assert_eq!(
            c1.shadow_rays > 300,
            integrator == Integrator::Nee,
            "{c1:?}"
        );
    }
}

#[test]
fn shipped_scenes_load() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for name in ["cornell.toml", "cornell-obj.toml"] {
        let s = Scene::load(&root.join(name)).unwrap_or_else(|e| panic!("{e}"));
        assert!(!s.triangles.is_empty());
    }
}

#[test]
fn a_transform_that_overflows_is_an_error_not_a_silent_drop() {
    let d = TempDir::new("overflow");
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let e = load(
        &d,
        &[("m.obj", tri)],
        &mesh(
            "m.obj",
            "material = \"white\"\nscale = 1e38\ntranslate = [3e38, 0.0, 0.0]",
        ),
    )
    .unwrap_err();
    assert!(e.file.ends_with("scene.toml"), "{e}");
    assert_eq!(e.field.as_deref(), Some("mesh[0]"), "{e}");
    assert!(e.message.contains("overflow"), "{e}");
    // The entry's `file = ...` line in the scene file as written.
    let text = std::fs::read_to_string(d.join("scene.toml")).unwrap();
    let line = text.lines().position(|l| l.starts_with("file = ")).unwrap() + 1;
    assert_eq!(e.line, line, "{e}");

    let body = "[[generate]]\nkind = \"sphere\"\ntriangles = 80\nmaterial = \"white\"\n\
                scale = 1e30\nradius = 1e30\n";
    // (A sphere of radius 1e30 scaled by 1e30: vertices near 1e60.)
    let e = load(&d, &[], body).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("generate[0]"), "{e}");
    assert!(e.message.contains("overflow"), "{e}");
}
