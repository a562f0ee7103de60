//! Photons as spheres for the beam radiance estimate (Jarosz, Zwicker and Jensen
//! 2008, "The beam radiance estimate for volumetric photon mapping", section 4):
//! every photon with its own radius, in a bounding-volume hierarchy of the spheres,
//! queried with a ray segment for every photon whose sphere the segment passes
//! through.

use glam::Vec3;

/// Photons per leaf of the hierarchy.
const LEAF: usize = 4;

/// A bounding-volume hierarchy over spheres (photon positions and radii), built
/// by median splits on the axis of largest extent; queries visit nodes in a fixed
/// order, so sums over what they find are deterministic.
#[derive(Clone, Debug, Default)]
pub struct SphereTree {
    /// Nodes: bounds of their spheres, and either two children or a range of
    /// `order`.
    nodes: Vec<Node>,
    /// Photon indices in leaf order.
    order: Vec<u32>,
    /// Centres \[m\], by photon index.
    centres: Vec<Vec3>,
    /// Squared radii [m^2], by photon index.
    radii2: Vec<f32>,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// For a leaf, `order[first..first + count]`; for an inner node, `first` is the
    /// left child's index (the right child follows its subtree) and `count` 0.
    first: u32,
    count: u32,
    /// For an inner node, the right child's index.
    right: u32,
}

impl SphereTree {
    /// The hierarchy over spheres of centres `centres` \[m\] and radii `radii` \[m\]
    /// (one per photon; a radius of zero leaves the photon out).
    pub fn new(centres: &[Vec3], radii: &[f32]) -> SphereTree {
        let mut order: Vec<u32> = (0..centres.len() as u32).filter(|&i| radii[i as usize] > 0.0).collect();
        let mut t = SphereTree {
            nodes: Vec::new(),
            order: Vec::new(),
            centres: centres.to_vec(),
            radii2: radii.iter().map(|r| r * r).collect(),
        };
        if !order.is_empty() {
            let n = order.len();
            t.build(&mut order, 0, n, radii);
        }
        t.order = order;
        t
    }

    /// Photon `i`'s centre \[m\] and radius \[m\] (zero: left out).
    pub fn sphere(&self, i: usize) -> (Vec3, f32) {
        (self.centres[i], self.radii2[i].sqrt())
    }

    /// Photons in the hierarchy.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// True when it holds no photon.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    fn build(&mut self, order: &mut [u32], start: usize, end: usize, radii: &[f32]) -> u32 {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (mut clo, mut chi) = (lo, hi);
        for &i in &order[start..end] {
            let (c, r) = (self.centres[i as usize], radii[i as usize]);
            lo = lo.min(c - Vec3::splat(r));
            hi = hi.max(c + Vec3::splat(r));
            clo = clo.min(c);
            chi = chi.max(c);
        }
        let id = self.nodes.len() as u32;
        self.nodes.push(Node { lo, hi, first: start as u32, count: (end - start) as u32, right: 0 });
        if end - start <= LEAF {
            return id;
        }
        let ext = chi - clo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = start + (end - start) / 2;
        let centres = &self.centres;
        order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            centres[a as usize][axis].total_cmp(&centres[b as usize][axis]).then(a.cmp(&b))
        });
        let left = self.build(order, start, mid, radii);
        let right = self.build(order, mid, end, radii);
        self.nodes[id as usize] = Node { lo, hi, first: left, count: 0, right };
        id
    }

    /// Call `f(photon, t, d2, r2)` for every photon whose sphere the segment from
    /// `o` along unit `d` over [0, `t_max`] passes through (its chord through the
    /// sphere, [t - h, t + h] with h = sqrt(r2 - d2), overlaps the segment): t the
    /// distance along the ray to the point of closest approach \[m\] (which may lie
    /// outside the segment), d2 the squared distance of the photon from the ray and
    /// r2 its squared radius [m^2] (d2 < r2). `stack` is scratch.
    pub fn for_each_crossed(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        stack: &mut Vec<u32>,
        mut f: impl FnMut(u32, f32, f32, f32),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        // No zero component (0 x inf would be NaN in the slab test).
        let inv = Vec3::ONE / Vec3::select(d.abs().cmplt(Vec3::splat(1e-20)), Vec3::splat(1e-20), d);
        stack.clear();
        stack.push(0);
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            // Slab test against the node's bounds.
            let t0 = (node.lo - o) * inv;
            let t1 = (node.hi - o) * inv;
            let near = t0.min(t1).max_element().max(0.0);
            let far = t0.max(t1).min_element().min(t_max);
            if !(near <= far) {
                continue;
            }
            if node.count > 0 {
                for &i in &self.order[node.first as usize..(node.first + node.count) as usize] {
                    let v = self.centres[i as usize] - o;
                    let t = v.dot(d);
                    let d2 = (v - d * t).length_squared();
                    let r2 = self.radii2[i as usize];
                    if d2 < r2 {
                        let h = (r2 - d2).sqrt();
                        if t + h >= 0.0 && t - h <= t_max {
                            f(i, t, d2, r2);
                        }
                    }
                }
            } else {
                // Right pushed first: the left subtree is visited first.
                stack.push(node.right);
                stack.push(node.first);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pm_sampling::Sampler;

    /// Every sphere a segment crosses is found once, and nothing else, against a
    /// scan of all spheres, for random segments (some axis-aligned) through a cloud
    /// of spheres of mixed radii.
    #[test]
    fn finds_exactly_the_spheres_a_segment_crosses() {
        let n = 3000;
        let mut s = Sampler::new(7, 0);
        let centres: Vec<Vec3> = (0..n).map(|_| Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 2.0).collect();
        let radii: Vec<f32> = (0..n).map(|i| if i % 10 == 0 { 0.0 } else { 0.01 + 0.1 * s.next_1d() }).collect();
        let tree = SphereTree::new(&centres, &radii);
        assert_eq!(tree.len(), n - n / 10);
        let mut stack = Vec::new();
        for q in 0..200 {
            let mut s = Sampler::new(8, q);
            let o = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 2.0;
            let d = match q % 4 {
                0 => Vec3::X,
                1 => Vec3::NEG_Z,
                _ => pm_sampling::uniform_sphere(s.next_2d()),
            };
            let t_max = 3.0 * s.next_1d();
            let mut found = Vec::new();
            tree.for_each_crossed(o, d, t_max, &mut stack, |i, t, d2, _| found.push((i, t, d2)));
            found.sort_by_key(|f| f.0);
            let mut want = Vec::new();
            for i in 0..n {
                let v = centres[i] - o;
                let t = v.dot(d);
                let d2 = (v - d * t).length_squared();
                let r2 = radii[i] * radii[i];
                let h = (r2 - d2).max(0.0).sqrt();
                if radii[i] > 0.0 && d2 < r2 && t + h >= 0.0 && t - h <= t_max {
                    want.push((i as u32, t, d2));
                }
            }
            assert_eq!(found, want, "segment {q}");
        }
    }
}
