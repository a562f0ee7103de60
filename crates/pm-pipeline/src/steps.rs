//! Christensen's steps as values: photon-trace, photon-sort (global, caustic, volume),
//! photon-irradiance, the irradiance-cache step and photon-render, each with the
//! stage it runs, its arguments, the files it reads and writes, and the key that
//! decides whether it runs again. `cargo xtask run` executes them in one output
//! folder with fixed names (global.pmap, caustic.pmap, global.kd.pmap,
//! caustic.kd.pmap, global.irr.pmap, icache.bin, image.exr, *.stats.json); the job
//! plan ([`crate::jobs`]) cuts the trace and the render into array tasks.

use crate::Pipeline;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// Which stage a step runs, and so which statistics it writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Stage 1: the photon maps.
    Trace,
    /// Stage 2: a map into a kd-tree.
    Sort,
    /// Stage 3: irradiance at a fraction of the global map's photons.
    Irradiance,
    /// The irradiance-cache prepass (photon-render --icache-out).
    Icache,
    /// Stage 4: the image.
    Render,
}

impl Kind {
    /// The stage binary.
    pub fn program(self) -> &'static str {
        match self {
            Kind::Trace => "photon-trace",
            Kind::Sort => "photon-sort",
            Kind::Irradiance => "photon-irradiance",
            Kind::Icache | Kind::Render => "photon-render",
        }
    }
}

/// One step of the pipeline.
#[derive(Clone, Debug)]
pub struct Step {
    /// Name, unique in the pipeline (e.g. "photon-sort global").
    pub name: String,
    /// The stage it runs.
    pub kind: Kind,
    /// What it computes from: the stage's parameters and input files, without where
    /// it writes (a job plan's array task writes elsewhere).
    pub args: Vec<String>,
    /// Where it writes, as the stage's options: (`--out`, file) and the like.
    pub writes: Vec<(&'static str, PathBuf)>,
    /// Its statistics file (`--stats-json`).
    pub stats: PathBuf,
    /// Files whose contents the step's key hashes (a missing one hashes as absent).
    pub inputs: Vec<PathBuf>,
    /// Files it writes (all must exist for it to be skipped as unchanged).
    pub outputs: Vec<PathBuf>,
    /// Skip the step when this input is absent (the scene did not need it).
    pub needs: Option<PathBuf>,
    /// Pass `--flag file` only when the file exists when the step runs.
    pub optional: Vec<(&'static str, PathBuf)>,
}

impl Step {
    /// The stage binary the step runs.
    pub fn program(&self) -> &'static str {
        self.kind.program()
    }

    /// True when its stage loads the scene (and so takes the scene options:
    /// the time or frame its animation is posed at).
    pub fn loads_scene(&self) -> bool {
        self.args.iter().any(|a| a == "--scene")
    }

    /// The options that say where it writes and its statistics file.
    pub fn write_args(&self) -> Vec<String> {
        let mut a = Vec::new();
        for (flag, file) in &self.writes {
            a.extend([flag.to_string(), file.display().to_string()]);
        }
        a.extend(["--stats-json".into(), self.stats.display().to_string()]);
        a
    }

    /// Its command line (but for the optional inputs): what it computes from, where
    /// it writes, its statistics file.
    pub fn argv(&self) -> Vec<String> {
        [self.args.clone(), self.write_args()].concat()
    }
}

/// The steps of the pipeline `cfg` on `scene` into `out`, simulating caustics,
/// indirect light and light in media as told: for a method that traces its own
/// paths one render; else Christensen's stages (trace, a sort per map, the
/// irradiance precompute), the irradiance cache when the method uses one, and the
/// render.
pub fn steps(
    cfg: &Pipeline,
    scene: &Path,
    out: &Path,
    caustics: bool,
    indirect: bool,
    volume: bool,
) -> Result<Vec<Step>> {
    let mut scene_files = scene_inputs(scene)?;
    scene_files.extend(cfg.scene_options.environment_file().map(Path::to_owned));
    let run = Run { cfg, scene, out, scene_files };
    if !cfg.mode.needs().photon_maps {
        return Ok(vec![run.render_alone()]);
    }
    let mut steps = vec![run.trace(caustics, indirect, volume)];
    steps.extend(["global", "caustic", "volume"].map(|map| run.sort(map)));
    steps.push(run.irradiance());
    steps.extend(run.render(indirect));
    Ok(steps)
}

/// What every step of one run shares: the settings, the scene, the output folder
/// and the files that loading the scene reads.
struct Run<'a> {
    cfg: &'a Pipeline,
    scene: &'a Path,
    out: &'a Path,
    scene_files: Vec<PathBuf>,
}

impl Run<'_> {
    /// A file of the output folder.
    fn o(&self, f: &str) -> PathBuf {
        self.out.join(f)
    }

    /// --scene and the scene and light options every step that loads the scene gets.
    fn scene_args(&self) -> Vec<String> {
        let mut a = vec!["--scene".to_string(), self.scene.display().to_string()];
        a.extend(self.cfg.scene_options.to_args());
        a
    }

    fn seed(&self) -> [String; 2] {
        ["--seed".to_string(), self.cfg.seed.to_string()]
    }

    /// A method that traces its own paths (and photons): no maps, one step.
    fn render_alone(&self) -> Step {
        let mut args = self.scene_args();
        args.extend(self.seed());
        args.extend(self.cfg.settings().to_args());
        Step {
            name: "photon-render".into(),
            kind: Kind::Render,
            args,
            writes: vec![("--out", self.o("image.exr")), ("--png", self.o("image.png"))],
            stats: self.o("render.stats.json"),
            inputs: self.scene_files.clone(),
            outputs: vec![self.o("image.exr"), self.o("image.png"), self.o("render.stats.json")],
            needs: None,
            optional: vec![],
        }
    }

    /// Stage 1: the maps the scene calls for (a skipped effect's map is neither
    /// traced nor written).
    fn trace(&self, caustics: bool, indirect: bool, volume: bool) -> Step {
        let cfg = self.cfg;
        let mut trace = cfg.trace.clone();
        if !indirect {
            trace.global_photons = 0;
        }
        if !caustics {
            trace.caustic_photons = 0;
        }
        if !volume {
            trace.volume_photons = 0;
        }
        let mut args = self.scene_args();
        args.extend(trace.to_args());
        args.extend(self.seed());
        Step {
            name: "photon-trace".into(),
            kind: Kind::Trace,
            args,
            writes: vec![("--out", self.out.to_owned())],
            stats: self.o("trace.stats.json"),
            inputs: self.scene_files.clone(),
            outputs: [
                indirect.then(|| self.o("global.pmap")),
                caustics.then(|| self.o("caustic.pmap")),
                volume.then(|| self.o("volume.pmap")),
                Some(self.o("trace.stats.json")),
            ]
            .into_iter()
            .flatten()
            .collect(),
            needs: None,
            optional: vec![],
        }
    }

    /// Stage 2 for `map`, skipped by the runner when its map is absent.
    fn sort(&self, map: &str) -> Step {
        let (input, output, stats) = (
            self.o(&format!("{map}.pmap")),
            self.o(&format!("{map}.kd.pmap")),
            self.o(&format!("sort-{map}.stats.json")),
        );
        Step {
            name: format!("photon-sort {map}"),
            kind: Kind::Sort,
            args: vec![input.display().to_string()],
            writes: vec![("--out", output.clone())],
            stats: stats.clone(),
            inputs: vec![input.clone()],
            outputs: vec![output, stats],
            needs: Some(input),
            optional: vec![],
        }
    }

    /// Stage 3: irradiance at a subset of the global photons, with the scene (the
    /// gaps between its surfaces bound each estimate).
    fn irradiance(&self) -> Step {
        let mut args = vec![self.o("global.kd.pmap").display().to_string()];
        args.extend(self.scene_args());
        args.extend(self.cfg.irradiance.to_args());
        Step {
            name: "photon-irradiance".into(),
            kind: Kind::Irradiance,
            args,
            writes: vec![("--out", self.o("global.irr.pmap"))],
            stats: self.o("irradiance.stats.json"),
            inputs: [self.scene_files.clone(), vec![self.o("global.kd.pmap")]].concat(),
            outputs: vec![self.o("global.irr.pmap"), self.o("irradiance.stats.json")],
            needs: Some(self.o("global.kd.pmap")),
            optional: vec![],
        }
    }

    /// Stage 4 from the maps: the irradiance-cache step when the method uses a
    /// cache, then the render.
    fn render(&self, indirect: bool) -> Vec<Step> {
        let (cfg, r) = (self.cfg, &self.cfg.render);
        let o = |f: &str| self.o(f);
        let mut base = self.scene_args();
        if indirect {
            base.extend(["--global".into(), o("global.irr.pmap").display().to_string()]);
        } else {
            base.push("--no-indirect".into());
        }
        base.extend(self.seed());
        let map_inputs = [self.scene_files.clone(), vec![o("global.irr.pmap")]].concat();
        let uses_cache = indirect && r.icache_accuracy > 0.0 && cfg.mode.needs().cache;
        let mut steps = Vec::new();
        let mut render_args = base.clone();
        let mut render_inputs = [map_inputs.clone(), vec![o("caustic.kd.pmap"), o("volume.kd.pmap")]].concat();
        if uses_cache {
            // The cache step gets only what shapes the cache (the rest at defaults),
            // so changing the rest re-runs only the render.
            let mut a = base;
            a.extend(r.cache_settings().render_params().to_args());
            steps.push(Step {
                name: "photon-render icache".into(),
                kind: Kind::Icache,
                args: a,
                writes: vec![("--icache-out", o("icache.bin"))],
                stats: o("icache.stats.json"),
                inputs: [map_inputs.clone(), vec![o("volume.kd.pmap")]].concat(),
                outputs: vec![o("icache.bin"), o("icache.stats.json")],
                needs: Some(o("global.irr.pmap")),
                // Gather rays through a medium read the light it scatters.
                optional: vec![("--volume", o("volume.kd.pmap"))],
            });
            render_args.extend(["--icache".into(), o("icache.bin").display().to_string()]);
            render_inputs.push(o("icache.bin"));
        }
        render_args.extend(cfg.settings().to_args());
        steps.push(Step {
            name: "photon-render".into(),
            kind: Kind::Render,
            args: render_args,
            writes: vec![("--out", o("image.exr")), ("--png", o("image.png"))],
            stats: o("render.stats.json"),
            inputs: render_inputs,
            outputs: vec![o("image.exr"), o("image.png"), o("render.stats.json")],
            needs: None,
            optional: vec![("--caustic", o("caustic.kd.pmap")), ("--volume", o("volume.kd.pmap"))],
        });
        steps
    }
}

/// blake3 over the program (its name and the binary's contents: a rebuilt stage
/// runs again), its arguments and the contents of its input files.
pub fn step_key(program: &Path, args: &[String], inputs: &[PathBuf]) -> String {
    let mut h = blake3::Hasher::new();
    h.update(program.file_name().unwrap_or_default().as_encoded_bytes());
    match std::fs::read(program) {
        Ok(bytes) => h.update(blake3::hash(&bytes).as_bytes()),
        Err(_) => h.update(b"absent"),
    };
    for a in args {
        h.update(a.as_bytes());
        h.update(&[0]);
    }
    for f in inputs {
        match std::fs::read(f) {
            Ok(bytes) => h.update(blake3::hash(&bytes).as_bytes()),
            Err(_) => h.update(b"absent"),
        };
    }
    h.finalize().to_hex().to_string()
}

/// The scene file and the external buffers and images a .gltf references, and
/// the environment image its scenes' extras name.
pub fn scene_inputs(scene: &Path) -> Result<Vec<PathBuf>> {
    let mut files = vec![scene.to_owned()];
    let bytes = std::fs::read(scene).with_context(|| format!("{}: cannot read", scene.display()))?;
    if let Ok(doc) = serde_json::from_slice::<serde_json::Value>(&bytes) {
        let dir = scene.parent().unwrap_or(Path::new("."));
        for key in ["buffers", "images"] {
            for item in doc[key].as_array().into_iter().flatten() {
                if let Some(uri) = item["uri"].as_str().filter(|u| !u.starts_with("data:")) {
                    files.push(dir.join(uri));
                }
            }
        }
        for scene in doc["scenes"].as_array().into_iter().flatten() {
            if let Some(f) = scene["extras"]["environment"]["file"].as_str() {
                files.push(dir.join(f));
            }
        }
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The key changes when the binary is rebuilt, an argument changes or an
    /// input changed; not when nothing did.
    #[test]
    fn a_step_key_covers_the_binary_the_arguments_and_the_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let (bin, input) = (dir.path().join("photon-render"), dir.path().join("map.pmap"));
        std::fs::write(&bin, b"build 1").unwrap();
        std::fs::write(&input, b"photons").unwrap();
        let args = vec!["--k".to_string(), "50".to_string()];
        let key = || step_key(&bin, &args, std::slice::from_ref(&input));
        let first = key();
        assert_eq!(key(), first);
        std::fs::write(&bin, b"build 2").unwrap();
        let rebuilt = key();
        assert_ne!(rebuilt, first, "a rebuilt binary");
        std::fs::write(&input, b"other photons").unwrap();
        assert_ne!(key(), rebuilt, "a changed input");
        assert_ne!(
            step_key(&bin, &["--k".into(), "60".into()], std::slice::from_ref(&input)),
            key(),
            "other arguments"
        );
    }
}
