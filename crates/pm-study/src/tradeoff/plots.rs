//! The study's figures: error against time (every method, and the photon-map
//! settings zoomed), bias against noise, per-layer error, and the defaults' error
//! map.

use super::results::{Row, shown_layers};
use super::sweep::Axis;
use crate::plot::{self, Shape};
use anyhow::Result;
use pm_methods::Method;
use pm_pipeline::quality::pareto;
use std::path::Path;

/// Each axis's colour, in legend order.
fn colour(axis: Axis) -> plot::Colour {
    plot::PALETTE[axis as usize % plot::PALETTE.len()]
}

/// The axes in legend order.
fn axes() -> &'static [Axis] {
    <Axis as clap::ValueEnum>::value_variants()
}

/// Where a panel goes and how it is drawn.
struct Panel<'a> {
    /// Its corner and size: x0, y0, w, h (SVG pixels).
    at: (f64, f64, f64, f64),
    title: &'a str,
    y_label: &'a str,
    /// Each point labelled with its setting.
    labels: bool,
    /// The value axis spans the shown rows' range instead of starting at 0.
    zoom: bool,
}

/// Panel `p`: `value` of each row that `show` admits against its total time (log
/// axis), a line through each axis's points (with the defaults' point), and
/// `front` dashed.
fn panel(
    shapes: &mut Vec<Shape>,
    p: &Panel,
    rows: &[Row],
    value: &dyn Fn(&Row) -> f64,
    show: &dyn Fn(&Row) -> bool,
    front: &[usize],
) {
    let Panel { at: (x0, y0, w, h), title, y_label, labels, zoom } = *p;
    let m = 55.0;
    let vis: Vec<usize> = (0..rows.len()).filter(|&i| show(&rows[i])).collect();
    let t: Vec<f64> = rows.iter().map(|r| r.total().max(1e-3)).collect();
    let tmin = vis.iter().map(|&i| t[i]).fold(f64::INFINITY, f64::min);
    let tmax = vis.iter().map(|&i| t[i]).fold(0.0, f64::max);
    let (lt0, lt1) = (tmin.log10().floor(), tmax.log10().ceil().max(tmin.log10().floor() + 1.0));
    let vhi = vis.iter().map(|&i| value(&rows[i])).fold(0.0, f64::max).max(1e-9);
    let vlo = vis.iter().map(|&i| value(&rows[i])).fold(f64::INFINITY, f64::min);
    let (vmin, vmax) = if zoom { (0.95 * vlo, 1.05 * vhi) } else { (0.0, 1.1 * vhi) };
    let x = |tv: f64| x0 + m + (tv.log10() - lt0) / (lt1 - lt0) * (w - 1.5 * m);
    let y = |v: f64| y0 + h - m + 10.0 - (v - vmin) / (vmax - vmin).max(1e-12) * (h - 1.6 * m);
    let black = (0u8, 0u8, 0u8);
    let (bx, by) = (x0 + m, y0 + h - m + 10.0);
    shapes.push(Shape::Line((bx, by), (x0 + w - 0.5 * m, by), black, false));
    shapes.push(Shape::Line((bx, y0 + 0.6 * m), (bx, by), black, false));
    shapes.push(Shape::Text((x0 + w / 2.0, y0 + 22.0), title.into(), "middle", false, 13));
    shapes.push(Shape::Text((x0 + w / 2.0, y0 + h - 8.0), "total time [s], log".into(), "middle", false, 11));
    shapes.push(Shape::Text((x0 + 14.0, y0 + h / 2.0), y_label.into(), "middle", true, 11));
    for p in lt0 as i32..=lt1 as i32 {
        let xv = x(10f64.powi(p));
        shapes.push(Shape::Line((xv, by), (xv, by + 5.0), black, false));
        shapes.push(Shape::Text((xv, by + 17.0), format!("{}", 10f64.powi(p)), "middle", false, 10));
    }
    for k in 0..=4 {
        let v = vmin + (vmax - vmin) * k as f64 / 4.0;
        shapes.push(Shape::Line((bx - 4.0, y(v)), (bx, y(v)), black, false));
        let text = if zoom { format!("{:.1}%", 100.0 * v) } else { format!("{:.0}%", 100.0 * v) };
        shapes.push(Shape::Text((bx - 6.0, y(v) + 4.0), text, "end", false, 10));
    }
    for wnd in front.windows(2) {
        let (a, b) = (wnd[0], wnd[1]);
        if vis.contains(&a) && vis.contains(&b) {
            shapes.push(Shape::Line((x(t[a]), y(value(&rows[a]))), (x(t[b]), y(value(&rows[b]))), (60, 60, 60), true));
        }
    }
    for &axis in &axes()[1..] {
        // The axis's points and the defaults, in time order.
        let mut pts: Vec<usize> = vis.iter().copied().filter(|&i| rows[i].setting.axis == axis).collect();
        if pts.is_empty() {
            continue;
        }
        if !axis.is_method() && vis.contains(&0) {
            pts.push(0);
        }
        pts.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
        for wnd in pts.windows(2) {
            let (a, b) = (wnd[0], wnd[1]);
            shapes.push(Shape::Line((x(t[a]), y(value(&rows[a]))), (x(t[b]), y(value(&rows[b]))), colour(axis), false));
        }
    }
    for &i in &vis {
        let r = &rows[i];
        shapes.push(Shape::Dot((x(t[i]), y(value(r))), colour(r.setting.axis)));
        if labels {
            shapes.push(Shape::Text((x(t[i]) + 6.0, y(value(r)) - 5.0), r.setting.label.clone(), "start", false, 8));
        }
    }
}

fn legend(shapes: &mut Vec<Shape>, x0: f64, y0: f64) {
    for (k, &a) in axes().iter().enumerate() {
        shapes.push(Shape::Dot((x0, y0 + 16.0 * k as f64), colour(a)));
        shapes.push(Shape::Text((x0 + 10.0, y0 + 16.0 * k as f64 + 4.0), a.to_string(), "start", false, 11));
    }
    let y = y0 + 16.0 * axes().len() as f64;
    shapes.push(Shape::Line((x0 - 5.0, y), (x0 + 5.0, y), (60, 60, 60), true));
    shapes.push(Shape::Text((x0 + 10.0, y + 4.0), "Pareto front".into(), "start", false, 11));
}

/// plot: error against time; bias_noise: bias against noise per setting (which
/// setting buys which); layers: per-layer error against time.
pub fn plots(out: &Path, rows: &[Row], front: &[usize]) -> Result<()> {
    // Left: every method; right: the photon-map settings alone, on their own scale.
    let photon_map = |r: &Row| r.setting.live.is_none() && r.setting.render.mode != Method::Path;
    let zoom_front = pareto(rows, Row::total, |r| if photon_map(r) { r.image().error } else { f64::INFINITY });
    let mut s = Vec::new();
    let error = |r: &Row| r.image().error;
    let y_label = "error sqrt(bias^2 + noise^2)";
    let every = Panel {
        at: (0.0, 0.0, 640.0, 560.0),
        title: "every method: error of one render against time",
        y_label,
        labels: false,
        zoom: false,
    };
    panel(&mut s, &every, rows, &error, &|_| true, front);
    let zoomed = Panel {
        at: (650.0, 0.0, 760.0, 560.0),
        title: "the photon-map settings, zoomed",
        y_label,
        labels: true,
        zoom: true,
    };
    panel(&mut s, &zoomed, rows, &error, &photon_map, &zoom_front);
    legend(&mut s, 1430.0, 60.0);
    plot::draw(&s, 1590.0, 560.0, &out.join("plot.svg"), &out.join("plot.png"))?;

    // Bias against noise: moving along an axis horizontally buys bias, vertically noise.
    let (w, h, m) = (760.0f64, 560.0f64, 60.0f64);
    let bmax = rows.iter().map(|r| r.image().bias).fold(0.0, f64::max).max(1e-9) * 1.1;
    let nmax = rows.iter().map(|r| r.image().noise).fold(0.0, f64::max).max(1e-9) * 1.1;
    let x = |v: f64| m + v / bmax * (w - 1.5 * m);
    let y = |v: f64| h - m - v / nmax * (h - 2.0 * m);
    let black = (0u8, 0u8, 0u8);
    let mut s = vec![
        Shape::Line((m, h - m), (w - 0.5 * m, h - m), black, false),
        Shape::Line((m, m), (m, h - m), black, false),
        Shape::Text((w / 2.0, 24.0), "what each setting buys: bias (across) or noise (up)".into(), "middle", false, 13),
        Shape::Text((w / 2.0, h - 18.0), "bias (relative RMS)".into(), "middle", false, 11),
        Shape::Text((16.0, h / 2.0), "noise of one render (relative RMS)".into(), "middle", true, 11),
    ];
    for k in 0..=4 {
        let (bv, nv) = (bmax * k as f64 / 4.0, nmax * k as f64 / 4.0);
        s.push(Shape::Text((x(bv), h - m + 16.0), format!("{:.1}%", 100.0 * bv), "middle", false, 10));
        s.push(Shape::Text((m - 6.0, y(nv) + 4.0), format!("{:.1}%", 100.0 * nv), "end", false, 10));
    }
    for &axis in &axes()[1..] {
        let mut pts: Vec<usize> = (0..rows.len()).filter(|&i| rows[i].setting.axis == axis).collect();
        if !axis.is_method() && !pts.is_empty() {
            pts.insert(pts.len() / 2, 0);
        }
        for wnd in pts.windows(2) {
            let (a, b) = (rows[wnd[0]].image(), rows[wnd[1]].image());
            s.push(Shape::Line((x(a.bias), y(a.noise)), (x(b.bias), y(b.noise)), colour(axis), false));
        }
    }
    for r in rows {
        let p = r.image();
        s.push(Shape::Dot((x(p.bias), y(p.noise)), colour(r.setting.axis)));
        s.push(Shape::Text((x(p.bias) + 6.0, y(p.noise) - 5.0), r.setting.label.clone(), "start", false, 8));
    }
    legend(&mut s, 780.0, 60.0);
    plot::draw(&s, 960.0, 560.0, &out.join("bias_noise.svg"), &out.join("bias_noise.png"))?;

    // Per layer.
    let mut s = Vec::new();
    let layers = shown_layers(rows);
    for (k, name) in layers.iter().enumerate() {
        let (px, py) = ((k % 2) as f64 * 480.0, (k / 2) as f64 * 340.0);
        let f = pareto(rows, Row::total, |r| r.layers.get(Some(*name)).error);
        let title = format!("{name} layer");
        let p = Panel { at: (px, py, 480.0, 340.0), title: &title, y_label: "error", labels: false, zoom: false };
        panel(&mut s, &p, rows, &|r| r.layers.get(Some(*name)).error, &|_| true, &f);
    }
    legend(&mut s, 985.0, 60.0);
    let height = 340.0 * layers.len().div_ceil(2) as f64;
    plot::draw(&s, 1140.0, height, &out.join("layers.svg"), &out.join("layers.png"))
}

/// The default setting's per-pixel relative error in false colour (black, blue,
/// red, yellow, white from 0 to the scale's top, the 99th percentile), with a scale
/// bar and its labels; the pixels left out are grey.
pub fn error_map_png(path: &Path, map: &[f32], size: u32) -> Result<()> {
    let mut sorted: Vec<f32> = map.iter().copied().filter(|v| *v > 0.0).collect();
    sorted.sort_by(f32::total_cmp);
    let top = sorted.get(sorted.len() * 99 / 100).copied().unwrap_or(1.0).max(1e-6);
    // The ramp's stops are sRGB colours; the canvas holds linear radiance.
    let ramp = |t: f32| -> glam::Vec3 {
        let stops = [
            glam::Vec3::ZERO,
            glam::Vec3::new(0.0, 0.1, 0.8),
            glam::Vec3::new(0.9, 0.1, 0.1),
            glam::Vec3::new(1.0, 0.9, 0.1),
            glam::Vec3::ONE,
        ];
        let u = t.clamp(0.0, 1.0) * 4.0;
        let k = (u.floor() as usize).min(3);
        stops[k].lerp(stops[k + 1], u - k as f32).to_array().map(pm_color::srgb_decode).into()
    };
    let (bar, pad) = (24u32, 90u32);
    let mut canvas = plot::Canvas::new(size + pad, size.max(120) + 20);
    let w = canvas.width;
    for (i, v) in map.iter().enumerate() {
        let (x, y) = (i as u32 % size, i as u32 / size);
        canvas.px[((y + 10) * w + x) as usize] =
            if *v > 0.0 || sorted.is_empty() { ramp(v / top) } else { glam::Vec3::splat(pm_color::srgb_decode(0.5)) };
    }
    let (bx, by0, by1) = (size + 10, 10u32, size.max(120) + 10);
    for y in by0..by1 {
        let t = 1.0 - (y - by0) as f32 / (by1 - by0) as f32;
        for x in bx..bx + bar {
            canvas.px[(y * w + x) as usize] = ramp(t);
        }
    }
    let x = (bx + bar + 4) as f64;
    canvas.text((x, by0 as f64 + 8.0), &format!("{:.0}%", 100.0 * top), "start", false, 10.0);
    canvas.text((x, (by0 + by1) as f64 / 2.0 + 4.0), &format!("{:.0}%", 50.0 * top), "start", false, 10.0);
    canvas.text((x, by1 as f64), "0%", "start", false, 10.0);
    pm_image::write_png(path, canvas.width, canvas.height, &canvas.px, 0.0)
}
