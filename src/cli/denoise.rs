//! `wavetrace denoise`: an image rendered earlier, denoised with OIDN.

use crate::denoise::{Aux, Denoiser};
use crate::error::{Error, Result};
use crate::fs::{check_outputs, check_writable};
use crate::output::{
    ImageFormat, aov_layer, aov_path, check_output_format, read_exr_layer, read_radiance,
    write_image_with_aovs,
};
use crate::scene::Aov;
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `wavetrace denoise`.
#[derive(Clone, Debug, Args)]
pub struct DenoiseArgs {
    /// The noisy image: linear .exr (its albedo.R/G/B and normal.X/Y/Z
    /// layers, when present, guide the denoiser; its AOV layers are carried
    /// to the output) or .pfm (colour only).
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// The denoised image (.exr, .pfm or .png; a .pfm or .png gets the
    /// input's AOV layers as STEM.NAME.pfm files beside it).
    #[arg(long, short = 'o', value_name = "FILE")]
    pub out: PathBuf,
    /// The PNG view.
    #[command(flatten)]
    pub view: crate::cli::ViewArgs,
}

/// An image's pixels: row-major linear RGB (or XYZ), row 0 at the top.
type Pixels = Vec<[f32; 3]>;

/// The AOV layers an EXR image has (none for other formats), in canonical
/// order.
pub(crate) fn aov_layers(path: &Path) -> Result<Vec<(Aov, Pixels)>> {
    if ImageFormat::from_path(path)? != ImageFormat::Exr {
        return Ok(Vec::new());
    }
    let mut layers = Vec::new();
    for aov in Aov::ALL {
        let (name, channels) = aov_layer(aov);
        if let Some(pixels) = read_exr_layer(path, name, channels)? {
            layers.push((aov, pixels));
        }
    }
    Ok(layers)
}

/// Run `wavetrace denoise`.
pub fn run(args: DenoiseArgs) -> Result<()> {
    check_output_format(&args.out)?;
    let view = args.view.transform(Some(&args.out))?;
    if crate::output::is_partial_path(&args.out) {
        return Err(Error::Settings(format!(
            "{}: denoise writes an image (.exr, .pfm or .png)",
            args.out.display()
        )));
    }
    // The AOV files beside a PNG or PFM --out: every one an EXR input
    // might hold as a layer.
    let aov_files: Vec<PathBuf> = if ImageFormat::from_path(&args.input)? == ImageFormat::Exr {
        Aov::ALL
            .iter()
            .filter_map(|&a| aov_path(&args.out, a))
            .collect()
    } else {
        Vec::new()
    };
    let mut outputs = vec![("--out", args.out.as_path())];
    outputs.extend(
        aov_files
            .iter()
            .map(|f| ("an AOV file of --out", f.as_path())),
    );
    check_outputs(&[("the image to denoise", &args.input)], &outputs)?;
    check_writable(&args.out)?;
    let image = read_radiance(&args.input, "the image to denoise")?;
    let mut denoiser = Denoiser::new()?;
    let layers = aov_layers(&args.input)?;
    let layer = |aov| layers.iter().find(|(a, _)| *a == aov).map(|(_, p)| &p[..]);
    let aux = layer(Aov::Albedo)
        .zip(layer(Aov::Normal))
        .map(|(albedo, normal)| Aux { albedo, normal });
    let t = Instant::now();
    let rgb = denoiser.denoise(image.width, image.height, &image.rgb, aux)?;
    let seconds = t.elapsed().as_secs_f64();
    let aovs: Vec<(Aov, &[[f32; 3]])> = layers.iter().map(|(a, p)| (*a, &p[..])).collect();
    write_image_with_aovs(&args.out, (image.width, image.height), &rgb, &aovs, view)?;
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
