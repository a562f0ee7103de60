//! What every stage binary shares, written once: the single exit path (one-line
//! error, non-zero exit code), the thread pool, progress reporting, scene loading
//! with its warnings printed once, the kd-tree check of maps read, and atomic JSON
//! output.
//!
//! Stage crates are `lib.rs` with `pub fn run(args) -> Result<Report>` and a
//! `main.rs` of a few lines that calls [`main_with`]. This crate knows nothing about
//! what a stage computes.

use anyhow::{Context, Result};
use std::io::IsTerminal;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// Run a stage's body and turn its result into the process exit: on error, print
/// `<stage>: error: <message chain>` as one line on stderr and return exit code 1.
pub fn main_with(stage: &str, body: impl FnOnce() -> Result<()>) -> ExitCode {
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let msg = format!("{e:#}").replace('\n', " ");
            eprintln!("{stage}: error: {msg}");
            ExitCode::FAILURE
        }
    }
}

/// Configure rayon's global pool: `threads` = 0 means one per core.
pub fn init_threads(threads: usize) -> Result<()> {
    if threads > 0 {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global()
            .context("cannot configure the thread pool")?;
    }
    Ok(())
}

/// Threads in the pool that parallel work runs on.
pub fn thread_count() -> usize {
    rayon::current_num_threads()
}

/// How a stage reads its scene file: `--light-units` on every stage that loads one,
/// pipeline.toml's top-level `light_units` for the runner.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct SceneArgs {
    /// Units of the glTF file's point, spot and directional light intensities:
    /// photometric (the glTF specification: candela and lux, divided by 683 lm/W into
    /// W/sr and W/m^2; what Blender's exporter writes by default) or radiometric
    /// (already W/sr and W/m^2; Blender's "Unitless" export). Emissive materials are
    /// radiance either way.
    #[arg(long, value_enum, default_value_t = pm_scene::LightUnits::Photometric)]
    pub light_units: pm_scene::LightUnits,
}

/// Load a scene, printing each of its warnings once on stderr.
pub fn load_scene(stage: &str, path: &Path, how: SceneArgs) -> Result<pm_scene::Scene> {
    let scene = pm_scene::load_with(path, how.light_units)?;
    for w in &scene.warnings {
        eprintln!("{stage}: warning: {}: {w}", path.display());
    }
    let memory = scene.memory_use();
    eprintln!(
        "{stage}: scene loaded: {} triangles, {} textures in {:.3} s (BVH {:.3} s); holds {memory}, {:.0} bytes per triangle",
        scene.triangles.len(),
        scene.textures.len(),
        scene.load_seconds,
        scene.bvh_seconds,
        memory.per_triangle(scene.triangles.len())
    );
    Ok(scene)
}

/// Stages 3 and 4 trust the kd-tree order of the maps they read: check it (a linear
/// pass, cheap next to reading the file), naming the file when it is not a tree.
pub fn verify_kd_tree<R: pm_format::PhotonRecord>(path: &Path, records: &[R]) -> Result<()> {
    pm_kdtree::KdTree::new(records)
        .verify()
        .map_err(|e| anyhow::anyhow!("{}: not a valid kd-tree: {e}", path.display()))
}

/// Parse K/N, part K (from 0) of N parts of some work (a trace slice, a tile, a run
/// of frames): whole numbers with 0 <= K < N. `part` names it in the error.
pub fn parse_part(s: &str, part: &str) -> Result<(u32, u32), String> {
    let (k, n) = s.split_once('/').ok_or_else(|| format!("expected K/N ({part} K of N, K from 0), got '{s}'"))?;
    let number = |v: &str| v.trim().parse::<u32>().map_err(|_| format!("expected K/N with whole numbers, got '{s}'"));
    let (k, n) = (number(k)?, number(n)?);
    if n == 0 || k >= n {
        return Err(format!("{part} {k} of {n}: needs 0 <= K < N"));
    }
    Ok((k, n))
}

/// Write a JSON value atomically (temporary file, then rename).
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    write_text(path, &(serde_json::to_string_pretty(value)? + "\n"))
}

/// Write text atomically (temporary file, then rename).
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    pm_format::write_atomically(path, |w| std::io::Write::write_all(w, text.as_bytes()))
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// Progress of a long step: a bar on a terminal; on a pipe or in CI, a start line
/// and a finish line with the elapsed time (indicatif hides itself there).
pub struct Progress {
    bar: indicatif::ProgressBar,
    label: String,
    start: Instant,
    terminal: bool,
}

impl Progress {
    /// Start a step of `total` units (0 for an unknown total).
    pub fn new(label: &str, total: u64) -> Progress {
        let terminal = std::io::stderr().is_terminal();
        let bar = if terminal {
            let bar = indicatif::ProgressBar::new(total);
            bar.set_style(
                indicatif::ProgressStyle::with_template("{prefix:>12} [{bar:40}] {pos}/{len} ({per_sec}, {eta})")
                    .expect("static template")
                    .progress_chars("=> "),
            );
            bar.set_prefix(label.to_owned());
            bar
        } else {
            eprintln!("{label}: started");
            indicatif::ProgressBar::hidden()
        };
        Progress { bar, label: label.to_owned(), start: Instant::now(), terminal }
    }

    /// Set the number of units done.
    pub fn set(&self, done: u64) {
        self.bar.set_position(done);
    }

    /// Finish, printing the elapsed time when not on a terminal. Returns seconds.
    pub fn finish(self) -> f64 {
        let secs = self.start.elapsed().as_secs_f64();
        self.bar.finish_and_clear();
        if !self.terminal {
            eprintln!("{}: done in {secs:.3} s", self.label);
        }
        secs
    }
}
