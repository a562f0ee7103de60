//! Directional albedo of the GGX specular layer, tabulated once: what the glTF
//! dielectric's layer reflects of light arriving at cos(theta) = mu, so that the
//! diffuse base can be weighted by exactly what the layer leaves (the albedo
//! scaling of Kelemen and Szirmay-Kalos 2001 and Kulla and Conty 2017).
//!
//! With Schlick's Fresnel F = F0 + (1 - F0)(1 - wo.h)^5 the albedo is linear in
//! F0: E(mu) = F0 A(mu, alpha) + B(mu, alpha), with A the albedo of the GGX lobe
//! weighted by 1 - (1 - wo.h)^5 and B by (1 - wo.h)^5. Both are integrated here by
//! importance sampling half vectors from D(h) cos(h) (1,024 Hammersley points), on
//! a 32 x 32 grid of mu and alpha, once per process, and read back bilinearly.

use std::sync::LazyLock;

/// Grid points in mu (cosine of the direction, 0..1) and alpha (MIN_ALPHA..1).
const N: usize = 32;
/// Half vectors per grid point.
const SAMPLES: u32 = 1024;

struct Tables {
    /// A and B at (mu index, alpha index), row-major in mu.
    a: Vec<f32>,
    b: Vec<f32>,
    /// Cosine-weighted means 2 int A mu dmu and 2 int B mu dmu per alpha index.
    a_mean: Vec<f32>,
    b_mean: Vec<f32>,
}

fn alpha_at(j: usize) -> f32 {
    crate::MIN_ALPHA + (1.0 - crate::MIN_ALPHA) * j as f32 / (N - 1) as f32
}

fn mu_at(i: usize) -> f32 {
    (i as f32 / (N - 1) as f32).max(1e-3)
}

static TABLES: LazyLock<Tables> = LazyLock::new(|| {
    use glam::{Vec2, Vec3};
    let mut a = vec![0.0; N * N];
    let mut b = vec![0.0; N * N];
    for j in 0..N {
        let alpha = alpha_at(j);
        for i in 0..N {
            let mu = mu_at(i);
            let lo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
            let (mut sa, mut sb) = (0.0f64, 0.0f64);
            for k in 0..SAMPLES {
                let u = Vec2::new((k as f32 + 0.5) / SAMPLES as f32, (k.reverse_bits() as f64 / 4294967296.0) as f32);
                let h = crate::ggx_sample_h(u, alpha);
                let li = crate::reflect(lo, h);
                let (vh, cos_h) = (lo.dot(h), h.z);
                if li.z <= 0.0 || vh <= 0.0 || cos_h <= 0.0 {
                    continue;
                }
                // f cos / pdf with F = 1: G vh / (mu cos_h).
                let g = crate::ggx_g1(lo.z, alpha) * crate::ggx_g1(li.z, alpha);
                let w = (g * vh / (mu * cos_h)) as f64;
                let s = ((1.0 - vh) as f64).powi(5);
                sa += w * (1.0 - s);
                sb += w * s;
            }
            a[i * N + j] = (sa / SAMPLES as f64) as f32;
            b[i * N + j] = (sb / SAMPLES as f64) as f32;
        }
    }
    // 2 int f(mu) mu dmu by the trapezoid rule over the grid.
    let mean = |t: &[f32], j: usize| {
        let h = 1.0 / (N - 1) as f32;
        (0..N - 1).map(|i| 0.5 * h * (t[i * N + j] * mu_at(i) + t[(i + 1) * N + j] * mu_at(i + 1))).sum::<f32>() * 2.0
    };
    let a_mean = (0..N).map(|j| mean(&a, j)).collect();
    let b_mean = (0..N).map(|j| mean(&b, j)).collect();
    Tables { a, b, a_mean, b_mean }
});

/// Fractional grid coordinate of `alpha`.
fn alpha_coord(alpha: f32) -> (usize, f32) {
    let x = ((alpha - crate::MIN_ALPHA) / (1.0 - crate::MIN_ALPHA)).clamp(0.0, 1.0) * (N - 1) as f32;
    let j = (x as usize).min(N - 2);
    (j, x - j as f32)
}

/// Directional albedo of the GGX layer with normal-incidence reflectance `f0`
/// (scalar) at cos(theta) = `mu`: F0 A + B, in [0, 1].
pub(crate) fn layer_albedo(f0: f32, mu: f32, alpha: f32) -> f32 {
    let t = &*TABLES;
    let x = mu.clamp(0.0, 1.0) * (N - 1) as f32;
    let i = (x as usize).min(N - 2);
    let fx = x - i as f32;
    let (j, fy) = alpha_coord(alpha);
    let at = |tab: &[f32]| {
        let v = |ii: usize, jj: usize| tab[ii * N + jj];
        (v(i, j) * (1.0 - fx) + v(i + 1, j) * fx) * (1.0 - fy) + (v(i, j + 1) * (1.0 - fx) + v(i + 1, j + 1) * fx) * fy
    };
    (f0 * at(&t.a) + at(&t.b)).clamp(0.0, 1.0)
}

/// The cosine-weighted mean of [`layer_albedo`] over the hemisphere.
pub(crate) fn layer_albedo_mean(f0: f32, alpha: f32) -> f32 {
    let t = &*TABLES;
    let (j, fy) = alpha_coord(alpha);
    let lerp = |tab: &[f32]| tab[j] * (1.0 - fy) + tab[j + 1] * fy;
    (f0 * lerp(&t.a_mean) + lerp(&t.b_mean)).clamp(0.0, 1.0)
}
