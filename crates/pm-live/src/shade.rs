//! Drawing a frame: the mesh with corner radiance interpolated across each
//! triangle (Gouraud shading, Jozwowski 2002 section 4.1.3) times the reflectance at
//! the pixel, direct light by shadow rays, shadow maps or from the photons, and
//! mirrors and glass by ray tracing. The image-space method (McGuire and Luebke
//! 2009) draws with the same integrator: its indirect light at the eye's surfaces is
//! splatted afterwards, and what mirrors and glass show gathers the same photons. An
//! [`Integrator`] over `pm-render`'s region loop, so frames get its deterministic
//! per-pixel streams and G-buffer.

use crate::splat::{PhotonIndex, Surface, VolumePhoton};
use crate::{Corners, DirectMode, LiveParams};
use glam::Vec3;
use pm_color::Rgb;
use pm_light::{DirectLighting, LitPoint, ShadowMaps};
use pm_raster::Fragment;
use pm_render::{Components, Counters, Integrator, VisibleSurface};
use pm_sampling::Sampler;
use pm_scene::{Hit, Scene};
use std::f32::consts::PI;

/// Where a frame's indirect light comes from.
enum Indirect<'a> {
    /// Irradiance at each corner [W m^-2 per channel], interpolated (the thesis).
    Corners { corners: &'a Corners, e: &'a [Rgb] },
    /// Photon volumes: splatted over the eye's surfaces after drawing, gathered
    /// where mirrors and glass lead (image-space photon mapping).
    Photons { photons: &'a [VolumePhoton], index: &'a PhotonIndex },
}

/// The per-pixel work of a live frame.
pub struct LiveShading<'a> {
    light: DirectLighting<'a>,
    indirect: Indirect<'a>,
    direct: DirectMode,
    light_samples: u32,
    max_depth: u32,
    /// A shadow map per light, when every light has one (else shadow rays serve
    /// all lights).
    shadow_maps: Option<&'a ShadowMaps>,
    counters: Counters,
}

impl<'a> LiveShading<'a> {
    /// Shading of `scene` with irradiance `e` at `corners`.
    pub fn new(
        scene: &'a Scene,
        corners: &'a Corners,
        e: &'a [Rgb],
        p: &LiveParams,
        shadow_maps: Option<&'a ShadowMaps>,
    ) -> Result<Self, pm_light::LightSelectError> {
        Self::with(scene, Indirect::Corners { corners, e }, p.direct, p, shadow_maps)
    }

    /// Shading of `scene` for image-space photon mapping: indirect light from
    /// `photons` (with their `index`), splatted at the eye's surfaces by the caller.
    /// Direct light from photons is not a choice there: it is taken by shadow rays.
    pub fn splatted(
        scene: &'a Scene,
        photons: &'a [VolumePhoton],
        index: &'a PhotonIndex,
        p: &LiveParams,
        shadow_maps: Option<&'a ShadowMaps>,
    ) -> Result<Self, pm_light::LightSelectError> {
        let direct = if p.direct == DirectMode::Photons { DirectMode::Rays } else { p.direct };
        Self::with(scene, Indirect::Photons { photons, index }, direct, p, shadow_maps)
    }

    fn with(
        scene: &'a Scene,
        indirect: Indirect<'a>,
        direct: DirectMode,
        p: &LiveParams,
        shadow_maps: Option<&'a ShadowMaps>,
    ) -> Result<Self, pm_light::LightSelectError> {
        Ok(LiveShading {
            // Plain light samples: at one sample a pixel the closed form with a
            // stochastic shadow (the batch renderer's) takes noise out of lit regions
            // but cost a fifth more direct-step time (cornell_spheres, 512 x 512),
            // and frames are timed. Shadow maps use the closed form.
            light: DirectLighting::new(scene)?,
            indirect,
            direct,
            light_samples: p.light_samples,
            max_depth: p.max_depth,
            shadow_maps,
            counters: Counters::default(),
        })
    }

    /// Irradiance at barycentrics `b` of triangle `tri`: the corners' values
    /// interpolated linearly (Gouraud; perspective-correct, since eye rays give
    /// true barycentrics). Zero for the image-space method.
    pub fn irradiance_at(&self, tri: u32, b: [f32; 3]) -> Rgb {
        match self.indirect {
            Indirect::Corners { corners, e } => {
                let c = corners.tri[tri as usize];
                e[c[0] as usize] * b[0] + e[c[1] as usize] * b[1] + e[c[2] as usize] * b[2]
            }
            Indirect::Photons { .. } => Rgb::ZERO,
        }
    }
}

impl LiveShading<'_> {
    /// Direct light at the eye's first surface `f` seen along `d`, from the fragment
    /// alone, when that surface is plainly Lambertian and emits nothing and every
    /// light has a shadow map: what [`Self::shade`] gives there (the same point,
    /// normals and reflectance, [`Scene::plain_lambert`]), without building the hit
    /// record and BSDF, or looking up emission and media. Most of an image-space
    /// frame's pixels are such walls and floors: this is deferred shading over the
    /// rasterised G-buffer, as the paper's direct-light pass is (section 3, step 3).
    fn lambert_first(&self, f: &Fragment, d: Vec3, s: &mut Sampler) -> Option<Rgb> {
        let scene = self.light.scene;
        let (p, ns, rho) = scene.plain_lambert(f.tri, f.b)?;
        let tr = &scene.triangles[f.tri as usize];
        if scene.materials[tr.material as usize].emission != Rgb::ZERO {
            return None;
        }
        let maps = self.shadow_maps?;
        Some(maps.direct(scene, LitPoint { p, ng: tr.ng, ns }, &pm_bsdf::Bsdf::Lambert { rho }, -d, s))
    }

    /// The components seen along direction `d` whose first hit is `first`.
    fn shade(&self, first: Option<Hit>, d: Vec3, s: &mut Sampler, mut vs: Option<&mut VisibleSurface>) -> Components {
        let scene = self.light.scene;
        let mut d = d;
        let mut beta = Rgb::ONE;
        let mut next = first;
        for depth in 0..=self.max_depth {
            let Some(hit) = next else { break };
            beta *= scene.transmittance(&hit, d);
            let wo = -d;
            let le = scene.emitted(&hit, wo);
            let bsdf = scene.bsdf(&hit);
            if depth == 0
                && let Some(v) = vs.as_deref_mut()
            {
                *v = VisibleSurface::at(scene, &hit, wo, bsdf, le);
            }
            if bsdf.is_specular() {
                // Mirrors and glass: one Fresnel-chosen branch per sample.
                let Some(bs) = bsdf.sample(wo, hit.ns, s.next_2d(), s.next_1d()) else { break };
                beta *= bs.weight;
                d = bs.wi;
                next = scene.intersect(scene.offset_origin(hit.p, hit.ng, bs.wi), d, f32::INFINITY);
                continue;
            }
            let direct = match self.direct {
                DirectMode::Rays => self.light.direct(&hit, &bsdf, wo, s, self.light_samples),
                DirectMode::ShadowMap => match self.shadow_maps {
                    Some(maps) => maps.direct(scene, LitPoint::of(&hit), &bsdf, wo, s),
                    None => self.light.direct(&hit, &bsdf, wo, s, self.light_samples),
                },
                DirectMode::Photons => Rgb::ZERO,
            };
            let indirect = match self.indirect {
                Indirect::Corners { .. } => bsdf.diffuse_albedo() * self.irradiance_at(hit.tri, hit.b) / PI,
                // Splatted later where the eye sees the surface directly.
                Indirect::Photons { .. } if depth == 0 => Rgb::ZERO,
                Indirect::Photons { photons, index } => {
                    let n = pm_render::facing(hit.ns, wo);
                    let surface = Surface::new(hit.p, n, wo, bsdf);
                    let (ind, caus) = crate::splat::gather(photons, index, &surface);
                    ind + caus
                }
            };
            if depth == 0 {
                if let Some(v) = vs {
                    v.direct = direct;
                }
                return Components { direct: le + direct, indirect, ..Default::default() };
            }
            return Components { specular: beta * (le + direct + indirect), ..Default::default() };
        }
        Components::default()
    }
}

impl Integrator for LiveShading<'_> {
    type Scratch = ();

    fn li(&self, o: Vec3, d: Vec3, s: &mut Sampler, _: &mut (), vs: Option<&mut VisibleSurface>) -> Components {
        self.shade(self.light.scene.intersect(o, d, f32::INFINITY), d, s, vs)
    }

    fn li_hit(
        &self,
        _: Vec3,
        d: Vec3,
        hit: Option<Hit>,
        s: &mut Sampler,
        _: &mut (),
        vs: Option<&mut VisibleSurface>,
    ) -> Components {
        self.shade(hit, d, s, vs)
    }

    fn li_fragment(
        &self,
        scene: &Scene,
        o: Vec3,
        d: Vec3,
        fragment: Option<&Fragment>,
        s: &mut Sampler,
        scratch: &mut (),
        vs: Option<&mut VisibleSurface>,
    ) -> Components {
        // Deferred shading of plain Lambertian pixels (image-space frames: their
        // indirect light is splatted afterwards, so direct light is all they take).
        if vs.is_none()
            && self.direct == DirectMode::ShadowMap
            && self.shadow_maps.is_some()
            && matches!(self.indirect, Indirect::Photons { .. })
            && let Some(f) = fragment
            && let Some(direct) = self.lambert_first(f, d, s)
        {
            return Components { direct, ..Default::default() };
        }
        self.li_hit(o, d, fragment.map(|f| f.hit(scene)), s, scratch, vs)
    }

    fn adaptive(&self) -> bool {
        !self.light.scene.has_stochastic_surfaces()
    }

    fn counters(&self) -> &Counters {
        &self.counters
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::splat::PhotonIndex;
    use pm_raster as raster;
    use pm_render::Film;
    use std::path::PathBuf;

    /// The deferred path of image-space frames gives, at every pixel it takes,
    /// exactly what shading the full hit record gives: area lights over Lambertian
    /// walls, an emitter seen directly, mirrors and glass (which it leaves to the
    /// full path), and point lights. A point or reflectance off by a rounding, or
    /// an emitter taken for a plain wall, fails it (these scenes' walls are flat:
    /// a geometric normal taken for the shading one would pass).
    #[test]
    fn deferred_lambert_pixels_equal_the_full_path() {
        for name in ["cornell_spheres.gltf", "cornell_boxes.gltf", "caustic_ring.gltf", "jozwowski_room_16.gltf"] {
            let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
            let scene = pm_scene::load(&dir.join(name)).unwrap();
            let p = LiveParams { direct: DirectMode::ShadowMap, ..LiveParams::default() };
            let maps = crate::shadow_maps(&scene, &p);
            let index = PhotonIndex::new(&[]);
            assert!(maps.is_some(), "{name}");
            let shading = LiveShading::splatted(&scene, &[], &index, &p, maps.as_ref()).unwrap();
            let camera = scene.camera.clone().unwrap();
            let film = Film { width: 96, height: 72, spp: 1, contrast: 0.0, seed: 3 };
            let fragments = raster::first_hits(&scene, &camera, film.size(), film.rect());
            let (mut deferred, mut lit) = (0, 0);
            for (j, f) in fragments.iter().enumerate() {
                let Some(f) = f else { continue };
                let hit = f.hit(&scene);
                let d = (hit.p - camera.position).normalize();
                let seeded = || Sampler::hashed(11, j as u64);
                let full = shading.li_hit(camera.position, d, Some(hit), &mut seeded(), &mut (), None);
                let got = shading.li_fragment(&scene, camera.position, d, Some(f), &mut seeded(), &mut (), None);
                let bits = |c: &Components| {
                    [c.direct, c.caustic, c.indirect, c.specular].map(|v| v.to_array().map(f32::to_bits))
                };
                assert_eq!(bits(&got), bits(&full), "{name}, pixel {j}");
                if shading.lambert_first(f, d, &mut seeded()).is_some() {
                    deferred += 1;
                    lit += (full.direct.max_element() > 0.0) as usize;
                }
            }
            let seen = fragments.iter().flatten().count();
            assert!(deferred * 2 > seen && lit * 2 > deferred, "{name}: {deferred} of {seen} deferred, {lit} lit");
        }
    }
}
