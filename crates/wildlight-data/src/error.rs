//! The error type of every fallible operation in this crate.
//!
//! Each variant names the file it concerns (and, where there is one, the
//! npz key or the pixel) and says what is wrong with it, so that a user who
//! sees only the message can fix the input.

use std::path::PathBuf;

/// Everything that can go wrong while reading or writing a dataset.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// The dataset folder does not exist or is not a folder.
    #[error("{path}: dataset folder not found (or not a folder)")]
    MissingFolder {
        /// The folder that was asked for.
        path: PathBuf,
    },
    /// A required file does not exist.
    #[error("{path}: file not found ({what})")]
    MissingFile {
        /// The file that was expected.
        path: PathBuf,
        /// What the file is for.
        what: String,
    },
    /// An operating-system error while reading or writing a file.
    #[error("{path}: {action} failed: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What was being done ("reading", "writing", "renaming", ...).
        action: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The npz file could not be opened or one of its arrays could not be decoded.
    #[error("{path}: cannot read npz{}: {message}", key_suffix(key))]
    Npz {
        /// The npz file.
        path: PathBuf,
        /// The array concerned, if any.
        key: Option<String>,
        /// What went wrong.
        message: String,
    },
    /// The npz file holds no `world_mat_<i>` array at all.
    #[error("{path}: no world_mat_<i> array found (keys present: {keys})")]
    NoCameras {
        /// The npz file.
        path: PathBuf,
        /// The keys that are present, comma separated.
        keys: String,
    },
    /// A camera array is missing for one image index.
    #[error("{path}: key {key} is missing (needed for camera {index})")]
    MissingKey {
        /// The npz file.
        path: PathBuf,
        /// The missing key.
        key: String,
        /// The camera index it belongs to.
        index: usize,
    },
    /// An array has a shape other than the one its key requires.
    #[error("{path}: key {key} has shape {found:?}, expected {expected}")]
    BadShape {
        /// The npz file.
        path: PathBuf,
        /// The array concerned.
        key: String,
        /// The shape found in the file.
        found: Vec<usize>,
        /// The shapes that would be accepted, in words.
        expected: &'static str,
    },
    /// A matrix or vector holds NaN, infinite, or otherwise unusable values.
    #[error("{path}: key {key}: {problem}")]
    BadValue {
        /// The npz file.
        path: PathBuf,
        /// The array concerned.
        key: String,
        /// What is wrong with its values.
        problem: String,
    },
    /// The projection P = world_mat · scale_mat of a camera cannot be decomposed.
    #[error(
        "{path}: camera {index} (world_mat_{index} · scale_mat_{index}): singular projection: {problem}"
    )]
    SingularProjection {
        /// The npz file.
        path: PathBuf,
        /// The camera index.
        index: usize,
        /// Why the decomposition failed.
        problem: String,
    },
    /// The image files do not match the camera indices of the npz.
    #[error("{folder}: files do not match the cameras of {npz}: {problem}")]
    IndexMismatch {
        /// The image (or mask) folder.
        folder: PathBuf,
        /// The npz file the cameras came from.
        npz: PathBuf,
        /// Which indices are missing or extra.
        problem: String,
    },
    /// The folder of images exists but holds no usable image.
    #[error("{path}: no images found (expected image/NNN.exr, image/NNN.png or images.npy)")]
    NoImages {
        /// The dataset folder.
        path: PathBuf,
    },
    /// Two images of one dataset have different sizes.
    #[error(
        "{path}: image is {found_width}x{found_height}, but {first} is {width}x{height}; all images must have one size"
    )]
    ImageSizeMismatch {
        /// The image that differs.
        path: PathBuf,
        /// Its width.
        found_width: u32,
        /// Its height.
        found_height: u32,
        /// The first image of the dataset.
        first: PathBuf,
        /// The width of the first image.
        width: u32,
        /// The height of the first image.
        height: u32,
    },
    /// A mask does not have the size of its image.
    #[error("{path}: mask is {found_width}x{found_height}, but its image is {width}x{height}")]
    MaskSizeMismatch {
        /// The mask file.
        path: PathBuf,
        /// The mask's width.
        found_width: u32,
        /// The mask's height.
        found_height: u32,
        /// The image's width.
        width: u32,
        /// The image's height.
        height: u32,
    },
    /// An image holds a NaN or infinite pixel value.
    #[error(
        "{path}: pixel (x={x}, y={y}) channel {channel} is {value} (NaN or infinite values are not allowed)"
    )]
    NonFinitePixel {
        /// The image file.
        path: PathBuf,
        /// Pixel column.
        x: u32,
        /// Pixel row.
        y: u32,
        /// Channel index (0 = R).
        channel: usize,
        /// The offending value.
        value: f32,
    },
    /// An image file could not be decoded.
    #[error("{path}: unreadable {format} image: {message}")]
    BadImage {
        /// The image file.
        path: PathBuf,
        /// "EXR", "PNG" or "npy".
        format: &'static str,
        /// What the decoder said.
        message: String,
    },
    /// An image could not be encoded or written.
    #[error("{path}: cannot write {format} image: {message}")]
    WriteImage {
        /// The file being written.
        path: PathBuf,
        /// "EXR" or "PNG".
        format: &'static str,
        /// What the encoder said.
        message: String,
    },
    /// A value handed to a writer or constructor is unusable.
    #[error("{what}: {problem}")]
    InvalidArgument {
        /// What was being built or written.
        what: String,
        /// Why it is unusable.
        problem: String,
    },
}

fn key_suffix(key: &Option<String>) -> String {
    match key {
        Some(k) => format!(" (key {k})"),
        None => String::new(),
    }
}

impl DataError {
    /// Builds an [`DataError::Io`] for `path`.
    pub(crate) fn io(
        path: impl Into<PathBuf>,
        action: &'static str,
        source: std::io::Error,
    ) -> Self {
        DataError::Io {
            path: path.into(),
            action,
            source,
        }
    }
}
