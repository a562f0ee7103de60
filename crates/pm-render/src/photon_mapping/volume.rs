//! Light scattered in participating media along the photon-map integrator's rays
//! (Jensen and Christensen 1998): along eye rays (and their specular recursion),
//! single scattering from the lights (pm-light, equiangular) plus multiple
//! scattering from the volume map; along final-gather rays, every volume photon.

use super::PhotonMapping;
use super::scratch::Scratch;
use crate::VolumeEstimate;
use glam::Vec3;
use pm_color::Rgb;
use pm_estimate::{Filter, KnnParams, Segment, Steps};
use pm_format::PhotonRecord;
use pm_sampling::Sampler;
use pm_scene::{Medium, MediumId};

/// Radiance [W sr^-1 m^-2 per channel] scattered toward `seg.o` along an eye
/// ray's segment inside medium `medium` (`m`, whose extinction `seg` carries):
/// single scattering from the lights and the volume map's multiple scattering.
pub(crate) fn eye_inscattered<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    seg: &Segment,
    medium: Option<MediumId>,
    m: &Medium,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    let single = ctx.light.single_scattering(seg.o, seg.d, seg.t_max, medium, s, ctx.cfg.volume_light_samples);
    single + multiple(ctx, seg, m, false, s, scratch)
}

/// The light [W sr^-1 m^-2 per channel] scattered toward `seg.o` along a
/// final-gather ray's segment in medium `m`, from
/// every volume photon: with precomputed lookups ([`crate::Lookup::Precomputed`]),
/// a march reading the nearest photon's precomputed in-scattering (Christensen
/// 1999's idea in a volume: on the volumetric caustic's gathers the beam
/// estimate crossed thousands of photon spheres per ray); with exact ones, the
/// eye rays' estimate ([`multiple`]).
pub(crate) fn gathered<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    seg: &Segment,
    m: &Medium,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    let Some(vm) = &ctx.maps.volume else { return Rgb::ZERO };
    let cfg = &ctx.cfg;
    if cfg.lookup != crate::Lookup::Precomputed || vm.inscattering.values.is_empty() {
        return multiple(ctx, seg, m, true, s, scratch);
    }
    let max_d2 = cfg.max_radius_volume * cfg.max_radius_volume;
    let u = s.next_1d();
    pm_estimate::precomputed_march(&vm.tree, &vm.inscattering, seg, m.phase.g, u, max_d2, &mut scratch.rejected)
}

/// The volume map's estimate [W sr^-1 m^-2 per channel] of the light scattered
/// toward `seg.o` along the segment (medium `m`): the beam estimate or a ray march,
/// counting every photon (`all`, final-gather rays) or all but the ones scattered
/// straight from a light (eye rays, which take those from the lights). Zero
/// without a volume map.
pub(crate) fn multiple<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    seg: &Segment,
    m: &Medium,
    all: bool,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    let Some(vm) = &ctx.maps.volume else { return Rgb::ZERO };
    let cfg = &ctx.cfg;
    let phase = |wi: Vec3| m.phase.p(-seg.d, wi);
    match cfg.volume_estimate {
        VolumeEstimate::Beam => {
            let spheres = if all { &vm.all } else { &vm.multiple };
            pm_estimate::beam(vm.tree.nodes(), spheres, seg, &mut scratch.stack, phase)
        }
        VolumeEstimate::RayMarch => {
            let p = KnnParams {
                k: cfg.volume_k,
                max_d2: cfg.max_radius_volume * cfg.max_radius_volume,
                filter: Filter::None,
            };
            let steps = Steps { step: cfg.volume_step, u: s.next_1d() };
            pm_estimate::ray_march(&vm.tree, seg, steps, &p, all, &mut scratch.knn, phase)
        }
    }
}
