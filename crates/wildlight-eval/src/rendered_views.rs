//! The `views.json` list that `wildlight render --out DIR` writes next to
//! its per-view maps (conventions: `[{"index":0,"split":"val","flash":true}, ...]`).

use crate::EvalError;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// One rendered view.
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct RenderedView {
    /// Camera index (file `NNN.exr` with NNN = index, 3 digits).
    pub index: usize,
    /// `"val"` for the dataset's `val/` folder, anything else (usually
    /// `"train"`) for the dataset folder itself.
    #[serde(default)]
    pub split: String,
    /// Whether the view was rendered with the flash (informative; metrics
    /// take flash on/off from the ground-truth camera).
    #[serde(default)]
    pub flash: Option<bool>,
}

impl RenderedView {
    /// Whether the view belongs to the `val/` split.
    pub fn is_val(&self) -> bool {
        self.split == "val"
    }

    /// The file of map `kind` for this view under `dir`: `dir/kind/NNN.exr`.
    pub fn map_path(&self, dir: &Path, kind: &str) -> PathBuf {
        map_path(dir, kind, self.index)
    }
}

/// `dir/kind/NNN.exr`.
pub fn map_path(dir: &Path, kind: &str, index: usize) -> PathBuf {
    dir.join(kind).join(format!("{index:03}.exr"))
}

/// Reads `dir/views.json`. Fails when it is missing or malformed, or when
/// two entries would share a file name (same index in two splits).
pub fn read_views(dir: &Path) -> Result<Vec<RenderedView>, EvalError> {
    let path = dir.join("views.json");
    let text = std::fs::read_to_string(&path).map_err(|e| EvalError::Input {
        path: path.clone(),
        problem: format!("cannot read ({e}); is this a folder written by `wildlight render`?"),
    })?;
    let views: Vec<RenderedView> = serde_json::from_str(&text).map_err(|e| EvalError::Input {
        path: path.clone(),
        problem: format!("not a list of {{\"index\", \"split\", \"flash\"}} entries: {e}"),
    })?;
    let mut seen = std::collections::HashSet::new();
    for v in &views {
        if !seen.insert(v.index) {
            return Err(EvalError::Input {
                path,
                problem: format!("view index {} appears more than once", v.index),
            });
        }
    }
    Ok(views)
}
