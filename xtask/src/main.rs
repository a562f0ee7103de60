//! Project automation, run as `cargo xtask <task>` (alias in `.cargo/config.toml`).
//! One module per task; few dependencies.

use xtask::{gen_scenes, run};

mod figure1;
mod tradeoff;

use anyhow::{Result, bail};
use std::path::PathBuf;

const USAGE: &str = "usage: cargo xtask <task>

tasks:
  run [PIPELINE.toml] [--scene FILE] [--out DIR] [--width W --height H] [--force]
                         run the pipeline stages in order (default: pipeline.toml,
                         output in out/<scene name>/); steps whose inputs and
                         parameters are unchanged are skipped unless --force
  compare IMAGE.exr REFERENCE.exr [--mask-above V] [--layer NAME]
                         relative RMSE, bias and SSIM of an image against a reference
                         (pixels where the reference exceeds V are left out)
  tradeoff [--scene FILE] [--out DIR] [--size N]
                         what accuracy costs in time: a path-traced reference, then
                         one setting at a time; CSV, markdown, plot.svg and plot.png
  figure1 [--out DIR] [--size N]
                         Christensen's Figure 1 (a)-(g), a contact sheet and the
                         section 3 table beside the paper's numbers
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
        Some("run") => run::run(&args[1..], &workspace_root()).map(|_| ()),
        Some("compare") => compare(&args[1..]),
        Some("tradeoff") => tradeoff::run(&args[1..], &workspace_root()),
        Some("figure1") => figure1::run(&args[1..], &workspace_root()),
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

fn compare(args: &[String]) -> Result<()> {
    let mut files = Vec::new();
    let mut mask = f32::INFINITY;
    let mut layer = "total".to_string();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--mask-above" => mask = it.next().map(|v| v.parse()).transpose()?.unwrap_or(f32::INFINITY),
            "--layer" => layer = it.next().cloned().unwrap_or_default(),
            f => files.push(PathBuf::from(f)),
        }
    }
    let [a, b] = files.as_slice() else { bail!("compare needs IMAGE.exr and REFERENCE.exr") };
    let (ia, ib) = (pm_image::read_exr(a)?, pm_image::read_exr(b)?);
    if (ia.width, ia.height) != (ib.width, ib.height) {
        bail!("{} is {}x{} but {} is {}x{}", a.display(), ia.width, ia.height, b.display(), ib.width, ib.height);
    }
    let pick = |i: &pm_image::Layers, p: &PathBuf| {
        i.layer(&layer).map(<[_]>::to_vec).ok_or_else(|| anyhow::anyhow!("{}: no layer {layer}", p.display()))
    };
    let (la, lb) = (pick(&ia, a)?, pick(&ib, b)?);
    let e = pm_image::compare(&la, &lb, mask);
    let ssim = pm_image::ssim(&la, &lb, ia.width as usize, ia.height as usize);
    println!("relative RMSE {:.5}  relative bias {:+.5}  SSIM {ssim:.4}  pixels {}", e.rel_rmse, e.rel_bias, e.pixels);
    Ok(())
}
