use super::*;
use pm_bsdf::Bsdf;
use std::path::PathBuf;

fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name)
}

fn load_scene(name: &str) -> Scene {
    load(&scene_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn project_scenes_load_with_expected_content() {
    let s = load_scene("cornell_spheres.gltf");
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    assert_eq!(s.lights.len(), 1);
    // Light: 0.5 m square, L_e = 12: Phi = pi L_e A.
    let expected = std::f32::consts::PI * 12.0 * 0.25;
    assert!((s.lights[0].power.x - expected).abs() < 1e-3 * expected, "{}", s.lights[0].power);
    let cam = s.camera.as_ref().unwrap();
    assert!((cam.position - Vec3::new(0.0, 1.0, 3.8)).length() < 1e-6);
    assert!((cam.forward - Vec3::NEG_Z).length() < 1e-6);
    let kinds: Vec<_> = s.materials.iter().map(|m| (m.name.as_str(), m.bsdf)).collect();
    assert!(kinds.iter().any(|(n, b)| *n == "chrome" && matches!(b, Bsdf::Mirror { .. })));
    assert!(kinds.iter().any(|(n, b)| *n == "glass" && matches!(b, Bsdf::Glass { thin: false, .. })));
    assert!(kinds.iter().any(|(n, b)| *n == "red" && matches!(b, Bsdf::Lambert { .. })));
    assert!(
        (s.bounds.min - Vec3::new(-1.0, 0.0, -1.0)).length() < 1e-6
            && (s.bounds.max - Vec3::new(1.0, 2.0, 1.0)).length() < 1e-6
    );

    let f = load_scene("furnace.gltf");
    assert_eq!(f.lights.len(), 1);
    assert!(
        f.triangles.iter().all(|t| t.ng().dot(-(t.p[0] + t.p[1] + t.p[2]) / 3.0) > 0.0),
        "furnace faces point inward"
    );
    let b = load_scene("cornell_boxes.gltf");
    assert!(b.triangles.len() > 12);
}

#[test]
fn closest_hits_match_hand_computed_values() {
    let s = load_scene("cornell_boxes.gltf");
    // Camera axis hits the back wall z = -1: t = 3.8 + 1.
    let h = s.intersect(Vec3::new(0.0, 1.9, 3.8), Vec3::NEG_Z, f32::INFINITY).unwrap();
    assert!((h.t - 4.8).abs() < 1e-5, "{}", h.t);
    assert!((h.p - Vec3::new(0.0, 1.9, -1.0)).length() < 1e-5);
    assert!((h.ng - Vec3::Z).length() < 1e-6);
    // Straight down from 1 m above the floor, clear of the blocks.
    let h = s.intersect(Vec3::new(-0.9, 1.0, 0.9), Vec3::NEG_Y, f32::INFINITY).unwrap();
    assert!((h.t - 1.0).abs() < 1e-6 && (h.ng - Vec3::Y).length() < 1e-6);
    // Straight up hits the light 2 mm below the ceiling; it emits downward only.
    let h = s.intersect(Vec3::new(0.1, 1.0, 0.1), Vec3::Y, f32::INFINITY).unwrap();
    assert!((h.t - 0.998).abs() < 1e-5, "{}", h.t);
    assert_eq!(s.material(&h).name, "ceiling_light");
    assert_eq!(s.emitted(&h, Vec3::NEG_Y), Rgb::splat(12.0));
    assert_eq!(s.emitted(&h, Vec3::Y), Rgb::ZERO);
    // Diagonal ray to a known wall point: from (0,1,0) toward (1, 1.5, 0.5) on the right wall.
    let target = Vec3::new(1.0, 1.5, 0.5);
    let o = Vec3::new(0.0, 1.0, 0.0);
    let h = s.intersect(o, (target - o).normalize(), f32::INFINITY).unwrap();
    assert!((h.t - (target - o).length()).abs() < 1e-5, "{}", h.t);
    // The point lies on the wall quad's diagonal, an edge of both its triangles:
    // the hit moves inside one by at most EDGE_INSET of its 2 m size.
    assert!((h.p - target).length() < 2.0 * 2.0 * crate::accel::EDGE_INSET, "{}", h.p);
    assert_eq!(s.material(&h).name, "blue");
    // t_max stops the search; shadow rays agree.
    assert!(s.intersect(o, (target - o).normalize(), 0.5).is_none());
    assert!(!s.occluded(o, (target - o).normalize(), 0.5));
    assert!(s.occluded(o, (target - o).normalize(), 2.0));
}

#[test]
fn sphere_hit_has_smooth_normal_and_barycentrics() {
    let s = load_scene("cornell_spheres.gltf");
    // Chrome sphere: centre (-0.45, 0.35, -0.35), r = 0.35; from +z along -z.
    let h = s.intersect(Vec3::new(-0.45, 0.35, 3.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
    assert!((h.t - 3.0).abs() < 2e-3, "{}", h.t); // tessellation error of the 48x24 sphere
    assert!((h.ns - Vec3::Z).length() < 0.01, "{}", h.ns);
    assert!((h.b.iter().sum::<f32>() - 1.0).abs() < 1e-5);
    assert_eq!(s.material(&h).name, "chrome");
}

#[test]
fn offset_origins_avoid_self_intersection_at_any_scale() {
    // A large random-ish set of points on a tilted triangle far from the origin and
    // close to it: rays leaving the offset point never re-hit the triangle.
    for scale in [1e-3f32, 1.0, 1e4, 1e5] {
        let p = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.2, 0.1), Vec3::new(0.1, 0.3, 1.0)]
            .map(|v| v * scale + Vec3::splat(scale * 3.0));
        let ng = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        let mut hits = 0;
        for i in 0..2000u64 {
            let mut s = pm_sampling::Sampler::new(9, i);
            let b = pm_sampling::uniform_triangle(s.next_2d());
            let x = p[0] * b.x + p[1] * b.y + p[2] * (1.0 - b.x - b.y);
            let mut d = pm_sampling::to_world(pm_sampling::cosine_hemisphere(s.next_2d()), ng);
            if i % 2 == 1 {
                d = -d;
            }
            let o = offset_ray_origin(x, ng, d, scale);
            if intersect_triangle(o, d, &p, f32::INFINITY).is_some() {
                hits += 1;
            }
        }
        assert_eq!(hits, 0, "scale {scale}");
    }
}

/// A concave edge far from the origin: a point on a wall (normal +x) interpolated
/// one ulp under the floor it stands on (y = -352 m, where f32 spacing is 3e-5 m),
/// as hits at a wall-floor edge were in cornell_boxes 1e5 m away. A ray toward a
/// light above must start above the floor: offsetting along the wall's normal only
/// left it under the floor, and the floor blocked every such ray.
#[test]
fn offset_origins_leave_a_concave_edge_on_the_rays_side() {
    let y = -352.0f32;
    let floor = [Vec3::new(-400.0, y, -400.0), Vec3::new(-400.0, y, -300.0), Vec3::new(-300.0, y, -350.0)];
    let under = f32::from_bits(y.to_bits() + 1); // one ulp further from zero: below
    assert!(under < y);
    let p = Vec3::new(-350.0, under, -350.0);
    for w in [Vec3::new(0.3, 0.9, 0.1), Vec3::new(0.9, 0.3, -0.2), Vec3::new(0.05, 0.99, 0.0)] {
        let w = w.normalize();
        let o = offset_ray_origin(p, Vec3::X, w, 200.0);
        assert!(o.y > y, "{w}: origin {o} under the floor");
        assert!(intersect_triangle(o, w, &floor, f32::INFINITY).is_none(), "{w}: the floor blocks the ray");
    }
}

#[test]
fn watertight_edges_are_not_missed() {
    // Rays aimed exactly at the shared diagonal of a two-triangle quad hit one of them.
    let a = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)];
    let b = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
    for i in 0..1000 {
        let x = -1.0 + 2.0 * (i as f32 + 0.5) / 1000.0;
        let o = Vec3::new(0.3, -0.2, 5.0);
        let d = (Vec3::new(x, x, 0.0) - o).normalize();
        let hit = intersect_triangle(o, d, &a, f32::INFINITY).or(intersect_triangle(o, d, &b, f32::INFINITY));
        assert!(hit.is_some(), "ray through the shared edge at x = {x} slipped through");
    }
}

#[test]
fn camera_rays_round_trip_through_projection() {
    let s = load_scene("cornell_spheres.gltf");
    let cam = s.camera.as_ref().unwrap();
    for (x, y) in [(0.5f32, 0.5f32), (0.1, 0.9), (0.8, 0.2)] {
        let d = cam.ray_direction(x, y, 1.5);
        let q = cam.project(cam.position + d * 3.0, 1.5).unwrap();
        assert!((q - Vec2::new(x, y)).length() < 1e-5);
    }
    // Row 0 is the top: y = 0 looks up.
    assert!(cam.ray_direction(0.5, 0.0, 1.0).y > 0.0);
}

/// Subdivision (Jozwowski 2002 section 4.3) splits triangles until no edge is
/// longer than the limit, keeps the surface (area, every ray's hit
/// point and shading normal), the objects, and each light's power; a light's
/// own triangles stay whole (so points near it sample it by solid angle).
#[test]
fn subdivision_keeps_the_surface_lights_and_objects() {
    let s = load_scene("cornell_spheres.gltf");
    let sub = s.subdivided(0.25);
    // The walls split (2 m quads); the spheres' small triangles stay whole.
    assert!(sub.triangles.len() > s.triangles.len() + 1000, "{} -> {}", s.triangles.len(), sub.triangles.len());
    let emits = |sc: &Scene, t: &Triangle| sc.materials[t.material as usize].emission != Rgb::ZERO;
    for t in sub.triangles.iter().filter(|t| !emits(&sub, t)) {
        for k in 0..3 {
            assert!((t.p[(k + 1) % 3] - t.p[k]).length() <= 0.25 * (1.0 + 1e-5));
        }
    }
    let lamps = |sc: &Scene| sc.triangles.iter().filter(|t| emits(sc, t)).map(|t| t.p).collect::<Vec<_>>();
    assert!(!lamps(&s).is_empty());
    assert_eq!(lamps(&sub), lamps(&s));
    assert!(lamps(&s).iter().any(|p| (p[1] - p[0]).length() > 0.25), "the lamp would have split");
    let area = |sc: &Scene| sc.triangles.iter().map(|t| t.area() as f64).sum::<f64>();
    assert!((area(&sub) / area(&s) - 1.0).abs() < 1e-5);
    assert_eq!(sub.objects.len(), s.objects.len());
    for (a, b) in s.objects.iter().zip(&sub.objects) {
        assert_eq!((a.material, &a.name), (b.material, &b.name));
    }
    assert_eq!(sub.lights.len(), s.lights.len());
    for (a, b) in s.lights.iter().zip(&sub.lights) {
        assert!((a.power - b.power).abs().max_element() < 1e-4 * a.power.max_element(), "{} vs {}", a.power, b.power);
    }
    let cam = s.camera.as_ref().unwrap();
    let mut hits = 0;
    for i in 0..400u32 {
        let d = cam.ray_direction((i % 20) as f32 / 20.0 + 0.013, (i / 20) as f32 / 20.0 + 0.017, 1.0);
        let (a, b) = (s.intersect(cam.position, d, f32::INFINITY), sub.intersect(cam.position, d, f32::INFINITY));
        assert_eq!(a.is_some(), b.is_some());
        if let (Some(a), Some(b)) = (a, b) {
            hits += 1;
            assert!((a.p - b.p).length() < 1e-4, "ray {i}: {} vs {}", a.p, b.p);
            assert!(a.ns.dot(b.ns) > 0.999, "ray {i}");
            assert_eq!(s.object_of(a.tri), sub.object_of(b.tri));
        }
    }
    assert!(hits > 300);
    // No limit: a copy.
    assert_eq!(s.subdivided(0.0).triangles.len(), s.triangles.len());
}

/// Subdivision keeps a closed mesh closed: the thesis's room (6 faces of 2
/// triangles, in three objects) split at lengths that split some edges more often
/// than others: every edge is still shared by exactly two triangles, end for end in
/// the same bits (no T-junction, no crack). And a triangle budget stops the rounds
/// early, reporting the longest edge left.
#[test]
fn subdivision_is_watertight_and_keeps_within_its_budget() {
    let s = load_scene("jozwowski_room_16.gltf");
    let walls = ["room", "left_wall", "right_wall"];
    let open_edges = |sc: &Scene| {
        let mut count = std::collections::HashMap::new();
        for o in sc.objects.iter().filter(|o| walls.contains(&o.name.as_str())) {
            for t in &sc.triangles[o.tris.start as usize..o.tris.end as usize] {
                for k in 0..3 {
                    let (a, b) = (t.p[k].to_array().map(f32::to_bits), t.p[(k + 1) % 3].to_array().map(f32::to_bits));
                    *count.entry(if a < b { (a, b) } else { (b, a) }).or_insert(0u32) += 1;
                }
            }
        }
        count.values().filter(|&&n| n != 2).count()
    };
    assert_eq!(open_edges(&s), 0, "the room is closed to begin with");
    let diagonal = s.bounds.diagonal();
    for f in [0.3f32, 0.07, 0.023] {
        let (sub, longest) = s.subdivided_within(f * diagonal, usize::MAX);
        assert!(longest <= f * diagonal);
        let open = open_edges(&sub);
        assert_eq!(open, 0, "{f} of the diagonal: {open} edges not shared by exactly two triangles");
    }
    let all = s.subdivided(0.023 * diagonal).triangles.len();
    let (within, longest) = s.subdivided_within(0.023 * diagonal, all / 3);
    assert!(within.triangles.len() <= all / 3 && within.triangles.len() > all / 16, "{}", within.triangles.len());
    assert!(longest > 0.023 * diagonal);
}

/// The photon-tracing stand-in (Jozwowski 2002 section 4.4.1): each non-emitting
/// object becomes its bounding box, the light stays, and the boxes bound the
/// objects: every eye ray that hits the proxy hits no farther than the object it
/// stands for would be hit, and the ceiling light keeps its power.
#[test]
fn the_bounding_box_proxy_bounds_every_object_and_keeps_the_lights() {
    let s = load_scene("cornell_spheres.gltf");
    let proxy = s.bounding_box_proxy();
    assert_eq!(proxy.objects.len(), s.objects.len());
    // Spheres (1,104 triangles each) become 12 triangles; flat walls 4 (their box is flat).
    assert!(proxy.triangles.len() < 100, "{}", proxy.triangles.len());
    for (a, b) in s.lights.iter().zip(&proxy.lights) {
        assert!((a.power - b.power).abs().max_element() < 1e-4 * a.power.max_element());
    }
    let cam = s.camera.as_ref().unwrap();
    for i in 0..400u32 {
        let d = cam.ray_direction((i % 20) as f32 / 20.0 + 0.013, (i / 20) as f32 / 20.0 + 0.017, 1.0);
        let (Some(a), Some(b)) =
            (s.intersect(cam.position, d, f32::INFINITY), proxy.intersect(cam.position, d, f32::INFINITY))
        else {
            panic!("ray {i} escapes the closed box");
        };
        assert!(b.t <= a.t + 1e-4, "ray {i}: proxy hit at {} beyond the object at {}", b.t, a.t);
    }
}

/// An animated mesh (glTF translation channel on a mesh node): its triangles follow
/// the node at every time and the BVH finds them there; the others stay.
#[test]
fn animated_meshes_move_and_are_hit_where_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let rest = load_scene("jozwowski_room_16.gltf");
    let mut s = moving_boxes_room(dir.path());
    assert!(s.has_moving_meshes() && !rest.has_moving_meshes());
    let boxes = s.objects.iter().position(|o| o.name.starts_with("boxes")).unwrap();
    for (t, offset) in [(0.0f32, Vec3::new(1.2, 2.0, 0.0)), (2.0, Vec3::new(0.0, 2.0, 1.2))] {
        s.set_time(t);
        for (i, (a, b)) in rest.triangles.iter().zip(&s.triangles).enumerate() {
            let moved = s.objects[boxes].tris.contains(&(i as u32));
            let want = if moved { a.p.map(|p| p + offset) } else { a.p };
            for (got, want) in b.p.iter().zip(want) {
                assert!((*got - want).length() < 1e-5, "t {t}, triangle {i}");
            }
        }
        // A ray nearly straight down onto the moved tall box's top (1.4 m high at rest,
        // centre (1.0, -0.8)) hits it at 1.4 m + the offset's height.
        let top = Vec3::new(1.0, 1.4, -0.8) + offset;
        let d = Vec3::new(0.01, -1.0, 0.02).normalize();
        let hit = s.intersect(top - d * 0.5, d, f32::INFINITY).expect("the moved box is hit");
        assert!((hit.p.y - top.y).abs() < 1e-4, "t {t}: hit at {}", hit.p);
    }
}

/// jozwowski_room_16 with its boxes (node 3) moving along the light's path (the
/// same sampler's keys), written to `dir` and loaded.
fn moving_boxes_room(dir: &std::path::Path) -> Scene {
    let text = std::fs::read_to_string(scene_path("jozwowski_room_16.gltf")).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(doc["nodes"][3]["name"], "boxes");
    doc["animations"][0]["channels"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"sampler": 0, "target": {"node": 3, "path": "translation"}}));
    std::fs::write(dir.join("moving.gltf"), doc.to_string()).unwrap();
    std::fs::copy(scene_path("jozwowski_room_16.bin"), dir.join("jozwowski_room_16.bin")).unwrap();
    load(&dir.join("moving.gltf")).unwrap()
}

/// Regression (issue 53, the vertex method drew a sliding box twice): a split
/// scene and a bounding-box proxy of an animated scene move as it does. Each kept
/// the unsplit mesh's rest triangles, so only as many triangles as the mesh had
/// before splitting moved, and those with the unsplit shapes: the rest stayed
/// where the box started.
#[test]
fn split_and_proxy_scenes_of_an_animated_mesh_move_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let s = moving_boxes_room(dir.path());
    let boxes = s.objects.iter().position(|o| o.name.starts_with("boxes")).unwrap();
    let of = |scene: &Scene| {
        let tris = &scene.triangles[scene.objects[boxes].tris.start as usize..scene.objects[boxes].tris.end as usize];
        let area: f32 = tris.iter().map(|t| t.area()).sum();
        (bounds_of(tris), area)
    };
    let split = s.subdivided(0.1);
    let proxy = s.bounding_box_proxy();
    assert!(split.objects[boxes].tris.len() > 8 * s.objects[boxes].tris.len());
    for t in [0.0f32, 1.0, 2.0, 5.0] {
        let (mut a, mut b, mut c) = (s.clone(), split.clone(), proxy.clone());
        for x in [&mut a, &mut b, &mut c] {
            x.set_time(t);
        }
        let ((bounds, area), (split_bounds, split_area)) = (of(&a), of(&b));
        assert!((split_area - area).abs() < 1e-4 * area, "t {t}: split area {split_area} against {area}");
        for (got, want) in [(split_bounds, bounds), (of(&c).0, bounds)] {
            assert!(
                (got.min - want.min).abs().max_element() < 1e-4 && (got.max - want.max).abs().max_element() < 1e-4,
                "t {t}: moved to {got:?}, the object is at {want:?}"
            );
        }
        // And the BVH finds the split mesh where it is: the same first hits.
        let cam = a.camera.clone().unwrap();
        for i in 0..100u32 {
            let d = cam.ray_direction((i % 10) as f32 / 10.0 + 0.03, (i / 10) as f32 / 10.0 + 0.05, 1.0);
            let (ha, hb) = (a.intersect(cam.position, d, f32::INFINITY), b.intersect(cam.position, d, f32::INFINITY));
            assert_eq!(ha.map(|h| (h.t * 1e3).round()), hb.map(|h| (h.t * 1e3).round()), "t {t}, ray {i}");
        }
    }
}

/// Regression: axis-aligned rays whose direction has -0.0 components (-Y is
/// (-0.0, -1, -0.0)) missed everything when they started outside the scene's bounds,
/// because obvhs inverted -0.0 to a negative number but ordered children as if it
/// were positive. Every axis direction, from outside and from inside the room.
#[test]
fn axis_aligned_rays_hit_from_outside_and_inside_the_scene() {
    let s = load_scene("jozwowski_room_16.gltf");
    // The room is [-2, 2] x [0, 2.5] x [-2, 2].
    let cases = [
        (Vec3::new(0.3, 3.0, 0.2), -Vec3::Y, 2.5),
        (Vec3::new(0.3, -1.0, 0.2), Vec3::Y, 0.0),
        (Vec3::new(3.0, 1.1, 0.2), -Vec3::X, 2.0),
        (Vec3::new(-3.0, 1.1, 0.2), Vec3::X, -2.0),
        (Vec3::new(0.3, 1.1, 3.0), -Vec3::Z, 2.0),
        (Vec3::new(0.3, 1.1, -3.0), Vec3::Z, -2.0),
        (Vec3::new(0.3, 1.0, 0.2), Vec3::Y, 2.5),
        (Vec3::new(0.3, 2.2, 0.2), -Vec3::Y, 0.0),
    ];
    for (o, d, want) in cases {
        let hit = s.intersect(o, d, f32::INFINITY).unwrap_or_else(|| panic!("ray from {o} along {d} misses"));
        let got = hit.p.dot(d.abs());
        assert!((got - want).abs() < 1e-4, "ray from {o} along {d}: hit at {}", hit.p);
        assert!(s.occluded(o, d, f32::INFINITY), "shadow ray from {o} along {d}");
    }
}

/// The distance to the nearest triangle of `scene` along the ray from `o` in
/// direction `d`, found by testing every triangle (infinite if none).
fn nearest_of_all_triangles(scene: &Scene, o: Vec3, d: Vec3) -> f32 {
    scene
        .triangles
        .iter()
        .filter_map(|t| intersect_triangle(o, d, &t.p, f32::INFINITY).map(|h| h.0))
        .fold(f32::INFINITY, f32::min)
}

/// Rays born a few hundredths of a millimetre above the floor of cornell_spheres, on
/// the walls, heading down: the closest hit is the floor at once, as a test of every
/// triangle finds. obvhs's compressed wide BVH (8-bit child boxes) lost 13 of 200,000
/// such gather rays, which then left the box; the binary BVH loses none.
#[test]
fn rays_from_a_corner_hit_the_floor_next_to_them() {
    let scene = load_scene("cornell_spheres.gltf");
    // The rays the wide BVH lost, then a sweep along both back corners.
    let mut rays = vec![
        (Vec3::new(-0.99999905, 0.00026279688, 0.5118114), Vec3::new(0.46144128, -0.8682495, 0.18224932)),
        (Vec3::new(0.7812996, 3.2424927e-5, -0.99999905), Vec3::new(0.8496363, -0.28151423, 0.44594604)),
        (Vec3::new(0.7812996, 3.2424927e-5, -0.99999905), Vec3::new(-0.40646514, -0.823085, 0.39663228)),
        (Vec3::new(0.3804741, 3.707409e-5, -0.99999905), Vec3::new(0.24273823, -0.72515035, 0.64438736)),
        (Vec3::new(0.3804741, 3.707409e-5, -0.99999905), Vec3::new(0.6406588, -0.24835846, 0.7265496)),
    ];
    let mut s = pm_sampling::Sampler::new(11, 0);
    for i in 0..4000 {
        let u = s.next_1d() * 1.9 - 0.95;
        let h = 1e-5 + 3e-4 * s.next_1d();
        let (o, n) =
            if i % 2 == 0 { (Vec3::new(-0.99999905, h, u), Vec3::X) } else { (Vec3::new(u, h, -0.99999905), Vec3::Z) };
        let l = pm_sampling::cosine_hemisphere(s.next_2d());
        let d = pm_sampling::to_world(l, n);
        if d.y < -0.05 {
            rays.push((o, d));
        }
    }
    let mut lost = 0;
    for &(o, d) in &rays {
        let want = nearest_of_all_triangles(&scene, o, d);
        let got = scene.intersect(o, d, f32::INFINITY).map_or(f32::INFINITY, |h| h.t);
        // Both infinite where the hit lies within the triangle test's rounding bound.
        if got != want && !((got - want).abs() <= 1e-4 * want.max(1.0)) {
            lost += 1;
        }
    }
    assert_eq!(lost, 0, "{lost} of {} rays disagree with the triangle-by-triangle answer", rays.len());
}

/// The BVH's answers equal a test of every triangle: closest hits and occlusion of
/// segments between random surface points of cornell_spheres (its spheres' many
/// small triangles, the walls' large ones, the light).
#[test]
fn bvh_answers_equal_a_test_of_every_triangle() {
    let scene = load_scene("cornell_spheres.gltf");
    let c = scene.bounds.center();
    let mut s = pm_sampling::Sampler::new(5, 0);
    let mut pts = Vec::new();
    while pts.len() < 3000 {
        let d = pm_sampling::uniform_sphere(s.next_2d());
        if let Some(h) = scene.intersect(c, d, f32::INFINITY) {
            let n = if h.ng.dot(d) > 0.0 { -h.ng } else { h.ng };
            pts.push(scene.offset_origin(h.p, n, n));
        }
    }
    let (mut occluded, mut differ) = (0, 0);
    for i in 0..pts.len() {
        let (a, b) = (pts[i], pts[(i * 7919 + 13) % pts.len()]);
        let len = (b - a).length();
        if len < 1e-3 {
            continue;
        }
        let d = (b - a) / len;
        let t = len * 0.999;
        let nearest = nearest_of_all_triangles(&scene, a, d);
        let blocked = nearest < t;
        occluded += blocked as u32;
        let got = scene.intersect(a, d, f32::INFINITY).map_or(f32::INFINITY, |h| h.t);
        if scene.occluded(a, d, t) != blocked || got != nearest {
            differ += 1;
        }
    }
    assert!(occluded > 300, "too few occluded segments to mean anything: {occluded}");
    assert_eq!(differ, 0, "{differ} of {} rays differ", pts.len());
}

/// Geometry a binned surface area heuristic splits badly stays correct and
/// shallow: triangles at x = 1.2^i, so that all but the last few centroids share
/// the first bin of their span (measured depth 13), and 40 copies of one triangle
/// (every centroid in one bin: halved in order). Rays down onto each triangle's centre
/// find what a test of every triangle finds.
#[test]
fn lopsided_and_coincident_triangles_are_hit_as_by_every_triangle() {
    let mut tris = Vec::new();
    for i in 0..120 {
        let x = 1.2f32.powi(i);
        let s = 0.3 * x;
        tris.push(
            Triangle::new([Vec3::new(x, 0.0, 0.0), Vec3::new(x + s, 0.0, 0.0), Vec3::new(x, s, 0.0)], 0).unwrap(),
        );
    }
    let same = Triangle::new([Vec3::new(-1.0, 0.0, 0.0), Vec3::new(-0.5, 0.0, 0.0), Vec3::new(-1.0, 0.5, 0.0)], 0);
    tris.extend(std::iter::repeat_n(same.unwrap(), 40));
    let grey = Material::new("grey", Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::ZERO);
    let scene = Scene::from_parts(tris.clone(), vec![grey], Vec::new(), None);
    for t in &tris {
        let c = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        let (o, d) = (c + Vec3::new(0.0, 0.0, 2.0 * t.p[1].x.abs().max(1.0)), -Vec3::Z);
        let want = nearest_of_all_triangles(&scene, o, d);
        let got = scene.intersect(o, d, f32::INFINITY).map_or(f32::INFINITY, |h| h.t);
        assert!(want.is_finite() && got == want, "ray onto {c}: {got} against {want}");
        assert!(scene.occluded(o, d, f32::INFINITY));
    }
    assert!(scene.bvh.depth() <= bvh::MAX_SAH_LEVEL + 12, "depth {}", scene.bvh.depth());
}

/// The four-lane triangle test reports what testing the lanes one after another
/// would, each against the t_max the lanes before it left: the same lanes, in
/// order, with the same distances and barycentrics bit for bit. The lanes' second
/// half runs as SIMD against the t_max given and is checked again per lane; a
/// missing re-check would report a farther lane after a nearer one.
#[test]
fn four_lane_triangle_test_matches_lanes_one_by_one() {
    use crate::geometry::{Tri4, TriangleRay};
    let mut s = pm_sampling::Sampler::hashed(11, 0);
    let mut u = || 2.0 * s.next_1d() - 1.0;
    let (mut reported, mut cases_with_two) = (0, 0);
    for case in 0..20_000 {
        let o = Vec3::new(u(), u(), u());
        let d = Vec3::new(u(), u(), u()).normalize_or(Vec3::Z);
        // Triangles about points along the ray, so that most lanes are hit; every
        // eighth case shares an edge between lanes 0 and 1, through which rays pass.
        let tris: Vec<[Vec3; 3]> = (0..4)
            .map(|_| {
                let c = o + d * (1.0 + u());
                [
                    c + Vec3::new(u(), u(), u()) * 0.5,
                    c + Vec3::new(u(), u(), u()) * 0.5,
                    c + Vec3::new(u(), u(), u()) * 0.5,
                ]
            })
            .collect();
        let mut tris = tris;
        if case % 8 == 0 {
            tris[1] = [tris[0][1], tris[0][0], tris[0][2] + Vec3::new(u(), u(), u()) * 0.5];
        }
        let t_max = if case % 3 == 0 { f32::INFINITY } else { 1.0 + u() };
        let ray = TriangleRay::new(o, d);
        for any_hit in [false, true] {
            let mut expected = Vec::new();
            let mut cur = t_max;
            for (lane, p) in tris.iter().enumerate() {
                if let Some((t, b)) = ray.hit(p, cur) {
                    expected.push((lane, t.to_bits(), b.map(f32::to_bits)));
                    cur = if any_hit { 0.0 } else { t };
                }
            }
            let mut got = Vec::new();
            ray.hit4(&Tri4::new(&tris), 0b1111, t_max, |lane, t, b| {
                got.push((lane, t.to_bits(), b.map(f32::to_bits)));
                if any_hit { 0.0 } else { t }
            });
            assert_eq!(got, expected, "case {case}, any hit {any_hit}: o {o}, d {d}, t_max {t_max}, {tris:?}");
            reported += got.len();
            cases_with_two += (got.len() >= 2) as usize;
        }
    }
    // The cases reach the re-check: many report more than one lane.
    assert!(reported > 10_000 && cases_with_two > 1_000, "{reported} hits, {cases_with_two} cases with two or more");
}

/// A floor (y = 0), a ceiling (y = 2) and a panel 2 mm below the ceiling: the gaps
/// `surface_gaps` reports from a point on the panel's underside are the panel's
/// distance to the ceiling behind it and to the floor in front, found from a
/// stored normal 15 degrees off; a point on no surface has none.
#[test]
fn surface_gaps_measure_the_distance_to_the_surfaces_around() {
    let quad = |y: f32, s: f32, up: bool| {
        let (a, b, c, d) = (Vec3::new(-s, y, -s), Vec3::new(s, y, -s), Vec3::new(s, y, s), Vec3::new(-s, y, s));
        let t = if up { [[a, c, b], [a, d, c]] } else { [[a, b, c], [a, c, d]] };
        t.map(|p| Triangle::new(p, 0).unwrap())
    };
    let mut tris = Vec::new();
    tris.extend(quad(0.0, 1.0, true));
    tris.extend(quad(2.0, 1.0, false));
    tris.extend(quad(1.998, 0.2, false));
    let grey = Material::new("grey", Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::ZERO);
    let scene = Scene::from_parts(tris, vec![grey], Vec::new(), None);
    let tilted = Vec3::new(0.26, -0.966, 0.0).normalize();
    let (n, behind, front) = scene.surface_gaps(Vec3::new(0.05, 1.998, 0.1), tilted, 3.0).unwrap();
    assert!(n.abs_diff_eq(-Vec3::Y, 1e-6), "{n}");
    assert!((behind - 0.002).abs() < 1e-5 && (front - 1.998).abs() < 1e-4, "{behind} {front}");
    // The floor, out to the reach of 0.5 m: nothing behind, nothing in reach in front.
    let (n, behind, front) = scene.surface_gaps(Vec3::new(0.5, 0.0, 0.5), Vec3::Y, 0.5).unwrap();
    assert!(n.abs_diff_eq(Vec3::Y, 1e-6) && behind == 0.5 && front == 0.5, "{n} {behind} {front}");
    assert_eq!(scene.surface_gaps(Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 3.0), None);
}

/// At the apex of a low pyramid over a floor (a vertex of a tessellated convex
/// surface, where the vertex method's corners sit) and on a facet, the gap
/// behind is the way down to the floor, not a facet round the vertex. (This
/// pyramid does not make the offset origin slide over the next facet as a
/// generated sphere's vertex did, a gap of 1e-7 m: the suite's
/// `the_gaps_round_a_spheres_vertices_are_not_its_own_facets` holds that case.)
#[test]
fn surface_gaps_at_a_vertex_look_past_the_facets_round_it() {
    let v = Vec3::new;
    let apex = v(0.0, 1.0, 0.0);
    let base = [v(-1.0, 0.9, -1.0), v(1.0, 0.9, -1.0), v(1.0, 0.9, 1.0), v(-1.0, 0.9, 1.0)];
    let mut tris: Vec<Triangle> =
        (0..4).map(|k| Triangle::new([apex, base[(k + 1) % 4], base[k]], 0).unwrap()).collect();
    let (a, b, c, d) = (v(-2., 0., -2.), v(2., 0., -2.), v(2., 0., 2.), v(-2., 0., 2.));
    tris.extend([[a, c, b], [a, d, c]].map(|p| Triangle::new(p, 0).unwrap()));
    let grey = Material::new("grey", Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::ZERO);
    let scene = Scene::from_parts(tris, vec![grey], Vec::new(), None);
    for x in [apex, v(0.5, 0.95, 0.0)] {
        let (_, behind, front) = scene.surface_gaps(x, Vec3::Y, 3.0).unwrap();
        assert!(behind > 0.9 && front == 3.0, "at {x}: behind {behind}, front {front}");
    }
}

/// A point on a two-sided emitting quad gets no light from the quad: seen from
/// its own plane it subtends no solid angle. The corners' directions surround
/// such a point, and the solid angle computed from them came out as a
/// hemisphere: the light samples there added up to pi Le (31.8 W/m^2 here), and a
/// reflecting panel lit itself (the path tracer 2.6% bright against Mitsuba 3).
#[test]
fn a_point_on_a_two_sided_light_receives_nothing_from_it() {
    let (a, b, c, d) =
        (Vec3::new(-0.5, 1.0, -0.5), Vec3::new(0.5, 1.0, -0.5), Vec3::new(0.5, 1.0, 0.5), Vec3::new(-0.5, 1.0, 0.5));
    let tris = vec![Triangle::new([a, b, c], 0).unwrap(), Triangle::new([a, c, d], 0).unwrap()];
    let mut panel = Material::new("panel", Bsdf::Lambert { rho: Rgb::splat(0.8) }, Rgb::splat(10.0));
    panel.double_sided = true;
    let scene = Scene::from_parts(tris, vec![panel], Vec::new(), None);
    let light = &scene.lights[0];
    let n = scene.triangles[0].ng();
    // Hit points lie on the plane to the rounding of their coordinates: one ulp
    // above and below it.
    let (up, down) = (f32::from_bits(1.0f32.to_bits() + 1), f32::from_bits(1.0f32.to_bits() - 1));
    let points = [Vec3::new(0.2, up, -0.1), Vec3::new(-0.3, down, 0.25), Vec3::new(0.01, up, 0.02)];
    for (k, p) in points.into_iter().enumerate() {
        for side in [n, -n] {
            let mut received = 0.0f64;
            for i in 0..256 {
                let u = glam::Vec2::new((i % 16) as f32 / 16.0 + 0.03, (i / 16) as f32 / 16.0 + 0.03);
                if let Some(ls) = light.sample_li(&scene, p, side, (i as f32 * 0.618).fract(), u) {
                    received += (ls.li.x * ls.wi.dot(side).max(0.0) / ls.pdf) as f64 / 256.0;
                }
            }
            assert!(received < 1e-3, "point {k}, side {side}: irradiance {received} W/m^2 from its own light");
        }
    }
}
