//! `cargo xtask tradeoff`: what accuracy costs in time. Renders a converged
//! path-traced reference as two independent halves (their difference measures the
//! reference's own noise), then sweeps one setting at a time from the defaults
//! (photon counts, k, precompute fraction, gather rays, irradiance-cache accuracy,
//! light samples, samples per pixel, lookup, record layout, path tracing at
//! several sample counts and progressive photon mapping at several pass counts;
//! in scenes with scattering media also volume photons, the volume estimate and
//! its k), each with several seeds, timing every stage. Errors
//! leave out the light's pixels and their neighbours and are split into bias and
//! noise ([`pm_image::accuracy`]) for the image and for each layer (direct, caustic,
//! indirect, specular, and volume in scenes with media). Writes results.csv, results.md, plot (error against time,
//! lines per setting, the Pareto front), bias_noise (which setting buys which),
//! layers (per-layer panels) as SVG and PNG, and error_map.png.

mod plots;
pub mod results;
pub mod sweep;

use anyhow::{Context, Result};
use glam::Vec3;
use pm_color::Layer;
use pm_image::accuracy;
use pm_methods::live::LiveParams;
use pm_methods::{Method, Settings};
use pm_pipeline::quality::StageTimes;
use pm_render::RenderParams;
use pm_runner::bins::{self, Bins};
use results::{COMPARED, LayerSplits, Row};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use sweep::{Axis, Setting};

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
    /// The unbiased method that renders the reference: `path`, or `bdpt` where
    /// the path tracer cannot find the light (a lamp behind glass: every direct
    /// path a caustic); `--reference-spp` is then its passes.
    #[arg(long, default_value_t = Method::Path)]
    reference_mode: Method,
    /// Copy results.json, results.csv, results.md, the plots and the error map here.
    #[arg(long)]
    docs: Option<PathBuf>,
    /// Render nothing: rewrite results.md, front.json, the plots and the error map
    /// from the output folder's results.json, cached reference and images.
    #[arg(long)]
    replot: bool,
    /// Only these axes of the sweep besides the defaults, comma-separated by name
    /// ("path", "light samples", ...; all when not given): a larger image's
    /// equal-error comparison needs only `--axes path`.
    #[arg(long, value_delimiter = ',')]
    axes: Vec<Axis>,
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
    bins::run(bins, "photon-live", &a, "photon-live", true)?;
    let csv =
        std::fs::read_to_string(dir.join("frames.csv")).with_context(|| format!("{}: no frames.csv", dir.display()))?;
    let walls =
        pm_methods::live::frame_seconds(p.method, &csv).map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))?;
    let times = &walls[walls.len().min((frames - 2) as usize)..];
    let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
    let exr = dir.join(format!("frames/{:04}.exr", frames - 1));
    Ok((pm_image::read_exr(&exr)?, mean))
}

/// The reference: two halves of `spp / 2` samples per pixel with their own seeds
/// by the unbiased method `mode` (the path tracer, or bidirectional path
/// tracing), cached by the content of the scene and every file it reads (its
/// environment too), the scene options, method, size and count. Returns their
/// layers.
fn reference_halves(
    bins: &Bins,
    base: &pm_pipeline::Pipeline,
    (scene, scene_args): (&Path, &[String]),
    out: &Path,
    (mode, size, spp): (Method, u32, u32),
) -> Result<[pm_image::Layers; 2]> {
    anyhow::ensure!(
        matches!(mode, Method::Path | Method::Bdpt),
        "--reference-mode {mode}: the reference is rendered by an unbiased method (path or bdpt)"
    );
    // The path tracer's files keep the names they had before there was a choice.
    let tag = if mode == Method::Path { String::new() } else { format!("{mode}-") };
    let mut h = blake3::Hasher::new();
    for f in pm_pipeline::steps::scene_inputs(scene)? {
        h.update(&std::fs::read(&f).with_context(|| format!("{}: cannot read", f.display()))?);
    }
    h.update(scene_args.join(" ").as_bytes());
    let key = format!("{}-{tag}{size}-{spp}", h.finalize().to_hex());
    let key_file = out.join(format!("reference-{tag}{size}-{spp}.key"));
    let halves = [0, 1].map(|h| out.join(format!("reference-{tag}{size}-{spp}-{h}.exr")));
    if std::fs::read_to_string(&key_file).ok().as_deref() != Some(key.as_str()) || !halves.iter().all(|p| p.exists()) {
        for (h, exr) in halves.iter().enumerate() {
            println!("rendering reference half {} of 2 ({size}x{size}, --mode {mode}, {} spp) ...", h + 1, spp / 2);
            let render = RenderParams { spp: (spp / 2).max(1), width: size, height: size, ..base.render.clone() };
            let mut p = Settings { mode, render, ..base.settings() };
            // BDPT's passes are its own setting: the half's share of --reference-spp.
            p.bdpt.bdpt_passes = (spp / 2).max(1);
            let mut a = scene_args.to_vec();
            a.extend(["--seed".into(), (1001 + h).to_string()]);
            a.extend(["--out".into(), exr.display().to_string()]);
            a.extend(p.to_args());
            let r: pm_stage::report::RenderReport =
                bins::run_for_report(bins, "photon-render", &a, &out.join(format!("reference-{h}.stats.json")))?;
            println!("  {:.1} s", r.seconds);
        }
        std::fs::write(&key_file, &key)?;
    }
    let [a, b] = &halves;
    Ok([pm_image::read_exr(a)?, pm_image::read_exr(b)?])
}

/// What every row is measured with: the scene, its options, the stage binaries,
/// the output folder, the reference and the pixels compared.
struct Study {
    bins: Bins,
    out: PathBuf,
    /// What every stage gets to read and light the scene.
    scene_args: Vec<String>,
    /// Whether the scene has scattering media (the volume layer is compared).
    media: bool,
    /// Mitsuba running, and its copy of the scene (with --peer).
    mitsuba: Option<(crate::peer::Mitsuba, PathBuf)>,
    /// Per [`COMPARED`] entry: the reference and its own noise variance.
    references: Vec<(Vec<Vec3>, f64)>,
    /// The pixels compared.
    keep: Vec<bool>,
    /// Photon maps already traced, by [`Setting::maps_key`]: their folder and
    /// trace, sort and precompute times [s].
    maps: BTreeMap<String, (PathBuf, [f64; 3])>,
}

/// Run the trade-off study: the scene and reference, every setting's row (or,
/// with --replot, the rows of results.json), then the results.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    anyhow::ensure!(args.seeds >= 2, "--seeds {}: bias and noise need at least 2", args.seeds);
    let base = pm_pipeline::Pipeline::load(&root.join("pipeline.toml"))?;
    let (mut study, diagonal) = prepare(args, root, &base)?;
    let mut settings = sweep::sweep(&base, args.size, diagonal, study.media);
    if study.mitsuba.is_some() {
        settings.extend(sweep::peer_rows(&settings[0]));
    }
    if !args.axes.is_empty() {
        settings.retain(|s| s.axis == Axis::Default || s.axis == Axis::Peer || args.axes.contains(&s.axis));
    }
    let (rows, default_image) = if args.replot {
        let rows = results::read_rows(&study.out.join("results.json"), &settings)?;
        (rows, pm_image::read_exr(&study.out.join("defaults-s1.exr"))?.pixels(None))
    } else {
        let mut rows = Vec::new();
        let mut default_image = Vec::new();
        for st in settings {
            let (row, first) = measure(&mut study, args, st)?;
            if row.setting.axis == Axis::Default {
                default_image = first;
            }
            rows.push(row);
        }
        (rows, default_image)
    };
    let map = accuracy::error_map(&default_image, &study.references[0].0, &study.keep);
    plots::error_map_png(&study.out.join("error_map.png"), &map, args.size)?;
    results::write_outputs(&study.out, args.size, args, &rows)?;
    if let Some(docs) = &args.docs {
        copy_to_docs(&study.out, docs)?;
    }
    Ok(())
}

/// The scene once (its size, whether it has media, Mitsuba's copy with --peer: a
/// Python without Mitsuba or a scene it cannot take fails before the reference
/// renders), the stage binaries and the reference. Returns the study and the
/// scene's bounding-box diagonal [m].
fn prepare(args: &Args, root: &Path, base: &pm_pipeline::Pipeline) -> Result<(Study, f32)> {
    let scene = if args.scene.is_absolute() { args.scene.clone() } else { root.join(&args.scene) };
    let name = scene.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let out = args.out.clone().unwrap_or_else(|| root.join("out/tradeoff").join(&name));
    std::fs::create_dir_all(&out)?;
    let bins = Bins::build(root)?;
    // pipeline.toml's scene options (its environment, media, ...) and the portals given.
    let mut options = base.scene_options.clone();
    options.portal.extend(args.portal.iter().cloned());
    let mut scene_args = vec!["--scene".to_string(), scene.display().to_string()];
    scene_args.extend(options.to_args());
    let loaded = pm_scene::load(&scene).map_err(|e| anyhow::anyhow!("{e}"));
    let diagonal = loaded.as_ref().map(|s| s.bounds.diagonal()).unwrap_or(1.0);
    // Media of the file, or of pipeline.toml's [media.*] tables.
    let media = loaded.as_ref().is_ok_and(|s| s.has_scattering_media())
        || options.medium.iter().any(|m| m.sigma_s.iter().any(|&v| v > 0.0));
    let mitsuba = match &args.peer {
        Some(python) => {
            let m = crate::peer::Mitsuba::start(python, &args.peer_variant, &out.join("mitsuba"))?;
            let xml = crate::peer::translate(&loaded?, &name, &out.join("mitsuba"), args.size, 16)?;
            Some((m, xml))
        }
        None => None,
    };
    let size = args.size;
    let [half_a, half_b] =
        reference_halves(&bins, base, (&scene, &scene_args), &out, (args.reference_mode, size, args.reference_spp))?;
    let (a, b) = (half_a.pixels(None), half_b.pixels(None));
    let keep = accuracy::keep_mask_of_halves(&a, &b, size as usize, size as usize, args.mask_above_mean);
    let references: Vec<(Vec<Vec3>, f64)> = COMPARED
        .iter()
        .map(|l| accuracy::reference_from_halves(&half_a.pixels(*l), &half_b.pixels(*l), &keep))
        .collect();
    println!(
        "reference: {} spp in two halves; {} of {} pixels compared; its own noise {:.2}% (relative RMS)",
        args.reference_spp,
        keep.iter().filter(|&&k| k).count(),
        size * size,
        100.0 * references[0].1.sqrt() / accuracy::kept_mean(&references[0].0, &keep)
    );
    let study = Study { bins, out, scene_args, media, mitsuba, references, keep, maps: BTreeMap::new() };
    Ok((study, diagonal))
}

/// One setting's row: `args.seeds` renders, their stage times and their error
/// split against the reference; and the first seed's image.
fn measure(study: &mut Study, args: &Args, st: Setting) -> Result<(Row, Vec<Vec3>)> {
    let mut times = StageTimes::default();
    let mut images = Vec::new();
    let per_seed = 1.0 / args.seeds as f64;
    for seed in 1..=args.seeds {
        let id = format!("{}-s{seed}", st.label.replace(' ', "_"));
        if let (Some(spp), Some((m, xml))) = (st.peer_spp, &study.mitsuba) {
            let exr = study.out.join(format!("{id}.exr"));
            times.render += m.render(xml, spp, seed as u32, &exr)? * per_seed;
            images.push(pm_image::read_exr(&exr)?);
        } else if let Some(lp) = &st.live {
            let dir = study.out.join("live").join(&id);
            let (img, secs) = live_frame(&study.bins, &study.scene_args, lp, seed, &dir)?;
            times.render += secs * per_seed;
            images.push(img);
        } else {
            let (img, t) = render_batch(study, &st, seed, &id)?;
            let [trace, sort, irradiance, render] = t.into();
            times.trace += trace * per_seed;
            times.sort += sort * per_seed;
            times.irradiance += irradiance * per_seed;
            times.render += render * per_seed;
            images.push(img);
        }
    }
    let media = study.media;
    let layers = LayerSplits::from_fn(|l| {
        if l.is_some() && st.peer_spp.is_some() || l == Some(Layer::Volume) && !media {
            return accuracy::Split::default(); // Mitsuba writes no layers; no volume without media
        }
        let k = COMPARED.iter().position(|c| *c == l).expect("every compared layer");
        let layers: Vec<Vec<Vec3>> = images.iter().map(|i| i.pixels(l)).collect();
        let refs: Vec<&[Vec3]> = layers.iter().map(Vec::as_slice).collect();
        accuracy::split(&refs, &study.references[k].0, study.references[k].1, &study.keep)
    });
    let size = args.size as usize;
    let first = images[0].pixels(None);
    let ssim = pm_image::ssim(&first, &study.references[0].0, size, size);
    let row = Row { setting: st, times, layers, ssim };
    let t = row.image();
    println!(
        "  {:<24} {:>7.2} s  error {:.4} = bias {:.4} (+) noise {:.4}  [measured {:.4}]",
        row.setting.label,
        row.total(),
        t.error,
        t.bias,
        t.noise,
        t.measured
    );
    Ok((row, first))
}

/// One seed of a batch setting: its photon maps (traced, sorted and precomputed
/// once per [`Setting::maps_key`]; the path tracer and progressive photon mapping
/// trace their own paths) and its render. Returns the image and the stage times
/// [s] (the maps' times whether or not they were traced now).
fn render_batch(study: &mut Study, st: &Setting, seed: u64, id: &str) -> Result<(pm_image::Layers, StageTimes)> {
    let photon_mapping = st.render.mode.needs().photon_maps;
    let key = st.maps_key(seed);
    let mdir = study.out.join("maps").join(&key);
    let mut times = StageTimes::default();
    if photon_mapping {
        if !study.maps.contains_key(&key) {
            let t = trace_maps(&study.bins, &study.scene_args, st, seed, &mdir)?;
            study.maps.insert(key.clone(), (mdir.clone(), t));
        }
        [times.trace, times.sort, times.irradiance] = study.maps[&key].1;
    }
    let img = study.out.join(format!("{id}.exr"));
    let mut a = study.scene_args.clone();
    a.extend(["--out".to_string(), img.display().to_string()]);
    a.extend(st.render.to_args());
    a.extend(["--seed".to_string(), seed.to_string()]);
    if photon_mapping {
        a.extend(["--global".to_string(), mdir.join("global.irr.pmap").display().to_string()]);
        for m in ["caustic", "volume"] {
            let map = mdir.join(format!("{m}.kd.pmap"));
            if map.exists() {
                a.extend([format!("--{m}"), map.display().to_string()]);
            }
        }
    }
    let stats = study.out.join(format!("{id}.stats.json"));
    let r: pm_stage::report::RenderReport = bins::run_for_report(&study.bins, "photon-render", &a, &stats)?;
    times.render = r.seconds;
    Ok((pm_image::read_exr(&img)?, times))
}

/// Stages 1-3 for a setting's maps into `mdir`: their trace, sort (every map) and
/// precompute times [s].
fn trace_maps(bins: &Bins, scene_args: &[String], st: &Setting, seed: u64, mdir: &Path) -> Result<[f64; 3]> {
    std::fs::create_dir_all(mdir)?;
    let o = |f: &str| mdir.join(f).display().to_string();
    let mut a = scene_args.to_vec();
    a.extend(["--out".to_string(), mdir.display().to_string()]);
    a.extend(st.trace.to_args());
    a.extend(["--seed".to_string(), seed.to_string()]);
    let t: pm_stage::report::TraceReport = bins::run_for_report(bins, "photon-trace", &a, &mdir.join("trace.json"))?;
    let mut sort = 0.0;
    for m in ["global", "caustic", "volume"] {
        if Path::new(&o(&format!("{m}.pmap"))).exists() {
            let a = [o(&format!("{m}.pmap")), "--out".to_string(), o(&format!("{m}.kd.pmap"))];
            let r: pm_stage::report::SortReport =
                bins::run_for_report(bins, "photon-sort", &a, &mdir.join("sort.json"))?;
            sort += r.seconds;
        }
    }
    let mut a = vec![o("global.kd.pmap"), "--out".to_string(), o("global.irr.pmap")];
    a.extend(st.irradiance.to_args());
    let i: pm_stage::report::IrradianceReport =
        bins::run_for_report(bins, "photon-irradiance", &a, &mdir.join("irr.json"))?;
    Ok([t.seconds, sort, i.seconds])
}

/// Copy the results and figures from `out` to `docs`.
fn copy_to_docs(out: &Path, docs: &Path) -> Result<()> {
    std::fs::create_dir_all(docs)?;
    for f in [
        "front.json",
        "results.json",
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
        std::fs::copy(out.join(f), docs.join(f)).with_context(|| format!("{f}: cannot copy to {}", docs.display()))?;
    }
    println!("copied the results to {}", docs.display());
    Ok(())
}
