//! The configurations of robots, boards and sensors, and the environment a simulated tool or a
//! virtual sensor touches.

use super::per_joint::PerJoint;
use crate::objects::config::describe::KindConfig;
use crate::objects::config::{bad, check_int, check_range};
use nalgebra::{Unit, Vector3};
use penelope_drivers::sim::environment::{ContactModel, Environment, Shape};
use penelope_hal::{JointVector, MAX_AXES, NamedPose};
use penelope_protocol::proto::{CallError, WireError};
use penelope_rt_core::safety::TeleopRole;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

use penelope_drivers::model as models;
use penelope_hal::{Frame, Pose, Wrench};

/// One contact shape of an environment.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ShapeConfig {
    /// `plane` or `sphere` (required).
    pub kind: String,
    /// A point on the plane, or the sphere's centre, m (the robot's base frame).
    #[serde(default)]
    pub point: [f64; 3],
    /// A plane's normal into free space (normalised).
    #[serde(default = "up")]
    pub normal: [f64; 3],
    /// A sphere's radius, m, > 0.
    #[serde(default = "radius")]
    pub radius: f64,
    /// Contact stiffness, N/m, 0..=1e7.
    #[serde(default = "stiffness")]
    pub stiffness: f64,
    /// Contact damping, N·s/m, 0..=1e5.
    #[serde(default = "damping")]
    pub damping: f64,
}

impl ShapeConfig {
    /// A plane at the origin, normal up, as the key lists show one.
    fn example() -> Self {
        ShapeConfig {
            kind: "plane".into(),
            point: [0.0; 3],
            normal: up(),
            radius: radius(),
            stiffness: stiffness(),
            damping: damping(),
        }
    }
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
/// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig) for an unknown shape kind, a value out of range or too many shapes.
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
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RobotConfig {
    /// The named pose (nest, start, work) where a simulated body starts and where Galil
    /// encoders read zero (the arm is parked there at power-up).
    pub start: String,
    /// `master` (a hand controller: force and moment caps, zero force on a fault) or `slave`
    /// (holds its pose); without it: master for robot/frhc, else slave.
    pub role: Option<String>,
    /// A master's largest displayed force, N, > 0 (the FRHC's).
    pub max_force_n: f64,
    /// A master's largest displayed moment, N·m, > 0.
    pub max_moment_nm: f64,
    /// The URDF file (required), in one of the node's robot-file
    /// directories (`--robot-files`), by name or absolute path; a regular file, 4 MiB at most;
    /// read when the robot is created.
    #[schemars(extend("x-only-kinds" = [super::ROBOT_URDF]))]
    pub file: Option<String>,
    /// The link whose frame is the tool frame (without it: the single leaf
    /// link).
    #[schemars(extend("x-only-kinds" = [super::ROBOT_URDF]))]
    pub tip: Option<String>,
    /// The link whose frame is the robot's base frame (without it: the root
    /// link).
    #[schemars(extend("x-only-kinds" = [super::ROBOT_URDF]))]
    pub base: Option<String>,
    /// Named poses (nest, start, work, ...), rad (m for prismatic joints), one
    /// value per joint; without them: all at the zero configuration (mid-range for a joint
    /// whose limits exclude zero).
    #[schemars(extend("x-only-kinds" = [super::ROBOT_URDF]))]
    pub poses: BTreeMap<String, Vec<f64>>,
}

impl KindConfig for RobotConfig {
    fn example() -> Self {
        RobotConfig {
            role: Some("slave".into()),
            file: Some("arm.urdf".into()),
            tip: Some("tool0".into()),
            base: Some("base_link".into()),
            poses: BTreeMap::from([("start".into(), vec![0.0, 0.8, -3.1, 0.0, 0.8, 0.0])]),
            ..Self::default()
        }
    }
}

impl Default for RobotConfig {
    fn default() -> Self {
        RobotConfig {
            start: "start".into(),
            role: None,
            max_force_n: 10.0,
            max_moment_nm: 0.5,
            file: None,
            tip: None,
            base: None,
            poses: BTreeMap::new(),
        }
    }
}

impl RobotConfig {
    /// The model of `robot/<model>`: a built-in one by name, or for `urdf` the chain of the
    /// URDF file `file` from `base` to `tip`.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig) for a missing `file`, a URDF that does not make a model (the
    /// message names the element), or `file`, `tip` or `base` given to a built-in robot;
    /// [`CallError::UnknownKind`](penelope_protocol::proto::CallError::UnknownKind) for an unknown model.
    pub fn model(&self, kind: &str, model: &str) -> Result<models::SerialRobotModel, WireError> {
        self.model_with(kind, model, |file| {
            std::fs::read_to_string(file).map_err(|e| format!("{file}: {e}"))
        })
    }

    /// As [`model`](Self::model), a URDF file read only from `dirs`, a regular file of at most
    /// [`MAX_ROBOT_FILE`](crate::objects::files::MAX_ROBOT_FILE) bytes
    /// ([`read_confined`](crate::objects::files::read_confined)): what a node does with the
    /// `file` a client names.
    ///
    /// # Errors
    /// As [`model`](Self::model); a file outside `dirs`, not regular or too large is
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig).
    pub fn model_in(
        &self,
        kind: &str,
        model: &str,
        dirs: &[std::path::PathBuf],
    ) -> Result<models::SerialRobotModel, WireError> {
        self.model_with(kind, model, |file| {
            crate::objects::files::read_confined(dirs, file).map_err(|e| e.to_string())
        })
    }

    fn model_with(
        &self,
        kind: &str,
        model: &str,
        read: impl FnOnce(&str) -> Result<String, String>,
    ) -> Result<models::SerialRobotModel, WireError> {
        if model != "urdf" {
            if self.file.is_some() || self.tip.is_some() || self.base.is_some() {
                return Err(bad(
                    kind,
                    "`file`, `tip` and `base` apply to robot/urdf only",
                ));
            }
            return models::by_name(model)
                .ok_or_else(|| WireError::Call(CallError::UnknownKind(kind.into())));
        }
        let Some(file) = &self.file else {
            return Err(bad(kind, "`file` (the URDF file) is required"));
        };
        let chain = models::UrdfChain {
            base: self.base.clone(),
            tip: self.tip.clone(),
        };
        let text = read(file).map_err(|e| bad(kind, e))?;
        let mut spec =
            models::urdf::spec_from_str(&text, &chain).map_err(|e| bad(kind, e.to_string()))?;
        let n = spec.joints.len();
        for (name, q) in &self.poses {
            if q.len() != n || !q.iter().all(|x| x.is_finite()) {
                return Err(bad(
                    kind,
                    format!("pose `{name}` needs {n} finite values (one per joint)"),
                ));
            }
            let q = JointVector::from_fn(|j, _| q.get(j).copied().unwrap_or(0.0));
            match spec.poses.iter_mut().find(|(p, _)| p == name) {
                Some((_, old)) => *old = q,
                None => spec.poses.push((name.clone(), q)),
            }
        }
        models::SerialRobotModel::new("urdf", spec).map_err(|e| bad(kind, e.to_string()))
    }

    /// The robot's role, defaulting by model (`frhc` is a master), and its checked caps.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig) for a word other than master or slave, or caps that are not
    /// positive.
    pub fn role(&self, kind: &str) -> Result<TeleopRole, WireError> {
        for (key, v) in [
            ("max_force_n", self.max_force_n),
            ("max_moment_nm", self.max_moment_nm),
        ] {
            if v.is_nan() || v <= 0.0 {
                return Err(bad(kind, format!("`{key}` must be > 0 (inf: no cap)")));
            }
        }
        match self.role.as_deref() {
            None if kind == super::ROBOT_FRHC => Ok(TeleopRole::Master),
            None | Some("slave") => Ok(TeleopRole::Slave),
            Some("master") => Ok(TeleopRole::Master),
            Some(other) => Err(bad(
                kind,
                format!("`role` = {other:?} is not \"master\" or \"slave\""),
            )),
        }
    }

    /// The start pose.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig) for a name other than nest, start, work.
    pub fn start_pose(&self, kind: &str) -> Result<NamedPose, WireError> {
        NamedPose::parse(&self.start).ok_or_else(|| {
            bad(
                kind,
                format!("`start` = {:?} is not nest, start or work", self.start),
            )
        })
    }
}

/// `board/sim` configuration, and the plant behind a `board/fpga`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SimBoardConfig {
    /// Number of axes, 1..=8.
    pub axes: u32,
    /// DAC resolution, bits, 8..=24.
    pub dac_bits: u32,
    /// Plant integration sub-step, µs, 20..=2000.
    pub substep_us: u64,
    /// Joint friction of the model in the plant.
    pub friction: bool,
    /// With torque on, no new command from the control tick for this long turns every axis off
    /// (the board's own check; the plant keeps moving), ms, 40..=10000 (0: off).
    pub command_timeout_ms: u64,
    /// Power-off holding brakes: the joints stand while the amplifiers are off (without, an arm
    /// whose amplifiers are off falls under gravity).
    pub brake: bool,
    /// The environment the plant's tool touches: up to 8 contact shapes, in the robot's base
    /// frame (none by default).
    pub shapes: Vec<ShapeConfig>,
}

impl KindConfig for SimBoardConfig {
    fn example() -> Self {
        SimBoardConfig {
            shapes: vec![ShapeConfig::example()],
            ..Self::default()
        }
    }
}

impl Default for SimBoardConfig {
    fn default() -> Self {
        SimBoardConfig {
            axes: 6,
            dac_bits: 16,
            substep_us: 200,
            friction: true,
            command_timeout_ms: penelope_drivers::sim::board::DEFAULT_COMMAND_TIMEOUT.as_millis()
                as u64,
            brake: false,
            shapes: Vec::new(),
        }
    }
}

impl SimBoardConfig {
    /// Checks ranges.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig).
    pub fn check(&self, kind: &str) -> Result<Environment, WireError> {
        check_int(kind, "axes", self.axes.into(), 1, MAX_AXES as u64)?;
        check_int(kind, "dac_bits", self.dac_bits.into(), 8, 24)?;
        check_int(kind, "substep_us", self.substep_us, 20, 2000)?;
        check_command_timeout(kind, self.command_timeout_ms)?;
        environment(kind, &self.shapes)
    }
}

/// The shortest command timeout a board accepts, ms: twice the longest control period
/// (`period_us` at most 20 ms), so that no loop's commands can look stale between its ticks.
pub const MIN_COMMAND_TIMEOUT_MS: u64 = 40;

/// Checks a board's `command_timeout_ms`: 0 (off), or from [`MIN_COMMAND_TIMEOUT_MS`] (two of the
/// longest control period, so that no loop's commands can look stale) to 10 s.
fn check_command_timeout(kind: &str, ms: u64) -> Result<(), WireError> {
    if ms == 0 {
        return Ok(());
    }
    check_int(
        kind,
        "command_timeout_ms",
        ms,
        MIN_COMMAND_TIMEOUT_MS,
        10_000,
    )
}

/// `board/galil` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct GalilConfig {
    /// The serial device; or else `address` (one of the two is required).
    pub device: Option<String>,
    /// The TCP address (host:port) of a DMC or of `penelope galil-sim`; or else `device`.
    pub address: Option<String>,
    /// Serial baud rate, 1200..=921600.
    pub baud: u32,
    /// Axes driven, 1..=8.
    pub axes: u32,
    /// Amplifier scaling, V per N·m of joint torque: one value or one per axis (|v| <= 10); the
    /// sign per joint comes from the robot's gear and encoder (negative flips a reversed
    /// amplifier).
    pub volts_per_newton_metre: PerJoint,
    /// TCP connect timeout, ms, 10..=60000.
    pub connect_timeout_ms: u64,
    /// The DMC turns its motors off when no exchange reached it for this long, ms, 5..=1000
    /// (0: no watchdog).
    pub watchdog_ms: u64,
    /// With torque on, no new command from the control tick for this long: OF 0, MO, heartbeat
    /// stopped, ms, 40..=10000 (0: off).
    pub command_timeout_ms: u64,
}

impl KindConfig for GalilConfig {
    fn example() -> Self {
        GalilConfig {
            device: Some("/dev/ttyUSB0".into()),
            address: Some("127.0.0.1:7400".into()),
            ..Self::default()
        }
    }
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
            command_timeout_ms: penelope_drivers::galil::DEFAULT_COMMAND_TIMEOUT.as_millis() as u64,
        }
    }
}

impl GalilConfig {
    /// Checks ranges and that exactly one of `device` and `address` is given.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig).
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
        check_command_timeout(kind, self.command_timeout_ms)?;
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
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SensorConfig {
    /// Plant mode: the robot whose simulated body's contact (its board's shapes, or the
    /// operator's hand) the sensor reads at the wrist, as a real sensor would; without it
    /// (probe mode), the `shapes` are probed at the reader's tool.
    pub robot: Option<String>,
    /// The sensor frame's origin in the tool frame, m, each -2..=2.
    pub mount_xyz: [f64; 3],
    /// Constant offset, N then N·m (sensor frame).
    pub bias: [f64; 6],
    /// Noise standard deviation per force axis, N, 0..=100.
    pub force_noise: f64,
    /// Noise standard deviation per torque axis, N·m, 0..=10.
    pub torque_noise: f64,
    /// First-order low-pass, Hz, 0 (off) or 0.1..=10000.
    pub cutoff_hz: f64,
    /// Noise seed (`penelope demo --seed` sets it).
    pub seed: u64,
    /// Probe mode only: the environment (up to 8 contact shapes, base frame) whose wrench on
    /// the probe (N, N·m, base frame, about the probe point), minus the bias, the sensor reads;
    /// empty space by default.
    pub shapes: Vec<ShapeConfig>,
    /// Probe mode only: publish on the data plane for controllers on other nodes (read over
    /// UDP, the same samples for every reader), host:port (an IP address; port 0: any free
    /// port); without it, such a controller is refused at activation.
    pub publish: Option<String>,
    /// Measure and send every this many ms, 1..=1000.
    pub publish_period_ms: u64,
}

impl KindConfig for SensorConfig {
    fn example() -> Self {
        SensorConfig {
            robot: Some("puma".into()),
            shapes: vec![ShapeConfig::example()],
            publish: Some("127.0.0.1:7420".into()),
            ..Self::default()
        }
    }
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            robot: None,
            mount_xyz: [0.0; 3],
            bias: [0.0; 6],
            force_noise: 0.0,
            torque_noise: 0.0,
            cutoff_hz: 0.0,
            seed: 1,
            shapes: Vec::new(),
            publish: None,
            publish_period_ms: 1,
        }
    }
}

impl SensorConfig {
    /// Checks ranges; a sensor reading a robot's plant has no shapes of its own (the plant's
    /// environment is its board's).
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig) naming the key.
    pub fn check(&self, kind: &str) -> Result<(), WireError> {
        for x in &self.mount_xyz {
            check_range(kind, "mount_xyz", *x, -2.0, 2.0)?;
        }
        for x in &self.bias {
            check_range(kind, "bias", *x, -1e4, 1e4)?;
        }
        check_range(kind, "force_noise", self.force_noise, 0.0, 100.0)?;
        check_range(kind, "torque_noise", self.torque_noise, 0.0, 10.0)?;
        if self.cutoff_hz != 0.0 {
            check_range(kind, "cutoff_hz", self.cutoff_hz, 0.1, 1e4)?;
        }
        if self.robot.is_some() && !self.shapes.is_empty() {
            return Err(bad(
                kind,
                "a sensor reading a robot's plant (`robot`) meets that plant's environment: put \
                 the `shapes` on the robot's simulated board",
            ));
        }
        if let Some(r) = &self.robot {
            penelope_protocol::proto::check_name(r)
                .map_err(|e| bad(kind, format!("robot: {e}")))?;
        }
        check_int(kind, "publish_period_ms", self.publish_period_ms, 1, 1000)?;
        if self.publish.is_some() && self.robot.is_some() {
            return Err(bad(
                kind,
                "`publish` serves a probe-mode sensor; a sensor reading a robot's plant \
                 (`robot`) is read inside that robot's loop",
            ));
        }
        self.publish_address(kind)?;
        Ok(())
    }

    /// The address of `publish`, if set.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig) for one that is not `host:port` with an IP address.
    pub fn publish_address(&self, kind: &str) -> Result<Option<std::net::SocketAddr>, WireError> {
        self.publish
            .as_deref()
            .map(|v| {
                v.parse().map_err(|e| {
                    bad(
                        kind,
                        format!("`publish` = {v:?}: {e} (host:port, an IP address)"),
                    )
                })
            })
            .transpose()
    }

    /// The driver's sensor settings (plant mode).
    pub fn plant_sensor(&self) -> penelope_drivers::sim::force_sensor::ForceSensorConfig {
        let [fx, fy, fz, tx, ty, tz] = self.bias;
        penelope_drivers::sim::force_sensor::ForceSensorConfig {
            mount: Pose::translation(self.mount_xyz[0], self.mount_xyz[1], self.mount_xyz[2]),
            bias: Wrench {
                force: Vector3::new(fx, fy, fz),
                torque: Vector3::new(tx, ty, tz),
                frame: Frame::Sensor,
            },
            force_noise: self.force_noise,
            torque_noise: self.torque_noise,
            cutoff_hz: self.cutoff_hz,
            seed: self.seed,
        }
    }
}

/// `sensor/netft` configuration: an ATI Net F/T box streaming RDT over UDP.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct NetFtSensorConfig {
    /// The box's RDT address (required), ip:port or an IP alone for port 49152;
    /// `penelope netft-sim` prints its own.
    pub address: String,
    /// Counts per N, the box's cfgcpf (its /netftapi2.xml), > 0.
    pub counts_per_force: f64,
    /// Counts per N·m, the box's cfgcpt, > 0.
    pub counts_per_torque: f64,
    /// The sensor frame's origin in the tool frame, m, each -2..=2.
    pub mount_xyz: [f64; 3],
    /// The sensor frame's orientation in the tool frame (roll, pitch, yaw), degrees.
    pub mount_rpy_deg: [f64; 3],
    /// A reading older than this is refused (the loop uses no wrench), ms, 1..=10000. Status
    /// bit 31 (error), saturation (bits 30, 27), a silence past the timeout or a loss burst:
    /// the loop notes a sensor error and uses no wrench, so a master displays zero force.
    pub timeout_ms: u64,
    /// More records lost in one gap than this is a fault (held for timeout_ms).
    pub max_gap: u32,
    /// Ask the box for a software bias when configured (`ctl call NAME bias` any time).
    pub bias_on_start: bool,
}

impl KindConfig for NetFtSensorConfig {
    fn example() -> Self {
        NetFtSensorConfig {
            address: "192.168.1.1:49152".into(),
            ..Self::default()
        }
    }
}

impl Default for NetFtSensorConfig {
    fn default() -> Self {
        NetFtSensorConfig {
            address: String::new(),
            counts_per_force: 1_000_000.0,
            counts_per_torque: 1_000_000.0,
            mount_xyz: [0.0; 3],
            mount_rpy_deg: [0.0; 3],
            timeout_ms: 20,
            max_gap: 4,
            bias_on_start: false,
        }
    }
}

impl NetFtSensorConfig {
    /// Checks ranges and the address, and gives the driver's settings.
    ///
    /// # Errors
    /// [`CallError::BadConfig`](penelope_protocol::proto::CallError::BadConfig) naming the key.
    pub fn check(&self, kind: &str) -> Result<penelope_drivers::netft::NetFtConfig, WireError> {
        let address = penelope_drivers::netft::parse_address(&self.address)
            .map_err(|e| bad(kind, format!("`address`: {e}")))?;
        check_range(kind, "counts_per_force", self.counts_per_force, 1e-3, 1e12)?;
        check_range(
            kind,
            "counts_per_torque",
            self.counts_per_torque,
            1e-3,
            1e12,
        )?;
        for x in &self.mount_xyz {
            check_range(kind, "mount_xyz", *x, -2.0, 2.0)?;
        }
        for x in &self.mount_rpy_deg {
            check_range(kind, "mount_rpy_deg", *x, -360.0, 360.0)?;
        }
        check_int(kind, "timeout_ms", self.timeout_ms, 1, 10_000)?;
        check_int(kind, "max_gap", self.max_gap.into(), 0, 1_000_000)?;
        let mut c = penelope_drivers::netft::NetFtConfig::new(address);
        c.calibration = penelope_drivers::netft::Calibration {
            counts_per_force: self.counts_per_force,
            counts_per_torque: self.counts_per_torque,
        };
        c.mount = self.mount();
        c.timeout = std::time::Duration::from_millis(self.timeout_ms);
        c.max_gap = self.max_gap;
        c.bias_on_start = self.bias_on_start;
        Ok(c)
    }

    /// The sensor frame's pose in the tool frame.
    pub fn mount(&self) -> Pose {
        let [r, p, y] = self.mount_rpy_deg.map(f64::to_radians);
        Pose::from_parts(
            nalgebra::Translation3::new(self.mount_xyz[0], self.mount_xyz[1], self.mount_xyz[2]),
            nalgebra::UnitQuaternion::from_euler_angles(r, p, y),
        )
    }
}

#[cfg(test)]
mod command_timeout_tests {
    use super::*;

    #[test]
    fn command_timeouts_are_off_or_at_least_two_of_the_longest_period() {
        let sim = |ms| SimBoardConfig {
            command_timeout_ms: ms,
            ..SimBoardConfig::default()
        };
        assert_eq!(SimBoardConfig::default().command_timeout_ms, 50);
        assert!(sim(0).check("board/sim").is_ok());
        assert!(sim(40).check("board/sim").is_ok());
        let e = sim(39).check("board/sim").unwrap_err();
        assert!(e.to_string().contains("command_timeout_ms"), "{e}");
        let galil = |ms| GalilConfig {
            device: Some("/dev/ttyUSB0".into()),
            command_timeout_ms: ms,
            ..GalilConfig::default()
        };
        assert_eq!(GalilConfig::default().command_timeout_ms, 50);
        assert!(galil(0).check("board/galil").is_ok());
        assert!(galil(10).check("board/galil").is_err());
        assert!(galil(10_001).check("board/galil").is_err());
    }
}
