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
use pm_scene::{Hit, MediumId, Scene};

/// Specular bounces from the eye up to this depth follow both Fresnel branches
/// (the batch renderer's eye paths: 3); deeper ones one chosen by Fresnel
/// probability. One branch chosen at random per pixel at every depth left glass
/// and mirrors speckled: on cornell_spheres (image-space method, 512 x 512, direct
/// light by shadow maps) the whole frame's relative RMSE against a converged
/// reference was 56% at 84 ms a frame; splitting to depth 1, 33% at 88 ms; 2, 27%
/// at 108 ms; 3, 26% at 129 ms. Depth 2 gives the least error for the time
/// (error^2 x time 26.4 / 9.6 / 8.1 / 8.9), and frames are timed.
const SPLIT_DEPTH: u32 = 2;

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

    /// Radiance [W sr^-1 m^-2 per channel] scattered toward `o` by the scattering
    /// medium `m` along the eye ray's segment from `o` in unit direction `d` to
    /// `t` \[m\], from light that scattered more than once (the light scattered
    /// once straight from the lights is the frame's own). None by default: the
    /// method then draws single scattering only.
    fn scattered(&self, _o: Vec3, _d: Vec3, _t: f32, _m: &pm_scene::Medium) -> Rgb {
        Rgb::ZERO
    }
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

    /// The components seen from `o` along direction `d` whose first hit is
    /// `first`. Media attenuate what the eye sees (Beer-Lambert over each segment,
    /// through index-matched boundaries, [`Scene::pass_from`]), and the eye ray
    /// takes the light they scatter toward it straight from the lights (the volume
    /// layer: single scattering, `light_samples` a segment) and the light they
    /// scatter more than once as the method gives it ([`IndirectLight::scattered`]).
    /// Without single scattering a fog box's frame lacked a third to half of the
    /// path tracer's light (the differential checker's fog scenes, issue 53).
    fn shade(
        &self,
        o: Vec3,
        first: Option<Hit>,
        d: Vec3,
        s: &mut Sampler,
        mut vs: Option<&mut VisibleSurface>,
    ) -> Components {
        let scene = self.light.scene;
        let first_tri = first.as_ref().map(|h| h.tri);
        let (pass, volume) = self.pass_lit(o, d, first, scene.eye_medium(o), s);
        let tr = pass.tr;
        // Nothing hit: the environment and sun discs (the background).
        let Some(hit) = pass.hit else {
            return Components { direct: tr * scene.escaped(d), volume, ..Default::default() };
        };
        let wo = -d;
        let le = scene.emitted(&hit, wo);
        let bsdf = scene.bsdf(&hit);
        if let Some(v) = vs.as_deref_mut() {
            *v = VisibleSurface::at(scene, &hit, wo, bsdf, le);
        }
        if bsdf.is_specular() {
            let l = self.through(&hit, &bsdf, wo, pass.medium, 0, s);
            return Components { specular: tr * l, volume, ..Default::default() };
        }
        let direct = self.direct_at(&hit, &bsdf, wo, pass.medium, s);
        if let Some(v) = vs {
            v.direct = direct;
        }
        // A splatted method adds its light later where the eye sees the surface
        // directly (not through an index-matched boundary: the splat's G-buffer
        // holds the first fragment, and the floor under a fog box's top face had
        // no indirect light at all, issue 53); a glossy surface's comes along its
        // lobe.
        let indirect = if bsdf.is_glossy() {
            self.glossy(&hit, &bsdf, wo, pass.medium, s)
        } else if I::SPLATTED && first_tri == Some(hit.tri) {
            Rgb::ZERO
        } else {
            self.indirect.radiance(&hit, &bsdf, wo)
        };
        Components { volume, ..Components { direct: le + direct, indirect, ..Default::default() }.scaled(tr) }
    }

    /// The walk from `o` along unit `d` in `medium` whose first hit is `first`
    /// ([`Scene::pass_from`]: through index-matched boundaries to the first other
    /// surface), and the radiance [W sr^-1 m^-2 per channel] the scattering media
    /// along it send back toward `o`: single scattering straight from the lights
    /// (`light_samples` a segment) and what the method gives for the rest
    /// ([`IndirectLight::scattered`]), each behind the transmittance before it.
    /// Every ray the frame follows takes it, not the eye's alone: a rough metal box
    /// standing in a fog box reflects the lit fog around it, and without it the box
    /// was black in both real-time methods where the path tracer shows it bright
    /// (generated scene 60606/39, its indirect layer's worst block 90% low, issue 53).
    fn pass_lit(
        &self,
        o: Vec3,
        d: Vec3,
        first: Option<Hit>,
        medium: Option<MediumId>,
        s: &mut Sampler,
    ) -> (pm_scene::Passage, Rgb) {
        let scene = self.light.scene;
        let mut volume = Rgb::ZERO;
        let pass = scene.pass_from_visiting(o, d, first, medium, |o, t, m, tr| {
            let Some(medium) = scene.medium(m).filter(|x| x.scatters()) else { return };
            let t = if t.is_finite() { t } else { scene.escape_distance(o, d) };
            let single = self.light.single_scattering(o, d, t, m, s, self.light_samples);
            volume += tr * (single + self.indirect.scattered(o, d, t, medium));
        });
        (pass, volume)
    }

    /// Direct light reflected toward `wo` at a non-specular `hit` reached in
    /// `medium`, as the frame's direct mode says (shadow maps exist only in scenes
    /// without media).
    fn direct_at(&self, hit: &Hit, bsdf: &Bsdf, wo: Vec3, medium: Option<MediumId>, s: &mut Sampler) -> Rgb {
        let scene = self.light.scene;
        match self.direct {
            DirectMode::Rays => self.light.direct(hit, bsdf, wo, s, self.light_samples, medium),
            DirectMode::ShadowMap => match self.shadow_maps {
                Some(maps) => maps.direct(scene, LitPoint::of(hit), bsdf, wo, s),
                None => self.light.direct(hit, bsdf, wo, s, self.light_samples, medium),
            },
            DirectMode::Photons => Rgb::ZERO,
        }
    }

    /// Indirect radiance the glossy surface `hit` (reached in `medium`) reflects
    /// toward `wo`: one sample of its lobe, followed to the next surface (its
    /// direct light and the method's indirect light there, or on through mirrors
    /// and glass). Emission straight along the sample is left out: the direct
    /// estimate's own BSDF samples took it. The method's indirect light read at
    /// a rough metal as if it were diffuse took blocks of the differential
    /// checker's rooms 40-75% off (issue 53; the batch methods' fix, as
    /// `pm_bsdf::Bsdf::is_glossy` says).
    fn glossy(&self, hit: &Hit, bsdf: &Bsdf, wo: Vec3, medium: Option<MediumId>, s: &mut Sampler) -> Rgb {
        let scene = self.light.scene;
        let Some(bs) = bsdf.sample(wo, hit.ns, s.next_2d(), s.next_1d()) else { return Rgb::ZERO };
        if !pm_scene::same_side(hit.ng, bs.wi, wo) {
            return Rgb::ZERO;
        }
        let o = scene.offset_origin(hit.p, hit.ng, bs.wi);
        let first = scene.intersect(o, bs.wi, f32::INFINITY);
        let (pass, volume) = self.pass_lit(o, bs.wi, first, scene.medium_after(hit, bs.wi, medium), s);
        let Some(next) = pass.hit else { return bs.radiance_weight() * volume };
        let (wo, bsdf) = (-bs.wi, scene.bsdf(&next));
        let l = if bsdf.is_specular() {
            self.through(&next, &bsdf, wo, pass.medium, 1, s)
        } else {
            self.direct_at(&next, &bsdf, wo, pass.medium, s) + self.indirect.radiance(&next, &bsdf, wo)
        };
        bs.radiance_weight() * (volume + pass.tr * l)
    }

    /// Radiance leaving the mirror or glass `hit` (reached in `medium`) toward
    /// `wo`, `depth` specular bounces from the eye: both Fresnel branches followed
    /// up to [`SPLIT_DEPTH`], one chosen by Fresnel probability past it, and at the
    /// first non-specular surface its emission, direct and indirect light, each
    /// segment attenuated by the medium it runs in.
    fn through(&self, hit: &Hit, bsdf: &Bsdf, wo: Vec3, medium: Option<MediumId>, depth: u32, s: &mut Sampler) -> Rgb {
        if depth >= self.max_depth {
            return Rgb::ZERO;
        }
        let scene = self.light.scene;
        let follow = |s: &mut Sampler, wi: Vec3| -> Rgb {
            let o = scene.offset_origin(hit.p, hit.ng, wi);
            let first = scene.intersect(o, wi, f32::INFINITY);
            let (pass, volume) = self.pass_lit(o, wi, first, scene.medium_after(hit, wi, medium), s);
            let Some(next) = pass.hit else { return volume + pass.tr * scene.escaped(wi) };
            let (wo, bsdf) = (-wi, scene.bsdf(&next));
            let l = if bsdf.is_specular() {
                self.through(&next, &bsdf, wo, pass.medium, depth + 1, s)
            } else {
                scene.emitted(&next, wo)
                    + self.direct_at(&next, &bsdf, wo, pass.medium, s)
                    + self.indirect.radiance(&next, &bsdf, wo)
            };
            volume + pass.tr * l
        };
        let u = s.next_2d();
        if depth < SPLIT_DEPTH {
            let [reflected, transmitted] = bsdf.specular_branches(wo, hit.ns, u);
            let mut l = Rgb::ZERO;
            for b in [reflected, transmitted].into_iter().flatten() {
                l += b.radiance_weight() * b.pdf * follow(s, b.wi);
            }
            l
        } else {
            match bsdf.sample(wo, hit.ns, u, s.next_1d()) {
                Some(b) => b.radiance_weight() * follow(s, b.wi),
                None => Rgb::ZERO,
            }
        }
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
        self.shade(o, first.resolve(self.light.scene, o, d), d, s, vs)
    }

    fn adaptive(&self) -> bool {
        !self.light.scene.has_stochastic_surfaces()
    }

    fn volume(&self) -> bool {
        self.light.scene.has_scattering_media()
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
            let film = Film { width: 96, height: 72, spp: 1, contrast: 0.0, seed: 3, pixel_centres: false };
            let fragments = raster::first_hits(&scene, &camera, film.size(), film.rect());
            let (mut deferred, mut lit) = (0, 0);
            for (j, f) in fragments.iter().enumerate() {
                let Some(f) = f else { continue };
                let hit = f.hit(&scene);
                let d = (hit.p - camera.position).normalize();
                let seeded = || Sampler::hashed(11, j as u64);
                let full = shading.shade(camera.position, Some(hit), d, &mut seeded(), None);
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

    /// Indirect radiance of a tenth everywhere, so what lies behind glass is lit.
    struct Constant;

    impl IndirectLight for Constant {
        const SPLATTED: bool = true;
        fn radiance(&self, _: &Hit, _: &Bsdf, _: Vec3) -> Rgb {
            Rgb::splat(0.1)
        }
    }

    /// Mirrors and glass are seen through both Fresnel branches: with direct light
    /// from shadow maps (no noise on Lambertian surfaces), a mirror or glass pixel
    /// is nearly the same whatever its seed (two seeds within 5% RMS; only paths
    /// still inside the glass past the split depth choose), where one pixel sample
    /// picking one branch at random varied by 100% and more. And it is that
    /// estimator's mean: 1,024 of its samples a pixel (an independent loop here),
    /// summed over the pixels, agree within 2%. A branch dropped or weighted by its probability twice fails the
    /// second; a random choice left in, the first.
    #[test]
    fn mirrors_and_glass_follow_both_fresnel_branches() {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
        let scene = pm_scene::load(&dir.join("cornell_spheres.gltf")).unwrap();
        let p = FrameParams { direct: DirectMode::ShadowMap, ..FrameParams::default() };
        let maps = p.shadow_maps(&scene);
        let shading = LiveShading::new(&scene, Constant, p.direct, &p, maps.as_ref()).unwrap();
        let camera = scene.camera.clone().unwrap();
        let film = Film { width: 48, height: 36, spp: 1, contrast: 0.0, seed: 3, pixel_centres: false };
        let fragments = raster::first_hits(&scene, &camera, film.size(), film.rect());
        // One branch a sample, chosen by Fresnel probability.
        let one_branch = |first: Hit, d: Vec3, s: &mut Sampler| -> Rgb {
            let (mut hit, mut d, mut beta) = (first, d, Rgb::ONE);
            for _ in 0..p.max_depth {
                let bsdf = scene.bsdf(&hit);
                if !bsdf.is_specular() {
                    let le = scene.emitted(&hit, -d);
                    return beta * (le + shading.direct_at(&hit, &bsdf, -d, None, s) + Rgb::splat(0.1));
                }
                let Some(b) = bsdf.sample(-d, hit.ns, s.next_2d(), s.next_1d()) else { break };
                beta *= b.radiance_weight();
                d = b.wi;
                let Some(next) = scene.intersect(scene.offset_origin(hit.p, hit.ng, d), d, f32::INFINITY) else {
                    break;
                };
                hit = next;
            }
            Rgb::ZERO
        };
        let (mut split_sum, mut random_sum, mut pixels, mut diff2) = (0.0f64, 0.0f64, 0, 0.0f64);
        for (j, f) in fragments.iter().enumerate() {
            let Some(f) = f else { continue };
            let hit = f.hit(&scene);
            if !scene.bsdf(&hit).is_specular() {
                continue;
            }
            let d = (hit.p - camera.position).normalize();
            let a = shading.shade(camera.position, Some(hit), d, &mut Sampler::hashed(1, j as u64), None).specular;
            let b = shading.shade(camera.position, Some(hit), d, &mut Sampler::hashed(2, j as u64), None).specular;
            diff2 += (a - b).length_squared() as f64;
            let n = 1024;
            let mean = (0..n).map(|k| one_branch(hit, d, &mut Sampler::new(j as u64, k))).sum::<Rgb>() / n as f32;
            split_sum += a.element_sum() as f64;
            random_sum += mean.element_sum() as f64;
            pixels += 1;
        }
        assert!(pixels > 100, "{pixels} mirror and glass pixels");
        // RMS of the two seeds' difference over the mean (per channel).
        let spread = (diff2 / (3 * pixels) as f64).sqrt() / (split_sum / (3 * pixels) as f64);
        let ratio = split_sum / random_sum;
        eprintln!("{pixels} pixels: seeds apart {:.2}% RMS; both branches / one at random {ratio:.4}", 100.0 * spread);
        assert!(spread < 0.05, "two seeds {:.1}% apart (RMS)", 100.0 * spread);
        assert!((ratio - 1.0).abs() < 0.02, "both branches / one at random: {ratio}");
    }
}
