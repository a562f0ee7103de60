//! `photon-render`: see the library for what it does.
use clap::Parser;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-render", || {
        let r = photon_render::run(&photon_render::Cli::parse())?;
        if r.unfinished {
            let passes = r.samples_per_pixel.round();
            return Err(
                pm_stage::Unfinished(format!("{passes} of {} passes; run again to continue", r.params.passes)).into()
            );
        }
        Ok(())
    })
}
