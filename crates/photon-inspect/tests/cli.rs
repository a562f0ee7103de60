//! photon-inspect on maps written here: the summary counts what is in the file and
//! catches a broken kd-tree; the PLY holds every photon.

use glam::Vec3;
use pm_format::{FullIrrPhoton, Header, Layout, MapKind, Order, Photon, PhotonMap, PhotonRecord, flags};
use std::process::Command;

fn inspect(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_photon-inspect")).args(args).output().unwrap()
}

#[test]
fn summary_counts_flags_verifies_the_tree_and_ply_has_every_photon() {
    let dir = tempfile::tempdir().unwrap();
    let photons: Vec<FullIrrPhoton> = (0..1000)
        .map(|i| {
            let f = if i % 4 == 0 {
                flags::DIRECT
            } else if i % 4 == 1 {
                flags::CAUSTIC
            } else {
                0
            };
            FullIrrPhoton::encode(&Photon {
                position: Vec3::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32),
                power: Vec3::splat(0.5),
                wi: Vec3::Y,
                flags: f
                    | flags::AXIS_LEAF
                    | if i % 10 == 0 { flags::HAS_IRRADIANCE } else { 0 }
                    | if i % 20 == 3 { flags::COVERED } else { 0 },
                normal: Vec3::Y,
                irradiance: Vec3::splat(if i % 10 == 0 { 2.0 } else { 0.0 }),
            })
        })
        .collect();
    let nodes = pm_kdtree::balance(&photons);
    // Positions relative to a camera 1e6 m from the world origin: the summary and the
    // point cloud give world coordinates.
    let origin = [1e6, -2.5, 0.125];
    let mut header =
        Header::new(MapKind::Global, Order::KdTree, Layout::FullIrradiance, 777, [5; 32], 1.0, "{}".into())
            .with_origin(origin);
    header.has_irradiance = true;
    let good = dir.path().join("good.pmap");
    PhotonMap::new(header.clone(), nodes.clone()).write(&good).unwrap();
    let ply = dir.path().join("g.ply");
    let o = inspect(&[good.to_str().unwrap(), "--json", "--ply", ply.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(s["photons"], 1000);
    assert_eq!(s["emitted"], 777);
    assert_eq!(
        (s["direct"].as_u64(), s["caustic_path"].as_u64(), s["indirect"].as_u64()),
        (Some(250), Some(250), Some(500))
    );
    assert_eq!(s["kd_tree"]["valid"], true);
    assert_eq!(s["in_medium"], 0);
    assert_eq!(s["covered"], 50);
    assert_eq!(s["irradiance"]["photons"], 100);
    assert_eq!(s["total_power_w"][0].as_f64(), Some(500.0));
    assert_eq!(s["origin_m"][0].as_f64(), Some(1e6));
    assert_eq!(s["bounds_min_m"][0].as_f64(), Some(1e6));
    assert_eq!(s["bounds_max_m"][1].as_f64(), Some(9.0 - 2.5));
    let bytes = std::fs::read(&ply).unwrap();
    let text = String::from_utf8_lossy(&bytes[..300]);
    assert!(text.contains("element vertex 1000"));
    let header_len = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    assert_eq!(bytes.len() - header_len, 1000 * 27);
    // Every point's world position is a record position plus the origin, to f64.
    let xs: Vec<f64> =
        (0..1000).map(|i| f64::from_le_bytes(bytes[header_len + i * 27..][..8].try_into().unwrap())).collect();
    assert!(xs.iter().all(|x| (x - 1e6).fract() == 0.0 && (1e6..=1e6 + 9.0).contains(x)), "{:?}", &xs[..5]);
    // Swap two nodes: still a valid file (checksums recomputed), but not a kd-tree.
    let mut broken = nodes;
    broken.swap(1, 2);
    let bad = dir.path().join("bad.pmap");
    PhotonMap::new(header, broken).write(&bad).unwrap();
    let o = inspect(&[bad.to_str().unwrap(), "--json"]);
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(s["kd_tree"]["valid"], false);
}
