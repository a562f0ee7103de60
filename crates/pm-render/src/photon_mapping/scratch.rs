//! Per-thread scratch memory of the photon-map integrators and the sampled
//! per-component clock, shared by final gathering, the volume estimates and the
//! integrator itself (so neither of the first two imports the other's module).

use pm_kdtree::KnnScratch;

/// Per-thread scratch memory of the photon-map integrators (photon queries).
#[derive(Default)]
pub struct Scratch {
    pub(crate) knn: KnnScratch,
    pub(crate) rejected: Vec<f32>,
    /// The beam estimate's traversal stack.
    pub(crate) stack: Vec<u32>,
    /// Calls of [`Scratch::clock`] so far (one in [`TIME_EVERY`] is timed).
    ticks: u32,
}

/// The per-component times in the render statistics time one call in this many and
/// count it this many times: reading the clock at every shading point was 5% of
/// rendering (perf, cornell_spheres 1024 x 1024).
pub(crate) const TIME_EVERY: u32 = 8;

impl Scratch {
    /// The start of a timed call, for one call in [`TIME_EVERY`] of this thread's.
    #[inline]
    pub(crate) fn clock(&mut self) -> Option<std::time::Instant> {
        self.ticks = self.ticks.wrapping_add(1);
        self.ticks.is_multiple_of(TIME_EVERY).then(std::time::Instant::now)
    }
}

/// Add a timed call's share to `counter` [ns]: its elapsed time x [`TIME_EVERY`].
#[inline]
pub(crate) fn add_time(counter: &std::sync::atomic::AtomicU64, start: Option<std::time::Instant>) {
    if let Some(t) = start {
        counter.fetch_add(t.elapsed().as_nanos() as u64 * TIME_EVERY as u64, std::sync::atomic::Ordering::Relaxed);
    }
}
