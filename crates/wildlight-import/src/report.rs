//! The import report: `CAPTURE/import.json` (one entry per input photo,
//! the registered count, reprojection error, flash split, saturation, the
//! region of interest, warnings) and the table `wildlight import` prints.

use crate::colmap::ColmapSettings;
use crate::photos::FlashSource;

/// One input photo.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PhotoReport {
    /// File name in the photo folder.
    pub file: String,
    /// Camera index in `cameras_sphere.npz` and `image/NNN.exr`; `None` when dropped.
    pub index: Option<usize>,
    /// Flash on.
    pub flash: bool,
    /// Where the flash label came from.
    pub flash_source: FlashSource,
    /// The factor the linear photo was multiplied by (median exposure / its exposure).
    pub exposure_scale: f64,
    /// Relative exposure t · ISO / N² from EXIF, when known.
    pub exposure: Option<f64>,
    /// EXIF orientation (1 = as stored).
    pub orientation: u16,
    /// Share of pixels with a channel at a top code value (≥ 250/255).
    pub saturated_share: f64,
    /// Its saturation cap `max_intensity_i` (none for EXR photos).
    pub max_intensity: Option<f64>,
    /// Why the photo is not in the capture, or `None`.
    pub dropped: Option<String>,
}

/// The region of interest.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RoiReport {
    /// Centre in world (COLMAP model) units.
    pub center: [f64; 3],
    /// Radius in world units.
    pub radius: f64,
    /// `auto` or `override`.
    pub source: String,
    /// The point nearest to the optical axes (auto only).
    pub axes_point: Option<[f64; 3]>,
    /// Sparse points that refined it (auto only).
    pub points_used: usize,
    /// Sparse points inside the sphere.
    pub points_inside: usize,
    /// The nearest camera's distance from the centre, in radii.
    pub nearest_camera: f64,
}

/// Where the poses came from.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ColmapReport {
    /// Whether COLMAP was run (false: `--colmap` model).
    pub ran: bool,
    /// The model used (its folder at import time).
    pub model: String,
    /// How many models the mapper made.
    pub models: usize,
    /// The camera model of the photos.
    pub camera_model: String,
    /// The settings, when COLMAP was run.
    pub settings: Option<ColmapSettings>,
    /// Seconds per COLMAP stage.
    pub seconds: Vec<(String, f64)>,
}

/// Everything the import did, written to `CAPTURE/import.json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ImportReport {
    /// The photo folder.
    pub photos_dir: String,
    /// The capture folder.
    pub capture: String,
    /// Every input photo, sorted by file name.
    pub photos: Vec<PhotoReport>,
    /// Number of input photos.
    pub photo_count: usize,
    /// Photos in the capture (registered by COLMAP).
    pub registered: usize,
    /// Flash photos in the capture.
    pub flash_count: usize,
    /// No-flash photos in the capture.
    pub no_flash_count: usize,
    /// Mean reprojection error of the sparse points, in pixels.
    pub mean_reprojection_error_px: f64,
    /// Sparse points in the model.
    pub sparse_points: usize,
    /// Share of saturated pixels over the capture's photos.
    pub saturation_share: f64,
    /// Photo size (after EXIF orientation).
    pub photo_size: [u32; 2],
    /// Size of the capture's images.
    pub image_size: [u32; 2],
    /// The region of interest.
    pub roi: RoiReport,
    /// The flash photos' `light_energy_i` (grey), normalized-frame units.
    pub light_energy: f64,
    /// How it was chosen.
    pub light_energy_note: String,
    /// The global `max_intensity` (the lowest per-image cap).
    pub max_intensity: Option<f64>,
    /// Where the poses came from.
    pub colmap: ColmapReport,
    /// Wall time of the import, in seconds.
    pub seconds: f64,
    /// Problems that did not stop the import.
    pub warnings: Vec<String>,
}

impl ImportReport {
    /// The printed summary: one row per photo, then the totals and warnings.
    pub fn to_table(&self) -> String {
        let mut s = String::new();
        let width = self
            .photos
            .iter()
            .map(|p| p.file.chars().count())
            .max()
            .unwrap_or(4)
            .max(4);
        s += &format!(
            "{:<width$}  {:>5}  {:<8}  {:>8}  {:>6}  status\n",
            "file", "index", "flash", "exposure", "sat %"
        );
        for p in &self.photos {
            let index = p.index.map_or("-".to_string(), |i| i.to_string());
            let flash = match (p.flash, p.flash_source) {
                (true, FlashSource::Exif) => "on",
                (false, FlashSource::Exif) => "off",
                (true, _) => "on (opt)",
                (false, _) => "off (opt)",
            };
            let status = p.dropped.as_deref().unwrap_or("ok");
            s += &format!(
                "{:<width$}  {:>5}  {:<8}  {:>8.3}  {:>6.2}  {}\n",
                p.file,
                index,
                flash,
                p.exposure_scale,
                100.0 * p.saturated_share,
                status
            );
        }
        s += &format!(
            "\nregistered      {} of {} photos ({} flash, {} no flash)\n",
            self.registered, self.photo_count, self.flash_count, self.no_flash_count
        );
        s += &format!(
            "reprojection    {:.3} px mean over {} sparse points\n",
            self.mean_reprojection_error_px, self.sparse_points
        );
        s += &format!(
            "images          {}x{} (photos {}x{})\n",
            self.image_size[0], self.image_size[1], self.photo_size[0], self.photo_size[1]
        );
        s += &format!(
            "saturated       {:.2} % of pixels\n",
            100.0 * self.saturation_share
        );
        let c = self.roi.center;
        s += &format!(
            "region          centre ({:.4}, {:.4}, {:.4}), radius {:.4} ({}); nearest camera at {:.2} radii\n",
            c[0], c[1], c[2], self.roi.radius, self.roi.source, self.roi.nearest_camera
        );
        s += &format!(
            "flash energy    {:.4} (normalized units; {})\n",
            self.light_energy, self.light_energy_note
        );
        s += &format!("time            {:.0} s\n", self.seconds);
        for w in &self.warnings {
            s += &format!("warning: {w}\n");
        }
        s
    }
}
