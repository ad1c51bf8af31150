//! A smoothness prior on the surface normals: the SDF's normal should turn
//! slowly between nearby surface points.
//!
//! Noisy photographs (sensor noise, or the Monte Carlo noise of a synthetic
//! capture) can be fitted by bumps finer than a pixel: the finest levels of
//! the SDF's hash grid are fine enough to hold them, and a tilted normal
//! changes both the flash term's cosine and the ambient field's input.
//! Such bumps fit the training photos and spoil every other view, and the
//! speckle they leave in the normals makes a sharp specular lobe look worse
//! than a blurred one. For pairs (x_j, x_j + ε_j), x_j on the surface (the
//! expected hit point of a foreground ray) and ε_j a small random offset,
//!
//! L_normal = λ · (1/m) Σ_j ρ(‖n(x_j) − n(x_j + ε_j)‖),
//!
//! with n = ∇φ/|∇φ| the normal the renderer shades with (the SDF's
//! finite-difference gradient at the same step) and ρ(d) = sqrt(d² + η²) − η
//! a pseudo-Huber penalty: quadratic below η, linear above, so that a crease
//! costs no more than its length while speckle is pushed out. Only the SDF
//! field receives the gradient (the points are held fixed). The prior is the
//! project's addition: SPEC §4 names "curvature or normal smoothness" as
//! welcome when measured to help. Its weight is `loss.normal_smoothness`; 0
//! turns it off.

use crate::float::{Float, dot3, of, sqrt, to_f64, unit3, unit3_backward};
use crate::smoothness::pair_points;
use wildlight_fields::{FdScheme, FieldGrads, NormalContext, SdfField};

/// η of the pseudo-Huber penalty: differences of normals below this are
/// penalised quadratically.
pub const HUBER_ETA: f64 = 0.01;

/// ρ(d) = sqrt(d² + η²) − η for the difference vector `d`, and ∂ρ/∂d.
#[inline]
pub fn pseudo_huber<T: Float>(d: [T; 3]) -> (T, [T; 3]) {
    let eta = of::<T>(HUBER_ETA);
    let r = sqrt(dot3(d, d) + eta * eta);
    (r - eta, d.map(|v| v / r))
}

/// Buffers of the normal smoothness term between calls.
#[derive(Default)]
pub struct NormalSmoothness<T> {
    points: Vec<[T; 3]>,
    ctx: NormalContext<T>,
    d_sdf: Vec<T>,
    d_features: Vec<T>,
    d_gradient: Vec<[T; 3]>,
}

impl<T: Float + Default> NormalSmoothness<T> {
    /// Evaluates λ · L_normal for the pairs (centres[j], centres[j] +
    /// offsets[j]), with normals from the tetrahedral finite differences of
    /// step `fd_step`, and ADDS its gradient with respect to the SDF field's
    /// parameters into `grads`. Returns the unweighted mean of ρ.
    pub fn forward_backward(
        &mut self,
        sdf: &SdfField<T>,
        centres: &[[T; 3]],
        offsets: &[[T; 3]],
        fd_step: f64,
        weight: T,
        grads: &mut FieldGrads<T>,
    ) -> f64 {
        let m = pair_points(centres, offsets, &mut self.points);
        if m == 0 {
            return 0.0;
        }
        sdf.forward_with_normals(&self.points, FdScheme::Tetrahedral, fd_step, &mut self.ctx);
        let scale = weight / of(m as f64);
        let mut sum = 0.0f64;
        self.d_gradient.clear();
        self.d_gradient.resize(2 * m, [T::ZERO; 3]);
        let (gn, gf) = self.ctx.gradient.split_at(m);
        let (d_near, d_far) = self.d_gradient.split_at_mut(m);
        for (((ga, gb), da), db) in gn.iter().zip(gf).zip(d_near).zip(d_far) {
            let (na, len_a) = unit3(*ga);
            let (nb, len_b) = unit3(*gb);
            let d = [na[0] - nb[0], na[1] - nb[1], na[2] - nb[2]];
            let (rho, u) = pseudo_huber(d);
            sum += to_f64(rho);
            // ∂ρ/∂n_a = u, ∂ρ/∂n_b = −u, then through n = g/|g|.
            let u = u.map(|v| scale * v);
            *da = unit3_backward(u, na, len_a);
            *db = unit3_backward(u.map(|v| -v), nb, len_b);
        }
        self.d_sdf.clear();
        self.d_sdf.resize(2 * m, T::ZERO);
        self.d_features.clear();
        self.d_features
            .resize(2 * m * sdf.config().n_features, T::ZERO);
        sdf.backward_with_normals(
            &mut self.ctx,
            &self.d_sdf,
            &self.d_features,
            &self.d_gradient,
            grads,
        );
        sum / m as f64
    }
}
