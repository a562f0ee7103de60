//! Participating media: homogeneous absorbing and scattering volumes inside closed
//! meshes (KHR_materials_volume with KHR_materials_volume_scatter, or pipeline.toml's
//! `[media.NAME]`) and one filling the scene (`[media.scene]`: fog, haze, water).
//!
//! A medium is where a ray is, not a property of a hit: every integrator that
//! simulates media carries the id of the medium its ray travels in and changes it
//! only where the ray leaves a surface that bounds a medium ([`Scene::medium_after`]).
//! The medium outside each bounding mesh, the camera's and each light's are found
//! once by walking a ray out of the scene (`finish_media`), so media may nest.
//!
//! Free-flight sampling is by a hero channel chosen once per path (Wilkie et al.
//! 2014), each event's density kept per channel so the path's contribution divides
//! by the mean of the three channels' path densities (the balance heuristic over
//! channels for the whole path, "spectral MIS": pbrt-v4 section 14.1.2's r_u): a
//! medium dense in one channel and clear in another is sampled well in both, and
//! no weight grows without bound (per-event balancing let a chromatic furnace's
//! blue channel read 14 instead of 5).

use crate::{Hit, LightKind, Scene};
use glam::Vec3;
use pm_bsdf::HenyeyGreenstein;
use pm_color::Rgb;

/// Index of a medium in [`Scene::media`]; a ray in no medium (vacuum) has `None`.
pub type MediumId = u32;

/// A homogeneous participating medium: coefficients per metre per RGB channel and a
/// Henyey-Greenstein phase function.
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    /// The material (or "scene") this medium belongs to: what errors name.
    pub name: String,
    /// Absorption coefficient sigma_a [m^-1 per channel].
    pub sigma_a: Rgb,
    /// Scattering coefficient sigma_s [m^-1 per channel].
    pub sigma_s: Rgb,
    /// The phase function (its asymmetry g in (-1, 1)).
    pub phase: HenyeyGreenstein,
}

/// What a free-flight sample found along a segment of a ray, sampled in the
/// path's hero channel h: `weight` is f / p_h per channel (f the path's measurement
/// factor for the event, p_h its density in the hero channel) and `ratio` p_c / p_h,
/// which the path multiplies into its running ratios; the path's contribution is
/// its weight over the mean of its ratios (the balance heuristic over the three
/// channels for the whole path, so a weight stays bounded in a chromatic medium).
/// Both are one for a grey medium's surface event, and weight is the albedo at its
/// scattering events.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FreeFlight {
    /// The ray scatters at distance `t` [m] (f = sigma_s T(t), p_c = sigma_t,c T_c(t)).
    Scatter {
        /// Distance along the ray \[m\].
        t: f32,
        /// f / p_h per channel.
        weight: Rgb,
        /// p_c / p_h per channel.
        ratio: Rgb,
    },
    /// The ray reaches the end of the segment (f = T(t_max), p_c = T_c(t_max)).
    Through {
        /// f / p_h per channel.
        weight: Rgb,
        /// p_c / p_h per channel.
        ratio: Rgb,
    },
}

impl Medium {
    /// A medium of absorption and scattering coefficients [m^-1 per channel] and
    /// Henyey-Greenstein asymmetry `g`; refused (naming it) when a coefficient is
    /// negative or not finite, or g is not in (-1, 1).
    pub fn new(name: impl Into<String>, sigma_a: Rgb, sigma_s: Rgb, g: f32) -> Result<Medium, String> {
        let name = name.into();
        match invalid(sigma_a, sigma_s, g) {
            Some(why) => Err(format!("medium '{name}': {why}")),
            None => Ok(Medium { name, sigma_a, sigma_s, phase: HenyeyGreenstein { g } }),
        }
    }

    /// A medium from KHR_materials_volume's attenuation colour c and distance d
    /// (sigma_t = -ln(c) / d) and the single-scattering albedo rho_ss (sigma_s =
    /// rho_ss sigma_t; zero without KHR_materials_volume_scatter: absorption only).
    /// A colour of 0 is taken as 1e-6: opaque within a few distances.
    pub fn from_attenuation(name: impl Into<String>, c: Rgb, d: f32, albedo: Rgb, g: f32) -> Result<Medium, String> {
        let name = name.into();
        if !c.is_finite() || c.min_element() < 0.0 || !(d > 0.0) {
            return Err(format!("material '{name}': volume attenuation colour {c} or distance {d} is not valid"));
        }
        let sigma_t = if d.is_finite() { -c.min(Rgb::ONE).max(Rgb::splat(1e-6)).ln() / d } else { Rgb::ZERO };
        let albedo = albedo.clamp(Rgb::ZERO, Rgb::ONE);
        let (sigma_a, sigma_s) = (sigma_t * (Rgb::ONE - albedo), sigma_t * albedo);
        match invalid(sigma_a, sigma_s, g) {
            Some(why) => Err(format!("material '{name}': scatter {why}")),
            None => Ok(Medium { name, sigma_a, sigma_s, phase: HenyeyGreenstein { g } }),
        }
    }

    /// Extinction coefficient sigma_t = sigma_a + sigma_s [m^-1 per channel].
    #[inline]
    pub fn sigma_t(&self) -> Rgb {
        self.sigma_a + self.sigma_s
    }

    /// Single-scattering albedo sigma_s / sigma_t per channel (zero where clear).
    pub fn albedo(&self) -> Rgb {
        let t = self.sigma_t();
        Rgb::new(ratio(self.sigma_s.x, t.x), ratio(self.sigma_s.y, t.y), ratio(self.sigma_s.z, t.z))
    }

    /// True when it scatters light in some channel.
    #[inline]
    pub fn scatters(&self) -> bool {
        self.sigma_s.max_element() > 0.0
    }

    /// True when it neither absorbs nor scatters (a clear volume: the inside of
    /// solid glass).
    #[inline]
    pub fn is_clear(&self) -> bool {
        self.sigma_t() == Rgb::ZERO
    }

    /// Beer-Lambert transmittance exp(-sigma_t t) of `t` metres (per channel, in
    /// [0, 1]; one in a clear channel even for t infinite).
    #[inline]
    pub fn transmittance(&self, t: f32) -> Rgb {
        let s = self.sigma_t();
        let tr = |s: f32| if s > 0.0 { (-s * t).exp() } else { 1.0 };
        Rgb::new(tr(s.x), tr(s.y), tr(s.z))
    }

    /// Sample where along a segment of `t_max` metres (may be infinite) a ray first
    /// interacts, by a distance exponential in the hero channel's sigma_t (`u`
    /// uniform in [0, 1)); absorption is in the weight, so only scattering events
    /// are returned. A medium that does not scatter is not sampled: its
    /// transmittance is the weight.
    pub fn sample_distance(&self, t_max: f32, hero: usize, u: f32) -> FreeFlight {
        if !self.scatters() {
            return FreeFlight::Through { weight: self.transmittance(t_max), ratio: Rgb::ONE };
        }
        let st = self.sigma_t();
        let s = st[hero.min(2)];
        let t = if s > 0.0 { -(1.0 - u).ln() / s } else { f32::INFINITY };
        if t < t_max {
            let tr = self.transmittance(t);
            let p = st * tr;
            let ph = p[hero.min(2)];
            if ph > 0.0 {
                return FreeFlight::Scatter { t, weight: self.sigma_s * tr / ph, ratio: p / ph };
            }
        }
        let tr = self.transmittance(t_max);
        let ph = tr[hero.min(2)];
        if ph > 0.0 {
            FreeFlight::Through { weight: tr / ph, ratio: tr / ph }
        } else {
            FreeFlight::Through { weight: Rgb::ZERO, ratio: Rgb::ONE }
        }
    }
}

/// A path's free flights through media with spectral MIS: the hero channel its
/// distances are sampled in (chosen once per path) and its density in each channel
/// over the hero's, multiplied over its flights; what it carries is weighed by
/// [`Flights::weight`].
#[derive(Clone, Copy, Debug)]
pub struct Flights {
    hero: usize,
    ratio: Rgb,
}

impl Flights {
    /// A path whose hero channel `u` in [0, 1) picks (channel floor(3u)).
    pub fn new(u: f32) -> Flights {
        Flights { hero: ((u * 3.0) as usize).min(2), ratio: Rgb::ONE }
    }

    /// One flight over a segment of `t_seg` metres of medium `m`
    /// ([`Medium::sample_distance`] in the hero channel, `u` uniform), its density
    /// ratios taken in.
    pub fn fly(&mut self, m: &Medium, t_seg: f32, u: f32) -> FreeFlight {
        let flight = m.sample_distance(t_seg, self.hero, u);
        let (FreeFlight::Through { ratio, .. } | FreeFlight::Scatter { ratio, .. }) = flight;
        self.ratio *= ratio;
        flight
    }

    /// The factor the path's weights are multiplied by: 3 over the sum of its
    /// ratios (one before any flight and in grey media).
    #[inline]
    pub fn weight(&self) -> f32 {
        3.0 / self.ratio.element_sum()
    }
}

/// Why coefficients sigma_a, sigma_s [m^-1] and asymmetry g make no medium (a
/// coefficient negative or not finite, g outside (-1, 1)), if they do not.
fn invalid(sigma_a: Rgb, sigma_s: Rgb, g: f32) -> Option<String> {
    for (what, c) in [("sigma_a", sigma_a), ("sigma_s", sigma_s)] {
        if !pm_color::is_valid(c) {
            return Some(format!("{what} {c} must be finite and >= 0 [m^-1]"));
        }
    }
    (!(g > -1.0 && g < 1.0)).then(|| format!("g {g} must be in (-1, 1)"))
}

/// a / b, zero where b is.
fn ratio(a: f32, b: f32) -> f32 {
    if b > 0.0 { a / b } else { 0.0 }
}

/// The single-scattering albedo rho_ss that gives multiple-scattering albedo
/// `rho_ms` (Kulla and Conty 2017, "Revisiting physically based shading at
/// Imageworks"), as KHR_materials_volume_scatter maps its `scatterAlbedo` (the
/// draft's earlier `multiscatterColor`): rho_ss = 1 - (4.09712 + 4.20863 rho_ms -
/// sqrt(9.59217 + 41.6808 rho_ms + 17.7126 rho_ms^2))^2, per channel.
pub fn single_scattering_albedo(rho_ms: Rgb) -> Rgb {
    let f = |m: f32| {
        let m = m.clamp(0.0, 1.0);
        let a = 4.09712 + 4.20863 * m - (9.59217 + 41.6808 * m + 17.7126 * m * m).sqrt();
        (1.0 - a * a).clamp(0.0, 1.0)
    };
    Rgb::new(f(rho_ms.x), f(rho_ms.y), f(rho_ms.z))
}

/// What the scene knows of its media beyond the list: where each one is.
#[derive(Clone, Debug, Default)]
pub(crate) struct MediaLayout {
    /// The medium filling the scene (inside its bounding sphere), if any.
    pub scene: Option<MediumId>,
    /// Per object: the medium just outside it.
    pub outside: Vec<Option<MediumId>>,
    /// Per object: true when the medium outside it differs across its surface
    /// (a glass box standing half in a fog box): the medium beyond each of its
    /// surfaces is then found where a ray leaves it ([`Scene::medium_after`]).
    pub straddles: Vec<bool>,
    /// The medium at the camera's position.
    pub camera: Option<MediumId>,
    /// Per light: the medium its light starts in (the scene's for lights at infinity).
    pub lights: Vec<Option<MediumId>>,
    /// Some medium absorbs or scatters: integrators must track media.
    pub any: bool,
    /// Some medium scatters: volume photons, in-scattering.
    pub scattering: bool,
    /// Some material is an index-matched boundary ([`Scene::index_matched`]).
    pub index_matched: bool,
    /// Radius \[m\] of the sphere about the bounds' centre that the scene medium
    /// fills when it must be larger than the bounding sphere to hold the camera
    /// (zero otherwise): see [`Scene::world_sphere`].
    pub sphere_radius: f32,
}

/// Where a ray goes through index-matched boundaries and the media between them
/// ([`Scene::intersect_through`]).
#[derive(Clone, Copy, Debug)]
pub struct Passage {
    /// Its first hit that is not an index-matched boundary; none when it leaves the
    /// scene or its transmittance falls to zero.
    pub hit: Option<Hit>,
    /// The transmittance of the media and boundaries before that hit (or to the
    /// world sphere's end), per channel in [0, 1].
    pub tr: Rgb,
    /// The hit's distance from the ray's origin \[m\] (infinite without one).
    pub t: f32,
    /// The medium the ray is in where it arrives.
    pub medium: Option<MediumId>,
}

/// Most surfaces a containment walk crosses before it gives up (and takes the
/// scene's medium): more than any sane nesting.
const WALK_HITS: usize = 4096;

/// Triangles of a medium's mesh whose outside is found to tell whether the mesh
/// stands in two media ([`MediaLayout::straddles`]).
const STRADDLE_SAMPLES: usize = 256;

impl Scene {
    /// The medium `id` names (`None` for vacuum).
    #[inline]
    pub fn medium(&self, id: Option<MediumId>) -> Option<&Medium> {
        id.map(|i| &self.media[i as usize])
    }

    /// True when some medium of the scene absorbs or scatters: an integrator that
    /// finds none may skip every medium check.
    #[inline]
    pub fn has_media(&self) -> bool {
        self.layout.any
    }

    /// True when some medium of the scene scatters light.
    #[inline]
    pub fn has_scattering_media(&self) -> bool {
        self.layout.scattering
    }

    /// True when some surface is an index-matched boundary ([`Self::index_matched`]).
    #[inline]
    pub fn has_index_matched(&self) -> bool {
        self.layout.index_matched
    }

    /// True when a ray's way through the scene is walked: through media that
    /// attenuate it and index-matched boundaries it passes ([`Self::transmittance_along`],
    /// [`Self::pass_from_visiting`]). Otherwise its first hit is all there is.
    #[inline]
    pub fn rays_walk(&self) -> bool {
        self.has_media() || self.layout.index_matched
    }

    /// The medium filling the scene, if any.
    pub fn scene_medium(&self) -> Option<MediumId> {
        self.layout.scene
    }

    /// The medium a ray is in after leaving the surface of `hit` in unit direction
    /// `wi`, having arrived in medium `cur`: for a surface that bounds a medium, its
    /// inside when `wi` leaves by the back and the medium outside the mesh when by
    /// the front; `cur` for any other surface (both of its sides are in one medium).
    /// A mesh that stands partly in another medium ([`MediaLayout::straddles`])
    /// has no one outside: leaving it, the medium is found by a walk from where
    /// the ray leaves, as [`Self::medium_at`] finds it.
    #[inline]
    pub fn medium_after(&self, hit: &Hit, wi: Vec3, cur: Option<MediumId>) -> Option<MediumId> {
        let Some(inside) = self.material(hit).interior else { return cur };
        if wi.dot(hit.ng) < 0.0 {
            return Some(inside);
        }
        let o = self.object_of(hit.tri)?;
        if self.layout.straddles.get(o as usize).copied().unwrap_or(false) {
            return self.medium_walk(self.offset_origin(hit.p, hit.ng, wi), wi, Some(o));
        }
        self.layout.outside.get(o as usize).copied().flatten()
    }

    /// The transmission colour of an index-matched boundary at `hit` (smooth
    /// transmission with ior 1 and no texture: a fog box's walls), which rays and
    /// photons pass straight through without a bounce; `None` for any other
    /// surface.
    #[inline]
    pub fn index_matched(&self, hit: &Hit) -> Option<Rgb> {
        if !self.layout.index_matched {
            return None;
        }
        match self.uniform_bsdf(hit.tri) {
            Some(pm_bsdf::Bsdf::Glass { eta: 1.0, tint, .. }) => Some(tint),
            _ => None,
        }
    }

    /// True when triangle `tri` is an index-matched boundary
    /// ([`Self::index_matched`]).
    #[inline]
    pub(crate) fn is_index_matched(&self, tri: u32) -> bool {
        matches!(self.uniform_bsdf(tri), Some(pm_bsdf::Bsdf::Glass { eta: 1.0, .. }))
    }

    /// What reaches the end of a shadow ray from `o` along unit `d` of length
    /// `t_max` (infinite toward lights at infinity) that starts in medium `medium`,
    /// per channel: zero when a surface blocks it; otherwise the product of each
    /// segment's Beer-Lambert transmittance and the colour of each index-matched
    /// boundary it passes (changing medium there). In a scene without media or
    /// index-matched boundaries, [`Self::occluded`]'s answer as zero or one.
    pub fn transmittance_along(&self, o: Vec3, d: Vec3, t_max: f32, medium: Option<MediumId>) -> Rgb {
        self.transmittance_to(o, d, t_max, Vec3::ZERO, medium)
    }

    /// [`Self::transmittance_along`] for a shadow ray that ends on a surface of
    /// unit normal `end_normal` (a light's; zero where it ends at a point): past
    /// each index-matched boundary the walk goes on from an origin offset off the
    /// boundary, which shifts the ray across it, and what is left of the ray is
    /// measured to the plane through its end, not along it. Measured along it, a
    /// grazing ray through a fog box's top reached the light's own surface (the
    /// shift over the cosine there), and shadow rays had ended a ten-thousandth
    /// of their length short to make up for it: in front of a lamp 0.03 mm below
    /// another they passed the lower one, lit with the upper one's hidden part,
    /// and the path tracer's indirect light came out 11% brighter than the
    /// photons' (issue 53's checker, seed 77777 scene 30).
    pub fn transmittance_to(&self, o: Vec3, d: Vec3, t_max: f32, end_normal: Vec3, medium: Option<MediumId>) -> Rgb {
        if !self.rays_walk() {
            return if self.occluded(o, d, t_max) { Rgb::ZERO } else { Rgb::ONE };
        }
        let first = self.intersect(o, d, t_max);
        let end = (t_max.is_finite() && d.dot(end_normal).abs() > 1e-6).then(|| (o + d * t_max, end_normal));
        match self.walk_visiting(o, d, (t_max, end), medium, first, |_, _, _, _| {}) {
            Passage { hit: Some(_), .. } => Rgb::ZERO,
            p => p.tr,
        }
    }

    /// The ray from `o` in unit direction `d`, starting in medium `medium`, to its
    /// first hit that is not an index-matched boundary ([`Passage`]). For rays that
    /// only look for what they hit (a BSDF sample that may find a light) and for
    /// integrators that attenuate light in media without scattering it there; in a
    /// scene without media or index-matched boundaries, [`Self::intersect`] with a
    /// transmittance of one.
    pub fn intersect_through(&self, o: Vec3, d: Vec3, medium: Option<MediumId>) -> Passage {
        self.pass_from(o, d, self.intersect(o, d, f32::INFINITY), medium)
    }

    /// [`Self::intersect_through`] for a ray whose first hit `first` is already
    /// known (a rasterised fragment, or a shadow map's first surface).
    pub fn pass_from(&self, o: Vec3, d: Vec3, first: Option<Hit>, medium: Option<MediumId>) -> Passage {
        self.pass_from_visiting(o, d, first, medium, |_, _, _, _| {})
    }

    /// [`Self::pass_from`], calling `visit(o, t, medium, tr)` for each stretch of
    /// the walk in a medium: from `o`, `t` \[m\] long (infinite: to the world
    /// sphere's end), in `medium`, behind transmittance `tr` (what the media and
    /// boundaries before it let through). What the eye sees scattered along the
    /// way is summed over these (`pm_light`'s single scattering of the real-time
    /// methods).
    pub fn pass_from_visiting(
        &self,
        o: Vec3,
        d: Vec3,
        first: Option<Hit>,
        medium: Option<MediumId>,
        visit: impl FnMut(Vec3, f32, Option<MediumId>, Rgb),
    ) -> Passage {
        if !self.rays_walk() {
            let t = first.as_ref().map_or(f32::INFINITY, |h| h.t);
            return Passage { hit: first, tr: Rgb::ONE, t, medium };
        }
        self.walk_visiting(o, d, (f32::INFINITY, None), medium, first, visit)
    }

    /// The walk the above take, from the ray's first hit `hit` within `t_max`:
    /// through index-matched boundaries (their colours and the media between them
    /// multiplied in, the medium changing at each) to the first other surface within
    /// `t_max` (infinite: to the world sphere's end). A walk whose transmittance
    /// falls to zero stops there without a hit.
    pub(crate) fn walk_from(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        medium: Option<MediumId>,
        hit: Option<Hit>,
    ) -> Passage {
        self.walk_visiting(o, d, (t_max, None), medium, hit, |_, _, _, _| {})
    }

    /// [`Self::walk_from`], calling `visit` for each stretch in a medium as
    /// [`Self::pass_from_visiting`] says; with `end` (a point and a unit normal
    /// not perpendicular to `d`), what is left of the walk after each boundary is
    /// measured to the plane through them ([`Self::transmittance_to`]).
    fn walk_visiting(
        &self,
        o: Vec3,
        d: Vec3,
        (t_max, end): (f32, Option<(Vec3, Vec3)>),
        medium: Option<MediumId>,
        mut hit: Option<Hit>,
        mut visit: impl FnMut(Vec3, f32, Option<MediumId>, Rgb),
    ) -> Passage {
        let (mut o, mut left, mut cur, mut tr, mut travelled) = (o, t_max, medium, Rgb::ONE, 0.0f32);
        let lost = |medium| Passage { hit: None, tr: Rgb::ZERO, t: f32::INFINITY, medium };
        for _ in 0..WALK_HITS {
            let Some(h) = hit else {
                if let Some(m) = self.medium(cur) {
                    visit(o, left, cur, tr);
                    let seg = if left.is_finite() { left } else { self.segment_length(o, d, None) };
                    tr *= m.transmittance(seg);
                }
                return Passage { hit: None, tr, t: f32::INFINITY, medium: cur };
            };
            if let Some(m) = self.medium(cur) {
                visit(o, h.t, cur, tr);
                tr *= m.transmittance(h.t);
            }
            let Some(tint) = self.index_matched(&h) else {
                let t = travelled + h.t;
                return Passage { hit: Some(h), tr, t, medium: cur };
            };
            tr *= tint;
            if tr.max_element() <= 0.0 {
                return lost(cur);
            }
            cur = self.medium_after(&h, d, cur);
            let next = self.offset_origin(h.p, h.ng, d);
            let step = (next - o).dot(d);
            let rest = match end {
                Some((e, n)) => (e - next).dot(n) / d.dot(n),
                None => left - step,
            };
            (travelled, left, o) = (travelled + step, rest, next);
            if !(left > 0.0) {
                return Passage { hit: None, tr, t: f32::INFINITY, medium: cur };
            }
            hit = self.intersect(o, d, left);
        }
        lost(cur)
    }

    /// The length \[m\] of the segment a ray from `o` along unit `d` runs in its
    /// medium: to `hit`, or without one to the world sphere's end.
    #[inline]
    pub fn segment_length(&self, o: Vec3, d: Vec3, hit: Option<&Hit>) -> f32 {
        hit.map_or_else(|| self.escape_distance(o, d), |h| h.t)
    }

    /// The medium at point `p` \[m\] (walking a ray out of the scene: the innermost
    /// medium mesh it is inside, else the scene's medium).
    pub fn medium_at(&self, p: Vec3) -> Option<MediumId> {
        self.medium_walk(p, Vec3::new(0.267, 0.534, 0.802).normalize(), None)
    }

    /// The medium eye rays from `o` start in: the camera's (found when the scene's
    /// media were laid out) for an origin at the scene camera's position, else
    /// found by [`Self::medium_at`]. `None` at once in a scene whose media are all
    /// clear (nothing to track).
    pub fn eye_medium(&self, o: Vec3) -> Option<MediumId> {
        if !self.has_media() {
            return None;
        }
        match &self.camera {
            Some(c) if c.position.distance(o) <= 1e-4 * self.bounds.diagonal() => self.layout.camera,
            _ => self.medium_at(o),
        }
    }

    /// The medium light from light `li` starts in.
    pub fn light_medium(&self, li: usize) -> Option<MediumId> {
        self.layout.lights.get(li).copied().flatten()
    }

    /// The sphere (centre, radius \[m\]) lights at infinity shoot their photons
    /// from and the scene medium fills: the scene's bounding sphere, grown to hold
    /// the camera when a medium fills the scene (so every eye ray starts inside
    /// it, and eye rays, shadow rays and photons all see fog of the same extent).
    pub fn world_sphere(&self) -> (Vec3, f32) {
        (self.bounds.center(), (0.5 * self.bounds.diagonal()).max(self.layout.sphere_radius).max(1e-6))
    }

    /// How far a ray from `o` along unit `d` that hits nothing runs inside the
    /// scene's medium \[m\]: to where it leaves [`Self::world_sphere`] (the scene
    /// medium fills that sphere, so the sky and the sun are seen through fog of
    /// finite depth).
    pub fn escape_distance(&self, o: Vec3, d: Vec3) -> f32 {
        let (c, r) = self.world_sphere();
        let oc = o - c;
        let b = oc.dot(d);
        let disc = b * b - (oc.length_squared() - r * r);
        if disc <= 0.0 { 0.0 } else { (-b + disc.sqrt()).max(0.0) }
    }

    /// The medium at `p` found by a ray along `d`, leaving out object `skip`: inside
    /// object o when the ray's first hit on o is a back face; the innermost such
    /// object (nearest first back face) wins.
    fn medium_walk(&self, p: Vec3, d: Vec3, skip: Option<u32>) -> Option<MediumId> {
        let mut seen = vec![false; self.objects.len()];
        let mut o = p;
        for _ in 0..WALK_HITS {
            let Some(hit) = self.intersect(o, d, f32::INFINITY) else { break };
            let m = self.material(&hit);
            if let (Some(inside), Some(obj)) = (m.interior, self.object_of(hit.tri))
                && Some(obj) != skip
                && !std::mem::replace(&mut seen[obj as usize], true)
                && d.dot(hit.ng) > 0.0
            {
                return Some(inside);
            }
            o = self.offset_origin(hit.p, hit.ng, d);
        }
        self.layout.scene
    }

    /// Give material `name` (the loader's name, as [`Scene::names`] matches it) or,
    /// for "scene", the whole scene a medium; pipeline.toml's `[media.NAME]`, which
    /// wins over the file. Joins the content hash. Call [`Self::finish_media`] after
    /// the last one.
    pub fn set_medium(&mut self, name: &str, medium: Medium) -> Result<(), String> {
        let identity = format!("{name}:{:?}", medium);
        if name == "scene" {
            let id = self.add_medium(medium);
            self.layout.scene = Some(id);
        } else {
            let matched: Vec<usize> =
                (0..self.materials.len()).filter(|&i| Scene::names(&self.materials[i].name, name)).collect();
            if matched.is_empty() {
                return Err(format!("[media.{name}]: the scene has no material '{name}'"));
            }
            let id = self.add_medium(Medium { name: name.to_string(), ..medium });
            for i in matched {
                self.set_material_medium(i, id);
            }
        }
        self.relight(b"medium", identity.as_bytes());
        Ok(())
    }

    /// Add a medium to the list, returning its id.
    pub(crate) fn add_medium(&mut self, medium: Medium) -> MediumId {
        self.media.push(medium);
        (self.media.len() - 1) as MediumId
    }

    /// Make material `i` bound medium `id`: its surfaces separate that inside from
    /// what surrounds them, and a smooth transmitter is no longer thin-walled.
    pub(crate) fn set_material_medium(&mut self, i: usize, id: MediumId) {
        let m = &mut self.materials[i];
        m.interior = Some(id);
        m.pbr.thin = false;
        if let pm_bsdf::Bsdf::Glass { thin, .. } = &mut m.bsdf {
            *thin = false;
        }
    }

    /// Lay the media out once they are all set: the medium outside each mesh that
    /// bounds one, at the camera and at each light. Refuses a medium on a mesh that
    /// is not closed (every edge shared by two triangles), naming the material, and
    /// warns of a medium no light can enter (its material lets no light through).
    pub fn finish_media(&mut self) -> Result<(), String> {
        let n = self.objects.len();
        self.layout.outside = vec![self.layout.scene; n];
        self.layout.straddles = vec![false; n];
        self.media_flags();
        if self.media.is_empty() {
            self.layout.camera = None;
            self.layout.lights = vec![None; self.lights.len()];
            return Ok(());
        }
        let mut warned = Vec::new();
        for o in 0..n {
            let obj = &self.objects[o];
            let mat = &self.materials[obj.material as usize];
            let Some(inside) = mat.interior else { continue };
            if !self.media[inside as usize].is_clear() {
                if !closed(&self.triangles[obj.tris.start as usize..obj.tris.end as usize]) {
                    return Err(format!(
                        "material '{}': its medium needs a closed mesh, and '{}' has open edges",
                        mat.name, obj.name
                    ));
                }
                if !matches!(mat.bsdf, pm_bsdf::Bsdf::Glass { .. }) && !warned.contains(&obj.material) {
                    warned.push(obj.material);
                    self.warnings.push(format!(
                        "material '{}': it has a medium but transmits no light (transmissionFactor 0): nothing enters it",
                        mat.name
                    ));
                }
            }
        }
        self.locate_media();
        Ok(())
    }

    /// What the scene's media and materials call for, as flags.
    pub(crate) fn media_flags(&mut self) {
        self.layout.any = self.media.iter().any(|m| !m.is_clear());
        self.layout.scattering = self.media.iter().any(Medium::scatters);
        self.layout.index_matched =
            self.materials.iter().any(|m| matches!(m.bsdf, pm_bsdf::Bsdf::Glass { eta, .. } if eta == 1.0));
    }

    /// A point just in front of triangle `tri`'s centroid (offset along its
    /// geometric normal) and that normal.
    fn in_front_of(&self, tri: u32) -> (Vec3, Vec3) {
        let t = &self.triangles[tri as usize];
        let (c, ng) = ((t.p[0] + t.p[1] + t.p[2]) / 3.0, t.ng());
        (self.offset_origin(c, ng, ng), ng)
    }

    /// Find, by walks out of the scene, the medium outside each mesh that bounds
    /// one (from just in front of one of its triangles, the mesh itself left out),
    /// at the camera and at each light: after the media are set, and again whenever
    /// lights, meshes or the camera move ([`Scene::set_time`]).
    pub(crate) fn locate_media(&mut self) {
        // The world sphere holds the camera when fog fills the scene; lights at
        // infinity then shoot from the larger disc.
        let grown = match (&self.camera, self.layout.scene) {
            (Some(c), Some(_)) => c.position.distance(self.bounds.center()) * 1.001 + 1e-4 * self.bounds.diagonal(),
            _ => 0.0,
        };
        if grown != self.layout.sphere_radius {
            self.layout.sphere_radius = grown;
            crate::light::finish_lights(self);
        }
        let bounding: Vec<usize> = (0..self.objects.len())
            .filter(|&o| self.materials[self.objects[o].material as usize].interior.is_some())
            .collect();
        let bounds: Vec<crate::Bounds> = bounding
            .iter()
            .map(|&o| {
                crate::bounds_of(
                    &self.triangles[self.objects[o].tris.start as usize..self.objects[o].tris.end as usize],
                )
            })
            .collect();
        for (k, &o) in bounding.iter().enumerate() {
            let tris = self.objects[o].tris.clone();
            let (p, ng) = self.in_front_of(tris.start);
            let outside = self.medium_walk(p, ng, Some(o as u32));
            self.layout.outside[o] = outside;
            // Only a mesh whose box overlaps another medium's can have two
            // media outside it: then walks from up to 256 of its triangles,
            // spread over the mesh, say whether it does.
            let overlaps = bounds.iter().enumerate().any(|(j, b)| j != k && b.overlaps(&bounds[k]));
            let stride = (tris.len() / STRADDLE_SAMPLES).max(1);
            self.layout.straddles[o] = overlaps
                && tris.step_by(stride).any(|t| {
                    let (p, ng) = self.in_front_of(t);
                    self.medium_walk(p, ng, Some(o as u32)) != outside
                });
        }
        self.layout.camera = self.camera.as_ref().map(|c| c.position).and_then(|p| self.medium_at(p));
        self.layout.lights = (0..self.lights.len())
            .map(|li| match &self.lights[li].kind {
                LightKind::Point { position, .. } | LightKind::Spot { position, .. } => self.medium_at(*position),
                LightKind::Area { tris, .. } if !tris.is_empty() => self.medium_at(self.in_front_of(tris.start).0),
                _ => self.layout.scene,
            })
            .collect();
    }
}

/// True when `tris` close a consistently oriented surface, as a medium's boundary
/// must: corners within 1e-5 of the mesh's size of each other are one vertex (a UV
/// sphere's seam and poles differ in the last bits), and every edge between two
/// vertices is crossed once in each direction (a sliver at a pole crosses its own
/// edge both ways, which cancels).
fn closed(tris: &[crate::Triangle]) -> bool {
    use std::collections::HashMap;
    let bounds = crate::bounds_of(tris);
    let eps = 1e-5 * bounds.diagonal().max(f32::MIN_POSITIVE);
    let cell = |p: Vec3| ((p - bounds.min) / eps).floor().as_ivec3();
    let mut cells: HashMap<glam::IVec3, Vec<u32>> = HashMap::new();
    let mut verts: Vec<Vec3> = Vec::new();
    let mut weld = |p: Vec3| -> u32 {
        let c = cell(p);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = cells.get(&(c + glam::IVec3::new(dx, dy, dz)))
                        && let Some(&v) = list.iter().find(|&&v| verts[v as usize].distance(p) <= eps)
                    {
                        return v;
                    }
                }
            }
        }
        verts.push(p);
        let v = (verts.len() - 1) as u32;
        cells.entry(c).or_default().push(v);
        v
    };
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in tris {
        let v = t.p.map(&mut weld);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            if a != b {
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
    }
    edges.values().all(|&c| c == 0)
}
