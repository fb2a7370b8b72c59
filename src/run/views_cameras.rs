//! The cameras of `wavetrace views`: where each view of an asset looks
//! from ([`poses`]), and how they are written for other tools — NeRF's
//! `transforms.json` (OpenGL axes, camera to world) and OpenCV's `K`, `R`,
//! `t` (world to camera). The conventions are in `docs/views.md`.

use crate::scene::camera::Camera;
use crate::scene::views_job::{CameraSet, ViewsJob};
use glam::Vec3;

/// One view's camera, in the job's world (normalised when the job asks).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Centre of projection.
    pub position: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit up direction, orthogonal to `forward`.
    pub up: Vec3,
    /// Unit right direction, `forward × up`.
    pub right: Vec3,
    /// Focal length in pixels of the rendered image.
    pub focal: f32,
}

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
    let focal = |vfov_deg: f32| Camera::focal_from_vfov(vfov_deg, job.render.height);
    let look = |dir: Vec3, distance: f32, vfov: f32| look_from(target, dir, distance, focal(vfov));
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
                let focal = 0.5 * w / (0.5 * c.angle_x).tan();
                oriented(col(3), -col(2), col(1), focal)
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
fn look_from(target: Vec3, dir: Vec3, distance: f32, focal: f32) -> Pose {
    let dir = dir.normalize();
    oriented(target + dir * distance, -dir, Vec3::Y, focal)
}

/// The pose at `position` looking along `forward` with up hint `up`, made
/// orthonormal as [`Camera::new`] makes it (so the pose written is the one
/// rendered).
fn oriented(position: Vec3, forward: Vec3, up: Vec3, focal: f32) -> Pose {
    let up = if forward.normalize().cross(up).length() < 1e-3 {
        Vec3::Z
    } else {
        up
    };
    let c =
        Camera::new(position, forward, up, focal, 1, 1).expect("a non-zero forward, not along up");
    Pose {
        position,
        forward: c.forward,
        up: c.up,
        right: c.right,
        focal,
    }
}

impl Pose {
    /// The renderer's camera for this pose, in the asset's own
    /// coordinates (`n` undone), for a `width × height` image.
    pub fn camera(&self, n: &Normalisation, width: u32, height: u32) -> Camera {
        Camera {
            position: n.to_asset(self.position),
            forward: self.forward,
            up: self.up,
            right: self.right,
            focal_length_px: self.focal,
            width,
            height,
        }
    }

    /// Camera to world (rows), NeRF's and OpenGL's axes: the camera looks
    /// down its −Z, +Y is up, +X right.
    pub fn camera_to_world(&self) -> [[f32; 4]; 4] {
        let (r, u, b, p) = (self.right, self.up, -self.forward, self.position);
        [
            [r.x, u.x, b.x, p.x],
            [r.y, u.y, b.y, p.y],
            [r.z, u.z, b.z, p.z],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// OpenCV's world-to-camera rotation `R` (rows: x right, y down, z
    /// forward) and translation `t = −R·position`.
    pub fn opencv_rt(&self) -> ([[f32; 3]; 3], [f32; 3]) {
        let rows = [self.right, -self.up, self.forward];
        let t = rows.map(|row| -row.dot(self.position));
        (rows.map(|r| r.to_array()), t)
    }
}

/// OpenCV's intrinsics `K` of a view `width × height` pixels with focal
/// length `focal`: pixel centres at integer coordinates, so the principal
/// point is `((W − 1)/2, (H − 1)/2)`.
pub fn opencv_k(focal: f32, width: u32, height: u32) -> [[f32; 3]; 3] {
    [
        [focal, 0.0, 0.5 * width as f32 - 0.5],
        [0.0, focal, 0.5 * height as f32 - 0.5],
        [0.0, 0.0, 1.0],
    ]
}

/// The text of an asset's `transforms.json` (NeRF / instant-ngp): the
/// intrinsics of the first view at the top (each frame repeats its own
/// when they differ), and a frame per view naming its colour file.
pub fn transforms_json(poses: &[Pose], files: &[String], width: u32, height: u32) -> String {
    use serde_json::json;
    let (w, h) = (width as f32, height as f32);
    let intrinsics = |focal: f32| {
        json!({
            "camera_angle_x": 2.0 * (0.5 * w / focal).atan(),
            "camera_angle_y": 2.0 * (0.5 * h / focal).atan(),
            "fl_x": focal,
            "fl_y": focal,
            "cx": 0.5 * w,
            "cy": 0.5 * h,
            "w": width,
            "h": height,
        })
    };
    let first = poses.first().map_or(1.0, |p| p.focal);
    let mut top = intrinsics(first);
    let frames: Vec<serde_json::Value> = poses
        .iter()
        .zip(files)
        .map(|(p, file)| {
            let mut f = json!({ "file_path": file, "transform_matrix": p.camera_to_world() });
            if p.focal != first
                && let (Some(f), Some(i)) = (f.as_object_mut(), intrinsics(p.focal).as_object())
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
pub fn opencv_json(poses: &[Pose], files: &[String], width: u32, height: u32) -> String {
    use serde_json::json;
    let views: Vec<serde_json::Value> = poses
        .iter()
        .zip(files)
        .map(|(p, file)| {
            let (r, t) = p.opencv_rt();
            json!({ "file_path": file, "K": opencv_k(p.focal, width, height), "R": r, "t": t })
        })
        .collect();
    let doc = json!({
        "convention": "OpenCV: world to camera x_cam = R x_world + t; camera x right, y down, z forward; pixel centres at integer coordinates",
        "width": width,
        "height": height,
        "views": views,
    });
    serde_json::to_string_pretty(&doc).expect("JSON") + "\n"
}
