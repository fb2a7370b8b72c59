//! Stage *retire*: finished paths go into the film and leave the queue.

use super::Ctx;
use super::queue::{NO_HIT, PathQueue, RETIRED, SetBits, load8, mask_8};
use crate::film::{accumulate_fixed, to_fixed_8};
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
    ctx: &Ctx<S>,
    depth: u32,
    last: bool,
    job: &mut TileJob,
) -> u64 {
    // At the last depth every row finishes: none is marked.
    if !last {
        mark_finished(queue, (ctx.sampler, ctx.est), depth);
    }
    let invalid = if job.has_aovs() {
        add_with_aovs(queue, job, last)
    } else {
        add(queue, job, last)
    };
    if last {
        queue.set_len(0);
    } else {
        queue.compact();
    }
    invalid
}

/// Mark [`RETIRED`] the rows that finish before the last depth: those
/// whose ray escaped, and those Russian roulette ends (whose numbers have
/// a roulette slot: it is drawn or skipped here for every live row).
///
/// (The sampler and estimator come as arguments of their own, not in a
/// [`Ctx`]: a reference argument tells the compiler that the loop's
/// writes do not change them.)
fn mark_finished<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    (sampler, estimator): (&S, &Estimator),
    depth: u32,
) {
    let n = queue.len();
    if !estimator.has_roulette_slot() {
        // A loop without branches: an escape is no pattern to predict.
        for h in &mut queue.hit[..n] {
            *h = if *h == NO_HIT { RETIRED } else { *h };
        }
        return;
    }
    for i in 0..n {
        let mut done = queue.hit[i] == NO_HIT;
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
            queue.hit[i] = RETIRED;
        }
    }
}

/// Add the radiance of every [`RETIRED`] row (of every row if `all`) to
/// its pixel's sums, finding them eight rows at a time. Returns the number
/// of invalid samples.
fn add<P>(queue: &PathQueue<P>, job: &mut TileJob, all: bool) -> u64 {
    let mut invalid = 0;
    let n = queue.len();
    for i in (0..n).step_by(8) {
        let hit = &queue.hit[i..(i + 8).min(n)];
        let done = if all {
            u8::MAX >> (8 - hit.len())
        } else {
            mask_8(hit, |&h| h == RETIRED)
        };
        if done == 0 {
            continue;
        }
        let [r, g, b] = &queue.radiance;
        let (fixed, valid) = to_fixed_8([load8(r, i), load8(g, i), load8(b, i)]);
        invalid += (done & !valid).count_ones() as u64;
        for l in SetBits(done & valid) {
            let q = [fixed[0][l], fixed[1][l], fixed[2][l]];
            accumulate_fixed(job.sum_of(queue.pixel[i + l]), q);
        }
    }
    invalid
}

/// [`add`], with the AOVs of each finished path. Returns the number of
/// invalid radiance samples.
fn add_with_aovs<P: Copy>(queue: &PathQueue<P>, job: &mut TileJob, all: bool) -> u64 {
    let mut invalid = 0;
    for i in 0..queue.len() {
        if all || queue.hit[i] == RETIRED {
            let [r, g, b] = queue.radiance.each_ref().map(|c| c[i]);
            let rgb = glam::Vec3::new(r, g, b);
            if !job.add_sample(queue.pixel[i], rgb, &queue.aov_sample(i)) {
                invalid += 1;
            }
        }
    }
    invalid
}
