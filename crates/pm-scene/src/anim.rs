//! glTF animations (glTF 2.0 section 3.11): translation, rotation and scale channels
//! of nodes with STEP, LINEAR (spherical for rotations) and CUBICSPLINE (Hermite)
//! interpolation, evaluated at a time to move the lights and the camera that hang
//! below animated nodes. Animations loop over their longest channel.

use crate::accel::build_bvh;
use crate::{Light, LightKind, Scene, Triangle, bounds_of, light};
use glam::{Mat4, Quat, Vec3, Vec4};

/// Which property a channel animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Path {
    Translation,
    Rotation,
    Scale,
}

/// How a channel interpolates between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Interp {
    Step,
    Linear,
    CubicSpline,
}

/// One animation channel: key times [s] and values (x, y, z[, w]); CUBICSPLINE keeps
/// (in-tangent, value, out-tangent) per key.
#[derive(Clone, Debug)]
pub(crate) struct Channel {
    pub node: usize,
    pub path: Path,
    pub interp: Interp,
    pub times: Vec<f32>,
    pub values: Vec<Vec4>,
}

/// An object below an animated node: its index in `Scene::objects`, the node,
/// its triangles in the node's own space (in the object's triangle order), and
/// the transform that places them where the scene's triangles are now.
#[derive(Clone, Debug)]
pub(crate) struct AnimatedMesh {
    pub object: usize,
    pub node: usize,
    pub local: Vec<crate::Triangle>,
    /// Node space to the scene's (camera-relative) space at the current pose: the
    /// rest pose as loaded, then the last [`Scene::set_time`]'s.
    pub pose: Mat4,
}

/// `local` (a triangle in its node's space) placed by `world`, with its normals and
/// tangents, its corners swapped when `world` mirrors (counter-clockwise stays the
/// front); `None` when the transform flattens it.
pub(crate) fn pose(local: &Triangle, world: Mat4) -> Option<Triangle> {
    let linear = glam::Mat3::from_mat4(world);
    let normal_m = linear.inverse().transpose();
    let flip = linear.determinant() < 0.0;
    let mut p = local.p.map(|q| world.transform_point3(q));
    let mut n = local.n.map(|n| n.map(|v| (normal_m * v).normalize_or_zero()));
    let mut attrs = local.clone();
    if let Some(t) = local.tangent() {
        attrs.extras_mut().tangent = Some(t.map(|t| {
            let w = if flip { -t.w } else { t.w };
            (linear * t.truncate()).normalize_or_zero().extend(w)
        }));
    }
    if flip {
        p.swap(1, 2);
        if let Some(n) = n.as_mut() {
            n.swap(1, 2);
        }
        attrs.swap_corners();
    }
    let moved = Triangle::new(p, local.material)?;
    Some(Triangle { n, p: moved.p, ..attrs })
}

/// A node's rest pose and parent.
#[derive(Clone, Debug)]
pub(crate) struct NodeRest {
    pub parent: Option<usize>,
    pub t: Vec3,
    pub r: Quat,
    pub s: Vec3,
}

/// What moves with the animation: the node hierarchy, the channels, and the nodes
/// lights and the camera hang on.
#[derive(Clone, Debug, Default)]
pub struct Animation {
    pub(crate) nodes: Vec<NodeRest>,
    pub(crate) channels: Vec<Channel>,
    /// (light index, node) of every light below an animated node.
    pub(crate) lights: Vec<(usize, usize)>,
    /// The camera's node, when it is below an animated node.
    pub(crate) camera: Option<usize>,
    /// Meshes below animated nodes, with their triangles in the node's space.
    pub(crate) meshes: Vec<AnimatedMesh>,
    /// Length of the animation \[s\] (its last key time).
    pub duration: f32,
    /// World position of the scene's coordinate origin [m] (the camera's rest
    /// position: see `Scene::origin`); world transforms are moved by minus this.
    pub(crate) origin: glam::DVec3,
}

impl Channel {
    /// The channel's value at time `t` [s] (clamped to its first and last keys).
    fn sample(&self, t: f32) -> Vec4 {
        let n = self.times.len();
        let key = |i: usize| match self.interp {
            Interp::CubicSpline => self.values[3 * i + 1],
            _ => self.values[i],
        };
        if n == 0 {
            return Vec4::ZERO;
        }
        if !(t > self.times[0]) || n == 1 {
            return key(0);
        }
        if t >= self.times[n - 1] {
            return key(n - 1);
        }
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let dt = t1 - t0;
        let u = if dt > 0.0 { (t - t0) / dt } else { 0.0 };
        match self.interp {
            Interp::Step => key(k),
            Interp::Linear if self.path == Path::Rotation => {
                Vec4::from(Quat::from_vec4(key(k)).normalize().slerp(Quat::from_vec4(key(k + 1)).normalize(), u))
            }
            Interp::Linear => key(k).lerp(key(k + 1), u),
            Interp::CubicSpline => {
                // glTF Appendix C: p(u) = (2u^3 - 3u^2 + 1) v_k + dt (u^3 - 2u^2 + u) b_k
                //                 + (-2u^3 + 3u^2) v_k+1 + dt (u^3 - u^2) a_k+1.
                let (u2, u3) = (u * u, u * u * u);
                let b_k = self.values[3 * k + 2];
                let a_k1 = self.values[3 * (k + 1)];
                key(k) * (2.0 * u3 - 3.0 * u2 + 1.0)
                    + b_k * (dt * (u3 - 2.0 * u2 + u))
                    + key(k + 1) * (-2.0 * u3 + 3.0 * u2)
                    + a_k1 * (dt * (u3 - u2))
            }
        }
    }
}

impl Animation {
    /// True when nothing moves.
    pub fn is_empty(&self) -> bool {
        self.channels.is_empty()
    }

    /// The local transform of `node` at time `t` [s], in f64.
    fn local(&self, node: usize, t: f32) -> glam::DMat4 {
        let rest = &self.nodes[node];
        let (mut tr, mut r, mut s) = (rest.t, rest.r, rest.s);
        for c in self.channels.iter().filter(|c| c.node == node) {
            let v = c.sample(t);
            match c.path {
                Path::Translation => tr = v.truncate(),
                Path::Rotation => r = Quat::from_vec4(v).normalize(),
                Path::Scale => s = v.truncate(),
            }
        }
        glam::DMat4::from_scale_rotation_translation(s.as_dvec3(), r.as_dquat(), tr.as_dvec3())
    }

    /// The world transform of `node` at time `t` [s], in the scene's camera-relative
    /// space (composed in f64, moved by `-origin`, then cast); animations loop.
    pub(crate) fn world(&self, node: usize, t: f32) -> Mat4 {
        let t = if self.duration > 0.0 { t.rem_euclid(self.duration) } else { 0.0 };
        let mut m = self.local(node, t);
        let mut n = node;
        let mut guard = 0;
        while let Some(p) = self.nodes[n].parent {
            m = self.local(p, t) * m;
            n = p;
            guard += 1;
            if guard > 256 {
                break;
            }
        }
        (glam::DMat4::from_translation(-self.origin) * m).as_mat4()
    }

    /// True when `node` or one of its ancestors has a channel.
    pub(crate) fn moves(&self, node: usize) -> bool {
        let mut n = Some(node);
        let mut guard = 0;
        while let Some(k) = n {
            if self.channels.iter().any(|c| c.node == k) {
                return true;
            }
            n = self.nodes[k].parent;
            guard += 1;
            if guard > 256 {
                return false;
            }
        }
        false
    }
}

impl Scene {
    /// True when the animation moves meshes (their triangles change with the time).
    pub fn has_moving_meshes(&self) -> bool {
        !self.animation.meshes.is_empty()
    }

    /// The triangles the animation moves (those of meshes below animated nodes).
    pub fn moving_triangles(&self) -> impl Iterator<Item = &Triangle> {
        self.animation.meshes.iter().flat_map(|m| {
            let r = &self.objects[m.object].tris;
            &self.triangles[r.start as usize..r.end as usize]
        })
    }

    /// Move the animated lights, camera and meshes to time `t` \[s\] (animations loop
    /// over their length). Lights and the camera move without rebuilding anything;
    /// moved meshes are re-transformed from their rest pose and the BVH is rebuilt.
    pub fn set_time(&mut self, t: f32) {
        let anim = &self.animation;
        for &(li, node) in &anim.lights {
            let world = anim.world(node, t);
            let position = world.transform_point3(Vec3::ZERO);
            let axis = world.transform_vector3(-Vec3::Z).normalize_or_zero();
            match &mut self.lights[li].kind {
                LightKind::Point { position: p, .. } => *p = position,
                LightKind::Spot { position: p, direction, .. } => {
                    *p = position;
                    if axis != Vec3::ZERO {
                        *direction = axis;
                    }
                }
                LightKind::Directional { direction, .. } => {
                    if axis != Vec3::ZERO {
                        *direction = axis;
                    }
                }
                LightKind::Area { .. } | LightKind::Environment { .. } => {}
            }
        }
        if !anim.meshes.is_empty() {
            let poses: Vec<Mat4> = anim.meshes.iter().map(|m| anim.world(m.node, t)).collect();
            for (m, &world) in self.animation.meshes.iter_mut().zip(&poses) {
                m.pose = world;
                let range = self.objects[m.object].tris.clone();
                for (local, out) in m.local.iter().zip(&mut self.triangles[range.start as usize..range.end as usize]) {
                    // A transform that flattens a triangle keeps its last good pose.
                    if let Some(moved) = pose(local, world) {
                        *out = moved;
                    }
                }
            }
            // Area lights on moved meshes cover their new triangles.
            let anim = &self.animation;
            for l in &mut self.lights {
                if let LightKind::Area { tris, .. } = &l.kind
                    && !tris.is_empty()
                    && anim.meshes.iter().any(|m| self.objects[m.object].tris.contains(&tris.start))
                {
                    let (range, t0) = (tris.clone(), tris.start);
                    let material = &self.materials[self.triangles[t0 as usize].material as usize];
                    *l = Light::area(l.name.clone(), range, &self.triangles, material);
                }
            }
            // Rebuild (a few milliseconds for thousands of triangles) rather than refit,
            // in the moved scene's own normalised coordinates; the radius reference
            // (`bounds`) stays.
            let bvh_bounds = bounds_of(&self.triangles);
            let (bvh, bvh_tris) = build_bvh(&self.triangles, &bvh_bounds);
            self.bvh = bvh;
            self.bvh_tris = bvh_tris;
            self.bvh_inv_scale = 1.0 / bvh_bounds.diagonal().max(f32::MIN_POSITIVE);
            light::finish_lights(self);
        }
        let anim = &self.animation;
        if let (Some(node), Some(cam)) = (anim.camera, self.camera.as_mut()) {
            let world = anim.world(node, t);
            let r = glam::Mat3::from_mat4(world);
            let forward = (r * -Vec3::Z).normalize_or_zero();
            let right = forward.cross((r * Vec3::Y).normalize_or_zero()).normalize_or_zero();
            if right != Vec3::ZERO {
                cam.position = world.transform_point3(Vec3::ZERO);
                cam.forward = forward;
                cam.right = right;
                cam.up = right.cross(forward);
            }
        }
        if self.has_media() {
            self.locate_media();
        }
    }
}
