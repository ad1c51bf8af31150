//! Element-wise activation functions of the MLPs, with derivatives expressed
//! through the activation's *output* (so the forward pass only keeps outputs).

use crate::real::Real;
use serde::{Deserialize, Serialize};

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

impl Activation {
    /// The activation of one value.
    #[inline(always)]
    pub fn apply<T: Real>(self, z: T) -> T {
        match self {
            Activation::None => z,
            Activation::Relu => z.max(T::ZERO),
            Activation::Softplus { beta } => {
                let b = T::from_f64(beta as f64);
                let t = b * z;
                // softplus(t) = max(t, 0) + ln(1 + e^(−|t|))
                (t.max(T::ZERO) + (-t.abs()).exp().ln_1p_unit()) / b
            }
            Activation::Sigmoid => T::ONE / (T::ONE + (-z).exp()),
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
                    *v = Activation::Relu.apply(*v);
                }
            }
            Activation::Softplus { beta } => {
                let act = Activation::Softplus { beta };
                for v in z.iter_mut() {
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
                for i in 0..n {
                    delta[i] = if a[i] > T::ZERO { delta[i] } else { T::ZERO };
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
