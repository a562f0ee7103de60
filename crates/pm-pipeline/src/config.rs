//! pipeline.toml, typed.

use anyhow::{Context, Result, bail};
use pm_estimate::IrradianceParams;
use pm_methods::live::LiveParams;
use pm_methods::{BdptParams, Method, Settings, SppmParams, VcmParams};
use pm_params::Naming;
use pm_photon::TraceParams;
use pm_render::RenderParams;
use serde::{Deserialize, Serialize};
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
    /// How every program that loads the scene reads and lights it: the top-level
    /// keys light_units, environment, environment_strength,
    /// environment_rotation_deg, sun_angle_deg, portals and the `[media.NAME]`
    /// tables (moved here from the top level when the file is read).
    #[serde(default)]
    pub scene_options: pm_stage::SceneOptions,
    /// An animation's frames to render, first and last (inclusive; Blender's
    /// frame numbers at `fps` frames a second, frame F at time F / fps): one
    /// output folder per frame (`frame-F/`, photon maps traced per frame), one
    /// array task per frame in the job plan. None: one image (at `time`, `frame`
    /// or the rest pose).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<[u32; 2]>,
    /// `"auto"` (the scene analysis decides; the default) or a list of effects
    /// to simulate.
    #[serde(default = "auto")]
    pub effects: EffectsCfg,
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
    /// Bidirectional path tracing's own settings (mode bdpt).
    #[serde(default)]
    pub bdpt: BdptParams,
    /// Vertex connection and merging's own settings (mode vcm).
    #[serde(default)]
    pub vcm: VcmParams,
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

fn auto() -> EffectsCfg {
    EffectsCfg::Auto(AutoWord::Auto)
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
const MOVED: [(&str, &str, &str, &str); 6] = [
    ("", "light_shares", "trace", "light_shares"),
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
/// the flat `[live]` to `[live.vertex]` and `[live.ispm]`, the light shares into
/// `[trace]`. Returns what moved as (old, new) names; a key at both places is an
/// error naming both.
fn move_old_keys(doc: &mut Doc<'_>) -> Result<Vec<(String, String)>> {
    let live_moves = LiveParams::moved_keys().map(|(key, part)| ("live", key, part, key));
    let moves: Vec<(&str, &str, &str, &str)> = MOVED.into_iter().chain(live_moves).collect();
    let mut moved = Vec::new();
    for (from, key, to, new_key) in moves {
        // `live.vertex` is a table inside `[live]`; `sppm` a section of its own.
        let to = if from == "live" { format!("live.{to}") } else { to.to_string() };
        let name =
            |section: &str, key: &str| if section.is_empty() { key.to_string() } else { format!("{section}.{key}") };
        let (old, new) = (name(from, key), name(&to, new_key));
        if move_key(doc, (from, key), (&to, new_key))
            .map_err(|()| anyhow::anyhow!("{old} and {new} are the same setting: give only {new}"))?
        {
            moved.push((old, new));
        }
    }
    Ok(moved)
}

/// Move `from`'s `key` (`from` a section, or "" for the top level) to `to`'s
/// `new_key` (`to` a dotted path of tables, made when missing), keeping the
/// value's place in the text. False when there was no such key; `Err` when the
/// new place already holds one (or is not a table).
fn move_key(doc: &mut Doc<'_>, (from, key): (&str, &str), (to, new_key): (&str, &str)) -> Result<bool, ()> {
    let source = if from.is_empty() { Some(&mut *doc) } else { table_mut(doc, from) };
    let Some((old_key, value)) = source.and_then(|t| t.remove_entry(key)) else {
        return Ok(false);
    };
    let span = value.span();
    let mut target = doc;
    for part in to.split('.') {
        let empty = || toml::Spanned::new(span.clone(), toml::de::DeValue::Table(Default::default()));
        target = match target
            .entry(toml::Spanned::new(span.clone(), part.to_string().into()))
            .or_insert_with(empty)
            .get_mut()
        {
            toml::de::DeValue::Table(t) => t,
            _ => return Err(()),
        };
    }
    if target.contains_key(new_key) {
        return Err(());
    }
    target.insert(toml::Spanned::new(old_key.span(), new_key.to_string().into()), value);
    Ok(true)
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
        if let Some(pm_stage::EnvironmentArg::File(f)) = &mut p.scene_options.environment {
            let joined = path.parent().unwrap_or(Path::new(".")).join(&*f);
            *f = std::path::absolute(&joined).unwrap_or(joined);
        }
        let fail = |e: String| anyhow::anyhow!("{file}: {e}");
        p.scene_options.validate(Naming::File("")).map_err(fail)?;
        p.scene_options.time_s(Naming::File("")).map_err(fail)?;
        if let Some([first, last]) = p.frames {
            if first > last {
                return Err(fail(format!("frames = [{first}, {last}]: the first frame is after the last")));
            }
            if p.scene_options.fps.is_none() {
                return Err(fail("frames needs fps (frames a second, the scene's frame rate)".into()));
            }
            if p.scene_options.time.is_some() || p.scene_options.frame.is_some() {
                return Err(fail("frames renders an animation: leave out time and frame".into()));
            }
        }
        p.trace.validate(Naming::File("trace")).map_err(fail)?;
        p.irradiance.validate(Naming::File("irradiance")).map_err(fail)?;
        p.settings().check(false).map_err(fail)?;
        p.live.check(false).map_err(fail)?;
        Ok(p)
    }

    /// Set `section.key` (a stage section: trace, irradiance, render, sppm, bdpt,
    /// vcm or live; `live.vertex` and `live.ispm` are live's tables).
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
            "bdpt" => set_key(&mut self.bdpt, key, value),
            "vcm" => set_key(&mut self.vcm, key, value),
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
        if doc.get_ref().contains_key("scene_options") {
            bail!("scene_options is not a key: its keys (light_units, environment, portals, ...) go at the top level");
        }
        for key in pm_stage::SceneOptions::FIELDS {
            move_key(doc.get_mut(), ("", key), ("scene_options", key)).expect("scene_options is a new table");
        }
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

    /// Every method's settings (`[render]` with its mode, `[sppm]`, `[bdpt]`,
    /// `[vcm]`).
    pub fn settings(&self) -> Settings {
        Settings { mode: self.mode, render: self.render.clone(), sppm: self.sppm, bdpt: self.bdpt, vcm: self.vcm }
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
        // The scene options are keys of the top level.
        if let Some(toml::Value::Table(options)) = table.remove("scene_options") {
            table.extend(options);
        }
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
        a.extend(self.scene_options.to_args());
        a.extend(self.live.to_args());
        a
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

/// The words of a choice with their documentation, for a user interface.
fn words<T: clap::ValueEnum>() -> Vec<serde_json::Value> {
    T::value_variants()
        .iter()
        .filter_map(T::to_possible_value)
        .map(|v| serde_json::json!({"name": v.get_name(), "help": v.get_help().map(ToString::to_string)}))
        .collect()
}

/// pipeline.toml's parameters as a user interface reads them, from their one
/// definition: each section's [`pm_params::Param`]s (the top level's scene
/// options under `""`), the render methods (`[render] mode`) and the quality
/// words, each with its documentation. What `cargo xtask schema` prints and the
/// Blender add-on's settings are made from.
pub fn schema() -> serde_json::Value {
    serde_json::json!({
        "sections": {
            "": pm_stage::SceneOptions::schema(),
            "trace": TraceParams::schema(),
            "irradiance": IrradianceParams::schema(),
            "render": RenderParams::schema(),
            "sppm": SppmParams::schema(),
            "bdpt": BdptParams::schema(),
            "vcm": VcmParams::schema(),
        },
        "modes": words::<Method>(),
        "qualities": words::<Quality>(),
    })
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

    /// The scene options are top-level keys of the file, typed by the one
    /// definition the stages' options use ([`pm_stage::SceneOptions`]): what the
    /// file says is what the runner passes, and it writes back as top-level keys.
    /// An older file's top-level `[light_shares]` is read as `[trace.light_shares]`.
    #[test]
    fn scene_options_are_top_level_keys_passed_on_as_the_stages_options() {
        let text = "scene = \"s.gltf\"\neffects = \"auto\"\nlight_units = \"radiometric\"\n\
            environment = [0.1, 0.2, 0.3]\nenvironment_strength = 2\nportals = [\"window\"]\n\
            sun_angle_deg = { Sun = 0.5 }\n[media.fog]\nsigma_s = [0.3, 0.3, 0.3]\ng = 0.2\n\
            [light_shares]\nLamp = 0.25\n";
        let (p, moved) = Pipeline::parse(text).unwrap();
        assert_eq!(moved, [("light_shares".to_string(), "trace.light_shares".to_string())]);
        let o = &p.scene_options;
        assert_eq!(o.light_units, pm_scene::LightUnits::Radiometric);
        assert_eq!(o.environment, Some(pm_stage::EnvironmentArg::Colour([0.1, 0.2, 0.3])));
        assert_eq!((o.environment_strength, o.environment_rotation_deg), (2.0, 0.0));
        assert_eq!(o.sun_angle_deg, [pm_stage::SunAngle { light: Some("Sun".into()), deg: 0.5 }]);
        let fog = pm_stage::MediumArg { name: "fog".into(), sigma_a: [0.0; 3], sigma_s: [0.3; 3], g: 0.2 };
        assert_eq!((o.portal.as_slice(), o.medium.as_slice()), (["window".to_string()].as_slice(), [fog].as_slice()));
        assert_eq!(p.trace.light_shares(), [("Lamp".to_string(), 0.25)]);
        let args = o.to_args().join(" ");
        assert_eq!(
            args,
            "--light-units radiometric --environment 0.1,0.2,0.3 --environment-strength 2 \
             --environment-rotation-deg 0 --sun-angle-deg Sun=0.5 --portal window \
             --medium fog:sigma_a=0,0,0:sigma_s=0.3,0.3,0.3:g=0.2"
        );
        assert!(p.trace.to_args().join(" ").ends_with("--light-share Lamp=0.25"));
        let written = p.to_toml();
        assert!(!written.contains("scene_options") && written.contains("\nportals = "), "{written}");
        let (q, none) = Pipeline::parse(&written).unwrap();
        assert!(none.is_empty());
        assert_eq!((&q.scene_options, &q.trace), (&p.scene_options, &p.trace));
        // The table is not a key of its own; a wrong value names its line.
        let e = Pipeline::parse("scene = \"s.gltf\"\neffects = \"auto\"\n[scene_options]\nportals = []").unwrap_err();
        assert!(e.to_string().contains("scene_options is not a key"), "{e}");
        let e = Pipeline::parse("scene = \"s.gltf\"\neffects = \"auto\"\nenvironment_strength = \"x\"").unwrap_err();
        assert!(e.to_string().contains("line 3"), "{e}");
    }
}
