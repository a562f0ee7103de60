//! The final gather's lookup alone (issue 40, goal 5): at the hit points of real
//! gather rays on cornell_spheres, the precomputed irradiance of the nearest similar
//! photon (Christensen 1999 section 2.2) against the exact k-nearest estimate it
//! replaces (Jensen 1996 eq. 6, k = 50), both through the renderer's own lookup
//! ([`PhotonMapping::gather_lookup`]) on maps built as photon-render builds them
//! (400k global photons, irradiance at a quarter of them in a tree of their own;
//! the exact estimate through leaf buckets). Christensen's 5.8x is measured on the
//! whole final gather; what precomputation makes cheaper is this lookup, seen here
//! without the gather rays' own cost.
//!
//! Run: `cargo bench -p pm-render --bench lookup` (one thread: a per-lookup cost).

use glam::Vec3;
use pm_estimate::{Filter, KnnParams, precompute};
use pm_format::{CompactIrrPhoton, PhotonRecord};
use pm_kdtree::{Buckets, KdTree};
use pm_render::{Lookup, Maps, PhotonMapping, RenderParams, Scratch};
use pm_sampling::Sampler;
use std::hint::black_box;
use std::time::Instant;

/// Eye rays (a grid over the image) and gather rays from each eye ray's hit.
const GRID: u32 = 64;
const RAYS_PER_HIT: u32 = 64;

fn main() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell_spheres.gltf");
    let scene = pm_scene::load(&path).unwrap();
    let photons = pm_photon::trace_global(&scene, 400_000, 1).unwrap();
    let recs: Vec<CompactIrrPhoton> = photons.iter().map(CompactIrrPhoton::encode).collect();
    let mut nodes = pm_kdtree::balance(&recs);
    let params = RenderParams::default();
    let max_r = params.max_radius_rel_diag * scene.bounds.diagonal();
    let knn = KnnParams { k: params.k, max_d2: max_r * max_r, filter: Filter::None };
    let surfaces = pm_render::SceneSurfaces { scene: &scene, reach: max_r };
    precompute(&mut nodes, &knn, (0.25, 0.0), Some(&surfaces), &|_| {});
    let irr = pm_render::irradiance_subset(&nodes);
    let buckets = Buckets::new(&nodes);
    let integrator = |lookup: Lookup| {
        let maps = Maps {
            global: Some(KdTree::with_buckets(&nodes, &buckets)),
            irradiance: Some(KdTree::new(&irr)),
            caustic: None,
            volume: None,
        };
        let p = RenderParams { gather_lookup: lookup, ..params.clone() };
        PhotonMapping::new(&scene, maps, &p, true).unwrap()
    };

    // Gather-ray hits: eye rays through a grid of pixels, cosine-distributed rays
    // from the surfaces they hit, each hit's normal turned towards its ray. Only
    // hits on non-specular surfaces look anything up (the renderer follows mirrors
    // and glass first; rays that meet them are left out here, since the global map
    // holds no photons on them and a lookup there would search its whole radius).
    let cam = scene.camera.as_ref().expect("cornell_spheres has a camera");
    let rays = cam.rays(1.0);
    let mut queries: Vec<(Vec3, Vec3)> = Vec::new();
    for j in 0..GRID {
        for i in 0..GRID {
            let d = rays.direction((i as f32 + 0.5) / GRID as f32, (j as f32 + 0.5) / GRID as f32);
            let Some(h) = scene.intersect(cam.position, d, f32::INFINITY) else { continue };
            let n = pm_scene::facing(h.ns, -d);
            let o = h.p + n * 1e-4 * scene.bounds.diagonal();
            let mut s = Sampler::new(7, (j * GRID + i) as u64);
            for _ in 0..RAYS_PER_HIT {
                let w = pm_sampling::to_world(pm_sampling::cosine_hemisphere(s.next_2d()), n);
                if let Some(g) = scene.intersect(o, w, f32::INFINITY) {
                    let b = scene.bsdf(&g);
                    if !b.is_specular() {
                        queries.push((g.p, pm_scene::facing(g.ng, -w)));
                    }
                }
            }
        }
    }
    println!(
        "{} lookups at gather-ray hits, {} photons ({} with irradiance), one thread, best of 3",
        queries.len(),
        nodes.len(),
        irr.len()
    );
    println!("| lookup | time [s] | per lookup [us] | exact / this |");
    println!("|---|---:|---:|---:|");
    let time = |lookup: &mut dyn FnMut(Vec3, Vec3) -> f32| {
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t = Instant::now();
            let mut acc = 0.0;
            for &(x, n) in &queries {
                acc += lookup(x, n);
            }
            black_box(acc);
            best = best.min(t.elapsed().as_secs_f64());
        }
        best
    };
    let mut scratch = Scratch::default();
    let (exact, pre) = (integrator(Lookup::Exact), integrator(Lookup::Precomputed));
    let exact = time(&mut |x, n| exact.gather_lookup(x, n, &mut scratch).x);
    let pre = time(&mut |x, n| pre.gather_lookup(x, n, &mut scratch).x);
    // The lookup's search alone, without the visibility ray the renderer asks of
    // the photon it finds.
    let (tree, mut rejected) = (KdTree::new(&irr), Vec::new());
    let search = time(&mut |x, n| {
        pm_estimate::precomputed_irradiance(&tree, x, n, knn.max_d2, &mut rejected).map_or(0.0, |(e, _)| e.x)
    });
    let per = |t: f64| 1e6 * t / queries.len() as f64;
    for (name, t) in [
        ("exact k-nearest estimate (k = 50)", exact),
        ("precomputed (nearest similar visible photon)", pre),
        ("precomputed, the search alone (no visibility ray)", search),
    ] {
        println!("| {name} | {t:.3} | {:.3} | {:.1}x |", per(t), exact / t);
    }
}
