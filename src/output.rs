//! Outputs: images (PNG, OpenEXR, PFM) and accumulation files, written
//! whole or not at all, and the checks on output paths made before any
//! work starts.
//!
//! An image with AOVs ([`write_image_with_aovs`]): an OpenEXR image holds
//! them as layers of the one multi-layer file ([`aov_layer`]: `albedo.R/G/B`,
//! `normal.X/Y/Z`, `depth.Z`, `variance.R/G/B`, beside the colour's `R`,
//! `G`, `B`); a PNG or PFM image gets one PFM file per AOV beside it
//! ([`aov_path`]: `STEM.albedo.pfm`, `STEM.normal.pfm`, `STEM.depth.pfm`,
//! `STEM.variance.pfm` for `STEM.png`), PFM because it keeps the floats
//! exactly (a PNG would clamp normals, depths and variances). A PFM's
//! depth repeats its one value in all three channels.
//!
//! Three AOVs are written otherwise ([`aov_path`], [`aov_layer`]):
//! **alpha** is the image's own alpha — a PNG becomes RGBA (8-bit, the
//! colour *not* premultiplied, as PNG defines it: the mean over the
//! samples that hit, `rgb / alpha`), an EXR gets an `A` channel beside
//! `R`, `G`, `B` (which stay premultiplied, as EXR defines them: the
//! misses add 0 to the mean), a PFM (which has no alpha) gets
//! `STEM.alpha.pfm`; **zdepth** is `zdepth.Z` in an EXR, else
//! `STEM.zdepth.pfm`; **object_id** is `object_id.id`, a 32-bit unsigned
//! integer channel, in an EXR, else `STEM.object_id.png`, a 16-bit
//! grey PNG holding the ids (refused for ids above 65535).

pub mod view;

use crate::error::{Error, Result};
use crate::film::{AccMeta, Film};
use crate::fs::{FileError, write_atomic};
use crate::scene::Aov;
use image::ExtendedColorType as ColorType;
use std::io::Write;
use std::path::{Path, PathBuf};
use view::ViewTransform;

/// The extension of accumulation (partial) files.
pub const PARTIAL_EXTENSION: &str = "wtacc";

/// Image file formats, chosen by the extension of the output path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB PNG, clamped to [0, 1].
    Png,
    /// Linear 32-bit float OpenEXR.
    Exr,
    /// Linear 32-bit float Portable Float Map.
    Pfm,
}

impl ImageFormat {
    /// The format for `path`'s extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            Some("pfm") => Ok(Self::Pfm),
            _ => Err(Error::Settings(format!(
                "{}: unknown image format; use a .png, .exr or .pfm extension",
                path.display()
            ))),
        }
    }
}

/// The sRGB transfer function (linear → encoded), for values in [0, 1].
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The 8-bit sRGB bytes of a linear RGB image, as a PNG holds them:
/// clamped to [0, 1], sRGB-encoded, rounded.
pub fn srgb8(rgb: &[[f32; 3]]) -> Vec<u8> {
    rgb.iter()
        .flat_map(|p| p.map(|c| (srgb_encode(c.clamp(0.0, 1.0)) * 255.0).round() as u8))
        .collect()
}

/// Write a linear RGB image (row-major, row 0 at the top) in the format that
/// `path`'s extension names, atomically; a PNG with the standard view
/// ([`write_image_viewed`]).
pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<()> {
    write_image_viewed(path, width, height, rgb, ViewTransform::default())
}

/// [`write_image`], a PNG through the exposure and view transform `view`
/// (EXR and PFM images are linear: `view` does not touch them).
pub fn write_image_viewed(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    view: ViewTransform,
) -> Result<()> {
    assert_eq!(rgb.len(), width as usize * height as usize);
    let format = ImageFormat::from_path(path)?;
    let written = match format {
        ImageFormat::Png => write_png(path, &view.bytes(rgb), (width, height), ColorType::Rgb8),
        ImageFormat::Pfm => write_atomic(path, |w| {
            write!(w, "PF\n{width} {height}\n-1.0\n")?;
            // PFM rows run bottom to top.
            for row in rgb.chunks_exact(width as usize).rev() {
                for p in row {
                    for c in p {
                        w.write_all(&c.to_le_bytes())?;
                    }
                }
            }
            Ok(())
        }),
        ImageFormat::Exr => {
            use exr::prelude::*;
            let (w_, h_) = (width as usize, height as usize);
            let encoding = exr_encoding();
            let image = Image::from_encoded_channels(
                (w_, h_),
                encoding,
                SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
                    let p = rgb[y * w_ + x];
                    (p[0], p[1], p[2])
                }),
            );
            write_exr(path, |buf| image.write().to_buffered(buf))
        }
    };
    Ok(written?)
}

/// A layer of one to three channels of a multi-layer EXR image, beside
/// the colour (`R`, `G`, `B`): channels `name.c` for each `c` of
/// `channels`, the `k`-th from component `k` of the pixels.
#[derive(Clone, Copy, Debug)]
pub struct ExrLayer<'a> {
    /// The layer's name (`albedo`).
    pub name: &'a str,
    /// Its channels' names within the layer (`R`, `G`, `B`): one to three.
    pub channels: &'a [&'a str],
    /// Row-major pixels, row 0 at the top.
    pub pixels: &'a [[f32; 3]],
}

/// The albedo layer's name and channels in wavetrace's EXR images.
pub const ALBEDO_LAYER: (&str, &[&str]) = Aov::Albedo.def().layer;
/// The normal layer's name and channels in wavetrace's EXR images.
pub const NORMAL_LAYER: (&str, &[&str]) = Aov::Normal.def().layer;
/// The depth layer's name and channel in wavetrace's EXR images.
pub const DEPTH_LAYER: (&str, &[&str]) = Aov::Depth.def().layer;
/// The variance layer's name and channels in wavetrace's EXR images.
pub const VARIANCE_LAYER: (&str, &[&str]) = Aov::Variance.def().layer;
/// The alpha's channel in wavetrace's EXR images: `A`, no layer name.
pub const ALPHA_LAYER: (&str, &[&str]) = Aov::Alpha.def().layer;
/// The zdepth layer's name and channel in wavetrace's EXR images.
pub const ZDEPTH_LAYER: (&str, &[&str]) = Aov::ZDepth.def().layer;
/// The object_id layer's name and channel in wavetrace's EXR images (a
/// `u32` channel).
pub const OBJECT_ID_LAYER: (&str, &[&str]) = Aov::ObjectId.def().layer;

/// The EXR layer name and channels of an AOV (an empty name: channels of
/// their own, the alpha's `A`).
pub fn aov_layer(aov: Aov) -> (&'static str, &'static [&'static str]) {
    aov.def().layer
}

/// The file an AOV of the PNG or PFM image `image` goes to: `STEM.NAME.pfm`
/// beside it (`out.png` → `out.albedo.pfm`), but `STEM.object_id.png`
/// beside a PNG. `None` for an EXR image (its AOVs are layers), an
/// accumulation file (it holds their sums), and the alpha of a PNG (its
/// own alpha channel).
pub fn aov_path(image: &Path, aov: Aov) -> Option<PathBuf> {
    match (ImageFormat::from_path(image), aov) {
        (Ok(ImageFormat::Png), Aov::Alpha) => None,
        (Ok(ImageFormat::Png), Aov::ObjectId) => {
            Some(image.with_extension(format!("{}.png", aov.name())))
        }
        (Ok(ImageFormat::Png | ImageFormat::Pfm), _) => {
            Some(image.with_extension(format!("{}.pfm", aov.name())))
        }
        _ => None,
    }
}

/// Write an object_id image as a 16-bit grey PNG of the ids, atomically;
/// refused, naming the file, when an id is above 65535.
pub fn write_id_png(path: &Path, width: u32, height: u32, ids: &[[f32; 3]]) -> Result<()> {
    if let Some(p) = ids.iter().find(|p| p[0] > 65535.0) {
        return Err(Error::Settings(format!(
            "{}: object id {} does not fit a 16-bit PNG: write an .exr image",
            path.display(),
            p[0]
        )));
    }
    let bytes: Vec<u8> = ids
        .iter()
        .flat_map(|p| (p[0] as u16).to_ne_bytes()) // (the image crate writes them big-endian)
        .collect();
    Ok(write_png(path, &bytes, (width, height), ColorType::L16)?)
}

/// Write an RGBA PNG, atomically: the colour `rgb` (premultiplied, as the
/// film holds it) divided by `alpha` (straight colour, as PNG defines it;
/// 0 where alpha is 0) through `view`, and the alpha as 8 bits.
pub fn write_rgba_png(
    path: &Path,
    (width, height): (u32, u32),
    rgb: &[[f32; 3]],
    alpha: &[[f32; 3]],
    view: ViewTransform,
) -> Result<()> {
    let straight: Vec<[f32; 3]> = (rgb.iter().zip(alpha))
        .map(|(c, a)| {
            if a[0] > 0.0 {
                c.map(|x| x / a[0])
            } else {
                [0.0; 3]
            }
        })
        .collect();
    write_rgba_png_straight(path, (width, height), &straight, alpha, view)
}

/// Write an RGBA PNG, atomically: the colour `rgb` as it is (straight, or
/// an opaque background's colour) through `view`, and `alpha` as 8 bits.
pub fn write_rgba_png_straight(
    path: &Path,
    (width, height): (u32, u32),
    rgb: &[[f32; 3]],
    alpha: &[[f32; 3]],
    view: ViewTransform,
) -> Result<()> {
    let colour = view.bytes(rgb);
    let mut bytes = Vec::with_capacity(colour.len() / 3 * 4);
    for (c, a) in colour.chunks_exact(3).zip(alpha) {
        bytes.extend_from_slice(c);
        bytes.push((a[0].clamp(0.0, 1.0) * 255.0).round() as u8);
    }
    Ok(write_png(path, &bytes, (width, height), ColorType::Rgba8)?)
}

/// Write `bytes` (pixels of type `colour`, rows top to bottom) as a PNG,
/// atomically.
fn write_png(
    path: &Path,
    bytes: &[u8],
    (width, height): (u32, u32),
    colour: ColorType,
) -> std::result::Result<(), FileError> {
    write_atomic(path, |w| {
        image::write_buffer_with_format(w, bytes, width, height, colour, image::ImageFormat::Png)
            .map_err(std::io::Error::other)
    })
}

/// Write a linear RGB image with AOV images `aovs` (each of the image's
/// size), atomically, as the module's docs say: EXR layers, or PFM files
/// beside a PNG or PFM (a PNG through `view`; the AOVs are linear
/// always). Without AOVs, exactly [`write_image_viewed`].
pub fn write_image_with_aovs(
    path: &Path,
    (width, height): (u32, u32),
    rgb: &[[f32; 3]],
    aovs: &[(Aov, &[[f32; 3]])],
    view: ViewTransform,
) -> Result<()> {
    if aovs.is_empty() {
        return write_image_viewed(path, width, height, rgb, view);
    }
    if ImageFormat::from_path(path)? == ImageFormat::Exr {
        let layers: Vec<ExrLayer<'_>> = aovs
            .iter()
            .map(|(aov, pixels)| {
                let (name, channels) = aov_layer(*aov);
                ExrLayer {
                    name,
                    channels,
                    pixels,
                }
            })
            .collect();
        return write_exr_layers(path, width, height, rgb, &layers);
    }
    let alpha = aovs.iter().find(|(a, _)| *a == Aov::Alpha);
    match alpha {
        Some((_, alpha)) if ImageFormat::from_path(path)? == ImageFormat::Png => {
            write_rgba_png(path, (width, height), rgb, alpha, view)?;
        }
        _ => write_image_viewed(path, width, height, rgb, view)?,
    }
    for (aov, pixels) in aovs {
        let Some(side) = aov_path(path, *aov) else {
            continue; // the PNG's alpha
        };
        if ImageFormat::from_path(&side)? == ImageFormat::Png {
            write_id_png(&side, width, height, pixels)?;
        } else {
            write_image(&side, width, height, pixels)?;
        }
    }
    Ok(())
}

/// Write a multi-layer OpenEXR image, atomically: the colour `rgb` as
/// channels `R`, `G`, `B` and each of `layers` as `name.channel`, all
/// 32-bit float, in one part (as Blender and OIDN's tools name them).
pub fn write_exr_layers(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    layers: &[ExrLayer<'_>],
) -> Result<()> {
    use exr::prelude::*;
    let n = width as usize * height as usize;
    assert_eq!(rgb.len(), n);
    let plane = |pixels: &[[f32; 3]], c: usize| -> FlatSamples {
        FlatSamples::F32(pixels.iter().map(|p| p[c]).collect())
    };
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        list.push(AnyChannel::new(name, plane(rgb, c)));
    }
    for layer in layers {
        assert_eq!(layer.pixels.len(), n);
        assert!((1..=3).contains(&layer.channels.len()));
        for (c, channel) in layer.channels.iter().enumerate() {
            // A layer without a name: channels of their own (alpha's `A`).
            let name = match layer.name {
                "" => channel.to_string(),
                layer => format!("{layer}.{channel}"),
            };
            let samples = if layer.name == OBJECT_ID_LAYER.0 {
                FlatSamples::U32(layer.pixels.iter().map(|p| p[c] as u32).collect())
            } else {
                plane(layer.pixels, c)
            };
            list.push(AnyChannel::new(name.as_str(), samples));
        }
    }
    let encoding = exr_encoding();
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::default(),
        encoding,
        AnyChannels::sort(list),
    );
    let image = Image::from_layer(layer);
    Ok(write_exr(path, |buf| image.write().to_buffered(buf))?)
}

/// How every OpenEXR image is encoded: lossless, its blocks compressed in
/// parallel but written in increasing order, so the same image gives the
/// same bytes.
fn exr_encoding() -> exr::prelude::Encoding {
    exr::prelude::Encoding {
        line_order: exr::prelude::LineOrder::Increasing,
        ..exr::prelude::Encoding::FAST_LOSSLESS
    }
}

/// Write an OpenEXR image atomically: `encode` writes it whole into a
/// buffer, which then goes to the file.
fn write_exr(
    path: &Path,
    encode: impl FnOnce(&mut std::io::Cursor<Vec<u8>>) -> exr::error::UnitResult,
) -> std::result::Result<(), FileError> {
    write_atomic(path, |w| {
        let mut buf = std::io::Cursor::new(Vec::new());
        encode(&mut buf).map_err(std::io::Error::other)?;
        w.write_all(buf.get_ref())
    })
}

/// Read the layer `name` (channels `name.c` for each of `channels`, one
/// to three) of an OpenEXR image's first part: `None` when any of its
/// channels is missing. A layer of fewer than three channels repeats its
/// last in the pixels' remaining components (depth: `[z, z, z]`).
pub fn read_exr_layer(path: &Path, name: &str, channels: &[&str]) -> Result<Option<Vec<[f32; 3]>>> {
    assert!((1..=3).contains(&channels.len()));
    use exr::prelude::{ReadChannels, ReadLayers, read};
    let bad = |e: exr::error::Error| {
        Error::Settings(format!(
            "{}: cannot read the EXR image: {e}",
            path.display()
        ))
    };
    // Sizes are checked (against memory) by `read_image` first.
    read_image(path)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(bad)?;
    let list = &image.layer_data.channel_data.list;
    let n = image.layer_data.size.0 * image.layer_data.size.1;
    let mut out = vec![[0.0f32; 3]; n];
    for (c, channel) in channels.iter().enumerate() {
        let full = match name {
            "" => channel.to_string(),
            name => format!("{name}.{channel}"),
        };
        let Some(found) = list.iter().find(|ch| ch.name.to_string() == full) else {
            return Ok(None);
        };
        let last = c + 1 == channels.len();
        for (p, v) in out.iter_mut().zip(found.sample_data.values_as_f32()) {
            if last {
                p[c..].fill(v);
            } else {
                p[c] = v;
            }
        }
    }
    Ok(Some(out))
}

/// Whether `path` names a partial (accumulation) file: a `.wtacc` extension.
pub fn is_partial_path(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case(PARTIAL_EXTENSION))
}

/// Check that `path` is an output wavetrace can write: an image format or
/// a partial file.
pub fn check_output_format(path: &Path) -> Result<()> {
    if is_partial_path(path) {
        return Ok(());
    }
    ImageFormat::from_path(path).map(|_| ()).map_err(|_| {
        Error::Settings(format!(
            "{}: unknown image format; use a .png, .exr or .pfm extension, or .{PARTIAL_EXTENSION} for a partial file",
            path.display()
        ))
    })
}

/// Check that `path` can be a partial file: a `.wtacc` extension.
pub fn check_partial_path(path: &Path) -> Result<()> {
    if is_partial_path(path) {
        Ok(())
    } else {
        Err(Error::Settings(format!(
            "{}: a partial file's name must end in .{PARTIAL_EXTENSION}",
            path.display()
        )))
    }
}

/// Write `film` to `path`, atomically: a partial file for `.wtacc` (with
/// the film's AOV sums), else an image in the format of the extension with
/// the film's AOVs ([`write_image_with_aovs`]); a PNG with the standard
/// view ([`write_output_viewed`]).
pub fn write_output(path: &Path, film: &Film, meta: &AccMeta) -> Result<()> {
    write_output_viewed(path, film, meta, ViewTransform::default())
}

/// [`write_output`], a PNG through the exposure and view transform `view`.
pub fn write_output_viewed(
    path: &Path,
    film: &Film,
    meta: &AccMeta,
    view: ViewTransform,
) -> Result<()> {
    if is_partial_path(path) {
        return Ok(film.save_with_meta(path, meta)?);
    }
    let images = film.aov_images();
    let aovs: Vec<(Aov, &[[f32; 3]])> = images.iter().map(|(a, p)| (*a, &p[..])).collect();
    write_image_with_aovs(path, (film.width, film.height), &film.to_rgb(), &aovs, view)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_image_gives_the_same_bytes_in_every_format() {
        // Big enough for many EXR blocks compressed in parallel, which once
        // landed in the file in whatever order they finished.
        let (w, h) = (300u32, 200u32);
        let rgb: Vec<[f32; 3]> = (0..w * h)
            .map(|i| [(i % 97) as f32 / 97.0, (i % 13) as f32, (i as f32).sqrt()])
            .collect();
        let dir = std::env::temp_dir().join(format!("wavetrace-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for ext in ["png", "exr", "pfm"] {
            let path = dir.join(format!("a.{ext}"));
            write_image(&path, w, h, &rgb).unwrap();
            let first = std::fs::read(&path).unwrap();
            for _ in 0..8 {
                write_image(&path, w, h, &rgb).unwrap();
                assert!(std::fs::read(&path).unwrap() == first, "{ext} bytes differ");
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// A linear RGB image read back from a file.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels, row 0 at the top.
    pub rgb: Vec<[f32; 3]>,
}

impl Image {
    /// The first pixel, in reading order, that is not radiance: a channel
    /// NaN, infinite or negative. Its column, row and value.
    pub fn first_non_radiance(&self) -> Option<(u32, u32, [f32; 3])> {
        let i = self
            .rgb
            .iter()
            .position(|p| p.iter().any(|c| !(c.is_finite() && *c >= 0.0)))?;
        let width = self.width.max(1) as usize;
        Some(((i % width) as u32, (i / width) as u32, self.rgb[i]))
    }
}

/// Read an image that must hold radiance — finite, non-negative pixels —
/// such as a reference to measure errors against or an image to denoise;
/// `role` names it in the error ("the reference"). A NaN, infinite or
/// negative pixel is refused, naming the first: it would turn every error
/// figure into NaN, or pass through the denoiser into its neighbours.
pub fn read_radiance(path: &Path, role: &str) -> Result<Image> {
    let image = read_image(path)?;
    match image.first_non_radiance() {
        None => Ok(image),
        Some((x, y, [r, g, b])) => Err(Error::Settings(format!(
            "{}: pixel ({x}, {y}) of {role} is ({r}, {g}, {b}); {role} must be \
             finite and non-negative (radiance) in every pixel",
            path.display()
        ))),
    }
}

/// Read a linear float image: a PFM (colour, either byte order) or an
/// OpenEXR file with R, G and B channels (its first layer). The size is
/// checked against the data before anything of that size is allocated.
pub fn read_image(path: &Path) -> Result<Image> {
    let bad = |m: String| Error::Settings(format!("{}: {m}", path.display()));
    let format = ImageFormat::from_path(path)?;
    match format {
        ImageFormat::Pfm => {
            let bytes = std::fs::read(path).map_err(|e| FileError::new(path, e))?;
            read_pfm(&bytes).map_err(bad)
        }
        ImageFormat::Exr => read_exr(path).map_err(bad),
        ImageFormat::Png => Err(bad(
            "a PNG is 8-bit and clamped; give the reference as .exr or .pfm".into(),
        )),
    }
}

fn read_pfm(bytes: &[u8]) -> std::result::Result<Image, String> {
    // Three whitespace-separated header tokens after "PF": width, height,
    // scale (negative: little-endian), then one whitespace byte.
    let mut at = 0;
    let mut token = || -> std::result::Result<&[u8], String> {
        while bytes.get(at).is_some_and(u8::is_ascii_whitespace) {
            at += 1;
        }
        let start = at;
        while bytes.get(at).is_some_and(|b| !b.is_ascii_whitespace()) {
            at += 1;
        }
        if start == at || at - start > 32 {
            return Err("not a PFM image (bad header)".into());
        }
        Ok(&bytes[start..at])
    };
    if token()? != b"PF" {
        return Err("not a colour PFM image (expected \"PF\")".into());
    }
    let mut number = |what: &str| -> std::result::Result<f64, String> {
        std::str::from_utf8(token()?)
            .ok()
            .and_then(|t| t.parse().ok())
            .ok_or_else(|| format!("not a PFM image (bad {what})"))
    };
    let (w, h, scale) = (number("width")?, number("height")?, number("scale")?);
    let data = bytes.get(at + 1..).unwrap_or(&[]);
    let valid = |x: f64| x >= 1.0 && x <= u32::MAX as f64 && x.fract() == 0.0;
    if !(valid(w) && valid(h)) || scale == 0.0 || !scale.is_finite() {
        return Err(format!("not a PFM image (size {w}x{h}, scale {scale})"));
    }
    let (w, h) = (w as usize, h as usize);
    if w.checked_mul(h).and_then(|n| n.checked_mul(12)) != Some(data.len()) {
        return Err(format!(
            "a {w}x{h} PFM holds {} bytes of pixels, not {}",
            w * h * 12,
            data.len()
        ));
    }
    let little = scale < 0.0;
    let float = |b: &[u8]| {
        let b: [u8; 4] = b.try_into().expect("4 bytes");
        if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let mut rgb = Vec::with_capacity(w * h);
    // PFM rows run bottom to top.
    for row in data.chunks_exact(w * 12).rev() {
        rgb.extend(
            row.chunks_exact(12)
                .map(|p| [float(&p[0..4]), float(&p[4..8]), float(&p[8..12])]),
        );
    }
    Ok(Image {
        width: w as u32,
        height: h as u32,
        rgb,
    })
}

/// The most an EXR compression can shrink pixel data (generously): a file
/// smaller than its declared pixel data over this cannot hold the image its
/// header declares, and is refused before that much memory is allocated.
fn max_exr_ratio(compression: exr::compression::Compression) -> u64 {
    use exr::compression::Compression::*;
    match compression {
        Uncompressed => 1,
        // A run of up to 128 equal bytes in 2.
        RLE => 64,
        // A 4×4 block of halves (32 bytes) in 14, or in 3 where it is flat.
        B44 => 3,
        B44A => 11,
        // Deflate's limit is 1032:1; PXR24 first packs 32-bit floats into 24 bits.
        ZIP1 | ZIP16 | PXR24 => 2 * 1032,
        // Huffman coders with run codes (PIZ), lossy DCT (DWA), wavelets.
        _ => 1 << 16,
    }
}

fn read_exr(path: &Path) -> std::result::Result<Image, String> {
    use exr::prelude::{ReadChannels, ReadLayers, RgbChannels, Vec2, read};
    // The header's size is checked before pixels of that size are
    // allocated: a forged header (or a tiny, highly compressed file) could
    // ask for any amount.
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| format!("cannot read the EXR image: {e}"))?;
    for h in &meta.headers {
        let bytes = (h.layer_size.0 as u64)
            .checked_mul(h.layer_size.1 as u64)
            .and_then(|n| n.checked_mul(12));
        let fits = crate::fs::system_memory().unwrap_or(u64::MAX) / 2;
        if bytes.is_none_or(|b| b > fits) {
            return Err(format!(
                "the EXR image is {}x{} pixels: too large to load in this system's memory",
                h.layer_size.0, h.layer_size.1
            ));
        }
    }
    let file_bytes = std::fs::metadata(path)
        .map_err(|e| format!("cannot read the EXR image: {e}"))?
        .len();
    for h in &meta.headers {
        let pixel_bytes = (h.layer_size.0 as u64)
            .saturating_mul(h.layer_size.1 as u64)
            .saturating_mul(h.channels.bytes_per_pixel as u64);
        let ratio = max_exr_ratio(h.compression);
        if file_bytes < pixel_bytes / ratio {
            return Err(format!(
                "the EXR header declares {}x{} pixels ({pixel_bytes} bytes of pixel data), \
                 more than the file's {file_bytes} bytes can hold with {} compression \
                 (at most {ratio}:1): the file is forged or truncated",
                h.layer_size.0, h.layer_size.1, h.compression
            ));
        }
    }
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            |size: Vec2<usize>, _: &RgbChannels| (size.0, vec![[0.0f32; 3]; size.0 * size.1]),
            |(w, px): &mut (usize, Vec<[f32; 3]>), p: Vec2<usize>, (r, g, b): (f32, f32, f32)| {
                px[p.1 * *w + p.0] = [r, g, b];
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| format!("cannot read the EXR image: {e}"))?;
    let layer = image.layer_data;
    Ok(self::Image {
        width: layer.size.0 as u32,
        height: layer.size.1 as u32,
        rgb: layer.channel_data.pixels.1,
    })
}
