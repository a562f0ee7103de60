//! The photon-map and irradiance-cache files through the crate's public API:
//! every layout round-trips, sizes and precision are the paper's and the stated
//! bounds, every bad file is refused with one line naming it, and the reader is
//! fuzzed (mutated files of each layout, random bytes) without a panic.

use glam::Vec3;
use pm_color::Rgb;
use pm_format::*;
use proptest::prelude::*;
use std::path::PathBuf;

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

fn header(kind: MapKind) -> Header {
    Header::new(kind, Order::Unsorted, Layout::Compact, 1234, [7; 32], 1.0, r#"{"seed":1}"#.into())
}

fn write_map<R: PhotonRecord>(dir: &std::path::Path, name: &str, n: usize) -> (PathBuf, PhotonMap<R>) {
    let path = dir.join(name);
    let mut map = PhotonMap::new(header(MapKind::Global), photons(n).iter().map(R::encode).collect());
    map.write(&path).unwrap();
    (path, map)
}

#[test]
fn every_layout_round_trips_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    fn check<R: PhotonRecord>(dir: &std::path::Path, name: &str) {
        let (path, map) = write_map::<R>(dir, name, 1000);
        let back: PhotonMap<R> = read_as(&path, &ReadExpect::default()).unwrap();
        assert_eq!(back.header, map.header);
        assert_eq!(bytemuck::cast_slice::<R, u8>(&back.records), bytemuck::cast_slice::<R, u8>(&map.records));
        // Writing what was read gives the same bytes.
        let again = dir.join(format!("again-{name}"));
        let mut back = back;
        back.write(&again).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), std::fs::read(&again).unwrap());
        assert_eq!(
            (std::fs::metadata(&path).unwrap().len() as usize).is_multiple_of(16),
            R::LAYOUT.record_size() * 1000 % 16 == 0
        );
    }
    check::<CompactPhoton>(dir.path(), "c.pmap");
    check::<CompactIrrPhoton>(dir.path(), "ci.pmap");
    check::<FullPhoton>(dir.path(), "f.pmap");
    check::<FullIrrPhoton>(dir.path(), "fi.pmap");
}

#[test]
fn record_sizes_are_the_papers() {
    assert_eq!(std::mem::size_of::<CompactPhoton>(), 18);
    assert_eq!(std::mem::size_of::<CompactIrrPhoton>(), 23);
    let dir = tempfile::tempdir().unwrap();
    let (path, map) = write_map::<CompactPhoton>(dir.path(), "c.pmap", 100);
    let header_len = std::fs::metadata(&path).unwrap().len() - 100 * 18;
    assert_eq!(header_len as usize, header::encode(&map.header).len());
}

#[test]
fn full_layout_is_exact_and_compact_is_within_stated_bounds() {
    let ps = photons(500);
    for p in &ps {
        assert_eq!(FullIrrPhoton::encode(p).decode(), *p);
        let c = CompactIrrPhoton::encode(p).decode();
        assert_eq!(c.position, p.position);
        assert_eq!(c.flags, p.flags);
        assert!(c.wi.angle_between(p.wi) <= DIRECTION_MAX_ERROR_RAD);
        assert!(c.normal.angle_between(p.normal) <= DIRECTION_MAX_ERROR_RAD);
        let m = p.power.max_element();
        assert!((c.power - p.power).abs().max_element() <= m / 128.0);
    }
}

#[test]
fn direction_byte_error_bound_holds_over_the_sphere() {
    let mut worst = 0f32;
    let n = 200;
    for i in 0..n {
        for j in 0..2 * n {
            let theta = std::f32::consts::PI * (i as f32 + 0.5) / n as f32;
            let phi = std::f32::consts::PI * j as f32 / n as f32;
            let v = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            worst = worst.max(decode_direction(encode_direction(v)).angle_between(v));
        }
    }
    assert!(worst <= DIRECTION_MAX_ERROR_RAD, "worst {worst} rad");
    assert!(worst > DIRECTION_MAX_ERROR_RAD * 0.8, "stated bound is loose: worst {worst} rad");
    // Axis directions survive exactly enough for "dot > 0.9" tests.
    for v in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
        assert!(decode_direction(encode_direction(v)).dot(v) > 0.999, "{v}");
    }
}

#[test]
fn empty_map_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_map::<CompactPhoton>(dir.path(), "e.pmap", 0);
    let back = read(&path, &ReadExpect::default()).unwrap();
    assert!(back.is_empty());
    assert_eq!(back.header().bounds_min, [0.0; 3]);
}

fn err_of(path: &std::path::Path, expect: &ReadExpect) -> String {
    let e = read(path, expect).expect_err("bad file was accepted").to_string();
    assert!(e.starts_with(&path.display().to_string()), "error does not name the file: {e}");
    assert!(!e.contains('\n'), "not one line: {e}");
    e
}

#[test]
fn every_bad_file_is_rejected_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let (path, map) = write_map::<CompactIrrPhoton>(dir.path(), "good.pmap", 200);
    let good = std::fs::read(&path).unwrap();
    let header_len = good.len() - 200 * 23;
    let variant = |name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let cases: Vec<(PathBuf, &str)> = vec![
        (variant("truncated.pmap", &good[..good.len() - 5]), "truncated"),
        (variant("truncated_header.pmap", &good[..100]), "only 100 bytes"),
        (variant("empty.pmap", &[]), "only 0 bytes"),
        (variant("padded.pmap", &[good.as_slice(), &[0u8; 23]].concat()), "truncated or padded"),
        (variant("payload_flip.pmap", &{ let mut b = good.clone(); b[header_len + 40] ^= 0x10; b }), "records are corrupted"),
        (variant("header_flip.pmap", &{ let mut b = good.clone(); b[70] ^= 0x01; b }), "header is corrupted"),
        (variant("magic.pmap", &{ let mut b = good.clone(); b[0] = b'X'; b }), "not a photon map"),
        (variant("version.pmap", &{ let mut b = good.clone(); b[8] = 9; b }), "version 9"),
        (variant("text.pmap", b"this is not a photon map at all, just some text that is long enough to fill a header. ........................................................ ........................................................................................."), "magic"),
    ];
    for (p, what) in &cases {
        let e = err_of(p, &ReadExpect::default());
        assert!(e.contains(what), "{p:?}: expected '{what}' in: {e}");
    }
    // Wrong kind, wrong order, missing irradiance, other scene.
    let e = err_of(&path, &ReadExpect { kind: Some(MapKind::Caustic), ..Default::default() });
    assert!(e.contains("expected a Caustic photon map, found a Global photon map"), "{e}");
    let e = err_of(&path, &ReadExpect { order: Some(Order::KdTree), ..Default::default() });
    assert!(e.contains("run photon-sort first"), "{e}");
    let e = err_of(&path, &ReadExpect { irradiance: Some(true), ..Default::default() });
    assert!(e.contains("run photon-irradiance first"), "{e}");
    let e = err_of(&path, &ReadExpect { scene_hash: Some([8; 32]), ..Default::default() });
    assert!(e.contains("another scene"), "{e}");
    // A valid header over records with NaN positions (checksums recomputed).
    let mut bad = map.clone();
    bad.records[3].pos = [f32::NAN, 0.0, 0.0];
    let nan_path = dir.path().join("nan.pmap");
    bad.write(&nan_path).unwrap();
    assert!(err_of(&nan_path, &ReadExpect::default()).contains("photon 3 is invalid: position is not finite"));
    // Missing file.
    assert!(err_of(&dir.path().join("missing.pmap"), &ReadExpect::default()).contains("No such file"));
}

#[test]
fn failed_write_leaves_the_old_file_and_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = write_map::<CompactPhoton>(dir.path(), "keep.pmap", 10);
    let before = std::fs::read(&path).unwrap();
    let r = write_atomically(&path, |w| {
        use std::io::Write;
        w.write_all(b"partial")?;
        Err(std::io::Error::other("disk full"))
    });
    assert!(r.is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "temporary file left behind");
    // Writing into a folder that does not exist fails with the path in the message.
    let mut map = PhotonMap::new(header(MapKind::Global), Vec::<CompactPhoton>::new());
    let e = map.write(&dir.path().join("no/such/dir/x.pmap")).unwrap_err().to_string();
    assert!(e.contains("no/such/dir/x.pmap") && !e.contains('\n'), "{e}");
}

#[test]
fn layouts_convert_through_the_decoded_photon() {
    let map =
        PhotonMap::new(header(MapKind::Global), photons(50).iter().map(FullIrrPhoton::encode).collect::<Vec<_>>());
    let compact: PhotonMap<CompactPhoton> = into_layout(AnyMap::FullIrr(map.clone()));
    assert_eq!(compact.header.layout, Layout::Compact);
    assert_eq!(compact.records.len(), 50);
    let same: PhotonMap<FullIrrPhoton> = into_layout(AnyMap::FullIrr(map.clone()));
    assert_eq!(bytemuck::cast_slice::<_, u8>(&same.records), bytemuck::cast_slice::<_, u8>(&map.records));
}

fn cache_file(n: usize) -> crate::CacheFile {
    let records = (0..n)
        .map(|i| {
            let f = i as f32;
            crate::CacheRecord {
                p: [f, -f, 0.5],
                n: [0.0, 1.0, 0.0],
                e: [f * 0.1, 1.0, 2.0],
                r: 0.25 + f,
                grad_t: [f * 1e-3; 9],
                grad_r: [-f * 1e-3; 9],
            }
        })
        .collect();
    crate::CacheFile {
        width: 64,
        height: 48,
        scene_hash: [3; 32],
        map_hash: [9; 32],
        params: "width=64 height=48".into(),
        records,
    }
}

#[test]
fn irradiance_cache_files_round_trip_and_every_bad_one_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("icache.bin");
    let c = cache_file(37);
    crate::write_cache(&path, &c).unwrap();
    assert_eq!(crate::read_cache(&path).unwrap(), c);
    let good = std::fs::read(&path).unwrap();
    let header_len = u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let mutate = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = good.clone();
        f(&mut b);
        std::fs::write(&path, &b).unwrap();
        let e = crate::read_cache(&path).unwrap_err().to_string();
        assert!(e.starts_with(&path.display().to_string()) && !e.contains('\n'), "{e}");
        e
    };
    assert!(mutate(&|b| b.truncate(20)).contains("only 20 bytes"));
    assert!(mutate(&|b| b[0] = b'X').contains("magic"));
    assert!(mutate(&|b| b[8] = 7).contains("version 7"));
    assert!(mutate(&|b| b[40] ^= 1).contains("checksum"));
    assert!(mutate(&|b| b.truncate(b.len() - 1)).contains("truncated"));
    assert!(mutate(&|b| b[header_len + 5] ^= 0x40).contains("corrupted"));
    // A photon map is not a cache.
    let (map, _) = write_map::<crate::CompactPhoton>(dir.path(), "map.pmap", 3);
    assert!(crate::read_cache(&map).unwrap_err().to_string().contains("magic"));
    // A record with a NaN, written with a valid checksum, is refused by index.
    let mut bad = cache_file(3);
    bad.records[2].e[1] = f32::NAN;
    crate::write_cache(&path, &bad).unwrap();
    assert!(crate::read_cache(&path).unwrap_err().to_string().contains("record 2"));
}

fn state_file(w: u32, h: u32) -> crate::StateFile {
    let records = (0..w * h)
        .map(|i| {
            let f = i as f32;
            crate::StateRecord {
                radius: 0.01 + f,
                n: 2.0 * f,
                tau: [[f * 0.5; 3]; 3],
                ld: [[f * 0.25; 3]; 5],
                l_sum: f,
                l_sq: f * f,
                share: 0.5,
                seen: f,
            }
        })
        .collect();
    crate::StateFile { width: w, height: h, passes: 12, scene_hash: [5; 32], params: "width=4 seed=1".into(), records }
}

/// The progressive state file round-trips, and every bad one (short, another
/// kind, another version, a flipped header or record byte, truncated, records
/// that do not cover the image, a NaN, a negative count or a zero radius) is
/// refused with one line naming the file; a key difference names the setting.
#[test]
fn progressive_state_files_round_trip_and_every_bad_one_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sppm.state");
    let st = state_file(4, 3);
    crate::write_state(&path, &st).unwrap();
    assert_eq!(crate::read_state(&path).unwrap(), st);
    let good = std::fs::read(&path).unwrap();
    let header_len = u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let refused = |bytes: &[u8]| {
        std::fs::write(&path, bytes).unwrap();
        let e = crate::read_state(&path).unwrap_err().to_string();
        assert!(e.starts_with(&path.display().to_string()) && !e.contains('\n'), "{e}");
        e
    };
    let mutate = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = good.clone();
        f(&mut b);
        refused(&b)
    };
    assert!(mutate(&|b| b.truncate(20)).contains("only 20 bytes"));
    assert!(mutate(&|b| b[0] = b'X').contains("magic"));
    assert!(mutate(&|b| b[8] = 1).contains("progressive state format version 1"));
    assert!(mutate(&|b| b[28] ^= 1).contains("checksum"));
    assert!(mutate(&|b| b.truncate(b.len() - 1)).contains("truncated"));
    assert!(mutate(&|b| b[header_len + 5] ^= 0x40).contains("corrupted"));
    let cache = dir.path().join("icache.bin");
    crate::write_cache(&cache, &cache_file(2)).unwrap();
    assert!(refused(&std::fs::read(&cache).unwrap()).contains("magic"));
    let write_bad = |f: &dyn Fn(&mut crate::StateFile)| {
        let mut bad = state_file(4, 3);
        f(&mut bad);
        crate::write_state(&path, &bad).unwrap();
        crate::read_state(&path).unwrap_err().to_string()
    };
    assert!(write_bad(&|s| s.width = 5).contains("12 records for a 5x3 image"));
    assert!(write_bad(&|s| s.records[7].tau[1][1] = f32::NAN).contains("record 7"));
    assert!(write_bad(&|s| s.records[2].n = -1.0).contains("record 2"));
    assert!(write_bad(&|s| s.records[0].radius = 0.0).contains("record 0"));
    assert_eq!(
        crate::key_difference("width=4 seed=1", "width=4 seed=2"),
        Some(("seed=1".to_string(), "seed=2".to_string()))
    );
    assert_eq!(crate::key_difference("width=4", "width=4 seed=2"), Some(("(none)".to_string(), "seed=2".to_string())));
    assert_eq!(crate::key_difference("width=4 seed=2", "width=4 seed=2"), None);
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
            0 => write_map::<CompactPhoton>(dir.path(), "m.pmap", 60).0,
            1 => write_map::<CompactIrrPhoton>(dir.path(), "m.pmap", 60).0,
            2 => write_map::<FullPhoton>(dir.path(), "m.pmap", 60).0,
            _ => write_map::<FullIrrPhoton>(dir.path(), "m.pmap", 60).0,
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
