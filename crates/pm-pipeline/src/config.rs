//! pipeline.toml, typed.

use anyhow::{Context, Result, bail};
use pm_estimate::IrradianceParams;
use pm_methods::live::LiveParams;
use pm_methods::{Method, Settings, SppmParams};
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
    /// What makes the image (`[render] mode` in the file).
    #[serde(skip)]
    pub mode: Method,
    /// Stage 4 (and the irradiance-cache step): the image, and the photon-map
    /// integrators' settings.
    #[serde(default)]
    pub render: RenderParams,
    /// Progressive photon mapping's own settings (mode sppm).
    #[serde(default)]
    pub sppm: SppmParams,
    /// The scene `cargo xtask live` renders, relative to the pipeline file
    /// (default: `scene`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub live_scene: Option<PathBuf>,
    /// The real-time mode (`photon-live`, `cargo xtask live`): `[live]`,
    /// `[live.vertex]`, `[live.ispm]`.
    #[serde(default)]
    pub live: LiveParams,
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

/// Keys that moved to their method's own section: (section, old key, new
/// section, new key).
const MOVED: [(&str, &str, &str, &str); 5] = [
    ("render", "passes", "sppm", "passes"),
    ("render", "photons_per_pass", "sppm", "photons_per_pass"),
    ("render", "sppm_alpha", "sppm", "alpha"),
    ("render", "sppm_radius_rel_diag", "sppm", "radius_rel_diag"),
    ("render", "sppm_boundary_probes", "sppm", "boundary_probes"),
];

/// A pipeline file's document with each value's place in the text (so that a
/// typed error shows the line at fault).
type Doc<'i> = toml::de::DeTable<'i>;

/// The table at `key` of `doc`, if it is one.
fn table_mut<'a, 'i>(doc: &'a mut Doc<'i>, key: &str) -> Option<&'a mut Doc<'i>> {
    match doc.get_mut(key).map(toml::Spanned::get_mut) {
        Some(toml::de::DeValue::Table(t)) => Some(t),
        _ => None,
    }
}

/// Move the keys of an older pipeline file to their new places: progressive
/// photon mapping's from `[render]` to `[sppm]`, the real-time methods' from
/// the flat `[live]` to `[live.vertex]` and `[live.ispm]`. Returns what moved as
/// (old, new) names; a key at both places is an error naming both.
fn move_old_keys(doc: &mut Doc<'_>) -> Result<Vec<(String, String)>> {
    let live_moves = LiveParams::moved_keys().map(|(key, part)| ("live", key, part, key));
    let moves: Vec<(&str, &str, &str, &str)> = MOVED.into_iter().chain(live_moves).collect();
    let mut moved = Vec::new();
    for (from, key, to, new_key) in moves {
        let Some((old_key, value)) = table_mut(doc, from).and_then(|t| t.remove_entry(key)) else {
            continue;
        };
        // `live.vertex` is a table inside `[live]`; `sppm` a section of its own.
        let (parent, new_section) = match from {
            "live" => (table_mut(doc, "live").expect("it held the key"), format!("live.{to}")),
            _ => (&mut *doc, to.to_string()),
        };
        let (old, new) = (format!("{from}.{key}"), format!("{new_section}.{new_key}"));
        let span = value.span();
        let empty = || toml::Spanned::new(span.clone(), toml::de::DeValue::Table(Default::default()));
        let target = match parent.entry(toml::Spanned::new(span.clone(), to.into())).or_insert_with(empty).get_mut() {
            toml::de::DeValue::Table(t) => t,
            _ => bail!("{new_section} is not a table"),
        };
        if target.contains_key(new_key) {
            bail!("{old} and {new} are the same setting: give only {new}");
        }
        target.insert(toml::Spanned::new(old_key.span(), new_key.into()), value);
        moved.push((old, new));
    }
    Ok(moved)
}

impl Pipeline {
    /// Read, parse and range-check a pipeline file; a quality or time budget
    /// replaces the swept settings by the chosen front point's before anything is
    /// checked. Every error is one line naming the file and the key.
    pub fn load(path: &Path) -> Result<Pipeline> {
        let file = path.display();
        let text = std::fs::read_to_string(path).with_context(|| format!("{file}: cannot read"))?;
        let (mut p, moved) = Pipeline::parse(&text).map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
        if !moved.is_empty() {
            eprintln!(
                "{file}: note: keys read at their new places (move them there): {}",
                moved.iter().map(|(old, new)| format!("{old} -> {new}")).collect::<Vec<_>>().join(", ")
            );
        }
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
        p.settings().check(false).map_err(fail)?;
        p.live.check(false).map_err(fail)?;
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

    /// Set `section.key` (a stage section: trace, irradiance, render, sppm or
    /// live; `live.vertex` and `live.ispm` are live's tables).
    pub fn set(&mut self, section: &str, key: &str, value: toml::Value) -> Result<()> {
        match section {
            "trace" => set_key(&mut self.trace, key, value),
            "irradiance" => set_key(&mut self.irradiance, key, value),
            "render" if key == "mode" => {
                self.mode = value.try_into().map_err(|e: toml::de::Error| anyhow::anyhow!("{}", e.message()))?;
                Ok(())
            }
            "render" => set_key(&mut self.render, key, value),
            "sppm" => set_key(&mut self.sppm, key, value),
            "live" => set_key(&mut self.live, key, value),
            "live.vertex" => set_key(&mut self.live.vertex, key, value),
            "live.ispm" => set_key(&mut self.live.ispm, key, value),
            _ => bail!("[{section}] is not a stage section"),
        }
    }

    /// Parse a pipeline file's text (no checks of ranges or files: see
    /// [`Self::load`]). Keys an older file has at their old places are read at
    /// their new ones and returned as (old, new) names; a key given at both is
    /// refused. A wrong value's error shows its line.
    pub fn parse(text: &str) -> Result<(Pipeline, Vec<(String, String)>)> {
        let one_line = |e: toml::de::Error| anyhow::anyhow!("{}", e.to_string().trim().replace('\n', " "));
        let mut doc = toml::de::DeTable::parse(text).map_err(one_line)?;
        let moved = move_old_keys(doc.get_mut())?;
        let mode = match table_mut(doc.get_mut(), "render").and_then(|r| r.remove("mode")) {
            None => Method::default(),
            Some(v) => {
                let word = v.get_ref().as_str().unwrap_or_default();
                <Method as clap::ValueEnum>::from_str(word, false).map_err(|_| {
                    let all: Vec<String> =
                        <Method as clap::ValueEnum>::value_variants().iter().map(|m| format!("\"{m}\"")).collect();
                    anyhow::anyhow!("render.mode = {}: expected one of {}", &text[v.span()], all.join(", "))
                })?
            }
        };
        let mut p = Pipeline::deserialize(toml::de::Deserializer::from(doc)).map_err(|mut e| {
            e.set_input(Some(text));
            one_line(e)
        })?;
        p.mode = mode;
        Ok((p, moved))
    }

    /// Every method's settings (`[render]` with its mode, `[sppm]`).
    pub fn settings(&self) -> Settings {
        Settings { mode: self.mode, render: self.render.clone(), sppm: self.sppm }
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
        let mut table = toml::Table::try_from(self).expect("a pipeline serialises");
        if let Some(render) = table.get_mut("render").and_then(toml::Value::as_table_mut) {
            render.insert("mode".into(), toml::Value::String(self.mode.to_string()));
        }
        toml::to_string(&table).expect("a table serialises")
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
        let (mut p, _) = Pipeline::parse("scene = \"s.gltf\"\neffects = \"auto\"").unwrap();
        p.set("render", "gather_rays", toml::Value::Integer(64)).unwrap();
        p.set("trace", "global_photons", toml::Value::Integer(1_600_000)).unwrap();
        p.set("irradiance", "fraction", toml::Value::Float(1.0)).unwrap();
        p.set("live.ispm", "subsample", toml::Value::Integer(2)).unwrap();
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

    /// An older file's keys are read at their new places (progressive photon
    /// mapping's from `[render]` to `[sppm]`, the real-time methods' from the flat
    /// `[live]` to its method tables) and named; a key at both places is refused;
    /// `[render] mode` is the method.
    #[test]
    fn old_keys_are_read_at_their_new_places() {
        let head = "scene = \"s.gltf\"\neffects = \"auto\"\n";
        let old = format!(
            "{head}[render]\nmode = \"sppm\"\npasses = 8\nsppm_alpha = 0.5\n[live]\nmethod = \"ispm\"\nwidth = 64\nper_frame = 10\nsubsample = 2"
        );
        let new = format!(
            "{head}[render]\nmode = \"sppm\"\n[sppm]\npasses = 8\nalpha = 0.5\n[live]\nmethod = \"ispm\"\nwidth = 64\n[live.vertex]\nper_frame = 10\n[live.ispm]\nsubsample = 2"
        );
        let (a, moved) = Pipeline::parse(&old).unwrap();
        let (b, none) = Pipeline::parse(&new).unwrap();
        assert_eq!(a.to_toml(), b.to_toml());
        assert!(none.is_empty(), "{none:?}");
        let names: Vec<String> = moved.iter().map(|(o, n)| format!("{o} -> {n}")).collect();
        assert_eq!(
            names,
            [
                "render.passes -> sppm.passes",
                "render.sppm_alpha -> sppm.alpha",
                "live.per_frame -> live.vertex.per_frame",
                "live.subsample -> live.ispm.subsample"
            ]
        );
        assert_eq!((b.mode, b.sppm.passes, b.sppm.sppm_alpha, b.live.vertex.per_frame), (Method::Sppm, 8, 0.5, 10));
        let both = format!("{head}[render]\npasses = 8\n[sppm]\npasses = 9");
        let e = Pipeline::parse(&both).unwrap_err().to_string();
        assert!(e.contains("render.passes and sppm.passes"), "{e}");
        let e = Pipeline::parse(&format!("{head}[render]\nmode = \"magic\"")).unwrap_err().to_string();
        assert!(e.contains("render.mode") && e.contains("magic"), "{e}");
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
        assert_eq!((q.settings(), q.live, q.trace, q.irradiance), (p.settings(), p.live, p.trace, p.irradiance));
    }
}
