//! `cargo xtask plan`: the pipeline as a job graph for machines other than this one
//! ([`pm_pipeline::jobs`]), written as `plan.json`, and with `--emit slurm` as sbatch
//! scripts and `submit.sh` or with `--emit openjd` as one Open Job Description
//! template; `--estimate` predicts the wall time on more machines from a run's
//! task times.

use anyhow::{Context, Result};
use pm_pipeline::jobs::{TaskTime, estimate, openjd, slurm};
use pm_runner::run::{LiveArgs, RunArgs, live_plan, plan_for};
use std::path::{Path, PathBuf};

/// Options of `cargo xtask plan`.
#[derive(clap::Args, Debug, Clone)]
// Help texts give units as [m] and [s], not links.
#[allow(rustdoc::broken_intra_doc_links)]
pub struct Args {
    /// Which pipeline, scene, output folder and image size (as `cargo xtask run`).
    #[command(flatten)]
    pub run: RunArgs,
    /// Where to write plan.json and the emitted job files.
    #[arg(long)]
    pub plan_out: PathBuf,
    /// Plan the real-time animation (`cargo xtask live`: photon-live with
    /// pipeline.toml's [live] section on its live_scene) instead of the batch
    /// pipeline: --frame-tasks runs of frames and an assemble step.
    #[arg(long)]
    pub live: bool,
    /// With --live: frames of the animation.
    #[arg(long, default_value_t = 120)]
    pub frames: u32,
    /// With --live: runs of consecutive frames, one array task each.
    #[arg(long, default_value_t = 1)]
    pub frame_tasks: u32,
    /// Also write job files for this system: slurm (sbatch scripts and submit.sh)
    /// or openjd (job.template.json).
    #[arg(long)]
    pub emit: Option<Emit>,
    /// Print the predicted wall time on 1, 2, 4 ... NODES machines from the task
    /// times a `cargo xtask run --tiles N` wrote (OUT/plan-times.json).
    #[arg(long, value_name = "NODES")]
    pub estimate: Option<u32>,
}

/// Job systems the plan can be written for.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Emit {
    /// Slurm: one sbatch script per step, job arrays, afterok dependencies.
    Slurm,
    /// Open Job Description (AWS Deadline Cloud's format): one job template.
    Openjd,
}

/// Write `plan.json` (and the job files) for `args`.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    let bins = args.run.binaries(root)?;
    let plan = if args.live {
        let live = LiveArgs {
            pipeline: args.run.pipeline.clone(),
            scene: args.run.scene.clone(),
            out: args.run.out.clone(),
            frames: args.frames,
            frame_tasks: args.frame_tasks,
            workers: 1,
            method: None,
        };
        live_plan(&live, root, &bins)?
    } else {
        plan_for(&args.run, root, &bins)?
    };
    let dir = &args.plan_out;
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let write = |name: &str, text: &str| -> Result<()> {
        let p = dir.join(name);
        pm_format::write_atomically(&p, |f| std::io::Write::write_all(f, text.as_bytes()))
            .with_context(|| format!("{}: cannot write", p.display()))
    };
    write("plan.json", &(serde_json::to_string_pretty(&plan)? + "\n"))?;
    match args.emit {
        Some(Emit::Slurm) => {
            for (name, text) in slurm(&plan) {
                write(&name, &text)?;
            }
        }
        Some(Emit::Openjd) => write("job.template.json", &(serde_json::to_string_pretty(&openjd(&plan))? + "\n"))?,
        None => {}
    }
    if let Some(nodes) = args.estimate {
        let path = Path::new(&plan.out).join("plan-times.json");
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("{}: cannot read (run `cargo xtask run --tiles N` first)", path.display()))?;
        let times: Vec<TaskTime> =
            serde_json::from_str(&text).with_context(|| format!("{}: not a list of task times", path.display()))?;
        println!("| nodes | predicted wall time [s] | speed-up |\n|---|---|---|");
        let one = estimate(&times, 1);
        let mut n = 1;
        while n <= nodes.max(1) {
            let t = estimate(&times, n);
            println!("| {n} | {t:.2} | {:.2} |", one / t);
            n *= 2;
        }
    }
    println!("plan ({} steps) in {}", plan.steps.len(), dir.display());
    for step in &plan.steps {
        println!(
            "  {}{}{}",
            step.name,
            if step.tasks > 1 { format!(" x {}", step.tasks) } else { String::new() },
            if step.after.is_empty() { String::new() } else { format!(" (after {})", step.after.join(", ")) }
        );
    }
    Ok(())
}
