//! Participating media against closed forms: Beer-Lambert through a slab, and the
//! furnace filled with a medium that only scatters (Le / (1 - rho) everywhere,
//! through the medium).

use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_methods::Method;
use pm_render::PathTracer;
use pm_scene::{Medium, Scene};
use pm_tests::{against_constant, camera, closed_box, material, render_params, sphere};

/// The path tracer's image of `scene` from its camera, `spp` samples a pixel.
fn path_image(scene: &Scene, size: u32, spp: u32) -> pm_render::Image {
    let mut cfg = render_params(Method::Path, size, size);
    cfg.render.spp = spp;
    let film = cfg.render.film(1);
    let pt = PathTracer::new(scene).unwrap();
    let cam = scene.camera.as_ref().unwrap();
    pm_render::render_region(cam, &film, film.rect(), &pt, false, &|_, _| {}).unwrap().0
}

/// An emitting floor (L_e = 1, black) seen from above through a 0.4 m slab, a box
/// whose walls are an index-matched boundary (smooth transmission, ior 1), holding
/// an absorbing and scattering medium: a shadow ray straight through it keeps
/// exp(-sigma_t 0.4) per channel (Beer-Lambert), and so does the path tracer's view
/// of the floor when the medium only absorbs. The test can fail: the slab's walls
/// alone would pass everything (they are index-matched), and a scattering medium
/// seen by the eye adds in-scattered light.
#[test]
fn beer_lambert_through_a_slab_per_channel() {
    let thick = 0.4f32;
    let build = |sigma_a: Rgb, sigma_s: Rgb| {
        let mut inward = Vec::new();
        closed_box(&mut inward, Vec3::new(-3.0, 0.5, -3.0), Vec3::new(4.0, 0.5 + thick, 4.0), 0);
        let mut tris: Vec<_> =
            inward.iter().map(|t| pm_scene::Triangle::new([t.p[0], t.p[2], t.p[1]], 0).unwrap()).collect();
        let v = |x: f32, z: f32| Vec3::new(x, 0.0, z);
        for q in [[v(-3.0, -3.0), v(-3.0, 4.0), v(4.0, 4.0)], [v(-3.0, -3.0), v(4.0, 4.0), v(4.0, -3.0)]] {
            tris.push(pm_scene::Triangle::new(q, 1).unwrap());
        }
        let walls = material("slab walls", Bsdf::Glass { eta: 1.0, tint: Rgb::ONE, thin: false }, 0.0);
        let floor = material("floor", Bsdf::Lambert { rho: Rgb::ZERO }, 1.0);
        let cam = pm_tests::camera_looking_down(Vec3::new(0.5, 3.0, 0.5), 0.1);
        let mut scene = Scene::from_parts(tris, vec![walls, floor], vec![], Some(cam));
        scene.set_medium("slab walls", Medium::new("slab", sigma_a, sigma_s, 0.3).unwrap()).unwrap();
        scene.finish_media().unwrap();
        scene
    };
    let (sigma_a, sigma_s) = (Rgb::new(1.0, 2.0, 0.5), Rgb::new(0.5, 0.0, 2.0));
    let scene = build(sigma_a, sigma_s);
    assert!(scene.has_scattering_media());
    assert_eq!(scene.eye_medium(Vec3::new(0.5, 3.0, 0.5)), None);
    assert!(scene.medium_at(Vec3::new(0.5, 0.7, 0.5)).is_some(), "inside the slab");
    // A shadow ray from under the slab straight up through it, to a point above.
    let o = Vec3::new(0.5, 0.1, 0.5);
    let got = scene.transmittance_along(o, Vec3::Y, 2.9, None);
    let want = (-(sigma_a + sigma_s) * thick).exp();
    let rel = |a: Rgb, b: Rgb| ((a - b) / b).abs().max_element();
    assert!(rel(got, want) < 1e-4, "shadow ray: {got}, Beer-Lambert {want}");
    // Blocked by the floor when it goes down.
    assert_eq!(scene.transmittance_along(Vec3::new(0.5, 2.0, 0.5), Vec3::NEG_Y, 5.0, None), Rgb::ZERO);
    // The eye sees the floor through an absorbing slab at exp(-sigma_a 0.4).
    let absorbing = build(sigma_a, Rgb::ZERO);
    let img = path_image(&absorbing, 8, 16);
    let mean = img.total().iter().copied().sum::<Rgb>() / img.total().len() as f32;
    let want = (-sigma_a * thick).exp();
    assert!(rel(mean, want) < 1e-3, "path tracer through the slab: {mean}, Beer-Lambert {want}");
}

/// The furnace (a closed sphere of albedo 0.8 emitting L_e = 1 inward: radiance 5
/// everywhere) filled with a medium that scatters without absorbing (single-scattering
/// albedo 1), forward-scattering (g = 0.6) and dense enough that most paths scatter
/// several times before reaching the wall (sigma_s = 1.5 / m in a sphere of radius
/// 2 m), with a different sigma_s per channel: the radiance is still 5 in every
/// direction. The path tracer's mean within 1% per channel, no pixel 15% off.
/// Measured (12 x 12, 1024 paths a pixel): 5.004, 5.002, 5.001, worst pixel 5%;
/// at 4096, 5.003, 4.992, 5.002. A medium that also absorbed, or free-flight weights
/// that did not cancel, would read otherwise: balancing the channels per event
/// instead of over the whole path read 4.96, 5.27 and 13.9 (weights that grow
/// without bound in the chromatic medium).
#[test]
fn furnace_filled_with_a_conservative_medium_stays_le_over_one_minus_rho() {
    let mut tris = Vec::new();
    sphere(&mut tris, Vec3::ZERO, 2.0, true, 0);
    let mats = vec![material("furnace", Bsdf::Lambert { rho: Rgb::splat(0.8) }, 1.0)];
    let cam = camera(Vec3::new(0.3, 0.2, 0.5), Vec3::new(1.0, 0.3, -2.0));
    let mut scene = Scene::from_parts(tris, mats, vec![], Some(cam));
    let fog = Medium::new("scene", Rgb::ZERO, Rgb::new(1.5, 0.7, 3.0), 0.6).unwrap();
    scene.set_medium("scene", fog).unwrap();
    scene.finish_media().unwrap();
    assert!(scene.eye_medium(Vec3::new(0.3, 0.2, 0.5)).is_some());
    let img = path_image(&scene, 12, 1024);
    for c in 0..3 {
        let px: Vec<Vec3> = img.total().iter().map(|p| Vec3::splat(p[c])).collect();
        let (mean, rms, worst) = against_constant(&px, 5.0);
        eprintln!(
            "furnace in a conservative medium, channel {c}: mean {mean:.4} (exact 5), rms {rms:.4}, worst {worst:.4}"
        );
    }
    for c in 0..3 {
        let px: Vec<Vec3> = img.total().iter().map(|p| Vec3::splat(p[c])).collect();
        let (mean, _, worst) = against_constant(&px, 5.0);
        assert!((mean / 5.0 - 1.0).abs() < 0.01, "channel {c}: mean {mean}");
        assert!(worst < 0.15, "channel {c}: a pixel {worst} off");
    }
}

/// The furnace of the test above for photons: every scattering event in the medium
/// is a volume photon, so the volume map's total power is the rate of scattering
/// in the sphere, sigma_s times the fluence 4 pi L (L = 5 everywhere) times the
/// volume V, per channel; and the global map's is the power arriving at the walls,
/// pi L times their area (the wall absorbs and re-emits whatever the medium
/// redistributes). The medium's chromatic sigma_s makes the photons' channels
/// differ in how often they scatter, which the spectral MIS must undo. Measured
/// (100,000 photons a map): within 0.9% per channel, both maps; asserted 2%.
#[test]
fn photons_in_a_conservative_medium_keep_the_furnace_power() {
    use pm_photon::{Budget, LightSelector, MapPass, TraceConfig};
    let mut tris = Vec::new();
    sphere(&mut tris, Vec3::ZERO, 2.0, true, 0);
    // The mesh's own volume and area (the sphere's facets lie inside the sphere).
    let volume: f32 = tris.iter().map(|t| t.p[0].dot(t.p[1].cross(t.p[2]))).sum::<f32>().abs() / 6.0;
    let area: f32 = tris.iter().map(|t| t.area()).sum();
    let mats = vec![material("furnace", Bsdf::Lambert { rho: Rgb::splat(0.8) }, 1.0)];
    let mut scene = Scene::from_parts(tris, mats, vec![], None);
    let sigma_s = Rgb::new(1.5, 0.7, 3.0);
    scene.set_medium("scene", Medium::new("scene", Rgb::ZERO, sigma_s, 0.6).unwrap()).unwrap();
    scene.finish_media().unwrap();
    let traced = |pass, target| {
        let cfg = TraceConfig {
            pass,
            budget: Budget::Stored { target, cap: target * 100 },
            seed: 5,
            selector: LightSelector::new(&scene, &[]).unwrap(),
        };
        pm_photon::trace(&scene, &cfg, &|_| {}).unwrap()
    };
    let vol = traced(MapPass::Volume, 100_000);
    assert!(vol.photons.iter().all(|p| p.flags & pm_format::flags::VOLUME != 0 && p.normal == Vec3::ZERO));
    assert!(vol.photons.iter().any(|p| p.flags & pm_format::flags::DIRECT != 0));
    let want = sigma_s * (4.0 * std::f32::consts::PI * 5.0 * volume);
    let got: Rgb = vol.photons.iter().map(|p| p.power).sum();
    let rel = |a: Rgb, b: Rgb| ((a - b) / b).abs().max_element();
    eprintln!("volume map: {got} W scattered, want {want} ({:.4})", rel(got, want));
    assert!(rel(got, want) < 0.02, "volume map power {got}, want {want}");
    let global = traced(MapPass::Global, 100_000);
    let got: Rgb = global.photons.iter().map(|p| p.power).sum();
    let want = Rgb::splat(std::f32::consts::PI * 5.0 * area);
    eprintln!("global map: {got} W on the walls, want {want} ({:.4})", rel(got, want));
    assert!(rel(got, want) < 0.02, "global map power {got}, want {want}");
}

/// Single scattering in closed form: a point light of intensity I at distance h
/// from a camera ray in a homogeneous medium (isotropic, sigma_s and sigma_t per
/// channel) sends along the ray L = sigma_s I / (4 pi) times the integral over the
/// ray of e^(-sigma_t (s + r)) / r^2 ds, r the distance from the ray's point at s
/// to the light. With s = t_foot + h tan(theta) that is sigma_s I / (4 pi h) times
/// the integral of e^(-sigma_t (s + r)) d theta, smooth, which Simpson's rule takes
/// to 1e-9 here. The estimator (equiangular distances, one light sample each)
/// within 0.5% per channel, on a segment that passes the light and on one that
/// ends before it. The surroundings are a black sphere, so nothing else arrives.
#[test]
fn single_scattering_matches_the_closed_form() {
    let mut tris = Vec::new();
    sphere(&mut tris, Vec3::ZERO, 30.0, true, 0);
    let mats = vec![material("black", Bsdf::Lambert { rho: Rgb::ZERO }, 0.0)];
    let (light_at, intensity) = (Vec3::new(1.0, 0.7, 0.0), Rgb::new(100.0, 50.0, 20.0));
    let bulb = pm_scene::Light {
        name: "bulb".into(),
        kind: pm_scene::LightKind::Point { position: light_at, intensity },
        power: Rgb::ZERO,
    };
    let mut scene = Scene::from_parts(tris, mats, vec![bulb], None);
    let (sigma_a, sigma_s) = (Rgb::new(0.05, 0.1, 0.0), Rgb::new(0.2, 0.05, 0.4));
    scene.set_medium("scene", Medium::new("scene", sigma_a, sigma_s, 0.0).unwrap()).unwrap();
    scene.finish_media().unwrap();
    let light = pm_light::DirectLighting::new(&scene).unwrap();
    let (o, d) = (Vec3::new(-3.0, 0.0, 0.0), Vec3::X);
    let medium = scene.medium_at(o);
    assert!(medium.is_some());
    let sigma_t = sigma_a + sigma_s;
    let h = 0.7f64;
    let t_foot = (light_at - o).dot(d) as f64;
    for t_max in [8.0f64, 2.5] {
        // Simpson over theta.
        let (a0, a1) = ((-t_foot / h).atan(), ((t_max - t_foot) / h).atan());
        let n = 20_000;
        let mut want = [0.0f64; 3];
        for c in 0..3 {
            let st = sigma_t[c] as f64;
            let f = |th: f64| {
                let s = t_foot + h * th.tan();
                let r = h / th.cos();
                (-st * (s + r)).exp()
            };
            let dx = (a1 - a0) / n as f64;
            let mut sum = f(a0) + f(a1);
            for i in 1..n {
                sum += f(a0 + i as f64 * dx) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            want[c] = sigma_s[c] as f64 * intensity[c] as f64 / (4.0 * std::f64::consts::PI * h) * sum * dx / 3.0;
        }
        let mut sum = Rgb::ZERO;
        let runs = 64;
        for i in 0..runs {
            let mut s = pm_sampling::Sampler::new(9, i);
            sum += light.single_scattering(o, d, t_max as f32, medium, &mut s, 1024);
        }
        let got = sum / runs as f32;
        for c in 0..3 {
            let rel = got[c] as f64 / want[c] - 1.0;
            eprintln!("single scattering to {t_max} m, channel {c}: {} against {} ({rel:+.5})", got[c], want[c]);
            assert!(rel.abs() < 0.005, "t_max {t_max}, channel {c}: {} against the closed form {}", got[c], want[c]);
        }
    }
}

/// The volume map of `scene`: `stored` photons at scattering events, balanced.
fn volume_nodes(scene: &Scene, stored: u64, seed: u64) -> Vec<pm_format::FullPhoton> {
    use pm_format::PhotonRecord;
    let cfg = pm_photon::TraceConfig {
        pass: pm_photon::MapPass::Volume,
        budget: pm_photon::Budget::Stored { target: stored, cap: stored * 100 },
        seed,
        selector: pm_photon::LightSelector::new(scene, &[]).unwrap(),
    };
    let photons = pm_photon::trace(scene, &cfg, &|_| {}).unwrap().photons;
    pm_kdtree::balance(&photons.iter().map(pm_format::FullPhoton::encode).collect::<Vec<_>>())
}

/// The photon-map renderer's full image of `scene` with its volume map (`nodes`),
/// by `estimate`.
fn full_with_volume(
    scene: &Scene,
    maps: &(Vec<pm_format::CompactIrrPhoton>, Vec<pm_format::FullPhoton>),
    nodes: &[pm_format::FullPhoton],
    cfg: &pm_render::RenderParams,
) -> pm_render::Image {
    let irr = pm_render::irradiance_subset(&maps.0);
    let diag = scene.bounds.diagonal();
    let m = pm_render::Maps {
        global: Some(pm_kdtree::KdTree::new(&maps.0)),
        irradiance: Some(pm_kdtree::KdTree::new(&irr)),
        caustic: (!maps.1.is_empty()).then(|| pm_kdtree::KdTree::new(&maps.1)),
        volume: Some(pm_render::VolumeMap::new(
            scene,
            nodes,
            cfg.volume_k,
            cfg.volume_radius_rel_diag * diag,
            cfg.gather_lookup == pm_render::Lookup::Precomputed,
            cfg.volume_estimate == pm_render::VolumeEstimate::Beam,
        )),
    };
    let camera = scene.camera.as_ref().unwrap();
    let film = cfg.film(1);
    let pm = pm_render::PhotonMapping::new(scene, m, cfg, true).unwrap();
    pm_render::render_region(camera, &film, film.rect(), &pm, false, &|_, _| {}).unwrap().0
}

/// The Cornell box with two blocks filled with fog (`[media.scene]`: sigma_s 0.3 /
/// m, sigma_a 0.03 / m, g 0.3; the camera 2.8 m in front of the box, in the fog):
/// the photon-map renderer (global and volume maps, single scattering from the
/// light, the beam estimate and the ray march) against the path tracer, layer by
/// layer in mean over the image but the light's pixels: the volume layer (light
/// scattered toward the eye), direct (surfaces lit through the fog), indirect,
/// and the total. Measured (32 x 32, path 1,024 a pixel; 200,000 global and
/// 200,000 volume photons, 16 light samples of single scattering): volume -1.8%
/// (beam and march), direct +0.5%, indirect -1.4%, total -1.4%; asserted 5%,
/// 3%, 10% and 3%. (Before final gathers read precomputed in-scattering at full
/// distance the indirect layer read -3.3%. Before the scene
/// medium's sphere held the camera, eye rays scattered in fog where no photon
/// could go, and the volume layer read 35% low: the test can tell.)
#[test]
fn fog_in_the_cornell_box_agrees_with_the_path_tracer() {
    let mut scene = pm_tests::load_scene("cornell_boxes.gltf");
    let fog = Medium::new("scene", Rgb::splat(0.03), Rgb::splat(0.3), 0.3).unwrap();
    scene.set_medium("scene", fog).unwrap();
    scene.finish_media().unwrap();
    assert!(pm_light::analyze(&scene).volume.yes);
    let maps = pm_tests::photon_maps(&scene, 200_000, 0, 0.25);
    let layers = [
        (Some(pm_color::Layer::Volume), 0.05),
        (Some(pm_color::Layer::Direct), 0.03),
        (Some(pm_color::Layer::Indirect), 0.10),
        (None, 0.03),
    ];
    photon_maps_agree_with_the_path_tracer("fog box", &scene, &maps, 1024, &layers, None);
}

/// The photon-map renderer with `maps` and a volume map of 200,000 photons
/// against the path tracer (`spp` a pixel) on `scene` at 32 x 32, layer by layer
/// in mean over the image but the light's pixels, each within its tolerance,
/// by the beam estimate and by the ray march. With `bright` (a tolerance), also
/// the volume layer over its bright pixels alone: those whose volume layer is
/// over twice the image's mean in an independent path-traced image (another
/// seed, a quarter of the paths, so choosing them does not favour either side).
fn photon_maps_agree_with_the_path_tracer(
    name: &str,
    scene: &Scene,
    maps: &(Vec<pm_format::CompactIrrPhoton>, Vec<pm_format::FullPhoton>),
    spp: u32,
    layers: &[(Option<pm_color::Layer>, f64)],
    bright: Option<f64>,
) {
    let size = 32;
    let mut cfg = render_params(Method::Path, size, size);
    cfg.render.spp = spp;
    let pt = PathTracer::new(scene).unwrap();
    let path_image = |cfg: &pm_render::RenderParams, seed: u64| {
        let film = cfg.film(seed);
        pm_render::render_region(scene.camera.as_ref().unwrap(), &film, film.rect(), &pt, false, &|_, _| {}).unwrap().0
    };
    let path = path_image(&cfg.render, 1);
    assert!(path.has_volume());
    let chooser = bright.map(|_| path_image(&pm_render::RenderParams { spp: spp / 4, ..cfg.render.clone() }, 2));
    let nodes = volume_nodes(scene, 200_000, 3);
    cfg.mode = Method::Full;
    cfg.render.spp = 4;
    // Fewer gather rays and longer march steps than the defaults: CI time (the
    // means do not move).
    cfg.render.gather_rays = 100;
    cfg.render.volume_step_rel_diag = 0.02;
    // The light seen directly and its neighbours are left out (its anti-aliased
    // edge differs between adaptive and jittered sampling).
    let keep = pm_image::accuracy::keep_mask(path.total(), size as usize, size as usize, None);
    let mean_where = |img: &pm_render::Image, layer: Option<pm_color::Layer>, keep: &[bool]| {
        let px = img.total_or_layer(layer);
        let kept: Vec<_> = px.iter().zip(keep).filter(|(_, k)| **k).map(|(p, _)| p.element_sum() as f64).collect();
        kept.iter().sum::<f64>() / (3 * kept.len()).max(1) as f64
    };
    let mean = |img: &pm_render::Image, layer: Option<pm_color::Layer>| mean_where(img, layer, &keep);
    let volume = Some(pm_color::Layer::Volume);
    let lit: Option<Vec<bool>> = chooser.as_ref().map(|c| {
        let m = mean(c, volume);
        c.total_or_layer(volume).iter().zip(&keep).map(|(p, k)| *k && p.element_sum() as f64 / 3.0 > 2.0 * m).collect()
    });
    for estimate in [pm_render::VolumeEstimate::Beam, pm_render::VolumeEstimate::RayMarch] {
        cfg.render.volume_estimate = estimate;
        let full = full_with_volume(scene, maps, &nodes, &cfg.render);
        assert!(full.has_volume() && full.total().iter().all(|p| p.is_finite()));
        for &(layer, tol) in layers {
            let (f, p) = (mean(&full, layer), mean(&path, layer));
            let layer_name = pm_color::layer_name(layer);
            eprintln!("{name}, {estimate:?}, {layer_name}: full {f:.5}, path {p:.5} ({:+.2}%)", 100.0 * (f / p - 1.0));
            assert!((f / p - 1.0).abs() < tol, "{name}, {estimate:?} {layer_name}: full {f} against path {p}");
        }
        if let (Some(tol), Some(lit)) = (bright, &lit) {
            let (f, p) = (mean_where(&full, volume, lit), mean_where(&path, volume, lit));
            let n = lit.iter().filter(|&&l| l).count();
            eprintln!(
                "{name}, {estimate:?}, volume's {n} bright pixels: full {f:.5}, path {p:.5} ({:+.2}%)",
                100.0 * (f / p - 1.0)
            );
            assert!(
                n >= 10 && (f / p - 1.0).abs() < tol,
                "{name}, {estimate:?} bright volume: full {f} against path {p}"
            );
        }
    }
}

/// The volumetric caustic (scenes/volumetric_caustic.gltf: a 0.3 m lamp above a
/// glass sphere in a fog box, sigma_t 0.16 per metre, albedo 0.8): the sphere
/// focuses the lamp into a bright cone of fog and a caustic on the floor, light
/// the lamp's single scattering cannot give (shadow rays stop at the glass). The
/// photon-map renderer carries the cone in its volume map's caustic photons (L S+
/// V) and the floor's caustic in the caustic map; against the path tracer (4,096
/// paths a pixel, which finds the lamp through the sphere by phase and BSDF
/// sampling) per layer in mean, by the beam estimate and the ray march, and the
/// volume layer over its bright pixels (the cone and the lamp's glow). Measured
/// (32 x 32; 200,000 global, 100,000 caustic and 200,000 volume photons): volume
/// -1.1% (beam) and -1.0% (march), caustic -0.5%, direct +0.9%, indirect -0.2%,
/// total -0.8%, the bright pixels -1.3% and -1.0%. Leaving the caustic volume
/// photons out of the eye rays' estimate takes 5.3% off the volume layer's mean.
#[test]
fn the_volumetric_caustic_agrees_with_the_path_tracer() {
    let scene = pm_tests::load_scene("volumetric_caustic.gltf");
    assert!(pm_light::analyze(&scene).volume.yes && pm_light::analyze(&scene).caustics.yes);
    let maps = pm_tests::photon_maps(&scene, 200_000, 100_000, 0.25);
    let layers = [
        (Some(pm_color::Layer::Volume), 0.03),
        (Some(pm_color::Layer::Caustic), 0.05),
        (Some(pm_color::Layer::Direct), 0.03),
        (Some(pm_color::Layer::Indirect), 0.10),
        (None, 0.03),
    ];
    photon_maps_agree_with_the_path_tracer("volumetric caustic", &scene, &maps, 4096, &layers, Some(0.05));
}

/// `cargo xtask run` on the fog-filled box: the analysis finds light entering the
/// medium, so stage 1 writes volume.pmap, photon-sort sorts it and photon-render
/// reads it; the image has a volume layer holding light (and the box without the
/// fog none, and no volume step). A bad `[media.NAME]` is a one-line error naming
/// the file, the key and the medium.
#[test]
fn the_pipeline_traces_sorts_and_renders_a_volume_map() {
    use pm_runner::run::{RunArgs, run_with};
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = tempfile::tempdir().unwrap();
    let p = pm_tests::small_pipeline(dir.path(), "cornell_boxes.gltf", "\"auto\"", 2, "fog");
    pm_tests::edit_pipeline(&p, |c| {
        let fog = pm_stage::MediumArg { name: "scene".into(), sigma_a: [0.03; 3], sigma_s: [0.3; 3], g: 0.3 };
        c.scene_options.medium.push(fog);
        c.trace.volume_photons = 20_000;
    });
    let out = dir.path().join("out");
    let args = RunArgs { pipeline: Some(p.clone()), out: Some(out.clone()), ..Default::default() };
    let bins = pm_tests::bins();
    let ran: Vec<String> =
        run_with(&args, &root, &bins).unwrap().into_iter().filter(|o| o.ran).map(|o| o.step).collect();
    assert!(ran.contains(&"photon-sort volume".to_string()), "{ran:?}");
    assert!(out.join("volume.kd.pmap").exists());
    // photon-inspect tells a volume map's photons: all in a medium, the first
    // events of paths from the light (single scattering) among them.
    let o = std::process::Command::new(pm_tests::bin_dir().join("photon-inspect"))
        .args([out.join("volume.kd.pmap").to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (n, direct) = (s["photons"].as_u64().unwrap(), s["direct"].as_u64().unwrap());
    assert_eq!((s["kind"].as_str(), s["in_medium"].as_u64()), (Some("Volume"), Some(n)), "{s}");
    assert!(direct > 0 && direct < n && s["kd_tree"]["valid"] == true, "{s}");
    let img = pm_image::read_exr(&out.join("image.exr")).unwrap();
    let volume = img.layers.iter().find(|(n, _)| n == "volume").expect("a volume layer");
    assert!(volume.1.iter().map(|p| p.element_sum()).sum::<f32>() > 0.0);
    // Without the fog: no volume map, no volume layer.
    pm_tests::edit_pipeline(&p, |c| {
        c.scene_options.medium.clear();
    });
    let ran: Vec<String> =
        run_with(&args, &root, &bins).unwrap().into_iter().filter(|o| o.ran).map(|o| o.step).collect();
    assert!(!ran.contains(&"photon-sort volume".to_string()) && !out.join("volume.kd.pmap").exists(), "{ran:?}");
    let img = pm_image::read_exr(&out.join("image.exr")).unwrap();
    assert!(!img.layers.iter().any(|(n, _)| n == "volume"));
    // Bad media, refused in one line naming the file, the key and the medium.
    let base = std::fs::read_to_string(&p).unwrap();
    for (table, what) in [
        ("sigma_s = [-0.1, 0.3, 0.3]", "sigma_s"),
        ("sigma_s = [0.3, 0.3, 0.3]\ng = 1.0", "g 1"),
        ("sigma_a = [nan, 0.0, 0.0]", "sigma_a"),
    ] {
        std::fs::write(&p, format!("{base}\n[media.scene]\n{table}\n")).unwrap();
        let e = pm_pipeline::Pipeline::load(&p).expect_err("refused").to_string();
        assert!(e.contains("fog.toml") && e.contains("media = scene:") && e.contains(what) && !e.contains('\n'), "{e}");
    }
}

/// The Cornell box in a fog that only absorbs (`[media.scene]` sigma_a 0.04,
/// 0.08, 0.16 per metre, so every layer loses a different share per channel):
/// what the fog keeps of each method's direct and indirect layers (fog over clear,
/// per channel, mean over the image but the light's pixels) is what it keeps of
/// the path tracer's. The ratio takes each method's own bias out (the vertex
/// method's interpolation, the splat's kernels, SPPM's radii), so what is left is
/// the attenuation: of eye rays, shadow rays and the photons (the vertex method
/// and SPPM fly pm-photon's paths; image-space photon mapping attenuates its
/// bounce maps, its traced bounces and its splat). A method that ignored the fog
/// would keep all (ratio 1 where the path tracer keeps 0.4 to 0.8); one that
/// forgot the splat's eye segment would keep too much indirect light (measured
/// with it left out: +18%, +40%, +94%). Shadow maps give way to shadow rays in
/// media (a depth map cannot see through them). Measured (32 x 32, path tracer
/// 512 a pixel): every method and layer within 1.1% per channel (SPPM's indirect
/// red the worst); asserted 3%.
#[test]
fn real_time_methods_and_sppm_attenuate_as_the_path_tracer_does() {
    use pm_color::Layer;
    use pm_live::{DirectMode, FrameParams};
    let clear = pm_tests::load_scene("cornell_boxes.gltf");
    let mut fog = clear.clone();
    fog.set_medium("scene", Medium::new("scene", Rgb::new(0.04, 0.08, 0.16), Rgb::ZERO, 0.0).unwrap()).unwrap();
    fog.finish_media().unwrap();
    assert!(fog.has_media() && !fog.has_scattering_media());
    assert!(pm_light::ShadowMaps::new(&clear, 64).is_some() && pm_light::ShadowMaps::new(&fog, 64).is_none());
    let size = 32;
    let reference = [&clear, &fog].map(|s| path_image(s, size, 512));
    let keep = pm_image::accuracy::keep_mask(reference[0].total(), size as usize, size as usize, None);
    let mean = |px: &[Rgb]| -> glam::DVec3 {
        let kept: Vec<_> = px.iter().zip(&keep).filter(|(_, k)| **k).map(|(p, _)| p.as_dvec3()).collect();
        kept.iter().sum::<glam::DVec3>() / kept.len().max(1) as f64
    };
    let layers = [Layer::Direct, Layer::Indirect];
    let kept = |pair: [Vec<Vec<Rgb>>; 2]| layers.map(|l| mean(&pair[1][l.index()]) / mean(&pair[0][l.index()]));
    let by_layer = |f: &dyn Fn(Layer) -> Vec<Rgb>| -> Vec<Vec<Rgb>> { Layer::SURFACE.map(f).to_vec() };
    let want = kept(reference.map(|img| by_layer(&|l| img.layer(l).to_vec())));
    let frame = FrameParams { width: size, height: size, light_samples: 16, ..Default::default() };
    type Run<'a> = Box<dyn Fn(&Scene) -> Vec<Vec<Rgb>> + 'a>;
    let methods: [(&str, Run); 4] = [
        (
            "vertex",
            Box::new(|s: &Scene| {
                let params = pm_vertex::VertexParams { per_frame: 50_000, total: 50_000, ..Default::default() };
                let mut live = pm_vertex::live(s.clone(), None, frame.clone(), params, 3).unwrap();
                live.step().unwrap();
                by_layer(&|l| live.frame_layers().layer(l).to_vec())
            }),
        ),
        (
            "image-space",
            Box::new(|s: &Scene| {
                let f = FrameParams { direct: DirectMode::ShadowMap, ..frame.clone() };
                let mut live = pm_ispm::live(s.clone(), f, Default::default(), 3).unwrap();
                live.step().unwrap();
                by_layer(&|l| live.frame_layers().layer(l).to_vec())
            }),
        ),
        (
            "image-space, subsampled",
            Box::new(|s: &Scene| {
                let params = pm_ispm::IspmParams { subsample: 2, ..Default::default() };
                let mut live = pm_ispm::live(s.clone(), frame.clone(), params, 3).unwrap();
                live.step().unwrap();
                by_layer(&|l| live.frame_layers().layer(l).to_vec())
            }),
        ),
        (
            "sppm",
            Box::new(|s: &Scene| {
                let params = pm_sppm::SppmParams { passes: 32, photons_per_pass: 20_000, ..Default::default() };
                let camera = s.camera.clone().unwrap();
                let mut p = pm_sppm::Sppm::new(s, size, size, params, 3, &Default::default()).unwrap();
                for _ in 0..32 {
                    p.pass(&camera);
                }
                let img = p.image();
                by_layer(&|l| img.layer(l).to_vec())
            }),
        ),
    ];
    for (name, run) in &methods {
        let got = kept([run(&clear), run(&fog)]);
        for ((layer, g), w) in layers.iter().zip(got).zip(want) {
            let off = g / w - 1.0;
            eprintln!("{name}, {}: fog keeps {g:.4} (path tracer {w:.4}), {:+.2?}%", layer.name(), 100.0 * off);
            assert!(w.max_element() < 0.9, "the fog keeps too much: {w}");
            assert!(off.abs().max_element() < 0.03, "{name}, {}: fog keeps {g} against {w}", layer.name());
        }
    }
}

/// Final gathers through an index-matched box: cornell_fog with its fog made clear
/// is cornell_boxes with a box of walls that rays pass straight through, so its
/// final gathers must give the same indirect light and take about as many
/// secondary gathers. The distance that decides a secondary gather (and a cache
/// record's radius) runs from the gather's origin through such walls: measured from
/// the last wall passed, every gather ray crossing the box's floor face, 1 mm above
/// the floor, was a short one (on a 16 x 16 image 776,000 secondary gathers against
/// about 5,000, and 16x the render time). Measured (24 x 24, 541 final gathers
/// each): indirect -0.4%; secondary gathers 1,341 against 465 (0.6% of the gather
/// rays against 0.2%), asserted under 4x; with the bug, about 150x. The rest is
/// where the gathers fall: the scene with walls has a few records on the room's
/// ceiling edges (within 3 um of both surfaces, where eye rays along the
/// symmetric camera's edge pixels land after passing a wall), each of whose
/// hundreds of rays is short; none of its short rays crossing a wall is wrong.
#[test]
fn final_gathers_pass_index_matched_walls_at_full_length() {
    let boxes = pm_tests::load_scene("cornell_boxes.gltf");
    let mut walls = pm_tests::load_scene("cornell_fog.gltf");
    walls.set_medium("fog", Medium::new("fog", Rgb::ZERO, Rgb::ZERO, 0.0).unwrap()).unwrap();
    walls.finish_media().unwrap();
    assert!(walls.has_index_matched());
    let mut cfg = render_params(Method::Indirect, 24, 24);
    cfg.render.spp = 1;
    let run = |scene: &Scene| {
        let maps = pm_tests::photon_maps(scene, 100_000, 0, 0.25);
        let (img, stats) = pm_tests::render(scene, &maps, &cfg);
        let sum: f64 = img.total().iter().map(|p| p.element_sum() as f64).sum();
        (sum, stats.secondary_gathers)
    };
    let ((e_boxes, sec_boxes), (e_walls, sec_walls)) = (run(&boxes), run(&walls));
    eprintln!("indirect {e_walls:.4} against {e_boxes:.4}; secondary gathers {sec_walls} against {sec_boxes}");
    assert!((e_walls / e_boxes - 1.0).abs() < 0.02, "indirect {e_walls} against {e_boxes}");
    assert!((sec_walls as f64) < 4.0 * sec_boxes as f64 + 100.0, "{sec_walls} secondary gathers against {sec_boxes}");
}

/// `cargo xtask run` as a user runs it, on fog boxes as users make them: the
/// repository's pipeline.toml with only the scene and the image size (64 x 64)
/// changed, against the path tracer (`photon-render --mode path`, 512 a pixel,
/// the same scene options). On cornell_fog (a thin fog box just inside the
/// walls) and on cornell_fogbox (a dense box, sigma_s 2.4 and sigma_a 0.6 per
/// metre, g 0.3, given by material name as `[media.fog]`, filling the room's
/// lower 0.30 m 2 mm inside the walls, under a glass sphere), each layer's mean
/// and its worst 8 x 8 block, the light's pixels left out. The irradiance cache's
/// prepass once ran without the volume map: its gathers lost the light the fog
/// scatters onto the surfaces, and the indirect layer came out at half the path
/// tracer's (0.48 on cornell_fog at 128 x 128, the whole image 20% dark; issue
/// 53). The volume layer of the dense box was then 8% dark, 20% near its top
/// face: the beam estimate lost the photons beside a grazing eye ray's ends and
/// spread the power of photons near a boundary into the empty space beyond it
/// (`pm_estimate::beam` and `Beams::with_inside_fractions` now correct both).
/// Measured, mean (worst block): cornell_fog total -0.1% (12%), indirect -1.0%,
/// volume +0.4%; cornell_fogbox total +0.3% (6%), indirect +0.3%, volume -0.2%
/// (6%).
///
/// SPPM (`mode = "sppm"`, its defaults) had no volume layer: the differential
/// checker's fog scenes read -100% there and 12-21% dark over the image. It now
/// gathers each pass's volume photons along its eye paths (pm-sppm's beam
/// estimate with shrinking radii). Measured, mean (worst block): cornell_fog
/// total +0.3% (4%), volume +0.2% (10%); cornell_fogbox total -0.0% (8%),
/// volume -0.5% (7%).
#[test]
fn the_pipeline_on_defaults_agrees_with_the_path_tracer_in_fog_boxes() {
    use pm_color::Layer;
    let dir = tempfile::tempdir().unwrap();
    let dense = pm_stage::MediumArg { name: "fog".into(), sigma_a: [0.6; 3], sigma_s: [2.4; 3], g: 0.3 };
    // (scene, medium, method, the most each layer's mean may be off: total, indirect, volume)
    let (full, sppm) = (pm_methods::Method::Full, pm_methods::Method::Sppm);
    for (name, medium, method, bounds) in [
        ("cornell_fog", None, full, [0.03, 0.05, 0.03]),
        ("cornell_fogbox", Some(dense.clone()), full, [0.03, 0.05, 0.03]),
        ("cornell_fog", None, sppm, [0.03, 0.05, 0.03]),
        ("cornell_fogbox", Some(dense), sppm, [0.03, 0.05, 0.03]),
    ] {
        let edit = |p: &mut pm_pipeline::Pipeline| {
            p.scene_options.medium.extend(medium);
            p.mode = method;
        };
        let (_, ours, reference) =
            pm_tests::defaults_and_path_tracer(dir.path(), &format!("{name}.gltf"), 64, 512, edit);
        let keep = pm_image::accuracy::keep_mask(&reference.pixels(None), 64, 64, None);
        for (l, bound) in [(None, bounds[0]), (Some(Layer::Indirect), bounds[1]), (Some(Layer::Volume), bounds[2])] {
            let a = pm_image::accuracy::agreement(&ours.pixels(l), &reference.pixels(l), 64, &keep, 8);
            let what = format!("{name} {method} {}: {a}", pm_color::layer_name(l));
            eprintln!("{what}");
            assert!(a.mean.abs() < bound, "{what}");
            if l.is_none() {
                assert!(a.worst_block < 0.15, "{what}");
            }
        }
    }
}

/// Issue 53: a fog box standing on the floor (the checker's fog boxes "on the
/// floor": its bottom face, an index-matched boundary, in the floor's plane).
/// Whichever of the two coplanar faces the traversal found first decided where a
/// ray looking down into the box ended: on the floor in the fog, or past the box's
/// bottom face, started under the floor, through it and out of the room (or on
/// the floor in no medium, so that its shadow rays and photons left it as if the
/// fog were not there). The checker's seed 90210 scene 31 (a sun and a spot over
/// the fog box, its floor in the foreground): the batch pipeline's indirect layer
/// 42% off in its worst block, the vertex method's direct layer +14% in mean.
/// `Scene::intersect` now hits the solid surface of a boundary and a surface
/// closer together than a ray's offset. Asserted: every camera ray of a 64 x 64
/// grid that reaches the floor inside the box's footprint ends there, in the fog
/// (before: 233 of the 335 did not).
#[test]
fn a_fog_box_standing_on_the_floor_keeps_the_floor_in_the_fog() {
    let dir = tempfile::tempdir().unwrap();
    let (path, recipe) = crate::generated_scene(dir.path(), 90210, 31);
    assert!(recipe.fog.as_deref().is_some_and(|f| f.starts_with("on the floor")), "{:?}", recipe.fog);
    let scene = pm_scene::load(&path).unwrap();
    let boundary = |tri: u32| matches!(scene.uniform_bsdf(tri), Some(Bsdf::Glass { eta: 1.0, .. }));
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for (i, t) in scene.triangles.iter().enumerate() {
        if boundary(i as u32) {
            for p in t.p {
                (lo, hi) = (lo.min(p), hi.max(p));
            }
        }
    }
    let floor = scene.bounds.min.y;
    assert!((lo.y - floor).abs() < 1e-6 * scene.bounds.diagonal(), "the box stands on the floor: {lo} / {floor}");
    let fog = scene.media.iter().position(|m| m.scatters()).map(|i| i as pm_scene::MediumId);
    let cam = scene.camera.clone().unwrap();
    let eye = scene.eye_medium(cam.position);
    let margin = 0.02 * (hi - lo);
    let inside =
        |p: Vec3| p.x > lo.x + margin.x && p.x < hi.x - margin.x && p.z > lo.z + margin.z && p.z < hi.z - margin.z;
    let (n, mut reached, mut wrong) = (64, 0, Vec::new());
    let tan = (0.5 * cam.yfov).tan();
    for j in 0..n {
        for i in 0..n {
            let (u, v) = ((i as f32 + 0.5) / n as f32 * 2.0 - 1.0, 1.0 - (j as f32 + 0.5) / n as f32 * 2.0);
            let d = (cam.forward + cam.right * (u * tan) + cam.up * (v * tan)).normalize();
            if d.y >= 0.0 {
                continue;
            }
            // Where the ray meets the floor's plane, if nothing is in the way.
            let at = cam.position + d * ((floor - cam.position.y) / d.y);
            if !inside(at) || scene.solid_hit(cam.position, d, f32::INFINITY).is_some_and(|h| h.p.y > floor + 1e-3) {
                continue;
            }
            reached += 1;
            let pass = scene.intersect_through(cam.position, d, eye);
            let on_floor = pass.hit.as_ref().is_some_and(|h| (h.p.y - floor).abs() < 1e-4 && h.ng.y.abs() > 0.99);
            if !on_floor || pass.medium != fog {
                wrong.push((at, pass.hit.map(|h| h.p), pass.medium));
            }
        }
    }
    eprintln!("{reached} rays reach the floor under the fog box; {} end elsewhere or out of the fog", wrong.len());
    assert!(reached > 200, "{reached}");
    assert!(wrong.is_empty(), "{} of {reached}: {:?}", wrong.len(), &wrong[..wrong.len().min(4)]);
}
