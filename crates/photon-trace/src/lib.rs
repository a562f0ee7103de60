//! Stage 1 of the pipeline (Christensen 1999 section 1.1): emit photons from the
//! scene's lights, trace them, and write `global.pmap` and `caustic.pmap`
//! (unsorted) in the photon-map format. A thin layer over `pm-photon`.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use pm_format::{
    CompactIrrPhoton, CompactPhoton, FullIrrPhoton, FullPhoton, Header, MapKind, Order, Photon, PhotonMap,
};
use pm_photon::{Budget, LightSelector, MapPass, RecordLayout, TraceConfig, TraceParams, TracedMap};
use pm_stage::Progress;
use serde_json::json;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Command line of `photon-trace`.
#[derive(Parser, Debug)]
#[command(
    name = "photon-trace",
    about = "Stage 1: emit photons from the lights and trace them into global and caustic photon maps",
    long_about = "Stage 1 (Christensen 1999, section 1.1). Emits photons from the scene's lights (chosen in \
proportion to power in W), traces them with the scene's BSDFs and Russian roulette, and writes DIR/global.pmap \
(every non-specular hit, 23-byte records with surface normal) and DIR/caustic.pmap (light-specular+-diffuse \
paths only, 18-byte records). Photon power is in W per RGB channel. The caustic map is absent when the scene \
has no mirror or glass.",
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    trace: TraceArgs,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Concatenate photon-map slices traced with --photon-range into one map,
    /// byte-identical to tracing the whole range in one run.
    Merge {
        /// Slices of one map (any order), covering 0..N without gaps.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Merged map.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Arguments of a tracing run.
#[derive(Args, Debug, Clone)]
pub struct TraceArgs {
    /// Scene (glTF 2.0: .gltf or .glb).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// How the scene file is read.
    #[command(flatten)]
    pub scene_args: pm_stage::SceneArgs,
    /// Output folder for global.pmap and caustic.pmap (created if missing).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Photon counts and record layout (pipeline.toml's [trace] section).
    #[command(flatten)]
    pub params: TraceParams,
    /// Emit exactly N global photons instead of a stored target (needed with
    /// --photon-range; overrides --global-photons).
    #[arg(long)]
    pub emit_global: Option<u64>,
    /// Emit exactly M caustic photons instead of a stored target (overrides --caustic-photons).
    #[arg(long)]
    pub emit_caustic: Option<u64>,
    /// Stop emitting for a map after this many photons even if its target is not reached
    /// [default: 100 x target + 1,000,000].
    #[arg(long)]
    pub max_emitted: Option<u64>,
    /// Random seed; equal seeds give byte-identical maps for any thread count.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Trace only photons FIRST..END of the emission index space (with --emit-*); merge the
    /// slices with `photon-trace merge`.
    #[arg(long, value_parser = parse_range)]
    pub photon_range: Option<Range<u64>>,
    /// Give light NAME this fraction of the photon budget (repeatable); other lights share
    /// the rest in proportion to their power.
    #[arg(long = "light-share", value_parser = parse_share)]
    pub light_shares: Vec<(String, f64)>,
    /// Write statistics (counts, photons per bounce, time) as JSON.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Print which effects the scene can produce (caustics, soft indirect, specular
    /// seen by the camera, glossy, direct) with reasons, as JSON, and trace nothing.
    #[arg(long)]
    pub analyze: bool,
}

fn parse_range(s: &str) -> Result<Range<u64>, String> {
    let (a, b) = s.split_once("..").ok_or("expected FIRST..END")?;
    let a: u64 = a.trim().parse().map_err(|e| format!("FIRST: {e}"))?;
    let b: u64 = b.trim().parse().map_err(|e| format!("END: {e}"))?;
    if a >= b {
        return Err(format!("empty range {a}..{b}"));
    }
    Ok(a..b)
}

fn parse_share(s: &str) -> Result<(String, f64), String> {
    let (n, w) = s.rsplit_once('=').ok_or("expected NAME=FRACTION")?;
    let w: f64 = w.parse().map_err(|e| format!("FRACTION: {e}"))?;
    Ok((n.to_owned(), w))
}

/// What a tracing run did: written as `--stats-json` and read back by the runner
/// into this type, so the writer and the reader cannot disagree on a key.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Report {
    /// Scene file.
    pub scene: String,
    /// Worker threads.
    pub threads: usize,
    /// Each light, its power [W per channel] and the probability of emitting from it.
    pub lights: Vec<LightReport>,
    /// The global map.
    pub global: MapReport,
    /// The caustic map.
    pub caustic: MapReport,
    /// Wall time of the stage [s].
    pub seconds: f64,
}

/// One light of [`Report`].
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct LightReport {
    /// Its name.
    pub name: String,
    /// Emitted power Phi [W per channel].
    pub power_w: [f32; 3],
    /// Probability of choosing it for a photon.
    pub selection_probability: f64,
}

/// One map of [`Report`]: why it was skipped, or what tracing it did.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct MapReport {
    /// Why no map was written (absent when one was).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
    /// Photons emitted (the power scale's N).
    pub emitted: u64,
    /// Photons stored.
    pub stored: u64,
    /// Stored photons by bounces before the store (index 0: direct).
    pub stored_per_bounce: Vec<u64>,
    /// Photons emitted per light, by light name.
    pub emitted_per_light: Vec<(String, u64)>,
    /// Rays traced.
    pub rays: u64,
    /// Paths cut by the bounce limit.
    pub truncated_paths: u64,
    /// True when emission stopped at the cap before reaching the target.
    pub hit_emission_cap: bool,
    /// Sum of stored photon power [W per channel].
    pub total_power_w: [f64; 3],
    /// Wall time [s].
    pub seconds: f64,
    /// Photon paths per second.
    pub paths_per_second: f64,
    /// Rays per second.
    pub rays_per_second: f64,
}

/// Run the stage.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Merge { inputs, out }) => merge(&inputs, &out).map(|_| ()),
        None => trace(&cli.trace).map(|_| ()),
    }
}

/// Trace both maps and write them (or, with `--analyze`, print the scene analysis
/// and return no report).
pub fn trace(args: &TraceArgs) -> Result<Option<Report>> {
    let scene_path = args.scene.as_ref().context("--scene is required")?;
    args.params.validate(pm_params::Naming::Cli).map_err(|e| anyhow::anyhow!(e))?;
    let out = match (&args.out, args.analyze) {
        (Some(o), _) => o.clone(),
        (None, true) => PathBuf::new(),
        (None, false) => anyhow::bail!("--out is required"),
    };
    let out = &out;
    pm_stage::init_threads(args.threads)?;
    let start = Instant::now();
    let scene = pm_stage::load_scene("photon-trace", scene_path, args.scene_args)?;
    if args.analyze {
        println!("{}", serde_json::to_string_pretty(&pm_scene::analyze(&scene))?);
        return Ok(None);
    }
    let selector = LightSelector::new(&scene, &args.light_shares).with_context(|| scene_path.display().to_string())?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create output folder", out.display()))?;
    let full = args.params.layout == RecordLayout::Full;
    let budget = |emit: Option<u64>, target: u64| match emit {
        Some(n) => Budget::Emitted(n),
        None => Budget::Stored {
            target,
            cap: args.max_emitted.unwrap_or(target.saturating_mul(100).saturating_add(1_000_000)),
        },
    };
    let mut report = Report {
        scene: scene_path.display().to_string(),
        threads: pm_stage::thread_count(),
        lights: scene
            .lights
            .iter()
            .zip(&selector.probs)
            .map(|(l, p)| LightReport { name: l.name.clone(), power_w: l.power.to_array(), selection_probability: *p })
            .collect(),
        ..Default::default()
    };
    let passes = [
        (MapPass::Global, MapKind::Global, "global", budget(args.emit_global, args.params.global_photons)),
        (MapPass::Caustic, MapKind::Caustic, "caustic", budget(args.emit_caustic, args.params.caustic_photons)),
    ];
    for (pass, kind, name, budget) in passes {
        let path = out.join(format!("{name}.pmap"));
        let wanted = !matches!(budget, Budget::Stored { target: 0, .. } | Budget::Emitted(0));
        let no_targets = pass == MapPass::Caustic && pm_photon::specular_targets(&scene).is_empty();
        if !wanted || no_targets {
            let why = if wanted { "the scene has no mirror or glass surface" } else { "no photons requested" };
            remove_stale(&path)?;
            *map_slot(&mut report, pass) = MapReport { skipped: Some(why.into()), ..Default::default() };
            eprintln!("photon-trace: no {name} map: {why}");
            continue;
        }
        let cfg =
            TraceConfig { pass, budget, seed: args.seed, selector: selector.clone(), range: args.photon_range.clone() };
        let total = match budget {
            Budget::Stored { target, .. } => target,
            Budget::Emitted(_) => 0,
        };
        let progress = Progress::new(&format!("trace {name}"), total);
        let traced =
            pm_photon::trace(&scene, &cfg, &|n| progress.set(n)).with_context(|| scene_path.display().to_string())?;
        let secs = progress.finish();
        if traced.stats.hit_cap {
            eprintln!(
                "photon-trace: warning: {name} map: emission cap reached after {} photons with {} stored",
                traced.stats.emitted, traced.stats.stored
            );
        }
        let params = json!({
            "seed": args.seed,
            "budget": format!("{budget:?}"),
            "layout": args.params.layout,
            "light_shares": args.light_shares,
        });
        let mut params_with_range = params.clone();
        params_with_range["photon_range"] = json!(args.photon_range.as_ref().map(|r| [r.start, r.end]));
        let header = Header::new(
            kind,
            Order::Unsorted,
            pm_format::Layout::Compact,
            traced.stats.emitted,
            scene.content_hash,
            scene.bounds.diagonal(),
            params_with_range.to_string(),
        )
        .with_origin(scene.origin.to_array());
        write_map(&path, header, &traced.photons, full, pass)?;
        *map_slot(&mut report, pass) = map_report(&traced, &scene, secs);
    }
    report.seconds = start.elapsed().as_secs_f64();
    if let Some(p) = &args.stats_json {
        pm_stage::write_json(p, &serde_json::to_value(&report)?)?;
    }
    Ok(Some(report))
}

fn map_slot(report: &mut Report, pass: MapPass) -> &mut MapReport {
    match pass {
        MapPass::Global => &mut report.global,
        MapPass::Caustic => &mut report.caustic,
    }
}

/// The global map carries the surface normal (23/64-byte layouts) so the irradiance
/// precompute and the renderer's leak tests need no scene lookups; the caustic map
/// uses the paper's 18-byte record (40 bytes full).
fn write_map(path: &Path, header: Header, photons: &[Photon], full: bool, pass: MapPass) -> Result<()> {
    fn write<R: pm_format::PhotonRecord>(path: &Path, header: Header, photons: &[Photon]) -> Result<()> {
        PhotonMap::new(header, photons.iter().map(R::encode).collect::<Vec<R>>()).write(path)?;
        Ok(())
    }
    match (pass, full) {
        (MapPass::Global, false) => write::<CompactIrrPhoton>(path, header, photons),
        (MapPass::Global, true) => write::<FullIrrPhoton>(path, header, photons),
        (MapPass::Caustic, false) => write::<CompactPhoton>(path, header, photons),
        (MapPass::Caustic, true) => write::<FullPhoton>(path, header, photons),
    }
}

fn map_report(traced: &TracedMap, scene: &pm_scene::Scene, secs: f64) -> MapReport {
    let s = &traced.stats;
    MapReport {
        skipped: None,
        emitted: s.emitted,
        stored: s.stored,
        stored_per_bounce: s.stored_per_bounce.clone(),
        emitted_per_light: scene.lights.iter().zip(&s.emitted_per_light).map(|(l, n)| (l.name.clone(), *n)).collect(),
        rays: s.rays,
        truncated_paths: s.truncated_paths,
        hit_emission_cap: s.hit_cap,
        total_power_w: pm_photon::total_power(&traced.photons).to_array(),
        seconds: secs,
        paths_per_second: s.emitted as f64 / secs.max(1e-9),
        rays_per_second: s.rays as f64 / secs.max(1e-9),
    }
}

fn remove_stale(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e).with_context(|| format!("{}: cannot remove stale map", path.display())),
    }
}

/// Merge slices traced with `--photon-range` into one map.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<serde_json::Value> {
    let mut maps = Vec::new();
    for p in inputs {
        let m = pm_format::read(p, &pm_format::ReadExpect { order: Some(Order::Unsorted), ..Default::default() })?;
        let params: serde_json::Value = serde_json::from_str(&m.header().params)
            .with_context(|| format!("{}: header parameters are not JSON", p.display()))?;
        let range = params["photon_range"]
            .as_array()
            .and_then(|a| Some(a.first()?.as_u64()?..a.get(1)?.as_u64()?))
            .with_context(|| format!("{}: not a --photon-range slice", p.display()))?;
        let mut base = params.clone();
        base["photon_range"] = serde_json::Value::Null;
        maps.push((range, base, p.clone(), m));
    }
    maps.sort_by_key(|m| m.0.start);
    let (_, base, first_path, first) = &maps[0];
    let h0 = first.header().clone();
    let mut expected_start = 0;
    for (range, params, path, m) in &maps {
        let h = m.header();
        if (h.kind, h.layout, h.scene_hash, h.n_emitted) != (h0.kind, h0.layout, h0.scene_hash, h0.n_emitted)
            || params != base
        {
            bail!(
                "{}: not a slice of the same map as {} (kind, layout, scene, emitted count or parameters differ)",
                path.display(),
                first_path.display()
            );
        }
        // Ranges are clipped to the emitted count (a slice past the end is empty).
        let start = range.start.min(h0.n_emitted);
        if start != expected_start {
            bail!(
                "{}: slice starts at {start} but the slices before it end at {expected_start} (gap or overlap)",
                path.display()
            );
        }
        expected_start = range.end.min(h0.n_emitted);
    }
    if expected_start != h0.n_emitted {
        bail!("slices cover 0..{expected_start} but the map emitted {} photons", h0.n_emitted);
    }
    let mut header = h0.clone();
    header.params = base.to_string();
    macro_rules! cat {
        ($variant:ident) => {{
            let mut records = Vec::new();
            for (_, _, _, m) in &maps {
                if let pm_format::AnyMap::$variant(m) = m {
                    records.extend_from_slice(&m.records);
                }
            }
            let mut merged = PhotonMap::new(header, records);
            merged.write(out)?;
            merged.records.len()
        }};
    }
    let n = match first {
        pm_format::AnyMap::Compact(_) => cat!(Compact),
        pm_format::AnyMap::CompactIrr(_) => cat!(CompactIrr),
        pm_format::AnyMap::Full(_) => cat!(Full),
        pm_format::AnyMap::FullIrr(_) => cat!(FullIrr),
    };
    Ok(json!({"stage": "photon-trace merge", "slices": maps.len(), "photons": n, "out": out.display().to_string()}))
}
