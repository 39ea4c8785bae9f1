//! What runs while a controller is active: the control task (period `T_ctrl`, SCHED_FIFO), the
//! communication task (period `T_com`: the trajectory's reference into a latest-value cell), the
//! sensor feed (a non-real-time thread that may block on the network) and the telemetry pump
//! (non-real-time: drains the telemetry ring, keeps the newest sample, fans batches out).
//!
//! ```text
//!  GoTo ──ring──> comm task ──LatestCell<reference>──> control task ──ring<telemetry>──> pump ──> outboxes
//!                    ^ LatestCell<sample>                  │  ^ LatestCell<wrench>
//!                    └─────────────────────────────────────┤  └── sensor feed <── remote.call(Measure)
//!                                  LatestCell<sample> ─────┘
//! ```
//!
//! [`ControlTask::tick`] is the whole per-tick body of the control thread; it is public so a test
//! can run it on a simulated clock under a counting allocator.
//!
//! Why the reference is produced in the communication task and not in the loop: DESIGN.md's two
//! threads per controller, and a GoTo or a new trajectory is then swapped without touching the
//! control thread; the control loop's watchdog holds the robot if that task ever stalls.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use nalgebra::Vector3;
use penelope_drivers::galil::{GalilBoard, GalilBoardError};
use penelope_drivers::model::DhRobotModel;
use penelope_drivers::sim::ToolContact;
use penelope_drivers::sim::board::{SimBoard, SimBoardError};
use penelope_drivers::sim::environment::Environment;
use penelope_hal::{
    AxisCommand, AxisState, Board, ControlInput, Controller, ControllerError, Error, ErrorKind,
    Frame, InverseKinematics, JacobianFrame, JointCommand, JointReference, JointState, JointVector,
    Kinematics, MAX_AXES, MAX_JOINTS, Pose, Reference, RobotModel, Sensor, Timestamp, Trajectory,
    TrajectoryError, Twist, Wrench,
};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Fresh, Stamped};
use penelope_rt_core::clock::MonotonicClock;
use penelope_rt_core::control::{ControlLoop, NoSensor, TickOutcome};
use penelope_rt_core::controller::{JointPid, JointPidGains, JointPositionServo};
use penelope_rt_core::exec::{Flow, PeriodicThread};
use penelope_rt_core::ring::{ArcConsumer, ArcProducer};
use penelope_rt_core::telemetry::{TelemetrySample, TelemetrySink};
use penelope_rt_core::teleop::{
    CartesianImpedance, ForceDisplay, ForceDisplayConfig, ImpedanceConfig, PositionErrorMaster,
    SlaveTracking, TrackingConfig,
};
use penelope_rt_core::trajectory::{
    CubicSpline, Goal, Ramp, SplineEnds, Step, Trapezoidal, Waypoint,
};

use super::kinematics::RobotKinematics;
use super::teleop::TeleopComm;
use crate::proto::{
    Method, PoseMsg, Reply, SensorMethod, ServerMsg, TelemetryBatch, TelemetryRecord, WireError,
    WrenchMsg, joints_from_vector,
};
use crate::service::{Outbox, Remote};

/// Telemetry samples buffered between a control thread and its pump (4 s at 1 kHz).
pub const TELEMETRY_CAPACITY: usize = 4096;
/// Commands buffered towards a control thread.
pub const COMMAND_CAPACITY: usize = 16;
/// GoTo requests buffered towards a communication thread.
pub const GOTO_CAPACITY: usize = 4;
/// Waypoints of a configured spline.
pub const SPLINE_CAPACITY: usize = crate::objects::kinds::MAX_WAYPOINTS;

/// A robot's simulated body: the rigid-body plant of its whole chain behind a simulated board
/// whose axes are the robot's joints in order (joints are dynamically coupled, so a robot whose
/// joints are spread over several simulated boards is still one plant).
pub type SimBody = SimBoard<DhRobotModel, ToolContact>;

// ---------------------------------------------------------------------------------------------
// The board a loop drives
// ---------------------------------------------------------------------------------------------

/// The board a control loop sees: one axis per robot joint, in joint order, whatever boards
/// the joints are mapped onto.
pub enum LoopBoard {
    /// The robot's simulated body, and the offset from the loop's clock to the plant's (set at
    /// the first call, so the plant goes on from its own time whenever a loop starts; grown by
    /// stalls longer than [`MAX_PLANT_STEP_NS`]).
    Sim(Box<SimBody>, Option<u64>),
    /// One or more Galil boards.
    Galil(Box<GalilSet>),
}

/// Joints spread over Galil boards: joint `j` is axis `map[j].1` of board `map[j].0`.
pub struct GalilSet {
    /// The boards, with their object names (given back when the loop stops).
    pub boards: Vec<(String, GalilBoard)>,
    map: [(u8, u8); MAX_JOINTS],
    joints: usize,
    read: Vec<[AxisState; MAX_AXES]>,
    write: Vec<[AxisCommand; MAX_AXES]>,
}

impl GalilSet {
    /// Joint `j` on board `map[j].0`, axis `map[j].1`, for `joints` joints.
    pub fn new(
        boards: Vec<(String, GalilBoard)>,
        map: [(u8, u8); MAX_JOINTS],
        joints: usize,
    ) -> Self {
        let n = boards.len();
        GalilSet {
            boards,
            map,
            joints: joints.min(MAX_JOINTS),
            read: vec![[AxisState::default(); MAX_AXES]; n],
            write: vec![[AxisCommand::Off; MAX_AXES]; n],
        }
    }
}

/// The longest stretch of simulated time a plant integrates in one board call, ns. A loop that
/// stalls longer (a VM pause, a debug build) finds the simulated world paused for the rest of the
/// stall instead of integrating all of it in its next tick: otherwise the catch-up costs time in
/// proportion to the stall, makes the next tick later still, and the loop never recovers.
pub const MAX_PLANT_STEP_NS: u64 = 10_000_000;

/// The plant's time for the loop's `now` (at most [`MAX_PLANT_STEP_NS`] past the plant's own).
fn plant_time(body: &SimBody, offset: &mut Option<u64>, now: Timestamp) -> Timestamp {
    let plant_now = body.plant().snapshot().time.as_nanos();
    let off = offset.get_or_insert_with(|| now.as_nanos().saturating_sub(plant_now));
    let target = now.as_nanos().saturating_sub(*off);
    let limit = plant_now.saturating_add(MAX_PLANT_STEP_NS);
    if target > limit {
        *off = off.saturating_add(target - limit);
        return Timestamp::from_nanos(limit);
    }
    Timestamp::from_nanos(target)
}

/// A [`LoopBoard`] error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopBoardError {
    /// From the simulated board.
    Sim(SimBoardError),
    /// From a Galil board.
    Galil(GalilBoardError),
    /// A slice shorter than the joint count.
    WrongLength,
}

impl Error for LoopBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            LoopBoardError::Sim(e) => e.kind(),
            LoopBoardError::Galil(e) => e.kind(),
            LoopBoardError::WrongLength => ErrorKind::InvalidInput,
        }
    }
}

impl Board for LoopBoard {
    type Error = LoopBoardError;

    fn axis_count(&self) -> usize {
        match self {
            LoopBoard::Sim(b, _) => b.axis_count(),
            LoopBoard::Galil(g) => g.joints,
        }
    }

    /// # Real-time
    /// Simulated: steps the plant (bounded sub-steps). Galil: one wait-free cell read per board.
    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), LoopBoardError> {
        match self {
            LoopBoard::Sim(b, offset) => {
                let now = plant_time(b, offset, now);
                b.read_axes(now, out).map_err(LoopBoardError::Sim)
            }
            LoopBoard::Galil(g) => {
                if out.len() < g.joints {
                    return Err(LoopBoardError::WrongLength);
                }
                for (i, (_, board)) in g.boards.iter_mut().enumerate() {
                    let count = board.axis_count().min(MAX_AXES);
                    board
                        .read_axes(now, &mut g.read[i][..count])
                        .map_err(LoopBoardError::Galil)?;
                }
                for (j, o) in out.iter_mut().enumerate().take(g.joints) {
                    let (b, a) = g.map[j];
                    *o = g.read[usize::from(b)][usize::from(a)];
                }
                Ok(())
            }
        }
    }

    /// # Real-time
    /// As [`read_axes`](Self::read_axes).
    fn write_axes(
        &mut self,
        now: Timestamp,
        commands: &[AxisCommand],
    ) -> Result<(), LoopBoardError> {
        match self {
            LoopBoard::Sim(b, offset) => {
                let now = plant_time(b, offset, now);
                b.write_axes(now, commands).map_err(LoopBoardError::Sim)
            }
            LoopBoard::Galil(g) => {
                if commands.len() < g.joints {
                    return Err(LoopBoardError::WrongLength);
                }
                for w in g.write.iter_mut() {
                    *w = [AxisCommand::Off; MAX_AXES];
                }
                for (j, c) in commands.iter().enumerate().take(g.joints) {
                    let (b, a) = g.map[j];
                    g.write[usize::from(b)][usize::from(a)] = *c;
                }
                for (i, (_, board)) in g.boards.iter_mut().enumerate() {
                    let count = board.axis_count().min(MAX_AXES);
                    board
                        .write_axes(now, &g.write[i][..count])
                        .map_err(LoopBoardError::Galil)?;
                }
                Ok(())
            }
        }
    }

    /// # Real-time
    /// Wait-free: a simulated board has no latch; each Galil board takes the request to its
    /// I/O thread.
    fn rearm(&mut self) -> Result<(), LoopBoardError> {
        match self {
            LoopBoard::Sim(b, _) => b.rearm().map_err(LoopBoardError::Sim),
            LoopBoard::Galil(g) => {
                for (_, board) in g.boards.iter_mut() {
                    board.rearm().map_err(LoopBoardError::Galil)?;
                }
                Ok(())
            }
        }
    }

    fn set_enabled(&mut self, enabled: bool) -> Result<(), LoopBoardError> {
        match self {
            LoopBoard::Sim(b, _) => b.set_enabled(enabled).map_err(LoopBoardError::Sim),
            LoopBoard::Galil(g) => {
                let mut result = Ok(());
                for (_, board) in g.boards.iter_mut() {
                    if let Err(e) = board.set_enabled(enabled) {
                        result = Err(LoopBoardError::Galil(e));
                    }
                }
                result
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Controllers
// ---------------------------------------------------------------------------------------------

/// The control laws a node runs. Inline, not boxed: one per loop, built before its thread
/// starts, and the control thread must reach it without a pointer chase.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum NodeController {
    /// `controller/joint-pid`.
    Pid(JointPid),
    /// `controller/cartesian-impedance`.
    Impedance(CartesianImpedance),
    /// `controller/joint-position`.
    Position(JointPositionServo),
    /// `controller/force-display`.
    ForceDisplay(ForceDisplay),
    /// `controller/position-error-master`.
    PositionErrorMaster(PositionErrorMaster),
    /// `controller/slave-tracking` and `controller/slave-position`.
    SlaveTracking(SlaveTracking),
}

impl NodeController {
    /// True when the law follows Cartesian references.
    pub fn is_cartesian(&self) -> bool {
        matches!(self, NodeController::Impedance(_))
    }

    /// The law's inner controller.
    fn inner(&mut self) -> &mut dyn Controller {
        match self {
            NodeController::Pid(c) => c,
            NodeController::Impedance(c) => c,
            NodeController::Position(c) => c,
            NodeController::ForceDisplay(c) => c,
            NodeController::PositionErrorMaster(c) => c,
            NodeController::SlaveTracking(c) => c,
        }
    }

    /// Applies new gains of the same law (others are ignored).
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn apply(&mut self, gains: &GainsUpdate) {
        match (self, gains) {
            (NodeController::Pid(p), GainsUpdate::Pid(g)) => p.set_gains(*g),
            // Checked before they were sent: a refusal keeps the old gains.
            (NodeController::Impedance(c), GainsUpdate::Impedance(g)) => {
                let _ = c.set_config(*g);
            }
            (NodeController::ForceDisplay(c), GainsUpdate::ForceDisplay(g)) => {
                let _ = c.set_config(*g);
            }
            (NodeController::PositionErrorMaster(c), GainsUpdate::PositionError(g)) => {
                let _ = c.set_config(*g);
            }
            (NodeController::SlaveTracking(c), GainsUpdate::Tracking(g)) => {
                let _ = c.set_config(*g);
            }
            _ => {}
        }
    }
}

impl Controller for NodeController {
    fn kind(&self) -> &'static str {
        match self {
            NodeController::Pid(c) => c.kind(),
            NodeController::Impedance(c) => c.kind(),
            NodeController::Position(c) => c.kind(),
            NodeController::ForceDisplay(c) => c.kind(),
            NodeController::PositionErrorMaster(c) => c.kind(),
            NodeController::SlaveTracking(c) => c.kind(),
        }
    }
    fn activate(&mut self, now: Timestamp, measured: &JointState, model: &dyn RobotModel) {
        self.inner().activate(now, measured, model);
    }
    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        self.inner().update(input)
    }
}

/// Gains sent to a running loop (`SetGains`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GainsUpdate {
    /// Joint PID gains.
    Pid(JointPidGains),
    /// Impedance settings.
    Impedance(ImpedanceConfig),
    /// Force-display settings.
    ForceDisplay(ForceDisplayConfig),
    /// Position-error master settings.
    PositionError(ImpedanceConfig),
    /// Slave-tracking settings.
    Tracking(TrackingConfig),
}

// ---------------------------------------------------------------------------------------------
// Trajectories
// ---------------------------------------------------------------------------------------------

/// The trajectories a node runs. Inline, not boxed: a GoTo swaps the variant in the
/// communication thread, which must not allocate or free.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum NodeTrajectory {
    /// A step.
    Step(Step),
    /// A ramp.
    Ramp(Ramp),
    /// A trapezoidal move.
    Trapezoidal(Trapezoidal),
    /// A configured spline.
    Spline(CubicSpline<SPLINE_CAPACITY>),
    /// A GoTo motion (clamped spline from the current reference).
    GoTo(CubicSpline<1>),
}

impl NodeTrajectory {
    fn inner(&mut self) -> &mut dyn Trajectory {
        match self {
            NodeTrajectory::Step(t) => t,
            NodeTrajectory::Ramp(t) => t,
            NodeTrajectory::Trapezoidal(t) => t,
            NodeTrajectory::Spline(t) => t,
            NodeTrajectory::GoTo(t) => t,
        }
    }

    /// The duration once started (`None` if unknown).
    pub fn duration(&self) -> Option<Duration> {
        match self {
            NodeTrajectory::Step(_) | NodeTrajectory::Ramp(_) => None,
            NodeTrajectory::Trapezoidal(t) => t.duration(),
            NodeTrajectory::Spline(t) => Some(t.duration()),
            NodeTrajectory::GoTo(t) => Some(t.duration()),
        }
    }

    /// A GoTo motion to `goal` lasting `duration`.
    ///
    /// # Errors
    /// [`WireError::BadArgument`] for a non-finite goal or a zero duration.
    pub fn go_to(goal: JointVector, duration: Duration) -> Result<Self, WireError> {
        CubicSpline::<1>::new(
            &[Waypoint {
                at: duration,
                goal: Goal::Joint(goal),
            }],
            SplineEnds::Clamped,
        )
        .map(NodeTrajectory::GoTo)
        .map_err(|e| WireError::BadArgument(format!("go-to motion: {e}")))
    }
}

impl Trajectory for NodeTrajectory {
    fn kind(&self) -> &'static str {
        match self {
            NodeTrajectory::GoTo(_) => "go-to",
            NodeTrajectory::Step(t) => t.kind(),
            NodeTrajectory::Ramp(t) => t.kind(),
            NodeTrajectory::Trapezoidal(t) => t.kind(),
            NodeTrajectory::Spline(t) => t.kind(),
        }
    }
    fn start(&mut self, now: Timestamp, from: &Reference) {
        self.inner().start(now, from);
    }
    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError> {
        self.inner().reference(now)
    }
    fn is_finished(&self, now: Timestamp) -> bool {
        match self {
            NodeTrajectory::Step(t) => t.is_finished(now),
            NodeTrajectory::Ramp(t) => t.is_finished(now),
            NodeTrajectory::Trapezoidal(t) => t.is_finished(now),
            NodeTrajectory::Spline(t) => t.is_finished(now),
            NodeTrajectory::GoTo(t) => t.is_finished(now),
        }
    }
}

/// A GoTo request to a communication task.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GoToCommand {
    /// Goal joints, rad.
    pub goal: JointVector,
    /// Duration.
    pub duration: Duration,
}

// ---------------------------------------------------------------------------------------------
// Ports
// ---------------------------------------------------------------------------------------------

type RefWriter = ArcLatestWriter<Stamped<Reference>>;
type RefReader = ArcLatestReader<Stamped<Reference>>;
type Commands = ArcConsumer<penelope_rt_core::control::ControlCommand, COMMAND_CAPACITY>;

/// The control loop's telemetry port: every sample into the ring (for the pump) and into
/// latest-value cells for the communication task and the sensor feed.
pub struct NodeSink {
    ring: ArcProducer<TelemetrySample, TELEMETRY_CAPACITY>,
    comm: ArcLatestWriter<TelemetrySample>,
    probe: ArcLatestWriter<TelemetrySample>,
}

impl NodeSink {
    /// A sink over these three ports.
    pub fn new(
        ring: ArcProducer<TelemetrySample, TELEMETRY_CAPACITY>,
        comm: ArcLatestWriter<TelemetrySample>,
        probe: ArcLatestWriter<TelemetrySample>,
    ) -> Self {
        NodeSink { ring, comm, probe }
    }
}

impl TelemetrySink for NodeSink {
    /// # Real-time
    /// Two wait-free cell writes and one ring push.
    fn push(&mut self, sample: &TelemetrySample) -> bool {
        self.comm.write(*sample);
        self.probe.write(*sample);
        self.ring.push(*sample).is_ok()
    }
}

/// The wrench a sensor feed publishes, read by the loop: wait-free, and refused when older than
/// the timeout (the loop then notes a sensor error and runs without a wrench).
pub struct CellSensor {
    reader: ArcLatestReader<Stamped<Wrench>>,
    timeout: Duration,
}

impl CellSensor {
    /// A sensor reading `reader`, trusting values younger than `timeout`.
    pub fn new(reader: ArcLatestReader<Stamped<Wrench>>, timeout: Duration) -> Self {
        CellSensor { reader, timeout }
    }
}

/// Why a [`CellSensor`] has no reading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellSensorError {
    /// Nothing arrived yet.
    NoData,
    /// The newest wrench is older than the timeout.
    Stale,
}

impl Error for CellSensorError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Timeout
    }
}

impl Sensor for CellSensor {
    type Error = CellSensorError;
    type Reading = Wrench;

    /// # Real-time
    /// One wait-free cell read.
    fn read(&mut self, now: Timestamp) -> Result<Wrench, CellSensorError> {
        match self.reader.latest() {
            None => Err(CellSensorError::NoData),
            Some(s) if now.saturating_since(s.stamp) > self.timeout => Err(CellSensorError::Stale),
            Some(s) => Ok(s.value),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The control task
// ---------------------------------------------------------------------------------------------

type Loop<F> =
    ControlLoop<LoopBoard, RobotKinematics, [NodeController; 1], RefReader, NodeSink, Commands, F>;

/// A node's control loop, with or without a force sensor.
pub enum NodeLoop {
    /// No sensor bound.
    Plain(Box<Loop<NoSensor>>),
    /// A sensor bound (its wrench comes through a [`CellSensor`]).
    Sensed(Box<Loop<CellSensor>>),
}

impl NodeLoop {
    /// The board, model and controllers back (the loop is taken apart).
    pub fn into_board(self) -> LoopBoard {
        match self {
            NodeLoop::Plain(l) => l.into_parts().0,
            NodeLoop::Sensed(l) => l.into_parts().0,
        }
    }

    /// The last tick's sample.
    pub fn last_sample(&self) -> &TelemetrySample {
        match self {
            NodeLoop::Plain(l) => l.last_sample(),
            NodeLoop::Sensed(l) => l.last_sample(),
        }
    }
}

/// The per-tick body of a control thread: new gains if any, then one [`ControlLoop::tick`].
pub struct ControlTask {
    lp: NodeLoop,
    gains: ArcLatestReader<GainsUpdate>,
}

impl ControlTask {
    /// A task over `lp`, taking gain changes from `gains`.
    pub fn new(lp: NodeLoop, gains: ArcLatestReader<GainsUpdate>) -> Self {
        ControlTask { lp, gains }
    }

    /// One control tick at `now`.
    ///
    /// # Real-time
    /// No allocation, no locks, no blocking (the ports are wait-free cells and rings; a simulated
    /// board steps its plant, a Galil board exchanges cells with its I/O thread), bounded time.
    pub fn tick(&mut self, now: Timestamp) -> TickOutcome {
        if let Fresh::New(g) = self.gains.read() {
            match &mut self.lp {
                NodeLoop::Plain(l) => l.controllers_mut()[0].apply(&g),
                NodeLoop::Sensed(l) => l.controllers_mut()[0].apply(&g),
            }
        }
        match &mut self.lp {
            NodeLoop::Plain(l) => l.tick(now),
            NodeLoop::Sensed(l) => l.tick(now),
        }
    }

    /// Passes the executor's timing of the previous tick to the loop.
    ///
    /// # Real-time
    /// Constant time.
    pub fn note_timing(&mut self, wake_latency: Duration, exec_time: Duration) {
        match &mut self.lp {
            NodeLoop::Plain(l) => l.note_timing(wake_latency, exec_time),
            NodeLoop::Sensed(l) => l.note_timing(wake_latency, exec_time),
        }
    }

    /// The loop.
    pub fn control_loop(&self) -> &NodeLoop {
        &self.lp
    }

    /// The loop, taken out.
    pub fn into_loop(self) -> NodeLoop {
        self.lp
    }

    /// Brings the robot to its safe state after a failure ([`ControlLoop::fail_safe`]).
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn fail_safe(&mut self, now: Timestamp) {
        match &mut self.lp {
            NodeLoop::Plain(l) => l.fail_safe(now),
            NodeLoop::Sensed(l) => l.fail_safe(now),
        }
    }

    /// Whether the loop holds its robot with the board's own servo (rather than with torques).
    pub fn holds_with_board_servo(&self) -> bool {
        let hold = match &self.lp {
            NodeLoop::Plain(l) => l.config().safety.hold,
            NodeLoop::Sensed(l) => l.config().safety.hold,
        };
        matches!(hold, penelope_rt_core::safety::HoldMode::BoardServo)
    }
}

// ---------------------------------------------------------------------------------------------
// The communication task
// ---------------------------------------------------------------------------------------------

/// Where a communication task's references come from.
// One per loop, built before its thread starts: inline, so a GoTo swaps it without allocating.
#[allow(clippy::large_enum_variant)]
enum ReferenceSource {
    /// A trajectory (and the GoTo motions that replace it).
    Trajectory(NodeTrajectory),
    /// One end of a teleoperation channel.
    Teleop(Box<TeleopComm>),
}

/// The per-tick body of a communication thread: starts the trajectory from the measured state
/// (no jump), swaps in GoTo motions from the current reference (no jump in position or velocity),
/// converts joint references to Cartesian ones for a Cartesian law (forward kinematics and
/// `J qd`), and publishes the stamped reference. Like rt-core's `CommLoop`, plus the conversion.
pub struct CommTask {
    source: ReferenceSource,
    writer: RefWriter,
    state: ArcLatestReader<TelemetrySample>,
    goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
    model: RobotKinematics,
    cartesian: bool,
    /// The trajectory's goals are tool poses (it starts from the measured tool pose).
    tool_goals: bool,
    started: bool,
    last: Option<JointReference>,
    /// When `last` was produced by inverse kinematics (for its velocity).
    last_at: Option<Timestamp>,
    measured: Option<JointVector>,
    published: u64,
    /// Tool references a joint law could not follow (no inverse kinematics solution near the
    /// last one): not published, so the loop's watchdog holds the robot if they persist.
    ik_failures: u64,
}

impl CommTask {
    /// A task publishing `trajectory` into `writer`; `cartesian` for a law that follows poses.
    pub fn new(
        trajectory: NodeTrajectory,
        writer: RefWriter,
        state: ArcLatestReader<TelemetrySample>,
        goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
        model: RobotKinematics,
        cartesian: bool,
    ) -> Self {
        let source = ReferenceSource::Trajectory(trajectory);
        CommTask::with_source(source, writer, state, goto, model, cartesian)
    }

    fn with_source(
        source: ReferenceSource,
        writer: RefWriter,
        state: ArcLatestReader<TelemetrySample>,
        goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
        model: RobotKinematics,
        cartesian: bool,
    ) -> Self {
        CommTask {
            source,
            writer,
            state,
            goto,
            model,
            cartesian,
            tool_goals: false,
            started: false,
            last: None,
            last_at: None,
            measured: None,
            published: 0,
            ik_failures: 0,
        }
    }

    /// Tells the task that the trajectory's goals are tool poses: it starts from the measured
    /// tool pose, and a joint law follows its references through inverse kinematics.
    pub fn with_tool_goals(mut self, tool_goals: bool) -> Self {
        self.tool_goals = tool_goals;
        self
    }

    /// Tool references a joint law could not follow so far.
    pub fn ik_failures(&self) -> u64 {
        self.ik_failures
    }

    /// A task running one end of a teleoperation channel instead of a trajectory (GoTo
    /// requests are refused by the creator before they reach it).
    pub fn teleop(
        teleop: TeleopComm,
        writer: RefWriter,
        state: ArcLatestReader<TelemetrySample>,
        goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
        model: RobotKinematics,
    ) -> Self {
        CommTask::with_source(
            ReferenceSource::Teleop(Box::new(teleop)),
            writer,
            state,
            goto,
            model,
            true,
        )
    }

    /// The teleoperation channel's end, given back when the loop stops.
    pub fn into_teleop_end(self) -> Option<super::teleop::TeleopEnd> {
        match self.source {
            ReferenceSource::Teleop(t) => Some(t.into_end()),
            ReferenceSource::Trajectory(_) => None,
        }
    }

    fn from(&self) -> Reference {
        let joints = self.last.unwrap_or(JointReference {
            position: self.measured.unwrap_or_else(JointVector::zeros),
            ..JointReference::default()
        });
        if self.tool_goals {
            Reference::Cartesian(penelope_hal::CartesianReference {
                pose: self.model.forward(&joints.position),
                twist: Twist::default(),
            })
        } else {
            Reference::Joint(joints)
        }
    }

    /// One communication tick at `now`.
    ///
    /// # Real-time
    /// No allocation, no locks: cell reads and writes, one ring pop, bounded spline set-up.
    pub fn tick(&mut self, now: Timestamp) {
        if let ReferenceSource::Teleop(t) = &mut self.source {
            let state = self.state.latest();
            t.tick(now, state, &mut self.writer);
            self.published += 1;
            return;
        }
        if let Some(s) = self.state.latest() {
            self.measured = Some(s.q);
        }
        if self.measured.is_none() {
            return; // the loop has not measured yet: start from the measured state, not zeros
        }
        if !self.started {
            let from = self.from();
            if let ReferenceSource::Trajectory(t) = &mut self.source {
                t.start(now, &from);
            }
            self.started = true;
        }
        if let Some(cmd) = self.goto.pop()
            && let Ok(mut t) = NodeTrajectory::go_to(cmd.goal, cmd.duration)
        {
            // A GoTo moves in joint space, from the current joint reference.
            self.tool_goals = false;
            let from = self.from();
            t.start(now, &from);
            self.source = ReferenceSource::Trajectory(t);
        }
        let ReferenceSource::Trajectory(trajectory) = &mut self.source else {
            return;
        };
        let Ok(r) = trajectory.reference(now) else {
            return;
        };
        if !r.is_finite() {
            return;
        }
        let out = match r {
            Reference::Joint(j) => {
                self.last = Some(j);
                if self.cartesian {
                    let pose = self.model.forward(&j.position);
                    let v = self.model.jacobian(&j.position, JacobianFrame::Base) * j.velocity;
                    Reference::Cartesian(penelope_hal::CartesianReference {
                        pose,
                        twist: Twist {
                            linear: v.fixed_rows::<3>(0).into(),
                            angular: v.fixed_rows::<3>(3).into(),
                            frame: Frame::Base,
                        },
                    })
                } else {
                    r
                }
            }
            // A tool reference for a joint law: the inverse kinematics branch nearest the last
            // joint reference, its velocity from the previous solution.
            Reference::Cartesian(c) if !self.cartesian => {
                let seed = self
                    .last
                    .map(|j| j.position)
                    .or(self.measured)
                    .unwrap_or_else(JointVector::zeros);
                let Ok(q) = self.model.inverse_near(&c.pose, &seed) else {
                    self.ik_failures += 1;
                    return;
                };
                let velocity = match (self.last, self.last_at) {
                    (Some(l), Some(at)) if now > at => {
                        (q - l.position) / now.saturating_since(at).as_secs_f64()
                    }
                    _ => JointVector::zeros(),
                };
                let j = JointReference {
                    position: q,
                    velocity,
                    acceleration: JointVector::zeros(),
                };
                self.last = Some(j);
                self.last_at = Some(now);
                Reference::Joint(j)
            }
            other => other,
        };
        self.writer.write(Stamped {
            stamp: now,
            value: out,
        });
        self.published += 1;
    }

    /// References published so far.
    pub fn published(&self) -> u64 {
        self.published
    }
}

// ---------------------------------------------------------------------------------------------
// Sensors
// ---------------------------------------------------------------------------------------------

/// The state of a `sensor/virtual`: an environment pushed by a probe.
#[derive(Clone, Debug)]
pub struct VirtualSensor {
    environment: Environment,
    bias: Wrench,
    last_raw: Wrench,
    probes: u64,
}

impl VirtualSensor {
    /// A sensor over `environment`, no bias.
    pub fn new(environment: Environment) -> Self {
        VirtualSensor {
            environment,
            bias: Wrench::zero(Frame::Base),
            last_raw: Wrench::zero(Frame::Base),
            probes: 0,
        }
    }

    /// The wrench the environment applies to a probe at `pose` moving at `velocity` (base frame,
    /// N and N·m about the probe point), minus the bias. Also the new [`read`](Self::read).
    pub fn measure(&mut self, pose: &Pose, velocity: Vector3<f64>) -> Wrench {
        use penelope_drivers::sim::Interaction;
        let twist = Twist {
            linear: velocity,
            angular: Vector3::zeros(),
            frame: Frame::Base,
        };
        self.last_raw = self
            .environment
            .wrench_on_tool(Timestamp::ZERO, pose, &twist);
        self.probes += 1;
        self.read()
    }

    /// The wrench at the last probe, minus the bias.
    pub fn read(&self) -> Wrench {
        Wrench {
            force: self.last_raw.force - self.bias.force,
            torque: self.last_raw.torque - self.bias.torque,
            frame: Frame::Base,
        }
    }

    /// Takes the wrench at the last probe as the zero.
    pub fn bias(&mut self) {
        self.bias = self.last_raw;
    }

    /// Probes so far.
    pub fn probes(&self) -> u64 {
        self.probes
    }
}

/// Where a controller's sensor feed gets its wrench.
pub enum SensorSource {
    /// A sensor on another node, at a naming path, through the node's [`Remote`].
    Remote {
        /// The node's remote.
        remote: Arc<dyn Remote>,
        /// The naming path.
        path: String,
    },
    /// A `sensor/virtual` on this node.
    Local(Arc<Mutex<VirtualSensor>>),
}

impl SensorSource {
    /// One measurement for a probe at `pose` moving at `velocity`.
    ///
    /// # Errors
    /// The remote's error, or [`WireError::Remote`] for an answer that is not a wrench.
    pub fn measure(&self, pose: &Pose, velocity: Vector3<f64>) -> Result<Wrench, WireError> {
        match self {
            SensorSource::Remote { remote, path } => {
                let method = Method::Sensor(SensorMethod::Measure {
                    pose: PoseMsg::from(pose),
                    velocity: [velocity.x, velocity.y, velocity.z],
                });
                match remote.call(path, method)? {
                    Reply::Wrench(w) => w.to_wrench(Frame::Base),
                    other => Err(WireError::Remote(format!(
                        "sensor `{path}` answered {other:?}, not a wrench"
                    ))),
                }
            }
            SensorSource::Local(s) => {
                let mut s = s
                    .lock()
                    .map_err(|_| WireError::Internal("sensor state poisoned".into()))?;
                Ok(s.measure(pose, velocity))
            }
        }
    }
}

/// Counters of a sensor feed.
#[derive(Debug, Default)]
pub struct FeedStats {
    /// Wrenches published.
    pub ok: AtomicU64,
    /// Failed measurements.
    pub failed: AtomicU64,
}

/// Runs a sensor feed until `stop`: every `period`, the tool pose and velocity of the newest
/// sample go to `source`, and the wrench (stamped on `CLOCK_MONOTONIC`) into `out`. A failing
/// source publishes nothing, so the loop's wrench goes stale; it never blocks the loop.
#[allow(clippy::too_many_arguments)]
pub fn run_sensor_feed(
    source: &SensorSource,
    model: &RobotKinematics,
    state: &mut ArcLatestReader<TelemetrySample>,
    out: &mut ArcLatestWriter<Stamped<Wrench>>,
    period: Duration,
    stop: &AtomicBool,
    stats: &FeedStats,
    name: &str,
) {
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(period);
        let Some(s) = state.latest() else { continue };
        let pose = model.forward(&s.q);
        let v = model.jacobian(&s.q, JacobianFrame::Base) * s.qd;
        match source.measure(&pose, Vector3::new(v[0], v[1], v[2])) {
            Ok(w) if w.is_finite() => {
                out.write(Stamped {
                    stamp: MonotonicClock::read(),
                    value: w,
                });
                stats.ok.fetch_add(1, Ordering::Relaxed);
            }
            Ok(_) | Err(_) => {
                if stats.failed.fetch_add(1, Ordering::Relaxed) == 0 {
                    log::warn!(
                        "controller `{name}`: sensor measurement failed; the wrench goes stale"
                    );
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Telemetry: the pump and the subscriptions
// ---------------------------------------------------------------------------------------------

/// The newest state of a running loop, as the pump keeps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Newest {
    /// The newest sample.
    pub sample: TelemetrySample,
    /// Joint accelerations estimated from the two newest samples, rad/s².
    pub acceleration: JointVector,
}

/// What a running loop shares with the non-real-time side.
#[derive(Debug, Default)]
pub struct LoopShared {
    /// The newest sample.
    pub newest: Mutex<Option<Newest>>,
    /// Samples the telemetry ring dropped.
    pub dropped: AtomicU64,
    /// Samples drained.
    pub drained: AtomicU64,
}

impl LoopShared {
    /// The newest sample.
    pub fn newest(&self) -> Option<Newest> {
        self.newest.lock().ok().and_then(|g| *g)
    }
}

/// One telemetry subscription.
#[derive(Debug)]
struct Subscription {
    id: u64,
    session: u64,
    controller: String,
    decimation: u64,
    outbox: Outbox,
    dropped: u64,
}

/// Every subscription of a creator (non-real-time side only).
#[derive(Debug, Default)]
pub struct Subscriptions {
    list: Mutex<Vec<Subscription>>,
    next: AtomicU64,
}

impl Subscriptions {
    /// How many there are.
    pub fn len(&self) -> usize {
        self.list.lock().map(|l| l.len()).unwrap_or(0)
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Adds one (at most `limit`), returning its id.
    ///
    /// # Errors
    /// [`WireError::LimitReached`].
    pub fn add(
        &self,
        session: u64,
        controller: &str,
        decimation: u32,
        outbox: Outbox,
        limit: u32,
    ) -> Result<u64, WireError> {
        let mut list = self
            .list
            .lock()
            .map_err(|_| WireError::Internal("subscriptions poisoned".into()))?;
        list.retain(|s| !s.outbox.is_closed());
        if list.len() >= limit as usize {
            return Err(WireError::LimitReached {
                what: "subscriptions".into(),
                limit,
            });
        }
        let id = self.next.fetch_add(1, Ordering::Relaxed) + 1;
        list.push(Subscription {
            id,
            session,
            controller: controller.to_string(),
            decimation: u64::from(decimation.max(1)),
            outbox,
            dropped: 0,
        });
        Ok(id)
    }

    /// Removes subscription `id` of `session`; false if there was none.
    pub fn remove(&self, session: u64, id: u64) -> bool {
        let Ok(mut list) = self.list.lock() else {
            return false;
        };
        let before = list.len();
        list.retain(|s| !(s.id == id && s.session == session));
        list.len() != before
    }

    /// Removes every subscription of `session`.
    pub fn remove_session(&self, session: u64) {
        if let Ok(mut list) = self.list.lock() {
            list.retain(|s| s.session != session);
        }
    }

    /// Sends `samples` of `controller` to its subscribers, decimated, without waiting: a full
    /// outbox loses the batch (counted), a closed one ends the subscription.
    pub fn publish(&self, controller: &str, samples: &[TelemetrySample], joints: usize) {
        if samples.is_empty() {
            return;
        }
        let Ok(mut list) = self.list.lock() else {
            return;
        };
        list.retain_mut(|s| {
            if s.controller != controller {
                return true;
            }
            let records: Vec<TelemetryRecord> = samples
                .iter()
                .filter(|x| x.seq % s.decimation == 0)
                .map(|x| record(x, joints))
                .collect();
            if records.is_empty() {
                return true;
            }
            let batch = TelemetryBatch {
                subscription: s.id,
                dropped: s.dropped,
                samples: records,
            };
            if s.outbox.try_push(ServerMsg::Telemetry(batch)) {
                true
            } else if s.outbox.is_closed() {
                false
            } else {
                s.dropped += 1;
                true
            }
        });
    }
}

/// A sample as a client sees it.
pub fn record(s: &TelemetrySample, joints: usize) -> TelemetryRecord {
    TelemetryRecord {
        time_ns: s.time.as_nanos(),
        seq: s.seq,
        q: joints_from_vector(&s.q, joints),
        qd: joints_from_vector(&s.qd, joints),
        effort: joints_from_vector(&s.effort, joints),
        tool_position: [s.tool_position.x, s.tool_position.y, s.tool_position.z],
        wrench: WrenchMsg::from(&s.wrench),
        state: s.state.as_str().to_string(),
        fault: s.fault.map(|f| f.to_string()),
    }
}

/// Runs a telemetry pump until `stop` (then drains once more): every `period`, takes every sample
/// out of the ring, keeps the newest in `shared`, and publishes them to the subscribers of
/// `controller`.
#[allow(clippy::too_many_arguments)]
pub fn run_pump(
    ring: &mut ArcConsumer<TelemetrySample, TELEMETRY_CAPACITY>,
    shared: &LoopShared,
    subscriptions: &Subscriptions,
    controller: &str,
    joints: usize,
    period: Duration,
    stop: &AtomicBool,
) {
    let mut batch: Vec<TelemetrySample> = Vec::with_capacity(TELEMETRY_CAPACITY);
    let mut previous: Option<TelemetrySample> = shared.newest().map(|n| n.sample);
    loop {
        let last_round = stop.load(Ordering::Acquire);
        if !last_round {
            std::thread::sleep(period);
        }
        batch.clear();
        while let Some(s) = ring.pop() {
            batch.push(s);
        }
        shared
            .dropped
            .store(ring.dropped() as u64, Ordering::Relaxed);
        shared
            .drained
            .fetch_add(batch.len() as u64, Ordering::Relaxed);
        if let Some(last) = batch.last().copied() {
            let before = batch.len().checked_sub(2).map(|i| batch[i]).or(previous);
            let acceleration = match before {
                Some(b) if last.time > b.time => {
                    (last.qd - b.qd) / (last.time - b.time).as_secs_f64()
                }
                _ => JointVector::zeros(),
            };
            if let Ok(mut g) = shared.newest.lock() {
                *g = Some(Newest {
                    sample: last,
                    acceleration,
                });
            }
            previous = Some(last);
        }
        subscriptions.publish(controller, &batch, joints);
        if last_round {
            break;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The threads of a running controller
// ---------------------------------------------------------------------------------------------

/// The threads of an active controller and the non-real-time ends of their ports.
pub struct Running {
    /// The control thread.
    pub control: Option<PeriodicThread>,
    /// Asks the control thread to hand its task back and stop.
    pub control_stop: Arc<AtomicBool>,
    /// Where the control thread hands its task back.
    pub control_back: Receiver<ControlTask>,
    /// The communication thread.
    pub comm: Option<PeriodicThread>,
    /// Asks the communication thread to hand its task back and stop.
    pub comm_stop: Arc<AtomicBool>,
    /// Where the communication thread hands its task back.
    pub comm_back: Receiver<CommTask>,
    /// Commands to the loop.
    pub commands: ArcProducer<penelope_rt_core::control::ControlCommand, COMMAND_CAPACITY>,
    /// GoTo requests to the communication task.
    pub goto: ArcProducer<GoToCommand, GOTO_CAPACITY>,
    /// New gains to the loop.
    pub gains: ArcLatestWriter<GainsUpdate>,
    /// The pump thread and its stop flag.
    pub pump: Option<std::thread::JoinHandle<()>>,
    /// Stops the pump and the sensor feed.
    pub aux_stop: Arc<AtomicBool>,
    /// The sensor feed thread.
    pub feed: Option<std::thread::JoinHandle<()>>,
    /// Sensor feed counters.
    pub feed_stats: Arc<FeedStats>,
    /// Newest state and counters.
    pub shared: Arc<LoopShared>,
    /// True when the control thread runs SCHED_FIFO.
    pub fifo: bool,
    /// The control period.
    pub period: Duration,
    /// Where the loop's threads report a failure.
    pub fault: Arc<LoopFault>,
}

impl Running {
    /// Overruns of the control thread so far.
    pub fn overruns(&mut self) -> u64 {
        self.control
            .as_mut()
            .and_then(PeriodicThread::live)
            .map_or(0, |l| l.overruns)
    }

    /// Why the loop failed, if it did: a thread reported a panic, or a thread ended although
    /// nobody asked it to.
    pub fn failure(&self) -> Option<String> {
        if self.fault.is_failed() {
            return Some(
                self.fault
                    .cause()
                    .unwrap_or_else(|| "a thread failed".into()),
            );
        }
        if self.control_stop.load(Ordering::Acquire) {
            return None;
        }
        if self
            .control
            .as_ref()
            .is_some_and(PeriodicThread::is_finished)
        {
            return Some("the control thread ended unexpectedly".into());
        }
        if self.comm.as_ref().is_some_and(PeriodicThread::is_finished) {
            return Some("the communication thread ended unexpectedly".into());
        }
        None
    }

    /// Stops the threads of a loop that failed (its control thread already brought the robot
    /// to its safe state, or is told to now) and returns the control task (`None` if its
    /// thread died with it).
    pub fn stop_failed(mut self) -> StoppedLoop {
        if let Some(cause) = self.failure() {
            self.fault.record(cause);
        }
        // The control thread sees the failure on its next tick, stops the robot and hands
        // the task back.
        let control = self.control_back.recv_timeout(Duration::from_secs(2)).ok();
        self.control_stop.store(true, Ordering::Release);
        let comm = self.join_all();
        StoppedLoop { control, comm }
    }

    /// Joins every thread; returns the communication task if its thread handed it back.
    fn join_all(&mut self) -> Option<CommTask> {
        if let Some(t) = self.control.take() {
            let _ = t.join();
        }
        self.comm_stop.store(true, Ordering::Release);
        let comm = match self.comm.take() {
            Some(t) if !t.is_finished() => {
                let task = self.comm_back.recv_timeout(Duration::from_secs(2)).ok();
                let _ = t.join();
                task
            }
            Some(t) => {
                let _ = t.join();
                self.comm_back.try_recv().ok()
            }
            None => None,
        };
        self.aux_stop.store(true, Ordering::Release);
        if let Some(t) = self.feed.take() {
            let _ = t.join();
        }
        if let Some(t) = self.pump.take() {
            let _ = t.join();
        }
        comm
    }

    /// Stops everything: `Deactivate` to the loop (amplifiers off), a few periods for it to take
    /// effect, then the threads are joined. Returns the tasks (`None` where a thread died).
    pub fn stop(mut self) -> StoppedLoop {
        let _ = self
            .commands
            .push(penelope_rt_core::control::ControlCommand::Deactivate);
        std::thread::sleep((self.period * 4).max(Duration::from_millis(5)));
        self.control_stop.store(true, Ordering::Release);
        let control = self.control_back.recv_timeout(Duration::from_secs(2)).ok();
        let comm = self.join_all();
        StoppedLoop { control, comm }
    }
}

/// How the threads of a running loop report that one of them failed (a panic, or an exit
/// nobody asked for). The control thread reads [`is_failed`](Self::is_failed) every tick; the
/// cause is written once, on the failure path only.
#[derive(Debug, Default)]
pub struct LoopFault {
    failed: AtomicBool,
    cause: Mutex<Option<String>>,
    /// A panic asked for by a fault-injection test: 0 none, else a [`LoopThread`] + 1.
    #[cfg(feature = "fault-injection")]
    inject: std::sync::atomic::AtomicU8,
}

/// The threads of a running loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopThread {
    /// The control thread.
    Control,
    /// The communication thread.
    Communication,
}

impl LoopFault {
    /// Makes `thread` panic in its next tick, as a bug would (fault-injection tests only).
    #[cfg(feature = "fault-injection")]
    pub fn inject_panic(&self, thread: LoopThread) {
        self.inject.store(thread as u8 + 1, Ordering::Release);
    }

    /// Panics if a panic of `thread` was injected (nothing without the `fault-injection`
    /// feature).
    #[inline(always)]
    fn injected(&self, thread: LoopThread) {
        #[cfg(feature = "fault-injection")]
        if self.inject.load(Ordering::Acquire) == thread as u8 + 1 {
            panic!("injected fault");
        }
        let _ = thread;
    }
}

impl LoopFault {
    /// Records a failure (the first cause is kept).
    pub fn record(&self, cause: String) {
        if let Ok(mut c) = self.cause.lock() {
            c.get_or_insert(cause);
        }
        self.failed.store(true, Ordering::Release);
    }

    /// True once a thread of the loop failed.
    ///
    /// # Real-time
    /// One atomic load.
    pub fn is_failed(&self) -> bool {
        self.failed.load(Ordering::Acquire)
    }

    /// The first failure's cause.
    pub fn cause(&self) -> Option<String> {
        self.cause.lock().ok().and_then(|c| c.clone())
    }
}

/// The text of a panic's payload.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_string())
}

/// Runs `f`; a panic in it becomes `Err(its message)` instead of unwinding further.
///
/// # Real-time
/// Free when `f` does not panic (unwinding costs only on the failure path).
pub fn guarded<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|p| panic_text(p.as_ref()))
}

/// The body of a control thread: ticks `task` until `stop`, then hands it back through `back`.
///
/// A tick that panics, or a failure of the loop's other threads reported through `fault`,
/// brings the robot to its safe state ([`ControlLoop::fail_safe`]: e-stop latched, amplifiers
/// off or the board's servo holding), records the cause, hands the task back and ends the
/// thread; the creator then shows the controller in `error`.
pub fn control_body(
    task: ControlTask,
    stop: Arc<AtomicBool>,
    back: SyncSender<ControlTask>,
    fault: Arc<LoopFault>,
) -> impl FnMut(penelope_rt_core::exec::Tick) -> Flow + Send + 'static {
    let mut task = Some(task);
    move |tick| {
        let Some(t) = task.as_mut() else {
            return Flow::Stop;
        };
        if stop.load(Ordering::Acquire) {
            if let Some(t) = task.take() {
                let _ = back.try_send(t);
            }
            return Flow::Stop;
        }
        let failed = fault.is_failed()
            || match guarded(|| {
                fault.injected(LoopThread::Control);
                t.note_timing(tick.latency(), tick.previous_exec);
                t.tick(tick.deadline)
            }) {
                Ok(_) => false,
                Err(why) => {
                    fault.record(format!("the control thread panicked: {why}"));
                    true
                }
            };
        if failed {
            if let Err(why) = guarded(|| t.fail_safe(tick.deadline)) {
                // The loop cannot even stop itself: the creator turns the board off when it
                // takes it back.
                log::error!("stopping a failed loop panicked too: {why}");
            }
            if let Some(t) = task.take() {
                let _ = back.try_send(t);
            }
            return Flow::Stop;
        }
        Flow::Continue
    }
}

/// The body of a communication thread: ticks `comm` until `stop`, then hands it back through
/// `back` (it may hold a teleoperation channel's end); a panicking tick records the cause in
/// `fault` (the control thread then stops the robot safely) and ends the thread.
pub fn comm_body(
    comm: CommTask,
    fault: Arc<LoopFault>,
    stop: Arc<AtomicBool>,
    back: SyncSender<CommTask>,
) -> impl FnMut(penelope_rt_core::exec::Tick) -> Flow + Send + 'static {
    let mut comm = Some(comm);
    move |tick| {
        let Some(c) = comm.as_mut() else {
            return Flow::Stop;
        };
        if stop.load(Ordering::Acquire) {
            if let Some(c) = comm.take() {
                let _ = back.try_send(c);
            }
            return Flow::Stop;
        }
        match guarded(|| {
            fault.injected(LoopThread::Communication);
            c.tick(tick.deadline)
        }) {
            Ok(()) => Flow::Continue,
            Err(why) => {
                fault.record(format!("the communication thread panicked: {why}"));
                Flow::Stop
            }
        }
    }
}

/// What a stopped loop hands back: its control task (with the board) and its communication
/// task (with a teleoperation channel's end), each `None` if its thread died with it.
pub struct StoppedLoop {
    /// The control task.
    pub control: Option<ControlTask>,
    /// The communication task.
    pub comm: Option<CommTask>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_drivers::model::puma560;
    use penelope_drivers::sim::board::SimBoardConfig as DriverSimConfig;
    use penelope_drivers::sim::plant::PlantConfig;

    #[test]
    fn a_stalled_loop_finds_the_simulated_world_paused_not_fast_forwarded() {
        let model = puma560();
        let body = SimBody::new(
            model.clone(),
            PlantConfig::default(),
            DriverSimConfig {
                counts_per_radian: JointVector::repeat(1000.0),
                effort_full_scale: JointVector::repeat(100.0),
                dac_bits: 16,
                position_kp: JointVector::repeat(100.0),
                position_kd: JointVector::repeat(1.0),
                velocity_cutoff_hz: 0.0,
            },
            ToolContact::Environment(Environment::new()),
            JointVector::zeros(),
            Timestamp::ZERO,
        );
        let mut board = LoopBoard::Sim(Box::new(body), None);
        let mut out = [AxisState::default(); MAX_AXES];
        let start = 5_000_000_000_u64;
        board
            .read_axes(Timestamp::from_nanos(start), &mut out[..6])
            .unwrap();
        let plant_ns = |b: &LoopBoard| match b {
            LoopBoard::Sim(s, _) => s.plant().snapshot().time.as_nanos(),
            LoopBoard::Galil(_) => unreachable!(),
        };
        // The first call anchors the loop's clock to the plant's.
        assert_eq!(plant_ns(&board), 0);
        // A 1 ms tick advances the plant by 1 ms.
        board
            .read_axes(Timestamp::from_nanos(start + 1_000_000), &mut out[..6])
            .unwrap();
        assert_eq!(plant_ns(&board), 1_000_000);
        // A 2 s stall advances it by at most MAX_PLANT_STEP_NS...
        board
            .read_axes(Timestamp::from_nanos(start + 2_001_000_000), &mut out[..6])
            .unwrap();
        assert_eq!(plant_ns(&board), 1_000_000 + MAX_PLANT_STEP_NS);
        // ...and the ticks after it advance it by their period again.
        board
            .read_axes(Timestamp::from_nanos(start + 2_002_000_000), &mut out[..6])
            .unwrap();
        assert_eq!(plant_ns(&board), 2_000_000 + MAX_PLANT_STEP_NS);
    }
}
