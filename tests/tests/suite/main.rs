//! The workspace's cross-stage and analytic-scene tests and the repository rules,
//! as one test binary (one link of the whole stack instead of one per file). Each
//! module is one area; TESTING.md says what each test compares against.

mod bdpt;
mod blender;
mod differential;
mod effects;
mod environment;
mod hard_cases;
mod hard_geometry;
mod hard_scenes;
mod irradiance;
mod materials;
mod media;
mod plan;
mod quality;
mod raster;
mod realtime;
mod regions;
mod render;
mod runner;
mod scenes;
mod sppm;
mod tidy;

/// Scene `index` of the differential checker's generator for `seed`, written
/// into `dir` as `cargo xtask differential` writes it (scene-NNN.gltf): its path
/// and what it holds.
fn generated_scene(dir: &std::path::Path, seed: u64, index: u32) -> (std::path::PathBuf, pm_scenegen::random::Recipe) {
    let (doc, recipe) = pm_scenegen::random::scene(seed, index);
    let name = format!("scene-{index:03}");
    doc.write(dir, &name, false).unwrap();
    (dir.join(format!("{name}.gltf")), recipe)
}
