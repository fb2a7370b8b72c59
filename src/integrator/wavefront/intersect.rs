//! Stage *intersect*: the closest hit of every ray in the queue.

use super::queue::{NO_HIT, PathQueue};
use crate::accel::bvh::Bvh;
use crate::accel::triangle::{Hit, LaneHits, Triangle8};
use crate::math::V3;
use glam::Vec3;
use wide::f32x8;

/// Room for a batch of rays in the form [`Bvh::closest_hits`] takes.
#[derive(Debug, Default)]
pub struct RayBatch {
    rays: Vec<(Vec3, Vec3)>,
    hits: Vec<Option<Hit>>,
}

/// Fill `queue.t` and `queue.hit` with each ray's closest hit
/// (smallest `(t, triangle)`), testing 8 triangles at a time.
///
/// A scene that is a single leaf (up to 32 triangles) is tested pack by
/// pack right here; a bigger one goes through the hierarchy, a batch of
/// rays at a time (interleaved, so memory latency overlaps).
pub fn intersect<P>(queue: &mut PathQueue<P>, bvh: &Bvh, epsilon: f32, batch: &mut RayBatch) {
    match bvh.single_leaf() {
        Some(packs) => intersect_packs(queue, packs, epsilon),
        None => intersect_bvh(queue, bvh, epsilon, batch),
    }
}

fn intersect_bvh<P>(queue: &mut PathQueue<P>, bvh: &Bvh, epsilon: f32, batch: &mut RayBatch) {
    let n = queue.len();
    let [ox, oy, oz] = &queue.o;
    let [dx, dy, dz] = &queue.d;
    batch.rays.clear();
    batch.rays.extend((0..n).map(|i| {
        (
            Vec3::new(ox[i], oy[i], oz[i]),
            Vec3::new(dx[i], dy[i], dz[i]),
        )
    }));
    batch.hits.clear();
    batch.hits.resize(n, None);
    bvh.closest_hits(&batch.rays, epsilon, f32::INFINITY, &mut batch.hits);
    for (i, h) in batch.hits.iter().enumerate() {
        match h {
            Some(h) => (queue.t[i], queue.hit[i]) = (h.t, h.triangle),
            None => queue.hit[i] = NO_HIT,
        }
    }
}

fn intersect_packs<P>(queue: &mut PathQueue<P>, packs: &[Triangle8], epsilon: f32) {
    let n = queue.len();
    let t_min = f32x8::splat(epsilon);
    let [ox, oy, oz] = &queue.o;
    let [dx, dy, dz] = &queue.d;
    let rays = ox[..n]
        .iter()
        .zip(&oy[..n])
        .zip(&oz[..n])
        .zip(dx[..n].iter().zip(&dy[..n]).zip(&dz[..n]));
    let hits = queue.t[..n].iter_mut().zip(&mut queue.hit[..n]);
    for ((((ox, oy), oz), ((dx, dy), dz)), (t, hit)) in rays.zip(hits) {
        let o = V3::new(f32x8::splat(*ox), f32x8::splat(*oy), f32x8::splat(*oz));
        let d = V3::new(f32x8::splat(*dx), f32x8::splat(*dy), f32x8::splat(*dz));
        let mut best = LaneHits::new(f32::INFINITY);
        for pack in packs {
            pack.intersect::<true>(&o, &d, t_min, &mut best);
        }
        match best.closest() {
            Some(h) => (*t, *hit) = (h.t, h.triangle),
            None => *hit = NO_HIT,
        }
    }
}
