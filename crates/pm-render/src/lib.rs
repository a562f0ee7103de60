//! Rendering from photon maps (Christensen 1999 sections 1.3, 2.2 and 3): eye rays
//! with adaptive supersampling, recursive specular reflection and refraction, direct
//! light by sampling the lights (multiple importance sampling for glossy surfaces),
//! caustics from the caustic map, and soft indirect light by final gathering, whose
//! rays read either an exact k-nearest estimate or the precomputed irradiance of
//! the nearest photon with a similar normal; final gathers are made sparse by Ward and
//! Heckbert's irradiance cache with gradients. An unbiased path tracer over the same
//! scene model and BSDFs is the reference.
//!
//! Radiance everywhere is W sr^-1 m^-2 per RGB channel. This crate does no I/O: it
//! returns an in-memory image with component layers and statistics.

mod direct;
mod gather;
mod icache;
mod integrator;
mod path;
mod render;

pub use render::{Image, RenderStats, render};

use glam::Vec3;
use pm_format::{FullPhoton, PhotonRecord, flags};
use pm_kdtree::KdTree;
use pm_scene::Scene;

/// What the renderer computes at each pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Direct light, specular, caustics and final-gathered indirect light.
    Full,
    /// Radiance estimated from the global map at the eye hit (Figure 1b).
    Photons,
    /// Precomputed irradiance x reflectance / pi at the eye hit (Figures 1c-1e).
    Radiance,
    /// The final-gathered soft indirect term alone (Figure 1f).
    Indirect,
    /// Unbiased path tracing with next-event estimation and MIS: the reference.
    Path,
}

/// How final-gather rays get the radiance at their hit points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lookup {
    /// Precomputed irradiance of the nearest photon with a similar normal (section 2.2).
    Precomputed,
    /// A k-nearest irradiance estimate at the hit point.
    Exact,
}

/// Render settings. Lengths are absolute metres (the stage converts the relative
/// values the user gives).
#[derive(Clone, Debug)]
pub struct RenderConfig {
    /// Image width [pixels].
    pub width: u32,
    /// Image height [pixels].
    pub height: u32,
    /// Most samples per pixel (adaptive supersampling; `path` mode always takes all).
    pub spp: u32,
    /// Contrast between neighbouring pixels that triggers supersampling.
    pub contrast: f32,
    /// What to compute.
    pub mode: Mode,
    /// Compute soft indirect light (final gathering); off when the scene analysis
    /// finds no diffusely reflected light reaching another diffuse surface.
    pub indirect: bool,
    /// Importance threshold (Christensen 1999 section 1.3): where the photon map says
    /// indirect irradiance is below this fraction of the direct irradiance, the
    /// photon-map estimate is used instead of a final gather; 0 always gathers.
    pub indirect_threshold: f32,
    /// Final-gather rays per gather (stratified, cosine-distributed).
    pub gather_rays: u32,
    /// Rays of a secondary final gather (the paper: 12).
    pub secondary_rays: u32,
    /// Gather rays shorter than this trigger a secondary gather [m].
    pub secondary_distance: f32,
    /// Final-gather lookup.
    pub lookup: Lookup,
    /// Photons per estimate in the global map.
    pub k_global: usize,
    /// Photons per caustic estimate.
    pub k_caustic: usize,
    /// Largest search radius in the global map [m].
    pub max_radius_global: f32,
    /// Largest search radius in the caustic map [m].
    pub max_radius_caustic: f32,
    /// Irradiance-cache accuracy a (Ward's error bound; smaller is finer); 0 disables
    /// the cache (a final gather at every shading point).
    pub icache_accuracy: f32,
    /// Smallest and largest record spacing of the irradiance cache [m].
    pub icache_spacing: (f32, f32),
    /// Light samples per shading point for direct light.
    pub light_samples: u32,
    /// Specular recursion depth; paths cut here are counted.
    pub max_depth: u32,
    /// Random seed.
    pub seed: u64,
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
}

/// The photons of a kd-tree map that carry a precomputed irradiance, as their own
/// balanced tree (empty when none do).
pub fn irradiance_subset<G: PhotonRecord>(global: &[G]) -> Vec<G> {
    let with: Vec<G> = global.iter().copied().filter(|r| r.flags() & flags::HAS_IRRADIANCE != 0).collect();
    pm_kdtree::balance(&with)
}

/// The renderer's view of everything it needs.
pub(crate) struct Ctx<'a, G> {
    pub scene: &'a Scene,
    pub maps: &'a Maps<'a, G>,
    pub cfg: &'a RenderConfig,
    pub lights: pm_photon::LightSelector,
    pub stats: &'a render::Counters,
}

/// Flip `n` to the side of `w`.
#[inline]
pub(crate) fn facing(n: Vec3, w: Vec3) -> Vec3 {
    if n.dot(w) < 0.0 { -n } else { n }
}
