//! First hits at 512 x 512 pixel centres by the rasteriser against eye rays, the
//! image loop's own cost over rasterised hits (an integrator that returns the hit
//! distance), shadow rays to the first light (an area light's centroid), and
//! gather rays (one cosine-distributed ray from each first hit, closest hit), on
//! the live room, cornell_spheres, cornell_dense (109k triangles) and instanced
//! (1.46M) (1 and 2 threads, best of 10 frames each), with each kind's rays per
//! second per thread.
//!
//! Run: `cargo bench -p pm-render --bench visibility`

use pm_raster as raster;
use pm_render::Film;
use rayon::prelude::*;
use std::time::Instant;

fn best_of(n: usize, mut f: impl FnMut()) -> f64 {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    println!(
        "| scene | triangles | threads | raster [ms] | image loop over raster [ms] | eye rays [ms] | shadow rays [ms] | gather rays [ms] | raster / eye rays | cube shadow map 6 x 256^2 [ms] | eye / shadow / gather [M rays/s/thread] |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for name in ["jozwowski_room_1024", "cornell_spheres", "cornell_dense", "instanced"] {
        let scene = pm_scene::load(&dir.join(format!("{name}.gltf"))).unwrap();
        let camera = scene.camera.clone().unwrap();
        let film = Film { width: 512, height: 512, spp: 1, contrast: 0.0, seed: 0, pixel_centres: false };
        let rect = film.rect();
        let light = match scene.lights[0].kind {
            pm_scene::LightKind::Point { position, .. } | pm_scene::LightKind::Spot { position, .. } => position,
            pm_scene::LightKind::Area { ref tris, .. } => {
                let c: glam::Vec3 =
                    tris.clone().map(|t| scene.triangles[t as usize].p.iter().sum::<glam::Vec3>()).sum();
                c / (3 * tris.len()).max(1) as f32
            }
            _ => scene.bounds.center(),
        };
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut frags = Vec::new();
                let t_raster = best_of(10, || raster::first_hits_into(&scene, &camera, film.size(), rect, &mut frags));
                let rays = camera.rays(1.0);
                let mut hits = Vec::new();
                let t_rays = best_of(10, || {
                    hits.clear();
                    hits.par_extend((0..512 * 512).into_par_iter().with_min_len(256).map(|i| {
                        let d = rays
                            .direction((i % 512) as f32 / 512.0 + 0.5 / 512.0, (i / 512) as f32 / 512.0 + 0.5 / 512.0);
                        scene.intersect(camera.position, d, f32::INFINITY).map(|h| {
                            let ng = if h.ng.dot(d) > 0.0 { -h.ng } else { h.ng };
                            (h.p, ng)
                        })
                    }));
                });
                let t_gather = best_of(10, || {
                    let n: usize = hits
                        .par_iter()
                        .enumerate()
                        .with_min_len(256)
                        .filter(|(i, h)| {
                            h.is_some_and(|(p, ng)| {
                                let mut s = pm_sampling::Sampler::new(3, *i as u64);
                                let d = pm_sampling::to_world(pm_sampling::cosine_hemisphere(s.next_2d()), ng);
                                scene.intersect(scene.offset_origin(p, ng, d), d, f32::INFINITY).is_some()
                            })
                        })
                        .count();
                    std::hint::black_box(n);
                });
                let t_shadow = best_of(10, || {
                    let n: usize = hits
                        .par_iter()
                        .with_min_len(256)
                        .filter(|h| {
                            h.is_some_and(|(p, _)| {
                                let d = light - p;
                                let len = d.length();
                                scene.occluded(p + d * 1e-4, d / len, len * 0.999)
                            })
                        })
                        .count();
                    std::hint::black_box(n);
                });
                let t_loop = image_loop(&scene, &camera, &film);
                let t_cube = best_of(10, || {
                    std::hint::black_box(raster::CubeDepth::new(&scene, light, 256));
                });
                let n_hits = hits.iter().filter(|h| h.is_some()).count() as f64;
                let per_thread = |rays: f64, t: f64| rays / t / threads as f64 * 1e-6;
                println!(
                    "| {name} | {} | {threads} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} / {:.1} / {:.1} |",
                    scene.triangles.len(),
                    t_raster * 1e3,
                    t_loop * 1e3,
                    t_rays * 1e3,
                    t_shadow * 1e3,
                    t_gather * 1e3,
                    t_raster / t_rays,
                    t_cube * 1e3,
                    per_thread((512 * 512) as f64, t_rays),
                    per_thread(n_hits, t_shadow),
                    per_thread(n_hits, t_gather),
                );
            });
        }
    }
}

/// An integrator that returns the hit distance: the image loop's own cost.
struct Flat(pm_render::Counters);

impl pm_render::Integrator for Flat {
    type Scratch = ();
    fn li(
        &self,
        _: glam::Vec3,
        _: glam::Vec3,
        first: pm_render::FirstHit,
        _: &mut pm_sampling::Sampler,
        _: &mut (),
        _: Option<&mut pm_render::VisibleSurface>,
    ) -> pm_render::Components {
        let t = match first {
            pm_render::FirstHit::Fragment(scene, f) => f.map_or(0.0, |f| f.hit(scene).t),
            pm_render::FirstHit::Unknown => 0.0,
        };
        pm_render::Components { direct: pm_color::Rgb::splat(t), ..Default::default() }
    }
    fn counters(&self) -> &pm_render::Counters {
        &self.0
    }
}

/// The image loop over rasterised first hits with an integrator that does nothing.
fn image_loop(scene: &pm_scene::Scene, camera: &pm_scene::Camera, film: &Film) -> f64 {
    let mut bufs = pm_render::FrameBuffers::default();
    let flat = Flat(Default::default());
    best_of(10, || {
        pm_render::render_into(
            pm_render::Shot { camera, film, rect: film.rect() },
            &flat,
            false,
            pm_render::Visibility::Raster(scene),
            &mut bufs,
            &|_, _| {},
        )
        .unwrap();
    })
}
