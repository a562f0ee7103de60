//! Cross-stage and analytic-scene tests of the photon-mapping pipeline. The tests
//! live in `tests/tests/`; this library holds the helpers they share.

use pm_format::{CompactIrrPhoton, FullPhoton, PhotonRecord};
use pm_photon::{Budget, LightSelector, MapPass, TraceConfig};
use pm_render::{Lookup, Mode, RenderConfig};
use pm_scene::Scene;
use std::path::PathBuf;

/// Path of a scene in the repository's `scenes/` folder.
pub fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name)
}

/// Load a scene from `scenes/`.
pub fn load_scene(name: &str) -> Scene {
    pm_scene::load(&scene_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// Trace a global map with at least `stored` photons and balance it into a kd-tree
/// of 23-byte records, as stages 1 and 2 do.
pub fn global_tree(scene: &Scene, stored: u64, seed: u64) -> Vec<CompactIrrPhoton> {
    let cfg = TraceConfig {
        pass: MapPass::Global,
        budget: Budget::Stored { target: stored, cap: stored * 1000 },
        seed,
        selector: LightSelector::new(scene, &[]).unwrap(),
        range: None,
    };
    let photons = pm_photon::trace(scene, &cfg, &|_| {}).unwrap().photons;
    let records: Vec<CompactIrrPhoton> = photons.iter().map(CompactIrrPhoton::encode).collect();
    pm_kdtree::balance(&records)
}

/// Stages 1-3 in memory: a global kd-tree map with precomputed irradiance at
/// `fraction` of its photons (k = 50), and a caustic kd-tree map (empty when the
/// scene has no specular surface).
pub fn photon_maps(
    scene: &Scene,
    global: u64,
    caustic: u64,
    fraction: f64,
) -> (Vec<CompactIrrPhoton>, Vec<FullPhoton>) {
    let mut g = global_tree(scene, global, 1);
    let params = pm_estimate::KnnParams {
        k: 50,
        max_d2: (0.1 * scene.bounds.diagonal()).powi(2),
        filter: pm_estimate::Filter::None,
    };
    pm_estimate::precompute(&mut g, &params, fraction, &|_| {});
    let cfg = TraceConfig {
        pass: MapPass::Caustic,
        budget: Budget::Stored { target: caustic, cap: caustic * 1000 },
        seed: 2,
        selector: LightSelector::new(scene, &[]).unwrap(),
        range: None,
    };
    let c: Vec<FullPhoton> =
        pm_photon::trace(scene, &cfg, &|_| {}).unwrap().photons.iter().map(FullPhoton::encode).collect();
    (g, pm_kdtree::balance(&c))
}

/// The renderer's defaults (as `photon-render` sets them) for a scene, at a size.
pub fn render_config(scene: &Scene, mode: Mode, width: u32, height: u32) -> RenderConfig {
    let diag = scene.bounds.diagonal();
    RenderConfig {
        width,
        height,
        spp: 16,
        contrast: 0.1,
        mode,
        indirect: true,
        indirect_threshold: 0.0,
        gather_rays: 400,
        secondary_rays: 12,
        secondary_distance: 0.005 * diag,
        lookup: Lookup::Precomputed,
        k_global: 50,
        k_caustic: 60,
        max_radius_global: 0.1 * diag,
        max_radius_caustic: 0.02 * diag,
        icache_accuracy: 0.3,
        icache_spacing: (0.005 * diag, 0.1 * diag),
        light_samples: 4,
        max_depth: 12,
        seed: 1,
    }
}

/// Render with the maps of [`photon_maps`].
pub fn render(
    scene: &Scene,
    maps: &(Vec<CompactIrrPhoton>, Vec<FullPhoton>),
    cfg: &RenderConfig,
) -> (pm_render::Image, pm_render::RenderStats) {
    let irr = pm_render::irradiance_subset(&maps.0);
    let m = pm_render::Maps {
        global: Some(pm_kdtree::KdTree::new(&maps.0)),
        irradiance: Some(pm_kdtree::KdTree::new(&irr)),
        caustic: (!maps.1.is_empty()).then(|| pm_kdtree::KdTree::new(&maps.1)),
    };
    pm_render::render(scene, &m, cfg, &|_, _| {}).unwrap()
}
