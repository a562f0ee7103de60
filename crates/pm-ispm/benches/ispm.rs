//! Image-space photon mapping (McGuire and Luebke 2009) on 2 threads: the frame
//! time split like the paper's Table 2 on cornell_spheres, the caustic ring and
//! cornell_dense (109k triangles) at 512 x 512 and 1920 x 1080; the splat against a
//! gather over the same photons at equal output (the paper's central claim); what
//! subsampling and the bounce count cost in error against the path tracer and
//! against their time (section 5.2); photon attrition (Figure 10).
//!
//! Run: `cargo bench -p pm-ispm --bench ispm`

use pm_color::Rgb;
use pm_ispm::KernelShape;
use pm_ispm::splat::{self, PhotonIndex, SplatOutput};
use pm_ispm::{Ispm, IspmFrame, IspmParams};
use pm_live::{DirectMode, FrameParams, Live};
use pm_raster as raster;
use pm_render::Film;
use pm_scene::Scene;
use std::time::Instant;

/// Frame and image-space parameters of a run.
#[derive(Clone, Default)]
struct Params(FrameParams, IspmParams);

fn start(s: Scene, _: Option<Scene>, p: Params, seed: u64) -> Result<Live<Ispm>, String> {
    pm_ispm::live(s, p.0, p.1, seed)
}

fn scene(name: &str) -> Scene {
    pm_scene::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../scenes/{name}.gltf"))).unwrap()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Frames of `p` (the first is a warm-up); the median split and the last frame's stats.
fn frames(s: &Scene, p: &Params, n: usize) -> ([f64; 7], IspmFrame, Vec<Rgb>) {
    let mut live = start(s.clone(), None, p.clone(), 1).unwrap();
    let rows: Vec<IspmFrame> = (0..n).map(|_| live.step().unwrap()).collect();
    let last = rows.last().cloned();
    let rows = &rows[1..];
    let m = |f: fn(&IspmFrame) -> f64| median(rows.iter().map(f).collect()) * 1e3;
    let split = [
        m(|t| t.gbuffer_s),
        m(|t| t.direct_s),
        m(|t| t.bounce_s),
        m(|t| t.trace_s),
        m(|t| t.splat_s),
        m(|t| t.upsample_s),
        m(|t| t.total_s),
    ];
    let indirect: Vec<Rgb> = {
        let l = live.frame_layers();
        l.layer(pm_color::Layer::Indirect).iter().zip(l.layer(pm_color::Layer::Caustic)).map(|(a, b)| *a + *b).collect()
    };
    (split, last.unwrap(), indirect)
}

fn main() {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    pool.install(run);
}

fn run() {
    // `cargo bench -p pm-ispm --bench ispm -- bounces`: only the bounce-count table.
    if std::env::args().any(|a| a == "bounces") {
        let s = scene("cornell_spheres");
        against_the_path_tracer(&s, &Reference::new(&s), &BOUNCE_ROWS);
        return;
    }
    let scenes: Vec<(&str, Scene)> =
        ["cornell_spheres", "caustic_ring", "cornell_dense"].into_iter().map(|n| (n, scene(n))).collect();
    table2(&scenes);
    attrition(&scenes);
    let s = find(&scenes, "cornell_spheres");
    splat_against_gather(s);
    subsampling(s);
    let reference = Reference::new(s);
    against_the_path_tracer(s, &reference, &ROWS);
    direct_light_both_ways(s, &reference);
}

/// The scene called `name`.
fn find<'a>(scenes: &'a [(&str, Scene)], name: &str) -> &'a Scene {
    &scenes.iter().find(|s| s.0 == name).unwrap().1
}

/// The frame time split like the paper's Table 2, per scene, size and setting.
fn table2(scenes: &[(&str, Scene)]) {
    println!("Frame time split like Table 2 (2 threads, medians of 4 frames after one warm-up) [ms]");
    println!(
        "| scene | size | direct | bounces | subsample | G-buffer | direct | bounce map | trace | splat | upsample | frame | fps | texels | stored photons |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let rows: [(&str, DirectMode, u32, u32); 7] = [
        ("cornell_spheres", DirectMode::Rays, 1, 1),
        ("cornell_spheres", DirectMode::Rays, 1, 4),
        ("cornell_spheres", DirectMode::ShadowMap, 1, 4),
        ("cornell_spheres", DirectMode::Rays, 3, 4),
        ("caustic_ring", DirectMode::ShadowMap, 1, 1),
        ("caustic_ring", DirectMode::Rays, 1, 1),
        ("cornell_dense", DirectMode::Rays, 1, 4),
    ];
    for (w, h) in [(512u32, 512u32), (1920, 1080)] {
        for &(name, direct, bounces, subsample) in &rows {
            let s = find(scenes, name);
            let bounce_res = if name == "caustic_ring" { 128 } else { 48 };
            let p = Params(
                FrameParams { width: w, height: h, direct, ..Default::default() },
                IspmParams { bounces, subsample, bounce_res, ..Default::default() },
            );
            let (t, st, _) = frames(s, &p, 5);
            println!(
                "| {name} | {w}x{h} | {direct:?} | {bounces} | {subsample} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} |",
                t[0],
                t[1],
                t[2],
                t[3],
                t[4],
                t[5],
                t[6],
                1e3 / t[6],
                st.texels,
                st.photons
            );
        }
    }
}

/// Photon attrition (Figure 10): of the texels shot, how many hit, survive the
/// first bounce, and how many photons each further bounce stores.
fn attrition(scenes: &[(&str, Scene)]) {
    println!("\nPhoton attrition (Figure 10), bounce_res 48 (128 for the ring), 3 bounces");
    println!("| scene | texels | hit a surface | survived bounce 1 | photons stored | stored per surviving path |");
    println!("|---|---|---|---|---|---|");
    for (name, s) in scenes {
        let res = if *name == "caustic_ring" { 128 } else { 48 };
        let b = pm_ispm::bounce_maps(s, res, 1, true);
        let st = b.stats;
        let p = Params(FrameParams { ..Default::default() }, IspmParams { bounces: 3, ..Default::default() });
        let photons = pm_ispm::trace(s, &b, 3, &KernelShape::new(&p.1, s.bounds.diagonal()), 1).photons;
        println!(
            "| {name} | {} | {} ({:.0}%) | {} ({:.0}%) | {} | {:.2} |",
            st.texels,
            st.hits,
            100.0 * st.hits as f64 / st.texels as f64,
            st.survived,
            100.0 * st.survived as f64 / st.texels as f64,
            photons.len(),
            photons.len() as f64 / st.survived.max(1) as f64
        );
    }
}

/// Scatter against gather at equal output (the paper's central claim).
fn splat_against_gather(s: &Scene) {
    println!("\nSplat against a gather over the same photons (cornell_spheres, 512 x 512, 1 bounce) [ms]");
    println!("| photons | splat | gather (grid radius query per pixel) | gather / splat | largest difference |");
    println!("|---|---|---|---|---|");
    for res in [32u32, 48, 96] {
        let p = Params(
            FrameParams { ..Default::default() },
            IspmParams { bounces: 1, bounce_res: res, ..Default::default() },
        );
        let b = pm_ispm::bounce_maps(s, res, 1, true);
        let photons = pm_ispm::trace(s, &b, 1, &KernelShape::new(&p.1, s.bounds.diagonal()), 1).photons;
        let camera = s.camera.clone().unwrap();
        let film = Film { width: 512, height: 512, spp: 1, contrast: 0.0, seed: 0, pixel_centres: false };
        let gb = pm_ispm::surfaces(s, &raster::first_hits(s, &camera, film.size(), film.rect()), &camera);
        let packed = splat::GBuffer::from_surfaces(&gb);
        let t = Instant::now();
        let (si, _) = splat::splat(&photons, &packed, &camera, (512, 512, 1), SplatOutput::Radiance);
        let t_splat = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let index = PhotonIndex::new(&photons);
        use rayon::prelude::*;
        let gi: Vec<Rgb> = gb
            .par_iter()
            .map(|g| g.as_ref().map_or(Rgb::ZERO, |surface| splat::gather(&photons, &index, surface).0))
            .collect();
        let t_gather = t.elapsed().as_secs_f64();
        let diff = si
            .iter()
            .zip(&gi)
            .map(|(a, b)| (*a - *b).abs().max_element() / b.max_element().max(1e-3))
            .fold(0.0f32, f32::max);
        println!(
            "| {} | {:.1} | {:.1} | {:.2} | {diff:.1e} |",
            photons.len(),
            t_splat * 1e3,
            t_gather * 1e3,
            t_gather / t_splat
        );
    }
}

/// What subsampling costs: indirect error against the full-resolution splat,
/// against frame time (section 5.2).
fn subsampling(s: &Scene) {
    println!("\nSubsampling (cornell_spheres, 512 x 512, 1 bounce): indirect + caustic against full resolution");
    println!("| subsample | frame [ms] | splat + upsample [ms] | relative RMSE | mean bias |");
    println!("|---|---|---|---|---|");
    let base = Params(FrameParams { ..Default::default() }, IspmParams { bounces: 1, ..Default::default() });
    let (_, _, full) = frames(s, &base, 3);
    for f in [1u32, 2, 4, 8, 16] {
        let (t, _, ind) = frames(s, &Params(base.0.clone(), IspmParams { subsample: f, ..base.1.clone() }), 4);
        let e = pm_image::compare(&ind, &full, 1.0);
        println!("| {f} | {:.1} | {:.1} | {:.4} | {:+.4} |", t[6], t[4] + t[5], e.rel_rmse, e.rel_bias);
    }
}

/// Side of the image compared with the path tracer [pixels].
const SIZE: u32 = 512;

/// Means of 4 x 4 blocks of a SIZE x SIZE image.
fn blocks(px: &[Rgb]) -> Vec<Rgb> {
    let (w, h) = (SIZE, SIZE);
    (0..(w / 4) * (h / 4))
        .map(|b| {
            let (bx, by) = (b % (w / 4), b / (w / 4));
            let mut sum = Rgb::ZERO;
            for y in by * 4..by * 4 + 4 {
                for x in bx * 4..bx * 4 + 4 {
                    sum += px[(y * w + x) as usize];
                }
            }
            sum / 16.0
        })
        .collect()
}

/// Error measures over the blocks that do not see the light: relative RMSE and
/// bias of the image, and the median and 90th percentile of the blocks' relative
/// errors (the RMSE is ruled by a few caustic blocks).
fn measure_against(img: &[Rgb], reference: &[Rgb]) -> (f64, f64, f32, f32) {
    let e = pm_image::compare(img, reference, 4.0);
    let mut rel: Vec<f32> = img
        .iter()
        .zip(reference)
        .filter(|(_, r)| r.max_element() <= 4.0 && r.max_element() > 0.01)
        .map(|(a, r)| (*a - *r).abs().element_sum() / r.element_sum())
        .collect();
    rel.sort_by(f32::total_cmp);
    (e.rel_rmse, e.rel_bias, rel[rel.len() / 2], rel[rel.len() * 9 / 10])
}

/// The path tracer's image at 64 paths per pixel, as 4 x 4 block means (the
/// reference's noise there is that of 1024 paths), its direct layer, and a second
/// image with another seed (the reference's own noise).
struct Reference {
    total: Vec<Rgb>,
    direct: Vec<Rgb>,
    second: Vec<Rgb>,
    seconds: f64,
}

impl Reference {
    fn new(s: &Scene) -> Reference {
        let camera = s.camera.clone().unwrap();
        let film = Film { width: SIZE, height: SIZE, spp: 64, contrast: 0.0, seed: 11, pixel_centres: false };
        let t = Instant::now();
        let pt = pm_render::PathTracer::new(s).unwrap();
        let (path, _) = pm_render::render_region(&camera, &film, film.rect(), &pt, false, &|_, _| {}).unwrap();
        let seconds = t.elapsed().as_secs_f64();
        let film2 = Film { seed: 12, ..film };
        let (path2, _) = pm_render::render_region(&camera, &film2, film2.rect(), &pt, false, &|_, _| {}).unwrap();
        Reference {
            total: blocks(path.total()),
            direct: blocks(path.layer(pm_color::Layer::Direct)),
            second: blocks(path2.total()),
            seconds,
        }
    }
}

/// (bounce_res, bounces, subsample) of the comparison with the path tracer.
const ROWS: [(u32, u32, u32); 7] =
    [(48, 1, 1), (48, 3, 1), (48, 8, 1), (48, 8, 4), (96, 8, 1), (96, 8, 4), (160, 8, 4)];

/// The bounce count at the default bounce map: where more bounces stop paying.
const BOUNCE_ROWS: [(u32, u32, u32); 6] = [(48, 1, 1), (48, 2, 1), (48, 3, 1), (48, 4, 1), (48, 6, 1), (48, 8, 1)];

/// Against the path tracer: 512 x 512, both images compared as means of 4 x 4
/// blocks, blocks touching the light's pixels left out, for each of `rows`.
fn against_the_path_tracer(s: &Scene, reference: &Reference, rows: &[(u32, u32, u32)]) {
    let t_path = reference.seconds;
    let measure = |img: &[Rgb]| measure_against(img, &reference.total);
    let (rr, rb, rm, r9) = measure(&reference.second);
    println!(
        "\nAgainst the path tracer (cornell_spheres, 512 x 512, 64 spp in {t_path:.0} s; 4 x 4 block means, the light's blocks left out)"
    );
    println!(
        "| bounce_res | bounces | subsample | frame [ms] | relative RMSE | mean bias | median block error | 90th percentile |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    println!("| (a second 64-spp path-traced image) | | | | {rr:.4} | {rb:+.4} | {rm:.4} | {r9:.4} |");
    for &(bounce_res, bounces, subsample) in rows {
        let p = Params(
            FrameParams { light_samples: 4, ..Default::default() },
            IspmParams { bounce_res, bounces, subsample, ..Default::default() },
        );
        let mut live = start(s.clone(), None, p.clone(), 1).unwrap();
        live.step().unwrap();
        let (er, eb, em, e9) = measure(&blocks(live.frame_layers().total()));
        // Frame time at the default light_samples = 1 (the error uses 4 to keep the
        // direct light's noise out of the comparison).
        let mut timed =
            start(s.clone(), None, Params(FrameParams { light_samples: 1, ..p.0.clone() }, p.1.clone()), 1).unwrap();
        let wall = (0..3).map(|_| timed.step().unwrap().total_s).fold(f64::INFINITY, f64::min);
        println!(
            "| {bounce_res} | {bounces} | {subsample} | {:.1} | {er:.4} | {eb:+.4} | {em:.4} | {e9:.4} |",
            wall * 1e3
        );
    }
}

/// Direct light both ways (the issue: "shadow rays or shadow maps: measure both").
fn direct_light_both_ways(s: &Scene, reference: &Reference) {
    let measure = |img: &[Rgb]| measure_against(img, &reference.total);
    println!(
        "\nDirect light by shadow rays or a shadow map (cornell_spheres, 512 x 512, bounce_res 48, 8 bounces, subsample 4; against the path tracer, 4 x 4 blocks)"
    );
    println!(
        "| direct | light samples | frame [ms] | direct step [ms] | direct layer: relative RMSE | mean bias | median block error | image: median block error |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (direct, light_samples) in [(DirectMode::Rays, 1), (DirectMode::Rays, 4), (DirectMode::ShadowMap, 1)] {
        let p = Params(
            FrameParams { direct, light_samples, ..Default::default() },
            IspmParams { bounce_res: 48, bounces: 8, subsample: 4, ..Default::default() },
        );
        let mut live = start(s.clone(), None, p, 1).unwrap();
        let (mut wall, mut step) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..4 {
            let st = live.step().unwrap();
            wall = wall.min(st.total_s);
            step = step.min(st.direct_s);
        }
        let layers = live.frame_layers();
        let (dr, db, dm, _) = measure_against(&blocks(layers.layer(pm_color::Layer::Direct)), &reference.direct);
        let (_, _, tm, _) = measure(&blocks(layers.total()));
        println!(
            "| {direct:?} | {light_samples} | {:.1} | {:.1} | {dr:.4} | {db:+.4} | {dm:.4} | {tm:.4} |",
            wall * 1e3,
            step * 1e3
        );
    }
}
