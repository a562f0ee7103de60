//! `photon-render`: see the library for what it does.
use clap::Parser;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-render", || photon_render::run(&photon_render::Cli::parse()).map(|_| ()))
}
