//! The import end to end on a COLMAP model the test writes (`--colmap`, so
//! COLMAP need not be installed): JPEG photos with EXIF → a capture that
//! `wildlight_data` loads, with the model's cameras, linear
//! exposure-normalized pixels, per-image saturation caps, flash energies,
//! the report and the preview; and every bad input: a clear error naming
//! the files or values, and nothing left in (or beside) `--out`.

mod common;

use std::path::{Path, PathBuf};

use common::{Tags, entries, ring_model, simple_radial, write_jpeg};
use glam::DVec3;
use wildlight_data::{Dataset, LoadOptions};
use wildlight_import::colmap::ColmapModel;
use wildlight_import::linear::{saturation_cap, srgb8_table};
use wildlight_import::{ImportError, ImportOptions, Roi, import};

const W: u32 = 64;
const H: u32 = 48;
const N: usize = 8;
const CENTER: DVec3 = DVec3::new(0.2, -0.1, 1.0);

/// Exposure 1/denom at ISO: the exposures are 1, 2, 0.5, 1, ... × 1/60·100.
const EXPOSURES: [(u32, u16); 4] = [(60, 100), (30, 100), (120, 100), (60, 100)];

/// Photos (flash on the even ones, a saturated corner in each) and a
/// text model of the cameras in `root/photos` and `root/sparse`.
fn setup(root: &Path) -> (PathBuf, PathBuf) {
    let photos = root.join("photos");
    std::fs::create_dir_all(&photos).unwrap();
    for k in 0..N {
        let mut img = common::picture(W, H, k as u32);
        for y in 0..16 {
            for x in 0..16 {
                img.put_pixel(x, y, image::Rgb([255, 255, 255]));
            }
        }
        let (denom, iso) = EXPOSURES[k % 4];
        write_jpeg(
            &photos.join(format!("IMG_{k:04}.jpg")),
            &img,
            Some(&Tags::phone(k % 2 == 0, denom, iso)),
        );
    }
    let sparse = root.join("sparse");
    ring_model(N, 3.0, CENTER, simple_radial(W, H, 60.0, 0.0))
        .write_text(&sparse)
        .unwrap();
    (photos, sparse)
}

fn options(root: &Path) -> ImportOptions {
    let (photos, sparse) = setup(root);
    let mut opts = ImportOptions::new(photos, root.join("capture"));
    opts.colmap_model = Some(sparse);
    opts
}

fn quiet(_: &str) {}

#[test]
fn imports_a_colmap_model_into_a_loadable_capture() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let report = import(&opts, &quiet).expect("import works");
    assert_eq!(report.registered, N);
    assert_eq!((report.flash_count, report.no_flash_count), (N / 2, N / 2));
    assert_eq!(report.image_size, [W, H]);
    // nothing but the capture was added beside the inputs
    assert_eq!(entries(dir.path()), ["capture", "photos", "sparse"]);
    for f in ["cameras_sphere.npz", "import.json", "roi.png", "colmap"] {
        assert!(opts.out.join(f).exists(), "{f}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(opts.out.join("import.json")).unwrap())
            .unwrap();
    let photos = json["photos"].as_array().unwrap();
    assert_eq!(photos.len(), N);
    assert_eq!(photos[3]["file"], "IMG_0003.jpg");
    assert_eq!(photos[3]["index"], 3);
    assert_eq!(photos[3]["flash"], false);
    assert_eq!(photos[2]["flash"], true);
    assert_eq!(photos[3]["dropped"], serde_json::Value::Null);
    // exposures 1, 2, 0.5, 1 (× a constant): the median (lower middle) is 1
    let scales: Vec<f64> = photos[..4]
        .iter()
        .map(|p| p["exposure_scale"].as_f64().unwrap())
        .collect();
    assert_eq!(scales, [1.0, 0.5, 2.0, 1.0]);

    let data = Dataset::load(&opts.out, &LoadOptions::default()).expect("the capture loads");
    assert_eq!(data.views.len(), N);
    assert!(!data.has_masks());
    let model = ColmapModel::read(&opts.model_dir()).unwrap();
    let table = srgb8_table();
    for (k, view) in data.views.iter().enumerate() {
        let cam = &view.camera;
        // the model's camera: centre, and K with pixel centres at integers
        let image = &model.images[&(k as u32 + 1)];
        assert!((cam.center_world() - image.center()).length() < 1e-9);
        assert!((cam.fx() - 60.0).abs() < 1e-6 && (cam.fy() - 60.0).abs() < 1e-6);
        assert!((cam.cx() - 31.5).abs() < 1e-6 && (cam.cy() - 23.5).abs() < 1e-6);
        // cameras outside the unit sphere
        assert!(cam.center.length() > 1.0);
        // flash energy on the even photos only
        assert_eq!(cam.flash(), k % 2 == 0);
        // linear pixels: sRGB decoded, times the exposure scale
        let jpeg = image::open(dir.path().join(format!("photos/IMG_{k:04}.jpg")))
            .unwrap()
            .into_rgb8();
        let scale = scales[k % 4] as f32;
        for (x, y) in [(10, 10), (40, 30), (63, 47)] {
            let code = jpeg.get_pixel(x, y).0;
            let got = view.image.get(x, y);
            for c in 0..3 {
                let want = table[code[c] as usize] * scale;
                assert!(
                    (got[c] - want).abs() < 1e-4,
                    "view {k} ({x}, {y}): {got:?} vs {code:?}"
                );
            }
        }
        // the saturated corner is at or above this view's cap, the rest below
        let cap = view.saturation.expect("a per-image cap");
        assert!((cap as f64 - saturation_cap(scale as f64)).abs() < 1e-6);
        assert!(view.image.get(4, 4).iter().all(|v| *v >= cap));
        assert!(view.image.get(40, 30).iter().all(|v| *v < cap));
    }
    let energies: Vec<f64> = data
        .views
        .iter()
        .filter(|v| v.camera.flash())
        .map(|v| v.camera.light_energy[0])
        .collect();
    assert!(energies.iter().all(|e| *e == energies[0] && *e > 0.0));
    // the global cap is the lowest per-image cap
    let lowest = data
        .views
        .iter()
        .filter_map(|v| v.saturation)
        .fold(f32::MAX, f32::min);
    assert!((data.saturation.unwrap() - lowest).abs() < 1e-6);

    // an import over an earlier one replaces it
    let again = import(&opts, &quiet).unwrap();
    assert_eq!(again.registered, N);
    assert_eq!(entries(dir.path()), ["capture", "photos", "sparse"]);
}

trait ModelDir {
    fn model_dir(&self) -> PathBuf;
}
impl ModelDir for ImportOptions {
    fn model_dir(&self) -> PathBuf {
        self.colmap_model.clone().unwrap()
    }
}

#[test]
fn max_size_resizes_and_scales_k() {
    let dir = tempfile::tempdir().unwrap();
    let mut opts = options(dir.path());
    opts.max_size = 32;
    import(&opts, &quiet).unwrap();
    let data = Dataset::load(&opts.out, &LoadOptions::default()).unwrap();
    let cam = &data.views[0].camera;
    assert_eq!((cam.width, cam.height), (32, 24));
    // f 60 → 30; cx 32 (COLMAP) → 16 → 15.5 with pixel centres at integers
    assert!((cam.fx() - 30.0).abs() < 1e-6);
    assert!((cam.cx() - 15.5).abs() < 1e-6 && (cam.cy() - 11.5).abs() < 1e-6);
}

/// Runs the import expecting an error; checks nothing was left behind.
fn fails(opts: &ImportOptions) -> ImportError {
    let parent = opts.out.parent().unwrap().to_path_buf();
    let before = entries(&parent);
    let npz = opts.out.join("cameras_sphere.npz").exists();
    let err = import(opts, &quiet).expect_err("the import fails");
    assert_eq!(
        before,
        entries(&parent),
        "the import left files beside --out"
    );
    assert_eq!(npz, opts.out.join("cameras_sphere.npz").exists());
    err
}

#[test]
fn an_empty_folder() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("photos")).unwrap();
    std::fs::write(dir.path().join("photos/notes.txt"), "hi").unwrap();
    let opts = ImportOptions::new(dir.path().join("photos"), dir.path().join("capture"));
    let err = fails(&opts);
    assert!(matches!(err, ImportError::NoPhotos { .. }), "{err}");
    assert!(err.to_string().contains("no photos found"));
    let opts = ImportOptions::new(dir.path().join("missing"), dir.path().join("capture"));
    assert!(fails(&opts).to_string().contains("not found"));
}

#[test]
fn unreadable_and_truncated_photos() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    std::fs::write(opts.photos.join("IMG_0100.jpg"), b"not a jpeg").unwrap();
    let bytes = std::fs::read(opts.photos.join("IMG_0001.jpg")).unwrap();
    std::fs::write(opts.photos.join("IMG_0101.jpg"), &bytes[..bytes.len() / 2]).unwrap();
    let msg = fails(&opts).to_string();
    assert!(
        msg.contains("IMG_0100.jpg") && msg.contains("IMG_0101.jpg"),
        "{msg}"
    );
}

#[test]
fn no_flash_information() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    write_jpeg(
        &opts.photos.join("IMG_0003.jpg"),
        &common::picture(W, H, 3),
        None,
    );
    let msg = fails(&opts).to_string();
    assert!(
        msg.contains("IMG_0003.jpg") && msg.contains("--flash"),
        "{msg}"
    );
    // a label fixes it
    let mut opts = opts;
    opts.no_flash = Some("IMG_0003.jpg".into());
    let report = import(&opts, &quiet).unwrap();
    assert_eq!(report.photos[3].dropped, None);
    assert!(!report.photos[3].flash);
}

#[test]
fn photos_of_different_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    write_jpeg(
        &opts.photos.join("IMG_0005.jpg"),
        &common::picture(48, 64, 5),
        Some(&Tags::phone(false, 60, 100)),
    );
    let err = fails(&opts);
    let msg = err.to_string();
    assert!(matches!(err, ImportError::MixedSizes { .. }));
    assert!(
        msg.contains("64x48") && msg.contains("48x64") && msg.contains("IMG_0005.jpg"),
        "{msg}"
    );
}

#[test]
fn too_few_photos_registered() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let mut model = ColmapModel::read(opts.colmap_model.as_ref().unwrap()).unwrap();
    model.images.retain(|id, _| *id == 1);
    model
        .write_text(opts.colmap_model.as_ref().unwrap())
        .unwrap();
    let err = fails(&opts);
    let msg = err.to_string();
    assert!(
        matches!(
            err,
            ImportError::TooFewRegistered {
                registered: 1,
                total: 8,
                ..
            }
        ),
        "{msg}"
    );
    assert!(
        msg.contains("IMG_0001.jpg") && msg.contains("IMG_0007.jpg"),
        "{msg}"
    );
    assert!(!msg.contains("IMG_0000.jpg"), "{msg}");
}

#[test]
fn a_region_that_puts_cameras_inside() {
    let dir = tempfile::tempdir().unwrap();
    let mut opts = options(dir.path());
    // the cameras are 3.0 · √1.16 = 3.23 from the centre
    opts.roi = Some(Roi {
        center: CENTER,
        radius: 3.5,
    });
    let err = fails(&opts);
    let msg = err.to_string();
    assert!(
        matches!(err, ImportError::CamerasInside { count: 8, .. }),
        "{msg}"
    );
    assert!(
        msg.contains("IMG_0000.jpg") && msg.contains("radii") && msg.contains("3.5"),
        "{msg}"
    );
    // a radius that fits is used as given
    opts.roi = Some(Roi {
        center: CENTER,
        radius: 1.5,
    });
    let report = import(&opts, &quiet).unwrap();
    assert_eq!(report.roi.source, "override");
    assert_eq!(report.roi.radius, 1.5);
}

#[test]
fn an_output_folder_that_is_not_a_capture() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    std::fs::create_dir(&opts.out).unwrap();
    std::fs::write(opts.out.join("thesis.tex"), "precious").unwrap();
    let err = fails(&opts);
    assert!(matches!(err, ImportError::OutputExists { .. }), "{err}");
    assert_eq!(
        std::fs::read_to_string(opts.out.join("thesis.tex")).unwrap(),
        "precious"
    );
}

#[test]
fn colmap_not_installed() {
    let dir = tempfile::tempdir().unwrap();
    let err = wildlight_import::colmap::find_colmap_in(dir.path().as_os_str()).unwrap_err();
    assert!(matches!(err, ImportError::ColmapMissing));
    assert!(err.to_string().contains("apt-get install colmap"), "{err}");
}

#[test]
fn exr_photos_pass_through_as_linear() {
    let dir = tempfile::tempdir().unwrap();
    let (_, sparse) = setup(dir.path());
    let photos = dir.path().join("exr");
    std::fs::create_dir(&photos).unwrap();
    let value = |k: usize, x: u32, y: u32, c: usize| {
        0.05 + 0.1 * k as f32 + 0.01 * x as f32 + 0.002 * y as f32 + 0.3 * c as f32
    };
    for k in 0..N {
        let mut img = wildlight_data::RgbImage::new(W, H);
        for y in 0..H {
            for x in 0..W {
                img.set(x, y, [0, 1, 2].map(|c| value(k, x, y, c)));
            }
        }
        wildlight_data::exr_io::write_exr_rgb(&photos.join(format!("IMG_{k:04}.exr")), &img)
            .unwrap();
    }
    let mut opts = ImportOptions::new(&photos, dir.path().join("capture"));
    opts.colmap_model = Some(sparse);
    // EXR has no EXIF: the labels come from the options
    assert!(matches!(
        import(&opts, &quiet).unwrap_err(),
        ImportError::NoFlashInfo { count: 8, .. }
    ));
    opts.flash = Some("IMG_000[0246].exr".into());
    opts.no_flash = Some("IMG_000[1357].exr".into());
    let report = import(&opts, &quiet).unwrap();
    assert_eq!(report.flash_count, 4);
    assert!(
        report
            .photos
            .iter()
            .all(|p| p.exposure_scale == 1.0 && p.max_intensity.is_none())
    );
    assert_eq!(report.max_intensity, None);
    let data = Dataset::load(&opts.out, &LoadOptions::default()).unwrap();
    assert_eq!(data.saturation, None);
    for (k, view) in data.views.iter().enumerate() {
        assert_eq!(view.saturation, None);
        for (x, y) in [(0, 0), (17, 31), (63, 47)] {
            let got = view.image.get(x, y);
            for c in 0..3 {
                assert!((got[c] - value(k, x, y, c)).abs() < 1e-4, "{got:?}");
            }
        }
    }
}

#[test]
fn flash_energy_from_the_brightness_difference() {
    let dir = tempfile::tempdir().unwrap();
    let mut opts = options(dir.path());
    // uniform grey photos: code 150 with the flash, 100 without, one exposure
    for k in 0..N {
        let code = if k % 2 == 0 { 150 } else { 100 };
        write_jpeg(
            &opts.photos.join(format!("IMG_{k:04}.jpg")),
            &image::RgbImage::from_pixel(W, H, image::Rgb([code; 3])),
            Some(&Tags::phone(k % 2 == 0, 60, 100)),
        );
    }
    opts.roi = Some(Roi {
        center: CENTER,
        radius: 1.5,
    });
    let report = import(&opts, &quiet).unwrap();
    // the object's pixel ≈ E · (0.5 / π) / d² with d the distance (in
    // radii) from the camera to a surface 0.6 radii in front of the centre
    let d = 3.0 * 1.16f64.sqrt() / 1.5 - 0.6;
    let lin = |c: f32| wildlight_import::linear::srgb_to_linear(c / 255.0) as f64;
    let expected = (lin(150.0) - lin(100.0)) * d * d * std::f64::consts::PI / 0.5;
    assert!(
        (report.light_energy / expected - 1.0).abs() < 0.01,
        "{} against {expected}",
        report.light_energy
    );
    let data = Dataset::load(&opts.out, &LoadOptions::default()).unwrap();
    for view in &data.views {
        let e = view.camera.light_energy;
        if view.camera.flash() {
            assert_eq!(e, [report.light_energy; 3]);
        } else {
            assert_eq!(e, [0.0; 3]);
        }
    }
}
