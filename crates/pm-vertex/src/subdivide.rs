//! How finely the drawn mesh is split (Jozwowski 2002 section 4.3): the scenes
//! the method draws and traces photons in, chosen from the scene and the settings.

use crate::{PhotonProxy, VertexParams};
use pm_scene::Scene;
use std::f32::consts::PI;
use std::fmt;

/// `subdivide`: split every drawn triangle until no edge is longer than a length
/// \[m\] (0: leave the mesh as it is), or choose that length from the scene (`auto`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Subdivide {
    /// An edge length from the expected photon search radius ([`scenes`]).
    Auto,
    /// At most this edge length \[m\]; 0 keeps the mesh.
    MaxEdge(f32),
}

impl std::str::FromStr for Subdivide {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s.trim() == "auto" {
            return Ok(Subdivide::Auto);
        }
        match s.trim().parse::<f32>() {
            Ok(v) => Subdivide::metres(v),
            Err(_) => Err(format!("'{s}' is neither auto nor a length in metres")),
        }
    }
}

impl Subdivide {
    /// A length \[m\]: finite and not negative.
    fn metres(v: f32) -> Result<Self, String> {
        if v.is_finite() && v >= 0.0 {
            Ok(Subdivide::MaxEdge(v))
        } else {
            Err(format!("{v} is not a length in metres (0 or more, or auto)"))
        }
    }
}

impl fmt::Display for Subdivide {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Subdivide::Auto => f.write_str("auto"),
            Subdivide::MaxEdge(v) => write!(f, "{v}"),
        }
    }
}

impl serde::Serialize for Subdivide {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Subdivide::Auto => s.serialize_str("auto"),
            Subdivide::MaxEdge(v) => s.serialize_f32(*v),
        }
    }
}

impl<'de> serde::Deserialize<'de> for Subdivide {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(f64),
            Text(String),
        }
        match Raw::deserialize(d)? {
            Raw::Number(v) => Subdivide::metres(v as f32),
            Raw::Text(s) => s.parse(),
        }
        .map_err(serde::de::Error::custom)
    }
}

/// Most triangles an automatic split may make: past this it stops a round early (a
/// scene whose area over the radius squared is larger gets coarser corners than
/// the rule asks for, and the note says so), so that the corner estimates stay
/// within a frame's budget (`cargo xtask live-study`, BENCHMARKS.md).
pub const AUTO_MAX_TRIANGLES: usize = 200_000;

/// The photon search radius \[m\] the estimates can expect: that of a disc holding
/// `k` photons when `total` paths' first hits spread evenly over the scene's area
/// A, sqrt(k A / (pi total)), at most the largest estimate radius. (Later hits add
/// photons and shrink it; first hits alone are the dimmest case.)
pub fn expected_radius(scene: &Scene, params: &VertexParams) -> f32 {
    let area: f64 = scene.triangles.iter().map(|t| t.area() as f64).sum();
    let r = (params.k as f64 * area / (PI as f64 * params.total as f64)).sqrt() as f32;
    r.min(params.max_radius_rel_diag * scene.bounds.diagonal())
}

/// How the drawn mesh was chosen: printed by `photon-live`.
#[derive(Clone, Debug, PartialEq)]
pub struct Subdivision {
    /// What was asked.
    pub asked: Subdivide,
    /// The drawn mesh's longest edge \[m\].
    pub longest_edge: f32,
    /// The expected photon search radius \[m\] ([`expected_radius`]).
    pub radius: f32,
    /// Triangles before and after.
    pub triangles: (usize, usize),
    /// Edges longer than asked are left, to keep within [`AUTO_MAX_TRIANGLES`]
    /// (or, for a length given, the split's own limit).
    pub capped: bool,
}

impl fmt::Display for Subdivision {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (before, after) = self.triangles;
        if after == before {
            write!(f, "drawn mesh as it is: {before} triangles, the longest edge {:.3} m", self.longest_edge)?;
        } else {
            write!(
                f,
                "drawn mesh: {before} triangles split into {after}, the longest edge {:.3} m",
                self.longest_edge
            )?;
        }
        match self.asked {
            Subdivide::MaxEdge(0.0) => f.write_str(" (subdivide = 0)"),
            Subdivide::MaxEdge(v) if self.capped => write!(f, " (subdivide = {v} m, past the split's limit)"),
            Subdivide::MaxEdge(v) => write!(f, " (subdivide = {v} m)"),
            Subdivide::Auto => {
                write!(f, " (subdivide = auto: at most the expected photon search radius {:.3} m", self.radius)?;
                if self.capped {
                    write!(f, " but for a limit of {AUTO_MAX_TRIANGLES} triangles")?;
                }
                f.write_str("; --subdivide METRES sets it, 0 keeps the mesh)")
            }
        }
    }
}

/// The scenes the vertex method works on, from the scene (and the photon scene)
/// given: the drawn mesh split as `params.subdivide` says, photons traced in the
/// photon scene, in the bounding-box proxy (`photon_proxy = boxes`), or in the
/// unsplit scene (splitting only adds corners; the photons' paths do not change).
///
/// `auto` splits toward the expected photon search radius ([`expected_radius`]),
/// in as many rounds as keep within [`AUTO_MAX_TRIANGLES`] (or the triangles the
/// scene has, if more). Why the radius: the corners sample the irradiance the
/// estimates see, which is smooth over about a radius, so corners closer than that
/// add little; corners farther apart than that leave most of a wall's light to
/// corners at its edges, whose estimates reach past the wall into nothing and come
/// out dark (a room of 2-triangle walls rendered 36% too dark by default; issue 36).
pub fn scenes(scene: Scene, photon_scene: Option<Scene>, params: &VertexParams) -> (Scene, Option<Scene>, Subdivision) {
    let photon_scene = match params.photon_proxy {
        PhotonProxy::Boxes => Some(photon_scene.as_ref().unwrap_or(&scene).bounding_box_proxy()),
        PhotonProxy::None => photon_scene,
    };
    let radius = expected_radius(photon_scene.as_ref().unwrap_or(&scene), params);
    let (max_edge, budget) = match params.subdivide {
        Subdivide::Auto => (radius, AUTO_MAX_TRIANGLES),
        Subdivide::MaxEdge(v) => (v, usize::MAX),
    };
    let before = scene.triangles.len();
    let (drawn, longest) = scene.subdivided_within(max_edge, budget);
    let subdivision = Subdivision {
        asked: params.subdivide,
        longest_edge: longest,
        radius,
        triangles: (before, drawn.triangles.len()),
        capped: max_edge > 0.0 && longest > max_edge,
    };
    if drawn.triangles.len() > before {
        (drawn, Some(photon_scene.unwrap_or(scene)), subdivision)
    } else {
        (scene, photon_scene, subdivision)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--subdivide` and the `[live]` key take `auto` or a length, and refuse the rest.
    #[test]
    fn subdivide_reads_auto_or_metres_and_refuses_the_rest() {
        assert_eq!("auto".parse::<Subdivide>(), Ok(Subdivide::Auto));
        assert_eq!("0.2".parse::<Subdivide>(), Ok(Subdivide::MaxEdge(0.2)));
        assert_eq!("0".parse::<Subdivide>(), Ok(Subdivide::MaxEdge(0.0)));
        for bad in ["-1", "inf", "NaN", "fine"] {
            assert!(bad.parse::<Subdivide>().is_err(), "{bad}");
        }
        #[derive(serde::Deserialize, Debug)]
        struct Section {
            subdivide: Subdivide,
        }
        let read = |text: &str| toml::from_str::<Section>(text).map(|s| s.subdivide).map_err(|e| e.to_string());
        assert_eq!(read("subdivide = \"auto\""), Ok(Subdivide::Auto));
        assert_eq!(read("subdivide = 0.25"), Ok(Subdivide::MaxEdge(0.25)));
        assert_eq!(read("subdivide = 0"), Ok(Subdivide::MaxEdge(0.0)));
        assert!(read("subdivide = -0.5").is_err());
        assert!(read("subdivide = \"fine\"").is_err());
        // The round trip the job plan relies on (to_args, then clap's FromStr).
        for v in [Subdivide::Auto, Subdivide::MaxEdge(0.125)] {
            assert_eq!(v.to_string().parse::<Subdivide>(), Ok(v));
        }
    }
}
