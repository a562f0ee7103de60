//! A glTF 2.0 writer: meshes, materials, textures, lights, cameras and animations
//! into plain JSON with one external .bin buffer and PNG textures. The scene
//! generator (`cargo xtask gen-scenes`) and the tests that write their own glTF
//! files both use it.

use anyhow::{Context, Result, bail};
use serde_json::{Value, json};
use std::path::Path;

/// A glTF document under construction: one binary buffer, appended to per accessor.
#[derive(Default)]
pub struct Doc {
    /// The binary buffer.
    pub bin: Vec<u8>,
    /// bufferViews.
    pub views: Vec<Value>,
    /// accessors.
    pub accessors: Vec<Value>,
    /// meshes.
    pub meshes: Vec<Value>,
    /// materials.
    pub materials: Vec<Value>,
    /// Nodes (each a root of the one scene).
    pub nodes: Vec<Value>,
    /// KHR_lights_punctual lights.
    pub lights: Vec<Value>,
    /// cameras.
    pub cameras: Vec<Value>,
    /// animations.
    pub animations: Vec<Value>,
    /// Extensions used (beyond lights, which are declared when there are any).
    pub extensions: Vec<&'static str>,
    /// Texture images (width, height, RGBA texels), written as `<scene>_<k>.png`,
    /// each with its own glTF texture and sampler (wrap modes).
    pub images: Vec<Image>,
    /// Top-level members written over the generated ones (a test's own extensions).
    pub top_level: serde_json::Map<String, Value>,
    /// The scene's `extras` (the environment it is lit by), if any.
    pub scene_extras: Option<Value>,
    /// A node (its translation, rotation, scale) to hold every other node as its
    /// children, as a Blender export's root does; none: every node is a root.
    pub root: Option<Value>,
}

/// A texture image and its sampler.
pub struct Image {
    /// Width and height \[texels\].
    pub size: (u32, u32),
    /// RGBA texels, row by row.
    pub texels: Vec<[u8; 4]>,
    /// The sampler's wrapS and wrapT (glTF enums).
    pub wrap: [u32; 2],
    /// The sampler's magnification and minification filter (glTF enum: 9728
    /// nearest, 9729 linear).
    pub filter: u32,
}

/// Per-vertex attributes beyond positions and normals.
#[derive(Default)]
pub struct Attrs {
    /// TEXCOORD_0.
    pub uv: Vec<[f32; 2]>,
    /// TEXCOORD_1.
    pub uv1: Vec<[f32; 2]>,
    /// COLOR_0, linear RGBA.
    pub color: Vec<[f32; 4]>,
}

/// Indexed triangle mesh with per-vertex normals (none: flat-shaded facets).
pub struct Mesh {
    /// Positions \[m\].
    pub p: Vec<[f32; 3]>,
    /// Unit normals, one per position, or none.
    pub n: Vec<[f32; 3]>,
    /// Three indices per triangle.
    pub idx: Vec<u32>,
}

impl Doc {
    /// Append `bytes` to the buffer (4-byte aligned) as a view with `target`; its index.
    pub fn push_view(&mut self, bytes: &[u8], target: u32) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len(), "target": target}));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    /// A VEC3 float vertex accessor, with its min and max when `with_bounds`; its index.
    pub fn vec3_accessor(&mut self, v: &[[f32; 3]], with_bounds: bool) -> usize {
        let i = self.vec_accessor(v, "VEC3");
        if with_bounds {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for p in v {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            self.accessors[i]["min"] = json!(lo);
            self.accessors[i]["max"] = json!(hi);
        }
        i
    }

    /// Key times \[s\] of an animation (a SCALAR float accessor with the min and max the
    /// specification requires of sampler inputs) and VEC3 values, in views without a
    /// target (animation data is neither vertex nor index data).
    pub fn animation_accessors(&mut self, times: &[f32], values: &[[f32; 3]]) -> (usize, usize) {
        let tb: Vec<u8> = times.iter().flat_map(|f| f.to_le_bytes()).collect();
        let vb: Vec<u8> = values.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        let mut untargeted = |bytes: &[u8]| {
            let view = self.push_view(bytes, 0);
            self.views[view].as_object_mut().expect("a view is an object").remove("target");
            view
        };
        let (tv, vv) = (untargeted(&tb), untargeted(&vb));
        let (lo, hi) = (
            times.iter().cloned().fold(f32::INFINITY, f32::min),
            times.iter().cloned().fold(f32::NEG_INFINITY, f32::max),
        );
        self.accessors.push(json!({"bufferView": tv, "componentType": 5126, "count": times.len(), "type": "SCALAR", "min": [lo], "max": [hi]}));
        self.accessors.push(json!({"bufferView": vv, "componentType": 5126, "count": values.len(), "type": "VEC3"}));
        (self.accessors.len() - 2, self.accessors.len() - 1)
    }

    /// A u32 index accessor; its index.
    pub fn index_accessor(&mut self, idx: &[u32]) -> usize {
        let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.push_view(&bytes, 34963);
        self.accessors.push(json!({"bufferView": view, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }

    /// Add a material; the extensions it uses are declared.
    pub fn material(&mut self, m: Value) -> usize {
        if let Some(ext) = m["extensions"].as_object() {
            for k in ext.keys() {
                let known = [
                    "KHR_materials_emissive_strength",
                    "KHR_materials_specular",
                    "KHR_materials_transmission",
                    "KHR_materials_ior",
                    "KHR_materials_volume",
                ];
                if let Some(&name) = known.iter().find(|&&n| n == k) {
                    self.extensions.push(name);
                }
            }
        }
        self.materials.push(m);
        self.materials.len() - 1
    }

    /// Add a mesh with one primitive and a node for it.
    pub fn mesh_node(&mut self, name: &str, mesh: &Mesh, material: usize) {
        self.mesh_node_attrs(name, mesh, &Attrs::default(), material);
    }

    /// A texture of RGBA texels with the sampler's wrap modes (glTF enums); its index.
    pub fn texture(&mut self, w: u32, h: u32, texels: Vec<[u8; 4]>, wrap: [u32; 2]) -> usize {
        self.texture_filtered(w, h, texels, wrap, 9729)
    }

    /// [`Self::texture`] with the sampler's `filter` (9728 nearest, 9729 linear).
    pub fn texture_filtered(&mut self, w: u32, h: u32, texels: Vec<[u8; 4]>, wrap: [u32; 2], filter: u32) -> usize {
        assert_eq!(texels.len(), (w * h) as usize);
        self.images.push(Image { size: (w, h), texels, wrap, filter });
        self.images.len() - 1
    }

    /// A float vertex accessor of N-vectors (`ty` VEC2, VEC3 or VEC4); its index.
    pub fn vec_accessor<const N: usize>(&mut self, v: &[[f32; N]], ty: &str) -> usize {
        let bytes: Vec<u8> = v.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.push_view(&bytes, 34962);
        self.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": v.len(), "type": ty}));
        self.accessors.len() - 1
    }

    /// Add a mesh with normals and the given extra attributes, and a node for it.
    pub fn mesh_node_attrs(&mut self, name: &str, mesh: &Mesh, attrs: &Attrs, material: usize) {
        let m = self.mesh_attrs(name, mesh, attrs, material);
        self.nodes.push(json!({"name": name, "mesh": m}));
    }

    /// Add a mesh with normals and the given extra attributes (no node); its index.
    pub fn mesh_attrs(&mut self, name: &str, mesh: &Mesh, attrs: &Attrs, material: usize) -> usize {
        let pos = self.vec3_accessor(&mesh.p, true);
        let mut attributes = json!({"POSITION": pos});
        if !mesh.n.is_empty() {
            attributes["NORMAL"] = self.vec3_accessor(&mesh.n, false).into();
        }
        if !attrs.uv.is_empty() {
            attributes["TEXCOORD_0"] = self.vec_accessor(&attrs.uv, "VEC2").into();
        }
        if !attrs.uv1.is_empty() {
            attributes["TEXCOORD_1"] = self.vec_accessor(&attrs.uv1, "VEC2").into();
        }
        if !attrs.color.is_empty() {
            attributes["COLOR_0"] = self.vec_accessor(&attrs.color, "VEC4").into();
        }
        let idx = self.index_accessor(&mesh.idx);
        self.meshes.push(
            json!({"name": name, "primitives": [{"attributes": attributes, "indices": idx, "material": material}]}),
        );
        self.meshes.len() - 1
    }

    /// Add a mesh without vertex normals (flat-shaded facets) and a node for it.
    pub fn flat_mesh_node(&mut self, name: &str, mesh: &Mesh, material: usize) {
        let pos = self.vec3_accessor(&mesh.p, true);
        let idx = self.index_accessor(&mesh.idx);
        self.meshes.push(json!({"name": name, "primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "material": material}]}));
        self.nodes.push(json!({"name": name, "mesh": self.meshes.len() - 1}));
    }

    /// The camera: at `eye`, looking down -z turned by the unit quaternion `rotation`
    /// (x, y, z, w; none: not turned). Numbers are written as given (an f32 as its
    /// widened f64 digits, as the older scenes have them).
    pub fn camera<T: serde::Serialize>(&mut self, eye: [T; 3], rotation: Option<[f64; 4]>, yfov: T, aspect: T) {
        self.cameras
            .push(json!({"type": "perspective", "perspective": {"yfov": yfov, "aspectRatio": aspect, "znear": 0.01}}));
        let mut node = json!({"name": "camera", "camera": 0, "translation": eye});
        if let Some(r) = rotation {
            node["rotation"] = json!(r);
        }
        self.nodes.push(node);
    }

    /// A white point light of `w_per_sr` W/sr at `at`, its intensity written in
    /// candela as the glTF specification asks (x 683 lm/W, the loader's
    /// [`pm_scene::LUMINOUS_EFFICACY`]). Returns the light's node.
    pub fn point_light(&mut self, name: &str, w_per_sr: f64, at: [f64; 3]) -> usize {
        self.coloured_point_light(name, w_per_sr, [1.0; 3], at)
    }

    /// [`Self::point_light`] of colour `rgb` (linear; the intensity per channel is
    /// `w_per_sr` times it).
    pub fn coloured_point_light(&mut self, name: &str, w_per_sr: f64, rgb: [f64; 3], at: [f64; 3]) -> usize {
        let candela = w_per_sr * pm_scene::LUMINOUS_EFFICACY as f64;
        self.lights.push(json!({"name": name, "type": "point", "intensity": candela, "color": rgb}));
        let light = self.lights.len() - 1;
        self.nodes
            .push(json!({"name": name, "translation": at, "extensions": {"KHR_lights_punctual": {"light": light}}}));
        self.nodes.len() - 1
    }

    /// Write `dir/NAME.gltf`, `NAME.bin` and the textures' `NAME_K.png` (with
    /// `check`, compare with the files there instead and fail if one differs).
    pub fn write(self, dir: &Path, name: &str, check: bool) -> Result<()> {
        let mut nodes = self.nodes;
        let n_nodes = nodes.len();
        let roots: Vec<usize> = match self.root {
            Some(mut r) => {
                r["children"] = json!((0..n_nodes).collect::<Vec<_>>());
                nodes.push(r);
                vec![n_nodes]
            }
            None => (0..n_nodes).collect(),
        };
        let mut root = json!({
            "asset": {"version": "2.0", "generator": "photon-map xtask gen-scenes"},
            "scene": 0,
            "scenes": [{"name": name, "nodes": roots}],
            "nodes": nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [{"uri": format!("{name}.bin"), "byteLength": self.bin.len()}],
        });
        if let Some(x) = &self.scene_extras {
            root["scenes"][0]["extras"] = x.clone();
        }
        if !self.cameras.is_empty() {
            root["cameras"] = json!(self.cameras);
        }
        if !self.animations.is_empty() {
            root["animations"] = json!(self.animations);
        }
        for (k, v) in &self.top_level {
            root[k] = v.clone();
        }
        let mut files = Vec::new();
        if !self.images.is_empty() {
            let mut images = vec![];
            let mut samplers = vec![];
            for (k, Image { size: (w, h), texels, wrap, filter }) in self.images.iter().enumerate() {
                let file = format!("{name}_{k}.png");
                let img = image::RgbaImage::from_raw(*w, *h, texels.concat()).context("texture size")?;
                let mut png = std::io::Cursor::new(Vec::new());
                img.write_to(&mut png, image::ImageFormat::Png)?;
                files.push((file.clone(), png.into_inner()));
                images.push(json!({"uri": file, "mimeType": "image/png"}));
                samplers.push(json!({"magFilter": filter, "minFilter": filter, "wrapS": wrap[0], "wrapT": wrap[1]}));
            }
            root["textures"] = (0..images.len()).map(|i| json!({"sampler": i, "source": i})).collect();
            root["images"] = images.into();
            root["samplers"] = samplers.into();
        }
        let mut ext = self.extensions.clone();
        if !self.lights.is_empty() {
            root["extensions"] = json!({"KHR_lights_punctual": {"lights": self.lights}});
            ext.push("KHR_lights_punctual");
        }
        ext.sort();
        ext.dedup();
        if !ext.is_empty() {
            root["extensionsUsed"] = json!(ext);
        }
        let text = serde_json::to_string_pretty(&root)? + "\n";
        files.extend([(format!("{name}.gltf"), text.into_bytes()), (format!("{name}.bin"), self.bin)]);
        for (file, bytes) in files {
            let path = dir.join(&file);
            if check {
                let old = std::fs::read(&path).with_context(|| format!("{}: cannot read", path.display()))?;
                if old != bytes {
                    bail!("{} is stale: run `cargo xtask gen-scenes`", path.display());
                }
            } else {
                std::fs::write(&path, bytes).with_context(|| format!("{}: cannot write", path.display()))?;
            }
        }
        Ok(())
    }
}
