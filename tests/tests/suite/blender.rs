//! The Blender add-on (blender/photon_map): its own tests (tests/blender/test_addon.py,
//! what `cargo xtask blender-test` runs) under Blender as a Python module, bpy
//! 4.5.4, installed into target/bpy when missing. They render through the add-on
//! as F12 does: the stage (HDRI world, a sun with a 3 degree disc, a
//! glass sphere, a Principled Volume fog cube) against Cycles (mean within 5%,
//! 8 x 8 blocks within 20%), the world's orientation against Cycles (an image
//! with a spot per axis, as it is, turned and baked), the volume conversion
//! (Principled Volume against Volume Scatter + Absorption: the same image), the
//! passes in the Render Result, Esc stopping a render within a second, and frame
//! 24 of an animation rendered by Render Animation against Cycles.

use pm_runner::blender;
use std::path::PathBuf;

#[test]
fn the_blender_addon_renders_as_cycles_does() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let python = blender::ensure_bpy(&root).unwrap_or_else(|e| panic!("{e:#}"));
    let work = tempfile::tempdir().unwrap();
    blender::run_tests(&root, &python, &pm_tests::bin_dir(), work.path(), None).unwrap_or_else(|e| panic!("{e:#}"));
}
