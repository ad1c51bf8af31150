//! `wildlight demo --quick` end to end: its metrics are finite and better
//! than those of an untrained model (a demo with no training step). Steps
//! are counted, not timed, so the test does the same work on any machine.

mod common;

fn demo(dir: &std::path::Path, iters: &str) -> serde_json::Value {
    let out = common::wildlight()
        .args(["demo", "--quick", "--json", "--iters", iters, "--out"])
        .arg(dir)
        .output()
        .expect("the wildlight binary runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "demo failed: {}\n{}",
        stdout,
        String::from_utf8_lossy(&out.stderr)
    );
    let last = stdout.lines().last().expect("demo prints its metrics");
    serde_json::from_str(last).expect("the last line is one JSON object")
}

#[test]
fn quick_demo_beats_an_untrained_model() {
    let dir = tempfile::tempdir().unwrap();
    let untrained = demo(&dir.path().join("untrained"), "0");
    let trained = demo(&dir.path().join("trained"), "200");
    for key in [
        "mesh_mean",
        "mesh_median",
        "base_color_psnr",
        "novel_view_psnr_flash",
        "novel_view_psnr_noflash",
        "seconds",
    ] {
        let v = trained[key].as_f64().unwrap_or(f64::NAN);
        assert!(v.is_finite(), "{key} = {v}");
    }
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    assert!(
        f(&trained, "mesh_mean") < 0.5 * f(&untrained, "mesh_mean"),
        "{trained} vs {untrained}"
    );
    // Novel views improve by several dB; base colour improves, but slowly
    // (measured: 13.0 → 13.8 dB after 200 steps; issue 6 tracks it).
    for k in ["novel_view_psnr_flash", "novel_view_psnr_noflash"] {
        assert!(
            f(&trained, k) > f(&untrained, k) + 3.0,
            "{k}: {trained} vs {untrained}"
        );
    }
    assert!(
        f(&trained, "base_color_psnr") > f(&untrained, "base_color_psnr") + 0.3,
        "base_color_psnr: {trained} vs {untrained}"
    );
    // everything the demo says it wrote is there
    let t = dir.path().join("trained");
    for p in [
        "export/model.glb",
        "export/model.obj",
        "export/mesh_raw.ply",
        "render-val/views.json",
        "run/checkpoint.safetensors",
        "demo.json",
        "preview.png",
    ] {
        assert!(t.join(p).exists(), "{p} is missing");
    }
    // The preview grid (README, "wildlight demo"): a 96 px label column and
    // an 18 px header, then 2 val views × (GT, OURS) columns and 4 rows
    // (flash, no flash, base colour, normals) of 96×96 tiles, each followed
    // by a 4 px gap.
    let dims = image::image_dimensions(t.join("preview.png")).expect("preview.png is a PNG");
    assert_eq!(dims, (96 + 4 * (96 + 4), 18 + 4 * (96 + 4)));
    let preview = image::open(t.join("preview.png")).unwrap().to_rgb8();
    // the OURS flash tile of the first (flash) view shows the object: not
    // only backdrop grey
    let (x0, y0) = (96 + 100, 18);
    let object_pixels = (0..96)
        .flat_map(|y| (0..96).map(move |x| (x0 + x, y0 + y)))
        .filter(|&(x, y)| preview.get_pixel(x, y).0 != [64, 64, 64])
        .count();
    assert!(object_pixels > 500, "{object_pixels} object pixels");
}
