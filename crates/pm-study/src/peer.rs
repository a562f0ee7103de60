//! `cargo xtask peer`: our path tracer against Mitsuba 3's on the same scene, size,
//! depth and sample count (issue 40, goal 1). Each glTF scene is translated into a
//! Mitsuba scene (XML with binary PLY meshes): Lambertian, mirror and smooth glass
//! materials, white (anisotropic) GGX metals as `roughconductor` (alpha_u along
//! the texture coordinates' dp/du, as our tangents run), one-sided area lights and point lights, the perspective camera and a
//! box pixel filter; anything else is refused with the reason, since a comparison of
//! different scenes would be no comparison. Both renderers then run alternately
//! (`--runs` times; the best time of each counts, Mitsuba's after a warm-up render
//! that compiles its kernels), the two images' means are checked against each other
//! (an honest comparison first: within 1%, or within the images' own noise), and the
//! time per sample is reported as a ratio. Not part of CI: it needs a Python with
//! `mitsuba` and `drjit` (../shared/CRATES.md), given by `--python`.

use anyhow::{Context, Result, bail};
use glam::Vec3;
use pm_bsdf::Bsdf;
use pm_runner::bins::Bins;
use pm_scene::{LightKind, Scene};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Options of `cargo xtask peer`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// glTF scenes to translate and render.
    #[arg(
        long = "scene",
        default_values = ["scenes/cornell_boxes.gltf", "scenes/cornell_spheres.gltf", "scenes/jozwowski_room_1024.gltf", "scenes/plane_point.gltf"]
    )]
    scenes: Vec<PathBuf>,
    /// Image width and height [pixels].
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Paths per pixel, both renderers.
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Timed runs of each renderer, alternately; the best of each counts.
    #[arg(long, default_value_t = 3)]
    runs: u32,
    /// A Python interpreter with `mitsuba` and `drjit` installed.
    #[arg(long, default_value = "python3")]
    python: String,
    /// Mitsuba variant (`llvm_ad_rgb` is the vectorised CPU peer; `scalar_rgb`
    /// runs anywhere but is not the peer).
    #[arg(long, default_value = "llvm_ad_rgb")]
    variant: String,
    /// Paths per pixel of the converged reference (Mitsuba's) both images' errors
    /// are measured against.
    #[arg(long, default_value_t = 1024)]
    reference_spp: u32,
    /// Output folder (one subfolder per scene, and `peer.md` with the table).
    #[arg(long, default_value = "out/peer")]
    out: PathBuf,
}

/// The Python side: load the scene, render once to compile the kernels, then time
/// one render and write it as OpenEXR. Prints its time as JSON.
const RENDER_PY: &str = r#"import json, sys, time
import drjit as dr
import mitsuba as mi
variant, xml, spp, seed, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
mi.set_variant(variant)
scene = mi.load_file(xml)
warm = mi.render(scene, spp=1, seed=seed + 1000)
dr.eval(warm)
dr.sync_thread()
t = time.perf_counter()
img = mi.render(scene, spp=spp, seed=seed)
dr.eval(img)
dr.sync_thread()
seconds = time.perf_counter() - t
mi.util.write_bitmap(out, img[:, :, :3])
print(json.dumps({"seconds": seconds}))
"#;

/// A Python that runs Mitsuba, and the render script it runs.
pub(crate) struct Mitsuba {
    python: String,
    variant: String,
    script: PathBuf,
}

impl Mitsuba {
    /// Check that `python` runs Mitsuba's `variant` and write the render script into
    /// `dir`.
    pub(crate) fn start(python: &str, variant: &str, dir: &Path) -> Result<Mitsuba> {
        let check = Command::new(python)
            .args(["-c", &format!("import mitsuba as mi; mi.set_variant('{variant}')")])
            .output()
            .with_context(|| format!("cannot start {python}"))?;
        if !check.status.success() {
            let err = String::from_utf8_lossy(&check.stderr);
            let last = err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("");
            bail!("{python} cannot run Mitsuba's {variant} variant ({last}): see ../shared/CRATES.md for the install");
        }
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
        let script = dir.join("render.py");
        std::fs::write(&script, RENDER_PY).with_context(|| format!("{}: cannot write", script.display()))?;
        Ok(Mitsuba { python: python.into(), variant: variant.into(), script })
    }

    /// Render scene `xml` at `spp` paths a pixel with `seed` into the OpenEXR `out`;
    /// returns the render's time [s] (after a warm-up render, load excluded).
    pub(crate) fn render(&self, xml: &Path, spp: u32, seed: u32, out: &Path) -> Result<f64> {
        let run = Command::new(&self.python)
            .arg(&self.script)
            .args([&self.variant, &xml.display().to_string(), &spp.to_string()])
            .args([&seed.to_string(), &out.display().to_string()])
            .output()
            .with_context(|| format!("cannot start {}", self.python))?;
        if !run.status.success() {
            bail!("Mitsuba failed: {}", String::from_utf8_lossy(&run.stderr).trim());
        }
        let json: serde_json::Value = serde_json::from_slice(&run.stdout)
            .with_context(|| format!("Mitsuba's output: {}", String::from_utf8_lossy(&run.stdout)))?;
        json["seconds"].as_f64().context("Mitsuba's time")
    }
}

/// `rgb` as Mitsuba's "r, g, b".
fn rgb(c: Vec3) -> String {
    format!("{}, {}, {}", c.x, c.y, c.z)
}

/// The Mitsuba BSDF element for material `m`, or why it cannot be translated.
fn bsdf_xml(scene: &pm_scene::Scene, m: &pm_scene::Material) -> Result<String, String> {
    let textured = [
        &m.base_texture,
        &m.metallic_roughness_texture,
        &m.emissive_texture,
        &m.specular_texture,
        &m.specular_color_texture,
        &m.normal_texture,
    ]
    .iter()
    .any(|t| t.is_some());
    if textured {
        return Err(format!("material {}: textures are not translated", m.name));
    }
    if m.alpha_mode != pm_scene::AlphaMode::Opaque {
        return Err(format!("material {}: alpha is not translated", m.name));
    }
    if m.layers.any() || m.layers.anisotropy_rotation != 0.0 {
        return Err(format!("material {}: layer textures and anisotropy rotation are not translated", m.name));
    }
    Ok(match m.bsdf {
        // Our reflecting BSDFs shade both sides (the normal is turned to the ray's
        // side); Mitsuba's are black from behind unless two-sided.
        Bsdf::Lambert { rho } => format!(
            "<bsdf type=\"twosided\"><bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"{}\"/></bsdf></bsdf>",
            rgb(rho)
        ),
        Bsdf::Mirror { r } => format!(
            "<bsdf type=\"twosided\"><bsdf type=\"conductor\"><string name=\"material\" value=\"none\"/><rgb name=\"specular_reflectance\" value=\"{}\"/></bsdf></bsdf>",
            rgb(r)
        ),
        Bsdf::Glass { eta, tint, thin } => {
            if scene.medium(m.interior).is_some_and(|v| !v.is_clear()) {
                return Err(format!("material {}: volume attenuation is not translated", m.name));
            }
            format!(
                "<bsdf type=\"{}\"><float name=\"int_ior\" value=\"{eta}\"/><float name=\"ext_ior\" value=\"1.0\"/><rgb name=\"specular_transmittance\" value=\"{}\"/></bsdf>",
                if thin { "thindielectric" } else { "dielectric" },
                rgb(tint)
            )
        }
        // A white metal's Schlick Fresnel is 1 at every angle: Mitsuba's
        // roughconductor of material "none" (F = 1), its alpha_u along the shading
        // frame's dp/du, which the PLY's texture coordinates give, as ours follows
        // the tangents generated from them (KHR_materials_anisotropy).
        Bsdf::Layered(l)
            if l.metal
                && l.f0 == pm_color::Rgb::ONE
                && l.coat == 0.0
                && l.sheen == pm_color::Rgb::ZERO
                && l.film.weight == 0.0 =>
        {
            format!(
                "<bsdf type=\"twosided\"><bsdf type=\"roughconductor\"><string name=\"distribution\" value=\"ggx\"/><float name=\"alpha_u\" value=\"{}\"/><float name=\"alpha_v\" value=\"{}\"/><string name=\"material\" value=\"none\"/></bsdf></bsdf>",
                l.alpha.x, l.alpha.y
            )
        }
        Bsdf::Conductor { .. } | Bsdf::Plastic { .. } | Bsdf::Layered(_) => {
            return Err(format!(
                "material {}: rough conductors, the glTF dielectric and its coat, sheen, anisotropy and thin film have no equal in Mitsuba (its Fresnel terms differ)",
                m.name
            ));
        }
    })
}

/// A binary little-endian PLY of triangles `tris` of `scene` (three vertices each,
/// with their normals when every triangle has them); with `behind` > 0, the
/// triangles turned over (winding and normals) and moved that far \[m\] behind
/// themselves: the back face of a two-sided emitter, as its own one-sided shape.
fn write_ply(path: &Path, scene: &Scene, tris: std::ops::Range<u32>, behind: f32) -> Result<()> {
    let list = &scene.triangles[tris.start as usize..tris.end as usize];
    let normals = list.iter().all(|t| t.n.is_some());
    let uvs = list.iter().all(|t| t.uv().is_some());
    let mut out = Vec::new();
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        3 * list.len()
    );
    if normals {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    if uvs {
        header.push_str("property float u\nproperty float v\n");
    }
    let _ = write!(header, "element face {}\nproperty list uchar int vertex_indices\nend_header\n", list.len());
    out.extend_from_slice(header.as_bytes());
    let order: [usize; 3] = if behind > 0.0 { [0, 2, 1] } else { [0, 1, 2] };
    for t in list {
        let (shift, turn) = if behind > 0.0 { (-t.ng() * behind, -1.0) } else { (Vec3::ZERO, 1.0) };
        for k in order {
            let mut v = (t.p[k] + shift).to_array().to_vec();
            if let Some(n) = t.n.filter(|_| normals) {
                v.extend((n[k] * turn).to_array());
            }
            if let Some(uv) = t.uv().filter(|_| uvs) {
                v.extend(uv[k].to_array());
            }
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    for i in 0..list.len() as i32 {
        out.push(3);
        for k in 0..3 {
            out.extend_from_slice(&(3 * i + k).to_le_bytes());
        }
    }
    std::fs::write(path, out).with_context(|| format!("{}: cannot write", path.display()))
}

/// Write `scene` as `dir/scene.xml` with a PLY per object, rendering `size` x
/// `size` at `spp` paths a pixel; fails with the reason when the scene has
/// something that cannot be translated.
pub(crate) fn translate(scene: &Scene, name: &str, dir: &Path, size: u32, spp: u32) -> Result<PathBuf> {
    let refuse = |why: String| anyhow::anyhow!("{name}: {why}");
    let cam = scene.camera.as_ref().ok_or_else(|| refuse("the scene has no camera".into()))?;
    if scene.environment_spec.is_some() || scene.environment().is_some() {
        return Err(refuse("environment lighting is not translated".into()));
    }
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let mut xml = String::from("<scene version=\"3.0.0\">\n");
    // Unbiased path tracing to any depth, Russian roulette from the fourth vertex
    // (ours starts at the fourth as well).
    xml.push_str(
        "  <integrator type=\"path\"><integer name=\"max_depth\" value=\"-1\"/><integer name=\"rr_depth\" value=\"4\"/></integrator>\n",
    );
    let target = cam.position + cam.forward;
    let _ = writeln!(
        xml,
        "  <sensor type=\"perspective\"><float name=\"fov\" value=\"{}\"/><string name=\"fov_axis\" value=\"y\"/>\
         <transform name=\"to_world\"><lookat origin=\"{}\" target=\"{}\" up=\"{}\"/></transform>\
         <sampler type=\"independent\"><integer name=\"sample_count\" value=\"{spp}\"/></sampler>\
         <film type=\"hdrfilm\"><integer name=\"width\" value=\"{size}\"/><integer name=\"height\" value=\"{size}\"/>\
         <rfilter type=\"box\"/><string name=\"pixel_format\" value=\"rgb\"/></film></sensor>",
        cam.yfov.to_degrees(),
        rgb(cam.position),
        rgb(target),
        rgb(cam.up)
    );
    for (i, o) in scene.objects.iter().enumerate() {
        let m = &scene.materials[o.material as usize];
        let bsdf = bsdf_xml(scene, m).map_err(refuse)?;
        let tris = &scene.triangles[o.tris.start as usize..o.tris.end as usize];
        if matches!(m.bsdf, Bsdf::Layered(l) if l.alpha.x != l.alpha.y) && !tris.iter().all(|t| t.uv().is_some()) {
            // Without texture coordinates the two shading frames are unrelated.
            return Err(refuse(format!("material {}: anisotropy on a mesh without texture coordinates", m.name)));
        }
        let ply = format!("mesh_{i}.ply");
        write_ply(&dir.join(&ply), scene, o.tris.clone(), 0.0)?;
        let mut emitter = String::new();
        let face_normals = scene.triangles[o.tris.start as usize].n.is_none();
        if m.emission.max_element() > 0.0 {
            emitter =
                format!("<emitter type=\"area\"><rgb name=\"radiance\" value=\"{}\"/></emitter>", rgb(m.emission));
            if m.double_sided {
                // Mitsuba's area emitters are one-sided: the back face is a second
                // shape, turned over, 1e-5 of the diagonal behind the first.
                let back = format!("mesh_{i}_back.ply");
                write_ply(&dir.join(&back), scene, o.tris.clone(), 1e-5 * scene.bounds.diagonal())?;
                let _ = writeln!(
                    xml,
                    "  <shape type=\"ply\"><string name=\"filename\" value=\"{back}\"/><boolean name=\"face_normals\" value=\"{face_normals}\"/>{bsdf}{emitter}</shape>"
                );
            }
        }
        let _ = writeln!(
            xml,
            "  <shape type=\"ply\"><string name=\"filename\" value=\"{ply}\"/><boolean name=\"face_normals\" value=\"{face_normals}\"/>{bsdf}{emitter}</shape>"
        );
    }
    for l in &scene.lights {
        match &l.kind {
            LightKind::Area { .. } => {} // written with its shape
            LightKind::Point { position, intensity } => {
                let _ = writeln!(
                    xml,
                    "  <emitter type=\"point\"><point name=\"position\" value=\"{}\"/><rgb name=\"intensity\" value=\"{}\"/></emitter>",
                    rgb(*position),
                    rgb(*intensity)
                );
            }
            _ => return Err(refuse(format!("light {}: only area and point lights are translated", l.name))),
        }
    }
    xml.push_str("</scene>\n");
    let path = dir.join("scene.xml");
    std::fs::write(&path, xml).with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(path)
}

/// The mean of image `a` over that of `b` minus one, and the standard error of
/// that from the spread of the two images' differences in 16 x 16 blocks (the
/// scene's own structure cancels in the differences; the noise does not).
fn means_apart(a: &[Vec3], b: &[Vec3], size: usize) -> (f64, f64) {
    let means =
        |px| pm_image::block_means(px, size, 16).into_iter().map(|p| pm_color::mean(p) as f64).collect::<Vec<_>>();
    let (ba, bb) = (means(a), means(b));
    let n = ba.len() as f64;
    let (ma, mb) = (ba.iter().sum::<f64>() / n, bb.iter().sum::<f64>() / n);
    let d: Vec<f64> = ba.iter().zip(&bb).map(|(x, y)| x - y).collect();
    let md = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|x| (x - md).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (ma / mb - 1.0, (var / n).sqrt() / mb)
}

/// One scene's comparison.
struct Row {
    scene: String,
    ours_s: f64,
    theirs_s: f64,
    means: (f64, f64),
    apart: (f64, f64),
    rmse: f64,
    /// One render's expected relative error against the truth, ours and Mitsuba's
    /// (bias and noise over the runs, the reference's own noise taken out).
    errors: (f64, f64),
}

/// Run and report.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    let mitsuba = Mitsuba::start(&args.python, &args.variant, &args.out)?;
    let bins = Bins::build(root)?;
    let mut rows = Vec::new();
    for scene_path in &args.scenes {
        let name = scene_path.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());
        let scene = pm_scene::load(scene_path).map_err(|e| anyhow::anyhow!("{e}"))?;
        let dir = args.out.join(&name);
        let xml = translate(&scene, &name, &dir.join("mitsuba"), args.size, args.spp)?;
        let (mut ours_s, mut theirs_s) = (f64::INFINITY, f64::INFINITY);
        // Each run's images are kept: their spread is each renderer's noise.
        let (mut ours_runs, mut theirs_runs) = (Vec::new(), Vec::new());
        for run in 0..args.runs {
            let (ours_exr, theirs_exr) = (dir.join(format!("ours-{run}.exr")), dir.join(format!("mitsuba-{run}.exr")));
            let stats = dir.join("ours.json");
            let out = Command::new(bins.path("photon-render"))
                .args(["--scene", &scene_path.display().to_string(), "--mode", "path"])
                .args(["--spp", &args.spp.to_string(), "--width", &args.size.to_string()])
                .args(["--height", &args.size.to_string(), "--seed", &(run + 1).to_string()])
                .args(["--out", &ours_exr.display().to_string(), "--stats-json", &stats.display().to_string()])
                .output()
                .context("cannot start photon-render")?;
            if !out.status.success() {
                bail!("photon-render failed on {name}: {}", String::from_utf8_lossy(&out.stderr).trim());
            }
            let report: pm_stage::report::RenderReport = serde_json::from_slice(&std::fs::read(&stats)?)?;
            ours_s = ours_s.min(report.seconds);
            let seconds = mitsuba.render(&xml, args.spp, run + 1, &theirs_exr).with_context(|| name.clone())?;
            theirs_s = theirs_s.min(seconds);
            println!("{name} run {}: ours {:.3} s, Mitsuba {seconds:.3} s", run + 1, report.seconds);
            ours_runs.push(pm_image::read_exr(&ours_exr)?.total().context("our image")?.to_vec());
            theirs_runs.push(pm_image::read_exr(&theirs_exr)?.total().context("Mitsuba's image")?.to_vec());
        }
        // The reference: Mitsuba at many paths a pixel in two halves with their own
        // seeds, whose difference measures its own noise (taken out of the errors).
        let mut halves = Vec::new();
        for h in 0..2u32 {
            let exr = dir.join(format!("reference-{h}.exr"));
            let spp = (args.reference_spp / 2).max(1);
            mitsuba.render(&xml, spp, 9998 + h, &exr).with_context(|| format!("{name}'s reference"))?;
            halves.push(pm_image::read_exr(&exr)?.total().context("the reference image")?.to_vec());
        }
        let size = args.size as usize;
        let keep = pm_image::accuracy::keep_mask_of_halves(&halves[0], &halves[1], size, size, None);
        let (reference, reference_var) = pm_image::accuracy::reference_from_halves(&halves[0], &halves[1], &keep);
        let error = |runs: &[Vec<Vec3>]| {
            let r: Vec<&[Vec3]> = runs.iter().map(Vec::as_slice).collect();
            pm_image::accuracy::split(&r, &reference, reference_var, &keep).error
        };
        let errors = (error(&ours_runs), error(&theirs_runs));
        let (pa, pb) = (&ours_runs[ours_runs.len() - 1][..], &theirs_runs[theirs_runs.len() - 1][..]);
        let e = pm_image::compare(pa, pb, f32::INFINITY);
        rows.push(Row {
            scene: name,
            ours_s,
            theirs_s,
            means: (
                pa.iter().map(|p| pm_color::mean(*p) as f64).sum::<f64>() / pa.len() as f64,
                pb.iter().map(|p| pm_color::mean(*p) as f64).sum::<f64>() / pb.len() as f64,
            ),
            apart: means_apart(pa, pb, size),
            rmse: e.rel_rmse as f64,
            errors,
        });
    }
    let mut md = format!(
        "`cargo xtask peer --size {} --spp {} --runs {}` (Mitsuba variant {}): path tracing, both renderers on\n\
         all cores, best of {} alternated runs each, render time only (Mitsuba after a warm-up render).\n\n\
         Error: one render's expected relative RMSE against the truth (`pm_image::accuracy`: over the runs'\n\
         seeds, against Mitsuba at {} paths a pixel in two halves whose own noise is taken out; the light's\n\
         pixels and their neighbours left out); the time to equal error is time x error^2 (both\n\
         estimators unbiased, error ~ 1/sqrt(time)).\n\n\
         | scene | ours [s] | Mitsuba [s] | ours / Mitsuba per sample | error ours | error Mitsuba | ours / Mitsuba at equal error | mean ours | mean Mitsuba | means apart | relative RMSE between |\n\
         |---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        args.size, args.spp, args.runs, args.variant, args.runs, args.reference_spp
    );
    for r in &rows {
        let (apart, noise) = r.apart;
        let _ = writeln!(
            md,
            "| {} | {:.3} | {:.3} | {:.2}x | {:.2}% | {:.2}% | {:.2}x | {:.5} | {:.5} | {:+.2}% (noise {:.2}%) | {:.1}% |",
            r.scene,
            r.ours_s,
            r.theirs_s,
            r.ours_s / r.theirs_s,
            100.0 * r.errors.0,
            100.0 * r.errors.1,
            (r.ours_s * r.errors.0.powi(2)) / (r.theirs_s * r.errors.1.powi(2)),
            r.means.0,
            r.means.1,
            100.0 * apart,
            100.0 * noise,
            100.0 * r.rmse
        );
    }
    print!("\n{md}");
    std::fs::write(args.out.join("peer.md"), &md)?;
    for r in &rows {
        let (apart, noise) = (r.apart.0.abs(), r.apart.1);
        if apart > 0.01 && apart > 3.0 * noise {
            bail!("{}: the two renderers' means differ by {:.2}%: not the same scene", r.scene, 100.0 * apart);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(name: &str) -> Scene {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
        pm_scene::load(&root.join(name)).unwrap()
    }

    /// cornell_boxes becomes one shape a mesh object, its ceiling light an area
    /// emitter of the same radiance, every mesh a PLY of three vertices a triangle;
    /// the textured materials scene is refused with the reason.
    #[test]
    fn scenes_translate_to_mitsuba_or_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let s = scene("cornell_boxes.gltf");
        let xml = std::fs::read_to_string(translate(&s, "boxes", dir.path(), 64, 4).unwrap()).unwrap();
        assert_eq!(xml.matches("<shape type=\"ply\">").count(), s.objects.len());
        let lights: Vec<_> = s.materials.iter().filter(|m| m.emission.max_element() > 0.0).collect();
        assert_eq!(xml.matches("<emitter type=\"area\">").count(), lights.len());
        assert!(xml.contains(&format!("<rgb name=\"radiance\" value=\"{}\"/>", rgb(lights[0].emission))));
        for (i, o) in s.objects.iter().enumerate() {
            let n = (o.tris.end - o.tris.start) as usize;
            let ply = std::fs::read(dir.path().join(format!("mesh_{i}.ply"))).unwrap();
            let header = ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
            let floats = if s.triangles[o.tris.start as usize].n.is_some() { 6 } else { 3 };
            assert_eq!(ply.len() - header, 3 * n * floats * 4 + n * 13, "mesh {i}");
        }
        let e = translate(&scene("materials.gltf"), "materials", dir.path(), 64, 4).unwrap_err();
        assert!(e.to_string().contains("not translated") || e.to_string().contains("no equal"), "{e}");
    }
}
