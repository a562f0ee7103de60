//! Running the pipeline on this machine: Christensen's steps ([`pm_pipeline::steps`])
//! as separate stage processes exchanging files ([`run`]), a job plan's steps and
//! array tasks ([`exec`]), the stage binaries themselves ([`bins`]), and the
//! Blender add-on: staged with the parameters' schema, zipped, and the Python
//! with `bpy` its tests run under ([`blender`]). What the
//! pipeline is (its settings, steps and job graph) is `pm-pipeline`; `cargo xtask
//! run`, `live` and `plan` and the tests all call this crate.
//!
//! It runs the stage binaries by path and reads their statistics through
//! [`pm_stage::report`], so it depends on no stage crate.

pub mod bins;
pub mod blender;
pub mod exec;
pub mod run;
