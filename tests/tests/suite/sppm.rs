//! Stochastic progressive photon mapping (issue 39): the batch pipeline's
//! consistent limit, against the furnace's closed form and the path tracer.

use pm_sppm::{Sppm, SppmParams};
use pm_tests::load_scene;

/// The shared render settings these tests use: one light sample a visible point.
fn one_light_sample() -> pm_render::RenderParams {
    pm_render::RenderParams { light_samples: 1, ..Default::default() }
}

/// `passes` passes of SPPM over `scene` at `w` x `h` with `photons` photon paths a
/// pass and `seed`: the image's pixels.
fn sppm(scene: &pm_scene::Scene, w: u32, h: u32, passes: u32, photons: u64, seed: u64) -> pm_render::Image {
    let params = SppmParams { passes, photons_per_pass: photons, ..Default::default() };
    let camera = scene.camera.clone().unwrap();
    let mut s = Sppm::new(scene, w, h, params, seed, &one_light_sample()).unwrap();
    for _ in 0..passes {
        s.pass(&camera);
    }
    s.image()
}

/// The furnace (a closed sphere of albedo 0.8 and emission 1 seen from inside:
/// radiance 5 everywhere): after 64 passes of 20,000 photon paths at 8 x 8 the
/// mean is 5 within 1% (measured 4.974) and the pixels' RMS spread about it is
/// under 5% (measured 3.0%, of one light sample and about 24 photons a pass).
/// Emission and direct light (1 + 0.8) come from the eye paths, the other 3.2
/// from the photons.
#[test]
fn sppm_furnace_is_five() {
    let scene = load_scene("furnace.gltf");
    let img = sppm(&scene, 8, 8, 64, 20_000, 1);
    let (mean, rms, worst) = pm_tests::against_constant(img.total(), 5.0);
    eprintln!("SPPM furnace: mean {mean:.4} (exact 5), RMS {:.2}%, worst {:.2}%", 100.0 * rms, 100.0 * worst);
    assert!((mean / 5.0 - 1.0).abs() < 0.01, "mean {mean}");
    assert!(rms < 0.05, "pixels {:.1}% RMS apart", 100.0 * rms);
}

/// The same seed and pass count give the same image whatever the thread count.
#[test]
fn sppm_is_deterministic_across_thread_counts() {
    let scene = load_scene("cornell_spheres.gltf");
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| sppm(&scene, 16, 16, 4, 5_000, 3))
            .total()
            .iter()
            .flat_map(|p| p.to_array())
            .map(f32::to_bits)
            .collect::<Vec<_>>()
    };
    assert_eq!(run(1), run(3));
}

/// Consistency (issue 39's test): on cornell_boxes at 64 x 64, against a
/// path-traced reference of 4,096 paths a pixel (two halves, its own noise taken
/// out), SPPM with 4 boundary probes (20,000 photon paths a pass, 8 seeds) has
/// an error that falls as the passes go 4, 16, 64, 256 (measured 32.1%, 18.4%,
/// 11.6%, 7.2%) and a bias (the seeds' mean against the reference, both noises
/// taken out, as the accuracy study measures it) under 0.5% after 256 passes
/// (measured 0.0%: below what 8 seeds resolve, about 0.3%), where the batch
/// pipeline's (defaults, 100,000 photons, 2 seeds) stays at its 4.5%. Without
/// the probes, Hachisuka's estimate divides by pi r^2 where walls and edges cut
/// the disc and keeps a bias first order in r along every edge of the room
/// (1.4% after 256 passes, falling as passes^(-1/6)); 4 seeds show it is more
/// than twice the probed one's. At every pass count the noise the render
/// estimates from its own passes is within 30% of the noise the seeds measure.
#[test]
fn sppm_error_and_bias_fall_with_passes() {
    use pm_image::accuracy;
    let scene = load_scene("cornell_boxes.gltf");
    let camera = scene.camera.clone().unwrap();
    let (w, h) = (64u32, 64u32);
    let path = pm_render::PathTracer::new(&scene).unwrap();
    let half = |seed: u64| {
        let film = pm_render::Film { width: w, height: h, spp: 2048, contrast: 0.0, seed, pixel_centres: false };
        pm_render::render_region(&camera, &film, film.rect(), &path, false, &|_, _| {}).unwrap().0.total().to_vec()
    };
    let (a, b) = (half(101), half(102));
    let keep = accuracy::keep_mask_of_halves(&a, &b, w as usize, h as usize, None);
    let (reference, var) = accuracy::reference_from_halves(&a, &b, &keep);
    // Runs of `seeds` seeds with `probes` boundary probes, split after 4, 16, 64
    // and 256 passes: (passes, split, estimated noise of seed 1's render).
    let study = |probes: u32, seeds: u64| {
        let params =
            SppmParams { passes: 256, photons_per_pass: 20_000, sppm_boundary_probes: probes, ..Default::default() };
        let mut runs: Vec<Sppm> =
            (1..=seeds).map(|seed| Sppm::new(&scene, w, h, params, seed, &one_light_sample()).unwrap()).collect();
        let mut out = Vec::new();
        for passes in 1..=256u32 {
            for r in &mut runs {
                r.pass(&camera);
            }
            if [4, 16, 64, 256].contains(&passes) {
                let images: Vec<Vec<glam::Vec3>> = runs.iter().map(|r| r.image().total().to_vec()).collect();
                let refs: Vec<&[glam::Vec3]> = images.iter().map(Vec::as_slice).collect();
                let s = accuracy::split(&refs, &reference, var, &keep);
                let own = accuracy::keep_mask(&images[0], w as usize, h as usize, None);
                let estimated = accuracy::noise_of_variances(&images[0], &runs[0].variances().unwrap(), &own);
                eprintln!(
                    "SPPM, {probes} probes, {passes} passes: error {:.2}% = bias {:.2}% (+) noise {:.2}% (estimated {:.2}%)",
                    100.0 * s.error,
                    100.0 * s.bias,
                    100.0 * s.noise,
                    100.0 * estimated
                );
                out.push((passes, s, estimated));
            }
        }
        out
    };
    let probed = study(4, 8);
    for pair in probed.windows(2) {
        assert!(pair[1].1.error < pair[0].1.error, "error {:?} after {:?}", pair[1], pair[0]);
    }
    for (passes, s, estimated) in &probed {
        assert!((estimated / s.noise - 1.0).abs() < 0.3, "{passes} passes: noise {} estimated as {estimated}", s.noise);
    }
    let bias = probed[3].1.bias;
    assert!(bias < 0.005, "SPPM's bias after 256 passes: {bias}");
    let plain = study(0, 4)[3].1.bias;
    assert!(plain > 2.0 * bias.max(0.003), "without probes the bias is {plain}, with them {bias}");
    let batch: Vec<Vec<glam::Vec3>> = (1..=2)
        .map(|seed| {
            let maps = pm_tests::photon_maps_seeded(&scene, 100_000, 0, 0.25, seed);
            pm_tests::render(&scene, &maps, &pm_tests::render_params(pm_methods::Method::Full, w, h)).0.total().to_vec()
        })
        .collect();
    let refs: Vec<&[glam::Vec3]> = batch.iter().map(Vec::as_slice).collect();
    let s = accuracy::split(&refs, &reference, var, &keep);
    eprintln!(
        "batch pipeline: error {:.2}% = bias {:.2}% (+) noise {:.2}%",
        100.0 * s.error,
        100.0 * s.bias,
        100.0 * s.noise
    );
    assert!(s.bias > 0.02, "the batch pipeline's bias {} (SPPM's {bias})", s.bias);
}

/// `[render] mode = "sppm"` in pipeline.toml: `cargo xtask run` runs
/// photon-render alone (no maps to trace), and its image's mean agrees with the
/// path tracer's through the same runner within 5% (24 x 24, 32 passes of
/// 20,000 photon paths against 256 paths a pixel).
#[test]
fn the_runner_renders_sppm_without_maps() {
    let dir = tempfile::tempdir().unwrap();
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let bins = pm_tests::bins();
    let mean = |mode: pm_methods::Method, name: &str| {
        let p = pm_tests::small_pipeline(dir.path(), "cornell_boxes.gltf", "\"auto\"", 256, name);
        pm_tests::edit_pipeline(&p, |c| {
            c.mode = mode;
            (c.sppm.passes, c.sppm.photons_per_pass) = (32, 20_000);
        });
        let out = dir.path().join(name);
        let args = pm_runner::run::RunArgs { pipeline: Some(p), out: Some(out.clone()), ..Default::default() };
        let ran = pm_runner::run::run_with(&args, &root, &bins).unwrap();
        let steps: Vec<&str> = ran.iter().filter(|o| o.ran).map(|o| o.step.as_str()).collect();
        assert_eq!(steps, ["photon-render"], "{name}");
        let img = pm_image::read_exr(&out.join("image.exr")).unwrap();
        let px = img.total().unwrap();
        px.iter().map(|p| p.element_sum() as f64).sum::<f64>() / (3 * px.len()) as f64
    };
    let (s, p) = (mean(pm_methods::Method::Sppm, "sppm"), mean(pm_methods::Method::Path, "path"));
    eprintln!("runner: SPPM mean {s:.4}, path tracer {p:.4}");
    assert!((s / p - 1.0).abs() < 0.05, "SPPM {s} vs path {p}");
}
