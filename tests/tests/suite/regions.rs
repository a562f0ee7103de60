//! The image loop is not the integrator: any rectangle of the image renders with the
//! whole image's per-pixel sample streams, and adaptive supersampling decides from a
//! one-pixel apron, so tiles assembled from regions equal the whole image bit for
//! bit, for every integrator. The G-buffer each sample fills is checked against
//! independent eye rays.

use glam::Vec3;
use pm_methods::Method;
use pm_render::{Film, Image, Integrator, Rect, render_region};
use pm_tests::{load_scene, photon_maps, render_params, with_photon_mapping};

/// Render `film` as tiles of `tw` x `th` pixels and assemble them.
fn tiled<I: Integrator>(camera: &pm_scene::Camera, film: &Film, integ: &I, tw: u32, th: u32) -> Vec<Vec<Vec3>> {
    let (w, h) = (film.width, film.height);
    let mut layers = vec![vec![Vec3::splat(-1.0); (w * h) as usize]; 5];
    for y0 in (0..h).step_by(th as usize) {
        for x0 in (0..w).step_by(tw as usize) {
            let rect = Rect { x0, y0, x1: (x0 + tw).min(w), y1: (y0 + th).min(h) };
            let (img, _) = render_region(camera, film, rect, integ, false, &|_, _| {}).unwrap();
            assert_eq!((img.width, img.height), (rect.width(), rect.height()));
            for (l, (_, px)) in img.named().enumerate() {
                for (j, v) in px.iter().enumerate() {
                    let (x, y) = (x0 + j as u32 % rect.width(), y0 + j as u32 / rect.width());
                    layers[l][(y * w + x) as usize] = *v;
                }
            }
        }
    }
    layers
}

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

fn assert_tiles_equal_whole<I: Integrator>(name: &str, camera: &pm_scene::Camera, film: &Film, integ: &I) -> Image {
    let (whole, stats) = render_region(camera, film, film.rect(), integ, false, &|_, _| {}).unwrap();
    // Tiles of one pixel row, square tiles that do not divide the image, and columns.
    for (tw, th) in [(film.width, 1), (8, 8), (13, 7), (1, film.height)] {
        let t = tiled(camera, film, integ, tw, th);
        for (l, (layer, px)) in whole.named().enumerate() {
            assert!(bits(px) == bits(&t[l]), "{name}: {tw}x{th} tiles differ from the whole image in layer {layer}");
        }
    }
    eprintln!(
        "{name}: {} of {} pixels supersampled; tiles equal the whole image",
        stats.supersampled_pixels,
        film.width * film.height
    );
    whole
}

#[test]
fn tiles_equal_the_whole_image_for_every_integrator() {
    let scene = load_scene("cornell_spheres.gltf");
    let camera = scene.camera.clone().unwrap();
    let maps = photon_maps(&scene, 20_000, 3_000, 0.25);
    // Small gathers keep this fast; spp 4 makes supersampling cross tile borders.
    let mut p = render_params(Method::Full, 37, 29);
    (p.render.gather_rays, p.render.spp) = (24, 4);
    let film = p.render.film(1);
    with_photon_mapping(&scene, &maps, &p, |pm| {
        assert!(pm.cache().is_some_and(|c| !c.is_empty()), "the shared cache is in use");
        let img = assert_tiles_equal_whole("full", &camera, &film, &pm);
        assert!(img.layer(pm_color::Layer::Caustic).iter().any(|v| v.max_element() > 0.0));
        let v = pm_render::PhotonsView(pm);
        assert_tiles_equal_whole("photons", &camera, &film, &v);
        let v = pm_render::RadianceView(v.0);
        assert_tiles_equal_whole("radiance", &camera, &film, &v);
        let v = pm_render::IndirectView(v.0);
        assert_tiles_equal_whole("indirect", &camera, &film, &v);
    });
    let pt = pm_render::PathTracer::new(&scene).unwrap();
    assert_tiles_equal_whole("path", &camera, &Film { spp: 2, ..film }, &pt);
}

/// Each pixel's G-buffer entry is the first hit of its first sample:
/// checked against an eye ray traced here, with depth, normals facing the camera,
/// the object's index and a direct-light term only where the surface is not specular.
#[test]
fn the_g_buffer_holds_each_pixels_first_hit() {
    let scene = load_scene("cornell_spheres.gltf");
    let camera = scene.camera.clone().unwrap();
    let maps = photon_maps(&scene, 20_000, 3_000, 0.25);
    let mut p = render_params(Method::Full, 24, 20);
    (p.render.gather_rays, p.render.spp) = (16, 1);
    let film = p.render.film(1);
    let rect = Rect { x0: 3, y0: 2, x1: 21, y1: 17 };
    let gb = with_photon_mapping(&scene, &maps, &p, |pm| {
        render_region(&camera, &film, rect, &pm, true, &|_, _| {}).unwrap().0.gbuffer.unwrap()
    });
    assert_eq!(gb.len(), 18 * 15);
    let aspect = film.width as f32 / film.height as f32;
    let (mut specular, mut lit) = (0, 0);
    for (j, vs) in gb.iter().enumerate() {
        let (x, y) = (rect.x0 + j as u32 % 18, rect.y0 + j as u32 / 18);
        let j = pm_render::pixel_sampler(&film, (y * 24 + x) as usize, 0).next_2d();
        let d = camera.ray_direction((x as f32 + j.x) / 24.0, (y as f32 + j.y) / 20.0, aspect);
        let hit =
            scene.intersect(camera.position, d, f32::INFINITY).expect("the box is closed around the camera's view");
        assert!(vs.hit && vs.tri == hit.tri && (vs.depth - hit.t).abs() <= 1e-6 * hit.t, "pixel {x},{y}");
        assert!((vs.p - hit.p).length() < 1e-5 && vs.ng.dot(-d) > 0.0 && vs.ns.dot(-d) > 0.0);
        let object = &scene.objects[vs.object as usize];
        assert!(object.tris.contains(&hit.tri));
        let bsdf = vs.bsdf.unwrap();
        if bsdf.is_specular() {
            specular += 1;
            assert_eq!(vs.direct, Vec3::ZERO);
        } else if vs.direct.max_element() > 0.0 {
            lit += 1;
        }
    }
    assert!(specular > 0 && lit > 100, "{specular} specular, {lit} lit pixels");
}
