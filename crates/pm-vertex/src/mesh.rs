//! Radiance estimates at mesh vertices (Jozwowski 2002, sections 4.1.3 and 4.4.2):
//! the scene's triangles as indexed meshes of *corners*, one per distinct
//! (object, position, normal), so triangles that share a vertex share its estimate
//! ("vertex cornering"); back-face and view-frustum culling decide which corners
//! need an estimate this frame.

use glam::Vec3;
use pm_color::Rgb;
use pm_estimate::{Filter, KnnParams};
use pm_format::FullIrrPhoton;
use pm_format::PhotonRecord;
use pm_kdtree::{KnnScratch, Neighbours};
use pm_scene::{Camera, Scene};
use rayon::prelude::*;
use std::collections::HashMap;

/// The unit normal at corner `k` of `tri`: its vertex normal there, or its
/// geometric normal where it has none (or a zero one).
fn corner_normal(tri: &pm_scene::Triangle, k: usize) -> Vec3 {
    let ng = tri.ng();
    tri.n.map_or(ng, |n| n[k]).normalize_or(ng)
}

/// The scene's triangles as indexed meshes: corner positions and normals, and the
/// corners of each triangle (same order as `Scene::triangles`).
#[derive(Clone, Debug)]
pub struct Corners {
    /// Corner position \[m\].
    pub p: Vec<Vec3>,
    /// Unit normal at the corner (the triangle's shading normal there).
    pub n: Vec<Vec3>,
    /// The three corners of each triangle.
    pub tri: Vec<[u32; 3]>,
}

impl Corners {
    /// Corners of `scene`. With `cornering`, triangle vertices of one object with the
    /// same position and normal share a corner (section 4.4.2, Figure 20); without,
    /// every triangle vertex is its own corner (three estimates per triangle).
    pub fn new(scene: &Scene, cornering: bool) -> Corners {
        let mut c = Corners { p: Vec::new(), n: Vec::new(), tri: Vec::with_capacity(scene.triangles.len()) };
        let mut index: HashMap<(u32, [u32; 3], [i32; 3]), u32> = HashMap::new();
        for (t, tri) in scene.triangles.iter().enumerate() {
            let object = scene.object_of(t as u32).unwrap_or(u32::MAX);
            let mut ids = [0u32; 3];
            for (k, id) in ids.iter_mut().enumerate() {
                let p = tri.p[k];
                let n = corner_normal(tri, k);
                let key = (object, p.to_array().map(f32::to_bits), (n * 1e4).round().as_ivec3().to_array());
                let new = c.p.len() as u32;
                *id = if cornering { *index.entry(key).or_insert(new) } else { new };
                if *id == new {
                    c.p.push(p);
                    c.n.push(n);
                }
            }
            c.tri.push(ids);
        }
        c
    }

    /// Move the corners with the scene's triangles (animated meshes): every corner
    /// takes the position and normal of the triangle vertices it stands for.
    pub fn follow(&mut self, scene: &Scene) {
        for (t, ids) in self.tri.iter().enumerate() {
            let tri = &scene.triangles[t];
            for (k, &c) in ids.iter().enumerate() {
                self.p[c as usize] = tri.p[k];
                self.n[c as usize] = corner_normal(tri, k);
            }
        }
    }

    /// Number of corners (radiance estimates when all are active).
    pub fn len(&self) -> usize {
        self.p.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.p.is_empty()
    }

    /// The corners of the triangles the camera may see: with `back_faces` off,
    /// triangles facing away from the camera (one-sided materials) are skipped; with
    /// `frustum`, triangles entirely outside one side of the view frustum are.
    pub fn active(&self, scene: &Scene, camera: &Camera, aspect: f32, back_faces: bool, frustum: bool) -> Vec<bool> {
        let mut on = vec![false; self.len()];
        let tan_y = (0.5 * camera.yfov).tan();
        let tan_x = tan_y * aspect;
        for (t, tri) in scene.triangles.iter().enumerate() {
            if back_faces
                && (tri.p[0] - camera.position).dot(tri.ng()) >= 0.0
                && !scene.materials[tri.material as usize].double_sided
            {
                continue;
            }
            if frustum {
                // View-space coordinates of the vertices; outside when all three lie
                // beyond the same plane (behind the camera, left, right, above, below).
                let v = tri.p.map(|p| {
                    let d = p - camera.position;
                    Vec3::new(d.dot(camera.right), d.dot(camera.up), d.dot(camera.forward))
                });
                let all = |f: &dyn Fn(Vec3) -> bool| v.iter().all(|&q| f(q));
                if all(&|q| q.z <= 0.0)
                    || all(&|q| q.x > q.z * tan_x)
                    || all(&|q| q.x < -q.z * tan_x)
                    || all(&|q| q.y > q.z * tan_y)
                    || all(&|q| q.y < -q.z * tan_y)
                {
                    continue;
                }
            }
            for &c in &self.tri[t] {
                on[c as usize] = true;
            }
        }
        on
    }

    /// Irradiance E [W m^-2 per channel] at every active corner from the k nearest
    /// photons of `tree` (the kd-tree or the photon grid) on the corner's side within `max_radius` \[m\]
    /// (`pm_estimate::irradiance`, the batch pipeline's estimate), with the squared
    /// radius of its disc \[m^2\]; zero elsewhere. A corner with its surroundings
    /// known (`around`, see [`CornerSurroundings`]) counts only the photons of its
    /// own surface and cover, as the irradiance precompute does
    /// ([`pm_estimate::irradiance_on`]), and with `view` (the photons' scene and
    /// a height \[m\] per corner) only those in view of it at that height
    /// ([`pm_render::in_view`]; the disc keeps the radius of the k nearest).
    pub fn irradiance(
        &self,
        tree: &(impl Neighbours<FullIrrPhoton> + Sync),
        active: &[bool],
        around: &[Option<Around>],
        (k, max_radius): (usize, f32),
        view: Option<(&Scene, &[f32])>,
    ) -> (Vec<Rgb>, Vec<f32>) {
        let p = KnnParams { k, max_d2: max_radius * max_radius, filter: Filter::None };
        (0..self.len())
            .into_par_iter()
            .map_init(KnnScratch::default, |scratch, c| {
                if !active[c] {
                    return (Rgb::ZERO, 0.0);
                }
                let (x, n) = (self.p[c], self.n[c]);
                let e = match (around.get(c).copied().flatten(), view) {
                    (Some(a), Some((scene, lift))) => {
                        let seen =
                            |r: &FullIrrPhoton| pm_render::in_view(scene, x, a.gaps.normal, r.position(), lift[c]);
                        pm_estimate::irradiance_on_seen(tree, x, n, &a.gaps, a.covered, &p, scratch, seen).0
                    }
                    (Some(a), None) => pm_estimate::irradiance_on(tree, x, n, &a.gaps, a.covered, &p, scratch).0,
                    (None, _) => pm_estimate::irradiance(tree, x, n, &p, scratch),
                };
                (e.e, e.r2)
            })
            .unzip()
    }
}

/// What a corner's estimate keeps out: the gaps to the surfaces behind and in
/// front of it, and whether it lies under a cover (another surface facing it
/// from closer than the method's cover distance, [`crate::cover_distance`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Around {
    /// The gaps along the corner's normal.
    pub gaps: pm_estimate::Surroundings,
    /// Under a cover ([`pm_format::flags::COVERED`], which the ring's photons carry).
    pub covered: bool,
}

/// Each corner's [`Around`], found once (two rays and one) when the corner is
/// first active and kept until the meshes move. Without it a ceiling corner
/// beside a two-sided light a few millimetres below the ceiling read the photons
/// trapped in the gap above the light, brighter than the room, and Gouraud
/// interpolation spread them over the ceiling around it: 50-1,500% too bright in
/// 8 x 8 blocks on seven of 40 generated rooms (issue 53's checker, seed 60606).
#[derive(Clone, Debug, Default)]
pub struct CornerSurroundings {
    /// Per corner its [`Around`], where found.
    around: Vec<Option<Around>>,
    /// Per corner whether it was looked for.
    probed: Vec<bool>,
}

impl CornerSurroundings {
    /// Forget every corner's (the scene's meshes moved).
    pub fn clear(&mut self) {
        self.around.clear();
        self.probed.clear();
    }

    /// Per corner its [`Around`], where found (as the last [`Self::update`] left them).
    pub fn around(&self) -> &[Option<Around>] {
        &self.around
    }

    /// Every corner's [`Around`] in `scene` (the photons' scene), looked for within
    /// `reach` \[m\] (the estimates' largest radius), under a cover closer than
    /// `cover` \[m\], at the corners `active` that have none yet; `None` for
    /// corners never active, or not on a surface of `scene` (a proxy's).
    pub fn update(
        &mut self,
        scene: &Scene,
        corners: &Corners,
        active: &[bool],
        (reach, cover): (f32, f32),
    ) -> &[Option<Around>] {
        self.around.resize(corners.len(), None);
        self.probed.resize(corners.len(), false);
        let todo: Vec<usize> = (0..corners.len()).filter(|&c| active[c] && !self.probed[c]).collect();
        let fresh: Vec<Option<Around>> = todo
            .par_iter()
            .with_min_len(16)
            .map(|&c| {
                let (x, n) = (corners.p[c], corners.n[c]);
                let gaps = scene.surface_gaps(x, n, reach)?.into();
                Some(Around { gaps, covered: scene.covered(x, n, cover) })
            })
            .collect();
        for (&c, a) in todo.iter().zip(fresh) {
            (self.around[c], self.probed[c]) = (a, true);
        }
        &self.around
    }
}
