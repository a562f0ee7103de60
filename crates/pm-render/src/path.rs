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
    let mut path = Path::new(scene, o, s);
    for depth in 0..MAX_PATH {
        let hit = if depth == 0 { first.resolve(scene, o, d) } else { scene.intersect(o, d, f32::INFINITY) };
        // The segment's medium: scatter inside it, or attenuate what lies beyond.
        if let Some(m) = scene.medium(path.medium).filter(|m| !m.is_clear()) {
            let t_seg = scene.segment_length(o, d, hit.as_ref());
            let u = if m.scatters() { s.next_1d() } else { 0.0 };
            let flight = path.flights.fly(m, t_seg, u);
            path.w = path.flights.weight();
            match flight {
                FreeFlight::Through { weight, .. } => path.beta *= weight,
                FreeFlight::Scatter { t, weight, .. } => {
                    path.beta *= weight;
                    let p = o + d * t;
                    match path.scatter(light, m, p, -d, depth, s) {
                        Some(wi) => (o, d) = (p, wi),
                        None => return path.l,
                    }
                    continue;
                }
            }
        }
        let Some(hit) = hit else {
            path.escape(light, d);
            return path.l;
        };
        if let Some(tint) = scene.index_matched(&hit) {
            // Straight through, into the medium beyond: no bounce.
            path.beta *= tint;
            path.medium = scene.medium_after(&hit, d, path.medium);
            let next = scene.offset_origin(hit.p, hit.ng, d);
            path.travelled += (next - o).dot(d);
            o = next;
            continue;
        }
        match path.surface(light, &hit, -d, depth, s, vs.as_deref_mut()) {
            Some(wi) => (o, d) = (scene.offset_origin(hit.p, hit.ng, wi), wi),
            None => return path.l,
        }
    }
    counters.terminated_paths.fetch_add(1, Relaxed);
    path.l
}

/// A path's state between its vertices: the throughput, what it has gathered, the
/// last non-specular vertex that light sampling's densities depend on, the history
/// that decides each contribution's layer, and the medium it is in.
struct Path {
    /// Throughput (without `w`).
    beta: Rgb,
    /// Radiance gathered so far, by layer.
    l: Components,
    /// Density of the last sampled direction (BSDF or phase function).
    prev_pdf: f32,
    /// The last non-specular vertex (a surface or a point in a medium) and its
    /// normal on the side light comes from (zero in a medium).
    prev_p: Vec3,
    prev_n: Vec3,
    /// Whether the last sampled direction was a specular one (no MIS).
    prev_specular: bool,
    /// Distance from `prev_p` along the current direction to the current ray's
    /// origin (index-matched boundaries passed).
    travelled: f32,
    /// The layer of emission found at the next hit.
    emission_layer: Layer,
    specular_before_d1: bool,
    d1_in_medium: bool,
    /// Non-specular vertices so far.
    n_diffuse: u32,
    medium: Option<pm_scene::MediumId>,
    /// In media: the path's flights (hero channel, density ratios); `w` is what
    /// every contribution and the roulette weigh by (one without media).
    flights: Flights,
    w: f32,
    /// The product of eta^2 over the refractions so far: Russian roulette weighs
    /// `beta` times it, so that radiance's 1 / eta^2 inside glass does not end
    /// paths there (pbrt-v4's etaScale).
    eta_scale: f32,
    /// Still on the eye ray (the visible surface is recorded there).
    eye_ray: bool,
}

impl Path {
    /// A path leaving the eye at `o`.
    fn new(scene: &Scene, o: Vec3, s: &mut Sampler) -> Path {
        Path {
            beta: Rgb::ONE,
            l: Components::default(),
            prev_pdf: 0.0,
            prev_p: o,
            prev_n: Vec3::Z,
            prev_specular: true,
            travelled: 0.0,
            emission_layer: Layer::Direct,
            specular_before_d1: false,
            d1_in_medium: false,
            n_diffuse: 0,
            medium: scene.eye_medium(o),
            flights: Flights::new(if scene.has_media() { s.next_1d() } else { 0.0 }),
            w: 1.0,
            eta_scale: 1.0,
            eye_ray: true,
        }
    }

    /// The layer of light arriving straight from a light at the current
    /// non-specular vertex.
    fn nee_layer(&self) -> Layer {
        volume_or(
            self.d1_in_medium,
            self.specular_before_d1,
            layer_of_light_at(self.specular_before_d1, self.n_diffuse),
        )
    }

    /// A scattering event at `p` in medium `m`, light arriving toward `wo`:
    /// next-event estimation, then the phase function sampled. The new direction,
    /// or `None` when the path ends.
    fn scatter(
        &mut self,
        light: &DirectLighting,
        m: &pm_scene::Medium,
        p: Vec3,
        wo: Vec3,
        depth: u32,
        s: &mut Sampler,
    ) -> Option<Vec3> {
        self.eye_ray = false;
        self.n_diffuse += 1;
        self.d1_in_medium |= self.n_diffuse == 1;
        let nee_layer = self.nee_layer();
        self.l.add_to(nee_layer, self.beta * self.w * light.medium_sample(p, wo, &m.phase, self.medium, s, true));
        let ps = m.phase.sample(wo, s.next_2d());
        let sampled = layer_of_sampled(self.specular_before_d1, self.n_diffuse, false);
        self.emission_layer = volume_or(self.d1_in_medium, self.specular_before_d1, sampled);
        self.prev_pdf = ps.pdf;
        self.prev_specular = false;
        (self.prev_p, self.prev_n, self.travelled) = (p, Vec3::ZERO, 0.0);
        roulette(&mut self.beta, self.w * self.eta_scale, depth, s).then_some(ps.wi)
    }

    /// The path left the scene along `d`: the environment and sun discs, weighed
    /// against light sampling like emission found on a surface.
    fn escape(&mut self, light: &DirectLighting, d: Vec3) {
        let le = light.scene.escaped(d);
        if le.max_element() > 0.0 {
            let mis = if self.prev_specular {
                1.0
            } else {
                power_heuristic(self.prev_pdf, light.pdf_escaped(self.prev_p, self.prev_n, d))
            };
            self.l.add_to(self.emission_layer, self.beta * self.w * le * mis);
        }
    }

    /// A surface hit seen from `wo`: its emission (weighed against light
    /// sampling), next-event estimation at a non-specular one, then the BSDF
    /// sampled. The new direction, or `None` when the path ends.
    fn surface(
        &mut self,
        light: &DirectLighting,
        hit: &pm_scene::Hit,
        wo: Vec3,
        depth: u32,
        s: &mut Sampler,
        mut vs: Option<&mut VisibleSurface>,
    ) -> Option<Vec3> {
        let scene = light.scene;
        let le = scene.emitted(hit, wo);
        if le.max_element() > 0.0 {
            if self.prev_specular {
                self.l.add_to(self.emission_layer, self.beta * self.w * le);
            } else if let Some(p_l) = light.pdf_emitter(self.prev_p, self.prev_n, hit.tri, -wo, self.travelled + hit.t)
            {
                self.l.add_to(self.emission_layer, self.beta * self.w * le * power_heuristic(self.prev_pdf, p_l));
            }
        }
        let bsdf = scene.bsdf(hit);
        if self.eye_ray
            && let Some(v) = vs.as_deref_mut()
        {
            *v = VisibleSurface::at(scene, hit, wo, bsdf, le);
        }
        let specular = bsdf.is_specular();
        if specular && self.n_diffuse == 0 {
            self.specular_before_d1 = true;
        }
        if !specular {
            self.n_diffuse += 1;
            // Next-event estimation, one light sample, MIS against BSDF sampling
            // (the BSDF-sampled continuation picks up emission with its weight).
            let nee = self.beta * self.w * light.light_sample(hit, &bsdf, wo, s, true, self.medium);
            self.l.add_to(self.nee_layer(), nee);
            if self.eye_ray
                && let Some(v) = vs
            {
                v.direct = nee;
            }
        }
        self.eye_ray = false;
        let u = s.next_2d();
        let uc = s.next_1d();
        let bs = bsdf.sample(wo, hit.ns, u, uc)?;
        let same_side = pm_scene::same_side(hit.ng, bs.wi, wo);
        if same_side == bs.transmitted {
            return None;
        }
        let sampled = layer_of_sampled(self.specular_before_d1, self.n_diffuse, specular);
        self.emission_layer = volume_or(self.d1_in_medium, self.specular_before_d1, sampled);
        self.beta *= bs.radiance_weight();
        self.eta_scale *= bs.eta * bs.eta;
        self.prev_pdf = bs.pdf;
        self.prev_specular = bs.specular;
        if !roulette(&mut self.beta, self.w * self.eta_scale, depth, s) {
            return None;
        }
        (self.prev_p, self.prev_n, self.travelled) = (hit.p, pm_scene::facing(hit.ng, wo), 0.0);
        if scene.has_media() {
            self.medium = scene.medium_after(hit, bs.wi, self.medium);
        }
        Some(bs.wi)
    }
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
/// MIS factor in media, one elsewhere; bidirectional path tracing folds in its
/// subpaths' eta^2 and their start's throughput there). `depth` counts vertices
/// from the path's start. False when the path ends (or its weight is not finite).
pub fn roulette(beta: &mut Rgb, w: f32, depth: u32, s: &mut Sampler) -> bool {
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
