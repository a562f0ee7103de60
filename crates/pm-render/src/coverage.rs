//! How much of a kernel's disc lies on the surface it is centred on: the boundary
//! bias of kernel density estimation (Silverman 1986, section 2.10), for the
//! estimates that show it directly.
//!
//! A kernel estimate divides the photons' power by the kernel's integral over its
//! whole disc (Jensen 1996, eq. 6). Where the disc runs off the surface (a wall
//! meeting the floor, the floor around a box standing on it) photons lie on only
//! part of it, so the estimate reads half (an edge) or a quarter (a corner) of the
//! light. The batch pipeline's final gather hides that; the vertex method's corner
//! estimates (issue 36) and image-space photon volumes (issue 53) show it, and both
//! divide by the part of the disc covered, probed here.

use glam::Vec3;
use pm_scene::Scene;

/// Least cosine between a photon's surface normal and a point's for the photon to
/// light the point (the test of every photon estimate), and so the test of what
/// [`disc_coverage`] counts as the same surface: an estimate that divides by the
/// coverage must make the same test.
pub use pm_estimate::SAME_SURFACE_COS;

/// Rings and spokes of the sample pattern (equal-area rings; each sample has its
/// opposite, so an edge through the centre covers exactly half).
const RINGS: usize = 4;
const SPOKES: usize = 8;

/// The least fraction an estimate should be divided by: a disc almost all off the
/// surface gains at most this much (a corner of a thin sliver, a probe lost).
pub const MIN_COVERAGE: f32 = 0.125;

/// Which parts of a disc count as covered: those a probe finds on a surface facing
/// the disc's way ([`SAME_SURFACE_COS`]) within a slab about the disc's plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Probe {
    /// In view of the centre: the slab is half the radius thick, and a part counts
    /// only if the point a quarter of the radius above it is seen from the point as
    /// far above the centre (a k-nearest estimate's photons lie on the surface
    /// around the corner, not behind a wall standing on it).
    InView,
    /// Anywhere within the slab |offset · n| < half-thickness \[m\], seen or not:
    /// the support of an image-space photon volume, which lights every pixel
    /// within its ellipsoid (an occlusion test there counted the floor under a
    /// sphere as uncovered, and the volumes around its foot shone eight times too
    /// bright).
    Slab(f32),
}

/// The part (0 to 1) of the disc of radius `r` \[m\] about `p` (unit normal `n`)
/// in its tangent plane that lies on surfaces of `scene` facing `n`'s way, as
/// `probe` tests, each part weighted by `weight(distance / r)` (the kernel's radial
/// profile: `|_| 1.0` for a disc).
///
/// Probed with rays: sample points on rings of the disc, each covered when a ray
/// down from the top of the slab above it meets a surface facing `n`'s way
/// ([`SAME_SURFACE_COS`], the photons' own test) within the slab.
/// The outermost ring is probed first. For [`Probe::Slab`], when all of it is
/// covered, so is the disc (the inner rings are not probed; a hole inside an
/// unbroken ring is missed), which spares three quarters of the rays in the middle
/// of a surface: volumes are probed afresh every frame. The vertex method caches
/// its corners' fractions and probes every ring.
pub fn disc_coverage(scene: &Scene, p: Vec3, n: Vec3, r: f32, probe: Probe, weight: impl Fn(f32) -> f32) -> f32 {
    let (t, b) = n.any_orthonormal_pair();
    let h = match probe {
        Probe::InView => 0.25 * r,
        Probe::Slab(half) => half,
    };
    let above = p + n * h;
    let (mut covered, mut total) = (0.0, 0.0);
    for ring in (0..RINGS).rev() {
        let s = ((ring as f32 + 0.5) / RINGS as f32).sqrt();
        let w = weight(s);
        total += w * SPOKES as f32;
        let mut all = true;
        for spoke in 0..SPOKES {
            // The rings turn by irrational steps so that no sample lies on an axis.
            let a = std::f32::consts::TAU * (spoke as f32 + 0.5 + 0.382 * ring as f32) / SPOKES as f32;
            let o = above + (t * a.cos() + b * a.sin()) * (r * s);
            let d = o - above;
            let len = d.length();
            let on_surface = match probe {
                Probe::InView => {
                    !(len > 0.0 && scene.occluded(above, d / len, len))
                        && scene.intersect(o, -n, 2.0 * h).is_some_and(|hit| hit.ng.dot(n) > SAME_SURFACE_COS)
                }
                Probe::Slab(_) => surface_below(scene, o, n, 2.0 * h),
            };
            if on_surface {
                covered += w;
            } else {
                all = false;
            }
        }
        if all && ring == RINGS - 1 && probe != Probe::InView {
            return 1.0;
        }
    }
    if total > 0.0 { covered / total } else { 1.0 }
}

/// Whether a ray down (along -`n`) from `o` meets a surface facing `n`'s way (either
/// side of it, [`SAME_SURFACE_COS`]) within `depth` \[m\], passing through the
/// surfaces that do not (the inside of a sphere standing on the floor); at most
/// four surfaces are passed.
fn surface_below(scene: &Scene, mut o: Vec3, n: Vec3, mut depth: f32) -> bool {
    for _ in 0..4 {
        let Some(hit) = scene.intersect(o, -n, depth) else { return false };
        if pm_scene::facing(hit.ng, n).dot(n) > SAME_SURFACE_COS {
            return true;
        }
        depth -= (hit.p - o).dot(-n);
        o = scene.offset_origin(hit.p, hit.ng, -n);
        if !(depth > 0.0) {
            return false;
        }
    }
    false
}
