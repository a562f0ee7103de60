//! Choosing a light for a shading point by a tree of light bounds: the many-light
//! sampler of Conty Estevez and Kulla 2018 ("Importance sampling of many lights
//! with adaptive tree splitting") in pbrt-v4's form (`BVHLightSampler`, section
//! 12.6.3). Each node bounds its lights' positions (a box), emission directions
//! (a cone about `w` of half-angle theta_o, light leaving within theta_e beyond
//! it) and power; a point's importance for a node is the power over the squared
//! distance times the least emission and incidence cosines any light in it can
//! have toward the point. A sample walks from the root choosing a child in
//! proportion to its importance; the probability of a light at a point is the
//! product of those choices along its path. Lights at infinity are chosen apart
//! from the tree, uniformly, each as likely as the whole tree. An emissive mesh
//! of several triangles is in the tree triangle by triangle, each with its share
//! of the mesh's power, so that the triangles near a point are chosen there.

use glam::Vec3;
use pm_scene::{LightKind, Scene};
use std::f32::consts::{FRAC_PI_2, PI};

/// What a light, or a node's lights, can send toward a point at most.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LightBounds {
    /// The box of the emitting points [m].
    lo: Vec3,
    hi: Vec3,
    /// Emitted power [W, channels summed].
    phi: f32,
    /// The axis of the emission directions' cone (unit).
    w: Vec3,
    /// cos theta_o: the cone's half-angle (-1: every direction).
    cos_o: f32,
    /// cos theta_e: how far past the cone light still leaves (0 for a surface's
    /// hemisphere of emission).
    cos_e: f32,
    /// Light leaves both ways along the axis (a two-sided emitter).
    two_sided: bool,
}

/// cos(max(0, a - b)) from the cosines and sines of a and b (angles in [0, pi]).
#[inline]
fn cos_sub_clamped(cos_a: f32, sin_a: f32, cos_b: f32, sin_b: f32) -> (f32, f32) {
    if cos_a > cos_b {
        (1.0, 0.0) // a < b
    } else {
        (cos_a * cos_b + sin_a * sin_b, (sin_a * cos_b - cos_a * sin_b).max(0.0))
    }
}

impl LightBounds {
    /// The bounds of light `li` of `scene`; None for lights at infinity and for
    /// lights that emit nothing.
    fn of(scene: &Scene, li: usize) -> Option<LightBounds> {
        let light = &scene.lights[li];
        let phi = light.power.element_sum();
        if !(phi > 0.0) || !phi.is_finite() {
            return None;
        }
        Some(match &light.kind {
            LightKind::Point { position, .. } => {
                LightBounds { lo: *position, hi: *position, phi, w: Vec3::Z, cos_o: -1.0, cos_e: 0.0, two_sided: false }
            }
            LightKind::Spot { position, direction, cos_inner, cos_outer, .. } => {
                // Full intensity within the inner cone, falling to zero at the outer.
                let theta_e = (cos_outer.clamp(-1.0, 1.0).acos() - cos_inner.clamp(-1.0, 1.0).acos()).max(0.0);
                LightBounds {
                    lo: *position,
                    hi: *position,
                    phi,
                    w: *direction,
                    cos_o: *cos_inner,
                    cos_e: theta_e.cos(),
                    two_sided: false,
                }
            }
            LightKind::Area { tris, two_sided, .. } => {
                let t = &scene.triangles[tris.start as usize..tris.end as usize];
                Self::of_triangles(t, phi, *two_sided)
            }
            _ => return None,
        })
    }

    /// The bounds of emitting triangles `t` of power `phi` [W], one- or two-sided.
    fn of_triangles(t: &[pm_scene::Triangle], phi: f32, two_sided: bool) -> LightBounds {
        let b = pm_scene::bounds_of(t);
        // The cone of the emitting faces' normals: about their area-weighted mean,
        // as wide as the farthest normal from it.
        let w = t.iter().map(|tr| tr.ng() * tr.area()).sum::<Vec3>().normalize_or_zero();
        let cos_o = if w == Vec3::ZERO {
            -1.0
        } else {
            t.iter().map(|tr| tr.ng().dot(w)).fold(1.0f32, f32::min).clamp(-1.0, 1.0)
        };
        LightBounds {
            lo: b.min,
            hi: b.max,
            phi,
            w: if w == Vec3::ZERO { Vec3::Z } else { w },
            cos_o,
            cos_e: 0.0,
            two_sided,
        }
    }

    /// No lights: what [`Self::union`] leaves unchanged.
    const EMPTY: LightBounds = LightBounds {
        lo: Vec3::INFINITY,
        hi: Vec3::NEG_INFINITY,
        phi: 0.0,
        w: Vec3::Z,
        cos_o: 1.0,
        cos_e: 1.0,
        two_sided: false,
    };

    fn centroid(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }

    /// The bounds of both: the box and cone that hold both, their powers summed.
    fn union(&self, o: &LightBounds) -> LightBounds {
        if self.phi == 0.0 {
            return *o;
        }
        if o.phi == 0.0 {
            return *self;
        }
        let (w, cos_o) = cone_union((self.w, self.cos_o), (o.w, o.cos_o));
        LightBounds {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            phi: self.phi + o.phi,
            w,
            cos_o,
            cos_e: self.cos_e.min(o.cos_e),
            two_sided: self.two_sided || o.two_sided,
        }
    }

    /// The importance of these lights for a point `p` with unit normal `n` (zero:
    /// a point in a medium, lit from every direction): phi cos(theta') / d^2,
    /// theta' the least angle between the emission cone and the direction to `p`
    /// over the box's bounding sphere, zero where it lies past theta_e; times the
    /// least incidence cosine at `p` over that sphere (both sides of the surface).
    /// Zero only where none of the lights can light `p`.
    fn importance(&self, p: Vec3, n: Vec3) -> f32 {
        if self.phi == 0.0 {
            return 0.0;
        }
        let pc = self.centroid();
        let r2 = ((self.hi - self.lo) * 0.5).length_squared();
        let d2 = p.distance_squared(pc).max(r2);
        let wi = (p - pc).normalize_or_zero();
        if wi == Vec3::ZERO {
            return self.phi / d2.max(f32::MIN_POSITIVE);
        }
        let mut cos_w = self.w.dot(wi);
        if self.two_sided {
            cos_w = cos_w.abs();
        }
        let sin_w = (1.0 - cos_w * cos_w).max(0.0).sqrt();
        // The bounding sphere's half-angle seen from p (every direction inside it).
        let (cos_b, sin_b) = if p.distance_squared(pc) <= r2 {
            (-1.0, 0.0)
        } else {
            let s2 = r2 / d2;
            ((1.0 - s2).max(0.0).sqrt(), s2.sqrt())
        };
        // theta' = max(0, theta_w - theta_o - theta_b).
        let sin_o = (1.0 - self.cos_o * self.cos_o).max(0.0).sqrt();
        let (cos_x, sin_x) = cos_sub_clamped(cos_w, sin_w, self.cos_o, sin_o);
        let (cos_p, _) = cos_sub_clamped(cos_x, sin_x, cos_b, sin_b);
        if cos_p <= self.cos_e {
            return 0.0;
        }
        let mut imp = self.phi * cos_p / d2;
        if n != Vec3::ZERO {
            let cos_i = wi.dot(n).abs();
            let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
            imp *= cos_sub_clamped(cos_i, sin_i, cos_b, sin_b).0;
        }
        imp.max(0.0)
    }
}

/// The smallest cone (axis, cos half-angle) holding two (pbrt-v4's
/// `DirectionCone::Union`): one that holds the other is the answer; else the
/// cone spanning both, its axis the first's turned toward the second.
fn cone_union((wa, cos_a): (Vec3, f32), (wb, cos_b): (Vec3, f32)) -> (Vec3, f32) {
    let theta_a = cos_a.clamp(-1.0, 1.0).acos();
    let theta_b = cos_b.clamp(-1.0, 1.0).acos();
    let theta_d = wa.dot(wb).clamp(-1.0, 1.0).acos();
    if (theta_d + theta_b).min(PI) <= theta_a {
        return (wa, cos_a);
    }
    if (theta_d + theta_a).min(PI) <= theta_b {
        return (wb, cos_b);
    }
    let theta_o = (theta_a + theta_d + theta_b) / 2.0;
    if theta_o >= PI {
        return (wa, -1.0);
    }
    let axis = wa.cross(wb);
    if axis.length_squared() < 1e-12 {
        return (wa, -1.0);
    }
    let w = glam::Quat::from_axis_angle(axis.normalize(), theta_o - theta_a) * wa;
    (w.normalize(), theta_o.cos())
}

/// A node: its bounds, and either two children (the first at the next index,
/// the second at `index`) or one light, or one triangle of an area light.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: LightBounds,
    /// The second child's index, or the light's index for a leaf.
    index: u32,
    /// For a leaf of one triangle, its place in the light's triangles; else
    /// [`WHOLE`].
    tri: u32,
    leaf: bool,
}

/// [`Node::tri`] of a leaf that is a whole light.
const WHOLE: u32 = u32::MAX;

/// What a light sample chose: a light, and for an area light in the tree
/// triangle by triangle, which of its triangles (its place in the light's
/// range): the sample is then taken on that triangle alone
/// ([`pm_scene::Light::sample_triangle`] with `chosen`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chosen {
    /// The light's index in the scene.
    pub light: usize,
    /// The triangle's place in the area light's range, if one was chosen.
    pub tri: Option<u32>,
}

impl Chosen {
    /// Light `li` whole.
    pub fn whole(li: usize) -> Chosen {
        Chosen { light: li, tri: None }
    }
}

/// The light tree over a set of a scene's lights (see the module doc).
#[derive(Clone, Debug)]
pub struct LightTree {
    nodes: Vec<Node>,
    /// The lights at infinity among the set, chosen apart from the tree.
    infinite: Vec<u32>,
    /// Per light of the scene: the path from the root to its leaf (bit k: the
    /// second child at depth k) and its depth; None for lights not in the tree
    /// whole.
    trails: Vec<Option<(u64, u32)>>,
    /// The same for the triangles of area lights in the tree triangle by
    /// triangle, by the triangle's id in the scene.
    tri_trails: std::collections::HashMap<u32, (u64, u32)>,
    /// Per light: whether it is in the tree triangle by triangle.
    split: Vec<bool>,
}

/// Bins per axis of the builder's split search.
const BUCKETS: usize = 12;

impl LightTree {
    /// The tree over `lights` (indices into `scene.lights`); lights that emit
    /// nothing are left out. None when nothing is left.
    pub fn new(scene: &Scene, lights: &[usize]) -> Option<LightTree> {
        let mut infinite = Vec::new();
        let mut bounded: Vec<(Chosen, LightBounds)> = Vec::new();
        let mut split = vec![false; scene.lights.len()];
        for &li in lights {
            let light = &scene.lights[li];
            match &light.kind {
                LightKind::Directional { .. } | LightKind::Environment { .. } => {
                    if light.power.element_sum() > 0.0 {
                        infinite.push(li as u32);
                    }
                }
                LightKind::Area { tris, cdf, two_sided, .. } if tris.len() > 1 => {
                    // Triangle by triangle, each with its share of the power (the
                    // light's own weights: area, or emitted power if textured).
                    let phi = light.power.element_sum();
                    let total = cdf.last().copied().unwrap_or(0.0);
                    if !(phi > 0.0 && total > 0.0) {
                        continue;
                    }
                    split[li] = true;
                    for (i, id) in tris.clone().enumerate() {
                        let w = cdf[i] - if i > 0 { cdf[i - 1] } else { 0.0 };
                        if w > 0.0 {
                            let t = std::slice::from_ref(&scene.triangles[id as usize]);
                            let b = LightBounds::of_triangles(t, phi * (w / total) as f32, *two_sided);
                            bounded.push((Chosen { light: li, tri: Some(i as u32) }, b));
                        }
                    }
                }
                _ => {
                    if let Some(b) = LightBounds::of(scene, li) {
                        bounded.push((Chosen { light: li, tri: None }, b));
                    }
                }
            }
        }
        if infinite.is_empty() && bounded.is_empty() {
            return None;
        }
        let mut tree = LightTree {
            nodes: Vec::new(),
            infinite,
            trails: vec![None; scene.lights.len()],
            tri_trails: Default::default(),
            split,
        };
        if !bounded.is_empty() {
            tree.build(scene, &mut bounded, 0, 0);
        }
        Some(tree)
    }

    /// Build the subtree of `lights` at depth `depth` whose path is `trail`;
    /// returns its bounds.
    fn build(&mut self, scene: &Scene, lights: &mut [(Chosen, LightBounds)], trail: u64, depth: u32) -> LightBounds {
        let at = self.nodes.len();
        if lights.len() == 1 {
            let (c, b) = lights[0];
            self.nodes.push(Node { bounds: b, index: c.light as u32, tri: c.tri.unwrap_or(WHOLE), leaf: true });
            match c.tri {
                Some(i) => {
                    let LightKind::Area { tris, .. } = &scene.lights[c.light].kind else { unreachable!() };
                    self.tri_trails.insert(tris.start + i, (trail, depth));
                }
                None => self.trails[c.light] = Some((trail, depth)),
            }
            return b;
        }
        // Deep in a lopsided tree, halves: the path must fit the trail's 64 bits.
        let mid = if depth >= 40 { lights.len() / 2 } else { split(lights) };
        self.nodes.push(Node { bounds: lights[0].1, index: 0, tri: WHOLE, leaf: false });
        let (left, right) = lights.split_at_mut(mid);
        let a = self.build(scene, left, trail, depth + 1);
        let second = self.nodes.len() as u32;
        let b = self.build(scene, right, trail | (1u64 << depth), depth + 1);
        let bounds = a.union(&b);
        self.nodes[at] = Node { bounds, index: second, tri: WHOLE, leaf: false };
        bounds
    }

    /// The probability of choosing the tree rather than one light at infinity.
    fn p_tree(&self) -> f32 {
        if self.nodes.is_empty() { 0.0 } else { 1.0 / (self.infinite.len() + 1) as f32 }
    }

    /// Choose a light for point `p` with unit normal `n` (zero in a medium) by `u`
    /// in [0, 1): the light (and triangle) and the probability it was chosen
    /// with; None when no light can light `p`.
    pub fn pick(&self, p: Vec3, n: Vec3, u: f32) -> Option<(Chosen, f32)> {
        let p_tree = self.p_tree();
        let p_inf = 1.0 - p_tree;
        if u < p_inf {
            let k = self.infinite.len();
            let i = ((u / p_inf * k as f32) as usize).min(k - 1);
            return Some((Chosen { light: self.infinite[i] as usize, tri: None }, p_inf / k as f32));
        }
        let mut u = ((u - p_inf) / p_tree).min(ONE_MINUS_EPSILON);
        let (mut node, mut pmf) = (0usize, p_tree);
        loop {
            let nd = &self.nodes[node];
            if nd.leaf {
                if node > 0 || nd.bounds.importance(p, n) > 0.0 {
                    let tri = (nd.tri != WHOLE).then_some(nd.tri);
                    return Some((Chosen { light: nd.index as usize, tri }, pmf));
                }
                return None;
            }
            let (c0, c1) = (node + 1, nd.index as usize);
            let i0 = self.nodes[c0].bounds.importance(p, n);
            let i1 = self.nodes[c1].bounds.importance(p, n);
            if !(i0 + i1 > 0.0) {
                return None;
            }
            let p0 = i0 / (i0 + i1);
            if u < p0 {
                (node, pmf, u) = (c0, pmf * p0, (u / p0).min(ONE_MINUS_EPSILON));
            } else {
                (node, pmf, u) = (c1, pmf * (1.0 - p0), ((u - p0) / (1.0 - p0)).min(ONE_MINUS_EPSILON));
            }
        }
    }

    /// Whether light `li` is in the tree triangle by triangle (its samples are then
    /// taken on a chosen triangle, and [`Self::prob_triangle`] gives their choice).
    pub fn is_split(&self, li: usize) -> bool {
        self.split.get(li).copied().unwrap_or(false)
    }

    /// The probability that [`Self::pick`] at `p`, `n` chooses light `li` whole (0
    /// for a light outside the set, or in it triangle by triangle).
    pub fn prob(&self, li: usize, p: Vec3, n: Vec3) -> f32 {
        let p_tree = self.p_tree();
        if self.infinite.contains(&(li as u32)) {
            return (1.0 - p_tree) / self.infinite.len() as f32;
        }
        let Some(trail) = self.trails.get(li).copied().flatten() else { return 0.0 };
        self.prob_along(trail, p, n)
    }

    /// The probability that [`Self::pick`] at `p`, `n` chooses the emitting
    /// triangle of scene id `tri` (0 unless its light is in the tree triangle by
    /// triangle).
    pub fn prob_triangle(&self, tri: u32, p: Vec3, n: Vec3) -> f32 {
        self.tri_trails.get(&tri).map_or(0.0, |&trail| self.prob_along(trail, p, n))
    }

    /// The product of the choices down the path `trail` of length `depth`.
    fn prob_along(&self, (trail, depth): (u64, u32), p: Vec3, n: Vec3) -> f32 {
        let p_tree = self.p_tree();
        let (mut node, mut pmf) = (0usize, p_tree);
        for k in 0..depth {
            let nd = &self.nodes[node];
            let (c0, c1) = (node + 1, nd.index as usize);
            let i0 = self.nodes[c0].bounds.importance(p, n);
            let i1 = self.nodes[c1].bounds.importance(p, n);
            if !(i0 + i1 > 0.0) {
                return 0.0;
            }
            if trail >> k & 1 == 0 {
                (node, pmf) = (c0, pmf * i0 / (i0 + i1));
            } else {
                (node, pmf) = (c1, pmf * i1 / (i0 + i1));
            }
        }
        if node == 0 && self.nodes[0].bounds.importance(p, n) <= 0.0 {
            return 0.0;
        }
        pmf
    }
}

const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// pbrt-v4's cost of a node's orientation bounds: the solid angle its cone and
/// emission spread reach, weighted by cosine, M_omega = 2 pi (1 - cos theta_o) +
/// pi / 2 (2 theta_w sin theta_o - cos(theta_o - 2 theta_w) - 2 theta_o sin
/// theta_o + cos theta_o), theta_w = min(theta_o + theta_e, pi).
fn orientation_cost(b: &LightBounds) -> f32 {
    let theta_o = b.cos_o.clamp(-1.0, 1.0).acos();
    let theta_e = b.cos_e.clamp(-1.0, 1.0).acos();
    let theta_w = (theta_o + theta_e).min(PI);
    let sin_o = theta_o.sin();
    2.0 * PI * (1.0 - b.cos_o)
        + FRAC_PI_2 * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o + b.cos_o)
}

/// Split `lights` (at least two) in two by the surface area orientation heuristic
/// over [`BUCKETS`] bins of centroid per axis (pbrt-v4's `buildBVH`): cost of a
/// side phi M_omega area, times the box's aspect along the axis. Where no split
/// separates them (every centroid in one bin), the halves in order. Returns the
/// first half's length; `lights` is partitioned in place.
fn split<K>(lights: &mut [(K, LightBounds)]) -> usize {
    let (mut clo, mut chi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for (_, b) in lights.iter() {
        let c = b.centroid();
        (clo, chi) = (clo.min(c), chi.max(c));
        (lo, hi) = (lo.min(b.lo), hi.max(b.hi));
    }
    let ext = hi - lo;
    let cext = chi - clo;
    let cost_of = |b: &LightBounds| {
        let e = b.hi - b.lo;
        let area = 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
        b.phi * orientation_cost(b) * area.max(1e-12)
    };
    // The bin of a light's centroid along axis `a`: the one expression both the
    // cost sweep and the partition use, so they agree on every light.
    let bucket =
        |b: &LightBounds, a: usize| (((b.centroid()[a] - clo[a]) / cext[a] * BUCKETS as f32) as usize).min(BUCKETS - 1);
    let mut best: Option<(f32, usize, usize)> = None;
    for a in 0..3 {
        if !(cext[a] > 0.0) {
            continue;
        }
        let mut bins = [LightBounds::EMPTY; BUCKETS];
        for (_, b) in lights.iter() {
            let k = bucket(b, a);
            bins[k] = bins[k].union(b);
        }
        let kr = ext.max_element() / ext[a].max(1e-12 * ext.max_element()).max(f32::MIN_POSITIVE);
        // Neither side is ever empty: the first bin holds the least centroid, the
        // last the greatest.
        for k in 0..BUCKETS - 1 {
            let left = bins[..=k].iter().fold(LightBounds::EMPTY, |acc, b| acc.union(b));
            let right = bins[k + 1..].iter().fold(LightBounds::EMPTY, |acc, b| acc.union(b));
            let cost = kr * (cost_of(&left) + cost_of(&right));
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, a, k));
            }
        }
    }
    let mid = match best {
        Some((_, a, k)) => {
            let mut i = 0;
            for j in 0..lights.len() {
                if bucket(&lights[j].1, a) <= k {
                    lights.swap(i, j);
                    i += 1;
                }
            }
            i
        }
        None => lights.len() / 2,
    };
    if mid == 0 || mid == lights.len() { lights.len() / 2 } else { mid }
}

#[cfg(test)]
mod tests;
