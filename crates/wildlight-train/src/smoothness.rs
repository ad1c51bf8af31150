//! A smoothness prior on the material field: real objects are made of few
//! materials, so Θ should change little between nearby surface points.
//!
//! For pairs of points (x_j, x_j + ε_j), with x_j on the surface (the
//! expected hit point of a foreground ray) and ε_j a small random offset,
//!
//! L_smooth = λ · (1/m) Σ_j Σ_i w_i δ_i(Θ_i(x_j), Θ_i(x_j + ε_j)),
//!
//! an L1-type penalty, so that sharp boundaries between materials cost no
//! more than their length while noise inside one material is pushed out.
//! For the parameters that scale the flash term (base colour, dielectric
//! specular, clearcoat: scaling all of them by k and the gain γ by 1/k
//! renders the same photos) the difference is relative, δ = |a − b| /
//! (a + b + 0.01), so the prior cannot lower itself by darkening the
//! object and raising γ; for the others (roughness, metallic, clearcoat
//! gloss, subsurface) it is absolute, δ = |a − b|. The factors w_i
//! (`loss.smoothness_factors`, 1 by default) weigh the parameters against
//! each other. With `loss.smoothness_relative = "batch"` the relative
//! difference divides by the mean of a + b over the whole batch instead of
//! the pair's own ([`RelativeDifference`]). With a saturation scale c > 0
//! (`loss.smoothness_saturation`, for the parameters named in
//! `loss.smoothness_saturated_parameters`) each difference enters as
//! ψ(δ) = c · ln(1 + δ/c) instead of δ: the same as L1 for differences well
//! below c, with a push ψ'(δ) = c / (c + δ) that fades across a boundary
//! between two materials (δ ≫ c), so that a thin part is not pulled
//! towards the parts beside it. Only the material field
//! receives the gradient (the points are held fixed). The prior is the
//! project's addition: SPEC §4 has no such term. Its weight
//! `loss.material_smoothness` defaults to 0.1; 0 turns it off.

use crate::float::{Float, of, sign, to_f64};
use crate::material_field::{MaterialContext, MaterialField, MaterialGrads};
use serde::{Deserialize, Serialize};
use wildlight_material::{BASE_COLOR, CLEARCOAT, DIELECTRIC, PARAM_COUNT};

/// Floor of the denominator of the relative difference.
const RELATIVE_FLOOR: f64 = 0.01;

/// Whether parameter `i` scales the flash term (compared relatively).
fn scales_the_flash(i: usize) -> bool {
    (BASE_COLOR..BASE_COLOR + 3).contains(&i) || i == DIELECTRIC || i == CLEARCOAT
}

/// δ(a, b) of parameter `i` and its derivatives (∂δ/∂a, ∂δ/∂b).
#[inline]
pub fn pair_difference<T: Float>(i: usize, a: T, b: T) -> (T, T, T) {
    let d = a - b;
    let sign = sign(d);
    let abs = sign * d;
    if scales_the_flash(i) {
        // δ = |a − b| / s, s = a + b + floor: ∂δ/∂a = sign/s − δ/s,
        // ∂δ/∂b = −sign/s − δ/s.
        let s = a + b + of::<T>(RELATIVE_FLOOR);
        let delta = abs / s;
        (delta, (sign - delta) / s, (-sign - delta) / s)
    } else {
        (abs, sign, -sign)
    }
}

/// Fills `points` with the pairs' first points, then their second points
/// (centre + offset); returns the number of pairs m.
pub(crate) fn pair_points<T: Float>(
    centres: &[[T; 3]],
    offsets: &[[T; 3]],
    points: &mut Vec<[T; 3]>,
) -> usize {
    let m = centres.len().min(offsets.len());
    points.clear();
    points.extend_from_slice(&centres[..m]);
    points.extend(
        centres[..m]
            .iter()
            .zip(offsets)
            .map(|(c, e)| [c[0] + e[0], c[1] + e[1], c[2] + e[2]]),
    );
    m
}

/// How the flash-scaling parameters' differences are made relative.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RelativeDifference {
    /// δ = |a − b| / (a + b + 0.01), pair by pair: the darker side of a
    /// boundary gets the larger push, so bright materials bleed into dark
    /// ones.
    #[default]
    Pair,
    /// δ = |a − b| / (M + 0.01) with M the mean of a + b over all pairs
    /// (differentiated too): both sides of a boundary get the same push.
    Batch,
}

/// The weights of the prior.
#[derive(Clone, Copy, Debug)]
pub struct SmoothnessSettings<T> {
    /// λ.
    pub weight: T,
    /// The per-parameter factors w_i, in Θ's order.
    pub factors: [T; PARAM_COUNT],
    /// How δ is relative for base colour, dielectric and clearcoat.
    pub relative: RelativeDifference,
    /// Per parameter, in Θ's order, the saturation scale c of
    /// ψ(δ) = c · ln(1 + δ/c); 0 keeps δ (L1).
    pub saturation: [T; PARAM_COUNT],
}

/// ψ(δ) = c · ln(1 + δ/c) in f64, for c > 0.
fn saturated_value(delta: f64, c: f64) -> f64 {
    c * (delta / c).ln_1p()
}

/// ψ'(δ) = c / (c + δ) (1 for c = 0).
#[inline]
fn saturated_slope<T: Float>(delta: T, c: T) -> T {
    if c > T::ZERO { c / (c + delta) } else { T::ONE }
}

impl<T: Float> SmoothnessSettings<T> {
    /// Weight λ, every factor 1, pairwise relative differences.
    pub fn uniform(weight: T) -> Self {
        Self {
            weight,
            factors: [T::ONE; PARAM_COUNT],
            relative: RelativeDifference::Pair,
            saturation: [T::ZERO; PARAM_COUNT],
        }
    }
}

/// Buffers of the smoothness term between calls.
#[derive(Default)]
pub struct MaterialSmoothness<T> {
    points: Vec<[T; 3]>,
    ctx: MaterialContext<T>,
    d_out: Vec<T>,
}

impl<T: Float + Default> MaterialSmoothness<T> {
    /// Evaluates λ · L_smooth for the pairs (centres[j], centres[j] +
    /// offsets[j]) with the weight, factors and kind of relative difference
    /// of `settings`, and ADDS its gradient with respect to the field's
    /// parameters into `grads`. Returns the mean Σ_i w_i δ_i (without λ).
    pub fn forward_backward(
        &mut self,
        field: &MaterialField<T>,
        centres: &[[T; 3]],
        offsets: &[[T; 3]],
        settings: &SmoothnessSettings<T>,
        grads: &mut MaterialGrads<T>,
    ) -> f64 {
        let m = pair_points(centres, offsets, &mut self.points);
        if m == 0 {
            return 0.0;
        }
        field.forward(&self.points, &mut self.ctx);
        let k = PARAM_COUNT;
        let out = self.ctx.output();
        let (near, far) = out.split_at(m * k);
        let scale = settings.weight / of(m as f64);
        let factors = &settings.factors;
        let saturation = &settings.saturation;
        self.d_out.clear();
        self.d_out.resize(2 * m * k, T::ZERO);
        let (d_near, d_far) = self.d_out.split_at_mut(m * k);
        let sum = match settings.relative {
            RelativeDifference::Pair => {
                let mut sum = 0.0f64;
                for (j, (((a, b), da), db)) in
                    near.iter().zip(far).zip(d_near).zip(d_far).enumerate()
                {
                    let i = j % PARAM_COUNT;
                    let (delta, d_a, d_b) = pair_difference(i, *a, *b);
                    let (w, c) = (factors[i], saturation[i]);
                    sum += if c > T::ZERO {
                        to_f64(w) * saturated_value(to_f64(delta), to_f64(c))
                    } else {
                        to_f64(w * delta)
                    };
                    let slope = saturated_slope(delta, c);
                    *da = scale * w * slope * d_a;
                    *db = scale * w * slope * d_b;
                }
                sum
            }
            RelativeDifference::Batch => {
                // Per parameter: D_i = Σ_j ψ(|a − b|) and M_i = (1/m) Σ_j
                // (a + b); L_i = D_i / (M_i + floor) for the flash-scaling
                // ones (D_i otherwise), so ∂L_i/∂a_j = ψ'_j sign_j / s_i −
                // D_i / (m s_i²).
                let mut diff = [T::ZERO; PARAM_COUNT];
                let mut mean = [T::ZERO; PARAM_COUNT];
                for (j, (a, b)) in near.iter().zip(far).enumerate() {
                    let abs = sign(*a - *b) * (*a - *b);
                    let c = saturation[j % PARAM_COUNT];
                    diff[j % PARAM_COUNT] += if c > T::ZERO {
                        of::<T>(saturated_value(to_f64(abs), to_f64(c)))
                    } else {
                        abs
                    };
                    mean[j % PARAM_COUNT] += *a + *b;
                }
                let mf = of::<T>(m as f64);
                let denom: [T; PARAM_COUNT] = std::array::from_fn(|i| {
                    if scales_the_flash(i) {
                        mean[i] / mf + of::<T>(RELATIVE_FLOOR)
                    } else {
                        T::ONE
                    }
                });
                let shared: [T; PARAM_COUNT] = std::array::from_fn(|i| {
                    if scales_the_flash(i) {
                        diff[i] / (mf * denom[i] * denom[i])
                    } else {
                        T::ZERO
                    }
                });
                for (j, (((a, b), da), db)) in
                    near.iter().zip(far).zip(d_near).zip(d_far).enumerate()
                {
                    let i = j % PARAM_COUNT;
                    let d = *a - *b;
                    let sign = sign(d) * saturated_slope(sign(d) * d, saturation[i]);
                    let w = factors[i];
                    *da = scale * w * (sign / denom[i] - shared[i]);
                    *db = scale * w * (-sign / denom[i] - shared[i]);
                }
                (0..PARAM_COUNT)
                    .map(|i| to_f64(factors[i] * diff[i] / denom[i]))
                    .sum::<f64>()
            }
        };
        field.backward(&mut self.ctx, &self.d_out, grads);
        sum / m as f64
    }
}
