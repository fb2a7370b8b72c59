//! Stage *shadow*: the shadow rays of next-event estimation, tested for
//! occlusion; the light of those that reach their emitter goes to their
//! paths.

use super::queue::PathQueue;
use crate::accel::bvh::Bvh;
use crate::integrator::nee::ShadowRay;

/// Shadow rays and the queue rows of the paths they belong to.
#[derive(Debug, Default)]
pub struct ShadowQueue {
    row: Vec<u32>,
    ray: Vec<ShadowRay<f32>>,
}

impl ShadowQueue {
    /// Empty it.
    pub fn clear(&mut self) {
        self.row.clear();
        self.ray.clear();
    }

    /// Queue `ray` for the path in row `row`.
    pub fn push(&mut self, row: u32, ray: ShadowRay<f32>) {
        self.row.push(row);
        self.ray.push(ray);
    }

    /// Number of rays queued.
    pub fn len(&self) -> usize {
        self.ray.len()
    }
}

/// Test every queued shadow ray; for each one that nothing blocks, the
/// path's radiance gains throughput × the ray's radiance. Returns the
/// number of rays traced.
pub fn shadow<P>(queue: &mut PathQueue<P>, shadows: &ShadowQueue, bvh: &Bvh, epsilon: f32) -> u64 {
    let (radiance, beta) = (&mut queue.radiance, &queue.beta);
    bvh.occluded_with(
        shadows.len(),
        #[inline(always)]
        |k| {
            let ray = &shadows.ray[k];
            (ray.origin.into(), ray.dir.into(), ray.t_max)
        },
        epsilon,
        #[inline(always)]
        |k, occluded| {
            if occluded {
                return;
            }
            let (i, l) = (shadows.row[k] as usize, shadows.ray[k].radiance);
            for ((radiance, beta), l) in radiance.iter_mut().zip(beta).zip([l.x, l.y, l.z]) {
                radiance[i] += beta[i] * l;
            }
        },
    );
    shadows.len() as u64
}
