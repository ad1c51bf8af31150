//! Photos and EXIF on real files the tests write: the flash bit, the
//! exposure tags, the orientation (applied to the pixels), 8- and 16-bit
//! sRGB decoding and exposure scaling against hand-computed values, and
//! the flash labels.

mod common;

use common::{Tags, write_jpeg};
use wildlight_import::ImportError;
use wildlight_import::linear::{
    ExposureScales, exposure_scales, saturated_share, saturation_cap, to_linear,
};
use wildlight_import::photos::{FlashSource, Pixels, decode, flash_labels, read_exif, scan_photos};

fn photo(dir: &std::path::Path, name: &str, tags: Option<&Tags>) -> std::path::PathBuf {
    let path = dir.join(name);
    write_jpeg(&path, &common::picture(32, 24, 1), tags);
    path
}

#[test]
fn flash_bit_zero_decides() {
    let dir = tempfile::tempdir().unwrap();
    for (value, fired) in [
        (0x19u16, true),
        (0x10, false),
        (0x18, false),
        (0x01, true),
        (0x00, false),
    ] {
        let tags = Tags {
            flash: Some(value),
            ..Tags::default()
        };
        let p = photo(dir.path(), &format!("f{value}.jpg"), Some(&tags));
        let (exif, warning) = read_exif(&p).unwrap();
        assert_eq!(warning, None);
        assert_eq!(exif.flash, Some(value as u32));
        assert_eq!(exif.flash_fired(), Some(fired), "Flash = {value:#x}");
    }
    // no tag at all, and no EXIF at all: unknown, not "off"
    let p = photo(
        dir.path(),
        "notag.jpg",
        Some(&Tags {
            iso: Some(100),
            ..Tags::default()
        }),
    );
    assert_eq!(read_exif(&p).unwrap().0.flash_fired(), None);
    let p = photo(dir.path(), "noexif.jpg", None);
    let (exif, warning) = read_exif(&p).unwrap();
    assert_eq!(
        (exif.flash_fired(), exif.orientation, warning),
        (None, 1, None)
    );
}

#[test]
fn exposure_tags_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let p = photo(dir.path(), "a.jpg", Some(&Tags::phone(true, 60, 200)));
    let (exif, _) = read_exif(&p).unwrap();
    assert!((exif.exposure_time.unwrap() - 1.0 / 60.0).abs() < 1e-12);
    assert_eq!(exif.iso, Some(200.0));
    assert!((exif.f_number.unwrap() - 1.8).abs() < 1e-12);
    assert!((exif.focal_length_mm.unwrap() - 4.7).abs() < 1e-12);
    assert_eq!(exif.focal_length_35mm, Some(26.0));
    // t · ISO / N² = (1/60) · 200 / 1.8² = 1.0288065843621
    assert!((exif.exposure().unwrap() - 1.028_806_584_362_14).abs() < 1e-12);
    // without FNumber (fixed aperture): t · ISO
    let p = photo(
        dir.path(),
        "b.jpg",
        Some(&Tags {
            exposure: Some((1, 100)),
            iso: Some(400),
            ..Tags::default()
        }),
    );
    assert!((read_exif(&p).unwrap().0.exposure().unwrap() - 4.0).abs() < 1e-12);
    // without ISO: unknown
    let p = photo(
        dir.path(),
        "c.jpg",
        Some(&Tags {
            exposure: Some((1, 100)),
            ..Tags::default()
        }),
    );
    assert_eq!(read_exif(&p).unwrap().0.exposure(), None);
}

/// A 64×32 picture in four flat quadrants: red, green / blue, white.
fn quadrants() -> image::RgbImage {
    image::RgbImage::from_fn(64, 32, |x, y| {
        image::Rgb(match (x < 32, y < 16) {
            (true, true) => [255, 0, 0],
            (false, true) => [0, 255, 0],
            (true, false) => [0, 0, 255],
            (false, false) => [255, 255, 255],
        })
    })
}

fn colour_at(d: &wildlight_import::photos::Decoded, x: u32, y: u32) -> [u8; 3] {
    let Pixels::Srgb8(p) = &d.pixels else {
        panic!("8-bit")
    };
    let i = 3 * (y * d.width + x) as usize;
    // snap to 0/255 (JPEG is lossy)
    [p[i], p[i + 1], p[i + 2]].map(|c| if c > 127 { 255 } else { 0 })
}

#[test]
fn orientation_is_applied_to_the_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let (red, green, blue, white) = ([255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]);
    // the displayed top-left quadrant for each orientation
    for (o, size, top_left, top_right) in [
        (1u16, (64, 32), red, green),
        (3, (64, 32), white, blue),
        (6, (32, 64), blue, red),
        (8, (32, 64), green, white),
    ] {
        let path = dir.path().join(format!("o{o}.jpg"));
        let tags = Tags {
            orientation: Some(o),
            ..Tags::default()
        };
        write_jpeg(&path, &quadrants(), Some(&tags));
        let (exif, _) = read_exif(&path).unwrap();
        assert_eq!(exif.orientation, o);
        let d = decode(&path, exif.orientation).unwrap();
        assert_eq!((d.width, d.height), size, "orientation {o}");
        let (w, h) = size;
        assert_eq!(colour_at(&d, w / 4, h / 8), top_left, "orientation {o}");
        assert_eq!(
            colour_at(&d, 3 * w / 4, h / 8),
            top_right,
            "orientation {o}"
        );
        // scan_photos reports the oriented size
        let info = &scan_photos(std::slice::from_ref(&path)).unwrap()[0];
        assert_eq!((info.width, info.height), size);
    }
}

#[test]
fn srgb_decoding_and_exposure_scaling_match_hand_computed_values() {
    let dir = tempfile::tempdir().unwrap();
    // 8-bit PNG (lossless), codes 128, 10, 250 in one pixel
    let path = dir.path().join("p8.png");
    image::RgbImage::from_raw(1, 1, vec![128, 10, 250])
        .unwrap()
        .save(&path)
        .unwrap();
    let d = decode(&path, 1).unwrap();
    let lin = to_linear(&d, 2.0);
    // ((128/255 + 0.055)/1.055)^2.4 · 2 = 0.4317210; 10/255/12.92 · 2 = 0.0060705
    assert!((lin.data[0] - 0.431_721).abs() < 1e-6, "{}", lin.data[0]);
    assert!((lin.data[1] - 0.006_070_54).abs() < 1e-7, "{}", lin.data[1]);
    // code 250 is saturated: raised to the clip level (the scale) ...
    assert_eq!(lin.data[2], 2.0);
    assert_eq!(lin.saturated, vec![0b100]);
    // ... above the photo's cap lin(250/255) · 2 = 1.9119467
    assert!((saturation_cap(2.0) - 1.911_946_7).abs() < 1e-6);
    assert!(lin.data[2] as f64 >= saturation_cap(2.0));
    assert!((lin.data[0] as f64) < saturation_cap(2.0));
    assert_eq!(saturated_share(&d.pixels), 1.0);

    // 16-bit PNG: codes 32768, 1000, 64249 (just below 250/255), 64250
    let path = dir.path().join("p16.png");
    image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(
        2,
        1,
        vec![32768u16, 1000, 64249, 64250, 0, 0],
    )
    .unwrap()
    .save(&path)
    .unwrap();
    let d = decode(&path, 1).unwrap();
    assert!(matches!(d.pixels, Pixels::Srgb16(_)));
    let lin = to_linear(&d, 1.0);
    // 32768/65535 → 0.2140482; 1000/65535 → 0.00118104 (linear segment); 64249 → 0.9559395
    assert!((lin.data[0] - 0.214_048_2).abs() < 1e-6);
    assert!((lin.data[1] - 0.001_181_04).abs() < 1e-7);
    assert!((lin.data[2] - 0.955_939_5).abs() < 1e-6);
    assert_eq!(lin.data[3], 1.0);
    assert_eq!(lin.saturated, vec![0, 0b001]);
    assert!((saturated_share(&d.pixels) - 0.5).abs() < 1e-12);
}

#[test]
fn exposure_scales_are_relative_to_the_median_photo() {
    let files: Vec<String> = (0..4).map(|i| format!("{i}.jpg")).collect();
    let ExposureScales {
        scales, warning, ..
    } = exposure_scales(&[Some(1.0), Some(4.0), Some(2.0)], &files[..3]);
    assert_eq!(scales, [2.0, 0.5, 1.0]);
    assert_eq!(warning, None);
    // an even count: the lower middle photo keeps scale 1
    let s = exposure_scales(&[Some(1.0), Some(2.0), Some(4.0), Some(8.0)], &files);
    assert_eq!(s.scales, [2.0, 1.0, 0.5, 0.25]);
    // one photo without: nothing is scaled, and the warning names it
    let s = exposure_scales(&[Some(1.0), None, Some(4.0)], &files[..3]);
    assert_eq!(s.scales, [1.0, 1.0, 1.0]);
    assert!(s.warning.unwrap().contains("1.jpg"));
}

#[test]
fn flash_labels_from_exif_and_options() {
    let dir = tempfile::tempdir().unwrap();
    let mut paths = Vec::new();
    for (i, flash) in [Some(true), Some(false), None, None].iter().enumerate() {
        let tags = flash.map(|f| Tags::phone(f, 60, 100));
        paths.push(photo(dir.path(), &format!("IMG_{i}.jpg"), tags.as_ref()));
    }
    let photos = scan_photos(&paths).unwrap();
    // two photos have no tag: an error naming them and saying how to label
    let err = flash_labels(&photos, None, None).unwrap_err();
    assert!(matches!(err, ImportError::NoFlashInfo { count: 2, .. }));
    let msg = err.to_string();
    assert!(
        msg.contains("IMG_2.jpg") && msg.contains("IMG_3.jpg"),
        "{msg}"
    );
    assert!(
        msg.contains("--flash") && msg.contains("--no-flash"),
        "{msg}"
    );
    assert!(!msg.contains("IMG_0.jpg"), "{msg}");
    // labels by list and by glob; the options override EXIF
    let labels = flash_labels(&photos, Some("IMG_2.jpg"), Some("IMG_[03].jpg")).unwrap();
    assert_eq!(
        labels,
        [
            (false, FlashSource::NoFlashOption),
            (false, FlashSource::Exif),
            (true, FlashSource::FlashOption),
            (false, FlashSource::NoFlashOption),
        ]
    );
    let labels = flash_labels(&photos, Some("IMG_2.jpg, IMG_3.jpg"), None).unwrap();
    assert_eq!(labels.iter().filter(|l| l.0).count(), 3);
    // a pattern matching nothing, and a photo in both
    let err = flash_labels(&photos, Some("DSC_*.jpg"), None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("DSC_*.jpg") && err.contains("matches none"),
        "{err}"
    );
    let err = flash_labels(&photos, Some("*"), Some("IMG_1.jpg"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("IMG_1.jpg") && err.contains("also matched by --flash"),
        "{err}"
    );
}

#[test]
fn unreadable_and_truncated_photos_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let good = photo(dir.path(), "good.jpg", None);
    let garbage = dir.path().join("garbage.jpg");
    std::fs::write(&garbage, b"this is not a JPEG").unwrap();
    let truncated = dir.path().join("truncated.jpg");
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 3]).unwrap();
    let err = scan_photos(&[good, garbage, truncated]).unwrap_err();
    let msg = err.to_string();
    assert!(
        matches!(err, ImportError::BadPhotos { count: 2, .. }),
        "{msg}"
    );
    assert!(
        msg.contains("garbage.jpg") && msg.contains("truncated.jpg"),
        "{msg}"
    );
    assert!(!msg.contains("good.jpg"), "{msg}");
}
