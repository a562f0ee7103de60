//! What every stage binary shares, written once: the single exit path (one-line
//! error, non-zero exit code), the thread pool, progress reporting, scene loading
//! with its warnings printed once, the kd-tree check of maps read, and atomic JSON
//! output.
//!
//! Stage crates are `lib.rs` with `pub fn run(args) -> Result<Report>` and a
//! `main.rs` of a few lines that calls [`main_with`]. This crate knows nothing about
//! what a stage computes.

pub mod report;

use anyhow::{Context, Result};
use std::io::IsTerminal;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// The exit code of a stage that stopped before its work was done but kept what
/// it did, so that the same command continues it (sysexits' EX_TEMPFAIL; a
/// progressive render stopped by its time budget).
pub const EXIT_UNFINISHED: u8 = 75;

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
/// ([`EXIT_UNFINISHED`] for [`Unfinished`]).
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

/// How a stage reads its scene file and lights it: options of every stage that
/// loads one, pipeline.toml's top-level keys of the same names for the runner.
#[derive(clap::Args, Debug, Clone)]
pub struct SceneArgs {
    /// Units of the glTF file's point, spot and directional light intensities:
    /// photometric (the glTF specification: candela and lux, divided by 683 lm/W into
    /// W/sr and W/m^2; what Blender's exporter writes by default) or radiometric
    /// (already W/sr and W/m^2; Blender's "Unitless" export). Emissive materials are
    /// radiance either way.
    #[arg(long, value_enum, default_value_t = pm_scene::LightUnits::Photometric)]
    pub light_units: pm_scene::LightUnits,
    /// Light from infinitely far away: an equirectangular image (.exr or Radiance
    /// .hdr, twice as wide as high, oriented as Blender's Environment Texture: the
    /// image's centre faces +X, its top row the zenith) of radiance
    /// [W sr^-1 m^-2 per channel], or one colour R,G,B of radiance. Replaces an
    /// environment the glTF file's scene extras name.
    #[arg(long, value_name = "FILE|R,G,B")]
    pub environment: Option<String>,
    /// Multiplier of the environment's radiance.
    #[arg(long, default_value_t = 1.0, value_name = "FACTOR")]
    pub environment_strength: f32,
    /// Rotation of the environment about the up (+Y) axis [degrees] (Blender's
    /// mapping rotation about Z): 90 turns the image's centre from +X to -Z.
    #[arg(long, default_value_t = 0.0, value_name = "DEG")]
    pub environment_rotation_deg: f32,
    /// Give directional lights a size: the angular diameter of the sun's disc
    /// [degrees, 0 < DEG < 180] (Blender's sun "angle", lost in glTF export), with
    /// the same irradiance at normal incidence: soft shadows. NAME=DEG for one
    /// light, DEG for all; repeatable.
    #[arg(long, value_name = "[NAME=]DEG")]
    pub sun_angle_deg: Vec<String>,
    /// A mesh (one quad: a window, a door) through which the environment lights an
    /// interior: it becomes an opening, and the environment's photons and light
    /// samples go through it instead of the whole sky (Bitterli et al. 2015).
    /// Repeatable; needs an environment.
    #[arg(long, value_name = "MESH")]
    pub portal: Vec<String>,
    /// A homogeneous participating medium inside the closed meshes of material
    /// NAME, or filling the scene for NAME "scene" (fog, haze, water: the camera
    /// and lights are in it unless inside a mesh with a medium of its own; it fills
    /// the scene's bounding sphere). Coefficients per metre per channel, g the
    /// Henyey-Greenstein asymmetry in (-1, 1); keys left out are zero. Wins over the
    /// glTF file's KHR_materials_volume(_scatter). Repeatable.
    #[arg(long, value_name = "NAME:sigma_a=R,G,B:sigma_s=R,G,B:g=G")]
    pub medium: Vec<String>,
}

/// One `--medium` value: a material's name (or "scene") and its medium's
/// coefficients, the form pipeline.toml's `[media.NAME]` is passed on in.
#[derive(Clone, Debug, PartialEq)]
pub struct MediumArg {
    /// The material, or "scene".
    pub name: String,
    /// Absorption coefficient sigma_a [m^-1 per channel].
    pub sigma_a: [f32; 3],
    /// Scattering coefficient sigma_s [m^-1 per channel].
    pub sigma_s: [f32; 3],
    /// Henyey-Greenstein asymmetry.
    pub g: f32,
}

impl MediumArg {
    /// Parse NAME:key=value:... (keys sigma_a, sigma_s, g; the name is everything
    /// before the first of them, so it may hold a colon).
    pub fn parse(s: &str) -> Result<MediumArg> {
        let bad = |why: &str| anyhow::anyhow!("--medium {s}: {why} (expected NAME:sigma_a=R,G,B:sigma_s=R,G,B:g=G)");
        let parts: Vec<&str> = s.split(':').collect();
        let is_key = |p: &str| ["sigma_a=", "sigma_s=", "g="].iter().any(|k| p.trim_start().starts_with(k));
        let first_key = parts.iter().position(|p| is_key(p)).unwrap_or(parts.len());
        let name = parts[..first_key].join(":");
        if name.is_empty() {
            return Err(bad("no material name"));
        }
        let mut m = MediumArg { name, sigma_a: [0.0; 3], sigma_s: [0.0; 3], g: 0.0 };
        for p in &parts[first_key..] {
            let (k, v) = p.split_once('=').ok_or_else(|| bad(&format!("'{p}' is not key=value")))?;
            let rgb = |v: &str| -> Result<[f32; 3]> {
                let c = parse_colour(v).ok_or_else(|| bad(&format!("{k}={v} is not three numbers")))?;
                Ok(c.to_array())
            };
            match k.trim() {
                "sigma_a" => m.sigma_a = rgb(v)?,
                "sigma_s" => m.sigma_s = rgb(v)?,
                "g" => m.g = v.trim().parse().map_err(|_| bad(&format!("g={v} is not a number")))?,
                other => return Err(bad(&format!("unknown key '{other}'"))),
            }
        }
        Ok(m)
    }

    /// The medium it gives (refused, naming it, when a coefficient is negative or
    /// not finite or g is outside (-1, 1)).
    pub fn medium(&self) -> Result<pm_scene::Medium, String> {
        let rgb = glam::Vec3::from_array;
        pm_scene::Medium::new(self.name.clone(), rgb(self.sigma_a), rgb(self.sigma_s), self.g)
    }
}

/// The `--medium` value [`MediumArg::parse`] reads back equal.
impl std::fmt::Display for MediumArg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [a, b, c] = self.sigma_a;
        let [d, e, g3] = self.sigma_s;
        write!(f, "{}:sigma_a={a},{b},{c}:sigma_s={d},{e},{g3}:g={}", self.name, self.g)
    }
}

/// The options' defaults: the file as it is.
impl Default for SceneArgs {
    fn default() -> Self {
        SceneArgs {
            light_units: pm_scene::LightUnits::Photometric,
            environment: None,
            environment_strength: 1.0,
            environment_rotation_deg: 0.0,
            sun_angle_deg: Vec::new(),
            portal: Vec::new(),
            medium: Vec::new(),
        }
    }
}

/// One `--sun-angle-deg` value: the light's name (all directional lights when
/// none) and the angular diameter [degrees].
pub fn parse_sun_angle(s: &str) -> Result<(Option<String>, f32)> {
    let (name, deg) = match s.rsplit_once('=') {
        Some((n, d)) => (Some(n.trim().to_string()), d),
        None => (None, s),
    };
    let deg: f32 = deg.trim().parse().map_err(|_| anyhow::anyhow!("--sun-angle-deg {s}: expected [NAME=]DEG"))?;
    if !pm_scene::Scene::sun_angle_ok(deg) {
        anyhow::bail!("--sun-angle-deg {s}: the angle must be in (0, 180) degrees");
    }
    Ok((name, deg))
}

/// An `--environment` value that is a colour: three comma-separated numbers.
fn parse_colour(s: &str) -> Option<glam::Vec3> {
    let v: Vec<f32> = s.split(',').map(|x| x.trim().parse().ok()).collect::<Option<_>>()?;
    (v.len() == 3).then(|| glam::Vec3::new(v[0], v[1], v[2]))
}

/// Light `scene` (read from `path`) as `how` says: the environment (the command
/// line's, else the one the glTF file's scene extras name) and sun sizes. Every
/// error names the file at fault.
pub fn light_scene(scene: &mut pm_scene::Scene, path: &Path, how: &SceneArgs) -> Result<()> {
    let from_file = scene.environment_spec.clone();
    let spec = match &how.environment {
        Some(e) => Some(pm_scene::EnvironmentSpec {
            source: match parse_colour(e) {
                Some(c) => pm_scene::EnvironmentSource::Colour(c),
                None => pm_scene::EnvironmentSource::File(e.into()),
            },
            strength: how.environment_strength,
            rotation_deg: how.environment_rotation_deg,
        }),
        None => from_file,
    };
    if let Some(spec) = spec {
        let env = match &spec.source {
            pm_scene::EnvironmentSource::Colour(c) => pm_scene::Environment::constant(*c * spec.strength)
                .map_err(|e| anyhow::anyhow!("{}: environment: {e}", path.display()))?,
            pm_scene::EnvironmentSource::File(f) => read_environment(f, spec.strength, spec.rotation_deg)?,
        };
        scene.set_environment(env);
    }
    scene.set_portals(&how.portal).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    for s in &how.sun_angle_deg {
        let (name, deg) = parse_sun_angle(s)?;
        if scene.set_sun_angle(name.as_deref(), deg) == 0 {
            let what = name.map_or("no directional light".to_string(), |n| format!("no directional light '{n}'"));
            anyhow::bail!("{}: --sun-angle-deg {s}: the scene has {what}", path.display());
        }
    }
    for s in &how.medium {
        let m = MediumArg::parse(s)?;
        let medium = m.medium().map_err(|e| anyhow::anyhow!("--medium {s}: {e}"))?;
        scene.set_medium(&m.name, medium).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    }
    // Lights and media as they now are: where each light and the camera sit.
    scene.finish_media().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(())
}

/// Load a scene, printing each of its warnings once on stderr.
pub fn load_scene(stage: &str, path: &Path, how: &SceneArgs) -> Result<pm_scene::Scene> {
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
        Progress { bar, label: label.to_owned(), start: Instant::now(), terminal }
    }

    /// Set the number of units done.
    pub fn set(&self, done: u64) {
        self.bar.set_position(done);
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
