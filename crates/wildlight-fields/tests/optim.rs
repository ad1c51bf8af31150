//! Adam against hand-computed steps, and the learning-rate schedules.

// Gradient checks index parameters, points and axes together.
#![allow(clippy::needless_range_loop)]

use wildlight_fields::*;

#[test]
fn adam_matches_hand_computed_steps() {
    let cfg = AdamConfig {
        lr: 0.1,
        beta1: 0.9,
        beta2: 0.99,
        eps: 1e-8,
    };
    let mut adam = Adam::<f64>::new();
    let other = adam.add_group("other", 1, AdamConfig { lr: 0.5, ..cfg });
    let g = adam.add_group("main", 2, cfg);
    let mut p = vec![1.0, -2.0];
    // step 1, gradient (0.5, -1): m = 0.1 g, v = 0.01 g², m̂ = g, v̂ = g² → p -= 0.1 · g/(|g| + 1e-8)
    adam.step(g, &mut p, &[0.5, -1.0], 1.0);
    assert!((p[0] - (1.0 - 0.1 * 0.5 / (0.5 + 1e-8))).abs() < 1e-12);
    assert!((p[1] - (-2.0 + 0.1 * 1.0 / (1.0 + 1e-8))).abs() < 1e-12);
    // step 2 for p[0], gradient 0.2, lr factor 0.5:
    // m = 0.9·0.05 + 0.1·0.2 = 0.065; v = 0.99·0.0025 + 0.01·0.04 = 0.002875
    // m̂ = 0.065/0.19, v̂ = 0.002875/0.0199
    adam.step(g, &mut p, &[0.2, 0.0], 0.5);
    let m_hat: f64 = 0.065 / 0.19;
    let v_hat: f64 = 0.002875 / 0.0199;
    let expected = (1.0 - 0.1 * 0.5 / (0.5 + 1e-8)) - 0.05 * m_hat / (v_hat.sqrt() + 1e-8);
    assert!((p[0] - expected).abs() < 1e-12, "{} vs {}", p[0], expected);
    assert_eq!(adam.groups[g].step, 2);
    // The other group is untouched and has its own step count and lr.
    assert_eq!(adam.groups[other].step, 0);
    let mut q = vec![0.0];
    adam.step(other, &mut q, &[-3.0], 1.0);
    assert!((q[0] - 0.5 * 3.0 / (3.0 + 1e-8)).abs() < 1e-12);
}

/// An entry without gradient keeps moving on its momentum while its moments
/// decay, and once they fall below the floor they are stored as exact
/// zeros (never subnormal), and the entry stops.
#[test]
fn decayed_moments_become_exact_zeros() {
    let mut adam = Adam::<f32>::new();
    let g = adam.add_group("grid", 2, AdamConfig::default());
    let mut p = vec![0.5f32, -0.25];
    adam.step(g, &mut p, &[1e-3, 2e-3], 1.0);
    let mut last = p.clone();
    let mut moved = 0;
    for _ in 0..6000 {
        adam.step(g, &mut p, &[0.0, 0.0], 1.0);
        let group = &adam.groups[g];
        for x in group.m.iter().chain(&group.v) {
            assert!(*x == 0.0 || x.is_normal(), "moment {x:e} is subnormal");
            assert!(*x == 0.0 || x.abs() as f64 >= adam::MOMENT_FLOOR);
        }
        if p != last {
            moved += 1;
        }
        last.clone_from(&p);
    }
    let group = &adam.groups[g];
    assert!(group.m.iter().chain(&group.v).all(|&x| x == 0.0));
    // m falls below 1e-30 after about 620 steps (0.9^k · 2e-4), v after
    // about 5,200 (0.99^k · 4e-8); the parameter moves on its momentum for
    // part of the first (until a step no longer changes it in f32) and
    // never afterwards.
    assert!(moved > 10 && moved < 700, "{moved}");
}

#[test]
fn adam_f32_matches_f64() {
    let mut a32 = Adam::<f32>::new();
    let mut a64 = Adam::<f64>::new();
    let n = 50_000; // several parallel chunks
    a32.add_group("g", n, AdamConfig::default());
    a64.add_group("g", n, AdamConfig::default());
    let mut p32: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin()).collect();
    let mut p64: Vec<f64> = p32.iter().map(|&v| v as f64).collect();
    for s in 0..3 {
        let g64: Vec<f64> = (0..n)
            .map(|i| ((i * (s + 2)) as f64 * 0.11).cos())
            .collect();
        let g32: Vec<f32> = g64.iter().map(|&v| v as f32).collect();
        a32.step(0, &mut p32, &g32, 1.0);
        a64.step(0, &mut p64, &g64, 1.0);
    }
    for (a, b) in p32.iter().zip(&p64) {
        assert!((*a as f64 - b).abs() < 1e-6);
    }
}

#[test]
fn lr_schedules() {
    let warm = LrSchedule {
        warmup_steps: 10,
        warmup_start_factor: 0.1,
        decay: Decay::Constant,
    };
    assert!((warm.factor(0) - 0.1).abs() < 1e-12);
    assert!((warm.factor(5) - 0.55).abs() < 1e-12);
    assert_eq!(warm.factor(10), 1.0);
    assert_eq!(warm.factor(1000), 1.0);

    let cos = LrSchedule {
        warmup_steps: 100,
        warmup_start_factor: 0.0,
        decay: Decay::Cosine {
            total_steps: 1100,
            final_factor: 0.05,
        },
    };
    assert!((cos.factor(100) - 1.0).abs() < 1e-12);
    // halfway through the decay: (1 + 0.05) / 2
    assert!((cos.factor(600) - 0.525).abs() < 1e-12);
    assert!((cos.factor(1100) - 0.05).abs() < 1e-12);
    assert!((cos.factor(5000) - 0.05).abs() < 1e-12);

    let exp = LrSchedule {
        warmup_steps: 0,
        warmup_start_factor: 1.0,
        decay: Decay::Exponential {
            total_steps: 1000,
            final_factor: 0.01,
        },
    };
    assert!((exp.factor(0) - 1.0).abs() < 1e-12);
    assert!((exp.factor(500) - 0.1).abs() < 1e-12);
    assert!((exp.factor(1000) - 0.01).abs() < 1e-12);
    assert_eq!(LrSchedule::constant().factor(77), 1.0);
}
