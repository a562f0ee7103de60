//! The study's points: one setting at a time from the defaults, along named axes.

use pm_estimate::IrradianceParams;
use pm_methods::live::{LiveMethod, LiveParams};
use pm_methods::{Method, Settings};
use pm_photon::{RecordLayout, TraceParams};
use pm_render::Lookup;

pm_params::value_enum! {
    /// What a row of the study varies from the defaults (`--axes`; legend order,
    /// each its own colour).
    pub enum Axis {
        /// pipeline.toml's values.
        #[value(name = "default")]
        #[serde(rename = "default")]
        Default,
        /// Photons stored in the global map.
        #[value(name = "global photons")]
        #[serde(rename = "global photons")]
        GlobalPhotons,
        /// Photons stored in the caustic map.
        #[value(name = "caustic photons")]
        #[serde(rename = "caustic photons")]
        CausticPhotons,
        /// Photons per irradiance estimate (precompute and render).
        #[value(name = "k")]
        #[serde(rename = "k")]
        K,
        /// Fraction of the global photons given an irradiance.
        #[value(name = "precompute fraction")]
        #[serde(rename = "precompute fraction")]
        PrecomputeFraction,
        /// Final-gather rays.
        #[value(name = "gather rays")]
        #[serde(rename = "gather rays")]
        GatherRays,
        /// The irradiance cache's accuracy.
        #[value(name = "cache accuracy")]
        #[serde(rename = "cache accuracy")]
        CacheAccuracy,
        /// Light samples at each shading point.
        #[value(name = "light samples")]
        #[serde(rename = "light samples")]
        LightSamples,
        /// The most eye samples a pixel.
        #[value(name = "max spp")]
        #[serde(rename = "max spp")]
        MaxSpp,
        /// The final gather's lookup.
        #[value(name = "lookup")]
        #[serde(rename = "lookup")]
        Lookup,
        /// The photon record layout.
        #[value(name = "records")]
        #[serde(rename = "records")]
        Records,
        /// Photons stored in the volume map.
        #[value(name = "volume photons")]
        #[serde(rename = "volume photons")]
        VolumePhotons,
        /// The volume estimate along eye rays.
        #[value(name = "volume estimate")]
        #[serde(rename = "volume estimate")]
        VolumeEstimate,
        /// Photons per volume estimate.
        #[value(name = "volume k")]
        #[serde(rename = "volume k")]
        VolumeK,
        /// Single scattering's light samples.
        #[value(name = "volume light samples")]
        #[serde(rename = "volume light samples")]
        VolumeLightSamples,
        /// The path tracer at several sample counts.
        #[value(name = "path")]
        #[serde(rename = "path")]
        Path,
        /// Progressive photon mapping at several pass counts.
        #[value(name = "sppm")]
        #[serde(rename = "sppm")]
        Sppm,
        /// Progressive photon mapping without boundary probes.
        #[value(name = "sppm no probes")]
        #[serde(rename = "sppm no probes")]
        SppmNoProbes,
        /// Bidirectional path tracing at several pass counts.
        #[value(name = "bdpt")]
        #[serde(rename = "bdpt")]
        Bdpt,
        /// Vertex connection and merging at several pass counts.
        #[value(name = "vcm")]
        #[serde(rename = "vcm")]
        Vcm,
        /// Jozwowski's vertex method (one frame of photon-live).
        #[value(name = "live vertex")]
        #[serde(rename = "live vertex")]
        LiveVertex,
        /// Image-space photon mapping (one frame of photon-live).
        #[value(name = "live ispm")]
        #[serde(rename = "live ispm")]
        LiveIspm,
        /// Mitsuba 3's path tracer (with --peer).
        #[value(name = "peer")]
        #[serde(rename = "peer")]
        Peer,
    }
}

impl Axis {
    /// A method of its own (drawn as its own line) rather than a setting varied
    /// about the defaults (whose line passes through the defaults' point).
    pub fn is_method(self) -> bool {
        matches!(
            self,
            Axis::Path | Axis::Sppm | Axis::SppmNoProbes | Axis::Bdpt | Axis::Vcm | Axis::LiveVertex | Axis::LiveIspm
        )
    }
}

/// One point of the sweep: the stage parameters it runs with.
#[derive(Clone, Debug)]
pub struct Setting {
    /// The axis it varies.
    pub axis: Axis,
    /// What it is, e.g. "gather rays 64" (its row's name in the results).
    pub label: String,
    /// Stage 1's parameters.
    pub trace: TraceParams,
    /// Stage 3's parameters.
    pub irradiance: IrradianceParams,
    /// The method and its settings.
    pub render: Settings,
    /// A real-time row instead: photon-live's settings (its frame of the scene's
    /// camera after the buffer filled, timed as its mean frame time).
    pub live: Option<LiveParams>,
    /// A peer row instead: Mitsuba's path tracer at this many paths a pixel.
    pub peer_spp: Option<u32>,
}

impl Setting {
    /// Photon maps are shared by settings that differ only in rendering.
    pub fn maps_key(&self, seed: u64) -> String {
        let t = &self.trace;
        let i = &self.irradiance;
        format!(
            "g{}-c{}-v{}-{}-k{}-f{}-s{seed}",
            t.global_photons, t.caustic_photons, t.volume_photons, t.layout, i.k, i.fraction
        )
    }
}

/// The defaults (pipeline.toml's values at `size`), then one setting at a time;
/// `base_diagonal` is the scene's bounding-box diagonal [m].
pub fn sweep(base: &pm_pipeline::Pipeline, size: u32, base_diagonal: f32, media: bool) -> Vec<Setting> {
    let mut render = base.settings();
    render.render.width = size;
    render.render.height = size;
    let d = Setting {
        axis: Axis::Default,
        label: "defaults".into(),
        trace: base.trace.clone(),
        irradiance: base.irradiance.clone(),
        render,
        live: None,
        peer_spp: None,
    };
    let mut v = vec![d.clone()];
    let with = |axis: Axis, label: String, f: &dyn Fn(&mut Setting)| {
        let mut s = d.clone();
        s.axis = axis;
        s.label = label;
        f(&mut s);
        s
    };
    for g in [25_000u64, 100_000, 1_600_000] {
        v.push(with(Axis::GlobalPhotons, format!("global {g}"), &|s| s.trace.global_photons = g));
    }
    for c in [5_000u64, 140_000] {
        v.push(with(Axis::CausticPhotons, format!("caustic {c}"), &|s| s.trace.caustic_photons = c));
    }
    for k in [25usize, 100, 200, 400] {
        v.push(with(Axis::K, format!("k {k}"), &|s| {
            s.irradiance.k = k;
            s.render.render.k = k;
        }));
    }
    for f in [1.0f64, 0.0625] {
        v.push(with(Axis::PrecomputeFraction, format!("fraction {f}"), &|s| s.irradiance.fraction = f));
    }
    for r in [64u32, 128, 256, 1024] {
        v.push(with(Axis::GatherRays, format!("gather rays {r}"), &|s| s.render.render.gather_rays = r));
    }
    for a in [0.15f32, 0.6] {
        v.push(with(Axis::CacheAccuracy, format!("cache a {a}"), &|s| s.render.render.icache_accuracy = a));
    }
    for n in [1u32, 16] {
        v.push(with(Axis::LightSamples, format!("light samples {n}"), &|s| s.render.render.light_samples = n));
    }
    for spp in [4u32, 64] {
        v.push(with(Axis::MaxSpp, format!("max spp {spp}"), &|s| s.render.render.spp = spp));
    }
    v.push(with(Axis::Lookup, "exact lookup".into(), &|s| s.render.render.gather_lookup = Lookup::Exact));
    // Participating media (issue 38): volume photons, the estimate along eye rays
    // (the beam estimate by default, or the ray march) and its k.
    if media {
        for n in [50_000u64, 800_000] {
            v.push(with(Axis::VolumePhotons, format!("volume {n}"), &|s| s.trace.volume_photons = n));
        }
        v.push(with(Axis::VolumeEstimate, "ray march".into(), &|s| {
            s.render.render.volume_estimate = pm_render::VolumeEstimate::RayMarch
        }));
        for k in [20usize, 150] {
            v.push(with(Axis::VolumeK, format!("volume k {k}"), &|s| s.render.render.volume_k = k));
        }
        // Single scattering's light samples per eye ray in a medium: its noise is
        // most of a thin fog's error.
        for n in [1u32, 16] {
            v.push(with(Axis::VolumeLightSamples, format!("volume light samples {n}"), &|s| {
                s.render.render.volume_light_samples = n
            }));
        }
    }
    v.push(with(Axis::Records, "full-precision records".into(), &|s| s.trace.layout = RecordLayout::Full));
    for spp in [16u32, 64, 256, 1024] {
        v.push(with(Axis::Path, format!("path {spp} spp"), &|s| {
            s.render.mode = Method::Path;
            s.render.render.spp = spp
        }));
    }
    // Progressive photon mapping (issue 39): passes of the default photons a pass
    // with the default boundary probes; its bias shrinks with the radius, so long
    // runs pass the batch pipeline. Without probes (Hachisuka's pi r^2), the edge
    // bias stays.
    for passes in [16u32, 64, 256, 1024] {
        v.push(with(Axis::Sppm, format!("sppm {passes} passes"), &|s| {
            s.render.mode = Method::Sppm;
            s.render.sppm.passes = passes
        }));
    }
    for passes in [16u32, 64, 256, 1024] {
        v.push(with(Axis::SppmNoProbes, format!("sppm {passes} passes no probes"), &|s| {
            s.render.mode = Method::Sppm;
            (s.render.sppm.passes, s.render.sppm.sppm_boundary_probes) = (passes, 0)
        }));
    }
    // Bidirectional path tracing (issue 56): passes of one eye and one light
    // subpath a pixel, unbiased like the path tracer.
    for passes in [16u32, 64, 256, 1024] {
        v.push(with(Axis::Bdpt, format!("bdpt {passes} passes"), &|s| {
            s.render.mode = Method::Bdpt;
            s.render.bdpt.bdpt_passes = passes
        }));
    }
    // Vertex connection and merging: BDPT's passes with merging, consistent
    // like SPPM (its merging radius shrinks with the passes).
    for passes in [16u32, 64, 256, 1024] {
        v.push(with(Axis::Vcm, format!("vcm {passes} passes"), &|s| {
            s.render.mode = Method::Vcm;
            s.render.vcm.vcm_passes = passes
        }));
    }
    // The real-time methods on the same reference: Jozwowski's vertex estimates
    // (paths in the buffer) and image-space photon mapping (subsampling).
    // One real-time row: the method's defaults at the study's size, then `edit`.
    let live = |method: LiveMethod, label: String, edit: &dyn Fn(&mut LiveParams)| {
        let axis = if method == LiveMethod::Vertex { Axis::LiveVertex } else { Axis::LiveIspm };
        with(axis, label, &|s| {
            let frame = pm_live::FrameParams { width: size, height: size, ..base.live.frame.clone() };
            let mut p = LiveParams { method, frame, ..base.live.clone() };
            edit(&mut p);
            s.live = Some(p)
        })
    };
    use LiveMethod::{Ispm, Vertex};
    for total in [5_000u32, 20_000, 80_000] {
        v.push(live(Vertex, format!("vertex total {total}"), &|p| {
            (p.vertex.total, p.vertex.per_frame) = (total, total / 10)
        }));
    }
    // Corner estimates need corners: the mesh split to edges of at most this
    // fraction of the scene's diagonal (section 4.3).
    let diagonal = base_diagonal;
    for f in [0.05f32, 0.02] {
        v.push(live(Vertex, format!("vertex subdivide {f} diag"), &|p| {
            p.vertex.subdivide = pm_vertex::Subdivide::MaxEdge(f * diagonal)
        }));
    }
    // Paths cut at a fixed depth lose the light of their later bounces (a closed
    // room keeps 0.7^8 of it past 8 bounces).
    for level in [8u32, 32] {
        v.push(live(Vertex, format!("vertex max level {level}"), &|p| p.vertex.max_level = level));
    }
    for k in [25usize, 100, 200] {
        v.push(live(Vertex, format!("vertex k {k}"), &|p| p.vertex.k = k));
    }
    for bounces in [4u32, 16] {
        v.push(live(Ispm, format!("ispm bounces {bounces}"), &|p| p.ispm.bounces = bounces));
    }
    for f in [1u32, 2, 4] {
        v.push(live(Ispm, format!("ispm subsample {f}"), &|p| p.ispm.subsample = f));
    }
    // Photons per frame: 6 x res^2 bounce-map texels for a point light (the
    // default 48).
    for res in [32u32, 96] {
        v.push(live(Ispm, format!("ispm bounce res {res}"), &|p| p.ispm.bounce_res = res));
    }
    // Direct light from cube shadow maps: no shadow rays, no noise (issue 40's
    // image-space figure).
    v.push(live(Ispm, "ispm direct shadow-map".into(), &|p| p.frame.direct = pm_live::DirectMode::ShadowMap));
    v
}

/// The peer's rows (axis "peer"): Mitsuba's path tracer at these sample counts.
pub fn peer_rows(d: &Setting) -> Vec<Setting> {
    [16u32, 64, 256]
        .map(|spp| Setting { axis: Axis::Peer, label: format!("mitsuba {spp} spp"), peer_spp: Some(spp), ..d.clone() })
        .to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    /// `--replot` matches results.json's rows to the sweep by label: every label
    /// is one setting's, and a sweep with media and peer rows covers every axis.
    #[test]
    fn every_axis_is_swept_and_every_label_is_one_settings() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let base = pm_pipeline::Pipeline::load(&root.join("pipeline.toml")).unwrap();
        let mut v = sweep(&base, 64, 1.0, true);
        v.extend(peer_rows(&v[0]));
        let mut labels: Vec<&str> = v.iter().map(|s| s.label.as_str()).collect();
        labels.sort();
        let n = labels.len();
        labels.dedup();
        assert_eq!(labels.len(), n, "a label names two settings");
        for a in Axis::value_variants() {
            assert!(v.iter().any(|s| s.axis == *a), "no row varies {a}");
        }
        assert_eq!(v[0].axis, Axis::Default);
    }

    /// Axes are given by the names the legend shows, spaces and all.
    #[test]
    fn axes_parse_by_their_legend_names() {
        assert_eq!(Axis::from_str("light samples", false), Ok(Axis::LightSamples));
        assert_eq!(Axis::LiveIspm.to_string(), "live ispm");
        assert!(Axis::from_str("light-samples", false).is_err());
    }
}
