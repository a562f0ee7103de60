//! `photon-render`: see the library for what it does.
use clap::Parser;

fn main() -> std::process::ExitCode {
    pm_stage::main_with("photon-render", || {
        let cli = photon_render::Cli::parse();
        let r = photon_render::run(&cli)?;
        if r.unfinished {
            let (done, total) = (r.samples_per_pixel.round(), cli.settings.passes().unwrap_or(0));
            return Err(pm_stage::Unfinished(format!("{done} of {total} passes; run again to continue")).into());
        }
        Ok(())
    })
}
