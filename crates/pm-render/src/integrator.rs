//! What is computed per eye sample: the [`Integrator`] interface (radiance
//! components of a sample, what is known of its first hit, the G-buffer entry it
//! fills), the film it samples, and the counters integrators keep. The image loop
//! (`render`) and every integrator (`path`, `photon_mapping`) build on it; it
//! depends on neither.

use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::{Layer, Rgb};
use pm_raster::Rect;
use pm_sampling::{Sampler, mix64};
use pm_scene::{Hit, Scene, facing};
use std::sync::atomic::AtomicU64;
use std::sync::atomic::Ordering::Relaxed;

/// Radiance components of one eye sample [W sr^-1 m^-2], one per [`Layer`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Components {
    /// Emission seen directly plus direct light at the first non-specular hit.
    pub direct: Rgb,
    /// Caustic-map radiance at the first non-specular hit.
    pub caustic: Rgb,
    /// Soft indirect light (final gather or cache) at the first non-specular hit.
    pub indirect: Rgb,
    /// Everything seen through one or more specular bounces.
    pub specular: Rgb,
    /// Light scattered toward the eye in media along the eye ray.
    pub volume: Rgb,
}

impl Components {
    /// The sum of the components: the radiance of the sample.
    pub fn total(&self) -> Rgb {
        self.direct + self.caustic + self.indirect + self.specular + self.volume
    }

    /// Every component times `w` (per channel).
    pub fn scaled(&self, w: Rgb) -> Components {
        Components {
            direct: self.direct * w,
            caustic: self.caustic * w,
            indirect: self.indirect * w,
            specular: self.specular * w,
            volume: self.volume * w,
        }
    }

    /// The component of `layer`.
    pub fn get(&self, layer: Layer) -> Rgb {
        match layer {
            Layer::Direct => self.direct,
            Layer::Caustic => self.caustic,
            Layer::Indirect => self.indirect,
            Layer::Specular => self.specular,
            Layer::Volume => self.volume,
        }
    }

    /// Add `v` to the component of `layer`.
    pub fn add_to(&mut self, layer: Layer, v: Rgb) {
        match layer {
            Layer::Direct => self.direct += v,
            Layer::Caustic => self.caustic += v,
            Layer::Indirect => self.indirect += v,
            Layer::Specular => self.specular += v,
            Layer::Volume => self.volume += v,
        }
    }

    /// Add another sample's components.
    pub fn add(&mut self, c: &Components) {
        self.direct += c.direct;
        self.caustic += c.caustic;
        self.indirect += c.indirect;
        self.specular += c.specular;
        self.volume += c.volume;
    }
}

/// The first surface an eye ray hits: one entry of the G-buffer (pbrt-v4's
/// `VisibleSurface`), filled by the integrator while it computes the sample, so it
/// costs no extra ray.
#[derive(Clone, Copy, Debug, Default)]
pub struct VisibleSurface {
    /// False where the eye ray leaves the scene (the other fields are then zero).
    pub hit: bool,
    /// Position \[m\].
    pub p: Vec3,
    /// Shading normal, turned toward the camera.
    pub ns: Vec3,
    /// Geometric normal, turned toward the camera.
    pub ng: Vec3,
    /// Distance from the camera along the eye ray \[m\].
    pub depth: f32,
    /// Index into `Scene::objects` (`u32::MAX` for a triangle in no object).
    pub object: u32,
    /// Index into `Scene::triangles`.
    pub tri: u32,
    /// The BSDF there, textures applied.
    pub bsdf: Option<Bsdf>,
    /// Radiance emitted toward the camera [W sr^-1 m^-2].
    pub le: Rgb,
    /// Reflected direct radiance toward the camera [W sr^-1 m^-2] as the integrator
    /// computed it there (zero at mirrors and glass, and in views that compute none).
    pub direct: Rgb,
}

impl VisibleSurface {
    /// The entry for `hit`, seen from direction `wo` (pointing at the camera).
    pub fn at(scene: &Scene, hit: &Hit, wo: Vec3, bsdf: Bsdf, le: Rgb) -> VisibleSurface {
        VisibleSurface {
            hit: true,
            p: hit.p,
            ns: facing(hit.ns, wo),
            ng: facing(hit.ng, wo),
            depth: hit.t,
            object: scene.object_of(hit.tri).unwrap_or(u32::MAX),
            tri: hit.tri,
            bsdf: Some(bsdf),
            le,
            direct: Rgb::ZERO,
        }
    }
}

/// What the image loop knows of an eye sample's first surface before it is shaded.
#[derive(Clone, Copy)]
pub enum FirstHit<'a> {
    /// Nothing: the ray is traced.
    Unknown,
    /// The rasteriser's fragment at the pixel centre on this scene (none: nothing
    /// is seen there), drawn for the same camera and film.
    Fragment(&'a Scene, Option<&'a pm_raster::Fragment>),
}

impl FirstHit<'_> {
    /// The first hit of the ray from `o` along `d` in `scene`: from the fragment
    /// when one is known (what `scene.intersect(o, d, inf)` finds, but for
    /// rounding), else traced.
    pub fn resolve(self, scene: &Scene, o: Vec3, d: Vec3) -> Option<Hit> {
        match self {
            FirstHit::Unknown => scene.intersect(o, d, f32::INFINITY),
            FirstHit::Fragment(drawn, f) => f.map(|f| f.hit(drawn)),
        }
    }
}

/// What an image is made of, per eye sample (pbrt-v4's `Li`): the image loop
/// ([`crate::render_region`]) knows nothing about how the radiance is found.
pub trait Integrator: Sync {
    /// Per-thread scratch memory.
    type Scratch: Default + Send;

    /// Radiance components arriving at `o` from direction `-d` [W sr^-1 m^-2].
    /// `first` is what the image loop already knows of the ray's first surface
    /// (the rasteriser's fragment at a pixel centre, or nothing): an integrator may
    /// take it ([`FirstHit::resolve`]) or trace the ray, and gives the same either
    /// way. With `vs`, also fill the G-buffer entry of the first hit.
    fn li(
        &self,
        o: Vec3,
        d: Vec3,
        first: FirstHit,
        s: &mut Sampler,
        scratch: &mut Self::Scratch,
        vs: Option<&mut VisibleSurface>,
    ) -> Components;

    /// True: the image loop takes one sample a pixel (jittered; at its centre when
    /// the first hits are rasterised) and supersamples where neighbours differ.
    /// False: every pixel takes all samples, jittered.
    /// Integrators of scenes with stochastic surfaces (blended alpha, partial
    /// transmission: [`pm_scene::Scene::has_stochastic_surfaces`]) say false: a pixel
    /// whose first sample and neighbours happened to choose alike would keep that one
    /// choice, and the image would be biased toward the likelier one.
    fn adaptive(&self) -> bool {
        true
    }

    /// True when its samples can carry light scattered in media
    /// ([`Components::volume`]): the image then has a volume layer.
    fn volume(&self) -> bool {
        false
    }

    /// Work counters (final gathers, lookups, cut paths, time per component).
    fn counters(&self) -> &Counters;
}

/// Counters an integrator keeps while rendering (sums, so their totals do not
/// depend on the thread schedule; the nanosecond sums are thread time).
#[derive(Default, Debug)]
pub struct Counters {
    pub(crate) gathers: AtomicU64,
    pub(crate) cache_records: AtomicU64,
    pub(crate) cache_hits: AtomicU64,
    pub(crate) gather_rays: AtomicU64,
    pub(crate) secondary_gathers: AtomicU64,
    pub(crate) lookups: AtomicU64,
    pub(crate) lookup_misses: AtomicU64,
    pub(crate) lookup_rank: [AtomicU64; 3],
    pub(crate) terminated_paths: AtomicU64,
    pub(crate) thinned: AtomicU64,
    pub(crate) ns_direct: AtomicU64,
    pub(crate) ns_caustic: AtomicU64,
    pub(crate) ns_gather: AtomicU64,
    pub(crate) ns_specular: AtomicU64,
    pub(crate) ns_icache: AtomicU64,
}

/// What a render looks at: the camera, the film, and the rectangle of the film to
/// render (the whole film, or a tile or `--region` of it).
#[derive(Clone, Copy, Debug)]
pub struct View<'a> {
    /// The camera.
    pub camera: &'a pm_scene::Camera,
    /// The image's size, sampling and seed.
    pub film: &'a Film,
    /// The pixels to render.
    pub rect: Rect,
}

/// The image being rendered: its size, sampling and seed. A region of it is
/// rendered with the same per-pixel sample streams as the whole.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Film {
    /// Width \[pixels\].
    pub width: u32,
    /// Height \[pixels\].
    pub height: u32,
    /// Most samples per pixel (adaptive integrators), or samples per pixel.
    pub spp: u32,
    /// Luminance contrast |a - b| / (a + b) between 4-neighbours that triggers
    /// supersampling (Mitchell's contrast), as a fraction.
    pub contrast: f32,
    /// Random seed.
    pub seed: u64,
    /// Every sample's eye ray through its pixel's centre, no pixel filter: the
    /// reference for the methods that draw one sample there (the real-time ones),
    /// whose images alias at every edge; judged against a filtered image, an edge
    /// between a mirror and the floor took a block of their indirect light 40% off.
    pub pixel_centres: bool,
}

impl Film {
    /// (width, height) \[pixels\], as the rasteriser takes the image's size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The whole image.
    pub fn rect(&self) -> Rect {
        Rect::full(self.width, self.height)
    }

    /// Tile `k` of `n` ([`Rect::band`]).
    pub fn band(&self, k: u32, n: u32) -> Option<Rect> {
        Rect::band(self.width, self.height, k, n)
    }

    /// True when `rect` is non-empty and inside the image.
    pub fn contains(&self, rect: Rect) -> bool {
        rect.is_valid_in(self.width, self.height)
    }
}

/// What a render did.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    /// Wall time of the region's image loop \[s\].
    pub seconds: f64,
    /// Thread time in direct lighting, caustic estimates, final gathers, specular
    /// recursion (inclusive of what it calls) and cache lookups \[s\].
    pub thread_seconds: [(String, f64); 5],
    /// Final gathers: those of the cache's records plus those done while rendering
    /// (cache misses and uncached shading points).
    pub final_gathers: u64,
    /// Records of the irradiance cache in use.
    pub cache_records: u64,
    /// Shading points served by cache interpolation.
    pub cache_hits: u64,
    /// Final-gather rays traced, secondary ones included.
    pub gather_rays: u64,
    /// Secondary final gathers.
    pub secondary_gathers: u64,
    /// Photon-map lookups at gather-ray hits.
    pub lookups: u64,
    /// Precomputed lookups that found no similar photon within the search radius.
    pub lookup_misses: u64,
    /// Rank of the accepted photon in precomputed lookups: 1st, 2nd, later.
    pub lookup_rank: [u64; 3],
    /// Paths cut by the depth limit.
    pub terminated_paths: u64,
    /// Shading points where indirect light was below the importance threshold and
    /// the photon-map estimate replaced a final gather.
    pub thinned: u64,
    /// Pixel values that came out NaN or infinite and were written as 0 (should be 0).
    pub nonfinite_pixels: u64,
    /// Eye samples traced in the region.
    pub samples: u64,
    /// Pixels of the region that were supersampled.
    pub supersampled_pixels: u64,
}

impl Counters {
    /// The counters as statistics (the image loop fills its own fields).
    pub fn stats(&self) -> RenderStats {
        let secs = |a: &AtomicU64| a.load(Relaxed) as f64 * 1e-9;
        RenderStats {
            thread_seconds: [
                ("direct".into(), secs(&self.ns_direct)),
                ("caustics".into(), secs(&self.ns_caustic)),
                ("final_gather".into(), secs(&self.ns_gather)),
                ("specular".into(), secs(&self.ns_specular)),
                ("irradiance_cache".into(), secs(&self.ns_icache)),
            ],
            final_gathers: self.gathers.load(Relaxed) + self.cache_records.load(Relaxed),
            cache_records: self.cache_records.load(Relaxed),
            cache_hits: self.cache_hits.load(Relaxed),
            gather_rays: self.gather_rays.load(Relaxed),
            secondary_gathers: self.secondary_gathers.load(Relaxed),
            lookups: self.lookups.load(Relaxed),
            lookup_misses: self.lookup_misses.load(Relaxed),
            lookup_rank: self.lookup_rank.each_ref().map(|a| a.load(Relaxed)),
            terminated_paths: self.terminated_paths.load(Relaxed),
            thinned: self.thinned.load(Relaxed),
            ..Default::default()
        }
    }
}

/// The seed of pixel `i` (row-major index in the whole image): every sample's
/// random numbers are keyed by (seed, pixel, sample index), never by thread or tile.
pub(crate) fn pixel_seed(seed: u64, i: usize) -> u64 {
    mix64(seed ^ mix64(pixel_salt(i)))
}

/// The salt of pixel `i` (see [`pixel_seed`]).
pub fn pixel_salt(i: usize) -> u64 {
    0x7069_7865_6c00 ^ i as u64
}

/// The variance of the mean of `n` (at least 2) independent estimates from their
/// sum and the sum of their squares: the progressive methods' per-pixel noise
/// from the spread of their passes [(W sr^-1 m^-2)^2].
pub fn variance_of_mean(sum: f32, sum_sq: f32, n: u32) -> f32 {
    let (s, s2, p) = (sum as f64, sum_sq as f64, n as f64);
    (((s2 - s * s / p) / (p - 1.0)).max(0.0) / p) as f32
}
