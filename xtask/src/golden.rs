//! `cargo xtask golden`: the outputs a restructuring must leave byte-identical,
//! recorded once and compared at every later commit (issue 35). It runs the
//! default pipeline, the same with `--tiles 4 --trace-slices 3`, the path tracer,
//! progressive photon mapping (one run, and two averaged) and the fog Cornell box
//! at 128 x 128, `photon-live`
//! with both methods for 30 frames on the thesis's room and on cornell_spheres,
//! and `cargo xtask figure1`, each into its own folder, and hashes (blake3) every
//! file they write except those that carry wall times or absolute paths (JSON,
//! CSV, Markdown, SVG, job scripts).

use anyhow::{Context, Result, bail};
use pm_runner::bins::{self, Bins};
use pm_runner::run::{self, RunArgs};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options of `cargo xtask golden`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Write the hashes to this file (one `workload/file hash` line each).
    #[arg(long, conflicts_with = "check")]
    record: Option<PathBuf>,
    /// Compare the hashes with this file and fail, listing each difference, unless
    /// every output is byte-identical.
    #[arg(long)]
    check: Option<PathBuf>,
    /// Working folder for the outputs [default: out/golden].
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Extensions of files that hold times, paths or text derived from them.
const SKIPPED: [&str; 6] = ["json", "csv", "md", "svg", "sh", "txt"];

/// Run every workload and record or compare its outputs' hashes.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    if args.record.is_none() && args.check.is_none() {
        bail!("give --record FILE or --check FILE");
    }
    let out = args.out.clone().unwrap_or_else(|| root.join("out/golden"));
    if out.exists() {
        std::fs::remove_dir_all(&out).with_context(|| format!("{}: cannot clear", out.display()))?;
    }
    let bins = Bins::build(root)?;
    let pipeline = root.join("pipeline.toml");
    let batch = |name: &str, more: RunArgs| -> Result<()> {
        println!("golden: {name}");
        let a = RunArgs { pipeline: Some(pipeline.clone()), out: Some(out.join(name)), force: true, ..more };
        run::run_with(&a, root, &bins).map(|_| ())
    };
    batch("run-default", RunArgs::default())?;
    batch("run-tiles4-slices3", RunArgs { tiles: 4, trace_slices: 3, ..Default::default() })?;
    // The methods that trace their own paths, and a scene with a medium (the
    // volume map, its precomputed in-scattering and the volume layer), smaller.
    let small = |method| RunArgs { width: Some(128), height: Some(128), method, ..Default::default() };
    batch("run-path", small(Some(pm_methods::Method::Path)))?;
    batch("run-sppm", small(Some(pm_methods::Method::Sppm)))?;
    batch("run-sppm-runs2", RunArgs { runs: 2, ..small(Some(pm_methods::Method::Sppm)) })?;
    batch("run-fog", RunArgs { scene: Some(root.join("scenes/cornell_fog.gltf")), ..small(None) })?;
    for method in [pm_methods::live::LiveMethod::Vertex, pm_methods::live::LiveMethod::Ispm] {
        for (label, scene) in [("room", None), ("spheres", Some(root.join("scenes/cornell_spheres.gltf")))] {
            let name = format!("live-{method}-{label}");
            println!("golden: {name}");
            let la = run::LiveArgs {
                pipeline: Some(pipeline.clone()),
                scene,
                out: Some(out.join(&name)),
                method: Some(method),
                frames: 30,
                ..Default::default()
            };
            let mut set = run::live_setup(&la, root)?;
            // Linear EXR frames too: 8-bit PNGs could hide a change in the last bits.
            set.args.push("--exr".into());
            bins::run(&bins, "photon-live", &set.args, &name, true)?;
        }
    }
    println!("golden: figure1");
    crate::figure1::run(&crate::figure1::Args { out: Some(out.join("figure1")), size: 1024 }, root)?;

    let hashes = hash_tree(&out)?;
    let mut text = String::new();
    for (file, h) in &hashes {
        writeln!(text, "{file} {h}")?;
    }
    if let Some(path) = &args.record {
        std::fs::write(path, &text).with_context(|| format!("{}: cannot write", path.display()))?;
        println!("golden: {} hashes written to {}", hashes.len(), path.display());
    }
    if let Some(path) = &args.check {
        let want = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
        let want: BTreeMap<String, String> =
            want.lines().filter_map(|l| l.split_once(' ')).map(|(f, h)| (f.to_string(), h.to_string())).collect();
        let mut bad = Vec::new();
        for (file, h) in &want {
            match hashes.get(file) {
                Some(got) if got == h => {}
                Some(_) => bad.push(format!("{file}: differs")),
                None => bad.push(format!("{file}: missing")),
            }
        }
        for file in hashes.keys().filter(|f| !want.contains_key(*f)) {
            bad.push(format!("{file}: new"));
        }
        if !bad.is_empty() {
            for b in &bad {
                println!("  {b}");
            }
            bail!("{} of {} outputs are not byte-identical to {}", bad.len(), want.len(), path.display());
        }
        println!("golden: all {} outputs byte-identical to {}", hashes.len(), path.display());
    }
    Ok(())
}

/// blake3 of every kept file under `dir`, keyed by its path relative to `dir`
/// (with `/` separators).
fn hash_tree(dir: &Path) -> Result<BTreeMap<String, String>> {
    let mut hashes = BTreeMap::new();
    let mut stack = vec![dir.to_owned()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).with_context(|| format!("{}: cannot list", d.display()))? {
            let path = entry?.path();
            let name = path.file_name().unwrap_or_default().to_string_lossy().into_owned();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            let ext = path.extension().unwrap_or_default().to_string_lossy().to_lowercase();
            if name.starts_with('.') || SKIPPED.contains(&ext.as_str()) {
                continue;
            }
            let rel = path.strip_prefix(dir)?.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>();
            let bytes = std::fs::read(&path).with_context(|| format!("{}: cannot read", path.display()))?;
            hashes.insert(rel.join("/"), blake3::hash(&bytes).to_hex().to_string());
        }
    }
    Ok(hashes)
}
