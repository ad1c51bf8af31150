//! The error type of the import. Every variant names the files or values it
//! concerns and says what to do, so that a user who sees only the message
//! can fix the input.

use std::path::PathBuf;

use wildlight_data::DataError;

/// Everything that can stop an import.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The photo folder does not exist.
    #[error("{path}: photo folder not found (or not a folder)")]
    MissingFolder {
        /// The folder asked for.
        path: PathBuf,
    },
    /// The photo folder holds no photo.
    #[error("{path}: no photos found (looked for .jpg, .jpeg, .png and .exr files)")]
    NoPhotos {
        /// The folder.
        path: PathBuf,
    },
    /// Photos that cannot be decoded (unreadable, truncated, not an image).
    #[error("cannot read {count} photo(s): {details}; remove or replace them")]
    BadPhotos {
        /// How many.
        count: usize,
        /// `file: reason` for each, separated by `; `.
        details: String,
    },
    /// Photos with no EXIF flash tag and no `--flash`/`--no-flash` label.
    #[error(
        "{count} photo(s) have no EXIF Flash tag and no label: {files}; say which photos had the \
         flash on with --flash and which had it off with --no-flash (a glob or a comma-separated \
         list of file names, e.g. --flash 'IMG_00*.jpg' --no-flash IMG_0101.jpg,IMG_0102.jpg)"
    )]
    NoFlashInfo {
        /// How many.
        count: usize,
        /// Their file names.
        files: String,
    },
    /// A `--flash`/`--no-flash` label that is wrong (matches nothing, or both).
    #[error("{option} {pattern}: {problem}")]
    BadLabel {
        /// `--flash` or `--no-flash`.
        option: &'static str,
        /// The pattern or list given.
        pattern: String,
        /// What is wrong.
        problem: String,
    },
    /// Photos of different sizes (COLMAP's single shared camera needs one).
    #[error(
        "the photos have different sizes: {sizes}; COLMAP's one shared camera needs one size \
         (after EXIF orientation): resize them to one size or import the groups separately"
    )]
    MixedSizes {
        /// `WxH: files` for each size.
        sizes: String,
    },
    /// No `colmap` executable.
    #[error(
        "COLMAP is not installed (no `colmap` on PATH): install it (Debian/Ubuntu: \
         `apt-get install colmap`), or pass --colmap SPARSE_DIR with a model made elsewhere"
    )]
    ColmapMissing,
    /// A COLMAP stage exited with an error.
    #[error("COLMAP {stage} failed ({status}); the end of its log {log}:\n{tail}")]
    ColmapFailed {
        /// The stage (`feature_extractor`, `mapper`, ...).
        stage: String,
        /// Exit status, in words.
        status: String,
        /// The log file.
        log: PathBuf,
        /// The last lines of the log.
        tail: String,
    },
    /// COLMAP made no model at all.
    #[error(
        "COLMAP could not reconstruct the scene from these photos (no model in {path}): too few \
         matches between them; take more photos with more overlap (every part seen from 3+ \
         photos, 10-20 degrees apart) and a textured background"
    )]
    NoModel {
        /// The sparse folder.
        path: PathBuf,
    },
    /// COLMAP registered too few photos.
    #[error(
        "COLMAP registered only {registered} of {total} photos (at least {needed} are needed); \
         not registered: {files}. Take more photos with more overlap between neighbours, keep \
         the object and a textured background in view, avoid blur"
    )]
    TooFewRegistered {
        /// Photos registered.
        registered: usize,
        /// Photos given.
        total: usize,
        /// The minimum.
        needed: usize,
        /// The photos left out.
        files: String,
    },
    /// A COLMAP model file that cannot be read.
    #[error("{path}: {message}")]
    Model {
        /// The file.
        path: PathBuf,
        /// What is wrong (with the line or byte offset).
        message: String,
    },
    /// The region of interest puts cameras inside the unit sphere.
    #[error(
        "the region of interest (centre {center}, radius {radius}) puts {count} camera(s) inside \
         the unit sphere: {cameras}; cameras must be outside it: choose a smaller --radius or \
         another --center"
    )]
    CamerasInside {
        /// The centre, in world units.
        center: String,
        /// The radius, in world units.
        radius: String,
        /// How many.
        count: usize,
        /// `file (distance d)` for each.
        cameras: String,
    },
    /// An option with an unusable value.
    #[error("{what}: {problem}")]
    InvalidArgument {
        /// The option.
        what: String,
        /// What is wrong.
        problem: String,
    },
    /// The output folder exists and is not an earlier import.
    #[error(
        "{path} exists and is not empty (and holds no import.json from an earlier import); \
         choose another --out or remove it"
    )]
    OutputExists {
        /// The folder.
        path: PathBuf,
    },
    /// An error of the capture format (writing images or cameras).
    #[error(transparent)]
    Data(#[from] DataError),
    /// An operating-system error.
    #[error("{path}: {action} failed: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// What was being done.
        action: &'static str,
        /// The error.
        #[source]
        source: std::io::Error,
    },
}

impl ImportError {
    /// An I/O error on `path` while doing `action`.
    pub fn io(path: impl Into<PathBuf>, action: &'static str, source: std::io::Error) -> Self {
        ImportError::Io {
            path: path.into(),
            action,
            source,
        }
    }
}

/// Joins at most `max` items with `, ` and says how many more there are.
pub fn list_some<S: AsRef<str>>(items: &[S], max: usize) -> String {
    let mut out: Vec<&str> = items.iter().take(max).map(AsRef::as_ref).collect();
    let more;
    if items.len() > max {
        more = format!("and {} more", items.len() - max);
        out.push(&more);
    }
    out.join(", ")
}
