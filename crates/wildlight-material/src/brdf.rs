//! The co-located principled BRDF ρ(n, h; Θ) of SPEC §3 (appendix eqs. 1–15)
//! and its exact derivatives.
//!
//! Light and view coincide (the flash sits at the camera centre), so the
//! model depends on the surface only through c = n·h. The RGB value splits
//! into a part proportional to the base colour and a grey part:
//!
//! ```text
//!   ρ = base_color · a(Θ, c) + b(Θ, c)
//!   a = (1 − m)·ρ_diffuse/base_color + m·S          (eqs. 2, 3, 9)
//!   b = 0.08·(1 − m)·sp·S + 0.25·cc·ρ_clearcoat      (eqs. 2, 10)
//!   S = D·G / (4c²)                                  (eq. 6)
//! ```
//!
//! which keeps the derivatives short: ∂ρ/∂base_color is diagonal with `a`.

use crate::{BASE_COLOR, CLEARCOAT, CLEARCOAT_GLOSS, DIELECTRIC, METALLIC, ROUGHNESS, SUBSURFACE};
use wildlight_real::Real;

/// Smallest c = n·h the model evaluates (SPEC §3 numerical safety).
pub const MIN_COS: f64 = 1e-4;
/// Smallest GGX alpha = roughness² (SPEC §3 numerical safety).
pub const MIN_ALPHA: f64 = 1e-4;

/// Settings of the material model that are not per-point parameters.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BrdfSettings {
    /// Clearcoat Fresnel F_c (appendix eq. 14 gives 0.2; the public
    /// WildLight code and Burley's notes use 0.04, see SPEC §8).
    pub clearcoat_fresnel: f64,
}

impl Default for BrdfSettings {
    fn default() -> Self {
        Self {
            clearcoat_fresnel: 0.2,
        }
    }
}

/// The value of ρ and its derivatives with respect to the 9 parameters and c.
#[derive(Clone, Copy, Debug)]
pub struct BrdfJacobian<T> {
    /// ρ (RGB).
    pub value: [T; 3],
    /// `d_params[j][i]` = ∂ρ_i / ∂Θ_j, in the parameter order of [`crate::Material`].
    pub d_params: [[T; 3]; 9],
    /// ∂ρ_i / ∂c.
    pub d_cos: [T; 3],
}

impl<T: Real> BrdfJacobian<T> {
    /// Chain rule: given ∂L/∂ρ, returns (∂L/∂Θ, ∂L/∂c).
    pub fn backward(&self, d_value: [T; 3]) -> ([T; 9], T) {
        let mut d_params = [T::default(); 9];
        for (dp, col) in d_params.iter_mut().zip(&self.d_params) {
            *dp = col[0] * d_value[0] + col[1] * d_value[1] + col[2] * d_value[2];
        }
        let d_cos =
            self.d_cos[0] * d_value[0] + self.d_cos[1] * d_value[1] + self.d_cos[2] * d_value[2];
        (d_params, d_cos)
    }
}

/// A value and its partial derivatives with respect to two inputs.
#[derive(Clone, Copy, Debug)]
struct Partials<T> {
    v: T,
    /// ∂/∂(first input)
    d0: T,
    /// ∂/∂c
    dc: T,
}

/// GGX normal distribution, appendix eq. 7, as a function of k = r⁴ = alpha²
/// and c: D = k / (π ((k − 1) c² + 1)²).
///
/// The denominator is evaluated as (1 − c)(1 + c) + k c², which equals
/// (k − 1) c² + 1 but keeps full relative precision when c → 1 and k is
/// tiny (a glossy lobe seen head-on), where the textbook form cancels.
#[inline(always)]
fn ggx_d<T: Real>(k: T, c: T) -> Partials<T> {
    let pi = T::from_f64(core::f64::consts::PI);
    let one = T::from_f64(1.0);
    let den = (one - c) * (one + c) + k * c * c;
    let den3 = den * den * den;
    Partials {
        v: k / (pi * den * den),
        d0: (den - T::from_f64(2.0) * k * c * c) / (pi * den3),
        dc: -T::from_f64(4.0) * k * (k - one) * c / (pi * den3),
    }
}

/// Smith shadowing of appendix eqs. 8 and 13 as a function of k (r⁴, or
/// 0.25² for the clearcoat) and c: G = 2 / (sqrt(1 + k (1 − c²)/c²) + 1).
#[inline(always)]
fn smith_g<T: Real>(k: T, c: T) -> Partials<T> {
    let one = T::from_f64(1.0);
    let inv_c2 = one / (c * c);
    // (1 − c²)/c², with 1 − c² as (1 − c)(1 + c) for precision near c = 1.
    let tan2 = (one - c) * (one + c) * inv_c2;
    let u = k * tan2;
    let s = (one + u).sqrt();
    let g = T::from_f64(2.0) / (s + one);
    // dG/du = −1 / ((s + 1)² s)
    let dg_du = -one / ((s + one) * (s + one) * s);
    Partials {
        v: g,
        d0: dg_du * tan2,
        dc: dg_du * (-T::from_f64(2.0) * k * inv_c2 / c),
    }
}

/// The specular lobe shape S = D·G / (4c²) of appendix eq. 6 (without its
/// Fresnel factor), as a function of k = r⁴ and c.
#[inline(always)]
fn specular<T: Real>(k: T, c: T) -> Partials<T> {
    let d = ggx_d(k, c);
    let g = smith_g(k, c);
    let four_c2 = T::from_f64(4.0) * c * c;
    let v = d.v * g.v / four_c2;
    Partials {
        v,
        d0: (d.d0 * g.v + d.v * g.d0) / four_c2,
        dc: (d.dc * g.v + d.v * g.dc) / four_c2 - T::from_f64(2.0) * v / c,
    }
}

/// The clearcoat lobe ρ_clearcoat of appendix eqs. 11–15 as a function of
/// the clearcoat gloss g and c; `d0` is ∂/∂g.
#[inline(always)]
fn clearcoat<T: Real>(gloss: T, c: T, fresnel: T) -> Partials<T> {
    let pi = T::from_f64(core::f64::consts::PI);
    let one = T::from_f64(1.0);
    let two = T::from_f64(2.0);
    // eq. 15: r_c = 0.1 − 0.099 g
    let rc = T::from_f64(0.1) - T::from_f64(0.099) * gloss;
    // eq. 12: D_c = (r_c² − 1) / (2π ln(r_c) (1 + (r_c² − 1) c²))
    let e = rc * rc - one;
    let l = rc.ln();
    // 1 + (r_c² − 1) c², evaluated as (1 − c)(1 + c) + r_c² c² (see ggx_d).
    let den = (one - c) * (one + c) + rc * rc * c * c;
    let dc_v = e / (two * pi * l * den);
    let ddc_de = one / (two * pi * l * den) - e * c * c / (two * pi * l * den * den);
    let ddc_dl = -e / (two * pi * l * l * den);
    let ddc_drc = ddc_de * two * rc + ddc_dl / rc;
    let ddc_dc = -e * two * e * c / (two * pi * l * den * den);
    // eq. 13: G_c with k = 0.25²
    let g = smith_g(T::from_f64(0.0625), c);
    let four_c2 = T::from_f64(4.0) * c * c;
    // eqs. 11, 14
    let v = dc_v * g.v * fresnel / four_c2;
    Partials {
        v,
        d0: ddc_drc * T::from_f64(-0.099) * g.v * fresnel / four_c2,
        dc: (ddc_dc * g.v + dc_v * g.dc) * fresnel / four_c2 - two * v / c,
    }
}

/// Value of [`ggx_d`] alone, in the same operations (same rounding).
#[inline(always)]
fn ggx_d_value<T: Real>(k: T, c: T) -> T {
    let one = T::from_f64(1.0);
    let den = (one - c) * (one + c) + k * c * c;
    k / (T::from_f64(core::f64::consts::PI) * den * den)
}

/// Value of [`smith_g`] alone, in the same operations (same rounding).
#[inline(always)]
fn smith_g_value<T: Real>(k: T, c: T) -> T {
    let one = T::from_f64(1.0);
    let tan2 = (one - c) * (one + c) * (one / (c * c));
    T::from_f64(2.0) / ((one + k * tan2).sqrt() + one)
}

/// Value of [`clearcoat`] alone, in the same operations (same rounding).
#[inline(always)]
fn clearcoat_value<T: Real>(gloss: T, c: T, fresnel: T) -> T {
    let one = T::from_f64(1.0);
    let two = T::from_f64(2.0);
    // eq. 15
    let rc = T::from_f64(0.1) - T::from_f64(0.099) * gloss;
    // eq. 12, denominator as in `clearcoat`
    let e = rc * rc - one;
    let den = (one - c) * (one + c) + rc * rc * c * c;
    let d_c = e / (two * T::from_f64(core::f64::consts::PI) * rc.ln() * den);
    // eqs. 11, 13, 14
    d_c * smith_g_value(T::from_f64(0.0625), c) * fresnel / (T::from_f64(4.0) * c * c)
}

/// Evaluates ρ(n, h; Θ) of SPEC §3 for c = n·h.
///
/// `params` are the 9 material parameters in the order of
/// [`crate::Material`]. c is clamped to [`MIN_COS`] and the GGX alpha to
/// [`MIN_ALPHA`].
///
/// This is the value-only path: it computes no derivatives, in the same
/// operations as [`eval_with_jacobian`], so the two values agree bit for bit.
#[inline]
pub fn eval<T: Real>(params: &[T; 9], cos: T, settings: &BrdfSettings) -> [T; 3] {
    let one = T::from_f64(1.0);
    let two = T::from_f64(2.0);
    let inv_pi = T::from_f64(core::f64::consts::FRAC_1_PI);
    let c = if cos > T::from_f64(MIN_COS) {
        cos
    } else {
        T::from_f64(MIN_COS)
    };
    let r = params[ROUGHNESS];
    let ss = params[SUBSURFACE];
    let m = params[METALLIC];
    let sp = params[DIELECTRIC];
    let cc = params[CLEARCOAT];

    // (1 − c)^5 of eqs. 4 and 5.
    let omc = one - c;
    let omc2 = omc * omc;
    let q = omc2 * omc2 * omc;
    // eq. 4 without base_color/π: (1 + (2r − 0.5) q)²
    let u = one + (two * r - T::from_f64(0.5)) * q;
    let f_base = u * u;
    // eq. 5 without 1.25·base_color/(2π): (1 + (r − 1) q)² (1/c − 1) + 1
    let v = one + (r - one) * q;
    let f_sub = v * v * (one / c - one) + one;
    // eq. 3 divided by base_color
    let k_sub = T::from_f64(1.25 / (2.0 * core::f64::consts::PI));
    let diffuse = (one - ss) * f_base * inv_pi + ss * k_sub * f_sub;

    // eqs. 6–8 with k = alpha² = r⁴, alpha clamped.
    let alpha_raw = r * r;
    let alpha = if alpha_raw > T::from_f64(MIN_ALPHA) {
        alpha_raw
    } else {
        T::from_f64(MIN_ALPHA)
    };
    let k = alpha * alpha;
    let spec = ggx_d_value(k, c) * smith_g_value(k, c) / (T::from_f64(4.0) * c * c);

    let cc_lobe = clearcoat_value(
        params[CLEARCOAT_GLOSS],
        c,
        T::from_f64(settings.clearcoat_fresnel),
    );

    // eq. 2 as ρ = base·a + b (eqs. 9, 10).
    let a = (one - m) * diffuse + m * spec;
    let b = T::from_f64(0.08) * (one - m) * sp * spec + T::from_f64(0.25) * cc * cc_lobe;
    [
        params[BASE_COLOR] * a + b,
        params[BASE_COLOR + 1] * a + b,
        params[BASE_COLOR + 2] * a + b,
    ]
}

/// Evaluates ρ and its derivatives with respect to all 9 parameters and c.
///
/// Where a clamp is active the derivative through the clamped quantity is
/// zero, consistent with the clamped function.
#[inline]
pub fn eval_with_jacobian<T: Real>(
    params: &[T; 9],
    cos: T,
    settings: &BrdfSettings,
) -> BrdfJacobian<T> {
    let one = T::from_f64(1.0);
    let zero = T::from_f64(0.0);
    let inv_pi = T::from_f64(core::f64::consts::FRAC_1_PI);
    let (c, dc_dcos) = if cos > T::from_f64(MIN_COS) {
        (cos, one)
    } else {
        (T::from_f64(MIN_COS), zero)
    };
    let base = [
        params[BASE_COLOR],
        params[BASE_COLOR + 1],
        params[BASE_COLOR + 2],
    ];
    let r = params[ROUGHNESS];
    let gloss = params[CLEARCOAT_GLOSS];
    let ss = params[SUBSURFACE];
    let m = params[METALLIC];
    let sp = params[DIELECTRIC];
    let cc = params[CLEARCOAT];

    // Schlick-style weight (1 − c)^5 shared by eqs. 4 and 5.
    let omc = one - c;
    let omc2 = omc * omc;
    let q = omc2 * omc2 * omc;
    let dq_dc = -T::from_f64(5.0) * omc2 * omc2;

    // eq. 4 without base_color/π: f_base = (1 + (2r − 0.5) q)²
    let u = one + (T::from_f64(2.0) * r - T::from_f64(0.5)) * q;
    let f_base = u * u;
    let df_base_dr = T::from_f64(2.0) * u * T::from_f64(2.0) * q;
    let df_base_dc = T::from_f64(2.0) * u * (T::from_f64(2.0) * r - T::from_f64(0.5)) * dq_dc;

    // eq. 5 without 1.25·base_color/(2π): f_sub = (1 + (r − 1) q)² (1/c − 1) + 1
    let v = one + (r - one) * q;
    let w = one / c - one;
    let f_sub = v * v * w + one;
    let df_sub_dr = T::from_f64(2.0) * v * q * w;
    let df_sub_dc = T::from_f64(2.0) * v * (r - one) * dq_dc * w - v * v / (c * c);

    // eq. 3 divided by base_color
    let k_sub = T::from_f64(1.25 / (2.0 * core::f64::consts::PI));
    let diffuse = (one - ss) * f_base * inv_pi + ss * k_sub * f_sub;
    let ddiffuse_dr = (one - ss) * df_base_dr * inv_pi + ss * k_sub * df_sub_dr;
    let ddiffuse_dc = (one - ss) * df_base_dc * inv_pi + ss * k_sub * df_sub_dc;
    let ddiffuse_dss = -f_base * inv_pi + k_sub * f_sub;

    // eqs. 6–8 with k = alpha² = r⁴, alpha clamped.
    let alpha_raw = r * r;
    let (alpha, dalpha_dr) = if alpha_raw > T::from_f64(MIN_ALPHA) {
        (alpha_raw, T::from_f64(2.0) * r)
    } else {
        (T::from_f64(MIN_ALPHA), zero)
    };
    let k = alpha * alpha;
    let dk_dr = T::from_f64(2.0) * alpha * dalpha_dr;
    let spec = specular(k, c);
    let dspec_dr = spec.d0 * dk_dr;

    let cc_lobe = clearcoat(gloss, c, T::from_f64(settings.clearcoat_fresnel));

    // eq. 2 split as ρ = base·a + b (metallic Fresnel = base_color, eq. 9;
    // dielectric Fresnel = 1, eq. 10).
    let a = (one - m) * diffuse + m * spec.v;
    let da_dr = (one - m) * ddiffuse_dr + m * dspec_dr;
    let da_dc = (one - m) * ddiffuse_dc + m * spec.dc;
    let da_dss = (one - m) * ddiffuse_dss;
    let da_dm = spec.v - diffuse;

    let w_diel = T::from_f64(0.08) * (one - m) * sp;
    let w_cc = T::from_f64(0.25) * cc;
    let b = w_diel * spec.v + w_cc * cc_lobe.v;
    let db_dr = w_diel * dspec_dr;
    let db_dc = w_diel * spec.dc + w_cc * cc_lobe.dc;
    let db_dm = -T::from_f64(0.08) * sp * spec.v;
    let db_dsp = T::from_f64(0.08) * (one - m) * spec.v;
    let db_dcc = T::from_f64(0.25) * cc_lobe.v;
    let db_dgloss = w_cc * cc_lobe.d0;

    let mut jac = BrdfJacobian {
        value: [zero; 3],
        d_params: [[zero; 3]; 9],
        d_cos: [zero; 3],
    };
    for (i, &base_i) in base.iter().enumerate() {
        jac.value[i] = base_i * a + b;
        jac.d_params[BASE_COLOR + i][i] = a;
        jac.d_params[ROUGHNESS][i] = base_i * da_dr + db_dr;
        jac.d_params[CLEARCOAT_GLOSS][i] = db_dgloss;
        jac.d_params[SUBSURFACE][i] = base_i * da_dss;
        jac.d_params[METALLIC][i] = base_i * da_dm + db_dm;
        jac.d_params[DIELECTRIC][i] = db_dsp;
        jac.d_params[CLEARCOAT][i] = db_dcc;
        jac.d_cos[i] = (base_i * da_dc + db_dc) * dc_dcos;
    }
    jac
}
