//! Stage *shade*: add what each hit surface emits towards the ray.

use super::Ctx;
use super::queue::{NO_HIT, PathQueue, rows_where};
use crate::integrator::aov::{Vertex, value};
use crate::integrator::bsdf::is_delta;
#[cfg(doc)]
use crate::integrator::environment::EnvLight;
use crate::integrator::lights::power_heuristic;
use crate::integrator::nee::{emission_weight, escaped};
use crate::integrator::sampler::Sampler;
use crate::integrator::tables::Tables;
use crate::math::V3;
use crate::scene::aov::When;
use glam::Vec3;
use wide::f32x8;

/// For every path whose ray hit a surface from its front side:
/// radiance += throughput × emitted radiance × its MIS weight (1 unless
/// the estimator samples lights too, see [`emission_weight`]).
pub fn shade<S: Sampler>(queue: &mut PathQueue<S::Path>, ctx: &Ctx<S>) {
    let (tables, lights, estimator) = (ctx.tables, ctx.lights, ctx.est);
    let n = queue.len();
    // Columns cut to the live rows: the loop below needs no bounds checks.
    let hit = &queue.hit[..n];
    let (t, pdf) = (&queue.t[..n], &queue.pdf[..n]);
    let [ox, oy, oz] = queue.o.each_ref().map(|c| &c[..n]);
    let [dx, dy, dz] = queue.d.each_ref().map(|c| &c[..n]);
    let beta = queue.beta.each_ref().map(|c| &c[..n]);
    let [lr, lg, lb] = queue.radiance.each_mut().map(|c| &mut c[..n]);
    // Most surfaces emit nothing: the rows that hit an emitter are found
    // eight at a time, without a branch per row.
    for i in rows_where(hit, |&h| tables.emits(h)) {
        let (o, d) = (V3::new(ox[i], oy[i], oz[i]), V3::new(dx[i], dy[i], dz[i]));
        let s = tables.surface(hit[i] as usize, (o, d), t[i]);
        let e = tables.emission_at(s.material, s.uv);
        if s.front {
            let cos_light = -glam::Vec3::from(s.ng).dot(glam::Vec3::from(d));
            let w = emission_weight(estimator, lights, (pdf[i], o), hit[i], t[i], cos_light);
            lr[i] += beta[0][i] * (e[0] * w);
            lg[i] += beta[1][i] * (e[1] * w);
            lb[i] += beta[2][i] * (e[2] * w);
        }
    }
}

/// For every path whose ray crossed an absorbing solid from inside (it
/// hit the back of a material that [`absorbs`](crate::scene::Material::absorbs)):
/// throughput ×= the segment's transmittance
/// ([`Tables::transmittance`], the reference tracer's factor, before
/// anything else at the vertex). Nothing in scenes without absorption.
pub fn absorb<P>(queue: &mut PathQueue<P>, tables: &Tables) {
    if !tables.has_absorption() {
        return;
    }
    let n = queue.len();
    for i in 0..n {
        let hit = queue.hit[i];
        if hit == NO_HIT || !tables.absorbs(hit) {
            continue;
        }
        let o = V3::new(queue.o[0][i], queue.o[1][i], queue.o[2][i]);
        let d = V3::new(queue.d[0][i], queue.d[1][i], queue.d[2][i]);
        let s = tables.surface(hit as usize, (o, d), queue.t[i]);
        if let Some(a) = tables.transmittance(&s, queue.t[i]) {
            for (c, a) in queue.beta.iter_mut().zip(a) {
                c[i] *= a;
            }
        }
    }
}

/// For every path whose ray left the scene, in a scene with an
/// environment: radiance += throughput × the environment's radiance ×
/// its MIS weight ([`escaped`]); camera rays (depth `depth` 0) see it only
/// where it is visible. The environment is looked up eight rays at a time
/// ([`EnvLight::radiance_and_pdf_lanes`]: the scalar lookup's bits, the
/// texels and densities read by gathers); the
/// weights and the suns seen, as [`escaped`] computes them. Out of line
/// (one call per depth), so that how the batch loop around it is compiled
/// does not hang on the lookup's size.
#[inline(never)]
pub fn shade_escaped<S: Sampler>(queue: &mut PathQueue<S::Path>, ctx: &Ctx<S>, depth: u32) {
    let n = queue.len();
    let hit = &queue.hit[..n];
    let pdf = &queue.pdf[..n];
    let [dx, dy, dz] = queue.d.each_ref().map(|c| &c[..n]);
    let beta = queue.beta.each_ref().map(|c| &c[..n]);
    let [lr, lg, lb] = queue.radiance.each_mut().map(|c| &mut c[..n]);
    let Some(env) = ctx.lights.environment() else {
        // Suns only, if any.
        for i in rows_where(hit, |&h| h == NO_HIT) {
            let d = V3::new(dx[i], dy[i], dz[i]);
            if let Some(l) = escaped(ctx.est, ctx.lights, pdf[i], d, depth == 0) {
                lr[i] += beta[0][i] * l.x;
                lg[i] += beta[1][i] * l.y;
                lb[i] += beta[2][i] * l.z;
            }
        }
        return;
    };
    if depth == 0 && !env.visible {
        return;
    }
    let samples_lights = ctx.est.samples_lights();
    let probability = ctx.lights.environment_probability();
    let mut escaping = rows_where(hit, |&h| h == NO_HIT);
    loop {
        let mut rows = [0usize; 8];
        let k = rows
            .iter_mut()
            .zip(&mut escaping)
            .map(|(r, i)| *r = i)
            .count();
        if k == 0 {
            return;
        }
        let gather = |c: &[f32]| f32x8::from(std::array::from_fn(|l| c[rows[l.min(k - 1)]]));
        let d = V3::new(gather(dx), gather(dy), gather(dz));
        let (radiance, env_pdf) = env.radiance_and_pdf_lanes(d, k);
        let [rx, ry, rz, env_pdf] =
            [radiance.x, radiance.y, radiance.z, env_pdf].map(|c| c.to_array());
        for (l, &i) in rows[..k].iter().enumerate() {
            // `escaped`, with the lookup done.
            let (bsdf_pdf, d) = (pdf[i], V3::new(dx[i], dy[i], dz[i]));
            let mis = samples_lights && bsdf_pdf != 0.0;
            let light = V3::new(rx[l], ry[l], rz[l]);
            let mut seen = if mis {
                let p = if probability > 0.0 {
                    probability * env_pdf[l]
                } else {
                    0.0
                };
                let w = power_heuristic(bsdf_pdf, p);
                V3::new(light.x * w, light.y * w, light.z * w)
            } else {
                light
            };
            for (sun, p) in ctx.lights.suns_seen(d) {
                let w = if mis {
                    power_heuristic(bsdf_pdf, p)
                } else {
                    1.0
                };
                seen = sun.mul_add(w, seen);
            }
            lr[i] += beta[0][i] * seen.x;
            lg[i] += beta[1][i] * seen.y;
            lb[i] += beta[2][i] * seen.z;
        }
    }
}

/// Record the AOVs of the hits at depth `depth` in the queue's AOV columns
/// (nothing without them), as [`crate::integrator::aov`] defines them
/// ([`value`]): at depth 0 those of the camera ray's hit, at the path's
/// first non-specular vertex those recorded there, for a camera looking
/// along `forward`. Scalar, one path at a time, with the reference
/// tracer's operations, so the values are its bits.
pub fn record_aovs<P>(queue: &mut PathQueue<P>, tables: &Tables, depth: u32, forward: Vec3) {
    let n = queue.len();
    let Some(aov) = queue.aov.as_mut() else {
        return;
    };
    if depth > 0 && !aov.surface {
        return;
    }
    for i in 0..n {
        let hit = queue.hit[i];
        if hit == NO_HIT {
            continue;
        }
        let first = aov.surface && aov.pending[i] != 0 && !is_delta(tables.model_of(hit));
        if depth != 0 && !first {
            continue;
        }
        let o = V3::new(queue.o[0][i], queue.o[1][i], queue.o[2][i]);
        let d = V3::new(queue.d[0][i], queue.d[1][i], queue.d[2][i]);
        let v = Vertex::new(tables, hit, (o, d), queue.t[i], forward);
        for (a, when, col) in &mut aov.values {
            if depth == 0 && *when == When::CameraHit || first && *when == When::FirstNonSpecular {
                col[i] = value(*a, &v);
            }
        }
        if first {
            aov.pending[i] = 0;
        }
    }
}
