//! Cross-stage and analytic-scene tests of the photon-mapping pipeline. The tests
//! live in `tests/tests/`; this library holds the helpers they share.

use pm_format::{CompactIrrPhoton, PhotonRecord};
use pm_photon::{Budget, LightSelector, MapPass, TraceConfig};
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
