//! Unbiased path tracing (pbrt-v4 section 13.4): next-event estimation with the
//! power heuristic against BSDF sampling, and Russian roulette. The reference and
//! speed baseline for the photon-map renderer, over the same scene and BSDFs.

use crate::integrator::{Components, Counters, FirstHit, Integrator, VisibleSurface};
use glam::Vec3;
use pm_color::{Layer, Rgb};
use pm_light::{DirectLighting, power_heuristic};
use pm_sampling::Sampler;
use pm_scene::{Flights, FreeFlight, Scene};
use std::sync::atomic::Ordering::Relaxed;

/// The path tracer: needs the scene and its lights, no photon map.
pub struct PathTracer<'a> {
    light: DirectLighting<'a>,
    counters: Counters,
}

impl<'a> PathTracer<'a> {
    /// A path tracer for `scene`; fails when nothing in it emits.
    pub fn new(scene: &'a Scene) -> Result<Self, pm_light::LightSelectError> {
        Ok(PathTracer { light: DirectLighting::new(scene)?, counters: Counters::default() })
    }
}

impl Integrator for PathTracer<'_> {
    type Scratch = ();

    fn li(
        &self,
        o: Vec3,
        d: Vec3,
        first: FirstHit,
        s: &mut Sampler,
        _: &mut (),
        vs: Option<&mut VisibleSurface>,
    ) -> Components {
        path_radiance(&self.light, &self.counters, o, d, first, s, vs)
    }

    /// Every pixel takes all its samples, jittered: the estimate stays unbiased.
    fn adaptive(&self) -> bool {
        false
    }

    fn volume(&self) -> bool {
        self.light.scene.has_scattering_media()
    }

    fn counters(&self) -> &Counters {
        &self.counters
    }
}

/// Hard path-length limit; Russian roulette ends paths long before in physical
/// scenes. Paths cut here are counted.
const MAX_PATH: u32 = 1000;

// The layer a contribution belongs to is decided along the path the way the
// photon-map renderer splits its image: everything seen through a specular chain
// from the eye is specular; otherwise, at the first non-specular vertex D1,
// emission seen directly and light arriving at D1 straight from a light are
// direct, light arriving at D1 through specular bounces only is caustic, and
// anything that has been diffusely reflected twice is indirect. When D1 is a
// point in a medium (the eye ray scattered before reaching a surface), everything
// the path brings is the volume layer, as the photon-map renderer puts the light
// scattered along its eye rays there.

/// Radiance along the ray from `o` in direction `d` [W sr^-1 m^-2], split into the
/// renderer's component layers. In a scene with media the path carries the medium
/// it is in (from the eye's, [`Scene::eye_medium`]): free-flight sampling by
/// channel with the balance heuristic over channels ([`pm_scene::Medium::sample_distance`]),
/// next-event estimation at every scattering point and surface through media
/// (shadow rays attenuated, index-matched boundaries passed), the phase function
/// sampled and weighed against light sampling by the power heuristic as a BSDF is
/// (pbrt-v4 section 14.2). Index-matched boundaries are passed without a bounce.
fn path_radiance(
    light: &DirectLighting,
    counters: &Counters,
    o: Vec3,
    d: Vec3,
    first: FirstHit,
    s: &mut Sampler,
    mut vs: Option<&mut VisibleSurface>,
) -> Components {
    let scene = light.scene;
    let (mut o, mut d) = (o, d);
    let mut beta = Rgb::ONE;
    let mut l = Components::default();
    let mut prev_pdf = 0.0f32;
    // The last non-specular vertex (a surface or a point in a medium) and its normal
    // on the side light comes from (zero in a medium): light sampling's densities
    // depend on them. `travelled` is the distance from it along the current
    // direction to the current ray's origin (index-matched boundaries passed).
    let mut prev_p = o;
    let mut prev_n = Vec3::Z;
    let mut prev_specular = true;
    let mut travelled = 0.0f32;
    // Classification of emission found at the next hit, and the path's history.
    let mut emission_layer = Layer::Direct;
    let mut specular_before_d1 = false;
    let mut d1_in_medium = false;
    let mut n_diffuse = 0u32;
    let media = scene.has_media();
    let mut medium = scene.eye_medium(o);
    // In media: the path's flights (hero channel, density ratios); `w` is what
    // every contribution and the roulette weigh by (one without media).
    let mut flights = Flights::new(if media { s.next_1d() } else { 0.0 });
    let mut w = 1.0f32;
    let mut eye_ray = true;
    for depth in 0..MAX_PATH {
        let hit = if depth == 0 { first.resolve(scene, o, d) } else { scene.intersect(o, d, f32::INFINITY) };
        // The segment's medium: scatter inside it, or attenuate what lies beyond.
        if let Some(m) = scene.medium(medium).filter(|m| !m.is_clear()) {
            let t_seg = scene.segment_length(o, d, hit.as_ref());
            let u = if m.scatters() { s.next_1d() } else { 0.0 };
            let flight = flights.fly(m, t_seg, u);
            w = flights.weight();
            match flight {
                FreeFlight::Through { weight, .. } => beta *= weight,
                FreeFlight::Scatter { t, weight, .. } => {
                    beta *= weight;
                    eye_ray = false;
                    let p = o + d * t;
                    let wo = -d;
                    n_diffuse += 1;
                    d1_in_medium |= n_diffuse == 1;
                    let nee_layer =
                        volume_or(d1_in_medium, specular_before_d1, layer_of_light_at(specular_before_d1, n_diffuse));
                    l.add_to(nee_layer, beta * w * light.medium_sample(p, wo, &m.phase, medium, s, true));
                    let ps = m.phase.sample(wo, s.next_2d());
                    let sampled = layer_of_sampled(specular_before_d1, n_diffuse, false);
                    emission_layer = volume_or(d1_in_medium, specular_before_d1, sampled);
                    prev_pdf = ps.pdf;
                    prev_specular = false;
                    (prev_p, prev_n, travelled) = (p, Vec3::ZERO, 0.0);
                    if !roulette(&mut beta, w, depth, s) {
                        return l;
                    }
                    (o, d) = (p, ps.wi);
                    continue;
                }
            }
        }
        let Some(hit) = hit else {
            // Left the scene: the environment and sun discs, weighed against light
            // sampling like emission found on a surface.
            let le = scene.escaped(d);
            if le.max_element() > 0.0 {
                let mis =
                    if prev_specular { 1.0 } else { power_heuristic(prev_pdf, light.pdf_escaped(prev_p, prev_n, d)) };
                l.add_to(emission_layer, beta * w * le * mis);
            }
            return l;
        };
        if let Some(tint) = scene.index_matched(&hit) {
            // Straight through, into the medium beyond: no bounce.
            beta *= tint;
            medium = scene.medium_after(&hit, d, medium);
            let next = scene.offset_origin(hit.p, hit.ng, d);
            travelled += (next - o).dot(d);
            o = next;
            continue;
        }
        let wo = -d;
        let le = scene.emitted(&hit, wo);
        if le.max_element() > 0.0 {
            if prev_specular {
                l.add_to(emission_layer, beta * w * le);
            } else if let Some(p_l) = light.pdf_emitter(prev_p, hit.tri, d, travelled + hit.t) {
                l.add_to(emission_layer, beta * w * le * power_heuristic(prev_pdf, p_l));
            }
        }
        let bsdf = scene.bsdf(&hit);
        if eye_ray && let Some(v) = vs.as_deref_mut() {
            *v = VisibleSurface::at(scene, &hit, wo, bsdf, le);
        }
        let specular = bsdf.is_specular();
        if specular && n_diffuse == 0 {
            specular_before_d1 = true;
        }
        if !specular {
            n_diffuse += 1;
            // Next-event estimation, one light sample, MIS against BSDF sampling
            // (the BSDF-sampled continuation below picks up emission with its weight).
            let nee_layer =
                volume_or(d1_in_medium, specular_before_d1, layer_of_light_at(specular_before_d1, n_diffuse));
            let nee = beta * w * light.light_sample(&hit, &bsdf, wo, s, true, medium);
            l.add_to(nee_layer, nee);
            if eye_ray && let Some(v) = vs.as_deref_mut() {
                v.direct = nee;
            }
        }
        eye_ray = false;
        let u = s.next_2d();
        let uc = s.next_1d();
        let Some(bs) = bsdf.sample(wo, hit.ns, u, uc) else { return l };
        let same_side = bs.wi.dot(hit.ng) * wo.dot(hit.ng) > 0.0;
        if same_side == bs.transmitted {
            return l;
        }
        let sampled = layer_of_sampled(specular_before_d1, n_diffuse, specular);
        emission_layer = volume_or(d1_in_medium, specular_before_d1, sampled);
        beta *= bs.weight;
        prev_pdf = bs.pdf;
        prev_specular = bs.specular;
        if !roulette(&mut beta, w, depth, s) {
            return l;
        }
        (prev_p, prev_n, travelled) = (hit.p, pm_scene::facing(hit.ng, wo), 0.0);
        if media {
            medium = scene.medium_after(&hit, bs.wi, medium);
        }
        o = scene.offset_origin(hit.p, hit.ng, bs.wi);
        d = bs.wi;
    }
    counters.terminated_paths.fetch_add(1, Relaxed);
    l
}

/// The layer of emission found along a direction sampled at a vertex (a surface,
/// `specular` or not, or a point in a medium) after `n_diffuse` non-specular
/// vertices.
fn layer_of_sampled(specular_before_d1: bool, n_diffuse: u32, specular: bool) -> Layer {
    if specular_before_d1 {
        Layer::Specular
    } else if n_diffuse >= 2 {
        Layer::Indirect
    } else if specular {
        Layer::Caustic // D1, then specular bounces only
    } else {
        Layer::Direct // sampled from D1 itself
    }
}

/// `layer`, or the volume layer for a path whose first non-specular vertex is in a
/// medium (and not seen through a mirror or glass first).
#[inline]
fn volume_or(d1_in_medium: bool, specular_before_d1: bool, layer: Layer) -> Layer {
    if d1_in_medium && !specular_before_d1 && layer != Layer::Specular { Layer::Volume } else { layer }
}

/// The layer of light arriving at the path's `n_diffuse`-th non-specular vertex
/// (a surface or a point in a medium) straight from a light.
fn layer_of_light_at(specular_before_d1: bool, n_diffuse: u32) -> Layer {
    if specular_before_d1 {
        Layer::Specular
    } else if n_diffuse == 1 {
        Layer::Direct
    } else {
        Layer::Indirect
    }
}

/// Russian roulette after a few bounces (pbrt-v4): survive with probability equal
/// to the throughput's largest channel, so surviving paths keep a weight near 1. A
/// cap below 1 (as this code once had, 0.95) makes weights grow geometrically on
/// bright paths and the long tail is then undersampled: the albedo-0.99 furnace
/// came out 13% dark at 1024 spp. The throughput is `beta` times `w` (the spectral
/// MIS factor in media, one elsewhere). False when the path ends (or its weight is
/// not finite).
fn roulette(beta: &mut Rgb, w: f32, depth: u32, s: &mut Sampler) -> bool {
    if depth >= 3 {
        let q = beta.max_element() * w;
        if q < 1.0 {
            if !(q > 0.0) || s.next_1d() >= q {
                return false;
            }
            *beta /= q;
        }
    }
    beta.is_finite()
}
