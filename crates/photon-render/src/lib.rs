//! Stage 4 of the pipeline (Christensen 1999 sections 1.3, 2.2 and 3): render the
//! scene from its photon maps and write an OpenEXR image (linear radiance with
//! component layers) and optionally a PNG. A thin layer over `pm-render`.

use anyhow::{Context, Result, bail, ensure};
use clap::Parser;
use pm_format::{FullPhoton, MapKind, Order, PhotonRecord, ReadExpect, with_map};
use pm_kdtree::{Buckets, KdTree};
use pm_methods::{Input, Method, Passes, Progressive, Settings};
use pm_render::{Image, Integrator, IrradianceCache, Lookup, Maps, PhotonMapping, Rect, RenderStats, View};
use pm_stage::Progress;
use pm_stage::report::RenderReport;
use std::path::PathBuf;

/// Command line of `photon-render`.
#[derive(Parser, Debug, Clone)]
#[command(
    name = "photon-render",
    about = "Stage 4: render from the photon maps to OpenEXR (linear radiance, W sr^-1 m^-2) and PNG",
    long_about = "Stage 4 (Christensen 1999, sections 1.3, 2.2, 3). Traces eye rays with adaptive supersampling; \
mirrors and glass by recursive ray tracing; at other surfaces direct light by sampling the lights, caustics from the \
caustic map and soft indirect light by final gathering whose rays read the precomputed irradiance of the nearest \
photon with a similar normal (or an exact k-nearest estimate), interpolated by an irradiance cache. Radiance in the \
EXR is W sr^-1 m^-2 per RGB channel, with layers direct, caustic, indirect and specular. Radii are fractions of the \
scene's bounding-box diagonal; the stats JSON logs the absolute values used."
)]
pub struct Cli {
    /// Scene (glTF 2.0); the first camera is used.
    #[arg(long)]
    pub scene: PathBuf,
    /// Global map with precomputed irradiance (global.irr.pmap), or global.kd.pmap with --gather-lookup exact.
    #[arg(long)]
    pub global: Option<PathBuf>,
    /// Sorted caustic map (caustic.kd.pmap).
    #[arg(long)]
    pub caustic: Option<PathBuf>,
    /// Sorted volume map (volume.kd.pmap): light scattered in participating media,
    /// read along eye rays (full mode: multiple scattering) and along final-gather
    /// rays (full and indirect modes and the cache prepass: all of it). Without it,
    /// media still attenuate and eye rays' single scattering is computed from the
    /// lights.
    #[arg(long)]
    pub volume: Option<PathBuf>,
    /// Output OpenEXR image (of the --region when given: its data window says where
    /// the region sits, and `cargo xtask assemble` joins regions). Not needed with
    /// --icache-out.
    #[arg(long, required_unless_present = "icache_out")]
    pub out: Option<PathBuf>,
    /// Render only this rectangle of the image, X0,Y0,X1,Y1 in pixels (columns
    /// X0..X1, rows Y0..Y1, row 0 at the top, X1 and Y1 exclusive). Regions of the
    /// same render with a shared --icache equal the whole image's pixels exactly.
    #[arg(long, value_parser = parse_region)]
    pub region: Option<[u32; 4]>,
    /// Render only tile K of N, K/N: the image cut into N bands of whole rows (what
    /// a job plan's tasks use; the same as the matching --region).
    #[arg(long, value_parser = parse_tile, conflicts_with = "region")]
    pub tile: Option<(u32, u32)>,
    /// Run only the irradiance-cache prepass (the final gathers at cache records over
    /// the whole image) and write its records to this file; no image is rendered.
    #[arg(long, conflicts_with_all = ["icache", "out", "png", "region", "tile"])]
    pub icache_out: Option<PathBuf>,
    /// Read the irradiance cache from this file (made by --icache-out with the same
    /// scene, maps, size and settings) instead of running the prepass.
    #[arg(long)]
    pub icache: Option<PathBuf>,
    /// Also write a PNG (exposure, sRGB).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Leave out soft indirect light (no final gathers, no global map needed); for
    /// scenes where no diffusely reflected light reaches another diffuse surface.
    #[arg(long)]
    pub no_indirect: bool,
    /// The method and every method's settings (pipeline.toml's \[render\] and
    /// \[sppm\] sections).
    #[command(flatten)]
    pub settings: Settings,
    /// How the scene file is read.
    #[command(flatten)]
    pub scene_options: pm_stage::SceneOptions,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Progressive methods (`--mode sppm`, `bdpt`, `vcm`; and `path`, which with
    /// any of these four options runs in passes of one sample a pixel, --spp of
    /// them): write the image (`--out`, its layers as usual) after every K
    /// passes, so a long render can be looked at while it runs.
    #[arg(long, value_name = "K")]
    pub checkpoint: Option<u32>,
    /// Progressive methods: stop after the pass that takes the render past this
    /// many seconds (the image holds the passes done; the pass count, and so the
    /// image, then depends on the machine: `--passes`, `--bdpt-passes`,
    /// `--vcm-passes` or path's `--spp` alone is deterministic). Every method
    /// compared at equal time takes this one option.
    #[arg(long, value_name = "SECONDS")]
    pub time_budget: Option<f64>,
    /// Progressive methods: keep the pixels' state in this file (sppm: radii,
    /// photon counts, fluxes, 120 bytes a pixel; bdpt, vcm and path: the layers'
    /// sums over the passes, 68 bytes a pixel). When it exists the render
    /// continues from the passes it holds (refused if it was made from another
    /// scene or with other settings; --passes, --bdpt-passes, --vcm-passes or
    /// path's --spp is the total); it is written at
    /// every checkpoint and when the render stops. A render that --time-budget
    /// stops before --passes then exits with code 75 (sysexits' EX_TEMPFAIL):
    /// run the same command again to continue (a Slurm job re-queues itself so).
    /// A stop and a resume equal one run bit for bit.
    #[arg(long, value_name = "FILE")]
    pub state: Option<PathBuf>,
    /// Progressive methods: run K of N independent runs, K/N (seed + K;
    /// `cargo xtask assemble --average` averages the runs' images, which is still
    /// consistent).
    #[arg(long, value_parser = parse_run, value_name = "K/N")]
    pub run: Option<(u32, u32)>,
    /// Write statistics (time per component, gathers, rays) as JSON.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

fn parse_tile(s: &str) -> Result<(u32, u32), String> {
    pm_stage::parse_part(s, "tile")
}

fn parse_run(s: &str) -> Result<(u32, u32), String> {
    pm_stage::parse_part(s, "run")
}

/// The rectangle --region or --tile asks for, checked against the image.
fn requested_region(cli: &Cli, film: &pm_render::Film) -> Result<Option<[u32; 4]>> {
    Ok(match (cli.region, cli.tile) {
        (Some([x0, y0, x1, y1]), _) => {
            let r = Rect { x0, y0, x1, y1 };
            ensure!(
                film.contains(r),
                "--region {x0},{y0},{x1},{y1} is outside the {}x{} image",
                film.width,
                film.height
            );
            Some([x0, y0, x1, y1])
        }
        (None, Some((k, n))) => {
            let r = film.band(k, n).with_context(|| {
                format!("--tile {k}/{n}: needs K below N and N at most the image's {} rows", film.height)
            })?;
            Some([r.x0, r.y0, r.x1, r.y1])
        }
        (None, None) => None,
    })
}

fn parse_region(s: &str) -> Result<[u32; 4], String> {
    let v: Vec<u32> = s
        .split(',')
        .map(|x| x.trim().parse::<u32>().map_err(|_| format!("'{x}' is not a pixel index")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x0, y0, x1, y1] if x0 < x1 && y0 < y1 => Ok([x0, y0, x1, y1]),
        [_, _, _, _] => Err("X0 < X1 and Y0 < Y1 are required".into()),
        _ => Err("give four numbers X0,Y0,X1,Y1".into()),
    }
}

/// True when the render runs in passes: a progressive method, or the path tracer
/// given a progressive option (then in passes of one sample a pixel, `--spp` of
/// them).
fn in_passes(cli: &Cli) -> bool {
    let mode = cli.settings.mode;
    mode.needs().progressive || (mode == Method::Path && cli.progressive_options())
}

impl Cli {
    /// True when an option of the progressive methods is given.
    fn progressive_options(&self) -> bool {
        self.checkpoint.is_some() || self.time_budget.is_some() || self.state.is_some() || self.run.is_some()
    }
}

/// Run the stage; returns the statistics.
pub fn run(cli: &Cli) -> Result<RenderReport> {
    let p = &cli.settings.render;
    cli.settings.check(true).map_err(|e| anyhow::anyhow!(e))?;
    if cli.progressive_options() && !in_passes(cli) {
        let methods = <Method as clap::ValueEnum>::value_variants().iter();
        let which: Vec<String> =
            methods.filter(|m| m.needs().progressive || **m == Method::Path).map(|m| m.to_string()).collect();
        bail!(
            "--checkpoint, --time-budget, --state and --run are for progressive methods and the path tracer (--mode {})",
            which.join(", ")
        );
    }
    if let Some(b) = cli.time_budget {
        ensure!(b.is_finite() && b > 0.0, "--time-budget {b}: give a positive number of seconds");
    }
    pm_stage::init_threads(cli.threads)?;
    let scene = pm_stage::load_scene("photon-render", &cli.scene, &cli.scene_options)?;
    let camera = scene
        .camera
        .clone()
        .with_context(|| format!("{}: the scene has no perspective camera", cli.scene.display()))?;
    let film = p.film(cli.seed.wrapping_add(cli.run.map_or(0, |(k, _)| k as u64)));
    let region = requested_region(cli, &film)?;
    let rect = match region {
        Some([x0, y0, x1, y1]) => Rect { x0, y0, x1, y1 },
        None => film.rect(),
    };
    // The cache prepass is the indirect view's work without the image.
    let mode = if cli.icache_out.is_some() { Method::Indirect } else { cli.settings.mode };
    let needs = mode.needs();
    let indirect = !cli.no_indirect;
    let needs_global = needs.photon_maps && (indirect || !needs.caustic);
    let needs_irradiance = needs.irradiance && p.gather_lookup == Lookup::Precomputed;
    // The caustic and volume maps: kd-trees of this scene, read as full records.
    let full_map = |path: &Option<PathBuf>, kind: MapKind, wanted: bool| {
        let Some(path) = path.as_ref().filter(|_| wanted) else { return Ok(None) };
        let expect = ReadExpect {
            kind: Some(kind),
            order: Some(Order::KdTree),
            scene_hash: Some(scene.content_hash),
            ..Default::default()
        };
        let map = pm_format::read_as::<FullPhoton>(path, &expect)?;
        pm_stage::verify_kd_tree(path, &map.records)?;
        anyhow::Ok(Some(map))
    };
    let caustic = full_map(&cli.caustic, MapKind::Caustic, needs.caustic)?;
    let volume = full_map(&cli.volume, MapKind::Volume, needs.volume)?;
    let mut notes = Vec::new();
    if needs.volume && scene.has_scattering_media() && volume.is_none() {
        notes.push("no volume map (--volume): light scattered more than once in media is left out".to_string());
    }
    let global = match (&cli.global, needs_global) {
        (Some(path), true) => {
            let expect = ReadExpect {
                kind: Some(MapKind::Global),
                order: Some(Order::KdTree),
                irradiance: needs_irradiance.then_some(true),
                scene_hash: Some(scene.content_hash),
            };
            let map = pm_format::read(path, &expect)?;
            if !map.header().layout.has_normal() {
                bail!(
                    "{}: {} records carry no surface normal; trace with photon-trace",
                    path.display(),
                    map.header().layout.name()
                );
            }
            with_map!(&map, m => pm_stage::verify_kd_tree(path, &m.records))?;
            if map.is_empty() {
                notes.push("the global photon map holds no photons: indirect light is zero".to_string());
            }
            Some(map)
        }
        (None, true) => bail!("--global is required in {mode} mode"),
        _ => None,
    };
    for n in &notes {
        eprintln!("photon-render: note: {n}");
    }
    let unfinished = std::cell::Cell::new(false);
    let job = Job {
        cli,
        scene: &scene,
        camera: &camera,
        film,
        rect,
        mode,
        indirect,
        volume: volume.as_ref(),
        unfinished: &unfinished,
    };
    let (image, stats, cache) = match &global {
        Some(pm_format::AnyMap::CompactIrr(m)) => job.run(Some(m), caustic.as_ref())?,
        Some(pm_format::AnyMap::FullIrr(m)) => job.run(Some(m), caustic.as_ref())?,
        Some(_) => unreachable!("layouts without normals were refused above"),
        None => job.run::<pm_format::FullIrrPhoton>(None, caustic.as_ref())?,
    };
    if let Some(image) = image {
        let layers = layers_of(image);
        let out = cli.out.as_ref().context("--out is required")?;
        write_exr(cli, out, region, &layers)?;
        // Fast compression: the PNG is a preview of the EXR; balanced compression took
        // 0.28 s on one thread for 1024 x 1024 (7% of the default render), fast 0.04 s
        // for a file 19% larger.
        if let Some(png) = &cli.png {
            pm_image::write_png_fast(
                png,
                layers.width,
                layers.height,
                layers.total().context("no total layer")?,
                p.exposure,
            )?;
        }
    }
    let report = RenderReport { unfinished: unfinished.get(), ..report(cli, region, &scene, &stats, &cache, &notes) };
    if let Some(path) = &cli.stats_json {
        pm_stage::write_json(path, &serde_json::to_value(&report)?)?;
    }
    Ok(report)
}

/// What the irradiance cache did in this run.
#[derive(Default)]
struct CacheReport {
    /// Records (made or read).
    records: u64,
    /// Wall time of the prepass [s] (0 when read from a file).
    prepass_seconds: f64,
    /// Final-gather rays the prepass traced.
    prepass_rays: u64,
    /// Where the records came from.
    source: &'static str,
}

/// One render: everything but the photon maps, which differ in record type.
struct Job<'a> {
    cli: &'a Cli,
    scene: &'a pm_scene::Scene,
    camera: &'a pm_scene::Camera,
    film: pm_render::Film,
    rect: Rect,
    mode: Method,
    indirect: bool,
    /// The volume map, when given.
    volume: Option<&'a pm_format::PhotonMap<FullPhoton>>,
    /// Set when --time-budget stopped a render with --state before its passes.
    unfinished: &'a std::cell::Cell<bool>,
}

impl Job<'_> {
    fn run<G: PhotonRecord>(
        &self,
        global: Option<&pm_format::PhotonMap<G>>,
        caustic: Option<&pm_format::PhotonMap<FullPhoton>>,
    ) -> Result<(Option<Image>, RenderStats, CacheReport)> {
        if !self.mode.needs().photon_maps {
            ensure!(self.cli.icache.is_none(), "--icache: --mode {} uses no irradiance cache", self.mode);
            let r = self.render(Input::<G>::Scene(self.scene))?;
            return Ok((Some(r.image), r.stats, CacheReport::default()));
        }
        let p = &self.cli.settings.render;
        let records = global.map(|m| &m.records[..]);
        let irr_nodes = records.map(pm_render::irradiance_subset).unwrap_or_default();
        // The maps searched for k nearest photons get leaf buckets: the caustic map,
        // and the global map when this render makes k-nearest estimates from it (with
        // precomputed lookups it does not, and its 400,000 photons' buckets would be
        // built for nothing); the irradiance subset answers nearest-photon lookups
        // only, which buckets slow.
        let global_buckets =
            records.filter(|_| self.mode.searches_global(p.gather_lookup)).map(Buckets::new).unwrap_or_default();
        let caustic_buckets = caustic.map(|c| Buckets::new(&c.records)).unwrap_or_default();
        let maps = Maps {
            global: records.map(|r| KdTree::with_buckets(r, &global_buckets)),
            irradiance: (!irr_nodes.is_empty()).then(|| KdTree::new(&irr_nodes[..])),
            caustic: caustic.map(|c| KdTree::with_buckets(&c.records[..], &caustic_buckets)),
            volume: self.volume.map(|v| {
                pm_render::VolumeMap::new(
                    self.scene,
                    &v.records,
                    p.volume_k,
                    p.volume_radius_rel_diag * self.scene.bounds.diagonal(),
                    self.indirect && p.gather_lookup == Lookup::Precomputed,
                    p.volume_estimate == pm_render::VolumeEstimate::Beam,
                )
            }),
        };
        let map_hash = global.map_or([0; 32], |m| m.header.payload_hash);
        let mut pm = PhotonMapping::new(self.scene, maps, p, self.indirect)
            .map_err(|e| anyhow::anyhow!("{}: {e}", self.cli.scene.display()))?;
        let mut cache = CacheReport::default();
        let uses_cache = pm.wants_cache() && self.mode.needs().cache;
        if let Some(path) = &self.cli.icache {
            ensure!(
                uses_cache,
                "--icache: this render uses no irradiance cache (mode {}, --icache-accuracy {})",
                self.mode,
                p.icache_accuracy
            );
            let file = pm_format::read_cache(path)?;
            ensure!(file.scene_hash == self.scene.content_hash, "{}: made from another scene", path.display());
            ensure!(file.map_hash == map_hash, "{}: made from another global photon map", path.display());
            let key = pm.cache_key(&self.film);
            if let Some((had, has)) = pm_format::key_difference(&file.params, &key) {
                bail!("{}: made with {had}, this render has {has}: run --icache-out again", path.display());
            }
            pm = pm.with_cache_records(&file.records);
            cache = CacheReport { records: file.records.len() as u64, source: "file", ..Default::default() };
        } else if uses_cache || self.cli.icache_out.is_some() {
            ensure!(pm.wants_cache(), "--icache-out needs --icache-accuracy above 0 and indirect light");
            let progress = Progress::new("icache", 0);
            let c = IrradianceCache::prepass(&pm, self.camera, &self.film);
            let prepass_seconds = progress.finish();
            let prepass_rays = pm.counters().stats().gather_rays;
            cache = CacheReport { records: c.len() as u64, prepass_seconds, prepass_rays, source: "prepass" };
            if let Some(out) = &self.cli.icache_out {
                let file = pm_format::CacheFile {
                    width: self.film.width,
                    height: self.film.height,
                    scene_hash: self.scene.content_hash,
                    map_hash,
                    params: pm.cache_key(&self.film),
                    records: c.to_records(),
                };
                pm_format::write_cache(out, &file)?;
                return Ok((None, pm.counters().stats(), cache));
            }
            pm = pm.with_cache(c);
        }
        let r = self.render(Input::PhotonMaps(Box::new(pm)))?;
        Ok((Some(r.image), r.stats, cache))
    }

    /// The image by the method chosen, with a progress bar over its pixels (or
    /// its passes, checkpoints and time budget: [`Self::progressive`]).
    fn render<G: PhotonRecord>(&self, input: Input<'_, G>) -> Result<pm_methods::Rendered> {
        let view = View { camera: self.camera, film: &self.film, rect: self.rect };
        let r = if in_passes(self.cli) {
            self.progressive(input, view)
        } else {
            let progress = Progress::new("render", self.rect.area() as u64);
            let r = pm_methods::render(&self.cli.settings, input, view, None, &|d, _| progress.set(d));
            progress.finish();
            r
        };
        r.map_err(|e| anyhow::anyhow!("{e}"))
    }

    /// A progressive method, pass by pass, from the state file's passes when there
    /// is one, with checkpoints and the time budget.
    fn progressive<G: PhotonRecord>(&self, input: Input<'_, G>, view: View) -> Result<pm_methods::Rendered, String> {
        let cli = self.cli;
        let total = cli.settings.passes().unwrap_or(0);
        let start = match &cli.state {
            Some(path) if path.exists() => {
                Some((path.as_path(), pm_methods::State::read(self.mode, path).map_err(|e| e.to_string())?))
            }
            _ => None,
        };
        if let Some(dir) = cli.state.as_deref().and_then(|p| p.parent()).filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
        }
        let progress = Progress::new(&format!("{} passes", self.mode), total as u64);
        let region =
            (self.rect != self.film.rect()).then_some([self.rect.x0, self.rect.y0, self.rect.x1, self.rect.y1]);
        let t0 = std::time::Instant::now();
        let per_pass = cli.settings.photons_per_pass();
        let mut after_pass = |s: &dyn Progressive| -> Result<bool, String> {
            let done = s.passes();
            // What the passes traced: photon paths (SPPM), or samples a pixel.
            let traced = match per_pass {
                Some(n) => format!("{} photon paths", done as u64 * n),
                None => format!("{done} samples a pixel"),
            };
            let go_on = cli.time_budget.is_none_or(|b| t0.elapsed().as_secs_f64() < b);
            let checkpoint = cli.checkpoint.is_some_and(|k| k > 0 && done.is_multiple_of(k));
            // The noise estimate reads the whole image: only where it is shown.
            let noise = (progress.shown() || checkpoint)
                .then(|| s.noise())
                .flatten()
                .map_or(String::new(), |n| format!(", noise ~{:.1}% (bias not included)", 100.0 * n));
            progress.set(done as u64);
            progress.message(&format!("{traced}{noise}"));
            if (checkpoint || !go_on || done == total)
                && let Some(path) = &cli.state
            {
                s.state().write(path).map_err(|e| e.to_string())?;
            }
            if let (true, Some(out)) = (checkpoint && done < total, &cli.out) {
                write_exr(cli, out, region, &layers_of(s.region_image(self.rect))).map_err(|e| format!("{e:#}"))?;
                eprintln!("photon-render: checkpoint: {done} passes written to {} ({traced}{noise})", out.display());
            }
            Ok(go_on)
        };
        let resume = start.as_ref().map(|(path, file)| (*path, file));
        let passes = Passes { start: resume, after_pass: &mut after_pass };
        let r = pm_methods::render(&cli.settings, input, view, Some(passes), &|_, _| {});
        progress.finish();
        if let (Some((path, file)), Ok(_)) = (&start, &r) {
            eprintln!("photon-render: continued from the {} passes in {}", file.passes(), path.display());
        }
        let r = r?;
        self.unfinished.set(r.passes.is_some_and(|done| done < total) && cli.state.is_some());
        Ok(r)
    }
}

/// Write the render's layers to `out` (and create the folders of the other
/// outputs): a region's EXR says where it sits, for `cargo xtask assemble`.
fn write_exr(cli: &Cli, out: &std::path::Path, region: Option<[u32; 4]>, layers: &pm_image::Layers) -> Result<()> {
    // Tiles of a job plan write into a folder of their own.
    for file in [Some(out), cli.png.as_deref(), cli.stats_json.as_deref()].into_iter().flatten() {
        if let Some(dir) = file.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
        }
    }
    match region {
        Some([x0, y0, _, _]) => {
            let p = &cli.settings.render;
            let at = pm_image::Placement { x: x0, y: y0, full_width: p.width, full_height: p.height };
            pm_image::write_exr_region(out, layers, at)
        }
        None => pm_image::write_exr(out, layers),
    }
}

/// An image's layers as the EXR writer takes them.
fn layers_of(image: pm_render::Image) -> pm_image::Layers {
    pm_image::Layers {
        width: image.width,
        height: image.height,
        layers: image.into_named().map(|(n, px)| (n.to_string(), px)).collect(),
    }
}

fn report(
    cli: &Cli,
    region: Option<[u32; 4]>,
    scene: &pm_scene::Scene,
    s: &RenderStats,
    cache: &CacheReport,
    notes: &[String],
) -> RenderReport {
    let p = &cli.settings.render;
    let pixels = match region {
        Some([x0, y0, x1, y1]) => (x1 - x0) as f64 * (y1 - y0) as f64,
        None => p.width as f64 * p.height as f64,
    };
    RenderReport {
        mode: if cli.icache_out.is_some() { "icache".to_string() } else { cli.settings.mode.to_string() },
        indirect: !cli.no_indirect,
        params: p.clone(),
        sppm: (cli.settings.mode == Method::Sppm).then_some(cli.settings.sppm),
        region,
        seconds: s.seconds + cache.prepass_seconds,
        prepass_seconds: cache.prepass_seconds,
        thread_seconds: s.thread_seconds.iter().cloned().collect(),
        final_gathers: s.final_gathers,
        cache_records: cache.records,
        cache_source: cache.source.to_string(),
        cache_hits: s.cache_hits,
        gather_rays: s.gather_rays,
        prepass_gather_rays: cache.prepass_rays,
        secondary_gathers: s.secondary_gathers,
        lookups: s.lookups,
        lookup_misses: s.lookup_misses,
        lookup_rank_1_2_more: s.lookup_rank,
        terminated_paths: s.terminated_paths,
        nonfinite_pixels: s.nonfinite_pixels,
        thinned_shading_points: s.thinned,
        samples: s.samples,
        samples_per_pixel: s.samples as f64 / pixels,
        supersampled_pixels: s.supersampled_pixels,
        scene_diagonal_m: scene.bounds.diagonal(),
        threads: pm_stage::thread_count(),
        notes: notes.to_vec(),
        unfinished: false,
    }
}
