//! `cargo xtask run`: Christensen's steps as separate processes exchanging photon-map
//! files in one output folder with fixed names (global.pmap, caustic.pmap,
//! global.kd.pmap, caustic.kd.pmap, *.stats.json, report.json).

use anyhow::{Context, Result, bail};
use serde::Deserialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// pipeline.toml, typed. Unknown keys are errors.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct Pipeline {
    scene: PathBuf,
    #[serde(default = "one")]
    seed: u64,
    width: u32,
    height: u32,
    spp: u32,
    effects: EffectsCfg,
    trace: TraceSection,
    irradiance: IrradianceSection,
    render: RenderSection,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct RenderSection {
    mode: RenderMode,
    gather_rays: u32,
    gather_lookup: GatherLookup,
    secondary_rays: u32,
    secondary_distance_rel_diag: f64,
    k: usize,
    caustic_k: usize,
    max_radius_rel_diag: f64,
    caustic_radius_rel_diag: f64,
    icache_accuracy: f64,
    icache_min_spacing_rel_diag: f64,
    icache_max_spacing_rel_diag: f64,
    indirect_threshold: f64,
    light_samples: u32,
    contrast: f64,
    exposure: f64,
}

/// `effects = "auto"` or a list of forced effects.
#[derive(Deserialize, Debug)]
#[serde(untagged)]
enum EffectsCfg {
    Auto(AutoWord),
    List(Vec<EffectName>),
}

#[derive(Deserialize, Debug)]
#[serde(rename_all = "lowercase")]
enum AutoWord {
    Auto,
}

#[derive(Deserialize, Debug, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum EffectName {
    Caustics,
    Indirect,
}

#[derive(Deserialize, Debug, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum RenderMode {
    Full,
    Photons,
    Radiance,
    Indirect,
    Path,
}

#[derive(Deserialize, Debug, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum GatherLookup {
    Precomputed,
    Exact,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct TraceSection {
    global_photons: u64,
    caustic_photons: u64,
    layout: Layout,
    #[serde(default)]
    light_shares: std::collections::BTreeMap<String, f64>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct IrradianceSection {
    fraction: f64,
    k: usize,
    max_radius_rel_diag: f64,
    filter: FilterKind,
}

#[derive(Deserialize, Debug, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum FilterKind {
    None,
    Cone,
    Gaussian,
}

#[derive(Deserialize, Debug, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum Layout {
    Compact,
    Full,
}

fn one() -> u64 {
    1
}

/// Largest photon count accepted before tracing: 23 bytes per stored photon, twice
/// (unsorted and sorted copies in memory during sorting), must fit in 16 GiB.
const MAX_PHOTONS: u64 = 16 * (1 << 30) / (2 * 64);

struct Args {
    pipeline: PathBuf,
    scene: Option<PathBuf>,
    out: Option<PathBuf>,
    width: Option<u32>,
    height: Option<u32>,
    force: bool,
}

fn parse(args: &[String], root: &Path) -> Result<Args> {
    let mut a =
        Args { pipeline: root.join("pipeline.toml"), scene: None, out: None, width: None, height: None, force: false };
    let mut it = args.iter();
    while let Some(x) = it.next() {
        match x.as_str() {
            "--scene" => a.scene = Some(PathBuf::from(it.next().context("--scene needs a file")?)),
            "--out" => a.out = Some(PathBuf::from(it.next().context("--out needs a folder")?)),
            "--width" => a.width = Some(it.next().context("--width needs a number")?.parse().context("--width")?),
            "--height" => a.height = Some(it.next().context("--height needs a number")?.parse().context("--height")?),
            "--force" => a.force = true,
            s if s.starts_with("--") => bail!("unknown option {s}"),
            s => a.pipeline = PathBuf::from(s),
        }
    }
    Ok(a)
}

/// What happened to one step of a run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// Step name, e.g. "photon-sort global".
    pub step: String,
    /// False when the step was skipped (unchanged, or its input map is absent).
    pub ran: bool,
}

/// Run the pipeline with the repository's release binaries, building them first.
pub fn run(args: &[String], root: &Path) -> Result<Vec<Outcome>> {
    build_stages(root)?;
    run_with(args, root, &root.join("target/release"))
}

/// Run the pipeline with the stage binaries in `bin_dir`.
pub fn run_with(args: &[String], root: &Path, bin_dir: &Path) -> Result<Vec<Outcome>> {
    let args = parse(args, root)?;
    let text =
        std::fs::read_to_string(&args.pipeline).with_context(|| format!("{}: cannot read", args.pipeline.display()))?;
    let cfg: Pipeline = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", args.pipeline.display(), e.to_string().replace('\n', " ")))?;
    validate(&cfg, &args.pipeline)?;
    for (key, v) in
        [("trace.global_photons", cfg.trace.global_photons), ("trace.caustic_photons", cfg.trace.caustic_photons)]
    {
        if v > MAX_PHOTONS {
            bail!(
                "{}: {key} = {v} would need about {} GiB; this machine allows at most {MAX_PHOTONS}",
                args.pipeline.display(),
                (v * 2 * 64) >> 30
            );
        }
    }
    let base = args.pipeline.parent().unwrap_or(Path::new("."));
    let scene = args.scene.clone().unwrap_or_else(|| base.join(&cfg.scene));
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out").join(&name));
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;

    let bin = |n: &str| bin_dir.join(n);
    for n in ["photon-trace", "photon-sort", "photon-irradiance", "photon-render"] {
        if !bin(n).exists() {
            bail!("{} is missing: build the stages (cargo build --release)", bin(n).display());
        }
    }
    // Which effects to simulate: the scene analysis, or the list pipeline.toml forces.
    let analysis: serde_json::Value = {
        let o = Command::new(bin("photon-trace"))
            .args(["--scene".to_string(), scene.display().to_string(), "--analyze".into()])
            .output()
            .context("cannot start photon-trace --analyze")?;
        if !o.status.success() {
            bail!("scene analysis failed: {}", String::from_utf8_lossy(&o.stderr).trim());
        }
        serde_json::from_slice(&o.stdout).context("photon-trace --analyze printed no JSON")?
    };
    let (caustics, indirect) = match &cfg.effects {
        EffectsCfg::Auto(_) => (analysis["caustics"]["yes"] == true, analysis["indirect"]["yes"] == true),
        EffectsCfg::List(l) => (l.contains(&EffectName::Caustics), l.contains(&EffectName::Indirect)),
    };
    let layout = match cfg.trace.layout {
        Layout::Compact => "compact",
        Layout::Full => "full",
    };
    let o = |f: &str| out.join(f).display().to_string();
    let mut trace_args: Vec<String> = vec![
        "--scene".into(),
        scene.display().to_string(),
        "--out".into(),
        out.display().to_string(),
        "--global".into(),
        if indirect { cfg.trace.global_photons } else { 0 }.to_string(),
        "--caustic".into(),
        if caustics { cfg.trace.caustic_photons } else { 0 }.to_string(),
        "--seed".into(),
        cfg.seed.to_string(),
        "--layout".into(),
        layout.into(),
        "--stats-json".into(),
        o("trace.stats.json"),
    ];
    for (name, share) in &cfg.trace.light_shares {
        trace_args.extend(["--light-share".into(), format!("{name}={share}")]);
    }
    let mut steps: Vec<(String, Vec<String>, Option<String>)> = vec![("photon-trace".into(), trace_args, None)];
    for map in ["global", "caustic"] {
        steps.push((
            "photon-sort".into(),
            vec![
                o(&format!("{map}.pmap")),
                "--out".into(),
                o(&format!("{map}.kd.pmap")),
                "--stats-json".into(),
                o(&format!("sort-{map}.stats.json")),
            ],
            Some(o(&format!("{map}.pmap"))),
        ));
    }
    let filter = match cfg.irradiance.filter {
        FilterKind::None => "none",
        FilterKind::Cone => "cone",
        FilterKind::Gaussian => "gaussian",
    };
    steps.push((
        "photon-irradiance".into(),
        vec![
            o("global.kd.pmap"),
            "--out".into(),
            o("global.irr.pmap"),
            "--fraction".into(),
            cfg.irradiance.fraction.to_string(),
            "--k".into(),
            cfg.irradiance.k.to_string(),
            "--max-radius".into(),
            cfg.irradiance.max_radius_rel_diag.to_string(),
            "--filter".into(),
            filter.into(),
            "--stats-json".into(),
            o("irradiance.stats.json"),
        ],
        Some(o("global.kd.pmap")),
    ));
    let r = &cfg.render;
    let name_of = |v: &dyn std::fmt::Debug| format!("{v:?}").to_lowercase();
    let mut render_args: Vec<String> = vec![
        "--scene".into(),
        scene.display().to_string(),
        "--global".into(),
        o("global.irr.pmap"),
        "--out".into(),
        o("image.exr"),
        "--png".into(),
        o("image.png"),
        "--width".into(),
        args.width.unwrap_or(cfg.width).to_string(),
        "--height".into(),
        args.height.unwrap_or(cfg.height).to_string(),
        "--spp".into(),
        cfg.spp.to_string(),
        "--seed".into(),
        cfg.seed.to_string(),
        "--mode".into(),
        name_of(&r.mode),
        "--gather-rays".into(),
        r.gather_rays.to_string(),
        "--gather-lookup".into(),
        name_of(&r.gather_lookup),
        "--secondary-rays".into(),
        r.secondary_rays.to_string(),
        "--secondary-distance".into(),
        r.secondary_distance_rel_diag.to_string(),
        "--k".into(),
        r.k.to_string(),
        "--caustic-k".into(),
        r.caustic_k.to_string(),
        "--max-radius".into(),
        r.max_radius_rel_diag.to_string(),
        "--caustic-radius".into(),
        r.caustic_radius_rel_diag.to_string(),
        "--icache-accuracy".into(),
        r.icache_accuracy.to_string(),
        "--icache-min-spacing".into(),
        r.icache_min_spacing_rel_diag.to_string(),
        "--icache-max-spacing".into(),
        r.icache_max_spacing_rel_diag.to_string(),
        "--indirect-threshold".into(),
        r.indirect_threshold.to_string(),
        "--light-samples".into(),
        r.light_samples.to_string(),
        "--contrast".into(),
        r.contrast.to_string(),
        "--exposure".into(),
        r.exposure.to_string(),
        "--stats-json".into(),
        o("render.stats.json"),
    ];
    if caustics && cfg.trace.caustic_photons > 0 {
        render_args.extend(["--caustic".into(), o("caustic.kd.pmap")]);
    }
    if !indirect {
        // No final gathers and no global map: drop it from the render's inputs.
        let i = render_args.iter().position(|x| x == "--global").expect("--global is in the render arguments");
        render_args.drain(i..i + 2);
        render_args.push("--no-indirect".into());
    }
    steps.push(("photon-render".into(), render_args, None));
    // Inputs (hashed) and outputs of each step, for skipping unchanged steps.
    let scene_files = scene_inputs(&scene)?;
    let map_in = |f: &str| vec![PathBuf::from(o(f))];
    let io: Vec<(String, Vec<PathBuf>, Vec<String>)> = vec![
        ("photon-trace".into(), scene_files.clone(), vec![o("global.pmap"), o("trace.stats.json")]),
        ("photon-sort global".into(), map_in("global.pmap"), vec![o("global.kd.pmap"), o("sort-global.stats.json")]),
        (
            "photon-sort caustic".into(),
            map_in("caustic.pmap"),
            vec![o("caustic.kd.pmap"), o("sort-caustic.stats.json")],
        ),
        ("photon-irradiance".into(), map_in("global.kd.pmap"), vec![o("global.irr.pmap"), o("irradiance.stats.json")]),
        (
            "photon-render".into(),
            [scene_files, map_in("global.irr.pmap"), map_in("caustic.kd.pmap")].concat(),
            vec![o("image.exr"), o("image.png"), o("render.stats.json")],
        ),
    ];
    let keys_path = out.join(".stage-keys.json");
    let mut keys: serde_json::Map<String, serde_json::Value> =
        std::fs::read(&keys_path).ok().and_then(|b| serde_json::from_slice(&b).ok()).unwrap_or_default();
    let mut outcomes = Vec::new();
    println!(
        "effects ({}):",
        if matches!(cfg.effects, EffectsCfg::Auto(_)) { "scene analysis" } else { "forced by pipeline.toml" }
    );
    for key in ["caustics", "indirect", "specular_seen", "glossy"] {
        let a = &analysis[key];
        println!("  {key}: {} ({})", if a["yes"] == true { "yes" } else { "no" }, a["reason"].as_str().unwrap_or(""));
    }
    println!("  direct: {}", analysis["direct"].as_str().unwrap_or(""));
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
    for (stage, a, _) in &steps {
        println!("  {stage} {}", a.join(" "));
    }
    let mut rows = Vec::new();
    for ((stage, a, needs), (step, inputs, outputs)) in steps.iter().zip(&io) {
        if let Some(input) = needs
            && !Path::new(input).exists()
        {
            println!("  {step}: skipped ({input} absent: the scene does not need it)");
            // What it wrote in an earlier run no longer belongs to this one.
            for f in outputs {
                let _ = std::fs::remove_file(f);
            }
            keys.remove(step);
            outcomes.push(Outcome { step: step.clone(), ran: false });
            continue;
        }
        let key = step_key(stage, a, inputs)?;
        if !args.force
            && keys.get(step).and_then(|k| k.as_str()) == Some(key.as_str())
            && outputs.iter().all(|f| Path::new(f).exists())
        {
            println!("  {step}: skipped (inputs and parameters unchanged)");
            outcomes.push(Outcome { step: step.clone(), ran: false });
            rows.push(json!({"stage": step, "seconds": 0.0, "figures": "unchanged, skipped", "skipped": true}));
            continue;
        }
        // A step about to run invalidates its recorded key until it succeeds.
        keys.remove(step);
        std::fs::write(&keys_path, serde_json::to_string_pretty(&keys)?)?;
        let mut a = a.clone();
        // The caustic map is optional: drop it when stage 1 wrote none.
        if let Some(i) = a.iter().position(|x| x == "--caustic")
            && !Path::new(&a[i + 1]).exists()
        {
            a.drain(i..i + 2);
        }
        let t = Instant::now();
        let status = Command::new(bin(stage)).args(&a).status().with_context(|| format!("cannot start {stage}"))?;
        let secs = t.elapsed().as_secs_f64();
        if !status.success() {
            bail!("stage {step} failed ({status}); earlier outputs in {} are intact", out.display());
        }
        println!("  {step}: done in {secs:.2} s");
        keys.insert(step.clone(), json!(key));
        std::fs::write(&keys_path, serde_json::to_string_pretty(&keys)?)?;
        outcomes.push(Outcome { step: step.clone(), ran: true });
        // Each stage's --stats-json is the argument after the flag.
        let stats_path = a.iter().position(|x| x == "--stats-json").and_then(|i| a.get(i + 1));
        let stats: serde_json::Value = match stats_path {
            Some(p) => serde_json::from_slice(&std::fs::read(p).with_context(|| format!("{p}: cannot read"))?)?,
            None => json!({}),
        };
        rows.push(json!({"stage": step, "seconds": secs, "figures": key_figures(stage, &stats), "stats": stats}));
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

/// blake3 over the stage, its arguments and the contents of its input files.
fn step_key(stage: &str, args: &[String], inputs: &[PathBuf]) -> Result<String> {
    let mut h = blake3::Hasher::new();
    h.update(stage.as_bytes());
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
    Ok(h.finalize().to_hex().to_string())
}

/// The scene file and the external buffers and images a .gltf references.
fn scene_inputs(scene: &Path) -> Result<Vec<PathBuf>> {
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

/// Build the stage binaries (release).
pub fn build_stages(root: &Path) -> Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(root)
        .args([
            "build",
            "--release",
            "--quiet",
            "-p",
            "photon-trace",
            "-p",
            "photon-sort",
            "-p",
            "photon-irradiance",
            "-p",
            "photon-render",
        ])
        .status()
        .context("cannot run cargo build")?;
    if !status.success() {
        bail!("building the stage binaries failed");
    }
    Ok(())
}

/// One line of the figures that matter for a stage, from its statistics.
fn key_figures(stage: &str, s: &serde_json::Value) -> String {
    match stage {
        "photon-trace" => format!(
            "global: {}; caustic: {}",
            s["global"].get("stored").map_or_else(
                || s["global"]["skipped"].to_string(),
                |n| format!("{} emitted / {n} stored", s["global"]["emitted"])
            ),
            s["caustic"].get("stored").map_or_else(|| s["caustic"]["skipped"].to_string(), |n| format!("{n} stored"))
        ),
        "photon-sort" => format!("{} photons, tree depth {}", s["photons"], s["depth"]),
        "photon-irradiance" => format!(
            "{} estimates (k = {}), median radius {:.4} m",
            s["computed"],
            s["k"],
            s["radius_m"]["p50"].as_f64().unwrap_or(0.0)
        ),
        "photon-render" => format!(
            "{}x{} {}, {:.2} samples/pixel, {} final gathers, {} gather rays",
            s["width"],
            s["height"],
            s["mode"].as_str().unwrap_or(""),
            s["samples_per_pixel"].as_f64().unwrap_or(0.0),
            s["final_gathers"],
            s["gather_rays"]
        ),
        _ => String::new(),
    }
}

/// Range checks that name the offending key (serde checked names and types).
fn validate(cfg: &Pipeline, path: &Path) -> Result<()> {
    let check = |key: &str, ok: bool, v: &dyn std::fmt::Display, want: &str| -> Result<()> {
        if ok { Ok(()) } else { bail!("{}: {key} = {v} is out of range ({want})", path.display()) }
    };
    check("width", (1..=16384).contains(&cfg.width), &cfg.width, "1 to 16384")?;
    check("height", (1..=16384).contains(&cfg.height), &cfg.height, "1 to 16384")?;
    check("spp", cfg.spp >= 1, &cfg.spp, "at least 1")?;
    let f = cfg.irradiance.fraction;
    check("irradiance.fraction", f > 0.0 && f <= 1.0, &f, "in (0, 1]")?;
    check("irradiance.k", cfg.irradiance.k >= 1, &cfg.irradiance.k, "at least 1")?;
    let r = cfg.irradiance.max_radius_rel_diag;
    check("irradiance.max_radius_rel_diag", r > 0.0, &r, "positive")?;
    check("render.gather_rays", cfg.render.gather_rays >= 1, &cfg.render.gather_rays, "at least 1")?;
    let a = cfg.render.icache_accuracy;
    check("render.icache_accuracy", a >= 0.0, &a, "0 (off) or positive")?;
    check("render.k", cfg.render.k >= 1, &cfg.render.k, "at least 1")?;
    check("render.caustic_k", cfg.render.caustic_k >= 1, &cfg.render.caustic_k, "at least 1")?;
    for (name, share) in &cfg.trace.light_shares {
        check(&format!("trace.light_shares.{name}"), (0.0..=1.0).contains(share), share, "in [0, 1]")?;
    }
    Ok(())
}
