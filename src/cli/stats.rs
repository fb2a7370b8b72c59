//! The `--stats` file: what was rendered, how long it took, how fast, and on
//! what — the machine, the build and the instruction set — so benchmark
//! results can be compared.

use serde::Serialize;
use std::collections::BTreeMap;

/// Figures of one render, written as JSON by `--stats`.
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// wavetrace's version.
    pub version: &'static str,
    /// The git commit wavetrace was built from ([`GIT_COMMIT`]).
    pub git_commit: &'static str,
    /// The CPU model ([`cpu_model`]).
    pub cpu_model: String,
    /// The SIMD instruction set the build uses ([`SIMD`]).
    pub simd: &'static str,
    /// Lanes of the intersection kernels that ran: 8 (AVX2) or 16
    /// (AVX-512, chosen at run time).
    pub kernel_lanes: usize,
    /// Scene name.
    pub scene: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel in the image (or partial file), including those
    /// of a resumed checkpoint: the samples actually done, which a time
    /// limit, a signal, or a shard (see `samples`) makes fewer than
    /// `spp_requested`.
    pub spp: u64,
    /// Samples per pixel of the whole render asked for (`--spp`).
    pub spp_requested: u32,
    /// Samples per pixel the resumed checkpoint held (0 for a new render).
    pub spp_resumed: u64,
    /// The sample indices `[A, B)` this run was to render: `[0, spp]` for a
    /// whole render, else `--samples A..B` or the shard's range. `spp` is
    /// what it holds of them.
    pub samples: [u32; 2],
    /// `[index, count]` when rendering a shard (`--shard`), else null.
    pub shard: Option<[u32; 2]>,
    /// Maximum path depth.
    pub max_depth: u32,
    /// Random seed.
    pub seed: u64,
    /// Worker threads.
    pub threads: usize,
    /// Engine name.
    pub engine: &'static str,
    /// Integrator name.
    pub integrator: &'static str,
    /// Sampler name.
    pub sampler: &'static str,
    /// The depth from which Russian roulette may end paths, if it may.
    pub rr_depth: Option<u32>,
    /// The AOVs accumulated (`--aov`, and albedo and normal for
    /// `--denoise`), in canonical order.
    pub aov: Vec<&'static str>,
    /// Why the render stopped: "complete", "time-limit", "SIGINT" or
    /// "SIGTERM".
    pub stop: &'static str,
    /// The `--time-limit`, in seconds.
    pub time_limit_seconds: Option<f64>,
    /// Sample passes rendered by this run.
    pub passes: u32,
    /// Seconds of this run's longest pass.
    pub longest_pass_seconds: f64,
    /// Wall-clock seconds this run spent rendering: the sum of its passes
    /// (not loading, checkpoints or writing; see `stages`).
    pub seconds: f64,
    /// Wall-clock seconds from the first pass to the stop, including the
    /// checkpoints and partial images written in between; this is what
    /// `--time-limit` bounds.
    pub elapsed_seconds: f64,
    /// Camera paths traced by this run.
    pub paths: u64,
    /// Rays cast by this run: closest-hit queries and shadow rays.
    pub rays: u64,
    /// Of `rays`, the shadow rays (occlusion queries toward a light).
    pub shadow_rays: u64,
    /// `rays / seconds`.
    pub rays_per_second: f64,
    /// `paths / seconds`.
    pub paths_per_second: f64,
    /// Samples refused as NaN, infinite or negative (should be 0), in the
    /// whole image.
    pub invalid_samples: u64,
    /// Seconds of each stage of this run ([`Stages`]).
    pub stages: Stages,
    /// CPU-seconds of each stage inside the engine's passes (summed over
    /// the threads and the passes), by stage name. Empty for engines that do not time their
    /// stages (the reference tracer).
    pub engine_stages: BTreeMap<&'static str, f64>,
    /// Of those CPU-seconds, the ones spent looking textures up and making
    /// the material parameters they give (inside the *light*, *bounce* and
    /// *shade* stages: not a stage of its own; 0 without textures).
    pub texture_seconds: f64,
    /// The checkpoint file, if any.
    pub checkpoint: Option<String>,
    /// Checkpoints saved by this run, the last one included.
    pub checkpoints_saved: u32,
    /// Partial images written (`--write-partial`).
    pub partial_images: u32,
    /// Triangles in the scene.
    pub triangles: usize,
    /// Meshes of the assets placed (glTF, PLY, OBJ), each counted once.
    pub meshes: usize,
    /// Placements of those meshes.
    pub instances: usize,
    /// The assets' triangles counting each mesh once.
    pub unique_triangles: usize,
    /// The assets' triangles counting each instance (flattened).
    pub instanced_triangles: usize,
    /// Textures the materials read.
    pub textures: usize,
    /// Memory the decoded textures take, in bytes.
    pub texture_bytes: usize,
    /// Inner nodes of the bounding volume hierarchy (0 without one).
    pub bvh_nodes: usize,
    /// Packs of triangles every ray tests before the hierarchy's walk: the
    /// scene's largest triangles, where the build put them in front of
    /// the tree (0 otherwise).
    pub bvh_first_packs: usize,
    /// Where the wavefront's rays are tested in packets against a small
    /// scene's triangles: how many triangles every ray tests (null where
    /// the rays walk the tree).
    pub packet_first_triangles: Option<usize>,
    /// The groups of triangles behind boxes that the packets test after
    /// those, each only for the rays that enter its box (null where the
    /// rays walk the tree).
    pub packet_groups: Option<usize>,
    /// Wall-clock seconds spent building the hierarchy.
    pub build_seconds: f64,
    /// Memory held by the hierarchy's nodes and triangle packs, in bytes.
    pub bvh_bytes: usize,
    /// Placements of meshes the hierarchy traces two-level (instancing):
    /// 0 where it traces the flattened triangles.
    pub bvh_instances: usize,
    /// What was written: the `--out` file (an image or a `.wtacc` partial
    /// file), or the `--write-partial` image when a signal stopped the
    /// render, or else the `--partial` file; null when nothing was.
    pub output: Option<String>,
    /// The `--partial` file (`.wtacc`) written, if any.
    pub partial: Option<String>,
    /// The `--reference` image, if any.
    pub reference: Option<String>,
    /// The mean squared error of the image written (denoised, with
    /// `--denoise`) against `reference`.
    pub mse: Option<f64>,
    /// The relative mean squared error of the image written against
    /// `reference`: mean of `(a - r)² / (r² + 0.01)` over pixels and
    /// channels.
    pub relmse: Option<f64>,
    /// Whether the image written was denoised (`--denoise`).
    pub denoised: bool,
    /// With `--denoise` and `--reference`: the noisy image's MSE.
    pub noisy_mse: Option<f64>,
    /// With `--denoise` and `--reference`: the noisy image's relMSE.
    pub noisy_relmse: Option<f64>,
}

/// Wall-clock seconds of the stages of a run.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Stages {
    /// Reading the scene and profile, and reading and checking the
    /// checkpoint to resume.
    pub load: f64,
    /// Preparing the engine and its threads.
    pub setup: f64,
    /// Rendering sample passes.
    pub render: f64,
    /// Saving checkpoints.
    pub checkpoint: f64,
    /// Writing partial images (`--write-partial`).
    pub partial_images: f64,
    /// Denoising the final image (`--denoise`).
    pub denoise: f64,
    /// Writing the final outputs: `--out` and the `--partial` file.
    pub output: f64,
}

impl RenderStats {
    /// The stats as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("stats serialise")
    }
}

/// The git commit wavetrace was built from (`git rev-parse --short HEAD`
/// at build time), or "unknown" when it was built outside a git checkout.
/// A packager can set it with the `WAVETRACE_GIT_COMMIT` environment
/// variable at build time.
pub const GIT_COMMIT: &str = env!("WAVETRACE_GIT_COMMIT");

/// The widest SIMD instruction set this build was compiled to use (the
/// target features enabled at compile time, e.g. by `-C target-cpu`), not
/// what the running CPU could do.
pub const SIMD: &str = if cfg!(target_feature = "avx512f") {
    "avx512f"
} else if cfg!(all(target_feature = "avx2", target_feature = "fma")) {
    "avx2+fma"
} else if cfg!(target_feature = "avx2") {
    "avx2"
} else if cfg!(target_feature = "avx") {
    "avx"
} else if cfg!(target_feature = "sse4.2") {
    "sse4.2"
} else if cfg!(target_feature = "sse4.1") {
    "sse4.1"
} else if cfg!(target_feature = "sse2") {
    "sse2"
} else if cfg!(target_feature = "neon") {
    "neon"
} else if cfg!(target_feature = "simd128") {
    "wasm-simd128"
} else {
    "none"
};

/// The CPU's model name, from the first "model name" line of
/// `/proc/cpuinfo`; "unknown" where there is none (non-Linux systems, some
/// ARM kernels).
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| model_name(&info))
        .unwrap_or_else(|| "unknown".into())
}

fn model_name(cpuinfo: &str) -> Option<String> {
    cpuinfo.lines().find_map(|line| {
        let (key, value) = line.split_once(':')?;
        (key.trim() == "model name" && !value.trim().is_empty()).then(|| value.trim().to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn model_name_is_the_first_one() {
        let info = "processor\t: 0\nvendor_id\t: GenuineIntel\nmodel name\t: Intel(R) Xeon(R) CPU @ 2.20GHz\n\
                    processor\t: 1\nmodel name\t: Other\n";
        assert_eq!(
            model_name(info).as_deref(),
            Some("Intel(R) Xeon(R) CPU @ 2.20GHz")
        );
        assert_eq!(model_name("processor : 0\n"), None);
    }

    #[test]
    fn build_facts_are_named() {
        assert!(!GIT_COMMIT.is_empty());
        assert!(!cpu_model().is_empty());
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        assert!(SIMD.starts_with("avx"));
    }
}
