//! The render options a scene file (its `[integrator]` table), a profile
//! or the command line can name: the estimator, where its numbers come
//! from, and the auxiliary outputs (AOVs) to accumulate. The integrator
//! layer gives them their meaning.

use super::aov::AovSet;

/// Which estimator of the rendering equation a render uses. Every one
/// converges to the same image (max depth counts segments the same way
/// for all of them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// The report's estimator exactly: directions uniform on the
    /// hemisphere, light found only by chance.
    Report,
    /// Directions drawn by the BSDF (cosine-weighted for diffuse), light
    /// found only by chance.
    Bsdf,
    /// Next-event estimation: at every vertex a point on an emitter is
    /// sampled and a shadow ray traced, combined with the BSDF-sampled
    /// direction by multiple importance sampling (power heuristic).
    Nee,
}

impl Integrator {
    /// Every integrator's name.
    pub const NAMES: &[&str] = &["report", "bsdf", "nee"];

    /// The integrator named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "report" => Some(Self::Report),
            "bsdf" => Some(Self::Bsdf),
            "nee" => Some(Self::Nee),
            _ => None,
        }
    }

    /// The integrator's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Report => "report",
            Self::Bsdf => "bsdf",
            Self::Nee => "nee",
        }
    }
}

/// Where a render's numbers come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SamplerKind {
    /// Independent uniform numbers: a PCG stream per (seed, pixel, sample).
    Independent,
    /// Owen-scrambled Sobol points.
    Sobol,
}

impl SamplerKind {
    /// Every sampler's name.
    pub const NAMES: &[&str] = &["independent", "sobol"];

    /// The sampler named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "independent" => Some(Self::Independent),
            "sobol" => Some(Self::Sobol),
            _ => None,
        }
    }

    /// The sampler's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Independent => "independent",
            Self::Sobol => "sobol",
        }
    }
}

/// What a scene file's `[integrator]` table asks for besides the maximum
/// depth; `None` leaves the
/// choice to the profile, the command line or the built-in default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderOptions {
    /// The estimator.
    pub integrator: Option<Integrator>,
    /// The sampler.
    pub sampler: Option<SamplerKind>,
    /// The depth from which Russian roulette may end paths.
    pub rr_depth: Option<u32>,
    /// The auxiliary outputs to accumulate beside the radiance.
    pub aov: Option<AovSet>,
    /// Whether `nee` picks emitters by a light tree (`true`) or by power
    /// alone (`false`); `None`: by the counted rule (a tree where the scene
    /// has more than 16 emitters, docs/lights.md).
    pub light_tree: Option<bool>,
}

/// Adaptive sampling: every pixel takes [`min_spp`](Self::min_spp)
/// samples; then, in rounds that double the samples of the pixels still
/// taking them (up to `spp`), a pixel stops once its estimated error and
/// that of each of its eight neighbours is at most
/// [`threshold`](Self::threshold). The error of a pixel of `n` samples
/// is the root of the relMSE its mean is expected to have: over the three
/// channels, the mean of `s²/n / (m² + 0.01)` (`m` the channel's mean,
/// `s²` its sample variance), the measure of wavetrace's relMSE. Every
/// decision is made from the film's exact sums between rounds, so an
/// adaptive render is as reproducible as any other: the same bytes
/// whatever the threads, batch size or kernel width. (The render layer
/// does the rounds: `Renderer::render_adaptive_or_stop`.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    /// The error at which a pixel stops (0: never; every pixel takes all
    /// `spp` samples, the bytes of a render without adaptive sampling).
    pub threshold: f32,
    /// The samples every pixel takes first (at least 2: a variance needs
    /// two).
    pub min_spp: u32,
}

impl Adaptive {
    /// Whether `threshold` can be a noise threshold: a number at least 0.
    pub fn threshold_ok(threshold: f32) -> bool {
        threshold >= 0.0 && threshold.is_finite()
    }

    /// Whether `min_spp` can be the first round of a render of `spp`
    /// samples per pixel: between 2 and `spp` (or `spp` itself, below 2).
    pub fn min_spp_ok(min_spp: u32, spp: u32) -> bool {
        min_spp <= spp && (min_spp >= 2 || min_spp == spp)
    }

    /// The default first round: a sixteenth of `spp`, at least 4 (and at
    /// most `spp`).
    pub fn default_min_spp(spp: u32) -> u32 {
        (spp / 16).max(4).min(spp)
    }
}
