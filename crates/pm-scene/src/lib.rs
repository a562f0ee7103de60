//! The scene: triangles, materials, lights and camera loaded from glTF 2.0, and the
//! ray queries every stage needs (closest hit and shadow-ray occlusion on a
//! eight-wide BVH built by the binned surface area heuristic: `bvh`).
//!
//! Units (see README): lengths are the glTF file's metres; emission of emissive
//! triangles is radiance L_e [W sr^-1 m^-2 per channel] = emissiveFactor x
//! KHR_materials_emissive_strength; KHR_lights_punctual point and spot intensities
//! are candela by default ([`LightUnits`]), read as radiant intensity
//! I [W sr^-1 per channel] = intensity / 683 x colour; directional light intensity is
//! lux, read as irradiance E [W m^-2 per channel] = intensity / 683 x colour on a
//! surface facing it. With `LightUnits::Radiometric` the 683 is left out.
//!
//! This crate knows nothing about photons, photon maps or files other than glTF. A
//! `Scene` is immutable after loading and `Send + Sync`, so one instance serves all
//! rayon threads, and later the per-frame real-time and image-space modes.

mod accel;
mod anim;
mod bvh;
mod camera;
mod draco;
mod environment;
mod geometry;
mod gltf_load;
mod light;
mod material;
mod medium;
mod memory;
mod mesh;
mod meshopt_views;
mod portal;

pub use anim::Animation;
pub use camera::{Camera, CameraRays};
pub use environment::{
    Environment, EnvironmentSample, EnvironmentSource, EnvironmentSpec, direction_to_uv, uv_to_direction,
};
pub use geometry::{TriangleRay, facing, intersect_triangle, offset_ray_origin, same_side};
pub use gltf_load::{SceneError, load, load_with};
pub use light::{
    AreaPoint, EmittedRay, EmitterPoint, Light, LightKind, LightSample, OUTLINE_TRIANGLES, Outline, SkyDirection,
    Target, spot_falloff, sun_radiance,
};
pub use material::{AlphaMode, Filter, LayerTextures, Material, Texture, TextureRef, Wrap};
pub use medium::{Flights, FreeFlight, Medium, MediumId, Passage, single_scattering_albedo};
pub use memory::MemoryUse;
pub use mesh::{Bounds, Object, Triangle, TriangleExtras, bounds_of};
pub use portal::Portal;

use accel::{BvhTris, build_bvh};
use glam::{Vec2, Vec3};
use pm_color::Rgb;

/// Luminous efficacy that converts photometric light units to radiometric ones
/// [lm/W]: the glTF exporters' convention (Blender writes P x 683 / (4 pi) cd for a
/// P-watt point lamp in its default "Standard" lighting mode).
pub const LUMINOUS_EFFICACY: f32 = 683.0;

// By hand: `value_enum!` passes only doc attributes to the variants, so no
// `#[default]`.
#[allow(clippy::derivable_impls)]
impl Default for LightUnits {
    fn default() -> Self {
        LightUnits::Photometric
    }
}

pm_params::value_enum! {
    /// What `KHR_lights_punctual` intensities are in.
    pub enum LightUnits {
        /// The glTF specification's: candela (lm/sr) for point and spot lights, lux
        /// (lm/m^2) for directional lights; divided by 683 lm/W to W/sr and W/m^2.
        Photometric,
        /// Already W/sr and W/m^2 (Blender's "Unitless" export writes W / (4 pi)).
        Radiometric,
    }
}

/// A ray-surface intersection.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Distance along the (unit) ray direction \[m\].
    pub t: f32,
    /// Triangle id (index into [`Scene::triangles`]).
    pub tri: u32,
    /// Barycentric coordinates of the hit point.
    pub b: [f32; 3],
    /// Hit point, interpolated from the vertices \[m\].
    pub p: Vec3,
    /// Unit geometric normal (winding order; not flipped toward the ray).
    pub ng: Vec3,
    /// Unit shading normal, on the same side as `ng`.
    pub ns: Vec3,
    /// Texture coordinates TEXCOORD_0 (zero when the mesh has none).
    pub uv: Vec2,
    /// Texture coordinates TEXCOORD_1 (zero when the mesh has none).
    pub uv1: Vec2,
    /// Vertex colour COLOR_0, linear RGBA (one when the mesh has none).
    pub color: glam::Vec4,
}

/// A loaded scene. Immutable while rendered, `Send + Sync`; a live renderer clones
/// it to move punctual lights between frames.
#[derive(Clone)]
pub struct Scene {
    /// Triangles in file order; the triangle id indexes this.
    pub triangles: Vec<Triangle>,
    /// Materials; index 0.. as in the file, plus a default at the end.
    pub materials: Vec<Material>,
    /// Base-colour textures.
    pub textures: Vec<Texture>,
    /// Light sources (emissive meshes, punctual lights and the environment).
    pub lights: Vec<Light>,
    /// Participating media (homogeneous), by [`MediumId`]: the insides of meshes
    /// whose material bounds one ([`Material::interior`]) and the one filling the
    /// scene ([`Scene::scene_medium`]).
    pub media: Vec<Medium>,
    /// Where the media are (outside each mesh, at the camera and the lights).
    layout: medium::MediaLayout,
    /// The lights that rays leaving the scene see (an environment, suns with a
    /// size), by index into `lights`: what [`Scene::escaped`] sums.
    pub infinite_lights: Vec<u32>,
    /// Mesh primitive instances, in file order, covering every triangle.
    pub objects: Vec<Object>,
    /// For each triangle, the index of the area light it belongs to (u32::MAX: none).
    pub light_of_triangle: Vec<u32>,
    /// The first camera found in the scene, if any.
    pub camera: Option<Camera>,
    /// World position \[m\] of this scene's coordinate origin: positions are stored
    /// relative to the first perspective camera's rest position snapped to a 16 m
    /// grid (pbrt-v4's "camera-world" space; transforms composed in f64 before the
    /// cast to f32), so a scene far from the file's origin keeps its precision and a
    /// scene near it keeps its coordinates. Zero without a camera.
    pub origin: glam::DVec3,
    /// Bounds of all triangles.
    pub bounds: Bounds,
    /// blake3 of the glTF file and every buffer it references: the identity that
    /// photon-map headers record so maps from another scene are refused.
    pub content_hash: [u8; 32],
    /// Problems that did not stop loading, each reported once.
    pub warnings: Vec<String>,
    /// The environment the glTF file's scene extras name (`"environment"`), not yet
    /// read: a program reads it unless its own settings name another.
    pub environment_spec: Option<EnvironmentSpec>,
    /// The glTF animations that move lights and the camera ([`Scene::set_time`]).
    pub animation: Animation,
    /// What loading took \[s\]: reading and decoding the file (geometry, textures,
    /// tangents) and building the BVH (zero for scenes built in code).
    pub load_seconds: f64,
    /// Building the BVH \[s\] (part of `load_seconds` for loaded scenes).
    pub bvh_seconds: f64,
    /// Some material has an alpha mode: ray queries test alpha at candidate hits.
    any_alpha: bool,
    bvh: bvh::Bvh,
    /// The triangles in the BVH's slot order.
    bvh_tris: BvhTris,
    /// 1 / the diagonal of the BVH's bounds [m^-1] (the scale of ray-origin offsets).
    bvh_inv_scale: f32,
}

/// What a scene is made of before its acceleration structure is built.
pub(crate) struct Contents {
    /// Degenerate ones already removed.
    pub triangles: Vec<Triangle>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub lights: Vec<Light>,
    pub objects: Vec<Object>,
    pub camera: Option<Camera>,
}

impl Scene {
    /// Build the acceleration structure over the contents' triangles; the scene
    /// file's hash and what loading it warned of are kept with it.
    pub(crate) fn build(contents: Contents, content_hash: [u8; 32], warnings: Vec<String>) -> Scene {
        let Contents { triangles, materials, textures, lights, objects, camera } = contents;
        // Lists grown as they are built (subdivision, proxies, skipped degenerate
        // triangles) keep spare capacity: before the loader reserved its list at
        // its final size, this was a fifth of a loaded scene's triangle bytes.
        let mut triangles = triangles;
        triangles.shrink_to_fit();
        let bounds = bounds_of(&triangles);
        let t0 = std::time::Instant::now();
        let (bvh, bvh_tris) = build_bvh(&triangles, &bounds);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let mut light_of_triangle = vec![u32::MAX; triangles.len()];
        for (i, l) in lights.iter().enumerate() {
            if let LightKind::Area { tris, .. } = &l.kind {
                for t in tris.clone() {
                    light_of_triangle[t as usize] = i as u32;
                }
            }
        }
        let any_alpha = materials.iter().any(Material::has_alpha);
        let mut scene = Scene {
            load_seconds: bvh_seconds,
            bvh_seconds,
            any_alpha,
            light_of_triangle,
            infinite_lights: Vec::new(),
            environment_spec: None,
            animation: Animation::default(),
            triangles,
            materials,
            textures,
            lights,
            media: Vec::new(),
            layout: medium::MediaLayout::default(),
            objects,
            camera,
            origin: glam::DVec3::ZERO,
            bounds,
            content_hash,
            warnings,
            bvh,
            bvh_tris,
            bvh_inv_scale: 1.0 / bounds.diagonal().max(f32::MIN_POSITIVE),
        };
        light::finish_lights(&mut scene);
        scene.media_flags();
        scene
    }

    /// A scene built in code (tests, generated scenes, later real-time callers):
    /// each run of consecutive triangles with one material becomes an object, and
    /// each emissive object an area light. `extra_lights` adds punctual lights.
    pub fn from_parts(
        triangles: Vec<Triangle>,
        materials: Vec<Material>,
        extra_lights: Vec<Light>,
        camera: Option<Camera>,
    ) -> Scene {
        let mut objects: Vec<Object> = Vec::new();
        for (i, t) in triangles.iter().enumerate() {
            match objects.last_mut() {
                Some(o) if o.material == t.material => o.tris.end = i as u32 + 1,
                _ => objects.push(Object {
                    name: format!("object #{} ({})", objects.len(), materials[t.material as usize].name),
                    tris: i as u32..i as u32 + 1,
                    material: t.material,
                }),
            }
        }
        let mut lights = Vec::new();
        for o in &objects {
            let m = &materials[o.material as usize];
            if m.emission.max_element() > 0.0 {
                lights.push(Light::area(o.name.clone(), o.tris.clone(), &triangles, m));
            }
        }
        lights.extend(extra_lights);
        let textures = Vec::new();
        Scene::build(Contents { triangles, materials, textures, lights, objects, camera }, [0; 32], Vec::new())
    }

    /// The index of the object (in `objects`) that triangle `tri` belongs to.
    pub fn object_of(&self, tri: u32) -> Option<u32> {
        let i = self.objects.partition_point(|o| o.tris.end <= tri);
        self.objects.get(i).filter(|o| o.tris.contains(&tri)).map(|_| i as u32)
    }

    /// True when `name` (a light's or an object's, as the loader makes them) is
    /// what a user's `wanted` names: equal to it, or `wanted` followed by " ("
    /// (the loader's suffix for a primitive or a material). The one rule by which
    /// light shares and portals find what they name.
    pub fn names(name: &str, wanted: &str) -> bool {
        name.strip_prefix(wanted).is_some_and(|rest| rest.is_empty() || rest.starts_with(" ("))
    }

    /// Sum of the power of all lights [W per channel].
    pub fn total_power(&self) -> Rgb {
        self.lights.iter().map(|l| l.power).sum()
    }

    /// Radiance L [W sr^-1 m^-2 per channel] arriving along a ray that leaves the
    /// scene in unit direction `d`: the environment and the discs of suns with a
    /// size (zero in a scene without them).
    #[inline]
    pub fn escaped(&self, d: Vec3) -> Rgb {
        let mut l = Rgb::ZERO;
        for &i in &self.infinite_lights {
            l += self.lights[i as usize].radiance_escaped(d);
        }
        l
    }

    /// The environment light, if the scene has one.
    pub fn environment(&self) -> Option<&Environment> {
        self.lights.iter().find_map(|l| match &l.kind {
            LightKind::Environment { env, .. } => Some(&**env),
            _ => None,
        })
    }

    /// Light the scene with `env` from infinitely far away (replacing an
    /// environment it had): a light named "environment" whose power is pi R^2
    /// times the integral of its radiance, R the bounding sphere's radius.
    /// The environment's radiance and rotation join the scene's content hash, so
    /// photon maps traced under another sky are refused.
    pub fn set_environment(&mut self, env: Environment) {
        let identity = env.identity();
        self.lights.retain(|l| !matches!(l.kind, LightKind::Environment { .. }));
        self.lights.push(Light {
            name: "environment".into(),
            kind: LightKind::Environment {
                env: std::sync::Arc::new(env),
                center: Vec3::ZERO,
                radius: 0.0,
                portals: Vec::new(),
            },
            power: Rgb::ZERO,
        });
        self.relight(b"environment", &identity);
    }

    /// True for an angular diameter a sun disc can have \[degrees\]: 0 < angle < 180.
    pub fn sun_angle_ok(angle_deg: f32) -> bool {
        angle_deg > 0.0 && angle_deg < 180.0
    }

    /// Give directional lights a size: a disc of angular diameter `angle_deg`
    /// (0 < angle < 180) with the same irradiance at normal incidence, for the
    /// lights named `name` (all directional lights when `None`). Returns how many
    /// lights changed. The content hash records the change.
    pub fn set_sun_angle(&mut self, name: Option<&str>, angle_deg: f32) -> usize {
        debug_assert!(Scene::sun_angle_ok(angle_deg), "sun angle {angle_deg}");
        let half = 0.5 * angle_deg.to_radians();
        // 1 - cos(half) = 2 sin^2(half / 2), exact for small angles.
        let cap = 2.0 * (0.5 * half).sin().powi(2);
        let mut n = 0;
        for l in &mut self.lights {
            if let LightKind::Directional { cap: c, .. } = &mut l.kind
                && name.is_none_or(|want| l.name == want)
            {
                *c = cap;
                n += 1;
            }
        }
        let tag = format!("sun {name:?} {angle_deg}");
        self.relight(tag.as_bytes(), &[]);
        n
    }

    /// Make the meshes named `names` the portals the environment lights the scene
    /// through ([`Portal`]): each must be one quad; it becomes an opening (its
    /// triangles are made invisible to every ray) whose outward side faces away
    /// from the scene's centre. A name matches objects as [`Scene::names`] says.
    /// Fails, saying why, without an
    /// environment, for a name no mesh has, and for a mesh that is not a quad or
    /// emits light.
    pub fn set_portals(&mut self, names: &[String]) -> Result<(), String> {
        if names.is_empty() {
            return Ok(());
        }
        if self.environment().is_none() {
            return Err("portals need an environment to let in".into());
        }
        let inside = self.bounds.center();
        let mut portals = Vec::new();
        let invisible = self.materials.len() as u32;
        let mut material = Material::new("portal opening", pm_bsdf::Bsdf::Lambert { rho: Rgb::ZERO }, Rgb::ZERO);
        material.alpha_mode = AlphaMode::Mask { cutoff: 0.5 };
        material.base_alpha = 0.0;
        for name in names {
            let matching: Vec<usize> =
                (0..self.objects.len()).filter(|&i| Scene::names(&self.objects[i].name, name)).collect();
            if matching.is_empty() {
                let all: Vec<&str> = self.objects.iter().map(|o| o.name.as_str()).collect();
                return Err(format!("portal '{name}': no mesh of that name (meshes: {})", all.join(", ")));
            }
            for i in matching {
                let tris = self.objects[i].tris.clone();
                if tris.clone().any(|t| self.light_of_triangle[t as usize] != u32::MAX) {
                    return Err(format!("portal '{name}': the mesh emits light"));
                }
                let t: Vec<&Triangle> = tris.clone().map(|t| &self.triangles[t as usize]).collect();
                portals.push(Portal::of(&t, inside).map_err(|e| format!("portal '{name}': {e}"))?);
                for t in tris {
                    self.triangles[t as usize].material = invisible;
                }
                self.objects[i].material = invisible;
            }
        }
        self.materials.push(material);
        self.any_alpha = true;
        let mut tag = Vec::new();
        for l in &mut self.lights {
            if let LightKind::Environment { portals: p, .. } = &mut l.kind {
                *p = portals.clone();
            }
        }
        for p in &portals {
            for v in [p.corner, p.u, p.v, p.outward] {
                tag.extend(v.to_array().map(f32::to_bits).map(u32::to_le_bytes).concat());
            }
        }
        self.relight(b"portals", &tag);
        Ok(())
    }

    /// Recompute the lights' powers and fold a change of the lighting (`what`,
    /// `identity`) into the content hash.
    fn relight(&mut self, what: &[u8], identity: &[u8]) {
        light::finish_lights(self);
        let mut h = blake3::Hasher::new();
        h.update(&self.content_hash);
        h.update(what);
        h.update(identity);
        self.content_hash = *h.finalize().as_bytes();
    }
}

#[cfg(test)]
mod tests;
