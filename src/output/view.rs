//! How a PNG shows the linear radiance: an exposure in stops, then a view
//! transform to the display's 8-bit values — `standard` (clamp, then the
//! sRGB curve, what wavetrace always did) or `agx`, Blender 4's AgX. EXR
//! and PFM images are linear and never pass through here.
//!
//! **AgX** is the "AgX Base sRGB" image formation of Blender 4 (its
//! default view), computed from the formulas of the script that made
//! Blender's look-up table (Eary Chow's `AgX_LUT_Gen`,
//! `AgXBaseRec2020.py` and `AgXBasesRGB.py`): linear Rec.709 → Rec.2020;
//! the *inset* matrix; each channel's log2 exposure relative to 0.18,
//! from −10 to +6.5 stops, mapped to [0, 1]; the AgX sigmoid (Jed Smith's
//! tunable sigmoid: pivot (10/16.5, 0.18^(1/2.4)), slope 2.4, toe and
//! shoulder powers 1.5); the 2.4 power back to linear; 40% of the hue
//! change undone (the hue mixed 60:40 between before and after the
//! curve, in HSV); the *outset* matrix; Rec.2020 → Rec.709; and the 1/2.4
//! power of the display encoding. Blender's table takes its input from
//! −10 to +15 stops, so the log value is clamped to [0, 25/16.5]; its
//! lower guard rail (a luminance-keeping offset of negative values) does
//! nothing to the non-negative colours a render gives, and the sRGB one
//! is replaced by clamping negatives to 0. The unit tests hold the curve
//! to values of Blender's `AgX_Base_sRGB.cube` (docs/view.md).

use super::srgb_encode;

/// A view transform (`--view`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum View {
    /// Clamp to [0, 1], then the sRGB transfer function.
    #[default]
    Standard,
    /// Blender 4's AgX (AgX Base sRGB).
    Agx,
}

impl View {
    /// The names `--view` takes.
    pub const NAMES: &'static [&'static str] = &["standard", "agx"];

    /// The view of a name in [`View::NAMES`].
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "standard" => Some(Self::Standard),
            "agx" => Some(Self::Agx),
            _ => None,
        }
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Standard => "standard",
            Self::Agx => "agx",
        }
    }
}

/// The exposure and view transform of a PNG image.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewTransform {
    /// Stops: the radiance is scaled by `2^exposure` first.
    pub exposure: f32,
    /// The view transform.
    pub view: View,
}

impl ViewTransform {
    /// The display value, in [0, 1], of a linear Rec.709 colour.
    pub fn display(&self, rgb: [f32; 3]) -> [f32; 3] {
        let scale = self.exposure.exp2();
        let c = rgb.map(|x| x * scale);
        match self.view {
            View::Standard => c.map(|x| srgb_encode(x.clamp(0.0, 1.0))),
            View::Agx => agx(c.map(f64::from)).map(|x| x.clamp(0.0, 1.0) as f32),
        }
    }

    /// The 8-bit display bytes of a linear image, as a PNG holds them.
    pub fn bytes(&self, rgb: &[[f32; 3]]) -> Vec<u8> {
        rgb.iter()
            .flat_map(|&p| self.display(p).map(|c| (c * 255.0).round() as u8))
            .collect()
    }
}

type M3 = [[f64; 3]; 3];

fn mul(m: &M3, v: [f64; 3]) -> [f64; 3] {
    m.map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
}

/// Linear Rec.709 to linear Rec.2020 (both D65), through the XYZ
/// matrices of the AgX scripts.
const REC709_TO_REC2020: M3 = [
    [0.6274019247222363, 0.32929197175500147, 0.0433061035227624],
    [
        0.06909548973926076,
        0.9195442812673948,
        0.011360228993344226,
    ],
    [0.016393709088163157, 0.08802816239790057, 0.895578128513936],
];

/// Linear Rec.2020 to linear Rec.709, the inverse of [`REC709_TO_REC2020`].
const REC2020_TO_REC709: M3 = [
    [1.660496219147829, -0.5876564441311355, -0.0728397750166942],
    [
        -0.12454709558601196,
        1.1328951092472963,
        -0.008348013661284438,
    ],
    [
        -0.018153681387071866,
        -0.10059737168574245,
        1.1187510530728142,
    ],
];

/// AgX's inset matrix (rotate [3, −1, −2], inset [0.4, 0.22, 0.13]).
const INSET: M3 = [
    [
        0.856_627_153_315_983,
        0.095_121_240_538_158_8,
        0.048_251_606_145_858_3,
    ],
    [
        0.137_318_972_929_847,
        0.761_241_990_602_591,
        0.101_439_036_467_562,
    ],
    [
        0.111_898_212_999_95,
        0.076_799_418_603_190_3,
        0.811_302_368_396_859,
    ],
];

/// AgX's outset matrix: the inverse of the matrix of rotate [0, 0, 0],
/// inset [0.4, 0.22, 0.04] (inverted by [`invert`] in the tests, which
/// hold the two to each other).
const OUTSET: M3 = [
    [
        1.1271005818144368,
        -0.11060664309660322,
        -0.01649393871783457,
    ],
    [
        -0.1413297634984383,
        1.1578237022162718,
        -0.016493938717834257,
    ],
    [
        -0.14132976349843826,
        -0.11060664309660294,
        1.2519364065950402,
    ],
];

/// The log2 range of the curve, in stops relative to 0.18.
const LOG_MIN: f64 = -10.0;
const LOG_MAX: f64 = 6.5;
/// The top of Blender's table's input range, in stops relative to 0.18.
const LOG_TABLE_MAX: f64 = 15.0;
const SLOPE: f64 = 2.4;
const POWER: f64 = 1.5;
/// The share of the curve's hue change that is kept.
const HUE_MIX: f64 = 0.4;

/// The AgX sigmoid, from the normalised log value `x` to the
/// display-encoded one: a line of slope [`SLOPE`] through the pivot, with
/// a toe to (0, 0) and a shoulder to (1, 1) of power [`POWER`].
fn sigmoid(x: f64) -> f64 {
    let pivot_x = -LOG_MIN / (LOG_MAX - LOG_MIN);
    let pivot_y = 0.18f64.powf(1.0 / 2.4);
    // The scale that takes the curve through the limit (lx, ly) from the
    // pivot (tx, ty).
    let scale = |lx: f64, ly: f64, tx: f64, ty: f64| {
        let run = SLOPE * (lx - tx);
        (run.powf(-POWER) * ((run / (ly - ty)).powf(POWER) - 1.0)).powf(-1.0 / POWER)
    };
    let s = if x < pivot_x {
        -scale(1.0, 1.0, 1.0 - pivot_x, 1.0 - pivot_y)
    } else {
        scale(1.0, 1.0, pivot_x, pivot_y)
    };
    let u = SLOPE * (x - pivot_x) / s;
    s * (u / (1.0 + u.powf(POWER)).powf(1.0 / POWER)) + pivot_y
}

/// Hue, saturation and value, hue in [0, 1) (as `colorsys` and
/// colour-science compute them).
fn hsv(c: [f64; 3]) -> [f64; 3] {
    let max = c[0].max(c[1]).max(c[2]);
    let min = c[0].min(c[1]).min(c[2]);
    let delta = max - min;
    if max <= 0.0 || delta <= 0.0 {
        return [0.0, 0.0, max];
    }
    let [r, g, b] = c.map(|x| (max - x) / delta);
    let h = if c[0] == max {
        b - g
    } else if c[1] == max {
        2.0 + r - b
    } else {
        4.0 + g - r
    };
    [(h / 6.0).rem_euclid(1.0), delta / max, max]
}

fn rgb_of_hsv([h, s, v]: [f64; 3]) -> [f64; 3] {
    if s == 0.0 {
        return [v; 3];
    }
    let h6 = (h * 6.0).rem_euclid(6.0);
    let i = h6.floor();
    let f = h6 - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match i as u32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

/// AgX Base sRGB: the display value (not clamped) of a linear Rec.709
/// colour, as the module's docs describe.
pub fn agx(rgb: [f64; 3]) -> [f64; 3] {
    let c = mul(&REC709_TO_REC2020, rgb.map(|x| x.max(0.0)));
    let c = mul(&INSET, c);
    let hue_before = hsv(c)[0];
    let log = c.map(|x| {
        let stops = (x / 0.18).log2().max(LOG_MIN);
        ((stops - LOG_MIN) / (LOG_MAX - LOG_MIN))
            .min((LOG_TABLE_MAX - LOG_MIN) / (LOG_MAX - LOG_MIN))
    });
    let formed = log.map(|x| sigmoid(x).max(0.0).powf(2.4));
    let [h, s, v] = hsv(formed);
    let mixed = rgb_of_hsv([(1.0 - HUE_MIX) * hue_before + HUE_MIX * h, s, v]);
    let out = mul(&REC2020_TO_REC709, mul(&OUTSET, mixed));
    out.map(|x| x.max(0.0).powf(1.0 / 2.4))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn invert(m: &M3) -> M3 {
        let [[a, b, c], [d, e, f], [g, h, i]] = *m;
        let det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
        [
            [
                (e * i - f * h) / det,
                (c * h - b * i) / det,
                (b * f - c * e) / det,
            ],
            [
                (f * g - d * i) / det,
                (a * i - c * g) / det,
                (c * d - a * f) / det,
            ],
            [
                (d * h - e * g) / det,
                (b * g - a * h) / det,
                (a * e - b * d) / det,
            ],
        ]
    }

    fn close(a: &M3, b: &M3, tol: f64) -> bool {
        (0..3).all(|i| (0..3).all(|j| (a[i][j] - b[i][j]).abs() < tol))
    }

    #[test]
    fn the_matrices_are_what_they_say() {
        let outset_of = [
            [
                0.899_796_955_911_611,
                0.087_199_619_202_835_1,
                0.013_003_424_885_555,
            ],
            [
                0.111_420_988_957_48,
                0.875_575_586_156_966,
                0.013_003_424_885_554_8,
            ],
            [
                0.111_420_988_957_48,
                0.087_199_619_202_834_9,
                0.801_379_391_839_686,
            ],
        ];
        assert!(close(&OUTSET, &invert(&outset_of), 1e-12));
        assert!(close(&REC2020_TO_REC709, &invert(&REC709_TO_REC2020), 1e-9));
        // White stays white through Rec.709 → Rec.2020.
        for row in REC709_TO_REC2020 {
            assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn the_sigmoid_meets_its_limits_and_pivot() {
        assert!(sigmoid(0.0).abs() < 1e-12);
        assert!((sigmoid(1.0) - 1.0).abs() < 1e-12);
        let pivot = sigmoid(10.0 / 16.5);
        assert!((pivot - 0.18f64.powf(1.0 / 2.4)).abs() < 1e-12);
        // Increasing.
        let mut last = -1.0;
        for i in 0..=100 {
            let y = sigmoid(f64::from(i) / 100.0);
            assert!(y > last);
            last = y;
        }
    }

    /// Blender's `AgX_Base_sRGB.cube` (Blender 4.x, 37³ entries; its input
    /// is E-Gamut, log2 from −10 to +15 stops about 0.18): entries
    /// `(r, g, b)` of the grid, with their E-Gamut inputs converted to
    /// linear Rec.709 here, and the table's output.
    const BLENDER: &[([usize; 3], [f64; 3])] = &[
        ([9, 9, 9], [0.139_598_4, 0.139_597_8, 0.139_609_4]),
        ([10, 9, 9], [0.199_849_3, 0.134_421_1, 0.133_740_0]),
        ([10, 10, 9], [0.184_230_5, 0.179_161_3, 0.122_561_0]),
        ([10, 11, 9], [0.158_279_2, 0.231_990_6, 0.097_281_7]),
        ([11, 11, 9], [0.238_486_1, 0.228_752_2, 0.078_161_5]),
        ([12, 9, 9], [0.348_124_8, 0.106_732_5, 0.094_814_0]),
        ([12, 10, 9], [0.339_649_3, 0.170_889_5, 0.069_353_6]),
    ];

    /// E-Gamut to XYZ and XYZ to Rec.709 (D65), for the table's inputs.
    const EGAMUT_TO_XYZ: M3 = [
        [0.705_396_850_1, 0.164_041_328_3, 0.081_017_748_65],
        [0.280_130_724_1, 0.820_206_641_5, -0.100_337_365_6],
        [-0.103_781_511_6, -0.072_907_257_03, 1.265_746_519],
    ];
    const XYZ_TO_REC709: M3 = [
        [
            3.241_003_232_976_36,
            -1.537_398_969_488_79,
            -0.498_615_881_996_363,
        ],
        [
            -0.969_224_252_202_516,
            1.875_929_983_695_18,
            0.041_554_226_340_084_7,
        ],
        [
            0.055_639_419_851_975_5,
            -0.204_011_206_123_91,
            1.057_148_977_187_53,
        ],
    ];

    #[test]
    fn agx_matches_blenders_table() {
        for (grid, expected) in BLENDER {
            let egamut = grid.map(|i| 0.18 * (-10.0 + 25.0 * i as f64 / 36.0).exp2());
            let rec709 = mul(&XYZ_TO_REC709, mul(&EGAMUT_TO_XYZ, egamut));
            let got = agx(rec709);
            let grey = grid[0] == grid[1] && grid[1] == grid[2];
            // Greys to the table's own rounding; colours within 0.01 (2.6
            // of 255): see docs/view.md.
            let tolerance = if grey { 2e-4 } else { 0.01 };
            for k in 0..3 {
                assert!(
                    (got[k] - expected[k]).abs() < tolerance,
                    "{grid:?}: {got:?} against Blender's {expected:?}"
                );
            }
        }
    }

    #[test]
    fn agx_greys_follow_the_curve_and_black_is_black() {
        assert_eq!(agx([0.0; 3]).map(|x| (x * 255.0).round()), [0.0; 3]);
        // Middle grey lands on the pivot, 0.18^(1/2.4) ≈ 0.49.
        let grey = agx([0.18; 3]);
        for c in grey {
            assert!((c - 0.18f64.powf(1.0 / 2.4)).abs() < 2e-3, "{grey:?}");
        }
        // Brighter is brighter, and highlights go to white, not beyond 1.1.
        let mut last = 0.0;
        for stops in -8..=10 {
            let c = agx([0.18 * f64::from(stops).exp2(); 3])[1];
            assert!(c > last, "{stops}: {c}");
            last = c;
        }
        assert!(last > 0.98 && last < 1.1, "{last}");
    }

    #[test]
    fn standard_is_the_old_png_encoding_and_exposure_is_in_stops() {
        let standard = ViewTransform::default();
        for x in [0.0, 0.001, 0.18, 0.5, 1.0, 3.0] {
            assert_eq!(standard.display([x; 3])[0], srgb_encode(x.clamp(0.0, 1.0)));
        }
        let up = ViewTransform {
            exposure: 1.0,
            view: View::Standard,
        };
        assert_eq!(up.display([0.25; 3]), standard.display([0.5; 3]));
    }
}
