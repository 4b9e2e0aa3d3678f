//! Haptic parameters: validated, TOML-loadable, with gains derived from the stability bound of
//! [`crate::stability`] when not given.

use crate::stability::{
    coupling_step_ratio, stability_index, COUPLING_TO_FIELD, SPHERE_INERTIA_FACTOR,
    STABILITY_MARGIN,
};
use std::path::Path;

/// An invalid parameter set or an unreadable parameter file.
#[derive(Debug, thiserror::Error)]
pub enum ParamsError {
    /// The file could not be read.
    #[error("cannot read haptic parameters from {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The TOML is malformed, has an unknown key or a value of the wrong type.
    #[error("{source_name}: {message}")]
    Toml {
        /// Where the text came from (file name or a label).
        source_name: String,
        /// The parser's message, with line and column.
        message: String,
    },
    /// A field has a value outside its range.
    #[error("{source_name}: haptic parameter `{field}` = {value} is invalid: {reason}")]
    Invalid {
        /// Where the parameters came from.
        source_name: String,
        /// The field's TOML key.
        field: &'static str,
        /// The offending value.
        value: f64,
        /// The rule it breaks, with the allowed range and unit.
        reason: String,
    },
    /// A key that is no longer a haptic parameter (see [`MOVED_KEYS`]).
    #[error(
        "{source_name}: `{key}` is no longer a haptic parameter; the device limit is set in {new}"
    )]
    Moved {
        /// Where the parameters came from.
        source_name: String,
        /// The old key.
        key: &'static str,
        /// Where the setting lives now.
        new: &'static str,
    },
}

/// The allowed range of one numeric haptic parameter: `lo < value ≤ hi` (`lo ≤ value ≤ hi` when
/// `lo_included`), in `unit`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamRange {
    /// The TOML key.
    pub field: &'static str,
    /// The lower bound.
    pub lo: f64,
    /// Whether `lo` itself is allowed.
    pub lo_included: bool,
    /// The upper bound (included).
    pub hi: f64,
    /// The SI unit, for messages.
    pub unit: &'static str,
}

impl ParamRange {
    /// True when `value` is finite and in the range.
    pub fn admits(&self, value: f64) -> bool {
        value.is_finite()
            && value <= self.hi
            && (value > self.lo || (self.lo_included && value == self.lo))
    }
}

impl std::fmt::Display for ParamRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let open = if self.lo_included { '[' } else { '(' };
        write!(f, "{open}{:e}, {:e}] {}", self.lo, self.hi, self.unit)
    }
}

const fn range(
    field: &'static str,
    lo: f64,
    lo_included: bool,
    hi: f64,
    unit: &'static str,
) -> ParamRange {
    ParamRange {
        field,
        lo,
        lo_included,
        hi,
        unit,
    }
}

/// The range of every numeric key (also listed in `configs/haptic.toml`). Stiffnesses have a
/// floor: below 1 N/m (k_T, K_ff) the coupling's holding force `k_T s / 2` is under 2.5 mN at
/// 5 mm and the part would not follow the handle.
pub const PARAM_RANGES: [ParamRange; 12] = [
    range("dt", 1e-5, true, 0.1, "s"),
    range("mass", 1e-6, true, 1e4, "kg"),
    range("inertia", 1e-15, true, 1e6, "kg·m²"),
    range("voxel_size", 0.0, false, 10.0, "m"),
    range("max_radius", 0.0, false, 1e3, "m"),
    range("k_ff", 1.0, true, 1e9, "N/m"),
    range("k_t", 1.0, true, 1e9, "N/m"),
    range("k_r", 1e-9, true, 1e6, "N·m/rad"),
    range("b_t", 0.0, false, 1e9, "N·s/m"),
    range("b_r", 0.0, false, 1e6, "N·m·s/rad"),
    range("contact_average_threshold", 1.0, true, 1e6, "contacts"),
    range("velocity_guard_fraction", 0.0, false, 1.0, ""),
];

/// Default k_R as a multiple of `k_T I / m` (the rotational stiffness with the translational natural
/// frequency). At 1× the coupling torque clamp `k_R s / (2 r_max)` (1.4e-2 N·m for the teapot at
/// 5 mm) was below the contact torques of side presses (3e-2 to 8e-2 N·m), so contacts spun the part
/// and drove its thin handle through the force layer: the standard session's penetration ratio was
/// 9e-2 with braking. At 2× it was 0 with braking (2.4e-2 without), with the rotational stability
/// index 0.57 instead of 0.50 (`examples/penetration_probe.rs`; a single deterministic session,
/// so a working choice, not a proven optimum). 10× let the part get stuck in a wall.
pub const ROTATIONAL_COUPLING_FACTOR: f64 = 2.0;

/// The largest haptic parameter file read, in bytes (1 MiB; the file has a dozen keys).
pub const MAX_PARAMS_FILE_BYTES: u64 = vps_files::MIB;

/// Parameters of one haptic frame (docs/architecture.md#the-haptic-frame). SI units. Gains left `None` are derived
/// ([`HapticParams::gains`]) from `dt`, `mass`, the inertia and the stability bound; see
/// [`crate::stability`] for the derivation. `voxel_size` and `max_radius` describe the scene and the
/// part; set them from the loaded data with [`HapticParams::with_scene`].
///
/// TOML: every key is optional, unknown keys are an error. `configs/haptic.toml` lists them all.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HapticParams {
    /// Fixed time step (s). Default 0.001 (1 kHz). Range [1e-5, 0.1].
    pub dt: f64,
    /// Mass of the dynamic object, the reflected mass felt at the handle (kg). Default 0.012, the
    /// paper's 12 g: small reflected inertia; the stiffness the bound allows grows with it.
    /// Range [1e-6, 1e4].
    pub mass: f64,
    /// Isotropic moment of inertia (kg·m²). Default (None): a solid sphere of radius `max_radius`,
    /// `0.4 m r_max²` (the paper's isotropic-inertia assumption). Range [1e-15, 1e6].
    pub inertia: Option<f64>,
    /// Voxel size of the scene's voxmap (m). Default 0.005. Range (0, 10].
    pub voxel_size: f64,
    /// Bounding radius of the part about its centre of mass, `r_max` (m). Default 0.0375 (a 75 mm
    /// part). Range (0, 1e3].
    pub max_radius: f64,
    /// Force-field stiffness per contact point, K_ff (N/m). Default: `k_T / κ` from the bound.
    /// Range [1, 1e9].
    pub k_ff: Option<f64>,
    /// Coupling translational stiffness k_T (N/m). Default: `κ K_ff` when `k_ff` is given, else
    /// `h² m / dt²` from the bound. Range [1, 1e9].
    pub k_t: Option<f64>,
    /// Coupling rotational stiffness k_R (N·m/rad). Default: `2 k_T I / m` (twice the stiffness of
    /// equal natural frequency; see [`ROTATIONAL_COUPLING_FACTOR`]). Range [1e-9, 1e6].
    pub k_r: Option<f64>,
    /// Coupling translational damping b_T (N·s/m). Default: critical, `2 √(k_T m)`. Range (0, 1e9].
    pub b_t: Option<f64>,
    /// Coupling rotational damping b_R (N·m·s/rad). Default: critical, `2 √(k_R I)`. Range (0, 1e6].
    pub b_r: Option<f64>,
    /// Contact count from which forces are averaged (the paper's 10). Range [1, 1e6].
    pub contact_average_threshold: u32,
    /// Pre-contact braking in Proximity voxels. Default true.
    pub braking: bool,
    /// Also apply a braking torque `−b S_t` (an extension of the paper, off by default).
    pub braking_torque: bool,
    /// Tunnelling guard: `|v| + |w| r_max ≤ f s / dt`. Default 0.25. Range (0, 1].
    pub velocity_guard_fraction: f64,
}

/// Keys that left the haptic parameters, with where they live now: the device layer owns the wrench
/// limit (`vps_device::DeviceLimits`), so a parameter file that still sets one is refused with a
/// message naming the new key rather than silently ignored.
pub const MOVED_KEYS: [(&str, &str); 2] = [
    (
        "device_max_force",
        "the scene file's `[device]` key `max_force` (N)",
    ),
    (
        "device_max_torque",
        "the scene file's `[device]` key `max_torque` (N·m)",
    ),
];

impl Default for HapticParams {
    fn default() -> Self {
        Self {
            dt: 0.001,
            mass: 0.012,
            inertia: None,
            voxel_size: 0.005,
            max_radius: 0.0375,
            k_ff: None,
            k_t: None,
            k_r: None,
            b_t: None,
            b_r: None,
            contact_average_threshold: 10,
            braking: true,
            braking_torque: false,
            velocity_guard_fraction: 0.25,
        }
    }
}

/// Fully resolved gains and derived quantities, SI units. Made by [`HapticParams::gains`]; cheap
/// (a few square roots), no allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gains {
    /// Isotropic moment of inertia (kg·m²).
    pub inertia: f64,
    /// Per-point field stiffness (N/m).
    pub k_ff: f64,
    /// Coupling translational stiffness (N/m).
    pub k_t: f64,
    /// Coupling rotational stiffness (N·m/rad).
    pub k_r: f64,
    /// Coupling translational damping (N·s/m).
    pub b_t: f64,
    /// Coupling rotational damping (N·m·s/rad).
    pub b_r: f64,
}

/// The stability indices of a parameter set (see [`crate::stability`]): < 1 is stable by the
/// linearised bound. The default k_T is derived for [`STABILITY_MARGIN`] with `k_R = k_T I / m`;
/// the default k_R is [`ROTATIONAL_COUPLING_FACTOR`] times that, so the default indices are
/// ≈ 0.574 (rotational, the worse) and ≈ 0.302 (translational).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StabilityIndices {
    /// Translation: coupling + `threshold · K_ff`, coupling damping.
    pub translational: f64,
    /// Rotation: coupling + `threshold · K_ff r_max²`, coupling damping.
    pub rotational: f64,
}

impl StabilityIndices {
    /// The worse of the two.
    pub fn worst(&self) -> f64 {
        self.translational.max(self.rotational)
    }
}

impl HapticParams {
    /// Parses and validates TOML text; `source_name` (a file name or label) prefixes every error.
    pub fn from_toml_str(s: &str, source_name: &str) -> Result<Self, ParamsError> {
        if let Ok(table) = s.parse::<toml::Table>() {
            if let Some((key, new)) = MOVED_KEYS.iter().find(|(k, _)| table.contains_key(*k)) {
                return Err(ParamsError::Moved {
                    source_name: source_name.to_owned(),
                    key,
                    new,
                });
            }
        }
        let params: HapticParams = toml::from_str(s).map_err(|e| ParamsError::Toml {
            source_name: source_name.to_owned(),
            message: e.to_string(),
        })?;
        params.validate(source_name)?;
        Ok(params)
    }

    /// Reads, parses and validates a TOML file (a regular file of at most
    /// [`MAX_PARAMS_FILE_BYTES`]).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, ParamsError> {
        let path = path.as_ref();
        let text =
            vps_files::read_regular_to_string(path, MAX_PARAMS_FILE_BYTES).map_err(|source| {
                ParamsError::Io {
                    path: path.display().to_string(),
                    source,
                }
            })?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// These parameters with the scene's voxel size and the part's bounding radius (m), validated.
    pub fn with_scene(mut self, voxel_size: f64, max_radius: f64) -> Result<Self, ParamsError> {
        self.voxel_size = voxel_size;
        self.max_radius = max_radius;
        self.validate("scene")?;
        Ok(self)
    }

    /// Checks every field against its range ([`PARAM_RANGES`]); errors name the source, the
    /// field, the value and the allowed range.
    pub fn validate(&self, source_name: &str) -> Result<(), ParamsError> {
        let value_of = |field: &str| -> Option<f64> {
            Some(match field {
                "dt" => self.dt,
                "mass" => self.mass,
                "inertia" => self.inertia?,
                "voxel_size" => self.voxel_size,
                "max_radius" => self.max_radius,
                "k_ff" => self.k_ff?,
                "k_t" => self.k_t?,
                "k_r" => self.k_r?,
                "b_t" => self.b_t?,
                "b_r" => self.b_r?,
                "contact_average_threshold" => f64::from(self.contact_average_threshold),
                "velocity_guard_fraction" => self.velocity_guard_fraction,
                _ => return None,
            })
        };
        for range in PARAM_RANGES {
            if let Some(value) = value_of(range.field) {
                if !range.admits(value) {
                    return Err(ParamsError::Invalid {
                        source_name: source_name.to_owned(),
                        field: range.field,
                        value,
                        reason: format!("must be finite and in {range}"),
                    });
                }
            }
        }
        Ok(())
    }

    /// The resolved gains: given values, or the defaults derived from the stability bound.
    /// Arithmetic only (called by [`crate::step`] every frame); does not allocate or block.
    pub fn gains(&self) -> Gains {
        let m = self.mass;
        let inertia = self
            .inertia
            .unwrap_or(SPHERE_INERTIA_FACTOR * m * self.max_radius * self.max_radius);
        let k_t = self
            .k_t
            .or(self.k_ff.map(|k_ff| k_ff * COUPLING_TO_FIELD))
            .unwrap_or_else(|| {
                let rho = self.field_to_coupling_ratio(inertia);
                let h = coupling_step_ratio(rho, STABILITY_MARGIN);
                h * h * m / (self.dt * self.dt)
            });
        let k_ff = self.k_ff.unwrap_or(k_t / COUPLING_TO_FIELD);
        let k_r = self
            .k_r
            .unwrap_or(ROTATIONAL_COUPLING_FACTOR * k_t * inertia / m);
        Gains {
            inertia,
            k_ff,
            k_t,
            k_r,
            b_t: self.b_t.unwrap_or(2.0 * (k_t * m).sqrt()),
            b_r: self.b_r.unwrap_or(2.0 * (k_r * inertia).sqrt()),
        }
    }

    /// The linearised stability indices of these parameters (see [`crate::stability`]).
    pub fn stability(&self) -> StabilityIndices {
        let g = self.gains();
        let dt = self.dt;
        let n = self.contact_average_threshold as f64;
        let r2 = self.max_radius * self.max_radius;
        let omega_t2 = (g.k_t + n * g.k_ff) / self.mass;
        let omega_r2 = (g.k_r + n * g.k_ff * r2) / g.inertia;
        StabilityIndices {
            translational: stability_index(omega_t2.sqrt() * dt, g.b_t / self.mass * dt),
            rotational: stability_index(omega_r2.sqrt() * dt, g.b_r / g.inertia * dt),
        }
    }

    /// ρ of the bound: the worse of the translational and rotational field stiffness relative to
    /// the coupling's, with `K_ff = k_T / κ` and `k_R = k_T I / m`.
    fn field_to_coupling_ratio(&self, inertia: f64) -> f64 {
        let n = self.contact_average_threshold as f64;
        let translational = n / COUPLING_TO_FIELD;
        let rotational =
            n * self.mass * self.max_radius * self.max_radius / (COUPLING_TO_FIELD * inertia);
        translational.max(rotational)
    }
}
