//! wavetrace: a fast, reproducible CPU path tracer.
//!
//! The data flow of a render:
//!
//! - [`scene`]: the scene (TOML files, the built-in Cornell box);
//! - [`camera`]: camera rays, jittered over each pixel;
//! - [`sampling`]: per-sample random streams and hemisphere sampling;
//! - [`mesh`]: generated meshes (spheres, terrain) for big scenes;
//! - [`geometry`]: Möller–Trumbore ray/triangle intersection;
//! - [`bvh`]: the 8-wide bounding volume hierarchy over the triangles;
//! - [`reference`](mod@reference): the scalar recursive reference tracer (the oracle);
//! - [`wavefront`]: the SIMD wavefront engine (generate → intersect →
//!   shade → bounce), the default;
//! - [`film`]: exact fixed-point accumulation of samples;
//! - [`output`]: PNG, EXR and PFM images, written atomically;
//! - [`render`]: settings and the driver that runs an engine;
//! - [`session`]: the render loop, in sample passes: progress, time
//!   limits, checkpoints and resume, for a whole render or one shard;
//! - [`shard`], [`merge`]: render farms: sample-range shards, exact merges;
//! - [`cli`], [`profile`], [`stats`]: the command line and what it reports.
//!
//! [`real`] holds the one numeric source shared by scalar and 8-wide code.

#![warn(missing_docs)]

pub mod accel;
pub mod cli;
pub mod error;
pub mod film;
pub mod fs;
pub mod integrator;
pub mod math;
pub mod output;
pub mod render;
pub mod run;
pub mod scene;

pub use error::{Error, Result};
