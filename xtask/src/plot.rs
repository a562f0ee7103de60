//! Plots as lists of shapes, drawn once as SVG (with text) and rasterised to PNG
//! (without text: there is no font rasteriser here), so both show the same drawing.

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
pub const PALETTE: [Colour; 12] = [
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
];

/// Write `shapes` on a white `w` x `h` canvas to `svg` and `png`.
pub fn draw(shapes: &[Shape], w: f64, h: f64, svg_path: &Path, png_path: &Path) -> Result<()> {
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    let (wi, hi) = (w as u32, h as u32);
    let mut px = vec![glam::Vec3::ONE; (wi * hi) as usize];
    let mut put = |xx: i64, yy: i64, (r, g, b): Colour| {
        if xx >= 0 && yy >= 0 && (xx as u32) < wi && (yy as u32) < hi {
            let c = glam::Vec3::new(r as f32, g as f32, b as f32) / 255.0;
            px[(yy as u32 * wi + xx as u32) as usize] = c.to_array().map(pm_color::srgb_decode).into();
        }
    };
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
                        put((x0 + f * (x1 - x0)) as i64, (y0 + f * (y1 - y0)) as i64, (*r, *g, *b));
                    }
                }
            }
            Shape::Dot((cx, cy), (r, g, b)) => {
                writeln!(svg, "<circle cx=\"{cx:.1}\" cy=\"{cy:.1}\" r=\"4\" fill=\"rgb({r},{g},{b})\"/>")?;
                for dy in -3i64..=3 {
                    for dx in -3i64..=3 {
                        if dx * dx + dy * dy <= 10 {
                            put(*cx as i64 + dx, *cy as i64 + dy, (*r, *g, *b));
                        }
                    }
                }
            }
            Shape::Text((tx, ty), text, anchor, rotated, size) => {
                let rot = if *rotated { format!(" transform=\"rotate(-90 {tx} {ty})\"") } else { String::new() };
                writeln!(
                    svg,
                    "<text x=\"{tx:.1}\" y=\"{ty:.1}\" font-size=\"{size}\" text-anchor=\"{anchor}\"{rot}>{text}</text>"
                )?;
            }
        }
    }
    svg.push_str("</svg>\n");
    std::fs::write(svg_path, svg)?;
    pm_image::write_png(png_path, wi, hi, &px, 0.0)
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
