//! Light sources and the sampling of emitted rays (photon emission, Jensen 1996;
//! pbrt-v4 section 12 for the emission distributions).

use crate::Scene;
use glam::Vec3;
use pm_color::Rgb;
use pm_sampling::{
    FOUR_PI, Sampler, concentric_disk, cosine_hemisphere, in_cap, sample_cdf, to_world, uniform_cap, uniform_cap_pdf,
    uniform_cone, uniform_cone_pdf, uniform_sphere,
};
use std::f32::consts::{PI, TAU};

/// What kind of emitter a light is, with its parameters in world space.
#[derive(Clone, Debug)]
pub enum LightKind {
    /// The emissive triangles of one mesh primitive instance.
    Area {
        /// Triangle ids.
        tris: std::ops::Range<u32>,
        /// Cumulative triangle weights for picking a triangle: areas [m^2] (uniform
        /// by area) for a uniform emitter, emitted power \[W\] for a textured one.
        cdf: Vec<f64>,
        /// Total area [m^2].
        area: f32,
        /// Emitted radiance L_e [W sr^-1 m^-2 per channel] of the material's factors
        /// (an emissive texture varies it over the surface).
        emission: Rgb,
        /// For a textured emitter, per triangle the area one pick of a point on it
        /// stands for, A_tri / p_tri [m^2] (the inverse of its area density); empty
        /// for a uniform emitter, where every pick stands for `area`.
        area_per_pick: Vec<f32>,
        /// Per triangle its centroid and squared bounding radius about it [m, m^2],
        /// for the solid-angle sampling decision (`near_solid_angle`).
        spheres: Vec<[f32; 4]>,
        /// Both faces emit.
        two_sided: bool,
        /// The outline of a planar one-sided light of at most [`OUTLINE_TRIANGLES`]
        /// triangles, for its closed-form irradiance ([`Light::cos_integral`]).
        outline: Option<Outline>,
    },
    /// Isotropic point light.
    Point {
        /// Position \[m\].
        position: Vec3,
        /// Radiant intensity I [W sr^-1 per channel].
        intensity: Rgb,
    },
    /// Spot light with the glTF cone falloff: (t)^2 with t the linear ramp of
    /// cos(theta) between the outer and inner cone (KHR_lights_punctual spec).
    Spot {
        /// Position \[m\].
        position: Vec3,
        /// Unit axis (the light node's -Z).
        direction: Vec3,
        /// Radiant intensity on the axis I [W sr^-1 per channel].
        intensity: Rgb,
        /// cos(inner cone angle).
        cos_inner: f32,
        /// cos(outer cone angle).
        cos_outer: f32,
    },
    /// Distant light: parallel rays, or a sun with a size: a disc of directions
    /// of uniform radiance (issue 37, `sun_angle_deg`).
    Directional {
        /// Unit direction the light travels (the node's -Z; the disc's axis).
        direction: Vec3,
        /// Irradiance E on a surface facing the light [W m^-2 per channel]; a sun
        /// with a size keeps it at normal incidence (its radiance is E over the
        /// disc's projected solid angle, [`sun_radiance`]).
        irradiance: Rgb,
        /// 1 - cos of the disc's angular radius; 0 for parallel rays (a delta light).
        cap: f32,
        /// Centre of the scene's bounding sphere \[m\].
        center: Vec3,
        /// Radius of the scene's bounding sphere \[m\]: photons start on a disk this big.
        radius: f32,
    },
    /// Light from infinitely far away in every direction: an environment image or
    /// colour ([`crate::Environment`]; pbrt-v4's `ImageInfiniteLight`).
    Environment {
        /// The radiance at infinity.
        env: std::sync::Arc<crate::Environment>,
        /// Centre of the scene's bounding sphere \[m\].
        center: Vec3,
        /// Radius of the scene's bounding sphere \[m\]: photons start on a disk this big.
        radius: f32,
        /// The openings it lights the scene through ([`crate::Portal`]); empty: the
        /// whole sphere of directions.
        portals: Vec<crate::Portal>,
    },
}

/// Radiance L [W sr^-1 m^-2 per channel] of a sun disc of `cap` = 1 - cos(theta_max)
/// that gives irradiance `e` [W m^-2] at normal incidence: E = L pi sin^2(theta_max)
/// and sin^2 = cap (2 - cap).
pub fn sun_radiance(e: Rgb, cap: f32) -> Rgb {
    e / (PI * cap * (2.0 - cap))
}

/// A light source.
#[derive(Clone, Debug)]
pub struct Light {
    /// Name from the file (node or material name).
    pub name: String,
    /// Parameters.
    pub kind: LightKind,
    /// Emitted power Phi [W per channel]; for lights at infinity the power crossing
    /// a disc of the scene's bounding radius R facing each direction they shine
    /// from: E pi R^2 for parallel rays, pi R^2 times the integral of the radiance
    /// over the directions for a sun with a size and an environment.
    pub power: Rgb,
}

/// A planar area light's shape as polygons, for Lambert's closed-form irradiance.
#[derive(Clone, Debug)]
pub struct Outline {
    /// One polygon when the triangles' unshared edges form a single loop of at most
    /// [`OUTLINE_CORNERS`] corners (a quad's four corners: the edges inside cancel in
    /// Lambert's formula), else each triangle; corners in order [m].
    polys: Vec<Vec<Vec3>>,
    /// Unit normal of the emitting side.
    normal: Vec3,
}

/// Planar one-sided area lights of at most this many triangles get an [`Outline`].
pub const OUTLINE_TRIANGLES: usize = 64;

/// Most corners of an outline polygon.
const OUTLINE_CORNERS: usize = 16;

impl Outline {
    /// The outline of triangles `t`, when they are planar (every normal within 0.1
    /// degrees of the first's) and at most [`OUTLINE_TRIANGLES`].
    fn of(t: &[&crate::Triangle]) -> Option<Outline> {
        let normal = t.first()?.ng();
        if t.len() > OUTLINE_TRIANGLES || !t.iter().all(|q| q.ng().dot(normal) >= 0.999_998) {
            return None;
        }
        Some(Outline { polys: outline_polygons(t), normal })
    }
}

/// The outline of planar triangles `t` as one polygon (corners in order) when the
/// edges that no neighbour shares form a single loop of at most
/// [`OUTLINE_CORNERS`] corners; else each triangle on its own. Corners are matched
/// by their exact coordinates (a mesh's shared vertices).
fn outline_polygons(t: &[&crate::Triangle]) -> Vec<Vec<Vec3>> {
    let key = |v: Vec3| v.to_array().map(f32::to_bits);
    let mut edges: Vec<([u32; 3], [u32; 3], Vec3)> = Vec::new();
    for q in t {
        for i in 0..3 {
            edges.push((key(q.p[i]), key(q.p[(i + 1) % 3]), q.p[i]));
        }
    }
    let boundary: Vec<&([u32; 3], [u32; 3], Vec3)> =
        edges.iter().filter(|e| !edges.iter().any(|f| f.0 == e.1 && f.1 == e.0)).collect();
    let per_triangle = || t.iter().map(|q| q.p.to_vec()).collect();
    let Some(first) = boundary.first() else { return per_triangle() };
    let mut poly = vec![first.2];
    let mut at = first.1;
    while at != first.0 {
        let mut next = boundary.iter().filter(|e| e.0 == at);
        let (Some(e), None) = (next.next(), next.next()) else { return per_triangle() };
        poly.push(e.2);
        at = e.1;
        if poly.len() > boundary.len() {
            return per_triangle();
        }
    }
    if poly.len() != boundary.len() || poly.len() > OUTLINE_CORNERS {
        return per_triangle();
    }
    vec![poly]
}

/// A ray leaving a light, with the power it carries if it were the only sample.
#[derive(Clone, Copy, Debug)]
pub struct EmittedRay {
    /// Start point \[m\], already offset off an emitting surface.
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    /// Phi-hat = L_e cos / (pdf_pos pdf_dir) (or its punctual analogue) [W per channel]:
    /// the photon's power before dividing by the number emitted and the light's
    /// selection probability.
    pub power: Rgb,
}

/// A sphere that bounds an object photons can be aimed at (the bounding-sphere form
/// of Jensen's projection maps).
#[derive(Clone, Copy, Debug)]
pub struct Target {
    /// Centre \[m\].
    pub center: Vec3,
    /// Radius \[m\].
    pub radius: f32,
}

impl Light {
    /// The area light made of triangles `tris` of `triangles`, emitting like
    /// `material` (power is filled in when the scene is built).
    pub fn area(
        name: String,
        tris: std::ops::Range<u32>,
        triangles: &[crate::Triangle],
        material: &crate::Material,
    ) -> Light {
        let mut acc = 0.0f64;
        let cdf = tris
            .clone()
            .map(|t| {
                acc += triangles[t as usize].area() as f64;
                acc
            })
            .collect();
        let spheres = tris
            .clone()
            .map(|t| {
                let p = triangles[t as usize].p;
                let c = (p[0] + p[1] + p[2]) * (1.0 / 3.0);
                let r2 = p.iter().map(|v| (*v - c).length_squared()).fold(0.0f32, f32::max);
                [c.x, c.y, c.z, r2]
            })
            .collect();
        let t: Vec<&crate::Triangle> = tris.clone().map(|i| &triangles[i as usize]).collect();
        let outline = if material.double_sided { None } else { Outline::of(&t) };
        Light {
            name,
            kind: LightKind::Area {
                tris,
                cdf,
                area: acc as f32,
                emission: material.emission,
                area_per_pick: Vec::new(),
                spheres,
                two_sided: material.double_sided,
                outline,
            },
            power: Rgb::ZERO,
        }
    }

    /// Sample an emitted ray distributed like the light's emission (so every sample
    /// carries the same power: exact importance sampling of emitted power).
    pub fn sample_emission(&self, scene: &Scene, s: &mut Sampler) -> Option<EmittedRay> {
        self.sample_emission_toward(scene, s, &[])
    }

    /// Sample an emitted ray; with `targets`, aim it at one of the spheres (chosen
    /// uniformly) and weight by the mixture density of all of them, so the estimate
    /// of any light path that starts toward a target stays unbiased. Rays that would
    /// carry no power return `None`.
    pub fn sample_emission_toward(&self, scene: &Scene, s: &mut Sampler, targets: &[Target]) -> Option<EmittedRay> {
        let u_pos = s.next_2d();
        let u_sel = s.next_1d();
        let u_dir = s.next_2d();
        let u_tgt = s.next_1d();
        let pick = |u: f32| &targets[((u * targets.len() as f32) as usize).min(targets.len() - 1)];
        // Mixture density over the cones from `o` to each target [sr^-1]; 0 outside all.
        let cone_pdf = |o: Vec3, d: Vec3| -> f32 {
            let mut pdf = 0.0;
            for t in targets {
                let (axis, cos_max) = cone_to(o, t);
                if d.dot(axis) >= cos_max {
                    pdf += uniform_cone_pdf(cos_max);
                }
            }
            pdf / targets.len() as f32
        };
        let cone_dir = |o: Vec3, t: &Target| -> Vec3 {
            let (axis, cos_max) = cone_to(o, t);
            to_world(uniform_cone(u_dir, cos_max), axis)
        };
        match &self.kind {
            LightKind::Area { two_sided, .. } => {
                let AreaPick { tri, p, le: emission, area, .. } = self.pick_area_point(scene, u_sel, u_pos)?;
                let ng = tri.ng();
                let (n, sides) = if *two_sided && u_tgt < 0.5 && targets.is_empty() {
                    (-ng, 2.0)
                } else if *two_sided {
                    (ng, 2.0)
                } else {
                    (ng, 1.0)
                };
                let (dir, power) = if targets.is_empty() {
                    // pdf_pos = 1/A, pdf_dir = cos/pi (per side), so Phi-hat = L_e pi A sides.
                    (to_world(cosine_hemisphere(u_dir), n), emission * (PI * area * sides))
                } else {
                    let d = cone_dir(p, pick(u_tgt));
                    let cos = if *two_sided { d.dot(ng).abs() } else { d.dot(ng) };
                    let pdf = cone_pdf(p, d);
                    if cos <= 0.0 || pdf <= 0.0 {
                        return None;
                    }
                    (d, emission * (cos * area / pdf))
                };
                let origin = scene.offset_origin(p, ng, dir);
                Some(EmittedRay { origin, dir, power })
            }
            LightKind::Point { position, intensity } => {
                if targets.is_empty() {
                    Some(EmittedRay { origin: *position, dir: uniform_sphere(u_dir), power: *intensity * FOUR_PI })
                } else {
                    let d = cone_dir(*position, pick(u_tgt));
                    let pdf = cone_pdf(*position, d);
                    (pdf > 0.0).then(|| EmittedRay { origin: *position, dir: d, power: *intensity / pdf })
                }
            }
            LightKind::Spot { position, direction, intensity, cos_inner, cos_outer } => {
                let (d, pdf) = if targets.is_empty() {
                    (to_world(uniform_cone(u_dir, *cos_outer), *direction), uniform_cone_pdf(*cos_outer))
                } else {
                    let d = cone_dir(*position, pick(u_tgt));
                    (d, cone_pdf(*position, d))
                };
                let f = spot_falloff(d.dot(*direction), *cos_inner, *cos_outer);
                (f > 0.0 && pdf > 0.0).then(|| EmittedRay { origin: *position, dir: d, power: *intensity * (f / pdf) })
            }
            LightKind::Directional { center, radius, .. } => {
                // A direction in the disc, each carrying L / pdf = L 2 pi cap (E for
                // parallel rays).
                let sd = self.sample_sky_dir(u_dir)?;
                from_disc(-sd.wi, sd.l / sd.pdf, *center, *radius, targets, u_pos, u_tgt)
            }
            LightKind::Environment { center, radius, portals, .. } if portals.is_empty() => {
                // pbrt-v4's ImageInfiniteLight::SampleLe: a direction by the image's
                // radiance, carrying L / pdf, then a point on the disc facing it.
                let sd = self.sample_sky_dir(u_dir)?;
                from_disc(-sd.wi, sd.l / sd.pdf, *center, *radius, targets, u_pos, u_tgt)
            }
            LightKind::Environment { env, portals, .. } => {
                // Through a portal (chosen by area, a point uniform on it): a
                // direction by the image's radiance from outside it, carrying
                // L cos A / pdf (A all portals' area); the caustic pass does not aim.
                let (portal, total_area) = pick_portal(portals, u_sel);
                let es = env.sample(u_dir)?;
                let cos = es.wi.dot(portal.outward);
                if cos <= 0.0 {
                    return None;
                }
                let q = portal.point(u_pos);
                let origin = q + es.wi * (1e-4 * scene.bounds.diagonal());
                Some(EmittedRay { origin, dir: -es.wi, power: es.l * (cos * total_area / es.pdf) })
            }
        }
    }
}

/// A direction a light at infinity sends light from, as its photons leave it
/// ([`Light::sample_sky_dir`]).
#[derive(Clone, Copy, Debug)]
pub struct SkyDirection {
    /// Unit direction toward the sky (the light travels along -wi).
    pub wi: Vec3,
    /// Radiance along it [W sr^-1 m^-2 per channel]; for parallel rays their
    /// irradiance E on a surface facing them [W m^-2 per channel].
    pub l: Rgb,
    /// Its solid-angle density [sr^-1]; 1 for parallel rays.
    pub pdf: f32,
    /// Parallel rays: one direction (a Dirac delta).
    pub delta: bool,
}

impl Light {
    /// For a light at infinity, a direction it sends light from, sampled as its
    /// photons are emitted (`u` uniform): uniform over a sun's disc, by an
    /// environment's radiance ([`crate::Environment::sample`], portals aside),
    /// parallel rays' one direction; none for other lights.
    pub fn sample_sky_dir(&self, u: glam::Vec2) -> Option<SkyDirection> {
        match &self.kind {
            LightKind::Directional { direction, irradiance, cap, .. } if *cap > 0.0 => {
                let wi = to_world(uniform_cap(u, *cap), -*direction);
                Some(SkyDirection { wi, l: sun_radiance(*irradiance, *cap), pdf: uniform_cap_pdf(*cap), delta: false })
            }
            LightKind::Directional { direction, irradiance, .. } => {
                Some(SkyDirection { wi: -*direction, l: *irradiance, pdf: 1.0, delta: true })
            }
            LightKind::Environment { env, .. } => {
                let es = env.sample(u)?;
                Some(SkyDirection { wi: es.wi, l: es.l, pdf: es.pdf, delta: false })
            }
            _ => None,
        }
    }

    /// The density [sr^-1] with which [`Self::sample_sky_dir`] gives unit `wi`
    /// (toward the sky); zero for parallel rays and lights not at infinity.
    pub fn pdf_sky_dir(&self, wi: Vec3) -> f32 {
        match &self.kind {
            LightKind::Directional { direction, cap, .. } if *cap > 0.0 && in_cap(wi, -*direction, *cap) => {
                uniform_cap_pdf(*cap)
            }
            LightKind::Environment { env, .. } => env.pdf(wi),
            _ => 0.0,
        }
    }

    /// For a light at infinity, where a ray of it travelling along unit `dir`
    /// starts: a point uniform (`u`) on the disc of the scene's bounding sphere
    /// perpendicular to `dir`, outside the sphere (what [`Light::sample_emission`]
    /// does without targets); none for other lights.
    pub fn sky_origin(&self, dir: Vec3, u: glam::Vec2) -> Option<Vec3> {
        let (LightKind::Directional { center, radius, .. } | LightKind::Environment { center, radius, .. }) =
            &self.kind
        else {
            return None;
        };
        Some(disc_origin(dir, *center, *radius, *center, *radius, u))
    }

    /// The density [m^-2] of [`Self::sky_origin`]'s point on its disc, 1 / (pi
    /// R^2); zero for lights not at infinity.
    pub fn pdf_sky_origin(&self) -> f32 {
        match &self.kind {
            LightKind::Directional { radius, .. } | LightKind::Environment { radius, .. } => {
                1.0 / (PI * radius * radius)
            }
            _ => 0.0,
        }
    }
}

/// The portal that `u` in [0, 1) picks, in proportion to area, and all portals'
/// area [m^2]: choosing by area and then a point uniformly gives every point of
/// every portal the same density, 1 / area.
fn pick_portal(portals: &[crate::Portal], u: f32) -> (&crate::Portal, f32) {
    let total: f32 = portals.iter().map(|p| p.area).sum();
    let mut acc = 0.0;
    for p in portals {
        acc += p.area;
        if u * total < acc {
            return (p, total);
        }
    }
    (portals.last().expect("at least one portal"), total)
}

/// A ray of light at infinity travelling in unit direction `dir`, whose
/// directions carry "irradiance" `e` (E of parallel rays, or L / pdf of a sampled
/// direction) [W m^-2 per channel]: from a point uniform on the disc of the
/// scene's bounding sphere (`center`, `radius`) perpendicular to `dir`, or with
/// `targets` on one target's disc, chosen by `u_tgt` (the mixture of the targets'
/// discs that hold the point weighs it), started outside the bounding sphere.
/// Power e / pdf_area (Jensen 2001, section 5.1; pbrt-v4's `SampleLe`).
fn from_disc(
    dir: Vec3,
    e: Rgb,
    center: Vec3,
    radius: f32,
    targets: &[Target],
    u_pos: glam::Vec2,
    u_tgt: f32,
) -> Option<EmittedRay> {
    let (disk_center, disk_radius) = if targets.is_empty() {
        (center, radius)
    } else {
        let tg = &targets[((u_tgt * targets.len() as f32) as usize).min(targets.len() - 1)];
        (tg.center, tg.radius)
    };
    let origin = disc_origin(dir, center, radius, disk_center, disk_radius, u_pos);
    let area_pdf = if targets.is_empty() {
        1.0 / (PI * radius * radius)
    } else {
        // Mixture of uniform densities over each target's disk (in the plane).
        let mut pdf = 0.0;
        for tg in targets {
            let off = origin - tg.center;
            let perp = off - dir * off.dot(dir);
            if perp.length_squared() <= tg.radius * tg.radius {
                pdf += 1.0 / (PI * tg.radius * tg.radius);
            }
        }
        pdf / targets.len() as f32
    };
    (area_pdf > 0.0).then(|| EmittedRay { origin, dir, power: e / area_pdf })
}

/// A point uniform (`u_pos`) on the disc of centre `disk_center` and radius
/// `disk_radius` perpendicular to unit `dir`, moved back along `dir` to start
/// outside the scene's bounding sphere (`center`, `radius`) \[m\].
fn disc_origin(dir: Vec3, center: Vec3, radius: f32, disk_center: Vec3, disk_radius: f32, u_pos: glam::Vec2) -> Vec3 {
    let (t, b) = pm_sampling::basis(dir);
    let q = concentric_disk(u_pos) * disk_radius;
    // Start outside the scene's bounding sphere, on the plane through disk_center.
    let along = (disk_center - center).dot(dir);
    disk_center + t * q.x + b * q.y - dir * (along + radius * 1.01 + 1e-6)
}

/// Area-light triangles are sampled by solid angle from points nearer to them than
/// half their bounding radius. Sampled by area, a light sample's weight
/// cos_l A / d^2 grows without bound as the point nears the triangle (a floor at
/// the foot of an emitting panel; a facet of an emitting sphere seen from the next
/// facet); by solid angle it is at most Ω. Farther away the two are nearly alike and
/// area sampling is cheaper (no trigonometry).
const SOLID_ANGLE_NEAR: f32 = 0.5;

/// The solid angle [sr] triangle `tri` (of bounding `sphere`: centroid, squared
/// radius) subtends at `p`, with the unit directions to its corners, when `p` is
/// near enough for solid-angle sampling (see
/// [`SOLID_ANGLE_NEAR`]) and the solid angle is not degenerate; `None` otherwise.
/// Sampling and its density both decide by this, so they agree.
///
/// A point in the triangle's plane (a path's vertex on the light itself) sees it
/// edge-on, a solid angle of zero; computed from the corners' directions, which
/// then surround the point, it came out as a hemisphere (2 pi), and a two-sided
/// light lit every point of itself with its own emission: a reflecting
/// two-sided panel sent 1.8 times its light on into the room, and the path
/// tracer's image was 2.6% bright against Mitsuba 3 (the differential checker's
/// scene 23 of seed 5092; tests/tests/suite/hard_scenes.rs).
fn near_solid_angle(tri: &crate::Triangle, sphere: [f32; 4], p: Vec3) -> Option<(f32, [Vec3; 3])> {
    let (c, r2) = (Vec3::new(sphere[0], sphere[1], sphere[2]), sphere[3]);
    // Cheap first: beyond (1 + NEAR) r of the centroid the triangle is beyond NEAR r.
    let (near2, far) = (SOLID_ANGLE_NEAR * SOLID_ANGLE_NEAR * r2, 1.0 + SOLID_ANGLE_NEAR);
    if (p - c).length_squared() >= far * far * r2 || (closest_point(tri, p) - p).length_squared() >= near2 {
        return None;
    }
    // In the plane, to the rounding of a hit point's coordinates.
    let height = (p - tri.p[0]).dot(tri.ng()).abs();
    if height <= 4.0 * f32::EPSILON * p.abs().max(c.abs()).max_element() + 1e-6 * r2.sqrt() {
        return None;
    }
    let v = tri.p.map(|q| (q - p).normalize_or_zero());
    if v.contains(&Vec3::ZERO) {
        return None;
    }
    let omega = pm_sampling::spherical_triangle_area(v[0], v[1], v[2]);
    (omega > 1e-5 && omega.is_finite()).then_some((omega, v))
}

/// The point of triangle `tri` nearest `p` (Ericson 2004, "Real-Time Collision
/// Detection", section 5.1.5: by the Voronoi region of `p`).
fn closest_point(tri: &crate::Triangle, p: Vec3) -> Vec3 {
    let [a, b, c] = tri.p;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Barycentrics of a point `q` in the plane of `tri`.
fn barycentrics(tri: &crate::Triangle, q: Vec3) -> [f32; 3] {
    let (e1, e2, d) = (tri.p[1] - tri.p[0], tri.p[2] - tri.p[0], q - tri.p[0]);
    let n = e1.cross(e2);
    let inv = 1.0 / n.length_squared().max(f32::MIN_POSITIVE);
    let b1 = d.cross(e2).dot(n) * inv;
    let b2 = e1.cross(d).dot(n) * inv;
    [1.0 - b1 - b2, b1, b2]
}

impl Light {
    /// The light's uniform emitted radiance L_e [W sr^-1 m^-2 per channel] and
    /// ∫ max(0, n·ω) dω \[sr\] over the directions from `p` to it, in closed form:
    /// Lambert's formula over its [`Outline`] clipped to the hemisphere of `n`
    /// ([`pm_sampling::polygon_cos_integral`]); zero behind its emitting side. L_e
    /// times the integral is the unoccluded irradiance [W m^-2] at `p`. `None` for
    /// lights without the closed form: punctual and directional ones, and area lights
    /// that are curved, two-sided, textured or of more than [`OUTLINE_TRIANGLES`]
    /// triangles.
    pub fn cos_integral(&self, p: Vec3, n: Vec3) -> Option<(Rgb, f32)> {
        let (o, emission) = self.uniform_outline()?;
        if (p - o.polys[0][0]).dot(o.normal) <= 0.0 {
            return Some((emission, 0.0));
        }
        let mut e = 0.0;
        for poly in &o.polys {
            let mut rel = [Vec3::ZERO; OUTLINE_CORNERS];
            for (r, q) in rel.iter_mut().zip(poly) {
                *r = *q - p;
            }
            e += pm_sampling::polygon_cos_integral(&rel[..poly.len()], n);
        }
        Some((emission, e))
    }

    /// True when [`Light::cos_integral`] has a closed form for this light.
    pub fn has_cos_integral(&self) -> bool {
        self.uniform_outline().is_some()
    }

    /// True for a light that reaches a point along one direction only: point and
    /// spot lights, and a sun without a size. Its sample never varies, and no
    /// sampled ray finds it.
    pub fn is_delta(&self) -> bool {
        match self.kind {
            LightKind::Point { .. } | LightKind::Spot { .. } => true,
            LightKind::Directional { cap, .. } => cap == 0.0,
            LightKind::Area { .. } | LightKind::Environment { .. } => false,
        }
    }

    /// The outline and uniform radiance of a light with a closed form: an area
    /// light with an [`Outline`] that no emissive texture varies.
    fn uniform_outline(&self) -> Option<(&Outline, Rgb)> {
        match &self.kind {
            LightKind::Area { emission, area_per_pick, outline: Some(o), .. } if area_per_pick.is_empty() => {
                Some((o, *emission))
            }
            _ => None,
        }
    }
}

/// A point picked on an area light (see [`Light::pick_area_point`]).
struct AreaPick<'s> {
    /// Its triangle.
    tri: &'s crate::Triangle,
    /// The point [m].
    p: Vec3,
    /// Emitted radiance there L_e [W sr^-1 m^-2 per channel] (not zero).
    le: Rgb,
    /// The area the pick stands for, 1 / (its area density) [m^2].
    area: f32,
}

/// A point picked on an area light before the point it lights is known
/// ([`Light::pick_point`]).
#[derive(Clone, Copy, Debug)]
pub struct AreaPoint {
    /// The point [m].
    pub p: Vec3,
    /// Its triangle's unit geometric normal.
    ng: Vec3,
    /// Emitted radiance there [W sr^-1 m^-2 per channel].
    le: Rgb,
    /// The area the pick stands for, 1 / (its area density) [m^2].
    area: f32,
}

impl From<AreaPick<'_>> for AreaPoint {
    fn from(a: AreaPick<'_>) -> AreaPoint {
        AreaPoint { p: a.p, ng: a.tri.ng(), le: a.le, area: a.area }
    }
}

impl Light {
    /// A point on an area light, by area (by emitted power for a textured one),
    /// picked before the point it is to light is known: sampling in a medium
    /// picks the light's point first and then distances along the ray
    /// equiangular about it (Kulla and Fajardo 2012 section 4.2). `None` for other
    /// lights and where the point emits nothing.
    pub fn pick_point(&self, scene: &Scene, u_sel: f32, u: glam::Vec2) -> Option<AreaPoint> {
        self.pick_area_point(scene, u_sel, u).map(AreaPoint::from)
    }

    /// The light sample toward `p` from the area light's point `q`: its direction,
    /// distance, radiance and solid-angle density (the area density converted,
    /// d^2 / (cos_l A)); `None` when `p` is behind a one-sided light or on `q`.
    pub fn sample_from(&self, q: &AreaPoint, p: Vec3) -> Option<LightSample> {
        let LightKind::Area { two_sided, .. } = &self.kind else { return None };
        let d = q.p - p;
        let dist2 = d.length_squared();
        if !(dist2 > 0.0) {
            return None;
        }
        let dist = dist2.sqrt();
        let wi = d / dist;
        let cos_l = -wi.dot(q.ng);
        let cos_l = if *two_sided { cos_l.abs() } else { cos_l };
        if cos_l <= 0.0 {
            return None;
        }
        Some(LightSample { wi, dist, li: q.le, pdf: dist2 / (cos_l * q.area), delta: false, normal: q.ng })
    }

    /// Pick a point on an area light: a triangle from the light's cdf (by area, or by
    /// emitted power for a textured emitter), then a uniform point on it. `None` for
    /// other lights and where the point emits nothing.
    fn pick_area_point<'s>(&self, scene: &'s Scene, u_sel: f32, u: glam::Vec2) -> Option<AreaPick<'s>> {
        let LightKind::Area { cdf, .. } = &self.kind else { return None };
        self.area_point(scene, sample_cdf(cdf, u_sel), u)
    }

    /// [`Self::pick_area_point`] on the light's `i`-th triangle, already chosen.
    fn area_point<'s>(&self, scene: &'s Scene, i: usize, u: glam::Vec2) -> Option<AreaPick<'s>> {
        let LightKind::Area { tris, area, emission, area_per_pick, .. } = &self.kind else { return None };
        let id = tris.start + i as u32;
        let tri = &scene.triangles[id as usize];
        let b = pm_sampling::uniform_triangle(u);
        let b = [b.x, b.y, 1.0 - b.x - b.y];
        let p = tri.point(b);
        let (le, area) = pick_radiance(scene, id, i, b, *emission, *area, area_per_pick);
        (le != Rgb::ZERO).then_some(AreaPick { tri, p, le, area })
    }
}

/// Emitted radiance L_e [W sr^-1 m^-2 per channel] at barycentrics `b` of an area
/// light's triangle `id` (its `i`-th), and the area one pick there stands for,
/// A_tri / p_tri [m^2]: the material's `emission` and the light's total `area` for a
/// uniform emitter, per triangle (`area_per_pick`) for a textured one.
fn pick_radiance(
    scene: &Scene,
    id: u32,
    i: usize,
    b: [f32; 3],
    emission: Rgb,
    area: f32,
    area_per_pick: &[f32],
) -> (Rgb, f32) {
    match area_per_pick.get(i) {
        Some(&a) => (scene.emission_at(id, b), a),
        None => (emission, area),
    }
}

/// A point a light emits from, picked as a light path's start is, with its area
/// density: what the methods that weigh every way a path could have been made
/// (bidirectional path tracing, vertex connection and merging) need of a light
/// (pbrt-v4's `Light::SampleLe` and `PDF_Le`, position and direction kept apart).
#[derive(Clone, Copy, Debug)]
pub struct EmitterPoint {
    /// The point \[m\].
    pub p: Vec3,
    /// Unit geometric normal of its triangle (winding order); zero for a point or
    /// spot light.
    pub n: Vec3,
    /// Emitted radiance L_e there [W sr^-1 m^-2 per channel] on an emitting side
    /// (area lights), or the radiant intensity on the axis I [W sr^-1 per channel]
    /// (point and spot lights).
    pub le: Rgb,
    /// Area density of the point given the light [m^-2]: 1 / the area a pick
    /// stands for; 1 for a point or spot light (a delta in position).
    pub pdf_pos: f32,
}

impl Light {
    /// The point a light path starts from ([`Light::pick_area_point`] for an area
    /// light: by area, or by power for a textured one), `u_sel` choosing the
    /// triangle and `u` the point on it. `None` for lights at infinity and where
    /// the point emits nothing.
    pub fn emitter_point(&self, scene: &Scene, u_sel: f32, u: glam::Vec2) -> Option<EmitterPoint> {
        match &self.kind {
            LightKind::Area { .. } => {
                let a = self.pick_area_point(scene, u_sel, u)?;
                Some(EmitterPoint { p: a.p, n: a.tri.ng(), le: a.le, pdf_pos: 1.0 / a.area })
            }
            LightKind::Point { position, intensity } | LightKind::Spot { position, intensity, .. } => {
                Some(EmitterPoint { p: *position, n: Vec3::ZERO, le: *intensity, pdf_pos: 1.0 })
            }
            LightKind::Directional { .. } | LightKind::Environment { .. } => None,
        }
    }

    /// The point of an area light's triangle `tri` at barycentrics `b`, as
    /// [`Light::emitter_point`] would have picked it (for a point an eye path found
    /// on the light); `None` when the triangle is not this light's.
    pub fn emitter_point_at(&self, scene: &Scene, tri: u32, b: [f32; 3]) -> Option<EmitterPoint> {
        let LightKind::Area { tris, area, emission, area_per_pick, .. } = &self.kind else { return None };
        if !tris.contains(&tri) {
            return None;
        }
        let t = &scene.triangles[tri as usize];
        let i = (tri - tris.start) as usize;
        let (le, per_pick) = pick_radiance(scene, tri, i, b, *emission, *area, area_per_pick);
        Some(EmitterPoint { p: t.point(b), n: t.ng(), le, pdf_pos: 1.0 / per_pick })
    }

    /// What the light sends from `q` along unit direction `dir`: radiance L_e
    /// [W sr^-1 m^-2] from an area light's emitting side (zero behind a one-sided
    /// one), radiant intensity [W sr^-1] from a point or spot light (the cone's
    /// falloff applied).
    pub fn emitted_toward(&self, q: &EmitterPoint, dir: Vec3) -> Rgb {
        match &self.kind {
            LightKind::Area { two_sided, .. } => {
                let cos = dir.dot(q.n);
                if cos > 0.0 || (*two_sided && cos < 0.0) { q.le } else { Rgb::ZERO }
            }
            LightKind::Point { intensity, .. } => *intensity,
            LightKind::Spot { direction, intensity, cos_inner, cos_outer, .. } => {
                *intensity * spot_falloff(dir.dot(*direction), *cos_inner, *cos_outer)
            }
            LightKind::Directional { .. } | LightKind::Environment { .. } => Rgb::ZERO,
        }
    }

    /// A direction for a light path leaving `q` and its solid-angle density
    /// [sr^-1]: cosine-weighted about the emitting side's normal (a two-sided
    /// light's side chosen by `u_side`, each with probability 1/2), uniform over
    /// the sphere for a point light and over the outer cone for a spot light, as
    /// [`Light::sample_emission`] draws them.
    pub fn sample_emitted_dir(&self, q: &EmitterPoint, u_side: f32, u: glam::Vec2) -> Option<(Vec3, f32)> {
        let dir = match &self.kind {
            LightKind::Area { two_sided, .. } => {
                let n = if *two_sided && u_side < 0.5 { -q.n } else { q.n };
                to_world(cosine_hemisphere(u), n)
            }
            LightKind::Point { .. } => uniform_sphere(u),
            LightKind::Spot { direction, cos_outer, .. } => to_world(uniform_cone(u, *cos_outer), *direction),
            LightKind::Directional { .. } | LightKind::Environment { .. } => return None,
        };
        let pdf = self.pdf_emitted_dir(q, dir);
        (pdf > 0.0).then_some((dir, pdf))
    }

    /// The solid-angle density [sr^-1] with which [`Light::sample_emitted_dir`]
    /// leaves `q` along unit `dir`.
    pub fn pdf_emitted_dir(&self, q: &EmitterPoint, dir: Vec3) -> f32 {
        match &self.kind {
            LightKind::Area { two_sided, .. } => {
                let cos = dir.dot(q.n);
                if *two_sided {
                    0.5 * pm_sampling::cosine_hemisphere_pdf(cos.abs())
                } else {
                    pm_sampling::cosine_hemisphere_pdf(cos.max(0.0))
                }
            }
            LightKind::Point { .. } => 1.0 / FOUR_PI,
            LightKind::Spot { direction, cos_outer, .. } => {
                if dir.dot(*direction) > *cos_outer {
                    uniform_cone_pdf(*cos_outer)
                } else {
                    0.0
                }
            }
            LightKind::Directional { .. } | LightKind::Environment { .. } => 0.0,
        }
    }
}

/// The cone from `o` that bounds target `t`: its axis and the cos of its
/// half-angle; the whole sphere of directions (cos -1) from inside the target.
fn cone_to(o: Vec3, t: &Target) -> (Vec3, f32) {
    let v = t.center - o;
    let (d2, r2) = (v.length_squared(), t.radius * t.radius);
    if d2 > r2 * 1.0001 {
        (v.normalize(), (1.0 - r2 / d2).max(0.0).sqrt())
    } else {
        // From inside the sphere (a light behind a glass panel wider than the
        // gap between them): every direction leads to the target. Such a target
        // once got no photons at all, and the analysis called it unreachable.
        (Vec3::Z, -1.0)
    }
}

/// glTF KHR_lights_punctual spot attenuation: t^2 with t = clamp((cos - cos_outer) /
/// (cos_inner - cos_outer)).
pub fn spot_falloff(cos: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    if cos <= cos_outer {
        return 0.0;
    }
    let range = cos_inner - cos_outer;
    let t = if range <= 1e-6 { 1.0 } else { ((cos - cos_outer) / range).clamp(0.0, 1.0) };
    t * t
}

/// Power of each light, and the scene-dependent parameters of directional lights.
pub(crate) fn finish_lights(scene: &mut Scene) {
    let (center, radius) = scene.world_sphere();
    let mut lights = std::mem::take(&mut scene.lights);
    for light in &mut lights {
        light.power = match &mut light.kind {
            LightKind::Area { tris, cdf, area, emission, area_per_pick, two_sided, .. } => {
                let sides = if *two_sided { 2.0 } else { 1.0 };
                let textured = scene
                    .triangles
                    .get(tris.start as usize)
                    .is_some_and(|t| scene.materials[t.material as usize].emissive_texture.is_some());
                if textured {
                    // Each triangle's mean radiance times its area, so that a
                    // triangle is picked in proportion to the power it emits.
                    let means: Vec<Rgb> = tris.clone().map(|t| scene.mean_emission(t)).collect();
                    let weights: Vec<f64> = tris
                        .clone()
                        .zip(&means)
                        .map(|(t, m)| pm_color::mean(*m) as f64 * scene.triangles[t as usize].area() as f64)
                        .collect();
                    let total: f64 = weights.iter().sum();
                    let mut acc = 0.0;
                    *cdf = weights
                        .iter()
                        .map(|w| {
                            acc += w;
                            acc
                        })
                        .collect();
                    // A triangle (or light) that emits nothing is never picked: its area
                    // density is zero, the area per pick infinite.
                    *area_per_pick = tris
                        .clone()
                        .zip(&weights)
                        .map(|(t, w)| {
                            if total > 0.0 {
                                scene.triangles[t as usize].area() / (w / total) as f32
                            } else {
                                f32::INFINITY
                            }
                        })
                        .collect();
                    let power: Rgb =
                        tris.clone().zip(&means).map(|(t, m)| *m * scene.triangles[t as usize].area()).sum();
                    power * (PI * sides)
                } else {
                    *emission * (PI * *area * sides)
                }
            }
            LightKind::Point { intensity, .. } => *intensity * FOUR_PI,
            // Integral of I t(cos)^2 over the cone: 2 pi I [(1 - ci) + (ci - co) / 3].
            LightKind::Spot { intensity, cos_inner, cos_outer, .. } => {
                *intensity * (TAU * ((1.0 - *cos_inner) + (*cos_inner - *cos_outer) / 3.0))
            }
            LightKind::Directional { irradiance, cap, center: c, radius: r, .. } => {
                *c = center;
                *r = radius;
                if *cap > 0.0 {
                    // L times the disc's solid angle 2 pi cap, through pi R^2.
                    sun_radiance(*irradiance, *cap) * (TAU * *cap * PI * radius * radius)
                } else {
                    *irradiance * (PI * radius * radius)
                }
            }
            LightKind::Environment { env, center: c, radius: r, portals } => {
                *c = center;
                *r = radius;
                if portals.is_empty() {
                    env.integral() * (PI * radius * radius)
                } else {
                    // What crosses the portals inward: A times the irradiance E_n on
                    // each from outside, estimated by the photons' own sampling
                    // (only the light choice uses it: photon power stays exact).
                    portals
                        .iter()
                        .map(|q| {
                            let n = 4096;
                            let mut e = Rgb::ZERO;
                            for k in 0..n {
                                let mut s = Sampler::new(0x706f_7274, k);
                                if let Some(x) = env.sample(s.next_2d()) {
                                    e += x.l * (x.wi.dot(q.outward).max(0.0) / x.pdf);
                                }
                            }
                            e * (q.area / n as f32)
                        })
                        .sum()
                }
            }
        };
    }
    scene.infinite_lights = (0..lights.len() as u32).filter(|&i| lights[i as usize].radiance_escaped_any()).collect();
    scene.lights = lights;
}

/// A sample of direct illumination toward a shading point (next-event estimation).
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point toward the light.
    pub wi: Vec3,
    /// Distance to the sampled point \[m\] (infinite for directional lights).
    pub dist: f32,
    /// Incident radiance L_i [W sr^-1 m^-2] for area lights; for punctual lights the
    /// incident irradiance on a surface facing the light, I / d^2 or E [W m^-2].
    pub li: Rgb,
    /// Solid-angle density of `wi` [sr^-1]; 1 for punctual lights (delta).
    pub pdf: f32,
    /// True for point, spot and parallel directional lights (no MIS with BSDF
    /// sampling).
    pub delta: bool,
    /// Geometric normal of the light's surface at the sampled point (either side):
    /// where a shadow ray leaving from an offset origin meets it; zero for lights
    /// without a surface.
    pub normal: Vec3,
}

impl Light {
    /// Sample a direction toward this light from point `p` (pbrt-v4 section 12.2).
    /// Area lights: a triangle from the light's cdf, then a point on it uniform by
    /// area, converted to solid angle; or, when `p` is near the triangle (see
    /// `near_solid_angle`), a direction uniform in the solid angle it subtends
    /// (Arvo 1995), whose weight stays bounded where the area density's d^2 /
    /// cos goes to zero. A sun with a size: uniform over its disc. An environment:
    /// by its radiance ([`crate::Environment::sample`]), or, one colour, over the
    /// cosine-weighted hemisphere of `n` (the unit normal on the side light may
    /// arrive from), which is then the exact importance of a Lambertian surface, or
    /// for `n` zero (a point in a medium) the whole sphere uniformly.
    pub fn sample_li(&self, scene: &Scene, p: Vec3, n: Vec3, u_sel: f32, u: glam::Vec2) -> Option<LightSample> {
        match &self.kind {
            LightKind::Area { cdf, .. } => self.sample_triangle(scene, p, sample_cdf(cdf, u_sel), false, u),
            LightKind::Point { position, intensity } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                (dist2 > 0.0).then(|| {
                    let dist = dist2.sqrt();
                    LightSample {
                        wi: d / dist,
                        dist,
                        li: *intensity / dist2,
                        pdf: 1.0,
                        delta: true,
                        normal: Vec3::ZERO,
                    }
                })
            }
            LightKind::Spot { position, direction, intensity, cos_inner, cos_outer } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                let dist = dist2.sqrt();
                let wi = d / dist;
                let f = spot_falloff((-wi).dot(*direction), *cos_inner, *cos_outer);
                (f > 0.0).then(|| LightSample {
                    wi,
                    dist,
                    li: *intensity * (f / dist2),
                    pdf: 1.0,
                    delta: true,
                    normal: Vec3::ZERO,
                })
            }
            LightKind::Directional { direction, irradiance, cap, .. } => {
                if *cap > 0.0 {
                    let wi = to_world(uniform_cap(u, *cap), -*direction);
                    let li = sun_radiance(*irradiance, *cap);
                    Some(LightSample {
                        wi,
                        dist: f32::INFINITY,
                        li,
                        pdf: uniform_cap_pdf(*cap),
                        delta: false,
                        normal: Vec3::ZERO,
                    })
                } else {
                    Some(LightSample {
                        wi: -*direction,
                        dist: f32::INFINITY,
                        li: *irradiance,
                        pdf: 1.0,
                        delta: true,
                        normal: Vec3::ZERO,
                    })
                }
            }
            LightKind::Environment { env, portals, .. } if !portals.is_empty() => {
                // One of two strategies, each with probability 1/2 (a defensive
                // mixture, weighed by its mean density): a point uniform over the
                // portals' area, which finds the sky through a window, or the
                // image's own importance, which finds a sun that a point on the
                // window hits too seldom (from a floor 2 m away the sun's disc is
                // 1 in 2,000 of the window's solid angle).
                let wi = if u_sel < 0.5 {
                    env.sample(u)?.wi
                } else {
                    let (portal, _) = pick_portal(portals, 2.0 * u_sel - 1.0);
                    (portal.point(u) - p).normalize_or_zero()
                };
                let pdf = self.pdf_escaped(p, n, wi);
                (pdf > 0.0).then(|| LightSample {
                    wi,
                    dist: f32::INFINITY,
                    li: env.radiance(wi),
                    pdf,
                    delta: false,
                    normal: Vec3::ZERO,
                })
            }
            LightKind::Environment { env, .. } => {
                let (wi, li, pdf) = if env.is_constant() && n == Vec3::ZERO {
                    // A point in a medium: no hemisphere, the whole sphere.
                    let wi = pm_sampling::uniform_sphere(u);
                    (wi, env.radiance(wi), 0.25 * std::f32::consts::FRAC_1_PI)
                } else if env.is_constant() {
                    let wi = to_world(cosine_hemisphere(u), n);
                    (wi, env.radiance(wi), pm_sampling::cosine_hemisphere_pdf(wi.dot(n)))
                } else {
                    let es = env.sample(u)?;
                    (es.wi, es.l, es.pdf)
                };
                (pdf > 0.0).then_some(LightSample {
                    wi,
                    dist: f32::INFINITY,
                    li,
                    pdf,
                    delta: false,
                    normal: Vec3::ZERO,
                })
            }
        }
    }

    /// Radiance [W sr^-1 m^-2 per channel] this light sends along a ray that
    /// leaves the scene in unit direction `wi` (toward the sky): an environment's,
    /// a sun disc's inside the disc, zero for every other light.
    pub fn radiance_escaped(&self, wi: Vec3) -> Rgb {
        match &self.kind {
            LightKind::Environment { env, .. } => env.radiance(wi),
            LightKind::Directional { direction, irradiance, cap, .. }
                if *cap > 0.0 && in_cap(wi, -*direction, *cap) =>
            {
                sun_radiance(*irradiance, *cap)
            }
            _ => Rgb::ZERO,
        }
    }

    /// True for lights that rays leaving the scene can find (an environment, a sun
    /// with a size): [`Self::radiance_escaped`] is not always zero.
    pub fn radiance_escaped_any(&self) -> bool {
        match &self.kind {
            LightKind::Environment { .. } => true,
            LightKind::Directional { cap, .. } => *cap > 0.0,
            _ => false,
        }
    }

    /// Solid-angle density [sr^-1] with which [`Light::sample_li`] at point `p` (with
    /// normal `n`) picks unit direction `wi` toward the sky, for MIS of
    /// BSDF-sampled rays that leave the scene; 0 for lights other than an
    /// environment or a sun disc. With portals: the mixture's, half the image's
    /// density plus half that of the point where the ray leaves through a portal
    /// (none if it leaves through none).
    pub fn pdf_escaped(&self, p: Vec3, n: Vec3, wi: Vec3) -> f32 {
        match &self.kind {
            LightKind::Environment { env, portals, .. } if !portals.is_empty() => {
                let total_area: f32 = portals.iter().map(|q| q.area).sum();
                let mut pdf_portal = 0.0;
                for q in portals {
                    if let Some(t) = q.exit(p, wi) {
                        pdf_portal += t * t / (wi.dot(q.outward) * total_area);
                    }
                }
                0.5 * (env.pdf(wi) + pdf_portal)
            }
            LightKind::Environment { env, .. } if env.is_constant() && n == Vec3::ZERO => {
                0.25 * std::f32::consts::FRAC_1_PI
            }
            LightKind::Environment { env, .. } if env.is_constant() => pm_sampling::cosine_hemisphere_pdf(wi.dot(n)),
            LightKind::Environment { env, .. } => env.pdf(wi),
            LightKind::Directional { direction, cap, .. } if *cap > 0.0 && in_cap(wi, -*direction, *cap) => {
                uniform_cap_pdf(*cap)
            }
            _ => 0.0,
        }
    }

    /// A sample of direction toward the `i`-th triangle of an area light from `p`
    /// (None for other lights): by the solid angle it subtends when near, else a
    /// point on it uniform by area. The pdf [sr^-1] includes the triangle's choice
    /// by the light's own weights, or with `chosen` (the caller chose it, and
    /// multiplies in its probability) none.
    pub fn sample_triangle(
        &self,
        scene: &Scene,
        p: Vec3,
        i: usize,
        chosen: bool,
        u: glam::Vec2,
    ) -> Option<LightSample> {
        let LightKind::Area { tris, area, emission, area_per_pick, spheres, two_sided, .. } = &self.kind else {
            return None;
        };
        let tri = &scene.triangles[(tris.start + i as u32) as usize];
        let Some((omega, v)) = near_solid_angle(tri, spheres[i], p) else {
            // Far from the triangle: a point on it, uniform by area.
            let mut pick: AreaPoint = self.area_point(scene, i, u)?.into();
            if chosen {
                pick.area = tri.area();
            }
            return self.sample_from(&pick, p);
        };
        let wi = pm_sampling::sample_spherical_triangle(v[0], v[1], v[2], omega, u)?;
        let ng = tri.ng();
        let cos_l = -wi.dot(ng);
        if !(if *two_sided { cos_l.abs() } else { cos_l } > 0.0) {
            return None;
        }
        // Where the direction meets the triangle's plane.
        let dist = (tri.p[0] - p).dot(ng) / -cos_l;
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        let id = tris.start + i as u32;
        let b = barycentrics(tri, p + wi * dist);
        let (le, per_pick) = pick_radiance(scene, id, i, b, *emission, *area, area_per_pick);
        let per_pick = if chosen { tri.area() } else { per_pick };
        (le != Rgb::ZERO).then(|| LightSample {
            wi,
            dist,
            li: le,
            pdf: tri.area() / (per_pick * omega),
            delta: false,
            normal: ng,
        })
    }

    /// Solid-angle density with which [`Light::sample_li`] would pick direction `wi`
    /// landing on triangle `tri` at distance `dist` (for MIS); 0 for
    /// punctual lights and triangles that are not part of this light.
    pub fn pdf_li(&self, scene: &Scene, p: Vec3, wi: Vec3, dist: f32, tri: u32) -> f32 {
        self.pdf_triangle(scene, p, wi, dist, tri, false)
    }

    /// [`Self::pdf_li`] for [`Self::sample_triangle`]: with `chosen`, the density
    /// given that triangle `tri` was chosen.
    pub fn pdf_triangle(&self, scene: &Scene, p: Vec3, wi: Vec3, dist: f32, tri: u32, chosen: bool) -> f32 {
        match &self.kind {
            LightKind::Area { tris, area, area_per_pick, spheres, two_sided, .. } => {
                if !tris.contains(&tri) {
                    return 0.0;
                }
                let t = &scene.triangles[tri as usize];
                let cos_l = -wi.dot(t.ng());
                let cos_l = if *two_sided { cos_l.abs() } else { cos_l };
                let area =
                    if chosen { t.area() } else { *area_per_pick.get((tri - tris.start) as usize).unwrap_or(area) };
                if cos_l <= 0.0 {
                    0.0
                } else if let Some((omega, _)) = near_solid_angle(t, spheres[(tri - tris.start) as usize], p) {
                    t.area() / (area * omega)
                } else {
                    dist * dist / (cos_l * area)
                }
            }
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The nearest point of a triangle against a search over a fine barycentric grid,
    /// for points in front of, behind, beside and beyond the corners and edges of a
    /// thin and a fat triangle: never farther than the grid's best, and inside the
    /// triangle.
    #[test]
    fn closest_point_is_the_nearest_point_of_the_triangle() {
        let tris = [
            crate::Triangle::new([Vec3::ZERO, Vec3::X, Vec3::Y], 0).unwrap(),
            crate::Triangle::new([Vec3::new(-1.0, 0.2, 0.3), Vec3::new(2.0, 0.1, -0.2), Vec3::new(0.4, 0.15, 0.1)], 0)
                .unwrap(),
        ];
        let h = |i: u64, s: u64| (pm_sampling::mix64(i * 13 + s) >> 40) as f32 / (1u64 << 24) as f32 * 6.0 - 3.0;
        let n = 200;
        for tri in &tris {
            for i in 0..300 {
                let p = Vec3::new(h(i, 1), h(i, 2), h(i, 3));
                let q = closest_point(tri, p);
                let mut best = f32::INFINITY;
                for a in 0..=n {
                    for b in 0..=(n - a) {
                        let (u, v) = (a as f32 / n as f32, b as f32 / n as f32);
                        let g = tri.point([1.0 - u - v, u, v]);
                        best = best.min((g - p).length());
                    }
                }
                let d = (q - p).length();
                assert!(d <= best + 1e-5, "point {p}: {d} against the grid's {best}");
                let [b0, b1, b2] = barycentrics(tri, q);
                assert!(b0.min(b1).min(b2) > -1e-4, "nearest point {q} outside the triangle");
            }
        }
    }
}
