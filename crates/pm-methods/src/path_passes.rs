//! The path tracer in passes of one sample a pixel, so that it runs as the
//! progressive methods do (`--time-budget`, `--state`, `--checkpoint`, `--run`)
//! and every method can be compared at equal time with one option.

use pm_render::{Film, Image, LAYERS, PassSums, PathTracer, Rect, View};

/// The path tracer's passes over a film: pass k renders every pixel with one
/// path from the seed [`pass_seed`]`(seed, k)`; the image is the passes' mean.
pub struct PathPasses<'a> {
    scene: &'a pm_scene::Scene,
    tracer: PathTracer<'a>,
    camera: &'a pm_scene::Camera,
    film: Film,
    sums: PassSums,
}

/// The film seed of pass `k` of a render seeded `seed`: its own stream for each
/// pass (a splitmix-style odd multiplier keeps them apart).
pub fn pass_seed(seed: u64, k: u32) -> u64 {
    seed ^ (k as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

impl<'a> PathPasses<'a> {
    /// No passes yet over `film` (its size and seed; one sample a pixel a pass)
    /// of `scene` seen by `camera`; refused for a scene without lights.
    pub fn new(scene: &'a pm_scene::Scene, camera: &'a pm_scene::Camera, film: &Film) -> Result<Self, String> {
        let tracer = PathTracer::new(scene).map_err(|e| e.to_string())?;
        let film = Film { spp: 1, contrast: 0.0, ..*film };
        Ok(PathPasses { scene, tracer, camera, sums: PassSums::new(film.width, film.height), film })
    }

    /// The settings that shape the state, as "name=value" words.
    pub fn key(&self) -> String {
        format!(
            "method=path width={} height={} seed={} pixel_centres={}",
            self.film.width, self.film.height, self.film.seed, self.film.pixel_centres
        )
    }

    /// One pass: a path a pixel over the whole film.
    pub fn pass(&mut self) -> Result<(), String> {
        let film = Film { seed: pass_seed(self.film.seed, self.sums.passes()), ..self.film };
        let (img, _) = pm_render::render_region(self.camera, &film, film.rect(), &self.tracer, false, &|_, _| {})?;
        let pass: Vec<[pm_color::Rgb; LAYERS]> = (0..img.total.len())
            .map(|i| std::array::from_fn(|l| img.layers[l].get(i).copied().unwrap_or_default()))
            .collect();
        self.sums.add(&pass);
        Ok(())
    }

    /// The scene it renders.
    pub fn scene(&self) -> &pm_scene::Scene {
        self.scene
    }

    /// The passes' sums.
    pub fn sums(&self) -> &PassSums {
        &self.sums
    }

    /// Passes done.
    pub fn passes(&self) -> u32 {
        self.sums.passes()
    }

    /// The image of `rect` after the passes done.
    pub fn region_image(&self, rect: Rect) -> Image {
        self.sums.region_image(rect, self.scene.has_scattering_media())
    }

    /// The state as its file holds it.
    pub fn to_file(&self) -> pm_format::PassStateFile {
        self.sums.to_file(self.scene.content_hash, self.key())
    }
}

/// `passes` passes of the path tracer over `view` (the whole film traced, its
/// region returned), from `start`'s passes when given (refused, naming the
/// file, when made from another scene or with other settings), calling
/// `after_pass` after each: the image, its statistics and the passes done.
pub fn render_with(
    scene: &pm_scene::Scene,
    view: View,
    passes: u32,
    start: Option<(&std::path::Path, &pm_format::PassStateFile)>,
    after_pass: &mut dyn FnMut(&PathPasses) -> Result<bool, String>,
) -> Result<(Image, pm_render::RenderStats, u32), String> {
    let t0 = std::time::Instant::now();
    let mut p = PathPasses::new(scene, view.camera, view.film)?;
    if let Some((path, file)) = start {
        let key = p.key();
        p.sums.resume(file, scene.content_hash, &key, passes).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    pm_render::run_passes(&mut p, &view, passes, t0, after_pass)
}

impl pm_render::PassLoop for PathPasses<'_> {
    fn passes_done(&self) -> u32 {
        self.passes()
    }
    fn next_pass(&mut self, _camera: &pm_scene::Camera) -> Result<(), String> {
        self.pass()
    }
    fn image_of(&self, rect: Rect) -> Image {
        self.region_image(rect)
    }
}
