//! Project automation, run as `cargo xtask <task>` (alias in `.cargo/config.toml`).
//! One module per task; few dependencies.

use xtask::gen_scenes;
mod run;

use anyhow::{Result, bail};
use std::path::PathBuf;

const USAGE: &str = "usage: cargo xtask <task>

tasks:
  run [PIPELINE.toml] [--scene FILE] [--out DIR]
                         run the pipeline stages in order (default: pipeline.toml,
                         output in out/<scene name>/)
  gen-scenes [--check]   write scenes/*.gltf + .bin from code (--check: fail if the
                         committed files differ from what the code generates)";

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("run") => run::run(&args[1..], &workspace_root()),
        Some("gen-scenes") => {
            gen_scenes::run(&workspace_root().join("scenes"), args[1..].iter().any(|a| a == "--check"))
        }
        Some("-h" | "--help") | None => {
            println!("{USAGE}");
            Ok(())
        }
        Some(other) => bail!("unknown task '{other}'\n{USAGE}"),
    }
}

/// The repository root (the parent of this crate's folder).
fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask lives one level below the root").to_owned()
}
