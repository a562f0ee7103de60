//! `photon-trace`: see the library for what it does.
use clap::Parser;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-trace", || photon_trace::run(photon_trace::Cli::parse()).map(|_| ()))
}
