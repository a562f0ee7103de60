//! `cargo xtask ispm-plot`: the image-space method's accuracy against its frame time,
//! drawn from the output of `cargo bench -p pm-ispm --bench ispm` (its table against
//! the path tracer): median block error against milliseconds per frame, one line
//! through the bounce counts, one through the bounce-map sizes, one through the
//! subsampling factors.

use crate::plot;
use anyhow::{Context, Result, ensure};
use std::path::PathBuf;

/// Options of `cargo xtask ispm-plot`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The bench's printed output (`cargo bench -p pm-ispm --bench ispm > FILE`).
    pub bench_output: PathBuf,
    /// The plot to write (SVG; a PNG beside it).
    #[arg(long, default_value = "docs/ispm_accuracy.svg")]
    pub out: PathBuf,
}

/// A row of the bench's table against the path tracer: bounce_res, bounces,
/// subsample, frame time [ms], median block error.
type Row = (u32, u32, u32, f64, f64);

/// The rows of the bench's table against the path tracer.
fn rows(text: &str) -> Vec<Row> {
    let start = text.find("Against the path tracer").map_or(text.len(), |i| i);
    text[start..]
        .lines()
        .filter_map(|l| {
            let c: Vec<&str> = l.split('|').map(str::trim).collect();
            // | bounce_res | bounces | subsample | frame | rmse | bias | median | p90 |
            if c.len() < 10 {
                return None;
            }
            Some((c[1].parse().ok()?, c[2].parse().ok()?, c[3].parse().ok()?, c[4].parse().ok()?, c[7].parse().ok()?))
        })
        .collect()
}

/// Draw the plot.
pub fn run(args: &Args) -> Result<()> {
    let text = std::fs::read_to_string(&args.bench_output)
        .with_context(|| format!("{}: cannot read", args.bench_output.display()))?;
    let r = rows(&text);
    ensure!(!r.is_empty(), "{}: no table against the path tracer in it", args.bench_output.display());
    let series = |name: &str, keep: &dyn Fn(&Row) -> bool| {
        let mut pts: Vec<(f64, f64)> = r.iter().filter(|x| keep(x)).map(|x| (x.3, x.4)).collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        (name.to_string(), pts)
    };
    let lines = vec![
        series("bounces 1, 3, 8", &|x| x.0 == 48 && x.2 == 1),
        series("texels 48, 96", &|x| x.1 == 8 && x.2 == 1),
        series("same, subsample 4", &|x| x.1 == 8 && x.2 == 4),
    ];
    let shapes = plot::line_chart(
        "image-space photon mapping, cornell_spheres 512 x 512, 2 cores: error against the path tracer \
         (texel lines at 8 bounces; bounce line at 48 texels a side)",
        "milliseconds per frame",
        "median relative error of 4 x 4 blocks",
        false,
        &lines,
        1000.0,
        560.0,
    );
    plot::draw(&shapes, 1000.0, 560.0, &args.out, &args.out.with_extension("png"))?;
    println!("wrote {}", args.out.display());
    Ok(())
}
