//! The bottom levels of a heap-order kd-tree copied out as leaf buckets: each
//! subtree rooted at depth [`Buckets::depth`] (its root and all its descendants,
//! several levels) becomes one contiguous run of positions, scanned linearly
//! instead of descended. In heap order a subtree's nodes lie far apart in memory
//! (a node's children at twice its index), so the search paid a cache miss per
//! node near the leaves; the stem above stays in heap order, where the top levels
//! share the first cache lines. kiddo's immutable tree uses 32-point leaf
//! buckets for the same reason. The records are not moved: the photon-map file
//! stays a heap-order tree, and the buckets are built from it when it is loaded.

use glam::Vec3;
use pm_format::{PhotonRecord, flags};
use rayon::prelude::*;

/// Positions a block holds (a bucket is a whole number of blocks).
pub(crate) const LANES: usize = 8;

/// Eight photons' positions, by coordinate, and their heap indices. Lanes past a
/// bucket's photons hold NaN, which no distance test passes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct Block {
    pub(crate) x: [f32; LANES],
    pub(crate) y: [f32; LANES],
    pub(crate) z: [f32; LANES],
    pub(crate) id: [u32; LANES],
}

impl Block {
    const EMPTY: Block =
        Block { x: [f32::NAN; LANES], y: [f32::NAN; LANES], z: [f32::NAN; LANES], id: [u32::MAX; LANES] };

    /// Squared distances from `q` to the block's positions [m^2] (NaN in empty lanes).
    #[inline(always)]
    pub(crate) fn dist2(&self, q: Vec3) -> [f32; LANES] {
        std::array::from_fn(|i| {
            let (dx, dy, dz) = (self.x[i] - q.x, self.y[i] - q.y, self.z[i] - q.z);
            dx * dx + dy * dy + dz * dz
        })
    }
}

/// Leaf buckets of a heap-order tree (see the module's documentation): about 16
/// bytes a photon beside the records.
#[derive(Clone, Debug, Default)]
pub struct Buckets {
    /// Levels of the stem: heap nodes below `2^depth - 1` are searched as a tree,
    /// and the node at `2^depth - 1 + b` roots bucket `b`.
    depth: u32,
    /// Bucket b's blocks are `blocks[start[b]..start[b + 1]]`.
    start: Vec<u32>,
    blocks: Vec<Block>,
}

/// Levels of a bucket's subtree: a full one holds 2^4 - 1 = 15 photons, two blocks.
const BUCKET_LEVELS: u32 = 5;

impl Buckets {
    /// The buckets of `nodes` (heap order, as [`crate::balance`] leaves them);
    /// photons flagged [`flags::UNUSED`] are left out. Trees of less than two
    /// buckets' depth get none (their search is the plain descent).
    pub fn new<R: PhotonRecord>(nodes: &[R]) -> Buckets {
        let n = nodes.len();
        let levels = usize::BITS - n.leading_zeros(); // of the whole tree
        if levels <= BUCKET_LEVELS + 1 {
            return Buckets::default();
        }
        let depth = levels - BUCKET_LEVELS;
        let first = (1usize << depth) - 1;
        let count = (n - first).min(1usize << depth);
        // A bucket's nodes level by level: at level l below its root h, the 2^l
        // consecutive indices from (h + 1) 2^l - 1.
        let members = |h: usize| {
            (0..BUCKET_LEVELS as usize)
                .map(move |l| ((h + 1) << l) - 1..(((h + 2) << l) - 1).min(n))
                .take_while(|r| r.start < n)
                .flatten()
                .filter(|&i| nodes[i].flags() & flags::UNUSED == 0)
        };
        let sizes: Vec<u32> =
            (0..count).into_par_iter().map(|b| members(first + b).count().div_ceil(LANES) as u32).collect();
        let mut start = Vec::with_capacity(count + 1);
        let mut total = 0u32;
        start.push(0);
        for s in &sizes {
            total += s;
            start.push(total);
        }
        let mut blocks = vec![Block::EMPTY; total as usize];
        // Fill each bucket's blocks in parallel: split the array at the buckets' starts.
        let mut rest: &mut [Block] = &mut blocks;
        let mut parts = Vec::with_capacity(count);
        for &s in &sizes {
            let (head, tail) = rest.split_at_mut(s as usize);
            parts.push(head);
            rest = tail;
        }
        parts.into_par_iter().enumerate().for_each(|(b, out)| {
            for (k, i) in members(first + b).enumerate() {
                let (blk, lane) = (&mut out[k / LANES], k % LANES);
                let p = nodes[i].position();
                blk.x[lane] = p.x;
                blk.y[lane] = p.y;
                blk.z[lane] = p.z;
                blk.id[lane] = i as u32;
            }
        });
        Buckets { depth, start, blocks }
    }

    /// Heap index of the first bucket's root (the stem is the nodes before it); 0
    /// for no buckets.
    #[inline]
    pub(crate) fn stem_len(&self) -> usize {
        if self.start.is_empty() { usize::MAX } else { (1usize << self.depth) - 1 }
    }

    /// The blocks of the bucket rooted at heap node `root` (at least `stem_len`).
    #[inline]
    pub(crate) fn bucket(&self, root: usize) -> &[Block] {
        let b = root - self.stem_len();
        &self.blocks[self.start[b] as usize..self.start[b + 1] as usize]
    }

    /// Bytes the buckets hold.
    pub fn bytes(&self) -> usize {
        self.blocks.len() * std::mem::size_of::<Block>() + self.start.len() * 4
    }
}
