//! The state of a progressive method whose pixels are the means of its passes
//! (bidirectional path tracing, vertex connection and merging, the path tracer
//! in passes of one sample a pixel): per pixel the sums over the passes of each
//! layer and of the pass's value and its square, kept in memory and in
//! pm-format's pass-sums file (`--state`).

use pm_color::{Layer, Rgb};
use pm_raster::Rect;

use crate::{Image, variance_of_mean};

/// Layers a pass fills ([`Layer::ALL`]'s order).
pub const LAYERS: usize = 5;

/// Every pixel's sums over the passes of a film.
#[derive(Clone, Debug)]
pub struct PassSums {
    width: u32,
    height: u32,
    passes: u32,
    /// Per pixel, the sum over passes of each layer's radiance [W sr^-1 m^-2].
    sum: Vec<[Rgb; LAYERS]>,
    /// Per pixel, the sums over passes of the pass's value (the mean of its
    /// channels) and its square, for the noise estimate.
    l_sum: Vec<f32>,
    l_sq: Vec<f32>,
}

impl PassSums {
    /// No passes yet, for a film of `width` x `height` pixels.
    pub fn new(width: u32, height: u32) -> PassSums {
        let n = width as usize * height as usize;
        PassSums {
            width,
            height,
            passes: 0,
            sum: vec![[Rgb::ZERO; LAYERS]; n],
            l_sum: vec![0.0; n],
            l_sq: vec![0.0; n],
        }
    }

    /// Passes added.
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// The whole film.
    pub fn full(&self) -> Rect {
        Rect::full(self.width, self.height)
    }

    /// Add a pass: every pixel's layers, in row order over the film.
    pub fn add(&mut self, pass: &[[Rgb; LAYERS]]) {
        for (i, p) in pass.iter().enumerate() {
            for (a, b) in self.sum[i].iter_mut().zip(p) {
                *a += *b;
            }
            let l = p.iter().copied().sum::<Rgb>().element_sum() / 3.0;
            self.l_sum[i] += l;
            self.l_sq[i] += l * l;
        }
        self.passes += 1;
    }

    /// Each pixel's variance of its mean over the passes [(W sr^-1 m^-2)^2], from
    /// the passes' spread; none before two passes.
    pub fn variances(&self) -> Option<Vec<f32>> {
        (self.passes >= 2)
            .then(|| self.l_sum.iter().zip(&self.l_sq).map(|(&s, &q)| variance_of_mean(s, q, self.passes)).collect())
    }

    /// The mean over the passes of the pixels of `rect`, by layer; the volume
    /// layer only when `volume` (a scene with a scattering medium).
    pub fn region_image(&self, rect: Rect, volume: bool) -> Image {
        let p = self.passes.max(1) as f32;
        let pixels: Vec<[Rgb; LAYERS]> = (rect.y0..rect.y1)
            .flat_map(|y| (rect.x0..rect.x1).map(move |x| (x, y)))
            .map(|(x, y)| self.sum[(y * self.width + x) as usize].map(|v| v / p))
            .collect();
        let layer = |l: usize| pixels.iter().map(|px| px[l]).collect::<Vec<Rgb>>();
        let volume_layer = if volume { layer(Layer::Volume.index()) } else { Vec::new() };
        Image {
            rect,
            width: rect.x1 - rect.x0,
            height: rect.y1 - rect.y0,
            total: pixels.iter().map(|px| px.iter().copied().sum()).collect(),
            layers: [layer(0), layer(1), layer(2), layer(3), volume_layer],
            gbuffer: None,
        }
    }

    /// The sums as their file holds them, for the scene of content hash
    /// `scene_hash` rendered with the settings `key` ("name=value" words).
    pub fn to_file(&self, scene_hash: [u8; 32], key: String) -> pm_format::PassStateFile {
        let records = (0..self.sum.len())
            .map(|i| pm_format::PassRecord {
                sum: self.sum[i].map(<[f32; 3]>::from),
                l_sum: self.l_sum[i],
                l_sq: self.l_sq[i],
            })
            .collect();
        pm_format::PassStateFile {
            width: self.width,
            height: self.height,
            passes: self.passes,
            scene_hash,
            params: key,
            records,
        }
    }

    /// Continue from a file's sums: refused when it was made from another scene
    /// than the one of content hash `scene_hash`, for another image size or with
    /// other settings than `key` (naming the first that differs), or holds more
    /// passes than `most`.
    pub fn resume(
        &mut self,
        file: &pm_format::PassStateFile,
        scene_hash: [u8; 32],
        key: &str,
        most: u32,
    ) -> Result<(), String> {
        if (file.width, file.height) != (self.width, self.height) {
            return Err(format!(
                "a state of a {}x{} image, this render is {}x{}",
                file.width, file.height, self.width, self.height
            ));
        }
        if file.scene_hash != scene_hash {
            return Err("made from another scene".into());
        }
        if let Some((had, has)) = pm_format::key_difference(&file.params, key) {
            return Err(format!("made with {had}, this render has {has}"));
        }
        if file.passes > most {
            return Err(format!("holds {} passes, more than the {most} asked for", file.passes));
        }
        for (i, r) in file.records.iter().enumerate() {
            self.sum[i] = r.sum.map(Rgb::from_array);
            (self.l_sum[i], self.l_sq[i]) = (r.l_sum, r.l_sq);
        }
        self.passes = file.passes;
        Ok(())
    }
}

/// A progressive renderer as [`run_passes`] drives it: SPPM, bidirectional
/// path tracing and VCM, the path tracer in passes.
pub trait PassLoop {
    /// Passes done.
    fn passes_done(&self) -> u32;
    /// One more pass over the film, seen by `camera`.
    fn next_pass(&mut self, camera: &pm_scene::Camera) -> Result<(), String>;
    /// The image of `rect` after the passes done.
    fn image_of(&self, rect: Rect) -> Image;
    /// Paths cut by a vertex limit so far.
    fn cut_paths(&self) -> u64 {
        0
    }
}

/// Run `state`'s passes over `view` until it holds `passes` (from those it
/// already holds: a resumed state), calling `after_pass` after each with the
/// state so far (to write a checkpoint image or state, or stop: `Ok(false)` ends
/// the render with the passes done; an error ends it with that error). Returns
/// the image of the view's rectangle, its statistics (the time from `t0`) and
/// the passes it holds.
pub fn run_passes<P: PassLoop>(
    state: &mut P,
    view: &crate::View,
    passes: u32,
    t0: std::time::Instant,
    after_pass: &mut dyn FnMut(&P) -> Result<bool, String>,
) -> Result<(Image, crate::RenderStats, u32), String> {
    while state.passes_done() < passes {
        state.next_pass(view.camera)?;
        if !after_pass(state)? {
            break;
        }
    }
    let image = state.image_of(view.rect);
    let stats = crate::RenderStats {
        seconds: t0.elapsed().as_secs_f64(),
        samples: state.passes_done() as u64 * image.total.len() as u64,
        terminated_paths: state.cut_paths(),
        ..Default::default()
    };
    Ok((image, stats, state.passes_done()))
}
