//! The cameras of `wavetrace views`: where each view of an asset looks
//! from ([`poses`]), and how they are written for other tools — NeRF's
//! `transforms.json` (OpenGL axes, camera to world) and OpenCV's `K`, `R`,
//! `t` (world to camera). The conventions are in `docs/views.md`.

use crate::scene::camera::Camera;
use crate::scene::views_job::{CameraSet, ViewsJob};
use glam::Vec3;

/// One view's camera, in the job's world (normalised when the job asks),
/// at the job's resolution.
pub type Pose = Camera;

/// The similarity taking an asset's own coordinates to the job's world:
/// `p ↦ scale · (p − centre)` (identity unless the job normalises).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normalisation {
    /// Subtracted first.
    pub centre: Vec3,
    /// Then multiplied by.
    pub scale: f32,
}

impl Normalisation {
    /// The asset's coordinates of the job's world point `p`.
    pub fn to_asset(&self, p: Vec3) -> Vec3 {
        p / self.scale + self.centre
    }

    /// The renderer's camera for a view's pose: the same camera in the
    /// asset's own coordinates (the normalisation undone).
    pub fn camera(&self, pose: &Pose) -> Camera {
        Camera {
            position: self.to_asset(pose.position),
            ..pose.clone()
        }
    }
}

/// The normalisation of an asset with bounds `lo..hi`: centred on the
/// origin, its largest side 1 when `normalize`, else none.
pub fn normalisation(lo: Vec3, hi: Vec3, normalize: bool) -> Normalisation {
    if !normalize {
        return Normalisation {
            centre: Vec3::ZERO,
            scale: 1.0,
        };
    }
    let side = (hi - lo).max_element();
    Normalisation {
        centre: (lo + hi) * 0.5,
        scale: if side > 0.0 { 1.0 / side } else { 1.0 },
    }
}

/// The numbers `u` in `[0, 1)` of a view's seeded stream (splitmix64).
pub struct Stream(u64);

impl Stream {
    /// The stream of `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next number in `[0, 1)`: 24 random bits.
    pub fn uniform(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// The camera of every view of an asset whose bounds, in the job's world,
/// are `lo..hi`. `camera_seed(i)` seeds view `i`'s random camera.
pub fn poses(job: &ViewsJob, lo: Vec3, hi: Vec3, camera_seed: &dyn Fn(u32) -> u64) -> Vec<Pose> {
    let (w, h) = (job.render.width as f32, job.render.height as f32);
    let centre = (lo + hi) * 0.5;
    let target = job.target.unwrap_or(centre);
    let radius = (hi - lo).length() * 0.5 + (centre - target).length();
    let radius = radius.max(1e-4);
    // The distance at which the bounding sphere fits the narrower field of view.
    let framing = |vfov_deg: f32| {
        let half_v = (0.5 * vfov_deg).to_radians();
        let half_h = (half_v.tan() * w / h).atan();
        radius / half_v.min(half_h).sin() * 1.05
    };
    let size = (job.render.width, job.render.height);
    let focal = |vfov_deg: f32| Camera::focal_from_vfov(vfov_deg, job.render.height);
    let look =
        |dir: Vec3, distance: f32, vfov: f32| look_from(target, dir, distance, focal(vfov), size);
    match &job.cameras {
        CameraSet::Orbit {
            views,
            elevations_deg,
            azimuth_deg,
            distance,
            vfov_deg,
        } => {
            let d = distance.unwrap_or_else(|| framing(*vfov_deg));
            let mut out = Vec::new();
            for e in elevations_deg {
                for k in 0..*views {
                    let a = azimuth_deg + 360.0 * k as f32 / *views as f32;
                    out.push(look(direction(*e, a), d, *vfov_deg));
                }
            }
            out
        }
        CameraSet::Fibonacci {
            views,
            distance,
            vfov_deg,
        } => {
            let d = distance.unwrap_or_else(|| framing(*vfov_deg));
            let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
            (0..*views)
                .map(|i| {
                    let y = 1.0 - (2 * i + 1) as f32 / *views as f32;
                    let r = (1.0 - y * y).max(0.0).sqrt();
                    let phi = golden * i as f32;
                    look(Vec3::new(r * phi.sin(), y, r * phi.cos()), d, *vfov_deg)
                })
                .collect()
        }
        CameraSet::Random {
            views,
            distance,
            vfov_deg,
        } => (0..*views)
            .map(|i| {
                let mut u = Stream::new(camera_seed(i));
                let y = 1.0 - 2.0 * u.uniform();
                let r = (1.0 - y * y).max(0.0).sqrt();
                let phi = std::f32::consts::TAU * u.uniform();
                let vfov = lerp(*vfov_deg, u.uniform());
                let d = match distance {
                    Some(range) => lerp(*range, u.uniform()),
                    None => framing(vfov) * lerp([1.0, 1.5], u.uniform()),
                };
                look(Vec3::new(r * phi.sin(), y, r * phi.cos()), d, vfov)
            })
            .collect(),
        CameraSet::Explicit(cameras) => cameras
            .iter()
            .map(|c| {
                let m = &c.camera_to_world;
                let col = |j: usize| Vec3::new(m[0][j], m[1][j], m[2][j]);
                let k = &c.intrinsics;
                let fx = 0.5 * w / (0.5 * k.angle_x).tan();
                let [ox, oy] = k.principal_offset;
                let pose = oriented(col(3), -col(2), col(1), fx * k.focal_aspect_y, size);
                Camera {
                    focal_aspect: 1.0 / k.focal_aspect_y,
                    principal_offset_px: [ox * w, oy * h],
                    ..pose
                }
            })
            .collect(),
    }
}

fn lerp([a, b]: [f32; 2], t: f32) -> f32 {
    a + (b - a) * t
}

/// The unit direction from the target to a camera at elevation `e` and
/// azimuth `a` (degrees; azimuth 0 is +Z, 90 is +X).
pub fn direction(e: f32, a: f32) -> Vec3 {
    let (e, a) = (e.to_radians(), a.to_radians());
    Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
}

/// A camera `distance` from `target` in direction `dir`, looking at it,
/// +Y up (+Z where it looks straight up or down).
fn look_from(target: Vec3, dir: Vec3, distance: f32, focal: f32, size: (u32, u32)) -> Pose {
    let dir = dir.normalize();
    oriented(target + dir * distance, -dir, Vec3::Y, focal, size)
}

/// The pose at `position` looking along `forward` with up hint `up` (+Z
/// where `up` is along `forward`), square pixels, a centred axis.
fn oriented(position: Vec3, forward: Vec3, up: Vec3, focal: f32, (w, h): (u32, u32)) -> Pose {
    let up = if forward.normalize().cross(up).length() < 1e-3 {
        Vec3::Z
    } else {
        up
    };
    Camera::new(position, forward, up, focal, w, h).expect("a non-zero forward, not along up")
}

/// The text of an asset's `transforms.json` (NeRF / instant-ngp): the
/// intrinsics of the first view at the top (each frame repeats its own
/// when they differ), and a frame per view naming its colour file. `cx`,
/// `cy` are continuous pixel coordinates (`w/2, h/2` when centred).
pub fn transforms_json(poses: &[Pose], files: &[String]) -> String {
    use serde_json::json;
    let intrinsics = |c: &Camera| {
        let (fx, fy) = c.focal_xy();
        let (cx, cy) = c.principal_point();
        let (w, h) = (c.width as f32, c.height as f32);
        json!({
            "camera_angle_x": 2.0 * (0.5 * w / fx).atan(),
            "camera_angle_y": 2.0 * (0.5 * h / fy).atan(),
            "fl_x": fx,
            "fl_y": fy,
            "cx": cx,
            "cy": cy,
            "w": c.width,
            "h": c.height,
        })
    };
    let first = poses.first().map(intrinsics).unwrap_or_default();
    let mut top = first.clone();
    let frames: Vec<serde_json::Value> = poses
        .iter()
        .zip(files)
        .map(|(p, file)| {
            let mut f = json!({ "file_path": file, "transform_matrix": p.camera_to_world() });
            let own = intrinsics(p);
            if own != first
                && let (Some(f), Some(i)) = (f.as_object_mut(), own.as_object())
            {
                f.extend(i.clone());
            }
            f
        })
        .collect();
    top["frames"] = serde_json::Value::Array(frames);
    serde_json::to_string_pretty(&top).expect("JSON") + "\n"
}

/// The text of an asset's `cameras.json`: per view, OpenCV's `K`, `R`,
/// `t` (world to camera; x right, y down, z forward), with the image size.
pub fn opencv_json(poses: &[Pose], files: &[String]) -> String {
    use serde_json::json;
    let views: Vec<serde_json::Value> = poses
        .iter()
        .zip(files)
        .map(|(p, file)| {
            let (r, t) = p.opencv_rt();
            json!({ "file_path": file, "K": p.opencv_k(), "R": r, "t": t })
        })
        .collect();
    let (width, height) = poses.first().map_or((0, 0), |p| (p.width, p.height));
    let doc = json!({
        "convention": "OpenCV: world to camera x_cam = R x_world + t; camera x right, y down, z forward; pixel centres at integer coordinates",
        "width": width,
        "height": height,
        "views": views,
    });
    serde_json::to_string_pretty(&doc).expect("JSON") + "\n"
}
