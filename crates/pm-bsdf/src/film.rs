//! Thin-film interference (KHR_materials_iridescence): the Fresnel reflectance of a
//! dielectric film over a base, after Belcour and Barla 2017 ("A practical
//! extension to microfacet theory for the modeling of varying iridescence"),
//! in the extension's approximation: Schlick reflectance at both interfaces,
//! polarisation ignored, and the spectral integral done in Fourier space with
//! Gaussian fits of the CIE 1931 sensitivities (their section 4), the first two
//! orders kept.

use glam::Vec3;
use pm_color::Rgb;
use std::f32::consts::{PI, TAU};

/// The extension's defaults: film ior 1.3, thickness 100-400 nm.
pub const FILM_IOR: f32 = 1.3;

/// A thin film over a surface's specular lobe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Film {
    /// iridescenceFactor x texture in [0, 1]: F = mix(F_schlick, F_film, weight).
    /// Zero: no film.
    pub weight: f32,
    /// The film's index of refraction (iridescenceIor).
    pub ior: f32,
    /// The film's thickness [nm].
    pub thickness: f32,
}

impl Film {
    /// No film.
    pub const NONE: Film = Film { weight: 0.0, ior: FILM_IOR, thickness: 0.0 };

    /// Reflectance per channel (linear Rec. 709) of the film over a base whose
    /// reflectance at normal incidence from air is `base_f0`, for light at cosine
    /// `cos` to the (micro)surface normal in air, meeting the film from a medium of
    /// index `outside` (1 in air, the coat's 1.5 under a clear coat, light then
    /// refracted into the coat first).
    ///
    /// The base's index comes from `base_f0` by inverting F0 = ((n-1)/(n+1))^2 per
    /// channel (a metal's extinction taken as zero, as the extension says). The
    /// optical path difference is 2 n_film d cos(theta_2), theta_2 the refracted
    /// angle in the film; each interface adds a phase of pi where light reflects
    /// off a lower index. (The extension's sample code clamps R12 R23 below at
    /// 1e-5; clamped at 0 here, a film of no thickness or of the base's index is
    /// exactly the bare interface.)
    pub fn reflectance(&self, cos: f32, outside: f32, base_f0: Rgb) -> Rgb {
        let sin_sq = 1.0 - cos.clamp(0.0, 1.0).powi(2);
        // A vanishing film fades to the outside medium (the extension's smoothstep
        // over 0-0.03 nm): no film, no interface.
        let t = (self.thickness / 0.03).clamp(0.0, 1.0);
        let n2 = outside + (self.ior - outside) * t * t * (3.0 - 2.0 * t);
        // Snell: n sin(theta) is the same in air, the outside medium and the film.
        let cos1 = (1.0 - sin_sq / (outside * outside)).max(0.0).sqrt();
        let sin2_sq = sin_sq / (n2 * n2);
        if sin2_sq >= 1.0 {
            return Rgb::ONE; // total internal reflection at the film's top
        }
        let cos2 = (1.0 - sin2_sq).sqrt();
        // Outside -> film.
        let r12 = interface(n2, outside, cos1);
        let t121 = 1.0 - r12;
        let phi21 = if n2 < outside { 0.0 } else { PI };
        // Film -> base, per channel.
        let f0 = base_f0.clamp(Vec3::ZERO, Vec3::splat(0.9999));
        let s = f0.map(f32::sqrt);
        let n3 = (Vec3::ONE + s) / (Vec3::ONE - s);
        let r23 = n3.map(|n| interface(n, n2, cos2));
        let phi23 = n3.map(|n| if n < n2 { PI } else { 0.0 });
        let phase = phi23 + Vec3::splat(phi21);
        let opd = 2.0 * n2 * self.thickness * cos2;
        // The Airy sum's Fourier series in wavenumber: a constant term and cosines
        // of the m-th multiple of the path difference, amplitudes falling as r123^m.
        let r123 = (r23 * r12).clamp(Vec3::ZERO, Vec3::splat(0.9999));
        let root = r123.map(f32::sqrt);
        let rs = r23 * (t121 * t121) / (Vec3::ONE - r123);
        let mut total = Vec3::splat(r12) + rs;
        let mut c = rs - Vec3::splat(t121);
        for m in 1..=2 {
            c *= root;
            total += c * 2.0 * sensitivity(m as f32 * opd, phase * m as f32);
        }
        total.max(Vec3::ZERO)
    }
}

/// Schlick's reflectance at cosine `cos` between indices `n_i` and `n`, from
/// ((n - n_i) / (n + n_i))^2 at normal incidence; zero between equal indices
/// (where Schlick's grazing term would reflect without an interface).
fn interface(n: f32, n_i: f32, cos: f32) -> f32 {
    if n == n_i { 0.0 } else { schlick1(((n - n_i) / (n + n_i)).powi(2), cos) }
}

/// Schlick's Fresnel of one channel.
fn schlick1(f0: f32, cos: f32) -> f32 {
    f0 + (1.0 - f0) * (1.0 - cos).powi(5)
}

/// The colour-matching functions' response to a spectrum cos(2 pi opd / lambda +
/// shift) in linear Rec. 709: the Fourier transform, at path difference `opd`
/// [nm], of Gaussian fits to x, y and z over wavenumber (each a Gaussian of
/// height a, centre k0 [m^-1] and variance v [m^-2], x with a second lobe),
/// normalised so that opd 0 gives XYZ (1, 1, 1) (Belcour and Barla 2017,
/// section 4; the fits are the extension's).
fn sensitivity(opd: f32, shift: Vec3) -> Vec3 {
    const A: [f32; 3] = [5.4856e-13, 4.4201e-13, 5.2481e-13];
    const K0: [f32; 3] = [1.6810e6, 1.7953e6, 2.2084e6];
    const V: [f32; 3] = [4.3278e9, 9.3046e9, 6.6121e9];
    const X2: (f32, f32, f32) = (9.7470e-14, 2.2399e6, 4.5282e9);
    const NORM: f32 = 1.0685e-7;
    let x = TAU * opd * 1e-9; // [m]
    let lobe = |a: f32, k0: f32, v: f32, shift: f32| a * (TAU * v).sqrt() * (k0 * x + shift).cos() * (-x * x * v).exp();
    let mut xyz = Vec3::from_array(std::array::from_fn(|i| lobe(A[i], K0[i], V[i], shift[i])));
    xyz.x += lobe(X2.0, X2.1, X2.2, shift.x);
    xyz /= NORM;
    // CIE XYZ -> linear Rec. 709 (D65).
    Vec3::new(
        3.240_454_2 * xyz.x - 1.537_138_5 * xyz.y - 0.498_531_4 * xyz.z,
        -0.969_266 * xyz.x + 1.876_010_8 * xyz.y + 0.041_556 * xyz.z,
        0.055_643_4 * xyz.x - 0.204_025_9 * xyz.y + 1.057_225_2 * xyz.z,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn film(ior: f32, thickness: f32) -> Film {
        Film { weight: 1.0, ior, thickness }
    }

    const GLASS: f32 = 0.04; // F0 of ior 1.5

    #[test]
    fn a_film_of_no_thickness_is_the_bare_surface() {
        for cos in [1.0, 0.7, 0.3, 0.05] {
            let f = film(1.8, 0.0).reflectance(cos, 1.0, Rgb::splat(GLASS));
            let bare = schlick1(GLASS, cos);
            for c in [f.x, f.y, f.z] {
                assert!((c - bare).abs() < 0.005, "cos {cos}: {f:?} against {bare}");
            }
        }
    }

    #[test]
    fn an_index_matched_film_only_adds_its_top_interface() {
        // A film of the base's own index: no second interface, no interference.
        let f = film(1.5, 300.0).reflectance(1.0, 1.0, Rgb::splat(GLASS));
        for c in [f.x, f.y, f.z] {
            assert!((c - GLASS).abs() < 0.003, "{f:?}");
        }
    }

    #[test]
    fn a_quarter_wave_film_reflects_most_at_its_wavelength() {
        // A film of index 1.8 over glass: the top reflects off a higher index, the
        // bottom off a lower one, so a film of optical thickness 3 lambda / 4 (a
        // path difference of 3 lambda / 2) reflects in phase at lambda and out of
        // phase at 3/2 and 3/4 of it: the strongest there. Blue, green and red in
        // turn.
        for (lambda, strongest) in [(450.0, 2), (540.0, 1), (640.0, 0)] {
            let d = 3.0 * lambda / (4.0 * 1.8);
            let f = film(1.8, d).reflectance(1.0, 1.0, Rgb::splat(GLASS));
            let c = [f.x, f.y, f.z];
            let max = (0..3).max_by(|&a, &b| c[a].total_cmp(&c[b])).unwrap();
            assert_eq!(max, strongest, "{lambda} nm film ({d} nm): {f:?}");
            // In phase, the two reflections add to more than either alone (0.08 and
            // 0.0087 at normal incidence, 0.14 in phase).
            assert!(c[strongest] > 0.1, "{lambda} nm: {f:?}");
        }
        // A path difference of 2 lambda: out of phase at lambda, least there.
        let f = film(1.8, 540.0 / 1.8).reflectance(1.0, 1.0, Rgb::splat(GLASS));
        assert!(f.y < f.x && f.y < f.z, "{f:?}");
    }

    #[test]
    fn film_reflectance_stays_in_range() {
        for ior in [1.0, 1.3, 1.8, 2.5] {
            for d in [0.0, 50.0, 150.0, 400.0, 1200.0] {
                for f0 in [0.0, 0.04, 0.5, 0.95, 1.0] {
                    for cos in [0.0, 0.01, 0.3, 0.7, 1.0] {
                        for outside in [1.0, 1.5] {
                            let f = film(ior, d).reflectance(cos, outside, Rgb::splat(f0));
                            assert!(f.is_finite() && f.min_element() >= 0.0 && f.max_element() <= 1.05, "{f:?}");
                        }
                    }
                }
            }
        }
    }
}
