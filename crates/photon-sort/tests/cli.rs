//! The photon-sort binary on real map files.

use glam::Vec3;
use pm_format::{CompactIrrPhoton, Header, Layout, MapKind, Order, Photon, PhotonMap, PhotonRecord, ReadExpect, flags};
use std::path::Path;
use std::process::Command;

fn sort(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_photon-sort")).args(args).output().unwrap()
}

fn write_input(path: &Path, n: usize) {
    let photons: Vec<CompactIrrPhoton> = (0..n)
        .map(|i| {
            let f = i as f32;
            CompactIrrPhoton::encode(&Photon {
                position: Vec3::new((f * 0.618).fract(), ((f * 0.377).fract() * 3.0).floor(), (f * 0.123).fract()),
                power: Vec3::splat(1e-3 + f * 1e-7),
                wi: Vec3::Y,
                flags: flags::AXIS_LEAF | if i % 3 == 0 { flags::DIRECT } else { 0 },
                normal: Vec3::Y,
                irradiance: Vec3::ZERO,
            })
        })
        .collect();
    PhotonMap::new(
        Header::new(MapKind::Global, Order::Unsorted, Layout::CompactIrradiance, n as u64, [3; 32], 1.0, "{}".into()),
        photons,
    )
    .write(path)
    .unwrap();
}

#[test]
fn sorted_file_is_a_valid_tree_of_the_same_photons_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("global.pmap");
    write_input(&input, 70_000);
    for t in ["1", "2"] {
        let o = sort(&[
            input.to_str().unwrap(),
            "--out",
            dir.path().join(format!("kd{t}.pmap")).to_str().unwrap(),
            "--threads",
            t,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let a = std::fs::read(dir.path().join("kd1.pmap")).unwrap();
    assert_eq!(a, std::fs::read(dir.path().join("kd2.pmap")).unwrap());
    let sorted: PhotonMap<CompactIrrPhoton> = pm_format::read_as(
        &dir.path().join("kd1.pmap"),
        &ReadExpect { order: Some(Order::KdTree), ..Default::default() },
    )
    .unwrap();
    assert!(pm_kdtree::KdTree::new(&sorted.records).verify().is_ok());
    let unsorted: PhotonMap<CompactIrrPhoton> = pm_format::read_as(&input, &ReadExpect::default()).unwrap();
    // Same photons (flags differ only in the axis bits), same header totals.
    let key = |r: &CompactIrrPhoton| {
        let mut b = bytemuck::bytes_of(r).to_vec();
        b[17] &= !flags::AXIS_MASK;
        b
    };
    let mut x: Vec<_> = unsorted.records.iter().map(key).collect();
    let mut y: Vec<_> = sorted.records.iter().map(key).collect();
    x.sort();
    y.sort();
    assert_eq!(x, y);
    assert_eq!(sorted.header.total_power, unsorted.header.total_power);
    assert_eq!(sorted.header.scene_hash, unsorted.header.scene_hash);
}

#[test]
fn corrupted_input_fails_cleanly_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("global.pmap");
    write_input(&input, 1000);
    let mut bytes = std::fs::read(&input).unwrap();
    let n = bytes.len();
    bytes[n - 100] ^= 0xff;
    std::fs::write(&input, &bytes).unwrap();
    let out = dir.path().join("global.kd.pmap");
    let o = sort(&[input.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err.trim_end().lines().last().unwrap().contains(&format!("{}: photon records are corrupted", input.display())),
        "{err}"
    );
    assert!(!out.exists());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary files left");
}
