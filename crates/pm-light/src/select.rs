//! Choosing a light: by emitted power, or by shares the user gives.

use pm_sampling::sample_cdf;
use pm_scene::Scene;

/// Why lights cannot be chosen from.
#[derive(Debug, thiserror::Error)]
pub enum LightSelectError {
    /// Nothing emits.
    #[error("the scene has no lights with non-zero power (add an emissive material or a KHR_lights_punctual light)")]
    NoLights,
    /// A light share names no light.
    #[error("light share for '{0}': no light of that name (lights: {1})")]
    UnknownLight(String, String),
    /// Shares out of range.
    #[error("light shares must be in [0, 1] and sum to at most 1 (got {0})")]
    BadShares(String),
}

/// Probabilities of choosing each light for an emitted photon: proportional to power
/// (sum of channels) by default (Jozwowski 2002 section 3.1). The one definition of light choice: the photon
/// tracer, the renderer's light sampling and the scene analysis all use it.; lights given an
/// explicit share of the budget get it, and the rest split the remainder by power.
#[derive(Clone, Debug)]
pub struct LightSelector {
    /// Probability per light.
    pub probs: Vec<f64>,
    cdf: Vec<f64>,
}

impl LightSelector {
    /// Build from the scene and `(light name, share)` overrides. A name matches a
    /// light whose name equals it or starts with it followed by " (".
    pub fn new(scene: &Scene, shares: &[(String, f64)]) -> Result<LightSelector, LightSelectError> {
        let power: Vec<f64> = scene.lights.iter().map(|l| (l.power.x + l.power.y + l.power.z) as f64).collect();
        if scene.lights.is_empty() || power.iter().all(|&p| !(p > 0.0)) {
            return Err(LightSelectError::NoLights);
        }
        let mut fixed = vec![None; scene.lights.len()];
        let total_share: f64 = shares.iter().map(|s| s.1).sum();
        if shares.iter().any(|s| !(0.0..=1.0).contains(&s.1)) || total_share > 1.0 + 1e-9 {
            return Err(LightSelectError::BadShares(format!("{shares:?}")));
        }
        for (name, share) in shares {
            let i = scene.lights.iter().position(|l| Scene::names(&l.name, name)).ok_or_else(|| {
                let names: Vec<_> = scene.lights.iter().map(|l| l.name.clone()).collect();
                LightSelectError::UnknownLight(name.clone(), names.join(", "))
            })?;
            fixed[i] = Some(*share);
        }
        let free_power: f64 = power.iter().zip(&fixed).filter(|(_, f)| f.is_none()).map(|(p, _)| p.max(0.0)).sum();
        let remainder = (1.0 - total_share).max(0.0);
        let probs: Vec<f64> = power
            .iter()
            .zip(&fixed)
            .map(|(&p, f)| match f {
                Some(s) if p > 0.0 => *s,
                Some(_) => 0.0,
                None if free_power > 0.0 => remainder * p.max(0.0) / free_power,
                None => 0.0,
            })
            .collect();
        let sum: f64 = probs.iter().sum();
        if !(sum > 0.0) {
            return Err(LightSelectError::BadShares("every light with power has a zero share".into()));
        }
        Ok(Self::of(probs.iter().map(|p| p / sum).collect()))
    }

    /// The choice from probabilities that sum to 1.
    fn of(probs: Vec<f64>) -> LightSelector {
        let mut acc = 0.0;
        let cdf = probs
            .iter()
            .map(|p| {
                acc += p;
                acc
            })
            .collect();
        LightSelector { probs, cdf }
    }

    /// This choice with the lights `out` never chosen (the rest in the same
    /// proportions); `None` when nothing is left to choose.
    pub fn excluding(&self, out: &[usize]) -> Option<LightSelector> {
        let probs: Vec<f64> =
            self.probs.iter().enumerate().map(|(i, &p)| if out.contains(&i) { 0.0 } else { p }).collect();
        let sum: f64 = probs.iter().sum();
        (sum > 0.0).then(|| Self::of(probs.iter().map(|p| p / sum).collect()))
    }

    /// Choose a light for sample `u`; returns (index, probability).
    pub fn pick(&self, u: f32) -> (usize, f64) {
        let i = sample_cdf(&self.cdf, u);
        (i, self.probs[i])
    }
}
