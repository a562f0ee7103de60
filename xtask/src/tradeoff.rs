//! `cargo xtask tradeoff`: what accuracy costs in time. Renders a path-traced
//! reference, then sweeps one setting at a time from the defaults (photon counts,
//! k, precompute fraction, gather rays, irradiance-cache accuracy, lookup, record
//! layout, and path tracing at several sample counts), timing every stage and
//! measuring the error of the image and of its caustic and indirect components
//! against the reference. Writes results.csv, results.md, plot.svg and plot.png.

use anyhow::Result;
use pm_estimate::IrradianceParams;
use pm_photon::{RecordLayout, TraceParams};
use pm_render::{Lookup, Method, RenderParams};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use xtask::plot::{self, Shape};
use xtask::stages::{self, Bins};

/// Options of `cargo xtask tradeoff`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene (glTF 2.0).
    #[arg(long, default_value = "scenes/cornell_spheres.gltf")]
    scene: PathBuf,
    /// Output folder [default: out/tradeoff/<scene name>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Image width and height [pixels].
    #[arg(long, default_value_t = 128)]
    size: u32,
}

/// One point of the sweep: the stage parameters it runs with.
#[derive(Clone, Debug)]
struct Setting {
    axis: &'static str,
    label: String,
    trace: TraceParams,
    irradiance: IrradianceParams,
    render: RenderParams,
}

impl Setting {
    /// Photon maps are shared by settings that differ only in rendering.
    fn maps_key(&self) -> String {
        let t = &self.trace;
        let i = &self.irradiance;
        format!("g{}-c{}-{}-k{}-f{}", t.global_photons, t.caustic_photons, t.layout, i.k, i.fraction)
    }
}

/// The defaults (pipeline.toml's values at `size`), then one setting at a time.
fn sweep(base: &xtask::run::Pipeline, size: u32) -> Vec<Setting> {
    let mut render = base.render.clone();
    render.width = size;
    render.height = size;
    let d = Setting {
        axis: "default",
        label: "defaults".into(),
        trace: base.trace.clone(),
        irradiance: base.irradiance.clone(),
        render,
    };
    let mut v = vec![d.clone()];
    let with = |axis: &'static str, label: String, f: &dyn Fn(&mut Setting)| {
        let mut s = d.clone();
        s.axis = axis;
        s.label = label;
        f(&mut s);
        s
    };
    for g in [25_000u64, 100_000, 1_600_000] {
        v.push(with("global photons", format!("global {g}"), &|s| s.trace.global_photons = g));
    }
    for c in [5_000u64, 140_000] {
        v.push(with("caustic photons", format!("caustic {c}"), &|s| s.trace.caustic_photons = c));
    }
    for k in [25usize, 100, 200, 400] {
        v.push(with("k", format!("k {k}"), &|s| {
            s.irradiance.k = k;
            s.render.k = k;
        }));
    }
    for f in [1.0f64, 0.0625] {
        v.push(with("precompute fraction", format!("fraction {f}"), &|s| s.irradiance.fraction = f));
    }
    for r in [64u32, 1024] {
        v.push(with("gather rays", format!("gather rays {r}"), &|s| s.render.gather_rays = r));
    }
    for a in [0.15f32, 0.6] {
        v.push(with("cache accuracy", format!("cache a {a}"), &|s| s.render.icache_accuracy = a));
    }
    for n in [1u32, 16] {
        v.push(with("light samples", format!("light samples {n}"), &|s| s.render.light_samples = n));
    }
    for spp in [4u32, 64] {
        v.push(with("max spp", format!("max spp {spp}"), &|s| s.render.spp = spp));
    }
    v.push(with("lookup", "exact lookup".into(), &|s| s.render.gather_lookup = Lookup::Exact));
    v.push(with("records", "full-precision records".into(), &|s| s.trace.layout = RecordLayout::Full));
    for spp in [16u32, 64, 256, 1024] {
        v.push(with("path", format!("path {spp} spp"), &|s| {
            s.render.mode = Method::Path;
            s.render.spp = spp
        }));
    }
    v
}

/// Run one stage quietly (its messages are kept for the error if it fails) and
/// read its typed statistics.
fn stage<T: serde::de::DeserializeOwned>(bins: &Bins, name: &str, args: &[String], stats: &Path) -> Result<T> {
    let mut a = args.to_vec();
    a.extend(["--stats-json".to_string(), stats.display().to_string()]);
    stages::run(bins, name, &a, name, true)?;
    stages::read_stats(stats)
}

/// Run the trade-off study.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    let scene = if args.scene.is_absolute() { args.scene.clone() } else { root.join(&args.scene) };
    let size = args.size;
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out/tradeoff").join(&name));
    std::fs::create_dir_all(&out)?;
    let base = xtask::run::Pipeline::load(&root.join("pipeline.toml"))?;
    let bins = Bins::build(root)?;
    let s = |v: &dyn std::fmt::Display| v.to_string();
    let scene_s = scene.display().to_string();

    // The reference: 4096 paths per pixel, cached by scene content and size.
    let scene_hash = blake3::hash(&std::fs::read(&scene)?).to_hex().to_string();
    let ref_exr = out.join(format!("reference-{size}.exr"));
    let ref_key = out.join(format!("reference-{size}.key"));
    if std::fs::read_to_string(&ref_key).ok().as_deref() != Some(scene_hash.as_str()) || !ref_exr.exists() {
        println!("rendering the reference ({size}x{size}, path tracing, 4096 spp) ...");
        let p = RenderParams { mode: Method::Path, spp: 4096, width: size, height: size, ..base.render.clone() };
        let mut a =
            vec![s(&"--scene"), scene_s.clone(), s(&"--seed"), s(&99), s(&"--out"), ref_exr.display().to_string()];
        a.extend(p.to_args());
        stage::<photon_render::Report>(&bins, "photon-render", &a, &out.join("reference.stats.json"))?;
        std::fs::write(&ref_key, &scene_hash)?;
    }
    let reference = pm_image::read_exr(&ref_exr)?;

    let mut maps: BTreeMap<String, (PathBuf, [f64; 3])> = BTreeMap::new();
    let mut rows: Vec<(Setting, [f64; 4], [f64; 5])> = Vec::new();
    for st in sweep(&base, size) {
        // Photon maps, shared by settings that differ only in rendering.
        let mut times = [0.0f64; 4];
        let mdir = out.join("maps").join(st.maps_key());
        let photon_mapping = st.render.mode != Method::Path;
        if photon_mapping {
            if !maps.contains_key(&st.maps_key()) {
                std::fs::create_dir_all(&mdir)?;
                let o = |f: &str| mdir.join(f).display().to_string();
                let mut a = vec![s(&"--scene"), scene_s.clone(), s(&"--out"), mdir.display().to_string()];
                a.extend(st.trace.to_args());
                let t: photon_trace::Report = stage(&bins, "photon-trace", &a, &mdir.join("trace.json"))?;
                let mut sort = 0.0;
                for m in ["global", "caustic"] {
                    if Path::new(&o(&format!("{m}.pmap"))).exists() {
                        let a = [o(&format!("{m}.pmap")), s(&"--out"), o(&format!("{m}.kd.pmap"))];
                        let r: photon_sort::Report = stage(&bins, "photon-sort", &a, &mdir.join("sort.json"))?;
                        sort += r.seconds;
                    }
                }
                let mut a = vec![o("global.kd.pmap"), s(&"--out"), o("global.irr.pmap")];
                a.extend(st.irradiance.to_args());
                let i: photon_irradiance::Report = stage(&bins, "photon-irradiance", &a, &mdir.join("irr.json"))?;
                maps.insert(st.maps_key(), (mdir.clone(), [t.seconds, sort, i.seconds]));
            }
            let (_, t) = &maps[&st.maps_key()];
            times[..3].copy_from_slice(t);
        }
        let id = st.label.replace(' ', "_");
        let img = out.join(format!("{id}.exr"));
        let mut a = vec![s(&"--scene"), scene_s.clone(), s(&"--out"), img.display().to_string()];
        a.extend(st.render.to_args());
        if photon_mapping {
            a.extend([s(&"--global"), mdir.join("global.irr.pmap").display().to_string()]);
            if mdir.join("caustic.kd.pmap").exists() {
                a.extend([s(&"--caustic"), mdir.join("caustic.kd.pmap").display().to_string()]);
            }
        }
        let r: photon_render::Report = stage(&bins, "photon-render", &a, &out.join(format!("{id}.stats.json")))?;
        times[3] = r.seconds;
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
    let colour = |axis: &str| plot::PALETTE[axes.iter().position(|a| *a == axis).unwrap_or(0) % plot::PALETTE.len()];
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
    plot::draw(&shapes, w, h, &out.join("plot.svg"), &out.join("plot.png"))
}
