//! Shared output helpers: stdout through a writer that returns errors (a closed pipe or a full
//! disk is an error, never a panic), output-path checks made before any work, atomic file writes,
//! and the error report printed by `main`.

use anyhow::{anyhow, bail, Context, Result};
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// The error of a write to stdout whose reader has gone (EPIPE, e.g. `vps inspect x | head -1`).
/// `main` ends the program quietly with [`BROKEN_PIPE_STATUS`] when a command returns it.
#[derive(Debug, thiserror::Error)]
#[error("stdout was closed by its reader (broken pipe)")]
pub struct BrokenStdout;

/// Exit status when stdout's reader has gone: 141 = 128 + SIGPIPE, what a shell reports for a
/// program killed by SIGPIPE (as `cat` is in `cat big | head -1`), so `set -o pipefail` scripts
/// see that the output was cut short.
pub const BROKEN_PIPE_STATUS: i32 = 141;

/// Maps an error writing to stdout: EPIPE becomes [`BrokenStdout`], anything else (ENOSPC on
/// `> /dev/full`) an error naming stdout.
fn stdout_error(e: std::io::Error) -> anyhow::Error {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        anyhow::Error::new(BrokenStdout)
    } else {
        anyhow::Error::new(e).context("writing to stdout")
    }
}

/// Writes `args` and a newline to stdout; a closed pipe becomes [`BrokenStdout`]. Use through [`outln!`].
pub fn stdout_line(args: std::fmt::Arguments) -> Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_fmt(args)
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush())
        .map_err(stdout_error)
}

/// `println!` that returns an error instead of panicking when stdout fails:
/// `outln!("{x}")?`.
#[macro_export]
#[doc(hidden)]
macro_rules! __outln {
    ($($arg:tt)*) => {
        $crate::output::stdout_line(format_args!($($arg)*))
    };
}
pub use crate::__outln as outln;

/// Prints `value` as pretty JSON on stdout.
pub fn print_json<T: Serialize>(value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    outln!("{text}")
}

/// Prints a command's summary on stdout: pretty JSON with `--json` (`json`), else its text (its
/// `Display`, one or more lines).
pub fn print_summary<T: Serialize + std::fmt::Display>(value: &T, json: bool) -> Result<()> {
    if json {
        print_json(value)
    } else {
        outln!("{value}")
    }
}

/// A whole number with thousands separators (`10000` → `10,000`), as the text reports print
/// counts.
pub fn grouped(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Prints a measurement's report: pretty JSON with `--json` (`json`), else `title` and the same
/// figures as indented `name: value` text ([`text_report`]).
pub fn print_report<T: Serialize>(title: &str, value: &T, json: bool) -> Result<()> {
    if json {
        return print_json(value);
    }
    let value = serde_json::to_value(value)?;
    outln!("{}", text_report(title, &value).trim_end())
}

/// A JSON value as text for a person: `title`, then one `name: value` line per field, nested
/// objects and lists of objects indented under their name (list items numbered from 1), lists of
/// plain values on one line, names with spaces for underscores, whole numbers with thousands
/// separators, `none` for an absent (JSON `null`) figure; strings are escaped
/// ([`vps_files::printable`]). The field names are those of `--json`'s output.
pub fn text_report(title: &str, value: &serde_json::Value) -> String {
    let mut out = format!("{}\n", vps_files::printable(title));
    write_text(&mut out, value, 1);
    out
}

/// One plain value (not an object, nor a list holding one) as text.
fn plain_text(value: &serde_json::Value) -> String {
    use serde_json::Value;
    match value {
        Value::Null => "none".into(),
        Value::Bool(b) => if *b { "yes" } else { "no" }.into(),
        Value::Number(n) => match n.as_u64() {
            Some(u) => grouped(u),
            None => match n.as_i64() {
                Some(i) => format!("-{}", grouped(i.unsigned_abs())),
                None => {
                    let f = n.as_f64().unwrap_or(f64::NAN);
                    if f != 0.0 && (f.abs() >= 1e6 || f.abs() < 1e-3) {
                        format!("{f:.3e}")
                    } else {
                        // Four significant decimals at most, no trailing zeros.
                        let t = format!("{f:.4}");
                        let t = t.trim_end_matches('0').trim_end_matches('.');
                        t.to_string()
                    }
                }
            },
        },
        Value::String(s) => vps_files::printable(s).into_owned(),
        Value::Array(items) => items.iter().map(plain_text).collect::<Vec<_>>().join(", "),
        Value::Object(_) => String::new(),
    }
}

/// True when `value` is printed on its name's line (not an object, nor a list holding one).
fn is_plain(value: &serde_json::Value) -> bool {
    match value {
        serde_json::Value::Object(_) => false,
        serde_json::Value::Array(items) => items.iter().all(|v| !v.is_object() && !v.is_array()),
        _ => true,
    }
}

fn write_text(out: &mut String, value: &serde_json::Value, depth: usize) {
    use serde_json::Value;
    let pad = "  ".repeat(depth);
    match value {
        Value::Object(fields) => {
            for (name, v) in fields {
                let name = vps_files::printable(&name.replace('_', " ")).into_owned();
                if v.as_array().is_some_and(Vec::is_empty)
                    || v.as_object().is_some_and(|o| o.is_empty())
                {
                    out.push_str(&format!("{pad}{name}: none\n"));
                } else if is_plain(v) {
                    out.push_str(&format!("{pad}{name}: {}\n", plain_text(v)));
                } else {
                    out.push_str(&format!("{pad}{name}:\n"));
                    write_text(out, v, depth + 1);
                }
            }
        }
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                if is_plain(v) {
                    out.push_str(&format!("{pad}{}: {}\n", i + 1, plain_text(v)));
                } else {
                    out.push_str(&format!("{pad}{}:\n", i + 1));
                    write_text(out, v, depth + 1);
                }
            }
        }
        v => out.push_str(&format!("{pad}{}\n", plain_text(v))),
    }
}

/// A length or coordinate (m) for a text report: four decimals (0.1 mm; `--json` has every digit),
/// never `-0.0000`.
pub fn metres_4(v: f64) -> String {
    let text = format!("{v:.4}");
    if text == "-0.0000" {
        "0.0000".into()
    } else {
        text
    }
}

/// Checks, before any work, that `output` (given with `flag`, e.g. `--report` or `-o`) can be
/// written: a regular file or a new path, never a directory, named pipe, device, socket or a link
/// to one or to nothing ([`vps_files::output_destination`]: outputs are written whole and renamed
/// into place, which would replace such a node); its directory exists and accepts a new file; and
/// it is none of `inputs` (the same file through links or other spellings of the path too).
/// Errors name the flag, the path and what to change.
pub fn check_output_path(flag: &str, output: &Path, inputs: &[&Path]) -> Result<()> {
    let shown = output.display();
    vps_files::output_destination(output).map_err(|e| anyhow!("{flag} {shown}: {e}"))?;
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!(
            "{flag} {shown}: directory {} does not exist (create it first)",
            dir.display()
        );
    }
    tempfile::Builder::new()
        .prefix(".vps-check-")
        .tempfile_in(dir)
        .with_context(|| format!("{flag} {shown}: cannot create files in {}", dir.display()))?;
    for input in inputs {
        if same_place(output, input) {
            bail!(
                "{flag} {shown} is the input {}; writing it would destroy that input: choose \
                 another output file",
                input.display()
            );
        }
    }
    Ok(())
}

/// Checks every output of a command ([`check_output_path`] each, against all of `inputs`) and
/// that no two of them name the same file (one would silently replace the other). `outputs` are
/// (flag, path) pairs.
pub fn check_outputs(outputs: &[(&str, &Path)], inputs: &[&Path]) -> Result<()> {
    for (i, (flag, path)) in outputs.iter().enumerate() {
        check_output_path(flag, path, inputs)?;
        for (other_flag, other) in &outputs[..i] {
            if same_place(path, other) {
                bail!(
                    "{other_flag} {} and {flag} {} name the same file; one would replace the \
                     other: give each its own file",
                    other.display(),
                    path.display()
                );
            }
        }
    }
    Ok(())
}

/// Where `path` leads: its canonical path when it exists (links resolved), else its directory's
/// canonical path joined with its name; `None` when neither resolves.
fn resolved(path: &Path) -> Option<std::path::PathBuf> {
    if let Ok(p) = std::fs::canonicalize(path) {
        return Some(p);
    }
    let name = path.file_name()?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(dir).ok()?.join(name))
}

/// True when `a` and `b` are the same file (device and inode: hard links too) or lead to the same
/// place ([`resolved`]: other spellings, links, and new paths not yet written).
fn same_place(a: &Path, b: &Path) -> bool {
    same_file(a, b) || matches!((resolved(a), resolved(b)), (Some(x), Some(y)) if x == y)
}

/// True when both paths exist and name the same file.
fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        false
    }
}

/// Writes `bytes` to `path` atomically (a temporary file in the same directory, renamed into
/// place): a failure leaves no truncated file. Errors name the path.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    vps_files::atomic::write_atomically(
        path,
        |w| w.write_all(bytes),
        |stage, e| std::io::Error::new(e.kind(), format!("{}: {e}", stage.name())),
    )
    .with_context(|| format!("writing {}", path.display()))
}

/// The longest line of an error message printed whole (bytes); longer lines (a parser echoing a
/// 600 KB line of a hostile file) are cut, saying how much was left out.
pub const MAX_ERROR_LINE: usize = 1000;

/// An error message as `main` prints it: control characters escaped, line breaks kept
/// ([`vps_files::printable_lines`]: a file cannot drive the terminal through an error quoting
/// it), every line after the first indented by two spaces (so no text of an input can stand at
/// the start of a line of its own, as if vps had printed it), and every line cut at
/// [`MAX_ERROR_LINE`] bytes.
pub fn shown_error(message: &str) -> String {
    let text = vps_files::printable_lines(message);
    let mut out = String::with_capacity(text.len().min(64 * 1024));
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.push_str("\n  ");
        }
        if line.len() <= MAX_ERROR_LINE {
            out.push_str(line);
        } else {
            let mut cut = MAX_ERROR_LINE;
            while !line.is_char_boundary(cut) {
                cut -= 1;
            }
            out.push_str(&line[..cut]);
            out.push_str(&format!(" … ({} more bytes)", line.len() - cut));
        }
    }
    out
}

/// Lower-case hexadecimal of a hash.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Bytes as a human-readable MiB figure.
pub fn mib(bytes: f64) -> String {
    format!("{:.2} MiB", bytes / (1024.0 * 1024.0))
}

/// Voxel counts by kind.
#[derive(Serialize, Clone, Copy)]
pub struct KindCounts {
    /// Free voxels.
    pub free: u64,
    /// Interior voxels.
    pub interior: u64,
    /// Surface (force layer) voxels.
    pub surface: u64,
    /// Proximity voxels.
    pub proximity: u64,
}

impl From<[u64; 4]> for KindCounts {
    fn from(c: [u64; 4]) -> Self {
        Self {
            free: c[vps_voxmap::Voxel::Free as usize],
            interior: c[vps_voxmap::Voxel::Interior as usize],
            surface: c[vps_voxmap::Voxel::Surface as usize],
            proximity: c[vps_voxmap::Voxel::Proximity as usize],
        }
    }
}

impl std::fmt::Display for KindCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "voxels: free {}, interior {}, surface {}, proximity {}",
            self.free, self.interior, self.surface, self.proximity
        )
    }
}

/// The files a mesh source reads (none for `builtin:NAME`), for the output-path check.
pub fn mesh_inputs(source: &str) -> Vec<&std::path::Path> {
    if source.starts_with("builtin:") {
        Vec::new()
    } else {
        vec![std::path::Path::new(source)]
    }
}

/// A point shell's figures, as `vps shell` and `vps inspect` print them.
#[derive(Serialize, Clone, Copy)]
pub struct ShellFigures {
    /// Points in the shell.
    pub points: usize,
    /// Voxel size it was built at (m).
    pub voxel_size_m: f64,
    /// The part's volume (m³).
    pub volume_m3: f64,
    /// The part's centre of mass (m, shell frame).
    pub center_of_mass_m: [f64; 3],
    /// The largest point distance from the origin (m).
    pub max_radius_m: f64,
}

impl ShellFigures {
    /// The figures of `shell`.
    pub fn of(shell: &vps_voxmap::PointShell) -> ShellFigures {
        ShellFigures {
            points: shell.len(),
            voxel_size_m: shell.voxel_size,
            volume_m3: shell.mass.volume,
            center_of_mass_m: shell.mass.center_of_mass.to_array(),
            max_radius_m: shell.max_radius(),
        }
    }
}

impl std::fmt::Display for ShellFigures {
    /// "N points at S m, volume V m³, max radius R m".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} points at {} m, volume {:.3e} m³, max radius {:.4} m",
            self.points, self.voxel_size_m, self.volume_m3, self.max_radius_m
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Text reports show 0.1 mm and never `-0.0000` (scene check printed a bound of -1e-18 so).
    #[test]
    fn metres_4_has_no_negative_zero() {
        assert_eq!(metres_4(-1e-18), "0.0000");
        assert_eq!(metres_4(-0.00004), "0.0000");
        assert_eq!(metres_4(-0.00005001), "-0.0001");
        assert_eq!(metres_4(0.07500950959614927), "0.0750");
    }

    #[test]
    fn counts_are_grouped_by_thousands() {
        assert_eq!(grouped(0), "0");
        assert_eq!(grouped(999), "999");
        assert_eq!(grouped(1000), "1,000");
        assert_eq!(grouped(10_000), "10,000");
        assert_eq!(grouped(1_234_567), "1,234,567");
    }

    /// The text form of a report holds every figure under its name, nested fields indented, and
    /// nothing that parses as JSON.
    #[test]
    fn a_report_as_text_is_not_json() {
        let value = serde_json::json!({
            "frames": 10000,
            "ratio": 0.12345678,
            "tiny": 6e-5,
            "missing": null,
            "ok": true,
            "name": "a\u{1b}[2Jb",
            "sizes": [10.0, 5.0],
            "inner": {"p50_us": 1.5},
            "rows": [{"a": 1}, {"a": 2}],
            "empty": [],
        });
        let text = text_report("bench x", &value);
        assert!(serde_json::from_str::<serde_json::Value>(&text).is_err());
        for line in [
            "bench x",
            "  frames: 10,000",
            "  ratio: 0.1235",
            "  tiny: 6.000e-5",
            "  missing: none",
            "  ok: yes",
            "  name: a\\u{1b}[2Jb",
            "  sizes: 10, 5",
            "  inner:\n    p50 us: 1.5",
            "  rows:\n    1:\n      a: 1\n    2:\n      a: 2",
            "  empty: none",
        ] {
            assert!(text.contains(line), "{line:?} in\n{text}");
        }
    }

    #[test]
    fn output_checks_refuse_bad_paths_and_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.obj");
        std::fs::write(&input, b"v 0 0 0\n").unwrap();
        let missing = dir.path().join("nope/out.vmap");
        let err = check_output_path("-o", &missing, &[&input])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("does not exist") && err.starts_with("-o "),
            "{err}"
        );
        let err = check_output_path("-o", &input, &[&input])
            .unwrap_err()
            .to_string();
        assert!(err.contains("is the input"), "{err}");
        let link = dir.path().join("link.obj");
        std::os::unix::fs::symlink(&input, &link).unwrap();
        assert!(check_output_path("-o", &link, &[&input]).is_err());
        // Another spelling of the same path.
        let dotted = dir.path().join(".").join("in.obj");
        assert!(check_output_path("-o", &dotted, &[&input]).is_err());
        let err = check_output_path("-o", dir.path(), &[])
            .unwrap_err()
            .to_string();
        assert!(err.contains("a directory"), "{err}");
        check_output_path("-o", &dir.path().join("out.vmap"), &[&input]).unwrap();
    }

    #[test]
    fn errors_are_shown_escaped_and_cut() {
        assert_eq!(shown_error("a\u{1b}[2J\nb"), "a\\u{1b}[2J\n  b");
        let long = format!("x{}", "é".repeat(1000));
        let shown = shown_error(&long);
        assert!(
            shown.len() < 1100 && shown.ends_with("more bytes)"),
            "{shown}"
        );
    }

    #[test]
    fn two_outputs_naming_one_file_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.json");
        let again = dir.path().join("sub/../a.json");
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let err = check_outputs(&[("--report", &a), ("--record", &again)], &[])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("--report") && err.contains("--record") && err.contains("same file"),
            "{err}"
        );
        check_outputs(
            &[("--report", &a), ("--record", &dir.path().join("b"))],
            &[],
        )
        .unwrap();
    }
}
