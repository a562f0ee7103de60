//! The state of a progressive method whose pixels are sums over passes
//! (bidirectional path tracing: each pass one eye and one light subpath a
//! pixel), so that a long render can stop and continue (a stop and a resume
//! equal one run bit for bit).
//!
//! The file is [`crate::framed`]'s frame (magic `b"PMPASSES"`, version 1,
//! records of 68 bytes, count the passes the records hold, source hash zero,
//! params the method and the settings that shaped the state as "name=value"
//! words: a reader refuses a state made with other settings). Records are
//! [`PassRecord`]s, one a pixel, row by row.

use crate::FormatError;
use crate::framed::{self, Kind};
use bytemuck::{Pod, Zeroable};
use std::path::Path;

/// File signature.
pub const PASSES_MAGIC: [u8; 8] = *b"PMPASSES";
/// The only version this build reads and writes.
pub const PASSES_VERSION: u32 = 1;
const KIND: Kind = Kind {
    magic: PASSES_MAGIC,
    version: PASSES_VERSION,
    record_size: size_of::<PassRecord>(),
    name: "progressive pass sums",
};

/// One pixel's sums over the passes (68 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PassRecord {
    /// Sum over the passes of the pixel's radiance [W sr^-1 m^-2 per channel]:
    /// the direct, caustic, indirect, specular and volume layers' RGB.
    pub sum: [[f32; 3]; 5],
    /// Sum over the passes of each pass's value of the pixel (the mean of its
    /// channels) [W sr^-1 m^-2], for the noise estimate.
    pub l_sum: f32,
    /// Sum of their squares [W^2 sr^-2 m^-4].
    pub l_sq: f32,
}

/// A pass-sums state file in memory.
pub type PassStateFile = framed::ImageState<PassRecord>;

/// Write `s` to `path` atomically.
pub fn write_pass_state(path: &Path, s: &PassStateFile) -> Result<(), FormatError> {
    framed::write_state(path, &KIND, s)
}

/// Read and check a pass-sums state file: one record a pixel, every value finite
/// and not negative.
pub fn read_pass_state(path: &Path) -> Result<PassStateFile, FormatError> {
    framed::read_state(path, &KIND, |r: &PassRecord| {
        let mut values = [r.l_sum, r.l_sq].into_iter().chain(r.sum.into_iter().flatten());
        values.any(|v| !v.is_finite() || v < 0.0).then_some("holds a non-finite or negative value")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> PassStateFile {
        let records =
            (0..6).map(|i| PassRecord { sum: [[i as f32, 0.5, 2.0]; 5], l_sum: 1.0 + i as f32, l_sq: 3.0 }).collect();
        PassStateFile {
            width: 3,
            height: 2,
            passes: 7,
            scene_hash: [9; 32],
            params: "method=bdpt seed=1".into(),
            records,
        }
    }

    /// A written state reads back equal; a record with a negative or non-finite
    /// value, a wrong record count and a truncated file are refused with the file
    /// named.
    #[test]
    fn pass_state_round_trips_and_bad_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.bin");
        let s = state();
        write_pass_state(&path, &s).unwrap();
        assert_eq!(read_pass_state(&path).unwrap(), s);
        for bad in [f32::NAN, -1.0, f32::INFINITY] {
            let mut b = state();
            b.records[4].sum[2][1] = bad;
            write_pass_state(&path, &b).unwrap();
            let e = read_pass_state(&path).unwrap_err().to_string();
            assert!(e.contains("state.bin") && e.contains("record 4"), "{e}");
        }
        let mut b = state();
        b.records.pop();
        write_pass_state(&path, &b).unwrap();
        let e = read_pass_state(&path).unwrap_err().to_string();
        assert!(e.contains("5 records for a 3x2 image"), "{e}");
        write_pass_state(&path, &s).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 10]).unwrap();
        assert!(read_pass_state(&path).unwrap_err().to_string().contains("state.bin"));
    }
}
