//! Light scattered in participating media along the photon-map integrator's rays
//! (Jensen and Christensen 1998): along eye rays (and their specular recursion),
//! single scattering from the lights (pm-light, equiangular) plus multiple
//! scattering from the volume map; along final-gather rays, every volume photon.

use super::PhotonMapping;
use super::scratch::Scratch;
use crate::VolumeEstimate;
use glam::Vec3;
use pm_color::Rgb;
use pm_estimate::{Filter, KnnParams};
use pm_format::PhotonRecord;
use pm_sampling::Sampler;
use pm_scene::{Medium, MediumId};

/// Radiance [W sr^-1 m^-2 per channel] scattered toward `o` along the segment
/// from `o` in unit direction `d` of `t` metres inside medium `medium` (`m`): single
/// scattering from the lights and the volume map's multiple scattering.
#[allow(clippy::too_many_arguments)]
pub(crate) fn eye_inscattered<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    o: Vec3,
    d: Vec3,
    t: f32,
    medium: Option<MediumId>,
    m: &Medium,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    let single = ctx.light.single_scattering(o, d, t, medium, s, ctx.cfg.volume_light_samples);
    single + multiple(ctx, o, d, t, m, false, s, scratch)
}

/// The light [W sr^-1 m^-2 per channel] scattered toward `o` along a final-gather
/// ray's segment from `o` in unit direction `d` of `t` metres in medium `m`, from
/// every volume photon: with precomputed lookups ([`crate::Lookup::Precomputed`]),
/// a march reading the nearest photon's precomputed in-scattering (Christensen
/// 1999's idea in a volume: on the volumetric caustic's gathers the beam
/// estimate crossed thousands of photon spheres per ray); with exact ones, the
/// eye rays' estimate ([`multiple`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn gathered<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    o: Vec3,
    d: Vec3,
    t: f32,
    m: &Medium,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    let Some(vm) = &ctx.maps.volume else { return Rgb::ZERO };
    let cfg = &ctx.cfg;
    if cfg.lookup != crate::Lookup::Precomputed || vm.inscattering.values.is_empty() {
        return multiple(ctx, o, d, t, m, true, s, scratch);
    }
    let max_d2 = cfg.max_radius_volume * cfg.max_radius_volume;
    let u = s.next_1d();
    pm_estimate::precomputed_march(&vm.tree, &vm.inscattering, o, d, t, m.sigma_t(), u, max_d2, &mut scratch.rejected)
}

/// The volume map's estimate [W sr^-1 m^-2 per channel] of the light scattered
/// toward `o` along the segment (medium `m`): the beam estimate or a ray march,
/// counting every photon (`all`, final-gather rays) or all but the ones scattered
/// straight from a light (eye rays, which take those from the lights). Zero
/// without a volume map.
#[allow(clippy::too_many_arguments)]
pub(crate) fn multiple<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    o: Vec3,
    d: Vec3,
    t: f32,
    m: &Medium,
    all: bool,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    let Some(vm) = &ctx.maps.volume else { return Rgb::ZERO };
    let cfg = &ctx.cfg;
    let phase = |wi: Vec3| m.phase.p(-d, wi);
    match cfg.volume_estimate {
        VolumeEstimate::Beam => {
            let spheres = if all { &vm.all } else { &vm.multiple };
            pm_estimate::beam(vm.tree.nodes(), spheres, o, d, t, m.sigma_t(), &mut scratch.stack, phase)
        }
        VolumeEstimate::RayMarch => {
            let p = KnnParams {
                k: cfg.volume_k,
                max_d2: cfg.max_radius_volume * cfg.max_radius_volume,
                filter: Filter::None,
            };
            let u = s.next_1d();
            pm_estimate::ray_march(&vm.tree, o, d, t, m.sigma_t(), cfg.volume_step, u, all, &p, &mut scratch.knn, phase)
        }
    }
}
