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
///
/// Each coordinate also steps 8 ulps times unit `w`'s component (half the normal's count)
/// toward `w`. A hit at a concave edge, such as a wall a hair above the floor, is
/// interpolated from the hit triangle's corners and can land an ulp on the far side
/// of the neighbouring surface; the normal's offset runs parallel to that surface
/// and leaves it there, so every ray from it would hit the neighbour from behind.
/// The step along `w` takes the origin back to the side the ray leaves toward. It
/// is counted in ulps near the origin too: a step of the absolute floor's size
/// along a grazing `w` carried photons out of the furnace between its facets (4% of
/// its indirect light).
pub fn offset_ray_origin(p: Vec3, ng: Vec3, w: Vec3, scale: f32) -> Vec3 {
    debug_assert!(w == Vec3::ZERO || (w.length_squared() - 1.0).abs() < 1e-3, "offset along a unit direction, not {w}");
    const INT_SCALE: f32 = 16.0;
    let origin = scale * (1.0 / 32.0);
    let float_scale = scale * (1.0 / 65536.0);
    let n = if ng.dot(w) < 0.0 { -ng } else { ng };
    let of_n = (n * INT_SCALE).as_ivec3();
    let of_w = (w * (0.5 * INT_SCALE)).as_ivec3();
    // `x` moved `k` ulps toward +infinity (k < 0: toward -infinity); values within
    // a few ulps of the smallest normal are left alone rather than stepped across zero.
    let step = |x: f32, k: i32| {
        if x.abs() < 64.0 * f32::MIN_POSITIVE {
            return x;
        }
        let bits = x.to_bits() as i32;
        f32::from_bits((if x < 0.0 { bits - k } else { bits + k }) as u32)
    };
    let bump = |pc: f32, on: i32, ow: i32, nc: f32| {
        if pc.abs() < origin { step(pc + float_scale * nc, ow) } else { step(pc, on + ow) }
    };
    Vec3::new(bump(p.x, of_n.x, of_w.x, n.x), bump(p.y, of_n.y, of_w.y, n.y), bump(p.z, of_n.z, of_w.z, n.z))
}

/// Watertight ray-triangle intersection (Woop, Benthin and Wald 2013, as in pbrt-v4
/// section 6.5.3): no ray passes between two triangles that share an edge. Returns
/// the distance t in (0, t_max) and barycentrics (b0, b1, b2) of (p0, p1, p2).
#[inline]
pub fn intersect_triangle(o: Vec3, d: Vec3, p: &[Vec3; 3], t_max: f32) -> Option<(f32, [f32; 3])> {
    TriangleRay::new(o, d).hit(p, t_max)
}

/// Flip `n` to the side of `w` (a shading normal to its geometric normal's side, a
/// normal toward the viewer).
#[inline]
pub fn facing(n: Vec3, w: Vec3) -> Vec3 {
    if n.dot(w) < 0.0 { -n } else { n }
}

/// Whether directions `a` and `b` lie on the same side of the surface whose
/// geometric normal is `ng` (strictly: neither grazes it). A direction sampled
/// about a shading normal can point through the geometric surface: light does
/// not pass that way, so every scattering and light sample is checked with this.
#[inline]
pub fn same_side(ng: Vec3, a: Vec3, b: Vec3) -> bool {
    a.dot(ng) * b.dot(ng) > 0.0
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
        let mut found = None;
        self.hit4(&Tri4::new(std::slice::from_ref(p)), 0b1, t_max, |_, t, b| {
            found = Some((t, b));
            t
        });
        found
    }

    /// [`Self::hit`] for the lanes of four triangles in `mask` (bit i: lane i): `on_hit(lane, t, b)`
    /// for each hit, in lane order, returning the t_max for the lanes after it (the
    /// closest-hit search passes t, an any-hit search 0 to stop). The arithmetic runs
    /// on all four lanes together, but for the double-precision edge fallback and the
    /// per-lane re-check against the t_max the earlier lanes left.
    #[inline]
    pub fn hit4(&self, tri: &Tri4, mask: u32, t_max: f32, on_hit: impl FnMut(usize, f32, [f32; 3]) -> f32) {
        // One copy of the test per permutation, so the axis swizzle is fixed at
        // compile time rather than indexed per vertex.
        match self.k[2] {
            0 => self.hit4_in::<1, 2, 0>(tri, mask, t_max, on_hit),
            1 => self.hit4_in::<2, 0, 1>(tri, mask, t_max, on_hit),
            _ => self.hit4_in::<0, 1, 2>(tri, mask, t_max, on_hit),
        }
    }

    #[inline(always)]
    fn hit4_in<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        tri: &Tri4,
        mask: u32,
        mut t_max: f32,
        mut on_hit: impl FnMut(usize, f32, [f32; 3]) -> f32,
    ) {
        use glam::Vec4;
        let (sx, sy) = (Vec4::splat(self.s.x), Vec4::splat(self.s.y));
        let o = self.o.to_array();
        // The vertices translated to the ray's origin, permuted and sheared, by
        // vertex, four lanes at a time (glam's Vec4 is an SSE register on x86-64).
        let vert = |v: usize| {
            let ax = Vec4::from_array(tri.v[v][KX]) - Vec4::splat(o[KX]);
            let ay = Vec4::from_array(tri.v[v][KY]) - Vec4::splat(o[KY]);
            let az = Vec4::from_array(tri.v[v][KZ]) - Vec4::splat(o[KZ]);
            (ax + sx * az, ay + sy * az, az)
        };
        let (x0, y0, z0) = vert(0);
        let (x1, y1, z1) = vert(1);
        let (x2, y2, z2) = vert(2);
        let mut e0 = x1 * y2 - y1 * x2;
        let mut e1 = x2 * y0 - y2 * x0;
        let mut e2 = x0 * y1 - y0 * x1;
        let zero = Vec4::ZERO;
        let both_signs = |e0: Vec4, e1: Vec4, e2: Vec4| {
            let neg = e0.cmplt(zero) | e1.cmplt(zero) | e2.cmplt(zero);
            let pos = e0.cmpgt(zero) | e1.cmpgt(zero) | e2.cmpgt(zero);
            (neg & pos).bitmask()
        };
        let on_edge = (e0.cmpeq(zero) | e1.cmpeq(zero) | e2.cmpeq(zero)).bitmask() & mask;
        // A lane with edge functions of both signs misses (unless one is zero,
        // which the double-precision fallback below decides).
        let mut alive = (on_edge | !both_signs(e0, e1, e2)) & mask & 0b1111;
        if alive == 0 {
            return;
        }
        if on_edge & alive != 0 {
            // Recompute the edge functions of lanes on an edge in double precision
            // (pbrt-v4 does the same), then decide their sign test again.
            let (mut a0, mut a1, mut a2) = (e0.to_array(), e1.to_array(), e2.to_array());
            let (x, y) = ([x0, x1, x2].map(|v| v.to_array()), [y0, y1, y2].map(|v| v.to_array()));
            let mut m = on_edge & alive;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                let c = |v: usize, w: usize| (x[v][i] as f64 * y[w][i] as f64 - y[v][i] as f64 * x[w][i] as f64) as f32;
                (a0[i], a1[i], a2[i]) = (c(1, 2), c(2, 0), c(0, 1));
            }
            (e0, e1, e2) = (Vec4::from_array(a0), Vec4::from_array(a1), Vec4::from_array(a2));
            alive &= !both_signs(e0, e1, e2);
        }
        // The rest of the test on the four lanes together, against the t_max given;
        // a lane that passes is checked again against the t_max its predecessors
        // left (the only conditions that depend on it) before it is reported.
        let det = e0 + e1 + e2;
        let sz = Vec4::splat(self.s.z);
        let (z0, z1, z2) = (z0 * sz, z1 * sz, z2 * sz);
        let t_scaled = e0 * z0 + e1 * z1 + e2 * z2;
        let t_max_det = Vec4::splat(t_max) * det;
        let in_range_neg = det.cmplt(zero) & t_scaled.cmplt(zero) & t_scaled.cmpge(t_max_det);
        let in_range_pos = det.cmpgt(zero) & t_scaled.cmpgt(zero) & t_scaled.cmple(t_max_det);
        alive &= (in_range_neg | in_range_pos).bitmask();
        if alive == 0 {
            return;
        }
        let inv = Vec4::ONE / det;
        let t = t_scaled * inv;
        alive &= (t.cmpgt(zero) & t.cmplt(Vec4::splat(t_max)) & t.abs().cmplt(Vec4::INFINITY)).bitmask();
        // Conservative lower bound on t (pbrt-v4 section 6.8.7): a t within the
        // floating-point error of the computation is not a hit, so a ray starting on a
        // surface (a camera lying on the floor) does not hit that surface at t ~ 0.
        let gamma = |n: f32| {
            let e = n * f32::EPSILON * 0.5;
            Vec4::splat(e / (1.0 - e))
        };
        let max_zt = z0.abs().max(z1.abs()).max(z2.abs());
        let max_xt = x0.abs().max(x1.abs()).max(x2.abs());
        let max_yt = y0.abs().max(y1.abs()).max(y2.abs());
        let delta_z = gamma(3.0) * max_zt;
        let delta_x = gamma(5.0) * (max_xt + max_zt);
        let delta_y = gamma(5.0) * (max_yt + max_zt);
        let delta_e = Vec4::splat(2.0) * (gamma(2.0) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = Vec4::splat(3.0) * (gamma(3.0) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv.abs();
        alive &= t.cmpgt(delta_t).bitmask();
        let t_given = t_max;
        let (t, det, t_scaled, inv) = (t.to_array(), det.to_array(), t_scaled.to_array(), inv.to_array());
        let (e0, e1, e2) = (e0.to_array(), e1.to_array(), e2.to_array());
        while alive != 0 {
            let i = alive.trailing_zeros() as usize;
            alive &= alive - 1;
            if t_max != t_given {
                let tmd = t_max * det[i];
                let in_range = if det[i] < 0.0 { t_scaled[i] >= tmd } else { t_scaled[i] <= tmd };
                if !(in_range && t[i] < t_max) {
                    continue;
                }
            }
            t_max = on_hit(i, t[i], [e0[i] * inv[i], e1[i] * inv[i], e2[i] * inv[i]]);
        }
    }
}

/// Four triangles by vertex, axis and lane (structure of arrays), so that one ray
/// is tested against all four at once ([`TriangleRay::hit4`]). Lanes past a
/// group's triangles repeat its first.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    v: [[[f32; 4]; 3]; 3],
}

impl Tri4 {
    /// `tris` (one to four) in lanes 0.., the first repeated in the lanes past them.
    pub fn new(tris: &[[Vec3; 3]]) -> Tri4 {
        let mut t = Tri4 { v: [[[0.0; 4]; 3]; 3] };
        for lane in 0..4 {
            let p = &tris[if lane < tris.len() { lane } else { 0 }];
            for (tv, pv) in t.v.iter_mut().zip(p) {
                for (ta, pa) in tv.iter_mut().zip(pv.to_array()) {
                    ta[lane] = pa;
                }
            }
        }
        t
    }
}
