//! glTF 2.0 (.gltf with embedded or external buffers, and .glb) to [`Scene`].
//!
//! Every input check happens here, once; the rest of the workspace trusts a `Scene`.

use crate::LayerTextures;
use crate::anim::{AnimatedMesh, Animation, Channel, Interp, NodeRest, Path as AnimPath};
use crate::light::Light;
use crate::{
    AlphaMode, Camera, Filter, LUMINOUS_EFFICACY, LightKind, LightUnits, Material, Object, Scene, Texture, TextureRef,
    Triangle, Wrap,
};
use glam::{DMat4, DVec3, Mat3, Mat4, Quat, Vec2, Vec3, Vec4};
use pm_bsdf::{Bsdf, FILM_IOR, Pbr};
use pm_color::Rgb;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Why a scene file could not be loaded. The message names the file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read: {error}")]
    Io {
        /// The scene file.
        path: PathBuf,
        /// The OS error (in the message, not a second link of the error's
        /// chain, which would say it twice).
        error: std::io::Error,
    },
    /// The file needs a glTF extension this renderer does not read
    /// (`extensionsRequired`).
    #[error("{path}: needs glTF extension {extension}, which this renderer does not read: {needed}")]
    Unsupported {
        /// The scene file.
        path: PathBuf,
        /// The extension (and how many more the file needs, if any).
        extension: String,
        /// What it holds and how to get a file without it.
        needed: String,
    },
    /// The glTF crate rejected the document or its buffers.
    #[error("{path}: not a valid glTF 2.0 file: {message}")]
    Gltf {
        /// The scene file.
        path: PathBuf,
        /// What the parser said.
        message: String,
    },
    /// The document parsed but its content is unusable.
    #[error("{path}: {message}")]
    Content {
        /// The scene file.
        path: PathBuf,
        /// The problem, naming the mesh, accessor or node.
        message: String,
    },
}

const SUPPORTED_EXTENSIONS: [&str; 17] = [
    "KHR_lights_punctual",
    "KHR_texture_transform",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_emissive_strength",
    "KHR_materials_volume",
    "KHR_materials_volume_scatter",
    "KHR_materials_specular",
    "EXT_texture_webp",
    "KHR_texture_basisu",
    "KHR_mesh_quantization",
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_anisotropy",
    "KHR_materials_iridescence",
];

/// The material extensions read from a material's own JSON (the glTF crate does
/// not model them): not said to be ignored.
const READ_MATERIAL_EXTENSIONS: &[&str] = &[
    "KHR_materials_volume_scatter",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_anisotropy",
    "KHR_materials_iridescence",
];

/// What an extension this renderer does not read holds, and how to get a file
/// without it: said when a file requires it ([`SceneError::Unsupported`]).
fn unsupported_needs(ext: &str) -> &'static str {
    match ext {
        "KHR_materials_pbrSpecularGlossiness" => {
            "the old specular-glossiness materials; convert them to metallic-roughness"
        }
        _ => "export the scene again without it",
    }
}

/// What is lost where a file uses, but does not require, an extension this
/// renderer does not read: said in the warning that names it.
fn ignored_loses(ext: &str) -> &'static str {
    match ext {
        "KHR_materials_diffuse_transmission" => "light through thin diffuse surfaces is not drawn",
        "KHR_materials_dispersion" => "glass does not disperse light",
        "KHR_materials_unlit" => "unlit materials are lit as the base colour's diffuse",
        "KHR_materials_variants" => "material variants are ignored: each mesh keeps its default material",
        "EXT_mesh_gpu_instancing" => "GPU instances are not drawn: each node draws its mesh once",
        "KHR_animation_pointer" => "animations of anything but node transforms are ignored",
        _ => "what it adds is ignored",
    }
}

/// Load a glTF 2.0 scene with the glTF specification's light units (see
/// [`LightUnits`]). Problems that do not stop loading are in `Scene::warnings`.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with(path, LightUnits::Photometric)
}

/// [`load`] reading `KHR_lights_punctual` intensities in `units`. The units are part
/// of the scene's content hash: photon maps traced with one reading are refused by
/// a stage that loads the scene with the other.
pub fn load_with(path: &Path, units: LightUnits) -> Result<Scene, SceneError> {
    let start = std::time::Instant::now();
    let content = |message: String| SceneError::Content { path: path.to_owned(), message };
    let (doc, buffers, content_hash) = read_document(path, units)?;
    let mut warnings = Vec::new();
    for ext in doc.extensions_used() {
        // One a material carries is said with the material's name (read_material).
        let on_a_material = doc.materials().any(|m| m.extensions().is_some_and(|e| e.contains_key(ext)));
        if !SUPPORTED_EXTENSIONS.contains(&ext) && !on_a_material {
            warnings.push(format!("extension {ext} is not read and is ignored: {}", ignored_loses(ext)));
        }
    }
    let base_dir = path.parent().unwrap_or(Path::new("."));
    let mats = Materials::read(&doc, base_dir, &buffers, &mut warnings).map_err(content)?;
    let mut animation = read_animations(&doc, &buffers).map_err(content)?;
    let scene =
        doc.default_scene().or_else(|| doc.scenes().next()).ok_or_else(|| content("the file has no scene".into()))?;
    // Node transforms are composed in f64 and the scene is moved near its camera
    // before anything is cast to f32 (pbrt-v4's "camera-world" space, with the
    // camera's position snapped to a 16 m grid): a scene placed 1e6 m from the
    // file's origin keeps 1 um precision within 8 m of the camera, and a scene whose
    // camera is within 8 m of it keeps its coordinates unchanged. (A 1,024 m grid
    // left the 0.5 m test box at 1e6 m 448 m from its origin, 30 um apart, and
    // image-space photon mapping lost 1% of its indirect light there; issue 36.)
    let gltf_scene_extras = scene.extras().clone();
    let nodes = node_worlds(&scene).map_err(content)?;
    let origin = nodes
        .iter()
        .find(|(n, _)| n.camera().is_some_and(|c| matches!(c.projection(), gltf::camera::Projection::Perspective(_))))
        .map_or(DVec3::ZERO, |(_, w)| (w.transform_point3(DVec3::ZERO) / ORIGIN_GRID).round() * ORIGIN_GRID);
    animation.origin = origin;
    let to_camera_world = DMat4::from_translation(-origin);
    let mut walk = NodeWalk::default();
    // The triangle list at its final size from the start: grown by doubling, the
    // last growth held the old and the new list at once (1.5 times the list's bytes
    // above what it needs, on a million triangles the load's peak).
    let count = |n: &gltf::Node| -> usize {
        n.mesh().map_or(0, |m| {
            m.primitives()
                .filter(|p| p.mode() == gltf::mesh::Mode::Triangles)
                .map(|p| p.indices().or_else(|| p.get(&gltf::Semantic::Positions)).map_or(0, |a| a.count() / 3))
                .sum()
        })
    };
    walk.triangles.reserve_exact(nodes.iter().map(|(n, _)| count(n)).sum());
    for (node, world64) in nodes {
        let world = (to_camera_world * world64).as_mat4();
        if !world.is_finite() {
            return Err(content(format!("node {}: transform is not finite", node.index())));
        }
        let node_name = node.name().map_or_else(|| format!("node #{}", node.index()), str::to_owned);
        let at = Placed { index: node.index(), name: &node_name, world };
        let (a, w) = (&mut animation, &mut warnings);
        if let Some(mesh) = node.mesh() {
            walk.mesh(&at, mesh, &mats, &doc, &buffers, a, w).map_err(content)?;
        }
        if let Some(light) = node.light() {
            walk.light(&at, light, units, a, w).map_err(content)?;
        }
        if walk.camera.is_none()
            && let Some(cam) = node.camera()
        {
            walk.camera(&at, cam, a, w).map_err(content)?;
        }
    }
    if walk.skipped_degenerate > 0 {
        warnings.push(format!("{} zero-area triangles skipped", walk.skipped_degenerate));
    }
    // The file's buffers and the decoded primitives are done with: freed before the
    // BVH is built, the load's other peak.
    let NodeWalk { triangles, lights, objects, camera, decoded, .. } = walk;
    drop((decoded, buffers));
    let mut scene = Scene::build(
        crate::Contents { triangles, materials: mats.materials, textures: mats.textures, lights, objects, camera },
        content_hash,
        warnings,
    );
    for (i, m) in mats.media.into_iter().enumerate() {
        if let Some(m) = m {
            let id = scene.add_medium(m);
            scene.set_material_medium(i, id);
        }
    }
    scene.finish_media().map_err(content)?;
    scene.animation = animation;
    scene.origin = origin;
    scene.environment_spec = match gltf_scene_extras {
        Some(x) => crate::EnvironmentSpec::from_extras(x.get(), base_dir).map_err(content)?,
        None => None,
    };
    scene.load_seconds = start.elapsed().as_secs_f64();
    Ok(scene)
}

/// Read and validate the document at `path` and its buffers; its content hash
/// covers the file, every buffer and the light units.
fn read_document(
    path: &Path,
    units: LightUnits,
) -> Result<(gltf::Document, Vec<gltf::buffer::Data>, [u8; 32]), SceneError> {
    let bytes = std::fs::read(path).map_err(|error| SceneError::Io { path: path.to_owned(), error })?;
    let gltf_err = |e: gltf::Error| SceneError::Gltf { path: path.to_owned(), message: e.to_string() };
    let content = |message: String| SceneError::Content { path: path.to_owned(), message };
    // Parse, check the references gltf-json's validation indexes without a bounds check
    // (it panics on a POSITION accessor index out of range; found by fuzzing), then
    // validate.
    let raw = gltf::Gltf::from_slice_without_validation(&bytes).map_err(gltf_err)?;
    let mut root = raw.document.into_json();
    // A required extension we do not read is the one thing to say: validation
    // would first list what it leaves undecodable (a Draco mesh's accessors
    // have no buffer view).
    let unread: Vec<&String> =
        root.extensions_required.iter().filter(|e| !SUPPORTED_EXTENSIONS.contains(&e.as_str())).collect();
    if let Some(first) = unread.first() {
        let more = match unread.len() - 1 {
            0 => String::new(),
            n => format!(" (and {n} more: {})", unread[1..].iter().map(|e| e.as_str()).collect::<Vec<_>>().join(", ")),
        };
        return Err(SceneError::Unsupported {
            path: path.to_owned(),
            extension: format!("{first}{more}"),
            needed: unsupported_needs(first).into(),
        });
    }
    // Every required extension is one we read: the glTF crate, which checks
    // them against its own shorter list (no KHR_mesh_quantization), need not.
    root.extensions_required.clear();
    check_attribute_indices(&root).map_err(content)?;
    // Draco primitives' accessors hold no data (it is in the extension's buffer
    // view), which glTF's JSON validation refuses: a copy is validated with them
    // pointing at that view, and the file is kept as it is.
    let draco = crate::draco::accessors(&root);
    let document = if draco.is_empty() {
        gltf::Document::from_json(root).map_err(gltf_err)?
    } else {
        let mut patched = root.clone();
        for &(a, view) in &draco {
            patched.accessors[a].buffer_view = Some(gltf::json::Index::new(view));
        }
        gltf::Document::from_json(patched).map_err(gltf_err)?;
        gltf::Document::from_json_without_validation(root)
    };
    let gltf = gltf::Gltf { document, blob: raw.blob };
    let base_dir = path.parent().unwrap_or(Path::new("."));
    let mut buffers = read_buffers(&gltf.document, base_dir, gltf.blob.clone()).map_err(gltf_err)?;
    crate::meshopt_views::decode_views(&gltf.document, &mut buffers).map_err(content)?;
    let mut hasher = blake3::Hasher::new();
    hasher.update(&bytes);
    for b in &buffers {
        hasher.update(&b.0);
    }
    hasher.update(format!("light units: {units}").as_bytes());
    Ok((gltf.document, buffers, *hasher.finalize().as_bytes()))
}

/// The buffers of `doc` (files beside the scene, data URIs, the GLB chunk), each
/// checked against its stated length, as the glTF crate reads them, except
/// EXT_meshopt_compression's fallback buffers, which have no data of their own:
/// zeros, for the compressed views to be decoded into
/// ([`crate::meshopt_views::decode_views`]).
fn read_buffers(
    doc: &gltf::Document,
    base_dir: &Path,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<gltf::buffer::Data>, gltf::Error> {
    let mut buffers = Vec::new();
    for b in doc.buffers() {
        let data = if crate::meshopt_views::is_fallback(&b) {
            gltf::buffer::Data(vec![0; b.length().next_multiple_of(4)])
        } else {
            gltf::buffer::Data::from_source_and_blob(b.source(), Some(base_dir), &mut blob)?
        };
        if data.len() < b.length() {
            return Err(gltf::Error::BufferLength { buffer: b.index(), expected: b.length(), actual: data.len() });
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// One glTF material as [`read_material`] reads it.
struct ReadMaterial {
    material: Material,
    /// The medium it bounds (volume attenuation and scattering), if any.
    medium: Option<crate::Medium>,
    /// Whether a texture reads TEXCOORD_1.
    uses_uv1: bool,
    /// The TEXCOORD_n set its tangents follow (its normal texture's, coat normal
    /// texture's or anisotropy's), if it needs tangents.
    tangent_uv_set: Option<u8>,
}

/// One glTF material: its BSDF factors, the textures it reads (decoded by
/// `loader`), alpha and emission, and the medium it bounds. Errors name the
/// material; what is not read is said once in `warnings`.
fn read_material(
    m: gltf::Material,
    i: usize,
    loader: &mut TextureLoader,
    warnings: &mut Vec<String>,
) -> Result<ReadMaterial, String> {
    let name = m.name().map_or_else(|| format!("material #{i}"), str::to_owned);
    let mut factors = read_factors(&m, &name, warnings)?;
    let (rotation, film_min) = read_layer_factors(&m, &mut factors).map_err(|e| format!("material '{name}': {e}"))?;
    let bsdf = Bsdf::from_pbr(&factors);
    let pbr = m.pbr_metallic_roughness();
    let doc = loader.doc;
    // Every texture a material reads, with its coordinate set and transform.
    let mut uses_uv1 = false;
    let mut texture = |source: Option<TextureSource>, srgb: bool, what: &str| -> Result<_, String> {
        let Some((texture, tex_coord, transform)) = source else { return Ok(None) };
        let (r, above) = loader
            .texture_ref(texture, tex_coord, transform, srgb)
            .map_err(|e| format!("material '{name}': {what} texture: {e}"))?;
        if above {
            warnings.push(format!(
                "material '{name}': {what} texture reads a coordinate set above TEXCOORD_1; TEXCOORD_0 used"
            ));
        }
        uses_uv1 |= r.uv_set == 1;
        Ok(Some(r))
    };
    let base_texture = texture(info(pbr.base_color_texture()), true, "base colour")?;
    let metallic_roughness_texture = texture(info(pbr.metallic_roughness_texture()), false, "metallicRoughness")?;
    let emissive_texture = texture(info(m.emissive_texture()), true, "emissive")?;
    let specular_texture = texture(info(m.specular().and_then(|s| s.specular_texture())), false, "specular")?;
    let specular_color_texture =
        texture(info(m.specular().and_then(|s| s.specular_color_texture())), true, "specular colour")?;
    let normal = m.normal_texture();
    let normal_scale = normal.as_ref().map_or(1.0, |nt| nt.scale());
    if !normal_scale.is_finite() {
        return Err(format!("material '{name}': normal texture scale {normal_scale} is not finite"));
    }
    let normal_texture = texture(normal.map(|nt| normal_source(&nt)), false, "normal")?;
    let ext = |k: &str| m.extensions().and_then(|e| e.get(k));
    let mut layer_texture = |k: &str, key: &str, srgb: bool| -> Result<Option<TextureRef>, String> {
        let Some(e) = ext(k) else { return Ok(None) };
        let source = json_info(doc, e, key).map_err(|e| format!("material '{name}': {k}: {e}"))?;
        texture(source, srgb, key)
    };
    let mut layers = LayerTextures {
        coat: layer_texture("KHR_materials_clearcoat", "clearcoatTexture", false)?,
        coat_roughness: layer_texture("KHR_materials_clearcoat", "clearcoatRoughnessTexture", false)?,
        coat_normal: layer_texture("KHR_materials_clearcoat", "clearcoatNormalTexture", false)?,
        coat_normal_scale: 1.0,
        sheen_color: layer_texture("KHR_materials_sheen", "sheenColorTexture", true)?,
        sheen_roughness: layer_texture("KHR_materials_sheen", "sheenRoughnessTexture", false)?,
        anisotropy: layer_texture("KHR_materials_anisotropy", "anisotropyTexture", false)?,
        anisotropy_rotation: rotation,
        iridescence: layer_texture("KHR_materials_iridescence", "iridescenceTexture", false)?,
        iridescence_thickness: layer_texture("KHR_materials_iridescence", "iridescenceThicknessTexture", false)?,
        film_thickness_min: film_min,
    };
    if let Some(scale) = ext("KHR_materials_clearcoat").and_then(|c| c.get("clearcoatNormalTexture")) {
        layers.coat_normal_scale = json_number(scale, "scale", 1.0, f32::MIN..=f32::MAX)
            .map_err(|e| format!("material '{name}': clearcoatNormalTexture: {e}"))?;
    }
    // What is not read, said once per material: material extensions the loader
    // does not know (iridescence, ...), then textures.
    if let Some(ext) = m.extensions() {
        for k in ext.keys().filter(|k| !READ_MATERIAL_EXTENSIONS.contains(&k.as_str())) {
            warnings.push(format!("material '{name}': extension {k} ignored: {}", ignored_loses(k)));
        }
    }
    if m.occlusion_texture().is_some() {
        warnings.push(format!(
            "material '{name}': occlusion texture ignored (occlusion is what the light transport computes)"
        ));
    }
    let alpha_mode = read_alpha_mode(&m, &name)?;
    let medium = read_medium(&m, &name, factors.thin, warnings)?;
    let ef = m.emissive_factor();
    let emission = Rgb::new(ef[0], ef[1], ef[2]) * m.emissive_strength().unwrap_or(1.0);
    if !pm_color::is_valid(emission) {
        return Err(format!("material '{name}': emission {emission} is not a non-negative finite colour"));
    }
    let material = Material {
        name,
        bsdf,
        pbr: factors,
        base_alpha: pbr.base_color_factor()[3],
        alpha_mode,
        base_texture,
        metallic_roughness_texture,
        emissive_texture,
        specular_texture,
        specular_color_texture,
        normal_texture,
        normal_scale,
        layers,
        emission,
        double_sided: m.double_sided(),
        interior: None,
    };
    // Tangents are read or generated from the coordinates of the first texture
    // that needs them (the normal texture's, the coat normal's, the
    // anisotropy's; TEXCOORD_0 for an untextured anisotropy).
    let tangent_uv_set = normal_texture
        .or(layers.coat_normal)
        .map(|t| t.uv_set)
        .or_else(|| (material.pbr.anisotropy > 0.0).then(|| layers.anisotropy.map_or(0, |t| t.uv_set)));
    Ok(ReadMaterial { material, medium, uses_uv1, tangent_uv_set })
}

/// The material's scattering factors (base colour, metallic, roughness,
/// transmission, ior, KHR_materials_specular, thin-walled or not), checked.
fn read_factors(m: &gltf::Material, name: &str, warnings: &mut Vec<String>) -> Result<Pbr, String> {
    let pbr = m.pbr_metallic_roughness();
    let bc = pbr.base_color_factor();
    let mut base = Rgb::new(bc[0], bc[1], bc[2]);
    if !base.is_finite() || base.min_element() < 0.0 || !(0.0..=1.0).contains(&bc[3]) {
        return Err(format!("material '{name}': baseColorFactor {bc:?} is not a colour"));
    }
    if base.max_element() > 1.0 {
        warnings.push(format!("material '{name}': albedo {base} above 1 clamped to 1"));
        base = base.min(Rgb::ONE);
    }
    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    if !(0.0..=1.0).contains(&transmission) {
        return Err(format!("material '{name}': transmissionFactor {transmission} is not in [0, 1]"));
    }
    if m.transmission().is_some_and(|t| t.transmission_texture().is_some()) {
        warnings.push(format!("material '{name}': transmission texture ignored (transmissionFactor used)"));
    }
    let ior = m.ior().unwrap_or(1.5);
    let (specular, specular_color) =
        m.specular().map_or((1.0, Rgb::ONE), |s| (s.specular_factor(), Rgb::from(s.specular_color_factor())));
    if !(0.0..=1.0).contains(&specular) || !specular_color.is_finite() || specular_color.min_element() < 0.0 {
        return Err(format!(
            "material '{name}': KHR_materials_specular factor {specular} or colour {specular_color} is not valid"
        ));
    }
    if !(ior.is_finite() && ior >= 1.0) {
        return Err(format!("material '{name}': ior {ior} must be >= 1"));
    }
    Ok(Pbr {
        base,
        metallic: pbr.metallic_factor().clamp(0.0, 1.0),
        roughness: pbr.roughness_factor().clamp(0.0, 1.0),
        transmission,
        ior,
        thin: m.volume().is_none_or(|v| v.thickness_factor() <= 0.0),
        specular,
        specular_color,
        ..Pbr::dielectric(base)
    })
}

/// A normal texture as a texture source: KHR_texture_transform on a normal
/// texture is only in its JSON.
fn normal_source<'a>(nt: &gltf::material::NormalTexture<'a>) -> TextureSource<'a> {
    (nt.texture(), nt.tex_coord(), nt.extension_value("KHR_texture_transform").map(json_transform))
}

/// A KHR_texture_transform object read from JSON: its matrix and its own
/// TEXCOORD_n if it names one.
fn json_transform(t: &gltf::json::Value) -> (glam::Affine2, Option<u32>) {
    let pair = |k: &str, d: f32| {
        let a = t.get(k).and_then(|v| v.as_array());
        let at = |i: usize| a.and_then(|a| a.get(i)).and_then(|v| v.as_f64()).map_or(d, |v| v as f32);
        [at(0), at(1)]
    };
    let rotation = t.get("rotation").and_then(|v| v.as_f64()).unwrap_or(0.0) as f32;
    let set = t.get("texCoord").and_then(|v| v.as_u64()).map(|v| v as u32);
    (uv_transform(pair("offset", 0.0), rotation, pair("scale", 1.0)), set)
}

/// A textureInfo inside a material extension's JSON (`index`, `texCoord`, and
/// KHR_texture_transform) as a texture source; `key` names it in errors.
fn json_info<'a>(
    doc: &'a gltf::Document,
    ext: &gltf::json::Value,
    key: &str,
) -> Result<Option<TextureSource<'a>>, String> {
    let Some(info) = ext.get(key) else { return Ok(None) };
    let index = info.get("index").and_then(|v| v.as_u64()).ok_or_else(|| format!("{key} has no texture index"))?;
    let texture = doc
        .textures()
        .nth(index as usize)
        .ok_or_else(|| format!("{key} names texture {index}, which the file does not have"))?;
    let tex_coord = info.get("texCoord").and_then(|v| v.as_u64()).unwrap_or(0) as u32;
    let transform = info.get("extensions").and_then(|e| e.get("KHR_texture_transform")).map(json_transform);
    Ok(Some((texture, tex_coord, transform)))
}

/// A number in a material extension's JSON, `default` when absent; an error
/// when present and not a finite number in `range`.
fn json_number(
    ext: &gltf::json::Value,
    key: &str,
    default: f32,
    range: std::ops::RangeInclusive<f32>,
) -> Result<f32, String> {
    match ext.get(key) {
        None => Ok(default),
        Some(v) => match v.as_f64().map(|x| x as f32) {
            Some(x) if x.is_finite() && range.contains(&x) => Ok(x),
            _ => Err(format!("{key} {v} is not a number in [{}, {}]", range.start(), range.end())),
        },
    }
}

/// The factors of KHR_materials_clearcoat, _sheen, _anisotropy and _iridescence
/// into `pbr` (the film's greatest thickness as its thickness), and the
/// anisotropy's rotation and the film's least thickness [nm] (textures are read
/// by the caller).
fn read_layer_factors(m: &gltf::Material, pbr: &mut Pbr) -> Result<(f32, f32), String> {
    let ext = |k: &str| m.extensions().and_then(|e| e.get(k));
    let mut rotation = 0.0;
    if let Some(c) = ext("KHR_materials_clearcoat") {
        let err = |e: String| format!("KHR_materials_clearcoat: {e}");
        pbr.coat = json_number(c, "clearcoatFactor", 0.0, 0.0..=1.0).map_err(err)?;
        pbr.coat_roughness = json_number(c, "clearcoatRoughnessFactor", 0.0, 0.0..=1.0).map_err(err)?;
    }
    if let Some(sh) = ext("KHR_materials_sheen") {
        let err = |e: String| format!("KHR_materials_sheen: {e}");
        let c = sh.get("sheenColorFactor").map_or(Ok([0.0; 3]), |v| {
            let a = v.as_array().filter(|a| a.len() == 3);
            let x = a.map(|a| a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN) as f32).collect::<Vec<_>>());
            match x {
                Some(x) if x.iter().all(|c| c.is_finite() && *c >= 0.0) => Ok([x[0], x[1], x[2]]),
                _ => Err(format!("sheenColorFactor {v} is not a colour")),
            }
        });
        pbr.sheen = Rgb::from(c.map_err(err)?).min(Rgb::ONE);
        pbr.sheen_roughness = json_number(sh, "sheenRoughnessFactor", 0.0, 0.0..=1.0).map_err(err)?;
    }
    if let Some(a) = ext("KHR_materials_anisotropy") {
        let err = |e: String| format!("KHR_materials_anisotropy: {e}");
        pbr.anisotropy = json_number(a, "anisotropyStrength", 0.0, 0.0..=1.0).map_err(err)?;
        rotation = json_number(a, "anisotropyRotation", 0.0, f32::MIN..=f32::MAX).map_err(err)?;
    }
    let mut film_min = 100.0;
    if let Some(f) = ext("KHR_materials_iridescence") {
        let err = |e: String| format!("KHR_materials_iridescence: {e}");
        pbr.iridescence = json_number(f, "iridescenceFactor", 0.0, 0.0..=1.0).map_err(err)?;
        // The ratified key, or the drafts' spelling.
        let ior_key = if f.get("iridescenceIOR").is_some() { "iridescenceIOR" } else { "iridescenceIor" };
        pbr.iridescence_ior = json_number(f, ior_key, FILM_IOR, 1.0..=f32::MAX).map_err(err)?;
        film_min = json_number(f, "iridescenceThicknessMinimum", 100.0, 0.0..=f32::MAX).map_err(err)?;
        pbr.iridescence_thickness =
            json_number(f, "iridescenceThicknessMaximum", 400.0, 0.0..=f32::MAX).map_err(err)?;
    }
    Ok((rotation, film_min))
}

/// The material's alpha mode, its cutoff checked.
fn read_alpha_mode(m: &gltf::Material, name: &str) -> Result<AlphaMode, String> {
    Ok(match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
        gltf::material::AlphaMode::Mask => {
            let cutoff = m.alpha_cutoff().unwrap_or(0.5);
            if !cutoff.is_finite() || cutoff < 0.0 {
                return Err(format!("material '{name}': alphaCutoff {cutoff} is not a non-negative number"));
            }
            AlphaMode::Mask { cutoff }
        }
        gltf::material::AlphaMode::Blend => AlphaMode::Blend,
    })
}

/// The medium a material bounds. KHR_materials_volume: attenuationColor is what
/// is left after attenuationDistance, so sigma_t = -ln(colour) / distance; with
/// the draft KHR_materials_volume_scatter, scatterAlbedo (earlier drafts:
/// multiscatterColor) is the multiple-scattering albedo, mapped to the
/// single-scattering albedo by Kulla and Conty's fit as the draft says, and
/// scatterAnisotropy is Henyey-Greenstein's g. A volume that is not `thin` (a
/// thicknessFactor above 0) bounds a medium, clear when nothing attenuates.
fn read_medium(
    m: &gltf::Material,
    name: &str,
    thin: bool,
    warnings: &mut Vec<String>,
) -> Result<Option<crate::Medium>, String> {
    let scatter = m.extension_value("KHR_materials_volume_scatter");
    let Some(v) = m.volume() else {
        if scatter.is_some() {
            warnings.push(format!(
                "material '{name}': KHR_materials_volume_scatter ignored (it needs KHR_materials_volume)"
            ));
        }
        return Ok(None);
    };
    let (c, d) = (Rgb::from(v.attenuation_color()), v.attenuation_distance());
    let (albedo, g) = match scatter {
        Some(x) => {
            let colour = x.get("scatterAlbedo").or_else(|| x.get("multiscatterColor"));
            let rho_ms = match colour.and_then(|v| v.as_array()) {
                Some(a) if a.len() == 3 && a.iter().all(|v| v.as_f64().is_some()) => {
                    let c: Vec<f32> = a.iter().map(|v| v.as_f64().unwrap_or(0.0) as f32).collect();
                    Rgb::new(c[0], c[1], c[2])
                }
                Some(_) => return Err(format!("material '{name}': scatterAlbedo is not three numbers")),
                None => Rgb::ZERO,
            };
            if !rho_ms.is_finite() || rho_ms.min_element() < 0.0 || rho_ms.max_element() > 1.0 {
                return Err(format!("material '{name}': scatterAlbedo {rho_ms} is not in [0, 1]"));
            }
            let g = match x.get("scatterAnisotropy") {
                Some(v) => v.as_f64().ok_or_else(|| format!("material '{name}': scatterAnisotropy is not a number"))?,
                None => 0.0,
            } as f32;
            (crate::single_scattering_albedo(rho_ms), g)
        }
        None => (Rgb::ZERO, 0.0),
    };
    let volume = crate::Medium::from_attenuation(name.to_string(), c, d, albedo, g)?;
    if !thin {
        return Ok(Some(volume));
    }
    if !volume.is_clear() {
        warnings
            .push(format!("material '{name}': volume attenuation ignored (thicknessFactor 0 makes it thin-walled)"));
    }
    Ok(None)
}

/// A node as the walk places it: its index (what animations name), its name for
/// messages, and its world (camera-world) transform.
#[derive(Clone, Copy)]
struct Placed<'a> {
    index: usize,
    name: &'a str,
    world: Mat4,
}

/// What the walk over the scene's nodes collects: triangles in world (camera-world)
/// space, lights, objects and the first perspective camera.
#[derive(Default)]
struct NodeWalk {
    triangles: Vec<Triangle>,
    lights: Vec<Light>,
    objects: Vec<Object>,
    camera: Option<Camera>,
    skipped_degenerate: usize,
    /// Each mesh primitive's decoded vertex data, by (mesh, primitive).
    decoded: std::collections::HashMap<(usize, usize), std::rc::Rc<LocalPrim>>,
    /// Primitive modes already warned about.
    warned_modes: BTreeSet<String>,
}

/// The materials of a file with what decoding their meshes needs to know.
struct Materials {
    materials: Vec<Material>,
    /// Per material, the medium it bounds (attached once the scene is built).
    media: Vec<Option<crate::Medium>>,
    textures: Vec<Texture>,
    /// Per material, whether a texture reads TEXCOORD_1 (only then is it read).
    uv1_needed: Vec<bool>,
    /// Per material, the TEXCOORD_n set its tangents follow (they are needed only
    /// then, generated from that set when the file has none).
    tangent_sets: Vec<Option<u8>>,
    /// glTF's default material (primitives without one), the last.
    default: u32,
}

impl Materials {
    /// Every material of `doc`, textures decoded once per image, wrapping and
    /// colour space, only when a material reads them; then the default material.
    fn read(
        doc: &gltf::Document,
        base_dir: &Path,
        buffers: &[gltf::buffer::Data],
        warnings: &mut Vec<String>,
    ) -> Result<Materials, String> {
        let mut loader = TextureLoader { doc, base_dir, buffers, textures: Vec::new(), cache: Default::default() };
        let (mut materials, mut uv1_needed, mut tangent_sets) = (Vec::new(), Vec::new(), Vec::new());
        let mut media = Vec::new();
        for (i, m) in doc.materials().enumerate() {
            let read = read_material(m, i, &mut loader, warnings)?;
            media.push(read.medium);
            uv1_needed.push(read.uses_uv1);
            tangent_sets.push(read.tangent_uv_set);
            materials.push(read.material);
        }
        // glTF's default material (primitives without one): white-ish diffuse.
        let default = materials.len() as u32;
        let default_factors = Pbr::dielectric(Rgb::splat(0.8));
        materials.push(Material {
            pbr: default_factors,
            ..Material::new("default", Bsdf::from_pbr(&default_factors), Rgb::ZERO)
        });
        media.push(None);
        Ok(Materials { materials, media, textures: loader.textures, uv1_needed, tangent_sets, default })
    }
}

impl NodeWalk {
    /// The triangles of `mesh` (on the node `at`), its objects, and an
    /// area light per emissive primitive; animated nodes' meshes are kept at rest
    /// for re-posing.
    fn mesh(
        &mut self,
        at: &Placed,
        mesh: gltf::Mesh,
        mats: &Materials,
        doc: &gltf::Document,
        buffers: &[gltf::buffer::Data],
        animation: &mut Animation,
        warnings: &mut Vec<String>,
    ) -> Result<(), String> {
        let Placed { index, name: node_name, world } = *at;
        let normal_m = Mat3::from_mat4(world).inverse().transpose();
        for (pi, prim) in mesh.primitives().enumerate() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                if self.warned_modes.insert(format!("{:?}", prim.mode())) {
                    warnings.push(format!(
                        "primitives of mode {:?} are skipped (only triangles are rendered)",
                        prim.mode()
                    ));
                }
                continue;
            }
            let what = format!("mesh '{}' primitive {pi}", mesh.name().unwrap_or("unnamed"));
            let first = self.triangles.len();
            let material = prim.material().index().map_or(mats.default, |i| i as u32);
            let mat = PrimMaterial {
                read_uv1: mats.uv1_needed.get(material as usize).copied().unwrap_or(false),
                tangent_set: mats.tangent_sets.get(material as usize).copied().flatten(),
            };
            // Decoded once per primitive, however many nodes instance its mesh.
            let local = match self.decoded.entry((mesh.index(), pi)) {
                std::collections::hash_map::Entry::Occupied(e) => std::rc::Rc::clone(e.get()),
                std::collections::hash_map::Entry::Vacant(e) => {
                    let d = decode_primitive(&prim, doc, buffers, mat).map_err(|m| format!("{what}: {m}"))?;
                    if let Some(w) = coarse_positions(&d.positions) {
                        warnings.push(format!("{what}: {w}"));
                    }
                    std::rc::Rc::clone(e.insert(std::rc::Rc::new(d)))
                }
            };
            let skipped = instance_primitive(&local, world, normal_m, material, &mut self.triangles)
                .map_err(|m| format!("{what}: {m}"))?;
            self.skipped_degenerate += skipped;
            if self.triangles.len() > first {
                let name = match mesh.name() {
                    Some(m) if m != node_name => format!("{node_name} ({m})"),
                    _ => node_name.to_string(),
                };
                if animation.moves(index) {
                    // The same primitive in the node's own space, re-posed per frame.
                    let mut rest = Vec::new();
                    instance_primitive(&local, Mat4::IDENTITY, Mat3::IDENTITY, material, &mut rest)
                        .map_err(|m| format!("{what}: {m}"))?;
                    if rest.len() == self.triangles.len() - first {
                        animation.meshes.push(AnimatedMesh {
                            object: self.objects.len(),
                            node: index,
                            local: rest,
                            pose: world,
                        });
                    } else {
                        warnings.push(format!(
                            "node '{node_name}': its triangles degenerate differently at rest; not animated"
                        ));
                    }
                }
                self.objects.push(Object { name, tris: first as u32..self.triangles.len() as u32, material });
            }
            let mat = &mats.materials[material as usize];
            if mat.emission.max_element() > 0.0 && self.triangles.len() > first {
                let name = format!("{node_name} ({})", mat.name);
                self.lights.push(Light::area(name, first as u32..self.triangles.len() as u32, &self.triangles, mat));
            }
        }
        Ok(())
    }

    /// A `KHR_lights_punctual` light on the node `at`, its intensity
    /// read in `units`.
    fn light(
        &mut self,
        at: &Placed,
        light: gltf::khr_lights_punctual::Light,
        units: LightUnits,
        animation: &mut Animation,
        warnings: &mut Vec<String>,
    ) -> Result<(), String> {
        let Placed { index, name: node_name, world } = *at;
        let position = world.transform_point3(Vec3::ZERO);
        let axis = world.transform_vector3(-Vec3::Z).normalize_or_zero();
        let c = light.color();
        // Candela (lm/sr) or lux (lm/m^2) to W/sr or W/m^2 at 683 lm/W, or already
        // radiometric.
        let watts = match units {
            LightUnits::Photometric => light.intensity() / LUMINOUS_EFFICACY,
            LightUnits::Radiometric => light.intensity(),
        };
        let value = Rgb::new(c[0], c[1], c[2]) * watts;
        if !pm_color::is_valid(value) {
            return Err(format!("light '{node_name}': intensity x colour {value} is not a non-negative finite colour"));
        }
        if light.range().is_some() {
            warnings.push(format!("light '{node_name}': range is ignored (inverse-square falloff is physical)"));
        }
        let kind = match light.kind() {
            gltf::khr_lights_punctual::Kind::Point => LightKind::Point { position, intensity: value },
            gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                if axis == Vec3::ZERO {
                    return Err(format!("light '{node_name}': degenerate orientation"));
                }
                let outer = outer_cone_angle.clamp(1e-4, std::f32::consts::FRAC_PI_2);
                let inner = inner_cone_angle.clamp(0.0, outer);
                LightKind::Spot {
                    position,
                    direction: axis,
                    intensity: value,
                    cos_inner: inner.cos(),
                    cos_outer: outer.cos(),
                }
            }
            gltf::khr_lights_punctual::Kind::Directional => {
                if axis == Vec3::ZERO {
                    return Err(format!("light '{node_name}': degenerate orientation"));
                }
                LightKind::Directional { direction: axis, irradiance: value, cap: 0.0, center: Vec3::ZERO, radius: 0.0 }
            }
        };
        if animation.moves(index) {
            animation.lights.push((self.lights.len(), index));
        }
        self.lights.push(Light { name: node_name.to_string(), kind, power: Rgb::ZERO });
        Ok(())
    }

    /// The camera on the node `at`, if it is perspective.
    fn camera(
        &mut self,
        at: &Placed,
        cam: gltf::Camera,
        animation: &mut Animation,
        warnings: &mut Vec<String>,
    ) -> Result<(), String> {
        let Placed { index, name: node_name, world } = *at;
        match cam.projection() {
            gltf::camera::Projection::Perspective(p) => {
                let r = Mat3::from_mat4(world);
                let forward = (r * -Vec3::Z).normalize_or_zero();
                let up0 = (r * Vec3::Y).normalize_or_zero();
                let right = forward.cross(up0).normalize_or_zero();
                let up = right.cross(forward);
                let yfov = p.yfov();
                if right == Vec3::ZERO || !(yfov > 0.0 && yfov < std::f32::consts::PI) {
                    return Err(format!("camera on '{node_name}': degenerate orientation or yfov {yfov}"));
                }
                if animation.moves(index) {
                    animation.camera = Some(index);
                }
                self.camera = Some(Camera {
                    position: world.transform_point3(Vec3::ZERO),
                    forward,
                    up,
                    right,
                    yfov,
                    aspect: p.aspect_ratio(),
                });
            }
            gltf::camera::Projection::Orthographic(_) => {
                warnings.push(format!("camera on '{node_name}': orthographic cameras are not supported; skipped"));
            }
        }
        Ok(())
    }
}

/// Spacing [m] of the grid the scene's origin (its camera's position) is snapped to.
const ORIGIN_GRID: f64 = 16.0;

/// The nodes of `scene` depth first, each with its world transform composed in f64.
fn node_worlds<'a>(scene: &gltf::Scene<'a>) -> Result<Vec<(gltf::Node<'a>, DMat4)>, String> {
    let mut out = Vec::new();
    let mut stack: Vec<(gltf::Node, DMat4, usize)> = scene.nodes().map(|n| (n, DMat4::IDENTITY, 0)).collect();
    stack.reverse();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 256 {
            return Err("node hierarchy deeper than 256 levels (a cycle?)".into());
        }
        let local = match node.transform() {
            gltf::scene::Transform::Matrix { matrix } => DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from))),
            gltf::scene::Transform::Decomposed { translation, rotation, scale } => {
                DMat4::from_scale_rotation_translation(
                    DVec3::from(scale.map(f64::from)),
                    glam::DQuat::from_array(rotation.map(f64::from)).normalize(),
                    DVec3::from(translation.map(f64::from)),
                )
            }
        };
        let world = parent * local;
        if !world.is_finite() {
            return Err(format!("node {}: transform is not finite", node.index()));
        }
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world, depth + 1));
        }
        out.push((node, world));
    }
    Ok(out)
}

/// The node hierarchy and every translation, rotation and scale channel of every
/// animation (morph-target weights are not read).
fn read_animations(doc: &gltf::Document, buffers: &[gltf::buffer::Data]) -> Result<Animation, String> {
    let mut nodes: Vec<NodeRest> = doc
        .nodes()
        .map(|n| {
            let (t, r, s) = n.transform().decomposed();
            NodeRest { parent: None, t: Vec3::from(t), r: Quat::from_array(r), s: Vec3::from(s) }
        })
        .collect();
    for n in doc.nodes() {
        for c in n.children() {
            nodes[c.index()].parent = Some(n.index());
        }
    }
    let mut anim = Animation { nodes, ..Default::default() };
    let n_accessors = doc.accessors().len();
    for a in doc.animations() {
        for ch in a.channels() {
            let sampler = ch.sampler();
            if sampler.input().index() >= n_accessors || sampler.output().index() >= n_accessors {
                return Err("animation sampler accessor index out of range".into());
            }
            let path = match ch.target().property() {
                gltf::animation::Property::Translation => AnimPath::Translation,
                gltf::animation::Property::Rotation => AnimPath::Rotation,
                gltf::animation::Property::Scale => AnimPath::Scale,
                gltf::animation::Property::MorphTargetWeights => continue,
            };
            let interp = match sampler.interpolation() {
                gltf::animation::Interpolation::Step => Interp::Step,
                gltf::animation::Interpolation::Linear => Interp::Linear,
                gltf::animation::Interpolation::CubicSpline => Interp::CubicSpline,
            };
            let reader = ch.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));
            let what = || format!("animation channel of node {}", ch.target().node().index());
            let times: Vec<f32> = reader.read_inputs().ok_or_else(|| format!("{}: no key times", what()))?.collect();
            let values: Vec<Vec4> = match reader.read_outputs().ok_or_else(|| format!("{}: no values", what()))? {
                gltf::animation::util::ReadOutputs::Translations(v) => v.map(|x| Vec3::from(x).extend(0.0)).collect(),
                gltf::animation::util::ReadOutputs::Scales(v) => v.map(|x| Vec3::from(x).extend(0.0)).collect(),
                gltf::animation::util::ReadOutputs::Rotations(v) => v.into_f32().map(Vec4::from).collect(),
                gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => continue,
            };
            let per_key = if interp == Interp::CubicSpline { 3 } else { 1 };
            if times.is_empty() || values.len() != per_key * times.len() {
                return Err(format!("{}: {} key times but {} values", what(), times.len(), values.len()));
            }
            if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] < w[0]) {
                return Err(format!("{}: key times are not finite and increasing", what()));
            }
            if values.iter().any(|v| !v.is_finite()) {
                return Err(format!("{}: a value is not finite", what()));
            }
            anim.duration = anim.duration.max(*times.last().unwrap_or(&0.0));
            anim.channels.push(Channel { node: ch.target().node().index(), path, interp, times, values });
        }
    }
    Ok(anim)
}

/// Every mesh attribute and morph-target accessor index must name an accessor.
fn check_attribute_indices(root: &gltf::json::Root) -> Result<(), String> {
    let n = root.accessors.len();
    for (mi, mesh) in root.meshes.iter().enumerate() {
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let targets = prim.targets.iter().flatten().flat_map(|t| [t.positions, t.normals, t.tangents]).flatten();
            for idx in prim.attributes.values().copied().chain(targets).chain(prim.indices) {
                if idx.value() >= n {
                    return Err(format!(
                        "mesh {mi} primitive {pi}: accessor index {} is out of range ({n} accessors)",
                        idx.value()
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Append one primitive's triangles in world space. Returns the number of degenerate
/// triangles skipped; errors name what is wrong with the accessors.
/// What [`decode_primitive`] needs of a primitive's material.
#[derive(Clone, Copy)]
struct PrimMaterial {
    /// A texture reads TEXCOORD_1.
    read_uv1: bool,
    /// The material has a normal texture reading this TEXCOORD_n set: tangents are
    /// read (TANGENT) or generated from it.
    tangent_set: Option<u8>,
}

/// A primitive's vertex data decoded from its accessors once, in the mesh's own
/// space, shared by every node that instances the mesh.
struct LocalPrim {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    uvs1: Option<Vec<Vec2>>,
    colors: Option<Vec<Vec4>>,
    indices: Vec<u32>,
    /// Per corner (index position), in the mesh's space.
    corner_tangents: Option<Vec<Vec4>>,
}

/// A warning when a primitive's positions, as the file stores them (f32, before
/// any node transform), are so far from the file's origin that the spacing of f32
/// there exceeds 0.1% of the primitive's size: its shape was lost when the file was
/// written, and no loading can restore it (a 0.5 m box stored 1e5 m out is on a 7.8
/// mm grid, 1.6% of its size). A node translation keeps full precision (the loader
/// composes node transforms in f64 and moves the scene to its camera first).
fn coarse_positions(positions: &[Vec3]) -> Option<String> {
    let (lo, hi) = positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let size = (hi - lo).length();
    let far = lo.abs().max(hi.abs()).max_element();
    let spacing = far * f32::EPSILON;
    (size > 0.0 && spacing > 1e-3 * size).then(|| {
        format!(
            "its positions are stored up to {far:.0} m from the file's origin, where f32 is spaced {:.2} mm apart, {:.1}% of its size {size:.3} m: its shape is quantised in the file itself; store it near the origin and place it with its node's translation",
            spacing * 1e3,
            100.0 * spacing / size
        )
    })
}

/// Decode one primitive's accessors (checked against their buffers) and, when its
/// material has a normal texture, its tangents; errors name the accessor.
fn decode_primitive(
    prim: &gltf::Primitive,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    PrimMaterial { read_uv1, tangent_set, .. }: PrimMaterial,
) -> Result<LocalPrim, String> {
    use gltf::accessor::{DataType, Dimensions};
    // KHR_draco_mesh_compression: the attributes it holds (and the triangles)
    // come from its decoded data, the rest from their accessors.
    let draco = crate::draco::decode(prim, doc, buffers)?;
    let in_draco = |sem: &str| draco.as_ref().is_some_and(|d| d.has(sem));
    let check = |sem: &str, acc: gltf::Accessor, dims: Dimensions, types: &[DataType]| -> Result<(), String> {
        if acc.dimensions() != dims || !types.contains(&acc.data_type()) {
            return Err(format!(
                "{sem} accessor {} is {:?} {:?}, expected {dims:?} of {types:?}",
                acc.index(),
                acc.dimensions(),
                acc.data_type()
            ));
        }
        if in_draco(sem) || (sem == "indices" && draco.is_some()) {
            return Ok(());
        }
        if acc.sparse().is_some() {
            return Err(format!("{sem} accessor {} is sparse, which is not supported", acc.index()));
        }
        let Some(view) = acc.view() else {
            return Err(format!("{sem} accessor {} has no buffer view", acc.index()));
        };
        let buf_len = buffers.get(view.buffer().index()).map_or(0, |b| b.0.len());
        let elem = acc.size();
        let stride = view.stride().unwrap_or(elem);
        let need = view.offset() + acc.offset() + if acc.count() == 0 { 0 } else { (acc.count() - 1) * stride + elem };
        if view.offset() + view.length() > buf_len || need > view.offset() + view.length() {
            return Err(format!(
                "{sem} accessor {} reads past the end of its buffer ({need} bytes needed, {buf_len} available)",
                acc.index()
            ));
        }
        Ok(())
    };
    let pos_acc = prim.get(&gltf::Semantic::Positions).ok_or("has no POSITION attribute")?;
    // The component types core glTF allows, and those KHR_mesh_quantization
    // adds (integers, normalised or not, for positions and texture coordinates;
    // normalised signed ones for normals and tangents).
    let (any_int, signed_norm) = (
        [DataType::F32, DataType::I8, DataType::U8, DataType::I16, DataType::U16],
        [DataType::F32, DataType::I8, DataType::I16],
    );
    check("POSITION", pos_acc.clone(), Dimensions::Vec3, &any_int)?;
    let normal_acc = prim.get(&gltf::Semantic::Normals);
    if let Some(a) = normal_acc.clone() {
        check("NORMAL", a, Dimensions::Vec3, &signed_norm)?;
    }
    let uv_acc = prim.get(&gltf::Semantic::TexCoords(0));
    if let Some(a) = uv_acc.clone() {
        check("TEXCOORD_0", a, Dimensions::Vec2, &any_int)?;
    }
    let uv1_acc = if read_uv1 { prim.get(&gltf::Semantic::TexCoords(1)) } else { None };
    if let Some(a) = uv1_acc.clone() {
        check("TEXCOORD_1", a, Dimensions::Vec2, &any_int)?;
    }
    let color_acc = prim.get(&gltf::Semantic::Colors(0));
    if let Some(a) = color_acc.clone() {
        let dims = if a.dimensions() == Dimensions::Vec3 { Dimensions::Vec3 } else { Dimensions::Vec4 };
        check("COLOR_0", a, dims, &[DataType::F32, DataType::U8, DataType::U16])?;
    }
    let tangent_acc = if tangent_set.is_some() { prim.get(&gltf::Semantic::Tangents) } else { None };
    if let Some(a) = tangent_acc.clone() {
        check("TANGENT", a, Dimensions::Vec4, &signed_norm)?;
    }
    if let Some(a) = prim.indices() {
        check("indices", a, Dimensions::Scalar, &[DataType::U8, DataType::U16, DataType::U32])?;
    }
    let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));
    let d = draco.as_ref();
    let positions: Vec<Vec3> = attribute(d, "POSITION", &pos_acc, buffers).into_iter().map(Vec3::from).collect();
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(format!(
            "vertex {i} has a position that is not finite (NaN or Inf, or overflow after the node transform)"
        ));
    }
    let normals: Option<Vec<Vec3>> =
        normal_acc.map(|a| attribute(d, "NORMAL", &a, buffers).into_iter().map(Vec3::from).collect());
    let read_uv = |a: gltf::Accessor, sem: &str| attribute(d, sem, &a, buffers).into_iter().map(Vec2::from).collect();
    let uvs: Option<Vec<Vec2>> = uv_acc.map(|a| read_uv(a, "TEXCOORD_0"));
    let uvs1: Option<Vec<Vec2>> = uv1_acc.map(|a| read_uv(a, "TEXCOORD_1"));
    let colors: Option<Vec<Vec4>> = match (&color_acc, d) {
        (Some(a), Some(d)) if d.has("COLOR_0") => Some(if a.dimensions() == Dimensions::Vec3 {
            d.floats::<3>("COLOR_0").unwrap_or_default().into_iter().map(|c| Vec3::from(c).extend(1.0)).collect()
        } else {
            d.floats::<4>("COLOR_0").unwrap_or_default().into_iter().map(Vec4::from).collect()
        }),
        (Some(_), _) => reader.read_colors(0).map(|it| it.into_rgba_f32().map(Vec4::from).collect()),
        (None, _) => None,
    };
    if let Some(c) = &colors
        && let Some(i) = c.iter().position(|c| !c.is_finite() || c.min_element() < 0.0)
    {
        return Err(format!("COLOR_0 of vertex {i} is not a non-negative finite colour"));
    }
    for (what, len) in [
        ("NORMAL", normals.as_ref().map(Vec::len)),
        ("TEXCOORD_0", uvs.as_ref().map(Vec::len)),
        ("TEXCOORD_1", uvs1.as_ref().map(Vec::len)),
        ("COLOR_0", colors.as_ref().map(Vec::len)),
    ] {
        if let Some(len) = len
            && len != positions.len()
        {
            return Err(format!("{what} has {len} entries but POSITION has {}", positions.len()));
        }
    }
    let indices: Vec<u32> = match (d, reader.read_indices()) {
        (Some(d), _) => d.indices.clone(),
        (None, Some(it)) => it.into_u32().collect(),
        (None, None) => (0..positions.len() as u32).collect(),
    };
    if !indices.len().is_multiple_of(3) {
        return Err(format!("{} indices is not a multiple of 3", indices.len()));
    }
    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
        return Err(format!("index {bad} is out of range ({} vertices)", positions.len()));
    }
    // Tangents per corner (index position) in the mesh's space: the file's, or
    // MikkTSpace's from the normal texture's coordinates (glTF 2.0 section 3.7.2.1).
    let tangent_uvs = match tangent_set {
        Some(1) => uvs1.as_ref(),
        Some(_) => uvs.as_ref(),
        None => None,
    };
    let corner_tangents: Option<Vec<Vec4>> = if tangent_set.is_none() {
        None
    } else if tangent_acc.is_some() {
        let t: Vec<Vec4> =
            attribute(d, "TANGENT", tangent_acc.as_ref().unwrap(), buffers).into_iter().map(Vec4::from).collect();
        if t.len() != positions.len() {
            return Err(format!("TANGENT has {} entries but POSITION has {}", t.len(), positions.len()));
        }
        Some(indices.iter().map(|&i| t[i as usize]).collect())
    } else {
        tangent_uvs.map(|uv| mikktspace_tangents(&positions, normals.as_deref(), uv, &indices))
    };
    Ok(LocalPrim { positions, normals, uvs, uvs1, colors, indices, corner_tangents })
}

/// Vertex attribute `sem` as floats, `N` a vertex: from the primitive's decoded
/// Draco data when it holds the attribute, else from its accessor `acc`
/// ([`read_floats`]).
fn attribute<const N: usize>(
    draco: Option<&crate::draco::Decoded>,
    sem: &str,
    acc: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
) -> Vec<[f32; N]> {
    match draco.and_then(|d| d.floats::<N>(sem)) {
        Some(v) => v,
        None => read_floats(acc, buffers),
    }
}

/// The elements of accessor `acc`, `N` components each, as floats: float
/// components as stored, integer ones as glTF 2.0 (section 3.11) and
/// KHR_mesh_quantization say: normalised, c / 255 or c / 65535 unsigned and
/// max(c / 127, -1) or max(c / 32767, -1) signed; otherwise the integer's value
/// (quantised positions, which the node's scale and translation place). The
/// accessor was checked: not sparse, within its buffer, `N` components.
fn read_floats<const N: usize>(acc: &gltf::Accessor, buffers: &[gltf::buffer::Data]) -> Vec<[f32; N]> {
    use gltf::accessor::DataType;
    let Some(view) = acc.view() else { return Vec::new() };
    let data = &buffers[view.buffer().index()].0;
    let (ty, norm) = (acc.data_type(), acc.normalized());
    let comp = ty.size();
    let stride = view.stride().unwrap_or(acc.size());
    let base = view.offset() + acc.offset();
    let component = |b: &[u8]| -> f32 {
        let c = match ty {
            DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            DataType::I8 => b[0] as i8 as f32,
            DataType::U8 => b[0] as f32,
            DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f32,
            DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32,
        };
        if norm { normalised(c, ty) } else { c }
    };
    (0..acc.count())
        .map(|i| {
            let at = base + i * stride;
            std::array::from_fn(|k| component(&data[at + k * comp..at + (k + 1) * comp]))
        })
        .collect()
}

/// Integer component `c` of type `ty` as a normalised accessor reads it (glTF 2.0
/// section 3.11): c / 255 or c / 65535 unsigned, max(c / 127, -1) or
/// max(c / 32767, -1) signed; float and 32-bit components as they are.
pub(crate) fn normalised(c: f32, ty: gltf::accessor::DataType) -> f32 {
    use gltf::accessor::DataType;
    match ty {
        DataType::I8 => (c / 127.0).max(-1.0),
        DataType::U8 => c / 255.0,
        DataType::I16 => (c / 32767.0).max(-1.0),
        DataType::U16 => c / 65535.0,
        DataType::F32 | DataType::U32 => c,
    }
}

/// Append a decoded primitive's triangles placed by `world` (normals by `normal_m`,
/// its inverse transpose). Returns the number of degenerate triangles skipped; an
/// error when a position overflows.
fn instance_primitive(
    local: &LocalPrim,
    world: Mat4,
    normal_m: Mat3,
    material: u32,
    out: &mut Vec<Triangle>,
) -> Result<usize, String> {
    let LocalPrim { positions, normals, uvs, uvs1, colors, indices, corner_tangents } = local;
    let positions: Vec<Vec3> = positions.iter().map(|&p| world.transform_point3(p)).collect();
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(format!("vertex {i} has a position that is not finite after the node transform (overflow)"));
    }
    let normals: Option<Vec<Vec3>> =
        normals.as_ref().map(|ns| ns.iter().map(|&n| (normal_m * n).normalize_or_zero()).collect());
    // A mirroring transform reverses the winding; keep counter-clockwise = front.
    let flip = Mat3::from_mat4(world).determinant() < 0.0;
    let linear = Mat3::from_mat4(world);
    let to_world = |t: Vec4| {
        let w = if (t.w < 0.0) != flip { -1.0 } else { 1.0 };
        (linear * t.truncate()).normalize_or_zero().extend(w)
    };
    let mut skipped = 0;
    for (f, tri) in indices.chunks_exact(3).enumerate() {
        let corners = if flip { [0, 2, 1] } else { [0, 1, 2] };
        let [a, b, c] = corners.map(|k| tri[k] as usize);
        let Some(mut t) = Triangle::new([positions[a], positions[b], positions[c]], material) else {
            skipped += 1;
            continue;
        };
        let n = normals.as_ref().and_then(|ns| {
            let n = [ns[a], ns[b], ns[c]];
            // Zero-length normals carry no information: fall back to the face normal.
            n.iter().all(|v| *v != Vec3::ZERO && v.is_finite()).then_some(n)
        });
        let uv = uvs.as_ref().map(|u| [u[a], u[b], u[c]]);
        let uv1 = uvs1.as_ref().map(|u| [u[a], u[b], u[c]]);
        let color = colors.as_ref().map(|v| [v[a], v[b], v[c]].map(|c| c.min(Vec4::ONE)));
        let tangent = corner_tangents.as_ref().map(|t| corners.map(|k| to_world(t[3 * f + k])));
        t.n = n;
        t.set_extras(crate::TriangleExtras { uv, uv1, color, tangent });
        out.push(t);
    }
    Ok(skipped)
}

/// MikkTSpace tangents (bevy_mikktspace, the reference algorithm's port) of an
/// indexed triangle list, per corner: xyz the tangent, w the bitangent's sign.
/// Without vertex normals the faces' own normals are used (glTF's flat shading).
fn mikktspace_tangents(positions: &[Vec3], normals: Option<&[Vec3]>, uvs: &[Vec2], indices: &[u32]) -> Vec<Vec4> {
    struct Mesh<'a> {
        p: &'a [Vec3],
        n: Option<&'a [Vec3]>,
        uv: &'a [Vec2],
        idx: &'a [u32],
        out: Vec<Vec4>,
    }
    impl bevy_mikktspace::Geometry for Mesh<'_> {
        fn num_faces(&self) -> usize {
            self.idx.len() / 3
        }
        fn num_vertices_of_face(&self, _: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.p[self.idx[3 * face + vert] as usize].to_array()
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            match self.n {
                Some(n) => n[self.idx[3 * face + vert] as usize].to_array(),
                None => {
                    let q = |k: usize| self.p[self.idx[3 * face + k] as usize];
                    (q(1) - q(0)).cross(q(2) - q(0)).normalize_or_zero().to_array()
                }
            }
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            self.uv[self.idx[3 * face + vert] as usize].to_array()
        }
        fn set_tangent(&mut self, ts: Option<bevy_mikktspace::TangentSpace>, face: usize, vert: usize) {
            if let Some(ts) = ts {
                self.out[3 * face + vert] = Vec4::from(ts.tangent_encoded());
            }
        }
    }
    let mut mesh = Mesh { p: positions, n: normals, uv: uvs, idx: indices, out: vec![Vec4::ZERO; indices.len()] };
    // The error type has no variants: generation cannot fail.
    let _ = bevy_mikktspace::generate_tangents(&mut mesh);
    mesh.out
}

/// A texture as a material names it: the texture, its TEXCOORD_n, and its
/// KHR_texture_transform (matrix, and the transform's own set if it names one).
type TextureSource<'a> = (gltf::Texture<'a>, u32, Option<(glam::Affine2, Option<u32>)>);

/// The [`TextureSource`] of a texture reference.
fn info(i: Option<gltf::texture::Info<'_>>) -> Option<TextureSource<'_>> {
    i.map(|i| {
        let transform =
            i.texture_transform().map(|t| (uv_transform(t.offset(), t.rotation(), t.scale()), t.tex_coord()));
        (i.texture(), i.tex_coord(), transform)
    })
}

/// The textures materials read, each image decoded once per wrapping and colour space.
struct TextureLoader<'a> {
    doc: &'a gltf::Document,
    base_dir: &'a Path,
    buffers: &'a [gltf::buffer::Data],
    textures: Vec<Texture>,
    cache: std::collections::HashMap<(usize, [Wrap; 2], Filter, bool), u32>,
}

impl TextureLoader<'_> {
    /// The reference to `texture` read with TEXCOORD_`tex_coord` (or the transform's
    /// own set) through `transform`; the flag says the set was above 1 and 0 is used.
    fn texture_ref(
        &mut self,
        texture: gltf::Texture,
        tex_coord: u32,
        transform: Option<(glam::Affine2, Option<u32>)>,
        srgb: bool,
    ) -> Result<(TextureRef, bool), String> {
        let (transform, set) = match transform {
            None => (glam::Affine2::IDENTITY, tex_coord),
            Some((a, set)) => (a, set.unwrap_or(tex_coord)),
        };
        if !transform.is_finite() {
            return Err("texture transform is not finite".into());
        }
        // KHR_texture_basisu's (KTX2) or EXT_texture_webp's image where there is
        // one (the extensions' rule: a client that reads it uses it; `source` is
        // then the fallback or absent).
        let ext_source = ["KHR_texture_basisu", "EXT_texture_webp"].into_iter().find_map(|name| {
            let e = texture.extensions()?.get(name)?;
            Some((name, e.get("source").and_then(|v| v.as_u64())?))
        });
        let image = match ext_source {
            Some((name, i)) => self.doc.images().nth(i as usize).ok_or_else(|| {
                format!("texture {}: {name} names image {i}, which the file does not have", texture.index())
            })?,
            None => texture.source().ok_or_else(|| format!("texture {} has no image", texture.index()))?,
        };
        let sampler = texture.sampler();
        let wrap = [sampler.wrap_s(), sampler.wrap_t()].map(|w| match w {
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
            gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        });
        let filter = match sampler.mag_filter() {
            Some(gltf::texture::MagFilter::Nearest) => Filter::Nearest,
            _ => Filter::Linear,
        };
        let key = (image.index(), wrap, filter, srgb);
        let index = match self.cache.get(&key) {
            Some(&t) => t,
            None => {
                let at = |e: String| format!("image {}: {e}", image.index());
                let bytes = image_bytes(&image, self.base_dir, self.buffers).map_err(at)?;
                let decoded = decode_image(&bytes).map_err(at)?;
                let mut t = decode_texture(&decoded, srgb)
                    .ok_or_else(|| at(format!("unsupported pixel format {:?}", decoded.color())))?;
                (t.wrap, t.filter) = (wrap, filter);
                self.textures.push(t);
                let i = self.textures.len() as u32 - 1;
                self.cache.insert(key, i);
                i
            }
        };
        Ok((TextureRef { texture: index, uv_set: if set == 1 { 1 } else { 0 }, transform }, set > 1))
    }
}

/// KHR_texture_transform's matrix: uv' = offset + R(rotation) (scale * uv), with R's
/// columns (cos, sin) and (-sin, cos).
fn uv_transform(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> glam::Affine2 {
    let (sin, cos) = rotation.sin_cos();
    let r = glam::Mat2::from_cols(Vec2::new(cos, sin), Vec2::new(-sin, cos));
    glam::Affine2::from_mat2_translation(r * glam::Mat2::from_diagonal(Vec2::from(scale)), Vec2::from(offset))
}

/// The encoded bytes of glTF image `image`: its buffer view's, a base64 data
/// URI's, or a file's beside the scene (its URI percent-decoded).
fn image_bytes(image: &gltf::Image, base_dir: &Path, buffers: &[gltf::buffer::Data]) -> Result<Vec<u8>, String> {
    match image.source() {
        gltf::image::Source::View { view, .. } => {
            let data = &buffers.get(view.buffer().index()).ok_or("its buffer is missing")?.0;
            let range = view.offset()..view.offset().saturating_add(view.length());
            data.get(range).map(<[u8]>::to_vec).ok_or_else(|| "its buffer view runs past its buffer".into())
        }
        gltf::image::Source::Uri { uri, .. } => match uri.strip_prefix("data:") {
            Some(rest) => {
                let (_, b64) = rest.split_once(";base64,").ok_or("a data URI that is not base64")?;
                base64::decode(b64).map_err(|e| format!("its data URI: {e}"))
            }
            None => {
                let name = urlencoding::decode(uri).map_err(|e| format!("uri '{uri}': {e}"))?;
                let path = base_dir.join(name.as_ref());
                std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))
            }
        },
    }
}

/// An image decoded from PNG, JPEG, WebP (EXT_texture_webp) or KTX2 with Basis
/// Universal data (KHR_texture_basisu: ETC1S or UASTC, transcoded to 8-bit RGBA
/// by the pure-Rust `basisu` crate, its largest mip level), told apart by
/// their first bytes (the glTF mimeType is not always given, nor right).
fn decode_image(bytes: &[u8]) -> Result<image::DynamicImage, String> {
    use image::ImageFormat;
    const KTX2: [u8; 12] = [0xab, b'K', b'T', b'X', b' ', b'2', b'0', 0xbb, b'\r', b'\n', 0x1a, b'\n'];
    if bytes.starts_with(&KTX2) {
        let t = basisu::Transcoder::new(bytes).map_err(|e| format!("KTX2: {e:?}"))?;
        let (w, h) = t.base_dimensions();
        let rgba = t
            .transcode(0, basisu::TargetFormat::Rgba32, basisu::DecodeFlags::NONE)
            .map_err(|e| format!("KTX2 ({:?}): {e:?}", t.source_format()))?;
        return image::RgbaImage::from_raw(w, h, rgba)
            .map(image::DynamicImage::ImageRgba8)
            .ok_or_else(|| format!("KTX2: {w} x {h} texels do not fit what it decodes to"));
    }
    let format = image::guess_format(bytes).map_err(|_| "not a PNG, JPEG or WebP image".to_string())?;
    if !matches!(format, ImageFormat::Png | ImageFormat::Jpeg | ImageFormat::WebP) {
        return Err(format!("a {format:?} image, which glTF does not allow (PNG, JPEG or WebP)"));
    }
    image::load_from_memory_with_format(bytes, format).map_err(|e| format!("{format:?}: {e}"))
}

/// 8-bit RGBA texels of a decoded image (16-bit channels keep their high byte; one
/// channel is grey, two are grey and alpha); `None` for float pixels.
fn decode_texture(img: &image::DynamicImage, srgb: bool) -> Option<Texture> {
    let color = img.color();
    let channels = color.channel_count() as usize;
    let bytes = color.bytes_per_pixel() as usize / channels;
    if !color.has_color() && channels > 2
        || bytes > 2
        || matches!(color, image::ColorType::Rgb32F | image::ColorType::Rgba32F)
    {
        return None;
    }
    let (width, height) = (img.width(), img.height());
    let n = (width as usize).checked_mul(height as usize)?;
    let pixels = img.as_bytes();
    if n == 0 || pixels.len() < n * channels * bytes {
        return None;
    }
    // The high byte of a 16-bit channel: image decodes to native-endian u16.
    let hi = if cfg!(target_endian = "little") { bytes - 1 } else { 0 };
    let texels = (0..n)
        .map(|i| {
            let px = &pixels[i * channels * bytes..];
            let c = |k: usize| px[k * bytes + hi];
            match channels {
                1 => [c(0), c(0), c(0), 255],
                2 => [c(0), c(0), c(0), c(1)],
                3 => [c(0), c(1), c(2), 255],
                _ => [c(0), c(1), c(2), c(3)],
            }
        })
        .collect();
    Some(Texture::new(width, height, texels, srgb))
}
