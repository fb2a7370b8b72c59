//! Textured assets in the engines: a checkerboard lands where its
//! texture coordinates put it, both engines trace the same paths on a
//! textured scene, images are byte-identical across threads, batch
//! sizes, kernel widths, passes and shards, a glTF renders as the same
//! scene written in TOML, and the shipped asset `scenes/textured.glb` is
//! what [`shipped_asset`] writes.
//!
//! The glTF files are written here by [`Gltf`], a small GLB writer.

mod common;

use common::{TempDir, scene_of};
use glam::{Quat, Vec3};
use std::path::Path;
use wavetrace::accel::bvh::{Bvh, BvhOptions};
use wavetrace::accel::hit::{Hit, NO_PRIM};
use wavetrace::accel::shape::{OwnedShapes, closest_hit_brute_force_filtered};
use wavetrace::accel::simd::SimdWidth;
use wavetrace::accel::{scene_bvh, two_level_bvh};
use wavetrace::film::Film;
use wavetrace::integrator::tables::Tables;
use wavetrace::math::V3;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::camera::Camera;
use wavetrace::scene::{Integrator, Scene, asset_scene};

// ---------------------------------------------------------------------------
// A GLB writer

/// A glTF asset being written: one binary buffer and the JSON arrays.
#[derive(Default)]
struct Gltf {
    bin: Vec<u8>,
    views: Vec<String>,
    accessors: Vec<String>,
    meshes: Vec<String>,
    materials: Vec<String>,
    textures: Vec<String>,
    images: Vec<String>,
    samplers: Vec<String>,
    nodes: Vec<String>,
    cameras: Vec<String>,
}

/// A texture as a material refers to it: `(texture index, extra JSON)`.
type Tex = Option<(usize, &'static str)>;

/// A metallic-roughness material.
struct Mat {
    base: [f32; 4],
    metallic: f32,
    roughness: f32,
    base_texture: Tex,
    mr_texture: Tex,
    emissive: [f32; 3],
    strength: f32,
    emissive_texture: Tex,
    normal_texture: Tex,
    /// Extra JSON of the material (e.g. its `alphaMode`).
    extra: &'static str,
}

impl Default for Mat {
    fn default() -> Self {
        Self {
            base: [1.0; 4],
            metallic: 0.0,
            roughness: 1.0,
            base_texture: None,
            mr_texture: None,
            emissive: [0.0; 3],
            strength: 1.0,
            emissive_texture: None,
            normal_texture: None,
            extra: "",
        }
    }
}

fn push(list: &mut Vec<String>, item: String) -> usize {
    list.push(item);
    list.len() - 1
}

impl Gltf {
    /// A buffer view of `bytes` (4-byte aligned).
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let item = format!(
            r#"{{"buffer": 0, "byteOffset": {}, "byteLength": {}}}"#,
            self.bin.len(),
            bytes.len()
        );
        self.bin.extend_from_slice(bytes);
        push(&mut self.views, item)
    }

    /// An accessor of `n`-component float vectors.
    fn floats(&mut self, values: &[f32], n: usize) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let ty = ["SCALAR", "VEC2", "VEC3", "VEC4"][n - 1];
        let count = values.len() / n;
        let bounds = if n == 3 {
            let col = |k: usize| values.iter().skip(k).step_by(3).copied();
            let lo: Vec<f32> = (0..3)
                .map(|k| col(k).fold(f32::INFINITY, f32::min))
                .collect();
            let hi: Vec<f32> = (0..3)
                .map(|k| col(k).fold(f32::NEG_INFINITY, f32::max))
                .collect();
            format!(r#", "min": {lo:?}, "max": {hi:?}"#)
        } else {
            String::new()
        };
        let item = format!(
            r#"{{"bufferView": {view}, "componentType": 5126, "count": {count}, "type": "{ty}"{bounds}}}"#
        );
        push(&mut self.accessors, item)
    }

    /// A triangle mesh: positions, texture coordinates, optional vertex
    /// colours, triangles; of material `material`.
    fn mesh(
        &mut self,
        positions: &[Vec3],
        uv: &[[f32; 2]],
        colours: Option<&[[f32; 4]]>,
        triangles: &[[u32; 3]],
        material: usize,
    ) -> usize {
        self.mesh_with(positions, uv, colours, (None, None), triangles, material)
    }

    /// [`mesh`](Self::mesh) with vertex normals and tangents where given.
    fn mesh_with(
        &mut self,
        positions: &[Vec3],
        uv: &[[f32; 2]],
        colours: Option<&[[f32; 4]]>,
        (normals, tangents): (Option<&[Vec3]>, Option<&[[f32; 4]]>),
        triangles: &[[u32; 3]],
        material: usize,
    ) -> usize {
        let p: Vec<f32> = positions.iter().flat_map(|v| v.to_array()).collect();
        let p = self.floats(&p, 3);
        let t: Vec<f32> = uv.iter().flatten().copied().collect();
        let t = self.floats(&t, 2);
        let mut attributes = format!(r#""POSITION": {p}, "TEXCOORD_0": {t}"#);
        if let Some(n) = normals {
            let n: Vec<f32> = n.iter().flat_map(|v| v.to_array()).collect();
            let n = self.floats(&n, 3);
            attributes += &format!(r#", "NORMAL": {n}"#);
        }
        if let Some(t) = tangents {
            let t: Vec<f32> = t.iter().flatten().copied().collect();
            let t = self.floats(&t, 4);
            attributes += &format!(r#", "TANGENT": {t}"#);
        }
        if let Some(c) = colours {
            let c: Vec<f32> = c.iter().flatten().copied().collect();
            let c = self.floats(&c, 4);
            attributes += &format!(r#", "COLOR_0": {c}"#);
        }
        let idx: Vec<u8> = triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let view = self.view(&idx);
        let count = triangles.len() * 3;
        let item = format!(
            r#"{{"bufferView": {view}, "componentType": 5125, "count": {count}, "type": "SCALAR"}}"#
        );
        let indices = push(&mut self.accessors, item);
        let item = format!(
            r#"{{"primitives": [{{"attributes": {{{attributes}}}, "indices": {indices}, "material": {material}}}]}}"#
        );
        push(&mut self.meshes, item)
    }

    /// A quad `corners[0..4]` (counter-clockwise seen from its front) with
    /// texture coordinates `uv` at the corners.
    fn quad(&mut self, corners: [Vec3; 4], uv: [[f32; 2]; 4], material: usize) -> usize {
        self.mesh(&corners, &uv, None, &[[0, 1, 2], [0, 2, 3]], material)
    }

    /// A cube of side `side` centred at the origin, each face's texture
    /// coordinates the whole image, (0, 0) at the face's top-left seen
    /// from outside.
    fn cube(&mut self, side: f32, material: usize) -> usize {
        let h = side / 2.0;
        let mut positions = Vec::new();
        let mut uv = Vec::new();
        let mut triangles = Vec::new();
        // Each face: its normal, and its "right" and "up" directions seen
        // from outside.
        let faces = [
            (Vec3::Z, Vec3::X, Vec3::Y),
            (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
            (Vec3::X, Vec3::NEG_Z, Vec3::Y),
            (Vec3::NEG_X, Vec3::Z, Vec3::Y),
            (Vec3::Y, Vec3::X, Vec3::NEG_Z),
            (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        ];
        for (n, r, u) in faces {
            let k = positions.len() as u32;
            // Top-left, bottom-left, bottom-right, top-right.
            for (a, b, t) in [
                (-1.0, 1.0, [0.0, 0.0]),
                (-1.0, -1.0, [0.0, 1.0]),
                (1.0, -1.0, [1.0, 1.0]),
                (1.0, 1.0, [1.0, 0.0]),
            ] {
                positions.push((n + r * a + u * b) * h);
                uv.push(t);
            }
            triangles.extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
        }
        self.mesh(&positions, &uv, None, &triangles, material)
    }

    /// An RGBA8 image as a PNG in the buffer, and a texture of it with a
    /// sampler of filter `filter` (glTF's code) that repeats.
    fn texture(&mut self, width: u32, height: u32, rgba: Vec<u8>, filter: u32) -> usize {
        let img = image::RgbaImage::from_raw(width, height, rgba).expect("the texel count");
        let mut png = std::io::Cursor::new(Vec::new());
        img.write_to(&mut png, image::ImageFormat::Png)
            .expect("PNG encoding");
        let view = self.view(png.get_ref());
        let image = push(
            &mut self.images,
            format!(r#"{{"bufferView": {view}, "mimeType": "image/png"}}"#),
        );
        let sampler = push(
            &mut self.samplers,
            format!(r#"{{"magFilter": {filter}, "minFilter": {filter}}}"#),
        );
        push(
            &mut self.textures,
            format!(r#"{{"source": {image}, "sampler": {sampler}}}"#),
        )
    }

    fn material(&mut self, m: Mat) -> usize {
        let tex = |key: &str, t: Tex| match t {
            Some((i, extra)) => format!(r#", "{key}": {{"index": {i}{extra}}}"#),
            None => String::new(),
        };
        let strength = match m.strength {
            1.0 => String::new(),
            s => format!(
                r#", "extensions": {{"KHR_materials_emissive_strength": {{"emissiveStrength": {s:?}}}}}"#
            ),
        };
        let item = format!(
            r#"{{"pbrMetallicRoughness": {{"baseColorFactor": {:?}, "metallicFactor": {:?}, "roughnessFactor": {:?}{}{}}}, "emissiveFactor": {:?}{strength}{}{}{}}}"#,
            m.base,
            m.metallic,
            m.roughness,
            tex("baseColorTexture", m.base_texture),
            tex("metallicRoughnessTexture", m.mr_texture),
            m.emissive,
            tex("emissiveTexture", m.emissive_texture),
            tex("normalTexture", m.normal_texture),
            m.extra,
        );
        push(&mut self.materials, item)
    }

    /// A node placing mesh `mesh` at `translation`, turned by `rotation`.
    fn node(&mut self, mesh: usize, translation: Vec3, rotation: Quat) -> usize {
        let item = format!(
            r#"{{"mesh": {mesh}, "translation": {:?}, "rotation": {:?}}}"#,
            translation.to_array(),
            rotation.to_array()
        );
        push(&mut self.nodes, item)
    }

    /// A perspective camera node.
    fn camera(&mut self, translation: Vec3, rotation: Quat, yfov: f32, aspect: f32) -> usize {
        let camera = push(
            &mut self.cameras,
            format!(
                r#"{{"type": "perspective", "perspective": {{"yfov": {yfov:?}, "aspectRatio": {aspect:?}, "znear": 0.01}}}}"#
            ),
        );
        let item = format!(
            r#"{{"camera": {camera}, "translation": {:?}, "rotation": {:?}}}"#,
            translation.to_array(),
            rotation.to_array()
        );
        push(&mut self.nodes, item)
    }

    /// The asset as a GLB file.
    fn glb(mut self) -> Vec<u8> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let list = |v: &[String]| v.join(",\n  ");
        let nodes: Vec<String> = (0..self.nodes.len()).map(|i| i.to_string()).collect();
        let uses_strength = self
            .materials
            .iter()
            .any(|m| m.contains("emissive_strength"));
        let used = match uses_strength {
            true => r#""extensionsUsed": ["KHR_materials_emissive_strength"],"#,
            false => "",
        };
        let mut json = format!(
            r#"{{"asset": {{"version": "2.0", "generator": "wavetrace tests/textured.rs"}}, {used}
 "buffers": [{{"byteLength": {}}}],
 "bufferViews": [{}],
 "accessors": [{}],
 "meshes": [{}],
 "materials": [{}],
 "textures": [{}],
 "images": [{}],
 "samplers": [{}],
 "cameras": [{}],
 "nodes": [{}],
 "scenes": [{{"nodes": [{}]}}], "scene": 0}}"#,
            self.bin.len(),
            list(&self.views),
            list(&self.accessors),
            list(&self.meshes),
            list(&self.materials),
            list(&self.textures),
            list(&self.images),
            list(&self.samplers),
            list(&self.cameras),
            list(&self.nodes),
            nodes.join(", ")
        );
        // Empty arrays are not valid glTF: drop them.
        for key in ["textures", "images", "samplers", "cameras"] {
            json = json.replace(&format!("\n \"{key}\": [],"), "");
        }
        let mut json = json.into_bytes();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let total = 12 + 8 + json.len() + 8 + self.bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&self.bin);
        out
    }
}

/// A `w × h` checkerboard of `cells × cells` squares, RGBA: `a` in the
/// top-left square and every other, `b` in the rest.
fn checker(w: u32, h: u32, cells: u32, a: [u8; 4], b: [u8; 4]) -> Vec<u8> {
    let mut out = Vec::new();
    for j in 0..h {
        for i in 0..w {
            let even = (i * cells / w + j * cells / h).is_multiple_of(2);
            out.extend_from_slice(if even { &a } else { &b });
        }
    }
    out
}

/// Writes `bytes` to `name` in `dir` and loads it as a scene.
fn render(scene: &Scene, s: &RenderSettings) -> Film {
    Renderer::new(scene, s).unwrap().render().0
}

fn settings(scene: &Scene, w: u32, h: u32, spp: u32) -> RenderSettings {
    let mut s = RenderSettings::for_scene(scene);
    (s.width, s.height, s.spp, s.threads) = (w, h, spp, 2);
    s
}

// ---------------------------------------------------------------------------
// The shipped asset

/// `scenes/textured.glb`: a checkered floor, a cube in a base colour
/// texture (bilinear), a gold cube whose metallic-roughness texture
/// stripes it shiny and rough, a wedge of vertex colours, and an emitting
/// panel above, seen by the file's camera. Written by this function
/// alone: CC0, like every file of the repository's scenes.
fn shipped_asset() -> Vec<u8> {
    let mut g = Gltf::default();
    // Textures: a grey checkerboard (nearest); a 16 × 16 pattern of four
    // coloured quadrants crossed by a white diagonal (linear); stripes of
    // roughness (G) 0.2 and 0.9, metal (B) 1 (nearest).
    let floor_tex = g.texture(8, 8, checker(8, 8, 8, [200; 4], [60, 60, 60, 255]), 9728);
    let mut pattern = Vec::new();
    for j in 0..16u32 {
        for i in 0..16u32 {
            let c = match (i < 8, j < 8) {
                _ if i == j || i + 1 == j => [240, 240, 240, 255],
                (true, true) => [200, 40, 40, 255],
                (false, true) => [40, 160, 60, 255],
                (true, false) => [40, 80, 200, 255],
                (false, false) => [230, 180, 30, 255],
            };
            pattern.extend_from_slice(&c);
        }
    }
    let cube_tex = g.texture(16, 16, pattern, 9729);
    let stripes: Vec<u8> = (0..8u32)
        .flat_map(|j| (0..8u32).map(move |_| j))
        .flat_map(|j| match j % 2 {
            0 => [0, 51, 255, 255],
            _ => [0, 230, 255, 255],
        })
        .collect();
    let stripes = g.texture(8, 8, stripes, 9728);
    let floor = g.material(Mat {
        base_texture: Some((floor_tex, "")),
        roughness: 0.8,
        ..Mat::default()
    });
    let painted = g.material(Mat {
        base_texture: Some((cube_tex, "")),
        roughness: 0.5,
        ..Mat::default()
    });
    let gold = g.material(Mat {
        base: [1.0, 0.78, 0.34, 1.0],
        metallic: 1.0,
        mr_texture: Some((stripes, "")),
        ..Mat::default()
    });
    let white = g.material(Mat {
        roughness: 0.6,
        ..Mat::default()
    });
    let lamp = g.material(Mat {
        base: [0.0, 0.0, 0.0, 1.0],
        emissive: [1.0, 1.0, 1.0],
        strength: 8.0,
        ..Mat::default()
    });
    let s = 2.5;
    let floor = g.quad(
        [
            Vec3::new(-s, 0.0, -s),
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
        ],
        [[0.0, 0.0], [0.0, 2.0], [2.0, 2.0], [2.0, 0.0]],
        floor,
    );
    g.node(floor, Vec3::ZERO, Quat::IDENTITY);
    let cube = g.cube(1.0, painted);
    g.node(cube, Vec3::new(-0.9, 0.5, 0.0), Quat::from_rotation_y(0.5));
    let cube = g.cube(0.9, gold);
    g.node(
        cube,
        Vec3::new(0.8, 0.45, -0.3),
        Quat::from_rotation_y(-0.4),
    );
    // A wedge of red, green and blue corners, in front.
    let wedge = g.mesh(
        &[
            Vec3::new(-0.5, 0.0, 0.0),
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(0.0, 0.8, 0.0),
        ],
        &[[0.0; 2]; 3],
        Some(&[
            [1.0, 0.1, 0.1, 1.0],
            [0.1, 1.0, 0.1, 1.0],
            [0.1, 0.1, 1.0, 1.0],
        ]),
        &[[0, 1, 2]],
        white,
    );
    g.node(wedge, Vec3::new(0.2, 0.0, 1.0), Quat::from_rotation_y(-0.2));
    let l = 0.9;
    let panel = g.quad(
        [
            Vec3::new(-l, 0.0, -l),
            Vec3::new(l, 0.0, -l),
            Vec3::new(l, 0.0, l),
            Vec3::new(-l, 0.0, l),
        ],
        [[0.0; 2]; 4],
        lamp,
    );
    g.node(panel, Vec3::new(0.0, 3.2, 0.3), Quat::IDENTITY);
    let eye = Vec3::new(0.0, 1.7, 4.4);
    let pitch = -((1.7f32 - 0.4) / 4.4).atan();
    g.camera(eye, Quat::from_rotation_x(pitch), 0.75, 4.0 / 3.0);
    g.glb()
}

#[test]
fn the_shipped_asset_is_what_this_test_writes() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textured.glb");
    let want = shipped_asset();
    if std::env::var_os("WAVETRACE_WRITE_ASSET").is_some() {
        std::fs::write(&path, &want).unwrap();
    }
    let have = std::fs::read(&path).unwrap();
    assert!(
        have == want,
        "scenes/textured.glb differs from what tests/textured.rs writes \
         (WAVETRACE_WRITE_ASSET=1 cargo test --release --test textured rewrites it)"
    );
    let (scene, warnings) = asset_scene::load(&path, None).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(scene.texturing.textures.len(), 3);
    assert_eq!(scene.texturing.uv.len(), scene.triangles.len());
    assert_eq!(scene.texturing.colours.len(), scene.triangles.len());
}

// ---------------------------------------------------------------------------
// Where a texture lands

/// A 2 × 2 quad in y = 0 seen straight from above, with a 4 × 4
/// checkerboard texture (nearest) and texture coordinates
/// `(u, v) = ((x + 1)/2, (z + 1)/2)`; the camera's right is +x and its up
/// −z, so the image's top-left is the texture's (0, 0). Lit by the
/// default sky.
fn checker_quad() -> Vec<u8> {
    let mut g = Gltf::default();
    let tex = g.texture(4, 4, checker(4, 4, 4, [255; 4], [0, 0, 0, 255]), 9728);
    let m = g.material(Mat {
        base_texture: Some((tex, "")),
        ..Mat::default()
    });
    let quad = g.quad(
        [
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(-1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, -1.0),
        ],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        m,
    );
    g.node(quad, Vec3::ZERO, Quat::IDENTITY);
    let down = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    g.camera(Vec3::new(0.0, 2.0, 0.0), down, 60f32.to_radians(), 1.0);
    g.glb()
}

#[test]
fn a_checkerboard_lands_where_its_texture_coordinates_put_it() {
    let dir = TempDir::new("checker");
    let scene = scene_of(&dir, "checker.glb", &checker_quad());
    let n = 64;
    let film = render(&scene, &settings(&scene, n, n, 16));
    let rgb = film.to_rgb();
    // The centre of cell (i, j) is at x = -1 + (i + ½)/2, z = -1 + (j + ½)/2,
    // 2 below the camera: pixel n/2 + f·x/2 (right), n/2 + f·z/2 (down).
    let f = n as f32 / 2.0 / 30f32.to_radians().tan();
    let mut white = Vec::new();
    let mut black = Vec::new();
    for j in 0..4 {
        for i in 0..4 {
            let x = -1.0 + (i as f32 + 0.5) / 2.0;
            let z = -1.0 + (j as f32 + 0.5) / 2.0;
            let (px, py) = (n as f32 / 2.0 + f * x / 2.0, n as f32 / 2.0 + f * z / 2.0);
            let mut sum = 0.0;
            for dy in -2..=2 {
                for dx in -2..=2 {
                    let (x, y) = (px as i32 + dx, py as i32 + dy);
                    let p = rgb[(y as u32 * n + x as u32) as usize];
                    sum += p[0] + p[1] + p[2];
                }
            }
            if (i + j) % 2 == 0 {
                white.push(((i, j), sum / 75.0));
            } else {
                black.push(((i, j), sum / 75.0));
            }
        }
    }
    let least_white = white.iter().map(|c| c.1).fold(f32::INFINITY, f32::min);
    let most_black = black.iter().map(|c| c.1).fold(0.0, f32::max);
    assert!(
        least_white > 0.05 && least_white > 4.0 * most_black,
        "white cells {white:?}, black cells {black:?}"
    );
}

// ---------------------------------------------------------------------------
// Cut-outs

/// A white leaf quad (x, z in [-1, 1], y = 0.5) whose base colour texture
/// is transparent on its left half (x < 0) and opaque on its right, of
/// alpha mode `mode`, above a red floor, seen from straight above as
/// [`checker_quad`] is, lit by the default sky.
fn leaf(mode: &'static str, opacity: f32) -> Vec<u8> {
    let mut g = Gltf::default();
    let tex = g.texture(2, 1, vec![255, 255, 255, 0, 255, 255, 255, 255], 9728);
    let leaf = g.material(Mat {
        base: [1.0, 1.0, 1.0, opacity],
        base_texture: Some((tex, "")),
        extra: mode,
        ..Mat::default()
    });
    let floor = g.material(Mat {
        base: [0.8, 0.1, 0.1, 1.0],
        ..Mat::default()
    });
    let quad = |g: &mut Gltf, s: f32, y: f32, m: usize| {
        g.quad(
            [
                Vec3::new(-s, y, -s),
                Vec3::new(-s, y, s),
                Vec3::new(s, y, s),
                Vec3::new(s, y, -s),
            ],
            [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
            m,
        )
    };
    let mesh = quad(&mut g, 1.0, 0.5, leaf);
    g.node(mesh, Vec3::ZERO, Quat::IDENTITY);
    let mesh = quad(&mut g, 2.0, 0.0, floor);
    g.node(mesh, Vec3::ZERO, Quat::IDENTITY);
    let down = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    g.camera(Vec3::new(0.0, 3.0, 0.0), down, 60f32.to_radians(), 1.0);
    g.glb()
}

const MASK: &str = r#", "alphaMode": "MASK", "alphaCutoff": 0.5"#;
const BLEND: &str = r#", "alphaMode": "BLEND""#;

#[test]
fn an_alpha_mask_cuts_the_surface_out_where_its_texture_is_transparent() {
    let dir = TempDir::new("mask");
    let scene = scene_of(&dir, "leaf.glb", &leaf(MASK, 1.0));
    let n = 64;
    let rgb = render(&scene, &settings(&scene, n, n, 16)).to_rgb();
    // The mean colour of the 5 × 5 pixels around the point x of the leaf
    // (z = 0; 2.5 below the camera).
    let f = n as f32 / 2.0 / 30f32.to_radians().tan();
    let at = |x: f32| {
        let (px, py) = ((n as f32 / 2.0 + f * x / 2.5) as i32, n as i32 / 2);
        let mut sum = [0.0f32; 3];
        for dy in -2..=2 {
            for dx in -2..=2 {
                let p = rgb[((py + dy) as u32 * n + (px + dx) as u32) as usize];
                (0..3).for_each(|c| sum[c] += p[c] / 25.0);
            }
        }
        sum
    };
    // The left half lets the red floor through; the right half is the
    // white leaf.
    let (left, right) = (at(-0.5), at(0.5));
    assert!(left[0] > 0.02 && left[0] > 3.0 * left[1], "left {left:?}");
    assert!(
        right[1] > 0.02 && right[1] > 0.5 * right[0],
        "right {right:?}"
    );
}

// ---------------------------------------------------------------------------
// Emissive textures

/// The sRGB curve's decoding of the 8-bit value `c`.
fn srgb(c: u8) -> f32 {
    let c = c as f64 / 255.0;
    (if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }) as f32
}

/// The texels of [`emissive_wall`]'s 2 × 2 emissive texture: orange, blue
/// (top row), green, white.
const WALL_TEXELS: [[u8; 4]; 4] = [
    [255, 128, 0, 255],
    [0, 0, 255, 255],
    [0, 255, 0, 255],
    [255, 255, 255, 255],
];

/// `emissiveFactor` × `KHR_materials_emissive_strength` of the wall.
const WALL_FACTOR: [f32; 3] = [2.0, 1.0, 3.0];
const WALL_STRENGTH: f32 = 2.0;

/// An emitting wall (x in [-1, 1], y in [0.1, 1.1], z = -1, facing +z)
/// whose emissive texture (nearest) is [`WALL_TEXELS`] over its four
/// quarters — texture coordinates `u` from left to right, `v` from top to
/// bottom — black in base colour, standing on a white floor that only it
/// lights, seen from the front and above.
fn emissive_wall() -> Vec<u8> {
    let mut g = Gltf::default();
    let tex = g.texture(2, 2, WALL_TEXELS.concat(), 9728);
    let wall = g.material(Mat {
        base: [0.0, 0.0, 0.0, 1.0],
        emissive: WALL_FACTOR,
        strength: WALL_STRENGTH,
        emissive_texture: Some((tex, "")),
        ..Mat::default()
    });
    let floor = g.material(Mat {
        base: [0.8, 0.8, 0.8, 1.0],
        ..Mat::default()
    });
    let mesh = g.quad(
        [
            Vec3::new(-1.0, 0.1, -1.0),
            Vec3::new(1.0, 0.1, -1.0),
            Vec3::new(1.0, 1.1, -1.0),
            Vec3::new(-1.0, 1.1, -1.0),
        ],
        [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
        wall,
    );
    g.node(mesh, Vec3::ZERO, Quat::IDENTITY);
    // The floor (x in [-1.5, 1.5], z in [-1, 2]) sees the wall from the
    // front only, none of it at a grazing angle.
    let mesh = g.quad(
        [
            Vec3::new(-1.5, 0.0, -1.0),
            Vec3::new(-1.5, 0.0, 2.0),
            Vec3::new(1.5, 0.0, 2.0),
            Vec3::new(1.5, 0.0, -1.0),
        ],
        [[0.0; 2]; 4],
        floor,
    );
    g.node(mesh, Vec3::ZERO, Quat::IDENTITY);
    let pitch = -(0.7f32 / 4.0).atan();
    g.camera(
        Vec3::new(0.0, 1.2, 3.0),
        Quat::from_rotation_x(pitch),
        0.9,
        4.0 / 3.0,
    );
    g.glb()
}

/// A camera ray that hits the wall sees `emissiveFactor` × strength × the
/// sRGB-decoded texel where it lands, exactly (at depth 1 nothing else
/// adds): each quarter of the wall shows its own texel, the orange one at
/// the top left, blue top right, green bottom left, white bottom right —
/// in both engines.
#[test]
fn an_emissive_texture_shines_where_its_texture_coordinates_put_it() {
    let dir = TempDir::new("emissive");
    let scene = scene_of(&dir, "wall.glb", &emissive_wall());
    let want: Vec<[f32; 3]> = WALL_TEXELS
        .iter()
        .map(|t| std::array::from_fn(|c| WALL_FACTOR[c] * WALL_STRENGTH * srgb(t[c])))
        .collect();
    for engine in [Engine::Reference, Engine::Wavefront] {
        let (w, h) = (64, 48);
        let mut s = settings(&scene, w, h, 8);
        (s.engine, s.max_depth) = (engine, 1);
        let rgb = render(&scene, &s).to_rgb();
        // Per texel: how many pixels show exactly it, and their mean x, y.
        let mut found = [(0usize, 0.0f32, 0.0f32); 4];
        let mut others = 0;
        for (i, p) in rgb.iter().enumerate() {
            let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
            let close = |a: &[f32; 3]| (0..3).all(|c| (p[c] - a[c]).abs() <= 1e-5 * a[c].max(1.0));
            match want.iter().position(close) {
                Some(k) => {
                    let f = &mut found[k];
                    (f.0, f.1, f.2) = (f.0 + 1, f.1 + x, f.2 + y);
                }
                None if p.iter().all(|&v| v == 0.0) => {}
                None => others += 1,
            }
        }
        let at = found.map(|(n, x, y)| (n, x / n.max(1) as f32, y / n.max(1) as f32));
        for (k, (n, ..)) in at.iter().enumerate() {
            assert!(*n >= 30, "{engine:?}: texel {k} in {n} pixels only: {at:?}");
        }
        // Orange left of blue, green left of white; orange above green,
        // blue above white.
        assert!(at[0].1 < at[1].1 && at[2].1 < at[3].1, "{engine:?}: {at:?}");
        assert!(at[0].2 < at[2].2 && at[1].2 < at[3].2, "{engine:?}: {at:?}");
        // Only the wall's edges mix texels with the black floor.
        assert!(others < 160, "{engine:?}: {others} pixels of no texel");
    }
}

/// An OBJ asset with texture coordinates (`vt`, whose `v` runs up) and an
/// MTL whose `map_Ke` (after an option) and `map_Kd` name a PNG beside
/// it: the wall of [`emissive_wall`] as OBJ + MTL + PNG (8 × 8, the four
/// texels as quarters, bilinear), placed by a TOML scene with that wall's
/// camera, shows each texel × `Ke` where the glTF wall does, in both
/// engines. An image that is not there is refused naming the MTL's line.
#[test]
fn an_obj_asset_reads_its_texture_coordinates_and_mtl_images() {
    let dir = TempDir::new("obj-maps");
    let quarter = |i: u32, j: u32| WALL_TEXELS[(j / 4 * 2 + i / 4) as usize];
    let png: Vec<u8> = (0..64).flat_map(|k| quarter(k % 8, k / 8)).collect();
    image::RgbaImage::from_raw(8, 8, png)
        .unwrap()
        .save(dir.join("wall.png"))
        .unwrap();
    let obj = "mtllib wall.mtl\nv -1 0.1 -1\nv 1 0.1 -1\nv 1 1.1 -1\nv -1 1.1 -1\n\
               vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl wall\nf 1/1 2/2 3/3 4/4\n";
    std::fs::write(dir.join("wall.obj"), obj).unwrap();
    let ke: [f32; 3] = std::array::from_fn(|c| WALL_FACTOR[c] * WALL_STRENGTH);
    let mtl = |image: &str| {
        format!(
            "newmtl wall\nKd 0 0 0\nKe {:?} {:?} {:?}\nmap_Kd wall.png\nmap_Ke -bm 1 {image}\n",
            ke[0], ke[1], ke[2]
        )
    };
    std::fs::write(dir.join("wall.mtl"), mtl("wall.png")).unwrap();
    let glb = scene_of(&dir, "wall.glb", &emissive_wall());
    let c = &glb.camera;
    let v = |p: Vec3| format!("[{:?}, {:?}, {:?}]", p.x, p.y, p.z);
    let toml = format!(
        "[camera]\nposition = {}\nforward = {}\nup = {}\nfocal_length_px = {:?}\nwidth = {}\nheight = {}\n\n\
         [integrator]\nmax_depth = 1\n\n[[asset]]\nfile = \"wall.obj\"\n",
        v(c.position),
        v(c.forward),
        v(c.up),
        c.focal_length_px,
        c.width,
        c.height
    );
    std::fs::write(dir.join("wall.toml"), &toml).unwrap();
    let scene = Scene::load(&dir.join("wall.toml")).unwrap();
    assert_eq!(scene.texturing.textures.len(), 2, "map_Kd and map_Ke");
    let want: Vec<[f32; 3]> = WALL_TEXELS
        .iter()
        .map(|t| std::array::from_fn(|c| ke[c] * srgb(t[c])))
        .collect();
    for engine in [Engine::Reference, Engine::Wavefront] {
        let (w, h) = (64, 48);
        let mut s = settings(&scene, w, h, 8);
        (s.engine, s.max_depth) = (engine, 1);
        let rgb = render(&scene, &s).to_rgb();
        let mut found = [(0usize, 0.0f32, 0.0f32); 4];
        for (i, p) in rgb.iter().enumerate() {
            let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
            let close = |a: &[f32; 3]| (0..3).all(|c| (p[c] - a[c]).abs() <= 1e-5 * a[c].max(1.0));
            if let Some(k) = want.iter().position(close) {
                let f = &mut found[k];
                (f.0, f.1, f.2) = (f.0 + 1, f.1 + x, f.2 + y);
            }
        }
        let at = found.map(|(n, x, y)| (n, x / n.max(1) as f32, y / n.max(1) as f32));
        for (k, (n, ..)) in at.iter().enumerate() {
            assert!(*n >= 20, "{engine:?}: texel {k} in {n} pixels only: {at:?}");
        }
        assert!(at[0].1 < at[1].1 && at[2].1 < at[3].1, "{engine:?}: {at:?}");
        assert!(at[0].2 < at[2].2 && at[1].2 < at[3].2, "{engine:?}: {at:?}");
    }
    std::fs::write(dir.join("wall.mtl"), mtl("missing.png")).unwrap();
    let e = Scene::load(&dir.join("wall.toml")).unwrap_err().to_string();
    assert!(
        e.contains("wall.mtl") && e.contains("line 5") && e.contains("missing.png"),
        "{e}"
    );
}

/// Per pixel and channel of the wall scene, the mean over `K` seeds of
/// `spp`-sample images of estimator `integrator`, and the squared
/// standard error of that mean.
fn wall_estimate(scene: &Scene, integrator: Integrator, spp: u32) -> Vec<(f64, f64)> {
    const K: u64 = 12;
    let images: Vec<Vec<f64>> = (0..K)
        .map(|k| {
            let mut s = settings(scene, 16, 12, spp);
            (s.integrator, s.seed, s.max_depth) = (integrator, 500 + k, 3);
            let film = render(scene, &s);
            assert_eq!(film.invalid_samples, 0);
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

/// Next-event estimation picks the wall by its mean power but weighs the
/// point it samples by the texture there, as a scattered ray that hits the
/// wall does: its image and the BSDF-sampling estimator's agree within
/// their noise (per pixel and channel, z = difference / standard error;
/// mean z² near 1, no |z| far in the tail); and the floor is lit by the
/// wall's colours where they are.
#[test]
fn light_sampling_weighs_an_emissive_texture_as_scattered_rays_see_it() {
    let dir = TempDir::new("emissive-z");
    let scene = scene_of(&dir, "wall.glb", &emissive_wall());
    let nee = wall_estimate(&scene, Integrator::Nee, 32);
    let bsdf = wall_estimate(&scene, Integrator::Bsdf, 256);
    let z: Vec<f64> = (nee.iter().zip(&bsdf))
        .map(|(&(ma, va), &(mb, vb))| match va + vb {
            0.0 if ma == mb => 0.0,
            0.0 => f64::INFINITY,
            v => (ma - mb) / v.sqrt(),
        })
        .collect();
    let mean_z2 = z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64;
    let max_z = z.iter().fold(0.0f64, |m, z| z.abs().max(m));
    assert!(
        mean_z2 < 1.6 && max_z < 7.0,
        "nee and bsdf disagree: mean z² {mean_z2:.3}, max |z| {max_z:.2}"
    );
    // The floor just in front of the wall's green quarter is greener
    // (against blue) than in front of its white quarter.
    let px = |x: usize, y: usize| &nee[(y * 16 + x) * 3..(y * 16 + x) * 3 + 3];
    let (l, r) = (px(5, 8), px(10, 8));
    assert!(
        l[1].0 / l[2].0 > 2.0 * r[1].0 / r[2].0,
        "left {l:?}, right {r:?}"
    );
}

// ---------------------------------------------------------------------------
// Normal textures

/// The 1 × 1 normal texture's texel: the tangent-space normal
/// (0.4, 0.3, 0.866) encoded as `(n + 1)/2` in 8 bits.
const TILT: [u8; 4] = [179, 166, 238, 255];

/// [`checker_quad`]'s quad (y = 0, normals +y, `u` along +x, `v` along +z)
/// white, with the normal texture [`TILT`] of scale `scale`, and vertex
/// tangents +x of handedness `w` (`None`: none in the file, so they are
/// generated), seen from straight above, lit by the default sky.
fn tilted_quad(w: Option<f32>, scale: f32) -> Vec<u8> {
    let mut g = Gltf::default();
    let tex = g.texture(1, 1, TILT.to_vec(), 9728);
    let extra: &'static str = Box::leak(format!(r#", "scale": {scale:?}"#).into_boxed_str());
    let m = g.material(Mat {
        normal_texture: Some((tex, extra)),
        ..Mat::default()
    });
    let tangents = w.map(|w| [[1.0, 0.0, 0.0, w]; 4]);
    let quad = g.mesh_with(
        &[
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(-1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, -1.0),
        ],
        &[[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        None,
        (Some(&[Vec3::Y; 4][..]), tangents.as_ref().map(|t| &t[..])),
        &[[0, 1, 2], [0, 2, 3]],
        m,
    );
    g.node(quad, Vec3::ZERO, Quat::IDENTITY);
    let down = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    g.camera(Vec3::new(0.0, 2.0, 0.0), down, 60f32.to_radians(), 1.0);
    g.glb()
}

/// A normal texture of a known tilt gives the shading normal (the normal
/// AOV, in both engines) the direction glTF 2.0 defines: `(2c − 1)`, X
/// and Y times `scale`, in the frame tangent `t` = +x, bitangent
/// `w · (n × t)`, normal `n` = +y. The file's tangents of either
/// handedness turn the tilt's Y part to −z (w = 1) or +z (w = −1);
/// generated ones (MikkTSpace) give the bitangent towards decreasing `v`,
/// the image's up (w = 1 here), as glTF's "+Y up" reads it.
#[test]
fn a_normal_texture_bends_the_shading_normal_as_its_tangent_frame_says() {
    use wavetrace::scene::{Aov, AovSet};
    let dir = TempDir::new("normal-map");
    let c = TILT.map(|b| 2.0 * (b as f32 / 255.0) - 1.0);
    for (w, scale, bitangent) in [
        (Some(1.0), 1.0, Vec3::NEG_Z),
        (Some(-1.0), 1.0, Vec3::Z),
        (None, 0.5, Vec3::NEG_Z),
    ] {
        let want = (Vec3::X * c[0] * scale + bitangent * c[1] * scale + Vec3::Y * c[2]).normalize();
        let scene = scene_of(&dir, "tilt.glb", &tilted_quad(w, scale));
        for engine in [Engine::Reference, Engine::Wavefront] {
            let mut s = settings(&scene, 16, 16, 4);
            (s.engine, s.aovs) = (engine, AovSet::of(&[Aov::Normal]));
            let film = render(&scene, &s);
            let (_, normals) = film.aov_images().into_iter().next().unwrap();
            for (x, y) in [(8, 8), (4, 5), (11, 10)] {
                let got = Vec3::from(normals[y * 16 + x]);
                assert!(
                    (got - want).length() < 1e-5,
                    "w {w:?}, scale {scale}, {engine:?}: pixel ({x}, {y}) has {got}, not {want}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Both engines, and reproducibility

/// `KHR_materials_transmission` on a checkered floor under a lamp: a
/// rough solid cube (`KHR_materials_volume`), a rough thin-walled pane,
/// a smooth thin pane of transmission 0.8, and a rough, partly metallic
/// solid cube whose transmission texture stripes it.
fn transmissive() -> Vec<u8> {
    let mut g = Gltf::default();
    let floor_tex = g.texture(8, 8, checker(8, 8, 8, [200; 4], [60, 60, 60, 255]), 9728);
    let stripes: Vec<u8> = (0..8u32)
        .flat_map(|j| (0..8u32).map(move |_| j))
        .flat_map(|j| match j % 2 {
            0 => [255, 0, 0, 255],
            _ => [40, 0, 0, 255],
        })
        .collect();
    let stripes = g.texture(8, 8, stripes, 9728);
    let floor = g.material(Mat {
        base_texture: Some((floor_tex, "")),
        roughness: 0.8,
        ..Mat::default()
    });
    let solid = g.material(Mat {
        base: [0.9, 0.95, 1.0, 1.0],
        roughness: 0.4,
        extra: r#", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_volume": {"thicknessFactor": 1.0}, "KHR_materials_ior": {"ior": 1.45}}"#,
        ..Mat::default()
    });
    let thin = g.material(Mat {
        base: [1.0, 0.9, 0.7, 1.0],
        roughness: 0.3,
        extra: r#", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}}"#,
        ..Mat::default()
    });
    let smooth = g.material(Mat {
        base: [0.8, 1.0, 0.8, 1.0],
        roughness: 0.0,
        extra: r#", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.8}}"#,
        ..Mat::default()
    });
    let striped: &'static str = Box::leak(
        format!(
            r#", "extensions": {{"KHR_materials_transmission": {{"transmissionFactor": 0.9, "transmissionTexture": {{"index": {stripes}}}}}, "KHR_materials_volume": {{"thicknessFactor": 0.5}}}}"#
        )
        .into_boxed_str(),
    );
    let striped = g.material(Mat {
        base: [1.0, 0.8, 0.8, 1.0],
        metallic: 0.3,
        roughness: 0.5,
        extra: striped,
        ..Mat::default()
    });
    let lamp = g.material(Mat {
        base: [0.0, 0.0, 0.0, 1.0],
        emissive: [1.0, 1.0, 1.0],
        strength: 8.0,
        ..Mat::default()
    });
    let s = 2.5;
    let floor = g.quad(
        [
            Vec3::new(-s, 0.0, -s),
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
        ],
        [[0.0, 0.0], [0.0, 2.0], [2.0, 2.0], [2.0, 0.0]],
        floor,
    );
    g.node(floor, Vec3::ZERO, Quat::IDENTITY);
    let cube = g.cube(1.0, solid);
    g.node(cube, Vec3::new(-0.9, 0.5, 0.0), Quat::from_rotation_y(0.5));
    let cube = g.cube(0.9, striped);
    g.node(
        cube,
        Vec3::new(0.8, 0.45, -0.3),
        Quat::from_rotation_y(-0.4),
    );
    let pane = |g: &mut Gltf, m| {
        let h = 0.5;
        g.quad(
            [
                Vec3::new(-h, 0.0, 0.0),
                Vec3::new(h, 0.0, 0.0),
                Vec3::new(h, 2.0 * h, 0.0),
                Vec3::new(-h, 2.0 * h, 0.0),
            ],
            [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
            m,
        )
    };
    let p = pane(&mut g, thin);
    g.node(p, Vec3::new(-0.3, 0.0, 1.2), Quat::from_rotation_y(0.3));
    let p = pane(&mut g, smooth);
    g.node(p, Vec3::new(0.7, 0.0, 1.0), Quat::from_rotation_y(-0.3));
    let l = 0.9;
    let panel = g.quad(
        [
            Vec3::new(-l, 0.0, -l),
            Vec3::new(l, 0.0, -l),
            Vec3::new(l, 0.0, l),
            Vec3::new(-l, 0.0, l),
        ],
        [[0.0; 2]; 4],
        lamp,
    );
    g.node(panel, Vec3::new(0.0, 3.2, 0.3), Quat::IDENTITY);
    let eye = Vec3::new(0.0, 1.7, 4.4);
    let pitch = -((1.7f32 - 0.4) / 4.4).atan();
    g.camera(eye, Quat::from_rotation_x(pitch), 0.75, 4.0 / 3.0);
    g.glb()
}

/// The transmissive asset's materials are read as the extensions say:
/// thin without `KHR_materials_volume`, solid with it, the transmission
/// texture as a map.
#[test]
fn transmission_materials_are_thin_or_solid_as_the_volume_extension_says() {
    use wavetrace::scene::Model;
    let dir = TempDir::new("transmission");
    let scene = scene_of(&dir, "transmission.glb", &transmissive());
    let m = |k: usize| &scene.materials[k];
    assert_eq!(m(1).model, Model::Transmission);
    assert!(!m(1).thin && (m(1).ior, m(1).roughness, m(1).transmission) == (1.45, 0.4, 1.0));
    assert!(m(2).thin && m(2).model == Model::Transmission);
    assert!(m(3).thin && m(3).transmission == 0.8 && m(3).roughness == 0.0);
    assert!(!m(4).thin && m(4).maps.transmission.is_some() && m(4).metallic == 0.3);
}

/// The two engines trace the same paths, and differ by the order of
/// summation only (as tests/wavefront.rs holds them), for every
/// integrator.
#[test]
fn both_engines_trace_the_same_paths_on_textured_assets() {
    let dir = TempDir::new("engines");
    for (name, bytes) in [
        ("textured.glb", shipped_asset()),
        ("checker.glb", checker_quad()),
        ("mask.glb", leaf(MASK, 1.0)),
        ("blend.glb", leaf(BLEND, 0.6)),
        ("stack.glb", cutout_stack(8, 3)),
        ("wall.glb", emissive_wall()),
        ("tilt.glb", tilted_quad(None, 0.5)),
        ("transmission.glb", transmissive()),
        ("specular.glb", specular_and_volume()),
    ] {
        let scene = scene_of(&dir, name, &bytes);
        for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
            let film = |engine| {
                let mut s = settings(&scene, 40, 30, 4);
                (s.engine, s.integrator) = (engine, integrator);
                render(&scene, &s).to_rgb()
            };
            let (a, b) = (film(Engine::Reference), film(Engine::Wavefront));
            common::assert_engines_close(&format!("{name} {integrator:?}"), &a, &b);
            let sum: f64 = a.iter().flatten().map(|&x| x as f64).sum();
            assert!(sum > 0.0, "{name}: a black image");
        }
    }
}

#[test]
fn a_textured_image_is_the_same_whatever_threads_batches_and_lanes() {
    let dir = TempDir::new("bits");
    for (name, bytes) in [
        ("textured.glb", shipped_asset()),
        ("blend.glb", leaf(BLEND, 0.6)),
        ("stack.glb", cutout_stack(8, 3)),
        ("wall.glb", emissive_wall()),
        ("tilt.glb", tilted_quad(Some(-1.0), 0.8)),
        ("transmission.glb", transmissive()),
        ("specular.glb", specular_and_volume()),
    ] {
        same_whatever_threads_batches_and_lanes(&scene_of(&dir, name, &bytes), name);
    }
}

fn same_whatever_threads_batches_and_lanes(scene: &Scene, name: &str) {
    let base = settings(scene, 40, 30, 4);
    let want = render(scene, &base);
    assert!(want.sums.iter().any(|s| s != &want.sums[0]));
    let mut variants = Vec::new();
    for threads in [1, 2] {
        for batch in [7, 64, 4096] {
            for simd in wavetrace::accel::simd::SimdWidth::available() {
                variants.push((threads, batch, simd));
            }
        }
    }
    for (threads, batch, simd) in variants {
        let mut s = base.clone();
        (s.threads, s.batch_size, s.simd) = (threads, batch, simd);
        let got = render(scene, &s);
        assert!(
            got.sums == want.sums,
            "{name}: {threads} threads, batches of {batch}, {simd:?}"
        );
    }
}

#[test]
fn a_textured_image_is_the_same_in_passes_and_shards() {
    let dir = TempDir::new("shards");
    std::fs::write(dir.join("t.glb"), shipped_asset()).unwrap();
    let small = [
        "--width",
        "24",
        "--height",
        "18",
        "--spp",
        "4",
        "--threads",
        "2",
    ];
    let run = |args: &[&str]| {
        let mut all: Vec<&str> = vec!["render", "t.glb"];
        all.extend_from_slice(&small);
        all.extend_from_slice(args);
        common::run_ok(&dir, &all);
    };
    run(&["-o", "whole.exr"]);
    run(&["--samples", "0..1", "--partial", "a.wtacc"]);
    run(&["--samples", "1..4", "--partial", "b.wtacc"]);
    common::run_ok(&dir, &["merge", "a.wtacc", "b.wtacc", "-o", "passes.exr"]);
    run(&["--shard", "0/2", "--partial", "s0.wtacc"]);
    run(&["--shard", "1/2", "--partial", "s1.wtacc"]);
    common::run_ok(&dir, &["merge", "s0.wtacc", "s1.wtacc", "-o", "shards.exr"]);
    let whole = std::fs::read(dir.join("whole.exr")).unwrap();
    for other in ["passes.exr", "shards.exr"] {
        assert!(
            std::fs::read(dir.join(other)).unwrap() == whole,
            "{other} differs from the whole render"
        );
    }
}

/// An image in a buffer view without a `mimeType` (the specification
/// requires one) is refused naming it: the `gltf` crate's own lookup
/// unwraps it (a panic, which tests/fuzz.rs-style mutations found).
#[test]
fn an_image_in_a_buffer_view_without_a_mime_type_is_refused() {
    let glb = checker_quad();
    let text = r#""mimeType": "image/png""#;
    let at = glb
        .windows(text.len())
        .position(|w| w == text.as_bytes())
        .unwrap();
    let mut bad = glb.clone();
    // The same length: the key renamed, so the image has no mimeType.
    bad[at..at + text.len()].copy_from_slice(br#""mimeTypX": "image/png""#);
    let e = wavetrace::scene::gltf::read(&bad, "bad.glb", None).unwrap_err();
    assert_eq!(e.at, "images[0]", "{e}");
    assert!(e.message.contains("mimeType"), "{e}");
    assert!(wavetrace::scene::gltf::read(&glb, "good.glb", None).is_ok());
}

// ---------------------------------------------------------------------------
// --stats

/// `--stats` counts an asset's meshes once and its instances each time:
/// one cube (12 triangles) placed by three nodes, in a 4 × 4 texture, is 1
/// mesh, 3 instances, 12 unique and 36 instanced triangles (the scene's
/// 36), 1 texture of 64 bytes.
#[test]
fn stats_count_meshes_instances_triangles_and_textures() {
    let dir = TempDir::new("stats");
    let mut g = Gltf::default();
    let tex = g.texture(4, 4, checker(4, 4, 2, [255; 4], [0, 0, 0, 255]), 9728);
    let m = g.material(Mat {
        base_texture: Some((tex, "")),
        ..Mat::default()
    });
    let cube = g.cube(0.5, m);
    for x in [-1.0, 0.0, 1.0] {
        g.node(cube, Vec3::new(x, 0.0, 0.0), Quat::IDENTITY);
    }
    std::fs::write(dir.join("cubes.glb"), g.glb()).unwrap();
    common::run_ok(
        &dir,
        &[
            "render",
            "cubes.glb",
            "--width",
            "8",
            "--height",
            "6",
            "--spp",
            "1",
            "-o",
            "c.png",
            "--stats",
            "s.json",
        ],
    );
    let text = std::fs::read_to_string(dir.join("s.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    for (field, want) in [
        ("triangles", 36),
        ("meshes", 1),
        ("instances", 3),
        ("unique_triangles", 12),
        ("instanced_triangles", 36),
        ("textures", 1),
        ("texture_bytes", 64),
    ] {
        assert_eq!(json[field], want, "{field} in {text}");
    }
    // The texture lookups' time: some, and part of the stages' (inside
    // light, bounce and shade).
    let textures = json["texture_seconds"].as_f64().unwrap();
    let inside: f64 = ["light", "bounce", "shade"]
        .iter()
        .map(|s| json["engine_stages"][s].as_f64().unwrap())
        .sum();
    assert!(
        textures > 0.0 && textures <= inside,
        "{textures} of {inside} in {text}"
    );
    // None without textures.
    let mut g = Gltf::default();
    let m = g.material(Mat::default());
    let cube = g.cube(0.5, m);
    g.node(cube, Vec3::ZERO, Quat::IDENTITY);
    std::fs::write(dir.join("plain.glb"), g.glb()).unwrap();
    common::run_ok(
        &dir,
        &["render", "plain.glb", "--width", "8", "--height", "6"]
            .into_iter()
            .chain(["--spp", "1", "-o", "p.png", "--stats", "p.json"])
            .collect::<Vec<_>>(),
    );
    let text = std::fs::read_to_string(dir.join("p.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["texture_seconds"], 0.0, "{text}");
}

// ---------------------------------------------------------------------------
// glTF and TOML

#[test]
fn a_gltf_renders_as_the_same_scene_written_in_toml() {
    // A floor, a tilted metal panel and a lamp, in both forms.
    let floor = [
        Vec3::new(-2.0, 0.0, -2.0),
        Vec3::new(-2.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, -2.0),
    ];
    let panel = [
        Vec3::new(-0.5, 0.0, -0.5),
        Vec3::new(0.5, 0.0, -0.5),
        Vec3::new(0.5, 1.0, -1.0),
        Vec3::new(-0.5, 1.0, -1.0),
    ];
    let lamp = [
        Vec3::new(-0.5, 2.0, -0.5),
        Vec3::new(0.5, 2.0, -0.5),
        Vec3::new(0.5, 2.0, 0.5),
        Vec3::new(-0.5, 2.0, 0.5),
    ];
    // Materials in the order TOML gives them (by name).
    let mats = [
        ("a_floor", [0.8, 0.3, 0.2], 0.0, 0.5, 0.0),
        ("b_panel", [0.9, 0.9, 0.5], 1.0, 0.3, 0.0),
        ("c_lamp", [0.0, 0.0, 0.0], 0.0, 1.0, 4.0),
    ];
    let mut g = Gltf::default();
    for (_, base, metallic, roughness, emit) in mats {
        g.material(Mat {
            base: [base[0], base[1], base[2], 1.0],
            metallic,
            roughness,
            emissive: if emit > 0.0 { [1.0; 3] } else { [0.0; 3] },
            strength: if emit > 0.0 { emit } else { 1.0 },
            ..Mat::default()
        });
    }
    for (k, quad) in [floor, panel, lamp].iter().enumerate() {
        let mesh = g.quad(*quad, [[0.0; 2]; 4], k);
        g.node(mesh, Vec3::ZERO, Quat::IDENTITY);
    }
    g.camera(Vec3::new(0.0, 1.0, 4.0), Quat::IDENTITY, 0.8, 1.0);
    let dir = TempDir::new("toml");
    let from_gltf = scene_of(&dir, "s.glb", &g.glb());

    let v = |p: Vec3| format!("[{:?}, {:?}, {:?}]", p.x, p.y, p.z);
    let mut toml = format!(
        "[camera]\nposition = [0.0, 1.0, 4.0]\nforward = [0.0, 0.0, -1.0]\nup = [0.0, 1.0, 0.0]\n\
         focal_length_px = {:?}\nwidth = 480\nheight = 480\n\n[integrator]\nmax_depth = {}\n\n",
        from_gltf.camera.focal_length_px,
        asset_scene::ASSET_MAX_DEPTH
    );
    for (name, base, metallic, roughness, emit) in mats {
        toml += &format!(
            "[materials.{name}]\nmodel = \"metallic-roughness\"\nreflectance = {base:?}\n\
             metallic = {metallic:?}\nroughness = {roughness:?}\nemission = [{emit:?}, {emit:?}, {emit:?}]\n\n"
        );
    }
    for ((name, ..), quad) in mats.iter().zip([floor, panel, lamp]) {
        for t in [[0, 1, 2], [0, 2, 3]] {
            toml += &format!(
                "[[triangle]]\nmaterial = \"{name}\"\nvertices = [{}, {}, {}]\n\n",
                v(quad[t[0]]),
                v(quad[t[1]]),
                v(quad[t[2]])
            );
        }
    }
    let path = dir.join("s.toml");
    std::fs::write(&path, &toml).unwrap();
    let from_toml = Scene::load(&path).unwrap();
    assert_eq!(from_gltf.triangles, from_toml.triangles);
    assert_eq!(from_gltf.camera, from_toml.camera);
    for engine in [Engine::Wavefront, Engine::Reference] {
        let films = [&from_gltf, &from_toml].map(|scene| {
            let mut s = settings(scene, 32, 32, 8);
            s.engine = engine;
            render(scene, &s)
        });
        assert!(films[0].sums.iter().any(|s| s[0] > 0));
        assert!(
            films[0].sums == films[1].sums,
            "{engine:?}: the images differ"
        );
    }
}

/// The camera Camera::new makes is what the file's camera gives (so the
/// checkerboard's projection above is the one rendered).
#[test]
fn the_checker_scene_has_the_camera_its_file_gives() {
    let dir = TempDir::new("camera");
    let scene = scene_of(&dir, "checker.glb", &checker_quad());
    let want = Camera::new(
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::NEG_Y,
        Vec3::NEG_Z,
        Camera::focal_from_vfov(60.0, 480),
        480,
        480,
    )
    .unwrap();
    let c = &scene.camera;
    assert!((c.position - want.position).length() < 1e-5);
    assert!((c.forward - want.forward).length() < 1e-5);
    assert!((c.up - want.up).length() < 1e-5);
    assert!((c.focal_length_px - want.focal_length_px).abs() < 1e-2);
    assert_eq!((c.width, c.height), (480, 480));
}

// ---------------------------------------------------------------------------
// Alpha and object ids through cut-outs

/// The MASK leaf of [`leaf`] alone (node 0), with a small red tile (node
/// 1, x in -0.8..-0.2, z in -0.3..0.3, y = 0) under its cut-out half,
/// seen from straight above, against nothing.
fn leaf_over_a_tile() -> Vec<u8> {
    let mut g = Gltf::default();
    let tex = g.texture(2, 1, vec![255, 255, 255, 0, 255, 255, 255, 255], 9728);
    let leaf = g.material(Mat {
        base: [1.0, 1.0, 1.0, 1.0],
        base_texture: Some((tex, "")),
        extra: MASK,
        ..Mat::default()
    });
    let red = g.material(Mat {
        base: [0.8, 0.1, 0.1, 1.0],
        ..Mat::default()
    });
    let quad = |g: &mut Gltf, s: f32, y: f32, m: usize| {
        g.quad(
            [
                Vec3::new(-s, y, -s),
                Vec3::new(-s, y, s),
                Vec3::new(s, y, s),
                Vec3::new(s, y, -s),
            ],
            [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
            m,
        )
    };
    let mesh = quad(&mut g, 1.0, 0.5, leaf);
    g.node(mesh, Vec3::ZERO, Quat::IDENTITY);
    let mesh = quad(&mut g, 0.3, 0.0, red);
    g.node(mesh, Vec3::new(-0.5, 0.0, 0.0), Quat::IDENTITY);
    let down = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    g.camera(Vec3::new(0.0, 3.0, 0.0), down, 60f32.to_radians(), 1.0);
    g.glb()
}

/// What the camera ray `(o, d)` hits in [`leaf_over_a_tile`], by this
/// test's own `f64` arithmetic: the object id (1 the leaf's opaque half,
/// 2 the tile, 0 nothing: the leaf's cut-out half lets rays through), and
/// whether that is certain (no edge within 1e-5).
fn leaf_hit(o: glam::DVec3, d: glam::DVec3) -> (u32, bool) {
    let at = |y: f64| o + (y - o.y) / d.y * d;
    let p = at(0.5);
    let near = |a: f64, b: f64| (a - b).abs() < 1e-5;
    let mut certain = ![p.x, p.z].iter().any(|&c| near(c.abs(), 1.0)) && !near(p.x, 0.0);
    if p.x > 0.0 && p.x < 1.0 && p.z.abs() < 1.0 {
        return (1, certain);
    }
    let q = at(0.0);
    certain &= !(near(q.x, -0.8) || near(q.x, -0.2) || near(q.z.abs(), 0.3));
    let tile = q.x > -0.8 && q.x < -0.2 && q.z.abs() < 0.3;
    (if tile { 2 } else { 0 }, certain)
}

/// With cut-outs, a camera ray that passes through the leaf's transparent
/// half counts as a miss for the alpha (unless it hits the tile below),
/// and hits are told apart by glTF node: the alpha's hit counts and the
/// per-object counts are exactly those of a brute-force count of the very
/// camera rays, in both engines; the legend names the nodes.
#[test]
fn alpha_and_object_ids_count_cut_outs_as_misses() {
    use wavetrace::integrator::sampler::{Sampler, Sobol};
    use wavetrace::scene::{Aov, AovSet, SamplerKind};
    let dir = TempDir::new("alpha-cutout");
    let scene = scene_of(&dir, "leaf.glb", &leaf_over_a_tile());
    assert_eq!(scene.objects.names, ["node 0", "node 1"]);
    let (n, spp, seed) = (32u32, 8u32, 11u64);
    let camera = scene.camera.for_resolution(n, n);
    let sampler = Sobol::new(seed);
    let mut want = vec![[0u64; 3]; (n * n) as usize];
    let mut certain = vec![true; (n * n) as usize];
    for y in 0..n {
        for x in 0..n {
            let i = (y * n + x) as usize;
            for s in 0..spp {
                let mut path = sampler.start(camera.pixel_index(x, y), s);
                let (o, d) = camera.pixel_ray(x, y, sampler.next_2d(&mut path));
                let (id, sure) = leaf_hit(o.as_dvec3(), d.as_dvec3());
                want[i][id as usize] += 1;
                certain[i] &= sure;
            }
        }
    }
    assert!(certain.iter().filter(|c| !**c).count() <= 2);
    // Not vacuous: rays through the cut-out, onto the tile, onto the leaf.
    let through = want.iter().filter(|w| w[0] == spp as u64).count();
    assert!(through > 50 && want.iter().any(|w| w[1] == spp as u64));
    assert!(want.iter().any(|w| w[2] == spp as u64));
    for engine in [Engine::Wavefront, Engine::Reference] {
        let mut s = settings(&scene, n, n, spp);
        (s.engine, s.seed, s.sampler) = (engine, seed, SamplerKind::Sobol);
        s.aovs = AovSet::of(&[Aov::Alpha, Aov::ObjectId]);
        let film = render(&scene, &s);
        for i in 0..(n * n) as usize {
            if !certain[i] {
                continue;
            }
            let w = want[i];
            assert_eq!(
                film.aov.counts(Aov::Alpha)[i],
                w[1] + w[2],
                "{engine:?} pixel {i}"
            );
            let counts: Vec<(u32, u64)> = [(1, w[1]), (2, w[2])]
                .into_iter()
                .filter(|c| c.1 > 0)
                .collect();
            assert_eq!(
                film.aov.votes(Aov::ObjectId)[i],
                counts,
                "{engine:?} pixel {i}"
            );
        }
    }
}

// ---------------------------------------------------------------------------
// KHR_materials_specular and KHR_materials_volume's attenuation

/// A box of side 1 of a smooth solid transmission material of index 1
/// (light goes straight through, nothing reflected), attenuation colour
/// `colour` over `distance` (`None`: no attenuation), seen end-on under
/// the default sky by a narrow camera on its axis.
fn absorbing_box(attenuation: Option<([f32; 3], f32)>) -> Vec<u8> {
    let mut g = Gltf::default();
    let volume = match attenuation {
        Some((c, d)) => format!(r#", "attenuationColor": {c:?}, "attenuationDistance": {d:?}"#),
        None => String::new(),
    };
    let extra: &'static str = Box::leak(
        format!(
            r#", "extensions": {{"KHR_materials_transmission": {{"transmissionFactor": 1.0}}, "KHR_materials_ior": {{"ior": 1.0}}, "KHR_materials_volume": {{"thicknessFactor": 1.0{volume}}}}}"#
        )
        .into_boxed_str(),
    );
    let m = g.material(Mat {
        roughness: 0.0,
        extra,
        ..Mat::default()
    });
    let cube = g.cube(1.0, m);
    g.node(cube, Vec3::ZERO, Quat::IDENTITY);
    g.camera(Vec3::new(0.0, 0.0, 5.0), Quat::IDENTITY, 0.01, 1.0);
    g.glb()
}

/// Beer–Lambert through a solid: a camera ray that crosses the box (1
/// long; the camera's rays are within 0.005 rad of its axis, so no longer
/// than 1 + 2·10⁻⁵) comes out attenuated by `colour^(1 / distance)` per
/// channel, in both engines, against the same box without attenuation.
#[test]
fn an_absorbing_solid_transmits_colour_to_the_power_of_length_over_distance() {
    let dir = TempDir::new("absorb");
    let (colour, distance) = ([0.5f32, 0.25, 0.8], 0.5f32);
    let clear = scene_of(&dir, "clear.glb", &absorbing_box(None));
    let dark = scene_of(&dir, "dark.glb", &absorbing_box(Some((colour, distance))));
    assert!(dark.materials[0].absorbs() && !clear.materials[0].absorbs());
    for engine in [Engine::Reference, Engine::Wavefront] {
        let film = |scene: &Scene| {
            let mut s = settings(scene, 8, 8, 4);
            s.engine = engine;
            render(scene, &s).to_rgb()
        };
        let (a, b) = (film(&clear), film(&dark));
        for (pa, pb) in a.iter().zip(&b) {
            for c in 0..3 {
                let want = (colour[c] as f64).powf(1.0 / distance as f64);
                let got = pb[c] as f64 / pa[c] as f64;
                assert!(
                    (got - want).abs() < 2e-4 * want,
                    "{engine:?}: channel {c}: transmittance {got}, Beer–Lambert {want}"
                );
            }
        }
        eprintln!(
            "{engine:?}: transmittance {:?} (clear {:?})",
            [0, 1, 2].map(|c| b[27][c] / a[27][c]),
            a[27]
        );
    }
}

/// A scene of both extensions: a floor whose specular strength (A) and
/// colour (RGB, sRGB) are textured, an opaque dielectric of tinted
/// specular, a rough solid of tinted specular that absorbs, a smooth
/// absorbing solid (glass), a thin pane of half specular, under a lamp.
fn specular_and_volume() -> Vec<u8> {
    let mut g = Gltf::default();
    let stripes: Vec<u8> = (0..8u32)
        .flat_map(|j| (0..8u32).map(move |i| (i, j)))
        .flat_map(|(i, j)| match (i + j) % 2 {
            0 => [255, 120, 40, 255],
            _ => [40, 200, 255, 30],
        })
        .collect();
    let stripes = g.texture(8, 8, stripes, 9728);
    let floor_ext: &'static str = Box::leak(
        format!(
            r#", "extensions": {{"KHR_materials_specular": {{"specularFactor": 0.9, "specularTexture": {{"index": {stripes}}}, "specularColorFactor": [2.0, 2.0, 2.0], "specularColorTexture": {{"index": {stripes}}}}}}}"#
        )
        .into_boxed_str(),
    );
    let floor = g.material(Mat {
        base: [0.6, 0.6, 0.6, 1.0],
        roughness: 0.3,
        extra: floor_ext,
        ..Mat::default()
    });
    let opaque = g.material(Mat {
        base: [0.2, 0.3, 0.8, 1.0],
        roughness: 0.25,
        extra: r#", "extensions": {"KHR_materials_specular": {"specularFactor": 0.7, "specularColorFactor": [1.0, 0.4, 8.0]}, "KHR_materials_ior": {"ior": 1.8}}"#,
        ..Mat::default()
    });
    let rough = g.material(Mat {
        base: [0.95, 0.95, 1.0, 1.0],
        roughness: 0.35,
        extra: r#", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationColor": [0.9, 0.5, 0.2], "attenuationDistance": 0.6}, "KHR_materials_specular": {"specularColorFactor": [1.0, 3.0, 1.0]}}"#,
        ..Mat::default()
    });
    let glass = g.material(Mat {
        roughness: 0.0,
        extra: r#", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationColor": [0.3, 0.8, 0.5], "attenuationDistance": 0.8}}"#,
        ..Mat::default()
    });
    let thin = g.material(Mat {
        base: [1.0, 0.9, 0.7, 1.0],
        roughness: 0.2,
        extra: r#", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.9}, "KHR_materials_specular": {"specularFactor": 0.5}}"#,
        ..Mat::default()
    });
    let lamp = g.material(Mat {
        base: [0.0, 0.0, 0.0, 1.0],
        emissive: [1.0, 1.0, 1.0],
        strength: 8.0,
        ..Mat::default()
    });
    let s = 2.5;
    let floor = g.quad(
        [
            Vec3::new(-s, 0.0, -s),
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
        ],
        [[0.0, 0.0], [0.0, 2.0], [2.0, 2.0], [2.0, 0.0]],
        floor,
    );
    g.node(floor, Vec3::ZERO, Quat::IDENTITY);
    for (m, side, at, turn) in [
        (opaque, 0.8, Vec3::new(-1.2, 0.4, -0.4), 0.3),
        (rough, 0.9, Vec3::new(0.0, 0.45, 0.0), -0.5),
        (glass, 0.8, Vec3::new(1.2, 0.4, -0.2), 0.7),
    ] {
        let cube = g.cube(side, m);
        g.node(cube, at, Quat::from_rotation_y(turn));
    }
    let h = 0.5;
    let pane = g.quad(
        [
            Vec3::new(-h, 0.0, 0.0),
            Vec3::new(h, 0.0, 0.0),
            Vec3::new(h, 2.0 * h, 0.0),
            Vec3::new(-h, 2.0 * h, 0.0),
        ],
        [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
        thin,
    );
    g.node(pane, Vec3::new(0.4, 0.0, 1.3), Quat::from_rotation_y(-0.3));
    let l = 0.9;
    let panel = g.quad(
        [
            Vec3::new(-l, 0.0, -l),
            Vec3::new(l, 0.0, -l),
            Vec3::new(l, 0.0, l),
            Vec3::new(-l, 0.0, l),
        ],
        [[0.0; 2]; 4],
        lamp,
    );
    g.node(panel, Vec3::new(0.0, 3.2, 0.3), Quat::IDENTITY);
    let eye = Vec3::new(0.0, 1.7, 4.4);
    let pitch = -((1.7f32 - 0.4) / 4.4).atan();
    g.camera(eye, Quat::from_rotation_x(pitch), 0.75, 4.0 / 3.0);
    g.glb()
}

/// The specular asset's materials are read as the extensions say.
#[test]
fn specular_and_attenuation_are_read_into_the_materials() {
    use wavetrace::scene::Model;
    let dir = TempDir::new("specular");
    let scene = scene_of(&dir, "specular.glb", &specular_and_volume());
    let m = |k: usize| &scene.materials[k];
    assert!(m(0).maps.specular.is_some() && m(0).maps.specular_colour.is_some());
    assert_eq!(
        (m(0).specular, m(0).specular_colour),
        (0.9, glam::Vec3::splat(2.0))
    );
    assert_eq!(
        (m(1).model, m(1).ior, m(1).specular),
        (Model::MetallicRoughness, 1.8, 0.7)
    );
    assert!(m(2).model == Model::Transmission && m(2).absorbs());
    assert_eq!(m(2).attenuation_distance, 0.6);
    assert!(m(3).model == Model::Glass && m(3).absorbs());
    assert!(m(4).thin && !m(4).absorbs() && m(4).specular == 0.5);
}

/// A specular texture of alpha 0 is a specular factor of 0, and a
/// specular colour texture is its decoded colour as a factor: the same
/// image, bit for bit, in both engines.
#[test]
fn specular_textures_multiply_their_factors() {
    let dir = TempDir::new("specular-textures");
    let quad = |ext: &str, texel: Option<[u8; 4]>| {
        let mut g = Gltf::default();
        let extra = match texel {
            Some(t) => {
                let tex = g.texture(2, 2, t.repeat(4), 9728);
                format!(
                    r#", "extensions": {{"KHR_materials_specular": {{{ext}, "specularTexture": {{"index": {tex}}}, "specularColorTexture": {{"index": {tex}}}}}}}"#
                )
            }
            None => format!(r#", "extensions": {{"KHR_materials_specular": {{{ext}}}}}"#),
        };
        let m = g.material(Mat {
            base: [0.5, 0.5, 0.5, 1.0],
            roughness: 0.3,
            extra: Box::leak(extra.into_boxed_str()),
            ..Mat::default()
        });
        let q = g.quad(
            [
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(-1.0, 1.0, 0.0),
            ],
            [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
            m,
        );
        g.node(q, Vec3::ZERO, Quat::from_rotation_x(-0.6));
        g.camera(Vec3::new(0.0, 0.0, 3.0), Quat::IDENTITY, 0.9, 1.0);
        g.glb()
    };
    // sRGB 188 decodes to 0.5029…; alpha 0 is a strength of 0.
    let decoded = wavetrace::scene::texture::srgb_to_linear(188.0 / 255.0) as f32;
    let factor =
        format!(r#""specularFactor": 0.0, "specularColorFactor": [{decoded:?}, 1.0, 1.0]"#);
    let textured = scene_of(
        &dir,
        "t.glb",
        &quad(r#""specularFactor": 1.0"#, Some([188, 255, 255, 0])),
    );
    let constant = scene_of(&dir, "c.glb", &quad(&factor, None));
    let strong = scene_of(&dir, "s.glb", &quad(r#""specularFactor": 1.0"#, None));
    for engine in [Engine::Reference, Engine::Wavefront] {
        let film = |scene: &Scene| {
            let mut s = settings(scene, 16, 16, 4);
            s.engine = engine;
            render(scene, &s).sums
        };
        let (a, b) = (film(&textured), film(&constant));
        assert!(
            a == b,
            "{engine:?}: the textured specular differs from its factors"
        );
        assert!(
            film(&strong) != a,
            "{engine:?}: specular makes no difference"
        );
    }
}

/// A volume's attenuation outside its range is refused naming its JSON
/// path: a colour beyond `[0, 1]`, a distance that is not positive.
#[test]
fn bad_attenuation_is_refused_with_its_json_path() {
    let dir = TempDir::new("bad-attenuation");
    for (volume, field) in [
        (r#""attenuationDistance": -1.0"#, "attenuationDistance"),
        (r#""attenuationDistance": 0.0"#, "attenuationDistance"),
        (r#""attenuationColor": [0.5, 1.5, 0.5]"#, "attenuationColor"),
    ] {
        let mut g = Gltf::default();
        let extra = format!(
            r#", "extensions": {{"KHR_materials_transmission": {{"transmissionFactor": 1.0}}, "KHR_materials_volume": {{"thicknessFactor": 1.0, {volume}}}}}"#
        );
        let m = g.material(Mat {
            extra: Box::leak(extra.into_boxed_str()),
            ..Mat::default()
        });
        let cube = g.cube(1.0, m);
        g.node(cube, Vec3::ZERO, Quat::IDENTITY);
        let path = dir.join("bad.glb");
        std::fs::write(&path, g.glb()).unwrap();
        let Err(e) = asset_scene::load(&path, None) else {
            panic!("{volume}: accepted");
        };
        let e = e.to_string();
        let want = format!("materials[0].extensions.KHR_materials_volume.{field}");
        assert!(e.contains(&want) && e.contains("bad.glb"), "{e}");
    }
}

/// The albedo AOV is the textured colour at the hit, not the material's
/// constant: on the checkerboard seen from above, 1 at the centres of the
/// white cells and 0 at the black ones, in both engines.
#[test]
fn the_albedo_aov_is_the_base_colour_texture_at_the_hit() {
    use wavetrace::scene::{Aov, AovSet};
    let dir = TempDir::new("checker-albedo");
    let scene = scene_of(&dir, "checker.glb", &checker_quad());
    let n = 64;
    let f = n as f32 / 2.0 / 30f32.to_radians().tan();
    for engine in [Engine::Wavefront, Engine::Reference] {
        let mut s = settings(&scene, n, n, 4);
        (s.engine, s.aovs) = (engine, AovSet::of(&[Aov::Albedo]));
        let film = render(&scene, &s);
        let albedo = &film.aov_images()[0].1;
        for j in 0..4 {
            for i in 0..4 {
                let x = -1.0 + (i as f32 + 0.5) / 2.0;
                let z = -1.0 + (j as f32 + 0.5) / 2.0;
                let (px, py) = (n as f32 / 2.0 + f * x / 2.0, n as f32 / 2.0 + f * z / 2.0);
                let a = albedo[(py as u32 * n + px as u32) as usize];
                let want = if (i + j) % 2 == 0 { 1.0 } else { 0.0 };
                assert_eq!(a, [want; 3], "{engine:?} cell ({i}, {j})");
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Any-hit through cut-outs

/// A stack of `layers` cut-out layers over an opaque floor, seen from
/// above: each layer a grid of `cells` × `cells` quads (x, z in [-1, 1]),
/// the even layers one mesh of alpha mode MASK, the odd ones one mesh of
/// BLEND (opacity 0.7), both textured by an 8 × 8 checker whose white
/// texels have alpha 0 (repeated twice across a layer, nearest); each mesh
/// placed by several nodes, at heights 0.25, 0.45, … and turned about the
/// vertical by 0.3 rad a layer, so that the checkers of the layers do not
/// line up.
fn cutout_stack(layers: usize, cells: usize) -> Vec<u8> {
    let mut g = Gltf::default();
    let tex = g.texture(
        8,
        8,
        checker(8, 8, 8, [255, 255, 255, 0], [60, 160, 60, 255]),
        9728,
    );
    let mask = g.material(Mat {
        base_texture: Some((tex, "")),
        extra: MASK,
        ..Mat::default()
    });
    let blend = g.material(Mat {
        base: [1.0, 1.0, 1.0, 0.7],
        base_texture: Some((tex, "")),
        extra: BLEND,
        ..Mat::default()
    });
    let floor = g.material(Mat {
        base: [0.8, 0.1, 0.1, 1.0],
        ..Mat::default()
    });
    let n = cells + 1;
    let mut positions = Vec::new();
    let mut uv = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (u, v) = (i as f32 / cells as f32, j as f32 / cells as f32);
            positions.push(Vec3::new(2.0 * u - 1.0, 0.0, 2.0 * v - 1.0));
            uv.push([2.0 * u, 2.0 * v]);
        }
    }
    let mut triangles = Vec::new();
    for j in 0..cells as u32 {
        for i in 0..cells as u32 {
            let k = j * n as u32 + i;
            let up = k + n as u32;
            triangles.extend([[k, up, up + 1], [k, up + 1, k + 1]]);
        }
    }
    let meshes = [mask, blend].map(|m| g.mesh(&positions, &uv, None, &triangles, m));
    for k in 0..layers {
        let turn = Quat::from_rotation_y(0.3 * k as f32);
        g.node(
            meshes[k % 2],
            Vec3::new(0.0, 0.25 + 0.2 * k as f32, 0.0),
            turn,
        );
    }
    let ground = g.quad(
        [
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
        ],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        floor,
    );
    g.node(ground, Vec3::ZERO, Quat::IDENTITY);
    let down = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    g.camera(Vec3::new(0.0, 4.0, 0.0), down, 50f32.to_radians(), 1.0);
    g.glb()
}

/// Random rays through the stack: origins in a box around it (between and
/// above its layers), directions uniform on the sphere; and an end for
/// each as a shadow ray, in (0, 3).
fn stack_rays(n: usize, seed: u64) -> Vec<(Vec3, Vec3, f32)> {
    let mut s = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut u = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..n)
        .map(|_| {
            let o = Vec3::new(3.0 * u() - 1.5, 3.0 * u(), 3.0 * u() - 1.5);
            let z = 2.0 * u() - 1.0;
            let phi = std::f32::consts::TAU * u();
            let r = (1.0 - z * z).max(0.0).sqrt();
            (o, Vec3::new(r * phi.cos(), z, r * phi.sin()), 3.0 * u())
        })
        .collect()
}

/// The closest hit on a surface that is there, as the engines found it
/// before the walk had a filter: the closest hit, then again from each
/// hit that lets the ray through.
fn retrace(bvh: &Bvh, tables: &Tables, (o, d): (Vec3, Vec3), t_max: f32) -> Option<Hit> {
    let ray = (V3::from(o), V3::from(d));
    let mut hit = bvh.closest_hit(o, d, 0.0, t_max);
    while let Some(h) = hit {
        if !tables.passes(h.triangle as usize, ray, h.t) {
            break;
        }
        hit = bvh.closest_hit(o, d, h.t, t_max);
    }
    hit
}

/// Every filtered query of `bvh` — one ray, columns, closest hit and
/// occlusion — against `want(ray, t_max)` for each of `rays`: the
/// closest hit that does not pass. Returns how many rays passed through
/// at least one cut-out before their hit.
fn check_filtered(
    bvh: &Bvh,
    tables: &Tables,
    rays: &[(Vec3, Vec3, f32)],
    want: impl Fn((Vec3, Vec3), f32) -> Option<Hit>,
    label: &str,
) -> usize {
    let n = rays.len();
    let col = |k: usize, axis: usize| -> Vec<f32> {
        let of = |r: &(Vec3, Vec3, f32)| if k == 0 { r.0 } else { r.1 };
        rays.iter().map(|r| of(r)[axis]).collect()
    };
    let o = [col(0, 0), col(0, 1), col(0, 2)];
    let d = [col(1, 0), col(1, 1), col(1, 2)];
    let cols = (o.each_ref().map(|c| &c[..]), d.each_ref().map(|c| &c[..]));
    let (mut t, mut prim) = (vec![0.0f32; n], vec![0u32; n]);
    bvh.closest_hits_columns_filtered(cols, (0.0, f32::INFINITY), (&mut t, &mut prim), |i| {
        tables.cutouts_of(cols, i)
    });
    let ends: Vec<f32> = rays.iter().map(|r| r.2).collect();
    let mut blocked = vec![false; n];
    bvh.occluded_columns_filtered(cols, (0.0, &ends), &mut blocked, |i| {
        tables.cutouts_of(cols, i)
    });
    let mut passed = 0;
    for (i, &(o, d, end)) in rays.iter().enumerate() {
        let filter = tables.cutouts((V3::from(o), V3::from(d)));
        let expect = want((o, d), f32::INFINITY);
        let one = bvh.closest_hit_filtered(o, d, (0.0, f32::INFINITY), &filter);
        let bits = |h: Option<Hit>| h.map(|h| (h.triangle, h.t.to_bits()));
        assert_eq!(
            bits(one),
            bits(expect),
            "{label}: ray {i} ({o}, {d}), one ray"
        );
        let column = (prim[i] != NO_PRIM).then_some(Hit {
            triangle: prim[i],
            t: t[i],
        });
        assert_eq!(bits(column), bits(expect), "{label}: ray {i}, in columns");
        let occluded = want((o, d), end).is_some();
        let one = bvh.occluded_filtered(o, d, (0.0, end), &filter);
        assert_eq!(one, occluded, "{label}: segment {i} to {end}, one ray");
        assert_eq!(
            blocked[i], occluded,
            "{label}: segment {i} to {end}, in columns"
        );
        passed += usize::from(bits(bvh.closest_hit(o, d, 0.0, f32::INFINITY)) != bits(expect));
    }
    passed
}

/// The walk's any-hit filter finds, for closest hits and shadow rays, one
/// ray at a time and in columns, at every SIMD width, the closest hit
/// that does not pass — what brute force over every triangle with the
/// same test finds, and what the engines' old loop (the closest hit, and
/// again beyond each one that passes) found, bit for bit — through a stack
/// of eight MASK and BLEND layers: in a small scene (the single-ray shape
/// of `small`), in one of 6,400 layer triangles (a tree walked in
/// interleaved batches), and two-level (each layer a placement).
#[test]
fn the_walk_passes_cut_outs_as_brute_force_and_the_old_loop_do() {
    let dir = TempDir::new("anyhit");
    for (cells, rays) in [(1, 20_000), (20, 6_000)] {
        let name = format!("stack-{cells}.glb");
        let scene = scene_of(&dir, &name, &cutout_stack(8, cells));
        let tables = Tables::new(&scene);
        assert!(tables.has_cutouts());
        let shapes = OwnedShapes::of_scene(&scene);
        let rays = stack_rays(rays, cells as u64);
        let brute = |(o, d): (Vec3, Vec3), end: f32| {
            let filter = tables.cutouts((V3::from(o), V3::from(d)));
            closest_hit_brute_force_filtered(&shapes.as_shapes(), o, d, (0.0, end), &filter)
        };
        for width in SimdWidth::available() {
            let options = BvhOptions { width };
            let flat = scene_bvh(&scene, &options);
            assert!(flat.two_level().is_none());
            if cells > 1 {
                // Big enough to walk in interleaved batches (256 KiB).
                assert!(flat.bytes() >= 256 << 10, "{} bytes", flat.bytes());
            }
            let label = format!("{name} flat at {width:?}");
            let passed = check_filtered(&flat, &tables, &rays, brute, &label);
            assert!(
                passed > rays.len() / 10,
                "{label}: {passed} rays passed a cut-out"
            );
            let old = |ray, end| retrace(&flat, &tables, ray, end);
            check_filtered(&flat, &tables, &rays, old, &format!("{label} (old loop)"));
            // Two-level: against the old loop over the same hierarchy (its
            // hits round as its transforms do, not as the flattened ones).
            let two = two_level_bvh(&scene, &options).expect("a two-level hierarchy");
            let label = format!("{name} two-level at {width:?}");
            let old = |ray, end| retrace(&two, &tables, ray, end);
            let passed = check_filtered(&two, &tables, &rays, old, &label);
            assert!(
                passed > rays.len() / 10,
                "{label}: {passed} rays passed a cut-out"
            );
        }
    }
}

/// The stack of cut-outs of the benchmark (`scenes/cutouts.glb`, twelve
/// layers of 16 × 16 cells) is what [`cutout_stack`] writes
/// (`WAVETRACE_WRITE_ASSET=1` rewrites it).
#[test]
fn the_shipped_cut_out_stack_is_what_this_test_writes() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cutouts.glb");
    let want = cutout_stack(12, 16);
    if std::env::var_os("WAVETRACE_WRITE_ASSET").is_some() {
        std::fs::write(&path, &want).unwrap();
    }
    let have = std::fs::read(&path).unwrap();
    assert!(
        have == want,
        "scenes/cutouts.glb differs from what tests/textured.rs writes \
         (WAVETRACE_WRITE_ASSET=1 cargo test --release --test textured rewrites it)"
    );
}
