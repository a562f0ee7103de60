//! The differential checks' small run, as CI runs it (issue 53): `cargo xtask
//! differential` on ten generated scenes of seed 3 at 24 x 24 pixels, the path
//! tracer at 128 + 128 samples a pixel, the batch renderer, SPPM and the two
//! real-time methods on the repository's settings.

use pm_study::differential::Checked;

/// The scenes of seed 3 the small run checks: the first nine and scene 10, whose
/// light the path tracer cannot see through a mirror (judged on its direct
/// layer). Until stop 81 it checked all of the first 20 (about 8 minutes of CI's
/// 15 beside the other tests); the ten keep a scene of each kind the twenty
/// judged (passing, failing, direct layer only) at half the time.
const SCENES: [u32; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 10];

/// No method crashes, runs a stage past two minutes or writes a non-finite or
/// negative pixel on any scene (those the path tracer cannot render whole are
/// run too and judged on their direct layer), every scene is accounted for once
/// per method, the report on disk says what the run returned. Scenes that pass
/// are at least as many as when this test was last raised (full 8, SPPM 10,
/// vertex 10 and ISPM 10 of 10, one of them judged on the direct layer only: the
/// failure classes the run found, in the note, are open), so a change
/// that breaks a passing case shows here. Full fails scenes 3 and 5. Scene 5
/// was passing until the generator gave some scenes Blender's layered materials
/// (stop 74): its brushed metal box under a sun draws a thin highlight that
/// adaptive supersampling under-samples (its direct layer +4.3% at the default
/// contrast 0.1, +0.16% with every pixel at 16 samples), the class of 18930/18's
/// edge-on mirror. Of all twenty, full passes 16, SPPM 19 (stop 81). About two
/// and a half minutes on the 2-core machine.
#[test]
fn the_small_differential_run_finds_no_crash_and_no_nonfinite_pixel() {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = tempfile::tempdir().unwrap();
    let args = pm_study::differential::Args {
        scenes: SCENES[SCENES.len() - 1] + 1,
        seed: 3,
        size: 24,
        methods: ["full", "sppm", "vertex", "ispm"].map(|m| Checked::parse(m).unwrap()).to_vec(),
        reference_spp: 128,
        out: Some(dir.path().to_path_buf()),
        time_limit_s: 120.0,
        only: SCENES.to_vec(),
    };
    let bins = pm_tests::bins();
    let report = pm_study::differential::run_with(&args, &root, &bins).unwrap();
    let summary = pm_study::differential::summary(&report);
    eprintln!("{summary}");
    let n = SCENES.len() as u32;
    for (m, c) in &report.methods {
        assert_eq!((c.crashed, c.hung, c.nonfinite), (0, 0, 0), "{m}: {summary}: {:?}", report.worst);
        assert_eq!(c.passed + c.failed + c.unjudged, n, "{m}: {summary}");
        assert_eq!(c.direct_only, 1, "{m}: {summary}");
    }
    assert_eq!(report.methods.len(), 4);
    let on_disk: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("report.json")).unwrap()).unwrap();
    let written: serde_json::Value = serde_json::from_str(&serde_json::to_string(&report).unwrap()).unwrap();
    assert_eq!(on_disk, written);
    // The contact sheet of the worst: a row per failure shown (at most eight).
    let (_, h, _) = pm_image::read_png_rgb8(&dir.path().join("worst.png")).unwrap();
    let failed: u32 = report.methods.values().map(|c| c.failed).sum();
    assert_eq!(h, failed.clamp(1, 8) * (24 * 5 + 34));
    let at_least = [("full", 8), ("sppm", 10), ("vertex", 10), ("ispm", 10)];
    for (m, k) in at_least {
        assert!(report.methods[m].passed >= k, "{m}: {summary}");
    }
}

/// Seed 77777's scene 37: the room's corner line (right wall on the floor)
/// passes through pixel (39, 39)'s centre at 48 x 48. The real-time methods'
/// rasteriser took the sunlit floor there and the path tracer's centre ray the
/// unlit wall: one pixel, 82% of its otherwise dark 8 x 8 block's direct light,
/// and both real-time methods failed. The checker judges methods that take one
/// sample at each centre without such pixels (`centres_on_edges`). Asserted: that
/// pixel is one, and they are few (under 3% of the image).
#[test]
fn pixels_whose_centre_lies_on_an_edge_are_found_and_few() {
    let dir = tempfile::tempdir().unwrap();
    let s = pm_scene::load(&crate::generated_scene(dir.path(), 77777, 37).0).unwrap();
    let edges = pm_study::differential::centres_on_edges(&s, 48, 48).unwrap();
    assert!(edges[39 * 48 + 39], "the corner's pixel");
    let n = edges.iter().filter(|e| **e).count();
    eprintln!("{n} of {} pixels have their centre on an edge", 48 * 48);
    assert!(n < 48 * 48 * 3 / 100, "{n} pixels");
}
