//! `photon-live`: real-time photon mapping as a program that writes files, by
//! either method: vertex estimates from a ring buffer of photon paths (Jozwowski
//! 2002, `pm-vertex`) or image-space photon mapping (McGuire and Luebke 2009,
//! `pm-ispm`). Writes `frames/NNNN.png` (and linear `frames/NNNN.exr` with
//! `--exr`), an animated preview `live.apng`, and `frames.csv` with each frame's
//! time split into the method's steps. A thin layer over `pm-live`, which runs
//! either method's frames.

use anyhow::{Context, Result, ensure};
use clap::Parser;
use pm_ispm::Ispm;
use pm_live::{Live, World};
pub use pm_methods::live::{LiveMethod, LiveParams};
use pm_stage::Progress;
use pm_vertex::Vertex;
use std::path::PathBuf;

/// Command line of `photon-live`.
#[derive(Parser, Debug)]
#[command(
    name = "photon-live",
    about = "Real-time photon mapping: frames by vertex estimates from a ring buffer of photon paths, or by \
image-space photon mapping (PNG, EXR, APNG, CSV)",
    long_about = "Real-time photon mapping. --method vertex (Jozwowski 2002, sections 4 and 5): each frame shoots \
--per-frame photon paths into a ring buffer of --total paths of up to --max-level hits, updates the photon search \
over the used slots, estimates irradiance E [W m^-2] at the mesh's corners from the k nearest photons, and draws the \
mesh with the corner radiance (reflectance / pi x E) interpolated across each triangle, direct light by shadow rays, \
shadow maps or from the photons, and mirrors and glass by ray tracing. --method ispm (McGuire and Luebke 2009): per \
light a bounce map of --bounce-res texels a side, --bounces further photons per path with kernels sized by path \
density (--kernel-*), and indirect light by splatting photon volumes over the eye's G-buffer (--subsample F splats \
at 1/F resolution and upsamples). Radiance in the EXR frames is W sr^-1 m^-2 per RGB channel. Writes \
OUT/frames/NNNN.png, OUT/live.apng and OUT/frames.csv (seconds per step; for ispm the paper's Table 2 split). \
With --frame-task K/N it renders the K-th of N runs of frames (for an animation split across machines) and \
`photon-live assemble` joins them.",
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
// Help texts give units as [m] and [s], not links.
#[allow(rustdoc::broken_intra_doc_links)]
pub struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Scene (glTF 2.0) drawn from its first camera.
    #[arg(long, required = true)]
    pub scene: Option<PathBuf>,
    /// A simpler scene to trace photons in (section 4.4.1, scene simplification);
    /// default: the scene itself.
    #[arg(long)]
    pub photon_scene: Option<PathBuf>,
    /// Output folder (created if missing).
    #[arg(long, required = true)]
    pub out: Option<PathBuf>,
    /// Frames to render.
    #[arg(long, default_value_t = 60)]
    pub frames: u32,
    /// Render only the K-th of N runs of consecutive frames (frames K x F / N up to
    /// (K + 1) x F / N of --frames F) into frames/NNNN.png and a part of frames.csv;
    /// earlier frames are simulated without drawing, so each frame equals one run's.
    /// `photon-live assemble` then writes live.apng and frames.csv.
    #[arg(long, value_name = "K/N", value_parser = parse_task)]
    pub frame_task: Option<(u32, u32)>,
    /// Also write each frame as linear OpenEXR (frames/NNNN.exr).
    #[arg(long)]
    pub exr: bool,
    /// Write the ring buffer after frame K as a photon-map file (buffer-K.pmap) that
    /// photon-inspect reads.
    #[arg(long)]
    pub dump_frame: Option<u64>,
    /// Random seed; equal seeds give identical frames for any thread count.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Show the frames in a window as they are drawn; arrow keys move the lights
    /// (0.1 m a key, PageUp/PageDown up and down), Escape stops. Needs the `window`
    /// cargo feature and a display; without a display the frames are only written.
    #[arg(long)]
    pub window: bool,
    /// The real-time settings (pipeline.toml's \[live\], \[live.vertex\] and \[live.ispm\] sections).
    #[command(flatten)]
    pub params: LiveParams,
    /// How the scene files are read.
    #[command(flatten)]
    pub scene_options: pm_stage::SceneOptions,
}

/// Subcommands.
#[derive(clap::Subcommand, Debug)]
enum Command {
    /// Join the frames of `--frame-task K/N` runs (all N, into one output folder)
    /// into live.apng and frames.csv, as one run writes them.
    Assemble {
        /// The output folder the tasks wrote into.
        #[arg(long)]
        out: PathBuf,
        /// Frames of the animation (the tasks' --frames).
        #[arg(long)]
        frames: u32,
        /// Frames per second of the preview (the tasks' --fps).
        #[arg(long, default_value_t = 60.0)]
        fps: f32,
    },
}

fn parse_task(s: &str) -> Result<(u32, u32), String> {
    pm_stage::parse_part(s, "run")
}

/// Run it (or its subcommand).
pub fn main(cli: &Cli) -> Result<()> {
    match &cli.command {
        Some(Command::Assemble { out, frames, fps }) => assemble(out, *frames, *fps),
        None => run(cli),
    }
}

/// Render the frames by the method chosen.
pub fn run(cli: &Cli) -> Result<()> {
    let (Some(scene_path), Some(out)) = (&cli.scene, &cli.out) else {
        anyhow::bail!("--scene and --out are required");
    };
    let p = &cli.params;
    p.check(true).map_err(|e| anyhow::anyhow!(e))?;
    ensure!(cli.frames >= 1, "--frames must be at least 1");
    ensure!(!(cli.window && cli.frame_task.is_some()), "--window shows one whole run; it cannot be a --frame-task");
    if p.method == LiveMethod::Ispm {
        ensure!(
            cli.dump_frame.is_none(),
            "--dump-frame writes the vertex method's ring buffer; --method ispm has none"
        );
        ensure!(cli.photon_scene.is_none(), "--photon-scene: --method ispm traces its photons in the scene drawn");
    }
    let frames = match cli.frame_task {
        Some((k, n)) => pm_live::task_frames(k, n, cli.frames),
        None => 0..cli.frames,
    };
    pm_stage::init_threads(cli.threads)?;
    let scene = pm_stage::load_scene("photon-live", scene_path, &cli.scene_options)?;
    if p.frame.direct == pm_live::DirectMode::ShadowMap
        && let Some(why) = pm_live::why_no_shadow_maps(&scene)
    {
        eprintln!("photon-live: note: --direct shadow-map: {why}; every light takes shadow rays");
    }
    if scene.has_scattering_media() {
        eprintln!(
            "photon-live: note: media attenuate what the eye and the photons see; the volume layer is the light they scatter toward the eye straight from the lights (single scattering), light scattered more than once is left out"
        );
    }
    let at_scene = |e: String| anyhow::anyhow!("{}: {e}", scene_path.display());
    match p.method {
        LiveMethod::Vertex => {
            let photon_scene = match &cli.photon_scene {
                Some(path) => Some(pm_stage::load_scene("photon-live", path, &cli.scene_options)?),
                None => None,
            };
            let (hash, origin, diagonal) = (scene.content_hash, scene.origin.to_array(), scene.bounds.diagonal());
            let live =
                pm_vertex::live(scene, photon_scene, p.frame.clone(), p.vertex.clone(), cli.seed).map_err(at_scene)?;
            if let Some(s) = live.method().subdivision() {
                eprintln!("photon-live: {s}");
            }
            let dump = |live: &Live<Vertex>, path: &std::path::Path| dump(live, hash, diagonal, origin, path);
            run_frames(cli, out, live, frames, dump)
        }
        LiveMethod::Ispm => {
            let world = World::new(scene, None).map_err(at_scene)?;
            let method = Ispm::new(&world, p.frame.clone(), p.ispm.clone(), cli.seed).map_err(at_scene)?;
            run_frames(cli, out, Live::new(world, method), frames, |_, _| Ok(()))
        }
    }
}

/// Draw `frames` (simulating the ones before them) and write them, the preview and
/// frames.csv (or this task's part of it) into `out`; `dump` writes the method's
/// photons after the frame `--dump-frame` names.
fn run_frames<M: pm_live::FrameMethod>(
    cli: &Cli,
    out: &std::path::Path,
    mut live: Live<M>,
    frames: std::ops::Range<u32>,
    dump: impl Fn(&Live<M>, &std::path::Path) -> Result<()>,
) -> Result<()> {
    let f = &cli.params.frame;
    let frames_dir = out.join("frames");
    std::fs::create_dir_all(&frames_dir).with_context(|| format!("{}: cannot create", frames_dir.display()))?;
    let (w, h) = (f.width, f.height);
    let mut view = if cli.window { window::View::open(w, h)? } else { None };
    let progress = Progress::new("frames", frames.end as u64);
    let mut rows: Vec<M::Row> = Vec::new();
    let mut apng = Vec::new();
    let fixed = cli.scene_options.time_s(pm_params::Naming::Cli).map_err(|e| anyhow::anyhow!(e))?;
    for i in 0..frames.end {
        // Frame i shows time i / fps: animated lights and camera move there.
        live.set_time(fixed.unwrap_or(i as f32 / f.fps));
        if i < frames.start {
            // Another task draws it; this one needs only the state it leaves.
            live.skip().map_err(|e| anyhow::anyhow!(e))?;
            progress.set(i as u64 + 1);
            continue;
        }
        let row = live.step().map_err(|e| anyhow::anyhow!(e))?;
        let image = live.frame_layers();
        let bytes = pm_image::srgb8(image.total(), f.exposure);
        pm_image::write_srgb8_png_fast(&frames_dir.join(format!("{i:04}.png")), w, h, &bytes)?;
        if cli.exr {
            let layers = pm_image::Layers {
                width: w,
                height: h,
                layers: image.named().map(|(n, px)| (n.to_string(), px.to_vec())).collect(),
            };
            pm_image::write_exr(&frames_dir.join(format!("{i:04}.exr")), &layers)?;
        }
        if cli.dump_frame == Some(i as u64) {
            dump(&live, &out.join(format!("buffer-{i}.pmap")))?;
        }
        apng.push(bytes);
        rows.push(row);
        progress.set(i as u64 + 1);
        if let Some(v) = view.as_mut() {
            match v.show(apng.last().expect("pushed above"), w, h) {
                Some(delta) => live.move_lights(delta),
                None => break,
            }
        }
    }
    progress.finish();
    let csv = pm_live::rows_to_csv(&rows).map_err(|e| anyhow::anyhow!("frames.csv: {e}"))?;
    let csv_path = if cli.frame_task.is_some() {
        frames_dir.join(pm_live::frames_part_file(&frames))
    } else {
        pm_image::write_apng(&out.join("live.apng"), w, h, &apng, f.fps)?;
        out.join("frames.csv")
    };
    pm_stage::write_text(&csv_path, &csv)?;
    let mean = pm_live::mean_frame_seconds(&rows, live.method().warm_up());
    eprintln!(
        "photon-live: {} frames of {w}x{h}; mean frame time after warm-up {:.2} ms ({:.1} fps)",
        frames.len(),
        1e3 * mean,
        if mean > 0.0 { 1.0 / mean } else { 0.0 }
    );
    Ok(())
}

/// `photon-live assemble`: live.apng from frames/NNNN.png and frames.csv from the
/// tasks' parts, which must cover frames 0..`frames` without gap or overlap.
fn assemble(out: &std::path::Path, frames: u32, fps: f32) -> Result<()> {
    ensure!(frames >= 1, "--frames must be at least 1");
    ensure!(fps.is_finite() && fps > 0.0, "--fps must be positive");
    let dir = out.join("frames");
    let mut parts: Vec<(u32, u32, PathBuf)> = Vec::new();
    for entry in std::fs::read_dir(&dir).with_context(|| format!("{}: cannot read", dir.display()))? {
        let path = entry?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if let Some(range) = name.strip_prefix("part-").and_then(|n| n.strip_suffix(".csv"))
            && let Some((a, b)) = range.split_once('-')
            && let (Ok(a), Ok(b)) = (a.parse(), b.parse())
        {
            parts.push((a, b, path));
        }
    }
    parts.sort();
    let mut csv = String::new();
    let mut next = 0;
    for (a, b, path) in &parts {
        ensure!(
            *a == next,
            "{}: starts at frame {a} but the parts before it end at {next} (gap or overlap)",
            path.display()
        );
        let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
        let (header, rows) = text.split_once('\n').with_context(|| format!("{}: no header line", path.display()))?;
        if csv.is_empty() {
            csv = format!("{header}\n");
        }
        ensure!(csv.starts_with(header), "{}: columns differ from the first part's", path.display());
        csv.push_str(rows);
        next = *b;
    }
    ensure!(next == frames, "{}: the parts cover frames 0..{next}, not 0..{frames}", dir.display());
    let mut size = None;
    let mut images = Vec::with_capacity(frames as usize);
    for f in 0..frames {
        let path = dir.join(format!("{f:04}.png"));
        let (w, h, rgb) = pm_image::read_png_rgb8(&path)?;
        ensure!(size.is_none_or(|s| s == (w, h)), "{}: {w}x{h}, unlike the frames before it", path.display());
        size = Some((w, h));
        images.push(rgb);
    }
    let (w, h) = size.expect("at least one frame");
    pm_image::write_apng(&out.join("live.apng"), w, h, &images, fps)?;
    pm_stage::write_text(&out.join("frames.csv"), &csv)?;
    eprintln!("photon-live assemble: {frames} frames from {} parts into {}", parts.len(), out.display());
    Ok(())
}

/// The ring buffer's used slots as a global photon map (full records, unsorted).
fn dump(
    live: &Live<Vertex>,
    scene_hash: [u8; 32],
    diagonal: f32,
    origin: [f64; 3],
    path: &std::path::Path,
) -> Result<()> {
    use pm_format::{FullIrrPhoton, Header, Layout, MapKind, Order, PhotonMap, PhotonRecord};
    let ring = live.method().ring();
    let photons = ring.photons();
    let header = Header::new(
        MapKind::Global,
        Order::Unsorted,
        Layout::FullIrradiance,
        ring.filled() as u64,
        scene_hash,
        diagonal,
        serde_json::json!({"photon-live frame": live.frame() - 1}).to_string(),
    )
    .with_origin(origin);
    PhotonMap::new(header, photons.iter().map(FullIrrPhoton::encode).collect::<Vec<_>>()).write(path)?;
    Ok(())
}

/// The interactive window (cargo feature `window`).
#[cfg(feature = "window")]
mod window {
    use anyhow::Result;
    use glam::Vec3;
    use minifb::{Key, Window, WindowOptions};

    /// A window showing frames.
    pub struct View {
        win: Window,
        buf: Vec<u32>,
    }

    impl View {
        /// Open a window of `w` x `h` pixels, or say why not and return none (no
        /// display): the frames are then only written.
        pub fn open(w: u32, h: u32) -> Result<Option<View>> {
            match Window::new(
                "photon-live (arrows, PageUp/PageDown: move the light; Esc: stop)",
                w as usize,
                h as usize,
                WindowOptions::default(),
            ) {
                Ok(win) => Ok(Some(View { win, buf: Vec::new() })),
                Err(e) => {
                    eprintln!("photon-live: note: no window ({e}); writing files only");
                    Ok(None)
                }
            }
        }

        /// Show a frame of sRGB bytes; returns how the keys move the lights [m], or
        /// none when the window was closed or Escape pressed.
        pub fn show(&mut self, rgb: &[u8], w: u32, h: u32) -> Option<Vec3> {
            self.buf.clear();
            self.buf.extend(rgb.chunks_exact(3).map(|p| (p[0] as u32) << 16 | (p[1] as u32) << 8 | p[2] as u32));
            if !self.win.is_open() || self.win.is_key_down(Key::Escape) {
                return None;
            }
            self.win.update_with_buffer(&self.buf, w as usize, h as usize).ok()?;
            let step = 0.1;
            let mut d = Vec3::ZERO;
            for (key, v) in [
                (Key::Left, Vec3::new(-step, 0.0, 0.0)),
                (Key::Right, Vec3::new(step, 0.0, 0.0)),
                (Key::Up, Vec3::new(0.0, 0.0, -step)),
                (Key::Down, Vec3::new(0.0, 0.0, step)),
                (Key::PageUp, Vec3::new(0.0, step, 0.0)),
                (Key::PageDown, Vec3::new(0.0, -step, 0.0)),
            ] {
                if self.win.is_key_down(key) {
                    d += v;
                }
            }
            Some(d)
        }
    }
}

/// Without the `window` feature: `--window` is refused with how to build it.
#[cfg(not(feature = "window"))]
mod window {
    use anyhow::{Result, bail};

    /// Never constructed.
    pub struct View;

    impl View {
        /// Refuse: this build has no window.
        pub fn open(_: u32, _: u32) -> Result<Option<View>> {
            bail!(
                "--window: this photon-live was built without the window feature (cargo build --release -p photon-live --features window)"
            )
        }

        /// Unreachable: no view is ever opened.
        pub fn show(&mut self, _: &[u8], _: u32, _: u32) -> Option<glam::Vec3> {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `[live]` section and its method tables fill each part, and the
    /// arguments the runner passes (one flat set of options) give the same
    /// settings back on the command line.
    #[test]
    fn the_live_sections_and_one_set_of_options_fill_every_part() {
        let text =
            "method = \"ispm\"\nwidth = 64\nfps = 24\n[vertex]\nper_frame = 100\ntotal = 400\n[ispm]\nsubsample = 2";
        let p: LiveParams = toml::from_str(text).unwrap();
        assert_eq!(p.method, LiveMethod::Ispm);
        assert_eq!((p.frame.width, p.frame.fps), (64, 24.0));
        assert_eq!((p.vertex.per_frame, p.vertex.total), (100, 400));
        assert_eq!(p.ispm.subsample, 2);
        assert_eq!(toml::from_str::<LiveParams>("").unwrap(), LiveParams::default());
        let e = toml::from_str::<LiveParams>("method = \"photons\"").unwrap_err().to_string();
        assert!(e.contains("photons"), "{e}");
        let args = ["photon-live", "--scene", "s.gltf", "--out", "o"].map(String::from);
        let cli = Cli::try_parse_from(args.into_iter().chain(p.to_args())).unwrap();
        assert_eq!(cli.params, p);
    }
}
