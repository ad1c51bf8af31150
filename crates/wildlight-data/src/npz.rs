//! Reading and writing `cameras_sphere.npz` (SPEC §5).
//!
//! For each image index `i` the archive holds `world_mat_i` (4×4 or 3×4),
//! `scale_mat_i` (4×4, or 3×4 with the implied last row `0 0 0 1`) and
//! optionally `light_energy_i` (3 values; missing = flash off) and
//! `max_intensity_i` (a scalar: image i's own saturation cap, written by
//! `wildlight import` because exposure scaling gives every photo its own
//! clip level; missing = the global cap), plus an optional scalar
//! `max_intensity` (the global cap, used for every image without its own). Arrays may be float32 or float64 (integer
//! arrays are accepted too), in C or Fortran order. Other keys (for example
//! NeuS's `world_mat_inv_i`) are ignored.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use glam::DMat4;
use ndarray::{ArrayD, IxDyn, OwnedRepr};
use ndarray_npy::{NpzReader, NpzWriter, ReadNpyError, ReadNpzError};

use crate::atomic::write_atomically;
use crate::error::DataError;

/// The raw arrays of one camera, as stored in the npz.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraArrays {
    /// Image index `i` of the keys `world_mat_i`, ...
    pub index: usize,
    /// `world_mat_i`, K[R|t], padded to 4×4 with the row `0 0 0 1`.
    pub world_mat: DMat4,
    /// `scale_mat_i`: x_world = scale_mat · x_normalized.
    pub scale_mat: DMat4,
    /// `light_energy_i` in normalized-frame units; zeros when the key is missing.
    pub light_energy: [f64; 3],
    /// `max_intensity_i`: this image's own saturation cap, when the key is present.
    pub max_intensity: Option<f64>,
}

/// Everything `cameras_sphere.npz` holds that this crate uses.
#[derive(Clone, Debug, PartialEq)]
pub struct CamerasNpz {
    /// The file that was read.
    pub path: PathBuf,
    /// One entry per `world_mat_i` key, sorted by index.
    pub cameras: Vec<CameraArrays>,
    /// The optional `max_intensity` scalar (the saturation cap, SPEC §5).
    pub max_intensity: Option<f64>,
}

type Npz = NpzReader<BufReader<File>>;

fn npz_error(path: &Path, key: Option<&str>, err: impl std::fmt::Display) -> DataError {
    DataError::Npz {
        path: path.to_path_buf(),
        key: key.map(str::to_owned),
        message: err.to_string(),
    }
}

fn is_wrong_type(err: &ReadNpzError) -> bool {
    matches!(err, ReadNpzError::Npy(ReadNpyError::WrongDescriptor(_)))
}

/// Reads array `key` of any real numeric dtype as f64, whatever its shape.
fn read_f64(npz: &mut Npz, path: &Path, key: &str) -> Result<ArrayD<f64>, DataError> {
    macro_rules! try_type {
        ($t:ty) => {
            match npz.by_name::<OwnedRepr<$t>, IxDyn>(key) {
                Ok(a) => return Ok(a.mapv(|v| v as f64)),
                Err(e) if is_wrong_type(&e) => {}
                Err(e) => return Err(npz_error(path, Some(key), e)),
            }
        };
    }
    try_type!(f64);
    try_type!(f32);
    try_type!(i64);
    try_type!(i32);
    try_type!(u8);
    Err(npz_error(
        path,
        Some(key),
        "unsupported dtype (expected float32 or float64)",
    ))
}

fn check_finite(a: &ArrayD<f64>, path: &Path, key: &str) -> Result<(), DataError> {
    if a.iter().any(|v| !v.is_finite()) {
        return Err(DataError::BadValue {
            path: path.to_path_buf(),
            key: key.to_owned(),
            problem: "contains NaN or infinite values".into(),
        });
    }
    Ok(())
}

/// Reads a 4×4 or 3×4 matrix; a 3×4 matrix gets the last row `0 0 0 1`.
fn read_mat(npz: &mut Npz, path: &Path, key: &str) -> Result<DMat4, DataError> {
    let a = read_f64(npz, path, key)?;
    let shape = a.shape().to_vec();
    let rows = match shape.as_slice() {
        [4, 4] => 4,
        [3, 4] => 3,
        _ => {
            return Err(DataError::BadShape {
                path: path.to_path_buf(),
                key: key.to_owned(),
                found: shape,
                expected: "4x4 or 3x4",
            });
        }
    };
    check_finite(&a, path, key)?;
    let mut m = [[0.0; 4]; 4];
    m[3][3] = 1.0;
    for (r, row) in m.iter_mut().enumerate().take(rows) {
        for (c, v) in row.iter_mut().enumerate() {
            *v = a[[r, c]];
        }
    }
    Ok(mat4_from_rows(m))
}

/// Builds a matrix from its rows (glam stores columns).
pub fn mat4_from_rows(rows: [[f64; 4]; 4]) -> DMat4 {
    DMat4::from_cols_array_2d(&rows).transpose()
}

/// The rows of a matrix (the layout numpy uses).
pub fn mat4_rows(m: &DMat4) -> [[f64; 4]; 4] {
    m.transpose().to_cols_array_2d()
}

/// Reads a 3-vector stored as shape (3,), (1,3) or (3,1); a scalar means grey.
fn read_vec3(npz: &mut Npz, path: &Path, key: &str) -> Result<[f64; 3], DataError> {
    let a = read_f64(npz, path, key)?;
    check_finite(&a, path, key)?;
    let values: Vec<f64> = a.iter().copied().collect();
    match values.as_slice() {
        [v] => Ok([*v; 3]),
        [r, g, b] => Ok([*r, *g, *b]),
        _ => Err(DataError::BadShape {
            path: path.to_path_buf(),
            key: key.to_owned(),
            found: a.shape().to_vec(),
            expected: "3 values: (3,), (1,3) or (3,1)",
        }),
    }
}

fn read_scalar(npz: &mut Npz, path: &Path, key: &str) -> Result<f64, DataError> {
    let a = read_f64(npz, path, key)?;
    check_finite(&a, path, key)?;
    match a.len() {
        1 => Ok(a.iter().copied().next().unwrap_or(0.0)),
        _ => Err(DataError::BadShape {
            path: path.to_path_buf(),
            key: key.to_owned(),
            found: a.shape().to_vec(),
            expected: "a scalar",
        }),
    }
}

/// Reads a scalar that must be positive (a saturation cap).
fn read_positive(npz: &mut Npz, path: &Path, key: &str) -> Result<f64, DataError> {
    let m = read_scalar(npz, path, key)?;
    if m <= 0.0 {
        return Err(DataError::BadValue {
            path: path.to_path_buf(),
            key: key.to_owned(),
            problem: format!("must be positive, found {m}"),
        });
    }
    Ok(m)
}

/// Opens an npz archive and lists its keys (without the `.npy` suffix).
fn open(path: &Path) -> Result<(Npz, Vec<String>), DataError> {
    let file = match File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(DataError::MissingFile {
                path: path.to_path_buf(),
                what: "camera parameters".into(),
            });
        }
        Err(e) => return Err(DataError::io(path, "opening", e)),
    };
    let mut npz = NpzReader::new(BufReader::new(file)).map_err(|e| npz_error(path, None, e))?;
    let names = npz.names().map_err(|e| npz_error(path, None, e))?;
    Ok((npz, names))
}

/// The image index of a `world_mat_<i>` key, if `key` is one.
fn world_mat_index(key: &str) -> Option<usize> {
    let digits = key.strip_prefix("world_mat_")?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// Reads `cameras_sphere.npz` (SPEC §5).
///
/// Errors name the file and the key: missing file, not an npz, no
/// `world_mat_i`, a `world_mat_i` without its `scale_mat_i`, wrong shapes,
/// non-finite values, a `scale_mat` whose last row is not `0 0 0 1` or that
/// is not invertible.
pub fn read_cameras_npz(path: &Path) -> Result<CamerasNpz, DataError> {
    let (mut npz, names) = open(path)?;
    let mut indices: Vec<usize> = names.iter().filter_map(|k| world_mat_index(k)).collect();
    indices.sort_unstable();
    indices.dedup();
    if indices.is_empty() {
        let mut keys = names.clone();
        keys.sort();
        return Err(DataError::NoCameras {
            path: path.to_path_buf(),
            keys: keys.join(", "),
        });
    }
    let has = |k: &str| names.iter().any(|n| n == k);
    let mut cameras = Vec::with_capacity(indices.len());
    for index in indices {
        let world_key = format!("world_mat_{index}");
        let world_mat = read_mat(&mut npz, path, &world_key)?;
        let scale_key = format!("scale_mat_{index}");
        if !has(&scale_key) {
            return Err(DataError::MissingKey {
                path: path.to_path_buf(),
                key: scale_key,
                index,
            });
        }
        let scale_mat = read_mat(&mut npz, path, &scale_key)?;
        let last = mat4_rows(&scale_mat)[3];
        let off = last
            .iter()
            .zip([0.0, 0.0, 0.0, 1.0])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if off > 1e-6 {
            return Err(DataError::BadValue {
                path: path.to_path_buf(),
                key: scale_key,
                problem: format!("last row is {last:?}, expected [0, 0, 0, 1] (an affine map)"),
            });
        }
        // Rounding noise in the last row (scale_mat computed by inversion) is dropped.
        let mut scale_mat = scale_mat;
        scale_mat.x_axis.w = 0.0;
        scale_mat.y_axis.w = 0.0;
        scale_mat.z_axis.w = 0.0;
        scale_mat.w_axis.w = 1.0;
        let det = scale_mat.determinant();
        if det.abs() < 1e-300 || !det.is_finite() {
            return Err(DataError::BadValue {
                path: path.to_path_buf(),
                key: scale_key,
                problem: "is not invertible (determinant 0)".into(),
            });
        }
        let energy_key = format!("light_energy_{index}");
        let light_energy = if has(&energy_key) {
            read_vec3(&mut npz, path, &energy_key)?
        } else {
            [0.0; 3]
        };
        if light_energy.iter().any(|v| *v < 0.0) {
            return Err(DataError::BadValue {
                path: path.to_path_buf(),
                key: energy_key,
                problem: format!("negative flash energy {light_energy:?}"),
            });
        }
        let cap_key = format!("max_intensity_{index}");
        let max_intensity = if has(&cap_key) {
            Some(read_positive(&mut npz, path, &cap_key)?)
        } else {
            None
        };
        cameras.push(CameraArrays {
            index,
            world_mat,
            scale_mat,
            light_energy,
            max_intensity,
        });
    }
    let max_intensity = if has("max_intensity") {
        Some(read_positive(&mut npz, path, "max_intensity")?)
    } else {
        None
    };
    Ok(CamerasNpz {
        path: path.to_path_buf(),
        cameras,
        max_intensity,
    })
}

/// Writes `cameras_sphere.npz` atomically: `world_mat_i` and `scale_mat_i`
/// as 4×4 float64, `light_energy_i` as (3,) float64, `max_intensity_i` for
/// the cameras that have their own cap, and `max_intensity` when given. Readable by numpy (`np.load`) and by [`read_cameras_npz`].
pub fn write_cameras_npz(
    path: &Path,
    cameras: &[CameraArrays],
    max_intensity: Option<f64>,
) -> Result<(), DataError> {
    let mut seen = std::collections::BTreeSet::new();
    for cam in cameras {
        if !seen.insert(cam.index) {
            return Err(DataError::InvalidArgument {
                what: path.display().to_string(),
                problem: format!("camera index {} appears twice", cam.index),
            });
        }
    }
    write_atomically(path, |w| {
        let mut npz = NpzWriter::new(w);
        let err = |key: &str, e: ndarray_npy::WriteNpzError| npz_error(path, Some(key), e);
        for cam in cameras {
            let world = ndarray::arr2(&mat4_rows(&cam.world_mat));
            let scale = ndarray::arr2(&mat4_rows(&cam.scale_mat));
            let energy = ndarray::arr1(&cam.light_energy);
            let key = format!("world_mat_{}", cam.index);
            npz.add_array(key.as_str(), &world)
                .map_err(|e| err(&key, e))?;
            let key = format!("scale_mat_{}", cam.index);
            npz.add_array(key.as_str(), &scale)
                .map_err(|e| err(&key, e))?;
            let key = format!("light_energy_{}", cam.index);
            npz.add_array(key.as_str(), &energy)
                .map_err(|e| err(&key, e))?;
            if let Some(m) = cam.max_intensity {
                let key = format!("max_intensity_{}", cam.index);
                npz.add_array(key.as_str(), &ndarray::arr0(m))
                    .map_err(|e| err(&key, e))?;
            }
        }
        if let Some(m) = max_intensity {
            npz.add_array("max_intensity", &ndarray::arr0(m))
                .map_err(|e| err("max_intensity", e))?;
        }
        npz.finish().map_err(|e| npz_error(path, None, e))?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn world_mat_keys_are_recognised() {
        assert_eq!(world_mat_index("world_mat_0"), Some(0));
        assert_eq!(world_mat_index("world_mat_12"), Some(12));
        assert_eq!(world_mat_index("world_mat_inv_3"), None);
        assert_eq!(world_mat_index("world_mat_"), None);
        assert_eq!(world_mat_index("scale_mat_3"), None);
    }

    #[test]
    fn rows_round_trip() {
        let rows = [
            [1.0, 2.0, 3.0, 4.0],
            [5.0, 6.0, 7.0, 8.0],
            [9.0, 10.0, 11.0, 12.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let m = mat4_from_rows(rows);
        assert_eq!(m.row(0).to_array(), rows[0]);
        assert_eq!(m.col(3).to_array(), [4.0, 8.0, 12.0, 1.0]);
        assert_eq!(mat4_rows(&m), rows);
    }
}
