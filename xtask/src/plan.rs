//! `cargo xtask plan`: the pipeline as a job graph for machines other than this one.
//! The steps `cargo xtask run` executes, with the photon trace cut into
//! `--trace-slices M` array tasks (`photon-trace --slice J/M`) and a merge step, and
//! the final render cut into `--tiles N` array tasks (`photon-render --tile K/N`,
//! each writing its own region EXR) and an assemble step, every step with its command line, inputs, outputs and the steps
//! it waits for (those that write its inputs). Written as `plan.json`, and with
//! `--emit slurm` as sbatch scripts (one job array per parallel step, chained by
//! `--dependency=afterok` in `submit.sh`) or with `--emit openjd` as one Open Job
//! Description template. Assumed: every task sees the same output folder (a shared
//! file system) and the same binaries.

use crate::run::{LiveArgs, RunArgs, Setup, live_setup, plan, setup};
use crate::stages::Bins;
use anyhow::{Context, Result, bail};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Stands for the array task's index in a step's arguments; each executor writes it
/// its own way (a number, `${SLURM_ARRAY_TASK_ID}`, `{{Task.Param.Index}}`).
pub const TASK: &str = "{TASK}";

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

/// A step of the job graph.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct JobStep {
    /// Name, unique in the plan.
    pub name: String,
    /// The program (absolute path).
    pub program: String,
    /// Its arguments; in an array step [`TASK`] stands for the task's index.
    pub args: Vec<String>,
    /// Array tasks (1: a single task).
    pub tasks: u32,
    /// Files it reads.
    pub inputs: Vec<String>,
    /// Files it writes.
    pub outputs: Vec<String>,
    /// Steps that must have finished (they write its inputs).
    pub after: Vec<String>,
}

/// The job graph.
#[derive(Serialize, Clone, Debug)]
pub struct JobPlan {
    /// The output folder every task writes into (shared).
    pub out: String,
    /// Steps in an order that respects `after`.
    pub steps: Vec<JobStep>,
}

/// The job graph of a run with `tiles` tiles and `slices` trace slices.
pub(crate) fn job_plan(setup: &Setup, bins: &Bins, tiles: u32, slices: u32) -> Result<JobPlan> {
    let Setup { cfg, scene, out, caustics, indirect, .. } = setup;
    if tiles == 0 || tiles > cfg.render.height {
        bail!("--tiles {tiles}: needs 1 to the image's {} rows", cfg.render.height);
    }
    if slices == 0 {
        bail!("--trace-slices 0: needs at least 1");
    }
    let s = |p: &Path| p.display().to_string();
    let mut steps: Vec<JobStep> = Vec::new();
    for step in plan(cfg, scene, out, *caustics, *indirect)? {
        // A step whose input the scene does not need (no caustic photons, no global
        // map) is not planned; optional inputs are passed when planned to exist.
        let planned = |p: &PathBuf| steps.iter().any(|j| j.outputs.contains(&s(p))) || !p.starts_with(out);
        if let Some(n) = &step.needs
            && !planned(n)
        {
            continue;
        }
        let mut args = step.args.clone();
        let mut inputs: Vec<String> = step.inputs.iter().filter(|p| planned(p)).map(|p| s(p)).collect();
        for (flag, file) in &step.optional {
            if planned(file) {
                args.extend([flag.to_string(), s(file)]);
                inputs.push(s(file));
            }
        }
        let program = s(&bins.path(step.program()));
        if step.name == "photon-trace" && slices > 1 {
            // The trace as interleaved slices of the emission index space, each into
            // its own folder, then merged into the maps one trace writes.
            let dir = |k: &str| out.join("slices").join(format!("slice-{k}"));
            let mut base = without(&args, &["--out", "--stats-json"]);
            base.extend(["--slice".into(), format!("{TASK}/{slices}"), "--out".into(), s(&dir(TASK))]);
            base.extend(["--stats-json".into(), s(&dir(TASK).join("trace.stats.json"))]);
            let maps: Vec<&str> =
                step.outputs.iter().filter_map(|p| p.file_name()?.to_str()).filter(|n| n.ends_with(".pmap")).collect();
            let slice_outputs: Vec<String> =
                (0..slices).flat_map(|k| maps.iter().map(move |m| s(&dir(&k.to_string()).join(m)))).collect();
            steps.push(JobStep {
                name: "photon-trace slices".into(),
                program: program.clone(),
                args: base,
                tasks: slices,
                inputs: inputs.clone(),
                outputs: slice_outputs.clone(),
                after: vec![],
            });
            let mut a = vec!["merge".to_string()];
            a.extend((0..slices).map(|k| s(&dir(&k.to_string()))));
            a.extend(["--out".into(), s(out), "--stats-json".into(), s(&out.join("trace.stats.json"))]);
            steps.push(JobStep {
                name: "photon-trace merge".into(),
                program,
                args: a,
                tasks: 1,
                inputs: slice_outputs,
                outputs: step.outputs.iter().map(|p| s(p)).collect(),
                after: vec![],
            });
        } else if step.name == "photon-render" && tiles > 1 {
            // The render as tiles: its --out/--png/--stats-json replaced per task.
            let mut base = without(&args, &["--out", "--png", "--stats-json"]);
            let tile = |k: &str, ext: &str| s(&out.join("tiles").join(format!("tile-{k}.{ext}")));
            base.extend([
                "--tile".into(),
                format!("{TASK}/{tiles}"),
                "--out".into(),
                tile(TASK, "exr"),
                "--stats-json".into(),
                tile(TASK, "stats.json"),
            ]);
            let tile_outputs: Vec<String> = (0..tiles).map(|k| tile(&k.to_string(), "exr")).collect();
            steps.push(JobStep {
                name: "photon-render tiles".into(),
                program,
                args: base,
                tasks: tiles,
                inputs: inputs.clone(),
                outputs: tile_outputs.clone(),
                after: vec![],
            });
            let mut a = vec!["assemble".to_string()];
            a.extend(tile_outputs.iter().cloned());
            a.extend(["--out".into(), s(&out.join("image.exr")), "--png".into(), s(&out.join("image.png"))]);
            a.extend(["--exposure".into(), cfg.render.exposure.to_string()]);
            steps.push(JobStep {
                name: "assemble".into(),
                program: s(&bins.path("xtask")),
                args: a,
                tasks: 1,
                inputs: tile_outputs,
                outputs: vec![s(&out.join("image.exr")), s(&out.join("image.png"))],
                after: vec![],
            });
        } else {
            steps.push(JobStep {
                name: step.name.clone(),
                program,
                args,
                tasks: 1,
                inputs,
                outputs: step.outputs.iter().map(|p| s(p)).collect(),
                after: vec![],
            });
        }
    }
    // Each step waits for the steps that write its inputs.
    for i in 0..steps.len() {
        let after: Vec<String> = steps[..i]
            .iter()
            .filter(|j| j.outputs.iter().any(|o| steps[i].inputs.contains(o)))
            .map(|j| j.name.clone())
            .collect();
        steps[i].after = after;
    }
    Ok(JobPlan { out: s(out), steps })
}

/// `args` without the options `flags` and their values (an array step replaces
/// them per task).
fn without(args: &[String], flags: &[&str]) -> Vec<String> {
    let mut kept = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if flags.contains(&a.as_str()) {
            it.next();
        } else {
            kept.push(a.clone());
        }
    }
    kept
}

/// Wall time of one task of a run \[s\].
#[derive(Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct TaskTime {
    /// The step.
    pub step: String,
    /// Array tasks of the step (1: a single task).
    pub tasks: u32,
    /// This task's index.
    pub task: u32,
    /// Its wall time \[s\].
    pub seconds: f64,
}

/// Run the plan on this machine, step after step; an array step's tasks `workers`
/// at a time, each with its index for [`TASK`]. A failing task stops the run with
/// one line naming the step and task, and every earlier output stays. Returns each
/// task's wall time and the whole run's \[s\].
pub fn execute(plan: &JobPlan, workers: u32) -> Result<(Vec<TaskTime>, f64)> {
    let start = std::time::Instant::now();
    let mut times = Vec::new();
    for step in &plan.steps {
        let run_task = |k: u32| -> Result<TaskTime> {
            let args: Vec<String> = step.args.iter().map(|a| a.replace(TASK, &k.to_string())).collect();
            let name =
                if step.tasks > 1 { format!("{} (task {k} of {})", step.name, step.tasks) } else { step.name.clone() };
            let t = std::time::Instant::now();
            crate::stages::run_program(Path::new(&step.program), &args, &name, true)
                .map_err(|e| anyhow::anyhow!("{e}; earlier outputs in {} are intact", plan.out))?;
            let seconds = t.elapsed().as_secs_f64();
            println!("  {name}: done in {seconds:.2} s");
            Ok(TaskTime { step: step.name.clone(), tasks: step.tasks, task: k, seconds })
        };
        // Tasks in waves of `workers`, each wave's processes side by side.
        let ks: Vec<u32> = (0..step.tasks).collect();
        for wave in ks.chunks(workers.max(1) as usize) {
            let results: Vec<Result<TaskTime>> = std::thread::scope(|sc| {
                let handles: Vec<_> = wave.iter().map(|&k| sc.spawn(move || run_task(k))).collect();
                handles.into_iter().map(|h| h.join().expect("a task thread panicked")).collect()
            });
            for r in results {
                times.push(r?);
            }
        }
    }
    Ok((times, start.elapsed().as_secs_f64()))
}

/// [`execute`], then write each task's time to OUT/plan-times.json (what
/// `cargo xtask plan --estimate` reads).
pub fn execute_and_record(plan: &JobPlan, workers: u32) -> Result<(Vec<TaskTime>, f64)> {
    let (times, wall) = execute(plan, workers)?;
    let path = Path::new(&plan.out).join("plan-times.json");
    let text = serde_json::to_string_pretty(&times)? + "\n";
    pm_format::write_atomically(&path, |f| std::io::Write::write_all(f, text.as_bytes()))
        .with_context(|| format!("{}: cannot write", path.display()))?;
    Ok((times, wall))
}

/// Predicted wall time \[s\] of the plan's measured `times` on `nodes` machines: the
/// single-task steps one after another, each array step in ceil(tasks / nodes)
/// waves of its mean task time (the model behind `cargo xtask plan --estimate`).
pub fn estimate(times: &[TaskTime], nodes: u32) -> f64 {
    let mut steps: Vec<(&str, u32)> = Vec::new();
    for t in times {
        if !steps.iter().any(|s| s.0 == t.step) {
            steps.push((&t.step, t.tasks));
        }
    }
    steps
        .iter()
        .map(|&(name, tasks)| {
            let own: Vec<f64> = times.iter().filter(|t| t.step == name).map(|t| t.seconds).collect();
            let mean = own.iter().sum::<f64>() / own.len().max(1) as f64;
            mean * tasks.div_ceil(nodes.max(1)) as f64
        })
        .sum()
}

/// Quote a word for bash (single quotes; a quote inside becomes '\'').
fn sh(word: &str) -> String {
    format!("'{}'", word.replace('\'', r"'\''"))
}

/// A file name for a step: its position and name, e.g. `03-photon-irradiance`.
fn file_stem(i: usize, step: &JobStep) -> String {
    format!("{i:02}-{}", step.name.replace(' ', "-"))
}

/// The sbatch scripts (one per step) and `submit.sh`, as (file name, text).
pub fn slurm(plan: &JobPlan) -> Vec<(String, String)> {
    let mut files = Vec::new();
    let mut submit = String::from(
        "#!/bin/bash\n# Submit the photon-mapping job graph to Slurm, each step after the steps it waits for.\nset -euo pipefail\ncd \"$(dirname \"$0\")\"\nmkdir -p logs\n",
    );
    for (i, step) in plan.steps.iter().enumerate() {
        let stem = file_stem(i, step);
        let mut t = String::from("#!/bin/bash\n");
        let _ = writeln!(t, "#SBATCH --job-name=pm-{}", step.name.replace(' ', "-"));
        let _ = writeln!(t, "#SBATCH --output=logs/{stem}-%A_%a.log");
        if step.tasks > 1 {
            let _ = writeln!(t, "#SBATCH --array=0-{}", step.tasks - 1);
        }
        let _ = writeln!(
            t,
            "# {}: waits for {}",
            step.name,
            if step.after.is_empty() { "nothing".into() } else { step.after.join(", ") }
        );
        t.push_str("set -euo pipefail\nTASK=\"${SLURM_ARRAY_TASK_ID:-0}\"\n");
        let args: Vec<String> = step.args.iter().map(|a| sh(a).replace(TASK, "'\"${TASK}\"'")).collect();
        let _ = writeln!(t, "exec {} {}", sh(&step.program), args.join(" "));
        files.push((format!("{stem}.sbatch"), t));
        let deps: Vec<String> = step
            .after
            .iter()
            .map(|a| format!("${{job_{}}}", plan.steps.iter().position(|s| &s.name == a).expect("after names a step")))
            .collect();
        let dep = if deps.is_empty() { String::new() } else { format!(" --dependency=afterok:{}", deps.join(":")) };
        let _ = writeln!(submit, "job_{i}=$(sbatch --parsable{dep} {stem}.sbatch)");
        let _ = writeln!(submit, "echo \"{}: job ${{job_{i}}}\"", step.name);
    }
    files.push(("submit.sh".into(), submit));
    files
}

/// One Open Job Description template (JSON is YAML's subset; `openjd check` reads it).
pub fn openjd(plan: &JobPlan) -> serde_json::Value {
    let steps: Vec<serde_json::Value> = plan
        .steps
        .iter()
        .map(|step| {
            let args: Vec<String> = step.args.iter().map(|a| a.replace(TASK, "{{Task.Param.Index}}")).collect();
            let mut v = serde_json::json!({
                "name": step.name,
                "script": {"actions": {"onRun": {"command": step.program, "args": args}}},
            });
            if step.tasks > 1 {
                v["parameterSpace"] = serde_json::json!({
                    "taskParameterDefinitions": [{"name": "Index", "type": "INT", "range": format!("0-{}", step.tasks - 1)}]
                });
            }
            if !step.after.is_empty() {
                v["dependencies"] = serde_json::Value::Array(
                    step.after.iter().map(|a| serde_json::json!({"dependsOn": a})).collect(),
                );
            }
            v
        })
        .collect();
    serde_json::json!({
        "specificationVersion": "jobtemplate-2023-09",
        "name": format!("photon map {}", plan.out),
        "steps": steps,
    })
}

/// The job graph of `args` (its pipeline, scene, output, `tiles` and
/// `trace_slices`), with the stage binaries in `bins`.
pub fn plan_for(args: &RunArgs, root: &Path, bins: &Bins) -> Result<JobPlan> {
    let setup = setup(args, root, bins)?;
    job_plan(&setup, bins, args.tiles.max(1), args.trace_slices.max(1))
}

/// The job graph of the real-time animation `args` describes: `frame_tasks` runs
/// of frames (array tasks, `photon-live --frame-task K/N`; each simulates the
/// frames before its own without drawing, so it draws what one run draws) and
/// `photon-live assemble` (live.apng, frames.csv).
pub fn live_plan(args: &LiveArgs, root: &Path, bins: &Bins) -> Result<JobPlan> {
    let n = args.frame_tasks;
    if n == 0 || n > args.frames {
        bail!("--frame-tasks {n}: needs 1 to the animation's {} frames", args.frames);
    }
    let set = live_setup(args, root)?;
    let out = &set.out;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let s = |p: &Path| p.display().to_string();
    let program = s(&bins.path("photon-live"));
    let frames = |k: u32| pm_live::task_frames(k, n, args.frames);
    let part = |k: u32| out.join("frames").join(pm_live::frames_part_file(&frames(k)));
    let pngs: Vec<String> = (0..args.frames).map(|f| s(&out.join("frames").join(format!("{f:04}.png")))).collect();
    let mut task_outputs = pngs.clone();
    task_outputs.extend((0..n).map(|k| s(&part(k))));
    let mut task_args = set.args.clone();
    task_args.extend(["--frame-task".into(), format!("{TASK}/{n}")]);
    let assemble = vec![
        "assemble".to_string(),
        "--out".into(),
        s(out),
        "--frames".into(),
        args.frames.to_string(),
        "--fps".into(),
        set.fps.to_string(),
    ];
    let steps = vec![
        JobStep {
            name: "photon-live frames".into(),
            program: program.clone(),
            args: task_args,
            tasks: n,
            inputs: vec![],
            outputs: task_outputs.clone(),
            after: vec![],
        },
        JobStep {
            name: "photon-live assemble".into(),
            program,
            args: assemble,
            tasks: 1,
            inputs: task_outputs,
            outputs: vec![s(&out.join("live.apng")), s(&out.join("frames.csv"))],
            after: vec!["photon-live frames".into()],
        },
    ];
    Ok(JobPlan { out: s(out), steps })
}

/// Write `plan.json` (and the job files) for `args`.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    let bins = Bins::build(root)?;
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
