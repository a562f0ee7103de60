use super::*;
use pm_format::{FullIrrPhoton, FullPhoton, Photon};

fn photon(p: Vec3, power: f32, n: Vec3, wi: Vec3) -> Photon {
    Photon { position: p, power: Rgb::splat(power), wi, flags: flags::AXIS_LEAF, normal: n, irradiance: Rgb::ZERO }
}

/// Integral of each filter's weight over the unit disk equals its area pi, so a
/// uniform density is estimated without bias by any filter.
#[test]
fn filters_are_normalised() {
    for f in [Filter::None, Filter::Cone { k: 1.0 }, Filter::Cone { k: 1.1 }, Filter::Gaussian] {
        let n = 2000;
        let mut integral = 0.0f64;
        for i in 0..n {
            let r = (i as f32 + 0.5) / n as f32;
            integral += (f.weight(r * r, 1.0) * 2.0 * PI * r) as f64 / n as f64;
        }
        assert!((integral / PI as f64 - 1.0).abs() < 2e-3, "{f:?}: {integral}");
    }
}

#[test]
fn uniform_grid_gives_the_exact_density() {
    // Photons of 1 mW on a 1 mm grid: E = 1e-3 W / 1e-6 m^2 = 1000 W/m^2. A disk of
    // radius r holds ~pi r^2 / 1e-6 photons; with k = 200 the boundary discretisation
    // error is about 1/sqrt(k) in the count's placement, well under 10%.
    let mut ps = Vec::new();
    for i in -40..=40 {
        for j in -40..=40 {
            ps.push(FullIrrPhoton::encode(&photon(
                Vec3::new(i as f32 * 1e-3, 0.0, j as f32 * 1e-3),
                1e-3,
                Vec3::Y,
                Vec3::Y,
            )));
        }
    }
    let nodes = pm_kdtree::balance(&ps);
    let tree = KdTree::new(&nodes);
    let mut s = KnnScratch::default();
    let p = KnnParams { k: 200, max_d2: f32::INFINITY, filter: Filter::None };
    let e = irradiance(&tree, Vec3::new(0.0, 0.0, 0.0), Vec3::Y, &p, &mut s);
    assert_eq!(e.count, 200);
    assert!((e.e.x / 1000.0 - 1.0).abs() < 0.1, "{}", e.e.x);
}

#[test]
fn corners_and_thin_walls_do_not_leak() {
    // Floor y = 0 (normal +y) meets a thin wall x = 0. The wall's lit face (normal -x,
    // facing the floor region x < 0... here the room is x > 0, so its face is +x) and
    // its back face (normal -x, in the dark room) carry bright photons. Irradiance on
    // the floor near the corner must come from floor photons only, and the dark side
    // of the wall must see nothing of the lit side.
    let mut ps = Vec::new();
    let mut floor_only = Vec::new();
    for i in 0..30 {
        for j in 0..30 {
            let (a, b) = (i as f32 * 0.01 + 0.005, j as f32 * 0.01 - 0.15);
            let f = photon(Vec3::new(a, 0.0, b), 1.0, Vec3::Y, Vec3::new(0.3, 0.9, 0.1).normalize());
            ps.push(FullIrrPhoton::encode(&f));
            floor_only.push(FullIrrPhoton::encode(&f));
            // Lit face of the wall, facing the room (+x).
            ps.push(FullIrrPhoton::encode(&photon(Vec3::new(0.0, a, b), 100.0, Vec3::X, Vec3::X)));
            // Back face, in the dark room: same positions, normal -x, nothing arrives there
            // except this probe photon set with tiny power.
            ps.push(FullIrrPhoton::encode(&photon(Vec3::new(0.0, a, b), 1e-6, -Vec3::X, -Vec3::X)));
        }
    }
    let nodes = pm_kdtree::balance(&ps);
    let tree = KdTree::new(&nodes);
    let floor_nodes = pm_kdtree::balance(&floor_only);
    let floor_tree = KdTree::new(&floor_nodes);
    let mut s = KnnScratch::default();
    let p = KnnParams { k: 50, max_d2: f32::INFINITY, filter: Filter::Cone { k: 1.1 } };
    let x = Vec3::new(0.002, 0.0, 0.0);
    let e = irradiance(&tree, x, Vec3::Y, &p, &mut s);
    let want = irradiance(&floor_tree, x, Vec3::Y, &p, &mut s);
    assert_eq!((e.count, e.r2), (want.count, want.r2), "floor estimate near the corner used wall photons");
    assert!(((e.e - want.e) / want.e).abs().max_element() < 1e-5, "{e:?} vs {want:?}");
    // Dark side: only the 1e-6 W probe photons count (100 W photons on the other face).
    let dark = irradiance(&tree, Vec3::new(-0.0001, 0.1, 0.0), -Vec3::X, &p, &mut s);
    assert!(dark.e.x > 0.0 && dark.e.x < 1e-6 * 50.0 / (PI * dark.r2) * 1.5, "leak: {}", dark.e.x);
}

#[test]
fn caustic_maps_use_the_incident_direction() {
    // Without stored normals (18/40-byte records), photons from below the query
    // surface are excluded.
    let ps: Vec<FullPhoton> = (0..100)
        .map(|i| {
            let from_below = i % 2 == 0;
            FullPhoton::encode(&photon(
                Vec3::new(i as f32 * 0.01, 0.0, 0.0),
                1.0,
                Vec3::ZERO,
                if from_below { -Vec3::Y } else { Vec3::Y },
            ))
        })
        .collect();
    let nodes = pm_kdtree::balance(&ps);
    let tree = KdTree::new(&nodes);
    let mut s = KnnScratch::default();
    let e = irradiance(
        &tree,
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::Y,
        &KnnParams { k: 1000, max_d2: f32::INFINITY, filter: Filter::None },
        &mut s,
    );
    assert_eq!(e.count, 50);
}

#[test]
fn degenerate_maps_give_zero_not_nan() {
    let same: Vec<FullIrrPhoton> =
        (0..10).map(|_| FullIrrPhoton::encode(&photon(Vec3::ONE, 1.0, Vec3::Y, Vec3::Y))).collect();
    let nodes = pm_kdtree::balance(&same);
    let tree = KdTree::new(&nodes);
    let mut s = KnnScratch::default();
    let p = KnnParams { k: 5, max_d2: f32::INFINITY, filter: Filter::Gaussian };
    // All photons exactly at the query: r = 0, no density can be formed.
    assert_eq!(irradiance(&tree, Vec3::ONE, Vec3::Y, &p, &mut s).e, Rgb::ZERO);
    // Empty map.
    let empty: Vec<FullIrrPhoton> = Vec::new();
    let e = irradiance(&KdTree::new(&empty), Vec3::ONE, Vec3::Y, &p, &mut s);
    assert_eq!((e.e, e.count), (Rgb::ZERO, 0));
    // k above the count uses them all.
    let e = irradiance(&tree, Vec3::new(1.0, 1.0, 1.5), Vec3::Y, &KnnParams { k: 100, ..p }, &mut s);
    assert_eq!(e.count, 10);
    assert!(e.e.is_finite());
}

#[test]
fn precomputed_lookup_needs_a_similar_normal_and_an_irradiance() {
    let mut a = photon(Vec3::new(0.0, 0.0, 0.0), 1.0, Vec3::Y, Vec3::Y);
    a.flags |= flags::HAS_IRRADIANCE;
    a.irradiance = Rgb::splat(7.0);
    let mut wall = photon(Vec3::new(0.01, 0.0, 0.0), 1.0, Vec3::X, Vec3::X);
    wall.flags |= flags::HAS_IRRADIANCE;
    wall.irradiance = Rgb::splat(99.0);
    let no_irr = photon(Vec3::new(0.005, 0.0, 0.0), 1.0, Vec3::Y, Vec3::Y);
    let nodes = pm_kdtree::balance(&[a, wall, no_irr].map(|p| FullIrrPhoton::encode(&p)));
    let tree = KdTree::new(&nodes);
    let mut rej = Vec::new();
    let (e, hit) = precomputed_irradiance(&tree, Vec3::new(0.009, 0.0, 0.0), Vec3::Y, f32::INFINITY, &mut rej).unwrap();
    assert_eq!(e, Rgb::splat(7.0));
    assert_eq!(hit.rank, 3, "the wall photon and the photon without irradiance were nearer");
}

/// Photons of 1 mW on a 1 mm grid on the plane y = 0 (1000 W/m^2), and 100 times
/// brighter ones on a parallel plane 0.5 mm behind it with the same normal (a
/// ceiling above a light's back): [`irradiance`] reads both planes, while
/// [`irradiance_on`], told the gap behind, reads only the query's own plane.
#[test]
fn estimates_leave_out_a_parallel_surface_a_gap_behind() {
    let mut ps = Vec::new();
    for i in -40..=40 {
        for j in -40..=40 {
            let (x, z) = (i as f32 * 1e-3, j as f32 * 1e-3);
            ps.push(FullIrrPhoton::encode(&photon(Vec3::new(x, 0.0, z), 1e-3, Vec3::Y, Vec3::Y)));
            ps.push(FullIrrPhoton::encode(&photon(Vec3::new(x + 5e-4, -5e-4, z), 0.1, Vec3::Y, Vec3::Y)));
        }
    }
    let nodes = pm_kdtree::balance(&ps);
    let tree = KdTree::new(&nodes);
    let mut s = KnnScratch::default();
    let p = KnnParams { k: 200, max_d2: f32::INFINITY, filter: Filter::None };
    let both = irradiance(&tree, Vec3::ZERO, Vec3::Y, &p, &mut s);
    assert!(both.e.x > 20_000.0, "{}", both.e.x);
    let around = Surroundings { normal: Vec3::Y, behind: 5e-4, front: f32::INFINITY };
    let (own, _) = irradiance_on(&tree, Vec3::ZERO, Vec3::Y, &around, false, &p, &mut s);
    assert!((own.e.x / 1000.0 - 1.0).abs() < 0.1, "{}", own.e.x);
}

/// A floor (y = 0, normal +y) that ends at x = 0.5 mm, as a scene would answer
/// about it: nothing around it, and a disc's point lies on it where x <= 0.5 mm
/// (the edge of the last row of 1 mm cells of the test's photon grid).
struct HalfFloor;

impl SurfaceQuery for HalfFloor {
    fn surroundings(&self, _: Vec3, _: Vec3) -> Option<Surroundings> {
        Some(Surroundings { normal: Vec3::Y, behind: 1.0, front: 1.0 })
    }
    fn continues(&self, x: Vec3, _: Vec3, off: Vec3, _: f32) -> bool {
        x.x + off.x <= 0.5e-3
    }
    fn covered(&self, _: Vec3, _: Vec3) -> bool {
        false
    }
}

/// A uniformly lit floor that ends at an edge: photons of 1 mW on a 1 mm grid for x
/// <= 0 (E = 1000 W/m^2 everywhere on it). At the photons within 2 mm of the edge
/// (about half of each estimate's disc, radius ~5.6 mm for k = 100, off the floor),
/// the precompute without the scene reads 0.65 E; with it, the estimate divides by
/// the disc's share on the floor ([`disc_share`]) and reads 1.007 E. The
/// plain estimate's edge bias is first order in the radius: -2.3% of a closed
/// room's indirect light (issue 53).
#[test]
fn estimates_at_an_edge_divide_by_the_share_of_their_disc_on_the_surface() {
    let mut ps = Vec::new();
    for i in -40..=0 {
        for j in -40..=40 {
            let p = Vec3::new(i as f32 * 1e-3, 0.0, j as f32 * 1e-3);
            ps.push(FullIrrPhoton::encode(&photon(p, 1e-3, Vec3::Y, Vec3::Y)));
        }
    }
    let p = KnnParams { k: 100, max_d2: f32::INFINITY, filter: Filter::None };
    let at_edge = |scene: Option<&dyn SurfaceQuery>| {
        let mut nodes = pm_kdtree::balance(&ps);
        precompute(&mut nodes, &p, (1.0, 0.0), scene, &|_| {});
        let edge: Vec<f32> = nodes
            .iter()
            .filter(|r| r.position().x > -2.5e-3 && r.position().z.abs() < 0.02)
            .map(|r| r.irradiance().x)
            .collect();
        edge.iter().sum::<f32>() / edge.len() as f32 / 1000.0
    };
    let (plain, corrected) = (at_edge(None), at_edge(Some(&HalfFloor)));
    eprintln!("at the edge, over E: {plain:.3} plain, {corrected:.3} with the share");
    assert!(plain < 0.7, "without the scene: {plain}");
    assert!((corrected - 1.0).abs() < 0.04, "with the share: {corrected} (without: {plain})");
}

/// A floor whose part x < 0 lies under a cover when `0` (a light's panel a
/// millimetre below, as the scene would say), every point on the floor (no edge).
struct HalfCovered(bool);

impl SurfaceQuery for HalfCovered {
    fn surroundings(&self, _: Vec3, _: Vec3) -> Option<Surroundings> {
        Some(Surroundings { normal: Vec3::Y, behind: 1.0, front: 1.0 })
    }
    fn continues(&self, _: Vec3, _: Vec3, _: Vec3, _: f32) -> bool {
        true
    }
    fn covered(&self, x: Vec3, _: Vec3) -> bool {
        self.0 && x.x < 0.0
    }
}

/// The gap above a two-sided light panel a millimetre under the ceiling is bright
/// with trapped light: photons of 10 mW there (x < 0), 1 mW on the open ceiling
/// beside it, on a 1 mm grid. The precompute flags the covered photons, and an
/// open photon's estimate counts only open ones: within 2 mm of the panel's edge
/// it reads the open ceiling's 1000 W/m^2 (1.000 of it), where counting the gap's
/// photons too gave 4.5 times that; the disc's share counts only the open side
/// (issue 53: +5% indirect light in a
/// generated room with such a light).
#[test]
fn estimates_keep_photons_under_a_cover_apart_from_the_open_surface() {
    let mut ps = Vec::new();
    for i in -40..=40 {
        for j in -40..=40 {
            let p = Vec3::new(i as f32 * 1e-3 + 0.5e-3, 0.0, j as f32 * 1e-3);
            let power = if p.x < 0.0 { 1e-2 } else { 1e-3 };
            ps.push(FullIrrPhoton::encode(&photon(p, power, Vec3::Y, Vec3::Y)));
        }
    }
    let p = KnnParams { k: 100, max_d2: f32::INFINITY, filter: Filter::None };
    let beside = |scene: &dyn SurfaceQuery| {
        let mut nodes = pm_kdtree::balance(&ps);
        let stats = precompute(&mut nodes, &p, (1.0, 0.0), Some(scene), &|_| {});
        let open: Vec<f32> = nodes
            .iter()
            .filter(|r| r.position().x > 0.0 && r.position().x < 2e-3 && r.position().z.abs() < 0.02)
            .map(|r| r.irradiance().x)
            .collect();
        (open.iter().sum::<f32>() / open.len() as f32 / 1000.0, stats.covered)
    };
    let (kept_apart, covered) = beside(&HalfCovered(true));
    let (mixed, none) = beside(&HalfCovered(false));
    eprintln!("beside the cover, over the open E: {kept_apart:.3} kept apart, {mixed:.3} mixed");
    assert_eq!((covered, none), (40 * 81, 0));
    assert!((kept_apart - 1.0).abs() < 0.05, "kept apart: {kept_apart} (mixed: {mixed})");
    assert!(mixed > 2.0, "mixed: {mixed}");
}

/// A floor lit four times as brightly on its half x < 0 as on the rest (photons of
/// equal power, four times as dense), a quarter of them given an irradiance: the
/// final gather's lookup reads the nearest one, and the sparse half's larger
/// cells let the bright half's photons serve points on the dark side of the edge.
/// Over a band 3 cm either side of the edge, the lookups' mean against the
/// estimates' own (at every query point) came out +3.2% plain and +0.8% with the
/// photons between disagreeing neighbours (more than 1.5 apart) given their own
/// estimate ([`precompute`]'s `refine`: 23% more estimates, the band being all
/// edge). Asserted: within 1.5% refined, and above 2% plain (the test can tell).
#[test]
fn refining_where_neighbours_disagree_keeps_the_bright_side_of_an_edge_to_itself() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut ps = Vec::new();
    for (lo, hi, n) in [(-0.5f32, 0.0f32, 20_000), (0.0, 0.5, 5_000)] {
        for _ in 0..n {
            let p = Vec3::new(lo + (hi - lo) * next(), 0.0, next() - 0.5);
            ps.push(FullIrrPhoton::encode(&photon(p, 1e-3, Vec3::Y, Vec3::Y)));
        }
    }
    let p = KnnParams { k: 50, max_d2: 0.04, filter: Filter::None };
    let exact_tree_nodes = pm_kdtree::balance(&ps);
    let exact_tree = KdTree::new(&exact_tree_nodes);
    let mut scratch = KnnScratch::default();
    let queries: Vec<Vec3> = (0..100)
        .flat_map(|i| {
            (0..40).map(move |j| Vec3::new(-0.03 + 0.06 * (i as f32 + 0.5) / 100.0, 0.0, -0.2 + 0.01 * j as f32))
        })
        .collect();
    let exact: f64 = queries.iter().map(|&x| irradiance(&exact_tree, x, Vec3::Y, &p, &mut scratch).e.x as f64).sum();
    let lookups = |refine: f32| {
        let mut nodes = pm_kdtree::balance(&ps);
        let stats = precompute(&mut nodes, &p, (0.25, refine), None, &|_| {});
        let tree = KdTree::new(&nodes);
        let mut rejected = Vec::new();
        let sum: f64 = queries
            .iter()
            .map(|&x| {
                precomputed_irradiance(&tree, x, Vec3::Y, p.max_d2, &mut rejected).map_or(0.0, |(e, _)| e.x as f64)
            })
            .sum();
        (sum / exact - 1.0, stats.computed)
    };
    let ((plain, n0), (refined, n1)) = (lookups(0.0), lookups(1.5));
    eprintln!(
        "lookups over exact: plain {:+.2}% ({n0} estimates), refined {:+.2}% ({n1})",
        100.0 * plain,
        100.0 * refined
    );
    assert!(plain > 0.02, "plain: {plain}");
    assert!(refined.abs() < 0.015, "refined: {refined} (plain {plain})");
}
