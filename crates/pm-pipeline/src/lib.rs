//! The batch pipeline as data: pipeline.toml typed ([`Pipeline`], with `quality` or
//! `time_budget_s` resolved against a measured accuracy/time front after parsing,
//! [`quality`]), Christensen's steps as values ([`steps`]: name, stage, arguments,
//! inputs, outputs; the key that decides whether a step runs again), and the job
//! graph for other machines ([`jobs`]: trace slices, render tiles, frame runs;
//! Slurm scripts and an Open Job Description template).
//!
//! It runs nothing: `cargo xtask run` executes the steps and `cargo xtask plan`
//! writes the job files. It sits beside the stage shell and below the stage
//! binaries: pipeline.toml's sections are the library crates' parameter types
//! (`TraceParams`, `IrradianceParams`, `RenderParams`, `SppmParams`, `LiveParams`),
//! the same the stages take as options.

mod config;
pub mod jobs;
pub mod quality;
pub mod steps;

pub use config::{AutoWord, EffectName, EffectsCfg, Pipeline, Quality, Setup, schema};
