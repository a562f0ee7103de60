//! The project's test scenes, generated from code so they are reproducible, and
//! written as plain glTF 2.0 (JSON + external .bin) that any viewer opens.

use crate::gltf::{Attrs, Doc, Mesh};
use anyhow::Result;
use serde_json::{Value, json};
use std::f32::consts::PI;
use std::path::Path;

/// An axis-aligned quad with corners a, b, c, d in counter-clockwise order as seen
/// from the side its normal points to.
pub(crate) fn quad(a: [f32; 3], b: [f32; 3], c: [f32; 3], d: [f32; 3]) -> Mesh {
    let e1 = sub(b, a);
    let e2 = sub(d, a);
    let n = normalize(cross(e1, e2));
    Mesh { p: vec![a, b, c, d], n: vec![n; 4], idx: vec![0, 1, 2, 0, 2, 3] }
}

/// Several quads as one mesh.
pub(crate) fn merge(parts: &[Mesh]) -> Mesh {
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
pub(crate) fn sphere(c: [f32; 3], r: f32, seg: u32, rings: u32, inward: bool) -> Mesh {
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
pub(crate) fn block(cx: f32, cz: f32, sx: f32, sy: f32, sz: f32, angle: f32) -> Mesh {
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
pub(crate) fn diffuse(name: &str, rgb: [f32; 3]) -> Value {
    lambertian(
        json!({"name": name, "pbrMetallicRoughness": {"baseColorFactor": [rgb[0], rgb[1], rgb[2], 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}),
    )
}

/// Material `m` with its dielectric specular layer turned off.
pub(crate) fn lambertian(mut m: Value) -> Value {
    m["extensions"]["KHR_materials_specular"] = json!({"specularFactor": 0.0});
    m
}

/// A white-emitting Lambertian material (albedo 0.8) of radiance `strength`
/// [W sr^-1 m^-2 per channel], through KHR_materials_emissive_strength.
pub(crate) fn emitter(doc: &mut Doc, name: &str, strength: f64) -> usize {
    let m = doc.material(lambertian(json!({
        "name": name,
        "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "emissiveFactor": [1.0, 1.0, 1.0],
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}
    })));
    doc.extensions.push("KHR_materials_emissive_strength");
    m
}

/// The Cornell box shell: floor, ceiling, back, left (red), right (blue), and a square
/// ceiling light of side 0.5 m. Box interior [-1,1] x [0,2] x [-1,1] metres; the light
/// has radiance 12 W sr^-1 m^-2 (power pi * 12 * 0.25 = 9.4 W per channel).
fn cornell_shell(doc: &mut Doc) {
    let white = doc.material(diffuse("white", [0.75, 0.75, 0.75]));
    let red = doc.material(diffuse("red", [0.75, 0.15, 0.12]));
    let blue = doc.material(diffuse("blue", [0.12, 0.2, 0.75]));
    let light = emitter(doc, "ceiling_light", 12.0);
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

/// A chrome material (metal, roughness 0) and a solid glass one (ior 1.5,
/// KHR_materials_volume of `thickness`: without it glTF glass is thin-walled and
/// focuses nothing), as the spheres scenes use them.
pub(crate) fn chrome_and_glass(doc: &mut Doc, thickness: f64) -> (usize, usize) {
    let chrome = doc.material(json!({"name": "chrome", "pbrMetallicRoughness": {"baseColorFactor": [0.95, 0.95, 0.95, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.0}}));
    let glass = doc.material(json!({
        "name": "glass",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_ior": {"ior": 1.5},
            "KHR_materials_volume": {"thicknessFactor": thickness}
        }
    }));
    doc.extensions.extend(["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume"]);
    (chrome, glass)
}

fn cornell_spheres() -> Doc {
    let mut doc = Doc::default();
    cornell_shell(&mut doc);
    let (chrome, glass) = chrome_and_glass(&mut doc, 0.7);
    doc.mesh_node("sphere_chrome", &sphere([-0.45, 0.35, -0.35], 0.35, 48, 24, false), chrome);
    doc.mesh_node("sphere_glass", &sphere([0.45, 0.35, 0.3], 0.35, 48, 24, false), glass);
    doc
}

/// The Cornell box with its chrome and glass spheres, the ceiling light behind a
/// clear glass panel: a closed slab 6 mm thick (ior 1.5) 4 cm below the light
/// and 5 cm wider than it on each side. Every photon from the light crosses the
/// panel and a shadow ray cannot refract, so all the room's light is a caustic
/// (L S+ D); the effects analysis once found no caustics in it (issue 53).
fn cornell_glass_panel() -> Doc {
    let mut doc = cornell_spheres();
    let (_, glass) = chrome_and_glass(&mut doc, 0.006);
    let (half, bottom) = (0.30, 2.0 - 0.002 - 0.04 - 0.006);
    let mut slab = block(0.0, 0.0, 2.0 * half, 0.006, 2.0 * half, 0.0);
    slab = merge(&[slab, quad([-half, 0.0, -half], [half, 0.0, -half], [half, 0.0, half], [-half, 0.0, half])]);
    for q in &mut slab.p {
        q[1] += bottom;
    }
    doc.mesh_node("glass_panel", &slab, glass);
    doc
}

/// Light reaching the room only through glass, with a mirror and a glossy floor
/// (issue 56's scene for the bidirectional methods): cornell_glass_panel's ceiling
/// light behind its clear panel, the chrome and glass spheres, and the floor
/// covered 1 mm above it by a polished dielectric (roughness 0.2: GGX alpha 0.04)
/// that shows the light's caustic and the spheres in a blurred reflection. Every
/// direct path is a caustic (a shadow ray cannot refract), and the floor's
/// glossy reflection of it is what photon maps blur and path tracers miss.
fn glass_lit_room() -> Doc {
    let mut doc = cornell_glass_panel();
    let polished = doc.material(json!({"name": "polished_floor", "pbrMetallicRoughness": {
        "baseColorFactor": [0.6, 0.6, 0.6, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.2}}));
    let h = 0.999;
    doc.mesh_node("polished_floor", &quad([-h, 0.001, h], [h, 0.001, h], [h, 0.001, -h], [-h, 0.001, -h]), polished);
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

/// An index-matched box of fog (smooth transmission with ior 1, so rays pass its
/// walls without a bounce) from `lo` to `hi`: KHR_materials_volume's extinction
/// -ln(`colour`) / 1 m and the draft KHR_materials_volume_scatter's multiple-
/// scattering albedo `albedo` and anisotropy `g`.
pub(crate) fn fog_box(doc: &mut Doc, lo: [f32; 3], hi: [f32; 3], colour: f64, albedo: f64, g: f64) {
    let fog = doc.material(json!({
        "name": "fog",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_ior": {"ior": 1.0},
            "KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationDistance": 1.0,
                "attenuationColor": [colour, colour, colour]},
            "KHR_materials_volume_scatter": {"scatterAlbedo": [albedo, albedo, albedo], "scatterAnisotropy": g}
        }
    }));
    doc.extensions.extend([
        "KHR_materials_transmission",
        "KHR_materials_ior",
        "KHR_materials_volume",
        "KHR_materials_volume_scatter",
    ]);
    let (c, e) = ([(lo[0] + hi[0]) / 2.0, (lo[2] + hi[2]) / 2.0], [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]]);
    // A block has no bottom (it stands on a floor); the fog's box is closed.
    let (hx, hz) = (e[0] / 2.0, e[2] / 2.0);
    let bottom = quad(
        [c[0] - hx, 0.0, c[1] - hz],
        [c[0] + hx, 0.0, c[1] - hz],
        [c[0] + hx, 0.0, c[1] + hz],
        [c[0] - hx, 0.0, c[1] + hz],
    );
    let mut b = merge(&[block(c[0], c[1], e[0], e[1], e[2], 0.0), bottom]);
    for q in &mut b.p {
        q[1] += lo[1];
    }
    doc.mesh_node("fog_box", &b, fog);
}

/// The Cornell box with two blocks, its room filled with a box of fog just inside
/// the walls (sigma_t = -ln 0.72 = 0.33 / m, multiple-scattering albedo 0.7: a
/// single-scattering albedo of 0.976, g = 0.3); the light, the camera and the
/// walls are outside it.
fn cornell_fog() -> Doc {
    let mut doc = cornell_boxes();
    fog_box(&mut doc, [-0.999, 0.001, -0.999], [0.999, 1.997, 0.999], 0.72, 0.7, 0.3);
    doc
}

/// The Cornell box's shell with a glass sphere (radius 0.3 m, ior 1.5) above a box
/// of fog filling the lower 0.30 m of the room 2 mm inside its walls (the file's
/// medium is cornell_fog's; the regression test gives the material "fog" a dense
/// one, sigma_s 2.4 and sigma_a 0.6 per metre, g 0.3, through pipeline.toml's
/// [media.fog], as a user would): the batch pipeline's defaults once lost half of
/// the indirect light of such a box (issue 53).
fn cornell_fogbox() -> Doc {
    let mut doc = Doc::default();
    cornell_shell(&mut doc);
    let (_, glass) = chrome_and_glass(&mut doc, 0.7);
    doc.mesh_node("sphere_glass", &sphere([0.0, 0.7, 0.0], 0.3, 48, 24, false), glass);
    fog_box(&mut doc, [-0.998, 0.002, -0.998], [0.998, 0.30, 0.998], 0.72, 0.7, 0.3);
    doc
}

/// A volumetric caustic: a small bright square light 2.9 m above a glass sphere
/// (radius 0.5 m, ior 1.5) in a room-sized box of fog over a grey floor; the
/// sphere focuses the light into a cone of brighter fog below it (L S+ V paths,
/// which only photons carry: the light's single scattering cannot see through the
/// glass).
fn volumetric_caustic() -> Doc {
    let mut doc = Doc::default();
    let grey = doc.material(diffuse("floor", [0.5, 0.5, 0.5]));
    doc.mesh_node("floor", &quad([-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0], [-3.0, 0.0, -3.0]), grey);
    let light = emitter(&mut doc, "lamp", 200.0);
    let (s, y) = (0.15, 2.9);
    doc.mesh_node("lamp", &quad([-s, y, -s], [s, y, -s], [s, y, s], [-s, y, s]), light);
    let (_, glass) = chrome_and_glass(&mut doc, 1.0);
    doc.mesh_node("glass_sphere", &sphere([0.0, 1.6, 0.0], 0.5, 48, 24, false), glass);
    fog_box(&mut doc, [-2.5, 0.001, -2.5], [2.5, 2.8, 2.5], 0.85, 0.8, 0.0);
    doc.camera([0.0f32, 1.3, 5.0], None, 0.75, 1.0);
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

/// The thesis room without its light: [-2, 2] x [0, 2.5] x [-2, 2] m, white with
/// a red left and a green right wall, and two boxes, every face split into n x n
/// quads.
fn thesis_room(doc: &mut Doc, n: usize) {
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
}

/// Jozwowski 2002's test scene (Figure 28): a room with two smaller boxes and a point
/// light circling the room (a glTF animation, 8 s per turn, looping). The room is
/// [-2, 2] x [0, 2.5] x [-2, 2] m with a red left and a green right wall; at
/// `n` = 1 it has 16 surfaces (6 room faces and 5 faces per box), and every face is
/// split into n x n quads, so the scene has 16 n^2 surfaces.
fn jozwowski_room(n: usize) -> Doc {
    let mut doc = Doc::default();
    thesis_room(&mut doc, n);
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

/// Many lights (issue 55): the thesis room ([`thesis_room`]: [-2, 2] x [0, 2.5] x [-2, 2] m, red
/// left and green right wall, two boxes) lit by 48 small coloured point lamps in
/// a 6 x 8 grid 20 cm under the ceiling, of intensities 0.01-0.05 W/sr per
/// channel, and a glowing sphere (radius 0.15 m, radiance 4) on the floor: a
/// room a light tree is for, where choosing lights by power alone sends most
/// light samples to lamps far from the point being lit.
fn lamps_room() -> Doc {
    let mut doc = Doc::default();
    thesis_room(&mut doc, 1);
    let glow = emitter(&mut doc, "glow", 4.0);
    doc.mesh_node("glowing_sphere", &sphere([0.2, 0.15, 0.9], 0.15, 24, 12, false), glow);
    const COLOURS: [[f64; 3]; 6] =
        [[1.0, 0.55, 0.3], [0.35, 0.6, 1.0], [1.0, 0.9, 0.6], [0.5, 1.0, 0.5], [1.0, 0.4, 0.7], [0.9, 0.9, 0.9]];
    for i in 0..6 {
        for j in 0..8 {
            let k = i * 8 + j;
            let at = [-1.75 + 0.7 * i as f64, 2.3, -1.75 + 0.5 * j as f64];
            let w = 0.01 + 0.04 * ((k * 7) % 11) as f64 / 10.0;
            doc.coloured_point_light(&format!("lamp_{i}_{j}"), w, COLOURS[(i + j) % 6], at);
        }
    }
    doc.camera([0.0, 1.4, 1.9], Some([-0.0871557, 0.0, 0.0, 0.9961947]), 1.3, 1.0);
    doc
}

/// The memory benchmark's scenes (issue 36): the Cornell room with 100 unique
/// spheres (10 x 10 on the floor, each its own mesh, smooth normals) of `seg` x
/// `seg / 2` segments: seg = 100 makes 994,092 triangles, seg = 316 makes 9,954,212.
fn sphere_room(seg: u32) -> Doc {
    let mut doc = Doc::default();
    cornell_shell(&mut doc);
    let white = doc.material(diffuse("spheres", [0.7, 0.7, 0.7]));
    for k in 0..100u32 {
        let (i, j) = (k % 10, k / 10);
        let (x, z) = (-0.9 + 0.2 * i as f32, -0.9 + 0.2 * j as f32);
        // Slightly different radii, so no two meshes are the same.
        let r = 0.07 + 0.0002 * k as f32;
        doc.mesh_node(&format!("sphere_{k}"), &sphere([x, r, z], r, seg, seg / 2, false), white);
    }
    doc
}

/// Direction toward the sun of `sky()`: 40 degrees above the horizon, 30 degrees
/// from +X toward -Z (glTF axes, y up).
const SUN_ELEVATION_DEG: f32 = 40.0;
const SUN_AZIMUTH_DEG: f32 = -30.0;
/// The sun disc's angular radius in `sky()` \[degrees\] and its radiance
/// [W sr^-1 m^-2]: irradiance pi (1.5 deg)^2 x 1500 = 3.2 W m^-2 at normal
/// incidence, about three times the sky's on a horizontal surface.
const SUN_RADIUS_DEG: f32 = 1.5;
const SUN_RADIANCE: f32 = 1500.0;

/// The environment of the HDRI scenes (`sky.hdr`, 512 x 256, Blender's
/// equirectangular orientation): a sky from a bright horizon (radiance 0.4) to a
/// deeper blue zenith, a darker ground below the horizon (0.05), and a sun disc.
fn sky() -> (usize, usize, Vec<[f32; 3]>) {
    let (w, h) = (512usize, 256usize);
    let (el, az) = (SUN_ELEVATION_DEG.to_radians(), SUN_AZIMUTH_DEG.to_radians());
    let sun = glam::Vec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin());
    let cos_sun = SUN_RADIUS_DEG.to_radians().cos();
    let px = (0..w * h)
        .map(|i| {
            let uv = glam::Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32);
            let d = pm_scene::uv_to_direction(uv);
            if d.dot(sun) >= cos_sun {
                return [SUN_RADIANCE; 3];
            }
            if d.y < 0.0 {
                return [0.05, 0.045, 0.04];
            }
            let t = d.y.sqrt();
            let horizon = glam::Vec3::new(0.4, 0.4, 0.38);
            let zenith = glam::Vec3::new(0.09, 0.16, 0.34);
            // Brighter toward the sun (a little forward scattering).
            let glow = 1.0 + 0.5 * d.dot(sun).max(0.0).powi(8);
            ((horizon + (zenith - horizon) * t) * glow).to_array()
        })
        .collect();
    (w, h, px)
}

/// The camera rotation (x, y, z, w) that turns glTF's view direction -z toward
/// `target` from `eye`, keeping +y up.
fn look_at(eye: [f32; 3], target: [f32; 3]) -> [f64; 4] {
    let f = (glam::Vec3::from(target) - glam::Vec3::from(eye)).normalize();
    let right = f.cross(glam::Vec3::Y).normalize();
    let up = right.cross(f);
    let q = glam::Quat::from_mat3(&glam::Mat3::from_cols(right, up, -f)).normalize();
    q.to_array().map(|c| ((c as f64) * 1e6).round() / 1e6)
}

/// An outdoor scene lit only by `sky.hdr` (issue 37): an 8 m x 8 m grey ground,
/// a glass sphere (the sun's caustic), a chrome sphere and a diffuse block.
fn hdri_spheres() -> Doc {
    let mut doc = Doc::default();
    let ground = doc.material(diffuse("ground", [0.5, 0.5, 0.5]));
    let red = doc.material(diffuse("block", [0.7, 0.2, 0.15]));
    let (chrome, glass) = chrome_and_glass(&mut doc, 0.8);
    let g = 4.0;
    doc.mesh_node("ground", &quad([-g, 0.0, g], [g, 0.0, g], [g, 0.0, -g], [-g, 0.0, -g]), ground);
    doc.mesh_node("sphere_glass", &sphere([0.45, 0.4, 0.35], 0.4, 48, 24, false), glass);
    doc.mesh_node("sphere_chrome", &sphere([-0.7, 0.4, -0.3], 0.4, 48, 24, false), chrome);
    doc.mesh_node("block", &block(0.9, -0.9, 0.5, 0.7, 0.5, 0.4), red);
    let eye = [0.0, 1.4, 3.6];
    doc.camera(eye, Some(look_at(eye, [0.0, 0.3, 0.0])), 0.69, 1.0);
    doc.scene_extras = Some(json!({"environment": {"file": "sky.hdr"}}));
    doc
}

/// A closed room (4 m x 2.6 m x 3 m, white walls, a beige floor, a block) lit
/// only by `sky.hdr` through one window in its +X wall (1.2 m x 1 m, an opening
/// with an invisible pane named "window": the portal of issue 37). The sun
/// shines through it onto the floor.
fn window_room() -> Doc {
    let mut doc = Doc::default();
    let white = doc.material(diffuse("walls", [0.75, 0.75, 0.75]));
    let floor = doc.material(diffuse("floor", [0.6, 0.5, 0.4]));
    let blocks = doc.material(diffuse("block", [0.3, 0.45, 0.7]));
    let pane = doc.material(json!({
        "name": "opening",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 0.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "alphaMode": "MASK"
    }));
    let (x0, x1, h, z) = (-2.0, 2.0, 2.6, 1.5);
    // The window: y in [w0, w1], z in [-wz, wz] in the wall x = x1.
    let (w0, w1, wz) = (0.9, 1.9, 0.6);
    let walls = merge(&[
        quad([x0, h, -z], [x1, h, -z], [x1, h, z], [x0, h, z]), // ceiling, -y
        quad([x0, 0.0, -z], [x1, 0.0, -z], [x1, h, -z], [x0, h, -z]), // back, +z
        quad([x0, 0.0, z], [x0, h, z], [x1, h, z], [x1, 0.0, z]), // front, -z
        quad([x0, 0.0, z], [x0, 0.0, -z], [x0, h, -z], [x0, h, z]), // left, +x
        // The window wall (x = x1, facing -x) around the opening.
        quad([x1, 0.0, -z], [x1, 0.0, z], [x1, w0, z], [x1, w0, -z]),
        quad([x1, w1, -z], [x1, w1, z], [x1, h, z], [x1, h, -z]),
        quad([x1, w0, -z], [x1, w0, -wz], [x1, w1, -wz], [x1, w1, -z]),
        quad([x1, w0, wz], [x1, w0, z], [x1, w1, z], [x1, w1, wz]),
    ]);
    doc.mesh_node("walls", &walls, white);
    doc.mesh_node("floor", &quad([x0, 0.0, z], [x1, 0.0, z], [x1, 0.0, -z], [x0, 0.0, -z]), floor);
    doc.mesh_node("block", &block(-0.6, -0.5, 0.6, 0.9, 0.6, 0.5), blocks);
    doc.mesh_node("window", &quad([x1, w0, -wz], [x1, w0, wz], [x1, w1, wz], [x1, w1, -wz]), pane);
    let eye = [-1.8, 1.4, 1.3];
    doc.camera(eye, Some(look_at(eye, [1.5, 0.9, -0.4])), 1.1, 1.0);
    doc.scene_extras = Some(json!({"environment": {"file": "sky.hdr"}}));
    doc
}

/// Write the memory benchmark's big scenes into `dir` (not committed: 28 and 280 MB).
pub fn run_big(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    for (name, seg) in [("spheres_1m", 100), ("spheres_10m", 316)] {
        sphere_room(seg).write(dir, name, false)?;
        println!("wrote {}", dir.join(format!("{name}.gltf")).display());
    }
    Ok(())
}

/// Write (or with `check`, compare) every scene.
pub fn run(dir: &Path, check: bool) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    for (name, doc) in [
        ("cornell_spheres", cornell_spheres()),
        ("cornell_boxes", cornell_boxes()),
        ("cornell_fog", cornell_fog()),
        ("cornell_fogbox", cornell_fogbox()),
        ("cornell_glass_panel", cornell_glass_panel()),
        ("glass_lit_room", glass_lit_room()),
        ("volumetric_caustic", volumetric_caustic()),
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
        ("hdri_spheres", hdri_spheres()),
        ("window_room", window_room()),
        ("lamps_room", lamps_room()),
    ] {
        doc.write(dir, name, check)?;
        println!("{} {name}", if check { "up to date:" } else { "wrote" });
    }
    // The HDRI scenes' environment.
    let (w, h, px) = sky();
    let path = dir.join("sky.hdr");
    let px: Vec<glam::Vec3> = px.into_iter().map(glam::Vec3::from).collect();
    if check {
        if pm_image::radiance_hdr_bytes(w, h, &px)? != std::fs::read(&path).unwrap_or_default() {
            anyhow::bail!("{} is stale: run `cargo xtask gen-scenes`", path.display());
        }
    } else {
        pm_image::write_radiance_hdr(&path, w, h, &px)?;
    }
    println!("{} sky.hdr", if check { "up to date:" } else { "wrote" });
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
