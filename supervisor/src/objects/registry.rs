//! The objects of a node, their relations and lifecycles, and every method they answer. Lives
//! behind the creator's mutex: the non-real-time side only.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use nalgebra::Vector3;
use penelope_drivers::galil::board::LinkFactory;
use penelope_drivers::galil::{GalilBoard, GalilBoardConfig, Link, TcpLink};
use penelope_drivers::model::{self as models, DhRobotModel};
use penelope_drivers::sim::ToolContact;
use penelope_drivers::sim::board::{SimBoard, SimBoardConfig as DriverSimConfig};
use penelope_drivers::sim::operator::VirtualOperator;
use penelope_drivers::sim::plant::PlantConfig;
use penelope_hal::{
    AxisState, Board, Dynamics, Frame, InverseKinematics, JacobianFrame, JointState, JointVector,
    Kinematics, LifecycleState, MAX_AXES, MAX_JOINTS, NamedPose, RobotModel, Timestamp, Transition,
};
use penelope_rt_core::control::{
    AxisBinding, ControlCommand, ControlConfig, ControlLoop, ControlPorts,
};
use penelope_rt_core::controller::{JointPid, JointPidGains, JointPositionServo};
use penelope_rt_core::safety::{HoldMode, Role, SafetyConfig};
use penelope_rt_core::teleop::{CartesianImpedance, ImpedanceConfig};
use penelope_rt_core::trajectory::{
    CubicSpline, Goal, Ramp, SplineEnds, Step, Trapezoidal, Waypoint,
};

use super::kinds::{
    self, GalilConfig, GoalConfig, ImpedanceConfigToml, JointPidConfig, JointPositionConfig, Kind,
    LoopTiming, RobotConfig, SensorConfig, SimBoardConfig, TrajectorySpec,
};
use super::kinematics::RobotKinematics;
use super::runtime::{
    CellSensor, ControlTask, GainsUpdate, GalilSet, GoToCommand, LoopBoard, NodeController,
    NodeLoop, NodeSink, NodeTrajectory, SimBody, VirtualSensor,
};
use super::teleop::{
    ForceDisplayToml, HandConfig, HandObj, PositionErrorToml, Side, SlaveTrackingToml, TeleopComm,
    TeleopConfig, TeleopLink,
};
use crate::proto::{
    BoardMethod, Class, ControlStatus, ControllerMethod, JointAxis, Joints, MatrixMsg, ObjectInfo,
    OperationalMsg, PoseMsg, ReferenceMsg, Reply, RobotMethod, SensorMethod, TrajectoryMethod,
    WireError, WrenchMsg, joints_from_vector, joints_to_vector,
};

/// One object.
pub(crate) struct Object {
    pub name: String,
    pub kind: Kind,
    pub state: LifecycleState,
    /// Active controllers using this object (it shows `active` while there is one).
    pub users: BTreeSet<String>,
    pub body: Body,
}

// One per object, in a map: the size difference costs nothing worth a box.
#[allow(clippy::large_enum_variant)]
pub(crate) enum Body {
    Robot(Box<RobotObj>),
    SimBoard(SimBoardObj),
    Galil(GalilObj),
    Sensor(SensorObj),
    Controller(Box<ControllerObj>),
    Trajectory(TrajectoryObj),
    Hand(Box<HandObj>),
    Teleop(Box<TeleopObj>),
}

/// A `trajectory/teleop`: its settings, and its cells once configured.
pub(crate) struct TeleopObj {
    pub config: TeleopConfig,
    pub link: Option<TeleopLink>,
}

pub(crate) struct RobotObj {
    /// The float model: dynamics, named poses, encoder scaling, and the simulated body.
    pub model: DhRobotModel,
    /// What the robot's loops and kinematic methods compute with.
    pub kinematics: RobotKinematics,
    /// Master or slave: what its loops' safety does.
    pub role: Role,
    /// A master's display caps, N and N·m.
    pub caps: (f64, f64),
    pub start: NamedPose,
    /// `(board, joints)` in the order given.
    pub maps: Vec<(String, Vec<JointAxis>)>,
    /// The simulated body (robots on simulated boards, configured, not running).
    pub body: Option<Box<SimBody>>,
}

pub(crate) struct SimBoardObj {
    pub config: SimBoardConfig,
}

pub(crate) struct GalilObj {
    pub config: GalilConfig,
    pub board: Option<GalilBoard>,
}

pub(crate) struct SensorObj {
    pub state: Arc<Mutex<VirtualSensor>>,
}

#[derive(Clone)]
pub(crate) enum ControllerConfig {
    Pid(JointPidConfig),
    Impedance(ImpedanceConfigToml),
    Position(JointPositionConfig),
    ForceDisplay(ForceDisplayToml),
    PositionError(PositionErrorToml),
    /// The slave half: torques, or position targets for the board's servo (`true`).
    Tracking(SlaveTrackingToml, bool),
}

impl ControllerConfig {
    /// The side of a teleoperation channel the law runs, if it is a teleoperation law.
    pub fn teleop_side(&self) -> Option<Side> {
        match self {
            ControllerConfig::ForceDisplay(_) | ControllerConfig::PositionError(_) => {
                Some(Side::Master)
            }
            ControllerConfig::Tracking(..) => Some(Side::Slave),
            _ => None,
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
    pub running: Option<super::runtime::Running>,
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

fn bad_arg(m: impl Into<String>) -> WireError {
    WireError::BadArgument(m.into())
}

fn not_ready(m: impl Into<String>) -> WireError {
    WireError::NotReady(m.into())
}

fn unsupported(kind: Kind, method: &str) -> WireError {
    WireError::Unsupported {
        kind: kind.as_str().to_string(),
        method: method.to_string(),
    }
}

fn finite_effort(model: &DhRobotModel, j: usize) -> f64 {
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

    pub fn info(&self) -> ObjectInfo {
        let mut relations = Vec::new();
        match &self.body {
            Body::Robot(r) => {
                for (b, joints) in &r.maps {
                    let list: Vec<String> = joints
                        .iter()
                        .map(|j| format!("{}:{}", j.joint, j.axis))
                        .collect();
                    relations.push(("board".to_string(), format!("{b} [{}]", list.join(" "))));
                }
            }
            Body::Hand(h) => relations.push(("robot".to_string(), h.config.robot.clone())),
            Body::Teleop(t) => {
                relations.push(("master".to_string(), t.config.master.clone()));
                relations.push(("slave".to_string(), t.config.slave.clone()));
            }
            Body::Controller(c) => {
                for (k, v) in [
                    ("robot", &c.robot),
                    ("trajectory", &c.trajectory),
                    ("sensor", &c.sensor),
                ] {
                    if let Some(v) = v {
                        relations.push((k.to_string(), v.clone()));
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

/// Makes the object `name` of `kind` from its configuration text (checked here).
pub(crate) fn make(kind: Kind, name: &str, config: &str) -> Result<Object, WireError> {
    let k = kind.as_str();
    let body = match kind {
        Kind::Robot(model) => {
            let cfg: RobotConfig = kinds::parse(k, config)?;
            let start = cfg.start_pose(k)?;
            let role = cfg.role(k)?;
            let model = models::by_name(model).ok_or_else(|| WireError::UnknownKind(k.into()))?;
            let kinematics = RobotKinematics::new(model.clone(), cfg.fpga(k)?).map_err(|e| {
                WireError::BadConfig {
                    kind: k.into(),
                    message: e.to_string(),
                }
            })?;
            Body::Robot(Box::new(RobotObj {
                model,
                kinematics,
                role,
                caps: (cfg.max_force_n, cfg.max_moment_nm),
                start,
                maps: Vec::new(),
                body: None,
            }))
        }
        Kind::SimBoard => {
            let cfg: SimBoardConfig = kinds::parse(k, config)?;
            cfg.check(k)?;
            Body::SimBoard(SimBoardObj { config: cfg })
        }
        Kind::GalilBoard => {
            let cfg: GalilConfig = kinds::parse(k, config)?;
            cfg.check(k)?;
            Body::Galil(GalilObj {
                config: cfg,
                board: None,
            })
        }
        Kind::VirtualSensor => {
            let cfg: SensorConfig = kinds::parse(k, config)?;
            let env = kinds::environment(k, &cfg.shapes)?;
            Body::Sensor(SensorObj {
                state: Arc::new(Mutex::new(VirtualSensor::new(env))),
            })
        }
        Kind::JointPid => {
            let cfg: JointPidConfig = kinds::parse(k, config)?;
            let timing = cfg.check(k)?;
            controller_body(ControllerConfig::Pid(cfg), timing, config)
        }
        Kind::CartesianImpedance => {
            let cfg: ImpedanceConfigToml = kinds::parse(k, config)?;
            let timing = cfg.check(k)?;
            controller_body(ControllerConfig::Impedance(cfg), timing, config)
        }
        Kind::JointPosition => {
            let cfg: JointPositionConfig = kinds::parse(k, config)?;
            let timing = cfg.check(k)?;
            controller_body(ControllerConfig::Position(cfg), timing, config)
        }
        Kind::OperatorHand => {
            let cfg: HandConfig = kinds::parse(k, config)?;
            let script = cfg.check(k)?;
            Body::Hand(Box::new(HandObj {
                config: cfg,
                script,
                clutch: Arc::default(),
            }))
        }
        Kind::Teleop => {
            let cfg: TeleopConfig = kinds::parse(k, config)?;
            cfg.check(k)?;
            Body::Teleop(Box::new(TeleopObj {
                config: cfg,
                link: None,
            }))
        }
        Kind::ForceDisplay => {
            let cfg: ForceDisplayToml = kinds::parse(k, config)?;
            cfg.law(k)?;
            let timing = cfg.timing(k)?;
            controller_body(ControllerConfig::ForceDisplay(cfg), timing, config)
        }
        Kind::PositionErrorMaster => {
            let cfg: PositionErrorToml = kinds::parse(k, config)?;
            cfg.law(k)?;
            let timing = cfg.timing(k)?;
            controller_body(ControllerConfig::PositionError(cfg), timing, config)
        }
        Kind::SlaveTracking | Kind::SlavePosition => {
            let cfg: SlaveTrackingToml = kinds::parse(k, config)?;
            let servo = kind == Kind::SlavePosition;
            cfg.law(k, servo)?;
            let timing = cfg.timing(k)?;
            controller_body(ControllerConfig::Tracking(cfg, servo), timing, config)
        }
        Kind::Step | Kind::Ramp | Kind::Trapezoidal | Kind::Spline => {
            Body::Trajectory(TrajectoryObj {
                spec: kinds::trajectory_spec(kind, config)?,
            })
        }
    };
    Ok(Object {
        name: name.to_string(),
        kind,
        state: LifecycleState::Unconfigured,
        users: BTreeSet::new(),
        body,
    })
}

fn controller_body(config: ControllerConfig, timing: LoopTiming, text: &str) -> Body {
    Body::Controller(Box::new(ControllerObj {
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
}

/// What activating a controller needs from the creator.
pub(crate) struct Launch<'a> {
    pub rt: &'a super::RtPolicy,
    pub remote: Option<Arc<dyn crate::service::Remote>>,
}

impl Registry {
    pub fn get(&self, name: &str) -> Result<&Object, WireError> {
        self.objects
            .get(name)
            .ok_or_else(|| WireError::UnknownName(name.to_string()))
    }

    pub fn get_mut(&mut self, name: &str) -> Result<&mut Object, WireError> {
        self.objects
            .get_mut(name)
            .ok_or_else(|| WireError::UnknownName(name.to_string()))
    }

    fn expect_class(&self, name: &str, class: Class) -> Result<&Object, WireError> {
        let o = self.get(name)?;
        if o.kind.class() != class {
            return Err(WireError::WrongClass {
                name: name.to_string(),
                expected: class,
                found: o.kind.class(),
            });
        }
        Ok(o)
    }

    fn robot(&self, name: &str) -> Result<&RobotObj, WireError> {
        match &self.expect_class(name, Class::Robot)?.body {
            Body::Robot(r) => Ok(r),
            _ => Err(WireError::Internal("robot body".into())),
        }
    }

    fn controller_mut(&mut self, name: &str) -> Result<&mut ControllerObj, WireError> {
        match &mut self.get_mut(name)?.body {
            Body::Controller(c) => Ok(c),
            _ => Err(WireError::Internal("controller body".into())),
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
    pub fn transition(&mut self, name: &str, t: Transition) -> Result<(), WireError> {
        let o = self.get(name)?;
        let kind = o.kind;
        let shown = o.shown_state();
        let refuse = || WireError::InvalidTransition {
            name: name.to_string(),
            state: shown,
            transition: t,
        };
        if !o.users.is_empty() && matches!(t, Transition::Cleanup | Transition::Shutdown) {
            return Err(WireError::InUse {
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
                Body::Robot(r) => r.body = None,
                Body::Teleop(t) => t.link = None,
                Body::Galil(g) => {
                    // The driver's release: amplifiers off, watchdog halted.
                    if let Some(b) = g.board.take() {
                        b.release();
                    }
                }
                _ => {}
            }
        }
    }

    fn configure(&mut self, name: &str) -> Result<(), WireError> {
        let kind = self.get(name)?.kind;
        match kind {
            Kind::Robot(_) => self.configure_robot(name),
            Kind::GalilBoard => {
                let Body::Galil(g) = &mut self.get_mut(name)?.body else {
                    return Err(WireError::Internal("galil body".into()));
                };
                g.board = Some(open_galil(&g.config)?);
                Ok(())
            }
            Kind::Teleop => self.configure_teleop(name),
            _ if kind.class() == Class::Controller => self.configure_controller(name),
            _ => Ok(()),
        }
    }

    fn configure_robot(&mut self, name: &str) -> Result<(), WireError> {
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
                Body::SimBoard(s) => {
                    sim_boards.push(board.clone());
                    s.config.axes as usize
                }
                Body::Galil(g) => {
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
        if let Some(first) = sim_boards.first() {
            let Body::SimBoard(s) = &self.get(first)?.body else {
                return Err(WireError::Internal("sim body".into()));
            };
            let env = kinds::environment("board/sim", &s.config.shapes)?;
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
            };
            // The operator's hand holds a master's handle; anything else meets the board's
            // environment (free space without shapes).
            let hand = self.objects.values().find_map(|o| match &o.body {
                Body::Hand(h) if h.config.robot == name => Some(h),
                _ => None,
            });
            let contact = match hand {
                Some(h) => ToolContact::Hand {
                    operator: VirtualOperator::new(
                        h.script.clone(),
                        h.config.impedance(),
                        model.forward(&q0),
                        Timestamp::ZERO,
                    ),
                    clutch: h.clutch.clone(),
                },
                None => ToolContact::Environment(env),
            };
            let body = SimBoard::new(model, plant, board_cfg, contact, q0, Timestamp::ZERO);
            if let Body::Robot(r) = &mut self.get_mut(name)?.body {
                r.body = Some(Box::new(body));
            }
        }
        Ok(())
    }

    fn configure_teleop(&mut self, name: &str) -> Result<(), WireError> {
        let Body::Teleop(t) = &self.get(name)?.body else {
            return Err(WireError::Internal("teleop body".into()));
        };
        let (master, slave, mapping) = (
            t.config.master.clone(),
            t.config.slave.clone(),
            t.config.mapping(),
        );
        self.expect_class(&master, Class::Robot)?;
        self.expect_class(&slave, Class::Robot)?;
        penelope_rt_core::teleop::WorkspaceMapping::new(mapping).map_err(|e| {
            WireError::BadConfig {
                kind: "trajectory/teleop".into(),
                message: format!("{e:?}"),
            }
        })?;
        if let Body::Teleop(t) = &mut self.get_mut(name)?.body {
            t.link = Some(TeleopLink::new());
        }
        Ok(())
    }

    fn configure_controller(&mut self, name: &str) -> Result<(), WireError> {
        let c = self.controller_mut(name)?;
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

    /// Builds the loop of controller `name` (configured, inactive) without starting threads.
    /// Takes the robot's board(s) and marks every object it uses.
    pub fn build_loop(&mut self, name: &str, launch: &Launch<'_>) -> Result<Built, WireError> {
        let o = self.get(name)?;
        if o.kind.class() != Class::Controller {
            return Err(unsupported(o.kind, "activate"));
        }
        if o.state != LifecycleState::Inactive {
            return Err(WireError::InvalidTransition {
                name: name.to_string(),
                state: o.shown_state(),
                transition: Transition::Activate,
            });
        }
        self.configure_controller(name)?;
        let c = self.controller_mut(name)?;
        let timing = c.timing;
        let robot_name = c.robot.clone().unwrap_or_default();
        let traj_name = c.trajectory.clone().unwrap_or_default();
        let sensor_name = c.sensor.clone();
        let law = c.config.clone();
        let kind = self.get(name)?.kind.as_str();

        // The robot and its boards: configured, and no axis driven by another loop.
        let robot_obj = self.get(&robot_name)?;
        if robot_obj.state != LifecycleState::Inactive {
            return Err(not_ready(format!("robot `{robot_name}` is not configured")));
        }
        if let Some(d) = robot_obj.users.iter().next() {
            return Err(WireError::InUse {
                name: robot_name.clone(),
                dependents: vec![d.clone()],
            });
        }
        let r = self.robot(&robot_name)?;
        for (board, joints) in &r.maps {
            for (other_name, other) in &self.objects {
                let Body::Robot(or) = &other.body else {
                    continue;
                };
                if other_name == &robot_name || other.users.is_empty() {
                    continue;
                }
                for (ob, oj) in &or.maps {
                    if ob == board && oj.iter().any(|x| joints.iter().any(|y| x.axis == y.axis)) {
                        return Err(WireError::InUse {
                            name: board.clone(),
                            dependents: other.users.iter().cloned().collect(),
                        });
                    }
                }
            }
            if let Body::Galil(g) = &self.get(board)?.body
                && g.board.is_none()
            {
                let b = self.get(board)?;
                return Err(WireError::InUse {
                    name: board.clone(),
                    dependents: b.users.iter().cloned().collect(),
                });
            }
        }
        let trajectory_obj = self.get(&traj_name)?;
        if trajectory_obj.state == LifecycleState::Unconfigured {
            return Err(not_ready(format!(
                "trajectory `{traj_name}` is not configured"
            )));
        }
        let local_sensor = match &sensor_name {
            Some(s) if !s.starts_with('/') => {
                let so = self.get(s)?;
                if so.state == LifecycleState::Unconfigured {
                    return Err(not_ready(format!("sensor `{s}` is not configured")));
                }
                match &so.body {
                    Body::Sensor(x) => Some(x.state.clone()),
                    _ => None,
                }
            }
            _ => None,
        };
        if sensor_name.as_deref().is_some_and(|s| s.starts_with('/')) && launch.remote.is_none() {
            return Err(not_ready(
                "no remote link to other nodes on this creator (set_remote)",
            ));
        }

        let r = self.robot(&robot_name)?;
        let model = r.model.clone();
        let kinematics = r.kinematics.clone();
        let (role, caps) = (r.role, r.caps);
        let n = model.joint_count();
        let start = r.start;
        // A trajectory, or one end of a teleoperation channel for the halves of the laws.
        let (trajectory, teleop) = match (&self.get(&traj_name)?.body, law.teleop_side()) {
            (Body::Trajectory(t), None) => (Some(build_trajectory(&t.spec, &model, kind)?), None),
            (Body::Teleop(t), Some(side)) => {
                check_teleop_end(&traj_name, t, side, &robot_name)?;
                (None, Some((side, t.config.mapping())))
            }
            (Body::Teleop(_), None) => {
                return Err(bad_arg(format!(
                    "`{traj_name}` is a teleoperation channel: it is followed by the halves of \
                     the teleoperation laws (force-display, position-error-master, \
                     slave-tracking, slave-position), not by {kind}"
                )));
            }
            (_, Some(_)) => {
                return Err(bad_arg(format!(
                    "{kind} follows a trajectory/teleop channel; `{traj_name}` is not one"
                )));
            }
            _ => return Err(WireError::Internal("trajectory body".into())),
        };

        // Controller.
        let (controller, hold) = match &law {
            ControllerConfig::Pid(p) => {
                let mut kp = JointVector::zeros();
                let mut kd = JointVector::zeros();
                for j in 0..n {
                    kp[j] = 10.0 * finite_effort(&model, j);
                    kd[j] = 0.5 * finite_effort(&model, j);
                }
                let gains = pid_gains(p, kind, n, kp, kd)?;
                (NodeController::Pid(JointPid::new(gains)), (kp, kd))
            }
            ControllerConfig::Impedance(i) => {
                let cfg = impedance(i);
                let c = CartesianImpedance::new(cfg).map_err(|e| WireError::BadConfig {
                    kind: kind.into(),
                    message: format!("{e:?}"),
                })?;
                let mut kp = JointVector::zeros();
                let mut kd = JointVector::zeros();
                for j in 0..n {
                    kp[j] = 10.0 * finite_effort(&model, j);
                    kd[j] = 0.5 * finite_effort(&model, j);
                }
                (NodeController::Impedance(c), (kp, kd))
            }
            ControllerConfig::Position(p) => {
                let max_velocity = p
                    .max_velocity
                    .resolve(kind, "max_velocity", n, 1e-3, 100.0)?;
                let mut kp = JointVector::zeros();
                let mut kd = JointVector::zeros();
                for j in 0..n {
                    kp[j] = 10.0 * finite_effort(&model, j);
                    kd[j] = 0.5 * finite_effort(&model, j);
                }
                (
                    NodeController::Position(JointPositionServo::new(max_velocity)),
                    (kp, kd),
                )
            }
            ControllerConfig::ForceDisplay(c) => (
                NodeController::ForceDisplay(c.law(kind)?),
                slave_hold(&model, n),
            ),
            ControllerConfig::PositionError(c) => (
                NodeController::PositionErrorMaster(c.law(kind)?),
                slave_hold(&model, n),
            ),
            ControllerConfig::Tracking(c, servo) => (
                NodeController::SlaveTracking(c.law(kind, *servo)?),
                slave_hold(&model, n),
            ),
        };

        // Safety by role (a master: display caps, zero force on a stale reference, amplifiers
        // off on a fault; a slave holds its pose), and axis bindings.
        let mut safety = match role {
            Role::Master => {
                let mut s = SafetyConfig::master(n, *model.limits());
                (s.max_force, s.max_moment) = caps;
                s
            }
            Role::Slave => SafetyConfig::slave(n, *model.limits()),
        };
        safety.watchdog = timing.watchdog;
        let mut config = ControlConfig::new(timing.period, safety);
        let r = self.robot(&robot_name)?;
        let on_sim = r.body.is_some();
        let zero = model.named_pose(start);
        for j in 0..n {
            let cpr = model.counts_per_radian(j);
            let mut b = AxisBinding::new(j as u8, cpr);
            if !on_sim {
                b.offset_counts = -((zero[j] * cpr).round() as i64);
            }
            config = config.with_axis(j, b);
        }
        config.safety.hold = if on_sim {
            HoldMode::Pd {
                kp: hold.0,
                kd: hold.1,
            }
        } else {
            HoldMode::BoardServo
        };
        config.validate(n).map_err(|e| WireError::BadConfig {
            kind: kind.into(),
            message: e.to_string(),
        })?;

        // Take the board(s).
        let maps = r.maps.clone();
        let board = if on_sim {
            let Body::Robot(r) = &mut self.get_mut(&robot_name)?.body else {
                return Err(WireError::Internal("robot body".into()));
            };
            LoopBoard::Sim(
                r.body
                    .take()
                    .ok_or_else(|| WireError::Internal("sim body".into()))?,
                None,
            )
        } else {
            let mut boards: Vec<(String, GalilBoard)> = Vec::new();
            let mut map = [(0u8, 0u8); MAX_JOINTS];
            for (board, joints) in &maps {
                let index = boards.len() as u8;
                let Body::Galil(g) = &mut self.get_mut(board)?.body else {
                    return Err(WireError::Internal("galil body".into()));
                };
                let Some(mut b) = g.board.take() else {
                    // Put back what was taken before refusing.
                    self.give_back(
                        LoopBoard::Galil(Box::new(GalilSet::new(boards, map, n))),
                        &robot_name,
                    );
                    return Err(not_ready(format!("board `{board}` is not open")));
                };
                // Torque directions from the model: the driver signs each axis' effort.
                let bindings: Vec<AxisBinding> = joints
                    .iter()
                    .map(|ja| AxisBinding::new(ja.axis, model.counts_per_radian(ja.joint.into())))
                    .collect();
                b.orient(&bindings);
                boards.push((board.clone(), b));
                for ja in joints {
                    map[usize::from(ja.joint)] = (index, ja.axis);
                }
            }
            LoopBoard::Galil(Box::new(GalilSet::new(boards, map, n)))
        };

        // Ports.
        use penelope_rt_core::cell::latest;
        use penelope_rt_core::ring::ring;
        let (ref_w, ref_r) = latest();
        let (tel_w, tel_r) = ring();
        let (comm_w, comm_r) = latest();
        let (probe_w, probe_r) = latest();
        let (mut cmd_w, cmd_r) = ring();
        let (goto_w, goto_r) = ring();
        let (gains_w, gains_r) = latest();
        let sink = NodeSink::new(tel_w, comm_w, probe_w);
        let ports = ControlPorts {
            reference: ref_r,
            telemetry: sink,
            commands: cmd_r,
        };
        let cartesian = controller.is_cartesian();
        let lp = match ControlLoop::new(config, board, kinematics.clone(), [controller], ports) {
            Ok(l) => l,
            Err(e) => return Err(WireError::Internal(format!("control loop: {e}"))),
        };
        let (lp, wrench_w) = if sensor_name.is_some() {
            let (w, r) = latest();
            (
                NodeLoop::Sensed(Box::new(
                    lp.with_sensor(CellSensor::new(r, timing.sensor_timeout)),
                )),
                Some(w),
            )
        } else {
            (NodeLoop::Plain(Box::new(lp)), None)
        };
        let _ = cmd_w.push(ControlCommand::Activate);
        let comm = match (trajectory, teleop) {
            (Some(trajectory), _) => super::runtime::CommTask::new(
                trajectory,
                ref_w,
                comm_r,
                goto_r,
                kinematics.clone(),
                cartesian,
            ),
            (None, Some((side, mapping))) => {
                // The master's clutch is its operator's hand's button, if a hand holds it.
                let clutch = self.objects.values().find_map(|o| match &o.body {
                    Body::Hand(h) if side == Side::Master && h.config.robot == robot_name => {
                        Some(h.clutch.clone())
                    }
                    _ => None,
                });
                let Some(Body::Teleop(t)) = self.objects.get_mut(&traj_name).map(|o| &mut o.body)
                else {
                    return Err(WireError::Internal("teleop body".into()));
                };
                let link = t
                    .link
                    .as_mut()
                    .ok_or_else(|| WireError::Internal("teleop link".into()))?;
                let end = link
                    .take(side)
                    .ok_or_else(|| WireError::Internal("teleop end".into()))?;
                super::runtime::CommTask::teleop(
                    TeleopComm::new(end, mapping, kinematics.clone())?.with_clutch(clutch),
                    ref_w,
                    comm_r,
                    goto_r,
                    kinematics.clone(),
                )?
            }
            (None, None) => return Err(WireError::Internal("no reference source".into())),
        };
        let source = match (&sensor_name, local_sensor) {
            (Some(path), None) => {
                launch
                    .remote
                    .clone()
                    .map(|remote| super::runtime::SensorSource::Remote {
                        remote,
                        path: path.clone(),
                    })
            }
            (_, Some(local)) => Some(super::runtime::SensorSource::Local(local)),
            _ => None,
        };

        // Mark the users.
        let mut used = vec![robot_name.clone(), traj_name.clone()];
        used.extend(maps.iter().map(|(b, _)| b.clone()));
        if let Some(s) = &sensor_name
            && !s.starts_with('/')
        {
            used.push(s.clone());
        }
        for u in &used {
            if let Some(o) = self.objects.get_mut(u) {
                o.users.insert(name.to_string());
            }
        }
        Ok(Built {
            control: ControlTask::new(lp, gains_r),
            comm,
            telemetry: tel_r,
            commands: cmd_w,
            goto: goto_w,
            gains: gains_w,
            probe: probe_r,
            wrench: wrench_w,
            source,
            model: kinematics,
            joints: n,
            timing,
        })
    }

    /// Takes a stopped loop of `controller` back: its board to the robot's objects (amplifiers
    /// off, or, `after_fault` on a board with its own servo, still holding), its teleoperation
    /// channel's end to the channel, and clears the users. What a thread took down with it is
    /// marked `unconfigured` (configure it again). Returns how the robot was left, in words.
    pub fn take_back(
        &mut self,
        stopped: super::runtime::StoppedLoop,
        controller: &str,
        after_fault: bool,
    ) -> &'static str {
        let (robot, trajectory) = match self.objects.get(controller).map(|o| &o.body) {
            Some(Body::Controller(c)) => (
                c.robot.clone().unwrap_or_default(),
                c.trajectory.clone().unwrap_or_default(),
            ),
            _ => (String::new(), String::new()),
        };
        let said = match stopped.control {
            Some(t) => {
                let hold = after_fault && t.holds_with_board_servo();
                self.give_back_after_fault(t.into_loop().into_board(), &robot, hold);
                if hold {
                    "held by its board's servo"
                } else {
                    "zero torque, amplifiers off"
                }
            }
            None => {
                if let Ok(o) = self.get_mut(&robot) {
                    o.state = LifecycleState::Unconfigured;
                }
                "its board went down with the thread; configure the robot again"
            }
        };
        let end = stopped.comm.and_then(|c| c.into_teleop_end());
        if let Some(Object {
            body: Body::Teleop(t),
            state,
            ..
        }) = self.objects.get_mut(&trajectory)
            && let Some(link) = t.link.as_mut()
        {
            match end {
                Some(end) => link.put_back(end),
                None => {
                    // The end went down with its thread: new cells at the next configure.
                    t.link = None;
                    *state = LifecycleState::Unconfigured;
                }
            }
        }
        self.release_users(controller);
        said
    }

    /// Gives a stopped loop's board back to the objects it came from, amplifiers off.
    pub fn give_back(&mut self, board: LoopBoard, robot: &str) {
        self.give_back_after_fault(board, robot, false);
    }

    /// Gives a failed loop's board back as the loop left it: still holding with its own servo
    /// when `holding` (a position board the loop stopped at its measured pose), else with its
    /// amplifiers off.
    pub fn give_back_after_fault(&mut self, mut board: LoopBoard, robot: &str, holding: bool) {
        if !holding {
            let _ = board.set_enabled(false);
        }
        match board {
            LoopBoard::Sim(body, _) => {
                if let Some(Object {
                    body: Body::Robot(r),
                    ..
                }) = self.objects.get_mut(robot)
                {
                    r.body = Some(body);
                }
            }
            LoopBoard::Galil(set) => {
                for (name, b) in set.boards {
                    if let Some(Object {
                        body: Body::Galil(g),
                        ..
                    }) = self.objects.get_mut(&name)
                    {
                        g.board = Some(b);
                    }
                }
            }
        }
    }

    /// Clears `controller` from every object's users.
    pub fn release_users(&mut self, controller: &str) {
        for o in self.objects.values_mut() {
            o.users.remove(controller);
        }
    }

    // -----------------------------------------------------------------------------------------
    // Methods
    // -----------------------------------------------------------------------------------------

    /// The measured joint state of `robot`: from its running loop, its simulated body, or its
    /// Galil boards.
    fn measured(&mut self, robot: &str) -> Result<(JointState, JointVector), WireError> {
        if let Some(c) = self.driver_of(robot)
            && let Ok(ctrl) = self.controller_mut(&c)
            && let Some(run) = &ctrl.running
        {
            let Some(n) = run.shared.newest() else {
                return Err(not_ready(format!(
                    "robot `{robot}`: its loop has not ticked yet"
                )));
            };
            let s = n.sample;
            return Ok((
                JointState {
                    position: s.q,
                    velocity: s.qd,
                    effort: s.effort,
                },
                n.acceleration,
            ));
        }
        let r = self.robot(robot)?;
        if let Some(b) = &r.body {
            return Ok((b.plant().snapshot().joints, JointVector::zeros()));
        }
        let model = r.model.clone();
        let zero = model.named_pose(r.start);
        let maps = r.maps.clone();
        let mut state = JointState::default();
        let mut any = false;
        for (board, joints) in &maps {
            let Ok(Object {
                body: Body::Galil(g),
                ..
            }) = self.get_mut(board)
            else {
                continue;
            };
            let Some(b) = g.board.as_mut() else { continue };
            let mut axes = [AxisState::default(); MAX_AXES];
            let count = b.axis_count().min(MAX_AXES);
            b.read_axes(
                penelope_rt_core::clock::MonotonicClock::read(),
                &mut axes[..count],
            )
            .map_err(|e| WireError::Device(format!("board `{board}`: {e}")))?;
            for ja in joints {
                let j = usize::from(ja.joint);
                let cpr = model.counts_per_radian(j);
                let offset = -((zero[j] * cpr).round() as i64);
                let a = axes[usize::from(ja.axis)];
                state.position[j] = a.position.wrapping_sub(offset) as f64 / cpr;
                state.velocity[j] = a.velocity / cpr;
                any = true;
            }
        }
        if any {
            Ok((state, JointVector::zeros()))
        } else {
            Err(not_ready(format!("robot `{robot}` is not configured")))
        }
    }

    fn q_or_measured(&mut self, robot: &str, q: &Option<Joints>) -> Result<JointVector, WireError> {
        let n = self.robot(robot)?.model.joint_count();
        match q {
            Some(q) => joints_to_vector(q, n),
            None => Ok(self.measured(robot)?.0.position),
        }
    }

    pub fn robot_method(&mut self, name: &str, m: RobotMethod) -> Result<Reply, WireError> {
        let n = self.robot(name)?.model.joint_count();
        match m {
            RobotMethod::JointPositions => Ok(Reply::Joints(joints_from_vector(
                &self.measured(name)?.0.position,
                n,
            ))),
            RobotMethod::JointVelocities => Ok(Reply::Joints(joints_from_vector(
                &self.measured(name)?.0.velocity,
                n,
            ))),
            RobotMethod::JointAccelerations => Ok(Reply::Joints(joints_from_vector(
                &self.measured(name)?.1,
                n,
            ))),
            RobotMethod::Operational => {
                let s = self.measured(name)?.0;
                let model = &self.robot(name)?.model;
                let o = model.operational_state(&s);
                Ok(Reply::Operational(OperationalMsg {
                    pose: PoseMsg::from(&o.pose),
                    linear_velocity: o.twist.linear.into(),
                    angular_velocity: o.twist.angular.into(),
                }))
            }
            RobotMethod::ToolWrench => {
                let driver = self.driver_of(name).ok_or_else(|| {
                    not_ready(format!(
                        "robot `{name}` is not driven by an active controller"
                    ))
                })?;
                let c = self.controller_mut(&driver)?;
                if c.sensor.is_none() {
                    return Err(not_ready(format!(
                        "controller `{driver}` has no force sensor"
                    )));
                }
                let s = c
                    .running
                    .as_ref()
                    .and_then(|r| r.shared.newest())
                    .ok_or_else(|| not_ready("no sample yet"))?;
                Ok(Reply::Wrench(WrenchMsg::from(&s.sample.wrench)))
            }
            RobotMethod::ForwardKinematics { q } => {
                let q = self.q_or_measured(name, &q)?;
                Ok(Reply::Pose(PoseMsg::from(
                    &self.robot(name)?.kinematics.forward(&q),
                )))
            }
            RobotMethod::Jacobian { q } => {
                let q = self.q_or_measured(name, &q)?;
                let j = self
                    .robot(name)?
                    .kinematics
                    .jacobian(&q, JacobianFrame::Base);
                Ok(Reply::Matrix(MatrixMsg::from_block(&j, 6, n)))
            }
            RobotMethod::JacobianInverse { q, damping } => {
                if !(damping.is_finite() && (0.0..=10.0).contains(&damping)) {
                    return Err(bad_arg("damping must be finite, 0..=10"));
                }
                let q = self.q_or_measured(name, &q)?;
                let j = self.robot(name)?.model.jacobian_damped_inverse(&q, damping);
                Ok(Reply::Matrix(MatrixMsg::from_block(&j, n, 6)))
            }
            RobotMethod::InverseKinematics { pose } => {
                let pose = pose.to_pose()?;
                let mut out = penelope_hal::IkSolutions::new();
                let model = &self.robot(name)?.model;
                let _ = model.inverse_all(&pose, &mut out);
                Ok(Reply::Solutions(
                    out.iter()
                        .filter(|s| s.within_limits)
                        .map(|s| joints_from_vector(&s.q, n))
                        .collect(),
                ))
            }
            RobotMethod::WrenchToTorques { wrench, q } => {
                let w = wrench.to_wrench(Frame::Base)?;
                let q = self.q_or_measured(name, &q)?;
                let tau = self
                    .robot(name)?
                    .model
                    .wrench_to_torques(&q, &w)
                    .map_err(|e| bad_arg(e.to_string()))?;
                Ok(Reply::Joints(joints_from_vector(&tau, n)))
            }
            RobotMethod::Gravity { q } => {
                let q = self.q_or_measured(name, &q)?;
                Ok(Reply::Joints(joints_from_vector(
                    &self.robot(name)?.model.gravity(&q),
                    n,
                )))
            }
            RobotMethod::Inertia { q } => {
                let q = self.q_or_measured(name, &q)?;
                let m = self.robot(name)?.model.inertia(&q);
                Ok(Reply::Matrix(MatrixMsg::from_block(&m, n, n)))
            }
            RobotMethod::CountsToRadians { counts } => {
                if counts.len() != n {
                    return Err(bad_arg(format!(
                        "expected {n} counts, got {}",
                        counts.len()
                    )));
                }
                let model = &self.robot(name)?.model;
                Ok(Reply::Joints(
                    counts
                        .iter()
                        .enumerate()
                        .map(|(j, c)| *c as f64 / model.counts_per_radian(j))
                        .collect(),
                ))
            }
            RobotMethod::RadiansToCounts { q } => {
                let q = joints_to_vector(&q, n)?;
                let model = &self.robot(name)?.model;
                Ok(Reply::Counts(
                    (0..n)
                        .map(|j| (q[j] * model.counts_per_radian(j)).round() as i64)
                        .collect(),
                ))
            }
            RobotMethod::NamedPose { pose } => Ok(Reply::Joints(joints_from_vector(
                &self.robot(name)?.model.named_pose(pose),
                n,
            ))),
            RobotMethod::GoTo { pose, duration_s } => {
                if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 3600.0) {
                    return Err(bad_arg("duration_s must be in (0, 3600]"));
                }
                let goal = self.robot(name)?.model.named_pose(pose);
                let driver = self.driver_of(name).ok_or_else(|| {
                    not_ready(format!(
                        "robot `{name}` is not driven by an active controller (activate one)"
                    ))
                })?;
                let c = self.controller_mut(&driver)?;
                if c.config.teleop_side().is_some() {
                    return Err(not_ready(format!(
                        "robot `{name}` follows a teleoperation channel (`{driver}`): it goes \
                         where the other side takes it"
                    )));
                }
                let run = c
                    .running
                    .as_mut()
                    .ok_or_else(|| not_ready("controller not running"))?;
                run.goto
                    .push(GoToCommand {
                        goal,
                        duration: Duration::from_secs_f64(duration_s),
                    })
                    .map_err(|_| not_ready("too many motions queued"))?;
                Ok(Reply::Unit)
            }
            RobotMethod::MapJoints { board, joints } => {
                let o = self.get(name)?;
                if o.state != LifecycleState::Unconfigured {
                    return Err(not_ready(format!(
                        "map the joints of `{name}` before configure (cleanup first)"
                    )));
                }
                crate::proto::check_name(&board)?;
                if joints.is_empty() || joints.len() > MAX_JOINTS {
                    return Err(bad_arg(format!("map 1 to {MAX_JOINTS} joints")));
                }
                for (i, ja) in joints.iter().enumerate() {
                    if usize::from(ja.joint) >= n {
                        return Err(bad_arg(format!("robot `{name}` has no joint {}", ja.joint)));
                    }
                    if usize::from(ja.axis) >= MAX_AXES {
                        return Err(bad_arg(format!("axis {} is past {MAX_AXES}", ja.axis)));
                    }
                    if joints[..i]
                        .iter()
                        .any(|o| o.joint == ja.joint || o.axis == ja.axis)
                    {
                        return Err(bad_arg("a joint or an axis appears twice"));
                    }
                }
                let Body::Robot(r) = &mut self.get_mut(name)?.body else {
                    return Err(WireError::Internal("robot body".into()));
                };
                // Replaces this board's mapping; joints mapped elsewhere move here.
                r.maps.retain(|(b, _)| b != &board);
                for (_, js) in r.maps.iter_mut() {
                    js.retain(|x| !joints.iter().any(|y| y.joint == x.joint));
                }
                r.maps.retain(|(_, js)| !js.is_empty());
                r.maps.push((board, joints));
                Ok(Reply::Unit)
            }
        }
    }

    pub fn board_method(&mut self, name: &str, m: BoardMethod) -> Result<Reply, WireError> {
        let o = self.expect_class(name, Class::Board)?;
        let active = !o.users.is_empty();
        match (&o.body, m) {
            (Body::SimBoard(s), BoardMethod::AxisCount) => Ok(Reply::Count(s.config.axes)),
            (Body::Galil(g), BoardMethod::AxisCount) => Ok(Reply::Count(g.config.axes)),
            (_, BoardMethod::AmplifiersEnabled) => {
                // An idle board says what the device holds (a failed loop may leave a position
                // board holding); a driven one, what its loop's safety state implies.
                if !active {
                    let on = match &o.body {
                        Body::Galil(g) => g.board.as_ref().is_some_and(GalilBoard::is_enabled),
                        _ => self.objects.values().any(|r| match &r.body {
                            Body::Robot(r) => {
                                r.maps.iter().any(|(b, _)| b == name)
                                    && r.body.as_ref().is_some_and(|b| b.is_enabled())
                            }
                            _ => false,
                        }),
                    };
                    return Ok(Reply::Flag(on));
                }
                let user = o.users.iter().next().cloned().unwrap_or_default();
                let c = self.controller_mut(&user)?;
                let on = c
                    .running
                    .as_ref()
                    .and_then(|r| r.shared.newest())
                    .is_some_and(|n| {
                        use penelope_rt_core::safety::SafetyState;
                        matches!(
                            n.sample.state,
                            SafetyState::Running | SafetyState::Holding | SafetyState::Fault
                        )
                    });
                Ok(Reply::Flag(on))
            }
            (_, BoardMethod::Rearm) if active => Err(not_ready(format!(
                "board `{name}` is driven by `{}`: re-arm that controller (it re-arms the board \
                 and its loop)",
                o.users.iter().next().cloned().unwrap_or_default()
            ))),
            (Body::Galil(g), BoardMethod::Rearm) => match &g.board {
                Some(b) => {
                    b.rearm();
                    Ok(Reply::Unit)
                }
                None => Err(not_ready(format!(
                    "board `{name}` is not open (configure it)"
                ))),
            },
            // A simulated board latches nothing.
            (_, BoardMethod::Rearm) => Ok(Reply::Unit),
            (_, BoardMethod::ReadEncoders) => {
                let axes = match &o.body {
                    Body::SimBoard(s) => s.config.axes as usize,
                    Body::Galil(g) => g.config.axes as usize,
                    _ => 0,
                };
                let mut counts = vec![0i64; axes];
                if let Body::Galil(_) = &o.body
                    && !active
                {
                    let Body::Galil(g) = &mut self.get_mut(name)?.body else {
                        unreachable_body()?
                    };
                    let b = g
                        .board
                        .as_mut()
                        .ok_or_else(|| not_ready(format!("board `{name}` is not configured")))?;
                    let mut st = [AxisState::default(); MAX_AXES];
                    let count = b.axis_count().min(MAX_AXES);
                    b.read_axes(
                        penelope_rt_core::clock::MonotonicClock::read(),
                        &mut st[..count],
                    )
                    .map_err(|e| WireError::Device(format!("board `{name}`: {e}")))?;
                    for (c, s) in counts.iter_mut().zip(st.iter()) {
                        *c = s.position;
                    }
                    return Ok(Reply::Counts(counts));
                }
                // Every robot mapped onto it: its joints' counts from the measured state.
                let robots: Vec<(String, Vec<JointAxis>)> = self
                    .objects
                    .iter()
                    .filter_map(|(rn, ro)| match &ro.body {
                        Body::Robot(r) => r
                            .maps
                            .iter()
                            .find(|(b, _)| b == name)
                            .map(|(_, j)| (rn.clone(), j.clone())),
                        _ => None,
                    })
                    .collect();
                for (rn, joints) in robots {
                    let Ok((state, _)) = self.measured(&rn) else {
                        continue;
                    };
                    let r = self.robot(&rn)?;
                    let zero = r.model.named_pose(r.start);
                    let on_sim =
                        r.body.is_some() || matches!(self.get(name)?.body, Body::SimBoard(_));
                    for ja in joints {
                        let j = usize::from(ja.joint);
                        let cpr = r.model.counts_per_radian(j);
                        let offset = if on_sim {
                            0
                        } else {
                            -((zero[j] * cpr).round() as i64)
                        };
                        if let Some(c) = counts.get_mut(usize::from(ja.axis)) {
                            *c = (state.position[j] * cpr).floor() as i64 + offset;
                        }
                    }
                }
                Ok(Reply::Counts(counts))
            }
            _ => Err(WireError::Internal("board body".into())),
        }
    }

    pub fn sensor_method(&mut self, name: &str, m: SensorMethod) -> Result<Reply, WireError> {
        let o = self.expect_class(name, Class::Sensor)?;
        if o.state == LifecycleState::Unconfigured {
            return Err(not_ready(format!("sensor `{name}` is not configured")));
        }
        let s = match &o.body {
            Body::Sensor(s) => s,
            Body::Hand(h) => {
                return Err(WireError::Unsupported {
                    kind: o.kind.as_str().into(),
                    method: format!(
                        "{m:?} (the hand pushes `{}`'s simulated handle; what it feels is in \
                         that robot's telemetry)",
                        h.config.robot
                    ),
                });
            }
            _ => return Err(WireError::Internal("sensor body".into())),
        };
        let state = s.state.clone();
        let mut st = state
            .lock()
            .map_err(|_| WireError::Internal("sensor state poisoned".into()))?;
        match m {
            SensorMethod::Read => Ok(Reply::Wrench(WrenchMsg::from(&st.read()))),
            SensorMethod::Bias => {
                st.bias();
                Ok(Reply::Unit)
            }
            SensorMethod::SetProbe { pose, velocity } => {
                let pose = pose.to_pose()?;
                let v = finite3(velocity)?;
                st.measure(&pose, v);
                Ok(Reply::Unit)
            }
            SensorMethod::Measure { pose, velocity } => {
                let pose = pose.to_pose()?;
                let v = finite3(velocity)?;
                Ok(Reply::Wrench(WrenchMsg::from(&st.measure(&pose, v))))
            }
        }
    }

    pub fn trajectory_method(
        &mut self,
        name: &str,
        m: TrajectoryMethod,
    ) -> Result<Reply, WireError> {
        let o = self.expect_class(name, Class::Trajectory)?;
        let t = match &o.body {
            Body::Trajectory(t) => t,
            Body::Teleop(_) => {
                return Err(WireError::Unsupported {
                    kind: o.kind.as_str().into(),
                    method: format!(
                        "{m:?} (a teleoperation channel's reference is what the other side sends)"
                    ),
                });
            }
            _ => return Err(WireError::Internal("trajectory body".into())),
        };
        let spec = t.spec.clone();
        let kind = o.kind.as_str();
        // Standalone: started at t = 0 from zero joints of the goal's length; a goal that names
        // a pose needs a robot (the one of a controller using it).
        let robot_model = self
            .objects
            .values()
            .find_map(|c| match &c.body {
                Body::Controller(x) if x.trajectory.as_deref() == Some(name) => x.robot.clone(),
                _ => None,
            })
            .and_then(|r| self.robot(&r).ok().map(|r| r.model.clone()));
        let mut traj = match &robot_model {
            Some(m) => build_trajectory(&spec, m, kind)?,
            None => build_standalone(&spec, kind)?,
        };
        let n = robot_model
            .as_ref()
            .map_or_else(|| spec_joints(&spec), |m| m.joint_count());
        use penelope_hal::Trajectory;
        traj.start(
            Timestamp::ZERO,
            &penelope_hal::Reference::Joint(penelope_hal::JointReference::default()),
        );
        match m {
            TrajectoryMethod::Duration => Ok(Reply::Duration(match &spec {
                TrajectorySpec::Step { delay, .. } => Some(delay.as_secs_f64()),
                TrajectorySpec::Ramp { duration, .. } => Some(duration.as_secs_f64()),
                _ => traj.duration().map(|d| d.as_secs_f64()),
            })),
            TrajectoryMethod::Reference { t_s } => {
                if !(t_s.is_finite() && (0.0..=1e6).contains(&t_s)) {
                    return Err(bad_arg("t_s must be finite, 0..=1e6"));
                }
                let r = traj
                    .reference(Timestamp::ZERO + Duration::from_secs_f64(t_s))
                    .map_err(|e| not_ready(e.to_string()))?;
                Ok(Reply::Reference(match r {
                    penelope_hal::Reference::Joint(j) => ReferenceMsg::Joint {
                        q: joints_from_vector(&j.position, n),
                        qd: joints_from_vector(&j.velocity, n),
                    },
                    penelope_hal::Reference::Cartesian(c) => ReferenceMsg::Cartesian {
                        pose: PoseMsg::from(&c.pose),
                    },
                    penelope_hal::Reference::Wrench(w) => ReferenceMsg::Wrench {
                        wrench: WrenchMsg::from(&w),
                    },
                    penelope_hal::Reference::Hybrid(h) => ReferenceMsg::Cartesian {
                        pose: PoseMsg::from(&h.motion.pose),
                    },
                }))
            }
        }
    }

    /// Controller methods other than the lifecycle (the creator handles those).
    pub fn controller_method(
        &mut self,
        name: &str,
        m: ControllerMethod,
    ) -> Result<Reply, WireError> {
        let o = self.expect_class(name, Class::Controller)?;
        let state = o.shown_state();
        let kind = o.kind;
        let set_guard = |what: &str| -> Result<(), WireError> {
            if state == LifecycleState::Active {
                Err(not_ready(format!(
                    "deactivate `{name}` before changing its {what}"
                )))
            } else {
                Ok(())
            }
        };
        match m {
            ControllerMethod::SetRobot { robot } => {
                set_guard("robot")?;
                crate::proto::check_name(&robot)?;
                self.controller_mut(name)?.robot = Some(robot);
                Ok(Reply::Unit)
            }
            ControllerMethod::SetTrajectory { trajectory } => {
                set_guard("trajectory")?;
                crate::proto::check_name(&trajectory)?;
                self.controller_mut(name)?.trajectory = Some(trajectory);
                Ok(Reply::Unit)
            }
            ControllerMethod::SetSensor { sensor } => {
                set_guard("sensor")?;
                if let Some(path) = sensor.strip_prefix('/') {
                    for part in path.split('/') {
                        crate::proto::check_name(part)?;
                    }
                } else {
                    crate::proto::check_name(&sensor)?;
                }
                self.controller_mut(name)?.sensor = Some(sensor);
                Ok(Reply::Unit)
            }
            ControllerMethod::SetGains { gains } => {
                let c = self.controller_mut(name)?;
                let k = kind.as_str();
                let update = match &mut c.config {
                    ControllerConfig::Pid(_) => {
                        let new: JointPidConfig = kinds::parse(k, &gains)?;
                        new.check(k)?;
                        let n = c.robot.clone().and_then(|r| {
                            self.robot(&r)
                                .ok()
                                .map(|r| (r.model.joint_count(), r.model.clone()))
                        });
                        let c = self.controller_mut(name)?;
                        let ControllerConfig::Pid(p) = &mut c.config else {
                            unreachable_body()?
                        };
                        merge_pid(p, &new, &gains);
                        match n {
                            Some((n, model)) if c.running.is_some() => {
                                let mut kp = JointVector::zeros();
                                let mut kd = JointVector::zeros();
                                for j in 0..n {
                                    kp[j] = 10.0 * finite_effort(&model, j);
                                    kd[j] = 0.5 * finite_effort(&model, j);
                                }
                                Some(GainsUpdate::Pid(pid_gains(p, k, n, kp, kd)?))
                            }
                            _ => None,
                        }
                    }
                    ControllerConfig::Position(_) => {
                        return Err(WireError::Unsupported {
                            kind: k.to_string(),
                            method:
                                "set-gains (its only setting, max_velocity, is fixed at creation)"
                                    .into(),
                        });
                    }
                    ControllerConfig::ForceDisplay(_)
                    | ControllerConfig::PositionError(_)
                    | ControllerConfig::Tracking(..) => {
                        let text = merged_gains(k, &c.config_text, &gains)?;
                        let (config, update) = teleop_gains(k, &c.config, &text)?;
                        c.config = config;
                        c.config_text = text;
                        Some(update)
                    }
                    ControllerConfig::Impedance(i) => {
                        let new: ImpedanceConfigToml = kinds::parse(k, &gains)?;
                        new.check(k)?;
                        merge_impedance(i, &new, &gains);
                        Some(GainsUpdate::Impedance(impedance(i)))
                    }
                };
                let c = self.controller_mut(name)?;
                if let (Some(u), Some(run)) = (update, c.running.as_mut()) {
                    run.gains.write(u);
                }
                Ok(Reply::Unit)
            }
            ControllerMethod::EStop => {
                let c = self.controller_mut(name)?;
                let run = c
                    .running
                    .as_mut()
                    .ok_or_else(|| not_ready(format!("controller `{name}` is not running")))?;
                run.commands
                    .push(ControlCommand::EStop)
                    .map_err(|_| not_ready("command queue full; retry"))?;
                Ok(Reply::Unit)
            }
            // Re-arming may start threads: the creator's job (`Creator::rearm`).
            ControllerMethod::Rearm => {
                Err(WireError::Internal("rearm is served by the creator".into()))
            }
            ControllerMethod::Status => {
                let joints = self
                    .controller_mut(name)?
                    .robot
                    .clone()
                    .and_then(|r| self.robot(&r).ok().map(|r| r.model.joint_count()))
                    .unwrap_or(MAX_JOINTS);
                let c = self.controller_mut(name)?;
                let (running, ticks, overruns, dropped, last) = match c.running.as_mut() {
                    Some(run) => {
                        let newest = run.shared.newest().map(|n| n.sample);
                        let overruns = run.overruns();
                        (
                            true,
                            newest.map_or(0, |s| s.seq),
                            overruns,
                            run.shared
                                .dropped
                                .load(std::sync::atomic::Ordering::Relaxed),
                            newest,
                        )
                    }
                    None => (false, c.last.map_or(0, |s| s.seq), 0, 0, c.last),
                };
                Ok(Reply::Status(ControlStatus {
                    state,
                    running,
                    ticks,
                    overruns,
                    telemetry_dropped: dropped,
                    last: last.map(|s| super::runtime::record(&s, joints)),
                }))
            }
        }
    }
}

/// The keys of every loop (fixed while the loop runs).
const LOOP_TIMING_KEYS: [&str; 6] = [
    "period_us",
    "comm_period_us",
    "watchdog_ms",
    "sensor_period_ms",
    "sensor_timeout_ms",
    "telemetry_period_ms",
];

/// `current` (a configuration's TOML text) with the keys of `gains` replaced: refused for loop
/// timing keys (set at creation) and for text that is not a TOML table.
fn merged_gains(kind: &str, current: &str, gains: &str) -> Result<String, WireError> {
    let bad = |message: String| WireError::BadConfig {
        kind: kind.into(),
        message,
    };
    let new: toml::Table = gains
        .parse()
        .map_err(|e: toml::de::Error| bad(e.message().to_string()))?;
    if let Some(k) = new.keys().find(|k| LOOP_TIMING_KEYS.contains(&k.as_str())) {
        return Err(bad(format!(
            "`{k}` is a loop timing key, set at creation; set-gains changes gains"
        )));
    }
    let mut table: toml::Table = current
        .parse()
        .map_err(|e: toml::de::Error| bad(e.message().to_string()))?;
    table.extend(new);
    Ok(table.to_string())
}

/// A teleoperation law's configuration from `text`, checked, and the update for its loop.
fn teleop_gains(
    kind: &str,
    current: &ControllerConfig,
    text: &str,
) -> Result<(ControllerConfig, GainsUpdate), WireError> {
    Ok(match current {
        ControllerConfig::ForceDisplay(_) => {
            let cfg: ForceDisplayToml = kinds::parse(kind, text)?;
            let law = cfg.law(kind)?;
            (
                ControllerConfig::ForceDisplay(cfg),
                GainsUpdate::ForceDisplay(*law.config()),
            )
        }
        ControllerConfig::PositionError(_) => {
            let cfg: PositionErrorToml = kinds::parse(kind, text)?;
            let law = cfg.law(kind)?;
            (
                ControllerConfig::PositionError(cfg),
                GainsUpdate::PositionError(*law.config()),
            )
        }
        ControllerConfig::Tracking(_, servo) => {
            let cfg: SlaveTrackingToml = kinds::parse(kind, text)?;
            let law = cfg.law(kind, *servo)?;
            (
                ControllerConfig::Tracking(cfg, *servo),
                GainsUpdate::Tracking(*law.config()),
            )
        }
        _ => return Err(WireError::Internal("not a teleoperation law".into())),
    })
}

/// The default gains a loop on a simulated body holds its pose with.
fn slave_hold(model: &DhRobotModel, n: usize) -> (JointVector, JointVector) {
    let mut kp = JointVector::zeros();
    let mut kd = JointVector::zeros();
    for j in 0..n {
        kp[j] = 10.0 * finite_effort(model, j);
        kd[j] = 0.5 * finite_effort(model, j);
    }
    (kp, kd)
}

/// Checks that the controller on `robot` may run `side` of channel `name`, and that the end is
/// free.
fn check_teleop_end(name: &str, t: &TeleopObj, side: Side, robot: &str) -> Result<(), WireError> {
    let (expected, word) = match side {
        Side::Master => (&t.config.master, "master"),
        Side::Slave => (&t.config.slave, "slave"),
    };
    if expected != robot {
        return Err(bad_arg(format!(
            "this law is a {word} half, and the {word} of `{name}` is `{expected}`, not `{robot}`"
        )));
    }
    let link = t
        .link
        .as_ref()
        .ok_or_else(|| not_ready(format!("channel `{name}` is not configured")))?;
    let free = match side {
        Side::Master => link.master.is_some(),
        Side::Slave => link.slave.is_some(),
    };
    if !free {
        return Err(not_ready(format!(
            "the {word} end of `{name}` is held by a running loop"
        )));
    }
    Ok(())
}

fn unreachable_body<T>() -> Result<T, WireError> {
    Err(WireError::Internal("object body changed".into()))
}

fn finite3(v: [f64; 3]) -> Result<Vector3<f64>, WireError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(Vector3::from(v))
    } else {
        Err(bad_arg("velocity has a NaN or infinite value"))
    }
}

/// Everything an activation built, before threads start.
pub(crate) struct Built {
    pub control: ControlTask,
    pub comm: super::runtime::CommTask,
    pub telemetry: penelope_rt_core::ring::ArcConsumer<
        penelope_rt_core::telemetry::TelemetrySample,
        { super::runtime::TELEMETRY_CAPACITY },
    >,
    pub commands:
        penelope_rt_core::ring::ArcProducer<ControlCommand, { super::runtime::COMMAND_CAPACITY }>,
    pub goto: penelope_rt_core::ring::ArcProducer<GoToCommand, { super::runtime::GOTO_CAPACITY }>,
    pub gains: penelope_rt_core::cell::ArcLatestWriter<GainsUpdate>,
    pub probe:
        penelope_rt_core::cell::ArcLatestReader<penelope_rt_core::telemetry::TelemetrySample>,
    pub wrench: Option<
        penelope_rt_core::cell::ArcLatestWriter<
            penelope_rt_core::cell::Stamped<penelope_hal::Wrench>,
        >,
    >,
    pub source: Option<super::runtime::SensorSource>,
    pub model: RobotKinematics,
    pub joints: usize,
    pub timing: LoopTiming,
}

fn pid_gains(
    p: &JointPidConfig,
    kind: &str,
    n: usize,
    kp_default: JointVector,
    kd_default: JointVector,
) -> Result<JointPidGains, WireError> {
    let kp = match &p.kp {
        Some(k) => k.resolve(kind, "kp", n, 0.0, 1e7)?,
        None => kp_default,
    };
    let kd = match &p.kd {
        Some(k) => k.resolve(kind, "kd", n, 0.0, 1e6)?,
        None => kd_default,
    };
    Ok(JointPidGains {
        kp,
        ki: p.ki.resolve(kind, "ki", n, 0.0, 1e7)?,
        kd,
        integral_limit: p
            .integral_limit
            .resolve(kind, "integral_limit", n, 0.0, 1e5)?,
        gravity_compensation: p.gravity_compensation,
        acceleration_feedforward: p.acceleration_feedforward,
    })
}

/// Keys present in `text` replace those of `into`.
fn merge_pid(into: &mut JointPidConfig, new: &JointPidConfig, text: &str) {
    let has = |k: &str| text.lines().any(|l| l.trim_start().starts_with(k));
    if has("kp") {
        into.kp = new.kp.clone();
    }
    if has("ki") {
        into.ki = new.ki.clone();
    }
    if has("kd") {
        into.kd = new.kd.clone();
    }
    if has("integral_limit") {
        into.integral_limit = new.integral_limit.clone();
    }
    if has("gravity_compensation") {
        into.gravity_compensation = new.gravity_compensation;
    }
    if has("acceleration_feedforward") {
        into.acceleration_feedforward = new.acceleration_feedforward;
    }
}

fn merge_impedance(into: &mut ImpedanceConfigToml, new: &ImpedanceConfigToml, text: &str) {
    let has = |k: &str| text.lines().any(|l| l.trim_start().starts_with(k));
    if has("stiffness") {
        into.stiffness = new.stiffness;
    }
    if has("damping") {
        into.damping = new.damping;
    }
    if has("gravity_compensation") {
        into.gravity_compensation = new.gravity_compensation;
    }
    if has("max_force") {
        into.max_force = new.max_force;
    }
    if has("max_torque") {
        into.max_torque = new.max_torque;
    }
    if has("ramp_in_ms") {
        into.ramp_in_ms = new.ramp_in_ms;
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

fn goal_vector(g: &GoalConfig, model: &DhRobotModel, kind: &str) -> Result<JointVector, WireError> {
    match g {
        GoalConfig::Pose(p) => Ok(model.named_pose(*p)),
        GoalConfig::Joints(q) => {
            joints_to_vector(q, model.joint_count()).map_err(|_| WireError::BadConfig {
                kind: kind.into(),
                message: format!(
                    "goal has {} values, the robot has {} joints",
                    q.len(),
                    model.joint_count()
                ),
            })
        }
    }
}

fn spec_joints(spec: &TrajectorySpec) -> usize {
    let of = |g: &GoalConfig| match g {
        GoalConfig::Joints(q) => q.len(),
        GoalConfig::Pose(_) => MAX_JOINTS,
    };
    match spec {
        TrajectorySpec::Step { goal, .. }
        | TrajectorySpec::Ramp { goal, .. }
        | TrajectorySpec::Trapezoidal { goal, .. } => of(goal),
        TrajectorySpec::Spline { waypoints, .. } => {
            waypoints.first().map_or(MAX_JOINTS, |w| of(&w.1))
        }
    }
}

fn build_standalone(spec: &TrajectorySpec, kind: &str) -> Result<NodeTrajectory, WireError> {
    let uses_pose = |g: &GoalConfig| matches!(g, GoalConfig::Pose(_));
    let any_pose = match spec {
        TrajectorySpec::Step { goal, .. }
        | TrajectorySpec::Ramp { goal, .. }
        | TrajectorySpec::Trapezoidal { goal, .. } => uses_pose(goal),
        TrajectorySpec::Spline { waypoints, .. } => waypoints.iter().any(|w| uses_pose(&w.1)),
    };
    if any_pose {
        return Err(not_ready(
            "the goal is a named pose: bind the trajectory to a controller with a robot first",
        ));
    }
    // A robot-less model of the goal's length: joints only, so any model of that many joints
    // gives the same result; use a PUMA 560 for six and below.
    let model = models::puma560();
    let n = spec_joints(spec);
    let pad = |g: &GoalConfig| match g {
        GoalConfig::Joints(q) => {
            let mut v = q.clone();
            v.resize(model.joint_count().max(n), 0.0);
            GoalConfig::Joints(v)
        }
        other => other.clone(),
    };
    let padded = match spec {
        TrajectorySpec::Step { goal, delay } => TrajectorySpec::Step {
            goal: pad(goal),
            delay: *delay,
        },
        TrajectorySpec::Ramp { goal, duration } => TrajectorySpec::Ramp {
            goal: pad(goal),
            duration: *duration,
        },
        TrajectorySpec::Trapezoidal {
            goal,
            velocity,
            acceleration,
        } => TrajectorySpec::Trapezoidal {
            goal: pad(goal),
            velocity: match velocity {
                kinds::PerJoint::Each(v) if v.len() == n => {
                    let mut v = v.clone();
                    v.resize(model.joint_count(), 1.0);
                    kinds::PerJoint::Each(v)
                }
                other => other.clone(),
            },
            acceleration: match acceleration {
                kinds::PerJoint::Each(v) if v.len() == n => {
                    let mut v = v.clone();
                    v.resize(model.joint_count(), 1.0);
                    kinds::PerJoint::Each(v)
                }
                other => other.clone(),
            },
        },
        TrajectorySpec::Spline { clamped, waypoints } => TrajectorySpec::Spline {
            clamped: *clamped,
            waypoints: waypoints.iter().map(|(t, g)| (*t, pad(g))).collect(),
        },
    };
    build_trajectory(&padded, &model, kind)
}

/// The trajectory `spec` for `model` (named poses resolved, lengths checked).
pub(crate) fn build_trajectory(
    spec: &TrajectorySpec,
    model: &DhRobotModel,
    kind: &str,
) -> Result<NodeTrajectory, WireError> {
    let n = model.joint_count();
    let cfg_err = |e: penelope_rt_core::trajectory::TrajectoryConfigError| WireError::BadConfig {
        kind: kind.into(),
        message: e.to_string(),
    };
    Ok(match spec {
        TrajectorySpec::Step { goal, delay } => NodeTrajectory::Step(
            Step::joint(goal_vector(goal, model, kind)?)
                .map_err(cfg_err)?
                .with_delay(*delay),
        ),
        TrajectorySpec::Ramp { goal, duration } => NodeTrajectory::Ramp(
            Ramp::joint(goal_vector(goal, model, kind)?, *duration).map_err(cfg_err)?,
        ),
        TrajectorySpec::Trapezoidal {
            goal,
            velocity,
            acceleration,
        } => {
            let mut v = velocity.resolve(kind, "max_velocity", n, 1e-4, 20.0)?;
            let mut a = acceleration.resolve(kind, "max_acceleration", n, 1e-4, 200.0)?;
            for j in n..MAX_JOINTS {
                v[j] = 1.0;
                a[j] = 1.0;
            }
            NodeTrajectory::Trapezoidal(
                Trapezoidal::joint(goal_vector(goal, model, kind)?, v, a).map_err(cfg_err)?,
            )
        }
        TrajectorySpec::Spline { clamped, waypoints } => {
            let mut w = Vec::with_capacity(waypoints.len());
            for (at, g) in waypoints {
                w.push(Waypoint {
                    at: *at,
                    goal: Goal::Joint(goal_vector(g, model, kind)?),
                });
            }
            let ends = if *clamped {
                SplineEnds::Clamped
            } else {
                SplineEnds::Natural
            };
            NodeTrajectory::Spline(CubicSpline::new(&w, ends).map_err(cfg_err)?)
        }
    })
}

/// Opens a Galil board.
fn open_galil(cfg: &GalilConfig) -> Result<GalilBoard, WireError> {
    let volts = cfg.volts();
    let path = cfg.device.clone().unwrap_or_else(|| "tcp".into());
    let mut board_cfg = GalilBoardConfig::new(path.clone(), cfg.axes as usize, &volts);
    board_cfg.serial.baud = cfg.baud;
    board_cfg.watchdog = (cfg.watchdog_ms > 0).then(|| Duration::from_millis(cfg.watchdog_ms));
    let result = match &cfg.address {
        Some(address) => {
            let address = address.clone();
            let timeout = Duration::from_millis(cfg.connect_timeout_ms);
            let factory: LinkFactory = Box::new(move || {
                use std::net::ToSocketAddrs;
                let addr = address
                    .to_socket_addrs()
                    .map_err(|e| penelope_drivers::galil::GalilError::Io(e.kind()))?
                    .next()
                    .ok_or(penelope_drivers::galil::GalilError::Closed)?;
                let stream = std::net::TcpStream::connect_timeout(&addr, timeout)
                    .map_err(|e| penelope_drivers::galil::GalilError::Io(e.kind()))?;
                TcpLink::new(stream).map(|l| Box::new(l) as Box<dyn Link + Send>)
            });
            GalilBoard::with_link_factory(board_cfg, factory)
        }
        None => GalilBoard::open(board_cfg),
    };
    let place = cfg
        .address
        .as_deref()
        .or(cfg.device.as_deref())
        .unwrap_or("?")
        .to_string();
    let board = result.map_err(|e| WireError::Device(format!("galil board at {place}: {e}")))?;
    // Configured means ready: wait for the I/O thread's first exchange, so the encoders can be
    // read as soon as `configure` returns.
    let deadline = std::time::Instant::now() + FIRST_EXCHANGE_TIMEOUT;
    while board.cycles() == 0 {
        if board.is_faulted() || std::time::Instant::now() >= deadline {
            return Err(WireError::Device(format!(
                "galil board at {place}: no answer within {} ms",
                FIRST_EXCHANGE_TIMEOUT.as_millis()
            )));
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    Ok(board)
}

/// How long `configure` of a Galil board waits for the first exchange with the controller.
const FIRST_EXCHANGE_TIMEOUT: Duration = Duration::from_secs(2);
