//! The control loop (period `T_ctrl`): read the board, take the latest reference, supervise,
//! run the active controller, write the board, report telemetry. One call of
//! [`ControlLoop::tick`] per period, with the tick's time passed in.
//!
//! The loop owns its [`Board`], its robot model, a [`ControllerSet`], an optional force sensor, and
//! three ports:
//!
//! - `reference`: a [`ReferenceSource`], normally the [`LatestReader`] the communication loop
//!   writes;
//! - `telemetry`: a [`TelemetrySink`], normally a ring [`Producer`](crate::ring::Producer);
//! - `commands`: a [`CommandSource`], normally a ring [`Consumer`] of [`ControlCommand`]s from the
//!   non-real-time side (activate, switch controller, e-stop, re-arm).
//!
//! ```
//! use core::time::Duration;
//! use penelope_hal::{JointVector, RobotModel, Timestamp};
//! use penelope_rt_core::cell::LatestCell;
//! use penelope_rt_core::control::{ControlCommand, ControlConfig, ControlLoop, ControlPorts};
//! use penelope_rt_core::controller::{JointPid, JointPidGains};
//! use penelope_rt_core::ring::Ring;
//! use penelope_rt_core::safety::{SafetyConfig, SafetyState};
//! use penelope_rt_core::telemetry::TelemetrySample;
//! use penelope_testbed::{ChainBoard, DecoupledChain};
//!
//! let model = DecoupledChain::six_joint();
//! let board = ChainBoard::new(model.clone(), 1000.0);
//! let safety = SafetyConfig::slave(6, *model.limits());
//! let config = ControlConfig::new(Duration::from_millis(1), safety).with_counts_per_radian(1000.0);
//! let pid = JointPid::new(JointPidGains::pd(JointVector::repeat(100.0), JointVector::repeat(10.0)));
//!
//! let reference = LatestCell::new();
//! let (_ref_writer, ref_reader) = reference.split().unwrap();
//! let telemetry = Ring::<TelemetrySample, 64>::new();
//! let (tel_tx, mut tel_rx) = telemetry.split().unwrap();
//! let commands = Ring::<ControlCommand, 8>::new();
//! let (mut cmd_tx, cmd_rx) = commands.split().unwrap();
//!
//! let ports = ControlPorts { reference: ref_reader, telemetry: tel_tx, commands: cmd_rx };
//! let mut ctl = ControlLoop::new(config, board, model, [pid], ports).unwrap();
//! cmd_tx.push(ControlCommand::Activate).unwrap();
//! let out = ctl.tick(Timestamp::from_nanos(1_000_000));
//! // No reference yet: a slave holds the position it was activated at.
//! assert_eq!(out.state, SafetyState::Holding);
//! assert_eq!(tel_rx.pop().unwrap().seq, 1);
//! ```

use core::fmt;
use core::ops::Deref;
use core::time::Duration;

use penelope_hal::{
    AxisCommand, AxisState, Board, ControlInput, ControllerError, Error, Frame, JointCommand,
    JointState, JointVector, MAX_AXES, Reference, RobotModel, Sensor, Timestamp, Wrench,
};

use crate::cell::{Fresh, LatestCell, LatestReader, Stamped};
use crate::controller::ControllerSet;
use crate::ring::{Consumer, Ring};
use crate::safety::{
    Action, EventSet, FaultAction, FaultCause, HoldMode, Safety, SafetyEvent, SafetyState,
    TeleopRole,
};
use crate::telemetry::{ReferenceKind, TelemetrySample, TelemetrySink};

/// At most this many commands are taken from the command port per tick (bounded work).
pub const MAX_COMMANDS_PER_TICK: usize = 4;

/// A request from the non-real-time side to the control loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlCommand {
    /// Enable the amplifiers and start from the measured state.
    Activate,
    /// Amplifiers off.
    Deactivate,
    /// Make controller `index` active (re-activated from the measured state if running).
    SwitchController(u8),
    /// Latch the emergency stop (amplifiers off until re-armed).
    EStop,
    /// Clear a latched fault or e-stop (then `Activate` again).
    Rearm,
}

/// Where the control loop reads references.
pub trait ReferenceSource {
    /// The newest stamped reference and whether it is new.
    ///
    /// # Real-time
    /// Implementations must be wait-free and allocation-free.
    fn read(&mut self) -> Fresh<Stamped<Reference>>;

    /// Safety events raised by whatever produces the references since the last call (a
    /// teleoperation channel's link lost or restored), noted in the tick's events. None by
    /// default.
    ///
    /// # Real-time
    /// Implementations must be wait-free and allocation-free.
    fn take_events(&mut self) -> EventSet {
        EventSet::EMPTY
    }

    /// The two-port passivity observer's energy at this side's port, as last published by
    /// whatever produces the references (a teleoperation channel's end), J; recorded in the
    /// tick's telemetry. `None` by default.
    ///
    /// # Real-time
    /// Implementations must be wait-free and allocation-free.
    fn channel_energy(&mut self) -> Option<f64> {
        None
    }
}

impl<P: Deref<Target = LatestCell<Stamped<Reference>>>> ReferenceSource
    for LatestReader<Stamped<Reference>, P>
{
    fn read(&mut self) -> Fresh<Stamped<Reference>> {
        LatestReader::read(self)
    }
}

/// Where the control loop takes commands.
pub trait CommandSource {
    /// The next pending command, if any.
    ///
    /// # Real-time
    /// Implementations must be wait-free and allocation-free.
    fn next_command(&mut self) -> Option<ControlCommand>;
}

impl<const N: usize, P: Deref<Target = Ring<ControlCommand, N>>> CommandSource
    for Consumer<ControlCommand, N, P>
{
    fn next_command(&mut self) -> Option<ControlCommand> {
        self.pop()
    }
}

/// A command port that never has a command.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCommands;

impl CommandSource for NoCommands {
    fn next_command(&mut self) -> Option<ControlCommand> {
        None
    }
}

/// The control loop's three ports.
#[derive(Debug)]
pub struct ControlPorts<R, T, Q> {
    /// References in.
    pub reference: R,
    /// Telemetry out.
    pub telemetry: T,
    /// Commands in.
    pub commands: Q,
}

/// A force-sensor slot that is always empty (the default of [`ControlLoop`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoSensor;

impl Sensor for NoSensor {
    type Error = core::convert::Infallible;
    type Reading = Wrench;
    fn read(&mut self, _now: Timestamp) -> Result<Wrench, Self::Error> {
        Ok(Wrench::zero(Frame::Base))
    }
}

mod config;

use config::position_counts;
pub use config::{AxisBinding, ControlConfig, ControlConfigError, DEFAULT_RESUME_TOLERANCE};

/// What one tick did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickOutcome {
    /// The tick counter (1 for the first tick).
    pub seq: u64,
    /// Safety state after the tick.
    pub state: SafetyState,
    /// Events of the tick.
    pub events: EventSet,
}

/// The control loop of one robot. See the [module docs](self).
///
/// Type parameters: board `B`, robot model `M`, controllers `C`, reference port `R`, telemetry
/// port `T`, command port `Q`, force sensor `F`.
pub struct ControlLoop<B, M, C, R, T, Q, F = NoSensor> {
    config: ControlConfig,
    board: B,
    model: M,
    controllers: C,
    sensor: F,
    has_sensor: bool,
    ports: ControlPorts<R, T, Q>,
    safety: Safety,
    active: usize,
    latest: Option<Stamped<Reference>>,
    axes: [AxisState; MAX_AXES],
    out: [AxisCommand; MAX_AXES],
    state: JointState,
    read_failures: u32,
    seq: u64,
    timing: (Duration, Duration),
    last: TelemetrySample,
}

impl<B, M, C, R, T, Q> ControlLoop<B, M, C, R, T, Q, NoSensor>
where
    B: Board,
    M: RobotModel,
    C: ControllerSet,
    R: ReferenceSource,
    T: TelemetrySink,
    Q: CommandSource,
{
    /// A loop in [`SafetyState::Inactive`], controller 0 selected.
    ///
    /// # Errors
    /// [`ControlConfigError`] for a bad configuration or an empty controller set.
    pub fn new(
        config: ControlConfig,
        board: B,
        model: M,
        controllers: C,
        ports: ControlPorts<R, T, Q>,
    ) -> Result<Self, ControlConfigError> {
        config.validate(board.axis_count())?;
        if controllers.count() == 0 {
            return Err(ControlConfigError::NoController);
        }
        let safety = Safety::new(config.safety).map_err(ControlConfigError::Safety)?;
        Ok(ControlLoop {
            config,
            board,
            model,
            controllers,
            sensor: NoSensor,
            has_sensor: false,
            ports,
            safety,
            active: 0,
            latest: None,
            axes: [AxisState::default(); MAX_AXES],
            out: [AxisCommand::Off; MAX_AXES],
            state: JointState::default(),
            read_failures: 0,
            seq: 0,
            timing: (Duration::ZERO, Duration::ZERO),
            last: TelemetrySample::default(),
        })
    }

    /// Binds a force sensor: its readings go to the controllers ([`ControlInput::wrench`]) and to
    /// telemetry. The wrench is passed on as the sensor reports it (its `frame` says where).
    pub fn with_sensor<S: Sensor<Reading = Wrench>>(
        self,
        sensor: S,
    ) -> ControlLoop<B, M, C, R, T, Q, S> {
        ControlLoop {
            config: self.config,
            board: self.board,
            model: self.model,
            controllers: self.controllers,
            sensor,
            has_sensor: true,
            ports: self.ports,
            safety: self.safety,
            active: self.active,
            latest: self.latest,
            axes: self.axes,
            out: self.out,
            state: self.state,
            read_failures: self.read_failures,
            seq: self.seq,
            timing: self.timing,
            last: self.last,
        }
    }
}

impl<B, M, C, R, T, Q, F> ControlLoop<B, M, C, R, T, Q, F>
where
    B: Board,
    M: RobotModel,
    C: ControllerSet,
    R: ReferenceSource,
    T: TelemetrySink,
    Q: CommandSource,
    F: Sensor<Reading = Wrench>,
{
    /// One control tick at `now`: measure, take commands, take the reference, supervise, control,
    /// write, report.
    ///
    /// # Real-time
    /// No allocation, no locks, no blocking (given a memory-like board and wait-free ports), no
    /// panics on any input, bounded time (at most [`MAX_COMMANDS_PER_TICK`] commands).
    pub fn tick(&mut self, now: Timestamp) -> TickOutcome {
        self.seq += 1;
        let measured = self.measure(now);
        let wrench = self.read_sensor(now);
        for _ in 0..MAX_COMMANDS_PER_TICK {
            match self.ports.commands.next_command() {
                Some(c) => self.apply(now, c),
                None => break,
            }
        }
        // Events raised with the reference (its link lost or back), taken before the reference
        // is read: the source raises them after publishing the reference they go with, so an
        // event seen here comes with its reference in this tick.
        self.safety.note_all(self.ports.reference.take_events());
        if let Fresh::New(s) = self.ports.reference.read() {
            if s.value.is_finite() {
                self.latest = Some(s);
            } else {
                self.safety.note(SafetyEvent::ReferenceRejected);
            }
        }

        // After a re-arm the interrupted motion's references are not followed: the robot holds
        // until a fresh reference starts where it is held (a restarted trajectory, a new
        // command).
        if measured
            && self.safety.awaiting_new_motion()
            && let Some(s) = self.latest
            && self.starts_here(&s.value)
        {
            self.safety.motion_reanchored();
        }

        let mut commanded_wrench = Wrench::zero(Frame::Base);
        let command = if measured {
            let action = self
                .safety
                .supervise(now, &self.state, self.latest.map(|s| s.stamp));
            if self
                .safety
                .events()
                .contains(SafetyEvent::ReferenceRecovered)
            {
                self.activate_controller(now);
            }
            let proposed = match action {
                Action::Run => self.run_controller(now, wrench.as_ref(), &mut commanded_wrench),
                other => self.safe_command(other),
            };
            let limited = match proposed {
                Some(c) => match self.safety.limit_command(c) {
                    Ok(c) => Some(c),
                    Err(cause) => {
                        self.safety.fault(cause);
                        self.checked_safe_command()
                    }
                },
                None => None,
            };
            Some(limited)
        } else if matches!(self.safety.state(), SafetyState::Fault | SafetyState::EStop) {
            Some(self.checked_safe_command())
        } else {
            None // read failed within tolerance: leave the board's last command in place
        };
        if let Some(command) = command {
            self.write(now, command);
        }

        let mut events = self.safety.take_events();
        self.fill_sample(now, wrench, commanded_wrench, events);
        if !self.ports.telemetry.push(&self.last) {
            events.insert(SafetyEvent::TelemetryDropped);
            self.last.events = events;
        }
        TickOutcome {
            seq: self.seq,
            state: self.safety.state(),
            events,
        }
    }

    /// Tells the loop the previous tick's wake-up latency and execution time (the executor
    /// measures them); they go into the next telemetry sample.
    ///
    /// # Real-time
    /// Constant time.
    pub fn note_timing(&mut self, wake_latency: Duration, exec_time: Duration) {
        self.timing = (wake_latency, exec_time);
    }

    /// Applies one command now (the same as receiving it on the command port).
    ///
    /// # Real-time
    /// Constant time, no allocation (a board `set_enabled` call on activation and stops).
    pub fn apply(&mut self, now: Timestamp, command: ControlCommand) {
        match command {
            ControlCommand::Activate => match self.safety.activate(now, &self.state) {
                Ok(()) => {
                    if let Err(e) = self.board.set_enabled(true) {
                        self.safety.note(SafetyEvent::BoardError);
                        self.safety.fault(FaultCause::BoardWrite(e.kind()));
                    } else {
                        self.activate_controller(now);
                    }
                }
                Err(_) => self.safety.note(SafetyEvent::CommandRejected),
            },
            ControlCommand::Deactivate => {
                self.safety.deactivate();
                let _ = self.board.set_enabled(false);
            }
            ControlCommand::SwitchController(i) => {
                let i = usize::from(i);
                if i < self.controllers.count() {
                    self.active = i;
                    self.safety.note(SafetyEvent::ControllerSwitched);
                    if matches!(
                        self.safety.state(),
                        SafetyState::Running | SafetyState::Holding
                    ) {
                        self.activate_controller(now);
                    }
                } else {
                    self.safety.note(SafetyEvent::CommandRejected);
                }
            }
            ControlCommand::EStop => {
                self.safety.estop();
                let _ = self.board.set_enabled(false);
            }
            ControlCommand::Rearm => {
                // The board's own latch first (a Galil line fault), then the loop's.
                if self.board.rearm().is_err() {
                    self.safety.note(SafetyEvent::BoardError);
                }
                if self.safety.rearm().is_err() {
                    self.safety.note(SafetyEvent::CommandRejected);
                }
            }
        }
    }

    /// Brings the robot to its safe state when the thread running this loop can no longer run
    /// it (a tick panicked, or the communication thread died): the e-stop is latched (an
    /// explicit re-arm is needed), and a board with its own servo
    /// ([`HoldMode::BoardServo`]) holds the last measured position while every other board
    /// gets zero torque and its amplifiers off.
    ///
    /// # Real-time
    /// Constant time, no allocation: one board write and one `set_enabled` call.
    pub fn fail_safe(&mut self, now: Timestamp) {
        self.safety.estop();
        match self.config.safety.hold {
            HoldMode::BoardServo if self.state.position.iter().all(|x| x.is_finite()) => {
                let q = self.state.position;
                self.write(now, Some(JointCommand::Position(q)));
            }
            // No servo to hold with, or nothing sane to hold: off.
            _ => {
                self.write(now, None);
                let _ = self.board.set_enabled(false);
            }
        }
    }

    /// The loop's last act when its thread is stopped on purpose (deactivation, destroy,
    /// shutdown), before anything is joined: the commands already sent to it are applied (a
    /// `Deactivate`), then a slave the loop is still driving is held where it was last measured
    /// by its board's own servo ([`hold_with_board_servo`](Self::hold_with_board_servo)), and
    /// anything else gets zero torque with its amplifiers off. No torque of the law outlives the
    /// loop's last tick by more than a period.
    ///
    /// # Real-time
    /// Constant time, no allocation: at most [`MAX_COMMANDS_PER_TICK`] commands, one board write
    /// and one `set_enabled` call.
    pub fn stop_safely(&mut self, now: Timestamp) {
        for _ in 0..MAX_COMMANDS_PER_TICK {
            match self.ports.commands.next_command() {
                Some(c) => self.apply(now, c),
                None => break,
            }
        }
        if self.config.safety.role == TeleopRole::Slave && self.hold_with_board_servo(now) {
            return;
        }
        self.write(now, None);
        let _ = self.board.set_enabled(false);
    }

    /// Leaves the robot held where it was last measured by the board's own position servo
    /// (the loop is about to stop: a slave's controller deactivated). Returns `false`, writing
    /// nothing, when the loop was not driving the robot (inactive, e-stopped, or faulted with
    /// the amplifiers off) or has no finite measurement to hold.
    ///
    /// # Real-time
    /// Constant time, no allocation: one board write.
    pub fn hold_with_board_servo(&mut self, now: Timestamp) -> bool {
        let driving = match self.safety.state() {
            SafetyState::Running | SafetyState::Holding => true,
            SafetyState::Fault => self.config.safety.fault_action == FaultAction::Hold,
            SafetyState::Inactive | SafetyState::EStop => false,
        };
        let q = self.state.position;
        if !driving || !q.iter().all(|x| x.is_finite()) {
            return false;
        }
        self.write(now, Some(JointCommand::Position(q)));
        true
    }

    fn measure(&mut self, now: Timestamp) -> bool {
        let count = self.board.axis_count().min(MAX_AXES);
        match self.board.read_axes(now, &mut self.axes[..count]) {
            Ok(()) => {
                self.read_failures = 0;
                for j in 0..self.config.safety.joint_count {
                    let b = self.config.axes[j];
                    let a = self.axes[usize::from(b.axis)];
                    let counts = a.position.wrapping_sub(b.offset_counts);
                    self.state.position[j] = counts as f64 / b.counts_per_radian;
                    self.state.velocity[j] = a.velocity / b.counts_per_radian;
                    self.state.effort[j] = a.effort;
                }
                true
            }
            Err(e) => {
                self.safety.note(SafetyEvent::BoardError);
                self.read_failures = self.read_failures.saturating_add(1);
                if self.read_failures > self.config.board_read_tolerance {
                    self.safety.fault(FaultCause::BoardRead(e.kind()));
                }
                false
            }
        }
    }

    fn read_sensor(&mut self, now: Timestamp) -> Option<Wrench> {
        if !self.has_sensor {
            return None;
        }
        match self.sensor.read(now) {
            Ok(w) if w.is_finite() => Some(w),
            _ => {
                self.safety.note(SafetyEvent::SensorError);
                None
            }
        }
    }

    fn activate_controller(&mut self, now: Timestamp) {
        if let Some(c) = self.controllers.get_mut(self.active) {
            c.activate(now, &self.state, &self.model);
        }
    }

    fn run_controller(
        &mut self,
        now: Timestamp,
        wrench: Option<&Wrench>,
        commanded_wrench: &mut Wrench,
    ) -> Option<JointCommand> {
        let Some(stamped) = self.latest else {
            return self.safe_command(self.safety.action());
        };
        let reference = self.safety.limit_reference(stamped.value);
        match &reference {
            Reference::Wrench(w) => *commanded_wrench = *w,
            Reference::Hybrid(h) => *commanded_wrench = h.wrench,
            _ => {}
        }
        let input = ControlInput {
            now,
            period: self.config.period,
            state: &self.state,
            reference: &reference,
            wrench,
            model: &self.model,
        };
        let result = match self.controllers.get_mut(self.active) {
            Some(c) => c.update(&input),
            None => Err(ControllerError::MissingInput),
        };
        match result {
            Ok(c) => Some(c),
            Err(e) => {
                self.safety.fault(FaultCause::Controller(e));
                self.safe_command(self.safety.action())
            }
        }
    }

    /// True when `reference` is within [`ControlConfig::resume_tolerance`] of where the robot
    /// is held (a wrench alone moves nothing: always true).
    fn starts_here(&self, reference: &Reference) -> bool {
        let tol = self.config.resume_tolerance;
        let q = &self.safety.hold_position();
        let near_pose = |pose: &penelope_hal::Pose| {
            let here = self.model.forward(q);
            (pose.translation.vector - here.translation.vector).norm() <= tol
                && pose.rotation.angle_to(&here.rotation) <= tol
        };
        match reference {
            Reference::Joint(j) => {
                (0..self.config.safety.joint_count).all(|i| (j.position[i] - q[i]).abs() <= tol)
            }
            Reference::Cartesian(c) => near_pose(&c.pose),
            Reference::Hybrid(h) => near_pose(&h.motion.pose),
            Reference::Wrench(_) => true,
        }
    }

    /// The command of the current safe state, through the same finiteness check and limits as
    /// any other. A hold that cannot be formed (a PD hold on a NaN state) is amplifiers off:
    /// zero torque, and the board told so, rather than a command the board would refuse (it
    /// would keep the previous one).
    fn checked_safe_command(&mut self) -> Option<JointCommand> {
        let command = self.safe_command(self.safety.action())?;
        match self.safety.limit_command(command) {
            Ok(c) => Some(c),
            Err(_) => {
                let _ = self.board.set_enabled(false);
                None
            }
        }
    }

    /// The command for a non-running action (`None` = amplifiers off).
    fn safe_command(&self, action: Action) -> Option<JointCommand> {
        match action {
            Action::Off => None,
            Action::ZeroForce => Some(JointCommand::Effort(JointVector::zeros())),
            Action::Run => None,
            Action::Hold(q) => Some(match self.config.safety.hold {
                HoldMode::BoardServo => JointCommand::Position(q),
                HoldMode::Pd { kp, kd } => {
                    let e = q - self.state.position;
                    let tau = kp.component_mul(&e) - kd.component_mul(&self.state.velocity)
                        + self.model.gravity(&self.state.position);
                    JointCommand::Effort(tau)
                }
            }),
        }
    }

    fn write(&mut self, now: Timestamp, command: Option<JointCommand>) {
        let count = self.board.axis_count().min(MAX_AXES);
        self.out = [AxisCommand::Off; MAX_AXES];
        if let Some(command) = command {
            for j in 0..self.config.safety.joint_count {
                let b = self.config.axes[j];
                self.out[usize::from(b.axis)] = match command {
                    JointCommand::Effort(t) => AxisCommand::Effort(t[j]),
                    JointCommand::Position(q) => position_counts(q[j], b),
                    JointCommand::Mixed {
                        effort,
                        position,
                        position_joints,
                    } => {
                        if position_joints.contains(j) {
                            position_counts(position[j], b)
                        } else {
                            AxisCommand::Effort(effort[j])
                        }
                    }
                };
            }
        }
        if let Err(e) = self.board.write_axes(now, &self.out[..count]) {
            self.safety.note(SafetyEvent::BoardError);
            self.safety.fault(FaultCause::BoardWrite(e.kind()));
        }
    }

    fn fill_sample(
        &mut self,
        now: Timestamp,
        wrench: Option<Wrench>,
        commanded_wrench: Wrench,
        events: EventSet,
    ) {
        let port_energy = self
            .controllers
            .get_mut(self.active)
            .and_then(|c| c.port_energy());
        let s = &mut self.last;
        s.time = now;
        s.seq = self.seq;
        s.q = self.state.position;
        s.qd = self.state.velocity;
        s.effort = JointVector::zeros();
        s.position_command = JointVector::zeros();
        for j in 0..self.config.safety.joint_count {
            let b = self.config.axes[j];
            match self.out[usize::from(b.axis)] {
                AxisCommand::Effort(t) => s.effort[j] = t,
                AxisCommand::Position(c) => {
                    s.position_command[j] =
                        c.wrapping_sub(b.offset_counts) as f64 / b.counts_per_radian;
                }
                AxisCommand::Off => {}
            }
        }
        s.reference_kind = ReferenceKind::None;
        s.reference_q = JointVector::zeros();
        s.reference_position = nalgebra::Vector3::zeros();
        s.reference_age = Duration::MAX;
        if let Some(r) = &self.latest {
            s.reference_kind = ReferenceKind::of(&r.value);
            s.reference_age = now.saturating_since(r.stamp);
            match &r.value {
                Reference::Joint(j) => s.reference_q = j.position,
                Reference::Cartesian(c) => s.reference_position = c.pose.translation.vector,
                Reference::Hybrid(h) => s.reference_position = h.motion.pose.translation.vector,
                Reference::Wrench(_) => {}
            }
        }
        s.wrench = wrench.unwrap_or(Wrench::zero(Frame::Base));
        s.commanded_wrench = commanded_wrench;
        s.tool_position = if self.config.tool_position && self.state.is_finite() {
            self.model.forward(&self.state.position).translation.vector
        } else {
            nalgebra::Vector3::zeros()
        };
        s.controller = u8::try_from(self.active).unwrap_or(u8::MAX);
        s.port_energy = port_energy;
        s.channel_energy = self.ports.reference.channel_energy();
        s.state = self.safety.state();
        s.events = events;
        s.fault = self.safety.fault_cause();
        s.wake_latency = self.timing.0;
        s.exec_time = self.timing.1;
    }

    /// The last tick's telemetry sample (also when the ring dropped it).
    pub fn last_sample(&self) -> &TelemetrySample {
        &self.last
    }

    /// The measured joint state of the last tick.
    pub fn joint_state(&self) -> &JointState {
        &self.state
    }

    /// The safety machine.
    pub fn safety(&self) -> &Safety {
        &self.safety
    }

    /// Index of the active controller.
    pub fn active_controller(&self) -> usize {
        self.active
    }

    /// The configuration.
    pub fn config(&self) -> &ControlConfig {
        &self.config
    }

    /// The board.
    pub fn board(&self) -> &B {
        &self.board
    }

    /// The board, mutably (for fault injection in tests and for drivers' housekeeping).
    pub fn board_mut(&mut self) -> &mut B {
        &mut self.board
    }

    /// The robot model.
    pub fn model(&self) -> &M {
        &self.model
    }

    /// The controllers (to retune between ticks).
    pub fn controllers_mut(&mut self) -> &mut C {
        &mut self.controllers
    }

    /// Ticks run so far.
    pub fn seq(&self) -> u64 {
        self.seq
    }

    /// Takes the loop apart, returning its board, model, controllers and ports.
    pub fn into_parts(self) -> (B, M, C, ControlPorts<R, T, Q>) {
        (self.board, self.model, self.controllers, self.ports)
    }
}

impl<B, M, C, R, T, Q, F> fmt::Debug for ControlLoop<B, M, C, R, T, Q, F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ControlLoop")
            .field("seq", &self.seq)
            .field("state", &self.safety.state())
            .field("active", &self.active)
            .finish_non_exhaustive()
    }
}
