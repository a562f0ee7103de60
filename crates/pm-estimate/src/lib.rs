//! Photon density estimates, in one place: irradiance from the k nearest photons
//! (Jensen 1996; Christensen 1999 section 1.3, item 1) with optional cone or
//! Gaussian filtering, and the lookup of a precomputed irradiance at the nearest
//! photon with a similar normal (Christensen 1999 section 2.2), and radiance in
//! participating media from a volume map: in-scattered radiance from the k nearest
//! photons and its ray march along a ray (Jensen and Christensen 1998), and the
//! beam radiance estimate (Jarosz, Zwicker and Jensen 2008).
//!
//! Every estimate counts only photons on the query's side of the surface, so light
//! does not leak through thin walls or around corners: with a surface normal in the
//! record (global maps) the photon's normal must agree with the query normal; without
//! one (caustic maps) the photon must have arrived from the query's front side.
//!
//! No I/O and no allocation per call (the caller owns the scratch).

mod precompute;
mod volume;

pub use precompute::{PrecomputeStats, precompute, selected};
pub use volume::{
    Beams, Inscattering, MIN_INSIDE, Segment, Steps, beam, beam_radii, beam_spheres, counted, inscattered,
    precomputed_march, ray_march,
};

use glam::Vec3;
use pm_color::Rgb;
use pm_format::{PhotonRecord, flags};
use pm_kdtree::{KdTree, KnnScratch, Nearest, Neighbours};
use std::f32::consts::PI;

/// A photon with a stored normal counts for a query when the normals' cosine exceeds
/// this: the same surface, or a gently curved continuation of it (60 degrees), but
/// not a wall meeting it at a corner nor the back of a thin wall.
pub const SAME_SURFACE_COS: f32 = 0.5;
/// Christensen 1999 section 2.2: a precomputed irradiance is used when the photon's
/// normal has a dot product above 0.9 with the query normal.
pub const SIMILAR_NORMAL_COS: f32 = 0.9;
/// Photons without a stored normal count when their incident direction is above the
/// surface, allowing for the 1-byte direction's error (0.30 rad, so sin = 0.3).
pub const FRONT_TOLERANCE: f32 = -0.3;

pm_params::value_enum! {
    /// The density-estimation kernel a user picks (see [`Filter`]).
    pub enum FilterKind {
        /// Constant kernel (the paper's estimate).
        None,
        /// Jensen's cone filter, k = 1.1.
        Cone,
        /// Jensen's Gaussian filter (renormalised).
        Gaussian,
    }
}

impl FilterKind {
    /// The kernel.
    pub fn filter(self) -> Filter {
        match self {
            FilterKind::None => Filter::None,
            FilterKind::Cone => Filter::Cone { k: 1.1 },
            FilterKind::Gaussian => Filter::Gaussian,
        }
    }
}

pm_params::params! {
    /// Stage 3's parameters, defined once: `photon-irradiance`'s options and the
    /// `[irradiance]` section of pipeline.toml (Christensen 1999 section 2.1).
    pub struct IrradianceParams {
        /// Fraction of photons that get an irradiance (the paper: 1 or 1/4): one in every
        /// 1/fraction consecutive kd-tree positions, a stratified subset that keeps the
        /// photon density's shape.
        fraction: f64 = 0.25 => pm_params::above_up_to(0.0, 1.0);
        /// With a fraction below 1, the other photons get an irradiance too where
        /// the precomputed photons the final gather could read for them differ by
        /// more than this factor (the light changes fast there: a shadow's edge);
        /// 0 turns it off. The gather reads the nearest precomputed photon, and
        /// the subset's cells, larger where photons are sparse, carry the bright
        /// side of an edge into the dark one: on four generated rooms the indirect
        /// light was +2.7% to +4.3% off the path tracer's, and with 1.5 (4% more
        /// estimates) +1.7% to +3.1% (BENCHMARKS.md, issue 53).
        refine_ratio: f32 = 1.5 => pm_params::at_least(0.0);
        /// Photons per estimate (the paper: 50).
        k: usize = 50 => pm_params::between(1, 1 << 16);
        /// Largest search radius, as a fraction of the scene's bounding-box diagonal
        /// (recorded in the photon-map header; the same reference as stage 4's).
        max_radius_rel_diag: f32 = 0.1 => pm_params::above(0.0);
        /// Density-estimation filter.
        filter: FilterKind = FilterKind::None => pm_params::Any;
    }
}

/// Density-estimation kernel (Jensen 2001, "Realistic Image Synthesis Using Photon
/// Mapping", section 7.2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    /// Constant kernel: E = sum(Phi) / (pi r^2).
    None,
    /// Cone filter w = 1 - d / (k r), normalised by 1 - 2 / (3 k); k >= 1.
    Cone {
        /// Filter constant k (1 gives the sharpest cone).
        k: f32,
    },
    /// Gaussian filter w = alpha (1 - (1 - e^{-beta d^2 / 2r^2}) / (1 - e^{-beta})),
    /// alpha = 0.918, beta = 1.953, renormalised to integrate to the disk's area.
    Gaussian,
}

impl Filter {
    /// Weight of a photon at squared distance `d2` in a disk of squared radius `r2`,
    /// divided by the kernel's normalisation.
    #[inline]
    fn weight(self, d2: f32, r2: f32) -> f32 {
        match self {
            Filter::None => 1.0,
            Filter::Cone { k } => (1.0 - (d2 / r2).sqrt() / k).max(0.0) / (1.0 - 2.0 / (3.0 * k)),
            Filter::Gaussian => {
                const ALPHA: f32 = 0.918;
                const BETA: f32 = 1.953;
                // Jensen's constants leave the kernel's integral over the disk at
                // 0.531 pi r^2; divide by it so E keeps its meaning (the integral of
                // alpha (1 - (1 - e^{-beta u/2}) / (1 - e^{-beta})) du over u in [0,1]).
                let norm = ALPHA * (1.0 - (1.0 - 2.0 / BETA * (1.0 - (-BETA / 2.0).exp())) / (1.0 - (-BETA).exp()));
                ALPHA * (1.0 - (1.0 - (-BETA * d2 / (2.0 * r2)).exp()) / (1.0 - (-BETA).exp())) / norm
            }
        }
    }
}

/// Parameters of a k-nearest estimate.
#[derive(Clone, Copy, Debug)]
pub struct KnnParams {
    /// Photons per estimate (the paper: 50; Jensen: 30-200).
    pub k: usize,
    /// Largest search radius, squared [m^2].
    pub max_d2: f32,
    /// Kernel.
    pub filter: Filter,
}

/// An irradiance estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Irradiance {
    /// Irradiance E [W m^-2 per channel].
    pub e: Rgb,
    /// Squared radius of the disk the photons were gathered from [m^2] (0 if none).
    pub r2: f32,
    /// Photons used.
    pub count: usize,
}

/// True when photon `r` counts for a query on a surface with unit normal `n`.
#[inline]
pub fn on_query_side<R: PhotonRecord>(r: &R, n: Vec3) -> bool {
    let np = r.normal();
    if np != Vec3::ZERO { np.dot(n) > SAME_SURFACE_COS } else { r.wi().dot(n) > FRONT_TOLERANCE }
}

/// Irradiance at `x` on a surface with unit normal `n` from the k nearest photons on
/// the query's side (Jensen 1996, eq. 6; Christensen 1999 section 1.3):
/// E ~ sum_p w_p Phi_p / (pi r^2), r the distance of the k-th photon.
///
/// The k-th photon only marks the radius and is not counted: the k - 1 photons
/// inside the disk over its area is the unbiased k-nearest density estimate for a
/// locally uniform (Poisson) photon density, where counting all k overestimates by
/// k/(k - 1) (+2% at k = 50). Evaluated at a photon's own position (the precompute)
/// a residual (k - 1)/(k - 2) remains for Poisson photons; photons emitted from a
/// stratified sequence are more regular than Poisson and come out slightly low
/// instead (the workspace tests measure both: +1.3% in the furnace, -1.0% on a
/// directly lit plane). Returns zero when no photon is found or all lie exactly at
/// `x` (r = 0).
pub fn irradiance<R: PhotonRecord>(
    tree: &impl Neighbours<R>,
    x: Vec3,
    n: Vec3,
    p: &KnnParams,
    scratch: &mut KnnScratch,
) -> Irradiance {
    let (e, r2, count) = gather(tree, x, n, p, scratch, |_| true, |_| Rgb::ONE);
    Irradiance { e, r2, count }
}

/// Where the nearest other surfaces lie around a query point, along its
/// surface's normal: what [`irradiance_on`] needs to keep their photons out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surroundings {
    /// Unit geometric normal of the query's surface, from the scene (a stored
    /// 1-byte normal is up to 17 degrees off).
    pub normal: Vec3,
    /// Distance to the nearest surface behind the query's (against `normal`) \[m\].
    pub behind: f32,
    /// Distance to the nearest surface in front of it (along `normal`) \[m\].
    pub front: f32,
}

/// From `(normal, behind, front)`, as `pm_scene::Scene::surface_gaps` finds them.
impl From<(Vec3, f32, f32)> for Surroundings {
    fn from((normal, behind, front): (Vec3, f32, f32)) -> Self {
        Surroundings { normal, behind, front }
    }
}

/// What an estimate asks of the scene around a query point on a surface
/// (pm-render's `SceneSurfaces` answers from a scene; this crate knows none).
pub trait SurfaceQuery: Sync {
    /// The surroundings of the surface through `x` (stored normal `n`, roughly):
    /// its exact normal and the gaps to the surfaces behind and in front of it,
    /// or none when no surface lies at `x`.
    fn surroundings(&self, x: Vec3, n: Vec3) -> Option<Surroundings>;
    /// Whether the point `off` from `x` in its tangent plane (unit normal `n`)
    /// lies on `x`'s surface or one that continues it within radius `r` \[m\]
    /// (a photon there would count in an estimate of that radius).
    fn continues(&self, x: Vec3, n: Vec3, off: Vec3, r: f32) -> bool;
    /// Whether another surface faces `x` (a surface point, unit normal `n`) from
    /// closer than the cover distance: the point lies in a gap under a cover
    /// ([`flags::COVERED`]).
    fn covered(&self, x: Vec3, n: Vec3) -> bool;
}

/// Points of the disc [`disc_share`] probes.
pub const DISC_PROBES: u32 = 12;
/// The smallest share of a disc an estimate divides by: a query point lies on its
/// surface, so its disc keeps about a quarter even at a box's corner, and a lower
/// count is the probes' noise.
pub const SHARE_FLOOR: f32 = 0.125;

/// The share of the disc of radius `r` \[m\] about `x` in its tangent plane
/// (unit normal `n`) that lies on `x`'s surface ([`SurfaceQuery::continues`]),
/// from [`DISC_PROBES`] points spread evenly over its area (a sunflower
/// pattern, turned by `turn` in [0, 1) of a revolution so that neighbouring
/// estimates do not probe alike), at least [`SHARE_FLOOR`]; with `cover`, only the
/// points covered so ([`SurfaceQuery::covered`]: an estimate that keeps covered and
/// open photons apart). Where a wall or an
/// edge cuts the disc, dividing its photons by pi r^2 undercounts their density:
/// a bias first order in r along every edge of a room, -2.3% of a closed room's
/// indirect light on the differential checker's scene 30 (seed 16654).
pub fn disc_share(q: &dyn SurfaceQuery, x: Vec3, n: Vec3, r: f32, turn: f32, cover: Option<bool>) -> f32 {
    let (t, b) = pm_sampling::basis(n);
    let golden = PI * (3.0 - 5f32.sqrt());
    let on = (0..DISC_PROBES)
        .filter(|&i| {
            let rho = r * ((i as f32 + 0.5) / DISC_PROBES as f32).sqrt();
            let phi = golden * i as f32 + 2.0 * PI * turn;
            let off = (t * phi.cos() + b * phi.sin()) * rho;
            q.continues(x, n, off, r) && cover.is_none_or(|c| q.covered(x + off, n) == c)
        })
        .count();
    (on as f32 / DISC_PROBES as f32).max(SHARE_FLOOR)
}

/// [`irradiance`] counting only photons nearer the query's tangent plane than
/// half the gap to the next surface behind or in front of it (`s`). A kd-tree
/// search reaches across gaps much narrower than its radius: the back of a light
/// 2.6 mm below the ceiling found the ceiling's photons there, on a parallel
/// surface with the same normal, brighter than the room by the light trapped in
/// the gap, and read +150% indirect light into every final gather that hit the
/// light (the differential checker's scenes, issue 53); the top of a box found the
/// floor's photons around it. On one smooth surface a neighbour's height over the
/// tangent plane is -|d|^2 / 2R, far inside the half gap (a sphere's back lies 2R
/// behind).
/// Of those, only photons covered as the query is (`covered`, [`flags::COVERED`]):
/// on the ceiling around a two-sided light 1.2 mm below it, estimates outside the
/// panel's footprint took in the bright photons of the gap above it. Also returns
/// whether the search met photons covered otherwise (then the disc's share on the
/// query's surface leaves out the other side: [`disc_share`]'s `cover`).
pub fn irradiance_on<R: PhotonRecord>(
    tree: &impl Neighbours<R>,
    x: Vec3,
    n: Vec3,
    s: &Surroundings,
    covered: bool,
    p: &KnnParams,
    scratch: &mut KnnScratch,
) -> (Irradiance, bool) {
    irradiance_on_seen(tree, x, n, s, covered, p, scratch, |_| true)
}

/// [`irradiance_on`] summing, of the photons it finds, only those `seen`
/// accepts; the disc keeps the radius of the k nearest. Divided by the share of
/// the disc where `seen` would accept a photon, it is the density over that
/// share: the vertex method's corners beside a glass box standing on the floor
/// count only the photons they see, not those on the floor under the box, lit
/// through it (issue 53's checker, seed 12902 scene 17).
#[allow(clippy::too_many_arguments)]
pub fn irradiance_on_seen<R: PhotonRecord>(
    tree: &impl Neighbours<R>,
    x: Vec3,
    n: Vec3,
    s: &Surroundings,
    covered: bool,
    p: &KnnParams,
    scratch: &mut KnnScratch,
    seen: impl Fn(&R) -> bool,
) -> (Irradiance, bool) {
    let (below, above) = (-0.5 * s.behind, 0.5 * s.front);
    let other_cover = std::cell::Cell::new(false);
    let between = |r: &R| {
        let h = s.normal.dot(r.position() - x);
        let alike = (r.flags() & flags::COVERED != 0) == covered;
        other_cover.set(other_cover.get() || !alike);
        h > below && h < above && alike
    };
    let weight = |r: &R| if seen(r) { Rgb::ONE } else { Rgb::ZERO };
    let (e, r2, count) = gather(tree, x, n, p, scratch, between, weight);
    (Irradiance { e, r2, count }, other_cover.get())
}

/// Irradiance [W m^-2] at surface point `x` (normal `n`, roughly) as the
/// precompute estimates it at a photon: with the scene (`scene`), by
/// [`irradiance_on`] (photons between the surfaces around `x`, covered as `x` is:
/// `covered`, asked once) divided by the share of its disc on `x`'s surface
/// ([`disc_share`], its probes turned by `turn` in [0, 1)); without, by
/// [`irradiance`]. What the final gather's exact lookup reads too: its plain
/// k-nearest estimate took the bright photons trapped above a lamp under the
/// ceiling into the ceiling beside it (+162% indirect light with `gather_lookup
/// = "exact"` on issue 53's checker's scene 35 of seed 12902).
#[allow(clippy::too_many_arguments)]
pub fn surface_irradiance<R: PhotonRecord>(
    tree: &impl Neighbours<R>,
    scene: Option<&dyn SurfaceQuery>,
    x: Vec3,
    n: Vec3,
    covered: impl FnOnce() -> bool,
    turn: f32,
    p: &KnnParams,
    scratch: &mut KnnScratch,
) -> Irradiance {
    match scene.and_then(|q| Some((q, q.surroundings(x, n)?))) {
        Some((q, s)) => {
            let under = covered();
            let (mut est, mixed) = irradiance_on(tree, x, n, &s, under, p, scratch);
            if est.count > 0 && est.r2 > 0.0 {
                est.e /= disc_share(q, x, s.normal, est.r2.sqrt(), turn, mixed.then_some(under));
            }
            est
        }
        None => irradiance(tree, x, n, p, scratch),
    }
}

/// sum_p weight(p) w_p Phi_p / (pi r^2) over the k nearest photons on the query's
/// side, leaving out the one that marks the radius; returns (sum, r^2, photons found).
fn gather<R: PhotonRecord>(
    tree: &impl Neighbours<R>,
    x: Vec3,
    n: Vec3,
    p: &KnnParams,
    scratch: &mut KnnScratch,
    keep: impl Fn(&R) -> bool,
    weight: impl Fn(&R) -> Rgb,
) -> (Rgb, f32, usize) {
    let res = tree.knn(x, p.k, p.max_d2, |_, r| on_query_side(r, n) && keep(r), scratch);
    if res.count == 0 || !(res.max_dist2 > 0.0) {
        return (Rgb::ZERO, res.max_dist2, res.count);
    }
    let r2 = res.max_dist2;
    let sum = sum_but_boundary(tree, scratch, |r, d2| weight(r) * r.power() * p.filter.weight(d2, r2));
    (sum / (PI * r2), r2, res.count)
}

/// The sum of `term(record, d2)` over the photons the last k-nearest query left in
/// `scratch` (d2 each one's squared distance [m^2]), leaving out the one that marks
/// the radius ([`boundary_photon`]): the estimates' density divides by that
/// radius, so the photon on it is not inside.
pub(crate) fn sum_but_boundary<R: PhotonRecord>(
    tree: &impl Neighbours<R>,
    scratch: &KnnScratch,
    term: impl Fn(&R, f32) -> Rgb,
) -> Rgb {
    let boundary = boundary_photon(tree, scratch);
    let mut sum = Rgb::ZERO;
    for (i, d2) in tree.found(scratch) {
        if Some(i) != boundary {
            sum += term(tree.record(i), d2);
        }
    }
    sum
}

/// The photon that defines the radius of the last k-nearest query (the farthest;
/// the lowest heap index among equals, so the choice is deterministic).
pub(crate) fn boundary_photon<R: PhotonRecord>(tree: &impl Neighbours<R>, scratch: &KnnScratch) -> Option<u32> {
    tree.found(scratch).max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0))).map(|(i, _)| i)
}

/// Outgoing radiance from a photon map at `x` for a BRDF evaluated per photon:
/// L ~ sum_p f_r(wo, wi_p) w_p Phi_p / (pi r^2) (Jensen 1996, eq. 6), with the
/// boundary photon not counted as in [`irradiance`]. `f_r` maps a photon's incident
/// direction to the BRDF value [sr^-1 per channel].
pub fn radiance<R: PhotonRecord>(
    tree: &impl Neighbours<R>,
    x: Vec3,
    n: Vec3,
    p: &KnnParams,
    scratch: &mut KnnScratch,
    f_r: impl Fn(Vec3) -> Rgb,
) -> Rgb {
    gather(tree, x, n, p, scratch, |_| true, |r| f_r(r.wi())).0
}

/// The precomputed irradiance of the nearest photon that carries one and whose
/// normal agrees with `n` (dot > 0.9), within squared radius `max_d2` (Christensen
/// 1999 section 2.2). `rejected` is scratch. Returns the irradiance [W m^-2] and the
/// search result (distance, rank).
pub fn precomputed_irradiance<R: PhotonRecord>(
    tree: &KdTree<R>,
    x: Vec3,
    n: Vec3,
    max_d2: f32,
    rejected: &mut Vec<f32>,
) -> Option<(Rgb, Nearest)> {
    precomputed_irradiance_where(tree, x, n, max_d2, rejected, || false, |_| true, 0)
}

/// [`precomputed_irradiance`] with an extra condition on the photon, asked only of
/// the nearest photon passing the cheap ones, then of the next nearest if it fails,
/// at most `max_refusals` times (the renderer passes a visibility test, so a photon
/// on the other side of a thin wall is not used). A photon under a cover
/// ([`flags::COVERED`]) serves only a query under one: `covered` says whether the
/// query is, asked once, and only when such a photon is met. Among the cheap
/// tests, so the gap's photons take none of the `max_refusals`: above a two-sided
/// lamp 0.4 mm under a ceiling, 60% of the photons lay in the gap, the 16 nearest
/// to the ceiling beside the lamp were all there, and 1.6% of the cache's gathers
/// missed and read no light: the whole room's indirect light -3% (issue 53's
/// checker, scene 35 of seed 12902).
#[allow(clippy::too_many_arguments)]
pub fn precomputed_irradiance_where<R: PhotonRecord>(
    tree: &KdTree<R>,
    x: Vec3,
    n: Vec3,
    max_d2: f32,
    rejected: &mut Vec<f32>,
    covered: impl Fn() -> bool,
    extra: impl FnMut(&R) -> bool,
    max_refusals: u32,
) -> Option<(Rgb, Nearest)> {
    let query_covered = std::cell::OnceCell::new();
    let hit = tree.nearest_where(
        x,
        max_d2,
        |r| {
            r.flags() & flags::HAS_IRRADIANCE != 0
                && r.normal().dot(n) > SIMILAR_NORMAL_COS
                && (r.flags() & flags::COVERED == 0 || *query_covered.get_or_init(&covered))
        },
        extra,
        max_refusals,
        rejected,
    )?;
    Some((tree.nodes()[hit.index as usize].irradiance(), hit))
}

#[cfg(test)]
mod tests;
