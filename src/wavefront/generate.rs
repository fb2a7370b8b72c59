//! Stage 1, *generate*: camera rays for a batch of (pixel, sample) pairs.

use super::queue::PathQueue;
use crate::camera::RasterCamera;
use crate::sampling::PathRng;

/// Fill `queue` with the camera ray of every (pixel, sample) pair of the
/// batch: pixels `pixels` (row-major indices) times samples `samples`,
/// pixel-major. Each path gets its own random stream, whose first two
/// numbers jitter the ray over the pixel — exactly as the reference does.
pub fn generate(
    queue: &mut PathQueue,
    camera: &RasterCamera,
    width: u32,
    seed: u64,
    pixels: std::ops::Range<u32>,
    samples: std::ops::Range<u32>,
) {
    let mut row = 0;
    for pixel in pixels {
        let (x, y) = (pixel % width, pixel / width);
        for sample in samples.clone() {
            let mut rng = PathRng::new(seed, pixel, sample);
            let (o, d) = camera.jittered_ray(&mut rng, x, y);
            queue.set_camera_ray(row, pixel, rng, o.to_array(), d.to_array());
            row += 1;
        }
    }
    queue.set_len(row);
}
