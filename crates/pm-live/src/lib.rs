//! Real-time photon mapping (Jozwowski 2002, "Real Time Photon Mapping", sections 4
//! and 5): every frame re-shoots the oldest `per_frame` of `total` photon paths into
//! a ring buffer ([`RingBuffer`], section 4.1.1-4.1.2), rebalances a kd-tree over the
//! used slots, estimates irradiance at the mesh's corners ([`Corners`], sections
//! 4.1.3 and 4.4.2), and draws the mesh with the corner radiance interpolated across
//! each triangle (Gouraud) times the reflectance, with direct light by shadow rays
//! per pixel (sharp shadows) or from the photons alone (as in the thesis).
//!
//! It reuses the batch pipeline's pieces rather than forking them: the tracer's own
//! per-path streams (`pm_photon::trace_path`), the kd-tree, the k-nearest irradiance
//! estimate, the BSDFs, light sampling, and the image loop of `pm-render` (the frame
//! is an [`Integrator`](pm_render::Integrator) over the region loop). Radiance is
//! W sr^-1 m^-2 per RGB channel; photon power W; irradiance W m^-2.
//!
//! This crate does no I/O: a frame is an in-memory image and its statistics.

pub mod ispm;
mod mesh;
mod ring;
mod shade;
pub mod splat;

pub use mesh::Corners;
pub use ring::{Distribution, RingBuffer, ShootStats};
pub use shade::LiveShading;

use pm_color::Rgb;
use pm_format::{FullIrrPhoton, PhotonRecord, flags};
use pm_light::LightSelector;
use pm_params::{Any, above, above_up_to, at_least, between};
use pm_photon::{Budget, MapPass, TraceConfig};
use pm_render::{Film, FrameBuffers, RenderStats, Visibility};
use pm_scene::{Camera, Scene, Target};
use std::time::Instant;

pm_params::value_enum! {
    /// Where direct light comes from.
    pub enum DirectMode {
        /// A shadow ray per light sample at every pixel: sharp shadows.
        Rays,
        /// Every light at every pixel, visibility from a cube shadow map drawn by the
        /// rasteriser each frame at the light's centre: point and spot lights exactly;
        /// small planar area lights with their unoccluded irradiance in closed form
        /// (Lambertian surfaces; one light sample elsewhere) and the centre's
        /// visibility, so without noise but with hard shadows. Scenes with other
        /// lights keep shadow rays.
        ShadowMap,
        /// The photons' estimate at the corners, like indirect light (the thesis).
        Photons,
    }
}

pm_params::value_enum! {
    /// Which real-time method draws the frames.
    pub enum Method {
        /// Jozwowski 2002: a ring buffer of photon paths, estimates at mesh vertices.
        Vertex,
        /// McGuire and Luebke 2009: bounce maps and photon volumes splatted over the
        /// eye's G-buffer.
        Ispm,
    }
}

pm_params::value_enum! {
    /// How a frame finds the surface at each pixel.
    pub enum DrawMode {
        /// A CPU rasteriser with a z-buffer and perspective-correct interpolation.
        Raster,
        /// An eye ray per pixel through the BVH.
        Rays,
    }
}

pm_params::value_enum! {
    /// How the estimates find photons each frame.
    pub enum PhotonSearch {
        /// Rebuild a balanced kd-tree over the used slots (the thesis, section 4.1.2).
        Rebuild,
        /// Update a hash grid (cells as large as the search radius) for the re-shot
        /// paths only: the thesis's future work.
        Grid,
    }
}

pm_params::value_enum! {
    /// What photons are traced in (section 4.4.1, scene simplification).
    pub enum PhotonProxy {
        /// The scene itself (or the --photon-scene given).
        None,
        /// Every non-emitting object replaced by its bounding box.
        Boxes,
    }
}

pm_params::params! {
    /// The real-time mode's parameters, defined once: `photon-live`'s options and the
    /// `[live]` section of pipeline.toml (Jozwowski 2002 sections 4.1 and 4.4).
    pub struct LiveParams {
        /// The method: vertex estimates (Jozwowski 2002) or image-space photon
        /// mapping (McGuire and Luebke 2009).
        method: Method = Method::Vertex => Any;
        /// Photon paths re-shot every frame (the thesis: 100-2,000).
        per_frame: u32 = 2_000 => between(1, 1 << 24);
        /// Photon paths the ring buffer holds (the thesis: 2,000; at least per_frame).
        total: u32 = 20_000 => between(1, 1 << 24);
        /// Hits kept per path. The thesis finds 3 sufficient, but in a closed room
        /// (albedo about 0.7) 3 loses 28% of the light and 8 loses 7% against the
        /// batch pipeline (`cargo xtask live-study`, BENCHMARKS.md), for 5% more time.
        max_level: u32 = 8 => between(1, 64);
        /// Which paths re-shot slots get: random, same-per-frame or same-over-total.
        distribution: Distribution = Distribution::SameOverTotal => Any;
        /// Photons per corner estimate.
        k: usize = 50 => between(1, 1 << 16);
        /// Largest estimate radius, as a fraction of the scene's bounding-box diagonal.
        max_radius_rel_diag: f32 = 0.1 => above(0.0);
        /// Direct light by shadow rays per pixel (rays) or from the photons (photons).
        direct: DirectMode = DirectMode::Rays => Any;
        /// Texels per side of each face of a cube shadow map (direct = shadow-map).
        shadow_map_res: u32 = 256 => between(16, 8192);
        /// Light samples per pixel for direct light by rays.
        light_samples: u32 = 1 => between(1, 1 << 10);
        /// One estimate per shared corner (section 4.4.2) instead of one per triangle vertex.
        cornering: bool = true => Any;
        /// Skip corners of triangles facing away from the camera (one-sided materials).
        back_face_culling: bool = true => Any;
        /// Skip corners of triangles outside the view frustum.
        frustum_culling: bool = true => Any;
        /// Split every triangle uniformly until no edge is longer than this [m] (section
        /// 4.3: more corners, finer indirect light; photons are still traced in the
        /// unsplit scene); 0 leaves the mesh as it is.
        subdivide: f32 = 0.0 => at_least(0.0);
        /// Find photons by rebuilding the kd-tree each frame (rebuild) or by updating a
        /// grid for the re-shot paths only (grid; measured faster: 5 against 7.5 ms of
        /// search structure and estimates per frame, BENCHMARKS.md).
        photon_search: PhotonSearch = PhotonSearch::Grid => Any;
        /// Trace photons in the scene (none) or in its bounding boxes (boxes).
        photon_proxy: PhotonProxy = PhotonProxy::None => Any;
        /// Temporal filter: weight of the previous frame's corner irradiance in this
        /// frame's (E = (1 - w) E_new + w E_previous; 0: off). Trades flicker for lag.
        temporal: f32 = 0.0 => between(0.0, 0.99);
        /// Surfaces seen at pixels by the rasteriser or by eye rays (the same except at silhouettes).
        draw: DrawMode = DrawMode::Raster => Any;
        /// Depth limit of mirror and glass recursion when drawing.
        max_depth: u32 = 8 => between(0, 1000);
        /// Image-space method: texels per side of each face of a light's bounce map
        /// (6 x res^2 directions for a point light; directional and area lights shoot
        /// as many samples; lights share texels by power).
        bounce_res: u32 = 48 => between(1, 4096);
        /// Image-space method: photons stored per path after the bounce map (1: one
        /// indirect bounce).
        bounces: u32 = 2 => between(1, 64);
        /// Image-space method: kernel radius of a path of density 1, as a fraction of
        /// the scene diagonal; a path of density ρ gets radius r / sqrt(ρ) (one
        /// Lambertian bounce: ρ ≈ albedo / 1000).
        kernel_radius_rel_diag: f32 = 0.001 => above(0.0);
        /// Image-space method: smallest kernel radius, fraction of the diagonal.
        kernel_min_rel_diag: f32 = 0.01 => above(0.0);
        /// Image-space method: largest kernel radius, fraction of the diagonal.
        kernel_max_rel_diag: f32 = 0.03 => above(0.0);
        /// Image-space method: kernel thickness along the photon's surface normal
        /// over its radius in the surface plane (r_z / r_xy, section 5.1).
        kernel_minor: f32 = 0.25 => above_up_to(0.0, 1.0);
        /// Image-space method: splat at 1 / subsample of the resolution in each
        /// direction and upsample with the joint bilateral filter (section 5.2; 1: off,
        /// the consistent estimate; the paper uses 2 to 16).
        subsample: u32 = 1 => between(1, 16);
        /// Frame width [pixels].
        width: u32 = 512 => between(1, 16384);
        /// Frame height [pixels].
        height: u32 = 512 => between(1, 16384);
        /// Frames per second of animation time (frame f shows time f / fps) [1/s].
        fps: f32 = 60.0 => above(0.0);
        /// Exposure of the PNG frames in stops.
        exposure: f32 = 0.0 => at_least(-64.0);
    }
}

impl LiveParams {
    /// [`Self::validate`] plus the checks that relate two values.
    pub fn check(&self, naming: pm_params::Naming) -> Result<(), String> {
        self.validate(naming)?;
        if self.per_frame > self.total {
            return Err(format!(
                "{} = {} is above {} = {}",
                naming.name("per_frame"),
                self.per_frame,
                naming.name("total"),
                self.total
            ));
        }
        Ok(())
    }
}

/// Wall time of each step of a frame \[s\] (the thesis's Figures 21-27 split).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct FrameTimes {
    /// Shooting `per_frame` paths into the ring buffer.
    pub shoot: f64,
    /// Rebuilding the kd-tree over the used slots.
    pub balance: f64,
    /// Corner culling and irradiance estimates.
    pub estimate: f64,
    /// Drawing the frame (rasterising or eye rays, interpolation, direct light).
    pub draw: f64,
    /// The whole frame. The rasteriser runs beside the photon update (the grid's
    /// update is serial and leaves a core free), so this is less than the sum.
    pub wall: f64,
}

/// What one frame did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FrameStats {
    /// Frame number (0 first).
    pub frame: u64,
    /// Times per step \[s\].
    pub times: FrameTimes,
    /// Paths shot this frame.
    pub paths_shot: u64,
    /// Rays the photon paths traced.
    pub photon_rays: u64,
    /// Paths the buffer holds.
    pub paths_held: usize,
    /// Photons in the kd-tree (used slots that the estimates read).
    pub photons_in_tree: usize,
    /// Corner estimates made (active corners).
    pub estimates: usize,
    /// Corners in all.
    pub corners: usize,
    /// Flicker: mean absolute change of corner irradiance since the previous frame
    /// over the mean irradiance, at corners active in both (0 at the first frame).
    pub flicker: f64,
    /// Eye samples drawn.
    pub samples: u64,
    /// The image-space method's own split and counts (its frames have no ring
    /// buffer, kd-tree or corners).
    pub ispm: Option<ispm::IspmStats>,
}

/// True for the photons the corner estimates read: all of them when direct light
/// comes from photons, else all but the direct ones (direct light is then computed
/// per pixel).
fn estimates_read(direct: DirectMode, p: &pm_format::Photon) -> bool {
    direct == DirectMode::Photons || p.flags & flags::DIRECT == 0
}

/// The shadow maps of `scene`'s lights when direct light comes from shadow maps
/// and every light can have one (see [`pm_light::ShadowMaps`]); none otherwise.
fn shadow_maps(scene: &Scene, p: &LiveParams) -> Option<pm_light::ShadowMaps> {
    if p.direct != DirectMode::ShadowMap {
        return None;
    }
    pm_light::ShadowMaps::new(scene, p.shadow_map_res)
}

/// The lights of `scene` that cannot have a shadow map (directional lights; area
/// lights that are large, curved, two-sided or textured), by name: with any of them
/// `--direct shadow-map` draws every light with shadow rays.
pub fn lights_without_shadow_maps(scene: &Scene) -> Vec<String> {
    scene.lights.iter().filter(|l| !pm_light::ShadowMaps::supports(l)).map(|l| l.name.clone()).collect()
}

/// The photons of `ring` the estimates read (see [`Live::tree_photons`]).
fn tree_photons(ring: &RingBuffer, direct: DirectMode) -> Vec<FullIrrPhoton> {
    ring.photons().iter().filter(|p| estimates_read(direct, p)).map(FullIrrPhoton::encode).collect()
}

/// The frames run `k` of `n` draws of an animation of `frames` frames: consecutive
/// runs of nearly equal length (frames k x F / n up to (k + 1) x F / n), the
/// frames dimension of a job plan (`photon-live --frame-task K/N`).
pub fn task_frames(k: u32, n: u32, frames: u32) -> std::ops::Range<u32> {
    let at = |i: u32| (i as u64 * frames as u64 / n.max(1) as u64) as u32;
    at(k)..at(k + 1)
}

/// The name of the part of frames.csv a run of `frames` writes (in OUT/frames).
pub fn frames_part_file(frames: &std::ops::Range<u32>) -> String {
    format!("part-{:04}-{:04}.csv", frames.start, frames.end)
}

/// Flicker of `now` against `before` (same corners): mean |now - before| over
/// mean(before), over channels; 0 when `before` is dark.
pub fn flicker_of(now: &[pm_color::Rgb], before: &[pm_color::Rgb]) -> f64 {
    let diff: f64 = now.iter().zip(before).map(|(a, b)| (*a - *b).abs().element_sum() as f64).sum();
    let base: f64 = before.iter().map(|b| b.element_sum() as f64).sum();
    if base > 0.0 { diff / base } else { 0.0 }
}

/// The real-time renderer's state between frames.
pub struct Live {
    scene: Scene,
    /// A simpler scene to trace photons in (section 4.4.1), or none (the scene).
    photon_scene: Option<Scene>,
    camera: Camera,
    params: LiveParams,
    seed: u64,
    trace: TraceConfig,
    targets: Vec<Target>,
    ring: RingBuffer,
    corners: Corners,
    frame: u64,
    /// The previous frame's corner irradiance, and which corners had one.
    previous: Option<(Vec<Rgb>, Vec<bool>)>,
    /// The drawing's memory, kept between frames.
    buffers: FrameBuffers,
    /// Added to every point and spot light's position after the animation (the
    /// interactive window moves lights with it) [m].
    light_offset: glam::Vec3,
    /// The lights as loaded, of the scene and the photon scene.
    rest_lights: (Vec<pm_scene::Light>, Option<Vec<pm_scene::Light>>),
    /// The incrementally updated photon grid (photon_search = grid), keyed by slot,
    /// with the paths' unscaled power.
    grid: Option<pm_kdtree::PhotonGrid<FullIrrPhoton>>,
    /// The frame's rasterised first hits.
    fragments: Vec<Option<pm_raster::Fragment>>,
    /// The image-space method's G-buffer and splat memory.
    ispm: ispm::IspmScratch,
    /// Whether caustic paths are traced (the image-space method asks the scene
    /// analysis once: "simulate only the effects a scene calls for").
    caustics: bool,
}

impl Live {
    /// A live renderer of `scene` drawn from its first camera; photons are traced in
    /// `photon_scene` (a simpler stand-in, section 4.4.1) or, without one, in the
    /// scene. Fails when the photon scene has no light with power or the scene no
    /// camera.
    pub fn new(scene: Scene, photon_scene: Option<Scene>, params: LiveParams, seed: u64) -> Result<Live, String> {
        params.check(pm_params::Naming::Cli)?;
        let camera = scene.camera.clone().ok_or("the scene has no perspective camera")?;
        let selector = LightSelector::new(photon_scene.as_ref().unwrap_or(&scene), &[]).map_err(|e| e.to_string())?;
        let trace = TraceConfig { pass: MapPass::Global, budget: Budget::Emitted(params.total as u64), seed, selector };
        let ring = RingBuffer::new(params.total as usize, params.max_level as usize);
        let corners = Corners::new(&scene, params.cornering);
        let caustics = params.method == Method::Ispm && pm_light::analyze(&scene).caustics.yes;
        let rest_lights = (scene.lights.clone(), photon_scene.as_ref().map(|p| p.lights.clone()));
        Ok(Live {
            scene,
            photon_scene,
            camera,
            params,
            seed,
            trace,
            targets: Vec::new(),
            ring,
            corners,
            frame: 0,
            previous: None,
            buffers: FrameBuffers::default(),
            light_offset: glam::Vec3::ZERO,
            rest_lights,
            grid: None,
            fragments: Vec::new(),
            ispm: ispm::IspmScratch::default(),
            caustics,
        })
    }

    /// The ring buffer.
    pub fn ring(&self) -> &RingBuffer {
        &self.ring
    }

    /// The corners.
    pub fn corners(&self) -> &Corners {
        &self.corners
    }

    /// Frames drawn so far.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Replace the scene photons are traced in (a light jumped); the buffer keeps
    /// its photons, which age out over the next total / per_frame frames.
    pub fn set_photon_scene(&mut self, photon_scene: Scene) -> Result<(), String> {
        self.trace.selector = LightSelector::new(&photon_scene, &[]).map_err(|e| e.to_string())?;
        self.rest_lights.1 = Some(photon_scene.lights.clone());
        self.photon_scene = Some(photon_scene);
        Ok(())
    }

    /// Move the animated lights and camera of both scenes to time `t` \[s\]: nothing
    /// is rebuilt, and the buffer's older photons age out as paths are re-shot.
    pub fn set_time(&mut self, t: f32) {
        self.scene.lights.clone_from(&self.rest_lights.0);
        self.scene.set_time(t);
        if let Some(p) = self.photon_scene.as_mut() {
            if let Some(rest) = &self.rest_lights.1 {
                p.lights.clone_from(rest);
            }
            p.set_time(t);
        }
        let offset = self.light_offset;
        for scene in std::iter::once(&mut self.scene).chain(self.photon_scene.as_mut()) {
            for l in &mut scene.lights {
                if let pm_scene::LightKind::Point { position, .. } | pm_scene::LightKind::Spot { position, .. } =
                    &mut l.kind
                {
                    *position += offset;
                }
            }
        }
        if let Some(c) = &self.scene.camera {
            self.camera = c.clone();
        }
        if self.scene.has_moving_meshes() {
            self.corners.follow(&self.scene);
        }
        // Moving emitters can change a light's power, and so its share of photons.
        if let Ok(selector) = LightSelector::new(self.photon_scene.as_ref().unwrap_or(&self.scene), &[]) {
            self.trace.selector = selector;
        }
    }

    /// The photons the estimates read this frame: the used slots (power scaled by
    /// the paths held), without the direct photons when direct light comes from rays.
    pub fn tree_photons(&self) -> Vec<FullIrrPhoton> {
        tree_photons(&self.ring, self.params.direct)
    }

    /// Move every point and spot light by `delta` \[m\] from the next [`Self::set_time`]
    /// on (on top of the animation).
    pub fn move_lights(&mut self, delta: glam::Vec3) {
        self.light_offset += delta;
    }

    /// The layers of the last frame drawn ("total", "direct", "caustic" (zero),
    /// "indirect", "specular"), row 0 at the top.
    pub fn frame_layers(&self) -> &FrameBuffers {
        &self.buffers
    }

    /// Shoot, balance, estimate and draw one frame (its image: [`Self::frame_layers`]).
    pub fn step(&mut self) -> Result<FrameStats, String> {
        self.advance(true)
    }

    /// Everything of [`Self::step`] that later frames depend on (shoot, photon
    /// search, corner estimates with their temporal filter), without drawing: a
    /// renderer that starts at frame N (one task of an animation split across
    /// machines) replays frames 0..N this way and then draws exactly what one run
    /// from frame 0 draws. The image-space method carries nothing between frames.
    pub fn skip(&mut self) -> Result<FrameStats, String> {
        self.advance(false)
    }

    fn advance(&mut self, draw: bool) -> Result<FrameStats, String> {
        let p = &self.params;
        if p.method == Method::Ispm && !draw {
            let stats = FrameStats { frame: self.frame, ..Default::default() };
            self.frame += 1;
            return Ok(stats);
        }
        if p.method == Method::Ispm {
            // The same seed every frame: a static light gives the same bounce map and
            // photons frame after frame (the paper's seeding by light and texel).
            let st = ispm::frame(
                &self.scene,
                &self.camera,
                p,
                self.seed,
                self.caustics,
                &mut self.buffers,
                &mut self.fragments,
                &mut self.ispm,
            )?;
            let times = FrameTimes { draw: st.times.wall, wall: st.times.wall, ..Default::default() };
            let stats = FrameStats {
                frame: self.frame,
                times,
                photons_in_tree: st.photons,
                samples: (p.width * p.height) as u64,
                ispm: Some(st),
                ..Default::default()
            };
            self.frame += 1;
            return Ok(stats);
        }
        let start = Instant::now();
        let t = Instant::now();
        let photons_in = self.photon_scene.as_ref().unwrap_or(&self.scene);
        let shot = self.ring.shoot(photons_in, &self.trace, &self.targets, p.per_frame as usize, p.distribution);
        let shoot = t.elapsed().as_secs_f64();
        let aspect = p.width as f32 / p.height as f32;
        let max_radius = p.max_radius_rel_diag * self.scene.bounds.diagonal();
        let film = Film { width: p.width, height: p.height, spp: 1, contrast: 0.0, seed: self.seed ^ self.frame };
        // The search structure (a kd-tree rebuilt over the used slots, or the grid
        // updated for the re-shot paths' slots only; the update is serial) and the
        // rasterised first hits of the frame, side by side.
        let (ring, grid, direct) = (&self.ring, &mut self.grid, p.direct);
        let update = || {
            let t = Instant::now();
            let records = match p.photon_search {
                PhotonSearch::Rebuild => pm_kdtree::balance(&tree_photons(ring, direct)),
                PhotonSearch::Grid => {
                    let (total, levels) = (ring.total(), ring.max_level());
                    let grid = grid.get_or_insert_with(|| pm_kdtree::PhotonGrid::new(max_radius, total * levels));
                    for &path in ring.last_paths() {
                        for level in 0..levels {
                            let photon = ring.slot(path, level).filter(|q| estimates_read(direct, q));
                            grid.set((path + level * total) as u32, photon.map(FullIrrPhoton::encode));
                        }
                    }
                    Vec::new()
                }
            };
            // The corners' k-nearest searches go through leaf buckets.
            let buckets = pm_kdtree::Buckets::new(&records);
            (records, buckets, t.elapsed().as_secs_f64())
        };
        let (scene, camera, fragments) = (&self.scene, &self.camera, &mut self.fragments);
        let raster = || {
            let t = Instant::now();
            if draw && p.draw == DrawMode::Raster {
                pm_raster::first_hits_into(scene, camera, film.size(), film.rect(), fragments);
            }
            t.elapsed().as_secs_f64()
        };
        let ((records, buckets, balance), raster) = rayon::join(update, raster);
        let t = Instant::now();
        let active = self.corners.active(&self.scene, &self.camera, aspect, p.back_face_culling, p.frustum_culling);
        let mut e = match &self.grid {
            Some(grid) if p.photon_search == PhotonSearch::Grid => {
                // The grid holds each path's unscaled power: scale the (linear) estimate.
                let held = self.ring.filled() as u64;
                let e = self.corners.irradiance(grid, &active, p.k, max_radius);
                e.into_iter().map(|v| pm_photon::scale_power(v, held)).collect()
            }
            _ => {
                self.corners.irradiance(&pm_kdtree::KdTree::with_buckets(&records, &buckets), &active, p.k, max_radius)
            }
        };
        let mut flicker = 0.0;
        if let Some((prev, was)) = &self.previous {
            let both: Vec<usize> = (0..e.len()).filter(|&c| active[c] && was[c]).collect();
            if p.temporal > 0.0 {
                for &c in &both {
                    e[c] = e[c] * (1.0 - p.temporal) + prev[c] * p.temporal;
                }
            }
            // Flicker of what is shown: this frame's (filtered) estimates against the last.
            let now: Vec<Rgb> = both.iter().map(|&c| e[c]).collect();
            let before: Vec<Rgb> = both.iter().map(|&c| prev[c]).collect();
            flicker = flicker_of(&now, &before);
        }
        let estimate = t.elapsed().as_secs_f64();
        if !draw {
            let stats = FrameStats { frame: self.frame, paths_shot: shot.paths, flicker, ..Default::default() };
            self.previous = Some((e, active));
            self.frame += 1;
            return Ok(stats);
        }
        let t = Instant::now();
        let maps = shadow_maps(&self.scene, p);
        let shading = LiveShading::new(&self.scene, &self.corners, &e, p, maps.as_ref()).map_err(|e| e.to_string())?;
        let visibility = match p.draw {
            DrawMode::Raster => Visibility::Fragments(&self.scene, &self.fragments),
            DrawMode::Rays => Visibility::Rays,
        };
        let (_, rs): (_, RenderStats) = pm_render::render_into(
            &self.camera,
            &film,
            film.rect(),
            &shading,
            false,
            visibility,
            &mut self.buffers,
            &|_, _| {},
        )?;
        // The rasteriser ran beside the photon update: its time counts as drawing.
        let draw = raster + t.elapsed().as_secs_f64();
        let stats = FrameStats {
            frame: self.frame,
            times: FrameTimes { shoot, balance, estimate, draw, wall: start.elapsed().as_secs_f64() },
            paths_shot: shot.paths,
            photon_rays: shot.rays,
            paths_held: self.ring.filled(),
            photons_in_tree: match &self.grid {
                Some(g) if p.photon_search == PhotonSearch::Grid => g.len(),
                _ => records.len(),
            },
            estimates: active.iter().filter(|&&a| a).count(),
            corners: self.corners.len(),
            samples: rs.samples,
            flicker,
            ispm: None,
        };
        self.previous = Some((e, active));
        self.frame += 1;
        Ok(stats)
    }
}
