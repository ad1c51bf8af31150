//! Tests of the material model against hand-computed values, finite
//! differences and the f32 / f64 agreement SPEC §3 asks for.

use std::f64::consts::PI;
use wildlight_material::{BrdfSettings, Material, PARAM_COUNT, brdf};

fn material(base: [f64; 3]) -> Material {
    Material {
        base_color: base,
        roughness: 0.5,
        clearcoat_gloss: 0.0,
        subsurface: 0.0,
        metallic: 0.0,
        dielectric: 0.0,
        clearcoat: 0.0,
    }
}

fn eval(m: &Material, c: f64) -> [f64; 3] {
    brdf::eval(&m.to_array::<f64>(), c, &BrdfSettings::default())
}

fn assert_rel(a: f64, b: f64, tol: f64, what: &str) {
    let err = (a - b).abs() / b.abs().max(1e-300);
    assert!(err <= tol, "{what}: {a} vs {b} (relative error {err:e})");
}

#[test]
fn lambertian_head_on_is_base_over_pi() {
    // eq. 4 at c = 1: (1 − c)^5 = 0, so ρ = base_color/π.
    let m = material([0.8, 0.4, 0.2]);
    let rho = eval(&m, 1.0);
    for (i, v) in rho.iter().enumerate() {
        assert_rel(*v, m.base_color[i] / PI, 1e-14, "diffuse at c=1");
    }
}

#[test]
fn diffuse_retroreflection_at_grazing_angle() {
    // eq. 4 at c = 0.5, r = 0.5: (1 + 0.5·(1/32))² = 1.031494140625 (by hand).
    let m = material([1.0, 1.0, 1.0]);
    let rho = eval(&m, 0.5);
    assert_rel(rho[0], 1.031_494_140_625 / PI, 1e-14, "diffuse at c=0.5");
}

#[test]
fn subsurface_lobe_head_on() {
    // eq. 5 at c = 1: the (1/c − 1) factor vanishes, ρ_sub = 1.25·base/(2π).
    let mut m = material([0.6, 0.6, 0.6]);
    m.subsurface = 1.0;
    let rho = eval(&m, 1.0);
    assert_rel(rho[1], 1.25 * 0.6 / (2.0 * PI), 1e-14, "subsurface at c=1");
    // At c = 0.5, r = 1: (1 + 0)²·(2 − 1) + 1 = 2.
    m.roughness = 1.0;
    let rho = eval(&m, 0.5);
    assert_rel(
        rho[1],
        2.0 * 1.25 * 0.6 / (2.0 * PI),
        1e-14,
        "subsurface at c=0.5",
    );
}

#[test]
fn rough_metal_has_closed_form() {
    // r = 1: D = 1/π, G = 2c/(1 + c), so ρ = base / (2π c (1 + c)).
    let mut m = material([0.9, 0.6, 0.3]);
    m.metallic = 1.0;
    m.roughness = 1.0;
    for c in [0.2, 0.5, 0.9, 1.0] {
        let rho = eval(&m, c);
        for (v, base) in rho.iter().zip(m.base_color) {
            let expected = base / (2.0 * PI * c * (1.0 + c));
            assert_rel(*v, expected, 1e-13, "metal r=1");
        }
    }
}

#[test]
fn glossy_dielectric_peak() {
    // At c = 1: D = 1/(π r⁴), G = 1, ρ_dielectric = 1/(4π r⁴), weighted 0.08·sp.
    let mut m = material([0.0, 0.0, 0.0]);
    m.dielectric = 1.0;
    m.roughness = 0.1;
    let rho = eval(&m, 1.0);
    assert_rel(rho[2], 0.08 / (4.0 * PI * 1e-4), 1e-12, "dielectric peak");
}

#[test]
fn clearcoat_peak_and_fresnel_setting() {
    // At c = 1 with gloss 1 (r_c = 0.001): 1 + (r_c² − 1) = r_c², G_c = 1, so
    // ρ_cc = (r_c² − 1)/(2π ln r_c · r_c²) · F_c / 4, weighted 0.25.
    let mut m = material([0.0, 0.0, 0.0]);
    m.clearcoat = 1.0;
    m.clearcoat_gloss = 1.0;
    let rc: f64 = 0.001;
    let dc = (rc * rc - 1.0) / (2.0 * PI * rc.ln() * rc * rc);
    let rho = eval(&m, 1.0);
    assert_rel(rho[0], 0.25 * dc * 0.2 / 4.0, 1e-10, "clearcoat F=0.2");
    let s = BrdfSettings {
        clearcoat_fresnel: 0.04,
    };
    let rho = brdf::eval(&m.to_array::<f64>(), 1.0, &s);
    assert_rel(rho[0], 0.25 * dc * 0.04 / 4.0, 1e-10, "clearcoat F=0.04");
}

/// Deterministic pseudo-random numbers in [0, 1) for sweeping parameters.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn jacobian_matches_central_differences() {
    let settings = BrdfSettings::default();
    let mut rng = Lcg(7);
    let mut checked = 0;
    for _ in 0..400 {
        let mut p = [0.0f64; PARAM_COUNT];
        for v in &mut p {
            *v = 0.05 + 0.9 * rng.next();
        }
        // roughness away from the alpha clamp, c away from its clamp.
        p[3] = 0.05 + 0.95 * rng.next();
        let c = 0.05 + 0.94 * rng.next();
        let jac = brdf::eval_with_jacobian(&p, c, &settings);
        let h = 1e-6;
        for j in 0..PARAM_COUNT {
            let (mut hi, mut lo) = (p, p);
            hi[j] += h;
            lo[j] -= h;
            let (fh, fl) = (brdf::eval(&hi, c, &settings), brdf::eval(&lo, c, &settings));
            for i in 0..3 {
                let fd = (fh[i] - fl[i]) / (2.0 * h);
                let an = jac.d_params[j][i];
                let scale = fd.abs().max(an.abs()).max(1e-3);
                assert!(
                    (fd - an).abs() / scale < 1e-5,
                    "d rho_{i}/d p_{j} at p={p:?} c={c}: analytic {an} vs fd {fd}"
                );
                checked += 1;
            }
        }
        let (fh, fl) = (
            brdf::eval(&p, c + h, &settings),
            brdf::eval(&p, c - h, &settings),
        );
        for i in 0..3 {
            let fd = (fh[i] - fl[i]) / (2.0 * h);
            let an = jac.d_cos[i];
            let scale = fd.abs().max(an.abs()).max(1e-3);
            assert!(
                (fd - an).abs() / scale < 1e-5,
                "d rho_{i}/dc at p={p:?} c={c}: analytic {an} vs fd {fd}"
            );
        }
    }
    assert_eq!(checked, 400 * 27);
}

#[test]
fn backward_contracts_the_jacobian() {
    let p = Material::default().to_array::<f64>();
    let jac = brdf::eval_with_jacobian(&p, 0.7, &BrdfSettings::default());
    let g = [0.3, -1.0, 2.0];
    let (dp, dc) = jac.backward(g);
    let expected_dc: f64 = (0..3).map(|i| jac.d_cos[i] * g[i]).sum();
    assert_rel(dc, expected_dc, 1e-15, "dc");
    // roughness affects all channels alike through b, and through base·a.
    let expected_dr: f64 = (0..3).map(|i| jac.d_params[3][i] * g[i]).sum();
    assert_rel(dp[3], expected_dr, 1e-15, "droughness");
}

#[test]
fn clamps_keep_values_finite_and_derivatives_consistent() {
    let settings = BrdfSettings::default();
    let m = Material {
        roughness: 0.0,
        metallic: 0.5,
        clearcoat: 1.0,
        ..Material::default()
    };
    for c in [-0.5, 0.0, 1e-6, 1e-4] {
        let jac = brdf::eval_with_jacobian(&m.to_array::<f64>(), c, &settings);
        assert!(jac.value.iter().all(|v| v.is_finite() && *v >= 0.0));
        // Below the clamp the value does not depend on c.
        assert_eq!(jac.d_cos, [0.0; 3]);
        // roughness below the alpha clamp: no gradient through GGX.
        let expected = jac.value;
        let at_clamp = brdf::eval(&m.to_array::<f64>(), brdf::MIN_COS, &settings);
        assert_eq!(expected, at_clamp);
    }
}

#[test]
fn f32_matches_the_equations_to_1e_4() {
    // SPEC §3: for r ≥ 0.02 and c ≥ 1e-3 the f32 evaluation must match the
    // equations to relative error ≤ 1e-4 (each lobe on its own, so that no
    // lobe hides behind another).
    let settings = BrdfSettings::default();
    let mut rng = Lcg(11);
    let mut worst = 0.0f64;
    let lobes: [fn(&mut [f64; 9]); 5] = [
        |p| {
            p[6] = 0.0;
            p[7] = 0.0;
            p[8] = 0.0
        },
        |p| {
            p[6] = 1.0;
            p[8] = 0.0
        },
        |p| {
            p[6] = 0.0;
            p[0] = 0.0;
            p[1] = 0.0;
            p[2] = 0.0;
            p[8] = 0.0
        },
        |p| {
            p[0] = 0.0;
            p[1] = 0.0;
            p[2] = 0.0;
            p[6] = 0.0;
            p[7] = 0.0
        },
        |_| {},
    ];
    for lobe in lobes {
        for n in 0..3000 {
            let mut p = [0.0f64; 9];
            for v in &mut p {
                *v = rng.next();
            }
            p[3] = 0.02 + 0.98 * rng.next();
            if n % 3 == 0 {
                p[3] = 0.02; // the glossiest allowed
            }
            lobe(&mut p);
            let c = match n % 4 {
                0 => 1e-3 + rng.next() * 0.01,
                1 => 1.0 - rng.next() * 1e-3,
                2 => 1.0,
                _ => 1e-3 + rng.next() * (1.0 - 1e-3),
            };
            let p32 = p.map(|v| v as f32);
            let c32 = c as f32;
            // The equations, evaluated in f64 at exactly the f32 inputs.
            let exact = brdf::eval(&p32.map(|v| v as f64), c32 as f64, &settings);
            let approx = brdf::eval(&p32, c32, &settings);
            for i in 0..3 {
                if exact[i] == 0.0 {
                    assert_eq!(approx[i], 0.0);
                    continue;
                }
                let err = (approx[i] as f64 - exact[i]).abs() / exact[i].abs();
                worst = worst.max(err);
                assert!(
                    err <= 1e-4,
                    "p={p32:?} c={c32}: {} vs {}",
                    approx[i],
                    exact[i]
                );
            }
        }
    }
    assert!(
        worst > 0.0,
        "f32 and f64 cannot agree bit for bit everywhere"
    );
}

/// Relative difference of two values (0 when both are 0).
fn rel_diff(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}

#[test]
fn value_path_equals_the_jacobian_value_in_f32_and_f64() {
    // The value-only `eval` repeats the operations of `eval_with_jacobian`,
    // so the values agree bit for bit (which is within the 1e-6 (f32) and
    // 1e-14 (f64) relative tolerances asked of the fast path), over the
    // whole parameter cube, both clamps and both Fresnel settings.
    let mut rng = Lcg(23);
    let mut nonzero = 0;
    for n in 0..20_000 {
        let settings = BrdfSettings {
            clearcoat_fresnel: if n % 2 == 0 { 0.2 } else { 0.04 },
        };
        let mut p = [0.0f64; 9];
        for v in &mut p {
            *v = rng.next();
        }
        match n % 5 {
            0 => p[3] = 0.005 * rng.next(), // below the alpha clamp
            1 => p[3] = 0.02,
            _ => {}
        }
        let c = match n % 7 {
            0 => -0.5 * rng.next(),       // back-facing: clamped
            1 => 1e-5 * rng.next(),       // below MIN_COS
            2 => 1.0 - rng.next() * 1e-4, // near head-on
            3 => 1.0,
            _ => rng.next(),
        };
        let fast = brdf::eval(&p, c, &settings);
        let full = brdf::eval_with_jacobian(&p, c, &settings).value;
        let p32 = p.map(|v| v as f32);
        let fast32 = brdf::eval(&p32, c as f32, &settings);
        let full32 = brdf::eval_with_jacobian(&p32, c as f32, &settings).value;
        for i in 0..3 {
            assert!(fast[i].is_finite() && fast[i] >= 0.0);
            assert!(
                rel_diff(fast[i], full[i]) <= 1e-14,
                "f64 p={p:?} c={c}: {} vs {}",
                fast[i],
                full[i]
            );
            assert!(
                rel_diff(fast32[i] as f64, full32[i] as f64) <= 1e-6,
                "f32 p={p32:?} c={c}: {} vs {}",
                fast32[i],
                full32[i]
            );
            assert_eq!(fast[i].to_bits(), full[i].to_bits(), "f64 bits");
            assert_eq!(fast32[i].to_bits(), full32[i].to_bits(), "f32 bits");
            nonzero += (fast[i] > 0.0) as usize;
        }
    }
    assert!(nonzero > 50_000, "{nonzero}");
}

#[test]
fn material_array_round_trip_and_range_check() {
    let m = Material {
        base_color: [0.1, 0.2, 0.3],
        roughness: 0.4,
        clearcoat_gloss: 0.5,
        subsurface: 0.6,
        metallic: 0.7,
        dielectric: 0.8,
        clearcoat: 0.9,
    };
    let a = m.to_array::<f64>();
    assert_eq!(a, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]);
    assert_eq!(Material::from_array(&a), m);
    assert_eq!(m.out_of_range(), None);
    let bad = Material { metallic: 1.5, ..m };
    assert_eq!(bad.out_of_range(), Some(("metallic", 1.5)));
}
