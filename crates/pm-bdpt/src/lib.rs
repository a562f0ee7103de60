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
//! strategies that could have made the same path, from the densities of
//! generating each vertex from either side (Veach 1997, section 10.2; the ratio
//! recursion of pbrt-v3's `MISWeight`): each vertex keeps its forward and reverse
//! densities in area measure, and the weight is 1 / (1 + sum r_i^2) over the
//! density ratios r_i of the other strategies. A path of one segment (an emitter
//! seen directly) has only the strategy s = 0, t = 2.
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
//! through media and index-matched boundaries. The MIS densities leave out the
//! distance sampling, as pbrt-v3's volumetric BDPT does: the weights still add
//! up to one for every path, so the estimate stays unbiased.
//!
//! Lights at infinity (an environment, suns) start no light subpath: the eye
//! subpaths find them by the path tracer's two strategies, leaving the scene
//! and sampling them at each vertex, weighed by the power heuristic. Their
//! light through glass (a sky's caustics) is then the path tracer's to find.

use glam::Vec3;
use pm_bsdf::{Bsdf, HenyeyGreenstein};
use pm_color::{Layer, Rgb};
use pm_light::LightSelector;
use pm_render::{Image, View, pixel_salt};
use pm_sampling::Sampler;
use pm_scene::{Camera, CameraRays, EmitterPoint, Flights, FreeFlight, LightKind, MediumId, Scene};
use rayon::prelude::*;

use pm_params::between;

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

/// Salt of the light subpaths' streams (an eye subpath's is `pixel_salt`).
const LIGHT_SALT: u64 = 0x6c69_6768_7400;

/// Pixels a parallel work item traces (and whose splats it keeps in order).
const CHUNK: usize = 256;

/// Strategies (s, t) with s and t below this are tallied apart when asked.
pub const TALLY: usize = 12;

/// The layers a pass fills ([`Layer::ALL`]'s order).
const LAYERS: usize = 5;

/// What a vertex is.
#[derive(Clone, Copy, Debug)]
enum Kind {
    /// The pinhole.
    Camera,
    /// A light subpath's start: light `light`'s point `q`.
    Light { light: u32, q: EmitterPoint },
    /// A surface: its BSDF, and for an eye vertex on an emitter what it emits
    /// toward `wo`, its light and the point as that light would have picked it.
    Surface { bsdf: Bsdf, le: Rgb, emitter: Option<(u32, EmitterPoint)> },
    /// A scattering event in a medium, with the medium's phase function.
    Medium { phase: HenyeyGreenstein },
}

/// A vertex of a subpath, with the densities of generating it from either side
/// in area measure [m^-2] (zero after a delta lobe: no strategy can connect
/// there, and the ratios skip them).
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
    /// Density of this vertex given its subpath's previous one.
    pdf_fwd: f32,
    /// Density of this vertex given the next one, as the other side would make it.
    pdf_rev: f32,
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

    /// |cos| between unit `w` and the geometric normal; 1 where there is no
    /// surface (a point in a medium, a point light).
    fn cos_at(&self, w: Vec3) -> f32 {
        if self.ng == Vec3::ZERO { 1.0 } else { self.ng.dot(w).abs() }
    }

    /// The medium a ray leaving along `w` starts in.
    fn medium_toward(&self, w: Vec3) -> Option<MediumId> {
        self.media[(w.dot(self.ng) < 0.0) as usize]
    }

    /// The area density at `to` of a direction from this vertex with solid-angle
    /// density `pdf` [sr^-1] (the cosine at `to` is 1 where it has no surface).
    fn area_density(&self, pdf: f32, to: &Vertex) -> f32 {
        let v = to.p - self.p;
        let d2 = v.length_squared();
        if !(d2 > 0.0) {
            return 0.0;
        }
        let cos = if to.ng == Vec3::ZERO { 1.0 } else { to.ng.dot(v).abs() / d2.sqrt() };
        pdf * cos / d2
    }

    /// The density [sr^-1] of sampling `wi` given `wo`: the BSDF's at a surface,
    /// the phase function's in a medium.
    fn pdf_dir(&self, wo: Vec3, wi: Vec3) -> f32 {
        match &self.kind {
            Kind::Surface { bsdf, .. } => bsdf.pdf(wo, wi, self.ns),
            Kind::Medium { phase } => phase.p(wo, wi),
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
            Kind::Medium { phase } => return Rgb::splat(phase.p(toward_eye, toward_light)),
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
/// throughput so far, the direction's density at the subpath's last vertex
/// [sr^-1] and the medium the ray starts in.
struct Leaving {
    o: Vec3,
    d: Vec3,
    beta: Rgb,
    pdf: f32,
    medium: Option<MediumId>,
}

/// How a random walk ended: cut by the vertex limit, and (eye subpaths) what it
/// found leaving the scene, weighed [W sr^-1 m^-2].
struct Walked {
    cut: bool,
    escaped: Rgb,
}

/// One splatted light-tracing contribution: the pixel, the layer, the value.
type Splat = (u32, u8, Rgb);

/// What a chunk of a pass's pixels made.
struct Chunk {
    /// Its first pixel.
    start: usize,
    /// What landed on each of its pixels, by layer.
    pixels: Vec<[Rgb; LAYERS]>,
    /// Light tracing's splats, in the order they were made.
    splats: Vec<Splat>,
    /// Subpaths cut by the vertex limit.
    cut: u64,
    /// Per strategy, when tallied (see [`Bdpt::tally_strategies`]).
    tally: Vec<[f64; 2]>,
}

/// A bidirectional path tracer's state: its passes and the image so far.
pub struct Bdpt<'a> {
    scene: &'a Scene,
    /// The choice among the lights that light subpaths start from (every light
    /// but those at infinity), by power; none when all are at infinity.
    lights: Option<LightSelector>,
    /// The choice among the lights at infinity (an environment, suns), by power,
    /// for the eye subpaths' samples of them; none when there are none.
    sky: Option<LightSelector>,
    lens: Lens,
    /// The medium the pinhole is in.
    eye_medium: Option<MediumId>,
    width: u32,
    height: u32,
    seed: u64,
    params: BdptParams,
    passes: u32,
    /// Per pixel, the sum over passes of each surface layer's radiance.
    sum: Vec<[Rgb; LAYERS]>,
    /// Per pixel, the sums over passes of the pass's mean radiance and its square
    /// (for the noise estimate).
    l_sum: Vec<f32>,
    l_sq: Vec<f32>,
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
        let all = LightSelector::new(scene, &[]).map_err(|e| e.to_string())?;
        let at_infinity: Vec<usize> = (0..scene.lights.len()).filter(|&i| at_infinity(&scene.lights[i])).collect();
        let finite: Vec<usize> = (0..scene.lights.len()).filter(|i| !at_infinity.contains(i)).collect();
        let n = width as usize * height as usize;
        Ok(Bdpt {
            scene,
            lights: all.excluding(&at_infinity),
            sky: all.excluding(&finite),
            lens: Lens::new(camera, width, height),
            eye_medium: scene.eye_medium(camera.position),
            width,
            height,
            seed,
            params,
            passes: 0,
            sum: vec![[Rgb::ZERO; LAYERS]; n],
            l_sum: vec![0.0; n],
            l_sq: vec![0.0; n],
            cut: 0,
            tally: Vec::new(),
        })
    }

    /// Passes done.
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// The settings that shape the state, as "name=value" words (the state file's
    /// key: a state made with other settings is refused).
    pub fn key(&self) -> String {
        format!(
            "method=bdpt width={} height={} seed={} bdpt_max_vertices={}",
            self.width, self.height, self.seed, self.params.bdpt_max_vertices
        )
    }

    /// The state as its file holds it.
    pub fn to_file(&self) -> pm_format::PassStateFile {
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
            scene_hash: self.scene.content_hash,
            params: self.key(),
            records,
        }
    }

    /// Continue from a state file's passes: refused when it was made from another
    /// scene, for another image size or with other settings (naming the first
    /// that differs), or holds more passes than `most`.
    pub fn resume(&mut self, file: &pm_format::PassStateFile, most: u32) -> Result<(), String> {
        if (file.width, file.height) != (self.width, self.height) {
            return Err(format!(
                "a state of a {}x{} image, this render is {}x{}",
                file.width, file.height, self.width, self.height
            ));
        }
        if file.scene_hash != self.scene.content_hash {
            return Err("made from another scene".into());
        }
        if let Some((had, has)) = pm_format::key_difference(&file.params, &self.key()) {
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
        let per = self.passes.max(1) as f64 * self.width as f64 * self.height as f64;
        (0..TALLY * TALLY)
            .filter(|&i| self.tally.get(i).is_some_and(|v| v[0] != 0.0))
            .map(|i| ((i / TALLY, i % TALLY), self.tally[i][0] / per, self.tally[i][1] / per))
            .collect()
    }

    /// Subpaths cut by the vertex limit so far.
    pub fn cut_paths(&self) -> u64 {
        self.cut
    }

    /// One pass: an eye and a light subpath per pixel, every strategy joined.
    pub fn pass(&mut self) {
        let n = self.width as usize * self.height as usize;
        let k = self.passes;
        let tallying = !self.tally.is_empty();
        let chunks: Vec<Chunk> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let range = c * CHUNK..((c + 1) * CHUNK).min(n);
                let mut out = Chunk {
                    start: range.start,
                    pixels: vec![[Rgb::ZERO; LAYERS]; range.len()],
                    splats: Vec::new(),
                    cut: 0,
                    tally: if tallying { vec![[0.0; 2]; TALLY * TALLY] } else { Vec::new() },
                };
                let mut paths = (Vec::new(), Vec::new());
                for i in range {
                    self.sample(i, k, &mut paths, &mut out);
                }
                out
            })
            .collect();
        let mut pass = Vec::with_capacity(n);
        for c in &chunks {
            pass.extend_from_slice(&c.pixels);
            self.cut += c.cut;
            for (a, b) in self.tally.iter_mut().zip(&c.tally) {
                a[0] += b[0];
                a[1] += b[1];
            }
        }
        for c in &chunks {
            for &(px, layer, v) in &c.splats {
                pass[px as usize][layer as usize] += v;
            }
        }
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

    /// Each pixel's variance of its mean over the passes so far [(W sr^-1 m^-2)^2],
    /// from the passes' spread; none before two passes.
    pub fn variances(&self) -> Option<Vec<f32>> {
        (self.passes >= 2).then(|| {
            self.l_sum.iter().zip(&self.l_sq).map(|(&s, &q)| pm_render::variance_of_mean(s, q, self.passes)).collect()
        })
    }

    /// The image after the passes done, by layer.
    pub fn image(&self) -> Image {
        self.region_image(pm_raster::Rect::full(self.width, self.height))
    }

    /// The image of `rect` after the passes done.
    pub fn region_image(&self, rect: pm_raster::Rect) -> Image {
        let p = self.passes.max(1) as f32;
        let pixels: Vec<[Rgb; LAYERS]> = (rect.y0..rect.y1)
            .flat_map(|y| (rect.x0..rect.x1).map(move |x| (x, y)))
            .map(|(x, y)| self.sum[(y * self.width + x) as usize].map(|v| v / p))
            .collect();
        let layer = |l: usize| pixels.iter().map(|px| px[l]).collect::<Vec<Rgb>>();
        Image {
            rect,
            width: rect.x1 - rect.x0,
            height: rect.y1 - rect.y0,
            total: pixels.iter().map(|px| px.iter().copied().sum()).collect(),
            // Only a scene with a scattering medium has a volume layer.
            layers: [
                layer(0),
                layer(1),
                layer(2),
                layer(3),
                if self.scene.has_scattering_media() { layer(4) } else { Vec::new() },
            ],
            gbuffer: None,
        }
    }

    /// Pixel `i`'s sample of pass `k` into `out`: its eye and light subpaths
    /// (kept in `paths` between samples) joined in every way; what lands on the
    /// pixel goes to its entry, light tracing's splats to the chunk's list.
    fn sample(&self, i: usize, k: u32, paths: &mut (Vec<Vertex>, Vec<Vertex>), out: &mut Chunk) {
        let (eye, light) = paths;
        let (w, h) = (self.width as usize, self.height as usize);
        let mut se = Sampler::salted(self.seed, pixel_salt(i), k as u64);
        let j = se.next_2d();
        let d = self.lens.rays.direction(((i % w) as f32 + j.x) / w as f32, ((i / w) as f32 + j.y) / h as f32);
        let walked = self.eye_subpath(d, &mut se, eye);
        out.cut += walked.cut as u64;
        if walked.escaped.max_element() > 0.0 {
            out.pixels[i - out.start][layer_of(eye, &[], 0, eye.len() + 1)] += walked.escaped;
        }
        let mut sl = Sampler::salted(self.seed, LIGHT_SALT ^ i as u64, k as u64);
        out.cut += self.light_subpath(&mut sl, light) as u64;
        // s = 1 picks its own light point, so it is tried even when the light
        // subpath did not start.
        for t in 1..=eye.len() {
            for s in 0..=light.len().max(1) {
                if s + t < 2 || (s == 1 && t == 1) {
                    continue;
                }
                if s == 0 && t >= 2 && self.sky.is_some() {
                    // The lights at infinity, sampled from z_{t-1}.
                    let u = (se.next_1d(), se.next_1d(), se.next_2d());
                    if let Some(c) = self.sky_sample(&eye[t - 1], u) {
                        out.pixels[i - out.start][layer_of(eye, &[], 0, t + 1)] += c;
                    }
                }
                // s = 1's light point takes the eye stream's next numbers.
                let u = if s == 1 { Some((se.next_1d(), se.next_1d(), se.next_2d())) } else { None };
                let found = if t == 1 {
                    self.splat(&light[..s]).map(|(px, c, w)| {
                        out.splats.push((px, layer_of(eye, light, s, t) as u8, c * w));
                        (c, w)
                    })
                } else {
                    self.connect(&eye[..t], &light[..s.min(light.len())], s, u).inspect(|&(c, w)| {
                        out.pixels[i - out.start][layer_of(eye, light, s, t)] += c * w;
                    })
                };
                if let Some((c, w)) = found
                    && s < TALLY
                    && t < TALLY
                    && let Some(v) = out.tally.get_mut(s * TALLY + t)
                {
                    let l = c.element_sum() as f64 / 3.0;
                    v[0] += l;
                    v[1] += l * w as f64;
                }
            }
        }
    }

    /// The eye subpath through unit direction `d` from the pinhole into `path`
    /// (the pinhole first): whether the vertex limit cut it, and what it found
    /// leaving the scene.
    fn eye_subpath(&self, d: Vec3, s: &mut Sampler, path: &mut Vec<Vertex>) -> Walked {
        path.clear();
        path.push(self.camera_vertex());
        let from = Leaving {
            o: self.lens.camera.position,
            d,
            beta: Rgb::ONE,
            pdf: self.lens.pdf_dir(d),
            medium: self.eye_medium,
        };
        self.walk(from, true, s, path)
    }

    /// The light subpath into `path` (the light's point first): a light chosen by
    /// power, a point on it and a direction from it as the photon tracer draws
    /// them. True when the vertex limit cut it.
    fn light_subpath(&self, s: &mut Sampler, path: &mut Vec<Vertex>) -> bool {
        path.clear();
        let (u_light, u_sel, u_pos) = (s.next_1d(), s.next_1d(), s.next_2d());
        let (u_side, u_dir) = (s.next_1d(), s.next_2d());
        let Some(y0) = self.light_point(u_light, u_sel, u_pos) else { return false };
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
        self.walk(Leaving { o, d: dir, beta, pdf: pdf_dir, medium: y0.media[0] }, false, s, path).cut
    }

    /// Extend a subpath from `o` along unit `d` (sampled with density `pdf_dir`
    /// [sr^-1] at the path's last vertex, starting in medium `medium`) with
    /// throughput `beta`, by BSDF and phase-function sampling, free flights in
    /// media (the path tracer's: distances by a hero channel chosen once a
    /// subpath, weighed by the balance heuristic over channels, `Flights`),
    /// index-matched boundaries passed without a vertex, and Russian roulette:
    /// radiance on the eye side (`eye`), power on the light side. True when the
    /// vertex limit cut it, and for an eye subpath what it found leaving the
    /// scene (weighed against the samples of lights at infinity).
    fn walk(&self, from: Leaving, eye: bool, s: &mut Sampler, path: &mut Vec<Vertex>) -> Walked {
        let scene = self.scene;
        let Leaving { o, d, beta, pdf: pdf_dir, medium } = from;
        let (mut o, mut d, mut beta, mut pdf_fwd, mut medium) = (o, d, beta, pdf_dir, medium);
        let ended = |cut: bool| Walked { cut, escaped: Rgb::ZERO };
        let start = beta.max_element();
        let mut eta_scale = 1.0f32;
        let mut flights = Flights::new(if scene.has_media() { s.next_1d() } else { 0.0 });
        let limit = self.params.bdpt_max_vertices as usize + 1;
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
                        scattered = Some((o + d * t, m.phase));
                    }
                }
            }
            let wo = -d;
            if let Some((p, phase)) = scattered {
                let mut v = Vertex {
                    kind: Kind::Medium { phase },
                    p,
                    ng: Vec3::ZERO,
                    ns: Vec3::ZERO,
                    wo,
                    beta: beta * flights.weight(),
                    pdf_fwd: 0.0,
                    pdf_rev: 0.0,
                    delta: false,
                    media: [medium; 2],
                };
                v.pdf_fwd = prev.area_density(pdf_fwd, &v);
                let at = path.len();
                path.push(v);
                let ps = phase.sample(wo, s.next_2d());
                // Henyey-Greenstein depends on the angle alone: the reverse
                // density is the forward one.
                path[at - 1].pdf_rev = v.area_density(ps.pdf, &prev);
                pdf_fwd = ps.pdf;
                // The path tracer's roulette on the throughput relative to the
                // subpath's start, eta^2 folded in on the eye side.
                if !pm_render::roulette(&mut beta, flights.weight() * eta_scale / start, at as u32, s) {
                    return ended(false);
                }
                (o, d) = (p, ps.wi);
                continue;
            }
            let Some(hit) = hit else {
                let escaped = if eye { self.escaped(&prev, pdf_fwd, d, beta * flights.weight()) } else { Rgb::ZERO };
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
                pdf_fwd: 0.0,
                pdf_rev: 0.0,
                delta: false,
                media,
            };
            v.pdf_fwd = prev.area_density(pdf_fwd, &v);
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
            let (fwd, rev) = if bs.specular { (0.0, 0.0) } else { (bs.pdf, bsdf.pdf(bs.wi, wo, hit.ns)) };
            path[at].delta = bs.specular;
            path[at - 1].pdf_rev = path[at].area_density(rev, &prev);
            pdf_fwd = fwd;
            if !pm_render::roulette(&mut beta, flights.weight() * eta_scale / start, at as u32, s) {
                return ended(false);
            }
            medium = v.medium_toward(bs.wi);
            o = scene.offset_origin(hit.p, hit.ng, bs.wi);
            d = bs.wi;
        }
    }

    /// What an eye subpath finds leaving the scene along unit `d` from its last
    /// vertex `prev` (which sampled `d` with density `pdf` [sr^-1]; zero after a
    /// delta lobe) with throughput `beta`: the environment's and sun discs'
    /// radiance [W sr^-1 m^-2], weighed by the power heuristic against
    /// [`Self::sky_sample`] at `prev` (the path tracer's two strategies for light
    /// at infinity: light subpaths do not start there).
    fn escaped(&self, prev: &Vertex, pdf: f32, d: Vec3, beta: Rgb) -> Rgb {
        let le = self.scene.escaped(d);
        if le.max_element() <= 0.0 {
            return Rgb::ZERO;
        }
        let w = if matches!(prev.kind, Kind::Camera) || prev.delta {
            1.0
        } else {
            pm_light::power_heuristic(pdf, self.pdf_sky(prev, d))
        };
        beta * le * w
    }

    /// The unit normal a vertex samples lights at infinity about: the geometric
    /// normal on the side `wo` is on; zero in a medium.
    fn sky_normal(v: &Vertex) -> Vec3 {
        if v.ng == Vec3::ZERO { Vec3::ZERO } else { pm_scene::facing(v.ng, v.wo) }
    }

    /// The density [sr^-1] with which [`Self::sky_sample`] at `v` picks unit
    /// direction `d` (every light at infinity's, by its choice).
    fn pdf_sky(&self, v: &Vertex, d: Vec3) -> f32 {
        let Some(sky) = &self.sky else { return 0.0 };
        let n = Self::sky_normal(v);
        (0..self.scene.lights.len())
            .filter(|&i| sky.probs[i] > 0.0)
            .map(|i| sky.probs[i] as f32 * self.scene.lights[i].pdf_escaped(v.p, n, d))
            .sum()
    }

    /// Light from a light at infinity at eye vertex `z`: one light chosen by power
    /// (`u.0`), a direction sampled on it (`u.1`, `u.2`: `Light::sample_li`), a
    /// shadow ray to the sky through the media and index-matched boundaries on the
    /// way, weighed by the power heuristic against the eye subpath's own
    /// direction leaving the scene ([`Self::escaped`]); a parallel sun is taken
    /// whole. What it adds to the pixel [W sr^-1 m^-2].
    fn sky_sample(&self, z: &Vertex, u: (f32, f32, glam::Vec2)) -> Option<Rgb> {
        if z.delta || !z.scatters() {
            return None;
        }
        let sky = self.sky.as_ref()?;
        let (li, prob) = sky.pick(u.0);
        let ls = self.scene.lights[li].sample_li(self.scene, z.p, Self::sky_normal(z), u.1, u.2)?;
        let f = z.f(z.wo, ls.wi) * z.cos_at(ls.wi);
        let c = z.beta * f * ls.li / (prob as f32 * ls.pdf);
        if c.max_element() <= 0.0 || !c.is_finite() {
            return None;
        }
        let o = if z.ng == Vec3::ZERO { z.p } else { self.scene.offset_origin(z.p, z.ng, ls.wi) };
        let tr = self.scene.transmittance_along(o, ls.wi, f32::INFINITY, z.medium_toward(ls.wi));
        let w = if ls.delta { 1.0 } else { pm_light::power_heuristic(self.pdf_sky(z, ls.wi), z.pdf_dir(z.wo, ls.wi)) };
        Some(c * tr * w)
    }

    /// What passes along the segment from vertex `a` to vertex `b` (each end
    /// offset off its surface toward the other) per channel: zero where a surface
    /// blocks it, else the media's transmittance and the colours of the
    /// index-matched boundaries it crosses (`Scene::transmittance_to`).
    fn transmittance(&self, a: &Vertex, b: &Vertex) -> Rgb {
        let scene = self.scene;
        let w = b.p - a.p;
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

    /// Strategy (s, t >= 2): the eye subpath `eye` (t vertices) joined to the light
    /// subpath `light` (its first s vertices), or for s = 0 its last vertex on an
    /// emitter, or for s = 1 a light point picked with `u` (light, triangle,
    /// point): the contribution to the pixel [W sr^-1 m^-2] and its MIS weight.
    fn connect(
        &self,
        eye: &[Vertex],
        light: &[Vertex],
        s: usize,
        u: Option<(f32, f32, glam::Vec2)>,
    ) -> Option<(Rgb, f32)> {
        let t = eye.len();
        let z = &eye[t - 1];
        if s == 0 {
            let Kind::Surface { le, emitter: Some(_), .. } = z.kind else { return None };
            return Some((z.beta * le, self.weight(eye, &[], 0, None)));
        }
        if z.delta || !z.scatters() {
            return None;
        }
        // The light-side end: y_{s-1}, or for s = 1 a new point on a light.
        let picked = if s == 1 {
            let (u_light, u_sel, u_pos) = u?;
            Some(self.light_point(u_light, u_sel, u_pos)?)
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
        Some((c, self.weight(eye, light, s, picked.as_ref())))
    }

    /// A point on a light picked as a light subpath's first vertex is (`u_light`
    /// the light, `u_sel` its triangle, `u_pos` the point), for strategy s = 1.
    fn light_point(&self, u_light: f32, u_sel: f32, u_pos: glam::Vec2) -> Option<Vertex> {
        let (li, prob) = self.lights.as_ref()?.pick(u_light);
        let q = self.scene.lights[li].emitter_point(self.scene, u_sel, u_pos)?;
        let pdf = prob as f32 * q.pdf_pos;
        (pdf > 0.0).then(|| Vertex {
            kind: Kind::Light { light: li as u32, q },
            p: q.p,
            ng: q.n,
            ns: q.n,
            wo: Vec3::ZERO,
            beta: Rgb::splat(1.0 / pdf),
            pdf_fwd: pdf,
            pdf_rev: 0.0,
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
            pdf_fwd: 1.0,
            pdf_rev: 0.0,
            delta: false,
            media: [self.eye_medium; 2],
        }
    }

    /// Strategy t = 1: the light subpath's last vertex y_{s-1} (s >= 2) seen by the
    /// pinhole: the pixel it lands in, what it adds there [W sr^-1 m^-2] and its
    /// MIS weight.
    fn splat(&self, light: &[Vertex]) -> Option<(u32, Rgb, f32)> {
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
        Some((px, c, self.weight(std::slice::from_ref(&camera), light, s, None)))
    }

    /// The MIS weight of strategy (s, t = `eye.len()`): the eye subpath joined to
    /// the light subpath's first s vertices (`light`), to the light point
    /// `picked` (s = 1), or for s = 0 ending on an emitter. Works out the
    /// densities the join changes (pbrt-v3's `MISWeight`: the reverse densities
    /// of both ends and of the vertices before them) and weighs by [`Self::mis`].
    fn weight(&self, eye: &[Vertex], light: &[Vertex], s: usize, picked: Option<&Vertex>) -> f32 {
        let t = eye.len();
        let z = &eye[t - 1];
        if s == 0 {
            let Kind::Surface { emitter: Some((li, q)), .. } = &z.kind else { return 0.0 };
            let light = &self.scene.lights[*li as usize];
            let fix = Fix {
                z_rev: self.lights.as_ref().map_or(0.0, |l| l.probs[*li as usize] as f32) * q.pdf_pos,
                z_prev_rev: z.area_density(light.pdf_emitted_dir(q, z.wo), &eye[t - 2]),
                ..Fix::default()
            };
            return self.mis(eye, &[], 0, &fix);
        }
        let y = picked.unwrap_or_else(|| &light[s - 1]);
        let wi = (y.p - z.p).normalize_or_zero();
        let y_prev_rev =
            |from_z: Vec3| if s >= 2 { y.area_density(y.pdf_dir(from_z, y.wo), &light[s - 2]) } else { 0.0 };
        let fix = if t == 1 {
            Fix { y_rev: z.area_density(self.lens.pdf_dir(wi), y), y_prev_rev: y_prev_rev(-wi), ..Fix::default() }
        } else {
            let pdf_z_from_y = match &y.kind {
                Kind::Light { light, q } => self.scene.lights[*light as usize].pdf_emitted_dir(q, -wi),
                _ => y.pdf_dir(y.wo, -wi),
            };
            Fix {
                z_rev: y.area_density(pdf_z_from_y, z),
                z_prev_rev: z.area_density(z.pdf_dir(wi, z.wo), &eye[t - 2]),
                y_rev: z.area_density(z.pdf_dir(z.wo, wi), y),
                y_prev_rev: y_prev_rev(-wi),
                y0: picked.copied(),
            }
        };
        self.mis(eye, light, s, &fix)
    }

    /// The power-heuristic weight of strategy (s, t = `eye.len()`; `light` holds
    /// the light subpath's first s vertices, all but y_0 for s = 1) for the path the two subpaths make when joined, with the
    /// densities the join changes in `fix`: 1 / (1 + sum r_i^2) over the ratios
    /// of every other strategy's density of the same path to this one's, walked
    /// outward from the join on each side (Veach 1997, section 10.2.1; r_i
    /// multiplies in p_rev / p_fwd at each vertex passed; a strategy that would
    /// join at a delta vertex or hit a point light counts nothing).
    fn mis(&self, eye: &[Vertex], light: &[Vertex], s: usize, fix: &Fix) -> f32 {
        let t = eye.len();
        if s + t == 2 {
            return 1.0;
        }
        let remap = |p: f32| if p != 0.0 { p } else { 1.0 };
        let mut sum = 0.0f32;
        let z_rev = |i: usize| {
            if i == t - 1 {
                fix.z_rev
            } else if i + 2 == t {
                fix.z_prev_rev
            } else {
                eye[i].pdf_rev
            }
        };
        let z_delta = |i: usize| i + 1 != t && eye[i].delta;
        let mut r = 1.0f32;
        for i in (1..t).rev() {
            r *= remap(z_rev(i)) / remap(eye[i].pdf_fwd);
            if !z_delta(i) && !z_delta(i - 1) {
                sum += r * r;
            }
        }
        let y = |i: usize| match (i, &fix.y0) {
            (0, Some(y0)) => y0,
            _ => &light[i],
        };
        let y_rev = |i: usize| {
            if i + 1 == s {
                fix.y_rev
            } else if i + 2 == s {
                fix.y_prev_rev
            } else {
                y(i).pdf_rev
            }
        };
        let y_delta = |i: usize| i + 1 != s && y(i).delta;
        let mut r = 1.0f32;
        for i in (0..s).rev() {
            r *= remap(y_rev(i)) / remap(y(i).pdf_fwd);
            let before = if i > 0 { y_delta(i - 1) } else { self.delta_light(y(0)) };
            if !y_delta(i) && !before {
                sum += r * r;
            }
        }
        let w = 1.0 / (1.0 + sum);
        if w.is_finite() { w } else { 0.0 }
    }

    /// True for a light subpath's first vertex on a point or spot light (no eye
    /// subpath can hit it).
    fn delta_light(&self, y0: &Vertex) -> bool {
        match &y0.kind {
            Kind::Light { light, .. } => self.scene.lights[*light as usize].is_delta(),
            _ => false,
        }
    }
}

/// True for a light at infinity (an environment, a sun): no light subpath starts
/// there; eye subpaths find it by leaving the scene or by sampling it.
fn at_infinity(l: &pm_scene::Light) -> bool {
    matches!(l.kind, LightKind::Directional { .. } | LightKind::Environment { .. })
}

/// The densities a join changes, for [`Bdpt::mis`]: the reverse densities of the
/// eye side's last vertex and the one before it, of the light side's last and
/// the one before it, and for s = 1 the light point picked in place of y_0.
#[derive(Default)]
struct Fix {
    z_rev: f32,
    z_prev_rev: f32,
    y_rev: f32,
    y_prev_rev: f32,
    y0: Option<Vertex>,
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
    let x = |j: usize| if j < t { &eye[j] } else { &light[s - 1 - (j - t)] };
    let delta = |j: usize| x(j).delta;
    let layer = if n == 1 {
        Layer::Direct
    } else if delta(1) {
        Layer::Specular
    } else if matches!(x(1).kind, Kind::Medium { .. }) {
        Layer::Volume
    } else if n == 2 {
        Layer::Direct
    } else if (2..n).all(delta) {
        Layer::Caustic
    } else {
        Layer::Indirect
    };
    layer.index()
}

/// Render `view.rect` of `view.film` by `params.bdpt_passes` passes (the whole film is
/// traced: light subpaths land anywhere), reporting passes done as progress.
pub fn render(
    scene: &Scene,
    params: &BdptParams,
    view: View,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, pm_render::RenderStats), String> {
    let passes = params.bdpt_passes as u64;
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
    params: &BdptParams,
    view: View,
    start: Option<(&std::path::Path, &pm_format::PassStateFile)>,
    after_pass: &mut dyn FnMut(&Bdpt) -> Result<bool, String>,
) -> Result<(Image, pm_render::RenderStats, u32), String> {
    let t0 = std::time::Instant::now();
    let film = view.film;
    let mut b = Bdpt::new(scene, view.camera, film.width, film.height, film.seed, *params)?;
    if let Some((path, file)) = start {
        b.resume(file, params.bdpt_passes).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    while b.passes() < params.bdpt_passes {
        b.pass();
        if !after_pass(&b)? {
            break;
        }
    }
    let image = b.region_image(view.rect);
    let stats = pm_render::RenderStats {
        seconds: t0.elapsed().as_secs_f64(),
        samples: b.passes() as u64 * image.total.len() as u64,
        terminated_paths: b.cut_paths(),
        ..Default::default()
    };
    Ok((image, stats, b.passes()))
}

#[cfg(test)]
mod tests;
