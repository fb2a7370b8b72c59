//! The auxiliary outputs (AOVs) a render can accumulate beside the
//! radiance, and what each one is, in one table ([`Aov::def`]): its name,
//! when a path records it, how a pixel's samples of it are summed, and how
//! it is written. The value a path records is
//! [`crate::integrator::aov::value`]'s; the two are the whole definition of
//! an AOV. Adding one touches this file (its variant and its row) and that
//! function; a new way of summing adds a [`Sum`] and its column in
//! [`crate::film::aov`].

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

    /// How many AOVs there are.
    pub const COUNT: usize = Self::EVERY.len();

    /// Every AOV's name, in canonical order.
    pub const NAMES: [&str; Self::COUNT] = {
        let mut names = [""; Self::COUNT];
        let mut i = 0;
        while i < Self::COUNT {
            names[i] = Self::EVERY[i].def().name;
            i += 1;
        }
        names
    };

    /// The AOV named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::EVERY.into_iter().find(|a| a.name() == name)
    }

    /// The AOV's name (in `--aov`, file names and EXR layers).
    pub fn name(self) -> &'static str {
        self.def().name
    }

    /// The AOV's definition: one row per AOV.
    pub const fn def(self) -> AovDef {
        let none = [0.0; 3];
        let missed = [f32::INFINITY, 0.0, 0.0];
        match self {
            Aov::Albedo => AovDef {
                name: "albedo",
                when: When::FirstNonSpecular,
                sum: Sum::Mean { lo: 0.0, hi: 1.0 },
                none,
                layer: ("albedo", &["R", "G", "B"]),
                length: false,
                meaning: "albedo: reflectance at the first non-specular hit, linear, mean over samples",
            },
            Aov::Normal => AovDef {
                name: "normal",
                when: When::FirstNonSpecular,
                sum: Sum::Mean { lo: -1.0, hi: 1.0 },
                none,
                layer: ("normal", &["X", "Y", "Z"]),
                length: false,
                meaning: "normal: shading normal at the first non-specular hit, world axes, mean over samples, not renormalised, 0 where none",
            },
            Aov::Depth => AovDef {
                name: "depth",
                when: When::CameraHit,
                sum: Sum::HitMean,
                none: missed,
                layer: ("depth", &["Z"]),
                length: true,
                meaning: "depth: distance from the camera centre along the ray to the first hit (not z), mean over the pixel's samples that hit, +inf where none hit; the job's world units",
            },
            Aov::Variance => AovDef {
                name: "variance",
                when: When::Radiance,
                sum: Sum::Squares,
                none,
                layer: ("variance", &["R", "G", "B"]),
                length: false,
                meaning: "variance: unbiased sample variance of the radiance per channel (of one sample; the pixel mean's is this / spp), linear",
            },
            Aov::Alpha => AovDef {
                name: "alpha",
                when: When::CameraHit,
                sum: Sum::Count,
                none,
                layer: ("", &["A"]),
                length: false,
                meaning: "alpha: the fraction of the pixel's camera rays that hit something",
            },
            Aov::ZDepth => AovDef {
                name: "zdepth",
                when: When::CameraHit,
                sum: Sum::HitMean,
                none: missed,
                layer: ("zdepth", &["Z"]),
                length: true,
                meaning: "zdepth: distance from the camera centre along the camera's forward (optical, OpenCV +z) axis to the first hit, = depth * cos(angle of the ray to that axis), mean over the pixel's samples that hit, +inf where none hit; the job's world units",
            },
            Aov::ObjectId => AovDef {
                name: "object_id",
                when: When::CameraHit,
                sum: Sum::Votes,
                none,
                layer: ("object_id", &["id"]),
                length: false,
                meaning: "object_id: the id of the object most of the pixel's camera rays hit (0: none)",
            },
        }
    }

    fn bit(self) -> u32 {
        1 << self as u32
    }
}

/// What defines an AOV, besides the value a path records
/// ([`crate::integrator::aov::value`]).
#[derive(Clone, Copy, Debug)]
pub struct AovDef {
    /// Its name, in `--aov`, file names and lists.
    pub name: &'static str,
    /// When a path records it.
    pub when: When,
    /// How a pixel's samples of it are summed, and so its image.
    pub sum: Sum,
    /// A sample's value when the path did not record it (a camera ray
    /// that hit nothing; a path with no non-specular vertex).
    pub none: [f32; 3],
    /// Its EXR layer name and channels (an empty name: channels of their
    /// own, as the alpha's `A`).
    pub layer: (&'static str, &'static [&'static str]),
    /// Whether it is a length in world units (scaled with the scene).
    pub length: bool,
    /// What it is, in a line, for the headers of the files it is written
    /// to.
    pub meaning: &'static str,
}

/// When a path records an AOV.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum When {
    /// At the camera ray's hit (a cut-out it passes through is not one).
    CameraHit,
    /// At the path's first vertex whose material is not a delta lobe (the
    /// vertex OIDN's auxiliary images describe).
    FirstNonSpecular,
    /// Never: the film makes it of the radiance sample itself.
    Radiance,
}

/// How a pixel's samples of an AOV are summed (exactly, in the film's
/// fixed point: [`crate::film::aov`]), and so what its image is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sum {
    /// Three channels, each clamped to `[lo, hi]`; the image is the mean
    /// over all the pixel's samples.
    Mean {
        /// The least value a channel adds.
        lo: f32,
        /// The largest.
        hi: f32,
    },
    /// One value (the first channel) where the sample hit something (a
    /// value in `[0, 2³¹)`), and the count of those; the image is their
    /// mean, `+inf` where none hit.
    HitMean,
    /// The samples whose value (first channel) is not 0; the image is
    /// their fraction.
    Count,
    /// A vote for an id, the bits of the first channel (0: none); the
    /// image is the id most samples voted for, the samples without one
    /// voting for 0, a tie going to the smallest id.
    Votes,
    /// The squares of the radiance samples; the image is the unbiased
    /// sample variance.
    Squares,
}

/// A set of [`Aov`]s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct AovSet(u32);

impl AovSet {
    /// No AOV.
    pub const NONE: AovSet = AovSet(0);

    /// What the denoiser needs: albedo and normal.
    pub const DENOISE: AovSet = AovSet(1 << Aov::Albedo as u32 | 1 << Aov::Normal as u32);

    /// The first four AOVs ([`Aov::ALL`]): albedo, normal, depth and
    /// variance.
    pub const ALL: AovSet = AovSet(0b1111);

    /// Every AOV ([`Aov::EVERY`]).
    pub const EVERY: AovSet = AovSet((1 << Aov::COUNT) - 1);

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
