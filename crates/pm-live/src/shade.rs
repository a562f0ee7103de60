//! Drawing a frame: direct light by shadow rays, shadow maps or from the photons,
//! mirrors and glass by ray tracing, and indirect light from the method's
//! [`IndirectLight`]: the vertex method's corner irradiance interpolated across
//! each triangle (Gouraud shading, Jozwowski 2002 section 4.1.3), or the
//! image-space method's photon volumes, splatted over the eye's surfaces after
//! drawing (McGuire and Luebke 2009) and gathered where mirrors and glass lead. An
//! [`Integrator`] over `pm-render`'s region loop, so frames get its deterministic
//! per-pixel streams and G-buffer.

use crate::{DirectMode, FrameParams};
use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_color::Rgb;
use pm_light::{DirectLighting, LitPoint, ShadowMaps};
use pm_raster::Fragment;
use pm_render::{Components, Counters, FirstHit, Integrator, VisibleSurface};
use pm_sampling::Sampler;
use pm_scene::{Hit, Scene};

/// Where a real-time method's indirect light comes from.
pub trait IndirectLight: Sync {
    /// True when the indirect light at the eye's first surfaces is added after
    /// drawing (splatted): those surfaces take direct light and emission only, and
    /// plainly Lambertian ones are shaded from the rasterised fragment alone
    /// (deferred shading).
    const SPLATTED: bool;

    /// Indirect radiance [W sr^-1 m^-2 per channel] that `bsdf` at `hit` reflects
    /// towards `wo`. Asked at the eye's first surface (unless [`Self::SPLATTED`])
    /// and where mirrors and glass lead.
    fn radiance(&self, hit: &Hit, bsdf: &Bsdf, wo: Vec3) -> Rgb;
}

/// The per-pixel work of a real-time frame, with indirect light from `I`.
pub struct LiveShading<'a, I> {
    light: DirectLighting<'a>,
    indirect: I,
    direct: DirectMode,
    light_samples: u32,
    max_depth: u32,
    /// A shadow map per light, when every light has one (else shadow rays serve
    /// all lights).
    shadow_maps: Option<&'a ShadowMaps>,
    counters: Counters,
}

impl<'a, I: IndirectLight> LiveShading<'a, I> {
    /// Shading of `scene` with indirect light from `indirect` and direct light as
    /// `direct` says (`p` gives the light samples, the recursion depth).
    pub fn new(
        scene: &'a Scene,
        indirect: I,
        direct: DirectMode,
        p: &FrameParams,
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
}

impl<I: IndirectLight> LiveShading<'_, I> {
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
        Some(maps.direct(scene, LitPoint { p, ng: tr.ng(), ns }, &pm_bsdf::Bsdf::Lambert { rho }, -d, s))
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
            // A splatted method adds its light later where the eye sees the surface directly.
            let indirect = if I::SPLATTED && depth == 0 { Rgb::ZERO } else { self.indirect.radiance(&hit, &bsdf, wo) };
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

impl<I: IndirectLight> Integrator for LiveShading<'_, I> {
    type Scratch = ();

    fn li(
        &self,
        o: Vec3,
        d: Vec3,
        first: FirstHit,
        s: &mut Sampler,
        _: &mut (),
        vs: Option<&mut VisibleSurface>,
    ) -> Components {
        // Deferred shading of plain Lambertian pixels (a splatting method's frames:
        // their indirect light is added afterwards, so direct light is all they take).
        if vs.is_none()
            && I::SPLATTED
            && self.direct == DirectMode::ShadowMap
            && self.shadow_maps.is_some()
            && let FirstHit::Fragment(_, Some(f)) = first
            && let Some(direct) = self.lambert_first(f, d, s)
        {
            return Components { direct, ..Default::default() };
        }
        self.shade(first.resolve(self.light.scene, o, d), d, s, vs)
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
    use pm_raster as raster;
    use pm_render::Film;
    use std::path::PathBuf;

    /// The deferred path of image-space frames gives, at every pixel it takes,
    /// exactly what shading the full hit record gives: area lights over Lambertian
    /// walls, an emitter seen directly, mirrors and glass (which it leaves to the
    /// full path), and point lights. A point or reflectance off by a rounding, or
    /// an emitter taken for a plain wall, fails it (these scenes' walls are flat:
    /// a geometric normal taken for the shading one would pass).
    /// Indirect light splatted after drawing, and none where mirrors lead (the
    /// image-space method with no photons).
    struct Splatted;

    impl IndirectLight for Splatted {
        const SPLATTED: bool = true;
        fn radiance(&self, _: &Hit, _: &Bsdf, _: Vec3) -> Rgb {
            Rgb::ZERO
        }
    }

    #[test]
    fn deferred_lambert_pixels_equal_the_full_path() {
        for name in ["cornell_spheres.gltf", "cornell_boxes.gltf", "caustic_ring.gltf", "jozwowski_room_16.gltf"] {
            let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
            let scene = pm_scene::load(&dir.join(name)).unwrap();
            let p = FrameParams { direct: DirectMode::ShadowMap, ..FrameParams::default() };
            let maps = p.shadow_maps(&scene);
            assert!(maps.is_some(), "{name}");
            let shading = LiveShading::new(&scene, Splatted, p.direct, &p, maps.as_ref()).unwrap();
            let camera = scene.camera.clone().unwrap();
            let film = Film { width: 96, height: 72, spp: 1, contrast: 0.0, seed: 3 };
            let fragments = raster::first_hits(&scene, &camera, film.size(), film.rect());
            let (mut deferred, mut lit) = (0, 0);
            for (j, f) in fragments.iter().enumerate() {
                let Some(f) = f else { continue };
                let hit = f.hit(&scene);
                let d = (hit.p - camera.position).normalize();
                let seeded = || Sampler::hashed(11, j as u64);
                let full = shading.shade(Some(hit), d, &mut seeded(), None);
                let first = FirstHit::Fragment(&scene, Some(f));
                let got = shading.li(camera.position, d, first, &mut seeded(), &mut (), None);
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
