//! Stage 1 of the pipeline (Christensen 1999 section 1.1): emit photons from the
//! scene's lights, trace them, and write `global.pmap`, `caustic.pmap` and, in a
//! scene with a scattering medium, `volume.pmap` (unsorted) in the photon-map
//! format. A thin layer over `pm-photon`.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use pm_format::{
    CompactIrrPhoton, CompactPhoton, FullIrrPhoton, FullPhoton, Header, Layout, MapKind, Order, Photon, PhotonMap,
    PhotonRecord,
};
use pm_photon::{Budget, LightSelector, MapPass, MapStats, RecordLayout, Slice, TraceConfig, TraceParams, TracedSlice};
use pm_stage::Progress;
use pm_stage::report::{LightReport, MapReport, TraceReport};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Command line of `photon-trace`.
#[derive(Parser, Debug)]
#[command(
    name = "photon-trace",
    about = "Stage 1: emit photons from the lights and trace them into global, caustic and volume photon maps",
    long_about = "Stage 1 (Christensen 1999, section 1.1). Emits photons from the scene's lights (chosen in \
proportion to power in W), traces them with the scene's BSDFs and Russian roulette, and writes DIR/global.pmap \
(every non-specular hit, 23-byte records with surface normal) and DIR/caustic.pmap (light-specular+-diffuse \
paths only, 18-byte records) and, when the scene has a scattering medium, DIR/volume.pmap (every scattering \
event in a medium, Jensen and Christensen 1998, 18-byte records flagged volume). Photon power is in W per RGB \
channel. The caustic map is absent when the scene has no mirror or glass.",
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
    /// Merge the output folders of every `--slice J/M` of one trace into
    /// global.pmap, caustic.pmap and volume.pmap, byte-identical to tracing in one
    /// run.
    Merge {
        /// The slices' output folders (any order), one per slice.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Output folder for the merged maps (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Write the merged maps' statistics (as photon-trace's) as JSON.
        #[arg(long)]
        stats_json: Option<PathBuf>,
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
    pub scene_options: pm_stage::SceneOptions,
    /// Output folder for global.pmap, caustic.pmap and volume.pmap (created if
    /// missing).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Photon counts and record layout (pipeline.toml's [trace] section).
    #[command(flatten)]
    pub params: TraceParams,
    /// Emit exactly N global photons instead of a stored target (overrides
    /// --global-photons).
    #[arg(long)]
    pub emit_global: Option<u64>,
    /// Emit exactly M caustic photons instead of a stored target (overrides --caustic-photons).
    #[arg(long)]
    pub emit_caustic: Option<u64>,
    /// Emit exactly V volume photons instead of a stored target (overrides --volume-photons).
    #[arg(long)]
    pub emit_volume: Option<u64>,
    /// Stop emitting for a map after this many photons even if its target is not reached
    /// [default: 100 x target + 1,000,000].
    #[arg(long)]
    pub max_emitted: Option<u64>,
    /// Random seed; equal seeds give byte-identical maps for any thread count.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Trace only slice J of M of the emission index space (paths in chunks of 256;
    /// chunk c belongs to slice c mod M) into slice files, for tracing on M machines;
    /// `photon-trace merge` joins the M output folders into the maps one run writes.
    /// With a stored target each slice stops at its share plus 10%.
    #[arg(long, value_name = "J/M", value_parser = parse_slice)]
    pub slice: Option<Slice>,
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

fn parse_slice(s: &str) -> Result<Slice, String> {
    let (index, count) = pm_stage::parse_part(s, "slice")?;
    Ok(Slice { index, count })
}

/// Run the stage.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Merge { inputs, out, stats_json }) => {
            let report = merge(&inputs, &out)?;
            if let Some(p) = &stats_json {
                pm_stage::write_json(p, &serde_json::to_value(&report)?)?;
            }
            Ok(())
        }
        None => trace(&cli.trace).map(|_| ()),
    }
}

/// Trace both maps and write them (or, with `--analyze`, print the scene analysis
/// and return no report).
pub fn trace(args: &TraceArgs) -> Result<Option<TraceReport>> {
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
    let scene = pm_stage::load_scene("photon-trace", scene_path, &args.scene_options)?;
    if args.analyze {
        println!("{}", serde_json::to_string_pretty(&pm_light::analyze(&scene))?);
        return Ok(None);
    }
    let light_shares = args.params.light_shares();
    let selector = LightSelector::new(&scene, &light_shares).with_context(|| scene_path.display().to_string())?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create output folder", out.display()))?;
    let full = args.params.layout == RecordLayout::Full;
    let budget = |emit: Option<u64>, target: u64| match emit {
        Some(n) => Budget::Emitted(n),
        None => Budget::Stored {
            target,
            cap: args.max_emitted.unwrap_or(target.saturating_mul(100).saturating_add(1_000_000)),
        },
    };
    let mut report = TraceReport {
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
    let lights: Vec<String> = scene.lights.iter().map(|l| l.name.clone()).collect();
    for (pass, kind, name) in MAPS {
        let budget = match kind {
            MapKind::Global => budget(args.emit_global, args.params.global_photons),
            MapKind::Caustic => budget(args.emit_caustic, args.params.caustic_photons),
            MapKind::Volume => budget(args.emit_volume, args.params.volume_photons),
        };
        let path = out.join(format!("{name}.pmap"));
        let wanted = !matches!(budget, Budget::Stored { target: 0, .. } | Budget::Emitted(0));
        let cannot = match kind {
            MapKind::Caustic if pm_photon::specular_targets(&scene).is_empty() => {
                Some("the scene has no mirror or glass surface")
            }
            MapKind::Volume if !scene.has_scattering_media() => Some("the scene has no scattering medium"),
            _ => None,
        };
        if !wanted || cannot.is_some() {
            let why = cannot.filter(|_| wanted).unwrap_or("no photons requested");
            remove_stale(&path)?;
            *map_slot(&mut report, kind) = MapReport { skipped: Some(why.into()), ..Default::default() };
            eprintln!("photon-trace: no {name} map: {why}");
            continue;
        }
        let cfg = TraceConfig { pass, budget, seed: args.seed, selector: selector.clone() };
        let total = match budget {
            Budget::Stored { target, .. } => target,
            Budget::Emitted(_) => 0,
        };
        let progress = Progress::new(&format!("trace {name}"), total);
        let slice = args.slice.unwrap_or(Slice::WHOLE);
        let traced = pm_photon::trace_slice(&scene, &cfg, slice, &|n| progress.set(n))
            .with_context(|| scene_path.display().to_string())?;
        let secs = progress.finish();
        let params = MapParams { seed: args.seed, budget, layout: args.params.layout, light_shares: &light_shares };
        let header = |order, layout, n_emitted, params: String| {
            Header::new(kind, order, layout, n_emitted, scene.content_hash, scene.bounds.diagonal(), params)
                .with_origin(scene.origin.to_array())
        };
        if args.slice.is_some() {
            // A slice keeps full precision and unscaled power: the merge scales and
            // encodes, as the single run does.
            let layout = if kind == MapKind::Global { Layout::FullIrradiance } else { Layout::Full };
            let meta = SliceParams {
                map: params.json(),
                slice,
                budget,
                lights: lights.clone(),
                chunks: traced.chunks.clone(),
            };
            write_map(
                &path,
                header(Order::Slice, layout, 0, serde_json::to_string(&meta)?),
                &traced.photons,
                true,
                kind,
            )?;
            // Unscaled power is no power: the slice reports none.
            *map_slot(&mut report, kind) = map_report(&traced.totals(), [0.0; 3], &lights, secs);
            continue;
        }
        let traced = pm_photon::merge_slices(vec![traced]).map_err(|e| anyhow::anyhow!("internal error: {e}"))?;
        if traced.stats.hit_cap {
            eprintln!(
                "photon-trace: warning: {name} map: emission cap reached after {} photons with {} stored",
                traced.stats.emitted, traced.stats.stored
            );
        }
        let h = header(Order::Unsorted, Layout::Compact, traced.stats.emitted, params.json().to_string());
        write_map(&path, h, &traced.photons, full, kind)?;
        let power = pm_photon::total_power(&traced.photons).to_array();
        *map_slot(&mut report, kind) = map_report(&traced.stats, power, &lights, secs);
    }
    report.seconds = start.elapsed().as_secs_f64();
    if let Some(p) = &args.stats_json {
        pm_stage::write_json(p, &serde_json::to_value(&report)?)?;
    }
    Ok(Some(report))
}

/// The maps stage 1 writes: its pass, its kind and its file's name (NAME.pmap).
const MAPS: [(MapPass, MapKind, &str); 3] = [
    (MapPass::Global, MapKind::Global, "global"),
    (MapPass::Caustic, MapKind::Caustic, "caustic"),
    (MapPass::Volume, MapKind::Volume, "volume"),
];

fn map_slot(report: &mut TraceReport, kind: MapKind) -> &mut MapReport {
    match kind {
        MapKind::Global => &mut report.global,
        MapKind::Caustic => &mut report.caustic,
        MapKind::Volume => &mut report.volume,
    }
}

/// The global map carries the surface normal (23/64-byte layouts) so the irradiance
/// precompute and the renderer's leak tests need no scene lookups; the caustic map
/// uses the paper's 18-byte record (40 bytes full).
fn write_map(path: &Path, header: Header, photons: &[Photon], full: bool, kind: MapKind) -> Result<()> {
    fn write<R: pm_format::PhotonRecord>(path: &Path, header: Header, photons: &[Photon]) -> Result<()> {
        PhotonMap::new(header, photons.iter().map(R::encode).collect::<Vec<R>>()).write(path)?;
        Ok(())
    }
    match (kind, full) {
        (MapKind::Global, false) => write::<CompactIrrPhoton>(path, header, photons),
        (MapKind::Global, true) => write::<FullIrrPhoton>(path, header, photons),
        (MapKind::Caustic | MapKind::Volume, false) => write::<CompactPhoton>(path, header, photons),
        (MapKind::Caustic | MapKind::Volume, true) => write::<FullPhoton>(path, header, photons),
    }
}

/// A map's report from its statistics, the summed power of its photons [W per
/// channel] and the names of the scene's lights.
fn map_report(s: &MapStats, total_power_w: [f64; 3], lights: &[String], secs: f64) -> MapReport {
    MapReport {
        skipped: None,
        emitted: s.emitted,
        stored: s.stored,
        stored_per_bounce: s.stored_per_bounce.clone(),
        emitted_per_light: lights.iter().zip(&s.emitted_per_light).map(|(l, n)| (l.clone(), *n)).collect(),
        reached_fraction_per_light: lights
            .iter()
            .zip(s.emitted_per_light.iter().zip(&s.reached_per_light))
            .map(|(l, (&n, &r))| (l.clone(), if n > 0 { r as f64 / n as f64 } else { 0.0 }))
            .collect(),
        rays: s.rays,
        truncated_paths: s.truncated_paths,
        hit_emission_cap: s.hit_cap,
        total_power_w,
        seconds: secs,
        paths_per_second: if secs > 0.0 { s.emitted as f64 / secs } else { 0.0 },
        rays_per_second: if secs > 0.0 { s.rays as f64 / secs } else { 0.0 },
    }
}

fn remove_stale(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e).with_context(|| format!("{}: cannot remove stale map", path.display())),
    }
}

/// What produced a map, as its header's parameters (JSON).
struct MapParams<'a> {
    seed: u64,
    budget: Budget,
    layout: RecordLayout,
    light_shares: &'a [(String, f64)],
}

impl MapParams<'_> {
    fn json(&self) -> serde_json::Value {
        json!({
            "seed": self.seed,
            "budget": format!("{:?}", self.budget),
            "layout": self.layout,
            "light_shares": self.light_shares,
        })
    }
}

/// A slice file's header parameters: the map's (which the merged map gets), the
/// slice, its budget, the scene's light names and what each of its chunks stored.
#[derive(serde::Serialize, serde::Deserialize)]
struct SliceParams {
    map: serde_json::Value,
    slice: Slice,
    budget: Budget,
    lights: Vec<String>,
    chunks: Vec<pm_photon::ChunkStats>,
}

/// Merge the output folders of every slice of one trace (`--slice J/M`) into
/// `out`/global.pmap, caustic.pmap and volume.pmap, byte-identical to one run's
/// maps.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<TraceReport> {
    let start = Instant::now();
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create output folder", out.display()))?;
    let mut report = TraceReport { scene: format!("{} slices", inputs.len()), threads: 1, ..Default::default() };
    for (_, kind, name) in MAPS {
        let file = format!("{name}.pmap");
        let present: Vec<&PathBuf> = inputs.iter().filter(|d| d.join(&file).exists()).collect();
        let target = out.join(&file);
        if present.is_empty() {
            remove_stale(&target)?;
            *map_slot(&mut report, kind) =
                MapReport { skipped: Some("no slice holds this map".into()), ..Default::default() };
            continue;
        }
        if present.len() != inputs.len() {
            let missing = inputs.iter().find(|d| !d.join(&file).exists()).expect("some slice lacks it");
            bail!("{}: no {file}, which the other slices have", missing.display());
        }
        let expect = pm_format::ReadExpect { kind: Some(kind), order: Some(Order::Slice), ..Default::default() };
        let mut slices = Vec::new();
        let mut first: Option<(Header, serde_json::Value, Vec<String>, PathBuf)> = None;
        for dir in inputs {
            let path = dir.join(&file);
            let m = pm_format::read(&path, &expect)?;
            let h = m.header().clone();
            let meta: SliceParams = serde_json::from_str(&h.params)
                .with_context(|| format!("{}: header parameters are not a slice's", path.display()))?;
            if let Some((h0, map0, _, p0)) = &first {
                let same = (h.scene_hash, h.scene_diagonal, h.origin) == (h0.scene_hash, h0.scene_diagonal, h0.origin);
                if !same || &meta.map != map0 {
                    bail!(
                        "{}: not a slice of the same trace as {} (scene or parameters differ)",
                        path.display(),
                        p0.display()
                    );
                }
            } else {
                first = Some((h.clone(), meta.map.clone(), meta.lights.clone(), path.clone()));
            }
            if !matches!(h.layout, Layout::Full | Layout::FullIrradiance) {
                bail!("{}: a slice must hold full-precision records, not {:?}", path.display(), h.layout);
            }
            let photons: Vec<pm_format::Photon> =
                pm_format::with_map!(&m, mm => mm.records.iter().map(|r| r.decode()).collect());
            slices.push(TracedSlice {
                slice: meta.slice,
                budget: meta.budget,
                chunks: meta.chunks,
                photons,
                bounces: Vec::new(),
            });
        }
        let (h0, map0, lights, _) = first.expect("at least one slice");
        let traced = pm_photon::merge_slices(slices).map_err(|e| anyhow::anyhow!("{}: {e}", out.display()))?;
        let layout: RecordLayout = serde_json::from_value(map0["layout"].clone())
            .with_context(|| format!("{}: record layout unreadable", target.display()))?;
        let header = Header::new(
            kind,
            Order::Unsorted,
            Layout::Compact,
            traced.stats.emitted,
            h0.scene_hash,
            h0.scene_diagonal,
            map0.to_string(),
        )
        .with_origin(h0.origin);
        write_map(&target, header, &traced.photons, layout == RecordLayout::Full, kind)?;
        let power = pm_photon::total_power(&traced.photons).to_array();
        *map_slot(&mut report, kind) = map_report(&traced.stats, power, &lights, 0.0);
    }
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}
