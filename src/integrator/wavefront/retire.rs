//! Stage *retire*: finished paths go into the film and leave the queue.

use super::queue::{NO_HIT, PathQueue, RETIRED};
use crate::film::accumulate;
use crate::integrator::TileJob;
use crate::integrator::nee::{Estimator, survival};
use crate::integrator::sampler::Sampler;

/// A path is finished when its ray escaped, when `last` is set (its next
/// ray would exceed the maximum depth), or when Russian roulette ends it
/// at this vertex (depth `depth`; the survivors' throughput is divided by
/// their chance of surviving). A finished path's radiance is one sample of
/// its pixel, added to the tile's sums (with its AOVs, when the render
/// accumulates them: the queue's AOV columns, and the radiance's square
/// for the variance); finished rows are then dropped
/// from the queue ([`PathQueue::compact`]). Returns the number of samples
/// refused as invalid.
pub fn retire<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    (sampler, estimator): (&S, &Estimator),
    depth: u32,
    last: bool,
    job: &mut TileJob,
) -> u64 {
    let mut invalid = 0;
    let n = queue.len();
    let aovs = job.has_aovs();
    for i in 0..n {
        let mut done = last || queue.hit[i] == NO_HIT;
        if !done && let Some(u) = estimator.roulette_number(sampler, &mut queue.sampler[i], depth) {
            let beta = glam::Vec3::new(queue.beta[0][i], queue.beta[1][i], queue.beta[2][i]);
            let q = survival(beta);
            if u >= q {
                done = true;
            } else {
                for c in &mut queue.beta {
                    c[i] /= q;
                }
            }
        }
        if done {
            let [r, g, b] = queue.radiance.each_ref().map(|c| c[i]);
            let rgb = glam::Vec3::new(r, g, b);
            let valid = if aovs {
                job.add_sample(queue.pixel[i], rgb, &queue.aov_sample(i))
            } else {
                accumulate(job.sum_of(queue.pixel[i]), rgb)
            };
            if !valid {
                invalid += 1;
            }
            queue.hit[i] = RETIRED;
        }
    }
    if last {
        queue.set_len(0);
    } else {
        queue.compact();
    }
    invalid
}
