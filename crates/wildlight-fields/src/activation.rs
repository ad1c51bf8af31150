//! Element-wise activation functions of the MLPs, with derivatives expressed
//! through the activation's *output* (so the forward pass only keeps outputs).

use serde::{Deserialize, Serialize};
use wildlight_real::Real;

/// An element-wise activation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Activation {
    /// Identity.
    None,
    /// `max(z, 0)`.
    Relu,
    /// `ln(1 + e^(beta·z)) / beta` (smooth ReLU; `beta = 100` for SDFs).
    Softplus {
        /// Sharpness (> 0).
        beta: f32,
    },
    /// `1 / (1 + e^(−z))`.
    Sigmoid,
}

/// Values per block of [`softplus_block`]: four AVX2 vectors of `f32`.
const SOFTPLUS_BLOCK: usize = 32;

/// Softplus of a block of values, computed stage by stage across the block
/// (every value's `β·z`, then every value's exponential, …) rather than
/// value by value. Each value's chain (exp, then ln(1 + u)) is about thirty
/// dependent operations; in this order four independent vectors are in
/// flight at each stage, so the chain's latency is hidden. Same arithmetic
/// as [`Activation::apply`], operation for operation.
#[inline(always)]
fn softplus_block<T: Real>(beta: f32, z: &mut [T; SOFTPLUS_BLOCK]) {
    let b = T::from_f64(beta as f64);
    let mut t = [T::ZERO; SOFTPLUS_BLOCK];
    let mut u = [T::ZERO; SOFTPLUS_BLOCK];
    for k in 0..SOFTPLUS_BLOCK {
        t[k] = b * z[k];
    }
    for k in 0..SOFTPLUS_BLOCK {
        u[k] = -t[k].abs();
    }
    T::exp_fast_block(&mut u);
    T::ln_1p_unit_block(&mut u);
    for k in 0..SOFTPLUS_BLOCK {
        z[k] = (t[k].max_cmp(T::ZERO) + u[k]) / b;
    }
}

impl Activation {
    /// The activation of one value.
    #[inline(always)]
    pub fn apply<T: Real>(self, z: T) -> T {
        match self {
            Activation::None => z,
            Activation::Relu => z.relu(),
            Activation::Softplus { beta } => {
                let b = T::from_f64(beta as f64);
                let t = b * z;
                // softplus(t) = max(t, 0) + ln(1 + e^(−|t|))
                (t.max_cmp(T::ZERO) + (-t.abs()).exp_fast().ln_1p_unit()) / b
            }
            Activation::Sigmoid => T::ONE / (T::ONE + (-z).exp_fast()),
        }
    }

    /// The derivative `da/dz`, written as a function of the output `a`.
    #[inline(always)]
    pub fn derivative_from_output<T: Real>(self, a: T) -> T {
        match self {
            Activation::None => T::ONE,
            Activation::Relu => {
                if a > T::ZERO {
                    T::ONE
                } else {
                    T::ZERO
                }
            }
            Activation::Softplus { beta } => {
                // d/dz = sigmoid(beta z) = 1 − e^(−beta a), since e^(beta a) = 1 + e^(beta z).
                let b = T::from_f64(beta as f64);
                -(-(b * a)).exp_m1()
            }
            Activation::Sigmoid => a * (T::ONE - a),
        }
    }

    /// Applies the activation in place to every value of `z`.
    pub fn forward_in_place<T: Real>(self, z: &mut [T]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports the enabled features (checked just above).
            unsafe { self.forward_avx2(z) };
            return;
        }
        self.forward_generic(z)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn forward_avx2<T: Real>(self, z: &mut [T]) {
        self.forward_generic(z)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn backward_avx2<T: Real>(self, a: &[T], delta: &mut [T]) {
        self.backward_generic(a, delta)
    }

    #[inline(always)]
    fn forward_generic<T: Real>(self, z: &mut [T]) {
        // Plain loops (no closures), so they are compiled with the caller's
        // target features and vectorise.
        match self {
            Activation::None => {}
            Activation::Relu => {
                for v in z.iter_mut() {
                    *v = v.relu();
                }
            }
            Activation::Softplus { beta } => {
                let act = Activation::Softplus { beta };
                let mut blocks = z.chunks_exact_mut(SOFTPLUS_BLOCK);
                for block in &mut blocks {
                    softplus_block(beta, block.try_into().expect("a whole block"));
                }
                for v in blocks.into_remainder() {
                    *v = act.apply(*v);
                }
            }
            Activation::Sigmoid => {
                for v in z.iter_mut() {
                    *v = Activation::Sigmoid.apply(*v);
                }
            }
        }
    }

    /// Multiplies each upstream gradient `delta` (w.r.t. the outputs `a`) by `da/dz`.
    pub fn backward_in_place<T: Real>(self, a: &[T], delta: &mut [T]) {
        assert_eq!(a.len(), delta.len());
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports the enabled features (checked just above).
            unsafe { self.backward_avx2(a, delta) };
            return;
        }
        self.backward_generic(a, delta)
    }

    #[inline(always)]
    fn backward_generic<T: Real>(self, a: &[T], delta: &mut [T]) {
        let n = a.len().min(delta.len());
        let (a, delta) = (&a[..n], &mut delta[..n]);
        match self {
            Activation::None => {}
            Activation::Relu => {
                // A product with the 0/1 derivative, so that every value is
                // stored (see `Real::relu` on masked stores); a non-finite
                // gradient at an inactive unit stays non-finite.
                for i in 0..n {
                    delta[i] *= Activation::Relu.derivative_from_output(a[i]);
                }
            }
            Activation::Softplus { beta } => {
                let act = Activation::Softplus { beta };
                for i in 0..n {
                    delta[i] *= act.derivative_from_output(a[i]);
                }
            }
            Activation::Sigmoid => {
                for i in 0..n {
                    delta[i] *= Activation::Sigmoid.derivative_from_output(a[i]);
                }
            }
        }
    }

    /// Checks the settings (softplus needs beta > 0).
    pub fn is_valid(self) -> bool {
        match self {
            Activation::Softplus { beta } => beta.is_finite() && beta > 0.0,
            _ => true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values from −2 to 2 with steps fine enough to cross every branch
    /// of the activations (softplus's clamp at β|z| = 87 included), plus zeros.
    fn inputs() -> Vec<f32> {
        let mut z: Vec<f32> = (0..4003).map(|i| (i as f32 - 2001.0) * 1e-3).collect();
        z.extend([0.0, -0.0, 0.9, -0.9, 1e-30, -1e-30]);
        z
    }

    /// The slice kernels (blocks for softplus, a maximum instruction for
    /// ReLU) give exactly what the one-value form gives.
    #[test]
    fn slice_kernels_equal_the_one_value_form() {
        for act in [
            Activation::Softplus { beta: 100.0 },
            Activation::Softplus { beta: 1.0 },
            Activation::Relu,
            Activation::Sigmoid,
        ] {
            let z = inputs();
            let mut out = z.clone();
            act.forward_in_place(&mut out);
            for (x, y) in z.iter().zip(&out) {
                assert_eq!(act.apply(*x).to_bits(), y.to_bits(), "{act:?} at {x}");
            }
            let delta: Vec<f32> = (0..out.len()).map(|i| (i % 7) as f32 - 3.0).collect();
            let mut d = delta.clone();
            act.backward_in_place(&out, &mut d);
            for i in 0..d.len() {
                assert_eq!(
                    d[i],
                    delta[i] * act.derivative_from_output(out[i]),
                    "{act:?} at {}",
                    z[i]
                );
            }
        }
    }
}
