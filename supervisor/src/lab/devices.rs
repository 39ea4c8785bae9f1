//! The lab's devices as the control loops see them: one board type and one interaction type
//! whatever the configuration chose, so a simulated board and a real one are swapped by a word.
//!
//! # Galil boards
//!
//! [`galil_board`] opens a Galil DMC (a real one, or `penelope galil-sim`) for one robot and
//! says how its axes bind to the robot's joints. Assumptions, until the lab file can say
//! otherwise:
//!
//! - **Encoder zero is the robot's `start` pose.** A DMC's incremental encoders count from where
//!   the motors were at power-up, so the lab assumes the arm was parked in its configured `start`
//!   pose when the board was switched on: each joint's `offset_counts` is minus the start pose in
//!   counts. A freshly started `penelope galil-sim` reads zero counts on every axis, so the
//!   emulated PUMA starts in its `start` pose. Counts away from zero are motion since power-up.
//! - **±10 V at the effort limit.** The DMC's `OF` output is a ±10 V amplifier command; the
//!   lab assumes the amplifiers are scaled so that 10 V is the joint's `effort_max` (the model's
//!   torque limit, 100 N·m when the model has none); the driver signs each axis from the joint's
//!   counts per radian ([`GalilBoard::orient`]: a positive volt drives the encoder count up).
//! - Releasing the board (dropping it) is the driver's: amplifiers off and the watchdog halted.
//! - Joint `j` is on board axis `axes[j]` (default `j`); the board drives its first
//!   `max(axes) + 1` axes, and an axis no joint uses is switched off (`MO`).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use penelope_drivers::galil::{
    GalilBoard, GalilBoardConfig, GalilBoardError, GalilError, axis_bindings,
};
use penelope_drivers::model::{DhRobot, DhRobotModel};
use penelope_drivers::sim::ToolContact;
use penelope_drivers::sim::board::{SimBoard, SimBoardError};
use penelope_hal::{
    AxisCommand, AxisState, Board, Error, ErrorKind, JointVector, Kinematics, MAX_AXES, MAX_JOINTS,
    RobotModel, Timestamp,
};
use penelope_rt_core::control::AxisBinding;

use super::config::{BoardConfig, BoardKind};
use crate::objects::kinematics::RobotKinematics;

/// Any board the lab can drive.
pub enum LabBoard {
    /// A simulated board with its plant.
    Sim(Box<SimBoard<RobotKinematics, ToolContact>>),
    /// A Galil DMC on a serial line (no plant behind it in this process).
    Galil(Box<LabGalilBoard>),
}

/// A board error, whatever the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LabBoardError {
    /// From a simulated board.
    Sim(SimBoardError),
    /// From a Galil board.
    Galil(GalilBoardError),
}

impl Error for LabBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            LabBoardError::Sim(e) => e.kind(),
            LabBoardError::Galil(e) => e.kind(),
        }
    }
}

impl core::fmt::Display for LabBoardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LabBoardError::Sim(e) => write!(f, "simulated board: {e:?}"),
            LabBoardError::Galil(e) => write!(f, "{e}"),
        }
    }
}

/// Counters of a Galil board's serial link, readable from any thread while the board is driven
/// by a control thread (and after it is gone).
#[derive(Clone, Debug, Default)]
pub struct LinkMonitor {
    inner: Arc<LinkCounters>,
}

#[derive(Debug, Default)]
struct LinkCounters {
    /// Exchange cycles the I/O thread completed, at the last board read.
    cycles: AtomicU64,
    /// The I/O thread's exchange rate over its last half second, Hz (f64 bits).
    rate_bits: AtomicU64,
    /// Cycles and caller time (ns) at the first board read, for the mean rate.
    first_cycles: AtomicU64,
    first_ns: AtomicU64,
    /// Caller time (ns) at the last board read.
    last_ns: AtomicU64,
    started: AtomicBool,
    /// The board reported a fault at the last read.
    faulted: AtomicBool,
}

impl LinkMonitor {
    /// Records the board's counters at a read at `now`.
    ///
    /// # Real-time
    /// Relaxed atomic loads and stores only.
    fn record(&self, board: &GalilBoard, now: Timestamp) {
        let c = &self.inner;
        let cycles = board.cycles();
        let ns = now.as_nanos();
        if !c.started.load(Ordering::Relaxed) {
            c.first_cycles.store(cycles, Ordering::Relaxed);
            c.first_ns.store(ns, Ordering::Relaxed);
            c.started.store(true, Ordering::Relaxed);
        }
        c.cycles.store(cycles, Ordering::Relaxed);
        c.last_ns.store(ns, Ordering::Relaxed);
        c.rate_bits
            .store(board.exchange_rate_hz().to_bits(), Ordering::Relaxed);
        c.faulted.store(board.is_faulted(), Ordering::Relaxed);
    }

    /// Command/reply cycles completed since the board was opened (as of the last read).
    pub fn cycles(&self) -> u64 {
        self.inner.cycles.load(Ordering::Relaxed)
    }

    /// The I/O thread's exchange rate over its last half second of good exchanges, Hz (0 before
    /// the first half second).
    pub fn exchange_rate_hz(&self) -> f64 {
        f64::from_bits(self.inner.rate_bits.load(Ordering::Relaxed))
    }

    /// Mean exchange rate between the first and the last board read, Hz (0 when they coincide).
    pub fn mean_exchange_rate_hz(&self) -> f64 {
        let c = &self.inner;
        let span_ns = c
            .last_ns
            .load(Ordering::Relaxed)
            .saturating_sub(c.first_ns.load(Ordering::Relaxed));
        let cycles = c
            .cycles
            .load(Ordering::Relaxed)
            .saturating_sub(c.first_cycles.load(Ordering::Relaxed));
        if span_ns == 0 {
            0.0
        } else {
            cycles as f64 / (span_ns as f64 * 1e-9)
        }
    }

    /// True when the board reported a fault at the last read.
    pub fn faulted(&self) -> bool {
        self.inner.faulted.load(Ordering::Relaxed)
    }
}

/// A [`GalilBoard`] as the lab drives it: its link counters go to a [`LinkMonitor`] at every
/// read; dropping it releases the board (the driver switches the amplifiers off).
pub struct LabGalilBoard {
    board: GalilBoard,
    monitor: LinkMonitor,
}

impl LabGalilBoard {
    /// The driver.
    pub fn board(&self) -> &GalilBoard {
        &self.board
    }

    /// The link counters (a handle on the same counters).
    pub fn monitor(&self) -> LinkMonitor {
        self.monitor.clone()
    }
}

impl Board for LabBoard {
    type Error = LabBoardError;

    fn axis_count(&self) -> usize {
        match self {
            LabBoard::Sim(b) => b.axis_count(),
            LabBoard::Galil(g) => g.board.axis_count(),
        }
    }

    /// # Real-time
    /// As the board's: a simulated board steps its plant; a Galil board reads a latest-value
    /// cell (wait-free) and updates its [`LinkMonitor`] with relaxed atomics.
    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), LabBoardError> {
        match self {
            LabBoard::Sim(b) => b.read_axes(now, out).map_err(LabBoardError::Sim),
            LabBoard::Galil(g) => {
                let result = g.board.read_axes(now, out).map_err(LabBoardError::Galil);
                g.monitor.record(&g.board, now);
                result
            }
        }
    }

    /// # Real-time
    /// As the board's (a Galil board writes a latest-value cell, wait-free).
    fn write_axes(
        &mut self,
        now: Timestamp,
        commands: &[AxisCommand],
    ) -> Result<(), LabBoardError> {
        match self {
            LabBoard::Sim(b) => b.write_axes(now, commands).map_err(LabBoardError::Sim),
            LabBoard::Galil(g) => g
                .board
                .write_axes(now, commands)
                .map_err(LabBoardError::Galil),
        }
    }

    /// # Real-time
    /// As the board's (a Galil board writes a latest-value cell, wait-free).
    fn set_enabled(&mut self, enabled: bool) -> Result<(), LabBoardError> {
        match self {
            LabBoard::Sim(b) => b.set_enabled(enabled).map_err(LabBoardError::Sim),
            LabBoard::Galil(g) => g.board.set_enabled(enabled).map_err(LabBoardError::Galil),
        }
    }
}

/// Why a Galil board could not be set up for a robot.
#[derive(Debug, thiserror::Error)]
pub enum GalilSetupError {
    /// The board's entry does not fit the robot (not a galil board, no port, bad axis map).
    #[error("galil board: {0}")]
    Invalid(String),
    /// The port could not be opened or the board did not initialise.
    #[error("galil board on {port}: {source}")]
    Open {
        /// The serial port.
        port: String,
        /// The cause.
        source: GalilError,
    },
    /// The board opened but sent no usable state in time.
    #[error("galil board on {port}: no axis state within {waited:?} ({last})")]
    NoState {
        /// The serial port.
        port: String,
        /// How long it waited.
        waited: Duration,
        /// The last read error.
        last: GalilBoardError,
    },
}

/// A Galil board opened for one robot, with what the control loop needs to bind it.
pub struct GalilSetup {
    /// The board ([`LabBoard::Galil`]).
    pub board: LabBoard,
    /// `bindings[j]`: joint `j`'s axis, counts per radian and encoder offset (for
    /// `ControlConfig::axes`).
    pub bindings: [AxisBinding; MAX_JOINTS],
    /// The joint positions the encoders read at start, rad (m for prismatic joints).
    pub measured: JointVector,
    /// The link counters.
    pub monitor: LinkMonitor,
}

/// Amplifier command at a joint's effort limit, V (the DMC's ±10 V output).
pub const GALIL_FULL_SCALE_VOLTS: f64 = 10.0;

/// Effort full scale of a joint whose model has no finite effort limit, N·m.
pub const DEFAULT_EFFORT_FULL_SCALE: f64 = 100.0;

/// How long [`galil_board`] waits for the board's first axis state.
pub const FIRST_STATE_TIMEOUT: Duration = Duration::from_secs(2);

/// Opens the Galil board `cfg` for the robot `model` and reads where the robot is.
///
/// Axes: joint `j` on `cfg.axes[j]` (default `j`); the board drives its first `max + 1` axes.
/// Scaling: the model's counts per radian (as [`axis_bindings`]), encoder zero at `zero_pose`
/// (the robot's configured `start` pose, see the [module docs](self)), and `OF` volts per N·m of
/// `10 V / effort_max`, signed by the driver from the counts per radian. Serial line: `cfg.port` at `cfg.baud`.
///
/// Blocks (not real-time) until the board's I/O thread published its first state, at most
/// [`FIRST_STATE_TIMEOUT`]; `now` stamps that first read.
///
/// # Errors
/// [`GalilSetupError::Invalid`] for a board entry that is not a galil board with a port, or an
/// axis map that does not fit the robot (wrong length, axis past 8, an axis used twice);
/// [`GalilSetupError::Open`] when the port cannot be opened or the board does not answer or has
/// too few axes; [`GalilSetupError::NoState`] when no state arrives in time.
pub fn galil_board(
    cfg: &BoardConfig,
    model: &DhRobotModel,
    zero_pose: &JointVector,
    now: Timestamp,
) -> Result<GalilSetup, GalilSetupError> {
    let invalid = |m: String| Err(GalilSetupError::Invalid(m));
    if cfg.kind != BoardKind::Galil {
        return invalid(format!(
            "board for `{}` is not of kind \"galil\"",
            cfg.robot
        ));
    }
    let Some(port) = cfg.port.clone() else {
        return invalid(format!("board for `{}` needs `port`", cfg.robot));
    };
    let n = model.joint_count().min(MAX_JOINTS);
    let map: Vec<u8> = match &cfg.axes {
        Some(a) => a.clone(),
        None => (0..n as u8).collect(),
    };
    if map.len() != n {
        return invalid(format!(
            "`axes` has {} entries, robot `{}` has {n} joints",
            map.len(),
            cfg.robot
        ));
    }
    let board_axes = MAX_AXES.min(8);
    for (j, a) in map.iter().enumerate() {
        if usize::from(*a) >= board_axes {
            return invalid(format!(
                "joint {j} on axis {a}: a DMC has axes 0..={}",
                board_axes - 1
            ));
        }
        if map[..j].contains(a) {
            return invalid(format!("joint {j} shares axis {a} with another joint"));
        }
    }
    let driven = map.iter().map(|a| usize::from(*a) + 1).max().unwrap_or(1);

    let robot = DhRobot::new(model.clone());
    let mut bindings = axis_bindings(&robot);
    let mut volts = [0.0; MAX_AXES];
    let limits = model.limits();
    for j in 0..n {
        let b = &mut bindings[j];
        b.axis = map[j];
        let cpr = b.counts_per_radian;
        if !(cpr.is_finite() && cpr != 0.0) {
            return invalid(format!(
                "joint {j}: counts per radian must be finite and non-zero"
            ));
        }
        b.offset_counts = -((zero_pose[j] * cpr).round() as i64);
        let effort = limits.effort_max[j];
        let full_scale = if effort.is_finite() && effort > 0.0 {
            effort
        } else {
            DEFAULT_EFFORT_FULL_SCALE
        };
        volts[usize::from(map[j])] = GALIL_FULL_SCALE_VOLTS / full_scale;
    }
    let mut config = GalilBoardConfig::new(port.clone(), driven, &volts);
    config.serial.baud = cfg.baud;
    let mut board = GalilBoard::open(config).map_err(|source| GalilSetupError::Open {
        port: port.clone(),
        source,
    })?;
    board.orient(&bindings[..n]);

    // The I/O thread publishes its first state after one exchange cycle.
    let mut axes = [AxisState::default(); MAX_AXES];
    let waited = Instant::now();
    loop {
        match board.read_axes(now, &mut axes[..driven]) {
            Ok(()) => break,
            Err(GalilBoardError::NoData) if waited.elapsed() < FIRST_STATE_TIMEOUT => {
                std::thread::sleep(Duration::from_millis(2));
            }
            Err(last) => {
                return Err(GalilSetupError::NoState {
                    port,
                    waited: waited.elapsed(),
                    last,
                });
            }
        }
    }
    let mut measured = JointVector::zeros();
    for j in 0..n {
        let b = bindings[j];
        let counts = axes[usize::from(b.axis)]
            .position
            .wrapping_sub(b.offset_counts);
        measured[j] = counts as f64 / b.counts_per_radian;
    }
    let monitor = LinkMonitor::default();
    monitor.record(&board, now);
    Ok(GalilSetup {
        board: LabBoard::Galil(Box::new(LabGalilBoard {
            board,
            monitor: monitor.clone(),
        })),
        bindings,
        measured,
        monitor,
    })
}
