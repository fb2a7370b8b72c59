//! Stage 1, *generate*: camera rays for a batch of (pixel, sample) pairs.

use super::queue::PathQueue;
use crate::integrator::sampler::PathRng;
use crate::scene::camera::RasterCamera;

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
    let n = pixels.len() * samples.len();
    queue.set_len(n);
    let paths = pixels.flat_map(|p| samples.clone().map(move |s| (p, s)));
    let rows = queue.rows_mut(n);
    for (row, (pixel, sample)) in rows.zip(paths) {
        let (x, y) = (pixel % width, pixel / width);
        let mut rng = PathRng::new(seed, pixel, sample);
        let (o, d) = camera.jittered_ray(&mut rng, x, y);
        row.set_camera_ray(pixel, rng, o.to_array(), d.to_array());
    }
}
