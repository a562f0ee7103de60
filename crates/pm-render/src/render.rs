//! The image loop: the irradiance-cache prepass, then one sample per pixel,
//! then adaptive supersampling where neighbouring pixels differ (Christensen 1999
//! section 3: "up to 16 samples per pixel"), with a box pixel filter.

use crate::gather::{Scratch, final_gather};
use crate::icache::IrradianceCache;
use crate::integrator::{Components, cheap_indirect, diffuse_points, trace};
use crate::{Ctx, Maps, Mode, RenderConfig};
use glam::Vec2;
use pm_color::Rgb;
use pm_format::PhotonRecord;
use pm_sampling::{Sampler, mix64};
use pm_scene::Scene;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Instant;

/// Counters shared by all threads (sums, so their totals do not depend on the
/// thread schedule).
#[derive(Default)]
pub(crate) struct Counters {
    pub gathers: AtomicU64,
    pub cache_hits: AtomicU64,
    pub gather_rays: AtomicU64,
    pub secondary_gathers: AtomicU64,
    pub lookups: AtomicU64,
    pub lookup_misses: AtomicU64,
    pub lookup_rank: [AtomicU64; 3],
    pub terminated_paths: AtomicU64,
    pub nonfinite: AtomicU64,
    pub thinned: AtomicU64,
    pub ns_direct: AtomicU64,
    pub ns_caustic: AtomicU64,
    pub ns_gather: AtomicU64,
    pub ns_specular: AtomicU64,
    pub ns_icache: AtomicU64,
}

/// What a render did.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    /// Wall time of the whole render [s].
    pub seconds: f64,
    /// Wall time of the irradiance-cache prepass [s].
    pub prepass_seconds: f64,
    /// Thread time in direct lighting, caustic estimates, final gathers (outside the
    /// prepass), specular recursion (inclusive of what it calls) and cache lookups [s].
    pub thread_seconds: [(String, f64); 5],
    /// Final gathers done (cache records plus uncached gathers).
    pub final_gathers: u64,
    /// Irradiance-cache records.
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
    /// Eye samples traced.
    pub samples: u64,
    /// Pixels that were supersampled.
    pub supersampled_pixels: u64,
}

/// A rendered image: linear radiance [W sr^-1 m^-2] per pixel, row 0 at the top,
/// with its component layers.
#[derive(Clone, Debug)]
pub struct Image {
    /// Width [pixels].
    pub width: u32,
    /// Height [pixels].
    pub height: u32,
    /// ("total" | "direct" | "caustic" | "indirect" | "specular", pixels).
    pub layers: Vec<(&'static str, Vec<Rgb>)>,
}

impl Image {
    /// The layer called `name`.
    pub fn layer(&self, name: &str) -> Option<&[Rgb]> {
        self.layers.iter().find(|l| l.0 == name).map(|l| l.1.as_slice())
    }
}

const LAYERS: [&str; 5] = ["total", "direct", "caustic", "indirect", "specular"];

/// Render the scene's first camera. Deterministic: every sample's random numbers are
/// keyed by (seed, pixel, sample index).
pub fn render<G: PhotonRecord>(
    scene: &Scene,
    maps: &Maps<G>,
    cfg: &RenderConfig,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, RenderStats), String> {
    let camera = scene.camera.as_ref().ok_or("the scene has no camera")?;
    let lights = pm_photon::LightSelector::new(scene, &[]).map_err(|e| e.to_string())?;
    let counters = Counters::default();
    let ctx = Ctx { scene, maps, cfg, lights, stats: &counters };
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let aspect = cfg.width as f32 / cfg.height as f32;
    let start = Instant::now();
    let pixel_seed = |i: usize| mix64(cfg.seed ^ mix64(0x7069_7865_6c00 ^ i as u64));

    // Irradiance-cache prepass: coarse-to-fine grids of pixel centres; at each level
    // the points no record covers yet get a final gather (in parallel), and the new
    // records are inserted in pixel order, so the cache does not depend on threads.
    let use_cache = cfg.icache_accuracy > 0.0 && cfg.indirect && matches!(cfg.mode, Mode::Full | Mode::Indirect);
    let mut cache = IrradianceCache::new(cfg.icache_accuracy, cfg.icache_spacing);
    let t_pre = Instant::now();
    if use_cache {
        let mut step = 32usize;
        loop {
            let pts: Vec<usize> = (0..h)
                .step_by(step)
                .flat_map(|y| (0..w).step_by(step).map(move |x| y * w + x))
                .filter(|&i| step == 32 || (i / w) % (2 * step) != 0 || (i % w) % (2 * step) != 0)
                .collect();
            let new: Vec<_> = pts
                .par_iter()
                .flat_map_iter(|&i| {
                    let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                    let d = camera.ray_direction(x / w as f32, y / h as f32, aspect);
                    let mut points = Vec::new();
                    diffuse_points(&ctx, camera.position, d, 0, &mut points);
                    let mut scratch = Scratch::default();
                    let cache = &cache;
                    let ctx = &ctx;
                    points.into_iter().enumerate().filter_map(move |(b, (hit, wo))| {
                        let (ns, ng) = (crate::facing(hit.ns, wo), crate::facing(hit.ng, wo));
                        if cache.lookup(hit.p, ns, 1.0).is_some() {
                            return None;
                        }
                        let mut s = Sampler::new(mix64(pixel_seed(i) ^ 0x0063_6163_6865 ^ b as u64), 0);
                        // No record where indirect light is unimportant: rendering will
                        // use the photon-map estimate there (same test, same result).
                        if cfg.indirect_threshold > 0.0 {
                            let bsdf = ctx.scene.bsdf(&hit);
                            let direct = crate::direct::direct(ctx, &hit, &bsdf, wo, &mut s, cfg.light_samples);
                            if cheap_indirect(ctx, hit.p, ng, bsdf.diffuse_albedo(), direct, &mut scratch).is_some() {
                                return None;
                            }
                        }
                        let g = final_gather(ctx, hit.p, ns, ng, cfg.gather_rays, &mut s, true, &mut scratch);
                        Some((hit.p, ns, g))
                    })
                })
                .collect();
            for (p, ns, g) in &new {
                cache.insert(*p, *ns, g);
            }
            if step == 1 {
                break;
            }
            step /= 2;
        }
    }
    let prepass_seconds = t_pre.elapsed().as_secs_f64();
    let cache_ref = use_cache.then_some(&cache);
    let records = cache.len() as u64;

    let sample = |i: usize, k: u32, scratch: &mut Scratch| -> Components {
        let mut s = Sampler::new(pixel_seed(i), k as u64);
        let j = if k == 0 && cfg.mode != Mode::Path { Vec2::splat(0.5) } else { s.next_2d() };
        let (x, y) = ((i % w) as f32 + j.x, (i / w) as f32 + j.y);
        let d = camera.ray_direction(x / w as f32, y / h as f32, aspect);
        if cfg.mode == Mode::Path {
            crate::path::path_radiance(&ctx, camera.position, d, &mut s)
        } else {
            trace(&ctx, camera.position, d, 0, &mut s, scratch, cache_ref)
        }
    };
    let done = AtomicU64::new(0);
    let total = (w * h) as u64;
    let first_spp = if cfg.mode == Mode::Path { cfg.spp.max(1) } else { 1 };
    // Pass 1: every pixel.
    let mut pixels: Vec<(Components, u32)> = (0..w * h)
        .into_par_iter()
        .chunks(64)
        .map_init(Scratch::default, |scratch, idx| {
            let out: Vec<(Components, u32)> = idx
                .iter()
                .map(|&i| {
                    let mut acc = Components::default();
                    for k in 0..first_spp {
                        add(&mut acc, &sample(i, k, scratch));
                    }
                    (acc, first_spp)
                })
                .collect();
            let n = done.fetch_add(out.len() as u64, Relaxed) + out.len() as u64;
            progress(n, total);
            out
        })
        .flatten()
        .collect();
    // Pass 2: supersample where a 4-neighbour differs by more than the contrast
    // threshold (Mitchell's contrast |a - b| / (a + b) on luminance).
    let mut supersampled = 0;
    if cfg.mode != Mode::Path && cfg.spp > 1 {
        let lum: Vec<f32> = pixels.iter().map(|(c, n)| pm_color::luminance(c.total()) / *n as f32).collect();
        let contrast = |a: f32, b: f32| (a - b).abs() / (a + b).max(1e-6);
        let mark: Vec<usize> = (0..w * h)
            .filter(|&i| {
                let (x, y) = (i % w, i / w);
                let l = lum[i];
                (x > 0 && contrast(l, lum[i - 1]) > cfg.contrast)
                    || (x + 1 < w && contrast(l, lum[i + 1]) > cfg.contrast)
                    || (y > 0 && contrast(l, lum[i - w]) > cfg.contrast)
                    || (y + 1 < h && contrast(l, lum[i + w]) > cfg.contrast)
            })
            .collect();
        supersampled = mark.len() as u64;
        let extra: Vec<(usize, Components)> = mark
            .par_iter()
            .map_init(Scratch::default, |scratch, &i| {
                let mut acc = Components::default();
                for k in 1..cfg.spp {
                    add(&mut acc, &sample(i, k, scratch));
                }
                (i, acc)
            })
            .collect();
        for (i, acc) in extra {
            add(&mut pixels[i].0, &acc);
            pixels[i].1 = cfg.spp;
        }
    }
    let mut layers: Vec<(&'static str, Vec<Rgb>)> = LAYERS.iter().map(|&n| (n, Vec::with_capacity(w * h))).collect();
    let mut samples = 0u64;
    for (c, n) in &pixels {
        samples += *n as u64;
        let inv = 1.0 / *n as f32;
        let vals = [c.total(), c.direct, c.caustic, c.indirect, c.specular];
        for (layer, v) in layers.iter_mut().zip(vals) {
            // No NaN or Inf leaves the renderer.
            if v.is_finite() {
                layer.1.push((v * inv).max(Rgb::ZERO));
            } else {
                counters.nonfinite.fetch_add(1, Relaxed);
                layer.1.push(Rgb::ZERO);
            }
        }
    }
    let c = &counters;
    let secs = |a: &AtomicU64| a.load(Relaxed) as f64 * 1e-9;
    let stats = RenderStats {
        seconds: start.elapsed().as_secs_f64(),
        prepass_seconds,
        thread_seconds: [
            ("direct".into(), secs(&c.ns_direct)),
            ("caustics".into(), secs(&c.ns_caustic)),
            ("final_gather".into(), secs(&c.ns_gather)),
            ("specular".into(), secs(&c.ns_specular)),
            ("irradiance_cache".into(), secs(&c.ns_icache)),
        ],
        final_gathers: c.gathers.load(Relaxed) + records,
        cache_records: records,
        cache_hits: c.cache_hits.load(Relaxed),
        gather_rays: c.gather_rays.load(Relaxed),
        secondary_gathers: c.secondary_gathers.load(Relaxed),
        lookups: c.lookups.load(Relaxed),
        lookup_misses: c.lookup_misses.load(Relaxed),
        lookup_rank: [c.lookup_rank[0].load(Relaxed), c.lookup_rank[1].load(Relaxed), c.lookup_rank[2].load(Relaxed)],
        terminated_paths: c.terminated_paths.load(Relaxed),
        nonfinite_pixels: c.nonfinite.load(Relaxed),
        thinned: c.thinned.load(Relaxed),
        samples,
        supersampled_pixels: supersampled,
    };
    Ok((Image { width: cfg.width, height: cfg.height, layers }, stats))
}

fn add(acc: &mut Components, c: &Components) {
    acc.direct += c.direct;
    acc.caustic += c.caustic;
    acc.indirect += c.indirect;
    acc.specular += c.specular;
}
