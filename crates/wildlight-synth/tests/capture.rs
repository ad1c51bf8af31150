//! End-to-end checks of a written synthetic capture: masks against the
//! ground-truth mesh, the flash term against an independent evaluation
//! from the ground-truth maps, inverse-square falloff, reading back through
//! the dataset loader, and determinism across thread counts.

use std::path::Path;

use glam::DVec3;
use wildlight_data::exr_io::{read_exr_channels, read_exr_rgb};
use wildlight_data::{Dataset, LoadOptions, RgbImage};
use wildlight_mesh::TriMesh;
use wildlight_pathtrace::general_brdf;
use wildlight_synth::{
    BuiltinScene, GroundTruthMaterial, RenderScene, RigOptions, SceneSource, SynthOptions,
    synthesize,
};

fn small_options(out: &Path, scene: BuiltinScene) -> SynthOptions {
    SynthOptions {
        source: SceneSource::Builtin(scene),
        rig: RigOptions {
            views: 4,
            val_views: 2,
            width: 64,
            height: 56,
            flash_fraction: 0.5,
            seed: 3,
            ..RigOptions::default()
        },
        spp: 4,
        val_spp: 4,
        mesh_resolution: 64,
        // full HDR: the flash term is compared exactly, highlights included
        saturation: None,
        out: out.to_path_buf(),
        progress: false,
        ..SynthOptions::default()
    }
}

fn load(dir: &Path) -> Dataset {
    Dataset::load(dir, &LoadOptions::default()).expect("the capture loads")
}

/// Every visible ground-truth vertex projects into the mask (≥ 99 %: the
/// bilinearly interpolated mask is positive there), and the mesh covers the
/// mask (≥ 99 % of its pixels are hit by a ray through the pixel).
#[test]
fn ground_truth_mesh_projects_into_the_mask_and_covers_it() {
    let dir = tempfile::tempdir().unwrap();
    for scene in BuiltinScene::ALL {
        let out = dir.path().join(scene.name());
        // At 64×56 a thin part narrower than half a pixel is in no mask pixel;
        // at 256×224 every part of both scenes spans pixels.
        let mut opts = small_options(&out, scene);
        opts.rig.width = 256;
        opts.rig.height = 224;
        opts.spp = 1;
        opts.val_spp = 1;
        synthesize(&opts).unwrap();
        let mesh = TriMesh::read(out.join("gt/mesh_normalized.ply")).unwrap();
        let world = TriMesh::read(out.join("gt/mesh_world.ply")).unwrap();
        let rs = RenderScene::new(
            &mesh,
            wildlight_synth::MaterialDefinition::Procedural {
                name: "patches".into(),
            },
        );
        let data = load(&out);
        let mut views = data.views.clone();
        views.extend(data.val.as_ref().expect("val split").views.clone());
        for view in &views {
            let cam = &view.camera;
            let mask = view.mask.as_ref().expect("mask");
            let (w, h) = (cam.width as i64, cam.height as i64);
            let (mut visible, mut inside, mut strictly_inside) = (0usize, 0usize, 0usize);
            for (p, pw) in mesh.positions.iter().zip(&world.positions) {
                let p = p.as_dvec3();
                // the world mesh is the normalized one through scale_mat
                assert!(cam.to_world(p).abs_diff_eq(pw.as_dvec3(), 1e-5));
                let Some(uv) = cam.project(p) else { continue };
                if !cam.contains_pixel(uv) {
                    continue;
                }
                let to = p - cam.center;
                let dist = to.length();
                if rs.occluded(cam.center, to / dist, dist - 2e-3) {
                    continue;
                }
                visible += 1;
                let (x, y) = (uv.x.round() as i64, uv.y.round() as i64);
                strictly_inside += mask.get(x as u32, y as u32) as usize;
                // The mask marks the pixels the object covers by at least half, so
                // its edge lies up to half a pixel inside the true silhouette, where
                // foreshortening crowds the vertices. A vertex lands inside the mask
                // when the mask interpolated bilinearly at its projection is
                // positive: one of the four pixel centres around it is set.
                let (x0, y0) = (uv.x.floor() as i64, uv.y.floor() as i64);
                let mut touches = false;
                for (nx, ny) in [(x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)] {
                    if nx >= 0 && ny >= 0 && nx < w && ny < h {
                        touches |= mask.get(nx as u32, ny as u32);
                    }
                }
                inside += touches as usize;
            }
            assert!(
                visible > 100,
                "{}: only {visible} visible vertices",
                scene.name()
            );
            let frac = inside as f64 / visible as f64;
            let strict = strictly_inside as f64 / visible as f64;
            eprintln!(
                "{} view {}: {strict:.4} of visible vertices in mask pixels, {frac:.4} where the bilinear mask is > 0",
                scene.name(),
                cam.index
            );
            assert!(
                frac >= 0.99,
                "{} view {}: {frac} of visible vertices touch the mask",
                scene.name(),
                cam.index
            );
            assert!(
                strict >= 0.75,
                "{} view {}: {strict} of visible vertices in mask pixels",
                scene.name(),
                cam.index
            );
            let (mut mask_px, mut covered) = (0usize, 0usize);
            for y in 0..h {
                for x in 0..w {
                    if !mask.get(x as u32, y as u32) {
                        continue;
                    }
                    mask_px += 1;
                    // The mesh covers a mask pixel when it is hit by the ray through
                    // the pixel's centre or through one of its corners (a pixel is
                    // in the mask once the object covers half of it).
                    let mut any = false;
                    for (ox, oy) in [
                        (0.0, 0.0),
                        (-0.5, -0.5),
                        (0.5, -0.5),
                        (-0.5, 0.5),
                        (0.5, 0.5),
                    ] {
                        let ray = cam.ray(x as f64 + ox, y as f64 + oy);
                        any |= rs.occluded(ray.origin, ray.dir, 10.0);
                    }
                    covered += any as usize;
                }
            }
            assert!(mask_px > 200, "mask too small: {mask_px}");
            let frac = covered as f64 / mask_px as f64;
            assert!(
                frac >= 0.99,
                "{} view {}: {frac} of mask pixels covered",
                scene.name(),
                cam.index
            );
        }
    }
}

/// image − ambient of a flash view equals E ρ(c) c / d² evaluated from the
/// ground-truth maps (position from the depth map, normal map, params map)
/// with the general BRDF at l = v — not the renderer's code path.
#[test]
fn flash_view_minus_ambient_is_the_flash_term_of_the_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cap");
    let mut opts = small_options(&out, BuiltinScene::Kettle);
    opts.rig.flash_fraction = 1.0;
    opts.rig.exposure = 0.7;
    synthesize(&opts).unwrap();
    let data = load(&out);
    let gt = GroundTruthMaterial::load(&out.join("gt/material.json")).unwrap();
    let settings = gt.brdf_settings;
    let mut checked = 0;
    for view in &data.views {
        let cam = &view.camera;
        assert!(cam.flash());
        for (e, want) in cam.light_energy.iter().zip(opts.rig.flash_energy) {
            assert!(
                (e - want * 0.7).abs() < 1e-12,
                "light_energy includes the exposure"
            );
        }
        let name = format!("{:03}.exr", cam.index);
        let ambient = read_exr_rgb(&out.join("gt/ambient").join(&name)).unwrap();
        let depth = read_exr_rgb(&out.join("gt/depth").join(&name)).unwrap();
        let normal = read_exr_rgb(&out.join("gt/normal").join(&name)).unwrap();
        let params = read_exr_channels(&out.join("gt/params").join(&name)).unwrap();
        let p: Vec<&[f32]> = (0..9)
            .map(|c| params.channel(&format!("p{c}")).unwrap())
            .collect();
        let mask = view.mask.as_ref().unwrap();
        for y in 0..cam.height {
            for x in 0..cam.width {
                let d = depth.get(x, y)[0] as f64;
                let img = view.image.get(x, y);
                let amb = ambient.get(x, y);
                if d <= 0.0 {
                    // no surface: no flash
                    for c in 0..3 {
                        assert_eq!(img[c], amb[c]);
                    }
                    continue;
                }
                let ray = cam.ray(x as f64, y as f64);
                let t = d / cam.world_scale();
                let pos = ray.at(t);
                let n = DVec3::from(normal.get(x, y).map(|v| v as f64));
                assert!((n.length() - 1.0).abs() < 1e-5);
                let i = (y * cam.width + x) as usize;
                let theta: [f64; 9] = std::array::from_fn(|c| p[c][i] as f64);
                // the ground-truth material evaluated at the surface point agrees
                let m = gt.eval_normalized(pos).to_array::<f64>();
                if mask.get(x, y) {
                    let close = m.iter().zip(&theta).all(|(a, b)| (a - b).abs() < 1e-4);
                    checked += close as usize;
                }
                let h = (cam.center - pos).normalize();
                let c = n.dot(h).max(0.0);
                let rho = general_brdf::eval(&theta, n, h, h, &settings);
                let dist2 = (cam.center - pos).length_squared();
                for ch in 0..3 {
                    let want = cam.light_energy[ch] * rho[ch] * c / dist2;
                    let got = img[ch] as f64 - amb[ch] as f64;
                    let tol = 2e-6 * (img[ch] as f64).abs() + 1e-4 * want + 1e-7;
                    assert!(
                        (got - want).abs() <= tol,
                        "view {} pixel ({x},{y}) ch {ch}: {got} vs {want}",
                        cam.index
                    );
                }
            }
        }
    }
    assert!(
        checked > 500,
        "material at depth points matched only {checked} times"
    );
}

/// Moving the camera twice as far along the same line quarters the flash
/// at the image centre (same surface point, same normal, same material).
#[test]
fn doubling_the_camera_distance_quarters_the_flash() {
    let dir = tempfile::tempdir().unwrap();
    let mut centre = Vec::new();
    for distance in [2.0, 4.0] {
        let out = dir.path().join(format!("d{distance}"));
        let mut opts = small_options(&out, BuiltinScene::Kettle);
        opts.rig = RigOptions {
            views: 1,
            val_views: 0,
            width: 33,
            height: 33,
            distance,
            jitter: 0.0,
            flash_fraction: 1.0,
            elevation_min_deg: 20.0,
            elevation_max_deg: 20.0,
            ..RigOptions::default()
        };
        synthesize(&opts).unwrap();
        let flash: RgbImage = read_exr_rgb(&out.join("gt/flash/000.exr")).unwrap();
        let depth = read_exr_rgb(&out.join("gt/depth/000.exr")).unwrap();
        centre.push((flash.get(16, 16), depth.get(16, 16)[0]));
    }
    let ((f1, d1), (f2, d2)) = (centre[0], centre[1]);
    let scale = RigOptions::default().world_scale as f32;
    assert!(f1[0] > 0.0);
    assert!(((d2 - d1) - 2.0 * scale).abs() < 1e-4, "depths {d1} {d2}");
    // the same point seen from twice as far (d2 = d1 + 2·scale, distance 2 → 4):
    // the flash falls off with the squared distance
    let ratio = (d2 / d1).powi(2);
    for c in 0..3 {
        assert!(
            (f1[c] / f2[c] - ratio).abs() < 1e-4 * ratio,
            "{} vs {ratio}",
            f1[c] / f2[c]
        );
    }
}

/// The written dataset reads back through the dataset loader with the same
/// cameras (matrices, intrinsics, pose, flash), training and val splits.
#[test]
fn capture_reads_back_with_the_same_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cap");
    let opts = small_options(&out, BuiltinScene::Sampler);
    let summary = synthesize(&opts).unwrap();
    assert_eq!(summary.train_views, 4);
    assert_eq!(summary.val_views, 2);
    let rig = opts.rig.build().unwrap();
    let data = load(&out);
    let val = data.val.as_ref().unwrap();
    assert_eq!(data.views.len(), 4);
    assert_eq!(val.views.len(), 2);
    assert_eq!(data.saturation, None);
    let loaded: Vec<_> = data
        .views
        .iter()
        .chain(&val.views)
        .map(|v| &v.camera)
        .collect();
    for (want, got) in rig.iter().map(|r| &r.camera).zip(loaded) {
        assert_eq!(want.index, got.index);
        assert_eq!(want.world_mat, got.world_mat);
        assert_eq!(want.scale_mat, got.scale_mat);
        assert_eq!(want.light_energy, got.light_energy);
        assert!((want.k - got.k).abs_diff_eq(glam::DMat3::ZERO, 1e-9));
        assert!(want.center.abs_diff_eq(got.center, 1e-9));
        assert!((want.c2w - got.c2w).abs_diff_eq(glam::DMat3::ZERO, 1e-9));
    }
    assert_eq!(data.flash_count(), 2);
    // a second run into the same folder needs --overwrite
    let err = synthesize(&opts).unwrap_err().to_string();
    assert!(err.contains("--overwrite"), "{err}");
    // the images are finite, non-negative, and brighter where the object is lit
    for v in &data.views {
        assert!(v.image.data.iter().all(|x| x.is_finite() && *x >= 0.0));
    }
}

/// Saturation clips the images and is written as max_intensity; noise
/// changes the image but not the ground-truth maps; the per-pixel random
/// numbers make the result independent of the thread count.
#[test]
fn noise_saturation_and_determinism() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, threads: usize, noise: f64, cap: Option<f64>| {
        let out = dir.path().join(name);
        let mut opts = small_options(&out, BuiltinScene::Kettle);
        opts.rig.views = 2;
        opts.rig.val_views = 0;
        opts.noise = noise;
        opts.saturation = cap;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| synthesize(&opts)).unwrap();
        load(&out)
    };
    let a = render("a", 1, 0.0, None);
    let b = render("b", 2, 0.0, None);
    for (va, vb) in a.views.iter().zip(&b.views) {
        assert_eq!(va.image, vb.image, "thread count changed the image");
    }
    let noisy = render("n", 2, 0.05, Some(0.5));
    assert_eq!(noisy.saturation, Some(0.5));
    let mut differs = 0;
    for (va, vn) in a.views.iter().zip(&noisy.views) {
        assert!(vn.image.data.iter().all(|x| (0.0..=0.5).contains(x)));
        differs += va
            .image
            .data
            .iter()
            .zip(&vn.image.data)
            .filter(|(x, y)| x != y)
            .count();
    }
    assert!(differs > 1000);
    let amb_a = read_exr_rgb(&dir.path().join("a/gt/ambient/000.exr")).unwrap();
    let amb_n = read_exr_rgb(&dir.path().join("n/gt/ambient/000.exr")).unwrap();
    assert_eq!(amb_a, amb_n, "ground truth is noise free");
}

/// Mean absolute difference between horizontally adjacent pixels of the
/// masked object: Monte Carlo noise raises it.
fn roughness_of(img: &RgbImage, mask: &[bool]) -> f64 {
    let w = img.width as usize;
    let (mut sum, mut n) = (0.0f64, 0usize);
    for i in 0..img.pixel_count() {
        if i % w + 1 < w && mask[i] && mask[i + 1] {
            for c in 0..3 {
                sum += (img.data[3 * i + c] - img.data[3 * (i + 1) + c]).abs() as f64;
            }
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// Held-out views are references: rendered with `val_spp` samples and no
/// sensor noise, so their photo is exactly the clipped sum of the
/// ground-truth ambient and flash maps, and more samples make it smoother;
/// the training photos keep `spp` and the noise.
#[test]
fn held_out_views_are_noise_free_references_at_val_spp() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, val_spp: usize| {
        let out = dir.path().join(name);
        let mut opts = small_options(&out, BuiltinScene::Kettle);
        opts.rig.views = 2;
        opts.rig.val_views = 2;
        opts.spp = 1;
        opts.val_spp = val_spp;
        opts.noise = 0.05;
        opts.saturation = Some(1.0);
        synthesize(&opts).unwrap();
        out
    };
    let coarse = render("coarse", 1);
    let fine = render("fine", 64);
    let maps = |dir: &Path, split: &str, i: usize| {
        let sub = if split == "val" {
            dir.join("val")
        } else {
            dir.to_path_buf()
        };
        let read = |kind: &str| {
            let path = if kind == "image" {
                sub.join(format!("image/{i:03}.exr"))
            } else {
                sub.join(format!("gt/{kind}/{i:03}.exr"))
            };
            read_exr_rgb(&path).unwrap()
        };
        (read("image"), read("ambient"), read("flash"))
    };
    let data = load(&fine);
    let val = data.val.as_ref().expect("val split");
    let mut smoother = 0;
    for (k, view) in val.views.iter().enumerate() {
        let (image, ambient, flash) = maps(&fine, "val", view.camera.index);
        for ((p, a), f) in image.data.iter().zip(&ambient.data).zip(&flash.data) {
            let expected = (a + f).clamp(0.0, 1.0);
            assert!((p - expected).abs() < 1e-5, "val photo {p} vs {expected}");
        }
        let mask = val.views[k].mask.as_ref().expect("mask").data.clone();
        let (_, coarse_ambient, _) = maps(&coarse, "val", view.camera.index);
        if roughness_of(&ambient, &mask) < 0.8 * roughness_of(&coarse_ambient, &mask) {
            smoother += 1;
        }
    }
    assert_eq!(
        smoother,
        val.views.len(),
        "64 samples must be smoother than 1"
    );
    // The training photos keep the sensor noise.
    let (image, ambient, flash) = maps(&fine, "train", data.views[0].camera.index);
    let noisy = image
        .data
        .iter()
        .zip(ambient.data.iter().zip(&flash.data))
        .filter(|(p, (a, f))| (*p - (*a + *f).clamp(0.0, 1.0)).abs() > 1e-4)
        .count();
    assert!(noisy > 100, "only {noisy} noisy training pixels");
}
