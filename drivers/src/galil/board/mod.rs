//! [`GalilBoard`]: the `hal::Board` for a DMC on a serial line.
//!
//! The serial line is slow and blocks, so it never meets the control thread. The board owns an
//! I/O thread that runs the protocol [`Client`](super::Client) as fast as the line allows and meets the control
//! thread only through lock-free latest-value cells (`penelope_rt_core::cell`):
//!
//! ```text
//! control thread                         I/O thread (owns the Client and the link)
//! write_axes / set_enabled --[commands]--> mode changes (SH, MO, gains, PT 1), then each cycle
//!                                           "pnhb=k;PA t1,..,tn;TP;TE" ("OF v.." for efforts),
//! read_axes <----------------[state]------ every few cycles "TV;TT;TS"; exchange rate measured
//! ```
//!
//! Per axis: [`AxisCommand::Position`] streams targets in position-tracking mode (`PT 1` + `PA`,
//! the board's own servo follows each new target at once) or, in [`TargetMode::Relative`], as
//! profiled relative moves (`PR` + `BG` when the previous move ended); [`AxisCommand::Effort`]
//! zeroes that axis' gains and writes the torque as `OF` volts (effort × volts per N·m, clamped to
//! the torque limit); [`AxisCommand::Off`] sends `MO`. Leaving effort mode restores the gains.
//! Encoder counts become radians in the control loop through each joint's
//! `AxisBinding` (see [`axis_bindings`]).
//!
//! # Torque directions
//! A DMC axis is wired for position servo: a positive volt drives its encoder count up. A joint
//! whose gear ratio (or encoder) is reversed — counts per radian below zero — therefore turns the
//! other way for a positive volt. [`GalilBoard::orient`] takes the joint bindings (the same
//! counts per radian that turn counts into radians) and signs each axis' effort with them, so a
//! joint torque means the same thing on every axis and for every user. `volts_per_newton_metre`
//! is the amplifier's scaling; a negative value flips an axis whose amplifier is wired
//! reversed.
//!
//! # Faults and release
//! Any line fault (device gone, garbage, timeout) or a rejected command puts the board in the
//! error state. If the line still answers, the I/O thread makes it safe: axes in effort mode get
//! `OF 0` and `MO` (no torque stays on), axes in position mode `ST` (the board's own servo
//! holds). It publishes the fault and [`read_axes`](Board::read_axes) returns it, so the
//! controller holds or stops. A state older than [`GalilBoardConfig::stale_after`] is a timeout
//! too. Re-arming is explicit: [`GalilBoard::rearm`] reopens and re-initialises the line.
//!
//! A dead host or a pulled cable cannot send anything, so the board watches the host itself:
//! at configure the driver downloads a watchdog program ([`watchdog`]) and runs it in its own
//! thread; every exchange writes a new heartbeat, and when the heartbeat stops changing for
//! [`GalilBoardConfig::watchdog`] (30 ms by default) the program turns the motors off. A motor
//! the watchdog switched off faults the board as [`BoardFault::Watchdog`].
//!
//! # A hung host
//! The heartbeat proves the I/O thread alive, not the control loop that feeds it: a control
//! thread that hangs (rather than dies) would leave its last torque on with the heartbeat fed.
//! So every command frame the control thread writes is fresh evidence of its tick, and while any
//! axis is in effort mode a frame older than [`GalilBoardConfig::command_timeout`] (on the I/O
//! thread's clock) is a fault, [`BoardFault::CommandStale`], handled here outside the control
//! thread: `OF 0` and `MO` on every driven axis, and the heartbeat is no longer fed, so the
//! board's watchdog switches everything off too should the line drop those commands. Axes only
//! in position mode need no fresh command: the board's own servo holds the last target (how a
//! slave is left when its loop stops on purpose).
//!
//! Dropping the board ([`GalilBoard::release`]) turns the amplifiers off (`OF 0`, `MO`) and
//! halts the watchdog, when the line answers. This is the one way to release a Galil board.

// Several per-axis arrays (commands, modes, replies, state) are walked in step by axis index.
#![allow(clippy::needless_range_loop)]

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use penelope_hal::board::{AxisCommand, AxisState, Board, MAX_AXES};
use penelope_hal::error::{Error as HalError, ErrorKind};
use penelope_hal::robot::Robot;
use penelope_hal::time::Timestamp;
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Fresh, latest};
use penelope_rt_core::control::AxisBinding;

use super::client::{BoardInfo, ClientConfig};
use super::command::MAX_GALIL_AXES;
use super::error::GalilError;
use super::link::{Link, SerialLink, SerialSettings};

mod io;
pub mod watchdog;

use io::Io;
pub use watchdog::DEFAULT_WATCHDOG;

/// The default [`GalilBoardConfig::command_timeout`]: 50 control periods at 1 kHz, a few
/// exchanges of the serial line, under twice the board's own watchdog time.
pub const DEFAULT_COMMAND_TIMEOUT: Duration = Duration::from_millis(50);

/// The largest output a DMC-40x0 drives, volts.
pub const MAX_VOLTS: f64 = 9.9982;

/// How position targets are sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TargetMode {
    /// `PT 1` + `PA`: the board follows each new target at once (teleoperation).
    #[default]
    PositionTracking,
    /// `PR` + `BG`: a profiled relative move toward the target whenever the previous one ended.
    Relative,
}

/// Everything needed to run a Galil board.
#[derive(Clone, Debug, PartialEq)]
pub struct GalilBoardConfig {
    /// The serial line.
    pub serial: SerialSettings,
    /// How many axes to drive (the first `axes` of the board), 1..=8.
    pub axes: usize,
    /// Effort-to-command scaling per axis: `OF` volts per N·m of joint torque (amplifier gain,
    /// motor constant and gear ratio folded together). Zero makes efforts on that axis no-ops.
    pub volts_per_newton_metre: [f64; MAX_AXES],
    /// Position-loop gains (`KP`, `KI`, `KD`) per axis to send at start and restore after effort
    /// mode; `None` keeps (and remembers) what the board has.
    pub gains: Option<[[f64; 3]; MAX_AXES]>,
    /// `TL` per axis, volts; `None` leaves the board's.
    pub torque_limit_volts: Option<[f64; MAX_AXES]>,
    /// `ER` per axis, counts; `None` leaves the board's.
    pub error_limit_counts: Option<[f64; MAX_AXES]>,
    /// `OE` for every axis (0..3); `None` leaves the board's.
    pub off_on_error: Option<u8>,
    /// How position targets are sent.
    pub target_mode: TargetMode,
    /// Protocol client settings (timeouts, `CW1`).
    pub client: ClientConfig,
    /// `read_axes` fails with a timeout when no new state arrived for this long (on the caller's
    /// clock).
    pub stale_after: Duration,
    /// Read velocity, torque and switches (`TV;TT;TS`) every this many cycles (at least 1).
    pub status_every: u32,
    /// Shortest cycle of the I/O thread (zero: as fast as the line goes).
    pub min_cycle: Duration,
    /// The board-side watchdog: the motors go off when no exchange reached the board for this
    /// long (see [`watchdog`]); `None` downloads no program (the board then keeps its last
    /// command when the host dies).
    pub watchdog: Option<Duration>,
    /// While any axis is driven by effort, a command frame from the control thread older than
    /// this (no new `write_axes` or `set_enabled`) faults the board
    /// ([`BoardFault::CommandStale`]): amplifiers off, heartbeat no longer fed. `None` turns
    /// the check off (a host that writes one command and waits, as some bench tests do).
    pub command_timeout: Option<Duration>,
}

impl GalilBoardConfig {
    /// A board on `path` at 115200 baud with `axes` axes and the given effort scaling (volts per
    /// N·m, one per axis; missing entries are zero).
    pub fn new(path: impl Into<String>, axes: usize, volts_per_newton_metre: &[f64]) -> Self {
        let mut scale = [0.0; MAX_AXES];
        for (s, v) in scale.iter_mut().zip(volts_per_newton_metre) {
            *s = *v;
        }
        GalilBoardConfig {
            serial: SerialSettings::new(path, 115_200),
            axes,
            volts_per_newton_metre: scale,
            gains: None,
            torque_limit_volts: None,
            error_limit_counts: None,
            off_on_error: None,
            target_mode: TargetMode::PositionTracking,
            client: ClientConfig::default(),
            stale_after: Duration::from_millis(500),
            status_every: 5,
            min_cycle: Duration::ZERO,
            watchdog: Some(DEFAULT_WATCHDOG),
            command_timeout: Some(DEFAULT_COMMAND_TIMEOUT),
        }
    }
}

/// Joint-to-axis bindings from a robot model's encoder scaling: joint `j` on axis `j` with the
/// model's counts per radian and zero offset.
pub fn axis_bindings<R: Robot + ?Sized>(
    robot: &R,
) -> [AxisBinding; penelope_hal::joint::MAX_JOINTS] {
    let mut out = [AxisBinding::new(0, 1.0); penelope_hal::joint::MAX_JOINTS];
    for (j, b) in out.iter_mut().enumerate().take(robot.joint_count()) {
        *b = AxisBinding::new(j as u8, robot.counts_per_radian(j));
    }
    out
}

/// What put the board in the error state.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BoardFault {
    /// No reply in time.
    Timeout,
    /// The device went away.
    Closed,
    /// An operating-system error on the line.
    Io,
    /// Garbage or lost framing.
    Garbled,
    /// The board rejected a command with this Galil code.
    Rejected(u16),
    /// An axis that should be on was switched off by the board (off-on-error, limit).
    MotorOff(u8),
    /// The board has fewer axes than configured.
    TooFewAxes,
    /// The board's watchdog turned the motors off: no heartbeat reached it in time.
    Watchdog,
    /// The control thread's commands stopped coming while an axis was driven by effort (a hung
    /// control loop): the I/O thread turned the amplifiers off.
    CommandStale,
}

impl BoardFault {
    fn from_error(e: &GalilError) -> BoardFault {
        match e {
            GalilError::Timeout(_) => BoardFault::Timeout,
            GalilError::Closed => BoardFault::Closed,
            GalilError::Io(_) => BoardFault::Io,
            GalilError::Rejected { code, .. } => BoardFault::Rejected(*code),
            GalilError::RejectedUnexplained => BoardFault::Rejected(0),
            _ => BoardFault::Garbled,
        }
    }

    fn encode(self) -> u8 {
        match self {
            BoardFault::Timeout => 1,
            BoardFault::Closed => 2,
            BoardFault::Io => 3,
            BoardFault::Garbled => 4,
            BoardFault::Rejected(_) => 5,
            BoardFault::MotorOff(_) => 6,
            BoardFault::TooFewAxes => 7,
            BoardFault::Watchdog => 8,
            BoardFault::CommandStale => 9,
        }
    }

    /// True when the line itself failed (nothing may get through any more).
    pub fn is_link_fault(self) -> bool {
        matches!(
            self,
            BoardFault::Timeout | BoardFault::Closed | BoardFault::Io
        )
    }
}

/// Errors of [`GalilBoard`]: small, `Copy`, no heap.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GalilBoardError {
    /// The board is in the error state (see [`GalilBoard::rearm`]).
    Fault(BoardFault),
    /// No new state for longer than `stale_after`.
    Stale,
    /// No state has arrived yet.
    NoData,
    /// A slice shorter than the axis count.
    WrongLength,
    /// A NaN or infinite effort.
    NonFinite,
}

impl core::fmt::Display for GalilBoardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            GalilBoardError::Fault(fault) => write!(f, "galil board fault: {fault:?}"),
            GalilBoardError::Stale => f.write_str("galil board state is stale"),
            GalilBoardError::NoData => f.write_str("no state from the galil board yet"),
            GalilBoardError::WrongLength => f.write_str("slice shorter than the axis count"),
            GalilBoardError::NonFinite => f.write_str("non-finite effort"),
        }
    }
}

impl std::error::Error for GalilBoardError {}

impl HalError for GalilBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            GalilBoardError::Fault(BoardFault::Timeout | BoardFault::CommandStale)
            | GalilBoardError::Stale => ErrorKind::Timeout,
            GalilBoardError::Fault(
                BoardFault::Rejected(_) | BoardFault::MotorOff(_) | BoardFault::Watchdog,
            ) => ErrorKind::Device,
            GalilBoardError::Fault(BoardFault::TooFewAxes) => ErrorKind::InvalidInput,
            GalilBoardError::Fault(_) => ErrorKind::Communication,
            GalilBoardError::NoData => ErrorKind::WrongState,
            GalilBoardError::WrongLength => ErrorKind::InvalidInput,
            GalilBoardError::NonFinite => ErrorKind::NonFinite,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct CommandFrame {
    enabled: bool,
    commands: [AxisCommand; MAX_AXES],
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct StateFrame {
    axes: [AxisState; MAX_AXES],
    fault: Option<BoardFault>,
}

/// Counters shared with the non-real-time side.
#[derive(Debug, Default)]
struct Shared {
    stop: AtomicBool,
    rearm: AtomicU64,
    cycles: AtomicU64,
    /// Exchange rate, Hz, as f64 bits.
    rate_bits: AtomicU64,
    fault: AtomicU8,
}

/// Opens (or reopens) the line.
pub type LinkFactory = Box<dyn FnMut() -> Result<Box<dyn Link + Send>, GalilError> + Send>;

/// A Galil DMC as a `hal::Board`, its serial I/O in its own thread.
pub struct GalilBoard {
    axes: usize,
    info: BoardInfo,
    enabled: bool,
    last: [AxisCommand; MAX_AXES],
    commands: ArcLatestWriter<CommandFrame>,
    state: ArcLatestReader<StateFrame>,
    last_new: Option<Timestamp>,
    stale_after: Duration,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
    /// Per axis, +1 or -1: the sign of joint torque per positive volt (see [`GalilBoard::orient`]).
    directions: [f64; MAX_AXES],
}

impl core::fmt::Debug for GalilBoard {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("GalilBoard")
            .field("axes", &self.axes)
            .field("info", &self.info)
            .finish_non_exhaustive()
    }
}

impl GalilBoard {
    /// Opens the serial port, initialises the board and starts the I/O thread.
    ///
    /// # Errors
    /// When the port cannot be opened, the board does not answer, or has fewer axes than asked.
    pub fn open(config: GalilBoardConfig) -> Result<GalilBoard, GalilError> {
        let serial = config.serial.clone();
        let factory: LinkFactory = Box::new(move || {
            SerialLink::open(&serial).map(|l| Box::new(l) as Box<dyn Link + Send>)
        });
        GalilBoard::with_link_factory(config, factory)
    }

    /// As [`open`](GalilBoard::open), over links made by `factory` (a TCP socket, a mock); the
    /// factory is called again on [`rearm`](GalilBoard::rearm) when the line was lost.
    ///
    /// # Errors
    /// As `open`.
    pub fn with_link_factory(
        config: GalilBoardConfig,
        mut factory: LinkFactory,
    ) -> Result<GalilBoard, GalilError> {
        if config.axes == 0 || config.axes > MAX_AXES.min(MAX_GALIL_AXES) {
            return Err(GalilError::InvalidArgument("axes must be 1..=8"));
        }
        if config.volts_per_newton_metre.iter().any(|v| !v.is_finite()) {
            return Err(GalilError::InvalidArgument("non-finite effort scaling"));
        }
        let link = factory()?;
        let mut io = Io::new(config.clone(), factory);
        let info = io.connect(link)?;
        let (cmd_w, cmd_r) = latest::<CommandFrame>();
        let (state_w, state_r) = latest::<StateFrame>();
        let shared = Arc::new(Shared::default());
        let thread_shared = Arc::clone(&shared);
        let thread = std::thread::Builder::new()
            .name("galil-io".into())
            .spawn(move || io.run(cmd_r, state_w, &thread_shared))
            .map_err(|e| GalilError::Io(e.kind()))?;
        Ok(GalilBoard {
            axes: config.axes,
            info,
            enabled: false,
            last: [AxisCommand::Off; MAX_AXES],
            commands: cmd_w,
            state: state_r,
            last_new: None,
            stale_after: config.stale_after,
            shared,
            thread: Some(thread),
            directions: [1.0; MAX_AXES],
        })
    }

    /// Signs each bound axis' effort with its joint's direction: the sign of
    /// `counts_per_radian` (gear ratio × encoder direction), the same binding that turns the
    /// axis' counts into the joint's radians. Axes no binding names keep +1.
    ///
    /// # Real-time
    /// Not for the control thread's loop (call it when the loop is built); no allocation.
    pub fn orient(&mut self, bindings: &[AxisBinding]) {
        for b in bindings {
            if let Some(d) = self.directions.get_mut(usize::from(b.axis))
                && b.counts_per_radian != 0.0
            {
                *d = b.counts_per_radian.signum();
            }
        }
    }

    /// The effort direction of each axis (+1 or -1), as [`orient`](GalilBoard::orient) set it.
    pub fn directions(&self) -> &[f64] {
        &self.directions[..self.axes]
    }

    /// Releases the board: amplifiers off (`OF 0`, `MO` on every driven axis), the watchdog
    /// halted, the I/O thread stopped. Dropping the board does the same.
    ///
    /// Not real-time: waits for the I/O thread (a few exchanges; up to the client timeout on a
    /// line that stopped answering).
    pub fn release(self) {
        drop(self);
    }

    /// Model, firmware and record layout found at start.
    pub fn info(&self) -> &BoardInfo {
        &self.info
    }

    /// Command/reply cycles per second the I/O thread achieves (over the last half second).
    pub fn exchange_rate_hz(&self) -> f64 {
        f64::from_bits(self.shared.rate_bits.load(Ordering::Relaxed))
    }

    /// Cycles completed since start.
    pub fn cycles(&self) -> u64 {
        self.shared.cycles.load(Ordering::Relaxed)
    }

    /// Whether the host asked for the amplifiers on (the last [`Board::set_enabled`]); the
    /// board follows on the I/O thread's next cycle.
    pub fn is_enabled(&self) -> bool {
        self.enabled
    }

    /// True while the I/O thread reports a fault.
    pub fn is_faulted(&self) -> bool {
        self.shared.fault.load(Ordering::Relaxed) != 0
    }

    /// Asks the I/O thread to leave the error state: reopen the line if it was lost,
    /// re-initialise, and start exchanging again. Axes come back as they were on the board; the
    /// next commands decide.
    pub fn rearm(&self) {
        self.shared.rearm.fetch_add(1, Ordering::SeqCst);
    }
}

impl Drop for GalilBoard {
    /// As [`release`](GalilBoard::release): the I/O thread turns the amplifiers off on its way
    /// out.
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Board for GalilBoard {
    type Error = GalilBoardError;

    fn axis_count(&self) -> usize {
        self.axes
    }

    /// # Real-time
    /// Wait-free: one cell read and a copy. No allocation, lock or system call.
    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), Self::Error> {
        let out = out
            .get_mut(..self.axes)
            .ok_or(GalilBoardError::WrongLength)?;
        let frame = match self.state.read() {
            Fresh::NoData => return Err(GalilBoardError::NoData),
            Fresh::New(f) => {
                self.last_new = Some(now);
                f
            }
            Fresh::Old(f) => {
                let since = self
                    .last_new
                    .map_or(Duration::ZERO, |t| now.saturating_since(t));
                if since > self.stale_after {
                    return Err(GalilBoardError::Stale);
                }
                f
            }
        };
        if let Some(fault) = frame.fault {
            return Err(GalilBoardError::Fault(fault));
        }
        out.copy_from_slice(&frame.axes[..self.axes]);
        for (o, d) in out.iter_mut().zip(&self.directions) {
            o.effort *= d;
        }
        Ok(())
    }

    /// Efforts are joint torques: each is signed with its axis' direction
    /// ([`GalilBoard::orient`]) before it becomes `OF` volts.
    ///
    /// # Real-time
    /// Wait-free: one cell write. No allocation, lock or system call.
    fn write_axes(&mut self, _now: Timestamp, commands: &[AxisCommand]) -> Result<(), Self::Error> {
        let commands = commands
            .get(..self.axes)
            .ok_or(GalilBoardError::WrongLength)?;
        if commands
            .iter()
            .any(|c| matches!(c, AxisCommand::Effort(t) if !t.is_finite()))
        {
            return Err(GalilBoardError::NonFinite);
        }
        for (i, c) in commands.iter().enumerate() {
            self.last[i] = match *c {
                AxisCommand::Effort(t) => AxisCommand::Effort(t * self.directions[i]),
                other => other,
            };
        }
        self.commands.write(CommandFrame {
            enabled: self.enabled,
            commands: self.last,
        });
        Ok(())
    }

    /// # Real-time
    /// Wait-free: one cell write. The I/O thread sends `SH`/`MO` on its next cycle.
    fn set_enabled(&mut self, enabled: bool) -> Result<(), Self::Error> {
        self.enabled = enabled;
        self.commands.write(CommandFrame {
            enabled,
            commands: self.last,
        });
        Ok(())
    }

    /// # Real-time
    /// Wait-free: one atomic increment; the I/O thread re-arms on its next cycle (see
    /// [`GalilBoard::rearm`]).
    fn rearm(&mut self) -> Result<(), Self::Error> {
        GalilBoard::rearm(self);
        Ok(())
    }
}
