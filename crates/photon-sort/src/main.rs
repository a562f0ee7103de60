//! `photon-sort`: see the library for what it does.
use clap::Parser;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-sort", || photon_sort::run(&photon_sort::Cli::parse()).map(|_| ()))
}
