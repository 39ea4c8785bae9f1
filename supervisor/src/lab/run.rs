//! The teleoperation run a lab configuration describes: two robots, each with a communication
//! thread and a control thread, on the real-time executor or on a simulated clock.
//!
//! ```text
//!  operator hand ──> FRHC plant ── sim board ──> master control (T_ctrl) ──telemetry──┐
//!                                      ^             ^ reference cell                 │
//!                                      │             │                                v
//!                           master comm (T_com): channel slave->master  <── link ── slave comm
//!                                      │ link (master pose, clutch)                   ^
//!                                      v                                              │
//!                           slave comm (T_com): channel master->slave ──> slave control ──> PUMA
//!                                                                   wrist sensor <── wall ┘
//! ```
//!
//! The links between the two sides are lock-free latest-value cells: the newest sample wins, as
//! on the UDP data plane between nodes.

use std::time::Duration;

use nalgebra::{UnitQuaternion, Vector3};
use penelope_drivers::model as models;
use penelope_drivers::sim::board::{SimBoard, SimBoardConfig};
use penelope_drivers::sim::environment::{ContactModel, Environment, Shape};
use penelope_drivers::sim::force_sensor::{ForceSensorConfig, VirtualForceSensor};
use penelope_drivers::sim::operator::{HandImpedance, OperatorScript, VirtualOperator};
use penelope_drivers::sim::plant::PlantConfig;
use penelope_drivers::sim::tap::{TapReader, TapSample, TapWriter};
use penelope_hal::{
    CartesianReference, Controller, Frame, HybridReference, JointVector, Kinematics, NamedPose,
    Pose, Reference, RobotModel, Timestamp, Trajectory, Twist, Wrench,
};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Fresh, Stamped, latest};
use penelope_rt_core::comm::CommLoop;
use penelope_rt_core::control::{
    ControlCommand, ControlConfig, ControlLoop, ControlPorts, NoSensor,
};
use penelope_rt_core::ring::{ArcConsumer, ArcProducer, ring};
use penelope_rt_core::safety::{HoldMode, SafetyConfig};
use penelope_rt_core::sim::{Flow, SimRunner, SimTask};
use penelope_rt_core::telemetry::{TelemetrySample, TelemetrySink};
use penelope_rt_core::teleop::{
    CartesianImpedance, ChannelConfig, ChannelDirection, ForceDisplay, ForceDisplayConfig,
    ImpedanceConfig, MappingConfig, PositionErrorMaster, SlaveTracking, TeleopChannel,
    TeleopSample, TrackingConfig, TrackingOutput,
};

use super::config::{
    BoardKind, ConfigError, ControllerKind, KinematicsChoice, LabConfig, Law, Role, ShapeKind,
};
use super::devices::{GalilSetup, LabBoard, LinkMonitor, galil_board};
use crate::objects::kinematics::RobotKinematics;
use penelope_drivers::sim::ToolContact;
use penelope_drivers::sim::scripts as script;

/// Samples buffered between a control thread and the logger.
pub const TELEMETRY_CAPACITY: usize = 8192;

/// Commands buffered towards a control thread.
pub const COMMAND_CAPACITY: usize = 16;

/// How the loops are clocked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockMode {
    /// SCHED_FIFO threads on `CLOCK_MONOTONIC`, in real time.
    RealTime,
    /// The same loops stepped in timestamp order on a simulated clock: faster than real time and
    /// bit-for-bit reproducible for a given seed.
    Simulated,
}

/// What to run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunOptions {
    /// Length of the run (default: the operator script's length).
    pub duration: Option<Duration>,
    /// The bilateral law (default: the configuration's).
    pub law: Option<Law>,
    /// Position scale (default: the configuration's).
    pub scale: Option<f64>,
    /// Seed of every random source (sensor noise).
    pub seed: u64,
    /// Real-time or simulated clock.
    pub clock: ClockMode,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            duration: None,
            law: None,
            scale: None,
            seed: 1,
            clock: ClockMode::Simulated,
        }
    }
}

/// One control tick of one robot, with the plant's ground truth at that instant (simulated
/// boards only).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LabSample {
    /// What the control loop reported.
    pub telemetry: TelemetrySample,
    /// The simulated plant's true state.
    pub truth: Option<TapSample>,
}

/// The control loop's telemetry port in a lab: every sample goes to the logger's ring (with the
/// plant's truth) and to a latest-value cell the robot's communication thread reads.
pub struct LabSink {
    ring: ArcProducer<LabSample, TELEMETRY_CAPACITY>,
    state: ArcLatestWriter<TelemetrySample>,
    truth: Option<TapReader>,
}

impl TelemetrySink for LabSink {
    fn push(&mut self, sample: &TelemetrySample) -> bool {
        self.state.write(*sample);
        let truth = self.truth.as_mut().and_then(TapReader::latest);
        self.ring
            .push(LabSample {
                telemetry: *sample,
                truth,
            })
            .is_ok()
    }
}

/// Why a run could not start.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The configuration cannot be built.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A component refused its settings.
    #[error("{0}")]
    Setup(String),
    /// A real-time thread failed.
    #[error("real-time thread: {0}")]
    Thread(String),
}

fn setup<E: std::fmt::Display>(what: &str) -> impl FnOnce(E) -> RunError + '_ {
    move |e| RunError::Setup(format!("{what}: {e}"))
}

type ControllerBox = Vec<Box<dyn Controller + Send>>;
type RefReader = ArcLatestReader<Stamped<Reference>>;
type RefWriter = ArcLatestWriter<Stamped<Reference>>;
type Commands = ArcConsumer<ControlCommand, COMMAND_CAPACITY>;
type Link = (ArcLatestWriter<TeleopSample>, ArcLatestReader<TeleopSample>);

/// Everything a built lab hands to its four loops and its logger.
struct Built {
    start: Timestamp,
    end: Timestamp,
    control_period: Duration,
    comm_period: Duration,
    master: ControlLoop<
        LabBoard,
        RobotKinematics,
        ControllerBox,
        RefReader,
        LabSink,
        Commands,
        NoSensor,
    >,
    slave: SlaveLoop,
    master_comm: MasterComm,
    slave_comm: SlaveComm,
    master_log: ArcConsumer<LabSample, TELEMETRY_CAPACITY>,
    slave_log: ArcConsumer<LabSample, TELEMETRY_CAPACITY>,
    info: RunInfo,
}

/// The slave's control loop: with the virtual wrist sensor (a simulated plant behind its board),
/// or without a sensor (a Galil board: no plant in this process for a virtual sensor to read, so
/// the loop has no sensor slot rather than one failing every tick).
enum SlaveLoop {
    Sensed(
        Box<
            ControlLoop<
                LabBoard,
                RobotKinematics,
                ControllerBox,
                RefReader,
                LabSink,
                Commands,
                VirtualForceSensor,
            >,
        >,
    ),
    Unsensed(
        Box<
            ControlLoop<
                LabBoard,
                RobotKinematics,
                ControllerBox,
                RefReader,
                LabSink,
                Commands,
                NoSensor,
            >,
        >,
    ),
}

impl SlaveLoop {
    /// # Real-time
    /// As [`ControlLoop::tick`].
    fn tick(&mut self, now: Timestamp) {
        match self {
            SlaveLoop::Sensed(l) => {
                l.tick(now);
            }
            SlaveLoop::Unsensed(l) => {
                l.tick(now);
            }
        }
    }

    /// # Real-time
    /// Constant time.
    fn note_timing(&mut self, wake_latency: Duration, exec_time: Duration) {
        match self {
            SlaveLoop::Sensed(l) => l.note_timing(wake_latency, exec_time),
            SlaveLoop::Unsensed(l) => l.note_timing(wake_latency, exec_time),
        }
    }
}

/// What a run was, for its report.
#[derive(Clone, Debug)]
pub struct RunInfo {
    /// The lab's name.
    pub lab: String,
    /// The law in use.
    pub law: Law,
    /// Position scale.
    pub scale: f64,
    /// Force gain.
    pub force_gain: f64,
    /// Seed.
    pub seed: u64,
    /// Clock mode.
    pub clock: ClockMode,
    /// Start instant (the clock's).
    pub start: Timestamp,
    /// Control period.
    pub control_period: Duration,
    /// Communication period.
    pub comm_period: Duration,
    /// The operator's script.
    pub script: OperatorScript,
    /// The master's model, for post-processing poses.
    pub master_model: RobotKinematics,
    /// The slave's model.
    pub slave_model: RobotKinematics,
    /// The environment.
    pub environment: Environment,
    /// The sensor's mount in the slave's tool frame.
    pub sensor_mount: Pose,
    /// `R_ms`: master base frame to slave base frame.
    pub rotation: UnitQuaternion<f64>,
    /// The slave's Galil board link counters (exchange rate), when the slave is on a Galil
    /// board.
    pub slave_link: Option<LinkMonitor>,
}

/// The master's communication thread: sends the master pose and clutch, feeds the slave's
/// samples into the master's channel.
struct MasterComm {
    comm: CommLoop<TeleopChannel, RefWriter>,
    model: RobotKinematics,
    state: ArcLatestReader<TelemetrySample>,
    to_slave: ArcLatestWriter<TeleopSample>,
    from_slave: ArcLatestReader<TeleopSample>,
    script: OperatorScript,
    start: Timestamp,
    sequence: u64,
}

impl MasterComm {
    fn tick(&mut self, now: Timestamp) {
        if let Some(sample) = self.state.latest() {
            let pose = self.model.forward(&sample.q);
            let clutch = self.script.clutch(now - self.start);
            self.comm.trajectory_mut().track_master(now, &pose, clutch);
            self.sequence += 1;
            let reference = Reference::Cartesian(CartesianReference {
                pose,
                twist: Twist::default(),
            });
            self.to_slave.write(TeleopSample {
                sequence: self.sequence,
                sent: now,
                clutch,
                reference,
            });
        }
        if let Fresh::New(sample) = self.from_slave.read() {
            // A stale or malformed sample is counted by the channel and dropped.
            let _ = self.comm.trajectory_mut().receive(sample);
        }
        self.comm.tick(now);
    }
}

/// The slave's communication thread: feeds the master's samples into the slave's channel, sends
/// the slave's pose and sensor wrench (base frame) back.
struct SlaveComm {
    comm: CommLoop<TeleopChannel, RefWriter>,
    model: RobotKinematics,
    state: ArcLatestReader<TelemetrySample>,
    to_master: ArcLatestWriter<TeleopSample>,
    from_master: ArcLatestReader<TeleopSample>,
    sensor_mount: Pose,
    sequence: u64,
}

impl SlaveComm {
    fn tick(&mut self, now: Timestamp) {
        if let Fresh::New(sample) = self.from_master.read() {
            let _ = self.comm.trajectory_mut().receive(sample);
        }
        self.comm.tick(now);
        if let Some(sample) = self.state.latest() {
            let pose = self.model.forward(&sample.q);
            let wrench = sensor_to_base(&sample.wrench, &self.sensor_mount, &pose);
            self.sequence += 1;
            let reference = Reference::Hybrid(HybridReference {
                motion: CartesianReference {
                    pose,
                    twist: Twist::default(),
                },
                wrench,
                force_axes: [true; 6],
            });
            self.to_master.write(TeleopSample {
                sequence: self.sequence,
                sent: now,
                clutch: false,
                reference,
            });
        }
    }
}

/// A wrist-sensor reading (sensor frame) as a wrench in the robot's base frame about the tool
/// origin.
pub fn sensor_to_base(reading: &Wrench, mount: &Pose, tool: &Pose) -> Wrench {
    let in_tool = reading.expressed_in(&mount.inverse(), Frame::Tool);
    Wrench {
        force: tool.rotation * in_tool.force,
        torque: tool.rotation * in_tool.torque,
        frame: Frame::Base,
    }
}

fn load_model(name: &str) -> Result<models::DhRobotModel, RunError> {
    if let Some(m) = models::by_name(name) {
        return Ok(m);
    }
    models::from_file(name).map_err(setup(&format!("robot model `{name}`")))
}

fn start_pose(model: &models::DhRobotModel, name: &str) -> Result<JointVector, RunError> {
    NamedPose::parse(name)
        .map(|p| model.named_pose(p))
        .ok_or_else(|| RunError::Setup(format!("unknown named pose `{name}` (nest, start, work)")))
}

/// Encoder counts per radian, DAC full scale and on-board servo gains of a simulated board for
/// `model`: counts from the model file, full scale from the joint torque limits.
fn sim_board_config(model: &models::DhRobotModel, dac_bits: u32) -> SimBoardConfig {
    let n = model.joint_count();
    let mut counts = JointVector::repeat(1.0);
    for j in 0..n {
        counts[j] = model.counts_per_radian(j);
    }
    let limits = *model.limits();
    let full_scale = limits
        .effort_max
        .map(|e| if e.is_finite() { e } else { 100.0 });
    SimBoardConfig {
        counts_per_radian: counts,
        effort_full_scale: full_scale,
        dac_bits,
        position_kp: full_scale * 200.0,
        position_kd: full_scale * 4.0,
        velocity_cutoff_hz: 150.0,
    }
}

fn build(lab: &LabConfig, options: &RunOptions, start: Timestamp) -> Result<Built, RunError> {
    let law = options.law.unwrap_or(lab.teleop.law);
    let scale = options.scale.unwrap_or(lab.teleop.scale);
    if !(scale.is_finite() && scale > 0.0) {
        return Err(RunError::Setup(format!(
            "scale must be positive, got {scale}"
        )));
    }
    let control_period = Duration::from_micros(lab.timing.control_period_us);
    let comm_period = Duration::from_micros(lab.timing.comm_period_us);
    let watchdog = Duration::from_millis(lab.timing.watchdog_ms);
    let script = script::by_name(&lab.operator.script).ok_or_else(|| {
        RunError::Setup(format!("unknown operator script `{}`", lab.operator.script))
    })?;
    let duration = options.duration.unwrap_or(script.duration());

    let (master_name, master_cfg) = lab.robot_with_role(Role::Master)?;
    let (slave_name, slave_cfg) = lab.robot_with_role(Role::Slave)?;
    let master_model = load_model(&master_cfg.model)?;
    let slave_model = load_model(&slave_cfg.model)?;
    let q_master = start_pose(&master_model, &master_cfg.start)?;
    let q_slave = start_pose(&slave_model, &slave_cfg.start)?;
    // A slave on a Galil board starts where its encoders say (encoder zero is the `start` pose:
    // see `devices::galil_board`); there is no plant behind it, so no ground truth and no
    // virtual wrist sensor.
    let slave_galil = open_slave_galil(lab, slave_name, &slave_model, &q_slave, options, start)?;
    let q_slave = slave_galil.as_ref().map_or(q_slave, |g| g.measured);
    let slave_on_galil = slave_galil.is_some();
    let master_tool = master_model.forward(&q_master);
    let slave_tool = slave_model.forward(&q_slave);
    // What the controllers compute with: float kinematics, or the FPGA model where configured.
    // The plants behind the simulated boards are physics and always use the float model.
    let master_kin = RobotKinematics::new(
        master_model.clone(),
        master_cfg.kinematics == KinematicsChoice::Fpga,
    )
    .map_err(setup(master_name))?;
    let slave_kin = RobotKinematics::new(
        slave_model.clone(),
        slave_cfg.kinematics == KinematicsChoice::Fpga,
    )
    .map_err(setup(slave_name))?;

    // The slave's environment, placed relative to its start tool point.
    let mut environment = Environment::new();
    for shape in &lab.environment.shapes {
        let point = slave_tool.translation.vector + Vector3::from(shape.point_m);
        let geometry = match shape.kind {
            ShapeKind::Plane => {
                let n = Vector3::from(shape.normal.unwrap_or([0.0, 0.0, 1.0]));
                Shape::Plane {
                    point,
                    normal: nalgebra::Unit::new_normalize(n),
                }
            }
            ShapeKind::Sphere => Shape::Sphere {
                center: point,
                radius: shape.radius_m.unwrap_or(0.05),
            },
        };
        environment = environment
            .with(ContactModel {
                shape: geometry,
                stiffness: shape.stiffness_n_per_m,
                damping: shape.damping_ns_per_m,
            })
            .map_err(|_| RunError::Setup("too many environment shapes".into()))?;
    }

    let hand = HandImpedance {
        stiffness: lab.operator.hand_stiffness_n_per_m,
        damping: lab.operator.hand_damping_ns_per_m,
        ..HandImpedance::default()
    };
    let operator = VirtualOperator::new(script.clone(), hand, master_tool, start);

    // Boards (simulated plants behind them) with their truth taps.
    let (_, master_board_cfg) = lab.board_of(master_name)?;
    let (_, slave_board_cfg) = lab.board_of(slave_name)?;
    if master_board_cfg.kind == BoardKind::Galil {
        return Err(RunError::Setup(format!(
            "robot `{master_name}`: the master runs on a simulated board (the virtual operator's \
             hand pushes its plant); only the slave can be on a galil board"
        )));
    }
    let mut master_tap = TapWriter::new();
    let master_truth = master_tap
        .reader()
        .map_err(|_| RunError::Setup("tap".into()))?;
    let master_plant = PlantConfig {
        motor_torque_limit: master_model.limits().effort_max,
        ..PlantConfig::default()
    };
    let master_board = SimBoard::new(
        RobotKinematics::Float(master_model.clone()),
        master_plant,
        sim_board_config(&master_model, master_board_cfg.dac_bits),
        ToolContact::Hand {
            operator,
            clutch: std::sync::Arc::default(),
        },
        q_master,
        start,
    )
    .with_tap(master_tap);

    // The slave's board with its plant's truth tap and the wrist sensor reading that plant
    // (simulated board), or the Galil board alone.
    let sensor_cfg = lab.sensors.values().find(|s| s.robot == slave_name);
    let sensor_mount = sensor_cfg.map_or(Pose::identity(), |c| {
        Pose::translation(c.mount_xyz_m[0], c.mount_xyz_m[1], c.mount_xyz_m[2])
    });
    let (slave_board, slave_truth, sensor, slave_bindings, slave_link) = match slave_galil {
        Some(GalilSetup {
            board,
            bindings,
            monitor,
            ..
        }) => {
            if sensor_cfg.is_some() {
                log::warn!(
                    "slave `{slave_name}` is on a galil board: its virtual wrist sensor has no plant to read and is left out"
                );
            }
            (board, None, None, Some(bindings), Some(monitor))
        }
        None => {
            let mut slave_tap = TapWriter::new();
            let slave_truth = slave_tap
                .reader()
                .map_err(|_| RunError::Setup("tap".into()))?;
            let sensor_source = slave_tap
                .reader()
                .map_err(|_| RunError::Setup("tap".into()))?;
            let slave_plant = PlantConfig {
                motor_torque_limit: slave_model.limits().effort_max,
                ..PlantConfig::default()
            };
            let slave_board = SimBoard::new(
                RobotKinematics::Float(slave_model.clone()),
                slave_plant,
                sim_board_config(&slave_model, slave_board_cfg.dac_bits),
                ToolContact::Environment(environment.clone()),
                q_slave,
                start,
            )
            .with_tap(slave_tap);

            // The wrist sensor.
            let sensor_cfg = sensor_cfg
                .ok_or_else(|| RunError::Setup(format!("no sensor on the slave `{slave_name}`")))?;
            let mut sensor = VirtualForceSensor::new(
                ForceSensorConfig {
                    mount: sensor_mount,
                    force_noise: sensor_cfg.force_noise_n,
                    torque_noise: sensor_cfg.torque_noise_nm,
                    cutoff_hz: sensor_cfg.cutoff_hz,
                    seed: options.seed,
                    ..ForceSensorConfig::default()
                },
                sensor_source,
            );
            // Tare the wrist sensor with the slave at rest in free space, as an operator does before a
            // session: one board read publishes the plant's state, the sensor takes its reading as zero.
            let mut slave_board = slave_board;
            let mut axes = [penelope_hal::AxisState::default(); penelope_hal::MAX_AXES];
            penelope_hal::Board::read_axes(&mut slave_board, start, &mut axes)
                .map_err(|e| RunError::Setup(format!("slave board: {e:?}")))?;
            penelope_hal::ForceSensor::tare(&mut sensor, start)
                .map_err(setup("wrist sensor tare"))?;
            (
                LabBoard::Sim(Box::new(slave_board)),
                Some(slave_truth),
                Some(sensor),
                None,
                None,
            )
        }
    };

    // Controllers, in configuration order; the law picks the active one.
    let [r, p, y] = lab.teleop.rotation_rpy_deg.map(f64::to_radians);
    let mapping = MappingConfig {
        scale,
        rotation: UnitQuaternion::from_euler_angles(r, p, y),
        force_gain: lab.teleop.force_gain,
        torque_gain: lab.teleop.force_gain,
        negate_wrench: true, // the wrist sensor reports the robot pushing on the world
        ..MappingConfig::default()
    };
    let (master_controllers, master_active) = controllers_for(lab, master_name, law, false)?;
    let (slave_controllers, slave_active) = controllers_for(lab, slave_name, law, slave_on_galil)?;

    // Cells and rings.
    let (master_ref_w, master_ref_r) = latest::<Stamped<Reference>>();
    let (slave_ref_w, slave_ref_r) = latest::<Stamped<Reference>>();
    let (master_log_w, master_log) = ring::<LabSample, TELEMETRY_CAPACITY>();
    let (slave_log_w, slave_log) = ring::<LabSample, TELEMETRY_CAPACITY>();
    let (master_state_w, master_state) = latest::<TelemetrySample>();
    let (slave_state_w, slave_state) = latest::<TelemetrySample>();
    let (mut master_cmd_w, master_cmd) = ring::<ControlCommand, COMMAND_CAPACITY>();
    let (mut slave_cmd_w, slave_cmd) = ring::<ControlCommand, COMMAND_CAPACITY>();
    let m2s: Link = latest::<TeleopSample>();
    let s2m: Link = latest::<TeleopSample>();

    // Control loops.
    let mut master_safety =
        SafetyConfig::master(master_model.joint_count(), *master_model.limits());
    master_safety.watchdog = watchdog;
    let master_control = ControlConfig::new(control_period, master_safety)
        .with_robot_scaling(&model_robot(&master_model));
    let master_loop = ControlLoop::new(
        master_control,
        LabBoard::Sim(Box::new(master_board)),
        master_kin.clone(),
        master_controllers,
        ControlPorts {
            reference: master_ref_r,
            telemetry: LabSink {
                ring: master_log_w,
                state: master_state_w,
                truth: Some(master_truth),
            },
            commands: master_cmd,
        },
    )
    .map_err(setup("master control loop"))?;

    let mut slave_safety = SafetyConfig::slave(slave_model.joint_count(), *slave_model.limits());
    slave_safety.watchdog = watchdog;
    let effort = slave_model.limits().effort_max;
    if slave_bindings.is_none() {
        slave_safety.hold = HoldMode::Pd {
            kp: effort * 40.0,
            kd: effort * 1.0,
        };
    } // A Galil board holds with its own servo (`HoldMode::BoardServo`, the slave default).
    let mut slave_control = ControlConfig::new(control_period, slave_safety)
        .with_robot_scaling(&model_robot(&slave_model));
    if let Some(bindings) = slave_bindings {
        slave_control.axes = bindings; // axis map, counts per radian and encoder offsets
    }
    let slave_loop = ControlLoop::new(
        slave_control,
        slave_board,
        slave_kin.clone(),
        slave_controllers,
        ControlPorts {
            reference: slave_ref_r,
            telemetry: LabSink {
                ring: slave_log_w,
                state: slave_state_w,
                truth: slave_truth,
            },
            commands: slave_cmd,
        },
    )
    .map_err(setup("slave control loop"))?;
    let slave_loop = match sensor {
        Some(sensor) => SlaveLoop::Sensed(Box::new(slave_loop.with_sensor(sensor))),
        None => SlaveLoop::Unsensed(Box::new(slave_loop)),
    };

    // Switch to the law's controllers, then activate from the measured state at the first tick.
    for (w, index) in [
        (&mut master_cmd_w, master_active),
        (&mut slave_cmd_w, slave_active),
    ] {
        let index =
            u8::try_from(index).map_err(|_| RunError::Setup("too many controllers".into()))?;
        w.push(ControlCommand::SwitchController(index))
            .map_err(|_| RunError::Setup("command ring".into()))?;
        w.push(ControlCommand::Activate)
            .map_err(|_| RunError::Setup("command ring".into()))?;
    }

    // Communication loops: the channels start from each robot's own tool pose.
    let mut master_channel = TeleopChannel::new(ChannelConfig {
        direction: ChannelDirection::SlaveToMaster,
        mapping,
        ..ChannelConfig::default()
    })
    .map_err(setup("master channel"))?;
    master_channel.start(
        start,
        &Reference::Cartesian(CartesianReference {
            pose: master_tool,
            twist: Twist::default(),
        }),
    );
    let mut slave_channel = TeleopChannel::new(ChannelConfig {
        direction: ChannelDirection::MasterToSlave,
        mapping,
        ..ChannelConfig::default()
    })
    .map_err(setup("slave channel"))?;
    slave_channel.start(
        start,
        &Reference::Cartesian(CartesianReference {
            pose: slave_tool,
            twist: Twist::default(),
        }),
    );
    let master_comm = MasterComm {
        comm: CommLoop::new(master_channel, master_ref_w),
        model: master_kin.clone(),
        state: master_state,
        to_slave: m2s.0,
        from_slave: s2m.1,
        script: script.clone(),
        start,
        sequence: 0,
    };
    let slave_comm = SlaveComm {
        comm: CommLoop::new(slave_channel, slave_ref_w),
        model: slave_kin.clone(),
        state: slave_state,
        to_master: s2m.0,
        from_master: m2s.1,
        sensor_mount,
        sequence: 0,
    };

    let info = RunInfo {
        lab: lab.name.clone(),
        law,
        scale,
        force_gain: lab.teleop.force_gain,
        seed: options.seed,
        clock: options.clock,
        start,
        control_period,
        comm_period,
        script,
        master_model: master_kin,
        slave_model: slave_kin,
        environment,
        sensor_mount,
        rotation: mapping.rotation,
        slave_link,
    };
    Ok(Built {
        start,
        end: start + duration,
        control_period,
        comm_period,
        master: master_loop,
        slave: slave_loop,
        master_comm,
        slave_comm,
        master_log,
        slave_log,
        info,
    })
}

/// Opens the slave's Galil board, when its board is one (`None` for a simulated board).
fn open_slave_galil(
    lab: &LabConfig,
    slave: &str,
    model: &models::DhRobotModel,
    zero_pose: &JointVector,
    options: &RunOptions,
    start: Timestamp,
) -> Result<Option<GalilSetup>, RunError> {
    let (name, board) = lab.board_of(slave)?;
    if board.kind != BoardKind::Galil {
        return Ok(None);
    }
    if options.clock == ClockMode::Simulated {
        return Err(RunError::Setup(format!(
            "board `{name}` is a galil board, which runs in real time: use the real-time clock (no --sim-clock)"
        )));
    }
    galil_board(board, model, zero_pose, start)
        .map(Some)
        .map_err(setup(&format!("board `{name}`")))
}

/// A `Robot` view of a model, for encoder scaling.
fn model_robot(model: &models::DhRobotModel) -> models::DhRobot {
    models::DhRobot::new(model.clone())
}

/// The controllers bound to `robot`, in configuration order, and the index of the one the law
/// uses. A slave on a board with its own servo over a slow link (`board_servo`) prefers a
/// `slave-position` controller (position targets) to `slave-tracking` (torques).
fn controllers_for(
    lab: &LabConfig,
    robot: &str,
    law: Law,
    board_servo: bool,
) -> Result<(ControllerBox, usize), RunError> {
    let mut set: ControllerBox = Vec::new();
    let mut active = None;
    for (name, c) in lab.controllers_of(robot) {
        let controller: Box<dyn Controller + Send> = match c.kind {
            ControllerKind::ForceDisplay => {
                Box::new(ForceDisplay::new(ForceDisplayConfig::default()).map_err(setup(name))?)
            }
            ControllerKind::PositionErrorMaster => {
                Box::new(PositionErrorMaster::new(ImpedanceConfig::master()).map_err(setup(name))?)
            }
            ControllerKind::SlaveTracking => {
                Box::new(SlaveTracking::new(TrackingConfig::default()).map_err(setup(name))?)
            }
            ControllerKind::SlavePosition => Box::new(
                SlaveTracking::new(TrackingConfig {
                    output: TrackingOutput::BoardServo,
                    ..TrackingConfig::default()
                })
                .map_err(setup(name))?,
            ),
            ControllerKind::CartesianImpedance => {
                Box::new(CartesianImpedance::new(ImpedanceConfig::default()).map_err(setup(name))?)
            }
            ControllerKind::JointPid => {
                return Err(RunError::Setup(format!(
                    "controller `{name}`: joint-pid follows joint trajectories, not a teleop channel"
                )));
            }
        };
        let slave_kind = if board_servo {
            ControllerKind::SlavePosition
        } else {
            ControllerKind::SlaveTracking
        };
        let wanted = match (law, c.kind) {
            (Law::ForcePosition, ControllerKind::ForceDisplay)
            | (Law::PositionError, ControllerKind::PositionErrorMaster) => true,
            (_, kind) => kind == slave_kind,
        };
        if wanted && active.is_none() {
            active = Some(set.len());
        }
        set.push(controller);
    }
    // A slave without a controller of the preferred kind falls back to the other one.
    if active.is_none() {
        let fallback = if board_servo {
            ControllerKind::SlaveTracking
        } else {
            ControllerKind::SlavePosition
        };
        active = lab
            .controllers_of(robot)
            .position(|(_, c)| c.kind == fallback);
    }
    let active = active.ok_or_else(|| {
        RunError::Setup(format!(
            "robot `{robot}` has no controller for the {} law",
            law.as_str()
        ))
    })?;
    Ok((set, active))
}

/// Progress of a running lab, for a status line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// Time since the start.
    pub elapsed: Duration,
    /// Planned length.
    pub total: Duration,
    /// The operator script's phase.
    pub phase: &'static str,
    /// Latest slave tool position error against its reference, m.
    pub tracking_error: f64,
    /// Latest sensed contact force magnitude, N.
    pub contact_force: f64,
    /// Latest displayed force magnitude on the master, N.
    pub displayed_force: f64,
}

/// Timing of one real-time thread.
#[derive(Clone, Debug)]
pub struct ThreadTiming {
    /// Thread name.
    pub name: String,
    /// Its period.
    pub period: Duration,
    /// What the executor measured (`None` on a simulated clock).
    pub report: Option<penelope_rt_core::exec::RunReport>,
}

/// Everything a run recorded.
pub struct RunOutput {
    /// What ran.
    pub info: RunInfo,
    /// Every master control tick.
    pub master: Vec<LabSample>,
    /// Every slave control tick.
    pub slave: Vec<LabSample>,
    /// Samples the rings dropped (the logger fell behind): master, slave.
    pub dropped: (usize, usize),
    /// Per-thread timing (real-time runs).
    pub threads: Vec<ThreadTiming>,
}

/// Control ticks in a run of length `total` (with room to spare), so the logger's vectors never
/// grow while the loops run.
fn ticks_in(total: Duration, period: Duration) -> usize {
    (total.as_nanos() / period.as_nanos().max(1)) as usize + 16
}

fn drain(log: &mut ArcConsumer<LabSample, TELEMETRY_CAPACITY>, into: &mut Vec<LabSample>) {
    while let Some(s) = log.pop() {
        into.push(s);
    }
}

fn progress_of(
    info: &RunInfo,
    start: Timestamp,
    master: &[LabSample],
    slave: &[LabSample],
    total: Duration,
) -> Progress {
    let now = slave.last().map(|s| s.telemetry.time).unwrap_or(start);
    let elapsed = now - start;
    let (tracking_error, contact_force) = slave
        .last()
        .map(|s| {
            (
                (s.telemetry.reference_position - s.telemetry.tool_position).norm(),
                s.telemetry.wrench.force.norm(),
            )
        })
        .unwrap_or((0.0, 0.0));
    let displayed_force = master
        .last()
        .map(|s| s.telemetry.commanded_wrench.force.norm())
        .unwrap_or(0.0);
    let phase = info
        .script
        .segment_at(elapsed)
        .map_or("", |(_, s, _)| s.label);
    Progress {
        elapsed,
        total,
        phase,
        tracking_error,
        contact_force,
        displayed_force,
    }
}

/// Runs the lab. `on_progress` is called from the calling (non-real-time) thread about 20 times
/// a second of run time.
///
/// # Errors
/// [`RunError`] when the configuration cannot be built or a thread fails.
pub fn run(
    lab: &LabConfig,
    options: &RunOptions,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<RunOutput, RunError> {
    match options.clock {
        ClockMode::Simulated => run_simulated(lab, options, on_progress),
        ClockMode::RealTime => run_real_time(lab, options, on_progress),
    }
}

fn run_simulated(
    lab: &LabConfig,
    options: &RunOptions,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<RunOutput, RunError> {
    let mut b = build(lab, options, Timestamp::ZERO)?;
    let total = b.end - b.start;
    let mut master = Vec::with_capacity(ticks_in(total, b.control_period));
    let mut slave = Vec::with_capacity(ticks_in(total, b.control_period));
    let mut runner = SimRunner::new(b.start);
    let chunk = Duration::from_millis(50);
    let mut until = b.start;
    while until < b.end {
        until = (until + chunk).min(b.end);
        {
            let (mc, sc) = (&mut b.master, &mut b.slave);
            let (mcomm, scomm) = (&mut b.master_comm, &mut b.slave_comm);
            let mut master_control = |now: Timestamp| {
                mc.tick(now);
                Flow::Continue
            };
            let mut slave_control = |now: Timestamp| {
                sc.tick(now);
                Flow::Continue
            };
            let mut master_comm = |now: Timestamp| {
                mcomm.tick(now);
                Flow::Continue
            };
            let mut slave_comm = |now: Timestamp| {
                scomm.tick(now);
                Flow::Continue
            };
            // Order at equal instants: communication before control, master before slave, as
            // the priorities would have it on one core.
            let mut tasks = [
                SimTask::new(b.comm_period, &mut master_comm),
                SimTask::new(b.comm_period, &mut slave_comm),
                SimTask::new(b.control_period, &mut master_control),
                SimTask::new(b.control_period, &mut slave_control),
            ];
            runner.run_until(&mut tasks, until);
        }
        drain(&mut b.master_log, &mut master);
        drain(&mut b.slave_log, &mut slave);
        on_progress(&progress_of(&b.info, b.start, &master, &slave, total));
    }
    let dropped = (b.master_log.dropped(), b.slave_log.dropped());
    Ok(RunOutput {
        info: b.info,
        master,
        slave,
        dropped,
        threads: Vec::new(),
    })
}

fn run_real_time(
    lab: &LabConfig,
    options: &RunOptions,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<RunOutput, RunError> {
    use penelope_rt_core::clock::MonotonicClock;
    use penelope_rt_core::exec::{PeriodicConfig, Tick, spawn};

    // Start a little in the future so every thread is up before the first deadline.
    let start = MonotonicClock::read() + Duration::from_millis(100);
    let b = build(lab, options, start)?;
    let total = b.end - b.start;
    let Built {
        end,
        control_period,
        comm_period,
        mut master,
        mut slave,
        mut master_comm,
        mut slave_comm,
        mut master_log,
        mut slave_log,
        info,
        ..
    } = b;
    // Control threads above communication threads; each robot's pair on its own CPU.
    let threads = [
        ("master-control", control_period, 80u8, 0usize),
        ("slave-control", control_period, 80, 1),
        ("master-comm", comm_period, 70, 0),
        ("slave-comm", comm_period, 70, 1),
    ];
    let spawn_until_end = |index: usize, mut body: Box<dyn FnMut(Tick) + Send>| {
        let (name, period, priority, cpu) = threads[index];
        let config = PeriodicConfig::new(name, period)
            .priority(priority)
            .cpu(cpu);
        spawn(config, move |tick| {
            if tick.deadline >= end {
                return Flow::Stop;
            }
            body(tick);
            Flow::Continue
        })
        .map_err(|e| RunError::Thread(format!("{name}: {e}")))
    };
    let handles = [
        spawn_until_end(
            0,
            Box::new(move |tick| {
                master.note_timing(tick.latency(), tick.previous_exec);
                master.tick(tick.deadline);
            }),
        )?,
        spawn_until_end(
            1,
            Box::new(move |tick| {
                slave.note_timing(tick.latency(), tick.previous_exec);
                slave.tick(tick.deadline);
            }),
        )?,
        spawn_until_end(2, Box::new(move |tick| master_comm.tick(tick.deadline)))?,
        spawn_until_end(3, Box::new(move |tick| slave_comm.tick(tick.deadline)))?,
    ];
    let mut master_rows = Vec::with_capacity(ticks_in(total, control_period));
    let mut slave_rows = Vec::with_capacity(ticks_in(total, control_period));
    while handles.iter().any(|h| !h.is_finished()) {
        std::thread::sleep(Duration::from_millis(50));
        drain(&mut master_log, &mut master_rows);
        drain(&mut slave_log, &mut slave_rows);
        on_progress(&progress_of(&info, start, &master_rows, &slave_rows, total));
    }
    let mut timings = Vec::new();
    for (h, (name, period, _, _)) in handles.into_iter().zip(threads) {
        match h.join() {
            Ok(report) => timings.push(ThreadTiming {
                name: name.to_string(),
                period,
                report: Some(report),
            }),
            Err(e) => return Err(RunError::Thread(format!("{name}: {e}"))),
        }
    }
    drain(&mut master_log, &mut master_rows);
    drain(&mut slave_log, &mut slave_rows);
    let dropped = (master_log.dropped(), slave_log.dropped());
    Ok(RunOutput {
        info,
        master: master_rows,
        slave: slave_rows,
        dropped,
        threads: timings,
    })
}
