//! `Scene::memory_use` against the heap: an allocator that counts (the `cap`
//! crate, safe to install as the global allocator) measures what a loaded scene
//! keeps, an estimate independent of the accounting.

#[global_allocator]
static ALLOCATOR: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, usize::MAX);

/// The accounting covers what the scene keeps: on cornell_dense and on the
/// textured materials scene, the heap grows by the accounted bytes when a scene
/// is loaded and kept (within 10%: small tables are not counted; materials
/// are since the layered BSDF of stop 74 made them large enough to matter). On
/// cornell_dense (108,300 generated triangles with normals) it keeps at most 160 bytes per triangle (measured 152; 452 before triangles kept their
/// texture coordinates, colours and tangents apart, computed their normal and area
/// when asked, and the BVH stopped padding every leaf and keeping slot ids twice),
/// and the load's heap peaks at most at issue 36's budget of 200 bytes per
/// triangle (measured 164; 361 with obvhs's PLOC build).
#[test]
fn memory_use_accounts_for_what_a_loaded_scene_keeps() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    for name in ["cornell_dense.gltf", "materials.gltf"] {
        let before = ALLOCATOR.allocated();
        let scene = pm_scene::load(&root.join(name)).unwrap();
        let kept = (ALLOCATOR.allocated() - before) as f64;
        // Nothing larger was held before this test's first load.
        let peak = (ALLOCATOR.max_allocated() - before) as f64;
        let m = scene.memory_use();
        let n = scene.triangles.len();
        eprintln!(
            "{name}: {n} triangles, heap kept {:.3} MB, accounted {:.3} MB: {m}; {:.0} bytes per triangle",
            kept / 1e6,
            m.total() as f64 / 1e6,
            m.per_triangle(n)
        );
        assert!((m.total() as f64 - kept).abs() < 0.1 * kept, "{name}: accounted {} of {kept} bytes kept", m.total());
        if name == "cornell_dense.gltf" {
            eprintln!("{name}: the load's heap peak {:.0} bytes per triangle", peak / n as f64);
            assert!(m.per_triangle(n) <= 160.0, "{name}: {:.0} bytes per triangle", m.per_triangle(n));
            assert!(peak <= 200.0 * n as f64, "{name}: the load peaked at {:.0} bytes per triangle", peak / n as f64);
        }
        drop(scene);
    }
}

/// The load's heap peak and what it keeps, for a scene named by `PM_SCENE` (the
/// big scenes of `cargo xtask gen-scenes --big` are not committed): a figure for
/// BENCHMARKS.md, not a check.
/// `PM_SCENE=out/big-scenes/spheres_1m.gltf cargo test --release -p pm-scene --test memory -- --ignored --nocapture`
#[test]
#[ignore]
fn load_peak_of_the_scene_in_pm_scene() {
    let Ok(path) = std::env::var("PM_SCENE") else { return };
    let before = ALLOCATOR.allocated();
    let scene = pm_scene::load(std::path::Path::new(&path)).unwrap();
    let n = scene.triangles.len();
    let (kept, peak) = (ALLOCATOR.allocated() - before, ALLOCATOR.max_allocated());
    eprintln!(
        "{path}: {n} triangles; heap kept {:.1} MB ({:.0} bytes per triangle), peak {:.1} MB ({:.0} bytes per triangle): {}",
        kept as f64 / 1e6,
        kept as f64 / n as f64,
        peak as f64 / 1e6,
        peak as f64 / n as f64,
        scene.memory_use()
    );
}
