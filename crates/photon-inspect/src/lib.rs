//! Inspection of photon-map files: a summary of the header and the records (with a
//! verification of the kd-tree), a coloured point cloud (PLY) for MeshLab,
//! CloudCompare or Blender, and the photons drawn from the scene's camera
//! (Christensen 1999 Figure 1a; Figures 1c/1d with precomputed irradiance).

use anyhow::{Context, Result, ensure};
use clap::Parser;
use glam::Vec3;
use pm_format::{AnyMap, Order, PhotonRecord, ReadExpect, flags, with_map};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;

/// Command line of `photon-inspect`.
#[derive(Parser, Debug)]
#[command(
    name = "photon-inspect",
    about = "Summarise a photon map; export it as a PLY point cloud or draw it from the scene's camera",
    long_about = "Reads any photon-map file and prints its header (kind, order, record layout, counts, bounds in m \
(world coordinates: the map's positions plus the origin its header records), \
total power in W per channel), counts by flag, for a kd-tree its depth and a check that the heap order is a valid \
kd-tree, and for maps with precomputed irradiance how many photons carry it and its range (W m^-2)."
)]
// Help texts give units as [m] and [s], not links.
#[allow(rustdoc::broken_intra_doc_links)]
pub struct Cli {
    /// Photon map (*.pmap).
    pub map: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write the photons as a coloured point cloud (binary little-endian PLY).
    #[arg(long)]
    pub ply: Option<PathBuf>,
    /// Draw the photons from the scene's camera into this PNG (needs --scene).
    #[arg(long, requires = "scene")]
    pub image: Option<PathBuf>,
    /// Scene the map was traced in (for --image; must be the same scene).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// How the scene file is read (as the map was traced).
    #[command(flatten)]
    pub scene_options: pm_stage::SceneOptions,
    /// Colour by precomputed irradiance instead of power (maps with irradiance).
    #[arg(long)]
    pub irradiance: bool,
    /// Image width [pixels].
    #[arg(long, default_value_t = 512)]
    pub width: u32,
    /// Image height [pixels].
    #[arg(long, default_value_t = 512)]
    pub height: u32,
}

/// The summary of a map, as JSON.
pub fn summary(map: &AnyMap) -> serde_json::Value {
    let h = map.header();
    let world = |p: [f32; 3]| world_of(h.origin, p);
    with_map!(map, m => {
        let recs = &m.records;
        let n = recs.len().max(1) as f64;
        let mut by_flag = [0u64; 6];
        let mut with_irr = 0u64;
        let (mut e_min, mut e_max) = (f32::INFINITY, 0f32);
        for r in recs {
            let f = r.flags();
            by_flag[0] += (f & flags::DIRECT != 0) as u64;
            by_flag[1] += (f & (flags::DIRECT | flags::CAUSTIC) == 0) as u64;
            by_flag[2] += (f & flags::CAUSTIC != 0) as u64;
            by_flag[3] += (f & flags::UNUSED != 0) as u64;
            by_flag[4] += (f & flags::VOLUME != 0) as u64;
            by_flag[5] += (f & flags::COVERED != 0) as u64;
            if f & flags::HAS_IRRADIANCE != 0 {
                with_irr += 1;
                let e = pm_color::mean(r.irradiance());
                e_min = e_min.min(e);
                e_max = e_max.max(e);
            }
        }
        let tree = if h.order == Order::KdTree {
            let t = pm_kdtree::KdTree::new(&recs[..]);
            json!({"depth": t.depth(), "valid": t.verify().is_ok(), "problem": t.verify().err()})
        } else {
            serde_json::Value::Null
        };
        json!({
            "kind": format!("{:?}", h.kind),
            "order": format!("{:?}", h.order),
            "layout": h.layout.name(),
            "record_bytes": h.layout.record_size(),
            "photons": recs.len(),
            "emitted": h.n_emitted,
            "bounds_min_m": world(h.bounds_min),
            "bounds_max_m": world(h.bounds_max),
            "origin_m": h.origin,
            "total_power_w": h.total_power,
            "mean_power_w": h.total_power.map(|t| t / n),
            "direct": by_flag[0],
            "indirect": by_flag[1],
            "caustic_path": by_flag[2],
            "unused": by_flag[3],
            // Photons stored where light scattered in a medium (a volume map's;
            // there "direct" is single scattering and "caustic_path" L S+ V).
            "in_medium": by_flag[4],
            // Photons the irradiance precompute found under a cover (a surface
            // facing them from closer than 1% of the diagonal).
            "covered": by_flag[5],
            "kd_tree": tree,
            "irradiance": if h.has_irradiance { json!({"photons": with_irr, "min_w_m2": e_min.min(e_max), "max_w_m2": e_max}) } else { serde_json::Value::Null },
            "scene_hash": h.scene_hash.iter().take(8).map(|b| format!("{b:02x}")).collect::<String>(),
            "params": serde_json::from_str::<serde_json::Value>(&h.params).unwrap_or(json!(h.params)),
        })
    })
}

/// World coordinates [m] of a position relative to the map's origin.
fn world_of(origin: [f64; 3], p: [f32; 3]) -> [f64; 3] {
    [origin[0] + p[0] as f64, origin[1] + p[1] as f64, origin[2] + p[2] as f64]
}

/// Positions and display colours (linear, normalised so the 99th percentile is 1).
fn points(map: &AnyMap, irradiance: bool) -> Vec<(Vec3, Vec3)> {
    let raw: Vec<(Vec3, Vec3)> = with_map!(map, m => m.records.iter()
        .filter(|r| !irradiance || r.flags() & flags::HAS_IRRADIANCE != 0)
        .map(|r| (r.position(), if irradiance { r.irradiance() } else { r.power() }))
        .collect());
    let mut lum: Vec<f32> = raw.iter().map(|p| p.1.max_element()).collect();
    lum.sort_by(f32::total_cmp);
    let scale = lum.get(lum.len() * 99 / 100).copied().filter(|v| *v > 0.0).unwrap_or(1.0);
    raw.into_iter().map(|(p, c)| (p, c / scale)).collect()
}

/// Run the inspector.
pub fn run(cli: &Cli) -> Result<()> {
    let map = pm_format::read(&cli.map, &ReadExpect::default())?;
    ensure!(
        !cli.irradiance || map.header().has_irradiance,
        "{}: the map has no precomputed irradiance",
        cli.map.display()
    );
    let s = summary(&map);
    if cli.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        println!("{}", cli.map.display());
        for (k, v) in s.as_object().context("summary")? {
            println!("  {k:<14} {v}");
        }
    }
    if let Some(ply) = &cli.ply {
        let pts = points(&map, cli.irradiance);
        let mut bytes = format!(
            "ply\nformat binary_little_endian 1.0\ncomment photon map {}\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
            cli.map.display(),
            pts.len()
        )
        .into_bytes();
        // World coordinates (the map stores positions relative to the scene's camera),
        // in f64 so a scene far from the origin keeps its precision.
        let origin = map.header().origin;
        for (p, c) in &pts {
            for v in world_of(origin, p.to_array()) {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
            bytes.extend((0..3).map(|k| pm_color::srgb8(c[k])));
        }
        pm_format::write_atomically(ply, |w| w.write_all(&bytes))
            .with_context(|| format!("{}: cannot write", ply.display()))?;
    }
    if let (Some(png), Some(scene_path)) = (&cli.image, &cli.scene) {
        let scene = pm_stage::load_scene("photon-inspect", scene_path, &cli.scene_options)?;
        ensure!(
            scene.content_hash == map.header().scene_hash,
            "{}: the map was traced in another scene than {}",
            cli.map.display(),
            scene_path.display()
        );
        let cam =
            scene.camera.as_ref().with_context(|| format!("{}: the scene has no camera", scene_path.display()))?;
        let (w, h) = (cli.width, cli.height);
        let aspect = w as f32 / h as f32;
        let mut img = vec![Vec3::ZERO; (w * h) as usize];
        for (p, c) in points(&map, cli.irradiance) {
            let Some(q) = cam.project(p, aspect) else { continue };
            if !(0.0..1.0).contains(&q.x) || !(0.0..1.0).contains(&q.y) {
                continue;
            }
            // Draw only photons the camera sees (a shadow ray back to the eye).
            let d = p - cam.position;
            let dist = d.length();
            if dist > 0.0 && scene.occluded(cam.position, d / dist, dist * (1.0 - 1e-4)) {
                continue;
            }
            let i = (q.y * h as f32) as usize * w as usize + (q.x * w as f32) as usize;
            img[i] = c;
        }
        pm_image::write_png(png, w, h, &img, 0.0)?;
    }
    Ok(())
}
