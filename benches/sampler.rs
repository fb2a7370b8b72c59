//! The samplers' cost per number: `Independent` (keyed PCG streams) against
//! `Sobol` (Owen-scrambled Sobol points, Burley 2020), drawn the way the
//! wavefront engine draws them — a batch of paths started together, then
//! one dimension at a time across all of the batch's lanes.
//!
//! Two ways of drawing: `next` (one number at a time) and `next_2d` (pairs,
//! from even dimensions). Each count includes starting the paths
//! (`Sampler::start`), spread over the numbers they draw.
//!
//! Before the criterion groups, a summary prints the medians of 301
//! interleaved runs of one batch of each (wall time), in ns per number,
//! measured in the same run.
//! `WAVETRACE_BENCH_SUMMARY_ONLY=1` stops after the summary.
//!
//! ```sh
//! cargo bench --bench sampler
//! ```

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::time::Instant;
use wavetrace::integrator::sampler::{Independent, Sampler, Sobol};

/// Paths per batch (a wavefront batch's lanes).
const LANES: u32 = 4096;
/// Numbers per path: the camera's two and seven 2D draws (what a path of
/// a few bounces with light sampling takes).
const DIMS: u32 = 16;
/// Numbers per batch.
const NUMBERS: u64 = LANES as u64 * DIMS as u64;

/// A batch's lanes: each path's state and a column its numbers go to.
struct Lanes<P> {
    paths: Vec<P>,
    out: Vec<f32>,
}

impl<P> Lanes<P> {
    fn new() -> Self {
        Self {
            paths: Vec::with_capacity(LANES as usize),
            out: vec![0.0; LANES as usize],
        }
    }
}

/// One batch of `next` draws: start every lane, then dimension by
/// dimension across the lanes, each lane adding its numbers into its own
/// slot of a column (no chain of dependent additions across lanes).
fn batch_1d<S: Sampler>(s: &S, lanes: &mut Lanes<S::Path>, pass: u32) -> f32 {
    lanes.paths.clear();
    lanes
        .paths
        .extend((0..LANES).map(|p| s.start(p * 7 + 3, pass)));
    for _ in 0..DIMS {
        for (path, out) in lanes.paths.iter_mut().zip(&mut lanes.out) {
            *out += s.next(path);
        }
    }
    lanes.out[(pass % LANES) as usize]
}

/// As [`batch_1d`], drawing pairs with `next_2d`.
fn batch_2d<S: Sampler>(s: &S, lanes: &mut Lanes<S::Path>, pass: u32) -> f32 {
    lanes.paths.clear();
    lanes
        .paths
        .extend((0..LANES).map(|p| s.start(p * 7 + 3, pass)));
    for _ in 0..DIMS / 2 {
        for (path, out) in lanes.paths.iter_mut().zip(&mut lanes.out) {
            let [a, b] = s.next_2d(path);
            *out += a + b;
        }
    }
    lanes.out[(pass % LANES) as usize]
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Medians of interleaved runs, ns per number, printed.
fn summary() {
    let (ind, sob) = (Independent::new(1), Sobol::new(1));
    let (mut pi, mut ps) = (Lanes::new(), Lanes::new());
    let mut t: [Vec<f64>; 4] = Default::default();
    // Short runs (one batch, under a millisecond) are seldom preempted on a
    // busy machine, so their median is the sampler's own speed.
    const RUNS: u32 = 301;
    for run in 0..RUNS {
        let mut time = |k: usize, f: &mut dyn FnMut(u32) -> f32| {
            let start = Instant::now();
            black_box(f(run));
            t[k].push(start.elapsed().as_secs_f64() * 1e9 / NUMBERS as f64);
        };
        time(0, &mut |p| batch_1d(&ind, &mut pi, p));
        time(1, &mut |p| batch_1d(&sob, &mut ps, p));
        time(2, &mut |p| batch_2d(&ind, &mut pi, p));
        time(3, &mut |p| batch_2d(&sob, &mut ps, p));
    }
    let [a, b, c, d] = t.map(median);
    println!("sampler summary: ns per number, median of {RUNS} interleaved runs of one batch");
    println!(
        "  next     independent {a:6.2}  sobol {b:6.2}  (sobol/independent {:.2})",
        b / a
    );
    println!(
        "  next_2d  independent {c:6.2}  sobol {d:6.2}  (sobol/independent {:.2})",
        d / c
    );
}

fn benches(c: &mut Criterion) {
    summary();
    if std::env::var_os("WAVETRACE_BENCH_SUMMARY_ONLY").is_some() {
        return;
    }
    let (ind, sob) = (Independent::new(1), Sobol::new(1));
    for (name, pairs) in [("sampler_next", false), ("sampler_next_2d", true)] {
        let mut group = c.benchmark_group(name);
        group.throughput(Throughput::Elements(NUMBERS));
        let mut pass = 0;
        let mut paths = Lanes::new();
        group.bench_function("independent", |b| {
            b.iter(|| {
                pass += 1;
                if pairs {
                    batch_2d(&ind, &mut paths, pass)
                } else {
                    batch_1d(&ind, &mut paths, pass)
                }
            })
        });
        let mut paths = Lanes::new();
        group.bench_function("sobol", |b| {
            b.iter(|| {
                pass += 1;
                if pairs {
                    batch_2d(&sob, &mut paths, pass)
                } else {
                    batch_1d(&sob, &mut paths, pass)
                }
            })
        });
        group.finish();
    }
}

criterion_group!(sampler_benches, benches);
criterion_main!(sampler_benches);
