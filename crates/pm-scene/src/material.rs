//! Surfaces: materials and textures, and what a hit's surface is (its BSDF with
//! textures applied, its emission, alpha and transmittance).

use crate::geometry::facing;
use crate::{Hit, Scene, Triangle};
use glam::{Vec2, Vec3};
use pm_bsdf::{Bsdf, Pbr};
use pm_color::Rgb;

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
    /// How a lookup between texel centres reads them (the sampler's magFilter).
    pub filter: Filter,
}

/// How a texture lookup reads the texels round it (glTF 2.0 sampler magFilter,
/// section 5.26; there is no mip-mapping, so minFilter's choice between levels
/// does not arise).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Filter {
    /// Bilinear between the four nearest texel centres (glTF's LINEAR, and what
    /// a sampler without a magFilter gets).
    #[default]
    Linear,
    /// The texel the point falls in (NEAREST; Blender's "Closest"
    /// interpolation): pixel art and coarse tiles keep their hard edges and
    /// colours.
    Nearest,
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
        Texture { width, height, texels, srgb, wrap: [Wrap::Repeat; 2], filter: Filter::Linear }
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

    /// Lookup of linear RGBA (sRGB texels decoded before filtering), bilinear or
    /// nearest and wrapped as the texture's sampler says.
    pub fn sample(&self, uv: Vec2) -> glam::Vec4 {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        if !x.is_finite() || !y.is_finite() {
            return self.texel(0);
        }
        let at = |i: i64, j: i64| self.texel((self.wrap[1].texel(j, h) * w + self.wrap[0].texel(i, w)) as usize);
        if self.filter == Filter::Nearest {
            // The texel whose square holds the point: x + 0.5 lies in [i, i + 1).
            // (Saturating: a coordinate past i64's range wraps like any other.)
            return at((x + 0.5).floor() as i64, (y + 0.5).floor() as i64);
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (i, j) = (x0 as i64, y0 as i64);
        (at(i, j) * (1.0 - fx) + at(i + 1, j) * fx) * (1.0 - fy)
            + (at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx) * fy
    }
}

/// The textures of KHR_materials_clearcoat, _sheen, _anisotropy and
/// _iridescence, the anisotropy's rotation and the film's least thickness: each
/// texture multiplies its factor in [`Material::pbr`] (the film's thickness
/// texture blends between the least and the factor's greatest).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LayerTextures {
    /// clearcoatTexture: R multiplies the coat's weight.
    pub coat: Option<TextureRef>,
    /// clearcoatRoughnessTexture: G multiplies the coat's roughness.
    pub coat_roughness: Option<TextureRef>,
    /// clearcoatNormalTexture: the coat's own tangent-space normal, about the
    /// mesh's normal (not the base's normal texture).
    pub coat_normal: Option<TextureRef>,
    /// The coat normal texture's `scale`.
    pub coat_normal_scale: f32,
    /// sheenColorTexture: RGB (sRGB) multiplies the sheen colour.
    pub sheen_color: Option<TextureRef>,
    /// sheenRoughnessTexture: A multiplies the sheen roughness.
    pub sheen_roughness: Option<TextureRef>,
    /// anisotropyTexture: RG the direction in tangent space ((d + 1) / 2), B
    /// multiplies the strength.
    pub anisotropy: Option<TextureRef>,
    /// anisotropyRotation [rad], counter-clockwise from the tangent.
    pub anisotropy_rotation: f32,
    /// iridescenceTexture: R multiplies the film's weight.
    pub iridescence: Option<TextureRef>,
    /// iridescenceThicknessTexture: G blends the film's thickness from
    /// [`Self::film_thickness_min`] to iridescenceThicknessMaximum.
    pub iridescence_thickness: Option<TextureRef>,
    /// iridescenceThicknessMinimum [nm].
    pub film_thickness_min: f32,
}

impl LayerTextures {
    /// True when any texture is present.
    pub fn any(&self) -> bool {
        self.coat.is_some()
            || self.coat_roughness.is_some()
            || self.coat_normal.is_some()
            || self.sheen_color.is_some()
            || self.sheen_roughness.is_some()
            || self.anisotropy.is_some()
            || self.iridescence.is_some()
            || self.iridescence_thickness.is_some()
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
    /// The textures of the clear coat, sheen and anisotropy, and the anisotropy's
    /// rotation.
    pub layers: LayerTextures,
    /// Emitted radiance L_e [W sr^-1 m^-2 per channel] (emissiveFactor x
    /// KHR_materials_emissive_strength), times the emissive texture where there is one.
    pub emission: Rgb,
    /// Both faces scatter and emit (glTF `doubleSided`); otherwise only the front emits.
    pub double_sided: bool,
    /// The medium this closed surface bounds (its inside: KHR_materials_volume and
    /// KHR_materials_volume_scatter, or pipeline.toml's `[media.NAME]`), by index
    /// into [`Scene::media`]; `None` for a surface with the same medium on both
    /// sides (thin-walled, opaque).
    pub interior: Option<crate::MediumId>,
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
            layers: LayerTextures::default(),
            emission,
            double_sided: false,
            interior: None,
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
            || self.pbr.anisotropy > 0.0
            || self.layers.any()
    }

    /// True when the material has textures of its coat or sheen, or an
    /// anisotropy, whose direction follows the surface's tangents: its points
    /// need a tangent frame ([`crate::Triangle::tangent`]).
    pub fn needs_tangents(&self) -> bool {
        self.pbr.anisotropy > 0.0 || self.layers.coat_normal.is_some()
    }

    /// KHR_materials_transmission with a factor strictly between 0 and 1: a mix of
    /// glass and the base BSDF.
    pub fn partly_transmissive(&self) -> bool {
        self.pbr.transmission > 0.0 && self.pbr.transmission < 1.0
    }
}

/// A uniform number in [0, 1) from triangle `tri`, barycentrics `b` and `salt`: the
/// per-point random choices (blended alpha, salt 0; partial transmission, salt 1)
/// that every ray and stage finding the point makes alike.
fn point_hash(tri: u32, b: [f32; 3], salt: u64) -> f32 {
    let key = ((tri as u64) << 32 | b[1].to_bits() as u64) ^ pm_sampling::mix64(b[2].to_bits() as u64 ^ salt << 40);
    (pm_sampling::mix64(key) >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

impl Scene {
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
        if self.materials[tr.material as usize].normal_texture.is_some() && tr.tangent().is_some() {
            return None;
        }
        let (p, ns) = tr.point_normal(crate::accel::off_the_boundary(b));
        Some((p, facing(ns, tr.ng()), rho))
    }

    /// The BSDF at every point of triangle `tri` when it is the same everywhere (a
    /// material without textures or partial transmission, and no vertex colours):
    /// what [`Scene::bsdf`] gives at any hit on it, without a hit record.
    #[inline]
    pub fn uniform_bsdf(&self, tri: u32) -> Option<Bsdf> {
        let tr = &self.triangles[tri as usize];
        let m = &self.materials[tr.material as usize];
        (!m.varies() && tr.color().is_none()).then_some(m.bsdf)
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
        if let Some(c) = tr.color() {
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
        if pbr.is_layered() {
            self.layers_at(m, hit, &mut pbr);
        }
        Bsdf::from_pbr(&pbr)
    }

    /// The clear coat's, sheen's, anisotropy's and film's textures at a hit, and the two
    /// directions they set in world space: the anisotropy direction
    /// (KHR_materials_anisotropy: the texture's direction, or the tangent, rotated
    /// by anisotropyRotation in the tangent plane of the shading normal) and the
    /// coat's normal (its normal texture about the mesh's interpolated normal).
    fn layers_at(&self, m: &Material, hit: &Hit, pbr: &mut Pbr) {
        let lt = &m.layers;
        if let Some(t) = &lt.coat {
            pbr.coat *= self.lookup(t, hit).x;
        }
        if let Some(t) = &lt.coat_roughness {
            pbr.coat_roughness *= self.lookup(t, hit).y;
        }
        if let Some(t) = &lt.sheen_color {
            let c = self.lookup(t, hit);
            pbr.sheen *= Rgb::new(c.x, c.y, c.z);
        }
        if let Some(t) = &lt.sheen_roughness {
            pbr.sheen_roughness *= self.lookup(t, hit).w;
        }
        if let Some(t) = &lt.iridescence {
            pbr.iridescence *= self.lookup(t, hit).x;
        }
        if let Some(t) = &lt.iridescence_thickness {
            let g = self.lookup(t, hit).y;
            pbr.iridescence_thickness = lt.film_thickness_min + (pbr.iridescence_thickness - lt.film_thickness_min) * g;
        }
        let tr = &self.triangles[hit.tri as usize];
        if pbr.anisotropy > 0.0
            && let Some((t, b)) = self.tangent_frame(tr, hit.b, hit.ns)
        {
            let mut d = Vec2::X;
            if let Some(tex) = &lt.anisotropy {
                let c = self.lookup(tex, hit);
                d = (Vec2::new(c.x, c.y) * 2.0 - Vec2::ONE).normalize_or(Vec2::X);
                pbr.anisotropy *= c.z;
            }
            let d = Vec2::from_angle(lt.anisotropy_rotation).rotate(d);
            pbr.anisotropy_dir = t * d.x + b * d.y;
        }
        if let Some(tex) = &lt.coat_normal {
            let (_, nv) = tr.point_normal(hit.b);
            let nv = facing(nv, hit.ng);
            if let Some((t, b)) = self.tangent_frame(tr, hit.b, nv) {
                let s = lt.coat_normal_scale;
                let v = (self.lookup(tex, hit).truncate() * 2.0 - Vec3::ONE) * Vec3::new(s, s, 1.0);
                pbr.coat_normal = facing((t * v.x + b * v.y + nv * v.z).normalize_or(nv), hit.ng);
            }
        }
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
        // Sub-triangles a side: two a texel for a bilinear texture (smooth
        // between texel centres); eight for a nearest one, whose steps at texel
        // edges the sub-triangles' centres must resolve (with two, a 4 x 4
        // texture's power on a quad was 6.5% off in red).
        let (per_texel, most) = if tex.filter == crate::Filter::Nearest { (8.0, 128) } else { (2.0, 64) };
        let n = ((per_texel * texels.sqrt()).ceil() as u32).clamp(4, most);
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
}
