//! The rest of the glTF material model over the core dielectric and metal: a
//! clear coat (KHR_materials_clearcoat), sheen (KHR_materials_sheen) and
//! anisotropic roughness (KHR_materials_anisotropy), as one reciprocal BSDF.
//!
//! f = c f_coat + S_c(o) S_c(i) k_c [ f_sheen + S_s(o) S_s(i) k_s f_base ]
//!
//! - f_coat: a GGX layer of F0 = 0.04 (ior 1.5) and the coat's roughness about the
//!   coat's normal, weighted by the coat factor c (the extension's
//!   `fresnel_coat` mix);
//! - f_sheen: the Charlie distribution with the visibility term of Estevez and
//!   Kulla 2017 ("Production friendly microfacet sheen BRDF"), as
//!   KHR_materials_sheen gives it, times the sheen colour;
//! - f_base: the glTF dielectric ([`crate::Bsdf::Plastic`]'s form) or metal, its
//!   GGX lobe anisotropic (alpha_t = mix(alpha, 1, strength^2) along the
//!   anisotropy direction, alpha_b = alpha across it: KHR_materials_anisotropy).
//!
//! S(mu) = 1 - w E(mu) is what a layer of weight w and directional albedo E
//! leaves at cosine mu (the albedo scaling both extensions prescribe), taken at
//! both ends so that f stays reciprocal; k = 1 / (1 - w E_min), E_min the layer's
//! least albedo over mu, gives back part of what the product takes twice while
//! keeping k S(mu) <= 1. The dielectric's diffuse base is rho / pi P(o) P(i) / K,
//! P(mu) the product of what every layer above it leaves (its own specular layer's
//! 1 - L(mu) included) and K = 2 int P(mu) mu dmu: a white base then reflects
//! exactly what the layers leave, so a white coated or sheened dielectric's
//! albedo is 1 less only what the glossy lobes lose under the layers above them,
//! and never more than 1: c E_c + S_c(o) [s E_s + S_s(o) (L + 1 - L)] = 1 bounds
//! it. (With one normalisation per layer, each for a Lambertian below it, the
//! layers' albedos rise together toward grazing and a white dielectric under a
//! coat and sheen reflected 1.017 at normal incidence.)

use crate::{
    BsdfSample, Film, Lobe, MIN_ALPHA, Pbr, albedo, ggx_d, ggx_f, ggx_g1, ggx_pdf, ggx_sample_h, reflect, schlick,
    to_local, to_world,
};
use glam::{Vec2, Vec3};
use pm_color::Rgb;
use pm_sampling::{basis, cosine_hemisphere, cosine_hemisphere_pdf};
use std::f32::consts::{FRAC_1_PI, PI, TAU};

/// Reflectance of the clear coat at normal incidence: ior 1.5
/// (KHR_materials_clearcoat fixes it).
pub const COAT_F0: f32 = 0.04;

/// Sheen roughness below this is read as this: the Charlie distribution's
/// sin^(1/alpha) is a spike at grazing angles beneath it (the Khronos sample
/// viewer clamps at the same value).
pub const MIN_SHEEN_ROUGHNESS: f32 = 0.07;

/// The least share of samples a present lobe gets: no lobe that has a value is
/// left to a probability near zero (its samples would carry huge weights).
const MIN_LOBE_PROB: f32 = 0.05;

/// A surface with glTF's clear coat, sheen and anisotropy over the dielectric or
/// metal base. Every quantity is at one surface point (textures applied).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layered {
    /// Diffuse reflectance of a dielectric base per channel (zero for a metal).
    pub rho: Rgb,
    /// The base's GGX lobe's reflectance at normal incidence per channel: the base
    /// colour for a metal, the dielectric's F0 (as in [`crate::Bsdf::Plastic`]).
    pub f0: Rgb,
    /// The dielectric's specular weight (specularFactor); 1 for a metal.
    pub spec_weight: f32,
    /// The base is a metal (a GGX conductor), not a dielectric.
    pub metal: bool,
    /// GGX alpha along the anisotropy direction (alpha_t) and across it (alpha_b);
    /// equal without anisotropy.
    pub alpha: Vec2,
    /// Unit anisotropy direction in world space, in the surface's tangent plane
    /// (the tangent rotated by anisotropyRotation); zero when isotropic.
    pub tangent: Vec3,
    /// Clear coat weight c in [0, 1] (clearcoatFactor x texture).
    pub coat: f32,
    /// The coat's GGX alpha (clearcoatRoughness^2, at least [`crate::MIN_ALPHA`]).
    pub coat_alpha: f32,
    /// The coat's unit normal in world space (its normal texture); zero: the
    /// surface's shading normal.
    pub coat_normal: Vec3,
    /// Sheen colour, linear, per channel (zero: no sheen).
    pub sheen: Rgb,
    /// Sheen alpha = sheenRoughness^2 (roughness at least [`MIN_SHEEN_ROUGHNESS`]).
    pub sheen_alpha: f32,
    /// A thin film over the base's specular lobe ([`Film::NONE`]: none).
    pub film: Film,
    /// K = 2 int P(mu) mu dmu, the diffuse base's normalisation, and the glossy
    /// lobes' k_c and k_s (module doc): set by [`Layered::normalised`], which
    /// whoever changes the fields above calls.
    pub norms: Norms,
}

/// What [`Layered::normalised`] computes once from a model's fields rather than
/// at every evaluation (k_c alone is a minimum over 32 table lookups).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Norms {
    /// K = 2 int P(mu) mu dmu, per channel.
    pub diffuse: Rgb,
    /// k_c = 1 / (1 - c E_c,min).
    pub coat: f32,
    /// k_s = 1 / (1 - s E_s,min).
    pub sheen: f32,
}

/// The two local frames at one wo, on wo's side of the surface, and wo in them.
struct Frames {
    /// The base frame: x along the anisotropy direction, z the normal on wo's side.
    base: [Vec3; 3],
    /// The coat's frame: z its normal on wo's side.
    coat: [Vec3; 3],
    /// wo in the base frame, z > 0.
    lo: Vec3,
    /// wo in the coat's frame.
    co: Vec3,
}

impl Frames {
    /// A direction in both frames.
    fn local(&self, w: Vec3) -> (Vec3, Vec3) {
        let ([t, b, n], [tc, bc, nc]) = (self.base, self.coat);
        (to_local(w, t, b, n), to_local(w, tc, bc, nc))
    }
}

/// Per-lobe sampling probabilities at one wo (coat, sheen, specular, diffuse).
#[derive(Clone, Copy, Debug)]
struct LobeProbs([f32; 4]);

impl Layered {
    /// The model of glTF parameters with a coat, sheen or anisotropy
    /// ([`Pbr::is_layered`]): the base as [`crate::Bsdf::from_pbr`] makes it (a
    /// metal at metallic 0.5 and above, F0 = base colour; else the dielectric of
    /// its ior and KHR_materials_specular), alpha_t = mix(alpha, 1, strength^2) and
    /// alpha_b = alpha (KHR_materials_anisotropy), the coat's alpha its
    /// roughness^2, the sheen's its roughness^2 (roughness at least
    /// [`MIN_SHEEN_ROUGHNESS`]).
    pub fn from_pbr(p: &Pbr) -> Layered {
        let base = p.base.clamp(Rgb::ZERO, Rgb::ONE);
        let r = p.roughness.clamp(0.0, 1.0);
        let alpha = r * r;
        let s = p.anisotropy.clamp(0.0, 1.0);
        let alpha_t = alpha + (1.0 - alpha) * s * s;
        let metal = p.metallic >= 0.5;
        let (rho, f0, spec_weight) = if metal {
            (Rgb::ZERO, base, 1.0)
        } else {
            let q = (p.ior - 1.0) / (p.ior + 1.0);
            let f0 = (p.specular_color.max(Rgb::ZERO) * (q * q)).min(Rgb::ONE);
            (base, if f0.is_finite() { f0 } else { Rgb::ZERO }, p.specular.clamp(0.0, 1.0))
        };
        let cr = p.coat_roughness.clamp(0.0, 1.0);
        let sr = p.sheen_roughness.clamp(MIN_SHEEN_ROUGHNESS, 1.0);
        let unit = |v: Vec3| if v.is_finite() { v.normalize_or_zero() } else { Vec3::ZERO };
        Layered {
            rho,
            f0,
            spec_weight,
            metal,
            alpha: Vec2::new(alpha_t.max(MIN_ALPHA), alpha.max(MIN_ALPHA)),
            tangent: if s > 0.0 { unit(p.anisotropy_dir) } else { Vec3::ZERO },
            coat: p.coat.clamp(0.0, 1.0),
            coat_alpha: (cr * cr).max(MIN_ALPHA),
            coat_normal: unit(p.coat_normal),
            sheen: p.sheen.clamp(Rgb::ZERO, Rgb::ONE),
            sheen_alpha: sr * sr,
            film: if p.iridescence > 0.0 {
                Film {
                    weight: p.iridescence.clamp(0.0, 1.0),
                    ior: p.iridescence_ior.max(1.0),
                    thickness: p.iridescence_thickness.max(0.0),
                }
            } else {
                Film::NONE
            },
            norms: Norms { diffuse: Rgb::ONE, coat: 1.0, sheen: 1.0 },
        }
        .normalised()
    }

    /// The same model with [`Self::norms`] computed for its fields: K = 2 int
    /// P(mu) mu dmu by the midpoint rule at 32 cosines, k_c and k_s from the
    /// layers' least albedos.
    pub fn normalised(self) -> Layered {
        const M: usize = 32;
        let k: Rgb = (0..M)
            .map(|i| {
                let mu = (i as f32 + 0.5) / M as f32;
                self.leaves(mu) * mu
            })
            .sum::<Rgb>()
            * 2.0
            / M as f32;
        let coat = 1.0 / (1.0 - self.coat * albedo::layer_albedo_min(COAT_F0, self.coat_alpha)).max(1e-4);
        let sheen = 1.0 / (1.0 - self.sheen_max() * albedo::sheen_albedo_min(self.sheen_alpha)).max(1e-4);
        Layered { norms: Norms { diffuse: k.max(Rgb::splat(1e-4)), coat, sheen }, ..self }
    }

    /// The base's specular Fresnel at cosine `cos` to the half vector: Schlick's
    /// of [`Self::f0`], mixed toward the film's by its weight. The film is lit from
    /// air under a clear coat too: glTF's coat does not refract what reaches the
    /// base (the base's Schlick term keeps its grazing rise under it), and the
    /// film follows it, as the Khronos sample viewer does; the extension's
    /// non-normative note would put the coat's index above the film.
    fn fresnel(&self, cos: f32) -> Rgb {
        let f = schlick(self.f0, cos);
        if self.film.weight > 0.0 { f.lerp(self.film.reflectance(cos, 1.0, self.f0), self.film.weight) } else { f }
    }

    /// P(mu) per channel: what the coat, the sheen and the dielectric's own
    /// specular layer leave for the diffuse base at cosine `mu` (module doc).
    fn leaves(&self, mu: f32) -> Rgb {
        (Rgb::ONE - self.spec_albedo(mu)) * (self.sheen_leaves(mu) * self.coat_leaves(mu))
    }

    /// The base frame at normal `n`: x along the anisotropy direction (without
    /// one, `basis(n)`'s, which lies the same way for `n` and `-n`: renderers
    /// pass the normal turned toward the viewer or not).
    fn base_frame(&self, n: Vec3) -> (Vec3, Vec3) {
        let t = self.tangent - n * n.dot(self.tangent);
        if t.length_squared() > 1e-8 {
            let t = t.normalize();
            (t, n.cross(t))
        } else {
            basis(n)
        }
    }

    /// The coat's normal on `n`'s side.
    fn coat_n(&self, n: Vec3) -> Vec3 {
        if self.coat_normal == Vec3::ZERO {
            n
        } else if self.coat_normal.dot(n) < 0.0 {
            -self.coat_normal
        } else {
            self.coat_normal
        }
    }

    /// The sheen's scalar weight (its colour's largest channel).
    fn sheen_max(&self) -> f32 {
        self.sheen.max_element().clamp(0.0, 1.0)
    }

    /// The isotropic alpha whose albedo table stands for the base's specular
    /// lobe: the smaller of the two (its albedo the larger, the diffuse base's
    /// share the smaller; with their geometric mean a white anisotropic dielectric
    /// under a coat reflected 1.009 at normal incidence).
    fn alpha_iso(&self) -> f32 {
        self.alpha.x.min(self.alpha.y)
    }

    /// What the coat leaves at cosine `mu` (about the coat normal): 1 - c E_c(mu).
    fn coat_leaves(&self, mu: f32) -> f32 {
        1.0 - self.coat * albedo::layer_albedo(COAT_F0, mu, self.coat_alpha)
    }

    /// What the sheen leaves at cosine `mu`: 1 - s E_s(mu).
    fn sheen_leaves(&self, mu: f32) -> f32 {
        1.0 - self.sheen_max() * albedo::sheen_albedo(mu, self.sheen_alpha)
    }

    /// The F0 per channel whose Schlick curve meets the base's Fresnel at cosine
    /// `mu`: [`Self::f0`], or under a thin film the film's reflectance at `mu`
    /// with Schlick's grazing term taken out. The film's reflectance oscillates
    /// with angle and the albedo tables know Schlick's curve only, so each cosine
    /// takes the lobe of its own F0 (the split-sum approximation: the Fresnel at
    /// the viewing angle, not at every half vector).
    fn lobe_f0(&self, mu: f32) -> Rgb {
        if self.film.weight > 0.0 {
            let m = (1.0 - mu.clamp(0.0, 1.0)).powi(5);
            ((self.fresnel(mu) - Rgb::splat(m)) / (1.0 - m).max(1e-6)).clamp(Rgb::ZERO, Rgb::ONE)
        } else {
            self.f0
        }
    }

    /// The dielectric's specular layer albedo L(mu) per channel (its weight
    /// included), each channel's from the layer table at its own F0.
    fn spec_albedo(&self, mu: f32) -> Rgb {
        let f0 = self.lobe_f0(mu);
        let a = self.alpha_iso();
        let l = if f0.x == f0.y && f0.y == f0.z {
            Rgb::splat(albedo::layer_albedo(f0.x, mu, a))
        } else {
            f0.map(|f| albedo::layer_albedo(f, mu, a))
        };
        l * self.spec_weight
    }

    /// The frames at wo, turned to its side of the surface; None at grazing.
    fn frames(&self, wo: Vec3, n: Vec3) -> Option<Frames> {
        if wo.dot(n) == 0.0 || !wo.is_finite() {
            return None;
        }
        let side = wo.dot(n).signum();
        let (t, b) = self.base_frame(n);
        let nc = self.coat_n(n) * side;
        let (tc, bc) = basis(nc);
        let mut f = Frames { base: [t, b, n * side], coat: [tc, bc, nc], lo: Vec3::ZERO, co: Vec3::ZERO };
        (f.lo, f.co) = f.local(wo);
        Some(f)
    }

    /// The lobes' sampling probabilities at wo: each lobe's share of what the
    /// surface reflects toward wo under even light, a present lobe at least
    /// [`MIN_LOBE_PROB`].
    fn probs(&self, f: &Frames) -> LobeProbs {
        let mu_c = f.co.z.clamp(0.0, 1.0);
        let mu = f.lo.z.clamp(0.0, 1.0);
        let coat = self.coat * albedo::layer_albedo(COAT_F0, mu_c, self.coat_alpha);
        let under = 1.0 - coat;
        let s = self.sheen_max();
        let sheen = under * s * albedo::sheen_albedo(mu, self.sheen_alpha);
        let base = under - sheen;
        let (spec, diffuse) = if self.metal {
            (base, 0.0)
        } else {
            let l = self.spec_albedo(mu).max_element();
            (base * l, base * (1.0 - l) * self.rho.max_element())
        };
        let mut p = [coat, sheen, spec, diffuse];
        let spec_on = self.metal || (self.spec_weight > 0.0 && self.f0.max_element() > 0.0);
        let present = [self.coat > 0.0 && f.co.z > 0.0, s > 0.0, spec_on, !self.metal && self.rho.max_element() > 0.0];
        for (pi, &on) in p.iter_mut().zip(&present) {
            *pi = if on { pi.max(MIN_LOBE_PROB) } else { 0.0 };
        }
        let sum: f32 = p.iter().sum();
        if !(sum > 0.0) {
            // Nothing reflects (a black, layerless dielectric): any lobe will do.
            return LobeProbs([0.0, 0.0, 0.0, 1.0]);
        }
        LobeProbs(p.map(|x| x / sum))
    }

    /// f in the local frames [sr^-1]; `li`, `ci` are wi in the base and coat frames.
    fn f_local(&self, lo: Vec3, li: Vec3, co: Vec3, ci: Vec3) -> Rgb {
        if lo.z <= 0.0 || li.z <= 0.0 {
            return Rgb::ZERO;
        }
        let (mu_o, mu_i) = (lo.z.min(1.0), li.z.min(1.0));
        // The glossy lobes, each under what the layers above it leave.
        let mut glossy = match aniso_ggx_dg(lo, li, self.alpha) {
            Some((dg, cos_h)) => self.fresnel(cos_h) * dg * self.spec_weight,
            None => Rgb::ZERO,
        };
        if self.sheen_max() > 0.0 {
            glossy *= self.sheen_leaves(mu_o) * self.sheen_leaves(mu_i) * self.norms.sheen;
            glossy += self.sheen * charlie_f(lo, li, self.sheen_alpha);
        }
        if self.coat > 0.0 {
            glossy *= self.coat_leaves(mu_o) * self.coat_leaves(mu_i) * self.norms.coat;
            if co.z > 0.0 && ci.z > 0.0 {
                glossy += ggx_f(co, ci, self.coat_alpha, Rgb::splat(COAT_F0)) * self.coat;
            }
        }
        if self.metal {
            return glossy;
        }
        glossy + self.rho * self.leaves(mu_o) * self.leaves(mu_i) / self.norms.diffuse * FRAC_1_PI
    }

    /// The mixture pdf [sr^-1] of the lobes at `probs`.
    fn pdf_local(&self, p: LobeProbs, lo: Vec3, li: Vec3, co: Vec3, ci: Vec3) -> f32 {
        if lo.z <= 0.0 || li.z <= 0.0 {
            return 0.0;
        }
        let [pc, ps, pg, pd] = p.0;
        let mut pdf = (ps + pd) * cosine_hemisphere_pdf(li.z) + pg * aniso_ggx_pdf(lo, li, self.alpha);
        // The coat's lobe draws wi about the coat's normal, below its horizon too.
        if pc > 0.0 && co.z > 0.0 {
            pdf += pc * ggx_pdf(co, ci, self.coat_alpha);
        }
        pdf
    }

    /// BSDF value f(wo, wi) [sr^-1] about shading normal `n`.
    pub fn f(&self, wo: Vec3, wi: Vec3, n: Vec3) -> Rgb {
        let Some(fr) = self.frames(wo, n) else { return Rgb::ZERO };
        let (li, ci) = fr.local(wi);
        self.f_local(fr.lo, li, fr.co, ci)
    }

    /// Solid-angle density of [`Self::sample`] drawing `wi` [sr^-1].
    pub fn pdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> f32 {
        let Some(fr) = self.frames(wo, n) else { return 0.0 };
        let (li, ci) = fr.local(wi);
        self.pdf_local(self.probs(&fr), fr.lo, li, fr.co, ci)
    }

    /// Draw wi: a lobe chosen by `uc` with [`Self::probs`], its direction by `u`;
    /// the weight is the whole f cos / the mixture pdf (one-sample MIS).
    pub fn sample(&self, wo: Vec3, n: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        let fr = self.frames(wo, n)?;
        let p = self.probs(&fr);
        let [pc, ps, pg, _] = p.0;
        let ([t, b, ns], [tc, bc, nc]) = (fr.base, fr.coat);
        let base_world = |l: Vec3| to_world(l, t, b, ns);
        let (wi, lobe) = if uc < pc {
            let ci = reflect(fr.co, ggx_sample_h(u, self.coat_alpha));
            (to_world(ci, tc, bc, nc), Lobe::Glossy)
        } else if uc < pc + ps {
            (base_world(cosine_hemisphere(u)), Lobe::Diffuse)
        } else if uc < pc + ps + pg {
            (base_world(reflect(fr.lo, aniso_ggx_sample_h(u, self.alpha))), Lobe::Glossy)
        } else {
            (base_world(cosine_hemisphere(u)), Lobe::Diffuse)
        };
        let (li, ci) = fr.local(wi);
        if li.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf_local(p, fr.lo, li, fr.co, ci);
        if !(pdf > 0.0) {
            return None;
        }
        let weight = self.f_local(fr.lo, li, fr.co, ci) * (li.z / pdf);
        Some(BsdfSample { wi, weight, pdf, specular: false, transmitted: false, lobe, eta: 1.0 })
    }

    /// Directional albedo toward `wo` under evenly arriving light, per channel:
    /// c E_c + S_c [sheen E_s + S_s tint L] + rho P(mu_o) for a dielectric, the
    /// metal's F0 for L (as [`crate::Bsdf::Conductor`]'s). Exact for the diffuse
    /// base; each glossy lobe's share is its directional albedo at wo, a little
    /// above what it keeps under the layers above it.
    pub fn albedo(&self, wo: Vec3, n: Vec3) -> Rgb {
        let Some(fr) = self.frames(wo, n) else { return Rgb::ZERO };
        let (mu, mu_c) = (fr.lo.z.clamp(0.0, 1.0), fr.co.z.clamp(0.0, 1.0));
        let coat = self.coat * albedo::layer_albedo(COAT_F0, mu_c, self.coat_alpha);
        let e_s = albedo::sheen_albedo(mu, self.sheen_alpha);
        let spec = if self.metal { self.lobe_f0(1.0) } else { self.spec_albedo(mu) };
        let glossy = Rgb::splat(coat) + (self.sheen * e_s + spec * self.sheen_leaves(mu)) * self.coat_leaves(mu);
        glossy + self.diffuse_albedo_at(mu)
    }

    /// The diffuse base's share of [`Self::albedo`] toward `wo`: rho P(mu_o)
    /// (zero for a metal).
    pub fn diffuse_albedo(&self, wo: Vec3, n: Vec3) -> Rgb {
        let Some(fr) = self.frames(wo, n) else { return Rgb::ZERO };
        self.diffuse_albedo_at(fr.lo.z.clamp(0.0, 1.0))
    }

    /// rho P(mu) at the base's cosine `mu` (zero for a metal).
    fn diffuse_albedo_at(&self, mu: f32) -> Rgb {
        if self.metal { Rgb::ZERO } else { self.rho * self.leaves(mu) }
    }

    /// The sharpest GGX alpha among the lobes that reflect toward a direction
    /// (the coat's and the base's, the latter the smaller of its two).
    pub fn sharpest_alpha(&self) -> f32 {
        let base = self.alpha_iso();
        if self.coat > 0.0 { base.min(self.coat_alpha) } else { base }
    }
}

/// Anisotropic GGX D(h) [sr^-1] (Heitz 2014, "Understanding the masking-shadowing
/// function", eq. 85): 1 / (pi a_x a_y (h_x^2 / a_x^2 + h_y^2 / a_y^2 + h_z^2)^2).
fn aniso_ggx_d(h: Vec3, a: Vec2) -> f32 {
    if a.x == a.y {
        return ggx_d(h.z, a.x);
    }
    let s = h.x * h.x / (a.x * a.x) + h.y * h.y / (a.y * a.y) + h.z * h.z;
    1.0 / (PI * a.x * a.y * s * s)
}

/// Smith G1 for anisotropic GGX: 1 / (1 + Lambda), Lambda = (sqrt(1 + (a_x^2 v_x^2
/// + a_y^2 v_y^2) / v_z^2) - 1) / 2 (Heitz 2014, eq. 86).
fn aniso_ggx_g1(v: Vec3, a: Vec2) -> f32 {
    let t2 = (a.x * a.x * v.x * v.x + a.y * a.y * v.y * v.y) / (v.z * v.z);
    2.0 / (1.0 + (1.0 + t2).sqrt())
}

/// Anisotropic GGX reflection without its Fresnel, D G / (4 cos_o cos_i), and the
/// cosine lo.h at which the Fresnel is taken; None when no half vector lies above
/// the surface. Isotropic alphas take [`crate::ggx_f`]'s terms.
fn aniso_ggx_dg(lo: Vec3, li: Vec3, a: Vec2) -> Option<(f32, f32)> {
    let h = (lo + li).normalize_or_zero();
    if h == Vec3::ZERO || lo.z <= 0.0 || li.z <= 0.0 {
        return None;
    }
    let (d, g) = if a.x == a.y {
        (ggx_d(h.z, a.x), ggx_g1(lo.z, a.x) * ggx_g1(li.z, a.x))
    } else {
        (aniso_ggx_d(h, a), aniso_ggx_g1(lo, a) * aniso_ggx_g1(li, a))
    };
    Some((d * g / (4.0 * lo.z * li.z), lo.dot(h)))
}

/// A half vector drawn from D(h) cos(theta_h): an isotropic slope of alpha 1
/// stretched by (a_x, a_y) (Heitz 2014, section 5.2: anisotropic GGX is the
/// isotropic one in stretched slope space).
fn aniso_ggx_sample_h(u: Vec2, a: Vec2) -> Vec3 {
    if a.x == a.y {
        return ggx_sample_h(u, a.x);
    }
    let ux = u.x.min(1.0 - 1e-7);
    let r = (ux / (1.0 - ux)).sqrt();
    let phi = TAU * u.y;
    Vec3::new(a.x * r * phi.cos(), a.y * r * phi.sin(), 1.0).normalize()
}

/// Solid-angle pdf of `li` under [`aniso_ggx_sample_h`]: D(h) cos_h / (4 lo.h).
fn aniso_ggx_pdf(lo: Vec3, li: Vec3, a: Vec2) -> f32 {
    if a.x == a.y {
        return ggx_pdf(lo, li, a.x);
    }
    let h = (lo + li).normalize_or_zero();
    let lh = lo.dot(h);
    if h.z <= 0.0 || lh <= 0.0 {
        return 0.0;
    }
    aniso_ggx_d(h, a) * h.z / (4.0 * lh)
}

/// The Charlie sheen distribution D(h) = (2 + 1/alpha) sin(theta_h)^(1/alpha) /
/// (2 pi) [sr^-1] (Estevez and Kulla 2017; KHR_materials_sheen).
fn charlie_d(cos_h: f32, alpha: f32) -> f32 {
    let inv = 1.0 / alpha;
    let sin2 = (1.0 - cos_h * cos_h).max(0.0);
    (2.0 + inv) * sin2.powf(0.5 * inv) / TAU
}

/// Estevez and Kulla's fitted exponent L(x) of the sheen's Lambda, its five
/// coefficients interpolated between alpha 0 and 1 by (1 - alpha)^2
/// (KHR_materials_sheen, "Sheen visibility").
fn charlie_l(x: f32, alpha: f32) -> f32 {
    let t = (1.0 - alpha) * (1.0 - alpha);
    let mix = |a0: f32, a1: f32| a0 + (a1 - a0) * t;
    let (a, b, c) = (mix(21.5473, 25.3245), mix(3.82987, 3.32435), mix(0.19823, 0.16801));
    let (d, e) = (mix(-1.97760, -1.27393), mix(-4.32054, -4.85967));
    a / (1.0 + b * x.powf(c)) + d * x + e
}

/// The sheen's Lambda(cos theta), symmetric about cos 0.5 as the fit prescribes.
fn charlie_lambda(cos: f32, alpha: f32) -> f32 {
    if cos < 0.5 {
        charlie_l(cos, alpha).exp()
    } else {
        (2.0 * charlie_l(0.5, alpha) - charlie_l(1.0 - cos, alpha)).exp()
    }
}

/// The sheen lobe of white sheen colour: D V with V = 1 / ((1 + Lambda(cos_o) +
/// Lambda(cos_i)) 4 cos_o cos_i) [sr^-1].
pub(crate) fn charlie_f(lo: Vec3, li: Vec3, alpha: f32) -> f32 {
    let h = (lo + li).normalize_or_zero();
    if h == Vec3::ZERO || lo.z <= 0.0 || li.z <= 0.0 {
        return 0.0;
    }
    let v = 1.0 / ((1.0 + charlie_lambda(lo.z, alpha) + charlie_lambda(li.z, alpha)) * 4.0 * lo.z * li.z);
    charlie_d(h.z, alpha) * v
}
