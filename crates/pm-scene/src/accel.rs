//! Ray queries: the BVH over the triangles (`bvh` builds and traverses it),
//! closest hit, shadow-ray occlusion, hit records and ray-origin offsets.

use crate::geometry::{self, TriangleRay, facing, offset_ray_origin};
use crate::{Bounds, Hit, Scene, Triangle, bvh};
use glam::{Vec2, Vec3};

/// The triangles' positions in the BVH's slot order, four slots to a
/// [`geometry::Tri4`]. A leaf lies within one group but need not start it: small
/// leaves share groups (see `Bvh::node`), and a leaf's lanes are a mask.
#[derive(Clone, Debug, Default)]
pub(crate) struct BvhTris {
    tri4: Vec<geometry::Tri4>,
}

impl BvhTris {
    /// Bytes its groups hold (their capacity).
    pub(crate) fn memory_bytes(&self) -> usize {
        self.tri4.capacity() * std::mem::size_of::<geometry::Tri4>()
    }

    /// The group of four that holds a leaf's slots `first..first + count`, the mask
    /// of their lanes in it, and its first slot. A leaf never straddles two groups
    /// (`Bvh::node` pads the slots so), so it takes one four-wide test.
    #[inline(always)]
    fn group(&self, first: u32, count: u32) -> (&geometry::Tri4, u32, u32) {
        let (g, lo) = (first / 4, first % 4);
        debug_assert!(lo + count <= 4, "a leaf straddles two groups of four");
        (&self.tri4[g as usize], ((1u32 << (lo + count)) - 1) & !((1u32 << lo) - 1), 4 * g)
    }
}

/// The BVH over `triangles` (whose bounds are `bounds`), and the triangles in its
/// slot order.
pub(crate) fn build_bvh(triangles: &[Triangle], bounds: &Bounds) -> (bvh::Bvh, BvhTris) {
    if triangles.is_empty() {
        return (bvh::Bvh::default(), BvhTris::default());
    }
    // Each triangle's box is padded by 2e-7 of the scene's size: with exact boxes,
    // slab tests missed rays that pass exactly through an edge lying on a node
    // boundary (30 of 13,000 rays aimed at a sphere's vertices and edge midpoints
    // slipped through obvhs's; tests/tests/suite/hard_cases.rs). Our own eight-wide
    // tree and build, not obvhs's compressed wide BVH (CWBVH), whose 8-bit
    // quantised child boxes lost rays that start a few hundredths of a millimetre
    // from a surface and hit it at once (13 of 200,000 gather rays from the walls of
    // cornell_spheres, born near the floor, went through it; tests.rs), nor its PLOC
    // build, whose scratch (about 190 bytes a triangle) set the load's peak memory.
    let diag = bounds.diagonal().max(f32::MIN_POSITIVE);
    let bvh = bvh::Bvh::build(triangles, 2e-7 * diag);
    let tri4 = bvh
        .slots()
        .chunks(4)
        .map(|c| {
            let mut p = [[Vec3::ZERO; 3]; 4];
            for (q, &i) in p.iter_mut().zip(c) {
                *q = triangles[i as usize].p;
            }
            geometry::Tri4::new(&p[..c.len()])
        })
        .collect();
    (bvh, BvhTris { tri4 })
}

impl Scene {
    /// [`offset_ray_origin`] at this scene's scale: where a ray leaving surface point
    /// `p` (geometric normal `ng`) toward `w` starts.
    #[inline]
    pub fn offset_origin(&self, p: Vec3, ng: Vec3, w: Vec3) -> Vec3 {
        offset_ray_origin(p, ng, w, 1.0 / self.bvh_inv_scale)
    }

    /// The surface through `x` (a point on it, as a photon records it; `n` its
    /// normal roughly, within tens of degrees) and its neighbours along its normal:
    /// the surface's unit geometric normal on `n`'s side, and the distances to the
    /// nearest other surface behind it and in front of it \[m\], each at most
    /// `reach`; index-matched boundaries (a fog box's walls, which light passes
    /// straight through) do not count, nor surfaces within a hair of it. Three
    /// rays: one from just above `x` down onto the surface, one on from there
    /// behind it, one out in front. `None` when
    /// no surface lies within a hair (1e-5 of the scene's diagonal, or a few ulps of
    /// `x`) of `x`.
    pub fn surface_gaps(&self, x: Vec3, n: Vec3, reach: f32) -> Option<(Vec3, f32, f32)> {
        let hair = (1e-5 * self.bounds.diagonal()).max(4.0 * f32::EPSILON * x.abs().max_element());
        let start = x + n * hair;
        let here = self.intersect_through(start, -n, None);
        let here = here.hit.filter(|_| here.t <= 3.0 * hair)?;
        let ng = geometry::facing(here.ng, n);
        // From a hair off the surface: at a mesh's vertex (the vertex method's
        // corners sit on them) a ray from the surface meets the facets round the
        // vertex at once, and a sphere's corner read a gap of 1e-7 m behind it,
        // so its estimate counted no photon below its tangent plane.
        let gap = |w: Vec3| (hair + self.intersect_through(here.p + w * hair, w, None).t).min(reach);
        Some((ng, gap(-ng), gap(ng)))
    }

    /// Whether the point `off` away from `x` in its tangent plane lies on the
    /// surface through `x` or on one that continues it, as a density estimate
    /// about `x` of radius `r` counts its photons: a surface within `r` of `x`
    /// whose normal on `n`'s side is within `same_cos` of `n` (`n` the unit
    /// normal on the side the estimate looks from, `off` perpendicular to it,
    /// |off| <= r). The segment to the point, lifted off the surface by r / 10,
    /// either meets a surface (a gently curved, concave continuation counts; a
    /// wall of a concave corner does not) or runs clear, and then a ray down from
    /// the lifted point finds the surface within 2r (a convex bend of up to 60
    /// degrees counts; past a box's edge there is nothing, or only the floor
    /// farther than r). Index-matched boundaries are passed, as photons pass them.
    /// Two rays at most. What a disc about `x` that an edge cuts holds of the
    /// surface is the share of such points in it (progressive photon mapping's
    /// gathers, the irradiance precompute).
    pub fn continues_surface(&self, x: Vec3, n: Vec3, off: Vec3, r: f32, same_cos: f32) -> bool {
        self.surface_beside(x, n, off, r, same_cos).is_some()
    }

    /// The surface point [`Self::continues_surface`] finds, where it finds one.
    pub fn surface_beside(&self, x: Vec3, n: Vec3, off: Vec3, r: f32, same_cos: f32) -> Option<Hit> {
        let lift = 0.1 * r;
        let o = x + lift * n;
        let alike = |hit: &Hit| facing(hit.ng, n).dot(n) > same_cos && hit.p.distance_squared(x) <= r * r;
        let dist = off.length();
        if dist > 0.0
            && let Some(hit) = self.solid_hit(o, off / dist, dist)
        {
            return Some(hit).filter(alike);
        }
        self.solid_hit(o + off, -n, lift + 2.0 * r).filter(alike)
    }

    /// True when a surface other than an index-matched boundary faces the point
    /// `x` of a surface (unit normal `n` on the side asked about) from closer than
    /// `within` \[m\] along its normal: the point lies in a gap under a cover. One
    /// ray.
    pub fn covered(&self, x: Vec3, n: Vec3, within: f32) -> bool {
        self.solid_hit(self.offset_origin(x, n, n), n, within).is_some()
    }

    /// The first hit within `t_max` along the ray from `o` in unit direction `d`
    /// that is not an index-matched boundary: what a probe of the scene's
    /// surfaces should find (a fog box's walls are not surfaces to light).
    pub fn solid_hit(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
        let first = self.intersect(o, d, t_max);
        if !self.layout.index_matched {
            return first;
        }
        self.walk_from(o, d, t_max, None, first).hit
    }

    /// True when something other than an index-matched boundary blocks the ray
    /// from `o` along unit `d` before `t_max` ([`Self::solid_hit`]; an any-hit
    /// test where the scene has no such boundaries).
    pub fn solidly_occluded(&self, o: Vec3, d: Vec3, t_max: f32) -> bool {
        if !self.layout.index_matched {
            return self.occluded(o, d, t_max);
        }
        self.solid_hit(o, d, t_max).is_some()
    }

    /// Closest intersection along the ray from `o` in unit direction `d` within
    /// (0, t_max). An index-matched boundary and a solid surface closer together
    /// than a ray's offset off a surface ([`Self::offset_origin`], doubled) are one
    /// surface here, and the solid one is hit: a fog box standing on the floor
    /// has its bottom face in the floor's plane, and whichever of the two the
    /// traversal found first decided whether the floor was reached in the fog
    /// (and its shadow rays and photons left in it) or the ray, passing the
    /// face, started under the floor and left the room (issue 53's checker, its
    /// fog boxes "on the floor").
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
        let hit = self.closest_where(o, d, t_max, |_| true)?;
        if !self.layout.index_matched || !self.is_index_matched(hit.tri) {
            return Some(hit);
        }
        let off = self.offset_origin(hit.p, hit.ng, d) - hit.p;
        let cos = d.dot(hit.ng).abs().max(0.05);
        let reach = (hit.t + 2.0 * off.length() / cos).min(t_max);
        Some(self.closest_where(o, d, reach, |tri| !self.is_index_matched(tri)).unwrap_or(hit))
    }

    /// The closest intersection within (0, t_max) with a triangle `accept`
    /// takes (and an alpha mask keeps).
    #[inline]
    fn closest_where(&self, o: Vec3, d: Vec3, t_max: f32, accept: impl Fn(u32) -> bool) -> Option<Hit> {
        let mut best_b = [0.0; 3];
        let tri_ray = TriangleRay::new(o, d);
        let (tris, id) = (&self.bvh_tris, self.bvh.slots());
        let (slot, t) = self.bvh.closest(o, d, t_max, |first, count, t_max| {
            let mut best = None;
            let mut t_best = t_max;
            let (group, mask, slot0) = tris.group(first, count);
            tri_ray.hit4(group, mask, t_best, |lane, t, b| {
                let s = slot0 + lane as u32;
                let tri = id[s as usize];
                if (!self.any_alpha || self.present(tri, b)) && accept(tri) {
                    (t_best, best_b, best) = (t, b, Some((s, t)));
                }
                t_best
            });
            best
        })?;
        Some(self.make_hit(id[slot as usize], t, best_b))
    }

    /// True when something blocks the segment from `o` along unit `d` before `t_max`.
    pub fn occluded(&self, o: Vec3, d: Vec3, t_max: f32) -> bool {
        let tri_ray = TriangleRay::new(o, d);
        let (tris, id) = (&self.bvh_tris, self.bvh.slots());
        self.bvh.any(o, d, t_max, |first, count, t_max| {
            let mut blocked = false;
            let (group, mask, slot0) = tris.group(first, count);
            tri_ray.hit4(group, mask, t_max, |lane, _, b| {
                blocked |= !self.any_alpha || self.present(id[slot0 as usize + lane], b);
                if blocked { 0.0 } else { t_max }
            });
            blocked
        })
    }

    /// The hit record of triangle `tri` at barycentrics `b`, t along the ray. The
    /// shading normal is the interpolated vertex normal, perturbed by the material's
    /// normal texture in the tangent frame (glTF 2.0 section 3.9.3: bitangent = w
    /// cross(n, t)), and turned to the geometric normal's side.
    pub fn make_hit(&self, tri: u32, t: f32, b: [f32; 3]) -> Hit {
        let b = off_the_boundary(b);
        let tr = &self.triangles[tri as usize];
        let ng = tr.ng();
        let (p, ns) = (tr.point(b), tr.shading_normal(b, ng));
        let lerp = |uv: &[Vec2; 3]| uv[0] * b[0] + uv[1] * b[1] + uv[2] * b[2];
        let uv = tr.uv().map_or(Vec2::ZERO, lerp);
        let uv1 = tr.uv1().map_or(Vec2::ZERO, lerp);
        let color = tr.color().map_or(glam::Vec4::ONE, |c| c[0] * b[0] + c[1] * b[1] + c[2] * b[2]);
        let mut hit = Hit { t, tri, b, p, ng, ns, uv, uv1, color };
        let m = &self.materials[tr.material as usize];
        if let Some(nt) = &m.normal_texture
            && let Some((tangent, bitangent)) = self.tangent_frame(tr, b, ns)
        {
            let c = self.lookup(nt, &hit);
            let v = (c.truncate() * 2.0 - Vec3::ONE) * Vec3::new(m.normal_scale, m.normal_scale, 1.0);
            hit.ns = (tangent * v.x + bitangent * v.y + ns * v.z).normalize_or(ns);
        }
        hit.ns = facing(hit.ns, ng);
        hit
    }

    /// The unit tangent and bitangent at barycentrics `b` of `tr` about unit normal
    /// `n`: the interpolated tangent made perpendicular to `n`, and bitangent = w
    /// cross(n, t) (glTF 2.0 section 3.7.2.1). None without tangents or where the
    /// tangent lies along `n`.
    pub(crate) fn tangent_frame(&self, tr: &Triangle, b: [f32; 3], n: Vec3) -> Option<(Vec3, Vec3)> {
        let tg = tr.tangent()?;
        let tangent = (tg[0] * b[0] + tg[1] * b[1] + tg[2] * b[2]).truncate();
        let tangent = (tangent - n * n.dot(tangent)).normalize_or_zero();
        (tangent != Vec3::ZERO).then(|| (tangent, n.cross(tangent) * if tg[0].w < 0.0 { -1.0 } else { 1.0 }))
    }
}

/// The least barycentric coordinate a hit keeps: [`Scene::make_hit`] moves a hit on
/// (or within this of) its triangle's boundary just inside it.
pub const EDGE_INSET: f32 = 1e-5;

/// Barycentrics `b` with each at least [`EDGE_INSET`], renormalised: the hit moved
/// inside its triangle by at most 1e-5 of its size (20 um on a 2 m wall, ten times
/// what a ray origin's offset moves it). A ray through a seam or along
/// an edge gets a coordinate of exactly zero, and from a point on the edge between
/// a wall and the floor, rays leaving toward the floor start behind it and escape:
/// a final gather there saw half its hemisphere black. A camera centred in a box
/// sees its floor's edges on the image's diagonals, through pixel centres: the
/// irradiance cache put records on them, each with half the light and the largest
/// radius (no near hits), and drew a dark band 20% deep along the room's lower
/// edges (the differential checker's scene 30 of seed 16654; issue 53).
pub(crate) fn off_the_boundary(b: [f32; 3]) -> [f32; 3] {
    if b.iter().all(|&x| x >= EDGE_INSET) {
        return b;
    }
    let c = b.map(|x| x.max(EDGE_INSET));
    let sum = c[0] + c[1] + c[2];
    c.map(|x| x / sum)
}

#[cfg(test)]
mod edge_tests {
    use super::*;

    /// A hit on an edge or a corner moves inside its triangle by about the inset;
    /// one inside stays bit for bit.
    #[test]
    fn hits_on_a_triangles_boundary_move_just_inside_it() {
        for b in [[0.0, 0.3, 0.7], [0.0, 0.0, 1.0], [-1e-7, 0.5, 0.5000001], [5e-5, 0.5, 0.49995]] {
            let c = off_the_boundary(b);
            assert!(c.iter().all(|&x| x >= 0.99 * EDGE_INSET), "{b:?} -> {c:?}");
            assert!((c.iter().sum::<f32>() - 1.0).abs() < 1e-6, "{c:?}");
            assert!(c.iter().zip(&b).all(|(x, y)| (x - y).abs() < 3.0 * EDGE_INSET), "{b:?} -> {c:?}");
        }
        let inside = [0.2, 0.3, 0.5];
        assert_eq!(off_the_boundary(inside), inside);
    }
}
