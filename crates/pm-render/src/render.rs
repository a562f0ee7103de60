//! The image loop (pbrt-v4's `ImageTileIntegrator::Render`): any rectangle of the
//! image, one sample per pixel, then adaptive supersampling where neighbouring
//! pixels differ (Christensen 1999 section 3: "up to 16 samples per pixel"), with a
//! box pixel filter. It knows nothing about what a sample computes.

use crate::integrator::{Components, Film, FirstHit, Integrator, RenderStats, VisibleSurface, pixel_salt};
use glam::Vec2;
use pm_color::{Layer, Rgb};
use pm_raster::{Fragment, Rect};
use pm_sampling::Sampler;
use pm_scene::Camera;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Instant;

/// A rendered region: linear radiance [W sr^-1 m^-2] per pixel, row by row from
/// the region's top-left pixel, with its component layers and, when asked for, the
/// G-buffer of each pixel's first sample.
#[derive(Clone, Debug)]
pub struct Image {
    /// The region of the film this is.
    pub rect: Rect,
    /// Width \[pixels\] (the region's).
    pub width: u32,
    /// Height \[pixels\] (the region's).
    pub height: u32,
    /// The image: the sum of the layers.
    pub total: Vec<Rgb>,
    /// Each [`Layer`], in [`Layer::ALL`]'s order; the volume layer is empty (no
    /// pixels) when the integrator carries no light scattered in media.
    pub layers: [Vec<Rgb>; 5],
    /// First-hit G-buffer, one entry per pixel (its first sample).
    pub gbuffer: Option<Vec<VisibleSurface>>,
}

impl Image {
    /// The image: the sum of the layers.
    pub fn total(&self) -> &[Rgb] {
        &self.total
    }

    /// The pixels of `layer` (none for a volume layer the render does not have).
    pub fn layer(&self, layer: Layer) -> &[Rgb] {
        &self.layers[layer.index()]
    }

    /// True when the image has a volume layer (its scene scatters light in media).
    pub fn has_volume(&self) -> bool {
        !self.layers[Layer::Volume.index()].is_empty()
    }

    /// The total (`None`) or a layer.
    pub fn total_or_layer(&self, layer: Option<Layer>) -> &[Rgb] {
        layer.map_or(self.total(), |l| self.layer(l))
    }

    /// The total and every layer it has, by their names in files, moved out (the
    /// EXR writer's input).
    pub fn into_named(self) -> impl Iterator<Item = (&'static str, Vec<Rgb>)> {
        std::iter::once((pm_color::TOTAL, self.total))
            .chain(Layer::ALL.into_iter().map(Layer::name).zip(self.layers))
            .filter(|(name, px)| *name == pm_color::TOTAL || !px.is_empty())
    }

    /// The total and every layer, by their names in files (the EXR writer's input).
    pub fn named(&self) -> impl Iterator<Item = (&'static str, &[Rgb])> {
        named(&self.total, &self.layers)
    }
}

/// `total` and the layers present (a volume layer only when it has pixels) by
/// their names in files.
fn named<'a>(total: &'a [Rgb], layers: &'a [Vec<Rgb>; 5]) -> impl Iterator<Item = (&'static str, &'a [Rgb])> {
    std::iter::once((pm_color::TOTAL, total)).chain(
        Layer::ALL
            .into_iter()
            .filter(|l| !layers[l.index()].is_empty())
            .map(|l| (l.name(), layers[l.index()].as_slice())),
    )
}

/// The sampler of sample `k` of pixel `i` (row by row) of `film`: its first two
/// numbers place the sample in the pixel (except a first sample on rasterised first
/// hits, at the centre), the integrator draws the rest. One sample per pixel has no
/// second point to stratify against: hashed noise has the same distribution and
/// costs a tenth.
pub fn pixel_sampler(film: &Film, i: usize, k: u32) -> Sampler {
    if film.spp <= 1 {
        Sampler::hashed(film.seed, pixel_salt(i))
    } else {
        Sampler::salted(film.seed, pixel_salt(i), k as u64)
    }
}

/// How the image loop finds the surfaces seen at pixel centres.
#[derive(Clone, Copy)]
pub enum Visibility<'s> {
    /// Eye rays through the BVH.
    Rays,
    /// The rasteriser ([`pm_raster::first_hits`]) for the first sample of each
    /// pixel (the centre), which the integrator gets as a [`FirstHit::Fragment`];
    /// supersamples still cast rays.
    Raster(&'s pm_scene::Scene),
    /// First hits the caller already rasterised ([`pm_raster::first_hits_into`])
    /// for this film and region: a live frame draws them while it updates its photons.
    Fragments(&'s pm_scene::Scene, &'s [Option<Fragment>]),
}

/// Render the pixels of `rect` of `film` seen by `camera`. Deterministic, and a
/// region equals the same pixels of the whole image: supersampling decisions read
/// the region's one-pixel apron, which is sampled (once) for that purpose.
pub fn render_region<I: Integrator>(
    camera: &Camera,
    film: &Film,
    rect: Rect,
    integ: &I,
    gbuffer: bool,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, RenderStats), String> {
    render_region_with(camera, film, rect, integ, gbuffer, Visibility::Rays, progress)
}

/// The memory of the region loop, kept between calls by a caller that renders many
/// frames (a frame allocates tens of megabytes; freeing and faulting them back in
/// cost a third of a live frame).
#[derive(Default)]
pub struct FrameBuffers {
    fragments: Vec<Option<Fragment>>,
    pixels: Vec<(Components, u32)>,
    in_region: Vec<usize>,
    /// The rendered image (the total) and its layers in [`Layer::ALL`]'s order.
    layers: [Vec<Rgb>; 6],
}

/// A value as a layer takes it: not finite or negative adds nothing.
#[inline]
fn clean(v: Rgb) -> Rgb {
    if v.is_finite() { v.max(Rgb::ZERO) } else { Rgb::ZERO }
}

/// Add `values` to a layer `l` and to the total `t`. Most of a layer of caustics
/// is zero: those pixels' cache lines of the two layers are neither read nor
/// written.
#[inline]
fn add_to_both(t: &mut [Rgb], l: &mut [Rgb], values: &[Rgb]) {
    for ((t, l), v) in t.iter_mut().zip(l).zip(values) {
        if *v != Rgb::ZERO {
            let v = clean(*v);
            *t += v;
            *l += v;
        }
    }
}

impl FrameBuffers {
    /// The image (the total of the layers) of the last region rendered into these
    /// buffers.
    pub fn total(&self) -> &[Rgb] {
        &self.layers[0]
    }

    /// The pixels of `layer` of the last region rendered into these buffers.
    pub fn layer(&self, layer: Layer) -> &[Rgb] {
        &self.layers[1 + layer.index()]
    }

    /// The total (`None`) or a layer of the last region rendered.
    pub fn total_or_layer(&self, layer: Option<Layer>) -> &[Rgb] {
        layer.map_or(self.total(), |l| self.layer(l))
    }

    /// Add `values` (one per pixel of the last region) to `layer` and to the total
    /// (image-space photon mapping splats its indirect layers after drawing).
    /// Values that are not finite or negative add nothing.
    pub fn add_to_layer(&mut self, layer: Layer, values: &[Rgb]) {
        let [total, rest @ ..] = &mut self.layers;
        let n = total.len().min(values.len());
        // In parallel: a 1920 x 1080 frame's layers are 25 MB each.
        const CHUNK: usize = 1 << 14;
        let values = &values[..n];
        let layer = &mut rest[layer.index()][..n];
        (total[..n].par_chunks_mut(CHUNK), layer.par_chunks_mut(CHUNK), values.par_chunks(CHUNK))
            .into_par_iter()
            .for_each(|(t, l, v)| add_to_both(t, l, v));
    }

    /// [`FrameBuffers::add_to_layer`] of values made a row at a time: `row(y, out)`
    /// writes row y's `width` values into `out`, for every row of the last region,
    /// in parallel.
    pub fn add_rows_to_layer(&mut self, layer: Layer, width: usize, row: impl Fn(usize, &mut [Rgb]) + Sync) {
        let [total, rest @ ..] = &mut self.layers;
        let layer = &mut rest[layer.index()];
        if width == 0 || total.len() % width != 0 || layer.len() != total.len() {
            return;
        }
        (total.par_chunks_mut(width), layer.par_chunks_mut(width)).into_par_iter().enumerate().for_each_init(
            || vec![Rgb::ZERO; width],
            |out, (y, (t, l))| {
                row(y, out);
                add_to_both(t, l, out);
            },
        );
    }

    /// The total and every layer of the last region rendered, by their names in
    /// files (the EXR writer's input).
    pub fn named(&self) -> impl Iterator<Item = (&'static str, &[Rgb])> {
        let [total, layers @ ..] = &self.layers;
        named(total, layers)
    }
}

/// [`render_region`] with the first surfaces found as `visibility` says.
pub fn render_region_with<I: Integrator>(
    camera: &Camera,
    film: &Film,
    rect: Rect,
    integ: &I,
    gbuffer: bool,
    visibility: Visibility,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, RenderStats), String> {
    let mut bufs = FrameBuffers::default();
    let (gb, stats) = render_into(Shot { camera, film, rect }, integ, gbuffer, visibility, &mut bufs, progress)?;
    let [total, layers @ ..] = std::mem::take(&mut bufs.layers);
    Ok((Image { rect, width: rect.width(), height: rect.height(), total, layers, gbuffer: gb }, stats))
}

/// What a render looks at: the camera, its film (size, samples, seed) and the
/// region of the film to render.
#[derive(Clone, Copy)]
pub struct Shot<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// The film.
    pub film: &'a Film,
    /// The region of the film.
    pub rect: Rect,
}

/// The region loop into `bufs` (its layers hold the result), reusing their memory;
/// returns the G-buffer when asked for and the statistics.
pub fn render_into<I: Integrator>(
    shot: Shot,
    integ: &I,
    gbuffer: bool,
    visibility: Visibility,
    bufs: &mut FrameBuffers,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Option<Vec<VisibleSurface>>, RenderStats), String> {
    let Shot { camera, film, rect } = shot;
    if !film.contains(rect) {
        return Err(format!("region {rect:?} is empty or outside the {}x{} image", film.width, film.height));
    }
    let start = Instant::now();
    let adaptive = integ.adaptive();
    let supersampling = adaptive && film.spp > 1;
    // The apron: one pixel around the region, inside the image. Sampling it only
    // matters for supersampling decisions.
    let apron = Rect {
        x0: rect.x0.saturating_sub(1),
        y0: rect.y0.saturating_sub(1),
        x1: (rect.x1 + 1).min(film.width),
        y1: (rect.y1 + 1).min(film.height),
    };
    let pass1 = if supersampling { apron } else { rect };
    let FrameBuffers { fragments, pixels, in_region, layers } = bufs;
    // Rasterised first hits at the centres of pass 1's pixels (its first samples).
    let first: Option<(&pm_scene::Scene, &[Option<Fragment>])> = match visibility {
        Visibility::Raster(scene) => {
            pm_raster::first_hits_into(scene, camera, film.size(), pass1, fragments);
            Some((scene, fragments.as_slice()))
        }
        Visibility::Fragments(scene, frags) => {
            if frags.len() != pass1.area() {
                return Err(format!("{} rasterised fragments for a region of {} pixels", frags.len(), pass1.area()));
            }
            Some((scene, frags))
        }
        Visibility::Rays => None,
    };
    let region = RegionLoop {
        camera_position: camera.position,
        rays: camera.rays(film.width as f32 / film.height as f32),
        film,
        integ,
        rect,
        pass1,
        adaptive,
        first_spp: if adaptive { 1 } else { film.spp.max(1) },
        first: first.filter(|_| adaptive),
        done: AtomicU64::new(0),
        progress,
    };
    // Without supersampling, G-buffer or apron, the write-out computes each pixel
    // itself (a live frame: no per-pixel buffer to fill and read back).
    let single_pass = !gbuffer && pass1 == rect && !supersampling && !integ.volume();
    let mut gbuffer_of_pass1 = Vec::new();
    let mut supersampled = 0;
    pixels.clear();
    if !single_pass {
        gbuffer_of_pass1 = region.first_pass(gbuffer, pixels);
        if supersampling {
            supersampled = region.supersample(pixels);
        }
    }
    // The region's pixels of pass 1 (which may include the apron), in row order.
    in_region.clear();
    if pass1 != rect {
        in_region.extend((0..pixels.len()).filter(|&j| region.in_rect(region.pixel_of(j))));
    }
    let pass1_of = |r: usize| pass1_index(in_region, r);
    let n = rect.area();
    let samples: u64 = if single_pass {
        n as u64 * region.first_spp as u64
    } else {
        (0..n).map(|r| pixels[pass1_of(r)].1 as u64).sum()
    };
    let source = if single_pass { Pass1::Compute } else { Pass1::Stored(pixels, in_region) };
    let nonfinite = region.write_layers(source, layers);
    let gb = gbuffer.then(|| (0..n).map(|r| std::mem::take(&mut gbuffer_of_pass1[pass1_of(r)])).collect());
    let stats = RenderStats {
        seconds: start.elapsed().as_secs_f64(),
        nonfinite_pixels: nonfinite,
        samples,
        supersampled_pixels: supersampled,
        ..integ.counters().stats()
    };
    Ok((gb, stats))
}

/// What one call of the region loop samples with: the camera, the film, the
/// integrator, the region and pass 1's pixels, and the rasterised first hits.
struct RegionLoop<'a, I> {
    camera_position: glam::Vec3,
    rays: pm_scene::CameraRays,
    film: &'a Film,
    integ: &'a I,
    /// The region rendered.
    rect: Rect,
    /// The pixels of the first pass: the region, with its apron when supersampling.
    pass1: Rect,
    /// The integrator's [`Integrator::adaptive`].
    adaptive: bool,
    /// Samples each pixel takes in the first pass (1 when adaptive).
    first_spp: u32,
    /// Rasterised first hits at pass 1's pixel centres (adaptive integrators only:
    /// the others never sample a centre).
    first: Option<(&'a pm_scene::Scene, &'a [Option<Fragment>])>,
    /// Pass 1's pixels done, for `progress`.
    done: AtomicU64,
    progress: &'a (dyn Fn(u64, u64) + Sync),
}

/// The index in pass 1's pixels of the region's pixel `r` (row order): itself when
/// pass 1 was the region, else through `in_region` (pass 1 included the apron).
fn pass1_index(in_region: &[usize], r: usize) -> usize {
    if in_region.is_empty() { r } else { in_region[r] }
}

/// Where the write-out finds pass 1's pixels.
enum Pass1<'p> {
    /// Not yet computed: the write-out computes each (one pass, one sample each).
    Compute,
    /// Computed, with the accumulated samples and their count; the second slice maps
    /// the region's pixels to pass 1's when pass 1 included the apron (else empty).
    Stored(&'p [(Components, u32)], &'p [usize]),
}

impl<I: Integrator> RegionLoop<'_, I> {
    /// True when pixel (x, y) is in the region.
    fn in_rect(&self, (x, y): (usize, usize)) -> bool {
        let r = &self.rect;
        (r.x0 as usize..r.x1 as usize).contains(&x) && (r.y0 as usize..r.y1 as usize).contains(&y)
    }

    /// (x, y) of pass 1's pixel `j` (row order).
    fn pixel_of(&self, j: usize) -> (usize, usize) {
        let w = self.pass1.width() as usize;
        (self.pass1.x0 as usize + j % w, self.pass1.y0 as usize + j / w)
    }

    /// Count pass 1's pixel `j` done (progress every 256 pixels).
    fn count(&self, j: usize) {
        if (j + 1).is_multiple_of(256) {
            let n = self.done.fetch_add(256, Relaxed) + 256;
            (self.progress)(n, self.pass1.area() as u64);
        }
    }

    /// Sample `k` of pixel (x, y). Pixels are addressed by column and row: integer
    /// division per pixel cost a live frame more than its shading.
    fn sample(
        &self,
        x: usize,
        y: usize,
        k: u32,
        scratch: &mut I::Scratch,
        vs: Option<&mut VisibleSurface>,
    ) -> Components {
        let film = self.film;
        let (w, h) = (film.width as usize, film.height as usize);
        let mut s = pixel_sampler(film, y * w + x, k);
        // Rasterised first hits are at pixel centres, so a first sample drawn from
        // them is too. Eye rays take the first sample where the others go: a
        // camera centred in a box sees its edges along the image's diagonals,
        // through every diagonal pixel's centre, and a centre sample there always
        // took the same side of the edge (one side's light in 8% of the pixels of a
        // 24 x 24 image: +2.5-3.6% in the direct layer against the path tracer on
        // the differential checker's scenes, issue 53).
        let centre = self.film.pixel_centres || k == 0 && self.adaptive && self.first.is_some();
        let j = if centre { Vec2::splat(0.5) } else { s.next_2d() };
        let d = self.rays.direction((x as f32 + j.x) / w as f32, (y as f32 + j.y) / h as f32);
        let known = match self.first {
            Some((scene, hits)) if k == 0 => {
                let (px, py) = (x - self.pass1.x0 as usize, y - self.pass1.y0 as usize);
                FirstHit::Fragment(scene, hits[py * self.pass1.width() as usize + px].as_ref())
            }
            _ => FirstHit::Unknown,
        };
        self.integ.li(self.camera_position, d, known, &mut s, scratch, vs)
    }

    /// Pass 1's samples of pixel (x, y), summed, and their count.
    fn pixel(
        &self,
        x: usize,
        y: usize,
        scratch: &mut I::Scratch,
        mut vs: Option<&mut VisibleSurface>,
    ) -> (Components, u32) {
        if self.first_spp == 1 {
            return (self.sample(x, y, 0, scratch, vs), 1);
        }
        let mut acc = Components::default();
        for k in 0..self.first_spp {
            let v = if k == 0 { vs.take() } else { None };
            acc.add(&self.sample(x, y, k, scratch, v));
        }
        (acc, self.first_spp)
    }

    /// Pass 1: every pixel of the region (and the apron, when supersampling) into
    /// `pixels`; the G-buffer of its region pixels when asked for (kept apart from
    /// the pixels: it is large and usually not asked for).
    fn first_pass(&self, gbuffer: bool, pixels: &mut Vec<(Components, u32)>) -> Vec<VisibleSurface> {
        let n = self.pass1.area();
        let mut g = Vec::new();
        if gbuffer {
            let (p, gb): (Vec<(Components, u32)>, Vec<VisibleSurface>) = (0..n)
                .into_par_iter()
                .with_min_len(64)
                .map_init(I::Scratch::default, |scratch, j| {
                    let mut vs = VisibleSurface::default();
                    let (x, y) = self.pixel_of(j);
                    let p = self.pixel(x, y, scratch, self.in_rect((x, y)).then_some(&mut vs));
                    self.count(j);
                    (p, vs)
                })
                .unzip();
            *pixels = p;
            g = gb;
        } else {
            pixels.par_extend((0..n).into_par_iter().with_min_len(64).map_init(I::Scratch::default, |scratch, j| {
                let (x, y) = self.pixel_of(j);
                self.count(j);
                self.pixel(x, y, scratch, None)
            }));
        }
        (self.progress)(n as u64, n as u64);
        g
    }

    /// Pass 2: supersample the region's pixels where a 4-neighbour differs by more
    /// than the contrast threshold (Mitchell's contrast |a - b| / (a + b) on
    /// luminance), up to the film's samples. The neighbours of a region pixel are in
    /// pass 1's apron. Returns the pixels supersampled.
    fn supersample(&self, pixels: &mut [(Components, u32)]) -> u64 {
        let film = self.film;
        let (w, h) = (film.width as usize, film.height as usize);
        let p1w = self.pass1.width() as usize;
        let lum: Vec<f32> = pixels.iter().map(|(c, n)| pm_color::luminance(c.total()) / *n as f32).collect();
        let contrast = |a: f32, b: f32| (a - b).abs() / (a + b).max(1e-6);
        let mark: Vec<usize> = (0..self.pass1.area())
            .filter(|&j| {
                let (x, y) = self.pixel_of(j);
                if !self.in_rect((x, y)) {
                    return false;
                }
                let l = lum[j];
                (x > 0 && contrast(l, lum[j - 1]) > film.contrast)
                    || (x + 1 < w && contrast(l, lum[j + 1]) > film.contrast)
                    || (y > 0 && contrast(l, lum[j - p1w]) > film.contrast)
                    || (y + 1 < h && contrast(l, lum[j + p1w]) > film.contrast)
            })
            .collect();
        let extra: Vec<(usize, Components)> = mark
            .par_iter()
            .map_init(I::Scratch::default, |scratch, &j| {
                let (x, y) = self.pixel_of(j);
                let mut acc = Components::default();
                for k in 1..film.spp {
                    acc.add(&self.sample(x, y, k, scratch, None));
                }
                (j, acc)
            })
            .collect();
        for (j, acc) in extra {
            pixels[j].0.add(&acc);
            pixels[j].1 = film.spp;
        }
        mark.len() as u64
    }

    /// The region's pixels, each its samples' mean, into the total and the layers in
    /// one parallel pass over rows (every value is overwritten, so a layer of the
    /// right length is not cleared first). No NaN or Inf leaves the renderer: returns
    /// the values that were not finite (written as zero).
    fn write_layers(&self, source: Pass1, layers: &mut [Vec<Rgb>; 6]) -> u64 {
        let rect = self.rect;
        let n = rect.area();
        let [l0, l1, l2, l3, l4, volume] = layers;
        for layer in [&mut *l0, &mut *l1, &mut *l2, &mut *l3, &mut *l4] {
            if layer.len() != n {
                layer.clear();
                layer.resize(n, Rgb::ZERO);
            }
        }
        // The volume layer, from the stored pixels (an integrator with volume light
        // is never rendered in one pass), or none.
        volume.clear();
        let mut bad_volume = 0u64;
        if let (true, Pass1::Stored(pixels, in_region)) = (self.integ.volume(), &source) {
            volume.extend((0..n).map(|r| {
                let (px, k) = &pixels[pass1_index(in_region, r)];
                let v = px.volume / *k as f32;
                if v.is_finite() {
                    v.max(Rgb::ZERO)
                } else {
                    bad_volume += 1;
                    Rgb::ZERO
                }
            }));
        }
        let rw = rect.width() as usize;
        let nonfinite: u64 = (
            l0.par_chunks_mut(rw),
            l1.par_chunks_mut(rw),
            l2.par_chunks_mut(rw),
            l3.par_chunks_mut(rw),
            l4.par_chunks_mut(rw),
        )
            .into_par_iter()
            .enumerate()
            .map_init(I::Scratch::default, |scratch, (c, (total, direct, caustic, indirect, specular))| {
                let mut bad = 0;
                for (i, out) in total.iter_mut().enumerate() {
                    let r = c * rw + i;
                    let computed;
                    let (px, n) = match source {
                        Pass1::Compute => {
                            let (x, y) = (rect.x0 as usize + i, rect.y0 as usize + c);
                            self.count(r);
                            computed = self.pixel(x, y, scratch, None);
                            (&computed.0, &computed.1)
                        }
                        Pass1::Stored(pixels, in_region) => {
                            let p = &pixels[pass1_index(in_region, r)];
                            (&p.0, &p.1)
                        }
                    };
                    let values = [px.total(), px.direct, px.caustic, px.indirect, px.specular];
                    let inv = 1.0 / *n as f32;
                    let slots = [out, &mut direct[i], &mut caustic[i], &mut indirect[i], &mut specular[i]];
                    for (v, slot) in values.into_iter().zip(slots) {
                        *slot = if v.is_finite() {
                            (v * inv).max(Rgb::ZERO)
                        } else {
                            bad += 1;
                            Rgb::ZERO
                        };
                    }
                }
                bad
            })
            .sum();
        if matches!(source, Pass1::Compute) {
            (self.progress)(n as u64, n as u64);
        }
        nonfinite + bad_volume
    }
}
