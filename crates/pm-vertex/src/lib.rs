//! Real-time photon mapping by vertex estimates (Jozwowski 2002, "Real Time Photon
//! Mapping", sections 4 and 5): every frame re-shoots the oldest `per_frame` of
//! `total` photon paths into a ring buffer ([`RingBuffer`], section 4.1.1-4.1.2),
//! updates the photon search over the used slots, estimates irradiance at the
//! mesh's corners ([`Corners`], sections 4.1.3 and 4.4.2), and draws the mesh with
//! the corner radiance interpolated across each triangle (Gouraud) times the
//! reflectance, with direct light by shadow rays or shadow maps per pixel (sharp
//! shadows) or from the photons alone (as in the thesis).
//!
//! A [`pm_live::FrameMethod`]: `pm-live` runs the frames and shades the pixels. It
//! reuses the batch pipeline's pieces rather than forking them: the tracer's own
//! per-path streams (`pm_photon::trace_path`), the kd-tree, the k-nearest irradiance
//! estimate. Radiance is W sr^-1 m^-2 per RGB channel; photon power W; irradiance
//! W m^-2.

mod coverage;
mod mesh;
mod ring;
mod subdivide;

pub use coverage::{CoverageCache, MIN_COVERAGE, coverage};
pub use mesh::{Around, CornerSurroundings, Corners};
pub use ring::{Distribution, RingBuffer, ShootStats};
pub use subdivide::{AUTO_MAX_TRIANGLES, Subdivide, Subdivision, expected_radius, scenes};

use glam::Vec3;
use pm_color::Rgb;
use pm_format::{FullIrrPhoton, PhotonRecord, flags};
use pm_light::LightSelector;
use pm_live::{DirectMode, FrameParams, FrameRow, IndirectLight, LiveShading, World};
use pm_params::{Any, above, at_least, between};
use pm_photon::{Budget, MapPass, TraceConfig};
use pm_render::{FrameBuffers, Visibility, VolumePhotons};
use pm_scene::{Hit, Scene, Target};
use rayon::prelude::*;
use std::f32::consts::PI;
use std::time::Instant;

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
    /// The vertex method's parameters (Jozwowski 2002 sections 4.1 and 4.4):
    /// `photon-live`'s options and keys of pipeline.toml's `[live]` section.
    pub struct VertexParams {
        /// Photon paths re-shot every frame (the thesis: 100-2,000).
        per_frame: u32 = 2_000 => between(1, 1 << 24);
        /// Photon paths the ring buffer holds (the thesis: 2,000; at least per_frame).
        total: u32 = 20_000 => between(1, 1 << 24);
        /// Hits kept per path. The thesis finds 3 sufficient, but in a closed room
        /// (albedo about 0.7) 3 loses 28% of the light and 8 loses 7% against the
        /// batch pipeline (`cargo xtask live-study`, BENCHMARKS.md), for 5% more time;
        /// 16 took cornell_boxes' bias from 11.6% to 11.0% at no measurable frame
        /// time, and 32 bought nothing more (`cargo xtask tradeoff`, issue 36).
        max_level: u32 = 16 => between(1, 64);
        /// How far lights and meshes may have moved since a photon path was shot, in
        /// expected photon search radii ([`expected_radius`]), before the path is
        /// re-shot ahead of its turn. The thesis's buffer lets photons lag up to
        /// total / per_frame frames behind a moving light: on Blender's animated room
        /// at 24 fps (the lamp 13 cm a frame) that put the image 5-9% off in mean and
        /// its 8 x 8 blocks 8.5-13.7% RMS (with k = 200), against 0-1.2% and 3.7-5.8%
        /// with 0.5. 0: any move re-shoots every path; 1e9: the thesis's buffer. Where
        /// things move slowly (the thesis's room at 60 fps: 1.6 cm a frame) no path
        /// is re-shot early and frames keep their speed. The first frame fills the
        /// buffer (the thesis fills it over total / per_frame frames).
        max_lag_rel_radius: f32 = 0.5 => at_least(0.0);
        /// Which paths re-shot slots get: random, same-per-frame or same-over-total.
        distribution: Distribution = Distribution::SameOverTotal => Any;
        /// Photons per corner estimate. Each estimate's noise is about 1/sqrt(k), and
        /// neighbouring corners' noise shows as coloured blotches: on Blender's
        /// animated room (tests/scenes/blender_room, walls of two triangles) the 8 x 8
        /// blocks of frames 0, 12, 24 and 36 were 6.6-9.7% RMS off the path tracer
        /// with the thesis's 50 and 3.7-5.8% with 200. The automatic split makes fewer
        /// corners for the larger radius, so the estimates take less time (9 against
        /// 5 ms a frame there); the indirect light's mean bias grows by about 1%
        /// (cornell_boxes +1.8% at 100, +2.9% at 200; BENCHMARKS.md, issue 53).
        k: usize = 200 => between(1, 1 << 16);
        /// Divide each corner estimate by the part of its disc that lies on the
        /// surface (probed with rays once per corner and radius step), not the whole
        /// disc: corners on an edge of a surface otherwise read half the light, and
        /// corners of two edges a quarter (on cornell_boxes the indirect light was 10%
        /// dark in mean, 40-60% along the walls' edges).
        coverage: bool = true => Any;
        /// Largest estimate radius, as a fraction of the scene's bounding-box diagonal.
        max_radius_rel_diag: f32 = 0.1 => above(0.0);
        /// One estimate per shared corner (section 4.4.2) instead of one per triangle vertex.
        cornering: bool = true => Any;
        /// Skip corners of triangles facing away from the camera (one-sided materials).
        back_face_culling: bool = true => Any;
        /// Skip corners of triangles outside the view frustum.
        frustum_culling: bool = true => Any;
        /// Split the drawn triangles at edge midpoints until no edge is longer than
        /// this [m] (section 4.3: more corners, finer indirect light; photons are still
        /// traced in the unsplit scene); 0 leaves the mesh as it is; auto: the photon
        /// search radius the estimates can expect, sqrt(k A / (pi total)) for the
        /// scene's area A, within 200,000 triangles (the choice is printed).
        subdivide: Subdivide = Subdivide::Auto => Any;
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
    }
}

impl VertexParams {
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

/// What one vertex-method frame did: a row of frames.csv (times \[s\], the thesis's
/// Figures 21-27 split, and counts).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VertexFrame {
    /// Frame number (0 first).
    pub frame: u64,
    /// Shooting `per_frame` paths into the ring buffer \[s\].
    pub shoot_s: f64,
    /// Updating the photon search: the kd-tree rebuilt, or the grid updated \[s\].
    pub balance_s: f64,
    /// Corner culling and irradiance estimates \[s\].
    pub estimate_s: f64,
    /// Drawing the frame (rasterising or eye rays, interpolation, direct light) \[s\].
    pub draw_s: f64,
    /// The whole frame \[s\]. The rasteriser runs beside the photon update (the
    /// grid's update is serial and leaves a core free), so this is less than the sum.
    pub total_s: f64,
    /// Paths shot this frame.
    pub paths_shot: u64,
    /// Rays the photon paths traced.
    pub photon_rays: u64,
    /// Paths the buffer holds.
    pub paths_held: usize,
    /// Photons the estimates search (used slots that the estimates read).
    pub photons_in_tree: usize,
    /// Corner estimates made (active corners).
    pub estimates: usize,
    /// Corners in all.
    pub corners: usize,
    /// Eye samples drawn.
    pub samples: u64,
    /// Flicker: mean absolute change of corner irradiance since the previous frame
    /// over the mean irradiance, at corners active in both (0 at the first frame).
    pub flicker: f64,
}

impl FrameRow for VertexFrame {
    fn frame(&self) -> u64 {
        self.frame
    }

    fn wall_seconds(&self) -> f64 {
        self.total_s
    }
}

/// Irradiance at the corners [W m^-2 per channel], interpolated across each
/// triangle (Gouraud; perspective-correct, since eye rays and the rasteriser give
/// true barycentrics) and reflected by the diffuse albedo: the thesis's indirect
/// light (section 4.1.3).
pub struct CornerLight<'a> {
    /// The corners of the drawn mesh.
    pub corners: &'a Corners,
    /// Irradiance at each corner.
    pub e: &'a [Rgb],
    /// Each corner's surroundings ([`CornerSurroundings::around`]; `None` where
    /// not known, or none at all): a triangle with corners both under a cover and
    /// not interpolates, at each point, only the corners of the point's kind.
    pub around: &'a [Option<Around>],
    /// The cover distance \[m\] the corners were tested with.
    pub cover: f32,
    /// Per drawn triangle whether a wall stands between two of its corners
    /// ([`SplitTriangles`]; `None` where not known, taken as no).
    pub split: &'a [Option<bool>],
    /// The scene the points are tested in.
    pub scene: &'a Scene,
    /// The ring's photons scattered in media, for the light media scatter more
    /// than once (none without scattering media).
    pub volume: Option<&'a VolumePhotons>,
}

impl CornerLight<'_> {
    /// Irradiance at barycentrics `b` of triangle `tri`.
    pub fn irradiance_at(&self, tri: u32, b: [f32; 3]) -> Rgb {
        let (c, e) = (self.corners.tri[tri as usize], self.e);
        e[c[0] as usize] * b[0] + e[c[1] as usize] * b[1] + e[c[2] as usize] * b[2]
    }

    /// Irradiance at `hit`: [`Self::irradiance_at`], or on a triangle whose
    /// corners lie some under a cover and some not (the ceiling's triangles that
    /// reach under a lamp a few millimetres below it), the corners of the hit's
    /// kind alone, their barycentrics renormalised: the covered corners read the
    /// light trapped in the gap, and interpolated it onto the open ceiling beside
    /// the lamp (+30-75% in the 8 x 8 blocks there on issue 53's checker, seed
    /// 60606 scene 24). Likewise on a triangle with a wall between two of its
    /// corners ([`SplitTriangles`]), the corners in view of the hit alone: the
    /// floor's corners under a glass box standing on it read the light through
    /// the box, four times the floor around, and the triangles reaching under
    /// the box drew it round the box's foot (+40-70% in the blocks there, seed
    /// 12902 scene 17).
    pub fn irradiance_seen(&self, hit: &Hit) -> Rgb {
        let c = self.corners.tri[hit.tri as usize];
        let cover = c.map(|k| self.around.get(k as usize).copied().flatten().map(|a| a.covered));
        let mixed = cover.contains(&Some(true)) && cover.contains(&Some(false));
        let split = self.split.get(hit.tri as usize).copied().flatten() == Some(true);
        if !mixed && !split {
            return self.irradiance_at(hit.tri, hit.b);
        }
        let n = pm_scene::facing(hit.ng, self.corners.n[c[0] as usize]);
        let here = mixed.then(|| Some(self.scene.covered(hit.p, n, self.cover)));
        let lift = split_lift(&c.map(|k| self.corners.p[k as usize]));
        let (mut sum, mut w) = (Rgb::ZERO, 0.0);
        for k in 0..3 {
            let p = self.corners.p[c[k] as usize];
            if here.is_none_or(|h| cover[k] == h) && (!split || pm_render::in_view(self.scene, hit.p, n, p, lift)) {
                sum += self.e[c[k] as usize] * hit.b[k];
                w += hit.b[k];
            }
        }
        if w > 0.0 { sum / w } else { self.irradiance_at(hit.tri, hit.b) }
    }
}

/// The height \[m\] over a triangle (corners `p`) at which its corners and the
/// points on it must see each other ([`SplitTriangles`]): a tenth of its
/// longest edge.
fn split_lift(p: &[Vec3; 3]) -> f32 {
    0.1 * p[0].distance(p[1]).max(p[1].distance(p[2])).max(p[2].distance(p[0]))
}

/// Per drawn triangle whether a wall stands between two of its corners: one
/// corner out of [`pm_render::in_view`] of another at [`split_lift`] over the
/// triangle, in the photons' scene (a triangle of the floor reaching under a
/// box standing on it). Found once (three rays) when one of its corners is
/// first active, and kept until the meshes move.
#[derive(Clone, Debug, Default)]
pub struct SplitTriangles {
    split: Vec<Option<bool>>,
}

impl SplitTriangles {
    /// Forget every triangle's (the scene's meshes moved).
    pub fn clear(&mut self) {
        self.split.clear();
    }

    /// Per triangle whether it is split, where found (as the last
    /// [`Self::update`] left them).
    pub fn split(&self) -> &[Option<bool>] {
        &self.split
    }

    /// Find the triangles of `corners` with an `active` corner and none found yet.
    pub fn update(&mut self, scene: &Scene, corners: &Corners, active: &[bool]) {
        self.split.resize(corners.tri.len(), None);
        let todo: Vec<usize> = (0..corners.tri.len())
            .filter(|&t| self.split[t].is_none() && corners.tri[t].iter().any(|&c| active[c as usize]))
            .collect();
        let fresh: Vec<bool> = todo
            .par_iter()
            .with_min_len(64)
            .map(|&t| {
                let c = corners.tri[t];
                let p = c.map(|k| corners.p[k as usize]);
                let n = corners.n[c[0] as usize];
                let n = pm_scene::facing((p[1] - p[0]).cross(p[2] - p[0]).normalize_or(n), n);
                let lift = split_lift(&p);
                (0..3).any(|k| !pm_render::in_view(scene, p[k], n, p[(k + 1) % 3], lift))
            })
            .collect();
        for (&t, f) in todo.iter().zip(fresh) {
            self.split[t] = Some(f);
        }
    }
}

impl IndirectLight for CornerLight<'_> {
    const SPLATTED: bool = false;

    fn radiance(&self, hit: &Hit, bsdf: &pm_bsdf::Bsdf, wo: glam::Vec3) -> Rgb {
        bsdf.albedo(wo, hit.ns) * self.irradiance_seen(hit) / PI
    }

    /// The beam radiance estimate over the ring's volume photons, all but those
    /// scattered straight from a light (the frame takes those from the lights),
    /// as the batch pipeline's eye rays take it ([`pm_estimate::beam`], Jarosz,
    /// Zwicker and Jensen 2008). Without it the frames of issue 53's fog scenes
    /// had single scattering only, and their volume layer was 50-80% dark.
    fn scattered(&self, o: glam::Vec3, d: glam::Vec3, t: f32, m: &pm_scene::Medium) -> Rgb {
        self.volume.map_or(Rgb::ZERO, |v| v.scattered(o, d, t, m))
    }
}

/// True for the photons the corner estimates read: the surfaces' (not the
/// media's), all of them when direct light comes from photons, else all but the
/// direct ones (direct light is then computed per pixel).
fn estimates_read(direct: DirectMode, p: &pm_format::Photon) -> bool {
    p.flags & flags::VOLUME == 0 && (direct == DirectMode::Photons || p.flags & flags::DIRECT == 0)
}

/// The ring's photons scattered in media ([`flags::VOLUME`]) for the beam
/// estimate; `None` when it holds none.
fn volume_photons(ring: &RingBuffer, scene: &Scene, max_radius: f32) -> Option<VolumePhotons> {
    VolumePhotons::new(scene, ring.photons().iter().filter(|p| p.flags & flags::VOLUME != 0), max_radius)
}

/// The photons of `ring` the estimates read (see [`Vertex::tree_photons`]).
fn tree_photons(ring: &RingBuffer, direct: DirectMode) -> Vec<FullIrrPhoton> {
    ring.photons().iter().filter(|p| estimates_read(direct, p)).map(FullIrrPhoton::encode).collect()
}

/// Flicker of `now` against `before` (same corners): mean |now - before| over
/// mean(before), over channels; 0 when `before` is dark.
pub fn flicker_of(now: &[Rgb], before: &[Rgb]) -> f64 {
    let diff: f64 = now.iter().zip(before).map(|(a, b)| (*a - *b).abs().element_sum() as f64).sum();
    let base: f64 = before.iter().map(|b| b.element_sum() as f64).sum();
    if base > 0.0 { diff / base } else { 0.0 }
}

/// The vertex method's state between frames: the ring buffer, the corners and
/// their previous irradiance, the photon search.
pub struct Vertex {
    frame_params: FrameParams,
    params: VertexParams,
    seed: u64,
    trace: TraceConfig,
    targets: Vec<Target>,
    ring: RingBuffer,
    corners: Corners,
    /// The previous frame's corner irradiance, and which corners had one.
    previous: Option<(Vec<Rgb>, Vec<bool>)>,
    /// The incrementally updated photon grid (photon_search = grid), keyed by slot,
    /// with the paths' unscaled power.
    grid: Option<pm_kdtree::PhotonGrid<FullIrrPhoton>>,
    /// The frame's rasterised first hits.
    fragments: Vec<Option<pm_raster::Fragment>>,
    /// How [`live`] chose the drawn mesh.
    subdivision: Option<Subdivision>,
    /// The corners' disc coverages probed so far (`coverage`).
    coverage: CoverageCache,
    surroundings: CornerSurroundings,
    /// Which drawn triangles have a wall between their corners.
    split: SplitTriangles,
    /// The buffer's paths in the order they were shot, oldest first, as runs of
    /// paths shot under one pose of the photons' world.
    shot_under: std::collections::VecDeque<(usize, pm_live::PhotonPose)>,
    /// How far things may move before a path is re-shot early \[m\] (`max_lag_rel_radius`).
    max_lag: f32,
    /// The cover distance [m] ([`cover_distance`]).
    cover: f32,
}

/// The cover distance \[m\] of the vertex method's estimates in `scene`: a
/// surface point with another surface facing it from closer lies in a gap whose
/// light is its own ([`Around`]). Half the expected search radius, and at least
/// the batch pipeline's ([`pm_render::COVER_REL_DIAG`] of the diagonal): a gap
/// matters when it is thin against the disc that reaches across it, and the
/// vertex method's discs are large (0.26 m in a 2 m room at its defaults). With
/// the batch pipeline's 3.5 cm there, the ceiling above a lamp 4 cm below it was
/// open, and the light in the gap spread over the ceiling around it: +50-200% in
/// 8 x 8 blocks on issue 53's checker, seed 60606 scene 31.
pub fn cover_distance(scene: &Scene, params: &VertexParams) -> f32 {
    (0.5 * expected_radius(scene, params)).max(pm_render::COVER_REL_DIAG * scene.bounds.diagonal())
}

impl Vertex {
    /// The method over `world` (its corners are the drawn scene's, its photons
    /// traced in the photon scene). Fails when a parameter is out of range or the
    /// photon scene has no light with power.
    pub fn new(world: &World, frame_params: FrameParams, params: VertexParams, seed: u64) -> Result<Vertex, String> {
        frame_params.validate(pm_params::Naming::Cli)?;
        params.check(pm_params::Naming::Cli)?;
        let selector = LightSelector::new(world.photon_scene(), &[]).map_err(|e| e.to_string())?;
        // In scattering media the paths also keep where they scatter (the
        // progressive pass: the same paths, with the volume photons stored) for the
        // light media scatter more than once ([`CornerLight::volume`]).
        let media = frame_params.multiple_scattering && world.photon_scene().media.iter().any(|m| m.scatters());
        let pass = if media { MapPass::Progressive } else { MapPass::Global };
        let trace = TraceConfig { pass, budget: Budget::Emitted(params.total as u64), seed, selector };
        let cover = cover_distance(world.photon_scene(), &params);
        let mut ring = RingBuffer::new(params.total as usize, params.max_level as usize);
        ring.cover = cover;
        let corners = Corners::new(world.scene(), params.cornering);
        let max_lag = params.max_lag_rel_radius * expected_radius(world.photon_scene(), &params);
        Ok(Vertex {
            frame_params,
            params,
            seed,
            trace,
            targets: Vec::new(),
            ring,
            corners,
            previous: None,
            grid: None,
            fragments: Vec::new(),
            subdivision: None,
            coverage: CoverageCache::default(),
            surroundings: CornerSurroundings::default(),
            split: SplitTriangles::default(),
            shot_under: std::collections::VecDeque::new(),
            max_lag,
            cover,
        })
    }

    /// How the drawn mesh was chosen, when [`live`] made the method (`None` for a
    /// method made by [`Vertex::new`] over a world as given).
    pub fn subdivision(&self) -> Option<&Subdivision> {
        self.subdivision.as_ref()
    }

    /// The ring buffer.
    pub fn ring(&self) -> &RingBuffer {
        &self.ring
    }

    /// The corners.
    pub fn corners(&self) -> &Corners {
        &self.corners
    }

    /// The photons the estimates read this frame: the used slots (power scaled by
    /// the paths held), without the direct photons when direct light comes from rays.
    pub fn tree_photons(&self) -> Vec<FullIrrPhoton> {
        tree_photons(&self.ring, self.frame_params.direct)
    }

    /// The largest estimate radius in `world` \[m\].
    fn max_radius(&self, world: &World) -> f32 {
        self.params.max_radius_rel_diag * world.scene().bounds.diagonal()
    }

    /// Frame `frame`'s film (its pixel streams keyed by the seed and the frame).
    fn film(&self, frame: u64) -> pm_render::Film {
        self.frame_params.film(self.seed ^ frame)
    }

    /// Shoot and update the photon search, rasterising beside it when drawing:
    /// returns the shoot statistics, the search's records (empty for the grid) with
    /// their buckets, and the times of shooting, search and rasterising \[s\].
    fn shoot_and_search(
        &mut self,
        world: &World,
        frame: u64,
        draw: bool,
    ) -> (ShootStats, Vec<FullIrrPhoton>, pm_kdtree::Buckets, [f64; 3]) {
        let t = Instant::now();
        let paths = self.paths_to_shoot(world);
        let (p, f) = (&self.params, &self.frame_params);
        let shot = self.ring.shoot(world.photon_scene(), &self.trace, &self.targets, paths, p.distribution);
        let shoot = t.elapsed().as_secs_f64();
        let (max_radius, film) = (self.max_radius(world), self.film(frame));
        // The search structure (a kd-tree rebuilt over the used slots, or the grid
        // updated for the re-shot paths' slots only; the update is serial) and the
        // rasterised first hits of the frame, side by side.
        let (ring, grid, direct) = (&self.ring, &mut self.grid, f.direct);
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
        let (scene, camera, fragments) = (world.scene(), world.camera(), &mut self.fragments);
        let raster = || {
            let t = Instant::now();
            if draw && p.draw == DrawMode::Raster {
                pm_raster::first_hits_into(scene, camera, film.size(), film.rect(), fragments);
            }
            t.elapsed().as_secs_f64()
        };
        let ((records, buckets, balance), raster) = rayon::join(update, raster);
        (shot, records, buckets, [shoot, balance, raster])
    }

    /// How many of the oldest paths this frame re-shoots: per_frame, or every path
    /// up to the newest shot where lights or meshes were farther than `max_lag`
    /// from where they are now, or the whole buffer while it is not yet full;
    /// the runs of paths shot under each pose are updated to match.
    fn paths_to_shoot(&mut self, world: &World) -> usize {
        let total = self.ring.total();
        let now = world.photon_pose();
        let mut paths = if self.ring.filled() < total { total } else { (self.params.per_frame as usize).min(total) };
        let mut older = 0;
        for (n, pose) in &self.shot_under {
            older += n;
            if pose.distance(now) > self.max_lag {
                paths = paths.max(older);
            }
        }
        let mut left = paths;
        while left > 0 {
            let Some(front) = self.shot_under.front_mut() else { break };
            let take = front.0.min(left);
            front.0 -= take;
            left -= take;
            if front.0 == 0 {
                self.shot_under.pop_front();
            }
        }
        self.shot_under.push_back((paths, now.clone()));
        paths
    }

    /// Irradiance at the active corners from the photon search, through the
    /// temporal filter, with the flicker against the previous frame.
    fn estimate(
        &mut self,
        world: &World,
        records: &[FullIrrPhoton],
        buckets: &pm_kdtree::Buckets,
        active: &[bool],
    ) -> (Vec<Rgb>, f64) {
        let p = &self.params;
        let max_radius = self.max_radius(world);
        let around = self.surroundings.update(world.photon_scene(), &self.corners, active, (max_radius, self.cover));
        let scene = world.photon_scene();
        // The estimates of the corners `which`, counting only the photons in view
        // of each at its lift (`view`) or all it finds.
        let estimate = |which: &[bool], view: Option<&[f32]>| match &self.grid {
            Some(grid) if p.photon_search == PhotonSearch::Grid => {
                // The grid holds each path's unscaled power: scale the (linear) estimate.
                let held = self.ring.filled() as u64;
                let view = view.map(|lift| (scene, lift));
                let (e, r2) = self.corners.irradiance(grid, which, around, (p.k, max_radius), view);
                (e.into_iter().map(|v| pm_photon::scale_power(v, held)).collect::<Vec<_>>(), r2)
            }
            _ => {
                let tree = pm_kdtree::KdTree::with_buckets(records, buckets);
                self.corners.irradiance(&tree, which, around, (p.k, max_radius), view.map(|lift| (scene, lift)))
            }
        };
        let (mut e, r2) = estimate(active, None);
        if p.coverage {
            // Divide by the share of the disc the estimate counts; where part of
            // the disc is out of the corner's view, estimate again from the
            // photons in view only (the same k nearest, the same radius).
            let shares = self.coverage.shares(scene, &self.corners, active, (around, self.cover), &r2);
            let hidden: Vec<bool> = shares.iter().map(|s| s.is_some_and(|s| s.hidden())).collect();
            if hidden.contains(&true) {
                let lift: Vec<f32> = shares.iter().map(|s| s.map_or(0.0, |s| s.lift)).collect();
                let (seen, _) = estimate(&hidden, Some(&lift));
                for c in (0..e.len()).filter(|&c| hidden[c]) {
                    e[c] = seen[c];
                }
            }
            for (e, s) in e.iter_mut().zip(&shares) {
                if let Some(s) = s {
                    *e /= s.divisor();
                }
            }
        }
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
        (e, flicker)
    }
}

impl pm_live::FrameMethod for Vertex {
    type Row = VertexFrame;

    fn warm_up(&self) -> u64 {
        1
    }

    fn moved(&mut self, world: &World) {
        if world.scene().has_moving_meshes() {
            self.corners.follow(world.scene());
            self.coverage.clear();
            self.surroundings.clear();
            self.split.clear();
        }
        // Moving emitters can change a light's power, and so its share of photons.
        if let Ok(selector) = LightSelector::new(world.photon_scene(), &[]) {
            self.trace.selector = selector;
        }
    }

    fn frame(&mut self, world: &World, frame: u64, draw: bool, out: &mut FrameBuffers) -> Result<VertexFrame, String> {
        let start = Instant::now();
        let (shot, records, buckets, [shoot, balance, raster]) = self.shoot_and_search(world, frame, draw);
        let t = Instant::now();
        let (p, f) = (&self.params, &self.frame_params);
        let aspect = f.width as f32 / f.height as f32;
        let active = self.corners.active(world.scene(), world.camera(), aspect, p.back_face_culling, p.frustum_culling);
        let (e, flicker) = self.estimate(world, &records, &buckets, &active);
        let estimate = t.elapsed().as_secs_f64();
        if !draw {
            self.previous = Some((e, active));
            return Ok(VertexFrame { frame, paths_shot: shot.paths, flicker, ..Default::default() });
        }
        let t = Instant::now();
        self.split.update(world.photon_scene(), &self.corners, &active);
        let (p, f) = (&self.params, &self.frame_params);
        let maps = f.shadow_maps(world.scene());
        // Only paths traced in scattering media keep volume photons.
        let volume = (self.trace.pass == MapPass::Progressive)
            .then(|| volume_photons(&self.ring, world.photon_scene(), self.max_radius(world)))
            .flatten();
        let indirect = CornerLight {
            corners: &self.corners,
            e: &e,
            around: self.surroundings.around(),
            cover: self.cover,
            split: self.split.split(),
            scene: world.photon_scene(),
            volume: volume.as_ref(),
        };
        let shading =
            LiveShading::new(world.scene(), indirect, f.direct, f, maps.as_ref()).map_err(|e| e.to_string())?;
        let visibility = match p.draw {
            DrawMode::Raster => Visibility::Fragments(world.scene(), &self.fragments),
            DrawMode::Rays => Visibility::Rays,
        };
        let film = self.film(frame);
        let (_, rs) = pm_render::render_into(
            pm_render::Shot { camera: world.camera(), film: &film, rect: film.rect() },
            &shading,
            false,
            visibility,
            out,
            &|_, _| {},
        )?;
        // The rasteriser ran beside the photon update: its time counts as drawing.
        let draw_s = raster + t.elapsed().as_secs_f64();
        let row = VertexFrame {
            frame,
            shoot_s: shoot,
            balance_s: balance,
            estimate_s: estimate,
            draw_s,
            total_s: start.elapsed().as_secs_f64(),
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
        };
        self.previous = Some((e, active));
        Ok(row)
    }
}

/// A live renderer of `scene` by the vertex method, photons traced in
/// `photon_scene` (or the scene), on the scenes [`scenes`] makes: the drawn mesh
/// split as `params.subdivide` says ([`Vertex::subdivision`] tells how).
pub fn live(
    scene: Scene,
    photon_scene: Option<Scene>,
    frame_params: FrameParams,
    params: VertexParams,
    seed: u64,
) -> Result<pm_live::Live<Vertex>, String> {
    params.check(pm_params::Naming::Cli)?;
    let (drawn, photon_scene, subdivision) = scenes(scene, photon_scene, &params);
    let world = World::new(drawn, photon_scene)?;
    let mut method = Vertex::new(&world, frame_params, params, seed)?;
    method.subdivision = Some(subdivision);
    Ok(pm_live::Live::new(world, method))
}
