//! Irradiance precompute on cornell_spheres' 400k-photon global map, k = 50, at
//! fraction 1 and 1/4 (Christensen 1999 section 3.1: 58 s and 15 s), 2 threads.
//!
//! Run: `cargo bench -p pm-render --bench precompute` (with the scene, pm-render's
//! `SceneSurfaces`: the gaps' three rays and the disc's probes an estimate).

use pm_estimate::{Filter, KnnParams, precompute};
use pm_format::{CompactIrrPhoton, PhotonRecord};
use std::time::Instant;

fn main() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell_spheres.gltf");
    let scene = pm_scene::load(&path).unwrap();
    let photons = pm_photon::trace_global(&scene, 400_000, 1).unwrap();
    let recs: Vec<CompactIrrPhoton> = photons.iter().map(CompactIrrPhoton::encode).collect();
    let nodes = pm_kdtree::balance(&recs);
    let p = KnnParams { k: 50, max_d2: 0.3464f32.powi(2), filter: Filter::None };
    let around = pm_render::SceneSurfaces { scene: &scene, reach: p.max_d2.sqrt() };
    println!("threads: {}, photons: {}", rayon::current_num_threads(), nodes.len());
    println!(
        "| fraction | estimates | time [s] | per estimate [us] | time / time at fraction 1 | with the scene [s] | scene / none |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut base = 0.0;
    for f in [1.0, 0.25, 1.0 / 16.0] {
        // Alternated, without and with the scene (three rays an estimate for
        // the gaps to the neighbouring surfaces, up to two a disc probe), best
        // of three each.
        let (mut best, mut gaps) = ((f64::INFINITY, 0), f64::INFINITY);
        for _ in 0..3 {
            for with_scene in [false, true] {
                let mut n = nodes.clone();
                let t = Instant::now();
                let with: Option<&dyn pm_estimate::SurfaceQuery> = with_scene.then_some(&around);
                let s = precompute(&mut n, &p, (f, 0.0), with, &|_| {});
                let secs = t.elapsed().as_secs_f64();
                if with_scene {
                    gaps = gaps.min(secs);
                } else {
                    best = (best.0.min(secs), s.computed as usize);
                }
            }
        }
        if f == 1.0 {
            base = best.0;
        }
        println!(
            "| {f} | {} | {:.3} | {:.2} | {:.3} | {gaps:.3} | {:.2} |",
            best.1,
            best.0,
            1e6 * best.0 / best.1 as f64,
            best.0 / base,
            gaps / best.0
        );
    }
}
