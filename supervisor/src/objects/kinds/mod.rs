//! The kinds a creator makes, and their configurations: TOML text with documented keys, units and
//! defaults, unknown keys refused, ranges checked. `""` means every default.

use std::time::Duration;

use serde::de::DeserializeOwned;

mod devices;
mod keys;
mod per_joint;
mod trajectory;

use keys::*;

pub use per_joint::PerJoint;

pub use devices::{
    GalilConfig, NetFtSensorConfig, RobotConfig, SensorConfig, ShapeConfig, SimBoardConfig,
    environment,
};

pub use trajectory::{
    GoalConfig, MAX_WAYPOINTS, RampConfig, SplineConfig, StepConfig, TrajectorySpec,
    TrapezoidalConfig, WaypointConfig, trajectory_spec,
};
use trajectory::{RAMP_KEYS, SPLINE_KEYS, STEP_KEYS, TRAPEZOIDAL_KEYS};

use super::teleop::{
    FORCE_DISPLAY_KEYS, FOUR_CHANNEL_KEYS, FOUR_CHANNEL_SLAVE_KEYS, HAND_KEYS, POSITION_ERROR_KEYS,
    SLAVE_TRACKING_KEYS, TELEOP_KEYS,
};
use super::teleop_wave::{WAVE_MASTER_KEYS, WAVE_SLAVE_KEYS};
use penelope_protocol::proto::{CallError, Class, KindInfo, WireError};

/// Every kind this creator makes, in listing order.
pub const KINDS: [&str; 29] = [
    "robot/puma560",
    "robot/puma200",
    "robot/frhc",
    "robot/urdf",
    "board/sim",
    "board/fpga",
    "board/galil",
    "sensor/virtual",
    "sensor/netft",
    "sensor/operator-hand",
    "sensor/replay",
    "sensor/operator-replay",
    "controller/joint-pid",
    "controller/cartesian-impedance",
    "controller/joint-position",
    "controller/joint-groups",
    "controller/force-display",
    "controller/position-error-master",
    "controller/four-channel-master",
    "controller/four-channel-slave",
    "controller/slave-tracking",
    "controller/slave-position",
    "controller/wave-master",
    "controller/wave-slave",
    "trajectory/step",
    "trajectory/ramp",
    "trajectory/trapezoidal",
    "trajectory/spline",
    "trajectory/teleop",
];

/// A kind, parsed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// `robot/<model>`: one of the built-in DH models, or `urdf` (a URDF file named in the
    /// configuration).
    Robot(&'static str),
    /// `board/sim`.
    SimBoard,
    /// `board/fpga`: a `board/sim` plant behind the FRHC's FPGA kinematics.
    FpgaBoard,
    /// `board/galil`.
    GalilBoard,
    /// `sensor/virtual`.
    VirtualSensor,
    /// `sensor/netft`: an ATI Net F/T over UDP.
    NetFtSensor,
    /// `sensor/operator-hand`.
    OperatorHand,
    /// `sensor/replay`: a recorded wrench stream ([`replay`](crate::objects::replay)).
    ReplaySensor,
    /// `sensor/operator-replay`: the operator's hand played back from a recording.
    OperatorReplay,
    /// `controller/joint-pid`.
    JointPid,
    /// `controller/cartesian-impedance`.
    CartesianImpedance,
    /// `controller/joint-position`.
    JointPosition,
    /// `controller/joint-groups`: other controllers, each on its own joints of one robot.
    JointGroups,
    /// `controller/force-display`: the master half of position-forward / force-back.
    ForceDisplay,
    /// `controller/position-error-master`: the master half of position-error.
    PositionErrorMaster,
    /// `controller/four-channel-master`: the master half of Lawrence's four channels.
    FourChannelMaster,
    /// `controller/four-channel-slave`: the slave half of Lawrence's four channels.
    FourChannelSlave,
    /// `controller/slave-tracking`: the slave half (computed torque to the mapped master pose).
    SlaveTracking,
    /// `controller/slave-position`: the slave half for a board with its own servo.
    SlavePosition,
    /// `controller/wave-master`: the master half of the wave-variable law.
    WaveMaster,
    /// `controller/wave-slave`: the slave half of the wave-variable law.
    WaveSlave,
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
            "robot/urdf" => Kind::Robot("urdf"),
            "board/sim" => Kind::SimBoard,
            "board/fpga" => Kind::FpgaBoard,
            "board/galil" => Kind::GalilBoard,
            "sensor/virtual" => Kind::VirtualSensor,
            "sensor/netft" => Kind::NetFtSensor,
            "sensor/operator-hand" => Kind::OperatorHand,
            "sensor/replay" => Kind::ReplaySensor,
            "sensor/operator-replay" => Kind::OperatorReplay,
            "controller/joint-pid" => Kind::JointPid,
            "controller/cartesian-impedance" => Kind::CartesianImpedance,
            "controller/joint-position" => Kind::JointPosition,
            "controller/joint-groups" => Kind::JointGroups,
            "controller/force-display" => Kind::ForceDisplay,
            "controller/position-error-master" => Kind::PositionErrorMaster,
            "controller/four-channel-master" => Kind::FourChannelMaster,
            "controller/four-channel-slave" => Kind::FourChannelSlave,
            "controller/slave-tracking" => Kind::SlaveTracking,
            "controller/slave-position" => Kind::SlavePosition,
            "controller/wave-master" => Kind::WaveMaster,
            "controller/wave-slave" => Kind::WaveSlave,
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
            Kind::Robot("urdf") => "robot/urdf",
            Kind::Robot(_) => "robot/frhc",
            Kind::SimBoard => "board/sim",
            Kind::FpgaBoard => "board/fpga",
            Kind::GalilBoard => "board/galil",
            Kind::VirtualSensor => "sensor/virtual",
            Kind::NetFtSensor => "sensor/netft",
            Kind::OperatorHand => "sensor/operator-hand",
            Kind::ReplaySensor => "sensor/replay",
            Kind::OperatorReplay => "sensor/operator-replay",
            Kind::JointPid => "controller/joint-pid",
            Kind::CartesianImpedance => "controller/cartesian-impedance",
            Kind::JointPosition => "controller/joint-position",
            Kind::JointGroups => "controller/joint-groups",
            Kind::ForceDisplay => "controller/force-display",
            Kind::PositionErrorMaster => "controller/position-error-master",
            Kind::FourChannelMaster => "controller/four-channel-master",
            Kind::FourChannelSlave => "controller/four-channel-slave",
            Kind::SlaveTracking => "controller/slave-tracking",
            Kind::SlavePosition => "controller/slave-position",
            Kind::WaveMaster => "controller/wave-master",
            Kind::WaveSlave => "controller/wave-slave",
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
            Kind::SimBoard | Kind::FpgaBoard | Kind::GalilBoard => Class::Board,
            Kind::VirtualSensor
            | Kind::NetFtSensor
            | Kind::OperatorHand
            | Kind::ReplaySensor
            | Kind::OperatorReplay => Class::Sensor,
            Kind::JointPid
            | Kind::CartesianImpedance
            | Kind::JointPosition
            | Kind::JointGroups
            | Kind::ForceDisplay
            | Kind::PositionErrorMaster
            | Kind::FourChannelMaster
            | Kind::FourChannelSlave
            | Kind::SlaveTracking
            | Kind::SlavePosition
            | Kind::WaveMaster
            | Kind::WaveSlave => Class::Controller,
            Kind::Step | Kind::Ramp | Kind::Trapezoidal | Kind::Spline | Kind::Teleop => {
                Class::Trajectory
            }
        }
    }

    /// What `kinds` lists for it.
    pub fn info(self) -> KindInfo {
        let (summary, config) = match self {
            Kind::Robot("urdf") => (
                "any serial robot from a URDF file: the joints from a base link to a tip link, \
                 the links' inertials for the dynamics",
                URDF_KEYS.to_string() + ROBOT_KEYS,
            ),
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
            Kind::FpgaBoard => (
                "NI PCI-7831R FPGA board for the FRHC: the simulated plant's encoders and motors, \
                 bit-exact forward kinematics and tau = J^T F on the board, with their latency",
                FPGA_BOARD_KEYS.to_string() + SIM_BOARD_KEYS + SHAPE_KEYS,
            ),
            Kind::GalilBoard => (
                "Galil DMC motion board over a serial line or TCP (a DMC or `penelope galil-sim`)",
                GALIL_KEYS.to_string(),
            ),
            Kind::VirtualSensor => (
                "6-axis force sensor: a robot's plant contact at the wrist (bias, noise, low-pass), or an \
                 environment probed at a pose",
                SENSOR_KEYS.to_string() + SHAPE_KEYS,
            ),
            Kind::NetFtSensor => (
                "6-axis force/torque sensor: an ATI Net F/T streaming RDT over UDP (or \
                 `penelope netft-sim`), read in the loop; faults give the loop no wrench",
                NETFT_KEYS.to_string(),
            ),
            Kind::OperatorHand => (
                "the operator's hand on a simulated master: a scripted impedance that pushes the \
                 handle and holds the clutch",
                HAND_KEYS.to_string(),
            ),
            Kind::ReplaySensor => (
                "6-axis force sensor playing back a recorded wrench stream (an MCAP recording's \
                 controller channel, read at configure)",
                super::replay::REPLAY_SENSOR_KEYS.to_string(),
            ),
            Kind::OperatorReplay => (
                "the operator's hand played back from a recording: the master's handle moves, \
                 and the clutch is held, as recorded",
                super::replay::OPERATOR_REPLAY_KEYS.to_string(),
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
            Kind::FourChannelMaster => (
                "teleoperation master, Lawrence's four channels: force channel (C2), position \
                 channel (C4), hand force (C6), local damping; the classical masters as cases",
                FOUR_CHANNEL_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::FourChannelSlave => (
                "teleoperation slave, Lawrence's four channels: position channel (C1, the \
                 tracking), the operator's force (C3), local force feedback (C5)",
                FOUR_CHANNEL_SLAVE_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::SlaveTracking => (
                "teleoperation slave: follows the mapped master pose (IK, computed torque)",
                SLAVE_TRACKING_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::SlavePosition => (
                "teleoperation slave for a board with its own servo: IK, then position targets",
                SLAVE_TRACKING_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::WaveMaster => (
                "teleoperation master, wave variables: passive under any delay and loss (the \
                 waves cross; an energy reserve on each receiver)",
                WAVE_MASTER_KEYS.to_string() + LOOP_KEYS,
            ),
            Kind::WaveSlave => (
                "teleoperation slave, wave variables: follows the wave's pose (matched line, \
                 IK, computed torque); its contact force goes back as a wave",
                WAVE_SLAVE_KEYS.to_string() + LOOP_KEYS,
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
            Kind::JointGroups => (
                "different laws on different joints of one robot: each group a configured \
                 joint-pid or joint-position controller following its own trajectory",
                JOINT_GROUPS_KEYS.to_string() + LOOP_KEYS,
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

// ---------------------------------------------------------------------------------------------
// Parsing helpers
// ---------------------------------------------------------------------------------------------

fn bad(kind: &str, message: impl Into<String>) -> WireError {
    WireError::Call(CallError::BadConfig {
        kind: kind.to_string(),
        message: message.into(),
    })
}

/// Parses `text` as the TOML configuration of `kind` (`""`: defaults).
///
/// # Errors
/// [`CallError::BadConfig`] for bad TOML, unknown keys or wrong types.
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
            /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig).
            pub fn timing(&self, kind: &str) -> Result<$crate::objects::kinds::LoopTiming, ::penelope_protocol::proto::WireError> {
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

loop_keys!(LoopKeysOnly {});

/// The timing keys of any controller's configuration text (other keys are ignored).
///
/// # Errors
/// [`CallError::BadConfig`] for text that is not TOML or timing out of range.
pub fn loop_timing(kind: &str, text: &str) -> Result<LoopTiming, WireError> {
    let table: toml::Table = text.parse().map_err(|e| bad(kind, format!("{e}")))?;
    let keys = [
        "period_us",
        "comm_period_us",
        "watchdog_ms",
        "sensor_period_ms",
        "sensor_timeout_ms",
        "telemetry_period_ms",
    ];
    let timing: toml::Table = table
        .into_iter()
        .filter(|(k, _)| keys.contains(&k.as_str()))
        .collect();
    let keys: LoopKeysOnly = parse(kind, &timing.to_string())?;
    keys.timing(kind)
}

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
    /// [`CallError::BadConfig`].
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

/// One group of a `controller/joint-groups`: a member controller and the joints it drives.
#[derive(Clone, Debug, PartialEq, ::serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointGroupToml {
    /// The member controller's name (on the same node).
    pub controller: String,
    /// The joints it drives, 0-based.
    pub joints: Vec<usize>,
}

loop_keys!(JointGroupsConfig {
    groups: Vec<JointGroupToml> = Vec::new(), #[doc = "The groups, each a member controller and its joints."]
});

impl JointGroupsConfig {
    /// Checks what does not depend on the robot or the members (those are checked when the
    /// loop is built).
    ///
    /// # Errors
    /// [`CallError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, WireError> {
        if self.groups.is_empty() || self.groups.len() > penelope_hal::MAX_JOINTS {
            return Err(bad(
                kind,
                format!(
                    "`groups`: {} groups, need 1 to {}",
                    self.groups.len(),
                    penelope_hal::MAX_JOINTS
                ),
            ));
        }
        let mut claimed = [None::<usize>; penelope_hal::MAX_JOINTS];
        for (i, g) in self.groups.iter().enumerate() {
            penelope_protocol::proto::check_name(&g.controller)
                .map_err(|e| bad(kind, format!("`groups[{i}].controller`: {e}")))?;
            if g.joints.is_empty() {
                return Err(bad(kind, format!("`groups[{i}].joints` is empty")));
            }
            if let Some(j) = g.joints.iter().find(|&&j| j >= penelope_hal::MAX_JOINTS) {
                return Err(bad(
                    kind,
                    format!("`groups[{i}].joints`: joint {j} is past the largest robot's joints"),
                ));
            }
            for &j in &g.joints {
                match claimed[j] {
                    Some(other) if other != i => {
                        return Err(bad(
                            kind,
                            format!("`groups`: joint {j} is in groups {other} and {i}"),
                        ));
                    }
                    _ => claimed[j] = Some(i),
                }
            }
        }
        if let Some(dup) = self.groups.iter().enumerate().find(|(i, g)| {
            self.groups[..*i]
                .iter()
                .any(|o| o.controller == g.controller)
        }) {
            return Err(bad(
                kind,
                format!(
                    "`groups`: controller `{}` is in two groups",
                    dup.1.controller
                ),
            ));
        }
        self.timing(kind)
    }

    /// The group's joints as a set (call after [`check`](Self::check)).
    pub fn joint_set(group: &JointGroupToml) -> penelope_hal::JointSet {
        group
            .joints
            .iter()
            .fold(penelope_hal::JointSet::EMPTY, |s, &j| s.with(j))
    }
}

impl JointPositionConfig {
    /// Checks what does not depend on the robot.
    ///
    /// # Errors
    /// [`CallError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, WireError> {
        self.max_velocity.check(kind, "max_velocity", 1e-3, 100.0)?;
        self.timing(kind)
    }
}

impl ImpedanceConfigToml {
    /// Checks ranges.
    ///
    /// # Errors
    /// [`CallError::BadConfig`].
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
                matches!(
                    c.check(k),
                    Err(WireError::Call(CallError::BadConfig { .. }))
                ),
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
        assert_eq!(kinds.len(), 29);
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
            Err(WireError::Call(CallError::BadConfig { .. }))
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
