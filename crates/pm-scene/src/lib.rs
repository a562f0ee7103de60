//! The scene: triangles, materials, lights and camera loaded from glTF 2.0, and the
//! ray queries every stage needs (closest hit and shadow-ray occlusion on an obvhs
//! compressed wide BVH, Ylitie et al. 2017).
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

mod anim;
mod bvh4;
mod geometry;
mod gltf_load;
mod light;

pub use anim::Animation;
pub use geometry::{TriangleRay, facing, intersect_triangle, offset_ray_origin};
pub use gltf_load::{SceneError, load, load_with};
pub use light::{EmittedRay, Light, LightKind, LightSample, OUTLINE_TRIANGLES, Outline, Target, spot_falloff};

use glam::{Vec2, Vec3};
use pm_bsdf::{Bsdf, Pbr};
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
    fn swap_corners(&mut self) {
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

/// A texture as the file stores it: 8-bit RGBA texels, decoded at lookup.
#[derive(Clone, Debug)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major RGBA, 8 bits per channel (one- and two-channel images are expanded
    /// as glTF reads them: grey to RGB, the second channel to alpha).
    pub texels: Vec<[u8; 4]>,
    /// The RGB channels are sRGB-encoded colour (base colour, emissive); otherwise
    /// linear data (metallic-roughness, normals). Alpha is always linear.
    pub srgb: bool,
    /// How u and v outside [0, 1] wrap (the glTF sampler's wrapS and wrapT).
    pub wrap: [Wrap; 2],
}

/// Which texture a material parameter reads, with which coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into [`Scene::textures`].
    pub texture: u32,
    /// The TEXCOORD_n set it reads (0 or 1).
    pub uv_set: u8,
    /// KHR_texture_transform's uv' = offset + R(rotation) (scale * uv); identity
    /// without it.
    pub transform: glam::Affine2,
}

/// How a material's alpha (base colour alpha x texture alpha x COLOR_0 alpha) lets
/// light through (glTF 2.0 `alphaMode`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored.
    Opaque,
    /// Surface points with alpha below the cutoff are not there.
    Mask {
        /// `alphaCutoff` (0.5 by default).
        cutoff: f32,
    },
    /// The surface is there with probability alpha (stochastic transparency: each
    /// ray decides by a hash of itself and the point, so the average over rays is
    /// alpha blending).
    Blend,
}

/// How a texture coordinate outside [0, 1] maps back into the texture (glTF 2.0
/// sampler wrapS / wrapT, section 3.8.4.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// The texture tiles (glTF's default).
    #[default]
    Repeat,
    /// Texels beyond the edge repeat the edge texel.
    ClampToEdge,
    /// The texture tiles, every other copy mirrored.
    MirroredRepeat,
}

impl Wrap {
    /// Texel `i` of a row or column of `n` texels, wrapped into 0..n.
    fn texel(self, i: i64, n: i64) -> i64 {
        match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                let m = i.rem_euclid(2 * n);
                if m >= n { 2 * n - 1 - m } else { m }
            }
        }
    }
}

/// sRGB-encoded 8-bit value to linear, per code.
static SRGB_TO_LINEAR: std::sync::LazyLock<[f32; 256]> =
    std::sync::LazyLock::new(|| std::array::from_fn(|i| pm_color::srgb_decode(i as f32 / 255.0)));

impl Texture {
    /// A texture of linear-or-sRGB 8-bit RGBA texels with repeat wrapping.
    pub fn new(width: u32, height: u32, texels: Vec<[u8; 4]>, srgb: bool) -> Texture {
        Texture { width, height, texels, srgb, wrap: [Wrap::Repeat; 2] }
    }

    /// One texel as linear RGBA.
    #[inline]
    fn texel(&self, i: usize) -> glam::Vec4 {
        let [r, g, b, a] = self.texels[i];
        let a = a as f32 / 255.0;
        if self.srgb {
            let lut = &*SRGB_TO_LINEAR;
            glam::Vec4::new(lut[r as usize], lut[g as usize], lut[b as usize], a)
        } else {
            glam::Vec4::new(r as f32 / 255.0, g as f32 / 255.0, b as f32 / 255.0, a)
        }
    }

    /// Bilinear lookup of linear RGBA (sRGB texels decoded before filtering),
    /// wrapped as the texture's sampler says.
    pub fn sample(&self, uv: Vec2) -> glam::Vec4 {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        if !x.is_finite() || !y.is_finite() {
            return self.texel(0);
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: i64, j: i64| self.texel((self.wrap[1].texel(j, h) * w + self.wrap[0].texel(i, w)) as usize);
        let (i, j) = (x0 as i64, y0 as i64);
        (at(i, j) * (1.0 - fx) + at(i + 1, j) * fx) * (1.0 - fy)
            + (at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx) * fy
    }
}

/// A surface material: its scattering model and emission, and the textures that
/// vary them over the surface.
#[derive(Clone, Debug)]
pub struct Material {
    /// Name from the file (or "material #i").
    pub name: String,
    /// Scattering model of the factors alone: what every point has when no texture
    /// or vertex colour varies it.
    pub bsdf: Bsdf,
    /// The factors [`Material::bsdf`] was made from, which textures and vertex
    /// colours multiply at a shading point ([`Scene::bsdf`]).
    pub pbr: Pbr,
    /// baseColorFactor's alpha.
    pub base_alpha: f32,
    /// How alpha lets light through.
    pub alpha_mode: AlphaMode,
    /// Base colour texture (RGB multiplies the base colour, A the alpha).
    pub base_texture: Option<TextureRef>,
    /// metallicRoughness texture: B multiplies metallic, G roughness.
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Emissive texture, multiplied into `emission`.
    pub emissive_texture: Option<TextureRef>,
    /// KHR_materials_specular's specularTexture: A multiplies the specular weight.
    pub specular_texture: Option<TextureRef>,
    /// KHR_materials_specular's specularColorTexture: RGB (sRGB) multiplies the
    /// specular colour.
    pub specular_color_texture: Option<TextureRef>,
    /// Tangent-space normal texture (linear RGB = (n + 1) / 2), perturbing the
    /// shading normal (never the geometry).
    pub normal_texture: Option<TextureRef>,
    /// The normal texture's `scale`: multiplies the sampled normal's x and y.
    pub normal_scale: f32,
    /// Emitted radiance L_e [W sr^-1 m^-2 per channel] (emissiveFactor x
    /// KHR_materials_emissive_strength), times the emissive texture where there is one.
    pub emission: Rgb,
    /// Both faces scatter and emit (glTF `doubleSided`); otherwise only the front emits.
    pub double_sided: bool,
    /// Absorption coefficient sigma_a [m^-1 per channel] of the medium this closed
    /// surface bounds (KHR_materials_volume: -ln(attenuationColor) /
    /// attenuationDistance); zero for a clear medium or no volume.
    pub attenuation: Rgb,
}

impl Material {
    /// An untextured opaque material of a scattering model and emitted radiance
    /// [W sr^-1 m^-2 per channel] (scenes built in code).
    pub fn new(name: impl Into<String>, bsdf: Bsdf, emission: Rgb) -> Material {
        Material {
            name: name.into(),
            bsdf,
            pbr: Pbr::dielectric(Rgb::ONE),
            base_alpha: 1.0,
            alpha_mode: AlphaMode::Opaque,
            base_texture: None,
            metallic_roughness_texture: None,
            emissive_texture: None,
            specular_texture: None,
            specular_color_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            emission,
            double_sided: false,
            attenuation: Rgb::ZERO,
        }
    }

    /// True when points of this material can be see-through (alpha mask or blend).
    pub fn has_alpha(&self) -> bool {
        self.alpha_mode != AlphaMode::Opaque
    }

    /// True when the BSDF varies over the surface (textures, partial transmission;
    /// vertex colours are a property of the mesh, checked at the hit).
    fn varies(&self) -> bool {
        self.base_texture.is_some()
            || self.metallic_roughness_texture.is_some()
            || self.specular_texture.is_some()
            || self.specular_color_texture.is_some()
            || self.partly_transmissive()
    }

    /// KHR_materials_transmission with a factor strictly between 0 and 1: a mix of
    /// glass and the base BSDF.
    pub fn partly_transmissive(&self) -> bool {
        self.pbr.transmission > 0.0 && self.pbr.transmission < 1.0
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

/// A pinhole camera (glTF perspective camera).
#[derive(Clone, Debug)]
pub struct Camera {
    /// Eye position \[m\].
    pub position: Vec3,
    /// Unit viewing direction (the camera's -Z axis).
    pub forward: Vec3,
    /// Unit up vector (the camera's +Y axis).
    pub up: Vec3,
    /// Unit right vector (the camera's +X axis).
    pub right: Vec3,
    /// Vertical field of view \[rad\].
    pub yfov: f32,
    /// Width / height from the file, if it gave one.
    pub aspect: Option<f32>,
}

impl Camera {
    /// Unit direction of the ray through film position (sx, sy) in \[0,1\]^2, with
    /// (0,0) the top-left corner (row 0 is the top row) and `aspect` = width/height.
    pub fn ray_direction(&self, sx: f32, sy: f32, aspect: f32) -> Vec3 {
        self.rays(aspect).direction(sx, sy)
    }

    /// Eye-ray directions for an image of `aspect`, with the field of view's tangent
    /// computed once (for loops over many pixels).
    pub fn rays(&self, aspect: f32) -> CameraRays {
        CameraRays { forward: self.forward, right: self.right, up: self.up, tan_y: (0.5 * self.yfov).tan(), aspect }
    }

    /// Inverse of [`Camera::ray_direction`]: film position of a world point, if in front.
    pub fn project(&self, p: Vec3, aspect: f32) -> Option<Vec2> {
        let v = p - self.position;
        let z = v.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let tan_y = (0.5 * self.yfov).tan();
        let x = v.dot(self.right) / (z * tan_y * aspect);
        let y = v.dot(self.up) / (z * tan_y);
        Some(Vec2::new(0.5 * (x + 1.0), 0.5 * (1.0 - y)))
    }
}

/// Eye-ray directions of a [`Camera`] for one image (see [`Camera::rays`]).
#[derive(Clone, Copy, Debug)]
pub struct CameraRays {
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_y: f32,
    aspect: f32,
}

impl CameraRays {
    /// Unit direction through film position (sx, sy) in [0, 1]^2, y down: the same
    /// value as [`Camera::ray_direction`].
    #[inline]
    pub fn direction(&self, sx: f32, sy: f32) -> Vec3 {
        let x = (2.0 * sx - 1.0) * self.tan_y * self.aspect;
        let y = (1.0 - 2.0 * sy) * self.tan_y;
        (self.forward + self.right * x + self.up * y).normalize()
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

/// A triangle's bounding box in the BVH's normalised coordinates, padded.
struct PaddedBox(obvhs::aabb::Aabb);

impl obvhs::Boundable for PaddedBox {
    fn aabb(&self) -> obvhs::aabb::Aabb {
        self.0
    }
}

/// The triangles in the BVH's slot order, four slots to a [`geometry::Tri4`] (a
/// leaf starts at a multiple of four), and the triangle id of each slot.
#[derive(Clone, Debug, Default)]
struct BvhTris {
    tri4: Vec<geometry::Tri4>,
    id: Vec<u32>,
}

impl BvhTris {
    /// The groups of four that slots `first..first + count` span, with the number
    /// of the range's slots in each, and the first slot of each.
    #[inline]
    fn groups(&self, first: u32, count: u32) -> impl Iterator<Item = (&geometry::Tri4, usize, u32)> {
        let end = first + count;
        (first / 4..end.div_ceil(4)).map(move |g| (&self.tri4[g as usize], (end - 4 * g).min(4) as usize, 4 * g))
    }
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
    /// Light sources (emissive meshes and punctual lights).
    pub lights: Vec<Light>,
    /// Mesh primitive instances, in file order, covering every triangle.
    pub objects: Vec<Object>,
    /// For each triangle, the index of the area light it belongs to (u32::MAX: none).
    pub light_of_triangle: Vec<u32>,
    /// The first camera found in the scene, if any.
    pub camera: Option<Camera>,
    /// World position \[m\] of this scene's coordinate origin: positions are stored
    /// relative to the first perspective camera's rest position snapped to a 1,024 m
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
    /// The glTF animations that move lights and the camera ([`Scene::set_time`]).
    pub animation: Animation,
    /// What loading took \[s\]: reading and decoding the file (geometry, textures,
    /// tangents) and building the BVH (zero for scenes built in code).
    pub load_seconds: f64,
    /// Building the BVH \[s\] (part of `load_seconds` for loaded scenes).
    pub bvh_seconds: f64,
    /// Some material has an alpha mode: ray queries test alpha at candidate hits.
    any_alpha: bool,
    bvh: bvh4::Bvh4,
    /// The triangles in the BVH's slot order.
    bvh_tris: BvhTris,
    /// 1 / the diagonal of the BVH's bounds [m^-1] (the scale of ray-origin offsets).
    bvh_inv_scale: f32,
}

/// A uniform number in [0, 1) from triangle `tri`, barycentrics `b` and `salt`: the
/// per-point random choices (blended alpha, salt 0; partial transmission, salt 1)
/// that every ray and stage finding the point makes alike.
fn point_hash(tri: u32, b: [f32; 3], salt: u64) -> f32 {
    let key = ((tri as u64) << 32 | b[1].to_bits() as u64) ^ pm_sampling::mix64(b[2].to_bits() as u64 ^ salt << 40);
    (pm_sampling::mix64(key) >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// The BVH over `triangles` (whose bounds are `bounds`), and the triangles in its
/// slot order.
fn build_bvh(triangles: &[Triangle], bounds: &Bounds) -> (bvh4::Bvh4, BvhTris) {
    if triangles.is_empty() {
        return (bvh4::Bvh4::default(), BvhTris::default());
    }
    // obvhs builds the tree (PLOC, reinsertion) over boxes in the normalised
    // coordinates (p - centre) / diagonal, where its build behaves the same at every
    // scale; the four-wide nodes then get boxes recomputed in world coordinates.
    // Each triangle's box is padded by 2e-7 of the scene's size, in both: with exact
    // boxes, obvhs's slab tests missed rays that pass exactly through an edge lying
    // on a node boundary (30 of 13,000 rays aimed at a sphere's vertices and edge
    // midpoints slipped through; tests/tests/hard_cases.rs).
    let diag = bounds.diagonal().max(f32::MIN_POSITIVE);
    let (c, inv) = (bounds.center(), 1.0 / diag);
    let norm = |p: Vec3| -> glam::Vec3A { ((p - c) * inv).into() };
    let boxes: Vec<PaddedBox> = triangles
        .iter()
        .map(|t| {
            let (a, b, c) = (norm(t.p[0]), norm(t.p[1]), norm(t.p[2]));
            let pad = glam::Vec3A::splat(2e-7);
            PaddedBox(obvhs::aabb::Aabb::new(a.min(b).min(c) - pad, a.max(b).max(c) + pad))
        })
        .collect();
    // Our own four-wide traversal, not obvhs's compressed wide BVH (CWBVH): its 8-bit
    // quantised child boxes lost rays that start a few hundredths of a millimetre
    // from a surface and hit it at once (13 of 200,000 gather rays from the walls of
    // cornell_spheres, born near the floor, went through it; tests.rs).
    let params = obvhs::BvhBuildParams { max_prims_per_leaf: 4, ..obvhs::BvhBuildParams::medium_build() };
    let bvh2 = obvhs::bvh2::builder::build_bvh2(&boxes, params, &mut std::time::Duration::default());
    let bvh = bvh4::Bvh4::new(&bvh2, triangles, 2e-7 * diag);
    let id = bvh.slots().to_vec();
    let tri4 = id
        .chunks(4)
        .map(|c| {
            let mut p = [[Vec3::ZERO; 3]; 4];
            for (q, &i) in p.iter_mut().zip(c) {
                *q = triangles[i as usize].p;
            }
            geometry::Tri4::new(&p[..c.len()])
        })
        .collect();
    (bvh, BvhTris { tri4, id })
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
    /// Build the acceleration structure over `triangles` (degenerate ones must
    /// already be removed).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn build(
        triangles: Vec<Triangle>,
        materials: Vec<Material>,
        textures: Vec<Texture>,
        lights: Vec<Light>,
        objects: Vec<Object>,
        camera: Option<Camera>,
        content_hash: [u8; 32],
        warnings: Vec<String>,
    ) -> Scene {
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
            animation: Animation::default(),
            triangles,
            materials,
            textures,
            lights,
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
        scene
    }

    /// [`offset_ray_origin`] at this scene's scale: where a ray leaving surface point
    /// `p` (geometric normal `ng`) toward `w` starts.
    #[inline]
    pub fn offset_origin(&self, p: Vec3, ng: Vec3, w: Vec3) -> Vec3 {
        offset_ray_origin(p, ng, w, 1.0 / self.bvh_inv_scale)
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
        Scene::build(triangles, materials, Vec::new(), lights, objects, camera, [0; 32], Vec::new())
    }

    /// True when the animation moves meshes (their triangles change with the time).
    pub fn has_moving_meshes(&self) -> bool {
        !self.animation.meshes.is_empty()
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
                LightKind::Area { .. } => {}
            }
        }
        if !anim.meshes.is_empty() {
            for m in &anim.meshes {
                let world = anim.world(m.node, t);
                let normal_m = glam::Mat3::from_mat4(world).inverse().transpose();
                let flip = glam::Mat3::from_mat4(world).determinant() < 0.0;
                let range = self.objects[m.object].tris.clone();
                for (local, out) in m.local.iter().zip(&mut self.triangles[range.start as usize..range.end as usize]) {
                    let mut p = local.p.map(|q| world.transform_point3(q));
                    let mut n = local.n.map(|n| n.map(|v| (normal_m * v).normalize_or_zero()));
                    let mut attrs = local.clone();
                    let linear = glam::Mat3::from_mat4(world);
                    attrs.tangent = local.tangent.map(|t| {
                        t.map(|t| {
                            let w = if flip { -t.w } else { t.w };
                            (linear * t.truncate()).normalize_or_zero().extend(w)
                        })
                    });
                    if flip {
                        p.swap(1, 2);
                        if let Some(n) = n.as_mut() {
                            n.swap(1, 2);
                        }
                        attrs.swap_corners();
                    }
                    // A transform that flattens a triangle keeps its last good pose.
                    if let Some(moved) = Triangle::new(p, local.material) {
                        *out = Triangle { n, p: moved.p, ng: moved.ng, area: moved.area, ..attrs };
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
    }

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

    /// Closest intersection along the ray from `o` in unit direction `d` within (0, t_max).
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
        let mut best_b = [0.0; 3];
        let tri_ray = TriangleRay::new(o, d);
        let tris = &self.bvh_tris;
        let (slot, t) = self.bvh.closest(o, d, t_max, |first, count, t_max| {
            let mut best = None;
            let mut t_best = t_max;
            for (group, lanes, slot0) in tris.groups(first, count) {
                tri_ray.hit4(group, lanes, t_best, |lane, t, b| {
                    let s = slot0 + lane as u32;
                    if !self.any_alpha || self.present(tris.id[s as usize], b) {
                        (t_best, best_b, best) = (t, b, Some((s, t)));
                    }
                    t_best
                });
            }
            best
        })?;
        Some(self.make_hit(tris.id[slot as usize], t, best_b))
    }

    /// True when something blocks the segment from `o` along unit `d` before `t_max`.
    pub fn occluded(&self, o: Vec3, d: Vec3, t_max: f32) -> bool {
        let tri_ray = TriangleRay::new(o, d);
        let tris = &self.bvh_tris;
        self.bvh.any(o, d, t_max, |first, count, t_max| {
            let mut blocked = false;
            for (group, lanes, slot0) in tris.groups(first, count) {
                tri_ray.hit4(group, lanes, t_max, |lane, _, b| {
                    blocked |= !self.any_alpha || self.present(tris.id[slot0 as usize + lane], b);
                    if blocked { 0.0 } else { t_max }
                });
                if blocked {
                    return true;
                }
            }
            false
        })
    }

    /// The hit record of triangle `tri` at barycentrics `b`, t along the ray. The
    /// shading normal is the interpolated vertex normal, perturbed by the material's
    /// normal texture in the tangent frame (glTF 2.0 section 3.9.3: bitangent = w
    /// cross(n, t)), and turned to the geometric normal's side.
    pub fn make_hit(&self, tri: u32, t: f32, b: [f32; 3]) -> Hit {
        let tr = &self.triangles[tri as usize];
        let (p, ns) = tr.point_normal(b);
        let ng = tr.ng;
        let lerp = |uv: &[Vec2; 3]| uv[0] * b[0] + uv[1] * b[1] + uv[2] * b[2];
        let uv = tr.uv.as_ref().map_or(Vec2::ZERO, lerp);
        let uv1 = tr.uv1.as_ref().map_or(Vec2::ZERO, lerp);
        let color = tr.color.map_or(glam::Vec4::ONE, |c| c[0] * b[0] + c[1] * b[1] + c[2] * b[2]);
        let mut hit = Hit { t, tri, b, p, ng, ns, uv, uv1, color };
        let m = &self.materials[tr.material as usize];
        if let (Some(nt), Some(tg)) = (&m.normal_texture, &tr.tangent) {
            let tangent = (tg[0] * b[0] + tg[1] * b[1] + tg[2] * b[2]).truncate();
            let tangent = (tangent - ns * ns.dot(tangent)).normalize_or_zero();
            if tangent != Vec3::ZERO {
                let bitangent = ns.cross(tangent) * if tg[0].w < 0.0 { -1.0 } else { 1.0 };
                let c = self.lookup(nt, &hit);
                let v = (c.truncate() * 2.0 - Vec3::ONE) * Vec3::new(m.normal_scale, m.normal_scale, 1.0);
                hit.ns = (tangent * v.x + bitangent * v.y + ns * v.z).normalize_or(ns);
            }
        }
        hit.ns = facing(hit.ns, ng);
        hit
    }

    /// Position \[m\], unit shading normal (on the geometric normal's side) and
    /// reflectance of the point at barycentrics `b` of triangle `tri`, when its
    /// surface is plainly Lambertian: a material of constant Lambertian BSDF, no
    /// vertex colours, no normal map. Equal to [`Scene::make_hit`]'s `p` and `ns`
    /// and [`Scene::bsdf`]'s `rho` there, without building either: a G-buffer of
    /// millions of pixels needs no more (a hit record and BSDF per pixel were 11%
    /// of an image-space frame).
    #[inline]
    pub fn plain_lambert(&self, tri: u32, b: [f32; 3]) -> Option<(Vec3, Vec3, Rgb)> {
        let tr = &self.triangles[tri as usize];
        let Some(Bsdf::Lambert { rho }) = self.uniform_bsdf(tri) else { return None };
        if self.materials[tr.material as usize].normal_texture.is_some() && tr.tangent.is_some() {
            return None;
        }
        let (p, ns) = tr.point_normal(b);
        Some((p, facing(ns, tr.ng), rho))
    }

    /// The BSDF at every point of triangle `tri` when it is the same everywhere (a
    /// material without textures or partial transmission, and no vertex colours):
    /// what [`Scene::bsdf`] gives at any hit on it, without a hit record.
    #[inline]
    pub fn uniform_bsdf(&self, tri: u32) -> Option<Bsdf> {
        let tr = &self.triangles[tri as usize];
        let m = &self.materials[tr.material as usize];
        (!m.varies() && tr.color.is_none()).then_some(m.bsdf)
    }

    /// Alpha at barycentrics `b` of triangle `tri`: baseColorFactor's alpha times the
    /// base texture's alpha times COLOR_0's alpha.
    pub fn alpha(&self, tri: u32, b: [f32; 3]) -> f32 {
        let tr = &self.triangles[tri as usize];
        let m = &self.materials[tr.material as usize];
        let mut a = m.base_alpha;
        if let Some(t) = &m.base_texture {
            a *= self.sample_at(t, tr, b).w;
        }
        if let Some(c) = tr.color {
            a *= c[0].w * b[0] + c[1].w * b[1] + c[2].w * b[2];
        }
        a
    }

    /// True when the surface is there at barycentrics `b` of triangle `tri`: always
    /// for opaque materials, where alpha reaches the cutoff for masks, and for blended
    /// materials with probability alpha, decided by a hash of the triangle and the
    /// point (the same decision for every ray and stage that finds this point, and
    /// independent between points; averaged over a pixel or a light path it is alpha
    /// blending). Ray queries, the rasteriser and the photon tracer all see this.
    pub fn present(&self, tri: u32, b: [f32; 3]) -> bool {
        let m = &self.materials[self.triangles[tri as usize].material as usize];
        match m.alpha_mode {
            AlphaMode::Opaque => true,
            AlphaMode::Mask { cutoff } => self.alpha(tri, b) >= cutoff,
            AlphaMode::Blend => point_hash(tri, b, 0) < self.alpha(tri, b),
        }
    }

    /// The probability [0, 1] that a photon arriving here is stored: that a ray stops
    /// here at all (alpha, for a blended material) times that the point's lobe choice
    /// is the non-specular base (1 - transmission, for partial transmission; see
    /// [`Scene::bsdf`]). A photon stored here carries its power divided by it, so the
    /// stored photons estimate all the light that arrives; the surface's own shares
    /// come from the eye rays that make the same choices.
    pub fn store_probability(&self, hit: &Hit) -> f32 {
        let m = self.material(hit);
        let alpha = match m.alpha_mode {
            AlphaMode::Blend => self.alpha(hit.tri, hit.b),
            _ => 1.0,
        };
        let base = if m.partly_transmissive() { 1.0 - m.pbr.transmission } else { 1.0 };
        (alpha * base).max(1.0 / 256.0)
    }

    /// True when some material can be see-through (the rasteriser then tests
    /// [`Scene::present`] per fragment).
    pub fn has_alpha(&self) -> bool {
        self.any_alpha
    }

    /// True when some surface makes a random choice per point (blended alpha,
    /// partial transmission): images then need all their samples in every pixel.
    pub fn has_stochastic_surfaces(&self) -> bool {
        self.materials.iter().any(|m| m.alpha_mode == AlphaMode::Blend || m.partly_transmissive())
    }

    /// The index of the object (in `objects`) that triangle `tri` belongs to.
    pub fn object_of(&self, tri: u32) -> Option<u32> {
        let i = self.objects.partition_point(|o| o.tris.end <= tri);
        self.objects.get(i).filter(|o| o.tris.contains(&tri)).map(|_| i as u32)
    }

    /// The material of a hit's triangle.
    pub fn material(&self, hit: &Hit) -> &Material {
        &self.materials[self.triangles[hit.tri as usize].material as usize]
    }

    /// Linear RGBA of texture `t` at a hit.
    #[inline]
    pub fn lookup(&self, t: &TextureRef, hit: &Hit) -> glam::Vec4 {
        // The hit's interpolated coordinates: the same value as `sample_at`.
        self.texel(t, if t.uv_set == 1 { hit.uv1 } else { hit.uv })
    }

    /// Linear RGBA of texture `t` at barycentrics `b` of triangle `tr` (for queries
    /// that have no [`Hit`]: alpha tests during traversal, light sampling).
    pub fn sample_at(&self, t: &TextureRef, tr: &Triangle, b: [f32; 3]) -> glam::Vec4 {
        self.texel(t, tr.uvs(t.uv_set).map_or(Vec2::ZERO, |uv| uv[0] * b[0] + uv[1] * b[1] + uv[2] * b[2]))
    }

    /// Linear RGBA of texture `t` at the mesh's coordinates `uv`, through its transform.
    #[inline]
    fn texel(&self, t: &TextureRef, uv: Vec2) -> glam::Vec4 {
        self.textures[t.texture as usize].sample(t.transform.transform_point2(uv))
    }

    /// The BSDF at a hit: the material's factors times its base-colour and
    /// metallic-roughness textures and the vertex colour, through the same selection
    /// ([`Bsdf::from_pbr`]) as the factors alone. Partial transmission (factor t) is
    /// the mix t glass + (1 - t) base, sampled by choosing one of the two at each
    /// point with those probabilities (a hash of the triangle and the point, like
    /// blended alpha): every path, eye or light, sees one pure lobe, and the mix is
    /// the expectation; photons are stored with [`Scene::store_probability`].
    pub fn bsdf(&self, hit: &Hit) -> Bsdf {
        let m = self.material(hit);
        if !m.varies() && hit.color == glam::Vec4::ONE {
            return m.bsdf;
        }
        let mut pbr = m.pbr;
        if m.partly_transmissive() && point_hash(hit.tri, hit.b, 1) >= pbr.transmission {
            pbr.transmission = 0.0;
        }
        if let Some(t) = &m.base_texture {
            let c = self.lookup(t, hit);
            pbr.base *= Rgb::new(c.x, c.y, c.z);
        }
        pbr.base *= Rgb::new(hit.color.x, hit.color.y, hit.color.z);
        if let Some(t) = &m.metallic_roughness_texture {
            let c = self.lookup(t, hit);
            pbr.roughness *= c.y;
            pbr.metallic *= c.z;
        }
        if let Some(t) = &m.specular_texture {
            pbr.specular *= self.lookup(t, hit).w;
        }
        if let Some(t) = &m.specular_color_texture {
            let c = self.lookup(t, hit);
            pbr.specular_color *= Rgb::new(c.x, c.y, c.z);
        }
        Bsdf::from_pbr(&pbr)
    }

    /// Radiance emitted at a hit toward `wo` [W sr^-1 m^-2]: the front face emits, and
    /// the back too when the material is double-sided.
    pub fn emitted(&self, hit: &Hit, wo: Vec3) -> Rgb {
        let m = self.material(hit);
        if m.emission == Rgb::ZERO || (!m.double_sided && wo.dot(hit.ng) <= 0.0) {
            return Rgb::ZERO;
        }
        self.emission_at(hit.tri, hit.b)
    }

    /// Beer-Lambert transmittance exp(-sigma_a t) of the segment a ray along unit `d`
    /// travelled to reach `hit` (per channel, in [0, 1]): below one when the ray
    /// arrives at the back of a surface whose material bounds an absorbing medium
    /// (KHR_materials_volume), that is when the segment ran inside it; one otherwise.
    /// Every integrator multiplies its path throughput (or photon power) by this
    /// after each intersection. A surface inside the medium that is not its boundary
    /// does not see the attenuation (media are not nested).
    #[inline]
    pub fn transmittance(&self, hit: &Hit, d: Vec3) -> Rgb {
        let sigma = self.material(hit).attenuation;
        if sigma == Rgb::ZERO || d.dot(hit.ng) <= 0.0 {
            return Rgb::ONE;
        }
        (-sigma * hit.t).exp()
    }

    /// Emitted radiance [W sr^-1 m^-2 per channel] at barycentrics `b` of triangle
    /// `tri`, on an emitting side: the material's emission times its emissive texture.
    pub fn emission_at(&self, tri: u32, b: [f32; 3]) -> Rgb {
        let tr = &self.triangles[tri as usize];
        let m = &self.materials[tr.material as usize];
        match &m.emissive_texture {
            Some(t) => m.emission * self.sample_at(t, tr, b).truncate(),
            None => m.emission,
        }
    }

    /// Mean emitted radiance over triangle `tri` [W sr^-1 m^-2 per channel]: for an
    /// emissive texture, the mean over the centres of n^2 equal sub-triangles, n
    /// twice the square root of the texels the triangle covers (4 to 64), so a light's power and
    /// its triangles' selection follow the texture.
    pub fn mean_emission(&self, tri: u32) -> Rgb {
        let tr = &self.triangles[tri as usize];
        let m = &self.materials[tr.material as usize];
        let Some(t) = &m.emissive_texture else { return m.emission };
        let tex = &self.textures[t.texture as usize];
        let uv = tr.uvs(t.uv_set).copied().unwrap_or([Vec2::ZERO; 3]).map(|q| t.transform.transform_point2(q));
        let texels = 0.5 * (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).abs() * (tex.width * tex.height) as f32;
        let n = ((2.0 * texels.sqrt()).ceil() as u32).clamp(4, 64);
        let mut sum = glam::DVec3::ZERO;
        for i in 0..n {
            for j in 0..n - i {
                // Centres of the upright and (where there is one) inverted sub-triangles.
                let mut add = |a: f32, b: f32| {
                    let (u, v) = (a / n as f32, b / n as f32);
                    sum += self.emission_at(tri, [1.0 - u - v, u, v]).as_dvec3();
                };
                add(i as f32 + 1.0 / 3.0, j as f32 + 1.0 / 3.0);
                if i + j + 1 < n {
                    add(i as f32 + 2.0 / 3.0, j as f32 + 2.0 / 3.0);
                }
            }
        }
        (sum / (n * n) as f64).as_vec3()
    }

    /// Sum of the power of all lights [W per channel].
    pub fn total_power(&self) -> Rgb {
        self.lights.iter().map(|l| l.power).sum()
    }
}

#[cfg(test)]
mod tests;
