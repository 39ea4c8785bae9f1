//! [`GalilBoard`]: the `hal::Board` for a DMC on a serial line.
//!
//! The serial line is slow and blocks, so it never meets the control thread. The board owns an
//! I/O thread that runs the protocol [`Client`] as fast as the line allows and meets the control
//! thread only through lock-free latest-value cells (`penelope_rt_core::cell`):
//!
//! ```text
//! control thread                         I/O thread (owns the Client and the link)
//! write_axes / set_enabled --[commands]--> mode changes (SH, MO, gains, PT 1), then each cycle
//!                                           "PA t1,..,tn;TP;TE" (and "OF v.." for efforts),
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
//! # Faults
//! Any line fault (device gone, garbage, timeout) or a rejected command puts the board in the
//! error state: the I/O thread sends `ST` if the line still works (the board's own servo then
//! holds position), publishes the fault, and [`read_axes`](Board::read_axes) returns it, so the
//! controller holds or stops. A state older than [`GalilBoardConfig::stale_after`] is a timeout
//! too. Re-arming is explicit: [`GalilBoard::rearm`] reopens and re-initialises the line.
//! *NOTE*: while faulted, the board keeps the physical state the last good commands left,
//! except that an explicit `set_enabled(false)` still sends `MO` when the line allows.

// Several per-axis arrays (commands, modes, replies, state) are walked in step by axis index.
#![allow(clippy::needless_range_loop)]

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use penelope_hal::board::{AxisCommand, AxisState, Board, MAX_AXES};
use penelope_hal::error::{Error as HalError, ErrorKind};
use penelope_hal::robot::Robot;
use penelope_hal::time::Timestamp;
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Fresh, latest};
use penelope_rt_core::control::AxisBinding;

use super::client::{BoardInfo, Client, ClientConfig, Reply};
use super::command::{Axes, Command, MAX_GALIL_AXES, Setting, Tell, encode_line};
use super::error::GalilError;
use super::link::{Link, SerialLink, SerialSettings};
use super::number::{parse_numbers, to_counts};

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
        }
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
            GalilBoardError::Fault(BoardFault::Timeout) | GalilBoardError::Stale => {
                ErrorKind::Timeout
            }
            GalilBoardError::Fault(BoardFault::Rejected(_) | BoardFault::MotorOff(_)) => {
                ErrorKind::Device
            }
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
        })
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
        Ok(())
    }

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
        self.last[..self.axes].copy_from_slice(commands);
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

/// What an axis is currently set up for on the board.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    /// Not known (at start: whatever the board was doing).
    Unknown,
    Off,
    Position,
    Effort,
}

/// The I/O thread's state.
struct Io {
    config: GalilBoardConfig,
    factory: LinkFactory,
    client: Option<Client<Box<dyn Link + Send>>>,
    modes: [Mode; MAX_AXES],
    gains: [[f64; 3]; MAX_AXES],
    /// Axes whose position gains were zeroed for effort mode and not restored yet (an axis can go
    /// effort, then off, then position: the gains must come back even though it was off).
    gains_zeroed: [bool; MAX_AXES],
    /// Last target sent per axis (relative mode), counts.
    sent_target: [Option<i64>; MAX_AXES],
    state: [AxisState; MAX_AXES],
    moving: [bool; MAX_AXES],
    cycle: u64,
    /// The axes argument of reports: empty (all, the shortest line) when every board axis is
    /// driven.
    report_axes: Axes,
}

impl Io {
    fn new(config: GalilBoardConfig, factory: LinkFactory) -> Self {
        let n = config.axes;
        Io {
            config,
            factory,
            client: None,
            modes: [Mode::Unknown; MAX_AXES],
            gains: [[0.0; 3]; MAX_AXES],
            gains_zeroed: [false; MAX_AXES],
            sent_target: [None; MAX_AXES],
            state: [AxisState::default(); MAX_AXES],
            moving: [false; MAX_AXES],
            cycle: 0,
            report_axes: Axes::first(n),
        }
    }

    fn n(&self) -> usize {
        self.config.axes
    }

    /// Initialises the board over `link` and sends the configured limits.
    fn connect(&mut self, link: Box<dyn Link + Send>) -> Result<BoardInfo, GalilError> {
        let mut client = Client::new(link, self.config.client.clone());
        let info = client.initialize()?;
        let n = self.n();
        if info.layout.axes < n {
            return Err(GalilError::InvalidArgument(
                "the board has fewer axes than configured",
            ));
        }
        let per_axis = |v: &[f64; MAX_AXES]| -> [Option<f64>; MAX_AXES] {
            let mut out = [None; MAX_AXES];
            for (o, x) in out.iter_mut().zip(v).take(n) {
                *o = Some(*x);
            }
            out
        };
        if let Some(tl) = &self.config.torque_limit_volts {
            client.set(Setting::TorqueLimit, &per_axis(tl)[..n])?;
        }
        if let Some(er) = &self.config.error_limit_counts {
            client.set(Setting::ErrorLimit, &per_axis(er)[..n])?;
        }
        if let Some(oe) = self.config.off_on_error {
            client.set(Setting::OffOnError, &[Some(f64::from(oe)); MAX_AXES][..n])?;
        }
        match &self.config.gains {
            Some(g) => {
                self.gains = *g;
                for (k, s) in [Setting::Kp, Setting::Ki, Setting::Kd]
                    .into_iter()
                    .enumerate()
                {
                    let mut v = [None; MAX_AXES];
                    for (i, x) in v.iter_mut().enumerate().take(n) {
                        *x = Some(g[i][k]);
                    }
                    client.set(s, &v[..n])?;
                }
            }
            None => {
                for (k, s) in [Setting::Kp, Setting::Ki, Setting::Kd]
                    .into_iter()
                    .enumerate()
                {
                    let v = client.query(s, n)?;
                    for (i, x) in v.iter().enumerate() {
                        self.gains[i][k] = *x;
                    }
                }
            }
        }
        self.modes = [Mode::Unknown; MAX_AXES];
        self.sent_target = [None; MAX_AXES];
        self.report_axes = if info.layout.axes == n {
            Axes::NONE
        } else {
            Axes::first(n)
        };
        self.client = Some(client);
        Ok(info)
    }

    fn run(
        mut self,
        mut commands: ArcLatestReader<CommandFrame>,
        mut state: ArcLatestWriter<StateFrame>,
        shared: &Shared,
    ) {
        let mut rearm_seen = shared.rearm.load(Ordering::SeqCst);
        let mut fault: Option<BoardFault> = None;
        let mut window_start = Instant::now();
        let mut window_cycles = 0u64;
        let mut disabled_in_fault = false;
        while !shared.stop.load(Ordering::SeqCst) {
            let started = Instant::now();
            let frame = commands.latest();
            if let Some(f) = fault {
                // Publish the fault, honour an explicit disable, wait for a re-arm.
                state.write(StateFrame {
                    axes: self.state,
                    fault: Some(f),
                });
                shared.fault.store(f.encode(), Ordering::Relaxed);
                if frame.is_some_and(|f| !f.enabled) && !disabled_in_fault {
                    disabled_in_fault = true;
                    if let Some(c) = self.client.as_mut() {
                        let _ = c.ack(&Command::MotorOff(Axes::first(self.config.axes)));
                    }
                }
                let r = shared.rearm.load(Ordering::SeqCst);
                if r != rearm_seen {
                    rearm_seen = r;
                    if self.reconnect().is_ok() {
                        fault = None;
                        disabled_in_fault = false;
                        shared.fault.store(0, Ordering::Relaxed);
                    }
                } else {
                    std::thread::sleep(Duration::from_millis(10));
                }
                continue;
            }
            match self.cycle_once(frame) {
                Ok(()) => {
                    state.write(StateFrame {
                        axes: self.state,
                        fault: None,
                    });
                    shared.cycles.fetch_add(1, Ordering::Relaxed);
                    window_cycles += 1;
                    let elapsed = window_start.elapsed();
                    if elapsed >= Duration::from_millis(500) {
                        let hz = window_cycles as f64 / elapsed.as_secs_f64();
                        shared.rate_bits.store(hz.to_bits(), Ordering::Relaxed);
                        window_start = Instant::now();
                        window_cycles = 0;
                    }
                }
                Err(f) => {
                    log::warn!("galil board fault: {f:?}");
                    // Hold: stop motion if the line still works; the board servo keeps position.
                    if !matches!(f, BoardFault::Closed)
                        && let Some(c) = self.client.as_mut()
                    {
                        let _ = c.ack(&Command::Stop(Axes::first(self.config.axes)));
                    }
                    fault = Some(f);
                }
            }
            let spent = started.elapsed();
            if spent < self.config.min_cycle {
                std::thread::sleep(self.config.min_cycle - spent);
            }
        }
        // Shutting down: stop motion, leave amplifiers as they are (a robot arm may need its
        // brakes or servo; the owner decides with set_enabled(false) before dropping).
        if fault.is_none()
            && let Some(c) = self.client.as_mut()
        {
            let _ = c.ack(&Command::Stop(Axes::first(self.config.axes)));
        }
    }

    fn reconnect(&mut self) -> Result<(), GalilError> {
        // Try the existing line first; reopen it if that fails.
        if let Some(c) = self.client.take() {
            let link = c.into_link();
            if self.connect(link).is_ok() {
                return Ok(());
            }
        }
        let link = (self.factory)()?;
        self.connect(link).map(|_| ())
    }

    /// One exchange cycle: mode changes, targets out, positions and errors back.
    fn cycle_once(&mut self, frame: Option<CommandFrame>) -> Result<(), BoardFault> {
        let n = self.n();
        let report = self.report_axes;
        let Some(client) = self.client.as_mut() else {
            return Err(BoardFault::Closed);
        };
        let fault = |e: GalilError| BoardFault::from_error(&e);
        // 1. Desired modes.
        let mut desired = [None; MAX_AXES];
        if let Some(f) = frame {
            for i in 0..n {
                desired[i] = Some(if f.enabled {
                    f.commands[i]
                } else {
                    AxisCommand::Off
                });
            }
        }
        // 2. Mode changes (rare; several exchanges).
        let mut to_off = Axes::NONE;
        let mut to_on = Axes::NONE;
        let mut to_position = Axes::NONE;
        let mut to_effort = Axes::NONE;
        let mut restore_gains = Axes::NONE;
        for i in 0..n {
            let want = match desired[i] {
                None => continue,
                Some(AxisCommand::Off) => Mode::Off,
                Some(AxisCommand::Position(_)) => Mode::Position,
                Some(AxisCommand::Effort(_)) => Mode::Effort,
            };
            if want == self.modes[i] {
                continue;
            }
            let bit = Axes(1 << i);
            match want {
                Mode::Off => to_off.0 |= bit.0,
                Mode::Position => to_position.0 |= bit.0,
                Mode::Effort => to_effort.0 |= bit.0,
                Mode::Unknown => {}
            }
            if want != Mode::Off && matches!(self.modes[i], Mode::Off | Mode::Unknown) {
                to_on.0 |= bit.0;
            }
            if want == Mode::Position
                && (matches!(self.modes[i], Mode::Effort | Mode::Unknown) || self.gains_zeroed[i])
            {
                restore_gains.0 |= bit.0;
            }
        }
        if !to_off.is_empty() {
            client.ack(&Command::MotorOff(to_off)).map_err(fault)?;
        }
        if !to_effort.is_empty() {
            // Zero gains: OF is then the output.
            let mut zeros = [None; MAX_AXES];
            let mut of = [None; MAX_AXES];
            for i in to_effort.indices() {
                zeros[i] = Some(0.0);
                of[i] = Some(0.0);
            }
            for s in [
                Setting::PositionTracking,
                Setting::Kp,
                Setting::Ki,
                Setting::Kd,
            ] {
                client.set(s, &zeros[..n]).map_err(fault)?;
            }
            client.set(Setting::Offset, &of[..n]).map_err(fault)?;
            for i in to_effort.indices() {
                self.gains_zeroed[i] = true;
            }
        }
        if !to_position.is_empty() {
            let mut of = [None; MAX_AXES];
            let mut g = [[None; MAX_AXES]; 3];
            let mut pt = [None; MAX_AXES];
            let tracking = self.config.target_mode == TargetMode::PositionTracking;
            for i in to_position.indices() {
                pt[i] = Some(if tracking { 1.0 } else { 0.0 });
            }
            for i in restore_gains.indices() {
                of[i] = Some(0.0);
                for (k, gk) in g.iter_mut().enumerate() {
                    gk[i] = Some(self.gains[i][k]);
                }
            }
            if !restore_gains.is_empty() {
                client.set(Setting::Offset, &of[..n]).map_err(fault)?;
                for (k, s) in [Setting::Kp, Setting::Ki, Setting::Kd]
                    .into_iter()
                    .enumerate()
                {
                    client.set(s, &g[k][..n]).map_err(fault)?;
                }
                for i in restore_gains.indices() {
                    self.gains_zeroed[i] = false;
                }
            }
            // Servo on (holding the current position) before tracking starts.
            let on = Axes(to_on.0 & to_position.0);
            if !on.is_empty() {
                client.ack(&Command::ServoHere(on)).map_err(fault)?;
            }
            client
                .set(Setting::PositionTracking, &pt[..n])
                .map_err(fault)?;
            for i in to_position.indices() {
                self.sent_target[i] = None;
            }
        }
        let on_effort = Axes(to_on.0 & to_effort.0);
        if !on_effort.is_empty() {
            client.ack(&Command::ServoHere(on_effort)).map_err(fault)?;
        }
        for i in 0..n {
            match desired[i] {
                Some(AxisCommand::Off) => self.modes[i] = Mode::Off,
                Some(AxisCommand::Position(_)) => self.modes[i] = Mode::Position,
                Some(AxisCommand::Effort(_)) => self.modes[i] = Mode::Effort,
                None => {}
            }
        }
        // 3. The cycle line: targets, then TP and TE (and TS in relative mode).
        let mut targets = [None; MAX_AXES];
        let mut offsets = [None; MAX_AXES];
        let mut relative = false;
        let mut begin = Axes::NONE;
        for i in 0..n {
            match desired[i] {
                Some(AxisCommand::Position(p)) => match self.config.target_mode {
                    TargetMode::PositionTracking => targets[i] = Some(p as f64),
                    TargetMode::Relative => {
                        let from = self.sent_target[i].unwrap_or(self.state[i].position);
                        if p != from && !self.moving[i] {
                            targets[i] = Some(p.saturating_sub(from) as f64);
                            self.sent_target[i] = Some(p);
                            begin.0 |= 1 << i;
                            relative = true;
                        }
                    }
                },
                Some(AxisCommand::Effort(t)) => {
                    let v =
                        (t * self.config.volts_per_newton_metre[i]).clamp(-MAX_VOLTS, MAX_VOLTS);
                    offsets[i] = Some(v);
                    self.state[i].effort = t;
                }
                _ => {}
            }
        }
        let mut parts: heapless::Vec<Command<'_>, 6> = heapless::Vec::new();
        let target_setting = if relative {
            Setting::PositionRelative
        } else {
            Setting::PositionAbsolute
        };
        let has_targets = targets.iter().any(Option::is_some);
        let has_offsets = offsets.iter().any(Option::is_some);
        let relative_mode = self.config.target_mode == TargetMode::Relative;
        let _ = parts.push(Command::Set(target_setting, &targets[..n]));
        let _ = parts.push(Command::Set(Setting::Offset, &offsets[..n]));
        let _ = parts.push(Command::Begin(begin));
        let _ = parts.push(Command::Tell(Tell::Position, report));
        let _ = parts.push(Command::Tell(Tell::Error, report));
        let _ = parts.push(Command::Tell(Tell::Switches, report));
        let used = [
            has_targets,
            has_offsets,
            !begin.is_empty(),
            true,
            true,
            relative_mode,
        ];
        let mut line: heapless::Vec<Command<'_>, 6> = heapless::Vec::new();
        for (c, u) in parts.iter().zip(used) {
            if u {
                let _ = line.push(*c);
            }
        }
        let mut replies: [Reply; 6] = Default::default();
        let reads = line.len() - usize::from(relative_mode) - 2;
        if encode_line(&line).is_ok() {
            client.transact(&line, &mut replies).map_err(fault)?;
        } else {
            // Too long for one line: one command per exchange.
            for (c, r) in line.iter().zip(replies.iter_mut()) {
                *r = client.command(c).map_err(fault)?;
            }
        }
        let mut values = [0.0; MAX_GALIL_AXES];
        let parse = |text: &[u8], values: &mut [f64; MAX_GALIL_AXES]| -> Result<(), BoardFault> {
            match parse_numbers(text, values) {
                Ok(k) if k == n => Ok(()),
                _ => Err(BoardFault::Garbled),
            }
        };
        parse(&replies[reads].text, &mut values)?;
        for i in 0..n {
            self.state[i].position = to_counts(values[i]).map_err(|_| BoardFault::Garbled)?;
        }
        parse(&replies[reads + 1].text, &mut values)?;
        for i in 0..n {
            self.state[i].following_error =
                to_counts(values[i]).map_err(|_| BoardFault::Garbled)?;
        }
        if relative_mode {
            parse(&replies[reads + 2].text, &mut values)?;
            self.apply_switches(&values)?;
        }
        // 4. Status every few cycles: velocity, torque, switches.
        self.cycle += 1;
        if self
            .cycle
            .is_multiple_of(u64::from(self.config.status_every.max(1)))
        {
            let Some(client) = self.client.as_mut() else {
                return Err(BoardFault::Closed);
            };
            let status = [
                Command::Tell(Tell::Velocity, report),
                Command::Tell(Tell::Torque, report),
                Command::Tell(Tell::Switches, report),
            ];
            let mut replies: [Reply; 3] = Default::default();
            client.transact(&status, &mut replies).map_err(fault)?;
            parse(&replies[0].text, &mut values)?;
            for i in 0..n {
                self.state[i].velocity = values[i];
            }
            parse(&replies[1].text, &mut values)?;
            for i in 0..n {
                let scale = self.config.volts_per_newton_metre[i];
                if self.modes[i] != Mode::Effort && scale != 0.0 {
                    self.state[i].effort = values[i] / scale;
                }
            }
            parse(&replies[2].text, &mut values)?;
            self.apply_switches(&values)?;
        }
        Ok(())
    }

    /// Reads `TS` values: amplifier state and motion; an axis the board switched off while it
    /// should be on is a fault.
    fn apply_switches(&mut self, ts: &[f64; MAX_GALIL_AXES]) -> Result<(), BoardFault> {
        for i in 0..self.n() {
            let bits = ts[i] as u32;
            let off = bits & 0x20 != 0;
            self.state[i].enabled = !off;
            self.moving[i] = bits & 0x80 != 0;
            if off && matches!(self.modes[i], Mode::Position | Mode::Effort) {
                return Err(BoardFault::MotorOff(i as u8));
            }
        }
        Ok(())
    }
}
