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
//! time. The chosen point's parameters replace the parsed file's (each through its
//! section's own parsing) before the file's values are checked, so every check
//! applies to them.

use crate::Pipeline;
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
    /// The defaults' stage times.
    pub defaults_s: StageTimes,
    /// The Pareto front, fastest first.
    pub points: Vec<Point>,
}

/// One point of the front.
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct Point {
    /// The setting, e.g. "gather rays 64".
    pub label: String,
    /// Its stage times.
    pub times_s: StageTimes,
    /// Expected error of one render (relative), and its bias and noise.
    pub error: f64,
    /// Bias (relative RMS).
    pub bias: f64,
    /// Noise of one render (relative RMS).
    pub noise: f64,
    /// The pipeline.toml values that differ from the defaults: section, key, value.
    pub overrides: Vec<(String, String, Value)>,
}

/// Wall time of each batch stage \[s\] (a real-time or peer row counts its frame or
/// render time as `render`). Written in front.json as the array [trace, sort,
/// precompute, render].
#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq)]
#[serde(from = "[f64; 4]", into = "[f64; 4]")]
pub struct StageTimes {
    /// photon-trace \[s\].
    pub trace: f64,
    /// photon-sort, every map \[s\].
    pub sort: f64,
    /// photon-irradiance \[s\].
    pub irradiance: f64,
    /// photon-render \[s\].
    pub render: f64,
}

impl StageTimes {
    /// The whole pipeline \[s\].
    pub fn total(&self) -> f64 {
        self.trace + self.sort + self.irradiance + self.render
    }

    /// Predicted time for an image of `pixels` pixels when these were measured at
    /// `size` x `size` \[s\]: the photon stages as they are, the render scaled by
    /// the pixel count.
    pub fn predict(&self, size: u32, pixels: f64) -> f64 {
        self.trace + self.sort + self.irradiance + self.render * pixels / (size as f64 * size as f64).max(1.0)
    }
}

impl From<[f64; 4]> for StageTimes {
    fn from([trace, sort, irradiance, render]: [f64; 4]) -> Self {
        StageTimes { trace, sort, irradiance, render }
    }
}

impl From<StageTimes> for [f64; 4] {
    fn from(t: StageTimes) -> Self {
        [t.trace, t.sort, t.irradiance, t.render]
    }
}

/// The Pareto front of `items`: those no faster item beats in error, fastest
/// first (an item of infinite error is never on it). The one rule the trade-off
/// study draws and writes front.json with.
pub fn pareto<T>(items: &[T], time: impl Fn(&T) -> f64, error: impl Fn(&T) -> f64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by(|&a, &b| time(&items[a]).total_cmp(&time(&items[b])));
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in order {
        if error(&items[i]) < best {
            best = error(&items[i]);
            front.push(i);
        }
    }
    front
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

    /// The value as pipeline.toml writes it.
    pub fn toml(&self) -> toml::Value {
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
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dirs = [pipeline.parent().unwrap_or(Path::new(".")).to_path_buf(), repo];
    [class.as_str(), "cornell_spheres"]
        .iter()
        .flat_map(|c| dirs.iter().map(move |d| d.join("docs/tradeoff").join(c).join("front.json")))
        .find(|p| p.exists())
}

/// The front point a pipeline file asked for.
pub struct Choice {
    /// Its values that differ from the defaults: section, key, value.
    pub overrides: Vec<(String, String, Value)>,
    /// What was chosen, from which front, predicted time and error.
    pub summary: String,
}

/// The front point `cfg` (read from the pipeline file at `path`) asks for with its
/// quality or time budget; none when it asks for neither.
pub fn choose(cfg: &Pipeline, path: &Path) -> Result<Option<Choice>> {
    let file = path.display();
    let what = match (cfg.quality, cfg.time_budget_s) {
        (None, None) => return Ok(None),
        (Some(_), Some(_)) => bail!("{file}: give quality or time_budget_s, not both"),
        (Some(q), None) => Budget::Relative(q),
        (None, Some(s)) if s > 0.0 && s.is_finite() => Budget::Seconds(s),
        (None, Some(s)) => bail!("{file}: time_budget_s = {s}: expected a positive number of seconds"),
    };
    let scene = cfg.scene.display().to_string();
    let front_file = front_path(path, &scene).with_context(|| {
        format!(
            "{file}: quality needs a measured front (docs/tradeoff/<scene>/front.json; run cargo xtask tradeoff --docs)"
        )
    })?;
    let front: Front = serde_json::from_str(
        &std::fs::read_to_string(&front_file).with_context(|| format!("{}: cannot read", front_file.display()))?,
    )
    .with_context(|| format!("{}: not a front", front_file.display()))?;
    let pixels = cfg.render.width as f64 * cfg.render.height as f64;
    let defaults = front.defaults_s.predict(front.size, pixels);
    let (budget, what) = match what {
        Budget::Relative(q) => (q.budget_factor() * defaults, q.to_string()),
        Budget::Seconds(s) => (s, "time budget".to_string()),
    };
    let fits = front.points.iter().filter(|p| p.times_s.predict(front.size, pixels) <= budget);
    let (point, note) = match fits.min_by(|a, b| a.error.total_cmp(&b.error)) {
        Some(p) => (p, ""),
        None => (front.points.first().context("the front has no points")?, " (nothing fits: the fastest point)"),
    };
    let summary = format!(
        "{what} ({budget:.1} s): \"{}\"{note} from {} (measured at {}x{} on {}): predicted {:.1} s, error {:.1}% (bias {:.1}%, noise {:.1}%)",
        point.label,
        front_file.display(),
        front.size,
        front.size,
        front.machine,
        point.times_s.predict(front.size, pixels),
        100.0 * point.error,
        100.0 * point.bias,
        100.0 * point.noise
    );
    Ok(Some(Choice { overrides: point.overrides.clone(), summary }))
}

/// What a pipeline file asks the front for.
enum Budget {
    /// A multiple of the defaults' predicted time.
    Relative(crate::Quality),
    /// Seconds.
    Seconds(f64),
}

#[cfg(test)]
mod tests {
    use super::*;

    /// front.json keeps its stage times as [trace, sort, precompute, render]: the
    /// fronts in docs/ were written that way and still read.
    #[test]
    fn stage_times_are_an_array_in_the_file() {
        let t = StageTimes { trace: 1.0, sort: 2.0, irradiance: 3.0, render: 4.0 };
        assert_eq!(serde_json::to_string(&t).unwrap(), "[1.0,2.0,3.0,4.0]");
        assert_eq!(serde_json::from_str::<StageTimes>("[1.0,2.0,3.0,4.0]").unwrap(), t);
        assert_eq!(t.total(), 10.0);
        // A 64 x 64 study predicts a 128 x 128 render four times as long.
        assert_eq!(t.predict(64, 128.0 * 128.0), 1.0 + 2.0 + 3.0 + 16.0);
    }

    /// The front: each point faster than the next and more accurate than every
    /// faster point; infinite errors never on it.
    #[test]
    fn pareto_keeps_what_no_faster_point_beats() {
        // (time, error)
        let pts = [(3.0, 0.1), (1.0, 0.5), (2.0, 0.6), (4.0, 0.2), (0.5, f64::INFINITY), (5.0, 0.05)];
        assert_eq!(pareto(&pts, |p| p.0, |p| p.1), [1, 0, 5]);
        assert!(pareto(&pts[4..5], |p| p.0, |p| p.1).is_empty());
    }
}
