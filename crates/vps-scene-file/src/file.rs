//! The scene file (TOML): one file describes a scene and what sessions on it run with: the static
//! objects, the part, the voxel settings, the workspace region, the haptic parameters, the
//! simulated hand's path and the default device. See `docs/scenes.md` for every key. Parsing
//! rejects unknown keys; every error names the file and the dotted field.

use crate::device_kind::DeviceKind;
use crate::error::{field_error, SceneError};
use crate::length::length;
use glam::{DQuat, DVec3};
use serde::{Deserialize, Deserializer};
use std::path::Path;
use vps_mesh::Aabb;
use vps_voxelize::ShellMethod;
use vps_voxmap::VoxelWidth;

/// The most waypoints a path may have, after a corridor is expanded (count × laps).
pub const MAX_WAYPOINTS: usize = 100_000;

/// The largest scene file read, in bytes: room for [`MAX_WAYPOINTS`] written inline with their
/// rotations. A larger file is refused before it is read, naming its size and this bound.
pub const MAX_SCENE_FILE_BYTES: u64 = 64 * vps_files::MIB;

/// How far a corridor's detours look for a surface (m) unless the scene says otherwise.
pub const DEFAULT_DETOUR_REACH: f64 = 0.8;

/// One scene file, as written (parsed by [`SceneFile::from_toml_str`]).
#[derive(Clone, Debug)]
pub struct SceneFile {
    /// Short name used in reports; default: the file's stem.
    pub name: Option<String>,
    /// The dynamic part (required): `part = "SOURCE"`, a `[part]` table, or the first of several
    /// `[[part]]` tables.
    pub part: PartSpec,
    /// The first part's name (`name` in its `[[part]]` table), if given.
    pub part_name: Option<String>,
    /// The second and later `[[part]]`s, each with its own hand or device (empty: one part).
    pub more_parts: Vec<MovingPartSpec>,
    /// Static objects (at least one), merged into one voxmap.
    pub objects: Vec<StaticObject>,
    /// The simulated hand's path: grip positions visited in order.
    pub hand: Option<HandPath>,
    /// The standard scripted session along a corridor, with detours into contact.
    pub corridor: Option<Corridor>,
    /// Voxel settings.
    pub voxels: VoxelSettings,
    /// The region the part can reach (m); only this region is voxelized when given.
    pub workspace: Option<Region>,
    /// Haptic parameters: the keys of `configs/haptic.toml` inline, or `file = "haptic.toml"`.
    pub haptic: Option<toml::Table>,
    /// The scene's default device.
    pub device: Option<DeviceSection>,
}

/// Length units of a mesh file.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
pub enum Units {
    /// Metres (the default).
    #[default]
    #[serde(rename = "m")]
    Metres,
    /// Centimetres.
    #[serde(rename = "cm")]
    Centimetres,
    /// Millimetres.
    #[serde(rename = "mm")]
    Millimetres,
    /// Inches.
    #[serde(rename = "in")]
    Inches,
}

impl std::str::FromStr for Units {
    type Err = String;

    /// The names a scene file's `units` takes: `m`, `cm`, `mm`, `in`.
    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "m" => Ok(Units::Metres),
            "cm" => Ok(Units::Centimetres),
            "mm" => Ok(Units::Millimetres),
            "in" => Ok(Units::Inches),
            _ => Err(format!("`{text}`: allowed m, cm, mm, in")),
        }
    }
}

impl Units {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            Units::Metres => 1.0,
            Units::Centimetres => 0.01,
            Units::Millimetres => 0.001,
            Units::Inches => 0.0254,
        }
    }
}

/// The part: a mesh source and how it is placed in its own frame.
#[derive(Clone, Debug, PartialEq)]
pub struct PartSpec {
    /// `builtin:NAME` or a mesh file (relative to the scene file).
    pub source: String,
    /// Units of the mesh file. Default metres.
    pub units: Units,
    /// Scale factors per axis (dimensionless, within [`SCALE_RANGE`]) about the mesh's origin,
    /// after units. Default `[1, 1, 1]`; a scene file may write one number for all three.
    pub scale: [f64; 3],
    /// Rotation of the mesh (degrees): about X, then Y, then Z, after scaling. Default none.
    pub rotate_deg: [f64; 3],
    /// Where the handle holds the part (m), in part coordinates after units, scale and rotation.
    /// Default: the centre of mass.
    pub grip: Option<[f64; 3]>,
    /// STEP sources only: the solids to read, by name (default all).
    pub solids: Option<Vec<String>>,
    /// STEP sources only: the largest distance between a triangle and the exact surface (m).
    /// Default a quarter of the voxel size.
    pub chord_tolerance: Option<f64>,
}

/// One moving part as a scene file writes it: `part = "SOURCE"`, a `[part]` table, or one of
/// several `[[part]]` tables (each may carry `name`, a `[part.hand]` path and a `[part.device]`).
#[derive(Clone, Debug, PartialEq)]
pub struct MovingPartSpec {
    /// The part's name in reports (default: its source's file stem).
    pub name: Option<String>,
    /// The mesh and its placement in the part's frame.
    pub part: PartSpec,
    /// Its simulated hand's path (the session starts at rest at its first waypoint; one waypoint
    /// holds the part still).
    pub hand: Option<HandPath>,
    /// Its device (default: the simulated hand on `hand`).
    pub device: Option<DeviceSection>,
}

impl MovingPartSpec {
    fn of_source(source: &str) -> MovingPartSpec {
        MovingPartSpec {
            name: None,
            part: PartSpec {
                source: source.to_string(),
                units: Units::Metres,
                scale: unit_scale(),
                rotate_deg: [0.0; 3],
                grip: None,
                solids: None,
                chord_tolerance: None,
            },
            hand: None,
            device: None,
        }
    }
}

/// A `[part]` or `[[part]]` table.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PartTable {
    name: Option<String>,
    source: String,
    #[serde(default)]
    units: Units,
    #[serde(default = "unit_scale", deserialize_with = "scale_factors")]
    scale: [f64; 3],
    #[serde(default)]
    rotate_deg: [f64; 3],
    grip: Option<[f64; 3]>,
    solids: Option<Vec<String>>,
    #[serde(default, deserialize_with = "optional_length")]
    chord_tolerance: Option<f64>,
    hand: Option<HandPath>,
    device: Option<DeviceSection>,
}

impl From<PartTable> for MovingPartSpec {
    fn from(t: PartTable) -> MovingPartSpec {
        MovingPartSpec {
            name: t.name,
            part: PartSpec {
                source: t.source,
                units: t.units,
                scale: t.scale,
                rotate_deg: t.rotate_deg,
                grip: t.grip,
                solids: t.solids,
                chord_tolerance: t.chord_tolerance,
            },
            hand: t.hand,
            device: t.device,
        }
    }
}

/// `part = "SOURCE"`, a `[part]` table or `[[part]]` tables.
fn part_specs<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<MovingPartSpec>, D::Error> {
    struct Visitor;
    impl<'de> serde::de::Visitor<'de> for Visitor {
        type Value = Vec<MovingPartSpec>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a mesh source string, a [part] table or [[part]] tables")
        }
        fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Self::Value, E> {
            Ok(vec![MovingPartSpec::of_source(v)])
        }
        fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<Self::Value, A::Error> {
            let t = PartTable::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
            Ok(vec![t.into()])
        }
        fn visit_seq<A: serde::de::SeqAccess<'de>>(
            self,
            mut seq: A,
        ) -> Result<Self::Value, A::Error> {
            let mut parts = Vec::new();
            while let Some(t) = seq.next_element::<PartTable>()? {
                if parts.len() == MAX_PARTS {
                    return Err(serde::de::Error::custom(format!(
                        "more than {MAX_PARTS} [[part]] tables"
                    )));
                }
                parts.push(t.into());
            }
            Ok(parts)
        }
    }
    d.deserialize_any(Visitor)
}

impl<'de> Deserialize<'de> for PartField {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        part_specs(d).map(PartField)
    }
}

/// The moving parts in any of their written forms.
struct PartField(Vec<MovingPartSpec>);

/// A static object: a mesh source in `units`, scaled per axis, rotated, then translated.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StaticObject {
    /// `builtin:NAME` or a mesh file (relative to the scene file).
    pub source: String,
    /// Units of the mesh file. Default metres.
    #[serde(default)]
    pub units: Units,
    /// Scale factors per axis (dimensionless, within [`SCALE_RANGE`]), about the mesh's origin,
    /// after units. Default `[1, 1, 1]`; a scene file may write one number for all three.
    #[serde(default = "unit_scale", deserialize_with = "scale_factors")]
    pub scale: [f64; 3],
    /// Rotation (degrees): about X, then Y, then Z, after scaling. Default none.
    #[serde(default)]
    pub rotate_deg: [f64; 3],
    /// Translation (m), applied last. Default zero.
    #[serde(default)]
    pub translate: [f64; 3],
    /// STEP sources only: the solids to read, by name (default all).
    #[serde(default)]
    pub solids: Option<Vec<String>>,
    /// STEP sources only: the largest distance between a triangle and the exact surface (m).
    /// Default a quarter of the voxel size.
    #[serde(default, deserialize_with = "optional_length")]
    pub chord_tolerance: Option<f64>,
}

/// The simulated hand's path: grip positions (m) visited in order at `speed`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HandPath {
    /// Grip positions (m), at least one; the session starts at rest at the first.
    pub waypoints: Vec<[f64; 3]>,
    /// Speed along the path (m/s), in (0, 10]. Default 0.1.
    #[serde(default = "default_speed")]
    pub speed: f64,
    /// Pause at every waypoint (s), in [0, 60]. Default 0.2.
    #[serde(default = "default_hold")]
    pub hold_s: f64,
}

/// The corridor: waypoints every `spacing` from `from` to `to`, walked `laps` times (there and
/// back); the standard session's detours press whatever surface lies within `reach`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Corridor {
    /// First waypoint (m).
    pub from: [f64; 3],
    /// Last waypoint (m).
    pub to: [f64; 3],
    /// Distance between waypoints (m), positive.
    #[serde(deserialize_with = "length")]
    pub spacing: f64,
    /// Walks along the corridor, 1..=100. Default 1.
    #[serde(default = "one")]
    pub laps: usize,
    /// How far a detour looks for a surface (m), positive. Default 0.8.
    #[serde(default = "default_reach", deserialize_with = "length")]
    pub reach: f64,
}

/// Voxel settings a scene declares, with the built-in defaults ([`VoxelSettings::default`]) for
/// the keys it leaves out.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelSettings {
    /// Voxel edge (m), a number or a string with a unit (`"2mm"`). Default 0.005.
    pub voxel_size: f64,
    /// Bits per voxel: 2 (kinds only, the paper's format), 4 or 8 (kinds plus distance layers).
    /// Default 4 ([`RECOMMENDED_VOXEL_WIDTH`]: the sweep's recommendation; 2 is the paper's).
    pub voxel_width: u8,
    /// Force-layer offset in voxel layers (0..=16). Default 2.
    pub offset_layers: u32,
    /// Pre-contact braking; when absent the haptic parameters decide (default on).
    pub braking: Option<bool>,
    /// Shell point placement: `centres` (the paper's) or `exact`. Default `exact`
    /// ([`RECOMMENDED_SHELL_METHOD`]: the sweep's recommendation).
    pub shell_method: ShellMethodName,
    /// The force model: `tangent-plane` (the paper's, on the voxel layers) or `distance` (the
    /// signed-distance band with a stand-off). Default `distance` ([`RECOMMENDED_FORCE_MODEL`]:
    /// the sweep's recommendation).
    pub force_model: ForceModelName,
    /// The `distance` model's stand-off (m): contact starts this far from the exact surface.
    /// `0..=` one voxel; `None`: half the voxel size
    /// ([`vps_voxmap::distance::DEFAULT_STANDOFF_VOXELS`]). Refused with `tangent-plane`.
    pub standoff: Option<f64>,
    /// Why the scene file chose its voxel settings (`voxels.reason`, 1..=500 characters), shown by
    /// `vps scene check`; `None` when the file gives none.
    pub reason: Option<String>,
    /// Which keys the scene file set; the others hold the built-in defaults.
    pub set_in_file: VoxelKeysSet,
}

/// Which `[voxels]` keys a scene file set (false: the built-in default,
/// [`BUILTIN_VOXELS_REASON`] says why it is what it is).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VoxelKeysSet {
    /// `voxels.voxel_size`.
    pub voxel_size: bool,
    /// `voxels.voxel_width`.
    pub voxel_width: bool,
    /// `voxels.offset_layers`.
    pub offset_layers: bool,
    /// `voxels.shell_method`.
    pub shell_method: bool,
    /// `voxels.force_model`.
    pub force_model: bool,
}

/// The built-in `voxels.voxel_width` (bits): 4, the sweep's recommendation (docs/sweep.md). The
/// paper's format is 2 (`voxel_width = 2`).
pub const RECOMMENDED_VOXEL_WIDTH: u8 = 4;

/// The built-in `voxels.shell_method`: exact-surface points, the sweep's recommendation
/// (docs/sweep.md). The paper's is `shell_method = "centres"`.
pub const RECOMMENDED_SHELL_METHOD: ShellMethodName = ShellMethodName::Exact;

/// The built-in `voxels.force_model`: the signed-distance band, the sweep's recommendation
/// (docs/sweep.md). The paper's is `force_model = "tangent-plane"`.
pub const RECOMMENDED_FORCE_MODEL: ForceModelName = ForceModelName::Distance;

/// Why the built-in voxel defaults (5 mm, 4-bit, offset 2, exact-surface points, the distance
/// model) are what they are, for a scene file that leaves the keys out; `vps scene check` shows
/// it.
pub const BUILTIN_VOXELS_REASON: &str = "the sweep's recommendation (docs/sweep.md): the distance model keeps every shell point outside the exact scene (penetration ratio 0, a stand-off of half a voxel) with a smaller force direction error than the paper's tangent-plane model on both standard scenes; 4-bit voxels with exact-surface shell points kept penetration ratio 0 at every swept size with either model; 5 mm voxels and 2 offset layers; for the paper's method set voxels.force_model = \"tangent-plane\", voxels.voxel_width = 2 and voxels.shell_method = \"centres\"";

impl Default for VoxelSettings {
    fn default() -> Self {
        Self {
            voxel_size: 0.005,
            voxel_width: RECOMMENDED_VOXEL_WIDTH,
            offset_layers: 2,
            braking: None,
            shell_method: RECOMMENDED_SHELL_METHOD,
            force_model: RECOMMENDED_FORCE_MODEL,
            standoff: None,
            reason: None,
            set_in_file: VoxelKeysSet::default(),
        }
    }
}

/// `[voxels]` as written: every key optional (see [`VoxelSettings`]).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct VoxelsWire {
    #[serde(default, deserialize_with = "optional_length")]
    voxel_size: Option<f64>,
    voxel_width: Option<u8>,
    offset_layers: Option<u32>,
    braking: Option<bool>,
    shell_method: Option<ShellMethodName>,
    force_model: Option<ForceModelName>,
    #[serde(default, deserialize_with = "optional_length")]
    standoff: Option<f64>,
    reason: Option<String>,
}

fn optional_length<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    length(d).map(Some)
}

impl VoxelsWire {
    fn into_settings(self) -> VoxelSettings {
        let d = VoxelSettings::default();
        VoxelSettings {
            set_in_file: VoxelKeysSet {
                voxel_size: self.voxel_size.is_some(),
                voxel_width: self.voxel_width.is_some(),
                offset_layers: self.offset_layers.is_some(),
                shell_method: self.shell_method.is_some(),
                force_model: self.force_model.is_some(),
            },
            voxel_size: self.voxel_size.unwrap_or(d.voxel_size),
            voxel_width: self.voxel_width.unwrap_or(d.voxel_width),
            offset_layers: self.offset_layers.unwrap_or(d.offset_layers),
            braking: self.braking,
            shell_method: self.shell_method.unwrap_or(d.shell_method),
            force_model: self.force_model.unwrap_or(d.force_model),
            standoff: self.standoff,
            reason: self.reason,
        }
    }
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

/// The force model as written in a scene file (`voxels.force_model`).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ForceModelName {
    /// The paper's tangent-plane model on the voxel layers (offset layers set the stand-off).
    TangentPlane,
    /// The signed-distance band: exact sub-voxel distances and the scene's own normals, with a
    /// stand-off in metres (`voxels.standoff`).
    Distance,
}

impl ForceModelName {
    /// `tangent-plane` or `distance`, as written.
    pub fn name(self) -> &'static str {
        match self {
            ForceModelName::TangentPlane => "tangent-plane",
            ForceModelName::Distance => "distance",
        }
    }
}

impl VoxelSettings {
    /// The stand-off (m) at `voxel_size` (m) for the `distance` model, `None` for the
    /// tangent-plane model: `voxels.standoff`, else half the voxel.
    pub fn standoff_at(&self, voxel_size: f64) -> Option<f64> {
        match self.force_model {
            ForceModelName::TangentPlane => None,
            ForceModelName::Distance => Some(
                self.standoff
                    .unwrap_or(voxel_size * vps_voxmap::distance::DEFAULT_STANDOFF_VOXELS),
            ),
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

/// The scene's default device.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DeviceSection {
    /// `sim`, `spacemouse`, `bridge[:ADDR]` or `replay:FILE` (relative to the scene file).
    /// Default `sim`.
    #[serde(default = "default_device")]
    pub kind: String,
    /// How the bridge's device frame maps into the scene and forces back (`scale`, `rotate_deg`,
    /// `offset`, `force_scale`; ranges checked where the bridge's settings are made, in
    /// `vps-session`). Used when the device is the bridge. Default: the identity.
    pub mapping: Option<MappingSection>,
    /// A bridge device silent this long is held with zero output and re-anchored when it resumes
    /// (ms, in [2, 10000]). Used when the device is the bridge. Default 50.
    pub pose_timeout_ms: Option<f64>,
    /// The largest force ever sent to the device (N, in (0, 1e4]), whatever the device. Default 15
    /// (the paper's device). The device layer owns this limit: the loop saturates every wrench to
    /// it before writing (replaces the haptic parameter `device_max_force`).
    pub max_force: Option<f64>,
    /// The largest torque ever sent to the device (N·m, in (0, 1e3]). Default 0.1 (replaces the
    /// haptic parameter `device_max_torque`).
    pub max_torque: Option<f64>,
}

/// A `[device.mapping]` table as written: each key left out takes the bridge's default (the
/// identity).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MappingSection {
    /// Scene metres per device metre.
    pub scale: Option<f64>,
    /// Rotation from device axes to scene axes, degrees about X, Y, Z (X applied first).
    pub rotate_deg: Option<[f64; 3]>,
    /// Scene position of the device's origin (m).
    pub offset: Option<[f64; 3]>,
    /// Device force per scene force (also applied to torques).
    pub force_scale: Option<f64>,
}

fn unit_scale() -> [f64; 3] {
    [1.0; 3]
}

/// The range of each `scale` factor of `[part]` and `[[static]]` (dimensionless).
pub const SCALE_RANGE: std::ops::RangeInclusive<f64> = 1e-6..=1e6;

/// `scale = 2.5` (the same factor on every axis) or `scale = [x, y, z]`; ranges are checked by
/// [`SceneFile::validate`].
fn scale_factors<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Written {
        Uniform(f64),
        PerAxis([f64; 3]),
    }
    match Written::deserialize(d).map_err(|_| {
        serde::de::Error::custom("a number or an array of three numbers [x, y, z] is expected")
    })? {
        Written::Uniform(s) => Ok([s; 3]),
        Written::PerAxis(s) => Ok(s),
    }
}

/// An error unless every factor of `scale` is within [`SCALE_RANGE`].
fn check_scale(path: &str, field: &str, scale: &[f64; 3]) -> Result<(), SceneError> {
    if scale.iter().all(|s| SCALE_RANGE.contains(s)) {
        return Ok(());
    }
    Err(field_error(
        path,
        field,
        format!(
            "{scale:?}: each factor must be within [{:e}, {:e}]",
            SCALE_RANGE.start(),
            SCALE_RANGE.end()
        ),
    ))
}
fn one() -> usize {
    1
}
fn default_reach() -> f64 {
    DEFAULT_DETOUR_REACH
}
fn default_speed() -> f64 {
    0.1
}
fn default_hold() -> f64 {
    0.2
}
fn default_device() -> String {
    "sim".into()
}

/// The voxmap width of `bits` (2, 4 or 8); errors name `path` and `field`.
pub fn width_from_bits(bits: u8, path: &str, field: &str) -> Result<VoxelWidth, SceneError> {
    VoxelWidth::from_bits(u32::from(bits))
        .ok_or_else(|| field_error(path, field, format!("{bits} must be 2, 4 or 8 (bits)")))
}

/// The rotation of `rotate_deg`: about X first, then Y, then Z (degrees).
pub fn rotation(rotate_deg: [f64; 3]) -> DQuat {
    let [x, y, z] = rotate_deg.map(f64::to_radians);
    DQuat::from_rotation_z(z) * DQuat::from_rotation_y(y) * DQuat::from_rotation_x(x)
}

/// The most `[` and `{` a scene file may hold (arrays, tables and array-of-table headers, the
/// characters counted wherever they are): what 100,000 waypoints and 10,000 objects need and more,
/// so that the parser's memory is bounded (about 80 MB for this many empty arrays).
pub const MAX_ARRAYS_AND_TABLES: usize = 400_000;

/// The deepest nesting of arrays and inline tables a scene file may have (`waypoints = [[x, y,
/// z]]` is 2 deep): below the TOML parser's own recursion limit (80), so that a file nested
/// 100,000 deep is refused by [`scan_structure`] naming the line, before the parser sees it.
pub const MAX_NESTING: usize = 32;

/// The most TOML tokens a scene file may hold (keys, values, punctuation, a run of spaces, a
/// string or a comment each count one; the count is an upper bound of the parser's). The parser
/// holds two 24-32 byte records per token before it builds anything: 4,000,000 tokens bound that
/// at about 250 MB, where a 63 MiB file of commas would take about 4 GB. 100,000 waypoints
/// written one to a line and 10,000 objects need about 2,000,000.
pub const MAX_TOKENS: usize = 4_000_000;

/// What [`scan_structure`] found over a bound: the message (without the file's name).
fn structure_error(what: String, line: usize) -> String {
    format!("{what}; the limit is passed on line {line}")
}

/// A cheap pass over a scene file's text before the TOML parser sees it: the nesting of arrays
/// and inline tables (outside strings and comments) within [`MAX_NESTING`] and the count of
/// tokens within [`MAX_TOKENS`]. Err names the bound, the limit and the line where it is passed.
/// Strings and comments are skipped as the TOML lexer does (basic strings with `\` escapes,
/// literal strings, their multi-line forms); an unterminated one ends the pass (the parser then
/// reports it).
pub fn scan_structure(text: &str) -> Result<(), String> {
    let b = text.as_bytes();
    let (mut i, mut line, mut depth, mut tokens) = (0usize, 1usize, 0usize, 0usize);
    // The index just past the end of a string opened at `i` by `quote` (1 or 3 bytes), counting
    // the line breaks inside it; `b.len()` when it never ends.
    let skip_string = |mut i: usize, quote: &[u8], escapes: bool, line: &mut usize| -> usize {
        i += quote.len();
        while i < b.len() {
            if b[i..].starts_with(quote) {
                return i + quote.len();
            }
            match b[i] {
                // The escaped byte is skipped (a line break after `\` in a multi-line string).
                b'\\' if escapes => {
                    i += 1;
                    if b.get(i) == Some(&b'\n') {
                        *line += 1;
                    }
                }
                b'\n' if quote.len() == 1 => return i,
                b'\n' => *line += 1,
                _ => {}
            }
            i += 1;
        }
        b.len()
    };
    while i < b.len() {
        tokens += 1;
        if tokens > MAX_TOKENS {
            return Err(structure_error(
                format!(
                    "more than {MAX_TOKENS} TOML tokens (keys, values, punctuation), the limit for \
                     a scene file ({MAX_WAYPOINTS} waypoints and 10000 objects need about \
                     2000000)"
                ),
                line,
            ));
        }
        match b[i] {
            b'#' => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'"' if b[i..].starts_with(b"\"\"\"") => {
                i = skip_string(i, b"\"\"\"", true, &mut line);
            }
            b'\'' if b[i..].starts_with(b"'''") => i = skip_string(i, b"'''", false, &mut line),
            b'"' => i = skip_string(i, b"\"", true, &mut line),
            b'\'' => i = skip_string(i, b"'", false, &mut line),
            b'[' | b'{' => {
                depth += 1;
                if depth > MAX_NESTING {
                    return Err(structure_error(
                        format!(
                            "arrays and inline tables nested more than {MAX_NESTING} deep, the \
                             limit for a scene file (waypoints need 2)"
                        ),
                        line,
                    ));
                }
                i += 1;
            }
            b']' | b'}' => {
                depth = depth.saturating_sub(1);
                i += 1;
            }
            b'\n' => {
                line += 1;
                i += 1;
            }
            b' ' | b'\t' => {
                while i < b.len() && matches!(b[i], b' ' | b'\t') {
                    i += 1;
                }
            }
            c if c.is_ascii_alphanumeric() || matches!(c, b'_' | b'-' | b'+') => {
                while i < b.len()
                    && (b[i].is_ascii_alphanumeric() || matches!(b[i], b'_' | b'-' | b'+'))
                {
                    i += 1;
                }
            }
            _ => i += 1,
        }
    }
    Ok(())
}

/// The largest coordinate (m) of a position or translation in a scene file: 1000 km. Far beyond
/// any scene a haptic device explores, and small enough that no distance, radius or time computed
/// from such positions overflows (a grip of 1e300 m gave an infinite `max_radius`, a waypoint of
/// 1e308 m a non-finite time, in the session, after `vps scene check` said ok).
pub const MAX_COORDINATE_M: f64 = 1e6;

/// The longest time (s) a `[hand]` path may take (waypoint to waypoint at `speed`): about 11.6
/// days. `speed = 1e-300` gave a 300-digit time.
pub const MAX_PATH_SECONDS: f64 = 1e6;

/// Finite and every coordinate within ±[`MAX_COORDINATE_M`].
fn position3(v: &[f64; 3]) -> bool {
    v.iter()
        .all(|x| x.is_finite() && x.abs() <= MAX_COORDINATE_M)
}

/// The error text of a position that is not [`position3`].
fn position_message(v: &[f64; 3]) -> String {
    format!("{v:?} must be finite and within ±{MAX_COORDINATE_M} m of the origin on every axis (m)")
}

/// A count for a message: whole below 10^9, else in scientific notation (a spacing of 1e-300 m
/// gave a 180-digit count).
fn count_text(n: f64) -> String {
    if n < 1e9 {
        format!("{n:.0}")
    } else {
        format!("{n:.2e}")
    }
}

/// Checks a hand path (`prefix` names it in errors: `hand`, `part[1].hand`).
fn validate_hand(path: &str, prefix: &str, h: &HandPath) -> Result<(), SceneError> {
    let bad = |field: &str, message: String| {
        Err(field_error(path, &format!("{prefix}.{field}"), message))
    };
    if h.waypoints.is_empty() || h.waypoints.len() > MAX_WAYPOINTS {
        return bad(
            "waypoints",
            format!(
                "{} waypoints; 1..={MAX_WAYPOINTS} are allowed",
                h.waypoints.len()
            ),
        );
    }
    if let Some(i) = h.waypoints.iter().position(|w| !position3(w)) {
        return bad(
            &format!("waypoints[{i}]"),
            position_message(&h.waypoints[i]),
        );
    }
    if !(h.speed.is_finite() && h.speed > 0.0 && h.speed <= 10.0) {
        return bad("speed", format!("{:?} must be in (0, 10] m/s", h.speed));
    }
    let length: f64 = h
        .waypoints
        .windows(2)
        .map(|w| DVec3::from_array(w[0]).distance(DVec3::from_array(w[1])))
        .sum();
    let seconds = length / h.speed;
    if seconds > MAX_PATH_SECONDS {
        return bad(
            "speed",
            format!(
                "{:?} m/s over the {length:.3} m of the waypoints takes {seconds:.3e} s; at \
                 most {MAX_PATH_SECONDS:.0e} s is allowed (use a larger speed)",
                h.speed
            ),
        );
    }
    if !(h.hold_s.is_finite() && (0.0..=60.0).contains(&h.hold_s)) {
        return bad("hold_s", format!("{:?} must be in [0, 60] s", h.hold_s));
    }
    Ok(())
}

/// Most moving parts a scene may hold.
pub const MAX_PARTS: usize = 8;

/// Rotations beyond this many degrees are refused as a likely typo (radians for degrees are fine).
const MAX_ROTATION_DEG: f64 = 3600.0;

impl SceneFile {
    /// Parses and validates `text`; `path` names the file in errors.
    pub fn from_toml_str(text: &str, path: &str) -> Result<SceneFile, SceneError> {
        // The parser holds every array and table of the file: counted first, so that a file of
        // millions of empty arrays is refused before it is parsed (a 63 MiB one peaked at 8.7 GB).
        let opened = text.bytes().filter(|b| matches!(b, b'[' | b'{')).count();
        if opened > MAX_ARRAYS_AND_TABLES {
            // The line where the limit is passed: where the file must be cut.
            let at = text
                .bytes()
                .enumerate()
                .filter(|(_, b)| matches!(b, b'[' | b'{'))
                .nth(MAX_ARRAYS_AND_TABLES)
                .map_or(0, |(i, _)| i);
            let line = text.as_bytes()[..at]
                .iter()
                .filter(|&&b| b == b'\n')
                .count()
                + 1;
            return Err(SceneError::Syntax {
                path: path.to_string(),
                message: format!(
                    "{opened} arrays and tables (`[` and `{{`, counted in strings too), over the \
                     limit of {MAX_ARRAYS_AND_TABLES} for a scene file ({MAX_WAYPOINTS} waypoints \
                     and 10000 objects need about 150000); the limit is passed on line {line}"
                ),
            });
        }
        // Nesting and token count: the parser's own vectors grow with the tokens (a 63 MiB file
        // of commas), and its recursion limit's error echoed a 600 KB line.
        scan_structure(text).map_err(|message| SceneError::Syntax {
            path: path.to_string(),
            message,
        })?;
        let de = toml::Deserializer::parse(text).map_err(|e| SceneError::Syntax {
            path: path.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let file: Wire = serde_path_to_error::deserialize(de).map_err(|e| {
            let field = e.path().to_string();
            let message = e.inner().message().trim_end().to_string();
            if field == "." || field.is_empty() {
                SceneError::Syntax {
                    path: path.to_string(),
                    message,
                }
            } else {
                let line = e
                    .inner()
                    .span()
                    .and_then(|span| text.get(..span.start))
                    .map(|before| before.matches('\n').count() + 1);
                SceneError::Field {
                    path: path.to_string(),
                    line,
                    field,
                    message,
                }
            }
        })?;
        let file = file.into_scene(path)?;
        file.validate(path)?;
        Ok(file)
    }

    /// Reads, parses and validates a scene file (a regular file of at most
    /// [`MAX_SCENE_FILE_BYTES`]).
    pub fn from_file(path: &Path) -> Result<SceneFile, SceneError> {
        let label = path.display().to_string();
        let text =
            vps_files::read_regular_to_string(path, MAX_SCENE_FILE_BYTES).map_err(|source| {
                SceneError::Read {
                    path: label.clone(),
                    source,
                }
            })?;
        Self::from_toml_str(&text, &label)
    }

    /// The voxmap width of `voxels.voxel_width`.
    pub fn width(&self, path: &str) -> Result<VoxelWidth, SceneError> {
        width_from_bits(self.voxels.voxel_width, path, "voxels.voxel_width")
    }

    /// Checks a part's fields (`prefix` names it in errors: `part`, `part[1]`).
    fn validate_part(&self, path: &str, prefix: &str, part: &PartSpec) -> Result<(), SceneError> {
        check_source(path, &format!("{prefix}.source"), &part.source)?;
        check_step(
            path,
            prefix,
            StepFields {
                source: &part.source,
                units: part.units,
                solids: part.solids.as_deref(),
                chord_tolerance: part.chord_tolerance,
                voxel_size: self.voxels.voxel_size,
            },
        )?;
        check_scale(path, &format!("{prefix}.scale"), &part.scale)?;
        check_rotation(path, &format!("{prefix}.rotate_deg"), &part.rotate_deg)?;
        if let Some(g) = &part.grip {
            if !position3(g) {
                return Err(field_error(
                    path,
                    &format!("{prefix}.grip"),
                    position_message(g),
                ));
            }
        }
        Ok(())
    }

    /// Checks the second and later `[[part]]`s: each has a hand or a device, names are unique.
    fn validate_more_parts(&self, path: &str) -> Result<(), SceneError> {
        if self.more_parts.len() + 1 > MAX_PARTS {
            return Err(field_error(
                path,
                "part",
                format!(
                    "{} [[part]] tables; at most {MAX_PARTS} are allowed",
                    self.more_parts.len() + 1
                ),
            ));
        }
        if !self.more_parts.is_empty() && self.corridor.is_some() {
            return Err(field_error(
                path,
                "corridor",
                "a scene of several [[part]]s drives each by its own [part.hand] or \
                 [part.device]; a [corridor] is for one part",
            ));
        }
        let mut names: Vec<&str> = self.part_name.as_deref().into_iter().collect();
        // Bridge ports given explicitly (port 0 picks a free one): one per part.
        let port_of = |choice: Option<DeviceKind>| match choice {
            Some(DeviceKind::Bridge(addr)) if addr.port() != 0 => Some(addr),
            _ => None,
        };
        let first = self
            .device
            .as_ref()
            .and_then(|d| DeviceKind::parse(&d.kind).ok());
        let mut bridges: Vec<std::net::SocketAddr> = port_of(first).into_iter().collect();
        for (k, m) in self.more_parts.iter().enumerate() {
            let prefix = format!("part[{}]", k + 1);
            self.validate_part(path, &prefix, &m.part)?;
            if let Some(name) = &m.name {
                if name.trim().is_empty() || name.chars().count() > 100 {
                    return Err(field_error(
                        path,
                        &format!("{prefix}.name"),
                        "must be 1..=100 characters, not blank",
                    ));
                }
                if names.contains(&name.as_str()) {
                    return Err(field_error(
                        path,
                        &format!("{prefix}.name"),
                        format!("'{name}' names another part too; part names must differ"),
                    ));
                }
                names.push(name);
            }
            let Some(h) = &m.hand else {
                return Err(field_error(
                    path,
                    &format!("{prefix}.hand"),
                    "each [[part]] after the first needs a [part.hand] path: where it starts \
                     (its first waypoint) and, for the simulated hand, where it goes (one \
                     waypoint holds it still)",
                ));
            };
            validate_hand(path, &format!("{prefix}.hand"), h)?;
            let mut choice = None;
            if let Some(d) = &m.device {
                choice = Some(DeviceKind::parse(&d.kind).map_err(|message| {
                    field_error(path, &format!("{prefix}.device.kind"), message)
                })?);
            }
            if let Some(addr) = port_of(choice) {
                if bridges.contains(&addr) {
                    return Err(field_error(
                        path,
                        &format!("{prefix}.device.kind"),
                        format!(
                            "bridge {addr} drives another part too: each part's bridge needs its \
                             own port (or port 0, a free one)"
                        ),
                    ));
                }
                bridges.push(addr);
            }
        }
        Ok(())
    }

    /// Checks every field's range; the error names the first field at fault.
    pub fn validate(&self, path: &str) -> Result<(), SceneError> {
        let bad = |field: &str, message: String| Err(field_error(path, field, message));
        if let Some(name) = &self.name {
            if name.trim().is_empty() || name.len() > 200 {
                return bad("name", "must be 1..=200 characters".into());
            }
        }
        self.validate_part(path, "part", &self.part)?;
        self.validate_more_parts(path)?;
        if self.objects.is_empty() {
            return bad("static", "at least one [[static]] object is needed".into());
        }
        if self.objects.len() > 10_000 {
            return bad("static", "at most 10000 [[static]] objects".into());
        }
        for (i, o) in self.objects.iter().enumerate() {
            check_source(path, &format!("static[{i}].source"), &o.source)?;
            check_step(
                path,
                &format!("static[{i}]"),
                StepFields {
                    source: &o.source,
                    units: o.units,
                    solids: o.solids.as_deref(),
                    chord_tolerance: o.chord_tolerance,
                    voxel_size: self.voxels.voxel_size,
                },
            )?;
            check_scale(path, &format!("static[{i}].scale"), &o.scale)?;
            check_rotation(path, &format!("static[{i}].rotate_deg"), &o.rotate_deg)?;
            if !position3(&o.translate) {
                return bad(
                    &format!("static[{i}].translate"),
                    position_message(&o.translate),
                );
            }
        }
        match (&self.hand, &self.corridor) {
            (None, None) => {
                return bad(
                    "hand",
                    "a [hand] path (waypoints, speed) or a [corridor] is needed".into(),
                )
            }
            (Some(_), Some(_)) => {
                return bad(
                    "corridor",
                    "give a [hand] path or a [corridor], not both".into(),
                )
            }
            _ => {}
        }
        if let Some(h) = &self.hand {
            validate_hand(path, "hand", h)?;
        }
        if let Some(c) = &self.corridor {
            self.validate_corridor(path, c)?;
        }
        let v = &self.voxels;
        if !(v.voxel_size.is_finite() && v.voxel_size > 0.0 && v.voxel_size <= 10.0) {
            return bad(
                "voxels.voxel_size",
                format!("{:?} must be a positive length up to 10 m", v.voxel_size),
            );
        }
        self.width(path)?;
        if let Some(standoff) = v.standoff {
            let max = v.voxel_size * vps_voxmap::distance::MAX_STANDOFF_VOXELS;
            if v.force_model != ForceModelName::Distance {
                return bad(
                    "voxels.standoff",
                    "applies to force_model = \"distance\" only (the tangent-plane model's stand-off is offset_layers voxels)".into(),
                );
            }
            if !(standoff.is_finite() && (0.0..=max).contains(&standoff)) {
                return bad(
                    "voxels.standoff",
                    format!(
                        "{standoff} m must be within 0..={max} m (one voxel_size, {} m)",
                        v.voxel_size
                    ),
                );
            }
        }
        if v.offset_layers > 16 {
            return bad(
                "voxels.offset_layers",
                format!("{} must be 0..=16", v.offset_layers),
            );
        }
        if let Some(reason) = &v.reason {
            let n = reason.chars().count();
            if reason.trim().is_empty() || n > 500 {
                return bad(
                    "voxels.reason",
                    format!("{n} characters; 1..=500 (not blank) are allowed"),
                );
            }
        }
        if let Some(r) = &self.workspace {
            let ok = position3(&r.min) && position3(&r.max) && (0..3).all(|a| r.min[a] < r.max[a]);
            if !ok {
                return bad(
                    "workspace",
                    format!(
                        "min {:?} must be below max {:?} on every axis, both finite and within \
                         ±{MAX_COORDINATE_M} m of the origin",
                        r.min, r.max
                    ),
                );
            }
            let inside = |p: &[f64; 3]| (0..3).all(|a| r.min[a] <= p[a] && p[a] <= r.max[a]);
            let ends: Vec<(String, [f64; 3])> = match (&self.corridor, &self.hand) {
                (Some(c), _) => vec![
                    ("corridor.from".into(), c.from),
                    ("corridor.to".into(), c.to),
                ],
                (None, Some(h)) => h
                    .waypoints
                    .iter()
                    .enumerate()
                    .map(|(i, w)| (format!("hand.waypoints[{i}]"), *w))
                    .collect(),
                (None, None) => Vec::new(),
            };
            if let Some((field, p)) = ends.iter().find(|(_, p)| !inside(p)) {
                return bad(
                    field,
                    format!(
                        "{p:?} lies outside the [workspace] region {:?}..{:?}",
                        r.min, r.max
                    ),
                );
            }
        }
        if let Some(d) = &self.device {
            DeviceKind::parse(&d.kind)
                .map_err(|message| field_error(path, "device.kind", message))?;
        }
        Ok(())
    }

    fn validate_corridor(&self, path: &str, c: &Corridor) -> Result<(), SceneError> {
        let bad = |field: &str, message: String| Err(field_error(path, field, message));
        if !position3(&c.from) {
            return bad("corridor.from", position_message(&c.from));
        }
        if !position3(&c.to) {
            return bad("corridor.to", position_message(&c.to));
        }
        if !(c.spacing.is_finite() && c.spacing > 0.0) {
            return bad(
                "corridor.spacing",
                format!("{:?} must be a positive length (m)", c.spacing),
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
        let count = (length / c.spacing).floor() + 2.0;
        if count * c.laps as f64 > MAX_WAYPOINTS as f64 {
            return bad(
                "corridor.spacing",
                format!(
                    "{:?} m over {length:.3} m and {} lap(s) gives {} waypoints per lap; at most \
                     {MAX_WAYPOINTS} in all are allowed (use a larger spacing)",
                    c.spacing,
                    c.laps,
                    count_text(count)
                ),
            );
        }
        if !(c.reach.is_finite() && c.reach > 0.0 && c.reach <= 1000.0) {
            return bad(
                "corridor.reach",
                format!("{:?} must be a positive length up to 1000 m", c.reach),
            );
        }
        Ok(())
    }

    /// The corridor's waypoints (m): `from + dir × spacing × i` for every whole spacing along the
    /// corridor, then `to` unless the last step already reached it. Empty without a corridor.
    /// Bounded by [`MAX_WAYPOINTS`] (checked by [`SceneFile::validate`]).
    pub fn corridor_waypoints(&self) -> Vec<DVec3> {
        let Some(c) = &self.corridor else {
            return Vec::new();
        };
        let (a, b) = (DVec3::from_array(c.from), DVec3::from_array(c.to));
        let length = a.distance(b);
        let dir = (b - a) / length;
        let n = ((length / c.spacing) + 1e-9).floor() as usize;
        let mut points: Vec<DVec3> = (0..=n).map(|i| a + dir * (c.spacing * i as f64)).collect();
        if points
            .last()
            .is_some_and(|last| last.distance(b) > c.spacing * 1e-6)
        {
            points.push(b);
        }
        points
    }
}

fn check_source(path: &str, field: &str, source: &str) -> Result<(), SceneError> {
    if source.trim().is_empty() {
        return Err(field_error(
            path,
            field,
            "must name a mesh file (.stl, .obj, .ply, .step, .stp) or builtin:NAME",
        ));
    }
    Ok(())
}

/// The finest chord tolerance a STEP source may ask for (m): 1 µm.
pub const MIN_CHORD_TOLERANCE: f64 = 1e-6;
/// The most solid names one object may select.
pub const MAX_SOLID_NAMES: usize = 1000;

/// Whether `source` names a STEP file: what the mesh loader reads as one (`.step` / `.stp`, any
/// case, [`vps_mesh::MeshFormat::from_path`]).
pub fn is_step_source(source: &str) -> bool {
    matches!(
        vps_mesh::MeshFormat::from_path(Path::new(source)),
        Ok(vps_mesh::MeshFormat::Step)
    )
}

/// The STEP-related fields of one object (`part` or `static[i]`).
struct StepFields<'a> {
    source: &'a str,
    units: Units,
    solids: Option<&'a [String]>,
    chord_tolerance: Option<f64>,
    voxel_size: f64,
}

/// `solids` and `chord_tolerance` apply to STEP sources only, a STEP source takes its unit from
/// the file (no `units`), the tolerance lies within [`MIN_CHORD_TOLERANCE`] ..= the voxel size,
/// and each selected name is non-empty.
fn check_step(path: &str, object: &str, f: StepFields<'_>) -> Result<(), SceneError> {
    let bad =
        |key: &str, message: String| Err(field_error(path, &format!("{object}.{key}"), message));
    if !is_step_source(f.source) {
        if f.solids.is_some() {
            return bad(
                "solids",
                "applies to STEP sources (.step, .stp) only".into(),
            );
        }
        if f.chord_tolerance.is_some() {
            return bad(
                "chord_tolerance",
                "applies to STEP sources (.step, .stp) only".into(),
            );
        }
        return Ok(());
    }
    if f.units != Units::Metres {
        return bad(
            "units",
            "a STEP file carries its own length unit (read from the file): remove `units`".into(),
        );
    }
    if let Some(t) = f.chord_tolerance {
        if !(t.is_finite() && (MIN_CHORD_TOLERANCE..=f.voxel_size).contains(&t)) {
            return bad(
                "chord_tolerance",
                format!(
                    "must be within {} mm ..= the voxel size ({} mm), got {} mm",
                    MIN_CHORD_TOLERANCE * 1e3,
                    f.voxel_size * 1e3,
                    t * 1e3
                ),
            );
        }
    }
    if let Some(names) = f.solids {
        if names.is_empty() || names.len() > MAX_SOLID_NAMES {
            return bad(
                "solids",
                format!("must list 1..={MAX_SOLID_NAMES} solid names (omit it to read all)"),
            );
        }
        if let Some(i) = names.iter().position(|n| n.trim().is_empty()) {
            return bad("solids", format!("name {i} is empty"));
        }
    }
    Ok(())
}

fn check_rotation(path: &str, field: &str, r: &[f64; 3]) -> Result<(), SceneError> {
    if !r
        .iter()
        .all(|a| a.is_finite() && a.abs() <= MAX_ROTATION_DEG)
    {
        return Err(field_error(
            path,
            field,
            format!("{r:?} must be finite angles within ±{MAX_ROTATION_DEG} degrees"),
        ));
    }
    Ok(())
}

/// The scene files built into the binary, by name (`builtin:NAME`).
pub const BUILTIN_SCENES: [(&str, &str); 2] = [
    (
        "bay-teapot",
        include_str!("../../../configs/scenes/bay-teapot.toml"),
    ),
    (
        "rig-teapot",
        include_str!("../../../configs/scenes/rig-teapot.toml"),
    ),
];

/// The file as parsed, before `part`'s two forms are unified.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Wire {
    name: Option<String>,
    part: PartField,
    #[serde(rename = "static")]
    objects: Vec<StaticObject>,
    hand: Option<HandPath>,
    corridor: Option<Corridor>,
    #[serde(default)]
    voxels: VoxelsWire,
    workspace: Option<Region>,
    haptic: Option<toml::Table>,
    device: Option<DeviceSection>,
}

impl Wire {
    /// The scene: the first part's own `[part.hand]` / `[part.device]` become the scene's
    /// `hand` / `device` (where the top-level tables are not also given).
    fn into_scene(self, path: &str) -> Result<SceneFile, SceneError> {
        let mut parts = self.part.0.into_iter();
        let Some(first) = parts.next() else {
            return Err(field_error(
                path,
                "part",
                "at least one [[part]] table is needed",
            ));
        };
        let hand = match (first.hand, self.hand) {
            (Some(_), Some(_)) => {
                return Err(field_error(
                    path,
                    "hand",
                    "the first part has its own [part.hand]; give it once",
                ))
            }
            (own, top) => own.or(top),
        };
        let device = match (first.device, self.device) {
            (Some(_), Some(_)) => {
                return Err(field_error(
                    path,
                    "device",
                    "the first part has its own [part.device]; give it once",
                ))
            }
            (own, top) => own.or(top),
        };
        Ok(SceneFile {
            name: self.name,
            part: first.part,
            part_name: first.name,
            more_parts: parts.collect(),
            objects: self.objects,
            hand,
            corridor: self.corridor,
            voxels: self.voxels.into_settings(),
            workspace: self.workspace,
            haptic: self.haptic,
            device,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vps_testkit::scene_edit::{bad_scenes, SceneEdit};

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

    fn parse(text: &str) -> Result<SceneFile, SceneError> {
        SceneFile::from_toml_str(text, "scene.toml")
    }

    #[test]
    fn good_file_parses_in_both_part_forms() {
        let c = parse(GOOD).unwrap();
        assert_eq!(c.voxels.shell_method.method(), ShellMethod::ExactSurface);
        assert_eq!(c.corridor_waypoints().len(), 7);
        assert_eq!(c.width("x").unwrap(), VoxelWidth::Two);
        assert_eq!(c.part.source, "builtin:teapot");
        let table = GOOD.replace(
            "part = \"builtin:teapot\"\n",
            "[part]\nsource = \"builtin:teapot\"\nunits = \"mm\"\nrotate_deg = [-90, 0, 0]\ngrip = [0, 0, 0.01]\n",
        );
        let c = parse(&table).unwrap();
        assert_eq!(c.part.units, Units::Millimetres);
        assert_eq!(c.part.rotate_deg, [-90.0, 0.0, 0.0]);
        assert_eq!(c.part.grip, Some([0.0, 0.0, 0.01]));
        assert_eq!(c.part.scale, [1.0; 3], "no scale: unscaled");
        let per_axis = table.replace("units = \"mm\"", "units = \"mm\"\nscale = [2, 1, 0.5]");
        assert_eq!(parse(&per_axis).unwrap().part.scale, [2.0, 1.0, 0.5]);
        let uniform = table.replace("units = \"mm\"", "units = \"mm\"\nscale = 2.5");
        assert_eq!(parse(&uniform).unwrap().part.scale, [2.5; 3]);
        let statics = parse(&GOOD.replace("scale = [4.0, 1.0, 0.5]", "scale = 3")).unwrap();
        assert_eq!(statics.objects[0].scale, [3.0; 3]);
        let mm = parse(&GOOD.replace("voxel_size = 0.005", "voxel_size = \"2mm\"")).unwrap();
        assert!((mm.voxels.voxel_size - 0.002).abs() < 1e-15);
    }

    /// The keys a file sets are told apart from the built-in defaults, and its reason is kept.
    #[test]
    fn voxel_keys_left_out_take_the_builtin_defaults() {
        let c = parse(GOOD).unwrap();
        let set = c.voxels.set_in_file;
        assert!(set.voxel_size && set.voxel_width && set.offset_layers && set.shell_method);
        assert_eq!(c.voxels.reason, None);
        let sparse = GOOD
            .replace("voxel_width = 2\n", "")
            .replace("shell_method = \"exact\"\n", "reason = \"measured\"\n");
        let c = parse(&sparse).unwrap();
        let set = c.voxels.set_in_file;
        assert!(set.voxel_size && !set.voxel_width && set.offset_layers && !set.shell_method);
        let builtin = VoxelSettings::default();
        assert_eq!(c.voxels.voxel_width, builtin.voxel_width);
        assert_eq!(c.voxels.shell_method, builtin.shell_method);
        assert_eq!(c.voxels.reason.as_deref(), Some("measured"));
        let blank = GOOD.replace("shell_method = \"exact\"\n", "reason = \" \"\n");
        let err = parse(&blank).unwrap_err().to_string();
        assert!(err.contains("`voxels.reason`"), "{err}");
        // Every built-in scene file states all its voxel settings and why.
        for (name, text) in BUILTIN_SCENES {
            let v = SceneFile::from_toml_str(text, name).unwrap().voxels;
            let set = v.set_in_file;
            assert!(
                set.voxel_size && set.voxel_width && set.offset_layers && set.shell_method,
                "{name}"
            );
            assert!(v.reason.is_some(), "{name}");
        }
    }

    #[test]
    fn corridor_waypoints_step_from_the_start() {
        // The built-in bay's corridor: 0.05 + 0.1 i, bit for bit (the demo's figures depend on it).
        let bay = SceneFile::from_toml_str(BUILTIN_SCENES[0].1, "bay").unwrap();
        let points = bay.corridor_waypoints();
        assert_eq!(points.len(), 30);
        for (i, p) in points.iter().enumerate() {
            assert_eq!(p.x, 0.05 + 0.1 * i as f64);
            assert_eq!((p.y, p.z), (1.0, 0.75));
        }
    }

    /// An error the TOML parser can place gives the line: `scene.toml:LINE: field ...`.
    #[test]
    fn a_misspelt_or_mistyped_key_names_its_line() {
        let typo = GOOD.replace("offset_layers = 2", "offset_layer = 2");
        let err = parse(&typo).unwrap_err().to_string();
        assert!(
            err.starts_with("scene.toml:14: field `voxels.offset_layer`: unknown field"),
            "{err}"
        );
        let wrong_type = GOOD.replace("braking = true", "braking = \"yes\"");
        let err = parse(&wrong_type).unwrap_err().to_string();
        assert!(
            err.starts_with("scene.toml:15: field `voxels.braking`"),
            "{err}"
        );
        // A range checked after parsing has no line.
        let err = parse(&GOOD.replace("voxel_width = 2", "voxel_width = 3"))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("scene.toml: field `voxels.voxel_width`"),
            "{err}"
        );
    }

    /// A length written as a string needs a unit: `"5"` is refused (likely meant mm), while the
    /// number `5` (metres) and `"5mm"` are read as documented.
    #[test]
    fn a_length_string_without_a_unit_is_refused() {
        let bare = GOOD.replace("voxel_size = 0.005", "voxel_size = \"5\"");
        let err = parse(&bare).unwrap_err().to_string();
        assert!(
            err.contains("field `voxels.voxel_size`") && err.contains("\"5\" has no unit"),
            "{err}"
        );
        let spacing = GOOD.replace("spacing = 0.05", "spacing = \"0.05\"");
        let err = parse(&spacing).unwrap_err().to_string();
        assert!(err.contains("field `corridor.spacing`"), "{err}");
        let mm = parse(&GOOD.replace("voxel_size = 0.005", "voxel_size = \"5mm\"")).unwrap();
        assert!((mm.voxels.voxel_size - 0.005).abs() < 1e-15);
    }

    #[test]
    fn errors_name_the_file_and_field() {
        let replaced = [
            SceneEdit {
                from: "voxel_width = 2",
                to: "voxel_width = 3",
                field: "`voxels.voxel_width`",
            },
            SceneEdit {
                from: "voxel_size = 0.005",
                to: "voxel_size = -1.0",
                field: "`voxels.voxel_size`",
            },
            SceneEdit {
                from: "voxel_size = 0.005",
                to: "voxel_size = \"fast\"",
                field: "`voxels.voxel_size`",
            },
            SceneEdit {
                from: "spacing = 0.05",
                to: "spacing = 0.0",
                field: "`corridor.spacing`",
            },
            SceneEdit {
                from: "spacing = 0.05",
                to: "spacing = 1e-9",
                field: "`corridor.spacing`",
            },
            SceneEdit {
                from: "max = [0.4, 0.1, 0.2]",
                to: "max = [0.4, -0.2, 0.2]",
                field: "`workspace`",
            },
            SceneEdit {
                from: "scale = [4.0, 1.0, 0.5]",
                to: "scale = [4.0, 0.0, 0.5]",
                field: "`static[0].scale`",
            },
            SceneEdit {
                from: "scale = [4.0, 1.0, 0.5]",
                to: "scale = [4.0, 1e300, 0.5]",
                field: "`static[0].scale`",
            },
            SceneEdit {
                from: "scale = [4.0, 1.0, 0.5]",
                to: "scale = \"big\"",
                field: "`static[0].scale`",
            },
            SceneEdit {
                from: "part = \"builtin:teapot\"\n",
                to: "[part]\nsource = \"x.stl\"\nscale = [1, 1e-9, 1]\n",
                field: "`part.scale`",
            },
            SceneEdit {
                from: "scale = [4.0, 1.0, 0.5]",
                to: "units = \"mmm\"",
                field: "`static[0].units`",
            },
            SceneEdit {
                from: "braking = true",
                to: "braking = true\nbrake = 1",
                field: "brake",
            },
            SceneEdit {
                from: "braking = true",
                to: "braking = 1",
                field: "`voxels.braking`",
            },
            SceneEdit {
                from: "shell_method = \"exact\"",
                to: "shell_method = \"dots\"",
                field: "dots",
            },
            SceneEdit {
                from: "part = \"builtin:teapot\"\n",
                to: "",
                field: "part",
            },
            SceneEdit {
                from: "part = \"builtin:teapot\"\n",
                to: "[part]\nsource = \"x.stl\"\ngrp = [0, 0, 0]\n",
                field: "grp",
            },
            SceneEdit {
                from: "[corridor]",
                to: "[hand]\nwaypoints = []\n[corridor]",
                field: "corridor",
            },
        ];
        // (appended, field): the scene with `appended` after it names `field`.
        let appended = [
            ("\n[device]\nkind = \"joystick\"\n", "`device.kind`"),
            ("\n[device]\n[device.mapping]\nscael = 2.0\n", "scael"),
            (
                "\n[device]\n[device.mapping]\noffset = [0.0, 1.0]\n",
                "`device.mapping.offset`",
            ),
        ];
        for (text, field) in bad_scenes(GOOD, &replaced, &appended) {
            let err = parse(&text).unwrap_err().to_string();
            assert!(err.starts_with("scene.toml"), "{err}");
            assert!(err.contains(field), "{field} not named in: {err}");
        }
        let err = width_from_bits(16, "sweep.toml", "widths[1]").unwrap_err();
        assert_eq!(
            err.to_string(),
            "sweep.toml: field `widths[1]`: 16 must be 2, 4 or 8 (bits)"
        );
    }

    /// Issue 36 item 6: a file of millions of empty arrays is refused before it is parsed,
    /// naming the count and the limit; a file of the largest legal corridor's size is not.
    #[test]
    fn a_file_of_millions_of_arrays_is_refused_before_parsing() {
        let text = format!("x = [{}]\n", "[],".repeat(MAX_ARRAYS_AND_TABLES));
        let err = parse(&text).unwrap_err().to_string();
        assert!(
            err.starts_with("scene.toml") && err.contains("400001 arrays and tables"),
            "{err}"
        );
        // Half the arrays on line 3, the rest on line 4: the limit is passed on line 4.
        let half = "[],".repeat(MAX_ARRAYS_AND_TABLES / 2);
        let text = format!("a = 1\n\nx = [{half}]\ny = [{half}[]]\n");
        let err = parse(&text).unwrap_err().to_string();
        assert!(err.contains("the limit is passed on line 4"), "{err}");
        let waypoints = vec!["[0.0, 0.0, 0.1]"; MAX_WAYPOINTS].join(", ");
        let big = GOOD.replace(
            "[corridor]\nfrom = [0.0, 0.0, 0.1]\nto = [0.3, 0.0, 0.1]\nspacing = 0.05\n",
            &format!("[hand]\nwaypoints = [{waypoints}]\n"),
        );
        assert_ne!(big, GOOD);
        parse(&big).unwrap();
    }

    /// Issue 36 item 6: nesting past [`MAX_NESTING`] and a file of more than [`MAX_TOKENS`]
    /// tokens are refused before parsing, naming the file, the limit and the line; brackets in
    /// strings and comments are not nesting, and a multi-line string's lines are counted.
    #[test]
    fn deep_nesting_and_too_many_tokens_are_refused_before_parsing_naming_the_line() {
        let depth = 100_000;
        let text = format!(
            "a = 1\nname = {}{}\n",
            "[ ".repeat(depth),
            "] ".repeat(depth)
        );
        let err = parse(&text).unwrap_err().to_string();
        assert!(
            err.starts_with("scene.toml")
                && err.contains(&format!("nested more than {MAX_NESTING} deep"))
                && err.contains("the limit is passed on line 2"),
            "{err}"
        );
        assert!(err.len() < 400, "{err}");
        let at_limit = format!("x = {}{}", "[".repeat(MAX_NESTING), "]".repeat(MAX_NESTING));
        scan_structure(&at_limit).unwrap();
        let over = format!(
            "x = {}{}",
            "{".repeat(MAX_NESTING + 1),
            "}".repeat(MAX_NESTING + 1)
        );
        assert!(scan_structure(&over).is_err());

        let brackets = "[".repeat(10 * MAX_NESTING);
        let quoted = format!(
            "a = \"{brackets}\\\"{brackets}\"\nb = '{brackets}'\n# {brackets}\nc = \"\"\"\n{brackets}\n\
             \"\"\"\nd = '''{brackets}\n'''\n"
        );
        scan_structure(&quoted).unwrap();
        let after_strings = format!("{quoted}e = {}\n", "[".repeat(MAX_NESTING + 1));
        assert!(
            scan_structure(&after_strings)
                .unwrap_err()
                .ends_with("passed on line 9"),
            "{after_strings}"
        );

        let commas = format!("a = 1\n\nx = [1{}]\n", ",".repeat(MAX_TOKENS));
        let err = parse(&commas).unwrap_err().to_string();
        assert!(
            err.starts_with("scene.toml")
                && err.contains(&format!("more than {MAX_TOKENS} TOML tokens"))
                && err.contains("the limit is passed on line 3"),
            "{err}"
        );
    }

    /// Issue 36 items 7 and 10: positions so far out that the session's radius or times overflow
    /// are refused naming the key and the bound; a spacing of 1e-300 m is refused without a
    /// 180-digit waypoint count.
    #[test]
    fn absurd_positions_and_spacings_are_refused_with_short_messages() {
        for (from, to, field) in [
            (
                "from = [0.0, 0.0, 0.1]",
                "from = [1e300, 0.0, 0.1]",
                "`corridor.from`",
            ),
            ("spacing = 0.05", "spacing = 1e-300", "`corridor.spacing`"),
            (
                "max = [0.4, 0.1, 0.2]",
                "max = [1e306, 0.1, 0.2]",
                "`workspace`",
            ),
        ] {
            assert!(GOOD.contains(from), "{from}");
            let err = parse(&GOOD.replace(from, to)).unwrap_err().to_string();
            assert!(err.contains(field), "{field} not named in: {err}");
            assert!(err.len() < 400, "{err}");
            assert!(
                !err.contains("00000000000000000000"),
                "a 20-digit number in: {err}"
            );
        }
        let err = parse(&GOOD.replace("spacing = 0.05", "spacing = 1e-300"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("gives 3.00e299 waypoints per lap"), "{err}");
    }

    #[test]
    fn rotation_turns_x_then_y_then_z() {
        let q = rotation([90.0, 90.0, 0.0]);
        // X first: +Y goes to +Z; then Y: +Z goes to +X.
        let v = q * DVec3::Y;
        assert!((v - DVec3::X).length() < 1e-12, "{v}");
    }

    /// Two `[[part]]` tables on a floor: the left a 40 mm box on its own hand, the right the
    /// built-in sphere on its own hand (one waypoint) and its own bridge device.
    fn two_parts() -> String {
        use vps_testkit::parts::approach;
        vps_testkit::parts::two_parts(
            "source = \"builtin:sphere\"",
            |side| {
                if side < 0.0 {
                    format!("[part.hand]\n{}\n", approach(side))
                } else {
                    "[part.hand]\nwaypoints = [[0.06, 0.0, 0.0]]\n\
                     [part.device]\nkind = \"bridge:127.0.0.1:7701\"\n"
                        .to_string()
                }
            },
            "",
        )
    }

    #[test]
    fn several_parts_each_with_its_own_hand_or_device() {
        let file = parse(&two_parts()).unwrap();
        assert_eq!(file.part.source, "builtin:box");
        assert_eq!(file.part.scale, [0.4; 3]);
        assert_eq!(file.part_name.as_deref(), Some("left"));
        assert_eq!(
            file.hand.as_ref().map(|h| h.waypoints.len()),
            Some(2),
            "the first part's hand is the scene's"
        );
        assert_eq!(file.more_parts.len(), 1);
        let right = &file.more_parts[0];
        assert_eq!(right.name.as_deref(), Some("right"));
        assert_eq!(right.part.source, "builtin:sphere");
        assert_eq!(
            right.hand.as_ref().unwrap().waypoints,
            vec![[0.06, 0.0, 0.0]]
        );
        assert_eq!(right.device.as_ref().unwrap().kind, "bridge:127.0.0.1:7701");
        // The one-part forms give no other parts.
        assert!(parse(GOOD).unwrap().more_parts.is_empty());
    }

    #[test]
    fn mistakes_in_several_parts_are_named() {
        let base = two_parts();
        let second = "[[part]]\nname = \"right\"";
        let cases: Vec<(String, &str, &str)> = vec![
            (
                base.replace(
                    "[part.hand]\nwaypoints = [[0.06, 0.0, 0.0]]\n",
                    "",
                ),
                "part[1].hand",
                "needs a [part.hand]",
            ),
            (
                base.replace("name = \"right\"", "name = \"left\""),
                "part[1].name",
                "names another part",
            ),
            (
                format!("{base}[hand]\nwaypoints = [[0.0, 0.0, 0.0]]\n"),
                "hand",
                "give it once",
            ),
            (
                base.replace("bridge:127.0.0.1:7701", "joystick"),
                "part[1].device.kind",
                "expected sim",
            ),
            (
                base.replace(
                    "source = \"builtin:box\"\nscale = 0.4\n",
                    "source = \"builtin:box\"\nscale = 0.4\n[part.device]\nkind = \"bridge:127.0.0.1:7701\"\n",
                ),
                "part[1].device.kind",
                "drives another part too",
            ),
            (
                base.replace(second, &format!("{second}\ncolour = \"red\"")),
                "part",
                "unknown field",
            ),
            (
                base.replace("[[0.06, 0.0, 0.0]]", "[[0.06, 0.0, 1e9]]"),
                "part[1].hand.waypoints[0]",
                "",
            ),
            (
                format!(
                    "{base}[corridor]\nfrom = [0.0, 0.0, 0.1]\nto = [0.1, 0.0, 0.1]\nspacing = 0.05\n"
                ),
                "corridor",
                "for one part",
            ),
            (
                format!(
                    "{base}{}",
                    "[[part]]\nsource = \"builtin:box\"\n[part.hand]\nwaypoints = [[0.0, 0.0, 0.0]]\n"
                        .repeat(MAX_PARTS - 1)
                ),
                "part",
                "more than 8",
            ),
        ];
        for (text, field, words) in cases {
            assert_ne!(text, base, "{field}: the edit left the scene as it was");
            let err = parse(&text).unwrap_err();
            let message = err.to_string();
            match &err {
                SceneError::Field { field: f, .. } => assert!(
                    f.starts_with(field),
                    "expected field {field}, got {f}: {message}"
                ),
                other => panic!("expected a field error at {field}, got {other}"),
            }
            assert!(message.contains(words), "{field}: {message}");
        }
    }
}
