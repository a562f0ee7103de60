//! `cargo xtask scale`: what input at scale costs each stage (issue 14, section 4).
//! Runs the pipeline's steps one by one, each under `/usr/bin/time` (GNU time, for
//! the process's peak resident memory), and reports per step its wall time, peak
//! memory, and the scene load and BVH build times the stage prints.

use anyhow::{Context, Result, bail};
use pm_runner::bins::Bins;
use pm_runner::run::RunArgs;
use std::path::Path;
use std::process::Command;

/// Options of `cargo xtask scale`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    run: RunArgs,
}

/// One step's measurements.
struct Row {
    step: String,
    wall: f64,
    peak_mb: f64,
    load: Option<(u64, f64, f64)>,
}

/// Run and report.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    let time = Path::new("/usr/bin/time");
    if !time.exists() {
        bail!("/usr/bin/time (GNU time) is needed for peak memory: install Debian's `time` package");
    }
    let bins = Bins::build(root)?;
    let plan = pm_runner::run::plan_for(&args.run, root, &bins)?;
    std::fs::create_dir_all(&plan.out).with_context(|| format!("{}: cannot create", plan.out))?;
    let mut rows = Vec::new();
    for step in &plan.steps {
        if step.tasks != 1 {
            bail!("step {} has {} tasks: measure without --tiles or --trace-slices", step.name, step.tasks);
        }
        let out = Command::new(time)
            .args(["-f", "peak-rss-kb %M wall-s %e", &step.program])
            .args(&step.args)
            .output()
            .with_context(|| format!("cannot start {}", step.program))?;
        let stderr = String::from_utf8_lossy(&out.stderr);
        if !out.status.success() {
            let last = stderr.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("");
            bail!("stage {} failed: {last}", step.name);
        }
        let field = |key: &str| -> Option<f64> {
            let line = stderr.lines().rev().find(|l| l.starts_with("peak-rss-kb"))?;
            let mut it = line.split_whitespace();
            while let Some(k) = it.next() {
                if k == key {
                    return it.next()?.parse().ok();
                }
            }
            None
        };
        // "<stage>: scene loaded: N triangles, T textures in X s (BVH Y s)"
        let load = stderr.lines().find(|l| l.contains("scene loaded:")).and_then(|l| {
            let nums: Vec<f64> = l
                .split(|c: char| !(c.is_ascii_digit() || c == '.'))
                .filter(|s| !s.is_empty() && s.chars().any(|c| c.is_ascii_digit()))
                .filter_map(|s| s.parse().ok())
                .collect();
            (nums.len() >= 4).then(|| (nums[0] as u64, nums[2], nums[3]))
        });
        let row = Row {
            step: step.name.clone(),
            wall: field("wall-s").unwrap_or(f64::NAN),
            peak_mb: field("peak-rss-kb").unwrap_or(f64::NAN) / 1024.0,
            load,
        };
        println!("  {}: {:.2} s, peak {:.0} MB", row.step, row.wall, row.peak_mb);
        rows.push(row);
    }
    println!(
        "\n| step | wall time [s] | peak memory [MB] | scene load [s] | of which BVH [s] |\n|---|---|---|---|---|"
    );
    for r in &rows {
        let (load, bvh) = match r.load {
            Some((tris, l, b)) => (format!("{l:.2} ({tris} triangles)"), format!("{b:.2}")),
            None => ("-".into(), "-".into()),
        };
        println!("| {} | {:.2} | {:.0} | {load} | {bvh} |", r.step, r.wall, r.peak_mb);
    }
    Ok(())
}
