//! What a robot's safety is configured with: its side of the teleoperation pair, its limits
//! and timeouts, how it holds and what a fault commands, and the check of all that.

use core::fmt;
use core::time::Duration;

use penelope_hal::{JointLimits, JointVector, MAX_JOINTS};

/// Which side of a teleoperation pair a robot is on: it decides what a stale reference does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TeleopRole {
    /// The operator's hand controller: a stale reference means zero force.
    Master,
    /// The remote arm: a stale reference means hold position.
    Slave,
}

/// How a slave holds its position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HoldMode {
    /// Ask the board's own position servo to hold the encoder counts
    /// ([`penelope_hal::AxisCommand::Position`]).
    BoardServo,
    /// A joint PD around the hold position plus the model's gravity torque, sent as efforts:
    /// gains in N·m/rad and N·m·s/rad.
    Pd {
        /// Stiffness per joint, N·m/rad.
        kp: JointVector,
        /// Damping per joint, N·m·s/rad.
        kd: JointVector,
    },
}

/// What a faulted robot does until it is re-armed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultAction {
    /// Hold the last good measured position (see [`HoldMode`]).
    Hold,
    /// Amplifiers off.
    Off,
}

/// The limits and timeouts of one robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SafetyConfig {
    /// Master or slave.
    pub role: TeleopRole,
    /// Joints in use (1 to [`MAX_JOINTS`]); entries past it are ignored and commanded zero.
    pub joint_count: usize,
    /// Position, velocity and torque limits. Measured positions or speeds outside them fault;
    /// commanded torques and positions are clamped to them.
    pub limits: JointLimits,
    /// A reference older than this is stale.
    pub watchdog: Duration,
    /// Stale for this long (after `watchdog`) means fault.
    pub stale_to_fault: Duration,
    /// Largest force a master may display, N (norm of the reference wrench's force).
    pub max_force: f64,
    /// Largest moment a master may display, N·m (norm of the reference wrench's moment).
    pub max_moment: f64,
    /// How a slave holds position.
    pub hold: HoldMode,
    /// What a fault commands.
    pub fault_action: FaultAction,
}

impl SafetyConfig {
    /// A slave's defaults: 50 ms watchdog, fault after 500 ms more, hold with the board's servo,
    /// hold on fault. Force limits are not applied to a slave.
    pub fn slave(joint_count: usize, limits: JointLimits) -> Self {
        SafetyConfig {
            role: TeleopRole::Slave,
            joint_count,
            limits,
            watchdog: Duration::from_millis(50),
            stale_to_fault: Duration::from_millis(500),
            max_force: f64::INFINITY,
            max_moment: f64::INFINITY,
            hold: HoldMode::BoardServo,
            fault_action: FaultAction::Hold,
        }
    }

    /// A master's defaults: the FRHC's 10 N / 0.5 N·m display limits, 50 ms watchdog, fault after
    /// 500 ms more, amplifiers off on fault.
    pub fn master(joint_count: usize, limits: JointLimits) -> Self {
        SafetyConfig {
            role: TeleopRole::Master,
            max_force: 10.0,
            max_moment: 0.5,
            fault_action: FaultAction::Off,
            ..SafetyConfig::slave(joint_count, limits)
        }
    }

    /// Checks the configuration.
    ///
    /// # Errors
    /// [`SafetyConfigError`] naming the first bad field.
    pub fn validate(&self) -> Result<(), SafetyConfigError> {
        if self.joint_count == 0 || self.joint_count > MAX_JOINTS {
            return Err(SafetyConfigError::JointCount);
        }
        if self.watchdog.is_zero() {
            return Err(SafetyConfigError::Watchdog);
        }
        for j in 0..self.joint_count {
            let l = &self.limits;
            let ok = !l.position_min[j].is_nan()
                && !l.position_max[j].is_nan()
                && l.position_min[j] <= l.position_max[j]
                && l.velocity_max[j] > 0.0
                && l.effort_max[j] > 0.0;
            if !ok {
                return Err(SafetyConfigError::Limits { joint: j as u8 });
            }
        }
        if !(self.max_force > 0.0 && self.max_moment > 0.0) {
            return Err(SafetyConfigError::ForceLimit);
        }
        if let HoldMode::Pd { kp, kd } = self.hold {
            let ok = (0..self.joint_count)
                .all(|j| kp[j].is_finite() && kd[j].is_finite() && kp[j] >= 0.0 && kd[j] >= 0.0);
            if !ok {
                return Err(SafetyConfigError::HoldGains);
            }
        }
        Ok(())
    }
}

/// A bad [`SafetyConfig`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SafetyConfigError {
    /// `joint_count` is zero or above [`MAX_JOINTS`].
    JointCount,
    /// The watchdog timeout is zero.
    Watchdog,
    /// A joint's limits are NaN, inverted, or not positive.
    Limits {
        /// The joint (0-based).
        joint: u8,
    },
    /// A force or moment limit is not positive.
    ForceLimit,
    /// A hold gain is negative or not finite.
    HoldGains,
}

impl fmt::Display for SafetyConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SafetyConfigError::JointCount => write!(f, "joint count must be 1 to {MAX_JOINTS}"),
            SafetyConfigError::Watchdog => f.write_str("watchdog timeout must be above zero"),
            SafetyConfigError::Limits { joint } => {
                write!(
                    f,
                    "joint {joint}: limits must be ordered, finite where bounded, and positive"
                )
            }
            SafetyConfigError::ForceLimit => {
                f.write_str("force and moment limits must be positive")
            }
            SafetyConfigError::HoldGains => {
                f.write_str("hold gains must be finite and non-negative")
            }
        }
    }
}
