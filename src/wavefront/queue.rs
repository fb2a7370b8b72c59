//! The ray queue: every live path's state, one plain column per field.

use crate::sampling::PathRng;

/// Marks a ray that hit nothing in [`PathQueue::hit`].
pub const MISS: u32 = u32::MAX;

/// The state of a batch of paths in structure-of-arrays form.
///
/// Row `i` of every column belongs to path `i`. The intersect stage fills
/// `t` and `hit`; the other columns are the path's state between bounces.
#[derive(Clone, Debug, Default)]
pub struct PathQueue {
    /// Pixel index (row-major) the path's sample belongs to.
    pub pixel: Vec<u32>,
    /// The path's random stream.
    pub rng: Vec<PathRng>,
    /// Ray origin, x/y/z columns.
    pub o: [Vec<f32>; 3],
    /// Unit ray direction, x/y/z columns.
    pub d: [Vec<f32>; 3],
    /// Throughput: the product of `brdf · cos θ / pdf` along the path, RGB.
    pub beta: [Vec<f32>; 3],
    /// Radiance gathered so far, RGB.
    pub radiance: [Vec<f32>; 3],
    /// Distance to the closest hit (intersect stage output).
    pub t: Vec<f32>,
    /// Triangle hit, or [`MISS`] (intersect stage output).
    pub hit: Vec<u32>,
}

impl PathQueue {
    /// An empty queue with room for `n` paths.
    pub fn with_capacity(n: usize) -> Self {
        let col = || Vec::<f32>::with_capacity(n);
        Self {
            pixel: Vec::with_capacity(n),
            rng: Vec::with_capacity(n),
            o: [col(), col(), col()],
            d: [col(), col(), col()],
            beta: [col(), col(), col()],
            radiance: [col(), col(), col()],
            t: col(),
            hit: Vec::with_capacity(n),
        }
    }

    /// Number of paths.
    pub fn len(&self) -> usize {
        self.pixel.len()
    }

    /// Whether the queue holds no path.
    pub fn is_empty(&self) -> bool {
        self.pixel.is_empty()
    }

    /// Remove every path, keeping the memory.
    pub fn clear(&mut self) {
        self.pixel.clear();
        self.rng.clear();
        for c in self
            .o
            .iter_mut()
            .chain(&mut self.d)
            .chain(&mut self.beta)
            .chain(&mut self.radiance)
        {
            c.clear();
        }
        self.t.clear();
        self.hit.clear();
    }

    /// Append a new path: a ray with throughput 1 and no radiance yet.
    #[inline]
    pub fn push_camera_ray(&mut self, pixel: u32, rng: PathRng, o: [f32; 3], d: [f32; 3]) {
        self.pixel.push(pixel);
        self.rng.push(rng);
        for c in 0..3 {
            self.o[c].push(o[c]);
            self.d[c].push(d[c]);
            self.beta[c].push(1.0);
            self.radiance[c].push(0.0);
        }
    }

    /// The radiance gathered by path `i`.
    #[inline]
    pub fn radiance_of(&self, i: usize) -> glam::Vec3 {
        glam::Vec3::new(
            self.radiance[0][i],
            self.radiance[1][i],
            self.radiance[2][i],
        )
    }
}
