//! Scalar helpers of the differentiable kernels, generic over
//! [`wildlight_real::Real`] (`f32` in training, `f64` in the
//! finite-difference tests).

use wildlight_real::Real;

/// The logistic sigmoid 1 / (1 + e^(−x)), evaluated without overflow.
#[inline(always)]
pub fn sigmoid<T: Real>(x: T) -> T {
    let one = T::from_f64(1.0);
    if x >= T::from_f64(0.0) {
        one / (one + (-x).exp())
    } else {
        let e = x.exp();
        e / (one + e)
    }
}

/// Dot product of two 3-vectors.
#[inline(always)]
pub fn dot3<T: Real>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
