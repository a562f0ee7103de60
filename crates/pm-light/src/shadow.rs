//! Direct light with visibility from cube shadow maps drawn by the rasteriser (the
//! image-space paper's shadow maps, McGuire and Luebke 2009 section 3 step 1a):
//! every light at every shading point, one depth lookup instead of a shadow ray.

use crate::direct::lambert_unoccluded;
use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_raster::CubeDepth;
use pm_sampling::Sampler;
use pm_scene::{Hit, Light, LightKind, Scene};

/// What direct light by shadow maps reads of a surface point.
#[derive(Clone, Copy, Debug)]
pub struct LitPoint {
    /// The point \[m\].
    pub p: Vec3,
    /// Unit geometric normal.
    pub ng: Vec3,
    /// Unit shading normal, on the geometric normal's side.
    pub ns: Vec3,
}

impl LitPoint {
    /// The point of a hit record.
    pub fn of(hit: &Hit) -> LitPoint {
        LitPoint { p: hit.p, ng: hit.ng, ns: hit.ns }
    }
}

/// One light's shadow map: depth seen from its centre.
struct LightMap {
    /// The cube depth map.
    depth: CubeDepth,
    /// True for an area light (one with [`Light::cos_integral`]).
    area: bool,
}

impl LightMap {
    /// The map of `light` at `res` x `res` texels a face, or none. Point and spot
    /// lights: at their position. Area lights with a closed-form irradiance
    /// ([`Light::cos_integral`]: planar, one-sided, uniformly emitting, of at most
    /// [`pm_scene::OUTLINE_TRIANGLES`] triangles): at their area-weighted centroid
    /// pushed 1e-3 of the scene's diagonal off the surface, so the map does not see
    /// the light itself.
    fn new(scene: &Scene, light: &Light, res: u32) -> Option<LightMap> {
        if !ShadowMaps::supports(light) {
            return None;
        }
        match &light.kind {
            LightKind::Point { position, .. } | LightKind::Spot { position, .. } => {
                Some(LightMap { depth: CubeDepth::new(scene, *position, res), area: false })
            }
            LightKind::Area { tris, .. } => {
                let t: Vec<&pm_scene::Triangle> = tris.clone().map(|i| &scene.triangles[i as usize]).collect();
                let normal = t.first()?.ng();
                let area: f32 = t.iter().map(|q| q.area()).sum();
                let centroid = t.iter().map(|q| (q.p[0] + q.p[1] + q.p[2]) * (q.area() / 3.0)).sum::<Vec3>() / area;
                let position = centroid + normal * (1e-3 * scene.bounds.diagonal());
                Some(LightMap { depth: CubeDepth::new(scene, position, res), area: true })
            }
            LightKind::Directional { .. } | LightKind::Environment { .. } => None,
        }
    }

    /// Whether the map's centre sees `at`: a bias of two texels at the point's
    /// distance, more at grazing light where one texel spans a longer stretch of
    /// the surface (shadow acne otherwise).
    fn sees(&self, at: LitPoint) -> bool {
        let d = self.depth.position() - at.p;
        let dist = d.length();
        let bias = 2.0 * self.depth.texel_angle() * dist / (d.dot(at.ng) / dist).abs().max(0.25);
        self.depth.visible(at.p, bias)
    }
}

/// A shadow map for every light of a scene.
pub struct ShadowMaps {
    /// One per light, in the scene's order.
    maps: Vec<LightMap>,
}

impl ShadowMaps {
    /// The maps of every light of `scene` at `res` x `res` texels a face, or none
    /// when some light cannot have one ([`Self::supports`]) or the scene has media
    /// or index-matched boundaries ([`Self::scene_supports`]): shadow rays then
    /// serve every light.
    pub fn new(scene: &Scene, res: u32) -> Option<ShadowMaps> {
        // Asked first, so no map is drawn for a scene that cannot have all of them.
        if !Self::scene_supports(scene) || !scene.lights.iter().all(Self::supports) {
            return None;
        }
        let maps = scene.lights.iter().map(|l| LightMap::new(scene, l, res)).collect::<Option<Vec<_>>>()?;
        Some(ShadowMaps { maps })
    }

    /// True when `scene`'s lights can have shadow maps at all: not when it has media
    /// or index-matched boundaries. A depth map says where light stops, not what
    /// it passes through: a fog box's walls would shadow everything inside them,
    /// and fog's attenuation between the point and the light needs the segment's
    /// length in each medium, which a shadow ray's walk finds
    /// ([`Scene::transmittance_along`]).
    pub fn scene_supports(scene: &Scene) -> bool {
        !scene.rays_walk()
    }

    /// True when `light` can have a shadow map: point and spot lights, and area
    /// lights with a closed-form irradiance (not lights at infinity, nor area
    /// lights that are large, curved, two-sided or textured).
    pub fn supports(light: &Light) -> bool {
        match &light.kind {
            LightKind::Point { .. } | LightKind::Spot { .. } => true,
            LightKind::Area { .. } => light.has_cos_integral(),
            LightKind::Directional { .. } | LightKind::Environment { .. } => false,
        }
    }

    /// Reflected direct radiance [W sr^-1 m^-2] toward `wo` at point `at` of a
    /// surface with BSDF `bsdf`: every light, with visibility from its map's centre.
    /// Point and spot lights: f I cos / d^2. Area lights on Lambertian surfaces: the
    /// unoccluded light in closed form times ρ / π (no noise, and the penumbrae of
    /// a point at the centre); on other surfaces one light sample.
    pub fn direct(&self, scene: &Scene, at: LitPoint, bsdf: &Bsdf, wo: Vec3, s: &mut Sampler) -> Rgb {
        let mut sum = Rgb::ZERO;
        for (light, map) in scene.lights.iter().zip(&self.maps) {
            if map.area
                && let Bsdf::Lambert { rho } = bsdf
            {
                let n = pm_scene::facing(at.ns, wo);
                let (l, e) = lambert_unoccluded(light, at.p, n, *rho);
                if e > 0.0 && map.sees(at) {
                    sum += l;
                }
                continue;
            }
            // A point or spot light from its position; an area light (on a surface
            // that is not Lambertian) by one light sample, with the centre's visibility.
            let (u_sel, u) = if map.area {
                let u = s.next_2d();
                (s.next_1d(), u)
            } else {
                (0.5, glam::Vec2::splat(0.5))
            };
            let Some(ls) = light.sample_li(scene, at.p, pm_scene::facing(at.ng, wo), u_sel, u) else { continue };
            if !pm_scene::same_side(at.ng, ls.wi, wo) {
                continue;
            }
            if map.sees(at) {
                sum += bsdf.f(wo, ls.wi, at.ns) * ls.wi.dot(at.ns).abs() * ls.li / ls.pdf;
            }
        }
        sum
    }
}
