//! Tests of the layered model (clear coat, sheen, anisotropy), lobe by lobe and
//! mixed, as Mitsuba 3 and pbrt-v4 test their BSDFs: a chi-square test that
//! `sample` draws directions by `pdf`, `eval / pdf` against `sample`'s weight,
//! reciprocity, and white-furnace albedos.

use super::*;
use pm_sampling::Sampler;

const N_UP: Vec3 = Vec3::Z;

/// Directions (cos theta, phi) binned over wo's hemisphere.
const BINS_Z: usize = 16;
const BINS_PHI: usize = 32;
/// Midpoints a bin's pdf is integrated at, per axis.
const SUB: usize = 16;

fn dir(z: f32, phi: f32) -> Vec3 {
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(s * phi.cos(), s * phi.sin(), z)
}

fn bin_of(w: Vec3) -> Option<usize> {
    if w.z <= 0.0 {
        return None;
    }
    let iz = ((w.z * BINS_Z as f32) as usize).min(BINS_Z - 1);
    let phi = w.y.atan2(w.x).rem_euclid(TAU);
    let ip = ((phi / TAU * BINS_PHI as f32) as usize).min(BINS_PHI - 1);
    Some(iz * BINS_PHI + ip)
}

/// Upper tail of the standard normal, 1 - Phi(x) (Abramowitz and Stegun 26.2.17,
/// error below 7.5e-8).
fn normal_tail(x: f64) -> f64 {
    if x < 0.0 {
        return 1.0 - normal_tail(-x);
    }
    let t = 1.0 / (1.0 + 0.2316419 * x);
    let poly = t * (0.319381530 + t * (-0.356563782 + t * (1.781477937 + t * (-1.821255978 + t * 1.330274429))));
    (-0.5 * x * x).exp() / (TAU as f64).sqrt() * poly
}

/// P(chi^2_k > x), by Wilson and Hilferty's cube-root normal approximation.
fn chi2_tail(x: f64, k: usize) -> f64 {
    let k = k as f64;
    let v = 2.0 / (9.0 * k);
    normal_tail(((x / k).powf(1.0 / 3.0) - (1.0 - v)) / v.sqrt())
}

/// Pearson's chi-square test that `sample` draws by `pdf` at `wo`, with the
/// samples below the surface (None) as one more cell; cells expecting fewer
/// than 5 are pooled. Returns the p-value. Also checks each sample's pdf and
/// weight against `pdf` and `f`.
fn chi2_p(bsdf: &Bsdf, wo: Vec3, n_samples: usize) -> f64 {
    let mut observed = vec![0.0f64; BINS_Z * BINS_PHI + 1];
    for i in 0..n_samples {
        let mut s = Sampler::new(0x5eed, i as u64);
        let (u, uc) = (s.next_2d(), s.next_1d());
        let Some(bs) = bsdf.sample(wo, N_UP, u, uc) else {
            observed[BINS_Z * BINS_PHI] += 1.0;
            continue;
        };
        let pdf = bsdf.pdf(wo, bs.wi, N_UP);
        assert!((pdf - bs.pdf).abs() <= 1e-3 * pdf.max(1.0), "{bsdf:?} wo={wo}: pdf {pdf} sampled {}", bs.pdf);
        let w = bsdf.f(wo, bs.wi, N_UP) * bs.wi.z / pdf;
        assert!(
            (w - bs.weight).abs().max_element() <= 1e-3 * w.max_element().max(1.0),
            "{bsdf:?} wo={wo}: f cos / pdf {w} weight {}",
            bs.weight
        );
        observed[bin_of(bs.wi).unwrap_or(BINS_Z * BINS_PHI)] += 1.0;
    }
    // Expected counts: the pdf integrated over each cell (dw = dz dphi).
    let mut expected = vec![0.0f64; BINS_Z * BINS_PHI + 1];
    let (dz, dphi) = (1.0 / (BINS_Z * SUB) as f32, TAU / (BINS_PHI * SUB) as f32);
    for iz in 0..BINS_Z * SUB {
        for ip in 0..BINS_PHI * SUB {
            let wi = dir((iz as f32 + 0.5) * dz, (ip as f32 + 0.5) * dphi);
            let cell = (iz / SUB) * BINS_PHI + ip / SUB;
            expected[cell] += (bsdf.pdf(wo, wi, N_UP) * dz * dphi) as f64 * n_samples as f64;
        }
    }
    let inside: f64 = expected.iter().sum();
    expected[BINS_Z * BINS_PHI] = (n_samples as f64 - inside).max(0.0);
    let (mut chi2, mut cells, mut pool_o, mut pool_e) = (0.0, 0usize, 0.0, 0.0);
    for (o, e) in observed.iter().zip(&expected) {
        if *e < 5.0 {
            pool_o += o;
            pool_e += e;
        } else {
            chi2 += (o - e) * (o - e) / e;
            cells += 1;
        }
    }
    if pool_e >= 5.0 {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        cells += 1;
    } else {
        assert!(pool_o <= 10.0 + 2.0 * pool_e, "{bsdf:?} wo={wo}: {pool_o} samples where {pool_e} were expected");
    }
    chi2_tail(chi2, cells.max(2) - 1)
}

fn layered(f: impl FnOnce(&mut Layered)) -> Bsdf {
    let mut l = Layered::from_pbr(&Pbr::dielectric(Rgb::new(0.6, 0.4, 0.2)));
    f(&mut l);
    Bsdf::Layered(l.normalised())
}

/// The models the tests run on: each lobe alone, then mixtures.
fn cases() -> Vec<(&'static str, Bsdf)> {
    let tangent = Vec3::new(1.0, 1.0, 0.0).normalize();
    let metal = |ax: f32, ay: f32| {
        layered(|l| {
            l.metal = true;
            l.rho = Rgb::ZERO;
            l.f0 = Rgb::new(0.9, 0.7, 0.5);
            l.spec_weight = 1.0;
            l.alpha = Vec2::new(ax, ay);
            l.tangent = tangent;
        })
    };
    vec![
        ("anisotropic metal 0.5 x 0.1", metal(0.5, 0.1)),
        ("anisotropic metal 0.2 x 0.8", metal(0.2, 0.8)),
        ("isotropic metal 0.3", metal(0.3, 0.3)),
        (
            "coat alone",
            layered(|l| {
                l.rho = Rgb::ZERO;
                l.spec_weight = 0.0;
                l.coat = 1.0;
                l.coat_alpha = 0.1;
            }),
        ),
        (
            "sheen alone",
            layered(|l| {
                l.rho = Rgb::ZERO;
                l.spec_weight = 0.0;
                l.sheen = Rgb::new(1.0, 0.8, 0.6);
                l.sheen_alpha = 0.25;
            }),
        ),
        (
            "coated dielectric",
            layered(|l| {
                l.coat = 1.0;
                l.coat_alpha = 0.05;
                l.alpha = Vec2::splat(0.25);
            }),
        ),
        (
            "coat with its own normal over anisotropic metal",
            layered(|l| {
                l.metal = true;
                l.rho = Rgb::ZERO;
                l.f0 = Rgb::splat(0.9);
                l.alpha = Vec2::new(0.6, 0.15);
                l.tangent = tangent;
                l.coat = 0.7;
                l.coat_alpha = 0.08;
                l.coat_normal = Vec3::new(0.2, -0.1, 1.0).normalize();
            }),
        ),
        (
            "thin film over a coated dielectric",
            layered(|l| {
                l.coat = 1.0;
                l.coat_alpha = 0.05;
                l.alpha = Vec2::splat(0.2);
                l.film = Film { weight: 1.0, ior: 1.8, thickness: 250.0 };
            }),
        ),
        (
            "everything over a dielectric",
            layered(|l| {
                l.coat = 0.5;
                l.coat_alpha = 0.15;
                l.sheen = Rgb::splat(0.7);
                l.sheen_alpha = 0.5;
                l.alpha = Vec2::new(0.7, 0.2);
                l.tangent = tangent;
            }),
        ),
    ]
}

const COSINES: [f32; 3] = [0.9, 0.5, 0.15];

#[test]
fn every_lobe_and_mixture_samples_directions_by_its_pdf() {
    let cases = cases();
    let tests = cases.len() * COSINES.len();
    for (name, bsdf) in &cases {
        for (k, cos) in COSINES.into_iter().enumerate() {
            let wo = dir(cos, 0.7 + k as f32);
            let p = chi2_p(bsdf, wo, 200_000);
            // 1% significance over all the tests together (Bonferroni).
            assert!(p > 0.01 / tests as f64, "{name}, cos {cos}: chi-square p = {p:.2e}");
        }
    }
}

#[test]
fn a_wrong_pdf_fails_the_chi_square_test() {
    // The test can fail: an anisotropic lobe whose pdf is that of its tangent
    // turned a quarter turn is refused.
    let Bsdf::Layered(l) = cases()[0].1 else { unreachable!() };
    let drawn = Bsdf::Layered(l);
    let turned = Bsdf::Layered(Layered { tangent: Vec3::new(-1.0, 1.0, 0.0).normalize(), ..l });
    let wo = dir(0.5, 0.3);
    let mut observed = vec![0usize; BINS_Z * BINS_PHI];
    let n = 50_000;
    for i in 0..n {
        let mut s = Sampler::new(0x5eed, i as u64);
        if let Some(bs) = drawn.sample(wo, N_UP, s.next_2d(), s.next_1d()) {
            observed[bin_of(bs.wi).unwrap()] += 1;
        }
    }
    // The drawn directions are far from what the turned pdf expects.
    let (dz, dphi) = (1.0 / (BINS_Z * SUB) as f32, TAU / (BINS_PHI * SUB) as f32);
    let mut expected = vec![0.0f64; BINS_Z * BINS_PHI];
    for iz in 0..BINS_Z * SUB {
        for ip in 0..BINS_PHI * SUB {
            let wi = dir((iz as f32 + 0.5) * dz, (ip as f32 + 0.5) * dphi);
            expected[(iz / SUB) * BINS_PHI + ip / SUB] += (turned.pdf(wo, wi, N_UP) * dz * dphi) as f64 * n as f64;
        }
    }
    let chi2: f64 =
        observed.iter().zip(&expected).filter(|(_, e)| **e >= 5.0).map(|(o, e)| (*o as f64 - e).powi(2) / e).sum();
    assert!(chi2_tail(chi2, BINS_Z * BINS_PHI - 1) < 1e-6, "chi2 {chi2}");
}

#[test]
fn every_layered_model_is_reciprocal() {
    for (name, bsdf) in cases() {
        for i in 0..2000u64 {
            let mut s = Sampler::new(9, i);
            let (a, b) = (s.next_2d(), s.next_2d());
            let wo = dir(a.x.max(0.02), TAU * a.y);
            let wi = dir(b.x.max(0.02), TAU * b.y);
            let (f1, f2) = (bsdf.f(wo, wi, N_UP), bsdf.f(wi, wo, N_UP));
            assert!(
                (f1 - f2).abs().max_element() <= 1e-4 * f1.max_element().max(1.0),
                "{name}: f(wo, wi) = {f1}, f(wi, wo) = {f2} at wo {wo} wi {wi}"
            );
        }
    }
}

/// Directional albedo by importance sampling, and the most that any channel
/// reaches.
fn albedo(bsdf: &Bsdf, wo: Vec3) -> Rgb {
    let n = 1 << 17;
    let mut sum = Rgb::ZERO;
    for i in 0..n {
        let mut s = Sampler::new(21, i);
        if let Some(bs) = bsdf.sample(wo, N_UP, s.next_2d(), s.next_1d()) {
            sum += bs.weight;
        }
    }
    sum / n as f32
}

/// White furnace: white bases under a coat, a white sheen or both reflect at
/// most all the light at every angle (the bound the module doc proves: 1.017 at
/// normal incidence before the diffuse base's normalisation took every layer
/// at once), and a white isotropic dielectric under them within 2.5% of all of
/// it, `albedo()` saying so within 1%. What the rest lose is GGX's single
/// scattering: an anisotropic lobe 0.67 wide loses what an isotropic one of that
/// width does (a white conductor of alpha 0.67 reflects 0.53 at normal incidence).
/// A thin film's Fresnel swings with angle while the albedo tables know
/// Schlick's curve: the diffuse base gets what the film leaves at each cosine
/// (split-sum), within 1% here (4.5% at roughness 0.7); under a coat a base of
/// roughness 0.2 loses 10% at grazing with or without a film (GGX's single
/// scattering twice).
#[test]
fn white_layered_materials_neither_create_nor_lose_much_light() {
    let white = Pbr { base: Rgb::ONE, ..Pbr::dielectric(Rgb::ONE) };
    let metal = Pbr { metallic: 1.0, roughness: 0.3, ..white };
    // (name, parameters, least albedo, most albedo, whether albedo() is exact)
    for (name, p, least, most, told_exact) in [
        ("coated white dielectric", Pbr { coat: 1.0, coat_roughness: 0.1, ..white }, 0.975, 1.002, true),
        ("rough coat over white", Pbr { coat: 1.0, coat_roughness: 0.8, roughness: 0.3, ..white }, 0.975, 1.002, true),
        ("white sheen over white", Pbr { sheen: Rgb::ONE, sheen_roughness: 0.5, ..white }, 0.975, 1.002, true),
        ("smooth sheen over white", Pbr { sheen: Rgb::ONE, sheen_roughness: 0.1, ..white }, 0.975, 1.002, true),
        (
            "coat and sheen over anisotropic white",
            Pbr {
                coat: 1.0,
                coat_roughness: 0.2,
                sheen: Rgb::ONE,
                sheen_roughness: 0.3,
                anisotropy: 0.8,
                anisotropy_dir: Vec3::X,
                roughness: 0.5,
                ..white
            },
            0.9,
            1.002,
            false,
        ),
        (
            "thin film over white",
            Pbr { iridescence: 1.0, iridescence_ior: 1.8, iridescence_thickness: 300.0, roughness: 0.3, ..white },
            0.96,
            1.01,
            false,
        ),
        (
            "thin film of the default ior under a coat",
            Pbr {
                iridescence: 1.0,
                iridescence_thickness: 150.0,
                coat: 1.0,
                coat_roughness: 0.1,
                roughness: 0.2,
                ..white
            },
            0.88,
            1.002,
            false,
        ),
        ("coated white metal", Pbr { coat: 1.0, coat_roughness: 0.05, ..metal }, 0.8, 1.002, false),
        ("anisotropic white metal", Pbr { anisotropy: 0.8, anisotropy_dir: Vec3::X, ..metal }, 0.7, 1.002, false),
        (
            "white metal under a thin film",
            Pbr { iridescence: 0.8, iridescence_ior: 2.0, iridescence_thickness: 400.0, ..metal },
            0.8,
            1.002,
            false,
        ),
    ] {
        let bsdf = Bsdf::from_pbr(&p);
        assert!(matches!(bsdf, Bsdf::Layered(_)), "{name}: {bsdf:?}");
        for cos in [1.0f32, 0.7, 0.4, 0.2, 0.08] {
            let a = albedo(&bsdf, dir(cos, 0.4));
            assert!(a.max_element() <= most, "{name}, cos {cos}: albedo {a} creates light");
            assert!(a.min_element() >= least, "{name}, cos {cos}: albedo {a} below {least}");
            let told = bsdf.albedo(dir(cos, 0.4), N_UP);
            if told_exact {
                assert!((told - a).abs().max_element() < 0.025, "{name}, cos {cos}: albedo() {told}, integrated {a}");
            }
        }
    }
}

/// The parts renderers split a coated dielectric into (`layers`) add up to the
/// whole under even light, as the plain dielectric's do.
#[test]
fn a_coated_dielectric_splits_into_its_base_and_its_layers_without_losing_light() {
    let p = Pbr {
        coat: 1.0,
        coat_roughness: 0.1,
        sheen: Rgb::splat(0.5),
        sheen_roughness: 0.4,
        ..Pbr::dielectric(Rgb::new(0.7, 0.1, 0.1))
    };
    let bsdf = Bsdf::from_pbr(&p);
    assert!(bsdf.layer_alpha().is_some_and(|a| (a - 0.01f32.max(MIN_ALPHA)).abs() < 1e-6));
    for cos in [1.0f32, 0.6, 0.25] {
        let wo = dir(cos, 1.1);
        let l = bsdf.layers(wo, N_UP).unwrap();
        let whole = albedo(&bsdf, wo);
        let parts = l.base_albedo + albedo(&l.layer, wo) * l.layer_weight;
        assert!((parts - whole).abs().max_element() < 0.02, "cos {cos}: parts {parts}, whole {whole}");
    }
}

/// Without a tangent (a mesh with neither tangents nor texture coordinates) an
/// anisotropic lobe lies the same way whether a renderer passes the normal
/// turned toward the viewer or not.
#[test]
fn an_anisotropic_lobe_without_a_tangent_does_not_turn_with_the_normals_sign() {
    let bsdf = Bsdf::from_pbr(&Pbr { metallic: 1.0, roughness: 0.4, anisotropy: 0.9, ..Pbr::dielectric(Rgb::ONE) });
    let Bsdf::Layered(l) = bsdf else { panic!("{bsdf:?}") };
    assert_eq!(l.tangent, Vec3::ZERO);
    for n in [Vec3::Z, Vec3::new(0.3, -0.5, 0.2).normalize(), Vec3::X, Vec3::new(0.0, 0.6, 0.0).normalize()] {
        for i in 0..64u64 {
            let mut s = Sampler::new(4, i);
            let (a, b) = (s.next_2d(), s.next_2d());
            let (t, bt) = basis(n);
            let local = |u: Vec2| {
                let d = dir(u.x.max(0.05), TAU * u.y);
                t * d.x + bt * d.y + n * d.z
            };
            let (wo, wi) = (local(a), local(b));
            let (f1, f2) = (bsdf.f(wo, wi, n), bsdf.f(wo, wi, -n));
            assert!((f1 - f2).abs().max_element() <= 1e-4 * f1.max_element().max(1.0), "n {n}: {f1} against {f2}");
        }
    }
}
