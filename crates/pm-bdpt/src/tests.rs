//! The multiple-importance weights against the densities worked out directly
//! from whole paths.

use super::*;

fn scene(name: &str) -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name);
    pm_scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Where a whole path ends.
#[derive(Clone, Copy)]
enum End {
    /// On a light's point: its index and the point.
    Point(u32, EmitterPoint),
    /// At a light at infinity: its index and the unit direction toward it.
    Sky(u32, Vec3),
}

/// A whole path x_0 (the pinhole) .. x_n (on a light, or the direction of a
/// light at infinity), as strategy (s, t) made it.
struct Whole {
    x: Vec<Vertex>,
    light: End,
}

/// x_n as a light subpath's first vertex.
fn as_light(v: &Vertex, light: u32, q: EmitterPoint) -> Vertex {
    Vertex { kind: Kind::Light { light, q }, ..*v }
}

impl Whole {
    fn n(&self) -> usize {
        self.x.len() - 1
    }

    /// Unit direction from x_i to x_j (toward a light at infinity, its own).
    fn dir(&self, i: usize, j: usize) -> Vec3 {
        match self.light {
            End::Sky(_, wi) if j == self.n() => wi,
            End::Sky(_, wi) if i == self.n() => -wi,
            _ => (self.x[j].p - self.x[i].p).normalize(),
        }
    }

    /// The light's index.
    fn li(&self) -> usize {
        match self.light {
            End::Point(li, _) | End::Sky(li, _) => li as usize,
        }
    }

    /// x_{n-1} as the eye side reaches it (its `wo` toward x_{n-2}).
    fn last_from_eye(&self) -> Vertex {
        let n = self.n();
        Vertex { wo: self.dir(n - 1, n - 2), ..self.x[n - 1] }
    }

    /// The density [m^-2] with which the eye side makes x_i from x_{i-1} (and
    /// x_{i-2}); after a delta vertex the direction's density is taken as 1 [sr^-1]
    /// (its discrete choice is common to every strategy that samples through it)
    /// and converted to area as any other: the geometric factors stay in the
    /// ratios, as they do in Georgiev et al.'s recursion (pbrt-v3 takes the area
    /// density itself as 1).
    fn p_eye(&self, b: &Bdpt, i: usize) -> f32 {
        if let End::Sky(_, wi) = self.light
            && i == self.n()
        {
            // Leaving the scene: a direction's density [sr^-1], no area.
            let z = &self.x[i - 1];
            return if z.delta { 1.0 } else { one_if_zero(z.pdf_dir(self.dir(i - 1, i - 2), wi)) };
        }
        let pdf = if i == 1 {
            b.lens.pdf_dir(self.dir(0, 1))
        } else if self.x[i - 1].delta {
            1.0
        } else {
            self.x[i - 1].pdf_dir(self.dir(i - 1, i - 2), self.dir(i - 1, i))
        };
        one_if_zero(self.x[i - 1].area_density(pdf, &self.x[i]))
    }

    /// The density [m^-2] with which the light side makes x_i from x_{i+1} (and
    /// x_{i+2}), as [`Self::p_eye`]; x_n's is the light's choice times its
    /// point's area density.
    fn p_light(&self, b: &Bdpt, i: usize) -> f32 {
        let n = self.n();
        let (li, q) = match self.light {
            End::Point(li, q) => (li, q),
            End::Sky(li, wi) => {
                let light = &b.scene.lights[li as usize];
                let prob = b.lights.probs[li as usize] as f32;
                // x_n: the direction [sr^-1]; x_{n-1}: the disc's point seen
                // across it [m^-2] (no 1 / d^2 from infinity).
                return one_if_zero(if i == n {
                    prob * if light.is_delta() { 1.0 } else { light.pdf_sky_dir(wi) }
                } else if i + 1 == n {
                    light.pdf_sky_origin() * self.x[i].measure(wi)
                } else if self.x[i + 1].delta {
                    self.x[i + 1].area_density(1.0, &self.x[i])
                } else {
                    let pdf = self.x[i + 1].pdf_dir(self.dir(i + 1, i + 2), self.dir(i + 1, i));
                    self.x[i + 1].area_density(pdf, &self.x[i])
                });
            }
        };
        let pdf = if i == n {
            return one_if_zero(b.lights.probs[li as usize] as f32 * q.pdf_pos);
        } else if i + 1 == n {
            b.scene.lights[li as usize].pdf_emitted_dir(&q, self.dir(n, i))
        } else if self.x[i + 1].delta {
            1.0
        } else {
            self.x[i + 1].pdf_dir(self.dir(i + 1, i + 2), self.dir(i + 1, i))
        };
        one_if_zero(self.x[i + 1].area_density(pdf, &self.x[i]))
    }

    /// True when strategy (s, t) can make this path.
    fn can(&self, b: &Bdpt, s: usize, t: usize) -> bool {
        let n = self.n();
        let x = &self.x;
        if n == 1 {
            return s == 0;
        }
        match (s, t) {
            (1, 1) => false,
            (_, 1) => !x[1].delta,
            (0, _) => !b.scene.lights[self.li()].is_delta(),
            (1, _) if matches!(self.light, End::Sky(..)) => !x[t - 1].delta,
            _ => !x[t - 1].delta && !x[t].delta,
        }
    }

    /// True when merging at x_i can make this path (`merging`: the pass merges).
    fn can_merge(&self, i: usize, merging: bool) -> bool {
        merging && i >= 1 && i < self.n() && self.x[i].merge_set().is_some()
    }

    /// The density of the path by strategy (n + 1 - t, t) [m^-2 per vertex]; at
    /// a light at infinity, s = 1 samples the direction at x_{n-1}.
    fn p_connect(&self, b: &Bdpt, t: usize) -> f64 {
        let n = self.n();
        let eye: f64 = (1..t).map(|i| self.p_eye(b, i) as f64).product();
        if let End::Sky(li, wi) = self.light
            && t == n
        {
            return eye * b.p_sample_sky(li as usize, &self.last_from_eye(), wi) as f64;
        }
        eye * self.p_light_side(b, t)
    }

    /// The density with which a light subpath makes x_n .. x_t.
    fn p_light_side(&self, b: &Bdpt, t: usize) -> f64 {
        (t..=self.n()).map(|i| self.p_light(b, i) as f64).product()
    }

    /// The density of the path by merging at x_i: the eye side makes x_1 .. x_i,
    /// the light side x_n .. x_i, and eta counts the light subpaths and the disc
    /// (pi r^2 N on a surface) or the ball (4/3 pi r^3 N in a medium; Georgiev
    /// et al. 2012, eq. 20 with n_VC = 1).
    fn p_merge(&self, b: &Bdpt, i: usize, f: &Factors) -> f64 {
        let eta = f.merge_at(&self.x[i]).sqrt();
        let eye: f64 = (1..=i).map(|j| self.p_eye(b, j) as f64).product();
        eye * self.p_light_side(b, i) * eta as f64
    }

    /// The power heuristic's weights, worked out from the whole path's densities,
    /// of every strategy that can make it: (strategy, weight) with strategy
    /// `Ok(t)` for the join (n + 1 - t, t), `Err(i)` for merging at x_i.
    fn direct_weights(&self, b: &Bdpt, f: &Factors) -> Vec<(Result<usize, usize>, f32)> {
        let n = self.n();
        let mut all: Vec<(Result<usize, usize>, f64)> =
            (1..=n + 1).filter(|&t| self.can(b, n + 1 - t, t)).map(|t| (Ok(t), self.p_connect(b, t).powi(2))).collect();
        all.extend((1..n).filter(|&i| self.can_merge(i, f.vm > 0.0)).map(|i| (Err(i), self.p_merge(b, i, f).powi(2))));
        let sum: f64 = all.iter().map(|a| a.1).sum();
        all.into_iter().map(|(k, p)| (k, (p / sum) as f32)).collect()
    }

    /// The eye subpath x_0 .. x_{t-1} with the MIS sums its walk would have
    /// stored, worked out from the whole path (x_{t-1} is the join's end: its
    /// delta flag cleared; on the light for t = n + 1).
    fn eye_part(&self, b: &Bdpt, f: &Factors, t: usize) -> Vec<Vertex> {
        let n = self.n();
        let mut mis = Partial::camera(b.lens.pdf_dir(self.dir(0, 1)));
        (0..t)
            .map(|i| {
                let mut v = self.x[i];
                v.wo = if i == 0 { Vec3::ZERO } else { self.dir(i, i - 1) };
                v.delta = i + 1 != t && v.delta;
                if i == n
                    && let End::Point(li, q) = self.light
                {
                    let le = b.scene.lights[li as usize].emitted_toward(&q, v.wo);
                    v.kind = Kind::Surface { bsdf: Bsdf::Lambert { rho: Rgb::ZERO }, le, emitter: Some((li, q)) };
                }
                if i >= 1 {
                    mis.arrive(v.p.distance_squared(self.x[i - 1].p), v.measure(v.wo));
                    v.mis = mis;
                    if i + 1 < t {
                        let w = self.dir(i, i + 1);
                        mis.leave(v.measure(w), v.pdf_dir(v.wo, w), v.pdf_dir(w, v.wo), v.delta, f.merge_at(&v), f);
                    }
                }
                v
            })
            .collect()
    }

    /// The light subpath x_n .. x_{n+1-s} likewise (its end's delta flag cleared).
    fn light_part(&self, b: &Bdpt, f: &Factors, s: usize) -> Vec<Vertex> {
        let n = self.n();
        let mut mis = Partial::default();
        (0..s)
            .map(|j| {
                let i = n - j;
                let mut v = self.x[i];
                v.delta = j + 1 != s && v.delta;
                if i == n {
                    match self.light {
                        End::Sky(li, _) => {
                            let emission = b.p_emit_sky(li as usize, self.dir(n - 1, n));
                            let delta = b.scene.lights[li as usize].is_delta();
                            let vc = if delta { 0.0 } else { super::mis(1.0 / emission) };
                            mis = Partial { vcm: super::mis(1.0 / emission), vc, vm: vc * f.vc };
                        }
                        End::Point(li, q) => {
                            let light = &b.scene.lights[li as usize];
                            v = as_light(&v, li, q);
                            v.wo = Vec3::ZERO;
                            let w = self.dir(n, n - 1);
                            let cos = if q.n == Vec3::ZERO { 1.0 } else { q.n.dot(w).abs() };
                            let pdf_dir = light.pdf_emitted_dir(&q, w);
                            mis = Partial::light(b.light_pdf(li as usize, &q), pdf_dir, cos, light.is_delta(), f);
                        }
                    }
                    return v;
                }
                v.wo = self.dir(i, i + 1);
                match self.light {
                    End::Sky(li, wi) if i + 1 == n => {
                        mis.arrive_from_sky(b.p_sample_sky(li as usize, &v, wi), v.measure(wi))
                    }
                    _ => mis.arrive(v.p.distance_squared(self.x[i + 1].p), v.measure(v.wo)),
                }
                v.mis = mis;
                if j + 1 < s {
                    let w = self.dir(i, i - 1);
                    mis.leave(v.measure(w), v.pdf_dir(v.wo, w), v.pdf_dir(w, v.wo), v.delta, f.merge_at(&v), f);
                }
                v
            })
            .collect()
    }

    /// The weight the renderer gives a strategy (as [`Self::direct_weights`]
    /// names it), from subpaths carrying the MIS sums of [`Self::eye_part`] and
    /// [`Self::light_part`].
    fn renderer_weight(&self, b: &Bdpt, f: &Factors, strategy: Result<usize, usize>) -> f32 {
        let n = self.n();
        match strategy {
            Ok(t) if matches!(self.light, End::Sky(..)) && t >= n => {
                let End::Sky(li, wi) = self.light else { unreachable!() };
                let eye = self.eye_part(b, f, n);
                if t == n {
                    // s = 1: the direction sampled at x_{n-1}.
                    return b.sky_weight(f, &eye[n - 1], li as usize, wi);
                }
                // s = 0: the eye subpath leaves the scene from x_{n-1}.
                let mut z = eye[n - 1];
                z.delta = self.x[n - 1].delta;
                let mut after = z.mis;
                after.leave(z.measure(wi), z.pdf_dir(z.wo, wi), z.pdf_dir(wi, z.wo), z.delta, f.merge_at(&z), f);
                b.escape_weight(&z, &after, &eye, li as usize, wi)
            }
            Ok(t) => {
                let s = n + 1 - t;
                let (eye, light) = (self.eye_part(b, f, t), self.light_part(b, f, s));
                if s == 1 { b.weight(f, &eye, &[], 1, Some(&light[0])) } else { b.weight(f, &eye, &light, s, None) }
            }
            Err(i) => {
                let (eye, light) = (self.eye_part(b, f, i + 1), self.light_part(b, f, n + 1 - i));
                b.merge_weight(f, &eye[i], &Photon::of(b.scene, &light, n - i))
            }
        }
    }
}

fn one_if_zero(p: f32) -> f32 {
    if p != 0.0 { p } else { 1.0 }
}

/// For every path the renderer's strategies make from random subpaths on a
/// diffuse box, glass and mirror spheres, glossy and coated materials, a fog box,
/// and 48 point lamps with an emitting sphere, with merging on (vertex connection
/// and merging) and off (bidirectional path tracing): the weights of every
/// strategy that can make the path add up to one within 1e-4, and each equals
/// the power heuristic's weight worked out from the whole path's densities
/// (Veach 1997, eq. 10.9; merging's density by Georgiev et al. 2012, eq. 20)
/// within 1e-4. The renderer's weights come from the recursive MIS sums and the
/// join's densities; the direct ones from the BSDFs' and lights' densities along
/// the whole path. And the sums the random walks stored are those worked out
/// from the path's points.
#[test]
#[allow(clippy::needless_range_loop)]
fn mis_weights_sum_to_one_and_match_the_whole_paths_densities() {
    // The project's scenes (a fog box; absorbing glass, a textured emitter and
    // glossy metal in `materials`), and the differential checker's generated ones
    // that this renderer takes (seed 1: rough and brushed metal, clear coats and
    // velvet, spot and point lights, two-sided panels, fog boxes, scales from 1e-3
    // to 1e4).
    let dir = tempfile::tempdir().unwrap();
    let generated = pm_scenegen::random::write(dir.path(), 1, 16).unwrap();
    let mut scenes: Vec<(String, Scene)> =
        ["cornell_boxes.gltf", "cornell_spheres.gltf", "lamps_room.gltf", "cornell_fogbox.gltf", "materials.gltf"]
            .iter()
            .map(|n| (n.to_string(), scene(n)))
            .collect();
    // Lit by an environment: spheres under an image with a bright spot (its
    // density by the image), a room through its window under one colour (the
    // s = 1 density over a vertex's hemisphere).
    let mut hdri = scene("hdri_spheres.gltf");
    let texels: Vec<Rgb> = (0..32 * 16)
        .map(|i| {
            let (x, y) = (i % 32, i / 32);
            if (x, y) == (20, 4) {
                Rgb::new(400.0, 380.0, 300.0)
            } else {
                Rgb::new(0.4, 0.6, 1.0) * (1.0 - y as f32 / 16.0)
            }
        })
        .collect();
    hdri.set_environment(pm_scene::Environment::image(32, 16, texels, 1.0, 30.0).unwrap());
    scenes.push(("hdri_spheres.gltf under an image".into(), hdri));
    let mut window = scene("window_room.gltf");
    window.set_environment(pm_scene::Environment::constant(Rgb::new(1.0, 0.9, 0.8)).unwrap());
    scenes.push(("window_room.gltf under one colour".into(), window));
    for (path, recipe) in generated {
        let s = pm_scene::load(&path).unwrap();
        let camera = s.camera.clone().unwrap();
        if Bdpt::new(&s, &camera, 8, 8, 1, BdptParams::default()).is_ok() {
            scenes.push((format!("generated {} ({:?}, {:?})", recipe.index, recipe.objects, recipe.lights), s));
        }
    }
    assert!(scenes.len() >= 8, "only {} scenes", scenes.len());
    for (name, scene) in &scenes {
        let camera = scene.camera.clone().unwrap();
        let b = Bdpt::vcm(scene, &camera, 24, 24, 7, VcmParams::default()).unwrap();
        // The fourth pass's radius, and no merging.
        for (f, merging) in [(b.factors(3), "merging"), (Factors::default(), "no merging")] {
            let (mut paths, mut longest, mut worst_sum, mut worst_one, mut delta_paths) = (0, 0, 0.0f32, 0.0f32, 0);
            let (mut medium_paths, mut merges, mut volume_merges, mut sky_paths) = (0, 0, 0, 0);
            let mut stored: Vec<f32> = Vec::new();
            let (mut eye, mut light) = (Vec::new(), Vec::new());
            for i in 0..24 * 24 {
                let mut se = Sampler::salted(7, pixel_salt(i), 0);
                let j = se.next_2d();
                let d = b.lens.rays.direction(((i % 24) as f32 + j.x) / 24.0, ((i / 24) as f32 + j.y) / 24.0);
                b.eye_subpath(d, &mut se, &f, &mut eye);
                let mut sl = Sampler::salted(7, LIGHT_SALT ^ i as u64, 0);
                b.light_subpath(&mut sl, &f, &mut light);
                for t in 1..=eye.len() {
                    for s in 0..=light.len() {
                        if s + t < 2 || (s == 1 && t == 1) || (t == 1 && s < 2) {
                            continue;
                        }
                        let mut x: Vec<Vertex> = eye[..t].to_vec();
                        let light_at = if s == 0 {
                            let Kind::Surface { emitter: Some((li, q)), .. } = eye[t - 1].kind else { continue };
                            End::Point(li, q)
                        } else {
                            x.extend(light[..s].iter().rev());
                            match light[0].kind {
                                Kind::Light { light: li, q } => End::Point(li, q),
                                Kind::Sky { light: li, wi } => End::Sky(li, wi),
                                _ => unreachable!(),
                            }
                        };
                        // The join's ends must be able to join.
                        if (t >= 2 && s >= 1 && eye[t - 1].delta) || (s >= 1 && light[s - 1].delta) {
                            continue;
                        }
                        x[t - 1].delta = false;
                        if s >= 1 {
                            x[t].delta = false;
                        }
                        let whole = Whole { x, light: light_at };
                        let n = whole.n();
                        // A path that carries nothing (x_n's light faces away, a
                        // join reaches a surface from behind, light tracing's
                        // vertex is off the film) has no weights.
                        let sends = match light_at {
                            End::Point(li, q) => b.scene.lights[li as usize].emitted_toward(&q, whole.dir(n, n - 1)),
                            End::Sky(li, wi) => {
                                let l = &b.scene.lights[li as usize];
                                if l.is_delta() { Rgb::ONE } else { l.radiance_escaped(wi) }
                            }
                        };
                        if sends.max_element() <= 0.0
                            || !b
                                .lens
                                .camera
                                .project(whole.x[1].p, b.lens.aspect)
                                .is_some_and(|p| (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y))
                            || (1..n).any(|i| {
                                !whole.x[i].delta
                                    && whole.x[i].f(whole.dir(i, i - 1), whole.dir(i, i + 1)).max_element() <= 0.0
                            })
                        {
                            continue;
                        }
                        // What the walks stored against the sums worked out from the
                        // path's points: they differ by the difference between a
                        // sampled direction and the one between the stored points
                        // (the ray left an offset origin, the hit point is
                        // interpolated from the triangle's corners), large only on
                        // segments of millimetres and at grazing angles, so they are
                        // judged by their quantiles below: a slip in the bookkeeping
                        // is off at most vertices, and moves the median.
                        let mut close = |a: Partial, b: Partial| {
                            for (a, b) in [(a.vcm, b.vcm), (a.vc, b.vc), (a.vm, b.vm)] {
                                if b > 0.0 && b.is_finite() {
                                    stored.push((a / b - 1.0).abs());
                                } else {
                                    stored.push(if a == b { 0.0 } else { f32::INFINITY });
                                }
                            }
                        };
                        let (ep, lp) = (whole.eye_part(&b, &f, t), whole.light_part(&b, &f, s));
                        for i in 1..t {
                            close(eye[i].mis, ep[i].mis);
                        }
                        for j in 1..s {
                            close(light[j].mis, lp[j].mis);
                        }
                        let mut sum = 0.0;
                        for (strategy, direct) in whole.direct_weights(&b, &f) {
                            let ours = whole.renderer_weight(&b, &f, strategy);
                            assert!(
                                (ours - direct).abs() < 1e-4,
                                "{name}, {merging}: path of {n} segments from ({s}, {t}), strategy {strategy:?} (Ok(t): a join, Err(i): merging at x_i): weight {ours}, from the whole path {direct}"
                            );
                            worst_one = worst_one.max((ours - direct).abs());
                            merges += strategy.is_err() as u32;
                            volume_merges +=
                                matches!(strategy, Err(i) if matches!(whole.x[i].kind, Kind::Medium { .. })) as u32;
                            sum += ours;
                        }
                        assert!(
                            (sum - 1.0).abs() < 1e-4,
                            "{name}, {merging}: path of {n} segments from ({s}, {t}): weights sum to {sum}"
                        );
                        worst_sum = worst_sum.max((sum - 1.0).abs());
                        paths += 1;
                        longest = longest.max(n);
                        delta_paths += whole.x.iter().any(|v| v.delta) as u32;
                        medium_paths += whole.x.iter().any(|v| matches!(v.kind, Kind::Medium { .. })) as u32;
                        sky_paths += matches!(whole.light, End::Sky(..)) as u32;
                    }
                }
            }
            stored.sort_by(f32::total_cmp);
            let quantile = |q: f64| stored[((stored.len() - 1) as f64 * q) as usize];
            let (median, p99, worst) = (quantile(0.5), quantile(0.99), quantile(1.0));
            eprintln!(
                "{name}, {merging}: {paths} paths ({delta_paths} through delta lobes, {medium_paths} scattered in a medium, {merges} merging strategies, {volume_merges} of them in a medium, {sky_paths} from lights at infinity), up to {longest} segments; sums within {worst_sum:.1e}, weights within {worst_one:.1e}; stored MIS sums against the path's: median {median:.1e}, 99% {p99:.1e}, worst {worst:.1e}"
            );
            assert!(
                median < 1e-5 && p99 < 3e-2,
                "{name}, {merging}: stored MIS sums off by {median} (median), {p99} (99%)"
            );
            assert!(paths > 300, "{name}, {merging}: only {paths} paths");
            if b.scene.lights.iter().any(at_infinity) {
                assert!(sky_paths > 100, "{name}, {merging}: only {sky_paths} paths from lights at infinity");
            }
            if f.vm > 0.0 {
                assert!(merges > 100, "{name}: only {merges} merging strategies weighed");
                if name.contains("fogbox") {
                    assert!(volume_merges > 100, "{name}: only {volume_merges} merges in the fog weighed");
                }
            }
        }
    }
}
