//! Photon tracing throughput on cornell_spheres: paths and rays per second with 1
//! and 2 threads, and the time to fill the paper's 400k global + 35k caustic photons.
//!
//! Run: `cargo bench -p pm-photon --bench trace`

use pm_photon::{Budget, LightSelector, MapPass, TraceConfig, trace};
use std::time::Instant;

fn main() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell_spheres.gltf");
    let scene = pm_scene::load(&path).unwrap();
    let selector = LightSelector::new(&scene, &[]).unwrap();
    let cfg = |pass, budget| TraceConfig { pass, budget, seed: 1, selector: selector.clone() };
    println!(
        "| threads | global 400k [s] | caustic 35k [s] | total [s] | global paths/s | global rays/s | speed-up vs 1 thread |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut base = 0.0;
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut best = (f64::INFINITY, 0.0, 0u64, 0u64);
        for _ in 0..3 {
            let (tg, tc, paths, rays) = pool.install(|| {
                let t = Instant::now();
                let g =
                    trace(&scene, &cfg(MapPass::Global, Budget::Stored { target: 400_000, cap: u64::MAX }), &|_| {})
                        .unwrap();
                let tg = t.elapsed().as_secs_f64();
                let t = Instant::now();
                trace(&scene, &cfg(MapPass::Caustic, Budget::Stored { target: 35_000, cap: u64::MAX }), &|_| {})
                    .unwrap();
                (tg, t.elapsed().as_secs_f64(), g.stats.emitted, g.stats.rays)
            });
            if tg + tc < best.0 + best.1 {
                best = (tg, tc, paths, rays);
            }
        }
        let total = best.0 + best.1;
        if threads == 1 {
            base = total;
        }
        println!(
            "| {threads} | {:.3} | {:.3} | {total:.3} | {:.0} | {:.0} | {:.2} |",
            best.0,
            best.1,
            best.2 as f64 / best.0,
            best.3 as f64 / best.0,
            base / total
        );
    }
}
