//! `--exposure` and `--view`: how a PNG shows the linear image (render,
//! merge and denoise take them).

use crate::cli::render::named;
use crate::error::{Error, Result};
use crate::output::ImageFormat;
use crate::output::view::{View, ViewTransform};
use clap::Args;
use std::path::Path;

/// The exposure and view transform of a PNG output.
#[derive(Clone, Copy, Debug, Default, Args)]
pub struct ViewArgs {
    /// PNG only: brighten (or darken, below 0) the image by this many stops
    /// before the view transform [default: 0].
    #[arg(long, value_name = "EV", allow_negative_numbers = true, value_parser = parse_exposure, help_heading = "Output")]
    pub exposure: Option<f32>,
    /// PNG only: standard (clamp, sRGB) or agx (Blender 4's AgX, which
    /// rolls highlights off to white) [default: standard].
    #[arg(long, value_parser = named(View::NAMES, View::from_name), help_heading = "Output")]
    pub view: Option<View>,
}

/// Stops of exposure: a finite number within ±64.
fn parse_exposure(text: &str) -> std::result::Result<f32, String> {
    match text.trim().parse::<f32>() {
        Ok(ev) if ev.is_finite() && ev.abs() <= 64.0 => Ok(ev),
        _ => Err(format!(
            "{text:?}: expected a number of stops between -64 and 64"
        )),
    }
}

impl ViewArgs {
    /// The transform for the image `out` (`None`: no image is written).
    /// Asking for one where no PNG is written is refused: EXR and PFM
    /// images stay linear.
    pub fn transform(&self, out: Option<&Path>) -> Result<ViewTransform> {
        let view = ViewTransform {
            exposure: self.exposure.unwrap_or(0.0),
            view: self.view.unwrap_or_default(),
        };
        if self.exposure.is_none() && self.view.is_none() {
            return Ok(view);
        }
        let png = out.is_some_and(|p| matches!(ImageFormat::from_path(p), Ok(ImageFormat::Png)));
        if !png {
            let what = match out {
                Some(p) => format!("{} is written linear", p.display()),
                None => "no image is written".into(),
            };
            return Err(Error::Settings(format!(
                "--exposure and --view shape PNG images only, and {what}: drop them, or write a .png"
            )));
        }
        Ok(view)
    }
}
