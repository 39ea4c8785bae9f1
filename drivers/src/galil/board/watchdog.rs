//! The board-side watchdog: a DMC program, downloaded at configure and run in its own thread,
//! that turns the motors off when the host's heartbeat variable stops changing.
//!
//! A host that dies, or a cable that is pulled, cannot send anything, so the last torque (`OF`)
//! would stay on the amplifiers. The host writes [`HEARTBEAT`] with a new value on every
//! exchange; the program compares it with the value it saw last at every pass (about one per
//! servo sample), and when it has not changed for the watchdog time it sends `MO` and zeroes
//! `OF` on the driven axes, sets [`TRIPPED`] to 1 and ends.
//!
//! *NOTE*: the download replaces the board's program memory and `HX` halts every thread first:
//! a board Penelope drives runs no other program.

use std::fmt::Write as _;
use std::time::Duration;

use super::super::command::AXIS_LETTERS;

/// The default watchdog time: what surgical teleoperation consoles use.
pub const DEFAULT_WATCHDOG: Duration = Duration::from_millis(30);

/// The program thread the watchdog runs in.
pub const WATCHDOG_THREAD: u8 = 7;

/// The program's label (without `#`).
pub const WATCHDOG_LABEL: &str = "PNWDOG";

/// The heartbeat variable the host writes.
pub const HEARTBEAT: &str = "pnhb";

/// The variable the program sets to 1 when it turned the motors off.
pub const TRIPPED: &str = "pntrip";

/// Servo samples the program waits without a heartbeat change: it sees a change within about
/// one sample and acts about one sample after its limit, so the limit is two samples short of
/// the watchdog time (at least 1).
pub fn limit_samples(timeout: Duration, servo_period: f64) -> u32 {
    let samples = (timeout.as_secs_f64() / servo_period.max(1e-6)).floor();
    (samples - 2.0).clamp(1.0, 1e9) as u32
}

/// The program text for `axes` driven axes (CR-separated lines, each within 80 characters).
pub fn program(timeout: Duration, servo_period: f64, axes: usize) -> String {
    let letters: String = AXIS_LETTERS.iter().take(axes.clamp(1, 8)).collect();
    let zeros = vec!["0"; axes.clamp(1, 8)].join(",");
    let limit = limit_samples(timeout, servo_period);
    let mut p = String::new();
    let _ = write!(
        p,
        "#{WATCHDOG_LABEL}\r\
         pnlast={HEARTBEAT};pnt0=TIME\r\
         #PNWDLP\r\
         IF ({HEARTBEAT}<>pnlast)\r\
         pnlast={HEARTBEAT};pnt0=TIME\r\
         ENDIF\r\
         IF ((TIME-pnt0)>{limit})\r\
         MO {letters};OF {zeros}\r\
         {TRIPPED}=1\r\
         EN\r\
         ENDIF\r\
         JP #PNWDLP\r"
    );
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_limit_leaves_room_for_the_program_to_see_and_act() {
        // TM 1000: 976.5625 µs samples; 30 ms is 30.7 samples.
        assert_eq!(limit_samples(DEFAULT_WATCHDOG, 976.5625e-6), 28);
        assert_eq!(limit_samples(Duration::from_millis(1), 976.5625e-6), 1);
        let p = program(DEFAULT_WATCHDOG, 976.5625e-6, 6);
        assert!(p.contains("MO ABCDEF;OF 0,0,0,0,0,0"));
        assert!(p.split('\r').all(|l| l.len() <= 80));
    }
}
