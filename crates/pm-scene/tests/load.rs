//! Loading glTF written outside this project, and rejecting malformed files with a
//! one-line error that names the file.

use glam::Vec3;
use pm_scene::{LightKind, LightUnits, load, load_with};
use std::f32::consts::PI;
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-5
}

/// `handmade.gltf` was written by hand to the specification (node matrices,
/// quaternions, a mirroring scale, non-indexed and u16-indexed primitives, all three
/// punctual light types, an embedded base64 buffer). Every expected value below is
/// worked out by hand in the comments. Its light intensities are read as W/sr and
/// W/m^2 here (radiometric); [`photometric_intensities_are_divided_by_683`] checks
/// the default reading.
fn check_handmade(path: &Path) {
    let s = load_with(path, LightUnits::Radiometric).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.triangles.len(), 3);
    // Ground: the unit quad scaled by 2 (node matrix), facing +y.
    let ground: Vec<_> = s.triangles.iter().filter(|t| close(t.ng(), Vec3::Y)).collect();
    assert_eq!(ground.len(), 2);
    assert!((ground.iter().map(|t| t.area()).sum::<f32>() - 16.0).abs() < 1e-5);
    // Mirrored triangle: (0,0,0),(1,0,0),(0,1,0) with normal +z, scaled by (-1,1,1),
    // rotated 90 degrees about y (x' = z, z' = -x), translated by +1 in y:
    // (0,1,0), (0,1,1), (0,2,0); normal (1,0,0). The negative determinant must not
    // flip the face: the winding normal agrees with the vertex normal.
    let tri = s.triangles.iter().find(|t| !close(t.ng(), Vec3::Y)).unwrap();
    for p in [Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 1.0), Vec3::new(0.0, 2.0, 0.0)] {
        assert!(tri.p.iter().any(|q| close(*q, p)), "{p} not in {:?}", tri.p);
    }
    assert!(close(tri.ng(), Vec3::X), "{}", tri.ng());
    assert!(tri.n.unwrap().iter().all(|n| close(*n, Vec3::X)));
    // Lights: the glowing triangle (area 0.5, L_e = 2) and the three punctual lights.
    assert_eq!(s.lights.len(), 4);
    let power =
        |name: &str| s.lights.iter().find(|l| l.name.starts_with(name)).unwrap_or_else(|| panic!("{name}")).power;
    assert!(close(power("mirrored"), Vec3::splat(PI * 2.0 * 0.5)));
    assert!(close(power("lamp") / 10.0, Vec3::new(1.0, 0.5, 0.25) * 4.0 * PI));
    let (ci, co) = (0.2f32.cos(), 0.5f32.cos());
    let spot = 2.0 * PI * 5.0 * ((1.0 - ci) + (ci - co) / 3.0);
    assert!((power("spot").x - spot).abs() < 1e-4 * spot);
    // Bounds (-2,0,-2)..(2,2,2): diagonal 6, bounding radius 3, so Phi = E pi 9.
    assert!((power("sun").x - 3.0 * PI * 9.0).abs() < 1e-3);
    for l in &s.lights {
        match &l.kind {
            LightKind::Spot { direction, position, .. } => {
                assert!(close(*direction, Vec3::NEG_Y) && close(*position, Vec3::new(1.0, 3.0, 0.0)))
            }
            LightKind::Directional { direction, .. } => assert!(close(*direction, Vec3::NEG_Y)),
            _ => {}
        }
    }
    let cam = s.camera.as_ref().unwrap();
    assert!(close(cam.position, Vec3::new(0.0, 2.0, 5.0)) && close(cam.forward, Vec3::NEG_Z));
    assert!(cam.aspect.is_none());
    // KHR_texture_transform is listed and supported: no warning about it.
    assert!(!s.warnings.iter().any(|w| w.contains("KHR_texture_transform")), "{:?}", s.warnings);
}

#[test]
fn handmade_gltf_loads_as_the_spec_says() {
    check_handmade(&data("handmade.gltf"));
}

#[test]
fn glb_written_by_gltf_transform_loads_identically() {
    // handmade_gltf_transform.glb: `gltf-transform copy handmade.gltf ...` (glTF
    // Transform 4.5.1, npm), a binary container with the buffer in its BIN chunk.
    check_handmade(&data("handmade_gltf_transform.glb"));
}

/// Write a variant of `handmade.gltf` into a temp dir and return the loader's error.
fn error_for(edit: impl FnOnce(&str, &Path) -> String) -> (String, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(data("handmade.gltf")).unwrap();
    let path = dir.path().join("bad.gltf");
    std::fs::write(&path, edit(&text, dir.path())).unwrap();
    let err = match load(&path) {
        Ok(_) => panic!("loaded a malformed file"),
        Err(e) => e.to_string(),
    };
    std::mem::forget(dir); // keep the file for the message check below
    (err, path)
}

fn assert_one_line_naming(err: &str, path: &Path, what: &str) {
    assert!(err.contains(&path.display().to_string()), "error does not name the file: {err}");
    assert!(!err.contains('\n'), "error is not one line: {err}");
    assert!(err.to_lowercase().contains(what), "error does not say '{what}': {err}");
}

/// Makes a malformed file from a valid one's text and path.
type Corrupt = Box<dyn FnOnce(&str, &Path) -> String>;

#[test]
fn malformed_files_are_rejected_with_one_line_errors() {
    let uri_start = "data:application/octet-stream;base64,";
    let cases: Vec<(&str, Corrupt)> = vec![
        ("not a valid gltf", Box::new(|t, _| t[..t.len() / 2].to_owned())),
        ("not a valid gltf", Box::new(|_, _| String::new())),
        ("not a valid gltf", Box::new(|_, _| "\u{1}\u{2}garbage".into())),
        // Positions declared as VEC2.
        (
            "position",
            Box::new(|t, _| {
                t.replacen("\"count\": 3, \"type\": \"VEC3\", \"min\"", "\"count\": 3, \"type\": \"VEC2\", \"min\"", 1)
            }),
        ),
        // Only two vertices but the indices reference vertex 2.
        (
            "out of range",
            Box::new(|t, _| {
                t.replacen(
                    "\"count\": 3, \"type\": \"VEC3\", \"min\": [ 0, 0, 0 ]",
                    "\"count\": 2, \"type\": \"VEC3\", \"min\": [ 0, 0, 0 ]",
                    1,
                )
                .replacen(
                    "\"componentType\": 5126, \"count\": 3, \"type\": \"VEC3\" }",
                    "\"componentType\": 5126, \"count\": 2, \"type\": \"VEC3\" }",
                    1,
                )
            }),
        ),
        // Accessor reading past the end of its buffer view.
        ("past the end", Box::new(|t, _| t.replacen("\"count\": 6,", "\"count\": 60,", 1))),
        // External buffer that does not exist.
        (
            "not a valid gltf",
            Box::new(move |t, _| {
                let start = t.find(uri_start).unwrap();
                let end = t[start..].find('"').unwrap() + start;
                format!("{}missing.bin{}", &t[..start], &t[end..])
            }),
        ),
        // NaN in a vertex position (external buffer written here).
        (
            "not finite",
            Box::new(move |t, dir| {
                let mut bin = vec![0u8; 152];
                bin[..4].copy_from_slice(&f32::NAN.to_le_bytes());
                std::fs::write(dir.join("nan.bin"), bin).unwrap();
                let start = t.find(uri_start).unwrap();
                let end = t[start..].find('"').unwrap() + start;
                format!("{}nan.bin{}", &t[..start], &t[end..])
            }),
        ),
    ];
    for (what, edit) in cases {
        let (err, path) = error_for(edit);
        assert_one_line_naming(&err, &path, what);
    }
    let missing = data("does_not_exist.gltf");
    let e = load(&missing).err().unwrap();
    let err = e.to_string();
    assert_one_line_naming(&err, &missing, "cannot read");
    // The OS's reason once: in the message, not again as the error's source
    // (an error chain printed whole said it twice).
    assert!(std::error::Error::source(&e).is_none() && err.matches("os error").count() == 1, "{err}");
}

/// `handmade.gltf` with its first accessor's buffer view taken away, as a
/// Draco-compressed file's accessors have none, and `extensions` added.
fn with_extensions(required: &[&str], used: &[&str]) -> PathBuf {
    let dir = tempfile::tempdir().unwrap().keep();
    let mut g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("handmade.gltf")).unwrap()).unwrap();
    if !required.is_empty() {
        g["accessors"][0].as_object_mut().unwrap().remove("bufferView");
        g["extensionsRequired"] = serde_json::json!(required);
    }
    g["extensionsUsed"] = serde_json::json!(used);
    let path = dir.join("compressed.gltf");
    std::fs::write(&path, g.to_string()).unwrap();
    path
}

/// A file that requires an extension not read (the old specular-glossiness
/// materials) is refused in one line that names it and says how to get a file
/// without it, not in a list of the accessors it leaves without data; two name
/// the first and count the rest. One used but not required is a warning naming
/// it and what is lost.
#[test]
fn extensions_not_read_are_named_with_what_they_need_or_lose() {
    let gloss = "KHR_materials_pbrSpecularGlossiness";
    let path = with_extensions(&[gloss], &[gloss]);
    let e = load(&path).err().expect("a specular-glossiness file is refused");
    let err = e.to_string();
    assert!(matches!(e, pm_scene::SceneError::Unsupported { .. }), "{err}");
    assert_one_line_naming(&err, &path, &gloss.to_lowercase());
    assert!(err.contains("metallic-roughness") && !err.contains("Missing data"), "{err}");
    let ibl = "EXT_lights_image_based";
    let path = with_extensions(&[gloss, ibl], &[gloss, ibl]);
    let err = load(&path).err().unwrap().to_string();
    assert!(err.contains("KHR_materials_pbrSpecularGlossiness (and 1 more: EXT_lights_image_based)"), "{err}");
    let dt = "KHR_materials_diffuse_transmission";
    let s = load(&with_extensions(&[], &[dt])).unwrap();
    let warned: Vec<&String> = s.warnings.iter().filter(|w| w.contains(dt)).collect();
    assert!(warned.len() == 1 && warned[0].contains("thin diffuse surfaces"), "{:?}", s.warnings);
}

/// Blender's coat, sheen and anisotropy as its exporter writes them (issue 54's
/// room): each material is the layered model with the file's factors, nothing
/// about them is said to be ignored, and the brushed sphere's anisotropy runs
/// along its exported tangents (perpendicular to the shading normal at every
/// hit, and horizontal: along the UV sphere's u, round its axis).
#[test]
fn blenders_coat_sheen_and_anisotropy_are_read() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/scenes/blender_coated/blender_coated.gltf");
    let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
    let said = |w: &&String| w.contains("clearcoat") || w.contains("sheen") || w.contains("anisotropy");
    assert!(!s.warnings.iter().any(|w| said(&w)), "{:?}", s.warnings);
    let layered = |name: &str| match s.materials.iter().find(|m| m.name == name).map(|m| m.bsdf) {
        Some(pm_bsdf::Bsdf::Layered(l)) => l,
        other => panic!("{name}: {other:?}"),
    };
    let coat = layered("coated_red");
    assert!(coat.coat == 1.0 && coat.coat_alpha == pm_bsdf::MIN_ALPHA && !coat.metal, "{coat:?}");
    assert!((coat.rho - Vec3::new(0.7, 0.05, 0.04)).length() < 1e-6 && coat.alpha == glam::Vec2::splat(0.25));
    let velvet = layered("velvet");
    assert!(velvet.sheen == Vec3::ONE && (velvet.sheen_alpha - 0.25).abs() < 1e-6, "{velvet:?}");
    let brushed = layered("brushed_metal");
    let a = 0.35f32 * 0.35;
    let alpha_t = a + (1.0 - a) * 0.64;
    assert!(brushed.metal && (brushed.alpha.x - alpha_t).abs() < 1e-5 && (brushed.alpha.y - a).abs() < 1e-6);
    // Hits across the brushed sphere (centre (1.1, 0.6, 0.4) in Blender, y up in
    // glTF: (1.1, 0.4, -0.6)), from just outside it.
    let centre = Vec3::new(1.1, 0.4, -0.6);
    let mut hits = 0;
    for k in 0..64 {
        let phi = k as f32 * 0.7;
        let dir = Vec3::new(phi.cos(), 0.3 * (k as f32 * 0.3).sin(), phi.sin()).normalize();
        let Some(h) = s.intersect(centre + dir * 0.45, -dir, f32::INFINITY) else { continue };
        if s.material(&h).name != "brushed_metal" {
            continue;
        }
        let pm_bsdf::Bsdf::Layered(l) = s.bsdf(&h) else { panic!("{:?}", s.bsdf(&h)) };
        hits += 1;
        let t = l.tangent;
        assert!((t.length() - 1.0).abs() < 1e-4 && t.dot(h.ns).abs() < 1e-3 && t.y.abs() < 1e-3, "{t} at ns {}", h.ns);
    }
    assert!(hits > 60, "{hits} hits on the brushed sphere");
}

/// KHR_materials_iridescence as tests/blender/film_room.py writes it for
/// Blender's Thin Film: each film material is the layered model with the file's
/// film (the ratified key iridescenceIor, read; the drafts' iridescenceIOR too),
/// and nothing about it is said to be ignored.
#[test]
fn a_thin_film_is_read() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/scenes/blender_film/blender_film.gltf");
    let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let film = |s: &pm_scene::Scene, name: &str| match s.materials.iter().find(|m| m.name == name).map(|m| m.bsdf) {
        Some(pm_bsdf::Bsdf::Layered(l)) => (l.metal, l.film),
        other => panic!("{name}: {other:?}"),
    };
    let (metal, f) = film(&s, "film_dielectric");
    assert!(!metal && f.weight == 1.0 && (f.ior - 1.8).abs() < 1e-6 && f.thickness == 320.0, "{f:?}");
    let (metal, f) = film(&s, "film_metal");
    assert!(metal && (f.ior - 1.5).abs() < 1e-6 && f.thickness == 250.0, "{f:?}");
    let text = std::fs::read_to_string(&path).unwrap().replace("iridescenceIor", "iridescenceIOR");
    let draft = tempfile::tempdir().unwrap();
    let copy = draft.path().join("blender_film.gltf");
    std::fs::write(&copy, text).unwrap();
    std::fs::copy(path.with_extension("bin"), copy.with_extension("bin")).unwrap();
    let (_, f) = film(&load(&copy).unwrap(), "film_dielectric");
    assert!((f.ior - 1.8).abs() < 1e-6, "the draft key: {f:?}");
}

/// Blender's Draco export of the coated room (`coated_room.py --draco`: its
/// default 14-bit positions, 10-bit normals, 12-bit texture coordinates)
/// loads as the uncompressed export does: every material's triangles, in the
/// same number, within the quantisation the file states (4 m room / 2^14 =
/// 0.24 mm) and with the same area to 0.2%, the tile's top face still
/// reading its yellow texels. It was refused (`KHR_draco_mesh_compression`
/// required). A Draco primitive whose data is cut short is one line naming it.
#[test]
fn blenders_draco_export_loads_as_the_uncompressed_one() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/scenes/blender_coated");
    let plain = load(&dir.join("blender_coated.gltf")).unwrap_or_else(|e| panic!("{e}"));
    let draco = load(&dir.join("blender_coated_draco.gltf")).unwrap_or_else(|e| panic!("{e}"));
    assert!(draco.warnings.is_empty(), "{:?}", draco.warnings);
    for m in &plain.materials {
        let tris = |s: &pm_scene::Scene| -> Vec<pm_scene::Triangle> {
            s.triangles.iter().filter(|t| s.materials[t.material as usize].name == m.name).cloned().collect()
        };
        let (a, b) = (tris(&plain), tris(&draco));
        assert_eq!(a.len(), b.len(), "{}", m.name);
        if a.is_empty() {
            continue;
        }
        let (x, y) = (pm_scene::bounds_of(&a), pm_scene::bounds_of(&b));
        let off = x.min.distance(y.min).max(x.max.distance(y.max));
        assert!(off < 5e-4, "'{}': bounds {off} m apart", m.name);
        // The surface's area (the vertices' positions together).
        let area = |t: &[pm_scene::Triangle]| t.iter().map(|t| t.area()).sum::<f32>();
        assert!((area(&a) - area(&b)).abs() < 2e-3 * area(&a), "'{}': area {} against {}", m.name, area(&b), area(&a));
    }
    let tile = draco.materials.iter().position(|m| m.name == "tile").unwrap();
    let tex = draco.materials[tile].base_texture.unwrap();
    let yellow = Vec3::new(0.85, 0.65, 0.05).map(pm_color::srgb_decode);
    for tri in draco.triangles.iter().filter(|t| t.material as usize == tile && t.ng().y > 0.99) {
        let c = draco.sample_at(&tex, tri, [0.3, 0.3, 0.4]).truncate();
        assert!((c - yellow).abs().max_element() < 0.01, "{c}");
    }
    // The compressed data cut to half: refused in one line.
    let tmp = tempfile::tempdir().unwrap().keep();
    let bin = std::fs::read(dir.join("blender_coated_draco.bin")).unwrap();
    std::fs::write(tmp.join("blender_coated_draco.bin"), &bin[..bin.len() / 2]).unwrap();
    let mut g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("blender_coated_draco.gltf")).unwrap()).unwrap();
    g["buffers"][0]["byteLength"] = serde_json::json!(bin.len() / 2);
    for v in g["bufferViews"].as_array_mut().unwrap() {
        let end = v["byteOffset"].as_u64().unwrap_or(0) + v["byteLength"].as_u64().unwrap();
        if end > (bin.len() / 2) as u64 {
            v["byteLength"] = serde_json::json!(
                ((bin.len() / 2) as u64).saturating_sub(v["byteOffset"].as_u64().unwrap_or(0)).max(1)
            );
        }
    }
    std::fs::copy(dir.join("tile.png"), tmp.join("tile.png")).unwrap();
    let path = tmp.join("cut.gltf");
    std::fs::write(&path, g.to_string()).unwrap();
    let err = load(&path).err().expect("cut Draco data is refused").to_string();
    assert!(!err.contains('\n') && err.contains("cut.gltf"), "{err}");
}

/// gltfpack's meshopt-compressed coated room (`-c`): a view whose compressed
/// bytes are damaged (its codec's header byte zeroed) is refused in one line
/// naming the file, the view and the extension; intact, it loads
/// (`tests/tests/suite/scenes.rs` renders it against the original).
#[test]
fn damaged_meshopt_data_is_one_line_naming_the_view() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/scenes/gltfpack");
    load(&dir.join("blender_coated_meshopt.gltf")).unwrap_or_else(|e| panic!("{e}"));
    let tmp = tempfile::tempdir().unwrap().keep();
    let g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("blender_coated_meshopt.gltf")).unwrap()).unwrap();
    let mut bin = std::fs::read(dir.join("blender_coated_meshopt.bin")).unwrap();
    let first = g["bufferViews"]
        .as_array()
        .unwrap()
        .iter()
        .find_map(|v| {
            v["extensions"]["EXT_meshopt_compression"]["byteOffset"]
                .as_u64()
                .or(v["extensions"]["EXT_meshopt_compression"].is_object().then_some(0))
        })
        .unwrap();
    bin[first as usize] = 0;
    std::fs::write(tmp.join("blender_coated_meshopt.bin"), &bin).unwrap();
    std::fs::copy(dir.join("tile.png"), tmp.join("tile.png")).unwrap();
    let path = tmp.join("damaged.gltf");
    std::fs::write(&path, g.to_string()).unwrap();
    let err = load(&path).err().expect("damaged data is refused").to_string();
    assert!(
        !err.contains('\n')
            && err.contains("damaged.gltf")
            && err.contains("EXT_meshopt_compression")
            && err.contains("buffer view"),
        "{err}"
    );
}

/// The coat's, sheen's and anisotropy's textures are read with their channels and
/// KHR_texture_transform: on textured.gltf's 2 x 1 texture (sRGB red left,
/// sRGB 188 blue right, NEAREST), clearcoatTexture's R is 1 on the left and 0
/// on the right, and an offset of half the width swaps them; sheenColorTexture
/// is decoded from sRGB; anisotropyTexture's B multiplies the strength (0 on the
/// red texel: isotropic there).
#[test]
fn layer_textures_are_read_with_their_channels_and_transforms() {
    let dir = tempfile::tempdir().unwrap().keep();
    let mut g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("textured.gltf")).unwrap()).unwrap();
    let bsdf = |g: &serde_json::Value, x: f32| {
        let path = dir.join("layers.gltf");
        std::fs::write(&path, g.to_string()).unwrap();
        let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
        let h = s.intersect(Vec3::new(x, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
        s.bsdf(&h)
    };
    let probe = |g: &serde_json::Value, x: f32| match bsdf(g, x) {
        pm_bsdf::Bsdf::Layered(l) => l,
        other => panic!("{other:?}"),
    };
    g["materials"][0]["extensions"] = serde_json::json!({
        "KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatTexture": {"index": 0}},
        "KHR_materials_sheen": {"sheenColorFactor": [1.0, 1.0, 1.0], "sheenColorTexture": {"index": 0}},
    });
    g["extensionsUsed"] = serde_json::json!(["KHR_materials_clearcoat", "KHR_materials_sheen"]);
    let (left, right) = (probe(&g, 0.25), probe(&g, 0.75));
    assert!(left.coat == 1.0 && right.coat == 0.0, "{} {}", left.coat, right.coat);
    let blue = pm_color::srgb_decode(188.0 / 255.0);
    assert!((left.sheen - Vec3::X).length() < 1e-6 && (right.sheen - Vec3::new(0.0, 0.0, blue)).length() < 1e-5);
    g["materials"][0]["extensions"]["KHR_materials_clearcoat"]["clearcoatTexture"]["extensions"] =
        serde_json::json!({"KHR_texture_transform": {"offset": [0.5, 0.0]}});
    let (left, right) = (probe(&g, 0.25), probe(&g, 0.75));
    assert!(left.coat == 0.0 && right.coat == 1.0, "with the offset: {} {}", left.coat, right.coat);
    g["materials"][0]["pbrMetallicRoughness"]["metallicFactor"] = serde_json::json!(1.0);
    g["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"] = serde_json::json!(0.5);
    g["materials"][0]["extensions"] = serde_json::json!({
        "KHR_materials_anisotropy": {"anisotropyStrength": 1.0, "anisotropyTexture": {"index": 0}}
    });
    g["extensionsUsed"] = serde_json::json!(["KHR_materials_anisotropy"]);
    // Strength 0 on the red texel: the plain isotropic conductor there.
    assert!(matches!(bsdf(&g, 0.25), pm_bsdf::Bsdf::Conductor { .. }), "{:?}", bsdf(&g, 0.25));
    let right = probe(&g, 0.75);
    assert!(right.alpha.x > right.alpha.y, "{:?}", right.alpha);
    // KHR_materials_iridescence: iridescenceTexture's R multiplies the weight,
    // iridescenceThicknessTexture's G blends the thickness from the minimum
    // (G 0 on both texels: the minimum) to the maximum.
    g["materials"][0]["pbrMetallicRoughness"]["metallicFactor"] = serde_json::json!(0.0);
    g["materials"][0]["extensions"] = serde_json::json!({
        "KHR_materials_iridescence": {
            "iridescenceFactor": 0.8, "iridescenceTexture": {"index": 0}, "iridescenceIor": 1.6,
            "iridescenceThicknessMinimum": 150.0, "iridescenceThicknessMaximum": 500.0,
            "iridescenceThicknessTexture": {"index": 0}
        }
    });
    g["extensionsUsed"] = serde_json::json!(["KHR_materials_iridescence"]);
    let left = probe(&g, 0.25);
    assert_eq!((left.film.weight, left.film.ior, left.film.thickness), (0.8, 1.6, 150.0), "{:?}", left.film);
    // No film where R is 0 (the blue texel): the plain dielectric.
    assert!(matches!(bsdf(&g, 0.75), pm_bsdf::Bsdf::Plastic { .. }), "{:?}", bsdf(&g, 0.75));
    g["materials"][0]["extensions"]["KHR_materials_iridescence"]
        .as_object_mut()
        .unwrap()
        .retain(|k, _| !k.ends_with("Texture"));
    let plain = probe(&g, 0.75);
    assert_eq!((plain.film.weight, plain.film.thickness), (0.8, 500.0), "without textures: {:?}", plain.film);
}

/// KHR_materials_anisotropy's rotation turns the direction counter-clockwise in
/// the tangent plane: a quarter turn runs it along the bitangent; a material
/// without TANGENTs gets them generated from its UVs.
#[test]
fn anisotropy_rotation_turns_the_direction_in_the_tangent_plane() {
    let dir = tempfile::tempdir().unwrap().keep();
    let mut g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("textured.gltf")).unwrap()).unwrap();
    g["materials"][0]["pbrMetallicRoughness"]["metallicFactor"] = serde_json::json!(1.0);
    g["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"] = serde_json::json!(0.5);
    let mut directions = Vec::new();
    for rotation in [0.0, std::f64::consts::FRAC_PI_2] {
        g["materials"][0]["extensions"] = serde_json::json!({
            "KHR_materials_anisotropy": {"anisotropyStrength": 0.6, "anisotropyRotation": rotation}
        });
        g["extensionsUsed"] = serde_json::json!(["KHR_materials_anisotropy"]);
        let path = dir.join(format!("aniso{rotation}.gltf"));
        std::fs::write(&path, g.to_string()).unwrap();
        let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
        let h = s.intersect(Vec3::new(0.3, 0.6, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
        let pm_bsdf::Bsdf::Layered(l) = s.bsdf(&h) else { panic!("{:?}", s.bsdf(&h)) };
        directions.push(l.tangent);
    }
    // The quad's u runs along x (textured.gltf), so the tangent is +x; a quarter
    // turn is +-y (the bitangent's sign follows the UVs' handedness).
    assert!((directions[0] - Vec3::X).length() < 1e-4, "{}", directions[0]);
    assert!(directions[1].dot(Vec3::X).abs() < 1e-4 && directions[1].y.abs() > 0.9999, "{}", directions[1]);
}

#[test]
fn base_colour_texture_is_sampled_in_linear_rgb() {
    // textured.gltf: a unit quad in z = 0 with a 2 x 1 PNG (sRGB red, sRGB 188 blue)
    // and baseColorFactor 0.5; u runs along x.
    let s = load(&data("textured.gltf")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.textures.len(), 1);
    let probe = |x: f32| {
        let h = s.intersect(Vec3::new(x, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
        match s.bsdf(&h) {
            pm_bsdf::Bsdf::Lambert { rho } | pm_bsdf::Bsdf::Plastic { rho, .. } => rho,
            other => panic!("{other:?}"),
        }
    };
    let red = probe(0.25);
    assert!((red - Vec3::new(0.5, 0.0, 0.0)).length() < 1e-4, "{red}");
    let blue = probe(0.75);
    let want = 0.5 * pm_color::srgb_decode(188.0 / 255.0);
    assert!((blue - Vec3::new(0.0, 0.0, want)).length() < 1e-4, "{blue}");
}

/// The glTF specification's light units (KHR_lights_punctual): point and spot
/// intensities in candela, directional in lux. The default reading divides them by
/// 683 lm/W; emissive materials (radiance) are read the same either way. So every
/// punctual light of the hand-made file carries 1/683 of its radiometric reading's
/// power, the glowing triangle the same power, and the two readings hash
/// differently (a photon map traced with one is refused with the other).
#[test]
fn photometric_intensities_are_divided_by_683() {
    let path = data("handmade.gltf");
    let photometric = load(&path).unwrap();
    let radiometric = load_with(&path, LightUnits::Radiometric).unwrap();
    assert_ne!(photometric.content_hash, radiometric.content_hash);
    for (p, r) in photometric.lights.iter().zip(&radiometric.lights) {
        let want = match r.kind {
            LightKind::Area { .. } => r.power,
            _ => r.power / 683.0,
        };
        assert!(((p.power - want).abs() / want).max_element() < 1e-6, "{}: {} vs {}", p.name, p.power, want);
    }
    assert_eq!(photometric.lights.len(), 4);
}

/// A scene whose lamp is written in candela (plane_point: 6830 cd) and the same scene
/// written in W/sr (10) and read radiometrically have the same lights exactly: the
/// analytic direct light of tests/tests/suite/effects.rs (rho/pi x 10 W/sr cos / d^2, through
/// the whole pipeline) holds for the photometric file.
#[test]
fn candela_and_watts_per_steradian_files_agree() {
    let scenes = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let candela = load(&scenes.join("plane_point.gltf")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scenes.join("plane_point.gltf")).unwrap();
    assert!(text.contains("\"intensity\": 6830.0"), "the file's lamp is written in candela");
    std::fs::write(dir.path().join("plane_point.gltf"), text.replace("\"intensity\": 6830.0", "\"intensity\": 10.0"))
        .unwrap();
    std::fs::copy(scenes.join("plane_point.bin"), dir.path().join("plane_point.bin")).unwrap();
    let watts = load_with(&dir.path().join("plane_point.gltf"), LightUnits::Radiometric).unwrap();
    assert_eq!(candela.lights.len(), 1);
    match (&candela.lights[0].kind, &watts.lights[0].kind) {
        (LightKind::Point { intensity: a, position: pa }, LightKind::Point { intensity: b, position: pb }) => {
            assert_eq!((a, pa), (b, pb));
            assert_eq!(*a, Vec3::splat(10.0));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(candela.lights[0].power, watts.lights[0].power);
}

/// Texture wrapping (glTF sampler wrapS / wrapT): a 2 x 1 texture [red, blue]
/// sampled at texel centres outside [0, 1] repeats, clamps or mirrors as the
/// sampler says, per axis; and the loader reads the sampler (textured.gltf with
/// its sampler given CLAMP_TO_EDGE and MIRRORED_REPEAT).
#[test]
fn texture_coordinates_wrap_as_the_sampler_says() {
    use pm_scene::{Texture, Wrap};
    let (red, blue) = (Vec3::X, Vec3::Z);
    let tex = |s: Wrap| Texture {
        wrap: [s, Wrap::Repeat],
        ..Texture::new(2, 1, vec![[255, 0, 0, 255], [0, 0, 255, 255]], true)
    };
    // Texel centres at u = 0.25 + k / 2.
    let at = |t: &Texture, u: f32| t.sample(glam::Vec2::new(u, 0.5)).truncate();
    let cases = [
        (Wrap::Repeat, [(1.25, red), (1.75, blue), (-0.25, blue), (-0.75, red)]),
        (Wrap::ClampToEdge, [(1.25, blue), (1.75, blue), (-0.25, red), (-0.75, red)]),
        (Wrap::MirroredRepeat, [(1.25, blue), (1.75, red), (-0.25, red), (-0.75, blue)]),
    ];
    for (wrap, probes) in cases {
        for (u, want) in probes {
            let got = at(&tex(wrap), u);
            assert!((got - want).length() < 1e-5, "{wrap:?} at u = {u}: {got}, want {want}");
        }
    }
    // The loader: the sampler's modes reach the texture.
    let text = std::fs::read_to_string(data("textured.gltf"))
        .unwrap()
        .replace("\"magFilter\": 9728,", "\"magFilter\": 9728,\n   \"wrapS\": 33071,\n   \"wrapT\": 33648,");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("wrapped.gltf");
    std::fs::write(&path, text).unwrap();
    let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.textures[0].wrap, [Wrap::ClampToEdge, Wrap::MirroredRepeat]);
    assert_eq!(load(&data("textured.gltf")).unwrap().textures[0].wrap, [Wrap::Repeat; 2]);
}

/// A base-colour texture reads the texture coordinate set it names (texCoord): the
/// textured quad with its coordinates moved to TEXCOORD_1 and nonsense in
/// TEXCOORD_0 samples as before when the material says texCoord 1, and not when it
/// says 0.
#[test]
fn base_colour_texture_reads_its_own_texcoord_set() {
    let original: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("textured.gltf")).unwrap()).unwrap();
    let variant = |tex_coord: u64| {
        let mut g = original.clone();
        // Accessor 3: the position bytes read as four VEC2 (not the quad's coordinates).
        g["accessors"].as_array_mut().unwrap().push(serde_json::json!(
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC2"}
        ));
        g["meshes"][0]["primitives"][0]["attributes"] =
            serde_json::json!({"POSITION": 0, "TEXCOORD_0": 3, "TEXCOORD_1": 1});
        g["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = tex_coord.into();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sets.gltf");
        std::fs::write(&path, g.to_string()).unwrap();
        let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
        [0.25f32, 0.75].map(|x| {
            let h = s.intersect(Vec3::new(x, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
            match s.bsdf(&h) {
                pm_bsdf::Bsdf::Lambert { rho } | pm_bsdf::Bsdf::Plastic { rho, .. } => rho,
                other => panic!("{other:?}"),
            }
        })
    };
    let (red, blue) = (Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.5 * pm_color::srgb_decode(188.0 / 255.0)));
    let [a, b] = variant(1);
    assert!((a - red).length() < 1e-4 && (b - blue).length() < 1e-4, "{a} {b}");
    let [a, b] = variant(0);
    assert!((a - red).length() > 1e-2 || (b - blue).length() > 1e-2, "{a} {b}");
}

/// KHR_texture_transform on the base-colour texture: uv' = offset + R (scale uv)
/// with R = [[cos, -sin], [sin, cos]] (the extension's GLSL matrix). On the
/// textured quad: an offset of half the texture swaps red and blue; at several
/// points, with offset, rotation and scale together, the colour is the texture at
/// the transformed coordinate (written here independently of the loader), which a
/// rotation of the opposite sense would not give.
#[test]
fn texture_transform_moves_the_base_colour_texture() {
    let original: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("textured.gltf")).unwrap()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let with = |t: serde_json::Value| {
        let mut g = original.clone();
        g["extensionsUsed"] = serde_json::json!(["KHR_texture_transform"]);
        g["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] =
            serde_json::json!({"KHR_texture_transform": t});
        let path = dir.path().join("transformed.gltf");
        std::fs::write(&path, g.to_string()).unwrap();
        load(&path).unwrap_or_else(|e| panic!("{e}"))
    };
    let probe = |s: &pm_scene::Scene, x: f32, y: f32| {
        let h = s.intersect(Vec3::new(x, y, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
        let rho = match s.bsdf(&h) {
            pm_bsdf::Bsdf::Lambert { rho } | pm_bsdf::Bsdf::Plastic { rho, .. } => rho,
            other => panic!("{other:?}"),
        };
        (rho, h.uv)
    };
    let shifted = with(serde_json::json!({"offset": [0.5, 0.0]}));
    let plain = load(&data("textured.gltf")).unwrap();
    for (a, b) in [(0.25, 0.75), (0.75, 0.25)] {
        let (got, _) = probe(&shifted, a, 0.5);
        let (want, _) = probe(&plain, b, 0.5);
        assert!((got - want).length() < 1e-4, "offset: at x = {a} {got}, want {want}");
    }
    let (r, sc, off) = (0.4f32, glam::Vec2::new(1.5, 0.7), glam::Vec2::new(0.1, 0.3));
    let all = with(serde_json::json!({"offset": [off.x, off.y], "rotation": r, "scale": [sc.x, sc.y]}));
    let tex = &all.textures[0];
    let mut differs_from_opposite = false;
    for (x, y) in [(0.1, 0.2), (0.3, 0.8), (0.6, 0.4), (0.9, 0.9), (0.45, 0.55)] {
        let (got, uv) = probe(&all, x, y);
        let q = uv * sc;
        let turned = |r: f32| glam::Vec2::new(r.cos() * q.x - r.sin() * q.y, r.sin() * q.x + r.cos() * q.y) + off;
        let want = 0.5 * tex.sample(turned(r)).truncate();
        assert!((got - want).length() < 1e-4, "at ({x}, {y}): {got}, want {want}");
        differs_from_opposite |= (0.5 * tex.sample(turned(-r)).truncate() - want).length() > 1e-3;
    }
    assert!(differs_from_opposite, "the probes cannot tell the rotation's sense");
}

/// What is not read yet is said, once, naming the material; what is read is not:
/// the textured quad given a metallicRoughness, normal and occlusion texture,
/// alphaMode MASK, volume attenuation and vertex colours. The volume's attenuation
/// is read as an absorption coefficient.
#[test]
fn ignored_material_features_are_warned_naming_the_material() {
    let mut g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data("textured.gltf")).unwrap()).unwrap();
    let m = &mut g["materials"][0];
    m["pbrMetallicRoughness"]["metallicRoughnessTexture"] = serde_json::json!({"index": 0});
    m["normalTexture"] = serde_json::json!({"index": 0});
    m["occlusionTexture"] = serde_json::json!({"index": 0});
    m["alphaMode"] = "MASK".into();
    m["extensions"] = serde_json::json!({
        "KHR_materials_transmission": {"transmissionFactor": 1.0},
        "KHR_materials_volume": {"thicknessFactor": 0.1, "attenuationDistance": 0.5, "attenuationColor": [1.0, 1.0, 1.0]}
    });
    m["extensions"]["KHR_materials_diffuse_transmission"] = serde_json::json!({"diffuseTransmissionFactor": 1.0});
    g["extensionsUsed"] =
        serde_json::json!(["KHR_materials_transmission", "KHR_materials_volume", "KHR_materials_diffuse_transmission"]);
    // COLOR_0: accessor 0 (the positions, a valid VEC3 float colour accessor).
    g["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = 0.into();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ignored.gltf");
    std::fs::write(&path, g.to_string()).unwrap();
    let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
    for what in ["occlusion texture", "extension KHR_materials_diffuse_transmission ignored"] {
        let n = s.warnings.iter().filter(|w| w.contains(what) && w.contains("material 'checker'")).count();
        assert_eq!(n, 1, "{what}: {:?}", s.warnings);
    }
    for read in ["metallicRoughness", "normal texture", "alphaMode", "COLOR_0", "attenuation"] {
        assert!(!s.warnings.iter().any(|w| w.contains(read)), "{read} is read: {:?}", s.warnings);
    }
    // A clear volume bounds a clear medium (the inside of solid glass), even open.
    let clear = s.medium(s.materials[0].interior).expect("a clear medium");
    assert!(clear.is_clear() && !s.has_media());
    // An absorbing one on the open quad is refused, naming the material.
    let text = g.to_string().replace("[1.0,1.0,1.0]", "[1.0,0.5,0.5]");
    std::fs::write(&path, text).unwrap();
    let e = load(&path).err().expect("an open mesh bounding a medium").to_string();
    assert!(e.contains("material 'checker'") && e.contains("closed mesh") && !e.contains('\n'), "{e}");
    // A thin-walled volume (thicknessFactor 0) has no inside: its attenuation is said
    // to be ignored.
    let text = g
        .to_string()
        .replace("\"thicknessFactor\":0.1", "\"thicknessFactor\":0.0")
        .replace("[1.0,1.0,1.0]", "[1.0,0.5,0.5]");
    std::fs::write(&path, text).unwrap();
    let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(s.materials[0].interior.is_none() && s.media.is_empty());
    assert_eq!(s.warnings.iter().filter(|w| w.contains("volume attenuation ignored")).count(), 1, "{:?}", s.warnings);
    // The plain file warns of none of them.
    assert!(load(&data("textured.gltf")).unwrap().warnings.is_empty());
}

/// Input at scale (`scenes/instanced.gltf`): three meshes stored once, instanced by
/// 100 nodes, become 1,464,962 world triangles; each mesh's accessors are decoded
/// (and its tangents generated) once, and every instance is that mesh moved rigidly:
/// the same triangle of two instances of a mesh has the same edge lengths and area,
/// at different places.
#[test]
fn instanced_meshes_load_once_and_place_every_instance() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes/instanced.gltf");
    let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.triangles.len(), 1_464_962);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let of = |name: &str| s.objects.iter().find(|o| o.name.starts_with(name)).unwrap_or_else(|| panic!("{name}"));
    // instance_i_j shows mesh (7 i + 3 j) % 3 = i % 3: the same for (0, 0) and (3, 5).
    let (a, b) = (of("instance_0_0 "), of("instance_3_5 "));
    assert_eq!(a.tris.len(), b.tris.len());
    for k in [0u32, 1000, a.tris.len() as u32 - 1] {
        let (ta, tb) = (&s.triangles[(a.tris.start + k) as usize], &s.triangles[(b.tris.start + k) as usize]);
        let edges = |t: &pm_scene::Triangle| [0, 1, 2].map(|i| (t.p[(i + 1) % 3] - t.p[i]).length());
        let (ea, eb) = (edges(ta), edges(tb));
        for i in 0..3 {
            assert!((ea[i] - eb[i]).abs() < 1e-5, "triangle {k}: edges {ea:?} vs {eb:?}");
        }
        assert!((ta.p[0] - tb.p[0]).length() > 1.0, "the instances are in different places");
        assert!(ta.tangent().is_some() && ta.uv().is_some(), "normal-mapped meshes carry tangents");
    }
}

/// Every point `Scene::plain_lambert` answers for gets exactly the hit record's
/// position and shading normal and the BSDF's reflectance there, and every
/// triangle `Scene::uniform_bsdf` answers for the BSDF at its hits; a surface
/// `plain_lambert` declines must not be plain (constant Lambertian, no vertex colours, no normal
/// map). Returns how many points it answered for and how many it declined.
fn check_plain_lambert(s: &pm_scene::Scene, name: &str) -> (usize, usize) {
    let (mut plain, mut other) = (0, 0);
    for tri in 0..s.triangles.len() as u32 {
        for b in [[1.0 / 3.0; 3], [0.7, 0.2, 0.1], [0.05, 0.05, 0.9]] {
            let hit = s.make_hit(tri, 1.0, b);
            let bsdf = s.bsdf(&hit);
            if let Some(u) = s.uniform_bsdf(tri) {
                assert_eq!(u, bsdf, "{name} triangle {tri}: uniform BSDF");
            }
            match s.plain_lambert(tri, b) {
                Some((p, ns, rho)) => {
                    plain += 1;
                    assert_eq!((p, ns), (hit.p, hit.ns), "{name} triangle {tri}");
                    assert!(matches!(bsdf, pm_bsdf::Bsdf::Lambert { rho: r } if r == rho), "{name} {tri}: {bsdf:?}");
                }
                None => {
                    other += 1;
                    let t = &s.triangles[tri as usize];
                    let m = &s.materials[t.material as usize];
                    let plain_material = matches!(m.bsdf, pm_bsdf::Bsdf::Lambert { .. })
                        && m.base_texture.is_none()
                        && t.color().is_none()
                        && m.normal_texture.is_none();
                    assert!(!plain_material, "{name} triangle {tri} is plain Lambertian but was declined");
                }
            }
        }
    }
    (plain, other)
}

/// `Scene::plain_lambert`, the G-buffer's shortcut, on scenes as written and on one
/// whose Lambertian surfaces are given vertex colours and normal maps (which it must
/// decline: both change the hit record or the BSDF).
#[test]
fn plain_lambert_equals_the_hit_record_and_bsdf() {
    let scenes = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let (mut plain, mut other) = (0, 0);
    for name in ["cornell_dense.gltf", "materials.gltf", "jozwowski_room_64.gltf"] {
        let s = load(&scenes.join(name)).unwrap_or_else(|e| panic!("{e}"));
        let (p, o) = check_plain_lambert(&s, name);
        (plain, other) = (plain + p, other + o);
    }
    assert!(plain > 1000 && other > 1000, "{plain} plain, {other} other");
    // Vertex colours on every other triangle, a normal map (tangents) on the rest.
    let mut s = load(&scenes.join("cornell_dense.gltf")).unwrap_or_else(|e| panic!("{e}"));
    s.textures.push(pm_scene::Texture::new(1, 1, vec![[200, 128, 255, 255]], false));
    let bumps =
        pm_scene::TextureRef { texture: s.textures.len() as u32 - 1, uv_set: 0, transform: glam::Affine2::IDENTITY };
    for m in &mut s.materials {
        m.normal_texture = Some(bumps);
    }
    for (i, t) in s.triangles.iter_mut().enumerate() {
        if i % 2 == 0 {
            t.extras_mut().color = Some([glam::Vec4::new(0.5, 0.7, 0.9, 1.0); 3]);
        } else {
            let tangent = (t.p[1] - t.p[0]).normalize().extend(1.0);
            t.extras_mut().tangent = Some([tangent; 3]);
        }
    }
    let (p, o) = check_plain_lambert(&s, "cornell_dense, coloured and normal-mapped");
    assert!(p == 0 && o > 1000, "{p} plain, {o} other");
}

/// A glTF file of one closed unit cube (12 outward triangles, centred on the origin)
/// with material `material` (JSON) and a camera at `eye`, its buffer beside it.
fn cube_file(dir: &Path, material: serde_json::Value, eye: [f32; 3]) -> PathBuf {
    let c = |i: usize| -> [f32; 3] { [(i & 1) as f32 - 0.5, ((i >> 1) & 1) as f32 - 0.5, ((i >> 2) & 1) as f32 - 0.5] };
    // Faces as corner indices (x = bit 0, y = bit 1, z = bit 2), counter-clockwise
    // seen from outside.
    let quads = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
    let mut bytes = Vec::new();
    for q in quads {
        for i in [q[0], q[1], q[2], q[0], q[2], q[3]] {
            for v in c(i) {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    std::fs::write(dir.join("cube.bin"), &bytes).unwrap();
    let g = serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_volume", "KHR_materials_volume_scatter"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"name": "cube", "mesh": 0}, {"name": "eye", "camera": 0, "translation": eye}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}],
        "materials": [material],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 36, "type": "VEC3",
            "min": [-0.5, -0.5, -0.5], "max": [0.5, 0.5, 0.5]}],
        "bufferViews": [{"buffer": 0, "byteLength": bytes.len()}],
        "buffers": [{"byteLength": bytes.len(), "uri": "cube.bin"}]
    });
    let path = dir.join("cube.gltf");
    std::fs::write(&path, g.to_string()).unwrap();
    path
}

/// KHR_materials_volume with KHR_materials_volume_scatter: sigma_t = -ln(c) / d,
/// the single-scattering albedo from scatterAlbedo (or the earlier draft's
/// multiscatterColor) by Kulla and Conty's fit, g from scatterAnisotropy; the camera
/// inside the cube is in its medium, outside it is not; bad values and an open
/// mesh are refused in one line naming the material.
#[test]
fn media_are_read_from_the_volume_extensions() {
    let dir = tempfile::tempdir().unwrap();
    let material = |scatter: serde_json::Value| {
        serde_json::json!({"name": "fog",
            "extensions": {
                "KHR_materials_transmission": {"transmissionFactor": 1.0},
                "KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationDistance": 2.0,
                    "attenuationColor": [0.5, 0.5, 0.25]},
                "KHR_materials_volume_scatter": scatter}})
    };
    let sigma_t = Vec3::new(0.5f32.ln(), 0.5f32.ln(), 0.25f32.ln()) / -2.0;
    for key in ["scatterAlbedo", "multiscatterColor"] {
        let path = cube_file(
            dir.path(),
            material(serde_json::json!({key: [0.8, 0.8, 0.0], "scatterAnisotropy": 0.3})),
            [0.0, 0.0, 0.1],
        );
        let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let id = s.materials[0].interior.expect("the cube bounds a medium");
        let m = &s.media[id as usize];
        let rho = pm_scene::single_scattering_albedo(Vec3::new(0.8, 0.8, 0.0));
        assert!(close(m.sigma_t(), sigma_t) && close(m.sigma_s, sigma_t * rho), "{key}: {m:?}");
        assert!((rho.x - 0.9906).abs() < 1e-3 && rho.z < 1e-4, "Kulla and Conty's fit: {rho}");
        assert_eq!(m.phase.g, 0.3);
        assert!(s.has_media() && s.has_scattering_media());
        assert_eq!(s.eye_medium(s.camera.as_ref().unwrap().position), Some(id), "the camera is inside the cube");
        assert_eq!(s.medium_at(Vec3::new(0.0, 2.0, 0.0)), None);
    }
    let path = cube_file(dir.path(), material(serde_json::json!({"scatterAlbedo": [0.5, 0.5, 0.5]})), [0.0, 0.0, 3.0]);
    let s = load(&path).unwrap();
    assert_eq!(s.eye_medium(s.camera.as_ref().unwrap().position), None, "the camera is outside the cube");
    // Bad values, each refused in one line naming the material.
    for (scatter, what) in [
        (serde_json::json!({"scatterAnisotropy": 1.0}), "g 1"),
        (serde_json::json!({"scatterAnisotropy": -1.5}), "g -1.5"),
        (serde_json::json!({"scatterAlbedo": [0.5, -0.1, 0.5]}), "scatterAlbedo"),
        (serde_json::json!({"scatterAlbedo": [0.5, 0.5]}), "scatterAlbedo"),
    ] {
        let path = cube_file(dir.path(), material(scatter), [0.0, 0.0, 3.0]);
        let e = load(&path).err().expect("refused").to_string();
        assert!(e.contains("material 'fog'") && e.contains(what) && !e.contains('\n'), "{what}: {e}");
    }
    // The cube less one triangle is open.
    let path = cube_file(dir.path(), material(serde_json::json!({})), [0.0, 0.0, 3.0]);
    let text = std::fs::read_to_string(&path).unwrap().replace("\"count\":36", "\"count\":33");
    std::fs::write(&path, text).unwrap();
    let e = load(&path).err().expect("an open cube").to_string();
    assert!(e.contains("material 'fog'") && e.contains("open edges"), "{e}");
}
