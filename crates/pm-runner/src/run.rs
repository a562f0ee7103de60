//! `cargo xtask run`: Christensen's steps ([`pm_pipeline::steps`]) as separate
//! processes exchanging files in one output folder with fixed names, and
//! report.json; a step whose arguments and input contents are unchanged is skipped.
//! `cargo xtask live`: photon-live with pipeline.toml's `[live]` settings.

use crate::bins::{self, Bins};
use anyhow::{Context, Result};
use pm_pipeline::steps::{Kind, Step, step_key, steps};
use pm_pipeline::{EffectsCfg, Pipeline, Setup};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `cargo xtask run`.
#[derive(clap::Args, Debug, Clone, Default)]
// Help texts give units as [m] and [s], not links, and placeholders as <name>.
#[allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]
pub struct RunArgs {
    /// Pipeline file [default: pipeline.toml at the repository root].
    #[arg(long, value_name = "FILE")]
    pub pipeline: Option<PathBuf>,
    /// Scene (glTF 2.0) instead of the pipeline file's.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Output folder [default: out/<scene name>].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Image width [pixels] instead of the pipeline file's.
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height [pixels] instead of the pipeline file's.
    #[arg(long)]
    pub height: Option<u32>,
    /// Run every step, even those whose inputs and parameters are unchanged.
    #[arg(long)]
    pub force: bool,
    /// Render the image as this many tiles (bands of rows) and assemble them, as
    /// the job plan does (`cargo xtask plan`); every step then runs. 1: one render.
    #[arg(long, default_value_t = 1)]
    pub tiles: u32,
    /// Trace the photons as this many slices of the emission index space and merge
    /// them, as the job plan does; the maps (and so the image) are byte-identical
    /// to one trace's. 1: one trace.
    #[arg(long, default_value_t = 1)]
    pub trace_slices: u32,
    /// With --tiles, --trace-slices or --runs: run this many tasks of a step at a
    /// time (each its own process).
    #[arg(long, default_value_t = 1)]
    pub workers: u32,
    /// Render mode instead of the pipeline file's ([render] mode: full, path,
    /// sppm, ...).
    #[arg(long)]
    pub method: Option<pm_methods::Method>,
    /// Progressive photon mapping (mode sppm): this many independent runs (seeds
    /// seed to seed + K - 1, each its own process) averaged into the image, as the
    /// job plan does; the mean of consistent estimates is consistent. 1: one run.
    #[arg(long, default_value_t = 1)]
    pub runs: u32,
    /// Progressive photon mapping: each run stops after this many seconds [s]
    /// with its state saved and is run again from it until its passes are done
    /// (what a Slurm task does to fit a queue's time limit: it re-queues itself).
    /// The image is the same as without it.
    #[arg(long, value_name = "SECONDS")]
    pub run_time_budget: Option<f64>,
    /// The folder of the stage binaries to run (as built by `cargo build
    /// --release`); given, nothing is built (what the Blender add-on passes)
    /// [default: build them and use cargo's target/release].
    #[arg(long, value_name = "DIR")]
    pub bins: Option<PathBuf>,
}

impl RunArgs {
    /// How the job plan cuts the work.
    pub fn parts(&self) -> pm_pipeline::jobs::Parts {
        pm_pipeline::jobs::Parts {
            tiles: self.tiles.max(1),
            slices: self.trace_slices.max(1),
            runs: self.runs.max(1),
            run_budget_s: self.run_time_budget,
        }
    }

    /// The stage binaries: `--bins` as they are, else built.
    pub fn binaries(&self, root: &Path) -> Result<Bins> {
        match &self.bins {
            Some(dir) => Ok(Bins::at(dir.clone())),
            None => Bins::build(root),
        }
    }

    /// True when the run is a job plan executed here rather than the steps.
    fn planned(&self) -> bool {
        self.tiles > 1 || self.trace_slices > 1 || self.runs > 1 || self.run_time_budget.is_some()
    }
}

/// What happened to one step of a run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// Step name, e.g. "photon-sort global".
    pub step: String,
    /// False when the step was skipped (unchanged, or its input map is absent).
    pub ran: bool,
}

/// Run the pipeline with the repository's release binaries, building them first
/// (or with those in `--bins`, as they are).
pub fn run(args: &RunArgs, root: &Path) -> Result<Vec<Outcome>> {
    let bins = args.binaries(root)?;
    run_with(args, root, &bins)
}

/// Load the pipeline, apply `args`, ask the scene analysis (through
/// photon-trace) which effects to simulate and create the output folder.
pub fn setup(args: &RunArgs, root: &Path, bins: &Bins) -> Result<Setup> {
    let pipeline = args.pipeline.clone().unwrap_or_else(|| root.join("pipeline.toml"));
    let mut cfg = Pipeline::load(&pipeline)?;
    cfg.render.width = args.width.unwrap_or(cfg.render.width);
    cfg.render.height = args.height.unwrap_or(cfg.render.height);
    cfg.mode = args.method.unwrap_or(cfg.mode);
    cfg.settings().check(true).map_err(|e| anyhow::anyhow!(e))?;
    let scene = args.scene.clone().unwrap_or_else(|| cfg.scene_path(&pipeline));
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out").join(&name));
    bins.check()?;

    // Which effects to simulate: the scene analysis, or the list pipeline.toml forces.
    let analysis: pm_light::Effects = {
        let o = std::process::Command::new(bins.path("photon-trace"))
            .args(["--scene".to_string(), scene.display().to_string(), "--analyze".into()])
            .args(cfg.scene_options.to_args())
            .output()
            .context("cannot start photon-trace --analyze")?;
        if !o.status.success() {
            // The stage's own line names the file and the problem; a scene
            // needing an extension not read keeps its exit code.
            let line = String::from_utf8_lossy(&o.stderr);
            return Err(bins::stage_error(o.status, format!("scene analysis failed: {}", line.trim())));
        }
        serde_json::from_slice(&o.stdout).context("photon-trace --analyze printed no analysis")?
    };
    // Created once the scene is known to load: a refused scene leaves nothing.
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    Ok(Setup::new(cfg, scene, out, analysis))
}

/// Run the pipeline with the stage binaries in `bins`.
pub fn run_with(args: &RunArgs, root: &Path, bins: &Bins) -> Result<Vec<Outcome>> {
    let set = setup(args, root, bins)?;
    if args.planned() || set.cfg.frames.is_some() {
        // The job plan, executed here (an animation: a task per frame).
        let program = |name: &str| bins.path(name);
        let plan = pm_pipeline::jobs::job_plan(&set, &program, args.parts())?;
        println!(
            "plan ({} -> {}, {} trace slices, {} tiles, {} runs):",
            set.scene.display(),
            set.out.display(),
            args.trace_slices,
            args.tiles,
            args.runs
        );
        let (times, wall) = crate::exec::execute_and_record(&plan, args.workers)?;
        println!(
            "  whole run {wall:.2} s with {} worker(s); the model predicts {:.2} s on {} node(s)",
            args.workers,
            pm_pipeline::jobs::estimate(&times, args.workers),
            args.workers
        );
        return Ok(plan.steps.iter().map(|s| Outcome { step: s.name.clone(), ran: true }).collect());
    }
    let Setup { cfg, scene, out, analysis, caustics, indirect, volume } = set;
    let steps = steps(&cfg, &scene, &out, caustics, indirect, volume)?;

    let keys_path = out.join(".stage-keys.json");
    let mut keys: serde_json::Map<String, serde_json::Value> =
        std::fs::read(&keys_path).ok().and_then(|b| serde_json::from_slice(&b).ok()).unwrap_or_default();
    println!(
        "effects ({}):",
        if matches!(cfg.effects, EffectsCfg::Auto(_)) { "scene analysis" } else { "forced by pipeline.toml" }
    );
    for (key, d) in [
        ("caustics", &analysis.caustics),
        ("indirect", &analysis.indirect),
        ("specular_seen", &analysis.specular_seen),
        ("glossy", &analysis.glossy),
        ("volume", &analysis.volume),
    ] {
        println!("  {key}: {} ({})", if d.yes { "yes" } else { "no" }, d.reason);
    }
    println!("  direct: {}", analysis.direct);
    let mut skipped_effects = Vec::new();
    if !caustics {
        skipped_effects.push("caustic photon tracing, sorting and estimates");
    }
    if !indirect {
        skipped_effects.push("global photon map, irradiance precompute and final gathering");
    }
    if !volume {
        skipped_effects.push("volume photon tracing and sorting (no medium that light reaches scatters)");
    }
    for s in &skipped_effects {
        println!("  skipped: {s}");
    }
    println!("plan ({} -> {}):", scene.display(), out.display());
    for step in &steps {
        println!("  {} {}", step.program(), step.argv().join(" "));
    }
    let mut outcomes = Vec::new();
    let mut rows = Vec::new();
    for step in &steps {
        if let Some(input) = &step.needs
            && !input.exists()
        {
            println!("  {}: skipped ({} absent: the scene does not need it)", step.name, input.display());
            // What it wrote in an earlier run no longer belongs to this one.
            for f in &step.outputs {
                let _ = std::fs::remove_file(f);
            }
            keys.remove(&step.name);
            outcomes.push(Outcome { step: step.name.clone(), ran: false });
            continue;
        }
        let key = step_key(&bins.path(step.program()), &step.argv(), &step.inputs);
        if !args.force
            && keys.get(&step.name).and_then(|k| k.as_str()) == Some(key.as_str())
            && step.outputs.iter().all(|f| f.exists())
        {
            println!("  {}: skipped (inputs and parameters unchanged)", step.name);
            outcomes.push(Outcome { step: step.name.clone(), ran: false });
            rows.push(json!({"stage": step.name, "seconds": 0.0, "figures": "unchanged, skipped", "skipped": true}));
            continue;
        }
        // A step about to run invalidates its recorded key until it succeeds.
        keys.remove(&step.name);
        std::fs::write(&keys_path, serde_json::to_string_pretty(&keys)?)?;
        let mut a = step.argv();
        for (flag, file) in &step.optional {
            if file.exists() {
                a.extend([flag.to_string(), file.display().to_string()]);
            }
        }
        let t = Instant::now();
        bins::run(bins, step.program(), &a, &step.name, false)
            .map_err(|e| anyhow::anyhow!("{e}; earlier outputs in {} are intact", out.display()))?;
        let secs = t.elapsed().as_secs_f64();
        println!("  {}: done in {secs:.2} s", step.name);
        keys.insert(step.name.clone(), json!(key));
        std::fs::write(&keys_path, serde_json::to_string_pretty(&keys)?)?;
        outcomes.push(Outcome { step: step.name.clone(), ran: true });
        let (figures, stats) = key_figures(step)?;
        rows.push(json!({"stage": step.name, "seconds": secs, "figures": figures, "stats": stats}));
    }
    println!("\n| stage | wall time [s] | key figures |\n|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {:.3} | {} |",
            r["stage"].as_str().unwrap_or(""),
            r["seconds"].as_f64().unwrap_or(0.0),
            r["figures"].as_str().unwrap_or("")
        );
    }
    let report = json!({
        "scene": scene.display().to_string(),
        "out": out.display().to_string(),
        "effects": analysis,
        "simulated": {"caustics": caustics, "indirect": indirect},
        "skipped_effects": skipped_effects,
        "stages": rows,
    });
    std::fs::write(out.join("report.json"), serde_json::to_string_pretty(&report)? + "\n")?;
    Ok(outcomes)
}

/// One line of the figures that matter for a step, from its typed statistics, and
/// the statistics themselves.
fn key_figures(step: &Step) -> Result<(String, serde_json::Value)> {
    fn read<T: serde::de::DeserializeOwned + serde::Serialize>(p: &Path) -> Result<(T, serde_json::Value)> {
        let t: T = bins::read_stats(p)?;
        let v = serde_json::to_value(&t)?;
        Ok((t, v))
    }
    Ok(match step.kind {
        Kind::Trace => {
            let (s, v) = read::<pm_stage::report::TraceReport>(&step.stats)?;
            let map = |m: &pm_stage::report::MapReport, emitted: bool| match &m.skipped {
                Some(why) => why.clone(),
                None if emitted => format!("{} emitted / {} stored", m.emitted, m.stored),
                None => format!("{} stored", m.stored),
            };
            (format!("global: {}; caustic: {}", map(&s.global, true), map(&s.caustic, false)), v)
        }
        Kind::Sort => {
            let (s, v) = read::<pm_stage::report::SortReport>(&step.stats)?;
            (format!("{} photons, tree depth {}", s.photons, s.depth), v)
        }
        Kind::Irradiance => {
            let (s, v) = read::<pm_stage::report::IrradianceReport>(&step.stats)?;
            (format!("{} estimates (k = {}), median radius {:.4} m", s.computed, s.params.k, s.radius_m[1]), v)
        }
        Kind::Icache => {
            let (s, v) = read::<pm_stage::report::RenderReport>(&step.stats)?;
            (format!("{} cache records, {} gather rays", s.cache_records, s.prepass_gather_rays), v)
        }
        Kind::Render => {
            let (s, v) = read::<pm_stage::report::RenderReport>(&step.stats)?;
            (
                format!(
                    "{}x{} {}, {:.2} samples/pixel, {} final gathers, {} gather rays",
                    s.params.width, s.params.height, s.mode, s.samples_per_pixel, s.final_gathers, s.gather_rays
                ),
                v,
            )
        }
    })
}

/// Options of `cargo xtask live`.
#[derive(clap::Args, Debug, Clone, Default)]
// Help texts give placeholders as <name>, not HTML.
#[allow(rustdoc::invalid_html_tags)]
pub struct LiveArgs {
    /// Pipeline file [default: pipeline.toml at the repository root]; its `[live]`
    /// section and `live_scene` are used.
    #[arg(long, value_name = "FILE")]
    pub pipeline: Option<PathBuf>,
    /// Scene (glTF 2.0) instead of the pipeline file's `live_scene`.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Output folder [default: out/live/<scene name>].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The real-time method instead of the pipeline file's `live.method`.
    #[arg(long)]
    pub method: Option<pm_methods::live::LiveMethod>,
    /// Frames to render.
    #[arg(long, default_value_t = 120)]
    pub frames: u32,
    /// Draw the animation as this many runs of consecutive frames (array tasks of
    /// the job plan, `photon-live --frame-task K/N`) and assemble them; each task
    /// simulates the frames before its own without drawing. 1: one run.
    #[arg(long, default_value_t = 1)]
    pub frame_tasks: u32,
    /// With --frame-tasks: run this many tasks at a time (each its own process).
    #[arg(long, default_value_t = 1)]
    pub workers: u32,
}

/// What `cargo xtask live` runs: the scene, the output folder and photon-live's
/// arguments (but for --frame-task) from the pipeline file's `[live]` section.
pub struct LiveSetup {
    /// The output folder.
    pub out: PathBuf,
    /// photon-live's arguments.
    pub args: Vec<String>,
    /// Frames per second of animation time [1/s].
    pub fps: f32,
}

/// photon-live's arguments for `cargo xtask live` with `args`.
pub fn live_setup(args: &LiveArgs, root: &Path) -> Result<LiveSetup> {
    let pipeline = args.pipeline.clone().unwrap_or_else(|| root.join("pipeline.toml"));
    let mut cfg = Pipeline::load(&pipeline)?;
    cfg.live.method = args.method.unwrap_or(cfg.live.method);
    let scene = args.scene.clone().unwrap_or_else(|| cfg.live_scene_path(&pipeline));
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out/live").join(&name));
    let args = cfg.live_args(&scene, &out, args.frames);
    Ok(LiveSetup { out, args, fps: cfg.live.frame.fps })
}

/// The job graph of the real-time animation `args` describes: `frame_tasks` runs
/// of frames and their assembly ([`pm_pipeline::jobs::live_plan`]).
pub fn live_plan(args: &LiveArgs, root: &Path, bins: &Bins) -> Result<pm_pipeline::jobs::JobPlan> {
    let set = live_setup(args, root)?;
    std::fs::create_dir_all(&set.out).with_context(|| format!("{}: cannot create", set.out.display()))?;
    pm_pipeline::jobs::live_plan(&bins.path("photon-live"), &set.args, &set.out, args.frames, args.frame_tasks, set.fps)
}

/// `cargo xtask live`: build the binaries and run `photon-live` with the pipeline
/// file's `[live]` settings (with `--frame-tasks N`, as the job plan's frame tasks
/// and assembly).
pub fn live(args: &LiveArgs, root: &Path) -> Result<()> {
    let bins = Bins::build(root)?;
    if args.frame_tasks > 1 {
        let plan = live_plan(args, root, &bins)?;
        let (_, wall) = crate::exec::execute_and_record(&plan, args.workers)?;
        println!("{} frames as {} tasks in {wall:.2} s with {} worker(s)", args.frames, args.frame_tasks, args.workers);
        println!("wrote {}/frames, live.apng and frames.csv", plan.out);
        return Ok(());
    }
    let set = live_setup(args, root)?;
    println!("photon-live {}", set.args.join(" "));
    bins::run(&bins, "photon-live", &set.args, "photon-live", false)?;
    println!("wrote {}/frames, live.apng and frames.csv", set.out.display());
    Ok(())
}

/// The job graph of `args` (its pipeline, scene, output, `tiles`,
/// `trace_slices`, `runs` and `run_time_budget`), with the stage binaries in `bins`.
pub fn plan_for(args: &RunArgs, root: &Path, bins: &Bins) -> Result<pm_pipeline::jobs::JobPlan> {
    let setup = setup(args, root, bins)?;
    pm_pipeline::jobs::job_plan(&setup, &|name: &str| bins.path(name), args.parts())
}
