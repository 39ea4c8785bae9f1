//! The lab configuration file (TOML): robots, boards, sensors, the environment, controllers,
//! trajectories and their bindings, by name.
//!
//! The shipped example, `config/demo.toml`, is the demo's setup; [`LabConfig::demo`] returns it.
//! Unknown keys are rejected (a typo is an error, not a silently ignored setting).

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

/// The demo's lab, as shipped in `config/demo.toml`.
pub const DEMO_TOML: &str = include_str!("../../../config/demo.toml");

/// Why a lab configuration could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The TOML is malformed or has unknown or missing keys.
    #[error("invalid lab configuration: {0}")]
    Parse(#[from] toml::de::Error),
    /// A binding names an object that does not exist, or a value is out of range.
    #[error("invalid lab configuration: {0}")]
    Invalid(String),
}

/// A whole lab.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LabConfig {
    /// The lab's name.
    pub name: String,
    /// Loop periods and the watchdog.
    pub timing: TimingConfig,
    /// Robots by name.
    pub robots: BTreeMap<String, RobotConfig>,
    /// Boards by name.
    pub boards: BTreeMap<String, BoardConfig>,
    /// Sensors by name.
    #[serde(default)]
    pub sensors: BTreeMap<String, SensorConfig>,
    /// What the slave touches.
    #[serde(default)]
    pub environment: EnvironmentConfig,
    /// Controllers by name.
    pub controllers: BTreeMap<String, ControllerConfig>,
    /// Trajectories by name.
    pub trajectories: BTreeMap<String, TrajectoryConfig>,
    /// The teleoperation coupling.
    pub teleop: TeleopConfig,
    /// The virtual operator holding the master (simulation only).
    pub operator: OperatorConfig,
}

/// Loop periods and the watchdog.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimingConfig {
    /// Control period T_ctrl, microseconds.
    pub control_period_us: u64,
    /// Communication period T_com, microseconds.
    pub comm_period_us: u64,
    /// Reference freshness limit, milliseconds.
    pub watchdog_ms: u64,
}

/// What a robot is in a teleoperation pair.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Role {
    /// The operator's device.
    Master,
    /// The remote arm.
    Slave,
}

/// Which implementation computes the forward kinematics.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
pub enum KinematicsChoice {
    /// The f64 model.
    #[default]
    Float,
    /// The bit-exact fixed-point model of the FPGA (FRHC).
    Fpga,
}

/// One robot.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    /// A built-in model name (`puma560`, `puma200`, `frhc`) or a path to a DH file.
    pub model: String,
    /// Float or FPGA kinematics.
    #[serde(default)]
    pub kinematics: KinematicsChoice,
    /// The named pose it starts in (`nest`, `start`, `work`).
    pub start: String,
    /// Master or slave.
    pub role: Role,
}

/// Which kind of board.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum BoardKind {
    /// A simulated board in front of a simulated plant.
    Sim,
    /// A Galil DMC over a serial line.
    Galil,
}

/// One board.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardConfig {
    /// Simulated or Galil.
    pub kind: BoardKind,
    /// The robot whose joints it drives.
    pub robot: String,
    /// Axis of each joint (`axes[j]` drives joint `j`); default: joint j on axis j.
    #[serde(default)]
    pub axes: Option<Vec<u8>>,
    /// DAC resolution of a simulated board, bits.
    #[serde(default = "default_dac_bits")]
    pub dac_bits: u32,
    /// Serial port of a Galil board.
    #[serde(default)]
    pub port: Option<String>,
    /// Baud rate of a Galil board.
    #[serde(default = "default_baud")]
    pub baud: u32,
}

fn default_dac_bits() -> u32 {
    16
}

fn default_baud() -> u32 {
    115_200
}

/// Which kind of sensor.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum SensorKind {
    /// A virtual wrist force sensor reading the simulated plant's contact wrench.
    Virtual,
}

/// One sensor.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    /// The kind.
    pub kind: SensorKind,
    /// The robot it is mounted on.
    pub robot: String,
    /// Low-pass cut-off, Hz.
    #[serde(default = "default_cutoff")]
    pub cutoff_hz: f64,
    /// Force noise per axis (standard deviation), N.
    #[serde(default)]
    pub force_noise_n: f64,
    /// Torque noise per axis (standard deviation), N·m.
    #[serde(default)]
    pub torque_noise_nm: f64,
    /// Sensor origin in the tool frame, m.
    #[serde(default)]
    pub mount_xyz_m: [f64; 3],
}

fn default_cutoff() -> f64 {
    30.0
}

/// The slave's surroundings.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentConfig {
    /// Shapes, placed relative to the slave's tool position at the start (base frame).
    #[serde(default)]
    pub shapes: Vec<ShapeConfig>,
}

/// A shape's geometry.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum ShapeKind {
    /// A plane (a wall or a table).
    Plane,
    /// A sphere.
    Sphere,
}

/// One shape.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeConfig {
    /// Plane or sphere.
    pub kind: ShapeKind,
    /// A point on the plane, or the sphere's centre, m (relative to the slave's start tool point).
    pub point_m: [f64; 3],
    /// The plane's normal, pointing into free space (planes only).
    #[serde(default)]
    pub normal: Option<[f64; 3]>,
    /// The sphere's radius, m (spheres only).
    #[serde(default)]
    pub radius_m: Option<f64>,
    /// Contact stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Contact damping, N·s/m.
    #[serde(default)]
    pub damping_ns_per_m: f64,
}

/// Which control law a controller runs.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum ControllerKind {
    /// Master half of position-forward / force-back: displays the mapped sensor wrench.
    ForceDisplay,
    /// Master half of position-error (position-position): a spring to the mapped slave pose.
    PositionErrorMaster,
    /// Slave half: follows the mapped master pose (inverse kinematics + computed torque).
    SlaveTracking,
    /// Slave half for a board with its own servo behind a slow link (a Galil DMC on a serial
    /// line): inverse kinematics, joint positions sent as the board's targets.
    SlavePosition,
    /// Cartesian impedance toward the reference pose.
    CartesianImpedance,
    /// Joint PID with gravity compensation.
    JointPid,
}

/// One controller and its bindings.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerConfig {
    /// The law.
    pub kind: ControllerKind,
    /// The robot it drives (`set_robot`).
    pub robot: String,
    /// The trajectory it follows (`set_trajectory`).
    pub trajectory: String,
    /// The force sensor it reads (`set_sensor`), if any.
    #[serde(default)]
    pub sensor: Option<String>,
}

/// Which kind of trajectory.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum TrajectoryKind {
    /// The teleoperation channel from another robot.
    Teleop,
}

/// One trajectory.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryConfig {
    /// The kind.
    pub kind: TrajectoryKind,
    /// For a teleop channel: the robot on the other side.
    #[serde(default)]
    pub from: Option<String>,
}

/// A bilateral control law.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Law {
    /// Position forward, force back (kinesthetic force feedback).
    ForcePosition,
    /// Position-error (position-position).
    PositionError,
}

impl Law {
    /// The name used in files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Law::ForcePosition => "force-position",
            Law::PositionError => "position-error",
        }
    }
}

/// The teleoperation coupling.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TeleopConfig {
    /// The law in use.
    pub law: Law,
    /// Position scale, slave motion per master motion.
    pub scale: f64,
    /// Displayed force per mapped sensor force.
    pub force_gain: f64,
    /// Rotation from the master's base frame to the slave's, roll-pitch-yaw, degrees.
    #[serde(default)]
    pub rotation_rpy_deg: [f64; 3],
}

/// The virtual operator.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatorConfig {
    /// The script's name (`demo`).
    pub script: String,
    /// Hand stiffness, N/m.
    pub hand_stiffness_n_per_m: f64,
    /// Hand damping, N·s/m.
    pub hand_damping_ns_per_m: f64,
}

impl LabConfig {
    /// Parses and checks a configuration.
    ///
    /// # Errors
    /// [`ConfigError::Parse`] for malformed TOML or unknown keys, [`ConfigError::Invalid`] for a
    /// binding to a missing object or an out-of-range value.
    pub fn from_toml(text: &str) -> Result<Self, ConfigError> {
        let config: LabConfig = toml::from_str(text)?;
        config.check()?;
        Ok(config)
    }

    /// Reads, parses and checks a configuration file.
    ///
    /// # Errors
    /// As [`from_toml`](Self::from_toml), plus [`ConfigError::Io`].
    pub fn from_file(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml(&text)
    }

    /// The demo's lab (`config/demo.toml`).
    pub fn demo() -> Self {
        // The shipped file is checked by a unit test; failing here would be a build defect.
        Self::from_toml(DEMO_TOML).unwrap_or_else(|e| panic!("config/demo.toml is invalid: {e}"))
    }

    /// The robot with `role`, by name.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] unless exactly one robot has that role.
    pub fn robot_with_role(&self, role: Role) -> Result<(&str, &RobotConfig), ConfigError> {
        let mut found = self.robots.iter().filter(|(_, r)| r.role == role);
        match (found.next(), found.next()) {
            (Some((name, robot)), None) => Ok((name.as_str(), robot)),
            _ => Err(ConfigError::Invalid(format!(
                "exactly one robot must have role {role:?}"
            ))),
        }
    }

    /// The board driving `robot`.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] unless exactly one board names it.
    pub fn board_of(&self, robot: &str) -> Result<(&str, &BoardConfig), ConfigError> {
        let mut found = self.boards.iter().filter(|(_, b)| b.robot == robot);
        match (found.next(), found.next()) {
            (Some((name, board)), None) => Ok((name.as_str(), board)),
            _ => Err(ConfigError::Invalid(format!(
                "exactly one board must drive robot `{robot}`"
            ))),
        }
    }

    /// The controllers bound to `robot`, in file order (sorted by name).
    pub fn controllers_of<'a>(
        &'a self,
        robot: &'a str,
    ) -> impl Iterator<Item = (&'a str, &'a ControllerConfig)> + 'a {
        self.controllers
            .iter()
            .filter(move |(_, c)| c.robot == robot)
            .map(|(n, c)| (n.as_str(), c))
    }

    fn check(&self) -> Result<(), ConfigError> {
        let invalid = |m: String| Err(ConfigError::Invalid(m));
        if self.timing.control_period_us == 0 || self.timing.comm_period_us == 0 {
            return invalid("loop periods must be positive".into());
        }
        for (name, board) in &self.boards {
            if !self.robots.contains_key(&board.robot) {
                return invalid(format!(
                    "board `{name}` drives unknown robot `{}`",
                    board.robot
                ));
            }
            if board.kind == BoardKind::Galil && board.port.is_none() {
                return invalid(format!("galil board `{name}` needs `port`"));
            }
        }
        for (name, sensor) in &self.sensors {
            if !self.robots.contains_key(&sensor.robot) {
                return invalid(format!(
                    "sensor `{name}` is on unknown robot `{}`",
                    sensor.robot
                ));
            }
        }
        for (name, c) in &self.controllers {
            if !self.robots.contains_key(&c.robot) {
                return invalid(format!(
                    "controller `{name}` drives unknown robot `{}`",
                    c.robot
                ));
            }
            if !self.trajectories.contains_key(&c.trajectory) {
                return invalid(format!(
                    "controller `{name}` follows unknown trajectory `{}`",
                    c.trajectory
                ));
            }
            if let Some(s) = &c.sensor
                && !self.sensors.contains_key(s)
            {
                return invalid(format!("controller `{name}` reads unknown sensor `{s}`"));
            }
        }
        for (name, t) in &self.trajectories {
            if let Some(from) = &t.from
                && !self.robots.contains_key(from)
            {
                return invalid(format!(
                    "trajectory `{name}` comes from unknown robot `{from}`"
                ));
            }
        }
        for shape in &self.environment.shapes {
            let ok = match shape.kind {
                ShapeKind::Plane => shape.normal.is_some_and(|n| n.iter().any(|x| *x != 0.0)),
                ShapeKind::Sphere => shape.radius_m.is_some_and(|r| r > 0.0),
            };
            if !ok || shape.stiffness_n_per_m <= 0.0 {
                return invalid("a plane needs a non-zero normal, a sphere a positive radius, both a positive stiffness".into());
            }
        }
        if !(self.teleop.scale > 0.0 && self.teleop.force_gain >= 0.0) {
            return invalid("teleop scale must be positive and force_gain non-negative".into());
        }
        self.robot_with_role(Role::Master)?;
        self.robot_with_role(Role::Slave)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_demo_configuration_is_valid() {
        let lab = LabConfig::from_toml(DEMO_TOML).unwrap();
        assert_eq!(lab.robot_with_role(Role::Master).unwrap().0, "frhc");
        assert_eq!(lab.board_of("puma").unwrap().1.kind, BoardKind::Sim);
        assert_eq!(lab.controllers_of("frhc").count(), 2);
    }

    #[test]
    fn typos_and_dangling_bindings_are_errors() {
        let typo = DEMO_TOML.replace("force_gain", "forse_gain");
        assert!(matches!(
            LabConfig::from_toml(&typo),
            Err(ConfigError::Parse(_))
        ));
        let dangling = DEMO_TOML.replace("sensor = \"wrist\"", "sensor = \"elbow\"");
        assert!(matches!(
            LabConfig::from_toml(&dangling),
            Err(ConfigError::Invalid(_))
        ));
        let galil = DEMO_TOML.replace(
            "kind = \"sim\"                 # \"galil\"",
            "kind = \"galil\" #",
        );
        assert!(
            matches!(LabConfig::from_toml(&galil), Err(ConfigError::Invalid(m)) if m.contains("port"))
        );
    }
}
