//! Importance sampling of the general BRDF ([`crate::general_brdf`]): a
//! mixture of a cosine lobe (diffuse and subsurface), GGX half vectors
//! drawn with density D(h)·(n·h) (metal and dielectric lobes, appendix
//! eq. 7) and clearcoat half vectors drawn with density D_c(h)·(n·h)
//! (appendix eq. 12), mixed with weights from the material parameters.

use std::f64::consts::PI;

use glam::DVec3;
use wildlight_material::{
    BASE_COLOR, BrdfSettings, CLEARCOAT, CLEARCOAT_GLOSS, DIELECTRIC, METALLIC, ROUGHNESS,
};

use crate::general_brdf::{clearcoat_d, clearcoat_roughness, ggx_d, ggx_k};

/// An orthonormal frame (t, b, n) around the unit vector `n`
/// (Duff et al. 2017, "Building an orthonormal basis, revisited").
pub fn frame(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// The lobe mixture for one material.
#[derive(Clone, Copy, Debug)]
pub struct LobeMixture {
    /// Probabilities of the diffuse, specular and clearcoat lobes.
    weights: [f64; 3],
    /// GGX k = r⁴ (alpha²).
    k: f64,
    /// Clearcoat roughness r_c.
    rc: f64,
}

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

impl LobeMixture {
    /// Lobe probabilities roughly proportional to each lobe's albedo, with
    /// a floor on the specular lobe (every surface has grazing Fresnel).
    pub fn new(params: &[f64; 9], settings: &BrdfSettings) -> LobeMixture {
        let base = [
            params[BASE_COLOR],
            params[BASE_COLOR + 1],
            params[BASE_COLOR + 2],
        ];
        let m = params[METALLIC];
        let lum = luminance(base).max(0.02);
        let diffuse = (1.0 - m) * lum;
        let specular = m * lum + (1.0 - m) * (0.08 * params[DIELECTRIC] + 0.05);
        let clear = 0.25 * params[CLEARCOAT] * settings.clearcoat_fresnel.max(0.04) * 2.0;
        let total = diffuse + specular + clear;
        LobeMixture {
            weights: [diffuse / total, specular / total, clear / total],
            k: ggx_k(params[ROUGHNESS]),
            rc: clearcoat_roughness(params[CLEARCOAT_GLOSS]),
        }
    }

    /// Draws a light direction for view `v` at normal `n` from three
    /// uniform numbers; `None` when the drawn direction is below the surface.
    pub fn sample(&self, n: DVec3, v: DVec3, u0: f64, u1: f64, u2: f64) -> Option<DVec3> {
        let (t, b) = frame(n);
        let phi = 2.0 * PI * u2;
        let local = |cos: f64| {
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            t * (sin * phi.cos()) + b * (sin * phi.sin()) + n * cos
        };
        let l = if u0 < self.weights[0] {
            local(u1.sqrt())
        } else {
            let cos2 = if u0 < self.weights[0] + self.weights[1] {
                // GGX: cos²θ_h = (1 − u)/(1 + (k − 1) u)
                (1.0 - u1) / (1.0 + (self.k - 1.0) * u1)
            } else {
                // GTR1 (clearcoat): cos²θ_h = (1 − r_c^(2(1 − u)))/(1 − r_c²)
                (1.0 - (self.rc * self.rc).powf(1.0 - u1)) / (1.0 - self.rc * self.rc)
            };
            let h = local(cos2.clamp(0.0, 1.0).sqrt());
            2.0 * v.dot(h) * h - v
        };
        (l.dot(n) > 0.0).then_some(l)
    }

    /// Solid-angle density of [`LobeMixture::sample`] drawing `l`.
    pub fn pdf(&self, n: DVec3, v: DVec3, l: DVec3) -> f64 {
        let cl = n.dot(l);
        if cl <= 0.0 {
            return 0.0;
        }
        let mut pdf = self.weights[0] * cl / PI;
        if let Some(h) = (l + v).try_normalize() {
            let ch = n.dot(h);
            let vh = v.dot(h).abs();
            if ch > 0.0 && vh > 0.0 {
                let jac = ch / (4.0 * vh);
                pdf += self.weights[1] * ggx_d(self.k, ch) * jac;
                if self.weights[2] > 0.0 {
                    pdf += self.weights[2] * clearcoat_d(self.rc, ch) * jac;
                }
            }
        }
        pdf
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::general_brdf;
    use rand::{Rng, SeedableRng};

    fn params(r: f64, m: f64, cc: f64) -> [f64; 9] {
        [0.7, 0.5, 0.3, r, 0.6, 0.2, m, 0.5, cc]
    }

    #[test]
    fn frame_is_orthonormal() {
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(0.3, -0.5, 0.2).normalize(),
            DVec3::new(0.0, 0.0, -0.9999).normalize(),
        ] {
            let (t, b) = frame(n);
            assert!((t.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
            assert!(t.dot(b).abs() < 1e-12 && t.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12);
            assert!((t.cross(b) - n).length() < 1e-12);
        }
    }

    /// The sampler draws with the density `pdf` reports: the estimate of
    /// ∫ f cos dω from samples equals a fine quadrature, for a glossy
    /// metal, a rough dielectric and a clearcoated material.
    #[test]
    fn sampling_matches_pdf() {
        let settings = BrdfSettings::default();
        let n = DVec3::new(0.2, 0.1, 1.0).normalize();
        let v = DVec3::new(0.5, -0.2, 0.8).normalize();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for p in [
            params(0.3, 1.0, 0.0),
            params(0.8, 0.0, 0.0),
            params(0.5, 0.0, 1.0),
        ] {
            let mix = LobeMixture::new(&p, &settings);
            // quadrature in the frame of n over (cos θ², φ) — cos θ = sqrt(s)
            let (t, b) = frame(n);
            let q = 600;
            let mut exact = 0.0;
            let mut pdf_total = 0.0;
            for i in 0..q {
                for j in 0..q {
                    let ct = ((i as f64 + 0.5) / q as f64).sqrt();
                    let st = (1.0 - ct * ct).sqrt();
                    let phi = 2.0 * PI * (j as f64 + 0.5) / q as f64;
                    let l = t * st * phi.cos() + b * st * phi.sin() + n * ct;
                    // dω = dφ d(cos θ) = dφ ds / (2 cos θ)
                    let dw = 2.0 * PI / q as f64 / q as f64 / (2.0 * ct);
                    exact += general_brdf::eval(&p, n, l, v, &settings)[0] * ct * dw;
                    pdf_total += mix.pdf(n, v, l) * dw;
                }
            }
            assert!(pdf_total <= 1.0 + 2e-2, "pdf integrates to {pdf_total}");
            let m = 200_000;
            let mut est = 0.0;
            for _ in 0..m {
                if let Some(l) = mix.sample(n, v, rng.random(), rng.random(), rng.random()) {
                    est +=
                        general_brdf::eval(&p, n, l, v, &settings)[0] * n.dot(l) / mix.pdf(n, v, l);
                }
            }
            est /= m as f64;
            assert!(
                (est - exact).abs() < 0.03 * exact,
                "{p:?}: {est} vs {exact}"
            );
        }
    }
}
