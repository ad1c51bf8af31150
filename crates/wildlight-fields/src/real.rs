//! The scalar type of the kernels: every kernel is generic over [`Real`], so the
//! same code runs in `f32` (training, benchmarks) and in `f64` (gradient checks).

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// Whether every value is neither infinite nor NaN.
///
/// Scans blocks in parallel, each without an early exit: `0 · v` is ±0 for
/// every finite `v` and NaN for ±∞ and NaN, so the comparison runs as SIMD
/// lanes instead of one branch per value (the gradient buffers this checks
/// each step hold tens of millions of values).
pub fn all_finite<T: Real>(values: &[T]) -> bool {
    use rayon::prelude::*;
    const BLOCK: usize = 1 << 16;
    values.par_chunks(BLOCK).all(|block| {
        block
            .iter()
            .fold(true, |ok, &v| ok & (v * T::ZERO == T::ZERO))
    })
}

/// A floating-point scalar the field kernels run on (`f32` or `f64`).
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
    /// Converts from `f64` (rounding).
    fn from_f64(v: f64) -> Self;
    /// Converts to `f64` (exact).
    fn to_f64(self) -> f64;
    /// Largest integer not above `self`.
    fn floor(self) -> Self;
    /// Square root.
    fn sqrt(self) -> Self;
    /// `self · a + b` with one rounding (fused multiply-add: one instruction
    /// where the CPU has FMA, an exact software fallback elsewhere, so the
    /// result is the same on every machine).
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// `e^self`; the `f32` version is a vectorisable polynomial (relative error < 2e-7).
    fn exp(self) -> Self;
    /// `ln(1 + self)` for `self ∈ [0, 1]`; the `f32` version is a vectorisable series.
    fn ln_1p_unit(self) -> Self;
    /// `e^self − 1`.
    fn exp_m1(self) -> Self;
    /// `max(self, 0)`, and 0 for NaN, as a maximum instruction: the form
    /// `if self > 0 { self } else { 0 }` over a slice in place compiles to
    /// masked stores of the zeros, which are slow on some CPUs (about
    /// 0.8 ns a value on the 2-vCPU EPYC, against about 0.05 ns).
    fn relu(self) -> Self;
    /// [`Real::exp`] of every value of a block, in place; the `f32` version
    /// runs stage by stage across the block (the same operations, so the
    /// same results), which keeps several vectors in flight.
    #[inline(always)]
    fn exp_block<const N: usize>(v: &mut [Self; N]) {
        for x in v.iter_mut() {
            *x = x.exp();
        }
    }
    /// [`Real::ln_1p_unit`] of every value of a block, in place (stage by
    /// stage for `f32`, as [`Real::exp_block`]).
    #[inline(always)]
    fn ln_1p_unit_block<const N: usize>(v: &mut [Self; N]) {
        for x in v.iter_mut() {
            *x = x.ln_1p_unit();
        }
    }
    /// Larger of two values (`self` when either is NaN-free equal).
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        if self >= o { self } else { o }
    }
    /// Smaller of two values.
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        if self <= o { self } else { o }
    }
    /// Absolute value.
    #[inline(always)]
    fn abs(self) -> Self {
        if self >= Self::ZERO { self } else { -self }
    }
    /// Truncation to an index (the value must be in `[0, 2^31)`).
    fn to_u32(self) -> u32;
    /// Truncation to an index without range checks, so that loops over it
    /// vectorise.
    ///
    /// # Safety
    /// The value must be finite and in `[0, 2^31)`.
    unsafe fn to_u32_unchecked(self) -> u32;
    /// Conversion from an integer below 2^31.
    fn from_u32(v: u32) -> Self;
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

impl Real for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn floor(self) -> Self {
        f64::floor(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        f64::mul_add(self, a, b)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline(always)]
    fn relu(self) -> Self {
        f64::max(self, 0.0)
    }
    #[inline(always)]
    fn ln_1p_unit(self) -> Self {
        f64::ln_1p(self)
    }
    #[inline(always)]
    fn exp_m1(self) -> Self {
        f64::exp_m1(self)
    }
    #[inline(always)]
    fn to_u32(self) -> u32 {
        self as i32 as u32
    }
    #[inline(always)]
    unsafe fn to_u32_unchecked(self) -> u32 {
        // SAFETY: forwarded contract of the caller.
        unsafe { self.to_int_unchecked::<i32>() as u32 }
    }
    #[inline(always)]
    fn from_u32(v: u32) -> Self {
        v as i32 as f64
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
        unsafe {
            matrixmultiply::dgemm(m, k, n, alpha, a, rsa, csa, b, rsb, csb, beta, c, rsc, csc)
        }
    }
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn floor(self) -> Self {
        // Branch-free floor for the range the grids use (|x| < 2^23).
        let t = self as i32 as f32;
        if t > self { t - 1.0 } else { t }
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        f32::mul_add(self, a, b)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        fast_exp_f32(self)
    }
    #[inline(always)]
    fn relu(self) -> Self {
        f32::max(self, 0.0)
    }
    #[inline(always)]
    fn ln_1p_unit(self) -> Self {
        fast_ln_1p_unit_f32(self)
    }
    #[inline(always)]
    fn exp_block<const N: usize>(v: &mut [Self; N]) {
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
    fn from_u32(v: u32) -> Self {
        v as i32 as f32
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
        unsafe {
            matrixmultiply::sgemm(m, k, n, alpha, a, rsa, csa, b, rsb, csb, beta, c, rsc, csc)
        }
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

/// Safe wrapper of [`Real::gemm_raw`] for row-major operands:
/// `C[m×n] = alpha · op(A)[m×k] · op(B)[k×n] + beta · C`, where `op` transposes
/// when the flag is set. `a`, `b`, `c` are dense row-major matrices
/// (`A` is `m×k`, or `k×m` when transposed; `B` is `k×n`, or `n×k` when transposed).
#[allow(clippy::too_many_arguments)]
pub fn gemm<T: Real>(
    m: usize,
    k: usize,
    n: usize,
    alpha: T,
    a: &[T],
    a_transposed: bool,
    b: &[T],
    b_transposed: bool,
    beta: T,
    c: &mut [T],
) {
    let sa = if a_transposed { (1, m) } else { (k, 1) };
    let sb = if b_transposed { (1, k) } else { (n, 1) };
    gemm_strided(m, k, n, alpha, a, sa, b, sb, beta, c, (n, 1));
}

/// Largest offset touched by a `rows × cols` matrix with strides `s` (row, column), plus one.
fn extent((rows, cols): (usize, usize), s: (usize, usize)) -> usize {
    if rows == 0 || cols == 0 {
        0
    } else {
        (rows - 1) * s.0 + (cols - 1) * s.1 + 1
    }
}

/// Safe wrapper of [`Real::gemm_raw`] with explicit (row, column) strides of
/// `A` (`m×k`), `B` (`k×n`) and `C` (`m×n`): `C = alpha·A·B + beta·C`.
#[allow(clippy::too_many_arguments)]
pub fn gemm_strided<T: Real>(
    m: usize,
    k: usize,
    n: usize,
    alpha: T,
    a: &[T],
    (rsa, csa): (usize, usize),
    b: &[T],
    (rsb, csb): (usize, usize),
    beta: T,
    c: &mut [T],
    (rsc, csc): (usize, usize),
) {
    assert!(a.len() >= extent((m, k), (rsa, csa)), "gemm: A too small");
    assert!(b.len() >= extent((k, n), (rsb, csb)), "gemm: B too small");
    assert!(c.len() >= extent((m, n), (rsc, csc)), "gemm: C too small");
    if m == 0 || n == 0 {
        return;
    }
    let (rsa, csa, rsb, csb, rsc, csc) = (
        rsa as isize,
        csa as isize,
        rsb as isize,
        csb as isize,
        rsc as isize,
        csc as isize,
    );
    // matrixmultiply's "threading" feature splits calls with m·k + k·n ≥ 2^15
    // over its own threads; our callers are already parallel, so the product
    // is cut into pieces below that size (the cut depends only on the shapes,
    // so results stay deterministic).
    const HALF_PIECE: usize = (1 << 14) - 1;
    let k_piece = (HALF_PIECE / n.max(1)).clamp(1, k.max(1));
    let mut k0 = 0;
    while k0 < k.max(1) {
        let kk = k_piece.min(k - k0.min(k));
        let m_piece = (HALF_PIECE / kk.max(1)).max(1);
        let beta_here = if k0 == 0 { beta } else { T::ONE };
        let mut m0 = 0;
        while m0 < m {
            let mm = m_piece.min(m - m0);
            // SAFETY: the asserts above bound every strided access inside the
            // slices, and each piece is a sub-block of those extents.
            unsafe {
                T::gemm_raw(
                    mm,
                    kk,
                    n,
                    alpha,
                    a.as_ptr().offset(m0 as isize * rsa + k0 as isize * csa),
                    rsa,
                    csa,
                    b.as_ptr().offset(k0 as isize * rsb),
                    rsb,
                    csb,
                    beta_here,
                    c.as_mut_ptr().offset(m0 as isize * rsc),
                    rsc,
                    csc,
                )
            }
            m0 += mm;
        }
        k0 += k_piece;
    }
}

#[cfg(test)]
mod tests {
    use super::all_finite;

    #[test]
    fn all_finite_finds_one_bad_value_anywhere() {
        // Longer than one block, so the scan crosses block boundaries.
        let n = 3 * (1 << 16) + 5;
        let good: Vec<f32> = (0..n).map(|i| (i as f32 - 1e5) * 1e30).collect();
        assert!(all_finite(&good));
        assert!(all_finite::<f64>(&[]));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for at in [0, 1 << 16, n - 1] {
                let mut v = good.clone();
                v[at] = bad;
                assert!(!all_finite(&v), "{bad} at {at} not found");
            }
        }
        assert!(all_finite(&[f64::MAX, f64::MIN_POSITIVE, -0.0]));
        assert!(!all_finite(&[1.0, f64::NAN]));
    }
}
