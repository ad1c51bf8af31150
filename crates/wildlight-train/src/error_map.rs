//! Error-guided ray draws: a running estimate of the colour error over
//! square tiles of every training image, from which a share of each batch
//! is drawn in proportion to the error (the error map of instant-ngp).
//!
//! Why: the residual error of a trained model sits in a few percent of the
//! pixels (creases whose normals are wrong, a metal's highlight tail, the
//! outline), which uniform foreground draws reach as rarely as any other
//! pixel. Drawing a pixel with probability p ∝ e (its current L1 error)
//! and following the L1 gradient sign(e) gives, in expectation, a gradient
//! ∝ |e|·sign(e) = e: for those draws the objective behaves like the
//! squared error that PSNR measures, while the loss itself stays the L1
//! of SPEC §4.
//!
//! The estimate is per tile, not per pixel: a run of 15,000 steps of 1,024
//! rays visits each pixel of the default capture about four times, too few
//! to estimate anything, but each 4×4 tile about sixty times. Tiles without
//! a foreground pixel (where the colour loss never counts) hold 0 and are
//! never drawn; the others start at [`ErrorMap::INITIAL`], so that every
//! tile is drawn until it has been measured.

use rand::Rng;

/// The per-tile error estimates of every view.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorMap {
    tile: u32,
    views: Vec<TileGrid>,
    /// Error estimate of each tile of each view (view-major, row-major).
    values: Vec<f32>,
    /// Whether a tile holds a foreground pixel.
    eligible: Vec<bool>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct TileGrid {
    width: u32,
    height: u32,
    tiles_x: u32,
    /// Index of the view's first tile in `values`.
    offset: usize,
}

impl ErrorMap {
    /// Error given to a tile before its first measurement: the summed L1
    /// error of the three channels of an untrained model's typical ray.
    pub const INITIAL: f32 = 1.0;
    /// Weight of a new measurement in a tile's running estimate.
    pub const BLEND: f32 = 0.5;

    /// The tiles (`tile` × `tile` pixels) of views of the given sizes,
    /// with their foreground masks (a view without a mask counts as all
    /// foreground).
    pub fn new(tile: u32, views: &[(u32, u32, Option<&[bool]>)]) -> Self {
        assert!(tile >= 1, "tile size must be at least 1");
        let mut grids = Vec::with_capacity(views.len());
        let mut eligible = Vec::new();
        for &(width, height, mask) in views {
            let (tiles_x, tiles_y) = (width.div_ceil(tile), height.div_ceil(tile));
            grids.push(TileGrid {
                width,
                height,
                tiles_x,
                offset: eligible.len(),
            });
            let start = eligible.len();
            eligible.resize(start + (tiles_x * tiles_y) as usize, mask.is_none());
            if let Some(mask) = mask {
                for (p, _) in mask.iter().enumerate().filter(|(_, on)| **on) {
                    let (x, y) = (p as u32 % width, p as u32 / width);
                    eligible[start + ((y / tile) * tiles_x + x / tile) as usize] = true;
                }
            }
        }
        let values = eligible
            .iter()
            .map(|&e| if e { Self::INITIAL } else { 0.0 })
            .collect();
        Self {
            tile,
            views: grids,
            values,
            eligible,
        }
    }

    /// The error estimates (view-major, row-major tiles), for checkpoints.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Replaces the estimates (from a checkpoint); ineligible tiles stay 0.
    pub fn set_values(&mut self, values: &[f32]) -> Result<(), String> {
        if values.len() != self.values.len() {
            return Err(format!(
                "{} tile errors, the capture has {} tiles",
                values.len(),
                self.values.len()
            ));
        }
        if let Some(v) = values.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
            return Err(format!(
                "tile error {v} is not a finite, non-negative number"
            ));
        }
        for ((dst, src), ok) in self.values.iter_mut().zip(values).zip(&self.eligible) {
            *dst = if *ok { *src } else { 0.0 };
        }
        Ok(())
    }

    fn tile_of(&self, view: u32, pixel: u32) -> usize {
        let g = &self.views[view as usize];
        let (x, y) = (pixel % g.width, pixel / g.width);
        g.offset + ((y / self.tile) * g.tiles_x + x / self.tile) as usize
    }

    /// Blends the measured error of a ray (the summed L1 error of its
    /// counted channels) into its tile's estimate. Non-finite errors and
    /// tiles without foreground are ignored.
    pub fn record(&mut self, view: u32, pixel: u32, error: f32) {
        let t = self.tile_of(view, pixel);
        if self.eligible[t] && error.is_finite() && error >= 0.0 {
            self.values[t] += Self::BLEND * (error - self.values[t]);
        }
    }

    /// Draws `n` pixels, each from a tile chosen with probability
    /// proportional to its error and then uniformly inside that tile
    /// (clipped to the image); `push(view, pixel)` receives each. Draws
    /// nothing when every tile's error is 0.
    pub fn draw(&self, rng: &mut impl Rng, n: usize, mut push: impl FnMut(u32, u32)) {
        if n == 0 {
            return;
        }
        let mut cumulative = Vec::with_capacity(self.values.len());
        let mut total = 0.0f64;
        for v in &self.values {
            total += *v as f64;
            cumulative.push(total);
        }
        if total <= 0.0 {
            return;
        }
        for _ in 0..n {
            let u = rng.random_range(0.0..total);
            let t = cumulative
                .partition_point(|c| *c <= u)
                .min(self.values.len() - 1);
            // the view holding tile t: the last one whose offset is ≤ t
            let v = self.views.partition_point(|g| g.offset <= t) - 1;
            let g = &self.views[v];
            let local = (t - g.offset) as u32;
            let (x0, y0) = (
                (local % g.tiles_x) * self.tile,
                (local / g.tiles_x) * self.tile,
            );
            let x = rng.random_range(x0..(x0 + self.tile).min(g.width));
            let y = rng.random_range(y0..(y0 + self.tile).min(g.height));
            push(v as u32, y * g.width + x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn tiles_without_foreground_are_never_drawn() {
        // A 10×6 view with tile 4 has 3×2 tiles; the mask covers pixel
        // (9, 5) only, in tile (2, 1): the only tile that can be drawn.
        let mut mask = vec![false; 60];
        mask[5 * 10 + 9] = true;
        let map = ErrorMap::new(4, &[(10, 6, Some(&mask))]);
        assert_eq!(map.values(), &[0.0, 0.0, 0.0, 0.0, 0.0, ErrorMap::INITIAL]);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let mut seen = Vec::new();
        map.draw(&mut rng, 200, |v, p| seen.push((v, p)));
        assert_eq!(seen.len(), 200);
        // every draw lies in the clipped tile: x in 8..10, y in 4..6
        for (v, p) in &seen {
            assert_eq!(*v, 0);
            let (x, y) = (p % 10, p / 10);
            assert!((8..10).contains(&x) && (4..6).contains(&y), "({x}, {y})");
        }
        // all four pixels of the clipped tile are reached
        let mut distinct: Vec<u32> = seen.iter().map(|(_, p)| *p).collect();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct, vec![48, 49, 58, 59]);
    }

    #[test]
    fn draws_follow_the_recorded_errors() {
        // Two 4×4 views of one tile each (no masks): after measuring errors
        // 0.3 and 0.1 (blended from the initial 1.0 until they settle),
        // three quarters of the draws go to the first view.
        let mut map = ErrorMap::new(4, &[(4, 4, None), (4, 4, None)]);
        for _ in 0..40 {
            map.record(0, 5, 0.3);
            map.record(1, 15, 0.1);
        }
        assert!((map.values()[0] - 0.3).abs() < 1e-6);
        assert!((map.values()[1] - 0.1).abs() < 1e-6);
        // non-finite or negative measurements change nothing
        map.record(0, 0, f32::NAN);
        map.record(1, 0, -1.0);
        assert!((map.values()[0] - 0.3).abs() < 1e-6);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(2);
        let mut first = 0usize;
        let n = 20_000;
        map.draw(&mut rng, n, |v, _| first += usize::from(v == 0));
        let share = first as f64 / n as f64;
        assert!((share - 0.75).abs() < 0.015, "share of view 0: {share}");
    }

    #[test]
    fn one_measurement_moves_an_estimate_halfway() {
        let mut map = ErrorMap::new(2, &[(4, 2, None)]);
        map.record(0, 3, 0.2); // pixel (3, 0): tile 1
        assert_eq!(map.values(), &[1.0, 0.6]);
    }

    #[test]
    fn restored_values_are_checked() {
        let mut mask = vec![true; 16];
        mask[..8].fill(false); // the top half: tile row 0 has no foreground
        let mut map = ErrorMap::new(2, &[(4, 4, Some(&mask))]);
        assert!(map.set_values(&[0.5; 3]).unwrap_err().contains("4 tiles"));
        assert!(map.set_values(&[0.5, 0.5, f32::NAN, 0.5]).is_err());
        map.set_values(&[0.5, 0.5, 0.25, 0.75]).unwrap();
        // the ineligible tiles stay 0 whatever the file says
        assert_eq!(map.values(), &[0.0, 0.0, 0.25, 0.75]);
        // nothing to draw from an all-zero map
        map.set_values(&[0.0; 4]).unwrap();
        let mut count = 0;
        map.draw(&mut rand_pcg::Pcg64::seed_from_u64(3), 10, |_, _| {
            count += 1
        });
        assert_eq!(count, 0);
    }
}
