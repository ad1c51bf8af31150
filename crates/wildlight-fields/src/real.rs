//! Helpers over the kernels' scalar type [`Real`] (`f32` in training and
//! benchmarks, `f64` in gradient checks): a finiteness scan of large
//! buffers and safe wrappers of [`Real::gemm_raw`].

use wildlight_real::Real;

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
