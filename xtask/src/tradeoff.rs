//! `cargo xtask tradeoff`: what accuracy costs in time. Renders a path-traced
//! reference, then sweeps one setting at a time from the defaults (photon counts,
//! k, precompute fraction, gather rays, irradiance-cache accuracy, lookup, record
//! layout, and path tracing at several sample counts), timing every stage and
//! measuring the error of the image and of its caustic and indirect components
//! against the reference. Writes results.csv, results.md, plot.svg and plot.png.

use anyhow::{Context, Result, bail};
use serde_json::Value;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// One point of the sweep.
#[derive(Clone, Debug)]
struct Setting {
    axis: &'static str,
    label: String,
    global: u64,
    caustic: u64,
    layout: &'static str,
    k: usize,
    fraction: f64,
    gather_rays: u32,
    icache: f64,
    lookup: &'static str,
    mode: &'static str,
    spp: u32,
    light_samples: u32,
}

impl Setting {
    fn default_full() -> Setting {
        Setting {
            axis: "default",
            label: "defaults".into(),
            global: 400_000,
            caustic: 35_000,
            layout: "compact",
            k: 50,
            fraction: 0.25,
            gather_rays: 400,
            icache: 0.3,
            lookup: "precomputed",
            mode: "full",
            spp: 16,
            light_samples: 4,
        }
    }
    fn maps_key(&self) -> String {
        format!("g{}-c{}-{}-k{}-f{}", self.global, self.caustic, self.layout, self.k, self.fraction)
    }
}

fn sweep() -> Vec<Setting> {
    let d = Setting::default_full();
    let mut v = vec![d.clone()];
    let with = |axis: &'static str, label: String, f: &dyn Fn(&mut Setting)| {
        let mut s = d.clone();
        s.axis = axis;
        s.label = label;
        f(&mut s);
        s
    };
    for g in [25_000u64, 100_000, 1_600_000] {
        v.push(with("global photons", format!("global {g}"), &|s| s.global = g));
    }
    for c in [5_000u64, 140_000] {
        v.push(with("caustic photons", format!("caustic {c}"), &|s| s.caustic = c));
    }
    for k in [25usize, 100, 200, 400] {
        v.push(with("k", format!("k {k}"), &|s| s.k = k));
    }
    for f in [1.0f64, 0.0625] {
        v.push(with("precompute fraction", format!("fraction {f}"), &|s| s.fraction = f));
    }
    for r in [64u32, 1024] {
        v.push(with("gather rays", format!("gather rays {r}"), &|s| s.gather_rays = r));
    }
    for a in [0.15f64, 0.6] {
        v.push(with("cache accuracy", format!("cache a {a}"), &|s| s.icache = a));
    }
    for n in [1u32, 16] {
        v.push(with("light samples", format!("light samples {n}"), &|s| s.light_samples = n));
    }
    for spp in [4u32, 64] {
        v.push(with("max spp", format!("max spp {spp}"), &|s| s.spp = spp));
    }
    v.push(with("lookup", "exact lookup".into(), &|s| s.lookup = "exact"));
    v.push(with("records", "full-precision records".into(), &|s| s.layout = "full"));
    for spp in [16u32, 64, 256, 1024] {
        v.push(with("path", format!("path {spp} spp"), &|s| {
            s.mode = "path";
            s.spp = spp
        }));
    }
    v
}

fn run_stage(bin_dir: &Path, name: &str, args: &[String], stats: &Path) -> Result<Value> {
    let status = Command::new(bin_dir.join(name))
        .args(args)
        .args(["--stats-json".to_string(), stats.display().to_string()])
        .stderr(std::process::Stdio::null())
        .status()
        .with_context(|| format!("cannot start {name}"))?;
    if !status.success() {
        bail!("{name} {} failed", args.join(" "));
    }
    Ok(serde_json::from_slice(&std::fs::read(stats)?)?)
}

/// Run the trade-off study.
pub fn run(args: &[String], root: &Path) -> Result<()> {
    let mut scene = root.join("scenes/cornell_spheres.gltf");
    let mut size = 128u32;
    let mut out: Option<PathBuf> = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--scene" => scene = PathBuf::from(it.next().context("--scene needs a file")?),
            "--out" => out = Some(PathBuf::from(it.next().context("--out needs a folder")?)),
            "--size" => size = it.next().context("--size needs a number")?.parse()?,
            other => bail!("unknown option {other}"),
        }
    }
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = out.unwrap_or_else(|| root.join("out/tradeoff").join(&name));
    std::fs::create_dir_all(&out)?;
    crate::run::build_stages(root)?;
    let bin = root.join("target/release");
    let s = |v: &dyn std::fmt::Display| v.to_string();
    let scene_s = scene.display().to_string();
    let dim = [s(&"--width"), s(&size), s(&"--height"), s(&size)];

    // The reference: 4096 paths per pixel, cached by scene content and size.
    let scene_hash = blake3::hash(&std::fs::read(&scene)?).to_hex().to_string();
    let ref_exr = out.join(format!("reference-{size}.exr"));
    let ref_key = out.join(format!("reference-{size}.key"));
    if std::fs::read_to_string(&ref_key).ok().as_deref() != Some(scene_hash.as_str()) || !ref_exr.exists() {
        println!("rendering the reference ({size}x{size}, path tracing, 4096 spp) ...");
        let mut a =
            vec![s(&"--scene"), scene_s.clone(), s(&"--mode"), s(&"path"), s(&"--spp"), s(&4096), s(&"--seed"), s(&99)];
        a.extend(dim.iter().cloned());
        a.extend([s(&"--out"), ref_exr.display().to_string()]);
        run_stage(&bin, "photon-render", &a, &out.join("reference.stats.json"))?;
        std::fs::write(&ref_key, &scene_hash)?;
    }
    let reference = pm_image::read_exr(&ref_exr)?;

    let mut maps: BTreeMap<String, (PathBuf, [f64; 3])> = BTreeMap::new();
    let mut rows: Vec<(Setting, [f64; 4], [f64; 5])> = Vec::new();
    for st in sweep() {
        // Photon maps, shared by settings that differ only in rendering.
        let mut times = [0.0f64; 4];
        let mdir = out.join("maps").join(st.maps_key());
        if st.mode == "full" {
            if !maps.contains_key(&st.maps_key()) {
                std::fs::create_dir_all(&mdir)?;
                let o = |f: &str| mdir.join(f).display().to_string();
                let t = run_stage(
                    &bin,
                    "photon-trace",
                    &[
                        s(&"--scene"),
                        scene_s.clone(),
                        s(&"--out"),
                        mdir.display().to_string(),
                        s(&"--global"),
                        s(&st.global),
                        s(&"--caustic"),
                        s(&st.caustic),
                        s(&"--layout"),
                        s(&st.layout),
                    ],
                    &mdir.join("trace.json"),
                )?;
                let mut sort = 0.0;
                for m in ["global", "caustic"] {
                    if Path::new(&o(&format!("{m}.pmap"))).exists() {
                        let r = run_stage(
                            &bin,
                            "photon-sort",
                            &[o(&format!("{m}.pmap")), s(&"--out"), o(&format!("{m}.kd.pmap"))],
                            &mdir.join("sort.json"),
                        )?;
                        sort += r["seconds"].as_f64().unwrap_or(0.0);
                    }
                }
                let i = run_stage(
                    &bin,
                    "photon-irradiance",
                    &[
                        o("global.kd.pmap"),
                        s(&"--out"),
                        o("global.irr.pmap"),
                        s(&"--k"),
                        s(&st.k),
                        s(&"--fraction"),
                        s(&st.fraction),
                    ],
                    &mdir.join("irr.json"),
                )?;
                maps.insert(
                    st.maps_key(),
                    (mdir.clone(), [t["seconds"].as_f64().unwrap_or(0.0), sort, i["seconds"].as_f64().unwrap_or(0.0)]),
                );
            }
            let (_, t) = &maps[&st.maps_key()];
            times[..3].copy_from_slice(t);
        }
        let id = st.label.replace(' ', "_");
        let img = out.join(format!("{id}.exr"));
        let mut a = vec![
            s(&"--scene"),
            scene_s.clone(),
            s(&"--mode"),
            s(&st.mode),
            s(&"--spp"),
            s(&st.spp),
            s(&"--light-samples"),
            s(&st.light_samples),
            s(&"--out"),
            img.display().to_string(),
        ];
        a.extend(dim.iter().cloned());
        if st.mode == "full" {
            let irr = mdir.join("global.irr.pmap");
            a.extend([
                s(&"--global"),
                irr.display().to_string(),
                s(&"--gather-rays"),
                s(&st.gather_rays),
                s(&"--icache-accuracy"),
                s(&st.icache),
                s(&"--gather-lookup"),
                s(&st.lookup),
                s(&"--k"),
                s(&st.k),
            ]);
            if mdir.join("caustic.kd.pmap").exists() {
                a.extend([s(&"--caustic"), mdir.join("caustic.kd.pmap").display().to_string()]);
            }
        }
        let r = run_stage(&bin, "photon-render", &a, &out.join(format!("{id}.stats.json")))?;
        times[3] = r["seconds"].as_f64().unwrap_or(0.0);
        let image = pm_image::read_exr(&img)?;
        let layer = |i: &pm_image::Layers, n: &str| i.layer(n).map(<[_]>::to_vec).unwrap_or_default();
        let total = pm_image::compare(&layer(&image, "total"), &layer(&reference, "total"), 1.0);
        let ssim = pm_image::ssim(&layer(&image, "total"), &layer(&reference, "total"), size as usize, size as usize);
        let caustic = pm_image::compare(&layer(&image, "caustic"), &layer(&reference, "caustic"), f32::INFINITY);
        let indirect = pm_image::compare(&layer(&image, "indirect"), &layer(&reference, "indirect"), f32::INFINITY);
        let errs = [total.rel_rmse, total.rel_bias, ssim, caustic.rel_rmse, indirect.rel_rmse];
        println!(
            "  {:<24} {:>7.2} s  rel. RMSE {:.4}  bias {:+.4}  SSIM {:.4}",
            st.label,
            times.iter().sum::<f64>(),
            errs[0],
            errs[1],
            errs[2]
        );
        rows.push((st, times, errs));
    }
    write_outputs(&out, size, &rows)
}

fn write_outputs(out: &Path, size: u32, rows: &[(Setting, [f64; 4], [f64; 5])]) -> Result<()> {
    let total = |t: &[f64; 4]| t.iter().sum::<f64>();
    let mut csv = String::from(
        "axis,setting,trace_s,sort_s,irradiance_s,render_s,total_s,rel_rmse,rel_bias,ssim,caustic_rel_rmse,indirect_rel_rmse\n",
    );
    for (s, t, e) in rows {
        writeln!(
            csv,
            "{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.5},{:.5},{:.5},{:.5},{:.5}",
            s.axis,
            s.label,
            t[0],
            t[1],
            t[2],
            t[3],
            total(t),
            e[0],
            e[1],
            e[2],
            e[3],
            e[4]
        )?;
    }
    std::fs::write(out.join("results.csv"), csv)?;
    // Pareto front: no faster point has lower error.
    let mut order: Vec<usize> = (0..rows.len()).collect();
    order.sort_by(|&a, &b| total(&rows[a].1).total_cmp(&total(&rows[b].1)));
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for &i in &order {
        if rows[i].2[0] < best {
            best = rows[i].2[0];
            front.push(i);
        }
    }
    let base_t = total(&rows[0].1);
    let pick = |budget: f64| {
        front
            .iter()
            .copied()
            .filter(|&i| total(&rows[i].1) <= budget)
            .min_by(|&a, &b| rows[a].2[0].total_cmp(&rows[b].2[0]))
    };
    let mut md = format!(
        "Trade-off on {size}x{size} against a 4096-spp path-traced reference (pixels that see the light left out of the RMSE). Times are wall seconds per stage on this machine, same session. The caustic column compares against the reference's caustic layer, whose own noise at 4096 spp is large (path tracing finds caustics poorly), so it ranks settings only roughly.\n\n| axis | setting | trace | sort | precompute | render | total [s] | rel. RMSE | bias | SSIM | caustic RMSE | indirect RMSE | Pareto |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for (i, (s, t, e)) in rows.iter().enumerate() {
        writeln!(
            md,
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.4} | {:+.4} | {:.4} | {:.3} | {:.3} | {} |",
            s.axis,
            s.label,
            t[0],
            t[1],
            t[2],
            t[3],
            total(t),
            e[0],
            e[1],
            e[2],
            e[3],
            e[4],
            if front.contains(&i) { "yes" } else { "" }
        )?;
    }
    // The reference's own noise: path tracing with 1024 spp has 4x the reference's
    // variance, so its error against the reference is sqrt(1 + 4) times the
    // reference's error against the truth.
    if let Some(r) = rows.iter().find(|r| r.0.label == "path 1024 spp") {
        writeln!(
            md,
            "\nNoise left in the reference: about {:.1}% relative RMSE (from the 1024-spp path image's error, {:.1}%, over sqrt(5)); errors below that level cannot be resolved.",
            100.0 * r.2[0] / 5f64.sqrt(),
            100.0 * r.2[0]
        )?;
    }
    md.push_str("\nBest setting per time budget (lowest error on the Pareto front within the budget):\n\n");
    for (name, budget) in [("preview", 0.25 * base_t), ("balanced", base_t), ("final", 4.0 * base_t)] {
        if let Some(i) = pick(budget) {
            writeln!(
                md,
                "- {name} (at most {budget:.2} s): {} ({:.2} s, rel. RMSE {:.4})",
                rows[i].0.label,
                total(&rows[i].1),
                rows[i].2[0]
            )?;
        }
    }
    std::fs::write(out.join("results.md"), &md)?;
    plot(out, rows, &front)?;
    println!("\n{md}\nwrote {}", out.display());
    Ok(())
}

/// Error against time (log axis) with the Pareto front: SVG with labels, and the
/// same drawing rasterised to PNG (points and lines, no text).
fn plot(out: &Path, rows: &[(Setting, [f64; 4], [f64; 5])], front: &[usize]) -> Result<()> {
    let (w, h, m) = (900.0f64, 560.0f64, 70.0f64);
    let t: Vec<f64> = rows.iter().map(|r| r.1.iter().sum::<f64>().max(1e-3)).collect();
    let e: Vec<f64> = rows.iter().map(|r| r.2[0]).collect();
    let (lt0, lt1) = (
        t.iter().cloned().fold(f64::INFINITY, f64::min).log10().floor(),
        t.iter().cloned().fold(0.0, f64::max).log10().ceil(),
    );
    let emax = e.iter().cloned().fold(0.0, f64::max) * 1.1;
    let x = |tv: f64| m + (tv.log10() - lt0) / (lt1 - lt0).max(1e-9) * (w - 2.0 * m);
    let y = |ev: f64| h - m - ev / emax.max(1e-9) * (h - 2.0 * m);
    let axes = [
        "default",
        "global photons",
        "caustic photons",
        "k",
        "precompute fraction",
        "gather rays",
        "cache accuracy",
        "lookup",
        "records",
        "path",
        "light samples",
        "max spp",
    ];
    let colour = |axis: &str| {
        let pal = [
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
        pal[axes.iter().position(|a| *a == axis).unwrap_or(0)]
    };
    // One list of shapes, written as SVG (with text) and rasterised to PNG (without).
    let black = (0u8, 0u8, 0u8);
    let mut shapes =
        vec![Shape::Line((m, h - m), (w - m, h - m), black, false), Shape::Line((m, m), (m, h - m), black, false)];
    for p in lt0 as i32..=lt1 as i32 {
        let xv = x(10f64.powi(p));
        shapes.push(Shape::Line((xv, h - m), (xv, h - m + 5.0), black, false));
        shapes.push(Shape::Text((xv, h - m + 20.0), format!("{}", 10f64.powi(p)), "middle", false, 12));
    }
    for k in 0..=4 {
        let ev = emax * k as f64 / 4.0;
        shapes.push(Shape::Text((m - 6.0, y(ev) + 4.0), format!("{ev:.3}"), "end", false, 12));
    }
    shapes.push(Shape::Text((w / 2.0, h - 25.0), "total time [s] (log)".into(), "middle", false, 12));
    shapes.push(Shape::Text((18.0, h / 2.0), "relative RMSE vs reference".into(), "middle", true, 12));
    for wnd in front.windows(2) {
        shapes.push(Shape::Line((x(t[wnd[0]]), y(e[wnd[0]])), (x(t[wnd[1]]), y(e[wnd[1]])), (77, 77, 77), true));
    }
    for (i, r) in rows.iter().enumerate() {
        shapes.push(Shape::Dot((x(t[i]), y(e[i])), colour(r.0.axis)));
        shapes.push(Shape::Text((x(t[i]) + 7.0, y(e[i]) - 4.0), r.0.label.clone(), "start", false, 9));
    }
    for (k, a) in axes.iter().enumerate() {
        shapes.push(Shape::Dot((w - 190.0, m + 16.0 * k as f64), colour(a)));
        shapes.push(Shape::Text((w - 180.0, m + 16.0 * k as f64 + 4.0), a.to_string(), "start", false, 12));
    }
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    let (wi, hi) = (w as u32, h as u32);
    let mut px = vec![glam::Vec3::ONE; (wi * hi) as usize];
    let mut put = |xx: i64, yy: i64, (r, g, b): (u8, u8, u8)| {
        if xx >= 0 && yy >= 0 && (xx as u32) < wi && (yy as u32) < hi {
            let c = glam::Vec3::new(r as f32, g as f32, b as f32) / 255.0;
            px[(yy as u32 * wi + xx as u32) as usize] = c.to_array().map(pm_color::srgb_decode).into();
        }
    };
    for shape in &shapes {
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
                    put((x0 + f * (x1 - x0)) as i64, (y0 + f * (y1 - y0)) as i64, (*r, *g, *b));
                }
            }
            Shape::Dot((cx, cy), (r, g, b)) => {
                writeln!(svg, "<circle cx=\"{cx:.1}\" cy=\"{cy:.1}\" r=\"5\" fill=\"rgb({r},{g},{b})\"/>")?;
                for dy in -4i64..=4 {
                    for dx in -4i64..=4 {
                        if dx * dx + dy * dy <= 16 {
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
    std::fs::write(out.join("plot.svg"), svg)?;
    pm_image::write_png(&out.join("plot.png"), wi, hi, &px, 0.0)?;
    Ok(())
}

/// A drawing primitive of the plot (points in SVG pixel coordinates, sRGB colours).
enum Shape {
    Line((f64, f64), (f64, f64), (u8, u8, u8), bool),
    Dot((f64, f64), (u8, u8, u8)),
    Text((f64, f64), String, &'static str, bool, u8),
}
