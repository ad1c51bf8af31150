//! Atomic file writing: write `name.tmp` next to the target, then rename.

use crate::MeshError;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes a file atomically: `body` writes into a buffered `name.tmp` in the
/// same folder, which is then flushed, synced and renamed over `path`. On
/// failure the temporary file is removed and `path` is left untouched.
pub(crate) fn write_atomically(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), MeshError> {
    let tmp = temp_path(path);
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut writer = BufWriter::new(file);
        body(&mut writer)?;
        writer.flush()?;
        writer.get_ref().sync_all()?;
        drop(writer);
        std::fs::rename(&tmp, path)
    })();
    if let Err(err) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(MeshError::io(path, err));
    }
    Ok(())
}

/// `dir/name.ext` → `dir/name.ext.tmp`.
fn temp_path(path: &Path) -> PathBuf {
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".tmp");
    path.with_file_name(name)
}
