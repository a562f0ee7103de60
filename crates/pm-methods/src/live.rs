//! The real-time methods by name, and their settings: what `photon-live
//! --method` chooses among and pipeline.toml's `[live]` section (`method` and
//! the frame settings both methods share), `[live.vertex]` and `[live.ispm]`
//! (each method's own, declared in its crate).

use pm_ispm::IspmParams;
use pm_live::{FrameParams, FrameRow};
use pm_params::Naming;
use pm_vertex::VertexParams;

pm_params::value_enum! {
    /// Which real-time method draws the frames.
    pub enum LiveMethod {
        /// Jozwowski 2002: a ring buffer of photon paths, estimates at mesh vertices.
        Vertex,
        /// McGuire and Luebke 2009: bounce maps and photon volumes splatted over the
        /// eye's G-buffer.
        Ispm,
    }
}

impl LiveMethod {
    /// How closely a still scene's settled frame ([`LiveParams::settled_frames`])
    /// agrees with the path tracer on defaults (the one statement of it; `cargo
    /// xtask differential` judges by it), the light's pixels left out: the image's
    /// mean and every 8 x 8 block's, each within 10% and 40% (the checker allows
    /// the frame's own noise on top, from two seeds, and compares with a
    /// reference sampled at the pixels' centres as the frames are). Looser than
    /// the batch methods' bound: both estimate indirect light from a few thousand
    /// photons a frame (the vertex method's at mesh corners, interpolated). In
    /// media both add the beam estimate of their photons' scattering events to
    /// the single scattering the eye takes from the lights.
    pub fn agreement(self) -> crate::Agreement {
        match self {
            LiveMethod::Vertex => crate::Agreement { mean: VERTEX_MEAN, worst_block: VERTEX_BLOCK },
            LiveMethod::Ispm => crate::Agreement { mean: ISPM_MEAN, worst_block: ISPM_BLOCK },
        }
    }

    /// True when its frames keep caustics (light that reached a surface through
    /// mirrors and glass only) in a layer of their own, as the batch methods do;
    /// the vertex method's corner estimates take every photon, so its caustics
    /// are part of its indirect layer.
    pub fn separates_caustics(self) -> bool {
        matches!(self, LiveMethod::Ispm)
    }
}

const VERTEX_MEAN: f64 = 0.10;
const VERTEX_BLOCK: f64 = 0.40;
const ISPM_MEAN: f64 = 0.10;
const ISPM_BLOCK: f64 = 0.40;

/// The real-time settings: the method, what every method's frames share, and
/// each method's own parameters. One flat set of options (`--per-frame`,
/// `--bounce-res`, ...: their names are unique across the groups); in
/// pipeline.toml `[live]` holds `method` and the frame keys, `[live.vertex]` and
/// `[live.ispm]` each method's. A key no part knows is refused.
#[derive(Clone, Debug, PartialEq, clap::Args, serde::Serialize)]
pub struct LiveParams {
    /// The method: vertex estimates (Jozwowski 2002) or image-space photon
    /// mapping (McGuire and Luebke 2009).
    #[arg(long, default_value_t = LiveMethod::Vertex)]
    pub method: LiveMethod,
    /// Frame size, clock, exposure and direct light (both methods).
    #[command(flatten, next_help_heading = "Frames (both methods)")]
    #[serde(flatten)]
    pub frame: FrameParams,
    /// The vertex method's parameters (`[live.vertex]`).
    #[command(flatten, next_help_heading = "Vertex method (--method vertex)")]
    pub vertex: VertexParams,
    /// The image-space method's parameters (`[live.ispm]`).
    #[command(flatten, next_help_heading = "Image-space method (--method ispm)")]
    pub ispm: IspmParams,
}

impl Default for LiveParams {
    fn default() -> Self {
        LiveParams {
            method: LiveMethod::Vertex,
            frame: FrameParams::default(),
            vertex: VertexParams::default(),
            ispm: IspmParams::default(),
        }
    }
}

impl<'de> serde::Deserialize<'de> for LiveParams {
    /// `method`, the method tables and the frame keys, which are checked as a
    /// `deny_unknown_fields` struct's (an unknown key is refused, naming it).
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let mut table = toml::Table::deserialize(d)?;
        let method = match table.remove("method") {
            Some(v) => LiveMethod::deserialize(v).map_err(Error::custom)?,
            None => LiveMethod::Vertex,
        };
        let mut part = |key: &str| table.remove(key).unwrap_or_else(|| toml::Value::Table(Default::default()));
        let vertex = VertexParams::deserialize(part("vertex")).map_err(|e| Error::custom(format!("vertex: {e}")))?;
        let ispm = IspmParams::deserialize(part("ispm")).map_err(|e| Error::custom(format!("ispm: {e}")))?;
        let frame = FrameParams::deserialize(toml::Value::Table(table)).map_err(Error::custom)?;
        Ok(LiveParams { method, frame, vertex, ispm })
    }
}

impl LiveParams {
    /// The keys of an older pipeline.toml's flat `[live]` section that now belong
    /// to `[live.vertex]` or `[live.ispm]`: (key, its table).
    pub fn moved_keys() -> impl Iterator<Item = (&'static str, &'static str)> {
        let vertex = VertexParams::FIELDS.iter().map(|k| (*k, "vertex"));
        vertex.chain(IspmParams::FIELDS.iter().map(|k| (*k, "ispm")))
    }

    /// Refuse a value outside its range or two that contradict each other, naming
    /// the option or key (`cli`: the option, else `live.key`, `live.vertex.key`).
    pub fn check(&self, cli: bool) -> Result<(), String> {
        let naming = |section| if cli { Naming::Cli } else { Naming::File(section) };
        self.frame.validate(naming("live"))?;
        self.vertex.check(naming("live.vertex"))?;
        self.ispm.validate(naming("live.ispm"))
    }

    /// The command-line arguments that give every field its value.
    pub fn to_args(&self) -> Vec<String> {
        let mut v = vec!["--method".to_string(), self.method.to_string()];
        v.extend(self.frame.to_args());
        v.extend(self.vertex.to_args());
        v.extend(self.ispm.to_args());
        v
    }

    /// Frames after which a still scene's frame stops improving by what the method
    /// accumulates: the vertex method's ring buffer full (total / per_frame
    /// frames), one frame for the image-space method (each frame shoots its own
    /// photons).
    pub fn settled_frames(&self) -> u32 {
        match self.method {
            LiveMethod::Vertex => self.vertex.total.div_ceil(self.vertex.per_frame).max(1),
            LiveMethod::Ispm => 1,
        }
    }
}

/// Each frame's wall time \[s\] from the frames.csv a run by `method` wrote.
pub fn frame_seconds(method: LiveMethod, csv: &str) -> Result<Vec<f64>, String> {
    fn walls<R: FrameRow>(csv: &str) -> Result<Vec<f64>, String> {
        Ok(pm_live::rows_from_csv::<R>(csv)?.iter().map(R::wall_seconds).collect())
    }
    match method {
        LiveMethod::Vertex => walls::<pm_vertex::VertexFrame>(csv),
        LiveMethod::Ispm => walls::<pm_ispm::IspmFrame>(csv),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `[live]` reads its method tables and frame keys; a vertex key left in
    /// `[live]`, or an unknown key anywhere, is refused naming it.
    #[test]
    fn the_live_section_reads_its_tables_and_refuses_strays() {
        let p: LiveParams = toml::from_str(
            "method = \"ispm\"\nwidth = 64\n[vertex]\nper_frame = 10\ntotal = 20\n[ispm]\nsubsample = 2",
        )
        .unwrap();
        assert_eq!((p.method, p.frame.width, p.vertex.per_frame, p.ispm.subsample), (LiveMethod::Ispm, 64, 10, 2));
        assert_eq!(p.vertex.max_level, VertexParams::default().max_level);
        for (text, want) in
            [("per_frame = 10", "per_frame"), ("[vertex]\nbogus = 1", "bogus"), ("[ispm]\nk = 3", "`k`")]
        {
            let e = toml::from_str::<LiveParams>(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text}: {e}");
        }
        let back: LiveParams = toml::from_str(&toml::to_string(&p).unwrap()).unwrap();
        assert_eq!(back, p);
    }
}
