//! What an error is made of: bias and noise of an estimator, from renders with
//! different seeds against a reference whose own noise is known (the trade-off
//! study's measures, `cargo xtask tradeoff`).
//!
//! With S renders I_k of one setting, their mean M, and a reference R = T + e_R
//! (truth T, noise of per-pixel variance s_R^2), over the kept pixels and channels:
//!
//! ```text
//! noise^2 = sum_k |I_k - M|^2 / ((S - 1) n)            (one render's variance)
//! |M - R|^2 / n = bias^2 + noise^2 / S + s_R^2          (in expectation)
//! bias^2  = max(0, |M - R|^2 / n - noise^2 / S - s_R^2)
//! error   = sqrt(bias^2 + noise^2)                      (one render against T)
//! ```
//!
//! each divided by the reference's mean (relative, like [`crate::compare`]).
//! The reference's s_R^2 comes from two independent halves A and B of it:
//! R = (A + B) / 2 has s_R^2 = |A - B|^2 / (4 n).

use glam::Vec3;

/// Bias and noise of one setting (relative to the reference's mean).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Split {
    /// sqrt(bias^2 + noise^2): the expected error of one render against the truth.
    pub error: f64,
    /// RMS of the seeds' mean minus the reference, less the noise of both.
    pub bias: f64,
    /// RMS spread of one render about the seeds' mean.
    pub noise: f64,
    /// The reference's own noise (RMS).
    pub reference_noise: f64,
    /// Signed mean difference of the seeds' mean from the reference.
    pub mean_bias: f64,
    /// Mean over the seeds of each render's RMSE against the reference (what a
    /// single comparison would report: it contains the reference's noise).
    pub measured: f64,
}

/// Pixels to compare: all but those within one pixel of a pixel brighter than half
/// the reference's brightest (the light seen directly, whose anti-aliased edge
/// would otherwise dominate every error), or, with `above_mean` = F, brighter
/// than F times the reference's mean (a sun's sub-pixel glints in mirrors and
/// glass: one pixel at the sun's radiance, 5,000 times the mean, is an RMS error
/// of 20 times the mean over a 256 x 256 image).
pub fn keep_mask(reference: &[Vec3], width: usize, height: usize, above_mean: Option<f32>) -> Vec<bool> {
    let peak = reference.iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
    let mean = reference.iter().map(|p| p.max_element() as f64).sum::<f64>() / reference.len().max(1) as f64;
    let limit = above_mean.map_or(0.5 * peak, |f| (0.5 * peak).min(f * mean as f32));
    let bright: Vec<bool> = reference.iter().map(|p| p.max_element() > limit && peak > 0.0).collect();
    left_out_with_neighbours(&bright, width, height)
}

/// Pixels to compare: all but the `marked` ones of a `width` x `height` image
/// and their eight neighbours.
pub fn left_out_with_neighbours(marked: &[bool], width: usize, height: usize) -> Vec<bool> {
    (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as i64, (i / width) as i64);
            !(-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (xx, yy) = (x + dx, y + dy);
                    xx >= 0
                        && yy >= 0
                        && xx < width as i64
                        && yy < height as i64
                        && marked[(yy * width as i64 + xx) as usize]
                })
            })
        })
        .collect()
}

/// [`keep_mask`] of the reference whose two independent halves are `a` and `b`
/// (their mean).
pub fn keep_mask_of_halves(a: &[Vec3], b: &[Vec3], width: usize, height: usize, above_mean: Option<f32>) -> Vec<bool> {
    let mean: Vec<Vec3> = a.iter().zip(b).map(|(a, b)| (*a + *b) * 0.5).collect();
    keep_mask(&mean, width, height, above_mean)
}

/// The reference (mean of its halves) and its per-pixel noise variance averaged
/// over the kept channels, from two independent halves of equal sample counts.
pub fn reference_from_halves(a: &[Vec3], b: &[Vec3], keep: &[bool]) -> (Vec<Vec3>, f64) {
    let r: Vec<Vec3> = a.iter().zip(b).map(|(a, b)| (*a + *b) * 0.5).collect();
    let n = (keep.iter().filter(|&&k| k).count() * 3).max(1) as f64;
    let d2: f64 = a.iter().zip(b).zip(keep).filter(|x| *x.1).map(|((a, b), _)| (*a - *b).length_squared() as f64).sum();
    (r, d2 / (4.0 * n))
}

/// Mean of `image` over the kept pixels and their channels (the denominator of
/// every relative measure here).
pub fn kept_mean(image: &[Vec3], keep: &[bool]) -> f64 {
    let (sum, n) = image
        .iter()
        .zip(keep)
        .filter(|x| *x.1)
        .fold((0.0, 0usize), |(s, n), (p, _)| (s + p.element_sum() as f64, n + 3));
    sum / n.max(1) as f64
}

/// The relative noise of one render from its own per-pixel noise variances
/// `var` (of the mean of a pixel's channels, as a progressive render estimates
/// them from its passes) over the `keep` pixels: sqrt(mean var) / kept mean,
/// the [`Split::noise`] of a render with that variance.
pub fn noise_of_variances(image: &[Vec3], var: &[f32], keep: &[bool]) -> f64 {
    let (sum, n) = var.iter().zip(keep).filter(|x| *x.1).fold((0.0, 0usize), |(s, n), (v, _)| (s + *v as f64, n + 1));
    (sum / n.max(1) as f64).sqrt() / kept_mean(image, keep).abs().max(1e-30)
}

/// Split the error of `renders` (one per seed, at least two) against `reference`
/// with per-pixel noise variance `reference_var`, over the `keep` pixels.
pub fn split(renders: &[&[Vec3]], reference: &[Vec3], reference_var: f64, keep: &[bool]) -> Split {
    let s = renders.len();
    let idx: Vec<usize> = (0..reference.len()).filter(|&i| keep[i]).collect();
    let n = (idx.len() * 3).max(1) as f64;
    let denom = kept_mean(reference, keep).abs().max(1e-30);
    let mean_of = |i: usize| renders.iter().map(|r| r[i].as_dvec3()).sum::<glam::DVec3>() / s.max(1) as f64;
    let (mut spread, mut diff, mut signed) = (0.0, 0.0, 0.0);
    for &i in &idx {
        let m = mean_of(i);
        spread += renders.iter().map(|r| (r[i].as_dvec3() - m).length_squared()).sum::<f64>();
        let d = m - reference[i].as_dvec3();
        diff += d.length_squared();
        signed += d.element_sum();
    }
    let noise2 = if s > 1 { spread / ((s - 1) as f64 * n) } else { 0.0 };
    let bias2 = (diff / n - noise2 / s.max(1) as f64 - reference_var).max(0.0);
    let measured = renders
        .iter()
        .map(|r| (idx.iter().map(|&i| (r[i] - reference[i]).as_dvec3().length_squared()).sum::<f64>() / n).sqrt())
        .sum::<f64>()
        / s.max(1) as f64;
    Split {
        error: (bias2 + noise2).sqrt() / denom,
        bias: bias2.sqrt() / denom,
        noise: noise2.sqrt() / denom,
        reference_noise: reference_var.sqrt() / denom,
        mean_bias: signed / n / denom,
        measured: measured / denom,
    }
}

/// Per-pixel relative error |image - reference| / mean(reference) (0 on pixels not
/// kept), for error maps.
pub fn error_map(image: &[Vec3], reference: &[Vec3], keep: &[bool]) -> Vec<f32> {
    let denom = kept_mean(reference, keep).max(1e-30) as f32;
    image
        .iter()
        .zip(reference)
        .zip(keep)
        .map(|((a, b), &k)| if k { (*a - *b).abs().element_sum() / 3.0 / denom } else { 0.0 })
        .collect()
}

/// How an image agrees with a reference over the kept pixels: the relative
/// difference of their means, and the worst relative difference of the means of
/// `n` x `n` blocks (what the differential checks judge a method by).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Agreement {
    /// mean(image) / mean(reference) - 1 over the kept pixels and channels (0
    /// when both are black).
    pub mean: f64,
    /// The largest |block mean of image / block mean of reference - 1| over the
    /// blocks that count: at least half their pixels kept and a reference mean of
    /// at least a tenth of the image's (darker blocks' relative errors are noise).
    pub worst_block: f64,
    /// That block's column and row.
    pub worst_at: (usize, usize),
    /// The root mean square of the same blocks' relative errors (0 when no block
    /// counts): what a viewer sees as blotches, where `worst_block` is one blotch.
    pub block_rms: f64,
}

impl std::fmt::Display for Agreement {
    /// "mean +1.23%, block RMS 4.56%, worst block 7.8% at (column, row)".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "mean {:+.2}%, block RMS {:.2}%, worst block {:.1}% at {:?}",
            100.0 * self.mean,
            100.0 * self.block_rms,
            100.0 * self.worst_block,
            self.worst_at
        )
    }
}

/// [`Agreement`] of `image` with `reference` (both `width` wide) over the pixels
/// `keep` selects, in blocks of `n` x `n` pixels.
pub fn agreement(image: &[Vec3], reference: &[Vec3], width: usize, keep: &[bool], n: usize) -> Agreement {
    let (mi, mr) = (kept_mean(image, keep), kept_mean(reference, keep));
    let mean = if mr > 0.0 {
        mi / mr - 1.0
    } else if mi > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    let (cols, height) = (width.div_ceil(n.max(1)), image.len() / width.max(1));
    let rows = height.div_ceil(n.max(1));
    // Per block: sums of the image and the reference over kept pixels, pixels kept, pixels.
    let mut blocks = vec![(0.0f64, 0.0f64, 0usize, 0usize); cols * rows];
    for i in 0..image.len().min(reference.len()).min(keep.len()) {
        let b = &mut blocks[(i / width / n) * cols + i % width / n];
        b.3 += 1;
        if keep[i] {
            b.0 += image[i].element_sum() as f64;
            b.1 += reference[i].element_sum() as f64;
            b.2 += 1;
        }
    }
    let mut worst = (0.0f64, (0, 0));
    let (mut squares, mut counted) = (0.0f64, 0usize);
    for (k, &(a, r, kept, all)) in blocks.iter().enumerate() {
        let reference_mean = r / (3 * kept.max(1)) as f64;
        if 2 * kept < all || kept == 0 || reference_mean < 0.1 * mr {
            continue;
        }
        let e = (a / r - 1.0).abs();
        if e > worst.0 || e.is_nan() {
            worst = (if e.is_nan() { f64::INFINITY } else { e }, (k % cols, k / cols));
        }
        squares += if e.is_nan() { f64::INFINITY } else { e * e };
        counted += 1;
    }
    let block_rms = if counted > 0 { (squares / counted as f64).sqrt() } else { 0.0 };
    Agreement { mean, worst_block: worst.0, worst_at: worst.1, block_rms }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic standard normal sequence (Box-Muller on a 64-bit LCG).
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn next(&mut self) -> f32 {
            let (u, v) = (self.uniform(), self.uniform());
            ((-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()) as f32
        }
    }

    /// A known answer: truth T (varying), renders T x (1 + 0.04) + noise of 0.1 x
    /// mean(T), a reference from two halves each with noise 0.05 x mean(T). The
    /// split recovers bias 4%, noise 10% and reference noise 0.05 / sqrt(2) = 3.5%,
    /// although the reference's noise is as large as the bias.
    #[test]
    fn split_recovers_a_known_bias_and_noise() {
        let n = 200 * 200;
        let mut g = Normal(7);
        let truth: Vec<Vec3> = (0..n).map(|i| Vec3::splat(0.5 + 0.5 * ((i % 200) as f32 / 200.0))).collect();
        let mean_t = 0.75f32;
        let half = |g: &mut Normal| -> Vec<Vec3> {
            truth.iter().map(|t| *t + Vec3::new(g.next(), g.next(), g.next()) * 0.05 * mean_t).collect()
        };
        let (a, b) = (half(&mut g), half(&mut g));
        let keep = vec![true; n];
        let (reference, var) = reference_from_halves(&a, &b, &keep);
        let renders: Vec<Vec<Vec3>> = (0..4)
            .map(|_| truth.iter().map(|t| *t * 1.04 + Vec3::new(g.next(), g.next(), g.next()) * 0.1 * mean_t).collect())
            .collect();
        let refs: Vec<&[Vec3]> = renders.iter().map(Vec::as_slice).collect();
        let s = split(&refs, &reference, var, &keep);
        // The bias field is 0.04 x T: its RMS over mean(T) is 0.04 x rms(T) / mean(T).
        let rms_t = (truth.iter().map(|t| t.x as f64 * t.x as f64).sum::<f64>() / n as f64).sqrt();
        let want_bias = 0.04 * rms_t / mean_t as f64;
        assert!((s.bias - want_bias).abs() < 0.1 * want_bias, "bias {} want {want_bias}", s.bias);
        assert!((s.noise - 0.1).abs() < 0.005, "noise {}", s.noise);
        assert!((s.reference_noise - 0.05 / 2f64.sqrt()).abs() < 0.002, "reference noise {}", s.reference_noise);
        assert!((s.mean_bias - 0.04).abs() < 0.003, "mean bias {}", s.mean_bias);
        // A single comparison would report the reference's noise as error too.
        assert!(s.measured > s.error, "{} vs {}", s.measured, s.error);
        // Without the split (reference noise ignored) the bias would read high.
        let naive = split(&refs, &reference, 0.0, &keep);
        assert!(naive.bias > 1.2 * want_bias, "{}", naive.bias);
    }

    /// The light's pixels and their neighbours are left out, nothing else.
    #[test]
    fn mask_leaves_out_the_light_and_its_rim() {
        let (w, h) = (8, 6);
        let mut img = vec![Vec3::splat(0.3); w * h];
        img[2 * w + 3] = Vec3::splat(50.0);
        let keep = keep_mask(&img, w, h, None);
        let out: Vec<usize> = (0..w * h).filter(|&i| !keep[i]).collect();
        assert_eq!(out, [w + 2, w + 3, w + 4, 2 * w + 2, 2 * w + 3, 2 * w + 4, 3 * w + 2, 3 * w + 3, 3 * w + 4]);
    }

    /// A known answer: an image 10% bright in one 8 x 8 block and 1% dark
    /// elsewhere; masked pixels and black blocks do not count.
    #[test]
    fn agreement_finds_the_mean_and_the_worst_block() {
        let (w, h) = (32usize, 16usize);
        let reference: Vec<Vec3> = (0..w * h).map(|i| Vec3::splat(1.0 + (i % 7) as f32)).collect();
        let mut image: Vec<Vec3> = reference.iter().map(|p| *p * 0.99).collect();
        for y in 8..16 {
            for x in 16..24 {
                image[y * w + x] = reference[y * w + x] * 1.1;
            }
        }
        let mut keep = vec![true; w * h];
        // A masked light's pixels, wildly off, do not count.
        keep[0] = false;
        image[0] = Vec3::splat(1e6);
        let a = agreement(&image, &reference, w, &keep, 8);
        assert_eq!(a.worst_at, (2, 1));
        assert!((a.worst_block - 0.1).abs() < 1e-5, "{a:?}");
        assert!(a.mean > -0.01 && a.mean < 0.02, "{a:?}");
        // Eight blocks: seven 1% dark, one 10% bright.
        assert!((a.block_rms - ((7.0 * 0.01f64.powi(2) + 0.1f64.powi(2)) / 8.0).sqrt()).abs() < 1e-5, "{a:?}");
        let same = agreement(&reference, &reference, w, &vec![true; w * h], 8);
        assert_eq!((same.mean, same.worst_block, same.block_rms), (0.0, 0.0, 0.0));
    }
}
