//! Repository rules as tests: the crate layers of ARCHITECTURE.md and its "knows
//! nothing about" column, read from every crate's Cargo.toml. A stage crate may not
//! depend on another stage crate, and no crate may depend on a layer above its own.

use std::collections::BTreeMap;
use std::path::PathBuf;

/// Layer of each crate, lowest first: a crate may depend only on crates of lower
/// layers (or, below the stage binaries, its own layer).
/// 0 vocabulary (colour, sampling, parameters, BSDFs); 1 data (the photon-map
/// file, the scene, the kd-tree); 2 the pieces every renderer shares (photon
/// tracing, estimates, the rasteriser, light sampling, images); 3 the image loop and integrators
/// (pm-render: nothing below it may depend on it); 4 what the real-time methods
/// share (pm-live: the frame loop and shading) and the progressive method; 5 the
/// real-time methods (never on each other); 6 the methods by name (pm-methods: the
/// one dispatch, every method's settings); 7 the stage shell and the pipeline as
/// data (pm-pipeline: settings, steps, job graph; pm-stage: what every stage
/// shares, and the statistics each writes); 8 stage binaries (never on each other,
/// and no library on them); 9 what runs the stage binaries as processes, by path
/// (pm-runner: the pipeline and job plans; pm-study: the trade-off and peer
/// studies); 10 the test crate. pm-scenegen (the glTF writer and the
/// project's scenes) sits with the pieces at 2.
const LAYERS: [(&str, u8); 31] = [
    ("pm-color", 0),
    ("pm-sampling", 0),
    ("pm-params", 0),
    ("pm-bsdf", 0),
    ("pm-format", 1),
    ("pm-scene", 1),
    ("pm-kdtree", 1),
    ("pm-photon", 2),
    ("pm-estimate", 2),
    ("pm-raster", 2),
    ("pm-light", 2),
    ("pm-image", 2),
    ("pm-scenegen", 2),
    ("pm-render", 3),
    ("pm-live", 4),
    ("pm-sppm", 4),
    ("pm-bdpt", 4),
    ("pm-vertex", 5),
    ("pm-ispm", 5),
    ("pm-methods", 6),
    ("pm-stage", 7),
    ("pm-pipeline", 7),
    ("photon-trace", STAGE),
    ("photon-sort", STAGE),
    ("photon-irradiance", STAGE),
    ("photon-render", STAGE),
    ("photon-inspect", STAGE),
    ("photon-live", STAGE),
    ("pm-runner", 9),
    ("pm-study", 9),
    ("pm-tests", 10),
];

/// The layer of the stage binaries.
const STAGE: u8 = 8;

/// ARCHITECTURE.md's "knows nothing about" column, as crates each may not use.
const KNOWS_NOTHING_ABOUT: [(&str, &[&str]); 16] = [
    ("pm-params", &["pm-color", "pm-sampling", "pm-bsdf"]),
    ("pm-sampling", &["pm-color", "pm-bsdf", "pm-scene"]),
    ("pm-bsdf", &["pm-scene", "pm-format", "pm-photon"]),
    ("pm-scene", &["pm-format", "pm-kdtree", "pm-photon", "pm-estimate", "pm-image"]),
    ("pm-format", &["pm-scene", "pm-kdtree", "pm-estimate", "pm-photon", "pm-render", "pm-image"]),
    ("pm-kdtree", &["pm-scene", "pm-estimate", "pm-photon", "pm-image"]),
    ("pm-photon", &["pm-kdtree", "pm-estimate", "pm-render", "pm-image"]),
    ("pm-estimate", &["pm-scene", "pm-photon", "pm-render", "pm-image"]),
    ("pm-raster", &["pm-bsdf", "pm-format", "pm-kdtree", "pm-photon", "pm-estimate", "pm-image"]),
    ("pm-light", &["pm-format", "pm-kdtree", "pm-photon", "pm-estimate", "pm-render", "pm-image"]),
    ("pm-render", &["pm-photon", "pm-image"]),
    ("pm-image", &["pm-scene", "pm-kdtree", "pm-photon", "pm-estimate", "pm-render"]),
    ("pm-live", &["pm-format", "pm-kdtree", "pm-photon", "pm-estimate", "pm-image"]),
    ("pm-vertex", &["pm-ispm", "pm-image"]),
    ("pm-sppm", &["pm-live", "pm-image"]),
    ("pm-ispm", &["pm-vertex", "pm-format", "pm-estimate", "pm-image"]),
];

/// Each workspace crate and the workspace crates in its `[dependencies]`.
fn dependencies() -> BTreeMap<String, Vec<String>> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut manifests: Vec<PathBuf> =
        std::fs::read_dir(root.join("crates")).unwrap().map(|e| e.unwrap().path().join("Cargo.toml")).collect();
    manifests.push(root.join("tests/Cargo.toml"));
    let mut out = BTreeMap::new();
    for m in manifests {
        let text = std::fs::read_to_string(&m).unwrap();
        let doc: toml::Table = toml::from_str(&text).unwrap();
        let name = doc["package"]["name"].as_str().unwrap().to_string();
        let deps = doc
            .get("dependencies")
            .and_then(|d| d.as_table())
            .map(|t| t.keys().filter(|k| k.starts_with("pm-") || k.starts_with("photon-")).cloned().collect())
            .unwrap_or_default();
        out.insert(name, deps);
    }
    out
}

#[test]
fn crates_depend_only_downward_and_stages_never_on_each_other() {
    let layer: BTreeMap<&str, u8> = LAYERS.into_iter().collect();
    let mut problems = Vec::new();
    for (name, deps) in dependencies() {
        let Some(&own) = layer.get(name.as_str()) else {
            problems.push(format!(
                "{name} has no layer in tests/tests/suite/tidy.rs (add it there and to ARCHITECTURE.md)"
            ));
            continue;
        };
        for d in deps {
            let theirs = layer.get(d.as_str()).copied().unwrap_or(u8::MAX);
            if theirs > own || (own == STAGE && theirs == STAGE) {
                problems.push(format!("{name} (layer {own}) depends on {d} (layer {theirs})"));
            }
            if theirs == STAGE && own != STAGE {
                problems.push(format!("{name} is a library and depends on the stage crate {d}"));
            }
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
}

/// xtask is a program over library crates: it has no library, and no crate uses it
/// (tests run the pipeline through pm-runner, write scenes through pm-scenegen).
#[test]
fn nothing_depends_on_xtask() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    assert!(
        !root.join("xtask/src/lib.rs").exists(),
        "xtask/src/lib.rs: move what other crates need into a library crate"
    );
    let mut manifests: Vec<PathBuf> =
        std::fs::read_dir(root.join("crates")).unwrap().map(|e| e.unwrap().path().join("Cargo.toml")).collect();
    manifests.push(root.join("tests/Cargo.toml"));
    let mut problems = Vec::new();
    for m in manifests {
        let doc: toml::Table = toml::from_str(&std::fs::read_to_string(&m).unwrap()).unwrap();
        for section in ["dependencies", "dev-dependencies", "build-dependencies"] {
            if doc.get(section).and_then(|d| d.as_table()).is_some_and(|t| t.contains_key("xtask")) {
                problems.push(format!("{}: [{section}] names xtask", m.display()));
            }
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
}

#[test]
fn crates_know_nothing_about_what_architecture_md_says() {
    let deps = dependencies();
    let mut problems = Vec::new();
    for (name, forbidden) in KNOWS_NOTHING_ABOUT {
        for d in deps.get(name).unwrap_or_else(|| panic!("{name} is not in crates/")) {
            if forbidden.contains(&d.as_str()) {
                problems.push(format!("{name} depends on {d}"));
            }
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
}

/// pm-render's settings hold only what its own integrators (the photon-map
/// integrators and the path tracer) read: no key shares a name with another
/// method's settings or is named for another method (`sppm_*`, and so for each
/// method added to pm-methods). A method's settings live in its own crate.
#[test]
fn the_renderers_settings_hold_no_other_methods_keys() {
    use clap::ValueEnum;
    let own = ["full", "photons", "radiance", "indirect", "path"];
    let others: Vec<String> = pm_methods::Method::value_variants()
        .iter()
        .map(|m| m.to_string())
        .filter(|m| !own.contains(&m.as_str()))
        .collect();
    assert!(others.contains(&"sppm".to_string()), "{others:?}");
    let mut problems = Vec::new();
    for key in pm_render::RenderParams::FIELDS {
        if pm_sppm::SppmParams::FIELDS.contains(key) {
            problems.push(format!("render.{key} is also sppm.{key}"));
        }
        for m in &others {
            if key.starts_with(&format!("{m}_")) || *key == m.as_str() {
                problems.push(format!("render.{key} is named for --mode {m}: move it to that method's crate"));
            }
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
}
