//! A control loop's configuration: its period, its safety settings and, per joint, the board
//! axis that drives it with its encoder scaling.

use core::fmt;
use core::time::Duration;

use penelope_hal::{AxisCommand, MAX_AXES, MAX_JOINTS, Robot};

use crate::safety::{SafetyConfig, SafetyConfigError};

/// Which board axis drives a joint, and its encoder scaling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisBinding {
    /// The board axis (0-based).
    pub axis: u8,
    /// Encoder counts per radian of joint motion (gear ratio included; the sign is the counting
    /// direction).
    pub counts_per_radian: f64,
    /// Encoder reading at joint position zero, counts.
    pub offset_counts: i64,
}

impl AxisBinding {
    /// Joint on `axis` with `counts_per_radian` and no offset.
    pub const fn new(axis: u8, counts_per_radian: f64) -> Self {
        AxisBinding {
            axis,
            counts_per_radian,
            offset_counts: 0,
        }
    }
}

/// The board's position target for joint position `q`, rad, on axis binding `b`.
pub(super) fn position_counts(q: f64, b: AxisBinding) -> AxisCommand {
    let counts = libm::round(q * b.counts_per_radian) as i64;
    AxisCommand::Position(counts.wrapping_add(b.offset_counts))
}

/// Configuration of a [`ControlLoop`](super::ControlLoop).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlConfig {
    /// The control period `T_ctrl` (passed to controllers).
    pub period: Duration,
    /// Safety limits, watchdog and role; `safety.joint_count` is the number of joints.
    pub safety: SafetyConfig,
    /// Joint `j` is driven by `axes[j]`.
    pub axes: [AxisBinding; MAX_JOINTS],
    /// Compute the tool position (forward kinematics) every tick for telemetry.
    pub tool_position: bool,
    /// Consecutive failed board reads tolerated (the tick is skipped) before faulting.
    pub board_read_tolerance: u32,
    /// After a re-arm, how close a fresh reference must be to where the robot is held before
    /// it is followed (the robot holds until then): rad for joint positions and orientations, m for
    /// tool positions.
    pub resume_tolerance: f64,
}

/// The default [`ControlConfig::resume_tolerance`]: 2 mrad (2 mm for tool positions).
pub const DEFAULT_RESUME_TOLERANCE: f64 = 2e-3;

impl ControlConfig {
    /// Joint `j` on axis `j` at 1 count per radian, tool position on, 2 failed reads tolerated.
    pub fn new(period: Duration, safety: SafetyConfig) -> Self {
        let mut axes = [AxisBinding::new(0, 1.0); MAX_JOINTS];
        for (j, a) in axes.iter_mut().enumerate() {
            a.axis = j as u8;
        }
        ControlConfig {
            period,
            safety,
            axes,
            tool_position: true,
            board_read_tolerance: 2,
            resume_tolerance: DEFAULT_RESUME_TOLERANCE,
        }
    }

    /// The same encoder scaling on every joint.
    pub fn with_counts_per_radian(mut self, counts_per_radian: f64) -> Self {
        for a in &mut self.axes {
            a.counts_per_radian = counts_per_radian;
        }
        self
    }

    /// Joint `j` on axis `j`, scaled by the robot's [`Robot::counts_per_radian`].
    pub fn with_robot_scaling(mut self, robot: &impl Robot) -> Self {
        for (j, a) in self.axes.iter_mut().enumerate() {
            a.counts_per_radian = robot.counts_per_radian(j);
        }
        self
    }

    /// Binds `joint` to `binding` (ignored for a joint index past [`MAX_JOINTS`]).
    pub fn with_axis(mut self, joint: usize, binding: AxisBinding) -> Self {
        if let Some(a) = self.axes.get_mut(joint) {
            *a = binding;
        }
        self
    }

    /// Checks the configuration against a board with `axis_count` axes.
    ///
    /// # Errors
    /// [`ControlConfigError`] naming the first problem.
    pub fn validate(&self, axis_count: usize) -> Result<(), ControlConfigError> {
        self.safety.validate().map_err(ControlConfigError::Safety)?;
        if self.period.is_zero() {
            return Err(ControlConfigError::Period);
        }
        let n = self.safety.joint_count;
        for j in 0..n {
            let b = self.axes[j];
            if usize::from(b.axis) >= axis_count.min(MAX_AXES) {
                return Err(ControlConfigError::AxisOutOfRange { joint: j as u8 });
            }
            if !(b.counts_per_radian.is_finite() && b.counts_per_radian != 0.0) {
                return Err(ControlConfigError::CountsPerRadian { joint: j as u8 });
            }
            if self.axes[..j].iter().any(|o| o.axis == b.axis) {
                return Err(ControlConfigError::DuplicateAxis { joint: j as u8 });
            }
        }
        Ok(())
    }
}

/// Why a [`ControlLoop`](super::ControlLoop) could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlConfigError {
    /// The safety configuration is bad.
    Safety(SafetyConfigError),
    /// The period is zero.
    Period,
    /// A joint is bound to an axis the board does not have.
    AxisOutOfRange {
        /// The joint (0-based).
        joint: u8,
    },
    /// Two joints share an axis.
    DuplicateAxis {
        /// The second joint bound to the axis (0-based).
        joint: u8,
    },
    /// A joint's counts per radian is zero or not finite.
    CountsPerRadian {
        /// The joint (0-based).
        joint: u8,
    },
    /// The controller set is empty.
    NoController,
}

impl fmt::Display for ControlConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ControlConfigError::Safety(e) => write!(f, "safety: {e}"),
            ControlConfigError::Period => f.write_str("control period must be above zero"),
            ControlConfigError::AxisOutOfRange { joint } => {
                write!(
                    f,
                    "joint {joint} is bound to an axis the board does not have"
                )
            }
            ControlConfigError::DuplicateAxis { joint } => {
                write!(f, "joint {joint} shares its axis with another joint")
            }
            ControlConfigError::CountsPerRadian { joint } => {
                write!(
                    f,
                    "joint {joint}: counts per radian must be finite and non-zero"
                )
            }
            ControlConfigError::NoController => f.write_str("at least one controller is needed"),
        }
    }
}
