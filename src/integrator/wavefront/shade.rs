//! Stage *shade*: add what each hit surface emits towards the ray.

use super::queue::{NO_HIT, PathQueue};
use super::tables::Tables;
use crate::integrator::bsdf::facing;
use crate::integrator::lights::Lights;
use crate::integrator::nee::{Estimator, emission_weight};
use crate::math::V3;

/// For every path whose ray hit a surface from its front side:
/// radiance += throughput × emitted radiance × its MIS weight (1 unless
/// the estimator samples lights too, see [`emission_weight`]).
pub fn shade<P>(queue: &mut PathQueue<P>, tables: &Tables, lights: &Lights, estimator: &Estimator) {
    let n = queue.len();
    // Columns cut to the live rows: the loop below needs no bounds checks.
    let hit = &queue.hit[..n];
    let (t, pdf) = (&queue.t[..n], &queue.pdf[..n]);
    let [ox, oy, oz] = queue.o.each_ref().map(|c| &c[..n]);
    let [dx, dy, dz] = queue.d.each_ref().map(|c| &c[..n]);
    let beta = queue.beta.each_ref().map(|c| &c[..n]);
    let [lr, lg, lb] = queue.radiance.each_mut().map(|c| &mut c[..n]);
    for i in 0..n {
        if hit[i] == NO_HIT {
            continue;
        }
        let tri = hit[i] as usize;
        let e = tables.emission[tables.material_of[tri] as usize];
        // Most surfaces emit nothing: skip the side test for them.
        if e == [0.0; 3] {
            continue;
        }
        let d = V3::new(dx[i], dy[i], dz[i]);
        let normal = tables.front_normal(tri, V3::new(ox[i], oy[i], oz[i]), d, t[i]);
        if facing(normal, d).0 {
            let cos_light = -glam::Vec3::from(normal).dot(glam::Vec3::from(d));
            let o = V3::new(ox[i], oy[i], oz[i]);
            let w = emission_weight(estimator, lights, (pdf[i], o), hit[i], t[i], cos_light);
            lr[i] += beta[0][i] * (e[0] * w);
            lg[i] += beta[1][i] * (e[1] * w);
            lb[i] += beta[2][i] * (e[2] * w);
        }
    }
}
