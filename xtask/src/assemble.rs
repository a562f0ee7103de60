//! `cargo xtask assemble`: join the region EXRs that `photon-render --region` wrote
//! (each knows where it sits) into the whole image, `image.exr` and a PNG. A tiled
//! render assembled equals the whole-image render byte for byte (tested in
//! crates/photon-render/tests/cli.rs).

use anyhow::{Context, Result};
use std::path::PathBuf;

/// Options of `cargo xtask assemble`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Region EXRs (from `photon-render --region X0,Y0,X1,Y1 --out ...`), covering
    /// the image exactly once between them.
    #[arg(required = true)]
    pub regions: Vec<PathBuf>,
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
    let parts = args.regions.iter().map(|p| pm_image::read_exr_placed(p)).collect::<Result<Vec<_>>>()?;
    let whole = pm_image::assemble(&parts).map_err(|e| {
        // Name the files rather than their indices.
        let named = args
            .regions
            .iter()
            .enumerate()
            .rev()
            .fold(e, |msg, (k, p)| msg.replace(&format!("region {k}"), &p.display().to_string()));
        anyhow::anyhow!("assemble: {named}")
    })?;
    pm_image::write_exr(&args.out, &whole)?;
    if let Some(png) = &args.png {
        let total = whole.layers.iter().find(|l| l.0 == "total").context("no total layer")?;
        pm_image::write_png_fast(png, whole.width, whole.height, &total.1, args.exposure)?;
    }
    println!("wrote {} ({}x{}, {} regions)", args.out.display(), whole.width, whole.height, parts.len());
    Ok(())
}
