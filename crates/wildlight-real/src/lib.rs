//! The one floating-point abstraction of wildlight.
//!
//! Every numeric kernel — the material model (`wildlight-material`), the
//! neural fields (`wildlight-fields`), the differentiable renderer
//! (`wildlight-render`) and the trainer (`wildlight-train`, where it is
//! called `Float`) — is generic over [`Real`], so the same code runs in
//! `f32` (training, benchmarks) and in `f64` (gradient and
//! finite-difference checks).
//!
//! Where the kernels need an operation in two forms with different `f32`
//! results, both are here under their own names, so that each caller keeps
//! exactly the arithmetic (and so the bits) it was written for:
//!
//! | operation | library form (as `f32::…`) | kernel form |
//! | --- | --- | --- |
//! | e^x | [`Real::exp`] | [`Real::exp_fast`], [`Real::exp_fast_block`]: a vectorisable polynomial |
//! | larger / smaller | [`Real::max`], [`Real::min`]: NaN-ignoring | [`Real::max_cmp`], [`Real::min_cmp`]: one compare-select |
//!
//! ```
//! use wildlight_real::Real;
//! fn hypot<T: Real>(a: T, b: T) -> T {
//!     (a * a + b * b).sqrt()
//! }
//! assert_eq!(hypot(3.0f32, 4.0), 5.0);
//! assert_eq!(hypot(3.0f64, 4.0), 5.0);
//! ```

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real scalar type (`f32` or `f64`) with every operation the kernels use.
pub trait Real:
    Copy
    + Send
    + Sync
    + Default
    + Debug
    + PartialOrd
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// Converts from `f64` (rounding for `f32`).
    fn from_f64(v: f64) -> Self;
    /// Converts to `f64` (exact).
    fn to_f64(self) -> f64;
    /// Conversion from an integer below 2^31.
    fn from_u32(v: u32) -> Self;
    /// Truncation to an index (the value must be in `[0, 2^31)`).
    fn to_u32(self) -> u32;
    /// Truncation to an index without range checks, so that loops over it
    /// vectorise.
    ///
    /// # Safety
    /// The value must be finite and in `[0, 2^31)`.
    unsafe fn to_u32_unchecked(self) -> u32;
    /// Whether the value is neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Natural logarithm (the library's `ln`).
    fn ln(self) -> Self;
    /// `e^self` (the library's `exp`); see [`Real::exp_fast`] for the
    /// kernels' vectorisable form.
    fn exp(self) -> Self;
    /// Absolute value (the library's `abs`: the sign bit cleared).
    fn abs(self) -> Self;
    /// The larger of two values (the library's `max`: a NaN operand gives
    /// the other one). See [`Real::max_cmp`] for the compare-select form.
    fn max(self, other: Self) -> Self;
    /// The smaller of two values (the library's `min`: a NaN operand gives
    /// the other one). See [`Real::min_cmp`] for the compare-select form.
    fn min(self, other: Self) -> Self;
    /// Largest integer not above `self`; the `f32` version is branch-free
    /// and exact only for |self| < 2^23 (the range the grids use).
    fn floor(self) -> Self;
    /// `self · a + b` with one rounding (fused multiply-add: one instruction
    /// where the CPU has FMA, an exact software fallback elsewhere, so the
    /// result is the same on every machine).
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// `e^self`; the `f32` version is a vectorisable polynomial (relative
    /// error < 2e-7, [`fast_exp_f32`]), the `f64` version the library's.
    fn exp_fast(self) -> Self;
    /// `ln(1 + self)` for `self ∈ [0, 1]`; the `f32` version is a
    /// vectorisable series ([`fast_ln_1p_unit_f32`]).
    fn ln_1p_unit(self) -> Self;
    /// `e^self − 1`; the `f32` version is [`Real::exp_fast`] − 1 (absolute
    /// error ~1e-7, enough for the derivative uses).
    fn exp_m1(self) -> Self;
    /// `max(self, 0)`, and 0 for NaN, as a maximum instruction: the form
    /// `if self > 0 { self } else { 0 }` over a slice in place compiles to
    /// masked stores of the zeros, which are slow on some CPUs (about
    /// 0.8 ns a value on the 2-vCPU EPYC, against about 0.05 ns).
    fn relu(self) -> Self;
    /// [`Real::exp_fast`] of every value of a block, in place; the `f32`
    /// version runs stage by stage across the block (the same operations,
    /// so the same results), which keeps several vectors in flight.
    #[inline(always)]
    fn exp_fast_block<const N: usize>(v: &mut [Self; N]) {
        for x in v.iter_mut() {
            *x = x.exp_fast();
        }
    }
    /// [`Real::ln_1p_unit`] of every value of a block, in place (stage by
    /// stage for `f32`, as [`Real::exp_fast_block`]).
    #[inline(always)]
    fn ln_1p_unit_block<const N: usize>(v: &mut [Self; N]) {
        for x in v.iter_mut() {
            *x = x.ln_1p_unit();
        }
    }
    /// The larger of two values as one compare-select,
    /// `if self >= o { self } else { o }`: ties keep `self`, a NaN `self`
    /// gives `o`. Differs from [`Real::max`] only for a NaN `o` and in the
    /// sign of a zero result; the kernels' form (one max instruction).
    #[inline(always)]
    fn max_cmp(self, o: Self) -> Self {
        if self >= o { self } else { o }
    }
    /// The smaller of two values as one compare-select,
    /// `if self <= o { self } else { o }` (see [`Real::max_cmp`]).
    #[inline(always)]
    fn min_cmp(self, o: Self) -> Self {
        if self <= o { self } else { o }
    }
    /// Row-major general matrix product `C = alpha·A·B + beta·C` with explicit
    /// strides (see [`matrixmultiply::sgemm`]).
    ///
    /// # Safety
    /// The strided extents must lie inside the allocations behind the pointers.
    #[allow(clippy::too_many_arguments)]
    unsafe fn gemm_raw(
        m: usize,
        k: usize,
        n: usize,
        alpha: Self,
        a: *const Self,
        rsa: isize,
        csa: isize,
        b: *const Self,
        rsb: isize,
        csb: isize,
        beta: Self,
        c: *mut Self,
        rsc: isize,
        csc: isize,
    );
}

/// What both types implement alike: the operations taken from the
/// standard library, the conversions (the same casts) and the matrix
/// product (`$gemm`, matrixmultiply's `sgemm` or `dgemm`).
macro_rules! common_forms {
    ($t:ty, $gemm:path) => {
        const ZERO: Self = 0.0;
        const ONE: Self = 1.0;
        #[inline(always)]
        fn from_f64(v: f64) -> Self {
            v as $t
        }
        #[inline(always)]
        fn to_f64(self) -> f64 {
            self as f64
        }
        #[inline(always)]
        fn from_u32(v: u32) -> Self {
            v as i32 as $t
        }
        #[inline(always)]
        fn to_u32(self) -> u32 {
            // Signed conversions vectorise (cvttps2dq); values are in [0, 2^31).
            self as i32 as u32
        }
        #[inline(always)]
        unsafe fn to_u32_unchecked(self) -> u32 {
            // SAFETY: forwarded contract of the caller.
            unsafe { self.to_int_unchecked::<i32>() as u32 }
        }
        #[inline(always)]
        fn is_finite(self) -> bool {
            <$t>::is_finite(self)
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            <$t>::sqrt(self)
        }
        #[inline(always)]
        fn ln(self) -> Self {
            <$t>::ln(self)
        }
        #[inline(always)]
        fn exp(self) -> Self {
            <$t>::exp(self)
        }
        #[inline(always)]
        fn abs(self) -> Self {
            <$t>::abs(self)
        }
        #[inline(always)]
        fn max(self, other: Self) -> Self {
            <$t>::max(self, other)
        }
        #[inline(always)]
        fn min(self, other: Self) -> Self {
            <$t>::min(self, other)
        }
        #[inline(always)]
        fn mul_add(self, a: Self, b: Self) -> Self {
            <$t>::mul_add(self, a, b)
        }
        #[inline(always)]
        fn relu(self) -> Self {
            <$t>::max(self, 0.0)
        }
        unsafe fn gemm_raw(
            m: usize,
            k: usize,
            n: usize,
            alpha: Self,
            a: *const Self,
            rsa: isize,
            csa: isize,
            b: *const Self,
            rsb: isize,
            csb: isize,
            beta: Self,
            c: *mut Self,
            rsc: isize,
            csc: isize,
        ) {
            // SAFETY: forwarded contract of the caller.
            unsafe { $gemm(m, k, n, alpha, a, rsa, csa, b, rsb, csb, beta, c, rsc, csc) }
        }
    };
}

impl Real for f64 {
    common_forms!(f64, matrixmultiply::dgemm);
    #[inline(always)]
    fn floor(self) -> Self {
        f64::floor(self)
    }
    #[inline(always)]
    fn exp_fast(self) -> Self {
        f64::exp(self)
    }
    #[inline(always)]
    fn ln_1p_unit(self) -> Self {
        f64::ln_1p(self)
    }
    #[inline(always)]
    fn exp_m1(self) -> Self {
        f64::exp_m1(self)
    }
}

impl Real for f32 {
    common_forms!(f32, matrixmultiply::sgemm);
    #[inline(always)]
    fn floor(self) -> Self {
        // Branch-free floor for the range the grids use (|x| < 2^23).
        let t = self as i32 as f32;
        if t > self { t - 1.0 } else { t }
    }
    #[inline(always)]
    fn exp_fast(self) -> Self {
        fast_exp_f32(self)
    }
    #[inline(always)]
    fn ln_1p_unit(self) -> Self {
        fast_ln_1p_unit_f32(self)
    }
    #[inline(always)]
    fn exp_fast_block<const N: usize>(v: &mut [Self; N]) {
        fast_exp_block_f32(v)
    }
    #[inline(always)]
    fn ln_1p_unit_block<const N: usize>(v: &mut [Self; N]) {
        fast_ln_1p_unit_block_f32(v)
    }
    #[inline(always)]
    fn exp_m1(self) -> Self {
        // Accurate enough for the derivative uses (absolute error ~1e-7).
        fast_exp_f32(self) - 1.0
    }
}

/// `e^x` in `f32` without a libm call, so that loops over it vectorise.
/// Range reduction `x = n·ln2 + r`, |r| ≤ ln2/2, then a degree-6 polynomial
/// (Horner steps as fused multiply-adds: half the latency of separate ones).
/// One value of [`fast_exp_block_f32`], where the steps are.
#[inline(always)]
pub fn fast_exp_f32(x: f32) -> f32 {
    let mut v = [x];
    fast_exp_block_f32(&mut v);
    v[0]
}

/// `ln(1 + u)` for `u ∈ [0, 1]` in `f32` via `2·atanh(u / (2 + u))`
/// (s ≤ 1/3, series to s^13 in fused multiply-adds; relative error < 1e-7).
/// One value of [`fast_ln_1p_unit_block_f32`], where the steps are.
#[inline(always)]
pub fn fast_ln_1p_unit_f32(u: f32) -> f32 {
    let mut v = [u];
    fast_ln_1p_unit_block_f32(&mut v);
    v[0]
}

/// Applies one step to every value of a block (a loop the compiler turns
/// into one vector operation per SIMD width of the block).
macro_rules! each {
    ($n:expr, |$k:ident| $body:expr) => {
        for $k in 0..$n {
            $body;
        }
    };
}

/// [`fast_exp_f32`] of every value of a block, stage by stage across the
/// block (the scalar form is this with one value, so the two agree exactly).
#[inline(always)]
pub fn fast_exp_block_f32<const N: usize>(x: &mut [f32; N]) {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    const MAGIC: f32 = 12_582_912.0;
    let mut n = [0.0f32; N];
    let mut r = [0.0f32; N];
    let mut p = [1.0f32 / 720.0; N];
    each!(N, |k| x[k] = x[k].clamp(-87.0, 88.0));
    // Round to nearest with the 1.5·2^23 trick (no SSE4.1 `round` needed).
    each!(N, |k| n[k] = (x[k] * LOG2E + MAGIC) - MAGIC);
    each!(N, |k| r[k] = (x[k] - n[k] * LN2_HI) - n[k] * LN2_LO);
    // Taylor coefficients of e^r up to r^6 (error < 2e-7 on |r| ≤ 0.347).
    for c in [1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0, 1.0] {
        each!(N, |k| p[k] = p[k].mul_add(r[k], c));
    }
    // SAFETY: x ∈ [−87, 88], so n ∈ [−126, 127] is finite and fits in i32
    // (the unchecked conversion vectorises; `as` saturates value by value).
    each!(N, |k| x[k] = p[k]
        * f32::from_bits(
            ((unsafe { n[k].to_int_unchecked::<i32>() } + 127) << 23) as u32
        ));
}

/// [`fast_ln_1p_unit_f32`] of every value of a block, stage by stage (the
/// scalar form is this with one value).
#[inline(always)]
pub fn fast_ln_1p_unit_block_f32<const N: usize>(u: &mut [f32; N]) {
    let mut s = [0.0f32; N];
    let mut s2 = [0.0f32; N];
    let mut p = [1.0f32 / 13.0; N];
    each!(N, |k| s[k] = u[k] / (2.0 + u[k]));
    each!(N, |k| s2[k] = s[k] * s[k]);
    for c in [1.0 / 11.0, 1.0 / 9.0, 1.0 / 7.0, 1.0 / 5.0, 1.0 / 3.0, 1.0] {
        each!(N, |k| p[k] = p[k].mul_add(s2[k], c));
    }
    each!(N, |k| u[k] = 2.0 * s[k] * p[k]);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The polynomial exponential is within its stated error of the
    /// library's over the range the kernels use, and a block gives exactly
    /// the scalar results.
    #[test]
    fn fast_exp_is_accurate_and_blocks_match_single_values() {
        let mut block = [0.0f32; 16];
        for i in 0..=4000 {
            let x = -80.0 + 0.04 * i as f32;
            let got = x.exp_fast() as f64;
            let want = (x as f64).exp();
            assert!(((got - want) / want).abs() < 4e-7, "e^{x}: {got} vs {want}");
            block[i % 16] = x;
            if i % 16 == 15 {
                let mut b = block;
                f32::exp_fast_block(&mut b);
                for (k, v) in b.iter().enumerate() {
                    assert_eq!(v.to_bits(), fast_exp_f32(block[k]).to_bits());
                }
            }
        }
        assert_eq!(1.5f64.exp_fast(), 1.5f64.exp());
    }

    #[test]
    fn fast_ln_1p_unit_is_accurate_and_blocks_match_single_values() {
        let us: Vec<f32> = (0..=1024).map(|i| i as f32 / 1024.0).collect();
        for &u in &us {
            let got = u.ln_1p_unit() as f64;
            let want = (u as f64).ln_1p();
            assert!(
                (got - want).abs() <= 3e-7 * want,
                "ln(1 + {u}): {got} vs {want}"
            );
        }
        let mut b: [f32; 8] = std::array::from_fn(|k| us[100 * k]);
        f32::ln_1p_unit_block(&mut b);
        for (k, v) in b.iter().enumerate() {
            assert_eq!(v.to_bits(), fast_ln_1p_unit_f32(us[100 * k]).to_bits());
        }
    }

    /// The two forms of max and min differ only where documented: a NaN
    /// second operand and the sign of a zero.
    #[test]
    fn compare_select_and_library_forms() {
        assert_eq!(Real::max(2.0f32, 3.0), 3.0);
        assert_eq!(2.0f32.max_cmp(3.0), 3.0);
        assert_eq!(2.0f32.min_cmp(3.0), 2.0);
        assert_eq!(f32::NAN.max_cmp(1.0), 1.0);
        assert!(1.0f32.max_cmp(f32::NAN).is_nan());
        assert_eq!(Real::max(1.0f32, f32::NAN), 1.0);
        assert_eq!((-0.0f32).max_cmp(0.0).to_bits(), (-0.0f32).to_bits());
        assert_eq!(Real::abs(-0.0f32).to_bits(), 0.0f32.to_bits());
        assert_eq!(f32::NAN.relu(), 0.0);
    }

    #[test]
    fn branch_free_floor_matches_the_library_in_range() {
        for i in -2000..=2000 {
            let x = i as f32 * 0.37;
            assert_eq!(Real::floor(x), x.floor(), "{x}");
        }
        assert_eq!(Real::floor(-3.0f32), -3.0);
        assert_eq!(Real::floor(-2.5f64), -3.0);
    }
}
