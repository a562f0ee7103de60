//! Degenerate geometry from a glTF file: zero-area, needle, duplicate and coincident
//! triangles, missing, zero-length and flipped vertex normals, a point light exactly
//! on a wall, and a camera exactly on the floor. Everything must load, render
//! without NaN or Inf, and still agree with the path tracer.

use glam::Vec3;
use pm_methods::Method;
use pm_tests::{photon_maps, render, render_params, scene_path};
use serde_json::json;
use std::path::{Path, PathBuf};

/// cornell_boxes with an extra mesh and lights added through a second buffer.
fn degenerate_scene(dir: &Path, camera_on_floor: bool) -> PathBuf {
    let text = std::fs::read_to_string(scene_path("cornell_boxes.gltf")).unwrap();
    std::fs::copy(scene_path("cornell_boxes.bin"), dir.join("cornell_boxes.bin")).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    // Vertices: 0-2 zero-area (collinear), 3-5 a needle, 6-8 a triangle used twice
    // (duplicate), 9-12 a quad lying exactly on the floor (z-fighting).
    let p: Vec<[f32; 3]> = vec![
        [-0.5, 0.5, 0.0],
        [0.0, 0.5, 0.0],
        [0.5, 0.5, 0.0],
        [-0.6, 0.3, 0.2],
        [0.6, 0.3, 0.2],
        [0.6, 0.3 + 1e-6, 0.2],
        [-0.2, 0.8, -0.5],
        [0.2, 0.8, -0.5],
        [0.0, 1.1, -0.5],
        [-0.9, 0.0, 0.9],
        [-0.4, 0.0, 0.9],
        [-0.4, 0.0, 0.4],
        [-0.9, 0.0, 0.4],
    ];
    // Normals: zero-length, flipped against the winding, and missing-like zeros.
    let n: Vec<[f32; 3]> = vec![
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, -1.0],
        [0.0, -1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, -1.0, 0.0],
    ];
    let idx: Vec<u32> = vec![0, 1, 2, 3, 4, 5, 6, 7, 8, 6, 7, 8, 9, 10, 11, 9, 11, 12];
    let mut bin = Vec::new();
    for v in p.iter().chain(&n) {
        for c in v {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in &idx {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    std::fs::write(dir.join("extra.bin"), &bin).unwrap();
    let buf = doc["buffers"].as_array().unwrap().len();
    doc["buffers"].as_array_mut().unwrap().push(json!({"uri": "extra.bin", "byteLength": bin.len()}));
    let views = doc["bufferViews"].as_array_mut().unwrap();
    let v0 = views.len();
    views.push(json!({"buffer": buf, "byteOffset": 0, "byteLength": 13 * 12}));
    views.push(json!({"buffer": buf, "byteOffset": 13 * 12, "byteLength": 13 * 12}));
    views.push(json!({"buffer": buf, "byteOffset": 26 * 12, "byteLength": idx.len() * 4}));
    let acc = doc["accessors"].as_array_mut().unwrap();
    let a0 = acc.len();
    acc.push(json!({"bufferView": v0, "componentType": 5126, "count": 13, "type": "VEC3", "min": [-0.9, 0.0, -0.5], "max": [0.6, 1.1, 0.9]}));
    acc.push(json!({"bufferView": v0 + 1, "componentType": 5126, "count": 13, "type": "VEC3"}));
    acc.push(json!({"bufferView": v0 + 2, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}));
    let mats = doc["materials"].as_array_mut().unwrap();
    let m = mats.len();
    mats.push(json!({"name": "odd", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.3, 0.3, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}));
    let meshes = doc["meshes"].as_array_mut().unwrap();
    meshes.push(json!({"name": "degenerate", "primitives": [{"attributes": {"POSITION": a0, "NORMAL": a0 + 1}, "indices": a0 + 2, "material": m}]}));
    let mesh = meshes.len() - 1;
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(json!({"name": "degenerate", "mesh": mesh}));
    // A point light exactly on the back wall (z = -1).
    nodes.push(json!({"name": "wall_lamp", "translation": [0.5, 1.0, -1.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    let new_nodes = [nodes.len() - 2, nodes.len() - 1];
    if camera_on_floor {
        for node in nodes.iter_mut() {
            if node.get("camera").is_some() {
                node["translation"] = json!([-0.5, 0.0, 0.8]); // on the floor and on the coincident quad
                node["rotation"] = json!([0.2588190, 0.0, 0.0, 0.9659258]); // 30 degrees up
            }
        }
    }
    doc["scenes"][0]["nodes"].as_array_mut().unwrap().extend(new_nodes.iter().map(|&i| json!(i)));
    doc["extensions"] = json!({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 341.5}]}});
    let used = doc["extensionsUsed"].as_array_mut().unwrap();
    used.push(json!("KHR_lights_punctual"));
    let p = dir.join(if camera_on_floor { "degenerate_floor_camera.gltf" } else { "degenerate.gltf" });
    std::fs::write(&p, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    p
}

/// Measured at 32 x 32, pixels at the area light's edge left out: full vs 512-spp
/// path relative RMSE 7.8% and bias -1.9% from the usual camera; 8.7% and -4.4%
/// from the camera lying on the floor (and on the coincident quad), whose rays graze
/// the floor and see more corners, where photon estimates are biased low. Asserted:
/// no NaN/Inf, the zero-area triangle skipped with a warning, RMSE below 20%,
/// |bias| below 7%.
#[test]
fn degenerate_geometry_renders_finite_and_agrees_with_the_path_tracer() {
    let dir = tempfile::tempdir().unwrap();
    for on_floor in [false, true] {
        let path = degenerate_scene(dir.path(), on_floor);
        let scene = pm_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.warnings.iter().any(|w| w.contains("zero-area triangles skipped")), "{:?}", scene.warnings);
        assert_eq!(scene.lights.len(), 2);
        let maps = photon_maps(&scene, 100_000, 0, 0.25);
        let mut cfg = render_params(Method::Full, 32, 32);
        let (full, fs) = render(&scene, &maps, &cfg);
        cfg.mode = Method::Path;
        cfg.render.spp = 512;
        let (pt, ps) = render(&scene, &maps, &cfg);
        assert_eq!((fs.nonfinite_pixels, ps.nonfinite_pixels), (0, 0));
        // Leave out pixels that see the area light or touch one that does: their error
        // is the sample coverage of a bright edge (16 samples against 512).
        let (f, q) = (full.total(), pt.total());
        let bright = |x: i32, y: i32| {
            (0..32).contains(&x) && (0..32).contains(&y) && q[(y * 32 + x) as usize].max_element() > 1.0
        };
        let keep: Vec<usize> = (0..f.len())
            .filter(|&i| {
                let (x, y) = ((i % 32) as i32, (i / 32) as i32);
                !(-1..=1).any(|dy| (-1..=1).any(|dx| bright(x + dx, y + dy)))
            })
            .collect();
        let pick = |v: &[Vec3]| keep.iter().map(|&i| v[i]).collect::<Vec<_>>();
        let e = pm_image::compare(&pick(f), &pick(q), f32::INFINITY);
        let mut worst: Vec<(f32, usize)> = keep.iter().map(|&i| ((f[i] - q[i]).length(), i)).collect();
        worst.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (d, i) in worst.iter().take(3) {
            eprintln!("  pixel ({}, {}): full {} path {} (diff {d:.3})", i % 32, i / 32, f[*i], q[*i]);
        }
        eprintln!(
            "degenerate scene (camera on floor: {on_floor}): full vs path relative RMSE {:.4}, bias {:+.4}",
            e.rel_rmse, e.rel_bias
        );
        assert!(e.rel_rmse < 0.2 && e.rel_bias.abs() < 0.07, "{e:?}");
    }
}
