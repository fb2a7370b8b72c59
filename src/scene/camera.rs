//! The pinhole camera: where each camera ray starts and which way it goes.

use glam::Vec3;

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
