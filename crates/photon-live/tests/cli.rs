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
    // One CSV row per frame; the first frame fills the buffer (1,500 paths), the
    // others re-shoot 500 (nothing moves).
    let csv = std::fs::read_to_string(a.join("frames.csv")).unwrap();
    let column =
        |k: usize| -> Vec<String> { csv.lines().skip(1).map(|l| l.split(',').nth(k).unwrap().to_string()).collect() };
    assert_eq!(column(8), ["1500", "1500", "1500", "1500"]);
    assert_eq!(column(6), ["1500", "500", "500", "500"]);
    // The dumped buffer is a photon map the reader accepts, with the photons of the
    // 1,500 paths held.
    let map = pm_format::read(&a.join("buffer-2.pmap"), &pm_format::ReadExpect::default()).unwrap();
    assert_eq!(map.header().n_emitted, 1500);
    let img = pm_image::read_exr(&a.join("frames/0003.exr")).unwrap();
    assert!(img.total().unwrap().iter().all(|p| p.is_finite()));
    assert!(img.layer(pm_color::Layer::Indirect).unwrap().iter().any(|p| p.max_element() > 0.0));
}

/// An animation split into three runs of frames (7 frames: 2, 2 and 3), each
/// simulating the frames before its own without drawing, then assembled, gives the
/// frames and preview of one run byte for byte, and frames.csv's counts; for the
/// vertex method with a moving light and the temporal filter (state carried from
/// frame to frame), and for the image-space method.
#[test]
fn frame_tasks_assembled_equal_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[&str]); 2] = [
        ("jozwowski_room_16.gltf", &["--per-frame", "300", "--total", "900", "--temporal", "0.5"]),
        ("caustic_ring.gltf", &["--method", "ispm", "--bounce-res", "16"]),
    ];
    for (name, extra) in cases {
        let s = scene(name);
        let common = |out: &std::path::Path| -> Vec<String> {
            let mut a: Vec<String> = ["--scene", s.to_str().unwrap(), "--out", out.to_str().unwrap()]
                .iter()
                .map(|x| x.to_string())
                .collect();
            a.extend(["--frames", "7", "--width", "24", "--height", "16", "--fps", "10"].map(String::from));
            a.extend(extra.iter().map(|x| x.to_string()));
            a
        };
        let run = |args: Vec<String>| {
            let o = live(&args.iter().map(String::as_str).collect::<Vec<_>>());
            assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        };
        let (one, split) = (dir.path().join(format!("{name}-one")), dir.path().join(format!("{name}-split")));
        run(common(&one));
        for k in [2, 0, 1] {
            run([common(&split), vec!["--frame-task".into(), format!("{k}/3")]].concat());
        }
        assert!(!split.join("live.apng").exists(), "a task writes no preview");
        assert!(split.join("frames/part-0004-0007.csv").exists());
        let o = live(&["assemble", "--out", split.to_str().unwrap(), "--frames", "7", "--fps", "10"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        for f in (0..7).map(|f| format!("frames/{f:04}.png")).chain(["live.apng".to_string()]) {
            assert!(std::fs::read(one.join(&f)).unwrap() == std::fs::read(split.join(&f)).unwrap(), "{name}: {f}");
        }
        // frames.csv: the same rows but for the times (columns ending in _s).
        let rows = |d: &std::path::Path| -> Vec<Vec<String>> {
            let text = std::fs::read_to_string(d.join("frames.csv")).unwrap();
            let header: Vec<String> = text.lines().next().unwrap().split(',').map(String::from).collect();
            text.lines()
                .map(|l| {
                    l.split(',').zip(&header).filter(|(_, h)| !h.ends_with("_s")).map(|(v, _)| v.to_string()).collect()
                })
                .collect()
        };
        assert_eq!(rows(&one), rows(&split), "{name}: frames.csv");
        assert_eq!(rows(&one).len(), 8);
    }
    // A missing part is named.
    let split = dir.path().join("caustic_ring.gltf-split");
    std::fs::remove_file(split.join("frames/part-0002-0004.csv")).unwrap();
    let o = live(&["assemble", "--out", split.to_str().unwrap(), "--frames", "7"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("gap or overlap"), "{}", String::from_utf8_lossy(&o.stderr));
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

/// `--direct shadow-map` says which lights it cannot map (the furnace's emitting
/// sphere is curved) and that every light then takes shadow rays; a scene whose
/// lights all have maps (cornell_spheres' panel) gets no note.
#[test]
fn shadow_maps_name_the_lights_they_cannot_draw() {
    let dir = tempfile::tempdir().unwrap();
    for (name, noted) in [("furnace.gltf", true), ("cornell_spheres.gltf", false)] {
        let s = scene(name);
        let out = dir.path().join(name);
        let args = ["--scene", s.to_str().unwrap(), "--out", out.to_str().unwrap(), "--method", "ispm"];
        let o = live(
            &[&args[..], &["--frames", "1", "--width", "16", "--height", "16", "--direct", "shadow-map"]].concat(),
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert_eq!(err.contains("no shadow map for furnace_sphere"), noted, "{name}: {err}");
        assert_eq!(err.contains("every light takes shadow rays"), noted, "{name}: {err}");
    }
}
