//! pipeline.toml, typed.

use anyhow::{Context, Result, bail};
use pm_estimate::IrradianceParams;
use pm_params::Naming;
use pm_photon::TraceParams;
use pm_render::RenderParams;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pm_params::value_enum! {
    /// A point on the measured accuracy/time front, by the time it may take
    /// (relative to the defaults' predicted time: see [`crate::quality`]).
    pub enum Quality {
        /// A quarter of the defaults' time.
        Preview,
        /// The defaults' time.
        Balanced,
        /// Four times the defaults' time.
        Final,
    }
}

impl Quality {
    /// The time it may take as a multiple of the defaults' predicted time.
    pub fn budget_factor(self) -> f64 {
        match self {
            Quality::Preview => 0.25,
            Quality::Balanced => 1.0,
            Quality::Final => 4.0,
        }
    }
}

/// pipeline.toml, typed: each stage's section is that stage's parameter type (the
/// one definition its command line also uses). Unknown keys are errors. It writes
/// back as a pipeline file (tests and studies derive files from it by field).
#[derive(Deserialize, Serialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    /// The scene, relative to the pipeline file.
    pub scene: PathBuf,
    /// Random seed of every stage.
    #[serde(default = "one")]
    pub seed: u64,
    /// Units of the scene's point, spot and directional light intensities:
    /// "photometric" (the glTF specification: candela and lux, at 683 lm/W) or
    /// "radiometric" (W/sr and W/m^2); every stage that reads the scene gets it.
    #[serde(default)]
    pub light_units: pm_scene::LightUnits,
    /// Light from infinitely far away: an equirectangular .exr or .hdr (relative
    /// to the pipeline file; Blender's orientation) or a colour of radiance
    /// [W sr^-1 m^-2 per channel]. Wins over one the glTF file's extras name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<EnvironmentCfg>,
    /// Multiplier of the environment's radiance (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment_strength: Option<f32>,
    /// Rotation of the environment about the up axis \[degrees\] (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment_rotation_deg: Option<f32>,
    /// Angular diameter of directional lights' sun disc \[degrees\]: one number for
    /// all, or a table by light name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sun_angle_deg: Option<SunAngleCfg>,
    /// Meshes (one quad each: windows, doors) through which the environment
    /// lights an interior (portals: its photons and light samples go through
    /// them).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub portals: Vec<String>,
    /// Participating media by material name (`[media.NAME]`: inside that
    /// material's closed meshes) or filling the scene (`[media.scene]`); each wins
    /// over the glTF file's KHR_materials_volume(_scatter).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub media: BTreeMap<String, MediumCfg>,
    /// `"auto"` (the scene analysis decides) or a list of effects to simulate.
    pub effects: EffectsCfg,
    /// Light name to fraction of the photon budget; the other lights share the rest
    /// by power.
    #[serde(default)]
    pub light_shares: BTreeMap<String, f64>,
    /// Stage 1.
    #[serde(default)]
    pub trace: TraceParams,
    /// Stage 3.
    #[serde(default)]
    pub irradiance: IrradianceParams,
    /// Stage 4 (and the irradiance-cache step).
    #[serde(default)]
    pub render: RenderParams,
    /// The scene `cargo xtask live` renders, relative to the pipeline file
    /// (default: `scene`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub live_scene: Option<PathBuf>,
    /// The real-time mode (`photon-live`, `cargo xtask live`).
    #[serde(default)]
    pub live: photon_live::LiveParams,
    /// The trace, irradiance and render settings picked from the measured
    /// accuracy/time front ([`crate::quality`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<Quality>,
    /// Or a time budget \[s\] for the whole pipeline at the file's image size.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_budget_s: Option<f64>,
    /// What quality or time_budget_s chose (not a key of the file).
    #[serde(skip)]
    pub chosen: Option<String>,
}

/// A `[media.NAME]` table: a homogeneous medium in physical units.
#[derive(Deserialize, Serialize, Debug, Clone, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct MediumCfg {
    /// Absorption coefficient sigma_a [m^-1 per channel].
    #[serde(default)]
    pub sigma_a: [f32; 3],
    /// Scattering coefficient sigma_s [m^-1 per channel].
    #[serde(default)]
    pub sigma_s: [f32; 3],
    /// Henyey-Greenstein asymmetry g in (-1, 1) (0: isotropic).
    #[serde(default)]
    pub g: f32,
}

impl MediumCfg {
    /// As the stages' `--medium` option takes it.
    fn arg(&self, name: &str) -> pm_stage::MediumArg {
        pm_stage::MediumArg { name: name.to_string(), sigma_a: self.sigma_a, sigma_s: self.sigma_s, g: self.g }
    }
}

/// `environment = "sky.exr"` or `environment = [r, g, b]`.
#[derive(Deserialize, Serialize, Debug, Clone, PartialEq)]
#[serde(untagged)]
pub enum EnvironmentCfg {
    /// An image file (made absolute when the pipeline file is read).
    File(PathBuf),
    /// One colour of radiance [W sr^-1 m^-2 per channel].
    Colour([f32; 3]),
}

/// `sun_angle_deg = 0.53` (every directional light) or `sun_angle_deg = { Sun =
/// 0.53 }` (by light name).
#[derive(Deserialize, Serialize, Debug, Clone, PartialEq)]
#[serde(untagged)]
pub enum SunAngleCfg {
    /// Every directional light.
    All(f32),
    /// By light name.
    Named(BTreeMap<String, f32>),
}

/// `effects = "auto"` or a list of forced effects.
#[derive(Deserialize, Serialize, Debug, Clone)]
#[serde(untagged)]
pub enum EffectsCfg {
    /// The scene analysis decides.
    Auto(AutoWord),
    /// Simulate exactly these.
    List(Vec<EffectName>),
}

/// The word `auto`.
#[derive(Deserialize, Serialize, Debug, Clone)]
#[serde(rename_all = "lowercase")]
pub enum AutoWord {
    /// `"auto"`.
    Auto,
}

/// An effect that can be forced on.
#[derive(Deserialize, Serialize, Debug, Clone, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum EffectName {
    /// The caustic map.
    Caustics,
    /// The global map, irradiance precompute and final gathers.
    Indirect,
    /// The volume map (light scattered in participating media).
    Volume,
}

fn one() -> u64 {
    1
}

/// Set `key` of the serialisable `section` to `value` through its file form, so the
/// section's own parsing (unknown keys, types) applies.
fn set_key<T: serde::Serialize + serde::de::DeserializeOwned>(
    section: &mut T,
    key: &str,
    value: toml::Value,
) -> Result<()> {
    let mut table = toml::Table::try_from(&*section).context("the section does not serialise")?;
    table.insert(key.to_string(), value);
    *section = table.try_into().map_err(|e: toml::de::Error| anyhow::anyhow!("{}", e.message()))?;
    Ok(())
}

impl Pipeline {
    /// Read, parse and range-check a pipeline file; a quality or time budget
    /// replaces the swept settings by the chosen front point's before anything is
    /// checked. Every error is one line naming the file and the key.
    pub fn load(path: &Path) -> Result<Pipeline> {
        let file = path.display();
        let text = std::fs::read_to_string(path).with_context(|| format!("{file}: cannot read"))?;
        let mut p: Pipeline = toml::from_str(&text)
            .map_err(|e: toml::de::Error| anyhow::anyhow!("{file}: {}", e.to_string().replace('\n', " ")))?;
        if let Some(choice) = crate::quality::choose(&p, path)? {
            for (section, key, value) in choice.overrides {
                p.set(&section, &key, value.toml())
                    .with_context(|| format!("{file}: the front sets {section}.{key}"))?;
            }
            println!("{file}: {}", choice.summary);
            p.chosen = Some(choice.summary);
        }
        if let Some(EnvironmentCfg::File(f)) = &mut p.environment {
            let joined = path.parent().unwrap_or(Path::new(".")).join(&*f);
            *f = std::path::absolute(&joined).unwrap_or(joined);
        }
        let check = |key: &str, v: Option<f32>, ok: bool, range: &str| match v {
            Some(v) if !ok => bail!("{file}: {key} = {v} is out of range ({range})"),
            _ => Ok(()),
        };
        let strength = p.environment_strength;
        check("environment_strength", strength, strength.is_none_or(|v| v.is_finite() && v >= 0.0), ">= 0")?;
        let rotation = p.environment_rotation_deg;
        check("environment_rotation_deg", rotation, rotation.is_none_or(f32::is_finite), "finite")?;
        if let Some(EnvironmentCfg::Colour(c)) = &p.environment {
            pm_scene::Environment::constant(glam::Vec3::from_array(*c)).map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
        }
        for (name, deg) in p.sun_angles() {
            if !pm_scene::Scene::sun_angle_ok(deg) {
                let key = name.map_or("sun_angle_deg".to_string(), |n| format!("sun_angle_deg.{n}"));
                bail!("{file}: {key} = {deg} is out of range (0 < degrees < 180)");
            }
        }
        let fail = |e: String| anyhow::anyhow!("{file}: {e}");
        p.trace.validate(Naming::File("trace")).map_err(fail)?;
        p.irradiance.validate(Naming::File("irradiance")).map_err(fail)?;
        p.render.check(Naming::File("render")).map_err(fail)?;
        p.live.check(Naming::File("live")).map_err(fail)?;
        for (name, m) in &p.media {
            m.arg(name).medium().map_err(|e| anyhow::anyhow!("{file}: [media.{name}]: {e}"))?;
        }
        for (name, share) in &p.light_shares {
            if !(0.0..=1.0).contains(share) {
                bail!("{file}: light_shares.{name} = {share} is out of range (in [0, 1])");
            }
        }
        Ok(p)
    }

    /// Set `section.key` (a stage section: trace, irradiance, render or live).
    pub fn set(&mut self, section: &str, key: &str, value: toml::Value) -> Result<()> {
        match section {
            "trace" => set_key(&mut self.trace, key, value),
            "irradiance" => set_key(&mut self.irradiance, key, value),
            "render" => set_key(&mut self.render, key, value),
            "live" => set_key(&mut self.live, key, value),
            _ => bail!("[{section}] is not a stage section"),
        }
    }

    /// The scene of the batch pipeline: `scene` relative to the pipeline file
    /// `pipeline`'s folder.
    pub fn scene_path(&self, pipeline: &Path) -> PathBuf {
        pipeline.parent().unwrap_or(Path::new(".")).join(&self.scene)
    }

    /// The scene of the real-time mode: `live_scene` (else `scene`) relative to the
    /// pipeline file's folder.
    pub fn live_scene_path(&self, pipeline: &Path) -> PathBuf {
        pipeline.parent().unwrap_or(Path::new(".")).join(self.live_scene.as_ref().unwrap_or(&self.scene))
    }

    /// The settings as a pipeline file (what [`Self::load`] reads back equal).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a pipeline serialises")
    }

    /// photon-live's arguments for `frames` frames of `scene` into `out` with the
    /// `[live]` settings, the seed and the light units (all but `--frame-task`).
    pub fn live_args(&self, scene: &Path, out: &Path, frames: u32) -> Vec<String> {
        let mut a = vec!["--scene".to_string(), scene.display().to_string(), "--out".into(), out.display().to_string()];
        a.extend(["--frames".into(), frames.to_string(), "--seed".into(), self.seed.to_string()]);
        a.extend(self.scene_args());
        a.extend(self.live.to_args());
        a
    }

    /// The sun angles as (light name or all, degrees).
    fn sun_angles(&self) -> Vec<(Option<String>, f32)> {
        match &self.sun_angle_deg {
            None => Vec::new(),
            Some(SunAngleCfg::All(d)) => vec![(None, *d)],
            Some(SunAngleCfg::Named(m)) => m.iter().map(|(n, d)| (Some(n.clone()), *d)).collect(),
        }
    }

    /// How every program that loads the scene reads and lights it: the light
    /// units, the environment and the sun angles, as options
    /// ([`pm_stage::SceneArgs`]'s).
    pub fn scene_args(&self) -> Vec<String> {
        let mut a = vec!["--light-units".to_string(), self.light_units.to_string()];
        match &self.environment {
            Some(EnvironmentCfg::File(f)) => a.extend(["--environment".into(), f.display().to_string()]),
            Some(EnvironmentCfg::Colour([r, g, b])) => a.extend(["--environment".into(), format!("{r},{g},{b}")]),
            None => {}
        }
        if let Some(v) = self.environment_strength {
            a.extend(["--environment-strength".into(), v.to_string()]);
        }
        if let Some(v) = self.environment_rotation_deg {
            a.extend(["--environment-rotation-deg".into(), v.to_string()]);
        }
        for (name, deg) in self.sun_angles() {
            let v = name.map_or(deg.to_string(), |n| format!("{n}={deg}"));
            a.extend(["--sun-angle-deg".into(), v]);
        }
        for p in &self.portals {
            a.extend(["--portal".into(), p.clone()]);
        }
        for (name, m) in &self.media {
            a.extend(["--medium".into(), m.arg(name).to_string()]);
        }
        a
    }

    /// The environment image file, if the settings name one (an input of every
    /// step that loads the scene).
    pub fn environment_file(&self) -> Option<&Path> {
        match &self.environment {
            Some(EnvironmentCfg::File(f)) => Some(f),
            _ => None,
        }
    }
}

/// What a run works on: the settings (with the command line's overrides), the
/// scene, the output folder, the scene analysis and the effects simulated.
pub struct Setup {
    /// The settings.
    pub cfg: Pipeline,
    /// The scene file.
    pub scene: PathBuf,
    /// The output folder.
    pub out: PathBuf,
    /// What the scene analysis found.
    pub analysis: pm_light::Effects,
    /// Trace and use a caustic map.
    pub caustics: bool,
    /// Trace a global map, precompute irradiance and gather.
    pub indirect: bool,
    /// Trace a volume map (scattering media that light reaches).
    pub volume: bool,
}

impl Setup {
    /// The effects to simulate: the analysis's (`effects = "auto"`) or the list
    /// pipeline.toml forces.
    pub fn new(cfg: Pipeline, scene: PathBuf, out: PathBuf, analysis: pm_light::Effects) -> Setup {
        let (caustics, indirect, volume) = match &cfg.effects {
            EffectsCfg::Auto(_) => (analysis.caustics.yes, analysis.indirect.yes, analysis.volume.yes),
            EffectsCfg::List(l) => {
                (l.contains(&EffectName::Caustics), l.contains(&EffectName::Indirect), l.contains(&EffectName::Volume))
            }
        };
        Setup { cfg, scene, out, analysis, caustics, indirect, volume }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A key of a stage section is set through the section's own parsing: a value
    /// of the wrong type or a key the section lacks is refused, naming it.
    #[test]
    fn setting_a_key_goes_through_the_sections_parsing() {
        let mut p: Pipeline = toml::from_str("scene = \"s.gltf\"\neffects = \"auto\"").unwrap();
        p.set("render", "gather_rays", toml::Value::Integer(64)).unwrap();
        p.set("trace", "global_photons", toml::Value::Integer(1_600_000)).unwrap();
        p.set("irradiance", "fraction", toml::Value::Float(1.0)).unwrap();
        p.set("live", "subsample", toml::Value::Integer(2)).unwrap();
        assert_eq!((p.render.gather_rays, p.trace.global_photons, p.irradiance.fraction), (64, 1_600_000, 1.0));
        assert_eq!(p.live.ispm.subsample, 2);
        // Other values survive the round trip through the file form unchanged.
        assert_eq!(p.render.max_radius_rel_diag, RenderParams::default().max_radius_rel_diag);
        let e = p.set("render", "bogus", toml::Value::Integer(1)).unwrap_err().to_string();
        assert!(e.contains("bogus"), "{e}");
        let e = p.set("render", "gather_rays", toml::Value::String("many".into())).unwrap_err().to_string();
        assert!(e.contains("many") || e.contains("integer"), "{e}");
        assert!(p.set("scene", "x", toml::Value::Integer(1)).is_err());
    }

    /// The repository's pipeline.toml written back and read again gives the same
    /// settings (the tests derive their small pipelines this way).
    #[test]
    fn a_pipeline_writes_back_as_the_file_it_was_read_from() {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
        let p = Pipeline::load(&root.join("pipeline.toml")).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let copy = dir.path().join("pipeline.toml");
        std::fs::write(&copy, p.to_toml()).unwrap();
        let q = Pipeline::load(&copy).unwrap();
        assert_eq!(q.to_toml(), p.to_toml());
        assert_eq!((q.render, q.live, q.trace, q.irradiance), (p.render, p.live, p.trace, p.irradiance));
    }
}
