//! `cargo xtask figure1`: Christensen 1999, Figure 1 and the section 3 table on
//! cornell_spheres. (a) the global photon map, (b) irradiance estimated at each image
//! sample (shown as radiance, reflectance/pi x E), (c) precomputed irradiance at all
//! photons, (d) at a quarter of them, (e) the radiance the final gather sees, (f)
//! soft indirect light by final gathering, (g) the complete image; a contact sheet
//! (SVG with captions, and a PNG grid), and the table beside the paper's numbers.

use anyhow::{Context, Result, bail};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

fn stage(bin: &Path, name: &str, args: &[String]) -> Result<Value> {
    let stats = std::env::temp_dir().join(format!("figure1-{name}-{}.json", std::process::id()));
    let status = Command::new(bin.join(name))
        .args(args)
        .args(["--stats-json".to_string(), stats.display().to_string()])
        .stderr(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .status()
        .with_context(|| format!("cannot start {name}"))?;
    if !status.success() {
        bail!("{name} {} failed", args.join(" "));
    }
    let v = serde_json::from_slice(&std::fs::read(&stats)?)?;
    let _ = std::fs::remove_file(stats);
    Ok(v)
}

/// Run it.
pub fn run(args: &[String], root: &Path) -> Result<()> {
    let mut size = 1024u32;
    let mut out: Option<PathBuf> = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--out" => out = Some(PathBuf::from(it.next().context("--out needs a folder")?)),
            "--size" => size = it.next().context("--size needs a number")?.parse()?,
            other => bail!("unknown option {other}"),
        }
    }
    let out = out.unwrap_or_else(|| root.join("out/figure1"));
    std::fs::create_dir_all(&out)?;
    crate::run::build_stages(root)?;
    let bin = root.join("target/release");
    let scene = root.join("scenes/cornell_spheres.gltf").display().to_string();
    let o = |f: &str| out.join(f).display().to_string();
    let s = |v: &dyn std::fmt::Display| v.to_string();
    let dim = vec![s(&"--width"), s(&size), s(&"--height"), s(&size)];

    let trace = stage(&bin, "photon-trace", &[s(&"--scene"), scene.clone(), s(&"--out"), out.display().to_string()])?;
    let mut sort_s = 0.0;
    for m in ["global", "caustic"] {
        sort_s +=
            stage(&bin, "photon-sort", &[o(&format!("{m}.pmap")), s(&"--out"), o(&format!("{m}.kd.pmap"))])?["seconds"]
                .as_f64()
                .unwrap_or(0.0);
    }
    let irr_all = stage(
        &bin,
        "photon-irradiance",
        &[o("global.kd.pmap"), s(&"--out"), o("global.irr1.pmap"), s(&"--fraction"), s(&1.0)],
    )?;
    let irr_quarter = stage(
        &bin,
        "photon-irradiance",
        &[o("global.kd.pmap"), s(&"--out"), o("global.irr.pmap"), s(&"--fraction"), s(&0.25)],
    )?;
    let inspect = |map: &str, png: &str, irradiance: bool| -> Result<()> {
        let mut a = vec![
            o(map),
            s(&"--image"),
            o(png),
            s(&"--scene"),
            scene.clone(),
            s(&"--width"),
            s(&size),
            s(&"--height"),
            s(&size),
        ];
        if irradiance {
            a.push(s(&"--irradiance"));
        }
        let status = Command::new(bin.join("photon-inspect")).args(&a).stdout(std::process::Stdio::null()).status()?;
        if !status.success() {
            bail!("photon-inspect failed");
        }
        Ok(())
    };
    inspect("global.kd.pmap", "a_photon_map.png", false)?;
    inspect("global.irr1.pmap", "c_precomputed_all.png", true)?;
    inspect("global.irr.pmap", "d_precomputed_quarter.png", true)?;
    let render = |mode: &str, png: &str, lookup: &str| -> Result<Value> {
        let mut a = vec![
            s(&"--scene"),
            scene.clone(),
            s(&"--global"),
            o("global.irr.pmap"),
            s(&"--caustic"),
            o("caustic.kd.pmap"),
            s(&"--mode"),
            s(&mode),
            s(&"--gather-lookup"),
            s(&lookup),
            s(&"--out"),
            o(&png.replace(".png", ".exr")),
            s(&"--png"),
            o(png),
        ];
        a.extend(dim.iter().cloned());
        stage(&bin, "photon-render", &a)
    };
    render("photons", "b_irradiance_at_samples.png", "precomputed")?;
    render("radiance", "e_radiance_seen_by_gather.png", "precomputed")?;
    render("indirect", "f_soft_indirect.png", "precomputed")?;
    let full = render("full", "g_complete.png", "precomputed")?;
    let exact = render("full", "g_complete_exact.png", "exact")?;

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
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
        4 * (tile + 10),
        2 * (tile + 30)
    );
    let mut grid = vec![glam::Vec3::ONE; (4 * tile * 2 * tile) as usize];
    for (k, (file, caption)) in panels.iter().enumerate() {
        let (cx, cy) = ((k % 4) as u32, (k / 4) as u32);
        writeln!(
            svg,
            "<image href=\"{file}\" x=\"{}\" y=\"{}\" width=\"{tile}\" height=\"{tile}\"/><text x=\"{}\" y=\"{}\">{caption}</text>",
            cx * (tile + 10),
            cy * (tile + 30),
            cx * (tile + 10),
            cy * (tile + 30) + tile + 16
        )?;
        let img = image::open(out.join(file)).with_context(|| format!("{file}: cannot read"))?.to_rgb8();
        let small = image::imageops::resize(&img, tile, tile, image::imageops::FilterType::Triangle);
        for (x, y, p) in small.enumerate_pixels() {
            let c = glam::Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0;
            grid[((cy * tile + y) * 4 * tile + cx * tile + x) as usize] =
                glam::Vec3::new(pm_color::srgb_decode(c.x), pm_color::srgb_decode(c.y), pm_color::srgb_decode(c.z));
        }
    }
    svg.push_str("</svg>\n");
    std::fs::write(out.join("contact_sheet.svg"), svg)?;
    pm_image::write_png(&out.join("contact_sheet.png"), 4 * tile, 2 * tile, &grid, 0.0)?;

    // The section 3 table.
    let f = |v: &Value, k: &str| v[k].as_f64().unwrap_or(0.0);
    let fg = |v: &Value| {
        f(v, "prepass_seconds")
            + v["thread_seconds"]["final_gather"].as_f64().unwrap_or(0.0) / v["threads"].as_f64().unwrap_or(1.0)
    };
    let saved = fg(&exact) - fg(&full);
    let mut md = String::new();
    writeln!(md, "| | Christensen 1999 (233 MHz Pentium) | this machine (2 cores) |\n|---|---|---|")?;
    let rows = [
        ("photons emitted", "220,000".to_string(), format!("{}", trace["global"]["emitted"])),
        ("global photons stored", "400,000".into(), format!("{}", trace["global"]["stored"])),
        (
            "caustic photons stored",
            "35,000".into(),
            format!("{} ({} emitted)", trace["caustic"]["stored"], trace["caustic"]["emitted"]),
        ),
        ("photon tracing", "10 s".into(), format!("{:.2} s", f(&trace, "seconds"))),
        ("sorting", "10 s".into(), format!("{sort_s:.2} s")),
        ("precompute, all photons", "58 s".into(), format!("{:.2} s", f(&irr_all, "seconds"))),
        ("precompute, a quarter", "15 s".into(), format!("{:.2} s", f(&irr_quarter, "seconds"))),
        (
            "rendering (1024 x 1024, up to 16 spp)",
            "5 min 29 s".into(),
            format!("{:.2} s ({size} x {size})", f(&full, "seconds")),
        ),
        ("of which soft indirect (final gathering)", "2 min 45 s".into(), format!("{:.2} s", fg(&full))),
        ("final gathers", "11,800".into(), format!("{}", full["final_gathers"])),
        ("final gather rays", "6.5 million".into(), format!("{:.2} million", f(&full, "gather_rays") / 1e6)),
        ("final gathering without precomputation", "16 min".into(), format!("{:.2} s", fg(&exact))),
        (
            "final-gather speed-up from precomputation",
            "5.8x".into(),
            format!("{:.1}x", fg(&exact) / fg(&full).max(1e-9)),
        ),
        (
            "precompute as a share of the time saved",
            "< 2%".into(),
            format!("{:.1}%", 100.0 * f(&irr_quarter, "seconds") / saved.max(1e-9)),
        ),
    ];
    for (what, paper, ours) in rows {
        writeln!(md, "| {what} | {paper} | {ours} |")?;
    }
    std::fs::write(out.join("table.md"), &md)?;
    println!("{md}\nwrote {}", out.display());
    Ok(())
}
