//! The flash term of SPEC §2, forward and backward:
//!
//! ```text
//!   f = γ · E ⊙ ρ(n, h; Θ) · max(0, n·h) / |x − o|²,   h = (o − x)/|o − x|,   n = ∇φ/|∇φ|
//! ```
//!
//! The flash sits at the camera centre o, so for a sample x = o + t·d of a
//! camera ray (|d| = 1) h = −d and |x − o| = t: the kernel takes the sample
//! distances t and the ray directions. The gain is learned through
//! γ = exp(g) (log parameterisation: γ > 0 and multiplicative steps); the
//! kernels take g and return ∂L/∂g.

use rayon::prelude::*;
use wildlight_material::{BrdfJacobian, BrdfSettings, brdf};

use crate::packing::{ray_chunks, split_mut, validate_offsets};
use crate::real::dot3;
use wildlight_real::Real;

/// Smallest squared light distance used in the inverse-square falloff.
pub const MIN_DIST2: f64 = 1e-8;
/// Smallest gradient length used when normalising ∇φ.
pub const MIN_GRAD_NORM: f64 = 1e-12;

/// The flash gain γ = exp(g) for log-gain `g`.
#[inline]
pub fn gain<T: Real>(log_gain: T) -> T {
    log_gain.exp()
}

/// Per-sample inputs of the flash term, packed as in [`crate::packing`].
#[derive(Clone, Copy, Debug)]
pub struct FlashInputs<'a, T> {
    /// Ray offsets into the per-sample arrays.
    pub offsets: &'a [u32],
    /// Unit direction d of each ray (h = −d).
    pub ray_dirs: &'a [[T; 3]],
    /// RGB flash energy E of each ray's image (zero: flash off).
    pub light_energy: &'a [[T; 3]],
    /// Distance t of each sample from the camera centre (= the light).
    pub t: &'a [T],
    /// Raw SDF gradient ∇φ at each sample.
    pub sdf_grad: &'a [[T; 3]],
    /// Material parameters Θ ∈ [0, 1]⁹ at each sample (order of `wildlight_material::Material`).
    pub params: &'a [[T; 9]],
}

impl<T> FlashInputs<'_, T> {
    /// Whether the array lengths agree with each other and with the offsets.
    pub fn is_consistent(&self) -> bool {
        let n = self.t.len();
        validate_offsets(self.offsets, n)
            && self.ray_dirs.len() + 1 == self.offsets.len()
            && self.light_energy.len() == self.ray_dirs.len()
            && self.sdf_grad.len() == n
            && self.params.len() == n
    }
}

/// Geometry of one sample: unit normal, |∇φ|, h, c = n·h and γ/t².
#[derive(Clone, Copy)]
struct SampleGeometry<T> {
    normal: [T; 3],
    grad_norm: T,
    h: [T; 3],
    cos: T,
    falloff: T,
}

#[inline(always)]
fn geometry<T: Real>(dir: [T; 3], grad: [T; 3], t: T, gamma: T) -> SampleGeometry<T> {
    let grad_norm = dot3(grad, grad).sqrt().max(T::from_f64(MIN_GRAD_NORM));
    let normal = grad.map(|g| g / grad_norm);
    let h = dir.map(|d| -d);
    SampleGeometry {
        normal,
        grad_norm,
        h,
        cos: dot3(normal, h),
        falloff: gamma / (t * t).max(T::from_f64(MIN_DIST2)),
    }
}

#[inline(always)]
fn is_off<T: Real>(e: [T; 3]) -> bool {
    let z = T::from_f64(0.0);
    e[0] == z && e[1] == z && e[2] == z
}

/// The BRDF Jacobians of a forward pass, kept for the backward pass so that
/// it does not evaluate the BRDF again (132 bytes per sample in `f32`).
#[derive(Clone, Debug, Default)]
pub struct FlashCache<T> {
    jacobians: Vec<BrdfJacobian<T>>,
}

impl<T: Real> FlashCache<T> {
    /// An empty cache (grows on first use, then reused).
    pub fn new() -> Self {
        Self {
            jacobians: Vec::new(),
        }
    }

    /// Number of samples cached.
    pub fn len(&self) -> usize {
        self.jacobians.len()
    }

    /// Whether nothing is cached.
    pub fn is_empty(&self) -> bool {
        self.jacobians.is_empty()
    }
}

fn zero_jacobian<T: Real>() -> BrdfJacobian<T> {
    let z = T::from_f64(0.0);
    BrdfJacobian {
        value: [z; 3],
        d_params: [[z; 3]; 9],
        d_cos: [z; 3],
    }
}

/// Evaluates the flash radiance f per sample into `out` (SPEC §2). With a
/// `cache`, also stores the BRDF Jacobians for [`flash_backward`].
///
/// # Panics
/// If the inputs are inconsistent or `out` has the wrong length.
pub fn flash_forward<T: Real>(
    inputs: &FlashInputs<'_, T>,
    log_gain: T,
    settings: &BrdfSettings,
    out: &mut [[T; 3]],
    cache: Option<&mut FlashCache<T>>,
) {
    assert!(inputs.is_consistent(), "flash_forward: inconsistent inputs");
    let n = inputs.t.len();
    assert_eq!(out.len(), n, "flash_forward: output length");
    let gamma = gain(log_gain);
    let chunks = ray_chunks(inputs.offsets);
    let outs = split_mut(out, chunks.iter().map(|c| c.samples.clone()));
    let caches: Vec<Option<&mut [BrdfJacobian<T>]>> = match cache {
        Some(cache) => {
            // Every entry is written below (zero where the flash is off or
            // the sample faces away), so a cache of the right length is
            // reused without the 132 bytes/sample of zero-filling first.
            if cache.jacobians.len() != n {
                cache.jacobians.clear();
                cache.jacobians.resize(n, zero_jacobian());
            }
            split_mut(
                &mut cache.jacobians,
                chunks.iter().map(|c| c.samples.clone()),
            )
            .into_iter()
            .map(Some)
            .collect()
        }
        None => chunks.iter().map(|_| None).collect(),
    };
    chunks
        .par_iter()
        .zip(outs)
        .zip(caches)
        .for_each(|((chunk, out), mut cache)| {
            let base = chunk.samples.start;
            for ray in chunk.rays.clone() {
                let e = inputs.light_energy[ray];
                let range = inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize;
                if is_off(e) {
                    for o in &mut out[range.start - base..range.end - base] {
                        *o = [T::from_f64(0.0); 3];
                    }
                    if let Some(c) = cache.as_deref_mut() {
                        c[range.start - base..range.end - base].fill(zero_jacobian());
                    }
                    continue;
                }
                let dir = inputs.ray_dirs[ray];
                for k in range {
                    let g = geometry(dir, inputs.sdf_grad[k], inputs.t[k], gamma);
                    out[k - base] = if g.cos > T::from_f64(0.0) {
                        let rho = match cache.as_deref_mut() {
                            Some(c) => {
                                let jac =
                                    brdf::eval_with_jacobian(&inputs.params[k], g.cos, settings);
                                c[k - base] = jac;
                                jac.value
                            }
                            None => brdf::eval(&inputs.params[k], g.cos, settings),
                        };
                        let s = g.cos * g.falloff;
                        [e[0] * rho[0] * s, e[1] * rho[1] * s, e[2] * rho[2] * s]
                    } else {
                        if let Some(c) = cache.as_deref_mut() {
                            c[k - base] = zero_jacobian();
                        }
                        [T::from_f64(0.0); 3]
                    };
                }
            }
        });
}

/// Backward of [`flash_forward`]: given ∂L/∂f per sample, ADDS ∂L/∂Θ into
/// `d_params` and ∂L/∂∇φ (through the normalisation n = ∇φ/|∇φ|) into
/// `d_sdf_grad`, and returns ∂L/∂g for the log-gain g (γ = exp(g)).
///
/// `cache`: the cache filled by the forward pass on the same inputs (the
/// BRDF is then not evaluated again), or `None` to recompute.
///
/// # Panics
/// If the inputs are inconsistent or a buffer has the wrong length.
#[allow(clippy::needless_range_loop)] // several parallel arrays share the index
pub fn flash_backward<T: Real>(
    inputs: &FlashInputs<'_, T>,
    log_gain: T,
    settings: &BrdfSettings,
    cache: Option<&FlashCache<T>>,
    d_out: &[[T; 3]],
    d_params: &mut [[T; 9]],
    d_sdf_grad: &mut [[T; 3]],
) -> T {
    assert!(
        inputs.is_consistent(),
        "flash_backward: inconsistent inputs"
    );
    let n = inputs.t.len();
    assert_eq!(d_out.len(), n, "flash_backward: d_out length");
    assert_eq!(d_params.len(), n, "flash_backward: d_params length");
    assert_eq!(d_sdf_grad.len(), n, "flash_backward: d_sdf_grad length");
    if let Some(c) = cache {
        assert_eq!(c.len(), n, "flash_backward: cache from another batch");
    }
    let gamma = gain(log_gain);
    let chunks = ray_chunks(inputs.offsets);
    let dps = split_mut(d_params, chunks.iter().map(|c| c.samples.clone()));
    let dgs = split_mut(d_sdf_grad, chunks.iter().map(|c| c.samples.clone()));
    let partial: Vec<T> = chunks
        .par_iter()
        .zip(dps)
        .zip(dgs)
        .map(|((chunk, dp), dg)| {
            let base = chunk.samples.start;
            let mut d_log_gain = T::from_f64(0.0);
            for ray in chunk.rays.clone() {
                let e = inputs.light_energy[ray];
                if is_off(e) {
                    continue;
                }
                let dir = inputs.ray_dirs[ray];
                for k in inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize {
                    let g = geometry(dir, inputs.sdf_grad[k], inputs.t[k], gamma);
                    if g.cos <= T::from_f64(0.0) {
                        continue;
                    }
                    // Borrowed from the cache (no 132-byte copy per sample).
                    let computed;
                    let jac = match cache {
                        Some(c) => &c.jacobians[k],
                        None => {
                            computed = brdf::eval_with_jacobian(&inputs.params[k], g.cos, settings);
                            &computed
                        }
                    };
                    let s = g.cos * g.falloff;
                    let df = d_out[k];
                    let mut d_rho = [T::from_f64(0.0); 3];
                    let mut d_cos = T::from_f64(0.0);
                    for i in 0..3 {
                        let f_i = e[i] * jac.value[i] * s;
                        d_log_gain += df[i] * f_i;
                        d_rho[i] = df[i] * e[i] * s;
                        // ∂f_i/∂c through max(0, c) (c > 0 here).
                        d_cos += df[i] * e[i] * jac.value[i] * g.falloff;
                    }
                    let (d_theta, d_cos_brdf) = jac.backward(d_rho);
                    d_cos += d_cos_brdf;
                    let l = k - base;
                    for (a, b) in dp[l].iter_mut().zip(d_theta) {
                        *a += b;
                    }
                    // c = n·h, n = ∇φ/|∇φ|: ∂c/∂∇φ = (h − n (n·h)) / |∇φ|.
                    for i in 0..3 {
                        dg[l][i] += d_cos * (g.h[i] - g.normal[i] * g.cos) / g.grad_norm;
                    }
                }
            }
            d_log_gain
        })
        .collect();
    let mut d_log_gain = T::from_f64(0.0);
    for x in partial {
        d_log_gain += x;
    }
    d_log_gain
}
