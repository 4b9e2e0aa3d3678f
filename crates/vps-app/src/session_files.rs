//! The files a session writes (`--report`, `--record`, `--study`, `--log-wrenches`): checked
//! before any work against the inputs the request names and each other, and again against the
//! scene's mesh files once the scene file is read ([`crate::prepare()`]); where each moving part's
//! trace goes beside the first's ([`part_trace_path`]).

use crate::output::check_outputs;
use crate::request::SessionRequest;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// The files a session writes at its end, checked before the session starts so that a bad path
/// fails before any work ([`check_outputs`]: each a regular file or a new path in a directory that
/// takes new files, none of them an input the command line names or another output), and again
/// against the scene's mesh files once the scene file is read ([`crate::prepare()`]); written atomically
/// at the end.
#[derive(Default)]
pub struct SessionOutputs {
    /// `--report FILE`.
    pub(crate) report: Option<PathBuf>,
    /// `--record FILE`.
    pub(crate) record: Option<PathBuf>,
    /// `--study DIR`.
    pub study: Option<PathBuf>,
}

/// Every file a session of `args` writes, with the flag that named it (a study's folder: each
/// file the study writes into it). `part_files`: with several moving parts, each part's file name
/// ([`vps_study::files::part_file_names`]): `--record` writes one trace per part
/// ([`part_trace_path`]) and `--study` one folder per part.
fn named_outputs(args: &SessionRequest, part_files: &[String]) -> Vec<(&'static str, PathBuf)> {
    let mut outputs: Vec<(&'static str, PathBuf)> = [
        ("--report", &args.report),
        ("--record", &args.record),
        ("--log-wrenches", &args.bridge.log_wrenches),
    ]
    .into_iter()
    .filter_map(|(flag, path)| Some((flag, path.clone()?)))
    .collect();
    if let (Some(dir), true) = (&args.study, part_files.len() <= 1) {
        outputs.extend(
            vps_study::files::study_paths(dir)
                .into_iter()
                .map(|p| ("--study", p)),
        );
    }
    if part_files.len() > 1 {
        if let Some(record) = &args.record {
            outputs.extend(
                part_files[1..]
                    .iter()
                    .map(|f| ("--record", part_trace_path(record, f))),
            );
        }
        if let Some(dir) = &args.study {
            for f in part_files {
                outputs.extend(
                    vps_study::files::study_paths(&dir.join(f))
                        .into_iter()
                        .map(|p| ("--study", p)),
                );
            }
            outputs.extend(
                vps_study::files::pair_paths(dir)
                    .into_iter()
                    .map(|p| ("--study", p)),
            );
        }
    }
    outputs
}

/// Where the trace of a session's moving part `part_file` (its file name,
/// [`vps_study::files::part_file_names`]) is written beside the first part's trace `record`
/// (`--record`), and read back from by `vps study`: `record`'s stem, a dot, the part's file
/// name, then `record`'s extension (`s.trace` → `s.peg.trace`).
pub fn part_trace_path(record: &Path, part_file: &str) -> PathBuf {
    let stem = record.file_stem().map_or_else(
        || std::ffi::OsString::from("trace"),
        std::ffi::OsStr::to_os_string,
    );
    let mut name = stem;
    name.push(".");
    name.push(part_file);
    if let Some(ext) = record.extension() {
        name.push(".");
        name.push(ext);
    }
    record.with_file_name(name)
}

/// The files a session of `args` reads that its command line names: the scene file, the haptic
/// parameter file and a replayed trace (`--device replay:FILE`).
pub(crate) fn command_line_inputs(args: &SessionRequest) -> Vec<PathBuf> {
    let mut inputs = Vec::new();
    if !args.scene.scene.starts_with("builtin:") {
        inputs.push(PathBuf::from(&args.scene.scene));
    }
    inputs.extend(args.haptic.clone());
    if let Some(trace) = args
        .device
        .as_deref()
        .and_then(|d| d.strip_prefix("replay:"))
    {
        inputs.push(PathBuf::from(trace));
    }
    inputs
}

/// Checks every output of `args` against `inputs` and each other ([`check_outputs`]), making the
/// study's folder (and with several parts each part's in it) first when missing.
pub(crate) fn check_session_outputs(
    args: &SessionRequest,
    inputs: &[PathBuf],
    part_files: &[String],
) -> Result<()> {
    if let Some(dir) = &args.study {
        make_study_dir(dir)?;
        if part_files.len() > 1 {
            for f in part_files {
                make_study_dir(&dir.join(f))?;
            }
        }
    }
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let outputs = named_outputs(args, part_files);
    let outputs: Vec<(&str, &Path)> = outputs.iter().map(|(f, p)| (*f, p.as_path())).collect();
    check_outputs(&outputs, &inputs)
}

/// Makes the study folder `dir` when missing and checks the files a study writes into it
/// against `inputs` ([`check_outputs`]).
pub fn reserve_study_dir(dir: &Path, inputs: &[&Path]) -> Result<()> {
    make_study_dir(dir)?;
    let paths = vps_study::files::study_paths(dir);
    let outputs: Vec<(&str, &Path)> = paths.iter().map(|p| ("--study", p.as_path())).collect();
    check_outputs(&outputs, inputs)
}

/// Makes `dir` (and its parents) unless it is a folder already; fails, naming it, when it is
/// something else.
fn make_study_dir(dir: &Path) -> Result<()> {
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => bail!(
            "--study {}: exists and is not a folder; give a folder (made when missing)",
            dir.display()
        ),
        Err(_) => std::fs::create_dir_all(dir)
            .with_context(|| format!("--study {}: cannot make the folder", dir.display())),
    }
}

impl SessionOutputs {
    /// Checks `--report`, `--record` and `--log-wrenches` of `args` (against the inputs its
    /// command line names and each other).
    pub fn reserve(args: &SessionRequest) -> Result<SessionOutputs> {
        check_session_outputs(args, &command_line_inputs(args), &[])?;
        Ok(SessionOutputs {
            report: args.report.clone(),
            record: args.record.clone(),
            study: args.study.clone(),
        })
    }
}
