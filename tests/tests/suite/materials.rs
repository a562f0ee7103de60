//! The glTF 2.0 material model at shading points (issue 14, section 3): textures
//! that vary the BSDF, vertex colours, emissive textures, and alpha that lets rays
//! and photons through, in every stage that finds surfaces. Each scene is a unit
//! quad written here as glTF with its own PNG, so what is expected is worked out
//! from the file's numbers, not from the loader.

use glam::{Vec2, Vec3, Vec4};
use pm_bsdf::Bsdf;
use pm_color::{Rgb, srgb_decode};
use pm_scene::{Scene, load};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// A glTF file in `dir`: quads (each four corners, counter-clockwise seen from the
/// side it faces, with uv = corner (0,0), (1,0), (1,1), (0,1)), each with a material
/// index and optional COLOR_0; `materials`; `images` as RGBA PNGs (texture i reads
/// image i with nearest filtering); optional extra top-level JSON merged in.
struct Doc {
    quads: Vec<([Vec3; 4], usize, Option<[Vec4; 4]>)>,
    materials: Vec<Value>,
    images: Vec<(u32, u32, Vec<[u8; 4]>)>,
    extra: Value,
}

impl Doc {
    /// Write `dir/NAME.gltf` (with its .bin and PNGs) through the scene generator's
    /// glTF writer: textures sampled nearest, quads without vertex normals.
    fn write(&self, dir: &Path, name: &str) -> PathBuf {
        let mut g = pm_scenegen::gltf::Doc::default();
        for m in &self.materials {
            g.material(m.clone());
        }
        for (w, h, px) in &self.images {
            g.texture_filtered(*w, *h, px.clone(), [10497, 10497], 9728);
        }
        for (i, (p, material, colors)) in self.quads.iter().enumerate() {
            let mesh =
                pm_scenegen::gltf::Mesh { p: p.map(|v| v.to_array()).to_vec(), n: vec![], idx: vec![0, 1, 2, 0, 2, 3] };
            let attrs = pm_scenegen::gltf::Attrs {
                uv: vec![[0., 0.], [1., 0.], [1., 1.], [0., 1.]],
                color: colors.map_or(vec![], |c| c.map(|v| v.to_array()).to_vec()),
                ..Default::default()
            };
            g.mesh_node_attrs(&format!("quad{i}"), &mesh, &attrs, *material);
        }
        if let Value::Object(extra) = &self.extra {
            g.top_level = extra.clone();
        }
        g.write(dir, name, false).unwrap();
        dir.join(format!("{name}.gltf"))
    }
}

/// The unit quad in z = 0 facing +z.
fn unit_quad() -> [Vec3; 4] {
    [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]
}

fn loaded(doc: &Doc, name: &str) -> (tempfile::TempDir, Scene) {
    let dir = tempfile::tempdir().unwrap();
    let path = doc.write(dir.path(), name);
    let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
    (dir, s)
}

/// The BSDF where a ray straight down at (x, y) meets the scene.
fn bsdf_at(s: &Scene, x: f32, y: f32) -> Bsdf {
    let h = s.intersect(Vec3::new(x, y, 1.0), Vec3::NEG_Z, f32::INFINITY).expect("the quad is there");
    s.bsdf(&h)
}

/// metallicRoughness texture: blue is metalness, green roughness, per point, through
/// the factors' selection. Texel 0 (B 255, G 0): a mirror of the base colour;
/// texel 1 (B 0, G 255): a dielectric of roughness 0.6 (GGX alpha 0.36 over the
/// base, F0 0.04); with factors metallic 1 and roughness 0.6, texel 1's green 255
/// gives roughness 0.6 and texel 0's blue 255 metallic 1. Red and alpha are not read.
#[test]
fn metallic_roughness_texture_selects_the_model_per_point() {
    let doc = Doc {
        quads: vec![(unit_quad(), 0, None)],
        materials: vec![json!({"name": "mr", "pbrMetallicRoughness": {
            "baseColorFactor": [0.8, 0.6, 0.4, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.6,
            "metallicRoughnessTexture": {"index": 0}}})],
        images: vec![(2, 1, vec![[77, 0, 255, 3], [200, 255, 0, 255]])],
        extra: json!({}),
    };
    let (_d, s) = loaded(&doc, "mr");
    let base = Rgb::new(0.8, 0.6, 0.4);
    assert_eq!(bsdf_at(&s, 0.25, 0.5), Bsdf::Mirror { r: base });
    match bsdf_at(&s, 0.75, 0.5) {
        Bsdf::Plastic { rho, alpha, f0, weight } => {
            assert_eq!((rho, weight), (base, 1.0));
            assert!((alpha - 0.36).abs() < 1e-6 && (f0 - Rgb::splat(0.04)).length() < 1e-6, "{alpha} {f0}");
        }
        other => panic!("{other:?}"),
    }
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // The texture is linear data: 128 of 255 green is roughness 0.6 x 0.502, a
    // coated dielectric with alpha = roughness^2 (sRGB decoding would give 0.22).
    let doc = Doc { images: vec![(1, 1, vec![[0, 128, 0, 255]])], ..doc };
    let (_d, s) = loaded(&doc, "mr_half");
    let r = 0.6 * 128.0 / 255.0;
    match bsdf_at(&s, 0.5, 0.5) {
        Bsdf::Plastic { rho, alpha, .. } => {
            assert_eq!(rho, base);
            assert!((alpha - r * r).abs() < 1e-6, "alpha {alpha}, want {}", r * r);
        }
        other => panic!("{other:?}"),
    }
}

/// COLOR_0 multiplies the base colour (linear, interpolated), and its alpha the
/// material's alpha.
#[test]
fn vertex_colours_multiply_the_base_colour() {
    let c = Vec4::new(1.0, 0.5, 0.25, 1.0);
    let doc = Doc {
        quads: vec![(unit_quad(), 0, Some([c, c, Vec4::new(0.0, 0.5, 0.25, 1.0), c]))],
        materials: vec![
            json!({"name": "vc", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0}}),
        ],
        images: vec![],
        extra: json!({}),
    };
    let (_d, s) = loaded(&doc, "vc");
    // (0.25, 0.125) lies in triangle (0, 1, 2), with weights (1 - x, x - y, y) =
    // (0.75, 0.125, 0.125): corner 2's red 0 weighs an eighth. (Off the triangle's
    // edge: a hit on it moves inside by `EDGE_INSET`.)
    let red = 0.8 * (0.75 * 1.0 + 0.125 * 1.0 + 0.125 * 0.0);
    match bsdf_at(&s, 0.25, 0.125) {
        Bsdf::Plastic { rho, .. } => assert_eq!(rho, Rgb::new(red, 0.4, 0.2)),
        other => panic!("{other:?}"),
    }
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

/// An emissive texture multiplies emissiveFactor x strength (sRGB decoded).
#[test]
fn emissive_texture_scales_the_emitted_radiance() {
    let doc = Doc {
        quads: vec![(unit_quad(), 0, None)],
        materials: vec![json!({"name": "glow", "emissiveFactor": [1.0, 0.5, 1.0],
            "emissiveTexture": {"index": 0},
            "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}})],
        images: vec![(2, 1, vec![[255, 255, 255, 255], [128, 0, 64, 255]])],
        extra: json!({"extensionsUsed": ["KHR_materials_emissive_strength"]}),
    };
    let (_d, s) = loaded(&doc, "glow");
    let at = |x: f32| {
        let h = s.intersect(Vec3::new(x, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
        s.emitted(&h, Vec3::Z)
    };
    assert!((at(0.25) - Rgb::new(4.0, 2.0, 4.0)).length() < 1e-5, "{}", at(0.25));
    let want = Rgb::new(4.0 * srgb_decode(128.0 / 255.0), 0.0, 4.0 * srgb_decode(64.0 / 255.0));
    assert!((at(0.75) - want).length() < 1e-5, "{} want {want}", at(0.75));
}

/// Ray queries and the rasteriser agree on where a masked quad is: texture alpha 0 on
/// the left half, 255 on the right, cutoff 0.5.
fn masked_doc(alpha_mode: Value) -> Doc {
    Doc {
        quads: vec![(unit_quad(), 0, None)],
        materials: vec![json!({"name": "leaf", "alphaMode": alpha_mode, "alphaCutoff": 0.5,
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})],
        images: vec![(2, 1, vec![[255, 255, 255, 0], [255, 255, 255, 255]])],
        extra: json!({}),
    }
}

#[test]
fn masked_alpha_lets_rays_through_in_every_query() {
    let (_d, s) = loaded(&masked_doc("MASK".into()), "mask");
    let o = |x: f32| Vec3::new(x, 0.5, 1.0);
    assert!(s.intersect(o(0.25), Vec3::NEG_Z, f32::INFINITY).is_none());
    assert!(s.intersect(o(0.75), Vec3::NEG_Z, f32::INFINITY).is_some());
    assert!(!s.occluded(o(0.25), Vec3::NEG_Z, 2.0));
    assert!(s.occluded(o(0.75), Vec3::NEG_Z, 2.0));
    // The rasteriser, looking down at the quad: every pixel centre over the right
    // half sees it and none over the left half does (the centres avoid x = 0.5).
    let camera = pm_scene::Camera {
        position: Vec3::new(0.5, 0.5, 2.0),
        forward: Vec3::NEG_Z,
        up: Vec3::Y,
        right: Vec3::X,
        yfov: 0.6,
        aspect: Some(1.0),
    };
    let film = pm_render::Film { width: 32, height: 32, spp: 1, contrast: 0.0, seed: 0, pixel_centres: false };
    let frags = pm_raster::first_hits(&s, &camera, film.size(), film.rect());
    let (mut seen, mut checked) = (0, 0);
    for (i, f) in frags.iter().enumerate() {
        let (x, y) = ((i % 32) as f32 + 0.5, (i / 32) as f32 + 0.5);
        let d = camera.ray_direction(x / 32.0, y / 32.0, 1.0);
        let by_ray = s.intersect(camera.position, d, f32::INFINITY);
        assert_eq!(f.is_some(), by_ray.is_some(), "pixel {i}");
        if let Some(h) = by_ray {
            assert!(h.p.x > 0.5);
            seen += 1;
        }
        checked += 1;
    }
    assert!(seen > 100 && seen < checked, "{seen} of {checked}");
    // Opaque mode ignores alpha.
    let (_d, s) = loaded(&masked_doc("OPAQUE".into()), "opaque");
    assert!(s.intersect(o(0.25), Vec3::NEG_Z, f32::INFINITY).is_some());
}

/// BLEND is stochastic transparency: of many rays through a quad of alpha 0.3
/// (baseColorFactor), 30% stop, whichever query asks; the decision is the same for
/// the same point.
#[test]
fn blended_alpha_stops_that_fraction_of_rays() {
    let doc = Doc {
        quads: vec![(unit_quad(), 0, None)],
        materials: vec![json!({"name": "veil", "alphaMode": "BLEND",
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 0.3]}})],
        images: vec![],
        extra: json!({}),
    };
    let (_d, s) = loaded(&doc, "veil");
    let n = 40_000;
    let mut s_rng = pm_sampling::Sampler::new(7, 0);
    let (mut hits, mut blocked) = (0, 0);
    for _ in 0..n {
        let u = s_rng.next_2d();
        let o = Vec3::new(u.x, u.y, 1.0);
        hits += s.intersect(o, Vec3::NEG_Z, f32::INFINITY).is_some() as u32;
        blocked += s.occluded(o, Vec3::NEG_Z, 2.0) as u32;
    }
    // Binomial standard deviation sqrt(0.21 / 40000) = 0.0023: 5 sigma.
    for (what, k) in [("intersect", hits), ("occluded", blocked)] {
        let f = k as f32 / n as f32;
        assert!((f - 0.3).abs() < 0.0115, "{what}: {f} of rays stopped");
    }
    // The same point decides the same way for a ray from elsewhere.
    let p = Vec2::new(0.3, 0.6);
    let a = s.intersect(Vec3::new(p.x, p.y, 1.0), Vec3::NEG_Z, f32::INFINITY).is_some();
    let b = s.occluded(Vec3::new(p.x, p.y, 1.0), Vec3::NEG_Z, 5.0);
    assert_eq!(a, b);
}

/// Photons under a sun straight down: a black blended quad (alpha 0.3) over a black
/// floor. Photons that stop on the veil carry their power / 0.3, so the veil's
/// stored power is the whole power falling on it (what its radiance estimate needs:
/// its own 0.3 comes from the eye rays that stop there); the floor below it gets the
/// other 70%. A masked leaf (the left half cut out) lets the floor under its hole get
/// the full power.
#[test]
fn photons_pass_through_alpha_and_the_stored_power_is_unbiased() {
    let floor = [
        Vec3::new(-1.0, -1.0, -1.0),
        Vec3::new(2.0, -1.0, -1.0),
        Vec3::new(2.0, 2.0, -1.0),
        Vec3::new(-1.0, 2.0, -1.0),
    ];
    for (mode, name) in [("BLEND", "veil"), ("MASK", "leaf")] {
        let mut doc = masked_doc(mode.into());
        doc.materials[0] = json!({"name": name, "alphaMode": mode, "alphaCutoff": 0.5,
            "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, if mode == "BLEND" { 0.3 } else { 1.0 }],
                "baseColorTexture": {"index": 0}}});
        if mode == "BLEND" {
            doc.images = vec![(1, 1, vec![[255, 255, 255, 255]])];
        }
        doc.quads.push((floor, 1, None));
        doc.materials.push(json!({"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]}}));
        doc.extra = json!({
            "extensionsUsed": ["KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 683.0}]}},
        });
        let dir = tempfile::tempdir().unwrap();
        let path = doc.write(dir.path(), name);
        // A sun node pointing down (-Z of the node is -z of the world: no rotation).
        let mut g: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        g["nodes"]
            .as_array_mut()
            .unwrap()
            .push(json!({"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 0}}}));
        g["scenes"][0]["nodes"].as_array_mut().unwrap().push(2.into());
        std::fs::write(&path, g.to_string()).unwrap();
        let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
        let cfg = pm_photon::TraceConfig {
            pass: pm_photon::MapPass::Global,
            budget: pm_photon::Budget::Stored { target: 200_000, cap: 10_000_000 },
            seed: 3,
            selector: pm_photon::LightSelector::new(&s, &[]).unwrap(),
        };
        let photons = pm_photon::trace(&s, &cfg, &|_| {}).unwrap().photons;
        // Irradiance 1 W/m^2: power per unit area of each region.
        let area_power = |f: &dyn Fn(Vec3) -> bool, area: f32| {
            photons.iter().filter(|p| f(p.position)).map(|p| p.power.x as f64).sum::<f64>() as f32 / area
        };
        let on_quad = |p: Vec3| p.z.abs() < 1e-4;
        let under = |x0: f32, x1: f32| move |p: Vec3| p.z < -0.5 && p.x > x0 && p.x < x1 && p.y > 0.0 && p.y < 1.0;
        if mode == "BLEND" {
            let veil = area_power(&on_quad, 1.0);
            let below = area_power(&under(0.0, 1.0), 1.0);
            assert!((veil - 1.0).abs() < 0.05, "veil stores {veil} W/m^2 of 1");
            assert!((below - 0.7).abs() < 0.04, "floor under the veil gets {below} W/m^2 of 0.7");
        } else {
            let hole = area_power(&under(0.0, 0.5), 0.5);
            let shade = area_power(&under(0.5, 1.0), 0.5);
            let leaf = area_power(&on_quad, 0.5);
            assert!((hole - 1.0).abs() < 0.05, "floor under the hole gets {hole} W/m^2 of 1");
            assert!(shade < 1e-3, "floor under the leaf gets {shade} W/m^2");
            assert!((leaf - 1.0).abs() < 0.05, "leaf stores {leaf} W/m^2 of 1");
        }
    }
}

/// A textured emitter is a light whose power and sampling follow the texture: a
/// 1 m^2 quad facing down with a 4 x 4 emissive texture of uneven texels, 1 m above a
/// point. Quadrature over a 600 x 600 grid of the surface (the scene's own
/// `emission_at`, which the emissive-texture test checks) gives the emitted power
/// pi * integral of L_e dA and the irradiance at the point; the light's power, the
/// mean power of emitted photons, and next-event estimates of the irradiance from
/// `sample_li` (with their pdf) must agree with it.
#[test]
fn textured_emitters_emit_and_are_sampled_in_proportion_to_their_texture() {
    let texels: Vec<[u8; 4]> =
        (0..16u32).map(|i| [((i * 97) % 256) as u8, ((i * 53 + 40) % 256) as u8, (i * 16) as u8, 255]).collect();
    let down = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0), Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, 0.0, 1.0)];
    let doc = Doc {
        quads: vec![(down, 0, None)],
        materials: vec![json!({"name": "panel", "emissiveFactor": [1.0, 1.0, 1.0], "emissiveTexture": {"index": 0}})],
        images: vec![(4, 4, texels)],
        extra: json!({}),
    };
    let (_d, s) = loaded(&doc, "panel");
    assert_eq!(s.lights.len(), 1);
    let light = &s.lights[0];
    let x = Vec3::new(0.3, 0.6, 0.0);
    let n = 600;
    let (mut power, mut irradiance) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for i in 0..n {
        for j in 0..n {
            let (u, v) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let y = Vec3::new(v, u, 1.0); // corner order: (0,0) (0,1) (1,1) (1,0)
            let h = s.intersect(Vec3::new(y.x, y.y, 0.5), Vec3::Z, 1.0).unwrap();
            let le = s.emitted(&h, Vec3::NEG_Z).as_dvec3();
            let da = 1.0 / (n * n) as f64;
            power += le * std::f64::consts::PI * da;
            let d = y - x;
            let r2 = d.length_squared();
            let cos = (d.z / r2.sqrt()) as f64; // the same at both ends: parallel planes
            irradiance += le * cos * cos / r2 as f64 * da;
        }
    }
    let rel = |a: glam::DVec3, b: glam::DVec3| ((a - b).length() / b.length()) as f32;
    assert!(rel(light.power.as_dvec3(), power) < 0.02, "light power {} against quadrature {power}", light.power);
    let mut sampler = pm_sampling::Sampler::new(11, 0);
    let (mut emitted, mut nee) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    let m = 200_000;
    for _ in 0..m {
        if let Some(r) = light.sample_emission(&s, &mut sampler) {
            emitted += r.power.as_dvec3();
        }
        let (u_sel, u) = (sampler.next_1d(), sampler.next_2d());
        if let Some(ls) = light.sample_li(&s, x, Vec3::Z, u_sel, u) {
            nee += (ls.li * (ls.wi.z / ls.pdf)).as_dvec3();
        }
    }
    let (emitted, nee) = (emitted / m as f64, nee / m as f64);
    assert!(rel(emitted, power) < 0.01, "photon power {emitted} against {power}");
    assert!(rel(nee, irradiance) < 0.01, "next-event irradiance {nee} against {irradiance}");
}

/// `tris` of material 0 (`m`) over a black 7 m floor at y = 0 (material 1, emitting
/// `floor_emission`), lit by a sun straight down (1 W/m^2) when `sun`, seen by a
/// narrow camera 3 m above (0.5, 0, 0.5) looking straight down.
fn over_floor(mut tris: Vec<pm_scene::Triangle>, m: pm_scene::Material, floor_emission: f32, sun: bool) -> Scene {
    let v = |x: f32, z: f32| Vec3::new(x, 0.0, z);
    for q in [[v(-3.0, -3.0), v(-3.0, 4.0), v(4.0, 4.0)], [v(-3.0, -3.0), v(4.0, 4.0), v(4.0, -3.0)]] {
        tris.push(pm_scene::Triangle::new(q, 1).unwrap());
    }
    let floor = pm_tests::material("floor", Bsdf::Lambert { rho: Rgb::ZERO }, floor_emission);
    let sun = sun.then(|| pm_scene::Light {
        name: "sun".into(),
        kind: pm_scene::LightKind::Directional {
            direction: Vec3::NEG_Y,
            irradiance: Rgb::ONE,
            cap: 0.0,
            center: Vec3::ZERO,
            radius: 0.0,
        },
        power: Rgb::ZERO,
    });
    let camera = pm_tests::camera_looking_down(Vec3::new(0.5, 3.0, 0.5), 0.1);
    Scene::from_parts(tris, vec![m, floor], sun.into_iter().collect(), Some(camera))
}

/// The photons of a global map traced in `s` from 400,000 emitted.
fn emitted_photons(s: &Scene) -> Vec<pm_format::Photon> {
    let cfg = pm_photon::TraceConfig {
        pass: pm_photon::MapPass::Global,
        budget: pm_photon::Budget::Emitted(400_000),
        seed: 5,
        selector: pm_photon::LightSelector::new(s, &[]).unwrap(),
    };
    pm_photon::trace(s, &cfg, &|_| {}).unwrap().photons
}

/// The mean radiance [W sr^-1 m^-2 per channel] of an 8 x 8 image of `s` from the
/// path tracer (`path_spp` samples per pixel) and the photon-map renderer
/// (`full_spp`, over 20,000 global photons).
fn mean_seen(s: &Scene, path_spp: u32, full_spp: u32) -> [(pm_methods::Method, Rgb); 2] {
    let maps = pm_tests::photon_maps(s, 20_000, 0, 0.25);
    [(pm_methods::Method::Path, path_spp), (pm_methods::Method::Full, full_spp)].map(|(method, spp)| {
        let mut cfg = pm_tests::render_params(method, 8, 8);
        cfg.render.spp = spp;
        let (img, _) = pm_tests::render(s, &maps, &cfg);
        let px = img.total();
        (method, px.iter().copied().sum::<Rgb>() / px.len() as f32)
    })
}

/// An absorbing glass slab (KHR_materials_volume's attenuation): a closed box 0.4 m
/// thick, ior 1.5, sigma_a = (1, 2, 0.5) m^-1, over a floor, seen and lit straight
/// down. At normal incidence each face reflects R = ((1.5 - 1) / (1.5 + 1))^2 = 0.04,
/// and with t = exp(-sigma_a 0.4) per crossing the slab transmits (Beer-Lambert
/// with every internal reflection summed) T = (1 - R)^2 t / (1 - R^2 t^2). Photons
/// from a sun (1 W/m^2) arrive on the floor under it with T W/m^2; the path tracer
/// and the photon-map renderer see an emitting floor (L_e = 1) through it at T.
#[test]
fn absorbing_glass_transmits_the_beer_lambert_fraction() {
    use pm_tests::{closed_box, material};
    let sigma = Rgb::new(1.0, 2.0, 0.5);
    let thick = 0.4f32;
    let r = (0.5f32 / 2.5).powi(2);
    let t = (-sigma * thick).exp();
    let want = (1.0 - r) * (1.0 - r) * t / (Rgb::ONE - r * r * t * t);
    let build = |floor_emission: f32, sun: bool| {
        // Outward-facing slab: the inward box with its triangles turned over.
        let mut inward = Vec::new();
        closed_box(&mut inward, Vec3::new(-1.0, 0.5, -1.0), Vec3::new(2.0, 0.5 + thick, 2.0), 0);
        let slab = inward.iter().map(|t| pm_scene::Triangle::new([t.p[0], t.p[2], t.p[1]], 0).unwrap()).collect();
        let glass = material("absorbing glass", Bsdf::Glass { eta: 1.5, tint: Rgb::ONE, thin: false }, 0.0);
        let mut scene = over_floor(slab, glass, floor_emission, sun);
        scene.set_medium("absorbing glass", pm_scene::Medium::new("glass", sigma, Rgb::ZERO, 0.0).unwrap()).unwrap();
        scene.finish_media().unwrap();
        scene
    };
    // Photons.
    let photons = emitted_photons(&build(0.0, true));
    let under: Rgb = photons
        .iter()
        .filter(|p| {
            p.position.y.abs() < 1e-4 && (0.0..1.0).contains(&p.position.x) && (0.0..1.0).contains(&p.position.z)
        })
        .map(|p| p.power)
        .sum();
    let rel = |a: Rgb, b: Rgb| ((a - b) / b).abs().max_element();
    assert!(rel(under, want) < 0.03, "photons: {under} W/m^2 under the slab, want {want}");
    // The clear slab would give (1 - R)^2 / (1 - R^2): the test can tell.
    assert!(rel(Rgb::splat((1.0 - r) * (1.0 - r) / (1.0 - r * r)), want) > 0.2);
    // Eye paths.
    for (method, mean) in mean_seen(&build(1.0, false), 64, 4) {
        assert!(rel(mean, want) < 0.02, "{method:?}: {mean} through the slab, want {want}");
    }
}

/// The tangent-space normal a texel encodes, n = 2 c - 1 with c = byte / 255.
fn texel_normal(c: [u8; 4]) -> Vec3 {
    Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) / 255.0 * 2.0 - Vec3::ONE
}

/// A normal texture tilts the shading normal in the tangent frame MikkTSpace builds
/// from the texture coordinates (no TANGENT in the file): on the unit quad, u runs
/// along +x and v along +y, so texel (x, y, z) gives world (x, y, z) (scaled in x
/// and y by the texture's scale). Mirrored by its node (scale -1 in x), u runs along
/// -x and the tilt follows it. With a TANGENT attribute, the file's frame is used.
/// The geometric normal never moves.
#[test]
fn normal_textures_tilt_the_shading_normal_in_the_tangent_frame() {
    let texel = [200u8, 100, 230, 255];
    let tn = texel_normal(texel);
    let doc = |scale: f32| Doc {
        quads: vec![(unit_quad(), 0, None)],
        materials: vec![json!({"name": "bumpy", "normalTexture": {"index": 0, "scale": scale},
            "pbrMetallicRoughness": {"metallicFactor": 0.0}})],
        images: vec![(1, 1, vec![texel])],
        extra: json!({}),
    };
    let ns_at = |s: &Scene, o: Vec3, d: Vec3| {
        let h = s.intersect(o, d, f32::INFINITY).unwrap();
        assert!((h.ng - Vec3::Z).length() < 1e-6, "geometric normal {}", h.ng);
        h.ns
    };
    for scale in [1.0f32, 0.5] {
        let (_d, s) = loaded(&doc(scale), "bumpy");
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let want = (tn * Vec3::new(scale, scale, 1.0)).normalize();
        let got = ns_at(&s, Vec3::new(0.3, 0.6, 1.0), Vec3::NEG_Z);
        assert!((got - want).length() < 1e-5, "scale {scale}: {got}, want {want}");
    }
    // Mirrored by the node: the tangent turns to -x, the bitangent stays +y.
    let dir = tempfile::tempdir().unwrap();
    let path = doc(1.0).write(dir.path(), "mirrored");
    let mut g: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    g["nodes"][0]["scale"] = json!([-1.0, 1.0, 1.0]);
    std::fs::write(&path, g.to_string()).unwrap();
    let s = load(&path).unwrap();
    let got = ns_at(&s, Vec3::new(-0.3, 0.6, 1.0), Vec3::NEG_Z);
    let want = Vec3::new(-tn.x, tn.y, tn.z).normalize();
    assert!((got - want).length() < 1e-5, "mirrored: {got}, want {want}");
    // A TANGENT attribute of +y with w = -1: bitangent = -(z x y) = +x.
    let path = doc(1.0).write(dir.path(), "tangents");
    let mut g: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let t: Vec<u8> = [0.0f32, 1.0, 0.0, -1.0].repeat(4).iter().flat_map(|x| x.to_le_bytes()).collect();
    let bin_path = dir.path().join("tangents.bin");
    let mut bin = std::fs::read(&bin_path).unwrap();
    let offset = bin.len();
    bin.extend(&t);
    std::fs::write(&bin_path, &bin).unwrap();
    g["buffers"][0]["byteLength"] = bin.len().into();
    g["bufferViews"].as_array_mut().unwrap().push(json!({"buffer": 0, "byteOffset": offset, "byteLength": 64}));
    let view = g["bufferViews"].as_array().unwrap().len() - 1;
    g["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"bufferView": view, "componentType": 5126, "count": 4, "type": "VEC4"}));
    g["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = (g["accessors"].as_array().unwrap().len() - 1).into();
    std::fs::write(&path, g.to_string()).unwrap();
    let s = load(&path).unwrap();
    let got = ns_at(&s, Vec3::new(0.3, 0.6, 1.0), Vec3::NEG_Z);
    let want = Vec3::new(tn.y, tn.x, tn.z).normalize();
    assert!((got - want).length() < 1e-5, "TANGENT: {got}, want {want}");
}

/// The furnace (a closed sphere, L_e = 1, albedo 0.8: radiance 5 everywhere) with
/// its inside normal-mapped by bumps tilted up to 35 degrees. Shading normals may
/// not create energy (no pixel above 5 beyond noise) or leak (rays and photons keep
/// to the geometric side); what they lose (the parts of cosine lobes tilted below
/// the geometric horizon, about 4% a bounce here) is bounded, and the path tracer
/// and the photon-map renderer lose about the same. Measured: path tracing 4.26,
/// photon map 4.38 (their shading-normal adjoints differ: Veach 1997 section 5.3).
#[test]
fn normal_mapped_furnace_creates_no_energy() {
    use pm_tests::{material, render, render_params, sphere};
    let mut tris = Vec::new();
    sphere(&mut tris, Vec3::ZERO, 2.0, true, 0);
    for t in &mut tris {
        let at = |p: Vec3| {
            let phi = p.z.atan2(p.x) / std::f32::consts::TAU + 0.5;
            let theta = (p.y / p.length()).clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
            let tangent = Vec3::Y.cross(p).normalize_or(Vec3::X);
            (Vec2::new(4.0 * phi, 2.0 * theta), tangent.extend(1.0))
        };
        let v = t.p.map(at);
        t.extras_mut().uv = Some(v.map(|x| x.0));
        t.extras_mut().tangent = Some(v.map(|x| x.1));
    }
    let mut m = material("furnace", Bsdf::Lambert { rho: Rgb::splat(0.8) }, 1.0);
    m.normal_texture = Some(pm_scene::TextureRef { texture: 0, uv_set: 0, transform: glam::Affine2::IDENTITY });
    let mut s = Scene::from_parts(tris, vec![m], vec![], Some(pm_tests::camera(Vec3::ZERO, Vec3::new(1.0, 0.2, -1.0))));
    let mut rng = pm_sampling::Sampler::new(3, 0);
    let texels: Vec<[u8; 4]> = (0..64)
        .map(|_| {
            let u = rng.next_2d();
            let (tilt, turn) = (u.x.sqrt() * 35f32.to_radians(), u.y * std::f32::consts::TAU);
            let n = Vec3::new(tilt.sin() * turn.cos(), tilt.sin() * turn.sin(), tilt.cos());
            let c = (n * 0.5 + Vec3::splat(0.5)) * 255.0;
            [c.x.round() as u8, c.y.round() as u8, c.z.round() as u8, 255]
        })
        .collect();
    s.textures.push(pm_scene::Texture::new(8, 8, texels, false));
    // The shading normals really are tilted (by 23 degrees on average).
    let tilt: f32 = (0..400)
        .map(|_| {
            let h = s.intersect(Vec3::ZERO, pm_sampling::uniform_sphere(rng.next_2d()), f32::INFINITY).unwrap();
            h.ns.dot(h.ng).clamp(-1.0, 1.0).acos()
        })
        .sum::<f32>()
        / 400.0;
    assert!(tilt > 15f32.to_radians(), "mean tilt {} degrees", tilt.to_degrees());
    let maps = pm_tests::photon_maps(&s, 100_000, 0, 0.25);
    let mut cfg = render_params(pm_methods::Method::Path, 16, 16);
    cfg.render.spp = 256;
    let (path, _) = render(&s, &maps, &cfg);
    cfg.mode = pm_methods::Method::Full;
    cfg.render.spp = 4;
    let (full, _) = render(&s, &maps, &cfg);
    let mut means = vec![];
    for (name, img) in [("path", &path), ("full", &full)] {
        let px = img.total();
        let (mean, _, _) = pm_tests::against_constant(px, 5.0);
        let brightest = px.iter().map(|p| p.max_element()).fold(0.0, f32::max);
        eprintln!("normal-mapped furnace {name}: mean {mean:.3}, brightest {brightest:.3}");
        assert!(brightest <= 5.5, "{name}: a pixel at {brightest} creates energy");
        assert!(mean <= 5.0 * 1.01 && mean > 5.0 * 0.82, "{name}: mean {mean}");
        means.push(mean);
    }
    assert!((means[0] / means[1] - 1.0).abs() < 0.04, "path {} and photon map {} disagree", means[0], means[1]);
}

/// Partial transmission (KHR_materials_transmission factor t = 0.4) is the mix
/// t glass + (1 - t) base: a thin-walled white sheet (ior 1.5) over an emitting
/// floor, seen from above where nothing else shines, shows the glass part only:
/// t (1 - R') with the thin slab's reflectance R' = 2R / (1 + R), R = 0.04. Under a
/// sun, the floor below gets that fraction of the light, and the photons stored on
/// the sheet (on its base's share of the points, power / (1 - t)) carry all of it.
/// The photon-map renderer takes every sample in every pixel of such a scene: with
/// its adaptive supersampling the image came out 6% dark (pixels whose single first
/// sample and neighbours all chose the base kept it).
#[test]
fn partial_transmission_mixes_glass_and_the_base() {
    use pm_tests::material;
    let t = 0.4f32;
    let r = 0.04f32;
    let want = t * (1.0 - 2.0 * r / (1.0 + r));
    let build = |floor_emission: f32, sun: bool| {
        let v = |x: f32, z: f32| Vec3::new(x, 0.5, z);
        let sheet_tris = [[v(-1.0, -1.0), v(-1.0, 2.0), v(2.0, 2.0)], [v(-1.0, -1.0), v(2.0, 2.0), v(2.0, -1.0)]]
            .map(|q| pm_scene::Triangle::new(q, 0).unwrap())
            .to_vec();
        let pbr = pm_bsdf::Pbr { transmission: t, ..pm_bsdf::Pbr::dielectric(Rgb::ONE) };
        let mut sheet = material("sheet", Bsdf::from_pbr(&pbr), 0.0);
        sheet.pbr = pbr;
        sheet.double_sided = true;
        over_floor(sheet_tris, sheet, floor_emission, sun)
    };
    let photons = emitted_photons(&build(0.0, true));
    let density = |y: f32| {
        photons
            .iter()
            .filter(|p| {
                (p.position.y - y).abs() < 1e-4
                    && (0.0..1.0).contains(&p.position.x)
                    && (0.0..1.0).contains(&p.position.z)
            })
            .filter(|p| p.wi.y > 0.0) // arriving from above
            .map(|p| p.power.x)
            .sum::<f32>()
    };
    let (floor, sheet) = (density(0.0), density(0.5));
    assert!((floor / want - 1.0).abs() < 0.03, "photons: {floor} W/m^2 on the floor, want {want}");
    assert!((sheet - 1.0).abs() < 0.03, "photons: the sheet stores {sheet} W/m^2 of 1");
    for (method, mean) in mean_seen(&build(1.0, false), 256, 64) {
        let mean = mean.x;
        assert!((mean / want - 1.0).abs() < 0.03, "{method:?}: {mean} through the sheet, want {want}");
    }
}

/// The scene with every material feature (`scenes/materials.gltf`: textures moving
/// the BSDF, normal and emissive textures, vertex colours, KHR_materials_specular,
/// absorbing glass, alpha mask and blend, partial transmission) loads without a
/// warning, and each component of the photon-map image agrees with the path
/// tracer's, within the tolerances the cornell_spheres component test uses.
#[test]
fn every_material_feature_agrees_with_the_path_tracer() {
    let scene = pm_tests::load_scene("materials.gltf");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let m = |name: &str| scene.materials.iter().find(|m| m.name == name).unwrap();
    assert!(m("textured").normal_texture.is_some() && m("textured").metallic_roughness_texture.is_some());
    assert!(m("vertex_coloured").specular_texture.is_some_and(|t| t.uv_set == 1));
    let absorbing = scene.medium(m("absorbing_glass").interior).expect("the glass bounds a medium");
    assert!(absorbing.sigma_a.min_element() > 0.0 && !absorbing.scatters());
    assert!(m("glowing_panel").emissive_texture.is_some());
    assert!(scene.has_alpha() && scene.has_stochastic_surfaces());
    let maps = pm_tests::photon_maps(&scene, 200_000, 35_000, 0.25);
    let mut cfg = pm_tests::render_params(pm_methods::Method::Full, 40, 40);
    let (full, _) = pm_tests::render(&scene, &maps, &cfg);
    cfg.mode = pm_methods::Method::Path;
    cfg.render.spp = 1024;
    let (path, _) = pm_tests::render(&scene, &maps, &cfg);
    pm_tests::assert_components_agree("materials", &full, &path);
}

/// Blender's material model as a user exports it (tests/scenes/blender_materials,
/// made by tests/blender/material_room.py with Blender's own glTF exporter): a
/// room of Principled BSDFs (glTF's dielectric with its specular layer) lit by
/// an emissive quad, an emissive panel whose Emission Color is an image texture
/// with a dark border texel, a base-colour-textured sphere, a rough metal one
/// and a (thin-walled: no KHR_materials_volume) glass one. `cargo xtask run` on
/// defaults at 64 x 64 against the path tracer (512 a pixel), the light's pixels
/// left out: the worst 8 x 8 block within the batch pipeline's 15%, and the mean
/// within 1.2%, tighter than its 2% because this is the case that found a bias.
///
/// The pipeline read the dielectric as (rho (1 - f0) + f0) / pi x irradiance, at
/// the eye and at gather rays' hits: this room came out +2.1% at 64 x 64 (+1.9%
/// at 128 x 128, its indirect layer +5%; with the spheres taken out +2.1%, and
/// +0.3% with the walls Lambertian), the checker's "+3% indirect on rooms"
/// failure class. At the eye its GGX layer is now sampled
/// ([`pm_bsdf::Bsdf::layers`]), and irradiance is read with the directional
/// albedo at the actual view ([`pm_bsdf::Bsdf::albedo`]): +0.64% (worst block
/// 4.6%).
/// Against Cycles, the panel's edge was 26% off in 8 x 8 blocks (issue 53):
/// Cycles filters 8-bit sRGB texels before decoding them, we (and glTF viewers)
/// after; given decoded float texels, Cycles agrees with our path tracer within
/// 2% in every block of the panel (BENCHMARKS.md).
#[test]
fn the_pipeline_on_defaults_agrees_with_the_path_tracer_on_blenders_materials() {
    let a = blender_room_on_defaults("blender_materials/blender_materials.gltf");
    assert!(a.mean.abs() < 0.012, "{a}");
    assert!(a.worst_block < 0.15, "{a}");
}

/// `cargo xtask run` on defaults at 64 x 64 against the path tracer (512 a
/// pixel) on one of tests/scenes' Blender rooms, the ceiling light left out
/// ([`pm_tests::agreement_off_the_light`]).
fn blender_room_on_defaults(scene: &str) -> pm_image::accuracy::Agreement {
    let dir = tempfile::tempdir().unwrap();
    let path = format!("../tests/scenes/{scene}");
    let (_, ours, reference) = pm_tests::defaults_and_path_tracer(dir.path(), &path, 64, 512, |_| {});
    let a = pm_tests::agreement_off_the_light(&ours.pixels(None), &reference.pixels(None), 64);
    eprintln!("{scene} full: {a}");
    a
}

/// Blender's clear coat, sheen and anisotropy as its exporter writes them
/// (tests/scenes/blender_coated: a coated red sphere, a velvet box, a brushed
/// metal sphere; KHR_materials_clearcoat, _sheen, _anisotropy): `cargo xtask
/// run` on defaults at 64 x 64 against the path tracer (512 a pixel), the
/// light's pixels left out, within the batch pipeline's 2% in mean and 15% in
/// the worst 8 x 8 block. The coat is sampled at the eye as a sharp layer
/// (`Bsdf::layer_alpha`), the brushed metal gathered along its lobe, the sheen
/// read with the base from the irradiance. Here +0.44%, worst block 3.8%; at
/// 256 x 256 +0.4%, worst block 13.7% (the brushed sphere's rim), RMS 1.9%
/// (BENCHMARKS.md).
#[test]
fn the_pipeline_on_defaults_agrees_with_the_path_tracer_on_blenders_coat_sheen_and_anisotropy() {
    let a = blender_room_on_defaults("blender_coated/blender_coated.gltf");
    assert!(a.mean.abs() < 0.02, "{a}");
    assert!(a.worst_block < 0.15, "{a}");
}

/// Thin-film iridescence (KHR_materials_iridescence) on Blender's Thin Film
/// (tests/blender/film_room.py: a dark dielectric sphere under a film of ior 1.8
/// and 320 nm, a silver metal one under ior 1.5 and 250 nm, single-scattering
/// GGX), against Cycles (tests/scenes/blender_film/cycles_64.exr, 4096 samples),
/// whose thin film is its own (exact Fresnel at both interfaces, its own
/// spectral integration). `cargo xtask run` on defaults at 64 x 64 agrees with
/// the path tracer (512 a pixel) within the batch pipeline's 2% and 15% (light
/// left out); the path tracer's sphere means, per channel, with Cycles': the
/// dielectric's within 6% (at 256 x 256: 0.99, 1.02, 0.97), the metal's red and
/// green within 6% and its blue within 16% (0.88 at 256 x 256: glTF's film takes
/// a metal for a dielectric of the index its F0 gives, no extinction, as the
/// extension says; Cycles changes this metal's colour by under 1% with its film,
/// ours by 12% in blue). Without the film the dielectric is 31% darker in red and
/// 44% in blue than with it (Cycles: 29% and 45%): a film ignored or with a
/// wrong phase fails.
#[test]
fn a_thin_film_colours_blenders_spheres_as_cycles_does() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "../tests/scenes/blender_film/blender_film.gltf";
    let (_, ours, path) = pm_tests::defaults_and_path_tracer(dir.path(), scene, 64, 512, |_| {});
    let a = pm_tests::agreement_off_the_light(&ours.pixels(None), &path.pixels(None), 64);
    eprintln!("blender_film full: {a}");
    assert!(a.mean.abs() < 0.02 && a.worst_block < 0.15, "{a}");
    let (w, h, cycles) =
        pm_image::read_radiance_image(Path::new("../tests/scenes/blender_film/cycles_64.exr")).unwrap();
    assert_eq!((w, h), (64, 64));
    // A sphere's pixels: a disc inside its outline (centres in pixels).
    let disc = |px: &[Vec3], cx: f32, cy: f32| {
        let inside = |i: usize| {
            let (x, y) = ((i % 64) as f32 + 0.5 - cx, (i / 64) as f32 + 0.5 - cy);
            x * x + y * y < 5.5 * 5.5
        };
        let (sum, n) =
            px.iter().enumerate().filter(|(i, _)| inside(*i)).fold((Vec3::ZERO, 0), |(s, n), (_, p)| (s + *p, n + 1));
        sum / n as f32
    };
    let path = path.pixels(None);
    for (name, cx, most) in [("dielectric", 17.6, Vec3::splat(0.06)), ("metal", 48.0, Vec3::new(0.06, 0.06, 0.16))] {
        let ratio = disc(&path, cx, 46.0) / disc(&cycles, cx, 46.0);
        eprintln!("{name} sphere, path tracer over Cycles: {ratio}");
        assert!(((ratio - Vec3::ONE).abs() - most).max_element() < 0.0, "{name}: {ratio}");
    }
}

/// The floor tile of tests/scenes/blender_coated (tests/blender/coated_room.py,
/// Blender's own exporter): a thin scaled cube with Blender's default cube UVs
/// and a 4 x 4 base-colour texture read with "Closest" interpolation, exported as
/// the sampler's magFilter NEAREST. Its top face covers two yellow texels and
/// lies between lilac ones. The sampler's filter was ignored and every lookup
/// bilinear: a texel-sized face blended its yellow with the lilac round it (the
/// "uniform pale grey-lilac" tile of issue 54; on a bare copy of the tile at 64 x
/// 64 ours read 0.52 to 0.34 across the face where Cycles reads 0.63 and 0.24,
/// and now reads those). Asserted: at 400 points over the top face, the base
/// colour is the yellow texel's.
#[test]
fn a_blender_tile_read_with_closest_interpolation_shows_its_texels_unblended() {
    let s = pm_scene::load(std::path::Path::new("../tests/scenes/blender_coated/blender_coated.gltf")).unwrap();
    let tile = s.objects.iter().find(|o| o.name.starts_with("floor_tile")).unwrap();
    let tex = s.materials[tile.material as usize].base_texture.expect("the tile's base colour is a texture");
    assert_eq!(s.textures[tex.texture as usize].filter, pm_scene::Filter::Nearest);
    // The script's yellow: Blender's 8-bit image holds its pixels as sRGB codes.
    let yellow = Vec3::new(0.85, 0.65, 0.05).map(srgb_decode);
    let top = tile.tris.clone().map(|t| &s.triangles[t as usize]).filter(|t| t.ng().y > 0.99);
    let mut checked = 0;
    for tri in top {
        for i in 1..20 {
            for j in 1..(20 - i) {
                let (u, v) = (i as f32 / 20.0, j as f32 / 20.0);
                let c = s.sample_at(&tex, tri, [1.0 - u - v, u, v]).truncate();
                assert!((c - yellow).abs().max_element() < 0.01, "base colour {c} at ({u}, {v}), not the yellow texel");
                checked += 1;
            }
        }
    }
    assert!(checked >= 300, "{checked} points on the tile's top face");
}

/// The coated room's tile as KTX2 images with Basis Universal data
/// (KHR_texture_basisu, required, no PNG fallback; encoded by Basis Universal's
/// own encoder, tests/scenes/blender_coated/ktx2_tile.mjs): they were refused.
/// UASTC (zstd-supercompressed) gives back every texel of the PNG exactly;
/// ETC1S (BasisLZ) loads with its codec's loss, which is large on a 4 x 4 image
/// of two colours (one ETC1 block, a base colour per half): the lilac texels
/// (140, 115, 191) come back as (144, 119, 160), the yellow pair as a light
/// lilac (182, 157, 198).
#[test]
fn ktx2_images_load_with_the_texels_basis_universal_gives_back() {
    let dir = Path::new("../tests/scenes/blender_coated");
    let tile = |s: &pm_scene::Scene| {
        let o = s.objects.iter().find(|o| o.name.starts_with("floor_tile")).unwrap();
        s.textures[s.materials[o.material as usize].base_texture.unwrap().texture as usize].clone()
    };
    let png = tile(&load(&dir.join("blender_coated.gltf")).unwrap());
    let uastc_scene = load(&dir.join("blender_coated_ktx2.gltf")).unwrap_or_else(|e| panic!("{e}"));
    assert!(uastc_scene.warnings.is_empty(), "{:?}", uastc_scene.warnings);
    let uastc = tile(&uastc_scene);
    assert_eq!((uastc.width, uastc.height, uastc.filter, uastc.srgb), (4, 4, pm_scene::Filter::Nearest, true));
    assert_eq!(uastc.texels, png.texels);
    let etc1s = tile(&load(&dir.join("blender_coated_ktx2_etc1s.gltf")).unwrap_or_else(|e| panic!("{e}")));
    let lilac = png.texels[0];
    let near = |a: [u8; 4], b: [u8; 4]| (0..3).all(|k| (a[k] as i32 - b[k] as i32).abs() <= 32);
    let kept = etc1s.texels.iter().zip(&png.texels).filter(|(e, p)| **p == lilac && near(**e, **p)).count();
    assert_eq!((etc1s.width, etc1s.height, kept), (4, 4, 14), "{:?}", etc1s.texels);
}

/// The same Blender scene exported with WebP images (Blender's Images: WebP
/// option, tests/blender/coated_room.py --webp): the texture has no `source`,
/// only EXT_texture_webp's, and the file requires the extension. It was refused
/// (the glTF crate decodes PNG and JPEG only, and rejects a texture without a
/// source); it now loads, with the triangles of the PNG twin and the tile's
/// texels as Blender's own decoder reads the file (within 2 of 255). Blender's
/// encoder is lossy (quality 75, chroma at half resolution): on this 4 x 4
/// texture the yellow texels come back as (180, 140, 146) and (190, 154, 137),
/// the PNG's being (217, 166, 13); a user who wants the texels kept exports PNG.
#[test]
fn blenders_webp_export_loads_with_the_texels_blender_decodes() {
    let dir = Path::new("../tests/scenes/blender_coated");
    let (png, webp) =
        (load(&dir.join("blender_coated.gltf")).unwrap(), load(&dir.join("blender_coated_webp.gltf")).unwrap());
    assert!(webp.warnings.iter().all(|w| !w.contains("webp")), "{:?}", webp.warnings);
    let o = webp.objects.iter().find(|o| o.name.starts_with("floor_tile")).unwrap();
    let t = &webp.textures[webp.materials[o.material as usize].base_texture.unwrap().texture as usize];
    assert_eq!((t.width, t.height, t.filter), (4, 4, pm_scene::Filter::Nearest));
    // Blender 4.5.4's decode of tile.webp (bpy.data.images.load), bottom row first.
    let blender: [[u8; 3]; 16] = [
        [142, 113, 180],
        [143, 114, 179],
        [147, 119, 176],
        [147, 120, 172],
        [146, 109, 181],
        [148, 113, 175],
        [151, 120, 160],
        [153, 123, 151],
        [153, 101, 184],
        [163, 115, 173],
        [180, 140, 146],
        [190, 154, 137],
        [162, 102, 191],
        [160, 105, 162],
        [158, 113, 106],
        [158, 119, 77],
    ];
    let mut worst = 0;
    for (k, want) in blender.iter().enumerate() {
        // glTF's images run top row first.
        let got = t.texels[(3 - k / 4) * 4 + k % 4];
        worst = worst.max((0..3).map(|c| got[c].abs_diff(want[c])).max().unwrap());
    }
    eprintln!("largest texel difference from Blender's decode: {worst} of 255");
    assert!(worst <= 2, "{worst} of 255");
    // The same objects, each with the same bounds (the exporter may order
    // meshes differently).
    assert_eq!(png.triangles.len(), webp.triangles.len());
    for o in &png.objects {
        let w = webp.objects.iter().find(|w| w.name == o.name).unwrap_or_else(|| panic!("{} missing", o.name));
        let bounds =
            |s: &Scene, r: &std::ops::Range<u32>| pm_scene::bounds_of(&s.triangles[r.start as usize..r.end as usize]);
        let (a, b) = (bounds(&png, &o.tris), bounds(&webp, &w.tris));
        assert!(a.min.distance(b.min).max(a.max.distance(b.max)) < 1e-6, "{}: {a:?} {b:?}", o.name);
    }
}
