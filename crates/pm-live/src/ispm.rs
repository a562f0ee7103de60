//! Image-space photon mapping (McGuire and Luebke 2009) on the CPU: per light a
//! *bounce map* (section 4.2: the first bounce of a regular grid of directions,
//! found by the rasteriser from the light's point of view like the paper's
//! light-space G-buffer, scattered by BSDF importance sampling and Russian roulette
//! per texel), the remaining bounces traced (section 4.3, storing photons with the
//! kernel shape their path density gives), the eye G-buffer with direct light by
//! shadow rays or shadow maps, and indirect light by splatting photon volumes over
//! it (section 5, [`crate::splat`]).
//!
//! Units: power W per RGB channel, radiance W sr^-1 m^-2, lengths m.

use crate::splat::{self, GBuffer, PhotonIndex, Seen, SplatOutput, Surface, VolumePhoton};
use crate::{LiveParams, LiveShading};
use glam::Vec3;
use pm_color::Rgb;
use pm_raster::{self, Fragment};
use pm_render::{Film, FrameBuffers, Visibility};
use pm_sampling::Sampler;
use pm_scene::{Camera, LightKind, Scene};
use rayon::prelude::*;
use std::f32::consts::PI;
use std::time::Instant;

/// Scattering events a photon path may take after its first bounce before it is cut
/// (specular chains store nothing, so they need a bound of their own).
const MAX_EVENTS: u32 = 32;

/// A photon leaving its first bounce: an entry of a bounce map (Table 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BouncePhoton {
    /// Where it leaves from (offset off the surface) \[m\].
    pub origin: Vec3,
    /// Unit direction it travels.
    pub dir: Vec3,
    /// Power [W per channel].
    pub power: Rgb,
    /// Path density estimate ρ_p so far (section 4.3).
    pub density: f32,
    /// True when the first bounce was specular (a caustic path so far).
    pub specular: bool,
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

/// Path density factor of one scattering event (section 4.3): ρ/1000 for a
/// Lambertian sample, ρ/10 for a glossy one, ρ for mirror reflection or refraction,
/// with ρ the sample's mean weight (its albedo).
fn density_factor(bs: &pm_bsdf::BsdfSample) -> f32 {
    let rho = pm_color::mean(bs.weight).clamp(1e-6, 1.0);
    match bs.lobe {
        pm_bsdf::Lobe::Diffuse => rho / 1000.0,
        pm_bsdf::Lobe::Glossy => rho / 10.0,
        pm_bsdf::Lobe::Specular => rho,
    }
}

/// Exact solid angle [sr] of the rectangle [u0, u1] x [v0, v1] of the plane at unit
/// distance (a cube-map texel).
fn rect_solid_angle(u0: f32, u1: f32, v0: f32, v1: f32) -> f32 {
    let f = |u: f32, v: f32| (u * v / (1.0 + u * u + v * v).sqrt()).atan();
    f(u1, v1) - f(u0, v1) - f(u1, v0) + f(u0, v0)
}

/// One texel's photon arriving at the first surface: direction, power and the hit.
struct Arrival {
    dir: Vec3,
    power: Rgb,
    hit: Option<pm_scene::Hit>,
}

/// The first hits of light `li`'s `res` x `res`-per-face directions with their power
/// (section 4.2). Point and spot lights: a cube map drawn by the rasteriser, each
/// texel carrying I(ω) times its exact solid angle (spot lights then rescaled to the
/// light's power: the paper's round-off correction). Directional and area lights
/// (which have no centre of projection): as many stratified emission samples
/// (Sobol') traced through the BVH, each carrying Φ / n.
fn arrivals(scene: &Scene, li: usize, res: u32, seed: u64) -> Vec<Arrival> {
    let light = &scene.lights[li];
    match light.kind {
        LightKind::Point { position, intensity } => cube_arrivals(scene, position, res, |_| intensity),
        LightKind::Spot { position, direction, intensity, cos_inner, cos_outer } => {
            let mut v = cube_arrivals(scene, position, res, |d| {
                intensity * pm_scene::spot_falloff(d.dot(direction), cos_inner, cos_outer)
            });
            let sum: Rgb = v.iter().map(|a| a.power).sum();
            let scale = light.power / sum.max(Rgb::splat(f32::MIN_POSITIVE));
            for a in &mut v {
                a.power *= scale;
            }
            v
        }
        LightKind::Directional { .. } | LightKind::Area { .. } => {
            let n = 6 * (res as usize) * (res as usize);
            (0..n)
                .into_par_iter()
                .with_min_len(256)
                .map(|k| {
                    let mut s = Sampler::new(pm_sampling::mix64(seed ^ 0x626f_756e_6365 ^ li as u64), k as u64);
                    match light.sample_emission(scene, &mut s) {
                        Some(ray) => {
                            let hit = scene.intersect(ray.origin, ray.dir, f32::INFINITY);
                            let tr = hit.as_ref().map_or(Rgb::ONE, |h| scene.transmittance(h, ray.dir));
                            Arrival { dir: ray.dir, power: ray.power * tr / n as f32, hit }
                        }
                        None => Arrival { dir: Vec3::Z, power: Rgb::ZERO, hit: None },
                    }
                })
                .collect()
        }
    }
}

/// The texels of a cube map around `position`, face by face, row by row.
fn cube_arrivals(scene: &Scene, position: Vec3, res: u32, intensity: impl Fn(Vec3) -> Rgb + Sync) -> Vec<Arrival> {
    let film = Film { width: res, height: res, spp: 1, contrast: 0.0, seed: 0 };
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
            Arrival { dir, power, hit: f.map(|f| f.hit(scene)) }
        }));
    }
    out
}

/// The bounce maps of every light: the photons leaving their first surface, in
/// light and texel order (deterministic: texel k of light l draws from its own
/// stream, so a static light gives the same bounce map every frame, as the paper's
/// seeding by light position and texel does).
pub fn bounce_maps(scene: &Scene, res: u32, seed: u64, caustics: bool) -> (Vec<BouncePhoton>, BounceStats) {
    let mut out = Vec::new();
    let mut stats = BounceStats::default();
    // Nothing emits: no bounce map.
    let Ok(selector) = pm_light::LightSelector::new(scene, &[]) else { return (out, stats) };
    for li in 0..scene.lights.len() {
        // Texels in proportion to the light's share of the power (section 4.2), the
        // share the photon tracer and light sampling also use.
        let share = selector.probs[li] as f32;
        if !(share > 0.0) {
            continue;
        }
        let r = ((res as f32 * (share * scene.lights.len() as f32).sqrt()).round() as u32).clamp(4, res.max(4) * 4);
        let arrivals = arrivals(scene, li, r, seed);
        stats.texels += arrivals.len() as u64;
        let bounced: Vec<Option<BouncePhoton>> = arrivals
            .par_iter()
            .enumerate()
            .with_min_len(256)
            .map(|(k, a)| {
                let hit = a.hit.as_ref()?;
                let wo = -a.dir;
                let bsdf = scene.bsdf(hit);
                let mut s = Sampler::hashed(seed ^ li as u64, 0x6d61_7000_0000 ^ k as u64);
                let (bs, factor) = pm_photon::scatter(&bsdf, hit, wo, &mut s)?;
                if bs.specular && !caustics {
                    return None;
                }
                Some(BouncePhoton {
                    origin: scene.offset_origin(hit.p, hit.ng, bs.wi),
                    dir: bs.wi,
                    power: a.power * factor,
                    density: density_factor(&bs),
                    specular: bs.specular,
                })
            })
            .collect();
        for (a, b) in arrivals.iter().zip(&bounced) {
            if a.hit.is_some() {
                stats.hits += 1;
                stats.incident += a.power;
            }
            if let Some(b) = b {
                stats.survived += 1;
                stats.outgoing += b.power;
            }
        }
        out.extend(bounced.into_iter().flatten());
    }
    (out, stats)
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
}

impl KernelShape {
    /// The shape from the parameters, for a scene of diagonal `diag` \[m\].
    pub fn new(p: &LiveParams, diag: f32) -> KernelShape {
        let r_max = p.kernel_max_rel_diag * diag;
        KernelShape {
            r1: p.kernel_radius_rel_diag * diag,
            r_min: (p.kernel_min_rel_diag * diag).min(r_max),
            r_max,
            minor: p.kernel_minor,
        }
    }

    /// (r_xy, r_z) \[m\] for path density `density`.
    pub fn radii(&self, density: f32) -> (f32, f32) {
        let r = (self.r1 / density.max(1e-30).sqrt()).clamp(self.r_min, self.r_max);
        (r, r * self.minor)
    }
}

/// Trace the bounce-map photons on (section 4.3): at every non-specular hit store
/// a photon (power, incident direction, the surface's normal on the arriving side,
/// the kernel from the path's density), up to `stored` photons per path; scatter by
/// the shared photon-tracing step. Photons are in bounce-map order.
pub fn trace(
    scene: &Scene,
    bounce: &[BouncePhoton],
    stored: u32,
    kernel: &KernelShape,
    seed: u64,
) -> Vec<VolumePhoton> {
    let paths: Vec<Vec<VolumePhoton>> = bounce
        .par_iter()
        .enumerate()
        .with_min_len(64)
        .map(|(i, b)| {
            let mut out = Vec::new();
            let mut s = Sampler::hashed(seed, 0x7472_6163_6500 ^ i as u64);
            let (mut o, mut d, mut power, mut density, mut caustic) = (b.origin, b.dir, b.power, b.density, b.specular);
            for _ in 0..MAX_EVENTS {
                if out.len() as u32 >= stored || !pm_color::is_valid(power) || power == Rgb::ZERO {
                    break;
                }
                let Some(hit) = scene.intersect(o, d, f32::INFINITY) else { break };
                power *= scene.transmittance(&hit, d);
                let wo = -d;
                let bsdf = scene.bsdf(&hit);
                if !bsdf.is_specular() {
                    // The kernel is compressed along the shading normal: on a
                    // tessellated curved surface the facet's own normal tilts the
                    // neighbouring facets' points out of the thin kernel (the furnace
                    // sphere lost 13% of its indirect light that way).
                    let n = pm_render::facing(hit.ns, wo);
                    let (r_xy, r_z) = kernel.radii(density);
                    out.push(VolumePhoton {
                        p: hit.p,
                        n,
                        wi: wo,
                        power: power / scene.store_probability(&hit),
                        r_xy,
                        r_z,
                        caustic,
                    });
                }
                let Some((bs, factor)) = pm_photon::scatter(&bsdf, &hit, wo, &mut s) else { break };
                power *= factor;
                density *= density_factor(&bs);
                caustic &= bs.specular;
                o = scene.offset_origin(hit.p, hit.ng, bs.wi);
                d = bs.wi;
            }
            out
        })
        .collect();
    paths.into_iter().flatten().collect()
}

/// Wall time of each step of an image-space frame \[s\] (the paper's Table 2 split).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct IspmTimes {
    /// The eye G-buffer (rasteriser).
    pub gbuffer: f64,
    /// Direct light, emission and mirrors and glass over the G-buffer.
    pub direct: f64,
    /// The bounce maps.
    pub bounce: f64,
    /// Tracing the remaining bounces.
    pub trace: f64,
    /// Splatting photon volumes.
    pub splat: f64,
    /// Bilateral upsampling of a subsampled splat.
    pub upsample: f64,
    /// The whole frame.
    pub wall: f64,
}

/// What one image-space frame did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct IspmStats {
    /// Times per step \[s\].
    pub times: IspmTimes,
    /// The bounce maps' attrition and power.
    pub bounce: BounceStats,
    /// Photons stored for splatting.
    pub photons: usize,
}

/// The surface the splat sees at each pixel of the rasterised first hits: none
/// where nothing is seen or a mirror or glass is (photons cannot be splatted there;
/// the paper's section 2.1).
pub fn surfaces(scene: &Scene, fragments: &[Option<Fragment>], camera: &Camera) -> Vec<Option<Surface>> {
    fragments.par_iter().with_min_len(1024).map(|f| surface_at(scene, f, camera)).collect()
}

/// The splat's G-buffer of [`surfaces`] into `out`, reusing its memory (a frame's
/// G-buffer is tens of megabytes; faulting it back in every frame showed in the
/// profile).
pub fn gbuffer_into(scene: &Scene, fragments: &[Option<Fragment>], camera: &Camera, out: &mut GBuffer) {
    out.fill(fragments.len(), |j| {
        let Some(f) = &fragments[j] else { return Seen::Nothing };
        // Most pixels see a plain Lambertian surface: the point, its normal and
        // albedo are all the splat reads, and building the hit record and BSDF for
        // them took most of this pass (the full path gives the same values). Mirror
        // and glass pixels are known from the material alone.
        if let Some((p, ns, rho)) = scene.plain_lambert(f.tri, f.b) {
            let wo = (camera.position - p).normalize_or(ns);
            return Seen::Lambert { p, n: pm_render::facing(ns, wo), albedo_pi: rho / PI };
        }
        if scene.uniform_bsdf(f.tri).is_some_and(|b| b.is_specular()) {
            return Seen::Nothing;
        }
        surface_at(scene, &fragments[j], camera).into()
    });
}

fn surface_at(scene: &Scene, fragment: &Option<Fragment>, camera: &Camera) -> Option<Surface> {
    let hit = fragment.as_ref()?.hit(scene);
    let bsdf = scene.bsdf(&hit);
    if bsdf.is_specular() {
        return None;
    }
    let wo = (camera.position - hit.p).normalize_or(hit.ns);
    Some(Surface::new(hit.p, pm_render::facing(hit.ns, wo), wo, bsdf))
}

/// The image-space method's memory, kept between frames: the G-buffer and the
/// splats' working arrays and outputs.
#[derive(Default)]
pub struct IspmScratch {
    /// The eye's G-buffer (full resolution).
    pub gbuffer: GBuffer,
    /// The full-resolution splat (all photons, or the caustic ones when subsampled).
    full: splat::SplatScratch,
    /// The subsampled splat of the soft indirect photons.
    low: splat::SplatScratch,
    /// The G-buffer it is splatted over.
    low_gbuffer: GBuffer,
}

/// Draw one image-space frame of `scene` seen by `camera` into `buffers` (layers
/// "total", "direct", "caustic", "indirect", "specular"). `fragments` and
/// `scratch` keep the rasteriser's, the G-buffer's and the splats' memory between
/// frames.
#[allow(clippy::too_many_arguments)]
pub fn frame(
    scene: &Scene,
    camera: &Camera,
    p: &LiveParams,
    seed: u64,
    caustics: bool,
    buffers: &mut FrameBuffers,
    fragments: &mut Vec<Option<Fragment>>,
    scratch: &mut IspmScratch,
) -> Result<IspmStats, String> {
    let start = Instant::now();
    let film = Film { width: p.width, height: p.height, spp: 1, contrast: 0.0, seed };
    let t = Instant::now();
    let (bounce, bstats) = bounce_maps(scene, p.bounce_res, seed, caustics);
    let t_bounce = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let kernel = KernelShape::new(p, scene.bounds.diagonal());
    let photons = trace(scene, &bounce, p.bounces, &kernel, seed);
    let index = PhotonIndex::new(&photons);
    let t_trace = t.elapsed().as_secs_f64();
    let t = Instant::now();
    pm_raster::first_hits_into(scene, camera, film.size(), film.rect(), fragments);
    let t_gbuffer = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let maps = crate::shadow_maps(scene, p);
    let shading = LiveShading::splatted(scene, &photons, &index, p, maps.as_ref()).map_err(|e| e.to_string())?;
    pm_render::render_into(
        camera,
        &film,
        film.rect(),
        &shading,
        false,
        Visibility::Fragments(scene, fragments),
        buffers,
        &|_, _| {},
    )?;
    let t_direct = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let IspmScratch { gbuffer, full, low, low_gbuffer } = scratch;
    gbuffer_into(scene, fragments, camera, gbuffer);
    let gbuffer = &*gbuffer;
    let (w, h, f) = (p.width, p.height, p.subsample);
    let (t_splat, t_upsample) = if f <= 1 {
        splat::splat_into(&photons, gbuffer, camera, (w, h, 1), SplatOutput::Radiance, full);
        buffers.add_to_layer(pm_color::Layer::Indirect, &full.indirect);
        (t.elapsed().as_secs_f64(), 0.0)
    } else {
        // Section 5.2: the soft indirect light's irradiance splatted at 1/f
        // resolution, upsampled with the joint bilateral filter, then times each
        // full-resolution pixel's albedo / π (exact for Lambertian surfaces; glossy
        // ones get their normal-incidence albedo). Caustic photons, whose kernels
        // are a few pixels wide, are splatted at full resolution: upsampled they
        // were 130% off at f = 2 (`cargo bench -p pm-live --bench ispm`).
        let (caustic_photons, soft): (Vec<VolumePhoton>, Vec<VolumePhoton>) = photons.iter().partition(|q| q.caustic);
        splat::splat_into(&caustic_photons, gbuffer, camera, (w, h, 1), SplatOutput::Radiance, full);
        gbuffer.subsample_into(w, h, f, low_gbuffer);
        let low_gb = &*low_gbuffer;
        splat::splat_into(&soft, low_gb, camera, (w, h, f), SplatOutput::Irradiance, low);
        let t_splat = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let up = splat::Upsample::new(&low.indirect, low_gb, gbuffer, camera.position, (w, h, f), true);
        buffers.add_rows_to_layer(pm_color::Layer::Indirect, w as usize, |y, row| up.row(y, row));
        (t_splat, t.elapsed().as_secs_f64())
    };
    buffers.add_to_layer(pm_color::Layer::Caustic, &full.caustic);
    Ok(IspmStats {
        times: IspmTimes {
            gbuffer: t_gbuffer,
            direct: t_direct,
            bounce: t_bounce,
            trace: t_trace,
            splat: t_splat,
            upsample: t_upsample,
            wall: start.elapsed().as_secs_f64(),
        },
        bounce: bstats,
        photons: photons.len(),
    })
}
