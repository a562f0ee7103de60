//! Physics and determinism of photon tracing, against analytic answers and an
//! independent estimator.

use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_format::{Photon, flags};
use pm_photon::{Budget, LightSelector, MapPass, Slice, TraceConfig, TraceError, merge_slices, trace, trace_slice};
use pm_scene::{Material, Scene, Triangle};
use std::path::PathBuf;

fn scene_file(name: &str) -> Scene {
    pm_scene::load(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name)).unwrap()
}

fn cfg(scene: &Scene, pass: MapPass, budget: Budget) -> TraceConfig {
    TraceConfig { pass, budget, seed: 5, selector: LightSelector::new(scene, &[]).unwrap() }
}

fn sum_power(ps: impl Iterator<Item = Photon>) -> Vec3 {
    ps.map(|p| p.power.as_dvec3()).sum::<glam::DVec3>().as_vec3()
}

fn material(name: &str, bsdf: Bsdf, emission: Rgb) -> Material {
    Material::new(name, bsdf, emission)
}

/// Quad a, b, c, d (counter-clockwise seen from the side it faces) as two triangles.
fn quad(out: &mut Vec<Triangle>, q: [Vec3; 4], m: u32) {
    out.push(Triangle::new([q[0], q[1], q[2]], m).unwrap());
    out.push(Triangle::new([q[0], q[2], q[3]], m).unwrap());
}

/// Closed unit box, faces pointing inward, with two ceiling lights of radiance 1 and
/// 4 (0.2 m squares at x = 0.3 and x = 0.7).
fn closed_box_two_lights() -> Scene {
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let mut t = Vec::new();
    // Inward-facing walls.
    quad(&mut t, [v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)], 0); // floor (+y)
    quad(&mut t, [v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)], 0); // ceiling (-y)
    quad(&mut t, [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)], 0); // z = 0 (+z)
    quad(&mut t, [v(0., 0., 1.), v(0., 1., 1.), v(1., 1., 1.), v(1., 0., 1.)], 0); // z = 1 (-z)
    quad(&mut t, [v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)], 0); // x = 0 (+x)
    quad(&mut t, [v(1., 0., 0.), v(1., 0., 1.), v(1., 1., 1.), v(1., 1., 0.)], 0); // x = 1 (-x)
    let y = 0.999;
    for (x, m) in [(0.3, 1u32), (0.7, 2u32)] {
        quad(&mut t, [v(x - 0.1, y, 0.4), v(x + 0.1, y, 0.4), v(x + 0.1, y, 0.6), v(x - 0.1, y, 0.6)], m);
    }
    let mats = vec![
        material("wall", Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::ZERO),
        material("dim", Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::splat(1.0)),
        material("bright", Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::splat(4.0)),
    ];
    Scene::from_parts(t, mats, Vec::new(), None)
}

#[test]
fn direct_photons_carry_the_lights_power_for_any_light_shares() {
    let scene = closed_box_two_lights();
    let phi = scene.total_power();
    // Phi = pi L A: (1 + 4) * pi * 0.04.
    assert!((phi.x - 5.0 * std::f32::consts::PI * 0.04).abs() < 1e-4);
    for shares in [vec![], vec![("object #1 (dim)".to_string(), 0.5)], vec![("object #2 (bright)".to_string(), 0.9)]] {
        let mut c = cfg(&scene, MapPass::Global, Budget::Emitted(100_000));
        c.selector = LightSelector::new(&scene, &shares).unwrap();
        let m = trace(&scene, &c, &|_| {}).unwrap();
        let direct = sum_power(m.photons.iter().copied().filter(|p| p.flags & flags::DIRECT != 0));
        let rel = ((direct - phi) / phi).abs().max_element();
        // Binomial light-choice noise: < 0.5% at 1e5 photons for these shares.
        eprintln!("shares {shares:?}: direct {direct} vs {phi}: {rel}");
        assert!(rel < 0.015, "shares {shares:?}: direct power {direct} vs {phi} ({rel})");
        // Every emitted photon hits the closed box: one direct photon each.
        assert_eq!(m.photons.iter().filter(|p| p.flags & flags::DIRECT != 0).count() as u64, m.stats.emitted);
    }
}

/// Russian roulette by a bounce's largest albedo channel (`pm_photon::Roulette`):
/// in a closed box whose every surface (lights included) is a saturated green
/// of albedo (0.1, 0.8, 0.1), no stored photon carries more of any channel than
/// a photon leaves the light with, and each channel's stored power is the
/// geometric series Phi / (1 - rho) of its own albedo (5 Phi green, 1.11 Phi red
/// and blue). By the channels' mean, as McGuire and Luebke's appendix A has it,
/// the series hold too but a green photon's green power grew 2.4 times a
/// bounce: the largest stored was 6,340 times the emitted (issue 53).
#[test]
fn russian_roulette_in_a_saturated_room_never_raises_a_photons_power() {
    let mut scene = closed_box_two_lights();
    let rho = Rgb::new(0.1, 0.8, 0.1);
    for m in &mut scene.materials {
        *m = material(&m.name.clone(), Bsdf::Lambert { rho }, m.emission);
    }
    let scene = Scene::from_parts(scene.triangles.clone(), scene.materials.clone(), Vec::new(), None);
    let phi = scene.total_power();
    let m = trace(&scene, &cfg(&scene, MapPass::Global, Budget::Emitted(40_000)), &|_| {}).unwrap();
    let emitted = phi / m.stats.emitted as f32;
    let largest = m.photons.iter().fold(Vec3::ZERO, |a, p| a.max(p.power));
    eprintln!("largest stored {largest} vs emitted {emitted}: {}", largest / emitted);
    assert!((largest / emitted).max_element() <= 1.0 + 1e-4, "largest stored {largest} vs emitted {emitted}");
    let total = sum_power(m.photons.iter().copied());
    let expected = phi / (Vec3::ONE - rho);
    let rel = (total / expected - Vec3::ONE).abs().max_element();
    eprintln!("stored {total} vs {expected}: {rel}");
    assert!(rel < 0.03, "stored {total} vs Phi / (1 - rho) = {expected}");
    assert_eq!(m.stats.truncated_paths, 0);
}

#[test]
fn furnace_stored_power_is_the_geometric_series() {
    // Closed sphere, albedo 0.8: bounce k stores Phi 0.8^k in expectation, in total
    // Phi / (1 - 0.8) = 5 Phi. Each photon carries Phi/N exactly (grey albedo, so
    // Russian roulette never rescales); the number stored per path is geometric with
    // mean 5 and standard deviation 4.5, so at 40k paths the total is within 0.5% (1 sigma).
    let scene = scene_file("furnace.gltf");
    let phi = scene.total_power();
    let m = trace(&scene, &cfg(&scene, MapPass::Global, Budget::Stored { target: 200_000, cap: 10_000_000 }), &|_| {})
        .unwrap();
    let total = sum_power(m.photons.iter().copied());
    let rel = ((total - 5.0 * phi) / (5.0 * phi)).abs().max_element();
    eprintln!("furnace stored {total} vs 5 Phi = {}: {rel}", 5.0 * phi);
    assert!(rel < 0.02, "stored {total} vs 5 Phi = {}", 5.0 * phi);
    let per_bounce = &m.stats.stored_per_bounce;
    for k in 1..6 {
        let ratio = per_bounce[k] as f64 / per_bounce[k - 1] as f64;
        assert!((ratio - 0.8).abs() < 0.02, "bounce {k}: ratio {ratio}");
    }
    assert_eq!(m.stats.truncated_paths, 0);
}

#[test]
fn aimed_caustic_map_agrees_with_unaimed_global_caustic_photons() {
    // Two independent estimators of the light-specular+-diffuse flux: the caustic pass
    // (emission aimed at the spheres' bounding spheres, weighted by the mixture pdf)
    // and the CAUSTIC-flagged photons of the global pass (plain emission).
    let scene = scene_file("cornell_spheres.gltf");
    let caustic = trace(&scene, &cfg(&scene, MapPass::Caustic, Budget::Emitted(200_000)), &|_| {}).unwrap();
    let global = trace(&scene, &cfg(&scene, MapPass::Global, Budget::Emitted(2_000_000)), &|_| {}).unwrap();
    let a = sum_power(caustic.photons.iter().copied());
    let flagged: Vec<Photon> = global.photons.iter().copied().filter(|p| p.flags & flags::CAUSTIC != 0).collect();
    let b = sum_power(flagged.iter().copied());
    assert!(flagged.len() > 5000, "{} caustic photons in the global map", flagged.len());
    let rel = ((a - b) / b).abs().max_element();
    eprintln!("aimed {a} vs unaimed {b}: relative difference {rel}");
    assert!(rel < 0.04, "aimed {a} vs unaimed {b}: {rel}");
    assert!(caustic.photons.iter().all(|p| p.flags & flags::CAUSTIC != 0 && p.flags & flags::DIRECT == 0));
    // Aiming is what makes the caustic map cheap: far more caustic photons per emitted.
    let aimed_yield = caustic.stats.stored as f64 / caustic.stats.emitted as f64;
    let plain_yield = flagged.len() as f64 / global.stats.emitted as f64;
    assert!(aimed_yield > 5.0 * plain_yield, "aimed {aimed_yield} vs plain {plain_yield}");
}

#[test]
fn glass_sphere_focuses_a_caustic_on_the_floor_below_it() {
    // Glass sphere: centre (0.45, 0.35, 0.3), r = 0.35, n = 1.5; its focal length
    // n R / (2 (n - 1)) = 0.525 m puts a concentrated spot on the floor below it.
    let scene = scene_file("cornell_spheres.gltf");
    let m = trace(&scene, &cfg(&scene, MapPass::Caustic, Budget::Stored { target: 50_000, cap: 5_000_000 }), &|_| {})
        .unwrap();
    let floor: Vec<&Photon> = m.photons.iter().filter(|p| p.position.y.abs() < 1e-4).collect();
    let below = Vec3::new(0.45, 0.0, 0.3);
    let r = 0.1f32;
    let spot: f32 = floor.iter().filter(|p| p.position.distance(below) < r).map(|p| p.power.x).sum();
    let all: f32 = floor.iter().map(|p| p.power.x).sum();
    let spot_density = spot / (std::f32::consts::PI * r * r);
    let floor_density = all / 4.0; // floor is 2 m x 2 m
    eprintln!("caustic spot {spot_density} W/m2, floor mean {floor_density} W/m2");
    assert!(spot_density > 8.0 * floor_density, "spot {spot_density} W/m2 vs floor mean {floor_density} W/m2");
}

#[test]
fn diffuse_scene_has_no_caustic_photons() {
    let scene = scene_file("cornell_boxes.gltf");
    assert!(pm_photon::specular_targets(&scene).is_empty());
    let c = trace(&scene, &cfg(&scene, MapPass::Caustic, Budget::Emitted(10_000)), &|_| {}).unwrap();
    assert!(c.photons.is_empty());
    let g = trace(&scene, &cfg(&scene, MapPass::Global, Budget::Emitted(10_000)), &|_| {}).unwrap();
    assert!(g.photons.iter().all(|p| p.flags & flags::CAUSTIC == 0));
    assert!(!g.photons.is_empty());
}

/// Photon classification with glossy lobes (module doc): the cornell_spheres
/// spheres turned into clear-coated red dielectrics (a sharp GGX coat over a
/// diffuse base, one material with both kinds of lobe) are no caustic targets,
/// the caustic pass stores nothing, every photon of the global pass is stored
/// unflagged, and the spheres themselves store photons (their base), the coat's
/// reflections among the walls' photons. With the spheres as they are (chrome
/// and glass) the global pass flags caustic photons: the test can tell them apart.
#[test]
fn a_coated_surface_stores_photons_and_its_coat_makes_no_caustic_photons() {
    let mut scene = scene_file("cornell_spheres.gltf");
    let plain = trace(&scene, &cfg(&scene, MapPass::Global, Budget::Emitted(20_000)), &|_| {}).unwrap();
    assert!(plain.photons.iter().any(|p| p.flags & flags::CAUSTIC != 0));
    let coated = Bsdf::from_pbr(&pm_bsdf::Pbr {
        coat: 1.0,
        coat_roughness: 0.05,
        ..pm_bsdf::Pbr::dielectric(Rgb::new(0.7, 0.05, 0.04))
    });
    assert!(matches!(coated, Bsdf::Layered(_)) && !coated.is_specular());
    for m in scene.materials.iter_mut().filter(|m| m.bsdf.is_specular()) {
        *m = material(&m.name.clone(), coated, Rgb::ZERO);
    }
    assert!(pm_photon::specular_targets(&scene).is_empty());
    let c = trace(&scene, &cfg(&scene, MapPass::Caustic, Budget::Emitted(10_000)), &|_| {}).unwrap();
    assert!(c.photons.is_empty());
    let g = trace(&scene, &cfg(&scene, MapPass::Global, Budget::Emitted(20_000)), &|_| {}).unwrap();
    assert!(g.photons.iter().all(|p| p.flags & flags::CAUSTIC == 0));
    // The glass sphere's surface: centre (0.45, 0.35, 0.3), radius 0.35.
    let on_sphere = g.photons.iter().filter(|p| (p.position.distance(Vec3::new(0.45, 0.35, 0.3)) - 0.35).abs() < 1e-3);
    assert!(on_sphere.count() > 100);
}

fn bits(ps: &[Photon]) -> Vec<[u32; 16]> {
    ps.iter()
        .map(|p| {
            let mut a = [0u32; 16];
            for (i, v) in p
                .position
                .to_array()
                .iter()
                .chain(&p.power.to_array())
                .chain(&p.wi.to_array())
                .chain(&p.normal.to_array())
                .enumerate()
            {
                a[i] = v.to_bits();
            }
            a[12] = p.flags as u32;
            a
        })
        .collect()
}

#[test]
fn identical_for_any_thread_count_and_for_slices_of_the_index_space() {
    let scene = scene_file("cornell_spheres.gltf");
    let pool = |threads: usize| rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    for pass in [MapPass::Global, MapPass::Caustic] {
        for budget in [Budget::Stored { target: 40_000, cap: 10_000_000 }, Budget::Emitted(30_001)] {
            let c = cfg(&scene, pass, budget);
            let one = pool(1).install(|| trace(&scene, &c, &|_| {}).unwrap());
            let two = pool(2).install(|| trace(&scene, &c, &|_| {}).unwrap());
            assert_eq!(bits(&one.photons), bits(&two.photons), "{pass:?}");
            if let Budget::Stored { target, .. } = budget {
                assert!(one.stats.stored >= target && one.stats.emitted % pm_photon::CHUNK == 0, "{pass:?}");
            }
            // Three interleaved slices, traced apart and merged in any order, give the
            // same map, the same emitted count and the same statistics.
            let mut slices: Vec<_> = (0..3)
                .map(|index| pool(2).install(|| trace_slice(&scene, &c, Slice { index, count: 3 }, &|_| {}).unwrap()))
                .collect();
            slices.reverse();
            let merged = merge_slices(slices.clone()).unwrap();
            assert_eq!(bits(&merged.photons), bits(&one.photons), "{pass:?} {budget:?} slices");
            assert_eq!(merged.stats.emitted, one.stats.emitted);
            assert_eq!(merged.stats.emitted_per_light, one.stats.emitted_per_light);
            assert_eq!(merged.stats.stored_per_bounce, one.stats.stored_per_bounce);
            assert_eq!(merged.stats.rays, one.stats.rays);
            // A missing slice, a duplicate, or slices of another budget are refused.
            assert!(merge_slices(slices[..2].to_vec()).is_err());
            let mut dup = slices.clone();
            dup[0] = slices[1].clone();
            assert!(merge_slices(dup).is_err());
            let mut other = slices.clone();
            other[0].budget = Budget::Emitted(7);
            assert!(merge_slices(other).is_err());
        }
    }
    // A slice that stopped early leaves a gap the merge names instead of a map
    // short of its target.
    let c = cfg(&scene, MapPass::Global, Budget::Stored { target: 40_000, cap: 10_000_000 });
    let mut slices: Vec<_> =
        (0..2).map(|index| trace_slice(&scene, &c, Slice { index, count: 2 }, &|_| {}).unwrap()).collect();
    slices[1].chunks.truncate(3);
    let e = merge_slices(slices).unwrap_err();
    assert!(matches!(e, pm_photon::MergeError::Gap { chunk: 7, slice: 1, .. }), "{e}");
}

#[test]
fn scenes_that_cannot_be_traced_are_refused() {
    let dark = Scene::from_parts(
        vec![Triangle::new([Vec3::ZERO, Vec3::X, Vec3::Y], 0).unwrap()],
        vec![material("m", Bsdf::Lambert { rho: Rgb::ONE }, Rgb::ZERO)],
        vec![],
        None,
    );
    assert!(matches!(LightSelector::new(&dark, &[]), Err(pm_light::LightSelectError::NoLights)));
    let zero = Scene::from_parts(
        vec![Triangle::new([Vec3::ZERO, Vec3::X, Vec3::Y], 0).unwrap()],
        vec![material("m", Bsdf::Lambert { rho: Rgb::ONE }, Rgb::ZERO)],
        vec![pm_scene::Light {
            name: "off".into(),
            kind: pm_scene::LightKind::Point { position: Vec3::Z, intensity: Rgb::ZERO },
            power: Rgb::ZERO,
        }],
        None,
    );
    assert!(matches!(LightSelector::new(&zero, &[]), Err(pm_light::LightSelectError::NoLights)));
    let empty = Scene::from_parts(
        vec![],
        vec![],
        vec![pm_scene::Light {
            name: "bulb".into(),
            kind: pm_scene::LightKind::Point { position: Vec3::Z, intensity: Rgb::ONE },
            power: Rgb::ZERO,
        }],
        None,
    );
    let sel = LightSelector::new(&empty, &[]).unwrap();
    let c = TraceConfig { pass: MapPass::Global, budget: Budget::Emitted(10), seed: 1, selector: sel };
    assert!(matches!(trace(&empty, &c, &|_| {}), Err(TraceError::NoSurfaces)));
    let box_scene = closed_box_two_lights();
    assert!(matches!(
        LightSelector::new(&box_scene, &[("nope".into(), 0.5)]),
        Err(pm_light::LightSelectError::UnknownLight(..))
    ));
    assert!(matches!(
        LightSelector::new(&box_scene, &[("object #1 (dim)".into(), 1.5)]),
        Err(pm_light::LightSelectError::BadShares(_))
    ));
}

/// Closed unit box (albedo 0.5) with one punctual light at its centre.
fn closed_box_with(light: pm_scene::LightKind) -> Scene {
    let mut scene_tris = Vec::new();
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    quad(&mut scene_tris, [v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)], 0);
    quad(&mut scene_tris, [v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)], 0);
    quad(&mut scene_tris, [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)], 0);
    quad(&mut scene_tris, [v(0., 0., 1.), v(0., 1., 1.), v(1., 1., 1.), v(1., 0., 1.)], 0);
    quad(&mut scene_tris, [v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)], 0);
    quad(&mut scene_tris, [v(1., 0., 0.), v(1., 0., 1.), v(1., 1., 1.), v(1., 1., 0.)], 0);
    let mats = vec![material("wall", Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::ZERO)];
    Scene::from_parts(
        scene_tris,
        mats,
        vec![pm_scene::Light { name: "lamp".into(), kind: light, power: Rgb::ZERO }],
        None,
    )
}

#[test]
fn point_and_spot_lights_emit_their_power_within_their_cone() {
    let centre = Vec3::splat(0.5);
    let point = closed_box_with(pm_scene::LightKind::Point { position: centre, intensity: Rgb::new(2.0, 1.0, 0.5) });
    // Phi = 4 pi I.
    assert!((point.total_power() - Rgb::new(2.0, 1.0, 0.5) * 4.0 * std::f32::consts::PI).abs().max_element() < 1e-4);
    let (ci, co) = (0.3f32.cos(), 0.6f32.cos());
    let spot = closed_box_with(pm_scene::LightKind::Spot {
        position: centre,
        direction: Vec3::NEG_Y,
        intensity: Rgb::splat(3.0),
        cos_inner: ci,
        cos_outer: co,
    });
    let phi_spot = 2.0 * std::f32::consts::PI * 3.0 * ((1.0 - ci) + (ci - co) / 3.0);
    assert!((spot.total_power().x - phi_spot).abs() < 1e-4 * phi_spot);
    for (name, scene) in [("point", &point), ("spot", &spot)] {
        let m = trace(scene, &cfg(scene, MapPass::Global, Budget::Emitted(50_000)), &|_| {}).unwrap();
        let direct: Vec<Photon> = m.photons.iter().copied().filter(|p| p.flags & flags::DIRECT != 0).collect();
        let phi = sum_power(direct.iter().copied());
        let rel = ((phi - scene.total_power()) / scene.total_power()).abs().max_element();
        eprintln!("{name}: direct photon power {phi} vs {}", scene.total_power());
        assert!(rel < 0.01, "{name}: {phi} vs {}", scene.total_power());
        if name == "spot" {
            // Every direct photon lies inside the outer cone.
            assert!(direct.iter().all(|p| (p.position - centre).normalize().dot(Vec3::NEG_Y) >= co - 1e-4));
            // The falloff: per unit solid angle, photons inside the inner cone carry
            // full intensity, so their power / solid angle is I.
            let inner: f32 = direct
                .iter()
                .filter(|p| (p.position - centre).normalize().dot(Vec3::NEG_Y) > ci)
                .map(|p| p.power.x)
                .sum();
            let omega = 2.0 * std::f32::consts::PI * (1.0 - ci);
            assert!((inner / omega / 3.0 - 1.0).abs() < 0.03, "inner-cone intensity {}", inner / omega);
        }
    }
}
