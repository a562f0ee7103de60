//! The parts of `cargo xtask` that tests also use: the scene generator (a test checks
//! the committed scenes are what the code generates), the pipeline runner (tests run
//! it on a small scene) and the stage binaries it runs.

pub mod accuracy;
pub mod assemble;
pub mod gen_scenes;
pub mod plan;
pub mod plot;
pub mod quality;
pub mod run;
pub mod slurm_selftest;
pub mod stages;
