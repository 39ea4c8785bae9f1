//! The object calls: the methods of each class of object (robot, board, sensor, controller,
//! trajectory).

#[cfg(doc)]
use crate::proto::CallError;
use penelope_hal::{NamedPose, Transition};
use serde::{Deserialize, Serialize};

use super::{Joints, PoseMsg, WrenchMsg};
#[cfg(doc)]
use super::{Reply, WireError};

/// A method of an object. Methods of a class the object is not are refused with
/// [`CallError::WrongClass`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Method {
    /// What the object is: [`Reply::Object`].
    Describe,
    /// A lifecycle transition (`configure`, `activate`, `deactivate`, `cleanup`, `shutdown`,
    /// `reset`): [`Reply::Object`] with the new state. Runs on the non-real-time side; reaches a
    /// running loop through its command ring.
    Transition(Transition),
    /// A robot's method.
    Robot(RobotMethod),
    /// A board's method.
    Board(BoardMethod),
    /// A sensor's method.
    Sensor(SensorMethod),
    /// A controller's method.
    Controller(ControllerMethod),
    /// A trajectory's method.
    Trajectory(TrajectoryMethod),
}

/// Robot methods (the paper's `Puma200` class). `q: None` means "the measured joint positions".
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum RobotMethod {
    /// Measured joint positions, rad: [`Reply::Joints`].
    JointPositions,
    /// Measured joint velocities, rad/s: [`Reply::Joints`].
    JointVelocities,
    /// Estimated joint accelerations, rad/s²: [`Reply::Joints`].
    JointAccelerations,
    /// Operational-space state at the measured joints (tool pose, twist): [`Reply::Operational`].
    Operational,
    /// The wrench at the tool from the bound force sensor, N and N·m in the base frame:
    /// [`Reply::Wrench`].
    ToolWrench,
    /// Forward kinematics: [`Reply::Pose`] (position and the three orientation versors).
    ForwardKinematics {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Geometric Jacobian in the base frame, `[v; w]` rows: [`Reply::Matrix`] (6 × n).
    Jacobian {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Damped least-squares inverse of the Jacobian: [`Reply::Matrix`] (n × 6).
    JacobianInverse {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
        /// Damping λ (dimensionless, around 0.01).
        damping: f64,
    },
    /// Inverse kinematics: every branch within the joint limits: [`Reply::Solutions`].
    InverseKinematics {
        /// The target tool pose in the base frame.
        pose: PoseMsg,
    },
    /// Joint torques that balance a tool wrench, `tau = Jᵀ F`: [`Reply::Joints`] (N·m).
    WrenchToTorques {
        /// The wrench at the tool, base frame.
        wrench: WrenchMsg,
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Gravity torques, N·m: [`Reply::Joints`].
    Gravity {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Joint-space inertia matrix, kg·m²: [`Reply::Matrix`] (n × n).
    Inertia {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Encoder counts to joint radians: [`Reply::Joints`].
    CountsToRadians {
        /// One count per joint.
        counts: Vec<i64>,
    },
    /// Joint radians to encoder counts: [`Reply::Counts`].
    RadiansToCounts {
        /// One angle per joint, rad.
        q: Joints,
    },
    /// The joint positions of a named pose: [`Reply::Joints`].
    NamedPose {
        /// `nest`, `start` or `work`.
        pose: NamedPose,
    },
    /// Moves to a named pose (goNested, goStart, goWork) along a smooth joint trajectory through
    /// the robot's active controller: [`Reply::Unit`] once started.
    GoTo {
        /// `nest`, `start` or `work`.
        pose: NamedPose,
        /// Duration of the motion, s (> 0).
        duration_s: f64,
    },
    /// Maps joints onto a board's axes (a robot may use several boards): [`Reply::Unit`].
    MapJoints {
        /// The board's name on this node.
        board: String,
        /// One entry per joint to map.
        joints: Vec<JointAxis>,
    },
    /// What a 3D viewer needs to draw the robot (its URDF, its frames, its joints, the contact
    /// shapes its simulated tool touches): [`Reply::RobotDescription`] (appended last).
    Description,
    /// The pose of every frame of the description (root first, the tool last), in the root
    /// frame: [`Reply::Poses`] (appended last).
    LinkFrames {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// CRTK `move_jp` (appended last, as are the five after it): a smooth joint motion from
    /// the active controller's current reference to `q` (the [`RobotMethod::GoTo`] machinery:
    /// a clamped spline, no jump): [`Reply::Unit`] once started. Refused with
    /// [`CallError::BadArgument`] for a wrong joint count, a non-finite value, a target outside
    /// the joint limits or a duration outside (0, 3600] s; [`CallError::NotReady`] without an
    /// active controller that follows a joint trajectory. A servo target cancels it.
    MoveJoints {
        /// The goal, rad, one value per joint.
        q: Joints,
        /// Duration of the motion, s.
        duration_s: f64,
    },
    /// CRTK `move_cp`: as [`RobotMethod::MoveJoints`] to a tool pose in the base frame (inverse
    /// kinematics, the branch nearest the current reference; an unreachable pose is a
    /// [`CallError::BadArgument`] saying why).
    MoveTool {
        /// The goal tool pose in the base frame.
        pose: PoseMsg,
        /// Duration of the motion, s.
        duration_s: f64,
    },
    /// CRTK `servo_jp`: the newest joint target of a stream. The active controller's reference
    /// jumps to it (no interpolation) and stays there; without a new target past the
    /// controller's reference watchdog the loop holds. Same checks as
    /// [`RobotMethod::MoveJoints`], plus the step limit: a target farther than the servo step
    /// limit from the current reference (any joint) is refused. [`Reply::Unit`].
    ServoJoints {
        /// The target, rad, one value per joint.
        q: Joints,
    },
    /// CRTK `servo_cp`: as [`RobotMethod::ServoJoints`] to a tool pose in the base frame (the
    /// inverse-kinematics branch nearest the current reference, then the same step limit).
    ServoTool {
        /// The target tool pose in the base frame.
        pose: PoseMsg,
    },
    /// CRTK `setpoint_js` / `setpoint_cp`: the reference the active controller follows now:
    /// [`Reply::Setpoints`].
    Setpoints,
    /// CRTK `operating_state`: [`Reply::OperatingState`].
    OperatingState,
}

/// One joint driven by one board axis.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointAxis {
    /// The joint (0-based).
    pub joint: u8,
    /// The board axis (0-based).
    pub axis: u8,
}

/// Board methods.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum BoardMethod {
    /// Number of axes: [`Reply::Count`].
    AxisCount,
    /// Encoder positions of every axis, counts: [`Reply::Counts`].
    ReadEncoders,
    /// Whether the amplifiers are enabled: [`Reply::Flag`].
    AmplifiersEnabled,
    /// Asks a board that latched a fault of its own (a lost Galil line) to leave it, once its
    /// cause is gone: [`Reply::Unit`]. A board driven by a running loop is re-armed through its
    /// controller (`ControllerMethod::Rearm`), which re-arms the loop too.
    Rearm,
}

/// Sensor methods.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SensorMethod {
    /// The newest reading (wrench in the sensor frame, N and N·m): [`Reply::Wrench`].
    Read,
    /// Takes the current reading as the zero (bias): [`Reply::Unit`].
    Bias,
    /// Where the sensor's probe is (for `sensor/virtual`: the tool pose and velocity that the
    /// environment model pushes against): [`Reply::Unit`]. A controller bound to the sensor
    /// feeds it every communication period.
    SetProbe {
        /// The probe pose in the base frame.
        pose: PoseMsg,
        /// The probe's linear velocity in the base frame, m/s.
        velocity: [f64; 3],
    },
    /// Reads the wrench for a probe in one round trip (a client's spot check; controllers on
    /// other nodes read the data plane instead, see [`SensorMethod::Stream`]):
    /// [`Reply::Wrench`].
    Measure {
        /// The probe pose in the base frame.
        pose: PoseMsg,
        /// The probe's linear velocity in the base frame, m/s.
        velocity: [f64; 3],
    },
    /// Where the sensor is published on the data plane (its `publish` key), asked once when a
    /// controller on another node is activated: [`Reply::Address`]. Refused with
    /// [`CallError::NotReady`] for a sensor without `publish`.
    Stream,
}

/// Controller methods (the paper's `ControllerImpl`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ControllerMethod {
    /// Binds the robot it drives: a name on this node (robots are not remote). [`Reply::Unit`].
    SetRobot {
        /// The robot's name.
        robot: String,
    },
    /// Binds the trajectory it follows: a name on this node. [`Reply::Unit`].
    SetTrajectory {
        /// The trajectory's name.
        trajectory: String,
    },
    /// Binds the force sensor: a name on this node or a naming path (`/node/sensors/name`) of a
    /// sensor on another node, which the controller's sensor feed then reads on the data plane
    /// (that sensor needs `publish`; see [`SensorMethod::Stream`]). [`Reply::Unit`].
    SetSensor {
        /// Local name or naming path.
        sensor: String,
    },
    /// Replaces gains at run time (keys depend on the kind, as in its config): [`Reply::Unit`].
    SetGains {
        /// TOML text, such as `kp = [100, 100, 100, 10, 10, 10]`.
        gains: String,
    },
    /// Latches the emergency stop of the running loop: [`Reply::Unit`].
    EStop,
    /// Clears a latched fault or e-stop (activate again afterwards): [`Reply::Unit`].
    Rearm,
    /// The running loop's newest sample and its counters: [`Reply::Status`].
    Status,
}

/// Trajectory methods.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum TrajectoryMethod {
    /// The reference at time `t_s` after the trajectory's start (the paper's `getReferiment`):
    /// [`Reply::Reference`].
    Reference {
        /// Seconds after the start.
        t_s: f64,
    },
    /// The total duration, s (`None` for endless ones): [`Reply::Duration`].
    Duration,
}
