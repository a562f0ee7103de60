//! Light as every method takes it: which light a photon or a light sample comes
//! from ([`LightSelector`], by power or by the user's shares; Jozwowski 2002
//! section 3.1), direct illumination by next-event estimation with multiple
//! importance sampling (pbrt-v4 section 13.4, Veach 1997) and, on Lambertian
//! surfaces, in closed form with a ratio estimate of visibility (Heitz, Hill and
//! McGuire 2018) ([`DirectLighting`]), visibility from cube shadow maps drawn by the
//! rasteriser ([`ShadowMaps`]; McGuire and Luebke 2009 section 3 step 1a), and the
//! scene analysis of which effects the lights can produce ([`analyze`]: "simulate
//! only the effects a scene calls for"), and light in participating media: next
//! event estimation at points in a medium and single scattering along a ray
//! (equiangular sampling, Kulla and Fajardo 2012), every shadow ray attenuated by
//! the media it crosses.
//!
//! The batch renderer's integrators, the path tracer, both real-time methods and
//! the photon tracer take lights from here. The lights themselves (their kinds,
//! power, and the per-light primitives: emitting a ray, sampling a direction toward
//! a point and its density, Lambert's closed form of a planar light) are scene data
//! in `pm-scene`. This crate knows nothing about photon maps, images or files.
//!
//! Units: radiance W sr^-1 m^-2 and power W per RGB channel; lengths m.

mod direct;
mod effects;
mod media;
mod select;
mod shadow;
mod tree;

pub use direct::{CLOSED_FORM_LIGHTS, DirectLighting, power_heuristic};
pub use effects::{Decision, Effects, analyze};
pub use select::{LightSelectError, LightSelector};
pub use shadow::{LitPoint, ShadowMaps};
pub use tree::{Chosen, LightTree};

#[cfg(test)]
mod tests;
