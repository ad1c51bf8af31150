//! The scalar type of the differentiable kernels.
//!
//! The kernels run in `f32` during training and in `f64` in the
//! finite-difference tests. [`Scalar`] extends the material model's
//! [`wildlight_material::Real`] with the few extra operations rendering needs.

pub use wildlight_material::Real;

/// A real scalar type (`f32` or `f64`) with the operations of the renderer.
pub trait Scalar: Real {
    /// `e^self`.
    fn exp(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
}

impl Scalar for f32 {
    #[inline(always)]
    fn exp(self) -> Self {
        f32::exp(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
}

impl Scalar for f64 {
    #[inline(always)]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
}

/// The logistic sigmoid 1 / (1 + e^(−x)), evaluated without overflow.
#[inline(always)]
pub fn sigmoid<T: Scalar>(x: T) -> T {
    let one = T::of(1.0);
    if x >= T::of(0.0) {
        one / (one + (-x).exp())
    } else {
        let e = x.exp();
        e / (one + e)
    }
}

/// Dot product of two 3-vectors.
#[inline(always)]
pub fn dot3<T: Scalar>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
