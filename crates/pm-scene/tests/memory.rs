//! `Scene::memory_use` against the heap: an allocator that counts (the `cap`
//! crate, safe to install as the global allocator) measures what a loaded scene
//! keeps, an estimate independent of the accounting.

#[global_allocator]
static ALLOCATOR: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, usize::MAX);

/// The accounting covers what the scene keeps: on cornell_dense and on the
/// textured materials scene, the heap grows by the accounted bytes when a scene
/// is loaded and kept (within 10%: names, materials and small tables are not
/// counted).
#[test]
fn memory_use_accounts_for_what_a_loaded_scene_keeps() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    for name in ["cornell_dense.gltf", "materials.gltf"] {
        let before = ALLOCATOR.allocated();
        let scene = pm_scene::load(&root.join(name)).unwrap();
        let kept = (ALLOCATOR.allocated() - before) as f64;
        let m = scene.memory_use();
        let n = scene.triangles.len();
        eprintln!(
            "{name}: {n} triangles, heap kept {:.2} MB, accounted {m}; {:.0} bytes per triangle",
            kept / 1e6,
            m.per_triangle(n)
        );
        assert!((m.total() as f64 - kept).abs() < 0.1 * kept, "{name}: accounted {} of {kept} bytes kept", m.total());
        drop(scene);
    }
}
