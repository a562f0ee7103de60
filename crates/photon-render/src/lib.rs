//! Stage 4 of the pipeline (Christensen 1999 sections 1.3, 2.2 and 3): render the
//! scene from its photon maps and write an OpenEXR image (linear radiance with
//! component layers) and optionally a PNG. A thin layer over `pm-render`.

use anyhow::{Context, Result, bail, ensure};
use clap::{Parser, ValueEnum};
use pm_format::{FullPhoton, MapKind, Order, PhotonRecord, ReadExpect};
use pm_kdtree::KdTree;
use pm_render::{Image, Lookup, Maps, Mode, RenderConfig, RenderStats};
use pm_stage::Progress;
use serde_json::json;
use std::path::PathBuf;

/// What to render.
#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum ModeArg {
    /// Direct + specular + caustics + final-gathered indirect (the complete image).
    Full,
    /// Radiance from the global map directly at the eye hit (Figure 1b).
    Photons,
    /// Precomputed irradiance x reflectance / pi (Figure 1e; 1c/1d show the irradiance).
    Radiance,
    /// The soft indirect term from final gathering alone (Figure 1f).
    Indirect,
    /// Unbiased path tracing: the reference (needs no photon maps).
    Path,
}

/// Final-gather lookup.
#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum LookupArg {
    /// Precomputed irradiance of the nearest photon with a similar normal (needs photon-irradiance).
    Precomputed,
    /// A k-nearest irradiance estimate at each gather-ray hit.
    Exact,
}

/// Command line of `photon-render`.
#[derive(Parser, Debug, Clone)]
#[command(
    name = "photon-render",
    about = "Stage 4: render from the photon maps to OpenEXR (linear radiance, W sr^-1 m^-2) and PNG",
    long_about = "Stage 4 (Christensen 1999, sections 1.3, 2.2, 3). Traces eye rays with adaptive supersampling; \
mirrors and glass by recursive ray tracing; at other surfaces direct light by sampling the lights, caustics from the \
caustic map and soft indirect light by final gathering whose rays read the precomputed irradiance of the nearest \
photon with a similar normal (or an exact k-nearest estimate), interpolated by an irradiance cache. Radiance in the \
EXR is W sr^-1 m^-2 per RGB channel, with layers direct, caustic, indirect and specular. Radii are fractions of the \
scene's bounding-box diagonal; the stats JSON logs the absolute values used."
)]
pub struct Cli {
    /// Scene (glTF 2.0); the first camera is used.
    #[arg(long)]
    pub scene: PathBuf,
    /// Global map with precomputed irradiance (global.irr.pmap), or global.kd.pmap with --gather-lookup exact.
    #[arg(long)]
    pub global: Option<PathBuf>,
    /// Sorted caustic map (caustic.kd.pmap).
    #[arg(long)]
    pub caustic: Option<PathBuf>,
    /// Output OpenEXR image.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write a PNG (exposure, sRGB).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Image width [pixels].
    #[arg(long, default_value_t = 512)]
    pub width: u32,
    /// Image height [pixels].
    #[arg(long, default_value_t = 512)]
    pub height: u32,
    /// Most samples per pixel (adaptive; the paper: 16). In path mode, samples per pixel.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Luminance contrast between neighbouring pixels that triggers supersampling.
    #[arg(long, default_value_t = 0.1)]
    pub contrast: f32,
    /// What to render.
    #[arg(long, value_enum, default_value_t = ModeArg::Full)]
    pub mode: ModeArg,
    /// Leave out soft indirect light (no final gathers, no global map needed); for
    /// scenes where no diffusely reflected light reaches another diffuse surface.
    #[arg(long)]
    pub no_indirect: bool,
    /// Importance threshold: where the photon map's indirect irradiance is below this
    /// fraction of the direct irradiance, use it instead of a final gather (0: always gather).
    #[arg(long, default_value_t = 0.0)]
    pub indirect_threshold: f32,
    /// Rays per final gather (stratified, cosine-weighted).
    #[arg(long, default_value_t = 400)]
    pub gather_rays: u32,
    /// How gather rays read the global map.
    #[arg(long, value_enum, default_value_t = LookupArg::Precomputed)]
    pub gather_lookup: LookupArg,
    /// Rays of a secondary final gather (the paper: 12; 0 disables).
    #[arg(long, default_value_t = 12)]
    pub secondary_rays: u32,
    /// Gather rays shorter than this fraction of the scene diagonal get a secondary gather.
    #[arg(long, default_value_t = 0.005)]
    pub secondary_distance: f32,
    /// Photons per global-map estimate (exact lookups and photons mode).
    #[arg(long, default_value_t = 50)]
    pub k: usize,
    /// Photons per caustic estimate.
    #[arg(long, default_value_t = 60)]
    pub caustic_k: usize,
    /// Largest global-map search radius, as a fraction of the scene diagonal.
    #[arg(long, default_value_t = 0.1)]
    pub max_radius: f32,
    /// Largest caustic search radius, as a fraction of the scene diagonal.
    #[arg(long, default_value_t = 0.02)]
    pub caustic_radius: f32,
    /// Irradiance-cache accuracy a (Ward's error bound, smaller is finer; 0 disables the cache).
    #[arg(long, default_value_t = 0.3)]
    pub icache_accuracy: f32,
    /// Smallest irradiance-cache record spacing, as a fraction of the scene diagonal.
    #[arg(long, default_value_t = 0.005)]
    pub icache_min_spacing: f32,
    /// Largest irradiance-cache record spacing, as a fraction of the scene diagonal.
    #[arg(long, default_value_t = 0.1)]
    pub icache_max_spacing: f32,
    /// Light samples per shading point.
    #[arg(long, default_value_t = 4)]
    pub light_samples: u32,
    /// Depth limit of specular recursion (cut paths are counted in the stats).
    #[arg(long, default_value_t = 12)]
    pub max_depth: u32,
    /// PNG exposure in stops (the PNG shows radiance x 2^exposure).
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write statistics (time per component, gathers, rays) as JSON.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// Run the stage; returns the statistics.
pub fn run(cli: &Cli) -> Result<serde_json::Value> {
    ensure!(
        cli.width > 0 && cli.height > 0 && cli.width <= 16384 && cli.height <= 16384,
        "--width and --height must be in 1..=16384"
    );
    ensure!(cli.spp >= 1, "--spp must be at least 1");
    ensure!(cli.gather_rays >= 1 || cli.mode == ModeArg::Path, "--gather-rays must be at least 1");
    pm_stage::init_threads(cli.threads)?;
    let scene = pm_stage::load_scene("photon-render", &cli.scene)?;
    ensure!(scene.camera.is_some(), "{}: the scene has no perspective camera", cli.scene.display());
    let diag = scene.bounds.diagonal().max(f32::MIN_POSITIVE);
    let cfg = RenderConfig {
        width: cli.width,
        height: cli.height,
        spp: cli.spp,
        contrast: cli.contrast,
        mode: match cli.mode {
            ModeArg::Full => Mode::Full,
            ModeArg::Photons => Mode::Photons,
            ModeArg::Radiance => Mode::Radiance,
            ModeArg::Indirect => Mode::Indirect,
            ModeArg::Path => Mode::Path,
        },
        indirect: !cli.no_indirect,
        indirect_threshold: cli.indirect_threshold.max(0.0),
        gather_rays: cli.gather_rays,
        secondary_rays: cli.secondary_rays,
        secondary_distance: cli.secondary_distance * diag,
        lookup: match cli.gather_lookup {
            LookupArg::Precomputed => Lookup::Precomputed,
            LookupArg::Exact => Lookup::Exact,
        },
        k_global: cli.k.max(1),
        k_caustic: cli.caustic_k.max(1),
        max_radius_global: cli.max_radius * diag,
        max_radius_caustic: cli.caustic_radius * diag,
        icache_accuracy: cli.icache_accuracy.max(0.0),
        icache_spacing: (cli.icache_min_spacing * diag, cli.icache_max_spacing.max(cli.icache_min_spacing) * diag),
        light_samples: cli.light_samples.max(1),
        max_depth: cli.max_depth,
        seed: cli.seed,
    };
    let needs_global = cfg.mode != Mode::Path && !(cfg.mode == Mode::Full && !cfg.indirect);
    let needs_irradiance =
        matches!(cfg.mode, Mode::Full | Mode::Indirect | Mode::Radiance) && cfg.lookup == Lookup::Precomputed;
    let caustic = match (&cli.caustic, matches!(cfg.mode, Mode::Full)) {
        (Some(p), true) => {
            let expect = ReadExpect {
                kind: Some(MapKind::Caustic),
                order: Some(Order::KdTree),
                scene_hash: Some(scene.content_hash),
                ..Default::default()
            };
            Some(pm_format::read_as::<FullPhoton>(p, &expect)?)
        }
        _ => None,
    };
    let mut notes = Vec::new();
    let global = match (&cli.global, needs_global) {
        (Some(p), true) => {
            let expect = ReadExpect {
                kind: Some(MapKind::Global),
                order: Some(Order::KdTree),
                irradiance: needs_irradiance.then_some(true),
                scene_hash: Some(scene.content_hash),
            };
            let map = pm_format::read(p, &expect)?;
            if !map.header().layout.has_normal() {
                bail!(
                    "{}: {} records carry no surface normal; trace with photon-trace",
                    p.display(),
                    map.header().layout.name()
                );
            }
            if map.is_empty() {
                notes.push("the global photon map holds no photons: indirect light is zero".to_string());
            }
            Some(map)
        }
        (None, true) => bail!("--global is required in {:?} mode", cli.mode),
        _ => None,
    };
    for n in &notes {
        eprintln!("photon-render: note: {n}");
    }
    let progress = Progress::new("render", (cli.width * cli.height) as u64);
    let (image, stats) = match global {
        Some(pm_format::AnyMap::CompactIrr(m)) => {
            render_with(&scene, Some(&m.records), caustic.as_ref(), &cfg, &progress)?
        }
        Some(pm_format::AnyMap::FullIrr(m)) => {
            render_with(&scene, Some(&m.records), caustic.as_ref(), &cfg, &progress)?
        }
        Some(_) => unreachable!("layouts without normals were refused above"),
        None => render_with::<pm_format::FullIrrPhoton>(&scene, None, caustic.as_ref(), &cfg, &progress)?,
    };
    progress.finish();
    let layers = pm_image::Layers {
        width: image.width,
        height: image.height,
        layers: image.layers.iter().map(|(n, px)| (n.to_string(), px.clone())).collect(),
    };
    pm_image::write_exr(&cli.out, &layers)?;
    if let Some(png) = &cli.png {
        pm_image::write_png(
            png,
            image.width,
            image.height,
            image.layer("total").context("no total layer")?,
            cli.exposure,
        )?;
    }
    let report = report(cli, &cfg, &stats, diag, &notes);
    if let Some(p) = &cli.stats_json {
        pm_stage::write_json(p, &report)?;
    }
    Ok(report)
}

fn render_with<G: PhotonRecord>(
    scene: &pm_scene::Scene,
    global: Option<&[G]>,
    caustic: Option<&pm_format::PhotonMap<FullPhoton>>,
    cfg: &RenderConfig,
    progress: &Progress,
) -> Result<(Image, RenderStats)> {
    let irr_nodes = global.map(pm_render::irradiance_subset).unwrap_or_default();
    let maps = Maps {
        global: global.map(KdTree::new),
        irradiance: (!irr_nodes.is_empty()).then(|| KdTree::new(&irr_nodes[..])),
        caustic: caustic.map(|c| KdTree::new(&c.records[..])),
    };
    pm_render::render(scene, &maps, cfg, &|done, _| progress.set(done)).map_err(|e| anyhow::anyhow!("{}", e))
}

fn report(cli: &Cli, cfg: &RenderConfig, s: &RenderStats, diag: f32, notes: &[String]) -> serde_json::Value {
    json!({
        "stage": "photon-render",
        "mode": format!("{:?}", cli.mode).to_lowercase(),
        "indirect": cfg.indirect,
        "lookup": format!("{:?}", cli.gather_lookup).to_lowercase(),
        "width": cli.width, "height": cli.height, "max_spp": cli.spp,
        "seconds": s.seconds,
        "prepass_seconds": s.prepass_seconds,
        "thread_seconds": s.thread_seconds.iter().map(|(k, v)| (k.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "final_gathers": s.final_gathers,
        "cache_records": s.cache_records,
        "cache_hits": s.cache_hits,
        "gather_rays": s.gather_rays,
        "secondary_gathers": s.secondary_gathers,
        "lookups": s.lookups,
        "lookup_misses": s.lookup_misses,
        "lookup_rank_1_2_more": s.lookup_rank,
        "terminated_paths": s.terminated_paths,
        "nonfinite_pixels": s.nonfinite_pixels,
        "thinned_shading_points": s.thinned,
        "samples": s.samples,
        "samples_per_pixel": s.samples as f64 / (cli.width as f64 * cli.height as f64),
        "supersampled_pixels": s.supersampled_pixels,
        "scene_diagonal_m": diag,
        "radii_m": {
            "max_radius_global": cfg.max_radius_global,
            "max_radius_caustic": cfg.max_radius_caustic,
            "secondary_distance": cfg.secondary_distance,
            "icache_spacing": [cfg.icache_spacing.0, cfg.icache_spacing.1],
        },
        "threads": pm_stage::thread_count(),
        "notes": notes,
    })
}
