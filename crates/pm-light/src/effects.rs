//! Which light-transport effects a scene can produce, and why: the analysis behind
//! "simulate only the effects a scene calls for". Each decision is made by shooting
//! a fixed set of probe rays (deterministic), so it is cheap and repeatable.

use pm_bsdf::Bsdf;
use pm_sampling::{Sampler, cosine_hemisphere, to_world};
use pm_scene::{LightKind, Scene, Target};

/// A yes/no decision with the reason in words.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Decision {
    /// Whether the effect can occur.
    pub yes: bool,
    /// Why, naming the objects and lights involved.
    pub reason: String,
}

impl Decision {
    fn yes(reason: String) -> Self {
        Decision { yes: true, reason }
    }
    fn no(reason: String) -> Self {
        Decision { yes: false, reason }
    }
}

/// The effects a scene can produce (`photon-trace --analyze` prints it as JSON and
/// the runner reads it back into this type).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Effects {
    /// Light-specular+-diffuse paths: a mirror or glass object a light reaches, and a
    /// non-specular surface for it to light.
    pub caustics: Decision,
    /// Soft indirect diffuse light: light reflected by a non-specular surface reaches
    /// another non-specular surface.
    pub indirect: Decision,
    /// Mirror or glass seen by the camera (specular recursion from the eye).
    pub specular_seen: Decision,
    /// Glossy (GGX) materials present.
    pub glossy: Decision,
    /// Light scattered in participating media (a volume photon map, in-scattering
    /// along rays): a medium that scatters, which some light's photons reach.
    pub volume: Decision,
    /// Lights by kind, e.g. "1 area light".
    pub direct: String,
}

const PROBES: u64 = 4096;

fn kind_name(b: &Bsdf) -> &'static str {
    match b {
        Bsdf::Mirror { .. } => "mirror",
        Bsdf::Glass { .. } => "glass",
        Bsdf::Conductor { .. } | Bsdf::Plastic { .. } | Bsdf::Layered(_) => "glossy",
        Bsdf::Lambert { .. } => "diffuse",
    }
}

/// The first hit along a ray that is not an index-matched boundary (a fog box's
/// walls, which light passes straight through).
fn first_hit(scene: &Scene, o: glam::Vec3, d: glam::Vec3) -> Option<pm_scene::Hit> {
    scene.intersect_through(o, d, None).hit
}

/// True when material `m` is an index-matched boundary (smooth transmission, ior 1).
fn index_matched(m: &pm_scene::Material) -> bool {
    matches!(m.bsdf, Bsdf::Glass { eta: 1.0, .. })
}

/// Analyse a scene (see [`Effects`]): one probe per effect.
pub fn analyze(scene: &Scene) -> Effects {
    let any_diffuse = scene.triangles.iter().any(|t| !scene.materials[t.material as usize].bsdf.is_specular());
    let caustics = caustics(scene, any_diffuse);
    let indirect = indirect(scene, any_diffuse);
    let specular_seen = specular_seen(scene);
    let glossy = glossy(scene);
    let direct = direct_lights(scene);
    let volume = volume_reached(scene);
    // Light scattered in a medium lights the surfaces too: indirect light that
    // final gathers (reading the volume map along their rays) bring.
    let indirect = if !indirect.yes && volume.yes && any_diffuse {
        Decision::yes(format!("light scattered in the medium ({}) reaches the surfaces", volume.reason))
    } else {
        indirect
    };
    Effects { caustics, indirect, specular_seen, glossy, volume, direct }
}

/// The object triangle `tri` belongs to.
fn object_of(scene: &Scene, tri: u32) -> Option<usize> {
    scene.objects.iter().position(|o| o.tris.contains(&tri))
}

/// The name of the object triangle `tri` belongs to ("?" for none).
fn object_name(scene: &Scene, tri: u32) -> String {
    object_of(scene, tri).map_or_else(|| "?".to_string(), |o| scene.objects[o].name.clone())
}

/// True when triangle `tri`'s material is a mirror or glass.
fn is_specular(scene: &Scene, tri: u32) -> bool {
    scene.materials[scene.triangles[tri as usize].material as usize].bsdf.is_specular()
}

/// Caustics: probe rays aimed from every light that emits at every mirror or
/// glass object (not an index-matched boundary); yes when one hits it first.
fn caustics(scene: &Scene, any_diffuse: bool) -> Decision {
    let lit: Vec<usize> = (0..scene.lights.len()).filter(|&i| scene.lights[i].power.max_element() > 0.0).collect();
    let specular_objects: Vec<usize> = (0..scene.objects.len())
        .filter(|&o| {
            let m = &scene.materials[scene.objects[o].material as usize];
            m.bsdf.is_specular() && !index_matched(m)
        })
        .collect();
    if specular_objects.is_empty() {
        return Decision::no("no mirror or glass surface".into());
    }
    if !any_diffuse {
        return Decision::no("no non-specular surface for focused light to land on".into());
    }
    let mut reached: Vec<(usize, usize)> = Vec::new();
    for &o in &specular_objects {
        let target: Target = scene.objects[o].bounding_sphere(scene);
        for &l in &lit {
            let hit = (0..PROBES / 4).any(|i| {
                let mut s = Sampler::new(0x6361_7573 + o as u64 * 131 + l as u64, i);
                let Some(ray) = scene.lights[l].sample_emission_toward(scene, &mut s, &[target]) else {
                    return false;
                };
                first_hit(scene, ray.origin, ray.dir).is_some_and(|h| object_of(scene, h.tri) == Some(o))
            });
            if hit {
                reached.push((o, l));
            }
        }
    }
    if reached.is_empty() {
        let names: Vec<String> = specular_objects.iter().map(|&o| format!("'{}'", scene.objects[o].name)).collect();
        return Decision::no(format!("{} not reachable from any light", a_few(&names)));
    }
    let mut objs: Vec<String> = reached
        .iter()
        .map(|&(o, _)| {
            let ob = &scene.objects[o];
            format!("{} '{}'", kind_name(&scene.materials[ob.material as usize].bsdf), ob.name)
        })
        .collect();
    objs.dedup();
    let mut lights: Vec<String> = reached.iter().map(|&(_, l)| format!("'{}'", scene.lights[l].name)).collect();
    lights.sort();
    lights.dedup();
    Decision::yes(format!("{} reachable from {}", a_few(&objs), a_few(&lights)))
}

/// The first few of `names` and how many more: a room with 48 lamps names four.
fn a_few(names: &[String]) -> String {
    const FEW: usize = 4;
    match names.len() {
        n if n <= FEW => names.join(", "),
        n => format!("{} and {} more", names[..FEW - 1].join(", "), n - (FEW - 1)),
    }
}

/// Indirect: probe photons leave the lights as the tracer's do (chosen by
/// power), follow specular bounces to their first non-specular hit, bounce once
/// diffusely, and yes when that reaches another non-specular surface.
fn indirect(scene: &Scene, any_diffuse: bool) -> Decision {
    if !any_diffuse {
        return Decision::no("no non-specular surface".into());
    }
    match crate::LightSelector::new(scene, &[]).ok().and_then(|selector| diffuse_pair(scene, &selector)) {
        Some((a, b)) => {
            Decision::yes(format!("light reflected by '{}' reaches '{}'", object_name(scene, a), object_name(scene, b)))
        }
        None => Decision::no(format!(
            "no probe of {PROBES} found diffusely reflected light reaching another non-specular surface"
        )),
    }
}

/// The first probe's (diffuse surface lit, non-specular surface its reflection
/// reaches) as triangles, for [`indirect`].
fn diffuse_pair(scene: &Scene, selector: &crate::LightSelector) -> Option<(u32, u32)> {
    'probe: for i in 0..PROBES {
        let mut s = Sampler::new(0x696e_6469, i);
        let (l, _) = selector.pick(s.next_1d());
        let Some(ray) = scene.lights[l].sample_emission(scene, &mut s) else { continue };
        let (mut o, mut d) = (ray.origin, ray.dir);
        for _ in 0..8 {
            let Some(h) = first_hit(scene, o, d) else { continue 'probe };
            let bsdf = scene.bsdf(&h);
            if bsdf.is_specular() {
                let Some(bs) = bsdf.sample(-d, h.ns, s.next_2d(), s.next_1d()) else { continue 'probe };
                o = scene.offset_origin(h.p, h.ng, bs.wi);
                d = bs.wi;
                continue;
            }
            let n = if h.ng.dot(-d) > 0.0 { h.ng } else { -h.ng };
            let d2 = to_world(cosine_hemisphere(s.next_2d()), n);
            let o2 = scene.offset_origin(h.p, h.ng, d2);
            if let Some(h2) = first_hit(scene, o2, d2)
                && !is_specular(scene, h2.tri)
            {
                return Some((h.tri, h2.tri));
            }
            continue 'probe;
        }
    }
    None
}

/// Specular seen by the camera: a grid of 48 x 48 eye rays; yes naming the
/// mirror and glass objects they hit first.
fn specular_seen(scene: &Scene) -> Decision {
    let Some(cam) = &scene.camera else {
        return Decision::no("no camera".into());
    };
    let mut seen: Vec<String> = Vec::new();
    for j in 0..48 {
        for i in 0..48 {
            let aspect = cam.aspect.unwrap_or(1.0);
            let d = cam.ray_direction((i as f32 + 0.5) / 48.0, (j as f32 + 0.5) / 48.0, aspect);
            if let Some(h) = first_hit(scene, cam.position, d)
                && is_specular(scene, h.tri)
            {
                let n = object_name(scene, h.tri);
                if !seen.contains(&n) {
                    seen.push(n);
                }
            }
        }
    }
    if seen.is_empty() {
        return Decision::no("the camera sees no mirror or glass".into());
    }
    Decision::yes(format!("the camera sees {}", seen.iter().map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ")))
}

/// Glossy: the GGX materials some triangle uses.
fn glossy(scene: &Scene) -> Decision {
    let glossy_names: Vec<String> = scene
        .materials
        .iter()
        .enumerate()
        .filter(|(i, m)| {
            matches!(m.bsdf, Bsdf::Conductor { .. } | Bsdf::Plastic { .. } | Bsdf::Layered(_))
                && scene.triangles.iter().any(|t| t.material as usize == *i)
        })
        .map(|(_, m)| format!("'{}'", m.name))
        .collect();
    if glossy_names.is_empty() {
        Decision::no("no glossy material".into())
    } else {
        Decision::yes(format!("glossy materials {}", glossy_names.join(", ")))
    }
}

/// The lights by kind, e.g. "1 area light, 2 point lights".
fn direct_lights(scene: &Scene) -> String {
    let mut counts = [0usize; 6];
    for l in &scene.lights {
        counts[match l.kind {
            LightKind::Area { .. } => 0,
            LightKind::Point { .. } => 1,
            LightKind::Spot { .. } => 2,
            LightKind::Directional { cap, .. } if cap > 0.0 => 3,
            LightKind::Directional { .. } => 4,
            LightKind::Environment { .. } => 5,
        }] += 1;
    }
    ["area", "point", "spot", "sun disc", "directional", "environment"]
        .iter()
        .zip(counts)
        .filter(|(_, c)| *c > 0)
        .map(|(k, c)| format!("{c} {k} light{}", if c == 1 { "" } else { "s" }))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether light reaches a scattering medium: probe photons leave the lights by
/// power and follow specular bounces and index-matched boundaries (up to 8 events,
/// tracking the medium they are in) until one runs through a medium that scatters.
fn volume_reached(scene: &Scene) -> Decision {
    let scattering: Vec<&str> = scene.media.iter().filter(|m| m.scatters()).map(|m| m.name.as_str()).collect();
    if scattering.is_empty() {
        return Decision::no("no medium that scatters".into());
    }
    let Ok(selector) = crate::LightSelector::new(scene, &[]) else {
        return Decision::no("no light".into());
    };
    for i in 0..PROBES {
        let mut s = Sampler::new(0x766f_6c75, i);
        let (l, _) = selector.pick(s.next_1d());
        let Some(ray) = scene.lights[l].sample_emission(scene, &mut s) else { continue };
        let (mut o, mut d, mut medium) = (ray.origin, ray.dir, scene.light_medium(l));
        for _ in 0..8 {
            if let Some(m) = scene.medium(medium).filter(|m| m.scatters()) {
                return Decision::yes(format!("light from '{}' enters medium '{}'", scene.lights[l].name, m.name));
            }
            let Some(h) = scene.intersect(o, d, f32::INFINITY) else { break };
            let wi = if scene.index_matched(&h).is_some() {
                d
            } else {
                let bsdf = scene.bsdf(&h);
                if !bsdf.is_specular() {
                    break;
                }
                let Some(bs) = bsdf.sample(-d, h.ns, s.next_2d(), s.next_1d()) else { break };
                bs.wi
            };
            medium = scene.medium_after(&h, wi, medium);
            o = scene.offset_origin(h.p, h.ng, wi);
            d = wi;
        }
    }
    let names: Vec<String> = scattering.iter().map(|n| format!("'{n}'")).collect();
    Decision::no(format!("no probe of {PROBES} from the lights reaches medium {}", names.join(", ")))
}

#[cfg(test)]
mod tests {
    /// Four names or fewer are all listed; more, the first three and a count.
    #[test]
    fn a_few_names_and_how_many_more() {
        let names: Vec<String> = (1..=48).map(|i| format!("'lamp {i}'")).collect();
        assert_eq!(super::a_few(&names[..4]), "'lamp 1', 'lamp 2', 'lamp 3', 'lamp 4'");
        assert_eq!(super::a_few(&names), "'lamp 1', 'lamp 2', 'lamp 3' and 45 more");
    }
}
