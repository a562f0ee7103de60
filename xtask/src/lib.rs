//! The parts of `cargo xtask` that tests also use: the scene generator (a test checks
//! the committed scenes are what the code generates), the pipeline runner (tests run
//! it on a small scene), the job plan's executor and the stage binaries they run.
//! What the pipeline is (its settings, steps and job graph) is `pm-pipeline`.

pub mod assemble;
pub mod exec;
pub mod gen_scenes;
pub mod gltf;
pub mod plan;
pub mod plot;
pub mod run;
pub mod slurm_selftest;
pub mod stages;
