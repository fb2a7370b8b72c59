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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampler::PathRng;
    use crate::math::V3;
    use crate::scene::Scene;

    /// The stage adds a ray's light to its path exactly when the scalar
    /// occlusion test finds nothing on the segment — on a million random
    /// segments in the Cornell box (about half of them blocked), several
    /// per path and in no particular order.
    #[test]
    fn the_stage_equals_the_scalar_occlusion_test_on_a_million_rays() {
        let scene = Scene::cornell();
        let bvh = Bvh::build(&crate::accel::scene_triangles(&scene));
        let corners = scene.triangles.iter().flat_map(|t| t.v);
        let lo = corners.clone().fold(glam::Vec3::INFINITY, glam::Vec3::min);
        let hi = corners.fold(glam::Vec3::NEG_INFINITY, glam::Vec3::max);
        let eps = 1e-4;
        let mut rng = PathRng::new(3, 1, 4);
        let mut u = || rng.next_f32();
        let rows = 4096;
        let mut queue = PathQueue::<()>::with_capacity(rows);
        queue.set_len(rows);
        let (mut blocked, mut total) = (0, 0);
        for _ in 0..250 {
            let mut shadows = ShadowQueue::default();
            let mut expected = vec![[0.0f32; 3]; rows];
            for i in 0..rows {
                for c in 0..3 {
                    queue.radiance[c][i] = 0.0;
                    queue.beta[c][i] = 0.5 + c as f32;
                }
            }
            for _ in 0..rows {
                let row = (u() * rows as f32) as usize % rows;
                let o = lo + (hi - lo) * glam::Vec3::new(u(), u(), u());
                let to = lo + (hi - lo) * glam::Vec3::new(u(), u(), u());
                let (dir, t_max) = ((to - o).normalize(), (to - o).length());
                let l = glam::Vec3::new(u(), u(), u());
                shadows.push(
                    row as u32,
                    ShadowRay {
                        origin: V3::from(o),
                        dir: V3::from(dir),
                        t_max,
                        radiance: V3::from(l),
                    },
                );
                total += 1;
                if bvh.occluded(o, dir, eps, t_max) {
                    blocked += 1;
                    continue;
                }
                for c in 0..3 {
                    expected[row][c] += queue.beta[c][row] * l[c];
                }
            }
            assert_eq!(shadow(&mut queue, &shadows, &bvh, eps), rows as u64);
            for (i, e) in expected.iter().enumerate() {
                let got = [0, 1, 2].map(|c| queue.radiance[c][i]);
                assert_eq!(got.map(f32::to_bits), e.map(f32::to_bits), "row {i}");
            }
        }
        assert_eq!(total, 250 * 4096);
        assert!(
            blocked > total / 5 && blocked < total * 4 / 5,
            "{blocked} of {total}"
        );
    }
}
