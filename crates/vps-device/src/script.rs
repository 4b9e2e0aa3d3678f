//! Scripted handle motions: timed waypoints with linear interpolation of position and slerp of
//! orientation, and built-in motions placed against a contact geometry supplied by the caller (so a
//! scene can aim them at its real surfaces).
//!
//! A script is the *target* a [`SimulatedHand`](crate::SimulatedHand) is pulled toward; the hand lags
//! it and is pushed back by the wrench the haptic loop writes. Positions in m, times in s from the
//! start of the script, orientations unit quaternions (world frame).

use crate::rotation::rotation_vector;
use glam::{DQuat, DVec3};

/// Why a script or one of its parameters is invalid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScriptError {
    /// A script needs at least one waypoint.
    #[error("script has no waypoints")]
    Empty,
    /// A waypoint field is NaN or infinite.
    #[error("waypoint {index}: {field} is not finite")]
    NonFinite {
        /// Waypoint index.
        index: usize,
        /// "time", "position" or "orientation".
        field: &'static str,
    },
    /// Waypoint times must start at ≥ 0 and strictly increase.
    #[error("waypoint {index}: time {time} s does not follow {previous} s (times must start at >= 0 and strictly increase)")]
    TimeOrder {
        /// Waypoint index.
        index: usize,
        /// The previous waypoint's time (s), or 0 for the first.
        previous: f64,
        /// This waypoint's time (s).
        time: f64,
    },
    /// A waypoint orientation is not a unit quaternion (|q| off by more than 1e-6).
    #[error("waypoint {index}: orientation is not a unit quaternion (length {length})")]
    NotUnit {
        /// Waypoint index.
        index: usize,
        /// The quaternion's length.
        length: f64,
    },
    /// A built-in script parameter is out of range.
    #[error("script parameter {name} = {value}: {reason}")]
    Parameter {
        /// Parameter name.
        name: &'static str,
        /// Its value (for vectors, the offending length or component).
        value: f64,
        /// What was expected.
        reason: &'static str,
    },
}

/// One timed target pose.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Waypoint {
    /// Time from the start of the script (s).
    pub time: f64,
    /// Target handle position (m).
    pub position: DVec3,
    /// Target handle orientation (unit quaternion).
    pub orientation: DQuat,
}

/// A validated list of waypoints. Invariants: non-empty, all fields finite, times ≥ 0 and strictly
/// increasing, orientations unit. Before the first waypoint the script holds the first pose, after
/// the last it holds the last.
#[derive(Clone, Debug, PartialEq)]
pub struct Script {
    waypoints: Vec<Waypoint>,
}

impl Script {
    /// Validates `waypoints` (see [`Script`] invariants); errors name the offending waypoint.
    pub fn new(waypoints: Vec<Waypoint>) -> Result<Script, ScriptError> {
        if waypoints.is_empty() {
            return Err(ScriptError::Empty);
        }
        let mut previous = 0.0;
        for (index, w) in waypoints.iter().enumerate() {
            let non_finite = |field| Err(ScriptError::NonFinite { index, field });
            if !w.time.is_finite() {
                return non_finite("time");
            }
            if !w.position.is_finite() {
                return non_finite("position");
            }
            if !w.orientation.is_finite() {
                return non_finite("orientation");
            }
            let ordered = if index == 0 {
                w.time >= 0.0
            } else {
                w.time > previous
            };
            if !ordered {
                return Err(ScriptError::TimeOrder {
                    index,
                    previous,
                    time: w.time,
                });
            }
            let length = w.orientation.length();
            if (length - 1.0).abs() > 1e-6 {
                return Err(ScriptError::NotUnit { index, length });
            }
            previous = w.time;
        }
        Ok(Script { waypoints })
    }

    /// The waypoints, in time order.
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// Time of the last waypoint (s): after it the target stands still.
    pub fn duration(&self) -> f64 {
        self.waypoints[self.waypoints.len() - 1].time
    }

    /// The segment `(from, to)` containing `t`, or the single waypoint held when `t` is outside
    /// (NaN counts as before the start).
    fn locate(&self, t: f64) -> Result<(&Waypoint, &Waypoint), &Waypoint> {
        let w = &self.waypoints;
        let first = &w[0];
        let last = &w[w.len() - 1];
        if t.is_nan() || t <= first.time {
            return Err(first);
        }
        if t >= last.time {
            return Err(last);
        }
        let i = w.partition_point(|p| p.time <= t);
        Ok((&w[i - 1], &w[i]))
    }

    /// Target pose at time `t` (s): position linearly interpolated, orientation slerped (shortest
    /// path). Continuous in `t`. Does not allocate.
    pub fn sample(&self, t: f64) -> (DVec3, DQuat) {
        match self.locate(t) {
            Err(w) => (w.position, w.orientation),
            Ok((a, b)) => {
                let u = (t - a.time) / (b.time - a.time);
                (
                    a.position.lerp(b.position, u),
                    a.orientation.slerp(b.orientation, u).normalize(),
                )
            }
        }
    }

    /// Target linear (m/s) and angular (rad/s, world frame) velocity at `t`: constant on each
    /// segment, zero outside the script. Does not allocate.
    pub fn velocity(&self, t: f64) -> (DVec3, DVec3) {
        match self.locate(t) {
            Err(_) => (DVec3::ZERO, DVec3::ZERO),
            Ok((a, b)) => {
                let dt = b.time - a.time;
                (
                    (b.position - a.position) / dt,
                    rotation_vector(b.orientation * a.orientation.inverse()) / dt,
                )
            }
        }
    }
}

/// Builds a script move by move, starting at time 0. Parameter errors are kept and returned by
/// [`ScriptBuilder::build`].
#[derive(Clone, Debug)]
pub struct ScriptBuilder {
    waypoints: Vec<Waypoint>,
    error: Option<ScriptError>,
}

impl ScriptBuilder {
    /// Starts at `position` (m) and `orientation` at time 0.
    pub fn start(position: DVec3, orientation: DQuat) -> ScriptBuilder {
        ScriptBuilder {
            waypoints: vec![Waypoint {
                time: 0.0,
                position,
                orientation,
            }],
            error: None,
        }
    }

    fn last(&self) -> Waypoint {
        self.waypoints[self.waypoints.len() - 1]
    }

    fn check(mut self, ok: bool, name: &'static str, value: f64, reason: &'static str) -> Self {
        if !ok && self.error.is_none() {
            self.error = Some(ScriptError::Parameter {
                name,
                value,
                reason,
            });
        }
        self
    }

    fn push(mut self, duration: f64, position: DVec3, orientation: DQuat) -> Self {
        if self.error.is_none() && duration > 0.0 {
            let time = self.last().time + duration;
            self.waypoints.push(Waypoint {
                time,
                position,
                orientation,
            });
        }
        self
    }

    /// Moves in a straight line to `position` at `speed` (m/s, > 0), keeping the orientation.
    /// A move of zero length adds nothing.
    pub fn move_to(self, position: DVec3, speed: f64) -> Self {
        let distance = self.last().position.distance(position);
        let orientation = self.last().orientation;
        self.check(
            speed > 0.0 && speed.is_finite(),
            "speed",
            speed,
            "must be > 0 and finite",
        )
        .push(distance / speed, position, orientation)
    }

    /// Rotates in place to `orientation` at `angular_speed` (rad/s, > 0), shortest path.
    pub fn rotate_to(self, orientation: DQuat, angular_speed: f64) -> Self {
        let last = self.last();
        let angle = rotation_vector(orientation * last.orientation.inverse()).length();
        self.check(
            angular_speed > 0.0 && angular_speed.is_finite(),
            "angular_speed",
            angular_speed,
            "must be > 0 and finite",
        )
        .push(angle / angular_speed, last.position, orientation)
    }

    /// Holds the current pose for `duration` (s, ≥ 0).
    pub fn hold(self, duration: f64) -> Self {
        let last = self.last();
        self.check(
            duration >= 0.0 && duration.is_finite(),
            "duration",
            duration,
            "must be >= 0 and finite",
        )
        .push(duration, last.position, last.orientation)
    }

    /// The script, or the first parameter error met.
    pub fn build(self) -> Result<Script, ScriptError> {
        match self.error {
            Some(e) => Err(e),
            None => Script::new(self.waypoints),
        }
    }
}

/// Where the handle meets a static surface.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceContact {
    /// Handle position at which the part just touches the surface (m).
    pub point: DVec3,
    /// Outward normal of the static surface there, pointing into free space (normalised on use;
    /// must be non-zero).
    pub normal: DVec3,
    /// Handle orientation held throughout the motion (unit quaternion).
    pub orientation: DQuat,
}

/// Where a press into a [`SurfaceContact`] starts and ends.
struct PressPoints {
    /// The contact's outward normal, normalised.
    normal: DVec3,
    /// `standoff` (m) out from the touching position along the normal.
    above: DVec3,
    /// `pace.press_depth` (m) past the touching position, along −normal.
    pressed: DVec3,
}

impl SurfaceContact {
    /// The points of a press from `standoff` (m) out to `pace.press_depth` (m) in. Errors name
    /// `normal` (zero or non-finite), `standoff` or `press_depth` (negative or non-finite), in
    /// that order.
    fn press_points(&self, standoff: f64, pace: &Pace) -> Result<PressPoints, ScriptError> {
        let normal = unit(self.normal, "normal")?;
        Ok(PressPoints {
            normal,
            above: self.point + non_negative(standoff, "standoff")? * normal,
            pressed: self.point - non_negative(pace.press_depth, "press_depth")? * normal,
        })
    }

    /// A script that starts at `start` and moves at `pace.speed` to `pace.press_depth` (m) past
    /// the touching position, along −normal. Errors name `normal` (zero or non-finite) or
    /// `press_depth` (negative or non-finite).
    fn press_from(&self, start: DVec3, pace: &Pace) -> Result<ScriptBuilder, ScriptError> {
        let pressed = self.press_points(0.0, pace)?.pressed;
        Ok(ScriptBuilder::start(start, self.orientation).move_to(pressed, pace.speed))
    }
}

/// How a built-in motion moves.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pace {
    /// Speed of straight moves (m/s, > 0).
    pub speed: f64,
    /// How far the handle target goes past the touching position into the surface (m, ≥ 0). The
    /// virtual coupling then presses with about `k_T · press_depth` (clamped by the haptic core).
    pub press_depth: f64,
    /// Time held still at each pause of the motion (s, ≥ 0).
    pub dwell: f64,
}

impl Default for Pace {
    /// 50 mm/s, 2 mm press, 0.2 s dwell: a gentle, deliberate hand.
    fn default() -> Self {
        Pace {
            speed: 0.05,
            press_depth: 0.002,
            dwell: 0.2,
        }
    }
}

fn unit(v: DVec3, name: &'static str) -> Result<DVec3, ScriptError> {
    v.try_normalize().ok_or(ScriptError::Parameter {
        name,
        value: v.length(),
        reason: "must be a non-zero finite vector",
    })
}

fn non_negative(v: f64, name: &'static str) -> Result<f64, ScriptError> {
    if v >= 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(ScriptError::Parameter {
            name,
            value: v,
            reason: "must be >= 0 and finite",
        })
    }
}

/// Approach and rest: from `start`, move straight at `pace.speed` to `pace.press_depth` past the
/// touching position (along −normal), then hold for `pace.dwell`. Exercises first contact and a
/// resting contact (the steady force should be the coupling's press, not a buzz).
pub fn approach_and_rest(
    start: DVec3,
    contact: &SurfaceContact,
    pace: &Pace,
) -> Result<Script, ScriptError> {
    contact.press_from(start, pace)?.hold(pace.dwell).build()
}

/// Slide along a surface: start `standoff` (m) above the touching position, descend and press by
/// `pace.press_depth`, dwell, slide `length` (m) along `direction` projected onto the tangent plane,
/// dwell, then lift back to the standoff. Exercises friction-free tangential motion across voxel
/// boundaries (the force direction must not jump).
pub fn slide_along_surface(
    contact: &SurfaceContact,
    standoff: f64,
    direction: DVec3,
    length: f64,
    pace: &Pace,
) -> Result<Script, ScriptError> {
    let n = unit(contact.normal, "normal")?;
    let tangent = unit(
        direction - direction.dot(n) * n,
        "direction (tangential part)",
    )?;
    let PressPoints { above, pressed, .. } = contact.press_points(standoff, pace)?;
    let slid = pressed + non_negative(length, "length")? * tangent;
    ScriptBuilder::start(above, contact.orientation)
        .move_to(pressed, pace.speed)
        .hold(pace.dwell)
        .move_to(slid, pace.speed)
        .hold(pace.dwell)
        .move_to(slid + (standoff + pace.press_depth) * n, pace.speed)
        .build()
}

/// Where the handle meets two static surfaces at once (an inside corner / groove).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CornerContact {
    /// Handle position at which the part just touches both walls (m).
    pub point: DVec3,
    /// Outward normal of the first wall (into free space; non-zero).
    pub normal_a: DVec3,
    /// Outward normal of the second wall (into free space; non-zero, not parallel to `normal_a`).
    pub normal_b: DVec3,
    /// Handle orientation held throughout (unit quaternion).
    pub orientation: DQuat,
}

/// Slide in a corner: start `standoff` (m) out of the corner along the bisector, press
/// `pace.press_depth` into each wall, dwell, slide `length` (m) along the edge (`normal_a ×
/// normal_b`), dwell, and back out. Two contact sets at once: the averaging of docs/architecture.md#the-haptic-frame and the
/// torque balance are exercised.
pub fn slide_in_corner(
    corner: &CornerContact,
    standoff: f64,
    length: f64,
    pace: &Pace,
) -> Result<Script, ScriptError> {
    let na = unit(corner.normal_a, "normal_a")?;
    let nb = unit(corner.normal_b, "normal_b")?;
    let edge = unit(na.cross(nb), "normal_a x normal_b")?;
    let out = unit(na + nb, "normal_a + normal_b")?;
    let press = non_negative(pace.press_depth, "press_depth")?;
    let pressed = corner.point - press * (na + nb);
    let slid = pressed + non_negative(length, "length")? * edge;
    let standoff = non_negative(standoff, "standoff")?;
    ScriptBuilder::start(corner.point + standoff * out, corner.orientation)
        .move_to(pressed, pace.speed)
        .hold(pace.dwell)
        .move_to(slid, pace.speed)
        .hold(pace.dwell)
        .move_to(slid + press * (na + nb) + standoff * out, pace.speed)
        .build()
}

/// High-speed collision: from `start`, hit the surface at `pace.speed` (meant to be fast, e.g.
/// 0.5–1 m/s), aiming `pace.press_depth` past the touching position, and go straight back to
/// `start` at the same speed, then hold for `pace.dwell`. Exercises pre-contact braking and the
/// tunnelling guard: the part must not pass through the force layer.
pub fn high_speed_collision(
    start: DVec3,
    contact: &SurfaceContact,
    pace: &Pace,
) -> Result<Script, ScriptError> {
    contact
        .press_from(start, pace)?
        .move_to(start, pace.speed)
        .hold(pace.dwell)
        .build()
}

/// Wedge: the contact is the apex of a V-groove or gap, `normal` its opening direction. Start
/// `standoff` (m) out along the opening, push in `pace.press_depth` past the touching position,
/// dwell, twist the handle by `+twist` then `−twist` (rad) about the opening axis at `twist_rate`
/// (rad/s), return to the untwisted pose, dwell, withdraw. Loads many contacts on opposing walls
/// and large torques at once.
pub fn wedge(
    apex: &SurfaceContact,
    standoff: f64,
    twist: f64,
    twist_rate: f64,
    pace: &Pace,
) -> Result<Script, ScriptError> {
    let PressPoints {
        normal: n,
        above,
        pressed,
    } = apex.press_points(standoff, pace)?;
    let twist = non_negative(twist, "twist")?;
    let q0 = apex.orientation;
    ScriptBuilder::start(above, q0)
        .move_to(pressed, pace.speed)
        .hold(pace.dwell)
        .rotate_to(DQuat::from_axis_angle(n, twist) * q0, twist_rate)
        .rotate_to(DQuat::from_axis_angle(n, -twist) * q0, twist_rate)
        .rotate_to(q0, twist_rate)
        .hold(pace.dwell)
        .move_to(above, pace.speed)
        .build()
}

/// Through a path: visit `waypoints` (m) in order along straight segments at constant `speed`
/// (m/s), holding `orientation`; repeated consecutive points are skipped. For threading a part
/// along a corridor (e.g. the teapot through the aircraft bay).
pub fn through_path(
    waypoints: &[DVec3],
    orientation: DQuat,
    speed: f64,
) -> Result<Script, ScriptError> {
    let (first, rest) = waypoints.split_first().ok_or(ScriptError::Empty)?;
    rest.iter()
        .fold(ScriptBuilder::start(*first, orientation), |b, &p| {
            b.move_to(p, speed)
        })
        .build()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wp(time: f64, x: f64) -> Waypoint {
        Waypoint {
            time,
            position: DVec3::new(x, 0.0, 0.0),
            orientation: DQuat::IDENTITY,
        }
    }

    fn contact() -> SurfaceContact {
        SurfaceContact {
            point: DVec3::new(0.0, 0.0, 0.01),
            normal: DVec3::Z,
            orientation: DQuat::IDENTITY,
        }
    }

    /// Largest jump between samples `dt` apart, against the largest script speed.
    fn assert_continuous(s: &Script, max_speed: f64, max_rate: f64) {
        let dt = 1e-4;
        let steps = ((s.duration() + 0.5) / dt) as usize;
        let (mut p0, mut q0) = s.sample(-0.1);
        for i in 0..steps {
            let (p, q) = s.sample(-0.1 + (i + 1) as f64 * dt);
            assert!(
                p.distance(p0) <= max_speed * dt * 1.0001 + 1e-12,
                "jump at step {i}"
            );
            assert!(
                q.angle_between(q0) <= max_rate * dt * 1.0001 + 1e-9,
                "twist jump at step {i}"
            );
            assert!((q.length() - 1.0).abs() < 1e-9);
            (p0, q0) = (p, q);
        }
    }

    #[test]
    fn validation_names_the_waypoint() {
        assert_eq!(Script::new(vec![]), Err(ScriptError::Empty));
        let e = Script::new(vec![wp(0.0, 0.0), wp(1.0, 1.0), wp(1.0, 2.0)]).unwrap_err();
        assert!(matches!(e, ScriptError::TimeOrder { index: 2, .. }), "{e}");
        let e = Script::new(vec![wp(0.0, 0.0), wp(1.0, f64::NAN)]).unwrap_err();
        assert_eq!(
            e,
            ScriptError::NonFinite {
                index: 1,
                field: "position"
            }
        );
        let mut bad = wp(0.5, 0.0);
        bad.orientation = DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0);
        assert!(matches!(
            Script::new(vec![bad]),
            Err(ScriptError::NotUnit { index: 0, .. })
        ));
        assert!(matches!(
            Script::new(vec![wp(-1.0, 0.0)]),
            Err(ScriptError::TimeOrder { index: 0, .. })
        ));
    }

    #[test]
    fn sample_interpolates_and_holds_the_ends() {
        let s = Script::new(vec![wp(1.0, 0.0), wp(3.0, 2.0)]).unwrap();
        assert_eq!(s.duration(), 3.0);
        assert_eq!(s.sample(0.0).0.x, 0.0);
        assert_eq!(s.sample(f64::NAN).0.x, 0.0);
        assert!((s.sample(2.0).0.x - 1.0).abs() < 1e-15);
        assert_eq!(s.sample(10.0).0.x, 2.0);
        assert_eq!(s.velocity(2.0).0, DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(s.velocity(0.5).0, DVec3::ZERO);
    }

    #[test]
    fn angular_velocity_matches_slerp() {
        let a = Waypoint {
            time: 0.0,
            position: DVec3::ZERO,
            orientation: DQuat::IDENTITY,
        };
        let b = Waypoint {
            time: 2.0,
            position: DVec3::ZERO,
            orientation: DQuat::from_rotation_y(1.0),
        };
        let s = Script::new(vec![a, b]).unwrap();
        let (_, w) = s.velocity(1.0);
        assert!((w - DVec3::new(0.0, 0.5, 0.0)).length() < 1e-12);
        let (_, q) = s.sample(1.0);
        assert!(q.angle_between(DQuat::from_rotation_y(0.5)) < 1e-9);
    }

    #[test]
    fn builtins_are_continuous_and_reach_their_targets() {
        let pace = Pace::default();
        let c = contact();
        let rest = approach_and_rest(DVec3::new(0.0, 0.0, 0.05), &c, &pace).unwrap();
        assert_continuous(&rest, pace.speed, 0.0);
        let end = rest.sample(rest.duration()).0;
        assert!((end - DVec3::new(0.0, 0.0, 0.008)).length() < 1e-12);
        assert!((rest.duration() - (0.042 / 0.05 + 0.2)).abs() < 1e-12);

        let slide = slide_along_surface(&c, 0.01, DVec3::new(1.0, 0.0, 1.0), 0.05, &pace).unwrap();
        assert_continuous(&slide, pace.speed, 0.0);
        let moved = slide.waypoints()[3].position - slide.waypoints()[2].position;
        assert!(
            (moved - DVec3::new(0.05, 0.0, 0.0)).length() < 1e-12,
            "{moved}"
        );

        let corner = CornerContact {
            point: DVec3::ZERO,
            normal_a: DVec3::X,
            normal_b: DVec3::Y,
            orientation: DQuat::IDENTITY,
        };
        let s = slide_in_corner(&corner, 0.01, 0.03, &pace).unwrap();
        assert_continuous(&s, pace.speed, 0.0);
        let edge = s.waypoints()[3].position - s.waypoints()[2].position;
        assert!(
            (edge - DVec3::new(0.0, 0.0, 0.03)).length() < 1e-12,
            "{edge}"
        );

        let fast = Pace { speed: 1.0, ..pace };
        let hit = high_speed_collision(DVec3::new(0.0, 0.0, 0.1), &c, &fast).unwrap();
        assert_continuous(&hit, 1.0, 0.0);
        assert_eq!(hit.sample(hit.duration()).0, DVec3::new(0.0, 0.0, 0.1));

        let w = wedge(&c, 0.01, 0.3, 1.5, &pace).unwrap();
        assert_continuous(&w, pace.speed, 1.5);
        let twisted = w.waypoints()[3].orientation;
        assert!((twisted.angle_between(DQuat::IDENTITY) - 0.3).abs() < 1e-9);

        let path = [
            DVec3::ZERO,
            DVec3::X * 0.1,
            DVec3::X * 0.1,
            DVec3::new(0.1, 0.1, 0.0),
        ];
        let p = through_path(&path, DQuat::IDENTITY, 0.2).unwrap();
        assert_continuous(&p, 0.2, 0.0);
        assert!((p.duration() - 1.0).abs() < 1e-12);
        assert_eq!(p.waypoints().len(), 3);
    }

    #[test]
    fn builtins_reject_bad_geometry() {
        let mut c = contact();
        c.normal = DVec3::ZERO;
        let e = approach_and_rest(DVec3::ZERO, &c, &Pace::default()).unwrap_err();
        assert!(
            matches!(e, ScriptError::Parameter { name: "normal", .. }),
            "{e}"
        );
        let e =
            slide_along_surface(&contact(), 0.01, DVec3::Z, 0.05, &Pace::default()).unwrap_err();
        assert!(matches!(e, ScriptError::Parameter { .. }), "{e}");
        let e = through_path(&[DVec3::ZERO, DVec3::X], DQuat::IDENTITY, 0.0).unwrap_err();
        assert!(
            matches!(e, ScriptError::Parameter { name: "speed", .. }),
            "{e}"
        );
        assert_eq!(
            through_path(&[], DQuat::IDENTITY, 1.0),
            Err(ScriptError::Empty)
        );
    }
}
