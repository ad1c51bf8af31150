//! Checkpoints: named `f32` tensors and string metadata in one safetensors
//! file, tagged with a format version. Written atomically (`name.tmp`, then
//! rename). Loading checks the version and every tensor's shape.
//!
//! Metadata keys used here: `format` = `"wildlight-checkpoint"`,
//! `format_version` = [`CHECKPOINT_FORMAT_VERSION`]; callers add their own.

use crate::adam::Adam;
use crate::error::FieldError;
use crate::hash_grid::HashGrid;
use crate::mlp::Mlp;
use crate::neural_field::NeuralField;
use crate::sdf_field::SdfField;
use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Version written into (and required from) every checkpoint.
pub const CHECKPOINT_FORMAT_VERSION: u32 = 1;
const FORMAT_NAME: &str = "wildlight-checkpoint";

/// Collects tensors and metadata, then writes one file.
#[derive(Clone, Debug, Default)]
pub struct CheckpointWriter {
    tensors: Vec<(String, Vec<usize>, Vec<u8>)>,
    metadata: HashMap<String, String>,
}

impl CheckpointWriter {
    /// An empty checkpoint.
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds tensor `name` of `shape` (row-major `f32` data; `data.len()` must equal the shape's product).
    pub fn add(&mut self, name: &str, shape: &[usize], data: &[f32]) {
        assert_eq!(
            shape.iter().product::<usize>(),
            data.len(),
            "checkpoint tensor '{name}': shape"
        );
        // Block-wise, so that the copy vectorises (a byte iterator over
        // tens of millions of values does not).
        let mut bytes = vec![0u8; 4 * data.len()];
        for (out, v) in bytes.chunks_exact_mut(4).zip(data) {
            out.copy_from_slice(&v.to_le_bytes());
        }
        self.tensors.push((name.to_string(), shape.to_vec(), bytes));
    }
    /// Sets a metadata entry.
    pub fn set_metadata(&mut self, key: &str, value: &str) {
        self.metadata.insert(key.to_string(), value.to_string());
    }
    /// Writes the file atomically (`path.tmp` then rename).
    pub fn save(&self, path: &Path) -> Result<(), FieldError> {
        let mut meta = self.metadata.clone();
        meta.insert("format".into(), FORMAT_NAME.into());
        meta.insert(
            "format_version".into(),
            CHECKPOINT_FORMAT_VERSION.to_string(),
        );
        let views: Vec<(String, TensorView<'_>)> = self
            .tensors
            .iter()
            .map(|(n, s, b)| {
                TensorView::new(Dtype::F32, s.clone(), b)
                    .map(|v| (n.clone(), v))
                    .map_err(|e| FieldError::Format {
                        path: path.to_path_buf(),
                        message: format!("tensor '{n}': {e}"),
                    })
            })
            .collect::<Result<_, _>>()?;
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".tmp");
        let tmp = PathBuf::from(tmp);
        // Straight to the file: building the whole file in memory first
        // copied every byte once more (a training checkpoint is ~220 MB).
        safetensors::serialize_to_file(views, Some(meta), &tmp).map_err(|e| match e {
            safetensors::SafeTensorError::IoError(source) => FieldError::Io {
                path: tmp.clone(),
                source,
            },
            e => FieldError::Format {
                path: path.to_path_buf(),
                message: e.to_string(),
            },
        })?;
        std::fs::rename(&tmp, path).map_err(|source| FieldError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

/// A loaded checkpoint.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    path: PathBuf,
    bytes: Vec<u8>,
    metadata: HashMap<String, String>,
}

impl Checkpoint {
    /// Reads and validates a checkpoint (format name and version).
    pub fn load(path: &Path) -> Result<Self, FieldError> {
        let bytes = std::fs::read(path).map_err(|source| FieldError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let fmt = |message: String| FieldError::Format {
            path: path.to_path_buf(),
            message,
        };
        let (_, meta) = SafeTensors::read_metadata(&bytes)
            .map_err(|e| fmt(format!("not a safetensors file: {e}")))?;
        SafeTensors::deserialize(&bytes)
            .map_err(|e| fmt(format!("not a safetensors file: {e}")))?;
        let metadata = meta.metadata().clone().unwrap_or_default();
        if metadata.get("format").map(String::as_str) != Some(FORMAT_NAME) {
            return Err(fmt(
                "not a wildlight checkpoint (metadata 'format' missing)".into(),
            ));
        }
        let version = metadata
            .get("format_version")
            .cloned()
            .unwrap_or_else(|| "(none)".into());
        if version != CHECKPOINT_FORMAT_VERSION.to_string() {
            return Err(FieldError::Version {
                path: path.to_path_buf(),
                found: version,
                expected: CHECKPOINT_FORMAT_VERSION,
            });
        }
        Ok(Checkpoint {
            path: path.to_path_buf(),
            bytes,
            metadata,
        })
    }

    /// The file this was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// A metadata entry.
    pub fn metadata(&self, key: &str) -> Option<&str> {
        self.metadata.get(key).map(String::as_str)
    }
    /// Whether tensor `name` exists.
    pub fn contains(&self, name: &str) -> bool {
        SafeTensors::deserialize(&self.bytes)
            .map(|s| s.tensor(name).is_ok())
            .unwrap_or(false)
    }

    /// Copies tensor `name` into `dst`, checking that its shape is `shape`
    /// (and `dst.len()` equals its product) and its dtype F32.
    pub fn read_into(
        &self,
        name: &str,
        shape: &[usize],
        dst: &mut [f32],
    ) -> Result<(), FieldError> {
        let st = SafeTensors::deserialize(&self.bytes).map_err(|e| FieldError::Format {
            path: self.path.clone(),
            message: e.to_string(),
        })?;
        let view = st.tensor(name).map_err(|_| FieldError::MissingTensor {
            path: self.path.clone(),
            name: name.to_string(),
        })?;
        if view.dtype() != Dtype::F32
            || view.shape() != shape
            || dst.len() != shape.iter().product::<usize>()
        {
            return Err(FieldError::Shape {
                path: self.path.clone(),
                name: name.to_string(),
                found: view.shape().to_vec(),
                expected: shape.to_vec(),
                dtype: view.dtype().to_string(),
            });
        }
        for (d, b) in dst.iter_mut().zip(view.data().chunks_exact(4)) {
            *d = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        Ok(())
    }
}

/// Parts whose parameters (or state) go into checkpoints under a name prefix.
pub trait Checkpointable {
    /// Adds this part's tensors/metadata under `prefix`.
    fn save_to(&self, w: &mut CheckpointWriter, prefix: &str);
    /// Restores this part from `ck` (shapes must match this part's configuration).
    fn load_from(&mut self, ck: &Checkpoint, prefix: &str) -> Result<(), FieldError>;
}

impl Checkpointable for HashGrid<f32> {
    fn save_to(&self, w: &mut CheckpointWriter, prefix: &str) {
        w.add(
            &format!("{prefix}.table"),
            &[self.params.len()],
            &self.params,
        );
    }
    fn load_from(&mut self, ck: &Checkpoint, prefix: &str) -> Result<(), FieldError> {
        let n = self.params.len();
        ck.read_into(&format!("{prefix}.table"), &[n], &mut self.params)
    }
}

impl Checkpointable for Mlp<f32> {
    fn save_to(&self, w: &mut CheckpointWriter, prefix: &str) {
        for (i, l) in self.layers().iter().enumerate() {
            w.add(
                &format!("{prefix}.{i}.weight"),
                &[l.n_out, l.n_in],
                &self.params[l.weight_offset..l.bias_offset],
            );
            w.add(
                &format!("{prefix}.{i}.bias"),
                &[l.n_out],
                &self.params[l.bias_offset..l.bias_offset + l.n_out],
            );
        }
    }
    fn load_from(&mut self, ck: &Checkpoint, prefix: &str) -> Result<(), FieldError> {
        for (i, l) in self.layers().to_vec().into_iter().enumerate() {
            ck.read_into(
                &format!("{prefix}.{i}.weight"),
                &[l.n_out, l.n_in],
                &mut self.params[l.weight_offset..l.bias_offset],
            )?;
            ck.read_into(
                &format!("{prefix}.{i}.bias"),
                &[l.n_out],
                &mut self.params[l.bias_offset..l.bias_offset + l.n_out],
            )?;
        }
        Ok(())
    }
}

impl Checkpointable for NeuralField<f32> {
    fn save_to(&self, w: &mut CheckpointWriter, prefix: &str) {
        self.grid.save_to(w, &format!("{prefix}.grid"));
        self.mlp.save_to(w, &format!("{prefix}.mlp"));
        w.set_metadata(
            &format!("{prefix}.active_levels"),
            &self.active_levels.to_string(),
        );
    }
    fn load_from(&mut self, ck: &Checkpoint, prefix: &str) -> Result<(), FieldError> {
        self.grid.load_from(ck, &format!("{prefix}.grid"))?;
        self.mlp.load_from(ck, &format!("{prefix}.mlp"))?;
        if let Some(v) = ck.metadata(&format!("{prefix}.active_levels")) {
            self.active_levels = v.parse().map_err(|_| FieldError::Format {
                path: ck.path().to_path_buf(),
                message: format!("metadata '{prefix}.active_levels' is not an integer: {v}"),
            })?;
        }
        Ok(())
    }
}

impl Checkpointable for SdfField<f32> {
    fn save_to(&self, w: &mut CheckpointWriter, prefix: &str) {
        self.field.save_to(w, prefix);
    }
    fn load_from(&mut self, ck: &Checkpoint, prefix: &str) -> Result<(), FieldError> {
        self.field.load_from(ck, prefix)
    }
}

impl Checkpointable for Adam<f32> {
    fn save_to(&self, w: &mut CheckpointWriter, prefix: &str) {
        for g in &self.groups {
            w.add(&format!("{prefix}.{}.m", g.name), &[g.m.len()], &g.m);
            w.add(&format!("{prefix}.{}.v", g.name), &[g.v.len()], &g.v);
            w.set_metadata(&format!("{prefix}.{}.step", g.name), &g.step.to_string());
        }
    }
    fn load_from(&mut self, ck: &Checkpoint, prefix: &str) -> Result<(), FieldError> {
        for g in &mut self.groups {
            let n = g.m.len();
            ck.read_into(&format!("{prefix}.{}.m", g.name), &[n], &mut g.m)?;
            ck.read_into(&format!("{prefix}.{}.v", g.name), &[n], &mut g.v)?;
            let key = format!("{prefix}.{}.step", g.name);
            let s = ck.metadata(&key).ok_or_else(|| FieldError::Format {
                path: ck.path().to_path_buf(),
                message: format!("metadata '{key}' is missing"),
            })?;
            g.step = s.parse().map_err(|_| FieldError::Format {
                path: ck.path().to_path_buf(),
                message: format!("metadata '{key}' is not an integer: {s}"),
            })?;
        }
        Ok(())
    }
}
