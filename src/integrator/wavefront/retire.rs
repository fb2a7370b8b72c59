//! Stage *retire*: finished paths go into the film and leave the queue.

use super::queue::{NO_HIT, PathQueue, RETIRED};
use crate::film::accumulate;
use crate::integrator::TileJob;

/// A path is finished when its ray escaped, or when `last` is set (its
/// next ray would exceed the maximum depth): its radiance is one sample of
/// its pixel, added to the tile's sums. Finished rows are then dropped
/// from the queue ([`PathQueue::compact`]). Returns the number of samples
/// refused as invalid.
pub fn retire<P: Copy>(queue: &mut PathQueue<P>, last: bool, job: &mut TileJob) -> u64 {
    let mut invalid = 0;
    let n = queue.len();
    let hit = &mut queue.hit[..n];
    let pixel = &queue.pixel[..n];
    let [lr, lg, lb] = queue.radiance.each_ref().map(|c| &c[..n]);
    for i in 0..n {
        if last || hit[i] == NO_HIT {
            let sample = glam::Vec3::new(lr[i], lg[i], lb[i]);
            if !accumulate(job.sum_of(pixel[i]), sample) {
                invalid += 1;
            }
            hit[i] = RETIRED;
        }
    }
    if last {
        queue.set_len(0);
    } else {
        queue.compact();
    }
    invalid
}
