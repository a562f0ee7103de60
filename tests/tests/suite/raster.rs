//! The rasteriser against eye rays: at every pixel centre the same surface point,
//! except where the centre lies on an object's silhouette or a triangle edge.

use pm_render::Film;
use pm_tests::load_scene;

#[test]
fn rasterised_first_hits_equal_eye_rays_except_at_silhouettes() {
    for name in ["cornell_spheres.gltf", "cornell_boxes.gltf", "furnace.gltf"] {
        let scene = load_scene(name);
        let camera = scene.camera.clone().unwrap();
        let film = Film { width: 96, height: 72, spp: 1, contrast: 0.0, seed: 1, pixel_centres: false };
        let (w, h) = (96usize, 72usize);
        let aspect = w as f32 / h as f32;
        let raster = pm_raster::first_hits(&scene, &camera, film.size(), film.rect());
        let rays: Vec<_> = (0..w * h)
            .map(|i| {
                let d =
                    camera.ray_direction(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32, aspect);
                scene.intersect(camera.position, d, f32::INFINITY)
            })
            .collect();
        let object = |i: usize| rays[i].map(|hit| scene.object_of(hit.tri));
        let tol = 1e-4 * scene.bounds.diagonal();
        let (mut differ, mut at_silhouette) = (0, 0);
        for i in 0..w * h {
            let same = match (raster[i].map(|f| f.hit(&scene)), rays[i]) {
                (Some(a), Some(b)) => (a.p - b.p).length() < tol && (a.t - b.t).abs() < tol,
                (None, None) => true,
                _ => false,
            };
            if same {
                continue;
            }
            differ += 1;
            let (x, y) = (i % w, i / w);
            let edge = [(-1i32, 0i32), (1, 0), (0, -1), (0, 1)].iter().any(|(dx, dy)| {
                let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                nx >= 0
                    && ny >= 0
                    && (nx as usize) < w
                    && (ny as usize) < h
                    && object(ny as usize * w + nx as usize) != object(i)
            });
            at_silhouette += edge as usize;
        }
        eprintln!("{name}: {differ} of {} pixels differ, {at_silhouette} of them at a silhouette", w * h);
        assert_eq!(differ, at_silhouette, "{name}: a pixel away from any silhouette differs");
        assert!(differ * 100 < w * h, "{name}: {differ} pixels differ");
        assert!(raster.iter().filter(|h| h.is_some()).count() > w * h / 2);
    }
}

/// The cube shadow map against shadow rays: from the room's light, points on
/// surfaces seen by the camera are visible in the map exactly when a shadow ray
/// reaches them, except within a few texels of a shadow's edge.
#[test]
fn cube_shadow_maps_agree_with_shadow_rays_away_from_shadow_edges() {
    let scene = load_scene("jozwowski_room_256.gltf");
    let pm_scene::LightKind::Point { position, .. } = scene.lights[0].kind else { panic!("a point light") };
    let map = pm_raster::CubeDepth::new(&scene, position, 256);
    let camera = scene.camera.clone().unwrap();
    let (w, h) = (64usize, 64usize);
    let (mut differ, mut shadowed, mut total) = (0, 0, 0);
    for i in 0..w * h {
        let d = camera.ray_direction(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32, 1.0);
        let Some(hit) = scene.intersect(camera.position, d, f32::INFINITY) else { continue };
        let to = position - hit.p;
        let dist = to.length();
        let o = scene.offset_origin(hit.p, hit.ng, to / dist);
        let ray_visible = !scene.occluded(o, to / dist, dist * (1.0 - 1e-4));
        let map_visible = map.visible(hit.p, 2.0 * map.texel_angle() * dist);
        total += 1;
        shadowed += !ray_visible as usize;
        differ += (ray_visible != map_visible) as usize;
    }
    eprintln!("{differ} of {total} points differ ({shadowed} in shadow by rays)");
    assert!(shadowed > total / 20, "the scene casts shadows: {shadowed}");
    assert!(differ * 50 < total, "{differ} of {total}");
}

/// A fragment buffer reused for another view (a live frame's) holds exactly what a
/// fresh one does: every texel is cleared before drawing, including where the new
/// view sees nothing (the camera turned half away from the box).
#[test]
fn reused_fragment_buffers_equal_fresh_ones() {
    let scene = load_scene("cornell_spheres.gltf");
    let camera = scene.camera.clone().unwrap();
    let mut turned = camera.clone();
    turned.forward = (camera.forward + camera.right).normalize();
    turned.right = turned.forward.cross(camera.up).normalize();
    let film = Film { width: 64, height: 48, spp: 1, contrast: 0.0, seed: 1, pixel_centres: false };
    let mut buffer = Vec::new();
    for (k, view) in [&camera, &turned, &camera, &turned].into_iter().enumerate() {
        pm_raster::first_hits_into(&scene, view, film.size(), film.rect(), &mut buffer);
        let fresh = pm_raster::first_hits(&scene, view, film.size(), film.rect());
        assert!(k % 2 == 0 || fresh.iter().any(Option::is_none), "the turned view must see past the box");
        assert_eq!(format!("{buffer:?}"), format!("{fresh:?}"));
    }
}
