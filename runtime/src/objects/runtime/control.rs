//! The control laws a node runs, the loop's ports and the control task.

use crate::objects::reference::ReferencePort;
use crate::objects::runtime::{Commands, JointBoard, RobotKinematics};
use crate::objects::runtime::{GAINS_CAPACITY, TELEMETRY_CAPACITY};
use crate::objects::tick::TickRecord;
use penelope_drivers::sim::force_sensor::VirtualForceSensor;
use penelope_drivers::sim::tap::TapReader;
use penelope_hal::{
    ControlInput, Controller, ControllerError, Error, ErrorKind, JointCommand, JointState, Pose,
    RobotModel, Sensor, Timestamp, Wrench,
};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Stamped};
use penelope_rt_core::control::{ControlLoop, NoSensor, TickOutcome};
use penelope_rt_core::controller::{JointGroups, JointPid, JointPidGains, JointPositionServo};
use penelope_rt_core::ring::{ArcConsumer, ArcProducer};
use penelope_rt_core::safety::EventSet;
use penelope_rt_core::telemetry::{TelemetrySample, TelemetrySink};
use penelope_rt_core::teleop::{
    CartesianImpedance, ForceDisplay, ForceDisplayConfig, FourChannelConfig, FourChannelMaster,
    FourChannelSlave, FourChannelSlaveConfig, ImpedanceConfig, PositionErrorMaster, SlaveTracking,
    TrackingConfig,
};
use penelope_rt_core::wake::Doorbell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// The control laws a node runs. Inline, not boxed: one per loop, built before its thread
/// starts, and the control thread must reach it without a pointer chase.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum ControlLaw {
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
    /// `controller/four-channel-master`.
    FourChannel(FourChannelMaster),
    /// `controller/slave-tracking` and `controller/slave-position`.
    SlaveTracking(SlaveTracking),
    /// `controller/four-channel-slave`.
    FourChannelSlave(FourChannelSlave),
    /// `controller/joint-groups`: members on joint subsets, in one loop.
    Groups(Box<JointGroups<ControlLaw>>),
}

impl ControlLaw {
    /// True when the law follows Cartesian references.
    pub fn is_cartesian(&self) -> bool {
        matches!(self, ControlLaw::Impedance(_))
    }

    /// Tells a law that adds a sensed wrench where the loop's force sensor sits in the tool
    /// frame (the four-channel halves; the others read no mount).
    pub fn set_sensor_mount(&mut self, mount: Option<Pose>) {
        match self {
            ControlLaw::FourChannel(c) => c.set_sensor_mount(mount),
            ControlLaw::FourChannelSlave(c) => c.set_sensor_mount(mount),
            _ => {}
        }
    }

    /// The law's inner controller.
    fn inner(&mut self) -> &mut dyn Controller {
        match self {
            ControlLaw::Pid(c) => c,
            ControlLaw::Impedance(c) => c,
            ControlLaw::Position(c) => c,
            ControlLaw::ForceDisplay(c) => c,
            ControlLaw::PositionErrorMaster(c) => c,
            ControlLaw::FourChannel(c) => c,
            ControlLaw::SlaveTracking(c) => c,
            ControlLaw::FourChannelSlave(c) => c,
            ControlLaw::Groups(c) => &mut **c,
        }
    }

    /// Applies new gains of the same law (others are ignored).
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn apply(&mut self, gains: &RoutedGains) {
        let (law, gains) = match (self, gains.member) {
            (ControlLaw::Groups(g), Some(i)) => match g.group_mut(usize::from(i)) {
                Some((_, member)) => (member, &gains.update),
                None => return,
            },
            (law, _) => (law, &gains.update),
        };
        match (law, gains) {
            (ControlLaw::Pid(p), GainsUpdate::Pid(g)) => p.set_gains(*g),
            // Checked before they were sent: a refusal keeps the old gains.
            (ControlLaw::Impedance(c), GainsUpdate::Impedance(g)) => {
                let _ = c.set_config(*g);
            }
            (ControlLaw::ForceDisplay(c), GainsUpdate::ForceDisplay(g)) => {
                let _ = c.set_config(*g);
            }
            (ControlLaw::PositionErrorMaster(c), GainsUpdate::PositionError(g)) => {
                let _ = c.set_config(*g);
            }
            (ControlLaw::FourChannel(c), GainsUpdate::FourChannel(g)) => {
                let _ = c.set_config(*g);
            }
            (ControlLaw::SlaveTracking(c), GainsUpdate::Tracking(g)) => {
                let _ = c.set_config(*g);
            }
            (ControlLaw::FourChannelSlave(c), GainsUpdate::FourChannelSlave(g)) => {
                let _ = c.set_config(*g);
            }
            _ => {}
        }
    }
}

impl Controller for ControlLaw {
    fn kind(&self) -> &'static str {
        match self {
            ControlLaw::Pid(c) => c.kind(),
            ControlLaw::Impedance(c) => c.kind(),
            ControlLaw::Position(c) => c.kind(),
            ControlLaw::ForceDisplay(c) => c.kind(),
            ControlLaw::PositionErrorMaster(c) => c.kind(),
            ControlLaw::FourChannel(c) => c.kind(),
            ControlLaw::SlaveTracking(c) => c.kind(),
            ControlLaw::FourChannelSlave(c) => c.kind(),
            ControlLaw::Groups(c) => c.kind(),
        }
    }
    fn activate(&mut self, now: Timestamp, measured: &JointState, model: &dyn RobotModel) {
        self.inner().activate(now, measured, model);
    }
    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        self.inner().update(input)
    }
    fn port_energy(&self) -> Option<f64> {
        match self {
            ControlLaw::Pid(c) => c.port_energy(),
            ControlLaw::Impedance(c) => c.port_energy(),
            ControlLaw::Position(c) => c.port_energy(),
            ControlLaw::ForceDisplay(c) => c.port_energy(),
            ControlLaw::PositionErrorMaster(c) => c.port_energy(),
            ControlLaw::FourChannel(c) => c.port_energy(),
            ControlLaw::SlaveTracking(c) => c.port_energy(),
            ControlLaw::FourChannelSlave(c) => c.port_energy(),
            ControlLaw::Groups(c) => c.port_energy(),
        }
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
    /// Four-channel master settings.
    FourChannel(FourChannelConfig),
    /// Slave-tracking settings.
    Tracking(TrackingConfig),
    /// Four-channel slave settings.
    FourChannelSlave(FourChannelSlaveConfig),
}

/// Gains on their way to a running loop: for the loop's own law, or for member `member` of a
/// joint-groups loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoutedGains {
    /// The group member (its index in the groups list), or `None` for the loop's law.
    pub member: Option<u8>,
    /// The new gains.
    pub update: GainsUpdate,
}

/// The control loop's telemetry port: every sample (with the plant's truth, if a plant is
/// behind the board) into the ring for the pump, and into latest-value cells for the
/// communication task and the sensor feed.
pub struct TelemetryPort {
    ring: ArcProducer<TickRecord, TELEMETRY_CAPACITY>,
    comm: ArcLatestWriter<TelemetrySample>,
    probe: ArcLatestWriter<TelemetrySample>,
    truth: Option<TapReader>,
    clutch: Option<Arc<AtomicBool>>,
    /// Wakes the communication thread on a new safety event (a teleoperation end's), or with
    /// every sample when `every_sample`.
    doorbell: Option<Arc<Doorbell>>,
    /// Ring with every sample: the communication thread sends each as it is made
    /// (event-driven handoff).
    every_sample: bool,
    /// The previous sample's safety events.
    events: EventSet,
}

impl TelemetryPort {
    /// A sink over these ports; `truth` reads the simulated plant, if there is one.
    pub fn new(
        ring: ArcProducer<TickRecord, TELEMETRY_CAPACITY>,
        comm: ArcLatestWriter<TelemetrySample>,
        probe: ArcLatestWriter<TelemetrySample>,
        truth: Option<TapReader>,
    ) -> Self {
        TelemetryPort {
            ring,
            comm,
            probe,
            truth,
            clutch: None,
            doorbell: None,
            every_sample: false,
            events: EventSet::EMPTY,
        }
    }

    /// Rings `doorbell` when a sample carries a safety event the previous one did not: the
    /// communication thread then sends it at once (a teleoperation end's urgent sample).
    pub fn with_doorbell(mut self, doorbell: Option<Arc<Doorbell>>) -> Self {
        self.doorbell = doorbell;
        self
    }

    /// Rings the doorbell with every sample (when `every`), not only on a new safety event:
    /// the communication thread sends each sample as it is made (event-driven handoff).
    pub fn ringing_every_sample(mut self, every: bool) -> Self {
        self.every_sample = every;
        self
    }

    /// Records the clutch button `clutch` of the operator's hand holding the robot with every
    /// tick.
    pub fn with_clutch(mut self, clutch: Option<Arc<AtomicBool>>) -> Self {
        self.clutch = clutch;
        self
    }
}

impl TelemetrySink for TelemetryPort {
    /// # Real-time
    /// Three wait-free cell operations, an atomic load, one ring push, and on a new safety
    /// event (with event-driven handoff: every sample) one non-blocking `write` (the doorbell).
    fn push(&mut self, sample: &TelemetrySample) -> bool {
        self.comm.write(*sample);
        self.probe.write(*sample);
        if (self.every_sample || sample.events.gained_since(self.events))
            && let Some(bell) = &self.doorbell
        {
            bell.ring();
        }
        self.events = sample.events;
        let truth = self.truth.as_mut().and_then(TapReader::latest);
        let clutch = self.clutch.as_ref().map(|c| c.load(Ordering::Relaxed));
        self.ring
            .push(TickRecord {
                sample: *sample,
                truth,
                clutch,
            })
            .is_ok()
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

/// A robot's control loop with sensor `F` (the variants of [`RobotLoop`]).
pub(crate) type Loop<F> = ControlLoop<
    JointBoard,
    RobotKinematics,
    [ControlLaw; 1],
    ReferencePort,
    TelemetryPort,
    Commands,
    F,
>;

/// A node's control loop, with or without a force sensor.
pub enum RobotLoop {
    /// No sensor bound.
    Plain(Box<Loop<NoSensor>>),
    /// A sensor bound (its wrench comes through a [`CellSensor`]).
    Sensed(Box<Loop<CellSensor>>),
    /// A wrist sensor reading the robot's own simulated plant, in the loop.
    Plant(Box<Loop<VirtualForceSensor>>),
    /// A `sensor/replay`: a recorded wrench stream, in the loop.
    Replayed(Box<Loop<crate::objects::replay::ReplaySensor>>),
    /// A sensor kind read in the loop's own thread (a device, such as a Net F/T), its type
    /// erased.
    Device(Box<Loop<crate::objects::runtime::LoopSensorReader>>),
}

/// `$body` with `$l` bound to the loop, whatever its sensor.
macro_rules! each_loop {
    ($lp:expr, $l:ident => $body:expr) => {
        match $lp {
            RobotLoop::Plain($l) => $body,
            RobotLoop::Sensed($l) => $body,
            RobotLoop::Plant($l) => $body,
            RobotLoop::Replayed($l) => $body,
            RobotLoop::Device($l) => $body,
        }
    };
}

impl RobotLoop {
    /// The board, model and controllers back (the loop is taken apart).
    pub fn into_board(self) -> JointBoard {
        each_loop!(self, l => l.into_parts().0)
    }

    /// The last tick's sample.
    pub fn last_sample(&self) -> &TelemetrySample {
        each_loop!(self, l => l.last_sample())
    }
}

/// The per-tick body of a control thread: new gains if any, then one [`ControlLoop::tick`].
pub struct ControlTask {
    lp: RobotLoop,
    gains: ArcConsumer<RoutedGains, GAINS_CAPACITY>,
}

impl ControlTask {
    /// A task over `lp`, taking gain changes from `gains`.
    pub fn new(lp: RobotLoop, gains: ArcConsumer<RoutedGains, GAINS_CAPACITY>) -> Self {
        ControlTask { lp, gains }
    }

    /// One control tick at `now`.
    ///
    /// # Real-time
    /// No allocation, no locks, no blocking (the ports are wait-free cells and rings; a simulated
    /// board steps its plant, a Galil board exchanges cells with its I/O thread), bounded time.
    pub fn tick(&mut self, now: Timestamp) -> TickOutcome {
        while let Some(g) = self.gains.pop() {
            each_loop!(&mut self.lp, l => l.controllers_mut()[0].apply(&g))
        }
        each_loop!(&mut self.lp, l => l.tick(now))
    }

    /// Applies `command` at `now` as if it came through the loop's command port (a test's or a
    /// stepped loop's way in; a thread's loop takes its commands from the ring).
    ///
    /// # Real-time
    /// As [`ControlLoop::apply`].
    pub fn apply(&mut self, now: Timestamp, command: penelope_rt_core::control::ControlCommand) {
        each_loop!(&mut self.lp, l => l.apply(now, command))
    }

    /// Passes the executor's timing of the previous tick to the loop.
    ///
    /// # Real-time
    /// Constant time.
    pub fn note_timing(&mut self, wake_latency: Duration, exec_time: Duration) {
        each_loop!(&mut self.lp, l => l.note_timing(wake_latency, exec_time))
    }

    /// The loop.
    pub fn control_loop(&self) -> &RobotLoop {
        &self.lp
    }

    /// Starts the plant keeper of a simulated body ([`SimDrive::start_keeper`](crate::objects::runtime::SimDrive::start_keeper)); nothing for
    /// Galil boards (their I/O thread watches the commands).
    pub fn keep_plant_moving(&mut self) {
        each_loop!(&mut self.lp, l => {
            if let JointBoard::Sim(d) | JointBoard::Fpga(d) = l.board_mut() {
                d.start_keeper();
            }
        })
    }

    /// The loop, taken out.
    pub fn into_loop(self) -> RobotLoop {
        self.lp
    }

    /// Brings the robot to its safe state after a failure ([`ControlLoop::fail_safe`]).
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn fail_safe(&mut self, now: Timestamp) {
        each_loop!(&mut self.lp, l => l.fail_safe(now))
    }

    /// The control thread's last act when it is stopped on purpose
    /// ([`ControlLoop::stop_safely`]): a slave still driven is held by its board's servo,
    /// anything else gets zero torque with its amplifiers off, before any thread is joined.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn stop_safely(&mut self, now: Timestamp) {
        each_loop!(&mut self.lp, l => l.stop_safely(now))
    }

    /// Leaves the robot held at its last measured pose by the board's own servo (a Galil's, or
    /// a simulated board's), for a loop being stopped; `false` when there was nothing to hold.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn hand_to_board_servo(&mut self) -> bool {
        each_loop!(&mut self.lp, l => {
            let now = l.last_sample().time;
            l.hold_with_board_servo(now)
        })
    }

    /// Whether the loop holds its robot with the board's own servo (rather than with torques).
    pub fn holds_with_board_servo(&self) -> bool {
        let hold = each_loop!(&self.lp, l => l.config().safety.hold);
        matches!(hold, penelope_rt_core::safety::HoldMode::BoardServo)
    }
}
