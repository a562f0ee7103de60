//! The progressive state file: what stochastic progressive photon mapping
//! (Hachisuka and Jensen 2009) keeps per pixel between passes, so that a long
//! render can stop and continue (a stop and a resume equal one run bit for bit).
//!
//! The file is [`crate::framed`]'s frame (magic `b"PMSPPMST"`, version 2, records
//! of 120 bytes, count the passes the records hold, source hash zero, params the
//! settings that shaped the state as "name=value" words: a reader refuses a
//! state made with other settings). Records are [`StateRecord`]s, one a pixel,
//! row by row.

use crate::FormatError;
use crate::framed::{self, Kind};
use bytemuck::{Pod, Zeroable};
use std::path::Path;

/// File signature.
pub const STATE_MAGIC: [u8; 8] = *b"PMSPPMST";
/// The only version this build reads and writes.
/// Version 2 keeps a volume layer beside the surface layers (version 1 had none).
pub const STATE_VERSION: u32 = 2;
const KIND: Kind = Kind {
    magic: STATE_MAGIC,
    version: STATE_VERSION,
    record_size: size_of::<StateRecord>(),
    name: "progressive state",
};

/// One pixel's progressive state (120 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct StateRecord {
    /// Gather radius r \[m\].
    pub radius: f32,
    /// Photon count N (fractional).
    pub n: f32,
    /// Accumulated photon flux tau [W per channel]: caustic RGB, indirect RGB,
    /// through mirrors and glass RGB.
    pub tau: [[f32; 3]; 3],
    /// Sum over the passes of emission, direct light and light scattered in
    /// media toward the eye [W sr^-1 m^-2 per channel]: the direct, caustic,
    /// indirect, specular and volume layers' RGB.
    pub ld: [[f32; 3]; 5],
    /// Sum over the passes of each pass's own estimate of the pixel (the mean of
    /// its channels) [W sr^-1 m^-2], and of its square, for the noise estimate.
    pub l_sum: f32,
    /// Sum of the squares [W^2 sr^-2 m^-4].
    pub l_sq: f32,
    /// The share of the gather disc on the visible surface (a running mean of
    /// the boundary probes; 1 without them), in [0, 1].
    pub share: f32,
    /// Passes that found a visible point (the running mean's count).
    pub seen: f32,
}

/// A progressive state file in memory.
pub type StateFile = framed::ImageState<StateRecord>;

/// Write `s` to `path` atomically.
pub fn write_state(path: &Path, s: &StateFile) -> Result<(), FormatError> {
    framed::write_state(path, &KIND, s)
}

/// Read and check a progressive state file: one record a pixel, every value
/// finite, radii above zero, counts, fluxes and sums not negative.
pub fn read_state(path: &Path) -> Result<StateFile, FormatError> {
    framed::read_state(path, &KIND, |r: &StateRecord| {
        let values = [r.radius, r.n, r.l_sum, r.l_sq, r.share, r.seen]
            .into_iter()
            .chain(r.tau.into_iter().flatten())
            .chain(r.ld.into_iter().flatten());
        let bad = !(r.radius > 0.0) || r.share > 1.0 || values.into_iter().any(|v| !v.is_finite() || v < 0.0);
        bad.then_some("holds a non-finite or negative value, a radius <= 0 or a share above 1")
    })
}
