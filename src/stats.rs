//! The `--stats` file: what was rendered, how long it took, how fast.

use serde::Serialize;

/// Figures of one render, written as JSON by `--stats`.
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// wavetrace's version.
    pub version: &'static str,
    /// Scene name.
    pub scene: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel rendered.
    pub spp: u64,
    /// Maximum path depth.
    pub max_depth: u32,
    /// Random seed.
    pub seed: u64,
    /// Worker threads.
    pub threads: usize,
    /// Engine name.
    pub engine: &'static str,
    /// Wall-clock seconds of the render (not loading or writing).
    pub seconds: f64,
    /// Camera paths traced.
    pub paths: u64,
    /// Rays cast (closest-hit queries).
    pub rays: u64,
    /// `rays / seconds`.
    pub rays_per_second: f64,
    /// `paths / seconds`.
    pub paths_per_second: f64,
    /// Samples refused as NaN, infinite or negative (should be 0).
    pub invalid_samples: u64,
    /// Triangles in the scene.
    pub triangles: usize,
    /// Inner nodes of the bounding volume hierarchy (0 without one).
    pub bvh_nodes: usize,
    /// Wall-clock seconds spent building the hierarchy.
    pub build_seconds: f64,
    /// Memory held by the hierarchy's nodes and triangle packs, in bytes.
    pub bvh_bytes: usize,
    /// The image written, if any.
    pub output: Option<String>,
}

impl RenderStats {
    /// The stats as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("stats serialise")
    }
}
