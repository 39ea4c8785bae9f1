//! The control laws a node runs, the loop's ports and the control task.

use super::*;

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
