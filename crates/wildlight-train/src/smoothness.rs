//! A smoothness prior on the material field: real objects are made of few
//! materials, so Θ should change little between nearby surface points.
//!
//! For pairs of points (x_j, x_j + ε_j), with x_j on the surface (the
//! expected hit point of a foreground ray) and ε_j a small random offset,
//!
//! L_smooth = λ · (1/m) Σ_j Σ_i δ_i(Θ_i(x_j), Θ_i(x_j + ε_j)),
//!
//! an L1-type penalty, so that sharp boundaries between materials cost no
//! more than their length while noise inside one material is pushed out.
//! For the parameters that scale the flash term (base colour, dielectric
//! specular, clearcoat: scaling all of them by k and the gain γ by 1/k
//! renders the same photos) the difference is relative, δ = |a − b| /
//! (a + b + 0.01), so the prior cannot lower itself by darkening the
//! object and raising γ; for the others (roughness, metallic, clearcoat
//! gloss, subsurface) it is absolute, δ = |a − b|. Only the material field
//! receives the gradient (the points are held fixed). The prior is the
//! project's addition: SPEC §4 has no such term. Its weight
//! `loss.material_smoothness` defaults to 0.1; 0 turns it off.

use crate::float::{Float, of, sign, to_f64};
use wildlight_fields::{FieldContext, FieldGrads, NeuralField};
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

/// Buffers of the smoothness term between calls.
#[derive(Default)]
pub struct MaterialSmoothness<T> {
    points: Vec<[T; 3]>,
    ctx: FieldContext<T>,
    d_out: Vec<T>,
}

impl<T: Float + Default> MaterialSmoothness<T> {
    /// Evaluates λ · L_smooth (λ = `weight`) for the pairs (centres[j],
    /// centres[j] + offsets[j]) and ADDS its gradient with respect to the
    /// material field's parameters into `grads`. Returns the mean Σ_i δ_i
    /// (without λ).
    pub fn forward_backward(
        &mut self,
        field: &NeuralField<T>,
        centres: &[[T; 3]],
        offsets: &[[T; 3]],
        weight: T,
        grads: &mut FieldGrads<T>,
    ) -> f64 {
        let m = pair_points(centres, offsets, &mut self.points);
        if m == 0 {
            return 0.0;
        }
        field.forward(&self.points, &[], &mut self.ctx);
        let k = PARAM_COUNT;
        let out = self.ctx.output();
        let (near, far) = out.split_at(m * k);
        let scale = weight / of(m as f64);
        self.d_out.clear();
        self.d_out.resize(2 * m * k, T::ZERO);
        let (d_near, d_far) = self.d_out.split_at_mut(m * k);
        let mut sum = 0.0f64;
        for (j, (((a, b), da), db)) in near.iter().zip(far).zip(d_near).zip(d_far).enumerate() {
            let (delta, d_a, d_b) = pair_difference(j % PARAM_COUNT, *a, *b);
            sum += to_f64(delta);
            *da = scale * d_a;
            *db = scale * d_b;
        }
        field.backward(&mut self.ctx, &self.d_out, grads, None, None);
        sum / m as f64
    }
}
