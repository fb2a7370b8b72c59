//! Stage *generate*: camera rays for a batch of (pixel, sample) pairs.

use super::queue::PathQueue;
use crate::integrator::Frame;
use crate::integrator::sampler::Sampler;
use std::ops::Range;

/// Fill `queue` with the camera ray of every (pixel, sample) pair of the
/// batch: pixels `pixels` (row-major indices) times samples `samples`,
/// pixel-major. Each path starts its numbers; the first two place the ray
/// in its pixel — exactly as the reference does. AOV columns, if any,
/// start empty.
pub fn generate<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    sampler: &S,
    frame: &Frame,
    pixels: Range<u32>,
    samples: Range<u32>,
) {
    let n = pixels.len() * samples.len();
    queue.set_len(n);
    if let Some(aov) = &mut queue.aov {
        aov.reset(0..n);
    }
    let paths = pixels.flat_map(|p| samples.clone().map(move |s| (p, s)));
    for (i, (pixel, sample)) in paths.enumerate() {
        queue.pixel[i] = pixel;
        queue.sampler[i] = sampler.start(pixel, sample);
    }
    // Eight paths' numbers at a time, then their rays.
    for i in (0..n).step_by(8) {
        let lanes = (n - i).min(8);
        let [ux, uy] = sampler
            .next_2d_8(&mut queue.sampler[i..i + lanes])
            .map(|v| v.to_array());
        for l in 0..lanes {
            let pixel = queue.pixel[i + l];
            let (x, y) = (pixel % frame.width, pixel / frame.width);
            let (o, d) = frame.camera.pixel_ray(x, y, [ux[l], uy[l]]);
            queue.set_camera_ray(i + l, o.to_array(), d.to_array());
        }
    }
}
