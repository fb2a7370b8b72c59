//! `wavetrace denoise`: an image rendered earlier, denoised with OIDN.

use crate::denoise::{Aux, Denoiser};
use crate::error::{Error, Result};
use crate::fs::check_writable;
use crate::output::{
    ALBEDO_LAYER, ExrLayer, ImageFormat, NORMAL_LAYER, check_output_format, read_exr_layer,
    read_image, write_exr_layers, write_image,
};
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `wavetrace denoise`.
#[derive(Clone, Debug, Args)]
pub struct DenoiseArgs {
    /// The noisy image: linear .exr (its albedo.R/G/B and normal.X/Y/Z
    /// layers, when present, guide the denoiser) or .pfm (colour only).
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// The denoised image (.exr, .pfm or .png).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// An image's pixels: row-major linear RGB (or XYZ), row 0 at the top.
type Pixels = Vec<[f32; 3]>;

/// The albedo and normal layers of an EXR image, if it has both.
pub(crate) fn aux_layers(path: &Path) -> Result<Option<(Pixels, Pixels)>> {
    if ImageFormat::from_path(path)? != ImageFormat::Exr {
        return Ok(None);
    }
    let albedo = read_exr_layer(path, ALBEDO_LAYER.0, ALBEDO_LAYER.1)?;
    let normal = read_exr_layer(path, NORMAL_LAYER.0, NORMAL_LAYER.1)?;
    Ok(albedo.zip(normal))
}

/// Write `rgb` to `path`, with the albedo and normal layers when it is an
/// EXR image and they are given.
pub(crate) fn write_with_aux(
    path: &Path,
    (width, height): (u32, u32),
    rgb: &[[f32; 3]],
    aux: Option<Aux<'_>>,
) -> Result<()> {
    match aux {
        Some(a) if ImageFormat::from_path(path)? == ImageFormat::Exr => {
            let layers = [
                ExrLayer {
                    name: ALBEDO_LAYER.0,
                    channels: ALBEDO_LAYER.1,
                    pixels: a.albedo,
                },
                ExrLayer {
                    name: NORMAL_LAYER.0,
                    channels: NORMAL_LAYER.1,
                    pixels: a.normal,
                },
            ];
            write_exr_layers(path, width, height, rgb, &layers)
        }
        _ => write_image(path, width, height, rgb),
    }
}

/// Run `wavetrace denoise`.
pub fn run(args: DenoiseArgs) -> Result<()> {
    check_output_format(&args.out)?;
    if crate::output::is_partial_path(&args.out) {
        return Err(Error::Settings(format!(
            "{}: denoise writes an image (.exr, .pfm or .png)",
            args.out.display()
        )));
    }
    check_writable(&args.out)?;
    let mut denoiser = Denoiser::new()?;
    let image = read_image(&args.input)?;
    let aux = aux_layers(&args.input)?;
    let aux = aux.as_ref().map(|(albedo, normal)| Aux { albedo, normal });
    let t = Instant::now();
    let rgb = denoiser.denoise(image.width, image.height, &image.rgb, aux)?;
    let seconds = t.elapsed().as_secs_f64();
    write_with_aux(&args.out, (image.width, image.height), &rgb, aux)?;
    println!(
        "denoise: {} ({}x{}, {}) -> {} in {seconds:.3} s",
        args.input.display(),
        image.width,
        image.height,
        if aux.is_some() {
            "with albedo and normal"
        } else {
            "colour only"
        },
        args.out.display()
    );
    Ok(())
}
