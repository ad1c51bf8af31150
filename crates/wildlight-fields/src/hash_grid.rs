//! Multi-resolution hash encoding (Instant-NGP, Müller et al. 2022).
//!
//! The encoding maps a point of the unit cube `[0,1]³` to `levels × features`
//! numbers. Level `l` is a grid with `N_l = floor(N_min · b^l)` cells per axis,
//! `b = (N_max / N_min)^(1/(L−1))`; its vertices store learned feature vectors
//! in a table. Coarse levels whose `(N_l+1)³` vertices fit in the table are
//! indexed densely, the others by the spatial hash
//! `(i · 1) xor (j · 2654435761) xor (k · 805459861) mod T`.
//! The output of a level blends its 8 corners with the product of per-axis
//! weights: trilinear (t, 1 − t), or smoothstep (s(t), 1 − s(t) with
//! s(t) = t²(3 − 2t)), which makes the encoding C¹ across cell faces
//! ([`Interpolation`]).
//!
//! Parameter layout: one flat vector, level after level; inside a level, entry
//! after entry, the `F` features of an entry contiguous.
//!
//! Forward over a batch ([`HashGrid::encode_blocks`]): level-major, every
//! point visits level 0, then level 1, …, so that the level's table (4 MiB
//! for 2^19 entries × 2 features in `f32`) stays in the cache while it is
//! read; points are processed in blocks of 32 whose cells are located in
//! struct-of-arrays form (vectorised) and whose table lines are prefetched
//! one block ahead. Outputs go to blocks of rows of any [`BlockLayout`]
//! (the fields use column-major chunk inputs: one level's columns of a chunk
//! are contiguous).
//!
//! Backward: table gradients are accumulated level-parallel (each rayon task
//! owns whole levels and walks all points in order), which needs no extra
//! buffers, has no races, and is bit-identical for any thread count.
//!
//! The same walk serves the encoding's spatial derivatives, which the
//! analytic SDF gradient needs: the corner weights are replaced by their
//! derivatives (along one direction per point for
//! [`HashGrid::encode_directional_blocks`] and its table gradient, along
//! the three axes for [`HashGrid::backward_input`]).

use crate::error::FieldError;
use crate::memory::{huge_vec, prefetch};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wildlight_real::Real;

/// Settings of a hash encoding.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HashGridConfig {
    /// Number of levels `L` (≥ 1).
    pub n_levels: usize,
    /// Features per level `F` (1, 2, 4 or 8).
    pub n_features: usize,
    /// `log2` of the maximum table size `T` per level (≤ 26).
    pub log2_table_size: u32,
    /// Cells per axis of the coarsest level `N_min` (≥ 1).
    pub base_resolution: u32,
    /// Cells per axis of the finest level `N_max` (≥ `N_min`).
    pub finest_resolution: u32,
    /// Table entries are drawn uniformly from `[−init_range, init_range]`.
    pub init_range: f32,
    /// How a level blends the eight corners of a cell.
    #[serde(default)]
    pub interpolation: Interpolation,
}

/// How a level blends the eight corners of the cell around a point, from
/// the point's fractional position t ∈ [0, 1] along each axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    /// Trilinear: weights t and 1 − t. The encoding is continuous, its
    /// spatial derivative jumps at every cell face, so a zero level set of a
    /// field built on it has a kink wherever it crosses one.
    #[default]
    Linear,
    /// Weights s(t) = t²(3 − 2t) and 1 − s(t): the derivative
    /// s'(t) = 6t(1 − t) vanishes at the faces, so the encoding is C¹ and
    /// level sets are smooth across cells.
    Smoothstep,
}

impl Default for HashGridConfig {
    /// 16 levels × 2 features, 2^19 entries, resolutions 16 … 2048.
    fn default() -> Self {
        HashGridConfig {
            n_levels: 16,
            n_features: 2,
            log2_table_size: 19,
            base_resolution: 16,
            finest_resolution: 2048,
            init_range: 1e-4,
            interpolation: Interpolation::Linear,
        }
    }
}

/// Geometry of one level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelInfo {
    /// Cells per axis.
    pub resolution: u32,
    /// Table entries of this level.
    pub entries: usize,
    /// Offset of the level's first parameter in the flat parameter vector.
    pub param_offset: usize,
    /// Whether the level is indexed densely (no hashing).
    pub dense: bool,
    /// Whether the corner weights use smoothstep ([`Interpolation::Smoothstep`]).
    pub smoothstep: bool,
}

/// Where the values of blocks of rows live (encoder outputs or their
/// gradients): row `r` of a block, column `j`, is at
/// `r · row_stride + j · col_stride`; block `b` holds rows `b · rows ..`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockLayout {
    /// Rows per block (the last block may hold fewer).
    pub rows: usize,
    /// Distance between consecutive rows.
    pub row_stride: usize,
    /// Distance between consecutive columns.
    pub col_stride: usize,
}

impl BlockLayout {
    /// Row-major blocks of `rows` rows, `stride` values per row.
    pub fn row_major(rows: usize, stride: usize) -> Self {
        BlockLayout {
            rows,
            row_stride: stride,
            col_stride: 1,
        }
    }
    /// Column-major blocks of `rows` rows (each column contiguous).
    pub fn column_major(rows: usize) -> Self {
        BlockLayout {
            rows,
            row_stride: 1,
            col_stride: rows,
        }
    }
    /// Offset of the last value of `rows` rows up to column `col` (inclusive).
    pub fn last_offset(&self, rows: usize, col: usize) -> usize {
        rows.saturating_sub(1) * self.row_stride + col * self.col_stride
    }
}

/// Points per rayon task of [`HashGrid::encode_blocks`].
const ENCODE_TASK_POINTS: usize = 4096;

/// Points located (and prefetched) together before their table accesses.
const BLOCK: usize = 32;

const PRIME_Y: u32 = 2_654_435_761;
const PRIME_Z: u32 = 805_459_861;

/// s(t) = t²(3 − 2t), the weight of [`Interpolation::Smoothstep`].
#[inline(always)]
fn smoothstep<T: Real>(t: T) -> T {
    t * t * (T::from_f64(3.0) - T::from_f64(2.0) * t)
}

/// What the weights of a located block are: the kernels blend table
/// entries with them, so one gather computes the encoding or its
/// derivative, and one scatter the gradient of either.
#[derive(Clone, Copy)]
enum Weighting<'a, T> {
    /// The corner weights w_c: the encoding itself.
    Value,
    /// ∂w_c/∂x · v_p: the encoding's derivative along each point's
    /// direction `v_p` (encoder coordinates; one direction per point).
    Directional(&'a [[T; 3]]),
    /// ∂w_c/∂x_k for the three axes k, in [`BlockCells::axis_weight`].
    Axes,
}

impl<'a, T> Weighting<'a, T> {
    /// The weighting of the points `range` of the batch.
    fn range(self, range: std::ops::Range<usize>) -> Weighting<'a, T> {
        match self {
            Weighting::Directional(v) => Weighting::Directional(&v[range]),
            w => w,
        }
    }
}

/// The per-point work of one level inside [`walk_level`]: the forward
/// gather ([`Gather`]) and the backward scatter ([`Scatter`]).
trait LevelKernel<T> {
    /// Prefetches the rows of points `first .. first + count` (the next block).
    fn prefetch_rows(&self, first: usize, count: usize);
    /// Processes point `i` of the located block `cells`, whose row is row
    /// `row` of row block `block`.
    fn point(&mut self, cells: &BlockCells<T>, i: usize, block: usize, row: usize);
}

/// The software-pipelined walk over the points of one level that the
/// forward and the backward kernels share: block b+1 is located, and its
/// table lines (at `table`, `F` values per entry) and rows prefetched,
/// before the points of block b are processed, so cache misses overlap
/// work. Rows come in blocks of `rows` rows.
#[inline(always)]
fn walk_level<T: Real, const F: usize>(
    level: &LevelInfo,
    x: &[[T; 3]],
    weighting: Weighting<'_, T>,
    table: *const T,
    rows: usize,
    kernel: &mut impl LevelKernel<T>,
) {
    let n_blocks = x.len().div_ceil(BLOCK);
    let range = |b: usize| b * BLOCK..((b + 1) * BLOCK).min(x.len());
    let block = |b: usize| &x[range(b)];
    let mut cells = [BlockCells::new(), BlockCells::new()];
    if n_blocks > 0 {
        cells[0].locate(level, block(0), weighting.range(range(0)));
        if !level.dense {
            cells[0].prefetch(table, F, block(0).len());
        }
    }
    let (mut ob, mut or) = (0usize, 0usize);
    for b in 0..n_blocks {
        let (head, tail) = cells.split_at_mut(1);
        let (cur, next) = if b % 2 == 0 {
            (&head[0], &mut tail[0])
        } else {
            (&tail[0], &mut head[0])
        };
        if b + 1 < n_blocks {
            next.locate(level, block(b + 1), weighting.range(range(b + 1)));
            if !level.dense {
                next.prefetch(table, F, block(b + 1).len());
            }
            kernel.prefetch_rows((b + 1) * BLOCK, block(b + 1).len());
        }
        for i in 0..block(b).len() {
            kernel.point(cur, i, ob, or);
            or += 1;
            if or == rows {
                or = 0;
                ob += 1;
            }
        }
    }
}

/// The forward kernel: out = Σ_c w_c · table[index_c] into columns
/// `c0 .. c0 + F` of the output rows.
struct Gather<'a, 'b, T, const F: usize> {
    table: &'a [T],
    out_blocks: &'a mut [&'b mut [T]],
    layout: BlockLayout,
    c0: usize,
}

impl<T: Real, const F: usize> LevelKernel<T> for Gather<'_, '_, T, F> {
    #[inline(always)]
    fn prefetch_rows(&self, first: usize, count: usize) {
        prefetch_rows(self.out_blocks, self.layout, first, count, self.c0, F);
    }

    #[inline(always)]
    fn point(&mut self, cur: &BlockCells<T>, i: usize, block: usize, row: usize) {
        let (rs, cs) = (self.layout.row_stride, self.layout.col_stride);
        let mut acc = [T::ZERO; F];
        for c in 0..8 {
            let e = cur.index[c][i] as usize * F;
            debug_assert!(e + F <= self.table.len());
            // SAFETY: `locate` yields indices below the level's entry
            // count (dense: at most (r+1)³ − 1; hashed: masked by T − 1),
            // and `table` holds `entries · F` values.
            let v: &[T; F] = unsafe { &*(self.table.as_ptr().add(e) as *const [T; F]) };
            let w = cur.weight[c][i];
            for k in 0..F {
                acc[k] += w * v[k];
            }
        }
        let out = &mut *self.out_blocks[block];
        let o = row * rs + self.c0 * cs;
        debug_assert!(o + (F - 1) * cs < out.len());
        for k in 0..F {
            // SAFETY: the caller checked that every block holds its
            // rows' columns `c0 .. c0 + F` (`BlockLayout::last_offset`).
            unsafe { *out.get_unchecked_mut(o + k * cs) = acc[k] };
        }
    }
}

/// The backward kernel: g[index_c] += w_c · d_out for the upstream
/// gradient in columns `c0 .. c0 + F` of the rows.
struct Scatter<'a, 'b, T, const F: usize> {
    g: &'a mut [T],
    d_out_blocks: &'a [&'b [T]],
    layout: BlockLayout,
    c0: usize,
}

impl<T: Real, const F: usize> LevelKernel<T> for Scatter<'_, '_, T, F> {
    #[inline(always)]
    fn prefetch_rows(&self, first: usize, count: usize) {
        prefetch_rows(self.d_out_blocks, self.layout, first, count, self.c0, F);
    }

    #[inline(always)]
    fn point(&mut self, cur: &BlockCells<T>, i: usize, block: usize, row: usize) {
        let (rs, cs) = (self.layout.row_stride, self.layout.col_stride);
        let blk = self.d_out_blocks[block];
        let o = row * rs + self.c0 * cs;
        debug_assert!(o + (F - 1) * cs < blk.len());
        let mut d = [T::ZERO; F];
        for k in 0..F {
            // SAFETY: `check_blocks` bounded every row's encoding columns.
            d[k] = unsafe { *blk.get_unchecked(o + k * cs) };
        }
        for c in 0..8 {
            let e = cur.index[c][i] as usize * F;
            let w = cur.weight[c][i];
            debug_assert!(e + F <= self.g.len());
            // SAFETY: as in `Gather::point`, indices are below the level's
            // entry count and `g` holds `entries · F` values.
            let gv: &mut [T; F] = unsafe { &mut *(self.g.as_mut_ptr().add(e) as *mut [T; F]) };
            for k in 0..F {
                gv[k] += w * d[k];
            }
        }
    }
}

/// The input-gradient kernel: d_x[p] += Σ_c (table[index_c] · d_out_p) ∂w_c/∂x
/// for the upstream gradient in columns `c0 .. c0 + F` of one block of rows
/// (cells located with [`Weighting::Axes`]).
struct InputGradient<'a, T, const F: usize> {
    table: &'a [T],
    d_out: &'a [T],
    layout: BlockLayout,
    c0: usize,
    d_x: &'a mut [[T; 3]],
}

impl<T: Real, const F: usize> LevelKernel<T> for InputGradient<'_, T, F> {
    #[inline(always)]
    fn prefetch_rows(&self, first: usize, count: usize) {
        prefetch_rows(&[self.d_out], self.layout, first, count, self.c0, F);
    }

    #[inline(always)]
    fn point(&mut self, cur: &BlockCells<T>, i: usize, _block: usize, row: usize) {
        let (rs, cs) = (self.layout.row_stride, self.layout.col_stride);
        let o = row * rs + self.c0 * cs;
        let mut d = [T::ZERO; F];
        for k in 0..F {
            d[k] = self.d_out[o + k * cs];
        }
        let dx = &mut self.d_x[row];
        for c in 0..8 {
            let e = cur.index[c][i] as usize * F;
            debug_assert!(e + F <= self.table.len());
            // SAFETY: as in `Gather::point`.
            let v: &[T; F] = unsafe { &*(self.table.as_ptr().add(e) as *const [T; F]) };
            let mut vd = T::ZERO;
            for k in 0..F {
                vd += v[k] * d[k];
            }
            for (k, g) in dx.iter_mut().enumerate() {
                *g += vd * cur.axis_weight[k][c][i];
            }
        }
    }
}

/// Prefetches the values of columns `c0 .. c0 + f` of rows `p .. p + count`
/// of blocks laid out as `layout` (one hint per cache line of a column-major
/// run; every row for other layouts).
#[inline(always)]
fn prefetch_rows<T, B: AsRef<[T]>>(
    blocks: &[B],
    layout: BlockLayout,
    p: usize,
    count: usize,
    c0: usize,
    f: usize,
) {
    let per_line = 64 / std::mem::size_of::<T>().max(1);
    let step = if layout.row_stride == 1 { per_line } else { 1 };
    let mut q = p;
    while q < p + count {
        let (b, r) = (q / layout.rows, q % layout.rows);
        if let Some(blk) = blocks.get(b) {
            for k in 0..f {
                prefetch(
                    blk.as_ref()
                        .as_ptr()
                        .wrapping_add(r * layout.row_stride + (c0 + k) * layout.col_stride),
                );
            }
        }
        q += step;
    }
    // The run's last row may start a new line.
    if count > 0 && layout.row_stride == 1 {
        let q = p + count - 1;
        let (b, r) = (q / layout.rows, q % layout.rows);
        if let Some(blk) = blocks.get(b) {
            for k in 0..f {
                prefetch(
                    blk.as_ref()
                        .as_ptr()
                        .wrapping_add(r + (c0 + k) * layout.col_stride),
                );
            }
        }
    }
}

/// Cells of a block of up to [`BLOCK`] points in struct-of-arrays form, so that
/// the arithmetic vectorises across points: `index[c][i]` and `weight[c][i]`
/// are corner `c` of point `i`; `axis_weight[k][c][i]` = ∂w_c/∂x_k with
/// [`Weighting::Axes`].
struct BlockCells<T> {
    index: [[u32; BLOCK]; 8],
    weight: [[T; BLOCK]; 8],
    axis_weight: [[[T; BLOCK]; 8]; 3],
}

impl<T: Real> BlockCells<T> {
    fn new() -> Self {
        BlockCells {
            index: [[0; BLOCK]; 8],
            weight: [[T::ZERO; BLOCK]; 8],
            axis_weight: [[[T::ZERO; BLOCK]; 8]; 3],
        }
    }

    /// Locates `xs` (≤ BLOCK points) in `level` and computes their weights
    /// as `weighting` says; lanes past `xs.len()` hold point 0 of the cube
    /// (with direction 0).
    ///
    /// Per axis the weights are [1 − s, s] with s = s(t) (smoothstep) or t
    /// (linear), t the fraction of `pos = x · N`, so their derivatives in x
    /// are ∓s'(t) · N; a clamped coordinate has none. Corner (a, b, e) has
    /// weight w = wx · wy · wz and ∂w/∂x = (wx' wy wz, wx wy' wz, wx wy wz').
    #[inline(always)]
    fn locate(&mut self, level: &LevelInfo, xs: &[[T; 3]], weighting: Weighting<'_, T>) {
        let res = level.resolution;
        let scale = T::from_u32(res);
        let top = res - 1;
        let derivative = !matches!(weighting, Weighting::Value);
        let mut soa = [[T::ZERO; BLOCK]; 3];
        for (i, p) in xs.iter().enumerate() {
            soa[0][i] = p[0];
            soa[1][i] = p[1];
            soa[2][i] = p[2];
        }
        let mut i0 = [[0u32; BLOCK]; 3];
        let mut w0 = [[T::ZERO; BLOCK]; 3];
        let mut w1 = [[T::ZERO; BLOCK]; 3];
        // ∂s/∂x on each axis (the derivative of w1; w0's is its negative).
        let mut d1 = [[T::ZERO; BLOCK]; 3];
        for d in 0..3 {
            for i in 0..BLOCK {
                // `max_cmp` maps NaN to 0, so xc ∈ [0, 1].
                let xc = soa[d][i].max_cmp(T::ZERO).min_cmp(T::ONE);
                let pos = xc * scale;
                // pos ≥ 0, so truncation is the floor.
                // SAFETY: pos ∈ [0, 2^20] (resolutions are at most 2^20).
                let fl = unsafe { pos.to_u32_unchecked() }.min(top);
                let fr = pos - T::from_u32(fl);
                i0[d][i] = fl;
                w1[d][i] = fr;
            }
            if derivative {
                for i in 0..BLOCK {
                    let xd = soa[d][i];
                    let inside = if xd >= T::ZERO && xd <= T::ONE {
                        scale
                    } else {
                        T::ZERO
                    };
                    let t = w1[d][i];
                    d1[d][i] = if level.smoothstep {
                        T::from_f64(6.0) * t * (T::ONE - t) * inside
                    } else {
                        inside
                    };
                }
            }
            if level.smoothstep {
                for w in &mut w1[d] {
                    *w = smoothstep(*w);
                }
            }
            for i in 0..BLOCK {
                w0[d][i] = T::ONE - w1[d][i];
            }
        }
        // The weight of a corner's bit `bit` on axis d, and its derivative.
        let pick = |w0: T, w1: T, bit: usize| if bit == 1 { w1 } else { w0 };
        let slope = |d: T, bit: usize| if bit == 1 { d } else { -d };
        // Corner c's (wx' wy wz, wx wy' wz, wx wy wz') at point i, the axes'
        // slopes of w1 given per axis.
        let partials = |c: usize, i: usize, d: &[[T; BLOCK]; 3]| {
            let (a, b, e) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let wx = pick(w0[0][i], w1[0][i], a);
            let wy = pick(w0[1][i], w1[1][i], b);
            let wz = pick(w0[2][i], w1[2][i], e);
            [
                slope(d[0][i], a) * wy * wz,
                wx * slope(d[1][i], b) * wz,
                wx * wy * slope(d[2][i], e),
            ]
        };
        match weighting {
            Weighting::Value => {
                // weight of corner (a, b, e) = (wx · wy) · wz, in that order.
                for i in 0..BLOCK {
                    let wxy = [
                        w0[0][i] * w0[1][i],
                        w1[0][i] * w0[1][i],
                        w0[0][i] * w1[1][i],
                        w1[0][i] * w1[1][i],
                    ];
                    for c in 0..8 {
                        let wz = if c >> 2 == 1 { w1[2][i] } else { w0[2][i] };
                        self.weight[c][i] = wxy[c & 3] * wz;
                    }
                }
            }
            Weighting::Directional(v) => {
                let mut dv = [[T::ZERO; BLOCK]; 3];
                for (i, vi) in v.iter().enumerate().take(BLOCK) {
                    for d in 0..3 {
                        dv[d][i] = d1[d][i] * vi[d];
                    }
                }
                for c in 0..8 {
                    for i in 0..BLOCK {
                        let [gx, gy, gz] = partials(c, i, &dv);
                        self.weight[c][i] = gx + gy + gz;
                    }
                }
            }
            Weighting::Axes => {
                for c in 0..8 {
                    for i in 0..BLOCK {
                        let g = partials(c, i, &d1);
                        for (k, gk) in g.into_iter().enumerate() {
                            self.axis_weight[k][c][i] = gk;
                        }
                    }
                }
            }
        }
        if level.dense {
            let r = res + 1;
            for c in 0..8 {
                let off =
                    (c & 1) as u32 + ((c >> 1) & 1) as u32 * r + ((c >> 2) & 1) as u32 * r * r;
                for i in 0..BLOCK {
                    self.index[c][i] = i0[0][i] + i0[1][i] * r + i0[2][i] * r * r + off;
                }
            }
        } else {
            let mask = (level.entries - 1) as u32;
            for c in 0..8 {
                let (a, b, e) = ((c & 1) as u32, ((c >> 1) & 1) as u32, ((c >> 2) & 1) as u32);
                for i in 0..BLOCK {
                    let hx = i0[0][i] + a;
                    let hy = (i0[1][i] + b).wrapping_mul(PRIME_Y);
                    let hz = (i0[2][i] + e).wrapping_mul(PRIME_Z);
                    self.index[c][i] = (hx ^ hy ^ hz) & mask;
                }
            }
        }
    }

    /// Prefetches the table entries of the first `n` points. Only the even
    /// corners: the x-neighbour `(i+1) xor h` shares the cache line of `i xor h`
    /// unless `i ≡ 7 (mod 8)`.
    #[inline(always)]
    fn prefetch<U>(&self, base: *const U, f: usize, n: usize) {
        for c in (0..8).step_by(2) {
            for i in 0..n {
                prefetch(base.wrapping_add(self.index[c][i] as usize * f));
            }
        }
    }
}

/// Runs `$obj.$method::<F>(args…)` for the table's feature count `F` (1, 2,
/// 4 or 8: [`HashGrid::layout`] allows no other).
macro_rules! by_features {
    ($f:expr, $obj:ident . $method:ident ( $($arg:expr),* )) => {
        match $f {
            1 => $obj.$method::<1>($($arg),*),
            2 => $obj.$method::<2>($($arg),*),
            4 => $obj.$method::<4>($($arg),*),
            _ => $obj.$method::<8>($($arg),*),
        }
    };
}

/// Defines `$name::<F>(&self, args)`, which runs the level kernel
/// `$generic::<F>` compiled with AVX2 (`$avx2`) where the CPU has it: the
/// same arithmetic, no FMA contraction, so results equal the generic build's.
macro_rules! with_avx2 {
    ($name:ident, $avx2:ident, $generic:ident, $args:ty) => {
        fn $name<const F: usize>(&self, args: $args) {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports the enabled features (checked just above).
                unsafe { self.$avx2::<F>(args) };
                return;
            }
            self.$generic::<F>(args)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn $avx2<const F: usize>(&self, args: $args) {
            self.$generic::<F>(args)
        }
    };
}

/// The arguments of a forward kernel of one level: the level, the points,
/// their weighting, the output blocks, their layout and the first column.
type EncodeArgs<'a, 'b, 'c, T> = (
    usize,
    &'a [[T; 3]],
    Weighting<'a, T>,
    &'b mut [&'c mut [T]],
    BlockLayout,
    usize,
);

/// The arguments of a backward kernel of one level: the level, the points,
/// their weighting, the upstream blocks, their layout, the first column and
/// the level's table gradient.
type ScatterArgs<'a, 'b, T> = (
    usize,
    &'a [[T; 3]],
    Weighting<'a, T>,
    &'a [&'b [T]],
    BlockLayout,
    usize,
    &'a mut [T],
);

/// The arguments of an input-gradient kernel of one level: the level, the
/// points, the upstream block, its layout, the level's first column and the
/// points' gradients.
type InputArgs<'a, T> = (
    usize,
    &'a [[T; 3]],
    &'a [T],
    BlockLayout,
    usize,
    &'a mut [[T; 3]],
);

/// A multi-resolution hash encoding with its parameters.
#[derive(Clone, Debug)]
pub struct HashGrid<T> {
    config: HashGridConfig,
    levels: Vec<LevelInfo>,
    /// All table entries (see the module docs for the layout).
    pub params: Vec<T>,
}

impl<T: Real> HashGrid<T> {
    /// Builds the encoding with entries drawn uniformly from `±init_range` (seeded).
    pub fn new(config: &HashGridConfig, seed: u64) -> Result<Self, FieldError> {
        let levels = Self::layout(config)?;
        let n: usize = levels
            .last()
            .map(|l| l.param_offset + l.entries * config.n_features)
            .unwrap_or(0);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed ^ 0x6861_7368);
        let r = config.init_range as f64;
        let mut params = huge_vec(n);
        for v in params.iter_mut() {
            *v = T::from_f64(rng.random_range(-r..=r));
        }
        Ok(HashGrid {
            config: config.clone(),
            levels,
            params,
        })
    }

    fn layout(c: &HashGridConfig) -> Result<Vec<LevelInfo>, FieldError> {
        let bad = |m: &str| Err(FieldError::InvalidConfig(format!("hash grid: {m}")));
        if c.n_levels == 0 || c.n_levels > 64 {
            return bad("n_levels must be in 1..=64");
        }
        if !matches!(c.n_features, 1 | 2 | 4 | 8) {
            return bad("n_features must be 1, 2, 4 or 8");
        }
        if !(1..=26).contains(&c.log2_table_size) {
            return bad("log2_table_size must be in 1..=26");
        }
        if c.base_resolution == 0 || c.finest_resolution < c.base_resolution {
            return bad("resolutions must satisfy 1 <= base_resolution <= finest_resolution");
        }
        if c.finest_resolution > 1 << 20 {
            return bad("finest_resolution must be <= 2^20");
        }
        if !(c.init_range.is_finite() && c.init_range >= 0.0) {
            return bad("init_range must be finite and >= 0");
        }
        let t = 1usize << c.log2_table_size;
        let growth = if c.n_levels > 1 {
            ((c.finest_resolution as f64).ln() - (c.base_resolution as f64).ln())
                / (c.n_levels - 1) as f64
        } else {
            0.0
        };
        let mut offset = 0;
        let mut levels = Vec::with_capacity(c.n_levels);
        for l in 0..c.n_levels {
            let res = ((c.base_resolution as f64) * (growth * l as f64).exp() + 1e-9).floor();
            let res = (res as u32).clamp(1, c.finest_resolution);
            let verts = (res as usize + 1).pow(3);
            let dense = verts <= t;
            let entries = if dense { verts } else { t };
            levels.push(LevelInfo {
                resolution: res,
                entries,
                param_offset: offset,
                dense,
                smoothstep: c.interpolation == Interpolation::Smoothstep,
            });
            offset += entries * c.n_features;
        }
        Ok(levels)
    }

    /// The settings.
    pub fn config(&self) -> &HashGridConfig {
        &self.config
    }
    /// Geometry of every level.
    pub fn levels(&self) -> &[LevelInfo] {
        &self.levels
    }
    /// Number of outputs per point (`L · F`).
    pub fn n_outputs(&self) -> usize {
        self.config.n_levels * self.config.n_features
    }
    /// Number of parameters.
    pub fn n_params(&self) -> usize {
        self.params.len()
    }
    /// Edge length of a cell of `level`, in units of the unit cube.
    pub fn cell_size(&self, level: usize) -> f64 {
        1.0 / self.levels[level].resolution as f64
    }

    /// Encodes `x` (points of `[0,1]³`; outside points are clamped to the cube)
    /// into `out`: row `p` starts at `p · stride + col`, level `l` feature `f`
    /// is written at `+ l·F + f`. Levels `≥ active_levels` output 0.
    /// Runs on the calling thread, looping level-major over the points.
    pub fn encode(
        &self,
        x: &[[T; 3]],
        out: &mut [T],
        stride: usize,
        col: usize,
        active_levels: usize,
    ) {
        assert!(col + self.n_outputs() <= stride, "encode: stride too small");
        assert!(out.len() >= x.len().saturating_sub(1) * stride + col + self.n_outputs());
        let layout = BlockLayout::row_major(x.len().max(1), stride);
        for l in 0..self.levels.len() {
            self.encode_level_blocks(l, x, &mut [&mut *out], layout, col, l < active_levels);
        }
    }

    /// Encodes all points `x` into blocks of rows laid out as `layout`
    /// (columns as in [`HashGrid::encode_level_blocks`]), level-major: every
    /// point visits level 0, then level 1, …, so that one level's table stays
    /// in the cache. Parallel (rayon) over groups of blocks within a level;
    /// each value is computed independently, so results do not depend on
    /// the thread count.
    pub fn encode_blocks(
        &self,
        x: &[[T; 3]],
        out_blocks: &mut [&mut [T]],
        layout: BlockLayout,
        col: usize,
        active_levels: usize,
    ) {
        self.encode_blocks_weighted(x, Weighting::Value, out_blocks, layout, col, active_levels)
    }

    /// The directional derivative of the encoding, `(∂ encoding / ∂x)(x_p) · v_p`
    /// (the encoding's rate of change along `v_p`, encoder coordinates), into
    /// blocks of rows as [`HashGrid::encode_blocks`] writes the encoding.
    /// Levels `≥ active_levels` give 0, as do clamped coordinates. With `v`
    /// the three axes in turn, this is the encoding's Jacobian, the
    /// forward-mode counterpart of [`HashGrid::backward_input`].
    pub fn encode_directional_blocks(
        &self,
        x: &[[T; 3]],
        v: &[[T; 3]],
        out_blocks: &mut [&mut [T]],
        layout: BlockLayout,
        col: usize,
        active_levels: usize,
    ) {
        assert_eq!(x.len(), v.len(), "encode_directional: directions");
        let weighting = Weighting::Directional(v);
        self.encode_blocks_weighted(x, weighting, out_blocks, layout, col, active_levels)
    }

    /// [`HashGrid::encode_directional_blocks`] into one row-major buffer:
    /// row `p` of `out` ([`HashGrid::n_outputs`] values a row).
    pub fn encode_directional(
        &self,
        x: &[[T; 3]],
        v: &[[T; 3]],
        active_levels: usize,
        out: &mut [T],
    ) {
        let layout = self.one_row_major_block(x.len(), out.len(), "encode_directional: output");
        self.encode_directional_blocks(x, v, &mut [out], layout, 0, active_levels)
    }

    fn encode_blocks_weighted(
        &self,
        x: &[[T; 3]],
        weighting: Weighting<'_, T>,
        out_blocks: &mut [&mut [T]],
        layout: BlockLayout,
        col: usize,
        active_levels: usize,
    ) {
        assert!(layout.rows > 0, "encode: empty blocks");
        let n_blocks = x.len().div_ceil(layout.rows);
        assert!(out_blocks.len() >= n_blocks, "encode: too few blocks");
        let group = (ENCODE_TASK_POINTS / layout.rows).max(1);
        for l in 0..self.levels.len() {
            out_blocks[..n_blocks]
                .par_chunks_mut(group)
                .enumerate()
                .for_each(|(g, outs)| {
                    let start = g * group * layout.rows;
                    let end = (start + outs.len() * layout.rows).min(x.len());
                    self.encode_level_weighted(
                        l,
                        &x[start..end],
                        weighting.range(start..end),
                        outs,
                        layout,
                        col,
                        l < active_levels,
                    );
                });
        }
    }

    /// Encodes level `level` of the points `x` into blocks of rows laid out as
    /// `layout` (point `p` is row `p mod layout.rows` of block `p / layout.rows`);
    /// feature `f` goes to column `col + level·F + f`. With `active == false`
    /// the level outputs 0 (coarse-to-fine training). Runs on the calling thread.
    ///
    /// Called level after level over a large batch, this keeps one level's
    /// table in the cache while all points visit it.
    pub fn encode_level_blocks(
        &self,
        level: usize,
        x: &[[T; 3]],
        out_blocks: &mut [&mut [T]],
        layout: BlockLayout,
        col: usize,
        active: bool,
    ) {
        self.encode_level_weighted(level, x, Weighting::Value, out_blocks, layout, col, active)
    }

    #[allow(clippy::too_many_arguments)]
    fn encode_level_weighted(
        &self,
        level: usize,
        x: &[[T; 3]],
        weighting: Weighting<'_, T>,
        out_blocks: &mut [&mut [T]],
        layout: BlockLayout,
        col: usize,
        active: bool,
    ) {
        let f = self.config.n_features;
        assert!(level < self.levels.len(), "encode: level out of range");
        assert!(layout.rows > 0, "encode: empty blocks");
        assert!(
            out_blocks.len() * layout.rows >= x.len(),
            "encode: too few blocks"
        );
        let c0 = col + level * f;
        for (b, blk) in out_blocks.iter().enumerate() {
            let rows = layout.rows.min(x.len().saturating_sub(b * layout.rows));
            if rows > 0 {
                assert!(
                    blk.len() > layout.last_offset(rows, c0 + f - 1),
                    "encode: output block {b} too small"
                );
            }
        }
        if !active {
            let mut p = 0;
            for blk in out_blocks.iter_mut() {
                for r in 0..layout.rows.min(x.len() - p.min(x.len())) {
                    for k in 0..f {
                        blk[r * layout.row_stride + (c0 + k) * layout.col_stride] = T::ZERO;
                    }
                }
                p += layout.rows;
            }
            return;
        }
        let args = (level, x, weighting, out_blocks, layout, c0);
        by_features!(f, self.encode_level_f(args))
    }

    with_avx2!(
        encode_level_f,
        encode_level_avx2,
        encode_level_generic,
        EncodeArgs<'_, '_, '_, T>
    );

    /// The forward kernel of one level (sizes checked by the caller).
    #[inline(always)]
    fn encode_level_generic<const F: usize>(&self, args: EncodeArgs<'_, '_, '_, T>) {
        let (level, x, weighting, out_blocks, layout, c0) = args;
        let level = &self.levels[level];
        let table = &self.params[level.param_offset..level.param_offset + level.entries * F];
        walk_level::<T, F>(
            level,
            x,
            weighting,
            table.as_ptr(),
            layout.rows,
            &mut Gather::<T, F> {
                table,
                out_blocks,
                layout,
                c0,
            },
        );
    }

    /// Accumulates table gradients: `grad += Σ_p (d out_p / d params)ᵀ · d_out_p`.
    ///
    /// The upstream gradients come in blocks (`d_out_blocks[b]` holds rows
    /// `b·block_rows ..`, row `r` at `r · stride + col`), so that callers can
    /// pass per-chunk buffers without copying. Level-parallel (see module docs).
    #[allow(clippy::too_many_arguments)]
    pub fn backward_params(
        &self,
        x: &[[T; 3]],
        d_out_blocks: &[&[T]],
        block_rows: usize,
        stride: usize,
        col: usize,
        active_levels: usize,
        grad: &mut [T],
    ) {
        self.backward_params_blocks(
            x,
            d_out_blocks,
            BlockLayout::row_major(block_rows, stride),
            col,
            active_levels,
            grad,
        )
    }

    /// [`HashGrid::backward_params`] for upstream gradients in blocks of any
    /// [`BlockLayout`] (level `l` feature `f` of a row in column `col + l·F + f`).
    pub fn backward_params_blocks(
        &self,
        x: &[[T; 3]],
        d_out_blocks: &[&[T]],
        layout: BlockLayout,
        col: usize,
        active_levels: usize,
        grad: &mut [T],
    ) {
        let weighting = Weighting::Value;
        self.backward_params_weighted(x, weighting, d_out_blocks, layout, col, active_levels, grad)
    }

    /// Backward pass of [`HashGrid::encode_directional_blocks`] with respect
    /// to the table: accumulates `grad[entry] += (∂w_c/∂x · v_p) · d_out_p`
    /// for each corner `c` of each point, the upstream gradients in blocks
    /// as [`HashGrid::backward_params_blocks`] reads them. The directional
    /// derivative is linear in the table, so this is its exact gradient;
    /// level-parallel, bit-identical for any thread count.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_params_directional_blocks(
        &self,
        x: &[[T; 3]],
        v: &[[T; 3]],
        d_out_blocks: &[&[T]],
        layout: BlockLayout,
        col: usize,
        active_levels: usize,
        grad: &mut [T],
    ) {
        assert_eq!(x.len(), v.len(), "backward_params_directional: directions");
        let weighting = Weighting::Directional(v);
        self.backward_params_weighted(x, weighting, d_out_blocks, layout, col, active_levels, grad)
    }

    /// [`HashGrid::backward_params_directional_blocks`] for upstream
    /// gradients in one row-major buffer (as [`HashGrid::encode_directional`]
    /// writes its output).
    pub fn backward_params_directional(
        &self,
        x: &[[T; 3]],
        v: &[[T; 3]],
        d_out: &[T],
        active_levels: usize,
        grad: &mut [T],
    ) {
        let layout =
            self.one_row_major_block(x.len(), d_out.len(), "backward_params_directional: d_out");
        self.backward_params_directional_blocks(x, v, &[d_out], layout, 0, active_levels, grad)
    }

    #[allow(clippy::too_many_arguments)]
    fn backward_params_weighted(
        &self,
        x: &[[T; 3]],
        weighting: Weighting<'_, T>,
        d_out_blocks: &[&[T]],
        layout: BlockLayout,
        col: usize,
        active_levels: usize,
        grad: &mut [T],
    ) {
        assert_eq!(
            grad.len(),
            self.params.len(),
            "backward_params: grad length"
        );
        self.check_blocks(x.len(), d_out_blocks, layout, col);
        let f = self.config.n_features;
        // Split the gradient into disjoint per-level slices.
        let mut slices: Vec<(usize, &mut [T])> = Vec::with_capacity(self.levels.len());
        let mut rest = grad;
        for (l, level) in self.levels.iter().enumerate() {
            let (head, tail) = rest.split_at_mut(level.entries * f);
            slices.push((l, head));
            rest = tail;
        }
        slices
            .into_par_iter()
            .filter(|(l, _)| *l < active_levels)
            .for_each(|(l, g)| {
                let args = (l, x, weighting, d_out_blocks, layout, col, g);
                by_features!(f, self.backward_level(args))
            });
    }

    /// The layout of one row-major block of `n` rows of the whole encoding,
    /// after checking that the buffer holding it (`len` values) has exactly
    /// that size (`what` names the buffer in the panic message).
    fn one_row_major_block(&self, n: usize, len: usize, what: &str) -> BlockLayout {
        let n_out = self.n_outputs();
        assert_eq!(len, n * n_out, "{what} length");
        BlockLayout::row_major(n.max(1), n_out)
    }

    /// Checks that `blocks` hold the encoding columns of `n` rows laid out as `layout`.
    fn check_blocks(&self, n: usize, blocks: &[&[T]], layout: BlockLayout, col: usize) {
        assert!(layout.rows > 0, "hash grid: empty blocks");
        assert!(blocks.len() * layout.rows >= n, "hash grid: too few blocks");
        let last_col = col + self.n_outputs() - 1;
        for (b, blk) in blocks.iter().enumerate() {
            let rows = layout.rows.min(n.saturating_sub(b * layout.rows));
            if rows > 0 {
                assert!(
                    blk.len() > layout.last_offset(rows, last_col),
                    "hash grid: block {b} too small"
                );
            }
        }
    }

    with_avx2!(
        backward_level,
        backward_level_avx2,
        backward_level_generic,
        ScatterArgs<'_, '_, T>
    );

    /// The table-gradient kernel of one level (sizes checked by the caller).
    #[inline(always)]
    fn backward_level_generic<const F: usize>(&self, args: ScatterArgs<'_, '_, T>) {
        let (l, x, weighting, d_out_blocks, layout, col, g) = args;
        let level = &self.levels[l];
        let c0 = col + l * F;
        walk_level::<T, F>(
            level,
            x,
            weighting,
            g.as_ptr(),
            layout.rows,
            &mut Scatter::<T, F> {
                g,
                d_out_blocks,
                layout,
                c0,
            },
        );
    }

    /// The alternative scheme, kept for the benchmark's comparison: the points
    /// are cut into `parts` contiguous ranges, each range accumulates into its
    /// own full-size buffer (`scratch`, resized to `parts` buffers), and the
    /// buffers are added to `grad` in order. Deterministic for a fixed `parts`,
    /// but it zeroes and reduces `parts` table-sized buffers per call, which
    /// the level-parallel [`HashGrid::backward_params`] avoids.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_params_per_part_buffers(
        &self,
        x: &[[T; 3]],
        d_out_blocks: &[&[T]],
        block_rows: usize,
        stride: usize,
        col: usize,
        active_levels: usize,
        parts: usize,
        scratch: &mut Vec<Vec<T>>,
        grad: &mut [T],
    ) {
        assert_eq!(grad.len(), self.params.len());
        let parts = parts.max(1);
        scratch.resize_with(parts, Vec::new);
        let per = x.len().div_ceil(parts).div_ceil(block_rows) * block_rows;
        let layout = BlockLayout::row_major(block_rows, stride);
        self.check_blocks(x.len(), d_out_blocks, layout, col);
        let f = self.config.n_features;
        scratch.par_iter_mut().enumerate().for_each(|(i, buf)| {
            if buf.len() != self.params.len() {
                *buf = huge_vec(self.params.len());
            } else {
                buf.fill(T::ZERO);
            }
            let start = (i * per).min(x.len());
            let end = ((i + 1) * per).min(x.len());
            let blocks = &d_out_blocks[start / block_rows..end.div_ceil(block_rows)];
            let xs = &x[start..end];
            let mut rest: &mut [T] = buf;
            for (l, level) in self.levels.iter().enumerate() {
                let (head, tail) = rest.split_at_mut(level.entries * f);
                rest = tail;
                if l >= active_levels {
                    continue;
                }
                let args = (l, xs, Weighting::Value, blocks, layout, col, head);
                by_features!(f, self.backward_level(args))
            }
        });
        const RED: usize = 1 << 16;
        grad.par_chunks_mut(RED).enumerate().for_each(|(c, g)| {
            for buf in scratch.iter() {
                for (gv, &b) in g.iter_mut().zip(&buf[c * RED..]) {
                    *gv += b;
                }
            }
        });
    }

    /// Accumulates gradients w.r.t. the input points:
    /// `d_x[p] += (d out_p / d x_p)ᵀ · d_out_p` (rows as in [`HashGrid::encode`]).
    /// Coordinates outside `[0,1]` get no gradient (they are clamped).
    pub fn backward_input(
        &self,
        x: &[[T; 3]],
        d_out: &[T],
        stride: usize,
        col: usize,
        active_levels: usize,
        d_x: &mut [[T; 3]],
    ) {
        let layout = BlockLayout::row_major(x.len().max(1), stride);
        self.backward_input_block(x, d_out, layout, col, active_levels, d_x)
    }

    /// [`HashGrid::backward_input`] for upstream gradients in one block of rows
    /// laid out as `layout` (`layout.rows ≥ x.len()`).
    pub fn backward_input_block(
        &self,
        x: &[[T; 3]],
        d_out: &[T],
        layout: BlockLayout,
        col: usize,
        active_levels: usize,
        d_x: &mut [[T; 3]],
    ) {
        assert_eq!(x.len(), d_x.len());
        assert!(layout.rows >= x.len(), "backward_input: one block of rows");
        self.check_blocks(x.len(), &[d_out], layout, col);
        let f = self.config.n_features;
        for l in 0..active_levels.min(self.levels.len()) {
            let args = (l, x, d_out, layout, col + l * f, &mut *d_x);
            by_features!(f, self.input_level(args))
        }
    }

    with_avx2!(
        input_level,
        input_level_avx2,
        input_level_generic,
        InputArgs<'_, T>
    );

    /// The input-gradient kernel of one level (sizes checked by the caller).
    #[inline(always)]
    fn input_level_generic<const F: usize>(&self, args: InputArgs<'_, T>) {
        let (l, x, d_out, layout, c0, d_x) = args;
        let level = &self.levels[l];
        let table = &self.params[level.param_offset..level.param_offset + level.entries * F];
        walk_level::<T, F>(
            level,
            x,
            Weighting::Axes,
            table.as_ptr(),
            layout.rows,
            &mut InputGradient::<T, F> {
                table,
                d_out,
                layout,
                c0,
                d_x,
            },
        );
    }
}
