//! Checkpoint round trip, exact resume, and rejection of bad files.

// Gradient checks index parameters, points and axes together.
#![allow(clippy::needless_range_loop)]

use std::collections::HashMap;
use wildlight_fields::*;

fn config() -> SdfFieldConfig {
    SdfFieldConfig {
        grid: HashGridConfig {
            n_levels: 4,
            n_features: 2,
            log2_table_size: 10,
            base_resolution: 4,
            finest_resolution: 32,
            init_range: 1e-4,
            interpolation: Default::default(),
        },
        hidden: vec![16],
        n_features: 3,
        ..SdfFieldConfig::default()
    }
}

fn points(n: usize) -> Vec<[f32; 3]> {
    (0..n)
        .map(|i| {
            let t = i as f32 * 0.173;
            [0.7 * t.sin(), 0.6 * (1.3 * t).cos(), 0.5 * (0.7 * t).sin()]
        })
        .collect()
}

/// One training step on a sphere-of-radius-0.3 target.
fn step(field: &mut SdfField<f32>, adam: &mut Adam<f32>, x: &[[f32; 3]]) {
    let mut ctx = FieldContext::new();
    field.forward(x, &mut ctx);
    let no = field.n_output();
    let mut d = vec![0.0; x.len() * no];
    for (p, q) in x.iter().enumerate() {
        let target = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt() - 0.3;
        d[p * no] = (ctx.output()[p * no] - target).signum() / x.len() as f32;
    }
    let mut g = field.new_grads();
    field.backward(&mut ctx, &d, &mut g, None);
    adam.step(0, &mut field.field.grid.params, &g.grid, 1.0);
    adam.step(1, &mut field.field.mlp.params, &g.mlp, 1.0);
}

fn optimiser(field: &SdfField<f32>) -> Adam<f32> {
    let mut adam = Adam::new();
    adam.add_group(
        "grid",
        field.field.grid.n_params(),
        AdamConfig {
            lr: 1e-2,
            ..AdamConfig::default()
        },
    );
    adam.add_group(
        "mlp",
        field.field.mlp.n_params(),
        AdamConfig {
            lr: 1e-3,
            ..AdamConfig::default()
        },
    );
    adam
}

#[test]
fn save_load_round_trip_resumes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ck.safetensors");
    let x = points(3000);
    let mut field = SdfField::<f32>::new(&config(), 1).unwrap();
    let mut adam = optimiser(&field);
    for _ in 0..3 {
        step(&mut field, &mut adam, &x);
    }
    field.field.active_levels = 3;
    let mut w = CheckpointWriter::new();
    field.save_to(&mut w, "sdf");
    adam.save_to(&mut w, "adam");
    w.set_metadata("step", "3");
    w.save(&path).unwrap();
    assert!(!dir.path().join("ck.safetensors.tmp").exists());

    let ck = Checkpoint::load(&path).unwrap();
    assert_eq!(ck.metadata("step"), Some("3"));
    let mut field2 = SdfField::<f32>::new(&config(), 99).unwrap();
    let mut adam2 = optimiser(&field2);
    field2.load_from(&ck, "sdf").unwrap();
    adam2.load_from(&ck, "adam").unwrap();
    assert_eq!(field2.field.grid.params, field.field.grid.params);
    assert_eq!(field2.field.mlp.params, field.field.mlp.params);
    assert_eq!(field2.field.active_levels, 3);
    assert_eq!(adam2.groups[0].step, 3);
    // Resume: the next steps are bit-identical.
    for _ in 0..2 {
        step(&mut field, &mut adam, &x);
        step(&mut field2, &mut adam2, &x);
    }
    assert_eq!(field2.field.grid.params, field.field.grid.params);
    assert_eq!(field2.field.mlp.params, field.field.mlp.params);
}

#[test]
fn load_rejects_wrong_shape_and_version() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ck.safetensors");
    let field = SdfField::<f32>::new(&config(), 1).unwrap();
    let mut w = CheckpointWriter::new();
    field.save_to(&mut w, "sdf");
    w.save(&path).unwrap();

    let mut other_cfg = config();
    other_cfg.hidden = vec![8];
    let mut other = SdfField::<f32>::new(&other_cfg, 1).unwrap();
    let err = other
        .load_from(&Checkpoint::load(&path).unwrap(), "sdf")
        .unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, FieldError::Shape { .. }), "{msg}");
    assert!(
        msg.contains("sdf.mlp.0.weight") && msg.contains("ck.safetensors"),
        "{msg}"
    );

    let missing = other
        .load_from(&Checkpoint::load(&path).unwrap(), "nope")
        .unwrap_err();
    assert!(
        matches!(missing, FieldError::MissingTensor { .. }),
        "{missing}"
    );

    // A file with another format version.
    let data = [1.0f32, 2.0];
    let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
    let view =
        safetensors::tensor::TensorView::new(safetensors::Dtype::F32, vec![2], &bytes).unwrap();
    let mut meta = HashMap::new();
    meta.insert("format".to_string(), "wildlight-checkpoint".to_string());
    meta.insert("format_version".to_string(), "999".to_string());
    let old = dir.path().join("old.safetensors");
    std::fs::write(
        &old,
        safetensors::serialize([("t", view)], Some(meta)).unwrap(),
    )
    .unwrap();
    let err = Checkpoint::load(&old).unwrap_err();
    assert!(matches!(err, FieldError::Version { .. }), "{err}");
    assert!(err.to_string().contains("999"));

    // Not a safetensors file at all.
    let junk = dir.path().join("junk.safetensors");
    std::fs::write(&junk, b"hello").unwrap();
    assert!(matches!(
        Checkpoint::load(&junk).unwrap_err(),
        FieldError::Format { .. }
    ));
}
