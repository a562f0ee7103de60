//! The scattering models of the scene (one place for all of them): Lambertian
//! diffuse, perfect mirror, smooth dielectric (glass, solid or thin-walled), and GGX
//! microfacet glossy reflection (conductor, and the glTF 2.0 dielectric: a GGX
//! specular layer Fresnel-mixed over a diffuse base, Appendix B), the rest of glTF's
//! material model over those (clear coat, sheen, anisotropy: [`Layered`]), and
//! scattering inside media (the Henyey-Greenstein phase function).
//!
//! Conventions (pbrt-v4, chapter 9): `wo` and `wi` are unit vectors pointing away
//! from the surface; `n` is the unit shading normal on the side the geometry was
//! defined with. `f` is the BSDF value [sr^-1]; a sample's `weight` is
//! f |cos theta_i| / pdf (unitless per channel), which is what a photon's power or a
//! path's throughput is multiplied by. This crate knows nothing of scenes, photons
//! or files.

use glam::{Vec2, Vec3};
use pm_color::Rgb;
use pm_sampling::{basis, cosine_hemisphere, cosine_hemisphere_pdf};
use std::f32::consts::{FRAC_1_PI, PI, TAU};

mod albedo;
mod film;
mod layered;
mod phase;

pub use film::{FILM_IOR, Film};
pub use layered::{COAT_F0, Layered, MIN_SHEEN_ROUGHNESS, Norms};
pub use phase::{HenyeyGreenstein, PhaseSample};

/// One scattering model. Built once per material by the scene crate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// Lambertian diffuse: f = rho / pi.
    Lambert {
        /// Hemispherical reflectance rho in \[0,1\] per channel.
        rho: Rgb,
    },
    /// Perfect specular reflection with reflectance `r` (glTF metallic, roughness ~ 0).
    Mirror {
        /// Reflectance in \[0,1\] per channel.
        r: Rgb,
    },
    /// Smooth dielectric with Fresnel reflection and refraction (total internal
    /// reflection included).
    Glass {
        /// Index of refraction of the inside relative to the outside (n2 / n1).
        eta: f32,
        /// Transmittance colour in \[0,1\] per channel (glTF base colour).
        tint: Rgb,
        /// Thin-walled (no `KHR_materials_volume`): transmitted light is not bent.
        thin: bool,
    },
    /// GGX microfacet conductor with Schlick Fresnel (glTF metallic, rough).
    Conductor {
        /// Reflectance at normal incidence per channel.
        f0: Rgb,
        /// GGX roughness alpha = roughness^2.
        alpha: f32,
    },
    /// The glTF 2.0 dielectric (Appendix B, with KHR_materials_specular's weight
    /// and colour): a GGX layer w F(wo.h) D G / (4 cos_o cos_i), F = F0 + (1 - F0)
    /// (1 - wo.h)^5 Schlick's Fresnel at the half vector h, over the diffuse base.
    /// Appendix B weights the base by 1 - w max F(wo.h), which creates energy at
    /// grazing angles (a white smooth dielectric reflected 1.6 of the light at
    /// cos 0.03, 1.04 averaged over the hemisphere); here the base is weighted by
    /// what the layer leaves at both ends, rho / pi (1 - E_o)(1 - E_i) / (1 - E_avg),
    /// with E the layer's directional albedo (tabulated) and E_avg its
    /// cosine-weighted mean (albedo scaling, Kelemen and Szirmay-Kalos 2001):
    /// reciprocal, and the albedo is rho (1 - E_o) + E_o, so a white base reflects
    /// exactly everything at every roughness and angle.
    Plastic {
        /// Diffuse reflectance of the base per channel.
        rho: Rgb,
        /// GGX roughness alpha = roughness^2.
        alpha: f32,
        /// Reflectance of the specular layer at normal incidence per channel:
        /// min(((ior - 1) / (ior + 1))^2 specularColor, 1) (0.04 for ior 1.5).
        f0: Rgb,
        /// The specular layer's weight w in [0, 1] (specularFactor).
        weight: f32,
    },
    /// A clear coat, sheen or anisotropic roughness over the dielectric or metal
    /// (KHR_materials_clearcoat, _sheen, _anisotropy): [`Layered`].
    Layered(Layered),
}

/// The glTF dielectric's two parts seen from one direction ([`Bsdf::layers`]).
#[derive(Clone, Copy, Debug)]
pub struct Layers {
    /// What the diffuse base reflects of evenly arriving light, per channel:
    /// rho (1 - E_o).
    pub base_albedo: Rgb,
    /// The GGX layer alone, as a conductor of the layer's f0 and alpha.
    pub layer: Bsdf,
    /// The layer's weight (specularFactor) multiplying `layer`'s f.
    pub layer_weight: f32,
    /// E_o: the share of evenly arriving light the layer reflects toward the
    /// direction (its weight included).
    pub layer_albedo: f32,
}

/// A sampled scattering direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Incident direction (pointing away from the surface).
    pub wi: Vec3,
    /// f |cos theta_i| / pdf per channel (for specular lobes: the lobe's reflectance
    /// or transmittance divided by its selection probability).
    pub weight: Rgb,
    /// Solid-angle density of `wi` [sr^-1]; for specular lobes the discrete selection
    /// probability (pbrt's convention: not comparable with non-specular pdfs).
    pub pdf: f32,
    /// True for a delta lobe (mirror, glass).
    pub specular: bool,
    /// True when `wi` is on the other side of the surface from `wo`.
    pub transmitted: bool,
    /// The kind of lobe that was sampled.
    pub lobe: Lobe,
    /// Index of refraction on `wi`'s side over that on `wo`'s: the refraction's
    /// relative index (1.5 entering glass, 1 / 1.5 leaving it), 1 for every
    /// reflection and a thin slab's straight-through transmission.
    pub eta: f32,
}

impl BsdfSample {
    /// [`Self::weight`] for radiance traced from the eye (pbrt-v4's
    /// TransportMode::Radiance): radiance crossing a refracting interface from
    /// `wi`'s side to `wo`'s is scaled by 1 / eta^2 (Veach 1997, section 5.2),
    /// photon power is not. Along a path that enters and leaves a glass object the
    /// factors cancel; a path ending on a surface immersed in it (a pool's floor,
    /// a glass block's open base on the floor) does not, and a photon estimate
    /// there, of the radiance inside, reached the eye eta^2 = 2.25 times too
    /// bright (the differential checker's glass box on the floor: +120%).
    #[inline]
    pub fn radiance_weight(&self) -> Rgb {
        self.weight / (self.eta * self.eta)
    }
}

/// The kind of lobe a direction was sampled from (image-space photon mapping sizes
/// its kernels by it: McGuire and Luebke 2009, section 4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobe {
    /// Lambertian (cosine-weighted).
    Diffuse,
    /// A rough microfacet lobe.
    Glossy,
    /// A Dirac delta: mirror reflection or refraction.
    Specular,
}

impl Bsdf {
    /// True when every lobe is a Dirac delta (photons are not stored here; the
    /// renderer recurses instead of estimating).
    pub fn is_specular(&self) -> bool {
        matches!(self, Bsdf::Mirror { .. } | Bsdf::Glass { .. })
    }

    /// True when all the light a surface reflects leaves in one rough lobe about
    /// the mirror direction (a GGX conductor): what it sends toward the eye depends
    /// on where indirect light comes from, not only on how much arrives, so the
    /// renderers sample the lobe for it (Jensen 2001, section 9.2: glossy
    /// reflection by sampling the BSDF, the photon map read at the rays' hits)
    /// instead of reading an irradiance. Treated as diffuse with
    /// [`Self::albedo`] it took a rough metal box's indirect light 30% off
    /// in 8 x 8 blocks (the differential checker's scenes, issue 53). The glTF
    /// dielectric's lobe over its diffuse base is not glossy in this sense: the
    /// base reflects most of the light.
    pub fn is_glossy(&self) -> bool {
        match self {
            Bsdf::Conductor { .. } => true,
            Bsdf::Layered(l) => l.metal,
            _ => false,
        }
    }

    /// The sharpest GGX alpha among the lobes [`Self::layers`] splits off a
    /// diffuse base (a glTF dielectric's specular layer; a coated or sheened
    /// dielectric's coat and specular layer): renderers that read the base's light
    /// from an irradiance sample these lobes when they are sharp. None for models
    /// without such a split.
    pub fn layer_alpha(&self) -> Option<f32> {
        match self {
            Bsdf::Plastic { alpha, .. } => Some(*alpha),
            Bsdf::Layered(l) if !l.metal => Some(l.sharpest_alpha()),
            _ => None,
        }
    }

    /// The glTF dielectric ([`Bsdf::Plastic`]) seen from `wo` as its two parts, for
    /// renderers that read an irradiance for diffuse light: its base, which sends
    /// `base_albedo` / pi x E toward `wo` under irradiance E arriving evenly
    /// (rho (1 - E_o), E_o the layer's directional albedo at `wo`), and its GGX
    /// layer, whose reflection depends on where the light comes from and is to be
    /// sampled: `layer` x `layer_weight` is exactly the layer's term of
    /// [`Self::f`]. None for every other model.
    ///
    /// Read whole as [`Self::albedo`] / pi x E at the eye, a room of Blender's default
    /// materials came out 3% too bright in its indirect light: at grazing views
    /// the layer reflects the dim light near the horizon, not the hemisphere's
    /// mean (issue 53's material room; BENCHMARKS.md).
    pub fn layers(&self, wo: Vec3, n: Vec3) -> Option<Layers> {
        if let Bsdf::Layered(l) = self {
            // Everything but the diffuse base is the layer: the same model without it.
            if l.metal {
                return None;
            }
            let base_albedo = l.diffuse_albedo(wo, n);
            let layer_albedo = (l.albedo(wo, n) - base_albedo).max_element().max(0.0);
            let layer = Bsdf::Layered(Layered { rho: Rgb::ZERO, ..*l });
            return Some(Layers { base_albedo, layer, layer_weight: 1.0, layer_albedo });
        }
        let Bsdf::Plastic { rho, alpha, f0, weight } = *self else { return None };
        let cos_o = wo.dot(n).abs().min(1.0);
        let layer_albedo = weight * albedo::layer_albedo(f0.max_element(), cos_o, alpha);
        Some(Layers {
            base_albedo: rho * (1.0 - layer_albedo),
            layer: Bsdf::Conductor { f0, alpha },
            layer_weight: weight,
            layer_albedo,
        })
    }

    /// Directional albedo toward `wo` under evenly arriving light (normal `n`): the
    /// factor that turns irradiance E into outgoing radiance L = albedo / pi x E
    /// where a full BSDF evaluation is not wanted (Christensen 1999 section 2.2: the
    /// "radiance estimate" of final-gather ray hits). Exact for Lambert, and for the
    /// glTF dielectric under even light: rho (1 - E_o) + E_o, E_o its layer's
    /// directional albedo at `wo` ([`Self::layers`]; tinted by the layer's f0). A
    /// conductor's is f0, which ignores its lobe's shape ([`Self::is_glossy`]
    /// surfaces are sampled instead). Read with E_o = f0 at every angle, the
    /// dielectric's took the batch pipeline's gather hits 1.6% bright on a room of
    /// Blender's default materials (issue 53; BENCHMARKS.md).
    pub fn albedo(&self, wo: Vec3, n: Vec3) -> Rgb {
        match *self {
            Bsdf::Lambert { rho } => rho,
            Bsdf::Plastic { f0, .. } => {
                let Some(l) = self.layers(wo, n) else { return Rgb::ZERO };
                l.base_albedo + layer_tint(f0) * l.layer_albedo
            }
            Bsdf::Conductor { f0, .. } => f0,
            Bsdf::Layered(l) => l.albedo(wo, n),
            Bsdf::Mirror { .. } | Bsdf::Glass { .. } => Rgb::ZERO,
        }
    }

    /// BSDF value f(wo, wi) [sr^-1]; zero for delta lobes.
    pub fn f(&self, wo: Vec3, wi: Vec3, n: Vec3) -> Rgb {
        // Lambert needs no local frame: only the sides of wo and wi (the same dot
        // products the frame would give as z).
        match self {
            Bsdf::Lambert { rho } => {
                return if wo.dot(n) * wi.dot(n) <= 0.0 { Rgb::ZERO } else { *rho * FRAC_1_PI };
            }
            Bsdf::Layered(l) => return l.f(wo, wi, n),
            _ => {}
        }
        let (t, b) = basis(n);
        let lo = to_local(wo, t, b, n);
        let li = to_local(wi, t, b, n);
        if lo.z * li.z <= 0.0 {
            return Rgb::ZERO;
        }
        let (lo, li) = if lo.z < 0.0 { (-lo, -li) } else { (lo, li) };
        match *self {
            Bsdf::Lambert { rho } => rho * FRAC_1_PI,
            Bsdf::Conductor { f0, alpha } => ggx_f(lo, li, alpha, f0),
            Bsdf::Plastic { rho, alpha, f0, weight } => plastic_f(rho, alpha, f0, weight, lo, li),
            Bsdf::Mirror { .. } | Bsdf::Glass { .. } | Bsdf::Layered(_) => Rgb::ZERO,
        }
    }

    /// Solid-angle density of sampling `wi` given `wo` [sr^-1]; zero for delta lobes.
    pub fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        if let Bsdf::Layered(l) = self {
            return l.pdf(wo, wi, n);
        }
        let (t, b) = basis(n);
        let lo = to_local(wo, t, b, n);
        let li = to_local(wi, t, b, n);
        if lo.z * li.z <= 0.0 {
            return 0.0;
        }
        let (lo, li) = if lo.z < 0.0 { (-lo, -li) } else { (lo, li) };
        match *self {
            Bsdf::Lambert { .. } => cosine_hemisphere_pdf(li.z),
            Bsdf::Conductor { alpha, .. } => ggx_pdf(lo, li, alpha),
            Bsdf::Plastic { alpha, f0, weight, .. } => {
                let ps = plastic_spec_prob(f0, weight, lo);
                ps * ggx_pdf(lo, li, alpha) + (1.0 - ps) * cosine_hemisphere_pdf(li.z)
            }
            Bsdf::Mirror { .. } | Bsdf::Glass { .. } | Bsdf::Layered(_) => 0.0,
        }
    }

    /// Both branches of a specular BSDF at `wo` (normal `n`), for following each of
    /// them instead of one chosen at random (Whitted's recursive ray tracing; what
    /// eye paths do through their first few mirror and glass bounces): reflection,
    /// and transmission when there is one (none for a mirror or at total internal
    /// reflection). Each is [`Bsdf::sample`]'s sample of that lobe, so a branch's
    /// share of the light is `weight * pdf` (the lobe's Fresnel reflectance or
    /// transmittance times its tint). `u` is passed on to `sample`.
    pub fn specular_branches(&self, wo: Vec3, n: Vec3, u: Vec2) -> [Option<BsdfSample>; 2] {
        let reflected = self.sample(wo, n, u, 0.0);
        let transmitted = self.sample(wo, n, u, 1.0 - f32::EPSILON).filter(|t| t.transmitted);
        [reflected, transmitted]
    }

    /// Importance-sample an incident direction. `u` picks the direction, `uc` the lobe.
    /// Returns `None` when the sample carries no energy (below the horizon, or a
    /// degenerate microfacet configuration).
    pub fn sample(&self, wo: Vec3, n: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        if let Bsdf::Layered(l) = self {
            return l.sample(wo, n, u, uc).filter(|s| s.wi.is_finite() && s.weight.is_finite());
        }
        let (t, b) = basis(n);
        let lo_raw = to_local(wo, t, b, n);
        if lo_raw.z == 0.0 || !lo_raw.is_finite() {
            return None;
        }
        // Work on the side of wo; flip back at the end.
        let side = lo_raw.z.signum();
        let lo = lo_raw * Vec3::new(1.0, 1.0, side);
        let world = |l: Vec3| to_world(l * Vec3::new(1.0, 1.0, side), t, b, n);
        let s = match *self {
            Bsdf::Layered(_) => return None,
            Bsdf::Lambert { rho } => {
                let li = cosine_hemisphere(u);
                if li.z <= 0.0 {
                    return None;
                }
                BsdfSample {
                    wi: world(li),
                    weight: rho,
                    pdf: cosine_hemisphere_pdf(li.z),
                    specular: false,
                    transmitted: false,
                    lobe: Lobe::Diffuse,
                    eta: 1.0,
                }
            }
            Bsdf::Mirror { r } => {
                let li = Vec3::new(-lo.x, -lo.y, lo.z);
                BsdfSample {
                    wi: world(li),
                    weight: r,
                    pdf: 1.0,
                    specular: true,
                    transmitted: false,
                    lobe: Lobe::Specular,
                    eta: 1.0,
                }
            }
            Bsdf::Glass { eta, tint, thin } => sample_glass(lo_raw, eta, tint, thin, uc, |l| to_world(l, t, b, n))?,
            Bsdf::Conductor { f0, alpha } => {
                let li = reflect(lo, ggx_sample_h(u, alpha));
                if li.z <= 0.0 {
                    return None;
                }
                let pdf = ggx_pdf(lo, li, alpha);
                if pdf <= 0.0 {
                    return None;
                }
                BsdfSample {
                    wi: world(li),
                    weight: ggx_f(lo, li, alpha, f0) * li.z / pdf,
                    pdf,
                    specular: false,
                    transmitted: false,
                    lobe: Lobe::Glossy,
                    eta: 1.0,
                }
            }
            Bsdf::Plastic { rho, alpha, f0, weight } => {
                let ps = plastic_spec_prob(f0, weight, lo);
                let li = if uc < ps { reflect(lo, ggx_sample_h(u, alpha)) } else { cosine_hemisphere(u) };
                if li.z <= 0.0 {
                    return None;
                }
                let pdf = ps * ggx_pdf(lo, li, alpha) + (1.0 - ps) * cosine_hemisphere_pdf(li.z);
                if pdf <= 0.0 {
                    return None;
                }
                let f = plastic_f(rho, alpha, f0, weight, lo, li);
                let lobe = if uc < ps { Lobe::Glossy } else { Lobe::Diffuse };
                BsdfSample {
                    wi: world(li),
                    weight: f * li.z / pdf,
                    pdf,
                    specular: false,
                    transmitted: false,
                    lobe,
                    eta: 1.0,
                }
            }
        };
        (s.wi.is_finite() && s.weight.is_finite()).then_some(s)
    }
}

/// The colour of a specular layer of reflectance `f0`: F0 over its largest channel
/// (white for a black F0). Its directional albedo, tabulated for that channel,
/// times this is the layer's albedo per channel.
fn layer_tint(f0: Rgb) -> Rgb {
    let m = f0.max_element();
    if m > 0.0 { f0 / m } else { Rgb::ONE }
}

#[inline]
fn to_local(v: Vec3, t: Vec3, b: Vec3, n: Vec3) -> Vec3 {
    Vec3::new(v.dot(t), v.dot(b), v.dot(n))
}

#[inline]
fn to_world(l: Vec3, t: Vec3, b: Vec3, n: Vec3) -> Vec3 {
    (t * l.x + b * l.y + n * l.z).normalize_or_zero()
}

#[inline]
fn reflect(wo: Vec3, h: Vec3) -> Vec3 {
    2.0 * wo.dot(h) * h - wo
}

/// Unpolarised Fresnel reflectance of a smooth dielectric interface (pbrt-v4 eq.
/// 9.5). `cos_i` is measured on the incident side, `eta` = n_t / n_i. Returns 1 on
/// total internal reflection.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// Smooth glass in the local frame; `lo.z` < 0 means wo is inside the object.
fn sample_glass(
    lo: Vec3,
    eta: f32,
    tint: Rgb,
    thin: bool,
    uc: f32,
    world: impl Fn(Vec3) -> Vec3,
) -> Option<BsdfSample> {
    let entering = lo.z > 0.0;
    let eta_rel = if thin || entering { eta } else { 1.0 / eta };
    let cos_o = lo.z.abs();
    let mut r = fresnel_dielectric(cos_o, eta_rel);
    if thin && r < 1.0 {
        // Thin slab: multiple internal bounces between two parallel faces,
        // R' = R + T^2 R / (1 - R^2) = 2R / (1 + R) (pbrt-v4 ThinDielectricBxDF).
        r += (1.0 - r) * (1.0 - r) * r / (1.0 - r * r);
    }
    if uc < r {
        let li = Vec3::new(-lo.x, -lo.y, lo.z);
        return Some(BsdfSample {
            wi: world(li),
            weight: Rgb::ONE,
            pdf: r,
            specular: true,
            transmitted: false,
            lobe: Lobe::Specular,
            eta: 1.0,
        });
    }
    let li = if thin {
        -lo
    } else {
        // Snell refraction about the normal on wo's side.
        let n_side = Vec3::new(0.0, 0.0, lo.z.signum());
        let cos_i = cos_o;
        let sin2_t = (1.0 - cos_i * cos_i) / (eta_rel * eta_rel);
        if sin2_t >= 1.0 {
            return None; // unreachable: r == 1 under total internal reflection
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        -lo / eta_rel + (cos_i / eta_rel - cos_t) * n_side
    };
    // The power (photon) weight; radiance traced from the eye takes
    // BsdfSample::radiance_weight, 1 / eta^2 of it.
    Some(BsdfSample {
        wi: world(li),
        weight: tint,
        pdf: 1.0 - r,
        specular: true,
        transmitted: true,
        lobe: Lobe::Specular,
        eta: if thin { 1.0 } else { eta_rel },
    })
}

/// GGX normal distribution D(h) [sr^-1] (Walter et al. 2007, eq. 33).
fn ggx_d(cos_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let d = c2 * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

/// Smith masking G1 for GGX (Walter et al. 2007, eq. 34).
fn ggx_g1(cos_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let c2 = cos_v * cos_v;
    2.0 * cos_v / (cos_v + (a2 + (1.0 - a2) * c2).max(0.0).sqrt())
}

fn schlick(f0: Rgb, cos: f32) -> Rgb {
    let m = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0 + (Rgb::ONE - f0) * m
}

/// GGX microfacet reflection f = D G F / (4 cos_o cos_i), both directions above the surface.
fn ggx_f(lo: Vec3, li: Vec3, alpha: f32, f0: Rgb) -> Rgb {
    let h = (lo + li).normalize_or_zero();
    if h == Vec3::ZERO || lo.z <= 0.0 || li.z <= 0.0 {
        return Rgb::ZERO;
    }
    let d = ggx_d(h.z, alpha);
    let g = ggx_g1(lo.z, alpha) * ggx_g1(li.z, alpha);
    schlick(f0, lo.dot(h)) * (d * g / (4.0 * lo.z * li.z))
}

/// Sample a half vector from D(h) cos(theta_h).
fn ggx_sample_h(u: Vec2, alpha: f32) -> Vec3 {
    let a2 = alpha * alpha;
    let cos2 = ((1.0 - u.x) / (1.0 + (a2 - 1.0) * u.x)).clamp(0.0, 1.0);
    let cos_t = cos2.sqrt();
    let sin_t = (1.0 - cos2).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Solid-angle pdf of `li` under half-vector sampling: D(h) cos_h / (4 |lo.h|).
fn ggx_pdf(lo: Vec3, li: Vec3, alpha: f32) -> f32 {
    let h = (lo + li).normalize_or_zero();
    let lh = lo.dot(h);
    if h.z <= 0.0 || lh <= 0.0 {
        return 0.0;
    }
    ggx_d(h.z, alpha) * h.z / (4.0 * lh)
}

/// The glTF dielectric's f (Appendix B's fresnel_mix, KHR_materials_specular's
/// form): the diffuse base weighted by 1 - w max(F), the GGX layer by w F, with F
/// Schlick's Fresnel at the half vector of `lo` and `li`.
fn plastic_f(rho: Rgb, alpha: f32, f0: Rgb, weight: f32, lo: Vec3, li: Vec3) -> Rgb {
    let h = (lo + li).normalize_or_zero();
    if h == Vec3::ZERO || lo.z <= 0.0 || li.z <= 0.0 {
        return Rgb::ZERO;
    }
    let f = schlick(f0, lo.dot(h).abs());
    let d = ggx_d(h.z, alpha);
    let g = ggx_g1(lo.z, alpha) * ggx_g1(li.z, alpha);
    // The layer's albedo at each end (the largest channel), and its mean.
    let m0 = f0.max_element();
    let layer = |cos: f32| weight * albedo::layer_albedo(m0, cos, alpha);
    let mean = weight * albedo::layer_albedo_mean(m0, alpha);
    let base = (1.0 - layer(lo.z)) * (1.0 - layer(li.z)) / (1.0 - mean).max(1e-4);
    rho * (FRAC_1_PI * base) + f * (weight * d * g / (4.0 * lo.z * li.z))
}

/// Probability of sampling the specular layer: its Fresnel weight seen from `lo`,
/// kept away from 0 and 1.
fn plastic_spec_prob(f0: Rgb, weight: f32, lo: Vec3) -> f32 {
    (weight * schlick(f0, lo.z).max_element()).clamp(0.1, 0.9)
}

/// Below this roughness a metal is a perfect mirror.
pub const MIRROR_ROUGHNESS: f32 = 0.05;
/// GGX alpha is clamped from below: near-delta microfacet lobes are numerically
/// unstable and better served by the mirror model.
pub const MIN_ALPHA: f32 = 0.02;

/// The glTF 2.0 metallic-roughness parameters at one surface point (factors times
/// texture values): what [`Bsdf::from_pbr`] turns into a scattering model, for the
/// material's factors once and for every textured shading point alike.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pbr {
    /// Base colour, linear, in [0, 1] per channel.
    pub base: Rgb,
    /// Metalness in [0, 1] (selects the conductor at 0.5 and above).
    pub metallic: f32,
    /// Perceptual roughness in [0, 1]; GGX alpha = roughness^2.
    pub roughness: f32,
    /// KHR_materials_transmission factor in [0, 1] (selects glass above 0).
    pub transmission: f32,
    /// Index of refraction (KHR_materials_ior), >= 1.
    pub ior: f32,
    /// Thin-walled transmission (no KHR_materials_volume thickness).
    pub thin: bool,
    /// KHR_materials_specular's specularFactor in [0, 1]: the dielectric's specular
    /// layer weight (1 without the extension; 0 makes a pure Lambertian).
    pub specular: f32,
    /// KHR_materials_specular's specularColorFactor (linear, >= 0): tints the
    /// dielectric's F0 (one without the extension).
    pub specular_color: Rgb,
    /// KHR_materials_clearcoat's weight in [0, 1] (clearcoatFactor x texture; 0
    /// without the extension).
    pub coat: f32,
    /// The coat's perceptual roughness in [0, 1] (alpha = roughness^2).
    pub coat_roughness: f32,
    /// The coat's unit normal in world space (clearcoatNormalTexture); zero: the
    /// shading normal.
    pub coat_normal: Vec3,
    /// KHR_materials_sheen's colour, linear (zero without the extension).
    pub sheen: Rgb,
    /// The sheen's perceptual roughness in [0, 1].
    pub sheen_roughness: f32,
    /// KHR_materials_anisotropy's strength in [0, 1] (0 without the extension).
    pub anisotropy: f32,
    /// The unit anisotropy direction in world space (the tangent rotated by
    /// anisotropyRotation, or the anisotropy texture's direction); zero when the
    /// surface has no tangents.
    pub anisotropy_dir: Vec3,
    /// KHR_materials_iridescence's weight in [0, 1] (iridescenceFactor x
    /// texture; 0 without the extension).
    pub iridescence: f32,
    /// The thin film's index of refraction (iridescenceIor).
    pub iridescence_ior: f32,
    /// The thin film's thickness [nm].
    pub iridescence_thickness: f32,
}

impl Pbr {
    /// The glTF defaults for a base colour: a fully rough dielectric, ior 1.5, with
    /// the specification's specular layer.
    pub fn dielectric(base: Rgb) -> Pbr {
        Pbr {
            base,
            metallic: 0.0,
            roughness: 1.0,
            transmission: 0.0,
            ior: 1.5,
            thin: true,
            specular: 1.0,
            specular_color: Rgb::ONE,
            coat: 0.0,
            coat_roughness: 0.0,
            coat_normal: Vec3::ZERO,
            sheen: Rgb::ZERO,
            sheen_roughness: 0.0,
            anisotropy: 0.0,
            anisotropy_dir: Vec3::ZERO,
            iridescence: 0.0,
            iridescence_ior: FILM_IOR,
            iridescence_thickness: 400.0,
        }
    }

    /// True when the point has a clear coat, sheen, anisotropy or a thin film: its model is
    /// [`Bsdf::Layered`].
    pub fn is_layered(&self) -> bool {
        self.coat > 0.0 || self.sheen.max_element() > 0.0 || self.anisotropy > 0.0 || self.iridescence > 0.0
    }
}

impl Bsdf {
    /// The scattering model of glTF parameters: glass when transmissive; a metal is
    /// a mirror below [`MIRROR_ROUGHNESS`] and a GGX conductor with F0 = base colour
    /// above; a dielectric is the specification's Fresnel mix of a GGX specular layer
    /// over the diffuse base at every roughness (Appendix B), Lambertian only when
    /// KHR_materials_specular turns the layer off (specularFactor or F0 zero).
    pub fn from_pbr(p: &Pbr) -> Bsdf {
        let base = p.base.clamp(Rgb::ZERO, Rgb::ONE);
        let roughness = p.roughness.clamp(0.0, 1.0);
        let alpha = (roughness * roughness).max(MIN_ALPHA);
        if p.transmission > 0.0 {
            Bsdf::Glass { eta: p.ior, tint: base, thin: p.thin }
        } else if p.is_layered() {
            Bsdf::Layered(Layered::from_pbr(p))
        } else if p.metallic >= 0.5 {
            if roughness < MIRROR_ROUGHNESS { Bsdf::Mirror { r: base } } else { Bsdf::Conductor { f0: base, alpha } }
        } else {
            let r = (p.ior - 1.0) / (p.ior + 1.0);
            let f0 = (p.specular_color.max(Rgb::ZERO) * (r * r)).min(Rgb::ONE);
            let weight = p.specular.clamp(0.0, 1.0);
            if weight == 0.0 || f0 == Rgb::ZERO || !f0.is_finite() {
                Bsdf::Lambert { rho: base }
            } else {
                Bsdf::Plastic { rho: base, alpha, f0, weight }
            }
        }
    }
}

#[cfg(test)]
mod tests;

impl Bsdf {
    /// The same model with its colour parameter multiplied by `c` (a texture lookup).
    pub fn tinted(self, c: Rgb) -> Bsdf {
        let c = c.clamp(Rgb::ZERO, Rgb::ONE);
        match self {
            Bsdf::Lambert { rho } => Bsdf::Lambert { rho: rho * c },
            Bsdf::Mirror { r } => Bsdf::Mirror { r: r * c },
            Bsdf::Glass { eta, tint, thin } => Bsdf::Glass { eta, tint: tint * c, thin },
            Bsdf::Conductor { f0, alpha } => Bsdf::Conductor { f0: f0 * c, alpha },
            Bsdf::Plastic { rho, alpha, f0, weight } => Bsdf::Plastic { rho: rho * c, alpha, f0, weight },
            Bsdf::Layered(l) if l.metal => Bsdf::Layered(Layered { f0: l.f0 * c, ..l }),
            Bsdf::Layered(l) => Bsdf::Layered(Layered { rho: l.rho * c, ..l }),
        }
    }
}

#[cfg(test)]
mod layered_tests;
