//! Light from infinitely far away in every direction (issue 37): an
//! equirectangular image of radiance, or one colour, with the importance
//! sampling every method takes it by (pbrt-v4 section 12.5.3, `ImageInfiniteLight`).
//!
//! Orientation is exactly Blender's Environment Texture with its default mapping,
//! so that the HDRI a Blender world uses renders the same here. In glTF axes (+Y
//! up) a direction d = (x, y, z) reads the image at column
//! `u = 0.5 + atan2(z, x) / 2 pi` (0 at the file's left edge) and row
//! `t = 0.5 - asin(y) / pi` (0 at the top row): the image's centre faces +X, a
//! quarter of the way from the left edge faces -Z, three quarters +Z, the top row
//! the zenith. A rotation of the environment by `a` about +Y (Blender's mapping
//! rotation about its up axis) turns the direction the centre faces to
//! (cos a, 0, -sin a).
//!
//! Units: radiance L [W sr^-1 m^-2 per channel] (the image's values times the
//! strength); densities per steradian.

use glam::{Vec2, Vec3};
use pm_color::Rgb;
use pm_sampling::Distribution2D;
use std::f32::consts::{PI, TAU};

/// The environment: radiance arriving from each direction at infinity.
#[derive(Clone, Debug)]
pub struct Environment {
    width: usize,
    height: usize,
    /// Radiance per texel, row-major from the top row [W sr^-1 m^-2 per channel].
    texels: Vec<Rgb>,
    /// cos and sin of the rotation about +Y.
    rotation: (f32, f32),
    /// Texels by their mean radiance times solid angle; None for one colour
    /// (sampled uniformly over the sphere).
    distribution: Option<Distribution2D>,
}

/// Where an environment's radiance comes from, before it is read.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvironmentSource {
    /// An equirectangular image file (.exr or .hdr).
    File(std::path::PathBuf),
    /// One colour of radiance [W sr^-1 m^-2 per channel].
    Colour(Vec3),
}

/// An environment as settings name it: where it comes from, a multiplier of its
/// radiance and its rotation about +Y \[degrees\].
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentSpec {
    /// The image or colour.
    pub source: EnvironmentSource,
    /// Multiplier of the radiance.
    pub strength: f32,
    /// Rotation about +Y \[degrees\].
    pub rotation_deg: f32,
}

impl EnvironmentSpec {
    /// The environment a glTF scene's `extras` name, if any:
    /// `"environment": {"file": "sky.hdr"}` (relative to `base_dir`, the glTF
    /// file's folder) or `{"color": [r, g, b]}` (radiance), each with optional
    /// `"strength"` (default 1) and `"rotation_deg"` (default 0). Anything else
    /// under `"environment"` is an error saying what is expected.
    pub fn from_extras(extras: &str, base_dir: &std::path::Path) -> Result<Option<EnvironmentSpec>, String> {
        #[derive(serde::Deserialize)]
        struct Extras {
            environment: Option<Env>,
        }
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Env {
            file: Option<std::path::PathBuf>,
            color: Option<[f32; 3]>,
            #[serde(default = "one")]
            strength: f32,
            #[serde(default)]
            rotation_deg: f32,
        }
        fn one() -> f32 {
            1.0
        }
        let Ok(x) = serde_json::from_str::<Extras>(extras) else {
            // The extras of other tools: only an "environment" key is ours.
            let v: serde_json::Value = serde_json::from_str(extras).map_err(|e| e.to_string())?;
            return match v.get("environment") {
                None => Ok(None),
                Some(e) => Err(format!(
                    "scene extras \"environment\": {e} is not {{\"file\": PATH}} or {{\"color\": [R, G, B]}} with optional \"strength\" and \"rotation_deg\""
                )),
            };
        };
        let Some(e) = x.environment else { return Ok(None) };
        let source = match (e.file, e.color) {
            (Some(f), None) => EnvironmentSource::File(base_dir.join(f)),
            (None, Some(c)) => EnvironmentSource::Colour(Vec3::from_array(c)),
            _ => return Err("scene extras \"environment\": give exactly one of \"file\" and \"color\"".into()),
        };
        Ok(Some(EnvironmentSpec { source, strength: e.strength, rotation_deg: e.rotation_deg }))
    }
}

/// A direction toward the environment, sampled by [`Environment::sample`].
#[derive(Clone, Copy, Debug)]
pub struct EnvironmentSample {
    /// Unit direction toward the sky.
    pub wi: Vec3,
    /// Radiance arriving from it [W sr^-1 m^-2 per channel].
    pub l: Rgb,
    /// Density of `wi` [sr^-1].
    pub pdf: f32,
}

/// Image coordinates (u, t) in [0, 1]^2 of unit direction `d` in the image's own
/// frame (Blender's convention, module doc).
pub fn direction_to_uv(d: Vec3) -> Vec2 {
    Vec2::new(0.5 + d.z.atan2(d.x) / TAU, 0.5 - d.y.clamp(-1.0, 1.0).asin() / PI)
}

/// The unit direction (image frame) that image coordinates (u, t) face; the
/// inverse of [`direction_to_uv`].
pub fn uv_to_direction(uv: Vec2) -> Vec3 {
    let phi = (uv.x - 0.5) * TAU;
    let elevation = (0.5 - uv.y) * PI;
    let c = elevation.cos();
    Vec3::new(c * phi.cos(), elevation.sin(), c * phi.sin())
}

impl Environment {
    /// The same radiance `l` from every direction.
    pub fn constant(l: Rgb) -> Result<Environment, String> {
        if !(l.is_finite() && l.min_element() >= 0.0) {
            return Err(format!("environment colour {l}: radiance must be finite and non-negative"));
        }
        Ok(Environment { width: 1, height: 1, texels: vec![l], rotation: (1.0, 0.0), distribution: None })
    }

    /// An equirectangular image of `width` x `height` texels (row-major, top row
    /// first) of radiance, times `strength`, rotated by `rotation_deg` about +Y.
    /// Fails, with the reason, unless the image is twice as wide as high and every
    /// value is finite and non-negative.
    pub fn image(
        width: usize,
        height: usize,
        texels: Vec<Rgb>,
        strength: f32,
        rotation_deg: f32,
    ) -> Result<Environment, String> {
        if height == 0 || width != 2 * height || texels.len() != width * height {
            return Err(format!("{width} x {height} texels: an equirectangular image is twice as wide as high"));
        }
        if !(strength.is_finite() && strength >= 0.0 && rotation_deg.is_finite()) {
            return Err(format!("strength {strength}, rotation {rotation_deg}: must be finite, strength non-negative"));
        }
        if let Some((i, v)) = texels.iter().enumerate().find(|(_, v)| !(v.is_finite() && v.min_element() >= 0.0)) {
            return Err(format!(
                "texel ({}, {}) is {v}: radiance must be finite and non-negative",
                i % width,
                i / width
            ));
        }
        let texels: Vec<Rgb> = texels.into_iter().map(|v| v * strength).collect();
        // Each texel weighs its mean radiance times its solid angle.
        let weights: Vec<f64> = texels
            .iter()
            .enumerate()
            .map(|(i, v)| pm_color::mean(*v) as f64 * texel_solid_angle(i / width, width, height))
            .collect();
        let a = rotation_deg.to_radians();
        Ok(Environment {
            width,
            height,
            distribution: Distribution2D::new(width, height, &weights),
            texels,
            rotation: (a.cos(), a.sin()),
        })
    }

    /// A hash of everything that decides the radiance (size, texels, rotation):
    /// what the scene's content hash records of its environment.
    pub fn identity(&self) -> [u8; 32] {
        let mut h = blake3::Hasher::new();
        h.update(&(self.width as u64).to_le_bytes());
        h.update(&self.rotation.0.to_le_bytes());
        h.update(&self.rotation.1.to_le_bytes());
        let mut bytes = Vec::with_capacity(12 * 4096);
        for row in self.texels.chunks(4096) {
            bytes.clear();
            bytes.extend(row.iter().flat_map(|t| t.to_array()).flat_map(f32::to_le_bytes));
            h.update(&bytes);
        }
        *h.finalize().as_bytes()
    }

    /// Bytes its texels and sampling distribution hold.
    pub fn memory_bytes(&self) -> usize {
        self.texels.capacity() * size_of::<Rgb>() + self.distribution.as_ref().map_or(0, Distribution2D::memory_bytes)
    }

    /// True when every direction has the same radiance.
    pub fn is_constant(&self) -> bool {
        self.texels.len() == 1
    }

    /// World direction `d` in the image's frame (the rotation undone).
    fn to_image(&self, d: Vec3) -> Vec3 {
        let (c, s) = self.rotation;
        Vec3::new(c * d.x - s * d.z, d.y, s * d.x + c * d.z)
    }

    /// Image-frame direction `d` in the world.
    fn to_world(&self, d: Vec3) -> Vec3 {
        let (c, s) = self.rotation;
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }

    /// Texel index at image coordinates `uv`.
    fn texel(&self, uv: Vec2) -> usize {
        let x = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        y * self.width + x
    }

    /// Radiance arriving from unit direction `d` [W sr^-1 m^-2 per channel]: the
    /// texel it falls in (no filtering: the density samples the same texels).
    pub fn radiance(&self, d: Vec3) -> Rgb {
        if self.is_constant() {
            return self.texels[0];
        }
        self.texels[self.texel(direction_to_uv(self.to_image(d)))]
    }

    /// A direction toward the environment for `u` in [0, 1)^2, by its radiance (a
    /// constant one uniformly over the sphere). None where the density vanishes
    /// (a pole, or a black image).
    pub fn sample(&self, u: Vec2) -> Option<EnvironmentSample> {
        let Some(dist) = &self.distribution else {
            let wi = pm_sampling::uniform_sphere(u);
            return Some(EnvironmentSample { wi, l: self.texels[0], pdf: 1.0 / pm_sampling::FOUR_PI });
        };
        let (uv, pdf_uv) = dist.sample(u);
        let d = uv_to_direction(uv);
        let pdf = solid_angle_pdf(pdf_uv, d);
        (pdf > 0.0).then(|| EnvironmentSample { wi: self.to_world(d), l: self.texels[self.texel(uv)], pdf })
    }

    /// Density [sr^-1] with which [`Environment::sample`] gives unit direction `d`.
    pub fn pdf(&self, d: Vec3) -> f32 {
        let Some(dist) = &self.distribution else { return 1.0 / pm_sampling::FOUR_PI };
        let d = self.to_image(d);
        solid_angle_pdf(dist.pdf(direction_to_uv(d)), d)
    }

    /// The integral of the radiance over the sphere, ∫ L dω [W m^-2 per channel]
    /// (a radiance field's "scalar irradiance"); times pi R^2 it is the power that
    /// crosses a disc of radius R facing every direction in turn, what photons
    /// emitted from the environment carry.
    pub fn integral(&self) -> Rgb {
        if self.is_constant() {
            return self.texels[0] * pm_sampling::FOUR_PI;
        }
        let mut sum = glam::DVec3::ZERO;
        for (i, v) in self.texels.iter().enumerate() {
            sum += v.as_dvec3() * texel_solid_angle(i / self.width, self.width, self.height);
        }
        sum.as_vec3()
    }
}

/// Solid angle [sr] of a texel in row `y` of a `width` x `height` equirectangular
/// image: (2 pi / width) (cos theta_top - cos theta_bottom), theta from the zenith.
fn texel_solid_angle(y: usize, width: usize, height: usize) -> f64 {
    use std::f64::consts::{PI, TAU};
    let (t0, t1) = (PI * y as f64 / height as f64, PI * (y + 1) as f64 / height as f64);
    TAU / width as f64 * (t0.cos() - t1.cos())
}

/// Density per steradian of image-frame direction `d` drawn with density `pdf_uv`
/// over the image's unit square: dω = 2 pi^2 sin(theta) du dt. Zero at the poles,
/// where it is undefined.
fn solid_angle_pdf(pdf_uv: f32, d: Vec3) -> f32 {
    let sin_theta = (1.0 - d.y * d.y).max(0.0).sqrt();
    if pdf_uv > 0.0 && sin_theta > 0.0 { pdf_uv / (2.0 * PI * PI * sin_theta) } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pm_sampling::Sampler;

    /// Blender's convention, fact by fact: +X reads the image's centre, -Z a
    /// quarter of the way from the left edge, +Z three quarters, -X the left (and
    /// right) edge, +Y the top row and -Y the bottom; directions and coordinates
    /// are each other's inverse; a marker texel is what the direction through its
    /// centre reads, and nothing else does; a rotation by 90 degrees turns the
    /// centre to face -Z.
    #[test]
    fn orientation_is_blenders_environment_texture() {
        let close = |a: Vec2, b: Vec2| (a - b).abs().max_element() < 1e-6;
        assert!(close(direction_to_uv(Vec3::X), Vec2::new(0.5, 0.5)), "+X faces the centre");
        assert!(close(direction_to_uv(Vec3::NEG_Z), Vec2::new(0.25, 0.5)), "-Z a quarter from the left");
        assert!(close(direction_to_uv(Vec3::Z), Vec2::new(0.75, 0.5)), "+Z three quarters");
        let left = direction_to_uv(Vec3::NEG_X).x;
        assert!(left.min(1.0 - left) < 1e-6, "-X at the left or right edge: {left}");
        assert!((direction_to_uv(Vec3::Y).y).abs() < 1e-6, "+Y the top row");
        assert!((direction_to_uv(Vec3::NEG_Y).y - 1.0).abs() < 1e-6, "-Y the bottom row");
        for k in 0..200 {
            let mut s = Sampler::new(1, k);
            let d = pm_sampling::uniform_sphere(s.next_2d());
            assert!((uv_to_direction(direction_to_uv(d)) - d).length() < 1e-5, "{d}");
        }
        let (w, h) = (16, 8);
        for (mx, my) in [(4, 3), (12, 3), (8, 0), (0, 7)] {
            let mut texels = vec![Rgb::splat(0.1); w * h];
            texels[my * w + mx] = Rgb::new(5.0, 4.0, 3.0);
            let env = Environment::image(w, h, texels, 1.0, 0.0).unwrap();
            let centre = Vec2::new((mx as f32 + 0.5) / w as f32, (my as f32 + 0.5) / h as f32);
            assert_eq!(env.radiance(uv_to_direction(centre)), Rgb::new(5.0, 4.0, 3.0), "marker ({mx}, {my})");
            let next = Vec2::new((mx as f32 + 1.5) / w as f32 % 1.0, centre.y);
            assert_eq!(env.radiance(uv_to_direction(next)), Rgb::splat(0.1), "beside marker ({mx}, {my})");
        }
        // The centre column's texels marked; rotated a quarter turn, -Z sees them.
        let mut texels = vec![Rgb::ZERO; w * h];
        texels[3 * w + 8] = Rgb::ONE;
        let env = Environment::image(w, h, texels, 1.0, 90.0).unwrap();
        let up = Vec3::new(0.0, 0.1, -1.0).normalize();
        assert_eq!(env.radiance(up), Rgb::ONE, "rotated: -Z faces the centre");
        assert_eq!(env.radiance(Vec3::new(1.0, 0.1, 0.0).normalize()), Rgb::ZERO, "rotated: +X does not");
    }

    /// The density integrates to 1 over the sphere (a fine latitude-longitude
    /// quadrature), and L / pdf averaged over samples is the radiance's integral
    /// over the sphere, computed in closed form from the texels' solid angles:
    /// within 1% on an image with a bright spot and a dark band, rotated, and for
    /// a single lit texel. A density off by its sin(theta) fails both.
    #[test]
    fn importance_sampling_is_unbiased_and_normalised() {
        let (w, h) = (32, 16);
        let mut texels: Vec<Rgb> = (0..w * h).map(|i| Rgb::splat(0.2 + (i % 5) as f32 * 0.1)).collect();
        texels[5 * w + 20] = Rgb::new(400.0, 300.0, 200.0);
        for x in 0..w {
            texels[12 * w + x] = Rgb::ZERO;
        }
        let mut single = vec![Rgb::ZERO; w * h];
        single[2 * w + 7] = Rgb::splat(2.0);
        for env in [
            Environment::image(w, h, texels, 1.5, 33.0).unwrap(),
            Environment::image(w, h, single, 1.0, 0.0).unwrap(),
            Environment::constant(Rgb::new(0.5, 1.0, 2.0)).unwrap(),
        ] {
            let m = 600;
            let mut integral = 0.0f64;
            for j in 0..m {
                for i in 0..2 * m {
                    let uv = Vec2::new((i as f32 + 0.5) / (2 * m) as f32, (j as f32 + 0.5) / m as f32);
                    let d = env.to_world(uv_to_direction(uv));
                    let sin_theta = (PI * uv.y).sin() as f64;
                    integral += env.pdf(d) as f64 * sin_theta * (std::f64::consts::PI / m as f64).powi(2);
                }
            }
            assert!((integral - 1.0).abs() < 0.01, "density integrates to {integral}");
            let n = 1 << 16;
            let (mut est, mut apart) = (glam::DVec3::ZERO, 0);
            for k in 0..n {
                let mut s = Sampler::new(9, k);
                if let Some(x) = env.sample(s.next_2d()) {
                    // A sample on a texel's edge may read its neighbour once rotated
                    // back and forth by a rounding: rare, never more.
                    apart += ((env.pdf(x.wi) - x.pdf).abs() > 1e-3 * x.pdf || env.radiance(x.wi) != x.l) as u32;
                    est += (x.l / x.pdf).as_dvec3();
                }
            }
            assert!(apart * 1000 < n as u32, "{apart} samples whose pdf or radiance differ from the lookup's");
            let (est, want) = (est / n as f64, env.integral().as_dvec3());
            let err = ((est - want).abs() / want.max(glam::DVec3::splat(1e-9))).max_element();
            assert!(err < 0.01, "estimate {est} vs integral {want}");
        }
    }

    /// Images that are not 2:1, or hold a NaN, infinite or negative value, are
    /// refused with a reason naming the problem.
    #[test]
    fn bad_images_are_refused() {
        let e = Environment::image(6, 2, vec![Rgb::ONE; 12], 1.0, 0.0).unwrap_err();
        assert!(e.contains("twice as wide"), "{e}");
        let mut t = vec![Rgb::ONE; 8];
        t[5] = Rgb::new(1.0, f32::NAN, 1.0);
        assert!(Environment::image(4, 2, t.clone(), 1.0, 0.0).unwrap_err().contains("texel (1, 1)"));
        t[5] = Rgb::new(1.0, -1.0, 1.0);
        assert!(Environment::image(4, 2, t, 1.0, 0.0).unwrap_err().contains("non-negative"));
        assert!(Environment::image(4, 2, vec![Rgb::ONE; 8], f32::INFINITY, 0.0).is_err());
        assert!(Environment::constant(Rgb::new(1.0, -0.1, 0.0)).is_err());
    }
}
