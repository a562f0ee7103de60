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

/// Grid points in mu (cosine of the direction, 0..1) and in alpha (MIN_ALPHA..1)
/// or sheen roughness (MIN_SHEEN_ROUGHNESS..1), for both tables.
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
    grid_coord((alpha - crate::MIN_ALPHA) / (1.0 - crate::MIN_ALPHA))
}

/// The cell and fraction of `x` in [0, 1] on a grid of `N` points spanning it.
fn grid_coord(x: f32) -> (usize, f32) {
    let x = x.clamp(0.0, 1.0) * (N - 1) as f32;
    let j = (x as usize).min(N - 2);
    (j, x - j as f32)
}

/// Table `tab` (row-major in mu, `N` x `N`) read bilinearly at cosine `mu` and
/// the column coordinate `(j, fy)`.
fn bilinear(tab: &[f32], mu: f32, (j, fy): (usize, f32)) -> f32 {
    let (i, fx) = grid_coord(mu);
    let v = |ii: usize, jj: usize| tab[ii * N + jj];
    (v(i, j) * (1.0 - fx) + v(i + 1, j) * fx) * (1.0 - fy) + (v(i, j + 1) * (1.0 - fx) + v(i + 1, j + 1) * fx) * fy
}

/// Directional albedo of the GGX layer with normal-incidence reflectance `f0`
/// (scalar) at cos(theta) = `mu`: F0 A + B, in [0, 1].
pub(crate) fn layer_albedo(f0: f32, mu: f32, alpha: f32) -> f32 {
    let t = &*TABLES;
    let c = alpha_coord(alpha);
    (f0 * bilinear(&t.a, mu, c) + bilinear(&t.b, mu, c)).clamp(0.0, 1.0)
}

/// The least value over mu of [`layer_albedo`] (at the grid's cosines).
pub(crate) fn layer_albedo_min(f0: f32, alpha: f32) -> f32 {
    (0..N).map(|i| layer_albedo(f0, mu_at(i), alpha)).fold(1.0, f32::min)
}

/// The cosine-weighted mean of [`layer_albedo`] over the hemisphere.
pub(crate) fn layer_albedo_mean(f0: f32, alpha: f32) -> f32 {
    let t = &*TABLES;
    let (j, fy) = alpha_coord(alpha);
    let lerp = |tab: &[f32]| tab[j] * (1.0 - fy) + tab[j + 1] * fy;
    (f0 * lerp(&t.a_mean) + lerp(&t.b_mean)).clamp(0.0, 1.0)
}

/// Midpoint quadrature per sheen grid point: this many cosines times as many azimuths.
const SHEEN_Q: usize = 64;

/// Directional albedo E_s(mu) of the Charlie sheen lobe (white sheen colour) at
/// (mu index, roughness index), row-major in mu, with the least value per
/// roughness index.
struct SheenTable {
    e: Vec<f32>,
    least: Vec<f32>,
}

fn sheen_roughness_at(j: usize) -> f32 {
    let r0 = crate::layered::MIN_SHEEN_ROUGHNESS;
    r0 + (1.0 - r0) * j as f32 / (N - 1) as f32
}

/// Integrated once per process (when a sheen is first met) by midpoint
/// quadrature over cos(theta_i) and phi: E_s(mu) = int f_sheen cos_i dw_i.
static SHEEN: LazyLock<SheenTable> = LazyLock::new(|| {
    use glam::Vec3;
    let mut e = vec![0.0; N * N];
    for j in 0..N {
        let r = sheen_roughness_at(j);
        for i in 0..N {
            let mu = mu_at(i);
            let lo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
            let mut sum = 0.0f64;
            for a in 0..SHEEN_Q {
                let z = (a as f32 + 0.5) / SHEEN_Q as f32;
                let s = (1.0 - z * z).max(0.0).sqrt();
                for b in 0..SHEEN_Q {
                    let phi = std::f32::consts::TAU * (b as f32 + 0.5) / SHEEN_Q as f32;
                    let li = Vec3::new(s * phi.cos(), s * phi.sin(), z);
                    sum += (crate::layered::charlie_f(lo, li, r * r) * z) as f64;
                }
            }
            // dw = dz dphi: the grid's cell is (1 / Q) (2 pi / Q).
            e[i * N + j] = (sum * std::f64::consts::TAU / (SHEEN_Q * SHEEN_Q) as f64) as f32;
        }
    }
    let least = (0..N).map(|j| (0..N).map(|i| e[i * N + j]).fold(f32::INFINITY, f32::min)).collect();
    SheenTable { e, least }
});

/// Fractional grid coordinate of sheen alpha (= roughness^2).
fn sheen_coord(alpha: f32) -> (usize, f32) {
    let r0 = crate::layered::MIN_SHEEN_ROUGHNESS;
    grid_coord((alpha.max(0.0).sqrt() - r0) / (1.0 - r0))
}

/// Directional albedo of the Charlie sheen lobe of white colour at cos(theta) =
/// `mu` and sheen alpha `alpha`, in [0, 1].
pub(crate) fn sheen_albedo(mu: f32, alpha: f32) -> f32 {
    bilinear(&SHEEN.e, mu, sheen_coord(alpha)).clamp(0.0, 1.0)
}

/// The least value over mu of [`sheen_albedo`] (a lower bound: the two
/// neighbouring roughnesses' least values interpolated).
pub(crate) fn sheen_albedo_min(alpha: f32) -> f32 {
    let t = &*SHEEN;
    let (j, fy) = sheen_coord(alpha);
    (t.least[j] * (1.0 - fy) + t.least[j + 1] * fy).clamp(0.0, 1.0)
}
