//! Where rays leave surfaces (`wavetrace::integrator::offset`): no ray
//! finds the surface it leaves, at any scale; and geometry far away never
//! changes the image of geometry near by.

use glam::Vec3;
use wavetrace::accel::sphere::{hit_normal, intersect_sphere};
use wavetrace::accel::triangle::{TriangleEdges, V3Tri, hit_point, moller_trumbore};
use wavetrace::film::Film;
use wavetrace::integrator::offset::{error_bound, spawn};
use wavetrace::integrator::sampler::PathRng;
use wavetrace::math::V3;
use wavetrace::metrics::ImageErrors;
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::options::Integrator;
use wavetrace::scene::{CORNELL_TOML, Scene};

/// Random numbers for the fuzzing below.
struct Rng(PathRng);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(PathRng::new(seed, 0, 0))
    }
    fn u(&mut self) -> f32 {
        self.0.next_f32()
    }
    /// `10^x`, `x` uniform in `[lo, hi)`.
    fn magnitude(&mut self, lo: f32, hi: f32) -> f32 {
        10f32.powf(lo + (hi - lo) * self.u())
    }
    /// A uniform unit direction.
    fn dir(&mut self) -> Vec3 {
        let z = 1.0 - 2.0 * self.u();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * self.u();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// Rays that leave a triangle from a hit on it, in every direction, never
/// find it again: triangles from 10⁻³ to 10⁶ across, centered up to 10⁶
/// from the origin, a quarter of them slivers (one vertex 10⁻³ of the
/// size from the opposite edge), hit from up to 10⁶ away.
#[test]
fn no_ray_finds_the_triangle_it_leaves() {
    let mut r = Rng::new(1);
    let (mut cases, mut found) = (0, 0);
    for _ in 0..200_000 {
        let c = r.dir() * r.magnitude(-2.0, 6.0);
        let size = r.magnitude(-3.0, 6.0);
        let mut v = [c + r.dir() * size, c + r.dir() * size, c + r.dir() * size];
        if r.u() < 0.25 {
            let mid = v[0].lerp(v[1], r.u());
            v[2] = mid + (v[2] - mid) * 1e-3;
        }
        let tri = TriangleEdges::new(v[0], v[1], v[2]);
        let Some(n) = tri.n.try_normalize() else {
            continue;
        };
        let o = c + r.dir() * r.magnitude(-3.0, 6.0);
        let (b1, b2) = (r.u(), r.u());
        let (b1, b2) = if b1 + b2 > 1.0 {
            (1.0 - b1, 1.0 - b2)
        } else {
            (b1, b2)
        };
        let d = (v[0] + tri.e1 * b1 + tri.e2 * b2 - o).normalize();
        let packed = V3Tri::from(&tri);
        let (inside, t) = moller_trumbore(V3::from(o), V3::from(d), &packed, 0.0);
        if !inside {
            continue;
        }
        let p = hit_point(V3::from(o), V3::from(d), t);
        let scale = v.iter().map(|v| v.abs().max_element()).fold(0.0, f32::max);
        let err = error_bound(V3::from(o), p, scale);
        for _ in 0..4 {
            let w = V3::from(r.dir());
            let from = spawn(p, V3::from(n), w, err);
            cases += 1;
            found += moller_trumbore(from, w, &packed, 0.0).0 as u32;
        }
    }
    assert!(cases > 500_000, "{cases} cases");
    assert_eq!(
        found, 0,
        "of {cases} rays, {found} found the triangle they left"
    );
}

/// Rays that leave a sphere from a hit on it never find it again near
/// where they left (those that go in find its far side, at about the
/// chord's length): spheres of radius 10⁻³ to 10⁶, centered up to 10⁶
/// from the origin, hit from inside and outside.
#[test]
fn no_ray_finds_the_sphere_it_leaves() {
    let mut r = Rng::new(2);
    let (mut cases, mut found) = (0, 0);
    for _ in 0..200_000 {
        let c = r.dir() * r.magnitude(-2.0, 6.0);
        let radius = r.magnitude(-3.0, 6.0);
        let o = c + r.dir() * radius * r.magnitude(-1.0, 3.0);
        let d = (c + r.dir() * radius - o).normalize();
        let (cv, rv) = (V3::from(c), radius);
        let (hit, t) = intersect_sphere(V3::from(o), V3::from(d), cv, rv, 0.0);
        if !hit {
            continue;
        }
        let p = hit_point(V3::from(o), V3::from(d), t);
        let n = hit_normal(V3::from(o), V3::from(d), t, cv);
        let err = error_bound(V3::from(o), p, c.abs().max_element() + radius);
        for _ in 0..4 {
            let w = r.dir();
            let from = spawn(p, n, V3::from(w), err);
            // Going in, the far side is a chord of 2r·cos away.
            let chord = -2.0 * radius * Vec3::from(n).dot(w);
            if chord > 0.0 && chord < 1e3 * err {
                continue; // grazing: the far side is within the error
            }
            cases += 1;
            let (hit, t) = intersect_sphere(from, V3::from(w), cv, rv, 0.0);
            found += (hit && t < 0.5 * chord.max(0.0) + err) as u32;
        }
    }
    assert!(cases > 500_000, "{cases} cases");
    assert_eq!(
        found, 0,
        "of {cases} rays, {found} found the sphere they left"
    );
}

/// The Cornell box with `extra` (scene-file text) added, and a black
/// material `far` for it.
fn cornell_with(extra: &str) -> Scene {
    let text = format!("{CORNELL_TOML}\n[materials.far]\nreflectance = [0.0, 0.0, 0.0]\n{extra}");
    wavetrace::scene::file::parse(&text, "far.toml").unwrap()
}

fn render(scene: &Scene, engine: Engine, integrator: Integrator) -> Film {
    let mut s = RenderSettings::for_scene(scene);
    (s.width, s.height, s.spp, s.seed) = (32, 32, 8, 5);
    (s.engine, s.integrator) = (engine, integrator);
    Renderer::new(scene, &s).unwrap().render().0
}

/// Far geometry changes nothing near by: the Cornell box with a tiny
/// triangle 10⁴ or 10⁵ away, or inside a sphere of radius 10⁵ (both
/// black: nothing they do can add light) renders the plain box's image,
/// bit for bit — the paths in the box are the same paths, and those that
/// leave it add nothing either way. (With the scene-wide offset
/// `10⁻⁴ × the largest coordinate` these were black, or lost a third of
/// their light.) Both engines, every integrator.
#[test]
fn far_geometry_leaves_the_cornell_box_image_as_it_is() {
    let tiny = |x: f32| {
        format!(
            "[[triangle]]\nmaterial = \"far\"\nvertices = [[{x}, 0.0, 0.0], [{x}, 0.001, 0.0], [{x}, 0.0, 0.001]]\n"
        )
    };
    let sphere = "[[sphere]]\nmaterial = \"far\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1e5\n";
    let plain = Scene::cornell();
    for integrator in [Integrator::Report, Integrator::Bsdf, Integrator::Nee] {
        for engine in [Engine::Reference, Engine::Wavefront] {
            let want = render(&plain, engine, integrator);
            let mean = want.to_rgb().iter().flatten().sum::<f32>() / (32.0 * 32.0 * 3.0);
            assert!(mean > 0.05, "the plain box is lit: mean {mean}");
            for extra in [tiny(1e4), tiny(1e5), sphere.to_string(), tiny(1e5) + sphere] {
                let got = render(&cornell_with(&extra), engine, integrator);
                let e = ImageErrors::of(&got.to_rgb(), &want.to_rgb());
                assert!(
                    got.sums == want.sums,
                    "{engine:?} {integrator:?} with {extra}: relMSE {} against the plain box",
                    e.relmse
                );
            }
        }
    }
}
