//! Errors of an image against a reference: what image quality per time is
//! measured with.

/// An image's errors against a reference image of the same size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageErrors {
    /// Mean squared error over pixels and channels: mean of `(a - r)²`.
    pub mse: f64,
    /// Relative mean squared error: mean of `(a - r)² / (r² + 0.01)` over
    /// pixels and channels (the 0.01 keeps black pixels from dominating).
    pub relmse: f64,
}

impl ImageErrors {
    /// The errors of `image` against `reference` (same length, row-major
    /// RGB). Non-finite differences count as infinite errors.
    pub fn of(image: &[[f32; 3]], reference: &[[f32; 3]]) -> Self {
        assert_eq!(image.len(), reference.len(), "images of one size");
        let (mut se, mut rel) = (0.0f64, 0.0f64);
        for (a, r) in image.iter().zip(reference) {
            for c in 0..3 {
                let d = a[c] as f64 - r[c] as f64;
                let d2 = if d.is_finite() { d * d } else { f64::INFINITY };
                se += d2;
                rel += d2 / ((r[c] as f64).powi(2) + 0.01);
            }
        }
        let n = (image.len() * 3).max(1) as f64;
        Self {
            mse: se / n,
            relmse: rel / n,
        }
    }

    /// Efficiency, `1 / (relMSE × seconds)`: independent of the sample
    /// count for an unbiased estimator, higher is better.
    pub fn efficiency(&self, seconds: f64) -> f64 {
        1.0 / (self.relmse * seconds)
    }
}

/// Mean ꟻLIP (NVIDIA's perceptual difference metric, LDR version; Andersson
/// et al. 2020, through the `nv-flip` crate and the reference C++ code) of
/// `image` against `reference`, both linear RGB of `width`×`height`, as
/// seen in their 8-bit sRGB PNGs ([`srgb8`](crate::output::srgb8)), at the default viewing
/// condition of 67 pixels per degree. 0 for identical images; at most 1.
pub fn mean_flip(image: &[[f32; 3]], reference: &[[f32; 3]], width: u32, height: u32) -> f64 {
    use crate::output::srgb8;
    mean_flip_srgb8(&srgb8(image), &srgb8(reference), width, height)
}

/// [`mean_flip`] of two 8-bit sRGB images (row-major RGB bytes).
pub fn mean_flip_srgb8(image: &[u8], reference: &[u8], width: u32, height: u32) -> f64 {
    let n = width as usize * height as usize;
    assert!(
        image.len() == n * 3 && reference.len() == n * 3,
        "images of one size"
    );
    if n == 0 {
        return 0.0;
    }
    let r = nv_flip::FlipImageRgb8::with_data(width, height, reference);
    let t = nv_flip::FlipImageRgb8::with_data(width, height, image);
    let error = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let sum: f64 = error.to_vec().iter().map(|&e| e as f64).sum();
    sum / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_follow_their_definitions() {
        let r = [[1.0, 0.0, 2.0], [0.5, 0.5, 0.5]];
        assert_eq!(
            ImageErrors::of(&r, &r),
            ImageErrors {
                mse: 0.0,
                relmse: 0.0
            }
        );
        let a = [[1.5, 0.1, 2.0], [0.5, 0.5, 0.0]];
        let e = ImageErrors::of(&a, &r);
        let mse = (0.25 + 0.01 + 0.25) / 6.0;
        let rel = (0.25 / 1.01 + 0.01 / 0.01 + 0.25 / 0.26) / 6.0;
        assert!(
            (e.mse - mse).abs() < 1e-7 && (e.relmse - rel).abs() < 1e-6,
            "{e:?}"
        );
        assert!(
            ImageErrors::of(&[[f32::NAN; 3]], &[[0.0; 3]])
                .relmse
                .is_infinite()
        );
        assert_eq!(
            ImageErrors {
                mse: 1.0,
                relmse: 0.5
            }
            .efficiency(4.0),
            0.5
        );
    }
}
