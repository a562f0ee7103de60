//! An eight-wide BVH for single rays: nodes of eight children whose boxes one ray
//! tests together (Wald et al. 2008, "Getting Rid of Packets"; Embree's BVH8 for
//! AVX2), built top-down by the binned surface area heuristic and traversed
//! nearest child first. The boxes bound the triangles in world coordinates,
//! padded, and are tested with Ize's (2013) conservative slab test, so a ray
//! through an edge on a node's boundary is not lost.
//!
//! The box test runs on `wide::f32x8`: one AVX register per box row on the
//! x86-64-v3 build, two SSE registers on a baseline x86-64 build (the portable
//! fallback). Both do the same IEEE operations (`maxps`/`minps`, no fused or
//! reordered arithmetic), so both find the same hits; no `unsafe` here. (Plain
//! lane arrays left to the compiler's vectoriser came out as AVX in one
//! traversal and as shuffled SSE in the other.) Eight lanes rather than four
//! shorten the serial chain of node loads a ray waits on (BENCHMARKS.md, issue
//! 55).

use crate::{Bounds, Triangle};
use glam::Vec3;
use wide::f32x8;

/// Children per node: one AVX2 register of f32 per box row.
pub(crate) const WIDTH: usize = 8;

/// Eight children: the box of each (by axis, its min and max, one lane a child;
/// an empty lane's box is inverted so that no ray hits it), and what each is:
/// `count` 0 with `child` a node index, or a leaf of `count` triangle slots from
/// `child` (within one group of four: see `Bvh::node`). 232 bytes, four cache
/// lines with the alignment.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node {
    b: [[f32x8; 2]; 3],
    child: [u32; WIDTH],
    count: [u8; WIDTH],
}

/// Slab-test margin: distances are computed with at most 3 roundings, so the far
/// distance is scaled by 1 + 2 gamma(3) (Ize 2013; pbrt-v4 section 6.8.2).
const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// A triangle's box, padded, and its index: what the builder sorts (28 bytes, the
/// build's only per-triangle scratch besides the tree it writes).
#[derive(Clone, Copy, Debug)]
struct PrimRef {
    lo: Vec3,
    hi: Vec3,
    id: u32,
}

impl PrimRef {
    /// Twice the centroid along axis `a` (the halving does not change the binning).
    #[inline(always)]
    fn centre2(&self, a: usize) -> f32 {
        self.lo[a] + self.hi[a]
    }
}

/// A range of the builder's primitives with their box and the box of their
/// centroids (doubled, as [`PrimRef::centre2`]).
#[derive(Clone, Copy, Debug)]
struct Span {
    start: usize,
    len: usize,
    bounds: Bounds,
    centres: Bounds,
}

/// Bins per axis of the SAH split search.
const BINS: usize = 32;

/// Below this level the builder halves spans at the median (see [`split`]): a
/// lopsided tree past it would cost a deep traversal stack.
pub(crate) const MAX_SAH_LEVEL: usize = 40;

/// Triangles a leaf holds at most: one four-wide test (`geometry::Tri4`).
const LEAF: usize = 4;

/// The bins of a span's centroids along one axis.
struct Binning {
    axis: usize,
    lo: f32,
    scale: f32,
}

impl Binning {
    /// [`BINS`] bins over span `s`'s centroids along axis `a` (whose extent is positive).
    fn new(s: &Span, a: usize) -> Binning {
        Binning { axis: a, lo: s.centres.min[a], scale: BINS as f32 / (s.centres.max[a] - s.centres.min[a]) }
    }

    /// The bin of `p`'s centroid: the one expression both the cost sweep and the
    /// partition use, so they agree on every primitive.
    #[inline(always)]
    fn of(&self, p: &PrimRef) -> usize {
        (((p.centre2(self.axis) - self.lo) * self.scale) as usize).min(BINS - 1)
    }
}

/// The box of `prims` and of their doubled centroids.
fn span_of(prims: &[PrimRef], start: usize) -> Span {
    let (mut bounds, mut centres) = (Bounds::EMPTY, Bounds::EMPTY);
    for p in prims {
        bounds.grow(p.lo, p.hi);
        let c = p.lo + p.hi;
        centres.grow(c, c);
    }
    Span { start, len: prims.len(), bounds, centres }
}

/// Split `s` (more than [`LEAF`] primitives of `prims`) in two by the surface area
/// heuristic over [`BINS`] bins of centroid position on each axis (Wald 2007, "On
/// fast construction of SAH-based bounding volume hierarchies"), costing a side by
/// its groups of four (one four-wide test each, as Embree counts blocks); the
/// primitives are partitioned in place. Where every centroid falls in one bin, the
/// span is halved in its present order; `median` (a deep level, where the heuristic
/// has made a lopsided tree) halves it by centroid along its widest axis instead,
/// which bounds the depth.
fn split(prims: &mut [PrimRef], s: &Span, median: bool) -> (Span, Span) {
    let all = &mut prims[s.start..s.start + s.len];
    let ext = s.centres.max - s.centres.min;
    if median {
        let a = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = all.len() / 2;
        all.select_nth_unstable_by(mid, |p, q| p.centre2(a).total_cmp(&q.centre2(a)));
        let (l, r) = all.split_at(mid);
        return (span_of(l, s.start), span_of(r, s.start + mid));
    }
    let mut best: Option<(f32, usize, usize)> = None;
    for a in 0..3 {
        if !(ext[a] > 0.0) {
            continue;
        }
        let bin = Binning::new(s, a);
        let mut boxes = [Bounds::EMPTY; BINS];
        let mut counts = [0usize; BINS];
        for p in all.iter() {
            let b = bin.of(p);
            boxes[b].grow(p.lo, p.hi);
            counts[b] += 1;
        }
        // Right sides' areas and counts from the last bin down, then sweep the left.
        let mut right = [(0.0f32, 0usize); BINS];
        let (mut acc, mut n) = (Bounds::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.join(boxes[b]);
            n += counts[b];
            right[b] = (acc.half_area(), n);
        }
        let (mut acc, mut n) = (Bounds::EMPTY, 0);
        for b in 1..BINS {
            acc = acc.join(boxes[b - 1]);
            n += counts[b - 1];
            let (ra, rn) = right[b];
            if n == 0 || rn == 0 {
                continue;
            }
            let cost = acc.half_area() * n.div_ceil(LEAF) as f32 + ra * rn.div_ceil(LEAF) as f32;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, a, b));
            }
        }
    }
    let mid = match best {
        Some((_, a, split_bin)) => {
            let bin = Binning::new(s, a);
            let left = |p: &PrimRef| bin.of(p) < split_bin;
            let (mut i, mut j) = (0, all.len());
            while i < j {
                if left(&all[i]) {
                    i += 1;
                } else {
                    j -= 1;
                    all.swap(i, j);
                }
            }
            i
        }
        None => all.len() / 2,
    };
    let (l, r) = all.split_at(mid);
    (span_of(l, s.start), span_of(r, s.start + mid))
}

/// The lanes set in `hit`, ordered by entry distance `t0` (ties in lane order),
/// and how many there are. An insertion sort: most nodes meet one or two
/// children and its branches predict well. (A sorting network over four children
/// took the closest-hit ray 1.1-1.2x as long; picking the least of eight keys
/// that hold distance and lane, one minimum at a time, 1.05-1.2x.)
#[inline(always)]
fn nearest_first(t0: &[f32; WIDTH], hit: u32) -> ([usize; WIDTH], usize) {
    let mut order = [0usize; WIDTH];
    let mut k = 0;
    let mut m = hit;
    while m != 0 {
        let i = m.trailing_zeros() as usize;
        m &= m - 1;
        let mut j = k;
        while j > 0 && t0[order[j - 1]] > t0[i] {
            order[j] = order[j - 1];
            j -= 1;
        }
        order[j] = i;
        k += 1;
    }
    (order, k)
}

/// Run `f` with a traversal stack of at least `need` entries: on the call stack in
/// one of a few sizes (a fixed large array cost a 1.5 kB memset per ray, 5% of a
/// ray's time), on the heap past them.
#[inline(always)]
fn with_stack<T: Copy + Default, R>(need: usize, f: impl FnOnce(&mut [T]) -> R) -> R {
    if need <= 32 {
        f(&mut [T::default(); 32])
    } else if need <= 64 {
        f(&mut [T::default(); 64])
    } else if need <= 128 {
        f(&mut [T::default(); 128])
    } else {
        f(&mut vec![T::default(); need])
    }
}

/// The tree; leaves refer to triangle slots, whose order [`Bvh::slots`] gives.
/// The default is the empty tree, which no ray hits.
#[derive(Clone, Debug, Default)]
pub(crate) struct Bvh {
    nodes: Vec<Node>,
    /// Index into the caller's triangles of each slot.
    slots: Vec<u32>,
    /// Most stack entries a traversal can need (WIDTH - 1 per level below the
    /// root, plus one).
    stack_need: usize,
}

/// A ray prepared for box tests: origin, reciprocal direction (a zero component
/// gives a huge finite value, so no 0 x inf arises), and which of each axis's two
/// planes (min 0, max 1) the ray meets first.
struct BoxRay {
    o: [f32; 3],
    inv: [f32; 3],
    near: [usize; 3],
}

impl BoxRay {
    fn new(o: Vec3, d: Vec3) -> BoxRay {
        let inv = d.to_array().map(|c| if c == 0.0 { 1e30 } else { 1.0 / c });
        let near = inv.map(|c| (c < 0.0) as usize);
        BoxRay { o: o.to_array(), inv, near }
    }

    /// Entry distances of the children and which of them the ray meets within
    /// (0, t_max], as a bit mask (bit i: child i).
    #[inline(always)]
    fn test(&self, n: &Node, t_max: f32) -> ([f32; WIDTH], u32) {
        let mut t0 = f32x8::ZERO;
        let mut t1 = f32x8::splat(t_max);
        for a in 0..3 {
            let (o, inv) = (f32x8::splat(self.o[a]), f32x8::splat(self.inv[a]));
            let near = self.near[a] & 1;
            // No NaN arises (the rows are finite or infinite, the origin finite), so
            // max and min pick as comparisons would, up to the sign of a zero.
            t0 = t0.fast_max((n.b[a][near] - o) * inv);
            t1 = t1.fast_min((n.b[a][near ^ 1] - o) * inv);
        }
        (t0.to_array(), t0.simd_le(t1 * f32x8::splat(ROBUST)).to_bitmask())
    }
}

impl Bvh {
    /// Bytes its nodes and slot ids hold (their capacities).
    pub(crate) fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>() + self.slots.capacity() * 4
    }

    /// The tree over `tris`, built top-down by the surface area heuristic (see
    /// [`split`]) straight into eight-wide nodes: a node's span is split in two,
    /// then the lane of largest surface area with more than [`LEAF`] triangles is
    /// split again, until there are [`WIDTH`] lanes or only leaves (as Embree's
    /// wide builders and Wald et al. 2008 collapse a binary tree). Child boxes bound
    /// the triangles' vertices padded by `pad` [m]. The build holds 28 bytes a
    /// triangle of scratch beside the tree (issue 36: obvhs's PLOC build held about
    /// 190).
    pub(crate) fn build(tris: &[Triangle], pad: f32) -> Bvh {
        let mut out = Bvh { nodes: Vec::new(), slots: Vec::new(), stack_need: 1 };
        if tris.is_empty() {
            return out;
        }
        let mut prims: Vec<PrimRef> = tris
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let [a, b, c] = t.p;
                PrimRef { lo: a.min(b).min(c) - pad, hi: a.max(b).max(c) + pad, id: i as u32 }
            })
            .collect();
        // Every inner node has at least two lanes, so there are fewer inner nodes
        // than leaves; a full tree has about (leaves - 1) / (WIDTH - 1).
        out.nodes.reserve(tris.len().div_ceil(LEAF * (WIDTH - 1)) + 1);
        out.slots.reserve_exact(tris.len() + tris.len() / 4);
        let root = span_of(&prims, 0);
        let mut depth = 0;
        out.node(&mut prims, root, 1, &mut depth);
        drop(prims);
        out.nodes.shrink_to_fit();
        out.slots.shrink_to_fit();
        out.stack_need = (WIDTH - 1) * depth + 1;
        out
    }

    /// Levels below and including the root.
    #[cfg(test)]
    pub(crate) fn depth(&self) -> usize {
        (self.stack_need - 1) / (WIDTH - 1)
    }

    /// Index into the caller's triangles of each slot.
    pub(crate) fn slots(&self) -> &[u32] {
        &self.slots
    }

    /// Build the node over span `s` of `prims` and its subtree (level `level`, the
    /// root 1); returns its index. Leaves take their slots as they are met, in lane
    /// order depth first.
    fn node(&mut self, prims: &mut [PrimRef], s: Span, level: usize, depth: &mut usize) -> u32 {
        *depth = (*depth).max(level);
        let deep = level > MAX_SAH_LEVEL;
        let mut lanes = if s.len <= LEAF {
            vec![s]
        } else {
            let (l, r) = split(prims, &s, deep);
            vec![l, r]
        };
        while lanes.len() < WIDTH {
            let open = lanes
                .iter()
                .enumerate()
                .filter(|(_, l)| l.len > LEAF)
                .max_by(|a, b| a.1.bounds.half_area().total_cmp(&b.1.bounds.half_area()))
                .map(|(i, _)| i);
            let Some(i) = open else { break };
            let (l, r) = split(prims, &lanes[i], deep);
            lanes[i] = r;
            lanes.insert(i, l);
        }
        let index = self.nodes.len();
        let empty = [f32x8::splat(f32::INFINITY), f32x8::splat(f32::NEG_INFINITY)];
        self.nodes.push(Node { b: [empty; 3], child: [0; WIDTH], count: [0; WIDTH] });
        for (lane, l) in lanes.iter().enumerate() {
            let (child, count) = if l.len <= LEAF {
                // A leaf (at most four triangles) never straddles two groups of four,
                // so it takes one four-wide test: it starts the next group when it
                // does not fit in what is left of this one. (Packed without this, a
                // straddling leaf took two, and eye rays in the instanced scene took
                // 1.37 times as long; padding every leaf to a group start held 58
                // bytes of positions per triangle instead of 36-40.)
                let used = self.slots.len() % 4;
                if used != 0 && used + l.len > 4 {
                    let last = self.slots[self.slots.len() - 1];
                    self.slots.resize(self.slots.len() + 4 - used, last);
                }
                let first = self.slots.len() as u32;
                self.slots.extend(prims[l.start..l.start + l.len].iter().map(|p| p.id));
                (first, l.len as u8)
            } else {
                (self.node(prims, *l, level + 1, depth), 0)
            };
            let n = &mut self.nodes[index];
            n.child[lane] = child;
            n.count[lane] = count;
            for a in 0..3 {
                n.b[a][0].as_mut_array()[lane] = l.bounds.min[a];
                n.b[a][1].as_mut_array()[lane] = l.bounds.max[a];
            }
        }
        index as u32
    }

    /// The closest hit along the ray from `o` in direction `d` within (0, t_max):
    /// `test(first, count, t)` intersects the triangles of a leaf's slots `first..
    /// first + count` and returns the slot and distance of the nearest hit below t.
    /// Returns the slot and distance.
    #[inline]
    pub(crate) fn closest(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        mut test: impl FnMut(u32, u32, f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best: Option<(u32, f32)> = None;
        let mut t_best = t_max;
        let ray = BoxRay::new(o, d);
        let visit = |stack: &mut [(u32, f32)]| {
            let mut top = 1;
            stack[0] = (0, 0.0);
            while top > 0 {
                top -= 1;
                let (node, t_enter) = stack[top];
                if t_enter > t_best * ROBUST {
                    continue;
                }
                let n = &self.nodes[node as usize];
                let (t0, hit) = ray.test(n, t_best);
                // Leaves are tested as they come, nearest first (each hit
                // shortens the reach); inner nodes within reach are pushed after,
                // so that the nearest is popped next.
                let (order, k) = nearest_first(&t0, hit);
                for &i in &order[..k] {
                    if n.count[i] > 0
                        && t0[i] <= t_best * ROBUST
                        && let Some((s, t)) = test(n.child[i], n.count[i] as u32, t_best)
                    {
                        t_best = t;
                        best = Some((s, t));
                    }
                }
                for &i in order[..k].iter().rev() {
                    if n.count[i] == 0 && t0[i] <= t_best * ROBUST {
                        stack[top] = (n.child[i], t0[i]);
                        top += 1;
                    }
                }
            }
        };
        with_stack(self.stack_need, visit);
        best
    }

    /// True when `test(first, count, t_max)` finds a triangle among a leaf's slots
    /// along the ray from `o` in direction `d` within (0, t_max) (any one: the
    /// search stops there).
    #[inline]
    pub(crate) fn any(&self, o: Vec3, d: Vec3, t_max: f32, mut test: impl FnMut(u32, u32, f32) -> bool) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let ray = BoxRay::new(o, d);
        let visit = |stack: &mut [u32]| {
            let mut top = 1;
            stack[0] = 0;
            while top > 0 {
                top -= 1;
                let n = &self.nodes[stack[top] as usize];
                // Any order will do: sorting the children by distance, as the
                // closest hit does, took shadow rays 1.25-1.4x as long.
                let (_, mut hit) = ray.test(n, t_max);
                while hit != 0 {
                    let i = hit.trailing_zeros() as usize;
                    hit &= hit - 1;
                    if n.count[i] == 0 {
                        stack[top] = n.child[i];
                        top += 1;
                    } else if test(n.child[i], n.count[i] as u32, t_max) {
                        return true;
                    }
                }
            }
            false
        };
        with_stack(self.stack_need, visit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The eight-lane box test gives, lane by lane and bit for bit, what the slab
    /// test computed one child at a time in scalar f32 gives (entry distance and
    /// hit), for boxes that are thin, empty (inverted), unbounded or behind the
    /// ray, and for directions along an axis (reciprocal 1e30). That is what makes
    /// an AVX, an SSE (the baseline x86-64 build of `wide`) and a scalar build
    /// find the same children.
    #[test]
    fn eight_lane_box_test_equals_scalar_slabs_bit_for_bit() {
        let mut s = pm_sampling::Sampler::hashed(21, 0);
        let mut u = || 4.0 * s.next_1d() - 2.0;
        let mut hits = 0;
        for case in 0..20_000 {
            let mut n = Node {
                b: [[f32x8::splat(f32::INFINITY), f32x8::splat(f32::NEG_INFINITY)]; 3],
                child: [0; WIDTH],
                count: [0; WIDTH],
            };
            for lane in 0..WIDTH {
                for a in 0..3 {
                    let (x, w) = (u(), u().abs() * [1.0, 0.0, 1e-7, 3.0][(case + lane + a) % 4]);
                    let (lo, hi) = match (case + lane) % 11 {
                        0 => (f32::INFINITY, f32::NEG_INFINITY),
                        1 => (f32::NEG_INFINITY, f32::INFINITY),
                        _ => (x, x + w),
                    };
                    n.b[a][0].as_mut_array()[lane] = lo;
                    n.b[a][1].as_mut_array()[lane] = hi;
                }
            }
            let o = Vec3::new(u(), u(), u());
            let mut d = Vec3::new(u(), u(), u());
            if case % 5 == 0 {
                d[case % 3] = 0.0;
            }
            let t_max = if case % 3 == 0 { f32::INFINITY } else { u().abs() * 3.0 };
            let ray = BoxRay::new(o, d);
            let (t0, hit) = ray.test(&n, t_max);
            for (lane, &t0) in t0.iter().enumerate() {
                let (mut e, mut x) = (0.0f32, t_max);
                for a in 0..3 {
                    let row = |r: usize| n.b[a][r].as_array()[lane];
                    let near = ray.near[a];
                    let (te, tx) = ((row(near) - ray.o[a]) * ray.inv[a], (row(near ^ 1) - ray.o[a]) * ray.inv[a]);
                    e = if e > te { e } else { te };
                    x = if x < tx { x } else { tx };
                }
                assert_eq!(t0.to_bits(), e.to_bits(), "case {case}, lane {lane}: entry");
                assert_eq!(hit >> lane & 1 == 1, e <= x * ROBUST, "case {case}, lane {lane}: hit");
                hits += hit >> lane & 1;
            }
        }
        assert!(hits > 10_000, "too few lanes hit to mean anything: {hits}");
    }

    /// A tree whose nodes use all eight lanes, over randomly placed triangles of
    /// many sizes: closest hits and occlusion of random segments equal a test of
    /// every triangle.
    #[test]
    fn full_eight_lane_nodes_find_what_every_triangle_test_finds() {
        let mut s = pm_sampling::Sampler::hashed(22, 0);
        let mut u = || 2.0 * s.next_1d() - 1.0;
        let tris: Vec<Triangle> = (0..600)
            .filter_map(|i| {
                let c = Vec3::new(u(), u(), u()) * 3.0;
                let size = [0.02, 0.2, 1.0][i % 3];
                Triangle::new([0, 1, 2].map(|_| c + Vec3::new(u(), u(), u()) * size), 0)
            })
            .collect();
        let bvh = Bvh::build(&tris, 0.0);
        let full = |n: &Node| n.b[0][0].as_array().iter().all(|x| x.is_finite());
        let n_full = bvh.nodes.iter().filter(|n| full(n)).count();
        assert!(full(&bvh.nodes[0]) && n_full >= 5, "{n_full} of {} nodes have all eight lanes", bvh.nodes.len());
        let (slots, tris) = (bvh.slots(), &tris);
        let leaf_test = |o: Vec3, d: Vec3| {
            let ray = crate::TriangleRay::new(o, d);
            move |first: u32, count: u32, t_max: f32| {
                let mut best: Option<(u32, f32)> = None;
                for slot in first..first + count {
                    let limit = best.map_or(t_max, |b| b.1);
                    if let Some((t, _)) = ray.hit(&tris[slots[slot as usize] as usize].p, limit) {
                        best = Some((slot, t));
                    }
                }
                best
            }
        };
        let mut blocked = 0;
        for _ in 0..3000 {
            let o = Vec3::new(u(), u(), u()) * 4.0;
            let d = Vec3::new(u(), u(), u()).normalize_or(Vec3::X);
            let ray = crate::TriangleRay::new(o, d);
            let want =
                tris.iter().filter_map(|t| ray.hit(&t.p, f32::INFINITY)).map(|h| h.0).fold(f32::INFINITY, f32::min);
            let got = bvh.closest(o, d, f32::INFINITY, leaf_test(o, d)).map_or(f32::INFINITY, |h| h.1);
            assert_eq!(got, want, "ray from {o} along {d}");
            let t = 2.0 * u().abs();
            let any = leaf_test(o, d);
            let occluded = bvh.any(o, d, t, |first, count, t_max| any(first, count, t_max).is_some());
            assert_eq!(occluded, want < t, "segment from {o} along {d} to {t}");
            blocked += occluded as u32;
        }
        assert!(blocked > 300, "too few segments blocked to mean anything: {blocked}");
    }
}
