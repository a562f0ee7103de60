//! Rendering from photon maps (Christensen 1999 sections 1.3, 2.2 and 3).
//!
//! The image loop is not the integrator (as pbrt-v4 separates
//! `ImageTileIntegrator::Render` from `Li`): [`render_region`] renders any rectangle
//! of the image with pixel-keyed sample streams and adaptive supersampling decided
//! on a one-pixel apron, so tiles assembled from regions equal the whole image byte
//! for byte; what is computed per sample is an [`Integrator`]:
//! - [`PhotonMapping`]: eye rays with recursive specular reflection and refraction,
//!   direct light by sampling the lights (multiple importance sampling on glossy
//!   surfaces), caustics from the caustic map, and soft indirect light by final
//!   gathering whose rays read the precomputed irradiance of the nearest photon with
//!   a similar normal (or an exact k-nearest estimate), made sparse by Ward and
//!   Heckbert's irradiance cache with gradients ([`IrradianceCache`], its own step);
//! - [`PhotonsView`], [`RadianceView`], [`IndirectView`]: Christensen's Figure 1
//!   (b), (e) and (f) as their own small integrators;
//! - [`PathTracer`]: unbiased path tracing over the same scene and BSDFs, with no
//!   photon map: the independent estimator the tests compare against.
//!
//! Each integrator can fill a [`VisibleSurface`] per pixel sample: the first-hit
//! G-buffer that image-space photon mapping splats into.
//!
//! Radiance everywhere is W sr^-1 m^-2 per RGB channel. This crate does no I/O: it
//! returns in-memory images with component layers, statistics, and cache records.

mod coverage;
mod icache;
mod integrator;
mod passes;
mod path;
mod photon_mapping;
mod render;

pub use coverage::{MIN_COVERAGE, Probe, SAME_SURFACE_COS, disc_coverage, in_view};
pub use icache::IrradianceCache;
pub use integrator::{
    Components, Counters, Film, FirstHit, Integrator, RenderStats, View, VisibleSurface, pixel_salt, variance_of_mean,
};
pub use passes::{LAYERS, PassLoop, PassSums, run_passes};
pub use path::{PathTracer, roulette};
pub use photon_mapping::{IndirectView, PhotonMapping, PhotonsView, RadianceView, Scratch};
pub use pm_raster::Rect;
pub use render::{
    FrameBuffers, Image, Shot, Visibility, pixel_sampler, render_into, render_region, render_region_with,
};

use glam::Vec3;
use pm_format::{FullPhoton, PhotonRecord, flags};
use pm_kdtree::KdTree;
use pm_scene::Scene;

pm_params::value_enum! {
    /// How final-gather rays get the radiance at their hit points.
    pub enum Lookup {
        /// Precomputed irradiance of the nearest photon with a similar normal (section 2.2; needs photon-irradiance).
        Precomputed,
        /// A k-nearest irradiance estimate at each gather-ray hit.
        Exact,
    }
}

pm_params::value_enum! {
    /// How light scattered more than once in a medium is read from the volume map
    /// along a ray.
    pub enum VolumeEstimate {
        /// Every photon whose sphere (its own k-nearest radius) the ray crosses (Jarosz, Zwicker and Jensen 2008).
        Beam,
        /// Steps along the ray, a k-nearest estimate at each (Jensen and Christensen 1998).
        RayMarch,
    }
}

use pm_params::{Any, above, at_least, between};

pm_params::params! {
    /// The settings of this crate's integrators, defined once: `photon-render`'s
    /// options, the `[render]` section of pipeline.toml (beside the `mode` key,
    /// which is pm-methods'), and what the runner, the trade-off study and the
    /// tests set. The image, light samples and specular depth are read by every
    /// method; the rest by the photon-map integrators. Lengths are fractions of the
    /// scene's bounding-box diagonal (the one reference every stage uses; the
    /// photon-map header records it).
    pub struct RenderParams {
        /// Image width [pixels].
        width: u32 = 512 => between(1, 16384);
        /// Image height [pixels].
        height: u32 = 512 => between(1, 16384);
        /// Most samples per pixel (adaptive; the paper: 16). In path mode, samples per pixel.
        spp: u32 = 16 => between(1, 1 << 20);
        /// Every eye ray through its pixel's centre (no pixel filter): a reference for the real-time
        /// methods, which draw one sample there.
        pixel_centres: bool = false => Any;
        /// Luminance contrast |a - b| / (a + b) between neighbouring pixels that triggers supersampling.
        contrast: f32 = 0.1 => at_least(0.0);
        /// Final-gather rays per gather (stratified, cosine-weighted; the paper: several hundred).
        gather_rays: u32 = 400 => between(1, 1 << 20);
        /// Rays per eye sample that gather the indirect light a glossy surface (a rough
        /// metal) reflects: sampled by its BSDF, each hit read from the photon maps as a
        /// final-gather ray's is (no cache: what such a surface reflects depends on the view).
        glossy_rays: u32 = 16 => between(1, 1 << 16);
        /// How gather rays read the global map (and, in media, the volume map:
        /// precomputed in-scattering at the nearest photon, or the eye rays'
        /// estimate).
        gather_lookup: Lookup = Lookup::Precomputed => Any;
        /// Rays of a secondary final gather (the paper: 12; 0 disables).
        secondary_rays: u32 = 12 => between(0, 1 << 16);
        /// Gather rays shorter than this fraction of the scene diagonal get a secondary gather.
        secondary_distance_rel_diag: f32 = 0.005 => at_least(0.0);
        /// Photons per global-map estimate (exact lookups and photons mode).
        k: usize = 50 => between(1, 1 << 16);
        /// Photons per caustic estimate.
        caustic_k: usize = 60 => between(1, 1 << 16);
        /// Largest global-map search radius, as a fraction of the scene diagonal.
        max_radius_rel_diag: f32 = 0.1 => above(0.0);
        /// Largest caustic search radius, as a fraction of the scene diagonal.
        caustic_radius_rel_diag: f32 = 0.02 => above(0.0);
        /// Irradiance-cache accuracy a (Ward's error bound, smaller is finer; 0 disables the cache).
        icache_accuracy: f32 = 0.3 => at_least(0.0);
        /// Smallest irradiance-cache record spacing, as a fraction of the scene diagonal.
        icache_min_spacing_rel_diag: f32 = 0.005 => above(0.0);
        /// Largest irradiance-cache record spacing, as a fraction of the scene diagonal (at least the smallest).
        icache_max_spacing_rel_diag: f32 = 0.1 => above(0.0);
        /// Importance threshold: where the photon map's indirect irradiance is below this
        /// fraction of the direct irradiance, use it instead of a final gather (0: always gather).
        indirect_threshold: f32 = 0.0 => at_least(0.0);
        /// Light samples per shading point (stratified among themselves; with a
        /// planar light they only decide its visibility, see `DirectLighting::direct`).
        light_samples: u32 = 4 => between(1, 1 << 16);
        /// Depth limit of specular recursion (cut paths are counted in the stats).
        max_depth: u32 = 12 => between(0, 1000);
        /// PNG exposure in stops (the PNG shows radiance x 2^exposure).
        exposure: f32 = 0.0 => between(-64.0, 64.0);
        /// Participating media: how the volume map gives multiple scattering along rays.
        volume_estimate: VolumeEstimate = VolumeEstimate::Beam => Any;
        /// Participating media: photons per volume estimate (and per beam radius).
        volume_k: usize = 50 => between(2, 1 << 16);
        /// Participating media: largest volume-estimate radius, as a fraction of the scene diagonal.
        volume_radius_rel_diag: f32 = 0.05 => above(0.0);
        /// Participating media: ray-march step, as a fraction of the scene diagonal.
        volume_step_rel_diag: f32 = 0.01 => above(0.0);
        /// Participating media: light samples of single scattering per ray segment in a medium (equiangular).
        /// Their noise is most of a thin fog's error, and they are cheap: on cornell_fog (48 x 48,
        /// `cargo xtask tradeoff`) 4 gave 7.7% error in 5.19 s, 16 gave 6.2% in 5.16 s.
        volume_light_samples: u32 = 16 => between(1, 1 << 16);
    }
}

impl RenderParams {
    /// [`Self::validate`] plus the checks that relate two values.
    pub fn check(&self, naming: pm_params::Naming) -> Result<(), String> {
        self.validate(naming)?;
        if self.icache_max_spacing_rel_diag < self.icache_min_spacing_rel_diag {
            return Err(format!(
                "{} = {} is below {} = {}",
                naming.name("icache_max_spacing_rel_diag"),
                self.icache_max_spacing_rel_diag,
                naming.name("icache_min_spacing_rel_diag"),
                self.icache_min_spacing_rel_diag
            ));
        }
        Ok(())
    }

    /// The image these parameters describe, with `seed`.
    pub fn film(&self, seed: u64) -> Film {
        Film {
            width: self.width,
            height: self.height,
            spp: self.spp,
            contrast: self.contrast,
            seed,
            pixel_centres: self.pixel_centres,
        }
    }

    /// What of these parameters shapes an irradiance cache.
    pub fn cache_settings(&self) -> CacheSettings {
        let d = RenderParams::default();
        CacheSettings(RenderParams {
            spp: d.spp,
            contrast: d.contrast,
            exposure: d.exposure,
            caustic_k: d.caustic_k,
            caustic_radius_rel_diag: d.caustic_radius_rel_diag,
            volume_light_samples: d.volume_light_samples,
            glossy_rays: d.glossy_rays,
            pixel_centres: d.pixel_centres,
            ..self.clone()
        })
    }
}

/// The settings that shape an irradiance cache, said once: render parameters with
/// every value that cannot shape a cache at its default (how the image is sampled
/// and shown: spp, contrast, exposure; the caustic estimate: caustic_k,
/// caustic_radius_rel_diag; the single-scattering samples of eye rays,
/// volume_light_samples; glossy surfaces' own gathers, glossy_rays; where in its
/// pixel an eye sample goes, pixel_centres: the prepass takes the centres). What remains is
/// the image size (the prepass samples the image), the final gather's settings,
/// the global map's estimate, the volume map's (gather rays read it), the cache's
/// accuracy and spacing, direct light and the specular depth. The runner's cache
/// step takes exactly these ([`Self::render_params`]), so a change of anything
/// else re-runs only the render; a cache file records them ([`Self::key`]) and a
/// render with other values refuses it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CacheSettings(RenderParams);

impl CacheSettings {
    /// The cache step's render parameters.
    pub fn render_params(&self) -> &RenderParams {
        &self.0
    }

    /// The cache file's record of these settings for a scene of diagonal `diag` \[m\]
    /// and the film `film` (its size and seed): `name=value` words, lengths in metres
    /// as the renderer resolves them.
    pub fn key(&self, diag: f32, film: &Film) -> String {
        format!(
            "width={} height={} seed={} gather_rays={} secondary_rays={} secondary_distance_m={} lookup={} k={} \
             max_radius_m={} icache_accuracy={} icache_spacing_m={},{} indirect_threshold={} light_samples={} \
             max_depth={} volume_estimate={} volume_k={} volume_radius_m={} volume_step_m={}",
            film.width,
            film.height,
            film.seed,
            self.0.gather_rays,
            self.0.secondary_rays,
            self.0.secondary_distance_rel_diag * diag,
            self.0.gather_lookup,
            self.0.k,
            self.0.max_radius_rel_diag * diag,
            self.0.icache_accuracy,
            self.0.icache_min_spacing_rel_diag * diag,
            self.0.icache_max_spacing_rel_diag * diag,
            self.0.indirect_threshold,
            self.0.light_samples,
            self.0.max_depth,
            self.0.volume_estimate,
            self.0.volume_k,
            self.0.volume_radius_rel_diag * diag,
            self.0.volume_step_rel_diag * diag
        )
    }
}

/// The photon-map integrators' settings in absolute units, resolved from
/// [`RenderParams`] against the scene diagonal.
#[derive(Clone, Debug)]
pub(crate) struct Settings {
    /// Compute soft indirect light (final gathering).
    pub indirect: bool,
    pub indirect_threshold: f32,
    pub gather_rays: u32,
    pub glossy_rays: u32,
    pub secondary_rays: u32,
    /// [m]
    pub secondary_distance: f32,
    pub lookup: Lookup,
    pub k_global: usize,
    pub k_caustic: usize,
    /// [m]
    pub max_radius_global: f32,
    /// [m]
    pub max_radius_caustic: f32,
    pub icache_accuracy: f32,
    /// (min, max) [m]
    pub icache_spacing: (f32, f32),
    pub light_samples: u32,
    pub max_depth: u32,
    pub volume_estimate: VolumeEstimate,
    pub volume_k: usize,
    /// [m]
    pub max_radius_volume: f32,
    /// [m]
    pub volume_step: f32,
    pub volume_light_samples: u32,
}

impl Settings {
    pub(crate) fn new(p: &RenderParams, diag: f32, indirect: bool) -> Settings {
        Settings {
            indirect,
            indirect_threshold: p.indirect_threshold,
            gather_rays: p.gather_rays,
            glossy_rays: p.glossy_rays,
            secondary_rays: p.secondary_rays,
            secondary_distance: p.secondary_distance_rel_diag * diag,
            lookup: p.gather_lookup,
            k_global: p.k,
            k_caustic: p.caustic_k,
            max_radius_global: p.max_radius_rel_diag * diag,
            max_radius_caustic: p.caustic_radius_rel_diag * diag,
            icache_accuracy: p.icache_accuracy,
            icache_spacing: (p.icache_min_spacing_rel_diag * diag, p.icache_max_spacing_rel_diag * diag),
            light_samples: p.light_samples,
            max_depth: p.max_depth,
            volume_estimate: p.volume_estimate,
            volume_k: p.volume_k,
            max_radius_volume: p.volume_radius_rel_diag * diag,
            volume_step: p.volume_step_rel_diag * diag,
            volume_light_samples: p.volume_light_samples,
        }
    }
}

/// The photon maps the renderer reads, as kd-trees.
pub struct Maps<'a, G> {
    /// Global map with normals (23/64-byte records), or none (render without it).
    pub global: Option<KdTree<'a, G>>,
    /// Photons of the global map that carry a precomputed irradiance, balanced into
    /// their own tree so the section 2.2 lookup does not skip over the others.
    pub irradiance: Option<KdTree<'a, G>>,
    /// Caustic map.
    pub caustic: Option<KdTree<'a, FullPhoton>>,
    /// Volume map (photons at scattering events in media), with its photons as
    /// spheres for the beam estimate.
    pub volume: Option<VolumeMap<'a>>,
}

/// A volume photon map as the renderer reads it: the kd-tree, and its photons as
/// spheres of their k-nearest radii for the beam estimate, once with the photons
/// eye rays count (all but single scattering, which comes from the lights) and
/// once with every photon (final-gather rays).
pub struct VolumeMap<'a> {
    /// The photons, balanced.
    pub tree: KdTree<'a, FullPhoton>,
    /// Every photon but the direct ones, as beam spheres.
    pub multiple: pm_estimate::Beams,
    /// Every photon, as beam spheres.
    pub all: pm_estimate::Beams,
    /// The in-scattered radiance per unit length at each photon (heap order)
    /// [W sr^-1 m^-3 per channel] that final-gather rays look up
    /// ([`pm_estimate::precomputed_inscattering`]; empty unless asked for).
    pub inscattering: pm_estimate::Inscattering,
}

impl<'a> VolumeMap<'a> {
    /// The volume map of kd-tree `nodes` in `scene` with beam radii from the `k`
    /// nearest photons within `max_radius` \[m\], their kernels corrected for the
    /// media's boundaries ([`pm_estimate::Beams::with_inside_fractions`], from
    /// [`inside_fractions`]), and with each photon's in-scattered radiance
    /// precomputed from as many when `precompute` (final gathers look it up:
    /// [`Lookup::Precomputed`]). The boundary correction casts rays, so it is
    /// made only for the spheres the beam estimate will read (`beam`: it is the
    /// volume estimate): eye rays' always, final gathers' only without
    /// `precompute`.
    pub fn new(
        scene: &Scene,
        nodes: &'a [FullPhoton],
        k: usize,
        max_radius: f32,
        precompute: bool,
        beam: bool,
    ) -> VolumeMap<'a> {
        let tree = KdTree::new(nodes);
        let max_d2 = max_radius * max_radius;
        let multiple = pm_estimate::beam_spheres(&tree, k, max_d2, false);
        let (all, inscattering) = if precompute {
            // The precomputation's queries give the all-photon radii too.
            let (inscattering, radii) = pm_estimate::Inscattering::with_beam_radii(&tree, k, max_d2);
            (pm_estimate::Beams::new(&tree, &radii), inscattering)
        } else {
            (pm_estimate::beam_spheres(&tree, k, max_d2, true), Default::default())
        };
        let correct_all = beam && !precompute;
        if !beam {
            return VolumeMap { tree, multiple, all, inscattering };
        }
        let reach = |i: usize| {
            let r = multiple.spheres.sphere(i).1;
            if correct_all { r.max(all.spheres.sphere(i).1) } else { r }
        };
        let positions: Vec<Vec3> = nodes.iter().map(|r| r.position()).collect();
        let free = free_distances(scene, &positions, reach);
        let inside = |i: usize, r: f32| inside_fraction(&free[i], r);
        let multiple = multiple.with_inside_fractions(inside);
        let all = if correct_all { all.with_inside_fractions(inside) } else { all };
        VolumeMap { tree, multiple, all, inscattering }
    }
}

/// Directions the medium around a photon is probed in: a Fibonacci sphere (equal
/// solid angles).
const PROBES: usize = 32;

/// For each photon, the distance from it to the first surface (a wall, a medium's
/// boundary, an object) in each of [`PROBES`] fixed directions, up to `reach(i)`
/// \[m\]. In parallel, each photon on its own (independent of the thread count).
fn free_distances(scene: &Scene, positions: &[Vec3], reach: impl Fn(usize) -> f32 + Sync) -> Vec<[f32; PROBES]> {
    use rayon::prelude::*;
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let dirs: [Vec3; PROBES] = std::array::from_fn(|j| {
        let z = 1.0 - (2.0 * j as f32 + 1.0) / PROBES as f32;
        let s = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * j as f32;
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    });
    positions
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            let far = reach(i);
            std::array::from_fn(|j| if far > 0.0 { scene.intersect(p, dirs[j], far).map_or(far, |h| h.t) } else { 0.0 })
        })
        .collect()
}

/// `beams` with their kernels corrected for the media's boundaries, as
/// [`VolumeMap::new`] corrects its own: for maps built elsewhere (progressive
/// photon mapping's passes).
pub fn boundary_corrected(scene: &Scene, beams: pm_estimate::Beams) -> pm_estimate::Beams {
    let positions: Vec<Vec3> = (0..beams.weights.len()).map(|i| beams.spheres.sphere(i).0).collect();
    let free = free_distances(scene, &positions, |i| beams.spheres.sphere(i).1);
    beams.with_inside_fractions(|i, r| inside_fraction(&free[i], r))
}

/// The volume photons of a real-time frame (the vertex method's ring, the
/// image-space method's paths): balanced, as the spheres of the beam estimate
/// over all but those scattered straight from a light
/// ([`pm_estimate::beam_spheres`]), their kernels corrected for the media's
/// boundaries ([`boundary_corrected`]).
pub struct VolumePhotons {
    /// The photons, balanced (heap order).
    pub nodes: Vec<FullPhoton>,
    /// Their beam spheres.
    pub beams: pm_estimate::Beams,
}

impl VolumePhotons {
    /// Photons a beam radius holds (the batch pipeline's `volume_k`).
    pub const K: usize = 50;

    /// The `photons` scattered in `scene`'s media (as the photon tracer emits
    /// them), with beam radii from the [`Self::K`] nearest within `max_radius`
    /// \[m\]; `None` when there are none.
    pub fn new<'p>(
        scene: &Scene,
        photons: impl IntoIterator<Item = &'p pm_format::Photon>,
        max_radius: f32,
    ) -> Option<VolumePhotons> {
        let photons: Vec<FullPhoton> = photons.into_iter().map(FullPhoton::encode).collect();
        if photons.is_empty() {
            return None;
        }
        let nodes = pm_kdtree::balance(&photons);
        let tree = KdTree::new(&nodes);
        let beams = pm_estimate::beam_spheres(&tree, Self::K, max_radius * max_radius, false);
        let beams = boundary_corrected(scene, beams);
        Some(VolumePhotons { nodes, beams })
    }

    /// Radiance [W sr^-1 m^-2 per channel] the photons scattered more than once
    /// put on the segment from `o` along unit `d` to `t` \[m\] in medium `m`
    /// ([`pm_estimate::beam`], Jarosz, Zwicker and Jensen 2008), as the batch
    /// pipeline's eye rays take it.
    pub fn scattered(&self, o: Vec3, d: Vec3, t: f32, m: &pm_scene::Medium) -> pm_color::Rgb {
        let seg = pm_estimate::Segment { o, d, t_max: t, sigma_t: m.sigma_t() };
        let mut stack = Vec::new();
        pm_estimate::beam(&self.nodes, &self.beams, &seg, &mut stack, |wi| m.phase.p(-d, wi))
    }
}

/// The fraction of a sphere of radius `r` around a photon that lies in its
/// medium, from its [`free_distances`]: the mean over the directions of the cube
/// of the free part of the radius (each direction's cone of the sphere).
fn inside_fraction(free: &[f32; PROBES], r: f32) -> f32 {
    free.iter().map(|&s| (s.min(r) / r).powi(3)).sum::<f32>() / PROBES as f32
}

/// A scene as density estimates ask about it ([`pm_estimate::SurfaceQuery`]): the
/// gaps around a surface, up to `reach` \[m\] (the estimate's largest radius),
/// and which points of a disc lie on it. What the irradiance precompute
/// (photon-irradiance) is given.
pub struct SceneSurfaces<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// How far the gaps are looked for \[m\].
    pub reach: f32,
}

impl pm_estimate::SurfaceQuery for SceneSurfaces<'_> {
    fn surroundings(&self, x: Vec3, n: Vec3) -> Option<pm_estimate::Surroundings> {
        self.scene.surface_gaps(x, n, self.reach).map(Into::into)
    }

    fn continues(&self, x: Vec3, n: Vec3, off: Vec3, r: f32) -> bool {
        self.scene.continues_surface(x, n, off, r, pm_estimate::SAME_SURFACE_COS)
    }

    fn covered(&self, x: Vec3, n: Vec3) -> bool {
        covered(self.scene, x, n)
    }
}

/// True when surface point `x` (unit normal `n`) of `scene` lies under a cover:
/// another surface faces it from closer than [`COVER_REL_DIAG`] of the diagonal.
/// What the precompute flags photons by and the final gather's lookup asks of
/// its query point.
pub fn covered(scene: &Scene, x: Vec3, n: Vec3) -> bool {
    scene.covered(x, n, COVER_REL_DIAG * scene.bounds.diagonal())
}

/// The cover distance, as a fraction of the scene diagonal: a surface point with
/// another surface facing it from closer than this lies in a gap, whose light is
/// its own ([`pm_format::flags::COVERED`]; the precompute flags its photons, the
/// final gather's lookup asks the same of its query point).
pub const COVER_REL_DIAG: f32 = 0.01;

/// The photons of a kd-tree map that carry a precomputed irradiance, as their own
/// balanced tree (empty when none do).
pub fn irradiance_subset<G: PhotonRecord>(global: &[G]) -> Vec<G> {
    let with: Vec<G> = global.iter().copied().filter(|r| r.flags() & flags::HAS_IRRADIANCE != 0).collect();
    pm_kdtree::balance(&with)
}

pub use pm_scene::facing;

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{Parser, ValueEnum};

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        p: RenderParams,
    }

    /// `params` with field `field` set to another accepted value.
    fn changed(params: &RenderParams, field: &str) -> RenderParams {
        let args = params.to_args();
        let at = args.iter().position(|a| *a == format!("--{}", field.replace('_', "-"))).unwrap() + 1;
        let text = &args[at];
        let mut candidates: Vec<String> = Lookup::value_variants().iter().map(|v| v.to_string()).collect();
        candidates.extend(VolumeEstimate::value_variants().iter().map(|v| v.to_string()));
        candidates.extend(["true", "false"].map(String::from));
        if let Ok(i) = text.parse::<u64>() {
            candidates.insert(0, (i + 1).to_string());
        } else if let Ok(f) = text.parse::<f64>() {
            candidates.insert(0, (f * 0.5 + 0.003).to_string());
        }
        for c in candidates {
            let mut a = args.clone();
            a[at] = c;
            if let Ok(cli) = Cli::try_parse_from(std::iter::once("x".to_string()).chain(a))
                && cli.p != *params
                && cli.p.check(pm_params::Naming::Cli).is_ok()
            {
                return cli.p;
            }
        }
        panic!("no other value for {field}");
    }

    /// "What shapes an irradiance cache" is said once, in [`CacheSettings`]: every
    /// `RenderParams` field changes the cache file's key exactly when it changes
    /// the cache settings, and the cache step's parameters carry them back
    /// unchanged. A field that changes the integrator's resolved settings but not
    /// the cache settings must be one that cannot shape the cache (the caustic
    /// estimate's): a new setting that the prepass reads fails here until it is
    /// classified.
    #[test]
    fn every_render_parameter_either_shapes_the_cache_or_cannot() {
        let base = RenderParams::default();
        let key = |p: &RenderParams| p.cache_settings().key(2.5, &p.film(7));
        let resolved = |p: &RenderParams| format!("{:?}", Settings::new(p, 2.5, true));
        let mut shaping = 0;
        for field in RenderParams::FIELDS {
            let p = changed(&base, field);
            let (in_key, in_settings) = (key(&p) != key(&base), p.cache_settings() != base.cache_settings());
            assert_eq!(in_key, in_settings, "{field}: changes the key {in_key}, the cache settings {in_settings}");
            assert_eq!(p.cache_settings().render_params().cache_settings(), p.cache_settings(), "{field}");
            if resolved(&p) != resolved(&base) && !in_settings {
                assert!(
                    ["caustic_k", "caustic_radius_rel_diag", "volume_light_samples", "glossy_rays"].contains(field),
                    "{field} changes what the integrator resolves but not the cache settings"
                );
            }
            shaping += in_settings as usize;
        }
        assert_eq!(
            shaping,
            RenderParams::FIELDS.len() - 8,
            "spp, contrast, exposure, pixel_centres, the caustic two, single scattering's light samples and \
             glossy_rays"
        );
    }
}
