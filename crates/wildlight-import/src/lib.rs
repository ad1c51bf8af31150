//! Photos → a posed capture (`wildlight import`, issue 50).
//!
//! A folder of phone photos (JPEG, PNG 8/16-bit, or linear EXR) becomes a
//! capture in the SPEC §5 layout that `info`, `train` and `eval` read:
//!
//! ```text
//! CAPTURE/cameras_sphere.npz   world_mat_i, scale_mat_i, light_energy_i,
//!                              max_intensity_i (per image), max_intensity
//! CAPTURE/image/NNN.exr        linear float RGB, undistorted, exposure-normalized
//! CAPTURE/import.json          the report (one entry per input photo, ...)
//! CAPTURE/roi.png              a few images with the region of interest drawn on
//! CAPTURE/colmap/sparse/       the COLMAP model the poses came from (text)
//! ```
//!
//! No masks are written (SPEC §6: captures without masks).
//!
//! ## The steps (one module each)
//!
//! 1. [`photos`]: list and decode the photos, read EXIF (Flash bit 0,
//!    ExposureTime, ISO, FNumber, focal lengths, Orientation), apply the
//!    orientation, check that all have one size, label flash / no flash
//!    (EXIF, or `--flash`/`--no-flash` globs or lists).
//! 2. [`linear`]: sRGB → linear, divide by the relative exposure, mark the
//!    saturated channels.
//! 3. [`colmap::runner`]: COLMAP 3.8 on the CPU (features, exhaustive
//!    matching, mapping, undistortion to PINHOLE); or `--colmap SPARSE_DIR`.
//! 4. [`colmap::model`]: read the model, text or binary.
//! 5. [`roi`]: the region of interest (the unit sphere), automatically or
//!    from `--center`/`--radius`.
//! 6. [`resample`] and [`import`]: undistort and resize each photo in
//!    linear light, write the images and the cameras.
//! 7. [`report`], [`preview`]: `import.json`, the printed table, `roi.png`.
//!
//! ## The per-image saturation cap `max_intensity_i`
//!
//! Exposure scaling gives every photo its own clip level, so one global
//! `max_intensity` cannot mark the saturated pixels of all of them. The
//! import writes, for each image i, `max_intensity_i` = the linear value
//! of code 250/255 times the photo's exposure scale; saturated channels
//! (code ≥ 250) are raised to the photo's clip level, which is above it.
//! The key is optional: `wildlight_data` reads it as
//! [`wildlight_data::View::saturation`] (falling back to the global cap),
//! and captures without it read as before. The global `max_intensity` is
//! the lowest per-image cap, so a reader that knows only the global cap
//! still leaves every saturated pixel out (and some bright unsaturated
//! ones with it).
//!
//! ## Conventions
//!
//! COLMAP poses are world → camera (qw qx qy qz, t), centre −Rᵀt, pixel
//! centres at +0.5; SPEC §5 puts pixel centres at integer coordinates, so
//! `cx_spec = cx_colmap − 0.5`. `world_mat = K [R | t]` in world (COLMAP)
//! units; `scale_mat` maps the normalized frame to the world
//! (x_world = centre + radius · x_normalized).
//!
//! Nothing half-written is ever left in `--out`: everything is written to
//! a hidden sibling folder, which is renamed onto `--out` at the end.

#![warn(missing_docs)]

pub mod align;
pub mod colmap;
pub mod error;
pub mod import;
pub mod linear;
pub mod photos;
pub mod preview;
pub mod report;
pub mod resample;
pub mod roi;

pub use error::ImportError;
pub use import::{ImportOptions, import};
pub use report::ImportReport;
pub use roi::Roi;
