//! `photon-live`: see the library for what it does.
use clap::Parser;

/// A frame allocates and frees tens of megabytes (the region loop's pixels and
/// layers, the rasteriser's fragments); glibc's allocator returned them to the
/// kernel and faulted them back in every frame, which cost 25 of 60 ms per 512 x 512
/// frame. mimalloc keeps them (measured in BENCHMARKS.md).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-live", || photon_live::main(&photon_live::Cli::parse()))
}
