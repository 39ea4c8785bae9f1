//! The objects of a node, their relations and lifecycles, and every method they answer. Lives
//! behind the creator's mutex: the non-real-time side only.
//!
//! - here: the objects (one body per class), making them from their configuration, and the
//!   lifecycle transitions (configure, cleanup);
//! - [`build`]: a controller's loop from its objects, and a stopped loop taken back;
//! - [`methods`]: every method an object answers, by class;
//! - [`sensors`]: a sensor's publisher on the data plane;
//! - [`trajectories`]: trajectories from their specifications.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::objects::teleop_passivity::PortLaw;
use nalgebra::Vector3;
use penelope_drivers::galil::GalilBoard;
use penelope_drivers::model::SerialRobotModel;
use penelope_drivers::sim::board::{SimBoard, SimBoardConfig as DriverSimConfig};
use penelope_drivers::sim::plant::PlantConfig;
use penelope_hal::{
    JointVector, Kinematics, LifecycleState, MAX_JOINTS, NamedPose, RobotModel, Timestamp,
    Transition,
};
use penelope_rt_core::safety::TeleopRole;
use penelope_rt_core::teleop::ImpedanceConfig;

use super::config::LoopTiming;
use super::kinds::{
    self, GalilConfig, GoalConfig, ImpedanceConfigToml, JointPidConfig, JointPositionConfig, Kind,
    SensorConfig, SimBoardConfig, TrajectorySpec,
};
use super::kinematics::RobotKinematics;
use super::teleop::{
    ForceDisplayToml, FourChannelSlaveToml, FourChannelToml, HandObj, PositionErrorToml, Side,
    SlaveTrackingToml, TeleopConfig, TeleopLink,
};
use super::teleop_wave::{WaveMasterToml, WaveSlaveToml};
use crate::dataplane::frame::DatagramKey;
use crate::dataplane::sensor_stream::SensorPublisher;
use crate::objects::error::ObjectError;
use crate::objects::runtime::{SimBody, VirtualSensor};
use penelope_protocol::proto::{Class, JointAxis, ObjectInfo};

mod build;
pub(crate) mod camera;
pub mod catalog;
mod controller_methods;
mod crtk_methods;
mod fpga;
mod galil;
mod groups;
mod kind_entry;
mod laws;
mod loop_sensor;
mod makers;
mod methods;
pub mod netft;
mod replay;
mod scene_robots;
mod sensors;
mod take_back;
mod teleop;
mod test_signal;
mod trajectories;

pub(crate) use build::Built;
use galil::open_galil;
use sensors::publisher_relations;
use teleop::link_relations;

/// One object.
pub(crate) struct Object {
    pub name: String,
    pub kind: Kind,
    pub state: LifecycleState,
    /// Active controllers using this object (it shows `active` while there is one).
    pub users: BTreeSet<String>,
    pub body: KindState,
}

// One per object, in a map: the size difference costs nothing worth a box.
#[allow(clippy::large_enum_variant)]
pub(crate) enum KindState {
    Robot(Box<RobotObj>),
    SimBoard(SimBoardObj),
    Galil(GalilObj),
    Sensor(SensorObj),
    Controller(Box<ControllerObj>),
    Trajectory(TrajectoryObj),
    Hand(Box<HandObj>),
    Teleop(Box<TeleopObj>),
    ReplaySensor(Box<crate::objects::replay::ReplaySensorObj>),
    /// A sensor kind read in the control loop's own thread ([`loop_sensor`]).
    LoopSensor(Box<dyn loop_sensor::LoopSensorObject>),
    OperatorReplay(Box<crate::objects::replay::OperatorReplayObj>),
    /// A `sensor/sim-camera` ([`camera`]).
    Camera(Box<camera::CameraObj>),
}

/// A `trajectory/teleop`: its settings, and its cells once configured.
pub(crate) struct TeleopObj {
    pub config: TeleopConfig,
    pub link: Option<TeleopLink>,
}

pub(crate) struct RobotObj {
    /// The float model: dynamics, named poses, encoder scaling, and the simulated body.
    pub model: SerialRobotModel,
    /// What the robot's loops and kinematic methods compute with: the float model, or, once
    /// configured on a `board/fpga`, the board's.
    pub kinematics: RobotKinematics,
    /// Master or slave: what its loops' safety does.
    pub role: TeleopRole,
    /// A master's display caps, N and N·m.
    pub caps: (f64, f64),
    pub start: NamedPose,
    /// `(board, joints)` in the order given.
    pub maps: Vec<(String, Vec<JointAxis>)>,
    /// The simulated body (robots on simulated boards, configured, not running).
    pub body: Option<Box<SimBody>>,
    /// When it was made, in the process's creation order (robots stand side by side in a 3D
    /// scene in this order).
    pub created: u64,
}

/// The creation order of robots ([`RobotObj::created`]).
static ROBOTS_MADE: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

pub(crate) struct SimBoardObj {
    pub config: SimBoardConfig,
    /// A `board/fpga`: the FRHC's FPGA kinematics in front of the plant.
    pub fpga: bool,
}

pub(crate) struct GalilObj {
    pub config: GalilConfig,
    pub board: Option<GalilBoard>,
}

pub(crate) struct SensorObj {
    /// The probe model's state (probe mode).
    pub state: Arc<Mutex<VirtualSensor>>,
    pub config: SensorConfig,
    /// Its publisher on the data plane, while configured with `publish`.
    pub publisher: Option<SensorPublisher>,
}

#[derive(Clone)]
pub(crate) enum ControllerConfig {
    Pid(JointPidConfig),
    Impedance(ImpedanceConfigToml),
    Position(JointPositionConfig),
    /// Member controllers on joint subsets of one robot, run in one loop.
    Groups(kinds::JointGroupsConfig),
    ForceDisplay(ForceDisplayToml),
    PositionError(PositionErrorToml),
    /// The master half of Lawrence's four channels.
    FourChannel(FourChannelToml),
    /// The slave half: torques, or position targets for the board's servo (`true`).
    Tracking(SlaveTrackingToml, bool),
    /// The slave half of Lawrence's four channels.
    FourChannelSlave(FourChannelSlaveToml),
    /// The master half of the wave-variable law.
    WaveMaster(WaveMasterToml),
    /// The slave half of the wave-variable law.
    WaveSlave(WaveSlaveToml),
}

impl ControllerConfig {
    /// The side of a teleoperation channel the law runs, if it is a teleoperation law.
    pub fn teleop_side(&self) -> Option<Side> {
        match self {
            ControllerConfig::ForceDisplay(_)
            | ControllerConfig::PositionError(_)
            | ControllerConfig::FourChannel(_)
            | ControllerConfig::WaveMaster(_) => Some(Side::Master),
            ControllerConfig::Tracking(..)
            | ControllerConfig::FourChannelSlave(_)
            | ControllerConfig::WaveSlave(_) => Some(Side::Slave),
            _ => None,
        }
    }

    /// What a teleoperation half runs in its channel end, checked: the wave transform, the
    /// two-port passivity observer (and controller), or nothing more.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn port_law(&self, kind: &str) -> Result<PortLaw, ObjectError> {
        match self {
            ControllerConfig::WaveMaster(c) => c.wave(kind).map(PortLaw::Wave),
            ControllerConfig::WaveSlave(c) => c.wave(kind).map(PortLaw::Wave),
            ControllerConfig::ForceDisplay(c) => c.port_law(kind),
            ControllerConfig::Tracking(c, _) => c.port_law(kind),
            ControllerConfig::PositionError(_) | ControllerConfig::FourChannel(_) => {
                Ok(PortLaw::Observer)
            }
            ControllerConfig::FourChannelSlave(c) => c.port_law(kind),
            _ => Ok(PortLaw::Plain),
        }
    }
}

pub(crate) struct ControllerObj {
    pub config: ControllerConfig,
    /// The configuration's TOML text as created and changed by `set-gains` (what a merge of new
    /// keys starts from).
    pub config_text: String,
    pub timing: LoopTiming,
    pub robot: Option<String>,
    pub trajectory: Option<String>,
    pub sensor: Option<String>,
    pub running: Option<crate::objects::runtime::Running>,
    /// The newest sample of the last run.
    pub last: Option<penelope_rt_core::telemetry::TelemetrySample>,
    /// How the control thread is scheduled (shown in `describe`).
    pub scheduling: Option<String>,
    /// Why its loop failed (a thread panicked or died), until it is re-armed.
    pub fault: Option<String>,
}

pub(crate) struct TrajectoryObj {
    pub spec: TrajectorySpec,
}

fn bad_arg(m: impl Into<String>) -> ObjectError {
    ObjectError::BadArgument(m.into())
}

fn not_ready(m: impl Into<String>) -> ObjectError {
    ObjectError::NotReady(m.into())
}

fn unsupported(kind: Kind, method: &str) -> ObjectError {
    ObjectError::Unsupported {
        kind: kind.as_str().to_string(),
        method: method.to_string().into(),
    }
}

fn finite_effort(model: &SerialRobotModel, j: usize) -> f64 {
    let e = model.limits().effort_max[j];
    if e.is_finite() && e > 0.0 { e } else { 100.0 }
}

impl Object {
    /// The state shown to users.
    pub fn shown_state(&self) -> LifecycleState {
        if self.users.is_empty() || self.state == LifecycleState::Error {
            self.state
        } else {
            LifecycleState::Active
        }
    }

    /// What `list` and `describe` show; `bridged`: the node's channels fed from Zenoh (their
    /// counters are shown with them).
    pub fn info(&self, bridged: &crate::objects::bridged::BridgedChannels) -> ObjectInfo {
        let mut relations = Vec::new();
        match &self.body {
            KindState::Robot(r) => {
                for (b, joints) in &r.maps {
                    let list: Vec<String> = joints
                        .iter()
                        .map(|j| format!("{}:{}", j.joint, j.axis))
                        .collect();
                    relations.push(("board".to_string(), format!("{b} [{}]", list.join(" "))));
                }
                relations.push(("kinematics".to_string(), r.kinematics.describe().into()));
                if r.kinematics.is_fpga_board() {
                    relations.extend(crate::objects::fpga_board::describe());
                }
            }
            KindState::SimBoard(b) if b.fpga => {
                relations.push(("kinematics".to_string(), "frhc, bit-exact".into()));
                relations.extend(crate::objects::fpga_board::describe());
            }
            KindState::Hand(h) => relations.push(("robot".to_string(), h.config.robot.clone())),
            KindState::OperatorReplay(h) => {
                relations.push(("robot".to_string(), h.config.robot.clone()));
                relations.push(("recording".to_string(), h.config.file.clone()));
            }
            KindState::ReplaySensor(s) => {
                relations.push(("recording".to_string(), s.config.file.clone()))
            }
            KindState::Sensor(s) => relations.extend(publisher_relations(s)),
            KindState::LoopSensor(s) => relations.extend(s.relations()),
            KindState::Camera(c) => relations.extend(c.relations(&self.name)),
            KindState::Teleop(t) => {
                relations.push(("master".to_string(), t.config.master.clone()));
                relations.push(("slave".to_string(), t.config.slave.clone()));
                // The mapping, for clients that show the channel (the web page's panel).
                let c = &t.config;
                let [roll, pitch, yaw] = c.rotation_rpy_deg;
                relations.push((
                    "mapping".to_string(),
                    format!(
                        "scale {} force_gain {} torque_gain {} rotation_rpy_deg {roll} {pitch} {yaw}",
                        c.scale, c.force_gain, c.torque_gain
                    ),
                ));
                relations.extend(link_relations(&self.name, t, bridged));
            }
            KindState::Controller(c) => {
                for (k, v) in [
                    ("robot", &c.robot),
                    ("trajectory", &c.trajectory),
                    ("sensor", &c.sensor),
                ] {
                    if let Some(v) = v {
                        relations.push((k.to_string(), v.clone()));
                    }
                }
                if let ControllerConfig::Groups(g) = &c.config {
                    for group in &g.groups {
                        let joints: Vec<String> =
                            group.joints.iter().map(|j| j.to_string()).collect();
                        relations.push((
                            "member".to_string(),
                            format!("{} [{}]", group.controller, joints.join(" ")),
                        ));
                    }
                }
                if let Some(s) = &c.scheduling {
                    relations.push(("scheduling".to_string(), s.clone()));
                }
                if let Some(f) = &c.fault {
                    relations.push(("fault".to_string(), f.clone()));
                }
            }
            _ => {}
        }
        for u in &self.users {
            relations.push(("used-by".to_string(), u.clone()));
        }
        ObjectInfo {
            name: self.name.clone(),
            kind: self.kind.as_str().to_string(),
            class: self.kind.class(),
            state: self.shown_state(),
            relations,
        }
    }
}

/// Makes the object `name` of `kind` from its configuration text (checked by the kind's maker,
/// the one its catalog entry names). A `robot/urdf`'s file is read only from `robot_files`
/// ([`crate::objects::files`]).
pub(crate) fn make(
    kind: Kind,
    name: &str,
    config: &str,
    robot_files: &[std::path::PathBuf],
) -> Result<Object, ObjectError> {
    let entry = catalog::entry_named(kind.as_str())
        .ok_or_else(|| ObjectError::UnknownKind(kind.as_str().into()))?;
    let body = (entry.make)(&kind_entry::MakeArgs {
        kind,
        config,
        robot_files,
    })?;
    Ok(Object {
        name: name.to_string(),
        kind,
        state: LifecycleState::Unconfigured,
        users: BTreeSet::new(),
        body,
    })
}

fn controller_body(config: ControllerConfig, timing: LoopTiming, text: &str) -> KindState {
    KindState::Controller(Box::new(ControllerObj {
        config,
        config_text: text.to_string(),
        timing,
        robot: None,
        trajectory: None,
        sensor: None,
        running: None,
        last: None,
        scheduling: None,
        fault: None,
    }))
}

/// The objects of a node.
#[derive(Default)]
pub(crate) struct Registry {
    pub objects: BTreeMap<String, Object>,
    /// The key of this system's data-plane datagrams (from the nodes' secret), if it has one.
    pub datagram_key: Option<DatagramKey>,
    /// How the creator's loops are clocked (a channel to another node stamps real times on
    /// real time, tick times on a simulated clock).
    pub clock: crate::objects::clock::ClockMode,
    /// The channels whose master is an operator station behind the Zenoh bridge.
    pub bridged: crate::objects::bridged::BridgedChannels,
    /// What a camera's thread needs from the creator (set by the creator).
    pub camera_env: Option<camera::CameraEnv>,
}

/// What activating a controller needs from the creator.
pub(crate) struct Launch<'a> {
    pub rt: &'a crate::objects::RtPolicy,
    pub remote: Option<Arc<dyn penelope_protocol::service::Remote>>,
    /// Where the controller's sensor on another node is published, asked before the build.
    pub sensor_stream: Option<std::net::SocketAddr>,
}

impl Registry {
    pub fn get(&self, name: &str) -> Result<&Object, ObjectError> {
        self.objects
            .get(name)
            .ok_or_else(|| ObjectError::UnknownName(name.to_string()))
    }

    pub fn get_mut(&mut self, name: &str) -> Result<&mut Object, ObjectError> {
        self.objects
            .get_mut(name)
            .ok_or_else(|| ObjectError::UnknownName(name.to_string()))
    }

    fn expect_class(&self, name: &str, class: Class) -> Result<&Object, ObjectError> {
        let o = self.get(name)?;
        if o.kind.class() != class {
            return Err(ObjectError::WrongClass {
                name: name.to_string(),
                expected: class,
                found: o.kind.class(),
            });
        }
        Ok(o)
    }

    fn robot(&self, name: &str) -> Result<&RobotObj, ObjectError> {
        match &self.expect_class(name, Class::Robot)?.body {
            KindState::Robot(r) => Ok(r),
            _ => Err(ObjectError::internal("robot body")),
        }
    }

    fn controller_mut(&mut self, name: &str) -> Result<&mut ControllerObj, ObjectError> {
        match &mut self.get_mut(name)?.body {
            KindState::Controller(c) => Ok(c),
            _ => Err(ObjectError::internal("controller body")),
        }
    }

    /// The active controller driving `robot`, if any.
    pub fn driver_of(&self, robot: &str) -> Option<String> {
        let o = self.objects.get(robot)?;
        if o.kind.class() != Class::Robot {
            return None;
        }
        o.users.iter().next().cloned()
    }

    // -----------------------------------------------------------------------------------------
    // Lifecycle
    // -----------------------------------------------------------------------------------------

    /// Runs a transition other than a controller's activate/deactivate (the creator handles
    /// those, since they start and stop threads).
    pub fn transition(&mut self, name: &str, t: Transition) -> Result<(), ObjectError> {
        let o = self.get(name)?;
        let kind = o.kind;
        let shown = o.shown_state();
        let refuse = || ObjectError::InvalidTransition {
            name: name.to_string(),
            state: shown,
            transition: t,
        };
        if !o.users.is_empty() && matches!(t, Transition::Cleanup | Transition::Shutdown) {
            return Err(ObjectError::InUse {
                name: name.to_string(),
                dependents: o.users.iter().cloned().collect(),
            });
        }
        if kind.class() != Class::Controller
            && matches!(t, Transition::Activate | Transition::Deactivate)
        {
            return Err(unsupported(
                kind,
                "activate/deactivate (it is active while a controller that uses it runs)",
            ));
        }
        let next = o.state.apply(t).map_err(|_| refuse())?;
        match t {
            Transition::Configure => self.configure(name)?,
            Transition::Cleanup | Transition::Shutdown | Transition::Reset => self.release(name),
            _ => {}
        }
        self.get_mut(name)?.state = next;
        Ok(())
    }

    fn release(&mut self, name: &str) {
        if let Some(o) = self.objects.get_mut(name) {
            match &mut o.body {
                KindState::Robot(r) => {
                    r.body = None;
                    r.kinematics = RobotKinematics::Float(r.model.clone());
                }
                KindState::Teleop(t) => t.link = None,
                // Its thread stops and is joined; readers fall silent and go stale.
                KindState::Sensor(s) => s.publisher = None,
                // A stop request to the box, and the I/O thread joined.
                KindState::LoopSensor(s) => s.release(),
                KindState::Camera(_) => self.release_camera(name),
                b @ (KindState::ReplaySensor(_) | KindState::OperatorReplay(_)) => {
                    Registry::release_replay(b)
                }
                KindState::Galil(g) => {
                    // The driver's release: amplifiers off, watchdog halted.
                    if let Some(b) = g.board.take() {
                        b.release();
                    }
                }
                _ => {}
            }
        }
    }

    fn configure(&mut self, name: &str) -> Result<(), ObjectError> {
        match &mut self.get_mut(name)?.body {
            KindState::Robot(_) => self.configure_robot(name),
            KindState::Galil(g) => {
                g.board = Some(open_galil(&g.config)?);
                Ok(())
            }
            KindState::Teleop(_) => self.configure_teleop(name),
            KindState::Sensor(_) => self.configure_sensor(name),
            KindState::LoopSensor(s) => s.configure(),
            KindState::Camera(_) => self.configure_camera(name),
            KindState::ReplaySensor(_) | KindState::OperatorReplay(_) => {
                self.configure_replay(name)
            }
            KindState::Controller(_) => self.configure_controller(name),
            KindState::SimBoard(_) | KindState::Trajectory(_) | KindState::Hand(_) => Ok(()),
        }
    }

    fn configure_robot(&mut self, name: &str) -> Result<(), ObjectError> {
        let r = self.robot(name)?;
        let n = r.model.joint_count();
        if r.maps.is_empty() {
            return Err(not_ready(format!(
                "robot `{name}` has no joints mapped onto a board (MapJoints first)"
            )));
        }
        let mut seen = [false; MAX_JOINTS];
        let mut sim_boards = Vec::new();
        let mut galil = false;
        for (board, joints) in &r.maps {
            let b = self.expect_class(board, Class::Board)?;
            if b.state == LifecycleState::Unconfigured {
                return Err(not_ready(format!("board `{board}` is not configured")));
            }
            let axes = match &b.body {
                KindState::SimBoard(s) => {
                    sim_boards.push(board.clone());
                    s.config.axes as usize
                }
                KindState::Galil(g) => {
                    galil = true;
                    g.config.axes as usize
                }
                _ => 0,
            };
            for ja in joints {
                let (j, a) = (usize::from(ja.joint), usize::from(ja.axis));
                if j >= n {
                    return Err(bad_arg(format!("robot `{name}` has no joint {j}")));
                }
                if a >= axes {
                    return Err(bad_arg(format!(
                        "board `{board}` has no axis {a} (it has {axes})"
                    )));
                }
                if seen[j] {
                    return Err(bad_arg(format!("joint {j} of `{name}` is mapped twice")));
                }
                seen[j] = true;
            }
        }
        if let Some(j) = (0..n).find(|j| !seen[*j]) {
            return Err(not_ready(format!(
                "joint {j} of robot `{name}` is not mapped onto a board"
            )));
        }
        if galil && !sim_boards.is_empty() {
            return Err(bad_arg(format!(
                "robot `{name}` mixes simulated and galil boards: a simulated body cannot move a real joint"
            )));
        }
        let kinematics = match self.fpga_board_of(name)? {
            Some(_) => RobotKinematics::on_fpga_board(r.model.clone())
                .ok_or_else(|| ObjectError::internal("fpga model"))?,
            None => RobotKinematics::Float(r.model.clone()),
        };
        if let KindState::Robot(r) = &mut self.get_mut(name)?.body {
            r.kinematics = kinematics;
        }
        if let Some(first) = sim_boards.first() {
            self.make_simulated_body(name, first, n)?;
        }
        Ok(())
    }

    /// The simulated body of robot `name` (`n` joints) on simulated board `board`: its plant,
    /// the board's encoders and amplifiers scaled to the robot, and what its tool touches.
    fn make_simulated_body(
        &mut self,
        name: &str,
        board: &str,
        n: usize,
    ) -> Result<(), ObjectError> {
        let KindState::SimBoard(s) = &self.get(board)?.body else {
            return Err(ObjectError::internal("sim body"));
        };
        let env = kinds::environment(Kind::SIM_BOARD.as_str(), &s.config.shapes)?;
        let cfg = s.config.clone();
        let r = self.robot(name)?;
        let model = r.model.clone();
        let q0 = model.named_pose(r.start);
        let mut counts = JointVector::repeat(1.0);
        let mut full = JointVector::repeat(100.0);
        for j in 0..n {
            counts[j] = model.counts_per_radian(j);
            full[j] = finite_effort(&model, j);
        }
        let plant = PlantConfig {
            substep: Duration::from_micros(cfg.substep_us),
            motor_torque_limit: full,
            friction: cfg.friction,
        };
        let board_cfg = DriverSimConfig {
            counts_per_radian: counts,
            effort_full_scale: full,
            dac_bits: cfg.dac_bits,
            position_kp: full * 200.0,
            position_kd: full * 4.0,
            velocity_cutoff_hz: 150.0,
            command_timeout: (cfg.command_timeout_ms > 0)
                .then(|| Duration::from_millis(cfg.command_timeout_ms)),
            brake: cfg.brake,
        };
        // The operator's hand holds a master's handle; anything else meets the board's
        // environment (free space without shapes).
        let contact = self.tool_contact(name, model.forward(&q0), env)?;
        let body = SimBoard::new(model, plant, board_cfg, contact, q0, Timestamp::ZERO);
        if let KindState::Robot(r) = &mut self.get_mut(name)?.body {
            r.body = Some(Box::new(body));
        }
        Ok(())
    }

    fn configure_controller(&mut self, name: &str) -> Result<(), ObjectError> {
        let c = self.controller_mut(name)?;
        if let ControllerConfig::Groups(groups) = &c.config {
            let groups = groups.clone();
            return self.configure_groups(name, &groups);
        }
        let (robot, trajectory, sensor) = (c.robot.clone(), c.trajectory.clone(), c.sensor.clone());
        let robot = robot
            .ok_or_else(|| not_ready(format!("controller `{name}` has no robot (SetRobot)")))?;
        self.expect_class(&robot, Class::Robot)?;
        let trajectory = trajectory.ok_or_else(|| {
            not_ready(format!(
                "controller `{name}` has no trajectory (SetTrajectory)"
            ))
        })?;
        self.expect_class(&trajectory, Class::Trajectory)?;
        if let Some(s) = sensor
            && !s.starts_with('/')
        {
            self.expect_class(&s, Class::Sensor)?;
        }
        Ok(())
    }
}

fn unreachable_body<T>() -> Result<T, ObjectError> {
    Err(ObjectError::internal("object body changed"))
}

fn finite3(v: [f64; 3]) -> Result<Vector3<f64>, ObjectError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(Vector3::from(v))
    } else {
        Err(bad_arg("velocity has a NaN or infinite value"))
    }
}

fn impedance(i: &ImpedanceConfigToml) -> ImpedanceConfig {
    ImpedanceConfig {
        stiffness: i.stiffness,
        damping: i.damping,
        gravity_compensation: i.gravity_compensation,
        max_force: i.max_force,
        max_torque: i.max_torque,
        ramp_in: Duration::from_millis(i.ramp_in_ms),
    }
}
