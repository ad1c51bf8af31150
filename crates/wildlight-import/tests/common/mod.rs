//! Test helpers: JPEG photos with hand-built EXIF (the image crate's
//! encoder plus an APP1 segment from kamadak-exif's writer) and synthetic
//! COLMAP models.
#![allow(dead_code)]

use std::path::Path;

use exif::experimental::Writer;
use exif::{Field, In, Rational, Tag, Value};
use glam::{DMat3, DQuat, DVec3};
use wildlight_import::colmap::{CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint};

/// The EXIF tags of a test photo.
#[derive(Clone, Debug, Default)]
pub struct Tags {
    pub flash: Option<u16>,
    /// ExposureTime as num/denom seconds.
    pub exposure: Option<(u32, u32)>,
    pub iso: Option<u16>,
    /// FNumber as num/denom.
    pub f_number: Option<(u32, u32)>,
    pub focal_mm: Option<(u32, u32)>,
    pub focal_35mm: Option<u16>,
    pub orientation: Option<u16>,
}

impl Tags {
    /// A phone photo: flash on or off, exposure 1/`denom` s at `iso`, f/1.8.
    pub fn phone(flash: bool, denom: u32, iso: u16) -> Tags {
        Tags {
            flash: Some(if flash { 0x19 } else { 0x10 }),
            exposure: Some((1, denom)),
            iso: Some(iso),
            f_number: Some((18, 10)),
            focal_mm: Some((47, 10)),
            focal_35mm: Some(26),
            orientation: Some(1),
        }
    }
}

/// The TIFF block of EXIF holding `tags`.
pub fn exif_tiff(tags: &Tags) -> Vec<u8> {
    let mut fields = Vec::new();
    let field = |tag, value| Field {
        tag,
        ifd_num: In::PRIMARY,
        value,
    };
    let rational = |(num, denom): (u32, u32)| Value::Rational(vec![Rational { num, denom }]);
    if let Some(o) = tags.orientation {
        fields.push(field(Tag::Orientation, Value::Short(vec![o])));
    }
    if let Some(f) = tags.flash {
        fields.push(field(Tag::Flash, Value::Short(vec![f])));
    }
    if let Some(e) = tags.exposure {
        fields.push(field(Tag::ExposureTime, rational(e)));
    }
    if let Some(i) = tags.iso {
        fields.push(field(Tag::PhotographicSensitivity, Value::Short(vec![i])));
    }
    if let Some(n) = tags.f_number {
        fields.push(field(Tag::FNumber, rational(n)));
    }
    if let Some(f) = tags.focal_mm {
        fields.push(field(Tag::FocalLength, rational(f)));
    }
    if let Some(f) = tags.focal_35mm {
        fields.push(field(Tag::FocalLengthIn35mmFilm, Value::Short(vec![f])));
    }
    let mut writer = Writer::new();
    for f in &fields {
        writer.push_field(f);
    }
    let mut buf = std::io::Cursor::new(Vec::new());
    writer.write(&mut buf, false).expect("EXIF encodes");
    buf.into_inner()
}

/// JPEG bytes of `img` (quality 95) with an APP1 Exif segment right after SOI.
pub fn jpeg_with_exif(img: &image::RgbImage, tags: Option<&Tags>) -> Vec<u8> {
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
        .encode_image(img)
        .expect("JPEG encodes");
    let Some(tags) = tags else { return jpeg };
    let tiff = exif_tiff(tags);
    let len = (2 + 6 + tiff.len()) as u16;
    let mut out = jpeg[..2].to_vec(); // SOI
    out.extend([0xFF, 0xE1]);
    out.extend(len.to_be_bytes());
    out.extend(b"Exif\0\0");
    out.extend(tiff);
    out.extend(&jpeg[2..]);
    out
}

/// Writes a JPEG with EXIF.
pub fn write_jpeg(path: &Path, img: &image::RgbImage, tags: Option<&Tags>) {
    std::fs::write(path, jpeg_with_exif(img, tags)).unwrap();
}

/// A smooth test picture whose pixels differ between photos.
pub fn picture(w: u32, h: u32, seed: u32) -> image::RgbImage {
    image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([
            (40 + (x * 3 + seed * 7) % 160) as u8,
            (60 + (y * 5 + seed * 3) % 120) as u8,
            (90 + ((x + y) * 2 + seed) % 100) as u8,
        ])
    })
}

/// World → camera rotation of a camera at `eye` looking at `target`
/// (OpenCV axes, world y up in the image).
pub fn look_at(eye: DVec3, target: DVec3) -> DMat3 {
    wildlight_data::camera::look_at_w2c(eye, target, DVec3::Y).unwrap()
}

/// (w, x, y, z) of a rotation.
pub fn qvec(r: DMat3) -> [f64; 4] {
    let q = DQuat::from_mat3(&r);
    [q.w, q.x, q.y, q.z]
}

/// A model of `n` cameras on a ring of radius `ring` around `center`,
/// looking at it, one shared camera `camera`, and points on a small
/// sphere around the centre; image names `IMG_<k>.jpg`.
pub fn ring_model(n: usize, ring: f64, center: DVec3, camera: ColmapCamera) -> ColmapModel {
    let mut model = ColmapModel::default();
    model.cameras.insert(camera.id, camera.clone());
    for k in 0..n {
        let a = k as f64 / n as f64 * std::f64::consts::TAU;
        let eye = center + DVec3::new(ring * a.cos(), 0.4 * ring, ring * a.sin());
        let r = look_at(eye, center);
        let t = -(r * eye);
        model.images.insert(
            k as u32 + 1,
            ColmapImage {
                id: k as u32 + 1,
                qvec: qvec(r),
                tvec: t.to_array(),
                camera_id: camera.id,
                name: format!("IMG_{k:04}.jpg"),
                points2d: Vec::new(),
            },
        );
    }
    for j in 0..200u64 {
        let u = (j as f64 * 0.618_034).fract() * std::f64::consts::TAU;
        let v = (j as f64 * 0.414_214).fract() * 2.0 - 1.0;
        let s = (1.0 - v * v).sqrt();
        let p = center + 0.3 * ring * DVec3::new(s * u.cos(), v, s * u.sin());
        model.points.push(ColmapPoint {
            id: j + 1,
            xyz: p,
            rgb: [128, 128, 128],
            error: 0.5,
            track: vec![(1, 0), (2, 0), (3, 0)],
        });
    }
    model
}

/// A SIMPLE_RADIAL camera.
pub fn simple_radial(w: u32, h: u32, f: f64, k: f64) -> ColmapCamera {
    ColmapCamera {
        id: 1,
        model: CameraModel::SimpleRadial,
        width: w,
        height: h,
        params: vec![f, w as f64 / 2.0, h as f64 / 2.0, k],
    }
}

/// Names of the entries of `dir` (for checking nothing is left behind).
pub fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}
