//! `cargo xtask figure1`: Christensen 1999, Figure 1 and the section 3 table on
//! cornell_spheres. (a) the global photon map, (b) irradiance estimated at each image
//! sample (shown as radiance, reflectance/pi x E), (c) precomputed irradiance at all
//! photons, (d) at a quarter of them, (e) the radiance the final gather sees, (f)
//! soft indirect light by final gathering, (g) the complete image; a contact sheet
//! (SVG with captions, and a PNG grid), and the table beside the paper's numbers.

use anyhow::{Context, Result};
use pm_estimate::IrradianceParams;
use pm_methods::Method;
use pm_render::{Lookup, RenderParams};
use pm_runner::bins::{self, Bins};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options of `cargo xtask figure1`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder [default: out/figure1].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Image width and height [pixels] (the paper: 1024).
    #[arg(long, default_value_t = 1024)]
    pub size: u32,
}

/// Run a stage quietly (its messages are kept for the error if it fails) and read
/// its typed statistics.
fn stage<T: serde::de::DeserializeOwned>(bins: &Bins, name: &str, args: &[String]) -> Result<T> {
    let stats = std::env::temp_dir().join(format!("figure1-{name}-{}.json", std::process::id()));
    let v = bins::run_for_report(bins, name, args, &stats);
    let _ = std::fs::remove_file(stats);
    v
}

/// Run it.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    let size = args.size;
    let out = args.out.clone().unwrap_or_else(|| root.join("out/figure1"));
    std::fs::create_dir_all(&out)?;
    let base = pm_pipeline::Pipeline::load(&root.join("pipeline.toml"))?;
    let bins = Bins::build(root)?;
    let scene = root.join("scenes/cornell_spheres.gltf").display().to_string();
    let o = |f: &str| out.join(f).display().to_string();
    let s = |v: &dyn std::fmt::Display| v.to_string();

    let mut a = vec![s(&"--scene"), scene.clone(), s(&"--out"), out.display().to_string()];
    a.extend(base.trace.to_args());
    let trace: pm_stage::report::TraceReport = stage(&bins, "photon-trace", &a)?;
    let mut sort_s = 0.0;
    for m in ["global", "caustic"] {
        let r: pm_stage::report::SortReport =
            stage(&bins, "photon-sort", &[o(&format!("{m}.pmap")), s(&"--out"), o(&format!("{m}.kd.pmap"))])?;
        sort_s += r.seconds;
    }
    let precompute = |fraction: f64, file: &str| -> Result<pm_stage::report::IrradianceReport> {
        let mut a = vec![o("global.kd.pmap"), s(&"--out"), o(file)];
        a.extend(IrradianceParams { fraction, ..base.irradiance.clone() }.to_args());
        stage(&bins, "photon-irradiance", &a)
    };
    let irr_all = precompute(1.0, "global.irr1.pmap")?;
    let irr_quarter = precompute(0.25, "global.irr.pmap")?;
    let inspect = |map: &str, png: &str, irradiance: bool| -> Result<()> {
        let mut a = vec![o(map), s(&"--image"), o(png), s(&"--scene"), scene.clone()];
        a.extend([s(&"--width"), s(&size), s(&"--height"), s(&size)]);
        if irradiance {
            a.push(s(&"--irradiance"));
        }
        bins::run(&bins, "photon-inspect", &a, "photon-inspect", true)
    };
    inspect("global.kd.pmap", "a_photon_map.png", false)?;
    inspect("global.irr1.pmap", "c_precomputed_all.png", true)?;
    inspect("global.irr.pmap", "d_precomputed_quarter.png", true)?;
    let render = |mode: Method, png: &str, lookup: Lookup| -> Result<pm_stage::report::RenderReport> {
        let mut a = vec![s(&"--scene"), scene.clone(), s(&"--global"), o("global.irr.pmap")];
        a.extend([
            s(&"--caustic"),
            o("caustic.kd.pmap"),
            s(&"--out"),
            o(&png.replace(".png", ".exr")),
            s(&"--png"),
            o(png),
        ]);
        let render = RenderParams { gather_lookup: lookup, width: size, height: size, ..base.render.clone() };
        a.extend(pm_methods::Settings { mode, render, ..base.settings() }.to_args());
        stage(&bins, "photon-render", &a)
    };
    render(Method::Photons, "b_irradiance_at_samples.png", Lookup::Precomputed)?;
    render(Method::Radiance, "e_radiance_seen_by_gather.png", Lookup::Precomputed)?;
    render(Method::Indirect, "f_soft_indirect.png", Lookup::Precomputed)?;
    let full = render(Method::Full, "g_complete.png", Lookup::Precomputed)?;
    let exact = render(Method::Full, "g_complete_exact.png", Lookup::Exact)?;

    // Contact sheet: SVG with captions over the PNGs, and a PNG grid (4 x 2).
    let panels = [
        ("a_photon_map.png", "(a) global photon map"),
        ("b_irradiance_at_samples.png", "(b) irradiance estimated at each image sample"),
        ("c_precomputed_all.png", "(c) precomputed irradiance, all photons"),
        ("d_precomputed_quarter.png", "(d) precomputed irradiance, a quarter of the photons"),
        ("e_radiance_seen_by_gather.png", "(e) radiance seen by the final gather"),
        ("f_soft_indirect.png", "(f) soft indirect light by final gathering"),
        ("g_complete.png", "(g) complete image"),
    ];
    let tile = 256u32;
    let (cell_w, cell_h) = (tile + 10, tile + 44);
    let (sheet_w, sheet_h) = (4 * cell_w, 2 * cell_h);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{sheet_w}\" height=\"{sheet_h}\" font-family=\"monospace\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    // The PNG: the same layout, captions rasterised with the plots' bundled font.
    let mut sheet = crate::plot::Canvas::new(sheet_w, sheet_h);
    for (k, (file, caption)) in panels.iter().enumerate() {
        let (x0, y0) = ((k % 4) as u32 * cell_w, (k / 4) as u32 * cell_h);
        writeln!(svg, "<image href=\"{file}\" x=\"{x0}\" y=\"{y0}\" width=\"{tile}\" height=\"{tile}\"/>")?;
        for (line, text) in wrap(caption, 38).iter().enumerate() {
            let (tx, ty) = (x0 as f64, (y0 + tile + 15 + 14 * line as u32) as f64);
            writeln!(svg, "<text x=\"{tx}\" y=\"{ty}\">{text}</text>")?;
            sheet.text((tx, ty), text, "start", false, 11.0);
        }
        let img = image::open(out.join(file)).with_context(|| format!("{file}: cannot read"))?.to_rgb8();
        let small = image::imageops::resize(&img, tile, tile, image::imageops::FilterType::Triangle);
        for (x, y, p) in small.enumerate_pixels() {
            let c = glam::Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0;
            sheet.px[((y0 + y) * sheet_w + x0 + x) as usize] =
                glam::Vec3::new(pm_color::srgb_decode(c.x), pm_color::srgb_decode(c.y), pm_color::srgb_decode(c.z));
        }
    }
    svg.push_str("</svg>\n");
    std::fs::write(out.join("contact_sheet.svg"), svg)?;
    pm_image::write_png(&out.join("contact_sheet.png"), sheet_w, sheet_h, &sheet.px, 0.0)?;

    // The section 3 table.
    let fg = |v: &pm_stage::report::RenderReport| {
        v.prepass_seconds + v.thread_seconds.get("final_gather").copied().unwrap_or(0.0) / v.threads.max(1) as f64
    };
    let saved = fg(&exact) - fg(&full);
    let mut md = String::new();
    writeln!(md, "| | Christensen 1999 (233 MHz Pentium) | this machine (2 cores) |\n|---|---|---|")?;
    let rows = [
        ("photons emitted", "220,000".to_string(), format!("{}", trace.global.emitted)),
        ("global photons stored", "400,000".into(), format!("{}", trace.global.stored)),
        (
            "caustic photons stored",
            "35,000".into(),
            format!("{} ({} emitted)", trace.caustic.stored, trace.caustic.emitted),
        ),
        ("photon tracing", "10 s".into(), format!("{:.2} s", trace.seconds)),
        ("sorting", "10 s".into(), format!("{sort_s:.2} s")),
        ("precompute, all photons", "58 s".into(), format!("{:.2} s", irr_all.seconds)),
        ("precompute, a quarter", "15 s".into(), format!("{:.2} s", irr_quarter.seconds)),
        (
            "rendering (1024 x 1024, up to 16 spp)",
            "5 min 29 s".into(),
            format!("{:.2} s ({size} x {size})", full.seconds),
        ),
        ("of which soft indirect (final gathering)", "2 min 45 s".into(), format!("{:.2} s", fg(&full))),
        ("final gathers", "11,800".into(), format!("{}", full.final_gathers)),
        ("final gather rays", "6.5 million".into(), format!("{:.2} million", full.gather_rays as f64 / 1e6)),
        ("final gathering without precomputation", "16 min".into(), format!("{:.2} s", fg(&exact))),
        (
            "final-gather speed-up from precomputation",
            "5.8x".into(),
            format!("{:.1}x", fg(&exact) / fg(&full).max(1e-9)),
        ),
        (
            "precompute as a share of the time saved",
            "< 2%".into(),
            format!("{:.1}%", 100.0 * irr_quarter.seconds / saved.max(1e-9)),
        ),
    ];
    for (what, paper, ours) in rows {
        writeln!(md, "| {what} | {paper} | {ours} |")?;
    }
    std::fs::write(out.join("table.md"), &md)?;
    println!("{md}\nwrote {}", out.display());
    Ok(())
}

/// `text` broken at spaces into lines of at most `width` characters.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split(' ') {
        match lines.last_mut() {
            Some(l) if l.len() + 1 + word.len() <= width => {
                l.push(' ');
                l.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    lines
}
