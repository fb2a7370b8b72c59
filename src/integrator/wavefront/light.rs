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
use crate::integrator::surface::SurfaceHit;
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
        // Sixteen paths at a time (two groups of eight whose light points
        // are computed side by side, `Lights::sample_16`), then the rest.
        let mut i = rows.start;
        while rows.end - i > 8 {
            let lanes = (rows.end - i - 8).min(8);
            sample_lights_16(queue, i, lanes, model, ctx, shadows);
            i += 8 + lanes;
        }
        if i < rows.end {
            sample_lights_8(queue, i..rows.end, model, ctx, shadows);
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
    let v = vertices_8(queue, rows.clone(), ctx);
    let light = ctx.lights.sample_8(v.hit.p, v.u, rows.len());
    connect_8(&v, light, rows, model, ctx, shadows);
}

/// [`sample_lights`] for the 8 paths from row `i` and the `lanes` (at
/// most 8) after them, at surfaces of model `model`: the two groups' light
/// points side by side ([`Lights::sample_16`](crate::integrator::lights::Lights::sample_16)),
/// the same bits as two [`sample_lights_8`].
#[inline(always)]
fn sample_lights_16<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    i: usize,
    lanes: usize,
    model: Model,
    ctx: &Ctx<S>,
    shadows: &mut ShadowQueue,
) {
    let rows = [i..i + 8, i + 8..i + 8 + lanes];
    let a = vertices_8(queue, rows[0].clone(), ctx);
    let b = vertices_8(queue, rows[1].clone(), ctx);
    let [la, lb] = (ctx.lights).sample_16([a.hit.p, b.hit.p], [a.u, b.u], [8, lanes]);
    let [ra, rb] = rows;
    connect_8(&a, la, ra, model, ctx, shadows);
    connect_8(&b, lb, rb, model, ctx, shadows);
}

/// Eight path vertices, as the light stage needs them.
struct Vertices8 {
    /// Each lane's light-sampling numbers.
    u: [f32x8; 2],
    /// Each lane's primitive (lanes past the last path: the first's).
    tris: [usize; 8],
    /// The incoming direction.
    d: V3<f32x8>,
    /// The hit points.
    hit: SurfaceHit<f32x8>,
}

/// The light-sampling numbers and hit points of the (at most 8) paths of
/// rows `rows` (lanes past the last path are for nothing: no shadow ray
/// is queued for them).
#[inline(always)]
fn vertices_8<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    rows: Range<usize>,
    ctx: &Ctx<S>,
) -> Vertices8 {
    let (i, lanes) = (rows.start, rows.len());
    let u = ctx
        .est
        .light_numbers_8(ctx.sampler, &mut queue.sampler[rows]);
    let mut tris = [queue.hit[i] as usize; 8];
    for (tri, &hit) in tris.iter_mut().zip(&queue.hit[i..i + lanes]) {
        *tri = hit as usize;
    }
    let load3 =
        |cols: &[Vec<f32>; 3]| V3::new(load8(&cols[0], i), load8(&cols[1], i), load8(&cols[2], i));
    let (o, d, t) = (load3(&queue.o), load3(&queue.d), load8(&queue.t, i));
    let hit = ctx.tables.surface_8(&tris, (o, d), t);
    Vertices8 { u, tris, d, hit }
}

/// The shadow rays from the vertices `v` (rows `rows`, at surfaces of
/// model `model`) to the points `light`, queued where they may carry
/// light.
#[inline(always)]
fn connect_8<S: Sampler>(
    v: &Vertices8,
    mut light: LightPoint<f32x8>,
    rows: Range<usize>,
    model: Model,
    ctx: &Ctx<S>,
    shadows: &mut ShadowQueue,
) {
    let (i, lanes) = (rows.start, rows.len());
    let (tables, s, d) = (ctx.tables, &v.hit, v.d);
    if tables.has_emissive_maps() {
        textured_emission_8(tables, &mut light, lanes);
    }
    let surface = tables.surfaces_at(model, &v.tris, s);
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
/// whose emission is textured, their radiance looked up there, eight
/// lanes at once ([`Tables::light_emissions_8`]: the reference tracer's
/// [`Tables::light_emission`], bit for bit).
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
    let p = std::array::from_fn(|l| V3::new(px[l], py[l], pz[l]));
    let found = tables.light_emissions_8(prim.map(f32::to_bits), p, lanes);
    for (l, c) in found.into_iter().enumerate() {
        if let Some(c) = c {
            for k in 0..3 {
                e[k][l] = c[k];
            }
        }
    }
    light.emission = V3::new(f32x8::from(e[0]), f32x8::from(e[1]), f32x8::from(e[2]));
}
