//! kd-tree benchmark: build time and query throughput of pm-kdtree against kiddo
//! (ImmutableKdTree) and brute force, on photon maps traced in cornell_spheres and
//! on clustered synthetic points. Prints a markdown table for BENCHMARKS.md.
//!
//! Run: `cargo bench -p pm-kdtree --bench kdtree` (`-- build`: build times only)

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use pm_format::{CompactIrrPhoton, Photon, PhotonRecord, flags};
use pm_kdtree::{Buckets, KdTree, KnnScratch, balance};
use rayon::prelude::*;
use std::num::NonZero;
use std::time::Instant;

const K: usize = 50;
const QUERIES: usize = 200_000;

fn real_photons(n: u64, seed: u64) -> Vec<CompactIrrPhoton> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell_spheres.gltf");
    let scene = pm_scene::load(&path).unwrap();
    let mut ps = pm_photon::trace_global(&scene, n, seed).unwrap();
    ps.truncate(n as usize);
    ps.iter().map(CompactIrrPhoton::encode).collect()
}

/// Gaussian-ish clusters of very different density (hash-based, deterministic).
fn clustered(n: u64) -> Vec<CompactIrrPhoton> {
    let h = |i: u64, s: u64| (pm_sampling::mix64(i * 31 + s) >> 40) as f32 / (1u64 << 24) as f32;
    (0..n)
        .map(|i| {
            let c = (h(i, 1) * h(i, 1) * 64.0) as u64; // skewed cluster choice
            let centre = Vec3::new(h(c, 2), h(c, 3), h(c, 4)) * 10.0;
            let spread = 0.001 + 0.2 * h(c, 5);
            let g = |s| (h(i, s) + h(i, s + 10) + h(i, s + 20) - 1.5) * spread;
            let p = Photon {
                position: centre + Vec3::new(g(6), g(7), g(8)),
                power: Vec3::ONE,
                wi: Vec3::Y,
                flags: flags::AXIS_LEAF,
                normal: Vec3::Y,
                irradiance: Vec3::ZERO,
            };
            CompactIrrPhoton::encode(&p)
        })
        .collect()
}

fn best_of<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..reps {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.unwrap())
}

/// `-- build`: build times alone, ours and kiddo's alternated `REPS` times on each
/// set (both take milliseconds, and one timing of either varies by a third).
fn builds_only() {
    const REPS: usize = 15;
    println!("threads: {}", rayon::current_num_threads());
    println!(
        "| data | photons | build ours, median (best) [ms] | build kiddo, median (best) [ms] | ours/kiddo, medians |"
    );
    println!("|---|---|---|---|---|");
    for n in [100_000u64, 1_000_000, 4_000_000] {
        for (name, recs) in [("cornell_spheres", real_photons(n, 1)), ("clustered", clustered(n))] {
            let positions: Vec<[f32; 3]> = recs.iter().map(|r| r.position().to_array()).collect();
            let (mut ours, mut kiddo) = (Vec::new(), Vec::new());
            for _ in 0..REPS {
                ours.push(best_of(1, || balance(&recs)).0);
                kiddo.push(best_of(1, || ImmutableKdTree::<f32, 3>::new_from_slice(&positions).unwrap()).0);
            }
            for v in [&mut ours, &mut kiddo] {
                v.sort_by(f64::total_cmp);
            }
            let (mo, mk) = (ours[REPS / 2], kiddo[REPS / 2]);
            println!(
                "| {name} | {n} | {:.2} ({:.2}) | {:.2} ({:.2}) | {:.2} |",
                1e3 * mo,
                1e3 * ours[0],
                1e3 * mk,
                1e3 * kiddo[0],
                mo / mk
            );
        }
    }
}

fn main() {
    if std::env::args().any(|a| a == "build") {
        return builds_only();
    }
    println!("threads: {}", rayon::current_num_threads());
    println!(
        "| data | photons | build ours [s] | of which buckets [s] | build kiddo [s] | build ours/kiddo | 50-NN ours [q/s] | 50-NN without buckets [q/s] | 50-NN kiddo [q/s] | ours/kiddo | nearest-with-normal ours [q/s] | rank 1 / 2 / 3+ | brute-force 50-NN [q/s] |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut bucket_bytes = 0.0;
    for n in [100_000u64, 1_000_000, 4_000_000] {
        // Query points: an independent photon set (another seed) with its surface normals,
        // so queries land where a renderer's would, edges and corners included.
        let probes = real_photons(QUERIES as u64, 99);
        for (name, recs) in [("cornell_spheres", real_photons(n, 1)), ("clustered", clustered(n))] {
            let positions: Vec<[f32; 3]> = recs.iter().map(|r| r.position().to_array()).collect();
            let (t_ours, nodes) = best_of(3, || balance(&recs));
            let (t_kiddo, kd) = best_of(3, || ImmutableKdTree::<f32, 3>::new_from_slice(&positions).unwrap());
            let (t_buckets, buckets) = best_of(3, || Buckets::new(&nodes));
            bucket_bytes = buckets.bytes() as f64 / n as f64;
            let plain = KdTree::new(&nodes);
            assert!(plain.verify().is_ok());
            let tree = KdTree::with_buckets(&nodes, &buckets);
            // Queries: photon positions nudged off the surface, and their normals.
            let qs: Vec<(Vec3, Vec3)> = if name == "clustered" {
                (0..QUERIES)
                    .map(|i| {
                        let r = &nodes[(pm_sampling::mix64(i as u64) % n) as usize];
                        (r.position() + Vec3::splat(1e-3), r.normal())
                    })
                    .collect()
            } else {
                probes.iter().map(|r| (r.position(), r.normal())).collect()
            };
            // Best time of two passes of 50-NN queries over `t`, and the sum of the
            // k-th distances (to check against kiddo's).
            let knn_all = |t: &KdTree<CompactIrrPhoton>| {
                best_of(2, || {
                    qs.par_chunks(1024)
                        .map(|c| {
                            let mut s = KnnScratch::with_capacity(K);
                            c.iter()
                                .map(|(x, _)| t.knn(*x, K, f32::INFINITY, |_, _| true, &mut s).max_dist2 as f64)
                                .sum::<f64>()
                        })
                        .sum::<f64>()
                })
            };
            let (t_knn, sum_ours) = knn_all(&tree);
            let (t_plain, _) = knn_all(&plain);
            let (t_kiddo_q, sum_kiddo) = best_of(2, || {
                qs.par_chunks(1024)
                    .map(|c| {
                        c.iter()
                            .map(|(x, _)| {
                                let r = kd
                                    .query(&x.to_array())
                                    .nearest_n::<SquaredEuclidean<f32>>(NonZero::new(K).unwrap())
                                    .execute();
                                r.last().map_or(0.0, |q| q.distance as f64)
                            })
                            .sum::<f64>()
                    })
                    .sum::<f64>()
            });
            assert!(
                (sum_ours - sum_kiddo).abs() <= 1e-6 * sum_kiddo.abs().max(1.0),
                "ours and kiddo disagree: {sum_ours} vs {sum_kiddo}"
            );
            let (t_near, ranks) = best_of(2, || {
                qs.par_chunks(1024)
                    .map(|c| {
                        let mut rej = Vec::new();
                        let mut hist = [0u64; 3];
                        for (x, nq) in c {
                            if let Some(h) = tree.nearest(*x, f32::INFINITY, |r| r.normal().dot(*nq) > 0.9, &mut rej) {
                                hist[(h.rank as usize - 1).min(2)] += 1;
                            }
                        }
                        hist
                    })
                    .reduce(|| [0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
            });
            let total: u64 = ranks.iter().sum();
            let pct = |i: usize| 100.0 * ranks[i] as f64 / total.max(1) as f64;
            let brute = if n <= 100_000 {
                let bq = &qs[..200];
                let (t, _) = best_of(1, || {
                    bq.par_iter()
                        .map(|(x, _)| {
                            let mut d: Vec<f32> = nodes.iter().map(|r| (r.position() - *x).length_squared()).collect();
                            d.select_nth_unstable_by(K, f32::total_cmp);
                            d[K] as f64
                        })
                        .sum::<f64>()
                });
                format!("{:.0}", bq.len() as f64 / t)
            } else {
                "-".into()
            };
            let q = QUERIES as f64;
            println!(
                "| {name} | {n} | {:.3} | {t_buckets:.3} | {t_kiddo:.3} | {:.2} | {:.0} | {:.0} | {:.0} | {:.2} | {:.0} | {:.1}% / {:.1}% / {:.1}% | {brute} |",
                t_ours + t_buckets,
                (t_ours + t_buckets) / t_kiddo,
                q / t_knn,
                q / t_plain,
                q / t_kiddo_q,
                t_kiddo_q / t_knn,
                q / t_near,
                pct(0),
                pct(1),
                pct(2)
            );
        }
    }
    println!(
        "\nmemory per photon: ours {} bytes (the record) and {:.1} bytes of leaf buckets (4M clustered)",
        std::mem::size_of::<CompactIrrPhoton>(),
        bucket_bytes
    );
}
