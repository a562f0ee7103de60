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
//! ([`pm_render::disc_coverage`], which image-space photon volumes share), with
//! the tests the estimate makes of its photons: the same surface within the
//! corner's half gaps, under a cover as the corner is. The estimate finds photons
//! by distance, so where part of the disc is out of the corner's view (the floor
//! beyond a box standing on it, or under a glass one) the corner counts only the
//! photons in view and divides by the part in view ([`Share`]). The fractions
//! are cached per corner and radius step (a quarter octave), so a still scene
//! probes each corner a few times, not every frame.

use crate::{Around, Corners};
use glam::Vec3;
use pm_scene::Scene;
use rayon::prelude::*;

/// Radius steps per octave of the cache.
const STEPS_PER_OCTAVE: f32 = 4.0;

pub use pm_render::MIN_COVERAGE;

/// How much of a corner's disc its estimate counts: all of it that holds the
/// photons the estimate finds, and the part of that in view of the corner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Share {
    /// The fraction (0 to 1) of the disc whose photons the estimate counts.
    pub all: f32,
    /// The fraction of the disc in view of the corner at [`Share::lift`] too.
    pub seen: f32,
    /// The height \[m\] over the corner's plane at which a photon must be in
    /// view of it ([`pm_render::in_view`]).
    pub lift: f32,
}

impl Share {
    /// True when part of the disc holds photons the corner does not see (the
    /// floor beyond a box standing on it, or under a glass one): then its
    /// estimate counts only the photons in view ([`crate::Corners::irradiance`])
    /// and is divided by [`Share::seen`]. One probe of the 32 is noise.
    pub fn hidden(&self) -> bool {
        self.seen < self.all - 1.5 / 32.0
    }

    /// What the estimate is divided by: the share it counts, at least
    /// [`MIN_COVERAGE`].
    pub fn divisor(&self) -> f32 {
        if self.hidden() { self.seen } else { self.all }.max(MIN_COVERAGE)
    }
}

/// The [`Share`] of the disc of radius `r` \[m\] about corner `p` (unit normal
/// `n`) in its tangent plane: [`pm_render::disc_coverage`] with every part of
/// the disc weighted alike (the estimate's disc kernel), probed within the
/// corner's half gaps and under a cover (closer than `cover` \[m\]) as the corner
/// is, where its surroundings are known (`around`), else within `r` of the
/// disc's plane (and all of it counted as seen).
pub fn coverage(scene: &Scene, p: Vec3, n: Vec3, r: f32, around: Option<Around>, cover: f32) -> Share {
    let Some(a) = around else {
        let probe = pm_render::Probe::Estimate { below: r, above: r, cover: None, view: None };
        let all = pm_render::disc_coverage(scene, p, n, r, probe, |_| 1.0);
        return Share { all, seen: all, lift: 0.0 };
    };
    let (below, above) = (0.5 * a.gaps.behind, 0.5 * a.gaps.front);
    let lift = (0.25 * r).min(above);
    let probe = |view| pm_render::Probe::Estimate { below, above, cover: Some((cover, a.covered)), view };
    let n = a.gaps.normal;
    Share {
        all: pm_render::disc_coverage(scene, p, n, r, probe(None), |_| 1.0),
        seen: pm_render::disc_coverage(scene, p, n, r, probe(Some(lift)), |_| 1.0),
        lift,
    }
}

/// Corner shares already probed: per corner, the radius step and the share.
#[derive(Clone, Debug, Default)]
pub struct CoverageCache {
    probed: Vec<Option<(i32, Share)>>,
}

impl CoverageCache {
    /// Forget every share (the scene's meshes moved).
    pub fn clear(&mut self) {
        self.probed.clear();
    }

    /// Each active corner's [`Share`] of its estimate's disc, whose squared
    /// radius is `r2` \[m^2\] (probed at the radius rounded to a quarter
    /// octave), with the corners' surroundings and the cover distance \[m\]
    /// their estimates kept to (`around`, `cover`); `None` for corners without
    /// photons (r2 = 0) or not active.
    pub fn shares(
        &mut self,
        scene: &Scene,
        corners: &Corners,
        active: &[bool],
        (around, cover): (&[Option<Around>], f32),
        r2: &[f32],
    ) -> Vec<Option<Share>> {
        self.probed.resize(corners.len(), None);
        let step = |c: usize| (STEPS_PER_OCTAVE * 0.5 * r2[c].log2()).round() as i32;
        let wanted = |c: usize| active[c] && r2[c] > 0.0 && r2[c].is_finite();
        let todo: Vec<usize> =
            (0..corners.len()).filter(|&c| wanted(c) && self.probed[c].is_none_or(|(s, _)| s != step(c))).collect();
        let fresh: Vec<Share> = todo
            .par_iter()
            .with_min_len(16)
            .map(|&c| {
                let r = (step(c) as f32 / STEPS_PER_OCTAVE).exp2();
                coverage(scene, corners.p[c], corners.n[c], r, around.get(c).copied().flatten(), cover)
            })
            .collect();
        for (&c, f) in todo.iter().zip(fresh) {
            self.probed[c] = Some((step(c), f));
        }
        (0..corners.len()).map(|c| self.probed[c].filter(|_| wanted(c)).map(|(_, f)| f)).collect()
    }
}
