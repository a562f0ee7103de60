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
    assert!(img.total().unwrap().iter().all(|p| p.is_finite()));
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
    // A medium for a material the scene lacks (one line naming the scene and the
    // material), and ones out of range (naming the option and the coefficient).
    let boxes = scene("cornell_boxes.gltf");
    for (medium, want) in [
        ("smoke:sigma_a=1,1,1:sigma_s=0,0,0:g=0", ["cornell_boxes.gltf", "no material 'smoke'"]),
        ("scene:sigma_a=0.1,0.1,0.1:sigma_s=0.2,0.2,0.2:g=1.5", ["--medium", "g 1.5 must be in (-1, 1)"]),
        ("scene:sigma_a=-1,0.1,0.1:sigma_s=0.2,0.2,0.2:g=0", ["--medium", "sigma_a"]),
    ] {
        let r = o(&["--scene", boxes.to_str().unwrap(), "--mode", "path", "--medium", medium]);
        let err = String::from_utf8_lossy(&r.stderr);
        let last = err.trim_end().lines().last().unwrap_or_default();
        assert_eq!(r.status.code(), Some(1), "{medium}: {err}");
        assert!(want.iter().all(|w| last.contains(w)), "{medium}: {err}");
    }
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
    assert!(img.total().unwrap().iter().all(|p| p.is_finite()));
    assert!(img.layer(pm_color::Layer::Direct).unwrap().iter().any(|p| p.max_element() > 0.0));
}

/// Stages 1-3 in memory (pm-tests), written as the kd-tree map files stage 4 reads.
fn write_maps(dir: &Path, scene_file: &Path) -> (PathBuf, PathBuf) {
    use pm_format::{Header, Layout, MapKind, Order, PhotonMap};
    let scene = pm_scene::load(scene_file).unwrap();
    let (g, c) = pm_tests::photon_maps(&scene, 20_000, 2_000, 0.25);
    let header = |kind, layout| {
        Header::new(kind, Order::KdTree, layout, 1, scene.content_hash, scene.bounds.diagonal(), "{}".into())
    };
    let mut gh = header(MapKind::Global, Layout::CompactIrradiance);
    gh.has_irradiance = true;
    let (gp, cp) = (dir.join("global.irr.pmap"), dir.join("caustic.kd.pmap"));
    PhotonMap::new(gh, g).write(&gp).unwrap();
    PhotonMap::new(header(MapKind::Caustic, Layout::Full), c).write(&cp).unwrap();
    (gp, cp)
}

/// The irradiance cache as a file, and regions: rendering with `--icache` gives the
/// same EXR bytes as the in-process prepass, each `--region` gives exactly the
/// whole image's pixels there (supersampling crosses the region borders at spp 4),
/// and a cache made with other settings is refused naming the setting.
#[test]
fn a_cache_file_and_regions_reproduce_the_whole_render() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_spheres.gltf");
    let (g, c) = write_maps(dir.path(), &s);
    let p = |f: &str| dir.path().join(f).display().to_string();
    let base = [
        "--scene",
        s.to_str().unwrap(),
        "--global",
        g.to_str().unwrap(),
        "--width",
        "37",
        "--height",
        "29",
        "--spp",
        "4",
        "--gather-rays",
        "32",
    ]
    .map(String::from);
    let go = |extra: &[String]| {
        let mut a = base.to_vec();
        a.extend(extra.iter().cloned());
        let o = Command::new(env!("CARGO_BIN_EXE_photon-render")).args(&a).output().unwrap();
        (o.status.success(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let strs = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let caustic = ["--caustic".to_string(), c.display().to_string()];
    let whole = [&caustic[..], &strs(&["--out", &p("whole.exr")])].concat();
    assert!(go(&whole).0);
    let (ok, err) = go(&strs(&["--icache-out", &p("icache.bin")]));
    assert!(ok, "{err}");
    let from_file = [&caustic[..], &strs(&["--icache", &p("icache.bin"), "--out", &p("file.exr")])].concat();
    assert!(go(&from_file).0);
    assert_eq!(std::fs::read(p("whole.exr")).unwrap(), std::fs::read(p("file.exr")).unwrap());
    let whole_img = pm_image::read_exr(Path::new(&p("whole.exr"))).unwrap();
    for (k, region) in ["0,0,37,1", "5,3,18,17", "18,3,37,29", "0,17,18,29"].iter().enumerate() {
        let out = p(&format!("r{k}.exr"));
        let a = [&caustic[..], &strs(&["--icache", &p("icache.bin"), "--region", region, "--out", &out])].concat();
        let (ok, err) = go(&a);
        assert!(ok, "{err}");
        let img = pm_image::read_exr(Path::new(&out)).unwrap();
        let r: Vec<u32> = region.split(',').map(|v| v.parse().unwrap()).collect();
        assert_eq!((img.width, img.height), (r[2] - r[0], r[3] - r[1]));
        for (name, px) in &img.layers {
            let all = whole_img.by_name(name).unwrap();
            for (j, v) in px.iter().enumerate() {
                let (x, y) = (r[0] + j as u32 % img.width, r[1] + j as u32 / img.width);
                assert_eq!(v.to_array().map(f32::to_bits), all[(y * 37 + x) as usize].to_array().map(f32::to_bits));
            }
        }
    }
    // Tiles assembled equal the whole render byte for byte: one-pixel-row tiles,
    // 8 x 8 tiles and 13 x 7 tiles (neither divides 37 x 29).
    let tilings: [Vec<[u32; 4]>; 3] =
        [vec![[0, 0, 37, 1], [0, 1, 37, 2], [0, 2, 37, 3], [0, 3, 37, 29]], grid(37, 29, 8, 8), grid(37, 29, 13, 7)];
    for (t, tiles) in tilings.iter().enumerate() {
        let mut parts = Vec::new();
        for (k, [x0, y0, x1, y1]) in tiles.iter().enumerate() {
            let out = p(&format!("t{t}_{k}.exr"));
            let region = format!("{x0},{y0},{x1},{y1}");
            let a = [&caustic[..], &strs(&["--icache", &p("icache.bin"), "--region", &region, "--out", &out])].concat();
            let (ok, err) = go(&a);
            assert!(ok, "{err}");
            parts.push(pm_image::read_exr_placed(Path::new(&out)).unwrap());
        }
        let whole = pm_image::assemble(&parts).unwrap();
        let joined = p(&format!("joined{t}.exr"));
        pm_image::write_exr(Path::new(&joined), &whole).unwrap();
        assert!(std::fs::read(&joined).unwrap() == std::fs::read(p("whole.exr")).unwrap(), "tiling {t}: bytes differ");
        // Leaving a tile out, or giving one twice, is an error naming the pixel.
        let gap = pm_image::assemble(&parts[1..]).unwrap_err();
        assert!(gap.starts_with("no region covers pixel"), "{gap}");
        let twice = [parts.clone(), vec![parts[0].clone()]].concat();
        assert!(pm_image::assemble(&twice).unwrap_err().contains("both cover pixel"));
    }
    let other = [&caustic[..], &strs(&["--icache", &p("icache.bin"), "--light-samples", "5", "--out", &p("x.exr")])];
    let (ok, err) = go(&other.concat());
    assert!(!ok && err.contains("icache.bin: made with light_samples=4, this render has light_samples=5"), "{err}");
    let (ok, err) = go(&strs(&["--region", "30,0,40,10", "--out", &p("x.exr")]));
    assert!(!ok && err.contains("--region 30,0,40,10 is outside the 37x29 image"), "{err}");
    let (ok, err) = go(&strs(&["--k", "0", "--out", &p("x.exr")]));
    assert!(!ok && err.contains("--k = 0 is out of range"), "{err}");
    assert!(!Path::new(&p("x.exr")).exists());
}

/// Stage 4 trusts the kd-tree order of the maps it reads: a map whose header says
/// kd-tree but whose records are not in heap order is refused, naming the file.
#[test]
fn a_map_that_is_not_a_kd_tree_is_refused() {
    use pm_format::{CompactIrrPhoton, Header, Layout, MapKind, Order, Photon, PhotonMap, PhotonRecord, flags};
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_boxes.gltf");
    let scene_ = pm_scene::load(&s).unwrap();
    // Records on a line, in reverse order, every one flagged a leaf: not a tree.
    let records: Vec<CompactIrrPhoton> = (0..50)
        .map(|i| {
            CompactIrrPhoton::encode(&Photon {
                position: glam::Vec3::new(0.9 - 0.03 * i as f32, 0.01, 0.0),
                power: glam::Vec3::splat(1e-3),
                wi: glam::Vec3::Y,
                flags: flags::AXIS_LEAF | flags::HAS_IRRADIANCE,
                normal: glam::Vec3::Y,
                irradiance: glam::Vec3::splat(0.1),
            })
        })
        .collect();
    let mut header = Header::new(
        MapKind::Global,
        Order::KdTree,
        Layout::CompactIrradiance,
        50,
        scene_.content_hash,
        scene_.bounds.diagonal(),
        "{}".into(),
    );
    header.has_irradiance = true;
    let g = dir.path().join("bad.irr.pmap");
    PhotonMap::new(header, records).write(&g).unwrap();
    let out = dir.path().join("x.exr");
    let o = render(&[
        "--scene",
        s.to_str().unwrap(),
        "--global",
        g.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("bad.irr.pmap: not a valid kd-tree"), "{err}");
    assert!(!out.exists());
}

/// Tiles of `tw` x `th` pixels over a `w` x `h` image, row by row (the last ones
/// cut short).
fn grid(w: u32, h: u32, tw: u32, th: u32) -> Vec<[u32; 4]> {
    (0..h.div_ceil(th))
        .flat_map(|j| (0..w.div_ceil(tw)).map(move |i| [i * tw, j * th, ((i + 1) * tw).min(w), ((j + 1) * th).min(h)]))
        .collect()
}

/// `--mode sppm` renders without photon maps; `--checkpoint 2` writes the image
/// after passes 2 and 4 of 6 (and says so) and leaves the finished image the
/// 6-pass render's, byte for byte; a tiny `--time-budget` stops after the first
/// pass (the report counts one sample a pixel); both options are refused outside
/// sppm mode.
#[test]
fn sppm_checkpoints_and_time_budget() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_boxes.gltf");
    let sppm = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let stats = dir.path().join(format!("{name}.json"));
        let mut a = vec![
            "--scene",
            s.to_str().unwrap(),
            "--mode",
            "sppm",
            "--photons-per-pass",
            "2000",
            "--width",
            "16",
            "--height",
            "12",
            "--out",
            out.to_str().unwrap(),
            "--stats-json",
            stats.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        let o = render(&a);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let said = String::from_utf8_lossy(&o.stderr).into_owned();
        (std::fs::read(&out).unwrap(), std::fs::read_to_string(&stats).unwrap(), said)
    };
    let (four, _, _) = sppm("four.exr", &["--passes", "4"]);
    let (six, _, _) = sppm("six.exr", &["--passes", "6"]);
    assert_ne!(four, six);
    let (six_checkpointed, _, said) = sppm("six_k.exr", &["--passes", "6", "--checkpoint", "2"]);
    assert_eq!(six_checkpointed, six, "checkpoints do not change the image");
    for k in [2, 4] {
        assert!(said.contains(&format!("checkpoint: {k} passes written")), "{said}");
    }
    let (_, stats, _) = sppm("budget.exr", &["--passes", "50", "--time-budget", "0.000001"]);
    let report: serde_json::Value = serde_json::from_str(&stats).unwrap();
    assert_eq!(report["samples"], 16 * 12, "one pass: {stats}");
    // The batch renderer has no passes (the path tracer has, of one sample a
    // pixel: `vcm_and_path_states_resume_bit_for_bit`).
    let o = render(&["--scene", s.to_str().unwrap(), "--mode", "full", "--checkpoint", "2", "--out", "x.exr"]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && said.contains("sppm") && said.contains("path"), "{said}");
}

/// `--state`: 8 passes, a stop, and 8 more from the state file (the render runs
/// to `--passes 16` from the 8 it holds) equal 16 passes in one run bit for bit,
/// image and state; a render stopped by `--time-budget` with a state exits with
/// code 75 and continues from the state with the same command; a state is
/// refused, naming the file and the setting, when the settings, the image size
/// or the scene differ, or when it holds more passes than asked for; and
/// `--run K/N` is the render with seed + K.
#[test]
fn sppm_state_resumes_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_boxes.gltf");
    let p = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
    let sppm_of = |scene: &Path, width: &str, out: &str, extra: &[&str]| {
        let out = p(out);
        let mut a = vec!["--scene", scene.to_str().unwrap(), "--mode", "sppm", "--photons-per-pass", "2000"];
        a.extend(["--width", width, "--height", "12", "--out", &out]);
        a.extend_from_slice(extra);
        render(&a)
    };
    let sppm = |out: &str, extra: &[&str]| sppm_of(&s, "16", out, extra);
    let ok = |o: std::process::Output| {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    ok(sppm("one.exr", &["--passes", "16", "--state", &p("one.state")]));
    ok(sppm("two.exr", &["--passes", "8", "--state", &p("two.state")]));
    let said = ok(sppm("two.exr", &["--passes", "16", "--state", &p("two.state")]));
    assert!(said.contains("continued from the 8 passes"), "{said}");
    let read = |f: &str| std::fs::read(p(f)).unwrap();
    assert_eq!(read("one.exr"), read("two.exr"), "8 + 8 passes against 16");
    assert_eq!(read("one.state"), read("two.state"));
    assert_eq!(pm_format::read_state(Path::new(&p("one.state"))).unwrap().passes, 16);
    // Stopped by the time budget: exit 75, the state holds the passes done; the
    // same command continues and finishes with the one-run image.
    let budget = ["--passes", "16", "--state", &p("b.state"), "--time-budget", "0.000001"];
    let o = sppm("b.exr", &budget);
    assert_eq!(o.status.code(), Some(75), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("unfinished: 1 of 16 passes"));
    assert_eq!(pm_format::read_state(Path::new(&p("b.state"))).unwrap().passes, 1);
    ok(sppm("b.exr", &["--passes", "16", "--state", &p("b.state")]));
    assert_eq!(read("one.exr"), read("b.exr"));
    // Refusals: one line naming the state file and what differs.
    let one_state = p("one.state");
    let refused_of = |scene: &Path, width: &str, extra: &[&str], what: &str| {
        let mut a = vec!["--state", one_state.as_str()];
        a.extend_from_slice(extra);
        let o = sppm_of(scene, width, "refused.exr", &a);
        let said = String::from_utf8_lossy(&o.stderr);
        let e = said.lines().find(|l| l.contains("error:")).unwrap_or_default();
        assert!(!o.status.success() && e.contains("one.state") && e.contains(what), "{said}");
        assert!(!dir.path().join("refused.exr").exists());
    };
    let refused = |extra: &[&str], what: &str| refused_of(&s, "16", extra, what);
    refused(&["--passes", "32", "--sppm-alpha", "0.5"], "sppm_alpha=0.5");
    refused(&["--passes", "32", "--seed", "2"], "seed=2");
    refused_of(&s, "20", &["--passes", "32"], "16x12");
    refused(&["--passes", "8"], "holds 16 passes");
    refused_of(&scene("furnace.gltf"), "16", &["--passes", "32"], "another scene");
    std::fs::write(p("bad.state"), b"not a state").unwrap();
    let o = sppm("refused.exr", &["--passes", "4", "--state", &p("bad.state")]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a usable progressive state"));
    // Run 2 of 4 is the render with seed 3.
    ok(sppm("run.exr", &["--passes", "4", "--run", "2/4"]));
    ok(sppm("seed.exr", &["--passes", "4", "--seed", "3"]));
    assert_eq!(read("run.exr"), read("seed.exr"));
}

/// Bidirectional path tracing runs in passes as SPPM does: 4 passes, a stop, and
/// 4 more from the state file (`--bdpt-passes 8` is the total) equal 8 passes in one run
/// bit for bit, image and state; `--time-budget` with a state exits with code 75
/// and the same command finishes the one-run image; a checkpoint does not change
/// the image; an SPPM state, another seed and another size are refused naming the
/// file.
#[test]
fn bdpt_state_resumes_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_spheres.gltf");
    let p = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
    let bdpt_of = |width: &str, out: &str, extra: &[&str]| {
        let out = p(out);
        let mut a = vec!["--scene", s.to_str().unwrap(), "--mode", "bdpt"];
        a.extend(["--width", width, "--height", "12", "--out", &out]);
        a.extend_from_slice(extra);
        render(&a)
    };
    let bdpt = |out: &str, extra: &[&str]| bdpt_of("16", out, extra);
    let ok = |o: std::process::Output| {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    ok(bdpt("one.exr", &["--bdpt-passes", "8", "--state", &p("one.state")]));
    ok(bdpt("plain.exr", &["--bdpt-passes", "8"]));
    ok(bdpt("two.exr", &["--bdpt-passes", "4", "--state", &p("two.state")]));
    let said = ok(bdpt("two.exr", &["--bdpt-passes", "8", "--state", &p("two.state")]));
    assert!(said.contains("continued from the 4 passes"), "{said}");
    let read = |f: &str| std::fs::read(p(f)).unwrap();
    assert_eq!(read("one.exr"), read("two.exr"), "4 + 4 passes against 8");
    assert_eq!(read("one.exr"), read("plain.exr"), "a state file does not change the image");
    assert_eq!(read("one.state"), read("two.state"));
    assert_eq!(pm_format::read_pass_state(Path::new(&p("one.state"))).unwrap().passes, 8);
    let said = ok(bdpt("k.exr", &["--bdpt-passes", "8", "--checkpoint", "2"]));
    assert!(said.contains("checkpoint: 4 passes written"), "{said}");
    assert_eq!(read("one.exr"), read("k.exr"));
    let o = bdpt("b.exr", &["--bdpt-passes", "8", "--state", &p("b.state"), "--time-budget", "0.000001"]);
    assert_eq!(o.status.code(), Some(75), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("unfinished: 1 of 8 passes"));
    ok(bdpt("b.exr", &["--bdpt-passes", "8", "--state", &p("b.state")]));
    assert_eq!(read("one.exr"), read("b.exr"));
    // Refusals: one line naming the state file and what differs.
    let refused = |width: &str, state: &str, extra: &[&str], what: &str| {
        let state = p(state);
        let mut a = vec!["--state", state.as_str()];
        a.extend_from_slice(extra);
        let o = bdpt_of(width, "refused.exr", &a);
        let said = String::from_utf8_lossy(&o.stderr);
        let e = said.lines().find(|l| l.contains("error:")).unwrap_or_default();
        assert!(!o.status.success() && e.contains(".state") && e.contains(what), "{said}");
        assert!(!dir.path().join("refused.exr").exists());
    };
    refused("16", "one.state", &["--bdpt-passes", "16", "--seed", "2"], "seed=2");
    refused("20", "one.state", &["--bdpt-passes", "16"], "16x12");
    refused("16", "one.state", &["--bdpt-passes", "4"], "holds 8 passes");
    let sppm_state = p("sppm.state");
    let o = render(&[
        "--scene",
        s.to_str().unwrap(),
        "--mode",
        "sppm",
        "--passes",
        "1",
        "--photons-per-pass",
        "100",
        "--width",
        "16",
        "--height",
        "12",
        "--state",
        &sppm_state,
        "--out",
        &p("sppm.exr"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    refused("16", "sppm.state", &["--bdpt-passes", "4"], "not a usable progressive pass sums");
}

/// Vertex connection and merging, and the path tracer in passes of one sample a
/// pixel, stop and resume as BDPT does: 4 passes and 4 more from the state equal
/// 8 in one run bit for bit (and the path tracer's passes hold --spp samples);
/// a time budget stops them with exit 75; each refuses the other's state, naming
/// the method it was made with.
#[test]
fn vcm_and_path_states_resume_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("cornell_spheres.gltf");
    let p = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
    let read = |f: &str| std::fs::read(p(f)).unwrap();
    for (mode, passes) in [("vcm", "--vcm-passes"), ("path", "--spp")] {
        let run = |out: &str, n: &str, extra: &[&str]| {
            let out = p(&format!("{mode}-{out}"));
            let mut a = vec!["--scene", s.to_str().unwrap(), "--mode", mode, passes, n];
            a.extend(["--width", "16", "--height", "12", "--out", &out]);
            a.extend_from_slice(extra);
            render(&a)
        };
        let ok = |o: std::process::Output| {
            assert!(o.status.success(), "{mode}: {}", String::from_utf8_lossy(&o.stderr));
            String::from_utf8_lossy(&o.stderr).into_owned()
        };
        let state = |f: &str| p(&format!("{mode}-{f}"));
        ok(run("one.exr", "8", &["--state", &state("one.state")]));
        ok(run("two.exr", "4", &["--state", &state("two.state")]));
        let said = ok(run("two.exr", "8", &["--state", &state("two.state")]));
        assert!(said.contains("continued from the 4 passes"), "{mode}: {said}");
        assert_eq!(read(&format!("{mode}-one.exr")), read(&format!("{mode}-two.exr")), "{mode}: 4 + 4 against 8");
        let file = pm_format::read_pass_state(Path::new(&state("one.state"))).unwrap();
        assert!(file.passes == 8 && file.params.contains(&format!("method={mode}")), "{mode}: {}", file.params);
        let o = run("b.exr", "8", &["--state", &state("b.state"), "--time-budget", "0.000001"]);
        assert_eq!(o.status.code(), Some(75), "{mode}: {}", String::from_utf8_lossy(&o.stderr));
    }
    // A state of one method refused by the other, naming what it was made with.
    let o = render(&[
        "--scene",
        s.to_str().unwrap(),
        "--mode",
        "bdpt",
        "--bdpt-passes",
        "8",
        "--width",
        "16",
        "--height",
        "12",
        "--state",
        &p("vcm-one.state"),
        "--out",
        &p("refused.exr"),
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && said.contains("vcm-one.state") && said.contains("method=vcm"), "{said}");
    assert!(!dir.path().join("refused.exr").exists());
}
