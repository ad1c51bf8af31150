//! The training losses of SPEC §4 with their gradients.

use crate::float::sign;
/// Clamp of the accumulated weight inside the mask cross-entropy (SPEC §4).
pub const MASK_CLAMP: f32 = 1e-3;

/// The (ray, channel, error) triples the colour terms count: the channels
/// of the rays marked `counts` that are not saturated (SPEC §4: a channel
/// counts unless both the prediction and the observation are ≥ the cap),
/// with error e = prediction − observation.
fn counted_channels<'a>(
    pred: &'a [[f32; 3]],
    target: &'a [[f32; 3]],
    counts: &'a [bool],
    cap: Option<f32>,
) -> impl Iterator<Item = (usize, usize, f32)> + 'a {
    pred.iter()
        .zip(target)
        .zip(counts)
        .enumerate()
        .filter(|(_, (_, c))| **c)
        .flat_map(move |(r, ((p, t), _))| {
            (0..3)
                .filter(move |&ch| !saturated(p[ch], t[ch], cap))
                .map(move |ch| (r, ch, p[ch] - t[ch]))
        })
}

/// The L1 colour loss over the rays marked `counts`, excluding saturated
/// channels ([`counted_channels`]). Returns (loss, counted channels, MSE of
/// the counted channels) and writes ∂loss/∂pred · `weight` into `d_pred`.
pub fn colour_l1(
    pred: &[[f32; 3]],
    target: &[[f32; 3]],
    counts: &[bool],
    cap: Option<f32>,
    weight: f32,
    d_pred: &mut [[f32; 3]],
) -> (f64, usize, f64) {
    let mut n = 0usize;
    let (mut l1, mut l2) = (0.0f64, 0.0f64);
    for (_, _, e) in counted_channels(pred, target, counts, cap) {
        let e = e as f64;
        l1 += e.abs();
        l2 += e * e;
        n += 1;
    }
    let inv = if n > 0 { 1.0 / n as f64 } else { 0.0 };
    for d in d_pred.iter_mut() {
        *d = [0.0; 3];
    }
    for (r, ch, e) in counted_channels(pred, target, counts, cap) {
        d_pred[r][ch] = weight * sign(e) * inv as f32;
    }
    (l1 * inv, n, l2 * inv)
}

/// The squared colour error over the same channels as [`colour_l1`]: the
/// mean of e² over the counted channels. ADDS ∂loss/∂pred · `weight` =
/// `weight` · 2e / n into `d_pred` and returns the (unweighted) mean.
///
/// SPEC §4's colour term is the L1 of [`colour_l1`]; L1 fits the median of
/// what the views say about a pixel, while the PSNR that scores novel views
/// is a mean squared error. Where the views disagree (a crease, a highlight's
/// tail, an outline) the two optima differ, and a share of L2 moves the fit
/// towards the mean (`loss.color_l2`, off by default).
pub fn add_colour_l2(
    pred: &[[f32; 3]],
    target: &[[f32; 3]],
    counts: &[bool],
    cap: Option<f32>,
    weight: f32,
    d_pred: &mut [[f32; 3]],
) -> f64 {
    let (mut n, mut sum) = (0usize, 0.0f64);
    for (_, _, e) in counted_channels(pred, target, counts, cap) {
        sum += (e as f64) * (e as f64);
        n += 1;
    }
    if n == 0 {
        return 0.0;
    }
    let scale = 2.0 * weight as f64 / n as f64;
    for (r, ch, e) in counted_channels(pred, target, counts, cap) {
        d_pred[r][ch] += (scale * e as f64) as f32;
    }
    sum / n as f64
}

/// Whether a channel is left out of the colour loss (SPEC §4: both the
/// prediction and the observation are ≥ the cap).
#[inline]
fn saturated(pred: f32, obs: f32, cap: Option<f32>) -> bool {
    cap.is_some_and(|c| pred >= c && obs >= c)
}

/// One ray's colour error under the rule of [`colour_l1`]: the summed
/// absolute error of its channels that are not saturated.
#[inline]
pub fn counted_l1(pred: [f32; 3], obs: [f32; 3], cap: Option<f32>) -> f32 {
    (0..3)
        .filter(|&c| !saturated(pred[c], obs[c], cap))
        .map(|c| (pred[c] - obs[c]).abs())
        .sum()
}

/// Mean binary cross-entropy between Σw (clamped to [1e-3, 1 − 1e-3]) and
/// the mask (SPEC §4); writes ∂loss/∂(Σw) · `weight` into `d_acc`.
pub fn mask_bce(acc: &[f32], mask: &[f32], weight: f32, d_acc: &mut [f32]) -> f64 {
    let n = acc.len().max(1) as f64;
    let mut loss = 0.0f64;
    for ((a, m), d) in acc.iter().zip(mask).zip(d_acc.iter_mut()) {
        let clamped = a.clamp(MASK_CLAMP, 1.0 - MASK_CLAMP);
        let (a64, m64) = (clamped as f64, *m as f64);
        loss -= m64 * a64.ln() + (1.0 - m64) * (1.0 - a64).ln();
        *d = if *a > MASK_CLAMP && *a < 1.0 - MASK_CLAMP {
            (weight as f64 * (-(m64 / a64) + (1.0 - m64) / (1.0 - a64)) / n) as f32
        } else {
            0.0
        };
    }
    loss / n
}

/// PSNR in dB for a mean squared error and a peak value.
pub fn psnr(mse: f64, peak: f64) -> f64 {
    if mse <= 0.0 {
        f64::INFINITY
    } else {
        10.0 * (peak * peak / mse).log10()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn l1_skips_saturated_channels_and_masked_rays() {
        let pred = [[0.5, 1.2, 0.9], [0.1, 0.1, 0.1]];
        let target = [[0.25, 1.0, 1.1], [9.0, 9.0, 9.0]];
        let mut d = [[0.0; 3]; 2];
        let (l, n, mse) = colour_l1(&pred, &target, &[true, false], Some(1.0), 2.0, &mut d);
        // green: both ≥ cap → excluded; red and blue count.
        assert_eq!(n, 2);
        assert!((l - (0.25 + 0.2) / 2.0).abs() < 1e-6);
        assert!((mse - (0.0625 + 0.04) / 2.0).abs() < 1e-6);
        assert_eq!(d[0], [1.0, 0.0, -1.0]);
        assert_eq!(d[1], [0.0; 3]);
        // the same rule for one ray's error: red and blue, not green
        assert!((counted_l1(pred[0], target[0], Some(1.0)) - 0.45).abs() < 1e-6);
        assert!((counted_l1(pred[0], target[0], None) - 0.65).abs() < 1e-6);
    }

    #[test]
    fn l2_adds_its_gradient_over_the_l1_channels() {
        // ray 0: green saturated on both sides (left out); ray 1 not counted.
        let pred = [[0.5, 1.2, 0.9], [0.1, 0.1, 0.1]];
        let target = [[0.25, 1.0, 1.1], [9.0, 9.0, 9.0]];
        let counts = [true, false];
        let mut d = [[1.0; 3]; 2];
        let mse = add_colour_l2(&pred, &target, &counts, Some(1.0), 3.0, &mut d);
        assert!((mse - (0.0625 + 0.04) / 2.0).abs() < 1e-7);
        // added to what was there: 1 + 3 · 2e / 2
        assert!((d[0][0] - (1.0 + 3.0 * 0.25)).abs() < 1e-6);
        assert_eq!(d[0][1], 1.0);
        assert!((d[0][2] - (1.0 - 3.0 * 0.2)).abs() < 1e-6);
        assert_eq!(d[1], [1.0; 3]);
        // central differences of weight · mean e² (f64 sums of f32 inputs)
        let h = 1e-3f32;
        for ch in [0, 2] {
            let (mut hi, mut lo) = (pred, pred);
            hi[0][ch] += h;
            lo[0][ch] -= h;
            let mut scratch = [[0.0f32; 3]; 2];
            let f = |p: &[[f32; 3]; 2], s: &mut [[f32; 3]; 2]| {
                3.0 * add_colour_l2(p, &target, &counts, Some(1.0), 0.0, s)
            };
            let fd = (f(&hi, &mut scratch) - f(&lo, &mut scratch)) / (2.0 * h as f64);
            let analytic = (d[0][ch] - 1.0) as f64;
            assert!((fd - analytic).abs() < 1e-4, "{ch}: {fd} vs {analytic}");
        }
        // nothing counted: zero, and no gradient
        let mut d = [[0.0; 3]; 2];
        assert_eq!(
            add_colour_l2(&pred, &target, &[false, false], None, 1.0, &mut d),
            0.0
        );
        assert_eq!(d, [[0.0; 3]; 2]);
    }

    #[test]
    fn bce_gradient_matches_finite_differences() {
        let acc = [0.3f32, 0.9, 0.5];
        let mask = [1.0f32, 0.0, 1.0];
        let mut d = [0.0f32; 3];
        mask_bce(&acc, &mask, 1.0, &mut d);
        for i in 0..3 {
            let h = 1e-3f32;
            let (mut hi, mut lo) = (acc, acc);
            hi[i] += h;
            lo[i] -= h;
            let mut scratch = [0.0f32; 3];
            let fd = (mask_bce(&hi, &mask, 1.0, &mut scratch)
                - mask_bce(&lo, &mask, 1.0, &mut scratch))
                / (2.0 * h as f64);
            assert!(
                (fd - d[i] as f64).abs() < 1e-3 * fd.abs().max(1.0),
                "{i}: {fd} vs {}",
                d[i]
            );
        }
    }

    #[test]
    fn psnr_of_known_error() {
        assert!((psnr(0.01, 1.0) - 20.0).abs() < 1e-12);
    }
}
