//! `cargo xtask run`: Christensen's steps as separate processes exchanging files in
//! one output folder with fixed names (global.pmap, caustic.pmap, global.kd.pmap,
//! caustic.kd.pmap, global.irr.pmap, icache.bin, image.exr, *.stats.json,
//! report.json). Each step is a value (name, program, arguments, inputs, outputs);
//! a step whose arguments and input contents are unchanged is skipped.

use crate::stages::{self, Bins};
use anyhow::{Context, Result, bail};
use pm_estimate::IrradianceParams;
use pm_params::Naming;
use pm_photon::TraceParams;
use pm_render::RenderParams;
use serde::Deserialize;
use serde_json::json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// pipeline.toml, typed: each stage's section is that stage's parameter type (the
/// one definition its command line also uses). Unknown keys are errors.
#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    /// The scene, relative to the pipeline file.
    pub scene: PathBuf,
    /// Random seed of every stage.
    #[serde(default = "one")]
    pub seed: u64,
    /// Units of the scene's point, spot and directional light intensities:
    /// "photometric" (the glTF specification: candela and lux, at 683 lm/W) or
    /// "radiometric" (W/sr and W/m^2); every stage that reads the scene gets it.
    #[serde(default)]
    pub light_units: pm_scene::LightUnits,
    /// `"auto"` (the scene analysis decides) or a list of effects to simulate.
    pub effects: EffectsCfg,
    /// Light name to fraction of the photon budget; the other lights share the rest
    /// by power.
    #[serde(default)]
    pub light_shares: BTreeMap<String, f64>,
    /// Stage 1.
    #[serde(default)]
    pub trace: TraceParams,
    /// Stage 3.
    #[serde(default)]
    pub irradiance: IrradianceParams,
    /// Stage 4 (and the irradiance-cache step).
    #[serde(default)]
    pub render: RenderParams,
    /// The scene `cargo xtask live` renders, relative to the pipeline file
    /// (default: `scene`).
    #[serde(default)]
    pub live_scene: Option<PathBuf>,
    /// The real-time mode (`photon-live`, `cargo xtask live`).
    #[serde(default)]
    pub live: photon_live::LiveParams,
    /// "preview", "balanced" or "final": the trace, irradiance and render settings
    /// are picked from the measured accuracy/time front ([`crate::quality`]).
    #[serde(default)]
    pub quality: Option<String>,
    /// Or a time budget \[s\] for the whole pipeline at the file's image size.
    #[serde(default)]
    pub time_budget_s: Option<f64>,
    /// What quality or time_budget_s chose (not a key of the file).
    #[serde(skip)]
    pub chosen: Option<String>,
}

/// `effects = "auto"` or a list of forced effects.
#[derive(Deserialize, Debug, Clone)]
#[serde(untagged)]
pub enum EffectsCfg {
    /// The scene analysis decides.
    Auto(AutoWord),
    /// Simulate exactly these.
    List(Vec<EffectName>),
}

/// The word `auto`.
#[derive(Deserialize, Debug, Clone)]
#[serde(rename_all = "lowercase")]
pub enum AutoWord {
    /// `"auto"`.
    Auto,
}

/// An effect that can be forced on.
#[derive(Deserialize, Debug, Clone, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum EffectName {
    /// The caustic map.
    Caustics,
    /// The global map, irradiance precompute and final gathers.
    Indirect,
}

fn one() -> u64 {
    1
}

impl Pipeline {
    /// Read, parse and range-check a pipeline file; every error is one line naming
    /// the file and the key.
    pub fn load(path: &Path) -> Result<Pipeline> {
        let mut text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
        let syntax = |e: toml::de::Error| anyhow::anyhow!("{}: {}", path.display(), e.to_string().replace('\n', " "));
        // A quality or time budget replaces the swept settings before anything is checked.
        let mut doc: toml::Value = toml::from_str(&text).map_err(syntax)?;
        let chosen = crate::quality::apply(&mut doc, path)?;
        if chosen.is_some() {
            text = toml::to_string(&doc).context("internal error: the pipeline does not serialise")?;
        }
        let mut p: Pipeline = toml::from_str(&text).map_err(syntax)?;
        p.chosen = chosen;
        let fail = |e: String| anyhow::anyhow!("{}: {e}", path.display());
        p.trace.validate(Naming::File("trace")).map_err(fail)?;
        p.irradiance.validate(Naming::File("irradiance")).map_err(fail)?;
        p.render.check(Naming::File("render")).map_err(fail)?;
        p.live.check(Naming::File("live")).map_err(fail)?;
        for (name, share) in &p.light_shares {
            if !(0.0..=1.0).contains(share) {
                bail!("{}: light_shares.{name} = {share} is out of range (in [0, 1])", path.display());
            }
        }
        if let Some(c) = &p.chosen {
            println!("{}: {c}", path.display());
        }
        Ok(p)
    }
}

/// Options of `cargo xtask run`.
#[derive(clap::Args, Debug, Clone, Default)]
// Help texts give units as [m] and [s], not links, and placeholders as <name>.
#[allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]
pub struct RunArgs {
    /// Pipeline file [default: pipeline.toml at the repository root].
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
    /// With --tiles or --trace-slices: run this many tasks of a step at a time
    /// (each its own process).
    #[arg(long, default_value_t = 1)]
    pub workers: u32,
}

/// What happened to one step of a run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// Step name, e.g. "photon-sort global".
    pub step: String,
    /// False when the step was skipped (unchanged, or its input map is absent).
    pub ran: bool,
}

/// Which stage a step runs, and so which statistics it writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Trace,
    Sort,
    Irradiance,
    Icache,
    Render,
}

impl Kind {
    fn program(self) -> &'static str {
        match self {
            Kind::Trace => "photon-trace",
            Kind::Sort => "photon-sort",
            Kind::Irradiance => "photon-irradiance",
            Kind::Icache | Kind::Render => "photon-render",
        }
    }
}

/// One step of the pipeline.
#[derive(Clone, Debug)]
pub(crate) struct Step {
    pub(crate) name: String,
    kind: Kind,
    pub(crate) args: Vec<String>,
    /// Files whose contents the step's key hashes (a missing one hashes as absent).
    pub(crate) inputs: Vec<PathBuf>,
    /// Files it writes (all must exist for it to be skipped as unchanged).
    pub(crate) outputs: Vec<PathBuf>,
    /// Skip the step when this input is absent (the scene did not need it).
    pub(crate) needs: Option<PathBuf>,
    /// Pass `--flag file` only when the file exists when the step runs.
    pub(crate) optional: Vec<(&'static str, PathBuf)>,
    stats: PathBuf,
}

impl Step {
    /// The stage binary the step runs.
    pub(crate) fn program(&self) -> &'static str {
        self.kind.program()
    }
}

/// Run the pipeline with the repository's release binaries, building them first.
pub fn run(args: &RunArgs, root: &Path) -> Result<Vec<Outcome>> {
    let bins = Bins::build(root)?;
    run_with(args, root, &bins)
}

/// The steps of the pipeline for `cfg`, writing into `out`.
pub(crate) fn plan(cfg: &Pipeline, scene: &Path, out: &Path, caustics: bool, indirect: bool) -> Result<Vec<Step>> {
    let o = |f: &str| out.join(f);
    let s = |p: &Path| p.display().to_string();
    let scene_files = scene_inputs(scene)?;
    let seed = ["--seed".to_string(), cfg.seed.to_string()];
    let mut trace = cfg.trace.clone();
    if !indirect {
        trace.global_photons = 0;
    }
    if !caustics {
        trace.caustic_photons = 0;
    }
    let units = ["--light-units".to_string(), cfg.light_units.to_string()];
    let mut trace_args = vec!["--scene".into(), s(scene), "--out".into(), s(out)];
    trace_args.extend(units.clone());
    trace_args.extend(trace.to_args());
    trace_args.extend(seed.clone());
    for (name, share) in &cfg.light_shares {
        trace_args.extend(["--light-share".into(), format!("{name}={share}")]);
    }
    let with_stats = |mut a: Vec<String>, stats: &Path| {
        a.extend(["--stats-json".into(), s(stats)]);
        a
    };
    let mut steps = vec![Step {
        name: "photon-trace".into(),
        kind: Kind::Trace,
        args: with_stats(trace_args, &o("trace.stats.json")),
        inputs: scene_files.clone(),
        // The maps the scene calls for (a skipped effect's map is not written).
        outputs: [indirect.then(|| o("global.pmap")), caustics.then(|| o("caustic.pmap")), Some(o("trace.stats.json"))]
            .into_iter()
            .flatten()
            .collect(),
        needs: None,
        optional: vec![],
        stats: o("trace.stats.json"),
    }];
    for map in ["global", "caustic"] {
        let (input, output, stats) =
            (o(&format!("{map}.pmap")), o(&format!("{map}.kd.pmap")), o(&format!("sort-{map}.stats.json")));
        steps.push(Step {
            name: format!("photon-sort {map}"),
            kind: Kind::Sort,
            args: with_stats(vec![s(&input), "--out".into(), s(&output)], &stats),
            inputs: vec![input.clone()],
            outputs: vec![output, stats.clone()],
            needs: Some(input),
            optional: vec![],
            stats,
        });
    }
    let mut irr_args = vec![s(&o("global.kd.pmap")), "--out".into(), s(&o("global.irr.pmap"))];
    irr_args.extend(cfg.irradiance.to_args());
    steps.push(Step {
        name: "photon-irradiance".into(),
        kind: Kind::Irradiance,
        args: with_stats(irr_args, &o("irradiance.stats.json")),
        inputs: vec![o("global.kd.pmap")],
        outputs: vec![o("global.irr.pmap"), o("irradiance.stats.json")],
        needs: Some(o("global.kd.pmap")),
        optional: vec![],
        stats: o("irradiance.stats.json"),
    });
    let r = &cfg.render;
    let mut base = vec!["--scene".into(), s(scene)];
    base.extend(units.clone());
    if indirect {
        base.extend(["--global".into(), s(&o("global.irr.pmap"))]);
    } else {
        base.push("--no-indirect".into());
    }
    base.extend(seed);
    let map_inputs = [scene_files, vec![o("global.irr.pmap")]].concat();
    let uses_cache = indirect && r.icache_accuracy > 0.0 && pm_render::method_uses_cache(r.mode);
    let mut render_args = base.clone();
    let mut render_inputs = [map_inputs.clone(), vec![o("caustic.kd.pmap")]].concat();
    if uses_cache {
        // The cache step gets only what shapes the cache (the rest at defaults), so
        // changing the rest re-runs only the render.
        let mut a = base;
        a.extend(r.cache_shaping().to_args());
        a.extend(["--icache-out".into(), s(&o("icache.bin"))]);
        steps.push(Step {
            name: "photon-render icache".into(),
            kind: Kind::Icache,
            args: with_stats(a, &o("icache.stats.json")),
            inputs: map_inputs,
            outputs: vec![o("icache.bin"), o("icache.stats.json")],
            needs: Some(o("global.irr.pmap")),
            optional: vec![],
            stats: o("icache.stats.json"),
        });
        render_args.extend(["--icache".into(), s(&o("icache.bin"))]);
        render_inputs.push(o("icache.bin"));
    }
    render_args.extend(r.to_args());
    render_args.extend(["--out".into(), s(&o("image.exr")), "--png".into(), s(&o("image.png"))]);
    steps.push(Step {
        name: "photon-render".into(),
        kind: Kind::Render,
        args: with_stats(render_args, &o("render.stats.json")),
        inputs: render_inputs,
        outputs: vec![o("image.exr"), o("image.png"), o("render.stats.json")],
        needs: None,
        optional: vec![("--caustic", o("caustic.kd.pmap"))],
        stats: o("render.stats.json"),
    });
    Ok(steps)
}

/// What a run works on: the pipeline file's settings with the command line's
/// overrides, the scene, the output folder and what the scene analysis decided.
pub(crate) struct Setup {
    pub(crate) cfg: Pipeline,
    pub(crate) scene: PathBuf,
    pub(crate) out: PathBuf,
    pub(crate) analysis: pm_light::Effects,
    pub(crate) caustics: bool,
    pub(crate) indirect: bool,
}

/// Load the pipeline, apply `args`, create the output folder and ask the scene
/// analysis (through photon-trace) which effects to simulate.
pub(crate) fn setup(args: &RunArgs, root: &Path, bins: &Bins) -> Result<Setup> {
    let pipeline = args.pipeline.clone().unwrap_or_else(|| root.join("pipeline.toml"));
    let mut cfg = Pipeline::load(&pipeline)?;
    cfg.render.width = args.width.unwrap_or(cfg.render.width);
    cfg.render.height = args.height.unwrap_or(cfg.render.height);
    cfg.render.check(Naming::Cli).map_err(|e| anyhow::anyhow!(e))?;
    let base = pipeline.parent().unwrap_or(Path::new("."));
    let scene = args.scene.clone().unwrap_or_else(|| base.join(&cfg.scene));
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out").join(&name));
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    bins.check()?;

    // Which effects to simulate: the scene analysis, or the list pipeline.toml forces.
    let analysis: pm_light::Effects = {
        let o = std::process::Command::new(bins.path("photon-trace"))
            .args(["--scene".to_string(), scene.display().to_string(), "--analyze".into()])
            .args(["--light-units".to_string(), cfg.light_units.to_string()])
            .output()
            .context("cannot start photon-trace --analyze")?;
        if !o.status.success() {
            bail!("scene analysis failed: {}", String::from_utf8_lossy(&o.stderr).trim());
        }
        serde_json::from_slice(&o.stdout).context("photon-trace --analyze printed no analysis")?
    };
    let (caustics, indirect) = match &cfg.effects {
        EffectsCfg::Auto(_) => (analysis.caustics.yes, analysis.indirect.yes),
        EffectsCfg::List(l) => (l.contains(&EffectName::Caustics), l.contains(&EffectName::Indirect)),
    };
    Ok(Setup { cfg, scene, out, analysis, caustics, indirect })
}

/// Run the pipeline with the stage binaries in `bins`.
pub fn run_with(args: &RunArgs, root: &Path, bins: &Bins) -> Result<Vec<Outcome>> {
    let set = setup(args, root, bins)?;
    if args.tiles > 1 || args.trace_slices > 1 {
        // The job plan, executed here.
        let plan = crate::plan::job_plan(&set, bins, args.tiles.max(1), args.trace_slices.max(1))?;
        println!(
            "plan ({} -> {}, {} trace slices, {} tiles):",
            set.scene.display(),
            set.out.display(),
            args.trace_slices,
            args.tiles
        );
        let (times, wall) = crate::plan::execute_and_record(&plan, args.workers)?;
        println!(
            "  whole run {wall:.2} s with {} worker(s); the model predicts {:.2} s on {} node(s)",
            args.workers,
            crate::plan::estimate(&times, args.workers),
            args.workers
        );
        return Ok(plan.steps.iter().map(|s| Outcome { step: s.name.clone(), ran: true }).collect());
    }
    let Setup { cfg, scene, out, analysis, caustics, indirect } = set;
    let steps = plan(&cfg, &scene, &out, caustics, indirect)?;

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
    for s in &skipped_effects {
        println!("  skipped: {s}");
    }
    println!("plan ({} -> {}):", scene.display(), out.display());
    for step in &steps {
        println!("  {} {}", step.kind.program(), step.args.join(" "));
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
        let key = step_key(&bins.path(step.kind.program()), &step.args, &step.inputs);
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
        let mut a = step.args.clone();
        for (flag, file) in &step.optional {
            if file.exists() {
                a.extend([flag.to_string(), file.display().to_string()]);
            }
        }
        let t = Instant::now();
        stages::run(bins, step.kind.program(), &a, &step.name, false)
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

/// blake3 over the program (its name and the binary's contents: a rebuilt stage
/// runs again), its arguments and the contents of its input files.
fn step_key(program: &Path, args: &[String], inputs: &[PathBuf]) -> String {
    let mut h = blake3::Hasher::new();
    h.update(program.file_name().unwrap_or_default().as_encoded_bytes());
    match std::fs::read(program) {
        Ok(bytes) => h.update(blake3::hash(&bytes).as_bytes()),
        Err(_) => h.update(b"absent"),
    };
    for a in args {
        h.update(a.as_bytes());
        h.update(&[0]);
    }
    for f in inputs {
        match std::fs::read(f) {
            Ok(bytes) => h.update(blake3::hash(&bytes).as_bytes()),
            Err(_) => h.update(b"absent"),
        };
    }
    h.finalize().to_hex().to_string()
}

/// The scene file and the external buffers and images a .gltf references.
pub fn scene_inputs(scene: &Path) -> Result<Vec<PathBuf>> {
    let mut files = vec![scene.to_owned()];
    let bytes = std::fs::read(scene).with_context(|| format!("{}: cannot read", scene.display()))?;
    if let Ok(doc) = serde_json::from_slice::<serde_json::Value>(&bytes) {
        let dir = scene.parent().unwrap_or(Path::new("."));
        for key in ["buffers", "images"] {
            for item in doc[key].as_array().into_iter().flatten() {
                if let Some(uri) = item["uri"].as_str().filter(|u| !u.starts_with("data:")) {
                    files.push(dir.join(uri));
                }
            }
        }
    }
    Ok(files)
}

/// One line of the figures that matter for a step, from its typed statistics, and
/// the statistics themselves.
fn key_figures(step: &Step) -> Result<(String, serde_json::Value)> {
    fn read<T: serde::de::DeserializeOwned + serde::Serialize>(p: &Path) -> Result<(T, serde_json::Value)> {
        let t: T = stages::read_stats(p)?;
        let v = serde_json::to_value(&t)?;
        Ok((t, v))
    }
    Ok(match step.kind {
        Kind::Trace => {
            let (s, v) = read::<photon_trace::Report>(&step.stats)?;
            let map = |m: &photon_trace::MapReport, emitted: bool| match &m.skipped {
                Some(why) => why.clone(),
                None if emitted => format!("{} emitted / {} stored", m.emitted, m.stored),
                None => format!("{} stored", m.stored),
            };
            (format!("global: {}; caustic: {}", map(&s.global, true), map(&s.caustic, false)), v)
        }
        Kind::Sort => {
            let (s, v) = read::<photon_sort::Report>(&step.stats)?;
            (format!("{} photons, tree depth {}", s.photons, s.depth), v)
        }
        Kind::Irradiance => {
            let (s, v) = read::<photon_irradiance::Report>(&step.stats)?;
            (format!("{} estimates (k = {}), median radius {:.4} m", s.computed, s.params.k, s.radius_m[1]), v)
        }
        Kind::Icache => {
            let (s, v) = read::<photon_render::Report>(&step.stats)?;
            (format!("{} cache records, {} gather rays", s.cache_records, s.prepass_gather_rays), v)
        }
        Kind::Render => {
            let (s, v) = read::<photon_render::Report>(&step.stats)?;
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
    pub pipeline: Option<PathBuf>,
    /// Scene (glTF 2.0) instead of the pipeline file's `live_scene`.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Output folder [default: out/live/<scene name>].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The real-time method instead of the pipeline file's `live.method`.
    #[arg(long)]
    pub method: Option<photon_live::Method>,
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
    let base = pipeline.parent().unwrap_or(Path::new("."));
    let scene = args.scene.clone().unwrap_or_else(|| base.join(cfg.live_scene.as_ref().unwrap_or(&cfg.scene)));
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out/live").join(&name));
    let mut a = vec!["--scene".to_string(), scene.display().to_string(), "--out".into(), out.display().to_string()];
    a.extend(["--frames".into(), args.frames.to_string(), "--seed".into(), cfg.seed.to_string()]);
    a.extend(["--light-units".into(), cfg.light_units.to_string()]);
    a.extend(cfg.live.to_args());
    Ok(LiveSetup { out, args: a, fps: cfg.live.frame.fps })
}

/// `cargo xtask live`: build the binaries and run `photon-live` with the pipeline
/// file's `[live]` settings (with `--frame-tasks N`, as the job plan's frame tasks
/// and assembly).
pub fn live(args: &LiveArgs, root: &Path) -> Result<()> {
    let bins = Bins::build(root)?;
    if args.frame_tasks > 1 {
        let plan = crate::plan::live_plan(args, root, &bins)?;
        let (_, wall) = crate::plan::execute_and_record(&plan, args.workers)?;
        println!("{} frames as {} tasks in {wall:.2} s with {} worker(s)", args.frames, args.frame_tasks, args.workers);
        println!("wrote {}/frames, live.apng and frames.csv", plan.out);
        return Ok(());
    }
    let set = live_setup(args, root)?;
    println!("photon-live {}", set.args.join(" "));
    stages::run(&bins, "photon-live", &set.args, "photon-live", false)?;
    println!("wrote {}/frames, live.apng and frames.csv", set.out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step runs again when its stage binary was rebuilt, its arguments or an
    /// input changed; not when nothing did.
    #[test]
    fn a_step_key_covers_the_binary_the_arguments_and_the_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let (bin, input) = (dir.path().join("photon-render"), dir.path().join("map.pmap"));
        std::fs::write(&bin, b"build 1").unwrap();
        std::fs::write(&input, b"photons").unwrap();
        let args = vec!["--k".to_string(), "50".to_string()];
        let key = || step_key(&bin, &args, std::slice::from_ref(&input));
        let first = key();
        assert_eq!(key(), first);
        std::fs::write(&bin, b"build 2").unwrap();
        let rebuilt = key();
        assert_ne!(rebuilt, first, "a rebuilt binary");
        std::fs::write(&input, b"other photons").unwrap();
        assert_ne!(key(), rebuilt, "a changed input");
        assert_ne!(
            step_key(&bin, &["--k".into(), "60".into()], std::slice::from_ref(&input)),
            key(),
            "other arguments"
        );
    }
}
