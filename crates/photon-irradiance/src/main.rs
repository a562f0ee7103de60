//! `photon-irradiance`: see the library for what it does.
use clap::Parser;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-irradiance", || photon_irradiance::run(&photon_irradiance::Cli::parse()).map(|_| ()))
}
