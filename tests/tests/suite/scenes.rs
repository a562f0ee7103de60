//! The committed scenes are exactly what `cargo xtask gen-scenes` generates.

#[test]
fn committed_scenes_are_up_to_date() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    if let Err(e) = pm_scenegen::scenes::run(&dir, true) {
        panic!("{e:#}");
    }
}
