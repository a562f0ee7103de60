//! The photon kd-tree (Christensen 1999 section 1.2; Jensen 1996, "Global
//! illumination using photon maps"; Jozwowski 2002 section 4.1.2): a left-balanced
//! kd-tree stored in heap order, so node `i` has children `2i+1` and `2i+2`, the
//! split axis lives in the record's flags byte, and the records themselves are the
//! tree: no pointers and no memory beyond them. Searches that visit many photons
//! (k nearest, all within a radius) can go through [`Buckets`], the bottom five
//! levels copied out as contiguous leaf buckets (about 17 bytes a photon), built
//! when a map is loaded; the file stays a heap-order tree.
//!
//! [`balance`] builds it in O(n log n) by median selection on the axis of largest
//! extent, in parallel, deterministically. [`KdTree`] answers the queries every
//! later stage needs: k nearest within a radius ([`KdTree::knn`]), the nearest photon
//! that satisfies a predicate in order of distance ([`KdTree::nearest`]), and all
//! photons within a radius ([`KdTree::for_each_within`]). Queries allocate nothing
//! (the caller owns the scratch), take `&self` so any number of threads can share a
//! tree, and skip photons flagged [`flags::UNUSED`]. [`SphereTree`] holds photons as
//! spheres of their own radii for the beam radiance estimate: every sphere a ray
//! segment crosses.
//!
//! This crate does no I/O and holds no global state.

use glam::Vec3;
use pm_format::{PhotonRecord, flags};
use rayon::prelude::*;
use std::collections::BinaryHeap;

mod beam;
mod buckets;
mod cells;
mod grid;
pub use beam::SphereTree;
pub use buckets::Buckets;
pub use cells::RadiusGrid;
pub use grid::PhotonGrid;

/// A structure that answers k-nearest photon queries: the kd-tree, or the
/// incrementally updated [`PhotonGrid`]. Density estimates (pm-estimate) work on either.
pub trait Neighbours<R: PhotonRecord> {
    /// The `k` nearest photons to `x` within squared radius `max_d2` that pass
    /// `filter(id, record)`, left in `scratch`.
    fn knn(
        &self,
        x: Vec3,
        k: usize,
        max_d2: f32,
        filter: impl Fn(u32, &R) -> bool,
        scratch: &mut KnnScratch,
    ) -> KnnResult;
    /// The photons of the last [`Neighbours::knn`] as (id, squared distance).
    fn found<'s>(&'s self, scratch: &'s KnnScratch) -> impl Iterator<Item = (u32, f32)> + 's;
    /// The photon with id `i`.
    fn record(&self, i: u32) -> &R;
}

/// Subtrees smaller than this are balanced on one thread.
const PARALLEL_CUTOFF: usize = 1 << 12;
/// Deepest possible tree: a left-balanced tree of n < 2^63 nodes has depth < 64.
const MAX_DEPTH: usize = 64;

/// Number of nodes in the left subtree of a left-balanced tree of `n` nodes: the
/// last level fills from the left, so the left subtree is complete whenever the
/// last level is at least half full.
pub fn left_size(n: usize) -> usize {
    if n <= 1 {
        return 0;
    }
    let h = usize::BITS - 1 - n.leading_zeros(); // depth of the last level
    let full_above = (1usize << h) - 1; // nodes on levels 0..h-1
    let last = n - full_above; // nodes on the last level
    let half = 1usize << (h - 1); // last-level capacity of the left subtree
    (half - 1) + last.min(half)
}

/// A point as the balance orders it: each coordinate as an integer key whose order
/// is `f32::total_cmp`'s (one integer comparison instead of two bit twiddles and a
/// comparison per element in the median selections), and its index.
#[derive(Clone, Copy)]
struct Item {
    key: [u32; 3],
    src: u32,
}

/// The order-preserving integer key of `v`: `f32::total_cmp(a, b)` is
/// `sort_key(a).cmp(&sort_key(b))`.
#[inline]
fn sort_key(v: f32) -> u32 {
    let b = v.to_bits();
    if b >> 31 == 1 { !b } else { b | 0x8000_0000 }
}

/// The float of a [`sort_key`].
#[inline]
fn from_sort_key(k: u32) -> f32 {
    f32::from_bits(if k >> 31 == 1 { k & 0x7fff_ffff } else { !k })
}

/// The balancing permutation of a set of positions: `order[h]` is the index of the
/// point placed at heap position `h`, and `axes[h]` its split axis (or
/// [`flags::AXIS_LEAF`]). Exposed for the real-time mode, which keeps the
/// photon-to-slot map of Jozwowski 2002 section 4.1.2.
pub fn balance_permutation(positions: &[Vec3]) -> (Vec<u32>, Vec<u8>) {
    permutation(positions.len(), |i| positions[i])
}

/// [`balance_permutation`] of the `n` points `position(i)`.
fn permutation(n: usize, position: impl Fn(usize) -> Vec3 + Sync) -> (Vec<u32>, Vec<u8>) {
    assert!(n < u32::MAX as usize, "photon maps hold fewer than 2^32 photons");
    let mut items: Vec<Item> =
        (0..n).into_par_iter().map(|i| Item { key: position(i).to_array().map(sort_key), src: i as u32 }).collect();
    let mut axes = vec![flags::AXIS_LEAF; items.len()];
    split(&mut items, &mut axes);
    // `items` is now in "segment order": each subtree is a contiguous segment whose
    // node sits at offset left_size(len). Map heap positions to segment positions.
    let n = items.len();
    let mut order = vec![0u32; n];
    let mut heap_axes = vec![flags::AXIS_LEAF; n];
    let mut stack = vec![(0usize, 0usize, n)]; // (heap index, segment start, segment length)
    while let Some((h, start, len)) = stack.pop() {
        if len == 0 {
            continue;
        }
        let l = left_size(len);
        order[h] = items[start + l].src;
        heap_axes[h] = axes[start + l];
        stack.push((2 * h + 1, start, l));
        stack.push((2 * h + 2, start + l + 1, len - l - 1));
    }
    (order, heap_axes)
}

/// Partition `items` recursively: median on the axis of largest extent of the
/// points' bounding box at offset `left_size(len)`, then the two sides. (Narrowing
/// the parent's cell instead of measuring the points, as Jensen does, saves a pass
/// per level but chose worse axes here: irradiance estimates on the Cornell map ran
/// 2.1x slower on such trees.)
fn split(items: &mut [Item], axes: &mut [u8]) {
    let n = items.len();
    if n <= 1 {
        return;
    }
    // The box from the extreme keys (the order is the floats'), then measured in
    // floats as before.
    let (mut lo, mut hi) = ([u32::MAX; 3], [0u32; 3]);
    for it in items.iter() {
        for k in 0..3 {
            lo[k] = lo[k].min(it.key[k]);
            hi[k] = hi[k].max(it.key[k]);
        }
    }
    let ext = [0, 1, 2].map(|k| from_sort_key(hi[k]) - from_sort_key(lo[k]));
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let m = left_size(n);
    items.select_nth_unstable_by_key(m, |a| a.key[axis]);
    axes[m] = axis as u8;
    let (left, rest) = items.split_at_mut(m);
    let right = &mut rest[1..];
    let (left_axes, rest_axes) = axes.split_at_mut(m);
    let right_axes = &mut rest_axes[1..];
    if n > PARALLEL_CUTOFF {
        rayon::join(|| split(left, left_axes), || split(right, right_axes));
    } else {
        split(left, left_axes);
        split(right, right_axes);
    }
}

/// Reorder records into a left-balanced kd-tree in heap order, writing each node's
/// split axis into its flags.
pub fn balance<R: PhotonRecord>(records: &[R]) -> Vec<R> {
    let (order, axes) = permutation(records.len(), |i| records[i].position());
    // The gather is a random read per record: done in parallel, in heap order.
    order
        .par_iter()
        .zip(axes.par_iter())
        .map(|(&src, &axis)| {
            let mut r = records[src as usize];
            r.set_flags((r.flags() & !flags::AXIS_MASK) | axis);
            r
        })
        .collect()
}

/// Reusable scratch for k-nearest queries: a max-heap on squared distance.
#[derive(Debug, Default, Clone)]
pub struct KnnScratch {
    heap: BinaryHeap<u64>,
}

impl KnnScratch {
    /// The photons the last k-nearest query left here, as (id, squared distance).
    fn found(&self) -> impl Iterator<Item = (u32, f32)> + '_ {
        self.heap.iter().map(|&e| (e as u32, entry_d2(e)))
    }

    /// Scratch for queries of up to `k` photons (grows if needed).
    pub fn with_capacity(k: usize) -> KnnScratch {
        KnnScratch { heap: BinaryHeap::with_capacity(k + 1) }
    }
}

/// Result of a k-nearest query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnnResult {
    /// Photons found (at most k).
    pub count: usize,
    /// Squared distance to the farthest photon found [m^2]; 0 when none.
    pub max_dist2: f32,
}

/// The nearest photon that satisfied a predicate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Heap index of the photon.
    pub index: u32,
    /// Squared distance [m^2].
    pub dist2: f32,
    /// 1 + the number of nearer photons the predicate rejected (Christensen 1999
    /// section 2.2: "usually the second or third found photon").
    pub rank: u32,
}

/// A k-nearest heap entry: the squared distance's bit pattern (monotonic for
/// non-negative floats) above the photon id, so one integer comparison orders
/// entries by distance, then id (as the (distance, id) pairs did, with one branch
/// per comparison instead of two: the heap's comparisons were a fifth of the
/// irradiance precompute).
#[inline]
fn entry(d2: f32, i: u32) -> u64 {
    (u64::from(d2.to_bits()) << 32) | u64::from(i)
}

/// Offer photon `i` at squared distance `d2` to a k-nearest max-heap of
/// [`entry`]s: it is kept when the heap has room, or in place of the farthest when
/// it comes before it (nearer, or as near with a lower id), and `accept()` (the
/// caller's filter, asked only then) says yes. The one rule every k-nearest search
/// keeps its photons by, so the kd-tree and the grid find the same set, ties
/// included, whatever order they meet the photons in.
#[inline(always)]
fn offer(heap: &mut BinaryHeap<u64>, k: usize, d2: f32, i: u32, accept: impl FnOnce() -> bool) {
    let e = entry(d2, i);
    if heap.len() < k {
        if accept() {
            heap.push(e);
        }
    } else if let Some(mut top) = heap.peek_mut()
        && e < *top
        && accept()
    {
        *top = e; // one sift-down when `top` drops
    }
}

/// The squared distance of a heap entry [m^2].
#[inline]
fn entry_d2(e: u64) -> f32 {
    f32::from_bits((e >> 32) as u32)
}

#[inline]
fn dist2(a: Vec3, b: Vec3) -> f32 {
    (a - b).length_squared()
}

/// What a search does with each photon within its radius: `visit(heap index,
/// record, squared distance)` returns the radius (squared) to go on with. Closures
/// are visitors; the k-nearest heap is one of its own, whose method is always
/// inlined into the search loops (left to the inliner's judgment, the closure it
/// replaced was once inlined and once not, and the caustic estimates took 1.2 s or
/// 1.5 s of the default render's thread time).
trait Visit<R> {
    fn visit(&mut self, i: u32, r: &R, d2: f32) -> f32;
}

/// A closure as a visitor (the bound makes its argument types, the record's
/// lifetime included, those of a visitor).
#[inline(always)]
fn visiting<R, F: FnMut(u32, &R, f32) -> f32>(f: F) -> F {
    f
}

impl<R, F: FnMut(u32, &R, f32) -> f32> Visit<R> for F {
    #[inline]
    fn visit(&mut self, i: u32, r: &R, d2: f32) -> f32 {
        self(i, r, d2)
    }
}

/// [`KdTree::knn`]'s visitor: the k nearest so far in a max-heap.
struct KnnVisit<'s, F> {
    heap: &'s mut BinaryHeap<u64>,
    k: usize,
    max_d2: f32,
    filter: F,
}

impl<R, F: Fn(u32, &R) -> bool> Visit<R> for KnnVisit<'_, F> {
    #[inline(always)]
    fn visit(&mut self, i: u32, r: &R, d2: f32) -> f32 {
        let (heap, k) = (&mut *self.heap, self.k);
        offer(heap, k, d2, i, || (self.filter)(i, r));
        // The search visits photons within the radius only: a full heap's farthest
        // is inside it.
        if heap.len() < k { self.max_d2 } else { heap.peek().map_or(0.0, |&e| entry_d2(e)) }
    }
}

/// The far subtrees a search deferred, each with the squared distance to its
/// splitting plane [m^2]; the last pushed is the nearest side of the deepest split.
struct Deferred {
    stack: [(u32, f32); MAX_DEPTH],
    top: usize,
}

impl Deferred {
    #[inline]
    fn new() -> Deferred {
        Deferred { stack: [(0, 0.0); MAX_DEPTH], top: 0 }
    }

    #[inline]
    fn push(&mut self, node: usize, plane_d2: f32) {
        self.stack[self.top] = (node as u32, plane_d2);
        self.top += 1;
    }

    /// The most recently deferred subtree whose plane lies within `max_d2`
    /// (the others are dropped); none when the search is done.
    #[inline]
    fn pop_within(&mut self, max_d2: f32) -> Option<usize> {
        while self.top > 0 {
            self.top -= 1;
            let (far, plane_d2) = self.stack[self.top];
            if plane_d2 <= max_d2 {
                return Some(far as usize);
            }
        }
        None
    }
}

/// A read-only view of records in heap order as a kd-tree, searched through its
/// leaf [`Buckets`] when it has them.
#[derive(Clone, Copy, Debug)]
pub struct KdTree<'a, R> {
    nodes: &'a [R],
    buckets: Option<&'a Buckets>,
}

impl<R: PhotonRecord> Neighbours<R> for KdTree<'_, R> {
    fn knn(
        &self,
        x: Vec3,
        k: usize,
        max_d2: f32,
        filter: impl Fn(u32, &R) -> bool,
        scratch: &mut KnnScratch,
    ) -> KnnResult {
        KdTree::knn(self, x, k, max_d2, filter, scratch)
    }
    fn found<'s>(&'s self, scratch: &'s KnnScratch) -> impl Iterator<Item = (u32, f32)> + 's {
        KdTree::found(self, scratch)
    }
    fn record(&self, i: u32) -> &R {
        &self.nodes[i as usize]
    }
}

impl<'a, R: PhotonRecord> KdTree<'a, R> {
    /// View `nodes` (heap order, as produced by [`balance`]) as a tree.
    pub fn new(nodes: &'a [R]) -> Self {
        KdTree { nodes, buckets: None }
    }

    /// View `nodes` as a tree searched through `buckets`, which must be
    /// [`Buckets::new`] of these nodes. Same answers as [`KdTree::new`], found
    /// sooner.
    pub fn with_buckets(nodes: &'a [R], buckets: &'a Buckets) -> Self {
        KdTree { nodes, buckets: Some(buckets) }
    }

    /// The records in heap order.
    pub fn nodes(&self) -> &'a [R] {
        self.nodes
    }

    /// Visit nodes whose subtree may hold points within `max_d2` (which the visitor
    /// may shrink), nearest side first. The visitor gets (index, record, dist2) for
    /// every used node inside the current radius and returns the new radius.
    /// Through the tree's [`Buckets`] when it has them: this is the search of the
    /// queries that visit many photons (k nearest, all within a radius); the
    /// nearest-photon query descends node by node ([`KdTree::nearest_where`]).
    #[inline]
    fn search(&self, x: Vec3, max_d2: f32, visit: impl Visit<R>) {
        match self.buckets {
            Some(b) if !b.is_empty() => self.search_buckets(b, x, max_d2, visit),
            _ => self.search_nodes::<false>(x, max_d2, visit),
        }
    }

    /// [`Self::search`] through `buckets`: down the stem by its splits alone, then
    /// each bucket reached scanned whole.
    #[inline]
    fn search_buckets(&self, b: &Buckets, x: Vec3, mut max_d2: f32, mut visit: impl Visit<R>) {
        if !(max_d2 >= 0.0) {
            return;
        }
        let splits = b.splits();
        let stem = splits.len();
        let mut deferred = Deferred::new();
        let mut node = 0usize;
        loop {
            while node < stem {
                let s = splits[node];
                let delta = x[s.axis as usize] - s.value;
                let left = 2 * node + 1;
                let (near, far) = if delta < 0.0 { (left, left + 1) } else { (left + 1, left) };
                deferred.push(far, delta * delta);
                node = near;
            }
            for blk in b.bucket(node) {
                for (&d2, &id) in blk.dist2(x).iter().zip(&blk.id) {
                    if d2 <= max_d2 {
                        max_d2 = visit.visit(id, &self.nodes[id as usize], d2);
                    }
                }
            }
            // The nearest deferred subtree still within the radius.
            match deferred.pop_within(max_d2) {
                Some(far) => node = far,
                None => return,
            }
        }
    }

    /// [`Self::search`] down the records in heap order. `LEAF_FIRST`: the nodes of
    /// each descent are visited from its end up rather than on the way down, so a
    /// search for the nearest photon meets a near one first and measures the
    /// ancestors against its radius instead of testing each as the best so far
    /// (nearest-with-normal throughput 3-7% higher at 100k photons, `cargo bench -p
    /// pm-kdtree --bench kdtree`; k-nearest searches, which keep everything within
    /// the radius, measured slower with a deferred visit: BENCHMARKS.md).
    #[inline]
    fn search_nodes<const LEAF_FIRST: bool>(&self, x: Vec3, mut max_d2: f32, mut visit: impl Visit<R>) {
        let n = self.nodes.len();
        if n == 0 || !(max_d2 >= 0.0) {
            return;
        }
        let mut deferred = Deferred::new();
        // With LEAF_FIRST, the nodes of one descent within the radius, visited
        // from the deepest up once it ends.
        let mut path = [(0u32, 0f32); MAX_DEPTH];
        let mut len = 0usize;
        let mut node = 0usize;
        loop {
            // Descend to a leaf along the near side, deferring far sides.
            while node < n {
                // Issue the loads of the grandchildren now (they are adjacent in heap
                // order) so their cache misses overlap with the work on this level;
                // the search is bound by memory latency, not arithmetic.
                for g in [4 * node + 3, 8 * node + 7, 8 * node + 11] {
                    if let Some(g) = self.nodes.get(g) {
                        std::hint::black_box(g.flags());
                    }
                }
                let r = &self.nodes[node];
                let p = r.position();
                let axis = (r.flags() & flags::AXIS_MASK) as usize;
                let left = 2 * node + 1;
                let next = if axis < 3 && left < n {
                    let delta = x[axis] - p[axis];
                    let (near, far) = if delta < 0.0 { (left, left + 1) } else { (left + 1, left) };
                    if far < n {
                        deferred.push(far, delta * delta);
                    }
                    near
                } else {
                    n
                };
                let d2 = dist2(p, x);
                if d2 <= max_d2 && r.flags() & flags::UNUSED == 0 {
                    if LEAF_FIRST {
                        path[len] = (node as u32, d2);
                        len += 1;
                    } else {
                        max_d2 = visit.visit(node as u32, r, d2);
                    }
                }
                node = next;
            }
            while len > 0 {
                len -= 1;
                let (i, d2) = path[len];
                if d2 <= max_d2 {
                    max_d2 = visit.visit(i, &self.nodes[i as usize], d2);
                }
            }
            // The nearest deferred subtree still within the radius.
            match deferred.pop_within(max_d2) {
                Some(far) => node = far,
                None => return,
            }
        }
    }

    /// The `k` nearest photons to `x` within squared radius `max_d2` that pass
    /// `filter(heap index, record)`. On return `scratch` holds them; iterate with
    /// [`KdTree::found`].
    pub fn knn(
        &self,
        x: Vec3,
        k: usize,
        max_d2: f32,
        filter: impl Fn(u32, &R) -> bool,
        scratch: &mut KnnScratch,
    ) -> KnnResult {
        scratch.heap.clear();
        if k == 0 {
            return KnnResult { count: 0, max_dist2: 0.0 };
        }
        self.search(x, max_d2, KnnVisit { heap: &mut scratch.heap, k, max_d2, filter });
        let heap = &scratch.heap;
        KnnResult { count: heap.len(), max_dist2: heap.peek().map_or(0.0, |&e| entry_d2(e)) }
    }

    /// The photons of the last [`KdTree::knn`] call as (heap index, squared distance).
    pub fn found<'s>(&self, scratch: &'s KnnScratch) -> impl Iterator<Item = (u32, f32)> + 's {
        scratch.found()
    }

    /// The nearest photon within `max_d2` that satisfies `accept`, searched in order
    /// of distance (Christensen 1999 section 2.2: the nearest photon with a similar
    /// normal). `rejected` is scratch for the rank statistic.
    pub fn nearest(
        &self,
        x: Vec3,
        max_d2: f32,
        accept: impl Fn(&R) -> bool,
        rejected: &mut Vec<f32>,
    ) -> Option<Nearest> {
        self.nearest_where(x, max_d2, accept, |_| true, 0, rejected)
    }

    /// The nearest photon within `max_d2` that satisfies both `cheap` and `costly`,
    /// where `costly` (a shadow ray) is asked only of the photon that is nearest among
    /// those passing `cheap`: if it refuses, that photon is set aside and the search
    /// repeated, up to `max_refusals` times (then there is no result). Asking `costly`
    /// inside one search would ask it of every candidate that improves on the best so
    /// far. `rejected` is scratch for the rank statistic: the rank is one more than
    /// the photons closer than the result that failed either test.
    pub fn nearest_where(
        &self,
        x: Vec3,
        max_d2: f32,
        cheap: impl Fn(&R) -> bool,
        mut costly: impl FnMut(&R) -> bool,
        max_refusals: u32,
        rejected: &mut Vec<f32>,
    ) -> Option<Nearest> {
        rejected.clear();
        let mut set_aside: Vec<u32> = Vec::new();
        // Cheap failures nearer than `floor` were recorded by an earlier pass.
        let mut floor = f32::NEG_INFINITY;
        loop {
            let pass_start = rejected.len();
            let mut best: Option<(u32, f32)> = None;
            // Not through the buckets, which would measure all 31 photons of each:
            // 0.76-0.85x the plain descent's throughput at 1M and 4M photons (`cargo
            // bench -p pm-kdtree --bench kdtree`).
            self.search_nodes::<true>(
                x,
                max_d2,
                visiting(|i, r, d2| {
                    let radius = best.map_or(max_d2, |b| b.1);
                    if best.is_some() && d2 >= radius {
                        return radius;
                    }
                    if !cheap(r) {
                        if d2 >= floor {
                            rejected.push(d2);
                        }
                        radius
                    } else if set_aside.contains(&i) {
                        radius
                    } else {
                        best = Some((i, d2));
                        d2
                    }
                }),
            );
            let (index, dist2) = best?;
            // This pass's cheap failures at or beyond its result are met again by the
            // next pass, if there is one; keep each photon counted once.
            let mut k = pass_start;
            for j in pass_start..rejected.len() {
                if rejected[j] < dist2 {
                    rejected[k] = rejected[j];
                    k += 1;
                }
            }
            rejected.truncate(k);
            if costly(&self.nodes[index as usize]) {
                return Some(Nearest {
                    index,
                    dist2,
                    rank: 1 + rejected.iter().filter(|&&d| d < dist2).count() as u32,
                });
            }
            if set_aside.len() as u32 >= max_refusals {
                return None;
            }
            rejected.push(dist2);
            set_aside.push(index);
            floor = dist2;
        }
    }

    /// Call `f(index, record, dist2)` for every used photon within `max_d2` of `x`.
    pub fn for_each_within(&self, x: Vec3, max_d2: f32, mut f: impl FnMut(u32, &R, f32)) {
        self.search(
            x,
            max_d2,
            visiting(|i, r, d2| {
                f(i, r, d2);
                max_d2
            }),
        );
    }

    /// Depth of the tree (levels; 0 for an empty tree).
    pub fn depth(&self) -> u32 {
        usize::BITS - self.nodes.len().leading_zeros()
    }

    /// Check the kd-tree invariant: every node lies within the half-spaces its
    /// ancestors' splits allow, and split axes are valid exactly where children
    /// exist. O(n). Returns the first violation.
    pub fn verify(&self) -> Result<(), String> {
        let n = self.nodes.len();
        let mut stack = vec![(0usize, [f32::NEG_INFINITY; 3], [f32::INFINITY; 3])];
        while let Some((i, lo, hi)) = stack.pop() {
            if i >= n {
                continue;
            }
            let r = &self.nodes[i];
            let p = r.position().to_array();
            for k in 0..3 {
                if p[k] < lo[k] || p[k] > hi[k] {
                    return Err(format!("photon {i} at {p:?} lies outside its subtree's bounds on axis {k}"));
                }
            }
            let axis = (r.flags() & flags::AXIS_MASK) as usize;
            let has_children = 2 * i + 1 < n;
            if has_children != (axis < 3) {
                return Err(format!(
                    "photon {i}: split axis {axis} but {} children",
                    if has_children { "has" } else { "no" }
                ));
            }
            if axis < 3 {
                let (mut lhi, mut rlo) = (hi, lo);
                lhi[axis] = p[axis];
                rlo[axis] = p[axis];
                stack.push((2 * i + 1, lo, lhi));
                stack.push((2 * i + 2, rlo, hi));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
