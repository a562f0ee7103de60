//! How a program reads its scene file and lights it, declared once
//! ([`SceneOptions`]): the options of every stage that loads a scene, the
//! top-level keys of pipeline.toml (`light_units`, `time`, `environment`, `portals`,
//! `sun_angle_deg`, `[media.NAME]`) and the arguments the runner passes on.
//! Each value is typed: it parses from its option (`FromStr`), reads from its key
//! (serde), prints back as the option (`Display`) and says what is wrong with it
//! ([`pm_params::SelfChecked`]).

use pm_params::{Any, SelfChecked, Valid, above, at_least, finite};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

pm_params::params! {
    /// How a program reads its scene file and lights it: options of every stage
    /// that loads one, pipeline.toml's top-level keys of the same names (`portals`
    /// and `[media.NAME]` for the repeatable `--portal` and `--medium`).
    pub struct SceneOptions {
        /// Units of the glTF file's point, spot and directional light intensities:
        /// photometric (the glTF specification: candela and lux, divided by 683 lm/W
        /// into W/sr and W/m^2; what Blender's exporter writes by default) or
        /// radiometric (already W/sr and W/m^2; Blender's "Unitless" export).
        /// Emissive materials are radiance either way.
        light_units: pm_scene::LightUnits = pm_scene::LightUnits::Photometric => Any;
        /// Pose the glTF file's animations at this time [s] (animations loop over
        /// their length): lights, meshes and camera where they are then; without it,
        /// the file's rest pose. Blender frame F at R fps is time F / R. The
        /// real-time methods show every frame at this time instead of frame / fps.
        #[serde(skip_serializing_if = "Option::is_none")]
        #[arg(value_name = "SECONDS")]
        time: Option<f32> => finite();
        /// Pose the animations at this frame of --fps frames a second instead of
        /// --time: time frame / fps [s], Blender's frame numbers as its glTF
        /// exporter writes them (frame F at F / fps; 0 at the file's time 0).
        /// What a job plan's frame tasks give each stage (`frames` in pipeline.toml).
        #[serde(skip_serializing_if = "Option::is_none")]
        #[arg(value_name = "N")]
        frame: Option<u32> => Any;
        /// Frames a second of --frame [1/s] (Blender's scene frame rate).
        #[serde(skip_serializing_if = "Option::is_none")]
        #[arg(value_name = "RATE")]
        fps: Option<f32> => above(0.0);
        /// Light from infinitely far away, FILE or R,G,B: an equirectangular image
        /// (.exr or Radiance .hdr, twice as wide as high, oriented as Blender's
        /// Environment Texture: the image's centre faces +X, its top row the zenith)
        /// of radiance [W sr^-1 m^-2 per channel], or one colour of radiance.
        /// Replaces an environment the glTF file's scene extras name. In
        /// pipeline.toml a file name (relative to it) or [r, g, b].
        #[serde(skip_serializing_if = "Option::is_none")]
        #[arg(value_name = "FILE|R,G,B")]
        environment: Option<EnvironmentArg> => Valid;
        /// Multiplier of the environment's radiance (of --environment's, else of
        /// the one the glTF file names).
        #[arg(value_name = "FACTOR")]
        environment_strength: f32 = 1.0 => at_least(0.0);
        /// Rotation of the environment about the up (+Y) axis [degrees] (Blender's
        /// mapping rotation about Z): 90 turns the image's centre from +X to -Z.
        #[arg(value_name = "DEG")]
        environment_rotation_deg: f32 = 0.0 => finite();
        /// Give directional lights a size, [NAME=]DEG: the angular diameter of the
        /// sun's disc [degrees, 0 < DEG < 180] (Blender's sun "angle", lost in glTF
        /// export), with the same irradiance at normal incidence: soft shadows.
        /// NAME=DEG for one light, DEG for all; repeatable. In pipeline.toml one
        /// number for all, or a table by light name.
        #[serde(with = "sun_angle_table", skip_serializing_if = "Vec::is_empty")]
        #[arg(value_name = "[NAME=]DEG")]
        sun_angle_deg: Vec<SunAngle> => Valid;
        /// A mesh (one quad: a window, a door) through which the environment lights
        /// an interior: it becomes an opening, and the environment's photons and
        /// light samples go through it instead of the whole sky (Bitterli et al.
        /// 2015). Repeatable; needs an environment. In pipeline.toml a list, portals.
        #[serde(skip_serializing_if = "Vec::is_empty")]
        #[arg(value_name = "MESH")]
        portal as "portals": Vec<String> => Any;
        /// A homogeneous participating medium, NAME:sigma_a=R,G,B:sigma_s=R,G,B:g=G,
        /// inside the closed meshes of material NAME, or filling the scene for NAME
        /// "scene" (fog, haze, water: the camera and lights are in it unless inside a
        /// mesh with a medium of its own; it fills the scene's bounding sphere).
        /// Coefficients per metre per channel, g the Henyey-Greenstein asymmetry in
        /// (-1, 1); keys left out are zero. Wins over the glTF file's
        /// KHR_materials_volume(_scatter). Repeatable. In pipeline.toml a table
        /// [media.NAME] with keys sigma_a, sigma_s and g.
        #[serde(with = "medium_table", skip_serializing_if = "Vec::is_empty")]
        #[arg(value_name = "NAME:sigma_a=R,G,B:sigma_s=R,G,B:g=G")]
        medium as "media": Vec<MediumArg> => Valid;
    }
}

impl SceneOptions {
    /// The time to pose the animations at [s]: --time, or --frame over --fps;
    /// none for the rest pose. An error, naming the options as `naming` does,
    /// when both --time and --frame are given, or --frame without --fps.
    pub fn time_s(&self, naming: pm_params::Naming) -> Result<Option<f32>, String> {
        let [time, frame, fps] = ["time", "frame", "fps"].map(|f| naming.name(f));
        match (self.time, self.frame, self.fps) {
            (Some(_), Some(_), _) => Err(format!("{time} and {frame} both pose the animation: give one")),
            (None, Some(_), None) => Err(format!("{frame} needs {fps} (the frame rate)")),
            (None, Some(f), Some(r)) => Ok(Some(f as f32 / r)),
            (t, None, _) => Ok(t),
        }
    }

    /// The environment image file, if the options name one (an input of every
    /// step that loads the scene).
    pub fn environment_file(&self) -> Option<&std::path::Path> {
        match &self.environment {
            Some(EnvironmentArg::File(f)) => Some(f),
            _ => None,
        }
    }
}

/// Three comma-separated numbers.
fn parse_colour(s: &str) -> Option<[f32; 3]> {
    let v: Vec<f32> = s.split(',').map(|x| x.trim().parse().ok()).collect::<Option<_>>()?;
    <[f32; 3]>::try_from(v).ok()
}

/// An environment as given: an image file or one colour of radiance
/// [W sr^-1 m^-2 per channel]. `environment = "sky.exr"` or `[r, g, b]` in
/// pipeline.toml; `--environment FILE` or `R,G,B`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum EnvironmentArg {
    /// An equirectangular image (made absolute when a pipeline file is read).
    File(PathBuf),
    /// One colour of radiance.
    Colour([f32; 3]),
}

impl FromStr for EnvironmentArg {
    type Err = String;

    /// Three numbers are a colour; anything else a file name.
    fn from_str(s: &str) -> Result<EnvironmentArg, String> {
        Ok(parse_colour(s).map_or_else(|| EnvironmentArg::File(s.into()), EnvironmentArg::Colour))
    }
}

impl fmt::Display for EnvironmentArg {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EnvironmentArg::File(p) => write!(f, "{}", p.display()),
            EnvironmentArg::Colour([r, g, b]) => write!(f, "{r},{g},{b}"),
        }
    }
}

impl SelfChecked for EnvironmentArg {
    /// A colour must be a radiance (finite, not negative); a file is checked when
    /// it is read.
    fn problem(&self) -> Option<String> {
        match self {
            EnvironmentArg::Colour(c) => pm_scene::Environment::constant(glam::Vec3::from_array(*c)).err(),
            EnvironmentArg::File(_) => None,
        }
    }
}

/// One sun's size: the angular diameter of directional light `light`'s disc
/// [degrees], or of every directional light's. `--sun-angle-deg [NAME=]DEG`.
#[derive(Clone, Debug, PartialEq)]
pub struct SunAngle {
    /// The light's name; every directional light when `None`.
    pub light: Option<String>,
    /// Angular diameter [degrees].
    pub deg: f32,
}

impl FromStr for SunAngle {
    type Err = String;

    fn from_str(s: &str) -> Result<SunAngle, String> {
        let (light, deg) = match s.rsplit_once('=') {
            Some((n, d)) => (Some(n.trim().to_string()), d),
            None => (None, s),
        };
        let deg = deg.trim().parse().map_err(|_| format!("'{s}' is not [NAME=]DEG"))?;
        Ok(SunAngle { light, deg })
    }
}

impl fmt::Display for SunAngle {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.light {
            Some(n) => write!(f, "{n}={}", self.deg),
            None => write!(f, "{}", self.deg),
        }
    }
}

impl SelfChecked for SunAngle {
    fn problem(&self) -> Option<String> {
        (!pm_scene::Scene::sun_angle_ok(self.deg)).then(|| "the angle must be in (0, 180) degrees".to_string())
    }
}

/// `sun_angle_deg = 0.53` (every directional light) or `sun_angle_deg = { Sun =
/// 0.53 }` (by light name).
mod sun_angle_table {
    use super::SunAngle;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use std::collections::BTreeMap;

    #[derive(Deserialize, Serialize)]
    #[serde(untagged)]
    enum Form {
        All(f32),
        Named(BTreeMap<String, f32>),
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<SunAngle>, D::Error> {
        Ok(match Form::deserialize(d)? {
            Form::All(deg) => vec![SunAngle { light: None, deg }],
            Form::Named(m) => m.into_iter().map(|(n, deg)| SunAngle { light: Some(n), deg }).collect(),
        })
    }

    pub fn serialize<S: Serializer>(v: &[SunAngle], s: S) -> Result<S::Ok, S::Error> {
        match v {
            [SunAngle { light: None, deg }] => Form::All(*deg),
            _ => Form::Named(
                v.iter()
                    .map(|a| a.light.clone().map(|n| (n, a.deg)))
                    .collect::<Option<_>>()
                    .ok_or_else(|| serde::ser::Error::custom("one sun angle for all lights, or one per named light"))?,
            ),
        }
        .serialize(s)
    }
}

/// One medium as given: a material's name (or "scene") and its coefficients.
/// `--medium NAME:sigma_a=R,G,B:sigma_s=R,G,B:g=G`, or pipeline.toml's
/// `[media.NAME]` table.
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

impl FromStr for MediumArg {
    type Err = String;

    /// NAME:key=value:... (keys sigma_a, sigma_s, g; the name is everything
    /// before the first of them, so it may hold a colon).
    fn from_str(s: &str) -> Result<MediumArg, String> {
        let bad = |why: &str| format!("'{s}': {why} (expected NAME:sigma_a=R,G,B:sigma_s=R,G,B:g=G)");
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
            let rgb = |v: &str| parse_colour(v).ok_or_else(|| bad(&format!("{k}={v} is not three numbers")));
            match k.trim() {
                "sigma_a" => m.sigma_a = rgb(v)?,
                "sigma_s" => m.sigma_s = rgb(v)?,
                "g" => m.g = v.trim().parse().map_err(|_| bad(&format!("g={v} is not a number")))?,
                other => return Err(bad(&format!("unknown key '{other}'"))),
            }
        }
        Ok(m)
    }
}

/// The `--medium` value `from_str` reads back equal.
impl fmt::Display for MediumArg {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [a, b, c] = self.sigma_a;
        let [d, e, g3] = self.sigma_s;
        write!(f, "{}:sigma_a={a},{b},{c}:sigma_s={d},{e},{g3}:g={}", self.name, self.g)
    }
}

impl MediumArg {
    /// The medium it gives (refused, naming it, when a coefficient is negative or
    /// not finite or g is outside (-1, 1)).
    pub fn medium(&self) -> Result<pm_scene::Medium, String> {
        let rgb = glam::Vec3::from_array;
        pm_scene::Medium::new(self.name.clone(), rgb(self.sigma_a), rgb(self.sigma_s), self.g)
    }
}

impl SelfChecked for MediumArg {
    fn problem(&self) -> Option<String> {
        self.medium().err()
    }
}

/// `[media.NAME]` tables: NAME to a medium's coefficients.
mod medium_table {
    use super::MediumArg;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use std::collections::BTreeMap;

    /// One `[media.NAME]` table; keys left out are zero.
    #[derive(Deserialize, Serialize, Default)]
    #[serde(deny_unknown_fields, default)]
    struct Table {
        sigma_a: [f32; 3],
        sigma_s: [f32; 3],
        g: f32,
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<MediumArg>, D::Error> {
        let m = BTreeMap::<String, Table>::deserialize(d)?;
        Ok(m.into_iter().map(|(name, t)| MediumArg { name, sigma_a: t.sigma_a, sigma_s: t.sigma_s, g: t.g }).collect())
    }

    pub fn serialize<S: Serializer>(v: &[MediumArg], s: S) -> Result<S::Ok, S::Error> {
        let m: BTreeMap<&str, Table> =
            v.iter().map(|a| (a.name.as_str(), Table { sigma_a: a.sigma_a, sigma_s: a.sigma_s, g: a.g })).collect();
        m.serialize(s)
    }
}
