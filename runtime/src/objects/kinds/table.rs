//! Every kind a creator makes, registered in one place: its name (written once, here), its
//! [`Kind`], a one-line summary and its configuration type, from which the key list `ctl kinds`
//! shows is derived ([`describe`](crate::objects::config::describe)). The class is the name's prefix.
//!
//! To add a kind (a sensor, say):
//! 1. its configuration type in its own module: `#[derive(Deserialize, Serialize, JsonSchema)]`,
//!    `#[serde(deny_unknown_fields, default)]`, a doc comment per field (units, range, what an
//!    absent optional key means), and `impl KindConfig` (with an `example` that sets the
//!    optional keys, so that the list shows them);
//! 2. a [`Kind`] variant;
//! 3. here, its name's const and one [`KindEntry`] line in [`KIND_TABLE`] (and its row in
//!    `docs/system-files.md`, which a test keeps equal to the table);
//! 4. what the object does: its arm in the registry's `make` (and `configure`, if it has one).
//!
//! `every_kind_round_trips_through_its_description` then checks the new kind's description
//! against its parser, and `the_creator_parses_each_kind_with_the_type_its_entry_describes` that
//! `make` parses the type the entry names.

use penelope_protocol::proto::{Class, KindInfo, WireError};

use std::collections::BTreeSet;

use super::Kind;
use crate::objects::config::describe::{
    FieldTree, KindConfig, fields_of, key_text, other_kinds_keys,
};
use crate::objects::config::parse;

use super::devices::{GalilConfig, NetFtSensorConfig, RobotConfig, SensorConfig, SimBoardConfig};
use super::trajectory::{RampConfig, SplineConfig, StepConfig, TrapezoidalConfig};
use super::{ImpedanceConfigToml, JointGroupsConfig, JointPidConfig, JointPositionConfig};
use crate::objects::operator_hand::HandConfig;
use crate::objects::replay::{OperatorReplayConfig, ReplaySensorConfig};
use crate::objects::teleop::TeleopConfig;
use crate::objects::teleop_laws::{
    ForceDisplayToml, FourChannelSlaveToml, FourChannelToml, PositionErrorToml, SlaveTrackingToml,
};
use crate::objects::teleop_wave::{WaveMasterToml, WaveSlaveToml};

/// `robot/puma560`.
pub const ROBOT_PUMA560: &str = "robot/puma560";
/// `robot/puma200`.
pub const ROBOT_PUMA200: &str = "robot/puma200";
/// `robot/frhc`.
pub const ROBOT_FRHC: &str = "robot/frhc";
/// `robot/urdf`.
pub const ROBOT_URDF: &str = "robot/urdf";
/// `board/sim`.
pub const BOARD_SIM: &str = "board/sim";
/// `board/fpga`.
pub const BOARD_FPGA: &str = "board/fpga";
/// `board/galil`.
pub const BOARD_GALIL: &str = "board/galil";
/// `sensor/virtual`.
pub const SENSOR_VIRTUAL: &str = "sensor/virtual";
/// `sensor/netft`.
pub const SENSOR_NETFT: &str = "sensor/netft";
/// `sensor/operator-hand`.
pub const SENSOR_OPERATOR_HAND: &str = "sensor/operator-hand";
/// `sensor/replay`.
pub const SENSOR_REPLAY: &str = "sensor/replay";
/// `sensor/operator-replay`.
pub const SENSOR_OPERATOR_REPLAY: &str = "sensor/operator-replay";
/// `controller/joint-pid`.
pub const CONTROLLER_JOINT_PID: &str = "controller/joint-pid";
/// `controller/cartesian-impedance`.
pub const CONTROLLER_CARTESIAN_IMPEDANCE: &str = "controller/cartesian-impedance";
/// `controller/joint-position`.
pub const CONTROLLER_JOINT_POSITION: &str = "controller/joint-position";
/// `controller/joint-groups`.
pub const CONTROLLER_JOINT_GROUPS: &str = "controller/joint-groups";
/// `controller/force-display`.
pub const CONTROLLER_FORCE_DISPLAY: &str = "controller/force-display";
/// `controller/position-error-master`.
pub const CONTROLLER_POSITION_ERROR_MASTER: &str = "controller/position-error-master";
/// `controller/four-channel-master`.
pub const CONTROLLER_FOUR_CHANNEL_MASTER: &str = "controller/four-channel-master";
/// `controller/four-channel-slave`.
pub const CONTROLLER_FOUR_CHANNEL_SLAVE: &str = "controller/four-channel-slave";
/// `controller/slave-tracking`.
pub const CONTROLLER_SLAVE_TRACKING: &str = "controller/slave-tracking";
/// `controller/slave-position`.
pub const CONTROLLER_SLAVE_POSITION: &str = "controller/slave-position";
/// `controller/wave-master`.
pub const CONTROLLER_WAVE_MASTER: &str = "controller/wave-master";
/// `controller/wave-slave`.
pub const CONTROLLER_WAVE_SLAVE: &str = "controller/wave-slave";
/// `trajectory/step`.
pub const TRAJECTORY_STEP: &str = "trajectory/step";
/// `trajectory/ramp`.
pub const TRAJECTORY_RAMP: &str = "trajectory/ramp";
/// `trajectory/trapezoidal`.
pub const TRAJECTORY_TRAPEZOIDAL: &str = "trajectory/trapezoidal";
/// `trajectory/spline`.
pub const TRAJECTORY_SPLINE: &str = "trajectory/spline";
/// `trajectory/teleop`.
pub const TRAJECTORY_TELEOP: &str = "trajectory/teleop";

/// What a kind's configuration type gives the table, its type erased.
#[derive(Clone, Copy)]
pub struct Described {
    /// The key list for a kind ([`key_text`]).
    pub keys: fn(&str) -> String,
    /// The keys that apply to other kinds only ([`other_kinds_keys`]).
    pub other_kinds_keys: fn(&str) -> BTreeSet<String>,
    /// The fields its parser knows ([`fields_of`]).
    pub fields: fn() -> FieldTree,
    /// Its parser ([`parse`]), the value dropped.
    pub parses: fn(&str, &str) -> Result<(), WireError>,
}

/// The description of configuration type `T`.
pub const fn described<T: KindConfig>() -> Described {
    Described {
        keys: key_text::<T>,
        other_kinds_keys: other_kinds_keys::<T>,
        fields: fields_of::<T>,
        parses: parses::<T>,
    }
}

fn parses<T: KindConfig>(kind: &str, text: &str) -> Result<(), WireError> {
    parse::<T>(kind, text).map(drop)
}

/// One registered kind.
#[derive(Clone, Copy)]
pub struct KindEntry {
    /// `class/kind`.
    pub name: &'static str,
    /// The kind the creator dispatches on.
    pub kind: Kind,
    /// One line on what it is.
    pub summary: &'static str,
    /// Its configuration.
    pub config: Described,
}

impl KindEntry {
    /// Its class: the name's prefix.
    pub fn class(&self) -> Class {
        self.name
            .split_once('/')
            .and_then(|(c, _)| Class::parse(c))
            .unwrap_or(Class::Creator)
    }

    /// What `kinds` lists for it.
    pub fn info(&self) -> KindInfo {
        KindInfo {
            kind: self.name.to_string(),
            class: self.class(),
            summary: self.summary.to_string(),
            config: (self.config.keys)(self.name).trim().to_string(),
        }
    }
}

const fn entry(
    name: &'static str,
    kind: Kind,
    summary: &'static str,
    config: Described,
) -> KindEntry {
    KindEntry {
        name,
        kind,
        summary,
        config,
    }
}

/// Every kind, in listing order: one line per kind.
#[rustfmt::skip]
pub static KIND_TABLE: &[KindEntry] = &[
    entry(ROBOT_PUMA560, Kind::Robot("puma560"), "Unimation PUMA 560 (Robotics Toolbox DH model with dynamics)", described::<RobotConfig>()),
    entry(ROBOT_PUMA200, Kind::Robot("puma200"), "Unimation PUMA 200 (PUMA 260 geometry, assumed dynamics)", described::<RobotConfig>()),
    entry(ROBOT_FRHC, Kind::Robot("frhc"), "JPL Force Reflecting Hand Controller (master joystick)", described::<RobotConfig>()),
    entry(ROBOT_URDF, Kind::Robot("urdf"), "any serial robot from a URDF file: the joints from a base link to a tip link, the links' inertials for the dynamics", described::<RobotConfig>()),
    entry(BOARD_SIM, Kind::SimBoard, "simulated motion board; the rigid-body plant of the robot mapped onto it", described::<SimBoardConfig>()),
    entry(BOARD_FPGA, Kind::FpgaBoard, "NI PCI-7831R FPGA board for the FRHC (all six joints): the simulated plant's encoders and motors, bit-exact forward kinematics, Jacobian frames and tau = J^T F on the board, the results on the host after 61 (FK) and 92 (FK + force) cycles at 40 MHz plus the DMA transfers (`ctl describe` of the board shows them); the plant behind it takes board/sim's keys", described::<SimBoardConfig>()),
    entry(BOARD_GALIL, Kind::GalilBoard, "Galil DMC motion board over a serial line or TCP (a DMC or `penelope galil-sim`)", described::<GalilConfig>()),
    entry(SENSOR_VIRTUAL, Kind::VirtualSensor, "6-axis force sensor: a robot's plant contact at the wrist (bias, noise, low-pass), or an environment probed at a pose", described::<SensorConfig>()),
    entry(SENSOR_NETFT, Kind::NetFtSensor, "6-axis force/torque sensor: an ATI Net F/T streaming RDT over UDP (or `penelope netft-sim`), read in the loop; faults give the loop no wrench", described::<NetFtSensorConfig>()),
    entry(SENSOR_OPERATOR_HAND, Kind::OperatorHand, "the operator's hand on a simulated master: a scripted impedance that pushes the handle and holds the clutch", described::<HandConfig>()),
    entry(SENSOR_REPLAY, Kind::ReplaySensor, "6-axis force sensor playing back a recorded wrench stream (an MCAP recording's controller channel, read at configure)", described::<ReplaySensorConfig>()),
    entry(SENSOR_OPERATOR_REPLAY, Kind::OperatorReplay, "the operator's hand played back from a recording: the master's handle moves, and the clutch is held, as recorded", described::<OperatorReplayConfig>()),
    entry(CONTROLLER_JOINT_PID, Kind::JointPid, "joint-space PID with gravity compensation", described::<JointPidConfig>()),
    entry(CONTROLLER_CARTESIAN_IMPEDANCE, Kind::CartesianImpedance, "Cartesian impedance (spring-damper at the tool) with gravity compensation", described::<ImpedanceConfigToml>()),
    entry(CONTROLLER_JOINT_POSITION, Kind::JointPosition, "joint positions for the board's own servo (a Galil DMC closes the loop)", described::<JointPositionConfig>()),
    entry(CONTROLLER_JOINT_GROUPS, Kind::JointGroups, "different laws on different joints of one robot: each group a configured joint-pid or joint-position controller following its own trajectory", described::<JointGroupsConfig>()),
    entry(CONTROLLER_FORCE_DISPLAY, Kind::ForceDisplay, "teleoperation master, position-forward / force-back: displays the mapped slave force (tau = J^T F), capped; its trajectory a trajectory/teleop whose master is this robot", described::<ForceDisplayToml>()),
    entry(CONTROLLER_POSITION_ERROR_MASTER, Kind::PositionErrorMaster, "teleoperation master, position-error: a spring-damper to the mapped slave pose; its trajectory a trajectory/teleop whose master is this robot", described::<PositionErrorToml>()),
    entry(CONTROLLER_FOUR_CHANNEL_MASTER, Kind::FourChannelMaster, "teleoperation master, Lawrence's four channels: F = c2 F_slave + c4 spring(slave pose) + c6 F_hand - C_m v, capped, tau = J^T F + g (c2 = 1, c4 = 0: force-display, bit for bit; c2 = 0, c4 = 1, damping 0: position-error-master); its trajectory a trajectory/teleop whose master is this robot", described::<FourChannelToml>()),
    entry(CONTROLLER_FOUR_CHANNEL_SLAVE, Kind::FourChannelSlave, "teleoperation slave, Lawrence's four channels: tau = tracking(master pose; gains x c1) + J^T (c3 F_hand + c5 F_contact) (c1 = 1, c3 = c5 = 0: slave-tracking, bit for bit); its trajectory a trajectory/teleop whose slave is this robot", described::<FourChannelSlaveToml>()),
    entry(CONTROLLER_SLAVE_TRACKING, Kind::SlaveTracking, "teleoperation slave: follows the mapped master pose (IK, computed torque); its trajectory a trajectory/teleop whose slave is this robot", described::<SlaveTrackingToml>()),
    entry(CONTROLLER_SLAVE_POSITION, Kind::SlavePosition, "teleoperation slave for a board with its own servo: IK, then position targets; its trajectory a trajectory/teleop whose slave is this robot", described::<SlaveTrackingToml>()),
    entry(CONTROLLER_WAVE_MASTER, Kind::WaveMaster, "teleoperation master, wave variables: passive under any delay and loss (the waves cross; an energy reserve on each receiver); its trajectory a trajectory/teleop on this node whose master is this robot", described::<WaveMasterToml>()),
    entry(CONTROLLER_WAVE_SLAVE, Kind::WaveSlave, "teleoperation slave, wave variables: follows the wave's pose (matched line, IK, computed torque); its contact force (its sensor, at the wrist) goes back as a wave; its trajectory a trajectory/teleop on this node whose slave is this robot", described::<WaveSlaveToml>()),
    entry(TRAJECTORY_STEP, Kind::Step, "joint step to a goal after a delay", described::<StepConfig>()),
    entry(TRAJECTORY_RAMP, Kind::Ramp, "joint ramp at constant speed over a duration", described::<RampConfig>()),
    entry(TRAJECTORY_TRAPEZOIDAL, Kind::Trapezoidal, "joint move with trapezoidal velocity, every joint synchronised", described::<TrapezoidalConfig>()),
    entry(TRAJECTORY_SPLINE, Kind::Spline, "C2 cubic spline through timed joint waypoints", described::<SplineConfig>()),
    entry(TRAJECTORY_TELEOP, Kind::Teleop, "the channel between a master and a slave: the master's pose forward (scaled, rotated, clutched), the slave's pose and wrench back", described::<TeleopConfig>()),
];

/// The entry of `kind` (every [`Kind`] the creator makes comes from this table; the first entry
/// stands in for one that does not, rather than a panic).
pub fn entry_of(kind: Kind) -> &'static KindEntry {
    KIND_TABLE
        .iter()
        .find(|e| e.kind == kind)
        .unwrap_or(&KIND_TABLE[0])
}

/// The entry named `name`.
pub fn entry_named(name: &str) -> Option<&'static KindEntry> {
    KIND_TABLE.iter().find(|e| e.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_docs_list_every_kind_with_its_summary() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/system-files.md");
        let docs = std::fs::read_to_string(path).unwrap();
        let rows: Vec<&str> = docs.lines().filter(|l| l.starts_with("| `")).collect();
        let expected: Vec<String> = KIND_TABLE
            .iter()
            .map(|e| format!("| `{}` | {} |", e.name, e.summary))
            .collect();
        assert_eq!(rows, expected, "docs/system-files.md's kind table");
    }

    #[test]
    fn a_key_of_one_kind_is_left_out_of_the_others_lists() {
        let urdf = entry_named(ROBOT_URDF).unwrap().info().config;
        let puma = entry_named(ROBOT_PUMA560).unwrap().info().config;
        for key in ["file =", "tip =", "base =", "poses ="] {
            assert!(urdf.contains(key), "{key} missing from {urdf}");
            assert!(!puma.contains(key), "{key} in {puma}");
        }
        assert!(
            puma.contains("start =") && puma.contains("role ="),
            "{puma}"
        );
    }
}
