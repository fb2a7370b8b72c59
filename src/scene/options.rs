//! The render options a scene file (its `[integrator]` table), a profile
//! or the command line can name: the estimator, where its numbers come
//! from, and the auxiliary outputs (AOVs) to accumulate. The integrator
//! layer gives them their meaning.

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
}

/// An auxiliary output (AOV) a render can accumulate beside the radiance
/// (defined in [`crate::integrator::aov`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Aov {
    /// The albedo at the first non-specular hit.
    Albedo,
    /// The shading normal at the first non-specular hit.
    Normal,
    /// The camera ray's hit distance.
    Depth,
    /// The per-pixel sample variance of the radiance.
    Variance,
    /// The fraction of the pixel's camera rays that hit something (the
    /// coverage: what `--transparent` writes as the image's alpha).
    Alpha,
    /// The camera ray's hit distance along the camera's forward axis.
    ZDepth,
    /// The object the most camera rays of the pixel hit.
    ObjectId,
}

impl Aov {
    /// The first four AOVs, those of [`AovSet::ALL`] (albedo, normal,
    /// depth, variance), in canonical order.
    pub const ALL: [Aov; 4] = [Aov::Albedo, Aov::Normal, Aov::Depth, Aov::Variance];

    /// Every AOV, in their canonical order (the order of files, layers and
    /// lists): [`Aov::ALL`], then alpha, zdepth and object_id.
    pub const EVERY: [Aov; 7] = [
        Aov::Albedo,
        Aov::Normal,
        Aov::Depth,
        Aov::Variance,
        Aov::Alpha,
        Aov::ZDepth,
        Aov::ObjectId,
    ];

    /// Every AOV's name, in canonical order.
    pub const NAMES: &[&str] = &[
        "albedo",
        "normal",
        "depth",
        "variance",
        "alpha",
        "zdepth",
        "object_id",
    ];

    /// The AOV named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::EVERY.into_iter().find(|a| a.name() == name)
    }

    /// The AOV's name (in `--aov`, file names and EXR layers).
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    fn bit(self) -> u8 {
        1 << self as u8
    }
}

/// A set of [`Aov`]s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct AovSet(u8);

impl AovSet {
    /// No AOV.
    pub const NONE: AovSet = AovSet(0);

    /// What the denoiser needs: albedo and normal.
    pub const DENOISE: AovSet = AovSet(1 << Aov::Albedo as u8 | 1 << Aov::Normal as u8);

    /// The first four AOVs ([`Aov::ALL`]): albedo, normal, depth and
    /// variance.
    pub const ALL: AovSet = AovSet(0b1111);

    /// Every AOV ([`Aov::EVERY`]).
    pub const EVERY: AovSet = AovSet(0b111_1111);

    /// The set of the AOVs in `aovs`.
    pub fn of(aovs: &[Aov]) -> Self {
        AovSet(aovs.iter().fold(0, |bits, a| bits | a.bit()))
    }

    /// Parse a list of names (`albedo,normal`; spaces around names are
    /// ignored, repeats are allowed). An unknown or empty name is refused,
    /// naming it and the known ones.
    pub fn parse_list(text: &str) -> Result<Self, String> {
        Self::from_names(text.split(','))
    }

    /// The set of the AOVs named by `names`; an unknown or empty name is
    /// refused, naming it and the known ones.
    pub fn from_names<'a>(names: impl IntoIterator<Item = &'a str>) -> Result<Self, String> {
        let mut set = AovSet::NONE;
        for name in names {
            let aov = Aov::from_name(name.trim()).ok_or_else(|| {
                format!(
                    "unknown AOV {:?} (known: {})",
                    name.trim(),
                    Aov::NAMES.join(", ")
                )
            })?;
            set = set.with(aov);
        }
        Ok(set)
    }

    /// This set with `aov` in it.
    pub fn with(self, aov: Aov) -> Self {
        AovSet(self.0 | aov.bit())
    }

    /// The AOVs in either set.
    pub fn union(self, other: AovSet) -> Self {
        AovSet(self.0 | other.0)
    }

    /// Whether `aov` is in the set.
    #[inline(always)]
    pub fn contains(self, aov: Aov) -> bool {
        self.0 & aov.bit() != 0
    }

    /// Whether the set is empty.
    #[inline(always)]
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The AOVs in the set, in canonical order ([`Aov::EVERY`]).
    pub fn iter(self) -> impl Iterator<Item = Aov> {
        Aov::EVERY.into_iter().filter(move |a| self.contains(*a))
    }

    /// The names of the AOVs in the set, in canonical order.
    pub fn names(self) -> Vec<&'static str> {
        self.iter().map(Aov::name).collect()
    }
}

/// `albedo,normal`, or `none` for the empty set.
impl std::fmt::Display for AovSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_empty() {
            write!(f, "none")
        } else {
            write!(f, "{}", self.names().join(","))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aov_lists_parse_in_canonical_order_and_refuse_unknown_names() {
        let set = AovSet::parse_list("variance, albedo,albedo").unwrap();
        assert_eq!(set.names(), ["albedo", "variance"]);
        assert_eq!(set.to_string(), "albedo,variance");
        assert_eq!(
            AovSet::parse_list("albedo,normal").unwrap(),
            AovSet::DENOISE
        );
        assert_eq!(
            AovSet::parse_list("albedo,normal,depth,variance").unwrap(),
            AovSet::ALL
        );
        let e = AovSet::parse_list("albedo,colour").unwrap_err();
        assert!(e.contains("\"colour\"") && e.contains("depth"), "{e}");
        assert!(AovSet::parse_list("").is_err());
        let every = AovSet::parse_list("object_id,zdepth,alpha,albedo,normal,depth,variance");
        assert_eq!(every.unwrap(), AovSet::EVERY);
        assert_eq!(AovSet::EVERY.names(), Aov::NAMES);
        assert_eq!(AovSet::NONE.to_string(), "none");
    }
}
