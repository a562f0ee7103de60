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
    /// What a surface estimate's photon search counts
    /// ([`pm_estimate::irradiance_on`]): a part counts when a ray down from
    /// `above` \[m\] over the disc's plane meets a surface facing the disc's way
    /// before `below` \[m\] under it (the estimate's half gaps), seen from the
    /// centre or not (photons are found by distance, not by sight), and, with
    /// `cover` (distance \[m\], the centre's state), only where that surface lies
    /// under a cover exactly when the centre does (the estimate keeps covered and
    /// open photons apart). The vertex method's corners had counted only what
    /// their centre saw: on the floor beside a glass box the floor beyond the box
    /// was out of view, its photons were in the estimate, and the corners at the
    /// box's foot read 2-4 times too bright (issue 53's checker, seed 12902 scene 3).
    /// With `view` (a height \[m\]), only the parts whose surface point is
    /// [`in_view`] of the centre at that height count, for an estimate that
    /// counts only the photons so seen.
    Estimate {
        /// How far under the disc's plane a surface counts \[m\].
        below: f32,
        /// How far over it \[m\].
        above: f32,
        /// The cover distance \[m\] and whether the centre is under a cover.
        cover: Option<(f32, bool)>,
        /// The height \[m\] at which a part must be in view of the centre.
        view: Option<f32>,
    },
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
    let (above, depth) = match probe {
        Probe::Estimate { below, above, .. } => (above, above + below),
        Probe::Slab(half) => (half, 2.0 * half),
    };
    let (mut covered, mut total) = (0.0, 0.0);
    for ring in (0..RINGS).rev() {
        let s = ((ring as f32 + 0.5) / RINGS as f32).sqrt();
        let w = weight(s);
        total += w * SPOKES as f32;
        let mut all = true;
        for spoke in 0..SPOKES {
            // The rings turn by irrational steps so that no sample lies on an axis.
            let a = std::f32::consts::TAU * (spoke as f32 + 0.5 + 0.382 * ring as f32) / SPOKES as f32;
            let off = (t * a.cos() + b * a.sin()) * (r * s);
            let o = p + n * above + off;
            let on_surface = match probe {
                Probe::Estimate { cover, view, .. } => {
                    let found = match cover {
                        // Under a cover along the surface's own normal there, as
                        // its photons are flagged (along the disc's, a point on
                        // a sphere found its own facet).
                        Some((within, centre)) => {
                            surface_below(scene, o, n, depth, |q, nq| scene.covered(q, nq, within) == centre)
                        }
                        None => surface_below(scene, o, n, depth, |_, _| true),
                    };
                    found.is_some_and(|q| view.is_none_or(|lift| in_view(scene, p, n, q, lift)))
                }
                Probe::Slab(_) => surface_below(scene, o, n, depth, |_, _| true).is_some(),
            };
            if on_surface {
                covered += w;
            } else {
                all = false;
            }
        }
        if all && ring == RINGS - 1 && matches!(probe, Probe::Slab(_)) {
            return 1.0;
        }
    }
    if total > 0.0 { covered / total } else { 1.0 }
}

/// Whether point `q` (a photon, a part of a disc) is in view of the surface
/// point `x` (unit normal `n`) as an estimate there may count it: the segment
/// between the two, both lifted `lift` \[m\] along `n`, meets no solid surface
/// (glass blocks it: what lies beyond a glass box standing on the floor is not
/// the floor around `x`).
pub fn in_view(scene: &Scene, x: Vec3, n: Vec3, q: Vec3, lift: f32) -> bool {
    let (a, b) = (x + n * lift, q + n * lift);
    let d = b - a;
    let len = d.length();
    !(len > 0.0 && scene.solidly_occluded(a, d / len, len))
}

/// Where a ray down (along -`n`) from `o` meets, within `depth` \[m\], a surface
/// point facing `n`'s way (either side of it, [`SAME_SURFACE_COS`]) that `keep`
/// accepts (given the point and the surface's normal there on `n`'s side),
/// passing through the steeper surfaces (the side of a sphere standing on the
/// floor, seen from inside) and those it refuses; at most four surfaces are
/// passed.
fn surface_below(
    scene: &Scene,
    mut o: Vec3,
    n: Vec3,
    mut depth: f32,
    keep: impl Fn(Vec3, Vec3) -> bool,
) -> Option<Vec3> {
    for _ in 0..4 {
        let hit = scene.solid_hit(o, -n, depth)?;
        let ng = pm_scene::facing(hit.ng, n);
        if ng.dot(n) > SAME_SURFACE_COS && keep(hit.p, ng) {
            return Some(hit.p);
        }
        depth -= (hit.p - o).dot(-n);
        o = scene.offset_origin(hit.p, hit.ng, -n);
        if !(depth > 0.0) {
            return None;
        }
    }
    None
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

    /// Against the disc's area on the floor, computed by hand: all of it in the
    /// open, half at the floor's open edge, a quarter at the floor's corner, and
    /// all of it beside the wall standing on the floor, whose far side holds
    /// photons the estimate finds as well, or, counting only what the centre
    /// sees, a chord at half the radius (within the 32 samples' resolution).
    #[test]
    fn estimate_coverage_is_the_part_of_the_disc_whose_photons_the_estimate_counts() {
        let s = floor_wall_and_strips();
        let probe = Probe::Estimate { below: 0.1, above: 0.1, cover: None, view: None };
        let cases = [
            (Vec3::new(0.8, 0.0, 0.5), 1.0, 0.0),
            (Vec3::new(1.0, 0.0, 0.5), 0.5, 0.0),
            (Vec3::new(1.0, 0.0, 1.0), 0.25, 0.04),
            (Vec3::new(0.2, 0.0, 0.5), 1.0, 0.0),
            (Vec3::new(0.4, 0.0, 0.5), 1.0, 0.0),
        ];
        for (p, want, tol) in cases {
            let got = disc_coverage(&s, p, Vec3::Y, 0.2, probe, |_| 1.0);
            assert!((got - want).abs() <= tol + 1e-6, "at {p}: {got} against {want}");
        }
        // For an estimate that counts only the photons in view, the wall cuts a
        // chord at half the radius on either side of it.
        let seen = Probe::Estimate { below: 0.1, above: 0.1, cover: None, view: Some(0.05) };
        for p in [Vec3::new(0.2, 0.0, 0.5), Vec3::new(0.4, 0.0, 0.5)] {
            let got = disc_coverage(&s, p, Vec3::Y, 0.2, seen, |_| 1.0);
            assert!((got - chord_at_half()).abs() <= 0.04, "at {p}, in view: {got}");
        }
    }

    /// A plate 1 cm over the floor's half x < 0.5 (above the slab): a disc whose
    /// edge it crosses at half the radius counts the open floor for an open centre
    /// and the floor under the plate for a covered one, as the estimate keeps their
    /// photons apart; without the cover test all of it counts.
    #[test]
    fn estimate_coverage_keeps_covered_and_open_floor_apart() {
        let mut s = floor_wall_and_strips();
        let v = |x, y, z| Vec3::new(x, y, z);
        let mut tris = s.triangles.clone();
        tris.push(Triangle::new([v(-0.5, 0.01, 0.0), v(-0.5, 0.01, 1.0), v(0.5, 0.01, 1.0)], 0).unwrap());
        tris.push(Triangle::new([v(-0.5, 0.01, 0.0), v(0.5, 0.01, 1.0), v(0.5, 0.01, 0.0)], 0).unwrap());
        s = Scene::from_parts(tris, s.materials.clone(), Vec::new(), None);
        let p = Vec3::new(0.6, 0.0, 0.5);
        let share = |cover| {
            let probe = Probe::Estimate { below: 0.1, above: 0.005, cover, view: None };
            disc_coverage(&s, p, Vec3::Y, 0.2, probe, |_| 1.0)
        };
        let open = share(Some((0.05, false)));
        assert!((open - chord_at_half()).abs() <= 0.04, "open: {open}");
        let shut = share(Some((0.05, true)));
        assert!((shut - (1.0 - chord_at_half())).abs() <= 0.04, "covered: {shut}");
        assert_eq!(share(None), 1.0, "without the cover test");
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
        // Over the strips: all the floor below them counts.
        let strips = Vec3::new(0.63, 0.0, 0.1);
        let got = disc_coverage(&s, strips, Vec3::Y, 0.1, Probe::Slab(0.05), cone);
        assert_eq!(got, 1.0, "over the strips");
    }
}
