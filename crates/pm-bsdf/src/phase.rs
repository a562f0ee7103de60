//! Scattering inside a medium: the Henyey-Greenstein phase function (Henyey and
//! Greenstein 1941; pbrt-v4 section 11.3.1), the one KHR_materials_volume_scatter
//! names for `scatterAnisotropy`.
//!
//! Conventions as for BSDFs: `wo` and `wi` are unit vectors pointing away from the
//! scattering point (`wo` toward where the light goes, `wi` toward where it came
//! from), so forward scattering (g > 0) favours wi = -wo. The phase function p is a
//! density over the sphere of directions [sr^-1] that integrates to one.

use glam::{Vec2, Vec3};
use pm_sampling::to_world;
use std::f32::consts::{PI, TAU};

/// The Henyey-Greenstein phase function with asymmetry g in (-1, 1): the mean
/// cosine of the scattering angle (0 isotropic, > 0 forward, < 0 backward).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HenyeyGreenstein {
    /// Asymmetry parameter g in (-1, 1).
    pub g: f32,
}

/// A direction sampled from a phase function.
#[derive(Clone, Copy, Debug)]
pub struct PhaseSample {
    /// Unit direction toward where the light came from.
    pub wi: Vec3,
    /// Its density [sr^-1], equal to the phase function's value (the sample's weight
    /// p / pdf is one).
    pub pdf: f32,
}

impl HenyeyGreenstein {
    /// Isotropic scattering: p = 1 / (4 pi) everywhere.
    pub const ISOTROPIC: HenyeyGreenstein = HenyeyGreenstein { g: 0.0 };

    /// The phase function's value [sr^-1] for the pair of directions: (1 - g^2) /
    /// (4 pi (1 + g^2 + 2 g cos)^(3/2)), cos = wo . wi (both point away, so cos = -1
    /// is straight on).
    #[inline]
    pub fn p(&self, wo: Vec3, wi: Vec3) -> f32 {
        hg(wo.dot(wi), self.g)
    }

    /// Sample `wi` with density p(wo, wi) by inverting the cumulative distribution of
    /// the scattering angle (pbrt-v4 section 11.3.1); `u` uniform in [0, 1)^2.
    pub fn sample(&self, wo: Vec3, u: Vec2) -> PhaseSample {
        let g = self.g;
        // cos_t = wo . wi, the cosine of wi about the axis wo (-1 straight on).
        let cos_t = if g.abs() < 1e-3 {
            1.0 - 2.0 * u.x
        } else {
            let s = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
            -(1.0 + g * g - s * s) / (2.0 * g)
        }
        .clamp(-1.0, 1.0);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = TAU * u.y;
        let wi = to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t), wo);
        PhaseSample { wi, pdf: hg(cos_t, g) }
    }
}

/// Henyey-Greenstein's density [sr^-1] at cos = wo . wi (both directions pointing
/// away from the scattering point).
#[inline]
fn hg(cos: f32, g: f32) -> f32 {
    let denom = 1.0 + g * g + 2.0 * g * cos;
    (1.0 - g * g) / (4.0 * PI * denom * denom.max(1e-12).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use pm_sampling::{Sampler, uniform_sphere};

    /// The phase function integrates to one over the sphere, its mean cosine of the
    /// scattering angle (between -wo and wi) is g, and sampling draws directions
    /// with the density it reports (the sampled mean of f(wi) equals f's uniform
    /// quadrature times p).
    #[test]
    fn henyey_greenstein_is_a_density_with_mean_cosine_g() {
        let wo = Vec3::new(0.3, -0.5, 0.8).normalize();
        for g in [-0.9, -0.3, 0.0, 0.5, 0.95] {
            let hg = HenyeyGreenstein { g };
            let n = 400_000;
            let (mut total, mut mean_cos) = (0.0f64, 0.0f64);
            for i in 0..n {
                let mut s = Sampler::new(3, i);
                let wi = uniform_sphere(s.next_2d());
                let p = hg.p(wo, wi) as f64 * 4.0 * std::f64::consts::PI;
                total += p;
                mean_cos += p * (-wo.dot(wi)) as f64;
            }
            let (total, mean_cos) = (total / n as f64, mean_cos / n as f64);
            // Uniform quadrature of a peaked lobe converges slowly: g = 0.95 is the hard one.
            let tol = if g > 0.9 { 0.03 } else { 0.005 };
            assert!((total - 1.0).abs() < tol, "g {g}: integral {total}");
            assert!((mean_cos - g as f64).abs() < tol, "g {g}: mean cosine {mean_cos}");
            let (mut sampled_cos, mut ratio_err) = (0.0f64, 0.0f32);
            for i in 0..n {
                let mut s = Sampler::new(4, i);
                let ps = hg.sample(wo, s.next_2d());
                assert!((ps.wi.length() - 1.0).abs() < 1e-4);
                ratio_err = ratio_err.max((ps.pdf / hg.p(wo, ps.wi) - 1.0).abs());
                sampled_cos += (-wo.dot(ps.wi)) as f64;
            }
            assert!(ratio_err < 1e-3, "g {g}: pdf differs from p by {ratio_err}");
            let sampled_cos = sampled_cos / n as f64;
            assert!((sampled_cos - g as f64).abs() < 0.005, "g {g}: sampled mean cosine {sampled_cos}");
        }
    }
}
