//! Light in participating media: what arrives along a ray through a medium
//! straight from the lights (single scattering), by equiangular sampling toward
//! point, spot and area lights (Kulla and Fajardo 2012) and exponential sampling
//! for lights at infinity; shadow rays attenuated by the media they cross.

use crate::DirectLighting;
use glam::Vec3;
use pm_color::Rgb;
use pm_sampling::Sampler;
use pm_scene::{LightKind, MediumId};

impl DirectLighting<'_> {
    /// Radiance [W sr^-1 m^-2 per channel] arriving at `o` along the ray from `o` in
    /// unit direction `d`, scattered once toward `o` inside medium `medium` over the
    /// segment (0, `t_max`) [m] (infinite: to the scene medium's end) from light that
    /// came straight from a light: the integral of T(o, x) sigma_s p(-d, wi) L_i(x,
    /// wi) T(x, light) over the segment's points x and directions wi (Jensen and
    /// Christensen 1998's single-scattering term), by `n` samples. Each picks a
    /// light by power, then a distance equiangular about the light's position,
    /// which cancels the 1 / r^2 that makes uniform or exponential distances noisy
    /// near the light, and a light sample from there with its shadow ray. An area
    /// light's point is picked first and the distance is equiangular about it
    /// (Kulla and Fajardo 2012 section 4.2; equiangular about the light's centre
    /// left a large ceiling light's fog noisy). Lights at infinity take distances
    /// exponential in the mean extinction. Zero in a medium that does not scatter.
    pub fn single_scattering(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        medium: Option<MediumId>,
        s: &mut Sampler,
        n: u32,
    ) -> Rgb {
        let scene = self.scene;
        let Some(m) = scene.medium(medium).filter(|m| m.scatters()) else { return Rgb::ZERO };
        let t_max = if t_max.is_finite() { t_max } else { scene.escape_distance(o, d) };
        if !(t_max > 0.0) {
            return Rgb::ZERO;
        }
        let mut sum = Rgb::ZERO;
        for _ in 0..n {
            let (li, p_sel) = self.lights.pick(s.next_1d());
            let (ut, u_tri, u) = (s.next_1d(), s.next_1d(), s.next_2d());
            let light = &scene.lights[li];
            let area = match light.kind {
                LightKind::Area { .. } => match light.pick_point(scene, u_tri, u) {
                    Some(q) => Some(q),
                    None => continue,
                },
                _ => None,
            };
            let centre = area.as_ref().map(|q| q.p);
            let Some((t, pdf_t)) = self.scatter_distance(li, centre, (o, d, t_max), m.sigma_t(), ut) else { continue };
            let x = o + d * t;
            let ls = match &area {
                Some(q) => light.sample_from(q, x),
                None => light.sample_li(scene, x, Vec3::ZERO, u_tri, u),
            };
            let Some(ls) = ls else { continue };
            let f = m.phase.p(-d, ls.wi);
            let p_l = ls.pdf * p_sel as f32 * pdf_t;
            if !(f > 0.0 && p_l > 0.0) {
                continue;
            }
            let tr = crate::direct::ShadowRay::new(x, x, &ls).transmittance(scene, medium);
            sum += m.transmittance(t) * m.sigma_s * ls.li * tr * (f / p_l);
        }
        sum / n.max(1) as f32
    }

    /// Where along the segment (0, t_max) of the ray from `o` in direction `d` to
    /// scatter for light `li`, and the density [m^-1]: equiangular about the
    /// light's position (about `picked`, the point already picked on an area
    /// light), or exponential in the mean of `sigma_t` (truncated to the segment)
    /// for lights at infinity and points on the ray's line.
    fn scatter_distance(
        &self,
        li: usize,
        picked: Option<Vec3>,
        (o, d, t_max): (Vec3, Vec3, f32),
        sigma_t: Rgb,
        u: f32,
    ) -> Option<(f32, f32)> {
        let scene = self.scene;
        let centre = match &scene.lights[li].kind {
            LightKind::Point { position, .. } | LightKind::Spot { position, .. } => Some(*position),
            LightKind::Area { .. } => picked,
            _ => None,
        };
        if let Some(c) = centre {
            let t_foot = (c - o).dot(d);
            let h = (c - o - d * t_foot).length();
            if h > 1e-6 * scene.bounds.diagonal() {
                return pm_sampling::equiangular(u, h, t_foot, 0.0, t_max);
            }
        }
        let sigma = pm_color::mean(sigma_t);
        if !(sigma > 0.0) {
            return Some((u * t_max, 1.0 / t_max));
        }
        // Truncated exponential: t = -ln(1 - u (1 - e^(-sigma t_max))) / sigma.
        let keep = -(-sigma * t_max).exp_m1();
        let t = (-(-u * keep).ln_1p() / sigma).min(t_max);
        Some((t, sigma * (-sigma * t).exp() / keep))
    }
}
