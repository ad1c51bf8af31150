//! NeuS opacity and volume-rendering weights (SPEC §2), forward and backward.
//!
//! For sample k of a ray with direction d, the SDF φ_k and its raw
//! (unnormalised) gradient ∇φ_k at the sample, and section length δ_k:
//!
//! ```text
//!   s      = exp(10·v)                                   (NeuS sharpness, v learned)
//!   q      = d·∇φ_k                                      (slope of φ along the ray)
//!   ĉ      = −[ relu(½ − ½q)·(1 − r) + relu(−q)·r ]       (cos annealing, r from 0 to 1)
//!   φ_k⁻   = φ_k − ĉ·δ_k/2,   φ_k⁺ = φ_k + ĉ·δ_k/2        (section start / end)
//!   alpha_k = clamp((Φ_s(φ_k⁻) − Φ_s(φ_k⁺) + 1e-5) / (Φ_s(φ_k⁻) + 1e-5), 0, 1)
//!   w_k    = alpha_k Π_{j<k} (1 − alpha_j)
//! ```
//!
//! with Φ_s(x) = sigmoid(s·x) (SPEC §2). As in NeuS, q uses the raw gradient
//! (the directional derivative of φ, which is the cosine when |∇φ| = 1), so
//! φ⁻ and φ⁺ are the first-order estimates of φ at the section ends.
//!
//! The backward pass takes ∂L/∂w_k (from [`mod@crate::composite`], which turns
//! ∂L/∂(colour), ∂L/∂(per-sample colour) and friends into it) and ∂L/∂(Σ_k w_k)
//! per ray, and produces ∂L/∂φ_k, ∂L/∂∇φ_k and ∂L/∂v. A background behind
//! the object is composited as `C += b·(1 − Σ w)`: pass −∂L/∂C·b as part of
//! ∂L/∂(Σ w).

use rayon::prelude::*;

use crate::packing::{ray_chunks, split_mut, validate_offsets};
use crate::real::dot3;
use wildlight_real::Real;

/// The ε of the NeuS alpha (SPEC §2).
pub const ALPHA_EPS: f64 = 1e-5;
/// Smallest sharpness s (NeuS clips 1/s to [1e-6, 1e6]).
pub const SHARPNESS_MIN: f64 = 1e-6;
/// Largest sharpness s.
pub const SHARPNESS_MAX: f64 = 1e6;
/// The initial value of the sharpness parameter v (NeuS; s = exp(3) ≈ 20).
pub const V_INIT: f64 = 0.3;

/// The sharpness s = exp(10·v) (SPEC §2, NeuS) and ds/dv; clamped to
/// [[`SHARPNESS_MIN`], [`SHARPNESS_MAX`]] with a zero derivative outside.
#[inline]
pub fn sharpness<T: Real>(v: T) -> (T, T) {
    let s = (T::from_f64(10.0) * v).exp();
    if s < T::from_f64(SHARPNESS_MIN) {
        (T::from_f64(SHARPNESS_MIN), T::from_f64(0.0))
    } else if s > T::from_f64(SHARPNESS_MAX) {
        (T::from_f64(SHARPNESS_MAX), T::from_f64(0.0))
    } else {
        (s, T::from_f64(10.0) * s)
    }
}

/// The NeuS cos-annealing ratio at training step `step`: rises linearly from
/// 0 to 1 over the first `anneal_end` steps (1 from the start if 0).
pub fn cos_anneal_ratio(step: u64, anneal_end: u64) -> f64 {
    if anneal_end == 0 {
        1.0
    } else {
        (step as f64 / anneal_end as f64).min(1.0)
    }
}

/// Settings of the NeuS weights that are not learned.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeusSettings {
    /// The cos-annealing ratio r ∈ [0, 1] (see [`cos_anneal_ratio`]).
    pub cos_anneal_ratio: f64,
    /// The ε of the alpha formula ([`ALPHA_EPS`] = 1e-5 per SPEC §2).
    ///
    /// Far from the surface Φ_s(φ⁻) ≈ Φ_s(φ⁺) ≈ 1 and alpha ≈ ε: every
    /// sample adds about ε of opacity, so Σw depends on the sample count
    /// (n·ε; 0.06 for 6000 dense samples, ≤ 1e-3 for the fast sampler).
    /// Comparisons between samplers set it to 0 to see the sampling error alone.
    pub alpha_eps: f64,
}

impl Default for NeusSettings {
    fn default() -> Self {
        Self {
            cos_anneal_ratio: 1.0,
            alpha_eps: ALPHA_EPS,
        }
    }
}

/// The per-sample inputs of the NeuS weights, packed as in [`crate::packing`].
#[derive(Clone, Copy, Debug)]
pub struct NeusInputs<'a, T> {
    /// Ray offsets into the per-sample arrays (rays + 1 entries).
    pub offsets: &'a [u32],
    /// Unit direction of each ray.
    pub ray_dirs: &'a [[T; 3]],
    /// SDF φ at each sample.
    pub sdf: &'a [T],
    /// Raw SDF gradient ∇φ at each sample.
    pub sdf_grad: &'a [[T; 3]],
    /// Length δ of each sample's section.
    pub delta: &'a [T],
}

impl<T> NeusInputs<'_, T> {
    /// Whether the array lengths agree with each other and with the offsets.
    pub fn is_consistent(&self) -> bool {
        let n = self.sdf.len();
        validate_offsets(self.offsets, n)
            && self.ray_dirs.len() + 1 == self.offsets.len()
            && self.sdf_grad.len() == n
            && self.delta.len() == n
    }
}

/// Alpha of one sample and its partial derivatives (zero where clamped).
#[derive(Clone, Copy, Debug)]
struct AlphaPartials<T> {
    /// The value (the passes use [`alpha_value`]; tests compare the two).
    #[cfg_attr(not(test), allow(dead_code))]
    alpha: T,
    d_sdf: T,
    d_slope: T,
    d_s: T,
}

/// σ(x) and σ'(x) = σ(x)·σ(−x), with one exponential and no cancellation.
#[inline(always)]
fn sigmoid_with_derivative<T: Real>(x: T) -> (T, T) {
    let one = T::from_f64(1.0);
    let e = (-x.abs()).exp();
    let inv = one / (one + e);
    let sig = if x >= T::from_f64(0.0) { inv } else { e * inv };
    (sig, e * inv * inv)
}

/// The NeuS alpha of one sample (module docs; SPEC §2) from φ, the slope
/// q = d·∇φ, δ, s and the cos-annealing ratio r.
#[inline(always)]
fn alpha_partials<T: Real>(sdf: T, slope: T, delta: T, s: T, r: T, eps: T) -> AlphaPartials<T> {
    let zero = T::from_f64(0.0);
    let one = T::from_f64(1.0);
    let half = T::from_f64(0.5);
    // Cos annealing (NeuS): ĉ = −(relu(½ − ½q)(1 − r) + relu(−q) r) ≤ 0.
    let a = (half - half * slope).max(zero);
    let b = (-slope).max(zero);
    let iter_cos = -(a * (one - r) + b * r);
    let mut dcos_dslope = zero;
    if slope < one {
        dcos_dslope += half * (one - r);
    }
    if slope < zero {
        dcos_dslope += r;
    }
    // Section start and end estimates.
    let prev = sdf - iter_cos * delta * half;
    let next = sdf + iter_cos * delta * half;
    let (p, dp) = sigmoid_with_derivative(s * prev);
    let (n, dn) = sigmoid_with_derivative(s * next);
    let denom = p + eps;
    if denom == zero {
        // Only with ε = 0, deep inside: the limit of 1 − N/P is 1 (opaque).
        return AlphaPartials {
            alpha: one,
            d_sdf: zero,
            d_slope: zero,
            d_s: zero,
        };
    }
    let raw = (p - n + eps) / denom;
    if raw < zero || raw > one {
        // Clamped: zero derivative, as the clamped function has. (A NaN
        // falls through both tests and propagates.)
        return AlphaPartials {
            alpha: if raw < zero { zero } else { one },
            d_sdf: zero,
            d_slope: zero,
            d_s: zero,
        };
    }
    // raw = 1 − N/(P + ε)
    let da_dp = n / ((p + eps) * (p + eps));
    let da_dn = -one / (p + eps);
    let g_prev = da_dp * dp; // ∂α/∂(s·prev)
    let g_next = da_dn * dn; // ∂α/∂(s·next)
    let d_sdf = (g_prev + g_next) * s;
    let d_cos = (g_next - g_prev) * s * delta * half;
    AlphaPartials {
        alpha: raw,
        d_sdf,
        d_slope: d_cos * dcos_dslope,
        d_s: g_prev * prev + g_next * next,
    }
}

/// The NeuS alpha of one sample without derivatives (same formula as
/// [`alpha_partials`]; the forward pass uses this one).
#[inline(always)]
fn alpha_value<T: Real>(sdf: T, slope: T, delta: T, s: T, r: T, eps: T) -> T {
    let zero = T::from_f64(0.0);
    let one = T::from_f64(1.0);
    let half = T::from_f64(0.5);
    let iter_cos = -((half - half * slope).max(zero) * (one - r) + (-slope).max(zero) * r);
    let p = sigmoid_with_derivative(s * (sdf - iter_cos * delta * half)).0;
    let n = sigmoid_with_derivative(s * (sdf + iter_cos * delta * half)).0;
    let denom = p + eps;
    if denom == zero {
        return one;
    }
    let raw = (p - n + eps) / denom;
    if raw < zero {
        zero
    } else if raw > one {
        one
    } else {
        raw
    }
}

/// NeuS alphas and weights of a batch of rays, kept for the backward pass.
#[derive(Clone, Debug, Default)]
pub struct NeusWeights<T> {
    /// alpha_k per sample.
    pub alpha: Vec<T>,
    /// w_k per sample.
    pub weight: Vec<T>,
    /// Π_{j<k} (1 − alpha_j) per sample (transmittance before the sample).
    pub transmittance: Vec<T>,
    /// Σ_k w_k per ray (accumulated weight, 1 − final transmittance).
    pub acc_weight: Vec<T>,
}

impl<T: Real> NeusWeights<T> {
    /// Empty buffers (they grow on the first [`Self::forward`] and are reused).
    pub fn new() -> Self {
        Self {
            alpha: Vec::new(),
            weight: Vec::new(),
            transmittance: Vec::new(),
            acc_weight: Vec::new(),
        }
    }

    /// Computes alphas, weights, transmittances and accumulated weights
    /// (SPEC §2) for sharpness parameter `v` (s = exp(10·v)).
    ///
    /// # Panics
    /// If the input arrays are inconsistent ([`NeusInputs::is_consistent`]).
    pub fn forward(&mut self, inputs: &NeusInputs<'_, T>, v: T, settings: &NeusSettings) {
        assert!(
            inputs.is_consistent(),
            "NeusWeights::forward: inconsistent inputs"
        );
        let n = inputs.sdf.len();
        let n_rays = inputs.ray_dirs.len();
        let zero = T::from_f64(0.0);
        self.alpha.clear();
        self.alpha.resize(n, zero);
        self.weight.clear();
        self.weight.resize(n, zero);
        self.transmittance.clear();
        self.transmittance.resize(n, zero);
        self.acc_weight.clear();
        self.acc_weight.resize(n_rays, zero);
        let (s, _) = sharpness(v);
        let r = T::from_f64(settings.cos_anneal_ratio);
        let eps = T::from_f64(settings.alpha_eps);
        let chunks = ray_chunks(inputs.offsets);
        let alpha = split_mut(&mut self.alpha, chunks.iter().map(|c| c.samples.clone()));
        let weight = split_mut(&mut self.weight, chunks.iter().map(|c| c.samples.clone()));
        let trans = split_mut(
            &mut self.transmittance,
            chunks.iter().map(|c| c.samples.clone()),
        );
        let acc = split_mut(&mut self.acc_weight, chunks.iter().map(|c| c.rays.clone()));
        chunks
            .par_iter()
            .zip(alpha)
            .zip(weight)
            .zip(trans)
            .zip(acc)
            .for_each(|((((chunk, alpha), weight), trans), acc)| {
                let base = chunk.samples.start;
                for (ri, ray) in chunk.rays.clone().enumerate() {
                    let dir = inputs.ray_dirs[ray];
                    let mut t = T::from_f64(1.0);
                    let range = inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize;
                    for k in range {
                        let slope = dot3(dir, inputs.sdf_grad[k]);
                        let a = alpha_value(inputs.sdf[k], slope, inputs.delta[k], s, r, eps);
                        let l = k - base;
                        alpha[l] = a;
                        weight[l] = t * a;
                        trans[l] = t;
                        t *= T::from_f64(1.0) - a;
                    }
                    acc[ri] = T::from_f64(1.0) - t;
                }
            });
    }

    /// Backward pass of [`Self::forward`] (same inputs, `v` and settings).
    ///
    /// `d_weight` is ∂L/∂w_k per sample, `d_acc_weight` (optional) ∂L/∂(Σ w)
    /// per ray. ADDS ∂L/∂φ_k into `d_sdf` and ∂L/∂∇φ_k into `d_sdf_grad`,
    /// and returns ∂L/∂v.
    ///
    /// # Panics
    /// If array lengths disagree with the forward pass.
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &self,
        inputs: &NeusInputs<'_, T>,
        v: T,
        settings: &NeusSettings,
        d_weight: &[T],
        d_acc_weight: Option<&[T]>,
        d_sdf: &mut [T],
        d_sdf_grad: &mut [[T; 3]],
    ) -> T {
        let n = inputs.sdf.len();
        assert!(
            inputs.is_consistent(),
            "NeusWeights::backward: inconsistent inputs"
        );
        assert_eq!(
            self.alpha.len(),
            n,
            "NeusWeights::backward: forward not run"
        );
        assert_eq!(d_weight.len(), n);
        assert_eq!(d_sdf.len(), n);
        assert_eq!(d_sdf_grad.len(), n);
        if let Some(d) = d_acc_weight {
            assert_eq!(d.len(), inputs.ray_dirs.len());
        }
        let (s, ds_dv) = sharpness(v);
        let r = T::from_f64(settings.cos_anneal_ratio);
        let eps = T::from_f64(settings.alpha_eps);
        let chunks = ray_chunks(inputs.offsets);
        let d_sdf = split_mut(d_sdf, chunks.iter().map(|c| c.samples.clone()));
        let d_grad = split_mut(d_sdf_grad, chunks.iter().map(|c| c.samples.clone()));
        let d_s_chunks: Vec<T> = chunks
            .par_iter()
            .zip(d_sdf)
            .zip(d_grad)
            .map(|((chunk, d_sdf), d_grad)| {
                let base = chunk.samples.start;
                let mut d_s = T::from_f64(0.0);
                for ray in chunk.rays.clone() {
                    let dir = inputs.ray_dirs[ray];
                    let g_acc = d_acc_weight.map_or(T::from_f64(0.0), |d| d[ray]);
                    let range = inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize;
                    // R_k = Σ_{i>k} alpha_i Π_{k<j<i}(1 − alpha_j) g_i, so that
                    // ∂L/∂alpha_k = T_k (g_k − R_k) without dividing by 1 − alpha_k.
                    let mut rest = T::from_f64(0.0);
                    for k in range.rev() {
                        let g = d_weight[k] + g_acc;
                        let a = self.alpha[k];
                        let d_alpha = self.transmittance[k] * (g - rest);
                        rest = a * g + (T::from_f64(1.0) - a) * rest;
                        let slope = dot3(dir, inputs.sdf_grad[k]);
                        let p = alpha_partials(inputs.sdf[k], slope, inputs.delta[k], s, r, eps);
                        let l = k - base;
                        d_sdf[l] += d_alpha * p.d_sdf;
                        let d_slope = d_alpha * p.d_slope;
                        for (dg, &di) in d_grad[l].iter_mut().zip(&dir) {
                            *dg += d_slope * di;
                        }
                        d_s += d_alpha * p.d_s;
                    }
                }
                d_s
            })
            .collect();
        let mut d_s = T::from_f64(0.0);
        for x in d_s_chunks {
            d_s += x;
        }
        d_s * ds_dv
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_only_alpha_equals_alpha_of_the_partials() {
        let mut next = crate::test_uniform(0x2545_f491_4f6c_dd1d);
        for i in 0..2000 {
            let sdf = next() * 0.6 - 0.3;
            let slope = next() * 3.0 - 1.5;
            let delta = next() * 0.05;
            let s = (next() * 9.0).exp();
            let r = next();
            let eps = if i % 2 == 0 { ALPHA_EPS } else { 0.0 };
            let a = alpha_value(sdf, slope, delta, s, r, eps);
            let b = alpha_partials(sdf, slope, delta, s, r, eps).alpha;
            assert_eq!(a.to_bits(), b.to_bits(), "{sdf} {slope} {delta} {s} {r}");
            assert!((0.0..=1.0).contains(&a));
        }
        // Deep inside with ε = 0: opaque.
        assert_eq!(alpha_value(-1.0f64, -1.0, 0.01, 1e6, 1.0, 0.0), 1.0);
        // Far outside: alpha ≈ ε.
        let far = alpha_value(1.0f64, -1.0, 0.01, 1e3, 1.0, ALPHA_EPS);
        assert!((far - ALPHA_EPS).abs() < 1e-9);
    }

    #[test]
    fn sharpness_is_exp_of_ten_v_and_clamped() {
        let (s, ds) = sharpness(V_INIT);
        assert!((s - 3f64.exp()).abs() < 1e-12 && (ds - 10.0 * s).abs() < 1e-9);
        assert_eq!(sharpness(10.0f64), (SHARPNESS_MAX, 0.0));
        assert_eq!(cos_anneal_ratio(500, 1000), 0.5);
        assert_eq!(cos_anneal_ratio(5000, 1000), 1.0);
        assert_eq!(cos_anneal_ratio(0, 0), 1.0);
    }
}
