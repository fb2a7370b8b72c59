//! The environment: radiance arriving from infinitely far away, seen by
//! every ray that leaves the scene. An equirectangular image (`.exr` or
//! `.hdr`) or one constant colour, scaled by a strength and
//! turned about the up axis (docs/lights.md).
//!
//! The mapping is Blender's and three.js's, in +Y-up coordinates: a
//! direction `d` looks up `u = ½ + atan2(d.z, d.x) / 2π`,
//! `v = acos(d.y) / π`, `v = 0` the image's top row; texel `(i, j)` sits
//! at `((i + ½) / W, (j + ½) / H)`, looked up bilinearly, wrapping in `u`
//! and clamped in `v`. A rotation `R` (degrees) turns the content
//! right-handed about +Y: what was seen in direction `d` is seen in
//! `R_y(R)·d`. The integrator's side of it (lookup, importance sampling)
//! is `crate::integrator::environment`.
//!
//! In a scene file:
//!
//! ```toml
//! [environment]
//! file = "sky.exr"        # or: color = [0.8, 0.9, 1.0]
//! strength = 1.0          # radiance scale (default 1)
//! rotation = 90.0         # degrees about +Y (default 0)
//! visible = true          # false: camera rays that miss see alpha 0
//! ```

use glam::Vec3;
use serde::Deserialize;
use std::path::Path;
use std::sync::Arc;
use toml::Spanned;

/// The most texels an environment image may have (an 8192×4096 image:
/// 400 MB of texels, as much again for sampling).
pub const MAX_TEXELS: u64 = 1 << 25;

/// An environment light: an equirectangular image and how it is seen.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// The image's texels, row-major, row 0 at the top (+Y), linear RGB
    /// radiance (before `strength`).
    pub texels: Arc<Vec<[f32; 3]>>,
    /// Width in texels (`u`).
    pub width: u32,
    /// Height in texels (`v`).
    pub height: u32,
    /// The radiance scale.
    pub strength: f32,
    /// Degrees, right-handed about +Y.
    pub rotation_deg: f32,
    /// Whether camera rays that leave the scene see it (else they record
    /// nothing: black, alpha 0).
    pub visible: bool,
    /// What it is, for messages: a file name or `constant (r, g, b)`.
    pub source: String,
    /// The image file it was read from (`None`: a constant colour).
    pub file: Option<std::path::PathBuf>,
    /// How many of the file's texels had a negative component, read as 0
    /// (the ringing of lossy EXR compression around a bright sun).
    pub negative_texels: usize,
}

/// Where an environment's radiance comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvSource {
    /// One colour from every direction.
    Constant([f32; 3]),
    /// An equirectangular image file.
    File(std::path::PathBuf),
}

impl EnvSource {
    /// `R,G,B` (three non-negative numbers) is a colour; anything else a
    /// file name.
    pub fn parse(text: &str) -> Self {
        let parts: Vec<_> = text.split(',').map(|p| p.trim().parse::<f32>()).collect();
        match parts.as_slice() {
            [Ok(r), Ok(g), Ok(b)] => EnvSource::Constant([*r, *g, *b]),
            _ => EnvSource::File(text.into()),
        }
    }
}

impl Environment {
    /// The environment of `source`, scaled by `strength` and turned by
    /// `rotation_deg`: an image file is read here. Errors name the file
    /// and what is wrong.
    pub fn load(
        source: &EnvSource,
        strength: f32,
        rotation_deg: f32,
        visible: bool,
    ) -> Result<Self, String> {
        if !(strength.is_finite() && strength >= 0.0) {
            return Err(format!(
                "the environment's strength must be a finite non-negative number, not {strength}"
            ));
        }
        if !rotation_deg.is_finite() {
            return Err(format!(
                "the environment's rotation must be a finite number of degrees, not {rotation_deg}"
            ));
        }
        let (mut texels, width, height, name, file) = match source {
            EnvSource::Constant(c) => {
                if !c.iter().all(|x| x.is_finite() && *x >= 0.0) {
                    return Err(format!(
                        "the environment's colour must be finite and non-negative, not {c:?}"
                    ));
                }
                (
                    vec![*c],
                    1,
                    1,
                    format!("constant ({}, {}, {})", c[0], c[1], c[2]),
                    None,
                )
            }
            EnvSource::File(path) => {
                let (t, w, h) = read_image(path)?;
                (t, w, h, path.display().to_string(), Some(path.clone()))
            }
        };
        let mut negative_texels = 0;
        for t in &mut texels {
            if t.iter().any(|&c| c < 0.0) {
                negative_texels += 1;
                *t = t.map(|c| c.max(0.0));
            }
        }
        Ok(Self {
            negative_texels,
            texels: Arc::new(texels),
            width,
            height,
            strength,
            rotation_deg,
            visible,
            source: name,
            file,
        })
    }

    /// Hash what changes an image: texels, size, strength, rotation and
    /// visibility.
    pub fn hash_into(&self, h: &mut xxhash_rust::xxh3::Xxh3) {
        // The texels in one update where their bytes in memory are their
        // little-endian bits (XXH3's digest does not depend on how its
        // input is cut; an update per number was most of a small asset's
        // views set-up).
        if cfg!(target_endian = "little") {
            h.update(bytemuck::cast_slice(&self.texels));
        } else {
            for t in self.texels.iter() {
                for c in t {
                    h.update(&c.to_bits().to_le_bytes());
                }
            }
        }
        for x in [self.width, self.height, u32::from(self.visible)] {
            h.update(&x.to_le_bytes());
        }
        for x in [self.strength, self.rotation_deg] {
            h.update(&x.to_bits().to_le_bytes());
        }
    }
}

/// An equirectangular radiance image, `.exr` or Radiance `.hdr`: its
/// texels (row 0 at the top), width and height. The size is checked
/// against [`MAX_TEXELS`] before the pixels are decoded; a NaN or infinite
/// texel is refused, naming it (negative ones are kept here, and read as 0
/// by [`Environment::load`]).
fn read_image(path: &Path) -> Result<(Vec<[f32; 3]>, u32, u32), String> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let (texels, width, height) = match ext.as_deref() {
        Some("exr") => read_exr(path)?,
        Some("hdr") => read_hdr(path)?,
        _ => {
            return Err(format!(
                "{}: an environment is an equirectangular .exr or .hdr image, or a colour R,G,B",
                path.display()
            ));
        }
    };
    Ok((check_finite(path, texels, width)?, width, height))
}

/// Refuses an image of `width × height` texels that is empty or larger
/// than [`MAX_TEXELS`].
fn check_size(path: &Path, width: u64, height: u64) -> Result<(), String> {
    let texels = width * height;
    if texels == 0 || texels > MAX_TEXELS {
        return Err(format!(
            "{}: an environment image of {width}×{height} texels (at least 1, at most {MAX_TEXELS})",
            path.display()
        ));
    }
    Ok(())
}

/// The `R`, `G`, `B` channels of an OpenEXR image's first RGB layer (any
/// compression the `exr` crate reads), its header read and its size
/// checked first.
fn read_exr(path: &Path) -> Result<(Vec<[f32; 3]>, u32, u32), String> {
    use exr::prelude::read_first_rgba_layer_from_file;
    let bad = |e: exr::error::Error| format!("{}: cannot read the EXR image: {e}", path.display());
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(bad)?;
    let size = meta
        .headers
        .first()
        .map(|h| h.layer_size)
        .ok_or_else(|| format!("{}: the EXR image has no part", path.display()))?;
    check_size(path, size.width() as u64, size.height() as u64)?;
    let image = read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![[0.0f32; 3]; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b];
        },
    )
    .map_err(bad)?;
    let (w, texels) = image.layer_data.channel_data.pixels;
    let h = texels.len() / w.max(1);
    Ok((texels, w as u32, h as u32))
}

/// A Radiance `.hdr` (RGBE) image, its size checked before it is decoded.
fn read_hdr(path: &Path) -> Result<(Vec<[f32; 3]>, u32, u32), String> {
    use image::ImageDecoder;
    let bad =
        |e: &dyn std::fmt::Display| format!("{}: cannot read the HDR image: {e}", path.display());
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let decoder =
        image::codecs::hdr::HdrDecoder::new(std::io::BufReader::new(file)).map_err(|e| bad(&e))?;
    let (width, height) = decoder.dimensions();
    check_size(path, u64::from(width), u64::from(height))?;
    let image = image::DynamicImage::from_decoder(decoder).map_err(|e| bad(&e))?;
    let rgb = image.into_rgb32f();
    let texels = rgb.pixels().map(|p| p.0).collect();
    Ok((texels, width, height))
}

/// `texels`, or an error naming the first NaN or infinite one.
fn check_finite(path: &Path, texels: Vec<[f32; 3]>, width: u32) -> Result<Vec<[f32; 3]>, String> {
    if let Some(i) = texels.iter().position(|t| !t.iter().all(|c| c.is_finite())) {
        let w = width as usize;
        return Err(format!(
            "{}: texel ({}, {}) is {:?}; an environment must be finite",
            path.display(),
            i % w,
            i / w,
            texels[i]
        ));
    }
    Ok(texels)
}

/// The `[environment]` table of a scene file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentFile {
    file: Option<Spanned<String>>,
    color: Option<Spanned<Vec<f32>>>,
    strength: Option<Spanned<f32>>,
    rotation: Option<Spanned<f32>>,
    visible: Option<bool>,
}

/// Where a problem with an `[environment]` table is: the span of the
/// scene file's text, the field (`environment.FIELD`) and the message.
pub type TableError = (std::ops::Range<usize>, String, String);

/// The environment a scene file's `[environment]` table (`raw`, if any)
/// asks for; a `file` is relative to the scene file `file`'s directory.
/// Errors are placed by the front end that read the table.
pub fn from_file(
    raw: Option<&Spanned<EnvironmentFile>>,
    file: &str,
) -> Result<Option<Environment>, TableError> {
    let Some(raw) = raw else {
        return Ok(None);
    };
    let at = |span: std::ops::Range<usize>, field: &str, message: String| {
        (span, format!("environment.{field}"), message)
    };
    let env = raw.get_ref();
    let source = match (&env.file, &env.color) {
        (Some(f), None) => {
            let base = Path::new(file).parent().unwrap_or(Path::new(""));
            (EnvSource::File(base.join(f.get_ref())), f.span(), "file")
        }
        (None, Some(c)) => match c.get_ref().as_slice() {
            &[r, g, b] => (EnvSource::Constant([r, g, b]), c.span(), "color"),
            _ => {
                return Err(at(
                    c.span(),
                    "color",
                    "must be an array of 3 numbers".into(),
                ));
            }
        },
        _ => {
            return Err(at(
                raw.span(),
                "file",
                "give exactly one of `file` and `color`".into(),
            ));
        }
    };
    let strength = env.strength.as_ref().map_or(1.0, |s| *s.get_ref());
    let rotation = env.rotation.as_ref().map_or(0.0, |s| *s.get_ref());
    if let Some(s) = &env.strength
        && !(s.get_ref().is_finite() && *s.get_ref() >= 0.0)
    {
        return Err(at(
            s.span(),
            "strength",
            "must be a finite non-negative number".into(),
        ));
    }
    if let Some(r) = &env.rotation
        && !r.get_ref().is_finite()
    {
        return Err(at(r.span(), "rotation", "must be a finite number".into()));
    }
    let visible = env.visible.unwrap_or(true);
    Environment::load(&source.0, strength, rotation, visible)
        .map(Some)
        .map_err(|m| at(source.1, source.2, m))
}

/// What [`default_sky`] is, in its [`Environment::source`].
pub const DEFAULT_SKY: &str = "the default environment (a uniform white sky of radiance 1)";

/// The environment a scene renders with after a caller's overrides (the
/// render command's `--env`, `--env-strength`, `--env-rotation`; the
/// Python package's `env=`…): `source` replaces the scene's environment
/// (keeping its `visible`); `strength` and `rotation` alone change the
/// scene's own, which a scene without one refuses. `Ok(None)`: nothing
/// to change. Errors name the flag, for the caller to place.
pub fn overridden(
    old: Option<&Environment>,
    source: Option<&EnvSource>,
    strength: Option<f32>,
    rotation: Option<f32>,
) -> Result<Option<Environment>, String> {
    match (source, old) {
        (Some(source), old) => Environment::load(
            source,
            strength.unwrap_or(1.0),
            rotation.unwrap_or(0.0),
            old.is_none_or(|e| e.visible),
        )
        .map(Some),
        (None, Some(old)) => Environment::load(
            &EnvSource::Constant([0.0; 3]),
            strength.unwrap_or(old.strength),
            rotation.unwrap_or(old.rotation_deg),
            old.visible,
        )
        .map(|checked| {
            Some(Environment {
                strength: checked.strength,
                rotation_deg: checked.rotation_deg,
                ..old.clone()
            })
        }),
        (None, None) if strength.is_some() || rotation.is_some() => Err(
            "--env-strength and --env-rotation change an environment: the scene has none; give one with --env".into(),
        ),
        (None, None) => Ok(None),
    }
}

/// The environment of an asset rendered alone that brings no light of its
/// own: a uniform white sky of radiance 1, visible — a white furnace, so a
/// white diffuse surface open to the whole sky is exactly white.
pub fn default_sky() -> Environment {
    Environment {
        source: DEFAULT_SKY.into(),
        ..constant(Vec3::ONE)
    }
}

/// A constant environment of radiance `c` (strength 1, visible).
pub fn constant(c: Vec3) -> Environment {
    Environment::load(&EnvSource::Constant(c.to_array()), 1.0, 0.0, true)
        .expect("a finite non-negative colour")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The digest of `e` as the hash defined it: one update per number.
    fn per_number(e: &Environment) -> u128 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        for c in e.texels.iter().flatten() {
            h.update(&c.to_bits().to_le_bytes());
        }
        for x in [e.width, e.height, u32::from(e.visible)] {
            h.update(&x.to_le_bytes());
        }
        for x in [e.strength, e.rotation_deg] {
            h.update(&x.to_bits().to_le_bytes());
        }
        h.digest128()
    }

    fn digest(e: &Environment) -> u128 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        e.hash_into(&mut h);
        h.digest128()
    }

    /// Files keyed by the hash (checkpoints, views manifests) stay valid:
    /// the texels in one update give the per-number digest, and every
    /// texel still counts.
    #[test]
    fn the_hash_is_the_per_number_digest_and_sees_every_texel() {
        let texels = (0..64 * 32).map(|i| [i as f32, 0.5, 1.0 / (1 + i) as f32]);
        let mut e = Environment {
            texels: Arc::new(texels.collect()),
            width: 64,
            height: 32,
            ..constant(Vec3::ONE)
        };
        assert_eq!(digest(&e), per_number(&e));
        let h = digest(&e);
        let last = e.texels.len() - 1;
        for i in [0, last / 2, last] {
            let mut t = (*e.texels).clone();
            t[i][1] += 1.0;
            e.texels = Arc::new(t);
            assert_ne!(digest(&e), h, "texel {i} is not hashed");
        }
    }
}
