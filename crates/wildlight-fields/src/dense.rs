//! Kernels of a dense layer on column-major ("feature-major") activations:
//! value `j` of row `r` at `j · ld + r`, so that one feature of many rows is
//! contiguous and the arithmetic vectorises across rows, with no packing.
//!
//! Weights are row-major `W[o][i]` (`n_out × n_in`), as in [`crate::mlp`].
//! Every sum runs in a fixed order that depends only on the shapes, so
//! results are deterministic.

use wildlight_real::Real;

/// Rows of a register tile (two or four SIMD vectors).
const RT: usize = 16;
/// Outputs of a register tile.
const OT: usize = 4;
/// Rows of a register tile with AVX-512 (two 16-lane vectors).
const FR: usize = 32;
/// Outputs of a register tile with AVX-512 (16 accumulators of the 32
/// vector registers; the fastest shape measured, `examples/mlp_parts`).
const FO: usize = 8;

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
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU supports the enabled features (checked just above).
        unsafe { forward_avx512(n_in, n_out, rows, ld, w, ws, bias, input, out) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports the enabled features (checked just above).
        unsafe { forward_avx2(n_in, n_out, rows, ld, w, ws, bias, input, out) };
        return;
    }
    forward_generic::<T, RT, OT>(n_in, n_out, rows, ld, w, ws, bias, input, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn forward_avx512<T: Real>(
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
    forward_generic::<T, FR, FO>(n_in, n_out, rows, ld, w, ws, bias, input, out)
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
    forward_generic::<T, RT, OT>(n_in, n_out, rows, ld, w, ws, bias, input, out)
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
fn forward_generic<T: Real, const RT: usize, const OT: usize>(
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
///
/// Each sum runs in `LANES` lane-wise partial sums (fused multiply-adds
/// over the full groups of rows), then the lanes in order, then the tail
/// rows: the same order on every instruction set and for every tile shape,
/// so the result does not depend on the CPU.
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
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU supports the enabled features (checked just above).
        unsafe { backward_params_avx512(n_in, n_out, rows, ld, delta, input, gw, gb) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports the enabled features (checked just above).
        unsafe { backward_params_avx2(n_in, n_out, rows, ld, delta, input, gw, gb) };
        return;
    }
    backward_params_generic::<T, 2, 2>(n_in, n_out, rows, ld, delta, input, gw, gb)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn backward_params_avx512<T: Real>(
    n_in: usize,
    n_out: usize,
    rows: usize,
    ld: usize,
    delta: &[T],
    input: &[T],
    gw: &mut [T],
    gb: &mut [T],
) {
    // 8 × 3 sums of one 16-lane vector each (24 of the 32 vector
    // registers), the fastest shape measured (`examples/mlp_parts`).
    backward_params_generic::<T, 8, 3>(n_in, n_out, rows, ld, delta, input, gw, gb)
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
    // 2 × 2 sums of two 8-lane vectors each, with the 4 loaded columns:
    // 16 vector registers.
    backward_params_generic::<T, 2, 2>(n_in, n_out, rows, ld, delta, input, gw, gb)
}

/// Lanes of the partial sums of the weight gradient.
const LANES: usize = 16;

/// `Σ_r a[r] · b[r]` for `NO × NI` pairs of columns, in lane-wise partial
/// sums over the full groups of [`LANES`] rows, then the lanes in order,
/// then the tail rows.
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
                        acc[oo][ii][k] = (*d.add(k)).mul_add(x[ii][k], acc[oo][ii][k]);
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
                s = delta[(o0 + oo) * ld + r].mul_add(input[(i0 + ii) * ld + r], s);
            }
            gw[(o0 + oo) * n_in + i0 + ii] += s;
        }
    }
}

/// The weight gradient in `PO × PI` tiles (then the edge tiles), and the
/// bias gradient.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn backward_params_generic<T: Real, const PO: usize, const PI: usize>(
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
    let full_i = n_in / PI * PI;
    // SAFETY (all tiles): outputs < `n_out`, inputs < `n_in`, rows < `rows`,
    // inside the extents asserted by `linear_backward_params`.
    for o0 in (0..full_o).step_by(PO) {
        for i0 in (0..full_i).step_by(PI) {
            unsafe { param_tile::<T, PO, PI>(n_in, rows, ld, delta, input, gw, o0, i0) };
        }
        for i0 in full_i..n_in {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic values in about ±1 (a fixed multiplicative hash).
    fn values(n: usize, seed: usize) -> Vec<f32> {
        (0..n)
            .map(|i| ((i * 7919 + seed * 104_729) % 2003) as f32 / 1001.5 - 1.0)
            .collect()
    }

    /// Shapes with full tiles, edge tiles and tail rows on every path.
    const SHAPES: [(usize, usize, usize, usize); 4] = [
        (35, 64, 256, 256),
        (64, 16, 200, 203),
        (3, 35, 37, 40),
        (1, 1, 5, 5),
    ];

    #[test]
    fn forward_is_the_same_on_every_path_and_matches_f64() {
        for (n_in, n_out, rows, ld) in SHAPES {
            let w = values(n_out * n_in, 1);
            let bias = values(n_out, 2);
            let input = values(n_in * ld, 3);
            let run = |f: &dyn Fn(&mut [f32])| {
                let mut out = vec![0.0f32; n_out * ld];
                f(&mut out);
                out
            };
            let generic = run(&|out| {
                forward_generic::<f32, RT, OT>(
                    n_in,
                    n_out,
                    rows,
                    ld,
                    &w,
                    (n_in, 1),
                    &bias,
                    &input,
                    out,
                )
            });
            let dispatched = run(&|out| {
                linear_forward(n_in, n_out, rows, ld, &w, (n_in, 1), &bias, &input, out)
            });
            let wide = run(&|out| {
                forward_generic::<f32, FR, FO>(
                    n_in,
                    n_out,
                    rows,
                    ld,
                    &w,
                    (n_in, 1),
                    &bias,
                    &input,
                    out,
                )
            });
            assert_eq!(generic, dispatched, "{n_in}×{n_out}, {rows} rows");
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports the enabled features.
                let avx2 = run(&|out| unsafe {
                    forward_avx2(n_in, n_out, rows, ld, &w, (n_in, 1), &bias, &input, out)
                });
                assert_eq!(generic, avx2, "{n_in}×{n_out}, {rows} rows");
            }
            assert_eq!(generic, wide, "{n_in}×{n_out}, {rows} rows");
            for o in 0..n_out {
                for r in 0..rows {
                    let exact = bias[o] as f64
                        + (0..n_in)
                            .map(|i| w[o * n_in + i] as f64 * input[i * ld + r] as f64)
                            .sum::<f64>();
                    let got = generic[o * ld + r] as f64;
                    assert!(
                        (got - exact).abs() < 1e-5 * (1.0 + n_in as f64),
                        "{got} vs {exact}"
                    );
                }
            }
        }
    }

    #[test]
    fn weight_gradients_are_the_same_for_every_tile_and_match_f64() {
        for (n_in, n_out, rows, ld) in SHAPES {
            let delta = values(n_out * ld, 4);
            let input = values(n_in * ld, 5);
            // Accumulates onto a non-zero start, as across chunks.
            let start_w = values(n_out * n_in, 6);
            let start_b = values(n_out, 7);
            type Kernel<'a> = &'a dyn Fn(&mut [f32], &mut [f32]);
            let run = |f: Kernel| {
                let (mut gw, mut gb) = (start_w.clone(), start_b.clone());
                f(&mut gw, &mut gb);
                (gw, gb)
            };
            let reference = run(&|gw, gb| {
                backward_params_generic::<f32, 1, 1>(n_in, n_out, rows, ld, &delta, &input, gw, gb)
            });
            let results = [
                run(&|gw, gb| {
                    linear_backward_params(n_in, n_out, rows, ld, &delta, &input, gw, gb)
                }),
                run(&|gw, gb| {
                    backward_params_generic::<f32, 2, 2>(
                        n_in, n_out, rows, ld, &delta, &input, gw, gb,
                    )
                }),
                run(&|gw, gb| {
                    backward_params_generic::<f32, 8, 3>(
                        n_in, n_out, rows, ld, &delta, &input, gw, gb,
                    )
                }),
            ];
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports the enabled features.
                let avx2 = run(&|gw, gb| unsafe {
                    backward_params_avx2(n_in, n_out, rows, ld, &delta, &input, gw, gb)
                });
                assert_eq!(avx2, reference, "{n_in}×{n_out}, {rows} rows");
            }
            for result in &results {
                assert_eq!(*result, reference, "{n_in}×{n_out}, {rows} rows");
            }
            for o in 0..n_out {
                let bias_exact =
                    start_b[o] as f64 + (0..rows).map(|r| delta[o * ld + r] as f64).sum::<f64>();
                assert!((reference.1[o] as f64 - bias_exact).abs() < 1e-4);
                for i in 0..n_in {
                    let exact = start_w[o * n_in + i] as f64
                        + (0..rows)
                            .map(|r| delta[o * ld + r] as f64 * input[i * ld + r] as f64)
                            .sum::<f64>();
                    let got = reference.0[o * n_in + i] as f64;
                    assert!((got - exact).abs() < 1e-4, "{got} vs {exact}");
                }
            }
        }
    }
}
