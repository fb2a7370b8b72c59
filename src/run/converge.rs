//! `wavetrace converge`'s study: how an image's error falls with samples
//! per pixel, and where more samples stop paying — the report's proposed
//! "perception study", with a perceptual metric (mean ꟻLIP,
//! [`crate::metrics::mean_flip`]) in place of a survey.
//!
//! The film sums samples exactly, so the image at 2^k samples per pixel
//! is a prefix of the same render: one progressive render (passes of
//! samples `2^(k-1)..2^k` added to one film) gives the whole curve, each
//! point bit-identical to a render of that many samples from scratch.
//! Library code: it prints nothing; [`StudyObserver`] reports progress.

use crate::error::Result;
use crate::metrics::{ImageErrors, mean_flip};
use crate::render::{DEFAULT_INTEGRATOR, DEFAULT_SAMPLER, RenderSettings, Renderer};
use crate::scene::{Integrator, SamplerKind, Scene};
use serde::Serialize;
use std::time::Instant;

/// The default `--jnd`: a doubling of the samples that lowers the mean
/// ꟻLIP by less than this (absolute, on ꟻLIP's 0–1 scale) no longer pays.
///
/// A convention, not a measured just-noticeable difference: 0.005 is half
/// a percent of ꟻLIP's range. With Monte Carlo noise a doubling of the
/// samples removes about 20% of the mean ꟻLIP (measured on the Cornell
/// box; 29% if it fell as 1/√N), so the threshold is reached near a mean
/// ꟻLIP of 0.025, where the noise left is faint in the 8-bit image. A
/// study with observers would calibrate it; `--jnd` sets another.
pub const DEFAULT_JND: f64 = 0.005;

/// One estimator setting of a study.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setting {
    /// The integrator.
    pub integrator: Integrator,
    /// The sampler.
    pub sampler: SamplerKind,
}

impl Setting {
    /// `integrator/sampler`, e.g. `report/independent`.
    pub fn label(&self) -> String {
        format!("{}/{}", self.integrator.name(), self.sampler.name())
    }
}

/// The errors of the image at one sample count.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Point {
    /// Samples per pixel.
    pub spp: u32,
    /// Render seconds to reach them (the sum of the passes so far; not
    /// the time spent measuring errors).
    pub seconds: f64,
    /// Mean squared error against the reference.
    pub mse: f64,
    /// Relative mean squared error against the reference.
    pub relmse: f64,
    /// Mean ꟻLIP against the reference (8-bit sRGB images).
    pub mean_flip: f64,
}

/// A setting's convergence curve.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Curve {
    /// The integrator's name.
    pub integrator: String,
    /// The sampler's name.
    pub sampler: String,
    /// The points, at spp 1, 2, 4, … ([`spp_levels`]).
    pub points: Vec<Point>,
    /// [`diminishing_returns`] of the mean ꟻLIP curve.
    pub diminishing_returns_spp: Option<u32>,
    /// The crop of the image at each point (linear RGB, row-major).
    #[serde(skip)]
    pub crops: Vec<Vec<[f32; 3]>>,
}

impl Curve {
    /// `integrator/sampler`.
    pub fn label(&self) -> String {
        format!("{}/{}", self.integrator, self.sampler)
    }
}

/// A rectangle of the image: the crops of the study's strip.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Crop {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Crop {
    /// The default crop of a `width`×`height` image: a square of a third
    /// of the shorter side, centred horizontally, its centre two thirds of
    /// the way down (in the Cornell box: the floor, the blocks' edges and
    /// their soft shadows, where noise shows most).
    pub fn default_for(width: u32, height: u32) -> Self {
        let side = (width.min(height) / 3).max(1);
        let x = (width - side) / 2;
        let y = (height * 2 / 3).saturating_sub(side / 2).min(height - side);
        Self {
            x,
            y,
            width: side,
            height: side,
        }
    }

    /// The crop's pixels of a row-major image `image_width` wide.
    pub fn cut(&self, rgb: &[[f32; 3]], image_width: u32) -> Vec<[f32; 3]> {
        let mut out = Vec::with_capacity((self.width * self.height) as usize);
        for row in self.y..self.y + self.height {
            let start = (row * image_width + self.x) as usize;
            out.extend_from_slice(&rgb[start..start + self.width as usize]);
        }
        out
    }
}

/// The sample counts a study measures: 1, 2, 4, … up to `max`, and `max`
/// itself when it is not a power of two.
pub fn spp_levels(max: u32) -> Vec<u32> {
    let mut v = Vec::new();
    let mut n = 1u32;
    while n <= max {
        v.push(n);
        match n.checked_mul(2) {
            Some(m) => n = m,
            None => break,
        }
    }
    if v.last() != Some(&max) && max > 0 {
        v.push(max);
    }
    v
}

/// The diminishing-returns point of an error curve `(spp, error)` sorted
/// by spp: the smallest spp from which on every doubling of the samples
/// lowers the error by less than `jnd`. Pairs of points that are not a
/// doubling (a last, non-power-of-two level) are ignored. `None` when the
/// last doubling still lowers the error by `jnd` or more (more samples
/// are needed to find the point), or when there is no doubling.
pub fn diminishing_returns(curve: &[(u32, f64)], jnd: f64) -> Option<u32> {
    let doublings: Vec<(u32, f64)> = curve
        .windows(2)
        .filter(|w| w[1].0 == w[0].0.saturating_mul(2))
        .map(|w| (w[0].0, w[0].1 - w[1].1))
        .collect();
    let mut found = None;
    for &(spp, gain) in doublings.iter().rev() {
        if gain < jnd {
            found = Some(spp);
        } else {
            break;
        }
    }
    found
}

/// The seed of a reference rendered by the study: the bitwise complement
/// of the study's seed, so the reference shares no sample with the
/// images measured against it (it would if it used the same seed and
/// estimator, making their errors too small).
pub fn reference_seed(seed: u64) -> u64 {
    !seed
}

/// The settings of a reference for a study with settings `base`: the
/// unbiased default estimator ([`DEFAULT_INTEGRATOR`], [`DEFAULT_SAMPLER`],
/// no Russian roulette), `spp` samples, seed [`reference_seed`].
pub fn reference_settings(base: &RenderSettings, spp: u32) -> RenderSettings {
    let mut s = base.clone();
    s.integrator = DEFAULT_INTEGRATOR;
    s.sampler = DEFAULT_SAMPLER;
    s.rr_depth = None;
    s.spp = spp;
    s.seed = reference_seed(base.seed);
    s
}

/// What a study reports as it goes.
pub trait StudyObserver {
    /// `spp` more samples per pixel of the current render are done.
    fn samples(&mut self, spp: u32);
}

impl<F: FnMut(u32)> StudyObserver for F {
    fn samples(&mut self, spp: u32) {
        self(spp)
    }
}

/// Render the reference with `settings` (see [`reference_settings`]) in
/// passes, reporting each to `observer`; linear RGB.
pub fn render_reference(
    scene: &Scene,
    settings: &RenderSettings,
    observer: &mut dyn StudyObserver,
) -> Result<Vec<[f32; 3]>> {
    let renderer = Renderer::new(scene, settings)?;
    let mut film = renderer.new_film();
    let step = (settings.spp / 32).max(1);
    let mut done = 0;
    while done < settings.spp {
        let next = (done + step).min(settings.spp);
        renderer.render_samples(done..next, &mut film);
        observer.samples(next - done);
        done = next;
    }
    Ok(film.to_rgb())
}

/// Render `setting` with `base`'s size, depth, seed and threads up to
/// `base.spp` samples per pixel, one pass per level of [`spp_levels`],
/// measuring each level's errors against `reference` and cutting `crop`.
pub fn study(
    scene: &Scene,
    base: &RenderSettings,
    setting: Setting,
    reference: &[[f32; 3]],
    crop: Crop,
    jnd: f64,
    observer: &mut dyn StudyObserver,
) -> Result<Curve> {
    let mut settings = base.clone();
    settings.integrator = setting.integrator;
    settings.sampler = setting.sampler;
    if setting.integrator == Integrator::Report {
        settings.rr_depth = None;
    }
    let renderer = Renderer::new(scene, &settings)?;
    let mut film = renderer.new_film();
    let (mut points, mut crops) = (Vec::new(), Vec::new());
    let mut seconds = 0.0;
    let mut done = 0;
    for spp in spp_levels(settings.spp) {
        let t = Instant::now();
        renderer.render_samples(done..spp, &mut film);
        seconds += t.elapsed().as_secs_f64();
        observer.samples(spp - done);
        done = spp;
        let rgb = film.to_rgb();
        let e = ImageErrors::of(&rgb, reference);
        points.push(Point {
            spp,
            seconds,
            mse: e.mse,
            relmse: e.relmse,
            mean_flip: mean_flip(&rgb, reference, settings.width, settings.height),
        });
        crops.push(crop.cut(&rgb, settings.width));
    }
    let flip: Vec<(u32, f64)> = points.iter().map(|p| (p.spp, p.mean_flip)).collect();
    Ok(Curve {
        integrator: setting.integrator.name().into(),
        sampler: setting.sampler.name().into(),
        diminishing_returns_spp: diminishing_returns(&flip, jnd),
        points,
        crops,
    })
}

/// The curves as CSV: one row per point, with a header.
pub fn to_csv(curves: &[Curve]) -> String {
    let mut s = String::from("integrator,sampler,spp,seconds,mse,relmse,mean_flip\n");
    for c in curves {
        for p in &c.points {
            s += &format!(
                "{},{},{},{},{},{},{}\n",
                c.integrator, c.sampler, p.spp, p.seconds, p.mse, p.relmse, p.mean_flip
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels() {
        assert_eq!(spp_levels(1), vec![1]);
        assert_eq!(spp_levels(8), vec![1, 2, 4, 8]);
        assert_eq!(spp_levels(10), vec![1, 2, 4, 8, 10]);
        assert!(spp_levels(0).is_empty());
        assert_eq!(spp_levels(u32::MAX).len(), 33);
    }

    #[test]
    fn default_crop_lies_in_the_image() {
        for (w, h) in [(1, 1), (2, 7), (256, 256), (640, 360)] {
            let c = Crop::default_for(w, h);
            assert!(
                c.x + c.width <= w && c.y + c.height <= h,
                "{c:?} in {w}x{h}"
            );
            assert!(c.width >= 1 && c.height >= 1);
        }
        let rgb: Vec<[f32; 3]> = (0..12).map(|i| [i as f32; 3]).collect();
        let c = Crop {
            x: 1,
            y: 1,
            width: 2,
            height: 2,
        };
        assert_eq!(
            c.cut(&rgb, 4),
            vec![[5.0; 3], [6.0; 3], [9.0; 3], [10.0; 3]]
        );
    }
}
