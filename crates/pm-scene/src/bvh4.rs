//! A four-wide BVH for single rays: obvhs's binary BVH (PLOC build with
//! reinsertion; Meister and Bittner 2018) collapsed into nodes of four children
//! whose boxes one ray tests together (Wald et al. 2008, "Getting Rid of Packets"),
//! traversed nearest child first. The boxes are recomputed from the triangles in
//! world coordinates, padded, and tested with Ize's (2013) conservative slab test,
//! so a ray through an edge on a node's boundary is not lost.

use crate::Triangle;
use glam::{Vec3, Vec4};

/// Four children: the box of each (min x, y, z, then max x, y, z, one lane a
/// child; an empty lane's box is inverted so that no ray hits it), and what each
/// is: `count` 0 with `child` a node index, or a leaf of `count` triangle slots
/// from `child` (a multiple of four).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node4 {
    b: [Vec4; 6],
    child: [u32; 4],
    count: [u32; 4],
}

/// Slab-test margin: distances are computed with at most 3 roundings, so the far
/// distance is scaled by 1 + 2 gamma(3) (Ize 2013; pbrt-v4 section 6.8.2).
const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

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
/// gives a huge finite value, so no 0 x inf arises), and each axis's near and far
/// planes among a node's six rows.
struct BoxRay {
    o: [f32; 3],
    inv: [f32; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl BoxRay {
    fn new(o: Vec3, d: Vec3) -> BoxRay {
        let inv = d.to_array().map(|c| if c == 0.0 { 1e30 } else { 1.0 / c });
        let near = [0, 1, 2].map(|a| if inv[a] < 0.0 { a + 3 } else { a });
        let far = [0, 1, 2].map(|a| if inv[a] < 0.0 { a } else { a + 3 });
        BoxRay { o: o.to_array(), inv, near, far }
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
            t0 = t0.max((n.b[self.near[a]] - o) * inv);
            t1 = t1.min((n.b[self.far[a]] - o) * inv);
        }
        (t0, t0.cmple(t1 * ROBUST).bitmask())
    }
}

impl Bvh4 {
    /// Bytes its nodes and slot ids hold (their capacities).
    pub(crate) fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node4>() + self.slots.capacity() * 4
    }

    /// Collapse `bvh` (over boxes of the triangles `tris`, in any coordinates) into
    /// four-wide nodes whose boxes bound `tris`'s vertices padded by `pad` [m].
    pub(crate) fn new(bvh: &obvhs::bvh2::Bvh2, tris: &[Triangle], pad: f32) -> Bvh4 {
        let mut out = Bvh4 { nodes: Vec::new(), slots: Vec::new(), stack_need: 1 };
        if bvh.nodes.is_empty() || tris.is_empty() {
            return out;
        }
        let mut depth = 0;
        out.collapse(bvh, 0, tris, pad, 1, &mut depth);
        out.stack_need = 3 * depth + 1;
        out
    }

    /// Index into the caller's triangles of each slot.
    pub(crate) fn slots(&self) -> &[u32] {
        &self.slots
    }

    /// Build the four-wide node for binary node `b2` (its children, and theirs, up to
    /// four); returns its index and box.
    fn collapse(
        &mut self,
        bvh: &obvhs::bvh2::Bvh2,
        b2: usize,
        tris: &[Triangle],
        pad: f32,
        level: usize,
        depth: &mut usize,
    ) -> (u32, [Vec3; 2]) {
        *depth = (*depth).max(level);
        let node = &bvh.nodes[b2];
        // The lanes: a binary leaf as root is one leaf lane; otherwise open the inner
        // child of largest surface area until there are four or only leaves.
        let mut lanes: Vec<usize> =
            if node.prim_count > 0 { vec![b2] } else { vec![node.first_index as usize, node.first_index as usize + 1] };
        while lanes.len() < 4 {
            let open = lanes
                .iter()
                .enumerate()
                .filter(|&(_, &c)| bvh.nodes[c].prim_count == 0)
                .max_by(|a, b| bvh.nodes[*a.1].aabb.half_area().total_cmp(&bvh.nodes[*b.1].aabb.half_area()))
                .map(|(i, _)| i);
            let Some(i) = open else { break };
            let c = lanes.remove(i);
            let first = bvh.nodes[c].first_index as usize;
            lanes.insert(i, first + 1);
            lanes.insert(i, first);
        }
        let index = self.nodes.len();
        self.nodes.push(Node4 {
            b: [
                Vec4::INFINITY,
                Vec4::INFINITY,
                Vec4::INFINITY,
                Vec4::NEG_INFINITY,
                Vec4::NEG_INFINITY,
                Vec4::NEG_INFINITY,
            ],
            child: [0; 4],
            count: [0; 4],
        });
        let mut whole = [Vec3::INFINITY, Vec3::NEG_INFINITY];
        for (lane, &c) in lanes.iter().enumerate() {
            let cn = &bvh.nodes[c];
            let (child, count, bx) = if cn.prim_count > 0 {
                // A leaf (at most four triangles) never straddles two groups of four,
                // so it takes one four-wide test: it starts the next group when it
                // does not fit in what is left of this one. (Packed without this, a
                // straddling leaf took two, and eye rays in the instanced scene took
                // 1.37 times as long; padding every leaf to a group start held 58
                // bytes of positions per triangle instead of 36-40.)
                let used = self.slots.len() % 4;
                if used != 0 && used + cn.prim_count as usize > 4 {
                    let last = self.slots[self.slots.len() - 1];
                    self.slots.resize(self.slots.len() + 4 - used, last);
                }
                let first = self.slots.len() as u32;
                let mut bx = [Vec3::INFINITY, Vec3::NEG_INFINITY];
                for k in cn.first_index..cn.first_index + cn.prim_count {
                    let t = bvh.primitive_indices[k as usize];
                    self.slots.push(t);
                    for p in tris[t as usize].p {
                        bx = [bx[0].min(p - pad), bx[1].max(p + pad)];
                    }
                }
                (first, cn.prim_count, bx)
            } else {
                let (i, bx) = self.collapse(bvh, c, tris, pad, level + 1, depth);
                (i, 0, bx)
            };
            let n = &mut self.nodes[index];
            n.child[lane] = child;
            n.count[lane] = count;
            for (a, (lo, hi)) in bx[0].to_array().into_iter().zip(bx[1].to_array()).enumerate() {
                n.b[a][lane] = lo;
                n.b[a + 3][lane] = hi;
            }
            whole = [whole[0].min(bx[0]), whole[1].max(bx[1])];
        }
        (index as u32, whole)
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
                // at once, inner nodes pushed so the nearest is popped next.
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
