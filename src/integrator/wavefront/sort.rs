//! Stage *sort*: group the live paths by the material model they hit, so
//! that the *light* and *bounce* stages run each model's routine on whole
//! runs of rows, eight at a time, with no branch per lane.

use super::queue::PathQueue;
use crate::integrator::tables::Tables;
use crate::scene::Model;
use std::ops::Range;

/// The live rows grouped by model: one range per model present, in the
/// order of [`Model::ALL`]. A scene of one model is not touched (one range
/// over every row); otherwise the rows are sorted in place, in one pass
/// that counts and one that swaps each row into its group (an American
/// flag sort). The order of the paths changes nothing else: each path
/// has its own numbers, and the film's sums are exact.
pub fn sort_by_model<P: Copy>(
    queue: &mut PathQueue<P>,
    tables: &Tables,
) -> Vec<(Model, Range<usize>)> {
    let n = queue.len();
    if let Some(model) = tables.single_model() {
        return vec![(model, 0..n)];
    }
    let key = |q: &PathQueue<P>, i: usize| tables.model_of(q.hit[i]) as usize;
    let mut count = [0usize; Model::ALL.len()];
    for i in 0..n {
        count[key(queue, i)] += 1;
    }
    let mut start = [0usize; Model::ALL.len()];
    for k in 1..start.len() {
        start[k] = start[k - 1] + count[k - 1];
    }
    let mut next = start;
    for k in 0..Model::ALL.len() {
        let end = start[k] + count[k];
        while next[k] < end {
            let i = next[k];
            let home = key(queue, i);
            if home == k {
                next[k] += 1;
            } else {
                queue.swap_rows(i, next[home]);
                next[home] += 1;
            }
        }
    }
    Model::ALL
        .iter()
        .enumerate()
        .filter(|&(k, _)| count[k] > 0)
        .map(|(k, &model)| (model, start[k]..start[k] + count[k]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// Every row lands in the range of its model, whole, and none is lost.
    #[test]
    fn rows_are_grouped_by_model_and_kept_whole() {
        let mut scene = Scene::cornell();
        for (i, m) in scene.materials.iter_mut().enumerate() {
            m.model = Model::ALL[i % Model::ALL.len()];
        }
        let tables = Tables::new(&scene);
        let tris = scene.triangles.len();
        for n in [0, 1, 7, 8, 9, 100, 1000] {
            let mut q = PathQueue::<u64>::with_capacity(n.max(1));
            q.set_len(n);
            for i in 0..n {
                q.hit[i] = ((i * 7919) % tris) as u32;
                q.pixel[i] = i as u32;
                q.sampler[i] = 10 * i as u64;
                q.t[i] = i as f32;
            }
            let before = q.clone();
            let bins = sort_by_model(&mut q, &tables);
            let mut seen = vec![false; n];
            let mut covered = 0;
            for (model, rows) in &bins {
                assert_eq!(rows.start, covered, "ranges tile the queue");
                covered = rows.end;
                for r in rows.clone() {
                    assert_eq!(tables.model_of(q.hit[r]), *model);
                    let i = q.pixel[r] as usize;
                    assert!(!seen[i]);
                    seen[i] = true;
                    assert_eq!(
                        (q.hit[r], q.sampler[r], q.t[r]),
                        (before.hit[i], before.sampler[i], before.t[i])
                    );
                }
            }
            assert_eq!(covered, n);
            assert!(seen.iter().all(|&s| s));
        }
    }
}
