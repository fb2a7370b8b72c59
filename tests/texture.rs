//! Texture lookups against analytic patterns: where a texel lands in UV for
//! each wrap mode and filter, with and without `KHR_texture_transform`; the
//! sRGB curve; decoding PNG and JPEG, and refusing hostile images.

use wavetrace::scene::texture::{
    ColourSpace, Filter, Sampler, Texture, UvTransform, Wrap, srgb_to_linear,
};

const W: usize = 5;
const H: usize = 3;
const WRAPS: [Wrap; 3] = [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat];

/// A 5 × 3 linear texture whose texel (i, j) says where it is: red
/// `40 i + 10`, green `60 j + 20`.
fn where_am_i() -> Texture {
    let texels = (0..H)
        .flat_map(|j| (0..W).map(move |i| [40 * i as u8 + 10, 60 * j as u8 + 20, 0, 255]))
        .collect();
    Texture::from_rgba8(W, H, texels, ColourSpace::Linear).unwrap()
}

/// The texel a lookup returned, from its red and green values.
fn which(t: [f32; 4]) -> (usize, usize) {
    let i = ((t[0] * 255.0).round() as usize - 10) / 40;
    let j = ((t[1] * 255.0).round() as usize - 20) / 60;
    (i, j)
}

/// A coordinate in texel units `x` (`u · n`) wrapped into `[0, n)`,
/// computed in f64 from the wrap mode's definition on the continuous line.
fn wrap64(x: f64, n: usize, wrap: Wrap) -> f64 {
    let n = n as f64;
    match wrap {
        Wrap::Repeat => x.rem_euclid(n),
        Wrap::ClampToEdge => x.clamp(0.0, n - 1e-9),
        Wrap::MirroredRepeat => {
            let m = x.rem_euclid(2.0 * n);
            if m < n { m } else { 2.0 * n - m }
        }
    }
}

struct Lcg(u64);
impl Lcg {
    fn f(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Whether `x` (texel units) is within `eps` of a texel border.
fn near_border(x: f64, eps: f64) -> bool {
    (x - x.round()).abs() < eps
}

#[test]
fn nearest_lands_on_the_texel_the_point_is_in_for_each_wrap() {
    let t = where_am_i();
    let mut rng = Lcg(1);
    for wrap_u in WRAPS {
        for wrap_v in WRAPS {
            let s = Sampler {
                wrap_u,
                wrap_v,
                filter: Filter::Nearest,
            };
            let mut checked = 0;
            for _ in 0..20_000 {
                let (u, v) = (rng.f() * 8.0 - 4.0, rng.f() * 8.0 - 4.0);
                let (u32_, v32_) = (u as f32, v as f32);
                let (x, y) = (u32_ as f64 * W as f64, v32_ as f64 * H as f64);
                if near_border(x, 1e-4) || near_border(y, 1e-4) {
                    continue;
                }
                let want = (
                    wrap64(x, W, wrap_u).floor() as usize,
                    wrap64(y, H, wrap_v).floor() as usize,
                );
                let got = which(t.sample(s, u32_, v32_));
                assert_eq!(got, want, "{s:?} at ({u}, {v})");
                checked += 1;
            }
            assert!(checked > 19_000);
        }
    }
    // Texel centres, and (0, 0) is the top-left corner.
    let s = Sampler {
        filter: Filter::Nearest,
        ..Sampler::default()
    };
    for j in 0..H {
        for i in 0..W {
            let (u, v) = ((i as f32 + 0.5) / W as f32, (j as f32 + 0.5) / H as f32);
            assert_eq!(which(t.sample(s, u, v)), (i, j));
        }
    }
    assert_eq!(which(t.sample(s, 0.01, 0.01)), (0, 0));
    assert_eq!(which(t.sample(s, 0.99, 0.01)), (W - 1, 0));
    assert_eq!(which(t.sample(s, 0.01, 0.99)), (0, H - 1));
}

#[test]
fn a_checkerboard_in_uv_lands_where_it_should_in_srgb() {
    // 8 × 8 squares of white and sRGB 128; the lookup is linear radiance.
    let n = 8;
    let texels = (0..n * n)
        .map(|k| {
            let c = if (k % n + k / n) % 2 == 0 { 255 } else { 128 };
            [c, c, c, 255]
        })
        .collect();
    let t = Texture::from_rgba8(n, n, texels, ColourSpace::Srgb).unwrap();
    let grey = srgb_to_linear(128.0 / 255.0);
    // The sRGB curve, not a 2.2 gamma (which gives 0.2195).
    assert!((grey - 0.215_861).abs() < 1e-6, "{grey}");
    let mut rng = Lcg(2);
    for wrap in WRAPS {
        for filter in [Filter::Nearest, Filter::Linear] {
            let s = Sampler {
                wrap_u: wrap,
                wrap_v: wrap,
                filter,
            };
            for _ in 0..20_000 {
                let (u, v) = ((rng.f() * 6.0 - 3.0) as f32, (rng.f() * 6.0 - 3.0) as f32);
                let (x, y) = (u as f64 * n as f64, v as f64 * n as f64);
                // Linear filtering blends within half a texel of a border.
                let eps = if filter == Filter::Linear {
                    0.5 + 1e-4
                } else {
                    1e-4
                };
                let (wx, wy) = (wrap64(x, n, wrap), wrap64(y, n, wrap));
                if near_border(wx, eps) || near_border(wy, eps) {
                    continue;
                }
                let white = (wx.floor() as usize + wy.floor() as usize).is_multiple_of(2);
                let want = if white { 1.0 } else { grey };
                let got = t.sample(s, u, v);
                assert!(
                    (got[0] as f64 - want).abs() < 1e-6 && got[3] == 1.0,
                    "{s:?} at ({u}, {v}): {got:?}, want {want}"
                );
            }
        }
    }
}

#[test]
fn bilinear_reproduces_a_linear_ramp_and_wraps_its_neighbours() {
    // Red 20 i + 5 and green 30 j + 7: bilinear filtering of a linear
    // function is the function, between the first and last texel centres.
    let texels = (0..H)
        .flat_map(|j| (0..W).map(move |i| [20 * i as u8 + 5, 30 * j as u8 + 7, 0, 255]))
        .collect();
    let t = Texture::from_rgba8(W, H, texels, ColourSpace::Linear).unwrap();
    let red = |i: f64| (20.0 * i + 5.0) / 255.0;
    let mut rng = Lcg(3);
    for wrap in WRAPS {
        let s = Sampler {
            wrap_u: wrap,
            wrap_v: Wrap::ClampToEdge,
            filter: Filter::Linear,
        };
        for _ in 0..20_000 {
            let (u, v) = ((rng.f() * 1.2 - 0.1) as f32, rng.f() as f32);
            let x = u as f64 * W as f64 - 0.5;
            let y = (v as f64 * H as f64 - 0.5).clamp(0.0, (H - 1) as f64);
            // The texel indices either side of x, wrapped, and the mix.
            let x0 = x.floor();
            let fx = x - x0;
            let wrap_i = |i: i64| -> f64 {
                let n = W as i64;
                (match wrap {
                    Wrap::Repeat => i.rem_euclid(n),
                    Wrap::ClampToEdge => i.clamp(0, n - 1),
                    Wrap::MirroredRepeat => {
                        let m = i.rem_euclid(2 * n);
                        if m < n { m } else { 2 * n - 1 - m }
                    }
                }) as f64
            };
            let want_r = red(wrap_i(x0 as i64)) * (1.0 - fx) + red(wrap_i(x0 as i64 + 1)) * fx;
            let want_g = (30.0 * y + 7.0) / 255.0;
            let got = t.sample(s, u, v);
            assert!(
                (got[0] as f64 - want_r).abs() < 2e-6,
                "{wrap:?} at u = {u}: red {}, want {want_r}",
                got[0]
            );
            assert!(
                (got[1] as f64 - want_g).abs() < 2e-6,
                "v = {v}: green {}, want {want_g}",
                got[1]
            );
            if (0.0..=(W - 1) as f64).contains(&x) {
                assert!((got[0] as f64 - red(x)).abs() < 2e-6);
            }
        }
    }
}

#[test]
fn texture_transform_is_t_r_s_as_the_extension_writes_it() {
    let t = where_am_i();
    let s = Sampler {
        filter: Filter::Nearest,
        ..Sampler::default()
    };
    // Offset alone moves the lookup by the offset.
    let m = UvTransform::new([0.5, 0.0], 0.0, [1.0, 1.0]);
    assert_eq!(
        which(t.sample(s, m.apply([0.1, 0.1])[0], m.apply([0.1, 0.1])[1])),
        (3, 0)
    );
    // Rotation by +π/2: u' = v, v' = -u (R = [[cos, sin], [-sin, cos]]).
    let m = UvTransform::new([0.0, 0.0], std::f32::consts::FRAC_PI_2, [1.0, 1.0]);
    let [u, v] = m.apply([0.1, 0.2]);
    assert!((u - 0.2).abs() < 1e-7 && (v + 0.1).abs() < 1e-7, "{u} {v}");
    assert_eq!(which(t.sample(s, u, v)), (1, 2));
    // Random transforms against the product written out in f64.
    let mut rng = Lcg(4);
    for _ in 0..20_000 {
        let off = [(rng.f() * 2.0 - 1.0) as f32, (rng.f() * 2.0 - 1.0) as f32];
        let rot = (rng.f() * 7.0 - 3.5) as f32;
        let sc = [(rng.f() * 4.0 - 2.0) as f32, (rng.f() * 4.0 - 2.0) as f32];
        let (u, v) = (rng.f() as f32, rng.f() as f32);
        let (sr, cr) = (rot as f64).sin_cos();
        // T · R · S · (u, v, 1), as 3 × 3 matrices.
        let scale = [
            [sc[0] as f64, 0.0, 0.0],
            [0.0, sc[1] as f64, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let rotation = [[cr, sr, 0.0], [-sr, cr, 0.0], [0.0, 0.0, 1.0]];
        let translation = [
            [1.0, 0.0, off[0] as f64],
            [0.0, 1.0, off[1] as f64],
            [0.0, 0.0, 1.0],
        ];
        let mul = |a: [[f64; 3]; 3], b: [[f64; 3]; 3]| -> [[f64; 3]; 3] {
            std::array::from_fn(|r| {
                std::array::from_fn(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum())
            })
        };
        let m64 = mul(mul(translation, rotation), scale);
        let want = [
            m64[0][0] * u as f64 + m64[0][1] * v as f64 + m64[0][2],
            m64[1][0] * u as f64 + m64[1][1] * v as f64 + m64[1][2],
        ];
        let got = UvTransform::new(off, rot, sc).apply([u, v]);
        assert!(
            (got[0] as f64 - want[0]).abs() < 1e-5 && (got[1] as f64 - want[1]).abs() < 1e-5,
            "{got:?} vs {want:?}"
        );
        let (x, y) = (want[0] * W as f64, want[1] * H as f64);
        if near_border(x, 1e-3) || near_border(y, 1e-3) {
            continue;
        }
        let expect = (
            wrap64(x, W, Wrap::Repeat).floor() as usize,
            wrap64(y, H, Wrap::Repeat).floor() as usize,
        );
        assert_eq!(which(t.sample(s, got[0], got[1])), expect);
    }
    assert!(UvTransform::default().is_identity());
}

#[test]
fn coordinates_that_are_not_finite_read_texel_zero() {
    let t = where_am_i();
    for filter in [Filter::Nearest, Filter::Linear] {
        for wrap in WRAPS {
            let s = Sampler {
                wrap_u: wrap,
                wrap_v: wrap,
                filter,
            };
            for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30, -1e30] {
                let got = t.sample(s, x, x);
                assert!(got.iter().all(|c| c.is_finite()), "{s:?} {x}: {got:?}");
            }
        }
    }
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG that declares `w × h` texels and carries no data.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = b"IHDR".to_vec();
    chunk.extend(w.to_be_bytes());
    chunk.extend(h.to_be_bytes());
    chunk.extend([8, 6, 0, 0, 0]);
    out.extend(13u32.to_be_bytes());
    out.extend(&chunk);
    out.extend(crc32(&chunk).to_be_bytes());
    out
}

#[test]
fn png_and_jpeg_decode_and_hostile_images_are_refused() {
    use image::{ImageEncoder, codecs::jpeg::JpegEncoder, codecs::png::PngEncoder};
    // A 3 × 2 PNG, RGBA.
    let pixels: Vec<u8> = (0..24).map(|k| (k * 10) as u8).collect();
    let mut png = Vec::new();
    PngEncoder::new(&mut png)
        .write_image(&pixels, 3, 2, image::ExtendedColorType::Rgba8)
        .unwrap();
    let t = Texture::decode(&png, ColourSpace::Linear).unwrap();
    // Stored in one 4 × 4 tile: 16 texels of 4 bytes.
    assert_eq!((t.width(), t.height(), t.bytes()), (3, 2, 64));
    // Texel (2, 1) holds bytes 20..24.
    let got = t.texel(2, 1);
    for (c, value) in got.into_iter().enumerate() {
        assert_eq!(value, ((20 + c) * 10) as f32 / 255.0);
    }
    // A grey JPEG decodes to about its grey.
    let grey = vec![200u8; 16 * 8 * 3];
    let mut jpg = Vec::new();
    JpegEncoder::new_with_quality(&mut jpg, 95)
        .write_image(&grey, 16, 8, image::ExtendedColorType::Rgb8)
        .unwrap();
    let t = Texture::decode(&jpg, ColourSpace::Srgb).unwrap();
    assert_eq!((t.width(), t.height()), (16, 8));
    let want = srgb_to_linear(200.0 / 255.0) as f32;
    assert!(
        (t.texel(7, 3)[1] - want).abs() < 0.02,
        "{:?}",
        t.texel(7, 3)
    );
    // Hostile: 10⁹ × 10⁹ is refused from its header, before any allocation.
    let e =
        Texture::decode(&png_header(1_000_000_000, 1_000_000_000), ColourSpace::Srgb).unwrap_err();
    assert!(e.to_string().contains("limit"), "{e}");
    // A header and no data; garbage; an empty buffer; another format.
    assert!(Texture::decode(&png_header(4, 4), ColourSpace::Srgb).is_err());
    for bad in [&b"not an image at all"[..], &[], b"GIF89a\x01\x00\x01\x00"] {
        let e = Texture::decode(bad, ColourSpace::Srgb).unwrap_err();
        assert!(e.to_string().contains("PNG"), "{e}");
    }
    // Inconsistent sizes.
    assert!(Texture::from_rgba8(2, 2, vec![[0; 4]; 3], ColourSpace::Linear).is_err());
    assert!(Texture::from_rgba8(0, 2, vec![], ColourSpace::Linear).is_err());
}
