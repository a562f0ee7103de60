//! The photon ring buffer of Jozwowski 2002, section 4.1: `total` photon paths of
//! up to `max_level` hits each, stored in `photons[]` with hit j of path i at slot
//! i + j x total (section 4.1.2, Figure 11). Every frame re-shoots the oldest
//! `per_frame` paths; a path's slots beyond its last stored hit (a specular hit, an
//! absorbed or escaped tail) are marked unused, so nothing of the path it replaced
//! survives. Power is scaled by the number of paths held, so the buffer carries the
//! lights' power while it fills (Figure 18) and after.

use pm_format::{Photon, flags};
use pm_photon::{PathOut, TraceConfig};
use pm_scene::{Scene, Target};
use rayon::prelude::*;

pm_params::value_enum! {
    /// Which photon path a slot gets when it is re-shot (section 4.1.1).
    pub enum Distribution {
        /// A path never shot before: flickers most, covers everything over time.
        Random,
        /// Every frame repeats the same `per_frame` paths: least flicker, poorest coverage.
        SamePerFrame,
        /// Path i of the buffer is always the same path: repeats every total / per_frame
        /// frames (the thesis's recommendation). A full buffer holds the batch map.
        SameOverTotal,
    }
}

/// The ring buffer.
#[derive(Clone, Debug)]
pub struct RingBuffer {
    total: usize,
    max_level: usize,
    /// `photons[]`: slot i + j x total holds hit j of path i, or none (unused).
    slots: Vec<Option<Photon>>,
    /// The emission index each held path was traced with (its stream), or none.
    index_of: Vec<Option<u64>>,
    /// Paths held (grows to `total` while the buffer fills).
    filled: usize,
    /// The next path to overwrite.
    next: usize,
    /// Paths shot since the start.
    shot: u64,
    /// The paths the last [`RingBuffer::shoot`] re-shot.
    last: Vec<usize>,
    /// The cover distance \[m\]: photons with another surface facing them from
    /// closer are flagged [`flags::COVERED`] as they are stored (0: none is).
    pub cover: f32,
}

/// What one call to [`RingBuffer::shoot`] did.
#[derive(Clone, Copy, Debug, Default)]
pub struct ShootStats {
    /// Paths shot.
    pub paths: u64,
    /// Rays traced.
    pub rays: u64,
    /// Hits stored (used slots written).
    pub stored: u64,
}

impl RingBuffer {
    /// An empty buffer of `total` paths of up to `max_level` hits.
    pub fn new(total: usize, max_level: usize) -> RingBuffer {
        RingBuffer {
            total,
            max_level,
            slots: vec![None; total * max_level],
            index_of: vec![None; total],
            filled: 0,
            next: 0,
            shot: 0,
            last: Vec::new(),
            cover: 0.0,
        }
    }

    /// Paths the buffer can hold.
    pub fn total(&self) -> usize {
        self.total
    }

    /// Hits kept per path.
    pub fn max_level(&self) -> usize {
        self.max_level
    }

    /// Paths held now.
    pub fn filled(&self) -> usize {
        self.filled
    }

    /// The emission index path `i` was traced with, if it has been shot.
    pub fn index_of(&self, i: usize) -> Option<u64> {
        self.index_of[i]
    }

    /// The paths the last [`RingBuffer::shoot`] re-shot (their slots changed).
    pub fn last_paths(&self) -> &[usize] {
        &self.last
    }

    /// Slot `i + level x total`: hit `level` of path `i`, if used.
    pub fn slot(&self, i: usize, level: usize) -> Option<&Photon> {
        self.slots[i + level * self.total].as_ref()
    }

    /// The emission index of the next re-shot path under `distribution`.
    fn stream_index(&self, distribution: Distribution, path: usize, per_frame: usize) -> u64 {
        match distribution {
            Distribution::Random => self.shot,
            Distribution::SamePerFrame => self.shot % per_frame as u64,
            Distribution::SameOverTotal => path as u64,
        }
    }

    /// Re-shoot the oldest `per_frame` paths (Figure 15/16): each path is traced
    /// with the stream of its emission index (`pm_photon::trace_path`, the batch
    /// tracer's own), and its hits go to its slots, level by level; slots past its
    /// last stored hit become unused. Deterministic for any thread count.
    pub fn shoot(
        &mut self,
        scene: &Scene,
        cfg: &TraceConfig,
        targets: &[Target],
        per_frame: usize,
        distribution: Distribution,
    ) -> ShootStats {
        let per_frame = per_frame.min(self.total);
        let mut jobs = Vec::with_capacity(per_frame);
        for _ in 0..per_frame {
            let path = self.next;
            jobs.push((path, self.stream_index(distribution, path, per_frame)));
            self.next = (self.next + 1) % self.total;
            self.shot += 1;
        }
        let traced: Vec<PathOut> = jobs
            .par_iter()
            .map(|&(_, index)| {
                let mut out = PathOut::default();
                pm_photon::trace_path(scene, cfg, targets, index, &mut out);
                // Photons under a cover, for the corner estimates to keep apart
                // (`crate::Around`).
                if self.cover > 0.0 {
                    for (photon, _) in &mut out.photons {
                        if photon.flags & flags::VOLUME == 0
                            && scene.covered(photon.position, photon.normal, self.cover)
                        {
                            photon.flags |= flags::COVERED;
                        }
                    }
                }
                out
            })
            .collect();
        let mut stats = ShootStats { paths: per_frame as u64, ..Default::default() };
        self.last.clear();
        self.last.extend(jobs.iter().map(|j| j.0));
        for ((path, index), out) in jobs.into_iter().zip(traced) {
            stats.rays += out.rays;
            for level in 0..self.max_level {
                self.slots[path + level * self.total] = None;
            }
            for (photon, level) in out.photons {
                if (level as usize) < self.max_level {
                    self.slots[path + level as usize * self.total] = Some(photon);
                    stats.stored += 1;
                }
            }
            if self.index_of[path].is_none() {
                self.filled += 1;
            }
            self.index_of[path] = Some(index);
        }
        stats
    }

    /// The used slots as photons whose power is divided by the paths held (so the
    /// buffer carries the lights' power at every frame of warm-up and after), in
    /// slot order.
    pub fn photons(&self) -> Vec<Photon> {
        let n = self.filled as u64;
        self.slots.iter().flatten().map(|p| Photon { power: pm_photon::scale_power(p.power, n), ..*p }).collect()
    }
}
