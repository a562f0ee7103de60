//! The photon-irradiance binary on real map files.

use glam::Vec3;
use pm_format::{
    CompactIrrPhoton, CompactPhoton, Header, MapKind, Order, Photon, PhotonMap, PhotonRecord, ReadExpect, flags,
};
use std::path::Path;
use std::process::Command;

fn irradiance(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_photon-irradiance")).args(args).output().unwrap()
}

/// A sorted global map: photons of 1 mW on a jittered 2 m x 2 m floor (E = 1 mW x
/// count / 4 m^2), normals +y.
fn write_sorted<R: PhotonRecord>(path: &Path, n: usize, kind: MapKind, order: Order) -> f32 {
    let photons: Vec<R> = (0..n)
        .map(|i| {
            let f = i as f32;
            R::encode(&Photon {
                position: Vec3::new((f * 0.618_034).fract() * 2.0 - 1.0, 0.0, (f * 0.414_214).fract() * 2.0 - 1.0),
                power: Vec3::splat(1e-3),
                wi: Vec3::new(0.2, 0.9, 0.1).normalize(),
                flags: flags::AXIS_LEAF,
                normal: Vec3::Y,
                irradiance: Vec3::ZERO,
            })
        })
        .collect();
    let records = if order == Order::KdTree { pm_kdtree::balance(&photons) } else { photons };
    PhotonMap::new(Header::new(kind, order, R::LAYOUT, n as u64, [1; 32], 1.0, "{}".into()), records)
        .write(path)
        .unwrap();
    1e-3 * n as f32 / 4.0
}

#[test]
fn stores_irradiance_in_the_selected_fraction_identically_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("global.kd.pmap");
    let e_true = write_sorted::<CompactIrrPhoton>(&input, 40_000, MapKind::Global, Order::KdTree);
    for t in ["1", "2"] {
        let out = dir.path().join(format!("irr{t}.pmap"));
        let o = irradiance(&[
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            t,
            "--k",
            "100",
            "--refine-ratio",
            "0",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let a = std::fs::read(dir.path().join("irr1.pmap")).unwrap();
    assert_eq!(a, std::fs::read(dir.path().join("irr2.pmap")).unwrap());
    let map: PhotonMap<CompactIrrPhoton> =
        pm_format::read_as(&dir.path().join("irr1.pmap"), &ReadExpect { irradiance: Some(true), ..Default::default() })
            .unwrap();
    let with: Vec<&CompactIrrPhoton> = map.records.iter().filter(|r| r.flags() & flags::HAS_IRRADIANCE != 0).collect();
    // One in every four kd-tree positions.
    assert_eq!(with.len(), 10_000);
    // Away from the floor's edges the estimate is the uniform density (k = 100: 10% noise).
    let inner: Vec<f32> =
        with.iter().filter(|r| r.position().abs().max_element() < 0.8).map(|r| r.irradiance().x).collect();
    let mean = inner.iter().sum::<f32>() / inner.len() as f32;
    assert!((mean / e_true - 1.0).abs() < 0.03, "mean {mean} vs {e_true}");
    assert!(
        map.records.iter().filter(|r| r.flags() & flags::HAS_IRRADIANCE == 0).all(|r| r.irradiance() == Vec3::ZERO)
    );
    // With the default refinement the photons between disagreeing precomputed
    // neighbours get one too: here only along the floor's edges, where (without
    // the scene) the estimates read half the light.
    let out = dir.path().join("refined.pmap");
    let o = irradiance(&[input.to_str().unwrap(), "--out", out.to_str().unwrap(), "--k", "100"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let refined: PhotonMap<CompactIrrPhoton> =
        pm_format::read_as(&out, &ReadExpect { irradiance: Some(true), ..Default::default() }).unwrap();
    let extra: Vec<&CompactIrrPhoton> = refined
        .records
        .iter()
        .zip(&map.records)
        .filter(|(r, plain)| r.flags() & flags::HAS_IRRADIANCE != 0 && plain.flags() & flags::HAS_IRRADIANCE == 0)
        .map(|(r, _)| r)
        .collect();
    assert!(!extra.is_empty() && extra.len() < 2_000, "{} refined", extra.len());
    assert!(extra.iter().all(|r| r.position().abs().max_element() > 0.75), "a photon refined away from the edges");
}

#[test]
fn refuses_maps_it_cannot_use() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("unsorted.pmap", "run photon-sort first"),
        ("caustic.kd.pmap", "expected a Global photon map, found a Caustic photon map"),
        ("compact.kd.pmap", "carry no surface normal"),
    ];
    write_sorted::<CompactIrrPhoton>(&dir.path().join(cases[0].0), 100, MapKind::Global, Order::Unsorted);
    write_sorted::<CompactPhoton>(&dir.path().join(cases[1].0), 100, MapKind::Caustic, Order::KdTree);
    write_sorted::<CompactPhoton>(&dir.path().join(cases[2].0), 100, MapKind::Global, Order::KdTree);
    for (file, what) in cases {
        let input = dir.path().join(file);
        let out = dir.path().join(format!("{file}.irr"));
        let o = irradiance(&[input.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        let last = err.trim_end().lines().last().unwrap();
        assert!(last.starts_with("photon-irradiance: error: ") && last.contains(what) && last.contains(file), "{err}");
        assert!(!out.exists());
    }
    let o = irradiance(&[dir.path().join("unsorted.pmap").to_str().unwrap(), "--out", "x", "--fraction", "0"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--fraction = 0 is out of range (in (0, 1])"));
    // A file whose header says kd-tree but whose records are not in kd-tree order.
    let mut m: PhotonMap<CompactIrrPhoton> =
        pm_format::read_as(&dir.path().join("unsorted.pmap"), &ReadExpect::default()).unwrap();
    m.header.order = Order::KdTree;
    let scrambled = dir.path().join("scrambled.kd.pmap");
    m.write(&scrambled).unwrap();
    let out = dir.path().join("scrambled.irr");
    let o = irradiance(&[scrambled.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("scrambled.kd.pmap: not a valid kd-tree"), "{err}");
    assert!(!out.exists());
}
