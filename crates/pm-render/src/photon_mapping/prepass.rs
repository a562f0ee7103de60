//! The irradiance-cache prepass (Ward and Heckbert 1992 records placed where
//! rendering will look them up), driven by the photon-map integrator's final
//! gathers.

use super::gather::{GatherFor, GatherPoint, final_gather};
use super::scratch::Scratch;
use super::{PhotonMapping, cheap_indirect, diffuse_points};
use crate::icache::IrradianceCache;
use crate::integrator::{Film, pixel_seed};
use pm_format::PhotonRecord;
use pm_sampling::{Sampler, mix64};
use pm_scene::Camera;
use rayon::prelude::*;
impl IrradianceCache {
    /// The irradiance-cache prepass over the image `film` of `camera`: coarse-to-fine
    /// grids of pixel centres (steps 32, 16, ..., 1); at each level the points no
    /// record covers yet get a final gather (in parallel), and the new records are
    /// inserted in pixel order, so the cache does not depend on threads. Eye rays
    /// follow mirrors and glass to the surfaces they show (Ward and Heckbert 1992's
    /// records at the points rendering will look up).
    pub fn prepass<G: PhotonRecord>(pm: &PhotonMapping<G>, camera: &Camera, film: &Film) -> IrradianceCache {
        let cfg = pm.config();
        let mut cache = IrradianceCache::new(cfg.icache_accuracy, cfg.icache_spacing);
        let (w, h) = (film.width as usize, film.height as usize);
        let aspect = film.width as f32 / film.height as f32;
        let mut step = 32usize;
        let eye_medium = pm.scene.eye_medium(camera.position);
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
                    diffuse_points(pm, camera.position, d, 0, eye_medium, &mut points);
                    let mut scratch = Scratch::default();
                    let cache = &cache;
                    points.into_iter().enumerate().filter_map(move |(b, (hit, wo, medium))| {
                        let (ns, ng) = (crate::facing(hit.ns, wo), crate::facing(hit.ng, wo));
                        if pm.cached_irradiance(cache, hit.p, ns, ng, 1.0).is_some() {
                            return None;
                        }
                        let mut s = Sampler::new(mix64(pixel_seed(film.seed, i) ^ 0x0063_6163_6865 ^ b as u64), 0);
                        // No record where indirect light is unimportant: rendering will
                        // use the photon-map estimate there (same test, same result).
                        if cfg.indirect_threshold > 0.0 {
                            let bsdf = pm.scene.bsdf(&hit);
                            let direct = pm.light.direct(&hit, &bsdf, wo, &mut s, cfg.light_samples, medium);
                            if cheap_indirect(pm, hit.p, ng, bsdf.albedo(wo, hit.ns), direct, &mut scratch).is_some() {
                                return None;
                            }
                        }
                        let at = GatherPoint { x: hit.p, ns, ng, medium };
                        let g = final_gather(pm, &at, cfg.gather_rays, &mut s, GatherFor::Record, &mut scratch);
                        Some((hit.p, ns, g))
                    })
                })
                .collect();
            for (p, ns, g) in &new {
                cache.insert(*p, *ns, g);
            }
            cache.clamp_to_neighbours();
            if step == 1 {
                break;
            }
            step /= 2;
        }
        cache
    }
}
