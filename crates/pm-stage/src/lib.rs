//! What every stage binary shares, written once: the single exit path (one-line
//! error, non-zero exit code), the thread pool, progress reporting, scene loading
//! with its warnings printed once, the kd-tree check of maps read, and atomic JSON
//! output.
//!
//! Stage crates are `lib.rs` with `pub fn run(args) -> Result<Report>` and a
//! `main.rs` of a few lines that calls [`main_with`]. This crate knows nothing about
//! what a stage computes.

pub mod report;
mod scene_options;

pub use scene_options::{EnvironmentArg, MediumArg, SceneOptions, SunAngle};

use anyhow::{Context, Result};
use std::io::IsTerminal;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// The exit code of a stage that stopped before its work was done but kept what
/// it did, so that the same command continues it (sysexits' EX_TEMPFAIL; a
/// progressive render stopped by its time budget).
pub const EXIT_UNFINISHED: u8 = 75;

/// The exit code of a stage, or of the runner, given a scene that needs a glTF
/// extension this renderer does not read ([`pm_scene::SceneError::Unsupported`]):
/// nothing is written, and no retry will help until the file changes.
pub const EXIT_UNSUPPORTED: u8 = 2;

/// A stage the runner ran stopped with [`EXIT_UNSUPPORTED`]: its message, so the
/// runner exits with the same code ([`exit_code`]).
#[derive(Debug)]
pub struct Unsupported(pub String);

impl std::fmt::Display for Unsupported {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Unsupported {}

/// True when the failure is (or a stage's was) a scene needing an extension
/// not read.
pub fn is_unsupported(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<Unsupported>().is_some()
            || matches!(c.downcast_ref::<pm_scene::SceneError>(), Some(pm_scene::SceneError::Unsupported { .. }))
    })
}

/// The exit code for a failure: [`EXIT_UNSUPPORTED`] for [`is_unsupported`],
/// else 1.
pub fn exit_code(e: &anyhow::Error) -> ExitCode {
    if is_unsupported(e) { ExitCode::from(EXIT_UNSUPPORTED) } else { ExitCode::FAILURE }
}

/// A stage's body stopped before its work was done and can be continued: its
/// outputs are written, and [`main_with`] prints `<stage>: unfinished: <what>`
/// and exits with [`EXIT_UNFINISHED`].
#[derive(Debug)]
pub struct Unfinished(pub String);

impl std::fmt::Display for Unfinished {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Unfinished {}

/// Run a stage's body and turn its result into the process exit: on error, print
/// `<stage>: error: <message chain>` as one line on stderr and return exit code 1
/// ([`EXIT_UNFINISHED`] for [`Unfinished`], [`EXIT_UNSUPPORTED`] for a scene
/// needing an extension not read).
pub fn main_with(stage: &str, body: impl FnOnce() -> Result<()>) -> ExitCode {
    // Built for x86-64-v3 (.cargo/config.toml): say so on a CPU without it rather
    // than die of an illegal instruction.
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    if !(std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")) {
        eprintln!(
            "{stage}: error: this build needs a CPU with AVX2 and FMA (x86-64-v3, .cargo/config.toml); on this one build with RUSTFLAGS=\"-C target-cpu=x86-64\""
        );
        return ExitCode::FAILURE;
    }
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.downcast_ref::<Unfinished>().is_some() => {
            eprintln!("{stage}: unfinished: {e}");
            ExitCode::from(EXIT_UNFINISHED)
        }
        Err(e) => {
            let msg = format!("{e:#}").replace('\n', " ");
            eprintln!("{stage}: error: {msg}");
            exit_code(&e)
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

/// Pose and light `scene` (read from `path`) as `how` says: its animation at the
/// time given, the environment (the command line's, else the one the glTF file's
/// scene extras name), sun sizes, portals and media. Every
/// error names the file at fault.
pub fn light_scene(scene: &mut pm_scene::Scene, path: &Path, how: &SceneOptions) -> Result<()> {
    how.validate(pm_params::Naming::Cli).map_err(|e| anyhow::anyhow!(e))?;
    let in_file = |e: String| anyhow::anyhow!("{}: {e}", path.display());
    if let Some(t) = how.time_s(pm_params::Naming::Cli).map_err(|e| anyhow::anyhow!(e))? {
        scene.set_time(t);
    }
    let spec = match &how.environment {
        Some(e) => Some(pm_scene::EnvironmentSpec {
            source: match e {
                EnvironmentArg::Colour(c) => pm_scene::EnvironmentSource::Colour(glam::Vec3::from_array(*c)),
                EnvironmentArg::File(f) => pm_scene::EnvironmentSource::File(f.clone()),
            },
            strength: how.environment_strength,
            rotation_deg: how.environment_rotation_deg,
        }),
        None => scene.environment_spec.clone(),
    };
    if let Some(spec) = spec {
        let env = match &spec.source {
            pm_scene::EnvironmentSource::Colour(c) => pm_scene::Environment::constant(*c * spec.strength)
                .map_err(|e| anyhow::anyhow!("{}: environment: {e}", path.display()))?,
            pm_scene::EnvironmentSource::File(f) => read_environment(f, spec.strength, spec.rotation_deg)?,
        };
        scene.set_environment(env);
    }
    scene.set_portals(&how.portal).map_err(in_file)?;
    for sun in &how.sun_angle_deg {
        if scene.set_sun_angle(sun.light.as_deref(), sun.deg) == 0 {
            let what = sun
                .light
                .as_ref()
                .map_or("no directional light".to_string(), |n| format!("no directional light '{n}'"));
            anyhow::bail!("{}: --sun-angle-deg {sun}: the scene has {what}", path.display());
        }
    }
    for m in &how.medium {
        let medium = m.medium().map_err(|e| anyhow::anyhow!("--medium {m}: {e}"))?;
        scene.set_medium(&m.name, medium).map_err(in_file)?;
    }
    // Lights and media as they now are: where each light and the camera sit.
    scene.finish_media().map_err(in_file)?;
    Ok(())
}

/// Load a scene, printing each of its warnings once on stderr.
pub fn load_scene(stage: &str, path: &Path, how: &SceneOptions) -> Result<pm_scene::Scene> {
    let mut scene = pm_scene::load_with(path, how.light_units)?;
    light_scene(&mut scene, path, how)?;
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

/// The environment light of image `path` (OpenEXR or Radiance `.hdr`,
/// equirectangular, Blender's orientation: [`pm_scene::Environment`]) times
/// `strength`, rotated by `rotation_deg` about the up axis. A missing or
/// unreadable file, or an image that is not 2:1 or holds a NaN, infinite or
/// negative value, is an error naming the file.
pub fn read_environment(path: &Path, strength: f32, rotation_deg: f32) -> Result<pm_scene::Environment> {
    let (w, h, px) = pm_image::read_radiance_image(path)?;
    pm_scene::Environment::image(w, h, px, strength, rotation_deg)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
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
/// and a finish line with the elapsed time (indicatif hides itself there). With
/// the environment variable [`PROGRESS_LINES`] set (what the Blender add-on
/// sets), also a line `progress: PROGRAM: LABEL DONE/TOTAL` on stderr at most
/// every quarter second, for a program that shows another's progress.
pub struct Progress {
    bar: indicatif::ProgressBar,
    label: String,
    start: Instant,
    terminal: bool,
    lines: Option<std::sync::Mutex<(Instant, u64)>>,
    total: u64,
}

/// The environment variable that asks every stage for progress lines
/// ([`Progress`]); the runner passes them on even when it keeps a stage quiet.
pub const PROGRESS_LINES: &str = "PHOTON_MAP_PROGRESS";

/// How a progress line starts.
pub const PROGRESS_PREFIX: &str = "progress: ";

/// This program's name, for progress lines.
fn program_name() -> String {
    std::env::args()
        .next()
        .and_then(|a| Path::new(&a).file_stem().map(|s| s.to_string_lossy().into_owned()))
        .unwrap_or_default()
}

impl Progress {
    /// Start a step of `total` units (0 for an unknown total).
    pub fn new(label: &str, total: u64) -> Progress {
        let terminal = std::io::stderr().is_terminal();
        let bar = if terminal {
            let bar = indicatif::ProgressBar::new(total);
            bar.set_style(
                indicatif::ProgressStyle::with_template("{prefix:>12} [{bar:40}] {pos}/{len} ({per_sec}, {eta}) {msg}")
                    .expect("static template")
                    .progress_chars("=> "),
            );
            bar.set_prefix(label.to_owned());
            bar
        } else {
            eprintln!("{label}: started");
            indicatif::ProgressBar::hidden()
        };
        let lines = std::env::var_os(PROGRESS_LINES).map(|_| {
            eprintln!("{PROGRESS_PREFIX}{}: {label} 0/{total}", program_name());
            std::sync::Mutex::new((Instant::now(), 0))
        });
        Progress { bar, label: label.to_owned(), start: Instant::now(), terminal, lines, total }
    }

    /// Set the number of units done.
    pub fn set(&self, done: u64) {
        self.bar.set_position(done);
        if let Some(lines) = &self.lines
            && let Ok(mut last) = lines.lock()
            && last.0.elapsed().as_secs_f64() >= 0.25
            && done != last.1
        {
            *last = (Instant::now(), done);
            eprintln!("{PROGRESS_PREFIX}{}: {} {done}/{}", program_name(), self.label, self.total);
        }
    }

    /// True when the bar is drawn (stderr is a terminal), so a message is seen.
    pub fn shown(&self) -> bool {
        self.terminal
    }

    /// Show `msg` after the bar (on a terminal; elsewhere nothing).
    pub fn message(&self, msg: &str) {
        self.bar.set_message(msg.to_owned());
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

#[cfg(test)]
mod tests {
    use super::*;

    /// An environment image reads the same from OpenEXR and from Radiance HDR
    /// (whose 8-bit mantissas round: within 1%), and a missing file, an unknown
    /// extension, garbage, a 3:1 image and a NaN texel are each a one-line error
    /// naming the file, with the problem.
    #[test]
    fn environment_images_read_or_fail_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (8usize, 4usize);
        let px: Vec<[f32; 3]> = (0..w * h).map(|i| [0.5 + i as f32, 2.0, 0.25 * (i % 3) as f32]).collect();
        let exr = dir.path().join("sky.exr");
        exr::prelude::write_rgb_file(&exr, w, h, |x, y| {
            let p = px[y * w + x];
            (p[0], p[1], p[2])
        })
        .unwrap();
        let hdr = dir.path().join("sky.hdr");
        let rgb: Vec<image::Rgb<f32>> = px.iter().map(|p| image::Rgb(*p)).collect();
        image::codecs::hdr::HdrEncoder::new(std::fs::File::create(&hdr).unwrap()).encode(&rgb, w, h).unwrap();
        let d = glam::Vec3::new(0.3, 0.2, -0.9).normalize();
        let a = read_environment(&exr, 2.0, 0.0).unwrap().radiance(d);
        let b = read_environment(&hdr, 2.0, 0.0).unwrap().radiance(d);
        assert!(((a - b).abs() / a.max(glam::Vec3::splat(0.1))).max_element() < 0.01, "{a} vs {b}");
        assert!(a.x > 1.0 && (a.y - 4.0).abs() < 1e-6, "{a}: strength 2 applied");
        let wide = dir.path().join("wide.exr");
        exr::prelude::write_rgb_file(&wide, 12, 4, |_, _| (1.0f32, 1.0f32, 1.0f32)).unwrap();
        let nan = dir.path().join("nan.exr");
        exr::prelude::write_rgb_file(&nan, 8, 4, |x, y| (if (x, y) == (3, 1) { f32::NAN } else { 1.0f32 }, 1.0, 1.0))
            .unwrap();
        let garbage = dir.path().join("garbage.hdr");
        std::fs::write(&garbage, b"not an image").unwrap();
        for (path, what) in [
            (dir.path().join("missing.exr"), "cannot read"),
            (dir.path().join("sky.png"), "unknown environment image format"),
            (garbage, "not a Radiance HDR image"),
            (wide, "twice as wide as high"),
            (nan, "texel (3, 1)"),
        ] {
            let e = format!("{:#}", read_environment(&path, 1.0, 0.0).unwrap_err());
            assert!(e.contains(&path.display().to_string()) && e.contains(what) && !e.contains('\n'), "{e}");
        }
    }
}
