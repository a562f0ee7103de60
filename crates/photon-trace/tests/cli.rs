//! The photon-trace binary: byte-identical output for any thread count, slices that
//! merge into the whole, and clear refusals of bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name)
}

fn trace(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_photon-trace")).args(args).output().unwrap()
}

fn ok(args: &[&str]) {
    let o = trace(args);
    assert!(o.status.success(), "photon-trace {args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn files_are_byte_identical_with_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_spheres.gltf");
    for t in ["1", "2"] {
        let out = dir.path().join(t);
        ok(&[
            "--scene",
            s.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--global-photons",
            "50000",
            "--caustic-photons",
            "5000",
            "--threads",
            t,
        ]);
    }
    for m in ["global.pmap", "caustic.pmap"] {
        assert_eq!(read(&dir.path().join("1").join(m)), read(&dir.path().join("2").join(m)), "{m}");
    }
}

#[test]
fn merged_slices_equal_a_single_run() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_spheres.gltf");
    let d = |n: &str| dir.path().join(n);
    // A stored target (the pipeline's budget) in the compact layout, and a fixed
    // emission count in the full layout.
    let budgets: [&[&str]; 2] = [
        &["--global-photons", "20000", "--caustic-photons", "3000"],
        &["--emit-global", "30000", "--emit-caustic", "20000", "--layout", "full"],
    ];
    for (b, budget) in budgets.iter().enumerate() {
        let common = [&["--scene", s.to_str().unwrap()][..], budget].concat();
        let whole = d(&format!("whole-{b}"));
        ok(&[&common[..], &["--out", whole.to_str().unwrap()]].concat());
        let slices: Vec<PathBuf> = (0..3).map(|j| d(&format!("slice-{b}-{j}"))).collect();
        for (j, out) in slices.iter().enumerate() {
            ok(&[&common[..], &["--out", out.to_str().unwrap(), "--slice", &format!("{j}/3")]].concat());
        }
        // A slice is no map: the other stages refuse it.
        let e = pm_format::read(&slices[0].join("global.pmap"), &Default::default()).unwrap_err().to_string();
        assert!(e.contains("trace slice"), "{e}");
        // Slices in any order on the command line.
        let merged = d(&format!("merged-{b}"));
        let stats = d(&format!("merged-{b}.json"));
        let mut args = vec!["merge".to_string()];
        args.extend([2, 0, 1].iter().map(|&j| slices[j].display().to_string()));
        args.extend(["--out".into(), merged.display().to_string(), "--stats-json".into(), stats.display().to_string()]);
        ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
        for m in ["global.pmap", "caustic.pmap"] {
            assert_eq!(read(&merged.join(m)), read(&whole.join(m)), "{budget:?} {m}");
        }
        let v: serde_json::Value = serde_json::from_slice(&read(&stats)).unwrap();
        let h = pm_format::read(&whole.join("global.pmap"), &Default::default()).unwrap().header().clone();
        assert_eq!(v["global"]["emitted"].as_u64(), Some(h.n_emitted));
    }
    // A missing slice is refused, naming it, and nothing is written.
    let o = trace(&[
        "merge",
        d("slice-0-0").to_str().unwrap(),
        d("slice-0-2").to_str().unwrap(),
        "--out",
        d("x").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("slice 1 of 3 is missing"), "{e}");
    assert!(!d("x").join("global.pmap").exists());
    // Slices of different traces are refused.
    let o = trace(&[
        "merge",
        d("slice-0-0").to_str().unwrap(),
        d("slice-1-1").to_str().unwrap(),
        d("slice-0-2").to_str().unwrap(),
        "--out",
        d("x").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("not a slice of the same trace"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn stats_report_counts_and_attrition() {
    let dir = tempfile::tempdir().unwrap();
    let stats = dir.path().join("stats.json");
    ok(&[
        "--scene",
        scene("cornell_spheres.gltf").to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
        "--global-photons",
        "20000",
        "--caustic-photons",
        "2000",
        "--stats-json",
        stats.to_str().unwrap(),
    ]);
    let v: serde_json::Value = serde_json::from_slice(&read(&stats)).unwrap();
    let g = &v["global"];
    assert!(g["stored"].as_u64().unwrap() >= 20000);
    let per_bounce: u64 = g["stored_per_bounce"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).sum();
    assert_eq!(per_bounce, g["stored"].as_u64().unwrap());
    assert_eq!(g["emitted_per_light"][0][1], g["emitted"]);
    assert!(v["caustic"]["stored"].as_u64().unwrap() >= 2000);
    // The file agrees with the stats.
    let map = pm_format::read(&dir.path().join("global.pmap"), &Default::default()).unwrap();
    assert_eq!(map.len() as u64, g["stored"].as_u64().unwrap());
    assert_eq!(map.header().n_emitted, g["emitted"].as_u64().unwrap());
    assert_eq!(map.header().layout, pm_format::Layout::CompactIrradiance);
}

#[test]
fn diffuse_scene_writes_no_caustic_map() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("caustic.pmap"), b"stale").unwrap();
    ok(&[
        "--scene",
        scene("cornell_boxes.gltf").to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
        "--global-photons",
        "5000",
    ]);
    assert!(dir.path().join("global.pmap").exists());
    assert!(!dir.path().join("caustic.pmap").exists(), "a stale caustic map would be mistaken for this scene's");
}

fn write_variant(dir: &Path, name: &str, edit: impl Fn(&str) -> String) -> PathBuf {
    let text = std::fs::read_to_string(scene("cornell_boxes.gltf")).unwrap();
    std::fs::copy(scene("cornell_boxes.bin"), dir.join("cornell_boxes.bin")).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, edit(&text)).unwrap();
    p
}

#[test]
fn bad_scenes_fail_with_one_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let dark = write_variant(dir.path(), "dark.gltf", |t| {
        t.replace("\"emissiveStrength\": 12.0", "\"emissiveStrength\": 0.0")
    });
    let broken = write_variant(dir.path(), "broken.gltf", |t| t[..t.len() / 3].to_owned());
    for (file, what) in [
        (dark, "no lights with non-zero power"),
        (broken, "not a valid glTF"),
        (dir.path().join("missing.gltf"), "cannot read"),
    ] {
        let out = dir.path().join(format!("out-{}", file.file_stem().unwrap().to_string_lossy()));
        let o = trace(&["--scene", file.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        let last = err.lines().last().unwrap_or("");
        assert!(
            last.starts_with("photon-trace: error: ") && last.contains(what) && last.contains(file.to_str().unwrap()),
            "{err}"
        );
        assert!(!out.join("global.pmap").exists());
    }
    let o = trace(&[
        "--scene",
        scene("cornell_boxes.gltf").to_str().unwrap(),
        "--out",
        dir.path().join("o").to_str().unwrap(),
        "--light-share",
        "nope=0.5",
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("no light of that name"));
}

#[test]
fn an_output_folder_that_cannot_be_written_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("not_a_folder");
    std::fs::write(&blocker, b"x").unwrap();
    let out = blocker.join("out");
    let o = trace(&[
        "--scene",
        scene("cornell_boxes.gltf").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--global-photons",
        "1000",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let last = err.trim_end().lines().last().unwrap();
    assert!(last.contains("cannot create output folder") && last.contains("not_a_folder"), "{err}");
    assert_eq!(std::fs::read(&blocker).unwrap(), b"x");
}
