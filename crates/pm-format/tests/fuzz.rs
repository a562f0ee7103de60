//! Fuzzing the photon-map reader: any mutation of a valid file of each record
//! layout (byte flips, truncation, extension) and arbitrary bytes are read as a
//! valid map or refused with one line naming the file; never a panic.

use glam::Vec3;
use pm_color::Rgb;
use pm_format::{
    CompactIrrPhoton, CompactPhoton, FullIrrPhoton, FullPhoton, Header, Layout, MapKind, Order, Photon, PhotonMap,
    PhotonRecord, ReadExpect, flags, read,
};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

/// `n` photons with every field varied.
fn photons(n: usize) -> Vec<Photon> {
    (0..n)
        .map(|i| {
            let f = i as f32;
            Photon {
                position: Vec3::new(f.sin() * 3.0, f * 0.01, -f.cos()),
                power: Rgb::new(0.5 + f * 1e-3, 0.25, 1e-4 * f),
                wi: Vec3::new(f.cos(), 0.3, f.sin()).normalize(),
                flags: if i % 3 == 0 { flags::DIRECT } else { 0 } | flags::AXIS_LEAF,
                normal: Vec3::new(0.2, 1.0, -0.1).normalize(),
                irradiance: Rgb::new(3.0, 2.0, f),
            }
        })
        .collect()
}

/// A valid map of `n` photons in layout `R` written to `dir/name`.
fn write_map<R: PhotonRecord>(dir: &Path, name: &str, n: usize) -> PathBuf {
    let path = dir.join(name);
    let header = Header::new(MapKind::Global, Order::Unsorted, Layout::Compact, 1234, [7; 32], 1.0, "{}".into());
    PhotonMap::new(header, photons(n).iter().map(R::encode).collect::<Vec<R>>()).write(&path).unwrap();
    path
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    /// Fuzz: any mutation of a valid file (byte flips, truncation, extension) is
    /// either read as a valid map or rejected with one line naming the file; never a panic.
    #[test]
    fn reader_never_panics_on_mutated_files(
        flips in proptest::collection::vec((0usize..4000, any::<u8>()), 0..6),
        cut in proptest::option::of(0usize..4000),
        extra in proptest::collection::vec(any::<u8>(), 0..40),
        layout in 0u8..4,
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = match layout {
            0 => write_map::<CompactPhoton>(dir.path(), "m.pmap", 60),
            1 => write_map::<CompactIrrPhoton>(dir.path(), "m.pmap", 60),
            2 => write_map::<FullPhoton>(dir.path(), "m.pmap", 60),
            _ => write_map::<FullIrrPhoton>(dir.path(), "m.pmap", 60),
        };
        let mut bytes = std::fs::read(&path).unwrap();
        for (at, v) in flips {
            if at < bytes.len() { bytes[at] ^= v; }
        }
        if let Some(c) = cut { bytes.truncate(c); }
        bytes.extend_from_slice(&extra);
        std::fs::write(&path, &bytes).unwrap();
        match read(&path, &ReadExpect::default()) {
            Ok(map) => {
                for p in map.decode_all() {
                    prop_assert!(p.position.is_finite() && pm_color::is_valid(p.power));
                }
            }
            Err(e) => {
                let s = e.to_string();
                prop_assert!(s.starts_with(&path.display().to_string()) && !s.contains('\n'), "{}", s);
            }
        }
    }

    /// Fuzz: arbitrary bytes.
    #[test]
    fn reader_never_panics_on_random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..600), magic in any::<bool>()) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.pmap");
        let mut bytes = bytes;
        if magic && bytes.len() >= 16 {
            bytes[..8].copy_from_slice(&pm_format::header::MAGIC);
            bytes[8..12].copy_from_slice(&1u32.to_le_bytes());
        }
        std::fs::write(&path, &bytes).unwrap();
        if let Err(e) = read(&path, &ReadExpect::default()) {
            prop_assert!(!e.to_string().contains('\n'));
        }
    }
}
