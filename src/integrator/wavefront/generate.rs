//! Stage *generate*: camera rays for a batch of (pixel, sample) pairs.

use super::queue::PathQueue;
use crate::integrator::Frame;
use crate::integrator::sampler::Sampler;
use std::ops::Range;

/// Fill `queue` with the camera ray of every (pixel, sample) pair of the
/// batch: pixels `pixels` (row-major indices) times samples `samples`,
/// pixel-major. Each path starts its numbers; the first two place the ray
/// in its pixel — exactly as the reference does.
pub fn generate<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    sampler: &S,
    frame: &Frame,
    pixels: Range<u32>,
    samples: Range<u32>,
) {
    let n = pixels.len() * samples.len();
    queue.set_len(n);
    let paths = pixels.flat_map(|p| samples.clone().map(move |s| (p, s)));
    let rows = queue.rows_mut(n);
    for (row, (pixel, sample)) in rows.zip(paths) {
        let (x, y) = (pixel % frame.width, pixel / frame.width);
        let mut path = sampler.start(pixel, sample);
        let (o, d) = frame.camera.pixel_ray(x, y, sampler.next_2d(&mut path));
        row.set_camera_ray(pixel, path, o.to_array(), d.to_array());
    }
}
