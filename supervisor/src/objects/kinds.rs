//! The kinds a creator makes, and their configurations: TOML text with documented keys, units and
//! defaults, unknown keys refused, ranges checked. `""` means every default.

use std::time::Duration;

use nalgebra::{Unit, Vector3};
use penelope_drivers::sim::environment::{ContactModel, Environment, Shape};
use penelope_hal::{JointVector, MAX_AXES, MAX_JOINTS, NamedPose};
use serde::Deserialize;
use serde::de::DeserializeOwned;

use penelope_rt_core::safety::Role;

use super::teleop::{
    FORCE_DISPLAY_KEYS, HAND_KEYS, POSITION_ERROR_KEYS, SLAVE_TRACKING_KEYS, TELEOP_KEYS,
};
use crate::proto::{Class, KindInfo, WireError};

/// Every kind this creator makes, in listing order.
pub const KINDS: [&str; 19] = [
    "robot/puma560",
    "robot/puma200",
    "robot/frhc",
    "board/sim",
    "board/galil",
    "sensor/virtual",
    "sensor/operator-hand",
    "controller/joint-pid",
    "controller/cartesian-impedance",
    "controller/joint-position",
    "controller/force-display",
    "controller/position-error-master",
    "controller/slave-tracking",
    "controller/slave-position",
    "trajectory/step",
    "trajectory/ramp",
    "trajectory/trapezoidal",
    "trajectory/spline",
    "trajectory/teleop",
];

/// A kind, parsed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// `robot/<model>`: one of the built-in DH models.
    Robot(&'static str),
    /// `board/sim`.
    SimBoard,
    /// `board/galil`.
    GalilBoard,
    /// `sensor/virtual`.
    VirtualSensor,
    /// `sensor/operator-hand`.
    OperatorHand,
    /// `controller/joint-pid`.
    JointPid,
    /// `controller/cartesian-impedance`.
    CartesianImpedance,
    /// `controller/joint-position`.
    JointPosition,
    /// `controller/force-display`: the master half of position-forward / force-back.
    ForceDisplay,
    /// `controller/position-error-master`: the master half of position-error.
    PositionErrorMaster,
    /// `controller/slave-tracking`: the slave half (computed torque to the mapped master pose).
    SlaveTracking,
    /// `controller/slave-position`: the slave half for a board with its own servo.
    SlavePosition,
    /// `trajectory/step`.
    Step,
    /// `trajectory/ramp`.
    Ramp,
    /// `trajectory/trapezoidal`.
    Trapezoidal,
    /// `trajectory/spline`.
    Spline,
    /// `trajectory/teleop`: the channel between a master and a slave.
    Teleop,
}

impl Kind {
    /// Parses `class/kind`.
    pub fn parse(kind: &str) -> Option<Kind> {
        Some(match kind {
            "robot/puma560" => Kind::Robot("puma560"),
            "robot/puma200" => Kind::Robot("puma200"),
            "robot/frhc" => Kind::Robot("frhc"),
            "board/sim" => Kind::SimBoard,
            "board/galil" => Kind::GalilBoard,
            "sensor/virtual" => Kind::VirtualSensor,
            "sensor/operator-hand" => Kind::OperatorHand,
            "controller/joint-pid" => Kind::JointPid,
            "controller/cartesian-impedance" => Kind::CartesianImpedance,
            "controller/joint-position" => Kind::JointPosition,
            "controller/force-display" => Kind::ForceDisplay,
            "controller/position-error-master" => Kind::PositionErrorMaster,
            "controller/slave-tracking" => Kind::SlaveTracking,
            "controller/slave-position" => Kind::SlavePosition,
            "trajectory/step" => Kind::Step,
            "trajectory/ramp" => Kind::Ramp,
            "trajectory/trapezoidal" => Kind::Trapezoidal,
            "trajectory/spline" => Kind::Spline,
            "trajectory/teleop" => Kind::Teleop,
            _ => return None,
        })
    }

    /// `class/kind`.
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Robot("puma560") => "robot/puma560",
            Kind::Robot("puma200") => "robot/puma200",
            Kind::Robot(_) => "robot/frhc",
            Kind::SimBoard => "board/sim",
            Kind::GalilBoard => "board/galil",
            Kind::VirtualSensor => "sensor/virtual",
            Kind::OperatorHand => "sensor/operator-hand",
            Kind::JointPid => "controller/joint-pid",
            Kind::CartesianImpedance => "controller/cartesian-impedance",
            Kind::JointPosition => "controller/joint-position",
            Kind::ForceDisplay => "controller/force-display",
            Kind::PositionErrorMaster => "controller/position-error-master",
            Kind::SlaveTracking => "controller/slave-tracking",
            Kind::SlavePosition => "controller/slave-position",
            Kind::Step => "trajectory/step",
            Kind::Ramp => "trajectory/ramp",
            Kind::Trapezoidal => "trajectory/trapezoidal",
            Kind::Spline => "trajectory/spline",
            Kind::Teleop => "trajectory/teleop",
        }
    }

    /// Its class.
    pub fn class(self) -> Class {
        match self {
            Kind::Robot(_) => Class::Robot,
            Kind::SimBoard | Kind::GalilBoard => Class::Board,
            Kind::VirtualSensor | Kind::OperatorHand => Class::Sensor,
            Kind::JointPid
            | Kind::CartesianImpedance
            | Kind::JointPosition
            | Kind::ForceDisplay
            | Kind::PositionErrorMaster
            | Kind::SlaveTracking
            | Kind::SlavePosition => Class::Controller,
            Kind::Step | Kind::Ramp | Kind::Trapezoidal | Kind::Spline | Kind::Teleop => {
                Class::Trajectory
            }
        }
    }

    /// What `kinds` lists for it.
    pub fn info(self) -> KindInfo {
        let (summary, config) = match self {
            Kind::Robot(m) => (
                match m {
                    "puma560" => "Unimation PUMA 560 (Robotics Toolbox DH model with dynamics)",
                    "puma200" => "Unimation PUMA 200 (PUMA 260 geometry, assumed dynamics)",
                    _ => "JPL Force Reflecting Hand Controller (master joystick)",
                },
                ROBOT_KEYS.to_string(),
            ),
            Kind::SimBoard => (
                "simulated motion board; the rigid-body plant of the robot mapped onto it",
                SIM_BOARD_KEYS.to_string() + SHAPE_KEYS,
            ),
            Kind::GalilBoard => (
                "Galil DMC motion board over a serial line or TCP (a DMC or `penelope galil-sim`)",
                GALIL_KEYS.to_string(),
            ),
            Kind::VirtualSensor => (
                "6-axis force sensor: an environment contact model fed by a probe pose",
                SENSOR_KEYS.to_string() + SHAPE_KEYS,
            ),
            Kind::OperatorHand => (
                "the operator's hand on a simulated master: a scripted impedance that pushes the \
                 handle and holds the clutch",
                HAND_KEYS.to_string(),
            ),
            Kind::ForceDisplay => (
                "teleoperation master, position-forward / force-back: displays the mapped slave \
                 force (tau = J^T F), capped",
                FORCE_DISPLAY_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::PositionErrorMaster => (
                "teleoperation master, position-error: a spring-damper to the mapped slave pose",
                POSITION_ERROR_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::SlaveTracking => (
                "teleoperation slave: follows the mapped master pose (IK, computed torque)",
                SLAVE_TRACKING_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::SlavePosition => (
                "teleoperation slave for a board with its own servo: IK, then position targets",
                SLAVE_TRACKING_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::Teleop => (
                "the channel between a master and a slave: the master's pose forward (scaled, \
                 rotated, clutched), the slave's pose and wrench back",
                TELEOP_KEYS.to_string(),
            ),
            Kind::JointPid => (
                "joint-space PID with gravity compensation",
                JOINT_PID_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::CartesianImpedance => (
                "Cartesian impedance (spring-damper at the tool) with gravity compensation",
                IMPEDANCE_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::JointPosition => (
                "joint positions for the board's own servo (a Galil DMC closes the loop)",
                JOINT_POSITION_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::Step => ("joint step to a goal after a delay", STEP_KEYS.to_string()),
            Kind::Ramp => (
                "joint ramp at constant speed over a duration",
                RAMP_KEYS.to_string(),
            ),
            Kind::Trapezoidal => (
                "joint move with trapezoidal velocity, every joint synchronised",
                TRAPEZOIDAL_KEYS.to_string(),
            ),
            Kind::Spline => (
                "C2 cubic spline through timed joint waypoints",
                SPLINE_KEYS.to_string(),
            ),
        };
        KindInfo {
            kind: self.as_str().to_string(),
            class: self.class(),
            summary: summary.to_string(),
            config: config.trim().to_string(),
        }
    }
}

/// Every kind, in listing order.
pub fn all_kinds() -> Vec<KindInfo> {
    KINDS
        .iter()
        .filter_map(|k| Kind::parse(k))
        .map(Kind::info)
        .collect()
}

const ROBOT_KEYS: &str = r#"
start = "start"       # named pose (nest, start, work) where a simulated body starts and where
                      # Galil encoders read zero (the arm is parked there at power-up)
kinematics = "float"  # "float", or "fpga": forward kinematics and Jacobian from the bit-exact
                      # model of the FRHC's FPGA board (frhc only; dynamics stay float)
role = "slave"        # "master" (a hand controller: force and moment caps, zero force on a
                      # fault) or "slave" (holds its pose); default: master for frhc, else slave
max_force_n = 10.0    # a master's largest displayed force, N (the FRHC's)
max_moment_nm = 0.5   # a master's largest displayed moment, N·m
"#;

const SHAPE_KEYS: &str = r#"
[[shapes]]                       # up to 8 contact shapes, base frame of the robot
kind = "plane"                   # "plane" or "sphere"
point = [0.0, 0.0, 0.0]          # m: a point on the plane, or the sphere's centre
normal = [0.0, 0.0, 1.0]         # plane: normal into free space (normalised)
radius = 0.05                    # sphere: radius, m (> 0)
stiffness = 5000.0               # N/m, 0..=1e7
damping = 20.0                   # N·s/m, 0..=1e5
"#;

const SIM_BOARD_KEYS: &str = r#"
axes = 6           # number of axes, 1..=8
dac_bits = 16      # DAC resolution, 8..=24 bits
substep_us = 200   # plant integration sub-step, 20..=2000 µs
friction = true    # joint friction of the model in the plant
# the environment the plant's tool touches (none by default):
"#;

const GALIL_KEYS: &str = r#"
device = "/dev/ttyUSB0"        # serial device, or else:
address = "127.0.0.1:7400"     # TCP address of a DMC or of `penelope galil-sim` (one of the two is required)
baud = 115200                  # serial baud rate, 1200..=921600
axes = 6                       # axes driven, 1..=8
volts_per_newton_metre = 0.1   # amplifier scaling, V per N·m of joint torque: one value or one per axis (|v| <= 10);
                               # the sign per joint comes from the robot's gear and encoder (negative flips a reversed amplifier)
connect_timeout_ms = 1000      # TCP connect timeout, 10..=60000 ms
watchdog_ms = 30               # the DMC turns its motors off when no exchange reached it for this long, 5..=1000 ms (0: no watchdog)
"#;

const SENSOR_KEYS: &str = r#"
# Reads the wrench the environment applies to the probe (N, N·m, base frame, about the probe
# point), minus the bias. Empty space by default:
"#;

const LOOP_KEYS: &str = r#"
period_us = 1000          # control period T_ctrl, 250..=20000 µs
comm_period_us = 2000     # communication period T_com (reference), 250..=100000 µs
watchdog_ms = 50          # a reference older than this holds the robot, 1..=10000 ms
sensor_period_ms = 2      # force-sensor feed period, 1..=1000 ms
sensor_timeout_ms = 20    # an older wrench is not used, 1..=10000 ms
telemetry_period_ms = 10  # telemetry batch period to subscribers, 1..=1000 ms
"#;

const JOINT_PID_KEYS: &str = r#"
kp = [...]                      # N·m/rad, one value or one per joint (default 10 × the joint's torque limit, per rad)
ki = 0.0                        # N·m/(rad·s)
kd = [...]                      # N·m·s/rad (default 0.5 × the joint's torque limit, per rad/s)
integral_limit = 0.0            # N·m, cap of the integral term
gravity_compensation = true     # add g(q)
acceleration_feedforward = false # add M(q) qdd_ref
# plus the loop keys:
"#;

const JOINT_POSITION_KEYS: &str = r#"
max_velocity = 1.0              # rad/s, one value or one per joint: how fast the servo's target may move
# plus the loop keys:
"#;

const IMPEDANCE_KEYS: &str = r#"
stiffness = [2000.0, 2000.0, 2000.0, 50.0, 50.0, 50.0]  # N/m then N·m/rad, base frame
damping = [150.0, 150.0, 150.0, 3.0, 3.0, 3.0]          # N·s/m then N·m·s/rad
gravity_compensation = true
max_force = inf          # N, cap of the commanded force (inf: none)
max_torque = inf         # N·m
ramp_in_ms = 0           # stiffness ramp after activation, 0..=60000 ms
# plus the loop keys:
"#;

const STEP_KEYS: &str = r#"
goal = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # rad, one per joint; or else
pose = "start"                         # a named pose of the robot (default "start")
delay_s = 0.0                          # 0..=3600 s
"#;

const RAMP_KEYS: &str = r#"
goal = [...] or pose = "start"   # as trajectory/step
duration_s = 2.0                 # 0.001..=3600 s
"#;

const TRAPEZOIDAL_KEYS: &str = r#"
goal = [...] or pose = "start"   # as trajectory/step
max_velocity = 0.5               # rad/s, one value or one per joint, 1e-4..=20
max_acceleration = 1.0           # rad/s², one value or one per joint, 1e-4..=200
"#;

const SPLINE_KEYS: &str = r#"
ends = "clamped"                 # "clamped" (arrive at rest) or "natural"
[[waypoints]]                    # 1..=16, times strictly increasing after the start
at_s = 2.0                       # s after the start, 0..=3600
q = [...]                        # rad, one per joint; or pose = "work"
# default: one waypoint, pose "start" at 2 s
"#;

// ---------------------------------------------------------------------------------------------
// Parsing helpers
// ---------------------------------------------------------------------------------------------

fn bad(kind: &str, message: impl Into<String>) -> WireError {
    WireError::BadConfig {
        kind: kind.to_string(),
        message: message.into(),
    }
}

/// Parses `text` as the TOML configuration of `kind` (`""`: defaults).
///
/// # Errors
/// [`WireError::BadConfig`] for bad TOML, unknown keys or wrong types.
pub fn parse<T: DeserializeOwned + Default>(kind: &str, text: &str) -> Result<T, WireError> {
    if text.trim().is_empty() {
        return Ok(T::default());
    }
    toml::from_str(text).map_err(|e| bad(kind, e.message().to_string()))
}

fn check_range(kind: &str, key: &str, v: f64, lo: f64, hi: f64) -> Result<(), WireError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(bad(kind, format!("`{key}` = {v} is outside {lo}..={hi}")))
    }
}

pub(crate) fn check_int(kind: &str, key: &str, v: u64, lo: u64, hi: u64) -> Result<(), WireError> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(bad(kind, format!("`{key}` = {v} is outside {lo}..={hi}")))
    }
}

/// One value for every joint, or one per joint.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum PerJoint {
    /// The same value on every joint.
    One(f64),
    /// One value per joint.
    Each(Vec<f64>),
}

impl PerJoint {
    /// The values for `n` joints, each checked in `lo..=hi`.
    ///
    /// # Errors
    /// [`WireError::BadConfig`] for a wrong count or a value out of range.
    pub fn resolve(
        &self,
        kind: &str,
        key: &str,
        n: usize,
        lo: f64,
        hi: f64,
    ) -> Result<JointVector, WireError> {
        let mut v = JointVector::zeros();
        match self {
            PerJoint::One(x) => {
                check_range(kind, key, *x, lo, hi)?;
                for j in 0..n.min(MAX_JOINTS) {
                    v[j] = *x;
                }
            }
            PerJoint::Each(xs) => {
                if xs.len() != n {
                    return Err(bad(
                        kind,
                        format!("`{key}` has {} values, the robot has {n} joints", xs.len()),
                    ));
                }
                for (j, x) in xs.iter().enumerate() {
                    check_range(kind, key, *x, lo, hi)?;
                    v[j] = *x;
                }
            }
        }
        Ok(v)
    }

    /// Checks what can be checked without knowing the joint count.
    fn check(&self, kind: &str, key: &str, lo: f64, hi: f64) -> Result<(), WireError> {
        let values: &[f64] = match self {
            PerJoint::One(x) => std::slice::from_ref(x),
            PerJoint::Each(xs) => xs,
        };
        if values.is_empty() || values.len() > MAX_JOINTS.max(MAX_AXES) {
            return Err(bad(kind, format!("`{key}` needs 1 to {MAX_AXES} values")));
        }
        for x in values {
            check_range(kind, key, *x, lo, hi)?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Environments
// ---------------------------------------------------------------------------------------------

/// One contact shape of an environment.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeConfig {
    /// `plane` or `sphere`.
    pub kind: String,
    /// A point on the plane, or the sphere's centre, m (base frame).
    #[serde(default)]
    pub point: [f64; 3],
    /// Plane normal into free space.
    #[serde(default = "up")]
    pub normal: [f64; 3],
    /// Sphere radius, m.
    #[serde(default = "radius")]
    pub radius: f64,
    /// Contact stiffness, N/m.
    #[serde(default = "stiffness")]
    pub stiffness: f64,
    /// Contact damping, N·s/m.
    #[serde(default = "damping")]
    pub damping: f64,
}

fn up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}
fn radius() -> f64 {
    0.05
}
fn stiffness() -> f64 {
    5000.0
}
fn damping() -> f64 {
    20.0
}

/// Builds an environment from shapes.
///
/// # Errors
/// [`WireError::BadConfig`] for an unknown shape kind, a value out of range or too many shapes.
pub fn environment(kind: &str, shapes: &[ShapeConfig]) -> Result<Environment, WireError> {
    let mut env = Environment::new();
    for s in shapes {
        for x in s.point.iter().chain(&s.normal) {
            check_range(kind, "shapes.point/normal", *x, -100.0, 100.0)?;
        }
        check_range(kind, "shapes.stiffness", s.stiffness, 0.0, 1e7)?;
        check_range(kind, "shapes.damping", s.damping, 0.0, 1e5)?;
        let shape = match s.kind.as_str() {
            "plane" => {
                let n = Vector3::from(s.normal);
                if n.norm() < 1e-9 {
                    return Err(bad(kind, "a plane's `normal` must not be zero"));
                }
                Shape::Plane {
                    point: Vector3::from(s.point),
                    normal: Unit::new_normalize(n),
                }
            }
            "sphere" => {
                check_range(kind, "shapes.radius", s.radius, 1e-6, 100.0)?;
                Shape::Sphere {
                    center: Vector3::from(s.point),
                    radius: s.radius,
                }
            }
            other => {
                return Err(bad(
                    kind,
                    format!("shape kind `{other}` is not \"plane\" or \"sphere\""),
                ));
            }
        };
        env = env
            .with(ContactModel {
                shape,
                stiffness: s.stiffness,
                damping: s.damping,
            })
            .map_err(|_| bad(kind, "at most 8 shapes"))?;
    }
    Ok(env)
}

// ---------------------------------------------------------------------------------------------
// Robots, boards, sensors
// ---------------------------------------------------------------------------------------------

/// `robot/*` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotConfig {
    /// The named pose a simulated body starts in, and where Galil encoders read zero.
    pub start: String,
    /// `float`, or `fpga` (the FRHC's FPGA board model).
    pub kinematics: String,
    /// `master` or `slave` (`None`: master for the FRHC, else slave).
    pub role: Option<String>,
    /// A master's largest displayed force, N.
    pub max_force_n: f64,
    /// A master's largest displayed moment, N·m.
    pub max_moment_nm: f64,
}

impl Default for RobotConfig {
    fn default() -> Self {
        RobotConfig {
            start: "start".into(),
            kinematics: "float".into(),
            role: None,
            max_force_n: 10.0,
            max_moment_nm: 0.5,
        }
    }
}

impl RobotConfig {
    /// Whether the FPGA kinematics were chosen.
    ///
    /// # Errors
    /// [`WireError::BadConfig`] for a word other than float or fpga.
    pub fn fpga(&self, kind: &str) -> Result<bool, WireError> {
        match self.kinematics.as_str() {
            "float" => Ok(false),
            "fpga" => Ok(true),
            other => Err(bad(
                kind,
                format!("`kinematics` = {other:?} is not \"float\" or \"fpga\""),
            )),
        }
    }

    /// The robot's role, defaulting by model (`frhc` is a master), and its checked caps.
    ///
    /// # Errors
    /// [`WireError::BadConfig`] for a word other than master or slave, or caps that are not
    /// positive.
    pub fn role(&self, kind: &str) -> Result<Role, WireError> {
        for (key, v) in [
            ("max_force_n", self.max_force_n),
            ("max_moment_nm", self.max_moment_nm),
        ] {
            if v.is_nan() || v <= 0.0 {
                return Err(bad(kind, format!("`{key}` must be > 0 (inf: no cap)")));
            }
        }
        match self.role.as_deref() {
            None if kind == "robot/frhc" => Ok(Role::Master),
            None | Some("slave") => Ok(Role::Slave),
            Some("master") => Ok(Role::Master),
            Some(other) => Err(bad(
                kind,
                format!("`role` = {other:?} is not \"master\" or \"slave\""),
            )),
        }
    }

    /// The start pose.
    ///
    /// # Errors
    /// [`WireError::BadConfig`] for a name other than nest, start, work.
    pub fn start_pose(&self, kind: &str) -> Result<NamedPose, WireError> {
        NamedPose::parse(&self.start).ok_or_else(|| {
            bad(
                kind,
                format!("`start` = {:?} is not nest, start or work", self.start),
            )
        })
    }
}

/// `board/sim` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimBoardConfig {
    /// Number of axes.
    pub axes: u32,
    /// DAC resolution, bits.
    pub dac_bits: u32,
    /// Plant integration sub-step, µs.
    pub substep_us: u64,
    /// Model friction in the plant.
    pub friction: bool,
    /// The environment the plant's tool touches.
    pub shapes: Vec<ShapeConfig>,
}

impl Default for SimBoardConfig {
    fn default() -> Self {
        SimBoardConfig {
            axes: 6,
            dac_bits: 16,
            substep_us: 200,
            friction: true,
            shapes: Vec::new(),
        }
    }
}

impl SimBoardConfig {
    /// Checks ranges.
    ///
    /// # Errors
    /// [`WireError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<Environment, WireError> {
        check_int(kind, "axes", self.axes.into(), 1, MAX_AXES as u64)?;
        check_int(kind, "dac_bits", self.dac_bits.into(), 8, 24)?;
        check_int(kind, "substep_us", self.substep_us, 20, 2000)?;
        environment(kind, &self.shapes)
    }
}

/// `board/galil` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GalilConfig {
    /// Serial device.
    pub device: Option<String>,
    /// TCP address.
    pub address: Option<String>,
    /// Serial baud rate.
    pub baud: u32,
    /// Axes driven.
    pub axes: u32,
    /// V per N·m.
    pub volts_per_newton_metre: PerJoint,
    /// TCP connect timeout, ms.
    pub connect_timeout_ms: u64,
    /// The board-side watchdog time, ms (0: none).
    pub watchdog_ms: u64,
}

impl Default for GalilConfig {
    fn default() -> Self {
        GalilConfig {
            device: None,
            address: None,
            baud: 115_200,
            axes: 6,
            volts_per_newton_metre: PerJoint::One(0.1),
            connect_timeout_ms: 1000,
            watchdog_ms: penelope_drivers::galil::DEFAULT_WATCHDOG.as_millis() as u64,
        }
    }
}

impl GalilConfig {
    /// Checks ranges and that exactly one of `device` and `address` is given.
    ///
    /// # Errors
    /// [`WireError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<(), WireError> {
        match (&self.device, &self.address) {
            (Some(_), Some(_)) => return Err(bad(kind, "give `device` or `address`, not both")),
            (None, None) => {
                return Err(bad(
                    kind,
                    "needs `device` (serial) or `address` (host:port)",
                ));
            }
            (None, Some(a)) => {
                if a.parse::<std::net::SocketAddr>().is_err() && !a.contains(':') {
                    return Err(bad(kind, format!("`address` = {a:?} is not host:port")));
                }
            }
            (Some(d), None) => {
                if d.is_empty() {
                    return Err(bad(kind, "`device` is empty"));
                }
            }
        }
        check_int(kind, "baud", self.baud.into(), 1200, 921_600)?;
        check_int(kind, "axes", self.axes.into(), 1, MAX_AXES as u64)?;
        check_int(
            kind,
            "connect_timeout_ms",
            self.connect_timeout_ms,
            10,
            60_000,
        )?;
        if self.watchdog_ms != 0 {
            check_int(kind, "watchdog_ms", self.watchdog_ms, 5, 1000)?;
        }
        self.volts_per_newton_metre
            .check(kind, "volts_per_newton_metre", -10.0, 10.0)?;
        if let PerJoint::Each(v) = &self.volts_per_newton_metre
            && v.len() != self.axes as usize
        {
            return Err(bad(
                kind,
                "`volts_per_newton_metre` needs one value or one per axis",
            ));
        }
        Ok(())
    }

    /// The scaling per axis.
    pub fn volts(&self) -> [f64; MAX_AXES] {
        let mut out = [0.0; MAX_AXES];
        for (a, o) in out.iter_mut().enumerate().take(self.axes as usize) {
            *o = match &self.volts_per_newton_metre {
                PerJoint::One(v) => *v,
                PerJoint::Each(v) => v.get(a).copied().unwrap_or(0.0),
            };
        }
        out
    }
}

/// `sensor/virtual` configuration.
#[derive(Clone, Debug, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorConfig {
    /// The contact shapes.
    pub shapes: Vec<ShapeConfig>,
}

// ---------------------------------------------------------------------------------------------
// Controllers
// ---------------------------------------------------------------------------------------------

/// Timing keys every controller shares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoopTiming {
    /// Control period.
    pub period: Duration,
    /// Communication (reference) period.
    pub comm_period: Duration,
    /// Reference watchdog.
    pub watchdog: Duration,
    /// Sensor feed period.
    pub sensor_period: Duration,
    /// Largest wrench age used.
    pub sensor_timeout: Duration,
    /// Telemetry batch period.
    pub telemetry_period: Duration,
}

macro_rules! loop_keys {
    ($name:ident { $($field:ident : $ty:ty = $default:expr, #[$doc:meta])* }) => {
        /// A controller's configuration.
        #[derive(Clone, Debug, PartialEq, ::serde::Deserialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct $name {
            $(#[$doc] pub $field: $ty,)*
            /// Control period, µs.
            pub period_us: u64,
            /// Communication period, µs.
            pub comm_period_us: u64,
            /// Reference watchdog, ms.
            pub watchdog_ms: u64,
            /// Sensor feed period, ms.
            pub sensor_period_ms: u64,
            /// Largest wrench age, ms.
            pub sensor_timeout_ms: u64,
            /// Telemetry batch period, ms.
            pub telemetry_period_ms: u64,
        }

        impl Default for $name {
            fn default() -> Self {
                $name {
                    $($field: $default,)*
                    period_us: 1000,
                    comm_period_us: 2000,
                    watchdog_ms: 50,
                    sensor_period_ms: 2,
                    sensor_timeout_ms: 20,
                    telemetry_period_ms: 10,
                }
            }
        }

        impl $name {
            /// The timing keys, checked.
            ///
            /// # Errors
            /// [`WireError::BadConfig`].
            pub fn timing(&self, kind: &str) -> Result<$crate::objects::kinds::LoopTiming, $crate::proto::WireError> {
                $crate::objects::kinds::check_int(kind, "period_us", self.period_us, 250, 20_000)?;
                $crate::objects::kinds::check_int(kind, "comm_period_us", self.comm_period_us, 250, 100_000)?;
                $crate::objects::kinds::check_int(kind, "watchdog_ms", self.watchdog_ms, 1, 10_000)?;
                $crate::objects::kinds::check_int(kind, "sensor_period_ms", self.sensor_period_ms, 1, 1000)?;
                $crate::objects::kinds::check_int(kind, "sensor_timeout_ms", self.sensor_timeout_ms, 1, 10_000)?;
                $crate::objects::kinds::check_int(kind, "telemetry_period_ms", self.telemetry_period_ms, 1, 1000)?;
                Ok($crate::objects::kinds::LoopTiming {
                    period: ::std::time::Duration::from_micros(self.period_us),
                    comm_period: ::std::time::Duration::from_micros(self.comm_period_us),
                    watchdog: ::std::time::Duration::from_millis(self.watchdog_ms),
                    sensor_period: ::std::time::Duration::from_millis(self.sensor_period_ms),
                    sensor_timeout: ::std::time::Duration::from_millis(self.sensor_timeout_ms),
                    telemetry_period: ::std::time::Duration::from_millis(self.telemetry_period_ms),
                })
            }
        }
    };
}

pub(crate) use loop_keys;

loop_keys!(JointPidConfig {
    kp: Option<PerJoint> = None, #[doc = "Proportional gain, N·m/rad (default 10 × torque limit)."]
    ki: PerJoint = PerJoint::One(0.0), #[doc = "Integral gain, N·m/(rad·s)."]
    kd: Option<PerJoint> = None, #[doc = "Derivative gain, N·m·s/rad (default 0.5 × torque limit)."]
    integral_limit: PerJoint = PerJoint::One(0.0), #[doc = "Integral term cap, N·m."]
    gravity_compensation: bool = true, #[doc = "Add g(q)."]
    acceleration_feedforward: bool = false, #[doc = "Add M(q) qdd_ref."]
});

loop_keys!(ImpedanceConfigToml {
    stiffness: [f64; 6] = [2000.0, 2000.0, 2000.0, 50.0, 50.0, 50.0], #[doc = "N/m then N·m/rad."]
    damping: [f64; 6] = [150.0, 150.0, 150.0, 3.0, 3.0, 3.0], #[doc = "N·s/m then N·m·s/rad."]
    gravity_compensation: bool = true, #[doc = "Add g(q)."]
    max_force: f64 = f64::INFINITY, #[doc = "Force cap, N."]
    max_torque: f64 = f64::INFINITY, #[doc = "Moment cap, N·m."]
    ramp_in_ms: u64 = 0, #[doc = "Stiffness ramp, ms."]
});

impl JointPidConfig {
    /// Checks what does not depend on the robot.
    ///
    /// # Errors
    /// [`WireError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, WireError> {
        if let Some(kp) = &self.kp {
            kp.check(kind, "kp", 0.0, 1e7)?;
        }
        if let Some(kd) = &self.kd {
            kd.check(kind, "kd", 0.0, 1e6)?;
        }
        self.ki.check(kind, "ki", 0.0, 1e7)?;
        self.integral_limit
            .check(kind, "integral_limit", 0.0, 1e5)?;
        self.timing(kind)
    }
}

loop_keys!(JointPositionConfig {
    max_velocity: PerJoint = PerJoint::One(1.0), #[doc = "Largest target speed, rad/s."]
});

impl JointPositionConfig {
    /// Checks what does not depend on the robot.
    ///
    /// # Errors
    /// [`WireError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, WireError> {
        self.max_velocity.check(kind, "max_velocity", 1e-3, 100.0)?;
        self.timing(kind)
    }
}

impl ImpedanceConfigToml {
    /// Checks ranges.
    ///
    /// # Errors
    /// [`WireError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, WireError> {
        for x in self.stiffness {
            check_range(kind, "stiffness", x, 0.0, 1e6)?;
        }
        for x in self.damping {
            check_range(kind, "damping", x, 0.0, 1e5)?;
        }
        for (key, v) in [
            ("max_force", self.max_force),
            ("max_torque", self.max_torque),
        ] {
            if v.is_nan() || v <= 0.0 {
                return Err(bad(kind, format!("`{key}` must be > 0 (inf: no cap)")));
            }
        }
        check_int(kind, "ramp_in_ms", self.ramp_in_ms, 0, 60_000)?;
        self.timing(kind)
    }
}

// ---------------------------------------------------------------------------------------------
// Trajectories
// ---------------------------------------------------------------------------------------------

/// Where a trajectory goes: explicit joints or a named pose of the robot it moves.
#[derive(Clone, Debug, PartialEq)]
pub enum GoalConfig {
    /// Joint positions, rad.
    Joints(Vec<f64>),
    /// A named pose.
    Pose(NamedPose),
}

fn goal_of(
    kind: &str,
    goal: &Option<Vec<f64>>,
    pose: &Option<String>,
) -> Result<GoalConfig, WireError> {
    match (goal, pose) {
        (Some(_), Some(_)) => Err(bad(kind, "give `goal` or `pose`, not both")),
        (Some(q), None) => {
            if q.is_empty() || q.len() > MAX_JOINTS {
                return Err(bad(kind, format!("`goal` needs 1 to {MAX_JOINTS} values")));
            }
            for x in q {
                check_range(kind, "goal", *x, -100.0, 100.0)?;
            }
            Ok(GoalConfig::Joints(q.clone()))
        }
        (None, Some(p)) => NamedPose::parse(p)
            .map(GoalConfig::Pose)
            .ok_or_else(|| bad(kind, format!("`pose` = {p:?} is not nest, start or work"))),
        (None, None) => Ok(GoalConfig::Pose(NamedPose::Start)),
    }
}

/// `trajectory/step`, `ramp` and `trapezoidal` configuration (keys not of the kind are refused).
#[derive(Clone, Debug, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StepConfig {
    /// Goal joints, rad.
    pub goal: Option<Vec<f64>>,
    /// Goal named pose.
    pub pose: Option<String>,
    /// Delay, s.
    pub delay_s: f64,
}

/// `trajectory/ramp` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RampConfig {
    /// Goal joints, rad.
    pub goal: Option<Vec<f64>>,
    /// Goal named pose.
    pub pose: Option<String>,
    /// Duration, s.
    pub duration_s: f64,
}

impl Default for RampConfig {
    fn default() -> Self {
        RampConfig {
            goal: None,
            pose: None,
            duration_s: 2.0,
        }
    }
}

/// `trajectory/trapezoidal` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrapezoidalConfig {
    /// Goal joints, rad.
    pub goal: Option<Vec<f64>>,
    /// Goal named pose.
    pub pose: Option<String>,
    /// Speed limit, rad/s.
    pub max_velocity: PerJoint,
    /// Acceleration limit, rad/s².
    pub max_acceleration: PerJoint,
}

impl Default for TrapezoidalConfig {
    fn default() -> Self {
        TrapezoidalConfig {
            goal: None,
            pose: None,
            max_velocity: PerJoint::One(0.5),
            max_acceleration: PerJoint::One(1.0),
        }
    }
}

/// One spline waypoint.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaypointConfig {
    /// Time after the start, s.
    pub at_s: f64,
    /// Joints, rad.
    pub q: Option<Vec<f64>>,
    /// Or a named pose.
    pub pose: Option<String>,
}

/// `trajectory/spline` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SplineConfig {
    /// `clamped` or `natural`.
    pub ends: String,
    /// The waypoints.
    pub waypoints: Vec<WaypointConfig>,
}

impl Default for SplineConfig {
    fn default() -> Self {
        SplineConfig {
            ends: "clamped".into(),
            waypoints: vec![WaypointConfig {
                at_s: 2.0,
                q: None,
                pose: Some("start".into()),
            }],
        }
    }
}

/// The most waypoints a `trajectory/spline` holds.
pub const MAX_WAYPOINTS: usize = 16;

/// A trajectory's configuration, checked (goals may still name poses of a robot).
#[derive(Clone, Debug, PartialEq)]
pub enum TrajectorySpec {
    /// A step after `delay`.
    Step {
        /// Goal.
        goal: GoalConfig,
        /// Delay.
        delay: Duration,
    },
    /// A ramp lasting `duration`.
    Ramp {
        /// Goal.
        goal: GoalConfig,
        /// Duration.
        duration: Duration,
    },
    /// A trapezoidal move.
    Trapezoidal {
        /// Goal.
        goal: GoalConfig,
        /// Speed limit, rad/s.
        velocity: PerJoint,
        /// Acceleration limit, rad/s².
        acceleration: PerJoint,
    },
    /// A spline.
    Spline {
        /// Clamped (true) or natural ends.
        clamped: bool,
        /// `(time after start, goal)`.
        waypoints: Vec<(Duration, GoalConfig)>,
    },
}

/// Parses and checks a trajectory kind's configuration.
///
/// # Errors
/// [`WireError::BadConfig`].
pub fn trajectory_spec(kind: Kind, text: &str) -> Result<TrajectorySpec, WireError> {
    let k = kind.as_str();
    Ok(match kind {
        Kind::Step => {
            let c: StepConfig = parse(k, text)?;
            check_range(k, "delay_s", c.delay_s, 0.0, 3600.0)?;
            TrajectorySpec::Step {
                goal: goal_of(k, &c.goal, &c.pose)?,
                delay: Duration::from_secs_f64(c.delay_s),
            }
        }
        Kind::Ramp => {
            let c: RampConfig = parse(k, text)?;
            check_range(k, "duration_s", c.duration_s, 0.001, 3600.0)?;
            TrajectorySpec::Ramp {
                goal: goal_of(k, &c.goal, &c.pose)?,
                duration: Duration::from_secs_f64(c.duration_s),
            }
        }
        Kind::Trapezoidal => {
            let c: TrapezoidalConfig = parse(k, text)?;
            c.max_velocity.check(k, "max_velocity", 1e-4, 20.0)?;
            c.max_acceleration
                .check(k, "max_acceleration", 1e-4, 200.0)?;
            TrajectorySpec::Trapezoidal {
                goal: goal_of(k, &c.goal, &c.pose)?,
                velocity: c.max_velocity,
                acceleration: c.max_acceleration,
            }
        }
        _ => {
            let c: SplineConfig = parse(k, text)?;
            let clamped = match c.ends.as_str() {
                "clamped" => true,
                "natural" => false,
                other => {
                    return Err(bad(
                        k,
                        format!("`ends` = {other:?} is not \"clamped\" or \"natural\""),
                    ));
                }
            };
            if c.waypoints.is_empty() || c.waypoints.len() > MAX_WAYPOINTS {
                return Err(bad(k, format!("needs 1 to {MAX_WAYPOINTS} waypoints")));
            }
            let mut previous = 0.0;
            let mut waypoints = Vec::with_capacity(c.waypoints.len());
            for w in &c.waypoints {
                check_range(k, "waypoints.at_s", w.at_s, 0.0, 3600.0)?;
                if w.at_s <= previous {
                    return Err(bad(
                        k,
                        "waypoint times must be strictly increasing and after 0",
                    ));
                }
                previous = w.at_s;
                waypoints.push((Duration::from_secs_f64(w.at_s), goal_of(k, &w.q, &w.pose)?));
            }
            TrajectorySpec::Spline { clamped, waypoints }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_joint_position_law_checks_its_speed_limit() {
        let k = "controller/joint-position";
        let c: JointPositionConfig = parse(k, "max_velocity = [1, 2, 3]").unwrap();
        assert!(c.check(k).is_ok());
        for bad in [
            "max_velocity = 0.0",
            "max_velocity = 1000.0",
            "max_velocity = nan",
        ] {
            let c: JointPositionConfig = parse(k, bad).unwrap();
            assert!(
                matches!(c.check(k), Err(WireError::BadConfig { .. })),
                "{bad}"
            );
        }
        assert!(parse::<JointPositionConfig>(k, "kp = 1.0").is_err());
    }

    #[test]
    fn every_kind_parses_back_and_documents_its_keys() {
        let kinds = all_kinds();
        // Every listed name parses (a name that does not would be dropped from the list).
        assert_eq!(kinds.len(), KINDS.len());
        assert_eq!(kinds.len(), 19);
        for k in &kinds {
            let parsed = Kind::parse(&k.kind).unwrap();
            assert_eq!(parsed.as_str(), k.kind);
            assert_eq!(parsed.class(), k.class);
            assert!(!k.config.is_empty());
        }
        assert_eq!(Kind::parse("robot/r2d2"), None);
    }

    #[test]
    fn configs_refuse_unknown_keys_and_out_of_range_values() {
        assert!(matches!(
            parse::<SimBoardConfig>("board/sim", "axis = 3"),
            Err(WireError::BadConfig { .. })
        ));
        let c: SimBoardConfig = parse("board/sim", "axes = 9").unwrap();
        assert!(c.check("board/sim").is_err());
        assert!(trajectory_spec(Kind::Ramp, "duration_s = -1").is_err());
        assert!(trajectory_spec(Kind::Ramp, "duration_s = nan").is_err());
        assert!(trajectory_spec(Kind::Step, "pose = \"home\"").is_err());
        assert!(trajectory_spec(Kind::Spline, "").is_ok());
        let g: GalilConfig = parse("board/galil", "").unwrap();
        assert!(
            g.check("board/galil").is_err(),
            "a galil board needs a device"
        );
        let c: JointPidConfig = parse("controller/joint-pid", "kp = [1, 2]").unwrap();
        assert!(c.check("controller/joint-pid").is_ok());
        assert!(
            c.kp.unwrap()
                .resolve("controller/joint-pid", "kp", 6, 0.0, 1e7)
                .is_err()
        );
    }
}
