//! The committed scenes are exactly what `cargo xtask gen-scenes` generates.

#[test]
fn committed_scenes_are_up_to_date() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    if let Err(e) = pm_scenegen::scenes::run(&dir, true) {
        panic!("{e:#}");
    }
}

/// A scene that requires a glTF extension the renderer does not read (here a
/// committed scene marked Draco-compressed, its first accessor's data gone as
/// in such a file) stops `cargo xtask run` before anything is written, with the
/// stage's one line naming the file and the extension and exit code 2 (kept
/// through the runner, `pm_stage::is_unsupported`); a stage run alone exits with
/// 2 and writes no image.
#[test]
fn a_scene_needing_an_extension_not_read_stops_the_run_with_exit_code_2_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let mut g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(scenes.join("cornell_boxes.gltf")).unwrap()).unwrap();
    g["accessors"][0].as_object_mut().unwrap().remove("bufferView");
    g["extensionsRequired"] = serde_json::json!(["KHR_draco_mesh_compression"]);
    g["extensionsUsed"] = serde_json::json!(["KHR_draco_mesh_compression"]);
    std::fs::copy(scenes.join("cornell_boxes.bin"), dir.path().join("cornell_boxes.bin")).unwrap();
    let scene = dir.path().join("draco.gltf");
    std::fs::write(&scene, g.to_string()).unwrap();
    let out = dir.path().join("out");
    let args = pm_runner::run::RunArgs { scene: Some(scene.clone()), out: Some(out.clone()), ..Default::default() };
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let e = pm_runner::run::run_with(&args, &root, &pm_tests::bins()).err().expect("the run succeeded");
    let msg = format!("{e:#}");
    assert!(pm_stage::is_unsupported(&e), "{msg}");
    assert!(msg.contains("draco.gltf") && msg.contains("KHR_draco_mesh_compression") && !msg.contains('\n'), "{msg}");
    assert!(!out.exists(), "the run created {}", out.display());
    let image = dir.path().join("image.exr");
    let status = std::process::Command::new(pm_tests::bins().path("photon-render"))
        .args(["--scene", scene.to_str().unwrap(), "--mode", "path", "--out", image.to_str().unwrap()])
        .stderr(std::process::Stdio::null())
        .status()
        .unwrap();
    assert_eq!(status.code(), Some(2));
    assert!(!image.exists());
}
