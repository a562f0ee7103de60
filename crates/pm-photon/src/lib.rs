//! Photon tracing (Christensen 1999 section 1.1; Jensen 1996; the loop follows the
//! summary in McGuire and Luebke 2009, Appendix A, step 2): photons leave the lights
//! with power proportional to emission, scatter by the scene's BSDFs with Russian
//! roulette, and are stored at non-specular hits in the global map; photons that
//! reach a non-specular surface through specular bounces only are stored in the
//! caustic map, traced in a separate pass aimed at the specular objects.
//!
//! Glossy lobes (a rough metal, the glTF dielectric's GGX layer, a clear coat,
//! sheen) are not specular here: a photon is stored at every hit on a surface
//! with any non-delta lobe (a coated dielectric stores at its coat and base
//! alike: the BSDF is one), and one that scattered off such a lobe is a global
//! photon wherever it lands. The caustic map holds Dirac chains only (LS+D):
//! light a sharp coat or rough metal focuses reaches the eye through final
//! gathers, whose rays sample those surfaces' lobes, or, at a surface seen
//! directly, through the gather's glossy sampling ([`pm_bsdf::Bsdf::layer_alpha`]),
//! never through both.
//!
//! Determinism: photon `i` of a map draws its samples from a stream keyed by
//! (seed, map, i) and nothing else, batches are traced in parallel and concatenated
//! in index order, so results are bit-identical for any thread count, and a map
//! traced in slices of the index space and concatenated equals one traced whole.
//!
//! This crate returns photons in memory and does no I/O, so the real-time mode can
//! call it per frame.

use glam::Vec3;
use pm_bsdf::BsdfSample;
use pm_color::Rgb;
/// The photons the tracer emits and their flags, for the methods that keep them
/// in memory and write no photon-map file (the image-space method).
pub use pm_format::{Photon, flags};
pub use pm_light::{LightSelectError, LightSelector};
use pm_sampling::{Sampler, mix64};
use pm_scene::{Flights, FreeFlight, Scene, Target};
use rayon::prelude::*;

/// Path length limit. Russian roulette ends paths long before this in physical
/// scenes; paths cut here are counted in [`MapStats::truncated_paths`].
pub const MAX_BOUNCES: u32 = 1000;
/// Photon paths traced per batch between checks of the stored count.
const BATCH: u64 = 1 << 14;
/// Paths per chunk: the parallel work item, the unit a stored budget stops at, and
/// the unit of slicing ([`Slice`]).
pub const CHUNK: u64 = 256;

pm_params::value_enum! {
    /// Precision of the stored photon records.
    pub enum RecordLayout {
        /// RGBE power and 1-byte directions (Christensen's 18 bytes; 23 with irradiance and normal).
        Compact,
        /// f32 everywhere (40 bytes; 64 with irradiance and normal), for accuracy comparisons.
        Full,
    }
}

/// Most photons a map may be asked for: the sort holds two copies of 64-byte records
/// (the largest layout), which must fit in 16 GiB.
pub const MAX_PHOTONS: u64 = 16 * (1 << 30) / (2 * 64);

pm_params::params! {
    /// Stage 1's parameters, defined once: `photon-trace`'s options and the `[trace]`
    /// section of pipeline.toml (Christensen 1999 section 1.1).
    pub struct TraceParams {
        /// Target number of photons stored in the global map (emission continues until
        /// reached; 0: no global map). At most 134,217,728 (memory of the sort).
        global_photons: u64 = 400_000 => pm_params::between(0, MAX_PHOTONS);
        /// Target number of photons stored in the caustic map (0: no caustic map).
        caustic_photons: u64 = 35_000 => pm_params::between(0, MAX_PHOTONS);
        /// Target number of photons stored in the volume map (0: none): scattering
        /// events in participating media, traced only when the scene has a medium
        /// that scatters and a light that reaches it.
        volume_photons: u64 = 200_000 => pm_params::between(0, MAX_PHOTONS);
        /// Record layout: compact (RGBE power, 1-byte directions; 18/23 bytes) or full (f32; 40/64 bytes).
        layout: RecordLayout = RecordLayout::Compact => pm_params::Any;
        /// Give light NAME this fraction of the photons emitted, NAME=FRACTION
        /// (repeatable); the other lights share the rest in proportion to their
        /// power. In pipeline.toml a table [trace.light_shares], name to fraction.
        #[serde(with = "light_share_table", skip_serializing_if = "Vec::is_empty")]
        #[arg(value_name = "NAME=FRACTION")]
        light_share as "light_shares": Vec<LightShare> => pm_params::Valid;
    }
}

/// A light's name and its share of the photons emitted, a fraction in [0, 1]:
/// `--light-share NAME=FRACTION`, or a key of pipeline.toml's `[trace.light_shares]`.
#[derive(Clone, Debug, PartialEq)]
pub struct LightShare {
    /// The light's name in the glTF file (or the start of it: [`LightSelector::new`]).
    pub light: String,
    /// Its fraction of the photons emitted.
    pub share: f64,
}

impl std::str::FromStr for LightShare {
    type Err = String;

    fn from_str(s: &str) -> Result<LightShare, String> {
        let (light, share) = s.rsplit_once('=').ok_or_else(|| format!("expected NAME=FRACTION, got '{s}'"))?;
        let share = share.trim().parse().map_err(|_| format!("'{share}' is not a number"))?;
        Ok(LightShare { light: light.to_string(), share })
    }
}

impl std::fmt::Display for LightShare {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}={}", self.light, self.share)
    }
}

impl pm_params::SelfChecked for LightShare {
    fn problem(&self) -> Option<String> {
        (!(0.0..=1.0).contains(&self.share)).then(|| "a share is a fraction in [0, 1]".to_string())
    }
}

impl TraceParams {
    /// The light shares as [`LightSelector::new`] takes them: (name, share).
    pub fn light_shares(&self) -> Vec<(String, f64)> {
        self.light_share.iter().map(|l| (l.light.clone(), l.share)).collect()
    }
}

/// `[trace.light_shares]`: light name to share, in name order.
mod light_share_table {
    use super::LightShare;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use std::collections::BTreeMap;

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<LightShare>, D::Error> {
        let table = BTreeMap::<String, f64>::deserialize(d)?;
        Ok(table.into_iter().map(|(light, share)| LightShare { light, share }).collect())
    }

    pub fn serialize<S: Serializer>(v: &[LightShare], s: S) -> Result<S::Ok, S::Error> {
        v.iter().map(|l| (l.light.as_str(), l.share)).collect::<BTreeMap<_, _>>().serialize(s)
    }
}

/// How many photons to emit for a map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Budget {
    /// Emit until this many photons are stored (whole chunks of [`CHUNK`] paths
    /// are kept, so the map may hold a few more), or until `cap` photons have been
    /// emitted.
    Stored {
        /// Target number of stored photons.
        target: u64,
        /// Emission limit.
        cap: u64,
    },
    /// Emit exactly this many photons (needed to split the index space).
    Emitted(u64),
}

/// Which map a pass fills. Every pass simulates the same transport (surfaces and
/// media alike); they differ in what they store.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapPass {
    /// Global map: every non-specular hit.
    Global,
    /// Caustic map: the first non-specular hit after one or more specular bounces
    /// (a path that scatters in a medium first is no caustic and ends there).
    Caustic,
    /// Volume map (Jensen and Christensen 1998): every scattering event in a
    /// medium, flagged [`flags::VOLUME`], [`flags::DIRECT`] for the first event of
    /// a path straight from the light (single scattering, which renderers take from
    /// the lights instead) and [`flags::CAUSTIC`] after specular bounces only
    /// (L S+ V: volumetric caustics).
    Volume,
    /// What progressive photon mapping gathers each pass: the global map's
    /// photons and the volume map's together, from one path each, drawn from the
    /// global map's stream (so a scene without media gets the global pass's
    /// photons exactly).
    Progressive,
}

/// Inputs of a tracing pass.
#[derive(Clone, Debug)]
pub struct TraceConfig {
    /// Which map.
    pub pass: MapPass,
    /// Emission budget.
    pub budget: Budget,
    /// Random seed.
    pub seed: u64,
    /// Probability of emitting from each light (same order as `scene.lights`); see
    /// [`LightSelector`].
    pub selector: LightSelector,
}

/// Statistics of a pass.
#[derive(Clone, Debug, Default)]
pub struct MapStats {
    /// Photons emitted (the power scale's N).
    pub emitted: u64,
    /// Photons stored.
    pub stored: u64,
    /// Stored photons by the number of bounces before the store (index 0 = direct).
    pub stored_per_bounce: Vec<u64>,
    /// Photons emitted from each light.
    pub emitted_per_light: Vec<u64>,
    /// Of those, the photons whose first ray hit the scene (the rest left it at
    /// once: most of an environment's, whose disc is the bounding sphere's).
    pub reached_per_light: Vec<u64>,
    /// Rays traced (intersection queries).
    pub rays: u64,
    /// Paths ended by [`MAX_BOUNCES`] rather than absorption or escape.
    pub truncated_paths: u64,
    /// True when emission stopped at the cap before reaching the target.
    pub hit_cap: bool,
}

/// Result of a pass: photons in index order, with power already divided by the
/// number emitted.
#[derive(Clone, Debug)]
pub struct TracedMap {
    /// The stored photons.
    pub photons: Vec<Photon>,
    /// Counts.
    pub stats: MapStats,
}

/// Why a scene cannot be traced.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// The lights cannot be chosen from (none has power, or the shares are wrong).
    #[error(transparent)]
    Lights(#[from] LightSelectError),
    /// Nothing to hit.
    #[error("the scene has no surfaces: photons would never be stored")]
    NoSurfaces,
    /// A slice outside 0..count.
    #[error("slice {} of {}: needs 0 <= index < count", .0.index, .0.count)]
    BadSlice(Slice),
}

/// The bounding spheres of every specular object (aim points for caustic photons).
pub fn specular_targets(scene: &Scene) -> Vec<Target> {
    scene
        .objects
        .iter()
        .filter(|o| scene.materials[o.material as usize].bsdf.is_specular())
        .map(|o| o.bounding_sphere(scene))
        .collect()
}

/// One traced path: its photons (unscaled power) and bookkeeping.
#[derive(Default, Clone, Debug)]
pub struct PathOut {
    /// The stored photons with the number of surfaces (specular ones included) the
    /// path hit before each: 0 for a photon straight from the light. Power is
    /// Phi-hat / p_select [W per channel], not yet divided by the number emitted.
    pub photons: Vec<(Photon, u32)>,
    /// The light the path left.
    pub light: usize,
    /// True when the photon's first ray hit the scene.
    pub reached: bool,
    /// Rays traced.
    pub rays: u64,
    /// True when the path was cut at [`MAX_BOUNCES`].
    pub truncated: bool,
}

/// Trace photon path `index` of the pass `cfg` describes, into `out` (cleared
/// first). The path draws its samples from the stream keyed by (seed, pass, index)
/// alone, exactly as [`trace`] does for its `index`-th photon, so a caller that
/// traces paths one by one (the real-time ring buffer) gets the batch map's photons.
/// `targets` are [`specular_targets`] (used by the caustic pass only).
pub fn trace_path(scene: &Scene, cfg: &TraceConfig, targets: &[Target], index: u64, out: &mut PathOut) {
    out.photons.clear();
    out.rays = 0;
    out.truncated = false;
    out.reached = false;
    let stream = match cfg.pass {
        MapPass::Global | MapPass::Progressive => 0x676c_6f62_616c,
        MapPass::Caustic => 0x6361_7573_7469,
        MapPass::Volume => 0x766f_6c75_6d65,
    };
    let mut s = Sampler::new(mix64(cfg.seed ^ stream), index);
    let (li, p_sel) = cfg.selector.pick(s.next_1d());
    out.light = li;
    let light = &scene.lights[li];
    let emitted = match cfg.pass {
        MapPass::Global | MapPass::Volume | MapPass::Progressive => light.sample_emission(scene, &mut s),
        MapPass::Caustic => light.sample_emission_toward(scene, &mut s, targets),
    };
    let Some(ray) = emitted else { return };
    let (mut o, mut d) = (ray.origin, ray.dir);
    let mut photon = PhotonPath::new(scene, li, ray.power / p_sel as f32, &mut s);
    for _ in 0..MAX_BOUNCES {
        if !pm_color::is_valid(photon.carrier.phi) || photon.carrier.phi == Rgb::ZERO {
            return;
        }
        out.rays += 1;
        match photon.carrier.fly(scene, o, d, &mut s) {
            Landing::Escaped => return,
            Landing::Scattered { p, medium } => {
                out.reached = true;
                match photon.in_medium(cfg.pass, medium, p, -d, &mut s, out) {
                    Some(wi) => (o, d) = (p, wi),
                    None => return,
                }
            }
            Landing::Passed { o: beyond } => {
                out.reached = true;
                o = beyond;
            }
            Landing::Surface(hit) => {
                out.reached = true;
                match photon.on_surface(scene, cfg.pass, &hit, -d, &mut s, out) {
                    Some(wi) => (o, d) = (scene.offset_origin(hit.p, hit.ng, wi), wi),
                    None => return,
                }
            }
        }
    }
    out.truncated = true;
}

/// What a photon carries from event to event and the medium it travels in:
/// the state every photon tracer shares (the batch maps' paths here, the
/// image-space method's bounce maps and paths).
#[derive(Clone, Copy, Debug)]
pub struct Carrier {
    /// Power it carries \[W per channel\], before its flights' weight
    /// ([`Carrier::power`]).
    pub phi: Rgb,
    /// The medium it is in.
    pub medium: Option<pm_scene::MediumId>,
    /// Its free flights through media (hero channel, density ratios).
    pub flights: Flights,
}

/// Where a photon's flight from a point ends ([`Carrier::fly`]).
#[derive(Clone, Copy, Debug)]
pub enum Landing<'a> {
    /// It left the scene.
    Escaped,
    /// It scattered at `p` in `medium` (power: the flight's weight taken in).
    Scattered {
        /// Where \[m\].
        p: Vec3,
        /// The medium it is in.
        medium: &'a pm_scene::Medium,
    },
    /// It went straight through an index-matched boundary and flies on from `o`
    /// (in the medium beyond, the boundary's colour taken in); no event.
    Passed {
        /// Where it flies on from (offset off the boundary) \[m\].
        o: Vec3,
    },
    /// It reached a surface.
    Surface(pm_scene::Hit),
}

impl Carrier {
    /// A photon of power `phi` [W per channel] leaving light `light`: in the
    /// light's medium, its hero channel drawn from `s` when the scene has media
    /// (one number; none otherwise).
    pub fn new(scene: &Scene, light: usize, phi: Rgb, s: &mut Sampler) -> Carrier {
        let media = scene.has_media();
        Carrier {
            phi,
            medium: if media { scene.light_medium(light) } else { None },
            flights: Flights::new(if media { s.next_1d() } else { 0.0 }),
        }
    }

    /// The power it carries [W per channel]: `phi` times its flights' weight (one
    /// without media).
    #[inline]
    pub fn power(&self) -> Rgb {
        self.phi * self.flights.weight()
    }

    /// Fly from `o` along unit `d` to the next thing that happens: across a
    /// medium that absorbs or scatters, a free flight (one number from `s` when
    /// it scatters; Beer-Lambert otherwise) that may end in it; then the first
    /// surface, an index-matched boundary passed, or nothing. One ray.
    pub fn fly<'s>(&mut self, scene: &'s Scene, o: Vec3, d: Vec3, s: &mut Sampler) -> Landing<'s> {
        let hit = scene.intersect(o, d, f32::INFINITY);
        if let Some(m) = scene.medium(self.medium).filter(|m| !m.is_clear()) {
            let u = if m.scatters() { s.next_1d() } else { 0.0 };
            let flight = self.flights.fly(m, scene.segment_length(o, d, hit.as_ref()), u);
            let (FreeFlight::Through { weight, .. } | FreeFlight::Scatter { weight, .. }) = flight;
            self.phi *= weight;
            if let FreeFlight::Scatter { t, .. } = flight {
                return Landing::Scattered { p: o + d * t, medium: m };
            }
        }
        let Some(hit) = hit else { return Landing::Escaped };
        if let Some(tint) = scene.index_matched(&hit) {
            self.phi *= tint;
            self.medium = scene.medium_after(&hit, d, self.medium);
            return Landing::Passed { o: scene.offset_origin(hit.p, hit.ng, d) };
        }
        Landing::Surface(hit)
    }

    /// A scattering event in medium `m`, the photon travelling toward `-wo`:
    /// Russian roulette by the single-scattering albedo's survival probability q
    /// as `roulette` says (the flight's weight already holds sigma_s over
    /// sigma_t; the power is divided by q), then the phase function sampled
    /// (three numbers from `s`, one when it ends). The new direction, or `None`
    /// when it is absorbed.
    pub fn scatter_in(&mut self, m: &pm_scene::Medium, wo: Vec3, roulette: Roulette, s: &mut Sampler) -> Option<Vec3> {
        let q = roulette.survival(m.albedo());
        if !(q > 0.0) || s.next_1d() >= q {
            return None;
        }
        self.phi /= q;
        Some(m.phase.sample(wo, s.next_2d()).wi)
    }

    /// Leave a surface event at `hit` in direction `wi`: the medium beyond.
    pub fn leave(&mut self, scene: &Scene, hit: &pm_scene::Hit, wi: Vec3) {
        if scene.has_media() {
            self.medium = scene.medium_after(hit, wi, self.medium);
        }
    }
}

/// A photon scattered at `p` in a medium, arriving from `wo` (unit, toward
/// where it came from), as a volume photon of power `power` [W per channel]
/// with `extra` flags besides [`flags::VOLUME`] ([`flags::DIRECT`] for a first
/// event, [`flags::CAUSTIC`] after mirrors and glass alone).
pub fn volume_photon(p: Vec3, wo: Vec3, power: Rgb, extra: u8) -> Photon {
    Photon {
        position: p,
        power,
        wi: wo,
        flags: flags::AXIS_LEAF | flags::VOLUME | extra,
        normal: Vec3::ZERO,
        irradiance: Rgb::ZERO,
    }
}

/// A photon's state between its events.
struct PhotonPath {
    /// What it carries and where.
    carrier: Carrier,
    /// Every event so far was specular (a caustic photon when it lands).
    specular_chain: bool,
    /// Scattering events so far (surfaces, specular ones included, and points in
    /// media; index-matched boundaries are not events).
    events: u32,
}

impl PhotonPath {
    /// A photon of power `phi` leaving light `light`.
    fn new(scene: &Scene, light: usize, phi: Rgb, s: &mut Sampler) -> PhotonPath {
        PhotonPath { carrier: Carrier::new(scene, light, phi, s), specular_chain: true, events: 0 }
    }

    /// A scattering event at `p` in medium `m`, the photon travelling toward
    /// `-wo`: stored in the volume map, then Russian roulette by the single-
    /// scattering albedo and the phase function sampled. The new direction, or
    /// `None` when the photon ends (a caustic photon ends on entering: L S+ V is no
    /// caustic).
    fn in_medium(
        &mut self,
        pass: MapPass,
        m: &pm_scene::Medium,
        p: Vec3,
        wo: Vec3,
        s: &mut Sampler,
        out: &mut PathOut,
    ) -> Option<Vec3> {
        if pass == MapPass::Caustic {
            return None;
        }
        if matches!(pass, MapPass::Volume | MapPass::Progressive) {
            let extra = if self.events == 0 {
                flags::DIRECT
            } else if self.specular_chain {
                flags::CAUSTIC
            } else {
                0
            };
            out.photons.push((volume_photon(p, wo, self.carrier.power(), extra), self.events));
        }
        let wi = self.carrier.scatter_in(m, wo, Roulette::LargestChannel, s)?;
        self.specular_chain = false;
        self.events += 1;
        Some(wi)
    }

    /// A surface event at `hit`, the photon arriving from `wo`: stored at a
    /// non-specular surface in the maps of `pass`, then [`scatter`]. The new
    /// direction, or `None` when the photon ends (the caustic pass ends at the
    /// first non-specular surface, or when the chain stops being specular).
    fn on_surface(
        &mut self,
        scene: &Scene,
        pass: MapPass,
        hit: &pm_scene::Hit,
        wo: Vec3,
        s: &mut Sampler,
        out: &mut PathOut,
    ) -> Option<Vec3> {
        let bsdf = scene.bsdf(hit);
        if !bsdf.is_specular() {
            let side_n = if wo.dot(hit.ng) >= 0.0 { hit.ng } else { -hit.ng };
            let caustic = self.events > 0 && self.specular_chain;
            let store = match pass {
                MapPass::Global | MapPass::Progressive => true,
                MapPass::Caustic => caustic,
                MapPass::Volume => false,
            };
            if store {
                let mut f = flags::AXIS_LEAF;
                if self.events == 0 {
                    f |= flags::DIRECT;
                }
                if caustic {
                    f |= flags::CAUSTIC;
                }
                let photon = Photon {
                    position: hit.p,
                    power: self.carrier.power() / scene.store_probability(hit),
                    wi: wo,
                    flags: f,
                    normal: side_n,
                    irradiance: Rgb::ZERO,
                };
                out.photons.push((photon, self.events));
            }
            if pass == MapPass::Caustic {
                return None; // the caustic map only needs the first non-specular hit
            }
        }
        let (bs, factor) = scatter(&bsdf, hit, wo, Roulette::LargestChannel, s)?;
        self.carrier.phi *= factor;
        self.specular_chain &= bs.specular;
        if pass == MapPass::Caustic && !self.specular_chain {
            return None;
        }
        self.events += 1;
        self.carrier.leave(scene, hit, bs.wi);
        Some(bs.wi)
    }
}

/// How a photon's Russian roulette keeps its spectral balance: the survival
/// probability q [0, 1] at an event whose sampling weight (a BSDF sample's, or a
/// medium's single-scattering albedo) is `weight`, the power then divided by q.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Roulette {
    /// q = the weight's largest channel (Jensen 2001, "Realistic Image Synthesis
    /// Using Photon Mapping", section 5.2): dividing by it never raises a channel
    /// at a Lambertian bounce. The photon tracer's (the batch maps, SPPM's passes,
    /// the vertex method's ring). By the mean, a green wall of albedo (0.1, 0.8,
    /// 0.1) raised a green photon's green power 2.4 times at every bounce, and in
    /// a green-walled fog room SPPM drew green sparks 140 times their pixel (the
    /// differential checker's seed 77777, scene 9; issue 53).
    LargestChannel,
    /// q = the weight's channel mean (McGuire and Luebke 2009, appendix A, step
    /// 2(d)): every photon keeps its mean power. The image-space method's, whose
    /// volumes are sized by the paper's path density and whose paths stop after
    /// `bounces` events (so a channel grows at most (max / mean)^bounces): with
    /// the largest channel its frames of Blender's animated room were no better
    /// (block RMS over four frames and two seeds 8.6% against 8.1%) and took 1.36
    /// times as long (60% more photons a frame on cornell_boxes).
    ChannelMean,
}

impl Roulette {
    /// The survival probability at an event of sampling weight `weight`.
    pub fn survival(self, weight: Rgb) -> f32 {
        match self {
            Roulette::LargestChannel => weight.max_element().min(1.0),
            Roulette::ChannelMean => pm_color::mean(weight).min(1.0),
        }
    }
}

/// One scattering event of a photon that arrived at `hit` from direction `wo`:
/// sample the BSDF, refuse directions the shading normal allows but the geometry
/// does not (they would leak through the surface), then Russian roulette on the
/// scattering albedo keeping spectral balance: survive with q as `roulette` says
/// and scale the power by weight / q. Returns the sample and the factor to
/// multiply the photon's power by, or none when the photon is absorbed. Draws
/// three numbers from `s`, four if it survives.
pub fn scatter(
    bsdf: &pm_bsdf::Bsdf,
    hit: &pm_scene::Hit,
    wo: Vec3,
    roulette: Roulette,
    s: &mut Sampler,
) -> Option<(BsdfSample, Rgb)> {
    let u = s.next_2d();
    let uc = s.next_1d();
    let bs = bsdf.sample(wo, hit.ns, u, uc)?;
    let same_side = pm_scene::same_side(hit.ng, bs.wi, wo);
    if same_side == bs.transmitted {
        return None;
    }
    let q = roulette.survival(bs.weight);
    if !(q > 0.0) || s.next_1d() >= q {
        return None;
    }
    Some((bs, bs.weight / q))
}

/// One of `count` interleaved slices of the emission index space: paths are
/// traced in chunks of [`CHUNK`] consecutive indices, and chunk c belongs to slice
/// c mod `count`. Slices trace independently (on other machines); merging their
/// chunks in index order gives the map one run traces ([`merge_slices`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Slice {
    /// This slice, in 0..count.
    pub index: u32,
    /// Number of slices.
    pub count: u32,
}

impl Slice {
    /// The whole index space as one slice.
    pub const WHOLE: Slice = Slice { index: 0, count: 1 };

    /// Stored photons after which a slice stops, for a stored target: its share of
    /// the target with 10% and 4,096 photons to spare, so that the slices together
    /// (almost surely) cover every chunk up to where one run would stop. Alone, the
    /// target itself.
    fn quota(self, target: u64) -> u64 {
        if self.count <= 1 { target } else { target.div_ceil(self.count as u64).saturating_mul(11) / 10 + 4096 }
    }
}

/// What one chunk of [`CHUNK`] paths stored and cost.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ChunkStats {
    /// Chunk index (paths index x CHUNK .. (index + 1) x CHUNK).
    pub index: u64,
    /// Photons stored.
    pub stored: u64,
    /// Rays traced.
    pub rays: u64,
    /// Paths cut at [`MAX_BOUNCES`].
    pub truncated: u64,
    /// Paths emitted from each light.
    pub per_light: Vec<u64>,
    /// Of those, the paths whose first ray hit the scene.
    #[serde(default)]
    pub reached_per_light: Vec<u64>,
}

impl MapStats {
    /// Count one chunk's paths, rays and cut paths in.
    fn add_chunk(&mut self, chunk: &ChunkStats) {
        if self.emitted_per_light.len() < chunk.per_light.len() {
            self.emitted_per_light.resize(chunk.per_light.len(), 0);
        }
        for (a, b) in self.emitted_per_light.iter_mut().zip(&chunk.per_light) {
            *a += b;
        }
        if self.reached_per_light.len() < chunk.reached_per_light.len() {
            self.reached_per_light.resize(chunk.reached_per_light.len(), 0);
        }
        for (a, b) in self.reached_per_light.iter_mut().zip(&chunk.reached_per_light) {
            *a += b;
        }
        self.rays += chunk.rays;
        self.truncated_paths += chunk.truncated;
    }

    /// Count stored photons by the bounces before them.
    fn add_bounces(&mut self, bounces: &[u32]) {
        for &b in bounces {
            let b = b as usize;
            if self.stored_per_bounce.len() <= b {
                self.stored_per_bounce.resize(b + 1, 0);
            }
            self.stored_per_bounce[b] += 1;
        }
    }
}

/// A traced slice: its chunks in index order, each with its photons, whose power
/// is Phi-hat / p_select [W per channel], not yet divided by the number emitted
/// (which only the merge knows).
#[derive(Clone, Debug)]
pub struct TracedSlice {
    /// Which slice.
    pub slice: Slice,
    /// The budget it was traced for.
    pub budget: Budget,
    /// Per chunk, its statistics.
    pub chunks: Vec<ChunkStats>,
    /// The chunks' photons, concatenated in chunk order.
    pub photons: Vec<Photon>,
    /// The surfaces each photon's path hit before it (as [`PathOut::photons`]): one
    /// per photon, or empty when read back from a slice file, which does not keep it.
    pub bounces: Vec<u32>,
}

impl TracedSlice {
    /// What the slice traced, all its chunks counted (`emitted` is the paths it
    /// traced; nothing is scaled or cut as a merge does).
    pub fn totals(&self) -> MapStats {
        let mut stats = MapStats::default();
        for chunk in &self.chunks {
            stats.add_chunk(chunk);
        }
        stats.add_bounces(&self.bounces);
        stats.emitted = stats.emitted_per_light.iter().sum();
        stats.stored = self.photons.len() as u64;
        stats
    }
}

/// Why slices cannot be merged into a map.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MergeError {
    /// Slices of different traces, or a slice missing or given twice.
    #[error("{0}")]
    Mismatch(String),
    /// A slice stopped before the chunk where one run would have stopped.
    #[error(
        "chunk {chunk} (slice {slice} of {count}) was not traced: that slice stopped at its quota before the map reached {target} photons; trace with fewer slices"
    )]
    Gap {
        /// The missing chunk.
        chunk: u64,
        /// Its slice.
        slice: u64,
        /// Number of slices.
        count: u32,
        /// The stored target.
        target: u64,
    },
}

/// The global map of `target` stored photons, every light emitting by its power
/// (photon-trace's defaults; benchmarks start from it), in index order.
pub fn trace_global(scene: &Scene, target: u64, seed: u64) -> Result<Vec<Photon>, TraceError> {
    let budget = Budget::Stored { target, cap: u64::MAX };
    let cfg = TraceConfig { pass: MapPass::Global, budget, seed, selector: LightSelector::new(scene, &[])? };
    Ok(trace(scene, &cfg, &|_| {})?.photons)
}

/// Trace a map in one run (every slice of the index space). `progress` is called
/// after each batch with the photons stored so far. Identical to merging the
/// slices of any [`Slice::count`] traced with [`trace_slice`].
pub fn trace(scene: &Scene, cfg: &TraceConfig, progress: &(dyn Fn(u64) + Sync)) -> Result<TracedMap, TraceError> {
    let whole = trace_slice(scene, cfg, Slice::WHOLE, progress)?;
    if cfg.pass == MapPass::Caustic && whole.chunks.is_empty() {
        // No mirror or glass to aim at: an empty map, nothing emitted.
        return Ok(TracedMap {
            photons: Vec::new(),
            stats: MapStats {
                emitted_per_light: vec![0; scene.lights.len()],
                reached_per_light: vec![0; scene.lights.len()],
                ..Default::default()
            },
        });
    }
    Ok(merge_slices(vec![whole]).expect("one whole slice always merges"))
}

/// Trace one slice of a map: its chunks in index order, stopping at the emission
/// budget's end or (for a stored target) when it holds its share of the target.
pub fn trace_slice(
    scene: &Scene,
    cfg: &TraceConfig,
    slice: Slice,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<TracedSlice, TraceError> {
    if scene.triangles.is_empty() {
        return Err(TraceError::NoSurfaces);
    }
    if slice.count == 0 || slice.index >= slice.count {
        return Err(TraceError::BadSlice(slice));
    }
    let targets = if cfg.pass == MapPass::Caustic { specular_targets(scene) } else { Vec::new() };
    let mut out =
        TracedSlice { slice, budget: cfg.budget, chunks: Vec::new(), photons: Vec::new(), bounces: Vec::new() };
    if cfg.pass == MapPass::Caustic && targets.is_empty() {
        return Ok(out);
    }
    let (end, quota) = match cfg.budget {
        Budget::Emitted(n) => (n, u64::MAX),
        Budget::Stored { target, cap } => (cap, slice.quota(target)),
    };
    let n_chunks = end.div_ceil(CHUNK);
    // Room for the stored target and the last batch's overshoot, reserved at once:
    // growing by doubling held the old and the new list together (the trace's peak
    // memory; issue 36), and what is never written takes no memory.
    if quota != u64::MAX {
        let room = quota.saturating_add(quota / 4).saturating_add(4 * BATCH);
        out.photons.reserve_exact(room as usize);
        out.bounces.reserve_exact(room as usize);
    }
    // This slice's chunks, BATCH paths' worth at a time in parallel.
    let mut mine = (slice.index as u64..n_chunks).step_by(slice.count as usize).peekable();
    let per_batch = (BATCH / CHUNK) as usize;
    let lights = scene.lights.len();
    while mine.peek().is_some() && (out.photons.len() as u64) < quota {
        let batch: Vec<u64> = mine.by_ref().take(per_batch).collect();
        let results: Vec<(ChunkStats, Vec<(Photon, u32)>)> = batch
            .par_iter()
            .map(|&c| {
                let mut stats = ChunkStats {
                    index: c,
                    per_light: vec![0; lights],
                    reached_per_light: vec![0; lights],
                    ..Default::default()
                };
                let mut photons = Vec::new();
                let mut path = PathOut::default();
                for i in c * CHUNK..((c + 1) * CHUNK).min(end) {
                    trace_path(scene, cfg, &targets, i, &mut path);
                    stats.per_light[path.light] += 1;
                    stats.reached_per_light[path.light] += path.reached as u64;
                    stats.rays += path.rays;
                    stats.truncated += path.truncated as u64;
                    photons.extend_from_slice(&path.photons);
                }
                stats.stored = photons.len() as u64;
                (stats, photons)
            })
            .collect();
        for (stats, photons) in results {
            if (out.photons.len() as u64) >= quota {
                break; // the slice was full before this chunk
            }
            out.chunks.push(stats);
            for (p, b) in photons {
                out.photons.push(p);
                out.bounces.push(b);
            }
        }
        progress(out.photons.len() as u64);
    }
    Ok(out)
}

/// Merge traced slices into the map one run gives (Jensen's power scaling by the
/// number emitted, section 1.1 of Christensen 1999): chunks in index order, up to
/// and including the chunk at which the stored target is reached (a stored budget
/// keeps whole chunks, so the map may hold a few more photons than the target), or
/// every chunk of a fixed emission count. `slices` must be all slices of one trace
/// (any order).
pub fn merge_slices(mut slices: Vec<TracedSlice>) -> Result<TracedMap, MergeError> {
    let Some(first) = slices.first() else { return Err(MergeError::Mismatch("no slices to merge".into())) };
    let (count, budget, first_index) = (first.slice.count, first.budget, first.slice.index);
    slices.sort_by_key(|s| s.slice.index);
    for (k, s) in slices.iter().enumerate() {
        if s.slice.count != count || s.budget != budget {
            return Err(MergeError::Mismatch(format!(
                "slice {} of {} ({:?}) is not from the same trace as slice {} of {count} ({budget:?})",
                s.slice.index, s.slice.count, s.budget, first_index
            )));
        }
        if s.slice.index != k as u32 {
            return Err(MergeError::Mismatch(format!(
                "slice {k} of {count} is missing or another slice is given twice"
            )));
        }
    }
    if slices.len() != count as usize {
        return Err(MergeError::Mismatch(format!("{} slices given for a trace in {count}", slices.len())));
    }
    let (end, target) = match budget {
        Budget::Emitted(n) => (n, u64::MAX),
        Budget::Stored { target, cap } => (cap, target),
    };
    let n_chunks = end.div_ceil(CHUNK);
    // Where each slice's photons of each of its chunks start.
    let offsets: Vec<Vec<usize>> = slices
        .iter()
        .map(|s| {
            let mut acc = 0;
            s.chunks
                .iter()
                .map(|c| {
                    let o = acc;
                    acc += c.stored as usize;
                    o
                })
                .collect()
        })
        .collect();
    let mut stats = MapStats::default();
    // The photon ranges kept, (slice, from, to), then the map gathered from them.
    let mut kept: Vec<(usize, usize, usize)> = Vec::new();
    let mut n_kept = 0;
    let keep_bounces = slices.iter().all(|s| s.bounces.len() == s.photons.len());
    let mut emitted = 0;
    for c in 0..n_chunks {
        if (n_kept as u64) >= target {
            break;
        }
        let k = (c % count as u64) as usize;
        let j = (c / count as u64) as usize;
        let s = &slices[k];
        let Some(chunk) = s.chunks.get(j) else {
            return Err(MergeError::Gap { chunk: c, slice: k as u64, count, target });
        };
        if chunk.index != c {
            return Err(MergeError::Mismatch(format!("slice {k} holds chunk {} where chunk {c} belongs", chunk.index)));
        }
        let from = offsets[k][j];
        let to = from + chunk.stored as usize;
        if to > s.photons.len() {
            return Err(MergeError::Mismatch(format!("slice {k} holds fewer photons than its chunks record")));
        }
        kept.push((k, from, to));
        n_kept += to - from;
        if keep_bounces {
            stats.add_bounces(&s.bounces[from..to]);
        }
        stats.add_chunk(chunk);
        emitted = ((c + 1) * CHUNK).min(end);
    }
    // One slice's kept chunks are its first photons: the map is that list, cut,
    // rather than a copy beside it (the trace's peak memory; issue 36).
    let mut photons = if slices.len() == 1 {
        let mut p = std::mem::take(&mut slices[0].photons);
        p.truncate(n_kept);
        p
    } else {
        let mut p = Vec::with_capacity(n_kept);
        for &(k, from, to) in &kept {
            p.extend_from_slice(&slices[k].photons[from..to]);
        }
        p
    };
    let n_emitted = match budget {
        Budget::Emitted(n) => n,
        Budget::Stored { .. } => emitted,
    };
    stats.emitted = n_emitted;
    stats.hit_cap = (photons.len() as u64) < target && matches!(budget, Budget::Stored { .. });
    for p in &mut photons {
        p.power = scale_power(p.power, n_emitted);
    }
    stats.stored = photons.len() as u64;
    Ok(TracedMap { photons, stats })
}

/// A stored photon's power [W per channel] from its path's Phi-hat / p_select when
/// `n_emitted` paths share the lights' power (Jensen's scaling; Jozwowski 2002
/// Figure 18 for a buffer that holds `n_emitted` paths), computed in f64.
pub fn scale_power(phi: Rgb, n_emitted: u64) -> Rgb {
    let scale = if n_emitted > 0 { 1.0 / n_emitted as f64 } else { 0.0 };
    (phi.as_dvec3() * scale).as_vec3()
}

/// Total power of a set of photons [W per channel], summed in f64 in index order.
pub fn total_power(photons: &[Photon]) -> glam::DVec3 {
    photons.iter().map(|p| p.power.as_dvec3()).sum()
}
