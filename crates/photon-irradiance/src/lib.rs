//! Stage 3 of the pipeline (Christensen 1999 section 2.1): estimate the irradiance
//! at a spatially uniform subset of the global photons and store it, with the
//! photon's surface normal, in the 23-byte (or 64-byte) records. A thin layer over
//! `pm-estimate`.

use anyhow::{Result, bail};
use clap::Parser;
use pm_estimate::{IrradianceParams, KnnParams};
use pm_format::{MapKind, Order, ReadExpect, with_map};
use pm_stage::Progress;
use pm_stage::report::IrradianceReport;
use serde_json::json;
use std::path::PathBuf;

/// Command line of `photon-irradiance`.
#[derive(Parser, Debug)]
#[command(
    name = "photon-irradiance",
    about = "Stage 3: precompute irradiance (W/m^2) at a subset of the global photons",
    long_about = "Stage 3 (Christensen 1999, section 2.1). Reads the sorted global map (global.kd.pmap), estimates \
the irradiance E [W m^-2 per RGB channel] at a spatially uniform fraction of the photons from their k nearest \
neighbours on the same side of the surface (E = sum of photon power / (pi r^2)), and writes the same tree with the \
irradiance stored in the selected photons (global.irr.pmap). The final gather then looks up the nearest photon \
with a similar normal instead of estimating. With --scene (as `cargo xtask run` gives it), each estimate leaves out \
the photons of a surface a gap behind or in front of the photon's own (a ceiling just above a light's back, the \
floor around a box's top)."
)]
pub struct Cli {
    /// Sorted global photon map (global.kd.pmap).
    pub input: PathBuf,
    /// Output map (global.irr.pmap).
    #[arg(long)]
    pub out: PathBuf,
    /// The scene the map was traced in (glTF 2.0). Without it, estimates count the
    /// photons of nearby parallel surfaces too: a ceiling 3 mm above a light's back
    /// lights the light's underside.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// How the scene file is read (as photon-trace read it).
    #[command(flatten)]
    pub scene_options: pm_stage::SceneOptions,
    /// The precompute settings (pipeline.toml's \[irradiance\] section).
    #[command(flatten)]
    pub params: IrradianceParams,
    /// Write statistics (count, time, radii) as JSON.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// Run the stage; returns the statistics.
pub fn run(cli: &Cli) -> Result<IrradianceReport> {
    let p = &cli.params;
    p.validate(pm_params::Naming::Cli).map_err(|e| anyhow::anyhow!(e))?;
    pm_stage::init_threads(cli.threads)?;
    let expect = ReadExpect { kind: Some(MapKind::Global), order: Some(Order::KdTree), ..Default::default() };
    let mut map = pm_format::read(&cli.input, &expect)?;
    let h = map.header().clone();
    if !h.layout.has_normal() {
        bail!(
            "{}: {} records carry no surface normal; trace the global map with photon-trace (23/64-byte records)",
            cli.input.display(),
            h.layout.name()
        );
    }
    with_map!(&map, m => pm_stage::verify_kd_tree(&cli.input, &m.records))?;
    // Relative radii are fractions of the scene diagonal the header records, the same
    // length stage 4 uses.
    let diag = h.scene_diagonal;
    let max_radius_m = (p.max_radius_rel_diag * diag).max(f32::MIN_POSITIVE);
    let filter = p.filter.filter();
    let params = KnnParams { k: p.k, max_d2: max_radius_m * max_radius_m, filter };
    let scene = match &cli.scene {
        Some(path) => Some(pm_stage::load_scene("photon-irradiance", path, &cli.scene_options)?),
        None => None,
    };
    // Each estimate bounded by the gaps to the surfaces around its photon, over
    // the share of its disc on the photon's surface.
    let surfaces = scene.as_ref().map(|scene| pm_render::SceneSurfaces { scene, reach: max_radius_m });
    let around = surfaces.as_ref().map(|s| s as &dyn pm_estimate::SurfaceQuery);
    let n = map.len();
    let progress = Progress::new("irradiance", n as u64);
    let stats = with_map!(&mut map, m => {
        let stats = pm_estimate::precompute(&mut m.records, &params, (p.fraction, p.refine_ratio), around, &|d| progress.set(d));
        m.header.has_irradiance = true;
        let mut p: serde_json::Value = serde_json::from_str(&m.header.params).unwrap_or(json!({}));
        p["irradiance"] = json!({"params": cli.params, "max_radius_m": max_radius_m});
        m.header.params = p.to_string();
        m.write(&cli.out)?;
        stats
    });
    let secs = progress.finish();
    let pct = |q: f64| {
        stats.radii.get(((stats.radii.len() as f64 - 1.0) * q).round().max(0.0) as usize).copied().unwrap_or(0.0)
    };
    let report = IrradianceReport {
        input: cli.input.display().to_string(),
        photons: n,
        computed: stats.computed as u64,
        refined: stats.refined,
        empty_estimates: stats.empty as u64,
        covered: stats.covered,
        params: cli.params.clone(),
        max_radius_m,
        scene_diagonal_m: diag,
        radius_m: [pct(0.05), pct(0.5), pct(0.95), pct(1.0)],
        estimates_at_max_radius: stats.radii.iter().filter(|&&r| r >= max_radius_m * 0.999).count(),
        seconds: secs,
        microseconds_per_estimate: 1e6 * secs / stats.computed.max(1) as f64,
        threads: pm_stage::thread_count(),
    };
    if let Some(p) = &cli.stats_json {
        pm_stage::write_json(p, &serde_json::to_value(&report)?)?;
    }
    Ok(report)
}
