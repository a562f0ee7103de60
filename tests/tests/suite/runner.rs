//! The pipeline runner on a small scene: every stage's output feeds the next, a
//! second run does nothing, changing a render parameter re-runs only the render, and
//! a corrupted intermediate stops the run at the stage that reads it.
//!
//! Uses the stage binaries that `cargo test --release --workspace` builds next to
//! this test (target/release).

use pm_runner::run::{Outcome, RunArgs, run_with};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn pipeline(dir: &Path, spp: u32) -> PathBuf {
    pm_tests::small_pipeline(dir, "cornell_spheres.gltf", "\"auto\"", spp, "pipeline")
}

fn run(p: &Path, out: &Path) -> anyhow::Result<Vec<Outcome>> {
    let args = RunArgs { pipeline: Some(p.to_owned()), out: Some(out.to_owned()), ..Default::default() };
    run_with(&args, &root(), &pm_tests::bins())
}

fn ran(outcomes: &[Outcome]) -> Vec<&str> {
    outcomes.iter().filter(|o| o.ran).map(|o| o.step.as_str()).collect()
}

#[test]
fn runner_runs_every_stage_then_only_what_changed() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let first = run(&pipeline(dir.path(), 4), &out).unwrap();
    assert_eq!(
        ran(&first),
        [
            "photon-trace",
            "photon-sort global",
            "photon-sort caustic",
            "photon-irradiance",
            "photon-render icache",
            "photon-render"
        ]
    );
    for f in [
        "global.pmap",
        "caustic.pmap",
        "global.kd.pmap",
        "caustic.kd.pmap",
        "global.irr.pmap",
        "icache.bin",
        "image.exr",
        "image.png",
        "report.json",
        "trace.stats.json",
        "irradiance.stats.json",
        "render.stats.json",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let img = pm_image::read_exr(&out.join("image.exr")).unwrap();
    assert!(img.total().unwrap().iter().any(|p| p.max_element() > 0.0));
    // Nothing changed: nothing runs.
    let second = run(&pipeline(dir.path(), 4), &out).unwrap();
    assert!(ran(&second).is_empty(), "{second:?}");
    // Only a render parameter changed: only the render runs.
    let third = run(&pipeline(dir.path(), 2), &out).unwrap();
    assert_eq!(ran(&third), ["photon-render"]);
    // The caustic estimate does not shape the irradiance cache: only the render runs
    // (the cache step once took every render parameter but the sampling's).
    let p = dir.path().join("pipeline.toml");
    pm_tests::edit_pipeline(&p, |c| c.render.caustic_k = 30);
    let fourth = run(&p, &out).unwrap();
    assert_eq!(ran(&fourth), ["photon-render"]);
    // A corrupted intermediate: the next stage fails, the runner names it, and the
    // earlier outputs are left as they were.
    let kd = out.join("global.kd.pmap");
    let mut bytes = std::fs::read(&kd).unwrap();
    let n = bytes.len();
    bytes[n - 7] ^= 0x55;
    std::fs::write(&kd, &bytes).unwrap();
    let before = std::fs::read(out.join("global.pmap")).unwrap();
    pm_tests::edit_pipeline(&p, |c| c.irradiance.k = 40);
    let err = run(&dir.path().join("pipeline.toml"), &out).unwrap_err().to_string();
    assert!(err.contains("stage photon-irradiance failed"), "{err}");
    // The stage's own message is kept in the error.
    assert!(err.contains("global.kd.pmap") && err.contains("corrupted"), "{err}");
    assert_eq!(std::fs::read(out.join("global.pmap")).unwrap(), before);
}

#[test]
fn pipeline_toml_errors_name_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let p = pipeline(dir.path(), 4);
    let out = dir.path().join("out");
    let table: toml::Table = toml::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    let with = |section: &str, key: &str, value: toml::Value| {
        let mut t = table.clone();
        t[section].as_table_mut().unwrap().insert(key.into(), value);
        toml::to_string(&t).unwrap()
    };
    let top = |key: &str, value: &str| {
        let mut t = table.clone();
        t.insert(key.into(), toml::from_str::<toml::Table>(&format!("v = {value}")).unwrap()["v"].clone());
        toml::to_string(&t).unwrap()
    };
    for (edit, what) in [
        (top("environment_strength", "-1.0"), "environment_strength = -1 is out of range"),
        (top("environment", "[1.0, -1.0, 0.0]"), "radiance must be finite and non-negative"),
        (top("sun_angle_deg", "200.0"), "sun_angle_deg = 200 is refused: the angle must be in (0, 180) degrees"),
        (top("sun_angle_deg", "{ Sun = 0.0 }"), "sun_angle_deg = Sun=0 is refused"),
        (with("render", "bogus_key", toml::Value::Integer(1)), "bogus_key"),
        (with("render", "k", toml::Value::String("fifty".into())), "k = \"fifty\""),
        (with("trace", "global_photons", toml::Value::Integer(10_000_000_000)), "trace.global_photons"),
        (with("irradiance", "fraction", toml::Value::Float(2.0)), "irradiance.fraction = 2 is out of range"),
    ] {
        std::fs::write(&p, edit).unwrap();
        let err = run(&p, &out).unwrap_err().to_string();
        assert!(err.contains(what) && err.contains("pipeline.toml") && !err.contains('\n'), "{err}");
    }
    assert!(!out.join("global.pmap").exists());
}
