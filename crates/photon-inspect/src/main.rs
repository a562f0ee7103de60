//! `photon-inspect`: see the library for what it does.
use clap::Parser;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-inspect", || photon_inspect::run(&photon_inspect::Cli::parse()))
}
