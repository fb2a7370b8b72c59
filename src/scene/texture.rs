//! Textures: images decoded once at load and looked up by texture
//! coordinates, the same way by both engines.
//!
//! The conventions are glTF 2.0's (which other renderers and viewers
//! share):
//!
//! - **Coordinates.** `(0, 0)` is the top-left corner of the image and
//!   `(1, 1)` the bottom-right one: `u` runs along a row (to the right),
//!   `v` down a column. Texel `(i, j)` (column `i`, row `j`) has its centre
//!   at `((i + ½)/W, (j + ½)/H)`.
//! - **Filters.** [`Filter::Nearest`] takes the texel the point lies in,
//!   `(⌊uW⌋, ⌊vH⌋)`, with no blending between texels. [`Filter::Linear`]
//!   is bilinear between the four texels whose centres surround the point:
//!   with `x = uW − ½`, `i₀ = ⌊x⌋` and `fx = x − i₀` (likewise `y`, `j₀`,
//!   `fy`), it mixes texels `i₀, i₀ + 1` by `fx` and rows `j₀, j₀ + 1` by
//!   `fy`. There are no mipmaps: a sampler's minification filter is read
//!   as its magnification filter.
//! - **Wrap modes**, per axis and by texel index (so a wrapped neighbour of
//!   a bilinear lookup is wrapped too): [`Wrap::Repeat`] takes `i mod W`,
//!   [`Wrap::ClampToEdge`] clamps `i` to `[0, W − 1]`,
//!   [`Wrap::MirroredRepeat`] takes `m = i mod 2W` and then `m` or
//!   `2W − 1 − m`, whichever lies in `[0, W)`.
//! - **Colour and data.** Colour textures (base colour, emissive) are
//!   decoded with the sRGB transfer curve of IEC 61966-2-1 (not a 2.2
//!   gamma), data textures (metallic-roughness, normal) linearly as
//!   `value / 255`; alpha is always linear. Each texture holds the 256
//!   decoded values of its curve in a table, so every texel value is
//!   decoded once, at load, and filtering mixes decoded (linear) values.
//! - **`KHR_texture_transform`**, as the extension writes it:
//!   `uv′ = T · R · S · uv` with `T` the offset, `R = [[cos r, sin r],
//!   [−sin r, cos r]]` and `S` the scale ([`UvTransform`]), applied before
//!   the wrap.
//!
//! **Memory.** [`BYTES_PER_TEXEL`] = 4 bytes a texel (RGBA, 8 bits a
//! channel; images of 16 bits a channel are rounded to 8 bits, grey images
//! are expanded to RGB), plus a table of 256 `f32` (1 KiB) a texture.
//! The texels are stored in tiles of [`TILE`] × [`TILE`] (one 64-byte
//! cache line each; the sides rounded up to whole tiles), laid out once
//! at load: the four texels of a bilinear lookup then lie in one cache
//! line more often than not, and nearby lookups above and below each other
//! share lines. [`texel_address`] is the one place that finds a texel.
//!
//! **Lanes.** `integrator::texture::sample_lanes` looks up 8 or 16 points
//! at a time for the wavefront engine (in the integrator layer, where the
//! lanes are): the same arithmetic in lanes, the texels gathered, and the
//! same bits as [`Texture::sample`] in every lane.

use std::fmt;

/// What a texel costs in memory: RGBA, one byte a channel.
pub const BYTES_PER_TEXEL: usize = 4;

/// The largest width or height of a texture image, in texels.
pub const MAX_SIDE: u32 = 16_384;

/// The most memory the decoding of one image may allocate, in bytes.
pub const MAX_DECODE_BYTES: u64 = 1 << 30;

/// The most texels an image file may hold per byte of it: deflate (PNG)
/// expands at most 1032 times, and a PNG of one bit a texel holds 8 a
/// byte (8256); JPEG needs at least two bits per 8 × 8 block (256 a byte).
/// A header declaring more is refused before decoding: a 100-byte PNG
/// declaring 16384 × 16384 texels had the decoder allocate 1 GiB.
pub const MAX_TEXELS_PER_BYTE: u64 = 8256;

/// How texel values are decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourSpace {
    /// The sRGB transfer curve (colour textures: base colour, emissive).
    Srgb,
    /// `value / 255` (data textures: metallic-roughness, normal).
    Linear,
}

/// How a coordinate outside `[0, 1)` is brought back into the image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// The image repeats (glTF `REPEAT`, 10497, the default).
    #[default]
    Repeat,
    /// The edge texels extend outward (glTF `CLAMP_TO_EDGE`, 33071).
    ClampToEdge,
    /// The image repeats, every other copy mirrored (glTF
    /// `MIRRORED_REPEAT`, 33648).
    MirroredRepeat,
}

impl Wrap {
    /// The wrap mode of a glTF sampler's `wrapS`/`wrapT` code.
    pub fn from_gl(code: u32) -> Option<Self> {
        match code {
            10497 => Some(Wrap::Repeat),
            33071 => Some(Wrap::ClampToEdge),
            33648 => Some(Wrap::MirroredRepeat),
            _ => None,
        }
    }

    /// The texel index `i` brought into `[0, n)` (`n ≥ 1`).
    #[inline]
    fn index(self, i: i64, n: usize) -> usize {
        let n = n as i64;
        let k = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                let m = i.rem_euclid(2 * n);
                if m < n { m } else { 2 * n - 1 - m }
            }
        };
        k as usize
    }
}

/// How texels are combined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// The texel the point lies in (glTF `NEAREST`, 9728, and the
    /// `NEAREST_MIPMAP_*` minification filters).
    Nearest,
    /// Bilinear between the four nearest texel centres (glTF `LINEAR`,
    /// 9729, and the `LINEAR_MIPMAP_*` filters; the default).
    #[default]
    Linear,
}

impl Filter {
    /// The filter of a glTF sampler's `magFilter` or `minFilter` code.
    pub fn from_gl(code: u32) -> Option<Self> {
        match code {
            9728 | 9984 | 9986 => Some(Filter::Nearest),
            9729 | 9985 | 9987 => Some(Filter::Linear),
            _ => None,
        }
    }
}

/// How a texture is looked up: a wrap mode per axis and a filter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sampler {
    /// The wrap mode along `u` (glTF `wrapS`).
    pub wrap_u: Wrap,
    /// The wrap mode along `v` (glTF `wrapT`).
    pub wrap_v: Wrap,
    /// The filter.
    pub filter: Filter,
}

/// `KHR_texture_transform`: `uv′ = T · R · S · uv`, kept as the 2 × 3
/// matrix `[[a, b, c], [d, e, f]]`: `u′ = a u + b v + c`,
/// `v′ = d u + e v + f`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    m: [f32; 6],
}

impl Default for UvTransform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl UvTransform {
    /// No transform.
    pub const IDENTITY: Self = Self {
        m: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    };

    /// The transform of an offset, a rotation `r` (radians) and a scale:
    /// `T · R · S` with `R = [[cos r, sin r], [−sin r, cos r]]`, so
    /// `u′ = cos r · sx · u + sin r · sy · v + ox` and
    /// `v′ = −sin r · sx · u + cos r · sy · v + oy`.
    pub fn new(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> Self {
        let (s, c) = (rotation as f64).sin_cos();
        let (sx, sy) = (scale[0] as f64, scale[1] as f64);
        Self {
            m: [
                (c * sx) as f32,
                (s * sy) as f32,
                offset[0],
                (-s * sx) as f32,
                (c * sy) as f32,
                offset[1],
            ],
        }
    }

    /// Whether it is the identity.
    pub fn is_identity(&self) -> bool {
        *self == Self::IDENTITY
    }

    /// The transformed coordinates (each a sum of fused multiply-adds).
    #[inline]
    pub fn apply(&self, [u, v]: [f32; 2]) -> [f32; 2] {
        let m = &self.m;
        [
            m[0].mul_add(u, m[1].mul_add(v, m[2])),
            m[3].mul_add(u, m[4].mul_add(v, m[5])),
        ]
    }
}

/// Why an image could not become a texture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextureError(pub String);

impl fmt::Display for TextureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for TextureError {}

/// The side of a tile of texels: an image is stored in tiles of
/// `TILE × TILE` texels (16 texels of 4 bytes: one 64-byte cache line),
/// the tiles row by row from the top, the texels of a tile row by row.
pub const TILE: usize = 4;

/// One tile of texels, each an RGBA texel as a little-endian `u32` (red in
/// the low byte), aligned to a cache line.
#[derive(Clone, Copy, PartialEq, Eq)]
#[repr(C, align(64))]
struct Tile([u32; TILE * TILE]);

// SAFETY: `Tile` is `repr(C)`, 64 bytes of `u32` with no padding (its
// alignment, 64, is its size), so every bit pattern is a valid `Tile` and
// it can be viewed as `u32`s.
unsafe impl bytemuck::Zeroable for Tile {}
// SAFETY: as above.
unsafe impl bytemuck::Pod for Tile {}

/// Integers, in one lane or several, that texel addresses are computed in
/// ([`texel_address`]): `i32` for the scalar lookups, the integer lanes
/// for the lane lookups (`integrator::texture`).
pub trait TexelIndex:
    Copy + std::ops::Add<Output = Self> + std::ops::BitAnd<Output = Self>
{
    /// The same value in every lane.
    fn splat_index(k: i32) -> Self;
    /// Logical shift right by `k` bits (`k < 32`).
    fn shr(self, k: u32) -> Self;
    /// Shift left by `k` bits (`k < 32`).
    fn shl(self, k: u32) -> Self;
    /// The low 32 bits of the product.
    fn mul(self, o: Self) -> Self;
}

impl TexelIndex for i32 {
    #[inline(always)]
    fn splat_index(k: i32) -> Self {
        k
    }
    #[inline(always)]
    fn shr(self, k: u32) -> Self {
        ((self as u32) >> k) as i32
    }
    #[inline(always)]
    fn shl(self, k: u32) -> Self {
        self << k
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.wrapping_mul(o)
    }
}

/// Where texel `(i, j)` (column, row; `0 ≤ i, j < 16384`) lies among the
/// texels of an image stored in tiles ([`TILE`]) that is `tiles_across`
/// tiles wide: the one address computation of the scalar and the lane
/// lookups.
#[inline(always)]
pub fn texel_address<I: TexelIndex>(i: I, j: I, tiles_across: I) -> I {
    let low = I::splat_index(TILE as i32 - 1);
    let tile = j.shr(2).mul(tiles_across) + i.shr(2);
    tile.shl(4) + (j & low).shl(2) + (i & low)
}

/// An image, decoded: RGBA texels of one byte a channel, stored in tiles
/// ([`TILE`]), with the table that turns a byte into its value.
#[derive(Clone, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    /// Tiles across a row of tiles: `⌈width / TILE⌉`.
    tiles_across: usize,
    /// `⌈width / TILE⌉ × ⌈height / TILE⌉` tiles (the texels past the
    /// image's right and bottom edges are zero, and never read).
    tiles: Vec<Tile>,
    space: ColourSpace,
    table: Box<[f32; 256]>,
}

impl fmt::Debug for Texture {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Texture")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("space", &self.space)
            .finish_non_exhaustive()
    }
}

/// The sRGB transfer curve (IEC 61966-2-1) from an encoded value in
/// `[0, 1]` to a linear one.
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Texture {
    /// A texture of `width × height` RGBA texels, row by row from the top.
    pub fn from_rgba8(
        width: usize,
        height: usize,
        texels: Vec<[u8; 4]>,
        space: ColourSpace,
    ) -> Result<Self, TextureError> {
        Self::from_rgba8_bytes(width, height, bytemuck::cast_slice(&texels), space)
    }

    /// A texture of `width × height` RGBA texels given as bytes (4 a
    /// texel, row by row from the top), laid out in tiles once, here.
    pub fn from_rgba8_bytes(
        width: usize,
        height: usize,
        bytes: &[u8],
        space: ColourSpace,
    ) -> Result<Self, TextureError> {
        if width == 0 || height == 0 || width > MAX_SIDE as usize || height > MAX_SIDE as usize {
            return Err(TextureError(format!(
                "an image of {width} × {height} texels (each side must be 1 to {MAX_SIDE})"
            )));
        }
        if bytes.len() != width * height * BYTES_PER_TEXEL {
            return Err(TextureError(format!(
                "{} texels for an image of {width} × {height}",
                bytes.len() / BYTES_PER_TEXEL
            )));
        }
        let table = Box::new(std::array::from_fn(|k| match space {
            ColourSpace::Srgb => srgb_to_linear(k as f64 / 255.0) as f32,
            ColourSpace::Linear => k as f32 / 255.0,
        }));
        let (tiles_across, tiles) = tiled(width, height, bytes);
        Ok(Self {
            width,
            height,
            tiles_across,
            tiles,
            space,
            table,
        })
    }

    /// Decodes a PNG or JPEG image (the format is found from its first
    /// bytes), refusing images wider or taller than [`MAX_SIDE`] or whose
    /// decoding would allocate more than [`MAX_DECODE_BYTES`] before
    /// allocating them.
    pub fn decode(bytes: &[u8], space: ColourSpace) -> Result<Self, TextureError> {
        use image::{ImageFormat, ImageReader, Limits};
        let reader = ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| TextureError(format!("cannot read the image: {e}")))?;
        match reader.format() {
            Some(ImageFormat::Png | ImageFormat::Jpeg) => {}
            Some(f) => {
                return Err(TextureError(format!(
                    "an image in {f:?} format (PNG and JPEG are supported)"
                )));
            }
            None => {
                return Err(TextureError(
                    "the data is not a PNG or JPEG image".to_string(),
                ));
            }
        }
        // The size its header declares, checked against what its bytes
        // can hold before any texel is allocated. (A header the size cannot
        // be read from is left to the decoder below, under its limits, to
        // refuse and name.)
        let size = ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .ok()
            .and_then(|r| r.into_dimensions().ok());
        let most = (bytes.len() as u64)
            .saturating_mul(MAX_TEXELS_PER_BYTE)
            .saturating_add(1 << 16);
        if let Some((w, h)) = size
            && u64::from(w) * u64::from(h) > most
        {
            return Err(TextureError(format!(
                "an image of {w} × {h} texels in {} bytes: more than such a file can hold \
                 ({MAX_TEXELS_PER_BYTE} texels a byte)",
                bytes.len()
            )));
        }
        let mut limits = Limits::default();
        limits.max_image_width = Some(MAX_SIDE);
        limits.max_image_height = Some(MAX_SIDE);
        limits.max_alloc = Some(MAX_DECODE_BYTES);
        let mut reader = reader;
        reader.limits(limits);
        let image = reader
            .decode()
            .map_err(|e| TextureError(format!("cannot decode the image: {e}")))?;
        let rgba = image.into_rgba8();
        let (w, h) = (rgba.width() as usize, rgba.height() as usize);
        Self::from_rgba8_bytes(w, h, rgba.as_raw(), space)
    }

    /// The width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// The height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// How its values are decoded.
    pub fn space(&self) -> ColourSpace {
        self.space
    }

    /// The memory its texels take, in bytes ([`BYTES_PER_TEXEL`] a texel,
    /// the image's width and height rounded up to whole tiles).
    pub fn bytes(&self) -> usize {
        self.tiles.len() * TILE * TILE * BYTES_PER_TEXEL
    }

    /// The texels' bytes, RGBA, row by row from the top: `row` is called
    /// with each row's bytes in turn (what a hash of the image reads; the
    /// texels are stored in tiles).
    pub fn for_each_row(&self, mut row: impl FnMut(&[u8])) {
        let mut bytes = Vec::with_capacity(self.width * BYTES_PER_TEXEL);
        let texels = self.tiled_texels();
        for j in 0..self.height {
            bytes.clear();
            for i in (0..self.width).step_by(TILE) {
                let at = self.address(i, j);
                let n = TILE.min(self.width - i);
                for t in &texels[at..at + n] {
                    bytes.extend_from_slice(&t.to_le_bytes());
                }
            }
            row(&bytes);
        }
    }

    /// The texels as stored: tiles of [`TILE`] × [`TILE`], row by row from
    /// the top, each texel a little-endian `u32` (red in the low byte);
    /// texel `(i, j)` is at [`texel_address`]`(i, j, tiles_across)`.
    #[inline(always)]
    pub fn tiled_texels(&self) -> &[u32] {
        bytemuck::cast_slice(&self.tiles)
    }

    /// How many tiles a row of tiles holds: `⌈width / TILE⌉`.
    #[inline(always)]
    pub fn tiles_across(&self) -> usize {
        self.tiles_across
    }

    /// The 256 decoded values of a byte of red, green or blue.
    #[inline(always)]
    pub fn table(&self) -> &[f32; 256] {
        &self.table
    }

    /// Where texel `(i, j)` (both in range) lies in [`tiled_texels`](Self::tiled_texels).
    #[inline(always)]
    fn address(&self, i: usize, j: usize) -> usize {
        texel_address(i as i32, j as i32, self.tiles_across as i32) as usize
    }

    /// Whether it decodes with the sRGB curve (else linearly).
    pub fn is_srgb(&self) -> bool {
        self.space == ColourSpace::Srgb
    }

    /// Texel `(i, j)` (column, row; both in range), decoded: RGB through
    /// the table, alpha linear.
    #[inline]
    pub fn texel(&self, i: usize, j: usize) -> [f32; 4] {
        let t = self.tiled_texels()[self.address(i, j)].to_le_bytes();
        let tb = &self.table;
        [
            tb[t[0] as usize],
            tb[t[1] as usize],
            tb[t[2] as usize],
            t[3] as f32 / 255.0,
        ]
    }

    /// The value at the texture coordinates `(u, v)` by `sampler`, decoded
    /// RGBA. Coordinates that are not finite read as 0.
    #[inline]
    pub fn sample(&self, sampler: Sampler, u: f32, v: f32) -> [f32; 4] {
        let u = if u.is_finite() { u } else { 0.0 };
        let v = if v.is_finite() { v } else { 0.0 };
        let (w, h) = (self.width as f32, self.height as f32);
        match sampler.filter {
            Filter::Nearest => {
                let i = sampler.wrap_u.index((u * w).floor() as i64, self.width);
                let j = sampler.wrap_v.index((v * h).floor() as i64, self.height);
                self.texel(i, j)
            }
            Filter::Linear => {
                let x = u.mul_add(w, -0.5);
                let y = v.mul_add(h, -0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let i0 = sampler.wrap_u.index(x0, self.width);
                let i1 = sampler.wrap_u.index(x0.saturating_add(1), self.width);
                let j0 = sampler.wrap_v.index(y0, self.height);
                let j1 = sampler.wrap_v.index(y0.saturating_add(1), self.height);
                let (a, b) = (self.texel(i0, j0), self.texel(i1, j0));
                let (c, d) = (self.texel(i0, j1), self.texel(i1, j1));
                std::array::from_fn(|k| {
                    let top = (b[k] - a[k]).mul_add(fx, a[k]);
                    let bottom = (d[k] - c[k]).mul_add(fx, c[k]);
                    (bottom - top).mul_add(fy, top)
                })
            }
        }
    }
}

/// The texels of a `width × height` image given as RGBA bytes row by row
/// from the top, laid out in tiles ([`TILE`]): the number of tiles across
/// and the tiles.
fn tiled(width: usize, height: usize, bytes: &[u8]) -> (usize, Vec<Tile>) {
    let across = width.div_ceil(TILE);
    let mut tiles = vec![Tile([0; TILE * TILE]); across * height.div_ceil(TILE)];
    let row_bytes = width * BYTES_PER_TEXEL;
    for (j, row) in bytes.chunks_exact(row_bytes).enumerate() {
        let (tile_row, r) = (j / TILE, j % TILE);
        let tiles = &mut tiles[tile_row * across..(tile_row + 1) * across];
        // A whole tile's row of a row at a time (4 texels, 16 bytes), then
        // the part tile at the right edge.
        let whole = row.chunks_exact(TILE * BYTES_PER_TEXEL);
        let rest = whole.remainder();
        for (tile, quad) in tiles.iter_mut().zip(whole) {
            let out = &mut tile.0[r * TILE..(r + 1) * TILE];
            for (t, b) in out.iter_mut().zip(quad.chunks_exact(BYTES_PER_TEXEL)) {
                *t = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
        if !rest.is_empty() {
            let tile = &mut tiles[across - 1];
            for (t, b) in tile.0[r * TILE..]
                .iter_mut()
                .zip(rest.chunks_exact(BYTES_PER_TEXEL))
            {
                *t = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
    }
    (across, tiles)
}

impl TextureRef {
    /// What a scene's content hash takes of it, as words of three floats
    /// (the first word starts with `slot`, the parameter it textures).
    pub fn hash_words(&self, slot: f32) -> [glam::Vec3; 4] {
        let m = self.transform.m;
        let s = self.sampler;
        let code = |w: Wrap| w as u32 as f32;
        [
            glam::Vec3::new(slot, self.texture as f32, self.tex_coord as f32),
            glam::Vec3::new(code(s.wrap_u), code(s.wrap_v), s.filter as u32 as f32),
            glam::Vec3::new(m[0], m[1], m[2]),
            glam::Vec3::new(m[3], m[4], m[5]),
        ]
    }
}

/// A texture as a material uses it: which texture, which set of texture
/// coordinates (`TEXCOORD_0` or `_1`), how it is sampled and transformed,
/// and a factor (a normal texture's `scale`; 1 elsewhere).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into the scene's textures.
    pub texture: u32,
    /// The set of texture coordinates: 0 or 1.
    pub tex_coord: u32,
    /// How it is sampled.
    pub sampler: Sampler,
    /// `KHR_texture_transform` (identity where absent).
    pub transform: UvTransform,
    /// A normal texture's `scale` (1 for the others).
    pub scale: f32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Row-major RGBA bytes of a `w × h` image, every texel distinct (as
    /// a 32-bit word).
    fn row_major(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .flat_map(|k| {
                let k = k as u32;
                (k.wrapping_mul(0x9e37_79b9) ^ (k << 8) ^ 0x5a).to_le_bytes()
            })
            .collect()
    }

    /// The tiled texels give, for every `(i, j)` of images of odd and
    /// even, whole-tile and part-tile sizes, the texel the row-major image
    /// has there (raw, and decoded by [`Texture::texel`]); the rows read
    /// back are the image's bytes; and the addresses are distinct and
    /// inside the storage.
    #[test]
    fn tiles_hold_the_row_major_texels() {
        let sizes = [
            (1, 1),
            (5, 3),
            (3, 5),
            (1, 13),
            (13, 1),
            (4, 4),
            (8, 4),
            (7, 9),
            (17, 17),
            (33, 2),
        ];
        for (w, h) in sizes {
            let bytes = row_major(w, h);
            let t = Texture::from_rgba8_bytes(w, h, &bytes, ColourSpace::Srgb).unwrap();
            let tiles = (w.div_ceil(TILE), h.div_ceil(TILE));
            assert_eq!(t.tiles_across(), tiles.0);
            assert_eq!(t.bytes(), tiles.0 * tiles.1 * TILE * TILE * BYTES_PER_TEXEL);
            let texels = t.tiled_texels();
            let mut seen = vec![false; texels.len()];
            for j in 0..h {
                for i in 0..w {
                    let at = texel_address(i as i32, j as i32, t.tiles_across() as i32) as usize;
                    assert!(
                        at < texels.len() && !seen[at],
                        "{w} × {h}: ({i}, {j}) at {at}"
                    );
                    seen[at] = true;
                    let b = &bytes[(j * w + i) * 4..][..4];
                    assert_eq!(
                        texels[at].to_le_bytes(),
                        [b[0], b[1], b[2], b[3]],
                        "{w} × {h}: texel ({i}, {j})"
                    );
                    let tb = t.table();
                    let want = [tb[b[0] as usize], tb[b[1] as usize], tb[b[2] as usize]];
                    let got = t.texel(i, j);
                    assert_eq!(got[..3], want, "{w} × {h}: texel ({i}, {j}) decoded");
                    assert_eq!(got[3], b[3] as f32 / 255.0);
                }
            }
            let mut back = Vec::new();
            let mut rows = 0;
            t.for_each_row(|row| {
                assert_eq!(row.len(), w * BYTES_PER_TEXEL);
                back.extend_from_slice(row);
                rows += 1;
            });
            assert_eq!((rows, &back), (h, &bytes), "{w} × {h}: the rows read back");
            // `from_rgba8` (texels) lays out as `from_rgba8_bytes` does.
            let texels: Vec<[u8; 4]> = bytes
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
            assert!(Texture::from_rgba8(w, h, texels, ColourSpace::Srgb).unwrap() == t);
        }
    }

    /// Sizes and texel counts that do not agree are refused, by name.
    #[test]
    fn a_wrong_number_of_bytes_is_refused() {
        let e = Texture::from_rgba8_bytes(3, 2, &[0; 20], ColourSpace::Linear).unwrap_err();
        assert_eq!(e.0, "5 texels for an image of 3 × 2");
        assert!(Texture::from_rgba8_bytes(0, 2, &[], ColourSpace::Linear).is_err());
    }
}
