//! The scene outside the region of interest (SPEC §6): samples along each
//! ray beyond the unit sphere, and their volume rendering with an ambient
//! and a flash term, forward and backward.
//!
//! A capture without masks sees the table, the walls and the sky behind the
//! object. Everything outside the unit sphere is a radiance field over the
//! inverted-sphere parameterisation (NeRF++): a point x with |x| = r > 1 is
//! (x/r, 1/r), and the samples are spaced uniformly in 1/r from where the
//! ray leaves the sphere out to `far_radius`, so the far background costs
//! as many samples as the near one. The field reads the point through the
//! contraction u = (x/r)(2 − 1/r), a one-to-one map of (x/r, 1/r) into the
//! shell 1 ≤ |u| < 2, so an ordinary 3-D encoding over [−2, 2]³ serves.
//!
//! For sample j of a ray (density σ_j ≥ 0, section δ_j, ambient radiance
//! a_j, flash response ρ_j ≥ 0, distance t_j from the camera centre, where
//! the flash is):
//!
//! ```text
//!   α_j = 1 − exp(−σ_j δ_j)         (the last sample: α = 1, the sky is opaque)
//!   T_j = Π_{i<j} (1 − α_i),   w_j = T_j α_j
//!   c_j = a_j + γ E ρ_j / t_j²      (SPEC §2's inverse-square flash, gain γ = e^g)
//!   B   = Σ_j w_j c_j
//! ```
//!
//! The pixel is C = C_object + (1 − Σ_k w_k) B ([`crate::add_background`]),
//! so an opaque object hides the background exactly and a ray that misses
//! the sphere sees only it.

use wildlight_real::Real;

/// How the background is sampled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BackgroundSettings {
    /// Samples per ray (the reference: 32).
    pub samples: usize,
    /// Radius of the farthest sample, in radii of the unit sphere (the
    /// reference: about 1000).
    pub far_radius: f64,
}

impl Default for BackgroundSettings {
    fn default() -> Self {
        BackgroundSettings {
            samples: 32,
            far_radius: 1000.0,
        }
    }
}

/// The background samples of a batch of rays: `samples` per ray, ray `r`'s
/// at indices `r·samples .. (r+1)·samples`, nearest first.
#[derive(Clone, Debug, Default)]
pub struct BackgroundSamples<T> {
    /// Samples per ray.
    pub per_ray: usize,
    /// Distance of each sample from the ray's origin (the camera centre).
    pub t: Vec<T>,
    /// Length of each sample's section (the last one's is unused: it is opaque).
    pub delta: Vec<T>,
    /// The contracted position u = (x/|x|)(2 − 1/|x|) of each sample, in
    /// the shell 1 ≤ |u| < 2 (the field's input).
    pub points: Vec<[T; 3]>,
}

impl<T: Real> BackgroundSamples<T> {
    /// An empty set.
    pub fn new() -> Self {
        BackgroundSamples {
            per_ray: 0,
            t: Vec::new(),
            delta: Vec::new(),
            points: Vec::new(),
        }
    }

    /// Number of samples in all.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Places the samples of every ray (origins in the normalized frame,
    /// unit directions). With `jitter`, each sample lies uniformly within
    /// its 1/r bin (training); without, at the bin's middle (rendering).
    /// Rays whose origin lies inside the sphere start at the sphere.
    pub fn place(
        &mut self,
        origins: &[[T; 3]],
        dirs: &[[T; 3]],
        settings: &BackgroundSettings,
        mut jitter: Option<&mut dyn FnMut() -> f64>,
    ) {
        assert_eq!(origins.len(), dirs.len(), "background: ray count");
        let n = settings.samples.max(1);
        self.per_ray = n;
        let total = n * origins.len();
        self.t.clear();
        self.delta.clear();
        self.points.clear();
        self.t.reserve(total);
        self.delta.reserve(total);
        self.points.reserve(total);
        let inv_far = 1.0 / settings.far_radius.max(1.0 + 1e-6);
        let mut radii = vec![0.0f64; n];
        for (o, d) in origins.iter().zip(dirs) {
            let o = o.map(|v| v.to_f64());
            let d = d.map(|v| v.to_f64());
            let od = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
            let oo = o[0] * o[0] + o[1] * o[1] + o[2] * o[2];
            // Closest approach to the centre: t_c along the ray, at distance b.
            let t_c = -od;
            let b2 = (oo - od * od).max(0.0);
            // Where the ray enters the background: leaving the unit sphere,
            // or at its closest approach when it misses the sphere, or at
            // its origin when it moves away from the centre.
            let r_start = if t_c < 0.0 {
                oo.sqrt().max(1.0)
            } else {
                b2.sqrt().max(1.0)
            };
            let inv_start = 1.0 / r_start;
            for (j, r) in radii.iter_mut().enumerate() {
                let xi = match jitter.as_deref_mut() {
                    Some(next) => next(),
                    None => 0.5,
                };
                let inv = inv_start - (j as f64 + xi) / n as f64 * (inv_start - inv_far);
                *r = 1.0 / inv;
            }
            for j in 0..n {
                let r = radii[j];
                let t = t_c + (r * r - b2).max(0.0).sqrt();
                let t = t.max(0.0);
                let delta = if j + 1 < n {
                    let r1 = radii[j + 1];
                    (t_c + (r1 * r1 - b2).max(0.0).sqrt()).max(0.0) - t
                } else {
                    0.0
                };
                let x = [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
                let len = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt().max(1.0);
                let scale = (2.0 - 1.0 / len) / len;
                self.t.push(T::from_f64(t));
                self.delta.push(T::from_f64(delta.max(0.0)));
                self.points.push(x.map(|v| T::from_f64(v * scale)));
            }
        }
    }
}

/// The per-sample values of the background field and the per-ray flash,
/// for [`background_forward`] and [`background_backward`].
#[derive(Clone, Copy, Debug)]
pub struct BackgroundInputs<'a, T> {
    /// The samples.
    pub samples: &'a BackgroundSamples<T>,
    /// Density σ ≥ 0 of each sample (per unit of normalized length).
    pub density: &'a [T],
    /// Ambient radiance a of each sample.
    pub ambient: &'a [[T; 3]],
    /// Flash response ρ ≥ 0 of each sample.
    pub flash_response: &'a [[T; 3]],
    /// RGB flash energy E of each ray's image (zero: flash off).
    pub light_energy: &'a [[T; 3]],
}

impl<T: Real> BackgroundInputs<'_, T> {
    fn check(&self) -> usize {
        let n = self.samples.len();
        let per_ray = self.samples.per_ray;
        assert!(per_ray > 0, "background: no samples placed");
        assert_eq!(
            n,
            per_ray * self.light_energy.len(),
            "background: ray count"
        );
        assert!(
            self.density.len() == n && self.ambient.len() == n && self.flash_response.len() == n,
            "background: per-sample array lengths"
        );
        per_ray
    }
}

/// The opacity of sample `j` of a ray of `per_ray` samples.
#[inline]
fn alpha<T: Real>(j: usize, per_ray: usize, density: T, delta: T) -> T {
    if j + 1 == per_ray {
        T::from_f64(1.0)
    } else {
        T::from_f64(1.0) - (-(density * delta)).exp()
    }
}

/// The flash factor γ E / t² of a sample.
#[inline]
fn flash_factor<T: Real>(gain: T, energy: [T; 3], t: T) -> [T; 3] {
    let inv_t2 = T::from_f64(1.0) / (t * t).max(T::from_f64(1e-12));
    energy.map(|e| gain * e * inv_t2)
}

/// The background radiance B of every ray (see the module docs), written
/// into `colour`; `weights` receives each sample's w_j (they sum to 1).
pub fn background_forward<T: Real>(
    inputs: &BackgroundInputs<'_, T>,
    log_gain: T,
    colour: &mut [[T; 3]],
    weights: &mut Vec<T>,
) {
    let per_ray = inputs.check();
    let s = inputs.samples;
    assert_eq!(
        colour.len(),
        inputs.light_energy.len(),
        "background: colour length"
    );
    let gain = log_gain.exp();
    weights.clear();
    weights.resize(s.len(), T::from_f64(0.0));
    for (r, out) in colour.iter_mut().enumerate() {
        let mut transmittance = T::from_f64(1.0);
        let mut sum = [T::from_f64(0.0); 3];
        for j in 0..per_ray {
            let k = r * per_ray + j;
            let a = alpha(j, per_ray, inputs.density[k], s.delta[k]);
            let w = transmittance * a;
            weights[k] = w;
            let f = flash_factor(gain, inputs.light_energy[r], s.t[k]);
            for c in 0..3 {
                sum[c] += w * (inputs.ambient[k][c] + f[c] * inputs.flash_response[k][c]);
            }
            transmittance *= T::from_f64(1.0) - a;
        }
        *out = sum;
    }
}

/// The distance along each ray at which its background weights (from
/// [`background_forward`]) reach `fraction` of their sum, interpolated
/// within the section where their running sum crosses it (a depth quantile
/// of what the background shows: 0.5 is the median); `None` for a ray whose
/// background holds no weight.
pub fn background_depth_quantile<T: Real>(
    samples: &BackgroundSamples<T>,
    weights: &[T],
    fraction: f64,
) -> Vec<Option<f64>> {
    let per_ray = samples.per_ray.max(1);
    assert_eq!(weights.len(), samples.len(), "background: weight count");
    weights
        .chunks(per_ray)
        .enumerate()
        .map(|(r, w)| {
            let total: f64 = w.iter().map(|v| v.to_f64()).sum();
            if total.is_nan() || total <= 0.0 {
                return None;
            }
            let target = fraction * total;
            let mut sum = 0.0;
            for (j, wj) in w.iter().enumerate() {
                let wj = wj.to_f64();
                let k = r * per_ray + j;
                if sum + wj >= target && wj > 0.0 {
                    let part = ((target - sum) / wj).clamp(0.0, 1.0);
                    return Some(samples.t[k].to_f64() + part * samples.delta[k].to_f64());
                }
                sum += wj;
            }
            Some(samples.t[r * per_ray + per_ray - 1].to_f64())
        })
        .collect()
}

/// Gradients of [`background_backward`].
#[derive(Clone, Debug, Default)]
pub struct BackgroundGrads<T> {
    /// ∂L/∂σ per sample.
    pub density: Vec<T>,
    /// ∂L/∂a per sample.
    pub ambient: Vec<[T; 3]>,
    /// ∂L/∂ρ per sample.
    pub flash_response: Vec<[T; 3]>,
    /// ∂L/∂g for the log-gain g.
    pub log_gain: T,
}

/// Backward of [`background_forward`] from ∂L/∂B per ray (`d_colour`),
/// with the weights the forward pass returned.
///
/// With d_j = ∂L/∂B · c_j and the suffix sums S_j = Σ_{k>j} w_k d_k,
/// ∂L/∂σ_j = δ_j (T_{j+1} d_j − S_j) (the last sample's σ has no effect),
/// ∂L/∂a_j = w_j ∂L/∂B, ∂L/∂ρ_j = w_j γ E / t_j² ∘ ∂L/∂B and
/// ∂L/∂g = Σ_j w_j ∂L/∂B · (γ E ρ_j / t_j²).
pub fn background_backward<T: Real>(
    inputs: &BackgroundInputs<'_, T>,
    log_gain: T,
    weights: &[T],
    d_colour: &[[T; 3]],
    grads: &mut BackgroundGrads<T>,
) {
    let per_ray = inputs.check();
    let s = inputs.samples;
    assert_eq!(weights.len(), s.len(), "background: weights length");
    assert_eq!(
        d_colour.len(),
        inputs.light_energy.len(),
        "background: d_colour length"
    );
    let gain = log_gain.exp();
    let zero = T::from_f64(0.0);
    grads.density.clear();
    grads.density.resize(s.len(), zero);
    grads.ambient.clear();
    grads.ambient.resize(s.len(), [zero; 3]);
    grads.flash_response.clear();
    grads.flash_response.resize(s.len(), [zero; 3]);
    let mut d_log_gain = zero;
    let mut d_w = vec![zero; per_ray];
    for (r, dc) in d_colour.iter().enumerate() {
        for (j, d_wj) in d_w.iter_mut().enumerate() {
            let k = r * per_ray + j;
            let f = flash_factor(gain, inputs.light_energy[r], s.t[k]);
            let w = weights[k];
            let mut dot = zero;
            for c in 0..3 {
                let flash = f[c] * inputs.flash_response[k][c];
                dot += dc[c] * (inputs.ambient[k][c] + flash);
                grads.ambient[k][c] = w * dc[c];
                grads.flash_response[k][c] = w * f[c] * dc[c];
                d_log_gain += w * dc[c] * flash;
            }
            *d_wj = dot;
        }
        // Walk back from the far end, carrying S_j = Σ_{k>j} w_k d_k.
        let mut suffix = zero;
        // T_{j+1} = T_j (1 − α_j); w_j = T_j α_j, so T_{j+1} = T_j − w_j.
        let mut transmittance_after = vec![zero; per_ray];
        let mut transmittance = T::from_f64(1.0);
        for (j, after) in transmittance_after.iter_mut().enumerate() {
            transmittance -= weights[r * per_ray + j];
            *after = transmittance;
        }
        for j in (0..per_ray).rev() {
            let k = r * per_ray + j;
            if j + 1 < per_ray {
                grads.density[k] = s.delta[k] * (transmittance_after[j] * d_w[j] - suffix);
            }
            suffix += weights[k] * d_w[j];
        }
    }
    grads.log_gain = d_log_gain;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rays() -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let origins = vec![
            [0.0, 0.0, 3.0],  // through the centre
            [0.5, 2.5, -1.0], // grazing
            [0.0, 2.0, 2.0],  // misses the sphere
            [3.0, 0.0, 0.0],  // looks away
            [0.2, -0.1, 0.3], // starts inside the sphere
        ];
        let targets: [[f64; 3]; 5] = [
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 2.0, -3.0],
            [6.0, 1.0, 0.0],
            [1.0, 1.0, 1.0],
        ];
        let dirs = origins
            .iter()
            .zip(targets)
            .map(|(o, t)| {
                let d: [f64; 3] = [t[0] - o[0], t[1] - o[1], t[2] - o[2]];
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                d.map(|v| v / l)
            })
            .collect();
        (origins, dirs)
    }

    fn norm(v: [f64; 3]) -> f64 {
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
    }

    #[test]
    fn samples_lie_outside_the_sphere_uniform_in_inverse_radius() {
        let (origins, dirs) = rays();
        let settings = BackgroundSettings {
            samples: 16,
            far_radius: 1000.0,
        };
        let mut s = BackgroundSamples::<f64>::new();
        s.place(&origins, &dirs, &settings, None);
        assert_eq!(s.len(), 16 * origins.len());
        for (r, (o, d)) in origins.iter().zip(&dirs).enumerate() {
            let radius = |k: usize| {
                let t = s.t[k];
                norm([o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]])
            };
            let mut last_inv = f64::INFINITY;
            for j in 0..16 {
                let k = r * 16 + j;
                let rad = radius(k);
                assert!(
                    (1.0 - 1e-9..=1000.0).contains(&rad),
                    "ray {r} sample {j}: |x| = {rad}"
                );
                // The contracted point has |u| = 2 − 1/|x| and x's direction.
                let u = s.points[k];
                assert!((norm(u) - (2.0 - 1.0 / rad)).abs() < 1e-9);
                assert!(s.t[k] >= 0.0);
                if j + 1 < 16 {
                    assert!((s.t[k + 1] - s.t[k] - s.delta[k]).abs() < 1e-9);
                }
                last_inv = last_inv.min(1.0 / rad);
            }
            // Bins of equal width in 1/r: consecutive differences agree.
            let inv: Vec<f64> = (0..16).map(|j| 1.0 / radius(r * 16 + j)).collect();
            let step = inv[0] - inv[1];
            for j in 1..15 {
                assert!(((inv[j] - inv[j + 1]) - step).abs() < 1e-9 * (1.0 + step));
            }
            // Midpoints of 16 bins: the last is half a bin from 1/1000.
            assert!((inv[15] - 1e-3 - step / 2.0).abs() < 1e-9, "ray {r}");
        }
        // The ray through the centre starts where it leaves the sphere (t = 4).
        assert!(s.t[0] > 4.0 && s.t[0] < 4.0 + 0.1);
    }

    /// Density, ambient radiance and flash response per sample, energy per ray.
    type Inputs = (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[f64; 3]>);

    fn inputs_for(s: &BackgroundSamples<f64>, rays: usize) -> Inputs {
        let mut next = crate::test_uniform(17);
        let n = s.len();
        let density = (0..n).map(|_| 3.0 * next()).collect();
        let ambient = (0..n).map(|_| [next(), next(), next()]).collect();
        let response = (0..n).map(|_| [next(), next(), next()]).collect();
        let energy = (0..rays)
            .map(|r| {
                if r % 2 == 0 {
                    [10.0, 9.0, 8.0]
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        (density, ambient, response, energy)
    }

    #[test]
    fn weights_sum_to_one_and_the_flash_falls_with_distance() {
        let (origins, dirs) = rays();
        let mut s = BackgroundSamples::<f64>::new();
        s.place(&origins, &dirs, &BackgroundSettings::default(), None);
        let (density, ambient, response, energy) = inputs_for(&s, origins.len());
        let inputs = BackgroundInputs {
            samples: &s,
            density: &density,
            ambient: &ambient,
            flash_response: &response,
            light_energy: &energy,
        };
        let mut colour = vec![[0.0; 3]; origins.len()];
        let mut w = Vec::new();
        background_forward(&inputs, 0.0, &mut colour, &mut w);
        for r in 0..origins.len() {
            let sum: f64 = w[r * 32..(r + 1) * 32].iter().sum();
            assert!((sum - 1.0).abs() < 1e-12, "ray {r}: Σw = {sum}");
        }
        // Fully transparent but for the sky: the last sample's colour alone.
        let zero = vec![0.0; s.len()];
        let inputs0 = BackgroundInputs {
            density: &zero,
            ..inputs
        };
        background_forward(&inputs0, 0.5, &mut colour, &mut w);
        let k = 31;
        let t = s.t[k];
        let expected = ambient[k][0] + 0.5f64.exp() * 10.0 * response[k][0] / (t * t);
        assert!((colour[0][0] - expected).abs() < 1e-12);
    }

    #[test]
    fn backward_matches_finite_differences() {
        let (origins, dirs) = rays();
        let settings = BackgroundSettings {
            samples: 8,
            far_radius: 50.0,
        };
        let mut s = BackgroundSamples::<f64>::new();
        let mut next = crate::test_uniform(5);
        let mut jitter = || next();
        s.place(&origins, &dirs, &settings, Some(&mut jitter));
        let rays = origins.len();
        let (density, ambient, response, energy) = inputs_for(&s, rays);
        let mut next = crate::test_uniform(99);
        let d_colour: Vec<[f64; 3]> = (0..rays)
            .map(|_| [next() - 0.5, next() - 0.5, next() - 0.5])
            .collect();
        let log_gain = 0.3;
        let loss = |density: &[f64], ambient: &[[f64; 3]], response: &[[f64; 3]], g: f64| {
            let inputs = BackgroundInputs {
                samples: &s,
                density,
                ambient,
                flash_response: response,
                light_energy: &energy,
            };
            let mut colour = vec![[0.0; 3]; rays];
            let mut w = Vec::new();
            background_forward(&inputs, g, &mut colour, &mut w);
            colour
                .iter()
                .zip(&d_colour)
                .map(|(c, d)| c[0] * d[0] + c[1] * d[1] + c[2] * d[2])
                .sum::<f64>()
        };
        let inputs = BackgroundInputs {
            samples: &s,
            density: &density,
            ambient: &ambient,
            flash_response: &response,
            light_energy: &energy,
        };
        let mut colour = vec![[0.0; 3]; rays];
        let mut w = Vec::new();
        background_forward(&inputs, log_gain, &mut colour, &mut w);
        let mut grads = BackgroundGrads::default();
        background_backward(&inputs, log_gain, &w, &d_colour, &mut grads);
        let h = 1e-6;
        let check = |analytic: f64, plus: f64, minus: f64, what: &str| {
            let numeric = (plus - minus) / (2.0 * h);
            assert!(
                (analytic - numeric).abs() <= 1e-6 * (1.0 + numeric.abs()),
                "{what}: analytic {analytic}, numeric {numeric}"
            );
        };
        for k in 0..s.len() {
            let mut p = density.clone();
            p[k] += h;
            let mut m = density.clone();
            m[k] -= h;
            check(
                grads.density[k],
                loss(&p, &ambient, &response, log_gain),
                loss(&m, &ambient, &response, log_gain),
                &format!("σ[{k}]"),
            );
            for c in 0..3 {
                let mut p = ambient.clone();
                p[k][c] += h;
                let mut m = ambient.clone();
                m[k][c] -= h;
                check(
                    grads.ambient[k][c],
                    loss(&density, &p, &response, log_gain),
                    loss(&density, &m, &response, log_gain),
                    &format!("a[{k}][{c}]"),
                );
                let mut p = response.clone();
                p[k][c] += h;
                let mut m = response.clone();
                m[k][c] -= h;
                check(
                    grads.flash_response[k][c],
                    loss(&density, &ambient, &p, log_gain),
                    loss(&density, &ambient, &m, log_gain),
                    &format!("ρ[{k}][{c}]"),
                );
            }
        }
        check(
            grads.log_gain,
            loss(&density, &ambient, &response, log_gain + h),
            loss(&density, &ambient, &response, log_gain - h),
            "g",
        );
        // The gradient is not trivially zero.
        assert!(grads.density.iter().any(|g| g.abs() > 1e-3));
        assert!(grads.log_gain.abs() > 1e-6);
    }
}
