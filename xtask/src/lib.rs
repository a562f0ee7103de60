//! The parts of `cargo xtask` that tests also use: the scene generator, so a test
//! can check that the committed scenes are what the code generates.

pub mod gen_scenes;
