//! The pinhole camera: where each camera ray starts and which way it goes,
//! and how it is written for other tools (OpenGL/NeRF camera-to-world,
//! OpenCV `K`, `R`, `t`): the one place these conventions live.

use crate::math::{V3, Vec3x8};
use glam::Vec3;
use wide::f32x8;

/// A pinhole camera with an orthonormal frame.
///
/// The image-plane point `(u, v)` (pixels, `u` rightwards, `v` downwards,
/// pixel `(i, j)` covering `[i, i+1) × [j, j+1)`) maps to the direction
/// `normalize(((u - cx) / a)·right + (v - cy)·(-up) + f·forward)`, with the
/// principal point `(cx, cy) = (W/2, H/2) + principal_offset_px` and `a` the
/// focal aspect `fx / fy`. With the defaults (`a = 1`, no offset) this is
/// exactly the DH2323 lab's `d = (x - W/2, y - H/2, f)` in its own frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Centre of projection.
    pub position: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit up direction, orthogonal to `forward`.
    pub up: Vec3,
    /// Unit right direction, `forward × up`.
    pub right: Vec3,
    /// Vertical focal length `fy` in pixels at the default resolution.
    pub focal_length_px: f32,
    /// The horizontal focal length over the vertical one, `fx / fy`
    /// (1: square pixels).
    pub focal_aspect: f32,
    /// Where the optical axis meets the image, in pixels from the image's
    /// centre at the default resolution (+x right, +y down; zero: centred).
    pub principal_offset_px: [f32; 2],
    /// Default image width in pixels.
    pub width: u32,
    /// Default image height in pixels.
    pub height: u32,
}

impl Camera {
    /// A camera from a position, a viewing direction and an up hint.
    ///
    /// `up` is made orthogonal to `forward`; `right = forward × up`.
    /// Returns `None` when `forward` is zero or parallel to `up`.
    pub fn new(
        position: Vec3,
        forward: Vec3,
        up: Vec3,
        focal_length_px: f32,
        width: u32,
        height: u32,
    ) -> Option<Self> {
        let forward = forward.try_normalize()?;
        let right = forward.cross(up).try_normalize()?;
        let up = right.cross(forward).normalize();
        Some(Self {
            position,
            forward,
            up,
            right,
            focal_length_px,
            focal_aspect: 1.0,
            principal_offset_px: [0.0, 0.0],
            width,
            height,
        })
    }

    /// This camera with OpenCV-style intrinsics: focal lengths `fx`, `fy`
    /// and principal point `(cx, cy)` in pixels of its default resolution,
    /// pixel centres at integer coordinates (OpenCV's convention). `None`
    /// unless both focal lengths are positive and everything is finite.
    pub fn with_intrinsics(mut self, fx: f32, fy: f32, cx: f32, cy: f32) -> Option<Self> {
        let finite = [fx, fy, cx, cy].iter().all(|v| v.is_finite());
        if !finite || fx <= 0.0 || fy <= 0.0 {
            return None;
        }
        self.focal_length_px = fy;
        self.focal_aspect = fx / fy;
        self.principal_offset_px = [
            cx + 0.5 - 0.5 * self.width as f32,
            cy + 0.5 - 0.5 * self.height as f32,
        ];
        Some(self)
    }

    /// The focal length that keeps the field of view at `vfov_deg` degrees
    /// for an image `height` pixels high.
    pub fn focal_from_vfov(vfov_deg: f32, height: u32) -> f32 {
        0.5 * height as f32 / (0.5 * vfov_deg.to_radians()).tan()
    }

    /// This camera for another image size: the field of view is kept, the
    /// focal length and the principal point's offset scale with the height
    /// (the lab's `focalLength = SCREEN_HEIGHT` at any size).
    pub fn resized(&self, width: u32, height: u32) -> Camera {
        let scale = |v: f32| v * height as f32 / self.height as f32;
        Camera {
            focal_length_px: scale(self.focal_length_px),
            principal_offset_px: self.principal_offset_px.map(scale),
            width,
            height,
            ..self.clone()
        }
    }

    /// The camera set up for one render resolution (see [`Camera::resized`]).
    pub fn for_resolution(&self, width: u32, height: u32) -> RasterCamera {
        let c = self.resized(width, height);
        RasterCamera {
            position: c.position,
            forward: c.forward,
            down: -c.up,
            right: c.right,
            focal: c.focal_length_px,
            x_scale: 1.0 / c.focal_aspect,
            width,
            cx: width as f32 * 0.5 + c.principal_offset_px[0],
            cy: height as f32 * 0.5 + c.principal_offset_px[1],
        }
    }

    /// The horizontal and vertical focal lengths `(fx, fy)`, in pixels.
    pub fn focal_xy(&self) -> (f32, f32) {
        let fy = self.focal_length_px;
        (fy * self.focal_aspect, fy)
    }

    /// The principal point in continuous pixel coordinates (pixel `(i, j)`
    /// covers `[i, i+1) × [j, j+1)`): `(W/2, H/2)` unless offset.
    pub fn principal_point(&self) -> (f32, f32) {
        let [ox, oy] = self.principal_offset_px;
        (0.5 * self.width as f32 + ox, 0.5 * self.height as f32 + oy)
    }

    /// Camera to world (rows), the OpenGL / NeRF / Blender axes: the
    /// camera looks down its −Z, +Y is up, +X right.
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

    /// OpenCV's intrinsics `K` at the camera's own size: pixel centres at
    /// integer coordinates, so a centred principal point is
    /// `((W − 1)/2, (H − 1)/2)`.
    pub fn opencv_k(&self) -> [[f32; 3]; 3] {
        let (fx, fy) = self.focal_xy();
        let (cx, cy) = self.principal_point();
        [[fx, 0.0, cx - 0.5], [0.0, fy, cy - 0.5], [0.0, 0.0, 1.0]]
    }

    /// Where the world point `p` is seen in the camera's image, in
    /// continuous pixel coordinates (pixel `(i, j)` covers
    /// `[i, i+1) × [j, j+1)`, row 0 at the top); `None` behind the camera.
    pub fn project(&self, p: Vec3) -> Option<[f64; 2]> {
        let d = p - self.position;
        let z = d.dot(self.forward) as f64;
        if z <= 0.0 || !z.is_finite() {
            return None;
        }
        let (fx, fy) = self.focal_xy();
        let (cx, cy) = self.principal_point();
        Some([
            cx as f64 + fx as f64 * d.dot(self.right) as f64 / z,
            cy as f64 - fy as f64 * d.dot(self.up) as f64 / z,
        ])
    }
}

/// A camera fixed to one image size: turns image-plane points into rays.
#[derive(Clone, Copy, Debug)]
pub struct RasterCamera {
    position: Vec3,
    forward: Vec3,
    down: Vec3,
    right: Vec3,
    focal: f32,
    /// `1 / (fx / fy)`: 1 for square pixels (an exact no-op then).
    x_scale: f32,
    width: u32,
    cx: f32,
    cy: f32,
}

impl RasterCamera {
    /// The ray through image-plane point `(u, v)` in pixels:
    /// `(origin, unit direction)`.
    #[inline]
    pub fn ray(&self, u: f32, v: f32) -> (Vec3, Vec3) {
        let d = self.right * ((u - self.cx) * self.x_scale)
            + self.down * (v - self.cy)
            + self.forward * self.focal;
        (self.position, d.normalize())
    }

    /// [`RasterCamera::ray`] for eight image-plane points at once (one per
    /// lane): the directions, each lane the same IEEE operations in the
    /// same order as `ray`'s (so the same bits); the origin is
    /// [`RasterCamera::position`].
    #[inline]
    pub fn directions_8(&self, u: f32x8, v: f32x8) -> Vec3x8 {
        let s = (
            (u - f32x8::splat(self.cx)) * f32x8::splat(self.x_scale),
            v - f32x8::splat(self.cy),
        );
        let axis = |r: f32, d: f32, f: f32| {
            f32x8::splat(r) * s.0 + f32x8::splat(d) * s.1 + f32x8::splat(f * self.focal)
        };
        let d = V3::new(
            axis(self.right.x, self.down.x, self.forward.x),
            axis(self.right.y, self.down.y, self.forward.y),
            axis(self.right.z, self.down.z, self.forward.z),
        );
        // glam's `normalize`: `d * (1 / sqrt((x·x + y·y) + z·z))`.
        let len = (d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
        let recip = f32x8::ONE / len;
        V3::new(d.x * recip, d.y * recip, d.z * recip)
    }

    /// The unit direction the camera looks along (the image centre's ray).
    #[inline]
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// The centre of projection: every camera ray's origin.
    #[inline]
    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// The row-major index of pixel `(x, y)`, which keys its random streams.
    #[inline]
    pub fn pixel_index(&self, x: u32, y: u32) -> u32 {
        y * self.width + x
    }

    /// The camera ray of one sample of pixel `(x, y)`, at the point
    /// `u = [u_x, u_y]` (two numbers in `[0, 1)`) of the pixel's area.
    #[inline]
    pub fn pixel_ray(&self, x: u32, y: u32, u: [f32; 2]) -> (Vec3, Vec3) {
        self.ray(x as f32 + u[0], y as f32 + u[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eight lanes at once give each lane the very bits `ray` gives it,
    /// for the built-in camera at several sizes and a tilted one, over
    /// points across (and past) the image.
    #[test]
    fn eight_directions_are_eight_rays() {
        let tilted = Camera::new(
            Vec3::new(0.3, -0.2, -2.0),
            Vec3::new(0.1, 0.2, 1.0),
            Vec3::new(0.0, -1.0, 0.3),
            300.0,
            300,
            200,
        )
        .expect("a valid camera");
        let cameras = [
            crate::scene::Scene::cornell()
                .camera
                .for_resolution(256, 256),
            crate::scene::Scene::cornell()
                .camera
                .for_resolution(253, 131),
            tilted.for_resolution(300, 200),
            tilted
                .clone()
                .with_intrinsics(310.0, 290.0, 140.3, 92.7)
                .expect("valid intrinsics")
                .for_resolution(300, 200),
        ];
        let mut x = 0x9e37_79b9u32;
        let mut u = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x >> 8) as f32 / (1 << 24) as f32
        };
        for cam in &cameras {
            for _ in 0..2000 {
                let p: [[f32; 2]; 8] =
                    std::array::from_fn(|_| [400.0 * u() - 50.0, 300.0 * u() - 50.0]);
                let d =
                    cam.directions_8(f32x8::from(p.map(|q| q[0])), f32x8::from(p.map(|q| q[1])));
                let lanes = [d.x, d.y, d.z].map(|c| c.to_array());
                for (l, q) in p.iter().enumerate() {
                    let (o, want) = cam.ray(q[0], q[1]);
                    assert_eq!(o, cam.position());
                    let got = [lanes[0][l], lanes[1][l], lanes[2][l]];
                    assert_eq!(
                        got.map(f32::to_bits),
                        want.to_array().map(f32::to_bits),
                        "{q:?}"
                    );
                }
            }
        }
    }

    /// A camera with its own intrinsics, at its own size and resized:
    /// the ray through `(u, v)` projects back to `(u, v)`; `K (R p + t)`
    /// is that pixel minus ½ (OpenCV's integer pixel centres); the
    /// camera-to-world matrix's columns are right, up, backward, position.
    #[test]
    fn rays_project_back_and_files_agree() {
        let base = Camera::new(
            Vec3::new(0.3, -0.2, -2.0),
            Vec3::new(0.1, 0.2, 1.0),
            Vec3::new(0.0, 1.0, 0.3),
            300.0,
            300,
            200,
        )
        .expect("a valid camera");
        let k = base
            .clone()
            .with_intrinsics(330.0, 280.0, 160.25, 90.5)
            .expect("valid intrinsics");
        for cam in [base, k.clone(), k.resized(150, 100), k.resized(450, 300)] {
            let raster = cam.for_resolution(cam.width, cam.height);
            let (kk, (r, t)) = (cam.opencv_k(), cam.opencv_rt());
            let m = cam.camera_to_world();
            for (u, v) in [(0.5, 0.5), (17.25, 80.0), (120.0, 33.5), (149.9, 99.9)] {
                let (o, d) = raster.ray(u, v);
                let p = o + d * 3.7;
                let got = cam.project(p).expect("in front");
                assert!(
                    (got[0] - u as f64).abs() < 2e-3 && (got[1] - v as f64).abs() < 2e-3,
                    "{cam:?}: ray through ({u}, {v}) projects to {got:?}"
                );
                let c: [f32; 3] = std::array::from_fn(|i| Vec3::from(r[i]).dot(p) + t[i]);
                let px = [0, 1].map(|i| (kk[i][0] * c[0] + kk[i][1] * c[1]) / c[2] + kk[i][2]);
                assert!(
                    (px[0] + 0.5 - u).abs() < 2e-3 && (px[1] + 0.5 - v).abs() < 2e-3,
                    "K R t put ({u}, {v}) at {px:?}"
                );
                // The matrix takes the camera-frame point (OpenGL axes) back.
                let g = [c[0], -c[1], -c[2], 1.0];
                let w: [f32; 3] =
                    std::array::from_fn(|i| (0..4).map(|j| m[i][j] * g[j]).sum::<f32>());
                assert!((Vec3::from(w) - p).length() < 1e-4, "{w:?} vs {p}");
            }
        }
    }
}
