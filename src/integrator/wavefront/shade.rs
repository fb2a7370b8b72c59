//! Stage *shade*: add what each hit surface emits towards the ray.

use super::queue::{NO_HIT, PathQueue};
use super::tables::Tables;
use crate::math::V3;

/// For every path whose ray hit a surface from its front side:
/// radiance += throughput × emitted radiance.
pub fn shade<P>(queue: &mut PathQueue<P>, tables: &Tables) {
    let n = queue.len();
    // Columns cut to the live rows: the loop below needs no bounds checks.
    let hit = &queue.hit[..n];
    let [dx, dy, dz] = queue.d.each_ref().map(|c| &c[..n]);
    let beta = queue.beta.each_ref().map(|c| &c[..n]);
    let [lr, lg, lb] = queue.radiance.each_mut().map(|c| &mut c[..n]);
    for i in 0..n {
        if hit[i] == NO_HIT {
            continue;
        }
        let t = hit[i] as usize;
        let e = tables.emission[tables.material_of[t] as usize];
        // Most surfaces emit nothing: skip the side test for them.
        if e == [0.0; 3] {
            continue;
        }
        let normal = V3::new(
            tables.normals[0][t],
            tables.normals[1][t],
            tables.normals[2][t],
        );
        if crate::integrator::bsdf::facing(normal, V3::new(dx[i], dy[i], dz[i])).0 {
            lr[i] += beta[0][i] * e[0];
            lg[i] += beta[1][i] * e[1];
            lb[i] += beta[2][i] * e[2];
        }
    }
}
