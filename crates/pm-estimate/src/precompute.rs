//! Irradiance precomputed at photon positions (Christensen 1999 section 2.1).

use crate::{Irradiance, KnnParams, irradiance};
use pm_format::{PhotonRecord, flags};
use pm_kdtree::{KdTree, KnnScratch};
use pm_sampling::mix64;
use rayon::prelude::*;

/// Photons per parallel work item.
const CHUNK: usize = 2048;

/// True when the photon at `position` is in the subset that gets a precomputed
/// irradiance. The choice is an independent coin flip per photon, keyed by a hash of
/// its position bits and the seed: a Bernoulli thinning of the photon distribution,
/// which keeps exactly the photon density's shape (scaled by `fraction`), whatever
/// the order of the records. (Every n-th photon in kd-tree heap order is not: heap
/// order groups photons by tree level, and the levels are not spatially
/// interchangeable; the workspace tests compare both.)
pub fn selected(position: glam::Vec3, fraction: f64, seed: u64) -> bool {
    if fraction >= 1.0 {
        return true;
    }
    let [x, y, z] = position.to_array().map(|v| v.to_bits() as u64);
    let h = mix64(x ^ mix64(y ^ mix64(z ^ mix64(seed))));
    (h as f64) < fraction * 18_446_744_073_709_551_616.0
}

/// What a precompute did.
#[derive(Clone, Debug, Default)]
pub struct PrecomputeStats {
    /// Photons that received an irradiance.
    pub computed: u64,
    /// Of those, estimates that found no photon on their side (irradiance 0).
    pub empty: u64,
    /// Radius of each estimate [m], sorted ascending.
    pub radii: Vec<f32>,
}

/// Estimate the irradiance at the selected photons of a kd-tree map (`nodes` in heap
/// order, with surface normals) and store it in them, flagging them
/// [`flags::HAS_IRRADIANCE`]. Parallel and deterministic. `progress` gets the number
/// of photons examined so far.
pub fn precompute<R: PhotonRecord>(
    nodes: &mut [R],
    p: &KnnParams,
    fraction: f64,
    seed: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> PrecomputeStats {
    let tree = KdTree::new(&*nodes);
    let done = std::sync::atomic::AtomicU64::new(0);
    let results: Vec<Vec<(u32, Irradiance)>> = (0..nodes.len())
        .step_by(CHUNK)
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&start| {
            let mut scratch = KnnScratch::with_capacity(p.k);
            let end = (start + CHUNK).min(tree.nodes().len());
            let out = (start..end)
                .filter(|&i| {
                    let r = &tree.nodes()[i];
                    r.flags() & flags::UNUSED == 0 && selected(r.position(), fraction, seed)
                })
                .map(|i| {
                    let r = &tree.nodes()[i];
                    (i as u32, irradiance(&tree, r.position(), r.normal(), p, &mut scratch))
                })
                .collect();
            let n = done.fetch_add((end - start) as u64, std::sync::atomic::Ordering::Relaxed);
            progress(n + (end - start) as u64);
            out
        })
        .collect();
    let mut stats = PrecomputeStats::default();
    for (i, est) in results.into_iter().flatten() {
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
