use super::*;
use pm_format::{CompactPhoton, FullPhoton, Photon};
use proptest::prelude::*;

fn photon(p: Vec3, f: u8) -> Photon {
    Photon {
        position: p,
        power: Vec3::ONE,
        wi: Vec3::Y,
        flags: f | flags::AXIS_LEAF,
        normal: Vec3::Y,
        irradiance: Vec3::ZERO,
    }
}

fn records<R: PhotonRecord>(pts: &[Vec3]) -> Vec<R> {
    pts.iter().enumerate().map(|(i, &p)| R::encode(&photon(p, if i % 7 == 3 { flags::DIRECT } else { 0 }))).collect()
}

/// Sorted squared distances of the k nearest by brute force.
fn brute_knn<R: PhotonRecord>(nodes: &[R], x: Vec3, k: usize, max_d2: f32, filter: impl Fn(&R) -> bool) -> Vec<f32> {
    let mut d: Vec<f32> = nodes
        .iter()
        .filter(|r| r.flags() & flags::UNUSED == 0 && filter(r))
        .map(|r| (r.position() - x).length_squared())
        .filter(|&d2| d2 <= max_d2)
        .collect();
    d.sort_by(f32::total_cmp);
    d.truncate(k);
    d
}

fn check_all_queries<R: PhotonRecord>(
    pts: &[Vec3],
    queries: &[Vec3],
    ks: &[usize],
    radii2: &[f32],
) -> Result<(), TestCaseError> {
    let nodes = balance(&records::<R>(pts));
    let buckets = Buckets::new(&nodes);
    prop_assert!(KdTree::new(&nodes).verify().is_ok(), "{:?}", KdTree::new(&nodes).verify());
    prop_assert_eq!(nodes.len(), pts.len());
    let mut scratch = KnnScratch::default();
    let mut rejected = Vec::new();
    let direct = |r: &R| r.flags() & flags::DIRECT != 0;
    // Every query searched through the leaf buckets and without them.
    for (tree, &x) in [KdTree::new(&nodes), KdTree::with_buckets(&nodes, &buckets)]
        .into_iter()
        .flat_map(|t| queries.iter().map(move |x| (t, x)))
    {
        for &k in ks {
            for &r2 in radii2 {
                for use_filter in [false, true] {
                    let f = |r: &R| !use_filter || direct(r);
                    let res = tree.knn(x, k, r2, |_, r| f(r), &mut scratch);
                    let mut got: Vec<f32> = tree.found(&scratch).map(|(_, d)| d).collect();
                    got.sort_by(f32::total_cmp);
                    let want = brute_knn(&nodes, x, k, r2, f);
                    prop_assert_eq!(&got, &want, "knn k={} r2={} filter={} at {}", k, r2, use_filter, x);
                    prop_assert_eq!(res.count, want.len());
                    prop_assert_eq!(res.max_dist2, want.last().copied().unwrap_or(0.0));
                    // Indices found really are at those distances.
                    for (i, d) in tree.found(&scratch) {
                        prop_assert_eq!((nodes[i as usize].position() - x).length_squared(), d);
                    }
                }
                // All within the radius.
                let mut within = Vec::new();
                tree.for_each_within(x, r2, |_, _, d| within.push(d));
                within.sort_by(f32::total_cmp);
                prop_assert_eq!(within, brute_knn(&nodes, x, usize::MAX, r2, |_| true));
                // Nearest satisfying a predicate.
                let near = tree.nearest(x, r2, direct, &mut rejected);
                let want = brute_knn(&nodes, x, 1, r2, direct);
                prop_assert_eq!(near.map(|n| n.dist2), want.first().copied());
                if let Some(n) = near {
                    prop_assert!(direct(&nodes[n.index as usize]));
                    let closer_rejected = nodes
                        .iter()
                        .filter(|r| {
                            !direct(r)
                                && r.flags() & flags::UNUSED == 0
                                && (r.position() - x).length_squared() < n.dist2
                        })
                        .count();
                    prop_assert_eq!(n.rank as usize, 1 + closer_rejected);
                }
                // Nearest satisfying a cheap and a costly predicate: the costly one is
                // asked of the cheap-passing photons in order of distance only.
                let costly = |r: &R| (r.position().x * 7.0).fract().abs() > 0.3;
                let both = |r: &R| direct(r) && costly(r);
                let calls = std::cell::Cell::new(0usize);
                let near = tree.nearest_where(
                    x,
                    r2,
                    direct,
                    |r| {
                        calls.set(calls.get() + 1);
                        costly(r)
                    },
                    u32::MAX,
                    &mut rejected,
                );
                let want = brute_knn(&nodes, x, 1, r2, both);
                prop_assert_eq!(near.map(|n| n.dist2), want.first().copied());
                let used = |r: &&R| r.flags() & flags::UNUSED == 0;
                let d2 = |r: &R| (r.position() - x).length_squared();
                if let Some(n) = near {
                    prop_assert!(both(&nodes[n.index as usize]));
                    let closer = |r: &&R| d2(r) < n.dist2;
                    let closer_rejected = nodes.iter().filter(used).filter(closer).filter(|r| !both(r)).count();
                    prop_assert_eq!(n.rank as usize, 1 + closer_rejected);
                    let asked = nodes.iter().filter(used).filter(closer).filter(|r| direct(r)).count();
                    prop_assert_eq!(calls.get(), 1 + asked);
                } else {
                    let within = |r: &&R| d2(r) <= r2;
                    prop_assert_eq!(
                        calls.get(),
                        nodes.iter().filter(used).filter(within).filter(|r| direct(r)).count()
                    );
                }
                // At most `max_refusals` refusals, then no result.
                calls.set(0);
                let none = tree.nearest_where(
                    x,
                    r2,
                    |_| true,
                    |_| {
                        calls.set(calls.get() + 1);
                        false
                    },
                    3,
                    &mut rejected,
                );
                prop_assert!(none.is_none());
                prop_assert!(calls.get() <= 4);
            }
        }
    }
    Ok(())
}

#[test]
fn left_size_matches_a_left_balanced_complete_tree() {
    // Count the left subtree of the root of a complete tree filled level by level.
    for n in 1..2000usize {
        let mut count = 0;
        let mut stack = vec![1usize];
        while let Some(i) = stack.pop() {
            if i < n {
                count += 1;
                stack.push(2 * i + 1);
                stack.push(2 * i + 2);
            }
        }
        assert_eq!(left_size(n), count, "n = {n}");
    }
}

#[test]
fn hard_cases_match_brute_force() {
    let q = [Vec3::ZERO, Vec3::new(0.5, 0.5, 0.5), Vec3::new(10.0, -3.0, 2.0)];
    let ks = [1, 3, 50, 1000];
    let r2 = [0.0, 0.01, 1.0, f32::INFINITY];
    let run = |pts: &[Vec3]| {
        check_all_queries::<FullPhoton>(pts, &q, &ks, &r2).unwrap();
        check_all_queries::<CompactPhoton>(pts, &q, &ks, &r2).unwrap();
    };
    run(&[]); // zero photons
    run(&[Vec3::new(0.5, 0.5, 0.5)]); // one photon (also: a radius of 0 finds it only at distance 0)
    run(&vec![Vec3::new(0.5, 0.5, 0.5); 300]); // all at the same position
    let grid: Vec<Vec3> = (0..400).map(|i| Vec3::new((i % 20) as f32 * 0.05, 0.25, (i / 20) as f32 * 0.05)).collect();
    run(&grid); // all on one plane
    let line: Vec<Vec3> = (0..300).map(|i| Vec3::new(i as f32 * 0.003, i as f32 * 0.003, 0.5)).collect();
    run(&line); // all on one line
    let huge: Vec<Vec3> = (0..200).map(|i| Vec3::new(1e15 + i as f32 * 1e12, -1e15, i as f32 * 3e12)).collect();
    check_all_queries::<FullPhoton>(&huge, &[Vec3::new(1e15, -1e15, 0.0)], &ks, &[0.0, 1e26, f32::INFINITY]).unwrap();
    let tiny: Vec<Vec3> = (0..200).map(|i| Vec3::new(i as f32 * 1e-12, (i % 5) as f32 * 1e-12, 0.0)).collect();
    check_all_queries::<FullPhoton>(&tiny, &[Vec3::new(5e-11, 1e-12, 0.0)], &ks, &[0.0, 1e-22, f32::INFINITY]).unwrap();
}

#[test]
fn unused_photons_are_skipped() {
    let pts: Vec<Vec3> = (0..100).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
    let mut nodes = balance(&records::<FullPhoton>(&pts));
    for r in nodes.iter_mut() {
        if (r.position().x as u32).is_multiple_of(2) {
            r.set_flags(r.flags() | flags::UNUSED);
        }
    }
    let buckets = Buckets::new(&nodes);
    for tree in [KdTree::new(&nodes), KdTree::with_buckets(&nodes, &buckets)] {
        let mut s = KnnScratch::default();
        tree.knn(Vec3::new(10.2, 0.0, 0.0), 3, f32::INFINITY, |_, _| true, &mut s);
        let mut xs: Vec<f32> = tree.found(&s).map(|(i, _)| nodes[i as usize].position().x).collect();
        xs.sort_by(f32::total_cmp);
        assert_eq!(xs, vec![9.0, 11.0, 13.0]);
        let mut within = Vec::new();
        tree.for_each_within(Vec3::new(10.2, 0.0, 0.0), 9.0, |_, r, _| within.push(r.position().x));
        within.sort_by(f32::total_cmp);
        assert_eq!(within, vec![9.0, 11.0, 13.0]);
    }
}

#[test]
fn balancing_is_deterministic_across_thread_counts() {
    let pts: Vec<Vec3> = (0..100_000u32)
        .map(|i| {
            let h = |s: u32| ((i.wrapping_mul(2_654_435_761).wrapping_add(s)) % 10_007) as f32 / 10_007.0;
            Vec3::new(h(1), h(7) * h(3), (h(5) * 4.0).floor()) // clustered in z
        })
        .collect();
    let recs = records::<CompactPhoton>(&pts);
    let run = |t| rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap().install(|| balance(&recs));
    let (a, b) = (run(1), run(2));
    assert_eq!(bytemuck_bytes(&a), bytemuck_bytes(&b));
    assert!(KdTree::new(&a).verify().is_ok());
    assert_eq!(KdTree::new(&a).depth(), 17);
}

fn bytemuck_bytes<R: PhotonRecord>(r: &[R]) -> Vec<u8> {
    r.iter().flat_map(|x| pm_format_bytes(x)).collect()
}

fn pm_format_bytes<R: PhotonRecord>(r: &R) -> Vec<u8> {
    let d = r.decode();
    [d.position.to_array(), d.power.to_array(), d.wi.to_array()]
        .concat()
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .chain([d.flags])
        .collect()
}

#[test]
fn sort_keys_order_as_total_cmp_and_invert() {
    let v = [
        f32::NEG_INFINITY,
        -f32::MAX,
        -1.5,
        -f32::MIN_POSITIVE,
        -1e-45,
        -0.0,
        0.0,
        1e-45,
        f32::MIN_POSITIVE,
        0.75,
        f32::MAX,
        f32::INFINITY,
    ];
    for a in v {
        assert_eq!(from_sort_key(sort_key(a)).to_bits(), a.to_bits());
        for b in v {
            assert_eq!(sort_key(a).cmp(&sort_key(b)), a.total_cmp(&b), "{a} {b}");
        }
    }
}

#[test]
fn verify_catches_a_broken_tree() {
    let pts: Vec<Vec3> = (0..50).map(|i| Vec3::new((i * 37 % 50) as f32, 0.0, 0.0)).collect();
    let mut nodes = balance(&records::<FullPhoton>(&pts));
    nodes.swap(1, 2);
    assert!(KdTree::new(&nodes).verify().is_err());
}

fn arb_points() -> impl Strategy<Value = Vec<Vec3>> {
    let uniform = proptest::collection::vec(
        (-1f32..1.0, -1f32..1.0, -1f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z)),
        0..400,
    );
    // Adversarial: few distinct values per axis (many ties), clusters of duplicates.
    let lattice = proptest::collection::vec(
        (0u8..3, 0u8..3, 0u8..2).prop_map(|(x, y, z)| Vec3::new(x as f32, y as f32 * 0.5, z as f32)),
        0..400,
    );
    let clustered = proptest::collection::vec(
        (0u8..4, -1e-3f32..1e-3, -1e-3f32..1e-3).prop_map(|(c, dx, dz)| Vec3::new(c as f32 + dx, 0.0, dz)),
        0..400,
    );
    prop_oneof![uniform, lattice, clustered]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    #[test]
    fn queries_match_brute_force(pts in arb_points(), qs in proptest::collection::vec((-1.5f32..3.5, -1f32..1.5, -1f32..2.0), 1..4), k in 1usize..60, r in 0f32..2.0) {
        let queries: Vec<Vec3> = qs.into_iter().map(|(x, y, z)| Vec3::new(x, y, z)).collect();
        check_all_queries::<FullPhoton>(&pts, &queries, &[k], &[r * r, f32::INFINITY])?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    /// The grid's nearest-first, pruned search finds what brute force finds, after
    /// photons were set, replaced and removed, for radii below, at and beyond the
    /// radius it was built for.
    #[test]
    fn grid_queries_match_brute_force(
        pts in arb_points(),
        qs in proptest::collection::vec((-1.5f32..3.5, -1f32..1.5, -1f32..2.0), 1..4),
        k in 1usize..60,
        cell_radius in 0.05f32..1.0,
        r in 0f32..2.0,
    ) {
        let recs = records::<FullPhoton>(&pts);
        let mut grid = PhotonGrid::new(cell_radius, recs.len() + 1);
        // Set everything, then move every third photon away and remove every fifth.
        for (i, r) in recs.iter().enumerate() {
            grid.set(i as u32, Some(*r));
        }
        let mut live: Vec<Option<FullPhoton>> = recs.iter().copied().map(Some).collect();
        for i in (0..recs.len()).step_by(3) {
            let moved = FullPhoton::encode(&photon(recs[i].position() * 0.5 + Vec3::splat(0.25), 0));
            grid.set(i as u32, Some(moved));
            live[i] = Some(moved);
        }
        for i in (0..recs.len()).step_by(5) {
            grid.set(i as u32, None);
            live[i] = None;
        }
        let held: Vec<FullPhoton> = live.iter().flatten().copied().collect();
        prop_assert_eq!(grid.len(), held.len());
        let direct = |r: &FullPhoton| r.flags() & flags::DIRECT != 0;
        let mut scratch = KnnScratch::default();
        for (x, y, z) in qs {
            let x = Vec3::new(x, y, z);
            for r2 in [r * r, cell_radius * cell_radius, f32::INFINITY] {
                for use_filter in [false, true] {
                    let f = |r: &FullPhoton| !use_filter || direct(r);
                    let res = grid.knn(x, k, r2, |_, r| f(r), &mut scratch);
                    let mut got: Vec<f32> = grid.found(&scratch).map(|(_, d)| d).collect();
                    got.sort_by(f32::total_cmp);
                    let want = brute_knn(&held, x, k, r2, f);
                    prop_assert_eq!(&got, &want, "k={} r2={} filter={} at {}", k, r2, use_filter, x);
                    prop_assert_eq!(res.max_dist2, want.last().copied().unwrap_or(0.0));
                    for (i, d) in grid.found(&scratch) {
                        prop_assert_eq!((grid.record(i).position() - x).length_squared(), d);
                    }
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    /// The static radius grid finds exactly the points brute force finds within the
    /// radius, for radii up to the built one, including points outside any cell
    /// (NaN) and all points in one spot.
    #[test]
    fn radius_grid_matches_brute_force(
        pts in arb_points(),
        qs in proptest::collection::vec((-1.5f32..3.5, -1f32..1.5, -1f32..2.0), 1..4),
        radius in 0.01f32..2.0,
        frac in 0f32..1.0,
    ) {
        let mut pts = pts;
        pts.push(Vec3::NAN);
        let grid = RadiusGrid::new(&pts, radius);
        for (x, y, z) in qs {
            let x = Vec3::new(x, y, z);
            let r2 = (radius * frac) * (radius * frac);
            let mut got: Vec<(u32, f32)> = Vec::new();
            grid.for_each_within(x, r2, |i, d| got.push((i, d)));
            got.sort_by_key(|g| g.0);
            let want: Vec<(u32, f32)> = pts
                .iter()
                .enumerate()
                .filter(|(_, p)| p.is_finite() && p.distance_squared(x) <= r2)
                .map(|(i, p)| (i as u32, p.distance_squared(x)))
                .collect();
            prop_assert_eq!(got, want);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    /// The kd-tree and the grid keep photons by one rule (nearer first, then the
    /// lower id), so over the same photons under the same ids they find the same
    /// photons, ties included, though they meet them in different orders. The
    /// lattice of points has many photons at equal distances; a search that kept
    /// whichever tied photon it met first fails it.
    #[test]
    fn kd_tree_and_grid_find_the_same_photons(
        pts in arb_points(),
        qs in proptest::collection::vec((-1.5f32..3.5, -1f32..1.5, -1f32..2.0), 1..4),
        k in 1usize..60,
        r in 0f32..2.0,
    ) {
        let nodes = balance(&records::<FullPhoton>(&pts));
        let tree = KdTree::new(&nodes);
        let mut grid = PhotonGrid::new(0.3, nodes.len() + 1);
        for (i, n) in nodes.iter().enumerate() {
            grid.set(i as u32, Some(*n));
        }
        let (mut a, mut b) = (KnnScratch::default(), KnnScratch::default());
        for (x, y, z) in qs {
            let x = Vec3::new(x, y, z);
            for r2 in [r * r, f32::INFINITY] {
                tree.knn(x, k, r2, |_, _| true, &mut a);
                grid.knn(x, k, r2, |_, _| true, &mut b);
                let ids = |found: &mut dyn Iterator<Item = (u32, f32)>| {
                    let mut v: Vec<u32> = found.map(|(i, _)| i).collect();
                    v.sort_unstable();
                    v
                };
                prop_assert_eq!(ids(&mut tree.found(&a)), ids(&mut grid.found(&b)), "k={} r2={} at {}", k, r2, x);
            }
        }
    }
}
