//! The pipeline as a job graph for machines other than this one: the steps
//! [`crate::steps`] makes, with the photon trace cut into `slices` array tasks
//! (`photon-trace --slice J/M`) and a merge step, and the final render cut into
//! `tiles` array tasks (`photon-render --tile K/N`, each writing its own region EXR)
//! and an assemble step; progressive photon mapping as `runs` independent runs
//! (`photon-render --run K/N`, each with its own seed and resumable state) and a
//! step that averages their images; an animation (`frames` in pipeline.toml) as
//! every step an array of one task per frame, each frame's maps and image in its
//! own folder `frame-F/`; or the real-time animation as runs of frames
//! and an assemble step. Every step has its command line, inputs, outputs and the steps it
//! waits for (those that write its inputs). Written as Slurm sbatch scripts (one
//! job array per parallel step, chained by `--dependency=afterok` in `submit.sh`)
//! or as one Open Job Description template. Assumed: every task sees the same
//! output folder (a shared file system) and the same binaries.

use crate::Setup;
use crate::steps::{Kind, steps};
use anyhow::{Result, bail};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Stands for the array task's index in a step's arguments; each executor writes it
/// its own way (a number, `${SLURM_ARRAY_TASK_ID}`, `{{Task.Param.Index}}`).
pub const TASK: &str = "{TASK}";

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
    /// The first task's index (its [`TASK`]); the tasks are `first_task` to
    /// `first_task + tasks - 1`. 0 but for an animation's frame tasks, whose
    /// index is the frame.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub first_task: u32,
    /// Files it reads.
    pub inputs: Vec<String>,
    /// Files it writes.
    pub outputs: Vec<String>,
    /// Steps that must have finished (they write its inputs).
    pub after: Vec<String>,
    /// A task that exits with code 75 (`pm_stage::EXIT_UNFINISHED`) stopped at
    /// its time budget with its state saved: running it again continues it (a
    /// Slurm task re-queues itself; `cargo xtask run` runs it again).
    pub resumable: bool,
}

impl JobStep {
    /// A step of `tasks` array tasks (1: a single task), waiting for nothing yet.
    fn array(
        name: &str,
        program: &str,
        args: Vec<String>,
        tasks: u32,
        inputs: Vec<String>,
        outputs: Vec<String>,
    ) -> Self {
        JobStep {
            name: name.into(),
            program: program.into(),
            args,
            tasks,
            first_task: 0,
            inputs,
            outputs,
            after: vec![],
            resumable: false,
        }
    }
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

impl JobStep {
    /// Its tasks' indices.
    pub fn task_indices(&self) -> std::ops::Range<u32> {
        self.first_task..self.first_task + self.tasks
    }

    /// True when it is an array of tasks, each given its index (one frame task
    /// is one too: its index is the frame).
    pub fn is_array(&self) -> bool {
        self.tasks > 1 || self.first_task > 0
    }
}

/// The job graph.
#[derive(Serialize, Clone, Debug)]
pub struct JobPlan {
    /// The output folder every task writes into (shared).
    pub out: String,
    /// Steps in an order that respects `after`.
    pub steps: Vec<JobStep>,
}

impl JobPlan {
    /// The plan of `steps` (in an order where a step's inputs are written before
    /// it) into `out`, each step waiting for the steps that write its inputs.
    fn new(out: String, mut steps: Vec<JobStep>) -> JobPlan {
        for i in 0..steps.len() {
            let after: Vec<String> = steps[..i]
                .iter()
                .filter(|j| j.outputs.iter().any(|o| steps[i].inputs.contains(o)))
                .map(|j| j.name.clone())
                .collect();
            steps[i].after = after;
        }
        JobPlan { out, steps }
    }
}

/// How a plan cuts the work into array tasks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Parts {
    /// Render tiles (bands of rows).
    pub tiles: u32,
    /// Trace slices of the emission index space.
    pub slices: u32,
    /// Progressive photon mapping: independent runs averaged into the image.
    pub runs: u32,
    /// Progressive photon mapping: each run stops after this many seconds with
    /// its state saved and is run again from it (None: each run in one go).
    pub run_budget_s: Option<f64>,
}

impl Default for Parts {
    fn default() -> Self {
        Parts { tiles: 1, slices: 1, runs: 1, run_budget_s: None }
    }
}

/// The job graph of `setup` cut into `parts`; `program(name)` is where the
/// binary `name` is (the stages, and `xtask` for the assemble step).
pub fn job_plan(setup: &Setup, program: &dyn Fn(&str) -> PathBuf, parts: Parts) -> Result<JobPlan> {
    let Setup { cfg, scene, out, caustics, indirect, volume, .. } = setup;
    let Parts { tiles, slices, runs, run_budget_s } = parts;
    // An animation: every step an array of one task per frame, each frame in its
    // own folder with its own photon maps, the stages that load the scene posed
    // at --frame TASK.
    let frames = cfg.frames.map(|[first, last]| (first, last - first + 1));
    if frames.is_some() && parts != Parts::default() {
        bail!("frames: an animation is planned as one task per frame; leave out --tiles, --trace-slices and --runs");
    }
    let frame_dir = out.join(format!("frame-{TASK}"));
    let out: &Path = if frames.is_some() { &frame_dir } else { out };
    if tiles == 0 || tiles > cfg.render.height {
        bail!("--tiles {tiles}: needs 1 to the image's {} rows", cfg.render.height);
    }
    if slices == 0 {
        bail!("--trace-slices 0: needs at least 1");
    }
    let sppm = cfg.mode.needs().progressive;
    if runs == 0 || (runs > 1 || run_budget_s.is_some()) && !sppm {
        bail!(
            "--runs {runs}: independent runs are progressive photon mapping's (render mode sppm), and need at least 1"
        );
    }
    if sppm && tiles > 1 {
        bail!(
            "--tiles {tiles}: progressive photon mapping traces the whole image every pass; cut it into --runs instead"
        );
    }
    if let Some(b) = run_budget_s
        && !(b.is_finite() && b > 0.0)
    {
        bail!("--run-time-budget {b}: give a positive number of seconds");
    }
    let s = |p: &Path| p.display().to_string();
    // `cargo xtask assemble [how] PARTS` into image.exr and image.png: tiles
    // joined, or runs averaged.
    let assemble = |name: &str, how: &[&str], parts: Vec<String>| {
        let mut a = vec!["assemble".to_string()];
        a.extend(how.iter().map(|w| w.to_string()));
        a.extend(parts.iter().cloned());
        a.extend(["--out".into(), s(&out.join("image.exr")), "--png".into(), s(&out.join("image.png"))]);
        a.extend(["--exposure".into(), cfg.render.exposure.to_string()]);
        let images = vec![s(&out.join("image.exr")), s(&out.join("image.png"))];
        JobStep::array(name, &s(&program("xtask")), a, 1, parts, images)
    };
    let mut jobs: Vec<JobStep> = Vec::new();
    for step in steps(cfg, scene, out, *caustics, *indirect, *volume)? {
        // A step whose input the scene does not need (no caustic photons, no global
        // map) is not planned; optional inputs are passed when planned to exist.
        let planned = |p: &PathBuf| jobs.iter().any(|j| j.outputs.contains(&s(p))) || !p.starts_with(out);
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
        let bin = s(&program(step.program()));
        let outputs: Vec<String> = step.outputs.iter().map(|p| s(p)).collect();
        match step.kind {
            Kind::Trace if slices > 1 => {
                // The trace as interleaved slices of the emission index space, each
                // into its own folder, then merged into the maps one trace writes.
                let dir = |k: &str| out.join("slices").join(format!("slice-{k}"));
                args.extend(["--slice".into(), format!("{TASK}/{slices}"), "--out".into(), s(&dir(TASK))]);
                args.extend(["--stats-json".into(), s(&dir(TASK).join("trace.stats.json"))]);
                let maps: Vec<&str> = step
                    .outputs
                    .iter()
                    .filter_map(|p| p.file_name()?.to_str())
                    .filter(|n| n.ends_with(".pmap"))
                    .collect();
                let slice_outputs: Vec<String> =
                    (0..slices).flat_map(|k| maps.iter().map(move |m| s(&dir(&k.to_string()).join(m)))).collect();
                jobs.push(JobStep::array("photon-trace slices", &bin, args, slices, inputs, slice_outputs.clone()));
                let mut a = vec!["merge".to_string()];
                a.extend((0..slices).map(|k| s(&dir(&k.to_string()))));
                a.extend(["--out".into(), s(out), "--stats-json".into(), s(&step.stats)]);
                jobs.push(JobStep::array("photon-trace merge", &bin, a, 1, slice_outputs, outputs));
            }
            Kind::Render if sppm && (runs > 1 || run_budget_s.is_some()) => {
                // Independent runs, each with its seed (seed + K), image, statistics
                // and state (to continue after a time budget), then their mean.
                let run = |k: &str, ext: &str| s(&out.join("runs").join(format!("run-{k}.{ext}")));
                args.extend(["--run".into(), format!("{TASK}/{runs}"), "--out".into(), run(TASK, "exr")]);
                args.extend(["--stats-json".into(), run(TASK, "stats.json"), "--state".into(), run(TASK, "state")]);
                if let Some(b) = run_budget_s {
                    args.extend(["--time-budget".into(), b.to_string()]);
                }
                let run_outputs: Vec<String> = (0..runs).map(|k| run(&k.to_string(), "exr")).collect();
                let mut step = JobStep::array("photon-render runs", &bin, args, runs, inputs, run_outputs.clone());
                step.resumable = true;
                jobs.push(step);
                jobs.push(assemble("average runs", &["--average"], run_outputs));
            }
            Kind::Render if tiles > 1 => {
                // The render as tiles, each writing its own region and statistics.
                let tile = |k: &str, ext: &str| s(&out.join("tiles").join(format!("tile-{k}.{ext}")));
                args.extend(["--tile".into(), format!("{TASK}/{tiles}"), "--out".into(), tile(TASK, "exr")]);
                args.extend(["--stats-json".into(), tile(TASK, "stats.json")]);
                let tile_outputs: Vec<String> = (0..tiles).map(|k| tile(&k.to_string(), "exr")).collect();
                jobs.push(JobStep::array("photon-render tiles", &bin, args, tiles, inputs, tile_outputs.clone()));
                jobs.push(assemble("assemble", &[], tile_outputs));
            }
            _ => {
                args.extend(step.write_args());
                let mut job = JobStep::array(&step.name, &bin, args, 1, inputs, outputs);
                if let Some((first, n)) = frames {
                    if step.loads_scene() {
                        job.args.extend(["--frame".into(), TASK.into()]);
                    }
                    (job.first_task, job.tasks) = (first, n);
                }
                jobs.push(job);
            }
        }
    }
    Ok(JobPlan::new(s(&setup.out), jobs))
}

/// The job graph of a real-time animation of `frames` frames drawn by `photon`
/// (photon-live) with `args` (all but `--frame-task`) into `out`: `n` runs of
/// frames (array tasks, `photon-live --frame-task K/N`; each simulates the frames
/// before its own without drawing, so it draws what one run draws) and
/// `photon-live assemble` (live.apng, frames.csv at `fps`).
pub fn live_plan(photon_live: &Path, args: &[String], out: &Path, frames: u32, n: u32, fps: f32) -> Result<JobPlan> {
    if n == 0 || n > frames {
        bail!("--frame-tasks {n}: needs 1 to the animation's {frames} frames");
    }
    let s = |p: &Path| p.display().to_string();
    let program = s(photon_live);
    let runs = |k: u32| pm_live::task_frames(k, n, frames);
    let part = |k: u32| out.join("frames").join(pm_live::frames_part_file(&runs(k)));
    let mut task_outputs: Vec<String> =
        (0..frames).map(|f| s(&out.join("frames").join(format!("{f:04}.png")))).collect();
    task_outputs.extend((0..n).map(|k| s(&part(k))));
    let mut task_args = args.to_vec();
    task_args.extend(["--frame-task".into(), format!("{TASK}/{n}")]);
    let assemble = vec![
        "assemble".to_string(),
        "--out".into(),
        s(out),
        "--frames".into(),
        frames.to_string(),
        "--fps".into(),
        fps.to_string(),
    ];
    let live = vec![s(&out.join("live.apng")), s(&out.join("frames.csv"))];
    Ok(JobPlan::new(
        s(out),
        vec![
            JobStep::array("photon-live frames", &program, task_args, n, vec![], task_outputs.clone()),
            JobStep::array("photon-live assemble", &program, assemble, 1, task_outputs, live),
        ],
    ))
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
        if step.is_array() {
            let ks = step.task_indices();
            let _ = writeln!(t, "#SBATCH --array={}-{}", ks.start, ks.end - 1);
        }
        let _ = writeln!(
            t,
            "# {}: waits for {}",
            step.name,
            if step.after.is_empty() { "nothing".into() } else { step.after.join(", ") }
        );
        if step.resumable {
            t.push_str("#SBATCH --requeue\n");
        }
        t.push_str("set -euo pipefail\nTASK=\"${SLURM_ARRAY_TASK_ID:-0}\"\n");
        let args: Vec<String> = step.args.iter().map(|a| sh(a).replace(TASK, "'\"${TASK}\"'")).collect();
        if step.resumable {
            // Exit 75: stopped at its time budget with its state saved; the task
            // goes back to the queue and continues from the state when it runs again.
            let _ = writeln!(t, "rc=0\n{} {} || rc=$?", sh(&step.program), args.join(" "));
            t.push_str(
                "if [ \"$rc\" -eq 75 ]; then\n  scontrol requeue \"${SLURM_ARRAY_JOB_ID:-$SLURM_JOB_ID}${SLURM_ARRAY_TASK_ID:+_$SLURM_ARRAY_TASK_ID}\"\n  exit 0\nfi\nexit \"$rc\"\n",
            );
        } else {
            let _ = writeln!(t, "exec {} {}", sh(&step.program), args.join(" "));
        }
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
            if step.is_array() {
                let ks = step.task_indices();
                v["parameterSpace"] = serde_json::json!({
                    "taskParameterDefinitions": [{"name": "Index", "type": "INT", "range": format!("{}-{}", ks.start, ks.end - 1)}]
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
