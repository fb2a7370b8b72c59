//! Stage *generate*: camera rays for a batch of (pixel, sample) pairs.

use super::Ctx;
use super::queue::{PathQueue, store3};
use crate::integrator::Frame;
use crate::integrator::sampler::Sampler;
use std::ops::Range;
use wide::f32x8;

/// Fill `queue` with the camera ray of every (pixel, sample) pair of the
/// batch: pixels `pixels` (row-major indices, ascending) times samples `samples`,
/// pixel-major. Each path starts its numbers; the first two place the ray
/// in its pixel — exactly as the reference does. AOV columns, if any,
/// start empty.
pub fn generate<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    ctx: &Ctx<S>,
    frame: &Frame,
    pixels: &[u32],
    samples: Range<u32>,
) {
    camera_rays(queue, ctx.sampler, frame, (pixels, samples));
}

/// [`generate`]'s work, with the sampler as an argument of its own (a
/// reference argument tells the compiler that nothing the loop writes
/// changes it, which a field of [`Ctx`] does not).
fn camera_rays<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    sampler: &S,
    frame: &Frame,
    (pixels, samples): (&[u32], Range<u32>),
) {
    let n = pixels.len() * samples.len();
    queue.set_len(n);
    if let Some(aov) = &mut queue.aov {
        aov.reset(0..n);
    }
    queue.start_paths();
    if n == 0 {
        return;
    }
    let (pixel_col, sampler_col) = (&mut queue.pixel[..n], &mut queue.sampler[..n]);
    // A pixel's rows, one per sample (a plain loop per pixel: each row's
    // hash is independent of the others', so they overlap).
    let rows = pixel_col
        .chunks_mut(samples.len())
        .zip(sampler_col.chunks_mut(samples.len()));
    for (&pixel, (p, s)) in pixels.iter().zip(rows) {
        p.fill(pixel);
        for (s, sample) in s.iter_mut().zip(samples.clone()) {
            *s = sampler.start(pixel, sample);
        }
    }
    // Eight paths' numbers at a time, then their rays, eight at a time:
    // the point `(x + u_x, y + u_y)` of each one's pixel.
    let camera = &frame.camera;
    let o = camera.position();
    for i in (0..n).step_by(8) {
        let lanes = (n - i).min(8);
        let [ux, uy] = sampler.next_2d_8(&mut sampler_col[i..i + lanes]);
        // The group's pixels ascend from its first: one division for the
        // group, then steps along the rows (a pixel skipped by adaptive
        // sampling may leave a gap of a row or more: then its own division).
        let first = pixel_col[i];
        let (x0, y0) = (first % frame.width, first / frame.width);
        let xy = |l: usize| {
            let p = pixel_col[i + l.min(lanes - 1)];
            let (mut x, mut y) = (x0 + (p - first), y0);
            if x >= 2 * frame.width {
                (x, y) = (p % frame.width, p / frame.width);
            }
            while x >= frame.width {
                (x, y) = (x - frame.width, y + 1);
            }
            [x as f32, y as f32]
        };
        let xy: [[f32; 2]; 8] = std::array::from_fn(xy);
        let (x, y) = (xy.map(|p| p[0]), xy.map(|p| p[1]));
        let d = camera.directions_8(f32x8::from(x) + ux, f32x8::from(y) + uy);
        store3(&mut queue.d, i, d, lanes);
        for (col, v) in queue.o.iter_mut().zip(o.to_array()) {
            col[i..i + lanes].fill(v);
        }
    }
}
