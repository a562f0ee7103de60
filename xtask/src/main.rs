//! Project automation, run as `cargo xtask <task>` (alias in `.cargo/config.toml`).
//! One module per task; `cargo xtask <task> --help` explains each.

use pm_runner::run;
use pm_scenegen::scenes as gen_scenes;
use pm_study::{differential, peer, plot, tradeoff};

mod assemble;
mod figure1;
mod golden;
mod ispm_plot;
mod live_study;
mod plan;
mod scale;
mod slurm_selftest;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// Project automation for the photon-map renderer.
#[derive(Parser, Debug)]
#[command(name = "cargo xtask", bin_name = "cargo xtask")]
struct Cli {
    #[command(subcommand)]
    task: Task,
}

#[derive(Subcommand, Debug)]
enum Task {
    /// Run the pipeline stages in order (photon-trace, photon-sort, photon-irradiance,
    /// the irradiance-cache step, photon-render) as separate processes; steps whose
    /// inputs and parameters are unchanged are skipped. With --trace-slices or
    /// --tiles, the job plan executed here; with --emit, its job files written instead.
    Run(RunCmd),
    /// Real-time photon mapping (Jozwowski 2002): photon-live with pipeline.toml's
    /// [live] settings, writing frames, live.apng and frames.csv.
    Live(run::LiveArgs),
    /// What the real-time mode's settings cost and buy: frame time split against
    /// per_frame, total, max_level and surfaces (Jozwowski 2002 Figures 21-27), and
    /// flicker and error against the batch image per distribution.
    LiveStudy(live_study::Args),
    /// Relative RMSE, bias and SSIM of an image against a reference.
    Compare(CompareArgs),
    /// Join region EXRs (photon-render --region) into the whole image and a PNG.
    Assemble(assemble::Args),
    /// The pipeline as a job graph (plan.json) with the trace cut into slices and the
    /// render into tiles (or, with --live, the animation into runs of frames), and
    /// with --emit the job files for Slurm (sbatch scripts, submit.sh) or an Open Job
    /// Description template.
    Plan(plan::Args),
    /// Run the emitted Slurm job on a one-node Slurm installed and started here
    /// (needs root on Debian or Ubuntu; not part of CI) and compare its image with
    /// `cargo xtask run`'s.
    SlurmSelftest(slurm_selftest::Args),
    /// What accuracy costs in time: a path-traced reference, then one setting at a
    /// time; CSV, markdown, plot.svg and plot.png.
    Tradeoff(tradeoff::Args),
    /// Christensen's Figure 1 (a)-(g), a contact sheet and the section 3 table beside
    /// the paper's numbers.
    Figure1(figure1::Args),
    /// Record or check the hashes of every output a restructuring must leave
    /// byte-identical (the default run, tiles and trace slices, photon-live with
    /// both methods, figure1).
    Golden(golden::Args),
    /// Image-space photon mapping's error against its frame time, drawn from the
    /// output of `cargo bench -p pm-ispm --bench ispm`.
    IspmPlot(ispm_plot::Args),
    /// What input at scale costs: each pipeline step under GNU time, with its wall
    /// time, peak memory, scene load and BVH build time (BENCHMARKS.md, with
    /// --scene scenes/instanced.gltf).
    Scale(scale::Args),
    /// Our path tracer against Mitsuba 3's on the same scenes: time per sample and
    /// means (needs a Python with mitsuba; not part of CI).
    Peer(peer::Args),
    /// Every method against the path tracer on generated scenes no one tuned for
    /// (seeded, written to OUT/scenes): each method on the repository's settings,
    /// judged by the bound its documentation states, in mean and 8 x 8 blocks per
    /// layer; OUT/report.json and a one-line summary.
    Differential(differential::Args),
    /// Every layer of an EXR image (the image itself as `total`) as a Portable
    /// Float Map, DIR/<layer>.pfm: float RGB from the bottom row up, what the
    /// Blender add-on loads into its render passes.
    Layers {
        /// The image (OpenEXR, as photon-render writes it).
        image: PathBuf,
        /// The folder to write the maps into.
        #[arg(long)]
        pfm: PathBuf,
    },
    /// The Blender add-on (blender/photon_map) as an extension zip,
    /// target/blender/photon_map-VERSION.zip, with schema.json (the settings,
    /// from pipeline.toml's parameter definitions) and the folder of this
    /// repository's release programs; builds them first. Install it with
    /// Blender's Preferences > Get Extensions > Install from Disk.
    BlenderAddon,
    /// The Blender add-on's tests (tests/blender/test_addon.py) under Blender as a
    /// Python module (bpy 4.5.4, installed into target/bpy when missing): renders
    /// through the add-on against Cycles, world orientation, volume conversion,
    /// passes, cancelling, an animation.
    BlenderTest {
        /// Run only the test of this name.
        #[arg(long)]
        only: Option<String>,
    },
    /// Print pipeline.toml's parameters as JSON, from their one definition:
    /// each section's keys with option, documentation (units), type, default,
    /// accepted range and choices; the render methods and quality words. The
    /// Blender add-on's settings are made from it.
    Schema,
    /// Write scenes/*.gltf + .bin from code.
    GenScenes {
        /// Fail if the committed files differ from what the code generates.
        #[arg(long)]
        check: bool,
        /// Write instead the memory benchmark's big scenes (a room with 100 spheres:
        /// 1 million and 10 million triangles) into out/big-scenes (not committed).
        #[arg(long)]
        big: bool,
    },
}

/// Options of `cargo xtask run`.
#[derive(clap::Args, Debug)]
struct RunCmd {
    #[command(flatten)]
    run: run::RunArgs,
    /// Do not run: write the plan's job files for SYSTEM (slurm or openjd) into DIR,
    /// as `cargo xtask plan --emit SYSTEM --plan-out DIR` does.
    #[arg(long, num_args = 2, value_names = ["SYSTEM", "DIR"])]
    emit: Option<Vec<String>>,
}

/// Options of `cargo xtask compare`.
#[derive(clap::Args, Debug)]
struct CompareArgs {
    /// The image (OpenEXR).
    image: PathBuf,
    /// The reference (OpenEXR) of the same size.
    reference: PathBuf,
    /// Leave out pixels where the reference exceeds this radiance [W sr^-1 m^-2]
    /// (the light's own pixels).
    #[arg(long, default_value_t = f32::INFINITY)]
    mask_above: f32,
    /// The layer to compare (direct, caustic, indirect, specular) [default: the
    /// image, the total of the layers].
    #[arg(long, value_parser = parse_layer)]
    layer: Option<pm_color::Layer>,
    /// Also print, for blocks of N x N pixels, the image's mean over the
    /// reference's in percent (channel means; "  -" where the reference is black):
    /// where in the picture a bias lives; then the root mean square and the worst
    /// of the blocks' relative errors.
    #[arg(long, value_name = "N")]
    blocks: Option<usize>,
    /// Also write a PNG of the layer: the image, the reference (both scaled so the
    /// reference's mean is mid-grey) and their ratio (red brighter, blue darker;
    /// full colour at a factor of 2), side by side.
    #[arg(long, value_name = "FILE")]
    png: Option<PathBuf>,
    /// Judge the pixels `cargo xtask differential` judges: leave out those that
    /// see one of this scene's emitters (directly or in mirrors and glass) and
    /// their neighbours, and print the mean as it does (kept image over kept
    /// reference, minus 1).
    #[arg(long, value_name = "GLTF")]
    scene: Option<PathBuf>,
    /// With `--layer indirect`: add each image's caustic layer to it, as `cargo
    /// xtask differential` judges a method that draws its caustics into its
    /// indirect layer (the vertex method).
    #[arg(long)]
    with_caustics: bool,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let root = workspace_root();
    let result = match cli.task {
        Task::Run(RunCmd { run, emit: None }) => run::run(&run, &root).map(|_| ()),
        Task::Run(RunCmd { run, emit: Some(emit) }) => emit_plan(run, &emit, &root),
        Task::Live(a) => run::live(&a, &root),
        Task::LiveStudy(a) => live_study::run(&a, &root),
        Task::Compare(a) => compare(&a),
        Task::Assemble(a) => assemble::run(&a),
        Task::Plan(a) => plan::run(&a, &root),
        Task::SlurmSelftest(a) => slurm_selftest::run(&a, &root),
        Task::Tradeoff(a) => tradeoff::run(&a, &root),
        Task::Figure1(a) => figure1::run(&a, &root),
        Task::Golden(a) => golden::run(&a, &root),
        Task::IspmPlot(a) => ispm_plot::run(&a),
        Task::Scale(a) => scale::run(&a, &root),
        Task::Peer(a) => peer::run(&a, &root),
        Task::Differential(a) => differential::run(&a, &root).map(|_| ()),
        Task::BlenderAddon => blender_addon(&root),
        Task::BlenderTest { only } => blender_test(&root, only.as_deref()),
        Task::Layers { image, pfm } => write_layers(&image, &pfm),
        Task::Schema => {
            println!("{}", serde_json::to_string_pretty(&pm_pipeline::schema()).expect("the schema serialises"));
            Ok(())
        }
        Task::GenScenes { big: true, .. } => gen_scenes::run_big(&root.join("out/big-scenes")),
        Task::GenScenes { check, .. } => gen_scenes::run(&root.join("scenes"), check),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", format!("{e:#}").replace('\n', " "));
            pm_stage::exit_code(&e)
        }
    }
}

/// `cargo xtask run --emit SYSTEM DIR`: the plan's job files, not a run.
fn emit_plan(run: run::RunArgs, emit: &[String], root: &std::path::Path) -> Result<()> {
    let [system, dir] = emit else { anyhow::bail!("--emit needs SYSTEM and DIR") };
    let system = <plan::Emit as clap::ValueEnum>::from_str(system, true)
        .map_err(|_| anyhow::anyhow!("--emit {system}: expected slurm or openjd"))?;
    let args = plan::Args {
        run,
        plan_out: dir.into(),
        emit: Some(system),
        estimate: None,
        live: false,
        frames: 120,
        frame_tasks: 1,
    };
    plan::run(&args, root)
}

/// `cargo xtask blender-addon`.
fn blender_addon(root: &std::path::Path) -> Result<()> {
    use pm_runner::blender;
    let bins = pm_runner::bins::Bins::build(root)?;
    let dir = pm_runner::bins::target_dir(root).join("blender");
    let staged = blender::stage_addon(root, &bins.dir, &dir)?;
    let zip = dir.join(format!("photon_map-{}.zip", blender::addon_version(root)?));
    blender::zip_addon(&staged, &zip)?;
    println!(
        "wrote {} (the add-on, for Blender 4.2 and newer; it runs the programs in {})",
        zip.display(),
        bins.dir.display()
    );
    Ok(())
}

/// `cargo xtask blender-test`.
fn blender_test(root: &std::path::Path, only: Option<&str>) -> Result<()> {
    use pm_runner::blender;
    let bins = pm_runner::bins::Bins::build(root)?;
    let python = blender::ensure_bpy(root)?;
    let work = pm_runner::bins::target_dir(root).join("blender-test");
    std::fs::create_dir_all(&work)?;
    blender::run_tests(root, &python, &bins.dir, &work, only)
}

/// `cargo xtask layers IMAGE --pfm DIR`.
fn write_layers(image: &std::path::Path, dir: &std::path::Path) -> Result<()> {
    let img = pm_image::read_exr(image)?;
    std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("{}: cannot create: {e}", dir.display()))?;
    for (name, px) in &img.layers {
        pm_image::write_pfm(&dir.join(format!("{name}.pfm")), img.width as usize, img.height as usize, px)?;
    }
    let names: Vec<&str> = img.layers.iter().map(|l| l.0.as_str()).collect();
    println!("wrote {} layers of {} to {}: {}", names.len(), image.display(), dir.display(), names.join(", "));
    Ok(())
}

/// A layer named on the command line.
fn parse_layer(name: &str) -> Result<pm_color::Layer, String> {
    pm_color::Layer::from_name(name)
        .ok_or_else(|| format!("expected direct, caustic, indirect or specular, got {name}"))
}

/// The repository root (the parent of this crate's folder).
fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask lives one level below the root").to_owned()
}

fn compare(a: &CompareArgs) -> Result<()> {
    let (ia, ib) = (pm_image::read_exr(&a.image)?, pm_image::read_exr(&a.reference)?);
    if (ia.width, ia.height) != (ib.width, ib.height) {
        anyhow::bail!(
            "{} is {}x{} but {} is {}x{}",
            a.image.display(),
            ia.width,
            ia.height,
            a.reference.display(),
            ib.width,
            ib.height
        );
    }
    let pick = |i: &pm_image::Layers, p: &PathBuf| {
        let name = pm_color::layer_name(a.layer);
        i.total_or_layer(a.layer).ok_or_else(|| anyhow::anyhow!("{}: no layer {name}", p.display()))?;
        anyhow::Ok(i.pixels_caustics_in_indirect(a.layer, a.with_caustics))
    };
    let (la, lb) = (pick(&ia, &a.image)?, pick(&ib, &a.reference)?);
    let (w, h) = (ia.width as usize, ia.height as usize);
    let keep: Vec<bool> = match &a.scene {
        Some(scene) => differential::emitters_left_out(&pm_scene::load(scene)?, w, h)?
            .into_iter()
            .zip(&lb)
            .map(|(k, p)| k && p.max_element() <= a.mask_above)
            .collect(),
        None => lb.iter().map(|p| p.max_element() <= a.mask_above).collect(),
    };
    let e = pm_image::compare(&la, &lb, a.mask_above);
    let ssim = pm_image::ssim(&la, &lb, ia.width as usize, ia.height as usize);
    let identical = la.iter().zip(&lb).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits));
    // The report is written at once at the end: a reader that closes the pipe
    // early (`| head`) is no error.
    let mut out = String::new();
    use std::fmt::Write as _;
    writeln!(
        out,
        "relative RMSE {:.5}  relative bias {:+.5}  SSIM {ssim:.4}  pixels {}{}",
        e.rel_rmse,
        e.rel_bias,
        e.pixels,
        if identical { "  (bit-identical)" } else { "" }
    )?;
    if a.scene.is_some() {
        let g = pm_image::accuracy::agreement(&la, &lb, w, &keep, 8);
        writeln!(out, "the pixels the differential checks judge: mean {:+.2}%", 100.0 * g.mean)?;
    }
    if let Some(n) = a.blocks.filter(|&n| n > 0) {
        let (ba, bb) = (pm_image::block_means(&la, w, n), pm_image::block_means(&lb, w, n));
        for (row_a, row_b) in ba.chunks(w.div_ceil(n)).zip(bb.chunks(w.div_ceil(n))) {
            let row: Vec<String> = row_a
                .iter()
                .zip(row_b)
                .map(|(i, r)| {
                    let (i, r) = (pm_color::mean(*i) as f64, pm_color::mean(*r) as f64);
                    if r > 0.0 { format!("{:4.0}", 100.0 * i / r) } else { "   -".into() }
                })
                .collect();
            writeln!(out, "{}", row.join(""))?;
        }
        // The blocks that count, as the differential checks count them (at least
        // half their pixels kept, not black next to the image).
        let g = pm_image::accuracy::agreement(&la, &lb, w, &keep, n);
        writeln!(
            out,
            "{n} x {n} blocks: RMS {:.2}%, worst {:.1}% at column {}, row {}",
            100.0 * g.block_rms,
            100.0 * g.worst_block,
            g.worst_at.0,
            g.worst_at.1
        )?;
    }
    if let Err(e) = std::io::Write::write_all(&mut std::io::stdout().lock(), out.as_bytes())
        && e.kind() != std::io::ErrorKind::BrokenPipe
    {
        return Err(e.into());
    }
    if let Some(png) = &a.png {
        pm_image::write_png(png, 3 * w as u32, h as u32, &side_by_side(&la, &lb, w, h), 0.0)?;
    }
    Ok(())
}

/// `image | reference | ratio` for `cargo xtask compare --png`: the two scaled so
/// the reference's mean is 0.18, the ratio of their channel means as red (image
/// brighter) or blue (darker), saturating at a factor of 2; grey where both are black.
fn side_by_side(image: &[glam::Vec3], reference: &[glam::Vec3], w: usize, h: usize) -> Vec<glam::Vec3> {
    use glam::Vec3;
    let gain = pm_image::mid_grey_gain(reference);
    let mut out = vec![Vec3::ZERO; 3 * w * h];
    for y in 0..h {
        for x in 0..w {
            let (i, r) = (image[y * w + x], reference[y * w + x]);
            let row = &mut out[y * 3 * w..(y + 1) * 3 * w];
            row[x] = i * gain;
            row[w + x] = r * gain;
            let (mi, mr) = (pm_color::mean(i), pm_color::mean(r));
            row[2 * w + x] = if mi <= 0.0 && mr <= 0.0 {
                Vec3::splat(0.2)
            } else {
                let t = ((mi.max(1e-12) / mr.max(1e-12)).log2()).clamp(-1.0, 1.0);
                if t > 0.0 { Vec3::new(0.2 + 0.8 * t, 0.2, 0.2) } else { Vec3::new(0.2, 0.2, 0.2 - 0.8 * t) }
            };
        }
    }
    out
}
