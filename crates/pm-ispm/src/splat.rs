//! The radiance estimate by scattering (McGuire and Luebke 2009, section 5): every
//! photon's *volume* — the support of its kernel, a disc of radius r_xy in the plane
//! of the surface it hit, compressed to r_z along that surface's normal (section 5.1,
//! equation 2) — is projected to a screen rectangle, and every pixel of that
//! rectangle whose G-buffer point lies inside gets the photon's contribution
//! (equation 1, whose cosine factor is dropped: see [`VolumePhoton::irradiance_at`]). The same contribution summed over a radius query is the gather
//! ([`gather`]) that mirrors and glass need and that the tests compare against.
//!
//! Deterministic without atomics: photons are binned into screen tiles in photon
//! order and each tile sums its photons in that order on one thread. Written so that
//! the per-tile loop is the only part a GPU backend would replace.
//!
//! Units: photon power W per RGB channel, kernel m^-2, radiance W sr^-1 m^-2,
//! irradiance W m^-2.

use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_scene::Camera;
use rayon::prelude::*;
use std::f32::consts::PI;

/// Screen tiles are this many pixels on a side.
pub const TILE: u32 = 16;

/// A stored photon with the shape of its kernel (section 4.1, Table 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumePhoton {
    /// Position \[m\].
    pub p: Vec3,
    /// Unit normal of the surface hit, on the side the photon arrived from.
    pub n: Vec3,
    /// Unit direction toward where the photon came from.
    pub wi: Vec3,
    /// Power [W per channel].
    pub power: Rgb,
    /// Kernel radius in the surface plane \[m\].
    pub r_xy: f32,
    /// Kernel radius along `n` \[m\] (at most `r_xy`).
    pub r_z: f32,
    /// Only specular scattering since the light (the caustic layer).
    pub caustic: bool,
    /// Stored under a cover ([`pm_render::covered`]): its light is the gap's
    /// own, and it lights only surfaces under a cover (and photons not under one
    /// only surfaces not under one), as the batch precompute, SPPM and the vertex
    /// method keep them apart. The ceiling's photons in the 3 mm gap above a
    /// two-sided lamp lit the ceiling around the lamp 10-15 times too bright and,
    /// in a rough metal sphere's reflection, an 8 x 8 block 381% (the
    /// differential checker's seed 90210, scene 27; issue 53).
    pub covered: bool,
}

/// A shading point of the G-buffer, as the splat reads it.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// Position \[m\].
    pub p: Vec3,
    /// Unit shading normal, toward the viewer.
    pub n: Vec3,
    /// Unit direction toward the viewer.
    pub wo: Vec3,
    /// The BSDF there (non-specular).
    pub bsdf: Bsdf,
    /// f / π-free shortcut: Some(ρ / π) when the BSDF is Lambertian (f is constant,
    /// so the splat sums irradiance and multiplies once).
    lambert: Option<Rgb>,
    /// Under a cover ([`VolumePhoton::covered`]); false unless set.
    pub covered: bool,
}

impl Surface {
    /// The surface at `p` with normal `n` seen from direction `wo`, not under a
    /// cover.
    pub fn new(p: Vec3, n: Vec3, wo: Vec3, bsdf: Bsdf) -> Surface {
        let lambert = match bsdf {
            Bsdf::Lambert { rho } => Some(rho / PI),
            _ => None,
        };
        Surface { p, n, wo, bsdf, lambert, covered: false }
    }
}

/// The splat's G-buffer (row 0 at the top): per pixel what the kernel test and a
/// Lambertian pixel's sum read, packed in 40 bytes, and the whole [`Surface`] only
/// for the few pixels whose BSDF is not Lambertian. Reading a full surface (about
/// 100 bytes) per pixel in the splat, the subsampling and the upsampling was the
/// larger part of their time at 1920 x 1080.
#[derive(Clone, Default)]
pub struct GBuffer {
    pixels: Vec<Pixel>,
    /// The non-Lambertian pixels' surfaces, in pixel order.
    others: Vec<Surface>,
}

/// A photon's kernel (equation 2 and the cone falloff) with its divisions done
/// once: the splat evaluates it at every pixel a volume covers.
#[derive(Clone, Copy, Debug)]
pub struct KernelForm {
    r_z: f32,
    r_xy2: f32,
    inv_r_xy: f32,
    /// (r_xy - r_z) / r_z.
    squash: f32,
    /// 3 / (π r_xy²) [m^-2].
    norm: f32,
}

impl KernelForm {
    /// The kernel's normalised radial coordinate (equation 2) at distance `dist` from
    /// the photon, `dn` = |d·n| of that along its normal:
    /// |d| / r_xy (1 + |cos| (r_xy - r_z) / r_z), which is |d| / r_xy in the photon's
    /// surface plane and |d| / r_z along its normal. The paper's equation prints the
    /// factor as (1 - |cos| (r_xy - r_z) / r_z), which is negative along the normal
    /// for r_z < r_xy / 2; the sign that gives |d| / r_z there is used.
    #[inline]
    fn t(&self, dist: f32, dn: f32) -> f32 {
        (dist + dn * self.squash) * self.inv_r_xy
    }

    /// κ [m^-2] at offset `d` from the photon whose normal is `n`: zero outside the
    /// slab |d·n| < r_z and beyond |d| = r_xy (both imply t >= 1, and are cheaper).
    #[inline]
    pub fn at(&self, d: Vec3, n: Vec3) -> f32 {
        let dn = d.dot(n).abs();
        let d2 = d.length_squared();
        if dn >= self.r_z || d2 >= self.r_xy2 {
            return 0.0;
        }
        let t = self.t(d2.sqrt(), dn);
        if t < 1.0 { self.norm * (1.0 - t) } else { 0.0 }
    }
}

/// A G-buffer pixel: point [m], unit normal toward the viewer, diffuse albedo / π
/// [sr^-1], and what it is ([`EMPTY`], [`LAMBERT`] or an index into `others`).
#[derive(Clone, Copy, Debug)]
struct Pixel {
    p: Vec3,
    n: Vec3,
    albedo_pi: Rgb,
    kind: u32,
    /// Under a cover ([`GBuffer::mark_covered`]).
    covered: bool,
}

/// No surface at the pixel (nothing seen, or a mirror or glass).
const EMPTY: u32 = u32::MAX;
/// A Lambertian surface: f = `albedo_pi` everywhere.
const LAMBERT: u32 = u32::MAX - 1;

impl Pixel {
    const NONE: Pixel = Pixel { p: Vec3::ZERO, n: Vec3::ZERO, albedo_pi: Rgb::ZERO, kind: EMPTY, covered: false };

    fn of(s: &Seen) -> Pixel {
        match *s {
            Seen::Nothing => Pixel::NONE,
            Seen::Lambert { p, n, albedo_pi } => Pixel { p, n, albedo_pi, kind: LAMBERT, covered: false },
            Seen::Surface(s) => Pixel {
                p: s.p,
                n: s.n,
                albedo_pi: s.lambert.unwrap_or_else(|| s.bsdf.albedo(s.wo, s.n) / PI),
                kind: if s.lambert.is_some() { LAMBERT } else { 0 },
                covered: s.covered,
            },
        }
    }
}

/// What the splat sees at a pixel, as a G-buffer's maker gives it.
#[derive(Clone, Copy, Debug)]
pub enum Seen {
    /// No surface photons can be splatted on (nothing seen, or a mirror or glass).
    Nothing,
    /// A Lambertian point (what [`Seen::Surface`] of a Lambertian surface keeps,
    /// without its BSDF and view direction).
    Lambert {
        /// Position \[m\].
        p: Vec3,
        /// Unit shading normal toward the viewer.
        n: Vec3,
        /// Albedo / π \[sr^-1\].
        albedo_pi: Rgb,
    },
    /// Any surface.
    Surface(Surface),
}

impl From<Option<Surface>> for Seen {
    fn from(s: Option<Surface>) -> Seen {
        s.map_or(Seen::Nothing, Seen::Surface)
    }
}

impl GBuffer {
    /// The G-buffer of `surfaces`.
    pub fn from_surfaces(surfaces: &[Option<Surface>]) -> GBuffer {
        let mut g = GBuffer::default();
        g.fill(surfaces.len(), |j| surfaces[j].into());
        g
    }

    /// Refill with `n` pixels, what pixel j sees being `seen(j)` (in parallel,
    /// reusing the memory).
    pub fn fill(&mut self, n: usize, seen: impl Fn(usize) -> Seen + Sync) {
        const CHUNK: usize = 4096;
        self.pixels.resize(n, Pixel::NONE);
        let others: Vec<Vec<(usize, Surface)>> = self
            .pixels
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let mut others = Vec::new();
                for (i, px) in chunk.iter_mut().enumerate() {
                    let s = seen(c * CHUNK + i);
                    *px = Pixel::of(&s);
                    if let Seen::Surface(s) = s
                        && px.kind == 0
                    {
                        others.push((c * CHUNK + i, s));
                    }
                }
                others
            })
            .collect();
        self.others.clear();
        for (j, s) in others.into_iter().flatten() {
            self.pixels[j].kind = self.others.len() as u32;
            self.others.push(s);
        }
    }

    /// Find which of this `width`-wide G-buffer's pixels inside the rectangles
    /// `rects` ([x0, y0, x1, y1), as [`VolumePhoton::screen_rect`] gives them)
    /// see a surface under a cover ([`pm_render::covered`]: one short ray each, in
    /// parallel); the rest count as uncovered. A frame asks for the rectangles of
    /// its covered photons, which are few (gaps under lamps, the foot of a sphere
    /// on a floor): the gap's light stays in the gap, and marking every pixel of a
    /// 256 x 256 frame cost up to a tenth of its time.
    pub fn mark_covered(&mut self, scene: &pm_scene::Scene, width: u32, rects: impl IntoIterator<Item = [u32; 4]>) {
        let mut asked = vec![false; self.pixels.len()];
        for [x0, y0, x1, y1] in rects {
            for y in y0..y1 {
                let row = (y * width) as usize;
                asked[row + x0 as usize..row + x1 as usize].fill(true);
            }
        }
        self.pixels.par_iter_mut().zip(asked).with_min_len(1024).for_each(|(px, asked)| {
            px.covered = asked && px.kind != EMPTY && pm_render::covered(scene, px.p, px.n);
        });
    }

    /// The G-buffer sampled every `factor` pixels of a `w` x `h` one: the pixel at
    /// the centre of each `factor` x `factor` block (clamped to the image), row by
    /// row (section 5.2).
    pub fn subsample(&self, w: u32, h: u32, factor: u32) -> GBuffer {
        let mut out = GBuffer::default();
        self.subsample_into(w, h, factor, &mut out);
        out
    }

    /// [`GBuffer::subsample`] into `out`, reusing its memory (rows in parallel).
    pub fn subsample_into(&self, w: u32, h: u32, factor: u32, out: &mut GBuffer) {
        let f = factor.max(1);
        let (lw, lh) = (w.div_ceil(f), h.div_ceil(f));
        out.pixels.resize((lw * lh) as usize, Pixel::NONE);
        out.pixels.par_chunks_mut(lw as usize).enumerate().for_each(|(ly, row)| {
            let y = (ly as u32 * f + f / 2).min(h - 1);
            for (lx, px) in row.iter_mut().enumerate() {
                let x = (lx as u32 * f + f / 2).min(w - 1);
                *px = self.pixels[(y * w + x) as usize];
            }
        });
        // The few non-Lambertian samples, renumbered in pixel order.
        out.others.clear();
        for px in out.pixels.iter_mut().filter(|px| px.kind < LAMBERT) {
            out.others.push(self.others[px.kind as usize]);
            px.kind = out.others.len() as u32 - 1;
        }
    }
}

impl VolumePhoton {
    /// The kernel κ at `x` [m^-2]: the cone falloff 1 - t, normalised so that it
    /// integrates to one over the photon's surface plane (∫ (1 - t) dA = π r_xy² / 3).
    #[inline]
    pub fn kernel(&self, x: Vec3) -> f32 {
        self.kernel_form().at(x - self.p, self.n)
    }

    /// The kernel's constants, for evaluating it at many points.
    #[inline]
    pub fn kernel_form(&self) -> KernelForm {
        KernelForm {
            r_z: self.r_z,
            r_xy2: self.r_xy * self.r_xy,
            inv_r_xy: 1.0 / self.r_xy,
            squash: (self.r_xy - self.r_z) / self.r_z,
            norm: 3.0 / (PI * self.r_xy * self.r_xy),
        }
    }

    /// Whether this photon lights a surface of unit normal `n` (toward the viewer)
    /// within its kernel: one it arrived at the front of, facing the way of the
    /// surface it hit ([`pm_render::SAME_SURFACE_COS`], the test every photon
    /// estimate and [`pm_render::disc_coverage`] make). Without the second test a
    /// large volume on the floor lit the sides of a box standing on it up to r_z
    /// above the floor.
    #[inline]
    pub fn lights(&self, n: Vec3) -> bool {
        self.wi.dot(n) > 0.0 && self.n.dot(n) > pm_render::SAME_SURFACE_COS
    }

    /// Irradiance this photon adds at a point `p` with normal `n` [W m^-2 per
    /// channel]: Φ κ, from the front only.
    ///
    /// The paper's equation 1 (and its appendix A, step 3(a)) multiplies by
    /// max(0, ω_i·n). A photon's power is already the flux through the surface (the
    /// density of photons carries the cosine; Jensen 2001, equation 7.6, has none),
    /// so only the sign is used here: with the cosine, a diffusely lit wall gets 2/3
    /// of its light (the furnace test measured 57% with it).
    #[inline]
    pub fn irradiance_at(&self, p: Vec3, n: Vec3) -> Rgb {
        if !self.lights(n) {
            return Rgb::ZERO;
        }
        let k = self.kernel(p);
        if k > 0.0 { self.power * k } else { Rgb::ZERO }
    }

    /// Radiance this photon adds at `s` toward the viewer (equation 1, without the
    /// cosine: see [`Self::irradiance_at`]) [W sr^-1 m^-2].
    #[inline]
    pub fn radiance_at(&self, s: &Surface) -> Rgb {
        if !self.lights(s.n) {
            return Rgb::ZERO;
        }
        let k = self.kernel(s.p);
        if !(k > 0.0) {
            return Rgb::ZERO;
        }
        let f = s.lambert.unwrap_or_else(|| s.bsdf.f(s.wo, self.wi, s.n));
        f * self.power * k
    }

    /// The pixel rectangle [x0, x1) x [y0, y1) of a `w` x `h` image seen by `camera`
    /// that the photon's volume can cover (its bounding box, an r_xy square of
    /// thickness 2 r_z, projected); the whole image when the box reaches behind the
    /// camera; none when it is outside.
    pub fn screen_rect(&self, camera: &Camera, w: u32, h: u32) -> Option<[u32; 4]> {
        let (t, b) = pm_sampling::basis(self.n);
        let tan_y = (0.5 * camera.yfov).tan();
        let tan_x = tan_y * w as f32 / h as f32;
        let (mut lo, mut hi) = (glam::Vec2::splat(f32::INFINITY), glam::Vec2::splat(f32::NEG_INFINITY));
        for k in 0..8 {
            let sx = if k & 1 == 0 { -1.0 } else { 1.0 };
            let sy = if k & 2 == 0 { -1.0 } else { 1.0 };
            let sz = if k & 4 == 0 { -1.0 } else { 1.0 };
            let c = self.p + t * (sx * self.r_xy) + b * (sy * self.r_xy) + self.n * (sz * self.r_z);
            let d = c - camera.position;
            let z = d.dot(camera.forward);
            if z <= 1e-6 {
                return Some([0, 0, w, h]);
            }
            let q = glam::Vec2::new(
                0.5 * (d.dot(camera.right) / (z * tan_x) + 1.0) * w as f32,
                0.5 * (1.0 - d.dot(camera.up) / (z * tan_y)) * h as f32,
            );
            lo = lo.min(q);
            hi = hi.max(q);
        }
        // Pixels whose centres (x + 0.5) may lie inside.
        let x0 = (lo.x - 0.5).ceil().max(0.0);
        let y0 = (lo.y - 0.5).ceil().max(0.0);
        let x1 = ((hi.x - 0.5).floor() + 1.0).min(w as f32);
        let y1 = ((hi.y - 0.5).floor() + 1.0).min(h as f32);
        (x0 < x1 && y0 < y1).then_some([x0 as u32, y0 as u32, x1 as u32, y1 as u32])
    }
}

/// Joint bilateral upsampling of a subsampled splat (section 5.2, Figure 12): each
/// full-resolution surface of `gbuffer` takes the values of the (up to) four
/// surrounding samples of `low` weighted by bilinear distance, normal agreement
/// (max(0, n·n')^8) and depth agreement (1 / (1 + (Δd / 0.05 d)^2)), normalised;
/// with no usable sample around it takes none (zero). With `reflect`, the result is
/// multiplied by the pixel's diffuse albedo / π (irradiance in, Lambertian radiance
/// out). Made row by row ([`Upsample::row`]), so a frame adds each row to its
/// layers as it is made instead of writing and reading back a full-resolution
/// image (25 MB at 1920 x 1080).
pub struct Upsample<'a> {
    low: &'a [Rgb],
    low_px: &'a [Pixel],
    px: &'a [Pixel],
    /// Distance of each low-resolution sample from the camera \[m\].
    low_depth: Vec<f32>,
    camera_position: Vec3,
    /// Full-resolution width, low-resolution width and height, and the factor.
    w: u32,
    lw: u32,
    lh: u32,
    f: u32,
    reflect: bool,
}

impl<'a> Upsample<'a> {
    /// The upsampling of `low` (over `low_gbuffer`, [`GBuffer::subsample`] of
    /// `gbuffer` by `factor`) to the `w` x `h` pixels of `gbuffer` seen from
    /// `camera_position`.
    pub fn new(
        low: &'a [Rgb],
        low_gbuffer: &'a GBuffer,
        gbuffer: &'a GBuffer,
        camera_position: Vec3,
        (w, h, factor): (u32, u32, u32),
        reflect: bool,
    ) -> Upsample<'a> {
        let f = factor.max(1);
        let low_px = &low_gbuffer.pixels;
        let low_depth = low_px.par_iter().map(|q| (q.p - camera_position).length()).collect();
        Upsample {
            low,
            low_px,
            px: &gbuffer.pixels,
            low_depth,
            camera_position,
            w,
            lw: w.div_ceil(f),
            lh: h.div_ceil(f),
            f,
            reflect,
        }
    }

    /// Row `y` (`w` values) into `row`.
    pub fn row(&self, y: usize, row: &mut [Rgb]) {
        let (f, w, lw, lh) = (self.f, self.w, self.lw, self.lh);
        let fy = (y as f32 - (f / 2) as f32) / f as f32;
        let iy = fy.floor();
        let ay = fy - iy;
        for (x, o) in row.iter_mut().enumerate() {
            *o = Rgb::ZERO;
            let s = &self.px[y * w as usize + x];
            if s.kind == EMPTY {
                continue;
            }
            let fx = (x as f32 - (f / 2) as f32) / f as f32;
            let ix = fx.floor();
            let ax = fx - ix;
            let depth = (s.p - self.camera_position).length();
            let inv_sigma = 1.0 / (0.05 * depth).max(1e-6);
            let mut sum = Rgb::ZERO;
            let mut wsum = 0.0f32;
            for (dx, dy, wb) in
                [(0, 0, (1.0 - ax) * (1.0 - ay)), (1, 0, ax * (1.0 - ay)), (0, 1, (1.0 - ax) * ay), (1, 1, ax * ay)]
            {
                let (sx, sy) = (ix as i64 + dx, iy as i64 + dy);
                if sx < 0 || sy < 0 || sx >= lw as i64 || sy >= lh as i64 {
                    continue;
                }
                let k = (sy as u32 * lw + sx as u32) as usize;
                let q = &self.low_px[k];
                if q.kind == EMPTY {
                    continue;
                }
                let c = s.n.dot(q.n).max(0.0);
                let (c2, r) = (c * c, (self.low_depth[k] - depth) * inv_sigma);
                let wgt = wb.max(1e-4) * (c2 * c2) * (c2 * c2) / (1.0 + r * r);
                sum += self.low[k] * wgt;
                wsum += wgt;
            }
            if wsum > 1e-8 {
                *o = if self.reflect { sum * s.albedo_pi / wsum } else { sum / wsum };
            }
        }
    }

    /// The whole image, row 0 at the top.
    pub fn image(&self, h: u32) -> Vec<Rgb> {
        let mut out = vec![Rgb::ZERO; (self.w * h) as usize];
        out.par_chunks_mut(self.w as usize).enumerate().for_each(|(y, row)| self.row(y, row));
        out
    }
}

/// What the splat adds up per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplatOutput {
    /// Reflected radiance with the full BSDF at the pixel (equation 1).
    Radiance,
    /// Irradiance (Φ κ), for subsampled splats that the renderer multiplies by
    /// the full-resolution albedo after upsampling (section 5.2).
    Irradiance,
}

/// Splat `photons` over the surfaces of a G-buffer (row 0 at the top; `None` where
/// nothing non-specular is seen) that samples a `full_w` x `full_h` image seen by
/// `camera` every `factor` pixels (1: every pixel; else the pixel at the centre of
/// each `factor` x `factor` block, the layout [`GBuffer::subsample`] makes): returns the
/// indirect and caustic layers at the G-buffer's resolution. Photons are binned into
/// [`TILE`]-pixel tiles in photon order and every tile sums its photons in that
/// order, so the result does not depend on the thread count.
pub fn splat(
    photons: &[VolumePhoton],
    gbuffer: &GBuffer,
    camera: &Camera,
    size: (u32, u32, u32),
    output: SplatOutput,
) -> (Vec<Rgb>, Vec<Rgb>) {
    let mut scratch = SplatScratch::default();
    splat_into(photons, gbuffer, camera, size, output, &mut scratch);
    (scratch.indirect, scratch.caustic)
}

/// The memory of [`splat_into`], kept between frames (fresh pages every frame
/// showed in the profile): its working arrays and its two outputs.
#[derive(Default)]
pub struct SplatScratch {
    rects: Vec<Option<[u32; 4]>>,
    bins: Vec<Vec<u32>>,
    /// Per band of tile rows, whether the outputs hold a non-zero value there
    /// from the last splat (only those bands are cleared before the next).
    dirty: Vec<bool>,
    /// The width of the last splat's outputs \[pixels\].
    width: u32,
    /// The indirect layer of the last splat.
    pub indirect: Vec<Rgb>,
    /// The caustic layer of the last splat.
    pub caustic: Vec<Rgb>,
}

/// [`splat`] into `scratch.indirect` and `scratch.caustic`, reusing its memory.
pub fn splat_into(
    photons: &[VolumePhoton],
    gbuffer: &GBuffer,
    camera: &Camera,
    (full_w, full_h, factor): (u32, u32, u32),
    output: SplatOutput,
    scratch: &mut SplatScratch,
) {
    let f = factor.max(1);
    let (w, h) = (full_w.div_ceil(f), full_h.div_ceil(f));
    let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
    // Full-resolution rectangles in G-buffer pixels, a pixel wider when subsampled.
    let grow = |[x0, y0, x1, y1]: [u32; 4]| {
        if f == 1 {
            [x0, y0, x1, y1]
        } else {
            [
                (x0 / f).saturating_sub(1),
                (y0 / f).saturating_sub(1),
                (x1.div_ceil(f) + 1).min(w),
                (y1.div_ceil(f) + 1).min(h),
            ]
        }
    };
    let SplatScratch { rects, bins, dirty, width, indirect, caustic } = scratch;
    rects.clear();
    rects.par_extend(photons.par_iter().map(|p| p.screen_rect(camera, full_w, full_h).map(grow)));
    // Photons binned into tiles in photon order.
    bins.resize_with((tw * th) as usize, Vec::new);
    bins.iter_mut().for_each(Vec::clear);
    for (i, r) in rects.iter().enumerate() {
        if let Some([x0, y0, x1, y1]) = *r {
            for ty in y0 / TILE..y1.div_ceil(TILE) {
                for tx in x0 / TILE..x1.div_ceil(TILE) {
                    bins[(ty * tw + tx) as usize].push(i as u32);
                }
            }
        }
    }
    // A Lambertian pixel's reflectance / pi is applied once to its sum of power x
    // kernel, other BSDFs are evaluated per photon; irradiance applies none.
    let lambert_only = output == SplatOutput::Irradiance;
    let (pixels, others) = (&gbuffer.pixels, &gbuffer.others);
    let (rects, bins) = (&*rects, &*bins);
    // Outputs of another size start as zero; otherwise each band is cleared below
    // only if the last splat wrote to it (a full-resolution caustic splat writes a
    // few bands: clearing both 25 MB layers of a 1920 x 1080 frame took 6 ms).
    // (The two outputs and the band flags are only ever resized together here.)
    if *width != w || indirect.len() != (w * h) as usize {
        *width = w;
        for layer in [&mut *indirect, &mut *caustic] {
            layer.clear();
            layer.resize((w * h) as usize, Rgb::ZERO);
        }
        dirty.clear();
        dirty.resize(th as usize, false);
    }
    let band = (TILE * w) as usize;
    // Bands of tile rows in parallel, each writing its own rows of the output; a
    // pixel sums its tile's photons in photon order, so the result does not depend
    // on the thread count.
    (indirect.par_chunks_mut(band), caustic.par_chunks_mut(band), dirty.par_iter_mut())
        .into_par_iter()
        .enumerate()
        .for_each(|(ty, (ind, cau, dirty))| {
            let ty = ty as u32;
            let (py0, py1) = (ty * TILE, ((ty + 1) * TILE).min(h));
            let tiles = &bins[(ty * tw) as usize..((ty + 1) * tw) as usize];
            if std::mem::replace(dirty, tiles.iter().any(|t| !t.is_empty())) {
                ind.fill(Rgb::ZERO);
                cau.fill(Rgb::ZERO);
            }
            if !*dirty {
                // No photon reaches this band: its rows stay zero (most bands of a
                // full-resolution caustic splat, which then need no reflectance pass).
                return;
            }
            for tx in 0..tw {
                let (px0, px1) = (tx * TILE, ((tx + 1) * TILE).min(w));
                for &i in &tiles[tx as usize] {
                    let ph = &photons[i as usize];
                    let form = ph.kernel_form();
                    let [x0, y0, x1, y1] = rects[i as usize].expect("binned photons have a rectangle");
                    let acc = if ph.caustic { &mut *cau } else { &mut *ind };
                    for y in y0.max(py0)..y1.min(py1) {
                        let row = (y * w) as usize;
                        let local = ((y - py0) * w) as usize;
                        for x in x0.max(px0)..x1.min(px1) {
                            let q = &pixels[row + x as usize];
                            if q.kind == EMPTY || !ph.lights(q.n) || q.covered != ph.covered {
                                continue;
                            }
                            let k = form.at(q.p - ph.p, ph.n);
                            if !(k > 0.0) {
                                continue;
                            }
                            let v = ph.power * k;
                            acc[local + x as usize] += if q.kind == LAMBERT || lambert_only {
                                v
                            } else {
                                let s = &others[q.kind as usize];
                                s.bsdf.f(s.wo, ph.wi, s.n) * v
                            };
                        }
                    }
                }
            }
            if !lambert_only {
                // Lambertian pixels: reflectance / pi times their summed power x kernel.
                for (j, (a, b)) in ind.iter_mut().zip(cau.iter_mut()).enumerate() {
                    let q = &pixels[py0 as usize * w as usize + j];
                    if q.kind == LAMBERT {
                        *a *= q.albedo_pi;
                        *b *= q.albedo_pi;
                    }
                }
            }
        });
}

/// The gather form of the same estimate: the indirect and caustic radiance at `s`
/// from the photons within their kernels, found by a radius query of `index` (the
/// largest kernel radius; the grid's cells are visited in a fixed order and keep
/// photon order, so the sum is deterministic). What mirrors and glass see, and the
/// reference the splat is tested against.
pub fn gather(photons: &[VolumePhoton], index: &PhotonIndex, s: &Surface) -> (Rgb, Rgb) {
    let (mut indirect, mut caustic) = (Rgb::ZERO, Rgb::ZERO);
    index.grid.for_each_within(s.p, index.radius * index.radius, |i, _| {
        let ph = &photons[i as usize];
        if ph.covered != s.covered {
            return;
        }
        let v = ph.radiance_at(s);
        if ph.caustic {
            caustic += v;
        } else {
            indirect += v;
        }
    });
    (indirect, caustic)
}

/// The photons' positions in pm-kdtree's static radius grid, searched to the
/// largest kernel radius.
pub struct PhotonIndex {
    grid: pm_kdtree::RadiusGrid,
    radius: f32,
}

impl PhotonIndex {
    /// The index of `photons`.
    pub fn new(photons: &[VolumePhoton]) -> PhotonIndex {
        let radius = photons.iter().map(|p| p.r_xy).fold(0.0, f32::max).max(f32::MIN_POSITIVE);
        let points: Vec<Vec3> = photons.iter().map(|p| p.p).collect();
        PhotonIndex { grid: pm_kdtree::RadiusGrid::new(&points, radius), radius }
    }
}
