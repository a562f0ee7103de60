//! Frame time of the live renderer split into its steps, on the thesis's room at
//! 1,024 surfaces, 512 x 512, 2 threads (the goal setting), for each way of
//! computing direct light. 20 warm-up frames fill the buffer; the medians of the
//! next 60 frames are printed (the light circles, so every frame re-shoots). The
//! frame is wall time: the rasteriser runs beside the photon update, so the steps
//! add up to more.
//!
//! Run: `cargo bench -p pm-vertex --bench frame [-- SCENE]`

use pm_live::{DirectMode, FrameParams};
use pm_vertex::{VertexFrame, VertexParams};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let name = std::env::args().nth(1).filter(|a| !a.starts_with('-')).unwrap_or("jozwowski_room_1024".into());
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../scenes/{name}.gltf"));
    let scene = pm_scene::load(&path).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    println!("{name}, 512 x 512, 2 threads, medians of 60 frames [ms]");
    println!("| direct | shoot | grid update | estimate | draw | frame | fps |");
    println!("|---|---|---|---|---|---|---|");
    for direct in [DirectMode::Photons, DirectMode::ShadowMap, DirectMode::Rays] {
        let frame = FrameParams { direct, ..FrameParams::default() };
        let mut live = pm_vertex::live(scene.clone(), None, frame, VertexParams::default(), 1).unwrap();
        let mut rows = Vec::new();
        pool.install(|| {
            for f in 0..80 {
                live.set_time(f as f32 / 60.0);
                let s = live.step().unwrap();
                if f >= 20 {
                    rows.push(s);
                }
            }
        });
        let m = |f: fn(&VertexFrame) -> f64| median(rows.iter().map(f).collect()) * 1e3;
        let frame = m(|t| t.total_s);
        println!(
            "| {direct:?} | {:.2} | {:.2} | {:.2} | {:.2} | {frame:.2} | {:.1} |",
            m(|t| t.shoot_s),
            m(|t| t.balance_s),
            m(|t| t.estimate_s),
            m(|t| t.draw_s),
            1e3 / frame
        );
    }
}
