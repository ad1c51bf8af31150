//! An occupancy grid over the bounding cube [−1, 1]³ of the unit sphere, for
//! skipping empty space.
//!
//! Each cell keeps the SDF value last measured at its centre. With the cell
//! half-diagonal r_c, a bound L on |∇φ| and the current NeuS sharpness s, a
//! cell is classified as
//!
//! - **surface** when |φ(centre)| ≤ band = L·r_c + tail/s + margin: the zero
//!   level set can be in the cell, or close enough for the NeuS weights
//!   (which fall off like e^(−s|φ|)) to be non-negligible;
//! - **inside** when φ(centre) < −band: entirely inside the object. A ray
//!   that reaches such a cell is opaque from there on (its transmittance
//!   was exhausted at the surface, or the ray starts inside the object,
//!   where NeuS alpha is 1), so marching stops after it;
//! - **empty** otherwise.
//!
//! Cells entirely outside the unit sphere are never evaluated (rays are
//! clipped to the sphere). The grid is refreshed from a batched SDF closure,
//! either fully or partially: a partial refresh re-measures every surface
//! cell and its 6-neighbours plus a rotating 1/stride subset of all cells
//! (the SDF-grid analogue of Instant-NGP's decaying density-grid updates),
//! so the surface may move by about a cell (plus the band's margin) between
//! two refreshes without being missed.

use rayon::prelude::*;

use crate::error::{RenderError, check};

/// Edge length, in cells, of the blocks the march skips at once.
const BLOCK: usize = 4;

/// ⌊x⌋ as an integer (saturating), without a libm call: on baseline x86-64
/// `f32::floor` is not inlined, and it dominated the march.
#[inline(always)]
fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) > x { i - 1 } else { i }
}

/// Settings of the occupancy grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OccupancySettings {
    /// Cells per axis of the grid over [−1, 1]³.
    pub resolution: usize,
    /// Assumed bound L on |∇φ| (an exact SDF has 1; learned fields drift).
    pub lipschitz: f32,
    /// NeuS weights are taken as negligible where s·|φ| > tail (e^(−10) ≈ 5e-5 for 10).
    pub tail: f32,
    /// Extra band width in SDF units (covers surface motion between refreshes).
    pub margin: f32,
}

impl Default for OccupancySettings {
    fn default() -> Self {
        Self {
            resolution: 128,
            lipschitz: 1.5,
            tail: 10.0,
            margin: 0.005,
        }
    }
}

/// How much of the grid a refresh re-measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefreshMode {
    /// Every cell that meets the unit sphere.
    Full,
    /// Every surface cell and its 6-neighbours, plus the cells whose index ≡
    /// round (mod stride).
    Partial {
        /// 1/stride of the empty cells is re-measured per refresh.
        stride: u32,
    },
}

/// The state of one grid cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellState {
    /// No surface near: skipped by the sampler.
    Empty,
    /// The surface can be in or near the cell: sampled.
    Surface,
    /// Entirely inside the object: sampled, and marching stops after it.
    Inside,
}

/// Everything a grid's classification depends on besides its settings: the
/// stored SDF values, the band they were classified with and the refresh
/// counter. Saved with a training checkpoint, it restores a grid
/// ([`OccupancyGrid::restore`]) that classifies, marches and refreshes
/// bit-identically to the original.
#[derive(Clone, Debug, PartialEq)]
pub struct OccupancySnapshot {
    /// Cells per axis of the grid the values come from.
    pub resolution: usize,
    /// SDF last measured at each cell centre, `resolution³` values in the
    /// grid's linear cell order ([`OccupancyGrid::cell_index`]); cells
    /// outside the unit sphere hold +∞.
    pub sdf: Vec<f32>,
    /// The band the classification used (+∞ before the first refresh).
    pub band: f32,
    /// Number of refreshes done (drives the partial-refresh rotation).
    pub round: u64,
}

/// The occupancy grid (see the module docs).
#[derive(Clone, Debug)]
pub struct OccupancyGrid {
    settings: OccupancySettings,
    /// SDF last measured at each cell centre (+∞ for cells outside the sphere).
    sdf: Vec<f32>,
    /// Whether each cell meets the unit sphere.
    in_sphere: Vec<bool>,
    /// Bit set of surface cells.
    surface: Vec<u64>,
    /// Bit set of inside cells.
    inside: Vec<u64>,
    /// Per block of BLOCK³ cells: whether any cell in it is sampled (lets
    /// the march cross empty blocks in one step).
    block_sampled: Vec<bool>,
    /// The band the bits were computed with.
    band: f32,
    /// Number of refreshes done (drives the partial-refresh rotation).
    round: u64,
    /// Scratch: cell indices and centres of a refresh.
    scratch_index: Vec<u32>,
    scratch_mark: Vec<bool>,
    scratch_pos: Vec<[f32; 3]>,
    scratch_sdf: Vec<f32>,
}

impl OccupancyGrid {
    /// A grid with every cell inside the sphere marked as surface (nothing is
    /// skipped until the first refresh).
    pub fn new(settings: OccupancySettings) -> Result<Self, RenderError> {
        let r = settings.resolution;
        check(
            (2..=1024).contains(&r),
            "resolution",
            r,
            "must be in 2..=1024",
        )?;
        check(
            settings.lipschitz.is_finite() && settings.lipschitz >= 1.0,
            "lipschitz",
            settings.lipschitz,
            "must be finite and ≥ 1",
        )?;
        check(
            settings.tail.is_finite() && settings.tail > 0.0,
            "tail",
            settings.tail,
            "must be finite and > 0",
        )?;
        check(
            settings.margin.is_finite() && settings.margin >= 0.0,
            "margin",
            settings.margin,
            "must be finite and ≥ 0",
        )?;
        let n = r * r * r;
        let h = 2.0 / r as f32;
        let mut in_sphere = vec![false; n];
        let mut sdf = vec![f32::INFINITY; n];
        for (i, (flag, v)) in in_sphere.iter_mut().zip(&mut sdf).enumerate() {
            let c = [i % r, (i / r) % r, i / (r * r)];
            // Distance from the origin to the nearest point of the cell.
            let mut d2 = 0.0f32;
            for &ci in &c {
                let lo = -1.0 + ci as f32 * h;
                let hi = lo + h;
                let nearest = 0.0f32.clamp(lo, hi);
                d2 += nearest * nearest;
            }
            if d2 <= 1.0 {
                *flag = true;
                *v = 0.0;
            }
        }
        let words = n.div_ceil(64);
        let mut grid = Self {
            settings,
            sdf,
            in_sphere,
            surface: vec![0; words],
            inside: vec![0; words],
            block_sampled: vec![true; r.div_ceil(BLOCK).pow(3)],
            band: f32::INFINITY,
            round: 0,
            scratch_index: Vec::new(),
            scratch_mark: Vec::new(),
            scratch_pos: Vec::new(),
            scratch_sdf: Vec::new(),
        };
        grid.classify(f32::INFINITY);
        Ok(grid)
    }

    /// The settings.
    pub fn settings(&self) -> &OccupancySettings {
        &self.settings
    }

    /// Cells per axis.
    pub fn resolution(&self) -> usize {
        self.settings.resolution
    }

    /// Edge length of a cell.
    pub fn cell_size(&self) -> f32 {
        2.0 / self.settings.resolution as f32
    }

    /// The band for sharpness `s`: L·r_c + tail/s + margin (module docs).
    pub fn band(&self, s: f32) -> f32 {
        let half_diagonal = 0.5 * 3f32.sqrt() * self.cell_size();
        self.settings.lipschitz * half_diagonal
            + self.settings.tail / s.max(1e-6)
            + self.settings.margin
    }

    /// The band the current classification used.
    pub fn current_band(&self) -> f32 {
        self.band
    }

    /// Linear index of cell (x, y, z).
    #[inline]
    pub fn cell_index(&self, x: usize, y: usize, z: usize) -> usize {
        let r = self.settings.resolution;
        x + r * (y + r * z)
    }

    /// Centre of the cell with linear index `i`.
    pub fn cell_center(&self, i: usize) -> [f32; 3] {
        let r = self.settings.resolution;
        let h = self.cell_size();
        [i % r, (i / r) % r, i / (r * r)].map(|c| -1.0 + (c as f32 + 0.5) * h)
    }

    /// State of the cell with linear index `i`.
    #[inline]
    pub fn state(&self, i: usize) -> CellState {
        let (w, b) = (i / 64, 1u64 << (i % 64));
        if self.surface[w] & b != 0 {
            CellState::Surface
        } else if self.inside[w] & b != 0 {
            CellState::Inside
        } else {
            CellState::Empty
        }
    }

    /// State of the cell containing point `p` (Empty outside the cube).
    pub fn state_at(&self, p: [f32; 3]) -> CellState {
        let r = self.settings.resolution;
        let h = self.cell_size();
        let mut c = [0usize; 3];
        for (ci, &x) in c.iter_mut().zip(&p) {
            let f = ((x + 1.0) / h).floor();
            if !(f >= 0.0 && f < r as f32) {
                return CellState::Empty;
            }
            *ci = f as usize;
        }
        self.state(self.cell_index(c[0], c[1], c[2]))
    }

    /// Number of cells per state: (surface, inside, empty-in-sphere).
    pub fn counts(&self) -> (usize, usize, usize) {
        let surface: usize = self.surface.iter().map(|w| w.count_ones() as usize).sum();
        let inside: usize = self.inside.iter().map(|w| w.count_ones() as usize).sum();
        let in_sphere = self.in_sphere.iter().filter(|&&b| b).count();
        (surface, inside, in_sphere - surface - inside)
    }

    /// Fraction of the in-sphere cells that are sampled (surface or inside).
    pub fn occupied_fraction(&self) -> f32 {
        let (s, i, e) = self.counts();
        (s + i) as f32 / (s + i + e).max(1) as f32
    }

    /// The SDF value last measured at each cell centre, in linear cell order
    /// (+∞ for cells outside the unit sphere, 0 before the first refresh).
    pub fn sdf_values(&self) -> &[f32] {
        &self.sdf
    }

    /// Number of refreshes done so far (drives the partial-refresh rotation).
    pub fn refresh_round(&self) -> u64 {
        self.round
    }

    /// A copy of the state a checkpoint needs to restore this grid exactly.
    pub fn snapshot(&self) -> OccupancySnapshot {
        OccupancySnapshot {
            resolution: self.settings.resolution,
            sdf: self.sdf.clone(),
            band: self.band,
            round: self.round,
        }
    }

    /// Restores the SDF values, band and refresh counter of `snapshot` and
    /// reclassifies with the saved band, so the grid classifies, marches and
    /// refreshes exactly as the grid the snapshot was taken from (given the
    /// same settings). Values of cells outside the unit sphere are ignored.
    ///
    /// # Errors
    /// If the resolution or the number of values does not match this grid,
    /// an in-sphere value is not finite, or the band is NaN or negative; the
    /// grid is then left unchanged.
    pub fn restore(&mut self, snapshot: &OccupancySnapshot) -> Result<(), RenderError> {
        check(
            snapshot.resolution == self.settings.resolution,
            "occupancy snapshot resolution",
            snapshot.resolution,
            "differs from this grid's resolution",
        )?;
        self.set_sdf_values(&snapshot.sdf, snapshot.band, snapshot.round)
    }

    /// Sets the stored SDF values (in linear cell order, `resolution³` of
    /// them), the band and the refresh counter, then reclassifies every cell
    /// with `band` (use [`Self::band`] of the current sharpness when the
    /// saved band is not at hand; [`Self::reclassify`] can change it later).
    ///
    /// # Errors
    /// As [`Self::restore`]; the grid is then left unchanged.
    pub fn set_sdf_values(
        &mut self,
        values: &[f32],
        band: f32,
        round: u64,
    ) -> Result<(), RenderError> {
        check(
            values.len() == self.sdf.len(),
            "occupancy sdf values",
            values.len(),
            "count must be resolution³ of this grid",
        )?;
        if let Some(i) = (0..values.len()).find(|&i| self.in_sphere[i] && !values[i].is_finite()) {
            return Err(RenderError::InvalidSetting {
                name: "occupancy sdf values",
                value: format!("{} at cell {i}", values[i]),
                reason: "cells inside the unit sphere must hold finite values",
            });
        }
        check(
            band >= 0.0,
            "occupancy band",
            band,
            "must be ≥ 0 (or +∞), not NaN",
        )?;
        for ((dst, &v), &inside) in self.sdf.iter_mut().zip(values).zip(&self.in_sphere) {
            *dst = if inside { v } else { f32::INFINITY };
        }
        self.round = round;
        self.classify(band);
        Ok(())
    }

    /// Re-measures cells with `sdf_fn` (which fills φ for a batch of
    /// points; called with batches of at most 65536 points, in a fixed order)
    /// and reclassifies every cell for sharpness `s`. Returns the number of
    /// cells measured.
    pub fn refresh<F>(&mut self, mut sdf_fn: F, s: f32, mode: RefreshMode) -> usize
    where
        F: FnMut(&[[f32; 3]], &mut [f32]),
    {
        const BATCH: usize = 1 << 16;
        let n = self.sdf.len();
        self.scratch_index.clear();
        match mode {
            RefreshMode::Full => {
                self.scratch_index
                    .extend((0..n as u32).filter(|&i| self.in_sphere[i as usize]));
            }
            RefreshMode::Partial { stride } => {
                let stride = stride.max(1) as u64;
                let phase = self.round % stride;
                let r = self.settings.resolution;
                // Surface cells and their 6-neighbours (the surface moves by
                // less than a cell between refreshes), plus a rotating subset.
                self.scratch_mark.clear();
                self.scratch_mark.resize(n, false);
                let surface_cells = self.surface.iter().enumerate().flat_map(|(w, &bits)| {
                    let mut bits = bits;
                    std::iter::from_fn(move || {
                        (bits != 0).then(|| {
                            let i = w * 64 + bits.trailing_zeros() as usize;
                            bits &= bits - 1;
                            i
                        })
                    })
                });
                for i in surface_cells {
                    self.scratch_mark[i] = true;
                    let (x, y, z) = (i % r, (i / r) % r, i / (r * r));
                    if x > 0 {
                        self.scratch_mark[i - 1] = true;
                    }
                    if x + 1 < r {
                        self.scratch_mark[i + 1] = true;
                    }
                    if y > 0 {
                        self.scratch_mark[i - r] = true;
                    }
                    if y + 1 < r {
                        self.scratch_mark[i + r] = true;
                    }
                    if z > 0 {
                        self.scratch_mark[i - r * r] = true;
                    }
                    if z + 1 < r {
                        self.scratch_mark[i + r * r] = true;
                    }
                }
                for i in 0..n {
                    if self.in_sphere[i] && (self.scratch_mark[i] || i as u64 % stride == phase) {
                        self.scratch_index.push(i as u32);
                    }
                }
            }
        }
        self.round += 1;
        let count = self.scratch_index.len();
        for start in (0..count).step_by(BATCH) {
            let end = (start + BATCH).min(count);
            self.scratch_pos.clear();
            for &i in &self.scratch_index[start..end] {
                let c = self.cell_center(i as usize);
                self.scratch_pos.push(c);
            }
            self.scratch_sdf.clear();
            self.scratch_sdf.resize(end - start, 0.0);
            sdf_fn(&self.scratch_pos, &mut self.scratch_sdf);
            for (&i, &v) in self.scratch_index[start..end].iter().zip(&self.scratch_sdf) {
                // A non-finite SDF value keeps the cell sampled.
                self.sdf[i as usize] = if v.is_finite() { v } else { 0.0 };
            }
        }
        self.classify(self.band(s));
        count
    }

    /// Reclassifies every cell from the stored SDF values for sharpness `s`
    /// (cheap; use when s changed but the field did not).
    pub fn reclassify(&mut self, s: f32) {
        self.classify(self.band(s));
    }

    fn classify(&mut self, band: f32) {
        self.band = band;
        let sdf = &self.sdf;
        let in_sphere = &self.in_sphere;
        self.surface
            .par_iter_mut()
            .zip(self.inside.par_iter_mut())
            .enumerate()
            .for_each(|(w, (surf, ins))| {
                let (mut s_bits, mut i_bits) = (0u64, 0u64);
                for b in 0..64 {
                    let i = w * 64 + b;
                    if i >= sdf.len() || !in_sphere[i] {
                        continue;
                    }
                    let v = sdf[i];
                    if v.abs() <= band {
                        s_bits |= 1 << b;
                    } else if v < -band {
                        i_bits |= 1 << b;
                    }
                }
                *surf = s_bits;
                *ins = i_bits;
            });
        let r = self.settings.resolution;
        let rb = r.div_ceil(BLOCK);
        self.block_sampled.iter_mut().for_each(|b| *b = false);
        for (w, (&sw, &iw)) in self.surface.iter().zip(&self.inside).enumerate() {
            let mut bits = sw | iw;
            while bits != 0 {
                let i = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let (x, y, z) = (i % r, (i / r) % r, i / (r * r));
                self.block_sampled[x / BLOCK + rb * (y / BLOCK + rb * (z / BLOCK))] = true;
            }
        }
    }

    /// Walks the cells that ray o + t·d crosses for t in [near, far]
    /// (3D-DDA), calling `visit(t_enter, t_exit, state)` in order until it
    /// returns false. Blocks of 4³ cells without a sampled cell are crossed
    /// in one visit (reported as [`CellState::Empty`]).
    pub fn march(
        &self,
        o: [f32; 3],
        d: [f32; 3],
        near: f32,
        far: f32,
        mut visit: impl FnMut(f32, f32, CellState) -> bool,
    ) {
        if !matches!(far.partial_cmp(&near), Some(std::cmp::Ordering::Greater)) {
            return;
        }
        let r = self.settings.resolution as i32;
        let rb = self.settings.resolution.div_ceil(BLOCK);
        let h = self.cell_size();
        let b = BLOCK as i32;
        let mut cell = [0i32; 3];
        let mut t_next = [f32::INFINITY; 3];
        let mut t_delta = [f32::INFINITY; 3];
        let mut step = [0i32; 3];
        for a in 0..3 {
            let p = o[a] + d[a] * near;
            cell[a] = floor_i32((p + 1.0) / h).clamp(0, r - 1);
            if d[a] > 0.0 {
                step[a] = 1;
                t_delta[a] = h / d[a];
            } else if d[a] < 0.0 {
                step[a] = -1;
                t_delta[a] = -h / d[a];
            }
        }
        // Time at which the ray leaves cell index c along axis a.
        let boundary = |a: usize, c: i32| -> f32 {
            match step[a] {
                1 => (-1.0 + (c + 1) as f32 * h - o[a]) / d[a],
                -1 => (-1.0 + c as f32 * h - o[a]) / d[a],
                _ => f32::INFINITY,
            }
        };
        for a in 0..3 {
            t_next[a] = boundary(a, cell[a]);
        }
        let mut t = near;
        loop {
            let blk = cell.map(|c| c / b);
            let bi = blk[0] as usize + rb * (blk[1] as usize + rb * blk[2] as usize);
            if !self.block_sampled[bi] {
                // Cross the whole empty block at once.
                let mut axis = 0;
                let mut t_exit = f32::INFINITY;
                for a in 0..3 {
                    let edge = match step[a] {
                        1 => ((blk[a] + 1) * b).min(r) - 1,
                        -1 => blk[a] * b,
                        _ => continue,
                    };
                    let te = boundary(a, edge);
                    if te < t_exit {
                        t_exit = te;
                        axis = a;
                    }
                }
                let t_exit = t_exit.min(far).max(t);
                if !visit(t, t_exit, CellState::Empty) || t_exit >= far {
                    return;
                }
                t = t_exit;
                for a in 0..3 {
                    if a == axis {
                        cell[a] = if step[a] > 0 {
                            ((blk[a] + 1) * b).min(r)
                        } else {
                            blk[a] * b - 1
                        };
                    } else {
                        let lo = blk[a] * b;
                        let hi = ((blk[a] + 1) * b).min(r) - 1;
                        let p = o[a] + d[a] * t;
                        cell[a] = floor_i32((p + 1.0) / h).clamp(lo, hi);
                    }
                }
                if cell[axis] < 0 || cell[axis] >= r {
                    return;
                }
                for a in 0..3 {
                    t_next[a] = boundary(a, cell[a]);
                }
                continue;
            }
            let axis = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
                0
            } else if t_next[1] <= t_next[2] {
                1
            } else {
                2
            };
            let t_exit = t_next[axis].min(far).max(t);
            let i = self.cell_index(cell[0] as usize, cell[1] as usize, cell[2] as usize);
            if !visit(t, t_exit, self.state(i)) || t_exit >= far {
                return;
            }
            t = t_exit;
            cell[axis] += step[axis];
            if cell[axis] < 0 || cell[axis] >= r {
                return;
            }
            t_next[axis] += t_delta[axis];
        }
    }

    /// Appends to `out` the intervals of [near, far] that the sampler must
    /// cover: runs of surface cells, and the first inside cell (after which
    /// the ray is opaque, so marching stops).
    pub fn sampled_intervals(
        &self,
        o: [f32; 3],
        d: [f32; 3],
        near: f32,
        far: f32,
        out: &mut Vec<[f32; 2]>,
    ) {
        let mut open: Option<[f32; 2]> = None;
        let push = |iv: [f32; 2], out: &mut Vec<[f32; 2]>| {
            if iv[1] > iv[0] {
                out.push(iv);
            }
        };
        self.march(o, d, near, far, |t0, t1, state| {
            if state == CellState::Empty {
                if let Some(iv) = open.take() {
                    push(iv, out);
                }
                return true;
            }
            match &mut open {
                Some(iv) => iv[1] = t1,
                None => open = Some([t0, t1]),
            }
            state != CellState::Inside
        });
        if let Some(iv) = open {
            push(iv, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_i32_matches_floor() {
        for &x in &[
            -2.5f32, -2.0, -1e-7, 0.0, 1e-7, 0.999_999, 1.0, 3.7, -0.5, 127.99,
        ] {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
        }
    }
}
