//! The ray kernel alone (issue 40, goal 2): closest hits and shadow-ray occlusion
//! per ray, on the rays a path tracer casts at its second vertex. Eye rays through a
//! grid of pixels find first hits; from each, a cosine-distributed bounce ray (a
//! closest-hit query) and a shadow ray to a point sampled on a light (an any-hit
//! query, as long as `pm_light` makes it). The rays are made once and replayed, so
//! the time is the kernel's: BVH traversal and triangle tests, no shading.
//!
//! Run: `cargo bench -p pm-scene --bench rays [-- SCENE...]` (one thread; best of 7 passes; ns per
//! ray). The sums of hit distances and of blocked rays are printed so that a kernel
//! change that loses or gains hits shows.

use glam::{Vec2, Vec3};
use pm_sampling::{Sampler, cosine_hemisphere, to_world};
use std::hint::black_box;
use std::time::Instant;

const GRID: u32 = 256;

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    // Scene names may be given (`cargo bench -p pm-scene --bench rays -- cornell_boxes`).
    let given: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let all = ["cornell_boxes", "cornell_spheres", "jozwowski_room_1024", "instanced"];
    let names: Vec<&str> = if given.is_empty() { all.to_vec() } else { given.iter().map(|s| s.as_str()).collect() };
    for name in names {
        let path = root.join(format!("{name}.gltf"));
        let scene = pm_scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let cam = scene.camera.as_ref().expect("the scene has a camera");
        let rays = cam.rays(1.0);
        let mut closest: Vec<(Vec3, Vec3)> = Vec::new();
        let mut shadow: Vec<(Vec3, Vec3, f32)> = Vec::new();
        let mut s = Sampler::hashed(7, 0);
        for j in 0..GRID {
            for i in 0..GRID {
                let d = rays.direction((i as f32 + 0.5) / GRID as f32, (j as f32 + 0.5) / GRID as f32);
                let Some(h) = scene.intersect(cam.position, d, f32::INFINITY) else { continue };
                let n = pm_scene::facing(h.ng, -d);
                let wi = to_world(cosine_hemisphere(s.next_2d()), n);
                closest.push((scene.offset_origin(h.p, h.ng, wi), wi));
                let Some(light) = scene.lights.first() else { continue };
                let u: Vec2 = s.next_2d();
                if let Some(ls) = light.sample_li(&scene, h.p, n, s.next_1d(), u)
                    && ls.wi.dot(n) > 0.0
                {
                    let o = scene.offset_origin(h.p, h.ng, ls.wi);
                    let t = if ls.dist.is_finite() {
                        (ls.dist - (o - h.p).dot(ls.wi)) * (1.0 - 1e-4)
                    } else {
                        f32::INFINITY
                    };
                    shadow.push((o, ls.wi, t));
                }
            }
        }
        let best = |f: &dyn Fn() -> f64| (0..7).map(|_| f()).fold(f64::INFINITY, f64::min);
        let mut t_sum = 0.0f64;
        let t_closest = best(&|| {
            let start = Instant::now();
            for &(o, d) in &closest {
                black_box(scene.intersect(black_box(o), d, f32::INFINITY));
            }
            start.elapsed().as_secs_f64()
        });
        for &(o, d) in &closest {
            t_sum += scene.intersect(o, d, f32::INFINITY).map_or(0.0, |h| h.t as f64);
        }
        let t_any = best(&|| {
            let start = Instant::now();
            for &(o, d, t) in &shadow {
                black_box(scene.occluded(black_box(o), d, t));
            }
            start.elapsed().as_secs_f64()
        });
        let blocked = shadow.iter().filter(|&&(o, d, t)| scene.occluded(o, d, t)).count();
        println!(
            "{name:>20}: {:>7} triangles | closest {:6.1} ns/ray ({} rays, sum t {t_sum:.3}) | occluded {:6.1} ns/ray ({} rays, {blocked} blocked)",
            scene.triangles.len(),
            t_closest * 1e9 / closest.len() as f64,
            closest.len(),
            t_any * 1e9 / shadow.len().max(1) as f64,
            shadow.len(),
        );
    }
}
