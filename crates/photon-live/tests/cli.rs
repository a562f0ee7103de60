//! The photon-live binary: frames, preview and timings on a real scene, identical
//! for any thread count, and clear refusals.

use std::path::PathBuf;
use std::process::Command;

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name)
}

fn live(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_photon-live")).args(args).output().unwrap()
}

#[test]
fn frames_preview_and_timings_are_written_and_identical_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_spheres.gltf");
    for t in ["1", "2"] {
        let out = dir.path().join(format!("t{t}"));
        let o = live(&[
            "--scene",
            s.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--frames",
            "4",
            "--per-frame",
            "500",
            "--total",
            "1500",
            "--width",
            "32",
            "--height",
            "24",
            "--exr",
            "--dump-frame",
            "2",
            "--threads",
            t,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (a, b) = (dir.path().join("t1"), dir.path().join("t2"));
    for f in ["frames/0000.png", "frames/0003.png", "frames/0003.exr", "live.apng", "buffer-2.pmap"] {
        assert_eq!(std::fs::read(a.join(f)).unwrap(), std::fs::read(b.join(f)).unwrap(), "{f}");
    }
    // The APNG is a real animation of 4 frames.
    let apng = std::fs::read(a.join("live.apng")).unwrap();
    let actl = apng.windows(4).position(|w| w == b"acTL").expect("an animation control chunk");
    assert_eq!(u32::from_be_bytes(apng[actl + 4..actl + 8].try_into().unwrap()), 4);
    // One CSV row per frame; the buffer holds 500, 1000, 1500, 1500 paths.
    let csv = std::fs::read_to_string(a.join("frames.csv")).unwrap();
    let held: Vec<&str> = csv.lines().skip(1).map(|l| l.split(',').nth(8).unwrap()).collect();
    assert_eq!(held, ["500", "1000", "1500", "1500"]);
    // The dumped buffer is a photon map the reader accepts, with the photons of the
    // 1,500 paths held.
    let map = pm_format::read(&a.join("buffer-2.pmap"), &pm_format::ReadExpect::default()).unwrap();
    assert_eq!(map.header().n_emitted, 1500);
    let img = pm_image::read_exr(&a.join("frames/0003.exr")).unwrap();
    assert!(img.layer("total").unwrap().iter().all(|p| p.is_finite()));
    assert!(img.layer("indirect").unwrap().iter().any(|p| p.max_element() > 0.0));
}

#[test]
fn refuses_bad_settings_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_boxes.gltf");
    let out = dir.path().join("o");
    for (args, want) in [
        (vec!["--per-frame", "3000", "--total", "2000"], "--per-frame = 3000 is above --total = 2000"),
        (vec!["--k", "0"], "--k = 0 is out of range"),
        (vec!["--max-radius-rel-diag", "-0.1"], "--max-radius-rel-diag = -0.1 is out of range"),
    ] {
        let mut a = vec!["--scene", s.to_str().unwrap(), "--out", out.to_str().unwrap()];
        a.extend(args);
        let o = live(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(want) && err.lines().count() == 1, "{err}");
    }
    assert!(!out.exists());
}
