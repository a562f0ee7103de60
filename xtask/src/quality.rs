//! What accuracy costs, as a knob: `quality = "preview" | "balanced" | "final"` or
//! `time_budget_s = N` in pipeline.toml picks the setting on the Pareto front that
//! `cargo xtask tradeoff` measured for the scene's class (its file name; the
//! front of cornell_spheres when the class was never measured): the lowest error
//! whose predicted time fits. The front records the study's image size and
//! machine; a point's time is predicted for the pipeline's image size as its photon
//! stages' time plus its render time scaled by the pixel count (pessimistic: for
//! the default 1024 x 1024 run it predicts 32 s against 10.7 s measured, the cache
//! prepass and per-process costs growing less than the pixels). preview, balanced
//! and final are a quarter of, equal to and four times the defaults' predicted
//! time. The chosen point's parameters replace pipeline.toml's before it is read,
//! so every check of the file applies to them.

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A measured front, as `cargo xtask tradeoff` writes it (front.json).
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct Front {
    /// The scene it was measured on.
    pub scene: String,
    /// Width and height of the study's images \[pixels\].
    pub size: u32,
    /// Where it was measured.
    pub machine: String,
    /// The defaults' stage times \[s\]: trace, sort, precompute, render.
    pub defaults_s: [f64; 4],
    /// The Pareto front, fastest first.
    pub points: Vec<Point>,
}

/// One point of the front.
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct Point {
    /// The setting, e.g. "gather rays 64".
    pub label: String,
    /// Stage times \[s\]: trace, sort, precompute, render.
    pub times_s: [f64; 4],
    /// Expected error of one render (relative), and its bias and noise.
    pub error: f64,
    /// Bias (relative RMS).
    pub bias: f64,
    /// Noise of one render (relative RMS).
    pub noise: f64,
    /// The pipeline.toml values that differ from the defaults: section, key, value.
    pub overrides: Vec<(String, String, Value)>,
}

/// A pipeline.toml value.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(untagged)]
pub enum Value {
    /// An integer.
    Int(i64),
    /// A number with a fraction.
    Float(f64),
    /// true or false.
    Bool(bool),
    /// A word (an enumeration's value).
    Text(String),
}

impl Value {
    /// A value from its command-line text, typed like the default's text (so that
    /// a fraction of 1 stays a float).
    pub fn parse(text: &str, default: &str) -> Value {
        let float_default = default.contains('.') || default.contains('e') || default == "inf";
        if let Ok(b) = text.parse::<bool>() {
            Value::Bool(b)
        } else if !float_default && let Ok(i) = text.parse::<i64>() {
            Value::Int(i)
        } else if let Ok(f) = text.parse::<f64>() {
            Value::Float(f)
        } else {
            Value::Text(text.to_string())
        }
    }

    fn toml(&self) -> toml::Value {
        match self {
            Value::Int(i) => toml::Value::Integer(*i),
            Value::Float(f) => toml::Value::Float(*f),
            Value::Bool(b) => toml::Value::Boolean(*b),
            Value::Text(t) => toml::Value::String(t.clone()),
        }
    }
}

/// The front a pipeline file's scene class uses: DIR/docs/tradeoff/CLASS/front.json
/// beside the pipeline file or in the repository, CLASS the scene's file name, else
/// cornell_spheres's.
pub fn front_path(pipeline: &Path, scene: &str) -> Option<PathBuf> {
    let class = Path::new(scene).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let dirs = [pipeline.parent().unwrap_or(Path::new(".")).to_path_buf(), repo];
    [class.as_str(), "cornell_spheres"]
        .iter()
        .flat_map(|c| dirs.iter().map(move |d| d.join("docs/tradeoff").join(c).join("front.json")))
        .find(|p| p.exists())
}

/// Predicted time of stage times `t` (measured at `size` x `size`) for an image of
/// `pixels` pixels [s].
fn predict(t: &[f64; 4], size: u32, pixels: f64) -> f64 {
    t[0] + t[1] + t[2] + t[3] * pixels / (size as f64 * size as f64).max(1.0)
}

/// If `doc` (a parsed pipeline.toml at `path`) asks for a quality or a time budget,
/// apply the chosen point's values to it and say what was chosen.
pub fn apply(doc: &mut toml::Value, path: &Path) -> Result<Option<String>> {
    let quality = doc.get("quality").cloned();
    let budget = doc.get("time_budget_s").cloned();
    if quality.is_none() && budget.is_none() {
        return Ok(None);
    }
    let file = path.display();
    if quality.is_some() && budget.is_some() {
        bail!("{file}: give quality or time_budget_s, not both");
    }
    let scene = doc.get("scene").and_then(toml::Value::as_str).unwrap_or_default().to_string();
    let front_file = front_path(path, &scene).with_context(|| {
        format!(
            "{file}: quality needs a measured front (docs/tradeoff/<scene>/front.json; run cargo xtask tradeoff --docs)"
        )
    })?;
    let front: Front = serde_json::from_str(
        &std::fs::read_to_string(&front_file).with_context(|| format!("{}: cannot read", front_file.display()))?,
    )
    .with_context(|| format!("{}: not a front", front_file.display()))?;
    let int = |k: &str| doc.get("render").and_then(|r| r.get(k)).and_then(toml::Value::as_integer);
    let pixels = (int("width").unwrap_or(1024) * int("height").unwrap_or(1024)) as f64;
    let defaults = predict(&front.defaults_s, front.size, pixels);
    let (budget, what) = match (&quality, &budget) {
        (Some(q), _) => match q.as_str() {
            Some("preview") => (0.25 * defaults, "preview"),
            Some("balanced") => (defaults, "balanced"),
            Some("final") => (4.0 * defaults, "final"),
            _ => bail!("{file}: quality = {q}: expected \"preview\", \"balanced\" or \"final\""),
        },
        (None, Some(b)) => match b.as_float().or_else(|| b.as_integer().map(|i| i as f64)) {
            Some(s) if s > 0.0 && s.is_finite() => (s, "time budget"),
            _ => bail!("{file}: time_budget_s = {b}: expected a positive number of seconds"),
        },
        (None, None) => unreachable!("one of them is set"),
    };
    let fits = front.points.iter().filter(|p| predict(&p.times_s, front.size, pixels) <= budget);
    let (point, note) = match fits.min_by(|a, b| a.error.total_cmp(&b.error)) {
        Some(p) => (p, ""),
        None => (front.points.first().context("the front has no points")?, " (nothing fits: the fastest point)"),
    };
    let table = doc.as_table_mut().context("pipeline.toml is not a table")?;
    for (section, key, value) in &point.overrides {
        let sec = table.entry(section.clone()).or_insert_with(|| toml::Value::Table(Default::default()));
        sec.as_table_mut()
            .with_context(|| format!("{file}: [{section}] is not a table"))?
            .insert(key.clone(), value.toml());
    }
    Ok(Some(format!(
        "{what} ({budget:.1} s): \"{}\"{note} from {} (measured at {}x{} on {}): predicted {:.1} s, error {:.1}% (bias {:.1}%, noise {:.1}%)",
        point.label,
        front_file.display(),
        front.size,
        front.size,
        front.machine,
        predict(&point.times_s, front.size, pixels),
        100.0 * point.error,
        100.0 * point.bias,
        100.0 * point.noise
    )))
}
