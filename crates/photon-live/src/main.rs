//! `photon-live`: see the library for what it does.
use clap::Parser;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-live", || photon_live::run(&photon_live::Cli::parse()).map(|_| ()))
}
