//! The differential checks' scene generator: seeded and deterministic, and every
//! scene it writes is a glTF file the loader reads, with a camera, lights that
//! emit, and the parts its recipe names.

#[test]
fn generated_scenes_are_deterministic_and_load() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let n = 40;
    let scenes = pm_scenegen::random::write(&a, 7, n).unwrap();
    pm_scenegen::random::write(&b, 7, n).unwrap();
    let (mut fog, mut moved, mut open) = (0, 0, 0);
    for (path, recipe) in &scenes {
        let name = path.file_name().unwrap();
        for ext in ["gltf", "bin", "json"] {
            let f = std::path::Path::new(name).with_extension(ext);
            assert_eq!(std::fs::read(a.join(&f)).unwrap(), std::fs::read(b.join(&f)).unwrap(), "{f:?} differs");
        }
        let scene = pm_scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(scene.camera.is_some(), "{recipe:?}");
        assert!(scene.lights.iter().any(|l| l.power.max_element() > 0.0), "{recipe:?}");
        assert_eq!(scene.lights.len(), recipe.lights.len(), "{recipe:?}");
        assert_eq!(scene.has_media(), recipe.fog.is_some(), "{recipe:?}");
        fog += recipe.fog.is_some() as u32;
        moved += (recipe.scale != 1.0 || recipe.offset != [0.0; 3]) as u32;
        open += (recipe.room == "open") as u32;
    }
    // The mix the generator promises shows up in forty scenes.
    assert!(fog > 0 && moved > 0 && open > 0, "fog {fog}, moved {moved}, open {open}");
    // Another seed, other scenes.
    let other = pm_scenegen::random::write(&dir.path().join("c"), 8, 1).unwrap();
    assert_ne!(std::fs::read(&other[0].0).unwrap(), std::fs::read(&scenes[0].0).unwrap());
}
