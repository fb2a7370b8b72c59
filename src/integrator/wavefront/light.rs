//! Stage *light*: next-event estimation — at every path's vertex, a point
//! on an emitter and the shadow ray towards it, queued for the *shadow*
//! stage. Eight paths at a time.

use super::queue::{PathQueue, load8};
use super::shadow::ShadowQueue;
use super::tables::Tables;
use crate::accel::triangle::hit_point;
use crate::integrator::bsdf::facing;
use crate::integrator::lights::{Emitter, LightPoint, Lights};
use crate::integrator::nee::{Estimator, ShadowRay, connect};
use crate::integrator::sampler::Sampler;
use crate::math::{V3, Vec3x8};
use wide::f32x8;

/// Sample an emitter from every path's vertex (three numbers per path)
/// and queue the shadow rays that may carry light.
pub fn sample_lights<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    (sampler, estimator): (&S, &Estimator),
    (tables, lights): (&Tables, &Lights),
    shadows: &mut ShadowQueue,
) {
    shadows.clear();
    let n = queue.len();
    for i in (0..n).step_by(8) {
        let lanes = (n - i).min(8);
        // Each lane's emitter and point on it; lanes past the last path
        // get no emitter (never valid).
        let (pick, u) = estimator.light_numbers_8(sampler, &mut queue.sampler[i..i + lanes]);
        let pick = pick.to_array();
        let mut emitters = [&Emitter::NONE; 8];
        let mut tris = [queue.hit[i] as usize; 8];
        for l in 0..lanes {
            emitters[l] = lights.pick(pick[l]);
            tris[l] = queue.hit[i + l] as usize;
        }
        let light = LightPoint::on(&Emitter::lanes(emitters), u);
        let gather = |cols: &[Vec<f32>; 3]| -> Vec3x8 {
            let g = |c: &Vec<f32>| f32x8::from(tris.map(|t| c[t]));
            V3::new(g(&cols[0]), g(&cols[1]), g(&cols[2]))
        };
        let load3 = |cols: &[Vec<f32>; 3]| {
            V3::new(load8(&cols[0], i), load8(&cols[1], i), load8(&cols[2], i))
        };
        let d = load3(&queue.d);
        let p = hit_point(load3(&queue.o), d, load8(&queue.t, i));
        let (_, n) = facing(gather(&tables.normals), d);
        let (valid, ray) = connect(
            &light,
            f32x8::splat(tables.epsilon),
            p,
            n,
            gather(&tables.brdf),
        );
        let valid = valid.to_bitmask();
        for l in 0..lanes {
            if valid & (1 << l) != 0 {
                shadows.push((i + l) as u32, lane_of(&ray, l));
            }
        }
    }
}

/// Lane `l` of eight shadow rays.
#[inline(always)]
fn lane_of(r: &ShadowRay<f32x8>, l: usize) -> ShadowRay<f32> {
    let v = |v: &Vec3x8| V3::new(v.x.to_array()[l], v.y.to_array()[l], v.z.to_array()[l]);
    ShadowRay {
        origin: v(&r.origin),
        dir: v(&r.dir),
        t_max: r.t_max.to_array()[l],
        radiance: v(&r.radiance),
    }
}
