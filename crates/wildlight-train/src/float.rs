//! The float type the model runs on: `f32` in training, `f64` in gradient
//! checks. It is the one scalar trait of every kernel of the pipeline
//! ([`wildlight_real::Real`]); the functions here are the trainer's
//! shorthands over it.

/// A float usable by every kernel of the pipeline.
pub use wildlight_real::Real as Float;

/// √x.
#[inline(always)]
pub fn sqrt<T: Float>(x: T) -> T {
    x.sqrt()
}

/// The larger of two values.
#[inline(always)]
pub fn max<T: Float>(a: T, b: T) -> T {
    if a > b { a } else { b }
}

/// Converts from `f64`.
#[inline(always)]
pub fn of<T: Float>(v: f64) -> T {
    T::from_f64(v)
}

/// a·b.
#[inline(always)]
pub fn dot3<T: Float>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// |v|.
#[inline(always)]
pub fn norm3<T: Float>(v: [T; 3]) -> T {
    sqrt(dot3(v, v))
}

/// |v| floored at 1e-12, the length the normals divide by.
#[inline(always)]
pub fn safe_norm3<T: Float>(v: [T; 3]) -> T {
    max(norm3(v), of(1e-12))
}

/// The unit vector n = g/|g| and the length it divided by
/// ([`safe_norm3`]; a vanishing g gives n = 0).
#[inline(always)]
pub fn unit3<T: Float>(g: [T; 3]) -> ([T; 3], T) {
    let len = safe_norm3(g);
    ([g[0] / len, g[1] / len, g[2] / len], len)
}

/// Backward of [`unit3`]: ∂L/∂g = (∂L/∂n − n (n·∂L/∂n)) / |g| for the
/// unit vector `n` and the length `len` it returned.
#[inline(always)]
pub fn unit3_backward<T: Float>(d_n: [T; 3], n: [T; 3], len: T) -> [T; 3] {
    let proj = dot3(d_n, n);
    [0, 1, 2].map(|a| (d_n[a] - n[a] * proj) / len)
}

/// −1, 0 or 1 by the sign of `x` (0 for 0 and NaN).
#[inline(always)]
pub fn sign<T: Float>(x: T) -> T {
    if x > T::ZERO {
        T::ONE
    } else if x < T::ZERO {
        -T::ONE
    } else {
        T::ZERO
    }
}

/// Whether `v` is neither infinite nor NaN.
#[inline(always)]
pub fn finite<T: Float>(v: T) -> bool {
    v.to_f64().is_finite()
}

/// Converts to `f64`.
#[inline(always)]
pub fn to_f64<T: Float>(v: T) -> f64 {
    v.to_f64()
}
