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
    ray: Vec<ShadowRay>,
}

impl ShadowQueue {
    /// Empty it.
    pub fn clear(&mut self) {
        self.row.clear();
        self.ray.clear();
    }

    /// Queue `ray` for the path in row `row`.
    pub fn push(&mut self, row: u32, ray: ShadowRay) {
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
    for (&row, ray) in shadows.row.iter().zip(&shadows.ray) {
        if bvh
            .closest_hit(ray.origin, ray.dir, epsilon, ray.t_max)
            .is_some()
        {
            continue;
        }
        let i = row as usize;
        for ((radiance, beta), l) in queue
            .radiance
            .iter_mut()
            .zip(&queue.beta)
            .zip(ray.radiance.to_array())
        {
            radiance[i] += beta[i] * l;
        }
    }
    shadows.len() as u64
}
