//! Image files and image comparison, in one place: OpenEXR with component layers
//! (linear radiance, W sr^-1 m^-2 per channel), 8-bit sRGB PNG, reading EXR back,
//! and the error measures the tests and the accuracy/time trade-off use.
//!
//! Writes are atomic (temporary file, then rename). [`accuracy`] splits an
//! estimator's error into bias and noise (the trade-off study's measures).

pub mod accuracy;

use anyhow::{Context, Result, bail};
use glam::Vec3;
use pm_color::{Layer, TOTAL};
use rayon::prelude::*;
use std::path::Path;

/// A linear-radiance image with named layers; row 0 is the top row.
#[derive(Clone, Debug, PartialEq)]
pub struct Layers {
    /// Width \[pixels\].
    pub width: u32,
    /// Height \[pixels\].
    pub height: u32,
    /// (name, pixels) as in the file: [`pm_color::TOTAL`] is the image itself, the
    /// others are [`Layer`]s by their names (a file from elsewhere may have others).
    pub layers: Vec<(String, Vec<Vec3>)>,
}

impl Layers {
    /// The image itself (R, G, B), when the file has it.
    pub fn total(&self) -> Option<&[Vec3]> {
        self.by_name(TOTAL)
    }

    /// The pixels of `layer`, when the file has it.
    pub fn layer(&self, layer: Layer) -> Option<&[Vec3]> {
        self.by_name(layer.name())
    }

    /// The total (`None`) or a layer, when the file has it.
    pub fn total_or_layer(&self, layer: Option<Layer>) -> Option<&[Vec3]> {
        self.by_name(pm_color::layer_name(layer))
    }

    /// The total (`None`) or a layer as pixels of their own; black where the
    /// file has none (a method that makes no volume layer has none to show).
    pub fn pixels(&self, layer: Option<Layer>) -> Vec<Vec3> {
        self.total_or_layer(layer)
            .map(<[_]>::to_vec)
            .unwrap_or_else(|| vec![Vec3::ZERO; (self.width * self.height) as usize])
    }

    /// [`Self::pixels`], with the caustic layer added to the indirect one when
    /// `caustics_in_indirect`: how an image is judged against a method that draws
    /// its caustics into its indirect layer (the vertex method has no caustic
    /// map), and that method's image against it alike.
    pub fn pixels_caustics_in_indirect(&self, layer: Option<Layer>, caustics_in_indirect: bool) -> Vec<Vec3> {
        let mut px = self.pixels(layer);
        if caustics_in_indirect && layer == Some(Layer::Indirect) {
            for (x, c) in px.iter_mut().zip(self.pixels(Some(Layer::Caustic))) {
                *x += c;
            }
        }
        px
    }

    /// The layer called `name` in the file (the total is [`TOTAL`]).
    pub fn by_name(&self, name: &str) -> Option<&[Vec3]> {
        self.layers.iter().find(|l| l.0 == name).map(|l| l.1.as_slice())
    }
}

/// Write OpenEXR, 32-bit float: the total as R, G, B and every other layer
/// as `<layer>.R`, `.G`, `.B` in the same part.
pub fn write_exr(path: &Path, img: &Layers) -> Result<()> {
    write_exr_file(path, img, None)
}

/// [`write_exr`] and [`write_exr_region`]: encoded straight into the temporary file
/// (through an in-memory copy, the 45 MB of a default render cost a tenth of a
/// second more in page faults and the copy).
fn write_exr_file(path: &Path, img: &Layers, at: Option<Placement>) -> Result<()> {
    let mut failed = None;
    let written = pm_format::write_atomically(path, |f| {
        encode_exr_into(f, img, true, at).map_err(|e| {
            failed = Some(e);
            std::io::Error::other("cannot encode EXR")
        })
    });
    if let Some(e) = failed {
        bail!("{}: {e}", path.display());
    }
    written.with_context(|| format!("{}: cannot write", path.display()))
}

/// Where a region of an image sits: the column and row of its top-left pixel in
/// an image of `full_width` x `full_height` pixels (the EXR's data window inside its
/// display window).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Placement {
    /// First column.
    pub x: u32,
    /// First row (row 0 at the top).
    pub y: u32,
    /// Width of the whole image \[pixels\].
    pub full_width: u32,
    /// Height of the whole image \[pixels\].
    pub full_height: u32,
}

/// [`write_exr`] for a region of a larger image: `img` is the region, `at` where it
/// sits (the file's data window is the region, its display window the image).
pub fn write_exr_region(path: &Path, img: &Layers, at: Placement) -> Result<()> {
    write_exr_file(path, img, Some(at))
}

/// The bytes of the EXR file [`write_exr`] writes (tests compare them).
#[cfg(test)]
fn encode_exr(img: &Layers, parallel: bool, at: Option<Placement>) -> std::result::Result<Vec<u8>, String> {
    let mut buf = std::io::Cursor::new(Vec::new());
    encode_exr_into(&mut buf, img, parallel, at)?;
    Ok(buf.into_inner())
}

/// Encode `img` as the EXR file [`write_exr`] writes into `out`; `parallel`
/// compresses chunks on several threads (the bytes are the same either way: tested).
fn encode_exr_into(
    out: impl std::io::Write + std::io::Seek,
    img: &Layers,
    parallel: bool,
    at: Option<Placement>,
) -> std::result::Result<(), String> {
    use exr::prelude::*;
    let (w, h) = (img.width as usize, img.height as usize);
    let mut channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (name, px) in &img.layers {
        if px.len() != w * h {
            return Err(format!("layer {name} has {} pixels, expected {}", px.len(), w * h));
        }
        for (c, comp) in ["R", "G", "B"].iter().enumerate() {
            let full = if name == TOTAL { comp.to_string() } else { format!("{name}.{comp}") };
            channels.push(AnyChannel::new(full.as_str(), FlatSamples::F32(px.iter().map(|p| p[c]).collect())));
        }
    }
    // Increasing line order makes the writer put compressed chunks in file order
    // whatever order its threads finish them in; with FAST_LOSSLESS's unspecified
    // order the offset table depended on the thread schedule, so renders with 1 and
    // 2 threads had equal pixels but different bytes.
    let encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };
    let attributes = match at {
        Some(a) => LayerAttributes::default().with_position(Vec2(a.x as i32, a.y as i32)),
        None => LayerAttributes::default(),
    };
    let layer = Layer::new((w, h), attributes, encoding, AnyChannels::sort(channels));
    let image = match at {
        Some(a) => exr::image::Image::new(
            ImageAttributes::new(IntegerBounds::from_dimensions((a.full_width as usize, a.full_height as usize))),
            layer,
        ),
        None => exr::image::Image::from_layer(layer),
    };
    let written = if parallel { image.write().to_buffered(out) } else { image.write().non_parallel().to_buffered(out) };
    written.map_err(|e| format!("cannot encode EXR: {e}"))
}

/// The mean of independent renders of one image (progressive photon mapping's
/// runs with their own seeds: the mean of consistent estimates is consistent, its
/// noise variance 1/K of one run's), layer by layer, summed in the order given
/// so the same files give the same bytes. Every image must have the same size
/// and layers; errors say which does not.
pub fn average(images: &[Layers]) -> std::result::Result<Layers, String> {
    let Some(first) = images.first() else { return Err("no images to average".into()) };
    let mut out = first.clone();
    for (k, img) in images.iter().enumerate().skip(1) {
        if (img.width, img.height) != (first.width, first.height) {
            return Err(format!("image {k} is {}x{}, image 0 {}x{}", img.width, img.height, first.width, first.height));
        }
        if img.layers.iter().map(|l| l.0.as_str()).ne(first.layers.iter().map(|l| l.0.as_str())) {
            return Err(format!("image {k} has other layers than image 0"));
        }
        for (dst, src) in out.layers.iter_mut().zip(&img.layers) {
            for (d, v) in dst.1.iter_mut().zip(&src.1) {
                *d += *v;
            }
        }
    }
    let n = images.len() as f32;
    for (_, px) in &mut out.layers {
        for v in px.iter_mut() {
            *v /= n;
        }
    }
    Ok(out)
}

/// Join regions of one image into the whole (tiles rendered separately): every
/// region must belong to the same image size and carry the same layers, and
/// together they must cover every pixel exactly once. Errors say which region
/// overlaps another or which pixel no region covers.
pub fn assemble(parts: &[(Layers, Placement)]) -> std::result::Result<Layers, String> {
    let Some((first, at0)) = parts.first() else { return Err("no regions to assemble".into()) };
    let (w, h) = (at0.full_width, at0.full_height);
    let names: Vec<&str> = first.layers.iter().map(|l| l.0.as_str()).collect();
    let mut out = Layers {
        width: w,
        height: h,
        layers: names.iter().map(|n| (n.to_string(), vec![Vec3::ZERO; (w * h) as usize])).collect(),
    };
    let mut owner = vec![u32::MAX; (w * h) as usize];
    for (k, (img, at)) in parts.iter().enumerate() {
        if (at.full_width, at.full_height) != (w, h) {
            return Err(format!(
                "region {k} belongs to a {}x{} image, region 0 to a {w}x{h} one",
                at.full_width, at.full_height
            ));
        }
        if at.x + img.width > w || at.y + img.height > h {
            return Err(format!(
                "region {k} ({}x{} at {},{}) reaches outside the {w}x{h} image",
                img.width, img.height, at.x, at.y
            ));
        }
        if img.layers.iter().map(|l| l.0.as_str()).ne(names.iter().copied()) {
            return Err(format!("region {k} has other layers than region 0"));
        }
        for j in 0..(img.width * img.height) as usize {
            let (x, y) = (at.x + j as u32 % img.width, at.y + j as u32 / img.width);
            let i = (y * w + x) as usize;
            if owner[i] != u32::MAX {
                return Err(format!("regions {} and {k} both cover pixel {x},{y}", owner[i]));
            }
            owner[i] = k as u32;
            for (dst, src) in out.layers.iter_mut().zip(&img.layers) {
                dst.1[i] = src.1[j];
            }
        }
    }
    if let Some(i) = owner.iter().position(|&o| o == u32::MAX) {
        return Err(format!("no region covers pixel {},{}", i as u32 % w, i as u32 / w));
    }
    Ok(out)
}

/// Read an OpenEXR file written by [`write_exr`] (or any single-part RGB EXR).
pub fn read_exr(path: &Path) -> Result<Layers> {
    read_exr_placed(path).map(|(layers, _)| layers)
}

/// An image of radiance for lighting (an environment map): its width, height and
/// pixels (row-major from the top row, linear RGB), from OpenEXR (the image's R, G,
/// B channels; a layered file's total) or Radiance RGBE (`.hdr`, decoded by the
/// `image` crate), chosen by the file's extension. Errors name the file.
pub fn read_radiance_image(path: &Path) -> Result<(usize, usize, Vec<Vec3>)> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    match ext.as_str() {
        "exr" => {
            let img = read_exr(path)?;
            let px = img.total().with_context(|| format!("{}: no R, G, B channels", path.display()))?.to_vec();
            Ok((img.width as usize, img.height as usize, px))
        }
        "hdr" => {
            let file = std::fs::File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
            let decoder = image::codecs::hdr::HdrDecoder::new(std::io::BufReader::new(file))
                .map_err(|e| anyhow::anyhow!("{}: not a Radiance HDR image: {e}", path.display()))?;
            let img = image::DynamicImage::from_decoder(decoder)
                .map_err(|e| anyhow::anyhow!("{}: cannot decode: {e}", path.display()))?
                .into_rgb32f();
            let (w, h) = (img.width() as usize, img.height() as usize);
            Ok((w, h, img.pixels().map(|p| Vec3::from(p.0)).collect()))
        }
        _ => bail!("{}: unknown environment image format (.exr or .hdr)", path.display()),
    }
}

/// Write an image of radiance as Radiance RGBE (`.hdr`; 8-bit mantissas with a
/// shared exponent, 1% steps), atomically: what [`read_radiance_image`] reads
/// back (generated environments, tests).
pub fn write_radiance_hdr(path: &Path, width: usize, height: usize, pixels: &[Vec3]) -> Result<()> {
    let bytes = radiance_hdr_bytes(width, height, pixels)
        .map_err(|e| anyhow::anyhow!("{}: cannot encode Radiance HDR: {e}", path.display()))?;
    pm_format::write_atomically(path, |f| std::io::Write::write_all(f, &bytes))
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// The bytes [`write_radiance_hdr`] writes.
pub fn radiance_hdr_bytes(width: usize, height: usize, pixels: &[Vec3]) -> Result<Vec<u8>> {
    let rgb: Vec<image::Rgb<f32>> = pixels.iter().map(|p| image::Rgb(p.to_array())).collect();
    let mut bytes = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut bytes).encode(&rgb, width, height)?;
    Ok(bytes)
}

/// Write an image as a Portable Float Map (`PF`, 32-bit float RGB,
/// little-endian, the bottom row first), atomically: the plainest float image a
/// program without an EXR reader can take (the Blender add-on's render passes
/// are rows from the bottom too). `pixels` has row 0 at the top.
pub fn write_pfm(path: &Path, width: usize, height: usize, pixels: &[Vec3]) -> Result<()> {
    if pixels.len() != width * height {
        bail!("{}: {} pixels for a {width}x{height} image", path.display(), pixels.len());
    }
    let mut bytes = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    bytes.reserve(12 * pixels.len());
    for row in pixels.chunks(width.max(1)).rev() {
        for v in row.iter().flat_map(|p| p.to_array()) {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    pm_format::write_atomically(path, |f| std::io::Write::write_all(f, &bytes))
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// [`read_exr`] with where the file's pixels sit in its image (a region written by
/// [`write_exr_region`]; a whole image sits at 0, 0 in itself).
pub fn read_exr_placed(path: &Path) -> Result<(Layers, Placement)> {
    use exr::prelude::read_first_flat_layer_from_file;
    let image = read_first_flat_layer_from_file(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read EXR: {e}", path.display()))?;
    let size = image.layer_data.size;
    let mut by_name: std::collections::BTreeMap<String, [Option<Vec<f32>>; 3]> = Default::default();
    for ch in &image.layer_data.channel_data.list {
        let name = ch.name.to_string();
        let (layer, comp) = match name.rsplit_once('.') {
            Some((l, c)) => (l.to_owned(), c.to_owned()),
            None => (TOTAL.to_owned(), name.clone()),
        };
        let idx = match comp.as_str() {
            "R" => 0,
            "G" => 1,
            "B" => 2,
            _ => continue,
        };
        let values: Vec<f32> = ch.sample_data.values_as_f32().collect();
        by_name.entry(layer).or_default()[idx] = Some(values);
    }
    let mut layers = Vec::new();
    for (name, [r, g, b]) in by_name {
        let (Some(r), Some(g), Some(b)) = (r, g, b) else { continue };
        layers.push((name, r.iter().zip(&g).zip(&b).map(|((r, g), b)| Vec3::new(*r, *g, *b)).collect()));
    }
    layers.sort_by_key(|l| l.0 != TOTAL);
    if layers.first().is_none_or(|l| l.0 != TOTAL) {
        bail!("{}: no R, G, B channels", path.display());
    }
    let (pos, display) = (image.layer_data.attributes.layer_position, image.attributes.display_window);
    let at = Placement {
        x: (pos.0 - display.position.0).max(0) as u32,
        y: (pos.1 - display.position.1).max(0) as u32,
        full_width: display.size.0 as u32,
        full_height: display.size.1 as u32,
    };
    Ok((Layers { width: size.0 as u32, height: size.1 as u32, layers }, at))
}

/// Write an 8-bit sRGB PNG of `pixels` scaled by 2^exposure and clamped.
pub fn write_png(path: &Path, width: u32, height: u32, pixels: &[Vec3], exposure: f32) -> Result<()> {
    write_frames(path, width, height, &[srgb8(pixels, exposure)], None, png::Compression::Balanced)
}

/// 8-bit sRGB bytes (R, G, B per pixel) of linear radiance times 2^exposure.
pub fn srgb8(pixels: &[Vec3], exposure: f32) -> Vec<u8> {
    let scale = 2f32.powf(exposure);
    let mut bytes = vec![0u8; 3 * pixels.len()];
    bytes.par_chunks_mut(3 * 4096).zip(pixels.par_chunks(4096)).for_each(|(out, px)| {
        for (o, p) in out.chunks_exact_mut(3).zip(px) {
            for c in 0..3 {
                o[c] = pm_color::srgb8(p[c] * scale);
            }
        }
    });
    bytes
}

/// [`write_png`] with fast compression (fdeflate), for frames written many per
/// second and previews of a render's EXR: about 20% larger files, 8x less encoding
/// time (0.04 against 0.28 s at 1024 x 1024).
pub fn write_png_fast(path: &Path, width: u32, height: u32, pixels: &[Vec3], exposure: f32) -> Result<()> {
    write_srgb8_png_fast(path, width, height, &srgb8(pixels, exposure))
}

/// [`write_png_fast`] of bytes [`srgb8`] made already (a live run keeps each frame's
/// bytes for the animated PNG too).
pub fn write_srgb8_png_fast(path: &Path, width: u32, height: u32, bytes: &[u8]) -> Result<()> {
    write_frames(path, width, height, &[bytes], None, png::Compression::Fast)
}

/// Write an animated PNG of `frames` (each [`srgb8`] bytes of `width` x `height`),
/// shown at `fps` frames per second and looping, atomically.
pub fn write_apng(path: &Path, width: u32, height: u32, frames: &[Vec<u8>], fps: f32) -> Result<()> {
    write_frames(path, width, height, frames, Some(fps), png::Compression::Fast)
}

/// Read a PNG written by [`write_png`] or [`write_png_fast`]: its width, height and
/// 8-bit sRGB bytes (R, G, B per pixel), the ones [`srgb8`] gave when it was written.
pub fn read_png_rgb8(path: &Path) -> Result<(u32, u32, Vec<u8>)> {
    let file = std::fs::File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| anyhow::anyhow!("{}: not a PNG: {e}", path.display()))?;
    let info = reader.info();
    if (info.color_type, info.bit_depth) != (png::ColorType::Rgb, png::BitDepth::Eight) {
        bail!("{}: not an 8-bit RGB PNG ({:?}, {:?})", path.display(), info.color_type, info.bit_depth);
    }
    let (w, h) = (info.width, info.height);
    let mut buf = vec![0; reader.output_buffer_size().context("PNG too large")?];
    reader.next_frame(&mut buf).map_err(|e| anyhow::anyhow!("{}: cannot decode: {e}", path.display()))?;
    buf.truncate(w as usize * h as usize * 3);
    Ok((w, h, buf))
}

/// The one PNG encoder: a PNG of one frame, or with `fps` an animated PNG of all,
/// written atomically.
fn write_frames(
    path: &Path,
    width: u32,
    height: u32,
    frames: &[impl AsRef<[u8]>],
    fps: Option<f32>,
    compression: png::Compression,
) -> Result<()> {
    let encode = || -> std::result::Result<Vec<u8>, png::EncodingError> {
        let mut buf = Vec::new();
        let mut enc = png::Encoder::new(&mut buf, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(compression);
        if let Some(fps) = fps {
            enc.set_animated(frames.len().max(1) as u32, 0)?;
            // Frame delay in milliseconds (APNG stores a fraction of a second).
            enc.set_frame_delay((1000.0 / fps).round().clamp(1.0, 65535.0) as u16, 1000)?;
        }
        let mut w = enc.write_header()?;
        for f in frames {
            w.write_image_data(f.as_ref())?;
        }
        w.finish()?;
        Ok(buf)
    };
    let bytes = encode().map_err(|e| anyhow::anyhow!("{}: cannot encode PNG: {e}", path.display()))?;
    pm_format::write_atomically(path, |f| std::io::Write::write_all(f, &bytes))
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// Error of `a` against reference `b` over the pixels `keep` selects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageError {
    /// sqrt(mean((a - b)^2)) / mean(b), over pixels and channels.
    pub rel_rmse: f64,
    /// (mean(a) - mean(b)) / mean(b).
    pub rel_bias: f64,
    /// Pixels compared.
    pub pixels: usize,
}

/// The factor that puts `reference`'s mean over its pixels and channels at 0.18
/// (mid-grey): how the contact sheets and `xtask compare --png` show an image and
/// its reference at one exposure. 1 for a black reference.
pub fn mid_grey_gain(reference: &[Vec3]) -> f32 {
    let mean = reference.iter().map(|p| p.element_sum() as f64 / 3.0).sum::<f64>() / reference.len().max(1) as f64;
    if mean > 0.0 { (0.18 / mean) as f32 } else { 1.0 }
}

/// The means of the `n` x `n` blocks of a `width`-wide image, row by row (`width /
/// n` rounded up to a row); a partial block at the right or bottom edge is the mean
/// of the pixels it has. Where in a picture a difference lives, and the unit the
/// far-from-origin tests and `xtask compare --blocks` judge in.
pub fn block_means(px: &[Vec3], width: usize, n: usize) -> Vec<Vec3> {
    let (cols, height) = (width.div_ceil(n), px.len() / width.max(1));
    let rows = height.div_ceil(n);
    let mut out = vec![Vec3::ZERO; cols * rows];
    for (i, p) in px.iter().enumerate() {
        let (bx, by) = (i % width / n, i / width / n);
        let (w, h) = ((width - bx * n).min(n), (height - by * n).min(n));
        out[by * cols + bx] += *p / (w * h) as f32;
    }
    out
}

/// Compare `a` against the reference `b`, skipping pixels where the reference's
/// largest channel exceeds `mask_above` (e.g. directly visible lights, whose
/// anti-aliased edges would dominate any error measure).
pub fn compare(a: &[Vec3], b: &[Vec3], mask_above: f32) -> ImageError {
    let keep: Vec<usize> = (0..a.len().min(b.len())).filter(|&i| b[i].max_element() <= mask_above).collect();
    let n = (keep.len() * 3).max(1) as f64;
    let sum = |v: &[Vec3]| keep.iter().map(|&i| (v[i].x + v[i].y + v[i].z) as f64).sum::<f64>() / n;
    let (mean_a, mean_b) = (sum(a), sum(b));
    let mse = keep.iter().map(|&i| (a[i] - b[i]).length_squared() as f64).sum::<f64>() / n;
    let denom = mean_b.abs().max(1e-30);
    ImageError { rel_rmse: mse.sqrt() / denom, rel_bias: (mean_a - mean_b) / denom, pixels: keep.len() }
}

/// Structural similarity (Wang et al. 2004, "Image Quality Assessment: From Error
/// Visibility to Structural Similarity") of `a` against reference `b`, both
/// `width` x `height`: computed on luminance mapped to [0, 1) by x / (1 + x) (the
/// images are HDR radiance), over 7 x 7 windows at every pixel, with C1 = 0.01^2 and
/// C2 = 0.03^2; the mean over windows. 1 for identical images.
pub fn ssim(a: &[Vec3], b: &[Vec3], width: usize, height: usize) -> f64 {
    let tone = |v: &[Vec3]| -> Vec<f64> {
        v.iter()
            .map(|p| {
                let y = pm_color::luminance(*p).max(0.0) as f64;
                y / (1.0 + y)
            })
            .collect()
    };
    let (x, y) = (tone(a), tone(b));
    const R: isize = 3;
    let (c1, c2) = (0.01f64 * 0.01, 0.03f64 * 0.03);
    let mut total = 0.0;
    let mut windows = 0usize;
    for cy in 0..height as isize {
        for cx in 0..width as isize {
            let (mut sx, mut sy, mut sxx, mut syy, mut sxy, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for dy in -R..=R {
                for dx in -R..=R {
                    let (px, py) = (cx + dx, cy + dy);
                    if px < 0 || py < 0 || px >= width as isize || py >= height as isize {
                        continue;
                    }
                    let i = py as usize * width + px as usize;
                    let (u, v) = (x[i], y[i]);
                    sx += u;
                    sy += v;
                    sxx += u * u;
                    syy += v * v;
                    sxy += u * v;
                    n += 1.0;
                }
            }
            let (mx, my) = (sx / n, sy / n);
            let (vx, vy, cov) = (sxx / n - mx * mx, syy / n - my * my, sxy / n - mx * my);
            total += ((2.0 * mx * my + c1) * (2.0 * cov + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
            windows += 1;
        }
    }
    if windows == 0 { 1.0 } else { total / windows as f64 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trips_every_layer_and_png_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let px = |s: f32| (0..12).map(|i| Vec3::new(i as f32 * s, 0.5, 1e-3 * i as f32)).collect::<Vec<_>>();
        let img = Layers {
            width: 4,
            height: 3,
            layers: vec![("total".into(), px(1.0)), ("direct".into(), px(0.25)), ("caustic".into(), px(2.0))],
        };
        let p = dir.path().join("a.exr");
        write_exr(&p, &img).unwrap();
        let mut back = read_exr(&p).unwrap();
        back.layers.sort_by(|a, b| (a.0 != "total", &a.0).cmp(&(b.0 != "total", &b.0)));
        let mut want = img.clone();
        want.layers.sort_by(|a, b| (a.0 != "total", &a.0).cmp(&(b.0 != "total", &b.0)));
        assert_eq!(back, want);
        let png = dir.path().join("a.png");
        write_png(&png, 4, 3, &px(1.0), 0.0).unwrap();
        assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    }

    /// Regression: chunks were stored in the order threads finished compressing
    /// them, so equal images gave different files.
    #[test]
    fn exr_bytes_do_not_depend_on_threads() {
        for (w, h) in [(96u32, 96u32), (1, 1), (257, 33), (7, 300)] {
            let px: Vec<Vec3> =
                (0..w * h).map(|i| Vec3::new((i % 97) as f32 * 0.37, (i % 13) as f32, 1.0 / (1 + i) as f32)).collect();
            let img = Layers { width: w, height: h, layers: vec![("total".into(), px.clone()), ("direct".into(), px)] };
            let serial = encode_exr(&img, false, None).unwrap();
            for _ in 0..3 {
                assert!(
                    encode_exr(&img, true, None).unwrap() == serial,
                    "{w}x{h}: parallel EXR bytes differ from serial"
                );
            }
        }
    }

    #[test]
    fn ssim_is_one_for_equal_images_and_drops_with_noise_and_structure_loss() {
        let (w, h) = (32, 24);
        let img: Vec<Vec3> =
            (0..w * h).map(|i| Vec3::splat(((i % w) as f32 / w as f32) * 2.0 + ((i / w) % 4) as f32 * 0.3)).collect();
        assert!((ssim(&img, &img, w, h) - 1.0).abs() < 1e-12);
        let noisy: Vec<Vec3> = img.iter().enumerate().map(|(i, p)| *p * if i % 2 == 0 { 1.2 } else { 0.8 }).collect();
        let s_noisy = ssim(&noisy, &img, w, h);
        let flat = vec![Vec3::splat(1.0); w * h];
        let s_flat = ssim(&flat, &img, w, h);
        assert!(s_noisy < 0.99 && s_noisy > s_flat, "noisy {s_noisy}, flat {s_flat}");
        assert!(s_flat < 0.5, "a flat image keeps no structure: {s_flat}");
    }

    /// A 3 x 3 image in 2 x 2 blocks: a whole block, two half blocks at the edges
    /// and a corner pixel, each the mean of the pixels it has.
    #[test]
    fn block_means_average_whole_and_partial_blocks() {
        let px: Vec<Vec3> = (1..=9).map(|v| Vec3::splat(v as f32)).collect();
        let got: Vec<f32> = block_means(&px, 3, 2).iter().map(|p| p.x).collect();
        assert_eq!(got, vec![(1.0 + 2.0 + 4.0 + 5.0) / 4.0, (3.0 + 6.0) / 2.0, (7.0 + 8.0) / 2.0, 9.0]);
    }

    #[test]
    fn compare_measures_rmse_and_bias() {
        let b = vec![Vec3::ONE; 100];
        let a: Vec<Vec3> = (0..100).map(|i| Vec3::splat(if i % 2 == 0 { 1.1 } else { 0.9 })).collect();
        let e = compare(&a, &b, f32::INFINITY);
        assert!((e.rel_rmse - 0.1).abs() < 1e-6 && e.rel_bias.abs() < 1e-6);
        let mut b2 = b.clone();
        b2[0] = Vec3::splat(100.0);
        assert_eq!(compare(&a, &b2, 10.0).pixels, 99);
    }
}
