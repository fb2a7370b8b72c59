//! Pictures of a convergence study ([`crate::run::converge`]): error
//! against samples per pixel and against seconds on log–log axes (PNG and
//! SVG, drawn with `plotters`), and the strip of crops at each sample
//! count. Text is drawn with DejaVu Sans Mono, built in
//! (`assets/fonts/`), so no system font is needed.

use crate::error::Result;
use crate::fs::{FileError, write_atomic};
use crate::run::converge::Curve;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters_backend::{
    BackendColor, BackendCoord, BackendTextStyle, DrawingErrorKind, text_anchor,
};
use std::io::Write;
use std::path::Path;

const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");
const FAMILY: &str = "sans-serif";

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
            .unwrap_or_else(|_| panic!("the built-in font loads"));
    });
}

/// A bitmap that draws its text itself. plotters' own text drawing
/// (its `ab_glyph` font code) places each glyph's inked box at the pen
/// position, dropping the glyph's left side bearing, so in a monospace font
/// a narrow glyph sat at the left of its cell: tick labels read `0. 01`.
/// This draws each glyph at its true origin; everything else is the
/// bitmap's own, and text is laid out and anchored as plotters does.
struct Bitmap<'a>(BitMapBackend<'a>);

type DrawResult<'a> =
    std::result::Result<(), DrawingErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>>;

impl<'a> DrawingBackend for Bitmap<'a> {
    type ErrorType = <BitMapBackend<'a> as DrawingBackend>::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.0.get_size()
    }
    fn ensure_prepared(&mut self) -> DrawResult<'a> {
        self.0.ensure_prepared()
    }
    fn present(&mut self) -> DrawResult<'a> {
        self.0.present()
    }
    fn draw_pixel(&mut self, point: BackendCoord, color: BackendColor) -> DrawResult<'a> {
        self.0.draw_pixel(point, color)
    }
    fn draw_line<S: plotters_backend::BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> DrawResult<'a> {
        self.0.draw_line(from, to, style)
    }
    fn draw_rect<S: plotters_backend::BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> DrawResult<'a> {
        self.0.draw_rect(upper_left, bottom_right, style, fill)
    }
    fn draw_path<S: plotters_backend::BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> DrawResult<'a> {
        self.0.draw_path(path, style)
    }
    fn draw_circle<S: plotters_backend::BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> DrawResult<'a> {
        self.0.draw_circle(center, radius, style, fill)
    }
    fn fill_polygon<S: plotters_backend::BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> DrawResult<'a> {
        self.0.fill_polygon(vert, style)
    }
    fn blit_bitmap(&mut self, pos: BackendCoord, size: (u32, u32), src: &[u8]) -> DrawResult<'a> {
        self.0.blit_bitmap(pos, size, src)
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> DrawResult<'a> {
        use ab_glyph::{Font, ScaleFont};
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        // plotters' layout (the box is the advances' sum by the size) and
        // anchoring, so labels sit where they always did.
        let ((min_x, min_y), (max_x, max_y)) = style
            .layout_box(text)
            .map_err(|e| DrawingErrorKind::FontError(Box::new(e)))?;
        let (width, height) = (max_x - min_x, max_y - min_y);
        let dx = match style.anchor().h_pos {
            text_anchor::HPos::Left => 0,
            text_anchor::HPos::Right => -width,
            text_anchor::HPos::Center => -width / 2,
        };
        let dy = match style.anchor().v_pos {
            text_anchor::VPos::Top => 0,
            text_anchor::VPos::Center => -height / 2,
            text_anchor::VPos::Bottom => -height,
        };
        let font = ab_glyph::FontRef::try_from_slice(FONT).expect("the built-in font loads");
        let size = style.size() as f32;
        let font = font.as_scaled(size);
        let trans = style.transform();
        let (w, h) = self.get_size();
        let mut pen = 0f32;
        let mut prev = None;
        let mut ink = Vec::new();
        for c in text.chars() {
            let id = font.glyph_id(c);
            if let Some(p) = prev {
                pen += font.kern(p, id);
            }
            prev = Some(id);
            // Positioned at its origin: its box then starts at the pen plus
            // its left side bearing.
            let glyph = id.with_scale_and_position(size, ab_glyph::point(pen, 0.0));
            if let Some(outline) = font.outline_glyph(glyph) {
                let b = outline.px_bounds();
                // plotters' vertical placement: the baseline at size / 2.
                let (x0, y0) = (b.min.x as i32, (size / 2.0 + b.min.y) as i32);
                outline.draw(|x, y, c| ink.push((x0 + x as i32, y0 + y as i32, c)));
            }
            pen += font.h_advance(id);
        }
        for (x, y, coverage) in ink {
            let (x, y) = trans.transform(x + dx - min_x, y + dy - min_y);
            let (x, y) = (pos.0 + x, pos.1 + y);
            if x >= 0 && x < w as i32 && y >= 0 && y < h as i32 {
                let c = BackendColor {
                    alpha: color.alpha * f64::from(coverage),
                    rgb: color.rgb,
                };
                self.0.draw_pixel((x, y), c)?;
            }
        }
        Ok(())
    }
}

/// The horizontal axis of an error plot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XAxis {
    /// Samples per pixel.
    Spp,
    /// Render seconds.
    Seconds,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0x8c, 0x56, 0x4b),
];

/// A tick label: up to 3 significant digits, in plain notation between
/// 0.001 and 100,000, else as `1e-5`.
pub fn short(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !(1e-3..1e5).contains(&a) {
        return format!("{v:.0e}");
    }
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    let t = format!("{v:.decimals$}");
    if t.contains('.') {
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        t
    }
}

/// Plot size in pixels (PNG) or user units (SVG).
pub const PLOT_SIZE: (u32, u32) = (1100, 440);

fn io<E: std::fmt::Debug>(e: E) -> std::io::Error {
    std::io::Error::other(format!("{e:?}"))
}

/// Draw the two panels (relMSE with a 1/N line, mean ꟻLIP with a 1/√N
/// line) of `curves` against `x` on `root`.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    curves: &[Curve],
    x: XAxis,
    title: &str,
) -> std::io::Result<()> {
    root.fill(&WHITE).map_err(io)?;
    let root = root.titled(title, (FAMILY, 20).into_font()).map_err(io)?;
    let panels = root.split_evenly((1, 2));
    type Pick = fn(&crate::run::converge::Point) -> f64;
    let metrics: [(&str, Pick, f64, &str); 2] = [
        ("relMSE", |p| p.relmse, 1.0, "1/N"),
        ("mean FLIP", |p| p.mean_flip, 0.5, "1/sqrt(N)"),
    ];
    for (area, (name, pick, slope, slope_label)) in panels.iter().zip(metrics) {
        let xy = |c: &Curve| -> Vec<(f64, f64)> {
            c.points
                .iter()
                .map(|p| {
                    let xv = match x {
                        XAxis::Spp => p.spp as f64,
                        XAxis::Seconds => p.seconds,
                    };
                    (xv, pick(p))
                })
                .filter(|(a, b)| *a > 0.0 && *b > 0.0 && a.is_finite() && b.is_finite())
                .collect()
        };
        let all: Vec<(f64, f64)> = curves.iter().flat_map(xy).collect();
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(a, b) in &all {
            (x0, x1, y0, y1) = (x0.min(a), x1.max(a), y0.min(b), y1.max(b));
        }
        if all.is_empty() {
            (x0, x1, y0, y1) = (1.0, 2.0, 0.1, 1.0);
        }
        // Room around the data (log axes need a range).
        let (x0, x1) = (x0 / 1.3, x1 * 1.3);
        let (y0, y1) = (y0 / 1.5, y1 * 1.5);
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(io)?;
        chart
            .configure_mesh()
            .x_desc(match x {
                XAxis::Spp => "samples per pixel",
                XAxis::Seconds => "render seconds",
            })
            .y_desc(name)
            .y_labels(6)
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .x_label_formatter(&|v| short(*v))
            .y_label_formatter(&|v| short(*v))
            .draw()
            .map_err(io)?;
        // The reference slope through the first curve's first point.
        if let Some(&(ax, ay)) = curves.first().and_then(|c| xy(c).first().copied()).as_ref() {
            let line: Vec<(f64, f64)> = (0..=40)
                .map(|i| {
                    let t = ax * (x1 / ax).powf(i as f64 / 40.0);
                    (t, ay * (ax / t).powf(slope))
                })
                .filter(|&(_, v)| v >= y0)
                .collect();
            let grey = RGBColor(0x80, 0x80, 0x80);
            chart
                .draw_series(DashedLineSeries::new(line, 6, 4, grey.stroke_width(2)))
                .map_err(io)?
                .label(slope_label)
                .legend(move |(a, b)| PathElement::new(vec![(a, b), (a + 20, b)], grey));
        }
        for (i, c) in curves.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let pts = xy(c);
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                .map_err(io)?
                .label(c.label())
                .legend(move |(a, b)| PathElement::new(vec![(a, b), (a + 20, b)], color));
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(io)?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .label_font((FAMILY, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(io)?;
    }
    root.present().map_err(io)?;
    Ok(())
}

/// The plot of `curves` against `x`, as SVG text.
pub fn plot_svg(curves: &[Curve], x: XAxis, title: &str) -> std::io::Result<String> {
    register_font();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, PLOT_SIZE).into_drawing_area();
        draw(&root, curves, x, title)?;
    }
    Ok(svg)
}

/// The plot of `curves` against `x`, as a PNG file's bytes.
pub fn plot_png(curves: &[Curve], x: XAxis, title: &str) -> std::io::Result<Vec<u8>> {
    register_font();
    let (w, h) = PLOT_SIZE;
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    {
        let root = Bitmap(BitMapBackend::with_buffer(&mut rgb, (w, h))).into_drawing_area();
        draw(&root, curves, x, title)?;
    }
    png(&rgb, w, h)
}

/// Encode 8-bit RGB as PNG.
pub fn png(rgb: &[u8], width: u32, height: u32) -> std::io::Result<Vec<u8>> {
    let mut out = std::io::Cursor::new(Vec::new());
    image::write_buffer_with_format(
        &mut out,
        rgb,
        width,
        height,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(std::io::Error::other)?;
    Ok(out.into_inner())
}

/// The strip of crops, as a PNG file's bytes: one row per curve, one
/// column per sample count (the curve's points in order), the reference
/// crop last; each crop magnified `zoom` times (nearest neighbour),
/// labelled above (sample count) and on the left (setting).
pub fn crop_strip_png(
    curves: &[Curve],
    reference: &[[f32; 3]],
    crop: (u32, u32),
    zoom: u32,
) -> std::io::Result<Vec<u8>> {
    register_font();
    let (cw, ch) = (crop.0 * zoom, crop.1 * zoom);
    let columns = curves.iter().map(|c| c.crops.len()).max().unwrap_or(0) as u32 + 1;
    let (left, top, gap) = (190u32, 26u32, 4u32);
    let width = left + columns * (cw + gap);
    let height = top + curves.len().max(1) as u32 * (ch + gap);
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    let mut blit = |col: u32, row: u32, pixels: &[[f32; 3]]| {
        let bytes = crate::output::srgb8(pixels);
        let (ox, oy) = (left + col * (cw + gap), top + row * (ch + gap));
        for y in 0..ch {
            for x in 0..cw {
                let s = (((y / zoom) * crop.0 + x / zoom) * 3) as usize;
                let d = (((oy + y) * width + ox + x) * 3) as usize;
                rgb[d..d + 3].copy_from_slice(&bytes[s..s + 3]);
            }
        }
    };
    for (row, c) in curves.iter().enumerate() {
        for (col, crop) in c.crops.iter().enumerate() {
            blit(col as u32, row as u32, crop);
        }
        blit(columns - 1, row as u32, reference);
    }
    {
        let root =
            Bitmap(BitMapBackend::with_buffer(&mut rgb, (width, height))).into_drawing_area();
        let style = TextStyle::from((FAMILY, 14).into_font()).color(&BLACK);
        let spps: Vec<String> = curves
            .iter()
            .max_by_key(|c| c.points.len())
            .map(|c| c.points.iter().map(|p| format!("{} spp", p.spp)).collect())
            .unwrap_or_default();
        for (col, label) in spps
            .iter()
            .chain(["reference".to_string()].iter())
            .enumerate()
        {
            let x = (left + col as u32 * (cw + gap)) as i32;
            let label = if col as u32 == columns - 1 {
                "reference"
            } else {
                label
            };
            root.draw(&Text::new(label.to_string(), (x + 2, 5), &style))
                .map_err(io)?;
        }
        for (row, c) in curves.iter().enumerate() {
            let y = (top + row as u32 * (ch + gap) + ch / 2) as i32 - 8;
            root.draw(&Text::new(c.label(), (6, y), &style))
                .map_err(io)?;
        }
        root.present().map_err(io)?;
    }
    png(&rgb, width, height)
}

/// Write `bytes` to `path` atomically.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes)).map_err(|e: FileError| e.into())
}

#[cfg(test)]
mod tests {
    use plotters::prelude::*;

    /// Where the ink of `text` begins and ends, in columns, drawn at x = 0
    /// left-anchored in a plot's label font.
    fn ink_columns(text: &str) -> (usize, usize) {
        super::register_font();
        let (w, h) = (200u32, 40u32);
        let mut rgb = vec![255u8; (w * h * 3) as usize];
        {
            let root =
                super::Bitmap(BitMapBackend::with_buffer(&mut rgb, (w, h))).into_drawing_area();
            let style = TextStyle::from((super::FAMILY, 20).into_font()).color(&BLACK);
            root.draw(&Text::new(text.to_string(), (0, 10), &style))
                .unwrap();
            root.present().unwrap();
        }
        let inked = |x: u32| (0..h).any(|y| rgb[((y * w + x) * 3) as usize] < 128);
        let columns: Vec<u32> = (0..w).filter(|&x| inked(x)).collect();
        (columns[0] as usize, *columns.last().unwrap() as usize)
    }

    #[test]
    fn glyphs_keep_their_side_bearings() {
        // A monospace font: every glyph has the same advance, and a full
        // stop sits in the middle of its cell, not at its left edge (where
        // plotters' own text drawing put it: "0. 01").
        let (dot_start, _) = ink_columns(".");
        let (zero_start, zero_end) = ink_columns("0");
        assert!(dot_start >= zero_start + 3, "{dot_start} {zero_start}");
        // In "0.01" the 0s keep their cells: each ends one advance after
        // the one before.
        let cell = ink_columns("00").1 - zero_end;
        assert!(cell >= 8, "{cell}");
        // (Within a pixel: the advance is not a whole number of them.)
        let third = ink_columns("0.0").1 as i64;
        assert!((third - (zero_end + 2 * cell) as i64).abs() <= 1, "{third}");
        assert_eq!(ink_columns("0.01").0, zero_start);
    }

    #[test]
    fn tick_labels() {
        use super::short;
        assert_eq!(short(1.0), "1");
        assert_eq!(short(10.0), "10");
        assert_eq!(short(1024.0), "1024");
        assert_eq!(short(0.25), "0.25");
        assert_eq!(short(0.1234), "0.123");
        assert_eq!(short(0.001), "0.001");
        assert_eq!(short(1e-5), "1e-5");
    }
}
