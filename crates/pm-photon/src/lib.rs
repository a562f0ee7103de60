//! Photon tracing (Christensen 1999 section 1.1; Jensen 1996; the loop follows the
//! summary in McGuire and Luebke 2009, Appendix A, step 2): photons leave the lights
//! with power proportional to emission, scatter by the scene's BSDFs with Russian
//! roulette, and are stored at non-specular hits in the global map; photons that
//! reach a non-specular surface through specular bounces only are stored in the
//! caustic map, traced in a separate pass aimed at the specular objects.
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
use pm_format::{Photon, flags};
use pm_sampling::{Sampler, mix64};
pub use pm_scene::{LightSelectError, LightSelector};
use pm_scene::{Scene, Target};
use rayon::prelude::*;
use std::ops::Range;

/// Path length limit. Russian roulette ends paths long before this in physical
/// scenes; paths cut here are counted in [`MapStats::truncated_paths`].
pub const MAX_BOUNCES: u32 = 1000;
/// Photon paths traced per batch between checks of the stored count.
const BATCH: u64 = 1 << 14;
/// Paths per parallel work item.
const CHUNK: u64 = 256;

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
        /// Record layout: compact (RGBE power, 1-byte directions; 18/23 bytes) or full (f32; 40/64 bytes).
        layout: RecordLayout = RecordLayout::Compact => pm_params::Any;
    }
}

/// How many photons to emit for a map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Budget {
    /// Emit until this many photons are stored (whole paths are kept, so the map
    /// may hold a few more), or until `cap` photons have been emitted.
    Stored {
        /// Target number of stored photons.
        target: u64,
        /// Emission limit.
        cap: u64,
    },
    /// Emit exactly this many photons (needed to split the index space).
    Emitted(u64),
}

/// Which map a pass fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapPass {
    /// Global map: every non-specular hit.
    Global,
    /// Caustic map: the first non-specular hit after one or more specular bounces.
    Caustic,
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
    /// Trace only this slice of the photon index space (requires `Budget::Emitted`).
    pub range: Option<Range<u64>>,
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
    /// Slicing needs a fixed emission count.
    #[error("--photon-range needs a fixed emission count (--emit-global/--emit-caustic), not a stored-photon target")]
    RangeNeedsFixedCount,
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
    let stream = match cfg.pass {
        MapPass::Global => 0x676c_6f62_616c,
        MapPass::Caustic => 0x6361_7573_7469,
    };
    let mut s = Sampler::new(mix64(cfg.seed ^ stream), index);
    let (li, p_sel) = cfg.selector.pick(s.next_1d());
    out.light = li;
    let light = &scene.lights[li];
    let emitted = match cfg.pass {
        MapPass::Global => light.sample_emission(scene, &mut s),
        MapPass::Caustic => light.sample_emission_toward(scene, &mut s, targets),
    };
    let Some(ray) = emitted else { return };
    let mut phi = ray.power / p_sel as f32;
    let (mut o, mut d) = (ray.origin, ray.dir);
    let mut specular_chain = true;
    for bounce in 0..MAX_BOUNCES {
        if !pm_color::is_valid(phi) || phi == Rgb::ZERO {
            return;
        }
        out.rays += 1;
        let Some(hit) = scene.intersect(o, d, f32::INFINITY) else { return };
        let bsdf = scene.bsdf(&hit);
        let wo = -d;
        let specular = bsdf.is_specular();
        if !specular {
            let side_n = if wo.dot(hit.ng) >= 0.0 { hit.ng } else { -hit.ng };
            let caustic = bounce > 0 && specular_chain;
            let store = match cfg.pass {
                MapPass::Global => true,
                MapPass::Caustic => caustic,
            };
            if store {
                let mut f = flags::AXIS_LEAF;
                if bounce == 0 {
                    f |= flags::DIRECT;
                }
                if caustic {
                    f |= flags::CAUSTIC;
                }
                let photon =
                    Photon { position: hit.p, power: phi, wi: wo, flags: f, normal: side_n, irradiance: Rgb::ZERO };
                out.photons.push((photon, bounce));
            }
            if cfg.pass == MapPass::Caustic {
                return; // the caustic map only needs the first non-specular hit
            }
        }
        let Some((bs, factor)) = scatter(&bsdf, &hit, wo, &mut s) else { return };
        phi *= factor;
        specular_chain &= bs.specular;
        if cfg.pass == MapPass::Caustic && !specular_chain {
            return;
        }
        o = scene.offset_origin(hit.p, hit.ng, bs.wi);
        d = bs.wi;
    }
    out.truncated = true;
}

/// One scattering event of a photon that arrived at `hit` from direction `wo`:
/// sample the BSDF, refuse directions the shading normal allows but the geometry
/// does not (they would leak through the surface), then Russian roulette on the
/// scattering albedo keeping spectral balance: survive with q = mean(weight) and
/// scale the power by weight / q (McGuire and Luebke 2009, appendix A, step 2(d)).
/// Returns the sample and the factor to multiply the photon's power by, or none
/// when the photon is absorbed. Draws three numbers from `s`, four if it survives.
pub fn scatter(bsdf: &pm_bsdf::Bsdf, hit: &pm_scene::Hit, wo: Vec3, s: &mut Sampler) -> Option<(BsdfSample, Rgb)> {
    let u = s.next_2d();
    let uc = s.next_1d();
    let bs = bsdf.sample(wo, hit.ns, u, uc)?;
    let same_side = bs.wi.dot(hit.ng) * wo.dot(hit.ng) > 0.0;
    if same_side == bs.transmitted {
        return None;
    }
    let q = pm_color::mean(bs.weight).min(1.0);
    if !(q > 0.0) || s.next_1d() >= q {
        return None;
    }
    Some((bs, bs.weight / q))
}

/// Trace a map. `progress` is called after each batch with the photons stored so far.
pub fn trace(scene: &Scene, cfg: &TraceConfig, progress: &(dyn Fn(u64) + Sync)) -> Result<TracedMap, TraceError> {
    if scene.triangles.is_empty() {
        return Err(TraceError::NoSurfaces);
    }
    if cfg.range.is_some() && !matches!(cfg.budget, Budget::Emitted(_)) {
        return Err(TraceError::RangeNeedsFixedCount);
    }
    let targets = if cfg.pass == MapPass::Caustic { specular_targets(scene) } else { Vec::new() };
    let mut stats = MapStats { emitted_per_light: vec![0; scene.lights.len()], ..Default::default() };
    if cfg.pass == MapPass::Caustic && targets.is_empty() {
        return Ok(TracedMap { photons: Vec::new(), stats });
    }
    let (mut next, end, target) = match (cfg.budget, &cfg.range) {
        (Budget::Emitted(n), Some(r)) => (r.start.min(n), r.end.min(n), u64::MAX),
        (Budget::Emitted(n), None) => (0, n, u64::MAX),
        (Budget::Stored { target, cap }, _) => (0, cap, target),
    };
    let mut photons: Vec<(Photon, u32)> = Vec::new();
    let mut emitted_until = next;
    while next < end && (photons.len() as u64) < target {
        let batch_end = (next + BATCH).min(end);
        let chunks: Vec<(u64, u64)> =
            (next..batch_end).step_by(CHUNK as usize).map(|a| (a, (a + CHUNK).min(batch_end))).collect();
        let results: Vec<Vec<PathOut>> = chunks
            .par_iter()
            .map(|&(a, b)| {
                (a..b)
                    .map(|i| {
                        let mut out = PathOut::default();
                        trace_path(scene, cfg, &targets, i, &mut out);
                        out
                    })
                    .collect()
            })
            .collect();
        for path in results.into_iter().flatten() {
            if (photons.len() as u64) >= target {
                break; // the map was full before this path was emitted
            }
            emitted_until += 1;
            stats.emitted_per_light[path.light] += 1;
            stats.rays += path.rays;
            stats.truncated_paths += path.truncated as u64;
            photons.extend(path.photons);
        }
        next = batch_end;
        progress(photons.len() as u64);
    }
    let range_start = cfg.range.as_ref().map_or(0, |r| r.start);
    let n_emitted = match cfg.budget {
        Budget::Emitted(n) => n,
        Budget::Stored { .. } => emitted_until - range_start,
    };
    stats.emitted = n_emitted;
    stats.hit_cap = matches!(cfg.budget, Budget::Stored { target, .. } if (photons.len() as u64) < target);
    let photons: Vec<Photon> = photons
        .into_iter()
        .map(|(mut p, bounce)| {
            let b = bounce as usize;
            if stats.stored_per_bounce.len() <= b {
                stats.stored_per_bounce.resize(b + 1, 0);
            }
            stats.stored_per_bounce[b] += 1;
            p.power = scale_power(p.power, n_emitted);
            p
        })
        .collect();
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
