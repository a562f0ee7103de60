//! `cargo xtask assemble`: join the region EXRs that `photon-render --region` wrote
//! (each knows where it sits) into the whole image, `image.exr` and a PNG. A tiled
//! render assembled equals the whole-image render byte for byte (tested in
//! crates/photon-render/tests/cli.rs). With `--average`: the mean of whole images,
//! progressive photon mapping's independent runs (`photon-render --run K/N`).

use anyhow::{Context, Result};
use std::path::PathBuf;

/// Options of `cargo xtask assemble`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Region EXRs (from `photon-render --region X0,Y0,X1,Y1 --out ...`), covering
    /// the image exactly once between them; with --average, whole images.
    #[arg(required = true)]
    pub regions: Vec<PathBuf>,
    /// Average whole images of the same size and layers (independent runs of
    /// progressive photon mapping, `photon-render --run K/N`) instead of joining
    /// regions; the same files in the same order give the same bytes.
    #[arg(long)]
    pub average: bool,
    /// The whole image (OpenEXR, every layer).
    #[arg(long)]
    pub out: PathBuf,
    /// Also an 8-bit sRGB PNG of the total layer.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Exposure of the PNG in stops (photon-render's --exposure).
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
}

/// Read the regions, join them and write the image (and PNG).
pub fn run(args: &Args) -> Result<()> {
    // Name the files rather than their indices.
    let named = |e: String, what: &str| {
        let msg = args
            .regions
            .iter()
            .enumerate()
            .rev()
            .fold(e, |msg, (k, p)| msg.replace(&format!("{what} {k}"), &p.display().to_string()));
        anyhow::anyhow!("assemble: {msg}")
    };
    let whole = if args.average {
        let images = args.regions.iter().map(|p| pm_image::read_exr(p)).collect::<Result<Vec<_>>>()?;
        pm_image::average(&images).map_err(|e| named(e, "image"))?
    } else {
        let parts = args.regions.iter().map(|p| pm_image::read_exr_placed(p)).collect::<Result<Vec<_>>>()?;
        pm_image::assemble(&parts).map_err(|e| named(e, "region"))?
    };
    pm_image::write_exr(&args.out, &whole)?;
    if let Some(png) = &args.png {
        let total = whole.layers.iter().find(|l| l.0 == "total").context("no total layer")?;
        pm_image::write_png_fast(png, whole.width, whole.height, &total.1, args.exposure)?;
    }
    let what = if args.average { "images averaged" } else { "regions" };
    println!("wrote {} ({}x{}, {} {what})", args.out.display(), whole.width, whole.height, args.regions.len());
    Ok(())
}
