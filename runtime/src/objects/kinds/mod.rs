//! The kinds a creator makes, and their configurations: TOML text with documented keys, units and
//! defaults, unknown keys refused, ranges checked. `""` means every default.
//!
//! Each kind is registered once, in the registry's catalog: its name, summary, configuration type
//! and maker. The key list `penelope ctl kinds`, the web page's forms and the docs show is derived
//! from that type ([`describe`](crate::objects::config::describe)): its fields, their doc comments
//! and an example value. A kind that is a whole module of its own (`sensor/netft`) keeps its
//! configuration there.

mod devices;
mod per_joint;
mod trajectory;

pub use per_joint::PerJoint;

pub use devices::{
    GalilConfig, RobotConfig, SensorConfig, ShapeConfig, SimBoardConfig, environment,
};

pub use trajectory::{
    GoalConfig, MAX_WAYPOINTS, RampConfig, SplineConfig, StepConfig, TrajectorySpec,
    TrapezoidalConfig, WaypointConfig, trajectory_spec,
};

use crate::objects::error::ObjectError;
use penelope_protocol::proto::Class;

use crate::objects::config::{KindConfig, LoopTiming, bad, check_int, check_range, loop_keys};

/// A kind: its name, `class/kind`. The kinds a creator makes, and what each does, are
/// registered in the registry's catalog; the names of the built-in kinds are constants here.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Kind(&'static str);

impl Kind {
    /// `robot/puma560`.
    pub const PUMA560: Kind = Kind("robot/puma560");
    /// `robot/puma200`.
    pub const PUMA200: Kind = Kind("robot/puma200");
    /// `robot/frhc`.
    pub const FRHC: Kind = Kind("robot/frhc");
    /// `robot/urdf`: any serial robot from a URDF file named in the configuration.
    pub const URDF: Kind = Kind("robot/urdf");
    /// `board/sim`.
    pub const SIM_BOARD: Kind = Kind("board/sim");
    /// `board/fpga`: a `board/sim` plant behind the FRHC's FPGA kinematics.
    pub const FPGA_BOARD: Kind = Kind("board/fpga");
    /// `board/galil`.
    pub const GALIL_BOARD: Kind = Kind("board/galil");
    /// `sensor/virtual`.
    pub const VIRTUAL_SENSOR: Kind = Kind("sensor/virtual");
    /// `sensor/operator-hand`.
    pub const OPERATOR_HAND: Kind = Kind("sensor/operator-hand");
    /// `sensor/replay`: a recorded wrench stream ([`replay`](crate::objects::replay)).
    pub const REPLAY_SENSOR: Kind = Kind("sensor/replay");
    /// `sensor/operator-replay`: the operator's hand played back from a recording.
    pub const OPERATOR_REPLAY: Kind = Kind("sensor/operator-replay");
    /// `controller/joint-pid`.
    pub const JOINT_PID: Kind = Kind("controller/joint-pid");
    /// `controller/cartesian-impedance`.
    pub const CARTESIAN_IMPEDANCE: Kind = Kind("controller/cartesian-impedance");
    /// `controller/joint-position`.
    pub const JOINT_POSITION: Kind = Kind("controller/joint-position");
    /// `controller/joint-groups`: other controllers, each on its own joints of one robot.
    pub const JOINT_GROUPS: Kind = Kind("controller/joint-groups");
    /// `controller/force-display`: the master half of position-forward / force-back.
    pub const FORCE_DISPLAY: Kind = Kind("controller/force-display");
    /// `controller/position-error-master`: the master half of position-error.
    pub const POSITION_ERROR_MASTER: Kind = Kind("controller/position-error-master");
    /// `controller/four-channel-master`: the master half of Lawrence's four channels.
    pub const FOUR_CHANNEL_MASTER: Kind = Kind("controller/four-channel-master");
    /// `controller/four-channel-slave`: the slave half of Lawrence's four channels.
    pub const FOUR_CHANNEL_SLAVE: Kind = Kind("controller/four-channel-slave");
    /// `controller/slave-tracking`: the slave half (computed torque to the mapped master pose).
    pub const SLAVE_TRACKING: Kind = Kind("controller/slave-tracking");
    /// `controller/slave-position`: the slave half for a board with its own servo.
    pub const SLAVE_POSITION: Kind = Kind("controller/slave-position");
    /// `controller/wave-master`: the master half of the wave-variable law.
    pub const WAVE_MASTER: Kind = Kind("controller/wave-master");
    /// `controller/wave-slave`: the slave half of the wave-variable law.
    pub const WAVE_SLAVE: Kind = Kind("controller/wave-slave");
    /// `trajectory/step`.
    pub const STEP: Kind = Kind("trajectory/step");
    /// `trajectory/ramp`.
    pub const RAMP: Kind = Kind("trajectory/ramp");
    /// `trajectory/trapezoidal`.
    pub const TRAPEZOIDAL: Kind = Kind("trajectory/trapezoidal");
    /// `trajectory/spline`.
    pub const SPLINE: Kind = Kind("trajectory/spline");
    /// `trajectory/teleop`: the channel between a master and a slave.
    pub const TELEOP: Kind = Kind("trajectory/teleop");

    /// The kind named `name` (`class/kind`); a kind's own module names it once, as a constant.
    pub const fn named(name: &'static str) -> Kind {
        Kind(name)
    }

    /// `class/kind`.
    pub const fn as_str(self) -> &'static str {
        self.0
    }

    /// Its class: the name's prefix.
    pub fn class(self) -> Class {
        self.0
            .split_once('/')
            .and_then(|(c, _)| Class::parse(c))
            .unwrap_or(Class::Creator)
    }

    /// The name after the class (`puma560` of `robot/puma560`).
    pub fn model(self) -> &'static str {
        self.0.split_once('/').map_or(self.0, |(_, m)| m)
    }
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
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, ObjectError> {
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
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, ObjectError> {
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
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, ObjectError> {
        self.max_velocity.check(kind, "max_velocity", 1e-3, 100.0)?;
        self.timing(kind)
    }
}

impl ImpedanceConfigToml {
    /// Checks ranges.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<LoopTiming, ObjectError> {
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
                matches!(c.check(k), Err(ObjectError::BadConfig { .. })),
                "{bad}"
            );
        }
        assert!(parse::<JointPositionConfig>(k, "kp = 1.0").is_err());
    }

    #[test]
    fn configs_refuse_unknown_keys_and_out_of_range_values() {
        assert!(matches!(
            parse::<SimBoardConfig>("board/sim", "axis = 3"),
            Err(ObjectError::BadConfig { .. })
        ));
        let c: SimBoardConfig = parse("board/sim", "axes = 9").unwrap();
        assert!(c.check("board/sim").is_err());
        assert!(trajectory_spec(Kind::RAMP, "duration_s = -1").is_err());
        assert!(trajectory_spec(Kind::RAMP, "duration_s = nan").is_err());
        assert!(trajectory_spec(Kind::STEP, "pose = \"home\"").is_err());
        assert!(trajectory_spec(Kind::SPLINE, "").is_ok());
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
