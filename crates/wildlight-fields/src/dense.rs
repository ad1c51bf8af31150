//! Kernels of a dense layer on column-major ("feature-major") activations:
//! value `j` of row `r` at `j · ld + r`, so that one feature of many rows is
//! contiguous and the arithmetic vectorises across rows, with no packing.
//!
//! Weights are row-major `W[o][i]` (`n_out × n_in`), as in [`crate::mlp`].
//! Every sum runs in a fixed order that depends only on the shapes, so
//! results are deterministic.

use crate::real::Real;

/// Rows of a register tile (two or four SIMD vectors).
const RT: usize = 16;
/// Outputs of a register tile.
const OT: usize = 4;

/// `out[o][r] = bias[o] + Σ_i w(o, i) · input[i][r]` for `r < rows`, where
/// `w(o, i) = w[o · ws.0 + i · ws.1]` (pass `(n_in, 1)` for `W`, `(1, n_out)`
/// for its transpose). `input` and `out` are column-major with leading
/// dimension `ld` (`ld ≥ rows`); `bias` may be empty (no bias).
#[allow(clippy::too_many_arguments)]
pub fn linear_forward<T: Real>(
    n_in: usize,
    n_out: usize,
    rows: usize,
    ld: usize,
    w: &[T],
    ws: (usize, usize),
    bias: &[T],
    input: &[T],
    out: &mut [T],
) {
    assert!(ld >= rows, "linear_forward: ld < rows");
    if rows == 0 || n_out == 0 {
        return;
    }
    assert!(n_in == 0 || w.len() > (n_out - 1) * ws.0 + (n_in - 1) * ws.1);
    assert!(bias.is_empty() || bias.len() >= n_out);
    assert!(n_in == 0 || input.len() >= (n_in - 1) * ld + rows);
    assert!(out.len() >= (n_out - 1) * ld + rows);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports the enabled features (checked just above).
        unsafe { forward_avx2(n_in, n_out, rows, ld, w, ws, bias, input, out) };
        return;
    }
    forward_generic(n_in, n_out, rows, ld, w, ws, bias, input, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn forward_avx2<T: Real>(
    n_in: usize,
    n_out: usize,
    rows: usize,
    ld: usize,
    w: &[T],
    ws: (usize, usize),
    bias: &[T],
    input: &[T],
    out: &mut [T],
) {
    forward_generic(n_in, n_out, rows, ld, w, ws, bias, input, out)
}

/// Sum of one output tile `o0 .. o0 + NO` over rows `r0 .. r0 + NR`.
///
/// # Safety
/// The tile must lie inside the extents checked by [`linear_forward`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn forward_tile<T: Real, const NO: usize, const NR: usize>(
    n_in: usize,
    ld: usize,
    w: &[T],
    ws: (usize, usize),
    bias: &[T],
    input: &[T],
    out: &mut [T],
    o0: usize,
    r0: usize,
) {
    let mut acc = [[T::ZERO; NR]; NO];
    let (wp, xp) = (w.as_ptr(), input.as_ptr());
    for i in 0..n_in {
        // SAFETY: rows r0 .. r0 + NR of input column i and weights (o, i)
        // of the tile's outputs are inside the checked extents.
        unsafe {
            let x = xp.add(i * ld + r0);
            for oo in 0..NO {
                let wv = *wp.add((o0 + oo) * ws.0 + i * ws.1);
                for rr in 0..NR {
                    acc[oo][rr] = wv.mul_add(*x.add(rr), acc[oo][rr]);
                }
            }
        }
    }
    for oo in 0..NO {
        let b = if bias.is_empty() {
            T::ZERO
        } else {
            bias[o0 + oo]
        };
        let dst = &mut out[(o0 + oo) * ld + r0..(o0 + oo) * ld + r0 + NR];
        for rr in 0..NR {
            dst[rr] = acc[oo][rr] + b;
        }
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn forward_generic<T: Real>(
    n_in: usize,
    n_out: usize,
    rows: usize,
    ld: usize,
    w: &[T],
    ws: (usize, usize),
    bias: &[T],
    input: &[T],
    out: &mut [T],
) {
    let full_r = rows / RT * RT;
    let full_o = n_out / OT * OT;
    // SAFETY (all tiles): rows < `rows`, outputs < `n_out`, inside the
    // extents asserted by `linear_forward`.
    for r0 in (0..full_r).step_by(RT) {
        for o0 in (0..full_o).step_by(OT) {
            unsafe { forward_tile::<T, OT, RT>(n_in, ld, w, ws, bias, input, out, o0, r0) };
        }
        for o0 in full_o..n_out {
            unsafe { forward_tile::<T, 1, RT>(n_in, ld, w, ws, bias, input, out, o0, r0) };
        }
    }
    for r0 in full_r..rows {
        for o0 in 0..n_out {
            unsafe { forward_tile::<T, 1, 1>(n_in, ld, w, ws, bias, input, out, o0, r0) };
        }
    }
}

/// Accumulates the weight and bias gradients of a layer:
/// `gw[o][i] += Σ_{r<rows} delta[o][r] · input[i][r]`, `gb[o] += Σ_r delta[o][r]`
/// (`gw` row-major `n_out × n_in`; `delta`, `input` column-major, leading dimension `ld`).
#[allow(clippy::too_many_arguments)]
pub fn linear_backward_params<T: Real>(
    n_in: usize,
    n_out: usize,
    rows: usize,
    ld: usize,
    delta: &[T],
    input: &[T],
    gw: &mut [T],
    gb: &mut [T],
) {
    assert!(ld >= rows, "linear_backward_params: ld < rows");
    if rows == 0 || n_out == 0 {
        return;
    }
    assert!(delta.len() >= (n_out - 1) * ld + rows);
    assert!(n_in == 0 || input.len() >= (n_in - 1) * ld + rows);
    assert!(gw.len() >= n_out * n_in && gb.len() >= n_out);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports the enabled features (checked just above).
        unsafe { backward_params_avx2(n_in, n_out, rows, ld, delta, input, gw, gb) };
        return;
    }
    backward_params_generic(n_in, n_out, rows, ld, delta, input, gw, gb)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn backward_params_avx2<T: Real>(
    n_in: usize,
    n_out: usize,
    rows: usize,
    ld: usize,
    delta: &[T],
    input: &[T],
    gw: &mut [T],
    gb: &mut [T],
) {
    backward_params_generic(n_in, n_out, rows, ld, delta, input, gw, gb)
}

/// Lanes of the partial sums of the weight gradient.
const LANES: usize = 8;
/// Outputs of a weight-gradient tile.
const PO: usize = 8;

/// `Σ_r a[r] · b[r]` for `NO × NI` pairs of columns, in lane-wise partial sums
/// over the full groups of [`LANES`] rows, then the lanes in order, then the tail rows.
///
/// # Safety
/// The tile must lie inside the extents checked by [`linear_backward_params`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn param_tile<T: Real, const NO: usize, const NI: usize>(
    n_in: usize,
    rows: usize,
    ld: usize,
    delta: &[T],
    input: &[T],
    gw: &mut [T],
    o0: usize,
    i0: usize,
) {
    let full = rows / LANES * LANES;
    let mut acc = [[[T::ZERO; LANES]; NI]; NO];
    let (dp, xp) = (delta.as_ptr(), input.as_ptr());
    for r0 in (0..full).step_by(LANES) {
        // SAFETY: rows r0 .. r0 + LANES ≤ rows of the tile's columns.
        unsafe {
            let mut x = [[T::ZERO; LANES]; NI];
            for ii in 0..NI {
                for k in 0..LANES {
                    x[ii][k] = *xp.add((i0 + ii) * ld + r0 + k);
                }
            }
            for oo in 0..NO {
                let d = dp.add((o0 + oo) * ld + r0);
                for ii in 0..NI {
                    for k in 0..LANES {
                        acc[oo][ii][k] += *d.add(k) * x[ii][k];
                    }
                }
            }
        }
    }
    for oo in 0..NO {
        for ii in 0..NI {
            let mut s = T::ZERO;
            for k in 0..LANES {
                s += acc[oo][ii][k];
            }
            for r in full..rows {
                s += delta[(o0 + oo) * ld + r] * input[(i0 + ii) * ld + r];
            }
            gw[(o0 + oo) * n_in + i0 + ii] += s;
        }
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn backward_params_generic<T: Real>(
    n_in: usize,
    n_out: usize,
    rows: usize,
    ld: usize,
    delta: &[T],
    input: &[T],
    gw: &mut [T],
    gb: &mut [T],
) {
    let full_o = n_out / PO * PO;
    // SAFETY (all tiles): outputs < `n_out`, inputs < `n_in`, rows < `rows`,
    // inside the extents asserted by `linear_backward_params`.
    for o0 in (0..full_o).step_by(PO) {
        for i0 in 0..n_in {
            unsafe { param_tile::<T, PO, 1>(n_in, rows, ld, delta, input, gw, o0, i0) };
        }
    }
    for o0 in full_o..n_out {
        for i0 in 0..n_in {
            unsafe { param_tile::<T, 1, 1>(n_in, rows, ld, delta, input, gw, o0, i0) };
        }
    }
    let full = rows / LANES * LANES;
    for o in 0..n_out {
        let d = &delta[o * ld..o * ld + rows];
        let mut acc = [T::ZERO; LANES];
        for c in d[..full].chunks_exact(LANES) {
            for k in 0..LANES {
                acc[k] += c[k];
            }
        }
        let mut s = T::ZERO;
        for k in 0..LANES {
            s += acc[k];
        }
        for &v in &d[full..] {
            s += v;
        }
        gb[o] += s;
    }
}
