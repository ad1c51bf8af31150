//! A smoothness prior on the surface normals: the SDF's normal should turn
//! slowly between nearby surface points.
//!
//! Noisy photographs (sensor noise, or the Monte Carlo noise of a synthetic
//! capture) can be fitted by bumps finer than a pixel: the finest levels of
//! the SDF's hash grid are fine enough to hold them, and a tilted normal
//! changes both the flash term's cosine and the ambient field's input.
//! Such bumps fit the training photos and spoil every other view, and the
//! speckle they leave in the normals makes a sharp specular lobe look worse
//! than a blurred one. For points x_j on the surface (the expected hit
//! points of foreground rays) and small random offsets ε_j,
//!
//! L_normal = λ · (1/m) Σ_j ρ(‖Δ_j‖),
//!
//! with n = ∇φ/|∇φ| the normal the renderer shades with (∇φ as the pass
//! computes it, [`wildlight_fields::NormalMethod`]), ρ(d) = sqrt(d² + η²)
//! − η a pseudo-Huber penalty (quadratic below η, linear above, so that a
//! crease costs no more than its length while speckle is pushed out) and Δ
//! the second difference Δ = P (n(x + ε) + n(x − ε) − 2 n(x)), P = I −
//! n(x) n(x)ᵀ the projection onto the tangent plane at x. For ε in that
//! plane (the trainer projects its offsets there, with the rays' expected
//! normals), n(x + ε) + n(x − ε) is parallel to n(x) on a sphere or a
//! cylinder of any radius, so Δ = 0 there: curvature itself costs nothing,
//! only a change of curvature (speckle, a bump, a crease) does, and a small
//! tightly curved part is not pulled flat. A third point per pair, x − ε,
//! makes it cost 1.5 times the normal evaluations of a first difference.
//!
//! Only the SDF field receives the gradient (the points are held fixed).
//! The prior is the project's addition: SPEC §4 names "curvature or normal
//! smoothness" as welcome when measured to help. Its weight is
//! `loss.normal_smoothness`; 0 turns it off.

use crate::float::{Float, dot3, of, sqrt, to_f64, unit3, unit3_backward};
use crate::smoothness::pair_points;
use wildlight_fields::{FieldGrads, NormalContext, NormalMethod, SdfField};

/// The offsets ε of the normal prior's pairs: the material prior's offsets
/// projected onto the tangent plane of each point's normal, since
/// n(x + ε) + n(x − ε) − 2 n(x) is zero on a circle only for x ± ε at the
/// same height above the surface.
pub fn pair_offsets(offsets: &[[f32; 3]], normals: &[[f32; 3]]) -> Vec<[f32; 3]> {
    assert_eq!(offsets.len(), normals.len(), "one normal per offset");
    offsets
        .iter()
        .zip(normals)
        .map(|(e, n)| {
            let en = dot3(*e, *n);
            [0, 1, 2].map(|a| e[a] - en * n[a])
        })
        .collect()
}

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

/// The second difference of three unit normals n₀ = n(x), n₁ = n(x + ε),
/// n₂ = n(x − ε): s = n₁ + n₂ − 2 n₀ and its tangential part Δ = s −
/// (s·n₀) n₀.
#[derive(Clone, Copy, Debug)]
pub struct SecondDifference<T> {
    /// Δ, the part of s tangent to the surface at x.
    pub tangential: [T; 3],
    /// s.
    pub sum: [T; 3],
    /// s·n₀.
    pub along_normal: T,
}

impl<T: Float> SecondDifference<T> {
    /// Backward through Δ = P s, s = n₁ + n₂ − 2 n₀, P = I − n₀ n₀ᵀ, for
    /// `u` = ∂L/∂Δ and the normal `n0` it was computed with: returns
    /// (∂L/∂n₀, ∂L/∂n₁ = ∂L/∂n₂), with ∂L/∂n₁ = ∂L/∂n₂ = P u and
    /// ∂L/∂n₀ = −2 P u − (n₀·s) u − (u·n₀) s.
    #[inline]
    pub fn backward(&self, n0: [T; 3], u: [T; 3]) -> ([T; 3], [T; 3]) {
        let two = of::<T>(2.0);
        let un = dot3(u, n0);
        let pu = [0, 1, 2].map(|a| u[a] - un * n0[a]);
        let d0 = [0, 1, 2].map(|a| -two * pu[a] - self.along_normal * u[a] - un * self.sum[a]);
        (d0, pu)
    }
}

/// [`SecondDifference`] of the normals `n0` (at x), `n1` and `n2`.
#[inline]
pub fn second_difference<T: Float>(n0: [T; 3], n1: [T; 3], n2: [T; 3]) -> SecondDifference<T> {
    let two = of::<T>(2.0);
    let sum = [0, 1, 2].map(|a| n1[a] + n2[a] - two * n0[a]);
    let along_normal = dot3(sum, n0);
    SecondDifference {
        tangential: [0, 1, 2].map(|a| sum[a] - along_normal * n0[a]),
        sum,
        along_normal,
    }
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
    /// Evaluates λ · L_normal (λ = `weight`) around the points `centres[j]`
    /// and their offsets `offsets[j]`, with normals from the tetrahedral
    /// `normals`, and ADDS its gradient with
    /// respect to the SDF field's parameters into `grads`. Returns the mean
    /// of ρ, without λ.
    pub fn forward_backward(
        &mut self,
        sdf: &SdfField<T>,
        centres: &[[T; 3]],
        offsets: &[[T; 3]],
        normals: NormalMethod,
        weight: T,
        grads: &mut FieldGrads<T>,
    ) -> f64 {
        let m = pair_points(centres, offsets, &mut self.points);
        if m == 0 {
            return 0.0;
        }
        // The third set of points: centre − offset.
        self.points.extend(
            centres[..m]
                .iter()
                .zip(offsets)
                .map(|(c, e)| [c[0] - e[0], c[1] - e[1], c[2] - e[2]]),
        );
        let n_points = self.points.len();
        sdf.forward_with_normals(&self.points, normals, &mut self.ctx);
        let scale = weight / of(m as f64);
        let mut sum = 0.0f64;
        self.d_gradient.clear();
        self.d_gradient.resize(n_points, [T::ZERO; 3]);
        let g = &self.ctx.gradient;
        for j in 0..m {
            let (n0, len0) = unit3(g[j]);
            let (n1, len1) = unit3(g[m + j]);
            let (n2, len2) = unit3(g[2 * m + j]);
            let sd = second_difference(n0, n1, n2);
            let (rho, u) = pseudo_huber(sd.tangential);
            sum += to_f64(rho);
            let (d0, pu) = sd.backward(n0, u.map(|v| scale * v));
            self.d_gradient[m + j] = unit3_backward(pu, n1, len1);
            self.d_gradient[2 * m + j] = unit3_backward(pu, n2, len2);
            self.d_gradient[j] = unit3_backward(d0, n0, len0);
        }
        self.d_sdf.clear();
        self.d_sdf.resize(n_points, T::ZERO);
        self.d_features.clear();
        self.d_features
            .resize(n_points * sdf.config().n_features, T::ZERO);
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
