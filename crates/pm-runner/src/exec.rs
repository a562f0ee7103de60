//! Running a job plan on this machine: its steps one after another, an array
//! step's tasks side by side in waves, a resumable task run again until it
//! finishes (`cargo xtask run --tiles/--trace-slices`,
//! `cargo xtask live --frame-tasks`).

use anyhow::{Context, Result};
use pm_pipeline::jobs::{JobPlan, TASK, TaskTime};
use std::path::Path;

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
            let ks = step.task_indices();
            let name = match (step.is_array(), step.first_task) {
                (false, _) => step.name.clone(),
                (true, 0) => format!("{} (task {k} of {})", step.name, step.tasks),
                (true, first) => format!("{} (task {k} of {first} to {})", step.name, ks.end - 1),
            };
            let t = std::time::Instant::now();
            let program = Path::new(&step.program);
            let intact = |e: anyhow::Error| anyhow::anyhow!("{e}; earlier outputs in {} are intact", plan.out);
            if step.resumable {
                // Stopped at its time budget with its state saved: run it again from
                // the state, as a re-queued Slurm task does.
                let mut runs = 1;
                while !crate::bins::run_resumable(program, &args, &name, true).map_err(intact)? {
                    runs += 1;
                }
                if runs > 1 {
                    println!("  {name}: ran {runs} times, each continuing from the state the one before saved");
                }
            } else {
                crate::bins::run_program(program, &args, &name, true).map_err(intact)?;
            }
            let seconds = t.elapsed().as_secs_f64();
            println!("  {name}: done in {seconds:.2} s");
            Ok(TaskTime { step: step.name.clone(), tasks: step.tasks, task: k, seconds })
        };
        // Tasks in waves of `workers`, each wave's processes side by side.
        let ks: Vec<u32> = step.task_indices().collect();
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
