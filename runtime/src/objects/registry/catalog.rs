//! The catalog: every kind a creator makes, registered in one place, one line each: its
//! [`Kind`] (its name), a one-line summary, its configuration type (from which the key list
//! `ctl kinds` shows is derived: [`describe`](crate::objects::config::describe)) and the function
//! that makes its object.
//!
//! To add a kind (a sensor, say), write its module (declared beside `netft` in the registry) and
//! add its line here; `docs/system-files.md` gets its row. A sensor read in the control loop's
//! own thread, like `sensor/netft` ([`netft`](super::netft)), is the example: its module holds its name (a
//! [`Kind`] constant), its configuration type (`#[derive(Deserialize, Serialize, JsonSchema)]`,
//! `#[serde(deny_unknown_fields, default)]`, a doc comment per field, and `impl KindConfig` with
//! an `example` that sets the optional keys), its object (a `LoopSensorObject`, the registry's
//! trait for such sensors: configure, release, describe, methods, and the reader the loop reads)
//! and its [`KindEntry`], registered below as `super::netft::ENTRY`.
//!
//! `every_kind_round_trips_through_its_description` then checks the new kind's description
//! against its parser, `the_creator_parses_each_kind_with_the_type_its_entry_describes` that its
//! maker parses the type the entry names, and `the_docs_list_every_kind_with_its_summary` that
//! `docs/system-files.md` lists it.

use penelope_protocol::proto::KindInfo;

pub use super::kind_entry::KindEntry;
use super::kind_entry::Maker;
use super::makers;
use crate::objects::config::describe::{Described, described};
use crate::objects::kinds::{
    GalilConfig, ImpedanceConfigToml, JointGroupsConfig, JointPidConfig, JointPositionConfig, Kind,
    RampConfig, RobotConfig, SensorConfig, SimBoardConfig, SplineConfig, StepConfig,
    TrapezoidalConfig,
};
use crate::objects::operator_hand::HandConfig;
use crate::objects::replay::{OperatorReplayConfig, ReplaySensorConfig};
use crate::objects::teleop::TeleopConfig;
use crate::objects::teleop_laws::{
    ForceDisplayToml, FourChannelSlaveToml, FourChannelToml, PositionErrorToml, SlaveTrackingToml,
};
use crate::objects::teleop_wave::{WaveMasterToml, WaveSlaveToml};

const fn entry(kind: Kind, summary: &'static str, config: Described, make: Maker) -> KindEntry {
    KindEntry::new(kind, summary, config, make)
}

/// Every kind, in listing order: one line per kind.
#[rustfmt::skip]
pub static KIND_TABLE: &[KindEntry] = &[
    entry(Kind::PUMA560, "Unimation PUMA 560 (Robotics Toolbox DH model with dynamics)", described::<RobotConfig>(), makers::robot),
    entry(Kind::PUMA200, "Unimation PUMA 200 (PUMA 260 geometry, assumed dynamics)", described::<RobotConfig>(), makers::robot),
    entry(Kind::FRHC, "JPL Force Reflecting Hand Controller (master joystick)", described::<RobotConfig>(), makers::robot),
    entry(Kind::URDF, "any serial robot from a URDF file: the joints from a base link to a tip link, the links' inertials for the dynamics", described::<RobotConfig>(), makers::robot),
    entry(Kind::SIM_BOARD, "simulated motion board; the rigid-body plant of the robot mapped onto it", described::<SimBoardConfig>(), makers::sim_board),
    entry(Kind::FPGA_BOARD, "NI PCI-7831R FPGA board for the FRHC (all six joints): the simulated plant's encoders and motors, bit-exact forward kinematics, Jacobian frames and tau = J^T F on the board, the results on the host after 61 (FK) and 92 (FK + force) cycles at 40 MHz plus the DMA transfers (`ctl describe` of the board shows them); the plant behind it takes board/sim's keys", described::<SimBoardConfig>(), makers::sim_board),
    entry(Kind::GALIL_BOARD, "Galil DMC motion board over a serial line or TCP (a DMC or `penelope galil-sim`)", described::<GalilConfig>(), makers::galil_board).as_real_device(),
    entry(Kind::VIRTUAL_SENSOR, "6-axis force sensor: a robot's plant contact at the wrist (bias, noise, low-pass), or an environment probed at a pose", described::<SensorConfig>(), makers::virtual_sensor),
    super::netft::ENTRY,
    super::test_signal::ENTRY,
    super::camera::ENTRY,
    super::camera::DEVICE_ENTRY,
    entry(Kind::OPERATOR_HAND, "the operator's hand on a simulated master: a scripted impedance that pushes the handle and holds the clutch", described::<HandConfig>(), makers::operator_hand),
    entry(Kind::REPLAY_SENSOR, "6-axis force sensor playing back a recorded wrench stream (an MCAP recording's controller channel, read at configure)", described::<ReplaySensorConfig>(), makers::replay),
    entry(Kind::OPERATOR_REPLAY, "the operator's hand played back from a recording: the master's handle moves, and the clutch is held, as recorded", described::<OperatorReplayConfig>(), makers::replay),
    entry(Kind::JOINT_PID, "joint-space PID with gravity compensation", described::<JointPidConfig>(), makers::joint_pid),
    entry(Kind::CARTESIAN_IMPEDANCE, "Cartesian impedance (spring-damper at the tool) with gravity compensation", described::<ImpedanceConfigToml>(), makers::cartesian_impedance),
    entry(Kind::JOINT_POSITION, "joint positions for the board's own servo (a Galil DMC closes the loop)", described::<JointPositionConfig>(), makers::joint_position),
    entry(Kind::JOINT_GROUPS, "different laws on different joints of one robot: each group a configured joint-pid or joint-position controller following its own trajectory", described::<JointGroupsConfig>(), makers::joint_groups),
    entry(Kind::FORCE_DISPLAY, "teleoperation master, position-forward / force-back: displays the mapped slave force (tau = J^T F), capped; its trajectory a trajectory/teleop whose master is this robot", described::<ForceDisplayToml>(), makers::force_display),
    entry(Kind::POSITION_ERROR_MASTER, "teleoperation master, position-error: a spring-damper to the mapped slave pose; its trajectory a trajectory/teleop whose master is this robot", described::<PositionErrorToml>(), makers::position_error_master),
    entry(Kind::FOUR_CHANNEL_MASTER, "teleoperation master, Lawrence's four channels: F = c2 F_slave + c4 spring(slave pose) + c6 F_hand - C_m v, capped, tau = J^T F + g (c2 = 1, c4 = 0: force-display, bit for bit; c2 = 0, c4 = 1, damping 0: position-error-master); its trajectory a trajectory/teleop whose master is this robot", described::<FourChannelToml>(), makers::four_channel_master),
    entry(Kind::FOUR_CHANNEL_SLAVE, "teleoperation slave, Lawrence's four channels: tau = tracking(master pose; gains x c1) + J^T (c3 F_hand + c5 F_contact) (c1 = 1, c3 = c5 = 0: slave-tracking, bit for bit); its trajectory a trajectory/teleop whose slave is this robot", described::<FourChannelSlaveToml>(), makers::four_channel_slave),
    entry(Kind::SLAVE_TRACKING, "teleoperation slave: follows the mapped master pose (IK, computed torque); its trajectory a trajectory/teleop whose slave is this robot", described::<SlaveTrackingToml>(), makers::slave_tracking),
    entry(Kind::SLAVE_POSITION, "teleoperation slave for a board with its own servo: IK, then position targets; its trajectory a trajectory/teleop whose slave is this robot", described::<SlaveTrackingToml>(), makers::slave_tracking),
    entry(Kind::WAVE_MASTER, "teleoperation master, wave variables: passive under any delay and loss (the waves cross; an energy reserve on each receiver); its trajectory a trajectory/teleop on this node whose master is this robot", described::<WaveMasterToml>(), makers::wave_master),
    entry(Kind::WAVE_SLAVE, "teleoperation slave, wave variables: follows the wave's pose (matched line, IK, computed torque); its contact force (its sensor, at the wrist) goes back as a wave; its trajectory a trajectory/teleop on this node whose slave is this robot", described::<WaveSlaveToml>(), makers::wave_slave),
    entry(Kind::STEP, "joint step to a goal after a delay", described::<StepConfig>(), makers::trajectory),
    entry(Kind::RAMP, "joint ramp at constant speed over a duration", described::<RampConfig>(), makers::trajectory),
    entry(Kind::TRAPEZOIDAL, "joint move with trapezoidal velocity, every joint synchronised", described::<TrapezoidalConfig>(), makers::trajectory),
    entry(Kind::SPLINE, "C2 cubic spline through timed joint waypoints", described::<SplineConfig>(), makers::trajectory),
    entry(Kind::TELEOP, "the channel between a master and a slave: the master's pose forward (scaled, rotated, clutched), the slave's pose and wrench back", described::<TeleopConfig>(), makers::teleop),
];

/// The entry named `name` (`class/kind`).
pub fn entry_named(name: &str) -> Option<&'static KindEntry> {
    KIND_TABLE.iter().find(|e| e.name() == name)
}

/// The kind named `name`, if the catalog has it.
pub fn parse_kind(name: &str) -> Option<Kind> {
    entry_named(name).map(|e| e.kind)
}

/// Every kind, in listing order, as `kinds` lists them.
pub fn all_kinds() -> Vec<KindInfo> {
    KIND_TABLE.iter().map(KindEntry::info).collect()
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
            .map(|e| format!("| `{}` | {} |", e.name(), e.summary))
            .collect();
        assert_eq!(rows, expected, "docs/system-files.md's kind table");
    }

    #[test]
    fn a_key_of_one_kind_is_left_out_of_the_others_lists() {
        let urdf = entry_named("robot/urdf").unwrap().info().config;
        let puma = entry_named("robot/puma560").unwrap().info().config;
        for key in ["file =", "tip =", "base =", "poses ="] {
            assert!(urdf.contains(key), "{key} missing from {urdf}");
            assert!(!puma.contains(key), "{key} in {puma}");
        }
        assert!(
            puma.contains("start =") && puma.contains("role ="),
            "{puma}"
        );
    }

    #[test]
    fn every_kind_is_registered_once_and_parses_back() {
        let kinds = all_kinds();
        assert_eq!(kinds.len(), KIND_TABLE.len());
        for k in &kinds {
            let parsed = parse_kind(&k.kind).unwrap();
            assert_eq!(parsed.as_str(), k.kind);
            assert_eq!(parsed.class(), k.class);
            assert_eq!(parsed.class().as_str(), k.kind.split('/').next().unwrap());
            assert!(!k.config.is_empty());
        }
        for (i, e) in KIND_TABLE.iter().enumerate() {
            assert!(
                KIND_TABLE[..i].iter().all(|o| o.kind != e.kind),
                "{} registered twice",
                e.name()
            );
        }
        assert_eq!(parse_kind("robot/r2d2"), None);
        // Only real devices are refused on a simulated clock.
        let real: Vec<&str> = KIND_TABLE
            .iter()
            .filter(|e| e.real_device)
            .map(|e| e.name())
            .collect();
        assert_eq!(real, ["board/galil", "sensor/netft"]);
    }
}
