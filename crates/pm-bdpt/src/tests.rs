//! The multiple-importance weights against the densities worked out directly
//! from whole paths.

use super::*;

fn scene(name: &str) -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name);
    pm_scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// A whole path x_0 (the pinhole) .. x_n (on a light), as strategy (s, t) made it.
struct Whole {
    x: Vec<Vertex>,
    /// The light's index and point at x_n.
    light: (u32, EmitterPoint),
}

/// x_n as a light subpath's first vertex.
fn as_light(v: &Vertex, light: u32, q: EmitterPoint) -> Vertex {
    Vertex { kind: Kind::Light { light, q }, ..*v }
}

impl Whole {
    fn n(&self) -> usize {
        self.x.len() - 1
    }

    /// Unit direction from x_i to x_j.
    fn dir(&self, i: usize, j: usize) -> Vec3 {
        (self.x[j].p - self.x[i].p).normalize()
    }

    /// The density [m^-2] with which the eye side makes x_i from x_{i-1} (and
    /// x_{i-2}); 1 after a delta vertex (its discrete choice is common to every
    /// strategy that samples through it).
    fn p_eye(&self, b: &Bdpt, i: usize) -> f32 {
        let pdf = if i == 1 {
            b.lens.pdf_dir(self.dir(0, 1))
        } else if self.x[i - 1].delta {
            return 1.0;
        } else {
            self.x[i - 1].pdf_dir(self.dir(i - 1, i - 2), self.dir(i - 1, i))
        };
        one_if_zero(self.x[i - 1].area_density(pdf, &self.x[i]))
    }

    /// The density [m^-2] with which the light side makes x_i from x_{i+1} (and
    /// x_{i+2}); x_n's is the light's choice times its point's area density.
    fn p_light(&self, b: &Bdpt, i: usize) -> f32 {
        let n = self.n();
        let (li, q) = self.light;
        let pdf = if i == n {
            return one_if_zero(b.lights.as_ref().unwrap().probs[li as usize] as f32 * q.pdf_pos);
        } else if i + 1 == n {
            b.scene.lights[li as usize].pdf_emitted_dir(&q, self.dir(n, i))
        } else if self.x[i + 1].delta {
            return 1.0;
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
            (0, _) => !b.scene.lights[self.light.0 as usize].is_delta(),
            _ => !x[t - 1].delta && !x[t].delta,
        }
    }

    /// The power heuristic's weight of strategy (n + 1 - t, t) from the densities of the
    /// whole path: p_{s,t}^2 / sum over the strategies that can make it.
    fn direct_weight(&self, b: &Bdpt, t: usize) -> f32 {
        let n = self.n();
        let p = |t: usize| -> f64 {
            let eye: f64 = (1..t).map(|i| self.p_eye(b, i) as f64).product();
            let light: f64 = (t..=n).map(|i| self.p_light(b, i) as f64).product();
            eye * light
        };
        let all: f64 = (1..=n + 1).filter(|&t| self.can(b, n + 1 - t, t)).map(|t| p(t).powi(2)).sum();
        (p(t).powi(2) / all) as f32
    }

    /// The weight the renderer gives strategy (s, t): the path cut into an eye
    /// subpath x_0 .. x_{t-1} and a light subpath x_n .. x_t with the densities
    /// the random walks would have stored (the ends' reverse densities NaN: the
    /// join must work them out), weighed by [`Bdpt::weight`].
    fn renderer_weight(&self, b: &Bdpt, s: usize, t: usize) -> f32 {
        let n = self.n();
        let (li, q) = self.light;
        let eye: Vec<Vertex> = (0..t)
            .map(|i| {
                let mut v = self.x[i];
                v.wo = if i == 0 { Vec3::ZERO } else { self.dir(i, i - 1) };
                v.pdf_fwd = if i == 0 { 1.0 } else { self.p_eye(b, i) };
                v.pdf_rev = if i + 1 == t {
                    f32::NAN
                } else if i == 0 {
                    0.0
                } else {
                    self.p_light(b, i)
                };
                v.delta = i + 1 != t && v.delta;
                if i == n {
                    let le = b.scene.lights[li as usize].emitted_toward(&q, v.wo);
                    v.kind = Kind::Surface { bsdf: Bsdf::Lambert { rho: Rgb::ZERO }, le, emitter: Some((li, q)) };
                }
                v
            })
            .collect();
        let light: Vec<Vertex> = (0..s)
            .map(|j| {
                let i = n - j;
                let mut v = self.x[i];
                if i == n {
                    v = as_light(&v, li, q);
                }
                v.wo = if i == n { Vec3::ZERO } else { self.dir(i, i + 1) };
                v.pdf_fwd = self.p_light(b, i);
                v.pdf_rev = if j + 1 == s { f32::NAN } else { self.p_eye(b, i) };
                v.delta = j + 1 != s && v.delta;
                v
            })
            .collect();
        if s == 1 { b.weight(&eye, &[], 1, Some(&light[0])) } else { b.weight(&eye, &light, s, None) }
    }
}

fn one_if_zero(p: f32) -> f32 {
    if p != 0.0 { p } else { 1.0 }
}

/// For every path the renderer's strategies make from random subpaths on a
/// diffuse box, glass and mirror spheres, glossy and coated materials, and 48
/// point lamps with an emitting sphere: the weights of every strategy that can
/// make the path add up to one within 1e-4, and each equals the power
/// heuristic's weight worked out from the whole path's densities (Veach 1997,
/// eq. 10.9) within 1e-4. The renderer's weights come from densities stored by
/// the random walks and the join's corrections (pbrt-v3's `MISWeight`); the
/// direct ones from the BSDFs' and lights' densities along the whole path.
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
    for (path, recipe) in generated {
        let s = pm_scene::load(&path).unwrap();
        let camera = s.camera.clone().unwrap();
        // Light subpaths start only at lights with a position.
        if Bdpt::new(&s, &camera, 8, 8, 1, BdptParams::default()).is_ok_and(|b| b.lights.is_some()) {
            scenes.push((format!("generated {} ({:?}, {:?})", recipe.index, recipe.objects, recipe.lights), s));
        }
    }
    assert!(scenes.len() >= 8, "only {} scenes", scenes.len());
    for (name, scene) in &scenes {
        let camera = scene.camera.clone().unwrap();
        let b = Bdpt::new(scene, &camera, 24, 24, 7, BdptParams::default()).unwrap();
        let diag2 = scene.bounds.diagonal().powi(2);
        let (mut paths, mut longest, mut worst_sum, mut worst_one, mut delta_paths) = (0, 0, 0.0f32, 0.0f32, 0);
        let mut medium_paths = 0;
        let mut stored: Vec<f32> = Vec::new();
        let (mut eye, mut light) = (Vec::new(), Vec::new());
        for i in 0..24 * 24 {
            let mut se = Sampler::salted(7, pixel_salt(i), 0);
            let j = se.next_2d();
            let d = b.lens.rays.direction(((i % 24) as f32 + j.x) / 24.0, ((i / 24) as f32 + j.y) / 24.0);
            b.eye_subpath(d, &mut se, &mut eye);
            let mut sl = Sampler::salted(7, LIGHT_SALT ^ i as u64, 0);
            b.light_subpath(&mut sl, &mut light);
            for t in 1..=eye.len() {
                for s in 0..=light.len() {
                    if s + t < 2 || (s == 1 && t == 1) || (t == 1 && s < 2) {
                        continue;
                    }
                    let mut x: Vec<Vertex> = eye[..t].to_vec();
                    let light_at = if s == 0 {
                        let Kind::Surface { emitter: Some(e), .. } = eye[t - 1].kind else { continue };
                        e
                    } else {
                        let Kind::Light { light: li, q } = light[0].kind else { unreachable!() };
                        x.extend(light[..s].iter().rev());
                        (li, q)
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
                    // A path that carries nothing (x_n's light faces away) has no weights.
                    if b.scene.lights[light_at.0 as usize]
                        .emitted_toward(&light_at.1, whole.dir(n, n - 1))
                        .max_element()
                        <= 0.0
                    {
                        continue;
                    }
                    // What the random walks stored is what the whole path says, to
                    // within the difference between a sampled direction and the one
                    // between the stored points (the ray left an offset origin, the
                    // hit point is interpolated from the triangle's corners). On
                    // segments of millimetres and at grazing angles that is not
                    // small (in a 5 m room densities above 9,000 m^-2 were 1.5-5%
                    // off, one of 62,000 m^-2 21%), so those above 1,000 m^-2 in a
                    // 5 m room (scaled with the scene) are left out and the rest
                    // judged by their quantiles below: a slip in the bookkeeping
                    // is off at most vertices, and moves the median.
                    let mut close = |a: f32, b: f32| {
                        if b * diag2 < 2.5e4 {
                            stored.push((one_if_zero(a) / b - 1.0).abs());
                        }
                    };
                    for i in 1..t {
                        let (fwd, exact) = (eye[i].pdf_fwd, whole.p_eye(&b, i));
                        close(fwd, exact);
                        if i + 2 < t {
                            let (rev, exact) = (eye[i].pdf_rev, whole.p_light(&b, i));
                            close(rev, exact);
                        }
                    }
                    for j in 0..s {
                        let (fwd, exact) = (light[j].pdf_fwd, whole.p_light(&b, n - j));
                        close(fwd, exact);
                        if j + 2 < s {
                            let (rev, exact) = (light[j].pdf_rev, whole.p_eye(&b, n - j));
                            close(rev, exact);
                        }
                    }
                    let mut sum = 0.0;
                    for t2 in 1..=n + 1 {
                        let s2 = n + 1 - t2;
                        if !whole.can(&b, s2, t2) {
                            continue;
                        }
                        let (ours, direct) = (whole.renderer_weight(&b, s2, t2), whole.direct_weight(&b, t2));
                        assert!(
                            (ours - direct).abs() < 1e-4,
                            "{name}: path of {n} segments from ({s}, {t}), strategy ({s2}, {t2}): weight {ours}, from the whole path {direct}"
                        );
                        worst_one = worst_one.max((ours - direct).abs());
                        sum += ours;
                    }
                    assert!(
                        (sum - 1.0).abs() < 1e-4,
                        "{name}: path of {n} segments from ({s}, {t}): weights sum to {sum}"
                    );
                    worst_sum = worst_sum.max((sum - 1.0).abs());
                    paths += 1;
                    longest = longest.max(n);
                    delta_paths += whole.x.iter().any(|v| v.delta) as u32;
                    medium_paths += whole.x.iter().any(|v| matches!(v.kind, Kind::Medium { .. })) as u32;
                }
            }
        }
        stored.sort_by(f32::total_cmp);
        let quantile = |q: f64| stored[((stored.len() - 1) as f64 * q) as usize];
        let (median, p99, worst) = (quantile(0.5), quantile(0.99), quantile(1.0));
        eprintln!(
            "{name}: {paths} paths ({delta_paths} through delta lobes, {medium_paths} scattered in a medium), up to {longest} segments; sums within {worst_sum:.1e}, weights within {worst_one:.1e}; stored densities against the path's: median {median:.1e}, 99% {p99:.1e}, worst {worst:.1e}"
        );
        assert!(median < 1e-5 && p99 < 3e-3, "{name}: stored densities off by {median} (median), {p99} (99%)");
        assert!(paths > 300, "{name}: only {paths} paths");
    }
}
