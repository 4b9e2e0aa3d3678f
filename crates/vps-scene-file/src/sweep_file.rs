//! The sweep file (`vps sweep --config FILE`, e.g. `configs/sweep.toml`): which scene files to
//! sweep, and over which voxel sizes (mm), voxel widths (bits) and shell methods.
//!
//! [`SweepFile::from_toml_str`] parses and checks the whole file before any work: unknown keys,
//! wrong types, an empty `[[run]]` or method list, empty or non-positive voxel size lists, widths
//! other than 2, 4 or 8 bits and run lengths outside `(0, MAX_SESSION_SECONDS]` are refused with
//! an error naming the file and the field (and the allowed range). Setup-time only: allocates,
//! never blocks (the caller reads the file).

use crate::file::{width_from_bits, ForceModelName, ShellMethodName};
use serde::Deserialize;
use std::path::PathBuf;
use vps_voxmap::VoxelWidth;

/// The longest session (s): 1e7 s, about 116 days; a longer one is a typo or an overflow.
pub const MAX_SESSION_SECONDS: f64 = 1e7;

/// The largest sweep file read, in bytes (1 MiB; the committed one is under 2 KiB).
pub const MAX_SWEEP_FILE_BYTES: u64 = 1 << 20;

/// The default of `reference_points_per_frame`.
pub const DEFAULT_REFERENCE_POINTS_PER_FRAME: usize = 500;

/// The built-in sweep file: `configs/sweep.toml` as built into the binary, used by `vps sweep`
/// without `--config`. Its runs name `scenes/NAME.toml`, read as the built-in scene `NAME`
/// ([`builtin_run_scene`]), so it works from any folder.
pub const BUILTIN_SWEEP_FILE: &str = include_str!("../../../configs/sweep.toml");

/// How errors and reports name [`BUILTIN_SWEEP_FILE`].
pub const BUILTIN_SWEEP_NAME: &str = "the built-in sweep file (configs/sweep.toml)";

/// The scene a run of the built-in sweep file names: `scenes/NAME.toml` is `builtin:NAME` when
/// `NAME` is a built-in scene ([`crate::file::BUILTIN_SCENES`]); `None` for any other path.
pub fn builtin_run_scene(scene: &std::path::Path) -> Option<String> {
    let name = scene
        .strip_prefix("scenes")
        .ok()?
        .to_str()?
        .strip_suffix(".toml")?;
    crate::file::BUILTIN_SCENES
        .iter()
        .any(|(n, _)| *n == name)
        .then(|| format!("builtin:{name}"))
}

/// A sweep file that cannot be used: the message opens with the file.
#[derive(Debug, thiserror::Error)]
pub enum SweepFileError {
    /// Not valid TOML, an unknown key or a wrong type, or a value outside its range: `message`
    /// names the field and what is allowed.
    #[error("{path}: {message}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong (with the field) and what is allowed.
        message: String,
    },
    /// A field outside its range, in the scene file's words (`PATH: field `NAME`: ...`).
    #[error(transparent)]
    Field(#[from] crate::SceneError),
}

/// A checked sweep file.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepFile {
    /// Voxel sizes (mm, each finite and > 0; at least one) for every run that lists none.
    pub voxel_sizes_mm: Vec<f64>,
    /// Shell methods (at least one) for every run that lists none.
    pub methods: Vec<ShellMethodName>,
    /// Voxel widths for every run that lists none; `None`: each scene's own
    /// `voxels.voxel_width`.
    pub widths: Option<Vec<VoxelWidth>>,
    /// Force models for every run that lists none; `None`: each scene's own
    /// `voxels.force_model` (with its own `voxels.standoff`).
    pub force_models: Option<Vec<ForceModelName>>,
    /// Reference cost budget: the exact reference is computed at every Nth touching frame with
    /// N = ceil(shell points / this) (0 counts as 1).
    pub reference_points_per_frame: usize,
    /// The runs (at least one), in file order.
    pub run: Vec<SweepRun>,
}

/// One `[[run]]` of a sweep file: a scene file and, where given, its own lists.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRun {
    /// Scene file, relative to the sweep file.
    pub scene: PathBuf,
    /// Voxel sizes (mm, each finite and > 0; at least one) for this run.
    pub voxel_sizes_mm: Option<Vec<f64>>,
    /// Voxel widths for this run (at least one).
    pub widths: Option<Vec<VoxelWidth>>,
    /// Shell methods for this run (at least one).
    pub methods: Option<Vec<ShellMethodName>>,
    /// Force models for this run (at least one).
    pub force_models: Option<Vec<ForceModelName>>,
    /// Longest session (s, in `(0, MAX_SESSION_SECONDS]`); `None`: the whole script.
    pub seconds: Option<f64>,
}

impl SweepRun {
    /// A run of `scene` with none of its own lists (the sweep's apply).
    pub fn of_scene(scene: PathBuf) -> SweepRun {
        SweepRun {
            scene,
            voxel_sizes_mm: None,
            widths: None,
            methods: None,
            force_models: None,
            seconds: None,
        }
    }
}

/// The file as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Wire {
    voxel_sizes_mm: Vec<f64>,
    methods: Vec<ShellMethodName>,
    widths: Option<Vec<u8>>,
    force_models: Option<Vec<ForceModelName>>,
    #[serde(default = "default_points_per_frame")]
    reference_points_per_frame: usize,
    run: Vec<WireRun>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WireRun {
    scene: PathBuf,
    voxel_sizes_mm: Option<Vec<f64>>,
    widths: Option<Vec<u8>>,
    methods: Option<Vec<ShellMethodName>>,
    force_models: Option<Vec<ForceModelName>>,
    seconds: Option<f64>,
}

fn default_points_per_frame() -> usize {
    DEFAULT_REFERENCE_POINTS_PER_FRAME
}

impl SweepFile {
    /// Parses and checks a sweep file's text; `path` names the file in errors.
    pub fn from_toml_str(text: &str, path: &str) -> Result<SweepFile, SweepFileError> {
        let invalid = |message: String| SweepFileError::Invalid {
            path: path.to_string(),
            message,
        };
        let wire: Wire = toml::from_str(text).map_err(|e| invalid(e.to_string()))?;
        if wire.run.is_empty() || wire.methods.is_empty() {
            return Err(invalid("needs at least one [[run]] and one method".into()));
        }
        check_sizes(&wire.voxel_sizes_mm, "voxel_sizes_mm").map_err(invalid)?;
        if wire.force_models.as_ref().is_some_and(Vec::is_empty) {
            return Err(invalid(
                "force_models is empty (list \"tangent-plane\", \"distance\" or both, or leave \
                 it out for each scene's own)"
                    .into(),
            ));
        }
        let widths = wire
            .widths
            .as_deref()
            .map(|bits| width_list(bits, path, "widths"))
            .transpose()?;
        let mut run = Vec::with_capacity(wire.run.len());
        for (i, r) in wire.run.into_iter().enumerate() {
            if let Some(sizes) = &r.voxel_sizes_mm {
                check_sizes(sizes, &format!("run[{i}].voxel_sizes_mm")).map_err(invalid)?;
            }
            if let Some(seconds) = r.seconds {
                if !(seconds > 0.0 && seconds <= MAX_SESSION_SECONDS) {
                    return Err(invalid(format!(
                        "run[{i}].seconds = {seconds}: a run lasts more than 0 s and at most \
                         {MAX_SESSION_SECONDS:e} s"
                    )));
                }
            }
            if r.methods.as_ref().is_some_and(Vec::is_empty) {
                return Err(invalid(format!("run[{i}].methods is empty")));
            }
            if r.force_models.as_ref().is_some_and(Vec::is_empty) {
                return Err(invalid(format!("run[{i}].force_models is empty")));
            }
            let widths = r
                .widths
                .as_deref()
                .map(|bits| width_list(bits, path, &format!("run[{i}].widths")))
                .transpose()?;
            run.push(SweepRun {
                scene: r.scene,
                voxel_sizes_mm: r.voxel_sizes_mm,
                widths,
                methods: r.methods,
                force_models: r.force_models,
                seconds: r.seconds,
            });
        }
        Ok(SweepFile {
            voxel_sizes_mm: wire.voxel_sizes_mm,
            methods: wire.methods,
            widths,
            force_models: wire.force_models,
            reference_points_per_frame: wire.reference_points_per_frame,
            run,
        })
    }

    /// The voxel sizes (mm) of `run`: its own, else the sweep's.
    pub fn sizes_mm<'a>(&'a self, run: &'a SweepRun) -> &'a [f64] {
        run.voxel_sizes_mm
            .as_deref()
            .unwrap_or(&self.voxel_sizes_mm)
    }

    /// The shell methods of `run`: its own, else the sweep's.
    pub fn methods_of<'a>(&'a self, run: &'a SweepRun) -> &'a [ShellMethodName] {
        run.methods.as_deref().unwrap_or(&self.methods)
    }

    /// The voxel widths of `run`: its own, else the sweep's; `None` when neither lists any (the
    /// scene's own width applies).
    pub fn widths_of<'a>(&'a self, run: &'a SweepRun) -> Option<&'a [VoxelWidth]> {
        run.widths.as_deref().or(self.widths.as_deref())
    }

    /// The force models of `run`: its own, else the sweep's; `None`: the scene's own.
    pub fn force_models_of<'a>(&'a self, run: &'a SweepRun) -> Option<&'a [ForceModelName]> {
        run.force_models.as_deref().or(self.force_models.as_deref())
    }
}

/// Refuses an empty voxel size list or one holding a size that is not a positive length (mm).
fn check_sizes(sizes: &[f64], field: &str) -> Result<(), String> {
    if sizes.is_empty() {
        return Err(format!(
            "{field} is empty: list at least one voxel size (mm, > 0)"
        ));
    }
    if let Some(bad) = sizes.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        return Err(format!(
            "{field} holds {bad}: voxel sizes are lengths in mm, > 0"
        ));
    }
    Ok(())
}

/// A width list: at least one entry, each 2, 4 or 8 (bits).
fn width_list(bits: &[u8], path: &str, field: &str) -> Result<Vec<VoxelWidth>, SweepFileError> {
    if bits.is_empty() {
        return Err(SweepFileError::Invalid {
            path: path.to_string(),
            message: format!("field `{field}` is empty"),
        });
    }
    bits.iter()
        .enumerate()
        .map(|(j, &b)| Ok(width_from_bits(b, path, &format!("{field}[{j}]"))?))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILE: &str = "sweep-test.toml";

    fn parse(text: &str) -> Result<SweepFile, String> {
        SweepFile::from_toml_str(text, FILE).map_err(|e| e.to_string())
    }

    #[test]
    fn the_committed_sweep_file_parses() {
        let text = include_str!("../../../configs/sweep.toml");
        let file = SweepFile::from_toml_str(text, "configs/sweep.toml").unwrap();
        assert!(!file.run.is_empty());
        assert!(file.voxel_sizes_mm.iter().all(|s| *s > 0.0));
    }

    /// Every run of the built-in sweep file is a built-in scene, so `vps sweep` needs no file of
    /// the repository.
    #[test]
    fn the_builtin_sweep_file_names_builtin_scenes() {
        let file = SweepFile::from_toml_str(BUILTIN_SWEEP_FILE, BUILTIN_SWEEP_NAME).unwrap();
        for run in &file.run {
            let scene = builtin_run_scene(&run.scene);
            assert!(scene.is_some(), "{}", run.scene.display());
        }
        assert_eq!(
            builtin_run_scene(std::path::Path::new("scenes/rig-teapot.toml")).as_deref(),
            Some("builtin:rig-teapot")
        );
        assert_eq!(
            builtin_run_scene(std::path::Path::new("scenes/mine.toml")),
            None
        );
        assert_eq!(
            builtin_run_scene(std::path::Path::new("rig-teapot.toml")),
            None
        );
    }

    #[test]
    fn lists_fall_back_to_the_sweeps() {
        let file = parse(
            "voxel_sizes_mm = [10.0]\nmethods = [\"centres\"]\nwidths = [2]\n\
             [[run]]\nscene = \"a.toml\"\n\
             [[run]]\nscene = \"b.toml\"\nvoxel_sizes_mm = [5.0]\nwidths = [4, 8]\n\
             methods = [\"exact\"]\nseconds = 2.5\n",
        )
        .unwrap();
        let (a, b) = (&file.run[0], &file.run[1]);
        assert_eq!(file.sizes_mm(a), &[10.0]);
        assert_eq!(file.sizes_mm(b), &[5.0]);
        assert_eq!(file.widths_of(a), Some(&[VoxelWidth::Two][..]));
        assert_eq!(
            file.widths_of(b),
            Some(&[VoxelWidth::Four, VoxelWidth::Eight][..])
        );
        assert_eq!(file.methods_of(a), &[ShellMethodName::Centres]);
        assert_eq!(file.methods_of(b), &[ShellMethodName::Exact]);
        assert_eq!(b.seconds, Some(2.5));
        assert_eq!(
            file.reference_points_per_frame,
            DEFAULT_REFERENCE_POINTS_PER_FRAME
        );
        let own = parse("voxel_sizes_mm = [1.0]\nmethods = [\"exact\"]\n[[run]]\nscene = \"a\"\n")
            .unwrap();
        assert_eq!(own.widths_of(&own.run[0]), None);
    }

    #[test]
    fn errors_name_the_file_the_field_and_the_range() {
        let head = "methods = [\"centres\"]\n";
        for (text, wants) in [
            (
                format!("voxel_sizes_mm = []\n{head}[[run]]\nscene = \"a\"\n"),
                &["voxel_sizes_mm is empty", "> 0"][..],
            ),
            (
                format!("voxel_sizes_mm = [-1.0]\n{head}[[run]]\nscene = \"a\"\n"),
                &["voxel_sizes_mm holds -1", "> 0"],
            ),
            (
                format!("voxel_sizes_mm = [nan]\n{head}[[run]]\nscene = \"a\"\n"),
                &["voxel_sizes_mm holds NaN"],
            ),
            (
                format!(
                    "voxel_sizes_mm = [1.0]\n{head}[[run]]\nscene = \"a\"\nvoxel_sizes_mm = []\n"
                ),
                &["run[0].voxel_sizes_mm is empty"],
            ),
            (
                format!("voxel_sizes_mm = [1.0]\n{head}[[run]]\nscene = \"a\"\nseconds = -1\n"),
                &["run[0].seconds = -1", "at most 1e7 s"],
            ),
            (
                format!("voxel_sizes_mm = [1.0]\n{head}[[run]]\nscene = \"a\"\nseconds = 1e8\n"),
                &["run[0].seconds = 100000000"],
            ),
            (
                format!("voxel_sizes_mm = [1.0]\n{head}[[run]]\nscene = \"a\"\nwidths = [2, 3]\n"),
                &["run[0].widths[1]", "2, 4 or 8"],
            ),
            (
                format!("voxel_sizes_mm = [1.0]\n{head}widths = []\n[[run]]\nscene = \"a\"\n"),
                &["field `widths` is empty"],
            ),
            (
                format!("voxel_sizes_mm = [1.0]\n{head}[[run]]\nscene = \"a\"\nmethods = []\n"),
                &["run[0].methods is empty"],
            ),
            (
                format!("voxel_sizes_mm = [1.0]\n{head}"),
                &["missing field `run`"],
            ),
            (
                format!("voxel_sizes_mm = [1.0]\n{head}run = []\n"),
                &["at least one [[run]]"],
            ),
            (
                format!("voxel_sizes_mm = [1.0]\n{head}[[run]]\nscene = \"a\"\ncolour = 1\n"),
                &["unknown field `colour`"],
            ),
        ] {
            let err = parse(&text).unwrap_err();
            assert!(err.starts_with(&format!("{FILE}: ")), "{err}");
            assert_eq!(err.matches(FILE).count(), 1, "{err}");
            for want in wants {
                assert!(err.contains(want), "{want:?} not in {err}");
            }
        }
    }
}
