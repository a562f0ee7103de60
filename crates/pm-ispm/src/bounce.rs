//! The photons of an image-space frame (McGuire and Luebke 2009): per light a
//! *bounce map* (section 4.2: the first bounce of a regular grid of directions,
//! found by the rasteriser from the light's point of view like the paper's
//! light-space G-buffer, scattered by BSDF importance sampling and Russian roulette
//! per texel), then the remaining bounces traced (section 4.3, storing photons with
//! the kernel shape their path density gives).
//!
//! Units: power W per RGB channel, radiance W sr^-1 m^-2, lengths m.

use crate::IspmParams;
use crate::splat::VolumePhoton;
use glam::Vec3;
use pm_color::Rgb;
use pm_photon::{Carrier, Landing};
use pm_photon::{Photon, flags, volume_photon};
use pm_raster::{self, Fragment};
use pm_render::Film;
use pm_sampling::Sampler;
use pm_scene::{Camera, Flights, LightKind, MediumId, Scene};
use rayon::prelude::*;

/// Scattering events a photon path may take after its first bounce before it is cut
/// (specular chains store nothing, so they need a bound of their own).
const MAX_EVENTS: u32 = 32;

/// A photon leaving its first bounce: an entry of a bounce map (Table 1). The
/// first bounce is a surface's, or in a scattering medium a point of the medium
/// where the photon scattered on its way from the light.
#[derive(Clone, Copy, Debug)]
pub struct BouncePhoton {
    /// Where it leaves from (offset off the surface) \[m\].
    pub origin: Vec3,
    /// Unit direction it travels.
    pub dir: Vec3,
    /// Its power [W per channel] ([`Carrier::power`]), medium and flights.
    pub carrier: Carrier,
    /// Path density estimate ρ_p so far (section 4.3).
    pub density: f32,
    /// True when the first bounce was specular (a caustic path so far).
    pub specular: bool,
}

/// The bounce maps of every light ([`bounce_maps`]).
#[derive(Clone, Debug, Default)]
pub struct BounceMaps {
    /// The photons leaving their first bounce, in light and texel order.
    pub photons: Vec<BouncePhoton>,
    /// The photons' first events in scattering media, as volume photons
    /// ([`flags::VOLUME`] and [`flags::DIRECT`]: single scattering, which the
    /// frame takes from the lights; their density sizes the beam estimate's
    /// spheres). Empty without scattering media.
    pub volume: Vec<Photon>,
    /// What building them did.
    pub stats: BounceStats,
}

/// What [`trace`] stores: photons on surfaces, with their kernels, and photons
/// in scattering media.
#[derive(Clone, Debug, Default)]
pub struct Traced {
    /// The surface photons, in bounce-map order.
    pub photons: Vec<VolumePhoton>,
    /// The photons scattered in media ([`flags::VOLUME`]), the bounce maps' first
    /// ones before the rest (empty without scattering media).
    pub volume: Vec<Photon>,
}

/// What building the bounce maps did (Figure 10's attrition, and the power test).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct BounceStats {
    /// Texels (directions) emitted, all lights.
    pub texels: u64,
    /// Texels whose direction hits the scene.
    pub hits: u64,
    /// Texels whose photon survived the first bounce's Russian roulette.
    pub survived: u64,
    /// Power reaching the first surfaces [W per channel].
    #[serde(serialize_with = "rgb_array")]
    pub incident: Rgb,
    /// Power leaving them in the bounce map [W per channel].
    #[serde(serialize_with = "rgb_array")]
    pub outgoing: Rgb,
}

fn rgb_array<S: serde::Serializer>(v: &Rgb, s: S) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&v.to_array(), s)
}

/// The image-space method's Russian roulette: the paper's spectral balance by
/// the channels' mean (appendix A, step 2(d); [`pm_photon::Roulette`] says why
/// this method keeps it).
const ROULETTE: pm_photon::Roulette = pm_photon::Roulette::ChannelMean;

/// Path density factor of one scattering event (section 4.3): ρ/1000 for a
/// Lambertian sample, ρ for mirror reflection or refraction, with ρ the
/// probability the photon survived the event's Russian roulette ([`ROULETTE`]
/// of the sample's weight, its albedo). A glossy sample's factor is the Lambertian one times
/// how much more concentrated its lobe is, π pdf (the pdf ratio of Herzog et al.'s
/// path density, about 1 for a cosine lobe), from 1 up to the paper's ρ/10 at 100:
/// the paper's ρ/10 for every glossy sample gave the rough (alpha 1) specular layer
/// of Blender's Principled BSDF volumes of a tenth of the diffuse ones' area, bright
/// dots all over a Blender room's walls.
fn density_factor(bs: &pm_bsdf::BsdfSample) -> f32 {
    let rho = ROULETTE.survival(bs.weight).max(1e-6);
    match bs.lobe {
        pm_bsdf::Lobe::Diffuse => rho / 1000.0,
        pm_bsdf::Lobe::Glossy => glossy_density(rho, bs.pdf),
        pm_bsdf::Lobe::Specular => rho,
    }
}

/// The density factor of a lobe of albedo `rho` whose sample had pdf `pdf`
/// \[sr^-1\]: the Lambertian ρ / 1000 times π pdf, from 1 up to 100.
fn glossy_density(rho: f32, pdf: f32) -> f32 {
    rho / 1000.0 * (std::f32::consts::PI * pdf).clamp(1.0, 100.0)
}

/// The density factor of scattering in medium `m` from `wo` to `wi` (both away
/// from the point): a glossy lobe's ([`glossy_density`]) with the medium's
/// single-scattering albedo and the phase function's value as its pdf, so an
/// isotropic medium spreads its paths like a Lambertian surface.
fn medium_density_factor(m: &pm_scene::Medium, wo: Vec3, wi: Vec3) -> f32 {
    glossy_density(ROULETTE.survival(m.albedo()).max(1e-6), m.phase.p(wo, wi))
}

/// Exact solid angle [sr] of the rectangle [u0, u1] x [v0, v1] of the plane at unit
/// distance (a cube-map texel).
fn rect_solid_angle(u0: f32, u1: f32, v0: f32, v1: f32) -> f32 {
    let f = |u: f32, v: f32| (u * v / (1.0 + u * u + v * v).sqrt()).atan();
    f(u1, v1) - f(u0, v1) - f(u1, v0) + f(u0, v0)
}

/// One texel's photon leaving the light: where from, its direction, its power
/// as emitted [W per channel], its first hit (the rasteriser's or the BVH's) and
/// the medium it starts in.
struct Arrival {
    origin: Vec3,
    dir: Vec3,
    power: Rgb,
    first: Option<pm_scene::Hit>,
    medium: Option<MediumId>,
}

impl Arrival {
    /// Its first event: without scattering media, its first surface through
    /// index-matched boundaries, attenuated on the way (Beer-Lambert) and no
    /// number drawn from `s`; with them, the free flights of the photon tracer
    /// ([`Carrier::fly`]: it may scatter in a medium before reaching a surface).
    fn land<'s>(&self, scene: &'s Scene, s: &mut Sampler) -> (Carrier, Landing<'s>) {
        if !scene.has_scattering_media() {
            let pass = scene.pass_from(self.origin, self.dir, self.first, self.medium);
            let carrier = Carrier { phi: self.power * pass.tr, medium: pass.medium, flights: Flights::new(0.0) };
            return (carrier, pass.hit.map_or(Landing::Escaped, Landing::Surface));
        }
        let mut carrier = Carrier { phi: self.power, medium: self.medium, flights: Flights::new(s.next_1d()) };
        let mut o = self.origin;
        for _ in 0..MAX_EVENTS {
            match carrier.fly(scene, o, self.dir, s) {
                Landing::Passed { o: beyond } => o = beyond,
                landing => return (carrier, landing),
            }
        }
        (carrier, Landing::Escaped)
    }
}

/// The first hits of light `li`'s `res` x `res`-per-face directions with their power
/// (section 4.2). Point and spot lights: a cube map drawn by the rasteriser, each
/// texel carrying I(ω) times its exact solid angle (spot lights then rescaled to the
/// light's power: the paper's round-off correction). Directional, area and
/// environment lights (which have no centre of projection): as many stratified
/// emission samples (Sobol') traced through the BVH, each carrying Φ / n (an
/// environment's photons start on the bounding sphere's disc, so the bounce map's
/// power stays exact; those that miss the scene carry theirs away). In media a
/// photon's power is attenuated on its way (Beer-Lambert, through index-matched
/// boundaries), and in scattering media it may scatter ([`Arrival::land`]).
fn arrivals(scene: &Scene, li: usize, res: u32, seed: u64) -> Vec<Arrival> {
    let light = &scene.lights[li];
    let medium = scene.light_medium(li);
    match light.kind {
        LightKind::Point { position, intensity } => cube_arrivals(scene, position, medium, res, |_| intensity),
        LightKind::Spot { position, direction, intensity, cos_inner, cos_outer } => {
            let mut v = cube_arrivals(scene, position, medium, res, |d| {
                intensity * pm_scene::spot_falloff(d.dot(direction), cos_inner, cos_outer)
            });
            let sum: Rgb = v.iter().map(|a| a.power).sum();
            let scale = light.power / sum.max(Rgb::splat(f32::MIN_POSITIVE));
            for a in &mut v {
                a.power *= scale;
            }
            v
        }
        LightKind::Directional { .. } | LightKind::Area { .. } | LightKind::Environment { .. } => {
            let n = 6 * (res as usize) * (res as usize);
            (0..n)
                .into_par_iter()
                .with_min_len(256)
                .map(|k| {
                    let mut s = Sampler::new(pm_sampling::mix64(seed ^ 0x626f_756e_6365 ^ li as u64), k as u64);
                    match light.sample_emission(scene, &mut s) {
                        Some(ray) => {
                            let first = scene.intersect(ray.origin, ray.dir, f32::INFINITY);
                            Arrival { origin: ray.origin, dir: ray.dir, power: ray.power / n as f32, first, medium }
                        }
                        None => Arrival { origin: Vec3::ZERO, dir: Vec3::Z, power: Rgb::ZERO, first: None, medium },
                    }
                })
                .collect()
        }
    }
}

/// The texels of a cube map around `position` (in `medium`), face by face, row by
/// row.
fn cube_arrivals(
    scene: &Scene,
    position: Vec3,
    medium: Option<MediumId>,
    res: u32,
    intensity: impl Fn(Vec3) -> Rgb + Sync,
) -> Vec<Arrival> {
    let film = Film { width: res, height: res, spp: 1, contrast: 0.0, seed: 0, pixel_centres: false };
    let mut frags: Vec<Option<Fragment>> = Vec::new();
    let mut out = Vec::with_capacity(6 * (res * res) as usize);
    let step = 2.0 / res as f32;
    // Texel (x, y) has the same solid angle on every face: computed once (four atan
    // each, a third of a point light's bounce map when done per face).
    let omega: Vec<f32> = (0..res * res)
        .into_par_iter()
        .with_min_len(1024)
        .map(|j| {
            let (x, y) = ((j % res) as f32, (j / res) as f32);
            let (u0, v1) = (x * step - 1.0, 1.0 - y * step);
            rect_solid_angle(u0, u0 + step, v1 - step, v1)
        })
        .collect();
    for &(forward, right, up) in &pm_raster::CUBE_FACES {
        let cam = Camera { position, forward, up, right, yfov: std::f32::consts::FRAC_PI_2, aspect: Some(1.0) };
        pm_raster::first_hits_into(scene, &cam, film.size(), film.rect(), &mut frags);
        out.par_extend(frags.par_iter().enumerate().with_min_len(256).map(|(j, f)| {
            let (x, y) = ((j as u32 % res) as f32, (j as u32 / res) as f32);
            let (u0, v1) = (x * step - 1.0, 1.0 - y * step);
            let v0 = v1 - step;
            let dir = (forward + right * (u0 + 0.5 * step) + up * (v0 + 0.5 * step)).normalize();
            let power = intensity(dir) * omega[j];
            Arrival { origin: position, dir, power, first: f.map(|f| f.hit(scene)), medium }
        }));
    }
    out
}

/// The bounce maps of every light: the photons leaving their first surface, in
/// light and texel order (deterministic: texel k of light l draws from its own
/// stream, so a static light gives the same bounce map every frame, as the paper's
/// seeding by light position and texel does).
pub fn bounce_maps(scene: &Scene, res: u32, seed: u64, caustics: bool) -> BounceMaps {
    let mut out = BounceMaps::default();
    // Nothing emits: no bounce map.
    let Ok(selector) = pm_light::LightSelector::new(scene, &[]) else { return out };
    for li in 0..scene.lights.len() {
        // Texels in proportion to the light's share of the power (section 4.2), the
        // share the photon tracer and light sampling also use.
        let share = selector.probs[li] as f32;
        if !(share > 0.0) {
            continue;
        }
        let r = ((res as f32 * (share * scene.lights.len() as f32).sqrt()).round() as u32).clamp(4, res.max(4) * 4);
        let arrivals = arrivals(scene, li, r, seed);
        out.stats.texels += arrivals.len() as u64;
        let bounced: Vec<FirstBounce> = arrivals
            .par_iter()
            .enumerate()
            .with_min_len(256)
            .map(|(k, a)| {
                let mut s = Sampler::hashed(seed ^ li as u64, 0x6d61_7000_0000 ^ k as u64);
                first_bounce(scene, a, caustics, &mut s)
            })
            .collect();
        for b in bounced {
            let Some(incident) = b.incident else { continue };
            out.stats.hits += 1;
            out.stats.incident += incident;
            out.volume.extend(b.volume);
            if let Some(b) = b.photon {
                out.stats.survived += 1;
                out.stats.outgoing += b.carrier.power();
                out.photons.push(b);
            }
        }
    }
    out
}

/// What one texel's photon did at its first event.
struct FirstBounce {
    /// The power reaching it [W per channel]; `None` when it left the scene.
    incident: Option<Rgb>,
    /// The volume photon it left where that event was in a medium.
    volume: Option<Photon>,
    /// The photon leaving it, if it survived.
    photon: Option<BouncePhoton>,
}

/// The first event of arrival `a` ([`Arrival::land`]) and the photon leaving it:
/// scattered by the surface's BSDF (a specular bounce only when `caustics`) or
/// the medium's phase function, with Russian roulette.
fn first_bounce(scene: &Scene, a: &Arrival, caustics: bool, s: &mut Sampler) -> FirstBounce {
    let (mut carrier, landing) = a.land(scene, s);
    let wo = -a.dir;
    match landing {
        Landing::Surface(hit) => {
            let incident = Some(carrier.power());
            let bsdf = scene.bsdf(&hit);
            let photon = pm_photon::scatter(&bsdf, &hit, wo, ROULETTE, s)
                .filter(|(bs, _)| caustics || !bs.specular)
                .map(|(bs, factor)| {
                    carrier.phi *= factor;
                    carrier.leave(scene, &hit, bs.wi);
                    BouncePhoton {
                        origin: scene.offset_origin(hit.p, hit.ng, bs.wi),
                        dir: bs.wi,
                        carrier,
                        density: density_factor(&bs),
                        specular: bs.specular,
                    }
                });
            FirstBounce { incident, volume: None, photon }
        }
        Landing::Scattered { p, medium } => {
            let power = carrier.power();
            let volume = Some(volume_photon(p, wo, power, flags::DIRECT));
            let photon = carrier.scatter_in(medium, wo, ROULETTE, s).map(|wi| BouncePhoton {
                origin: p,
                dir: wi,
                carrier,
                density: medium_density_factor(medium, wo, wi),
                specular: false,
            });
            FirstBounce { incident: Some(power), volume, photon }
        }
        Landing::Escaped | Landing::Passed { .. } => FirstBounce { incident: None, volume: None, photon: None },
    }
}

/// The kernel shape of a path of density ρ_p (section 4.3): radius r1 / sqrt(ρ_p)
/// in the surface plane, so a path a thousand times less likely gets a kernel of a
/// thousand times the area, clamped to [r_min, r_max]; r_z = minor × r_xy.
#[derive(Clone, Copy, Debug)]
pub struct KernelShape {
    /// Radius of a path of density 1 \[m\].
    pub r1: f32,
    /// Smallest radius \[m\].
    pub r_min: f32,
    /// Largest radius \[m\].
    pub r_max: f32,
    /// r_z / r_xy.
    pub minor: f32,
    /// Divide each photon's power by its disc's coverage ([`pm_render::disc_coverage`]).
    pub coverage: bool,
}

impl KernelShape {
    /// The shape from the parameters, for a scene of diagonal `diag` \[m\].
    pub fn new(p: &IspmParams, diag: f32) -> KernelShape {
        let r_max = p.kernel_max_rel_diag * diag;
        KernelShape {
            r1: p.kernel_radius_rel_diag * diag,
            r_min: (p.kernel_min_rel_diag * diag).min(r_max),
            r_max,
            minor: p.kernel_minor,
            coverage: p.volume_coverage,
        }
    }

    /// (r_xy, r_z) \[m\] for path density `density`, of a photon under a cover or
    /// not (`covered`, [`pm_render::covered`]: another surface faces it from
    /// closer than a hundredth of the diagonal). A photon under a cover gets the
    /// smallest radius: the light in a gap is its own (the batch pipeline keeps
    /// such photons apart for the same reason), and the ceiling's photons in the
    /// 2-7 mm gap above a lamp, spread by volumes of 6% of the diagonal, lit the
    /// ceiling around the lamp 80% too bright in 8 x 8 blocks (the differential
    /// checker's seed 23897, scene 0).
    pub fn radii(&self, density: f32, covered: bool) -> (f32, f32) {
        let r = if covered { self.r_min } else { (self.r1 / density.max(1e-30).sqrt()).clamp(self.r_min, self.r_max) };
        (r, r * self.minor)
    }
}

/// Trace the bounce-map photons on (section 4.3): at every non-specular hit store
/// a photon (power, incident direction, the surface's normal on the arriving side,
/// the kernel from the path's density), up to `stored` photons per path; scatter by
/// the shared photon-tracing step. In scattering media the photons fly as the
/// photon tracer's do ([`Carrier::fly`]) and every point they scatter at is a
/// volume photon besides. Photons are in bounce-map order.
pub fn trace(scene: &Scene, maps: &BounceMaps, stored: u32, kernel: &KernelShape, seed: u64) -> Traced {
    let paths: Vec<Traced> = maps
        .photons
        .par_iter()
        .enumerate()
        .with_min_len(64)
        .map(|(i, b)| {
            let mut out = Traced::default();
            let mut s = Sampler::hashed(seed, 0x7472_6163_6500 ^ i as u64);
            let (mut o, mut d, mut density, mut caustic) = (b.origin, b.dir, b.density, b.specular);
            let mut c = b.carrier;
            for _ in 0..MAX_EVENTS {
                if out.photons.len() as u32 >= stored || !pm_color::is_valid(c.phi) || c.phi == Rgb::ZERO {
                    break;
                }
                let wo = -d;
                let hit = match c.fly(scene, o, d, &mut s) {
                    Landing::Surface(hit) => hit,
                    Landing::Passed { o: beyond } => {
                        o = beyond;
                        continue;
                    }
                    Landing::Scattered { p, medium } => {
                        let extra = if caustic { flags::CAUSTIC } else { 0 };
                        out.volume.push(volume_photon(p, wo, c.power(), extra));
                        let Some(wi) = c.scatter_in(medium, wo, ROULETTE, &mut s) else { break };
                        density *= medium_density_factor(medium, wo, wi);
                        caustic = false;
                        (o, d) = (p, wi);
                        continue;
                    }
                    Landing::Escaped => break,
                };
                let bsdf = scene.bsdf(&hit);
                if !bsdf.is_specular() {
                    // The kernel is compressed along the shading normal: on a
                    // tessellated curved surface the facet's own normal tilts the
                    // neighbouring facets' points out of the thin kernel (the furnace
                    // sphere lost 13% of its indirect light that way).
                    let n = pm_render::facing(hit.ns, wo);
                    let under_cover = pm_render::covered(scene, hit.p, n);
                    let (r_xy, r_z) = kernel.radii(density, under_cover);
                    // The cone kernel's weight 1 - t over its disc.
                    let covered = if kernel.coverage {
                        pm_render::disc_coverage(scene, hit.p, n, r_xy, pm_render::Probe::Slab(r_z), |t| 1.0 - t)
                            .max(pm_render::MIN_COVERAGE)
                    } else {
                        1.0
                    };
                    out.photons.push(VolumePhoton {
                        p: hit.p,
                        n,
                        wi: wo,
                        power: c.power() / (scene.store_probability(&hit) * covered),
                        r_xy,
                        r_z,
                        caustic,
                        covered: under_cover,
                    });
                }
                let Some((bs, factor)) = pm_photon::scatter(&bsdf, &hit, wo, ROULETTE, &mut s) else { break };
                c.phi *= factor;
                c.leave(scene, &hit, bs.wi);
                density *= density_factor(&bs);
                caustic &= bs.specular;
                o = scene.offset_origin(hit.p, hit.ng, bs.wi);
                d = bs.wi;
            }
            out
        })
        .collect();
    let mut all = Traced { photons: Vec::new(), volume: maps.volume.clone() };
    for t in paths {
        all.photons.extend(t.photons);
        all.volume.extend(t.volume);
    }
    all
}
