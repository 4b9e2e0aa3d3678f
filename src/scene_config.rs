//! Scene configuration files (TOML): what a standard scene needs declared in one place: the static
//! objects, the part, the corridor the scripted hand threads, the voxel settings and the workspace
//! region the part can reach. See `configs/scenes/*.toml`.

use anyhow::{Context, Result};
use glam::DVec3;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use vps_mesh::{Aabb, TriMesh};
use vps_voxelize::{ShellMethod, VoxelizeOptions};
use vps_voxmap::VoxelWidth;

/// Why a scene file is rejected: always names the file, and the field when one is at fault.
#[derive(Debug, thiserror::Error)]
pub enum SceneConfigError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not valid TOML, or a field is unknown, missing or of the wrong type (the message names it).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The TOML parser's message (line, column, field).
        message: String,
    },
    /// A field has a value outside its range.
    #[error("{path}: field `{field}`: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Dotted field name, e.g. `voxels.voxel_width`.
        field: String,
        /// What is wrong.
        message: String,
    },
}

/// One scene file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneConfig {
    /// Short name used in reports.
    pub name: String,
    /// The dynamic part: `builtin:NAME` or a mesh file (relative to the scene file).
    pub part: String,
    /// Static objects, merged into one voxmap.
    #[serde(rename = "static")]
    pub objects: Vec<StaticObject>,
    /// The scripted hand's path.
    pub corridor: Corridor,
    /// Voxel settings.
    #[serde(default)]
    pub voxels: VoxelSettings,
    /// The region the part can reach (m); only this region is voxelized when given.
    pub workspace: Option<Region>,
}

/// A static object: a mesh source, scaled per axis about its own origin then translated.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StaticObject {
    /// `builtin:NAME` or a mesh file (relative to the scene file).
    pub source: String,
    /// Scale factors per axis (dimensionless), positive. Default `[1, 1, 1]`.
    #[serde(default = "unit_scale")]
    pub scale: [f64; 3],
    /// Translation (m). Default zero.
    #[serde(default)]
    pub translate: [f64; 3],
}

/// The corridor: waypoints every `spacing` from `from` to `to`, walked `laps` times (there and
/// back); the standard session's detours press whatever surface lies within `reach`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Corridor {
    /// First waypoint (m).
    pub from: [f64; 3],
    /// Last waypoint (m).
    pub to: [f64; 3],
    /// Distance between waypoints (m), positive.
    pub spacing: f64,
    /// Walks along the corridor (≥ 1). Default 1.
    #[serde(default = "one")]
    pub laps: usize,
    /// How far a detour looks for a surface (m), positive. Default 0.8.
    #[serde(default = "default_reach")]
    pub reach: f64,
}

/// Voxel settings a scene declares.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VoxelSettings {
    /// Voxel edge (m). Default 0.005.
    pub voxel_size: f64,
    /// Bits per voxel: 2 (kinds only, the paper's format), 4 or 8 (kinds plus distance layers: a
    /// deeper force field, see [`vps_voxmap::LayeredVoxel`]). Default 2. See [`VoxelSettings::width`].
    pub voxel_width: u8,
    /// Force-layer offset in voxel layers (0..=16). Default 2.
    pub offset_layers: u32,
    /// Pre-contact braking. Default true.
    pub braking: bool,
    /// Shell point placement: `centres` or `exact`. Default `centres`.
    pub shell_method: ShellMethodName,
}

/// Shell point placement as written in a scene file.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ShellMethodName {
    /// Voxel centres (the paper).
    Centres,
    /// Exact surface points.
    Exact,
}

impl ShellMethodName {
    /// The voxelizer's method.
    pub fn method(self) -> ShellMethod {
        match self {
            ShellMethodName::Centres => ShellMethod::VoxelCentres,
            ShellMethodName::Exact => ShellMethod::ExactSurface,
        }
    }
}

/// An axis-aligned region (m).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// Minimum corner (m).
    pub min: [f64; 3],
    /// Maximum corner (m), above `min` on every axis.
    pub max: [f64; 3],
}

impl Region {
    /// As a box.
    pub fn aabb(&self) -> Aabb {
        Aabb {
            min: DVec3::from_array(self.min),
            max: DVec3::from_array(self.max),
        }
    }
}

impl Default for VoxelSettings {
    fn default() -> Self {
        Self {
            voxel_size: 0.005,
            voxel_width: 2,
            offset_layers: 2,
            braking: true,
            shell_method: ShellMethodName::Centres,
        }
    }
}

impl VoxelSettings {
    /// The voxmap width of `voxel_width`; errors (naming `path` and the field) unless it is 2, 4 or
    /// 8 bits.
    pub fn width(&self, path: &Path) -> Result<VoxelWidth, SceneConfigError> {
        width_from_bits(self.voxel_width, path, "voxels.voxel_width")
    }

    /// Fails for settings that parse but that this build cannot apply. Every width that
    /// [`VoxelSettings::width`] accepts (2, 4, 8 bits) is applied: the voxmap is built with
    /// [`vps_voxelize::voxelize_tree`] at that width and the kernel reads its distance layers.
    pub fn check_supported(&self, path: &Path) -> Result<(), SceneConfigError> {
        self.width(path).map(|_| ())
    }
}

/// The voxmap width of `bits` (2, 4 or 8); errors name `path` and `field`.
pub fn width_from_bits(bits: u8, path: &Path, field: &str) -> Result<VoxelWidth, SceneConfigError> {
    VoxelWidth::from_bits(u32::from(bits))
        .ok_or_else(|| invalid(path, field, format!("{bits} must be 2, 4 or 8 (bits)")))
}

fn unit_scale() -> [f64; 3] {
    [1.0; 3]
}
fn one() -> usize {
    1
}
fn default_reach() -> f64 {
    0.8
}

fn invalid(path: &Path, field: &str, message: impl Into<String>) -> SceneConfigError {
    SceneConfigError::Invalid {
        path: path.to_path_buf(),
        field: field.to_string(),
        message: message.into(),
    }
}

fn finite3(v: &[f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl SceneConfig {
    /// Parses and validates `text`; `path` names the file in errors.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<SceneConfig, SceneConfigError> {
        let config: SceneConfig = toml::from_str(text).map_err(|e| SceneConfigError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().to_string(),
        })?;
        config.validate(path)?;
        Ok(config)
    }

    /// Reads, parses and validates a scene file.
    pub fn from_file(path: &Path) -> Result<SceneConfig, SceneConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text, path)
    }

    /// Checks every field's range; the error names the first field at fault.
    pub fn validate(&self, path: &Path) -> Result<(), SceneConfigError> {
        let bad = |field: &str, message: String| Err(invalid(path, field, message));
        if self.name.trim().is_empty() {
            return bad("name", "must not be empty".into());
        }
        if self.objects.is_empty() {
            return bad("static", "at least one [[static]] object is needed".into());
        }
        for (i, o) in self.objects.iter().enumerate() {
            if !o.scale.iter().all(|s| s.is_finite() && *s > 0.0) {
                return bad(
                    &format!("static[{i}].scale"),
                    format!("{:?} must be positive and finite", o.scale),
                );
            }
            if !finite3(&o.translate) {
                return bad(&format!("static[{i}].translate"), "must be finite".into());
            }
        }
        let c = &self.corridor;
        if !finite3(&c.from) || !finite3(&c.to) {
            return bad("corridor.from", "corridor ends must be finite".into());
        }
        if !(c.spacing.is_finite() && c.spacing > 0.0) {
            return bad(
                "corridor.spacing",
                format!("{} must be a positive length (m)", c.spacing),
            );
        }
        let length = DVec3::from_array(c.from).distance(DVec3::from_array(c.to));
        if length < c.spacing {
            return bad(
                "corridor.to",
                format!("the corridor ({length} m) is shorter than one spacing"),
            );
        }
        if c.laps == 0 || c.laps > 100 {
            return bad("corridor.laps", format!("{} must be 1..=100", c.laps));
        }
        if !(c.reach.is_finite() && c.reach > 0.0) {
            return bad(
                "corridor.reach",
                format!("{} must be a positive length (m)", c.reach),
            );
        }
        let v = &self.voxels;
        if !(v.voxel_size.is_finite() && v.voxel_size > 0.0) {
            return bad(
                "voxels.voxel_size",
                format!("{} must be a positive length (m)", v.voxel_size),
            );
        }
        v.width(path)?;
        if v.offset_layers > 16 {
            return bad(
                "voxels.offset_layers",
                format!("{} must be 0..=16", v.offset_layers),
            );
        }
        if let Some(r) = &self.workspace {
            let ok = finite3(&r.min) && finite3(&r.max) && (0..3).all(|a| r.min[a] < r.max[a]);
            if !ok {
                return bad(
                    "workspace",
                    format!(
                        "min {:?} must be finite and below max {:?} on every axis",
                        r.min, r.max
                    ),
                );
            }
            for end in [c.from, c.to] {
                if !(0..3).all(|a| r.min[a] <= end[a] && end[a] <= r.max[a]) {
                    return bad(
                        "workspace",
                        format!("corridor end {end:?} lies outside the region"),
                    );
                }
            }
        }
        Ok(())
    }

    /// The voxelizer's options for this scene at `voxel_size` (m) and `width`: the scene's offset
    /// layers, and its workspace region (only that region is voxelized) when it declares one.
    pub fn voxelize_options(&self, voxel_size: f64, width: VoxelWidth) -> VoxelizeOptions {
        VoxelizeOptions {
            voxel_size,
            offset_layers: self.voxels.offset_layers,
            width,
            workspace: self.workspace.as_ref().map(Region::aabb),
            ..VoxelizeOptions::default()
        }
    }

    /// The corridor's waypoints (m).
    pub fn waypoints(&self) -> Vec<DVec3> {
        let (a, b) = (
            DVec3::from_array(self.corridor.from),
            DVec3::from_array(self.corridor.to),
        );
        let n = (a.distance(b) / self.corridor.spacing).round().max(1.0) as usize;
        (0..=n).map(|i| a.lerp(b, i as f64 / n as f64)).collect()
    }

    /// Loads the static objects (scaled and placed, m) and the part; relative file paths are taken
    /// from `base` (the scene file's directory).
    pub fn load_meshes(&self, base: &Path) -> Result<(Vec<TriMesh>, TriMesh)> {
        let resolve = |source: &str| -> String {
            if source.starts_with("builtin:") || Path::new(source).is_absolute() {
                source.to_string()
            } else {
                base.join(source).display().to_string()
            }
        };
        let mut objects = Vec::with_capacity(self.objects.len());
        for (i, o) in self.objects.iter().enumerate() {
            let mut mesh = crate::scene::load(&resolve(&o.source))
                .with_context(|| format!("static[{i}]"))?
                .mesh;
            let (scale, shift) = (DVec3::from_array(o.scale), DVec3::from_array(o.translate));
            mesh.vertices
                .iter_mut()
                .for_each(|v| *v = *v * scale + shift);
            objects.push(mesh);
        }
        let part = crate::scene::load(&resolve(&self.part))
            .context("part")?
            .mesh;
        Ok((objects, part))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "t"
part = "builtin:teapot"
[[static]]
source = "builtin:box"
scale = [4.0, 1.0, 0.5]
[corridor]
from = [0.0, 0.0, 0.1]
to = [0.3, 0.0, 0.1]
spacing = 0.05
[voxels]
voxel_size = 0.005
voxel_width = 2
offset_layers = 2
braking = true
shell_method = "exact"
[workspace]
min = [-0.1, -0.1, -0.1]
max = [0.4, 0.1, 0.2]
"#;

    fn parse(text: &str) -> Result<SceneConfig, SceneConfigError> {
        SceneConfig::from_toml_str(text, Path::new("scene.toml"))
    }

    #[test]
    fn good_file_parses() {
        let c = parse(GOOD).unwrap();
        assert_eq!(c.voxels.shell_method.method(), ShellMethod::ExactSurface);
        assert_eq!(c.waypoints().len(), 7);
        assert!(c.voxels.check_supported(Path::new("x")).is_ok());
        assert_eq!(c.voxels.width(Path::new("x")).unwrap(), VoxelWidth::Two);
        let opts = c.voxelize_options(0.0025, VoxelWidth::Four);
        assert_eq!(opts.width, VoxelWidth::Four);
        assert_eq!(opts.voxel_size, 0.0025);
        assert_eq!(opts.offset_layers, 2);
        assert_eq!(opts.workspace, c.workspace.map(|r| r.aabb()));
    }

    #[test]
    fn errors_name_the_file_and_field() {
        let cases = [
            (
                GOOD.replace("voxel_width = 2", "voxel_width = 3"),
                "voxels.voxel_width",
            ),
            (
                GOOD.replace("voxel_size = 0.005", "voxel_size = -1.0"),
                "voxels.voxel_size",
            ),
            (
                GOOD.replace("spacing = 0.05", "spacing = 0.0"),
                "corridor.spacing",
            ),
            (
                GOOD.replace("max = [0.4, 0.1, 0.2]", "max = [0.4, -0.2, 0.2]"),
                "workspace",
            ),
            (
                GOOD.replace("scale = [4.0, 1.0, 0.5]", "scale = [4.0, 0.0, 0.5]"),
                "static[0].scale",
            ),
            (
                GOOD.replace("braking = true", "braking = true\nbrake = 1"),
                "brake",
            ),
            (
                GOOD.replace("shell_method = \"exact\"", "shell_method = \"dots\""),
                "dots",
            ),
            (GOOD.replace("part = \"builtin:teapot\"\n", ""), "part"),
        ];
        for (text, field) in cases {
            let err = parse(&text).unwrap_err().to_string();
            assert!(err.starts_with("scene.toml"), "{err}");
            assert!(err.contains(field), "{field} not named in: {err}");
        }
        for (bits, width) in [(4, VoxelWidth::Four), (8, VoxelWidth::Eight)] {
            let wide =
                parse(&GOOD.replace("voxel_width = 2", &format!("voxel_width = {bits}"))).unwrap();
            assert!(wide.voxels.check_supported(Path::new("s.toml")).is_ok());
            assert_eq!(wide.voxels.width(Path::new("s.toml")).unwrap(), width);
        }
        let err = width_from_bits(16, Path::new("sweep.toml"), "widths[1]").unwrap_err();
        assert_eq!(
            err.to_string(),
            "sweep.toml: field `widths[1]`: 16 must be 2, 4 or 8 (bits)"
        );
    }
}
