//! The study's results: a typed row per setting (results.json, read back by
//! `--replot`), and what is written from the rows: results.csv, results.md and
//! front.json, the Pareto front `quality` in pipeline.toml picks from.

use super::Args;
use super::sweep::{Axis, Setting};
use anyhow::{Context, Result};
use pm_color::Layer;
use pm_image::accuracy::Split;
use pm_pipeline::Quality;
use pm_pipeline::quality::{Front, Point, StageTimes, Value, pareto};
use std::fmt::Write as _;
use std::path::Path;

/// What is compared: the image (the total, `None`) first, then each layer (the
/// volume layer only in scenes with scattering media: elsewhere its split is
/// empty and no column shows it).
pub const COMPARED: [Option<Layer>; 6] = [
    None,
    Some(Layer::Direct),
    Some(Layer::Caustic),
    Some(Layer::Indirect),
    Some(Layer::Specular),
    Some(Layer::Volume),
];

/// The bias/noise split of the image and of each layer.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct LayerSplits {
    /// The image (the total of the layers).
    pub image: Split,
    /// Direct light.
    pub direct: Split,
    /// Caustics.
    pub caustic: Split,
    /// Soft indirect light.
    pub indirect: Split,
    /// Specular reflection and refraction.
    pub specular: Split,
    /// Light scattered in media (zero without media).
    pub volume: Split,
}

impl LayerSplits {
    /// Each of [`COMPARED`] from `f`.
    pub fn from_fn(mut f: impl FnMut(Option<Layer>) -> Split) -> LayerSplits {
        LayerSplits {
            image: f(None),
            direct: f(Some(Layer::Direct)),
            caustic: f(Some(Layer::Caustic)),
            indirect: f(Some(Layer::Indirect)),
            specular: f(Some(Layer::Specular)),
            volume: f(Some(Layer::Volume)),
        }
    }

    /// The image's (`None`) or a layer's split.
    pub fn get(&self, layer: Option<Layer>) -> &Split {
        match layer {
            None => &self.image,
            Some(Layer::Direct) => &self.direct,
            Some(Layer::Caustic) => &self.caustic,
            Some(Layer::Indirect) => &self.indirect,
            Some(Layer::Specular) => &self.specular,
            Some(Layer::Volume) => &self.volume,
        }
    }
}

/// One setting's measurements.
pub struct Row {
    /// The setting.
    pub setting: Setting,
    /// Stage times, means over the seeds.
    pub times: StageTimes,
    /// Error, bias and noise of the image and each layer.
    pub layers: LayerSplits,
    /// SSIM of the first seed's image.
    pub ssim: f64,
}

impl Row {
    /// Total time \[s\].
    pub fn total(&self) -> f64 {
        self.times.total()
    }

    /// The image's error, bias and noise.
    pub fn image(&self) -> &Split {
        &self.layers.image
    }
}

/// A row as results.json holds it: the setting by name.
#[derive(serde::Serialize, serde::Deserialize)]
struct Record {
    axis: Axis,
    setting: String,
    seeds: u64,
    times_s: StageTimes,
    layers: LayerSplits,
    ssim: f64,
}

/// The rows of a results.json this study wrote, matched to `settings` by label
/// (rows of settings no longer in the sweep are dropped).
pub fn read_rows(path: &Path, settings: &[Setting]) -> Result<Vec<Row>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let records: Vec<Record> =
        serde_json::from_str(&text).with_context(|| format!("{}: not this study's results", path.display()))?;
    let rows: Vec<Row> = records
        .into_iter()
        .filter_map(|r| {
            let setting = settings.iter().find(|s| s.label == r.setting)?.clone();
            Some(Row { setting, times: r.times_s, layers: r.layers, ssim: r.ssim })
        })
        .collect();
    anyhow::ensure!(
        rows.first().is_some_and(|r| r.setting.axis == Axis::Default),
        "{}: no defaults row first",
        path.display()
    );
    Ok(rows)
}

/// results.json: the rows, typed.
fn results_json(rows: &[Row], seeds: u64) -> Result<String> {
    let records: Vec<Record> = rows
        .iter()
        .map(|r| Record {
            axis: r.setting.axis,
            setting: r.setting.label.clone(),
            seeds,
            times_s: r.times,
            layers: r.layers,
            ssim: r.ssim,
        })
        .collect();
    Ok(serde_json::to_string_pretty(&records)? + "\n")
}

/// The pipeline.toml values of `s` that differ from `d`'s: (section, key, value),
/// from their command lines (whose option names are the keys).
fn overrides(d: &Setting, s: &Setting) -> Vec<(String, String, Value)> {
    let mut v = Vec::new();
    if d.render.mode != s.render.mode {
        let mode = s.render.mode.to_string();
        v.push(("render".to_string(), "mode".to_string(), Value::parse(&mode, &mode)));
    }
    for (section, a, b) in [
        ("trace", d.trace.to_args(), s.trace.to_args()),
        ("irradiance", d.irradiance.to_args(), s.irradiance.to_args()),
        ("render", d.render.to_args(), s.render.render.to_args()),
    ] {
        for (da, sa) in a.chunks(2).zip(b.chunks(2)) {
            if da[1] != sa[1] {
                let key = sa[0].trim_start_matches("--").replace('-', "_");
                v.push((section.to_string(), key, Value::parse(&sa[1], &da[1])));
            }
        }
    }
    v
}

/// Write results.json, results.csv, results.md, front.json and the plots into `out`.
pub fn write_outputs(out: &Path, size: u32, args: &Args, rows: &[Row]) -> Result<()> {
    std::fs::write(out.join("results.json"), results_json(rows, args.seeds)?)?;
    std::fs::write(out.join("results.csv"), results_csv(rows, args.seeds)?)?;
    let front =
        pareto(rows, Row::total, |r| if r.setting.peer_spp.is_some() { f64::INFINITY } else { r.image().error });
    let md = results_md(rows, &front, size, args)?;
    std::fs::write(out.join("results.md"), &md)?;
    let f = quality_front(rows, size, args);
    std::fs::write(out.join("front.json"), serde_json::to_string_pretty(&f)? + "\n")?;
    super::plots::plots(out, rows, &front)?;
    println!("\n{md}\nwrote {}", out.display());
    Ok(())
}

/// results.csv: a row per setting, its stage times [s], its error split and each
/// layer's.
fn results_csv(rows: &[Row], seeds: u64) -> Result<String> {
    let mut csv = String::from(
        "axis,setting,seeds,trace_s,sort_s,irradiance_s,render_s,total_s,error,bias,noise,reference_noise,mean_bias,measured_rmse,ssim",
    );
    let layers = shown_layers(rows);
    for l in &layers {
        write!(csv, ",{l}_error,{l}_bias,{l}_noise,{l}_reference_noise")?;
    }
    csv.push('\n');
    for r in rows {
        let t = r.image();
        write!(
            csv,
            "{},{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.5},{:.5},{:.5},{:.5},{:+.5},{:.5},{:.5}",
            r.setting.axis,
            r.setting.label,
            seeds,
            r.times.trace,
            r.times.sort,
            r.times.irradiance,
            r.times.render,
            r.total(),
            t.error,
            t.bias,
            t.noise,
            t.reference_noise,
            t.mean_bias,
            t.measured,
            r.ssim
        )?;
        for l in layers.iter().map(|&l| r.layers.get(Some(l))) {
            write!(csv, ",{:.5},{:.5},{:.5},{:.5}", l.error, l.bias, l.noise, l.reference_noise)?;
        }
        csv.push('\n');
    }
    Ok(csv)
}

/// The layers the study's outputs show: the surface layers, and the volume layer
/// when some row measured one (a scene with scattering media).
pub fn shown_layers(rows: &[Row]) -> Vec<Layer> {
    let mut v = Layer::SURFACE.to_vec();
    if rows.iter().any(|r| r.layers.volume.reference_noise > 0.0 || r.layers.volume.error > 0.0) {
        v.push(Layer::Volume);
    }
    v
}

/// results.md: the table of settings (Pareto `front` marked), what each axis buys,
/// and the best setting per quality's time budget.
fn results_md(rows: &[Row], front: &[usize], size: u32, args: &Args) -> Result<String> {
    let pct = |v: f64| format!("{:.1}%", 100.0 * v);
    let reference_noise = rows.first().map_or(0.0, |r| r.image().reference_noise);
    let smallest = rows.iter().map(|r| r.image().error).fold(f64::INFINITY, f64::min);
    let peer = rows.iter().any(|r| r.setting.peer_spp.is_some());
    let volume = shown_layers(rows).contains(&Layer::Volume);
    let mut md = format!(
        "Trade-off on {size}x{size} against a path-traced reference of {} paths per pixel (two halves with their own seeds; \
         its own noise, from their difference, is {} relative RMS, {:.2} of the smallest error below, {}). Every setting is \
         rendered with {} seeds; the light's pixels and their neighbours are left out. **error** is what one render is \
         expected to be off from the truth, sqrt(bias^2 + noise^2); **bias** is the seeds' mean against the reference with \
         both noises taken out; **noise** the spread of one render; **measured** what a single comparison with the \
         reference reports. Times are wall seconds per stage (means over the seeds) on this machine (2 cores), one session; \
         the real-time rows (photon-live, one frame of the same camera) count the mean frame time after the vertex \
         method's buffer filled.\n\n\
         | axis | setting | trace | sort | precompute | render | total [s] | error | bias | noise | measured | direct | caustic | indirect | specular |{} Pareto |{}\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|{}---|{}\n",
        args.reference_spp,
        pct(reference_noise),
        reference_noise / smallest.max(1e-12),
        if reference_noise <= smallest / 3.0 {
            "below a third of it, as required"
        } else {
            "above a third of it: raise --reference-spp"
        },
        args.seeds,
        if volume { " volume |" } else { "" },
        if peer { " Mitsuba at equal error |" } else { "" },
        if volume { "---|" } else { "" },
        if peer { "---:|" } else { "" },
    );
    for (i, r) in rows.iter().enumerate() {
        let t = r.image();
        let l = |layer: Layer| match r.setting.peer_spp {
            Some(_) => "-".to_string(),
            None => format!("{} / {}", pct(r.layers.get(Some(layer)).bias), pct(r.layers.get(Some(layer)).noise)),
        };
        // Mitsuba's time to this row's error over the row's time.
        let lead = peer_time_at(rows, t.error).map_or(String::new(), |p| format!(" {:.1}x |", p / r.total()));
        writeln!(
            md,
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} | {} | {} | {} | {} |{} {} |{lead}",
            r.setting.axis,
            r.setting.label,
            r.times.trace,
            r.times.sort,
            r.times.irradiance,
            r.times.render,
            r.total(),
            pct(t.error),
            pct(t.bias),
            pct(t.noise),
            pct(t.measured),
            l(Layer::Direct),
            l(Layer::Caustic),
            l(Layer::Indirect),
            l(Layer::Specular),
            if volume { format!(" {} |", l(Layer::Volume)) } else { String::new() },
            if front.contains(&i) { "yes" } else { "" }
        )?;
    }
    md.push_str("\nLayers: bias / noise, relative to each layer's own mean in the reference.\n\n");
    if peer {
        md.push_str(
            "Mitsuba at equal error: the time Mitsuba 3's path tracer (the peer rows, render time only, after a \
             warm-up render) needs to reach the row's error, from its row with the most paths as time x \
             (its error / the row's error)^2 (unbiased: error ~ 1 / sqrt(time)), over the row's total time; above \
             1x the row is ahead.\n\n",
        );
    }
    md.push_str("What each setting buys, from its smallest to its largest value (the defaults in between):\n\n");
    let mut axes: Vec<Axis> = Vec::new();
    for r in rows {
        if r.setting.axis != Axis::Default && !axes.contains(&r.setting.axis) {
            axes.push(r.setting.axis);
        }
    }
    for axis in &axes {
        let own: Vec<&Row> = rows.iter().filter(|r| r.setting.axis == *axis).collect();
        let (first, last) = (own[0], own[own.len() - 1]);
        let d = &rows[0];
        writeln!(
            md,
            "- {axis}: {} -> {}: bias {} -> {} (defaults {}), noise {} -> {} (defaults {}), time {:.2} -> {:.2} s (defaults {:.2} s)",
            first.setting.label,
            last.setting.label,
            pct(first.image().bias),
            pct(last.image().bias),
            pct(d.image().bias),
            pct(first.image().noise),
            pct(last.image().noise),
            pct(d.image().noise),
            first.total(),
            last.total(),
            d.total()
        )?;
    }
    md.push_str("\nBest setting per time budget (lowest error on the Pareto front within the budget):\n\n");
    let base_t = rows[0].total();
    for q in [Quality::Preview, Quality::Balanced, Quality::Final] {
        let (name, budget) = (q, q.budget_factor() * base_t);
        if let Some(&i) = front
            .iter()
            .filter(|&&i| rows[i].total() <= budget)
            .min_by(|&&a, &&b| rows[a].image().error.total_cmp(&rows[b].image().error))
        {
            writeln!(
                md,
                "- {name} (at most {budget:.2} s): {} ({:.2} s, error {})",
                rows[i].setting.label,
                rows[i].total(),
                pct(rows[i].image().error)
            )?;
        }
    }
    Ok(md)
}

/// The front as the quality knob reads it (`quality` in pipeline.toml; front.json):
/// batch settings only, the real-time rows being another program.
fn quality_front(rows: &[Row], size: u32, args: &Args) -> Front {
    let batch_front = pareto(rows, Row::total, |r| {
        if r.setting.live.is_some() || r.setting.peer_spp.is_some() { f64::INFINITY } else { r.image().error }
    });
    let name = Path::new(&args.scene).file_stem().map_or(String::new(), |s| s.to_string_lossy().into_owned());
    Front {
        scene: name,
        size,
        machine: format!("{} cores", std::thread::available_parallelism().map_or(1, |n| n.get())),
        defaults_s: rows[0].times,
        points: batch_front
            .iter()
            .map(|&i| Point {
                label: rows[i].setting.label.clone(),
                times_s: rows[i].times,
                error: rows[i].image().error,
                bias: rows[i].image().bias,
                noise: rows[i].image().noise,
                overrides: overrides(&rows[0].setting, &rows[i].setting),
            })
            .collect(),
    }
}

/// Mitsuba's time to reach `error` [s]: its path tracer is unbiased, so its error
/// falls as 1 / sqrt(time); fitted on its row with the most paths (the one whose
/// fixed costs weigh least). None without peer rows.
fn peer_time_at(rows: &[Row], error: f64) -> Option<f64> {
    let r = rows.iter().filter(|r| r.setting.peer_spp.is_some()).max_by_key(|r| r.setting.peer_spp)?;
    Some(r.total() * (r.image().error / error).powi(2))
}
