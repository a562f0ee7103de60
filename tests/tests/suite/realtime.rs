//! The real-time methods on a scene made elsewhere: Blender's export of an animated
//! room (tests/scenes/blender_room, made by tests/blender/animated_room.py), run as
//! `cargo xtask live` runs it (the repository's pipeline.toml, only the scene, the
//! frame size and Blender's 24 fps changed), against the path tracer posed at each
//! frame's time (`photon-render --mode path --time T`).

use pm_image::accuracy::{agreement, keep_mask};
use pm_methods::live::LiveMethod;
use std::path::{Path, PathBuf};

/// The Blender room's glTF file.
fn blender_room() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/blender_room/blender_room.gltf")
}

/// Frames `0..frames` of `scene` drawn by `method` as `cargo xtask live` draws them
/// (pipeline.toml's `[live]` settings at `size` x `size` and 24 fps), as EXR files
/// in `dir/frames`.
fn live_frames(dir: &Path, scene: &Path, method: LiveMethod, size: u32, frames: u32) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut p = pm_pipeline::Pipeline::load(&root.join("pipeline.toml")).unwrap();
    (p.live.frame.width, p.live.frame.height, p.live.frame.fps) = (size, size, 24.0);
    let file = dir.join("pipeline.toml");
    std::fs::write(&file, p.to_toml()).unwrap();
    let args = pm_runner::run::LiveArgs {
        pipeline: Some(file),
        scene: Some(scene.to_path_buf()),
        out: Some(dir.to_path_buf()),
        method: Some(method),
        frames,
        ..Default::default()
    };
    let mut set = pm_runner::run::live_setup(&args, &root).unwrap();
    set.args.push("--exr".into());
    let o = std::process::Command::new(pm_tests::bins().path("photon-live")).args(&set.args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The pixels of a `width`-wide image where it steps by more than a quarter to a
/// neighbour (a silhouette, a room's edge): a frame's one sample at the pixel's
/// centre and the path tracer's samples spread over the pixel see different
/// surfaces there (aliasing, not lighting: the ceiling's edge alone put a row of
/// 8 x 8 blocks 7% off in the direct light, which is exact elsewhere).
fn edges(image: &[glam::Vec3], width: usize) -> Vec<bool> {
    let height = image.len() / width;
    (0..image.len())
        .map(|i| {
            let (x, y) = ((i % width) as i64, (i / width) as i64);
            let v = image[i].max_element();
            (-1..=1i64).any(|dy| {
                (-1..=1i64).any(|dx| {
                    let (nx, ny) = (x + dx, y + dy);
                    let inside = nx >= 0 && ny >= 0 && nx < width as i64 && ny < height as i64;
                    inside && {
                        let w = image[(ny * width as i64 + nx) as usize].max_element();
                        (v - w).abs() > 0.25 * v.max(w)
                    }
                })
            })
        })
        .collect()
}

/// The path tracer's image of `scene` at animation time `t` [s].
fn path_traced_at(dir: &Path, scene: &Path, t: f32, size: u32, spp: u32) -> pm_image::Layers {
    path_traced(dir, scene, t, size, spp, false)
}

/// [`path_traced_at`], with every sample through its pixel's centre (`centres`)
/// as a frame's one sample is, or spread over the pixel.
fn path_traced(dir: &Path, scene: &Path, t: f32, size: u32, spp: u32, centres: bool) -> pm_image::Layers {
    let out = dir.join(format!("path_{t}.exr"));
    let size = size.to_string();
    let o = std::process::Command::new(pm_tests::bins().path("photon-render"))
        .args(["--scene", scene.to_str().unwrap(), "--mode", "path", "--spp", &spp.to_string()])
        .args(["--width", &size, "--height", &size, "--time", &t.to_string(), "--out", out.to_str().unwrap()])
        .args(["--pixel-centres", &centres.to_string()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    pm_image::read_exr(&out).unwrap()
}

/// Issue 53: on Blender's animated room (a point lamp circling under the ceiling, a
/// box sliding across the floor, walls of two triangles each) every frame of the
/// vertex method is within 10% block RMS (8 x 8 blocks) of the path tracer at that
/// frame's time, and within 4% in mean. Its old defaults failed both ways: the
/// ring buffer's photons lagged up to ten frames behind the lamp (indirect light
/// 10-13% off in mean) and 50-photon corner estimates covered the walls in coloured
/// blotches (block RMS 14-17%); and the split mesh drew the sliding box twice, its
/// split triangles left at rest.
#[test]
fn the_vertex_method_follows_an_animated_blender_room() {
    for (frame, g) in against_the_path_tracer_on_the_blender_room(LiveMethod::Vertex) {
        assert!(g.mean.abs() < 0.04, "frame {frame}: {g}");
        assert!(g.block_rms < 0.10, "frame {frame}: {g}");
    }
}

/// Issue 53: the same for image-space photon mapping on its defaults: every frame
/// within 10% block RMS and 6% in mean. Its old defaults (48 x 48 bounce-map faces,
/// volumes of at most 3% of the diagonal, no coverage) covered every frame in
/// coloured splotches, 14-17% block RMS: too few photons per volume (two seeds'
/// frames differed by 25% block RMS), bright dots where the Principled BSDF's
/// rough specular layer made volumes a tenth of the size, and, with larger volumes,
/// dark bands along every edge of the room (`IspmParams::volume_coverage`). Now
/// 8.4, 6.8, 9.6 and 5.7% (frame 24 closest to the bound).
#[test]
fn ispm_follows_an_animated_blender_room() {
    for (frame, g) in against_the_path_tracer_on_the_blender_room(LiveMethod::Ispm) {
        assert!(g.mean.abs() < 0.06, "frame {frame}: {g}");
        assert!(g.block_rms < 0.10, "frame {frame}: {g}");
    }
}

/// The Blender room's frames that are judged, and their size [pixels].
const JUDGED: [u32; 4] = [0, 12, 24, 36];
const SIZE: u32 = 128;

/// The path tracer's images of the Blender room at the judged frames' times,
/// rendered once for both methods' tests.
fn blender_room_references() -> &'static [pm_image::Layers] {
    static REFERENCES: std::sync::OnceLock<Vec<pm_image::Layers>> = std::sync::OnceLock::new();
    REFERENCES.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        JUDGED.map(|frame| path_traced_at(dir.path(), &blender_room(), frame as f32 / 24.0, SIZE, 256)).to_vec()
    })
}

/// Frames 0, 12, 24 and 36 of the Blender room drawn by `method` at 128 x 128, each
/// with its agreement (8 x 8 blocks) against the path tracer at that frame's time,
/// leaving out the lamp's pixels and the image's edges (`edges`).
fn against_the_path_tracer_on_the_blender_room(method: LiveMethod) -> Vec<(u32, pm_image::accuracy::Agreement)> {
    let dir = tempfile::tempdir().unwrap();
    let size = SIZE;
    live_frames(dir.path(), &blender_room(), method, size, JUDGED[3] + 1);
    JUDGED
        .into_iter()
        .zip(blender_room_references())
        .map(|(frame, reference)| {
            let ours = pm_image::read_exr(&dir.path().join(format!("frames/{frame:04}.exr"))).unwrap();
            let (a, b) = (ours.pixels(None), reference.pixels(None));
            let keep: Vec<bool> = keep_mask(&b, size as usize, size as usize, Some(5.0))
                .into_iter()
                .zip(edges(&b, size as usize))
                .map(|(k, e)| k && !e)
                .collect();
            let g = agreement(&a, &b, size as usize, &keep, 8);
            eprintln!("{method:?} frame {frame}: {g}");
            (frame, g)
        })
        .collect()
}

/// Issue 53: the differential checker's rooms with area lights a few millimetres
/// under the ceiling, drawn by the vertex method against the path tracer
/// ([`live_on_generated`]): seed 60606's scenes 16 (a
/// two-sided light 18 mm under the ceiling), 22 (two, 1.7 and 3.1 mm under it)
/// and 24 (two, 19 and 4.3 mm, and a mirror slab). The light trapped in the gap
/// above a two-sided light (its emission between its back and the ceiling) is
/// brighter than the room; the corner estimates beside the light found those
/// photons on the same plane and took them for their own, and interpolation
/// spread them over the ceiling around it: scene 16's indirect layer 84% off in
/// its worst 8 x 8 block (the checker: 71%, 61% and 209% on the three). Now the
/// ring's photons carry the cover flag, each corner counts only photons of its own
/// surface and cover (as the irradiance precompute does), and a triangle reaching
/// under the light interpolates only the corners of each point's kind: 20.5%,
/// 18.6% and 26.7%. Asserted: every block within 40% (the method's stated
/// bound).
#[test]
fn the_vertex_method_keeps_the_light_trapped_above_a_lamp_to_itself() {
    for index in [16, 22, 24] {
        let (g, recipe) = live_on_generated(LiveMethod::Vertex, 60606, index, &[pm_color::Layer::Indirect]);
        let g = &g[0];
        eprintln!("scene-{index:03} indirect: {g} ({:?})", recipe.lights);
        assert!(g.worst_block < 0.40, "scene-{index:03} indirect: {g} ({:?})", recipe.lights);
    }
}

/// Issue 53: glass boxes standing on the floor (the generator's boxes have no
/// bottom face), drawn by the vertex method against the path tracer
/// ([`live_on_generated`]): seed 12902's scenes 3 (a glass box 4 mm from the
/// back wall) and 17 (a glass box under a mirror slab). The light through a
/// box lights the floor under it, four times the floor around; the corners
/// beside the box found those photons by distance, through the glass, while
/// their coverage probes, which counted only the disc in view, left that part
/// of the disc out, and divided by it: the box's foot glowed (the checker:
/// worst 8 x 8 block of the indirect layer 116% and 105% off). A corner whose
/// disc holds photons out of its view now counts only the photons in view, and
/// its coverage is the part of the disc that holds them (`pm_vertex::Share`):
/// 35% and 73% in this test's one frame; and a triangle reaching under the box
/// interpolates, at each point, only the corners in view of it
/// (`pm_vertex::SplitTriangles`): 22% and 18%. Asserted: every block within 40%
/// (the method's stated bound).
#[test]
fn the_vertex_method_keeps_the_light_under_a_glass_box_to_the_floor_under_it() {
    for index in [3, 17] {
        let (g, recipe) = live_on_generated(LiveMethod::Vertex, 12902, index, &[pm_color::Layer::Indirect]);
        let g = &g[0];
        eprintln!("scene-{index:03} indirect: {g} ({:?})", recipe.objects);
        assert!(g.worst_block < 0.40, "scene-{index:03} indirect: {g} ({:?})", recipe.objects);
    }
}

/// Issue 53: seed 77777's scene 35 of the checker's generator (a Cornell box
/// whose lower half is a fog box inset 2 mm from the walls and floor: an
/// index-matched boundary, extinction 0.66 / m), drawn by the vertex method as
/// `cargo xtask live` draws it against the path tracer, as above. The coverage
/// probes took the fog box's bottom face, 2 mm above the floor and facing away
/// from it, for the floor's edge: the floor's corners read their discs as 0-25%
/// covered, and the indirect light under the fog came out three times too bright
/// (the checker: mean +207%, worst 8 x 8 block +669%). The probes now pass
/// index-matched boundaries as photons do: measured +2.4% in mean, 10.4% in the
/// worst block. The fog itself (the volume layer) had single scattering only,
/// 65% dark in mean; the ring now keeps where its paths scatter and the frame
/// adds their beam estimate (`CornerLight::scattered`): +1.8% in mean, 15.2% in
/// the worst block.
/// Asserted: both layers' means within 10% and every block within 40% (the
/// method's stated bound).
#[test]
fn the_vertex_method_draws_a_fog_box_and_the_floor_under_it_as_the_path_tracer_does() {
    fog_box_as_the_path_tracer_draws_it(LiveMethod::Vertex);
}

/// Issue 53: the same scene drawn by the image-space method. Its photons did not
/// scatter in media (the paper has none): the fog had single scattering only
/// (the checker: volume layer 65% dark in mean); now the bounce maps and paths
/// fly through media as the photon tracer's photons do (`pm_photon::Carrier`)
/// and the frame adds the beam estimate over the points they scattered at. The
/// floor under the fog box, seen through its index-matched top face, had no
/// indirect light at all (the splat's G-buffer held the face; blocks 100% dark,
/// indirect 69% dark in mean); the shading now gathers the photons there. The
/// checker's ISPM passes on seed 77777 went from 11 of 21 judged scenes to 21.
/// Asserted as above.
#[test]
fn the_image_space_method_draws_a_fog_box_and_the_floor_under_it_as_the_path_tracer_does() {
    fog_box_as_the_path_tracer_draws_it(LiveMethod::Ispm);
}

/// Issue 53: seed 60606's scene 39 of the checker's generator (a closed room
/// whose lower part is a fog box inset 2 mm, extinction 1.59 / m, albedo 0.83,
/// holding a rough metal box), drawn by both real-time methods. The rays a frame
/// follows from a rough metal (one sample of its lobe) and from mirrors and glass
/// took the fog's transmittance but not the light it scatters toward them: the
/// box, standing in lit fog, came out black and speckled (the checker: indirect
/// layer's worst block 90% low in both methods). Every ray now adds the media's
/// single and multiple scattering along its walk as the eye ray does
/// (`LiveShading::pass_lit`). Asserted: the indirect layer's mean within 10% and
/// every block within 40% (the methods' stated bound).
#[test]
fn a_rough_metal_box_in_fog_reflects_the_lit_fog_in_both_real_time_methods() {
    for method in [LiveMethod::Ispm, LiveMethod::Vertex] {
        let (g, recipe) = live_on_generated(method, 60606, 39, &[pm_color::Layer::Indirect]);
        let g = &g[0];
        eprintln!("{method:?} indirect: {g} ({:?}, {:?})", recipe.objects, recipe.fog);
        assert!(g.mean.abs() < 0.10 && g.worst_block < 0.40, "{method:?} indirect: {g} ({:?})", recipe.objects);
    }
}

/// Issue 53: seed 60606's scene 33 of the checker's generator (a two-sided lamp
/// 0.68 m wide hanging 8.5 cm under the ceiling), as the vertex method draws it.
/// Its automatic subdivision split the lamp into small triangles, and a light is
/// sampled by solid angle only from points near one of its triangles relative to
/// that triangle's size: the ceiling above the lamp sampled it by area, each
/// sample weighing up to A / d^2, and the frames' direct light had sparks 10-40
/// times the path tracer's there (the checker: a block 248% off). The split now
/// leaves emitters whole. Asserted at the ceiling point above the lamp's centre,
/// over 4,096 stratified light samples: the irradiance the drawn scene's lamp
/// gives equals the file's lamp's within 1%, and no sample weighs more than 4
/// times the mean (split, the largest weighed 21 times it; now 1.6).
#[test]
fn the_vertex_methods_split_leaves_a_lamp_near_the_ceiling_sampled_without_sparks() {
    let dir = tempfile::tempdir().unwrap();
    let (path, recipe) = crate::generated_scene(dir.path(), 60606, 33);
    let file = pm_scene::load(&path).unwrap();
    let (drawn, _, split) = pm_vertex::scenes(file.clone(), None, &pm_vertex::VertexParams::default());
    assert!(split.triangles.1 > split.triangles.0, "the vertex method splits this scene: {split:?}");
    let up = glam::Vec3::Y;
    let irradiance = |scene: &pm_scene::Scene| {
        let light = &scene.lights[0];
        let pm_scene::LightKind::Area { tris, .. } = &light.kind else { panic!("{:?}", recipe.lights) };
        let corners = scene.triangles[tris.start as usize..tris.end as usize].iter().flat_map(|t| t.p);
        let centre = corners.clone().sum::<glam::Vec3>() / corners.count() as f32;
        let ceiling = scene.intersect(centre + 1e-3 * up, up, f32::INFINITY).expect("a ceiling over the lamp");
        let (p, n) = (ceiling.p, -up);
        let m = 64;
        let weights: Vec<f32> = (0..m * m)
            .map(|k| {
                let u = glam::Vec2::new(((k % m) as f32 + 0.5) / m as f32, ((k / m) as f32 + 0.5) / m as f32);
                let u_sel = ((k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40) as f32 / (1u64 << 24) as f32;
                light.sample_li(scene, p, n, u_sel, u).map_or(0.0, |ls| ls.li.x * ls.wi.dot(n).max(0.0) / ls.pdf)
            })
            .collect();
        let mean = weights.iter().sum::<f32>() / weights.len() as f32;
        (mean, weights.iter().fold(0.0f32, |a, &w| a.max(w)))
    };
    let (e_file, _) = irradiance(&file);
    let (e_drawn, max) = irradiance(&drawn);
    eprintln!("irradiance {e_file} (file) {e_drawn} (drawn), largest sample {:.1} x the mean", max / e_drawn);
    assert!((e_drawn / e_file - 1.0).abs() < 0.01, "{e_drawn} vs {e_file}");
    assert!(max < 4.0 * e_drawn, "a sample weighs {:.1} times the mean", max / e_drawn);
}

/// Issue 53: seed 90210's scene 27 of the checker's generator (a two-sided lamp
/// 3 mm under the ceiling), drawn by the image-space method. The ceiling's
/// photons in the gap above the lamp (under a cover) have the smallest kernel,
/// whose slab still reaches the lamp's underside 3 mm below, facing the same way:
/// the gap's light was splatted onto the lamp as seen from the room, whose
/// indirect layer read 25-50 times the path tracer's (2-3.5 against 0.07 W
/// sr^-1 m^-2; the checker leaves the lamp's pixels out, so it did not count).
/// Photons under a cover now light only surfaces under one
/// (`VolumePhoton::covered`, `GBuffer::mark_covered`). Asserted: the indirect
/// light of the top six rows, the lamp's pixels included, within 25% of the path
/// tracer's.
#[test]
fn the_image_space_method_keeps_the_light_between_a_lamp_and_the_ceiling_in_the_gap() {
    let (ours, reference, _, recipe) = live_and_reference(LiveMethod::Ispm, 90210, 27);
    let layer = Some(pm_color::Layer::Indirect);
    let top = |v: &[glam::Vec3]| v[..6 * 48].iter().map(|p| p.element_sum() as f64).sum::<f64>();
    let ratio = top(&ours.pixels(layer)) / top(&reference.pixels(layer));
    eprintln!("top rows' indirect: {ratio:.3} x the path tracer's ({:?})", recipe.lights);
    assert!((ratio - 1.0).abs() < 0.25, "top rows' indirect {ratio:.3} x the path tracer's ({:?})", recipe.lights);
}

/// Seed 77777's scene 35 drawn by `method`: its indirect and volume layers'
/// means within 10% of the path tracer's and every block within 40% (the
/// real-time methods' stated bound).
fn fog_box_as_the_path_tracer_draws_it(method: LiveMethod) {
    let layers = [pm_color::Layer::Indirect, pm_color::Layer::Volume];
    let (g, recipe) = live_on_generated(method, 77777, 35, &layers);
    for (layer, g) in layers.iter().zip(&g) {
        eprintln!("{method:?} {layer:?}: {g} ({:?})", recipe.fog);
        assert!(g.mean.abs() < 0.10 && g.worst_block < 0.40, "{method:?} {layer:?}: {g} ({:?})", recipe.fog);
    }
}

/// Scene `index` of the checker's generator for `seed` drawn by `method` (one
/// 48 x 48 frame as `cargo xtask live` draws it), the path tracer's image of it
/// (4,096 a pixel through the pixels' centres), the pixels that count (the
/// light's left out) and what the scene holds.
fn live_and_reference(
    method: LiveMethod,
    seed: u64,
    index: u32,
) -> (pm_image::Layers, pm_image::Layers, Vec<bool>, pm_scenegen::random::Recipe) {
    let size = 48;
    let dir = tempfile::tempdir().unwrap();
    let (scene, recipe) = crate::generated_scene(dir.path(), seed, index);
    live_frames(dir.path(), &scene, method, size, 1);
    let ours = pm_image::read_exr(&dir.path().join("frames/0000.exr")).unwrap();
    let reference = generated_reference(dir.path(), &scene, (seed, index), size, 4096);
    let n = size as usize;
    let keep = keep_mask(&reference.pixels(None), n, n, None);
    (ours, reference, keep, recipe)
}

/// The path tracer's image of generated scene `key` (seed, index), written at
/// `scene`, at `size` x `size` and `spp` a pixel through the pixels' centres,
/// rendered once in a test run: the tests that judge a scene with both real-time
/// methods share it (it takes longer than drawing the scene: 20 s on 2 cores at
/// 48 x 48 and 4,096 a pixel). A second test asking for it while it renders waits.
fn generated_reference(dir: &Path, scene: &Path, key: (u64, u32), size: u32, spp: u32) -> pm_image::Layers {
    type Slot = std::sync::Arc<std::sync::Mutex<Option<pm_image::Layers>>>;
    static DONE: std::sync::Mutex<std::collections::BTreeMap<(u64, u32, u32, u32), Slot>> =
        std::sync::Mutex::new(std::collections::BTreeMap::new());
    let slot = DONE.lock().unwrap().entry((key.0, key.1, size, spp)).or_default().clone();
    let mut image = slot.lock().unwrap();
    image.get_or_insert_with(|| path_traced(dir, scene, 0.0, size, spp, true)).clone()
}

/// Scene `index` of the differential checker's generator for `seed`, drawn by
/// `method` as `cargo xtask live` draws it (48 x 48, one frame), against the path
/// tracer (4,096 a pixel, each through the pixel's centre as the frame's one
/// sample is): each of `layers`' agreement in 8 x 8 blocks, the light's pixels
/// left out, and what the scene holds. The vertex method draws caustics in its
/// indirect layer: the reference's caustic layer is counted as indirect light
/// for it.
fn live_on_generated(
    method: LiveMethod,
    seed: u64,
    index: u32,
    layers: &[pm_color::Layer],
) -> (Vec<pm_image::accuracy::Agreement>, pm_scenegen::random::Recipe) {
    let (ours, reference, keep, recipe) = live_and_reference(method, seed, index);
    let n = (keep.len() as f64).sqrt() as usize;
    let agreements = layers
        .iter()
        .map(|&layer| {
            let l = Some(layer);
            let theirs = reference.pixels_caustics_in_indirect(l, method == LiveMethod::Vertex);
            agreement(&ours.pixels(l), &theirs, n, &keep, 8)
        })
        .collect();
    (agreements, recipe)
}
