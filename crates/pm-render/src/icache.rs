//! Irradiance caching (Ward, Rubinstein and Clear 1988; Ward and Heckbert 1992):
//! final gathers are done at a sparse set of records and interpolated between
//! them with translational and rotational gradients. Record weight
//! w_i = 1 / (|p - p_i| / R_i + sqrt(1 - n . n_i)); a record is used where
//! w_i > 1 / a, a being the user's accuracy.

use crate::gather::Gather;
use glam::{IVec3, Vec3};
use pm_color::Rgb;
use std::collections::HashMap;

/// One cached final gather.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Record {
    p: Vec3,
    n: Vec3,
    e: Rgb,
    r: f32,
    grad_t: [Vec3; 3],
    grad_r: [Vec3; 3],
}

/// The cache: records in insertion order, indexed by a hash grid whose cells are as
/// large as the largest region a record can serve, so a lookup reads 27 cells.
pub(crate) struct IrradianceCache {
    records: Vec<Record>,
    grid: HashMap<IVec3, Vec<u32>>,
    cell: f32,
    a: f32,
    spacing: (f32, f32),
}

impl IrradianceCache {
    /// An empty cache for accuracy `a` and record spacing (min, max) [m].
    pub fn new(a: f32, spacing: (f32, f32)) -> Self {
        // Cells as large as the farthest a record can serve at slack 2.
        IrradianceCache {
            records: Vec::new(),
            grid: HashMap::new(),
            cell: (2.0 * a * spacing.1).max(1e-12),
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

    /// Add a final gather at `p` (normal `n`) as a record. The record's radius is the
    /// gather's harmonic mean distance, limited by its gradient and clamped to the
    /// spacing limits.
    pub fn insert(&mut self, p: Vec3, n: Vec3, g: &Gather) {
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
        for c in 0..3 {
            let gl = grad_t[c].length();
            if gl * r > g.e[c] {
                grad_t[c] *= if gl > 0.0 { g.e[c] / (gl * r) } else { 0.0 };
            }
        }
        let rec = Record { p, n, e: g.e, r, grad_t, grad_r: g.grad_r };
        let k = self.key(p);
        self.grid.entry(k).or_default().push(self.records.len() as u32);
        self.records.push(rec);
    }

    /// Interpolated indirect irradiance at `p` with normal `n`, or `None` when no
    /// record is close enough: within accuracy `a x slack` (the prepass decides where
    /// records go with slack 1; rendering accepts a little extrapolation, slack 2, as
    /// Ward's RADIANCE does for secondary samples, so jittered supersamples near a
    /// record's edge do not each trigger a fresh final gather).
    pub fn lookup(&self, p: Vec3, n: Vec3, slack: f32) -> Option<Rgb> {
        let a = self.a * slack;
        let k = self.key(p);
        let mut sum = Rgb::ZERO;
        let mut wsum = 0.0f32;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(ids) = self.grid.get(&(k + IVec3::new(dx, dy, dz))) else { continue };
                    for &i in ids {
                        let r = &self.records[i as usize];
                        let d = p - r.p;
                        let eps = d.length() / r.r + (1.0 - n.dot(r.n)).max(0.0).sqrt();
                        if eps >= a {
                            continue;
                        }
                        // Ward's test: skip records in front of the point (they see
                        // surfaces the point may not).
                        if d.dot(n + r.n) * 0.5 < -0.05 * r.r {
                            continue;
                        }
                        let w = 1.0 / eps.max(1e-4);
                        let rot = r.n.cross(n);
                        let e = Rgb::new(
                            r.e.x + rot.dot(r.grad_r[0]) + d.dot(r.grad_t[0]),
                            r.e.y + rot.dot(r.grad_r[1]) + d.dot(r.grad_t[1]),
                            r.e.z + rot.dot(r.grad_r[2]) + d.dot(r.grad_t[2]),
                        )
                        .max(Rgb::ZERO);
                        sum += e * w;
                        wsum += w;
                    }
                }
            }
        }
        (wsum > 0.0).then(|| sum / wsum)
    }
}
