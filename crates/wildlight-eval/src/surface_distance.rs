//! The surface-to-surface distance of SPEC §7 (appendix eq. 16).
//!
//! D(S₁, S₂) = ½ E[ d(x₁, S₂) + d(x₂, S₁) ], with x₁ and x₂ independent and
//! uniform by area on S₁ and S₂ and d the distance from a point to the
//! nearest point of the other surface. Each *pair* contributes the value
//! vⱼ = ½ (d(x₁ⱼ, S₂) + d(x₂ⱼ, S₁)); the estimate of D is the mean of the
//! vⱼ, the median variant their sample median. Pairs are drawn in batches
//! until the standard deviation of the sample mean, s/√n with s the sample
//! standard deviation of the vⱼ, is at most 1e-5, or one million pairs
//! have been drawn.

use crate::EvalError;
use crate::surface_sampler::SampledSurface;
use rand::SeedableRng;
use rayon::prelude::*;
use serde::Serialize;
use wildlight_mesh::TriMesh;

/// Settings of the adaptive estimate of eq. 16.
#[derive(Clone, Debug)]
pub struct SurfaceDistanceOptions {
    /// Seed of the sampler (PCG64); the result depends only on it, not on
    /// the number of threads.
    pub seed: u64,
    /// Pairs drawn per batch; the stopping rule is checked after each batch.
    pub batch_pairs: usize,
    /// Stop once the standard deviation of the mean is at most this.
    pub target_std_of_mean: f64,
    /// Stop once this many pairs have been drawn.
    pub max_pairs: usize,
}

impl Default for SurfaceDistanceOptions {
    /// SPEC §7: σ of the mean ≤ 1e-5 or one million pairs, in batches of 10 000.
    fn default() -> Self {
        SurfaceDistanceOptions {
            seed: 0,
            batch_pairs: 10_000,
            target_std_of_mean: 1e-5,
            max_pairs: 1_000_000,
        }
    }
}

/// The result of eq. 16, in the meshes' own units.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SurfaceDistance {
    /// Mean of the pair values: the estimate of D(S₁, S₂).
    pub mean: f64,
    /// Sample median of the pair values.
    pub median: f64,
    /// Number of pairs drawn.
    pub pairs: usize,
    /// Standard deviation of the mean (sample std of the pair values / √pairs).
    pub std_of_mean: f64,
    /// Mean of d(x₁, S₂): how far the first (predicted) surface is from the
    /// second (accuracy).
    pub mean_pred_to_gt: f64,
    /// Mean of d(x₂, S₁): how far the second (ground-truth) surface is from
    /// the first (completeness).
    pub mean_gt_to_pred: f64,
    /// Area of the first surface (after any visibility restriction).
    pub area_pred: f64,
    /// Area of the second surface (after any visibility restriction).
    pub area_gt: f64,
}

/// Estimates D(S₁, S₂) of appendix eq. 16 for `pred` = S₁ and `gt` = S₂.
pub fn surface_distance(
    pred: &TriMesh,
    gt: &TriMesh,
    options: &SurfaceDistanceOptions,
) -> Result<SurfaceDistance, EvalError> {
    let s1 = SampledSurface::new(pred, "predicted mesh")?;
    let s2 = SampledSurface::new(gt, "ground-truth mesh")?;
    Ok(surface_distance_prepared(&s1, &s2, options))
}

/// [`surface_distance`] on surfaces already prepared for sampling.
pub fn surface_distance_prepared(
    s1: &SampledSurface,
    s2: &SampledSurface,
    options: &SurfaceDistanceOptions,
) -> SurfaceDistance {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(options.seed);
    let batch = options.batch_pairs.max(2);
    let mut one_sided: Vec<(f64, f64)> = Vec::new();
    let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
    let (mut std_of_mean, mut n) = (f64::INFINITY, 0usize);
    while n < options.max_pairs.max(2) {
        let count = batch.min(options.max_pairs.max(2) - n);
        // Points are drawn sequentially (deterministic), distances in parallel.
        let points: Vec<_> = (0..count)
            .map(|_| (s1.sample(&mut rng), s2.sample(&mut rng)))
            .collect();
        let distances: Vec<(f64, f64)> = points
            .par_iter()
            .map(|&(x1, x2)| (s2.distance(x1), s1.distance(x2)))
            .collect();
        for &(d1, d2) in &distances {
            // appendix eq. 16: one pair's value ½ (d(x₁, S₂) + d(x₂, S₁)).
            let v = 0.5 * (d1 + d2);
            sum += v;
            sum_sq += v * v;
        }
        one_sided.extend(distances);
        n += count;
        let mean = sum / n as f64;
        let variance = ((sum_sq - n as f64 * mean * mean) / (n as f64 - 1.0)).max(0.0);
        std_of_mean = (variance / n as f64).sqrt();
        if std_of_mean <= options.target_std_of_mean {
            break;
        }
    }
    let mut values: Vec<f64> = one_sided.iter().map(|(a, b)| 0.5 * (a + b)).collect();
    let mean = values.iter().sum::<f64>() / n as f64;
    SurfaceDistance {
        mean,
        median: median(&mut values),
        pairs: n,
        std_of_mean,
        mean_pred_to_gt: one_sided.iter().map(|p| p.0).sum::<f64>() / n as f64,
        mean_gt_to_pred: one_sided.iter().map(|p| p.1).sum::<f64>() / n as f64,
        area_pred: s1.area(),
        area_gt: s2.area(),
    }
}

/// The sample median: the middle value of the sorted values, or the mean of
/// the two middle values for an even count. NaN for no values. Reorders
/// `values`.
pub fn median(values: &mut [f64]) -> f64 {
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    let (_, upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *upper;
    if n % 2 == 1 {
        return upper;
    }
    let lower = values[..n / 2]
        .iter()
        .copied()
        .max_by(f64::total_cmp)
        .unwrap_or(upper);
    0.5 * (lower + upper)
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut [5.0]), 5.0);
        assert!(median(&mut []).is_nan());
    }

    #[test]
    fn median_of_an_exponential_sample_is_ln2() {
        // Inverse-CDF samples of Exp(1) on a fine stratified grid: the
        // median of the distribution is ln 2.
        let n = 100_001;
        let mut v: Vec<f64> = (0..n)
            .map(|i| -(1.0 - (i as f64 + 0.5) / n as f64).ln())
            .collect();
        v.reverse();
        assert!((median(&mut v) - std::f64::consts::LN_2).abs() < 1e-9);
    }
}
