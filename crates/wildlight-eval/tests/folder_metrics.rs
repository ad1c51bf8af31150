//! `evaluate_images` and `evaluate_materials` on small hand-made datasets
//! with known answers.

use glam::{DMat4, DVec3};
use std::path::Path;
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_data::exr_io::write_exr_rgb;
use wildlight_data::writer::{DatasetWriter, ViewToWrite};
use wildlight_data::{Camera, Mask, RgbImage};
use wildlight_eval::{Pixels, Split, evaluate_images, evaluate_materials};

const W: u32 = 8;
const H: u32 = 8;

fn constant(value: [f32; 3]) -> RgbImage {
    RgbImage {
        width: W,
        height: H,
        data: (0..W * H).flat_map(|_| value).collect(),
    }
}

fn camera(index: usize, flash: bool) -> Camera {
    let k = intrinsics_from_fov_x(W, H, 40.0);
    let eye = DVec3::new(3.0 * (index as f64).cos(), 3.0 * (index as f64).sin(), 1.0);
    let energy = if flash { [1.0; 3] } else { [0.0; 3] };
    Camera::look_at(
        index,
        W,
        H,
        k,
        eye,
        DVec3::ZERO,
        DVec3::Z,
        DMat4::IDENTITY,
        energy,
    )
    .unwrap()
}

fn left_half() -> Mask {
    Mask {
        width: W,
        height: H,
        data: (0..W * H).map(|i| i % W < W / 2).collect(),
    }
}

fn full() -> Mask {
    Mask {
        width: W,
        height: H,
        data: vec![true; (W * H) as usize],
    }
}

fn write_pred(dir: &Path, kind: &str, index: usize, image: &RgbImage) {
    std::fs::create_dir_all(dir.join(kind)).unwrap();
    write_exr_rgb(&dir.join(kind).join(format!("{index:03}.exr")), image).unwrap();
}

/// SSIM of two constant images a, b (σ = 0): (2ab + C1) / (a² + b² + C1).
fn ssim_constants(a: f64, b: f64) -> f64 {
    let c1 = 1e-4;
    (2.0 * a * b + c1) / (a * a + b * b + c1)
}

#[test]
fn images_by_flash_group_with_mask_and_saturation() {
    let root = tempfile::tempdir().unwrap();
    let gt_dir = root.path().join("capture");
    let pred_dir = root.path().join("render");
    let writer = DatasetWriter::create(&gt_dir).unwrap();

    // View 0 (flash): 0.5 everywhere, one saturated pixel (3.0), left-half mask.
    let mut gt0 = constant([0.5; 3]);
    gt0.set(1, 1, [3.0, 3.0, 3.0]);
    let gt1 = constant([0.4; 3]);
    let (cam0, cam1) = (camera(0, true), camera(1, false));
    let (m0, m1) = (left_half(), full());
    writer
        .write_views(
            &[
                ViewToWrite {
                    camera: &cam0,
                    image: &gt0,
                    mask: Some(&m0),
                },
                ViewToWrite {
                    camera: &cam1,
                    image: &gt1,
                    mask: Some(&m1),
                },
            ],
            Some(1.0),
        )
        .unwrap();
    let val = writer.val().unwrap();
    let (cam2, gt2, m2) = (camera(2, false), constant([0.5; 3]), full());
    val.write_views(
        &[ViewToWrite {
            camera: &cam2,
            image: &gt2,
            mask: Some(&m2),
        }],
        Some(1.0),
    )
    .unwrap();

    // Predictions: view 0 exact inside the mask (the saturated pixel is 2.0,
    // also above the cap of 1, so no error), wrong outside it.
    let mut p0 = constant([0.5; 3]);
    p0.set(1, 1, [2.0, 2.0, 2.0]);
    for y in 0..H {
        for x in W / 2..W {
            p0.set(x, y, [0.9, 0.1, 0.0]);
        }
    }
    write_pred(&pred_dir, "image", 0, &p0);
    write_pred(&pred_dir, "image", 1, &constant([0.6; 3])); // MSE 0.04
    write_pred(&pred_dir, "image", 2, &constant([0.6; 3])); // MSE 0.01
    std::fs::write(
        pred_dir.join("views.json"),
        r#"[{"index":0,"split":"train","flash":true},
            {"index":1,"split":"train","flash":false},
            {"index":2,"split":"val","flash":false}]"#,
    )
    .unwrap();

    let r = evaluate_images(&pred_dir, &gt_dir, Pixels::Mask).unwrap();
    let psnr1 = 10.0 * (1.0f64 / 0.04).log10();
    let psnr2 = 20.0;
    assert!((r.psnr_flash.unwrap() - 100.0).abs() < 1e-9, "{r:?}");
    assert!(
        (r.psnr_noflash.unwrap() - (psnr1 + psnr2) / 2.0).abs() < 1e-4,
        "{r:?}"
    );
    assert!((r.psnr_all.unwrap() - (100.0 + psnr1 + psnr2) / 3.0).abs() < 1e-4);
    let (s1, s2) = (ssim_constants(0.6, 0.4), ssim_constants(0.6, 0.5));
    assert!((r.ssim_flash.unwrap() - 1.0).abs() < 1e-9);
    assert!(
        (r.ssim_noflash.unwrap() - (s1 + s2) / 2.0).abs() < 1e-5,
        "{r:?}"
    );
    assert!((r.ssim_all.unwrap() - (1.0 + s1 + s2) / 3.0).abs() < 1e-5);
    assert_eq!((r.views_flash, r.views_noflash), (1, 2));
    assert_eq!(r.per_view[0].mask_pixels, 32);

    let json = serde_json::to_value(&r).unwrap();
    for key in [
        "psnr_flash",
        "psnr_noflash",
        "psnr_all",
        "ssim_flash",
        "ssim_noflash",
        "ssim_all",
    ] {
        assert!(json[key].is_f64(), "{key} missing in {json}");
    }

    // Over the whole image, view 0's right half counts too: squared errors
    // 0.16, 0.16, 0.25 there (the saturated pixel still none), so the MSE
    // is half their mean; the other views had full masks and stay as they
    // were.
    let whole = evaluate_images(&pred_dir, &gt_dir, Pixels::WholeImage).unwrap();
    let mse0: f64 = 0.5 * (0.16 + 0.16 + 0.25) / 3.0;
    let psnr0 = 10.0 * (1.0 / mse0).log10();
    assert!(
        (whole.psnr_flash.unwrap() - psnr0).abs() < 1e-4,
        "{whole:?}"
    );
    assert!((whole.psnr_noflash.unwrap() - r.psnr_noflash.unwrap()).abs() < 1e-9);
    assert_eq!(whole.per_view[0].mask_pixels, (W * H) as usize);

    // A missing prediction names the file.
    std::fs::remove_file(pred_dir.join("image/002.exr")).unwrap();
    let err = evaluate_images(&pred_dir, &gt_dir, Pixels::Mask)
        .unwrap_err()
        .to_string();
    assert!(err.contains("002.exr"), "{err}");
    // No views.json: say what the folder should be.
    let err = evaluate_images(&gt_dir, &gt_dir, Pixels::Mask)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("views.json") && err.contains("wildlight render"),
        "{err}"
    );
}

#[test]
fn materials_with_scale_alignment_and_masks() {
    let root = tempfile::tempdir().unwrap();
    let gt_dir = root.path().join("capture");
    let pred_dir = root.path().join("recon");
    let val = DatasetWriter::create(&gt_dir).unwrap().val().unwrap();
    let tilt = 10f32.to_radians();
    for index in [0usize, 1] {
        let mask = left_half();
        val.write_mask(index, &mask).unwrap();
        val.write_map("base_color", index, &constant([0.2, 0.4, 0.6]))
            .unwrap();
        val.write_map("roughness", index, &constant([0.3; 3]))
            .unwrap();
        val.write_map("metallic", index, &constant([0.0; 3]))
            .unwrap();
        val.write_map("normal", index, &constant([0.0, 0.0, 1.0]))
            .unwrap();

        // Prediction: base colour twice the truth (an unknown flash gain),
        // wrong values outside the mask, which must not count.
        let masked = |inside: [f32; 3], outside: [f32; 3]| {
            let mut img = constant(inside);
            for y in 0..H {
                for x in W / 2..W {
                    img.set(x, y, outside);
                }
            }
            img
        };
        write_pred(
            &pred_dir,
            "base_color",
            index,
            &masked([0.4, 0.8, 1.2], [9.0; 3]),
        );
        write_pred(&pred_dir, "roughness", index, &masked([0.5; 3], [9.0; 3]));
        write_pred(&pred_dir, "metallic", index, &masked([0.1; 3], [9.0; 3]));
        let mut normal = masked([tilt.sin(), 0.0, tilt.cos()], [1.0, 0.0, 0.0]);
        if index == 1 {
            normal.set(0, 0, [0.0; 3]); // no predicted surface at one pixel
            // Four pixels 40° off (a missed crease): the mean moves, the
            // median does not.
            let steep = 40f32.to_radians();
            for y in 0..4 {
                normal.set(1, y, [steep.sin(), 0.0, steep.cos()]);
            }
        }
        write_pred(&pred_dir, "normal", index, &normal);
    }
    let r = evaluate_materials(&pred_dir, &gt_dir, Split::Val).unwrap();
    assert_eq!((r.views, r.pixels), (2, 64));
    // Raw: errors (0.2, 0.4, 0.6) → MSE 0.56/3.
    let raw = 10.0 * (3.0f64 / 0.56).log10();
    assert!((r.base_color_psnr.unwrap() - raw).abs() < 1e-4, "{r:?}");
    // Aligned: the scale 0.5 per channel recovers the truth exactly.
    assert!(r.base_color_psnr_aligned.unwrap() > 90.0, "{r:?}");
    for s in r.base_color_scale.unwrap() {
        assert!((s - 0.5).abs() < 1e-6);
    }
    assert!((r.roughness_mae.unwrap() - 0.2).abs() < 1e-6);
    assert!((r.metallic_mae.unwrap() - 0.1).abs() < 1e-6);
    // 63 compared normals: 59 at 10°, 4 at 40°.
    let mean = (59.0 * 10.0 + 4.0 * 40.0) / 63.0;
    assert!((r.normal_error_deg.unwrap() - mean).abs() < 1e-3, "{r:?}");
    assert!((r.normal_coverage.unwrap() - 63.0 / 64.0).abs() < 1e-12);
    assert!(
        (r.normal_error_median_deg.unwrap() - 10.0).abs() < 1e-3,
        "{r:?}"
    );
    let within: Vec<(f64, f64)> = r
        .normal_within
        .as_ref()
        .unwrap()
        .iter()
        .map(|w| (w.deg, w.fraction))
        .collect();
    let share = 59.0 / 63.0;
    let expected = [
        (1.0, 0.0),
        (5.0, 0.0),
        (11.25, share),
        (22.5, share),
        (30.0, share),
    ];
    assert_eq!(within.len(), expected.len());
    for ((deg, fraction), (want_deg, want)) in within.iter().zip(expected) {
        assert_eq!(*deg, want_deg);
        assert!(
            (fraction - want).abs() < 1e-12,
            "{deg}°: {fraction} vs {want}"
        );
    }

    // The train split has no ground truth here.
    let err = evaluate_materials(&pred_dir, &gt_dir, Split::Train)
        .unwrap_err()
        .to_string();
    assert!(err.contains("ground-truth"), "{err}");
    // Without a roughness prediction the metric is absent, not an error.
    std::fs::remove_dir_all(pred_dir.join("roughness")).unwrap();
    let r = evaluate_materials(&pred_dir, &gt_dir, Split::Val).unwrap();
    assert!(r.roughness_mae.is_none() && r.metallic_mae.is_some());
}
