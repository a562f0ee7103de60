//! Image-space photon mapping (McGuire and Luebke 2009) on the CPU: per light a
//! bounce map and the remaining bounces traced ([`bounce`], sections 4.2-4.3), the
//! eye G-buffer with direct light by shadow rays or shadow maps, and indirect light
//! by splatting photon volumes over it ([`splat`], section 5), optionally at a
//! lower resolution with joint bilateral upsampling (section 5.2).
//!
//! A [`pm_live::FrameMethod`]: `pm-live` runs the frames and shades the pixels; what
//! mirrors and glass show gathers the same photons ([`SplatLight`]). A frame
//! carries nothing to the next. Units: power W per RGB channel, radiance
//! W sr^-1 m^-2, lengths m.

pub mod bounce;
pub mod splat;

pub use bounce::{BounceMaps, BouncePhoton, BounceStats, KernelShape, Traced, bounce_maps, trace};

use glam::Vec3;
use pm_color::Rgb;
use pm_live::{DirectMode, FrameParams, FrameRow, IndirectLight, LiveShading, World};
use pm_params::{Any, above, above_up_to, between};
use pm_raster::Fragment;
use pm_render::{FrameBuffers, Visibility, VolumePhotons};
use pm_scene::{Camera, Hit, Scene};
use rayon::prelude::*;
use splat::{GBuffer, PhotonIndex, Seen, SplatOutput, Surface, VolumePhoton};
use std::f32::consts::PI;
use std::time::Instant;

pm_params::params! {
    /// The image-space method's parameters (McGuire and Luebke 2009 sections 4-5):
    /// `photon-live`'s options and keys of pipeline.toml's `[live]` section.
    pub struct IspmParams {
        /// Texels per side of each face of a light's bounce map (6 x res^2 directions
        /// for a point light; directional and area lights shoot as many samples;
        /// lights share texels by power). 64 rather than 48: with the volumes below,
        /// Blender's animated room's frames are 7.3-8.7% block RMS off the path
        /// tracer at 64; 80 takes them to 6.5-8.1% for 1.5 times the frame time
        /// (BENCHMARKS.md, issue 53).
        bounce_res: u32 = 64 => between(1, 4096);
        /// Photons stored per path after the bounce map (1: one indirect bounce). The
        /// default traces until more stop paying: on cornell_spheres the image's mean
        /// bias against the path tracer is -14.9% at 2, -6.4% at 4, -4.3% at 6 and
        /// -3.7% at 8 (`cargo bench -p pm-ispm --bench ispm -- bounces`, BENCHMARKS.md).
        bounces: u32 = 8 => between(1, 64);
        /// Kernel radius of a path of density 1, as a fraction of the scene diagonal;
        /// a path of density ρ gets radius r / sqrt(ρ) (one Lambertian bounce:
        /// ρ ≈ albedo / 1000, so about 0.05 to 0.07 of the diagonal, clamped to
        /// the largest). Larger volumes hold more photons: at 0.001 and at most
        /// 0.03, the volumes of Blender's room held about 30 photons each and its
        /// frames were splotched (two seeds 25% block RMS apart). At 0.002 and at
        /// most 0.06 they were smoother still, but the ceiling around a lamp 2 mm
        /// below it glowed (the differential checker's seed 23897, scene 9).
        kernel_radius_rel_diag: f32 = 0.0015 => above(0.0);
        /// Smallest kernel radius, fraction of the diagonal (also every photon's
        /// under a cover: [`KernelShape::radii`]).
        kernel_min_rel_diag: f32 = 0.01 => above(0.0);
        /// Largest kernel radius, fraction of the diagonal (most indirect photons
        /// have it).
        kernel_max_rel_diag: f32 = 0.05 => above(0.0);
        /// Kernel thickness along the photon's surface normal over its radius in the
        /// surface plane (r_z / r_xy, section 5.1).
        kernel_minor: f32 = 0.25 => above_up_to(0.0, 1.0);
        /// Splat at 1 / subsample of the resolution in each direction and upsample
        /// with the joint bilateral filter (section 5.2; 1: off, the consistent
        /// estimate; the paper uses 2 to 16).
        subsample: u32 = 1 => between(1, 16);
        /// Divide each photon's power by the part of its kernel's disc that lies on
        /// the surface it hit (probed with rays, weighted by the kernel), so a
        /// volume at a wall's edge does not lose the part that runs off the wall.
        volume_coverage: bool = true => Any;
    }
}

/// What one image-space frame did: a row of frames.csv (times \[s\] split like the
/// paper's Table 2, and the bounce maps' attrition of Figure 10).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IspmFrame {
    /// Frame number (0 first).
    pub frame: u64,
    /// The eye G-buffer (rasteriser) \[s\].
    pub gbuffer_s: f64,
    /// Direct light, emission and mirrors and glass over the G-buffer \[s\].
    pub direct_s: f64,
    /// The bounce maps \[s\].
    pub bounce_s: f64,
    /// Tracing the remaining bounces \[s\].
    pub trace_s: f64,
    /// Splatting photon volumes \[s\].
    pub splat_s: f64,
    /// Bilateral upsampling of a subsampled splat \[s\].
    pub upsample_s: f64,
    /// The whole frame \[s\].
    pub total_s: f64,
    /// Bounce-map texels (directions) emitted, all lights.
    pub texels: u64,
    /// Texels whose direction hits the scene.
    pub texel_hits: u64,
    /// Texels whose photon survived the first bounce's Russian roulette.
    pub survived: u64,
    /// Photons stored for splatting.
    pub photons: usize,
}

impl FrameRow for IspmFrame {
    fn frame(&self) -> u64 {
        self.frame
    }

    fn wall_seconds(&self) -> f64 {
        self.total_s
    }
}

/// Indirect light from photon volumes: splatted over the eye's surfaces after
/// drawing, gathered (the same kernels, [`splat::gather`]) where mirrors and glass
/// lead; in scattering media, the beam estimate over the frame's volume photons.
pub struct SplatLight<'a> {
    /// The frame's photons.
    pub photons: &'a [VolumePhoton],
    /// Their radius-query index.
    pub index: &'a PhotonIndex,
    /// The scene, when some photon lies under a cover
    /// ([`VolumePhoton::covered`]): the points gathered at are then asked too.
    pub covers: Option<&'a Scene>,
    /// The frame's photons scattered in media (none without scattering media).
    pub volume: Option<&'a VolumePhotons>,
}

impl IndirectLight for SplatLight<'_> {
    const SPLATTED: bool = true;

    fn radiance(&self, hit: &Hit, bsdf: &pm_bsdf::Bsdf, wo: Vec3) -> Rgb {
        let n = pm_render::facing(hit.ns, wo);
        let mut surface = Surface::new(hit.p, n, wo, *bsdf);
        surface.covered = self.covers.is_some_and(|scene| pm_render::covered(scene, hit.p, n));
        let (ind, caus) = splat::gather(self.photons, self.index, &surface);
        ind + caus
    }

    /// The beam estimate over the frame's volume photons scattered more than
    /// once ([`VolumePhotons::scattered`]); the paper has no media, and without
    /// it the frames of issue 53's fog scenes had single scattering only (volume
    /// layer 50-80% dark).
    fn scattered(&self, o: Vec3, d: Vec3, t: f32, m: &pm_scene::Medium) -> Rgb {
        self.volume.map_or(Rgb::ZERO, |v| v.scattered(o, d, t, m))
    }
}

/// The surface the splat sees at each pixel of the rasterised first hits: none
/// where nothing is seen or a mirror or glass is (photons cannot be splatted there;
/// the paper's section 2.1), nor on a glossy surface, whose indirect light the
/// shading takes along its lobe (`pm_live::LiveShading`).
pub fn surfaces(scene: &Scene, fragments: &[Option<Fragment>], camera: &Camera) -> Vec<Option<Surface>> {
    fragments.par_iter().with_min_len(1024).map(|f| surface_at(scene, f, camera)).collect()
}

/// The splat's G-buffer of [`surfaces`] into `out`, reusing its memory (a frame's
/// G-buffer is tens of megabytes; faulting it back in every frame showed in the
/// profile).
pub fn gbuffer_into(scene: &Scene, fragments: &[Option<Fragment>], camera: &Camera, out: &mut GBuffer) {
    out.fill(fragments.len(), |j| {
        let Some(f) = &fragments[j] else { return Seen::Nothing };
        // Most pixels see a plain Lambertian surface: the point, its normal and
        // albedo are all the splat reads, and building the hit record and BSDF for
        // them took most of this pass (the full path gives the same values). Mirror
        // and glass pixels are known from the material alone.
        if let Some((p, ns, rho)) = scene.plain_lambert(f.tri, f.b) {
            let wo = (camera.position - p).normalize_or(ns);
            return Seen::Lambert { p, n: pm_render::facing(ns, wo), albedo_pi: rho / PI };
        }
        if scene.uniform_bsdf(f.tri).is_some_and(|b| b.is_specular() || b.is_glossy()) {
            return Seen::Nothing;
        }
        surface_at(scene, &fragments[j], camera).into()
    });
}

fn surface_at(scene: &Scene, fragment: &Option<Fragment>, camera: &Camera) -> Option<Surface> {
    let hit = fragment.as_ref()?.hit(scene);
    let bsdf = scene.bsdf(&hit);
    if bsdf.is_specular() || bsdf.is_glossy() {
        return None;
    }
    let wo = (camera.position - hit.p).normalize_or(hit.ns);
    Some(Surface::new(hit.p, pm_render::facing(hit.ns, wo), wo, bsdf))
}

/// What the medium the camera is in lets through from each pixel's rasterised first
/// surface to the eye (Beer-Lambert over the fragment's distance, per channel);
/// none in a clear medium. The splat's light on those surfaces is attenuated by it,
/// as the shading's is along every eye ray (the splat covers only surfaces seen
/// directly, with nothing but the eye's medium in between).
fn eye_transmittance(scene: &Scene, camera: &Camera, fragments: &[Option<Fragment>]) -> Option<Vec<Rgb>> {
    let m = scene.medium(scene.eye_medium(camera.position)).filter(|m| !m.is_clear())?;
    Some(fragments.par_iter().with_min_len(1024).map(|f| f.map_or(Rgb::ONE, |f| m.transmittance(f.t))).collect())
}

/// `values` times `tr`, pixel by pixel, when there is a `tr`.
fn attenuate(values: &mut [Rgb], tr: Option<&[Rgb]>) {
    if let Some(tr) = tr {
        values.par_iter_mut().zip(tr).with_min_len(4096).for_each(|(v, t)| *v *= *t);
    }
}

/// The image-space method: its parameters and the memory its frames reuse (the
/// rasteriser's fragments, the G-buffer, the splats' working arrays and outputs).
pub struct Ispm {
    frame_params: FrameParams,
    params: IspmParams,
    seed: u64,
    /// Whether caustic paths are traced (the scene analysis is asked once:
    /// "simulate only the effects a scene calls for").
    caustics: bool,
    fragments: Vec<Option<Fragment>>,
    /// The eye's G-buffer (full resolution).
    gbuffer: GBuffer,
    /// The full-resolution splat (all photons, or the caustic ones when subsampled).
    full: splat::SplatScratch,
    /// The subsampled splat of the soft indirect photons.
    low: splat::SplatScratch,
    /// The G-buffer it is splatted over.
    low_gbuffer: GBuffer,
}

impl Ispm {
    /// The method over `world`'s scene. Fails when a parameter is out of range.
    pub fn new(world: &World, frame_params: FrameParams, params: IspmParams, seed: u64) -> Result<Ispm, String> {
        frame_params.validate(pm_params::Naming::Cli)?;
        params.validate(pm_params::Naming::Cli)?;
        Ok(Ispm {
            frame_params,
            params,
            seed,
            caustics: pm_light::analyze(world.scene()).caustics.yes,
            fragments: Vec::new(),
            gbuffer: GBuffer::default(),
            full: Default::default(),
            low: Default::default(),
            low_gbuffer: GBuffer::default(),
        })
    }

    /// Draw one frame of `scene` seen by `camera` into `buffers`.
    fn draw(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        frame: u64,
        buffers: &mut FrameBuffers,
    ) -> Result<IspmFrame, String> {
        let (f, p, seed) = (&self.frame_params, &self.params, self.seed);
        let start = Instant::now();
        // The same seed every frame: a static light gives the same bounce map and
        // photons frame after frame (the paper's seeding by light and texel).
        let film = f.film(seed);
        let t = Instant::now();
        let bounce = bounce_maps(scene, p.bounce_res, seed, self.caustics);
        let bstats = bounce.stats;
        let t_bounce = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let diag = scene.bounds.diagonal();
        let kernel = KernelShape::new(p, diag);
        let Traced { photons, volume } = trace(scene, &bounce, p.bounces, &kernel, seed);
        let index = PhotonIndex::new(&photons);
        // Beam spheres up to a tenth of the diagonal, as the vertex method's
        // estimates reach.
        let volume = f.multiple_scattering.then(|| VolumePhotons::new(scene, &volume, 0.1 * diag)).flatten();
        let t_trace = t.elapsed().as_secs_f64();
        let t = Instant::now();
        pm_raster::first_hits_into(scene, camera, film.size(), film.rect(), &mut self.fragments);
        let t_gbuffer = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let maps = f.shadow_maps(scene);
        // Direct light from photons is not a choice here: it is taken by shadow rays.
        let direct = if f.direct == DirectMode::Photons { DirectMode::Rays } else { f.direct };
        let any_covered = photons.iter().any(|p| p.covered);
        let indirect = SplatLight {
            photons: &photons,
            index: &index,
            covers: any_covered.then_some(scene),
            volume: volume.as_ref(),
        };
        let shading = LiveShading::new(scene, indirect, direct, f, maps.as_ref()).map_err(|e| e.to_string())?;
        let visibility = Visibility::Fragments(scene, &self.fragments);
        pm_render::render_into(
            pm_render::Shot { camera, film: &film, rect: film.rect() },
            &shading,
            false,
            visibility,
            buffers,
            &|_, _| {},
        )?;
        let t_direct = t.elapsed().as_secs_f64();
        let t = Instant::now();
        gbuffer_into(scene, &self.fragments, camera, &mut self.gbuffer);
        if any_covered {
            let (w, h) = (f.width, f.height);
            let rects = photons.iter().filter(|p| p.covered).filter_map(|p| p.screen_rect(camera, w, h));
            self.gbuffer.mark_covered(scene, w, rects);
        }
        let eye_tr = eye_transmittance(scene, camera, &self.fragments);
        let (gbuffer, full, low, low_gbuffer) = (&self.gbuffer, &mut self.full, &mut self.low, &mut self.low_gbuffer);
        let (w, h, sub) = (f.width, f.height, p.subsample);
        let (t_splat, t_upsample) = if sub <= 1 {
            splat::splat_into(&photons, gbuffer, camera, (w, h, 1), SplatOutput::Radiance, full);
            attenuate(&mut full.indirect, eye_tr.as_deref());
            buffers.add_to_layer(pm_color::Layer::Indirect, &full.indirect);
            (t.elapsed().as_secs_f64(), 0.0)
        } else {
            // Section 5.2: the soft indirect light's irradiance splatted at 1/f
            // resolution, upsampled with the joint bilateral filter, then times each
            // full-resolution pixel's albedo / π (exact for Lambertian surfaces; glossy
            // ones get their normal-incidence albedo). Caustic photons, whose kernels
            // are a few pixels wide, are splatted at full resolution: upsampled they
            // were 130% off at f = 2 (`cargo bench -p pm-ispm --bench ispm`).
            let (caustic_photons, soft): (Vec<VolumePhoton>, Vec<VolumePhoton>) =
                photons.iter().partition(|q| q.caustic);
            splat::splat_into(&caustic_photons, gbuffer, camera, (w, h, 1), SplatOutput::Radiance, full);
            gbuffer.subsample_into(w, h, sub, low_gbuffer);
            let low_gb = &*low_gbuffer;
            splat::splat_into(&soft, low_gb, camera, (w, h, sub), SplatOutput::Irradiance, low);
            let t_splat = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let up = splat::Upsample::new(&low.indirect, low_gb, gbuffer, camera.position, (w, h, sub), true);
            buffers.add_rows_to_layer(pm_color::Layer::Indirect, w as usize, |y, row| {
                up.row(y, row);
                attenuate(row, eye_tr.as_deref().map(|t| &t[y * w as usize..][..row.len()]));
            });
            (t_splat, t.elapsed().as_secs_f64())
        };
        attenuate(&mut full.caustic, eye_tr.as_deref());
        buffers.add_to_layer(pm_color::Layer::Caustic, &full.caustic);
        Ok(IspmFrame {
            frame,
            gbuffer_s: t_gbuffer,
            direct_s: t_direct,
            bounce_s: t_bounce,
            trace_s: t_trace,
            splat_s: t_splat,
            upsample_s: t_upsample,
            total_s: start.elapsed().as_secs_f64(),
            texels: bstats.texels,
            texel_hits: bstats.hits,
            survived: bstats.survived,
            photons: photons.len(),
        })
    }
}

impl pm_live::FrameMethod for Ispm {
    type Row = IspmFrame;

    fn warm_up(&self) -> u64 {
        // No state carries over; the first frame pays for first-touch memory.
        1
    }

    fn moved(&mut self, _: &World) {}

    fn frame(&mut self, world: &World, frame: u64, draw: bool, out: &mut FrameBuffers) -> Result<IspmFrame, String> {
        if !draw {
            return Ok(IspmFrame { frame, ..Default::default() });
        }
        self.draw(world.scene(), world.camera(), frame, out)
    }
}

/// A live renderer of `scene` by the image-space method.
pub fn live(
    scene: Scene,
    frame_params: FrameParams,
    params: IspmParams,
    seed: u64,
) -> Result<pm_live::Live<Ispm>, String> {
    let world = World::new(scene, None)?;
    let method = Ispm::new(&world, frame_params, params, seed)?;
    Ok(pm_live::Live::new(world, method))
}
