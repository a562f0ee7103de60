//! Bidirectional path tracing (Veach 1997, chapter 10; the vertex bookkeeping of
//! pbrt-v3 section 16.3): the robust end of the accuracy study, consistent
//! where the photon maps are biased and able to find what the path tracer
//! cannot (light paths that reach the eye only through a small bright light
//! seen in a mirror, caustics on a diffuse floor seen directly).
//!
//! Each pass traces, for every pixel, one eye subpath z_0 z_1 ... (z_0 the
//! pinhole, z_1 through a point uniform in the pixel) and one light subpath
//! y_0 y_1 ... (y_0 on a light chosen by power, pm-light's [`LightSelector`],
//! the photon tracer's choice), each extended by BSDF sampling with Russian
//! roulette, and joins them in every way (s, t) that can make a path of s light
//! and t eye vertices:
//!
//! - s = 0: the eye subpath found an emitter;
//! - s = 1: a point picked on a light (as a light subpath's start) is joined to
//!   z_{t-1} by a shadow ray (next-event estimation);
//! - t = 1: y_{s-1} is joined to the pinhole and splatted into the pixel it
//!   projects to (light tracing);
//! - otherwise z_{t-1} and y_{s-1} are joined by a shadow ray.
//!
//! Every strategy's contribution is weighed by the power heuristic over all the
//! strategies that could have made the same path (Veach 1997, section 10.2),
//! computed in O(1) a join from three running sums each vertex keeps, the
//! recursive quantities d_VCM, d_VC and d_VM of Georgiev, Krivanek, Davidovic and
//! Slusallek's technical report ("Implementing vertex connection and merging",
//! 2012, eqs. 31-50; [`Partial`]). A path of one segment (an emitter seen
//! directly) has only the strategy s = 0, t = 2.
//!
//! **Vertex connection and merging** ([`Bdpt::vcm`]; Georgiev et al. 2012,
//! "Light transport simulation with vertex connection and merging") is the same
//! pass with one more strategy at every diffuse or glossy eye vertex: merging it
//! with the light vertices of *every* light subpath of the pass within radius
//! r_i = r_0 i^((alpha - 1) / 2) (pass i), a photon density estimate whose
//! weight against the connections comes from the same sums. The pass first
//! traces all its light subpaths (one a pixel), stores their vertices (sized
//! per pass: nothing grows with passes) and splats light tracing, then traces
//! the eye subpaths; eye subpath i joins light subpath i. With merging off it
//! is bidirectional path tracing, the same code; with connections off it is a
//! progressive photon mapper with the merges weighed against each other
//! (SmallVCM's "BPM").
//!
//! Radiance [W sr^-1 m^-2 per RGB channel] is carried along eye subpaths as the
//! path tracer carries it (its 1 / eta^2 through glass); light subpaths carry
//! power, with Veach's correction for shading normals (1997, section 5.3) so
//! that the same path gets the same value from either side. The camera's
//! importance is W_e = 1 / (A cos^4 theta) for a film of area A at unit distance,
//! so that a splatted light path adds its pixel's mean radiance.
//!
//! Deterministic: pass k's eye subpath of pixel i is point k of the pixel's
//! stream, its light subpath point k of a stream keyed by i too; pixels are
//! traced in fixed chunks, each chunk's splats kept in order and added chunk by
//! chunk after the pass, so any thread count gives the same image.
//!
//! Participating media: subpaths scatter in them by the path tracer's free
//! flights (a hero channel a subpath, the balance heuristic over channels), a
//! point in a medium is a vertex like a surface's (its phase function for the
//! BSDF, no cosines), and joins carry the transmittance between their ends
//! through media and index-matched boundaries. The MIS densities of a point in
//! a medium are per volume: its mean extinction takes the place of a surface's
//! cosine ([`Vertex::measure`]); the transmittance before it is left out, as
//! pbrt-v3's volumetric BDPT leaves out all of the distance sampling: the
//! weights still add up to one for every path, so the estimate stays unbiased.
//! VCM merges eye points in a medium with the pass's light vertices in media
//! within the radius (a ball: Jensen and Christensen 1998's volume radiance
//! estimate, eta_vol = 4/3 pi r^3 N in the weights), so that merging alone
//! carries in-scattered light too; point-to-point merges in a volume are
//! rare, and where connections can make the same path they take nearly all
//! of its weight.
//!
//! Lights at infinity (an environment, suns) start light subpaths too, as in
//! SmallVCM: a direction by the light's emission (`Light::sample_sky_dir`) and a
//! point on the disc of the scene's bounding sphere across it, density 1 / (pi
//! R^2); their first segment has no 1 / d^2 and their "cosine" is 1. The eye
//! subpaths find them by leaving the scene (s = 0) and by sampling them at a
//! vertex (s = 1, `Light::sample_li`, the same choice of light as every other
//! s = 1), each light weighed on its own in the same recursive sums, so a sun's
//! light through glass (its caustics) has the light subpaths' strategies.

use glam::Vec3;
use pm_bsdf::{Bsdf, HenyeyGreenstein};
use pm_color::{Layer, Rgb};
use pm_kdtree::RadiusGrid;
use pm_light::LightSelector;
use pm_render::{Image, LAYERS, View, pixel_salt};
use pm_sampling::Sampler;
use pm_scene::{Camera, CameraRays, EmitterPoint, Flights, FreeFlight, LightKind, MediumId, Scene};
use rayon::prelude::*;

use pm_params::{Any, above, between};

pm_params::params! {
    /// Bidirectional path tracing's own settings, defined once: `photon-render
    /// --mode bdpt`'s options and pipeline.toml's `[bdpt]` section (keys without
    /// the `bdpt_` of the options). The image size is `[render]`'s.
    #[derive(Copy)]
    pub struct BdptParams {
        /// Passes, each one eye and one light subpath a pixel (at 16, the
        /// differential checker's fog and glass scenes were off by their noise
        /// alone in 3 of 20).
        bdpt_passes as "passes": u32 = 64 => between(1, 1 << 24);
        /// Most vertices of a subpath after its first (the pinhole or the light's
        /// point), the path tracer's limit; Russian roulette ends nearly every
        /// subpath long before, and the cut ones are counted. (At 64, the
        /// furnace filled with a dense conservative medium lost 3% of its light.)
        bdpt_max_vertices as "max_vertices": u32 = 1000 => between(1, 1 << 16);
    }
}

pm_params::params! {
    /// Vertex connection and merging's own settings, defined once: `photon-render
    /// --mode vcm`'s options and pipeline.toml's `[vcm]` section (keys without
    /// the `vcm_` of the options). The image size is `[render]`'s.
    #[derive(Copy)]
    pub struct VcmParams {
        /// Passes, each one light subpath a pixel (all traced and stored first)
        /// and one eye subpath a pixel.
        vcm_passes as "passes": u32 = 64 => between(1, 1 << 24);
        /// Most vertices of a subpath after its first, as for `bdpt`.
        vcm_max_vertices as "max_vertices": u32 = 1000 => between(1, 1 << 16);
        /// The first pass's merging radius r_0, as a fraction of the scene
        /// diagonal (SPPM's default; SmallVCM takes 0.0015 at 512 x 512). On
        /// glass_lit_room at 64 x 64 and 64 passes, 0.01 to 0.04 gave errors
        /// within 3% of each other, 0.005 3.4% more and 0.0025 16% more; a disc
        /// holds fewer light vertices the smaller the image (one light subpath a
        /// pixel).
        vcm_radius_rel_diag as "radius_rel_diag": f32 = 0.01 => above(0.0);
        /// The radius of pass i is r_0 i^((alpha - 1) / 2): the variance of the
        /// merges falls as i^-alpha, their bias as i^(alpha - 1) (Georgiev et al.
        /// 2012, section 5; SmallVCM's 0.75).
        vcm_alpha as "alpha": f32 = 0.75 => between(0.01, 1.0);
        /// Merge eye vertices with the pass's light vertices (off: bidirectional
        /// path tracing, the same image as `--mode bdpt` with the same passes).
        vcm_merge as "merge": bool = true => Any;
        /// Join eye and light subpaths by shadow rays and light tracing (off: a
        /// progressive photon mapper weighing its merges along the path; needs
        /// `merge`).
        vcm_connect as "connect": bool = true => Any;
    }
}

/// What a pass of [`Bdpt`] does: bidirectional path tracing's strategies, vertex
/// merging's, or both.
#[derive(Clone, Copy, Debug)]
struct Config {
    /// The method's name in the state file's key.
    method: &'static str,
    max_vertices: u32,
    /// Merging's first radius \[m\] and alpha, when it merges.
    merge: Option<(f32, f32)>,
    connect: bool,
}

/// The per-pass constants of the weights (Georgiev et al.'s technical report,
/// eq. 20, with n_VC = 1 join a pixel and n_VM = N light subpaths a pass):
/// on surfaces eta = pi r^2 N \[m^2\] and under the power heuristic `vm` =
/// eta^2 (zero without merging), `vc` = eta^-2 (zero without connections);
/// merging's radius r \[m\] and its normalization 1 / (pi r^2 N) \[m^-2\]. In a
/// medium the disc is a ball: eta_vol = 4/3 pi r^3 N \[m^3\] (`vm_vol` its
/// square, `normalization_vol` its inverse), against the medium vertices'
/// densities per volume ([`Vertex::measure`]).
#[derive(Clone, Copy, Debug, Default)]
struct Factors {
    vm: f32,
    vc: f32,
    radius: f32,
    normalization: f32,
    vm_vol: f32,
    normalization_vol: f32,
}

impl Factors {
    /// Mis(eta) of merging at vertex `v`: the disc's on a surface that merging
    /// can use, the ball's in a medium; zero where it does not merge (or the
    /// pass does not).
    fn merge_at(&self, v: &Vertex) -> f32 {
        match v.merge_set() {
            Some(SURFACE) => self.vm,
            Some(_) => self.vm_vol,
            None => 0.0,
        }
    }
}

/// The power heuristic's "Mis" of a density ratio: its square.
fn mis(x: f32) -> f32 {
    x * x
}

/// The recursive quantities of a subpath at a vertex (Georgiev et al.'s technical
/// report, eqs. 31-36, as SmallVCM computes them, under the power heuristic):
/// sums over the strategies that would make the subpath's part beyond the vertex
/// with fewer of its own vertices, each over this strategy's density, so that a
/// join's weight needs only the densities at its ends. `vcm` stands for the
/// strategy one vertex shorter \[m^2\], `vc` for the connections beyond it and
/// `vm` for the merges (both per reverse solid-angle density at the vertex,
/// \[m^2 sr\] under Mis), `vm` relative to a merge on a surface (eta = pi r^2 N:
/// a merge in a medium scales it by its own eta). Geometric cosines convert
/// between solid angle and area, and in a medium the mean extinction between
/// solid angle and volume ([`Vertex::measure`]); the BSDFs' densities are about
/// the shading normal; Russian roulette is left out of every density (common
/// to all strategies).
#[derive(Clone, Copy, Debug, Default)]
struct Partial {
    vcm: f32,
    vc: f32,
    vm: f32,
}

impl Partial {
    /// Leaving the pinhole along a direction of solid-angle density `pdf_lens`
    /// [sr^-1] over the whole film (one light subpath a pixel: the light tracing
    /// strategy's N samples cancel the film's N pixels).
    fn camera(pdf_lens: f32) -> Partial {
        Partial { vcm: mis(1.0 / pdf_lens), vc: 0.0, vm: 0.0 }
    }

    /// Leaving a light's point picked with area density `pdf_a` [m^-2] (the
    /// light's choice included) along a direction of density `pdf_dir` [sr^-1] at
    /// cosine `cos` to its normal (1 at a point); `delta` for a point or spot
    /// light, which no eye subpath can hit (eqs. 31-33, 48-50).
    fn light(pdf_a: f32, pdf_dir: f32, cos: f32, delta: bool, f: &Factors) -> Partial {
        let vc = if delta { 0.0 } else { mis(cos / (pdf_a * pdf_dir)) };
        Partial { vcm: mis(1.0 / pdf_dir), vc, vm: vc * f.vc }
    }

    /// Arriving at a vertex `d2` \[m^2\] from the last, whose measure along the
    /// way is `cos` (the cosine to its geometric normal; its mean extinction
    /// \[m^-1\] in a medium: [`Vertex::measure`]).
    fn arrive(&mut self, d2: f32, cos: f32) {
        let c = mis(cos);
        self.vcm = self.vcm * mis(d2) / c;
        self.vc /= c;
        self.vm /= c;
    }

    /// Arriving at a light subpath's first vertex from a light at infinity, whose
    /// measure along the way is `cos` (as in [`Partial::arrive`]): no 1 / d^2,
    /// and d_VCM takes `p_sample` [sr^-1], the density of the same direction by
    /// strategy s = 1 at this vertex (SmallVCM's directPdf of an infinite
    /// light, which here depends on the vertex: an environment of one colour is
    /// sampled over its normal's hemisphere).
    fn arrive_from_sky(&mut self, p_sample: f32, cos: f32) {
        // `arrive`'s arithmetic with p_sample in d^2's place.
        self.arrive(p_sample, cos);
    }

    /// Leaving a vertex along a direction where its measure is `cos_out` (as in
    /// [`Partial::arrive`]), sampled with solid-angle density `pdf_fwd`, whose
    /// reverse is `pdf_rev` [sr^-1]; `specular` when a delta lobe chose it (eqs.
    /// 34-36, 53-55); `merge` Mis(eta) of merging at the vertex
    /// ([`Factors::merge_at`]).
    fn leave(&mut self, cos_out: f32, pdf_fwd: f32, pdf_rev: f32, specular: bool, merge: f32, f: &Factors) {
        if specular {
            self.vcm = 0.0;
            self.vc *= mis(cos_out);
            self.vm *= mis(cos_out);
            return;
        }
        let g = mis(cos_out / pdf_fwd);
        // Relative to a surface's merge: 1 on a surface, (eta_vol / eta)^2 in a medium.
        let (vm_here, one) = if merge > 0.0 { (merge, merge / f.vm) } else { (0.0, 0.0) };
        let vc = g * (self.vc * mis(pdf_rev) + self.vcm + vm_here);
        self.vm = g * (self.vm * mis(pdf_rev) + self.vcm * f.vc + one);
        self.vc = vc;
        self.vcm = mis(1.0 / pdf_fwd);
    }

    /// The sum, over the strategies that make the path with fewer vertices on
    /// this side, of their densities over the join's, for a join whose other
    /// end makes this vertex with area density `p_from_other` [m^-2] and whose
    /// direction this vertex would sample with reverse density `pdf_rev` [sr^-1]
    /// (eqs. 40, 41, 45, 46); `merge` as in [`Partial::leave`].
    fn toward(&self, p_from_other: f32, pdf_rev: f32, merge: f32) -> f32 {
        mis(p_from_other) * (merge + self.vcm + self.vc * mis(pdf_rev))
    }
}

/// Salt of the light subpaths' streams (an eye subpath's is `pixel_salt`).
const LIGHT_SALT: u64 = 0x6c69_6768_7400;

/// Pixels a parallel work item traces (and whose splats it keeps in order).
const CHUNK: usize = 256;

/// Strategies (s, t) with s and t below this are tallied apart when asked.
pub const TALLY: usize = 12;

/// What a vertex is.
#[derive(Clone, Copy, Debug)]
enum Kind {
    /// The pinhole.
    Camera,
    /// A light subpath's start: light `light`'s point `q`.
    Light { light: u32, q: EmitterPoint },
    /// A light subpath's start at light at infinity `light`, whose light travels
    /// along -`wi` (unit; `wi` toward the sky); the vertex's position is where
    /// the ray starts, on the disc outside the scene.
    Sky { light: u32, wi: Vec3 },
    /// A surface: its BSDF, and for an eye vertex on an emitter what it emits
    /// toward `wo`, its light and the point as that light would have picked it.
    Surface { bsdf: Bsdf, le: Rgb, emitter: Option<(u32, EmitterPoint)> },
    /// A scattering event in a medium, with the medium's phase function, its
    /// mean extinction over the channels \[m^-1\] (what the densities of points
    /// in it per volume take: [`Vertex::measure`]) and its scattering
    /// coefficient [m^-1 per channel].
    Medium { phase: HenyeyGreenstein, sigma_t: f32, sigma_s: Rgb },
}

/// A vertex of a subpath, with its subpath's recursive MIS quantities there.
#[derive(Clone, Copy, Debug)]
struct Vertex {
    kind: Kind,
    /// Position \[m\].
    p: Vec3,
    /// Unit geometric normal; zero at the pinhole and at a point or spot light.
    ng: Vec3,
    /// Unit shading normal (on `ng`'s side).
    ns: Vec3,
    /// Unit direction toward the subpath's previous vertex (zero at its first).
    wo: Vec3,
    /// Throughput of the subpath up to and including the density of this vertex:
    /// radiance weight on the eye side, power on the light side.
    beta: Rgb,
    /// The subpath's MIS sums on arriving here.
    mis: Partial,
    /// Scattered by a delta lobe (mirror, glass).
    delta: bool,
    /// The medium on each side: in front of the geometric normal and behind it
    /// (both the same off a surface).
    media: [Option<MediumId>; 2],
}

impl Vertex {
    /// True at a surface or a point in a medium: where light scatters, and so
    /// where a join may end.
    fn scatters(&self) -> bool {
        matches!(self.kind, Kind::Surface { .. } | Kind::Medium { .. })
    }

    /// Which of merging's sets the vertex joins: [`SURFACE`] on a surface with a
    /// lobe that is not a Dirac delta, [`VOLUME`] at a point in a medium; none
    /// elsewhere.
    fn merge_set(&self) -> Option<usize> {
        match &self.kind {
            Kind::Surface { bsdf, .. } if !bsdf.is_specular() => Some(SURFACE),
            Kind::Medium { .. } => Some(VOLUME),
            _ => None,
        }
    }

    /// |cos| between unit `w` and the geometric normal; 1 where there is no
    /// surface (a point in a medium, a point light).
    fn cos_at(&self, w: Vec3) -> f32 {
        if self.ng == Vec3::ZERO { 1.0 } else { self.ng.dot(w).abs() }
    }

    /// What turns a solid-angle density [sr^-1] of the direction from another
    /// point toward this vertex, along unit `w`, into the density of the vertex
    /// (times 1 / d^2): on a surface |cos| to the geometric normal (a density per
    /// area \[m^-2\]); in a medium its mean extinction sigma_t \[m^-1\], the
    /// free flight's density of stopping there (a density per volume \[m^-3\],
    /// which volume merging's eta_vol needs; the transmittance before it is left
    /// out, as pbrt-v3's volumetric BDPT leaves out all of the distance
    /// sampling: the weights still add up to one for every path); 1 at a point
    /// light.
    fn measure(&self, w: Vec3) -> f32 {
        match self.kind {
            Kind::Medium { sigma_t, .. } => sigma_t,
            _ => self.cos_at(w),
        }
    }

    /// The medium a ray leaving along `w` starts in.
    fn medium_toward(&self, w: Vec3) -> Option<MediumId> {
        self.media[(w.dot(self.ng) < 0.0) as usize]
    }

    /// The density at `to` of a direction from this vertex with solid-angle
    /// density `pdf` [sr^-1]: per area on a surface, per volume in a medium
    /// ([`Vertex::measure`]).
    fn area_density(&self, pdf: f32, to: &Vertex) -> f32 {
        let v = to.p - self.p;
        let d2 = v.length_squared();
        if !(d2 > 0.0) {
            return 0.0;
        }
        let cos = match to.kind {
            Kind::Medium { sigma_t, .. } => sigma_t,
            _ if to.ng == Vec3::ZERO => 1.0,
            _ => to.ng.dot(v).abs() / d2.sqrt(),
        };
        pdf * cos / d2
    }

    /// The density [sr^-1] of sampling `wi` given `wo`: the BSDF's at a surface,
    /// the phase function's in a medium.
    fn pdf_dir(&self, wo: Vec3, wi: Vec3) -> f32 {
        match &self.kind {
            Kind::Surface { bsdf, .. } => bsdf.pdf(wo, wi, self.ns),
            Kind::Medium { phase, .. } => phase.p(wo, wi),
            _ => 0.0,
        }
    }

    /// f_s(toward_eye, toward_light) |toward_light . n_s| / |toward_light . n_g|
    /// [sr^-1]: the BSDF with the shading normal's cosine over the geometric one
    /// (Veach 1997, section 5.3), zero where the two directions are on opposite
    /// sides of the geometric surface (every non-delta lobe reflects); the phase
    /// function in a medium.
    fn f(&self, toward_eye: Vec3, toward_light: Vec3) -> Rgb {
        let bsdf = match &self.kind {
            Kind::Surface { bsdf, .. } => bsdf,
            Kind::Medium { phase, .. } => return Rgb::splat(phase.p(toward_eye, toward_light)),
            _ => return Rgb::ZERO,
        };
        let (ce, cl) = (toward_eye.dot(self.ng), toward_light.dot(self.ng));
        if ce * cl <= 0.0 {
            return Rgb::ZERO;
        }
        bsdf.f(toward_eye, toward_light, self.ns) * (toward_light.dot(self.ns).abs() / cl.abs())
    }
}

/// The pinhole as a sensor: its position, directions and film area.
struct Lens {
    camera: Camera,
    rays: CameraRays,
    aspect: f32,
    /// Area of the film at unit distance in front of the pinhole \[m^2\].
    area: f32,
}

impl Lens {
    fn new(camera: &Camera, width: u32, height: u32) -> Lens {
        let aspect = width as f32 / height as f32;
        let tan_y = (0.5 * camera.yfov).tan();
        Lens { camera: camera.clone(), rays: camera.rays(aspect), aspect, area: 4.0 * tan_y * tan_y * aspect }
    }

    /// Solid-angle density [sr^-1] of an eye ray along unit `w` (a film point
    /// uniform over the whole film): 1 / (A cos^3 theta).
    fn pdf_dir(&self, w: Vec3) -> f32 {
        let c = w.dot(self.camera.forward);
        if c > 0.0 { 1.0 / (self.area * c * c * c) } else { 0.0 }
    }
}

/// Where a random walk goes on from: the ray (origin \[m\], unit direction), the
/// throughput so far and the medium the ray starts in.
struct Leaving {
    o: Vec3,
    d: Vec3,
    beta: Rgb,
    medium: Option<MediumId>,
    /// The subpath's MIS sums on leaving its last vertex.
    mis: Partial,
}

/// How a random walk ended: cut by the vertex limit, and (eye subpaths) what it
/// found leaving the scene, weighed [W sr^-1 m^-2].
struct Walked {
    cut: bool,
    escaped: Rgb,
}

/// One splatted light-tracing contribution: the pixel, the layer, the value.
type Splat = (u32, u8, Rgb);

/// What a chunk of a pass's pixels tallies: its subpaths cut by the vertex
/// limit and, when asked (see [`Bdpt::tally_strategies`]), each strategy's
/// unweighted and weighted contributions.
#[derive(Default)]
struct Tallies {
    cut: u64,
    strategies: Vec<[f64; 2]>,
}

impl Tallies {
    /// Zero, with room for the strategies when `tallying`.
    fn reset(&mut self, tallying: bool) {
        self.cut = 0;
        self.strategies.clear();
        if tallying {
            self.strategies.resize(TALLY * TALLY, [0.0; 2]);
        }
    }

    /// Strategy (s, t)'s contribution `c` and weight `w`, when tallying.
    fn add(&mut self, s: usize, t: usize, c: Rgb, w: f32) {
        if s < TALLY
            && t < TALLY
            && let Some(v) = self.strategies.get_mut(s * TALLY + t)
        {
            let l = c.element_sum() as f64 / 3.0;
            v[0] += l;
            v[1] += l * w as f64;
        }
    }
}

/// What a chunk of a pass's pixels' light subpaths made in its first phase.
#[derive(Default)]
struct LightChunk {
    /// The light subpaths' vertices, path after path.
    vertices: Vec<Vertex>,
    /// Where each pixel's light subpath ends in `vertices`.
    ends: Vec<u32>,
    /// The light vertices merging can use, on surfaces and in media, in the
    /// order of `vertices` (when the pass merges).
    photons: [Vec<Photon>; 2],
    /// Light tracing's splats, in the order they were made.
    splats: Vec<Splat>,
    tallies: Tallies,
}

impl LightChunk {
    /// Empty, its buffers kept for reuse.
    fn reset(&mut self, tallying: bool) {
        self.vertices.clear();
        self.ends.clear();
        self.photons.iter_mut().for_each(Vec::clear);
        self.splats.clear();
        self.tallies.reset(tallying);
    }

    /// Its pixel `j`'s light subpath.
    fn path(&self, j: usize) -> &[Vertex] {
        let start = if j == 0 { 0 } else { self.ends[j - 1] as usize };
        &self.vertices[start..self.ends[j] as usize]
    }
}

/// What a chunk of a pass's pixels' eye subpaths made in its second phase.
#[derive(Default)]
struct EyeChunk {
    /// Its first pixel.
    start: usize,
    /// What landed on each of its pixels, by layer.
    pixels: Vec<[Rgb; LAYERS]>,
    tallies: Tallies,
}

/// The pass's light vertices that merging can use, on surfaces and in media
/// (index [`SURFACE`], [`VOLUME`]): grids over their positions and each as
/// merging reads it.
struct Merging {
    grids: [RadiusGrid; 2],
    photons: [Vec<Photon>; 2],
}

/// [`Merging`]'s and [`LightChunk::photons`]' index of surfaces' light vertices.
const SURFACE: usize = 0;
/// Their index of media's.
const VOLUME: usize = 1;

/// A light vertex as merging reads it, in one cache line (a pass's queries
/// visit tens of them each; the whole vertex is 272 bytes).
#[derive(Clone, Copy, Debug)]
struct Photon {
    /// Position \[m\].
    p: Vec3,
    /// Unit geometric normal on the side the light arrived from (zero in a
    /// medium).
    n: Vec3,
    /// Unit direction toward the light subpath's previous vertex.
    wo: Vec3,
    /// The light subpath's power up to here [W]; in a medium over the medium's
    /// scattering coefficient [W m per channel] (the free flight that stopped
    /// there took it in, and the merged path has it once, in the eye
    /// subpath's).
    beta: Rgb,
    /// The light subpath's MIS sums d_VCM and d_VM here.
    vcm: f32,
    vm: f32,
    /// Its index k in the light subpath (y_k; the light's point is y_0).
    k: u16,
    /// Every vertex between the light's point and it is a delta one.
    caustic: bool,
    /// It lies under a cover (`pm_render::covered`: another surface faces it
    /// from within 1% of the diagonal, as the ceiling above a lamp's panel).
    covered: bool,
}

impl Photon {
    /// Light subpath `path`'s vertex y_k of `scene` as a photon.
    fn of(scene: &Scene, path: &[Vertex], k: usize) -> Photon {
        let y = &path[k];
        let (n, covered, beta) = match y.kind {
            Kind::Medium { sigma_s, .. } => {
                let over = |b: f32, s: f32| if s > 0.0 { b / s } else { 0.0 };
                let beta = Rgb::new(over(y.beta.x, sigma_s.x), over(y.beta.y, sigma_s.y), over(y.beta.z, sigma_s.z));
                (Vec3::ZERO, false, beta)
            }
            _ => {
                let n = pm_scene::facing(y.ng, y.wo);
                (n, pm_render::covered(scene, y.p, n), y.beta)
            }
        };
        Photon {
            p: y.p,
            n,
            covered,
            wo: y.wo,
            beta,
            vcm: y.mis.vcm,
            vm: y.mis.vm,
            k: k.min(u16::MAX as usize) as u16,
            caustic: path[1..k].iter().all(|v| v.delta),
        }
    }
}

/// A bidirectional path tracer's (or vertex connection and merging's) state:
/// its passes and the image so far.
pub struct Bdpt<'a> {
    scene: &'a Scene,
    /// The choice among the lights, by power: where light subpaths start, and
    /// which light an eye vertex samples (s = 1).
    lights: LightSelector,
    /// The lights at infinity (an environment, suns), which rays leaving the
    /// scene may find.
    sky: Vec<usize>,
    lens: Lens,
    /// The medium the pinhole is in.
    eye_medium: Option<MediumId>,
    width: u32,
    height: u32,
    seed: u64,
    config: Config,
    /// The last pass's light subpaths, chunk by chunk (sized by the pass, reused
    /// by the next), and the buffers of its eye subpaths' chunks.
    light_chunks: Vec<LightChunk>,
    eye_chunks: Vec<EyeChunk>,
    /// The passes' sums.
    sums: pm_render::PassSums,
    /// Subpaths cut by the vertex limit.
    cut: u64,
    /// Per strategy (s, t), s and t below [`TALLY`], the sums over every sample
    /// of its contribution's mean over the channels, unweighted and weighted;
    /// empty unless asked for ([`Bdpt::tally_strategies`]).
    tally: Vec<[f64; 2]>,
}

impl<'a> Bdpt<'a> {
    /// A bidirectional path tracer of `scene` seen by `camera` on a film of
    /// `width` x `height` pixels; refused (with the reason) for a scene without
    /// lights.
    pub fn new(
        scene: &'a Scene,
        camera: &Camera,
        width: u32,
        height: u32,
        seed: u64,
        params: BdptParams,
    ) -> Result<Bdpt<'a>, String> {
        let config = Config { method: "bdpt", max_vertices: params.bdpt_max_vertices, merge: None, connect: true };
        Bdpt::with(scene, camera, width, height, seed, config)
    }

    /// Vertex connection and merging of `scene` seen by `camera` on a film of
    /// `width` x `height` pixels; refused (with the reason) for a scene without
    /// lights or with both merging and connections off.
    pub fn vcm(
        scene: &'a Scene,
        camera: &Camera,
        width: u32,
        height: u32,
        seed: u64,
        params: VcmParams,
    ) -> Result<Bdpt<'a>, String> {
        if !params.vcm_merge && !params.vcm_connect {
            return Err("vcm with neither merging nor connections has no strategies".into());
        }
        let r0 = params.vcm_radius_rel_diag * scene.bounds.diagonal();
        let config = Config {
            method: "vcm",
            max_vertices: params.vcm_max_vertices,
            merge: params.vcm_merge.then_some((r0, params.vcm_alpha)),
            connect: params.vcm_connect,
        };
        Bdpt::with(scene, camera, width, height, seed, config)
    }

    fn with(
        scene: &'a Scene,
        camera: &Camera,
        width: u32,
        height: u32,
        seed: u64,
        config: Config,
    ) -> Result<Bdpt<'a>, String> {
        let all = LightSelector::new(scene, &[]).map_err(|e| e.to_string())?;
        Ok(Bdpt {
            scene,
            lights: all,
            sky: (0..scene.lights.len()).filter(|&i| at_infinity(&scene.lights[i])).collect(),
            lens: Lens::new(camera, width, height),
            eye_medium: scene.eye_medium(camera.position),
            width,
            height,
            seed,
            config,
            light_chunks: Vec::new(),
            eye_chunks: Vec::new(),
            sums: pm_render::PassSums::new(width, height),
            cut: 0,
            tally: Vec::new(),
        })
    }

    /// Passes done.
    pub fn passes(&self) -> u32 {
        self.sums.passes()
    }

    /// The passes' sums.
    pub fn sums(&self) -> &pm_render::PassSums {
        &self.sums
    }

    /// The scene it renders.
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    /// The settings that shape the state, as "name=value" words (the state file's
    /// key: a state made with other settings is refused).
    pub fn key(&self) -> String {
        let c = &self.config;
        let mut key = format!(
            "method={} width={} height={} seed={} {}_max_vertices={}",
            c.method, self.width, self.height, self.seed, c.method, c.max_vertices
        );
        if c.method == "vcm" {
            let (r0, alpha) = c.merge.unwrap_or((0.0, 0.0));
            key += &format!(" vcm_merge={} vcm_connect={} vcm_r0={r0} vcm_alpha={alpha}", c.merge.is_some(), c.connect);
        }
        key
    }

    /// The state as its file holds it.
    pub fn to_file(&self) -> pm_format::PassStateFile {
        self.sums.to_file(self.scene.content_hash, self.key())
    }

    /// Continue from a state file's passes: refused when it was made from another
    /// scene, for another image size or with other settings (naming the first
    /// that differs), or holds more passes than `most`.
    pub fn resume(&mut self, file: &pm_format::PassStateFile, most: u32) -> Result<(), String> {
        self.sums.resume(file, self.scene.content_hash, &self.key(), most)
    }

    /// Keep, from the next pass on, every strategy's contributions apart (see
    /// [`Bdpt::strategies`]): for checking that each strategy alone is unbiased.
    pub fn tally_strategies(&mut self) {
        self.tally = vec![[0.0; 2]; TALLY * TALLY];
    }

    /// For each strategy (s, t) with s and t below [`TALLY`] that contributed:
    /// its own estimate of the image's mean radiance over the paths of s + t - 1
    /// segments (unweighted: as if it were the only strategy) and its share of
    /// the image (MIS-weighted) [W sr^-1 m^-2, mean over pixels and channels].
    pub fn strategies(&self) -> Vec<((usize, usize), f64, f64)> {
        let per = self.passes().max(1) as f64 * self.width as f64 * self.height as f64;
        (0..TALLY * TALLY)
            .filter(|&i| self.tally.get(i).is_some_and(|v| v[0] != 0.0))
            .map(|i| ((i / TALLY, i % TALLY), self.tally[i][0] / per, self.tally[i][1] / per))
            .collect()
    }

    /// Subpaths cut by the vertex limit so far.
    pub fn cut_paths(&self) -> u64 {
        self.cut
    }

    /// The weights' constants of pass `k` (from 0) and its merging radius.
    fn factors(&self, k: u32) -> Factors {
        let Some((r0, alpha)) = self.config.merge else {
            return Factors::default();
        };
        let radius = (r0 * ((k + 1) as f32).powf(0.5 * (alpha - 1.0))).max(1e-7);
        let n = self.width as f32 * self.height as f32;
        let eta = std::f32::consts::PI * radius * radius * n;
        let eta_vol = 4.0 / 3.0 * eta * radius;
        Factors {
            vm: mis(eta),
            vc: if self.config.connect { mis(1.0 / eta) } else { 0.0 },
            radius,
            normalization: 1.0 / eta,
            vm_vol: mis(eta_vol),
            normalization_vol: 1.0 / eta_vol,
        }
    }

    /// One pass: a light subpath per pixel, traced and stored first (light tracing
    /// splatted as they go), then an eye subpath per pixel joined to its pixel's
    /// light subpath in every way and merged with every light subpath's vertices
    /// nearby.
    pub fn pass(&mut self) {
        let n = self.width as usize * self.height as usize;
        let k = self.passes();
        let f = self.factors(k);
        let tallying = !self.tally.is_empty();
        let chunks = n.div_ceil(CHUNK);
        let (mut lights, mut eyes) = (std::mem::take(&mut self.light_chunks), std::mem::take(&mut self.eye_chunks));
        lights.resize_with(chunks, LightChunk::default);
        eyes.resize_with(chunks, EyeChunk::default);
        lights.par_iter_mut().enumerate().for_each(|(c, out)| {
            out.reset(tallying);
            let mut path = Vec::new();
            for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
                let mut sl = Sampler::salted(self.seed, LIGHT_SALT ^ i as u64, k as u64);
                out.tallies.cut += self.light_subpath(&mut sl, &f, &mut path) as u64;
                if self.config.connect {
                    self.light_trace(&path, &f, out);
                }
                if self.config.merge.is_some() {
                    // Not the light's own point: merging needs a segment of light path.
                    for k in 1..path.len() {
                        if let Some(at) = path[k].merge_set() {
                            out.photons[at].push(Photon::of(self.scene, &path, k));
                        }
                    }
                }
                out.vertices.extend_from_slice(&path);
                out.ends.push(out.vertices.len() as u32);
            }
        });
        let merging = self.config.merge.is_some().then(|| {
            let photons =
                [SURFACE, VOLUME].map(|at| lights.iter().flat_map(|c| &c.photons[at]).copied().collect::<Vec<_>>());
            let grids = [SURFACE, VOLUME].map(|at| {
                let points: Vec<Vec3> = photons[at].iter().map(|ph| ph.p).collect();
                // Cells a radius wide, but no more than 2 a point: built every
                // pass, the grid must cost its points, not empty space (at 64 x
                // 64 in a box, cells a radius wide made two million a pass; 4
                // and 16 a point were 5-10% slower on cornell_boxes at 96 x 96
                // than 2).
                let most = (2 * points.len()).clamp(1 << 12, 1 << 22);
                RadiusGrid::with_cells_at_most(&points, f.radius, most)
            });
            Merging { grids, photons }
        });
        eyes.par_iter_mut().enumerate().for_each(|(c, out)| {
            out.start = c * CHUNK;
            out.tallies.reset(tallying);
            let end = ((c + 1) * CHUNK).min(n);
            out.pixels.clear();
            out.pixels.resize(end - out.start, [Rgb::ZERO; LAYERS]);
            let mut eye = Vec::new();
            for i in out.start..end {
                self.sample(i, k, &f, &lights, merging.as_ref(), &mut eye, out);
            }
        });
        let mut pass = Vec::with_capacity(n);
        for c in &eyes {
            pass.extend_from_slice(&c.pixels);
        }
        for t in lights.iter().map(|c| &c.tallies).chain(eyes.iter().map(|c| &c.tallies)) {
            self.cut += t.cut;
            for (a, b) in self.tally.iter_mut().zip(&t.strategies) {
                a[0] += b[0];
                a[1] += b[1];
            }
        }
        for c in &lights {
            for &(px, layer, v) in &c.splats {
                pass[px as usize][layer as usize] += v;
            }
        }
        self.sums.add(&pass);
        (self.light_chunks, self.eye_chunks) = (lights, eyes);
    }

    /// The bytes the last pass's light subpaths held per pixel (their vertices
    /// and path ends; merging's grid, built over them for the pass, adds 20
    /// bytes a merging vertex and its cells).
    pub fn store_bytes_per_pixel(&self) -> f64 {
        let bytes: usize =
            self.light_chunks.iter().map(|c| c.vertices.len() * std::mem::size_of::<Vertex>() + c.ends.len() * 4).sum();
        bytes as f64 / (self.width as f64 * self.height as f64)
    }

    /// Light tracing (t = 1) from every vertex of light subpath `light` after its
    /// first, splatted into `out` (and tallied).
    fn light_trace(&self, light: &[Vertex], f: &Factors, out: &mut LightChunk) {
        for s in 2..=light.len() {
            if let Some((px, c, w)) = self.splat(&light[..s], f) {
                out.splats.push((px, layer_of(&[self.camera_vertex()], light, s, 1) as u8, c * w));
                out.tallies.add(s, 1, c, w);
            }
        }
    }

    /// Each pixel's variance of its mean over the passes so far [(W sr^-1 m^-2)^2],
    /// from the passes' spread; none before two passes.
    pub fn variances(&self) -> Option<Vec<f32>> {
        self.sums.variances()
    }

    /// The image after the passes done, by layer.
    pub fn image(&self) -> Image {
        self.region_image(pm_raster::Rect::full(self.width, self.height))
    }

    /// The image of `rect` after the passes done (only a scene with a scattering
    /// medium has a volume layer).
    pub fn region_image(&self, rect: pm_raster::Rect) -> Image {
        self.sums.region_image(rect, self.scene.has_scattering_media())
    }

    /// Pixel `i`'s sample of pass `k` into `out`: its eye subpath (kept in `eye`
    /// between samples) joined in every way to the pixel's light subpath and
    /// merged with the light vertices near its vertices (`merging`).
    #[allow(clippy::too_many_arguments)]
    fn sample(
        &self,
        i: usize,
        k: u32,
        f: &Factors,
        lights: &[LightChunk],
        merging: Option<&Merging>,
        eye: &mut Vec<Vertex>,
        out: &mut EyeChunk,
    ) {
        let light = lights[i / CHUNK].path(i % CHUNK);
        let (w, h) = (self.width as usize, self.height as usize);
        let px = i - out.start;
        let mut se = Sampler::salted(self.seed, pixel_salt(i), k as u64);
        let j = se.next_2d();
        let d = self.lens.rays.direction(((i % w) as f32 + j.x) / w as f32, ((i / w) as f32 + j.y) / h as f32);
        let walked = self.eye_subpath(d, &mut se, f, eye);
        out.tallies.cut += walked.cut as u64;
        if walked.escaped.max_element() > 0.0 {
            out.pixels[px][layer_of(eye, &[], 0, eye.len() + 1)] += walked.escaped;
        }
        let connect = self.config.connect;
        for t in 2..=eye.len() {
            // s = 0; without connections only where no merge could make the path
            // (an emitter seen directly or through delta lobes alone).
            if (connect || eye[1..t - 1].iter().all(|v| v.delta))
                && let Some((c, w)) = self.emitted(f, &eye[..t])
            {
                out.pixels[px][layer_of(eye, &[], 0, t)] += c * w;
                out.tallies.add(0, t, c, w);
            }
            if connect {
                // s = 1 picks its own light point (with the eye stream's next
                // numbers), so it is tried even when the light subpath did not start.
                for s in 1..=light.len().max(1) {
                    let u = if s == 1 { Some((se.next_1d(), se.next_1d(), se.next_2d())) } else { None };
                    if let Some((c, w, sky)) = self.connect(f, &eye[..t], &light[..s.min(light.len())], s, u) {
                        // A light at infinity counts as a vertex past z_{t-1}.
                        let layer = if sky { layer_of(eye, &[], 0, t + 1) } else { layer_of(eye, light, s, t) };
                        out.pixels[px][layer] += c * w;
                        out.tallies.add(s, t, c, w);
                    }
                }
            }
            if let Some(m) = merging {
                self.merge(f, m, &eye[..t], &mut out.pixels[px]);
            }
        }
    }

    /// Vertex merging at the eye subpath's last vertex z = `eye[t - 1]`: on a
    /// surface, the light vertices of the pass within the radius on the same
    /// surface (stored normals within [`pm_estimate::SAME_SURFACE_COS`], each
    /// seen from its own side, both under a cover or neither), each a photon of
    /// the density estimate z.beta f(z.wo, y.wo) y.beta / (pi r^2 N); in a
    /// medium, the light vertices in media within the radius, each of z.beta
    /// f_p(z.wo, y.wo) y.beta / (sigma_s 4/3 pi r^3 N) (Jensen and Christensen
    /// 1998's volume radiance estimate, the photon's sigma_s taken out as the
    /// eye's free flight has it: [`Photon::beta`]). Each is weighed against every
    /// other strategy (tech. rep. eqs. 37-39) and added to `pixel` by layer.
    fn merge(&self, f: &Factors, m: &Merging, eye: &[Vertex], pixel: &mut [Rgb; LAYERS]) {
        let t = eye.len();
        let z = &eye[t - 1];
        let Some(at) = z.merge_set() else { return };
        let volume = at == VOLUME;
        let nz = if volume { Vec3::ZERO } else { pm_scene::facing(z.ng, z.wo) };
        // SPPM's rule: light in a gap (between a lamp's panel and the ceiling)
        // is not merged with points outside it, nor the other way round (at
        // 48 x 48, two-sided lamps a few millimetres under the ceiling leaked
        // 4-7% into the indirect layer of 5 of 40 generated rooms). The probe
        // is cast at the first photon that passes the normal's test.
        let mut covered = None;
        let mut sum = [Rgb::ZERO; LAYERS];
        m.grids[at].for_each_within(z.p, f.radius * f.radius, |gi, _| {
            let y = &m.photons[at][gi as usize];
            if !volume
                && (y.n.dot(nz) <= pm_estimate::SAME_SURFACE_COS
                    || y.covered != *covered.get_or_insert_with(|| pm_render::covered(self.scene, z.p, nz)))
            {
                return;
            }
            let c = z.f(z.wo, y.wo) * y.beta;
            if c.max_element() <= 0.0 || !c.is_finite() {
                return;
            }
            // The path x_0 .. x_{t-1} = y_k, y_{k-1} .. y_0: t - 1 + k segments.
            let caustic = y.caustic && eye[2.min(t)..t].iter().all(|v| v.delta);
            sum[layer(t - 1 + y.k as usize, &eye[1], caustic)] += c * self.merge_weight(f, z, y);
        });
        let normalization = if volume { f.normalization_vol } else { f.normalization };
        for (p, v) in pixel.iter_mut().zip(sum) {
            if v.max_element() > 0.0 {
                *p += z.beta * v * normalization;
            }
        }
    }

    /// The MIS weight of merging eye vertex `z` with light vertex `y` (tech. rep.
    /// eqs. 37-39; both densities at z's BSDF or phase function: the two points
    /// are taken as one). The stored sums are relative to a surface's merge: in
    /// a medium, to the ball's, they scale by (eta / eta_vol)^2.
    fn merge_weight(&self, f: &Factors, z: &Vertex, y: &Photon) -> f32 {
        let scale = if z.merge_set() == Some(VOLUME) { f.vm / f.vm_vol } else { 1.0 };
        let w_light = (y.vcm * f.vc + y.vm * mis(z.pdf_dir(z.wo, y.wo))) * scale;
        let w_eye = (z.mis.vcm * f.vc + z.mis.vm * mis(z.pdf_dir(y.wo, z.wo))) * scale;
        finite_or_zero(1.0 / (w_light + 1.0 + w_eye))
    }

    /// The eye subpath through unit direction `d` from the pinhole into `path`
    /// (the pinhole first): whether the vertex limit cut it, and what it found
    /// leaving the scene.
    fn eye_subpath(&self, d: Vec3, s: &mut Sampler, f: &Factors, path: &mut Vec<Vertex>) -> Walked {
        path.clear();
        path.push(self.camera_vertex());
        let pdf = self.lens.pdf_dir(d);
        let from = Leaving {
            o: self.lens.camera.position,
            d,
            beta: Rgb::ONE,
            medium: self.eye_medium,
            mis: Partial::camera(pdf),
        };
        self.walk(from, true, s, f, path)
    }

    /// The light subpath into `path` (the light's point first): a light chosen by
    /// power, a point on it and a direction from it as the photon tracer draws
    /// them. True when the vertex limit cut it.
    fn light_subpath(&self, s: &mut Sampler, f: &Factors, path: &mut Vec<Vertex>) -> bool {
        path.clear();
        let (u_light, u_sel, u_pos) = (s.next_1d(), s.next_1d(), s.next_2d());
        let (u_side, u_dir) = (s.next_1d(), s.next_2d());
        let (li, prob) = self.lights.pick(u_light);
        if at_infinity(&self.scene.lights[li]) {
            return self.sky_subpath(li, prob as f32, u_pos, u_dir, s, f, path);
        }
        let Some(y0) = self.light_point(li, u_sel, u_pos) else { return false };
        let Kind::Light { light: li, q } = y0.kind else { return false };
        let light = &self.scene.lights[li as usize];
        path.push(y0);
        let Some((dir, pdf_dir)) = light.sample_emitted_dir(&q, u_side, u_dir) else { return false };
        let cos = if q.n == Vec3::ZERO { 1.0 } else { q.n.dot(dir).abs() };
        let beta = y0.beta * light.emitted_toward(&q, dir) * (cos / pdf_dir);
        if beta.max_element() <= 0.0 || !beta.is_finite() {
            return false;
        }
        let o = if q.n == Vec3::ZERO { q.p } else { self.scene.offset_origin(q.p, q.n, dir) };
        let pdf_a = self.light_pdf(li as usize, &q);
        let mis = Partial::light(pdf_a, pdf_dir, cos, light.is_delta(), f);
        self.walk(Leaving { o, d: dir, beta, medium: y0.media[0], mis }, false, s, f, path).cut
    }

    /// A light subpath from light at infinity `li` (chosen with probability
    /// `prob`) into `path`: a direction by its emission (`u_dir`), a point on the
    /// disc across it (`u_pos`), carrying L / (prob pdf_dir pdf_pos) [W]. Its MIS
    /// sums start as SmallVCM's for an infinite light (cosine 1; d_VCM's density
    /// of the direction by s = 1 is taken at the first vertex, which it depends
    /// on: [`Partial::arrive_from_sky`]). True when the vertex limit cut it.
    #[allow(clippy::too_many_arguments)]
    fn sky_subpath(
        &self,
        li: usize,
        prob: f32,
        u_pos: glam::Vec2,
        u_dir: glam::Vec2,
        s: &mut Sampler,
        f: &Factors,
        path: &mut Vec<Vertex>,
    ) -> bool {
        let light = &self.scene.lights[li];
        let Some(sd) = light.sample_sky_dir(u_dir) else { return false };
        let Some(o) = light.sky_origin(-sd.wi, u_pos) else { return false };
        let emission = prob * sd.pdf * light.pdf_sky_origin();
        let beta = sd.l / emission;
        if !(emission > 0.0) || beta.max_element() <= 0.0 || !beta.is_finite() {
            return false;
        }
        let y0 = Vertex {
            kind: Kind::Sky { light: li as u32, wi: sd.wi },
            p: o,
            ng: Vec3::ZERO,
            ns: Vec3::ZERO,
            wo: Vec3::ZERO,
            beta: Rgb::splat(1.0 / (prob * light.pdf_sky_origin())),
            mis: Partial::default(),
            delta: false,
            media: [self.scene.light_medium(li); 2],
        };
        path.clear();
        path.push(y0);
        let vc = if sd.delta { 0.0 } else { mis(1.0 / emission) };
        let mis = Partial { vcm: mis(1.0 / emission), vc, vm: vc * f.vc };
        self.walk(Leaving { o, d: -sd.wi, beta, medium: y0.media[0], mis }, false, s, f, path).cut
    }

    /// Extend a subpath from `o` along unit `d` (starting in medium `medium`) with
    /// throughput `beta`, by BSDF and phase-function sampling, free flights in
    /// media (the path tracer's: distances by a hero channel chosen once a
    /// subpath, weighed by the balance heuristic over channels, `Flights`),
    /// index-matched boundaries passed without a vertex, and Russian roulette:
    /// radiance on the eye side (`eye`), power on the light side. True when the
    /// vertex limit cut it, and for an eye subpath what it found leaving the
    /// scene ([`Self::escaped`]).
    fn walk(&self, from: Leaving, eye: bool, s: &mut Sampler, f: &Factors, path: &mut Vec<Vertex>) -> Walked {
        let scene = self.scene;
        let Leaving { o, d, beta, medium, mut mis } = from;
        let (mut o, mut d, mut beta, mut medium) = (o, d, beta, medium);
        let ended = |cut: bool| Walked { cut, escaped: Rgb::ZERO };
        let start = beta.max_element();
        let mut eta_scale = 1.0f32;
        let mut flights = Flights::new(if scene.has_media() { s.next_1d() } else { 0.0 });
        let limit = self.config.max_vertices as usize + 1;
        loop {
            if path.len() >= limit {
                return ended(true);
            }
            let hit = scene.intersect(o, d, f32::INFINITY);
            let prev = *path.last().expect("a subpath starts with its first vertex");
            let mut scattered = None;
            if let Some(m) = scene.medium(medium).filter(|m| !m.is_clear()) {
                let t_seg = scene.segment_length(o, d, hit.as_ref());
                let u = if m.scatters() { s.next_1d() } else { 0.0 };
                match flights.fly(m, t_seg, u) {
                    FreeFlight::Through { weight, .. } => beta *= weight,
                    FreeFlight::Scatter { t, weight, .. } => {
                        beta *= weight;
                        let kind = Kind::Medium {
                            phase: m.phase,
                            sigma_t: m.sigma_t().element_sum() / 3.0,
                            sigma_s: m.sigma_s,
                        };
                        scattered = Some((o + d * t, kind));
                    }
                }
            }
            let wo = -d;
            if let Some((p, kind)) = scattered {
                let Kind::Medium { phase, .. } = kind else { unreachable!("a medium's event") };
                let mut v = Vertex {
                    kind,
                    p,
                    ng: Vec3::ZERO,
                    ns: Vec3::ZERO,
                    wo,
                    beta: beta * flights.weight(),
                    mis,
                    delta: false,
                    media: [medium; 2],
                };
                self.arrive(&mut v, &prev);
                mis = v.mis;
                let at = path.len();
                path.push(v);
                let ps = phase.sample(wo, s.next_2d());
                // Henyey-Greenstein depends on the angle alone: the reverse
                // density is the forward one.
                mis.leave(v.measure(ps.wi), ps.pdf, ps.pdf, false, f.merge_at(&v), f);
                // The path tracer's roulette on the throughput relative to the
                // subpath's start, eta^2 folded in on the eye side.
                if !pm_render::roulette(&mut beta, flights.weight() * eta_scale / start, at as u32, s) {
                    return ended(false);
                }
                (o, d) = (p, ps.wi);
                continue;
            }
            let Some(hit) = hit else {
                let escaped = if eye { self.escaped(&prev, &mis, path, d, beta * flights.weight()) } else { Rgb::ZERO };
                return Walked { cut: false, escaped };
            };
            if let Some(tint) = scene.index_matched(&hit) {
                // Straight through into the medium beyond: no vertex.
                beta *= tint;
                medium = scene.medium_after(&hit, d, medium);
                o = scene.offset_origin(hit.p, hit.ng, d);
                continue;
            }
            let bsdf = scene.bsdf(&hit);
            let le = if eye { scene.emitted(&hit, wo) } else { Rgb::ZERO };
            let emitter = if le.max_element() > 0.0 {
                let li = scene.light_of_triangle[hit.tri as usize];
                scene.lights.get(li as usize).and_then(|l| l.emitter_point_at(scene, hit.tri, hit.b)).map(|q| (li, q))
            } else {
                None
            };
            let media = if scene.has_media() {
                [scene.medium_after(&hit, hit.ng, medium), scene.medium_after(&hit, -hit.ng, medium)]
            } else {
                [medium; 2]
            };
            let mut v = Vertex {
                kind: Kind::Surface { bsdf, le, emitter },
                p: hit.p,
                ng: hit.ng,
                ns: hit.ns,
                wo,
                beta: beta * flights.weight(),
                mis,
                delta: false,
                media,
            };
            self.arrive(&mut v, &prev);
            mis = v.mis;
            let at = path.len();
            path.push(v);
            let (u, uc) = (s.next_2d(), s.next_1d());
            let Some(bs) = bsdf.sample(wo, hit.ns, u, uc) else { return ended(false) };
            if pm_scene::same_side(hit.ng, bs.wi, wo) == bs.transmitted {
                return ended(false);
            }
            let weight = if eye {
                eta_scale *= bs.eta * bs.eta;
                bs.radiance_weight()
            } else {
                // Veach's adjoint BSDF with shading normals (1997, eq. 5.17).
                let num = wo.dot(hit.ns).abs() * bs.wi.dot(hit.ng).abs();
                let den = wo.dot(hit.ng).abs() * bs.wi.dot(hit.ns).abs();
                if !(den > 0.0) {
                    return ended(false);
                }
                bs.weight * (num / den)
            };
            beta *= weight;
            let rev = if bs.specular { 0.0 } else { bsdf.pdf(bs.wi, wo, hit.ns) };
            path[at].delta = bs.specular;
            mis.leave(hit.ng.dot(bs.wi).abs(), bs.pdf, rev, bs.specular, f.merge_at(&v), f);
            if !pm_render::roulette(&mut beta, flights.weight() * eta_scale / start, at as u32, s) {
                return ended(false);
            }
            medium = v.medium_toward(bs.wi);
            o = scene.offset_origin(hit.p, hit.ng, bs.wi);
            d = bs.wi;
        }
    }

    /// The MIS sums of vertex `v`, reached from its subpath's last vertex `prev`
    /// (its `wo` set), on arriving there.
    fn arrive(&self, v: &mut Vertex, prev: &Vertex) {
        let cos = v.measure(v.wo);
        if let Kind::Sky { light, wi } = prev.kind {
            v.mis.arrive_from_sky(self.p_sample_sky(light as usize, v, wi), cos);
        } else {
            v.mis.arrive(v.p.distance_squared(prev.p), cos);
        }
    }

    /// What an eye subpath finds leaving the scene along unit `d` from its last
    /// vertex `prev` with throughput `beta` (`after`: its MIS sums on leaving
    /// `prev`; `path` the subpath): each light at infinity's radiance [W sr^-1
    /// m^-2] weighed by [`Self::escape_weight`].
    fn escaped(&self, prev: &Vertex, after: &Partial, path: &[Vertex], d: Vec3, beta: Rgb) -> Rgb {
        let mut sum = Rgb::ZERO;
        for &li in &self.sky {
            let le = self.scene.lights[li].radiance_escaped(d);
            if le.max_element() > 0.0 {
                sum += le * self.escape_weight(prev, after, path, li, d);
            }
        }
        beta * sum
    }

    /// The weight of strategy s = 0 for light at infinity `li`: the eye subpath
    /// `path` leaves the scene from `prev` along `d` (`after`: its sums on
    /// leaving). Against the same direction sampled at `prev` (s = 1) and the
    /// light subpaths from the sky (SmallVCM's background weight); the sky seen
    /// directly has this strategy alone, and without connections so has a sky
    /// seen through delta lobes only (merges make the rest).
    fn escape_weight(&self, prev: &Vertex, after: &Partial, path: &[Vertex], li: usize, d: Vec3) -> f32 {
        if matches!(prev.kind, Kind::Camera) {
            return 1.0;
        }
        if !self.config.connect {
            return if path[1..].iter().all(|v| v.delta) { 1.0 } else { 0.0 };
        }
        let w = mis(self.p_sample_sky(li, prev, d)) * after.vcm + mis(self.p_emit_sky(li, d)) * after.vc;
        finite_or_zero(1.0 / (1.0 + w))
    }

    /// The unit normal a vertex samples lights at infinity about: the geometric
    /// normal on the side `wo` is on; zero in a medium.
    fn sky_normal(v: &Vertex) -> Vec3 {
        if v.ng == Vec3::ZERO { Vec3::ZERO } else { pm_scene::facing(v.ng, v.wo) }
    }

    /// The density [sr^-1] with which strategy s = 1 at vertex `v` picks light at
    /// infinity `li` and unit direction `wi` toward it (the light's choice times
    /// `Light::sample_li`'s density; a parallel sun's direction counts 1).
    fn p_sample_sky(&self, li: usize, v: &Vertex, wi: Vec3) -> f32 {
        let light = &self.scene.lights[li];
        let pdf = if light.is_delta() { 1.0 } else { light.pdf_escaped(v.p, Self::sky_normal(v), wi) };
        self.lights.probs[li] as f32 * pdf
    }

    /// The density with which a light subpath starts at light at infinity `li`
    /// along unit -`wi`: its choice, the direction's density [sr^-1] (1 for a
    /// parallel sun) and the disc point's [m^-2].
    fn p_emit_sky(&self, li: usize, wi: Vec3) -> f32 {
        let light = &self.scene.lights[li];
        let pdf = if light.is_delta() { 1.0 } else { light.pdf_sky_dir(wi) };
        self.lights.probs[li] as f32 * pdf * light.pdf_sky_origin()
    }

    /// Strategy s = 1 for light at infinity `li` at eye vertex `z`: a direction
    /// sampled on it (`u_sel`, `u`: `Light::sample_li`), a shadow ray to the sky
    /// through the media and index-matched boundaries on the way. What it adds to
    /// the pixel [W sr^-1 m^-2] and its weight ([`Self::sky_weight`]).
    fn sky_connect(&self, f: &Factors, z: &Vertex, li: usize, u_sel: f32, u: glam::Vec2) -> Option<(Rgb, f32)> {
        let ls = self.scene.lights[li].sample_li(self.scene, z.p, Self::sky_normal(z), u_sel, u)?;
        let p = self.p_sample_sky(li, z, ls.wi);
        let c = z.beta * z.f(z.wo, ls.wi) * z.cos_at(ls.wi) * ls.li / p;
        if c.max_element() <= 0.0 || !c.is_finite() {
            return None;
        }
        let o = if z.ng == Vec3::ZERO { z.p } else { self.scene.offset_origin(z.p, z.ng, ls.wi) };
        let c = c * self.scene.transmittance_along(o, ls.wi, f32::INFINITY, z.medium_toward(ls.wi));
        (c.max_element() > 0.0).then(|| (c, self.sky_weight(f, z, li, ls.wi)))
    }

    /// The weight of strategy s = 1 toward light at infinity `li` along unit `wi`
    /// from eye vertex `z`: against z's BSDF leaving the scene along `wi` (s = 0;
    /// never for a parallel sun) and against the light subpaths from the sky
    /// reaching z (SmallVCM's direct-illumination weight with an infinite
    /// light's cosine of 1).
    fn sky_weight(&self, f: &Factors, z: &Vertex, li: usize, wi: Vec3) -> f32 {
        let p = self.p_sample_sky(li, z, wi);
        let w_light = if self.scene.lights[li].is_delta() { 0.0 } else { mis(z.pdf_dir(z.wo, wi) / p) };
        let p_z = self.p_emit_sky(li, wi) * z.measure(wi) / p;
        let w_eye = z.mis.toward(p_z, z.pdf_dir(wi, z.wo), f.merge_at(z));
        finite_or_zero(1.0 / (w_light + 1.0 + w_eye))
    }

    /// What passes along the segment from vertex `a` to vertex `b` (each end
    /// offset off its surface toward the other) per channel: zero where a surface
    /// blocks it, else the media's transmittance and the colours of the
    /// index-matched boundaries it crosses (`Scene::transmittance_to`).
    fn transmittance(&self, a: &Vertex, b: &Vertex) -> Rgb {
        let scene = self.scene;
        // A unit direction: the offsets step ulps in proportion to it (a
        // segment's own length, kilometres in a scene at scale 2,510, moved its
        // end 10 m off the ceiling, past a lamp 7 m below it: seed 10409's scene
        // 14 lit its floor through the lamp, +25% indirect).
        let w = (b.p - a.p).normalize_or_zero();
        let o = if a.ng == Vec3::ZERO { a.p } else { scene.offset_origin(a.p, a.ng, w) };
        let e = if b.ng == Vec3::ZERO { b.p } else { scene.offset_origin(b.p, b.ng, -w) };
        let v = e - o;
        let len = v.length();
        if !(len > 0.0) {
            return Rgb::ZERO;
        }
        let ulps = 32.0 * f32::EPSILON * e.abs().max_element();
        scene.transmittance_to(o, v / len, (len - ulps).max(0.0), b.ng, a.medium_toward(w))
    }

    /// Strategy s = 0 (t = `eye.len()` >= 2): the eye subpath's last vertex on an
    /// emitter, what it adds [W sr^-1 m^-2] and its MIS weight.
    fn emitted(&self, f: &Factors, eye: &[Vertex]) -> Option<(Rgb, f32)> {
        let z = &eye[eye.len() - 1];
        let Kind::Surface { le, emitter: Some(_), .. } = z.kind else { return None };
        Some((z.beta * le, self.weight(f, eye, &[], 0, None)))
    }

    /// Strategy (s >= 1, t = `eye.len()` >= 2): the eye subpath joined to the light
    /// subpath `light` (its first s vertices), or for s = 1 to a light point
    /// picked with `u` (light, triangle, point; for a light at infinity a
    /// direction toward it, [`Self::sky_connect`]): the contribution to the pixel
    /// [W sr^-1 m^-2], its MIS weight, and whether the light is at infinity.
    fn connect(
        &self,
        f: &Factors,
        eye: &[Vertex],
        light: &[Vertex],
        s: usize,
        u: Option<(f32, f32, glam::Vec2)>,
    ) -> Option<(Rgb, f32, bool)> {
        let t = eye.len();
        let z = &eye[t - 1];
        if z.delta || !z.scatters() {
            return None;
        }
        // The light-side end: y_{s-1}, or for s = 1 a new point on a light.
        let picked = if s == 1 {
            let (u_light, u_sel, u_pos) = u?;
            let (li, _) = self.lights.pick(u_light);
            if at_infinity(&self.scene.lights[li]) {
                return self.sky_connect(f, z, li, u_sel, u_pos).map(|(c, w)| (c, w, true));
            }
            Some(self.light_point(li, u_sel, u_pos)?)
        } else {
            None
        };
        let y = picked.as_ref().unwrap_or_else(|| &light[s - 1]);
        if y.delta {
            return None;
        }
        let v = y.p - z.p;
        let d2 = v.length_squared();
        if !(d2 > 0.0) {
            return None;
        }
        let wi = v / d2.sqrt();
        // What each end passes on along the connection: the BSDF at a surface
        // (with its shading cosine over the geometric one), the emission toward
        // z at the light's point.
        let f_z = z.f(z.wo, wi);
        let (f_y, cos_y) = match &y.kind {
            Kind::Light { light, q } => {
                let cos = if q.n == Vec3::ZERO { 1.0 } else { q.n.dot(wi).abs() };
                (self.scene.lights[*light as usize].emitted_toward(q, -wi), cos)
            }
            _ => (y.f(-wi, y.wo), y.cos_at(wi)),
        };
        let c = z.beta * f_z * f_y * y.beta * (z.cos_at(wi) * cos_y / d2);
        if c.max_element() <= 0.0 || !c.is_finite() {
            return None;
        }
        let c = c * self.transmittance(z, y);
        if c.max_element() <= 0.0 {
            return None;
        }
        Some((c, self.weight(f, eye, light, s, picked.as_ref()), false))
    }

    /// The area density [m^-2] with which light subpaths start at light `li`'s
    /// point `q`: the light's choice times the point's density.
    fn light_pdf(&self, li: usize, q: &EmitterPoint) -> f32 {
        self.lights.probs[li] as f32 * q.pdf_pos
    }

    /// A point on light `li` (not at infinity) picked as a light subpath's first
    /// vertex is (`u_sel` its triangle, `u_pos` the point), for strategy s = 1.
    fn light_point(&self, li: usize, u_sel: f32, u_pos: glam::Vec2) -> Option<Vertex> {
        let q = self.scene.lights[li].emitter_point(self.scene, u_sel, u_pos)?;
        let pdf = self.light_pdf(li, &q);
        (pdf > 0.0).then(|| Vertex {
            kind: Kind::Light { light: li as u32, q },
            p: q.p,
            ng: q.n,
            ns: q.n,
            wo: Vec3::ZERO,
            beta: Rgb::splat(1.0 / pdf),
            mis: Partial::default(),
            delta: false,
            media: [self.scene.light_medium(li); 2],
        })
    }

    /// The pinhole as a vertex.
    fn camera_vertex(&self) -> Vertex {
        Vertex {
            kind: Kind::Camera,
            p: self.lens.camera.position,
            ng: Vec3::ZERO,
            ns: Vec3::ZERO,
            wo: Vec3::ZERO,
            beta: Rgb::ONE,
            mis: Partial::default(),
            delta: false,
            media: [self.eye_medium; 2],
        }
    }

    /// Strategy t = 1: the light subpath's last vertex y_{s-1} (s >= 2) seen by the
    /// pinhole: the pixel it lands in, what it adds there [W sr^-1 m^-2] and its
    /// MIS weight.
    fn splat(&self, light: &[Vertex], f: &Factors) -> Option<(u32, Rgb, f32)> {
        let s = light.len();
        let y = &light[s - 1];
        if y.delta || !y.scatters() {
            return None;
        }
        let cam = &self.lens.camera;
        let film = cam.project(y.p, self.lens.aspect)?;
        if !(0.0..1.0).contains(&film.x) || !(0.0..1.0).contains(&film.y) {
            return None;
        }
        let v = y.p - cam.position;
        let d2 = v.length_squared();
        let wc = v / d2.sqrt();
        let cos_c = wc.dot(cam.forward);
        if !(cos_c > 0.0) {
            return None;
        }
        // beta f_s G W_e with G = |cos_y| cos_c / d^2, W_e = 1 / (A cos_c^4).
        let c = y.beta * y.f(-wc, y.wo) * (y.cos_at(wc) / (d2 * self.lens.area * cos_c * cos_c * cos_c));
        let camera = self.camera_vertex();
        if c.max_element() <= 0.0 || !c.is_finite() {
            return None;
        }
        let c = c * self.transmittance(y, &camera);
        if c.max_element() <= 0.0 {
            return None;
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let px = ((film.x * w) as u32).min(self.width - 1) + ((film.y * h) as u32).min(self.height - 1) * self.width;
        Some((px, c, self.weight(f, std::slice::from_ref(&camera), light, s, None)))
    }

    /// The power-heuristic weight of strategy (s, t = `eye.len()`): the eye
    /// subpath joined to the light subpath's first s vertices (`light`), to the
    /// light point `picked` (s = 1), or for s = 0 ending on an emitter; 1 / (1 +
    /// w_light + w_eye) with each side's sum over the strategies that move the
    /// join toward it from the MIS sums its end vertex stored and the densities
    /// the join alone knows (tech. rep. eqs. 37, 40-47; a path of one segment has
    /// one strategy).
    fn weight(&self, f: &Factors, eye: &[Vertex], light: &[Vertex], s: usize, picked: Option<&Vertex>) -> f32 {
        let t = eye.len();
        if s + t == 2 {
            return 1.0;
        }
        let z = &eye[t - 1];
        if s == 0 {
            // Eqs. 42-43: the same path with its last vertex picked on the light
            // (s = 1), and with more of it from the light's side.
            let Kind::Surface { emitter: Some((li, q)), .. } = &z.kind else { return 0.0 };
            let pdf_a = self.light_pdf(*li as usize, q);
            let pdf_emit = pdf_a * self.scene.lights[*li as usize].pdf_emitted_dir(q, z.wo);
            return finite_or_zero(1.0 / (1.0 + mis(pdf_a) * z.mis.vcm + mis(pdf_emit) * z.mis.vc));
        }
        let y = picked.unwrap_or_else(|| &light[s - 1]);
        let wi = (y.p - z.p).normalize_or_zero();
        if t == 1 {
            // Eqs. 46-47: the eye side has no other strategy.
            let p_y = z.area_density(self.lens.pdf_dir(wi), y);
            return finite_or_zero(1.0 / (1.0 + y.mis.toward(p_y, y.pdf_dir(-wi, y.wo), f.merge_at(y))));
        }
        // The densities with which each end would make the other.
        let pdf_z_to_y = z.pdf_dir(z.wo, wi);
        let w_eye_side = |p_z_from_y: f32| z.mis.toward(p_z_from_y, z.pdf_dir(wi, z.wo), f.merge_at(z));
        let w = match &y.kind {
            Kind::Light { light: li, q } => {
                // Eqs. 44-45: the light point against the eye subpath hitting it
                // (never a point or spot light) and against longer light subpaths.
                let light = &self.scene.lights[*li as usize];
                let hit = if light.is_delta() { 0.0 } else { z.area_density(pdf_z_to_y, y) };
                let w_light = mis(hit / self.light_pdf(*li as usize, q));
                let w_eye = w_eye_side(y.area_density(light.pdf_emitted_dir(q, -wi), z));
                1.0 / (w_light + 1.0 + w_eye)
            }
            _ => {
                // Eqs. 40-41.
                let w_light = y.mis.toward(z.area_density(pdf_z_to_y, y), y.pdf_dir(-wi, y.wo), f.merge_at(y));
                let w_eye = w_eye_side(y.area_density(y.pdf_dir(y.wo, -wi), z));
                1.0 / (w_light + 1.0 + w_eye)
            }
        };
        finite_or_zero(w)
    }
}

/// `w`, or 0 when it is not finite.
fn finite_or_zero(w: f32) -> f32 {
    if w.is_finite() { w } else { 0.0 }
}

/// True for a light at infinity (an environment, a sun): no light subpath starts
/// there; eye subpaths find it by leaving the scene or by sampling it.
fn at_infinity(l: &pm_scene::Light) -> bool {
    matches!(l.kind, LightKind::Directional { .. } | LightKind::Environment { .. })
}

/// The layer of the path strategy (s, t) makes, split as the path tracer splits
/// its image (pm-render's `path`): emission seen directly and light arriving
/// straight from a light at the first surface are direct; anything seen through
/// a mirror or glass first is specular; light reaching the first surface through
/// delta bounces only is caustic; the rest indirect; and every path whose first
/// vertex (not seen through a mirror or glass) is in a medium is the volume
/// layer. Index into [`Layer::ALL`].
fn layer_of(eye: &[Vertex], light: &[Vertex], s: usize, t: usize) -> usize {
    // Vertices after the pinhole, from the eye: x_1 .. x_n, x_n on the light.
    let n = t - 1 + s;
    if n == 1 {
        return Layer::Direct.index();
    }
    let x = |j: usize| if j < t { &eye[j] } else { &light[s - 1 - (j - t)] };
    layer(n, x(1), (2..n).all(|j| x(j).delta))
}

/// The layer of a path of `n` segments whose first vertex after the pinhole is
/// `x1`, `caustic` when every vertex between x_1 and the light's is a delta one
/// ([`layer_of`]'s rule).
fn layer(n: usize, x1: &Vertex, caustic: bool) -> usize {
    let layer = if n == 1 {
        Layer::Direct
    } else if x1.delta {
        Layer::Specular
    } else if matches!(x1.kind, Kind::Medium { .. }) {
        Layer::Volume
    } else if n == 2 {
        Layer::Direct
    } else if caustic {
        Layer::Caustic
    } else {
        Layer::Indirect
    };
    layer.index()
}

/// The settings of either method this crate runs: [`BdptParams`] or
/// [`VcmParams`].
pub trait Method: Copy {
    /// Passes to render.
    fn passes(&self) -> u32;
    /// The renderer's state before its first pass.
    fn start<'a>(&self, scene: &'a Scene, camera: &Camera, film: &pm_render::Film) -> Result<Bdpt<'a>, String>;
}

impl Method for BdptParams {
    fn passes(&self) -> u32 {
        self.bdpt_passes
    }
    fn start<'a>(&self, scene: &'a Scene, camera: &Camera, film: &pm_render::Film) -> Result<Bdpt<'a>, String> {
        Bdpt::new(scene, camera, film.width, film.height, film.seed, *self)
    }
}

impl Method for VcmParams {
    fn passes(&self) -> u32 {
        self.vcm_passes
    }
    fn start<'a>(&self, scene: &'a Scene, camera: &Camera, film: &pm_render::Film) -> Result<Bdpt<'a>, String> {
        Bdpt::vcm(scene, camera, film.width, film.height, film.seed, *self)
    }
}

/// Render `view.rect` of `view.film` by the method's passes (the whole film is
/// traced: light subpaths land anywhere), reporting passes done as progress.
pub fn render(
    scene: &Scene,
    params: &impl Method,
    view: View,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, pm_render::RenderStats), String> {
    let passes = params.passes() as u64;
    let (image, stats, _) = render_with(scene, params, view, None, &mut |b| {
        progress(b.passes() as u64, passes);
        Ok(true)
    })?;
    Ok((image, stats))
}

/// [`render`], continuing from the passes of `start` when given (a state file,
/// read from the path it names, of the same scene and settings: see
/// [`Bdpt::resume`]; a refusal names the file) and calling `after_pass` after
/// each pass with the state so far (to write a checkpoint image or state, or
/// stop: `Ok(false)` ends the render with the passes done). Returns the image,
/// its statistics and the passes it holds.
pub fn render_with(
    scene: &Scene,
    params: &impl Method,
    view: View,
    start: Option<(&std::path::Path, &pm_format::PassStateFile)>,
    after_pass: &mut dyn FnMut(&Bdpt) -> Result<bool, String>,
) -> Result<(Image, pm_render::RenderStats, u32), String> {
    let t0 = std::time::Instant::now();
    let mut b = params.start(scene, view.camera, view.film)?;
    if let Some((path, file)) = start {
        b.resume(file, params.passes()).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    pm_render::run_passes(&mut b, &view, params.passes(), t0, after_pass)
}

impl pm_render::PassLoop for Bdpt<'_> {
    fn passes_done(&self) -> u32 {
        self.passes()
    }
    fn next_pass(&mut self, _camera: &Camera) -> Result<(), String> {
        self.pass();
        Ok(())
    }
    fn image_of(&self, rect: pm_render::Rect) -> Image {
        self.region_image(rect)
    }
    fn cut_paths(&self) -> u64 {
        self.cut
    }
}

#[cfg(test)]
mod tests;
