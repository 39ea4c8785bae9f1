//! Controllers: algorithms that turn a reference and a state into joint commands.

use core::fmt;
use core::time::Duration;

use crate::error::{Error, ErrorKind};
use crate::joint::{JointState, JointVector};
use crate::reference::Reference;
use crate::robot::RobotModel;
use crate::spatial::Wrench;
use crate::time::Timestamp;

/// Everything a controller sees in one control tick.
#[derive(Clone, Copy)]
pub struct ControlInput<'a> {
    /// The tick's time.
    pub now: Timestamp,
    /// The control period.
    pub period: Duration,
    /// The measured joint state.
    pub state: &'a JointState,
    /// The reference to follow (already checked finite and fresh by the loop's safety layer).
    pub reference: &'a Reference,
    /// The latest wrench from the robot's force sensor, in the base frame about the tool origin,
    /// if the controller is bound to one.
    pub wrench: Option<&'a Wrench>,
    /// The robot's model (kinematics and dynamics).
    pub model: &'a dyn RobotModel,
}

/// What a controller asks of the joints.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum JointCommand {
    /// Joint torques, N·m.
    Effort(JointVector),
    /// Joint positions for the board's own servo loop, rad.
    Position(JointVector),
    /// Per joint: a position target for the joints in `position_joints`, a torque for the
    /// others (controllers of one robot driving different joint sets with different laws).
    Mixed {
        /// Joint torques, N·m (joints not in `position_joints`).
        effort: JointVector,
        /// Joint positions, rad (joints in `position_joints`).
        position: JointVector,
        /// The joints given position targets.
        position_joints: crate::joint::JointSet,
    },
}

/// Why a controller could not compute a command this tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ControllerError {
    /// The reference is of a kind this controller does not follow (for example a wrench reference
    /// given to a joint PID).
    UnsupportedReference,
    /// A required input (a force sensor) is not bound.
    MissingInput,
    /// The controller computed a non-finite command.
    NonFinite,
    /// Inverse kinematics failed for a Cartesian reference.
    Kinematics(crate::robot::KinematicsError),
}

impl fmt::Display for ControllerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ControllerError::UnsupportedReference => f.write_str("reference kind not supported"),
            ControllerError::MissingInput => f.write_str("a required input is not bound"),
            ControllerError::NonFinite => f.write_str("command is NaN or infinite"),
            ControllerError::Kinematics(e) => write!(f, "kinematics: {e}"),
        }
    }
}

impl Error for ControllerError {
    fn kind(&self) -> ErrorKind {
        match self {
            ControllerError::UnsupportedReference | ControllerError::MissingInput => {
                ErrorKind::InvalidInput
            }
            ControllerError::NonFinite => ErrorKind::NonFinite,
            ControllerError::Kinematics(e) => e.kind(),
        }
    }
}

/// A control law.
///
/// # Real-time
/// [`update`](Controller::update) and [`activate`](Controller::activate) run in the control
/// thread: no allocation, no locks, no blocking, bounded time.
pub trait Controller {
    /// The controller's kind, for example `"joint-pid"`.
    fn kind(&self) -> &'static str;

    /// Starts from the measured state so the first command does not jump (integrators cleared,
    /// hold positions set to `measured`).
    fn activate(&mut self, now: Timestamp, measured: &JointState, model: &dyn RobotModel);

    /// One control tick.
    ///
    /// # Errors
    /// [`ControllerError`]; the loop then applies its safe fallback.
    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError>;

    /// The energy its passivity observer reads on the law's port since activation, J, if the
    /// law has one: energy that has flowed from the device into the law (or, for a two-port
    /// observer, what the law may still give out). Negative means the law has given out more
    /// than it received: a live stability monitor, copied into every telemetry sample. `None`
    /// (the default) for laws without an observer.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    fn port_energy(&self) -> Option<f64> {
        None
    }
}
