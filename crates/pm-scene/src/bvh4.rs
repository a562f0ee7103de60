//! A four-wide BVH for single rays: nodes of four children whose boxes one ray
//! tests together (Wald et al. 2008, "Getting Rid of Packets"), built top-down by
//! the binned surface area heuristic and traversed nearest child first. The boxes
//! bound the triangles in world coordinates, padded, and are tested with Ize's
//! (2013) conservative slab test, so a ray through an edge on a node's boundary is
//! not lost.

use crate::{Bounds, Triangle};
use glam::{Vec3, Vec4};

/// Four children: the box of each (by axis, its min and max, one lane a child;
/// an empty lane's box is inverted so that no ray hits it), and what each is:
/// `count` 0 with `child` a node index, or a leaf of `count` triangle slots from
/// `child` (within one group of four: see `Bvh4::node`).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node4 {
    b: [[Vec4; 2]; 3],
    child: [u32; 4],
    count: [u32; 4],
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

/// The tree; leaves refer to triangle slots, whose order [`Bvh4::slots`] gives.
/// The default is the empty tree, which no ray hits.
#[derive(Clone, Debug, Default)]
pub(crate) struct Bvh4 {
    nodes: Vec<Node4>,
    /// Index into the caller's triangles of each slot.
    slots: Vec<u32>,
    /// Most stack entries a traversal can need (3 per level below the root, plus one).
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

    /// Entry distances of the four children and which of them the ray meets within
    /// (0, t_max], as a bit mask (bit i: child i).
    #[inline(always)]
    fn test(&self, n: &Node4, t_max: f32) -> (Vec4, u32) {
        let mut t0 = Vec4::ZERO;
        let mut t1 = Vec4::splat(t_max);
        for a in 0..3 {
            let (o, inv) = (Vec4::splat(self.o[a]), Vec4::splat(self.inv[a]));
            // No NaN arises (the rows are finite or infinite, the origin finite), so
            // max and min pick as comparisons would, up to the sign of a zero.
            let near = self.near[a] & 1;
            t0 = t0.max((n.b[a][near] - o) * inv);
            t1 = t1.min((n.b[a][near ^ 1] - o) * inv);
        }
        (t0, t0.cmple(t1 * ROBUST).bitmask())
    }
}

impl Bvh4 {
    /// Bytes its nodes and slot ids hold (their capacities).
    pub(crate) fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node4>() + self.slots.capacity() * 4
    }

    /// The tree over `tris`, built top-down by the surface area heuristic (see
    /// [`split`]) straight into four-wide nodes: a node's span is split in two, then
    /// the lane of largest surface area with more than [`LEAF`] triangles is split
    /// again, until there are four lanes or only leaves (as Embree's wide builders
    /// and Wald et al. 2008 collapse a binary tree). Child boxes bound the triangles'
    /// vertices padded by `pad` [m]. The build holds 28 bytes a triangle of scratch
    /// beside the tree (issue 36: obvhs's PLOC build held about 190).
    pub(crate) fn build(tris: &[Triangle], pad: f32) -> Bvh4 {
        let mut out = Bvh4 { nodes: Vec::new(), slots: Vec::new(), stack_need: 1 };
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
        // A four-wide tree over n leaves has at most (n - 1) / 3 + 1 inner nodes.
        out.nodes.reserve_exact(tris.len().div_ceil(3) + 1);
        out.slots.reserve_exact(tris.len() + tris.len() / 4);
        let root = span_of(&prims, 0);
        let mut depth = 0;
        out.node(&mut prims, root, 1, &mut depth);
        drop(prims);
        out.nodes.shrink_to_fit();
        out.slots.shrink_to_fit();
        out.stack_need = 3 * depth + 1;
        out
    }

    /// Levels below and including the root.
    #[cfg(test)]
    pub(crate) fn depth(&self) -> usize {
        (self.stack_need - 1) / 3
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
        while lanes.len() < 4 {
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
        self.nodes.push(Node4 { b: [[Vec4::INFINITY, Vec4::NEG_INFINITY]; 3], child: [0; 4], count: [0; 4] });
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
                (first, l.len as u32)
            } else {
                (self.node(prims, *l, level + 1, depth), 0)
            };
            let n = &mut self.nodes[index];
            n.child[lane] = child;
            n.count[lane] = count;
            for a in 0..3 {
                n.b[a][0][lane] = l.bounds.min[a];
                n.b[a][1][lane] = l.bounds.max[a];
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
                // Children met, nearest first (ties in lane order): leaves are tested
                // at once, inner nodes pushed so the nearest is popped next. (An
                // insertion sort: most nodes meet one or two children, and a sorting
                // network over all four took the closest-hit ray 1.1-1.2x as long.)
                let t0 = t0.to_array();
                let mut order = [0usize; 4];
                let mut k = 0;
                for i in 0..4 {
                    if hit & (1 << i) == 0 {
                        continue;
                    }
                    let mut j = k;
                    while j > 0 && t0[order[j - 1]] > t0[i] {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = i;
                    k += 1;
                }
                for &i in order[..k].iter().rev() {
                    if n.count[i] == 0 {
                        stack[top] = (n.child[i], t0[i]);
                        top += 1;
                    }
                }
                for &i in &order[..k] {
                    if n.count[i] > 0
                        && t0[i] <= t_best * ROBUST
                        && let Some((s, t)) = test(n.child[i], n.count[i], t_best)
                    {
                        t_best = t;
                        best = Some((s, t));
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
                let (_, mut hit) = ray.test(n, t_max);
                while hit != 0 {
                    let i = hit.trailing_zeros() as usize;
                    hit &= hit - 1;
                    if n.count[i] == 0 {
                        stack[top] = n.child[i];
                        top += 1;
                    } else if test(n.child[i], n.count[i], t_max) {
                        return true;
                    }
                }
            }
            false
        };
        with_stack(self.stack_need, visit)
    }
}
