//! `cargo xtask live-study`: what the real-time mode's settings cost and buy
//! (Jozwowski 2002, Figures 21-27): frame time split into shoot, balance, estimate
//! and draw against per_frame, total, max_level and the surface count, with and
//! without cornering, culling and the photon proxy; and flicker and error against
//! the batch pipeline's image for each distribution and total, against frame time.
//! Writes results.csv, results.md and SVG/PNG plots.

use crate::plot;
use anyhow::{Context, Result};
use pm_runner::bins::{self, Bins};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options of `cargo xtask live-study`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder [default: out/live-study].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Frames per run (the means leave out the warm-up frames).
    #[arg(long, default_value_t = 40)]
    frames: u32,
}

/// One run's means after warm-up.
#[derive(Clone, Debug, Default)]
struct Row {
    sweep: &'static str,
    label: String,
    x: f64,
    /// shoot, balance, estimate, draw, total [ms]
    ms: [f64; 5],
    flicker: f64,
    error: Option<f64>,
}

fn room(n: u32, root: &Path) -> String {
    root.join(format!("scenes/jozwowski_room_{n}.gltf")).display().to_string()
}

/// Run photon-live quietly and read its frames.csv into the means after warm-up.
fn run_live(bins: &Bins, dir: &Path, args: &[String], warmup: usize) -> Result<([f64; 5], f64)> {
    let mut a = args.to_vec();
    a.extend(["--out".into(), dir.display().to_string()]);
    bins::run(bins, "photon-live", &a, "photon-live", true)?;
    let csv =
        std::fs::read_to_string(dir.join("frames.csv")).with_context(|| format!("{}: frames.csv", dir.display()))?;
    let rows = pm_live::rows_from_csv::<pm_vertex::VertexFrame>(&csv)
        .map_err(|e| anyhow::anyhow!("{}: frames.csv: {e}", dir.display()))?;
    let kept = &rows[warmup.min(rows.len().saturating_sub(1))..];
    let n = kept.len().max(1) as f64;
    let mean = |f: fn(&pm_vertex::VertexFrame) -> f64| kept.iter().map(f).sum::<f64>() / n;
    let ms =
        [mean(|r| r.shoot_s), mean(|r| r.balance_s), mean(|r| r.estimate_s), mean(|r| r.draw_s), mean(|r| r.total_s)];
    Ok((ms.map(|v| 1e3 * v), mean(|r| r.flicker)))
}

/// Run the study.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    let out = args.out.clone().unwrap_or_else(|| root.join("out/live-study"));
    std::fs::create_dir_all(&out)?;
    let bins = Bins::build(root)?;
    let frames = args.frames.to_string();
    let s = |v: &dyn std::fmt::Display| v.to_string();
    let base = |scene: String, per_frame: u32, total: u32| {
        vec![
            s(&"--scene"),
            scene,
            s(&"--frames"),
            frames.clone(),
            s(&"--per-frame"),
            s(&per_frame),
            s(&"--total"),
            s(&total),
        ]
    };
    let mut rows = Vec::new();
    let mut go = |sweep: &'static str, label: String, x: f64, a: Vec<String>, warmup: usize| -> Result<()> {
        let dir = out.join("runs").join(label.replace([' ', '='], "_"));
        let (ms, flicker) = run_live(&bins, &dir, &a, warmup)?;
        println!(
            "  {sweep:<12} {label:<28} {:>7.2} ms  (shoot {:.2}, balance {:.2}, estimate {:.2}, draw {:.2})",
            ms[4], ms[0], ms[1], ms[2], ms[3]
        );
        rows.push(Row { sweep, label, x, ms, flicker, error: None });
        Ok(())
    };
    let warm = |per_frame: u32, total: u32| total.div_ceil(per_frame) as usize;
    println!("frame time (512 x 512, 2 cores):");
    for pf in [500u32, 1000, 2000, 4000, 8000] {
        go("per_frame", format!("per_frame {pf}"), pf as f64, base(room(1024, root), pf, 20_000), warm(pf, 20_000))?;
    }
    for total in [5_000u32, 10_000, 20_000, 40_000] {
        go("total", format!("total {total}"), total as f64, base(room(1024, root), total / 10, total), 10)?;
    }
    for ml in [1u32, 2, 3, 5, 8] {
        let mut a = base(room(1024, root), 2000, 20_000);
        a.extend([s(&"--max-level"), s(&ml)]);
        go("max_level", format!("max_level {ml}"), ml as f64, a, 10)?;
    }
    for n in [16u32, 64, 256, 1024, 4096] {
        go("surfaces", format!("surfaces {n}"), n as f64, base(room(n, root), 2000, 20_000), 10)?;
    }
    for (k, (label, extra)) in [
        ("defaults", vec![]),
        ("no cornering", vec![s(&"--cornering"), s(&false)]),
        ("no culling", vec![s(&"--back-face-culling"), s(&false), s(&"--frustum-culling"), s(&false)]),
        ("photon proxy boxes", vec![s(&"--photon-proxy"), s(&"boxes")]),
        ("direct from photons", vec![s(&"--direct"), s(&"photons")]),
        ("eye rays, no raster", vec![s(&"--draw"), s(&"rays")]),
    ]
    .into_iter()
    .enumerate()
    {
        let mut a = base(room(4096, root), 2000, 20_000);
        a.extend(extra);
        go("options", label.to_string(), k as f64, a, 10)?;
    }
    // Accuracy: a static light (time 0) against the batch pipeline's image.
    println!("reference: the batch pipeline on jozwowski_room_1024 at 512 x 512 ...");
    let reference_dir = out.join("reference");
    let run_args = pm_runner::run::RunArgs {
        scene: Some(PathBuf::from(room(1024, root))),
        out: Some(reference_dir.clone()),
        width: Some(512),
        height: Some(512),
        ..Default::default()
    };
    pm_runner::run::run_with(&run_args, root, &bins)?;
    let reference = pm_image::read_exr(&reference_dir.join("image.exr"))?;
    let reference = reference.total().context("reference has no total layer")?.to_vec();
    println!("accuracy (static light):");
    for dist in ["same-over-total", "same-per-frame", "random"] {
        for total in [5_000u32, 20_000, 40_000] {
            let label = format!("{dist} {total}");
            let dir = out.join("runs").join(label.replace(' ', "_"));
            let mut a = base(room(1024, root), total / 10, total);
            a.extend([s(&"--distribution"), s(&dist), s(&"--time"), s(&0.0), s(&"--exr")]);
            let (ms, flicker) = run_live(&bins, &dir, &a, 10)?;
            let last = dir.join(format!("frames/{:04}.exr", args.frames - 1));
            let img = pm_image::read_exr(&last)?;
            let e = pm_image::compare(img.total().context("no total layer")?, &reference, f32::INFINITY);
            println!(
                "  {label:<24} {:>7.2} ms  flicker {flicker:.4}  relative RMSE {:.4}  bias {:+.4}",
                ms[4], e.rel_rmse, e.rel_bias
            );
            rows.push(Row { sweep: "accuracy", label, x: total as f64, ms, flicker, error: Some(e.rel_rmse) });
        }
    }
    // The bias of keeping max_level hits per path (higher bounces are dropped).
    for ml in [2u32, 3, 5, 8, 16] {
        let label = format!("max_level {ml} (static)");
        let dir = out.join("runs").join(format!("bias_max_level_{ml}"));
        let mut a = base(room(1024, root), 2000, 20_000);
        a.extend([s(&"--max-level"), s(&ml), s(&"--time"), s(&0.0), s(&"--exr")]);
        let (ms, flicker) = run_live(&bins, &dir, &a, 10)?;
        let img = pm_image::read_exr(&dir.join(format!("frames/{:04}.exr", args.frames - 1)))?;
        let e = pm_image::compare(img.total().context("no total layer")?, &reference, f32::INFINITY);
        println!("  {label:<24} {:>7.2} ms  relative RMSE {:.4}  bias {:+.4}", ms[4], e.rel_rmse, e.rel_bias);
        rows.push(Row { sweep: "bias", label, x: ml as f64, ms, flicker, error: Some(e.rel_rmse) });
    }
    write(&out, &rows)
}

fn write(out: &Path, rows: &[Row]) -> Result<()> {
    let mut csv = String::from(
        "sweep,setting,x,shoot_ms,balance_ms,estimate_ms,draw_ms,total_ms,fps,flicker,rel_rmse_vs_batch\n",
    );
    let mut md = String::from(
        "| sweep | setting | shoot | balance | estimate | draw | frame [ms] | fps | flicker | rel. RMSE vs batch |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        // The same cells in both tables (the CSV also has the swept value).
        let mut cells = vec![r.sweep.to_string(), r.label.clone()];
        cells.extend(r.ms.iter().map(|m| format!("{m:.3}")));
        cells.push(format!("{:.2}", 1e3 / r.ms[4].max(1e-9)));
        cells.push(format!("{:.5}", r.flicker));
        cells.push(r.error.map_or(String::new(), |e| format!("{e:.4}")));
        let mut with_x = cells.clone();
        with_x.insert(2, r.x.to_string());
        writeln!(csv, "{}", with_x.join(","))?;
        writeln!(md, "| {} |", cells.join(" | "))?;
    }
    std::fs::write(out.join("results.csv"), csv)?;
    std::fs::write(out.join("results.md"), &md)?;
    let parts = ["shoot", "balance", "estimate", "draw", "total"];
    for (sweep, x_label, log_x) in [
        ("per_frame", "photon paths shot per frame", true),
        ("total", "photon paths in the ring buffer", true),
        ("max_level", "hits kept per path (max_level)", false),
        ("surfaces", "surfaces in the scene", true),
    ] {
        let sel: Vec<&Row> = rows.iter().filter(|r| r.sweep == sweep).collect();
        let series: Vec<(String, Vec<(f64, f64)>)> =
            (0..5).map(|k| (parts[k].to_string(), sel.iter().map(|r| (r.x, r.ms[k])).collect())).collect();
        let shapes = plot::line_chart(
            &format!("frame time against {sweep} (jozwowski_room, 512 x 512, 2 cores)"),
            x_label,
            "milliseconds per frame",
            log_x,
            &series,
            900.0,
            520.0,
        );
        plot::draw(
            &shapes,
            900.0,
            520.0,
            &out.join(format!("time_{sweep}.svg")),
            &out.join(format!("time_{sweep}.png")),
        )?;
    }
    let acc: Vec<&Row> = rows.iter().filter(|r| r.sweep == "accuracy").collect();
    let mut series = Vec::new();
    for dist in ["same-over-total", "same-per-frame", "random"] {
        let pts: Vec<(f64, f64)> =
            acc.iter().filter(|r| r.label.starts_with(dist)).map(|r| (r.ms[4], r.error.unwrap_or(0.0))).collect();
        series.push((format!("{dist}: error"), pts));
        let pts: Vec<(f64, f64)> =
            acc.iter().filter(|r| r.label.starts_with(dist)).map(|r| (r.ms[4], r.flicker)).collect();
        series.push((format!("{dist}: flicker"), pts));
    }
    let shapes = plot::line_chart(
        "what accuracy costs: error vs the batch image and flicker, by distribution (total 5k, 20k, 40k)",
        "milliseconds per frame",
        "relative RMSE / flicker",
        false,
        &series,
        1000.0,
        560.0,
    );
    plot::draw(&shapes, 1000.0, 560.0, &out.join("accuracy.svg"), &out.join("accuracy.png"))?;
    println!("\n{md}\nwrote {}", out.display());
    Ok(())
}
