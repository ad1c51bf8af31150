//! The summary of a dataset printed by `wildlight info` (issue 2): counts,
//! resolution, flash, saturation, masks, per-camera parameters, and the
//! warnings a user needs before training.

use serde::Serialize;

use crate::dataset::{Dataset, ImageSource};

/// Per-camera line of the summary.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CameraInfo {
    /// Image index.
    pub index: usize,
    /// Whether the flash is on.
    pub flash: bool,
    /// Flash RGB energy (normalized-frame units).
    pub light_energy: [f64; 3],
    /// Camera centre in the normalized frame.
    pub center_normalized: [f64; 3],
    /// Camera centre in world coordinates.
    pub center_world: [f64; 3],
    /// Focal length x (pixels).
    pub fx: f64,
    /// Focal length y (pixels).
    pub fy: f64,
    /// Principal point x (pixels; pixel centres at integers).
    pub cx: f64,
    /// Principal point y (pixels).
    pub cy: f64,
    /// Distance from the centre to the origin of the normalized frame.
    pub distance: f64,
    /// Fraction of the image covered by the mask (`null` without mask).
    pub mask_coverage: Option<f64>,
}

/// Smallest, mean and largest of a set of numbers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Range {
    /// Smallest value.
    pub min: f64,
    /// Mean value.
    pub mean: f64,
    /// Largest value.
    pub max: f64,
}

impl Range {
    /// The range of `values`; `None` when empty.
    pub fn of(values: &[f64]) -> Option<Range> {
        if values.is_empty() {
            return None;
        }
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Some(Range {
            min,
            mean: values.iter().sum::<f64>() / values.len() as f64,
            max,
        })
    }
}

/// Everything `wildlight info --json` prints.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DatasetInfo {
    /// The dataset folder.
    pub root: String,
    /// Number of (training) images.
    pub images: usize,
    /// Number of images with the flash on.
    pub flash_images: usize,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Image format (`exr`, `png`, `mixed`, `npy`).
    pub image_format: ImageSource,
    /// Whether any image has a mask.
    pub has_masks: bool,
    /// Number of images with a mask.
    pub masked_images: usize,
    /// Saturation cap (`null` = none).
    pub saturation: Option<f32>,
    /// Fraction of pixels that reach the saturation cap in some channel (0 without a cap).
    pub saturated_pixel_fraction: f64,
    /// Mask coverage over the masked images (fraction of the image).
    pub mask_coverage: Option<Range>,
    /// Distances from the camera centres to the origin, normalized frame.
    pub camera_distance: Option<Range>,
    /// The same distances in world units.
    pub camera_distance_world: Option<Range>,
    /// Number of images in the `val/` split (0 without one).
    pub val_images: usize,
    /// Number of `val/` images with the flash on.
    pub val_flash_images: usize,
    /// One entry per training camera.
    pub cameras: Vec<CameraInfo>,
    /// One entry per `val/` camera.
    pub val_cameras: Vec<CameraInfo>,
    /// Problems a user should know about before training.
    pub warnings: Vec<String>,
    /// How training will treat the capture, where it is not the usual way
    /// (no masks: the background is modelled).
    pub notes: Vec<String>,
}

fn camera_infos(data: &Dataset) -> Vec<CameraInfo> {
    data.views
        .iter()
        .map(|v| {
            let c = &v.camera;
            CameraInfo {
                index: c.index,
                flash: c.flash(),
                light_energy: c.light_energy,
                center_normalized: c.center.to_array(),
                center_world: c.center_world().to_array(),
                fx: c.fx(),
                fy: c.fy(),
                cx: c.cx(),
                cy: c.cy(),
                distance: c.center.length(),
                mask_coverage: v.mask.as_ref().map(|m| m.coverage()),
            }
        })
        .collect()
}

fn list(indices: &[usize]) -> String {
    let shown: Vec<String> = indices.iter().take(10).map(|i| i.to_string()).collect();
    let more = if indices.len() > 10 {
        format!(", ... ({} in all)", indices.len())
    } else {
        String::new()
    };
    format!("{}{more}", shown.join(", "))
}

fn saturated_fraction(data: &Dataset) -> f64 {
    let Some(cap) = data.saturation else {
        return 0.0;
    };
    let (mut saturated, mut total) = (0usize, 0usize);
    for v in &data.views {
        total += v.image.pixel_count();
        saturated += v
            .image
            .data
            .chunks_exact(3)
            .filter(|p| p.iter().any(|x| *x >= cap))
            .count();
    }
    if total == 0 {
        0.0
    } else {
        saturated as f64 / total as f64
    }
}

impl DatasetInfo {
    /// Summarizes a loaded dataset.
    pub fn from_dataset(data: &Dataset) -> DatasetInfo {
        let cameras = camera_infos(data);
        let val_cameras = data.val.as_deref().map(camera_infos).unwrap_or_default();
        let coverages: Vec<f64> = cameras.iter().filter_map(|c| c.mask_coverage).collect();
        let distances: Vec<f64> = cameras.iter().map(|c| c.distance).collect();
        let world_distances: Vec<f64> = data
            .views
            .iter()
            .map(|v| (v.camera.center_world() - v.camera.to_world(glam::DVec3::ZERO)).length())
            .collect();
        let mut warnings = Vec::new();
        let flash_images = data.flash_count();
        if flash_images == 0 {
            warnings.push(
                "no flash images (every light_energy is zero): reflectance cannot be separated from the room light"
                    .to_string(),
            );
        }
        let all_cameras = cameras
            .iter()
            .map(|c| (c, ""))
            .chain(val_cameras.iter().map(|c| (c, "val ")));
        let inside: Vec<String> = all_cameras
            .filter(|(c, _)| c.distance <= 1.0)
            .map(|(c, split)| format!("{split}{}", c.index))
            .collect();
        if !inside.is_empty() {
            warnings.push(format!(
                "cameras inside the unit sphere (the object region): {}; the normalization (scale_mat) is probably wrong",
                inside.join(", ")
            ));
        }
        let unmasked: Vec<usize> = cameras
            .iter()
            .filter(|c| c.mask_coverage.is_none())
            .map(|c| c.index)
            .collect();
        let mut notes = Vec::new();
        if unmasked.len() == cameras.len() {
            notes.push("no masks: training will model the background (SPEC §6)".to_string());
        } else if !unmasked.is_empty() {
            warnings.push(format!("images without masks: {}", list(&unmasked)));
        }
        let empty: Vec<usize> = cameras
            .iter()
            .filter(|c| c.mask_coverage == Some(0.0))
            .map(|c| c.index)
            .collect();
        if !empty.is_empty() {
            warnings.push(format!("empty masks (no object pixel): {}", list(&empty)));
        }
        let saturated_pixel_fraction = saturated_fraction(data);
        if saturated_pixel_fraction > 0.05 {
            warnings.push(format!(
                "{:.1}% of the pixels are saturated; they are left out of the colour loss",
                100.0 * saturated_pixel_fraction
            ));
        }
        DatasetInfo {
            root: data.root.display().to_string(),
            images: data.views.len(),
            flash_images,
            width: data.width(),
            height: data.height(),
            image_format: data.source,
            has_masks: data.has_masks(),
            masked_images: coverages.len(),
            saturation: data.saturation,
            saturated_pixel_fraction,
            mask_coverage: Range::of(&coverages),
            camera_distance: Range::of(&distances),
            camera_distance_world: Range::of(&world_distances),
            val_images: val_cameras.len(),
            val_flash_images: val_cameras.iter().filter(|c| c.flash).count(),
            cameras,
            val_cameras,
            warnings,
            notes,
        }
    }

    /// A short human-readable report (what `wildlight info` prints without `--json`).
    pub fn to_table(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let fmt_range = |r: &Option<Range>, pct: bool| match r {
            Some(r) if pct => format!(
                "{:.1}% .. {:.1}% (mean {:.1}%)",
                100.0 * r.min,
                100.0 * r.max,
                100.0 * r.mean
            ),
            Some(r) => format!("{:.4} .. {:.4}", r.min, r.max),
            None => "-".to_string(),
        };
        let _ = writeln!(s, "dataset     {}", self.root);
        let _ = writeln!(
            s,
            "images      {} ({} with flash), {}x{}, {}",
            self.images,
            self.flash_images,
            self.width,
            self.height,
            self.image_format.describe()
        );
        let sat = match self.saturation {
            Some(c) => format!(
                "{c} ({:.2}% of pixels reach it)",
                100.0 * self.saturated_pixel_fraction
            ),
            None => "none".to_string(),
        };
        let _ = writeln!(s, "saturation  {sat}");
        let _ = writeln!(
            s,
            "masks       {} of {} images, coverage {}",
            self.masked_images,
            self.images,
            fmt_range(&self.mask_coverage, true)
        );
        let _ = writeln!(
            s,
            "distance    camera to origin {} (normalized), {} (world)",
            fmt_range(&self.camera_distance, false),
            fmt_range(&self.camera_distance_world, false)
        );
        let _ = writeln!(
            s,
            "val         {} images ({} with flash)",
            self.val_images, self.val_flash_images
        );
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "{:>5} {:>5} {:>26} {:>29} {:>29} {:>9} {:>9} {:>8} {:>8} {:>6}",
            "index",
            "flash",
            "light_energy",
            "centre (normalized)",
            "centre (world)",
            "fx",
            "fy",
            "cx",
            "cy",
            "mask"
        );
        for (split, cams) in [("", &self.cameras), ("val ", &self.val_cameras)] {
            for c in cams.iter() {
                let v3 = |v: [f64; 3]| format!("{:9.4}{:10.4}{:10.4}", v[0], v[1], v[2]);
                let e = c.light_energy;
                let _ = writeln!(
                    s,
                    "{:>5} {:>5} {:>8.3} {:>8.3} {:>8.3} {:>29} {:>29} {:>9.3} {:>9.3} {:>8.3} {:>8.3} {:>6}",
                    format!("{split}{}", c.index),
                    if c.flash { "yes" } else { "no" },
                    e[0],
                    e[1],
                    e[2],
                    v3(c.center_normalized),
                    v3(c.center_world),
                    c.fx,
                    c.fy,
                    c.cx,
                    c.cy,
                    c.mask_coverage
                        .map_or("-".to_string(), |m| format!("{:.1}%", 100.0 * m)),
                );
            }
        }
        for n in &self.notes {
            let _ = writeln!(s, "\nnote: {n}");
        }
        if !self.warnings.is_empty() {
            let _ = writeln!(s, "\nwarnings:");
            for w in &self.warnings {
                let _ = writeln!(s, "  - {w}");
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_of_values() {
        let r = Range::of(&[3.0, 1.0, 2.0]).unwrap();
        assert_eq!((r.min, r.mean, r.max), (1.0, 2.0, 3.0));
        assert!(Range::of(&[]).is_none());
    }
}
