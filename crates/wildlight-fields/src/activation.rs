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
        match self {
            Activation::None => {}
            Activation::Relu => z.iter_mut().for_each(|v| *v = Activation::Relu.apply(*v)),
            Activation::Softplus { beta } => {
                let act = Activation::Softplus { beta };
                z.iter_mut().for_each(|v| *v = act.apply(*v))
            }
            Activation::Sigmoid => z
                .iter_mut()
                .for_each(|v| *v = Activation::Sigmoid.apply(*v)),
        }
    }

    /// Multiplies each upstream gradient `delta` (w.r.t. the outputs `a`) by `da/dz`.
    pub fn backward_in_place<T: Real>(self, a: &[T], delta: &mut [T]) {
        assert_eq!(a.len(), delta.len());
        match self {
            Activation::None => {}
            Activation::Relu => delta.iter_mut().zip(a).for_each(|(d, &a)| {
                if a <= T::ZERO {
                    *d = T::ZERO
                }
            }),
            Activation::Softplus { beta } => {
                let act = Activation::Softplus { beta };
                delta
                    .iter_mut()
                    .zip(a)
                    .for_each(|(d, &a)| *d *= act.derivative_from_output(a))
            }
            Activation::Sigmoid => delta
                .iter_mut()
                .zip(a)
                .for_each(|(d, &a)| *d *= Activation::Sigmoid.derivative_from_output(a)),
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
