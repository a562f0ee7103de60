//! Cross-stage and analytic-scene tests of the photon-mapping pipeline. The tests
//! live in `tests/tests/suite/`; this library holds the helpers they share.

use pm_format::{CompactIrrPhoton, FullPhoton, PhotonRecord};
use pm_methods::{Input, Method, Settings};
use pm_photon::{Budget, LightSelector, MapPass, TraceConfig};
use pm_render::RenderParams;
use pm_scene::Scene;
use std::path::{Path, PathBuf};

/// `image` against `reference` (both `width` wide) in 8 x 8 blocks, leaving out
/// the reference's pixels above radiance 8 [W sr^-1 m^-2] and their neighbours:
/// the Blender rooms' ceiling light (12), which no renderer draws alike at its
/// edges; an emissive panel (6 at most) is kept.
pub fn agreement_off_the_light(
    image: &[glam::Vec3],
    reference: &[glam::Vec3],
    width: usize,
) -> pm_image::accuracy::Agreement {
    let bright: Vec<bool> = reference.iter().map(|p| p.max_element() > 8.0).collect();
    let keep = pm_image::accuracy::left_out_with_neighbours(&bright, width, reference.len() / width);
    pm_image::accuracy::agreement(image, reference, width, &keep, 8)
}

/// Path of a scene in the repository's `scenes/` folder.
pub fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name)
}

/// The repository's pipeline.toml made small and fast, written to `dir/NAME.toml`:
/// scene `scene` from `scenes/`, `effects` (a TOML value), 24 x 24 pixels, `spp`,
/// 20,000 global and 2,000 caustic photons, 32 gather rays.
pub fn small_pipeline(dir: &std::path::Path, scene: &str, effects: &str, spp: u32, name: &str) -> PathBuf {
    #[derive(serde::Deserialize)]
    struct Effects {
        effects: pm_pipeline::EffectsCfg,
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut p = pm_pipeline::Pipeline::load(&root.join("pipeline.toml")).unwrap();
    p.scene = root.join("scenes").join(scene);
    p.effects = toml::from_str::<Effects>(&format!("effects = {effects}")).unwrap().effects;
    p.trace.global_photons = 20_000;
    p.trace.caustic_photons = 2_000;
    (p.render.width, p.render.height, p.render.spp, p.render.gather_rays) = (24, 24, spp, 32);
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, p.to_toml()).unwrap();
    path
}

/// Change the pipeline file at `path` by field: read it, apply `edit`, write it back.
pub fn edit_pipeline(path: &std::path::Path, edit: impl FnOnce(&mut pm_pipeline::Pipeline)) {
    let mut p = pm_pipeline::Pipeline::load(path).unwrap();
    edit(&mut p);
    std::fs::write(path, p.to_toml()).unwrap();
}

/// The folder of the binaries the workspace test build made (this test's
/// `target/<profile>`, from `target/<profile>/deps/<test>`).
pub fn bin_dir() -> PathBuf {
    std::env::current_exe().unwrap().parent().unwrap().parent().unwrap().to_owned()
}

/// What a user runs against the independent estimator: `cargo xtask run` on the
/// repository's pipeline.toml with only the scene (from `scenes/`, or a path
/// relative to it), the image
/// size (`size` x `size`) and what `edit` changes, into `dir/NAME`; and
/// `photon-render --mode path` at `spp` a pixel with the same scene options.
/// Returns the pipeline's output folder, its image and the path tracer's.
pub fn defaults_and_path_tracer(
    dir: &std::path::Path,
    scene: &str,
    size: u32,
    spp: u32,
    edit: impl FnOnce(&mut pm_pipeline::Pipeline),
) -> (PathBuf, pm_image::Layers, pm_image::Layers) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let name = Path::new(scene).file_stem().unwrap().to_str().unwrap();
    let mut p = pm_pipeline::Pipeline::load(&root.join("pipeline.toml")).unwrap();
    p.scene = scene_path(scene);
    (p.render.width, p.render.height) = (size, size);
    edit(&mut p);
    let file = dir.join(format!("{name}.toml"));
    std::fs::write(&file, p.to_toml()).unwrap();
    let out = dir.join(name);
    let args = pm_runner::run::RunArgs { pipeline: Some(file), out: Some(out.clone()), ..Default::default() };
    pm_runner::run::run_with(&args, &root, &bins()).unwrap();
    let path = out.join("path.exr");
    let size = size.to_string();
    let o = std::process::Command::new(bins().path("photon-render"))
        .args(["--scene", p.scene.to_str().unwrap(), "--mode", "path", "--spp", &spp.to_string()])
        .args(["--width", &size, "--height", &size, "--out", path.to_str().unwrap()])
        .args(p.scene_options.to_args())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (ours, reference) = (pm_image::read_exr(&out.join("image.exr")).unwrap(), pm_image::read_exr(&path).unwrap());
    (out, ours, reference)
}

/// The stage binaries of this test build, with no time limit.
pub fn bins() -> pm_runner::bins::Bins {
    pm_runner::bins::Bins::at(bin_dir())
}

/// Load a scene from `scenes/`, lit as the stages light it by default (the
/// environment its glTF extras name).
pub fn load_scene(name: &str) -> Scene {
    let path = scene_path(name);
    let mut scene = pm_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    pm_stage::light_scene(&mut scene, &path, &pm_stage::SceneOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    scene
}

/// Trace a global map with at least `stored` photons and balance it into a kd-tree
/// of 23-byte records, as stages 1 and 2 do.
pub fn global_tree(scene: &Scene, stored: u64, seed: u64) -> Vec<CompactIrrPhoton> {
    let cfg = TraceConfig {
        pass: MapPass::Global,
        budget: Budget::Stored { target: stored, cap: stored * 1000 },
        seed,
        selector: LightSelector::new(scene, &[]).unwrap(),
    };
    let photons = pm_photon::trace(scene, &cfg, &|_| {}).unwrap().photons;
    let records: Vec<CompactIrrPhoton> = photons.iter().map(CompactIrrPhoton::encode).collect();
    pm_kdtree::balance(&records)
}

/// Stages 1-3 in memory: a global kd-tree map with precomputed irradiance at
/// `fraction` of its photons (k = 50), and a caustic kd-tree map (empty when the
/// scene has no specular surface).
pub fn photon_maps(
    scene: &Scene,
    global: u64,
    caustic: u64,
    fraction: f64,
) -> (Vec<CompactIrrPhoton>, Vec<FullPhoton>) {
    photon_maps_seeded(scene, global, caustic, fraction, 1)
}

/// [`photon_maps`] with the global map traced with `seed` and the caustic map
/// with `seed + 1` (`photon_maps` is seed 1).
pub fn photon_maps_seeded(
    scene: &Scene,
    global: u64,
    caustic: u64,
    fraction: f64,
    seed: u64,
) -> (Vec<CompactIrrPhoton>, Vec<FullPhoton>) {
    let mut g = global_tree(scene, global, seed);
    let params = pm_estimate::KnnParams {
        k: 50,
        max_d2: (0.1 * scene.bounds.diagonal()).powi(2),
        filter: pm_estimate::Filter::None,
    };
    let surfaces = pm_render::SceneSurfaces { scene, reach: params.max_d2.sqrt() };
    let refine = pm_estimate::IrradianceParams::default().refine_ratio;
    pm_estimate::precompute(&mut g, &params, (fraction, refine), Some(&surfaces), &|_| {});
    let cfg = TraceConfig {
        pass: MapPass::Caustic,
        budget: Budget::Stored { target: caustic, cap: caustic * 1000 },
        seed: seed + 1,
        selector: LightSelector::new(scene, &[]).unwrap(),
    };
    let c: Vec<FullPhoton> =
        pm_photon::trace(scene, &cfg, &|_| {}).unwrap().photons.iter().map(FullPhoton::encode).collect();
    (g, pm_kdtree::balance(&c))
}

/// The renderer's defaults (`Settings::default()`, as `photon-render` has them)
/// with another method and size.
pub fn render_params(mode: Method, width: u32, height: u32) -> Settings {
    Settings { mode, render: RenderParams { width, height, ..Default::default() }, ..Default::default() }
}

/// The photon-map integrator over the maps of [`photon_maps`], with its
/// irradiance cache made by the prepass when the settings call for one (seed 1,
/// as `photon-render` does), handed to `f`.
pub fn with_photon_mapping<R>(
    scene: &Scene,
    maps: &(Vec<CompactIrrPhoton>, Vec<FullPhoton>),
    settings: &Settings,
    f: impl FnOnce(pm_render::PhotonMapping<CompactIrrPhoton>) -> R,
) -> R {
    let p = &settings.render;
    let irr = pm_render::irradiance_subset(&maps.0);
    let m = pm_render::Maps {
        global: Some(pm_kdtree::KdTree::new(&maps.0)),
        irradiance: Some(pm_kdtree::KdTree::new(&irr)),
        caustic: (!maps.1.is_empty()).then(|| pm_kdtree::KdTree::new(&maps.1)),
        volume: None,
    };
    let camera = scene.camera.as_ref().expect("test scenes have a camera");
    let mut pm = pm_render::PhotonMapping::new(scene, m, p, true).unwrap();
    if pm.wants_cache() && settings.mode.needs().cache {
        let cache = pm_render::IrradianceCache::prepass(&pm, camera, &p.film(1));
        pm = pm.with_cache(cache);
    }
    f(pm)
}

/// Render the whole image by `p.mode` (seed 1): from the maps of [`photon_maps`],
/// running the irradiance-cache prepass first when the settings call for it, as
/// `photon-render` does, or from the scene alone for a method that traces its own
/// paths.
pub fn render(
    scene: &Scene,
    maps: &(Vec<CompactIrrPhoton>, Vec<FullPhoton>),
    p: &Settings,
) -> (pm_render::Image, pm_render::RenderStats) {
    render_seeded(scene, maps, p, 1)
}

/// [`render`] with the film's seed `seed` (the cache, when made, with seed 1).
pub fn render_seeded(
    scene: &Scene,
    maps: &(Vec<CompactIrrPhoton>, Vec<FullPhoton>),
    p: &Settings,
    seed: u64,
) -> (pm_render::Image, pm_render::RenderStats) {
    let camera = scene.camera.as_ref().expect("test scenes have a camera");
    let film = p.render.film(seed);
    let view = pm_render::View { camera, film: &film, rect: film.rect() };
    let r = if p.mode.needs().photon_maps {
        with_photon_mapping(scene, maps, p, |pm| {
            pm_methods::render(p, Input::PhotonMaps(Box::new(pm)), view, None, &|_, _| {})
        })
    } else {
        pm_methods::render(p, Input::<CompactIrrPhoton>::Scene(scene), view, None, &|_, _| {})
    }
    .unwrap();
    (r.image, r.stats)
}

/// An inward-facing closed box [lo, hi] as quads (two triangles each) of material `m`.
pub fn closed_box(out: &mut Vec<pm_scene::Triangle>, lo: glam::Vec3, hi: glam::Vec3, m: u32) {
    use glam::Vec3;
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let (a, b) = (lo, hi);
    let quads = [
        [v(a.x, a.y, a.z), v(a.x, a.y, b.z), v(b.x, a.y, b.z), v(b.x, a.y, a.z)], // floor, +y
        [v(a.x, b.y, a.z), v(b.x, b.y, a.z), v(b.x, b.y, b.z), v(a.x, b.y, b.z)], // ceiling, -y
        [v(a.x, a.y, a.z), v(b.x, a.y, a.z), v(b.x, b.y, a.z), v(a.x, b.y, a.z)], // back, +z
        [v(a.x, a.y, b.z), v(a.x, b.y, b.z), v(b.x, b.y, b.z), v(b.x, a.y, b.z)], // front, -z
        [v(a.x, a.y, a.z), v(a.x, b.y, a.z), v(a.x, b.y, b.z), v(a.x, a.y, b.z)], // left, +x
        [v(b.x, a.y, a.z), v(b.x, a.y, b.z), v(b.x, b.y, b.z), v(b.x, b.y, a.z)], // right, -x
    ];
    for q in quads {
        out.push(pm_scene::Triangle::new([q[0], q[1], q[2]], m).unwrap());
        out.push(pm_scene::Triangle::new([q[0], q[2], q[3]], m).unwrap());
    }
}

/// A material of the given model, emission and name.
pub fn material(name: &str, bsdf: pm_bsdf::Bsdf, emission: f32) -> pm_scene::Material {
    pm_scene::Material::new(name, bsdf, glam::Vec3::splat(emission))
}

/// A UV sphere (outward faces unless `inward`) of material `m`.
pub fn sphere(out: &mut Vec<pm_scene::Triangle>, c: glam::Vec3, r: f32, inward: bool, m: u32) {
    let (seg, rings) = (32, 16);
    let at = |i: u32, j: u32| {
        let (th, ph) =
            (std::f32::consts::PI * j as f32 / rings as f32, 2.0 * std::f32::consts::PI * i as f32 / seg as f32);
        c + r * glam::Vec3::new(th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin())
    };
    for j in 0..rings {
        for i in 0..seg {
            let (a, b, cc, d) = (at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
            for t in [[a, b, cc], [a, cc, d]] {
                let t = if inward { [t[0], t[2], t[1]] } else { t };
                if let Some(tri) = pm_scene::Triangle::new(t, m) {
                    out.push(tri);
                }
            }
        }
    }
}

/// A square perspective camera at `position` looking straight down (-y), image up
/// toward -z, of vertical field of view `yfov` [radians] ([`camera`] cannot look
/// along its up axis).
pub fn camera_looking_down(position: glam::Vec3, yfov: f32) -> pm_scene::Camera {
    use glam::Vec3;
    pm_scene::Camera { position, forward: Vec3::NEG_Y, up: Vec3::NEG_Z, right: Vec3::X, yfov, aspect: Some(1.0) }
}

/// A perspective camera at `position` looking at `target` (y up), 60 degrees.
pub fn camera(position: glam::Vec3, target: glam::Vec3) -> pm_scene::Camera {
    let forward = (target - position).normalize();
    let right = forward.cross(glam::Vec3::Y).normalize();
    pm_scene::Camera { position, forward, up: right.cross(forward), right, yfov: 1.05, aspect: None }
}

/// Each component layer of a photon-map image against the path tracer's same layer
/// (means over the image, all channels): direct within 3%, caustic 15%, indirect 8%,
/// specular 8%, total 3% (the tolerances `components_agree_with_the_path_tracers_
/// components` justifies). Prints each, naming `scene`.
pub fn assert_components_agree(scene: &str, full: &pm_render::Image, path: &pm_render::Image) {
    assert_components_agree_where(scene, full, path, &vec![true; full.total().len()]);
}

/// [`assert_components_agree`] over the pixels `keep` marks.
pub fn assert_components_agree_where(scene: &str, full: &pm_render::Image, path: &pm_render::Image, keep: &[bool]) {
    use pm_color::Layer;
    let mean = |img: &pm_render::Image, layer: Option<Layer>| {
        let px = img.total_or_layer(layer);
        let kept = px.iter().zip(keep).filter(|(_, k)| **k);
        kept.clone().map(|(p, _)| p.element_sum() as f64).sum::<f64>() / (3 * kept.count()).max(1) as f64
    };
    let tolerances = [
        (Some(Layer::Direct), 0.03),
        (Some(Layer::Caustic), 0.15),
        (Some(Layer::Indirect), 0.08),
        (Some(Layer::Specular), 0.08),
        (None, 0.03),
    ];
    for (which, tol) in tolerances {
        let layer = pm_color::layer_name(which);
        let (f, p) = (mean(full, which), mean(path, which));
        if f == 0.0 && p == 0.0 {
            eprintln!("{scene} {layer}: none in either");
            continue;
        }
        eprintln!("{scene} {layer}: full {f:.5}, path {p:.5} ({:+.2}%)", 100.0 * (f / p - 1.0));
        assert!((f / p - 1.0).abs() < tol, "{scene} {layer}: full {f} vs path {p}");
    }
}

/// Mean, relative RMS error and worst relative error of the red channel of `px`
/// against a constant `want` (the furnace tests' figures).
pub fn against_constant(px: &[glam::Vec3], want: f64) -> (f64, f64, f64) {
    let n = px.len().max(1) as f64;
    let mean = px.iter().map(|p| p.x as f64).sum::<f64>() / n;
    let rms = (px.iter().map(|p| (p.x as f64 / want - 1.0).powi(2)).sum::<f64>() / n).sqrt();
    let worst = px.iter().map(|p| (p.x as f64 / want - 1.0).abs()).fold(0.0, f64::max);
    (mean, rms, worst)
}
