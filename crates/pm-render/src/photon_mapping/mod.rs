//! The photon-map integrator of Christensen 1999 section 1.3 (direct, caustics,
//! soft indirect, with recursive specular reflection and refraction), the
//! inspection views of Figure 1 as their own small integrators over the same
//! specular recursion, final gathering ([`gather`]) and the irradiance-cache
//! prepass ([`prepass`]).

mod gather;
mod prepass;
mod scratch;
mod volume;

pub use scratch::Scratch;

use crate::icache::IrradianceCache;
use crate::integrator::{Components, Counters, Film, FirstHit, Integrator, VisibleSurface};
use crate::{CacheSettings, Maps, RenderParams, Settings, facing};
use gather::{final_gather, lookup_irradiance};
use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_estimate::{Filter, KnnParams};
use pm_format::PhotonRecord;
use pm_light::DirectLighting;
use pm_sampling::Sampler;
use pm_scene::{Hit, MediumId, Scene};
use std::f32::consts::PI;
use std::sync::atomic::Ordering::Relaxed;
/// Specular bounces up to this depth trace both reflection and refraction (weighted
/// by Fresnel, [`pm_bsdf::Bsdf::specular_branches`]); deeper ones pick one by
/// Fresnel probability.
const SPLIT_DEPTH: u32 = 3;

/// The photon-map integrator (Christensen 1999 section 1.3): at the first
/// non-specular hit, direct light + caustics + soft indirect light; mirrors and glass
/// by recursive ray tracing. The inspection views wrap it.
pub struct PhotonMapping<'a, G> {
    pub(crate) scene: &'a Scene,
    pub(crate) maps: Maps<'a, G>,
    pub(crate) cfg: Settings,
    /// What shapes an irradiance cache, as given (relative lengths).
    cache_settings: CacheSettings,
    pub(crate) light: DirectLighting<'a>,
    pub(crate) cache: Option<IrradianceCache>,
    pub(crate) counters: Counters,
}

impl<'a, G: PhotonRecord> PhotonMapping<'a, G> {
    /// The integrator over `scene` and its photon maps with the settings of
    /// `params` (lengths relative to the scene's bounding-box diagonal); `indirect`
    /// false leaves out soft indirect light (for scenes where the analysis finds no
    /// diffusely reflected light reaching another diffuse surface). Fails when
    /// nothing emits.
    pub fn new(
        scene: &'a Scene,
        maps: Maps<'a, G>,
        params: &RenderParams,
        indirect: bool,
    ) -> Result<Self, pm_light::LightSelectError> {
        let cfg = Settings::new(params, scene.bounds.diagonal(), indirect);
        Ok(PhotonMapping {
            scene,
            maps,
            cfg,
            cache_settings: params.cache_settings(),
            light: DirectLighting::with_closed_form(scene)?,
            cache: None,
            counters: Counters::default(),
        })
    }

    /// Interpolate soft indirect light from `cache` (made by
    /// [`IrradianceCache::prepass`] for the same maps and settings).
    pub fn with_cache(mut self, cache: IrradianceCache) -> Self {
        self.counters.cache_records.store(cache.len() as u64, Relaxed);
        self.cache = Some(cache);
        self
    }

    /// The irradiance cache in use.
    pub fn cache(&self) -> Option<&IrradianceCache> {
        self.cache.as_ref()
    }

    /// True when the settings call for an irradiance cache (accuracy above 0 and
    /// soft indirect light computed).
    pub fn wants_cache(&self) -> bool {
        self.cfg.icache_accuracy > 0.0 && self.cfg.indirect
    }

    /// The irradiance [W m^-2 per channel] a final-gather ray reads where it hits a
    /// diffuse surface at `x` with normal `n` (facing the ray's origin), by the
    /// configured lookup: what `benches/lookup.rs` times on its own.
    pub fn gather_lookup(&self, x: Vec3, n: Vec3, scratch: &mut Scratch) -> Rgb {
        lookup_irradiance(self, x, n, scratch)
    }

    pub(crate) fn config(&self) -> &Settings {
        &self.cfg
    }

    /// The record a cache file keeps of what shaped the cache ([`CacheSettings::key`]):
    /// a cache made with other values (or for another image size or seed) must not
    /// be used.
    pub fn cache_key(&self, film: &Film) -> String {
        self.cache_settings.key(self.scene.bounds.diagonal(), film)
    }

    /// The integrator with the irradiance cache of a file's `records`, at its own
    /// accuracy and record spacing.
    pub fn with_cache_records(self, records: &[pm_format::CacheRecord]) -> Self {
        let c = IrradianceCache::from_records(self.cfg.icache_accuracy, self.cfg.icache_spacing, records);
        self.with_cache(c)
    }
}

/// Precomputed irradiance x reflectance / pi at the eye hit: Figure 1 (e), what
/// the final gather sees.
pub struct RadianceView<'a, G>(pub PhotonMapping<'a, G>);
/// Radiance estimated from the global map at the eye hit: Figure 1 (b).
pub struct PhotonsView<'a, G>(pub PhotonMapping<'a, G>);
/// The final-gathered soft indirect term alone: Figure 1 (f).
pub struct IndirectView<'a, G>(pub PhotonMapping<'a, G>);

/// The photon-map integrators differ only in what they compute at the first
/// non-specular hit (`shade`); the specular recursion is [`trace_from`]'s.
macro_rules! photon_map_integrator {
    ($ty:ident, |$pm:ident| $get:expr, $shade:path) => {
        impl<G: PhotonRecord> Integrator for $ty<'_, G> {
            type Scratch = Scratch;
            fn li(
                &self,
                o: Vec3,
                d: Vec3,
                first: FirstHit,
                s: &mut Sampler,
                scratch: &mut Scratch,
                vs: Option<&mut VisibleSurface>,
            ) -> Components {
                let $pm = self;
                let pm = $get;
                let hit = first.resolve(pm.scene, o, d);
                let medium = pm.scene.eye_medium(o);
                let ray = SpecularRay { o, d, depth: 0, medium };
                trace_from(pm, &($shade as Shade<G>), &ray, hit, s, scratch, vs)
            }
            fn volume(&self) -> bool {
                let $pm = self;
                $get.scene.has_scattering_media()
            }
            fn counters(&self) -> &Counters {
                let $pm = self;
                &$get.counters
            }
            fn adaptive(&self) -> bool {
                let $pm = self;
                !$get.scene.has_stochastic_surfaces()
            }
        }
    };
}
photon_map_integrator!(PhotonMapping, |pm| pm, shade_full);
photon_map_integrator!(PhotonsView, |v| &v.0, shade_photons);
photon_map_integrator!(RadianceView, |v| &v.0, shade_radiance);
photon_map_integrator!(IndirectView, |v| &v.0, shade_indirect);

impl<G: PhotonRecord> PhotonMapping<'_, G> {
    /// Indirect irradiance [W m^-2] at `p` (shading normal `ns`, geometric `ng`)
    /// interpolated from `cache`'s records within accuracy x `slack`
    /// ([`IrradianceCache::lookup`]) that `p` sees: the segment between the two
    /// points, each lifted off its surface by the ray offset along `ng`, is not
    /// blocked.
    pub(crate) fn cached_irradiance(
        &self,
        cache: &IrradianceCache,
        p: Vec3,
        ns: Vec3,
        ng: Vec3,
        slack: f32,
    ) -> Option<Rgb> {
        let o = self.scene.offset_origin(p, ng, ng);
        let lift = o - p;
        cache.lookup(p, ns, slack, |q| {
            let d = q + lift - o;
            let l = d.length();
            !(l > 0.0) || !self.scene.occluded(o, d / l, l)
        })
    }
}

/// Soft indirect irradiance at a non-specular point (in medium `medium`):
/// interpolated from the cache when a record covers it, else a fresh final gather.
pub(crate) fn indirect_irradiance<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    p: Vec3,
    ns: Vec3,
    ng: Vec3,
    medium: Option<MediumId>,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    if let Some(c) = &ctx.cache {
        let t = scratch.clock();
        let e = ctx.cached_irradiance(c, p, ns, ng, 2.0);
        scratch::add_time(&ctx.counters.ns_icache, t);
        if let Some(e) = e {
            ctx.counters.cache_hits.fetch_add(1, Relaxed);
            return e;
        }
    }
    let t = scratch.clock();
    ctx.counters.gathers.fetch_add(1, Relaxed);
    let at = gather::GatherPoint { x: p, ns, ng, medium };
    let g = final_gather(ctx, &at, ctx.cfg.gather_rays, s, gather::GatherFor::Estimate, scratch);
    scratch::add_time(&ctx.counters.ns_gather, t);
    g.e
}

/// Where indirect light matters little (Christensen 1999 section 1.3: "if the
/// importance is low, the irradiance is estimated from the photons"), the photon
/// map's indirect irradiance: the precomputed total irradiance minus the direct
/// irradiance just computed by light sampling, used when it is below
/// `indirect_threshold` x the direct irradiance. `direct_l` is the reflected direct
/// radiance, turned back into irradiance through the albedo.
pub(crate) fn cheap_indirect<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
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
        ctx.counters.thinned.fetch_add(1, Relaxed);
        e_ind
    })
}

/// What an integrator computes at the first non-specular hit of an eye path: the
/// hit, its BSDF, the direction toward the viewer, the emitted radiance there, and
/// the G-buffer entry to complete (at the eye ray's own hit only).
type Shade<G> = fn(&PhotonMapping<G>, &At, &mut Sampler, &mut Scratch, Option<&mut VisibleSurface>) -> Components;

/// A non-specular hit as the shading functions see it.
#[derive(Clone, Copy)]
struct At<'h> {
    hit: &'h Hit,
    bsdf: &'h Bsdf,
    /// Toward the viewer.
    wo: Vec3,
    /// Emitted radiance toward the viewer [W sr^-1 m^-2].
    le: Rgb,
    /// The medium the point is in (on the viewer's side).
    medium: Option<MediumId>,
}

/// A ray of the specular recursion: from `o` in unit direction `d`, after `depth`
/// specular bounces, starting in medium `medium`.
#[derive(Clone, Copy, Debug)]
struct SpecularRay {
    o: Vec3,
    d: Vec3,
    depth: u32,
    medium: Option<MediumId>,
}

/// Radiance components along `ray`, whose first hit is `hit`: recursive specular
/// reflection and
/// refraction, and `shade` at the first non-specular hit. Index-matched boundaries
/// are passed; in a medium the segment attenuates what lies beyond it and adds
/// the light scattered toward the viewer along it (the volume layer from the eye,
/// the specular layer seen through mirrors and glass).
fn trace_from<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    shade: &Shade<G>,
    ray: &SpecularRay,
    hit: Option<pm_scene::Hit>,
    s: &mut Sampler,
    scratch: &mut Scratch,
    vs: Option<&mut VisibleSurface>,
) -> Components {
    let SpecularRay { o, d, depth, medium } = *ray;
    let scene = ctx.scene;
    let mut c = match &hit {
        None => {
            // Left the scene: the environment and sun discs, seen directly (a
            // background pixel's direct layer) or through specular bounces.
            let l = scene.escaped(d);
            if depth == 0 {
                Components { direct: l, ..Default::default() }
            } else {
                Components { specular: l, ..Default::default() }
            }
        }
        Some(h) => match scene.index_matched(h) {
            Some(tint) => {
                // Straight through, into the medium beyond.
                let o2 = scene.offset_origin(h.p, h.ng, d);
                let next = scene.intersect(o2, d, f32::INFINITY);
                let m2 = scene.medium_after(h, d, medium);
                let through = SpecularRay { o: o2, d, depth, medium: m2 };
                trace_from(ctx, shade, &through, next, s, scratch, vs).scaled(tint)
            }
            None => trace_hit(ctx, shade, h, ray, s, scratch, vs),
        },
    };
    if !scene.has_media() {
        return c;
    }
    if let Some(m) = scene.medium(medium).filter(|m| !m.is_clear()) {
        let t_seg = scene.segment_length(o, d, hit.as_ref());
        c = c.scaled(m.transmittance(t_seg));
        if m.scatters() {
            let seg = pm_estimate::Segment { o, d, t_max: t_seg, sigma_t: m.sigma_t() };
            let l = volume::eye_inscattered(ctx, &seg, medium, m, s, scratch);
            if depth == 0 {
                c.volume += l;
            } else {
                c.specular += l;
            }
        }
    }
    c
}

/// [`trace_from`] from `ray`'s hit (before the segment's transmittance).
fn trace_hit<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    shade: &Shade<G>,
    hit: &pm_scene::Hit,
    ray: &SpecularRay,
    s: &mut Sampler,
    scratch: &mut Scratch,
    mut vs: Option<&mut VisibleSurface>,
) -> Components {
    let SpecularRay { d, depth, medium, .. } = *ray;
    let (scene, cfg, hit) = (ctx.scene, &ctx.cfg, *hit);
    let wo = -d;
    let le = scene.emitted(&hit, wo);
    let bsdf = scene.bsdf(&hit);
    if let Some(v) = vs.as_deref_mut() {
        *v = VisibleSurface::at(scene, &hit, wo, bsdf, le);
    }
    if !bsdf.is_specular() {
        return shade(ctx, &At { hit: &hit, bsdf: &bsdf, wo, le, medium }, s, scratch, vs);
    }
    if depth >= cfg.max_depth {
        ctx.counters.terminated_paths.fetch_add(1, Relaxed);
        return Components { specular: le, ..Default::default() };
    }
    let t0 = scratch.clock();
    let mut l = le;
    let follow = |s: &mut Sampler, scratch: &mut Scratch, wi: Vec3, w: Rgb| -> Rgb {
        let o2 = ctx.scene.offset_origin(hit.p, hit.ng, wi);
        let m2 = if scene.has_media() { scene.medium_after(&hit, wi, medium) } else { None };
        let next = ctx.scene.intersect(o2, wi, f32::INFINITY);
        let bounce = SpecularRay { o: o2, d: wi, depth: depth + 1, medium: m2 };
        w * trace_from(ctx, shade, &bounce, next, s, scratch, None).total()
    };
    let u = s.next_2d();
    let uc = s.next_1d();
    if depth < SPLIT_DEPTH {
        // Both Fresnel branches (without a reflection, nothing).
        if let [Some(a), b] = bsdf.specular_branches(wo, hit.ns, u) {
            l += follow(s, scratch, a.wi, a.radiance_weight() * a.pdf);
            if let Some(b) = b {
                l += follow(s, scratch, b.wi, b.radiance_weight() * b.pdf);
            }
        }
    } else if let Some(bs) = bsdf.sample(wo, hit.ns, u, uc) {
        l += follow(s, scratch, bs.wi, bs.radiance_weight());
    }
    scratch::add_time(&ctx.counters.ns_specular, t0);
    Components { specular: l, ..Default::default() }
}

/// Figure 1 (b): reflectance / pi x a k-nearest irradiance estimate from the global map.
fn shade_photons<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    at: &At,
    _: &mut Sampler,
    scratch: &mut Scratch,
    _: Option<&mut VisibleSurface>,
) -> Components {
    let At { hit, bsdf, wo, le, .. } = *at;
    let cfg = &ctx.cfg;
    let e = match &ctx.maps.global {
        Some(tree) => {
            let p = KnnParams {
                k: cfg.k_global,
                max_d2: cfg.max_radius_global * cfg.max_radius_global,
                filter: Filter::None,
            };
            pm_estimate::irradiance(tree, hit.p, facing(hit.ng, wo), &p, &mut scratch.knn).e
        }
        None => Rgb::ZERO,
    };
    Components { direct: le, indirect: bsdf.albedo(wo, hit.ns) * e / PI, ..Default::default() }
}

/// Figure 1 (e): reflectance / pi x the precomputed irradiance the final gather reads.
fn shade_radiance<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    at: &At,
    _: &mut Sampler,
    scratch: &mut Scratch,
    _: Option<&mut VisibleSurface>,
) -> Components {
    let At { hit, bsdf, wo, le, .. } = *at;
    let e = lookup_irradiance(ctx, hit.p, facing(hit.ng, wo), scratch);
    Components { direct: le, indirect: bsdf.albedo(wo, hit.ns) * e / PI, ..Default::default() }
}

/// Figure 1 (f): the soft indirect term alone.
fn shade_indirect<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    at: &At,
    s: &mut Sampler,
    scratch: &mut Scratch,
    _: Option<&mut VisibleSurface>,
) -> Components {
    let At { hit, bsdf, wo, medium, .. } = *at;
    if bsdf.is_glossy() {
        return Components {
            indirect: gather::glossy_gather(ctx, hit, bsdf, wo, ctx.cfg.glossy_rays, medium, s, scratch),
            ..Default::default()
        };
    }
    let e = indirect_irradiance(ctx, hit.p, facing(hit.ns, wo), facing(hit.ng, wo), medium, s, scratch);
    Components { indirect: reflected_indirect(ctx, at, bsdf.albedo(wo, hit.ns), e, s, scratch), ..Default::default() }
}

/// The broadest GGX layer (alpha; roughness 0.5) of a glTF dielectric whose
/// reflection of indirect light the eye's shading samples ([`reflected_indirect`]).
/// On a room of Blender's default materials (roughness 1) sampling changed the
/// mean by 0.2% and cost 33% of the render at 1024 x 1024 (a ray's noise drew
/// more samples); with the walls at roughness 0.2 it took 8 x 8 blocks from 4.1%
/// to 3.0% RMS (issue 53; BENCHMARKS.md).
const SAMPLED_LAYER_ALPHA: f32 = 0.25;

/// Indirect radiance a surface that is not glossy reflects toward the eye
/// [W sr^-1 m^-2], its indirect irradiance being `e` [W m^-2]: `albedo` / pi x E
/// (Christensen 1999, section 1.3), `albedo` being its albedo toward `wo`
/// ([`Bsdf::albedo`]); a glTF dielectric with a sharp GGX layer
/// ([`SAMPLED_LAYER_ALPHA`]) has the layer's share sampled as a glossy surface's
/// is ([`Bsdf::layers`]), with the layer's share of `glossy_rays` (at least one
/// ray), and only its base read from E.
fn reflected_indirect<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    at: &At,
    albedo: Rgb,
    e: Rgb,
    s: &mut Sampler,
    scratch: &mut Scratch,
) -> Rgb {
    let At { hit, bsdf, wo, medium, .. } = *at;
    let sharp = bsdf.layer_alpha().is_some_and(|alpha| alpha < SAMPLED_LAYER_ALPHA);
    match sharp.then(|| bsdf.layers(wo, hit.ns)).flatten() {
        None => albedo * e / PI,
        Some(layers) => {
            let rays = (ctx.cfg.glossy_rays as f32 * layers.layer_albedo).ceil() as u32;
            let layer = gather::glossy_gather(ctx, hit, &layers.layer, wo, rays, medium, s, scratch);
            layers.base_albedo * e / PI + layer * layers.layer_weight
        }
    }
}

/// The complete image (section 1.3): direct light by light sampling, caustics from
/// the caustic map, soft indirect light from the cache or a final gather.
fn shade_full<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    at: &At,
    s: &mut Sampler,
    scratch: &mut Scratch,
    vs: Option<&mut VisibleSurface>,
) -> Components {
    let At { hit, bsdf, wo, le, medium } = *at;
    let cfg = &ctx.cfg;
    let n = facing(hit.ng, wo);
    let ns = facing(hit.ns, wo);
    let albedo = bsdf.albedo(wo, hit.ns);
    let t = scratch.clock();
    let reflected = ctx.light.direct(hit, bsdf, wo, s, cfg.light_samples, medium);
    let direct = le + reflected;
    if let Some(v) = vs {
        v.direct = reflected;
    }
    scratch::add_time(&ctx.counters.ns_direct, t);
    let t = scratch.clock();
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
    scratch::add_time(&ctx.counters.ns_caustic, t);
    let indirect = if !cfg.indirect {
        Rgb::ZERO
    } else if bsdf.is_glossy() {
        let t = scratch.clock();
        let l = gather::glossy_gather(ctx, hit, bsdf, wo, cfg.glossy_rays, medium, s, scratch);
        scratch::add_time(&ctx.counters.ns_gather, t);
        l
    } else if let Some(e) = cheap_indirect(ctx, hit.p, n, albedo, direct - le, scratch) {
        albedo * e / PI
    } else {
        let e = indirect_irradiance(ctx, hit.p, ns, n, medium, s, scratch);
        reflected_indirect(ctx, at, albedo, e, s, scratch)
    };
    Components { direct, caustic, indirect, ..Default::default() }
}

/// The non-specular hits an eye ray reaches, following specular bounces exactly as
/// [`trace_from`] does (both Fresnel branches up to `SPLIT_DEPTH`, the more likely one
/// after): where the irradiance-cache prepass puts records (not on glossy
/// surfaces, which gather along their lobes). Each is the hit, the
/// direction toward the viewer and the medium it is in (the ray starts in
/// `medium`; index-matched boundaries are passed).
pub(crate) fn diffuse_points<G: PhotonRecord>(
    ctx: &PhotonMapping<G>,
    o: Vec3,
    d: Vec3,
    depth: u32,
    medium: Option<MediumId>,
    out: &mut Vec<(pm_scene::Hit, Vec3, Option<MediumId>)>,
) {
    let scene = ctx.scene;
    let Some(hit) = scene.intersect(o, d, f32::INFINITY) else { return };
    if scene.index_matched(&hit).is_some() {
        let m2 = scene.medium_after(&hit, d, medium);
        return diffuse_points(ctx, scene.offset_origin(hit.p, hit.ng, d), d, depth, m2, out);
    }
    let bsdf = scene.bsdf(&hit);
    if bsdf.is_glossy() {
        // Its indirect light is gathered along its lobe: no record.
        return;
    }
    if !bsdf.is_specular() {
        out.push((hit, -d, medium));
        return;
    }
    if depth >= ctx.cfg.max_depth {
        return;
    }
    let [Some(refl), refr] = bsdf.specular_branches(-d, hit.ns, glam::Vec2::ZERO) else { return };
    let mut go = |wi: Vec3| {
        let m2 = if scene.has_media() { scene.medium_after(&hit, wi, medium) } else { None };
        diffuse_points(ctx, scene.offset_origin(hit.p, hit.ng, wi), wi, depth + 1, m2, out)
    };
    match refr {
        Some(t) if depth < SPLIT_DEPTH => {
            go(refl.wi);
            go(t.wi);
        }
        Some(t) if t.pdf > refl.pdf => go(t.wi),
        _ => go(refl.wi),
    }
}
