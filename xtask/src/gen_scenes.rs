//! The project's test scenes, generated from code so they are reproducible, and
//! written as plain glTF 2.0 (JSON + external .bin) that any viewer opens.

use anyhow::{Context, Result, bail};
use serde_json::{Value, json};
use std::f32::consts::PI;
use std::path::Path;

/// A glTF document under construction: one binary buffer, appended to per accessor.
#[derive(Default)]
struct Doc {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    materials: Vec<Value>,
    nodes: Vec<Value>,
    lights: Vec<Value>,
    cameras: Vec<Value>,
    animations: Vec<Value>,
    extensions: Vec<&'static str>,
    /// Texture images (width, height, RGBA texels), written as `<scene>_<k>.png`,
    /// each with its own glTF texture and sampler (wrap modes).
    images: Vec<Image>,
}

/// A texture image: width, height, RGBA texels, the sampler's wrapS and wrapT.
type Image = (u32, u32, Vec<[u8; 4]>, [u32; 2]);

/// Per-vertex attributes beyond positions and normals.
#[derive(Default)]
struct Attrs {
    uv: Vec<[f32; 2]>,
    uv1: Vec<[f32; 2]>,
    color: Vec<[f32; 4]>,
}

/// Indexed triangle mesh with per-vertex normals.
struct Mesh {
    p: Vec<[f32; 3]>,
    n: Vec<[f32; 3]>,
    idx: Vec<u32>,
}

impl Doc {
    fn push_view(&mut self, bytes: &[u8], target: u32) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len(), "target": target}));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn vec3_accessor(&mut self, v: &[[f32; 3]], with_bounds: bool) -> usize {
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

    /// Key times [s] of an animation (a SCALAR float accessor with the min and max the
    /// specification requires of sampler inputs) and VEC3 values, in views without a
    /// target (animation data is neither vertex nor index data).
    fn animation_accessors(&mut self, times: &[f32], values: &[[f32; 3]]) -> (usize, usize) {
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

    fn index_accessor(&mut self, idx: &[u32]) -> usize {
        let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.push_view(&bytes, 34963);
        self.accessors.push(json!({"bufferView": view, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }

    /// Add a material; the extensions it uses are declared.
    fn material(&mut self, m: Value) -> usize {
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
    fn mesh_node(&mut self, name: &str, mesh: &Mesh, material: usize) {
        self.mesh_node_attrs(name, mesh, &Attrs::default(), material);
    }

    /// A texture of RGBA texels with the sampler's wrap modes (glTF enums); its index.
    fn texture(&mut self, w: u32, h: u32, texels: Vec<[u8; 4]>, wrap: [u32; 2]) -> usize {
        assert_eq!(texels.len(), (w * h) as usize);
        self.images.push((w, h, texels, wrap));
        self.images.len() - 1
    }

    /// A float vertex accessor of N-vectors (`ty` VEC2, VEC3 or VEC4); its index.
    fn vec_accessor<const N: usize>(&mut self, v: &[[f32; N]], ty: &str) -> usize {
        let bytes: Vec<u8> = v.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.push_view(&bytes, 34962);
        self.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": v.len(), "type": ty}));
        self.accessors.len() - 1
    }

    /// Add a mesh with normals and the given extra attributes, and a node for it.
    fn mesh_node_attrs(&mut self, name: &str, mesh: &Mesh, attrs: &Attrs, material: usize) {
        let m = self.mesh_attrs(name, mesh, attrs, material);
        self.nodes.push(json!({"name": name, "mesh": m}));
    }

    /// Add a mesh with normals and the given extra attributes (no node); its index.
    fn mesh_attrs(&mut self, name: &str, mesh: &Mesh, attrs: &Attrs, material: usize) -> usize {
        let pos = self.vec3_accessor(&mesh.p, true);
        let nrm = self.vec3_accessor(&mesh.n, false);
        let mut attributes = json!({"POSITION": pos, "NORMAL": nrm});
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
    fn flat_mesh_node(&mut self, name: &str, mesh: &Mesh, material: usize) {
        let pos = self.vec3_accessor(&mesh.p, true);
        let idx = self.index_accessor(&mesh.idx);
        self.meshes.push(json!({"name": name, "primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "material": material}]}));
        self.nodes.push(json!({"name": name, "mesh": self.meshes.len() - 1}));
    }

    /// The camera: at `eye`, looking down -z turned by the unit quaternion `rotation`
    /// (x, y, z, w; none: not turned). Numbers are written as given (an f32 as its
    /// widened f64 digits, as the older scenes have them).
    fn camera<T: serde::Serialize>(&mut self, eye: [T; 3], rotation: Option<[f64; 4]>, yfov: T, aspect: T) {
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
    fn point_light(&mut self, name: &str, w_per_sr: f64, at: [f64; 3]) -> usize {
        let candela = w_per_sr * pm_scene::LUMINOUS_EFFICACY as f64;
        self.lights.push(json!({"name": name, "type": "point", "intensity": candela, "color": [1.0, 1.0, 1.0]}));
        let light = self.lights.len() - 1;
        self.nodes
            .push(json!({"name": name, "translation": at, "extensions": {"KHR_lights_punctual": {"light": light}}}));
        self.nodes.len() - 1
    }

    fn write(self, dir: &Path, name: &str, check: bool) -> Result<()> {
        let n_nodes = self.nodes.len();
        let mut root = json!({
            "asset": {"version": "2.0", "generator": "photon-map xtask gen-scenes"},
            "scene": 0,
            "scenes": [{"name": name, "nodes": (0..n_nodes).collect::<Vec<_>>()}],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [{"uri": format!("{name}.bin"), "byteLength": self.bin.len()}],
        });
        if !self.cameras.is_empty() {
            root["cameras"] = json!(self.cameras);
        }
        if !self.animations.is_empty() {
            root["animations"] = json!(self.animations);
        }
        let mut files = Vec::new();
        if !self.images.is_empty() {
            let mut images = vec![];
            let mut samplers = vec![];
            for (k, (w, h, texels, wrap)) in self.images.iter().enumerate() {
                let file = format!("{name}_{k}.png");
                let img = image::RgbaImage::from_raw(*w, *h, texels.concat()).context("texture size")?;
                let mut png = std::io::Cursor::new(Vec::new());
                img.write_to(&mut png, image::ImageFormat::Png)?;
                files.push((file.clone(), png.into_inner()));
                images.push(json!({"uri": file, "mimeType": "image/png"}));
                samplers.push(json!({"magFilter": 9729, "minFilter": 9729, "wrapS": wrap[0], "wrapT": wrap[1]}));
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

/// An axis-aligned quad with corners a, b, c, d in counter-clockwise order as seen
/// from the side its normal points to.
fn quad(a: [f32; 3], b: [f32; 3], c: [f32; 3], d: [f32; 3]) -> Mesh {
    let e1 = sub(b, a);
    let e2 = sub(d, a);
    let n = normalize(cross(e1, e2));
    Mesh { p: vec![a, b, c, d], n: vec![n; 4], idx: vec![0, 1, 2, 0, 2, 3] }
}

/// Several quads as one mesh.
fn merge(parts: &[Mesh]) -> Mesh {
    let mut m = Mesh { p: vec![], n: vec![], idx: vec![] };
    for part in parts {
        let base = m.p.len() as u32;
        m.p.extend_from_slice(&part.p);
        m.n.extend_from_slice(&part.n);
        m.idx.extend(part.idx.iter().map(|i| i + base));
    }
    m
}

/// UV sphere with smooth normals; `inward` flips normals and winding (front faces inside).
fn sphere(c: [f32; 3], r: f32, seg: u32, rings: u32, inward: bool) -> Mesh {
    let mut p = vec![];
    let mut n = vec![];
    for j in 0..=rings {
        let theta = PI * j as f32 / rings as f32;
        for i in 0..=seg {
            let phi = 2.0 * PI * i as f32 / seg as f32;
            let d = [theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin()];
            p.push([c[0] + r * d[0], c[1] + r * d[1], c[2] + r * d[2]]);
            n.push(if inward { [-d[0], -d[1], -d[2]] } else { d });
        }
    }
    let mut idx = vec![];
    let w = seg + 1;
    for j in 0..rings {
        for i in 0..seg {
            let (a, b, cc, d) = (j * w + i, (j + 1) * w + i, (j + 1) * w + i + 1, j * w + i + 1);
            // Counter-clockwise seen from outside: a, b, c then a, c, d.
            let tris = [[a, b, cc], [a, cc, d]];
            for t in tris {
                // Skip the degenerate triangles at the poles.
                if (j == 0 && t.contains(&a) && t.contains(&d)) || (j == rings - 1 && t.contains(&b) && t.contains(&cc))
                {
                    continue;
                }
                if inward { idx.extend([t[0], t[2], t[1]]) } else { idx.extend(t) }
            }
        }
    }
    Mesh { p, n, idx }
}

/// A box of size (sx, sy, sz) standing on the floor at (cx, cz), rotated by `angle` about y.
fn block(cx: f32, cz: f32, sx: f32, sy: f32, sz: f32, angle: f32) -> Mesh {
    let (s, c) = angle.sin_cos();
    let at = |x: f32, y: f32, z: f32| [cx + c * x + s * z, y, cz - s * x + c * z];
    let (hx, hz) = (sx / 2.0, sz / 2.0);
    let v = |i: u32| {
        let x = if i & 1 == 0 { -hx } else { hx };
        let y = if i & 2 == 0 { 0.0 } else { sy };
        let z = if i & 4 == 0 { -hz } else { hz };
        at(x, y, z)
    };
    merge(&[
        quad(v(4), v(5), v(7), v(6)), // +z
        quad(v(1), v(0), v(2), v(3)), // -z
        quad(v(5), v(1), v(3), v(7)), // +x
        quad(v(0), v(4), v(6), v(2)), // -x
        quad(v(2), v(6), v(7), v(3)), // +y
    ])
}

/// A Lambertian material: glTF's dielectric with its specular layer turned off
/// (KHR_materials_specular's specularFactor 0; without it every glTF dielectric has
/// a GGX layer, Appendix B). The analytic scenes need pure Lambertian surfaces.
fn diffuse(name: &str, rgb: [f32; 3]) -> Value {
    lambertian(
        json!({"name": name, "pbrMetallicRoughness": {"baseColorFactor": [rgb[0], rgb[1], rgb[2], 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}),
    )
}

/// Material `m` with its dielectric specular layer turned off.
fn lambertian(mut m: Value) -> Value {
    m["extensions"]["KHR_materials_specular"] = json!({"specularFactor": 0.0});
    m
}

/// The Cornell box shell: floor, ceiling, back, left (red), right (blue), and a square
/// ceiling light of side 0.5 m. Box interior [-1,1] x [0,2] x [-1,1] metres; the light
/// has radiance 12 W sr^-1 m^-2 (power pi * 12 * 0.25 = 9.4 W per channel).
fn cornell_shell(doc: &mut Doc) {
    let white = doc.material(diffuse("white", [0.75, 0.75, 0.75]));
    let red = doc.material(diffuse("red", [0.75, 0.15, 0.12]));
    let blue = doc.material(diffuse("blue", [0.12, 0.2, 0.75]));
    let light = doc.material(lambertian(json!({
        "name": "ceiling_light",
        "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "emissiveFactor": [1.0, 1.0, 1.0],
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 12.0}}
    })));
    doc.extensions.push("KHR_materials_emissive_strength");
    let (l, h) = (1.0, 2.0);
    let whites = merge(&[
        quad([-l, 0.0, l], [l, 0.0, l], [l, 0.0, -l], [-l, 0.0, -l]), // floor, +y
        quad([-l, h, -l], [l, h, -l], [l, h, l], [-l, h, l]),         // ceiling, -y
        quad([-l, 0.0, -l], [l, 0.0, -l], [l, h, -l], [-l, h, -l]),   // back, +z
    ]);
    doc.mesh_node("white_walls", &whites, white);
    doc.mesh_node("left_wall", &quad([-l, 0.0, l], [-l, 0.0, -l], [-l, h, -l], [-l, h, l]), red);
    doc.mesh_node("right_wall", &quad([l, 0.0, -l], [l, 0.0, l], [l, h, l], [l, h, -l]), blue);
    let (s, y) = (0.25, h - 0.002);
    doc.mesh_node("ceiling_light", &quad([-s, y, -s], [s, y, -s], [s, y, s], [-s, y, s]), light);
    doc.camera([0.0f32, 1.0, 3.8], None, 0.69, 1.0);
}

fn cornell_spheres() -> Doc {
    let mut doc = Doc::default();
    cornell_shell(&mut doc);
    let chrome = doc.material(json!({"name": "chrome", "pbrMetallicRoughness": {"baseColorFactor": [0.95, 0.95, 0.95, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.0}}));
    let glass = doc.material(json!({
        "name": "glass",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_ior": {"ior": 1.5},
            "KHR_materials_volume": {"thicknessFactor": 0.7}
        }
    }));
    doc.extensions.extend(["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume"]);
    doc.mesh_node("sphere_chrome", &sphere([-0.45, 0.35, -0.35], 0.35, 48, 24, false), chrome);
    doc.mesh_node("sphere_glass", &sphere([0.45, 0.35, 0.3], 0.35, 48, 24, false), glass);
    doc
}

fn cornell_boxes() -> Doc {
    let mut doc = Doc::default();
    cornell_shell(&mut doc);
    let white = doc.material(diffuse("block_white", [0.75, 0.75, 0.75]));
    let blocks = merge(&[block(0.35, 0.35, 0.6, 0.6, 0.6, -0.3), block(-0.35, -0.3, 0.6, 1.2, 0.6, 0.3)]);
    doc.mesh_node("blocks", &blocks, white);
    doc
}

/// Closed sphere of radius 1 seen from its centre; albedo 0.8 and emission 1 on the
/// inside, so the radiance is Le / (1 - rho) = 5 everywhere and the irradiance 5 pi.
/// Flat-shaded: interpolated normals would bend the Lambertian lobe away from the
/// facets and lose about 1% of the energy, so the answer would no longer be exact.
fn furnace() -> Doc {
    let mut doc = Doc::default();
    let m = doc.material(lambertian(json!({
        "name": "furnace_wall",
        "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "emissiveFactor": [1.0, 1.0, 1.0]
    })));
    doc.flat_mesh_node("furnace_sphere", &sphere([0.0, 0.0, 0.0], 1.0, 32, 16, true), m);
    doc.camera([0.0f32, 0.0, 0.0], None, 1.2, 1.0);
    doc
}

/// A 4 m x 4 m floor (albedo 0.5) under a point light of 10 W/sr, 1 m above its
/// centre, seen from 3 m straight above: no surface sees another, so there is no
/// indirect light, and the floor's radiance is exactly rho/pi I cos(theta)/d^2.
// The camera's quaternion is written with the digits the committed file has.
#[allow(clippy::approx_constant)]
fn plane_point() -> Doc {
    let mut doc = Doc::default();
    let m = doc.material(diffuse("floor", [0.5, 0.5, 0.5]));
    doc.mesh_node("floor", &quad([-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0], [-2.0, 0.0, -2.0]), m);
    doc.point_light("bulb", 10.0, [0.0, 1.0, 0.0]);
    // Looking down -y: rotate -90 degrees about x (camera -z becomes -y).
    doc.camera([0.0, 3.0, 0.0], Some([-0.70710678, 0.0, 0.0, 0.70710678]), 1.0, 1.0);
    doc
}

/// An open cylinder of radius r from y0 to y1 around the vertical axis through
/// (cx, cz), `seg` quads round, normals outward.
fn cylinder(cx: f32, cz: f32, r: f32, y0: f32, y1: f32, seg: u32) -> Mesh {
    let mut m = Mesh { p: vec![], n: vec![], idx: vec![] };
    for i in 0..=seg {
        let phi = 2.0 * PI * i as f32 / seg as f32;
        let (s, c) = phi.sin_cos();
        m.p.extend([[cx + r * c, y0, cz - r * s], [cx + r * c, y1, cz - r * s]]);
        m.n.extend([[c, 0.0, -s], [c, 0.0, -s]]);
    }
    for i in 0..seg {
        let (a, b, c, d) = (2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1);
        m.idx.extend([a, b, c, a, c, d]);
    }
    m
}

/// The paper's caustic ring (McGuire and Luebke 2009, Figure 5): a polished metal
/// ring (an open cylinder, mirror on both sides) standing on a 3 m x 3 m floor
/// (albedo 0.75) under a point light low on the camera's side, so the far half of
/// the ring's inside focuses the light into a cardioid on the floor; seen from above
/// and in front.
fn caustic_ring() -> Doc {
    let mut doc = Doc::default();
    let floor = doc.material(diffuse("floor", [0.75, 0.75, 0.75]));
    let metal = doc.material(json!({
        "name": "ring_metal",
        "doubleSided": true,
        "pbrMetallicRoughness": {"baseColorFactor": [0.95, 0.9, 0.8, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.0}
    }));
    doc.mesh_node("floor", &quad([-1.5, 0.0, 1.5], [1.5, 0.0, 1.5], [1.5, 0.0, -1.5], [-1.5, 0.0, -1.5]), floor);
    doc.mesh_node("ring", &cylinder(0.0, 0.0, 0.5, 0.0, 0.2, 200), metal);
    doc.point_light("bulb", 3.0, [0.0, 0.5, 1.2]);
    // 1.5 m up and 1.3 m in front, looking down 50 degrees at the ring.
    doc.camera([0.0, 1.5, 1.3], Some([-0.4226183, 0.0, 0.0, 0.9063078]), 0.8, 1.0);
    doc
}

/// A scene of over 100,000 triangles for the image-space method's timings: the
/// Cornell box shell with twelve finely tessellated diffuse spheres in three rows.
fn cornell_dense() -> Doc {
    let mut doc = Doc::default();
    cornell_shell(&mut doc);
    let colours = [[0.8, 0.75, 0.7], [0.3, 0.6, 0.3], [0.7, 0.6, 0.2]];
    for (row, z) in [-0.55f32, 0.0, 0.55].into_iter().enumerate() {
        let m = doc.material(diffuse(&format!("spheres_{row}"), colours[row]));
        let balls: Vec<Mesh> =
            [-0.6f32, -0.2, 0.2, 0.6].iter().map(|&x| sphere([x, 0.18, z], 0.18, 96, 48, false)).collect();
        doc.mesh_node(&format!("spheres_{row}"), &merge(&balls), m);
    }
    doc
}

/// Texture coordinates of a mesh by projection along each vertex normal's dominant
/// axis (box mapping), `scale` texture repeats per metre.
fn box_uv(m: &Mesh, scale: f32) -> Vec<[f32; 2]> {
    m.p.iter()
        .zip(&m.n)
        .map(|(p, n)| {
            let a = n.map(f32::abs);
            let (u, v) = if a[0] >= a[1] && a[0] >= a[2] {
                (p[2] * n[0].signum(), p[1])
            } else if a[1] >= a[2] {
                (p[0], p[2] * n[1].signum())
            } else {
                (-p[0] * n[2].signum(), p[1])
            };
            [u * scale, 1.0 - v * scale]
        })
        .collect()
}

/// Every material feature the loader reads, in one Cornell box (issue 14): a block
/// with a base-colour checker moved by KHR_texture_transform, a metallicRoughness
/// texture (smooth-metal and rough-dielectric stripes) and a normal texture (bumps
/// up to 20 degrees, MikkTSpace tangents); a block with COLOR_0 vertex colours and
/// KHR_materials_specular (tinted F0, a specular texture on TEXCOORD_1); a sphere of
/// absorbing glass (KHR_materials_volume attenuation); a leaf cut out by alpha MASK;
/// a veil of alpha BLEND; a sheet with partial transmission (0.5); and a panel with
/// an emissive texture on the left wall. The walls are Lambertian.
fn materials() -> Doc {
    let mut doc = Doc::default();
    cornell_shell(&mut doc);
    let (repeat, clamp) = (10497u32, 33071u32);
    // A deterministic pseudo-random stream for the texture patterns.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let checker = doc.texture(
        8,
        8,
        (0..64).map(|i| if (i % 8 + i / 8) % 2 == 0 { [230, 200, 150, 255] } else { [90, 120, 170, 255] }).collect(),
        [repeat, repeat],
    );
    let stripes = doc.texture(
        8,
        1,
        (0..8).map(|i| if i % 2 == 0 { [0, 40, 255, 255] } else { [0, 230, 0, 255] }).collect(),
        [repeat, repeat],
    );
    let bumps = doc.texture(
        16,
        16,
        (0..256)
            .map(|_| {
                let (tilt, turn) = (rnd().sqrt() * 20f32.to_radians(), rnd() * 2.0 * PI);
                let n = [tilt.sin() * turn.cos(), tilt.sin() * turn.sin(), tilt.cos()];
                let c = |x: f32| ((x * 0.5 + 0.5) * 255.0).round() as u8;
                [c(n[0]), c(n[1]), c(n[2]), 255]
            })
            .collect(),
        [repeat, repeat],
    );
    let leaf_alpha = doc.texture(
        16,
        16,
        (0..256)
            .map(|i| {
                let (x, y) = ((i % 16) as f32 / 7.5 - 1.0, (i / 16) as f32 / 7.5 - 1.0);
                let inside = x * x + y * y < 0.9 && (x * 3.0).sin().abs() > 0.3;
                [80, 170, 60, if inside { 255 } else { 0 }]
            })
            .collect(),
        [clamp, clamp],
    );
    let glow = doc.texture(
        4,
        1,
        vec![[255, 230, 190, 255], [40, 30, 20, 255], [255, 200, 120, 255], [0, 0, 0, 255]],
        [repeat, repeat],
    );
    let spec = doc.texture(
        4,
        4,
        (0..16).map(|i| [255, 255, 255, if i % 3 == 0 { 64 } else { 255 }]).collect(),
        [repeat, repeat],
    );
    let tex = |index: usize| json!({"index": index});

    let textured = doc.material(json!({
        "name": "textured",
        "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 1.0, "roughnessFactor": 1.0,
            "baseColorTexture": {"index": checker, "extensions": {"KHR_texture_transform": {"scale": [2.0, 2.0], "offset": [0.1, 0.0]}}},
            "metallicRoughnessTexture": tex(stripes)
        },
        "normalTexture": {"index": bumps, "scale": 1.0}
    }));
    doc.extensions.push("KHR_texture_transform");
    let block_a = block(-0.45, -0.35, 0.5, 0.6, 0.5, 0.4);
    let attrs = Attrs { uv: box_uv(&block_a, 1.5), ..Default::default() };
    doc.mesh_node_attrs("textured_block", &block_a, &attrs, textured);

    let coloured = doc.material(json!({
        "name": "vertex_coloured",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.3},
        "extensions": {"KHR_materials_specular": {
            "specularFactor": 1.0, "specularColorFactor": [1.0, 0.6, 0.3],
            "specularTexture": {"index": spec, "texCoord": 1}
        }}
    }));
    let block_b = block(0.5, -0.5, 0.4, 0.9, 0.4, -0.3);
    let attrs = Attrs {
        uv: box_uv(&block_b, 1.0),
        uv1: box_uv(&block_b, 3.0),
        color: block_b.p.iter().map(|p| [0.3 + 0.5 * p[1] / 0.9, 0.4 + 0.4 * (p[0] - 0.3) / 0.4, 0.6, 1.0]).collect(),
    };
    doc.mesh_node_attrs("coloured_block", &block_b, &attrs, coloured);

    let tinted_glass = doc.material(json!({
        "name": "absorbing_glass",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_ior": {"ior": 1.5},
            "KHR_materials_volume": {"thicknessFactor": 0.5, "attenuationColor": [0.9, 0.6, 0.3], "attenuationDistance": 0.3}
        }
    }));
    doc.mesh_node("glass_sphere", &sphere([0.35, 0.25, 0.35], 0.25, 32, 16, false), tinted_glass);

    let leaf = doc.material(json!({
        "name": "leaf", "doubleSided": true, "alphaMode": "MASK", "alphaCutoff": 0.5,
        "pbrMetallicRoughness": {"baseColorTexture": tex(leaf_alpha), "metallicFactor": 0.0, "roughnessFactor": 0.8}
    }));
    let leaf_quad = quad([-0.9, 0.05, 0.45], [-0.3, 0.05, 0.45], [-0.3, 0.65, 0.45], [-0.9, 0.65, 0.45]);
    let attrs = Attrs { uv: vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]], ..Default::default() };
    doc.mesh_node_attrs("leaf", &leaf_quad, &attrs, leaf);

    let veil = doc.material(lambertian(json!({
        "name": "veil", "doubleSided": true, "alphaMode": "BLEND",
        "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.5, 0.9, 0.4], "metallicFactor": 0.0, "roughnessFactor": 1.0}
    })));
    doc.mesh_node("veil", &quad([0.05, 0.95, -0.7], [0.9, 0.95, -0.7], [0.9, 1.6, -0.7], [0.05, 1.6, -0.7]), veil);

    let sheet = doc.material(json!({
        "name": "half_transmissive", "doubleSided": true,
        "pbrMetallicRoughness": {"baseColorFactor": [0.95, 0.9, 0.85, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.2},
        "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.5}}
    }));
    doc.mesh_node("sheet", &quad([-0.25, 0.0, 0.75], [0.1, 0.0, 0.75], [0.1, 0.45, 0.75], [-0.25, 0.45, 0.75]), sheet);

    let panel = doc.material(lambertian(json!({
        "name": "glowing_panel",
        "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "emissiveFactor": [1.0, 1.0, 1.0],
        "emissiveTexture": tex(glow),
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}
    })));
    let panel_quad = quad([-0.995, 0.8, -0.2], [-0.995, 0.8, -0.6], [-0.995, 1.2, -0.6], [-0.995, 1.2, -0.2]);
    let attrs = Attrs { uv: vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]], ..Default::default() };
    doc.mesh_node_attrs("glowing_panel", &panel_quad, &attrs, panel);
    doc
}

/// A torus around the y axis through `c`: ring radius `big`, tube radius `small`,
/// `seg` x `rings` quads.
fn torus(c: [f32; 3], big: f32, small: f32, seg: u32, rings: u32) -> Mesh {
    let mut m = Mesh { p: vec![], n: vec![], idx: vec![] };
    for j in 0..=rings {
        let v = 2.0 * PI * j as f32 / rings as f32;
        for i in 0..=seg {
            let u = 2.0 * PI * i as f32 / seg as f32;
            let n = [v.cos() * u.cos(), v.sin(), -v.cos() * u.sin()];
            let r = big + small * v.cos();
            m.p.push([c[0] + r * u.cos(), c[1] + small * v.sin(), c[2] - r * u.sin()]);
            m.n.push(n);
        }
    }
    let w = seg + 1;
    for j in 0..rings {
        for i in 0..seg {
            let (a, b, cc, d) = (j * w + i, j * w + i + 1, (j + 1) * w + i + 1, (j + 1) * w + i);
            m.idx.extend([a, b, cc, a, cc, d]);
        }
    }
    m
}

/// Texture coordinates of a UV sphere or torus from its vertex order: (i / seg,
/// j / rings) on its (seg + 1) x (rings + 1) grid, `repeat` times.
fn grid_uv(seg: u32, rings: u32, repeat: f32) -> Vec<[f32; 2]> {
    (0..=rings)
        .flat_map(|j| (0..=seg).map(move |i| [repeat * i as f32 / seg as f32, repeat * j as f32 / rings as f32]))
        .collect()
}

/// A scene of input at scale (issue 14, section 4): 1.36 million triangles from
/// three textured, normal-mapped meshes (a sphere, a torus and a lumpy rock of
/// 9-24k triangles each) instanced 100 times by nodes on a 10 x 10 grid, on a
/// textured floor under a sun and a point light. The file stores each mesh once.
fn instanced() -> Doc {
    let mut doc = Doc::default();
    let repeat = 10497u32;
    let checker = doc.texture(
        16,
        16,
        (0..256)
            .map(|i| if (i % 16 / 4 + i / 64) % 2 == 0 { [220, 210, 190, 255] } else { [120, 90, 70, 255] })
            .collect(),
        [repeat, repeat],
    );
    let bumps = doc.texture(
        32,
        32,
        (0..1024)
            .map(|i| {
                let (x, y) = ((i % 32) as f32 / 32.0 * 2.0 * PI, (i / 32) as f32 / 32.0 * 2.0 * PI);
                let n = [0.25 * x.sin(), 0.25 * y.cos(), 1.0];
                let l = (n[0] * n[0] + n[1] * n[1] + 1.0f32).sqrt();
                let c = |v: f32| ((v / l * 0.5 + 0.5) * 255.0).round() as u8;
                [c(n[0]), c(n[1]), c(n[2]), 255]
            })
            .collect(),
        [repeat, repeat],
    );
    let tex = |i: usize| json!({"index": i});
    let floor = doc.material(json!({"name": "floor", "pbrMetallicRoughness": {
        "baseColorTexture": tex(checker), "metallicFactor": 0.0, "roughnessFactor": 0.9}}));
    let (l, y) = (11.0f32, 0.0f32);
    let floor_quad = quad([-l, y, l], [l, y, l], [l, y, -l], [-l, y, -l]);
    let attrs = Attrs { uv: vec![[0.0, 0.0], [8.0, 0.0], [8.0, 8.0], [0.0, 8.0]], ..Default::default() };
    doc.mesh_node_attrs("floor", &floor_quad, &attrs, floor);
    let colours = [[0.8, 0.3, 0.2], [0.3, 0.6, 0.8], [0.6, 0.6, 0.55]];
    let kinds: Vec<(String, Mesh, Vec<[f32; 2]>, f32)> = vec![
        ("ball".into(), sphere([0.0, 0.4, 0.0], 0.4, 96, 48, false), grid_uv(96, 48, 4.0), 0.0),
        ("ring".into(), torus([0.0, 0.25, 0.0], 0.35, 0.15, 120, 48), grid_uv(120, 48, 6.0), 1.0),
        (
            "rock".into(),
            {
                let mut m = sphere([0.0, 0.35, 0.0], 0.35, 160, 80, false);
                for (p, n) in m.p.iter_mut().zip(&m.n) {
                    let bump = 0.04 * ((7.0 * n[0]).sin() * (5.0 * n[1]).cos() + (9.0 * n[2]).sin());
                    for k in 0..3 {
                        p[k] += bump * n[k];
                    }
                }
                m
            },
            grid_uv(160, 80, 5.0),
            0.0,
        ),
    ];
    let mut meshes = vec![];
    for (k, (name, mesh, uv, metallic)) in kinds.into_iter().enumerate() {
        let c = colours[k];
        let m = doc.material(json!({"name": name, "pbrMetallicRoughness": {
            "baseColorFactor": [c[0], c[1], c[2], 1.0], "baseColorTexture": tex(checker),
            "metallicFactor": metallic, "roughnessFactor": 0.4}, "normalTexture": tex(bumps)}));
        meshes.push(doc.mesh_attrs(&name, &mesh, &Attrs { uv, ..Default::default() }, m));
    }
    for j in 0..10 {
        for i in 0..10 {
            let k = (i * 7 + j * 3) % 3;
            let turn = 0.37 * (i * 10 + j) as f32;
            let (s, c) = (0.5 * turn).sin_cos();
            doc.nodes.push(json!({
                "name": format!("instance_{i}_{j}"),
                "mesh": meshes[k],
                "translation": [2.0 * i as f32 - 9.0, 0.0, 2.0 * j as f32 - 9.0],
                "rotation": [0.0, s, 0.0, c],
            }));
        }
    }
    doc.point_light("lamp", 40.0, [0.0, 4.0, 2.0]);
    // A sun from the upper left: a directional light turned about x and y.
    doc.lights.push(json!({"name": "sun", "type": "directional", "intensity": 2000.0}));
    let light = doc.lights.len() - 1;
    doc.nodes.push(json!({"name": "sun", "rotation": [-0.4082483, 0.4082483, 0.0, 0.8164966],
        "extensions": {"KHR_lights_punctual": {"light": light}}}));
    doc.camera([0.0f32, 9.0, 16.0], Some([-0.2588190, 0.0, 0.0, 0.9659258]), 0.9, 1.0);
    doc
}

/// An axis-aligned quad split into n x n quads (for scenes of a given surface count).
fn grid_quad(a: [f32; 3], b: [f32; 3], c: [f32; 3], d: [f32; 3], n: usize) -> Mesh {
    let at = |u: f32, v: f32| {
        let lerp = |p: [f32; 3], q: [f32; 3], t: f32| {
            [p[0] + (q[0] - p[0]) * t, p[1] + (q[1] - p[1]) * t, p[2] + (q[2] - p[2]) * t]
        };
        lerp(lerp(a, b, u), lerp(d, c, u), v)
    };
    let mut parts = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let (u0, u1, v0, v1) =
                (i as f32 / n as f32, (i + 1) as f32 / n as f32, j as f32 / n as f32, (j + 1) as f32 / n as f32);
            parts.push(quad(at(u0, v0), at(u1, v0), at(u1, v1), at(u0, v1)));
        }
    }
    merge(&parts)
}

/// Jozwowski 2002's test scene (Figure 28): a room with two smaller boxes and a point
/// light circling the room (a glTF animation, 8 s per turn, looping). The room is
/// [-2, 2] x [0, 2.5] x [-2, 2] m with a red left and a green right wall; at
/// `n` = 1 it has 16 surfaces (6 room faces and 5 faces per box), and every face is
/// split into n x n quads, so the scene has 16 n^2 surfaces.
fn jozwowski_room(n: usize) -> Doc {
    let mut doc = Doc::default();
    let white = doc.material(diffuse("white", [0.75, 0.75, 0.75]));
    let red = doc.material(diffuse("red", [0.75, 0.15, 0.12]));
    let green = doc.material(diffuse("green", [0.15, 0.6, 0.15]));
    let boxes = doc.material(diffuse("box", [0.7, 0.65, 0.5]));
    let (l, h) = (2.0, 2.5);
    let room = merge(&[
        grid_quad([-l, 0.0, l], [l, 0.0, l], [l, 0.0, -l], [-l, 0.0, -l], n), // floor, +y
        grid_quad([-l, h, -l], [l, h, -l], [l, h, l], [-l, h, l], n),         // ceiling, -y
        grid_quad([-l, 0.0, -l], [l, 0.0, -l], [l, h, -l], [-l, h, -l], n),   // back, +z
        grid_quad([-l, 0.0, l], [-l, h, l], [l, h, l], [l, 0.0, l], n),       // front, -z
    ]);
    doc.mesh_node("room", &room, white);
    doc.mesh_node("left_wall", &grid_quad([-l, 0.0, l], [-l, 0.0, -l], [-l, h, -l], [-l, h, l], n), red);
    doc.mesh_node("right_wall", &grid_quad([l, 0.0, -l], [l, 0.0, l], [l, h, l], [l, h, -l], n), green);
    // Two boxes: each face of `block` split n x n.
    let split = |m: Mesh| {
        let quads: Vec<Mesh> = m
            .idx
            .chunks(6)
            .map(|q| grid_quad(m.p[q[0] as usize], m.p[q[1] as usize], m.p[q[2] as usize], m.p[q[5] as usize], n))
            .collect();
        merge(&quads)
    };
    doc.mesh_node(
        "boxes",
        &merge(&[split(block(-0.8, -0.5, 0.8, 0.8, 0.8, 0.4)), split(block(1.0, -0.8, 0.7, 1.4, 0.7, -0.3))]),
        boxes,
    );
    let light_node = doc.point_light("bulb", 6.0, [1.2, 2.0, 0.0]);
    // The light's path: 33 keys around a circle of radius 1.2 m at 2 m height, linear
    // between them, 8 s per turn.
    let keys = 32;
    let times: Vec<f32> = (0..=keys).map(|k| 8.0 * k as f32 / keys as f32).collect();
    let path: Vec<[f32; 3]> = (0..=keys)
        .map(|k| {
            let a = 2.0 * PI * k as f32 / keys as f32;
            [1.2 * a.cos(), 2.0, 1.2 * a.sin()]
        })
        .collect();
    let (input, output) = doc.animation_accessors(&times, &path);
    doc.animations.push(json!({
        "name": "light_circle",
        "samplers": [{"input": input, "output": output, "interpolation": "LINEAR"}],
        "channels": [{"sampler": 0, "target": {"node": light_node, "path": "translation"}}]
    }));
    // At the front, 1.4 m up, looking toward the back wall and slightly down.
    doc.camera([0.0, 1.4, 1.9], Some([-0.0871557, 0.0, 0.0, 0.9961947]), 1.3, 1.0);
    doc
}

/// Write (or with `check`, compare) every scene.
pub fn run(dir: &Path, check: bool) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    for (name, doc) in [
        ("cornell_spheres", cornell_spheres()),
        ("cornell_boxes", cornell_boxes()),
        ("furnace", furnace()),
        ("plane_point", plane_point()),
        ("caustic_ring", caustic_ring()),
        ("cornell_dense", cornell_dense()),
        ("materials", materials()),
        ("instanced", instanced()),
        ("jozwowski_room_16", jozwowski_room(1)),
        ("jozwowski_room_64", jozwowski_room(2)),
        ("jozwowski_room_256", jozwowski_room(4)),
        ("jozwowski_room_1024", jozwowski_room(8)),
        ("jozwowski_room_4096", jozwowski_room(16)),
    ] {
        doc.write(dir, name, check)?;
        println!("{} {name}", if check { "up to date:" } else { "wrote" });
    }
    Ok(())
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn normalize(a: [f32; 3]) -> [f32; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}
