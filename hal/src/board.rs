//! Boards: the interface from a computer to hardware, one axis per motor and encoder.
//!
//! A board reads encoder counts and writes one command per axis. A robot's joints are mapped onto
//! one or more boards by configuration; one board may serve several robots.
//!
//! # Real-time
//! A board that is memory-like (the simulated board, the FPGA emulation) may be called from the
//! control thread directly. A board whose transport can block (a Galil DMC on a serial line) must
//! implement these methods as exchanges with its own I/O thread through lock-free cells, so that
//! no call here blocks.

use crate::error::Error;
use crate::time::Timestamp;

/// The largest number of axes one board may have.
pub const MAX_AXES: usize = 8;

/// What one axis measured.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct AxisState {
    /// Encoder position, counts.
    pub position: i64,
    /// Encoder velocity, counts/s (the board's estimate).
    pub velocity: f64,
    /// The effort the axis is applying, N·m at the joint (the command as the amplifier saw it,
    /// after saturation). *NOTE*: this is the commanded value; the physical torque may differ.
    pub effort: f64,
    /// Position error of the board's own servo loop, counts (zero in torque mode).
    pub following_error: i64,
    /// True when the axis' amplifier is enabled.
    pub enabled: bool,
}

/// What one axis is told to do.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum AxisCommand {
    /// Amplifier off (motor free).
    #[default]
    Off,
    /// Apply a torque, N·m at the joint. The board converts to its output (DAC volts, current)
    /// and saturates at its limit.
    Effort(f64),
    /// Servo to an absolute encoder position, counts, with the board's own position loop.
    Position(i64),
}

/// A board's hardware interface.
pub trait Board {
    /// The board's error type.
    type Error: Error;

    /// Number of axes (at most [`MAX_AXES`]).
    fn axis_count(&self) -> usize;

    /// Reads every axis into `out` (`out.len()` must be at least [`axis_count`](Board::axis_count)).
    ///
    /// # Errors
    /// A device, communication or timeout error; the caller holds or stops the robot.
    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), Self::Error>;

    /// Writes one command per axis (`commands.len()` must be at least
    /// [`axis_count`](Board::axis_count)).
    ///
    /// # Errors
    /// A device, communication or timeout error, or invalid input (wrong length, non-finite effort).
    fn write_axes(&mut self, now: Timestamp, commands: &[AxisCommand]) -> Result<(), Self::Error>;

    /// Turns every amplifier on (servo here) or off.
    ///
    /// # Errors
    /// As for [`write_axes`](Board::write_axes).
    fn set_enabled(&mut self, enabled: bool) -> Result<(), Self::Error>;

    /// Asks a board that latched a fault of its own (a lost line, a watchdog) to leave it, once
    /// its cause is gone; the amplifiers stay as they are until the next
    /// [`set_enabled`](Board::set_enabled). Boards without such a latch do nothing (the default).
    ///
    /// # Real-time
    /// Implementations must not block: a board that needs I/O to re-arm hands the request to
    /// its own I/O thread.
    ///
    /// # Errors
    /// As for [`write_axes`](Board::write_axes).
    fn rearm(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}
