//! Base colour against the truth, up to the flash gain: the running sums
//! behind `base_color_psnr` and `base_color_psnr_aligned` of `wildlight eval
//! materials` ([`crate::material_eval`]).
//!
//! The flash power is learned only up to a gain, which multiplies the
//! recovered base colour, so besides the plain PSNR the comparison scales
//! each predicted channel by the least-squares factor
//! s_c = argmin_s Σ (s p_c − g_c)² = Σ p_c g_c / Σ p_c² before it.

use crate::image_metrics::psnr_from_mse;

/// Sums over pairs (prediction p, truth g) of RGB colours, mergeable.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ColourFit {
    /// Colours added.
    pub count: usize,
    /// Σ (p − g)², Σ p g, Σ p², Σ g², per channel.
    sq_err: [f64; 3],
    pg: [f64; 3],
    pp: [f64; 3],
    gg: [f64; 3],
}

impl ColourFit {
    /// Adds one pair.
    pub fn add(&mut self, p: [f64; 3], g: [f64; 3]) {
        for c in 0..3 {
            self.sq_err[c] += (p[c] - g[c]).powi(2);
            self.pg[c] += p[c] * g[c];
            self.pp[c] += p[c] * p[c];
            self.gg[c] += g[c] * g[c];
        }
        self.count += 1;
    }

    /// The sums of both.
    pub fn merge(mut self, o: ColourFit) -> ColourFit {
        for c in 0..3 {
            self.sq_err[c] += o.sq_err[c];
            self.pg[c] += o.pg[c];
            self.pp[c] += o.pp[c];
            self.gg[c] += o.gg[c];
        }
        self.count += o.count;
        self
    }

    /// The least-squares factor of each channel (1 for a channel whose
    /// prediction is all zero); `None` without pairs.
    pub fn scale(&self) -> Option<[f64; 3]> {
        (self.count > 0).then(|| {
            [0, 1, 2].map(|c| {
                if self.pp[c] > 0.0 {
                    self.pg[c] / self.pp[c]
                } else {
                    1.0
                }
            })
        })
    }

    /// PSNR (peak 1) of the mean squared error over pairs × channels.
    pub fn psnr(&self) -> Option<f64> {
        (self.count > 0).then(|| {
            psnr_from_mse(
                self.sq_err.iter().sum::<f64>() / (3 * self.count) as f64,
                1.0,
            )
        })
    }

    /// [`Self::psnr`] after scaling each predicted channel by [`Self::scale`].
    pub fn psnr_aligned(&self) -> Option<f64> {
        let k = self.scale()?;
        // Σ (k p − g)² = k² Σp² − 2k Σpg + Σg², per channel.
        let sq: f64 = (0..3)
            .map(|c| (k[c] * k[c] * self.pp[c] - 2.0 * k[c] * self.pg[c] + self.gg[c]).max(0.0))
            .sum();
        Some(psnr_from_mse(sq / (3 * self.count) as f64, 1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_prediction_off_by_a_gain_per_channel_aligns_exactly() {
        let truth = [[0.2, 0.4, 0.6], [0.8, 0.1, 0.3], [0.5, 0.5, 0.05]];
        let mut fit = ColourFit::default();
        for g in truth {
            fit.add([0.5 * g[0], 2.0 * g[1], g[2]], g);
        }
        let k = fit.scale().unwrap();
        for (got, want) in k.iter().zip([2.0, 0.5, 1.0]) {
            assert!((got - want).abs() < 1e-12, "{k:?}");
        }
        assert_eq!(fit.psnr_aligned().unwrap(), crate::image_metrics::MAX_PSNR);
        // unaligned: mean of (0.5 g_r)², (g_g)², 0 over 3 × 3 values
        let mse = truth
            .iter()
            .map(|g| (0.5 * g[0]).powi(2) + g[1].powi(2))
            .sum::<f64>()
            / 9.0;
        assert!((fit.psnr().unwrap() - psnr_from_mse(mse, 1.0)).abs() < 1e-9);
        assert_eq!(ColourFit::default().psnr(), None);
    }

    #[test]
    fn merged_sums_equal_sums_of_all_pairs() {
        let pairs = [
            ([0.1, 0.2, 0.3], [0.2, 0.2, 0.1]),
            ([0.9, 0.4, 0.0], [0.7, 0.5, 0.2]),
        ];
        let (mut a, mut b, mut all) = (
            ColourFit::default(),
            ColourFit::default(),
            ColourFit::default(),
        );
        a.add(pairs[0].0, pairs[0].1);
        b.add(pairs[1].0, pairs[1].1);
        for (p, g) in pairs {
            all.add(p, g);
        }
        assert_eq!(a.merge(b), all);
        // a channel predicted all zero keeps the factor 1
        let mut dark = ColourFit::default();
        dark.add([0.4, 0.0, 0.2], [0.2, 0.3, 0.1]);
        assert_eq!(dark.scale().unwrap(), [0.5, 1.0, 0.5]);
    }
}
