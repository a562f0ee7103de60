//! The parts of `cargo xtask` that tests also use: the scene generator (a test checks
//! the committed scenes are what the code generates) and the pipeline runner (tests
//! run it on a small scene).

pub mod gen_scenes;
pub mod run;
