//! Texture lookups 8 and 16 lanes at a time (issue 30): the lanes
//! (`integrator::texture::sample_lanes`: the wrap, the weights and the
//! filter in lanes, the texels gathered from 4 × 4 tiles) against the way
//! before them (`sample_by_lane`: the scalar `Texture::sample` lane by
//! lane, which is also the lanes' oracle), on a 1024² and a 4096² sRGB
//! texture, bilinear with `REPEAT`, for 4096 coherent lookups (a 64 × 64
//! patch of the screen, one lookup per texel across, row after row) and
//! 4096 incoherent ones (uniform over the image).
//!
//! ```sh
//! cargo bench --bench texture
//! WAVETRACE_BENCH_SUMMARY_ONLY=1 cargo bench --bench texture   # medians only
//! ```
//!
//! Before the criterion group a summary prints, for each case, the median
//! nanoseconds per lookup of 31 timings of each way, interleaved, and
//! their ratio.

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::time::Instant;
use wavetrace::accel::simd::SimdWidth;
use wavetrace::integrator::texture::{LaneLookup, sample_columns};
use wavetrace::scene::texture::{ColourSpace, Sampler, Texture};

/// Lookups per timing.
const N: usize = 4096;

/// A `side × side` sRGB texture of hashed texels.
fn texture(side: usize) -> Texture {
    let bytes: Vec<u8> = (0..side * side)
        .flat_map(|k| ((k as u32).wrapping_mul(0x9e37_79b9) ^ 0x1234_5678).to_le_bytes())
        .collect();
    Texture::from_rgba8_bytes(side, side, &bytes, ColourSpace::Srgb).unwrap()
}

/// `N` coordinates: `coherent`, a 64 × 64 patch one texel apart, rows in
/// order, at an offset of a third of the image; else uniform over it.
fn coordinates(side: usize, coherent: bool) -> (Vec<f32>, Vec<f32>) {
    let mut k = 7u32;
    let mut next = || {
        k = k.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (k >> 8) as f32 / (1u32 << 24) as f32
    };
    let texel = 1.0 / side as f32;
    (0..N)
        .map(|n| {
            if coherent {
                let (i, j) = ((n % 64) as f32, (n / 64) as f32);
                (
                    1.0 / 3.0 + (i + 0.37) * texel,
                    1.0 / 3.0 + (j + 0.61) * texel,
                )
            } else {
                (next(), next())
            }
        })
        .unzip()
}

struct Case {
    name: String,
    texture: Texture,
    u: Vec<f32>,
    v: Vec<f32>,
    width: SimdWidth,
}

fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    for side in [1024, 4096] {
        let t = texture(side);
        for coherent in [true, false] {
            let (u, v) = coordinates(side, coherent);
            for width in SimdWidth::available() {
                out.push(Case {
                    name: format!(
                        "{side}²/{}/{}",
                        if coherent { "coherent" } else { "incoherent" },
                        width.lanes()
                    ),
                    texture: t.clone(),
                    u: u.clone(),
                    v: v.clone(),
                    width,
                });
            }
        }
    }
    out
}

fn run(c: &Case, how: LaneLookup, out: &mut [Vec<f32>; 4]) {
    let [r, g, b, a] = out;
    sample_columns(
        black_box(&c.texture),
        Sampler::default(),
        (c.width, how),
        (&c.u, &c.v),
        [r, g, b, a],
    );
    black_box(&out);
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// What the tiles cost at load, for a 1024² image: laying its RGBA bytes
/// out in tiles (`Texture::from_rgba8_bytes`) against copying them as
/// texels (what the decoder's output took before), and reading the rows
/// back for the content hash against hashing the bytes as they are;
/// medians of 31.
fn layout_at_load() {
    let side = 1024;
    let bytes: Vec<u8> = (0..side * side * 4).map(|k| (k * 7 % 251) as u8).collect();
    let time = |f: &mut dyn FnMut()| {
        let mut t = Vec::new();
        for _ in 0..31 {
            let start = Instant::now();
            f();
            t.push(start.elapsed().as_secs_f64() * 1e3);
        }
        median(t)
    };
    let tiles = time(&mut || {
        black_box(
            Texture::from_rgba8_bytes(side, side, black_box(&bytes), ColourSpace::Srgb).unwrap(),
        );
    });
    let copy = time(&mut || {
        let texels: Vec<[u8; 4]> = black_box(&bytes)
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect();
        black_box(texels);
    });
    let t = Texture::from_rgba8_bytes(side, side, &bytes, ColourSpace::Srgb).unwrap();
    let rows = time(&mut || {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        black_box(&t).for_each_row(|row| h.update(row));
        black_box(h.digest128());
    });
    let flat = time(&mut || {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(black_box(&bytes));
        black_box(h.digest128());
    });
    println!(
        "1024² at load (ms, medians of 31): into tiles {tiles:.3} (a copy as texels: {copy:.3}); \
         the rows hashed from the tiles {rows:.3} (the bytes hashed as they are: {flat:.3})"
    );
}

fn bench(cr: &mut Criterion) {
    let cases = cases();
    let mut out: [Vec<f32>; 4] = std::array::from_fn(|_| vec![0.0; N]);
    println!("texture lookups, ns a lookup (medians of 31, the two ways interleaved):");
    for c in &cases {
        let (mut before, mut after) = (Vec::new(), Vec::new());
        for _ in 0..31 {
            for (how, times) in [
                (LaneLookup::ByLane, &mut before),
                (LaneLookup::Lanes, &mut after),
            ] {
                let t = Instant::now();
                for _ in 0..8 {
                    run(c, how, &mut out);
                }
                times.push(t.elapsed().as_secs_f64() * 1e9 / (8 * N) as f64);
            }
        }
        let (b, a) = (median(before), median(after));
        println!(
            "  {:<22} by lane {b:6.2}  lanes {a:6.2}  ratio {:.2}×",
            c.name,
            b / a
        );
    }
    layout_at_load();
    if std::env::var("WAVETRACE_BENCH_SUMMARY_ONLY").is_ok() {
        return;
    }
    let mut g = cr.benchmark_group("texture");
    g.sample_size(20);
    g.measurement_time(std::time::Duration::from_secs(2));
    g.warm_up_time(std::time::Duration::from_millis(500));
    for c in &cases {
        for (how, name) in [
            (LaneLookup::ByLane, "by_lane"),
            (LaneLookup::Lanes, "lanes"),
        ] {
            g.bench_function(format!("{}/{name}", c.name), |b| {
                b.iter(|| run(c, how, &mut out))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
