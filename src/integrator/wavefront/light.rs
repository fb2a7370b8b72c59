//! Stage *light*: next-event estimation — at every path's vertex, a point
//! on an emitter and the shadow ray towards it, queued for the *shadow*
//! stage.

use super::queue::PathQueue;
use super::shadow::ShadowQueue;
use super::tables::Tables;
use crate::accel::triangle::hit_point;
use crate::integrator::bsdf::facing;
use crate::integrator::lights::Lights;
use crate::integrator::nee::{Estimator, connect};
use crate::integrator::sampler::Sampler;
use crate::math::V3;
use glam::Vec3;

/// Sample an emitter from every path's vertex (three numbers per path)
/// and queue the shadow rays that may carry light.
pub fn sample_lights<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    (sampler, estimator): (&S, &Estimator),
    (tables, lights): (&Tables, &Lights),
    shadows: &mut ShadowQueue,
) {
    shadows.clear();
    for i in 0..queue.len() {
        let (pick, u) = estimator.light_numbers(sampler, &mut queue.sampler[i]);
        let tri = queue.hit[i] as usize;
        let col = |c: &[Vec<f32>; 3], i: usize| V3::new(c[0][i], c[1][i], c[2][i]);
        let (o, d) = (col(&queue.o, i), col(&queue.d, i));
        let p = Vec3::from(hit_point(o, d, queue.t[i]));
        let (_, n) = facing(col(&tables.normals, tri), d);
        let brdf = Vec3::from(col(&tables.brdf, tri));
        if let Some(ray) = connect(lights, tables.epsilon, p, Vec3::from(n), brdf, pick, u) {
            shadows.push(i as u32, ray);
        }
    }
}
