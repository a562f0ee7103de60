//! Colour vocabulary: linear RGB triples, Ward's RGBE shared-exponent encoding
//! ("Real Pixels", Graphics Gems II, 1991) and the sRGB transfer curve.
//!
//! Every radiometric quantity in this project is a linear RGB triple, one value per
//! channel: power in W, irradiance in W m^-2, radiance in W sr^-1 m^-2, reflectance
//! unitless. This crate knows nothing about which of those a triple holds; the field
//! names and doc comments of the users say so.
//!
//! It also names the component layers every image is split into ([`Layer`]), the
//! one vocabulary of the integrators, the film, the EXR files and the studies.

use glam::Vec3;

/// A linear RGB triple. The unit is the caller's (see the crate doc).
pub type Rgb = Vec3;

/// A component layer of an image: the radiance [W sr^-1 m^-2] a pixel receives,
/// split the way Christensen 1999 (section 1.3) splits the rendering equation. The
/// four layers sum to the image ("total", which is not a layer). The batch
/// renderer, the path tracer (which classifies each path the same way) and both
/// real-time methods fill them; the EXR files name their channels after them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Layer {
    /// Emission seen directly, plus direct light at the first non-specular surface.
    Direct,
    /// Light reaching the first non-specular surface through specular bounces only
    /// (the caustic map's, or the path tracer's L S+ D paths).
    Caustic,
    /// Soft indirect light at the first non-specular surface (final gathering, the
    /// irradiance cache, corner estimates or splatted photons).
    Indirect,
    /// Everything seen through one or more mirror or glass bounces from the eye.
    Specular,
    /// Light scattered toward the eye inside participating media along the eye
    /// ray (single and multiple scattering; the path tracer's paths whose first
    /// non-specular vertex is in a medium). Only renders of scenes with a medium
    /// that scatters have it.
    Volume,
}

impl Layer {
    /// Every layer, in file order.
    pub const ALL: [Layer; 5] = [Layer::Direct, Layer::Caustic, Layer::Indirect, Layer::Specular, Layer::Volume];
    /// The layers every render has (all but [`Layer::Volume`]).
    pub const SURFACE: [Layer; 4] = [Layer::Direct, Layer::Caustic, Layer::Indirect, Layer::Specular];

    /// The name of the layer in files and on the command line (`direct`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Layer::Direct => "direct",
            Layer::Caustic => "caustic",
            Layer::Indirect => "indirect",
            Layer::Specular => "specular",
            Layer::Volume => "volume",
        }
    }

    /// The layer called `name`, if any (the file and command-line boundary).
    pub fn from_name(name: &str) -> Option<Layer> {
        Layer::ALL.into_iter().find(|l| l.name() == name)
    }

    /// Position in [`Layer::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }
}

impl std::fmt::Display for Layer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The name of the image itself (the sum of the layers) in files: its channels
/// are plain R, G, B.
pub const TOTAL: &str = "total";

/// The name in files of `layer`, or of the image itself ([`TOTAL`]) for `None`:
/// what the studies and comparisons that take either call it.
pub fn layer_name(layer: Option<Layer>) -> &'static str {
    layer.map_or(TOTAL, Layer::name)
}

/// Mean of the three channels: the scalar used for power-proportional choices and
/// Russian roulette (Jensen's photon maps use the channel average, not luminance,
/// so that a photon's expected power is preserved per channel).
#[inline]
pub fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) * (1.0 / 3.0)
}

/// Rec. 709 luminance Y of a linear RGB triple (for display-oriented contrast tests).
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// True when every channel is finite and not negative.
#[inline]
pub fn is_valid(c: Rgb) -> bool {
    c.is_finite() && c.min_element() >= 0.0
}

/// Ward's RGBE encoding of a non-negative RGB triple in 4 bytes: an 8-bit mantissa per
/// channel and one shared 8-bit exponent (bias 128).
///
/// Error bound (stated and tested): for the largest channel m the decoded value is
/// within m/256 (relative error <= 0.39%); every other channel is within m/128 in
/// absolute terms (so small channels of a saturated colour may lose all precision).
/// Values below 2^-128 encode as 0; values above 2^127 saturate to the largest
/// representable triple. NaN and negative inputs encode as 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[repr(transparent)]
pub struct Rgbe(pub [u8; 4]);

impl Rgbe {
    /// The encoding of black.
    pub const ZERO: Rgbe = Rgbe([0; 4]);

    /// Encode (truncating mantissas; [`Rgbe::decode`] adds half a step back).
    pub fn encode(c: Rgb) -> Rgbe {
        let clean = |v: f32| {
            if v.is_finite() && v > 0.0 {
                v
            } else if v == f32::INFINITY {
                f32::MAX
            } else {
                0.0
            }
        };
        let (r, g, b) = (clean(c.x), clean(c.y), clean(c.z));
        let m = r.max(g).max(b);
        if m < pow2(-128) {
            return Rgbe::ZERO;
        }
        // m = mant * 2^e with mant in [0.5, 1).
        let (mut e, _) = frexp(m);
        if e > 127 {
            return Rgbe([255, 255, 255, 255]);
        }
        // Scale so the largest channel maps into [128, 256).
        let mut scale = ldexp(256.0, -e);
        if (m * scale) as u32 >= 256 {
            // Rounding of frexp at the top of the range: move up one exponent.
            e += 1;
            scale = ldexp(256.0, -e);
        }
        let q = |v: f32| ((v * scale) as u32).min(255) as u8;
        Rgbe([q(r), q(g), q(b), (e + 128) as u8])
    }

    /// Decode to linear RGB. A zero mantissa decodes to exactly 0 so that black and
    /// pure primaries survive the round trip.
    pub fn decode(self) -> Rgb {
        let [r, g, b, e] = self.0;
        if e == 0 {
            return Rgb::ZERO;
        }
        let f = ldexp(1.0, e as i32 - (128 + 8));
        let d = |c: u8| if c == 0 { 0.0 } else { (c as f32 + 0.5) * f };
        Rgb::new(d(r), d(g), d(b))
    }
}

/// Split a positive finite float into mantissa in [0.5, 1) and exponent.
fn frexp(x: f32) -> (i32, f32) {
    let e = x.log2().floor() as i32 + 1;
    (e, x * pow2(-e))
}

/// x * 2^e without overflow in the intermediate power for |e| up to ~260.
fn ldexp(x: f32, e: i32) -> f32 {
    let half = e / 2;
    x * pow2(half) * pow2(e - half)
}

/// 2^n, exactly, from its bits: subnormal below 2^-126, 0 below 2^-149 and infinite
/// above 2^127 (equal to `2f32.powi(n)` over the normal range, which is all that
/// [`ldexp`] asks for). `powi` is a library call that multiplies in a loop; it was 9%
/// of the irradiance precompute, which decodes a photon's RGBE power for every
/// neighbour it sums.
#[inline]
fn pow2(n: i32) -> f32 {
    if n > 127 {
        f32::INFINITY
    } else if n >= -126 {
        f32::from_bits(((n + 127) as u32) << 23)
    } else if n >= -149 {
        f32::from_bits(1 << (n + 149))
    } else {
        0.0
    }
}

/// sRGB transfer function (IEC 61966-2-1): linear \[0,1\] to encoded \[0,1\].
pub fn srgb_encode(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// The 8-bit sRGB code of a linear value: `srgb_encode(v)` scaled to 0..=255 and
/// rounded to nearest, exactly as `(srgb_encode(v) * 255.0 + 0.5) as u8` gives it
/// (NaN and negatives to 0, at least 1 to 255), but without a `powf` per value.
///
/// The code is the number of thresholds at or below `v`. Threshold k is the least
/// float whose code is at least k, found once by bisection over the floats' bit
/// patterns; the codes are monotonic in `v`, so counting thresholds agrees with the
/// direct formula everywhere (checked at both sides of every threshold in the
/// tests). The count starts from a table indexed by the top 16 bits of `v` (sign,
/// exponent and 7 bits of mantissa: buckets 1/128 of an octave wide, 16 kB), which
/// holds the code of the bucket's least value; at most two further thresholds lie
/// inside a bucket (the test `srgb8_buckets_hold_few_thresholds` counts them). A frame of 1920 x 1080 is six million values: a
/// `powf` each (about 20 ns) took a tenth of a second of a live run's frame, an
/// eight-step binary search over the thresholds still about 25 ns on this project's
/// machines (its steps depend on each other).
#[inline]
pub fn srgb8(v: f32) -> u8 {
    let Srgb8Tables { thresholds: t, buckets } = &*SRGB8_TABLES;
    // NaN and values below the first threshold (negatives, zeros) are 0, values
    // from 1 up 255: neither indexes the buckets.
    if !(v >= t[1]) {
        return 0;
    }
    if v >= 1.0 {
        return 255;
    }
    let mut code = buckets[(v.to_bits() >> 16) as usize] as usize;
    while code < 255 && v >= t[code + 1] {
        code += 1;
    }
    code as u8
}

/// [`srgb8`]'s thresholds and buckets.
struct Srgb8Tables {
    /// `thresholds[k]` for k in 1..=255: the least non-negative float whose
    /// [`srgb8_direct`] code is at least k (`thresholds[0]` is unused).
    thresholds: [f32; 256],
    /// The code of the least float of each bucket of 2^16 bit patterns, for the
    /// positive floats below 1.
    buckets: Vec<u8>,
}

static SRGB8_TABLES: std::sync::LazyLock<Srgb8Tables> = std::sync::LazyLock::new(|| {
    let thresholds = std::array::from_fn(|k| {
        // Non-negative floats order as their bit patterns; 1.0 has code 255.
        let (mut lo, mut hi) = (0u32, 1f32.to_bits());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if (srgb8_direct(f32::from_bits(mid)) as usize) < k { lo = mid + 1 } else { hi = mid }
        }
        f32::from_bits(lo)
    });
    let buckets = (0..=1f32.to_bits() >> 16).map(|b| srgb8_direct(f32::from_bits(b << 16))).collect();
    Srgb8Tables { thresholds, buckets }
});

/// The 8-bit code by the formula [`srgb8`] reproduces.
fn srgb8_direct(v: f32) -> u8 {
    (srgb_encode(v) * 255.0 + 0.5) as u8
}

/// Inverse sRGB transfer: encoded \[0,1\] to linear \[0,1\] (glTF base-colour textures are sRGB).
pub fn srgb_decode(v: f32) -> f32 {
    if v <= 0.040_45 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn rgbe_zero_and_primaries_round_trip_exactly_in_zero_channels() {
        assert_eq!(Rgbe::encode(Rgb::ZERO).decode(), Rgb::ZERO);
        let red = Rgbe::encode(Rgb::new(3.0, 0.0, 0.0)).decode();
        assert_eq!((red.y, red.z), (0.0, 0.0));
        assert!((red.x - 3.0).abs() / 3.0 < 1.0 / 256.0);
    }

    #[test]
    fn pow2_is_powi_of_two() {
        for n in -126..=127 {
            assert_eq!(pow2(n).to_bits(), 2f32.powi(n).to_bits(), "2^{n}");
        }
        assert_eq!(pow2(-127), f32::MIN_POSITIVE / 2.0);
        assert_eq!(pow2(-149), f32::from_bits(1));
        assert_eq!((pow2(-150), pow2(128)), (0.0, f32::INFINITY));
    }

    #[test]
    fn rgbe_extremes() {
        // Tiny: below the representable range goes to zero, just above survives.
        assert_eq!(Rgbe::encode(Rgb::splat(1e-39)).decode(), Rgb::ZERO);
        let tiny = Rgb::splat(1e-30);
        let d = Rgbe::encode(tiny).decode();
        assert!(((d.x - tiny.x) / tiny.x).abs() < 1.0 / 256.0, "{d:?}");
        // Huge: 1e38 is representable, infinity saturates to a finite value.
        let huge = Rgb::new(1e38, 5e37, 0.0);
        let d = Rgbe::encode(huge).decode();
        assert!(((d.x - huge.x) / huge.x).abs() < 1.0 / 256.0, "{d:?}");
        assert!(Rgbe::encode(Rgb::splat(f32::INFINITY)).decode().is_finite());
        assert_eq!(Rgbe::encode(Rgb::new(f32::NAN, -1.0, 0.0)).decode(), Rgb::ZERO);
    }

    #[test]
    fn srgb8_equals_the_formula_on_both_sides_of_every_step() {
        let t = &SRGB8_TABLES.thresholds;
        for (k, &tk) in t.iter().enumerate().skip(1) {
            let below = f32::from_bits(tk.to_bits() - 1);
            assert_eq!((srgb8(tk), srgb8_direct(tk)), (k as u8, k as u8), "threshold {k}");
            assert_eq!((srgb8(below), srgb8_direct(below)), (k as u8 - 1, k as u8 - 1), "below threshold {k}");
        }
        for v in [f32::NAN, f32::NEG_INFINITY, -1.0, -0.0, 0.0, 1.0, 2.0, f32::INFINITY, f32::MAX] {
            assert_eq!(srgb8(v), srgb8_direct(v), "{v}");
        }
    }

    /// The table's buckets: each starts at its least float's code and holds at most
    /// two thresholds (the most steps [`srgb8`] takes), and the first and last float
    /// of every bucket, and a million others spread over the bit patterns of [0, 4),
    /// get the formula's code. A bucket index off by one, or a table of the wrong
    /// codes, fails it.
    #[test]
    fn srgb8_buckets_hold_few_thresholds() {
        let Srgb8Tables { thresholds: t, buckets } = &*SRGB8_TABLES;
        let bits_of_one = 1f32.to_bits();
        for (b, &code) in buckets.iter().enumerate() {
            let (lo, hi) = ((b as u32) << 16, (((b as u32) << 16) | 0xffff).min(bits_of_one - 1));
            let inside = t[1..].iter().filter(|x| (lo + 1..=hi).contains(&x.to_bits())).count();
            assert!(inside <= 2, "bucket {b}: {inside} thresholds");
            assert_eq!(code, srgb8_direct(f32::from_bits(lo)), "bucket {b}");
            for v in [lo, hi].map(f32::from_bits) {
                assert_eq!(srgb8(v), srgb8_direct(v), "{v:e}");
            }
        }
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..1_000_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = f32::from_bits((x >> 34) as u32 % (bits_of_one + (1 << 24)));
            assert_eq!(srgb8(v), srgb8_direct(v), "{v:e}");
        }
    }

    proptest! {
        #[test]
        fn srgb8_equals_the_formula(v in -0.1f32..1.1) {
            prop_assert_eq!(srgb8(v), srgb8_direct(v));
        }

        #[test]
        fn rgbe_error_within_stated_bound(r in 0f32..1e6, g in 0f32..1e6, b in 0f32..1e6, s in -100i32..100) {
            let c = Rgb::new(r, g, b) * 2f32.powi(s);
            prop_assume!(c.max_element() > 1e-37 && c.max_element() < 1e37);
            let d = Rgbe::encode(c).decode();
            let m = c.max_element();
            for i in 0..3 {
                let err = (d[i] - c[i]).abs();
                let bound = if c[i] == m { m / 256.0 } else { m / 128.0 };
                prop_assert!(err <= bound * 1.0001, "channel {i}: {c:?} -> {d:?}");
            }
        }

        #[test]
        fn srgb_round_trip(v in 0f32..1.0) {
            prop_assert!((srgb_decode(srgb_encode(v)) - v).abs() < 1e-5);
        }
    }
}
