//! Visibility by rasterisation: the first hit at every pixel centre of a region,
//! found by projecting triangles instead of casting eye rays (a z-buffer over
//! triangles clipped to the near plane, perspective-correct barycentrics). The
//! result is the same [`Hit`] a pinhole eye ray through the pixel centre finds,
//! except where a pixel centre lies exactly on an edge or silhouette. The image
//! loop (`pm-render`) takes its [`Fragment`]s as first hits; the real-time and
//! image-space methods draw their G-buffers, shadow maps ([`CubeDepth`]) and bounce
//! maps ([`CUBE_FACES`]) with it.
//!
//! It knows scenes and cameras, not integrators, lights or images: what is seen,
//! not what it looks like. It does no I/O.

use glam::{Vec2, Vec3};
use pm_scene::{Camera, Hit, Scene};
use rayon::prelude::*;

/// A rectangle of pixels [x0, x1) x [y0, y1) of an image; row 0 is the top row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl Rect {
    /// The whole of an image of `width` x `height` pixels.
    pub fn full(width: u32, height: u32) -> Rect {
        Rect { x0: 0, y0: 0, x1: width, y1: height }
    }

    /// Tile `k` of `n` of an image of `width` x `height` pixels: the image cut into
    /// `n` bands of whole rows, as equal as rows allow, top first (the job plan's
    /// tiles). None when `k >= n` or there are more tiles than rows.
    pub fn band(width: u32, height: u32, k: u32, n: u32) -> Option<Rect> {
        if k >= n || n > height {
            return None;
        }
        let row = |i: u32| (i as u64 * height as u64 / n as u64) as u32;
        Some(Rect { x0: 0, y0: row(k), x1: width, y1: row(k + 1) })
    }
    /// Width \[pixels\].
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    /// Height \[pixels\].
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
    /// Pixel count.
    pub fn area(&self) -> usize {
        self.width() as usize * self.height() as usize
    }
    /// True when the rectangle is non-empty and inside an image of `width` x
    /// `height` pixels.
    pub fn is_valid_in(&self, width: u32, height: u32) -> bool {
        self.x0 < self.x1 && self.y0 < self.y1 && self.x1 <= width && self.y1 <= height
    }
}

/// Rows per parallel band.
const BAND: u32 = 16;
/// Near clipping distance as a fraction of the scene diagonal. At 1e-6 the clipped
/// vertices projected millions of pixels out and the shared edges of two clipped
/// wall triangles no longer met: a point light's cube map in the closed room had
/// 2 of 6,144 texels seeing through the walls. Surfaces nearer than this to the eye
/// or the light are not drawn.
const NEAR_REL: f32 = 1e-4;

/// A triangle in screen space: pixel coordinates, 1/z and the view-space vertices'
/// barycentric bookkeeping.
#[derive(Clone, Copy)]
struct ScreenTri {
    /// Pixel coordinates (x right, y down) of the (possibly clipped) vertices.
    s: [Vec2; 3],
    /// 1 / view depth of each vertex.
    inv_z: [f32; 3],
    /// Barycentrics of each vertex in the original triangle (clipping makes new ones).
    b: [Vec3; 3],
    tri: u32,
    /// Its material can be see-through: test [`Scene::present`] per fragment.
    alpha: bool,
    /// Rows covered, [y0, y1).
    y0: u32,
    y1: u32,
}

/// What the rasteriser keeps per pixel: the nearest triangle, the barycentrics of
/// the pixel centre on it, and the distance along the eye ray \[m\].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment {
    /// Triangle id.
    pub tri: u32,
    /// Barycentric coordinates of the pixel centre's point.
    pub b: [f32; 3],
    /// Distance from the camera along the unit eye ray \[m\].
    pub t: f32,
}

impl Fragment {
    /// The full hit record (position, normals, texture coordinates).
    pub fn hit(&self, scene: &Scene) -> Hit {
        scene.make_hit(self.tri, self.t, self.b)
    }
}

/// What a pixel of the rasteriser's z-buffer holds while triangles are drawn: the
/// nearest surface so far, by 1 / view depth (larger is nearer).
trait Texel: Copy + Send + Sync {
    /// The empty pixel.
    const EMPTY: Self;
    /// Whether the surface's barycentrics are kept (else they are computed only
    /// for a see-through material's presence test).
    const BARYCENTRICS: bool;
    /// True when triangle `tri` at 1 / view depth `iz` is to replace what is held
    /// (nearer; at equal depth, the lower id).
    fn closer(&self, iz: f32, tri: u32) -> bool;
    /// Hold triangle `tri` at barycentrics `b` and 1 / view depth `iz`.
    fn set(&mut self, tri: u32, b: [f32; 3], iz: f32);
    /// Turn the held 1 / view depth into the distance along the ray, `len` per unit
    /// of view depth.
    fn finish(&mut self, len: f32);
}

impl Texel for Option<Fragment> {
    const EMPTY: Self = None;
    const BARYCENTRICS: bool = true;
    #[inline]
    fn closer(&self, iz: f32, tri: u32) -> bool {
        match self {
            None => true,
            Some(f) => iz > f.t || (iz == f.t && tri < f.tri),
        }
    }
    #[inline]
    fn set(&mut self, tri: u32, b: [f32; 3], iz: f32) {
        *self = Some(Fragment { tri, b, t: iz });
    }
    #[inline]
    fn finish(&mut self, len: f32) {
        if let Some(f) = self {
            f.t = len / f.t;
        }
    }
}

/// A shadow map's pixel: 1 / view depth of the nearest surface while drawing (0:
/// none), then its distance \[m\] (infinite: none). Which triangle it is does not
/// matter, so no barycentrics are interpolated and 4 bytes are written instead of
/// a fragment's 24: a cube map took twice the eye's G-buffer's time.
impl Texel for f32 {
    const EMPTY: Self = 0.0;
    const BARYCENTRICS: bool = false;
    #[inline]
    fn closer(&self, iz: f32, _: u32) -> bool {
        iz > *self
    }
    #[inline]
    fn set(&mut self, _: u32, _: [f32; 3], iz: f32) {
        *self = iz;
    }
    #[inline]
    fn finish(&mut self, len: f32) {
        *self = if *self > 0.0 { len / *self } else { f32::INFINITY };
    }
}

/// The first surface at each pixel centre of `rect` (row by row) of an image of
/// `size` = (width, height) pixels seen by `camera`, or none.
pub fn first_hits(scene: &Scene, camera: &Camera, size: (u32, u32), rect: Rect) -> Vec<Option<Fragment>> {
    let mut out = Vec::new();
    first_hits_into(scene, camera, size, rect, &mut out);
    out
}

/// [`first_hits`] into `out`, reusing its memory (frames of a live view).
pub fn first_hits_into(scene: &Scene, camera: &Camera, size: (u32, u32), rect: Rect, out: &mut Vec<Option<Fragment>>) {
    // Cleared band by band as it is drawn (clearing 48 MB of a 1920 x 1080 frame's
    // fragments on one thread took a fifth of this step).
    out.resize(rect.area(), None);
    draw(scene, camera, size, rect, out);
}

/// The distance \[m\] along the ray through each pixel centre of `rect` to the
/// first surface (infinite where none), appended to `out`: [`first_hits`]'s `t`
/// without the fragments.
pub fn depths_into(scene: &Scene, camera: &Camera, size: (u32, u32), rect: Rect, out: &mut Vec<f32>) {
    let start = out.len();
    out.resize(start + rect.area(), f32::EMPTY);
    draw(scene, camera, size, rect, &mut out[start..]);
}

/// Draw `rect` of `scene` seen by `camera` into `out` (one texel a pixel, row by
/// row; what it held before is cleared first).
fn draw<T: Texel>(scene: &Scene, camera: &Camera, size: (u32, u32), rect: Rect, out: &mut [T]) {
    let (w, h) = (size.0 as f32, size.1 as f32);
    let aspect = w / h;
    let tan_y = (0.5 * camera.yfov).tan();
    let tan_x = tan_y * aspect;
    let near = NEAR_REL * scene.bounds.diagonal().max(f32::MIN_POSITIVE);
    let view = |p: Vec3| {
        let d = p - camera.position;
        Vec3::new(d.dot(camera.right), d.dot(camera.up), d.dot(camera.forward))
    };
    let screen = |v: Vec3| Vec2::new(0.5 * (v.x / (v.z * tan_x) + 1.0) * w, 0.5 * (1.0 - v.y / (v.z * tan_y)) * h);
    // Project every triangle (clipped to the near plane) once.
    let project = |(t, tri): (usize, &pm_scene::Triangle)| {
        let v = tri.p.map(view);
        let mut kept = [None; 2];
        for (slot, (poly_v, poly_b)) in kept.iter_mut().zip(clip_near(v, near).into_iter().flatten()) {
            let s = poly_v.map(screen);
            let (lo, hi) = (s[0].min(s[1]).min(s[2]), s[0].max(s[1]).max(s[2]));
            if !(hi.y > rect.y0 as f32 - 1.0
                && lo.y < rect.y1 as f32 + 1.0
                && hi.x > rect.x0 as f32 - 1.0
                && lo.x < rect.x1 as f32 + 1.0)
            {
                continue;
            }
            // Pixel rows whose centres (y + 0.5) may lie inside.
            let y0 = (lo.y - 0.5).ceil().max(rect.y0 as f32) as u32;
            let y1 = ((hi.y - 0.5).floor() + 1.0).min(rect.y1 as f32).max(y0 as f32) as u32;
            if y0 < y1 {
                let alpha = scene.has_alpha() && scene.materials[tri.material as usize].has_alpha();
                *slot =
                    Some(ScreenTri { s, inv_z: poly_v.map(|q| 1.0 / q.z), b: poly_b, tri: t as u32, alpha, y0, y1 });
            }
        }
        kept.into_iter().flatten()
    };
    let mut tris: Vec<ScreenTri> = scene.triangles.par_iter().enumerate().flat_map_iter(project).collect();
    tris.sort_by_key(|t| (t.y0, t.tri));
    let rw = rect.width() as usize;
    // The eye ray through a pixel centre has length sqrt(1 + u^2 + v^2) per unit of
    // view depth (u, v: the centre on the image plane at depth 1), split by column and row.
    let plane = |i: u32, n: f32, tan: f32| ((2.0 * (i as f32 + 0.5) / n - 1.0) * tan).powi(2);
    let col2: Vec<f32> = (rect.x0..rect.x1).map(|x| plane(x, w, tan_x)).collect();
    out.par_chunks_mut(rw * BAND as usize).enumerate().for_each(|(band, chunk)| {
        let by0 = rect.y0 + band as u32 * BAND;
        let by1 = (by0 + BAND).min(rect.y1);
        chunk.fill(T::EMPTY);
        // While drawing, a texel holds 1 / view depth of the surface.
        for st in tris.iter().take_while(|t| t.y0 < by1).filter(|t| t.y1 > by0) {
            raster_tri(scene, st, rect, by0, by1, chunk);
        }
        for (row, y) in chunk.chunks_mut(rw).zip(by0..by1) {
            let row2 = plane(y, h, tan_y);
            for (slot, c2) in row.iter_mut().zip(&col2) {
                slot.finish((1.0 + c2 + row2).sqrt());
            }
        }
    });
}

/// Rasterise one screen triangle into the band [by0, by1) of rows: keep, per pixel
/// centre, the nearest surface (largest 1 / view depth, held in the fragment's `t`
/// while drawing; ties to the lower triangle id) that is there ([`Scene::present`]).
fn raster_tri<T: Texel>(scene: &Scene, st: &ScreenTri, rect: Rect, by0: u32, by1: u32, band: &mut [T]) {
    let [a, b, c] = st.s;
    let area = (b - a).perp_dot(c - a);
    if !(area.abs() > 0.0) || !area.is_finite() {
        return;
    }
    let inv = 1.0 / area;
    let x0 = (a.x.min(b.x).min(c.x) - 0.5).ceil().max(rect.x0 as f32) as u32;
    let x1 = ((a.x.max(b.x).max(c.x) - 0.5).floor() + 1.0).min(rect.x1 as f32).max(x0 as f32) as u32;
    let rw = rect.width() as usize;
    for y in st.y0.max(by0)..st.y1.min(by1) {
        let row = (y - by0) as usize * rw;
        for x in x0..x1 {
            let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            // Screen-space barycentrics from the vertices relative to the pixel centre
            // (an affine form with the origin far away loses interior pixels of
            // triangles clipped at the near plane, whose vertices project far out);
            // a centre on an edge belongs to the triangle (both neighbours may claim
            // it: the nearer one, then the lower id, wins). Each edge's function is
            // computed from that edge's own two vertices, so the two triangles that
            // share an edge evaluate it as exact negatives and no centre falls between
            // them; with the third as 1 - l0 - l1, its rounding left a crack along the
            // wall-floor edge of cornell_boxes 1 km from the origin, whose pixel
            // centres the edge passes through exactly (issue 36).
            let l0 = (b - q).perp_dot(c - q) * inv;
            let l1 = (c - q).perp_dot(a - q) * inv;
            let l2 = (a - q).perp_dot(b - q) * inv;
            if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
                continue;
            }
            // Perspective-correct: interpolate 1/z linearly in screen space (while
            // drawing, a fragment's `t` holds 1/z: larger is nearer).
            let iz = l0 * st.inv_z[0] + l1 * st.inv_z[1] + l2 * st.inv_z[2];
            if !(iz > 0.0) {
                continue;
            }
            let slot = &mut band[row + (x - rect.x0) as usize];
            if slot.closer(iz, st.tri) {
                let mut bc = [0.0; 3];
                if T::BARYCENTRICS || st.alpha {
                    let wts = Vec3::new(l0 * st.inv_z[0], l1 * st.inv_z[1], l2 * st.inv_z[2]) / iz;
                    bc = (st.b[0] * wts.x + st.b[1] * wts.y + st.b[2] * wts.z).to_array();
                    if st.alpha && !scene.present(st.tri, bc) {
                        continue;
                    }
                }
                slot.set(st.tri, bc, iz);
            }
        }
    }
}

/// Clip a view-space triangle against the near plane z = near: none, one or two
/// triangles, each with the barycentrics of its vertices in the original.
fn clip_near(v: [Vec3; 3], near: f32) -> [Option<([Vec3; 3], [Vec3; 3])>; 2] {
    let b = [Vec3::X, Vec3::Y, Vec3::Z];
    let inside = v.map(|p| p.z >= near);
    match inside.iter().filter(|&&i| i).count() {
        3 => [Some((v, b)), None],
        0 => [None, None],
        _ => {
            let (mut pv, mut pb, mut n) = ([Vec3::ZERO; 4], [Vec3::ZERO; 4], 0);
            for i in 0..3 {
                let j = (i + 1) % 3;
                if inside[i] {
                    (pv[n], pb[n], n) = (v[i], b[i], n + 1);
                }
                if inside[i] != inside[j] {
                    let t = (near - v[i].z) / (v[j].z - v[i].z);
                    (pv[n], pb[n], n) = (v[i].lerp(v[j], t), b[i].lerp(b[j], t), n + 1);
                }
            }
            // One vertex inside: a triangle; two inside: a quadrilateral, two triangles.
            let tri = |k: usize| ([pv[0], pv[k], pv[k + 1]], [pb[0], pb[k], pb[k + 1]]);
            [Some(tri(1)), (n == 4).then(|| tri(2))]
        }
    }
}

/// The six 90-degree faces of a cube map around a point, as (forward, right, up):
/// +x, -x, +y, -y, +z, -z. Shadow maps and image-space bounce maps both use them.
pub const CUBE_FACES: [(Vec3, Vec3, Vec3); 6] = [
    (Vec3::X, Vec3::NEG_Z, Vec3::Y),
    (Vec3::NEG_X, Vec3::Z, Vec3::Y),
    (Vec3::Y, Vec3::X, Vec3::NEG_Z),
    (Vec3::NEG_Y, Vec3::X, Vec3::Z),
    (Vec3::Z, Vec3::X, Vec3::Y),
    (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
];

/// A cube shadow map: the distance \[m\] from `position` to the nearest surface
/// through the centre of each texel of six 90-degree faces (+x, -x, +y, -y, +z, -z),
/// drawn by the rasteriser. Direct light from a point or spot light then needs one
/// lookup per pixel instead of a shadow ray.
pub struct CubeDepth {
    position: Vec3,
    res: u32,
    /// Faces' cameras (forward, right, up).
    faces: [(Vec3, Vec3, Vec3); 6],
    depth: Vec<f32>,
}

impl CubeDepth {
    /// The shadow map of `scene` seen from `position`, `res` x `res` texels a face.
    pub fn new(scene: &Scene, position: Vec3, res: u32) -> CubeDepth {
        let faces = CUBE_FACES;
        let mut depth = Vec::with_capacity(6 * (res * res) as usize);
        for &(forward, right, up) in &faces {
            let cam = Camera { position, forward, up, right, yfov: std::f32::consts::FRAC_PI_2, aspect: Some(1.0) };
            depths_into(scene, &cam, (res, res), Rect::full(res, res), &mut depth);
        }
        CubeDepth { position, res, faces, depth }
    }

    /// True when nothing the map saw lies between the light and `p`, allowing
    /// `bias` \[m\] (against self-shadowing from the texels' finite size).
    pub fn visible(&self, p: Vec3, bias: f32) -> bool {
        let d = p - self.position;
        let a = d.abs();
        let face = if a.x >= a.y && a.x >= a.z {
            if d.x > 0.0 { 0 } else { 1 }
        } else if a.y >= a.z {
            if d.y > 0.0 { 2 } else { 3 }
        } else if d.z > 0.0 {
            4
        } else {
            5
        };
        let (forward, right, up) = self.faces[face];
        let z = d.dot(forward);
        if !(z > 0.0) {
            return true;
        }
        let (u, v) = (0.5 * (d.dot(right) / z + 1.0), 0.5 * (1.0 - d.dot(up) / z));
        let r = self.res as f32;
        let (x, y) = (((u * r) as u32).min(self.res - 1), ((v * r) as u32).min(self.res - 1));
        let stored = self.depth[face * (self.res * self.res) as usize + (y * self.res + x) as usize];
        d.length() <= stored + bias
    }

    /// Where the map was drawn from \[m\].
    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// The angle a texel subtends at the centre of a face \[rad\] (for biases).
    pub fn texel_angle(&self) -> f32 {
        2.0 / self.res as f32
    }
}
