//! The `sobol` sampler seen from outside the crate, and a guard that adding
//! it left the `independent` sampler's images byte for byte as they were.

use wavetrace::film::Film;
use wavetrace::integrator::sampler::{Sampler, Sobol, SobolPath};
use wavetrace::render::{Engine, RenderSettings, Renderer};
use wavetrace::scene::Scene;

const SEEDS: [u64; 3] = [0, 1, 0xDEAD_BEEF_CAFE];
const PIXELS: [u32; 4] = [0, 1, 70_000, u32::MAX];

/// Whether `2^m` points in `[0, 1)²` (as `f32`s with 24 bits, so exact in
/// `f64`) form a (0,m,2)-net: every elementary interval of area `2^-m`
/// holds exactly one.
fn is_net(points: &[[f32; 2]]) -> bool {
    let n = points.len();
    assert!(n.is_power_of_two());
    let m = n.trailing_zeros();
    (0..=m).all(|a| {
        let b = m - a;
        let mut seen = vec![false; n];
        points.iter().all(|&[x, y]| {
            let cx = (x as f64 * (1u64 << a) as f64) as usize;
            let cy = (y as f64 * (1u64 << b) as f64) as usize;
            !std::mem::replace(&mut seen[cx << b | cy], true)
        })
    })
}

#[test]
fn each_pixels_pairs_of_dimensions_are_0_2_sequences_by_global_index() {
    // Dimensions (2g, 2g + 1) of samples [k 2^m, (k+1) 2^m): the first
    // 2^m samples, a later pass or shard of that size (samples 64..128 are
    // k = 1, m = 6), drawn through the Sampler API from even dimensions.
    for seed in SEEDS {
        let sobol = Sobol::new(seed);
        for pixel in PIXELS {
            for m in 0..=12u32 {
                let n = 1u32 << m;
                for k in [0, 1, 3] {
                    let mut paths: Vec<SobolPath> = (k * n..(k + 1) * n)
                        .map(|i| sobol.start(pixel, i))
                        .collect();
                    for g in 0..6 {
                        // Dimensions 0..12: pairs by next_2d, then by next.
                        let points: Vec<[f32; 2]> = paths
                            .iter_mut()
                            .map(|p| {
                                if g % 2 == 0 {
                                    sobol.next_2d(p)
                                } else {
                                    [sobol.next(p), sobol.next(p)]
                                }
                            })
                            .collect();
                        assert!(
                            is_net(&points),
                            "seed {seed} pixel {pixel} samples {}..{} dims {}, {}",
                            k * n,
                            (k + 1) * n,
                            2 * g,
                            2 * g + 1
                        );
                    }
                }
            }
        }
    }
    // And deep in a path: dimensions 4998 and 4999 (depth 1024 territory).
    let sobol = Sobol::new(5);
    for m in [4, 10] {
        let points: Vec<[f32; 2]> = (0..1u32 << m)
            .map(|i| [sobol.get(9, i, 4998), sobol.get(9, i, 4999)])
            .collect();
        assert!(is_net(&points));
    }
}

#[test]
fn a_number_is_the_same_however_it_is_reached() {
    let sobol = Sobol::new(3);
    // In order, as a path draws it, or fresh by (pixel, sample, dimension).
    for (pixel, sample) in [(0, 0), (12, 345), (u32::MAX, u32::MAX)] {
        let mut path = sobol.start(pixel, sample);
        for dim in 0..5000 {
            assert_eq!(path.dim(), dim);
            let x = sobol.next(&mut path);
            assert_eq!(x.to_bits(), sobol.get(pixel, sample, dim).to_bits());
        }
        assert_eq!((path.pixel(), path.sample()), (pixel, sample));
    }
    // next_2d is two nexts, from an even or an odd dimension.
    for skip in 0..4 {
        let (mut a, mut b) = (sobol.start(7, 9), sobol.start(7, 9));
        for _ in 0..skip {
            sobol.next(&mut a);
            sobol.next(&mut b);
        }
        for _ in 0..50 {
            let [x, y] = sobol.next_2d(&mut a);
            assert_eq!([x, y], [sobol.next(&mut b), sobol.next(&mut b)]);
        }
    }
    // Many paths drawn interleaved in a scrambled order, with other
    // samplers' and pixels' draws in between: each number is still its
    // own (seed, pixel, sample, dimension)'s.
    let other = Sobol::new(4);
    let mut paths: Vec<(u32, u32, SobolPath)> = (0..64u32)
        .map(|k| {
            let (pixel, sample) = (k * 37 % 11, k / 3);
            (pixel, sample, sobol.start(pixel, sample))
        })
        .collect();
    let mut noise = other.start(1, 1);
    let mut state = 1u32;
    for _ in 0..20_000 {
        state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
        let (pixel, sample, path) = &mut paths[(state >> 26) as usize];
        let dim = path.dim();
        let x = sobol.next(path);
        assert_eq!(x.to_bits(), sobol.get(*pixel, *sample, dim).to_bits());
        other.next(&mut noise);
    }
}

#[test]
fn scrambling_depends_on_seed_pixel_and_dimension() {
    let seq = |seed: u64, pixel: u32, dim: u32| -> Vec<u32> {
        let s = Sobol::new(seed);
        (0..32).map(|i| s.get(pixel, i, dim).to_bits()).collect()
    };
    let base = seq(1, 5, 0);
    assert_eq!(base, seq(1, 5, 0));
    assert_eq!(Sobol::new(1), Sobol::new(1));
    for other in [
        seq(2, 5, 0),
        seq(1, 6, 0),
        seq(1, 5, 1),
        seq(1, 5, 2),
        seq(1, 5, 4999),
    ] {
        assert_ne!(base, other);
        // Not merely shifted or reordered: most numbers differ.
        let mut a = base.clone();
        let mut b = other.clone();
        a.sort();
        b.sort();
        let same = a.iter().filter(|x| b.binary_search(x).is_ok()).count();
        assert!(same <= 1, "{same} numbers in common");
    }
    // Neighbouring pixels of one seed never share a sequence.
    let mut firsts: Vec<Vec<u32>> = (0..512).map(|p| seq(1, p, 0)[..4].to_vec()).collect();
    firsts.sort();
    firsts.dedup();
    assert_eq!(firsts.len(), 512);
}

#[test]
fn passes_resumes_and_shards_draw_the_same_numbers() {
    // A number knows nothing of how many samples the render takes: samples
    // 0..256 drawn at once equal them drawn in passes, by separate
    // samplers (a resumed process, a farm node).
    let draw = |samples: std::ops::Range<u32>| -> Vec<u32> {
        let s = Sobol::new(77);
        samples
            .flat_map(|i| {
                let mut p = s.start(1234, i);
                (0..8).map(move |_| s.next(&mut p).to_bits())
            })
            .collect()
    };
    let whole = draw(0..256);
    let parts: Vec<u32> = [0..64, 64..200, 200..256]
        .into_iter()
        .flat_map(draw)
        .collect();
    assert_eq!(whole, parts);
}

#[test]
fn numbers_are_in_the_unit_interval() {
    let sobol = Sobol::new(u64::MAX);
    let mut lo = f32::MAX;
    let mut hi = f32::MIN;
    for pixel in [0, 1, u32::MAX] {
        for sample in (0..4096).chain(u32::MAX - 4096..=u32::MAX) {
            let mut p = sobol.start(pixel, sample);
            for _ in 0..8 {
                let x = sobol.next(&mut p);
                assert!((0.0..1.0).contains(&x), "{x}");
                (lo, hi) = (lo.min(x), hi.max(x));
            }
        }
    }
    // 4096 samples of a dimension fill [0, 1) to within 1/4096.
    assert!(lo < 1.0 / 4096.0 && hi > 1.0 - 1.0 / 4096.0, "{lo} {hi}");
}

#[test]
fn a_sobol_path_is_16_bytes_of_plain_data() {
    assert_eq!(std::mem::size_of::<SobolPath>(), 16);
    let sobol = Sobol::new(1);
    let p = sobol.start(3, 4);
    let bytes: &[u8] = bytemuck::bytes_of(&p);
    assert_eq!(bytemuck::pod_read_unaligned::<SobolPath>(bytes), p);
}

/// An xxh3 of everything a film holds: its size, sums, sample ranges and
/// refused samples.
fn film_hash(film: &Film) -> u64 {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(&film.width.to_le_bytes());
    h.update(&film.height.to_le_bytes());
    for s in &film.sums {
        for c in s {
            h.update(&c.to_le_bytes());
        }
    }
    for r in &film.ranges {
        h.update(&r.start.to_le_bytes());
        h.update(&r.end.to_le_bytes());
    }
    h.update(&film.invalid_samples.to_le_bytes());
    h.digest()
}

fn render(scene: &Scene, engine: Engine, seed: u64, max_depth: u32) -> Film {
    let mut s = RenderSettings::for_scene(scene).report();
    (s.width, s.height, s.spp, s.max_depth) = (32, 24, 8, max_depth);
    (s.seed, s.threads, s.engine) = (seed, 2, engine);
    Renderer::new(scene, &s).unwrap().render().0
}

/// The films of the report's estimator with the `independent` sampler are
/// those of the commit before the sampler module became a directory with
/// `sobol` in it (92df1c6, where the engines traced the report's estimator
/// only): these hashes were taken there, with this very test. Both engines, two scenes, a short and a deep path.
/// Since then one change moved rays on purpose: rays leave surfaces from
/// points offset by a bound local to the hit (issue 25, not a scene-wide
/// `10⁻⁴ × extent`), which changed the two deep `cornell-obj` films (the
/// others' fixed-point sums came out the same) and the fingerprint.
#[test]
fn independent_images_are_byte_identical_to_before_sobol() {
    const BEFORE: [(&str, Engine, u64, u32, u64); 8] = [
        ("cornell", Engine::Reference, 0, 3, 0xf47371800d87320c),
        ("cornell", Engine::Reference, 7, 12, 0x513eb0155aafcf57),
        ("cornell", Engine::Wavefront, 0, 3, 0xe39feb811de270ba),
        ("cornell", Engine::Wavefront, 7, 12, 0x6cdf1afe5f2923f6),
        ("cornell-obj", Engine::Reference, 0, 3, 0x3b488a04a2e639e0),
        ("cornell-obj", Engine::Reference, 7, 12, 0xefccf4fb35cf1e92),
        ("cornell-obj", Engine::Wavefront, 0, 3, 0xcd689bdccdac1a85),
        ("cornell-obj", Engine::Wavefront, 7, 12, 0x8f3b15f22cf270de),
    ];
    let cornell = Scene::cornell();
    let obj = Scene::load(std::path::Path::new("scenes/cornell-obj.toml")).unwrap();
    for (name, engine, seed, depth, want) in BEFORE {
        let scene = if name == "cornell" { &cornell } else { &obj };
        let got = film_hash(&render(scene, engine, seed, depth));
        assert_eq!(
            got, want,
            "{name} {engine:?} seed {seed} depth {depth}: {got:#018x}"
        );
    }
    // The settings hash of checkpoints and shards sees the same build.
    assert_eq!(
        wavetrace::integrator::estimator_fingerprint(),
        FINGERPRINT_BEFORE,
        "{:#018x}",
        wavetrace::integrator::estimator_fingerprint()
    );
}

/// `estimator_fingerprint()` at 92df1c6 was `0xa1445333b9c5e092`; the
/// local ray offset (issue 25) added its probe (`0x9f7d42d6e0dc45a3`), and
/// the environment's own `atan2` (issue 30: no longer the system's
/// `atan2f` and `acosf`) its.
const FINGERPRINT_BEFORE: u64 = 0xfea7d4c5134a7323;
