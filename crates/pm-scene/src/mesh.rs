//! Meshes: triangles with their shading data, the object instances that group
//! them, bounds, and the scenes made from a scene's meshes (uniform subdivision,
//! bounding-box proxies).

use crate::{Light, LightKind, Scene, Target};
use glam::{Vec2, Vec3};

/// A triangle's shading data, in the order the file listed them (the triangle id).
#[derive(Clone, Debug)]
pub struct Triangle {
    /// World-space vertices \[m\].
    pub p: [Vec3; 3],
    /// World-space unit vertex normals, when the file had usable ones.
    pub n: Option<[Vec3; 3]>,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Texture coordinates, vertex colours and tangents, when the mesh has any. Boxed:
    /// most triangles have none, and held inline they were 184 of the record's 288
    /// bytes (issue 36; `Scene::memory_use`).
    pub extras: Option<Box<TriangleExtras>>,
}

/// What some meshes carry per corner besides positions and normals.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleExtras {
    /// Texture coordinates TEXCOORD_0, when present.
    pub uv: Option<[Vec2; 3]>,
    /// Texture coordinates TEXCOORD_1, when present (and read by some texture).
    pub uv1: Option<[Vec2; 3]>,
    /// Linear RGBA vertex colours (COLOR_0), when present: RGB multiplies the base
    /// colour, A the alpha.
    pub color: Option<[glam::Vec4; 3]>,
    /// World-space unit tangents (xyz) with the bitangent's sign (w: bitangent =
    /// w cross(normal, tangent)), from TANGENT or generated with MikkTSpace, when the
    /// material has a normal texture.
    pub tangent: Option<[glam::Vec4; 3]>,
}

impl Triangle {
    /// Unit geometric normal from the winding (counter-clockwise = front). Computed
    /// from the vertices when asked, as the loader computed it, rather than held (16
    /// bytes a triangle with the area; issue 36).
    #[inline]
    pub fn ng(&self) -> Vec3 {
        (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0]).normalize_or_zero()
    }

    /// Area [m^2].
    #[inline]
    pub fn area(&self) -> f32 {
        0.5 * (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0]).length()
    }

    /// Position \[m\] and interpolated unit vertex normal (the geometric normal
    /// when there are none; not yet turned to its side, nor normal-mapped) at
    /// barycentrics `b`.
    #[inline]
    pub fn point_normal(&self, b: [f32; 3]) -> (Vec3, Vec3) {
        (self.point(b), self.shading_normal(b, self.ng()))
    }

    /// The point at barycentrics `b` \[m\].
    #[inline]
    pub fn point(&self, b: [f32; 3]) -> Vec3 {
        self.p[0] * b[0] + self.p[1] * b[1] + self.p[2] * b[2]
    }

    /// The interpolated unit vertex normal at barycentrics `b`, or `ng` (the unit
    /// geometric normal, [`Self::ng`], which a hit record has at hand) without
    /// vertex normals.
    #[inline]
    pub fn shading_normal(&self, b: [f32; 3], ng: Vec3) -> Vec3 {
        self.n.map_or(ng, |n| (n[0] * b[0] + n[1] * b[1] + n[2] * b[2]).normalize_or(ng))
    }

    /// Texture coordinates TEXCOORD_0, when present.
    #[inline]
    pub fn uv(&self) -> Option<&[Vec2; 3]> {
        self.extras.as_ref().and_then(|e| e.uv.as_ref())
    }

    /// Texture coordinates TEXCOORD_1, when present.
    #[inline]
    pub fn uv1(&self) -> Option<&[Vec2; 3]> {
        self.extras.as_ref().and_then(|e| e.uv1.as_ref())
    }

    /// Linear RGBA vertex colours, when present.
    #[inline]
    pub fn color(&self) -> Option<&[glam::Vec4; 3]> {
        self.extras.as_ref().and_then(|e| e.color.as_ref())
    }

    /// Tangents with the bitangent's sign, when present.
    #[inline]
    pub fn tangent(&self) -> Option<&[glam::Vec4; 3]> {
        self.extras.as_ref().and_then(|e| e.tangent.as_ref())
    }

    /// The corners' texture coordinates of set `set` (TEXCOORD_0 or TEXCOORD_1), when
    /// the mesh has them.
    pub fn uvs(&self, set: u8) -> Option<&[Vec2; 3]> {
        if set == 1 { self.uv1() } else { self.uv() }
    }

    /// The extras to change (made empty when there are none).
    pub fn extras_mut(&mut self) -> &mut TriangleExtras {
        self.extras.get_or_insert_with(Default::default)
    }

    /// Set the extras: none are held when `e` has none.
    pub fn set_extras(&mut self, e: TriangleExtras) {
        self.extras = (e != TriangleExtras::default()).then(|| Box::new(e));
    }

    /// Swap corners 1 and 2 of the per-vertex attributes (a mirroring transform
    /// reverses the winding).
    /// The piece of this triangle with corners `p` at barycentrics `b` (one per
    /// corner) of it, its shading normals, texture coordinates, colours and tangents
    /// interpolated; `None` when the piece is degenerate.
    pub(crate) fn piece(&self, p: [Vec3; 3], b: [[f32; 3]; 3]) -> Option<Triangle> {
        let mut sub = Triangle::new(p, self.material)?;
        let lerp3 = |q: &[Vec3; 3], w: [f32; 3]| q[0] * w[0] + q[1] * w[1] + q[2] * w[2];
        sub.n = self.n.map(|n| b.map(|w| lerp3(&n, w).normalize_or(self.ng())));
        if let Some(e) = &self.extras {
            let lerp2 = |q: &[Vec2; 3]| b.map(|w| q[0] * w[0] + q[1] * w[1] + q[2] * w[2]);
            let lerp4 = |c: &[glam::Vec4; 3]| b.map(|w| c[0] * w[0] + c[1] * w[1] + c[2] * w[2]);
            sub.set_extras(TriangleExtras {
                uv: e.uv.as_ref().map(lerp2),
                uv1: e.uv1.as_ref().map(lerp2),
                color: e.color.as_ref().map(lerp4),
                tangent: e.tangent.as_ref().map(lerp4),
            });
        }
        Some(sub)
    }

    pub(crate) fn swap_corners(&mut self) {
        let Some(e) = self.extras.as_mut() else { return };
        if let Some(uv) = e.uv.as_mut() {
            uv.swap(1, 2);
        }
        if let Some(uv) = e.uv1.as_mut() {
            uv.swap(1, 2);
        }
        if let Some(c) = e.color.as_mut() {
            c.swap(1, 2);
        }
        if let Some(t) = e.tangent.as_mut() {
            t.swap(1, 2);
        }
    }

    /// A triangle without vertex normals or UVs; `None` when it has no area.
    pub fn new(p: [Vec3; 3], material: u32) -> Option<Triangle> {
        let t = Triangle { p, n: None, extras: None, material };
        let area = t.area();
        (area > 0.0 && area.is_finite() && t.ng() != Vec3::ZERO).then_some(t)
    }
}

/// One mesh primitive instance: a named run of consecutive triangles with one material.
#[derive(Clone, Debug)]
pub struct Object {
    /// "node (mesh)" name from the file.
    pub name: String,
    /// Triangle ids `first..end`.
    pub tris: std::ops::Range<u32>,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

impl Object {
    /// Bounding sphere (centre of the bounding box, radius to the farthest vertex).
    pub fn bounding_sphere(&self, scene: &Scene) -> Target {
        let tris = &scene.triangles[self.tris.start as usize..self.tris.end as usize];
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in tris.iter().flat_map(|t| t.p) {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        let center = 0.5 * (lo + hi);
        let radius = tris.iter().flat_map(|t| t.p).map(|p| p.distance(center)).fold(0.0, f32::max);
        Target { center, radius: radius * (1.0 + 1e-4) }
    }
}

/// Axis-aligned bounds \[m\].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Bounds {
    /// The empty box (inverted, so that growing it by a point gives that point).
    pub(crate) const EMPTY: Bounds = Bounds { min: Vec3::INFINITY, max: Vec3::NEG_INFINITY };

    /// Grow to contain the box from `lo` to `hi`.
    #[inline(always)]
    pub(crate) fn grow(&mut self, lo: Vec3, hi: Vec3) {
        self.min = self.min.min(lo);
        self.max = self.max.max(hi);
    }

    /// The box containing both.
    #[inline(always)]
    pub(crate) fn join(self, o: Bounds) -> Bounds {
        Bounds { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    /// Half the surface area \[m^2\] (0 for the empty box).
    pub(crate) fn half_area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// Length of the diagonal \[m\]; the unit for radii "relative to the scene".
    pub fn diagonal(&self) -> f32 {
        (self.max - self.min).length()
    }
    /// Centre point.
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// True when the two boxes share a point (touching counts).
    pub fn overlaps(&self, o: &Bounds) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }
}

/// The bounds of `triangles` (zero for none).
pub fn bounds_of(triangles: &[Triangle]) -> Bounds {
    let mut bounds = Bounds::EMPTY;
    for t in triangles {
        for p in t.p {
            bounds.grow(p, p);
        }
    }
    if triangles.is_empty() { Bounds { min: Vec3::ZERO, max: Vec3::ZERO } } else { bounds }
}

impl Scene {
    /// The scene with its triangles split until no edge is longer than `max_edge`
    /// \[m\] ([`Scene::subdivided_within`] without a limit).
    pub fn subdivided(&self, max_edge: f32) -> Scene {
        self.subdivided_within(max_edge, usize::MAX).0
    }

    /// The scene with its triangles split for more corners (Jozwowski 2002 section
    /// 4.3), in rounds: each round splits every edge longer than `max_edge` \[m\] at
    /// its midpoint and each triangle by the edges split (into 2, 3 or 4), for as
    /// many rounds as keep the count within `max_triangles` (or until no edge is
    /// longer). Returns the scene and its longest edge \[m\].
    ///
    /// Whether an edge splits and where its midpoint lies depend on its two ends
    /// only ((a + b) / 2 is the same float either way round), so two triangles that
    /// share an edge split it alike and the mesh stays watertight. (A uniform split
    /// into n^2 by each triangle's own longest edge left T-junctions between
    /// neighbours of different n: cracks a shadow map saw light through.) Shading
    /// normals and texture coordinates are interpolated from the parent, so the
    /// surface and its shading are unchanged; objects, materials, punctual lights and
    /// the camera are kept. Emitting objects (area lights) keep their triangles
    /// whole: a light is sampled by solid angle only from points near one of its
    /// triangles relative to that triangle's size, and a lamp split into small
    /// triangles was sampled by area from the ceiling 9 cm above it, each sample
    /// weighing up to A / d^2: sparks of 10-40 times the mean in the vertex
    /// method's frames (generated scene 60606/33, a direct-light block 248% off;
    /// issue 53). A `max_edge` that is not positive and finite returns a copy.
    pub fn subdivided_within(&self, max_edge: f32, max_triangles: usize) -> (Scene, f32) {
        let longest_edge = |tris: &[Triangle]| {
            tris.iter().flat_map(|t| (0..3).map(move |k| (t.p[(k + 1) % 3] - t.p[k]).length())).fold(0.0f32, f32::max)
        };
        if !(max_edge > 0.0) || !max_edge.is_finite() {
            return (self.clone(), longest_edge(&self.triangles));
        }
        // Triangles after each round, summed over the scene, for the rounds to run.
        let mut counts = [0usize; MAX_SPLIT_ROUNDS + 1];
        for o in &self.objects {
            for t in &self.triangles[o.tris.start as usize..o.tris.end as usize] {
                let split = split_counts(t.p, if self.emits(o) { f32::INFINITY } else { max_edge });
                for (c, n) in counts.iter_mut().zip(split) {
                    *c = c.saturating_add(n);
                }
            }
        }
        let limit = max_triangles.max(self.triangles.len());
        let rounds = counts.iter().rposition(|&c| c <= limit && c < usize::MAX).unwrap_or(0);
        // An animated mesh splits in the scene's space (edge lengths as seen) and
        // the same pieces of its node-space triangles are what is kept and posed.
        let scene = self.map_objects(|o, tris, local| {
            let mut out = Vec::new();
            let rounds = if self.emits(o) { 0 } else { rounds };
            for (i, t) in tris.iter().enumerate() {
                let parent = local.map_or(t, |l| &l[i]);
                for corners in split(t.p, max_edge, rounds, |_| true) {
                    let b = corners.map(|c| c.1.to_array());
                    let p = match local {
                        None => corners.map(|c| c.0),
                        Some(_) => b.map(|w| parent.point(w)),
                    };
                    out.extend(parent.piece(p, b));
                }
            }
            out
        });
        let longest = longest_edge(&scene.triangles);
        (scene, longest)
    }

    /// A stand-in for photon tracing (Jozwowski 2002 section 4.4.1, scene
    /// simplification): every object that does not emit is replaced by its
    /// axis-aligned bounding box (12 triangles of the object's material, facing out);
    /// emitting objects, punctual lights, the camera and the animation are kept.
    pub fn bounding_box_proxy(&self) -> Scene {
        // An animated mesh's box is its node-space box, posed with it.
        self.map_objects(|o, tris, local| {
            let tris = local.unwrap_or(tris);
            if self.emits(o) {
                return tris.to_vec();
            }
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for t in tris {
                for p in t.p {
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
            let v = |i: u32| {
                Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            };
            // Faces as corner indices, counter-clockwise seen from outside.
            let faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
            let mut out = Vec::new();
            for f in faces {
                for tri in [[f[0], f[1], f[2]], [f[0], f[2], f[3]]] {
                    // A flat object has a flat box: its zero-area faces are left out.
                    if let Some(t) = Triangle::new(tri.map(v), o.material) {
                        out.push(t);
                    }
                }
            }
            out
        })
    }

    /// True when object `o`'s material emits (its triangles are an area light's).
    fn emits(&self, o: &Object) -> bool {
        self.materials[o.material as usize].emission.max_element() > 0.0
    }

    /// The scene with each object's triangles replaced by `f(object, its
    /// triangles, None)`; materials, textures, punctual lights, camera, identity and
    /// animation are kept, and each area light covers its object's new triangles.
    /// An animated mesh's object is replaced by `f(object, its triangles, Some(the
    /// same in its node's space))`, which returns node-space triangles: they become
    /// the mesh's rest triangles and, posed where the mesh is now, its triangles (so
    /// that the new scene moves as the old one does).
    fn map_objects(&self, f: impl Fn(&Object, &[Triangle], Option<&[Triangle]>) -> Vec<Triangle>) -> Scene {
        let mut triangles = Vec::new();
        let mut objects = Vec::with_capacity(self.objects.len());
        let mut animation = self.animation.clone();
        // New range of every old triangle's object, for area lights.
        let mut object_range = vec![0u32..0u32; self.triangles.len()];
        for (index, o) in self.objects.iter().enumerate() {
            let start = triangles.len() as u32;
            let tris = &self.triangles[o.tris.start as usize..o.tris.end as usize];
            match animation.meshes.iter_mut().find(|m| m.object == index) {
                Some(m) => {
                    let local = f(o, tris, Some(&m.local));
                    let posed: Vec<(Triangle, Triangle)> =
                        local.into_iter().filter_map(|l| crate::anim::pose(&l, m.pose).map(|w| (l, w))).collect();
                    m.local = posed.iter().map(|(l, _)| l.clone()).collect();
                    triangles.extend(posed.into_iter().map(|(_, w)| w));
                }
                None => triangles.extend(f(o, tris, None)),
            }
            let range = start..triangles.len() as u32;
            for t in o.tris.clone() {
                object_range[t as usize] = range.clone();
            }
            objects.push(Object { tris: range, ..o.clone() });
        }
        let lights: Vec<Light> = self
            .lights
            .iter()
            .map(|l| match &l.kind {
                LightKind::Area { tris, .. } if !tris.is_empty() => {
                    let t0 = tris.start as usize;
                    let material = &self.materials[self.triangles[t0].material as usize];
                    Light::area(l.name.clone(), object_range[t0].clone(), &triangles, material)
                }
                _ => l.clone(),
            })
            .collect();
        let contents = crate::Contents {
            triangles,
            materials: self.materials.clone(),
            textures: self.textures.clone(),
            lights,
            objects,
            camera: self.camera.clone(),
        };
        let mut scene = Scene::build(contents, self.content_hash, self.warnings.clone());
        // The same surfaces (or a stand-in for them): keep the original's bounds, so
        // every relative radius means the same length; lights keep their indices, so
        // the animation carries over.
        scene.bounds = self.bounds;
        scene.animation = animation;
        scene.origin = self.origin;
        // The same media, in the same places (objects keep their indices).
        scene.media = self.media.clone();
        scene.layout = self.layout.clone();
        scene
    }
}

/// Most rounds of [`Scene::subdivided_within`]: each halves the split edges, so
/// 24 take an edge below 1e-7 of its length.
const MAX_SPLIT_ROUNDS: usize = 24;

/// A corner of a split triangle: its position \[m\] and barycentrics in the parent.
type Corner = (Vec3, Vec3);

/// One round: the edges of `t` (counter-clockwise) longer than `max_edge` split at
/// their midpoints, and `t` into the triangles those make, in the same winding.
fn split_once(t: [Corner; 3], max_edge: f32, out: &mut Vec<[Corner; 3]>) {
    let mid = |a: Corner, b: Corner| ((a.0 + b.0) * 0.5, (a.1 + b.1) * 0.5);
    let long = |a: Corner, b: Corner| (a.0 - b.0).length() > max_edge;
    let [v0, v1, v2] = t;
    match (long(v0, v1), long(v1, v2), long(v2, v0)) {
        (false, false, false) => out.push(t),
        (true, false, false) => {
            let m = mid(v0, v1);
            out.extend([[v0, m, v2], [m, v1, v2]]);
        }
        (false, true, false) => {
            let m = mid(v1, v2);
            out.extend([[v0, v1, m], [v0, m, v2]]);
        }
        (false, false, true) => {
            let m = mid(v2, v0);
            out.extend([[v0, v1, m], [m, v1, v2]]);
        }
        (true, true, true) => {
            let (m0, m1, m2) = (mid(v0, v1), mid(v1, v2), mid(v2, v0));
            out.extend([[v0, m0, m2], [m0, v1, m1], [m2, m1, v2], [m0, m1, m2]]);
        }
        (s0, s1, _) => {
            // Two edges split: turn the triangle so the whole edge is (w2, w0), cut
            // off the corner at w1, and split the quad left by its shorter diagonal.
            let [w0, w1, w2] = if !s0 {
                [v1, v2, v0]
            } else if !s1 {
                [v2, v0, v1]
            } else {
                [v0, v1, v2]
            };
            let (m0, m1) = (mid(w0, w1), mid(w1, w2));
            out.push([m0, w1, m1]);
            if (w0.0 - m1.0).length() <= (m0.0 - w2.0).length() {
                out.extend([[w0, m0, m1], [w0, m1, w2]]);
            } else {
                out.extend([[w0, m0, w2], [m0, m1, w2]]);
            }
        }
    }
}

/// The triangle with corners `p` after up to `rounds` rounds of [`split_once`]:
/// `after_round(count)` hears the count after each round that split something, and
/// stops the rounds by returning false; a round that splits nothing ends them.
fn split(p: [Vec3; 3], max_edge: f32, rounds: usize, mut after_round: impl FnMut(usize) -> bool) -> Vec<[Corner; 3]> {
    let mut tris = vec![[(p[0], Vec3::X), (p[1], Vec3::Y), (p[2], Vec3::Z)]];
    let mut next = Vec::new();
    for _ in 0..rounds {
        next.clear();
        for &t in &tris {
            split_once(t, max_edge, &mut next);
        }
        if next.len() == tris.len() {
            break;
        }
        std::mem::swap(&mut tris, &mut next);
        if !after_round(tris.len()) {
            break;
        }
    }
    tris
}

/// Most triangles one triangle is counted into: a round past it counts as too many.
const MAX_SPLIT_COUNT: usize = 1 << 20;

/// How many triangles the triangle with corners `p` is after 0, 1, ...,
/// [`MAX_SPLIT_ROUNDS`] rounds (`usize::MAX` past [`MAX_SPLIT_COUNT`]).
fn split_counts(p: [Vec3; 3], max_edge: f32) -> [usize; MAX_SPLIT_ROUNDS + 1] {
    let mut counts = [usize::MAX; MAX_SPLIT_ROUNDS + 1];
    counts[0] = 1;
    let mut round = 0;
    split(p, max_edge, MAX_SPLIT_ROUNDS, |n| {
        round += 1;
        counts[round] = if n > MAX_SPLIT_COUNT { usize::MAX } else { n };
        n <= MAX_SPLIT_COUNT
    });
    // Past the last round that split something, the count stays (unless too many).
    let last = counts[round];
    if last < usize::MAX {
        counts[round..].fill(last);
    }
    counts
}
