//! Photos and their EXIF: listing a folder, reading the tags the import
//! needs (flash, exposure, focal length, orientation), decoding JPEG, PNG
//! (8 and 16 bit) and EXR, applying the EXIF orientation, and the flash
//! labels (EXIF bit 0, or `--flash`/`--no-flash` patterns).

use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use exif::{In, Tag, Value};
use rayon::prelude::*;

use crate::error::{ImportError, list_some};

/// The file formats the import reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PhotoFormat {
    /// JPEG, 8-bit sRGB.
    Jpeg,
    /// PNG, 8- or 16-bit sRGB.
    Png,
    /// OpenEXR, linear float (passed through).
    Exr,
}

impl PhotoFormat {
    /// The format of a file name, from its extension (case-insensitive).
    pub fn of(path: &Path) -> Option<PhotoFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "jpg" | "jpeg" => Some(PhotoFormat::Jpeg),
            "png" => Some(PhotoFormat::Png),
            "exr" => Some(PhotoFormat::Exr),
            _ => None,
        }
    }
}

/// The photos of `dir` (JPEG, PNG, EXR by extension), sorted by file name.
pub fn list_photos(dir: &Path) -> Result<Vec<PathBuf>, ImportError> {
    if !dir.is_dir() {
        return Err(ImportError::MissingFolder {
            path: dir.to_path_buf(),
        });
    }
    let entries = std::fs::read_dir(dir).map_err(|e| ImportError::io(dir, "listing", e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|e| ImportError::io(dir, "listing", e))?
            .path();
        if path.is_file() && PhotoFormat::of(&path).is_some() {
            files.push(path);
        }
    }
    files.sort();
    if files.is_empty() {
        return Err(ImportError::NoPhotos {
            path: dir.to_path_buf(),
        });
    }
    Ok(files)
}

/// The EXIF tags the import uses; `None` where the tag is missing.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ExifInfo {
    /// Flash (0x9209) as stored: bit 0 = fired.
    pub flash: Option<u32>,
    /// ExposureTime in seconds.
    pub exposure_time: Option<f64>,
    /// PhotographicSensitivity (ISO).
    pub iso: Option<f64>,
    /// FNumber.
    pub f_number: Option<f64>,
    /// FocalLength in mm.
    pub focal_length_mm: Option<f64>,
    /// FocalLengthIn35mmFilm in mm.
    pub focal_length_35mm: Option<f64>,
    /// Orientation 1..=8 (1 when missing).
    pub orientation: u16,
}

impl ExifInfo {
    /// Whether the flash fired (EXIF Flash bit 0), when the tag is there.
    pub fn flash_fired(&self) -> Option<bool> {
        self.flash.map(|f| f & 1 == 1)
    }

    /// The relative exposure t · ISO / N² (N = 1 when FNumber is missing:
    /// phones have a fixed aperture); `None` without ExposureTime or ISO.
    pub fn exposure(&self) -> Option<f64> {
        let t = self.exposure_time.filter(|t| *t > 0.0)?;
        let iso = self.iso.filter(|i| *i > 0.0)?;
        let n = self.f_number.filter(|n| *n > 0.0).unwrap_or(1.0);
        Some(t * iso / (n * n))
    }
}

fn rational(value: &Value) -> Option<f64> {
    let v = match value {
        Value::Rational(r) => r.first().map(|r| r.to_f64()),
        Value::SRational(r) => r.first().map(|r| r.to_f64()),
        Value::Float(f) => f.first().map(|f| *f as f64),
        Value::Double(d) => d.first().copied(),
        _ => value.get_uint(0).map(f64::from),
    }?;
    v.is_finite().then_some(v)
}

/// Extracts the tags from parsed EXIF data.
pub fn exif_info(exif: &exif::Exif) -> ExifInfo {
    let field = |tag| exif.get_field(tag, In::PRIMARY).map(|f| &f.value);
    let uint = |tag| field(tag).and_then(|v| v.get_uint(0));
    let real = |tag| field(tag).and_then(rational);
    ExifInfo {
        flash: uint(Tag::Flash),
        exposure_time: real(Tag::ExposureTime),
        iso: uint(Tag::PhotographicSensitivity).map(f64::from),
        f_number: real(Tag::FNumber),
        focal_length_mm: real(Tag::FocalLength),
        focal_length_35mm: real(Tag::FocalLengthIn35mmFilm).filter(|f| *f > 0.0),
        orientation: uint(Tag::Orientation)
            .filter(|o| (1..=8).contains(o))
            .map_or(1, |o| o as u16),
    }
}

/// Reads the EXIF of a JPEG or PNG file. A file without EXIF gives the
/// default (no tags, orientation 1); EXIF that cannot be parsed gives the
/// default too, with the reason as the second value (a warning).
pub fn read_exif(path: &Path) -> Result<(ExifInfo, Option<String>), ImportError> {
    if PhotoFormat::of(path) == Some(PhotoFormat::Exr) {
        return Ok((ExifInfo::default_oriented(), None));
    }
    let file = std::fs::File::open(path).map_err(|e| ImportError::io(path, "opening", e))?;
    match exif::Reader::new().read_from_container(&mut BufReader::new(file)) {
        Ok(exif) => Ok((exif_info(&exif), None)),
        Err(exif::Error::NotFound(_)) | Err(exif::Error::BlankValue(_)) => {
            Ok((ExifInfo::default_oriented(), None))
        }
        Err(e) => Ok((
            ExifInfo::default_oriented(),
            Some(format!("unreadable EXIF ({e}), read as none")),
        )),
    }
}

impl ExifInfo {
    /// No tags, orientation 1.
    pub fn default_oriented() -> ExifInfo {
        ExifInfo {
            orientation: 1,
            ..ExifInfo::default()
        }
    }
}

/// Decoded pixels of a photo, RGB interleaved, row-major.
#[derive(Clone, Debug, PartialEq)]
pub enum Pixels {
    /// 8-bit sRGB.
    Srgb8(Vec<u8>),
    /// 16-bit sRGB.
    Srgb16(Vec<u16>),
    /// Linear float (EXR).
    Linear(Vec<f32>),
}

/// A decoded, oriented photo.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    /// Width after orientation.
    pub width: u32,
    /// Height after orientation.
    pub height: u32,
    /// The pixels after orientation.
    pub pixels: Pixels,
}

fn bad(path: &Path, message: impl std::fmt::Display) -> ImportError {
    ImportError::BadPhotos {
        count: 1,
        details: format!("{}: {message}", path.display()),
    }
}

/// Decodes a photo and applies the EXIF `orientation` (1..=8).
pub fn decode(path: &Path, orientation: u16) -> Result<Decoded, ImportError> {
    let format = PhotoFormat::of(path).ok_or_else(|| bad(path, "not a JPEG, PNG or EXR file"))?;
    let (w, h, pixels) = match format {
        PhotoFormat::Exr => {
            let img = wildlight_data::exr_io::read_exr_rgb(path).map_err(|e| bad(path, e))?;
            img.check_finite(path).map_err(|e| bad(path, e))?;
            (img.width, img.height, Pixels::Linear(img.data))
        }
        PhotoFormat::Jpeg => {
            let (w, h, rgb) = decode_jpeg(path)?;
            (w, h, Pixels::Srgb8(rgb))
        }
        PhotoFormat::Png => {
            let reader = image::ImageReader::open(path)
                .map_err(|e| ImportError::io(path, "opening", e))?
                .with_guessed_format()
                .map_err(|e| ImportError::io(path, "reading", e))?;
            let img = reader.decode().map_err(|e| bad(path, e))?;
            let (w, h) = (img.width(), img.height());
            let pixels = match img {
                image::DynamicImage::ImageRgb16(_)
                | image::DynamicImage::ImageRgba16(_)
                | image::DynamicImage::ImageLuma16(_)
                | image::DynamicImage::ImageLumaA16(_) => {
                    Pixels::Srgb16(img.into_rgb16().into_raw())
                }
                image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_) => {
                    Pixels::Linear(img.into_rgb32f().into_raw())
                }
                _ => Pixels::Srgb8(img.into_rgb8().into_raw()),
            };
            (w, h, pixels)
        }
    };
    if w == 0 || h == 0 {
        return Err(bad(path, "the image is empty"));
    }
    Ok(orient(w, h, pixels, orientation))
}

/// Decodes a JPEG to 8-bit RGB in strict mode, so that a truncated or
/// corrupt file is an error rather than an image padded with grey.
fn decode_jpeg(path: &Path) -> Result<(u32, u32, Vec<u8>), ImportError> {
    use zune_jpeg::zune_core::bytestream::ZCursor;
    use zune_jpeg::zune_core::colorspace::ColorSpace;
    use zune_jpeg::zune_core::options::DecoderOptions;
    let bytes = std::fs::read(path).map_err(|e| ImportError::io(path, "reading", e))?;
    let options = DecoderOptions::default()
        .set_strict_mode(true)
        .set_max_width(1 << 16)
        .set_max_height(1 << 16)
        .jpeg_set_out_colorspace(ColorSpace::RGB);
    let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(&bytes[..]), options);
    let rgb = decoder
        .decode()
        .map_err(|e| bad(path, format!("not a readable JPEG ({e})")))?;
    let info = decoder
        .info()
        .ok_or_else(|| bad(path, "not a readable JPEG (no header)"))?;
    let (w, h) = (info.width as u32, info.height as u32);
    if rgb.len() != 3 * w as usize * h as usize {
        return Err(bad(
            path,
            format!("decoded {} values for a {w}x{h} RGB image", rgb.len()),
        ));
    }
    Ok((w, h, rgb))
}

/// The oriented size of a `w`×`h` image (orientations 5..=8 swap them).
pub fn oriented_size(w: u32, h: u32, orientation: u16) -> (u32, u32) {
    if (5..=8).contains(&orientation) {
        (h, w)
    } else {
        (w, h)
    }
}

/// The source pixel (column, row) of the displayed pixel (`ox`, `oy`) of a
/// `w`×`h` image stored with EXIF `orientation`.
pub fn oriented_source(ox: u32, oy: u32, w: u32, h: u32, orientation: u16) -> (u32, u32) {
    match orientation {
        2 => (w - 1 - ox, oy),
        3 => (w - 1 - ox, h - 1 - oy),
        4 => (ox, h - 1 - oy),
        5 => (oy, ox),
        6 => (oy, h - 1 - ox),
        7 => (w - 1 - oy, h - 1 - ox),
        8 => (w - 1 - oy, ox),
        _ => (ox, oy),
    }
}

fn orient_vec<T: Copy + Send + Sync>(w: u32, h: u32, data: Vec<T>, orientation: u16) -> Vec<T> {
    if !(2..=8).contains(&orientation) {
        return data;
    }
    let (ow, oh) = oriented_size(w, h, orientation);
    let mut out = Vec::with_capacity(data.len());
    for oy in 0..oh {
        for ox in 0..ow {
            let (sx, sy) = oriented_source(ox, oy, w, h, orientation);
            let s = 3 * (sy as usize * w as usize + sx as usize);
            out.extend_from_slice(&data[s..s + 3]);
        }
    }
    out
}

/// Applies the EXIF `orientation` to `w`×`h` pixels.
pub fn orient(w: u32, h: u32, pixels: Pixels, orientation: u16) -> Decoded {
    let (width, height) = oriented_size(w, h, orientation);
    let pixels = match pixels {
        Pixels::Srgb8(d) => Pixels::Srgb8(orient_vec(w, h, d, orientation)),
        Pixels::Srgb16(d) => Pixels::Srgb16(orient_vec(w, h, d, orientation)),
        Pixels::Linear(d) => Pixels::Linear(orient_vec(w, h, d, orientation)),
    };
    Decoded {
        width,
        height,
        pixels,
    }
}

/// What the import knows about one photo before COLMAP runs.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotoInfo {
    /// The file.
    pub path: PathBuf,
    /// Its file name.
    pub file: String,
    /// Its format.
    pub format: PhotoFormat,
    /// Its EXIF tags.
    pub exif: ExifInfo,
    /// Width after orientation.
    pub width: u32,
    /// Height after orientation.
    pub height: u32,
    /// Share of pixels with a channel at a top code value (≥ 250/255).
    pub saturated_share: f64,
    /// A problem that does not stop the import (unreadable EXIF).
    pub warning: Option<String>,
}

/// File name of `path` as a string.
pub fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Reads the EXIF of every photo and decodes it once (to find unreadable
/// or truncated files before COLMAP runs), in parallel. Every unreadable
/// photo is named in one error.
pub fn scan_photos(paths: &[PathBuf]) -> Result<Vec<PhotoInfo>, ImportError> {
    let results: Vec<Result<PhotoInfo, ImportError>> = paths
        .par_iter()
        .map(|path| {
            let (exif, warning) = read_exif(path)?;
            let decoded = decode(path, exif.orientation)?;
            Ok(PhotoInfo {
                path: path.clone(),
                file: file_name(path),
                format: PhotoFormat::of(path).unwrap_or(PhotoFormat::Jpeg),
                exif,
                width: decoded.width,
                height: decoded.height,
                saturated_share: crate::linear::saturated_share(&decoded.pixels),
                warning,
            })
        })
        .collect();
    let mut infos = Vec::new();
    let mut failures = Vec::new();
    for r in results {
        match r {
            Ok(info) => infos.push(info),
            Err(ImportError::BadPhotos { details, .. }) => failures.push(details),
            Err(e) => failures.push(e.to_string()),
        }
    }
    if !failures.is_empty() {
        return Err(ImportError::BadPhotos {
            count: failures.len(),
            details: failures.join("; "),
        });
    }
    Ok(infos)
}

/// Checks that all photos have one size (after orientation).
pub fn check_sizes(photos: &[PhotoInfo]) -> Result<(u32, u32), ImportError> {
    let mut by_size: BTreeMap<(u32, u32), Vec<&str>> = BTreeMap::new();
    for p in photos {
        by_size
            .entry((p.width, p.height))
            .or_default()
            .push(&p.file);
    }
    if by_size.len() > 1 {
        let sizes: Vec<String> = by_size
            .iter()
            .map(|((w, h), files)| {
                format!("{w}x{h} ({} photos: {})", files.len(), list_some(files, 6))
            })
            .collect();
        return Err(ImportError::MixedSizes {
            sizes: sizes.join("; "),
        });
    }
    Ok(by_size.keys().next().copied().unwrap_or((0, 0)))
}

/// Whether `name` matches the glob `pattern` (`*` any run, `?` one
/// character, `[abc]`/`[a-z]` a class; everything else literal).
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let n: Vec<char> = name.chars().collect();
    glob_at(&p, &n)
}

fn glob_at(p: &[char], n: &[char]) -> bool {
    match p.first() {
        None => n.is_empty(),
        Some('*') => (0..=n.len()).any(|k| glob_at(&p[1..], &n[k..])),
        Some('?') => !n.is_empty() && glob_at(&p[1..], &n[1..]),
        Some('[') => {
            let Some(close) = p.iter().skip(2).position(|c| *c == ']').map(|i| i + 2) else {
                return n.first() == Some(&'[') && glob_at(&p[1..], &n[1..]);
            };
            let Some(c) = n.first() else { return false };
            let class = &p[1..close];
            let (negate, class) = match class.first() {
                Some('!') | Some('^') => (true, &class[1..]),
                _ => (false, class),
            };
            let mut hit = false;
            let mut i = 0;
            while i < class.len() {
                if i + 2 < class.len() && class[i + 1] == '-' {
                    hit |= class[i] <= *c && *c <= class[i + 2];
                    i += 3;
                } else {
                    hit |= class[i] == *c;
                    i += 1;
                }
            }
            hit != negate && glob_at(&p[close + 1..], &n[1..])
        }
        Some(c) => n.first() == Some(c) && glob_at(&p[1..], &n[1..]),
    }
}

/// Where a photo's flash label came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FlashSource {
    /// EXIF Flash bit 0.
    Exif,
    /// `--flash`.
    FlashOption,
    /// `--no-flash`.
    NoFlashOption,
}

/// The photos a `--flash`/`--no-flash` value names: a comma-separated list
/// of globs or file names. Each item must match at least one photo.
pub fn match_labels(
    option: &'static str,
    value: &str,
    files: &[String],
) -> Result<Vec<bool>, ImportError> {
    let mut hits = vec![false; files.len()];
    for item in value.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let mut any = false;
        for (hit, file) in hits.iter_mut().zip(files) {
            if glob_match(item, file) {
                *hit = true;
                any = true;
            }
        }
        if !any {
            return Err(ImportError::BadLabel {
                option,
                pattern: value.to_string(),
                problem: format!(
                    "`{item}` matches none of the photos (they are {})",
                    list_some(files, 5)
                ),
            });
        }
    }
    Ok(hits)
}

/// Flash on/off for every photo: the `--flash`/`--no-flash` labels first,
/// then EXIF Flash bit 0. A photo matched by both options, or with neither
/// a label nor the EXIF tag, is an error naming the files.
pub fn flash_labels(
    photos: &[PhotoInfo],
    flash: Option<&str>,
    no_flash: Option<&str>,
) -> Result<Vec<(bool, FlashSource)>, ImportError> {
    let files: Vec<String> = photos.iter().map(|p| p.file.clone()).collect();
    let on = match flash {
        Some(v) => match_labels("--flash", v, &files)?,
        None => vec![false; files.len()],
    };
    let off = match no_flash {
        Some(v) => match_labels("--no-flash", v, &files)?,
        None => vec![false; files.len()],
    };
    let both: Vec<&str> = files
        .iter()
        .zip(on.iter().zip(&off))
        .filter(|(_, (a, b))| **a && **b)
        .map(|(f, _)| f.as_str())
        .collect();
    if !both.is_empty() {
        return Err(ImportError::BadLabel {
            option: "--no-flash",
            pattern: no_flash.unwrap_or_default().to_string(),
            problem: format!(
                "also matched by --flash: {} (a photo is either flash or no-flash)",
                list_some(&both, 8)
            ),
        });
    }
    let mut missing = Vec::new();
    let labels: Vec<(bool, FlashSource)> = photos
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if on[i] {
                (true, FlashSource::FlashOption)
            } else if off[i] {
                (false, FlashSource::NoFlashOption)
            } else if let Some(f) = p.exif.flash_fired() {
                (f, FlashSource::Exif)
            } else {
                missing.push(p.file.as_str());
                (false, FlashSource::Exif)
            }
        })
        .collect();
    if !missing.is_empty() {
        return Err(ImportError::NoFlashInfo {
            count: missing.len(),
            files: list_some(&missing, 12),
        });
    }
    Ok(labels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn globs() {
        assert!(glob_match("IMG_00*.jpg", "IMG_0012.jpg"));
        assert!(!glob_match("IMG_00*.jpg", "IMG_0112.jpg"));
        assert!(glob_match("IMG_001?.jpg", "IMG_0019.jpg"));
        assert!(glob_match("IMG_00[1-2]?.jpg", "IMG_0021.jpg"));
        assert!(!glob_match("IMG_00[!1-2]?.jpg", "IMG_0021.jpg"));
        assert!(glob_match("*", "a.png"));
        assert!(glob_match("a.png", "a.png"));
        assert!(!glob_match("a.png", "ba.png"));
    }

    #[test]
    fn orientation_maps_corners() {
        // A 3x2 image; the displayed top-left pixel comes from these corners.
        let (w, h) = (3, 2);
        let top_left: Vec<(u32, u32)> = (1..=8).map(|o| oriented_source(0, 0, w, h, o)).collect();
        assert_eq!(
            top_left,
            [
                (0, 0),
                (2, 0),
                (2, 1),
                (0, 1),
                (0, 0),
                (0, 1),
                (2, 1),
                (2, 0)
            ]
        );
        // Orientation 6 (rotate 90° clockwise for display): the stored left
        // column becomes the top row, read bottom to top.
        let d = orient(w, h, Pixels::Srgb8((0..18).map(|v| v as u8).collect()), 6);
        assert_eq!((d.width, d.height), (2, 3));
        let Pixels::Srgb8(p) = d.pixels else { panic!() };
        // stored pixel (x, y) has value 3 * (3y + x)
        let px = |x: usize, y: usize| p[3 * (y * 2 + x)];
        assert_eq!(px(0, 0), 9); // stored (0, 1)
        assert_eq!(px(1, 0), 0); // stored (0, 0)
        assert_eq!(px(0, 2), 15); // stored (2, 1)
    }
}
