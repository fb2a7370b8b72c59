//! Stage *bounce*: sample each live path's next direction and update its
//! throughput, eight paths at a time, each model's rows (grouped by the
//! *sort* stage) with the model's scattering routine.

use super::Ctx;
use super::queue::{PathQueue, load8, store_lanes, store3};
use crate::integrator::offset::spawn;
use crate::integrator::sampler::Sampler;
use crate::math::V3;
use crate::scene::{Integrator, Model};
use std::ops::Range;

/// Bounce every path in the queue (all live: retired rows are gone) off
/// the surface it hit, each model's rows (`bins`, from the *sort* stage)
/// with its routine.
pub fn bounce<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    bins: &[(Model, Range<usize>)],
    ctx: &Ctx<S>,
) {
    for (model, rows) in bins {
        scatter(queue, *model, rows.clone(), ctx);
    }
}

/// Bounce the paths in rows `rows`, all at surfaces of model `model`,
/// eight at a time: the new origin is the hit point moved off the surface
/// ([`spawn`]); the new direction and
/// the throughput's factor come from [`Surface::sample`](crate::integrator::bsdf::Surface::sample) (for diffuse
/// surfaces, uniform directions for the report's estimator and
/// cosine-weighted ones otherwise), with the vertex's scattering numbers
/// ([`Estimator::bsdf_numbers`]). The density goes to the queue for the
/// MIS weight of the emission the new ray finds: 0 after a delta bounce.
pub fn scatter<S: Sampler>(
    queue: &mut PathQueue<S::Path>,
    model: Model,
    rows: Range<usize>,
    ctx: &Ctx<S>,
) {
    let (sampler, tables, estimator) = (ctx.sampler, ctx.tables, ctx.est);
    let report = estimator.integrator == Integrator::Report;
    for i in rows.clone().step_by(8) {
        // Two groups ahead: their rows are on their way while these bounce.
        let ahead = (i + 16).min(rows.end)..(i + 24).min(rows.end);
        tables.prefetch_rows(&queue.hit, ahead);
        let lanes = (rows.end - i).min(8);
        // Lanes past the last row of the range compute garbage that is not
        // stored (the next rows belong to another model's range); they
        // borrow the first lane's triangle for the lookups.
        let tri = |l: usize| queue.hit[i + if l < lanes { l } else { 0 }] as usize;
        let tris: [usize; 8] = std::array::from_fn(tri);
        let (_lobe, u) = estimator.bsdf_numbers_8(sampler, &mut queue.sampler[i..i + lanes]);
        let load3 = |cols: &[Vec<f32>; 3]| {
            V3::new(load8(&cols[0], i), load8(&cols[1], i), load8(&cols[2], i))
        };
        let o = load3(&queue.o);
        let d = load3(&queue.d);
        let beta = load3(&queue.beta);
        let t = load8(&queue.t, i);
        let hit = tables.surface_8(&tris, (o, d), t);
        let surface = tables.surfaces_at(model, &tris, &hit);
        let s = if tables.has_smooth() {
            surface.sample_shaded((hit.front, hit.n, hit.ns), d, u, report)
        } else {
            surface.sample(hit.ng, d, u, report)
        };
        let beta = s.weigh(beta);
        let pdf = surface.mis_pdf(&s, hit.n);
        let origin = spawn(hit.p, hit.ng, s.wi, hit.err);

        store3(&mut queue.o, i, origin, lanes);
        store3(&mut queue.d, i, s.wi, lanes);
        store3(&mut queue.beta, i, beta, lanes);
        store_lanes(&mut queue.pdf, i, pdf, lanes);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::bvh::Bvh;
    use crate::accel::triangle::hit_point;
    use crate::integrator::bsdf::Surface;
    use crate::integrator::lights::Lights;
    use crate::integrator::nee::Estimator;
    use crate::integrator::offset::error_bound;
    use crate::integrator::sampler::{Independent, PathRng};
    use crate::integrator::tables::Tables;
    use crate::scene::Scene;

    /// A queue of `n` paths that hit Cornell box triangles, with varied
    /// origins, directions and throughputs.
    fn queue(n: usize, sampler: &Independent) -> PathQueue<PathRng> {
        let mut q = PathQueue::with_capacity(n.max(1));
        q.set_len(n);
        let mut rng = PathRng::new(5, 5, 5);
        for i in 0..n {
            q.pixel[i] = i as u32;
            q.sampler[i] = sampler.start(i as u32, 3);
            for c in 0..3 {
                q.o[c][i] = rng.next_f32() - 0.5;
                q.d[c][i] = rng.next_f32() - 0.5;
                q.beta[c][i] = rng.next_f32();
            }
            q.t[i] = rng.next_f32();
            q.hit[i] = (i * 7 % 32) as u32;
        }
        q
    }

    #[test]
    fn every_row_bounces_as_the_scalar_routine_whatever_the_tail() {
        let scene = Scene::cornell();
        let tables = Tables::new(&scene);
        let lights = Lights::new(&scene);
        let bvh = Bvh::build(&crate::accel::scene_triangles(&scene));
        let sampler = Independent::new(11);
        for n in 0..=17 {
            let before = queue(n, &sampler);
            let mut after = before.clone();
            let ctx = Ctx {
                sampler: &sampler,
                est: &Estimator::report(3),
                tables: &tables,
                lights: &lights,
                bvh: &bvh,
            };
            scatter(&mut after, Model::Diffuse, 0..n, &ctx);
            for i in 0..n {
                // The same row, bounced by the scalar (f32) routine.
                let tri = before.hit[i] as usize;
                let col = |c: &[Vec<f32>; 3]| V3::new(c[0][i], c[1][i], c[2][i]);
                let normal = V3::from(scene.triangles[tri].normal);
                let material = &scene.materials[scene.triangles[tri].material as usize];
                let mut path = before.sampler[i];
                let u = sampler.next_2d(&mut path);
                let (o, d) = (col(&before.o), col(&before.d));
                let s = Surface::of(material).sample(normal, d, u, true);
                let p = hit_point(o, d, before.t[i]);
                let err = error_bound(o, p, scene.primitive_scale(tri));
                let want = [
                    spawn(p, normal, s.wi, err),
                    s.wi,
                    s.weigh(col(&before.beta)),
                ];
                let got = [col(&after.o), col(&after.d), col(&after.beta)];
                for (w, g) in want.iter().zip(&got) {
                    assert_eq!(
                        [w.x, w.y, w.z].map(f32::to_bits),
                        [g.x, g.y, g.z].map(f32::to_bits),
                        "{n} rows: row {i}"
                    );
                }
                assert_eq!(after.sampler[i], path, "row {i} drew two numbers");
                assert_eq!(after.pixel[i], before.pixel[i]);
            }
        }
    }
}
