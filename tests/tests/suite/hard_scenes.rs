//! Hard cases on scenes built in code: light leaks between rooms, glass seen from
//! inside and nested glass in a furnace, rendering without photons.

use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_methods::Method;
use pm_scene::Scene;
use pm_tests::{camera, closed_box, material, photon_maps, render, render_params, sphere};

/// A closed lit room next to a closed dark room sharing the wall plane x = 1 (each
/// room has its own wall there, back to back, as a modeller would build them), the
/// camera in the dark room. Every pixel there must be zero: no photon or ray may
/// cross. Measured 8e-5 of the lit room's total (before the renderer checked the
/// visibility of the photon a gather ray reads: 8.8%): what remains comes from
/// photons within 0.1% of the scene diagonal of the query, which are accepted
/// without a visibility ray. Asserted: below 2e-4.
#[test]
fn no_light_leaks_into_a_closed_dark_room() {
    let mut tris = Vec::new();
    closed_box(&mut tris, Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0), 0);
    closed_box(&mut tris, Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 1.0), 0);
    let v = |x, y, z| Vec3::new(x, y, z);
    // Light in the lit room, right against the shared wall.
    for t in [
        [v(0.9, 0.95, 0.3), v(0.9, 0.95, 0.7), v(0.999, 0.95, 0.7)],
        [v(0.9, 0.95, 0.3), v(0.999, 0.95, 0.7), v(0.999, 0.95, 0.3)],
    ] {
        tris.push(pm_scene::Triangle::new([t[0], t[2], t[1]], 1).unwrap());
    }
    let mats = vec![
        material("wall", Bsdf::Lambert { rho: Rgb::splat(0.8) }, 0.0),
        material("lamp", Bsdf::Lambert { rho: Rgb::ZERO }, 50.0),
    ];
    let lit_cam = camera(Vec3::new(0.1, 0.5, 0.5), Vec3::new(1.0, 0.5, 0.5));
    let dark_cam = camera(Vec3::new(1.9, 0.5, 0.5), Vec3::new(1.0, 0.5, 0.5));
    let mut totals = Vec::new();
    for cam in [lit_cam, dark_cam] {
        let scene = Scene::from_parts(tris.clone(), mats.clone(), vec![], Some(cam));
        let maps = photon_maps(&scene, 100_000, 0, 0.25);
        let cfg = render_params(Method::Full, 24, 24);
        let (img, s) = render(&scene, &maps, &cfg);
        assert_eq!(s.nonfinite_pixels, 0);
        totals.push(img.total().iter().map(|p| p.element_sum() as f64).sum::<f64>());
    }
    eprintln!("lit room {:.4}, dark room {:.3e} (sum of pixel radiance)", totals[0], totals[1]);
    assert!(totals[0] > 1.0);
    assert!(totals[1] <= 2e-4 * totals[0], "leak: {}", totals[1] / totals[0]);
}

/// Energy is not created by glass: inside a furnace (albedo 0.8, L_e = 1, radiance
/// 5 everywhere in its air) a lossless glass sphere with a second one nested inside
/// it (total internal reflection, rays at silhouettes), seen from the air between
/// them and the furnace wall, only redirects light, so every pixel is 5. Asserted:
/// path mode mean within 2% and no pixel above 5 by more than its noise (15%);
/// full mode no pixel above 6 and mean within 5% (its glass paths stop at the
/// depth limit and are counted). Measured: path 5.004 (brightest 5.50), full 4.884
/// (brightest 5.24).
///
/// And the n^2 law: in equilibrium the radiance inside a dielectric of index n is
/// n^2 times the radiance outside (radiance over n^2 is what a refraction keeps;
/// Veach 1997, section 5.2), so a camera inside one glass sphere (n = 1.5) sees
/// 5 x 2.25 = 11.25 everywhere. Eye paths that carried power weights, as photons
/// do, saw 5 (and this test once asserted 5 there). Measured 11.24. Asserted:
/// path mode mean within 2% of 11.25.
#[test]
fn nested_glass_in_a_furnace_creates_no_energy() {
    let mats = vec![
        material("furnace", Bsdf::Lambert { rho: Rgb::splat(0.8) }, 1.0),
        material("glass", Bsdf::Glass { eta: 1.5, tint: Rgb::ONE, thin: false }, 0.0),
    ];
    let mut tris = Vec::new();
    sphere(&mut tris, Vec3::ZERO, 2.0, true, 0);
    sphere(&mut tris, Vec3::ZERO, 1.0, false, 1);
    sphere(&mut tris, Vec3::ZERO, 0.6, false, 1);
    let scene = Scene::from_parts(
        tris,
        mats.clone(),
        vec![],
        Some(camera(Vec3::new(0.1, 0.05, 1.7), Vec3::new(0.0, 0.0, -1.0))),
    );
    let maps = photon_maps(&scene, 100_000, 10_000, 0.25);
    let mut cfg = render_params(Method::Path, 16, 16);
    cfg.render.spp = 512;
    let (path, ps) = render(&scene, &maps, &cfg);
    cfg.mode = Method::Full;
    cfg.render.spp = 4;
    cfg.render.light_samples = 8;
    // At the default depth limit (12) eye paths trapped between the nested spheres
    // are cut (counted in the stats): -4.8% from outside them; at 32, what is
    // asserted is the glass alone. Final-gather rays once stopped after 4 specular
    // bounces and lost 12%.
    cfg.render.max_depth = 32;
    let (full, fs) = render(&scene, &maps, &cfg);
    for (name, img, max, tol) in [("path", &path, 5.75, 0.02), ("full", &full, 6.0, 0.05)] {
        let px = img.total();
        let (mean, _, _) = pm_tests::against_constant(px, 5.0);
        let brightest = px.iter().map(|p| p.max_element()).fold(0.0, f32::max);
        eprintln!("glass furnace {name}: mean {mean:.3}, brightest {brightest:.3}");
        assert!(brightest <= max, "{name}: a pixel at {brightest} creates energy");
        assert!((mean / 5.0 - 1.0).abs() < tol, "{name}: mean {mean}");
    }
    eprintln!("paths cut by the depth limit: path {}, full {}", ps.terminated_paths, fs.terminated_paths);
    // The camera inside one glass sphere.
    let mut tris = Vec::new();
    sphere(&mut tris, Vec3::ZERO, 2.0, true, 0);
    sphere(&mut tris, Vec3::ZERO, 1.0, false, 1);
    let inside =
        Scene::from_parts(tris, mats, vec![], Some(camera(Vec3::new(0.1, 0.05, 0.2), Vec3::new(1.0, 0.3, -2.0))));
    let maps = photon_maps(&inside, 100_000, 10_000, 0.25);
    let mut cfg = render_params(Method::Path, 16, 16);
    cfg.render.spp = 512;
    let (img, _) = render(&inside, &maps, &cfg);
    let (mean, _, _) = pm_tests::against_constant(img.total(), 11.25);
    eprintln!("inside one glass sphere: path mean {mean:.3} (n^2 x 5 = 11.25)");
    assert!((mean / 11.25 - 1.0).abs() < 0.02, "inside glass: mean {mean}, n^2 x 5 = 11.25");
}

/// A global map with no photons: the render still completes, finite, with direct
/// light and only what secondary gathers' own light sampling adds, and the stage
/// says so (see photon-render's note).
#[test]
fn rendering_with_empty_photon_maps_falls_back_to_direct_light() {
    let scene = pm_tests::load_scene("cornell_boxes.gltf");
    let empty: (Vec<pm_format::CompactIrrPhoton>, Vec<pm_format::FullPhoton>) = (Vec::new(), Vec::new());
    let cfg = render_params(Method::Full, 16, 16);
    let (img, s) = render(&scene, &empty, &cfg);
    assert_eq!(s.nonfinite_pixels, 0);
    let indirect: f32 = img.layer(pm_color::Layer::Indirect).iter().map(|p| p.element_sum()).sum();
    let direct: f32 = img.layer(pm_color::Layer::Direct).iter().map(|p| p.element_sum()).sum();
    assert!(direct > 0.0 && indirect >= 0.0 && indirect < 0.1 * direct, "direct {direct}, indirect {indirect}");
}

/// A room as Blender exports it (jozwowski_room_16: every wall and box face two
/// triangles, a point light) drawn by the vertex method on its defaults, the mesh
/// split automatically at the expected photon search radius (issue 36), against
/// the batch pipeline's image at the same time: within 10% in mean and 25% in 8 x 8
/// block RMS. Measured at 64 x 64 (16 hits a path): mean ratio 1.016 and block
/// RMS 5.0% (32 triangles split into 6,880, edges at most 0.25 m, estimates
/// divided by their discs' coverage). On the mesh as the file has it with neither
/// (`subdivide = 0`, `coverage = false`, the behaviour before) 0.506 and 55.5%: the
/// corners at the walls' edges estimate from part discs and the walls' middles get
/// only their light. The coverage alone gives 0.895 and 15.2%; the split alone gave
/// 0.952 and 9.8% (with 8 hits a path).
#[test]
fn the_vertex_method_on_its_defaults_draws_a_coarse_room_like_the_batch_pipeline() {
    let scene = pm_scene::load(&pm_tests::scene_path("jozwowski_room_16.gltf")).unwrap();
    let (w, h) = (64u32, 64u32);
    let maps = photon_maps(&scene, 200_000, 0, 0.25);
    let mut cfg = render_params(Method::Full, w, h);
    (cfg.render.spp, cfg.render.gather_rays) = (4, 128);
    let reference = render(&scene, &maps, &cfg).0.total().to_vec();
    let vertex = |subdivide, coverage| {
        let frame = pm_live::FrameParams { width: w, height: h, light_samples: 4, ..Default::default() };
        let params = pm_vertex::VertexParams { subdivide, coverage, ..Default::default() };
        let mut live = pm_vertex::live(scene.clone(), None, frame, params, 1).unwrap();
        live.set_time(0.0);
        // Fill the ring buffer (total / per_frame frames), then draw.
        for _ in 0..10 {
            live.skip().unwrap();
        }
        live.step().unwrap();
        live.frame_layers().total().to_vec()
    };
    let judge = |img: &[Vec3]| {
        let (a, b) = (pm_image::block_means(img, w as usize, 8), pm_image::block_means(&reference, w as usize, 8));
        let mean = |v: &[Vec3]| v.iter().map(|p| p.element_sum() as f64).sum::<f64>();
        let rms = (a
            .iter()
            .zip(&b)
            .map(|(a, b)| ((*a - *b).element_sum() / b.element_sum().max(1e-6)).powi(2) as f64)
            .sum::<f64>()
            / a.len() as f64)
            .sqrt();
        (mean(&a) / mean(&b), rms)
    };
    let (auto_mean, auto_rms) = judge(&vertex(pm_vertex::Subdivide::Auto, true));
    let (raw_mean, raw_rms) = judge(&vertex(pm_vertex::Subdivide::MaxEdge(0.0), false));
    eprintln!(
        "defaults: mean ratio {auto_mean:.3}, block RMS {auto_rms:.3}; as exported, no coverage: mean ratio {raw_mean:.3}, block RMS {raw_rms:.3}"
    );
    assert!((auto_mean - 1.0).abs() < 0.10, "mean ratio {auto_mean}");
    assert!(auto_rms < 0.25, "block RMS {auto_rms}");
    assert!(raw_rms > 0.25, "the mesh as exported is already fine: {raw_rms}");
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer (1024 a pixel)
/// on three scenes of the differential checker's generator (issue 53) whose area
/// lights sit a few millimetres below the ceiling: seed 5092 scene 32 (one
/// two-sided light 2.6 mm below it) and scene 14 (two lights 2.3 and 2.1 mm below
/// it, overlapping, so one's back faces the other 0.25 mm away). The ceiling above
/// a light and the back of a light are brighter than the room (the light's own
/// emission is trapped there), and a final gather that hits a light's underside
/// read them: the precomputed lookup took a ceiling photon within 3.5 mm without
/// a visibility test, and the precompute's kd-tree search found photons on the
/// parallel surface a gap behind and took them for its own (same normal, nearly in
/// the tangent plane when the gap is small against the search radius). The
/// indirect layer was +162% (scene 32) and +15% (scene 14, worst 8 x 8 block +51%)
/// at 48 x 48; measured now +4.1% and +1.4% (every lookup tests visibility,
/// `pm_estimate::irradiance_on` bounds the precompute's estimates). Scene 23 (a
/// two-sided light 21 mm below the ceiling, base colour 0.8) was the reference's
/// fault: the path tracer lit the panel with its own emission (a point on a light
/// sampled the light's triangle as a hemisphere) and read -10% here; Mitsuba 3
/// agreed with the pipeline; measured now -1.2%. Asserted: the indirect layer's
/// mean within 8% (the reference holds fireflies from the trapped light: its own
/// noise is a few percent).
#[test]
fn lights_just_below_the_ceiling_do_not_light_the_room_through_the_gap() {
    for index in [32, 14, 23] {
        let (a, recipe) = generated_on_defaults(5092, index, 48, pm_color::Layer::Indirect, 8);
        eprintln!("scene-{index:03} indirect: {a} ({:?})", recipe.lights);
        assert!(a.mean.abs() < 0.08, "scene-{index:03} indirect: {a} ({:?})", recipe.lights);
    }
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer on seed 16654's
/// scene 30 of the differential checker's generator: a closed room with a diffuse
/// box and a spot light, the camera centred in front of it, so the floor's edges
/// run along the image's diagonals through pixel centres. Eye rays there hit the
/// edge exactly; the irradiance cache put a record on it whose gather lost the
/// half of its hemisphere behind the floor (rays started on the floor's edge and
/// escaped under it), with the largest radius, and a band along each lower edge
/// came out 20% dark (17.5% in 16 x 16 blocks at 192 x 192). `Scene::make_hit`
/// now moves hits off their triangle's boundary. The precompute's estimates also
/// divided by pi r^2 where a wall cut their disc (`pm_estimate::disc_share` now).
/// The indirect layer before: -2.3% (worst 8 x 8 block 10.5%); now -0.8% (3.4%).
/// Asserted: its mean within 1.5% and every block within 8%.
#[test]
fn a_camera_centred_in_a_room_sees_no_dark_band_along_its_edges() {
    let (a, recipe) = generated_on_defaults(16654, 30, 48, pm_color::Layer::Indirect, 8);
    eprintln!("indirect: {a} ({:?})", recipe.objects);
    assert!(a.mean.abs() < 0.015 && a.worst_block < 0.08, "indirect: {a} ({:?})", recipe.objects);
}

/// Scene `index` of the differential checker's generator for `seed`, through
/// `cargo xtask run` on defaults at `size` x `size` against the path tracer (1024
/// a pixel): the agreement of `layer` in `block` x `block` blocks, the pixels the
/// checker leaves out left out (those that see a light, and their neighbours),
/// and what the scene holds.
fn generated_on_defaults(
    seed: u64,
    index: u32,
    size: u32,
    layer: pm_color::Layer,
    block: usize,
) -> (pm_image::accuracy::Agreement, pm_scenegen::random::Recipe) {
    generated_with(seed, index, size, layer, block, pm_methods::Method::Full, 1024)
}

/// [`generated_on_defaults`] with render mode `mode`, against the path tracer at
/// `spp` a pixel.
fn generated_with(
    seed: u64,
    index: u32,
    size: u32,
    layer: pm_color::Layer,
    block: usize,
    mode: pm_methods::Method,
    spp: u32,
) -> (pm_image::accuracy::Agreement, pm_scenegen::random::Recipe) {
    generated_edited(seed, index, size, layer, block, spp, |p| p.mode = mode)
}

/// [`generated_with`] with the repository's pipeline.toml changed by `edit`.
fn generated_edited(
    seed: u64,
    index: u32,
    size: u32,
    layer: pm_color::Layer,
    block: usize,
    spp: u32,
    edit: impl FnOnce(&mut pm_pipeline::Pipeline),
) -> (pm_image::accuracy::Agreement, pm_scenegen::random::Recipe) {
    let dir = tempfile::tempdir().unwrap();
    let (scene, recipe) = crate::generated_scene(dir.path(), seed, index);
    let (_, ours, reference) = pm_tests::defaults_and_path_tracer(dir.path(), scene.to_str().unwrap(), size, spp, edit);
    let n = size as usize;
    let keep = pm_study::differential::emitters_left_out(&pm_scene::load(&scene).unwrap(), n, n).unwrap();
    let l = Some(layer);
    (pm_image::accuracy::agreement(&ours.pixels(l), &reference.pixels(l), n, &keep, block), recipe)
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer (4096 a pixel)
/// on seed 12902's scene 35 of the differential checker's generator: a two-sided
/// lamp 0.4 mm under the ceiling (the room 20 cm wide). 60% of the stored photons
/// lie in the gap above it, under the cover; the nearest photons to the ceiling
/// beside the lamp were all there, and a final gather's lookup tried 16 of them
/// (one ray each) and missed: 1.6% of the cache's gather rays read no light, and
/// the whole room's indirect layer -3.0% (worst 8 x 8 block 15%). Covered photons
/// are now passed over among the cheap tests (`pm_estimate::precomputed_irradiance_where`):
/// 25 misses, +1.0% (4.0%). The exact lookup took the gap's photons in: +162%;
/// it now estimates as the precompute does (`pm_estimate::surface_irradiance`):
/// +0.5%. Asserted for each: the indirect layer's mean within 2.5% and every
/// block within 10%.
#[test]
fn the_light_trapped_above_a_lamp_neither_darkens_nor_lights_the_room() {
    for lookup in [pm_render::Lookup::Precomputed, pm_render::Lookup::Exact] {
        let (a, recipe) = generated_edited(12902, 35, 48, pm_color::Layer::Indirect, 8, 4096, |p| {
            p.render.gather_lookup = lookup;
        });
        eprintln!("{lookup:?} lookup, indirect: {a} ({:?})", recipe.lights);
        assert!(a.mean.abs() < 0.025 && a.worst_block < 0.10, "{lookup:?} lookup, indirect: {a} ({:?})", recipe.lights);
    }
}

/// Seed 23897's scene 26 of the differential checker's generator holds a sphere
/// (a UV sphere of radius 0.3 m). The gaps behind and in front of the surface at
/// each of its vertices, along the vertex's normal, are what the vertex method's
/// corner estimates keep their photons within: from one vertex the ray behind
/// left an origin offset off the surface that had slid over the next facet, and
/// met it 1e-7 m away; the corner there counted only the photons within 1e-7 m
/// of its tangent plane, four in a 4 cm disc, and drew a white spot on the
/// sphere five times as bright as the rest (`pm_scene::Scene::surface_gaps` now
/// looks from a hair off the surface). Asserted: every vertex's gaps at least
/// 1 cm.
#[test]
fn the_gaps_round_a_spheres_vertices_are_not_its_own_facets() {
    let dir = tempfile::tempdir().unwrap();
    let s = pm_scene::load(&crate::generated_scene(dir.path(), 23897, 26).0).unwrap();
    let sphere = s.objects.iter().find(|o| o.name.starts_with("object_0")).unwrap();
    let mut worst = f32::INFINITY;
    for t in sphere.tris.clone() {
        let tri = &s.triangles[t as usize];
        for k in 0..3 {
            let n = tri.n.map_or(tri.ng(), |n| n[k]).normalize();
            let (_, behind, front) = s.surface_gaps(tri.p[k], n, 0.35).unwrap();
            worst = worst.min(behind).min(front);
        }
    }
    assert!(worst > 0.01, "a gap of {worst} m at a vertex of the sphere");
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer (4096 a pixel)
/// on seed 77777's scene 30 of the differential checker's generator: two lamps
/// 0.03 mm apart under the ceiling, the lower one covering most of the upper,
/// over a fog box. Where rays walk through index-matched boundaries, shadow rays
/// ended a ten-thousandth of their length short of the light (0.3 mm here) and
/// passed the lower lamp to the upper one's hidden part; photons do not pass it,
/// and the batch pipeline's indirect layer read 11.7% darker than the path
/// tracer's (SPPM 10%). Shadow rays now end at the light's plane
/// (`pm_scene::Scene::transmittance_to`): -1.4% (SPPM +0.4%). Asserted: the
/// indirect layer's mean within 3% (the cause is `pm_light`'s test
/// `a_cover_just_in_front_of_a_light_blocks_it`, for every method).
#[test]
fn shadow_rays_through_a_fog_box_do_not_pass_a_lamp_in_front_of_another() {
    let (a, recipe) = generated_with(77777, 30, 48, pm_color::Layer::Indirect, 8, pm_methods::Method::Full, 1024);
    eprintln!("indirect: {a} ({:?})", recipe.lights);
    assert!(a.mean.abs() < 0.03, "indirect: {a} ({:?})", recipe.lights);
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer (1024 a pixel)
/// on seed 60606's scene 27 of the differential checker's generator: a two-sided
/// lamp 4 mm under the ceiling, whose light out of the gap above it makes the
/// ceiling round it far brighter than the rest of the room. The final gather
/// reads the nearest photon with a precomputed irradiance (a quarter of them),
/// and the sparse photons' larger cells carried the bright light into the dim
/// parts: the indirect layer +3.0% (every photon precomputed: +0.7%). Photons
/// between precomputed neighbours more than 1.5 apart now get their own
/// estimate (`pm_estimate::precompute`'s refinement, 7% more estimates here):
/// +1.9%. Asserted: the indirect layer's mean within 2.5%.
#[test]
fn the_final_gathers_lookup_keeps_bright_light_out_of_the_dim_parts() {
    let (a, recipe) = generated_with(60606, 27, 48, pm_color::Layer::Indirect, 8, pm_methods::Method::Full, 1024);
    eprintln!("indirect: {a} ({:?})", recipe.lights);
    assert!(a.mean.abs() < 0.025, "indirect: {a} ({:?})", recipe.lights);
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer (4096 a pixel)
/// on seed 23897's scene 2 of the differential checker's generator: two lamps, one
/// 8 cm under the other, and the lower wider, so that the upper one lights the
/// room past the lower one's edges: every wall is in its penumbra. The ratio
/// estimate of its visibility, from the pipeline's four light samples shared by
/// the two lamps, left one or two to a lamp and read the walls' direct light 2.1%
/// to 2.7% dark (with seeds 1 and 5); each lamp now takes its own four
/// (`pm_light::DirectLighting`): -0.3% (64 samples: +0.3%). Asserted: the direct
/// layer's mean within 1.2%.
#[test]
fn two_stacked_lamps_light_the_walls_as_the_path_tracer_does() {
    let (a, recipe) = generated_with(23897, 2, 48, pm_color::Layer::Direct, 8, pm_methods::Method::Full, 4096);
    eprintln!("direct: {a} ({:?})", recipe.lights);
    assert!(a.mean.abs() < 0.012, "direct: {a} ({:?})", recipe.lights);
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer (4096 a pixel)
/// on seed 23897's scene 9 of the differential checker's generator: a lamp 6 cm
/// under another hung 2 mm under the ceiling. The light between the two comes out
/// of the gap and makes a bright glow on the ceiling round the lamps, 70 W m^-2 at
/// their edge, 0.3 W m^-2 10 cm out. The irradiance cache's records out there had
/// radii of 12 cm and reached the edge (`pm_render::IrradianceCache`'s neighbour
/// clamping): the glow read 43% dark in 8 x 8 blocks and the indirect layer -2.9%
/// (-0.5% with no cache); now -0.9%. Asserted: its mean within 1.8% and every
/// block within 32%.
#[test]
fn the_irradiance_cache_keeps_the_glow_round_a_lamp() {
    let (a, recipe) = generated_with(23897, 9, 48, pm_color::Layer::Indirect, 8, pm_methods::Method::Full, 4096);
    eprintln!("indirect: {a} ({:?})", recipe.lights);
    assert!(a.mean.abs() < 0.018 && a.worst_block < 0.32, "indirect: {a} ({:?})", recipe.lights);
}

/// `cargo xtask run` on defaults (128 x 128) against the path tracer (1024 a pixel)
/// on seed 3's scene 19 of the differential checker's generator: a glass box
/// (ior 1.5, its base open, as the generator builds a box on the floor) standing on
/// the floor, a mirror sphere and a rough metal slab. The floor under the box is
/// immersed in the glass, and the radiance a photon estimate gives there is the
/// radiance inside it, which leaves the glass 1 / 1.5^2 as bright: the eye path
/// did not carry that factor (`pm_bsdf::BsdfSample::radiance_weight`), and the
/// specular layer was +135% at 24 x 24 (+100% at 256 x 256 in the blocks showing
/// the box's base; SPPM +120%). The path tracer agrees with Mitsuba 3 here (-0.4%, noise
/// 0.4%, without the metal slab, which Mitsuba cannot take). The pipeline's
/// specular layer before: +30% at 256 x 256; measured now +1.1% (16 x 16 blocks
/// 11% RMS: the box is small). Asserted: the specular layer's mean within 10%.
#[test]
fn a_floor_seen_through_a_glass_block_is_as_bright_as_the_path_tracer_sees_it() {
    let (a, recipe) = generated_on_defaults(3, 19, 128, pm_color::Layer::Specular, 16);
    eprintln!("specular: {a} ({:?})", recipe.objects);
    assert!(a.mean.abs() < 0.10, "specular: {a} ({:?})", recipe.objects);
}

/// SPPM through `cargo xtask run` on defaults (48 x 48) against the path tracer
/// (1024 a pixel) on seed 90210's scene 27 of the differential checker's
/// generator: a two-sided lamp 3 mm under the ceiling, a rough metal sphere, a
/// glass slab and two diffuse objects. The gap between the lamp's back and the
/// ceiling holds light far brighter than the room; an eye path reflected by the
/// sphere toward the ceiling beside the lamp made a visible point there that
/// gathered the gap's photons (same plane, same normal), and the sphere's
/// highlight in the indirect layer read 63% bright in its 8 x 8 block (the
/// checker's worst; 2,400% in the block of the lamp's own pixels). Visible points
/// and photons under a cover are now kept apart, and the boundary probes count
/// the other kind's part of the disc as off the surface: measured 6.5% in the
/// worst block. Asserted: every block of the indirect layer within 25%.
#[test]
fn sppm_keeps_the_light_trapped_above_a_lamp_to_itself() {
    let (a, recipe) = generated_with(90210, 27, 48, pm_color::Layer::Indirect, 8, pm_methods::Method::Sppm, 1024);
    eprintln!("sppm indirect: {a} ({:?})", recipe.lights);
    assert!(a.worst_block < 0.25, "sppm indirect: {a} ({:?})", recipe.lights);
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer (4096 a pixel:
/// a glass box's layer is noisy in it) on seed 90210's scene 2 of the differential
/// checker's generator: a glass box (its base open) that crosses the back wall, so
/// the part of the wall inside it is immersed in the glass, beside a diffuse box
/// through the same wall, a mirror slab and two lamps. The irradiance cache
/// interpolated the wall's records made outside the glass (lit by the room) into
/// its part inside (lit through the glass: caustics, which the cache does not
/// hold): Ward's tests cannot tell them apart on one plane. The specular layer
/// (what is seen through the glass) was +9.9% against the path tracer at 8192 a
/// pixel, in vertical stripes up to +20% in 8 x 8 blocks; a fresh final gather at
/// every point gave +2.4%. A lookup now reads only records its point sees
/// (`PhotonMapping::cached_irradiance`): +2.9%, worst block 11%. Asserted: the
/// specular layer's mean within 6%.
#[test]
fn the_irradiance_cache_does_not_read_records_across_a_glass_face() {
    let (a, recipe) = generated_with(90210, 2, 48, pm_color::Layer::Specular, 8, pm_methods::Method::Full, 4096);
    eprintln!("specular: {a} ({:?})", recipe.objects);
    assert!(a.mean.abs() < 0.06, "specular: {a} ({:?})", recipe.objects);
}

/// `cargo xtask run` on defaults (48 x 48) against the path tracer (1024 a pixel)
/// on the checker's rooms with rough metal (GGX, roughness 0.35): seed 16654's
/// scene 3 (a rough metal sphere, slab and box and a mirror slab under a lamp 4.4
/// mm below the ceiling) and seed 4282's scene 24 (a rough metal box beside mirror
/// ones). The batch pipeline read a glossy surface's indirect light as f0 / pi x
/// irradiance, as if it were diffuse: the metal box's front 30% dark; and a final
/// gather that hit the metal slab read it the same way, so the ceiling around the
/// lamp missed the lamp's blurred reflection (35% dark). Now the eye's hit
/// samples the lobe, and a gather ray that hits a glossy surface takes its direct
/// light and follows its lobe (`Bsdf::is_glossy`). The indirect layer's worst 8
/// x 8 block before: 35% and 31%; measured now 8.0% and 5.7% (means +1.4% and
/// +0.9%). SPPM gathered photons on the metal and now follows its lobe to the next
/// surface: on seed 16654's scene 32 (a rough metal box in an open room under the
/// sun, at 1/15 scale) its worst block went from 36% to 10.7%. Asserted: the batch pipeline's indirect
/// mean within 4% and every block within 20%; SPPM's blocks within 25%.
#[test]
fn rough_metal_reflects_the_room_as_the_path_tracer_sees_it() {
    for (seed, index) in [(16654, 3), (4282, 24)] {
        let (a, recipe) = generated_on_defaults(seed, index, 48, pm_color::Layer::Indirect, 8);
        eprintln!("{seed}/{index} indirect: {a} ({:?})", recipe.objects);
        assert!(a.mean.abs() < 0.04 && a.worst_block < 0.20, "{seed}/{index} indirect: {a} ({:?})", recipe.objects);
    }
    let (a, recipe) = generated_with(16654, 32, 48, pm_color::Layer::Indirect, 8, pm_methods::Method::Sppm, 1024);
    eprintln!("sppm 16654/32 indirect: {a} ({:?})", recipe.objects);
    assert!(a.worst_block < 0.25, "sppm 16654/32 indirect: {a} ({:?})", recipe.objects);
}

/// Seed 18930's scene 18 of the differential checker's generator: a glass box
/// (ior 1.5, a medium of its own) standing on the floor, its lower 0.36 m inside
/// a fog box that crosses the right wall. The medium outside each mesh was found
/// once, from one of its triangles: the glass box's was the fog, so a ray leaving
/// the box's top, 0.5 m above the fog, travelled through fog that is not there,
/// and the path tracer and every method disagreed on what the box shows (the
/// specular layer 26-32% darker in all four methods than in the path tracer,
/// each wrong in its own way). A mesh that stands in two media now finds the
/// medium where a ray leaves it (`pm_scene::Scene::medium_after`). Asserted:
/// leaving the box sideways below the fog's top is fog, above it is none, and
/// leaving its top is none.
#[test]
fn a_glass_box_standing_half_in_fog_leaves_its_rays_in_the_medium_outside_where_they_leave() {
    let dir = tempfile::tempdir().unwrap();
    let s = pm_scene::load(&crate::generated_scene(dir.path(), 18930, 18).0).unwrap();
    let bounds_of = |name: &str| {
        let o = s.objects.iter().find(|o| o.name.starts_with(name)).unwrap();
        pm_scene::bounds_of(&s.triangles[o.tris.start as usize..o.tris.end as usize])
    };
    let (glass, fog) = (bounds_of("object_2"), bounds_of("fog_box"));
    let inside = s.materials.iter().find(|m| m.name == "glass").unwrap().interior;
    assert!(inside.is_some() && glass.min.y < fog.max.y && fog.max.y < glass.max.y, "{glass:?} {fog:?}");
    let fog_id = s.materials.iter().find(|m| m.name == "fog").unwrap().interior;
    let c = glass.center();
    let leave = |from: glam::Vec3, d: glam::Vec3| {
        let hit = s.intersect(from, d, f32::INFINITY).unwrap();
        assert!(d.dot(hit.ng) > 0.0 && s.material(&hit).name == "glass", "{hit:?}");
        s.medium_after(&hit, d, inside)
    };
    let low = glam::Vec3::new(c.x, glass.min.y + 0.5 * (fog.max.y - glass.min.y), c.z);
    let high = glam::Vec3::new(c.x, fog.max.y + 0.5 * (glass.max.y - fog.max.y), c.z);
    assert_eq!(leave(low, glam::Vec3::X), fog_id, "leaving the side in the fog");
    assert_eq!(leave(high, glam::Vec3::X), None, "leaving the side above the fog");
    assert_eq!(leave(high, glam::Vec3::Y), None, "leaving the top");
}

/// The same scene through `cargo xtask run` on defaults (48 x 48) against the
/// path tracer (1024 a pixel): what the glass box shows, the specular layer, was
/// 32% darker than the path tracer's (both wrong); now within 2.7%. Asserted: the
/// mean within 6% and every block within 30%. One block, at the glass box's
/// edge, is the noisiest of the layer: against a 4096-path reference, over the
/// pipeline's seeds 1 to 4 it is 6.6-25.7% off with lights chosen by the light
/// tree, 6.2-57.8% with lights chosen by power (stop 75; the two path tracers
/// agree there within 0.2% at 4096 paths). The bound of 20% held for seed 1
/// with power (12%) and not with the tree (20.4%).
#[test]
fn what_a_glass_box_half_in_fog_shows_agrees_with_the_path_tracer() {
    let (a, recipe) = generated_with(18930, 18, 48, pm_color::Layer::Specular, 8, pm_methods::Method::Full, 1024);
    eprintln!("specular: {a} ({:?})", recipe.objects);
    assert!(a.mean.abs() < 0.06 && a.worst_block < 0.30, "specular: {a} ({:?})", recipe.objects);
}
