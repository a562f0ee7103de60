//! Ray-triangle intersection and self-intersection-free ray origins.

use glam::Vec3;

/// Offset a surface point along the geometric normal so a ray leaving it toward the
/// side of `w` cannot re-hit the same surface, by an amount proportional to the
/// magnitude of the point's coordinates rather than a fixed epsilon (Wächter and
/// Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing
/// Gems ch. 6): the offset is a fixed number (16, where the chapter uses 256: hit
/// points from our watertight test are off the plane by a few ulps, and 256 ulps
/// moved rays by 2 m in a scene 100 km from the origin) of units in the last place of each
/// coordinate, with a small absolute floor near the origin. That floor and the
/// threshold below which it applies are multiples of `scale`, the scene's size
/// (its bounding-box diagonal), so scenes at scale 1e-3 and 1e4 behave alike (with
/// fixed values, a 2 mm scene got offsets of 0.75% of its size).
pub fn offset_ray_origin(p: Vec3, ng: Vec3, w: Vec3, scale: f32) -> Vec3 {
    const INT_SCALE: f32 = 16.0;
    let origin = scale * (1.0 / 32.0);
    let float_scale = scale * (1.0 / 65536.0);
    let n = if ng.dot(w) < 0.0 { -ng } else { ng };
    let of_i = (n * INT_SCALE).as_ivec3();
    let bump = |pc: f32, oi: i32, nc: f32| {
        if pc.abs() < origin {
            pc + float_scale * nc
        } else {
            let bits = pc.to_bits() as i32;
            f32::from_bits((if pc < 0.0 { bits - oi } else { bits + oi }) as u32)
        }
    };
    Vec3::new(bump(p.x, of_i.x, n.x), bump(p.y, of_i.y, n.y), bump(p.z, of_i.z, n.z))
}

/// Watertight ray-triangle intersection (Woop, Benthin and Wald 2013, as in pbrt-v4
/// section 6.5.3): no ray passes between two triangles that share an edge. Returns
/// the distance t in (0, t_max) and barycentrics (b0, b1, b2) of (p0, p1, p2).
#[inline]
pub fn intersect_triangle(o: Vec3, d: Vec3, p: &[Vec3; 3], t_max: f32) -> Option<(f32, [f32; 3])> {
    TriangleRay::new(o, d).hit(p, t_max)
}

/// A ray prepared for many triangle tests: the axis permutation that makes the
/// direction's largest component z, and the shear that maps the direction onto +z,
/// computed once per ray as Woop, Benthin and Wald (2013, section 3) intend rather
/// than once per triangle (a BVH traversal tests tens of triangles per ray).
#[derive(Clone, Copy, Debug)]
pub struct TriangleRay {
    o: Vec3,
    /// Axis indices of the permuted x, y and z.
    k: [usize; 3],
    /// Shear (sx, sy) and 1 / d_z of the permuted direction.
    s: Vec3,
}

impl TriangleRay {
    /// Prepare the ray from `o` along `d` (need not be unit length).
    #[inline]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        let ad = d.abs();
        let kz = if ad.x > ad.y {
            if ad.x > ad.z { 0 } else { 2 }
        } else if ad.y > ad.z {
            1
        } else {
            2
        };
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let d = d.to_array();
        let sz = 1.0 / d[kz];
        TriangleRay { o, k: [kx, ky, kz], s: Vec3::new(-d[kx] * sz, -d[ky] * sz, sz) }
    }

    /// The distance t in (0, t_max) and barycentrics (b0, b1, b2) where this ray hits
    /// the triangle (p0, p1, p2), if it does.
    #[inline]
    pub fn hit(&self, p: &[Vec3; 3], t_max: f32) -> Option<(f32, [f32; 3])> {
        // One copy of the test per permutation, so the axis swizzle is fixed at
        // compile time rather than indexed per vertex.
        match self.k[2] {
            0 => self.hit_in::<1, 2, 0>(p, t_max),
            1 => self.hit_in::<2, 0, 1>(p, t_max),
            _ => self.hit_in::<0, 1, 2>(p, t_max),
        }
    }

    #[inline(always)]
    fn hit_in<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        p: &[Vec3; 3],
        t_max: f32,
    ) -> Option<(f32, [f32; 3])> {
        let (sx, sy, sz) = (self.s.x, self.s.y, self.s.z);
        let perm = |v: Vec3| {
            let a = v - self.o;
            Vec3::new(a[KX], a[KY], a[KZ])
        };
        let mut p0 = perm(p[0]);
        let mut p1 = perm(p[1]);
        let mut p2 = perm(p[2]);
        p0.x += sx * p0.z;
        p0.y += sy * p0.z;
        p1.x += sx * p1.z;
        p1.y += sy * p1.z;
        p2.x += sx * p2.z;
        p2.y += sy * p2.z;
        let mut e0 = p1.x * p2.y - p1.y * p2.x;
        let mut e1 = p2.x * p0.y - p2.y * p0.x;
        let mut e2 = p0.x * p1.y - p0.y * p1.x;
        if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
            // Fall back to double precision on edges (pbrt-v4 does the same).
            e0 = (p1.x as f64 * p2.y as f64 - p1.y as f64 * p2.x as f64) as f32;
            e1 = (p2.x as f64 * p0.y as f64 - p2.y as f64 * p0.x as f64) as f32;
            e2 = (p0.x as f64 * p1.y as f64 - p0.y as f64 * p1.x as f64) as f32;
        }
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        p0.z *= sz;
        p1.z *= sz;
        p2.z *= sz;
        let t_scaled = e0 * p0.z + e1 * p1.z + e2 * p2.z;
        if det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_max * det) {
            return None;
        }
        if det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_max * det) {
            return None;
        }
        let inv = 1.0 / det;
        let t = t_scaled * inv;
        if !(t > 0.0 && t < t_max && t.is_finite()) {
            return None;
        }
        // Conservative lower bound on t (pbrt-v4 section 6.8.7): a t within the
        // floating-point error of the computation is not a hit, so a ray starting on a
        // surface (a camera lying on the floor) does not hit that surface at t ~ 0.
        let gamma = |n: f32| {
            let e = n * f32::EPSILON * 0.5;
            e / (1.0 - e)
        };
        let max_zt = p0.z.abs().max(p1.z.abs()).max(p2.z.abs());
        let max_xt = p0.x.abs().max(p1.x.abs()).max(p2.x.abs());
        let max_yt = p0.y.abs().max(p1.y.abs()).max(p2.y.abs());
        let delta_z = gamma(3.0) * max_zt;
        let delta_x = gamma(5.0) * (max_xt + max_zt);
        let delta_y = gamma(5.0) * (max_yt + max_zt);
        let delta_e = 2.0 * (gamma(2.0) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = 3.0 * (gamma(3.0) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv.abs();
        if t <= delta_t {
            return None;
        }
        Some((t, [e0 * inv, e1 * inv, e2 * inv]))
    }
}
