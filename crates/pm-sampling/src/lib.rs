//! Sampling vocabulary: a deterministic low-discrepancy sample stream keyed by an
//! index (a photon or a pixel sample, never a thread), and the warps from the unit
//! square to the domains light transport integrates over (pbrt-v4 chapter A.5).
//!
//! The sample stream is Owen-scrambled Sobol' (Burley 2020, "Practical Hash-based
//! Owen Scrambling", via `sobol_burley`), which is limited to 2^16 points per seed and
//! 256 dimensions: the stream re-seeds every 2^16 indices and falls back to hashed
//! white noise past dimension 255. This crate does no I/O and holds no global state.

use glam::{Vec2, Vec3, Vec4};
use std::f32::consts::{FRAC_1_PI, PI, TAU};

/// Largest f32 below 1, so that warps never receive exactly 1.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// 64-bit mixing function (SplitMix64 finaliser), used to derive seeds from indices.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A number in [0, 1) from the top 24 bits of `h` (a [`mix64`] of some key): a
/// fixed, well-spread value per key, where no sample stream is at hand.
#[inline]
pub fn unit_of(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// A stream of samples in [0,1) for one index (photon, pixel sample, ...). Each call
/// advances one dimension. Equal (seed, index) give equal streams on every thread.
/// The stream's keys are derived on the first draw: a pixel whose shading needs no
/// random numbers (a diffuse surface of a live frame) pays nothing for its sampler.
#[derive(Clone, Debug)]
pub struct Sampler {
    seed: u32,
    /// The point's index within its block of 2^16, bit-reversed and Owen-scrambled
    /// by the seed (Burley 2020 section 4's shuffle), shared by every dimension.
    shuffled: u32,
    noise_key: u64,
    dim: u32,
    /// (seed, salt, index) not derived yet.
    pending: Option<(u64, Option<u64>, u64)>,
    /// The four Sobol' dimensions of set `cached_set` (sobol_burley computes four at
    /// once for about the price of one, with identical values).
    cached: [f32; 4],
    cached_set: u32,
}

impl Sampler {
    /// Sobol' dimensions available before the stream falls back to hashed noise.
    pub const SOBOL_DIMS: u32 = 256;

    /// The stream for `index` within the sequence named by `seed`.
    pub fn new(seed: u64, index: u64) -> Sampler {
        Sampler {
            seed: 0,
            shuffled: 0,
            noise_key: 0,
            dim: 0,
            pending: Some((seed, None, index)),
            cached: [0.0; 4],
            cached_set: u32::MAX,
        }
    }

    /// The stream for `index` within the sequence named by `mix64(seed ^
    /// mix64(salt))` (a pixel's own sequence, for example): the same as
    /// `Sampler::new(mix64(seed ^ mix64(salt)), index)`, with the hashing deferred.
    pub fn salted(seed: u64, salt: u64, index: u64) -> Sampler {
        Sampler {
            seed: 0,
            shuffled: 0,
            noise_key: 0,
            dim: 0,
            pending: Some((seed, Some(salt), index)),
            cached: [0.0; 4],
            cached_set: u32::MAX,
        }
    }

    /// A stream that is only ever point 0 of its sequence (one sample per pixel, one
    /// path per photon of a frame): hashed white noise from the first dimension,
    /// keyed like [`Sampler::salted`]`(seed, salt, 0)`. Point 0 of an Owen-scrambled
    /// Sobol' sequence is a uniform random point of [0, 1)^d (each coordinate
    /// scrambled independently), and a stream's seed is its own, so without a
    /// second point to stratify against this is the same distribution; it skips the
    /// Sobol' evaluation, which was a fifth of a live frame's shading.
    pub fn hashed(seed: u64, salt: u64) -> Sampler {
        Sampler { dim: Self::SOBOL_DIMS, ..Sampler::salted(seed, salt, 0) }
    }

    #[cold]
    fn derive(&mut self, seed: u64, salt: Option<u64>, index: u64) {
        let seed = salt.map_or(seed, |salt| mix64(seed ^ mix64(salt)));
        let block = index >> 16;
        let block_seed = mix64(seed ^ mix64(block.wrapping_add(0x9e37_79b9_7f4a_7c15)));
        self.seed = block_seed as u32;
        self.shuffled = shuffle_index((index & 0xffff) as u32, self.seed);
        self.noise_key = mix64(seed.wrapping_mul(0x2545_f491_4f6c_dd1d) ^ index);
    }

    /// The next sample in [0, 1).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        if let Some((seed, salt, index)) = self.pending.take() {
            self.derive(seed, salt, index);
        }
        let d = self.dim;
        self.dim += 1;
        if d < Self::SOBOL_DIMS {
            if d / 4 != self.cached_set {
                self.cached_set = d / 4;
                self.cached = sobol_4d(self.shuffled, d / 4, self.seed);
            }
            self.cached[(d % 4) as usize].min(ONE_MINUS_EPSILON)
        } else {
            let h = mix64(self.noise_key ^ (d as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            ((h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)).min(ONE_MINUS_EPSILON)
        }
    }

    /// A set of 4-D points that one shading point uses together (its light samples),
    /// stratified among themselves: the leading points of a [`NetTable`]'s
    /// Owen-scrambled Sobol' net, scrambled again with seeds of its own drawn from
    /// this stream (one dimension is consumed). Consecutive dimensions of the stream
    /// are independent of each other, so n light samples drawn from them are n
    /// independent points; the net's first two coordinates fall in distinct strata of
    /// the square (Burley 2020, section 3).
    pub fn net_4d(&mut self) -> Net4 {
        let u = self.next_1d();
        let h = mix64(self.noise_key ^ (u.to_bits() as u64) << 32 ^ self.dim as u64);
        let g = mix64(h);
        Net4 { seeds: [h as u32, (h >> 32) as u32, g as u32, (g >> 32) as u32] }
    }

    /// The next two samples as a point in [0,1)^2.
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_1d(), self.next_1d())
    }
}

/// Dimension sets of 4 that `sobol_burley` has direction numbers for.
const SOBOL_SETS: usize = 64;

/// The Sobol' generator's direction numbers as nibble tables, `[set][group][value]`,
/// 4 lanes: for each 4-D dimension set and each 4-bit group of the (bit-reversed,
/// scrambled) index's top 16 bits, the Sobol' point of the index with only that
/// group's bits set to each of their 16 values (an XOR of direction vectors; the
/// point of an index is the XOR of its groups' entries). Read from
/// `sobol_nibbles.bin`, which `sobol_burley` itself generates
/// (`nibble_tables_are_sobol_burleys` checks it and, with
/// `PM_WRITE_TABLES=1`, rewrites it), so that the two can never disagree.
static SOBOL_NIBBLES: [[[[u32; 4]; 16]; 4]; SOBOL_SETS] = nibbles_from_le_bytes(include_bytes!("sobol_nibbles.bin"));

/// [`SOBOL_NIBBLES`] from its file: little-endian u32s in the table's order.
const fn nibbles_from_le_bytes(b: &[u8; SOBOL_SETS * 4 * 16 * 4 * 4]) -> [[[[u32; 4]; 16]; 4]; SOBOL_SETS] {
    let mut t = [[[[0u32; 4]; 16]; 4]; SOBOL_SETS];
    let mut i = 0;
    while i < SOBOL_SETS * 4 * 16 * 4 {
        let v = u32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]]);
        t[i / 256][i / 64 % 4][i / 4 % 16][i % 4] = v;
        i += 1;
    }
    t
}

/// Index `index` (below 2^16) of the sequence `seed`, bit-reversed and shuffled by
/// a nested uniform scramble: `sobol_burley::sample_4d`'s first step, done once per
/// stream.
#[inline]
fn shuffle_index(index: u32, seed: u32) -> u32 {
    use sobol_burley::parts::{hash, owen_scramble_rev};
    owen_scramble_rev(index.reverse_bits(), hash(seed ^ 0x79c68e4a))
}

/// Dimensions 4 set .. 4 set + 3 of the point whose shuffled index is `shuffled`
/// ([`shuffle_index`]) in the Owen-scrambled Sobol' sequence `seed`: bit for bit
/// `sobol_burley::sample_4d` (Burley 2020), with its Sobol' step read from the
/// nibble tables instead of a loop over the index's bits (its data-dependent
/// branches were most of the sampler's cost: 43 -> 20 ns a call).
#[inline]
fn sobol_4d(shuffled: u32, set: u32, seed: u32) -> [f32; 4] {
    use sobol_burley::parts::{Int4, hash_int4, owen_scramble_int4_rev};
    let t = &SOBOL_NIBBLES[set as usize];
    let mut sobol = Int4::from(t[0][(shuffled >> 28) as usize]);
    sobol ^= Int4::from(t[1][(shuffled >> 24 & 15) as usize]);
    sobol ^= Int4::from(t[2][(shuffled >> 20 & 15) as usize]);
    sobol ^= Int4::from(t[3][(shuffled >> 16 & 15) as usize]);
    let scramble = Int4::from([seed.wrapping_mul(0x9c8f_2d3b) ^ set; 4])
        ^ Int4::from([0x912f_69ba, 0x174f_18ab, 0x691e_72ca, 0xb40c_c1b8]);
    owen_scramble_int4_rev(sobol, hash_int4(scramble)).reverse_bits().to_f32_norm()
}

/// A randomised 4-D net from [`Sampler::net_4d`]: a [`NetTable`]'s points, each
/// coordinate Owen-scrambled again with seeds of this net's own (Burley 2020's hash
/// form of a nested uniform scramble). A scramble of a scrambled net is a net
/// scrambled as well: the strata stay, each point is uniform, and nets of different
/// shading points are independent. Evaluating a Sobol' point per light sample
/// instead cost 8% of the default render; a mere digital shift (an XOR) of the table
/// kept the strata but not the spread of an Owen scramble (a furnace pixel 14% off
/// where Owen-scrambled nets left at most 10%).
#[derive(Clone, Copy, Debug)]
pub struct Net4 {
    seeds: [u32; 4],
}

/// Owen scrambling of the bits of `x` in base 2, as a hash (Laine and Karras 2011;
/// Burley 2020, section 3, with his constants): bit-reverse, a permutation that only
/// lets each bit depend on the bits below it, reverse back, so each bit is flipped
/// by a function of the bits above it.
#[inline]
fn owen_scramble(x: u32, seed: u32) -> u32 {
    let mut x = x.reverse_bits();
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x.reverse_bits()
}

/// The leading points of one fixed Owen-scrambled 4-D Sobol' net, kept as their 24
/// significant bits, for [`Net4`]s to scramble again. Computed once by whoever
/// samples with nets (no global state here).
#[derive(Clone, Debug)]
pub struct NetTable {
    points: Vec<[u32; 4]>,
}

impl NetTable {
    /// Seed of the fixed scramble.
    const SEED: u32 = 0x6e65_7434;

    /// The first `n` points (at most 2^16).
    pub fn new(n: u32) -> NetTable {
        let n = n.min(1 << 16);
        let bits = |v: f32| ((v * (1u32 << 24) as f32) as u32).min((1 << 24) - 1) << 8;
        let seed = Self::SEED;
        NetTable { points: (0..n).map(|k| sobol_4d(shuffle_index(k, seed), 0, seed).map(bits)).collect() }
    }
}

impl Net4 {
    /// Point `k` of the net: the table's point k scrambled when the table holds all
    /// `n` points the caller uses, else point k of a Sobol' net Owen-scrambled by the
    /// seeds (a set is drawn from one net or the other, never both). Coordinates in
    /// [0, 1); the first 2^16 points are distinct.
    #[inline]
    pub fn point(&self, table: &NetTable, n: u32, k: u32) -> [f32; 4] {
        match table.points.get(k as usize) {
            Some(p) if n as usize <= table.points.len() => {
                let mut out = [0.0; 4];
                for i in 0..4 {
                    out[i] = (owen_scramble(p[i], self.seeds[i]) >> 8) as f32 * (1.0 / (1u32 << 24) as f32);
                }
                out
            }
            _ => sobol_4d(shuffle_index(k & 0xffff, self.seeds[0]), 0, self.seeds[0]).map(|v| v.min(ONE_MINUS_EPSILON)),
        }
    }
}

/// An orthonormal basis around a unit normal (Duff et al. 2017, "Building an
/// Orthonormal Basis, Revisited"): returns (tangent, bitangent).
#[inline]
pub fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// Express a local direction (z = normal) in world space around `n`.
#[inline]
pub fn to_world(local: Vec3, n: Vec3) -> Vec3 {
    let (t, b) = basis(n);
    t * local.x + b * local.y + n * local.z
}

/// Concentric map of the unit square to the unit disk (Shirley and Chiu 1997).
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, std::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Cosine-weighted direction on the hemisphere around +z (Malley's method);
/// pdf = cos(theta) / pi [sr^-1].
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Density of [`cosine_hemisphere`] [sr^-1].
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform direction on the unit sphere; pdf = 1 / (4 pi) [sr^-1].
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Equiangular sampling of a distance along a ray segment [t0, t1] for a point at
/// distance `h` > 0 from the ray's line whose foot is at `t_foot` (Kulla and Fajardo
/// 2012, "Importance sampling techniques for path tracing in participating media",
/// section 4.1): t = t_foot + h tan(theta), theta uniform between the segment ends'
/// angles, so the density h / ((theta1 - theta0) (h^2 + (t - t_foot)^2)) [m^-1]
/// cancels the 1 / r^2 of a point light. Returns (t, density); `None` for an
/// empty segment or h not positive.
pub fn equiangular(u: f32, h: f32, t_foot: f32, t0: f32, t1: f32) -> Option<(f32, f32)> {
    if !(h > 0.0 && t1 > t0) {
        return None;
    }
    let a0 = ((t0 - t_foot) / h).atan();
    let a1 = ((t1 - t_foot) / h).atan();
    if !(a1 > a0) {
        return None;
    }
    let t = (t_foot + h * (a0 + u * (a1 - a0)).tan()).clamp(t0, t1);
    Some((t, equiangular_pdf(t, h, t_foot, a1 - a0)))
}

/// Density [m^-1] of [`equiangular`] at `t`, for the angle `span` its segment
/// subtends.
#[inline]
pub fn equiangular_pdf(t: f32, h: f32, t_foot: f32, span: f32) -> f32 {
    let x = t - t_foot;
    h / (span * (h * h + x * x))
}

/// Uniform direction in the cone of half-angle acos(cos_max) around +z;
/// pdf = 1 / (2 pi (1 - cos_max)) [sr^-1].
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_t = 1.0 - u.x * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Density of [`uniform_cone`] [sr^-1].
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (TAU * (1.0 - cos_max))
}

/// Uniform direction in a small cone around +z given by `cap` = 1 - cos(theta_max)
/// (the sun's disc: a 0.5-degree sun has cap 9.5e-6, which 1 - cos_max in f32
/// holds only to 0.6%); pdf = [`uniform_cap_pdf`].
pub fn uniform_cap(u: Vec2, cap: f32) -> Vec3 {
    let one_minus_cos = u.x * cap;
    let cos_t = 1.0 - one_minus_cos;
    let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Density of [`uniform_cap`] [sr^-1]: 1 / (2 pi cap).
pub fn uniform_cap_pdf(cap: f32) -> f32 {
    1.0 / (TAU * cap)
}

/// True when unit direction `d` lies in the cone of `cap` = 1 - cos(theta_max)
/// around unit `axis`: |d - axis|^2 = 2 (1 - cos) <= 2 cap, precise for small
/// cones where d . axis rounds to 1.
pub fn in_cap(d: Vec3, axis: Vec3, cap: f32) -> bool {
    (d - axis).length_squared() <= 2.0 * cap
}

/// Uniform barycentrics (b0, b1) on a triangle (pbrt-v4's area-preserving warp,
/// Heitz 2019 "A Low-Distortion Map Between Triangle and Square").
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    let (b0, b1);
    if u.x < u.y {
        b0 = u.x / 2.0;
        b1 = u.y - b0;
    } else {
        b1 = u.y / 2.0;
        b0 = u.x - b1;
    }
    Vec2::new(b0, b1)
}

/// Solid angle \[sr\] of the spherical triangle with unit vertices `a`, `b`, `c`:
/// tan(Ω / 2) = |a·(b×c)| / (1 + a·b + b·c + c·a) (Van Oosterom and Strackee 1983),
/// which keeps its precision for small and nearly flat triangles where the sum of
/// the angles minus π loses it. In f64: seen from a point 0.1 mm from a 1 m edge,
/// two corners are π - 2e-4 apart, and f32 rounds their cosine to -1.
pub fn spherical_triangle_area(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let num = a.dot(b.cross(c)).abs();
    let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    (2.0 * num.atan2(den)) as f32
}

/// ∫ max(0, n·ω) dω \[sr\] over the directions from the origin to the planar polygon
/// `verts` (vertices relative to the point, in order): the polygon is clipped to the
/// half-space n·x >= 0 and Lambert's formula summed over its edges, 1/2 Σ Θ_i
/// n·(v_i × v_{i+1}) / |v_i × v_{i+1}|, Θ_i the angle between the directions to
/// consecutive vertices (as atan2 of the cross and dot products, which keeps its
/// precision for nearly opposite directions; a polynomial one, to 2e-6 rad). Times
/// L_e it is the irradiance [W m^-2] from a uniform Lambertian emitter. Up to 16
/// vertices are read.
///
/// Every term is unchanged by the lengths of v_i and v_{i+1} (the angle's atan2 and
/// the unit normal of their plane both take a ratio), so the corners are not
/// normalised, and four edges are evaluated at once, one a lane; a polygon of at
/// most four corners wholly above the horizon (a quad light, seen from most points
/// of a room) skips the clipping. It is called at every shading point of a
/// closed-form light: one edge at a time, with a square root and two divisions per
/// corner, it took 76 ns a quad and was a third of a live frame's direct step with
/// shadow maps; now about 30 ns.
pub fn polygon_cos_integral(verts: &[Vec3], n: Vec3) -> f32 {
    const MAX: usize = 16;
    let v = &verts[..verts.len().min(MAX)];
    let k = v.len();
    if k <= 4 && v.iter().all(|q| q.dot(n) >= 0.0) {
        // Nothing to clip (a quad light wholly above the horizon, the usual case).
        let a = std::array::from_fn(|i| if i < k { v[i] } else { Vec3::ZERO });
        let b = std::array::from_fn(|i| if i < k { v[(i + 1) % k] } else { Vec3::ZERO });
        return (0.5 * lambert_edges(&a, &b, n).element_sum()).abs();
    }
    // Clipping adds at most one corner per edge; then the first corner again, and
    // zeros for the last block of four to read past the end.
    let mut c = [Vec3::ZERO; 2 * MAX + 1 + 3];
    let mut m = 0;
    for i in 0..k {
        let (a, b) = (v[i], v[(i + 1) % k]);
        let (da, db) = (a.dot(n), b.dot(n));
        if da >= 0.0 {
            c[m] = a;
            m += 1;
        }
        if (da >= 0.0) != (db >= 0.0) {
            c[m] = a + (b - a) * (da / (da - db));
            m += 1;
        }
    }
    if m == 0 {
        return 0.0;
    }
    c[m] = c[0];
    let mut sum = Vec4::ZERO;
    for s in (0..m).step_by(4) {
        let block = |i: usize| std::array::from_fn(|j| c[s + i + j]);
        sum += lambert_edges(&block(0), &block(1), n);
    }
    (0.5 * sum.element_sum()).abs()
}

/// The terms Θ n·(a × b) / |a × b| of Lambert's formula for four edges from corner
/// a\[i\] to b\[i\] (relative to the point), one a lane; 0 for an edge with no plane
/// (through the point, or a lane of zero padding).
#[inline]
fn lambert_edges(a: &[Vec3; 4], b: &[Vec3; 4], n: Vec3) -> Vec4 {
    let lanes = |c: &[Vec3; 4]| {
        (
            Vec4::new(c[0].x, c[1].x, c[2].x, c[3].x),
            Vec4::new(c[0].y, c[1].y, c[2].y, c[3].y),
            Vec4::new(c[0].z, c[1].z, c[2].z, c[3].z),
        )
    };
    let ((ax, ay, az), (bx, by, bz)) = (lanes(a), lanes(b));
    let (cx, cy, cz) = (ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx);
    let len = (cx * cx + cy * cy + cz * cz).sqrt();
    let term = angle(len, ax * bx + ay * by + az * bz) * (n.x * cx + n.y * cy + n.z * cz) / len;
    Vec4::select(len.cmpgt(Vec4::ZERO), term, Vec4::ZERO)
}

/// atan2(y, x) for y >= 0 [rad], lane by lane, to within 2e-6 rad (and 3e-5
/// relative): an odd polynomial of degree 11 for atan on [0, 1] (in Estrin's form,
/// a shorter chain of dependent operations than Horner's) and the octant
/// symmetries. A fifth of the libm call's time; Lambert's formula calls it per edge at
/// every shading point. Lanes with x = y = 0 give 0.
#[inline]
fn angle(y: Vec4, x: Vec4) -> Vec4 {
    let ax = x.abs();
    let (lo, hi) = (ax.min(y), ax.max(y));
    let t = lo / hi;
    let t2 = t * t;
    let t4 = t2 * t2;
    let r = ((0.999_977_26 - 0.332_623_47 * t2)
        + t4 * ((0.193_543_46 - 0.116_432_87 * t2) + t4 * (0.052_653_32 - 0.011_721_2 * t2)))
        * t;
    let r = Vec4::select(y.cmpgt(ax), Vec4::splat(std::f32::consts::FRAC_PI_2) - r, r);
    let r = Vec4::select(x.cmplt(Vec4::ZERO), Vec4::splat(PI) - r, r);
    Vec4::select(hi.cmpgt(Vec4::ZERO), r, Vec4::ZERO)
}

/// A direction distributed uniformly in solid angle over the spherical triangle
/// with unit vertices `a`, `b`, `c` of area `area` (its solid angle,
/// [`spherical_triangle_area`]), from `u` in [0, 1)^2 (Arvo 1995, "Stratified
/// sampling of spherical triangles"): `u.x` chooses the point C' on arc AC such that
/// triangle ABC' has area `u.x` x `area`, `u.y` a point on arc BC' with the cosine
/// to B uniform, which is uniform in area within ABC'. The map is continuous, so
/// stratified `u` give stratified directions. Computed in f64 (see
/// [`spherical_triangle_area`]). `None` for a degenerate triangle.
pub fn sample_spherical_triangle(a: Vec3, b: Vec3, c: Vec3, area: f32, u: Vec2) -> Option<Vec3> {
    use glam::DVec3;
    let (a, b, c) = (a.as_dvec3().normalize(), b.as_dvec3().normalize(), c.as_dvec3().normalize());
    // The angle at A, between the great circles AB and AC.
    let (n_ab, n_ac) = (a.cross(b).normalize_or_zero(), a.cross(c).normalize_or_zero());
    if n_ab == DVec3::ZERO || n_ac == DVec3::ZERO {
        return None;
    }
    let cos_alpha = n_ab.dot(n_ac).clamp(-1.0, 1.0);
    let sin_alpha = (1.0 - cos_alpha * cos_alpha).max(0.0).sqrt();
    let cos_c = a.dot(b);
    // Area of the sub-triangle ABC', and C' on arc AC (Arvo's equations).
    let sub = u.x as f64 * area as f64;
    let (s, t) = (sub - cos_alpha.acos()).sin_cos();
    let uu = t - cos_alpha;
    let v = s + sin_alpha * cos_c;
    let den = (v * s + uu * t) * sin_alpha;
    if den == 0.0 {
        return None;
    }
    let q = (((v * t - uu * s) * cos_alpha - v) / den).clamp(-1.0, 1.0);
    let c_perp = (c - a * c.dot(a)).normalize_or_zero();
    let c1 = a * q + c_perp * (1.0 - q * q).max(0.0).sqrt();
    // A point on arc BC', uniform in the cosine to B.
    let z = 1.0 - u.y as f64 * (1.0 - c1.dot(b));
    let c1_perp = (c1 - b * c1.dot(b)).normalize_or_zero();
    let w = (b * z + c1_perp * (1.0 - z * z).max(0.0).sqrt()).as_vec3().normalize_or_zero();
    (w != Vec3::ZERO && w.is_finite()).then_some(w)
}

/// Choose an index from a discrete distribution by a cumulative table (last entry is
/// the total, entries non-decreasing). Returns the index; u in [0,1).
pub fn sample_cdf(cdf: &[f64], u: f32) -> usize {
    let total = *cdf.last().unwrap_or(&0.0);
    let target = u as f64 * total;
    let i = cdf.partition_point(|&c| c <= target);
    i.min(cdf.len().saturating_sub(1))
}

/// A piecewise-constant density over the unit square, proportional to a grid of
/// non-negative weights (`width` x `height` cells, row 0 at v = 0), sampled by
/// inversion: a row by the rows' marginal, then a column within it, each
/// continuous within its cell (pbrt-v4 section A.5.6, `PiecewiseConstant2D`). What
/// an environment image is importance-sampled by.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    width: usize,
    height: usize,
    /// Per row, the cumulative weights of its cells (the last is the row's sum).
    rows: Vec<f64>,
    /// Cumulative row sums (the last is the total).
    marginal: Vec<f64>,
}

impl Distribution2D {
    /// Bytes its tables hold.
    pub fn memory_bytes(&self) -> usize {
        (self.rows.capacity() + self.marginal.capacity()) * 8
    }

    /// The density of `weights` (row-major, `width` x `height`). None when the
    /// grid is empty, a weight is negative or not finite, or all are zero.
    pub fn new(width: usize, height: usize, weights: &[f64]) -> Option<Distribution2D> {
        if width == 0 || height == 0 || weights.len() != width * height {
            return None;
        }
        if weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return None;
        }
        let mut rows = Vec::with_capacity(weights.len());
        let mut marginal = Vec::with_capacity(height);
        let mut total = 0.0;
        for row in weights.chunks(width) {
            let mut acc = 0.0;
            for w in row {
                acc += w;
                rows.push(acc);
            }
            total += acc;
            marginal.push(total);
        }
        (total > 0.0).then_some(Distribution2D { width, height, rows, marginal })
    }

    /// Pick a cell of the cumulative table `cdf` by `u` in [0, 1), continuously:
    /// the index and the offset within the cell in [0, 1).
    fn invert(cdf: &[f64], u: f32) -> (usize, f32) {
        let i = sample_cdf(cdf, u);
        let target = u as f64 * cdf[cdf.len() - 1];
        let lo = if i == 0 { 0.0 } else { cdf[i - 1] };
        let w = cdf[i] - lo;
        let off = if w > 0.0 { ((target - lo) / w) as f32 } else { 0.5 };
        (i, off.clamp(0.0, ONE_MINUS_EPSILON))
    }

    /// A point of the square with this density, and the density there (w.r.t.
    /// area of the unit square; the mean density is 1).
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (y, fy) = Self::invert(&self.marginal, u.y);
        let row = &self.rows[y * self.width..(y + 1) * self.width];
        let (x, fx) = Self::invert(row, u.x);
        let p = Vec2::new((x as f32 + fx) / self.width as f32, (y as f32 + fy) / self.height as f32);
        (p, self.cell_pdf(x, y))
    }

    /// The density at point `p` of the unit square (0 outside it).
    pub fn pdf(&self, p: Vec2) -> f32 {
        if !(p.x >= 0.0 && p.y >= 0.0 && p.x < 1.0 && p.y < 1.0) {
            return 0.0;
        }
        let x = ((p.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((p.y * self.height as f32) as usize).min(self.height - 1);
        self.cell_pdf(x, y)
    }

    /// The density of cell (x, y): its weight over the mean weight.
    fn cell_pdf(&self, x: usize, y: usize) -> f32 {
        let row = &self.rows[y * self.width..(y + 1) * self.width];
        let w = row[x] - if x == 0 { 0.0 } else { row[x - 1] };
        let total = self.marginal[self.height - 1];
        (w * (self.width * self.height) as f64 / total) as f32
    }
}

/// 4 pi: the solid angle of the sphere \[sr\].
pub const FOUR_PI: f32 = 2.0 * TAU;
/// pi, re-exported for radiometric formulas (E = pi L for a uniform hemisphere).
pub const PI_F32: f32 = PI;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A shading point's net of n = 4^m points puts exactly one point in each of the
    /// 2^m x 2^m strata of its first two coordinates, and n / 4 in each quarter of
    /// the others; nets of different shading points (streams, or draws of one
    /// stream) are scrambled differently. Independent draws would fail both counts.
    #[test]
    fn light_sample_nets_are_stratified() {
        // A table holding all 64 points, and one too short, whose sets come from the
        // Owen-scrambled fallback.
        for table in [NetTable::new(64), NetTable::new(8)] {
            let mut firsts = std::collections::HashSet::new();
            for index in 0..200u64 {
                let mut s = Sampler::new(5, index);
                for _draw in 0..3 {
                    let net = s.net_4d();
                    firsts.insert(net.point(&table, 64, 0).map(f32::to_bits));
                    for (m, side) in [(1u32, 2usize), (2, 4), (3, 8)] {
                        let n = 1u32 << (2 * m);
                        let mut cells = vec![0u32; side * side];
                        let mut quarters = [[0u32; 4]; 2];
                        for k in 0..n {
                            let u = net.point(&table, n, k);
                            assert!(u.iter().all(|&v| (0.0..1.0).contains(&v)));
                            let cell = |v: f32| (v * side as f32) as usize;
                            cells[cell(u[1]) * side + cell(u[0])] += 1;
                            quarters[0][(u[2] * 4.0) as usize] += 1;
                            quarters[1][(u[3] * 4.0) as usize] += 1;
                        }
                        assert!(cells.iter().all(|&c| c == 1), "index {index}, n {n}: {cells:?}");
                        assert!(quarters.iter().flatten().all(|&c| c == n / 4), "index {index}, n {n}: {quarters:?}");
                    }
                }
            }
            assert_eq!(firsts.len(), 600, "nets share scrambles");
        }
    }

    /// The four-at-a-time cache and the deferred hashing give exactly the scalar
    /// Owen-scrambled Sobol' values (and the hashed noise past them), for plain and
    /// salted streams across a block boundary of indices.
    #[test]
    fn streams_equal_the_scalar_definition() {
        for (seed, salt, index) in [(1u64, None, 0u64), (7, Some(3u64), 5), (99, Some(0x7069_7865_6c00), 70_000)] {
            let base = salt.map_or(seed, |salt| mix64(seed ^ mix64(salt)));
            let block_seed = mix64(base ^ mix64((index >> 16).wrapping_add(0x9e37_79b9_7f4a_7c15))) as u32;
            let noise_key = mix64(base.wrapping_mul(0x2545_f491_4f6c_dd1d) ^ index);
            let mut s = match salt {
                Some(salt) => Sampler::salted(seed, salt, index),
                None => Sampler::new(seed, index),
            };
            for d in 0..300u32 {
                let want = if d < Sampler::SOBOL_DIMS {
                    sobol_burley::sample((index & 0xffff) as u32, d, block_seed).min(ONE_MINUS_EPSILON)
                } else {
                    let h = mix64(noise_key ^ (d as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
                    ((h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)).min(ONE_MINUS_EPSILON)
                };
                assert_eq!(s.next_1d().to_bits(), want.to_bits(), "seed {seed} index {index} dim {d}");
            }
        }
    }

    /// Distribution2D's samples land in each cell in proportion to its weight
    /// (zero-weight cells never), its density is the weight over the mean weight
    /// wherever a sample lands and integrates to 1 over the square, and invalid
    /// weights are refused.
    #[test]
    fn piecewise_constant_2d_samples_its_weights() {
        let (w, h) = (5, 3);
        let weights: Vec<f64> = (0..w * h).map(|i| if i % 4 == 1 { 0.0 } else { (i % 7 + 1) as f64 }).collect();
        let d = Distribution2D::new(w, h, &weights).unwrap();
        let total: f64 = weights.iter().sum();
        let n = 1 << 16;
        let mut counts = vec![0u32; w * h];
        for k in 0..n {
            let (p, pdf) = d.sample(Sampler::new(3, k).next_2d());
            let (x, y) = ((p.x * w as f32) as usize, (p.y * h as f32) as usize);
            let cell = y * w + x;
            counts[cell] += 1;
            let want = weights[cell] * (w * h) as f64 / total;
            assert!((pdf as f64 - want).abs() < 1e-5 * want && d.pdf(p) == pdf, "cell {cell}: {pdf} vs {want}");
        }
        for (cell, &c) in counts.iter().enumerate() {
            let expect = n as f64 * weights[cell] / total;
            assert!((c as f64 - expect).abs() <= 4.0 * expect.sqrt() + 1.0, "cell {cell}: {c} vs {expect}");
        }
        // Midpoint integral of the density over a fine grid: 1.
        let m = 200;
        let integral: f64 = (0..m * m)
            .map(|i| d.pdf(Vec2::new(((i % m) as f32 + 0.5) / m as f32, ((i / m) as f32 + 0.5) / m as f32)) as f64)
            .sum::<f64>()
            / (m * m) as f64;
        assert!((integral - 1.0).abs() < 0.01, "{integral}");
        assert!(Distribution2D::new(2, 1, &[1.0, -1.0]).is_none());
        assert!(Distribution2D::new(2, 1, &[1.0, f64::NAN]).is_none());
        assert!(Distribution2D::new(2, 1, &[0.0, 0.0]).is_none());
        assert!(Distribution2D::new(2, 2, &[1.0, 1.0]).is_none());
    }

    /// `sobol_nibbles.bin` is what `sobol_burley` generates: for each set, group
    /// and value, the Sobol' point of the reversed index holding only that group's
    /// bits. With `PM_WRITE_TABLES=1` the file is written instead (after a
    /// `sobol_burley` update).
    #[test]
    fn nibble_tables_are_sobol_burleys() {
        assert_eq!(sobol_burley::NUM_DIMENSION_SETS_4D as usize, SOBOL_SETS);
        let mut bytes = Vec::new();
        for set in 0..SOBOL_SETS as u32 {
            for group in 0..4u32 {
                for value in 0..16u32 {
                    let rev = value << (28 - 4 * group);
                    let v: [u32; 4] = sobol_burley::parts::sobol_int4_rev(rev, set).into();
                    bytes.extend(v.iter().flat_map(|x| x.to_le_bytes()));
                }
            }
        }
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/sobol_nibbles.bin");
        if std::env::var_os("PM_WRITE_TABLES").is_some() {
            std::fs::write(&path, &bytes).unwrap();
        }
        let committed = std::fs::read(&path).unwrap_or_default();
        assert!(committed == bytes, "{} is stale: run PM_WRITE_TABLES=1 cargo test -p pm-sampling", path.display());
    }

    /// The nibble tables give `sobol_burley::sample_4d` bit for bit: every
    /// dimension set, indices with every bit pattern of a few thousand (including 0
    /// and 2^16 - 1), several seeds. A wrong table entry or group shift fails here.
    #[test]
    fn table_sobol_points_equal_sobol_burley() {
        let indices = (0..4096u32).map(|i| mix64(i as u64) as u32 & 0xffff).chain([0, 1, 0x8000, 0xffff]);
        for i in indices {
            for seed in [0u32, 1, 0x6e65_7434, 0xdead_beef] {
                for set in 0..Sampler::SOBOL_DIMS / 4 {
                    let got = sobol_4d(shuffle_index(i, seed), set, seed).map(f32::to_bits);
                    assert_eq!(got, sobol_burley::sample_4d(i, set, seed).map(f32::to_bits), "index {i} set {set}");
                }
            }
        }
    }

    /// Lambert's closed form against Monte Carlo (area sampling, 2^18 stratified
    /// points) for triangles above the horizon, straddling it (clipped) and below
    /// it (zero), and a quad. Without the clipping the straddling triangle comes out
    /// wrong by its part below the horizon.
    /// The polynomial atan2 against the library's over every octant, near the axes
    /// and at tiny angles (relative error there: Lambert's formula divides by sin).
    #[test]
    fn polynomial_angle_is_within_2e_6_rad() {
        let angle = |y: f32, x: f32| super::angle(Vec4::splat(y), Vec4::splat(x)).x;
        let mut worst: f32 = 0.0;
        for i in 0..=20_000 {
            let phi = std::f32::consts::PI * i as f32 / 20_000.0;
            for r in [1e-3f32, 1.0, 7e3] {
                let (y, x) = (r * phi.sin().abs(), r * phi.cos());
                worst = worst.max((angle(y, x) - y.atan2(x)).abs());
            }
        }
        assert!(worst < 2e-6, "largest error {worst} rad");
        for t in [1e-6f32, 1e-4, 1e-2] {
            assert!((angle(t, 1.0) / t.atan2(1.0) - 1.0).abs() < 3e-5);
        }
        assert_eq!(angle(0.0, 0.0), 0.0);
    }

    #[test]
    fn polygon_cos_integrals_equal_monte_carlo() {
        let n = Vec3::Z;
        let cases: [&[Vec3]; 4] = [
            &[Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.5, -0.5, 2.5), Vec3::new(0.0, 1.0, 1.5)],
            &[Vec3::new(-1.0, 0.5, -0.6), Vec3::new(1.2, 0.4, 0.8), Vec3::new(0.1, 1.5, 0.3)],
            &[Vec3::new(-1.0, 0.5, -0.6), Vec3::new(1.2, 0.4, -0.8), Vec3::new(0.1, 1.5, -0.3)],
            &[Vec3::new(-0.5, 0.3, 0.0), Vec3::new(0.5, 0.3, 0.0), Vec3::new(0.5, 0.3, 1.0), Vec3::new(-0.5, 0.3, 1.0)],
        ];
        for verts in cases {
            let m = 1usize << 18;
            let mut mc = 0.0f64;
            for t in 1..verts.len() - 1 {
                let (a, b, c) = (verts[0], verts[t], verts[t + 1]);
                let (ng, area) = ((b - a).cross(c - a).normalize(), 0.5 * (b - a).cross(c - a).length());
                for k in 0..m {
                    let bc = uniform_triangle(Vec2::new((k as f32 + 0.5) / m as f32, radical_inverse(k)));
                    let q = a * bc.x + b * bc.y + c * (1.0 - bc.x - bc.y);
                    let w = q.normalize();
                    mc += (area * w.dot(n).max(0.0) * w.dot(ng).abs() / q.length_squared()) as f64 / m as f64;
                }
            }
            let got = polygon_cos_integral(verts, n) as f64;
            assert!((got - mc).abs() <= 2e-3 * mc.max(1e-2), "closed form {got}, Monte Carlo {mc}");
        }
    }

    /// Lambert's formula four edges at a time, on unnormalised corners, against the
    /// same formula one edge at a time in f64 with normalised corners and the
    /// library's atan2: random convex and star-shaped polygons of 3 to 16 corners,
    /// near and far, above, across and below the horizon, and stars of eight teeth
    /// whose horizon crosses several (the clipped polygon then has more corners
    /// than the input). A lane mask that let the padding lanes or the wrap-around edge in, or
    /// a dropped clip, would be off by whole edges' terms.
    #[test]
    fn polygon_cos_integral_matches_an_edge_by_edge_reference() {
        fn reference(verts: &[Vec3], n: Vec3) -> f64 {
            let n = n.as_dvec3();
            let mut clipped = Vec::new();
            for i in 0..verts.len() {
                let (a, b) = (verts[i].as_dvec3(), verts[(i + 1) % verts.len()].as_dvec3());
                let (da, db) = (a.dot(n), b.dot(n));
                if da >= 0.0 {
                    clipped.push(a);
                }
                if (da >= 0.0) != (db >= 0.0) {
                    clipped.push(a + (b - a) * (da / (da - db)));
                }
            }
            let mut sum = 0.0;
            for i in 0..clipped.len() {
                let (a, b) = (clipped[i].normalize(), clipped[(i + 1) % clipped.len()].normalize());
                let c = a.cross(b);
                if c.length() > 0.0 {
                    sum += c.length().atan2(a.dot(b)) * n.dot(c) / c.length();
                }
            }
            (0.5 * sum).abs()
        }
        let h = |i: u64| (mix64(i) >> 40) as f32 / (1u64 << 24) as f32;
        for case in 0..4000u64 {
            let k = 3 + (case % 14) as usize;
            let centre = Vec3::new(h(case * 8) - 0.5, h(case * 8 + 1) - 0.5, h(case * 8 + 2) - 0.3) * 4.0;
            let scale = 0.05 + 2.0 * h(case * 8 + 3);
            let tilt = Vec3::new(h(case * 8 + 4) - 0.5, h(case * 8 + 5) - 0.5, 1.0).normalize();
            let (u, v) = {
                let t = if tilt.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
                let u = tilt.cross(t).normalize();
                (u, tilt.cross(u))
            };
            // Every fifth a star of eight teeth whose horizon cuts through several.
            let star = case % 5 == 0;
            let (centre, u, v, k) =
                if star { (Vec3::new(0.0, -0.6 * scale, 1.0), Vec3::X, Vec3::Y, 16) } else { (centre, u, v, k) };
            let verts: Vec<Vec3> = (0..k)
                .map(|j| {
                    let phi = std::f32::consts::TAU * (j as f32 + h(case * 8 + 6)) / k as f32;
                    let r = if star || case % 3 == 0 { if j % 2 == 0 { 1.0 } else { 0.35 } } else { 1.0 };
                    centre + (u * phi.cos() + v * phi.sin()) * (r * scale)
                })
                .collect();
            let n = if star { Vec3::Y } else { Vec3::Z };
            let (got, want) = (polygon_cos_integral(&verts, n) as f64, reference(&verts, n));
            // f32 terms of up to pi each, summed: an absolute allowance for the
            // cancellation when only a sliver is above the horizon.
            let err = (got - want).abs();
            assert!(err < 3e-5 + 1e-4 * want, "case {case}: {got} against {want}");
        }
    }

    /// Solid-angle sampling of spherical triangles (Arvo 1995): every direction
    /// falls inside the triangle; Ω from the Van Oosterom-Strackee formula equals a
    /// Monte Carlo estimate by area sampling; the sampled directions' mean cosine
    /// times Ω equals Lambert's closed form for the polygon, for triangles far, near
    /// and almost edge-on (each within 0.5% at 2^16 stratified samples); and the
    /// first coordinate stratifies: u.x = 1/2 splits off half the solid angle. A wrong
    /// vertex angle or arc formula fails the cosine or the half-area count.
    #[test]
    fn spherical_triangles_are_sampled_uniformly_in_solid_angle() {
        let n = Vec3::Z;
        let tris = [
            [Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.5, -0.5, 2.5), Vec3::new(0.0, 1.0, 1.5)],
            [Vec3::new(-0.05, 0.01, 0.02), Vec3::new(1.0, 0.0, 0.5), Vec3::new(0.3, 1.0, 0.05)],
            [Vec3::new(0.2, -0.3, 0.01), Vec3::new(2.0, 0.1, 0.05), Vec3::new(0.5, 1.5, 0.3)],
            // Half of a 0.24 m light seen from 13 mm and 2 mm away (nearly half the
            // hemisphere, angles near pi: where Arvo's map is worst conditioned;
            // the differential checker's lights just under a ceiling, issue 53).
            [Vec3::new(-0.12, -0.12, 0.013), Vec3::new(0.12, -0.12, 0.013), Vec3::new(0.12, 0.12, 0.013)],
            [Vec3::new(-0.1, -0.14, 0.013), Vec3::new(0.14, -0.14, 0.013), Vec3::new(0.14, 0.1, 0.013)],
            [Vec3::new(-0.2, -0.01, 0.013), Vec3::new(0.04, -0.01, 0.013), Vec3::new(0.04, 0.23, 0.013)],
            [Vec3::new(-0.12, -0.12, 0.002), Vec3::new(0.12, -0.12, 0.002), Vec3::new(0.12, 0.12, 0.002)],
        ];
        for t in tris {
            let (a, b, c) = (t[0].normalize(), t[1].normalize(), t[2].normalize());
            let omega = spherical_triangle_area(a, b, c);
            // Ω = ∫ cos_l / d^2 dA by area sampling.
            let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
            let (ng, area) = (e1.cross(e2).normalize(), 0.5 * e1.cross(e2).length());
            let m = 1 << 16;
            let mut omega_area = 0.0f64;
            for k in 0..m {
                let bc = uniform_triangle(Vec2::new((k as f32 + 0.5) / m as f32, radical_inverse(k)));
                let q = t[0] * bc.x + t[1] * bc.y + t[2] * (1.0 - bc.x - bc.y);
                omega_area += (area * q.normalize().dot(ng).abs() / q.length_squared()) as f64 / m as f64;
            }
            assert!((omega as f64 / omega_area - 1.0).abs() < 5e-3, "Ω {omega} vs {omega_area}");
            let mut cos_sum = 0.0f64;
            for k in 0..m {
                let u = Vec2::new((k as f32 + 0.5) / m as f32, radical_inverse(k));
                let w = sample_spherical_triangle(a, b, c, omega, u).expect("a proper triangle");
                // Inside: on the inner side of the three great circles.
                let side = a.cross(b).dot(c).signum();
                for (p, q) in [(a, b), (b, c), (c, a)] {
                    assert!(p.cross(q).dot(w) * side > -1e-4, "direction {w} outside");
                }
                cos_sum += w.dot(n).max(0.0) as f64;
            }
            let want = polygon_cos_integral(&t, n) as f64;
            let got = omega as f64 * cos_sum / m as f64;
            assert!((got / want - 1.0).abs() < 5e-3, "∫cos: sampled {got}, Lambert {want}");
            // u.x = 1/2 (with u.y = 1, the point C' itself) halves the area.
            let c_half = sample_spherical_triangle(a, b, c, omega, Vec2::new(0.5, 1.0)).unwrap();
            let sub = spherical_triangle_area(a, b, c_half);
            assert!((sub / omega - 0.5).abs() < 1e-3, "half area: {sub} of {omega}");
        }
    }

    fn radical_inverse(k: usize) -> f32 {
        (k as u32).reverse_bits() as f32 * (1.0 / 4_294_967_296.0)
    }

    /// A hashed stream is the salted stream's noise (from its dimension 256 on), and
    /// across streams its first two dimensions are uniform and independent in the
    /// square, as point 0 of an Owen-scrambled Sobol' sequence is: chi-square over
    /// 16 x 16 cells of 65,536 streams, 255 degrees of freedom (p = 0.001 at 330).
    #[test]
    fn hashed_streams_are_uniform_points_of_the_square() {
        let mut h = Sampler::hashed(5, 77);
        let mut s = Sampler::salted(5, 77, 0);
        for _ in 0..Sampler::SOBOL_DIMS {
            s.next_1d();
        }
        for _ in 0..40 {
            assert_eq!(h.next_1d().to_bits(), s.next_1d().to_bits());
        }
        let mut cells = [0u32; 256];
        let n = 1u64 << 16;
        for salt in 0..n {
            let u = Sampler::hashed(9, salt).next_2d();
            cells[(u.x * 16.0) as usize * 16 + (u.y * 16.0) as usize] += 1;
        }
        let e = n as f64 / 256.0;
        let chi2: f64 = cells.iter().map(|&c| (c as f64 - e).powi(2) / e).sum();
        assert!(chi2 < 330.0, "chi-square {chi2}");
    }

    #[test]
    fn streams_are_keyed_by_index_not_call_order() {
        let a: Vec<f32> = {
            let mut s = Sampler::new(7, 123_456);
            (0..300).map(|_| s.next_1d()).collect()
        };
        let _other = {
            let mut s = Sampler::new(7, 5);
            s.next_1d()
        };
        let b: Vec<f32> = {
            let mut s = Sampler::new(7, 123_456);
            (0..300).map(|_| s.next_1d()).collect()
        };
        assert_eq!(a, b);
        assert!(a.iter().all(|&x| (0.0..1.0).contains(&x)));
    }

    #[test]
    fn stratified_first_dimension_has_low_discrepancy() {
        // 1024 consecutive indices fall one in each of 1024 strata (Sobol' property,
        // preserved by Owen scrambling).
        let mut hits = vec![0u32; 1024];
        for i in 0..1024 {
            let x = Sampler::new(3, i).next_1d();
            hits[(x * 1024.0) as usize] += 1;
        }
        assert!(hits.iter().all(|&h| h == 1));
    }

    #[test]
    fn cosine_hemisphere_mean_cos_is_two_thirds() {
        // E[cos] under pdf cos/pi is 2/3.
        let n = 1 << 14;
        let mean: f64 = (0..n)
            .map(|i| {
                let mut s = Sampler::new(1, i);
                cosine_hemisphere(s.next_2d()).z as f64
            })
            .sum::<f64>()
            / n as f64;
        assert!((mean - 2.0 / 3.0).abs() < 1e-3, "{mean}");
    }

    #[test]
    fn cdf_sampling_respects_weights_and_zero_entries() {
        let cdf = [1.0, 1.0, 4.0];
        assert_eq!(sample_cdf(&cdf, 0.0), 0);
        assert_eq!(sample_cdf(&cdf, 0.24), 0);
        assert_eq!(sample_cdf(&cdf, 0.26), 2);
        assert_eq!(sample_cdf(&cdf, ONE_MINUS_EPSILON), 2);
    }

    proptest! {
        #[test]
        fn basis_is_orthonormal(x in -1f32..1.0, y in -1f32..1.0, z in -1f32..1.0) {
            let n = Vec3::new(x, y, z);
            prop_assume!(n.length() > 1e-3);
            let n = n.normalize();
            let (t, b) = basis(n);
            prop_assert!((t.length() - 1.0).abs() < 1e-4 && (b.length() - 1.0).abs() < 1e-4);
            prop_assert!(t.dot(n).abs() < 1e-4 && b.dot(n).abs() < 1e-4 && t.dot(b).abs() < 1e-4);
        }

        #[test]
        fn warps_stay_in_domain(u in 0f32..1.0, v in 0f32..1.0, c in -1f32..0.999) {
            let u2 = Vec2::new(u, v);
            prop_assert!(concentric_disk(u2).length() <= 1.0 + 1e-5);
            prop_assert!((uniform_sphere(u2).length() - 1.0).abs() < 1e-4);
            let w = uniform_cone(u2, c);
            prop_assert!(w.z >= c - 1e-5);
            let b = uniform_triangle(u2);
            prop_assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
        }
    }
}
