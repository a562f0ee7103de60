//! What the real-time methods share: the frame loop and its clock, the animated
//! world a frame is drawn in, the per-pixel shading of a frame (direct light by
//! shadow rays or shadow maps, mirrors and glass by ray tracing, indirect light
//! from the method), and the per-frame statistics file.
//!
//! A real-time method is a [`FrameMethod`]: "draw frame f of this world into these
//! buffers". Two exist, each in its own crate, neither knowing the other:
//! `pm-vertex` (Jozwowski 2002: a ring buffer of photon paths, irradiance at mesh
//! vertices) and `pm-ispm` (McGuire and Luebke 2009: bounce maps, photon volumes
//! splatted over the eye's G-buffer). [`Live`] runs either over a [`World`]: it
//! moves lights and camera to each frame's time and keeps the drawing's memory.
//!
//! Radiance is W sr^-1 m^-2 per RGB channel; power W; irradiance W m^-2. This crate
//! does no I/O: a frame is an in-memory image and a row of statistics.

mod shade;

pub use shade::{IndirectLight, LiveShading};

use pm_params::{Any, above, at_least, between};
use pm_render::{Film, FrameBuffers};
use pm_scene::{Camera, Light, LightKind, Scene};

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
        /// The photons' estimate, like indirect light (the vertex method: at the
        /// corners, as in the thesis; the image-space method takes shadow rays).
        Photons,
    }
}

pm_params::params! {
    /// What every real-time method's frames share: their size, clock, exposure and
    /// how they take direct light (`photon-live`'s options and keys of pipeline.toml's
    /// `[live]` section).
    pub struct FrameParams {
        /// Direct light by shadow rays per pixel (rays), shadow maps (shadow-map) or
        /// from the photons (photons).
        direct: DirectMode = DirectMode::Rays => Any;
        /// Texels per side of each face of a cube shadow map (direct = shadow-map).
        shadow_map_res: u32 = 256 => between(16, 8192);
        /// Light samples per pixel for direct light by rays.
        light_samples: u32 = 1 => between(1, 1 << 10);
        /// Depth limit of mirror and glass recursion when drawing.
        max_depth: u32 = 8 => between(0, 1000);
        /// Frame width [pixels].
        width: u32 = 512 => between(1, 16384);
        /// Frame height [pixels].
        height: u32 = 512 => between(1, 16384);
        /// Frames per second of animation time (frame f shows time f / fps) [1/s].
        fps: f32 = 60.0 => above(0.0);
        /// Exposure of the PNG frames in stops.
        exposure: f32 = 0.0 => at_least(-64.0);
        /// In scattering media, add the beam estimate of the points where the
        /// frame's photons scattered along eye rays (light scattered more than
        /// once); off: single scattering alone (the photons scatter in the media
        /// either way, so the light fog scatters onto surfaces is there). On the
        /// checker's fog room (seed 77777, scene 35) the volume layer is within 2%
        /// of the path tracer with it (both methods) and 65% dark without; a 256 x
        /// 256 frame of it takes 296 against 37 ms by the vertex method, and of
        /// cornell_fog 662-690 against 208-224 ms by image-space photon mapping
        /// (BENCHMARKS.md, issue 53). Scenes without scattering media are not
        /// affected.
        multiple_scattering: bool = true => Any;
    }
}

impl FrameParams {
    /// The film of a frame: one sample a pixel at its centre, streams from `seed`.
    pub fn film(&self, seed: u64) -> Film {
        Film { width: self.width, height: self.height, spp: 1, contrast: 0.0, seed, pixel_centres: false }
    }

    /// The shadow maps of `scene`'s lights when direct light comes from shadow maps
    /// and every light can have one (see [`pm_light::ShadowMaps`]); none otherwise.
    pub fn shadow_maps(&self, scene: &Scene) -> Option<pm_light::ShadowMaps> {
        if self.direct != DirectMode::ShadowMap {
            return None;
        }
        pm_light::ShadowMaps::new(scene, self.shadow_map_res)
    }
}

/// Why `--direct shadow-map` draws every light of `scene` with shadow rays, if it
/// does: the lights that cannot have a shadow map (directional lights; area lights
/// that are large, curved, two-sided or textured), by name, or the scene's media
/// ([`pm_light::ShadowMaps::scene_supports`]).
pub fn why_no_shadow_maps(scene: &Scene) -> Option<String> {
    if !pm_light::ShadowMaps::scene_supports(scene) {
        return Some("the scene has media or index-matched boundaries, which a depth map cannot see through".into());
    }
    let without: Vec<String> =
        scene.lights.iter().filter(|l| !pm_light::ShadowMaps::supports(l)).map(|l| l.name.clone()).collect();
    (!without.is_empty()).then(|| {
        format!(
            "no shadow map for {} (directional, or an area light that is large, curved, two-sided or textured)",
            without.join(", ")
        )
    })
}

/// The animated world frames are drawn in: the scene, a simpler scene to trace
/// photons in (Jozwowski 2002 section 4.4.1), the camera, and lights moved by hand
/// on top of the animation.
pub struct World {
    scene: Scene,
    /// A simpler scene to trace photons in, or none (the scene).
    photon_scene: Option<Scene>,
    camera: Camera,
    /// The lights as loaded, of the scene and the photon scene.
    rest_lights: (Vec<Light>, Option<Vec<Light>>),
    /// Added to every point and spot light's position after the animation (the
    /// interactive window moves lights with it) [m].
    light_offset: glam::Vec3,
    /// Where the photon scene's lights and moving meshes are now ([`World::photon_pose`]).
    photon_pose: PhotonPose,
}

/// Where a scene's lights and moving meshes are and what the lights emit: photons
/// traced under one pose show the scene under another as far as
/// [`PhotonPose::distance`] says.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotonPose {
    /// Per light: position \[m\], unit direction (zero where a kind has neither) and
    /// power \[W per channel\].
    lights: Vec<[glam::Vec3; 3]>,
    /// The corners of the triangles the animation moves \[m\].
    triangles: Vec<[glam::Vec3; 3]>,
    /// The scene's bounding-box diagonal \[m\]: how far a turn of a light's
    /// direction or a change of its power counts.
    diagonal: f32,
}

impl PhotonPose {
    fn of(scene: &Scene) -> PhotonPose {
        let zero = glam::Vec3::ZERO;
        let lights = scene
            .lights
            .iter()
            .map(|l| {
                let (p, d) = match &l.kind {
                    LightKind::Point { position, .. } => (*position, zero),
                    LightKind::Spot { position, direction, .. } => (*position, *direction),
                    LightKind::Directional { direction, .. } => (zero, *direction),
                    LightKind::Area { .. } | LightKind::Environment { .. } => (zero, zero),
                };
                [p, d, l.power]
            })
            .collect();
        let triangles = scene.moving_triangles().map(|t| t.p).collect();
        PhotonPose { lights, triangles, diagonal: scene.bounds.diagonal() }
    }

    /// How far apart two poses are \[m\]: the farthest any light or mesh corner
    /// moved, a light's turn counted as the chord its direction sweeps at the
    /// scene's diagonal and a change of its power as that fraction of the diagonal;
    /// infinite between poses of scenes with other lights or meshes. (A replaced
    /// photon scene with the same lights and meshes, where a light jumped, is
    /// as far as the jump.)
    pub fn distance(&self, other: &PhotonPose) -> f32 {
        if self.lights.len() != other.lights.len() || self.triangles.len() != other.triangles.len() {
            return f32::INFINITY;
        }
        let mut d = 0.0f32;
        for (a, b) in self.lights.iter().zip(&other.lights) {
            let power = (a[2] - b[2]).abs().max_element() / a[2].max(b[2]).max_element().max(f32::MIN_POSITIVE);
            d = d.max((a[0] - b[0]).length()).max((a[1] - b[1]).length() * self.diagonal).max(power * self.diagonal);
        }
        for (a, b) in self.triangles.iter().zip(&other.triangles) {
            for k in 0..3 {
                d = d.max((a[k] - b[k]).length());
            }
        }
        if d.is_nan() { f32::INFINITY } else { d }
    }
}

impl World {
    /// `scene` seen from its first camera, photons traced in `photon_scene` or,
    /// without one, in the scene. Fails when the scene has no camera.
    pub fn new(scene: Scene, photon_scene: Option<Scene>) -> Result<World, String> {
        let camera = scene.camera.clone().ok_or("the scene has no perspective camera")?;
        let rest_lights = (scene.lights.clone(), photon_scene.as_ref().map(|p| p.lights.clone()));
        let photon_pose = PhotonPose::of(photon_scene.as_ref().unwrap_or(&scene));
        Ok(World { scene, photon_scene, camera, rest_lights, light_offset: glam::Vec3::ZERO, photon_pose })
    }

    /// Where the photon scene's lights and moving meshes are now. (The camera
    /// moving changes nothing photons see.)
    pub fn photon_pose(&self) -> &PhotonPose {
        &self.photon_pose
    }

    /// The scene drawn.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The scene photons are traced in: the photon scene, or the scene.
    pub fn photon_scene(&self) -> &Scene {
        self.photon_scene.as_ref().unwrap_or(&self.scene)
    }

    /// The camera at the current time.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Replace the scene photons are traced in (a light jumped).
    fn set_photon_scene(&mut self, photon_scene: Scene) {
        self.rest_lights.1 = Some(photon_scene.lights.clone());
        self.photon_scene = Some(photon_scene);
        self.photon_pose = PhotonPose::of(self.photon_scene());
    }

    /// Move the animated lights, meshes and camera of both scenes to time `t` \[s\],
    /// then every point and spot light by the hand-made offset.
    fn set_time(&mut self, t: f32) {
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
                if let LightKind::Point { position, .. } | LightKind::Spot { position, .. } = &mut l.kind {
                    *position += offset;
                }
            }
        }
        if let Some(c) = &self.scene.camera {
            self.camera = c.clone();
        }
        self.photon_pose = PhotonPose::of(self.photon_scene());
    }
}

/// One row of a real-time run's `frames.csv`: what one frame did. Each method has
/// its own row; its field names are the file's columns, so the file is written and
/// read through the one type ([`rows_to_csv`], [`rows_from_csv`]).
pub trait FrameRow: serde::Serialize + serde::de::DeserializeOwned + Default + Clone + std::fmt::Debug {
    /// The frame's number (0 first).
    fn frame(&self) -> u64;
    /// The frame's wall time \[s\] (the `total_s` column).
    fn wall_seconds(&self) -> f64;
}

/// A real-time method: draws frame f of a [`World`] into a frame's buffers.
pub trait FrameMethod {
    /// What one frame did.
    type Row: FrameRow;

    /// Frames before the frame time settles (the vertex method's first frame fills
    /// its ring buffer; the image-space method needs none).
    fn warm_up(&self) -> u64;

    /// The world moved to another time, or its photon scene was replaced: lights,
    /// meshes and camera may have moved.
    fn moved(&mut self, world: &World);

    /// Frame `frame` of `world` into `out` (layers total, direct, caustic, indirect,
    /// specular; row 0 at the top). Without `draw`, only what later frames depend on:
    /// a renderer that starts at frame N (one task of an animation split across
    /// machines) replays frames 0..N this way and then draws exactly what one run
    /// from frame 0 draws.
    fn frame(&mut self, world: &World, frame: u64, draw: bool, out: &mut FrameBuffers) -> Result<Self::Row, String>;
}

/// A real-time renderer's state between frames: the world, the method, the frame
/// clock and the drawing's memory.
pub struct Live<M> {
    world: World,
    method: M,
    frame: u64,
    buffers: FrameBuffers,
}

impl<M: FrameMethod> Live<M> {
    /// Frames of `world` drawn by `method`, from frame 0.
    pub fn new(world: World, method: M) -> Live<M> {
        Live { world, method, frame: 0, buffers: FrameBuffers::default() }
    }

    /// The world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The method.
    pub fn method(&self) -> &M {
        &self.method
    }

    /// Frames drawn or skipped so far.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// The layers of the last frame drawn ("total", "direct", "caustic", "indirect",
    /// "specular"), row 0 at the top.
    pub fn frame_layers(&self) -> &FrameBuffers {
        &self.buffers
    }

    /// Move the animated lights, meshes and camera to time `t` \[s\]: nothing is
    /// rebuilt; the method follows (the vertex method's older photons age out as
    /// its paths are re-shot).
    pub fn set_time(&mut self, t: f32) {
        self.world.set_time(t);
        self.method.moved(&self.world);
    }

    /// Move every point and spot light by `delta` \[m\] from the next
    /// [`Self::set_time`] on (on top of the animation).
    pub fn move_lights(&mut self, delta: glam::Vec3) {
        self.world.light_offset += delta;
    }

    /// Replace the scene photons are traced in (a light jumped). Fails when it has
    /// no light with power.
    pub fn set_photon_scene(&mut self, photon_scene: Scene) -> Result<(), String> {
        pm_light::LightSelector::new(&photon_scene, &[]).map_err(|e| e.to_string())?;
        self.world.set_photon_scene(photon_scene);
        self.method.moved(&self.world);
        Ok(())
    }

    /// Draw the next frame (its image: [`Self::frame_layers`]).
    pub fn step(&mut self) -> Result<M::Row, String> {
        self.advance(true)
    }

    /// Advance over the next frame without drawing it (see [`FrameMethod::frame`]).
    pub fn skip(&mut self) -> Result<M::Row, String> {
        self.advance(false)
    }

    fn advance(&mut self, draw: bool) -> Result<M::Row, String> {
        let row = self.method.frame(&self.world, self.frame, draw, &mut self.buffers)?;
        self.frame += 1;
        Ok(row)
    }
}

/// Mean wall time \[s\] of the frames from `warm_up` on (0 when there are none).
pub fn mean_frame_seconds<R: FrameRow>(rows: &[R], warm_up: u64) -> f64 {
    let warm: Vec<f64> = rows.iter().filter(|r| r.frame() >= warm_up).map(R::wall_seconds).collect();
    if warm.is_empty() { 0.0 } else { warm.iter().sum::<f64>() / warm.len() as f64 }
}

/// `rows` as CSV: a header of the row's field names, then a line per row. Zero rows
/// still give the header, so a part of an animation that drew nothing joins cleanly.
pub fn rows_to_csv<R: FrameRow>(rows: &[R]) -> Result<String, String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in rows {
        w.serialize(r).map_err(|e| e.to_string())?;
    }
    if rows.is_empty() {
        w.serialize(R::default()).map_err(|e| e.to_string())?;
    }
    let bytes = w.into_inner().map_err(|e| e.to_string())?;
    let text = String::from_utf8(bytes).map_err(|e| e.to_string())?;
    Ok(match rows.is_empty() {
        true => text.lines().next().map(|h| format!("{h}\n")).unwrap_or_default(),
        false => text,
    })
}

/// The rows of a CSV that [`rows_to_csv`] wrote; an error names the line.
pub fn rows_from_csv<R: FrameRow>(text: &str) -> Result<Vec<R>, String> {
    let mut r = csv::Reader::from_reader(text.as_bytes());
    r.deserialize().enumerate().map(|(i, row)| row.map_err(|e| format!("line {}: {e}", i + 2))).collect()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Row {
        frame: u64,
        total_s: f64,
        count: usize,
    }

    impl FrameRow for Row {
        fn frame(&self) -> u64 {
            self.frame
        }
        fn wall_seconds(&self) -> f64 {
            self.total_s
        }
    }

    /// Rows go through the file and back unchanged (floats to the bit), zero rows
    /// give the header alone, a malformed line is refused naming it, and the mean
    /// frame time leaves out the warm-up.
    #[test]
    fn frame_rows_round_trip_through_csv() {
        let rows = vec![Row { frame: 0, total_s: 0.1 + 0.2, count: 3 }, Row { frame: 1, total_s: 1e-9, count: 0 }];
        let text = rows_to_csv(&rows).unwrap();
        assert!(text.starts_with("frame,total_s,count\n"), "{text}");
        assert_eq!(rows_from_csv::<Row>(&text).unwrap(), rows);
        assert_eq!(rows_to_csv::<Row>(&[]).unwrap(), "frame,total_s,count\n");
        assert!(rows_from_csv::<Row>(&rows_to_csv::<Row>(&[]).unwrap()).unwrap().is_empty());
        let e = rows_from_csv::<Row>("frame,total_s,count\n0,0.5,1\n1,x,2\n").unwrap_err();
        assert!(e.starts_with("line 3:"), "{e}");
        assert_eq!(mean_frame_seconds(&rows, 1), 1e-9);
        assert_eq!(mean_frame_seconds(&rows, 2), 0.0);
    }

    /// Frame k of n covers the animation without gap or overlap.
    #[test]
    fn task_frames_partition_the_animation() {
        for (frames, n) in [(10, 3), (2, 5), (60, 4)] {
            let runs: Vec<_> = (0..n).map(|k| task_frames(k, n, frames)).collect();
            assert_eq!(runs[0].start, 0);
            assert_eq!(runs[n as usize - 1].end, frames);
            assert!(runs.windows(2).all(|w| w[0].end == w[1].start));
        }
    }
}
