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
    /// Unit geometric normal from the winding (counter-clockwise = front).
    pub ng: Vec3,
    /// Area [m^2].
    pub area: f32,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

impl Triangle {
    /// Position \[m\] and interpolated unit vertex normal (the geometric normal
    /// when there are none; not yet turned to its side, nor normal-mapped) at
    /// barycentrics `b`.
    #[inline]
    pub fn point_normal(&self, b: [f32; 3]) -> (Vec3, Vec3) {
        let p = self.p[0] * b[0] + self.p[1] * b[1] + self.p[2] * b[2];
        let ns = self.n.map_or(self.ng, |n| (n[0] * b[0] + n[1] * b[1] + n[2] * b[2]).normalize_or(self.ng));
        (p, ns)
    }

    /// The corners' texture coordinates of set `set` (TEXCOORD_0 or TEXCOORD_1), when
    /// the mesh has them.
    pub fn uvs(&self, set: u8) -> Option<&[Vec2; 3]> {
        if set == 1 { self.uv1.as_ref() } else { self.uv.as_ref() }
    }

    /// Swap corners 1 and 2 of the per-vertex attributes (a mirroring transform
    /// reverses the winding).
    pub(crate) fn swap_corners(&mut self) {
        if let Some(uv) = self.uv.as_mut() {
            uv.swap(1, 2);
        }
        if let Some(uv) = self.uv1.as_mut() {
            uv.swap(1, 2);
        }
        if let Some(c) = self.color.as_mut() {
            c.swap(1, 2);
        }
        if let Some(t) = self.tangent.as_mut() {
            t.swap(1, 2);
        }
    }

    /// A triangle without vertex normals or UVs; `None` when it has no area.
    pub fn new(p: [Vec3; 3], material: u32) -> Option<Triangle> {
        let cross = (p[1] - p[0]).cross(p[2] - p[0]);
        let area = 0.5 * cross.length();
        let ng = cross.normalize_or_zero();
        (area > 0.0 && area.is_finite() && ng != Vec3::ZERO).then_some(Triangle {
            p,
            n: None,
            uv: None,
            uv1: None,
            color: None,
            tangent: None,
            ng,
            area,
            material,
        })
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
    /// Length of the diagonal \[m\]; the unit for radii "relative to the scene".
    pub fn diagonal(&self) -> f32 {
        (self.max - self.min).length()
    }
    /// Centre point.
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
}

/// The bounds of `triangles` (zero for none).
pub fn bounds_of(triangles: &[Triangle]) -> Bounds {
    let mut bounds = Bounds { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };
    for t in triangles {
        for p in t.p {
            bounds.min = bounds.min.min(p);
            bounds.max = bounds.max.max(p);
        }
    }
    if triangles.is_empty() { Bounds { min: Vec3::ZERO, max: Vec3::ZERO } } else { bounds }
}

impl Scene {
    /// The scene with every triangle split uniformly into n^2 triangles, n the
    /// smallest count with (longest edge / n) <= `max_edge` \[m\] (Jozwowski 2002
    /// section 4.3: more vertices, so estimates at vertices resolve more detail).
    /// Positions, shading normals and texture coordinates are interpolated from the
    /// parent, so the surface and its shading are unchanged; objects, materials,
    /// punctual lights and the camera are kept, and area lights cover their split
    /// triangles. A `max_edge` that is not positive and finite returns a copy.
    pub fn subdivided(&self, max_edge: f32) -> Scene {
        if !(max_edge > 0.0) || !max_edge.is_finite() {
            return self.clone();
        }
        self.map_objects(|_, tris| {
            let mut out = Vec::new();
            for t in tris {
                let longest = (0..3).map(|k| (t.p[(k + 1) % 3] - t.p[k]).length()).fold(0.0f32, f32::max);
                let n = ((longest / max_edge).ceil() as usize).clamp(1, 1024);
                let at = |i: usize, j: usize| {
                    let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                    [1.0 - u - v, u, v]
                };
                let mut emit = |b: [[f32; 3]; 3]| {
                    let lerp3 = |q: &[Vec3; 3], w: [f32; 3]| q[0] * w[0] + q[1] * w[1] + q[2] * w[2];
                    let p = b.map(|w| lerp3(&t.p, w));
                    if let Some(mut sub) = Triangle::new(p, t.material) {
                        sub.n = t.n.map(|n| b.map(|w| lerp3(&n, w).normalize_or(t.ng)));
                        let lerp2 = |q: &[Vec2; 3]| b.map(|w| q[0] * w[0] + q[1] * w[1] + q[2] * w[2]);
                        sub.uv = t.uv.as_ref().map(lerp2);
                        sub.uv1 = t.uv1.as_ref().map(lerp2);
                        sub.color = t.color.map(|c| b.map(|w| c[0] * w[0] + c[1] * w[1] + c[2] * w[2]));
                        sub.tangent = t.tangent.map(|c| b.map(|w| c[0] * w[0] + c[1] * w[1] + c[2] * w[2]));
                        out.push(sub);
                    }
                };
                for i in 0..n {
                    for j in 0..n - i {
                        emit([at(i, j), at(i + 1, j), at(i, j + 1)]);
                        if i + j + 1 < n {
                            emit([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                        }
                    }
                }
            }
            out
        })
    }

    /// A stand-in for photon tracing (Jozwowski 2002 section 4.4.1, scene
    /// simplification): every object that does not emit is replaced by its
    /// axis-aligned bounding box (12 triangles of the object's material, facing out);
    /// emitting objects, punctual lights, the camera and the animation are kept.
    pub fn bounding_box_proxy(&self) -> Scene {
        self.map_objects(|o, tris| {
            if self.materials[o.material as usize].emission.max_element() > 0.0 {
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

    /// The scene with each object's triangles replaced by `f(object, its
    /// triangles)`; materials, textures, punctual lights, camera, identity and
    /// animation are kept, and each area light covers its object's new triangles.
    fn map_objects(&self, f: impl Fn(&Object, &[Triangle]) -> Vec<Triangle>) -> Scene {
        let mut triangles = Vec::new();
        let mut objects = Vec::with_capacity(self.objects.len());
        // New range of every old triangle's object, for area lights.
        let mut object_range = vec![0u32..0u32; self.triangles.len()];
        for o in &self.objects {
            let start = triangles.len() as u32;
            triangles.extend(f(o, &self.triangles[o.tris.start as usize..o.tris.end as usize]));
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
        let mut scene = Scene::build(
            triangles,
            self.materials.clone(),
            self.textures.clone(),
            lights,
            objects,
            self.camera.clone(),
            self.content_hash,
            self.warnings.clone(),
        );
        // The same surfaces (or a stand-in for them): keep the original's bounds, so
        // every relative radius means the same length; lights keep their indices, so
        // the animation carries over.
        scene.bounds = self.bounds;
        scene.animation = self.animation.clone();
        scene.origin = self.origin;
        scene
    }
}
