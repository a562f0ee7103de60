//! What accuracy costs in time, measured: the trade-off study ([`tradeoff`]: one
//! setting at a time against a path-traced reference, typed rows, the Pareto front
//! that pipeline.toml's `quality` picks from), the comparison with Mitsuba 3's path
//! tracer ([`peer`]), and the figures both draw ([`plot`]: SVG and PNG from one list
//! of shapes). `cargo xtask tradeoff` and `cargo xtask peer` call it; it runs the
//! stage binaries through pm-runner.

pub mod differential;
pub mod peer;
pub mod plot;
pub mod tradeoff;
