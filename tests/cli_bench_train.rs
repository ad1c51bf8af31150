//! `wildlight bench train` from the outside: on a tiny capture with a small
//! model, the JSON report holds one timing per repetition, its rays per
//! second agree with the timed steps' wall time, and the phases of a step
//! add up to no more than the step; the maskless mode is reported; bad
//! arguments are refused.

mod common;

use common::{path_arg, run, run_json, tiny_synth};

#[test]
fn the_training_benchmark_reports_rays_per_second_and_phases() {
    let dir = tempfile::tempdir().unwrap();
    let capture = dir.path().join("capture");
    assert!(tiny_synth("kettle", &capture).status().unwrap().success());
    let config = dir.path().join("tiny.toml");
    std::fs::write(&config, common::TINY_MODEL_CONFIG).unwrap();
    let bench = |masks: &str| {
        run_json(&[
            "bench",
            "train",
            "--data",
            path_arg(&capture),
            "--config",
            path_arg(&config),
            "--masks",
            masks,
            "--warmup",
            "2",
            "--steps",
            "4",
            "--reps",
            "2",
            "--json",
        ])
    };
    for (masks, maskless) in [("use", false), ("ignore", true)] {
        let report = bench(masks);
        assert_eq!(report["maskless"], maskless, "{report}");
        assert_eq!(report["batch_rays"], 256);
        assert_eq!(report["steps"], 4);
        let reps = report["reps"].as_array().unwrap();
        assert_eq!(reps.len(), 2);
        for rep in reps {
            let seconds = rep["seconds"].as_f64().unwrap();
            let rays_per_s = rep["rays_per_s"].as_f64().unwrap();
            assert!(seconds > 0.0 && rays_per_s > 0.0, "{rep}");
            // 256 rays × 4 steps in `seconds`
            assert!((rays_per_s * seconds / 1024.0 - 1.0).abs() < 1e-9, "{rep}");
            let step_ms = 1e3 * seconds / 4.0;
            let phases: Vec<f64> = ["setup", "forward", "backward", "priors", "hull", "update"]
                .iter()
                .map(|k| rep["phase_ms"][k].as_f64().unwrap())
                .collect();
            assert!(phases.iter().all(|p| *p >= 0.0), "{rep}");
            let sum: f64 = phases.iter().sum();
            assert!(
                sum <= step_ms * 1.001 && sum > 0.5 * step_ms,
                "{sum} of {step_ms}: {rep}"
            );
            assert!(rep["samples_per_ray"].as_f64().unwrap() > 0.0);
            // The background's time is part of forward + backward, and only
            // a maskless run has one.
            let background = rep["phase_ms"]["background"].as_f64().unwrap();
            if maskless {
                assert!(
                    background > 0.0 && background < phases[1] + phases[2],
                    "{rep}"
                );
            } else {
                assert_eq!(background, 0.0, "{rep}");
            }
        }
        // The reported rays per second is the median of the two (their mean).
        let each: Vec<f64> = reps
            .iter()
            .map(|r| r["rays_per_s"].as_f64().unwrap())
            .collect();
        let median = report["rays_per_s"].as_f64().unwrap();
        assert!((median - 0.5 * (each[0] + each[1])).abs() <= 1e-9 * median);
    }
    let out = run(&[
        "bench",
        "train",
        "--data",
        path_arg(&capture),
        "--steps",
        "0",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--steps"));
    let missing = dir.path().join("missing");
    let out = run(&["bench", "train", "--data", path_arg(&missing)]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing"));
}
