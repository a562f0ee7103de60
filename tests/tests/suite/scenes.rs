//! The committed scenes are exactly what `cargo xtask gen-scenes` generates.

#[test]
fn committed_scenes_are_up_to_date() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    if let Err(e) = pm_scenegen::scenes::run(&dir, true) {
        panic!("{e:#}");
    }
}

/// A scene that requires a glTF extension the renderer does not read (here a
/// committed scene marked as needing the old specular-glossiness materials,
/// its first accessor's data gone as well) stops `cargo xtask run` before anything is written, with the
/// stage's one line naming the file and the extension and exit code 2 (kept
/// through the runner, `pm_stage::is_unsupported`); a stage run alone exits with
/// 2 and writes no image.
#[test]
fn a_scene_needing_an_extension_not_read_stops_the_run_with_exit_code_2_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let mut g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(scenes.join("cornell_boxes.gltf")).unwrap()).unwrap();
    g["accessors"][0].as_object_mut().unwrap().remove("bufferView");
    g["extensionsRequired"] = serde_json::json!(["KHR_materials_pbrSpecularGlossiness"]);
    g["extensionsUsed"] = serde_json::json!(["KHR_materials_pbrSpecularGlossiness"]);
    std::fs::copy(scenes.join("cornell_boxes.bin"), dir.path().join("cornell_boxes.bin")).unwrap();
    let scene = dir.path().join("glossiness.gltf");
    std::fs::write(&scene, g.to_string()).unwrap();
    let out = dir.path().join("out");
    let args = pm_runner::run::RunArgs { scene: Some(scene.clone()), out: Some(out.clone()), ..Default::default() };
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let e = pm_runner::run::run_with(&args, &root, &pm_tests::bins()).expect_err("the run succeeded");
    let msg = format!("{e:#}");
    assert!(pm_stage::is_unsupported(&e), "{msg}");
    assert!(
        msg.contains("glossiness.gltf") && msg.contains("KHR_materials_pbrSpecularGlossiness") && !msg.contains('\n'),
        "{msg}"
    );
    assert!(!out.exists(), "the run created {}", out.display());
    let image = dir.path().join("image.exr");
    let status = std::process::Command::new(pm_tests::bins().path("photon-render"))
        .args(["--scene", scene.to_str().unwrap(), "--mode", "path", "--out", image.to_str().unwrap()])
        .stderr(std::process::Stdio::null())
        .status()
        .unwrap();
    assert_eq!(status.code(), Some(2));
    assert!(!image.exists());
}

/// gltfpack's quantised files (tests/scenes/gltfpack, `KHR_mesh_quantization`,
/// required): positions as 16-bit integers placed by the node's scale, normals
/// as normalised bytes, texture coordinates as normalised 16-bit integers under
/// a texture transform. They were refused; they now load as their originals:
/// every object's bounds within the file's quantisation step (the room's 2 m in
/// 14 bits: 0.12 mm; also for a box 1,000 km from the origin, which the loader
/// moves near its camera), the path tracer's image of the quantised Cornell box
/// within 0.5% of the original's in mean and 3% in every 8 x 8 block (same seed,
/// 32 x 32, 64 a pixel), and the Blender tile's top face still shows only its
/// yellow texel (NEAREST sampling through quantised coordinates). The same for
/// gltfpack's meshopt-compressed files (`EXT_meshopt_compression`, required;
/// refused until stop 74): the coated room (`-c`), the Cornell box with its
/// normals octahedral-filtered (`-cc`) and with float positions
/// exponent-filtered (`-cc -vpf`), decoded into their fallback buffers.
#[test]
fn gltfpacks_quantised_scenes_load_and_render_as_their_originals() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/scenes");
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let pairs = [
        (root.join("cornell_spheres.gltf"), dir.join("gltfpack/cornell_spheres_quantized.gltf")),
        (dir.join("blender_coated/blender_coated.gltf"), dir.join("gltfpack/blender_coated_quantized.gltf")),
        // The box placed 1,000 km out (a parent node's translation), packed:
        // loaded near its camera, it must land where the original does.
        (root.join("cornell_boxes.gltf"), dir.join("gltfpack/cornell_boxes_far_quantized.gltf")),
        // EXT_meshopt_compression (required): `-c` (vertex and index codecs),
        // `-cc` (normals through the OCTAHEDRAL filter), `-cc -vpf` (float
        // positions through the EXPONENTIAL filter).
        (dir.join("blender_coated/blender_coated.gltf"), dir.join("gltfpack/blender_coated_meshopt.gltf")),
        (root.join("cornell_spheres.gltf"), dir.join("gltfpack/cornell_spheres_meshopt.gltf")),
        (root.join("cornell_boxes.gltf"), dir.join("gltfpack/cornell_boxes_meshopt_exp.gltf")),
    ];
    for (original, packed) in &pairs {
        let (a, b) = (pm_scene::load(original).unwrap(), pm_scene::load(packed).unwrap());
        // gltfpack merges meshes: each material's triangles are compared.
        let bounds = |s: &pm_scene::Scene, name: &str| {
            let tris: Vec<pm_scene::Triangle> =
                s.triangles.iter().filter(|t| s.materials[t.material as usize].name == name).cloned().collect();
            (tris.len(), pm_scene::bounds_of(&tris))
        };
        for m in
            a.materials.iter().filter(|m| a.triangles.iter().any(|t| a.materials[t.material as usize].name == m.name))
        {
            let ((n, x), (k, y)) = (bounds(&a, &m.name), bounds(&b, &m.name));
            let off = x.min.distance(y.min).max(x.max.distance(y.max));
            assert!(
                n == k && off < 3e-4,
                "{}: '{}': {k} of {n} triangles, bounds {off} m apart",
                packed.display(),
                m.name
            );
        }
    }
    let mut cfg = pm_tests::render_params(pm_methods::Method::Path, 32, 32);
    cfg.render.spp = 256;
    let none = (Vec::new(), Vec::new());
    for (original, packed) in [&pairs[0], &pairs[4], &pairs[3]] {
        let (a, b) = (pm_scene::load(original).unwrap(), pm_scene::load(packed).unwrap());
        let (ia, _) = pm_tests::render(&a, &none, &cfg);
        let (ib, _) = pm_tests::render(&b, &none, &cfg);
        let g = pm_tests::agreement_off_the_light(ib.total(), ia.total(), 32);
        eprintln!("{} against the original: {g}", packed.display());
        assert!(g.mean.abs() < 0.005 && g.worst_block < 0.03, "{}: {g}", packed.display());
    }
    let s = pm_scene::load(&pairs[1].1).unwrap();
    let tile = s.materials.iter().position(|m| m.name == "tile").unwrap();
    let tex = s.materials[tile].base_texture.unwrap();
    let yellow = glam::Vec3::new(0.85, 0.65, 0.05).map(pm_color::srgb_decode);
    let top: Vec<&pm_scene::Triangle> =
        s.triangles.iter().filter(|t| t.material as usize == tile && t.ng().y > 0.99).collect();
    assert_eq!(top.len(), 2, "the tile's top face");
    for tri in top {
        let c = s.sample_at(&tex, tri, [0.3, 0.3, 0.4]).truncate();
        assert!((c - yellow).abs().max_element() < 0.01, "{c}");
    }
}

/// Blender's coated room as a user who wants small files exports it, Draco
/// meshes (`coated_room.py --draco`) and also WebP images (`--draco --webp`;
/// 31 KB against 160 KB), renders as the uncompressed export does: the path
/// tracer's image (same seed, 32 x 32, 256 a pixel) within 0.3% in mean and 3%
/// in every 8 x 8 block for Draco (its 14-bit positions; at 64 x 64 and 512 a
/// pixel: bias 0.001%), within 1.5% and 10% with WebP too, whose lossy tile is
/// 3-8% darker in its blocks (Blender's WebP export is lossy; the texels are
/// the ones Blender decodes, `materials::blenders_webp_export_loads_with_the_texels_blender_decodes`).
/// The tile as a KTX2 image with UASTC data gives the same image exactly. Draco
/// and KTX2 files were refused (`KHR_draco_mesh_compression`,
/// `KHR_texture_basisu` required) until stop 74.
#[test]
fn blenders_draco_and_webp_exports_render_as_the_uncompressed_one() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/scenes/blender_coated");
    let mut cfg = pm_tests::render_params(pm_methods::Method::Path, 32, 32);
    cfg.render.spp = 256;
    let none = (Vec::new(), Vec::new());
    let image = |name: &str| {
        let s = pm_scene::load(&dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(s.warnings.is_empty(), "{name}: {:?}", s.warnings);
        pm_tests::render(&s, &none, &cfg).0
    };
    let plain = image("blender_coated.gltf");
    for (name, mean, worst) in [
        ("blender_coated_draco.gltf", 0.003, 0.03),
        ("blender_coated_draco_webp.gltf", 0.015, 0.10),
        // The tile as KTX2 with UASTC data (KHR_texture_basisu): its texels
        // come back exactly, so the image is the PNG twin's.
        ("blender_coated_ktx2.gltf", 1e-6, 1e-6),
    ] {
        let g = pm_tests::agreement_off_the_light(image(name).total(), plain.total(), 32);
        eprintln!("{name} against the uncompressed export: {g}");
        assert!(g.mean.abs() < mean && g.worst_block < worst, "{name}: {g}");
    }
}
