//! The training losses of SPEC §4 with their gradients.

use crate::float::sign;
/// Clamp of the accumulated weight inside the mask cross-entropy (SPEC §4).
pub const MASK_CLAMP: f32 = 1e-3;

/// The (ray, channel, error) triples the colour terms count: the channels
/// of the rays marked `counts` that are not saturated (SPEC §4: a channel
/// counts unless both the prediction and the observation are ≥ the ray's
/// cap, `caps[r]`), with error e = prediction − observation.
fn counted_channels<'a>(
    pred: &'a [[f32; 3]],
    target: &'a [[f32; 3]],
    counts: &'a [bool],
    caps: &'a [Option<f32>],
) -> impl Iterator<Item = (usize, usize, f32)> + 'a {
    pred.iter()
        .zip(target)
        .zip(counts.iter().zip(caps))
        .enumerate()
        .filter(|(_, (_, (c, _)))| **c)
        .flat_map(move |(r, ((p, t), (_, &cap)))| {
            (0..3)
                .filter(move |&ch| !saturated(p[ch], t[ch], cap))
                .map(move |ch| (r, ch, p[ch] - t[ch]))
        })
}

/// The L1 colour loss over the rays marked `counts`, excluding saturated
/// channels ([`counted_channels`]; `caps` holds each ray's saturation cap). Returns (loss, counted channels, MSE of
/// the counted channels) and writes ∂loss/∂pred · `weight` into `d_pred`.
pub fn colour_l1(
    pred: &[[f32; 3]],
    target: &[[f32; 3]],
    counts: &[bool],
    caps: &[Option<f32>],
    weight: f32,
    d_pred: &mut [[f32; 3]],
) -> (f64, usize, f64) {
    let mut n = 0usize;
    let (mut l1, mut l2) = (0.0f64, 0.0f64);
    for (_, _, e) in counted_channels(pred, target, counts, caps) {
        let e = e as f64;
        l1 += e.abs();
        l2 += e * e;
        n += 1;
    }
    let inv = if n > 0 { 1.0 / n as f64 } else { 0.0 };
    for d in d_pred.iter_mut() {
        *d = [0.0; 3];
    }
    for (r, ch, e) in counted_channels(pred, target, counts, caps) {
        d_pred[r][ch] = weight * sign(e) * inv as f32;
    }
    (l1 * inv, n, l2 * inv)
}

/// Whether a channel is left out of the colour loss (SPEC §4: both the
/// prediction and the observation are ≥ the cap).
#[inline]
fn saturated(pred: f32, obs: f32, cap: Option<f32>) -> bool {
    cap.is_some_and(|c| pred >= c && obs >= c)
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
        let caps = [Some(1.0), Some(1.0)];
        let (l, n, mse) = colour_l1(&pred, &target, &[true, false], &caps, 2.0, &mut d);
        // green: both ≥ cap → excluded; red and blue count.
        assert_eq!(n, 2);
        assert!((l - (0.25 + 0.2) / 2.0).abs() < 1e-6);
        assert!((mse - (0.0625 + 0.04) / 2.0).abs() < 1e-6);
        assert_eq!(d[0], [1.0, 0.0, -1.0]);
        assert_eq!(d[1], [0.0; 3]);
        // without a cap every channel of the counted ray counts
        let (l, n, _) = colour_l1(&pred, &target, &[true, false], &[None, None], 1.0, &mut d);
        assert_eq!(n, 3);
        assert!((l - (0.25 + 0.2 + 0.2) / 3.0).abs() < 1e-6);
    }

    #[test]
    fn each_ray_has_its_own_cap() {
        // Two rays, both counted, the same colours; the first image clips
        // at 1.0, the second (a brighter exposure scaled down) at 0.8.
        let pred = [[0.9, 1.1, 0.5], [0.9, 1.1, 0.5]];
        let target = [[0.8, 1.0, 0.4], [0.8, 1.0, 0.4]];
        let mut d = [[0.0; 3]; 2];
        let caps = [Some(1.0), Some(0.8)];
        let (_, n, _) = colour_l1(&pred, &target, &[true, true], &caps, 1.0, &mut d);
        // ray 0: green (1.1 and 1.0 ≥ 1.0) is left out; ray 1: red (0.9 and
        // 0.8 ≥ 0.8) and green are left out; blue counts in both.
        assert_eq!(n, 3);
        assert_eq!(d[0], [1.0 / 3.0, 0.0, 1.0 / 3.0]);
        assert_eq!(d[1], [0.0, 0.0, 1.0 / 3.0]);
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
