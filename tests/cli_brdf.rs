//! `wildlight brdf` checked from outside: an independent, literal transcription
//! of SPEC §3 (appendix eqs. 1–15) in f64 against the command's output.

mod common;

use std::f64::consts::PI;
use std::io::Write;
use std::process::Stdio;

/// SPEC §3 written out term by term, as in the appendix, with no shared code.
fn spec_rho(p: &[f64; 9], c: f64, fc: f64) -> [f64; 3] {
    let (bc, r, g, ss, m, sp, cc) = ([p[0], p[1], p[2]], p[3], p[4], p[5], p[6], p[7], p[8]);
    let r4 = r.powi(4);
    let d = r4 / (PI * ((r4 - 1.0) * c * c + 1.0).powi(2)); // eq. 7
    let gg = 2.0 / ((1.0 + r4 * (1.0 - c * c) / (c * c)).sqrt() + 1.0); // eq. 8
    let rc = 0.1 - 0.099 * g; // eq. 15
    let dc = (rc * rc - 1.0) / (2.0 * PI * rc.ln() * (1.0 + (rc * rc - 1.0) * c * c)); // eq. 12
    let gc = 2.0 / ((1.0 + 0.0625 * (1.0 - c * c) / (c * c)).sqrt() + 1.0); // eq. 13
    let rho_cc = dc * gc * fc / (4.0 * c * c); // eq. 11
    let rho_diel = d * gg / (4.0 * c * c); // eqs. 6, 10
    let mut out = [0.0; 3];
    for i in 0..3 {
        let base = bc[i] / PI * (1.0 + (2.0 * r - 0.5) * (1.0 - c).powi(5)).powi(2); // eq. 4
        let sub = 1.25 * bc[i] / (2.0 * PI)
            * ((1.0 + (r - 1.0) * (1.0 - c).powi(5)).powi(2) * (1.0 / c - 1.0) + 1.0); // eq. 5
        let diffuse = (1.0 - ss) * base + ss * sub; // eq. 3
        let metal = d * gg * bc[i] / (4.0 * c * c); // eqs. 6, 9
        out[i] =
            (1.0 - m) * diffuse + m * metal + 0.08 * (1.0 - m) * sp * rho_diel + 0.25 * cc * rho_cc; // eq. 2
    }
    out
}

fn run_brdf(args: &[&str], input: &str) -> (i32, String, String) {
    let mut child = common::wildlight()
        .arg("brdf")
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the wildlight binary runs");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Deterministic numbers in [0, 1).
fn lcg(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 53) as f64
}

#[test]
fn agrees_with_the_equations_to_1e_4() {
    for fc in [0.2, 0.04] {
        let mut s = 42u64;
        let mut inputs = Vec::new();
        let mut lines = String::new();
        for n in 0..600 {
            let mut p = [0.0; 9];
            for v in &mut p {
                *v = lcg(&mut s);
            }
            p[3] = 0.02 + 0.98 * lcg(&mut s);
            let c = if n % 5 == 0 {
                1e-3 + 0.01 * lcg(&mut s)
            } else {
                1e-3 + (1.0 - 1e-3) * lcg(&mut s)
            };
            lines += &format!(
                "{{\"cos\":{c},\"base_color\":[{},{},{}],\"roughness\":{},\"clearcoat_gloss\":{},\"subsurface\":{},\"metallic\":{},\"dielectric\":{},\"clearcoat\":{}}}\n",
                p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]
            );
            inputs.push((p, c));
        }
        let fc_arg = fc.to_string();
        let (code, out, err) = run_brdf(&["--clearcoat-fresnel", &fc_arg], &lines);
        assert_eq!(code, 0, "stderr: {err}");
        let rows: Vec<[f64; 3]> = out
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(rows.len(), inputs.len(), "one output line per input line");
        for ((p, c), got) in inputs.iter().zip(&rows) {
            let want = spec_rho(p, *c, fc);
            for i in 0..3 {
                let rel = (got[i] - want[i]).abs() / want[i].abs();
                assert!(
                    rel <= 1e-4,
                    "p={p:?} c={c}: {} vs {} (rel {rel:e})",
                    got[i],
                    want[i]
                );
            }
        }
    }
}

#[test]
fn malformed_lines_name_the_line_and_fail() {
    let (code, out, err) = run_brdf(&[], "{\"cos\":0.5}\n{\"cos\":0.5,\"roughness\":\n");
    assert_ne!(code, 0);
    assert!(err.contains("<stdin>:2"), "{err}");
    assert!(err.contains("not a valid query"), "{err}");
    // the good first line was answered before the error
    assert_eq!(out.lines().count(), 1);

    let (code, _, err) = run_brdf(&[], "{\"cos\":0.5,\"metallic\":1.5}\n");
    assert_ne!(code, 0);
    assert!(err.contains("metallic = 1.5 is outside [0, 1]"), "{err}");

    let (code, _, err) = run_brdf(&[], "{\"roughness\":0.5}\n");
    assert_ne!(code, 0);
    assert!(err.contains("missing \"cos\""), "{err}");
}

#[test]
fn missing_file_is_reported() {
    let (code, _, err) = run_brdf(&["/nonexistent/queries.jsonl"], "");
    assert_ne!(code, 0);
    assert!(
        err.contains("cannot open /nonexistent/queries.jsonl"),
        "{err}"
    );
}

#[test]
fn plot_writes_a_png_with_the_curves() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("lobe.png");
    let (code, _, err) = run_brdf(
        &["--plot", png.to_str().unwrap()],
        "{\"base_color\":[1,0,0],\"roughness\":0.5,\"dielectric\":0}\n",
    );
    assert_eq!(code, 0, "{err}");
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (640, 480));
    // A red-only base colour: the red curve is drawn, the green one is flat at 0
    // (on the axis), so strongly red pixels exist.
    let red = img
        .pixels()
        .filter(|p| p[0] > 200 && p[1] < 80 && p[2] < 80)
        .count();
    assert!(red > 300, "{red} red pixels");
    assert!(!dir.path().join("lobe.png.tmp").exists());
}
