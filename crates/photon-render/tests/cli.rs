//! The photon-render binary: images that round-trip, identical for any thread count,
//! and clear refusals.

use std::path::{Path, PathBuf};
use std::process::Command;

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name)
}

fn run(bin: &str, args: &[&str]) -> std::process::Output {
    Command::new(bin).args(args).output().unwrap()
}

fn render(args: &[&str]) -> std::process::Output {
    run(env!("CARGO_BIN_EXE_photon-render"), args)
}

#[test]
fn path_mode_images_are_identical_for_any_thread_count_and_readable() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_spheres.gltf");
    for t in ["1", "2"] {
        let out = dir.path().join(format!("p{t}.exr"));
        let png = dir.path().join(format!("p{t}.png"));
        let o = render(&[
            "--scene",
            s.to_str().unwrap(),
            "--mode",
            "path",
            "--spp",
            "8",
            "--width",
            "40",
            "--height",
            "30",
            "--out",
            out.to_str().unwrap(),
            "--png",
            png.to_str().unwrap(),
            "--threads",
            t,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let a = std::fs::read(dir.path().join("p1.exr")).unwrap();
    assert_eq!(a, std::fs::read(dir.path().join("p2.exr")).unwrap());
    assert_eq!(std::fs::read(dir.path().join("p1.png")).unwrap(), std::fs::read(dir.path().join("p2.png")).unwrap());
    let img = pm_image::read_exr(&dir.path().join("p1.exr")).unwrap();
    assert_eq!((img.width, img.height), (40, 30));
    let names: Vec<&str> = img.layers.iter().map(|l| l.0.as_str()).collect();
    for want in ["total", "direct", "caustic", "indirect", "specular"] {
        assert!(names.contains(&want), "{names:?}");
    }
    assert!(img.layer("total").unwrap().iter().all(|p| p.is_finite()));
}

#[test]
fn refuses_bad_inputs_without_writing_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let o = |args: &[&str]| {
        let mut v = args.to_vec();
        v.extend(["--out", out.to_str().unwrap(), "--width", "8", "--height", "8"]);
        render(&v)
    };
    // Full mode without photon maps.
    let r = o(&["--scene", scene("cornell_boxes.gltf").to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&r.stderr).contains("--global is required"));
    // A map that is not a photon map.
    let bogus = dir.path().join("g.pmap");
    std::fs::write(&bogus, b"hello").unwrap();
    let r = o(&["--scene", scene("cornell_boxes.gltf").to_str().unwrap(), "--global", bogus.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.trim_end().lines().last().unwrap().contains("g.pmap: not a photon map"), "{err}");
    // A scene without a camera (the hand-written test scene of pm-scene has one;
    // write one that does not).
    let no_cam = dir.path().join("nocam.gltf");
    let text = std::fs::read_to_string(scene("cornell_boxes.gltf")).unwrap();
    let text = text.replace("\"camera\": 0,", "");
    std::fs::write(&no_cam, text).unwrap();
    std::fs::copy(scene("cornell_boxes.bin"), dir.path().join("cornell_boxes.bin")).unwrap();
    let r = o(&["--scene", no_cam.to_str().unwrap(), "--mode", "path"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1));
    assert!(err.contains("nocam.gltf: the scene has no perspective camera"), "{err}");
    assert!(!out.exists() && !Path::new(&out).with_extension("png").exists());
}

#[test]
fn an_empty_global_map_renders_and_says_so() {
    use pm_format::{CompactIrrPhoton, Header, Layout, MapKind, Order, PhotonMap};
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_boxes.gltf");
    let hash = pm_scene::load(&s).unwrap().content_hash;
    let mut header =
        Header::new(MapKind::Global, Order::KdTree, Layout::CompactIrradiance, 1000, hash, 1.0, "{}".into());
    header.has_irradiance = true;
    let g = dir.path().join("global.irr.pmap");
    PhotonMap::new(header, Vec::<CompactIrrPhoton>::new()).write(&g).unwrap();
    let out = dir.path().join("x.exr");
    let o = render(&[
        "--scene",
        s.to_str().unwrap(),
        "--global",
        g.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--width",
        "12",
        "--height",
        "12",
        "--gather-rays",
        "16",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("the global photon map holds no photons"), "{err}");
    let img = pm_image::read_exr(&out).unwrap();
    assert!(img.layer("total").unwrap().iter().all(|p| p.is_finite()));
    assert!(img.layer("direct").unwrap().iter().any(|p| p.max_element() > 0.0));
}
