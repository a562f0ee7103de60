//! Every way of making an image, by name, and the one place a name becomes a
//! method (as pbrt-v4's `Integrator::Create` dispatches on the integrator's name
//! once and each integrator reads only its own parameters).
//!
//! - [`Method`]: the methods `photon-render --mode` and pipeline.toml's
//!   `[render] mode` name; [`Settings`] holds every method's own settings (each
//!   declared once in its own crate with `pm_params::params!`: pm-render's
//!   [`RenderParams`], which every method reads for the image, light samples and
//!   depth; pm-sppm's [`SppmParams`]); [`render`] runs one on a view of a scene.
//! - [`live`]: the real-time methods `photon-live --method` names
//!   ([`live::LiveMethod`]) and their settings ([`live::LiveParams`]).
//!
//! Adding a method (ARCHITECTURE.md, "Adding an integrator"): its crate, its
//! `params!` struct, a variant here with what it needs ([`Method::needs`]), a field
//! of [`Settings`] and an arm of [`render`]. No other method's crate or settings
//! change. This crate does no I/O: the stage binaries read the files a method
//! needs and write what it makes.

pub mod live;
pub mod path_passes;

pub use pm_bdpt::{BdptParams, VcmParams};
use pm_render::{
    Image, IndirectView, Integrator, Lookup, PathTracer, PhotonMapping, PhotonsView, RadianceView, RenderParams,
    RenderStats, View,
};
use pm_sppm::Sppm;
pub use pm_sppm::SppmParams;

pm_params::value_enum! {
    /// What makes the image: the method, and so the integrator.
    #[derive(Default)]
    pub enum Method {
        /// Direct + specular + caustics + final-gathered indirect from the photon
        /// maps (Christensen 1999: the complete image).
        #[default]
        Full,
        /// Radiance from the global map directly at the eye hit (Figure 1b).
        Photons,
        /// Precomputed irradiance x reflectance / pi (Figure 1e; 1c/1d show the irradiance).
        Radiance,
        /// The soft indirect term from final gathering alone (Figure 1f).
        Indirect,
        /// Unbiased path tracing: the reference (needs no photon maps).
        Path,
        /// Stochastic progressive photon mapping: passes of eye paths and photons
        /// with shrinking radii, the batch pipeline's consistent limit (needs no
        /// photon maps; Hachisuka and Jensen 2009; the pm-sppm crate).
        Sppm,
        /// Bidirectional path tracing: eye and light subpaths joined in every way,
        /// weighed by the power heuristic (needs no photon maps; Veach 1997; the
        /// pm-bdpt crate).
        Bdpt,
        /// Vertex connection and merging: bidirectional path tracing's joins and
        /// photon merging at every eye vertex with shrinking radii, under one
        /// weighting (needs no photon maps; Georgiev et al. 2012; pm-bdpt).
        Vcm,
    }
}

/// What a method reads besides the scene, and how it runs: the one table the
/// stage binaries and the runner ask instead of naming methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Needs {
    /// It reads the pipeline's photon maps (else it traces its own paths and
    /// photons, and the pipeline is one step).
    pub photon_maps: bool,
    /// It reads the caustic map too (caustics seen at the eye's surfaces).
    pub caustic: bool,
    /// It reads the volume map too: light scattered in media along its eye rays
    /// and, through the final gathers' rays, onto surfaces (so the irradiance
    /// cache's prepass, the indirect view, reads it as well).
    pub volume: bool,
    /// It reads soft indirect light from an irradiance cache (when the settings
    /// enable one).
    pub cache: bool,
    /// It reads the precomputed irradiance of global photons (Christensen's
    /// section 2.2) when final gathers look it up.
    pub irradiance: bool,
    /// It runs in passes that can be checkpointed, stopped by a time budget,
    /// resumed from a state file and averaged over independent runs.
    pub progressive: bool,
}

impl Method {
    /// What the method reads and how it runs.
    pub fn needs(self) -> Needs {
        let none = Needs {
            photon_maps: false,
            caustic: false,
            volume: false,
            cache: false,
            irradiance: false,
            progressive: false,
        };
        match self {
            Method::Full => {
                Needs { photon_maps: true, caustic: true, volume: true, cache: true, irradiance: true, ..none }
            }
            Method::Indirect => Needs { photon_maps: true, volume: true, cache: true, irradiance: true, ..none },
            Method::Radiance => Needs { photon_maps: true, irradiance: true, ..none },
            Method::Photons => Needs { photon_maps: true, ..none },
            Method::Path => none,
            Method::Sppm | Method::Bdpt | Method::Vcm => Needs { progressive: true, ..none },
        }
    }

    /// How closely the method's image agrees with the path tracer's on any scene,
    /// on its defaults (the one statement of it; `cargo xtask differential` judges
    /// by it): the batch renderer (`full`), SPPM, bidirectional path tracing
    /// (unbiased: only its noise at the default 64 passes) and vertex connection
    /// and merging (its noise and merging's shrinking bias) within 2% in the
    /// image's mean and 15% in every 8 x 8 block's, the light's pixels left out.
    /// None for the partial views (`indirect`, `radiance`, `photons`:
    /// Christensen's Figure 1) and for the path tracer, which is the reference.
    pub fn agreement(self) -> Option<Agreement> {
        match self {
            Method::Full | Method::Sppm | Method::Bdpt | Method::Vcm => {
                Some(Agreement { mean: 0.02, worst_block: 0.15 })
            }
            Method::Indirect | Method::Radiance | Method::Photons | Method::Path => None,
        }
    }

    /// True when the method with final-gather lookups `lookup` makes k-nearest
    /// estimates from the global map (Figure 1b's radiance at the eye hit, or exact
    /// lookups at gather-ray hits); otherwise the global map is only searched
    /// through its precomputed-irradiance subset, for the nearest photon.
    pub fn searches_global(self, lookup: Lookup) -> bool {
        self == Method::Photons || (lookup == Lookup::Exact && self.needs().photon_maps)
    }
}

/// The most a method's image may differ from the path tracer's (relative).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Agreement {
    /// In the mean over the image.
    pub mean: f64,
    /// In any 8 x 8 block's mean.
    pub worst_block: f64,
}

/// Every method's settings, each group declared once in its method's crate:
/// `photon-render`'s options (`--mode` and the groups flattened), pipeline.toml's
/// `[render]` (with `mode`) and `[sppm]` sections.
#[derive(Clone, Debug, PartialEq, Default, clap::Args, serde::Serialize)]
pub struct Settings {
    /// What makes the image.
    #[arg(long, default_value_t = Method::default())]
    pub mode: Method,
    /// The image, light samples and depth (every method) and the photon-map
    /// integrators' settings (pm-render).
    #[command(flatten)]
    pub render: RenderParams,
    /// Progressive photon mapping's (`--mode sppm`; pm-sppm).
    #[command(flatten, next_help_heading = "Progressive photon mapping (--mode sppm)")]
    pub sppm: SppmParams,
    /// Bidirectional path tracing's (`--mode bdpt`; pm-bdpt).
    #[command(flatten, next_help_heading = "Bidirectional path tracing (--mode bdpt)")]
    pub bdpt: BdptParams,
    /// Vertex connection and merging's (`--mode vcm`; pm-bdpt).
    #[command(flatten, next_help_heading = "Vertex connection and merging (--mode vcm)")]
    pub vcm: VcmParams,
}

impl Settings {
    /// Every group's range checks, naming the option or `section.key`.
    pub fn check(&self, cli: bool) -> Result<(), String> {
        use pm_params::Naming;
        let naming = |section| if cli { Naming::Cli } else { Naming::File(section) };
        self.render.check(naming("render"))?;
        self.sppm.validate(naming("sppm"))?;
        self.bdpt.validate(naming("bdpt"))?;
        self.vcm.validate(naming("vcm"))
    }

    /// The passes a progressive method is asked for (none for the others): SPPM's
    /// `--passes`, bidirectional path tracing's `--bdpt-passes`, VCM's
    /// `--vcm-passes`, and the path tracer's `--spp` (its passes of one sample a
    /// pixel when it runs progressively).
    pub fn passes(&self) -> Option<u32> {
        match self.mode {
            Method::Sppm => Some(self.sppm.passes),
            Method::Bdpt => Some(self.bdpt.bdpt_passes),
            Method::Vcm => Some(self.vcm.vcm_passes),
            // In passes of one sample a pixel when run progressively.
            Method::Path => Some(self.render.spp),
            _ => None,
        }
    }

    /// The photon paths a progressive method traces per pass (none for the others).
    pub fn photons_per_pass(&self) -> Option<u64> {
        (self.mode == Method::Sppm).then_some(self.sppm.photons_per_pass)
    }

    /// The command-line arguments that give every setting its value.
    pub fn to_args(&self) -> Vec<String> {
        let mut a = vec!["--mode".to_string(), self.mode.to_string()];
        a.extend(self.render.to_args());
        a.extend(self.sppm.to_args());
        a.extend(self.bdpt.to_args());
        a.extend(self.vcm.to_args());
        a
    }
}

/// What a method renders from: the photon-map integrators' state (maps, cache,
/// resolved settings), built by the caller when [`Needs::photon_maps`], or only
/// the scene.
pub enum Input<'a, G> {
    /// The photon maps (and cache) of the scene (boxed: it is several hundred
    /// bytes, the other variant one pointer).
    PhotonMaps(Box<PhotonMapping<'a, G>>),
    /// The scene alone: the method traces its own paths and photons.
    Scene(&'a pm_scene::Scene),
}

/// A progressive method's state after a pass, as the caller sees it (to show
/// progress, write a checkpoint image or the state file, or stop).
pub trait Progressive {
    /// Passes done.
    fn passes(&self) -> u32;
    /// The image of `rect` after the passes done.
    fn region_image(&self, rect: pm_render::Rect) -> Image;
    /// Estimated noise of the image so far (relative RMS, bias not included) over
    /// the pixels the accuracy study compares; none before two passes.
    fn noise(&self) -> Option<f64>;
    /// The state as its file holds it.
    fn state(&self) -> State;
}

/// A progressive method's state as its file holds it: SPPM's per-pixel radii,
/// counts and fluxes, or the plain sums over passes of the methods whose pixels
/// are averages of their passes (bidirectional path tracing).
#[derive(Clone, Debug, PartialEq)]
pub enum State {
    /// `--mode sppm`'s.
    Sppm(pm_format::StateFile),
    /// `--mode bdpt`'s and `--mode vcm`'s.
    Passes(pm_format::PassStateFile),
}

impl State {
    /// Passes the state holds.
    pub fn passes(&self) -> u32 {
        match self {
            State::Sppm(f) => f.passes,
            State::Passes(f) => f.passes,
        }
    }

    /// Write it to `path` atomically.
    pub fn write(&self, path: &std::path::Path) -> Result<(), pm_format::FormatError> {
        match self {
            State::Sppm(f) => pm_format::write_state(path, f),
            State::Passes(f) => pm_format::write_pass_state(path, f),
        }
    }

    /// Read the state file of `method` at `path` (a file of another kind is
    /// refused by its signature, naming the file).
    pub fn read(method: Method, path: &std::path::Path) -> Result<State, pm_format::FormatError> {
        Ok(match method {
            Method::Sppm => State::Sppm(pm_format::read_state(path)?),
            _ => State::Passes(pm_format::read_pass_state(path)?),
        })
    }
}

/// A progressive image's estimated noise (relative RMS) from each pixel's
/// variance `var` over its passes' spread, over all pixels but the light seen
/// directly and its neighbours (whose anti-aliased edge would decide the figure).
fn noise_of(image: &Image, var: &[f32]) -> f64 {
    let (w, h) = (image.width as usize, image.height as usize);
    let keep = pm_image::accuracy::keep_mask(&image.total, w, h, None);
    pm_image::accuracy::noise_of_variances(&image.total, var, &keep)
}

impl Progressive for Sppm<'_> {
    fn passes(&self) -> u32 {
        Sppm::passes(self)
    }

    fn region_image(&self, rect: pm_render::Rect) -> Image {
        Sppm::region_image(self, rect)
    }

    fn noise(&self) -> Option<f64> {
        Some(noise_of(&self.image(), &self.variances()?))
    }

    fn state(&self) -> State {
        State::Sppm(self.to_file())
    }
}

/// A progressive method whose pixels are the means of its passes, kept in
/// [`pm_render::PassSums`] (bidirectional path tracing, VCM, the path tracer in
/// passes): its [`Progressive`] side comes from the sums alone.
pub trait MeanOfPasses {
    /// The passes' sums.
    fn sums(&self) -> &pm_render::PassSums;
    /// True when its images have a volume layer (a scene with a scattering medium).
    fn volume(&self) -> bool;
    /// The state as its file holds it.
    fn to_file(&self) -> pm_format::PassStateFile;
}

impl<T: MeanOfPasses> Progressive for T {
    fn passes(&self) -> u32 {
        self.sums().passes()
    }

    fn region_image(&self, rect: pm_render::Rect) -> Image {
        self.sums().region_image(rect, self.volume())
    }

    fn noise(&self) -> Option<f64> {
        let sums = self.sums();
        Some(noise_of(&sums.region_image(sums.full(), self.volume()), &sums.variances()?))
    }

    fn state(&self) -> State {
        State::Passes(MeanOfPasses::to_file(self))
    }
}

impl MeanOfPasses for path_passes::PathPasses<'_> {
    fn sums(&self) -> &pm_render::PassSums {
        path_passes::PathPasses::sums(self)
    }
    fn volume(&self) -> bool {
        self.scene().has_scattering_media()
    }
    fn to_file(&self) -> pm_format::PassStateFile {
        path_passes::PathPasses::to_file(self)
    }
}

impl MeanOfPasses for pm_bdpt::Bdpt<'_> {
    fn sums(&self) -> &pm_render::PassSums {
        pm_bdpt::Bdpt::sums(self)
    }
    fn volume(&self) -> bool {
        self.scene().has_scattering_media()
    }
    fn to_file(&self) -> pm_format::PassStateFile {
        pm_bdpt::Bdpt::to_file(self)
    }
}

/// How a progressive method runs: from the passes of a state file when given
/// (the path names it in a refusal), calling `after_pass` after each pass
/// (`Ok(false)` stops with the passes done).
pub struct Passes<'a> {
    /// A state to continue from, and the file it was read from.
    pub start: Option<(&'a std::path::Path, &'a State)>,
    /// Called after each pass.
    pub after_pass: &'a mut dyn FnMut(&dyn Progressive) -> Result<bool, String>,
}

/// What a render made.
pub struct Rendered {
    /// The image of the view's rectangle, with its layers.
    pub image: Image,
    /// Its statistics.
    pub stats: RenderStats,
    /// Passes done, for a progressive method.
    pub passes: Option<u32>,
}

/// Render `view` by `settings.mode` from `input`: the one dispatch from a method
/// to its integrator. `progress` hears pixels done (or passes, for a progressive
/// method without `passes`); `passes` drives a progressive method.
pub fn render<G: pm_format::PhotonRecord>(
    settings: &Settings,
    input: Input<'_, G>,
    view: View,
    passes: Option<Passes>,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Rendered, String> {
    let method = settings.mode;
    match (method, input) {
        (Method::Sppm, Input::Scene(scene)) => {
            let (render, sppm) = (&settings.render, &settings.sppm);
            let (image, stats, done) = match passes {
                Some(Passes { start, after_pass }) => {
                    let start = match start {
                        Some((path, State::Sppm(f))) => Some((path, f)),
                        Some((path, _)) => return Err(format!("{}: not a state of --mode sppm", path.display())),
                        None => None,
                    };
                    pm_sppm::render_with(scene, render, sppm, view, start, &mut |s| after_pass(s))?
                }
                None => {
                    let (image, stats) = pm_sppm::render(scene, render, sppm, view, progress)?;
                    (image, stats, sppm.passes)
                }
            };
            Ok(Rendered { image, stats, passes: Some(done) })
        }
        (Method::Bdpt, Input::Scene(scene)) => {
            bidirectional(scene, &settings.bdpt, Method::Bdpt, view, passes, progress)
        }
        (Method::Vcm, Input::Scene(scene)) => bidirectional(scene, &settings.vcm, Method::Vcm, view, passes, progress),
        (Method::Path, Input::Scene(scene)) if passes.is_some() => {
            let Some(Passes { start, after_pass }) = passes else { unreachable!() };
            let start = match start {
                Some((path, State::Passes(f))) => Some((path, f)),
                Some((path, _)) => return Err(format!("{}: not a state of --mode path", path.display())),
                None => None,
            };
            let total = settings.render.spp;
            let (image, stats, done) = path_passes::render_with(scene, view, total, start, &mut |p| after_pass(p))?;
            Ok(Rendered { image, stats, passes: Some(done) })
        }
        (Method::Path, Input::Scene(scene)) => {
            let pt = PathTracer::new(scene).map_err(|e| e.to_string())?;
            image(view, &pt, progress)
        }
        (Method::Full, Input::PhotonMaps(pm)) => image(view, &*pm, progress),
        (Method::Photons, Input::PhotonMaps(pm)) => image(view, &PhotonsView(*pm), progress),
        (Method::Radiance, Input::PhotonMaps(pm)) => image(view, &RadianceView(*pm), progress),
        (Method::Indirect, Input::PhotonMaps(pm)) => image(view, &IndirectView(*pm), progress),
        (m, _) => Err(format!(
            "--mode {m} {} photon maps",
            if m.needs().photon_maps { "renders from" } else { "traces its own paths, without" }
        )),
    }
}

/// Bidirectional path tracing or vertex connection and merging (`method`, with
/// `params`), in passes.
fn bidirectional(
    scene: &pm_scene::Scene,
    params: &impl pm_bdpt::Method,
    method: Method,
    view: View,
    passes: Option<Passes>,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Rendered, String> {
    let (image, stats, done) = match passes {
        Some(Passes { start, after_pass }) => {
            let start = match start {
                Some((path, State::Passes(f))) => Some((path, f)),
                Some((path, _)) => return Err(format!("{}: not a state of --mode {method}", path.display())),
                None => None,
            };
            pm_bdpt::render_with(scene, params, view, start, &mut |b| after_pass(b))?
        }
        None => {
            let (image, stats) = pm_bdpt::render(scene, params, view, progress)?;
            (image, stats, params.passes())
        }
    };
    Ok(Rendered { image, stats, passes: Some(done) })
}

/// The image loop over an integrator.
fn image<I: Integrator>(view: View, integrator: &I, progress: &(dyn Fn(u64, u64) + Sync)) -> Result<Rendered, String> {
    let (image, stats) = pm_render::render_region(view.camera, view.film, view.rect, integrator, false, progress)?;
    Ok(Rendered { image, stats, passes: None })
}
