//! Irradiance precomputed at photon positions (Christensen 1999 section 2.1).

use crate::{Irradiance, KnnParams, SurfaceQuery};
use pm_format::{PhotonRecord, flags};
use pm_kdtree::{KdTree, KnnScratch};
use rayon::prelude::*;

/// Photons per parallel work item.
const CHUNK: usize = 2048;

/// True when the photon at heap index `index` of a kd-tree map is in the subset
/// that gets a precomputed irradiance: heap positions 0, 1/f, 2/f, ... (one in every
/// 1/`fraction` consecutive positions). Neighbouring heap positions are siblings and
/// cousins in the tree, so neighbours in space, and the stride takes one photon from
/// each small group: a stratified thinning that keeps the photon density's shape more
/// evenly than independent coin flips. Measured on the Cornell box at f = 1/4 (the
/// workspace test): chi-square per degree of freedom of the per-cell selected share
/// 0.23 for this phase, about 1.0 for coin flips. (Groups of four heap positions are
/// the four grandchildren of a node; the phases that pick an outer grandchild measure
/// 0.91, still no worse than coin flips.)
pub fn selected(index: usize, fraction: f64) -> bool {
    fraction >= 1.0 || (index as f64 * fraction).floor() > ((index as f64 - 1.0) * fraction).floor()
}

/// What a precompute did.
#[derive(Clone, Debug, Default)]
pub struct PrecomputeStats {
    /// Photons that received an irradiance.
    pub computed: u64,
    /// Of those, estimates that found no photon on their side (irradiance 0).
    pub empty: u64,
    /// Photons under a cover ([`flags::COVERED`]; none without the scene).
    pub covered: u64,
    /// Of the photons that received an irradiance, those outside the subset
    /// (where the subset's irradiance changes fast: `refine`).
    pub refined: u64,
    /// Radius of each estimate \[m\], sorted ascending.
    pub radii: Vec<f32>,
}

/// Precomputed neighbours a photon outside the subset compares
/// ([`precompute`]'s refinement).
const REFINE_NEIGHBOURS: usize = 4;

/// Estimate the irradiance at the selected photons of a kd-tree map (`nodes` in heap
/// order, with surface normals) and store it in them, flagging them
/// [`flags::HAS_IRRADIANCE`]. With the `scene`, each estimate leaves out the
/// photons of the surfaces next to the photon's ([`irradiance_on`]) and divides
/// by the area of its disc that lies on the photon's surface ([`disc_share`]),
/// not pi r^2, so that estimates at a room's edges and corners are not dark.
///
/// With `refine` above 1, then also at every other photon whose
/// [`REFINE_NEIGHBOURS`] nearest precomputed photons (those the final gather's
/// lookup could take for it: a similar normal, covered alike) differ in
/// luminance by more than that factor: the lookup reads the nearest one, so the
/// subset's cells, larger where photons are sparse, carried the bright side of a
/// shadow's edge into the dark side, +2.4% over a room lit by a lamp in a
/// corner (issue 53's checker, seed 60606 scene 27) that every photon's own
/// estimate brings to +0.7%. Refined where the light changes, at a quarter's
/// cost elsewhere. Parallel and deterministic. `progress` gets the number of
/// photons examined so far.
pub fn precompute<R: PhotonRecord>(
    nodes: &mut [R],
    p: &KnnParams,
    (fraction, refine): (f64, f32),
    scene: Option<&dyn SurfaceQuery>,
    progress: &(dyn Fn(u64) + Sync),
) -> PrecomputeStats {
    // Which photons lie under a cover, before any estimate reads the flags.
    let mut covered = 0;
    if let Some(q) = scene {
        nodes.par_iter_mut().for_each(|r| {
            let mut f = r.flags() & !flags::COVERED;
            if f & flags::UNUSED == 0 && q.covered(r.position(), r.normal()) {
                f |= flags::COVERED;
            }
            r.set_flags(f);
        });
        covered = nodes.iter().filter(|r| r.flags() & flags::COVERED != 0).count() as u64;
    }
    let buckets = pm_kdtree::Buckets::new(&*nodes);
    let tree = KdTree::with_buckets(&*nodes, &buckets);
    let used = |i: usize| tree.nodes()[i].flags() & flags::UNUSED == 0;
    let (first, rest): (Vec<usize>, Vec<usize>) =
        (0..nodes.len()).filter(|&i| used(i)).partition(|&i| selected(i, fraction));
    let refining = fraction < 1.0 && refine > 1.0;
    // Progress over the photons: the subset's estimates, then (refining) the
    // other photons' checks, each its share of them.
    let total = nodes.len() as u64;
    let span = if refining { total / 2 } else { total };
    let done = std::sync::atomic::AtomicU64::new(0);
    let tick = |part: usize, of: usize, base: u64| {
        let before = done.fetch_add(part as u64, std::sync::atomic::Ordering::Relaxed);
        progress(base + span * (before + part as u64) / of.max(1) as u64);
    };
    let estimate = |todo: &[usize], report: bool| -> Vec<(u32, Irradiance)> {
        todo.par_chunks(CHUNK)
            .map(|chunk| {
                let mut scratch = KnnScratch::with_capacity(p.k);
                let out: Vec<(u32, Irradiance)> = chunk
                    .iter()
                    .map(|&i| {
                        let r = &tree.nodes()[i];
                        let (x, n) = (r.position(), r.normal());
                        // A fixed turn per photon (deterministic), spread by a hash.
                        let turn = pm_sampling::unit_of(pm_sampling::mix64(i as u64));
                        let under = || r.flags() & flags::COVERED != 0;
                        (i as u32, crate::surface_irradiance(&tree, scene, x, n, under, turn, p, &mut scratch))
                    })
                    .collect();
                if report {
                    tick(chunk.len(), todo.len(), 0);
                }
                out
            })
            .flatten()
            .collect()
    };
    let mut results = estimate(&first, true);
    let mut refined_count = 0;
    if refining {
        // The subset with its irradiance, as its own tree for the checks.
        let mut subset: Vec<R> = results
            .iter()
            .map(|(i, est)| {
                let mut r = tree.nodes()[*i as usize];
                r.set_irradiance(est.e);
                r
            })
            .collect();
        subset = pm_kdtree::balance(&subset);
        let sub = KdTree::new(&subset);
        done.store(0, std::sync::atomic::Ordering::Relaxed);
        let refined: Vec<usize> = rest
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut scratch = KnnScratch::with_capacity(REFINE_NEIGHBOURS);
                let out: Vec<usize> = chunk
                    .iter()
                    .copied()
                    .filter(|&i| disagree(&sub, &tree.nodes()[i], p.max_d2, refine, &mut scratch))
                    .collect();
                tick(chunk.len(), rest.len(), span);
                out
            })
            .flatten()
            .collect();
        refined_count = refined.len() as u64;
        results.extend(estimate(&refined, false));
        results.sort_by_key(|(i, _)| *i);
    }
    progress(total);
    let mut stats = PrecomputeStats { covered, refined: refined_count, ..Default::default() };
    for (i, est) in results {
        let r = &mut nodes[i as usize];
        r.set_irradiance(est.e);
        r.set_flags(r.flags() | flags::HAS_IRRADIANCE);
        stats.computed += 1;
        stats.empty += (est.count == 0 || est.e == glam::Vec3::ZERO) as u64;
        stats.radii.push(est.r2.max(0.0).sqrt());
    }
    stats.radii.sort_by(f32::total_cmp);
    stats
}

/// Whether the [`REFINE_NEIGHBOURS`] nearest photons of `subset` (those with a
/// precomputed irradiance) to photon `r` within squared radius `max_d2` that the
/// final gather's lookup would take for it ([`crate::precomputed_irradiance_where`]:
/// normals within [`crate::SIMILAR_NORMAL_COS`], under a cover only for a photon
/// under one) differ in luminance by more than the factor `ratio`.
fn disagree<R: PhotonRecord>(subset: &KdTree<R>, r: &R, max_d2: f32, ratio: f32, scratch: &mut KnnScratch) -> bool {
    let (x, n, under) = (r.position(), r.normal(), r.flags() & flags::COVERED != 0);
    let takes = |_, q: &R| q.normal().dot(n) > crate::SIMILAR_NORMAL_COS && (q.flags() & flags::COVERED == 0 || under);
    subset.knn(x, REFINE_NEIGHBOURS, max_d2, takes, scratch);
    let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
    for (j, _) in subset.found(scratch) {
        let l = pm_color::luminance(subset.nodes()[j as usize].irradiance());
        (lo, hi) = (lo.min(l), hi.max(l));
    }
    hi > ratio * lo
}
