//! Stage 3 of the pipeline (Christensen 1999 section 2.1): estimate the irradiance
//! at a spatially uniform subset of the global photons and store it, with the
//! photon's surface normal, in the 23-byte (or 64-byte) records. A thin layer over
//! `pm-estimate`.

use anyhow::{Result, bail, ensure};
use clap::{Parser, ValueEnum};
use pm_estimate::{Filter, KnnParams};
use pm_format::{MapKind, Order, ReadExpect, with_map};
use pm_stage::Progress;
use serde_json::json;
use std::path::PathBuf;

/// Density-estimation filter.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FilterArg {
    /// Constant kernel (the paper's estimate).
    None,
    /// Jensen's cone filter, k = 1.1.
    Cone,
    /// Jensen's Gaussian filter (renormalised).
    Gaussian,
}

/// Command line of `photon-irradiance`.
#[derive(Parser, Debug)]
#[command(
    name = "photon-irradiance",
    about = "Stage 3: precompute irradiance (W/m^2) at a subset of the global photons",
    long_about = "Stage 3 (Christensen 1999, section 2.1). Reads the sorted global map (global.kd.pmap), estimates \
the irradiance E [W m^-2 per RGB channel] at a spatially uniform fraction of the photons from their k nearest \
neighbours on the same side of the surface (E = sum of photon power / (pi r^2)), and writes the same tree with the \
irradiance stored in the selected photons (global.irr.pmap). The final gather then looks up the nearest photon \
with a similar normal instead of estimating."
)]
pub struct Cli {
    /// Sorted global photon map (global.kd.pmap).
    pub input: PathBuf,
    /// Output map (global.irr.pmap).
    #[arg(long)]
    pub out: PathBuf,
    /// Fraction of photons that get an irradiance (the paper: 1 or 1/4): one in every
    /// 1/fraction consecutive kd-tree positions, a stratified subset that keeps the
    /// photon density's shape.
    #[arg(long, default_value_t = 0.25)]
    pub fraction: f64,
    /// Photons per estimate (the paper: 50).
    #[arg(long, default_value_t = 50)]
    pub k: usize,
    /// Largest search radius, as a fraction of the photon map's bounding-box diagonal.
    #[arg(long, default_value_t = 0.1)]
    pub max_radius: f64,
    /// Density-estimation filter.
    #[arg(long, value_enum, default_value_t = FilterArg::None)]
    pub filter: FilterArg,
    /// Write statistics (count, time, radii) as JSON.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// Run the stage; returns the statistics.
pub fn run(cli: &Cli) -> Result<serde_json::Value> {
    ensure!(cli.fraction > 0.0 && cli.fraction <= 1.0, "--fraction must be in (0, 1], got {}", cli.fraction);
    ensure!(cli.k >= 1, "--k must be at least 1");
    ensure!(
        cli.max_radius > 0.0 && cli.max_radius.is_finite(),
        "--max-radius must be positive, got {}",
        cli.max_radius
    );
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
    let diag = (0..3).map(|k| (h.bounds_max[k] as f64 - h.bounds_min[k] as f64).powi(2)).sum::<f64>().sqrt();
    let max_radius_m = (cli.max_radius * diag).max(f64::MIN_POSITIVE) as f32;
    let filter = match cli.filter {
        FilterArg::None => Filter::None,
        FilterArg::Cone => Filter::Cone { k: 1.1 },
        FilterArg::Gaussian => Filter::Gaussian,
    };
    let params = KnnParams { k: cli.k, max_d2: max_radius_m * max_radius_m, filter };
    let n = map.len();
    let progress = Progress::new("irradiance", n as u64);
    let stats = with_map!(&mut map, m => {
        let stats = pm_estimate::precompute(&mut m.records, &params, cli.fraction, &|d| progress.set(d));
        m.header.has_irradiance = true;
        let mut p: serde_json::Value = serde_json::from_str(&m.header.params).unwrap_or(json!({}));
        p["irradiance"] = json!({"fraction": cli.fraction, "k": cli.k, "max_radius_m": max_radius_m, "filter": format!("{filter:?}")});
        m.header.params = p.to_string();
        m.write(&cli.out)?;
        stats
    });
    let secs = progress.finish();
    let pct = |q: f64| {
        stats.radii.get(((stats.radii.len() as f64 - 1.0) * q).round().max(0.0) as usize).copied().unwrap_or(0.0)
    };
    let report = json!({
        "stage": "photon-irradiance",
        "input": cli.input.display().to_string(),
        "photons": n,
        "computed": stats.computed,
        "fraction": cli.fraction,
        "empty_estimates": stats.empty,
        "k": cli.k,
        "filter": format!("{filter:?}"),
        "max_radius_m": max_radius_m,
        "max_radius_rel_diag": cli.max_radius,
        "radius_m": {"p05": pct(0.05), "p50": pct(0.5), "p95": pct(0.95), "max": pct(1.0)},
        "estimates_at_max_radius": stats.radii.iter().filter(|&&r| r >= max_radius_m * 0.999).count(),
        "seconds": secs,
        "microseconds_per_estimate": 1e6 * secs / stats.computed.max(1) as f64,
        "threads": pm_stage::thread_count(),
    });
    if let Some(p) = &cli.stats_json {
        pm_stage::write_json(p, &report)?;
    }
    Ok(report)
}
