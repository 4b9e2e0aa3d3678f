//! Atomic file replacement: write to a temporary file in the destination's directory, flush and
//! sync it, then rename it over the destination. A failed or interrupted write (full disk, killed
//! process) leaves the destination as it was and removes the temporary file.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// The stage of [`write_atomically`] that failed, for error messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtomicStage {
    /// Creating the temporary file beside the destination.
    Create,
    /// Writing, flushing or syncing the temporary file.
    Write,
    /// Renaming the temporary file over the destination.
    Rename,
}

impl AtomicStage {
    /// A short name: "create", "write" or "rename".
    pub fn name(self) -> &'static str {
        match self {
            AtomicStage::Create => "create",
            AtomicStage::Write => "write",
            AtomicStage::Rename => "rename",
        }
    }
}

/// Writes `path` atomically: `write` fills a buffered temporary file in `path`'s directory (mode
/// 0644 on Unix), which is then flushed, synced and renamed over `path`. An error from `write` is
/// returned as is; an I/O error of the other stages goes through `io_error`. On any error the
/// temporary file is removed and `path` is untouched. Blocks on file I/O.
///
/// Only a regular file or a new path is ever replaced ([`crate::output_destination`]): a
/// symbolic link to a regular file has that file replaced (the link stays); a directory, named
/// pipe, device, socket, or a link to one or to nothing, is refused (stage
/// [`AtomicStage::Create`]) before anything is written.
pub fn write_atomically<E>(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> Result<(), E>,
    io_error: impl Fn(AtomicStage, io::Error) -> E,
) -> Result<(), E> {
    let destination =
        crate::output_destination(path).map_err(|e| io_error(AtomicStage::Create, e))?;
    let path = destination.as_path();
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".vps-tmp-");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let mut tmp = builder
        .tempfile_in(dir)
        .map_err(|e| io_error(AtomicStage::Create, e))?;
    {
        let mut w = BufWriter::new(tmp.as_file_mut());
        write(&mut w)?;
        w.flush().map_err(|e| io_error(AtomicStage::Write, e))?;
    }
    tmp.as_file()
        .sync_all()
        .map_err(|e| io_error(AtomicStage::Write, e))?;
    tmp.persist(path)
        .map_err(|e| io_error(AtomicStage::Rename, e.error))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_the_destination_and_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        std::fs::write(&path, b"old").unwrap();
        let err = write_atomically(
            &path,
            |w| {
                w.write_all(b"partial").map_err(|e| e.to_string())?;
                Err("encoder failed".to_string())
            },
            |stage, e| format!("{}: {e}", stage.name()),
        )
        .unwrap_err();
        assert_eq!(err, "encoder failed");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "temporary file left behind");
    }

    #[test]
    fn success_replaces_the_destination() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        std::fs::write(&path, b"old").unwrap();
        write_atomically(&path, |w| w.write_all(b"new"), |_, e| e).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
    }

    #[test]
    fn missing_directory_fails_at_create() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/out.bin");
        let stage = write_atomically(
            &path,
            |w| w.write_all(b"x").map_err(|_| AtomicStage::Write),
            |stage, _| stage,
        )
        .unwrap_err();
        assert_eq!(stage, AtomicStage::Create);
    }

    #[test]
    fn a_device_a_pipe_or_a_link_to_one_is_never_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let crate::tests::NotFiles { fifo, to_null } = crate::tests::not_files(dir.path());
        for path in [&fifo, &to_null] {
            let err = write_atomically(path, |w| w.write_all(b"new"), |_, e| e).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{path:?}: {err}");
        }
        assert!(fifo.exists() && !fifo.is_file(), "the FIFO is still a FIFO");
        assert!(
            std::fs::symlink_metadata(&to_null)
                .unwrap()
                .file_type()
                .is_symlink(),
            "the link is still a link"
        );
        // A link to a regular file: the file is replaced, the link kept.
        let file = dir.path().join("file.txt");
        std::fs::write(&file, "old").unwrap();
        let link = dir.path().join("link.txt");
        std::os::unix::fs::symlink(&file, &link).unwrap();
        write_atomically(&link, |w| w.write_all(b"new"), |_, e| e).unwrap();
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "new");
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
    }
}
