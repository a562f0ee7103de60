//! Scenes no one tuned for: a seeded generator of glTF scenes composed from what
//! users' scenes contain and what breaks renderers (issue 53), for the
//! differential checks (`cargo xtask differential`). Scene `index` of seed `seed`
//! is the same file on every machine; its [`Recipe`] says what was chosen.
//!
//! A scene is a room (closed, or open to a sun when its ceiling is left out) with
//! walls of random colours, one to four objects (boxes, spheres, thin closed
//! slabs, some standing nearly touching a wall or another object: gaps from 0.1 mm
//! to 5 cm) of diffuse, mirror, glass or rough metal, one or two lights (one- or
//! two-sided area lights, some close to a surface; point, spot, sun), sometimes an
//! index-matched box of fog (inset, touching or crossing the walls), a root
//! node that scales the whole by 1e-3 to 1e4 and moves it up to 1e6 m away, and
//! in two scenes of five Blender's layered materials (issue 54: the rough metal
//! brushed, diffuse objects clear-coated or velvet), drawn from a stream of their
//! own so the rest of every scene is what it was before they were added.

use crate::gltf::Doc;
use crate::scenes::{block, chrome_and_glass, diffuse, emitter, fog_box, merge, quad, sphere};
use serde::Serialize;
use serde_json::json;
use std::f64::consts::FRAC_1_SQRT_2;

/// What a generated scene holds, written beside it as JSON.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Recipe {
    /// The generator's seed.
    pub seed: u64,
    /// The scene's index.
    pub index: u32,
    /// "closed" or "open" (no ceiling; a sun).
    pub room: String,
    /// The objects: kind, material, and the gap to what it stands beside \[m\].
    pub objects: Vec<String>,
    /// The lights: kind and where.
    pub lights: Vec<String>,
    /// The fog box, if any: where it sits and its extinction [m^-1].
    pub fog: Option<String>,
    /// Clear coats, sheen and anisotropy given to its materials (issue 54).
    pub layers: Vec<String>,
    /// The root node's uniform scale.
    pub scale: f64,
    /// The root node's translation \[m\].
    pub offset: [f64; 3],
}

/// A small deterministic generator (splitmix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn f(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f()
    }

    /// True with probability p.
    fn chance(&mut self, p: f32) -> bool {
        self.f() < p
    }
}

/// Scene `index` of the scenes of `seed`, and what it holds.
pub fn scene(seed: u64, index: u32) -> (Doc, Recipe) {
    let key = seed.wrapping_mul(0x2545_f491_4f6c_dd1d) ^ (index as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    let mut r = Rng(key);
    let mut doc = Doc::default();
    let mut recipe = Recipe { seed, index, ..Default::default() };
    let open = r.chance(0.25);
    recipe.room = if open { "open" } else { "closed" }.into();
    room(&mut doc, &mut r, open);
    let (chrome, glass) = chrome_and_glass(&mut doc, 0.5);
    let metal = doc.material(json!({"name": "rough_metal", "pbrMetallicRoughness": {
        "baseColorFactor": [0.9, 0.7, 0.5, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.35}}));
    let n_objects = 1 + (r.next() % 4) as usize;
    for k in 0..n_objects {
        recipe.objects.push(object(&mut doc, &mut r, k, [chrome, glass, metal]));
    }
    recipe.lights = lights(&mut doc, &mut r, open);
    if r.chance(0.25) {
        recipe.fog = Some(fog(&mut doc, &mut r));
    }
    let look = [0.0f32, 1.0, 3.6];
    doc.camera(look, None, 0.75, 1.0);
    // The whole scene under a root that scales and moves it (media keep scale 1:
    // their coefficients are per metre of the file).
    recipe.scale = if recipe.fog.is_none() && r.chance(0.3) { 10f64.powf(r.range(-3.0, 4.0) as f64) } else { 1.0 };
    recipe.offset = if r.chance(0.3) {
        let far = 10f64.powf(r.range(0.0, 6.0) as f64);
        [far * r.range(-1.0, 1.0) as f64, far * r.range(-1.0, 1.0) as f64, far * r.range(-1.0, 1.0) as f64]
    } else {
        [0.0; 3]
    };
    if recipe.scale != 1.0 || recipe.offset != [0.0; 3] {
        let scale = [recipe.scale; 3];
        doc.root = Some(json!({"name": "root", "translation": recipe.offset, "scale": scale}));
    }
    // Blender's layered materials, from a stream of their own so that every
    // other choice of the scene is what it was before they were added.
    let mut rl = Rng(key ^ 0x1a7e_12ed_c0a7_5eed);
    if rl.chance(0.4) {
        recipe.layers = layers(&mut doc, &mut rl);
    }
    (doc, recipe)
}

/// Clear coats, sheen, anisotropy and thin films (KHR_materials_clearcoat,
/// _sheen, _anisotropy, _iridescence) on the scene's objects: the rough metal
/// brushed (its direction whatever the surface's frame is: the generated meshes
/// have no texture coordinates), each diffuse object coated or velvet half the
/// time, then the rough metal under a thin film half the time (drawn last, so
/// that the other layers are what they were before films were added).
fn layers(doc: &mut Doc, r: &mut Rng) -> Vec<String> {
    let mut out = Vec::new();
    for i in 0..doc.materials.len() {
        let name = doc.materials[i]["name"].as_str().unwrap_or("").to_owned();
        let ext = if name == "rough_metal" {
            let (s, rot) = (r.range(0.3, 0.9), r.range(0.0, std::f32::consts::PI));
            out.push(format!("{name}: anisotropy {s:.2} at {rot:.2} rad"));
            ("KHR_materials_anisotropy", json!({"anisotropyStrength": s, "anisotropyRotation": rot}))
        } else if name.starts_with("object_") && r.chance(0.5) {
            if r.chance(0.5) {
                let (c, rough) = (r.range(0.5, 1.0), r.range(0.0, 0.3));
                out.push(format!("{name}: clear coat {c:.2}, roughness {rough:.2}"));
                ("KHR_materials_clearcoat", json!({"clearcoatFactor": c, "clearcoatRoughnessFactor": rough}))
            } else {
                let (c, rough) = ([r.range(0.3, 1.0), r.range(0.3, 1.0), r.range(0.3, 1.0)], r.range(0.3, 0.8));
                out.push(format!("{name}: sheen {c:.2?}, roughness {rough:.2}"));
                ("KHR_materials_sheen", json!({"sheenColorFactor": c, "sheenRoughnessFactor": rough}))
            }
        } else {
            continue;
        };
        doc.materials[i]["extensions"][ext.0] = ext.1;
        doc.extensions.push(ext.0);
    }
    let metal = doc.materials.iter().position(|m| m["name"] == "rough_metal");
    if let Some(i) = metal
        && r.chance(0.5)
    {
        let (ior, d) = (r.range(1.2, 2.2), r.range(150.0, 700.0));
        out.push(format!("rough_metal: thin film of ior {ior:.2}, {d:.0} nm"));
        doc.materials[i]["extensions"]["KHR_materials_iridescence"] =
            json!({"iridescenceFactor": 1.0, "iridescenceIor": ior, "iridescenceThicknessMaximum": d});
        doc.extensions.push("KHR_materials_iridescence");
    }
    out
}

/// The room: a floor, back and side walls of random colours, and a ceiling unless
/// `open`. Interior [-1, 1] x [0, 2] x [-1, 1] m; the front is open to the camera.
fn room(doc: &mut Doc, r: &mut Rng, open: bool) {
    let colour = |r: &mut Rng| [r.range(0.1, 0.85), r.range(0.1, 0.85), r.range(0.1, 0.85)];
    let (l, h) = (1.0, 2.0);
    let floor = doc.material(diffuse("floor", colour(r)));
    doc.mesh_node("floor", &quad([-l, 0.0, l], [l, 0.0, l], [l, 0.0, -l], [-l, 0.0, -l]), floor);
    let back = doc.material(diffuse("back", colour(r)));
    doc.mesh_node("back_wall", &quad([-l, 0.0, -l], [l, 0.0, -l], [l, h, -l], [-l, h, -l]), back);
    let left = doc.material(diffuse("left", colour(r)));
    doc.mesh_node("left_wall", &quad([-l, 0.0, l], [-l, 0.0, -l], [-l, h, -l], [-l, h, l]), left);
    let right = doc.material(diffuse("right", colour(r)));
    doc.mesh_node("right_wall", &quad([l, 0.0, -l], [l, 0.0, l], [l, h, l], [l, h, -l]), right);
    if !open {
        let ceiling = doc.material(diffuse("ceiling", colour(r)));
        doc.mesh_node("ceiling", &quad([-l, h, -l], [l, h, -l], [l, h, l], [-l, h, l]), ceiling);
    }
}

/// Object `k`: a box, a sphere or a thin closed slab of a random material,
/// sometimes standing a small gap from the back wall.
fn object(doc: &mut Doc, r: &mut Rng, k: usize, [chrome, glass, metal]: [usize; 3]) -> String {
    let (material, what) = match r.next() % 4 {
        0 => (chrome, "mirror"),
        1 => (glass, "glass"),
        2 => (metal, "rough metal"),
        _ => {
            let c = [r.range(0.1, 0.9), r.range(0.1, 0.9), r.range(0.1, 0.9)];
            (doc.material(diffuse(&format!("object_{k}"), c)), "diffuse")
        }
    };
    let size = r.range(0.2, 0.6);
    let (x, mut z) = (r.range(-0.6, 0.6), r.range(-0.5, 0.5));
    // A gap of 0.1 mm to 5 cm to the back wall, for a third of them.
    let gap = r.chance(0.33).then(|| 10f32.powf(r.range(-4.0, -1.3)));
    if let Some(g) = gap {
        z = -1.0 + g + size / 2.0;
    }
    let name = format!("object_{k}");
    let kind = match r.next() % 3 {
        0 => {
            doc.mesh_node(&name, &block(x, z, size, size * r.range(0.5, 2.0), size, r.range(0.0, 1.5)), material);
            "box"
        }
        1 => {
            let rad = size / 2.0;
            doc.mesh_node(&name, &sphere([x, rad + r.range(0.0, 0.3), z], rad, 32, 16, false), material);
            "sphere"
        }
        _ => {
            // A thin closed slab lying on supports: top, sides and bottom.
            let (t, y) = (r.range(0.004, 0.03), r.range(0.2, 1.2));
            let h = size / 2.0;
            let mut slab = block(x, z, size, t, size, 0.0);
            slab = merge(&[
                slab,
                quad([x - h, 0.0, z - h], [x + h, 0.0, z - h], [x + h, 0.0, z + h], [x - h, 0.0, z + h]),
            ]);
            for q in &mut slab.p {
                q[1] += y;
            }
            doc.mesh_node(&name, &slab, material);
            "slab"
        }
    };
    match gap {
        Some(g) => format!("{what} {kind} {g:.5} m from the back wall"),
        None => format!("{what} {kind}"),
    }
}

/// One or two lights: an area light on the ceiling (one- or two-sided, some a
/// few millimetres below it; two times in three), a point or a spot light, and a
/// sun in an open room.
fn lights(doc: &mut Doc, r: &mut Rng, open: bool) -> Vec<String> {
    let mut out = Vec::new();
    let n = 1 + (r.next() % 2) as usize;
    for k in 0..n {
        // Area lights half the time: a light of no size seen through a mirror or
        // glass is beyond the path tracer the checks compare with.
        let choice = if open && k == 0 { 3 } else { [0, 0, 0, 1, 2, 0][(r.next() % 6) as usize] };
        let name = format!("light_{k}");
        match choice {
            0 => {
                let s = r.range(0.1, 0.4);
                let y = 2.0 - 10f32.powf(r.range(-3.0, -1.0));
                let two_sided = r.chance(0.3);
                let strength = r.range(5.0, 20.0) as f64;
                let m = emitter(doc, &name, strength);
                if two_sided {
                    doc.materials[m]["doubleSided"] = json!(true);
                }
                let (cx, cz) = (r.range(-0.5, 0.5), r.range(-0.5, 0.5));
                doc.mesh_node(
                    &name,
                    &quad([cx - s, y, cz - s], [cx + s, y, cz - s], [cx + s, y, cz + s], [cx - s, y, cz + s]),
                    m,
                );
                out.push(format!(
                    "area {:.2} m, {} m below the ceiling{}",
                    2.0 * s,
                    2.0 - y,
                    if two_sided { ", two-sided" } else { "" }
                ));
            }
            1 => {
                let at = [r.range(-0.7, 0.7) as f64, r.range(0.8, 1.9) as f64, r.range(-0.7, 0.7) as f64];
                doc.point_light(&name, r.range(0.5, 3.0) as f64, at);
                out.push(format!("point at {at:?}"));
            }
            2 => {
                let at = [r.range(-0.5, 0.5) as f64, 1.95, r.range(-0.5, 0.5) as f64];
                let candela = r.range(1.0, 5.0) as f64 * pm_scene::LUMINOUS_EFFICACY as f64;
                let outer = r.range(0.3, 1.0) as f64;
                doc.lights.push(json!({"name": name, "type": "spot", "intensity": candela, "color": [1.0, 1.0, 1.0],
                    "spot": {"innerConeAngle": outer * 0.6, "outerConeAngle": outer}}));
                let light = doc.lights.len() - 1;
                // Pointing down: -z turned to -y.
                doc.nodes.push(
                    json!({"name": name, "translation": at, "rotation": [-FRAC_1_SQRT_2, 0.0, 0.0, FRAC_1_SQRT_2],
                    "extensions": {"KHR_lights_punctual": {"light": light}}}),
                );
                out.push(format!("spot at {at:?}, outer cone {outer:.2} rad"));
            }
            _ => {
                let lux = r.range(2.0, 8.0) as f64 * pm_scene::LUMINOUS_EFFICACY as f64;
                doc.lights
                    .push(json!({"name": name, "type": "directional", "intensity": lux, "color": [1.0, 0.95, 0.9]}));
                let light = doc.lights.len() - 1;
                // Tilted from straight down by up to 40 degrees about x.
                let a = r.range(0.0, 0.7) / 2.0;
                let (s, c) =
                    ((-std::f32::consts::FRAC_PI_4 - a).sin() as f64, (-std::f32::consts::FRAC_PI_4 - a).cos() as f64);
                doc.nodes.push(json!({"name": name, "rotation": [s, 0.0, 0.0, c],
                    "extensions": {"KHR_lights_punctual": {"light": light}}}));
                out.push(format!("sun {:.0} degrees from the zenith", (2.0 * a).to_degrees()));
            }
        }
    }
    out
}

/// An index-matched box of fog: inset in the room, touching its floor, or
/// crossing its side wall.
fn fog(doc: &mut Doc, r: &mut Rng) -> String {
    let colour = r.range(0.05, 0.8) as f64;
    let albedo = r.range(0.3, 0.95) as f64;
    let g = r.range(-0.3, 0.6) as f64;
    let (lo, hi, where_) = match r.next() % 3 {
        0 => ([-0.998, 0.002, -0.998], [0.998, r.range(0.2, 1.0), 0.998], "inset 2 mm"),
        1 => ([-0.8, 0.0, -0.8], [0.8, r.range(0.2, 1.0), 0.8], "on the floor"),
        _ => ([0.2, 0.0, -0.6], [1.3, r.range(0.3, 1.5), 0.6], "crossing the right wall"),
    };
    fog_box(doc, lo, hi, colour, albedo, g);
    format!("{where_}, extinction {:.2} / m, albedo {albedo:.2}, g {g:.2}", -colour.ln())
}

/// Write scenes 0..n of `seed` to `dir` as `scene-NNN.gltf` (with `.bin` and
/// `.json`, its recipe).
pub fn write(dir: &std::path::Path, seed: u64, n: u32) -> anyhow::Result<Vec<(std::path::PathBuf, Recipe)>> {
    std::fs::create_dir_all(dir)?;
    let mut out = Vec::new();
    for i in 0..n {
        let (doc, recipe) = scene(seed, i);
        let name = format!("scene-{i:03}");
        doc.write(dir, &name, false)?;
        std::fs::write(dir.join(format!("{name}.json")), serde_json::to_string_pretty(&recipe)? + "\n")?;
        out.push((dir.join(format!("{name}.gltf")), recipe));
    }
    Ok(out)
}
