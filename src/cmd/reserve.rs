//! Output files of a session, checked before the session starts: [`ReservedFile::reserve`]
//! creates a temporary file beside the destination (so a missing directory or a read-only one is
//! an error before any work), and [`ReservedFile::commit`] renames it into place once written.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// A destination whose directory is known to be writable; its contents go to a temporary file
/// beside it until [`ReservedFile::commit`]. Dropped uncommitted, the temporary file is removed.
pub struct ReservedFile {
    path: PathBuf,
    temporary: PathBuf,
    committed: bool,
}

impl ReservedFile {
    /// Creates the temporary file `.NAME.PID.tmp` beside `path`. Errors name `path`.
    pub fn reserve(path: &Path) -> Result<ReservedFile> {
        let name = path
            .file_name()
            .with_context(|| format!("{}: not a file name", path.display()))?;
        let mut temporary_name = std::ffi::OsString::from(".");
        temporary_name.push(name);
        temporary_name.push(format!(".{}.tmp", std::process::id()));
        let temporary = path.with_file_name(temporary_name);
        std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&temporary)
            .with_context(|| format!("{}: cannot create the file", path.display()))?;
        Ok(ReservedFile {
            path: path.to_path_buf(),
            temporary,
            committed: false,
        })
    }

    /// The destination.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes through `write` (given the temporary file's path), then renames the temporary file
    /// into place.
    pub fn commit(mut self, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
        write(&self.temporary).with_context(|| format!("writing {}", self.path.display()))?;
        std::fs::rename(&self.temporary, &self.path).with_context(|| {
            format!(
                "{}: cannot move the finished file into place",
                self.path.display()
            )
        })?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for ReservedFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.temporary);
        }
    }
}
