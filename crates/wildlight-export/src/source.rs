//! The fields an export reads: [`FieldSource`], implemented by a trained
//! model (by the trainer) or by closures ([`AnalyticSource`], for tests,
//! examples and benchmarks).
//!
//! Everything is in the normalized frame (SPEC §5): the object lies inside
//! the unit sphere; `ExportOptions::scale_mat` maps it to world units.

use glam::Vec3;
use wildlight_material::PARAM_COUNT;

/// Largest batch the pipeline passes to one [`FieldSource`] call.
pub const MAX_BATCH: usize = 4096;

/// The trained fields an asset is exported from, evaluated in batches.
///
/// The pipeline calls these methods concurrently from several rayon
/// threads, with batches of at most [`MAX_BATCH`] points, all in the
/// normalized frame. `out` always has the same length as `points`.
pub trait FieldSource: Sync {
    /// Signed distance (negative inside the object) at each point.
    fn sdf(&self, points: &[[f32; 3]], out: &mut [f32]);

    /// The 9 material parameters (SPEC §3 order, each in [0, 1]) at each point.
    fn material(&self, points: &[[f32; 3]], out: &mut [[f32; PARAM_COUNT]]);

    /// The SDF gradient at each point (not necessarily unit length).
    ///
    /// The default takes central differences of [`FieldSource::sdf`] with
    /// step [`FieldSource::gradient_step`]; a model with an analytic
    /// gradient should override it.
    fn gradient(&self, points: &[[f32; 3]], out: &mut [[f32; 3]]) {
        let h = self.gradient_step();
        let mut probes = Vec::with_capacity(points.len() * 6);
        for p in points {
            for axis in 0..3 {
                for sign in [1.0f32, -1.0] {
                    let mut q = *p;
                    q[axis] += sign * h;
                    probes.push(q);
                }
            }
        }
        let mut values = vec![0.0f32; probes.len()];
        for (chunk_points, chunk_values) in
            probes.chunks(MAX_BATCH).zip(values.chunks_mut(MAX_BATCH))
        {
            self.sdf(chunk_points, chunk_values);
        }
        for (g, v) in out.iter_mut().zip(values.chunks_exact(6)) {
            for axis in 0..3 {
                g[axis] = (v[2 * axis] - v[2 * axis + 1]) / (2.0 * h);
            }
        }
    }

    /// Step of the default finite-difference gradient (normalized units).
    fn gradient_step(&self) -> f32 {
        1e-4
    }
}

/// A [`FieldSource`] made of closures evaluated point by point.
pub struct AnalyticSource<S, M> {
    sdf: S,
    material: M,
    gradient: Option<Box<dyn Fn(Vec3) -> Vec3 + Sync>>,
}

impl<S, M> AnalyticSource<S, M>
where
    S: Fn(Vec3) -> f32 + Sync,
    M: Fn(Vec3) -> [f32; PARAM_COUNT] + Sync,
{
    /// A source from an SDF and a material function (normalized frame);
    /// gradients by central differences.
    pub fn new(sdf: S, material: M) -> Self {
        AnalyticSource {
            sdf,
            material,
            gradient: None,
        }
    }

    /// Uses an exact gradient instead of finite differences.
    pub fn with_gradient(mut self, gradient: impl Fn(Vec3) -> Vec3 + Sync + 'static) -> Self {
        self.gradient = Some(Box::new(gradient));
        self
    }

    /// The SDF at one point.
    pub fn sdf_at(&self, p: Vec3) -> f32 {
        (self.sdf)(p)
    }

    /// The material at one point.
    pub fn material_at(&self, p: Vec3) -> [f32; PARAM_COUNT] {
        (self.material)(p)
    }
}

impl<S, M> FieldSource for AnalyticSource<S, M>
where
    S: Fn(Vec3) -> f32 + Sync,
    M: Fn(Vec3) -> [f32; PARAM_COUNT] + Sync,
{
    fn sdf(&self, points: &[[f32; 3]], out: &mut [f32]) {
        for (o, p) in out.iter_mut().zip(points) {
            *o = (self.sdf)(Vec3::from_array(*p));
        }
    }

    fn material(&self, points: &[[f32; 3]], out: &mut [[f32; PARAM_COUNT]]) {
        for (o, p) in out.iter_mut().zip(points) {
            *o = (self.material)(Vec3::from_array(*p));
        }
    }

    fn gradient(&self, points: &[[f32; 3]], out: &mut [[f32; 3]]) {
        match &self.gradient {
            Some(g) => {
                for (o, p) in out.iter_mut().zip(points) {
                    *o = g(Vec3::from_array(*p)).to_array();
                }
            }
            None => {
                let h = self.gradient_step();
                for (o, p) in out.iter_mut().zip(points) {
                    let p = Vec3::from_array(*p);
                    for axis in 0..3 {
                        let mut e = Vec3::ZERO;
                        e[axis] = h;
                        o[axis] = ((self.sdf)(p + e) - (self.sdf)(p - e)) / (2.0 * h);
                    }
                }
            }
        }
    }
}

/// Evaluates `f` over `points` in parallel batches of at most [`MAX_BATCH`].
pub(crate) fn par_eval<T: Send + Copy + Default>(
    points: &[[f32; 3]],
    f: impl Fn(&[[f32; 3]], &mut [T]) + Sync,
) -> Vec<T> {
    use rayon::prelude::*;
    let mut out = vec![T::default(); points.len()];
    out.par_chunks_mut(MAX_BATCH)
        .zip(points.par_chunks(MAX_BATCH))
        .for_each(|(o, p)| f(p, o));
    out
}

/// The SDF restricted to the unit sphere: max(φ(p), |p| − 1) (the CSG
/// intersection with the region of interest, SPEC §9).
#[inline]
pub(crate) fn bounded_sdf(phi: f32, p: [f32; 3]) -> f32 {
    phi.max(Vec3::from_array(p).length() - 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_gradient_matches_analytic_gradient() {
        // A source that only overrides sdf(): the trait's default gradient.
        struct Plane;
        impl FieldSource for Plane {
            fn sdf(&self, points: &[[f32; 3]], out: &mut [f32]) {
                for (o, p) in out.iter_mut().zip(points) {
                    *o = 0.3 * p[0] - 0.4 * p[1] + p[2] * p[2];
                }
            }
            fn material(&self, _: &[[f32; 3]], out: &mut [[f32; PARAM_COUNT]]) {
                out.fill([0.5; PARAM_COUNT]);
            }
            fn gradient_step(&self) -> f32 {
                1e-2
            }
        }
        let mut g = [[0.0; 3]; 2];
        Plane.gradient(&[[0.1, 0.2, 0.3], [-0.5, 0.0, -0.25]], &mut g);
        let expect = [[0.3, -0.4, 0.6], [0.3, -0.4, -0.5]];
        for (a, b) in g.iter().zip(expect) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-4, "{a:?} vs {b:?}");
            }
        }
    }
}
