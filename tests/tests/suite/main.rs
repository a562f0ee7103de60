//! The workspace's cross-stage and analytic-scene tests and the repository rules,
//! as one test binary (one link of the whole stack instead of one per file). Each
//! module is one area; TESTING.md says what each test compares against.

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
