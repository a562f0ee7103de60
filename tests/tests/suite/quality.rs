//! The quality knob: `quality` or `time_budget_s` in pipeline.toml picks the point of
//! the measured accuracy/time front whose predicted time fits, lowest error first,
//! and its values replace the file's before they are checked.

use pm_pipeline::Pipeline;
use std::path::{Path, PathBuf};

fn front() -> serde_json::Value {
    serde_json::json!({
        "scene": "cornell_spheres",
        "size": 256,
        "machine": "2 cores",
        "defaults_s": [0.1, 0.02, 0.1, 0.8],
        "points": [
            {"label": "gather rays 64", "times_s": [0.1, 0.02, 0.1, 0.2], "error": 0.2, "bias": 0.1, "noise": 0.17,
             "overrides": [["render", "gather_rays", 64]]},
            {"label": "cache a 0.15", "times_s": [0.1, 0.02, 0.1, 1.0], "error": 0.1, "bias": 0.05, "noise": 0.08,
             "overrides": [["render", "icache_accuracy", 0.15]]},
            {"label": "global 1600000", "times_s": [1.0, 0.2, 0.5, 1.2], "error": 0.05, "bias": 0.02, "noise": 0.04,
             "overrides": [["trace", "global_photons", 1600000], ["irradiance", "fraction", 1.0]]}
        ]
    })
}

/// A pipeline file in `dir` with `extra` keys at the top and an image of `size`
/// pixels a side, beside a measured front for its scene.
fn pipeline(dir: &Path, extra: &str, size: u32) -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let scene = root.join("scenes/cornell_spheres.gltf");
    let text = format!(
        "{extra}\nscene = {:?}\neffects = \"auto\"\n[render]\nwidth = {size}\nheight = {size}\n",
        scene.display().to_string()
    );
    let p = dir.join("pipeline.toml");
    std::fs::write(&p, text).unwrap();
    let f = dir.join("docs/tradeoff/cornell_spheres");
    std::fs::create_dir_all(&f).unwrap();
    std::fs::write(f.join("front.json"), front().to_string()).unwrap();
    p
}

#[test]
fn quality_and_budget_pick_the_fitting_point_with_the_least_error() {
    let dir = tempfile::tempdir().unwrap();
    let load = |extra: &str, size: u32| Pipeline::load(&pipeline(dir.path(), extra, size)).unwrap();
    let d = load("", 256);
    assert!(d.chosen.is_none());
    // At the study's size the defaults take 1.02 s: preview (0.26 s) fits nothing
    // and gets the fastest point; balanced (1.02 s) the 0.42-s point; final (4.1 s)
    // the most accurate.
    let p = load("quality = \"preview\"", 256);
    assert_eq!(p.render.gather_rays, 64);
    assert!(p.chosen.as_deref().unwrap().contains("nothing fits"), "{:?}", p.chosen);
    assert_eq!(load("quality = \"balanced\"", 256).render.gather_rays, 64);
    let f = load("quality = \"final\"", 256);
    assert_eq!(
        (f.trace.global_photons, f.irradiance.fraction, f.render.gather_rays),
        (1_600_000, 1.0, d.render.gather_rays)
    );
    // A budget of 1.5 s: the cache point (1.22 s) beats the faster, worse one.
    assert_eq!(load("time_budget_s = 1.5", 256).render.icache_accuracy, 0.15);
    // At 1024 x 1024 renders take 16 times longer: the same budget fits only the first.
    assert_eq!(load("time_budget_s = 5", 1024).render.gather_rays, 64);
    // Bad values name the key.
    for (extra, says) in [
        ("quality = \"best\"", "quality = \"best\""),
        ("time_budget_s = -1", "time_budget_s = -1"),
        ("quality = \"final\"\ntime_budget_s = 3", "not both"),
    ] {
        let e = Pipeline::load(&pipeline(dir.path(), extra, 256)).unwrap_err().to_string();
        assert!(e.contains(says) && e.contains("pipeline.toml"), "{e}");
    }
}

/// The bias/noise split on a real renderer with an exact reference: the furnace
/// (radiance 5 everywhere) path-traced with four seeds. An unbiased estimator: the
/// split finds almost no bias, and its expected error equals what each render
/// measures against the truth.
#[test]
fn furnace_split_finds_an_unbiased_path_tracer_unbiased() {
    let scene = pm_tests::load_scene("furnace.gltf");
    let maps = pm_tests::photon_maps(&scene, 20_000, 0, 0.25);
    let mut p = pm_tests::render_params(pm_methods::Method::Path, 24, 24);
    p.render.spp = 16;
    let images: Vec<Vec<glam::Vec3>> =
        (1..=4).map(|seed| pm_tests::render_seeded(&scene, &maps, &p, seed).0.total().to_vec()).collect();
    let exact = vec![glam::Vec3::splat(5.0); 24 * 24];
    let keep = vec![true; 24 * 24];
    let refs: Vec<&[glam::Vec3]> = images.iter().map(Vec::as_slice).collect();
    let s = pm_image::accuracy::split(&refs, &exact, 0.0, &keep);
    eprintln!("furnace, path 16 spp: {s:?}");
    assert!(s.noise > 0.01, "{s:?}");
    assert!(s.bias < 0.25 * s.noise && s.mean_bias.abs() < 0.01, "{s:?}");
    assert!((s.measured / s.error - 1.0).abs() < 0.1, "{s:?}");
    assert_eq!(s.reference_noise, 0.0);
}
