//! `cargo xtask tradeoff`: what accuracy costs in time. Renders a converged
//! path-traced reference as two independent halves (their difference measures the
//! reference's own noise), then sweeps one setting at a time from the defaults
//! (photon counts, k, precompute fraction, gather rays, irradiance-cache accuracy,
//! light samples, samples per pixel, lookup, record layout, path tracing at
//! several sample counts and progressive photon mapping at several pass counts;
//! in scenes with scattering media also volume photons, the volume estimate and
//! its k), each with several seeds, timing every stage. Errors
//! leave out the light's pixels and their neighbours and are split into bias and
//! noise ([`xtask::accuracy`]) for the image and for each layer (direct, caustic,
//! indirect, specular, and volume in scenes with media). Writes results.csv, results.md, plot (error against time,
//! lines per setting, the Pareto front), bias_noise (which setting buys which),
//! layers (per-layer panels) as SVG and PNG, and error_map.png.

use anyhow::{Context, Result, bail};
use pm_color::Layer;
use pm_estimate::IrradianceParams;
use pm_image::accuracy::{self, Split};
use pm_methods::live::{LiveMethod, LiveParams};
use pm_methods::{Method, Settings};
use pm_photon::{RecordLayout, TraceParams};
use pm_pipeline::Quality;
use pm_render::{Lookup, RenderParams};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use xtask::plot::{self, Shape};
use xtask::stages::{self, Bins};

/// Options of `cargo xtask tradeoff`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene (glTF 2.0).
    #[arg(long, default_value = "scenes/cornell_spheres.gltf")]
    scene: PathBuf,
    /// Output folder [default: out/tradeoff/<scene name>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Image width and height [pixels].
    #[arg(long, default_value_t = 256)]
    size: u32,
    /// Renders per setting, each with its own seed (bias and noise need two or more).
    #[arg(long, default_value_t = 3)]
    seeds: u64,
    /// Paths per pixel of the path-traced reference (in two halves with different
    /// seeds); cached in the output folder by scene content, size and count.
    #[arg(long, default_value_t = 16384)]
    reference_spp: u32,
    /// Copy results.csv, results.md, the plots and the error map here.
    #[arg(long)]
    docs: Option<PathBuf>,
    /// Render nothing: rewrite results.md, front.json, the plots and the error map
    /// from the output folder's results.csv, cached reference and images.
    #[arg(long)]
    replot: bool,
    /// Only these axes of the sweep besides the defaults, comma-separated by name
    /// ("path", "light samples", ...; all when not given): a larger image's
    /// equal-error comparison needs only `--axes path`.
    #[arg(long, value_delimiter = ',')]
    axes: Vec<String>,
    /// A Python with Mitsuba 3 (`mitsuba`, `drjit`; ../shared/CRATES.md): adds the
    /// peer's path tracer as rows of its own (axis "peer": 16, 64 and 256 paths a
    /// pixel, render time only, after a warm-up render) and, for every row, the
    /// time Mitsuba takes to reach that row's error over the row's own time (issue
    /// 40). Needs a scene `cargo xtask peer` can translate.
    #[arg(long)]
    peer: Option<String>,
    /// Mitsuba variant of the peer rows.
    #[arg(long, default_value = "llvm_ad_rgb")]
    peer_variant: String,
    /// A mesh of the scene that is a portal of its environment (every stage gets
    /// `--portal`; the reference too, which converges to the same image).
    #[arg(long)]
    portal: Vec<String>,
    /// Also leave out pixels brighter than this many times the reference's mean
    /// (and their neighbours): a sun's glints in mirrors and glass, sub-pixel and
    /// thousands of times the mean, otherwise decide every row's error (on
    /// hdri_spheres, 64% for every photon-map setting but the pixel sample count).
    #[arg(long)]
    mask_above_mean: Option<f32>,
}

/// One point of the sweep: the stage parameters it runs with.
#[derive(Clone, Debug)]
struct Setting {
    axis: &'static str,
    label: String,
    trace: TraceParams,
    irradiance: IrradianceParams,
    /// The method and its settings.
    render: Settings,
    /// A real-time row instead: photon-live's settings (its frame of the scene's
    /// camera after the buffer filled, timed as its mean frame time).
    live: Option<LiveParams>,
    /// A peer row instead: Mitsuba's path tracer at this many paths a pixel.
    peer_spp: Option<u32>,
}

impl Setting {
    /// Photon maps are shared by settings that differ only in rendering.
    fn maps_key(&self, seed: u64) -> String {
        let t = &self.trace;
        let i = &self.irradiance;
        format!(
            "g{}-c{}-v{}-{}-k{}-f{}-s{seed}",
            t.global_photons, t.caustic_photons, t.volume_photons, t.layout, i.k, i.fraction
        )
    }
}

/// What is compared: the image (the total, `None`) first, then each layer (the
/// volume layer only in scenes with scattering media: elsewhere its split is
/// empty and no column shows it).
const LAYERS: [Option<Layer>; 6] = [
    None,
    Some(Layer::Direct),
    Some(Layer::Caustic),
    Some(Layer::Indirect),
    Some(Layer::Specular),
    Some(Layer::Volume),
];

/// One setting's measurements.
struct Row {
    setting: Setting,
    /// trace, sort, precompute, render [s], means over the seeds.
    times: [f64; 4],
    /// Per layer of [`LAYERS`].
    splits: [Split; 6],
    /// SSIM of the first seed's image.
    ssim: f64,
}

impl Row {
    fn total(&self) -> f64 {
        self.times.iter().sum()
    }
}

/// The defaults (pipeline.toml's values at `size`), then one setting at a time;
/// `base_diagonal` is the scene's bounding-box diagonal [m].
fn sweep(base: &pm_pipeline::Pipeline, size: u32, base_diagonal: f32, media: bool) -> Vec<Setting> {
    let mut render = base.settings();
    render.render.width = size;
    render.render.height = size;
    let d = Setting {
        axis: "default",
        label: "defaults".into(),
        trace: base.trace.clone(),
        irradiance: base.irradiance.clone(),
        render,
        live: None,
        peer_spp: None,
    };
    let mut v = vec![d.clone()];
    let with = |axis: &'static str, label: String, f: &dyn Fn(&mut Setting)| {
        let mut s = d.clone();
        s.axis = axis;
        s.label = label;
        f(&mut s);
        s
    };
    for g in [25_000u64, 100_000, 1_600_000] {
        v.push(with("global photons", format!("global {g}"), &|s| s.trace.global_photons = g));
    }
    for c in [5_000u64, 140_000] {
        v.push(with("caustic photons", format!("caustic {c}"), &|s| s.trace.caustic_photons = c));
    }
    for k in [25usize, 100, 200, 400] {
        v.push(with("k", format!("k {k}"), &|s| {
            s.irradiance.k = k;
            s.render.render.k = k;
        }));
    }
    for f in [1.0f64, 0.0625] {
        v.push(with("precompute fraction", format!("fraction {f}"), &|s| s.irradiance.fraction = f));
    }
    for r in [64u32, 128, 256, 1024] {
        v.push(with("gather rays", format!("gather rays {r}"), &|s| s.render.render.gather_rays = r));
    }
    for a in [0.15f32, 0.6] {
        v.push(with("cache accuracy", format!("cache a {a}"), &|s| s.render.render.icache_accuracy = a));
    }
    for n in [1u32, 16] {
        v.push(with("light samples", format!("light samples {n}"), &|s| s.render.render.light_samples = n));
    }
    for spp in [4u32, 64] {
        v.push(with("max spp", format!("max spp {spp}"), &|s| s.render.render.spp = spp));
    }
    v.push(with("lookup", "exact lookup".into(), &|s| s.render.render.gather_lookup = Lookup::Exact));
    // Participating media (issue 38): volume photons, the estimate along eye rays
    // (the beam estimate by default, or the ray march) and its k.
    if media {
        for n in [50_000u64, 800_000] {
            v.push(with("volume photons", format!("volume {n}"), &|s| s.trace.volume_photons = n));
        }
        v.push(with("volume estimate", "ray march".into(), &|s| {
            s.render.render.volume_estimate = pm_render::VolumeEstimate::RayMarch
        }));
        for k in [20usize, 150] {
            v.push(with("volume k", format!("volume k {k}"), &|s| s.render.render.volume_k = k));
        }
        // Single scattering's light samples per eye ray in a medium: its noise is
        // most of a thin fog's error.
        for n in [1u32, 16] {
            v.push(with("volume light samples", format!("volume light samples {n}"), &|s| {
                s.render.render.volume_light_samples = n
            }));
        }
    }
    v.push(with("records", "full-precision records".into(), &|s| s.trace.layout = RecordLayout::Full));
    for spp in [16u32, 64, 256, 1024] {
        v.push(with("path", format!("path {spp} spp"), &|s| {
            s.render.mode = Method::Path;
            s.render.render.spp = spp
        }));
    }
    // Progressive photon mapping (issue 39): passes of the default photons a pass
    // with the default boundary probes; its bias shrinks with the radius, so long
    // runs pass the batch pipeline. Without probes (Hachisuka's pi r^2), the edge
    // bias stays.
    for passes in [16u32, 64, 256, 1024] {
        v.push(with("sppm", format!("sppm {passes} passes"), &|s| {
            s.render.mode = Method::Sppm;
            s.render.sppm.passes = passes
        }));
    }
    for passes in [16u32, 64, 256, 1024] {
        v.push(with("sppm no probes", format!("sppm {passes} passes no probes"), &|s| {
            s.render.mode = Method::Sppm;
            (s.render.sppm.passes, s.render.sppm.sppm_boundary_probes) = (passes, 0)
        }));
    }
    // The real-time methods on the same reference: Jozwowski's vertex estimates
    // (paths in the buffer) and image-space photon mapping (subsampling).
    // One real-time row: the method's defaults at the study's size, then `edit`.
    let live = |method: LiveMethod, label: String, edit: &dyn Fn(&mut LiveParams)| {
        let axis = if method == LiveMethod::Vertex { "live vertex" } else { "live ispm" };
        with(axis, label, &|s| {
            let frame = pm_live::FrameParams { width: size, height: size, ..base.live.frame.clone() };
            let mut p = LiveParams { method, frame, ..base.live.clone() };
            edit(&mut p);
            s.live = Some(p)
        })
    };
    use LiveMethod::{Ispm, Vertex};
    for total in [5_000u32, 20_000, 80_000] {
        v.push(live(Vertex, format!("vertex total {total}"), &|p| {
            (p.vertex.total, p.vertex.per_frame) = (total, total / 10)
        }));
    }
    // Corner estimates need corners: the mesh split to edges of at most this
    // fraction of the scene's diagonal (section 4.3).
    let diagonal = base_diagonal;
    for f in [0.05f32, 0.02] {
        v.push(live(Vertex, format!("vertex subdivide {f} diag"), &|p| {
            p.vertex.subdivide = pm_vertex::Subdivide::MaxEdge(f * diagonal)
        }));
    }
    // Paths cut at a fixed depth lose the light of their later bounces (a closed
    // room keeps 0.7^8 of it past 8 bounces).
    for level in [8u32, 32] {
        v.push(live(Vertex, format!("vertex max level {level}"), &|p| p.vertex.max_level = level));
    }
    for k in [25usize, 100, 200] {
        v.push(live(Vertex, format!("vertex k {k}"), &|p| p.vertex.k = k));
    }
    for bounces in [4u32, 16] {
        v.push(live(Ispm, format!("ispm bounces {bounces}"), &|p| p.ispm.bounces = bounces));
    }
    for f in [1u32, 2, 4] {
        v.push(live(Ispm, format!("ispm subsample {f}"), &|p| p.ispm.subsample = f));
    }
    // Photons per frame: 6 x res^2 bounce-map texels for a point light (the
    // default 48).
    for res in [32u32, 96] {
        v.push(live(Ispm, format!("ispm bounce res {res}"), &|p| p.ispm.bounce_res = res));
    }
    // Direct light from cube shadow maps: no shadow rays, no noise (issue 40's
    // image-space figure).
    v.push(live(Ispm, "ispm direct shadow-map".into(), &|p| p.frame.direct = pm_live::DirectMode::ShadowMap));
    v
}

/// The peer's rows (axis "peer"): Mitsuba's path tracer at these sample counts.
fn peer_rows(d: &Setting) -> Vec<Setting> {
    [16u32, 64, 256]
        .map(|spp| Setting { axis: "peer", label: format!("mitsuba {spp} spp"), peer_spp: Some(spp), ..d.clone() })
        .to_vec()
}

/// Mitsuba's time to reach `error` [s]: its path tracer is unbiased, so its error
/// falls as 1 / sqrt(time); fitted on its row with the most paths (the one whose
/// fixed costs weigh least). None without peer rows.
fn peer_time_at(rows: &[Row], error: f64) -> Option<f64> {
    let r = rows.iter().filter(|r| r.setting.peer_spp.is_some()).max_by_key(|r| r.setting.peer_spp)?;
    Some(r.total() * (r.splits[0].error / error).powi(2))
}

/// Render a real-time row's frame: photon-live runs until the vertex method's
/// buffer is full (one frame more), writes the last frame's EXR, and the mean frame
/// time after warm-up is the row's time [s].
fn live_frame(
    bins: &Bins,
    scene_args: &[String],
    p: &LiveParams,
    seed: u64,
    dir: &Path,
) -> Result<(pm_image::Layers, f64)> {
    let frames = (p.vertex.total / p.vertex.per_frame.max(1)).max(1) + 3;
    let mut a = scene_args.to_vec();
    a.extend(["--out".into(), dir.display().to_string()]);
    a.extend(["--frames".into(), frames.to_string(), "--exr".into(), "--seed".into(), seed.to_string()]);
    a.extend(p.to_args());
    stages::run(bins, "photon-live", &a, "photon-live", true)?;
    let csv =
        std::fs::read_to_string(dir.join("frames.csv")).with_context(|| format!("{}: no frames.csv", dir.display()))?;
    let walls =
        pm_methods::live::frame_seconds(p.method, &csv).map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))?;
    let times = &walls[walls.len().min((frames - 2) as usize)..];
    let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
    let exr = dir.join(format!("frames/{:04}.exr", frames - 1));
    Ok((pm_image::read_exr(&exr)?, mean))
}

/// Run one stage quietly (its messages are kept for the error if it fails) and
/// read its typed statistics.
fn stage<T: serde::de::DeserializeOwned>(bins: &Bins, name: &str, args: &[String], stats: &Path) -> Result<T> {
    let mut a = args.to_vec();
    a.extend(["--stats-json".to_string(), stats.display().to_string()]);
    stages::run(bins, name, &a, name, true)?;
    stages::read_stats(stats)
}

/// The reference: two path-traced halves of `spp / 2` paths per pixel with their
/// own seeds, cached by the content of the scene and every file it reads (its
/// environment too), the scene options, size and count. Returns their layers.
fn reference_halves(
    bins: &Bins,
    base: &pm_pipeline::Pipeline,
    (scene, scene_args): (&Path, &[String]),
    out: &Path,
    size: u32,
    spp: u32,
) -> Result<[pm_image::Layers; 2]> {
    let mut h = blake3::Hasher::new();
    for f in pm_pipeline::steps::scene_inputs(scene)? {
        h.update(&std::fs::read(&f).with_context(|| format!("{}: cannot read", f.display()))?);
    }
    h.update(scene_args.join(" ").as_bytes());
    let key = format!("{}-{size}-{spp}", h.finalize().to_hex());
    let key_file = out.join(format!("reference-{size}-{spp}.key"));
    let halves = [0, 1].map(|h| out.join(format!("reference-{size}-{spp}-{h}.exr")));
    if std::fs::read_to_string(&key_file).ok().as_deref() != Some(key.as_str()) || !halves.iter().all(|p| p.exists()) {
        for (h, exr) in halves.iter().enumerate() {
            println!("rendering reference half {} of 2 ({size}x{size}, path tracing, {} spp) ...", h + 1, spp / 2);
            let render = RenderParams { spp: (spp / 2).max(1), width: size, height: size, ..base.render.clone() };
            let p = Settings { mode: Method::Path, render, ..base.settings() };
            let mut a = scene_args.to_vec();
            a.extend(["--seed".into(), (1001 + h).to_string()]);
            a.extend(["--out".into(), exr.display().to_string()]);
            a.extend(p.to_args());
            let r: photon_render::Report =
                stage(bins, "photon-render", &a, &out.join(format!("reference-{h}.stats.json")))?;
            println!("  {:.1} s", r.seconds);
        }
        std::fs::write(&key_file, &key)?;
    }
    let [a, b] = &halves;
    Ok([pm_image::read_exr(a)?, pm_image::read_exr(b)?])
}

/// The total (`None`) or a layer of `i`; zero where the file has none.
fn layer(i: &pm_image::Layers, l: Option<Layer>) -> Vec<glam::Vec3> {
    i.total_or_layer(l).map(<[_]>::to_vec).unwrap_or_else(|| vec![glam::Vec3::ZERO; (i.width * i.height) as usize])
}

/// Run the trade-off study.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    anyhow::ensure!(args.seeds >= 2, "--seeds {}: bias and noise need at least 2", args.seeds);
    let scene = if args.scene.is_absolute() { args.scene.clone() } else { root.join(&args.scene) };
    let size = args.size;
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out/tradeoff").join(&name));
    std::fs::create_dir_all(&out)?;
    let base = pm_pipeline::Pipeline::load(&root.join("pipeline.toml"))?;
    let bins = Bins::build(root)?;
    let s = |v: &dyn std::fmt::Display| v.to_string();
    let scene_s = scene.display().to_string();
    // What every stage gets to read and light the scene.
    let mut scene_args = vec![s(&"--scene"), scene_s.clone()];
    for p in &args.portal {
        scene_args.extend([s(&"--portal"), p.clone()]);
    }

    // The scene once, for its size and, with --peer, Mitsuba's copy of it: a Python
    // without Mitsuba or a scene it cannot take fails before the reference renders.
    let (diagonal, media, mitsuba) = {
        let loaded = pm_scene::load(&scene).map_err(|e| anyhow::anyhow!("{e}"));
        let diagonal = loaded.as_ref().map(|s| s.bounds.diagonal()).unwrap_or(1.0);
        // Media of the file, or of pipeline.toml's [media.*] tables.
        let media = loaded.as_ref().is_ok_and(|s| s.has_scattering_media())
            || base.media.values().any(|m| m.sigma_s.iter().any(|&v| v > 0.0));
        let mitsuba = match &args.peer {
            Some(python) => {
                let m = crate::peer::Mitsuba::start(python, &args.peer_variant, &out.join("mitsuba"))?;
                let xml = crate::peer::translate(&loaded?, &name, &out.join("mitsuba"), size, 16)?;
                Some((m, xml))
            }
            None => None,
        };
        (diagonal, media, mitsuba)
    };
    let [half_a, half_b] = reference_halves(&bins, &base, (&scene, &scene_args), &out, size, args.reference_spp)?;
    let n = (size * size) as usize;
    let total = |h: &pm_image::Layers| layer(h, None);
    let (a, b) = (total(&half_a), total(&half_b));
    let keep = accuracy::keep_mask_of_halves(&a, &b, size as usize, size as usize, args.mask_above_mean);
    let references: Vec<(Vec<glam::Vec3>, f64)> = LAYERS
        .iter()
        .map(|l| accuracy::reference_from_halves(&layer(&half_a, *l), &layer(&half_b, *l), &keep))
        .collect();
    println!(
        "reference: {} spp in two halves; {} of {n} pixels compared; its own noise {:.2}% (relative RMS)",
        args.reference_spp,
        keep.iter().filter(|&&k| k).count(),
        100.0 * references[0].1.sqrt() / accuracy::kept_mean(&references[0].0, &keep)
    );
    let mut maps: BTreeMap<String, (PathBuf, [f64; 3])> = BTreeMap::new();
    let mut rows: Vec<Row> = Vec::new();
    let mut default_image = None;
    let mut settings = sweep(&base, size, diagonal, media);
    if mitsuba.is_some() {
        settings.extend(peer_rows(&settings[0]));
    }
    if !args.axes.is_empty() {
        for a in &args.axes {
            if !AXES.contains(&a.as_str()) {
                bail!("--axes: no axis named '{a}' (the axes: {})", AXES[1..].join(", "));
            }
        }
        settings.retain(|s| s.axis == "default" || s.axis == "peer" || args.axes.iter().any(|a| a == s.axis));
    }
    if args.replot {
        rows = read_rows(&out.join("results.csv"), &settings)?;
        default_image = Some(layer(&pm_image::read_exr(&out.join("defaults-s1.exr"))?, None));
    }
    for st in settings.into_iter().filter(|_| !args.replot) {
        let mut times = [0.0f64; 4];
        let mut images = Vec::new();
        for seed in 1..=args.seeds {
            if let (Some(spp), Some((m, xml))) = (st.peer_spp, &mitsuba) {
                let exr = out.join(format!("{}-s{seed}.exr", st.label.replace(' ', "_")));
                times[3] += m.render(xml, spp, seed as u32, &exr)? / args.seeds as f64;
                images.push(pm_image::read_exr(&exr)?);
                continue;
            }
            if let Some(lp) = &st.live {
                let dir = out.join("live").join(format!("{}-s{seed}", st.label.replace(' ', "_")));
                let (img, secs) = live_frame(&bins, &scene_args, lp, seed, &dir)?;
                times[3] += secs / args.seeds as f64;
                images.push(img);
                continue;
            }
            // Photon maps, shared by settings that differ only in rendering.
            let key = st.maps_key(seed);
            let mdir = out.join("maps").join(&key);
            // The path tracer and progressive photon mapping trace their own paths.
            let photon_mapping = st.render.mode.needs().photon_maps;
            if photon_mapping {
                if !maps.contains_key(&key) {
                    std::fs::create_dir_all(&mdir)?;
                    let o = |f: &str| mdir.join(f).display().to_string();
                    let mut a = scene_args.clone();
                    a.extend([s(&"--out"), mdir.display().to_string()]);
                    a.extend(st.trace.to_args());
                    a.extend([s(&"--seed"), s(&seed)]);
                    let t: photon_trace::Report = stage(&bins, "photon-trace", &a, &mdir.join("trace.json"))?;
                    let mut sort = 0.0;
                    for m in ["global", "caustic", "volume"] {
                        if Path::new(&o(&format!("{m}.pmap"))).exists() {
                            let a = [o(&format!("{m}.pmap")), s(&"--out"), o(&format!("{m}.kd.pmap"))];
                            let r: photon_sort::Report = stage(&bins, "photon-sort", &a, &mdir.join("sort.json"))?;
                            sort += r.seconds;
                        }
                    }
                    let mut a = vec![o("global.kd.pmap"), s(&"--out"), o("global.irr.pmap")];
                    a.extend(st.irradiance.to_args());
                    let i: photon_irradiance::Report = stage(&bins, "photon-irradiance", &a, &mdir.join("irr.json"))?;
                    maps.insert(key.clone(), (mdir.clone(), [t.seconds, sort, i.seconds]));
                }
                let (_, t) = &maps[&key];
                for k in 0..3 {
                    times[k] += t[k] / args.seeds as f64;
                }
            }
            let id = format!("{}-s{seed}", st.label.replace(' ', "_"));
            let img = out.join(format!("{id}.exr"));
            let mut a = scene_args.clone();
            a.extend([s(&"--out"), img.display().to_string()]);
            a.extend(st.render.to_args());
            a.extend([s(&"--seed"), s(&seed)]);
            if photon_mapping {
                a.extend([s(&"--global"), mdir.join("global.irr.pmap").display().to_string()]);
                for m in ["caustic", "volume"] {
                    let map = mdir.join(format!("{m}.kd.pmap"));
                    if map.exists() {
                        a.extend([format!("--{m}"), map.display().to_string()]);
                    }
                }
            }
            let r: photon_render::Report = stage(&bins, "photon-render", &a, &out.join(format!("{id}.stats.json")))?;
            times[3] += r.seconds / args.seeds as f64;
            images.push(pm_image::read_exr(&img)?);
        }
        let splits: [Split; 6] = std::array::from_fn(|k| {
            if k > 0 && st.peer_spp.is_some() || LAYERS[k] == Some(Layer::Volume) && !media {
                return Split::default(); // Mitsuba writes no layers; no volume without media
            }
            let layers: Vec<Vec<glam::Vec3>> = images.iter().map(|i| layer(i, LAYERS[k])).collect();
            let refs: Vec<&[glam::Vec3]> = layers.iter().map(Vec::as_slice).collect();
            accuracy::split(&refs, &references[k].0, references[k].1, &keep)
        });
        let ssim = pm_image::ssim(&layer(&images[0], None), &references[0].0, size as usize, size as usize);
        let row = Row { setting: st, times, splits, ssim };
        let t = &row.splits[0];
        println!(
            "  {:<24} {:>7.2} s  error {:.4} = bias {:.4} (+) noise {:.4}  [measured {:.4}]",
            row.setting.label,
            row.total(),
            t.error,
            t.bias,
            t.noise,
            t.measured
        );
        if row.setting.axis == "default" {
            default_image = Some(layer(&images[0], None));
        }
        rows.push(row);
    }
    let map = accuracy::error_map(default_image.as_deref().unwrap_or(&[]), &references[0].0, &keep);
    error_map_png(&out.join("error_map.png"), &map, size)?;
    write_outputs(&out, size, args, &rows)?;
    if let Some(docs) = &args.docs {
        std::fs::create_dir_all(docs)?;
        for f in [
            "front.json",
            "results.csv",
            "results.md",
            "plot.svg",
            "plot.png",
            "bias_noise.svg",
            "bias_noise.png",
            "layers.svg",
            "layers.png",
            "error_map.png",
        ] {
            std::fs::copy(out.join(f), docs.join(f))
                .with_context(|| format!("{f}: cannot copy to {}", docs.display()))?;
        }
        println!("copied the results to {}", docs.display());
    }
    Ok(())
}

/// The rows of a results.csv this study wrote, matched to `settings` by label.
fn read_rows(path: &Path, settings: &[Setting]) -> Result<Vec<Row>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let col = |name: &str| {
        header.iter().position(|h| *h == name).with_context(|| format!("{}: no column {name}", path.display()))
    };
    let mut rows = Vec::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let num = |name: &str| -> Result<f64> {
            let c = col(name)?;
            f.get(c).and_then(|v| v.parse().ok()).with_context(|| format!("{}: bad {name} in {line}", path.display()))
        };
        let label = f.get(col("setting")?).copied().unwrap_or_default();
        let Some(setting) = settings.iter().find(|s| s.label == label) else { continue };
        let split = |prefix: &str| -> Result<Split> {
            let p = if prefix.is_empty() { String::new() } else { format!("{prefix}_") };
            Ok(Split {
                error: num(&format!("{p}error"))?,
                bias: num(&format!("{p}bias"))?,
                noise: num(&format!("{p}noise"))?,
                reference_noise: num(&format!("{p}reference_noise"))?,
                mean_bias: if prefix.is_empty() { num("mean_bias")? } else { 0.0 },
                measured: if prefix.is_empty() { num("measured_rmse")? } else { 0.0 },
            })
        };
        rows.push(Row {
            setting: setting.clone(),
            times: [num("trace_s")?, num("sort_s")?, num("irradiance_s")?, num("render_s")?],
            splits: [
                split("")?,
                split("direct")?,
                split("caustic")?,
                split("indirect")?,
                split("specular")?,
                // Studies of scenes without media have no volume columns.
                if header.contains(&"volume_error") { split("volume")? } else { Split::default() },
            ],
            ssim: num("ssim")?,
        });
    }
    anyhow::ensure!(!rows.is_empty() && rows[0].setting.axis == "default", "{}: no defaults row first", path.display());
    Ok(rows)
}

/// The pipeline.toml values of `s` that differ from `d`'s: (section, key, value),
/// from their command lines (whose option names are the keys).
fn overrides(d: &Setting, s: &Setting) -> Vec<(String, String, pm_pipeline::quality::Value)> {
    let mut v = Vec::new();
    if d.render.mode != s.render.mode {
        let mode = s.render.mode.to_string();
        v.push(("render".to_string(), "mode".to_string(), pm_pipeline::quality::Value::parse(&mode, &mode)));
    }
    for (section, a, b) in [
        ("trace", d.trace.to_args(), s.trace.to_args()),
        ("irradiance", d.irradiance.to_args(), s.irradiance.to_args()),
        ("render", d.render.to_args(), s.render.render.to_args()),
    ] {
        for (da, sa) in a.chunks(2).zip(b.chunks(2)) {
            if da[1] != sa[1] {
                let key = sa[0].trim_start_matches("--").replace('-', "_");
                v.push((section.to_string(), key, pm_pipeline::quality::Value::parse(&sa[1], &da[1])));
            }
        }
    }
    v
}

/// Pareto front: the rows no faster row beats in error, fastest first.
fn pareto(rows: &[Row], error: impl Fn(&Row) -> f64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..rows.len()).collect();
    order.sort_by(|&a, &b| rows[a].total().total_cmp(&rows[b].total()));
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in order {
        if error(&rows[i]) < best {
            best = error(&rows[i]);
            front.push(i);
        }
    }
    front
}

fn write_outputs(out: &Path, size: u32, args: &Args, rows: &[Row]) -> Result<()> {
    std::fs::write(out.join("results.csv"), results_csv(rows, args.seeds)?)?;
    let front = pareto(rows, |r| if r.setting.peer_spp.is_some() { f64::INFINITY } else { r.splits[0].error });
    let md = results_md(rows, &front, size, args)?;
    std::fs::write(out.join("results.md"), &md)?;
    let f = quality_front(rows, size, args);
    std::fs::write(out.join("front.json"), serde_json::to_string_pretty(&f)? + "\n")?;
    plots(out, rows, &front)?;
    println!("\n{md}\nwrote {}", out.display());
    Ok(())
}

/// results.csv: a row per setting, its stage times [s], its error split and each
/// layer's.
fn results_csv(rows: &[Row], seeds: u64) -> Result<String> {
    let mut csv = String::from(
        "axis,setting,seeds,trace_s,sort_s,irradiance_s,render_s,total_s,error,bias,noise,reference_noise,mean_bias,measured_rmse,ssim",
    );
    let layers = shown_layers(rows);
    for l in &layers {
        write!(csv, ",{l}_error,{l}_bias,{l}_noise,{l}_reference_noise")?;
    }
    csv.push('\n');
    for r in rows {
        let t = &r.splits[0];
        write!(
            csv,
            "{},{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.5},{:.5},{:.5},{:.5},{:+.5},{:.5},{:.5}",
            r.setting.axis,
            r.setting.label,
            seeds,
            r.times[0],
            r.times[1],
            r.times[2],
            r.times[3],
            r.total(),
            t.error,
            t.bias,
            t.noise,
            t.reference_noise,
            t.mean_bias,
            t.measured,
            r.ssim
        )?;
        for l in &r.splits[1..=layers.len()] {
            write!(csv, ",{:.5},{:.5},{:.5},{:.5}", l.error, l.bias, l.noise, l.reference_noise)?;
        }
        csv.push('\n');
    }
    Ok(csv)
}

/// The layers the study's outputs show: the surface layers, and the volume layer
/// when some row measured one (a scene with scattering media).
fn shown_layers(rows: &[Row]) -> Vec<Layer> {
    let mut v = Layer::SURFACE.to_vec();
    if rows.iter().any(|r| r.splits[5].reference_noise > 0.0 || r.splits[5].error > 0.0) {
        v.push(Layer::Volume);
    }
    v
}

/// results.md: the table of settings (Pareto `front` marked), what each axis buys,
/// and the best setting per quality's time budget.
fn results_md(rows: &[Row], front: &[usize], size: u32, args: &Args) -> Result<String> {
    let pct = |v: f64| format!("{:.1}%", 100.0 * v);
    let reference_noise = rows.first().map_or(0.0, |r| r.splits[0].reference_noise);
    let smallest = rows.iter().map(|r| r.splits[0].error).fold(f64::INFINITY, f64::min);
    let peer = rows.iter().any(|r| r.setting.peer_spp.is_some());
    let volume = shown_layers(rows).contains(&Layer::Volume);
    let mut md = format!(
        "Trade-off on {size}x{size} against a path-traced reference of {} paths per pixel (two halves with their own seeds; \
         its own noise, from their difference, is {} relative RMS, {:.2} of the smallest error below, {}). Every setting is \
         rendered with {} seeds; the light's pixels and their neighbours are left out. **error** is what one render is \
         expected to be off from the truth, sqrt(bias^2 + noise^2); **bias** is the seeds' mean against the reference with \
         both noises taken out; **noise** the spread of one render; **measured** what a single comparison with the \
         reference reports. Times are wall seconds per stage (means over the seeds) on this machine (2 cores), one session; \
         the real-time rows (photon-live, one frame of the same camera) count the mean frame time after the vertex \
         method's buffer filled.\n\n\
         | axis | setting | trace | sort | precompute | render | total [s] | error | bias | noise | measured | direct | caustic | indirect | specular |{} Pareto |{}\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|{}---|{}\n",
        args.reference_spp,
        pct(reference_noise),
        reference_noise / smallest.max(1e-12),
        if reference_noise <= smallest / 3.0 {
            "below a third of it, as required"
        } else {
            "above a third of it: raise --reference-spp"
        },
        args.seeds,
        if volume { " volume |" } else { "" },
        if peer { " Mitsuba at equal error |" } else { "" },
        if volume { "---|" } else { "" },
        if peer { "---:|" } else { "" },
    );
    for (i, r) in rows.iter().enumerate() {
        let t = &r.splits[0];
        let l = |k: usize| match r.setting.peer_spp {
            Some(_) => "-".to_string(),
            None => format!("{} / {}", pct(r.splits[k].bias), pct(r.splits[k].noise)),
        };
        // Mitsuba's time to this row's error over the row's time.
        let lead = peer_time_at(rows, t.error).map_or(String::new(), |p| format!(" {:.1}x |", p / r.total()));
        writeln!(
            md,
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} | {} | {} | {} | {} |{} {} |{lead}",
            r.setting.axis,
            r.setting.label,
            r.times[0],
            r.times[1],
            r.times[2],
            r.times[3],
            r.total(),
            pct(t.error),
            pct(t.bias),
            pct(t.noise),
            pct(t.measured),
            l(1),
            l(2),
            l(3),
            l(4),
            if volume { format!(" {} |", l(5)) } else { String::new() },
            if front.contains(&i) { "yes" } else { "" }
        )?;
    }
    md.push_str("\nLayers: bias / noise, relative to each layer's own mean in the reference.\n\n");
    if peer {
        md.push_str(
            "Mitsuba at equal error: the time Mitsuba 3's path tracer (the peer rows, render time only, after a \
             warm-up render) needs to reach the row's error, from its row with the most paths as time x \
             (its error / the row's error)^2 (unbiased: error ~ 1 / sqrt(time)), over the row's total time; above \
             1x the row is ahead.\n\n",
        );
    }
    md.push_str("What each setting buys, from its smallest to its largest value (the defaults in between):\n\n");
    let mut axes: Vec<&str> = Vec::new();
    for r in rows {
        if r.setting.axis != "default" && !axes.contains(&r.setting.axis) {
            axes.push(r.setting.axis);
        }
    }
    for axis in &axes {
        let own: Vec<&Row> = rows.iter().filter(|r| r.setting.axis == *axis).collect();
        let (first, last) = (own[0], own[own.len() - 1]);
        let d = &rows[0];
        writeln!(
            md,
            "- {axis}: {} -> {}: bias {} -> {} (defaults {}), noise {} -> {} (defaults {}), time {:.2} -> {:.2} s (defaults {:.2} s)",
            first.setting.label,
            last.setting.label,
            pct(first.splits[0].bias),
            pct(last.splits[0].bias),
            pct(d.splits[0].bias),
            pct(first.splits[0].noise),
            pct(last.splits[0].noise),
            pct(d.splits[0].noise),
            first.total(),
            last.total(),
            d.total()
        )?;
    }
    md.push_str("\nBest setting per time budget (lowest error on the Pareto front within the budget):\n\n");
    let base_t = rows[0].total();
    for q in [Quality::Preview, Quality::Balanced, Quality::Final] {
        let (name, budget) = (q, q.budget_factor() * base_t);
        if let Some(&i) = front
            .iter()
            .filter(|&&i| rows[i].total() <= budget)
            .min_by(|&&a, &&b| rows[a].splits[0].error.total_cmp(&rows[b].splits[0].error))
        {
            writeln!(
                md,
                "- {name} (at most {budget:.2} s): {} ({:.2} s, error {})",
                rows[i].setting.label,
                rows[i].total(),
                pct(rows[i].splits[0].error)
            )?;
        }
    }
    Ok(md)
}

/// The front as the quality knob reads it (`quality` in pipeline.toml; front.json):
/// batch settings only, the real-time rows being another program.
fn quality_front(rows: &[Row], size: u32, args: &Args) -> pm_pipeline::quality::Front {
    let batch_front = pareto(rows, |r| {
        if r.setting.live.is_some() || r.setting.peer_spp.is_some() { f64::INFINITY } else { r.splits[0].error }
    });
    let name = Path::new(&args.scene).file_stem().map_or(String::new(), |s| s.to_string_lossy().into_owned());
    pm_pipeline::quality::Front {
        scene: name,
        size,
        machine: format!("{} cores", std::thread::available_parallelism().map_or(1, |n| n.get())),
        defaults_s: rows[0].times,
        points: batch_front
            .iter()
            .map(|&i| pm_pipeline::quality::Point {
                label: rows[i].setting.label.clone(),
                times_s: rows[i].times,
                error: rows[i].splits[0].error,
                bias: rows[i].splits[0].bias,
                noise: rows[i].splits[0].noise,
                overrides: overrides(&rows[0].setting, &rows[i].setting),
            })
            .collect(),
    }
}

/// The sweep's axes in legend order, and each one's colour.
const AXES: [&str; 21] = [
    "default",
    "global photons",
    "caustic photons",
    "k",
    "precompute fraction",
    "gather rays",
    "cache accuracy",
    "light samples",
    "max spp",
    "lookup",
    "records",
    "volume photons",
    "volume estimate",
    "volume k",
    "volume light samples",
    "path",
    "sppm",
    "sppm no probes",
    "live vertex",
    "live ispm",
    "peer",
];

fn colour(axis: &str) -> plot::Colour {
    plot::PALETTE[AXES.iter().position(|a| *a == axis).unwrap_or(0) % plot::PALETTE.len()]
}

/// A panel at (x0, y0) of size w x h: `value` of each row that `show` admits
/// against its total time (log axis), a line through each axis's points (with the
/// defaults' point), and `front` dashed; with `zoom` the value axis spans the shown
/// rows' range instead of starting at 0.
#[allow(clippy::too_many_arguments)]
fn panel(
    shapes: &mut Vec<Shape>,
    (x0, y0, w, h): (f64, f64, f64, f64),
    title: &str,
    y_label: &str,
    rows: &[Row],
    value: &dyn Fn(&Row) -> f64,
    show: &dyn Fn(&Row) -> bool,
    front: &[usize],
    (labels, zoom): (bool, bool),
) {
    let m = 55.0;
    let vis: Vec<usize> = (0..rows.len()).filter(|&i| show(&rows[i])).collect();
    let t: Vec<f64> = rows.iter().map(|r| r.total().max(1e-3)).collect();
    let tmin = vis.iter().map(|&i| t[i]).fold(f64::INFINITY, f64::min);
    let tmax = vis.iter().map(|&i| t[i]).fold(0.0, f64::max);
    let (lt0, lt1) = (tmin.log10().floor(), tmax.log10().ceil().max(tmin.log10().floor() + 1.0));
    let vhi = vis.iter().map(|&i| value(&rows[i])).fold(0.0, f64::max).max(1e-9);
    let vlo = vis.iter().map(|&i| value(&rows[i])).fold(f64::INFINITY, f64::min);
    let (vmin, vmax) = if zoom { (0.95 * vlo, 1.05 * vhi) } else { (0.0, 1.1 * vhi) };
    let x = |tv: f64| x0 + m + (tv.log10() - lt0) / (lt1 - lt0) * (w - 1.5 * m);
    let y = |v: f64| y0 + h - m + 10.0 - (v - vmin) / (vmax - vmin).max(1e-12) * (h - 1.6 * m);
    let black = (0u8, 0u8, 0u8);
    let (bx, by) = (x0 + m, y0 + h - m + 10.0);
    shapes.push(Shape::Line((bx, by), (x0 + w - 0.5 * m, by), black, false));
    shapes.push(Shape::Line((bx, y0 + 0.6 * m), (bx, by), black, false));
    shapes.push(Shape::Text((x0 + w / 2.0, y0 + 22.0), title.into(), "middle", false, 13));
    shapes.push(Shape::Text((x0 + w / 2.0, y0 + h - 8.0), "total time [s], log".into(), "middle", false, 11));
    shapes.push(Shape::Text((x0 + 14.0, y0 + h / 2.0), y_label.into(), "middle", true, 11));
    for p in lt0 as i32..=lt1 as i32 {
        let xv = x(10f64.powi(p));
        shapes.push(Shape::Line((xv, by), (xv, by + 5.0), black, false));
        shapes.push(Shape::Text((xv, by + 17.0), format!("{}", 10f64.powi(p)), "middle", false, 10));
    }
    for k in 0..=4 {
        let v = vmin + (vmax - vmin) * k as f64 / 4.0;
        shapes.push(Shape::Line((bx - 4.0, y(v)), (bx, y(v)), black, false));
        let text = if zoom { format!("{:.1}%", 100.0 * v) } else { format!("{:.0}%", 100.0 * v) };
        shapes.push(Shape::Text((bx - 6.0, y(v) + 4.0), text, "end", false, 10));
    }
    for wnd in front.windows(2) {
        let (a, b) = (wnd[0], wnd[1]);
        if vis.contains(&a) && vis.contains(&b) {
            shapes.push(Shape::Line((x(t[a]), y(value(&rows[a]))), (x(t[b]), y(value(&rows[b]))), (60, 60, 60), true));
        }
    }
    for axis in AXES.iter().skip(1) {
        // The axis's points and the defaults, in time order.
        let mut pts: Vec<usize> = vis.iter().copied().filter(|&i| rows[i].setting.axis == *axis).collect();
        if pts.is_empty() {
            continue;
        }
        if !matches!(*axis, "path" | "sppm" | "sppm no probes" | "live vertex" | "live ispm") && vis.contains(&0) {
            pts.push(0);
        }
        pts.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
        for wnd in pts.windows(2) {
            let (a, b) = (wnd[0], wnd[1]);
            shapes.push(Shape::Line((x(t[a]), y(value(&rows[a]))), (x(t[b]), y(value(&rows[b]))), colour(axis), false));
        }
    }
    for &i in &vis {
        let r = &rows[i];
        shapes.push(Shape::Dot((x(t[i]), y(value(r))), colour(r.setting.axis)));
        if labels {
            shapes.push(Shape::Text((x(t[i]) + 6.0, y(value(r)) - 5.0), r.setting.label.clone(), "start", false, 8));
        }
    }
}

fn legend(shapes: &mut Vec<Shape>, x0: f64, y0: f64) {
    for (k, a) in AXES.iter().enumerate() {
        shapes.push(Shape::Dot((x0, y0 + 16.0 * k as f64), colour(a)));
        shapes.push(Shape::Text((x0 + 10.0, y0 + 16.0 * k as f64 + 4.0), a.to_string(), "start", false, 11));
    }
    let y = y0 + 16.0 * AXES.len() as f64;
    shapes.push(Shape::Line((x0 - 5.0, y), (x0 + 5.0, y), (60, 60, 60), true));
    shapes.push(Shape::Text((x0 + 10.0, y + 4.0), "Pareto front".into(), "start", false, 11));
}

/// plot: error against time; bias_noise: bias against noise per setting (which
/// setting buys which); layers: per-layer error against time.
fn plots(out: &Path, rows: &[Row], front: &[usize]) -> Result<()> {
    // Left: every method; right: the photon-map settings alone, on their own scale.
    let photon_map = |r: &Row| r.setting.live.is_none() && r.setting.render.mode != Method::Path;
    let zoom_front = pareto(rows, |r| if photon_map(r) { r.splits[0].error } else { f64::INFINITY });
    let mut s = Vec::new();
    let error = |r: &Row| r.splits[0].error;
    panel(
        &mut s,
        (0.0, 0.0, 640.0, 560.0),
        "every method: error of one render against time",
        "error sqrt(bias^2 + noise^2)",
        rows,
        &error,
        &|_| true,
        front,
        (false, false),
    );
    panel(
        &mut s,
        (650.0, 0.0, 760.0, 560.0),
        "the photon-map settings, zoomed",
        "error sqrt(bias^2 + noise^2)",
        rows,
        &error,
        &photon_map,
        &zoom_front,
        (true, true),
    );
    legend(&mut s, 1430.0, 60.0);
    plot::draw(&s, 1590.0, 560.0, &out.join("plot.svg"), &out.join("plot.png"))?;

    // Bias against noise: moving along an axis horizontally buys bias, vertically noise.
    let (w, h, m) = (760.0f64, 560.0f64, 60.0f64);
    let bmax = rows.iter().map(|r| r.splits[0].bias).fold(0.0, f64::max).max(1e-9) * 1.1;
    let nmax = rows.iter().map(|r| r.splits[0].noise).fold(0.0, f64::max).max(1e-9) * 1.1;
    let x = |v: f64| m + v / bmax * (w - 1.5 * m);
    let y = |v: f64| h - m - v / nmax * (h - 2.0 * m);
    let black = (0u8, 0u8, 0u8);
    let mut s = vec![
        Shape::Line((m, h - m), (w - 0.5 * m, h - m), black, false),
        Shape::Line((m, m), (m, h - m), black, false),
        Shape::Text((w / 2.0, 24.0), "what each setting buys: bias (across) or noise (up)".into(), "middle", false, 13),
        Shape::Text((w / 2.0, h - 18.0), "bias (relative RMS)".into(), "middle", false, 11),
        Shape::Text((16.0, h / 2.0), "noise of one render (relative RMS)".into(), "middle", true, 11),
    ];
    for k in 0..=4 {
        let (bv, nv) = (bmax * k as f64 / 4.0, nmax * k as f64 / 4.0);
        s.push(Shape::Text((x(bv), h - m + 16.0), format!("{:.1}%", 100.0 * bv), "middle", false, 10));
        s.push(Shape::Text((m - 6.0, y(nv) + 4.0), format!("{:.1}%", 100.0 * nv), "end", false, 10));
    }
    for axis in AXES.iter().skip(1) {
        let mut pts: Vec<usize> = (0..rows.len()).filter(|&i| rows[i].setting.axis == *axis).collect();
        if !matches!(*axis, "path" | "sppm" | "sppm no probes" | "live vertex" | "live ispm") && !pts.is_empty() {
            pts.insert(pts.len() / 2, 0);
        }
        for wnd in pts.windows(2) {
            let (a, b) = (&rows[wnd[0]].splits[0], &rows[wnd[1]].splits[0]);
            s.push(Shape::Line((x(a.bias), y(a.noise)), (x(b.bias), y(b.noise)), colour(axis), false));
        }
    }
    for r in rows {
        let p = &r.splits[0];
        s.push(Shape::Dot((x(p.bias), y(p.noise)), colour(r.setting.axis)));
        s.push(Shape::Text((x(p.bias) + 6.0, y(p.noise) - 5.0), r.setting.label.clone(), "start", false, 8));
    }
    legend(&mut s, 780.0, 60.0);
    plot::draw(&s, 960.0, 560.0, &out.join("bias_noise.svg"), &out.join("bias_noise.png"))?;

    // Per layer.
    let mut s = Vec::new();
    let layers = shown_layers(rows);
    for (k, name) in layers.iter().enumerate() {
        let (px, py) = ((k % 2) as f64 * 480.0, (k / 2) as f64 * 340.0);
        let f = pareto(rows, |r| r.splits[k + 1].error);
        panel(
            &mut s,
            (px, py, 480.0, 340.0),
            &format!("{name} layer"),
            "error",
            rows,
            &|r| r.splits[k + 1].error,
            &|_| true,
            &f,
            (false, false),
        );
    }
    legend(&mut s, 985.0, 60.0);
    let height = 340.0 * layers.len().div_ceil(2) as f64;
    plot::draw(&s, 1140.0, height, &out.join("layers.svg"), &out.join("layers.png"))
}

/// The default setting's per-pixel relative error in false colour (black, blue,
/// red, yellow, white from 0 to the scale's top, the 99th percentile), with a scale
/// bar and its labels; the pixels left out are grey.
fn error_map_png(path: &Path, map: &[f32], size: u32) -> Result<()> {
    let mut sorted: Vec<f32> = map.iter().copied().filter(|v| *v > 0.0).collect();
    sorted.sort_by(f32::total_cmp);
    let top = sorted.get(sorted.len() * 99 / 100).copied().unwrap_or(1.0).max(1e-6);
    // The ramp's stops are sRGB colours; the canvas holds linear radiance.
    let ramp = |t: f32| -> glam::Vec3 {
        let stops = [
            glam::Vec3::ZERO,
            glam::Vec3::new(0.0, 0.1, 0.8),
            glam::Vec3::new(0.9, 0.1, 0.1),
            glam::Vec3::new(1.0, 0.9, 0.1),
            glam::Vec3::ONE,
        ];
        let u = t.clamp(0.0, 1.0) * 4.0;
        let k = (u.floor() as usize).min(3);
        stops[k].lerp(stops[k + 1], u - k as f32).to_array().map(pm_color::srgb_decode).into()
    };
    let (bar, pad) = (24u32, 90u32);
    let mut canvas = plot::Canvas::new(size + pad, size.max(120) + 20);
    let w = canvas.width;
    for (i, v) in map.iter().enumerate() {
        let (x, y) = (i as u32 % size, i as u32 / size);
        canvas.px[((y + 10) * w + x) as usize] =
            if *v > 0.0 || sorted.is_empty() { ramp(v / top) } else { glam::Vec3::splat(pm_color::srgb_decode(0.5)) };
    }
    let (bx, by0, by1) = (size + 10, 10u32, size.max(120) + 10);
    for y in by0..by1 {
        let t = 1.0 - (y - by0) as f32 / (by1 - by0) as f32;
        for x in bx..bx + bar {
            canvas.px[(y * w + x) as usize] = ramp(t);
        }
    }
    let x = (bx + bar + 4) as f64;
    canvas.text((x, by0 as f64 + 8.0), &format!("{:.0}%", 100.0 * top), "start", false, 10.0);
    canvas.text((x, (by0 + by1) as f64 / 2.0 + 4.0), &format!("{:.0}%", 50.0 * top), "start", false, 10.0);
    canvas.text((x, by1 as f64), "0%", "start", false, 10.0);
    pm_image::write_png(path, canvas.width, canvas.height, &canvas.px, 0.0)
}
