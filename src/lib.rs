//! wavetrace: a fast, reproducible CPU path tracer.
//!
//! The modules follow the data flow of a render, each layer using only
//! its own modules and those of the layers before it (`tests/architecture.rs`
//! checks it, and that no two modules use each other). The layers, in order:
//! `math`, `fs` → `scene` → `accel` → `film` → `integrator` → `output`,
//! `metrics`, `denoise` → `render` → `run` → `cli`.
//!
//! 1. [`scene`]: the input — camera, materials, triangles; TOML scene
//!    files, OBJ meshes, generated meshes, the built-in Cornell box. Knows
//!    nothing of how it is rendered.
//! 2. [`accel`]: which surface a ray hits first — Möller–Trumbore in 8-wide
//!    packs and the bounding volume hierarchy, built from the scene.
//! 3. [`film`]: exact per-pixel sums of samples, and their file format
//!    (`.wtacc`).
//! 4. [`integrator`]: what a path does at a vertex — the sampler, the
//!    scattering routine of each material model — and the two engines that
//!    trace paths: the scalar recursive [reference
//!    tracer](integrator::reference) (the oracle) and the SIMD
//!    [wavefront engine](integrator::wavefront) (the default).
//! 5. [`output`]: images (PNG, EXR, PFM) and accumulation files, written
//!    whole or not at all (and read back); [`metrics`]: an image's errors
//!    against a reference (MSE, relMSE, mean ꟻLIP); [`denoise`]: Intel Open
//!    Image Denoise, loaded at run time.
//! 6. [`render`]: the settings of a render and the [`Renderer`](render::Renderer):
//!    one tile loop, on its own thread pool, for both engines.
//! 7. [`run`]: long renders in sample passes (time limits, checkpoints,
//!    signals), farm shards and merges; the benchmark suite
//!    ([`run::bench`]) and convergence studies ([`run::converge`],
//!    [`run::plot`]). Library code: it parses no arguments and prints
//!    nothing.
//! 8. [`cli`]: the `wavetrace` command — flags, progress bar, messages and
//!    exit statuses.
//!
//! Beside them: [`math`] (the one numeric source of scalar and 8-wide
//! kernels), [`fs`] (atomic writes) and [`error`] (the library's [`Error`],
//! which wraps the typed errors of every layer).
//!
//! # Example
//!
//! Render the built-in Cornell box at 32×32 pixels, 4 samples per pixel,
//! and read a pixel back:
//!
//! ```
//! use wavetrace::render::{RenderSettings, Renderer};
//! use wavetrace::scene::Scene;
//!
//! let scene = Scene::cornell();
//! let mut settings = RenderSettings::for_scene(&scene);
//! (settings.width, settings.height, settings.spp, settings.threads) = (32, 32, 4, 2);
//! let renderer = Renderer::new(&scene, &settings)?;
//! let (film, counters, _seconds) = renderer.render();
//! assert_eq!(film.samples_per_pixel(), 4);
//! assert_eq!(counters.paths, 32 * 32 * 4);
//! let rgb = film.to_rgb(); // linear RGB, row-major, row 0 at the top
//! assert!(rgb.iter().all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0)));
//! // Same seed, same bits, whatever the thread count:
//! settings.threads = 1;
//! assert_eq!(Renderer::new(&scene, &settings)?.render().0, film);
//! # Ok::<(), wavetrace::Error>(())
//! ```

#![warn(missing_docs)]

pub mod accel;
pub mod cli;
pub mod denoise;
pub mod error;
pub mod film;
pub mod fs;
pub mod integrator;
pub mod math;
pub mod metrics;
pub mod output;
pub mod render;
pub mod run;
pub mod scene;

pub use error::{Error, Result};
