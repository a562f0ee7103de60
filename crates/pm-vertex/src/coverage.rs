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

pub use pm_render::MIN_COVERAGE;

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
