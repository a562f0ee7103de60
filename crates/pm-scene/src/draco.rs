//! KHR_draco_mesh_compression: a primitive's vertex attributes and triangles
//! decoded from its Draco buffer view (draco-core, a pure Rust decoder), for the
//! loader to read in place of the accessors, which then have no data.
//!
//! The extension maps each glTF attribute (POSITION, NORMAL, TEXCOORD_n,
//! TANGENT, COLOR_0) to a Draco attribute by its unique id; the accessors keep
//! their type, count and normalisation, and the decoded values are what the
//! accessors would hold: floats as stored (positions dequantised by Draco),
//! integers normalised as the accessor says (glTF 2.0, section 3.11).

use std::collections::HashMap;

use draco_core::{DataType, DecoderBuffer, FaceIndex, Mesh, MeshDecoder};

/// The extension's name.
pub(crate) const EXTENSION: &str = "KHR_draco_mesh_compression";

/// A Draco primitive, decoded.
pub(crate) struct Decoded {
    /// Per glTF attribute name, its values (`components` floats a vertex).
    attributes: HashMap<String, (Vec<f32>, usize)>,
    /// Three vertex indices a triangle.
    pub(crate) indices: Vec<u32>,
}

/// The buffer view and attribute ids the extension object names.
fn extension<'a>(prim: &'a gltf::Primitive<'a>) -> Option<&'a gltf::json::Value> {
    prim.extension_value(EXTENSION)
}

/// The accessors a Draco primitive's data replaces (its attributes' and its
/// indices'), each with the buffer view of the compressed data: glTF's JSON
/// validation wants a buffer view on every accessor that is not sparse, and
/// these have none.
pub(crate) fn accessors(root: &gltf::json::Root) -> Vec<(usize, u32)> {
    let mut out = Vec::new();
    for prim in root.meshes.iter().flat_map(|m| &m.primitives) {
        let Some(ext) = prim.extensions.as_ref().and_then(|e| e.others.get(EXTENSION)) else { continue };
        let Some(view) = ext.get("bufferView").and_then(|v| v.as_u64()) else { continue };
        let used = prim.attributes.values().map(|a| a.value()).chain(prim.indices.as_ref().map(|i| i.value()));
        for a in used {
            if root.accessors.get(a).is_some_and(|acc| acc.buffer_view.is_none() && acc.sparse.is_none()) {
                out.push((a, view as u32));
            }
        }
    }
    out
}

/// Decode `prim`'s Draco data, or None when it has no such extension. Errors
/// say what is wrong with the data (the caller names the primitive).
pub(crate) fn decode(
    prim: &gltf::Primitive,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
) -> Result<Option<Decoded>, String> {
    let Some(ext) = extension(prim) else { return Ok(None) };
    let err = |m: String| format!("{EXTENSION}: {m}");
    let view = ext
        .get("bufferView")
        .and_then(|v| v.as_u64())
        .and_then(|v| doc.views().nth(v as usize))
        .ok_or_else(|| err("no valid bufferView".into()))?;
    let data = buffers.get(view.buffer().index()).map(|b| b.0.as_slice()).unwrap_or(&[]);
    let bytes = data
        .get(view.offset()..view.offset().saturating_add(view.length()))
        .ok_or_else(|| err(format!("buffer view {} reads past the end of its buffer", view.index())))?;
    let mut mesh = Mesh::new();
    MeshDecoder::new()
        .decode(&mut DecoderBuffer::new(bytes), &mut mesh)
        .map_err(|e| err(format!("the compressed data does not decode ({e:?})")))?;
    let vertices = mesh.num_points();
    let mut indices = Vec::with_capacity(3 * mesh.num_faces());
    for f in 0..mesh.num_faces() {
        indices.extend(mesh.face(FaceIndex(f as u32)).map(|p| p.0));
    }
    let mut attributes = HashMap::new();
    let ids = ext.get("attributes").and_then(|a| a.as_object()).ok_or_else(|| err("no attributes".into()))?;
    for (name, id) in ids {
        let Some(acc) = prim.attributes().find(|(s, _)| s.to_string() == *name).map(|(_, a)| a) else { continue };
        let id = id.as_u64().ok_or_else(|| err(format!("attribute {name}'s id is not a number")))? as u32;
        let att = (0..mesh.num_attributes())
            .map(|i| mesh.attribute(i))
            .find(|a| a.unique_id() == id)
            .ok_or_else(|| err(format!("attribute {name} names Draco attribute {id}, which the data does not have")))?;
        let n = acc.dimensions().multiplicity();
        let mut values = att.read_f32s(vertices, n);
        if acc.normalized() {
            // Integer components as the accessor's normalised type, by glTF's rule.
            use gltf::accessor::DataType as Gl;
            let ty = match att.data_type() {
                DataType::Uint8 => Some(Gl::U8),
                DataType::Uint16 => Some(Gl::U16),
                DataType::Int8 => Some(Gl::I8),
                DataType::Int16 => Some(Gl::I16),
                _ => None,
            };
            if let Some(ty) = ty {
                values.iter_mut().for_each(|v| *v = crate::gltf_load::normalised(*v, ty));
            }
        }
        attributes.insert(name.clone(), (values, n));
    }
    Ok(Some(Decoded { attributes, indices }))
}

impl Decoded {
    /// True when the data holds glTF attribute `name`.
    pub(crate) fn has(&self, name: &str) -> bool {
        self.attributes.contains_key(name)
    }

    /// The decoded values of glTF attribute `name`, `N` components a vertex.
    pub(crate) fn floats<const N: usize>(&self, name: &str) -> Option<Vec<[f32; N]>> {
        let (values, n) = self.attributes.get(name)?;
        (*n == N).then(|| values.chunks_exact(N).map(|c| std::array::from_fn(|k| c[k])).collect())
    }
}
