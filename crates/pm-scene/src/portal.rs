//! Portals: the openings (windows, doors) through which an environment lights an
//! interior (Bitterli, Novák and Jarosz 2015, "Portal-masked environment map
//! sampling"; pbrt-v4's `PortalImageInfiniteLight`). A portal is a parallelogram
//! named by its mesh; the environment's photons start on it and light samples aim
//! at it, so none are spent on the walls' outside. Directions that cross no portal
//! are still lit by the environment (a BSDF sample that finds the sky another way
//! keeps its full MIS weight), but no photon comes from them: surfaces outside the
//! portals get no photons from the environment.

use glam::{Vec2, Vec3};

/// A parallelogram opening: `corner + a u + b v` for a, b in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Portal {
    /// One corner \[m\].
    pub corner: Vec3,
    /// The two edges from it \[m\].
    pub u: Vec3,
    /// See `u`.
    pub v: Vec3,
    /// Unit normal toward the outside (away from the scene's centre).
    pub outward: Vec3,
    /// Area [m^2].
    pub area: f32,
}

impl Portal {
    /// The parallelogram that triangles `tris` (of a mesh) make, its outward side
    /// the one away from `inside`: two triangles sharing an edge whose four corners
    /// form a parallelogram (within 1e-4 of its size). Else why not.
    pub fn of(tris: &[&crate::Triangle], inside: Vec3) -> Result<Portal, String> {
        let [a, b] = tris else {
            return Err(format!("a portal is one quad (two triangles); this mesh has {} triangles", tris.len()));
        };
        // The corner of `b` that `a` lacks, and `a`'s corner opposite the shared edge.
        let key = |v: Vec3| v.to_array().map(f32::to_bits);
        let lone = |t: &crate::Triangle, other: &crate::Triangle| {
            t.p.iter().copied().find(|p| !other.p.iter().any(|q| key(*q) == key(*p)))
        };
        let (Some(pa), Some(pb)) = (lone(a, b), lone(b, a)) else {
            return Err("the portal's two triangles do not share an edge".into());
        };
        let shared: Vec<Vec3> = a.p.iter().copied().filter(|p| key(*p) != key(pa)).collect();
        let (u, v) = (shared[0] - pa, shared[1] - pa);
        let size = u.length().max(v.length());
        if (pa + u + v - pb).length() > 1e-4 * size {
            return Err("the portal's corners do not form a parallelogram".into());
        }
        let n = u.cross(v);
        let area = n.length();
        if !(area > 0.0) {
            return Err("the portal has no area".into());
        }
        let n = n / area;
        let outward = if (pa - inside).dot(n) >= 0.0 { n } else { -n };
        Ok(Portal { corner: pa, u, v, outward, area })
    }

    /// The point at parameters `uv` in [0, 1]^2 (uniform by area).
    pub fn point(&self, uv: Vec2) -> Vec3 {
        self.corner + self.u * uv.x + self.v * uv.y
    }

    /// Distance along the ray from `o` in unit direction `d` at which it leaves
    /// through the portal (crossing it outward), if it does.
    pub fn exit(&self, o: Vec3, d: Vec3) -> Option<f32> {
        let cos = d.dot(self.outward);
        if cos <= 0.0 {
            return None;
        }
        let t = (self.corner - o).dot(self.outward) / cos;
        if !(t > 0.0) {
            return None;
        }
        // Parallelogram coordinates of the crossing point.
        let q = o + d * t - self.corner;
        let (uu, uv, vv) = (self.u.dot(self.u), self.u.dot(self.v), self.v.dot(self.v));
        let (qu, qv) = (q.dot(self.u), q.dot(self.v));
        let det = uu * vv - uv * uv;
        let a = (qu * vv - qv * uv) / det;
        let b = (qv * uu - qu * uv) / det;
        ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)).then_some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Triangle;

    /// A quad's two triangles make its parallelogram, facing away from the inside
    /// point whichever way they wind; rays cross it inside and miss it outside; a
    /// single triangle or a kite is refused.
    #[test]
    fn a_quad_makes_a_portal_that_rays_cross() {
        let q =
            [Vec3::new(2.0, 1.0, -0.5), Vec3::new(2.0, 1.0, 0.5), Vec3::new(2.0, 2.0, 0.5), Vec3::new(2.0, 2.0, -0.5)];
        let t1 = Triangle::new([q[0], q[1], q[2]], 0).unwrap();
        let t2 = Triangle::new([q[0], q[2], q[3]], 0).unwrap();
        for inside in [Vec3::ZERO, Vec3::new(5.0, 1.0, 0.0)] {
            let p = Portal::of(&[&t1, &t2], inside).unwrap();
            assert!((p.area - 1.0).abs() < 1e-6);
            let want = if inside.x < 2.0 { Vec3::X } else { Vec3::NEG_X };
            assert!((p.outward - want).length() < 1e-6, "{inside}: {}", p.outward);
            let through = (Vec3::new(2.0, 1.5, 0.2) - inside).normalize();
            let t = p.exit(inside, through).unwrap();
            assert!((inside + through * t - Vec3::new(2.0, 1.5, 0.2)).length() < 1e-5);
            let beside = (Vec3::new(2.0, 2.5, 0.2) - inside).normalize();
            assert!(p.exit(inside, beside).is_none());
            assert!(p.exit(inside, -through).is_none(), "away from the portal");
        }
        assert!(Portal::of(&[&t1], Vec3::ZERO).is_err());
        let kite = Triangle::new([q[0], q[2], Vec3::new(2.0, 2.5, -1.0)], 0).unwrap();
        assert!(Portal::of(&[&t1, &kite], Vec3::ZERO).is_err());
    }
}
