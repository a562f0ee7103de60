//! What each stage writes as `--stats-json`, as types: the stage serialises one and
//! the runner (`pm-runner`), the accuracy study and the figure tasks read it back
//! into the same type, so writer and reader cannot disagree on a key. Times are wall
//! times \[s\]; powers are W per RGB channel.

use pm_estimate::IrradianceParams;
use pm_render::RenderParams;

/// What a tracing run did: written as `--stats-json` and read back by the runner
/// into this type, so the writer and the reader cannot disagree on a key.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TraceReport {
    /// Scene file.
    pub scene: String,
    /// Worker threads.
    pub threads: usize,
    /// Each light, its power [W per channel] and the probability of emitting from it.
    pub lights: Vec<LightReport>,
    /// The global map.
    pub global: MapReport,
    /// The caustic map.
    pub caustic: MapReport,
    /// The volume map.
    #[serde(default)]
    pub volume: MapReport,
    /// Wall time of the stage \[s\].
    pub seconds: f64,
}

/// One light of [`TraceReport`].
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct LightReport {
    /// Its name.
    pub name: String,
    /// Emitted power Phi [W per channel].
    pub power_w: [f32; 3],
    /// Probability of choosing it for a photon.
    pub selection_probability: f64,
}

/// One map of [`TraceReport`]: why it was skipped, or what tracing it did.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct MapReport {
    /// Why no map was written (absent when one was).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
    /// Photons emitted (the power scale's N).
    pub emitted: u64,
    /// Photons stored.
    pub stored: u64,
    /// Stored photons by bounces before the store (index 0: direct).
    pub stored_per_bounce: Vec<u64>,
    /// Photons emitted per light, by light name.
    pub emitted_per_light: Vec<(String, u64)>,
    /// Per light, the fraction of its photons whose first ray hit the scene (an
    /// environment's photons start on the bounding sphere's disc: most miss an
    /// object that fills little of it, or a room seen through a window).
    #[serde(default)]
    pub reached_fraction_per_light: Vec<(String, f64)>,
    /// Rays traced.
    pub rays: u64,
    /// Paths cut by the bounce limit.
    pub truncated_paths: u64,
    /// True when emission stopped at the cap before reaching the target.
    pub hit_emission_cap: bool,
    /// Sum of stored photon power [W per channel].
    pub total_power_w: [f64; 3],
    /// Wall time \[s\].
    pub seconds: f64,
    /// Photon paths per second.
    pub paths_per_second: f64,
    /// Rays per second.
    pub rays_per_second: f64,
}

/// What a sort did: written as `--stats-json` and read back by the runner.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SortReport {
    /// Input map.
    pub input: String,
    /// Photons sorted.
    pub photons: usize,
    /// Depth of the kd-tree.
    pub depth: u32,
    /// Bytes per record.
    pub record_bytes: usize,
    /// Wall time \[s\].
    pub seconds: f64,
    /// Worker threads.
    pub threads: usize,
}

/// What a precompute did: written as `--stats-json` and read back by the runner.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct IrradianceReport {
    /// Input map.
    pub input: String,
    /// Photons in the map.
    pub photons: usize,
    /// Estimates computed (photons given an irradiance).
    pub computed: u64,
    /// Of those, at photons outside the stratified subset, where the subset's
    /// irradiance changes fast (`refine_ratio`).
    #[serde(default)]
    pub refined: u64,
    /// Estimates that found no photon.
    pub empty_estimates: u64,
    /// Photons under a cover (`flags::COVERED`: another surface faces them from
    /// closer than the cover distance; none without `--scene`).
    #[serde(default)]
    pub covered: u64,
    /// The parameters.
    pub params: IrradianceParams,
    /// Largest search radius used \[m\].
    pub max_radius_m: f32,
    /// The scene diagonal the relative radius refers to \[m\] (from the map's header).
    pub scene_diagonal_m: f32,
    /// Estimate radii \[m\]: 5th, 50th, 95th percentile and largest.
    pub radius_m: [f32; 4],
    /// Estimates whose radius reached the largest search radius.
    pub estimates_at_max_radius: usize,
    /// Wall time \[s\].
    pub seconds: f64,
    /// Wall time per estimate \[us\].
    pub microseconds_per_estimate: f64,
    /// Worker threads.
    pub threads: usize,
}

/// What a render did: written as `--stats-json` and read back by the runner, the
/// trade-off study and figure1 into this type.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct RenderReport {
    /// "full", "photons", "radiance", "indirect", "path", "sppm", or "icache" (--icache-out).
    pub mode: String,
    /// Soft indirect light computed.
    pub indirect: bool,
    /// The render parameters.
    pub params: RenderParams,
    /// Progressive photon mapping's parameters (mode sppm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sppm: Option<pm_methods::SppmParams>,
    /// The region rendered (X0, Y0, X1, Y1), or none for the whole image.
    pub region: Option<[u32; 4]>,
    /// Wall time: the cache prepass plus the image loop \[s\].
    pub seconds: f64,
    /// Wall time of the cache prepass \[s\] (0 when the cache was read from a file).
    pub prepass_seconds: f64,
    /// Thread time per component \[s\] (direct, caustics, final_gather, specular, irradiance_cache).
    pub thread_seconds: std::collections::BTreeMap<String, f64>,
    /// Final gathers: the cache's records plus those done while rendering.
    pub final_gathers: u64,
    /// Irradiance-cache records.
    pub cache_records: u64,
    /// Where the cache came from: "prepass", "file" or "" (none).
    pub cache_source: String,
    /// Shading points served by the cache.
    pub cache_hits: u64,
    /// Final-gather rays, prepass included when it ran in this process.
    pub gather_rays: u64,
    /// Final-gather rays of the prepass.
    pub prepass_gather_rays: u64,
    /// Secondary final gathers.
    pub secondary_gathers: u64,
    /// Photon-map lookups at gather-ray hits.
    pub lookups: u64,
    /// Precomputed lookups that found no similar photon.
    pub lookup_misses: u64,
    /// Rank of the accepted photon in precomputed lookups: 1st, 2nd, later.
    pub lookup_rank_1_2_more: [u64; 3],
    /// Paths cut by the depth limit.
    pub terminated_paths: u64,
    /// Pixel values written as 0 because they came out NaN or infinite.
    pub nonfinite_pixels: u64,
    /// Shading points where the importance threshold replaced a final gather.
    pub thinned_shading_points: u64,
    /// Eye samples.
    pub samples: u64,
    /// Eye samples per pixel of the region.
    pub samples_per_pixel: f64,
    /// Supersampled pixels.
    pub supersampled_pixels: u64,
    /// The scene diagonal relative lengths refer to \[m\].
    pub scene_diagonal_m: f32,
    /// Worker threads.
    pub threads: usize,
    /// Notes printed on stderr.
    pub notes: Vec<String>,
    /// Progressive photon mapping: --time-budget stopped the render before its
    /// --passes, and its --state holds the passes done (run the same command again
    /// to continue; the program exits with [`crate::EXIT_UNFINISHED`]).
    #[serde(default)]
    pub unfinished: bool,
}
