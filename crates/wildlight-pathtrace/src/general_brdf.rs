//! A general principled BRDF f(n, l, v; Θ) for separate light and view
//! directions that reduces exactly to the co-located model of SPEC §3
//! (appendix eqs. 1–15) when l = v.
//!
//! The ambient light of a synthetic capture comes from every direction, so
//! the renderer needs the BRDF for l ≠ v. Each lobe of SPEC §3 is the l = v
//! restriction of a standard Disney lobe; this module evaluates the full
//! lobes with h = normalize(l + v), c_l = n·l, c_v = n·v, c_h = n·h and
//! c_d = l·h:
//!
//! ```text
//!   ρ_base = base/π · (1 + (F_D90 − 1)(1 − c_l)^5)(1 + (F_D90 − 1)(1 − c_v)^5),
//!            F_D90 = 0.5 + 2 r c_d²                 → eq. 4 at l = v (c_d = 1)
//!   ρ_sub  = 1.25 base/π · (F_ss (1/(c_l + c_v) − 0.5) + 0.5),
//!            F_ss = (1 + (r c_d² − 1)(1 − c_l)^5)(1 + (r c_d² − 1)(1 − c_v)^5)
//!                                                   → eq. 5 at l = v
//!   specular lobes  D(c_h) · G(c_l, c_v) · F(c_d) / (4 c_l c_v)
//!            G = 1 / (1 + (Λ(c_l) + Λ(c_v))/2),  Λ(c) = (sqrt(1 + k (1 − c²)/c²) − 1)/2
//!            (height-correlated Smith with the mean Λ; equals eqs. 8/13 at l = v)
//!            F = F0 + (1 − F0)(1 − c_d)^5 (Schlick; equals F0 at l = v)
//! ```
//!
//! with F0 = base_color for the metal lobe (eq. 9), 0.08·sp for the
//! dielectric lobe (eq. 10 folds 0.08·sp into the weight with Fresnel 1),
//! and F_c for the clearcoat (eq. 14). The lobe weights are those of eq. 2.

use glam::DVec3;
use wildlight_material::brdf::{MIN_ALPHA, MIN_COS};
use wildlight_material::{
    BASE_COLOR, BrdfSettings, CLEARCOAT, CLEARCOAT_GLOSS, DIELECTRIC, METALLIC, ROUGHNESS,
    SUBSURFACE,
};

use std::f64::consts::PI;

/// GGX distribution D of appendix eq. 7 with k = alpha²: k / (π ((k − 1) c² + 1)²),
/// the denominator written as (1 − c)(1 + c) + k c² for precision near c = 1.
#[inline]
pub fn ggx_d(k: f64, c: f64) -> f64 {
    let den = (1.0 - c) * (1.0 + c) + k * c * c;
    k / (PI * den * den)
}

/// Clearcoat distribution D_c of appendix eq. 12 with roughness `rc`.
#[inline]
pub fn clearcoat_d(rc: f64, c: f64) -> f64 {
    let den = (1.0 - c) * (1.0 + c) + rc * rc * c * c;
    (rc * rc - 1.0) / (2.0 * PI * rc.ln() * den)
}

/// Smith Λ for a GGX-like lobe with k = alpha², so that 1/(1 + Λ) is the
/// G of appendix eq. 8 (k = r⁴) or eq. 13 (k = 0.25²).
#[inline]
pub fn smith_lambda(k: f64, c: f64) -> f64 {
    let tan2 = (1.0 - c) * (1.0 + c) / (c * c);
    0.5 * ((1.0 + k * tan2).sqrt() - 1.0)
}

/// Clearcoat roughness r_c = 0.1 − 0.099 g (appendix eq. 15).
#[inline]
pub fn clearcoat_roughness(gloss: f64) -> f64 {
    0.1 - 0.099 * gloss
}

/// GGX k = alpha² = r⁴ with alpha clamped to [`MIN_ALPHA`] (SPEC §3 numerical safety).
#[inline]
pub fn ggx_k(roughness: f64) -> f64 {
    let alpha = (roughness * roughness).max(MIN_ALPHA);
    alpha * alpha
}

#[inline]
fn pow5(x: f64) -> f64 {
    let x2 = x * x;
    x2 * x2 * x
}

/// Evaluates ρ(n, l, v; Θ) (RGB, without the cosine factor) for unit
/// vectors `n` (normal), `l` (towards the light) and `v` (towards the
/// viewer). Zero when l or v is below the surface (n·l ≤ 0 or n·v ≤ 0).
/// Cosines are clamped to ≥ [`MIN_COS`] and the GGX alpha to ≥
/// [`MIN_ALPHA`], as in `wildlight_material::brdf::eval`.
pub fn eval(params: &[f64; 9], n: DVec3, l: DVec3, v: DVec3, settings: &BrdfSettings) -> [f64; 3] {
    let cl_raw = n.dot(l);
    let cv_raw = n.dot(v);
    if cl_raw <= 0.0 || cv_raw <= 0.0 {
        return [0.0; 3];
    }
    let h = match (l + v).try_normalize() {
        Some(h) => h,
        None => return [0.0; 3],
    };
    let cl = cl_raw.max(MIN_COS);
    let cv = cv_raw.max(MIN_COS);
    let ch = n.dot(h).max(MIN_COS);
    let cd = l.dot(h).clamp(0.0, 1.0);

    let r = params[ROUGHNESS];
    let ss = params[SUBSURFACE];
    let m = params[METALLIC];
    let sp = params[DIELECTRIC];
    let cc = params[CLEARCOAT];
    let gloss = params[CLEARCOAT_GLOSS];

    let ql = pow5(1.0 - cl);
    let qv = pow5(1.0 - cv);
    let qd = pow5(1.0 - cd);
    let cd2 = cd * cd;

    // eq. 4 generalised (Disney diffuse retro-reflection).
    let fd90 = 0.5 + 2.0 * r * cd2;
    let f_base = (1.0 + (fd90 - 1.0) * ql) * (1.0 + (fd90 - 1.0) * qv) / PI;
    // eq. 5 generalised (Hanrahan–Krueger-like subsurface of Disney).
    let fss90 = r * cd2;
    let fss = (1.0 + (fss90 - 1.0) * ql) * (1.0 + (fss90 - 1.0) * qv);
    let f_sub = 1.25 / PI * (fss * (1.0 / (cl + cv) - 0.5) + 0.5);
    // eq. 3
    let diffuse = (1.0 - ss) * f_base + ss * f_sub;

    // eqs. 6–8: S = D G / (4 c_l c_v) without Fresnel.
    let k = ggx_k(r);
    let g = 1.0 / (1.0 + 0.5 * (smith_lambda(k, cl) + smith_lambda(k, cv)));
    let s = ggx_d(k, ch) * g / (4.0 * cl * cv);

    // eqs. 11–15 with Schlick Fresnel around F_c.
    let rc = clearcoat_roughness(gloss);
    let gc = 1.0 / (1.0 + 0.5 * (smith_lambda(0.0625, cl) + smith_lambda(0.0625, cv)));
    let fc = settings.clearcoat_fresnel + (1.0 - settings.clearcoat_fresnel) * qd;
    let clear = clearcoat_d(rc, ch) * gc * fc / (4.0 * cl * cv);

    // eq. 10 with Fresnel 0.08 sp at normal incidence.
    let f_diel = 0.08 * sp + (1.0 - 0.08 * sp) * qd;
    let grey = (1.0 - m) * f_diel * s + 0.25 * cc * clear;
    let mut out = [0.0; 3];
    for (i, o) in out.iter_mut().enumerate() {
        let base = params[BASE_COLOR + i];
        // eq. 9: metal Fresnel = base_color at normal incidence.
        let f_metal = base + (1.0 - base) * qd;
        // eq. 2
        *o = (1.0 - m) * base * diffuse + m * f_metal * s + grey;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn random_params(rng: &mut Pcg64) -> [f64; 9] {
        let mut p = [0.0; 9];
        for v in &mut p {
            *v = rng.random::<f64>();
        }
        p[ROUGHNESS] = 0.02 + 0.98 * rng.random::<f64>();
        p
    }

    fn random_unit(rng: &mut Pcg64) -> DVec3 {
        loop {
            let v = DVec3::new(
                rng.random::<f64>() * 2.0 - 1.0,
                rng.random::<f64>() * 2.0 - 1.0,
                rng.random::<f64>() * 2.0 - 1.0,
            );
            if let Some(u) = v.try_normalize()
                && v.length() <= 1.0
            {
                return u;
            }
        }
    }

    #[test]
    fn equals_spec_model_when_light_equals_view() {
        let mut rng = Pcg64::seed_from_u64(7);
        for fresnel in [0.2, 0.04] {
            let settings = BrdfSettings {
                clearcoat_fresnel: fresnel,
            };
            for _ in 0..2000 {
                let p = random_params(&mut rng);
                let n = random_unit(&mut rng);
                let mut l = random_unit(&mut rng);
                if l.dot(n) < 0.0 {
                    l = -l;
                }
                let c = n.dot(l);
                if c < 1e-3 {
                    continue;
                }
                let general = eval(&p, n, l, l, &settings);
                let spec = wildlight_material::brdf::eval(&p, c, &settings);
                for i in 0..3 {
                    let rel = (general[i] - spec[i]).abs() / spec[i].abs().max(1e-300);
                    assert!(
                        rel < 1e-12,
                        "channel {i}: {} vs {} (c = {c}, p = {p:?})",
                        general[i],
                        spec[i]
                    );
                }
            }
        }
    }

    #[test]
    fn is_symmetric_in_light_and_view() {
        let mut rng = Pcg64::seed_from_u64(3);
        let settings = BrdfSettings::default();
        for _ in 0..500 {
            let p = random_params(&mut rng);
            let n = DVec3::Z;
            let mut l = random_unit(&mut rng);
            let mut v = random_unit(&mut rng);
            l.z = l.z.abs();
            v.z = v.z.abs();
            let a = eval(&p, n, l, v, &settings);
            let b = eval(&p, n, v, l, &settings);
            for i in 0..3 {
                assert!((a[i] - b[i]).abs() <= 1e-12 * a[i].abs().max(1.0));
            }
        }
    }

    #[test]
    fn below_the_surface_is_zero() {
        let p = wildlight_material::Material::default().to_array::<f64>();
        let s = BrdfSettings::default();
        let l = DVec3::new(0.3, 0.0, -0.2).normalize();
        assert_eq!(eval(&p, DVec3::Z, l, DVec3::Z, &s), [0.0; 3]);
        assert_eq!(eval(&p, DVec3::Z, DVec3::Z, l, &s), [0.0; 3]);
    }

    /// A white Lambertian-like material (rough, no specular) reflects at most
    /// what it receives: the directional albedo ∫ ρ c_l dω stays ≤ 1.05 (the
    /// Disney diffuse is not exactly energy conserving) and ≥ 0.5.
    #[test]
    fn rough_white_albedo_is_plausible() {
        let mut p = [0.0; 9];
        p[0] = 1.0;
        p[1] = 1.0;
        p[2] = 1.0;
        p[ROUGHNESS] = 1.0;
        let s = BrdfSettings::default();
        let v = DVec3::new(0.5, 0.0, 0.8).normalize();
        let n = 400;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                // uniform hemisphere grid in (cos θ, φ)
                let ct = (i as f64 + 0.5) / n as f64;
                let phi = 2.0 * PI * (j as f64 + 0.5) / n as f64;
                let st = (1.0 - ct * ct).sqrt();
                let l = DVec3::new(st * phi.cos(), st * phi.sin(), ct);
                sum += eval(&p, DVec3::Z, l, v, &s)[0] * ct;
            }
        }
        let albedo = sum * 2.0 * PI / (n * n) as f64;
        assert!(albedo > 0.5 && albedo < 1.05, "albedo {albedo}");
    }
}
