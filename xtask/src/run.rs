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
    trace: TraceSection,
    irradiance: IrradianceSection,
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
}

fn parse(args: &[String], root: &Path) -> Result<Args> {
    let mut a = Args { pipeline: root.join("pipeline.toml"), scene: None, out: None };
    let mut it = args.iter();
    while let Some(x) = it.next() {
        match x.as_str() {
            "--scene" => a.scene = Some(PathBuf::from(it.next().context("--scene needs a file")?)),
            "--out" => a.out = Some(PathBuf::from(it.next().context("--out needs a folder")?)),
            s if s.starts_with("--") => bail!("unknown option {s}"),
            s => a.pipeline = PathBuf::from(s),
        }
    }
    Ok(a)
}

/// Run the pipeline.
pub fn run(args: &[String], root: &Path) -> Result<()> {
    let args = parse(args, root)?;
    let text =
        std::fs::read_to_string(&args.pipeline).with_context(|| format!("{}: cannot read", args.pipeline.display()))?;
    let cfg: Pipeline = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", args.pipeline.display(), e.to_string().replace('\n', " ")))?;
    for (key, v) in
        [("trace.global_photons", cfg.trace.global_photons), ("trace.caustic_photons", cfg.trace.caustic_photons)]
    {
        if v > MAX_PHOTONS {
            bail!(
                "{}: {key} = {v} would need about {} GiB; this machine allows at most {MAX_PHOTONS}",
                args.pipeline.display(),
                v * 2 * 64 >> 30
            );
        }
    }
    let base = args.pipeline.parent().unwrap_or(Path::new("."));
    let scene = args.scene.clone().unwrap_or_else(|| base.join(&cfg.scene));
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out").join(&name));
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;

    build_stages(root)?;
    let bin = |n: &str| root.join("target/release").join(n);
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
        cfg.trace.global_photons.to_string(),
        "--caustic".into(),
        cfg.trace.caustic_photons.to_string(),
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
    println!("plan ({} -> {}):", scene.display(), out.display());
    for (stage, a, _) in &steps {
        println!("  {stage} {}", a.join(" "));
    }
    let mut rows = Vec::new();
    for (stage, a, needs) in &steps {
        if let Some(input) = needs {
            if !Path::new(input).exists() {
                println!("  {stage}: skipped ({input} absent: the scene does not need it)");
                continue;
            }
        }
        let t = Instant::now();
        let status = Command::new(bin(stage)).args(a).status().with_context(|| format!("cannot start {stage}"))?;
        let secs = t.elapsed().as_secs_f64();
        if !status.success() {
            bail!("stage {stage} failed ({status}); earlier outputs in {} are intact", out.display());
        }
        println!("  {stage}: done in {secs:.2} s");
        // Each stage's --stats-json is the argument after the flag.
        let stats_path = a.iter().position(|x| x == "--stats-json").and_then(|i| a.get(i + 1));
        let stats: serde_json::Value = match stats_path {
            Some(p) => serde_json::from_slice(&std::fs::read(p).with_context(|| format!("{p}: cannot read"))?)?,
            None => json!({}),
        };
        rows.push(json!({"stage": stage, "seconds": secs, "figures": key_figures(stage, &stats), "stats": stats}));
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
    let report = json!({"scene": scene.display().to_string(), "out": out.display().to_string(), "stages": rows});
    std::fs::write(out.join("report.json"), serde_json::to_string_pretty(&report)? + "\n")?;
    Ok(())
}

fn build_stages(root: &Path) -> Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(root)
        .args(["build", "--release", "--quiet", "-p", "photon-trace", "-p", "photon-sort", "-p", "photon-irradiance"])
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
            "global: {} emitted / {} stored; caustic: {}",
            s["global"]["emitted"],
            s["global"]["stored"],
            s["caustic"].get("stored").map_or_else(|| s["caustic"]["skipped"].to_string(), |n| format!("{n} stored"))
        ),
        "photon-sort" => format!("{} photons, tree depth {}", s["photons"], s["depth"]),
        "photon-irradiance" => format!(
            "{} estimates (k = {}), median radius {:.4} m",
            s["computed"],
            s["k"],
            s["radius_m"]["p50"].as_f64().unwrap_or(0.0)
        ),
        _ => String::new(),
    }
}
