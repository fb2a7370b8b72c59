//! The ray queue: every live path's state, one plain column per field.

use crate::integrator::sampler::PathRng;
use wide::f32x8;

// Every column's element type is plain old data.
const _: fn() = || {
    fn pod<T: bytemuck::Pod>() {}
    pod::<u32>();
    pod::<f32>();
    pod::<PathRng>();
};

/// Marks a ray that hit nothing in [`PathQueue::hit`].
pub const MISS: u32 = u32::MAX;

/// The state of a batch of paths in structure-of-arrays form.
///
/// Every column is plain old data (`bytemuck::Pod`): numbers, and the
/// random streams as their two words.
///
/// Row `i < len()` of every column belongs to path `i`. Columns are
/// allocated once, for the batch size rounded up to a multiple of 8, so the
/// stages can load and store 8 rows at a time. The intersect stage fills
/// `t` and `hit`; the other columns are the path's state between bounces.
#[derive(Clone, Debug)]
pub struct PathQueue {
    len: usize,
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
        let rows = n.div_ceil(8) * 8;
        let col = || vec![0.0f32; rows];
        Self {
            len: 0,
            pixel: vec![0; rows],
            rng: vec![PathRng::new(0, 0, 0); rows],
            o: [col(), col(), col()],
            d: [col(), col(), col()],
            beta: [col(), col(), col()],
            radiance: [col(), col(), col()],
            t: col(),
            hit: vec![MISS; rows],
        }
    }

    /// Room in rows.
    pub fn capacity(&self) -> usize {
        self.pixel.len()
    }

    /// Number of paths.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the queue holds no path.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Set the number of paths (rows past it are free).
    pub fn set_len(&mut self, len: usize) {
        assert!(len <= self.capacity());
        self.len = len;
    }

    /// Mutable views of rows `0..n` of the columns a new path sets.
    pub fn rows_mut(&mut self, n: usize) -> impl Iterator<Item = NewPath<'_>> {
        let [ox, oy, oz] = &mut self.o;
        let [dx, dy, dz] = &mut self.d;
        let [br, bg, bb] = &mut self.beta;
        let [lr, lg, lb] = &mut self.radiance;
        fn f(c: &mut [f32], n: usize) -> std::slice::IterMut<'_, f32> {
            c[..n].iter_mut()
        }
        // Zipped column iterators: no per-row bounds checks.
        self.pixel[..n]
            .iter_mut()
            .zip(self.rng[..n].iter_mut())
            .zip(f(ox, n).zip(f(oy, n)).zip(f(oz, n)))
            .zip(f(dx, n).zip(f(dy, n)).zip(f(dz, n)))
            .zip(f(br, n).zip(f(bg, n)).zip(f(bb, n)))
            .zip(f(lr, n).zip(f(lg, n)).zip(f(lb, n)))
            .map(
                |(
                    ((((pixel, rng), ((ox, oy), oz)), ((dx, dy), dz)), ((br, bg), bb)),
                    ((lr, lg), lb),
                )| NewPath {
                    pixel,
                    rng,
                    o: [ox, oy, oz],
                    d: [dx, dy, dz],
                    beta: [br, bg, bb],
                    radiance: [lr, lg, lb],
                },
            )
    }

    /// Copy path `from` into row `to` (the intersect outputs too).
    #[inline]
    pub fn move_row(&mut self, from: usize, to: usize) {
        self.pixel[to] = self.pixel[from];
        self.rng[to] = self.rng[from];
        for cols in [&mut self.o, &mut self.d, &mut self.beta, &mut self.radiance] {
            for col in cols.iter_mut() {
                col[to] = col[from];
            }
        }
        self.t[to] = self.t[from];
        self.hit[to] = self.hit[from];
    }
}

/// Rows `i..i + 8` of a column (in bounds: columns are multiples of 8).
#[inline(always)]
pub fn load8(col: &[f32], i: usize) -> f32x8 {
    let rows: [f32; 8] = col[i..i + 8].try_into().expect("8 rows");
    f32x8::from(rows)
}

/// Store `v` in rows `i..i + 8` of a column.
#[inline(always)]
pub fn store8(col: &mut [f32], i: usize, v: f32x8) {
    col[i..i + 8].copy_from_slice(&v.to_array());
}

/// One row of a [`PathQueue`], as the generate stage writes it.
pub struct NewPath<'a> {
    pixel: &'a mut u32,
    rng: &'a mut PathRng,
    o: [&'a mut f32; 3],
    d: [&'a mut f32; 3],
    beta: [&'a mut f32; 3],
    radiance: [&'a mut f32; 3],
}

impl NewPath<'_> {
    /// A camera ray: throughput 1, no radiance yet.
    #[inline(always)]
    pub fn set_camera_ray(self, pixel: u32, rng: PathRng, o: [f32; 3], d: [f32; 3]) {
        *self.pixel = pixel;
        *self.rng = rng;
        for c in 0..3 {
            *self.o[c] = o[c];
            *self.d[c] = d[c];
            *self.beta[c] = 1.0;
            *self.radiance[c] = 0.0;
        }
    }
}
