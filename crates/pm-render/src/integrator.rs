//! Eye paths of the photon-map renderer: recursive specular reflection and
//! refraction, and at non-specular hits the components of Christensen 1999
//! section 1.3 (direct, caustics, soft indirect) or one of the inspection modes.

use crate::gather::{Scratch, final_gather, lookup_irradiance};
use crate::icache::IrradianceCache;
use crate::{Ctx, Mode, facing};
use glam::Vec3;
use pm_color::Rgb;
use pm_estimate::{Filter, KnnParams};
use pm_format::PhotonRecord;
use pm_sampling::Sampler;
use std::f32::consts::PI;
use std::sync::atomic::Ordering::Relaxed;
use std::time::Instant;

/// Specular bounces up to this depth trace both reflection and refraction (weighted
/// by Fresnel); deeper ones pick one by Fresnel probability.
const SPLIT_DEPTH: u32 = 3;

/// Radiance components of one eye sample [W sr^-1 m^-2].
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Components {
    /// Emission seen directly plus direct light at the first non-specular hit.
    pub direct: Rgb,
    /// Caustic-map radiance at the first non-specular hit.
    pub caustic: Rgb,
    /// Soft indirect light (final gather or cache) at the first non-specular hit.
    pub indirect: Rgb,
    /// Everything seen through one or more specular bounces.
    pub specular: Rgb,
}

impl Components {
    pub fn total(&self) -> Rgb {
        self.direct + self.caustic + self.indirect + self.specular
    }
}

fn elapsed_ns(t: Instant) -> u64 {
    t.elapsed().as_nanos() as u64
}

/// Soft indirect irradiance at a non-specular point: interpolated from the cache
/// when a record covers it, else a fresh final gather.
pub(crate) fn indirect_irradiance<G: PhotonRecord>(
    ctx: &Ctx<G>,
    p: Vec3,
    ns: Vec3,
    ng: Vec3,
    s: &mut Sampler,
    scratch: &mut Scratch,
    cache: Option<&IrradianceCache>,
) -> Rgb {
    if let Some(c) = cache {
        let t = Instant::now();
        let e = c.lookup(p, ns, 2.0);
        ctx.stats.ns_icache.fetch_add(elapsed_ns(t), Relaxed);
        if let Some(e) = e {
            ctx.stats.cache_hits.fetch_add(1, Relaxed);
            return e;
        }
    }
    let t = Instant::now();
    ctx.stats.gathers.fetch_add(1, Relaxed);
    let g = final_gather(ctx, p, ns, ng, ctx.cfg.gather_rays, s, true, scratch);
    ctx.stats.ns_gather.fetch_add(elapsed_ns(t), Relaxed);
    g.e
}

/// Where indirect light matters little (Christensen 1999 section 1.3: "if the
/// importance is low, the irradiance is estimated from the photons"), the photon
/// map's indirect irradiance: the precomputed total irradiance minus the direct
/// irradiance just computed by light sampling, used when it is below
/// `indirect_threshold` x the direct irradiance. `direct_l` is the reflected direct
/// radiance, turned back into irradiance through the albedo.
pub(crate) fn cheap_indirect<G: PhotonRecord>(
    ctx: &Ctx<G>,
    p: Vec3,
    n: Vec3,
    albedo: Rgb,
    direct_l: Rgb,
    scratch: &mut Scratch,
) -> Option<Rgb> {
    let t = ctx.cfg.indirect_threshold;
    if !(t > 0.0) || ctx.maps.irradiance.is_none() {
        return None;
    }
    let e_direct = Rgb::new(
        if albedo.x > 0.0 { PI * direct_l.x / albedo.x } else { 0.0 },
        if albedo.y > 0.0 { PI * direct_l.y / albedo.y } else { 0.0 },
        if albedo.z > 0.0 { PI * direct_l.z / albedo.z } else { 0.0 },
    );
    let e_total = lookup_irradiance(ctx, p, n, scratch);
    let e_ind = (e_total - e_direct).max(Rgb::ZERO);
    (pm_color::mean(e_ind) < t * pm_color::mean(e_direct)).then(|| {
        ctx.stats.thinned.fetch_add(1, Relaxed);
        e_ind
    })
}

/// Radiance components along the ray from `o` in direction `d`.
pub(crate) fn trace<G: PhotonRecord>(
    ctx: &Ctx<G>,
    o: Vec3,
    d: Vec3,
    depth: u32,
    s: &mut Sampler,
    scratch: &mut Scratch,
    cache: Option<&IrradianceCache>,
) -> Components {
    let scene = ctx.scene;
    let cfg = ctx.cfg;
    let Some(hit) = scene.intersect(o, d, f32::INFINITY) else { return Components::default() };
    let wo = -d;
    let le = scene.emitted(&hit, wo);
    let bsdf = scene.bsdf(&hit);
    if bsdf.is_specular() {
        if depth >= cfg.max_depth {
            ctx.stats.terminated_paths.fetch_add(1, Relaxed);
            return Components { specular: le, ..Default::default() };
        }
        let t0 = Instant::now();
        let mut l = le;
        let follow = |s: &mut Sampler, scratch: &mut Scratch, wi: Vec3, w: Rgb| -> Rgb {
            let o2 = ctx.scene.offset_origin(hit.p, hit.ng, wi);
            w * trace(ctx, o2, wi, depth + 1, s, scratch, cache).total()
        };
        let u = s.next_2d();
        let uc = s.next_1d();
        if depth < SPLIT_DEPTH {
            // Both Fresnel branches: sample with uc at either end of [0, 1).
            let refl = bsdf.sample(wo, hit.ns, u, 0.0);
            let refr = bsdf.sample(wo, hit.ns, u, 1.0 - f32::EPSILON);
            match (refl, refr) {
                (Some(a), Some(b)) if b.transmitted => {
                    l += follow(s, scratch, a.wi, a.weight * a.pdf);
                    l += follow(s, scratch, b.wi, b.weight * b.pdf);
                }
                // Mirror, or total internal reflection: one branch of probability 1.
                (Some(a), _) => l += follow(s, scratch, a.wi, a.weight * a.pdf),
                _ => {}
            }
        } else if let Some(bs) = bsdf.sample(wo, hit.ns, u, uc) {
            l += follow(s, scratch, bs.wi, bs.weight);
        }
        ctx.stats.ns_specular.fetch_add(elapsed_ns(t0), Relaxed);
        return Components { specular: l, ..Default::default() };
    }
    let n = facing(hit.ng, wo);
    let ns = facing(hit.ns, wo);
    let albedo = bsdf.diffuse_albedo();
    match cfg.mode {
        Mode::Photons => {
            let e = match &ctx.maps.global {
                Some(tree) => {
                    let p = KnnParams {
                        k: cfg.k_global,
                        max_d2: cfg.max_radius_global * cfg.max_radius_global,
                        filter: Filter::None,
                    };
                    pm_estimate::irradiance(tree, hit.p, n, &p, &mut scratch.knn).e
                }
                None => Rgb::ZERO,
            };
            Components { direct: le, indirect: albedo * e / PI, ..Default::default() }
        }
        Mode::Radiance => {
            let e = lookup_irradiance(ctx, hit.p, n, scratch);
            Components { direct: le, indirect: albedo * e / PI, ..Default::default() }
        }
        Mode::Indirect => {
            let e = indirect_irradiance(ctx, hit.p, ns, n, s, scratch, cache);
            Components { indirect: albedo * e / PI, ..Default::default() }
        }
        Mode::Full | Mode::Path => {
            let t = Instant::now();
            let direct = le + crate::direct::direct(ctx, &hit, &bsdf, wo, s, cfg.light_samples);
            ctx.stats.ns_direct.fetch_add(elapsed_ns(t), Relaxed);
            let t = Instant::now();
            let caustic = match &ctx.maps.caustic {
                Some(tree) => {
                    let p = KnnParams {
                        k: cfg.k_caustic,
                        max_d2: cfg.max_radius_caustic * cfg.max_radius_caustic,
                        filter: Filter::Cone { k: 1.1 },
                    };
                    pm_estimate::radiance(tree, hit.p, n, &p, &mut scratch.knn, |wi| bsdf.f(wo, wi, hit.ns))
                }
                None => Rgb::ZERO,
            };
            ctx.stats.ns_caustic.fetch_add(elapsed_ns(t), Relaxed);
            let e = if !cfg.indirect {
                Rgb::ZERO
            } else if let Some(e) = cheap_indirect(ctx, hit.p, n, albedo, direct - le, scratch) {
                e
            } else {
                indirect_irradiance(ctx, hit.p, ns, n, s, scratch, cache)
            };
            Components { direct, caustic, indirect: albedo * e / PI, specular: Rgb::ZERO }
        }
    }
}

/// The non-specular hits an eye ray reaches, following specular bounces exactly as
/// [`trace`] does (both Fresnel branches up to `SPLIT_DEPTH`, the more likely one
/// after): where the irradiance-cache prepass puts records. Each is the hit and the
/// direction toward the viewer.
pub(crate) fn diffuse_points<G: PhotonRecord>(
    ctx: &Ctx<G>,
    o: Vec3,
    d: Vec3,
    depth: u32,
    out: &mut Vec<(pm_scene::Hit, Vec3)>,
) {
    let Some(hit) = ctx.scene.intersect(o, d, f32::INFINITY) else { return };
    let bsdf = ctx.scene.bsdf(&hit);
    if !bsdf.is_specular() {
        out.push((hit, -d));
        return;
    }
    if depth >= ctx.cfg.max_depth {
        return;
    }
    let Some(refl) = bsdf.sample(-d, hit.ns, glam::Vec2::ZERO, 0.0) else { return };
    let refr = bsdf.sample(-d, hit.ns, glam::Vec2::ZERO, 1.0 - f32::EPSILON).filter(|t| t.transmitted);
    let mut go = |wi: Vec3| diffuse_points(ctx, ctx.scene.offset_origin(hit.p, hit.ng, wi), wi, depth + 1, out);
    match refr {
        Some(t) if depth < SPLIT_DEPTH => {
            go(refl.wi);
            go(t.wi);
        }
        Some(t) if t.pdf > refl.pdf => go(t.wi),
        _ => go(refl.wi),
    }
}
