//! The pinhole camera: where each camera ray starts and which way it goes.

use crate::math::{V3, Vec3x8};
use glam::Vec3;
use wide::f32x8;

/// A pinhole camera with an orthonormal frame.
///
/// The image-plane point `(u, v)` (pixels, `u` rightwards, `v` downwards,
/// pixel `(i, j)` covering `[i, i+1) × [j, j+1)`) maps to the direction
/// `normalize((u - W/2)·right + (v - H/2)·(-up) + f·forward)`, exactly the
/// DH2323 lab's `d = (x - W/2, y - H/2, f)` in its own frame.
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
    /// Focal length in pixels at the default resolution.
    pub focal_length_px: f32,
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
            width,
            height,
        })
    }

    /// The focal length that keeps the field of view at `vfov_deg` degrees
    /// for an image `height` pixels high.
    pub fn focal_from_vfov(vfov_deg: f32, height: u32) -> f32 {
        0.5 * height as f32 / (0.5 * vfov_deg.to_radians()).tan()
    }

    /// The camera set up for one render resolution.
    ///
    /// The field of view is the scene's: the focal length scales with the
    /// rendered height (the lab's `focalLength = SCREEN_HEIGHT` at any size).
    pub fn for_resolution(&self, width: u32, height: u32) -> RasterCamera {
        RasterCamera {
            position: self.position,
            forward: self.forward,
            down: -self.up,
            right: self.right,
            focal: self.focal_length_px * height as f32 / self.height as f32,
            width,
            half_width: width as f32 * 0.5,
            half_height: height as f32 * 0.5,
        }
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
    width: u32,
    half_width: f32,
    half_height: f32,
}

impl RasterCamera {
    /// The ray through image-plane point `(u, v)` in pixels:
    /// `(origin, unit direction)`.
    #[inline]
    pub fn ray(&self, u: f32, v: f32) -> (Vec3, Vec3) {
        let d = self.right * (u - self.half_width)
            + self.down * (v - self.half_height)
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
            u - f32x8::splat(self.half_width),
            v - f32x8::splat(self.half_height),
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
}
