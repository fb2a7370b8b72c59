//! Named render presets (`profiles/*.toml`), picked with `--profile NAME`.
//!
//! A profile sets any of the render settings; command-line flags override
//! it, and it overrides the scene's defaults. The profiles in `profiles/`
//! are built into the binary; `--profile` also takes a path to a file.

use crate::error::{Error, Result};
use crate::fs::FileError;
use serde::Deserialize;
use std::path::Path;

/// A render preset; every field is optional.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// One line saying what the preset is for.
    pub description: Option<String>,
    /// Image width in pixels.
    pub width: Option<u32>,
    /// Image height in pixels.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Maximum path depth.
    pub max_depth: Option<u32>,
    /// Random seed.
    pub seed: Option<u64>,
    /// Engine name.
    pub engine: Option<String>,
    /// Integrator name (report, bsdf, nee).
    pub integrator: Option<String>,
    /// Sampler name (independent, sobol).
    pub sampler: Option<String>,
    /// Russian roulette from this depth on.
    pub rr_depth: Option<u32>,
    /// The AOVs to accumulate (albedo, normal, depth, variance).
    pub aov: Option<Vec<String>>,
}

/// The built-in profiles: name and TOML text.
pub const BUILT_IN: &[(&str, &str)] = &[
    ("preview", include_str!("../../profiles/preview.toml")),
    ("default", include_str!("../../profiles/default.toml")),
    (
        "seed-figure8",
        include_str!("../../profiles/seed-figure8.toml"),
    ),
];

impl Profile {
    /// Parse profile text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self> {
        toml::from_str(text)
            .map_err(|e| Error::Settings(format!("profile {origin}: {}", e.to_string().trim())))
    }

    /// The file that `--profile NAME` reads: `NAME` when it is not a
    /// built-in profile and has a `/` or ends in `.toml`.
    pub fn file(name: &str) -> Option<&Path> {
        let is_file = !BUILT_IN.iter().any(|(n, _)| *n == name)
            && (name.contains('/') || name.ends_with(".toml"));
        is_file.then(|| Path::new(name))
    }

    /// A built-in profile by name, or a profile file by path (anything
    /// with a `/` or ending in `.toml`).
    pub fn load(name: &str) -> Result<Self> {
        if let Some((_, text)) = BUILT_IN.iter().find(|(n, _)| *n == name) {
            return Self::parse(text, name);
        }
        if let Some(path) = Self::file(name) {
            let text =
                std::fs::read_to_string(path).map_err(|source| FileError::new(path, source))?;
            return Self::parse(&text, name);
        }
        let known: Vec<&str> = BUILT_IN.iter().map(|(n, _)| *n).collect();
        Err(Error::Settings(format!(
            "unknown profile {name:?} (built in: {}; or give a path to a .toml file)",
            known.join(", ")
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_in_profiles_parse() {
        for (name, _) in BUILT_IN {
            Profile::load(name).unwrap();
        }
        let f8 = Profile::load("seed-figure8").unwrap();
        assert_eq!(
            (f8.width, f8.height, f8.spp, f8.max_depth),
            (Some(300), Some(300), Some(32768), Some(3))
        );
    }

    #[test]
    fn unknown_profile_and_unknown_keys_are_refused() {
        assert!(
            Profile::load("nope")
                .unwrap_err()
                .to_string()
                .contains("unknown profile")
        );
        assert!(Profile::parse("spp = 4\nsamples = 3\n", "x").is_err());
    }
}
