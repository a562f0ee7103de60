//! The light tree against its own definition: probabilities that sum to one, a
//! choice that follows them, and bounds that never rule out a light that lights
//! a point.

use super::*;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_sampling::Sampler;
use pm_scene::{Light, Material, Triangle};

/// A 4 m floor (y = 0), a 0.6 m panel at y = 1.9 facing down, and `n` x `n`
/// coloured point lamps of varied intensity at y = 1.7, plus a spot aimed down.
fn many_lamps(n: usize) -> Scene {
    let v = Vec3::new;
    let mut tris = Vec::new();
    let mut quad = |q: [Vec3; 4], m: u32| {
        tris.push(Triangle::new([q[0], q[1], q[2]], m).unwrap());
        tris.push(Triangle::new([q[0], q[2], q[3]], m).unwrap());
    };
    quad([v(-2., 0., -2.), v(-2., 0., 2.), v(2., 0., 2.), v(2., 0., -2.)], 0);
    quad([v(-0.3, 1.9, -0.3), v(0.3, 1.9, -0.3), v(0.3, 1.9, 0.3), v(-0.3, 1.9, 0.3)], 1);
    let mats = vec![
        Material::new("floor", Bsdf::Lambert { rho: Rgb::splat(0.5) }, Rgb::ZERO),
        Material::new("panel", Bsdf::Lambert { rho: Rgb::ZERO }, Rgb::splat(3.0)),
    ];
    let mut lights = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let at = v(-1.8 + 3.6 * i as f32 / (n - 1) as f32, 1.7, -1.8 + 3.6 * j as f32 / (n - 1) as f32);
            let c = Rgb::new(1.0 + (i % 3) as f32, 1.0 + (j % 2) as f32, 0.5 + ((i + j) % 4) as f32);
            lights.push(Light {
                name: format!("lamp {i} {j}"),
                kind: LightKind::Point { position: at, intensity: c * 0.05 },
                power: Rgb::ZERO,
            });
        }
    }
    lights.push(Light {
        name: "spot".into(),
        kind: LightKind::Spot {
            position: v(0., 1.8, 1.5),
            direction: -Vec3::Y,
            intensity: Rgb::ONE,
            cos_inner: 0.95,
            cos_outer: 0.9,
        },
        power: Rgb::ZERO,
    });
    Scene::from_parts(tris, mats, lights, None)
}

fn all(s: &Scene) -> Vec<usize> {
    (0..s.lights.len()).collect()
}

/// Everything the tree can choose (whole lights, and the triangles of the lights
/// it holds triangle by triangle) with its probability at `p`, `n`.
fn choices(s: &Scene, tree: &LightTree, p: Vec3, n: Vec3) -> Vec<(Chosen, f32)> {
    let mut out = Vec::new();
    for li in 0..s.lights.len() {
        match &s.lights[li].kind {
            LightKind::Area { tris, .. } if tree.is_split(li) => {
                for (i, id) in tris.clone().enumerate() {
                    out.push((Chosen { light: li, tri: Some(i as u32) }, tree.prob_triangle(id, p, n)));
                }
            }
            _ => out.push((Chosen::whole(li), tree.prob(li, p, n))),
        }
    }
    out
}

/// At points on the floor and in the air, the probabilities of every light (the
/// panel's two triangles each) sum to one, `pick`'s stated probability is
/// `prob`'s, and over 20,000 stratified numbers each is chosen as often as its
/// probability says (within four standard deviations).
#[test]
fn the_tree_chooses_lights_by_the_probabilities_it_states() {
    let s = many_lamps(7);
    let tree = LightTree::new(&s, &all(&s)).unwrap();
    assert!(tree.is_split(0) && !tree.is_split(1), "the panel is in the tree triangle by triangle");
    let mut rng = Sampler::new(11, 0);
    for k in 0..12 {
        let u = rng.next_2d();
        let (p, n) = if k % 3 == 2 {
            (Vec3::new(u.x * 3.0 - 1.5, 0.9, u.y * 3.0 - 1.5), Vec3::ZERO)
        } else {
            (Vec3::new(u.x * 3.6 - 1.8, 0.0, u.y * 3.6 - 1.8), Vec3::Y)
        };
        let probs = choices(&s, &tree, p, n);
        let sum: f32 = probs.iter().map(|c| c.1).sum();
        assert!((sum - 1.0).abs() < 1e-4, "at {p}: probabilities sum to {sum}");
        let m = 20_000;
        let mut count = vec![0u32; probs.len()];
        for i in 0..m {
            let (c, pmf) = tree.pick(p, n, (i as f32 + 0.5) / m as f32).expect("a light");
            let k = probs.iter().position(|q| q.0 == c).unwrap();
            let want = probs[k].1;
            assert!((pmf - want).abs() <= 1e-5 * want.max(1e-3), "{c:?}: pick says {pmf}, prob {want}");
            count[k] += 1;
        }
        for ((c, q), &n_k) in probs.iter().zip(&count) {
            let want = *q as f64 * m as f64;
            let sd = (want * (1.0 - *q as f64)).sqrt().max(1.0);
            assert!((n_k as f64 - want).abs() <= 4.0 * sd, "at {p}: {c:?} chosen {n_k} times, expected {want:.1}");
        }
    }
}

/// The bounds are conservative: a light that sends any light to a point is never
/// given probability zero there (sampled points and normals against each light's
/// own emission), and a point no light can reach (above the down-facing panel,
/// with only the panel in the set) gets no light. Near lamps are chosen more
/// than their power alone would choose them: under lamp (0, 0), over five times
/// its share of the power.
#[test]
fn the_tree_never_rules_out_a_light_that_reaches_a_point() {
    let s = many_lamps(5);
    let tree = LightTree::new(&s, &all(&s)).unwrap();
    let mut rng = Sampler::new(5, 1);
    for _ in 0..400 {
        let (u, w) = (rng.next_2d(), rng.next_2d());
        let p = Vec3::new(u.x * 4.0 - 2.0, w.x * 2.5, u.y * 4.0 - 2.0);
        let n = pm_sampling::uniform_sphere(rng.next_2d());
        for (c, q) in choices(&s, &tree, p, n) {
            let light = &s.lights[c.light];
            let ls = match c.tri {
                Some(i) => light.sample_triangle(&s, p, i as usize, true, w),
                None => light.sample_li(&s, p, n, 0.5, w),
            };
            if ls.is_some_and(|ls| ls.li.max_element() > 0.0 && ls.pdf > 0.0 && ls.wi.dot(n) != 0.0) {
                assert!(q > 0.0, "{c:?} reaches {p} (n {n}) but has probability 0");
            }
        }
    }
    let panel = LightTree::new(&s, &[0]).unwrap();
    let LightKind::Area { two_sided, .. } = s.lights[0].kind else { panic!() };
    assert!(!two_sided && s.triangles[2].ng().y < 0.0, "the panel emits downward only");
    assert!(panel.pick(Vec3::new(0.0, 3.0, 0.0), Vec3::ZERO, 0.5).is_none());
    assert!(panel.pick(Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 0.5).is_some());
    let under = Vec3::new(-1.8, 1.0, -1.8);
    let lamp = s.lights.iter().position(|l| l.name == "lamp 0 0").unwrap();
    let total: f32 = s.lights.iter().map(|l| l.power.element_sum()).sum();
    let share = s.lights[lamp].power.element_sum() / total;
    let p = tree.prob(lamp, under, Vec3::Y);
    assert!(p > 5.0 * share, "the lamp overhead: probability {p}, its power's share {share}");
}

/// What the tree is for: the variance of a one-light estimate of the irradiance
/// from 49 point lamps (exact: f_l^2 / q_l summed, less the square of the mean)
/// at floor points, with lights chosen by the tree against by power. Over 64
/// points the tree's variance is under a tenth of power's (here 0.025), so its
/// error at equal samples is under a third.
#[test]
fn the_tree_cuts_the_variance_of_a_many_lamp_estimate() {
    let s = many_lamps(7);
    let lamps: Vec<usize> = (0..s.lights.len()).filter(|&i| s.lights[i].name.starts_with("lamp")).collect();
    let tree = LightTree::new(&s, &lamps).unwrap();
    let total: f32 = lamps.iter().map(|&i| s.lights[i].power.element_sum()).sum();
    let (mut var_tree, mut var_power) = (0.0f64, 0.0f64);
    for k in 0..64 {
        let p = Vec3::new(-1.75 + 3.5 * (k % 8) as f32 / 7.0, 0.0, -1.75 + 3.5 * (k / 8) as f32 / 7.0);
        let (mut mean, mut sq_tree, mut sq_power) = (0.0f64, 0.0f64, 0.0f64);
        for &li in &lamps {
            let LightKind::Point { position, intensity } = s.lights[li].kind else { unreachable!() };
            let d = position - p;
            let f = (intensity.element_sum() * d.normalize().y.max(0.0) / d.length_squared()) as f64;
            let q_tree = tree.prob(li, p, Vec3::Y) as f64;
            let q_power = (s.lights[li].power.element_sum() / total) as f64;
            mean += f;
            if f > 0.0 {
                sq_tree += f * f / q_tree;
                sq_power += f * f / q_power;
            }
        }
        var_tree += (sq_tree - mean * mean) / (mean * mean);
        var_power += (sq_power - mean * mean) / (mean * mean);
    }
    let ratio = var_tree / var_power;
    eprintln!("relative variance: tree {:.4}, power {:.4}, ratio {ratio:.3}", var_tree / 64.0, var_power / 64.0);
    assert!(ratio < 0.1, "ratio {ratio}");
}

/// Unbiased through the tree: at floor points of the many-lamp room, direct
/// light on a Lambertian floor by [`DirectLighting::direct`] (the tree choosing
/// among 50 lights, the panel triangle by triangle, 4096 samples) against the
/// exact sum, each lamp's rho / pi I cos / d^2 and the panel's closed form; and
/// on a glossy floor (the glTF dielectric: light and BSDF samples weighed by the
/// power heuristic, the tree's probability at the point in both weights) against
/// 1,000,000 lamp-by-lamp samples of the same BSDF.
#[test]
fn direct_light_chosen_by_the_tree_is_unbiased() {
    let s = many_lamps(7);
    let sampling = crate::DirectLighting::new(&s).unwrap();
    let rho = Rgb::splat(0.5);
    for p in [Vec3::new(0.1, 0.0, 0.2), Vec3::new(-1.3, 0.0, 1.1), Vec3::new(1.7, 0.0, -1.6)] {
        let hit = s.intersect(p + Vec3::Y * 0.5, -Vec3::Y, f32::INFINITY).unwrap();
        let mut want = crate::direct::lambert_unoccluded(&s.lights[0], p, Vec3::Y, rho).0;
        for l in &s.lights[1..] {
            // (None: outside the spot's cone.)
            if let Some(ls) = l.sample_li(&s, p, Vec3::Y, 0.5, glam::Vec2::splat(0.5)) {
                want += rho / std::f32::consts::PI * ls.li * ls.wi.y.max(0.0);
            }
        }
        let mut sampler = Sampler::new(5, 0);
        let got = sampling.direct(&hit, &Bsdf::Lambert { rho }, Vec3::Y, &mut sampler, 4096, None);
        assert!(((got - want) / want).abs().max_element() < 0.01, "{p}: tree {got}, exact {want}");
        // Glossy: every light sampled on its own (its own sample_li, no choice).
        let glossy = Bsdf::from_pbr(&pm_bsdf::Pbr { roughness: 0.3, ..pm_bsdf::Pbr::dielectric(Rgb::splat(0.4)) });
        let wo = Vec3::new(0.3, 0.8, 0.2).normalize();
        let mut reference = Rgb::ZERO;
        let m = 20_000;
        for (li, l) in s.lights.iter().enumerate() {
            let mut sum = Rgb::ZERO;
            let k = if li == 0 { m * 20 } else { 1 };
            for i in 0..k {
                let mut r = Sampler::new(9, i as u64);
                let (u_tri, u) = (r.next_1d(), r.next_2d());
                let Some(ls) = l.sample_li(&s, p, Vec3::Y, u_tri, u) else { continue };
                if ls.wi.y > 0.0 {
                    sum += glossy.f(wo, ls.wi, Vec3::Y) * ls.li * (ls.wi.y / ls.pdf);
                }
            }
            reference += sum / k as f32;
        }
        let hit = s.intersect(p + Vec3::Y * 0.5, -Vec3::Y, f32::INFINITY).unwrap();
        let got = sampling.direct(&hit, &glossy, wo, &mut sampler, 16384, None);
        assert!(
            ((got - reference) / reference).abs().max_element() < 0.015,
            "{p}: glossy, tree {got}, lamp by lamp {reference}"
        );
    }
}
