//! Plots as lists of shapes, drawn once as SVG and rasterised to PNG, so both show
//! the same drawing, text included: the PNG's text is rasterised with ab_glyph from
//! a bundled font (Noto Mono, SIL Open Font License, `crates/pm-study/assets/OFL.txt`), so no
//! system font is needed.

use anyhow::Result;
use std::fmt::Write as _;
use std::path::Path;

/// An sRGB colour.
pub type Colour = (u8, u8, u8);

/// A drawing primitive (points in SVG pixel coordinates).
pub enum Shape {
    /// From, to, colour, dashed.
    Line((f64, f64), (f64, f64), Colour, bool),
    /// Centre, colour.
    Dot((f64, f64), Colour),
    /// Anchor point, text, SVG text-anchor, rotated by -90 degrees, font size.
    Text((f64, f64), String, &'static str, bool, u8),
}

/// Colours for series, distinguishable on white.
pub const PALETTE: [Colour; 14] = [
    (0, 0, 0),
    (230, 25, 75),
    (60, 180, 75),
    (0, 130, 200),
    (245, 130, 48),
    (145, 30, 180),
    (70, 150, 150),
    (200, 160, 0),
    (128, 128, 128),
    (170, 110, 40),
    (250, 100, 200),
    (0, 0, 128),
    (0, 190, 255),
    (110, 70, 0),
];

/// Write `shapes` on a white `w` x `h` canvas to `svg` and `png`.
pub fn draw(shapes: &[Shape], w: f64, h: f64, svg_path: &Path, png_path: &Path) -> Result<()> {
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    let mut canvas = Canvas::new(w as u32, h as u32);
    for shape in shapes {
        match shape {
            Shape::Line((x0, y0), (x1, y1), (r, g, b), dashed) => {
                let dash = if *dashed { " stroke-dasharray=\"4 3\"" } else { "" };
                writeln!(
                    svg,
                    "<line x1=\"{x0:.1}\" y1=\"{y0:.1}\" x2=\"{x1:.1}\" y2=\"{y1:.1}\" stroke=\"rgb({r},{g},{b})\"{dash}/>"
                )?;
                let n = ((x1 - x0).abs().max((y1 - y0).abs()) as i64).max(1);
                for k in 0..=n {
                    let f = k as f64 / n as f64;
                    if !*dashed || (k / 4) % 2 == 0 {
                        canvas.put((x0 + f * (x1 - x0)) as i64, (y0 + f * (y1 - y0)) as i64, 1.0, (*r, *g, *b));
                    }
                }
            }
            Shape::Dot((cx, cy), (r, g, b)) => {
                writeln!(svg, "<circle cx=\"{cx:.1}\" cy=\"{cy:.1}\" r=\"4\" fill=\"rgb({r},{g},{b})\"/>")?;
                for dy in -3i64..=3 {
                    for dx in -3i64..=3 {
                        if dx * dx + dy * dy <= 10 {
                            canvas.put(*cx as i64 + dx, *cy as i64 + dy, 1.0, (*r, *g, *b));
                        }
                    }
                }
            }
            Shape::Text((tx, ty), text, anchor, rotated, size) => {
                let rot = if *rotated { format!(" transform=\"rotate(-90 {tx} {ty})\"") } else { String::new() };
                writeln!(
                    svg,
                    "<text x=\"{tx:.1}\" y=\"{ty:.1}\" font-size=\"{size}\" text-anchor=\"{anchor}\"{rot}>{}</text>",
                    escape(text)
                )?;
                canvas.text((*tx, *ty), text, anchor, *rotated, *size as f32);
            }
        }
    }
    svg.push_str("</svg>\n");
    std::fs::write(svg_path, svg)?;
    pm_image::write_png(png_path, canvas.width, canvas.height, &canvas.px, 0.0)
}

/// A white raster of linear radiance that shapes and text are drawn into.
pub struct Canvas {
    /// Width \[pixels\].
    pub width: u32,
    /// Height \[pixels\].
    pub height: u32,
    /// Row-major pixels.
    pub px: Vec<glam::Vec3>,
}

impl Canvas {
    /// A white canvas.
    pub fn new(width: u32, height: u32) -> Canvas {
        Canvas { width, height, px: vec![glam::Vec3::ONE; (width * height) as usize] }
    }

    /// Cover pixel (x, y), when it is on the canvas, with the sRGB `colour` at
    /// opacity `a`.
    pub fn put(&mut self, x: i64, y: i64, a: f32, (r, g, b): Colour) {
        if x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height {
            let c: glam::Vec3 =
                (glam::Vec3::new(r as f32, g as f32, b as f32) / 255.0).to_array().map(pm_color::srgb_decode).into();
            let p = &mut self.px[(y as u32 * self.width + x as u32) as usize];
            *p = *p * (1.0 - a) + c * a;
        }
    }

    /// Black text placed as SVG places it (see [`text_pixels`]).
    pub fn text(&mut self, at: (f64, f64), text: &str, anchor: &str, rotated: bool, size: f32) {
        text_pixels(at, text, anchor, rotated, size, &mut |x, y, a| self.put(x, y, a, (0, 0, 0)));
    }
}

/// The bundled font.
const FONT: &[u8] = include_bytes!("../assets/NotoMono-Regular.ttf");

/// Text as SVG character data.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// Rasterise `text` of `size` px (the SVG font-size) with its baseline at `at`,
/// anchored like SVG's text-anchor ("start", "middle", "end"), and with `rotated`
/// turned by -90 degrees about `at` (SVG's rotate(-90 x y)): calls `cover` with each
/// pixel and its coverage in [0, 1].
pub fn text_pixels(
    (tx, ty): (f64, f64),
    text: &str,
    anchor: &str,
    rotated: bool,
    size: f32,
    cover: &mut dyn FnMut(i64, i64, f32),
) {
    use ab_glyph::{Font, FontRef, ScaleFont, point};
    let font = FontRef::try_from_slice(FONT).expect("the bundled font parses");
    // SVG's font-size is the em in pixels; ab_glyph scales by ascent - descent.
    let em = font.units_per_em().unwrap_or(1000.0);
    let scale = ab_glyph::PxScale::from(size * font.height_unscaled() / em);
    let scaled = font.as_scaled(scale);
    let ids: Vec<ab_glyph::GlyphId> = text.chars().map(|c| font.glyph_id(c)).collect();
    let mut carets = Vec::with_capacity(ids.len());
    let mut caret = 0.0f32;
    for (k, &id) in ids.iter().enumerate() {
        if k > 0 {
            caret += scaled.kern(ids[k - 1], id);
        }
        carets.push(caret);
        caret += scaled.h_advance(id);
    }
    let start = match anchor {
        "middle" => -caret / 2.0,
        "end" => -caret,
        _ => 0.0,
    };
    for (&id, &x) in ids.iter().zip(&carets) {
        let Some(outline) = font.outline_glyph(id.with_scale_and_position(scale, point(start + x, 0.0))) else {
            continue;
        };
        let bb = outline.px_bounds();
        outline.draw(|gx, gy, a| {
            // (dx, dy): offset from the anchor along and across the text.
            let (dx, dy) = (bb.min.x as f64 + gx as f64, bb.min.y as f64 + gy as f64);
            let (x, y) = if rotated { (tx + dy, ty - dx) } else { (tx + dx, ty + dy) };
            cover(x.round() as i64, y.round() as i64, a.clamp(0.0, 1.0));
        });
    }
}

/// A line chart of `series` (name, points) in a `w` x `h` canvas: axes from 0 (or
/// the data's range on a log x axis), five ticks per axis, a legend, a title.
pub fn line_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    log_x: bool,
    series: &[(String, Vec<(f64, f64)>)],
    w: f64,
    h: f64,
) -> Vec<Shape> {
    let m = 70.0;
    let fx = |x: f64| if log_x { x.max(1e-12).log10() } else { x };
    let pts = series.iter().flat_map(|s| s.1.iter());
    let (mut x0, mut x1, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    for &(x, y) in pts {
        x0 = x0.min(fx(x));
        x1 = x1.max(fx(x));
        y1 = y1.max(y);
    }
    if !x0.is_finite() {
        (x0, x1) = (0.0, 1.0);
    }
    if !log_x {
        x0 = x0.min(0.0);
    }
    let (x1, y1) = (if x1 > x0 { x1 } else { x0 + 1.0 }, if y1 > 0.0 { y1 * 1.1 } else { 1.0 });
    let px = |x: f64| m + (fx(x) - x0) / (x1 - x0) * (w - 2.0 * m - 150.0);
    let py = |y: f64| h - m - y / y1 * (h - 2.0 * m);
    let black = (0, 0, 0);
    let mut s = vec![
        Shape::Line((m, h - m), (w - m - 150.0, h - m), black, false),
        Shape::Line((m, m), (m, h - m), black, false),
        Shape::Text((w / 2.0, 30.0), title.to_string(), "middle", false, 14),
        Shape::Text(((w - 150.0) / 2.0, h - 25.0), x_label.to_string(), "middle", false, 12),
        Shape::Text((18.0, h / 2.0), y_label.to_string(), "middle", true, 12),
    ];
    for k in 0..=4 {
        let yv = y1 * k as f64 / 4.0;
        s.push(Shape::Line((m - 5.0, py(yv)), (m, py(yv)), black, false));
        s.push(Shape::Text((m - 8.0, py(yv) + 4.0), format!("{yv:.3}"), "end", false, 11));
        let xf = x0 + (x1 - x0) * k as f64 / 4.0;
        let xv = if log_x { 10f64.powf(xf) } else { xf };
        s.push(Shape::Line((px(xv), h - m), (px(xv), h - m + 5.0), black, false));
        s.push(Shape::Text((px(xv), h - m + 18.0), format!("{xv:.4}"), "middle", false, 11));
    }
    for (i, (name, points)) in series.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        for p in points.windows(2) {
            s.push(Shape::Line((px(p[0].0), py(p[0].1)), (px(p[1].0), py(p[1].1)), c, false));
        }
        for p in points {
            s.push(Shape::Dot((px(p.0), py(p.1)), c));
        }
        let ly = m + 18.0 * i as f64;
        s.push(Shape::Dot((w - m - 130.0, ly), c));
        s.push(Shape::Text((w - m - 120.0, ly + 4.0), name.clone(), "start", false, 12));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Covered pixels (coverage above a half) of `text` at (100, 100), size 12.
    fn covered(text: &str, anchor: &str, rotated: bool) -> Vec<(i64, i64)> {
        let mut v = Vec::new();
        text_pixels((100.0, 100.0), text, anchor, rotated, 12.0, &mut |x, y, a| {
            if a > 0.5 {
                v.push((x, y))
            }
        });
        v
    }

    /// Text lands where SVG would put it: after, around or before the anchor, on
    /// the baseline (capitals above it), turned by -90 degrees when rotated.
    #[test]
    fn text_is_placed_like_svg() {
        let start = covered("HELLO", "start", false);
        assert!(start.len() > 40, "{} pixels", start.len());
        // Noto Mono advances 0.6 em: five capitals span 36 px at 12 px.
        assert!(start.iter().all(|&(x, y)| (99..=137).contains(&x) && (90..=101).contains(&y)), "{start:?}");
        let mean_x = |v: &[(i64, i64)]| v.iter().map(|p| p.0 as f64).sum::<f64>() / v.len() as f64;
        let middle = covered("HELLO", "middle", false);
        assert!((mean_x(&middle) - 100.0).abs() < 3.0, "{}", mean_x(&middle));
        let end = covered("HELLO", "end", false);
        assert!(end.iter().all(|&(x, _)| x <= 101), "{end:?}");
        let turned = covered("HELLO", "start", true);
        assert!(turned.iter().all(|&(x, y)| (90..=101).contains(&x) && (63..=101).contains(&y)), "{turned:?}");
    }

    /// The PNG carries the text the SVG does.
    #[test]
    fn png_has_the_labels() {
        let dir = tempfile::tempdir().unwrap();
        let (svg, png) = (dir.path().join("t.svg"), dir.path().join("t.png"));
        draw(&[Shape::Text((20.0, 30.0), "error [%]".into(), "start", false, 14)], 120.0, 50.0, &svg, &png).unwrap();
        let (w, _, rgb) = pm_image::read_png_rgb8(&png).unwrap();
        let dark = |x0: u32, x1: u32| {
            (15..35)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .filter(|&(x, y)| rgb[((y * w + x) * 3) as usize] < 100)
                .count()
        };
        assert!(dark(20, 100) > 30, "no text where the label is");
        assert_eq!(dark(100, 120), 0, "ink past the label's end");
        assert!(std::fs::read_to_string(&svg).unwrap().contains(">error [%]</text>"));
    }
}
