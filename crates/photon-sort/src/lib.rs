//! Stage 2 of the pipeline (Christensen 1999 section 1.2): reorder a photon map into
//! a left-balanced kd-tree in heap order, so the file itself is the tree. A thin
//! layer over `pm-kdtree`.

use anyhow::Result;
use clap::Parser;
use pm_format::{Order, ReadExpect, with_map};
use pm_stage::Progress;
use pm_stage::report::SortReport;
use std::path::PathBuf;

/// Command line of `photon-sort`.
#[derive(Parser, Debug)]
#[command(
    name = "photon-sort",
    about = "Stage 2: reorder a photon map into a left-balanced kd-tree (heap order; the file is the tree)",
    long_about = "Stage 2 (Christensen 1999, section 1.2). Reads a photon map written by photon-trace and writes \
the same photons as a left-balanced kd-tree in heap order: node i has children 2i+1 and 2i+2 and its split axis in \
the flags byte, so the tree needs no memory beyond the records. Balancing is by median selection on the axis of \
largest extent, O(n log n), parallel and deterministic. Positions are in metres; nothing else changes."
)]
pub struct Cli {
    /// Photon map to sort (global.pmap or caustic.pmap).
    pub input: PathBuf,
    /// Output map (e.g. global.kd.pmap).
    #[arg(long)]
    pub out: PathBuf,
    /// Write statistics (count, depth, time) as JSON.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// Run the stage.
pub fn run(cli: &Cli) -> Result<SortReport> {
    pm_stage::init_threads(cli.threads)?;
    let mut map = pm_format::read(&cli.input, &ReadExpect::default())?;
    let n = map.len();
    let progress = Progress::new("sort", n as u64);
    let (depth, verified) = with_map!(&mut map, m => {
        let sorted = pm_kdtree::balance(&m.records);
        m.records = sorted;
        m.header.order = Order::KdTree;
        let tree = pm_kdtree::KdTree::new(&m.records);
        let depth = tree.depth();
        let verified = tree.verify().is_ok();
        m.write(&cli.out)?;
        (depth, verified)
    });
    progress.set(n as u64);
    let secs = progress.finish();
    anyhow::ensure!(verified, "internal error: the balanced tree failed verification");
    let layout = map.header().layout;
    let stats = SortReport {
        input: cli.input.display().to_string(),
        photons: n,
        depth,
        record_bytes: layout.record_size(),
        seconds: secs,
        threads: pm_stage::thread_count(),
    };
    if let Some(p) = &cli.stats_json {
        pm_stage::write_json(p, &serde_json::to_value(&stats)?)?;
    }
    Ok(stats)
}
