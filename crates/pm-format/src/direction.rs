//! One-byte unit directions (Christensen 1999 section 1.1: "1 byte to encode
//! incident direction"; section 2.1: 1 byte for the surface normal).
//!
//! The byte is a 15 x 15 grid over the octahedral map of the sphere (Meyer et al.
//! 2010, "On Floating-Point Normal Vectors"): one nibble per octahedral coordinate. It
//! is coarse by design; photon directions are used for front/back tests and normals
//! for the "dot > 0.9" similarity test, both of which tolerate it.

use glam::{Vec2, Vec3};

/// Largest angle between a unit vector and its decoded byte \[rad\], measured over a
/// dense sweep of the sphere in this crate's tests (measured worst case 0.289 rad, 16.5
/// degrees, near the octahedron's folded edges; typical error is a third of that).
pub const DIRECTION_MAX_ERROR_RAD: f32 = 0.30;

/// 15 values per coordinate (0..=14), so that 0 and +-1 are exact and axis-aligned
/// directions (walls, floors) survive unchanged; codes with a 15 in a nibble are unused.
const LEVELS: f32 = 14.0;

/// Encode a direction (need not be unit; zero or non-finite gives +z's code).
pub fn encode_direction(v: Vec3) -> u8 {
    let l1 = v.x.abs() + v.y.abs() + v.z.abs();
    if !(l1 > 0.0) || !l1.is_finite() {
        return encode_direction(Vec3::Z);
    }
    let p = Vec2::new(v.x, v.y) / l1;
    let p = if v.z < 0.0 { Vec2::new((1.0 - p.y.abs()) * sign(p.x), (1.0 - p.x.abs()) * sign(p.y)) } else { p };
    let q = |c: f32| ((c * 0.5 + 0.5) * LEVELS).round().clamp(0.0, LEVELS) as u8;
    q(p.x) | (q(p.y) << 4)
}

/// Decode a byte to a unit direction: a lookup in the table of all 256 (the
/// precomputed-irradiance search decodes a candidate's normal at every photon it
/// considers; computed each time, with its normalisation, that was a tenth of the
/// irradiance-cache prepass).
#[inline]
pub fn decode_direction(b: u8) -> Vec3 {
    static TABLE: std::sync::LazyLock<[Vec3; 256]> =
        std::sync::LazyLock::new(|| std::array::from_fn(|b| decode_computed(b as u8)));
    TABLE[b as usize]
}

/// [`decode_direction`] computed.
fn decode_computed(b: u8) -> Vec3 {
    let c = |q: u8| q as f32 / LEVELS * 2.0 - 1.0;
    let (x, y) = (c(b & 15), c(b >> 4));
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    let v = Vec3::new(x - t * sign(x), y - t * sign(y), z);
    v.normalize()
}

fn sign(x: f32) -> f32 {
    if x >= 0.0 { 1.0 } else { -1.0 }
}
