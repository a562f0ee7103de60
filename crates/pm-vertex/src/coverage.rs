//! How much of a corner estimate's disc lies on the surface, so the estimate can be
//! divided by that part of the disc rather than all of it.
//!
//! A k-nearest estimate divides the photons' power by pi r^2, the area of the whole
//! disc (Jensen 1996, eq. 6). At a corner on the edge of a surface (a wall meeting
//! the floor, the floor around a box standing on it) photons lie on only part of
//! the disc, so the estimate reads half (an edge) or a quarter (a corner) of the
//! light there, and Gouraud interpolation spreads that over every triangle that
//! touches the edge: on cornell_boxes the vertex method's indirect light was 10%
//! dark in mean, 40-60% in the blocks along the walls' edges and around the boxes'
//! bases (issue 36). It is the boundary bias of kernel density estimation
//! (Silverman 1986, section 2.10); the batch pipeline's final gather hides it, the
//! vertex method shows it directly.
//!
//! The part covered is probed with rays in the photon scene
//! ([`pm_render::disc_coverage`], which image-space photon volumes share). The
//! fractions are cached per corner and radius step (a quarter octave), so a still
//! scene probes each corner a few times, not every frame.

use crate::Corners;
use glam::Vec3;
use pm_color::Rgb;
use pm_scene::Scene;
use rayon::prelude::*;

/// Radius steps per octave of the cache.
const STEPS_PER_OCTAVE: f32 = 4.0;

/// The least fraction divided by: a corner whose disc is almost all off the
/// surface gains at most this much (a corner of a thin sliver, a probe lost).
pub const MIN_COVERAGE: f32 = pm_render::MIN_COVERAGE;

/// The fraction (0 to 1) of the disc of radius `r` \[m\] about corner `p` (unit
/// normal `n`) in its tangent plane that lies on surfaces of `scene` facing `n`'s
/// way and in view of the corner: [`pm_render::disc_coverage`] with every part of
/// the disc weighted alike (the estimate's disc kernel).
pub fn coverage(scene: &Scene, p: Vec3, n: Vec3, r: f32) -> f32 {
    pm_render::disc_coverage(scene, p, n, r, pm_render::Probe::InView, |_| 1.0)
}

/// Corner coverages already probed: per corner, the radius step and the fraction.
#[derive(Clone, Debug, Default)]
pub struct CoverageCache {
    probed: Vec<Option<(i32, f32)>>,
}

impl CoverageCache {
    /// Forget every fraction (the scene's meshes moved).
    pub fn clear(&mut self) {
        self.probed.clear();
    }

    /// Divide each active corner's irradiance `e` by the coverage (at least
    /// [`MIN_COVERAGE`]) of its estimate's disc, whose squared radius is `r2`
    /// \[m^2\]; corners without photons (r2 = 0) stay as they are.
    pub fn correct(&mut self, scene: &Scene, corners: &Corners, active: &[bool], e: &mut [Rgb], r2: &[f32]) {
        self.probed.resize(corners.len(), None);
        let step = |c: usize| (STEPS_PER_OCTAVE * 0.5 * r2[c].log2()).round() as i32;
        let wanted = |c: usize| active[c] && r2[c] > 0.0 && r2[c].is_finite();
        let todo: Vec<usize> =
            (0..corners.len()).filter(|&c| wanted(c) && self.probed[c].is_none_or(|(s, _)| s != step(c))).collect();
        let fresh: Vec<f32> = todo
            .par_iter()
            .with_min_len(16)
            .map(|&c| coverage(scene, corners.p[c], corners.n[c], (step(c) as f32 / STEPS_PER_OCTAVE).exp2()))
            .collect();
        for (&c, f) in todo.iter().zip(fresh) {
            self.probed[c] = Some((step(c), f));
        }
        for c in (0..corners.len()).filter(|&c| wanted(c)) {
            if let Some((_, f)) = self.probed[c] {
                e[c] /= f.max(MIN_COVERAGE);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pm_scene::{Material, Triangle};

    /// A unit square floor (y = 0, facing up) and a wall at x = 0.3 standing on it.
    fn floor_and_wall() -> Scene {
        let v = |x, y, z| Vec3::new(x, y, z);
        let quad = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| {
            [Triangle::new([a, b, c], 0).unwrap(), Triangle::new([a, c, d], 0).unwrap()]
        };
        let mut tris = Vec::new();
        tris.extend(quad(v(0.0, 0.0, 0.0), v(0.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, 0.0)));
        tris.extend(quad(v(0.3, 0.0, 0.0), v(0.3, 1.0, 0.0), v(0.3, 1.0, 1.0), v(0.3, 0.0, 1.0)));
        let grey = Material::new("grey", pm_bsdf::Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::ZERO);
        Scene::from_parts(tris, vec![grey], Vec::new(), None)
    }

    /// Against the disc's area on the floor, computed by hand: all of it in the open,
    /// half at the floor's open edge, a quarter at the floor's corner, and with the
    /// wall a chord at half the radius away on either side, 1 - (acos(1/2) -
    /// sqrt(3)/4) / pi = 0.804 (within the 32 samples' resolution). (A corner
    /// exactly at the wall's foot sees the floor on both sides: its probes start in
    /// the wall's plane.)
    #[test]
    fn coverage_is_the_part_of_the_disc_on_the_surface() {
        let s = floor_and_wall();
        let up = Vec3::Y;
        let cases = [
            (Vec3::new(0.65, 0.0, 0.5), 1.0, 0.0),
            (Vec3::new(1.0, 0.0, 0.5), 0.5, 0.0),
            (Vec3::new(1.0, 0.0, 1.0), 0.25, 0.0),
            (Vec3::new(0.2, 0.0, 0.5), 1.0 - ((0.5f32).acos() - 3f32.sqrt() / 4.0) / std::f32::consts::PI, 0.04),
            (Vec3::new(0.4, 0.0, 0.5), 1.0 - ((0.5f32).acos() - 3f32.sqrt() / 4.0) / std::f32::consts::PI, 0.04),
        ];
        for (p, want, tol) in cases {
            let got = coverage(&s, p, up, 0.2);
            assert!((got - want).abs() <= tol + 1e-6, "at {p}: {got} against {want}");
        }
    }
}
