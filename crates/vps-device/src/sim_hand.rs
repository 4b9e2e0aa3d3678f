//! A simulated hand: a mass-spring-damper that follows a [`Script`] target and feels the wrench
//! written to the device. Closed loop: the haptic loop's force pushes the hand back, the hand's
//! spring pushes on through the virtual coupling, exactly as a person's arm would.
//!
//! Model (world frame, semi-implicit Euler at a fixed sub-step of at most
//! [`HandParams::max_substep`], integrated inside [`HapticDevice::read`] up to the time passed in):
//! `m a = k (x_t − x) + c (v_t − v) + F_dev`, `I α = k_R θ + c_R (ω_t − ω) + T_dev`, θ = axis × angle
//! of `q_t q⁻¹`, with `c = 2 ζ sqrt(k m)` and `c_R = 2 ζ sqrt(k_R I)`. The target velocity comes from
//! the script, so the hand tracks a moving target without lag in free space. Under a constant device
//! force it settles offset from the target by `F / k`.

use crate::device::{check_sample, DeviceError, DeviceLimits, HapticDevice};
use crate::rotation::rotation_vector;
use crate::script::Script;
use glam::{DQuat, DVec3};
use vps_haptic::{HandleSample, Wrench};

/// Physical parameters of the simulated hand. Invariant (checked by [`SimulatedHand::new`]): all
/// finite, all > 0 except `damping_ratio` ≥ 0.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HandParams {
    /// Mass of hand, arm and handle (kg).
    pub mass: f64,
    /// Translational stiffness of the arm toward the scripted target (N/m).
    pub stiffness: f64,
    /// Rotational inertia of the hand about its grip, isotropic (kg·m²).
    pub inertia: f64,
    /// Rotational stiffness toward the scripted orientation (N·m/rad).
    pub angular_stiffness: f64,
    /// Damping ratio ζ for both translation and rotation (1 = critical).
    pub damping_ratio: f64,
    /// Largest integration sub-step (s).
    pub max_substep: f64,
    /// The device's limits: written wrenches are saturated to them.
    pub limits: DeviceLimits,
}

impl Default for HandParams {
    /// 0.5 kg at 300 N/m (≈ 3.9 Hz), 1e-3 kg·m² at 2 N·m/rad, critically damped, 0.25 ms sub-steps,
    /// the paper's 15 N / 0.1 N·m device.
    fn default() -> Self {
        HandParams {
            mass: 0.5,
            stiffness: 300.0,
            inertia: 1e-3,
            angular_stiffness: 2.0,
            damping_ratio: 1.0,
            max_substep: 2.5e-4,
            limits: DeviceLimits::PAPER,
        }
    }
}

impl HandParams {
    fn validate(&self) -> Result<(), DeviceError> {
        let positive = [
            ("mass", self.mass),
            ("stiffness", self.stiffness),
            ("inertia", self.inertia),
            ("angular_stiffness", self.angular_stiffness),
            ("max_substep", self.max_substep),
            ("limits.max_force", self.limits.max_force),
            ("limits.max_torque", self.limits.max_torque),
        ];
        let bad = positive
            .iter()
            .find(|(_, v)| !(v.is_finite() && *v > 0.0))
            .map(|(n, v)| format!("{n} = {v} must be finite and > 0"))
            .or_else(|| {
                (!(self.damping_ratio.is_finite() && self.damping_ratio >= 0.0)).then(|| {
                    format!(
                        "damping_ratio = {} must be finite and >= 0",
                        self.damping_ratio
                    )
                })
            });
        match bad {
            None => Ok(()),
            Some(message) => Err(DeviceError::Config {
                device: SimulatedHand::NAME.to_string(),
                message,
            }),
        }
    }
}

/// The simulated hand device. Starts at rest at the script's first pose at time 0.
#[derive(Clone, Debug)]
pub struct SimulatedHand {
    script: Script,
    params: HandParams,
    time: f64,
    position: DVec3,
    orientation: DQuat,
    linear_velocity: DVec3,
    angular_velocity: DVec3,
    applied: Wrench,
}

impl SimulatedHand {
    /// The name reported by [`HapticDevice::name`].
    pub const NAME: &'static str = "simulated-hand";

    /// A hand at rest at `script`'s first pose; errors on invalid `params`.
    pub fn new(script: Script, params: HandParams) -> Result<SimulatedHand, DeviceError> {
        params.validate()?;
        let (position, orientation) = script.sample(0.0);
        Ok(SimulatedHand {
            script,
            params,
            time: 0.0,
            position,
            orientation,
            linear_velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
            applied: Wrench::ZERO,
        })
    }

    /// The script the hand follows.
    pub fn script(&self) -> &Script {
        &self.script
    }

    /// The wrench currently acting on the hand (the last write, saturated).
    pub fn applied_wrench(&self) -> Wrench {
        self.applied
    }

    /// The hand's state at the last integrated time, without advancing it.
    pub fn current(&self) -> HandleSample {
        HandleSample {
            position: self.position,
            orientation: self.orientation,
            linear_velocity: self.linear_velocity,
            angular_velocity: self.angular_velocity,
        }
    }

    /// One semi-implicit Euler step of length `h` (s) ending at `self.time + h`.
    fn substep(&mut self, h: f64) {
        let p = &self.params;
        let t = self.time;
        let (x_t, q_t) = self.script.sample(t);
        let (v_t, w_t) = self.script.velocity(t);
        let c = 2.0 * p.damping_ratio * (p.stiffness * p.mass).sqrt();
        let c_r = 2.0 * p.damping_ratio * (p.angular_stiffness * p.inertia).sqrt();
        let force = p.stiffness * (x_t - self.position)
            + c * (v_t - self.linear_velocity)
            + self.applied.force;
        let theta = rotation_vector(q_t * self.orientation.inverse());
        let torque =
            p.angular_stiffness * theta + c_r * (w_t - self.angular_velocity) + self.applied.torque;
        self.linear_velocity += force / p.mass * h;
        self.position += self.linear_velocity * h;
        self.angular_velocity += torque / p.inertia * h;
        self.orientation =
            (DQuat::from_scaled_axis(self.angular_velocity * h) * self.orientation).normalize();
        self.time = t + h;
    }
}

impl HapticDevice for SimulatedHand {
    /// Integrates from the previous time to `t` in equal sub-steps of at most `max_substep`, then
    /// returns the hand's state. Never blocks; cost is proportional to the time advanced.
    fn read(&mut self, t: f64) -> Result<HandleSample, DeviceError> {
        if !t.is_finite() || t < self.time {
            return Err(DeviceError::TimeWentBackwards {
                device: Self::NAME.to_string(),
                previous: self.time,
                now: t,
            });
        }
        let span = t - self.time;
        let steps = (span / self.params.max_substep).ceil() as u64;
        let start = self.time;
        for i in 0..steps {
            let h = span / steps as f64;
            self.substep(h);
            // Keep the clock exact rather than a running sum of rounded sub-steps.
            self.time = start + span * (i + 1) as f64 / steps as f64;
        }
        let sample = self.current();
        check_sample(Self::NAME, &sample)?;
        Ok(sample)
    }

    /// Holds `wrench` (saturated to the limits) on the hand until the next write. Never blocks.
    fn write(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        if !wrench.force.is_finite() || !wrench.torque.is_finite() {
            return Err(DeviceError::NonFinite {
                device: Self::NAME.to_string(),
                what: "written wrench",
            });
        }
        self.applied = self.params.limits.saturate(wrench);
        Ok(())
    }

    fn limits(&self) -> DeviceLimits {
        self.params.limits
    }

    fn name(&self) -> &str {
        Self::NAME
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::script::{ScriptBuilder, Waypoint};

    fn still(at: DVec3, q: DQuat) -> Script {
        Script::new(vec![Waypoint {
            time: 0.0,
            position: at,
            orientation: q,
        }])
        .unwrap()
    }

    /// Runs the hand at 1 kHz for `seconds`, writing `wrench` every frame.
    fn run(hand: &mut SimulatedHand, seconds: f64, wrench: Wrench) -> HandleSample {
        let mut last = hand.current();
        for n in 1..=(seconds * 1000.0) as u64 {
            last = hand.read(n as f64 * 1e-3).unwrap();
            hand.write(&wrench).unwrap();
        }
        last
    }

    #[test]
    fn follows_a_moved_target_and_settles() {
        let target = DVec3::new(0.1, -0.05, 0.02);
        let q = DQuat::from_rotation_x(0.4);
        let script = ScriptBuilder::start(DVec3::ZERO, DQuat::IDENTITY)
            .move_to(target, 0.5)
            .rotate_to(q, 2.0)
            .build()
            .unwrap();
        let mut hand = SimulatedHand::new(script, HandParams::default()).unwrap();
        let s = run(&mut hand, 3.0, Wrench::ZERO);
        assert!(s.position.distance(target) < 1e-5, "{}", s.position);
        assert!(s.orientation.angle_between(q) < 1e-4);
        assert!(s.linear_velocity.length() < 1e-4);
        assert!(s.angular_velocity.length() < 1e-3);
    }

    #[test]
    fn constant_force_settles_offset_by_f_over_k() {
        let params = HandParams::default();
        let mut hand = SimulatedHand::new(still(DVec3::ZERO, DQuat::IDENTITY), params).unwrap();
        let push = Wrench {
            force: DVec3::new(0.0, 0.0, 6.0),
            torque: DVec3::new(0.02, 0.0, 0.0),
        };
        let s = run(&mut hand, 3.0, push);
        let expected = 6.0 / params.stiffness;
        assert!(
            (s.position.z - expected).abs() < 1e-6,
            "{} vs {expected}",
            s.position.z
        );
        assert!(s.position.x.abs() < 1e-9 && s.position.y.abs() < 1e-9);
        let angle = rotation_vector(s.orientation);
        assert!(
            (angle.x - 0.02 / params.angular_stiffness).abs() < 1e-4,
            "{angle}"
        );
    }

    #[test]
    fn writes_are_saturated_and_non_finite_rejected() {
        let mut hand =
            SimulatedHand::new(still(DVec3::ZERO, DQuat::IDENTITY), HandParams::default()).unwrap();
        hand.write(&Wrench {
            force: DVec3::new(100.0, 0.0, 0.0),
            torque: DVec3::ZERO,
        })
        .unwrap();
        assert!((hand.applied_wrench().force.x - 15.0).abs() < 1e-12);
        let bad = Wrench {
            force: DVec3::new(f64::INFINITY, 0.0, 0.0),
            torque: DVec3::ZERO,
        };
        assert!(matches!(
            hand.write(&bad),
            Err(DeviceError::NonFinite { .. })
        ));
        assert!((hand.applied_wrench().force.x - 15.0).abs() < 1e-12);
    }

    #[test]
    fn time_must_not_go_backwards_and_reads_are_deterministic() {
        let mut a =
            SimulatedHand::new(still(DVec3::X, DQuat::IDENTITY), HandParams::default()).unwrap();
        a.read(0.5).unwrap();
        assert!(matches!(
            a.read(0.4),
            Err(DeviceError::TimeWentBackwards { .. })
        ));
        assert!(a.read(f64::NAN).is_err());
        let mut b =
            SimulatedHand::new(still(DVec3::X, DQuat::IDENTITY), HandParams::default()).unwrap();
        b.read(0.5).unwrap();
        assert_eq!(a.read(0.7).unwrap(), b.read(0.7).unwrap());
    }

    #[test]
    fn invalid_params_are_named() {
        let p = HandParams {
            mass: 0.0,
            ..HandParams::default()
        };
        let e = SimulatedHand::new(still(DVec3::ZERO, DQuat::IDENTITY), p).unwrap_err();
        assert!(e.to_string().contains("mass"), "{e}");
    }
}
