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
/// Index-matched boundaries are passed, as photons pass them
/// ([`Scene::solid_hit`], [`Scene::solidly_occluded`]): the bottom face of a fog
/// box 2 mm above a floor, facing away from it, looked like the floor's edge, the
/// floor's discs read 0-25% covered, and the vertex method's corners there came
/// out 2-4 times too bright (issue 53's checker, seed 77777).
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
            let on_surface = match probe {
                Probe::InView => {
                    let d = o - above;
                    let len = d.length();
                    !(len > 0.0 && scene.solidly_occluded(above, d / len, len))
                        && scene.solid_hit(o, -n, 2.0 * h).is_some_and(|hit| hit.ng.dot(n) > SAME_SURFACE_COS)
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
/// steeper ones (the side of a sphere standing on the floor, seen from inside);
/// at most four surfaces are passed.
fn surface_below(scene: &Scene, mut o: Vec3, n: Vec3, mut depth: f32) -> bool {
    for _ in 0..4 {
        let Some(hit) = scene.solid_hit(o, -n, depth) else { return false };
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

#[cfg(test)]
mod tests {
    use super::*;
    use pm_color::Rgb;
    use pm_scene::{Material, Triangle};

    /// A unit square floor (y = 0, facing up), a wall at x = 0.3 standing on it,
    /// and a sawtooth of steep strips (70 degrees, 2 cm wide, 5.5 cm high, every
    /// 3 cm from x = 0.5 to 0.76) over the floor's corner z < 0.25.
    fn floor_wall_and_strips() -> Scene {
        let v = |x, y, z| Vec3::new(x, y, z);
        let quad = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| {
            [Triangle::new([a, b, c], 0).unwrap(), Triangle::new([a, c, d], 0).unwrap()]
        };
        let mut tris = Vec::new();
        tris.extend(quad(v(0.0, 0.0, 0.0), v(0.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, 0.0)));
        tris.extend(quad(v(0.3, 0.0, 0.0), v(0.3, 1.0, 0.0), v(0.3, 1.0, 1.0), v(0.3, 0.0, 1.0)));
        let top = 0.02 * 70f32.to_radians().tan();
        for k in 0..9 {
            let x = 0.5 + 0.03 * k as f32;
            tris.extend(quad(v(x, 0.0, 0.0), v(x, 0.0, 0.25), v(x + 0.02, top, 0.25), v(x + 0.02, top, 0.0)));
        }
        let grey = Material::new("grey", pm_bsdf::Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::ZERO);
        Scene::from_parts(tris, vec![grey], Vec::new(), None)
    }

    /// 1 - (acos(1/2) - sqrt(3)/4) / pi: a disc's part on the near side of a chord
    /// at half its radius.
    fn chord_at_half() -> f32 {
        1.0 - ((0.5f32).acos() - 3f32.sqrt() / 4.0) / std::f32::consts::PI
    }

    /// Against the disc's area on the floor, computed by hand: all of it in the open,
    /// half at the floor's open edge, a quarter at the floor's corner, and with the
    /// wall a chord at half the radius away on either side (within the 32 samples'
    /// resolution) for the vertex method's probe, which counts only what the centre
    /// sees. (A corner exactly at the wall's foot sees the floor on both sides: its
    /// probes start in the wall's plane.)
    #[test]
    fn in_view_coverage_is_the_part_of_the_disc_on_the_surface_in_view() {
        let s = floor_wall_and_strips();
        let cases = [
            (Vec3::new(0.8, 0.0, 0.5), 1.0, 0.0),
            (Vec3::new(1.0, 0.0, 0.5), 0.5, 0.0),
            (Vec3::new(1.0, 0.0, 1.0), 0.25, 0.0),
            (Vec3::new(0.2, 0.0, 0.5), chord_at_half(), 0.04),
            (Vec3::new(0.4, 0.0, 0.5), chord_at_half(), 0.04),
        ];
        for (p, want, tol) in cases {
            let got = disc_coverage(&s, p, Vec3::Y, 0.2, Probe::InView, |_| 1.0);
            assert!((got - want).abs() <= tol + 1e-6, "at {p}: {got} against {want}");
        }
    }

    /// A photon volume's support has no view test: the floor behind the wall
    /// counts (the volume lights it), and rays down pass the steep strips to the
    /// floor below them; the open edge and corner still cover a half and a quarter
    /// with the cone kernel's weights (each ring is cut in half alike).
    #[test]
    fn slab_coverage_counts_the_surface_within_the_slab_seen_or_not() {
        let s = floor_wall_and_strips();
        let cone = |t: f32| 1.0 - t;
        let cases = [
            (Vec3::new(0.2, 0.0, 0.5), 1.0, 0.0),
            (Vec3::new(0.4, 0.0, 0.5), 1.0, 0.0),
            (Vec3::new(1.0, 0.0, 0.5), 0.5, 1e-6),
            (Vec3::new(1.0, 0.0, 1.0), 0.25, 0.04),
        ];
        for (p, want, tol) in cases {
            let got = disc_coverage(&s, p, Vec3::Y, 0.2, Probe::Slab(0.05), cone);
            assert!((got - want).abs() <= tol + 1e-6, "at {p}: {got} against {want}");
        }
        // Over the strips: all the floor below them counts, where the vertex
        // method's probe stops at them.
        let strips = Vec3::new(0.63, 0.0, 0.1);
        let got = disc_coverage(&s, strips, Vec3::Y, 0.1, Probe::Slab(0.05), cone);
        assert_eq!(got, 1.0, "over the strips");
        let in_view = disc_coverage(&s, strips, Vec3::Y, 0.1, Probe::InView, |_| 1.0);
        assert!(in_view < 0.9, "over the strips, in view: {in_view}");
    }
}
