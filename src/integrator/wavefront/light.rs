//! Stage *light*: next-event estimation — at every path's vertex, a point
//! on an emitter and the shadow ray towards it, queued for the *shadow*
//! stage. Eight paths at a time.

use super::Ctx;
use super::queue::{PathQueue, load8};
use super::shadow::ShadowQueue;
use crate::integrator::bsdf::is_delta;
use crate::integrator::lights::LightPoint;
use crate::integrator::nee::{connect, connect_shaded};
use crate::integrator::sampler::Sampler;
use crate::integrator::tables::Tables;
use crate::math::V3;
use crate::scene::Model;
use std::ops::Range;
use wide::f32x8;

/// Sample an emitter from every path's vertex at a non-delta surface
/// (three numbers per path; paths at delta surfaces skip theirs), model by
/// model (`bins`, from the *sort* stage), and queue the shadow rays that
/// may carry light.
pub fn sample_lights<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    bins: &[(Model, Range<usize>)],
    ctx: &Ctx<S>,
    shadows: &mut ShadowQueue,
) {
    shadows.clear();
    for (model, rows) in bins {
        if is_delta(*model) {
            for path in &mut queue.sampler[rows.clone()] {
                ctx.est.skip_light_numbers(ctx.sampler, path);
            }
            continue;
        }
        let (model, rows) = (*model, rows.clone());
        for i in rows.clone().step_by(8) {
            let lanes = (rows.end - i).min(8);
            sample_lights_8(queue, i..i + lanes, model, ctx, shadows);
        }
    }
}

/// [`sample_lights`] for the (at most 8) paths of rows `rows`, at
/// surfaces of model `model`.
#[inline(always)]
fn sample_lights_8<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    rows: Range<usize>,
    model: Model,
    ctx: &Ctx<S>,
    shadows: &mut ShadowQueue,
) {
    let (i, lanes) = (rows.start, rows.len());
    let (tables, lights) = (ctx.tables, ctx.lights);
    // Each lane's emitter and point on it (lanes past the last path are
    // for nothing: no shadow ray is queued for them).
    let [u0, u1] = ctx
        .est
        .light_numbers_8(ctx.sampler, &mut queue.sampler[rows]);
    let mut tris = [queue.hit[i] as usize; 8];
    for (tri, &hit) in tris.iter_mut().zip(&queue.hit[i..i + lanes]) {
        *tri = hit as usize;
    }
    let load3 =
        |cols: &[Vec<f32>; 3]| V3::new(load8(&cols[0], i), load8(&cols[1], i), load8(&cols[2], i));
    let (o, d, t) = (load3(&queue.o), load3(&queue.d), load8(&queue.t, i));
    let s = tables.surface_8(&tris, (o, d), t);
    let mut light = lights.sample_8(s.p, [u0, u1], lanes);
    if tables.has_emissive_maps() {
        textured_emission_8(tables, &mut light, lanes);
    }
    let surface = tables.surfaces_at(model, &tris, &s);
    let (valid, ray) = if tables.has_smooth() {
        connect_shaded(&light, s.err, (s.p, s.n, s.ns, -d), s.front, &surface)
    } else {
        connect(&light, s.err, (s.p, s.n, -d), s.front, &surface)
    };
    // The live lanes that may carry light.
    let valid = valid.to_bitmask() as u8 & (u8::MAX >> (8 - lanes));
    if valid != 0 {
        shadows.push_8(i as u32, valid, &ray);
    }
}

/// Where the points `light` (the first `lanes` lanes) lie on emitters
/// whose emission is textured, their radiance looked up there, lane by
/// lane, as the reference tracer does ([`Tables::light_emission`]).
#[inline(never)]
fn textured_emission_8(tables: &Tables, light: &mut LightPoint<f32x8>, lanes: usize) {
    let prim = light.prim.to_array();
    let (px, py, pz) = (
        light.point.x.to_array(),
        light.point.y.to_array(),
        light.point.z.to_array(),
    );
    let mut e = [
        light.emission.x.to_array(),
        light.emission.y.to_array(),
        light.emission.z.to_array(),
    ];
    for l in 0..lanes {
        let p = V3::new(px[l], py[l], pz[l]);
        if let Some(c) = tables.light_emission(prim[l].to_bits(), p) {
            for k in 0..3 {
                e[k][l] = c[k];
            }
        }
    }
    light.emission = V3::new(f32x8::from(e[0]), f32x8::from(e[1]), f32x8::from(e[2]));
}
