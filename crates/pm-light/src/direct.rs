//! Direct illumination by next-event estimation (pbrt-v4 section 13.4), with the
//! power heuristic between light and BSDF sampling on glossy surfaces and inside
//! emitters that enclose space (Veach 1997), and, for the photon-map integrators,
//! closed-form unoccluded light with stochastic shadows (Heitz, Hill and McGuire
//! 2018).

use crate::tree::Chosen;
use crate::{LightSelector, LightTree};
use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_sampling::Sampler;
use pm_scene::{Hit, MediumId, Scene};
use std::f32::consts::PI;

/// Direct light from the scene's lights: what every integrator that samples
/// lights shares (the photon-map renderer, its secondary gathers and the path
/// tracer). Knows nothing about photons.
///
/// A scene's few delta lights (point, spot, a sun without a size: at most
/// [`EVERY_DELTA_LIGHT`]) are each taken once at every estimate, with one shadow
/// ray and no noise but their shadow's edge; the light samples choose among the
/// other lights by power. Chosen by power among all, a sun took nearly every
/// sample of an open room's, since its power counts the whole scene's disc, and
/// left the ceiling light a sample in 30: the walls' direct light 55% off in 8 x 8
/// blocks at the pipeline's four samples a pixel (issue 53's checker, scene 35 of
/// seed 23897; BENCHMARKS.md).
pub struct DirectLighting<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Light choice by power among all lights (the same as the photon tracer's):
    /// for single scattering in media.
    pub lights: LightSelector,
    /// The delta lights taken at every estimate (empty when the scene has more than
    /// [`EVERY_DELTA_LIGHT`]).
    every: Vec<usize>,
    /// The choice among the other lights; `None` when there are none.
    sampled: Option<Choice>,
    /// The net a shading point's light samples are scrambled copies of.
    nets: pm_sampling::NetTable,
    /// Bounding boxes [m] of the area lights that enclose space (positive extent on
    /// every axis: an emitting sphere, a lit room's walls). See [`Self::direct`].
    enclosing: Vec<(Vec3, Vec3)>,
    /// Take Lambertian surfaces' direct light in closed form with a ratio estimate
    /// of visibility (see [`Self::direct`]): asked for by the photon-map integrators
    /// (off for the path tracer, which must stay unbiased), and decided once for the
    /// scene: at most [`CLOSED_FORM_LIGHTS`] lights, each with a closed form.
    closed_form: bool,
}

/// Most lights of a scene whose direct light [`DirectLighting::direct`] takes in
/// closed form (each costs Lambert's formula at every shading point; a scene with
/// more keeps plain light samples).
pub const CLOSED_FORM_LIGHTS: usize = 4;

/// Most delta lights of a scene that [`DirectLighting`] takes at every estimate
/// (each costs a shadow ray there; a scene with more chooses among them by power).
pub const EVERY_DELTA_LIGHT: usize = 4;

/// Light samples per shading point that [`DirectLighting::direct`] takes from its
/// precomputed net; more take an Owen-scrambled net each (slower, equally good).
const NET_POINTS: u32 = 256;

impl<'a> DirectLighting<'a> {
    /// Direct lighting of `scene`; fails when nothing in it emits.
    pub fn new(scene: &'a Scene) -> Result<Self, crate::LightSelectError> {
        let enclosing = scene
            .lights
            .iter()
            .filter_map(|l| match &l.kind {
                pm_scene::LightKind::Area { tris, .. } => {
                    let b = pm_scene::bounds_of(&scene.triangles[tris.start as usize..tris.end as usize]);
                    let ext = b.max - b.min;
                    (ext.min_element() > 1e-3 * ext.max_element()).then_some((b.min, b.max))
                }
                _ => None,
            })
            .collect();
        let lights = LightSelector::new(scene, &[])?;
        let delta: Vec<usize> = (0..scene.lights.len()).filter(|&i| scene.lights[i].is_delta()).collect();
        let every = if delta.len() <= EVERY_DELTA_LIGHT { delta } else { Vec::new() };
        Ok(DirectLighting {
            scene,
            sampled: Choice::among(scene, &lights, &every),
            every,
            lights,
            nets: pm_sampling::NetTable::new(NET_POINTS),
            enclosing,
            closed_form: false,
        })
    }

    /// [`Self::new`] with closed-form unoccluded direct light when the scene's lights
    /// have one (see [`Self::direct`]): for the photon-map integrators.
    pub fn with_closed_form(scene: &'a Scene) -> Result<Self, crate::LightSelectError> {
        let closed_form =
            scene.lights.len() <= CLOSED_FORM_LIGHTS && scene.lights.iter().all(pm_scene::Light::has_cos_integral);
        Ok(DirectLighting { closed_form, ..Self::new(scene)? })
    }

    /// One light-sampling estimate of reflected direct radiance: every delta light
    /// taken once (see [`DirectLighting`]), and of the others one picked by power, a
    /// point or direction sampled on it; a shadow ray to each, which starts in
    /// `medium` (attenuated by media and passing index-matched boundaries:
    /// [`Scene::transmittance_along`]). With `mis`, non-delta lights are weighted by
    /// the power heuristic against BSDF sampling (the caller then also samples the
    /// BSDF).
    pub fn light_sample(
        &self,
        hit: &Hit,
        bsdf: &Bsdf,
        wo: Vec3,
        s: &mut Sampler,
        mis: bool,
        medium: Option<MediumId>,
    ) -> Rgb {
        self.light_sample_at(hit, bsdf, wo, light_numbers(s), mis, medium)
    }

    /// [`Self::light_sample`] with its random numbers given: the point on the light
    /// (u\[0\], u\[1\]), the emitting triangle (u\[2\]) and the light (u\[3\]).
    pub fn light_sample_at(
        &self,
        hit: &Hit,
        bsdf: &Bsdf,
        wo: Vec3,
        u: [f32; 4],
        mis: bool,
        medium: Option<MediumId>,
    ) -> Rgb {
        let at = Lit { hit, bsdf, wo };
        self.every_delta(&at, medium) + self.sampled_light(&at, u, mis, medium)
    }

    /// Reflected radiance from the delta lights taken at every estimate.
    fn every_delta(&self, at: &Lit, medium: Option<MediumId>) -> Rgb {
        let mut sum = Rgb::ZERO;
        for &li in &self.every {
            if let Some((c, ray)) = self.unshadowed_on((Chosen::whole(li), 1.0), at, [0.5; 4], false) {
                sum += c * ray.transmittance(self.scene, medium);
            }
        }
        sum
    }

    /// One sample of reflected radiance from a light picked among the others.
    fn sampled_light(&self, at: &Lit, u: [f32; 4], mis: bool, medium: Option<MediumId>) -> Rgb {
        match self.unshadowed(at.hit, at.bsdf, at.wo, u, mis) {
            Some((_, c, ray)) => c * ray.transmittance(self.scene, medium),
            None => Rgb::ZERO,
        }
    }

    /// One light-sampling estimate of the radiance [W sr^-1 m^-2] scattered toward
    /// `wo` at point `p` inside medium `medium` by its phase function, per unit
    /// sigma_s (the caller's free-flight weight holds sigma_s): the delta lights
    /// taken every time and one light picked among the others (as
    /// [`Self::light_sample`]), each sampled from `p` over the whole sphere,
    /// p(wo, wi) L_i T / pdf with the shadow ray's transmittance T. With `mis`,
    /// non-delta lights are weighted by the power heuristic against phase-function
    /// sampling (the caller then samples the phase function and weighs the
    /// emission it finds).
    pub fn medium_sample(
        &self,
        p: Vec3,
        wo: Vec3,
        phase: &pm_bsdf::HenyeyGreenstein,
        medium: Option<MediumId>,
        s: &mut Sampler,
        mis: bool,
    ) -> Rgb {
        let u = light_numbers(s);
        let mut sum = Rgb::ZERO;
        for &li in &self.every {
            sum += self.medium_sample_on((Chosen::whole(li), 1.0), (p, wo), phase, medium, [0.5; 4], false);
        }
        if let Some(chosen) = self.sampled.as_ref().and_then(|c| c.pick(p, Vec3::ZERO, u[3])) {
            sum += self.medium_sample_on(chosen, (p, wo), phase, medium, u, mis);
        }
        sum
    }

    /// [`Self::medium_sample`] on light `li`, chosen with probability `p_sel`, at
    /// point `p` toward `wo`.
    fn medium_sample_on(
        &self,
        (c, p_sel): (Chosen, f32),
        (p, wo): (Vec3, Vec3),
        phase: &pm_bsdf::HenyeyGreenstein,
        medium: Option<MediumId>,
        u: [f32; 4],
        mis: bool,
    ) -> Rgb {
        let scene = self.scene;
        let Some(ls) = self.sample_chosen(c, p, Vec3::ZERO, u) else {
            return Rgb::ZERO;
        };
        let f = phase.p(wo, ls.wi);
        let p_l = ls.pdf * p_sel;
        if !(f > 0.0 && p_l > 0.0) {
            return Rgb::ZERO;
        }
        let w = if ls.delta || !mis { 1.0 } else { power_heuristic(p_l, f) };
        ls.li * (f * w / p_l) * ShadowRay::new(p, p, &ls).transmittance(scene, medium)
    }

    /// A light sample's light, its contribution as if nothing blocked it, and its
    /// shadow ray; `None` where it contributes nothing.
    #[inline]
    fn unshadowed(&self, hit: &Hit, bsdf: &Bsdf, wo: Vec3, u: [f32; 4], mis: bool) -> Option<(usize, Rgb, ShadowRay)> {
        let chosen = self.sampled.as_ref()?.pick(hit.p, pm_scene::facing(hit.ng, wo), u[3])?;
        let (c, ray) = self.unshadowed_on(chosen, &Lit { hit, bsdf, wo }, u, mis)?;
        Some((chosen.0.light, c, ray))
    }

    /// A sample toward what was chosen: the whole light (its triangle by `u[2]`),
    /// or the chosen triangle alone; the point by `u[0]`, `u[1]`.
    #[inline]
    fn sample_chosen(&self, c: Chosen, p: Vec3, n: Vec3, u: [f32; 4]) -> Option<pm_scene::LightSample> {
        let light = &self.scene.lights[c.light];
        let uv = glam::Vec2::new(u[0], u[1]);
        match c.tri {
            Some(i) => light.sample_triangle(self.scene, p, i as usize, true, uv),
            None => light.sample_li(self.scene, p, n, u[2], uv),
        }
    }

    /// [`Self::unshadowed`] on what was chosen, with probability `p_sel`.
    #[inline]
    fn unshadowed_on(&self, (c, p_sel): (Chosen, f32), at: &Lit, u: [f32; 4], mis: bool) -> Option<(Rgb, ShadowRay)> {
        let Lit { hit, bsdf, wo } = *at;
        let scene = self.scene;
        let ls = self.sample_chosen(c, hit.p, pm_scene::facing(hit.ng, wo), u)?;
        if !pm_scene::same_side(hit.ng, ls.wi, wo) {
            return None;
        }
        let f = bsdf.f(wo, ls.wi, hit.ns) * ls.wi.dot(hit.ns).abs();
        if f.max_element() <= 0.0 {
            return None;
        }
        let ray = ShadowRay::new(hit.p, scene.offset_origin(hit.p, hit.ng, ls.wi), &ls);
        let p_l = ls.pdf * p_sel;
        let w = if ls.delta || !mis { 1.0 } else { power_heuristic(p_l, bsdf.pdf(wo, ls.wi, hit.ns)) };
        Some((f * ls.li * (w / p_l), ray))
    }

    /// Direct light on a Lambertian surface from lights that all have a closed-form
    /// irradiance, by the ratio estimator of Heitz, Hill and McGuire 2018 ("Combining
    /// analytic direct illumination and stochastic shadows"): per light its
    /// `unoccluded` radiance ρ / π L_e ∫ cos dω [W sr^-1 m^-2] in closed form
    /// ([`pm_scene::Light::cos_integral`]) times the ratio estimate of its visibility
    /// Σ w_i V_i / Σ w_i over `n` light samples of its own (stratified over it), w_i
    /// each sample's unoccluded contribution. Where a light is wholly seen or
    /// wholly hidden it is exact (no noise); in penumbrae it is consistent, its
    /// bias falling as 1 / n (and smaller for stratified samples than for
    /// independent ones). The jackknife, which takes that term away from
    /// independent samples, does not suit stratified ones: it made a penumbra 1.2%
    /// bright at eight samples, where the plain ratio agreed with unbiased light
    /// sampling within 0.1% (the suite's
    /// `closed_form_direct_light_is_exact_where_seen_and_unbiased_in_penumbrae`).
    /// One sample gives that sample's visibility alone, whose mean weighs the
    /// light's points by the sampling density rather than by their contribution:
    /// on cornell_boxes, bias 4.4% against 2.0% from four samples on (trade-off
    /// study).
    ///
    /// Each light takes its own `n` samples (a scene has at most
    /// [`CLOSED_FORM_LIGHTS`]): `n` among them all, chosen by power, gave a light
    /// one or two, and two stacked lamps, which put a whole room in the upper one's
    /// penumbra, lit its walls 2.1% to 2.7% dark at the pipeline's four samples
    /// (issue 53's checker, scene 2 of seed 23897): -1.0% to -0.2% now, +0.3% at 64.
    /// In a medium the visibility is each shadow ray's transmittance (per channel):
    /// the ratio estimates the mean transmittance the light arrives with.
    fn closed_form_direct(
        &self,
        at: &Lit,
        unoccluded: &[Rgb],
        s: &mut Sampler,
        n: u32,
        medium: Option<MediumId>,
    ) -> Rgb {
        let scene = self.scene;
        let mut sum = Rgb::ZERO;
        for (li, u) in unoccluded.iter().enumerate() {
            if u.max_element() <= 0.0 {
                continue;
            }
            let net = (n > 1).then(|| s.net_4d());
            let (mut seen, mut all) = (Rgb::ZERO, 0.0f32);
            for k in 0..n {
                let u = match &net {
                    Some(net) => net.point(&self.nets, n, k),
                    None => light_numbers(s),
                };
                let Some((c, ray)) = self.unshadowed_on((Chosen::whole(li), 1.0), at, u, false) else { continue };
                let (w, v) = (c.element_sum(), ray.transmittance(scene, medium));
                (seen, all) = (seen + v * w, all + w);
            }
            if all > 0.0 {
                sum += *u * (seen / all);
            }
        }
        sum
    }
}

/// One light sample's numbers drawn from the stream (the light, then the triangle,
/// then the point), in [`DirectLighting::light_sample_at`]'s order.
#[inline]
fn light_numbers(s: &mut Sampler) -> [f32; 4] {
    let pick = s.next_1d();
    let u_tri = s.next_1d();
    let u = s.next_2d();
    [u.x, u.y, u_tri, pick]
}

/// Reflected radiance [W sr^-1 m^-2] from `light` at point `p` with unit normal
/// `n` (on the side the reflected light leaves) of a Lambertian surface of
/// reflectance `rho`, as if nothing blocked the light: ρ / π L_e ∫ cos dω, with
/// the integral in closed form ([`pm_scene::Light::cos_integral`], Lambert's
/// formula for a planar polygon); and the integral itself \[sr\] (0 for a light
/// without a closed form, or wholly below the horizon). The one home of the
/// closed-form term: stochastic shadows ([`DirectLighting::direct`]) and shadow
/// maps ([`crate::ShadowMaps`]) both scale it by a visibility.
pub(crate) fn lambert_unoccluded(light: &pm_scene::Light, p: Vec3, n: Vec3, rho: Rgb) -> (Rgb, f32) {
    let (le, e) = light.cos_integral(p, n).unwrap_or((Rgb::ZERO, 0.0));
    (rho * le * (e / PI), e)
}

/// How far a shadow ray from `o` (the offset of surface point `p`) toward the light
/// sample `ls` may go before it counts as blocked \[m\]: to where it meets the
/// light, measured from the offset origin (the offset can exceed a relative margin
/// in tiny scenes, and the ray would then reach the light itself: every shadow ray
/// in a 2 mm Cornell box was blocked before this), less a margin of a few units in
/// the last place of the light point's coordinates (far from the origin the sampled
/// point and the ray's hit on the light's own triangle differ by such units: a box
/// 350 m from its camera-relative origin has coordinates 3e-5 m apart, and without
/// it the floor of a 0.55 m Cornell box 100 km away lost most of its direct light;
/// issue 36), stretched by the cosine at the light's surface. Toward a point or
/// spot light the units unstretched and 1e-4 of the length. Infinite for lights
/// at infinity. A ray that walks through index-matched boundaries measures what
/// is left of it after each to the light's plane ([`ShadowRay`]).
fn shadow_length(p: Vec3, o: Vec3, ls: &pm_scene::LightSample) -> f32 {
    if !ls.dist.is_finite() {
        return f32::INFINITY;
    }
    let far = (p + ls.wi * ls.dist).abs().max_element();
    // Where the ray from `o`, parallel to the one from `p`, meets the light's
    // surface: sooner by the offset's height over it divided by the cosine there.
    // Taken as the offset's length along the ray, a grazing shadow ray from a
    // ceiling to a light 13 mm below it met the light short of its end: 43% of
    // them on the differential checker's scene 25 of seed 23897 (12% with the
    // scene at the file's origin), and the path tracer, the checks' reference,
    // lost a fifth of the light in the gap (issue 53; BENCHMARKS.md).
    let along = (o - p).dot(ls.wi);
    let cos = ls.wi.dot(ls.normal);
    let ahead = if cos.abs() > 1e-6 { ((o - p).dot(ls.normal) / cos).max(along) } else { along };
    let ulps = far * (16.0 * f32::EPSILON);
    let end = ls.dist - ahead;
    if ls.normal == Vec3::ZERO {
        return end * (1.0 - 1e-4) - ulps;
    }
    // On a light's surface the end is known to the rounding of its coordinates,
    // stretched along the ray by the cosine there. A margin of 1e-4 of the length
    // instead (0.5 mm of a 5 m ray) let shadow rays pass a light 0.3 mm in front of
    // another: the checker's scene 30 of seed 23897 lit 2% brighter than the
    // photon maps said, as Mitsuba 3 does (it has such a margin too), and as both
    // do not with the lights 2 cm apart (BENCHMARKS.md).
    end - ulps / cos.abs().max(0.01)
}

/// A shadow ray toward a light sample: from `o` along unit `d`, `t_max` \[m\]
/// long ([`shadow_length`]), ending on the light's surface of unit normal
/// `end` (zero toward a point, spot or sun light).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ShadowRay {
    pub o: Vec3,
    pub d: Vec3,
    pub t_max: f32,
    pub end: Vec3,
}

impl ShadowRay {
    /// The shadow ray from `o` (the offset of point `p`) toward `ls`.
    pub fn new(p: Vec3, o: Vec3, ls: &pm_scene::LightSample) -> ShadowRay {
        ShadowRay { o, d: ls.wi, t_max: shadow_length(p, o, ls), end: ls.normal }
    }

    /// What reaches the light along it from medium `medium`
    /// ([`pm_scene::Scene::transmittance_to`]).
    pub fn transmittance(&self, scene: &pm_scene::Scene, medium: Option<MediumId>) -> Rgb {
        scene.transmittance_to(self.o, self.d, self.t_max, self.end, medium)
    }
}

/// The power heuristic (beta = 2) weight of a sample with density `a` against `b`.
#[inline]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 { a2 / (a2 + b2) } else { 0.0 }
}

impl DirectLighting<'_> {
    /// The density [sr^-1] with which [`Self::light_sample`] at shading point `p`
    /// (geometric normal `n` turned toward the viewer; zero in a medium) picks
    /// direction `wi` toward the emitting triangle `tri` seen at distance `t` (light
    /// choice included); `None` when the triangle belongs to no light. For MIS
    /// weights of BSDF-sampled emission.
    pub fn pdf_emitter(&self, p: Vec3, n: Vec3, tri: u32, wi: Vec3, t: f32) -> Option<f32> {
        let li = self.scene.light_of_triangle[tri as usize];
        if li == u32::MAX {
            return None;
        }
        let light = &self.scene.lights[li as usize];
        Some(match &self.sampled {
            Some(Choice::Tree(tree)) if tree.is_split(li as usize) => {
                light.pdf_triangle(self.scene, p, wi, t, tri, true) * tree.prob_triangle(tri, p, n)
            }
            _ => light.pdf_li(self.scene, p, wi, t, tri) * self.sampled_prob(li as usize, p, n),
        })
    }

    /// The density [sr^-1] with which [`Self::light_sample`] at shading point `p`
    /// with unit normal `n` (on the side light arrives from) picks unit direction
    /// `wi` toward the sky, over the lights at infinity (light choice included): for
    /// MIS weights of BSDF-sampled rays that leave the scene.
    pub fn pdf_escaped(&self, p: Vec3, n: Vec3, wi: Vec3) -> f32 {
        let mut pdf = 0.0;
        for &i in &self.scene.infinite_lights {
            pdf += self.scene.lights[i as usize].pdf_escaped(p, n, wi) * self.sampled_prob(i as usize, p, n);
        }
        pdf
    }

    /// The probability that a light sample at `p` with normal `n` picks light `li`
    /// (0 for the delta lights taken every time).
    fn sampled_prob(&self, li: usize, p: Vec3, n: Vec3) -> f32 {
        self.sampled.as_ref().map_or(0.0, |c| c.prob(li, p, n))
    }

    /// Reflected direct radiance L_o [W sr^-1 m^-2] toward `wo` at a non-specular hit:
    /// the delta lights taken once each (see [`DirectLighting`]), the others
    /// averaged over `n` light samples. Glossy surfaces, and every surface inside an
    /// area light that encloses space, also sample the BSDF and weigh the two by the
    /// power heuristic, and so does every surface of a scene with lights at
    /// infinity (an environment, a sun disc; issue 37). Inside such a light (the
    /// furnace's emitting sphere) the facets next to a point subtend large solid
    /// angles but are chosen by their small areas: a light sample on one weighed up
    /// to 11 times the mean, and made the furnace test's worst pixel;
    /// cosine-sampled directions find those facets often.
    /// Built [`Self::with_closed_form`], Lambertian surfaces in a scene of at most
    /// `CLOSED_FORM_LIGHTS` lights that all have a closed-form irradiance take the
    /// closed form with stochastic shadows instead (see `closed_form_direct`).
    ///
    /// The shading point is in medium `medium`: shadow rays are attenuated by the
    /// media they cross (and pass index-matched boundaries).
    pub fn direct(&self, hit: &Hit, bsdf: &Bsdf, wo: Vec3, s: &mut Sampler, n: u32, medium: Option<MediumId>) -> Rgb {
        let scene = self.scene;
        let mis = !matches!(bsdf, Bsdf::Lambert { .. })
            || !scene.infinite_lights.is_empty()
            || self.enclosing.iter().any(|(lo, hi)| hit.p.cmpgt(*lo).all() && hit.p.cmplt(*hi).all());
        if !mis
            && self.closed_form
            && let Bsdf::Lambert { rho } = bsdf
        {
            let side = pm_scene::facing(hit.ns, wo);
            let mut unoccluded = [Rgb::ZERO; CLOSED_FORM_LIGHTS];
            let mut lit = false;
            for (u, light) in unoccluded.iter_mut().zip(&scene.lights) {
                // Some for every light: `closed_form` is decided by that.
                let e;
                (*u, e) = lambert_unoccluded(light, hit.p, side, *rho);
                lit |= e > 0.0;
            }
            // Nothing of any light above the horizon: no shadow rays.
            return if lit {
                self.closed_form_direct(&Lit { hit, bsdf, wo }, &unoccluded[..scene.lights.len()], s, n, medium)
            } else {
                Rgb::ZERO
            };
        }
        let at = Lit { hit, bsdf, wo };
        let delta = self.every_delta(&at, medium);
        if self.sampled.is_none() {
            return delta;
        }
        let mut sum = Rgb::ZERO;
        // The n light samples stratified among themselves: on a Cornell box's area
        // light, n independent points left direct light the largest part of the
        // image's error (BENCHMARKS.md, issue 18). One sample (a live frame's)
        // takes its numbers from the stream, as a net of one point would, cheaper.
        let net = (n > 1).then(|| s.net_4d());
        for k in 0..n {
            let u = match &net {
                Some(net) => net.point(&self.nets, n, k),
                None => light_numbers(s),
            };
            sum += self.sampled_light(&at, u, mis, medium);
            if mis {
                // BSDF sampling, weighted against light sampling.
                let u = s.next_2d();
                let uc = s.next_1d();
                if let Some(bs) = bsdf.sample(wo, hit.ns, u, uc)
                    && !bs.specular
                    && pm_scene::same_side(hit.ng, bs.wi, wo)
                {
                    let o = scene.offset_origin(hit.p, hit.ng, bs.wi);
                    let pm_scene::Passage { hit: found, tr, t, .. } = scene.intersect_through(o, bs.wi, medium);
                    match found {
                        Some(h) => {
                            let le = scene.emitted(&h, -bs.wi) * tr;
                            if le.max_element() > 0.0
                                && let Some(p_l) =
                                    self.pdf_emitter(hit.p, pm_scene::facing(hit.ng, wo), h.tri, bs.wi, t)
                            {
                                sum += bs.weight * le * power_heuristic(bs.pdf, p_l);
                            }
                        }
                        None => {
                            let le = scene.escaped(bs.wi) * tr;
                            if le.max_element() > 0.0 {
                                let p_l = self.pdf_escaped(hit.p, pm_scene::facing(hit.ng, wo), bs.wi);
                                sum += bs.weight * le * power_heuristic(bs.pdf, p_l);
                            }
                        }
                    }
                }
            }
        }
        delta + sum / n.max(1) as f32
    }
}

/// The point being lit: its hit, its BSDF and the direction toward the viewer.
#[derive(Clone, Copy)]
struct Lit<'a> {
    hit: &'a Hit,
    bsdf: &'a Bsdf,
    wo: Vec3,
}

/// How a light sample chooses among the lights not taken every time: the one
/// there is, or the light tree ([`LightTree`]: by each light's importance at the
/// shading point; Conty Estevez and Kulla 2018).
#[derive(Clone, Debug)]
enum Choice {
    One(usize),
    Tree(LightTree),
}

impl Choice {
    /// The choice among the lights `all` can choose, less `every`; None when none
    /// is left.
    fn among(scene: &Scene, all: &LightSelector, every: &[usize]) -> Option<Choice> {
        let rest = all.excluding(every)?;
        let rest: Vec<usize> = (0..rest.probs.len()).filter(|&i| rest.probs[i] > 0.0).collect();
        match rest.as_slice() {
            [] => None,
            [one] => Some(Choice::One(*one)),
            _ => LightTree::new(scene, &rest).map(Choice::Tree),
        }
    }

    /// The light chosen by `u` at `p` with normal `n`, and its probability.
    #[inline]
    fn pick(&self, p: Vec3, n: Vec3, u: f32) -> Option<(Chosen, f32)> {
        match self {
            Choice::One(li) => Some((Chosen::whole(*li), 1.0)),
            Choice::Tree(t) => t.pick(p, n, u),
        }
    }

    /// The probability that [`Self::pick`] at `p`, `n` chooses `li`.
    #[inline]
    fn prob(&self, li: usize, p: Vec3, n: Vec3) -> f32 {
        match self {
            Choice::One(one) => (li == *one) as u8 as f32,
            Choice::Tree(t) => t.prob(li, p, n),
        }
    }
}
