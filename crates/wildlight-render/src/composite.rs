//! Compositing per-sample attributes with the NeuS weights (SPEC §2:
//! C = Σ_k w_k c_k), forward and backward, plus the per-ray maps the trainer
//! and `wildlight render` need (accumulated weight, depth, normal).
//!
//! Backward convention: ∂L/∂(per-ray output) in, ∂L/∂w_k and ∂L/∂(per-sample
//! attribute) ADDED into the caller's buffers, so several composited
//! attributes (colour, flash-only, normals, …) accumulate into one ∂L/∂w that
//! [`crate::neus::NeusWeights::backward`] then consumes.

use rayon::prelude::*;

use crate::packing::{ray_chunks, ray_count, sample_count, split_mut};
use crate::real::dot3;
use wildlight_real::Real;

/// Per-ray Σ_k w_k a_k of a `C`-channel per-sample attribute.
///
/// # Panics
/// If lengths disagree with `offsets`.
pub fn composite<T: Real, const C: usize>(
    offsets: &[u32],
    weight: &[T],
    attr: &[[T; C]],
    out: &mut [[T; C]],
) {
    let n = sample_count(offsets);
    assert_eq!(weight.len(), n, "composite: weight length");
    assert_eq!(attr.len(), n, "composite: attribute length");
    assert_eq!(out.len(), ray_count(offsets), "composite: output length");
    let chunks = ray_chunks(offsets);
    let outs = split_mut(out, chunks.iter().map(|c| c.rays.clone()));
    chunks.par_iter().zip(outs).for_each(|(chunk, out)| {
        for (o, ray) in out.iter_mut().zip(chunk.rays.clone()) {
            let mut acc = [T::from_f64(0.0); C];
            for k in offsets[ray] as usize..offsets[ray + 1] as usize {
                let w = weight[k];
                for (a, &x) in acc.iter_mut().zip(&attr[k]) {
                    *a += w * x;
                }
            }
            *o = acc;
        }
    });
}

/// Backward of [`composite`]: given ∂L/∂out per ray, ADDS
/// ∂L/∂w_k = ∂L/∂out·a_k into `d_weight` and ∂L/∂a_k = w_k ∂L/∂out into
/// `d_attr` (pass `None` when the attribute needs no gradient).
///
/// # Panics
/// If lengths disagree with `offsets`.
pub fn composite_backward<T: Real, const C: usize>(
    offsets: &[u32],
    weight: &[T],
    attr: &[[T; C]],
    d_out: &[[T; C]],
    d_weight: &mut [T],
    d_attr: Option<&mut [[T; C]]>,
) {
    let n = sample_count(offsets);
    assert_eq!(weight.len(), n, "composite_backward: weight length");
    assert_eq!(attr.len(), n, "composite_backward: attribute length");
    assert_eq!(d_weight.len(), n, "composite_backward: d_weight length");
    assert_eq!(
        d_out.len(),
        ray_count(offsets),
        "composite_backward: d_out length"
    );
    let chunks = ray_chunks(offsets);
    let dws = split_mut(d_weight, chunks.iter().map(|c| c.samples.clone()));
    match d_attr {
        Some(d_attr) => {
            assert_eq!(d_attr.len(), n, "composite_backward: d_attr length");
            let das = split_mut(d_attr, chunks.iter().map(|c| c.samples.clone()));
            chunks
                .par_iter()
                .zip(dws)
                .zip(das)
                .for_each(|((chunk, dw), da)| {
                    let base = chunk.samples.start;
                    for ray in chunk.rays.clone() {
                        let g = d_out[ray];
                        for k in offsets[ray] as usize..offsets[ray + 1] as usize {
                            let l = k - base;
                            let mut s = T::from_f64(0.0);
                            for c in 0..C {
                                s += g[c] * attr[k][c];
                                da[l][c] += weight[k] * g[c];
                            }
                            dw[l] += s;
                        }
                    }
                });
        }
        None => {
            chunks.par_iter().zip(dws).for_each(|(chunk, dw)| {
                let base = chunk.samples.start;
                for ray in chunk.rays.clone() {
                    let g = d_out[ray];
                    for k in offsets[ray] as usize..offsets[ray + 1] as usize {
                        let mut s = T::from_f64(0.0);
                        for c in 0..C {
                            s += g[c] * attr[k][c];
                        }
                        dw[k - base] += s;
                    }
                }
            });
        }
    }
}

/// ADDS a per-ray ∂L/∂(Σ w) (e.g. from the mask loss, or −∂L/∂C·b for a
/// background colour b composited with weight 1 − Σ w) into ∂L/∂w_k.
pub fn acc_weight_backward<T: Real>(offsets: &[u32], d_acc: &[T], d_weight: &mut [T]) {
    assert_eq!(d_acc.len(), ray_count(offsets));
    assert_eq!(d_weight.len(), sample_count(offsets));
    for (ray, &g) in d_acc.iter().enumerate() {
        for dw in &mut d_weight[offsets[ray] as usize..offsets[ray + 1] as usize] {
            *dw += g;
        }
    }
}

/// Composites a per-ray background radiance b behind the samples:
/// C += b·(1 − Σw) (the "+ background" of SPEC §2; §6 for captures
/// without masks).
pub fn add_background<T: Real>(acc_weight: &[T], background: &[[T; 3]], colour: &mut [[T; 3]]) {
    assert_eq!(acc_weight.len(), colour.len(), "add_background: ray count");
    assert_eq!(background.len(), colour.len(), "add_background: ray count");
    for ((c, b), &w) in colour.iter_mut().zip(background).zip(acc_weight) {
        for i in 0..3 {
            c[i] += b[i] * (T::from_f64(1.0) - w);
        }
    }
}

/// Backward of [`add_background`]: ADDS −∂L/∂C·b into `d_acc_weight`
/// (per ray ∂L/∂(Σw), to pass to [`crate::neus::NeusWeights::backward`])
/// and ∂L/∂b = ∂L/∂C·(1 − Σw) into `d_background`.
pub fn add_background_backward<T: Real>(
    acc_weight: &[T],
    background: &[[T; 3]],
    d_colour: &[[T; 3]],
    d_acc_weight: &mut [T],
    d_background: Option<&mut [[T; 3]]>,
) {
    let n = acc_weight.len();
    assert!(background.len() == n && d_colour.len() == n && d_acc_weight.len() == n);
    for r in 0..n {
        d_acc_weight[r] += -dot3(d_colour[r], background[r]);
    }
    if let Some(db) = d_background {
        assert_eq!(db.len(), n, "add_background_backward: d_background length");
        for r in 0..n {
            for i in 0..3 {
                db[r][i] += d_colour[r][i] * (T::from_f64(1.0) - acc_weight[r]);
            }
        }
    }
}

/// Per-ray maps for evaluation and previews.
#[derive(Clone, Debug, Default)]
pub struct RayMaps {
    /// Σ_k w_k (the rendered mask).
    pub acc_weight: Vec<f32>,
    /// Σ_k w_k t_k / Σ_k w_k: expected distance along the ray (0 where Σ w = 0).
    pub depth: Vec<f32>,
    /// Σ_k w_k n_k with n_k = ∇φ_k/|∇φ_k|, renormalised to unit length (0 where Σ w = 0).
    pub normal: Vec<[f32; 3]>,
}

/// Composites depth, normal and accumulated weight per ray.
///
/// `t` are the sample distances along the rays, `sdf_grad` the raw SDF
/// gradients (normalised per sample here).
pub fn ray_maps(offsets: &[u32], weight: &[f32], t: &[f32], sdf_grad: &[[f32; 3]]) -> RayMaps {
    let n_rays = ray_count(offsets);
    let n = sample_count(offsets);
    assert_eq!(weight.len(), n);
    assert_eq!(t.len(), n);
    assert_eq!(sdf_grad.len(), n);
    let mut maps = RayMaps {
        acc_weight: vec![0.0; n_rays],
        depth: vec![0.0; n_rays],
        normal: vec![[0.0; 3]; n_rays],
    };
    let chunks = ray_chunks(offsets);
    let accs = split_mut(&mut maps.acc_weight, chunks.iter().map(|c| c.rays.clone()));
    let depths = split_mut(&mut maps.depth, chunks.iter().map(|c| c.rays.clone()));
    let normals = split_mut(&mut maps.normal, chunks.iter().map(|c| c.rays.clone()));
    chunks
        .par_iter()
        .zip(accs)
        .zip(depths)
        .zip(normals)
        .for_each(|(((chunk, acc), depth), normal)| {
            for (i, ray) in chunk.rays.clone().enumerate() {
                let (mut w_sum, mut d_sum, mut n_sum) = (0.0f32, 0.0f32, [0.0f32; 3]);
                for k in offsets[ray] as usize..offsets[ray + 1] as usize {
                    let w = weight[k];
                    w_sum += w;
                    d_sum += w * t[k];
                    let g = sdf_grad[k];
                    let len = dot3(g, g).sqrt().max(1e-12);
                    for (ns, gc) in n_sum.iter_mut().zip(g) {
                        *ns += w * gc / len;
                    }
                }
                acc[i] = w_sum;
                if w_sum > 0.0 {
                    depth[i] = d_sum / w_sum;
                    let len = dot3(n_sum, n_sum).sqrt();
                    if len > 0.0 {
                        normal[i] = n_sum.map(|x| x / len);
                    }
                }
            }
        });
    maps
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn composite_sums_weighted_attributes_per_ray() {
        let offsets = [0u32, 2, 2, 5];
        let weight = [0.5f64, 0.25, 0.1, 0.2, 0.3];
        let attr = [[1.0, 2.0], [4.0, 0.0], [1.0, 1.0], [2.0, 0.0], [0.0, 10.0]];
        let mut out = [[9.0; 2]; 3];
        composite(&offsets, &weight, &attr, &mut out);
        assert_eq!(out[0], [1.5, 1.0]);
        assert_eq!(out[1], [0.0, 0.0]);
        assert!((out[2][0] - 0.5).abs() < 1e-15 && (out[2][1] - 3.1).abs() < 1e-15);
        let mut d_w = [0.0; 5];
        acc_weight_backward(&offsets, &[1.0, 7.0, -2.0], &mut d_w);
        assert_eq!(d_w, [1.0, 1.0, -2.0, -2.0, -2.0]);
    }

    #[test]
    fn ray_maps_normalise_depth_and_normal() {
        let offsets = [0u32, 2, 2];
        let weight = [0.2f32, 0.6];
        let t = [1.0f32, 2.0];
        let grad = [[0.0f32, 0.0, 2.0], [0.0, 0.0, 0.5]];
        let maps = ray_maps(&offsets, &weight, &t, &grad);
        assert!((maps.acc_weight[0] - 0.8).abs() < 1e-6);
        assert!((maps.depth[0] - 1.75).abs() < 1e-6);
        assert_eq!(maps.normal[0], [0.0, 0.0, 1.0]);
        assert_eq!(
            (maps.acc_weight[1], maps.depth[1], maps.normal[1]),
            (0.0, 0.0, [0.0; 3])
        );
    }
}
