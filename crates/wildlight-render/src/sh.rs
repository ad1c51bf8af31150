//! Real spherical harmonics of a unit direction up to degree 3 (four bands,
//! 16 values), orthonormal on the sphere, in the order l = 0..3,
//! m = −l..l. The ambient field takes a direction in this encoding (the view
//! direction, or the view direction reflected about the normal, which depends
//! on the SDF and so needs [`sh_deg4_jacobian`]).

use wildlight_real::Real;

/// Number of values of [`sh_deg4`].
pub const SH_DEG4_LEN: usize = 16;

/// The 16 real SH basis values of unit direction `d` (bands l = 0..3).
#[inline]
pub fn sh_deg4<T: Real>(d: [T; 3]) -> [T; SH_DEG4_LEN] {
    let c = |v: f64| T::from_f64(v);
    let [x, y, z] = d;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    [
        // l = 0
        c(0.282_094_791_773_878_14),
        // l = 1
        c(0.488_602_511_902_919_9) * y,
        c(0.488_602_511_902_919_9) * z,
        c(0.488_602_511_902_919_9) * x,
        // l = 2
        c(1.092_548_430_592_079_2) * x * y,
        c(1.092_548_430_592_079_2) * y * z,
        c(0.315_391_565_252_520_05) * (c(3.0) * zz - c(1.0)),
        c(1.092_548_430_592_079_2) * x * z,
        c(0.546_274_215_296_039_6) * (xx - yy),
        // l = 3
        c(0.590_043_589_926_643_5) * y * (c(3.0) * xx - yy),
        c(2.890_611_442_640_554) * x * y * z,
        c(0.457_045_799_464_465_8) * y * (c(5.0) * zz - c(1.0)),
        c(0.373_176_332_590_115_4) * z * (c(5.0) * zz - c(3.0)),
        c(0.457_045_799_464_465_8) * x * (c(5.0) * zz - c(1.0)),
        c(1.445_305_721_320_277) * z * (xx - yy),
        c(0.590_043_589_926_643_5) * x * (xx - c(3.0) * yy),
    ]
}

/// ∂Y_i/∂d_j of [`sh_deg4`] at `d` (the polynomials differentiated as they
/// are, without renormalising `d`): row i is the gradient of value i.
#[inline]
pub fn sh_deg4_jacobian<T: Real>(d: [T; 3]) -> [[T; 3]; SH_DEG4_LEN] {
    let c = |v: f64| T::from_f64(v);
    let z0 = T::from_f64(0.0);
    let [x, y, z] = d;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (k1, k2a, k2b, k2c) = (
        c(0.488_602_511_902_919_9),
        c(1.092_548_430_592_079_2),
        c(0.315_391_565_252_520_05),
        c(0.546_274_215_296_039_6),
    );
    let (k3a, k3b, k3c, k3d, k3e) = (
        c(0.590_043_589_926_643_5),
        c(2.890_611_442_640_554),
        c(0.457_045_799_464_465_8),
        c(0.373_176_332_590_115_4),
        c(1.445_305_721_320_277),
    );
    [
        [z0, z0, z0],
        [z0, k1, z0],
        [z0, z0, k1],
        [k1, z0, z0],
        [k2a * y, k2a * x, z0],
        [z0, k2a * z, k2a * y],
        [z0, z0, k2b * c(6.0) * z],
        [k2a * z, z0, k2a * x],
        [k2c * c(2.0) * x, -(k2c * c(2.0) * y), z0],
        // y (3x² − y²)
        [k3a * c(6.0) * x * y, k3a * (c(3.0) * xx - c(3.0) * yy), z0],
        [k3b * y * z, k3b * x * z, k3b * x * y],
        // y (5z² − 1)
        [z0, k3c * (c(5.0) * zz - c(1.0)), k3c * c(10.0) * y * z],
        // z (5z² − 3)
        [z0, z0, k3d * (c(15.0) * zz - c(3.0))],
        // x (5z² − 1)
        [k3c * (c(5.0) * zz - c(1.0)), z0, k3c * c(10.0) * x * z],
        // z (x² − y²)
        [
            k3e * c(2.0) * x * z,
            -(k3e * c(2.0) * y * z),
            k3e * (xx - yy),
        ],
        // x (x² − 3y²)
        [
            k3a * (c(3.0) * xx - c(3.0) * yy),
            -(k3a * c(6.0) * x * y),
            z0,
        ],
    ]
}

/// Encodes each direction of `dirs` into `out` (16 values per direction).
pub fn sh_deg4_batch<T: Real>(dirs: &[[T; 3]], out: &mut [[T; SH_DEG4_LEN]]) {
    assert_eq!(dirs.len(), out.len(), "sh_deg4_batch: length mismatch");
    for (o, &d) in out.iter_mut().zip(dirs) {
        *o = sh_deg4(d);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Jacobian against central differences in f64 at random points.
    #[test]
    fn jacobian_matches_finite_differences() {
        let mut uniform = crate::test_uniform(0x9e37_79b9_7f4a_7c15);
        let mut rnd = || uniform() * 2.0 - 1.0;
        for _ in 0..50 {
            let d = [rnd(), rnd(), rnd()];
            let jac = sh_deg4_jacobian(d);
            for j in 0..3 {
                let h = 1e-6;
                let (mut hi, mut lo) = (d, d);
                hi[j] += h;
                lo[j] -= h;
                let (a, b) = (sh_deg4(hi), sh_deg4(lo));
                for i in 0..SH_DEG4_LEN {
                    let fd = (a[i] - b[i]) / (2.0 * h);
                    assert!(
                        (fd - jac[i][j]).abs() < 1e-7 * (1.0 + fd.abs()),
                        "∂Y{i}/∂d{j}: {} vs {fd}",
                        jac[i][j]
                    );
                }
            }
        }
    }

    /// Monte-Carlo-free check: a Fibonacci-sphere quadrature of Y_i·Y_j is
    /// the identity (orthonormality) to quadrature accuracy.
    #[test]
    fn basis_is_orthonormal_on_the_sphere() {
        let n = 20_000;
        let mut gram = [[0.0f64; 16]; 16];
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            let y = sh_deg4([r * phi.cos(), r * phi.sin(), z]);
            for a in 0..16 {
                for b in 0..16 {
                    gram[a][b] += y[a] * y[b] * 4.0 * std::f64::consts::PI / n as f64;
                }
            }
        }
        for (a, row) in gram.iter().enumerate() {
            for (b, &g) in row.iter().enumerate() {
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((g - want).abs() < 2e-3, "gram[{a}][{b}] = {g}");
            }
        }
    }

    #[test]
    fn first_band_is_linear_in_the_direction() {
        let d = [0.6f64, 0.0, 0.8];
        let y = sh_deg4(d);
        assert!((y[3] / y[2] - 0.75).abs() < 1e-12);
        assert_eq!(y[1], 0.0);
        assert!((y[6] - 0.315_391_565_252_520_05 * (3.0 * 0.64 - 1.0)).abs() < 1e-12);
    }
}
