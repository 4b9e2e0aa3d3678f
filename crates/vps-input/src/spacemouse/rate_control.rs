//! Pure rate control: SpaceMouse deflection → handle velocity → integrated handle pose.
//!
//! A SpaceMouse is an isometric 6-axis joystick, so deflection commands a velocity. Per raw axis
//! `j` the count is scaled to `d = clamp(count / full_scale, −1, 1)`, the dead zone is removed with
//! rescaling (`|d| ≤ dead_zone → 0`, else `sign(d)·(|d| − dead_zone)/(1 − dead_zone)`, so the
//! output is continuous and reaches ±1 at full deflection), then output axis `i` (0..3 linear x, y,
//! z; 3..6 angular x, y, z, world frame) is
//! `axis_sign[i] · axis_sensitivity[i] · shaped[axis_map[i]]`, times `translation_speed` (m/s) or
//! `rotation_speed` (rad/s).
//!
//! Reports arrive at 60–125 Hz while the haptic loop calls [`RateControl::advance`] every 1 ms: the
//! latest deflection is held between reports, and once it is older than `stale_after` (s) it is
//! treated as zero (a stalled or unplugged device never keeps the handle moving). This assumes the
//! device repeats its report while deflected, as 3Dconnexion devices do.
//!
//! Buttons: a press of the left button (bit 0) toggles the grab; while not grabbed the handle
//! velocity is zero. A press of the right button (bit 1) resets the pose to the start pose.
//!
//! No clock is read: time advances only by the `dt` passed to [`RateControl::advance`]. Nothing
//! here allocates or blocks.

use glam::{DQuat, DVec3};
use vps_haptic::HandleSample;

use super::report::Report;

/// Bit of the left button in a button mask (grab toggle).
pub const BUTTON_LEFT: u64 = 1;
/// Bit of the right button in a button mask (reset pose).
pub const BUTTON_RIGHT: u64 = 2;

/// SpaceMouse rate-control settings (TOML/JSON loadable; every field has a default).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpaceMouseConfig {
    /// Raw count at full deflection (counts; > 0). Default 350.
    pub full_scale: f64,
    /// Dead zone as a fraction of full deflection, in `[0, 1)`. Default 0.05.
    pub dead_zone: f64,
    /// Handle speed at full deflection on one axis (m/s; finite, ≥ 0). Default 0.1.
    pub translation_speed: f64,
    /// Handle angular speed at full deflection on one axis (rad/s; finite, ≥ 0). Default 1.0.
    pub rotation_speed: f64,
    /// Output axis `i` takes raw axis `axis_map[i]` (raw order tx, ty, tz, rx, ry, rz). Must be a
    /// permutation of 0..6. Default `[0, 2, 1, 3, 5, 4]` with `axis_sign = [1, −1, 1, 1, −1, 1]`
    /// maps the raw frame (x right, y toward the user, z down, as commonly documented for
    /// 3Dconnexion HID reports) to a y-up world (x right, y up, z toward the user). Check the signs
    /// on a real device; they are a proper rotation, so rotations follow the same map.
    pub axis_map: [usize; 6],
    /// Sign of each output axis (each exactly +1 or −1).
    pub axis_sign: [f64; 6],
    /// Per-output-axis sensitivity (finite, ≥ 0; 0 disables an axis). Default all 1.
    pub axis_sensitivity: [f64; 6],
    /// A report older than this is treated as zero deflection (s; finite, > 0). Default 0.1.
    pub stale_after: f64,
    /// Whether the handle starts grabbed (moving with the deflection). Default true.
    pub start_grabbed: bool,
    /// Start (and reset) position of the handle (m, world frame; finite).
    pub start_position: DVec3,
    /// Start (and reset) orientation (unit quaternion within 1e-6; finite).
    pub start_orientation: DQuat,
}

impl Default for SpaceMouseConfig {
    fn default() -> Self {
        Self {
            full_scale: 350.0,
            dead_zone: 0.05,
            translation_speed: 0.1,
            rotation_speed: 1.0,
            axis_map: [0, 2, 1, 3, 5, 4],
            axis_sign: [1.0, -1.0, 1.0, 1.0, -1.0, 1.0],
            axis_sensitivity: [1.0; 6],
            stale_after: 0.1,
            start_grabbed: true,
            start_position: DVec3::ZERO,
            start_orientation: DQuat::IDENTITY,
        }
    }
}

/// An invalid [`SpaceMouseConfig`] field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("SpaceMouse config field `{field}`: {message}")]
pub struct ConfigError {
    /// The field (with index, e.g. `axis_map[3]`).
    pub field: String,
    /// What is wrong with it.
    pub message: String,
}

fn bad(field: impl Into<String>, message: impl Into<String>) -> ConfigError {
    ConfigError {
        field: field.into(),
        message: message.into(),
    }
}

impl SpaceMouseConfig {
    /// Checks every field against its documented range; the error names the first bad field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(self.full_scale.is_finite() && self.full_scale > 0.0) {
            return Err(bad(
                "full_scale",
                format!("{} must be finite and > 0", self.full_scale),
            ));
        }
        if !(self.dead_zone >= 0.0 && self.dead_zone < 1.0) {
            return Err(bad(
                "dead_zone",
                format!("{} must be in [0, 1)", self.dead_zone),
            ));
        }
        for (field, v) in [
            ("translation_speed", self.translation_speed),
            ("rotation_speed", self.rotation_speed),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(field, format!("{v} must be finite and >= 0")));
            }
        }
        let mut used = [false; 6];
        for (i, &j) in self.axis_map.iter().enumerate() {
            if j >= 6 {
                return Err(bad(
                    format!("axis_map[{i}]"),
                    format!("{j} is not a raw axis 0..6"),
                ));
            }
            if used[j] {
                return Err(bad(
                    format!("axis_map[{i}]"),
                    format!("raw axis {j} used twice (must be a permutation of 0..6)"),
                ));
            }
            used[j] = true;
        }
        for (i, &s) in self.axis_sign.iter().enumerate() {
            if s != 1.0 && s != -1.0 {
                return Err(bad(
                    format!("axis_sign[{i}]"),
                    format!("{s} must be 1 or -1"),
                ));
            }
        }
        for (i, &s) in self.axis_sensitivity.iter().enumerate() {
            if !(s.is_finite() && s >= 0.0) {
                return Err(bad(
                    format!("axis_sensitivity[{i}]"),
                    format!("{s} must be finite and >= 0"),
                ));
            }
        }
        if !(self.stale_after.is_finite() && self.stale_after > 0.0) {
            return Err(bad(
                "stale_after",
                format!("{} s must be finite and > 0", self.stale_after),
            ));
        }
        crate::check_start_pose(
            self.start_position,
            self.start_orientation,
            ["start_position", "start_orientation"],
        )
        .map_err(|(field, message)| bad(field, message))
    }
}

/// The rate-control state machine: feed it reports, advance it by `dt`, read the handle sample.
#[derive(Clone, Debug)]
pub struct RateControl {
    config: SpaceMouseConfig,
    /// Latest raw counts, raw order tx, ty, tz, rx, ry, rz.
    raw: [i16; 6],
    /// Time (s, this controller's clock) the latest motion report arrived; `None` before any.
    last_motion: Option<f64>,
    buttons: u64,
    grabbed: bool,
    time: f64,
    position: DVec3,
    orientation: DQuat,
    linear_velocity: DVec3,
    angular_velocity: DVec3,
}

impl RateControl {
    /// A controller at the start pose, at time 0, with zero deflection. Fails on an invalid config.
    pub fn new(config: SpaceMouseConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            raw: [0; 6],
            last_motion: None,
            buttons: 0,
            grabbed: config.start_grabbed,
            time: 0.0,
            position: config.start_position,
            orientation: config.start_orientation,
            linear_velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
            config,
        })
    }

    /// The validated configuration.
    pub fn config(&self) -> &SpaceMouseConfig {
        &self.config
    }

    /// Applies one decoded report, stamped with the controller's current time. A button press edge
    /// of the left button toggles the grab; of the right button resets the pose.
    pub fn on_report(&mut self, report: &Report) {
        match *report {
            Report::Translation(t) => {
                self.raw[..3].copy_from_slice(&t);
                self.last_motion = Some(self.time);
            }
            Report::Rotation(r) => {
                self.raw[3..].copy_from_slice(&r);
                self.last_motion = Some(self.time);
            }
            Report::Motion {
                translation,
                rotation,
            } => {
                self.raw[..3].copy_from_slice(&translation);
                self.raw[3..].copy_from_slice(&rotation);
                self.last_motion = Some(self.time);
            }
            Report::Buttons(mask) => {
                let pressed = mask & !self.buttons;
                self.buttons = mask;
                if pressed & BUTTON_LEFT != 0 {
                    self.grabbed = !self.grabbed;
                }
                if pressed & BUTTON_RIGHT != 0 {
                    self.reset();
                }
            }
        }
    }

    /// Moves the pose and velocities back to the start pose at rest (the grab state is kept).
    pub fn reset(&mut self) {
        self.position = self.config.start_position;
        self.orientation = self.config.start_orientation;
        self.linear_velocity = DVec3::ZERO;
        self.angular_velocity = DVec3::ZERO;
    }

    /// Normalised, dead-zoned, mapped deflection per output axis (dimensionless, each within
    /// `±axis_sensitivity[i]`), or all zero when no report is fresh.
    pub fn deflection(&self) -> [f64; 6] {
        let fresh = self
            .last_motion
            .is_some_and(|t| self.time - t <= self.config.stale_after);
        let mut out = [0.0; 6];
        if !fresh {
            return out;
        }
        let c = &self.config;
        for (i, o) in out.iter_mut().enumerate() {
            let d = shape(self.raw[c.axis_map[i]], c.full_scale, c.dead_zone);
            *o = c.axis_sign[i] * c.axis_sensitivity[i] * d;
        }
        out
    }

    /// Advances time by `dt` (s; a non-finite or negative `dt` is treated as 0): sets the velocity
    /// from the current deflection (zero while not grabbed or stale) and integrates the pose with
    /// it (explicit Euler for position, exact exponential map for orientation). Within one long
    /// step the motion stops where the report turns stale. Returns the new sample.
    pub fn advance(&mut self, dt: f64) -> HandleSample {
        let dt = if dt.is_finite() && dt > 0.0 { dt } else { 0.0 };
        let d = if self.grabbed {
            self.deflection()
        } else {
            [0.0; 6]
        };
        // Time within this step while the latest report is still fresh.
        let moving = self.last_motion.map_or(0.0, |t| {
            (t + self.config.stale_after - self.time).clamp(0.0, dt)
        });
        self.linear_velocity = DVec3::new(d[0], d[1], d[2]) * self.config.translation_speed;
        self.angular_velocity = DVec3::new(d[3], d[4], d[5]) * self.config.rotation_speed;
        self.position += self.linear_velocity * moving;
        let turn = self.angular_velocity * moving;
        if turn != DVec3::ZERO {
            self.orientation = (DQuat::from_scaled_axis(turn) * self.orientation).normalize();
        }
        self.time += dt;
        self.sample()
    }

    /// The current handle sample (pose and the velocity of the last step).
    pub fn sample(&self) -> HandleSample {
        HandleSample {
            position: self.position,
            orientation: self.orientation,
            linear_velocity: self.linear_velocity,
            angular_velocity: self.angular_velocity,
        }
    }

    /// Whether the handle currently follows the deflection.
    pub fn grabbed(&self) -> bool {
        self.grabbed
    }

    /// The latest button mask.
    pub fn buttons(&self) -> u64 {
        self.buttons
    }

    /// This controller's clock (s): the sum of every `dt` advanced.
    pub fn time(&self) -> f64 {
        self.time
    }
}

/// Count → normalised deflection in −1..1 with the dead zone removed and the rest rescaled.
fn shape(count: i16, full_scale: f64, dead_zone: f64) -> f64 {
    let d = (f64::from(count) / full_scale).clamp(-1.0, 1.0);
    let m = d.abs();
    if m <= dead_zone {
        0.0
    } else {
        d.signum() * (m - dead_zone) / (1.0 - dead_zone)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity_config() -> SpaceMouseConfig {
        SpaceMouseConfig {
            axis_map: [0, 1, 2, 3, 4, 5],
            axis_sign: [1.0; 6],
            ..SpaceMouseConfig::default()
        }
    }

    fn run(rc: &mut RateControl, seconds: f64, report_every: usize, report: Report) {
        let steps = (seconds * 1000.0).round() as usize;
        for i in 0..steps {
            if i % report_every == 0 {
                rc.on_report(&report);
            }
            rc.advance(1e-3);
        }
    }

    #[test]
    fn constant_deflection_integrates_to_v_times_t() {
        let mut rc = RateControl::new(identity_config()).unwrap();
        // Full deflection on x, half-way past the dead zone on z (negative), reports at 125 Hz.
        let half: f64 = (0.05 + 0.5 * 0.95) * 350.0;
        let report = Report::Translation([350, 0, -(half.round() as i16)]);
        run(&mut rc, 2.0, 8, report);
        let s = rc.sample();
        assert!((s.linear_velocity.x - 0.1).abs() < 1e-12);
        assert!((s.position.x - 0.2).abs() < 1e-9, "{:?}", s.position);
        assert!((s.position.z + 0.1).abs() < 2e-3 * 0.2, "{:?}", s.position);
        assert_eq!(s.position.y, 0.0);
        assert_eq!(s.angular_velocity, DVec3::ZERO);
    }

    #[test]
    fn rotation_integrates_to_omega_times_t() {
        let mut rc = RateControl::new(identity_config()).unwrap();
        run(&mut rc, 0.5, 16, Report::Rotation([0, 0, 400]));
        let s = rc.sample();
        let (axis, angle) = s.orientation.to_axis_angle();
        assert!((angle - 0.5).abs() < 1e-9, "angle {angle}");
        assert!((axis - DVec3::Z).length() < 1e-9);
        assert!((s.angular_velocity.z - 1.0).abs() < 1e-12);
    }

    #[test]
    fn dead_zone_gives_exactly_zero() {
        let mut rc = RateControl::new(identity_config()).unwrap();
        let inside = (0.05 * 350.0) as i16; // 17 counts ≤ 17.5
        run(
            &mut rc,
            0.2,
            10,
            Report::Motion {
                translation: [inside, -inside, 1],
                rotation: [-inside, 0, inside],
            },
        );
        let s = rc.sample();
        assert_eq!(s.position, DVec3::ZERO);
        assert_eq!(s.orientation, DQuat::IDENTITY);
        assert_eq!(rc.deflection(), [0.0; 6]);
        assert!(shape(18, 350.0, 0.05) > 0.0, "just outside the dead zone");
    }

    #[test]
    fn stale_reports_stop_motion() {
        let mut rc = RateControl::new(identity_config()).unwrap();
        rc.on_report(&Report::Translation([350, 0, 0]));
        for _ in 0..100 {
            rc.advance(1e-3);
        }
        assert!(rc.sample().linear_velocity.x > 0.0, "held within 100 ms");
        for _ in 0..10 {
            rc.advance(1e-3);
        }
        let s = rc.sample();
        assert_eq!(s.linear_velocity, DVec3::ZERO, "stale after 100 ms");
        let x = s.position.x;
        for _ in 0..100 {
            rc.advance(1e-3);
        }
        assert_eq!(rc.sample().position.x, x);
        // A fresh report resumes motion.
        rc.on_report(&Report::Translation([350, 0, 0]));
        rc.advance(1e-3);
        assert!(rc.sample().position.x > x);
    }

    #[test]
    fn a_long_step_moves_only_while_the_report_is_fresh() {
        let mut rc = RateControl::new(identity_config()).unwrap();
        rc.on_report(&Report::Translation([350, 0, 0]));
        let s = rc.advance(1.0);
        assert!((s.position.x - 0.1 * 0.1).abs() < 1e-12, "{:?}", s.position);
        let s = rc.advance(1.0);
        assert!((s.position.x - 0.01).abs() < 1e-12);
        assert_eq!(s.linear_velocity, DVec3::ZERO);
    }

    #[test]
    fn axis_map_and_sign_route_raw_axes() {
        let mut rc = RateControl::new(SpaceMouseConfig::default()).unwrap();
        // Raw z (push down) with the default map becomes world −y... and raw y becomes world z.
        rc.on_report(&Report::Motion {
            translation: [0, 350, 350],
            rotation: [0, 0, 350],
        });
        let s = rc.advance(1e-3);
        assert!((s.linear_velocity - DVec3::new(0.0, -0.1, 0.1)).length() < 1e-12);
        assert!((s.angular_velocity - DVec3::new(0.0, -1.0, 0.0)).length() < 1e-12);

        let cfg = SpaceMouseConfig {
            axis_map: [5, 4, 3, 2, 1, 0],
            axis_sign: [1.0, 1.0, -1.0, 1.0, 1.0, 1.0],
            axis_sensitivity: [0.5, 1.0, 1.0, 1.0, 1.0, 0.0],
            ..identity_config()
        };
        let mut rc = RateControl::new(cfg).unwrap();
        rc.on_report(&Report::Motion {
            translation: [350, 0, 0],
            rotation: [350, 0, 350],
        });
        let s = rc.advance(1e-3);
        assert!((s.linear_velocity - DVec3::new(0.05, 0.0, -0.1)).length() < 1e-12);
        assert_eq!(
            s.angular_velocity,
            DVec3::ZERO,
            "raw tx → out rz, sensitivity 0"
        );
    }

    #[test]
    fn buttons_toggle_grab_and_reset() {
        let mut rc = RateControl::new(identity_config()).unwrap();
        run(&mut rc, 0.1, 8, Report::Translation([350, 0, 0]));
        let moved = rc.sample().position.x;
        assert!(moved > 0.0);
        rc.on_report(&Report::Buttons(BUTTON_LEFT));
        assert!(!rc.grabbed());
        rc.on_report(&Report::Buttons(BUTTON_LEFT)); // still held: no second toggle
        assert!(!rc.grabbed());
        rc.on_report(&Report::Translation([350, 0, 0]));
        let s = rc.advance(1e-3);
        assert_eq!(s.linear_velocity, DVec3::ZERO);
        assert_eq!(s.position.x, moved);
        rc.on_report(&Report::Buttons(0));
        rc.on_report(&Report::Buttons(BUTTON_LEFT));
        assert!(rc.grabbed());
        rc.on_report(&Report::Buttons(BUTTON_LEFT | BUTTON_RIGHT));
        let s = rc.sample();
        assert_eq!(s.position, DVec3::ZERO);
        assert!(rc.grabbed());
    }

    #[test]
    fn validation_names_the_field() {
        /// An edit of the default config, and the field its error must name.
        type Case = (fn(&mut SpaceMouseConfig), &'static str);
        let cases: [Case; 9] = [
            (|c| c.dead_zone = 1.0, "dead_zone"),
            (|c| c.full_scale = 0.0, "full_scale"),
            (|c| c.translation_speed = f64::NAN, "translation_speed"),
            (|c| c.axis_map = [0, 1, 2, 3, 4, 4], "axis_map[5]"),
            (|c| c.axis_map = [0, 1, 9, 3, 4, 5], "axis_map[2]"),
            (
                |c| c.axis_sign = [1.0, 1.0, 0.5, 1.0, 1.0, 1.0],
                "axis_sign[2]",
            ),
            (
                |c| c.axis_sensitivity = [1.0, -1.0, 1.0, 1.0, 1.0, 1.0],
                "axis_sensitivity[1]",
            ),
            (|c| c.stale_after = 0.0, "stale_after"),
            (
                |c| c.start_orientation = DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0),
                "start_orientation",
            ),
        ];
        for (edit, field) in cases {
            let mut cfg = SpaceMouseConfig::default();
            edit(&mut cfg);
            let e = RateControl::new(cfg).unwrap_err();
            assert_eq!(e.field, field);
            assert!(e.to_string().contains(field));
        }
    }

    #[test]
    fn config_loads_from_toml_with_defaults() {
        let cfg: SpaceMouseConfig =
            toml::from_str("dead_zone = 0.1\ntranslation_speed = 0.25\naxis_map = [0,1,2,3,4,5]\n")
                .unwrap();
        assert_eq!(cfg.dead_zone, 0.1);
        assert_eq!(cfg.translation_speed, 0.25);
        assert_eq!(cfg.rotation_speed, 1.0);
        cfg.validate().unwrap();
        assert!(toml::from_str::<SpaceMouseConfig>("dead_zon = 0.1").is_err());
    }
}
