//! Stage *shadow*: the shadow rays of next-event estimation, tested for
//! occlusion; the light of those that reach their emitter goes to their
//! paths.

use super::queue::PathQueue;
use crate::accel::bvh::Bvh;
use crate::accel::simd::Lanes;
use crate::integrator::nee::ShadowRay;
use crate::integrator::tables::Tables;
use wide::{f32x8, u32x8};

/// Shadow rays, in columns (so that the hierarchy tests them 8 or 16 at a
/// time in a scene of ray packets), and the queue rows of the paths they
/// belong to. The columns hold `len` rays and room past them.
#[derive(Debug, Default)]
pub struct ShadowQueue {
    len: usize,
    row: Vec<u32>,
    origin: [Vec<f32>; 3],
    dir: [Vec<f32>; 3],
    t_max: Vec<f32>,
    radiance: [Vec<f32>; 3],
    /// Whether each ray is blocked (the stage's answers).
    occluded: Vec<bool>,
}

impl ShadowQueue {
    /// Empty it.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Queue `ray` for the path in row `row` (for tests: the light stage
    /// queues eight lanes at a time, [`ShadowQueue::push_8`]).
    #[cfg(test)]
    pub fn push(&mut self, row: u32, ray: ShadowRay<f32>) {
        use crate::math::V3;
        let lanes = ShadowRay {
            origin: V3::splat(ray.origin.into()),
            dir: V3::splat(ray.dir.into()),
            t_max: f32x8::splat(ray.t_max),
            radiance: V3::splat(ray.radiance.into()),
        };
        self.push_8(row, 1, &lanes);
    }

    /// Queue lane `l` of `rays` for the path in row `first_row + l`, for
    /// each bit `l` set in `lanes`: the set lanes, packed low, go to the
    /// end of every column at once, without a branch per lane.
    #[inline(always)]
    pub fn push_8(&mut self, first_row: u32, lanes: u8, rays: &ShadowRay<f32x8>) {
        let (start, end) = (self.len, self.len + 8);
        if self.row.len() < end {
            let room = end.max(2 * self.row.len());
            self.row.resize(room, 0);
            for c in self.columns() {
                c.resize(room, 0.0);
            }
        }
        // The numbers of the set lanes, packed low (then junk).
        let mut lane = [0u32; 8];
        let count = <f32x8 as Lanes>::compress(u32::from(lanes), 0, &mut lane);
        for (r, &l) in self.row[start..end].iter_mut().zip(&lane) {
            *r = first_row + l;
        }
        // Column by column, written out: an array of the ten vectors,
        // iterated, was copied through the stack in overlapping pieces
        // (stalled stores, a fifth of the light stage). Each column's set
        // lanes are packed low by one permutation (`vpermd` on AVX2) and
        // stored as a whole vector, rather than lane by lane.
        let index = u32x8::from(lane) & u32x8::splat(7);
        let put = |c: &mut Vec<f32>, v: f32x8| {
            let packed =
                bytemuck::cast::<u32x8, [f32; 8]>(bytemuck::cast::<f32x8, u32x8>(v).shuffle(index));
            c[start..end].copy_from_slice(&packed);
        };
        let (o, d, r) = (&rays.origin, &rays.dir, &rays.radiance);
        put(&mut self.origin[0], o.x);
        put(&mut self.origin[1], o.y);
        put(&mut self.origin[2], o.z);
        put(&mut self.dir[0], d.x);
        put(&mut self.dir[1], d.y);
        put(&mut self.dir[2], d.z);
        put(&mut self.t_max, rays.t_max);
        put(&mut self.radiance[0], r.x);
        put(&mut self.radiance[1], r.y);
        put(&mut self.radiance[2], r.z);
        self.len += count;
    }

    /// Every float column.
    fn columns(&mut self) -> [&mut Vec<f32>; 10] {
        let [ox, oy, oz] = &mut self.origin;
        let [dx, dy, dz] = &mut self.dir;
        let [rx, ry, rz] = &mut self.radiance;
        [ox, oy, oz, dx, dy, dz, &mut self.t_max, rx, ry, rz]
    }

    /// Number of rays queued.
    pub fn len(&self) -> usize {
        self.len
    }
}

/// Test every queued shadow ray (hits at `t > 0`: rays start off their
/// surface, [`crate::integrator::offset`]); for each one that nothing blocks, the
/// path's radiance gains throughput × the ray's radiance (in queue order).
/// Returns the number of rays traced.
pub fn shadow<P>(
    queue: &mut PathQueue<P>,
    shadows: &mut ShadowQueue,
    bvh: &Bvh,
    tables: &Tables,
) -> u64 {
    let n = shadows.len();
    let s = &mut *shadows;
    s.occluded.resize(n, false);
    let (o, d) = (s.origin.each_ref(), s.dir.each_ref());
    let (o, d) = (o.map(|c| &c[..n]), d.map(|c| &c[..n]));
    if tables.has_cutouts() {
        // A ray is blocked only by a surface that is there: the walk
        // passes over the hits that a cut-out lets through, as the
        // reference tracer's does.
        bvh.occluded_columns_filtered((o, d), (0.0, &s.t_max[..n]), &mut s.occluded[..n], |k| {
            tables.cutouts_of((o, d), k)
        });
    } else {
        bvh.occluded_columns(o, d, 0.0, &s.t_max[..n], &mut s.occluded[..n]);
    }
    let (radiance, beta) = (&mut queue.radiance, &queue.beta);
    for (k, _) in s.occluded[..n].iter().enumerate().filter(|(_, b)| !**b) {
        let i = s.row[k] as usize;
        for ((radiance, beta), l) in radiance.iter_mut().zip(beta).zip(&s.radiance) {
            radiance[i] += beta[i] * l[k];
        }
    }
    n as u64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::sampler::PathRng;
    use crate::math::V3;
    use crate::scene::Scene;

    /// `push_8` queues exactly the set lanes, in lane order, each with its
    /// own row and every one of its columns, for every mask, after rays
    /// already queued (the columns grow as needed).
    #[test]
    fn eight_lanes_queue_the_set_ones_in_order() {
        let mut q = ShadowQueue::default();
        let lane = |base: f32| f32x8::from(std::array::from_fn::<f32, 8, _>(|l| base + l as f32));
        let v3 = |base: f32| V3::new(lane(base), lane(base + 10.0), lane(base + 20.0));
        let mut want: Vec<(u32, [f32; 10])> = Vec::new();
        for mask in 0..=255u8 {
            let b = f32::from(mask) * 100.0;
            let rays = ShadowRay {
                origin: v3(b),
                dir: v3(b + 30.0),
                t_max: lane(b + 60.0),
                radiance: v3(b + 70.0),
            };
            q.push_8(1000 * u32::from(mask), mask, &rays);
            for l in (0..8).filter(|l| mask & (1 << l) != 0) {
                let x = l as f32;
                let cols =
                    [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0].map(|o| b + o + x);
                want.push((1000 * u32::from(mask) + l, cols));
            }
            assert_eq!(q.len(), want.len(), "mask {mask:#010b}");
        }
        let got_cols = |k: usize| {
            let (o, d, r) = (&q.origin, &q.dir, &q.radiance);
            [
                o[0][k], o[1][k], o[2][k], d[0][k], d[1][k], d[2][k], q.t_max[k], r[0][k], r[1][k],
                r[2][k],
            ]
        };
        for (k, (row, cols)) in want.iter().enumerate() {
            assert_eq!((q.row[k], got_cols(k)), (*row, *cols), "ray {k}");
        }
        q.clear();
        assert_eq!(q.len(), 0);
    }

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
                if bvh.occluded(o, dir, 0.0, t_max) {
                    blocked += 1;
                    continue;
                }
                for c in 0..3 {
                    expected[row][c] += queue.beta[c][row] * l[c];
                }
            }
            let tables = Tables::new(&scene);
            assert_eq!(shadow(&mut queue, &mut shadows, &bvh, &tables), rows as u64);
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
