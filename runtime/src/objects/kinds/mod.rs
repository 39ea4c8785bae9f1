//! The kinds a creator makes, and their configurations: TOML text with documented keys, units and
//! defaults, unknown keys refused, ranges checked. `""` means every default.
//!
//! Each kind is registered once, in [`table`]: its name, summary and configuration type. The key
//! list `penelope ctl kinds`, the web page's forms and the docs show is derived from that type
//! ([`describe`](crate::objects::config::describe)): its fields, their doc comments and an example value.

mod devices;
mod per_joint;
pub mod table;
mod trajectory;

pub use per_joint::PerJoint;
pub use table::{
    BOARD_FPGA, BOARD_GALIL, BOARD_SIM, CONTROLLER_CARTESIAN_IMPEDANCE, CONTROLLER_FORCE_DISPLAY,
    CONTROLLER_FOUR_CHANNEL_MASTER, CONTROLLER_FOUR_CHANNEL_SLAVE, CONTROLLER_JOINT_GROUPS,
    CONTROLLER_JOINT_PID, CONTROLLER_JOINT_POSITION, CONTROLLER_POSITION_ERROR_MASTER,
    CONTROLLER_SLAVE_POSITION, CONTROLLER_SLAVE_TRACKING, CONTROLLER_WAVE_MASTER,
    CONTROLLER_WAVE_SLAVE, Described, KIND_TABLE, KindEntry, ROBOT_FRHC, ROBOT_PUMA200,
    ROBOT_PUMA560, ROBOT_URDF, SENSOR_NETFT, SENSOR_OPERATOR_HAND, SENSOR_OPERATOR_REPLAY,
    SENSOR_REPLAY, SENSOR_VIRTUAL, TRAJECTORY_RAMP, TRAJECTORY_SPLINE, TRAJECTORY_STEP,
    TRAJECTORY_TELEOP, TRAJECTORY_TRAPEZOIDAL, described, entry_named, entry_of,
};

pub use devices::{
    GalilConfig, NetFtSensorConfig, RobotConfig, SensorConfig, ShapeConfig, SimBoardConfig,
    environment,
};

pub use trajectory::{
    GoalConfig, MAX_WAYPOINTS, RampConfig, SplineConfig, StepConfig, TrajectorySpec,
    TrapezoidalConfig, WaypointConfig, trajectory_spec,
};

use penelope_protocol::proto::{Class, KindInfo, WireError};

use crate::objects::config::{KindConfig, LoopTiming, bad, check_int, check_range, loop_keys};

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
    /// Parses `class/kind` (a name in [`KIND_TABLE`]).
    pub fn parse(kind: &str) -> Option<Kind> {
        entry_named(kind).map(|e| e.kind)
    }

    /// `class/kind`.
    pub fn as_str(self) -> &'static str {
        entry_of(self).name
    }

    /// Its class.
    pub fn class(self) -> Class {
        entry_of(self).class()
    }

    /// What `kinds` lists for it.
    pub fn info(self) -> KindInfo {
        entry_of(self).info()
    }
}

/// Every kind, in listing order.
pub fn all_kinds() -> Vec<KindInfo> {
    KIND_TABLE.iter().map(KindEntry::info).collect()
}

loop_keys!(JointPidConfig {
    kp: Option<PerJoint> = None, #[doc = "Proportional gain, N·m/rad, one value or one per joint, 0..=1e7 (without it: 10 × the joint's torque limit, per rad)."]
    ki: PerJoint = PerJoint::One(0.0), #[doc = "Integral gain, N·m/(rad·s), one value or one per joint, 0..=1e7."]
    kd: Option<PerJoint> = None, #[doc = "Derivative gain, N·m·s/rad, one value or one per joint, 0..=1e6 (without it: 0.5 × the joint's torque limit, per rad/s)."]
    integral_limit: PerJoint = PerJoint::One(0.0), #[doc = "Cap of the integral term, N·m, 0..=1e5."]
    gravity_compensation: bool = true, #[doc = "Add g(q)."]
    acceleration_feedforward: bool = false, #[doc = "Add M(q) qdd_ref."]
});

impl KindConfig for JointPidConfig {
    fn example() -> Self {
        JointPidConfig {
            kp: Some(PerJoint::Each(vec![
                900.0, 1600.0, 900.0, 100.0, 100.0, 100.0,
            ])),
            kd: Some(PerJoint::One(20.0)),
            ..Self::default()
        }
    }
}

loop_keys!(ImpedanceConfigToml {
    stiffness: [f64; 6] = [2000.0, 2000.0, 2000.0, 50.0, 50.0, 50.0], #[doc = "N/m then N·m/rad, base frame, each 0..=1e6."]
    damping: [f64; 6] = [150.0, 150.0, 150.0, 3.0, 3.0, 3.0], #[doc = "N·s/m then N·m·s/rad, each 0..=1e5."]
    gravity_compensation: bool = true, #[doc = "Add g(q)."]
    max_force: f64 = f64::INFINITY, #[doc = "Cap of the commanded force, N, > 0 (inf: none)."]
    max_torque: f64 = f64::INFINITY, #[doc = "Cap of the commanded moment, N·m, > 0 (inf: none)."]
    ramp_in_ms: u64 = 0, #[doc = "Stiffness ramp after activation, ms, 0..=60000."]
});

impl KindConfig for ImpedanceConfigToml {}

impl JointPidConfig {
    /// Checks what does not depend on the robot.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig).
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
    max_velocity: PerJoint = PerJoint::One(1.0), #[doc = "How fast the servo's target may move, rad/s, one value or one per joint, 1e-3..=100."]
});

impl KindConfig for JointPositionConfig {}

/// One group of a `controller/joint-groups`: a member controller and the joints it drives.
#[derive(
    Clone, Debug, PartialEq, ::serde::Deserialize, ::serde::Serialize, ::schemars::JsonSchema,
)]
#[serde(deny_unknown_fields)]
pub struct JointGroupToml {
    /// The member controller's name (on the same node): a configured controller/joint-pid or
    /// controller/joint-position with the same robot, following its own trajectory (joint or
    /// tool goals); it runs in this controller's loop, not on its own.
    pub controller: String,
    /// The joints it drives, 0-based.
    pub joints: Vec<usize>,
}

loop_keys!(JointGroupsConfig {
    groups: Vec<JointGroupToml> = Vec::new(), #[doc = "The groups (1 to 8), each a member controller and its joints; each joint of the robot in exactly one group."]
});

impl KindConfig for JointGroupsConfig {
    fn example() -> Self {
        JointGroupsConfig {
            groups: vec![
                JointGroupToml {
                    controller: "arm".into(),
                    joints: vec![0, 1, 2],
                },
                JointGroupToml {
                    controller: "wrist".into(),
                    joints: vec![3, 4, 5],
                },
            ],
            ..Self::default()
        }
    }
}

impl JointGroupsConfig {
    /// Checks what does not depend on the robot or the members (those are checked when the
    /// loop is built).
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig).
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
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig).
    pub fn check(&self, kind: &str) -> Result<LoopTiming, WireError> {
        self.max_velocity.check(kind, "max_velocity", 1e-3, 100.0)?;
        self.timing(kind)
    }
}

impl ImpedanceConfigToml {
    /// Checks ranges.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig).
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
    use crate::objects::config::parse;
    use penelope_protocol::proto::CallError;

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
        assert_eq!(kinds.len(), KIND_TABLE.len());
        for k in &kinds {
            let parsed = Kind::parse(&k.kind).unwrap();
            assert_eq!(parsed.as_str(), k.kind);
            assert_eq!(parsed.class(), k.class);
            assert_eq!(parsed.class().as_str(), k.kind.split('/').next().unwrap());
            assert!(!k.config.is_empty());
        }
        // A name and a kind are registered once.
        for (i, e) in KIND_TABLE.iter().enumerate() {
            assert!(
                KIND_TABLE[..i]
                    .iter()
                    .all(|o| o.name != e.name && o.kind != e.kind),
                "{} registered twice",
                e.name
            );
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
