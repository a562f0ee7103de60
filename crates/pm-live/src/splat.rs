//! The radiance estimate by scattering (McGuire and Luebke 2009, section 5): every
//! photon's *volume* — the support of its kernel, a disc of radius r_xy in the plane
//! of the surface it hit, compressed to r_z along that surface's normal (section 5.1,
//! equation 2) — is projected to a screen rectangle, and every pixel of that
//! rectangle whose G-buffer point lies inside gets the photon's contribution
//! (equation 1). The same contribution summed over a radius query is the gather
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
use pm_format::{FullPhoton, PhotonRecord};
use pm_scene::Camera;
use rayon::prelude::*;
use std::f32::consts::PI;

/// Screen tiles are this many pixels on a side.
pub const TILE: u32 = 16;

/// A stored photon with the shape of its kernel (section 4.1, Table 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumePhoton {
    /// Position [m].
    pub p: Vec3,
    /// Unit normal of the surface hit, on the side the photon arrived from.
    pub n: Vec3,
    /// Unit direction toward where the photon came from.
    pub wi: Vec3,
    /// Power [W per channel].
    pub power: Rgb,
    /// Kernel radius in the surface plane [m].
    pub r_xy: f32,
    /// Kernel radius along `n` [m] (at most `r_xy`).
    pub r_z: f32,
    /// Only specular scattering since the light (the caustic layer).
    pub caustic: bool,
}

/// A shading point of the G-buffer, as the splat reads it.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// Position [m].
    pub p: Vec3,
    /// Unit shading normal, toward the viewer.
    pub n: Vec3,
    /// Unit direction toward the viewer.
    pub wo: Vec3,
    /// The BSDF there (non-specular).
    pub bsdf: Bsdf,
}

impl VolumePhoton {
    /// The kernel's normalised radial coordinate of `x` (equation 2): |d| / r_xy in
    /// the photon's surface plane, |d| / r_z along its normal. The paper's equation
    /// prints the factor as (1 - |cos| (r_xy - r_z) / r_z), which is negative along the
    /// normal for r_z < r_xy / 2; the sign that gives |d| / r_z there is used.
    #[inline]
    pub fn kernel_t(&self, x: Vec3) -> f32 {
        let d = x - self.p;
        let dist = d.length();
        if dist == 0.0 {
            return 0.0;
        }
        let cos = (d.dot(self.n) / dist).abs();
        dist / self.r_xy * (1.0 + cos * (self.r_xy - self.r_z) / self.r_z)
    }

    /// The kernel κ at `x` [m^-2]: the cone falloff 1 - t, normalised so that it
    /// integrates to one over the photon's surface plane (∫ (1 - t) dA = π r_xy² / 3).
    #[inline]
    pub fn kernel(&self, x: Vec3) -> f32 {
        let t = self.kernel_t(x);
        if t < 1.0 { 3.0 * (1.0 - t) / (PI * self.r_xy * self.r_xy) } else { 0.0 }
    }

    /// Irradiance this photon adds at `s` [W m^-2 per channel]: Φ max(0, ω_i·n) κ.
    #[inline]
    pub fn irradiance_at(&self, p: Vec3, n: Vec3) -> Rgb {
        let cos = self.wi.dot(n);
        if cos <= 0.0 {
            return Rgb::ZERO;
        }
        let k = self.kernel(p);
        if k > 0.0 { self.power * (cos * k) } else { Rgb::ZERO }
    }

    /// Radiance this photon adds at `s` toward the viewer (equation 1) [W sr^-1 m^-2].
    #[inline]
    pub fn radiance_at(&self, s: &Surface) -> Rgb {
        let cos = self.wi.dot(s.n);
        if cos <= 0.0 {
            return Rgb::ZERO;
        }
        let k = self.kernel(s.p);
        if k > 0.0 { s.bsdf.f(s.wo, self.wi, s.n) * self.power * (cos * k) } else { Rgb::ZERO }
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
        (x0 < x1 && y0 < y1).then(|| [x0 as u32, y0 as u32, x1 as u32, y1 as u32])
    }
}

/// What the splat adds up per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplatOutput {
    /// Reflected radiance with the full BSDF at the pixel (equation 1).
    Radiance,
    /// Irradiance (Φ cos κ), for subsampled splats that the renderer multiplies by
    /// the full-resolution albedo after upsampling (section 5.2).
    Irradiance,
}

/// Splat `photons` over the surfaces of a `w` x `h` G-buffer (row 0 at the top;
/// `None` where nothing non-specular is seen) seen by `camera`: returns the indirect
/// and caustic layers. Photons are binned into [`TILE`]-pixel tiles in photon order
/// and every tile sums its photons in that order, so the result does not depend on
/// the thread count.
pub fn splat(
    photons: &[VolumePhoton],
    gbuffer: &[Option<Surface>],
    camera: &Camera,
    w: u32,
    h: u32,
    output: SplatOutput,
) -> (Vec<Rgb>, Vec<Rgb>) {
    let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let rects: Vec<Option<[u32; 4]>> = photons.par_iter().map(|p| p.screen_rect(camera, w, h)).collect();
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); (tw * th) as usize];
    for (i, r) in rects.iter().enumerate() {
        if let Some([x0, y0, x1, y1]) = *r {
            for ty in y0 / TILE..y1.div_ceil(TILE) {
                for tx in x0 / TILE..x1.div_ceil(TILE) {
                    bins[(ty * tw + tx) as usize].push(i as u32);
                }
            }
        }
    }
    let tiles: Vec<(Vec<Rgb>, Vec<Rgb>)> = bins
        .par_iter()
        .enumerate()
        .map(|(tile, list)| {
            let (tx, ty) = (tile as u32 % tw, tile as u32 / tw);
            let (px0, py0) = (tx * TILE, ty * TILE);
            let (px1, py1) = ((px0 + TILE).min(w), (py0 + TILE).min(h));
            let tw_px = (px1 - px0) as usize;
            let n = tw_px * (py1 - py0) as usize;
            let (mut indirect, mut caustic) = (vec![Rgb::ZERO; n], vec![Rgb::ZERO; n]);
            for &i in list {
                let ph = &photons[i as usize];
                let [x0, y0, x1, y1] = rects[i as usize].expect("binned photons have a rectangle");
                let acc = if ph.caustic { &mut caustic } else { &mut indirect };
                for y in y0.max(py0)..y1.min(py1) {
                    for x in x0.max(px0)..x1.min(px1) {
                        let Some(s) = &gbuffer[(y * w + x) as usize] else { continue };
                        let v = match output {
                            SplatOutput::Radiance => ph.radiance_at(s),
                            SplatOutput::Irradiance => ph.irradiance_at(s.p, s.n),
                        };
                        acc[(y - py0) as usize * tw_px + (x - px0) as usize] += v;
                    }
                }
            }
            (indirect, caustic)
        })
        .collect();
    let (mut indirect, mut caustic) = (vec![Rgb::ZERO; (w * h) as usize], vec![Rgb::ZERO; (w * h) as usize]);
    for (tile, (ti, tc)) in tiles.into_iter().enumerate() {
        let (px0, py0) = ((tile as u32 % tw) * TILE, (tile as u32 / tw) * TILE);
        let tw_px = ((px0 + TILE).min(w) - px0) as usize;
        for (j, (a, b)) in ti.into_iter().zip(tc).enumerate() {
            let (x, y) = (px0 as usize + j % tw_px, py0 as usize + j / tw_px);
            indirect[y * w as usize + x] = a;
            caustic[y * w as usize + x] = b;
        }
    }
    (indirect, caustic)
}

/// The gather form of the same estimate: the indirect and caustic radiance at `s`
/// from the photons within their kernels, found by a radius query of `index` (the
/// largest kernel radius) and summed in photon order. What mirrors and glass see, and
/// the reference the splat is tested against.
pub fn gather(photons: &[VolumePhoton], index: &PhotonIndex, s: &Surface, ids: &mut Vec<u32>) -> (Rgb, Rgb) {
    ids.clear();
    index.grid.for_each_within(s.p, index.radius * index.radius, |i, _| ids.push(i));
    ids.sort_unstable();
    let (mut indirect, mut caustic) = (Rgb::ZERO, Rgb::ZERO);
    for &i in ids.iter() {
        let ph = &photons[i as usize];
        let v = ph.radiance_at(s);
        if ph.caustic {
            caustic += v;
        } else {
            indirect += v;
        }
    }
    (indirect, caustic)
}

/// The photons' positions in pm-kdtree's grid, searched to the largest kernel radius.
pub struct PhotonIndex {
    grid: pm_kdtree::PhotonGrid<FullPhoton>,
    radius: f32,
}

impl PhotonIndex {
    /// The index of `photons`.
    pub fn new(photons: &[VolumePhoton]) -> PhotonIndex {
        let radius = photons.iter().map(|p| p.r_xy).fold(0.0, f32::max).max(f32::MIN_POSITIVE);
        let mut grid = pm_kdtree::PhotonGrid::new(radius, photons.len());
        for (i, p) in photons.iter().enumerate() {
            let record = pm_format::Photon {
                position: p.p,
                power: Rgb::ZERO,
                wi: p.wi,
                flags: pm_format::flags::AXIS_LEAF,
                normal: p.n,
                irradiance: Rgb::ZERO,
            };
            grid.set(i as u32, Some(FullPhoton::encode(&record)));
        }
        PhotonIndex { grid, radius }
    }
}
