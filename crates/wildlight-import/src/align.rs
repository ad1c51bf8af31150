//! Similarity alignment (Umeyama 1991) of two point sets, and the pose
//! errors after it: for checking imported cameras against a ground truth
//! (`examples/check_poses.rs`), never used by the import itself.

use glam::{DMat3, DVec3};

/// x_b ≈ scale · rotation · x_a + translation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similarity {
    /// Scale.
    pub scale: f64,
    /// Rotation.
    pub rotation: DMat3,
    /// Translation.
    pub translation: DVec3,
}

impl Similarity {
    /// Applies the map to a point.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.scale * (self.rotation * p) + self.translation
    }
}

/// Jacobi eigen-decomposition of a symmetric 3×3 matrix: (eigenvalues,
/// eigenvectors as columns), sorted by decreasing eigenvalue.
#[allow(clippy::needless_range_loop)] // index notation is the algorithm's
fn symmetric_eigen(m: DMat3) -> ([f64; 3], DMat3) {
    let mut a = m.to_cols_array_2d(); // a[col][row], symmetric anyway
    let mut v = DMat3::IDENTITY.to_cols_array_2d();
    for _ in 0..64 {
        let (mut p, mut q, mut best) = (0, 1, 0.0);
        for i in 0..3 {
            for j in i + 1..3 {
                if a[i][j].abs() > best {
                    best = a[i][j].abs();
                    p = i;
                    q = j;
                }
            }
        }
        if best < 1e-300 {
            break;
        }
        let theta = 0.5 * (a[q][q] - a[p][p]) / a[p][q];
        let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
        let t = if theta == 0.0 { 1.0 } else { t };
        let c = 1.0 / (t * t + 1.0).sqrt();
        let s = t * c;
        for k in 0..3 {
            let (akp, akq) = (a[k][p], a[k][q]);
            a[k][p] = c * akp - s * akq;
            a[k][q] = s * akp + c * akq;
        }
        for k in 0..3 {
            let (apk, aqk) = (a[p][k], a[q][k]);
            a[p][k] = c * apk - s * aqk;
            a[q][k] = s * apk + c * aqk;
        }
        for row in &mut v {
            let (vp, vq) = (row[p], row[q]);
            row[p] = c * vp - s * vq;
            row[q] = s * vp + c * vq;
        }
    }
    // v is stored as v[col][row] transposed use: columns of V are eigvecs;
    // our updates treated v[k] as row k, so V = rows → transpose.
    let vm = DMat3::from_cols_array_2d(&v).transpose();
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|x, y| a[*y][*y].total_cmp(&a[*x][*x]));
    let vals = [a[idx[0]][idx[0]], a[idx[1]][idx[1]], a[idx[2]][idx[2]]];
    let vecs = DMat3::from_cols(vm.col(idx[0]), vm.col(idx[1]), vm.col(idx[2]));
    (vals, vecs)
}

/// The similarity mapping `a` onto `b` best in the least-squares sense
/// (Umeyama); `None` with fewer than 3 points or degenerate sets.
pub fn umeyama(a: &[DVec3], b: &[DVec3]) -> Option<Similarity> {
    let n = a.len();
    if n < 3 || n != b.len() {
        return None;
    }
    let ma = a.iter().copied().sum::<DVec3>() / n as f64;
    let mb = b.iter().copied().sum::<DVec3>() / n as f64;
    let mut cov = DMat3::ZERO; // Σ (b - mb)(a - ma)ᵀ / n
    let mut var_a = 0.0;
    for (pa, pb) in a.iter().zip(b) {
        let (da, db) = (*pa - ma, *pb - mb);
        cov += DMat3::from_cols(db * da.x, db * da.y, db * da.z);
        var_a += da.length_squared();
    }
    cov *= 1.0 / n as f64;
    var_a /= n as f64;
    if var_a <= 0.0 {
        return None;
    }
    // SVD of cov through the eigen-decomposition of covᵀcov.
    let (vals, v) = symmetric_eigen(cov.transpose() * cov);
    let sigma: Vec<f64> = vals.iter().map(|x| x.max(0.0).sqrt()).collect();
    if sigma[1] <= 1e-12 * sigma[0].max(1e-300) {
        return None;
    }
    let u0 = cov * v.col(0) / sigma[0];
    let u1 = cov * v.col(1) / sigma[1];
    let u2 = u0.cross(u1);
    let u = DMat3::from_cols(u0, u1, u2);
    let v2 = v.col(0).cross(v.col(1));
    let v = DMat3::from_cols(v.col(0), v.col(1), v2);
    // sign of the smallest singular value so that R is proper
    let s3 = (cov * v.col(2)).dot(u2);
    let rotation = u * v.transpose();
    let trace = sigma[0] + sigma[1] + s3;
    let scale = trace / var_a;
    let translation = mb - scale * (rotation * ma);
    Some(Similarity {
        scale,
        rotation,
        translation,
    })
}

/// The world rotation that best maps the orientations of one set of
/// cameras onto another's: for world → camera rotations `est` and `truth`
/// of the same cameras, R with truthₖ · R ≈ estₖ (the quaternion mean of
/// truthₖᵀ · estₖ). Aligning rotations by the orientations themselves is
/// better conditioned than by the centres when the cameras lie on a short
/// arc.
pub fn rotation_alignment(est: &[DMat3], truth: &[DMat3]) -> Option<DMat3> {
    let mut sum = glam::DVec4::ZERO;
    let mut first: Option<glam::DQuat> = None;
    for (e, t) in est.iter().zip(truth) {
        let q = glam::DQuat::from_mat3(&(t.transpose() * *e)).normalize();
        let q0 = *first.get_or_insert(q);
        let v = glam::DVec4::from(q);
        sum += if v.dot(glam::DVec4::from(q0)) < 0.0 {
            -v
        } else {
            v
        };
    }
    let q = glam::DQuat::from_vec4(sum.try_normalize()?);
    Some(DMat3::from_quat(q))
}

/// The angle of the rotation r_a⁻¹ r_b, in degrees.
pub fn rotation_angle_deg(r: DMat3) -> f64 {
    let cos = ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) / 2.0).clamp(-1.0, 1.0);
    cos.acos().to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_similarity() {
        let rot = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 2.1);
        let truth = Similarity {
            scale: 3.5,
            rotation: rot,
            translation: DVec3::new(0.3, -2.0, 5.0),
        };
        let a: Vec<DVec3> = (0..12)
            .map(|i| {
                let t = i as f64;
                DVec3::new(t.sin() * 2.0, (t * 1.7).cos(), t * 0.1 - 0.5)
            })
            .collect();
        let b: Vec<DVec3> = a.iter().map(|p| truth.apply(*p)).collect();
        let s = umeyama(&a, &b).unwrap();
        assert!((s.scale - 3.5).abs() < 1e-9, "{}", s.scale);
        assert!(rotation_angle_deg(s.rotation.transpose() * rot) < 1e-6);
        assert!((s.translation - truth.translation).length() < 1e-8);
        // orientations: est = truth · R
        let cams: Vec<DMat3> = (0..5)
            .map(|k| {
                DMat3::from_axis_angle(DVec3::new(k as f64, 1.0, 0.5).normalize(), 0.3 * k as f64)
            })
            .collect();
        let est: Vec<DMat3> = cams.iter().map(|c| *c * rot.transpose()).collect();
        let r = rotation_alignment(&est, &cams).unwrap();
        assert!(rotation_angle_deg(r * rot) < 1e-6);
    }
}
