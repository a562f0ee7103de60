//! The bottom levels of a heap-order kd-tree copied out as leaf buckets: each
//! subtree of the bottom five levels (its root and all its descendants) becomes
//! one contiguous run of positions, scanned linearly instead of descended. In heap
//! order a subtree's nodes lie far apart in memory (a node's children at twice its
//! index), so the search paid a cache miss per node near the leaves. The stem
//! above is searched by its splitting planes alone, kept in heap order in an array
//! of their own, where the top levels share the first cache lines. kiddo's
//! immutable tree uses 32-point leaf buckets for the same reason. The records are
//! not moved: the photon-map file stays a heap-order tree, and the buckets are
//! built from it when it is loaded.

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

/// Leaf buckets of a heap-order tree (see the module's documentation): about 17
/// bytes a photon beside the records.
#[derive(Clone, Debug, Default)]
pub struct Buckets {
    /// The stem nodes' splits, in heap order (the stem is the first 2^d - 1 nodes,
    /// and the node at 2^d - 1 + b roots bucket b): the search descends the stem
    /// reading only these (8 bytes a node, where a record is 18-23), and each
    /// stem node's own photon is stored in the bucket its position leads to.
    splits: Vec<Split>,
    /// Bucket b's blocks are `blocks[start[b]..start[b + 1]]`.
    start: Vec<u32>,
    blocks: Vec<Block>,
}

/// A stem node's splitting plane: coordinate `axis` equals `value` [m].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Split {
    pub(crate) value: f32,
    pub(crate) axis: u32,
}

/// Levels of a bucket's subtree: a full one holds 2^5 - 1 = 31 photons (plus the
/// stem photons routed to it), four blocks.
const BUCKET_LEVELS: u32 = 5;

impl Buckets {
    /// The buckets of `nodes` (heap order, as [`crate::balance`] leaves them);
    /// photons flagged [`flags::UNUSED`] are left out. Trees of less than two
    /// buckets' depth get none (their search is the plain descent).
    ///
    /// Each stem node's photon lies on its splitting plane, so in the closed cells
    /// of both its subtrees; it is routed down the left one by the splits below to
    /// a bucket whose cell contains it. A search reaches every bucket whose cell
    /// lies within its radius, so it finds the photon there as it would have at
    /// the stem node.
    pub fn new<R: PhotonRecord>(nodes: &[R]) -> Buckets {
        let n = nodes.len();
        let levels = usize::BITS - n.leading_zeros(); // of the whole tree
        if levels <= BUCKET_LEVELS + 1 {
            return Buckets::default();
        }
        let depth = levels - BUCKET_LEVELS;
        let first = (1usize << depth) - 1;
        // Level `depth` is full (levels below it exist), so every stem node has two
        // children and there are 2^depth buckets.
        let count = 1usize << depth;
        let used = |i: usize| nodes[i].flags() & flags::UNUSED == 0;
        let splits: Vec<Split> = nodes[..first]
            .par_iter()
            .map(|r| {
                let axis = (r.flags() & flags::AXIS_MASK) as u32;
                Split { value: r.position()[axis as usize], axis }
            })
            .collect();
        // The stem photons by the bucket they are routed to, in heap order.
        let mut routed: Vec<(u32, u32)> = (0..first)
            .into_par_iter()
            .filter(|&i| used(i))
            .map(|i| {
                let p = nodes[i].position();
                let mut j = 2 * i + 1;
                while j < first {
                    let s = splits[j];
                    j = if p[s.axis as usize] <= s.value { 2 * j + 1 } else { 2 * j + 2 };
                }
                ((j - first) as u32, i as u32)
            })
            .collect();
        routed.par_sort_unstable();
        let routed_of = |b: usize| {
            let lo = routed.partition_point(|&(r, _)| (r as usize) < b);
            let hi = routed.partition_point(|&(r, _)| (r as usize) <= b);
            routed[lo..hi].iter().map(|&(_, i)| i as usize)
        };
        // A bucket's subtree level by level (at level l below its root h, the 2^l
        // consecutive indices from (h + 1) 2^l - 1), then its routed stem photons.
        let members = |b: usize| {
            let h = first + b;
            (0..BUCKET_LEVELS as usize)
                .map(move |l| ((h + 1) << l) - 1..(((h + 2) << l) - 1).min(n))
                .take_while(|r| r.start < n)
                .flatten()
                .filter(|&i| used(i))
                .chain(routed_of(b))
        };
        let sizes: Vec<u32> = (0..count).into_par_iter().map(|b| members(b).count().div_ceil(LANES) as u32).collect();
        let mut start = Vec::with_capacity(count + 1);
        let mut total = 0u32;
        start.push(0);
        for s in &sizes {
            total += s;
            start.push(total);
        }
        // Filled in parallel: tens of megabytes for millions of photons.
        let mut blocks: Vec<Block> = (0..total).into_par_iter().map(|_| Block::EMPTY).collect();
        // Fill each bucket's blocks in parallel: split the array at the buckets' starts.
        let mut rest: &mut [Block] = &mut blocks;
        let mut parts = Vec::with_capacity(count);
        for &s in &sizes {
            let (head, tail) = rest.split_at_mut(s as usize);
            parts.push(head);
            rest = tail;
        }
        parts.into_par_iter().enumerate().for_each(|(b, out)| {
            for (k, i) in members(b).enumerate() {
                let (blk, lane) = (&mut out[k / LANES], k % LANES);
                let p = nodes[i].position();
                blk.x[lane] = p.x;
                blk.y[lane] = p.y;
                blk.z[lane] = p.z;
                blk.id[lane] = i as u32;
            }
        });
        Buckets { splits, start, blocks }
    }

    /// The stem's splits in heap order.
    #[inline]
    pub(crate) fn splits(&self) -> &[Split] {
        &self.splits
    }

    /// True for no buckets (a tree too small for them).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.start.is_empty()
    }

    /// The blocks of the bucket rooted at heap node `root` (one past the stem).
    #[inline]
    pub(crate) fn bucket(&self, root: usize) -> &[Block] {
        let b = root - self.splits.len();
        &self.blocks[self.start[b] as usize..self.start[b + 1] as usize]
    }

    /// Bytes the buckets hold.
    pub fn bytes(&self) -> usize {
        self.blocks.len() * std::mem::size_of::<Block>() + self.start.len() * 4 + self.splits.len() * 8
    }
}
