//! The files a user names (meshes, scene and parameter files, voxmaps, traces, point lists) are
//! opened only when they are regular files and read only within a size bound.
//!
//! A path given by mistake can be something other than a file: a named pipe (or a shell's
//! `<(...)`) makes an ordinary `open` wait for a writer forever; `/dev/zero` or `/dev/urandom`
//! never end, so reading them whole grows a buffer until memory runs out; a directory fails with
//! an error that does not say what was expected. [`open_regular`] refuses each of these at once
//! with an error saying what the path is, and [`read_regular`] also refuses a file over the
//! caller's size bound before allocating for it. Errors are [`std::io::Error`]s, so callers keep
//! their own error types (which name the file) and only change how they open it.
//!
//! Outputs go the other way through [`atomic::write_atomically`]: written whole to a temporary
//! file beside the destination and renamed over it, and only ever over a regular file or a new
//! path ([`output_destination`]).
//!
//! Where this crate sits in vps: `docs/architecture.md#crates` at the repository root.

#![warn(missing_docs)]

use std::fs::{File, FileType, OpenOptions};
use std::io::{self, Read};
use std::path::{Path, PathBuf};

pub mod atomic;

/// One mebibyte (2^20 bytes), for writing size bounds.
pub const MIB: u64 = 1 << 20;
/// One gibibyte (2^30 bytes), for writing size bounds.
pub const GIB: u64 = 1 << 30;

/// Opens `path` for reading if it is a regular file (symbolic links followed), returning the file
/// and its length in bytes.
///
/// Never blocks: on Unix the file is opened with `O_NONBLOCK`, so opening a named pipe returns at
/// once; the flag is cleared again once the file is known to be regular. Anything else (a
/// directory, a named pipe, a character or block device, a socket) is an error of kind
/// [`io::ErrorKind::InvalidInput`] whose message says what the path is.
pub fn open_regular(path: &Path) -> io::Result<(File, u64)> {
    let mut options = OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path)?;
    let metadata = file.metadata()?;
    if !metadata.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "not a regular file but {}: give the path of a file on disk (a pipe or device \
                 could block or never end)",
                describe(&metadata.file_type())
            ),
        ));
    }
    #[cfg(unix)]
    clear_nonblocking(&file)?;
    Ok((file, metadata.len()))
}

/// Reads all of `path` if it is a regular file (see [`open_regular`]) of at most `max_bytes`
/// bytes. A larger file is an error of kind [`io::ErrorKind::FileTooLarge`] naming its size and
/// the bound, returned before anything is allocated; a file that grows past the bound while it is
/// read is refused the same way, so at most `max_bytes + 1` bytes are ever held.
pub fn read_regular(path: &Path, max_bytes: u64) -> io::Result<Vec<u8>> {
    let (file, len) = open_regular(path)?;
    if len > max_bytes {
        return Err(too_large(len, max_bytes));
    }
    // `len <= max_bytes`, a bound the caller chose to fit in memory.
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large(bytes.len() as u64, max_bytes));
    }
    Ok(bytes)
}

/// [`read_regular`], then the bytes as UTF-8 text; text that is not UTF-8 is an error of kind
/// [`io::ErrorKind::InvalidData`] naming the byte offset of the first invalid byte.
pub fn read_regular_to_string(path: &Path, max_bytes: u64) -> io::Result<String> {
    String::from_utf8(read_regular(path, max_bytes)?).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "not UTF-8 text: the byte at offset {} is not valid UTF-8",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// `bytes` for people: `"5.0 GiB (5368709120 bytes)"`, `"512 bytes"`.
pub fn describe_size(bytes: u64) -> String {
    let b = bytes as f64;
    if bytes >= GIB {
        format!("{:.1} GiB ({bytes} bytes)", b / GIB as f64)
    } else if bytes >= MIB {
        format!("{:.1} MiB ({bytes} bytes)", b / MIB as f64)
    } else if bytes >= 1024 {
        format!("{:.1} KiB ({bytes} bytes)", b / 1024.0)
    } else {
        format!("{bytes} bytes")
    }
}

/// The file an output written to `path` replaces: `path` itself when nothing is there or it is a
/// regular file; when `path` is a symbolic link (or a chain of them) to a regular file, that file
/// (canonical path), so the link stays and the file it names is replaced.
///
/// Anything else is an error of kind [`io::ErrorKind::InvalidInput`] saying what is there: a
/// directory, a named pipe, a character or block device or a socket (written as a file, it would
/// be replaced by one, or block, or swallow the output), a link to one of these, or a link to
/// nothing (a dangling link: where it leads is not checked, so it is not followed). Outputs are
/// written whole to a temporary file and renamed into place; such a path never is a place for
/// that. Blocking only for the file-system calls; never opens `path`.
pub fn output_destination(path: &Path) -> io::Result<PathBuf> {
    let refuse = |what: String| {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{what}: vps writes an output file whole and renames it into place, so it writes \
                 only to a regular file or a new path; give the path of a file on disk"
            ),
        ))
    };
    let link = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(path.to_path_buf()),
        Err(e) => return Err(e),
    };
    if link.is_file() {
        return Ok(path.to_path_buf());
    }
    if !link.file_type().is_symlink() {
        return refuse(format!(
            "not a regular file but {}",
            describe(&link.file_type())
        ));
    }
    match std::fs::metadata(path) {
        Ok(target) if target.is_file() => std::fs::canonicalize(path),
        Ok(target) => refuse(format!(
            "a symbolic link to {}, which is not a regular file but {}",
            std::fs::read_link(path)
                .map(|t| t.display().to_string())
                .unwrap_or_default(),
            describe(&target.file_type())
        )),
        Err(e) if e.kind() == io::ErrorKind::NotFound => refuse(format!(
            "a symbolic link to {}, which does not exist",
            std::fs::read_link(path)
                .map(|t| t.display().to_string())
                .unwrap_or_default()
        )),
        Err(e) => Err(e),
    }
}

/// True for a character that must not reach a terminal raw: a control character (Unicode
/// category Cc: C0, DEL, C1, among them ESC, BEL, CR and LF) or a bidirectional-text control
/// (U+200E, U+200F, U+202A..=U+202E, U+2066..=U+2069), which can reorder what a line shows.
fn is_unprintable(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
}

/// `text` (taken from an input: a scene's `name` or `voxels.reason`, a path, a mesh source) fit to
/// print: every control character written as an escape (`\n`, `\r`, `\t`, else `\u{1b}`
/// style), so what a file says cannot retitle or clear the terminal, move the cursor or forge a
/// line of output. The one escaping function of vps: everything printed from input goes through
/// it (or [`printable_lines`]). Borrowed when nothing needs escaping.
pub fn printable(text: &str) -> std::borrow::Cow<'_, str> {
    escape(text, false)
}

/// [`printable`] for a message of several lines (an error chain with a parser's excerpt of the
/// file): line breaks are kept, every other control character escaped.
pub fn printable_lines(text: &str) -> std::borrow::Cow<'_, str> {
    escape(text, true)
}

fn escape(text: &str, keep_newlines: bool) -> std::borrow::Cow<'_, str> {
    let unprintable = |c: char| is_unprintable(c) && !(keep_newlines && c == '\n');
    if !text.chars().any(unprintable) {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 16);
    for c in text.chars() {
        if !unprintable(c) {
            out.push(c);
            continue;
        }
        match c {
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            _ => out.push_str(&format!("\\u{{{:x}}}", c as u32)),
        }
    }
    std::borrow::Cow::Owned(out)
}

fn too_large(len: u64, max_bytes: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::FileTooLarge,
        format!(
            "the file is {}, over the limit of {} for this input",
            describe_size(len),
            describe_size(max_bytes)
        ),
    )
}

/// What a path that is not a regular file is, as a noun phrase.
fn describe(file_type: &FileType) -> &'static str {
    if file_type.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return "a named pipe (FIFO)";
        }
        if file_type.is_char_device() {
            return "a character device";
        }
        if file_type.is_block_device() {
            return "a block device";
        }
        if file_type.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// Clears `O_NONBLOCK` on a file opened with it, so reads behave as on any opened file.
#[cfg(unix)]
fn clear_nonblocking(file: &File) -> io::Result<()> {
    use std::os::fd::AsRawFd;
    let fd = file.as_raw_fd();
    // SAFETY: `fd` is an open descriptor owned by `file` for the duration of both calls; F_GETFL
    // and F_SETFL read and set its status flags and touch no memory of ours.
    unsafe {
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags < 0 || libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) < 0 {
            return Err(io::Error::last_os_error());
        }
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::sync::mpsc;
    use std::time::Duration;

    /// Two paths that are not regular files, made in `dir`: a named pipe and a link to
    /// `/dev/null`.
    pub(crate) struct NotFiles {
        pub fifo: PathBuf,
        pub to_null: PathBuf,
    }

    /// Makes [`NotFiles`] in `dir` (`mkfifo` and a symbolic link).
    pub(crate) fn not_files(dir: &Path) -> NotFiles {
        let fifo = dir.join("fifo");
        assert!(std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success());
        let to_null = dir.join("null.json");
        std::os::unix::fs::symlink("/dev/null", &to_null).unwrap();
        NotFiles { fifo, to_null }
    }

    #[test]
    fn a_regular_file_reads_whole_up_to_the_bound() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, "0123456789").unwrap();
        assert_eq!(read_regular_to_string(&path, 10).unwrap(), "0123456789");
        let (_, len) = open_regular(&path).unwrap();
        assert_eq!(len, 10);
    }

    #[test]
    fn a_file_over_the_bound_is_refused_naming_both_sizes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.bin");
        std::fs::write(&path, vec![7u8; 2048]).unwrap();
        let err = read_regular(&path, 1024).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::FileTooLarge);
        let message = err.to_string();
        assert!(message.contains("2.0 KiB (2048 bytes)"), "{message}");
        assert!(message.contains("1.0 KiB (1024 bytes)"), "{message}");
    }

    #[test]
    fn a_directory_is_refused_as_a_directory() {
        let dir = tempfile::tempdir().unwrap();
        let err = read_regular(dir.path(), MIB).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("a directory"), "{err}");
    }

    #[test]
    fn text_that_is_not_utf8_names_the_offset() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("latin1.toml");
        std::fs::write(&path, b"name = \"caf\xe9\"").unwrap();
        let err = read_regular_to_string(&path, MIB).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidData);
        assert!(err.to_string().contains("offset 11"), "{err}");
    }

    /// Runs `open` on another thread and fails (instead of hanging) if it has not returned in
    /// 10 s; the only thread in this crate's tests, there because the failure being tested for
    /// is a call that never returns.
    fn returns_promptly(path: std::path::PathBuf) -> io::Result<(File, u64)> {
        let (send, receive) = mpsc::channel();
        std::thread::spawn(move || send.send(open_regular(&path)).unwrap());
        receive
            .recv_timeout(Duration::from_secs(10))
            .expect("open_regular blocked for 10 s")
    }

    #[cfg(unix)]
    #[test]
    fn a_named_pipe_is_refused_without_waiting_for_a_writer() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pipe");
        let c_path = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: `c_path` is a valid NUL-terminated path that outlives the call.
        assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0);
        let err = returns_promptly(path).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("a named pipe (FIFO)"), "{err}");
    }

    #[cfg(unix)]
    #[test]
    fn an_endless_device_is_refused_before_any_read() {
        let zero = Path::new("/dev/zero");
        if !zero.exists() {
            eprintln!("skipped: no /dev/zero");
            return;
        }
        let err = returns_promptly(zero.to_path_buf()).unwrap_err();
        assert!(err.to_string().contains("a character device"), "{err}");
        let err = read_regular(zero, GIB).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    }

    #[test]
    fn sizes_read_in_the_largest_whole_unit() {
        assert_eq!(describe_size(512), "512 bytes");
        assert_eq!(describe_size(1536), "1.5 KiB (1536 bytes)");
        assert_eq!(describe_size(16 * MIB), "16.0 MiB (16777216 bytes)");
        assert_eq!(describe_size(5 * GIB), "5.0 GiB (5368709120 bytes)");
    }

    #[test]
    fn an_output_is_a_regular_file_a_new_path_or_a_link_to_a_regular_file() {
        let dir = tempfile::tempdir().unwrap();
        let new = dir.path().join("new.json");
        assert_eq!(output_destination(&new).unwrap(), new);
        let file = dir.path().join("old.json");
        std::fs::write(&file, "{}").unwrap();
        assert_eq!(output_destination(&file).unwrap(), file);
        let link = dir.path().join("link.json");
        std::os::unix::fs::symlink(&file, &link).unwrap();
        assert_eq!(
            output_destination(&link).unwrap(),
            std::fs::canonicalize(&file).unwrap()
        );
    }

    #[test]
    fn an_output_that_is_a_pipe_a_device_a_directory_or_a_link_to_one_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let NotFiles { fifo, to_null } = not_files(dir.path());
        let dangling = dir.path().join("dangling.json");
        std::os::unix::fs::symlink(dir.path().join("nowhere"), &dangling).unwrap();
        for (path, what) in [
            (fifo.as_path(), "a named pipe (FIFO)"),
            (Path::new("/dev/null"), "a character device"),
            (Path::new("/dev/full"), "a character device"),
            (to_null.as_path(), "a symbolic link to /dev/null"),
            (dangling.as_path(), "which does not exist"),
            (dir.path(), "a directory"),
        ] {
            let err = output_destination(path).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{path:?}");
            assert!(err.to_string().contains(what), "{path:?}: {err}");
        }
        assert!(fifo.exists() && !fifo.is_file());
    }

    #[test]
    fn control_characters_are_escaped_for_printing() {
        let hostile = "bay\u{1b}]0;owned\u{7}\u{1b}[2J\r\nFAKE: ok\u{202e}txt.exe\u{9b}";
        let shown = printable(hostile);
        assert_eq!(
            shown,
            "bay\\u{1b}]0;owned\\u{7}\\u{1b}[2J\\r\\nFAKE: ok\\u{202e}txt.exe\\u{9b}"
        );
        assert!(!shown.chars().any(is_unprintable));
        assert_eq!(printable_lines("a\nb\u{7}"), "a\nb\\u{7}");
        assert!(matches!(
            printable("plain, ünïcode ok"),
            std::borrow::Cow::Borrowed(_)
        ));
    }
}
