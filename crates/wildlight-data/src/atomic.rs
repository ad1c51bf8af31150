//! Atomic file writing: write `name.tmp` in the target's folder, then rename.
//!
//! A reader never sees a half-written file, and a crash leaves at worst a
//! stray `.tmp` file next to the old (intact) one.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::DataError;

/// The temporary name used while `path` is being written: `path` + `.tmp`.
pub fn temp_path(path: &Path) -> PathBuf {
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".tmp");
    path.with_file_name(name)
}

/// Writes `path` atomically: `fill` writes the content to a buffered
/// temporary file in the same folder, which is then renamed over `path`.
/// On any error the temporary file is removed and `path` is untouched.
pub fn write_atomically<F>(path: &Path, fill: F) -> Result<(), DataError>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<(), DataError>,
{
    let tmp = temp_path(path);
    let result = (|| {
        let file = File::create(&tmp).map_err(|e| DataError::io(&tmp, "creating", e))?;
        let mut writer = BufWriter::new(file);
        fill(&mut writer)?;
        writer
            .flush()
            .map_err(|e| DataError::io(&tmp, "writing", e))?;
        let file = writer
            .into_inner()
            .map_err(|e| DataError::io(&tmp, "writing", e.into_error()))?;
        file.sync_all()
            .map_err(|e| DataError::io(&tmp, "syncing", e))?;
        drop(file);
        std::fs::rename(&tmp, path)
            .map_err(|e| DataError::io(path, "renaming the temporary file onto", e))
    })();
    if result.is_err() {
        // Best effort: the error being returned is the one that matters.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `path` atomically as [`write_atomically`] does, with `fill`
/// writing through plain I/O: its errors are reported as writing the
/// temporary file.
pub fn write_io_atomically<F>(path: &Path, fill: F) -> Result<(), DataError>
where
    F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
{
    write_atomically(path, |w| {
        fill(w).map_err(|e| DataError::io(temp_path(path), "writing", e))
    })
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes_atomically(path: &Path, bytes: &[u8]) -> Result<(), DataError> {
    write_io_atomically(path, |w| w.write_all(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_and_leaves_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        write_bytes_atomically(&path, b"hello").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"hello");
        assert!(!temp_path(&path).exists());
    }

    #[test]
    fn failed_fill_keeps_old_content() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        std::fs::write(&path, b"old").unwrap();
        let err = write_atomically(&path, |_| {
            Err(DataError::InvalidArgument {
                what: "test".into(),
                problem: "refused".into(),
            })
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert!(!temp_path(&path).exists());
    }
}
