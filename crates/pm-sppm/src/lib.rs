//! Stochastic progressive photon mapping (Hachisuka and Jensen 2009, "Stochastic
//! progressive photon mapping"; the pass structure of pbrt-v4's `SPPMIntegrator`):
//! the batch pipeline's consistent limit. Each pass traces one eye path per pixel
//! to its first non-specular surface (a *visible point*, through mirrors and
//! glass; past glossy surfaces too, as pbrt-v3's `SPPMIntegrator` does: see
//! [`Sppm::eye_path`]), takes direct light there by next-event estimation, traces a pass of
//! photons with the photon tracer's own paths and streams, and gathers into each
//! visible point the photons within its radius. Each pixel keeps a radius r, a
//! photon count N and a flux tau; after a pass that found M photons,
//!
//! ```text
//! N' = N + alpha M,   r' = r sqrt(N' / (N + M)),   tau' = (tau + beta Phi) (r' / r)^2
//! ```
//!
//! (Hachisuka, Ogaki and Jensen 2008, equations 6-11; alpha = 2/3 by default), so
//! the radius shrinks, the estimate's bias goes to zero and its memory stays fixed
//! at one record per pixel. After P passes of N_p photons a pixel's radiance is
//! L = L_d / P + tau / (P N_p pi r^2) [W sr^-1 m^-2].
//!
//! Photons only carry indirect and caustic light: a photon's first hit (direct
//! light) is left to next-event estimation, as in pbrt-v4.
//!
//! In participating media the eye path's segments gather the light scattered
//! toward the eye: single scattering from the lights (pm-light's equiangular
//! estimate, the batch pipeline's), and the pass's volume photons (all but the
//! first event of paths straight from a light) by the beam radiance estimate
//! (Jarosz, Zwicker and Jensen 2008), each photon's sphere the distance to its
//! k-th nearest photon of the pass times a factor that shrinks pass by pass as
//! the surface radius does, s_k^2 = prod_{j=1..k} (j + alpha) / (j + 1) (the
//! radius sequence of Knaus and Zwicker 2011, "Progressive photon mapping: a
//! probabilistic approach", eq. 15, for the beam estimate's 2D kernel): each
//! pass's estimate is kept and the passes averaged, so the bias goes to zero
//! with s_k while the average's variance still falls as k^-alpha.
//!
//! Deterministic: pass k's
//! eye sample of a pixel is point k of the pixel's stream, its photons the photon
//! tracer's paths keyed by (seed, pass, index), and each visible point sums its
//! photons in a fixed order (pm-kdtree's `RadiusGrid`: cell by cell, by index
//! within a cell), so any thread count gives the same image.

use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::{Layer, Rgb};
use pm_estimate::{Beams, Segment};
use pm_format::{FullPhoton, PhotonRecord};
use pm_kdtree::{KdTree, RadiusGrid};
use pm_light::DirectLighting;
use pm_photon::{Budget, MapPass, PathOut, TraceConfig};
use pm_render::{Image, View, pixel_salt};
use pm_sampling::{Sampler, mix64};
use pm_scene::{Camera, MediumId, Scene};
use rayon::prelude::*;

use pm_params::{above, between};

pm_params::params! {
    /// Progressive photon mapping's own settings, defined once: `photon-render
    /// --mode sppm`'s options and pipeline.toml's `[sppm]` section (keys without
    /// the `sppm_` of the options: `alpha`, `radius_rel_diag`, `boundary_probes`).
    /// The image size, light samples and specular depth are `[render]`'s, which
    /// every method shares.
    #[derive(Copy)]
    pub struct SppmParams {
        /// Passes, each one eye sample a pixel and a photon pass.
        passes: u32 = 64 => between(1, 1 << 24);
        /// Photon paths traced per pass.
        photons_per_pass: u64 = 100_000 => between(1, 1 << 30);
        /// Hachisuka's alpha: the share of a pass's photons a pixel keeps as its
        /// radius shrinks (smaller shrinks faster, noisier).
        sppm_alpha as "alpha": f32 = 0.6666667 => between(0.01, 0.99);
        /// Starting gather radius, as a fraction of the scene diagonal.
        sppm_radius_rel_diag as "radius_rel_diag": f32 = 0.01 => above(0.0);
        /// Probe rays a pixel a pass that measure how much of the gather disc lies
        /// on the visible surface (walls and edges cut it), so the density divides
        /// by that area instead of pi r^2 (0: pi r^2, Hachisuka's estimate;
        /// [`surface_share`]).
        sppm_boundary_probes as "boundary_probes": u32 = 4 => between(0, 64);
    }
}

/// Render `view.rect` of `view.film` by `params.passes` passes of progressive
/// photon mapping (the whole film is traced, its `rect` kept: a pixel's value depends
/// only on its own eye paths and each pass's photons, so a region equals the same
/// pixels of the whole image), reporting passes done as progress.
pub fn render(
    scene: &Scene,
    shared: &pm_render::RenderParams,
    params: &SppmParams,
    view: View,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, pm_render::RenderStats), String> {
    let passes = params.passes as u64;
    let (image, stats, _) = render_with(scene, shared, params, view, None, &mut |s| {
        progress(s.passes() as u64, passes);
        Ok(true)
    })?;
    Ok((image, stats))
}

/// [`render`], continuing from the passes of `start` when given (a state file,
/// read from the path it names, of the same scene and settings: see
/// [`Sppm::resume`]; a refusal names the file) and calling
/// `after_pass` after each pass with the state so far (to write a checkpoint
/// image or state, or stop: `Ok(false)` ends the render with the passes done;
/// an error ends it with that error). Returns the image, its statistics and the
/// passes it holds.
pub fn render_with(
    scene: &Scene,
    shared: &pm_render::RenderParams,
    params: &SppmParams,
    view: View,
    start: Option<(&std::path::Path, &pm_format::StateFile)>,
    after_pass: &mut dyn FnMut(&Sppm) -> Result<bool, String>,
) -> Result<(Image, pm_render::RenderStats, u32), String> {
    let t0 = std::time::Instant::now();
    let (p, film) = (*params, view.film);
    let mut s = Sppm::new(scene, film.width, film.height, p, film.seed, shared).map_err(|e| e.to_string())?;
    if let Some((path, file)) = start {
        s.resume(file).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    pm_render::run_passes(&mut s, &view, p.passes, t0, after_pass)
}

impl pm_render::PassLoop for Sppm<'_> {
    fn passes_done(&self) -> u32 {
        self.passes()
    }
    fn next_pass(&mut self, camera: &Camera) -> Result<(), String> {
        self.pass(camera);
        Ok(())
    }
    fn image_of(&self, rect: pm_render::Rect) -> Image {
        self.region_image(rect)
    }
}

/// One pixel's progressive state: what a long render keeps between passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelState {
    /// Gather radius r \[m\].
    pub radius: f32,
    /// Photon count N (fractional: alpha of each pass's photons).
    pub n: f32,
    /// Accumulated flux tau [W per channel] of photons seen directly by the eye's
    /// first non-specular surface: caustic (photons that reached it through
    /// specular bounces only), then indirect.
    pub tau: [Rgb; 2],
    /// tau of visible points reached through mirrors and glass (the specular layer).
    pub tau_specular: Rgb,
    /// Sum over the passes of the pixel's emission, direct light and each pass's
    /// estimate of the light media scatter toward the eye, by layer
    /// ([`Layer::ALL`] order) [W sr^-1 m^-2].
    pub ld: [Rgb; 5],
    /// Sum over the passes of each pass's own estimate of the pixel, the mean of
    /// its channels [W sr^-1 m^-2]: the image is their mean (tau / r^2 sums each
    /// pass's flux over that pass's radius squared), so their spread measures its
    /// noise ([`Sppm::variances`]).
    pub l_sum: f32,
    /// Sum of their squares [W^2 sr^-2 m^-4].
    pub l_sq: f32,
    /// The share of the gather disc that lies on the visible surface, a running
    /// mean of the passes' probes over the last few passes (1 without probes).
    pub share: f32,
    /// Passes whose eye path found a visible point (the running mean's count).
    pub seen: f32,
}

impl PixelState {
    /// A pixel at radius `r0` \[m\] with nothing accumulated.
    pub fn new(r0: f32) -> PixelState {
        PixelState {
            radius: r0,
            n: 0.0,
            tau: [Rgb::ZERO; 2],
            tau_specular: Rgb::ZERO,
            ld: [Rgb::ZERO; 5],
            l_sum: 0.0,
            l_sq: 0.0,
            share: 1.0,
            seen: 0.0,
        }
    }

    /// Count in one pass's probed share `sample` of the gather disc on the surface
    /// (with `probes` > 0) and return the share to divide by: the running mean
    /// over the last [`SHARE_MEMORY`] passes or fewer (the radius barely changes
    /// over them, and a mean of many probes keeps 1 / share nearly unbiased), at
    /// least [`SHARE_FLOOR`]. Without probes, 1.
    fn update_share(&mut self, sample: f32, probes: u32) -> f32 {
        if probes == 0 {
            return 1.0;
        }
        self.seen += 1.0;
        let lambda = (1.0 / self.seen).max(1.0 / SHARE_MEMORY);
        self.share += (sample - self.share) * lambda;
        self.share.max(SHARE_FLOOR)
    }

    /// Count in one pass's own estimate `l` of the pixel (the mean of its
    /// channels) [W sr^-1 m^-2], for the noise estimate.
    fn add_estimate(&mut self, l: f32) {
        self.l_sum += l;
        self.l_sq += l * l;
    }

    /// Count in one pass's `m` photons, whose flux beta f Phi at the pixel's
    /// visible point is `phi` [W per channel] (caustic, indirect, and all of it
    /// when the point was reached through a mirror or glass), and shrink the
    /// radius (Hachisuka, Ogaki and Jensen 2008, equations 6-11):
    /// N' = N + alpha M, r'^2 = r^2 N' / (N + M), tau' = (tau + phi) r'^2 / r^2.
    /// A pass without photons changes nothing.
    pub fn add_photons(&mut self, phi: [Rgb; 3], m: u64, alpha: f32) {
        if m == 0 {
            return;
        }
        let n_new = self.n + alpha * m as f32;
        let shrink = n_new / (self.n + m as f32);
        self.tau = [(self.tau[0] + phi[0]) * shrink, (self.tau[1] + phi[1]) * shrink];
        self.tau_specular = (self.tau_specular + phi[2]) * shrink;
        self.n = n_new;
        self.radius *= shrink.sqrt();
    }
}

/// Passes over which a pixel's share of the gather disc on its surface is
/// averaged (an exponential mean after the first ones).
pub const SHARE_MEMORY: f32 = 16.0;
pub use pm_estimate::SHARE_FLOOR;

/// A pass's visible point: the first non-specular surface of the pixel's eye path.
struct VisiblePoint {
    p: Vec3,
    /// Unit geometric normal on the side the eye path arrived from.
    n: Vec3,
    /// Unit shading normal.
    ns: Vec3,
    wo: Vec3,
    bsdf: Bsdf,
    /// The eye path's throughput to the point.
    beta: Rgb,
    /// What lies between it and the eye: what its photons' light is.
    seen: Seen,
    /// The share of the gather disc on the surface its probes found (of its
    /// own kind: under a cover or not).
    share: f32,
    /// Under a cover ([`pm_render::covered`]): it gathers only photons of its
    /// kind. Two-sided lamps a few millimetres under a ceiling trap light
    /// brighter than the room between them; a visible point on the ceiling
    /// beside a lamp, reached in a rough metal sphere's reflection, took those
    /// photons and the sphere's highlight read 63% bright in an 8 x 8 block
    /// (the differential checker's seed 90210, scene 27). The batch precompute
    /// and the vertex method keep them apart alike.
    covered: bool,
}

/// How a visible point is seen from the eye: the layer of the light it gathers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Seen {
    /// Directly (through index-matched boundaries at most): caustic and indirect.
    Directly,
    /// Through mirrors and glass: the specular layer.
    Specular,
    /// Reflected by a glossy surface first: light that reaches the eye after two
    /// non-specular scatterings, indirect.
    Glossy,
}

impl Seen {
    /// Where light that arrives from a light at the current non-specular vertex
    /// goes ([`Layer::Direct`] at the first, or `first` for a point in a medium).
    fn layer(self, first: Layer) -> usize {
        match self {
            Seen::Directly => first,
            Seen::Specular => Layer::Specular,
            Seen::Glossy => Layer::Indirect,
        }
        .index()
    }
}

/// A stretch of a pass's eye path inside a scattering medium, where the pass's
/// volume photons are gathered.
struct EyeSegment {
    seg: Segment,
    medium: Option<MediumId>,
    /// The eye path's throughput to the segment's start.
    beta: Rgb,
    /// The layer what it gathers goes to (volume, or specular behind a mirror or glass).
    layer: usize,
}

/// What a pass's eye path through a pixel found: its visible point, its
/// emission and direct light along the way by layer, and its stretches in media.
struct EyePath {
    vp: Option<VisiblePoint>,
    ld: [Rgb; 5],
    segments: Vec<EyeSegment>,
}

/// The volume settings progressive photon mapping shares with the batch
/// pipeline (`[render]`'s `volume_*`), for a scene whose media scatter.
#[derive(Clone, Copy, Debug)]
struct VolumeSettings {
    /// Photons of the pass whose distance sets a volume photon's radius.
    k: usize,
    /// The largest such radius \[m\].
    max_radius: f32,
    /// Single-scattering light samples per eye segment.
    light_samples: u32,
}

/// A pass's volume photons as spheres for the beam estimate: the records (kd-tree
/// heap order) and their spheres, boundary-corrected.
struct VolumePass {
    records: Vec<FullPhoton>,
    beams: Beams,
}

/// Knaus and Zwicker's radius factor after `k` passes: s_k with s_k^2 =
/// prod_{j=1..k} (j + alpha) / (j + 1) (1 at the first pass).
fn radius_factor(k: u32, alpha: f32) -> f32 {
    (1..=k).map(|j| (j as f64 + alpha as f64) / (j as f64 + 1.0)).product::<f64>().sqrt() as f32
}

/// A stored photon of a pass: where, from where, with what power, and whether it
/// came from the light through specular bounces only.
struct PassPhoton {
    p: Vec3,
    wi: Vec3,
    n: Vec3,
    power: Rgb,
    caustic: bool,
    /// Under a cover ([`pm_render::covered`]): its light is the gap's own.
    covered: bool,
}

/// Progressive photon mapping of one image: the pixels' state and the passes done.
pub struct Sppm<'a> {
    light: DirectLighting<'a>,
    params: SppmParams,
    width: u32,
    height: u32,
    seed: u64,
    light_samples: u32,
    max_depth: u32,
    volume: Option<VolumeSettings>,
    pixels: Vec<PixelState>,
    passes: u32,
}

/// What a pass did.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassStats {
    /// Photons stored (after their first bounce) in the pass.
    pub photons: u64,
    /// Visible points that found at least one photon.
    pub pixels_with_photons: u64,
    /// The largest radius after the pass \[m\].
    pub max_radius: f32,
}

impl<'a> Sppm<'a> {
    /// Start an image of `width` x `height` of `scene`: every pixel at the initial
    /// radius, nothing accumulated. The light samples, specular depth and volume
    /// settings are `shared`'s (`[render]`'s). Fails when nothing emits.
    pub fn new(
        scene: &'a Scene,
        width: u32,
        height: u32,
        params: SppmParams,
        seed: u64,
        shared: &pm_render::RenderParams,
    ) -> Result<Self, pm_light::LightSelectError> {
        let diag = scene.bounds.diagonal();
        let r0 = params.sppm_radius_rel_diag * diag;
        let empty = PixelState::new(r0);
        let volume = scene.has_scattering_media().then_some(VolumeSettings {
            k: shared.volume_k,
            max_radius: shared.volume_radius_rel_diag * diag,
            light_samples: shared.volume_light_samples,
        });
        Ok(Sppm {
            light: DirectLighting::new(scene)?,
            params,
            width,
            height,
            seed,
            light_samples: shared.light_samples,
            max_depth: shared.max_depth,
            volume,
            pixels: vec![empty; (width * height) as usize],
            passes: 0,
        })
    }

    /// Passes done.
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// The pixels' state (row by row).
    pub fn pixels(&self) -> &[PixelState] {
        &self.pixels
    }

    /// Each pixel's estimated noise variance after the passes done, s_i^2 / P
    /// [W^2 sr^-2 m^-4], with s_i^2 the sample variance of its per-pass
    /// estimates (the mean of the channels; the image is their mean and the
    /// passes are independent). It leaves out the bias, which shrinks with the
    /// radius (Hachisuka and Jensen 2009, section 4). None before two passes.
    pub fn variances(&self) -> Option<Vec<f32>> {
        (self.passes >= 2)
            .then(|| self.pixels.iter().map(|px| pm_render::variance_of_mean(px.l_sum, px.l_sq, self.passes)).collect())
    }

    /// The settings that shape the state, as "name=value" words (the state file's
    /// key: a state made with other settings is refused).
    pub fn key(&self) -> String {
        let p = &self.params;
        let mut key = format!(
            "width={} height={} photons_per_pass={} sppm_alpha={} sppm_radius_rel_diag={} sppm_boundary_probes={} seed={} light_samples={} max_depth={}",
            self.width,
            self.height,
            p.photons_per_pass,
            p.sppm_alpha,
            p.sppm_radius_rel_diag,
            p.sppm_boundary_probes,
            self.seed,
            self.light_samples,
            self.max_depth
        );
        if let Some(v) = &self.volume {
            key +=
                &format!(" volume_k={} volume_radius_m={} volume_light_samples={}", v.k, v.max_radius, v.light_samples);
        }
        key
    }

    /// The state as its file holds it.
    pub fn to_file(&self) -> pm_format::StateFile {
        let records = self
            .pixels
            .iter()
            .map(|px| pm_format::StateRecord {
                radius: px.radius,
                n: px.n,
                tau: [px.tau[0], px.tau[1], px.tau_specular].map(<[f32; 3]>::from),
                ld: px.ld.map(<[f32; 3]>::from),
                l_sum: px.l_sum,
                l_sq: px.l_sq,
                share: px.share,
                seen: px.seen,
            })
            .collect();
        pm_format::StateFile {
            width: self.width,
            height: self.height,
            passes: self.passes,
            scene_hash: self.light.scene.content_hash,
            params: self.key(),
            records,
        }
    }

    /// Continue from a state file's passes: refused when it was made from another
    /// scene, for another image size or with other settings (naming the first
    /// that differs), or holds more passes than asked for.
    pub fn resume(&mut self, file: &pm_format::StateFile) -> Result<(), String> {
        if (file.width, file.height) != (self.width, self.height) {
            return Err(format!(
                "a state of a {}x{} image, this render is {}x{}",
                file.width, file.height, self.width, self.height
            ));
        }
        if file.scene_hash != self.light.scene.content_hash {
            return Err("made from another scene".into());
        }
        if let Some((had, has)) = pm_format::key_difference(&file.params, &self.key()) {
            return Err(format!("made with {had}, this render has {has}"));
        }
        if file.passes > self.params.passes {
            return Err(format!("holds {} passes, more than the {} asked for", file.passes, self.params.passes));
        }
        self.pixels = file
            .records
            .iter()
            .map(|r| PixelState {
                radius: r.radius,
                n: r.n,
                tau: [Rgb::from_array(r.tau[0]), Rgb::from_array(r.tau[1])],
                tau_specular: Rgb::from_array(r.tau[2]),
                ld: r.ld.map(Rgb::from_array),
                l_sum: r.l_sum,
                l_sq: r.l_sq,
                share: r.share,
                seen: r.seen,
            })
            .collect();
        self.passes = file.passes;
        Ok(())
    }

    /// One pass: eye paths, photons, gathering, the radius update.
    pub fn pass(&mut self, camera: &Camera) -> PassStats {
        let k = self.passes;
        let (w, h) = (self.width as usize, self.height as usize);
        let rays = camera.rays(w as f32 / h as f32);
        // Eye paths: each pixel's visible point, its direct light and its
        // stretches in media.
        let paths: Vec<EyePath> = (0..w * h)
            .into_par_iter()
            .with_min_len(64)
            .map(|i| {
                let mut s = Sampler::salted(self.seed, pixel_salt(i), k as u64);
                let j = s.next_2d();
                let d = rays.direction(((i % w) as f32 + j.x) / w as f32, ((i / w) as f32 + j.y) / h as f32);
                let mut path = self.eye_path(camera.position, d, &mut s);
                if let Some(vp) = &mut path.vp {
                    vp.share = surface_share(
                        self.light.scene,
                        vp,
                        self.pixels[i].radius,
                        self.params.sppm_boundary_probes,
                        &mut s,
                    );
                }
                path
            })
            .collect();
        // The pass's photons after their first bounce, in index order.
        let (photons, volume) = self.photons(k);
        let volume = self.volume_pass(volume, k);
        let max_r = self.pixels.iter().map(|p| p.radius).fold(0.0f32, f32::max);
        let positions: Vec<Vec3> = photons.iter().map(|ph| ph.p).collect();
        let grid = RadiusGrid::new(&positions, max_r);
        let alpha = self.params.sppm_alpha;
        let np = self.params.photons_per_pass as f32;
        let scene = self.light.scene;
        let found: Vec<u64> = self
            .pixels
            .par_iter_mut()
            .zip(paths.par_iter())
            .with_min_len(64)
            .map_init(Vec::new, |stack, (px, path)| {
                let mut ld = path.ld;
                if let Some(v) = &volume {
                    for e in &path.segments {
                        ld[e.layer] += e.beta * gather_volume(scene, v, e, stack) / np;
                    }
                }
                for (a, b) in px.ld.iter_mut().zip(&ld) {
                    *a += *b;
                }
                let direct = ld.iter().copied().sum::<Rgb>().element_sum() / 3.0;
                let Some(vp) = &path.vp else {
                    px.add_estimate(direct);
                    return 0;
                };
                let (phi, m) = gather(&grid, &photons, vp, px.radius);
                // The density divides by the disc's area on the surface: pi r^2 times
                // its share there, folded into the flux so that the alpha rule's
                // bookkeeping stays Hachisuka's.
                let share = px.update_share(vp.share, self.params.sppm_boundary_probes);
                let phi = phi.map(|f| vp.beta * f / share);
                let photon =
                    (phi[0] + phi[1]).element_sum() / 3.0 / (np * std::f32::consts::PI * px.radius * px.radius);
                px.add_estimate(direct + if photon.is_finite() { photon } else { 0.0 });
                let by_layer = match vp.seen {
                    Seen::Directly => [phi[0], phi[1], Rgb::ZERO],
                    Seen::Glossy => [Rgb::ZERO, phi[0] + phi[1], Rgb::ZERO],
                    Seen::Specular => [Rgb::ZERO, Rgb::ZERO, phi[0] + phi[1]],
                };
                px.add_photons(by_layer, m, alpha);
                (m > 0) as u64
            })
            .collect();
        self.passes += 1;
        PassStats {
            photons: photons.len() as u64,
            pixels_with_photons: found.iter().sum(),
            max_radius: self.pixels.iter().map(|p| p.radius).fold(0.0f32, f32::max),
        }
    }

    /// The eye path of one pass through a pixel: emission and direct light along it
    /// by layer, its visible point (none when it leaves the scene, is absorbed or
    /// reaches the depth limit) and its stretches in scattering media. A glossy
    /// surface ([`Bsdf::is_glossy`]) takes its direct light and the path goes on
    /// along one sample of its lobe to the next surface, as pbrt-v3's SPPM does
    /// (a visible point there only at the depth limit): gathered on the glossy
    /// surface, the photons a sharp lobe sees were few and its blocks 30% off
    /// against the path tracer (the differential checker's seed 16654, issue 53).
    /// Light through mirrors and glass from the glossy surface then comes from
    /// lights the path can hit (area lights and the sky), not from photons:
    /// a point light's caustic seen in a rough metal is left out. Media
    /// attenuate it, through index-matched boundaries; along each stretch in a
    /// medium that scatters it takes single scattering from the lights (the
    /// volume layer, or the specular layer behind a mirror or glass) and keeps the
    /// stretch for the pass's volume photons ([`gather_volume`]). The
    /// photons fly through the media (`pm_photon::trace_path`), so what media
    /// scatter onto surfaces is counted too.
    fn eye_path(&self, o: Vec3, d: Vec3, s: &mut Sampler) -> EyePath {
        let scene = self.light.scene;
        let mut path = EyePath { vp: None, ld: [Rgb::ZERO; 5], segments: Vec::new() };
        let (mut o, mut d, mut beta) = (o, d, Rgb::ONE);
        let mut seen = Seen::Directly;
        // The layer of emission found along the current ray; none right after a
        // glossy surface's lobe sample, whose direct light (its own BSDF samples
        // weighed against light samples) took what that sample would find.
        let mut emission = Some(Layer::Direct.index());
        let mut glossy_vertices = 0u32;
        let mut medium = scene.eye_medium(o);
        let (mut depth, mut crossings) = (0, 0);
        while depth <= self.max_depth && crossings < MAX_CROSSINGS {
            let hit = scene.intersect(o, d, f32::INFINITY);
            if let Some(m) = scene.medium(medium).filter(|m| !m.is_clear()) {
                let t_max = scene.segment_length(o, d, hit.as_ref());
                if let Some(v) = self.volume.filter(|_| m.scatters()) {
                    let layer = seen.layer(Layer::Volume);
                    let single = self.light.single_scattering(o, d, t_max, medium, s, v.light_samples);
                    path.ld[layer] += beta * single;
                    let seg = Segment { o, d, t_max, sigma_t: m.sigma_t() };
                    path.segments.push(EyeSegment { seg, medium, beta, layer });
                }
                beta *= m.transmittance(t_max);
            }
            let Some(hit) = hit else {
                if let Some(layer) = emission {
                    path.ld[layer] += beta * scene.escaped(d);
                }
                return path;
            };
            if let Some(tint) = scene.index_matched(&hit) {
                // Straight through, into the medium beyond: no event.
                beta *= tint;
                if beta.max_element() <= 0.0 {
                    return path;
                }
                medium = scene.medium_after(&hit, d, medium);
                o = scene.offset_origin(hit.p, hit.ng, d);
                crossings += 1;
                continue;
            }
            let wo = -d;
            if let Some(layer) = emission {
                path.ld[layer] += beta * scene.emitted(&hit, wo);
            }
            let bsdf = scene.bsdf(&hit);
            let specular = bsdf.is_specular();
            if !specular {
                let direct = self.light.direct(&hit, &bsdf, wo, s, self.light_samples, medium);
                path.ld[seen.layer(Layer::Direct)] += beta * direct;
                if !bsdf.is_glossy() || depth == self.max_depth {
                    let n = pm_scene::facing(hit.ng, wo);
                    let covered = pm_render::covered(scene, hit.p, n);
                    path.vp = Some(VisiblePoint { p: hit.p, n, ns: hit.ns, wo, bsdf, beta, seen, share: 1.0, covered });
                    return path;
                }
            }
            let Some(bs) = bsdf.sample(wo, hit.ns, s.next_2d(), s.next_1d()) else { return path };
            if !specular && !pm_scene::same_side(hit.ng, bs.wi, wo) {
                return path;
            }
            beta *= bs.radiance_weight();
            if !beta.is_finite() || beta == Rgb::ZERO {
                return path;
            }
            if specular {
                // Emission after mirrors and glass: seen through them from the eye
                // (specular), or a caustic at the glossy surface before them.
                if seen == Seen::Directly {
                    seen = Seen::Specular;
                }
                // (Past this point `seen` is never `Directly`.)
                let layer = match seen {
                    Seen::Glossy if glossy_vertices == 1 => Layer::Caustic,
                    Seen::Glossy => Layer::Indirect,
                    _ => Layer::Specular,
                };
                emission = Some(layer.index());
            } else {
                glossy_vertices += 1;
                if seen == Seen::Directly {
                    seen = Seen::Glossy;
                }
                emission = None;
            }
            depth += 1;
            medium = scene.medium_after(&hit, bs.wi, medium);
            o = scene.offset_origin(hit.p, hit.ng, bs.wi);
            d = bs.wi;
        }
        path
    }

    /// Pass `k`'s volume photons as spheres: each photon's radius the distance
    /// to its k-th nearest (at most the volume radius) times [`radius_factor`],
    /// the kernels corrected for the media's boundaries as the batch pipeline's
    /// are ([`pm_render::boundary_corrected`]). None without scattering media or
    /// photons in them.
    fn volume_pass(&self, photons: Vec<FullPhoton>, k: u32) -> Option<VolumePass> {
        let v = self.volume?;
        if photons.is_empty() {
            return None;
        }
        let records = pm_kdtree::balance(&photons);
        // Leaf buckets: the k-nearest searches for the radii were most of a pass.
        let buckets = pm_kdtree::Buckets::new(&records);
        let tree = KdTree::with_buckets(&records, &buckets);
        let shrink = radius_factor(k, self.params.sppm_alpha);
        let mut radii = pm_estimate::beam_radii(&tree, v.k, v.max_radius * v.max_radius, false);
        for r in &mut radii {
            *r *= shrink;
        }
        let beams = pm_render::boundary_corrected(self.light.scene, Beams::new(&tree, &radii));
        Some(VolumePass { records, beams })
    }

    /// Pass `k`'s photons that have scattered at least once (direct light is the
    /// eye paths'), in path-index order: the photon tracer's global-map paths with
    /// the pass's own seed, power Phi-hat / p_select (not yet divided by the
    /// count); those on surfaces, then those in media (all but the first event of
    /// paths straight from a light, which single scattering takes from the lights).
    fn photons(&self, k: u32) -> (Vec<PassPhoton>, Vec<FullPhoton>) {
        let scene = self.light.scene;
        let cfg = TraceConfig {
            pass: MapPass::Progressive,
            budget: Budget::Emitted(self.params.photons_per_pass),
            seed: mix64(self.seed ^ 0x7370_706d ^ (k as u64) << 32),
            selector: self.light.lights.clone(),
        };
        let n = self.params.photons_per_pass;
        let chunk = 1024u64;
        let chunks: Vec<(Vec<PassPhoton>, Vec<FullPhoton>)> = (0..n.div_ceil(chunk))
            .into_par_iter()
            .map(|c| {
                let mut out = PathOut::default();
                let (mut surface, mut volume) = (Vec::new(), Vec::new());
                for i in c * chunk..((c + 1) * chunk).min(n) {
                    pm_photon::trace_path(scene, &cfg, &[], i, &mut out);
                    for (ph, bounce) in &out.photons {
                        if *bounce == 0 {
                            continue;
                        }
                        if ph.flags & pm_format::flags::VOLUME != 0 {
                            volume.push(FullPhoton::encode(ph));
                        } else {
                            surface.push(PassPhoton {
                                p: ph.position,
                                wi: ph.wi,
                                n: ph.normal,
                                power: ph.power,
                                caustic: ph.flags & pm_format::flags::CAUSTIC != 0,
                                covered: pm_render::covered(scene, ph.position, ph.normal),
                            });
                        }
                    }
                }
                (surface, volume)
            })
            .collect();
        let (mut surface, mut volume) = (Vec::new(), Vec::new());
        for (a, b) in chunks {
            surface.extend(a);
            volume.extend(b);
        }
        (surface, volume)
    }

    /// [`Self::image`]'s pixels of `rect`.
    pub fn region_image(&self, rect: pm_raster::Rect) -> Image {
        let whole = self.image();
        let keep = |v: &[Rgb]| -> Vec<Rgb> {
            (rect.y0..rect.y1)
                .flat_map(|y| (rect.x0..rect.x1).map(move |x| (x, y)))
                .map(|(x, y)| v[(y * self.width + x) as usize])
                .collect()
        };
        Image {
            rect,
            width: rect.x1 - rect.x0,
            height: rect.y1 - rect.y0,
            total: keep(&whole.total),
            // An absent (empty) layer stays absent.
            layers: whole.layers.each_ref().map(|l| if l.is_empty() { Vec::new() } else { keep(l) }),
            gbuffer: None,
        }
    }

    /// The image after the passes done: per pixel L_d / P + tau / (P N_p pi r^2),
    /// by layer.
    pub fn image(&self) -> Image {
        let p = self.passes.max(1) as f32;
        let np = self.params.photons_per_pass as f32;
        let mut layers: [Vec<Rgb>; 5] = std::array::from_fn(|_| Vec::with_capacity(self.pixels.len()));
        for px in &self.pixels {
            let area = p * np * std::f32::consts::PI * px.radius * px.radius;
            let photon = |t: Rgb| if area > 0.0 { t / area } else { Rgb::ZERO };
            let mut l = px.ld.map(|v| v / p);
            l[Layer::Caustic.index()] += photon(px.tau[0]);
            l[Layer::Indirect.index()] += photon(px.tau[1]);
            l[Layer::Specular.index()] += photon(px.tau_specular);
            for (layer, v) in layers.iter_mut().zip(l) {
                layer.push(if v.is_finite() { v.max(Rgb::ZERO) } else { Rgb::ZERO });
            }
        }
        if self.volume.is_none() {
            // An absent layer is empty.
            layers[Layer::Volume.index()].clear();
        }
        let total =
            (0..self.pixels.len()).map(|i| layers.iter().filter(|l| !l.is_empty()).map(|l| l[i]).sum()).collect();
        let [direct, caustic, indirect, specular, volume] = layers;
        Image {
            rect: pm_raster::Rect { x0: 0, y0: 0, x1: self.width, y1: self.height },
            width: self.width,
            height: self.height,
            total,
            layers: [direct, caustic, indirect, specular, volume],
            gbuffer: None,
        }
    }
}

/// The light [W sr^-1 m^-2 per channel, times the photons per pass] the pass's
/// volume photons `v` scatter toward the start of eye segment `e` (before its
/// throughput): the beam estimate ([`pm_estimate::beam`]) with the medium's phase
/// function. `stack` is scratch.
fn gather_volume(scene: &Scene, v: &VolumePass, e: &EyeSegment, stack: &mut Vec<u32>) -> Rgb {
    let Some(m) = scene.medium(e.medium) else { return Rgb::ZERO };
    pm_estimate::beam(&v.records, &v.beams, &e.seg, stack, |wi| m.phase.p(-e.seg.d, wi))
}

/// The most index-matched boundaries an eye path passes (a walk that meets more
/// ends there, as pm-scene's walks do).
const MAX_CROSSINGS: u32 = 64;

/// The share of the gather disc of radius `r` around visible point `vp` that lies
/// on its surface, from `probes` points q drawn uniformly on the disc in its
/// tangent plane, each asking what the gather asks of a photon: is there a
/// surface point within r of the visible point whose normal is alike
/// ([`pm_estimate::SAME_SURFACE_COS`]; [`Scene::surface_beside`])? The photons
/// found over the disc's area on the surface estimate the density without the
/// disc's missing part: the boundary bias, first order in r at every edge,
/// goes. A point under a cover where the visible point is not (or the other way
/// round) is not its surface either: the photons there are not gathered. 1
/// without probes.
fn surface_share(scene: &Scene, vp: &VisiblePoint, r: f32, probes: u32, s: &mut Sampler) -> f32 {
    if probes == 0 {
        return 1.0;
    }
    let (t, b) = pm_sampling::basis(vp.n);
    let inside = (0..probes)
        .filter(|_| {
            let u = pm_sampling::concentric_disk(s.next_2d()) * r;
            let off = t * u.x + b * u.y;
            scene
                .surface_beside(vp.p, vp.n, off, r, pm_estimate::SAME_SURFACE_COS)
                .is_some_and(|h| pm_render::covered(scene, h.p, pm_scene::facing(h.ng, vp.n)) == vp.covered)
        })
        .count();
    inside as f32 / probes as f32
}

/// The flux f(wo, wi) Phi of the pass's `photons` within `r` of visible point
/// `vp` on its surface (stored normal within [`pm_estimate::SAME_SURFACE_COS`]),
/// found through `grid` (built over their positions for the largest radius, so
/// the order of the sum is fixed): caustic, then the rest, and their count.
fn gather(grid: &RadiusGrid, photons: &[PassPhoton], vp: &VisiblePoint, r: f32) -> ([Rgb; 2], u64) {
    let (mut phi, mut m) = ([Rgb::ZERO; 2], 0u64);
    grid.for_each_within(vp.p, r * r, |i, _| {
        let ph = &photons[i as usize];
        if ph.covered == vp.covered && ph.n.dot(vp.n) > pm_estimate::SAME_SURFACE_COS {
            phi[!ph.caustic as usize] += vp.bsdf.f(vp.wo, ph.wi, vp.ns) * ph.power;
            m += 1;
        }
    });
    (phi, m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The radius update against a hand-computed sequence (alpha = 2/3, r = 1):
    /// 6 photons: N = 4, r^2 = 4/6, tau = (0 + 6) x 4/6 = 4; then 3 photons:
    /// N = 6, r^2 = 4/6 x 6/7 = 4/7, tau = (4 + 3) x 6/7 = 6; a pass without
    /// photons changes nothing. The radius never grows and tau / r^2 (the
    /// estimate's numerator over its area) is the sum of the fluxes over the
    /// first radius's area scaled only by what alpha keeps.
    #[test]
    fn radius_update_follows_the_alpha_rule() {
        let mut px = PixelState::new(1.0);
        let one = |v: f32| [Rgb::ZERO, Rgb::splat(v), Rgb::ZERO];
        px.add_photons(one(6.0), 6, 2.0 / 3.0);
        assert!((px.n - 4.0).abs() < 1e-6 && (px.radius.powi(2) - 4.0 / 6.0).abs() < 1e-6);
        assert!((px.tau[1].x - 4.0).abs() < 1e-5, "{:?}", px.tau);
        px.add_photons(one(3.0), 3, 2.0 / 3.0);
        assert!((px.n - 6.0).abs() < 1e-6 && (px.radius.powi(2) - 4.0 / 7.0).abs() < 1e-6);
        assert!((px.tau[1].x - 6.0).abs() < 1e-5, "{:?}", px.tau);
        let before = px;
        px.add_photons(one(5.0), 0, 2.0 / 3.0);
        assert_eq!(px, before);
        let mut r = px.radius;
        for m in [1u64, 10, 100, 1000, 3] {
            px.add_photons(one(1.0), m, 2.0 / 3.0);
            assert!(px.radius <= r);
            r = px.radius;
        }
    }
}
