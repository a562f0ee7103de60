//! Irradiance caching (Ward, Rubinstein and Clear 1988; Ward and Heckbert 1992):
//! final gathers are done at a sparse set of records and interpolated between
//! them with translational and rotational gradients. Record weight
//! w_i = 1 / (|p - p_i| / R_i + sqrt(1 - n . n_i)); a record is used where
//! w_i > 1 / a, a being the user's accuracy.

use glam::{IVec3, Vec3};
use pm_color::Rgb;
use pm_format::CacheRecord;
use pm_sampling::mix64;
use std::collections::HashMap;

/// The result of a final gather at a point.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Gather {
    /// Indirect irradiance E [W m^-2 per channel] from the gathered radiance.
    pub e: Rgb,
    /// Harmonic mean distance to the surfaces the rays hit [m] (infinite if none).
    pub r_harmonic: f32,
    /// Translational gradient dE/dx [W m^-3], one vector per channel.
    pub grad_t: [Vec3; 3],
    /// Rotational gradient [W m^-2 rad^-1], one vector per channel.
    pub grad_r: [Vec3; 3],
}

/// One cached final gather: position [m], normal, irradiance E [W m^-2], radius of
/// validity R [m], translational [W m^-3] and rotational [W m^-2 rad^-1] gradients.
#[derive(Clone, Copy, Debug)]
struct Record {
    p: Vec3,
    n: Vec3,
    e: Rgb,
    r: f32,
    grad_t: [Vec3; 3],
    grad_r: [Vec3; 3],
}

impl Record {
    /// The record's irradiance carried to point `p` with normal `n` by its
    /// gradients (Ward and Heckbert 1992), at least 0.
    fn extrapolated(&self, p: Vec3, n: Vec3) -> Rgb {
        let (d, rot) = (p - self.p, self.n.cross(n));
        Rgb::new(
            self.e.x + rot.dot(self.grad_r[0]) + d.dot(self.grad_t[0]),
            self.e.y + rot.dot(self.grad_r[1]) + d.dot(self.grad_t[1]),
            self.e.z + rot.dot(self.grad_r[2]) + d.dot(self.grad_t[2]),
        )
        .max(Rgb::ZERO)
    }
}

/// A record as a grid cell lists it: what a lookup's first test reads, stored in the
/// cell so that records out of reach are skipped without touching the record array.
#[derive(Clone, Copy, Debug)]
struct Entry {
    p: Vec3,
    r: f32,
    id: u32,
}

/// How far a neighbour's irradiance may be from a record's extrapolation to it
/// (a factor, either way) before it clamps the record's radius
/// ([`IrradianceCache::clamp_to_neighbours`]): 1.5 took 1.56 times the records on
/// cornell_spheres, 2 took 1.22 times, for the same result on the scene that
/// asked for it.
const DISAGREE: f32 = 2.0;

/// The most a lookup may extrapolate: rendering's slack (see [`IrradianceCache::lookup`]).
const MAX_SLACK: f32 = 2.0;

/// The cache: records in insertion order, indexed by a hash grid in which every
/// record is listed in each cell its reach (a x `MAX_SLACK` x R_i) overlaps, so a
/// lookup reads the one cell it falls in (it read 27 cells, each record listed once,
/// and lookups were 31% of rendering: BENCHMARKS.md). Made once per image by
/// [`IrradianceCache::prepass`] (its own pipeline step, so that tiles rendered apart
/// share one cache), read-only while rendering.
#[derive(Clone, Debug)]
pub struct IrradianceCache {
    records: Vec<Record>,
    grid: HashMap<IVec3, Vec<Entry>, CellHash>,
    cell: f32,
    a: f32,
    spacing: (f32, f32),
}

/// A fast hash for grid cells (the standard SipHash was a visible part of lookups).
#[derive(Clone, Copy, Debug, Default)]
struct CellHash;

impl std::hash::BuildHasher for CellHash {
    type Hasher = CellHasher;
    fn build_hasher(&self) -> CellHasher {
        CellHasher(0)
    }
}

/// [`CellHash`]'s hasher: a multiply-xorshift mix of the words written.
#[derive(Clone, Copy, Debug)]
struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        mix64(self.0)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    }
    fn write_i32(&mut self, v: i32) {
        self.0 = (self.0 ^ v as u32 as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(23);
    }
}

impl IrradianceCache {
    /// An empty cache for accuracy `a` and record spacing (min, max) [m].
    pub(crate) fn new(a: f32, spacing: (f32, f32)) -> Self {
        // Cells half as large as the farthest a record can serve: the largest
        // records are listed in at most 5^3 cells, most in a few.
        IrradianceCache {
            records: Vec::new(),
            grid: HashMap::default(),
            cell: (0.5 * MAX_SLACK * a * spacing.1).max(1e-12),
            a,
            spacing,
        }
    }

    fn key(&self, p: Vec3) -> IVec3 {
        (p / self.cell).floor().as_ivec3()
    }

    /// Number of records.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// True when the cache holds no record.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Add a final gather at `p` (normal `n`) as a record. The record's radius is the
    /// gather's harmonic mean distance, limited by its gradient and clamped to the
    /// spacing limits.
    pub(crate) fn insert(&mut self, p: Vec3, n: Vec3, g: &Gather) {
        // Gradient-based radius limit (Tabellion and Lamorlette 2004): a record does not
        // reach farther than the distance over which its translational gradient
        // would change its irradiance by its own value, R_i <= E_i / |grad_t E_i|.
        let mut r = g.r_harmonic;
        for c in 0..3 {
            let gl = g.grad_t[c].length();
            if gl > 0.0 && g.e[c] > 0.0 {
                r = r.min(g.e[c] / gl);
            }
        }
        let r = r.clamp(self.spacing.0, self.spacing.1);
        // The spacing floor can leave R_i above E_i / |grad|; then scale the gradient
        // down so that extrapolating across the record's reach changes E by at most
        // E itself (near corners, gather rays of length ~0 make 1/r gradients huge).
        let mut grad_t = g.grad_t;
        for (gc, e) in grad_t.iter_mut().zip(g.e.to_array()) {
            let gl = gc.length();
            if gl * r > e {
                *gc *= if gl > 0.0 { e / (gl * r) } else { 0.0 };
            }
        }
        self.push(Record { p, n, e: g.e, r, grad_t, grad_r: g.grad_r });
    }

    /// Neighbour clamping (Křivánek, Bouatouch, Pattanaik and Žára 2006) where
    /// the neighbour disagrees: no record reaches past a neighbour by more than
    /// that neighbour's own radius, R_j <= R_i + |p_i - p_j|, for every record i
    /// that j's reach covers and whose irradiance j's extrapolation misses by more
    /// than a factor [`DISAGREE`]. A gather's radius comes from distances and its
    /// gradient, which both miss light that arrives near the horizon from a small
    /// bright source: records on a ceiling 10 cm from a lamp hung 6 cm under it (a
    /// second lamp above lighting the gap) had radii of 12 cm, irradiance 0.3 W
    /// m^-2, and reached the lamp's edge, where the records beside it held 7 to 23
    /// W m^-2 in radii of 1 cm: lookups there read 0.3 where fresh gathers found 2
    /// to 10, the ceiling 43% dark in 8 x 8 blocks, the indirect layer -2.9%
    /// (issue 53's checker, scene 9 of seed 23897); -0.9% now, -0.5% with a
    /// fresh gather at every point. Clamping by every neighbour, as Křivánek et
    /// al. do, took 2.3 times the records on cornell_spheres at 384 x 384 (near
    /// every corner) and twice the cache's time; by those that disagree, 1.22
    /// times the records (5890) and 1.19 times the time. Done after each of the
    /// prepass's levels; new radii from the old ones, in record order
    /// (deterministic).
    pub(crate) fn clamp_to_neighbours(&mut self) {
        let a = self.a * MAX_SLACK;
        let mut r: Vec<f32> = self.records.iter().map(|x| x.r).collect();
        for (i, ri) in self.records.iter().enumerate() {
            let Some(entries) = self.grid.get(&self.key(ri.p)) else { continue };
            let own = ri.e.element_sum();
            for e in entries {
                let (j, d) = (e.id as usize, (ri.p - e.p).length());
                if j == i || d >= a * e.r || r[j] <= ri.r + d {
                    continue;
                }
                let predicted = self.records[j].extrapolated(ri.p, ri.n).element_sum();
                if predicted * DISAGREE < own || predicted > DISAGREE * own {
                    r[j] = ri.r + d;
                }
            }
        }
        if r.iter().zip(&self.records).all(|(x, rec)| *x == rec.r) {
            return;
        }
        let records = std::mem::take(&mut self.records);
        self.grid.clear();
        for (mut rec, rj) in records.into_iter().zip(r) {
            // A gradient scaled for the old reach may be kept: the new is smaller.
            rec.r = rj.max(self.spacing.0.min(rec.r));
            self.push(rec);
        }
    }

    fn push(&mut self, rec: Record) {
        let reach = Vec3::splat(MAX_SLACK * self.a * rec.r);
        let (lo, hi) = (self.key(rec.p - reach), self.key(rec.p + reach));
        let entry = Entry { p: rec.p, r: rec.r, id: self.records.len() as u32 };
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                for z in lo.z..=hi.z {
                    self.grid.entry(IVec3::new(x, y, z)).or_default().push(entry);
                }
            }
        }
        self.records.push(rec);
    }

    /// The records as the file format stores them, in insertion order.
    pub fn to_records(&self) -> Vec<CacheRecord> {
        let v = |v: Vec3| v.to_array();
        let g = |g: &[Vec3; 3]| {
            let mut out = [0.0; 9];
            for (c, gc) in g.iter().enumerate() {
                out[3 * c..3 * c + 3].copy_from_slice(&gc.to_array());
            }
            out
        };
        self.records
            .iter()
            .map(|r| CacheRecord {
                p: v(r.p),
                n: v(r.n),
                e: v(r.e),
                r: r.r,
                grad_t: g(&r.grad_t),
                grad_r: g(&r.grad_r),
            })
            .collect()
    }

    /// A cache of accuracy `a` and spacing (min, max) \[m\] holding `records` (from
    /// [`Self::to_records`]), in the same order: lookups give the same results.
    pub fn from_records(a: f32, spacing: (f32, f32), records: &[CacheRecord]) -> Self {
        let mut c = IrradianceCache::new(a, spacing);
        let g = |g: &[f32; 9]| [0, 1, 2].map(|c| Vec3::from_slice(&g[3 * c..3 * c + 3]));
        for r in records {
            c.push(Record {
                p: r.p.into(),
                n: r.n.into(),
                e: r.e.into(),
                r: r.r,
                grad_t: g(&r.grad_t),
                grad_r: g(&r.grad_r),
            });
        }
        c
    }

    /// Interpolated indirect irradiance at `p` with normal `n`, or `None` when no
    /// record is close enough: within accuracy `a x slack` (the prepass decides where
    /// records go with slack 1; rendering accepts a little extrapolation, slack 2, as
    /// Ward's RADIANCE does for secondary samples, so jittered supersamples near a
    /// record's edge do not each trigger a fresh final gather).
    ///
    /// Only records for which `seen(record's position)` holds are read: the caller
    /// says whether the record's point and `p` see each other (nothing between
    /// them). Ward's tests alone read records across a surface that divides two
    /// regions of one plane: a wall's indirect irradiance outside a glass box that
    /// crosses it leaked into the wall's part inside the glass, the specular layer
    /// (what is seen through the glass) 10% bright, in stripes up to 20%, where a
    /// fresh gather at every point agreed within 2.4% (differential checker seed
    /// 90210, scene 2).
    pub(crate) fn lookup(&self, p: Vec3, n: Vec3, slack: f32, seen: impl Fn(Vec3) -> bool) -> Option<Rgb> {
        debug_assert!(slack <= MAX_SLACK);
        let a = self.a * slack.min(MAX_SLACK);
        let entries = self.grid.get(&self.key(p))?;
        let mut sum = Rgb::ZERO;
        let mut wsum = 0.0f32;
        // Most listed records are out of reach: |d| / R_i >= a alone fails Ward's
        // test. Checked squared, with a margin far above rounding, before the exact
        // test below (which the results depend on, bit for bit).
        let reach2 = a * a * (1.0 + 1e-4);
        for e in entries {
            let d = p - e.p;
            if d.length_squared() >= reach2 * e.r * e.r {
                continue;
            }
            let r = &self.records[e.id as usize];
            let eps = d.length() / r.r + (1.0 - n.dot(r.n)).max(0.0).sqrt();
            if eps >= a {
                continue;
            }
            // Ward's test: skip records in front of the point (they see
            // surfaces the point may not).
            if d.dot(n + r.n) * 0.5 < -0.05 * r.r {
                continue;
            }
            if !seen(r.p) {
                continue;
            }
            let w = 1.0 / eps.max(1e-4);
            sum += r.extrapolated(p, n) * w;
            wsum += w;
        }
        (wsum > 0.0).then(|| sum / wsum)
    }
}
