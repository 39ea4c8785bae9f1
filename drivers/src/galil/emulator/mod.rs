//! A DMC-40x0 emulator: the reply grammar, echo, `TC1` codes for the common errors, stop codes,
//! `QZ`/`QR`, position tracking, and motor dynamics per axis at the `TM` servo period.
//!
//! [`Dmc`] is the pure state machine (bytes in, bytes out, time passed in); [`PtyEmulator`] runs
//! it on a pseudo-terminal so any serial client can drive it like a board
//! (`penelope galil-sim`).
//!
//! # What it models
//!
//! - Commands end with CR or `;`; each gets `:` (accepted, after any data and `\r\n`) or a lone
//!   `?` (rejected). An empty line gets `:`. Lines over 80 characters and lower-case commands are
//!   rejected (code 1). Unknown commands: code 1. Values out of range: code 6. `PR`/`PA` during a
//!   profiled move: code 7. `BG` with the motor off: 20; while moving: 21.
//! - `EO` (echo, on after power-up and `RS`), `CW` (`CW1` sets bit 7 on unsolicited bytes; `CW2`,
//!   the power-up default, does not), `LZ` (`LZ0` prints ten-digit zero-padded fields), `TC0`/`TC1`
//!   (reading clears), `TM`, `RS`, `^R^V`, `QZ`, `QR`, `MG` (strings, numbers and `_TP`, `_TE`,
//!   `_TV`, `_TT`, `_TS`, `_SC`, `_BG` operands, four decimals).
//! - Per axis: `SH`, `MO`, `BG`, `ST`, `AB`, `TP`, `TE`, `TV`, `TT`, `TS`, `SC`, and the settings
//!   `PR PA SP AC DC JG KP KI KD OF TL ER OE PT` written positionally, by name (`PRA=10`) or
//!   queried (`PR ?,?`, `ACA=?`).
//! - Dynamics at the `TM` period (`TM 1000` = 976.5625 µs): a trapezoidal profiler (`SP`, `AC`,
//!   `DC`) drives the reference; with the motor on, the motor follows the reference as a
//!   critically damped 20 Hz second-order loop with acceleration feed-forward; with zero gains
//!   (`KP`=`KI`=`KD`=0) the axis is in torque mode and `OF` volts accelerate it; with the motor
//!   off it coasts. `OE` ≥ 1 turns the motor off (stop code 8) when `|TE|` exceeds `ER`. `TS`
//!   bits: 7 moving, 5 motor off, 3 and 2
//!   the limit switches (1 = inactive, as wired on a DMC-40x0 without switches).
//!
//! - Programs ([`program`]): `DL` downloads text up to `\` (or Ctrl-Z), parsed at once (a
//!   program that does not parse is refused with `?`); `XQ #LABEL,t` runs it in thread `t`
//!   (0..7), `HX t` / `HX` halts threads; host assignments `name=value` and `MG name` read and
//!   write the same variables; `TIME` counts servo samples. Threads run at the servo rate, so a
//!   watchdog program keeps time on the emulator's own clock whether or not a host talks to it.
//! - An arm ([`ArmConfig`]): the axes can drive a robot's rigid-body plant (gravity included)
//!   instead of bare motors.
//!
//! The emulator records when each amplifier went off and when the host last sent a command, on
//! its own clock ([`Dmc::now`]), so tests can bound a watchdog against the emulator's time.
//!
//! The emulator allocates freely: it stands in for hardware and never runs in the control thread.

mod arm;
mod axis;
pub mod program;
mod pty;
mod threads;

pub use arm::ArmConfig;
pub use pty::{DmcObserver, PtyEmulator, PtyOptions};

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use axis::{AxisSim, Profile, axis_record};
use program::{Program, Thread};

use super::command::{AXIS_LETTERS, MAX_GALIL_AXES, MAX_LINE, Setting};
use super::record::{AxisRecord, RecordLayout, encode_record};

/// Threads a DMC-40x0 runs programs in.
pub const THREADS: usize = 8;

/// Variables a DMC-40x0 holds.
pub const MAX_VARIABLES: usize = 510;

/// The largest program `DL` takes, bytes (a DMC-40x0 holds 4000 lines of 80 characters; the
/// emulator is stricter).
pub const MAX_PROGRAM: usize = 64 * 1024;

/// How the emulator presents itself.
#[derive(Clone, Debug, PartialEq)]
pub struct DmcConfig {
    /// Number of axes, 1..=8.
    pub axes: usize,
    /// Model string, e.g. `DMC4060`.
    pub model: String,
    /// Firmware revision string.
    pub firmware: String,
    /// A robot arm the axes drive; `None`: each axis is a bare motor.
    pub arm: Option<ArmConfig>,
}

impl Default for DmcConfig {
    fn default() -> Self {
        DmcConfig {
            axes: 6,
            model: "DMC4060".into(),
            firmware: "1.2h1-SIN".into(),
            arm: None,
        }
    }
}

/// A snapshot of one emulated axis, for tests and displays.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AxisSnapshot {
    /// Motor position, counts.
    pub position: f64,
    /// Profiler reference position, counts.
    pub reference: f64,
    /// Velocity, counts/s.
    pub velocity: f64,
    /// Amplifier on.
    pub motor_on: bool,
    /// Stop code.
    pub stop_code: u8,
    /// Position tracking mode on.
    pub tracking: bool,
    /// Output (DAC) volts.
    pub output: f64,
    /// `OF` setting, volts.
    pub offset: f64,
    /// When the amplifier last went from on to off, on the emulator's clock.
    pub off_at: Option<Duration>,
    /// How long the host had been silent (no command received) at that instant.
    pub host_silent_at_off: Option<Duration>,
}

/// The emulated controller.
#[derive(Clone, Debug)]
pub struct Dmc {
    config: DmcConfig,
    layout: RecordLayout,
    echo: bool,
    marked: bool,
    lz0: bool,
    error_code: u16,
    tm: f64,
    axes: Vec<AxisSim>,
    sim_time: f64,
    sample: u16,
    line: Vec<u8>,
    line_too_long: bool,
    parts_in_line: usize,
    pending_unsolicited: VecDeque<Vec<u8>>,
    /// Servo samples since power-up (`TIME`).
    ticks: u64,
    variables: HashMap<String, f64>,
    program: Option<Arc<Program>>,
    threads: [Option<Thread>; THREADS],
    /// Threads halted (`HX`) while one of them was running, one bit each.
    halted: u8,
    /// Program text being received after `DL`.
    download: Option<Vec<u8>>,
    arm: Option<arm::Arm>,
    /// Amplifier state seen last, and when each went off.
    was_on: Vec<bool>,
    off_at: Vec<Option<f64>>,
    silent_at_off: Vec<Option<f64>>,
    last_command_at: Option<f64>,
}

/// Galil's text for the error codes the emulator produces.
pub fn error_text(code: u16) -> &'static str {
    match code {
        0 => "No error",
        1 => "Unrecognized command",
        6 => "Number out of range",
        7 => "Command not valid while running",
        20 => "Begin not valid with motor off",
        21 => "Begin not valid while running",
        22 => "Begin not possible due to limit switch",
        _ => "Error",
    }
}

/// The largest simulated time one call catches up, seconds (an idle emulator jumps beyond it).
const MAX_CATCH_UP: f64 = 60.0;

impl Dmc {
    /// A controller at power-up: echo on, `CW2`, `LZ1`, motors off, every axis at zero.
    pub fn new(config: DmcConfig) -> Self {
        let n = config.axes.clamp(1, MAX_GALIL_AXES);
        let config = DmcConfig { axes: n, ..config };
        Dmc {
            layout: RecordLayout {
                axes: n,
                general: 52,
                coordinated: 26,
                axis: 36,
            },
            config,
            echo: true,
            marked: false,
            lz0: false,
            error_code: 0,
            tm: 1000.0,
            axes: vec![AxisSim::new(); n],
            sim_time: 0.0,
            sample: 0,
            line: Vec::new(),
            line_too_long: false,
            parts_in_line: 0,
            pending_unsolicited: VecDeque::new(),
            ticks: 0,
            variables: HashMap::new(),
            program: None,
            threads: Default::default(),
            halted: 0,
            download: None,
            arm: None,
            was_on: vec![false; n],
            off_at: vec![None; n],
            silent_at_off: vec![None; n],
            last_command_at: None,
        }
        .with_arm()
    }

    fn with_arm(mut self) -> Self {
        let period = self.servo_period();
        self.arm = self.config.arm.clone().map(|a| arm::Arm::new(a, period));
        self.sync_arm();
        self
    }

    /// Axes read the arm's encoders.
    fn sync_arm(&mut self) {
        if let Some(arm) = &self.arm {
            for (j, a) in self.axes.iter_mut().enumerate().take(arm.joints()) {
                let (p, v) = arm.encoder(j);
                a.moved(p, v);
            }
        }
    }

    /// The emulator's clock: simulated time since power-up.
    pub fn now(&self) -> Duration {
        Duration::from_secs_f64(self.sim_time)
    }

    /// When the host last sent a command (any part of a line), on the emulator's clock.
    pub fn last_command_at(&self) -> Option<Duration> {
        self.last_command_at.map(Duration::from_secs_f64)
    }

    /// The arm's joint positions, rad, when the axes drive an arm.
    pub fn arm_joints(&self) -> Option<penelope_hal::JointVector> {
        self.arm.as_ref().map(arm::Arm::joint_positions)
    }

    /// The configuration (axes clamped to 1..=8).
    pub fn config(&self) -> &DmcConfig {
        &self.config
    }

    /// The record layout `QZ` reports.
    pub fn layout(&self) -> RecordLayout {
        self.layout
    }

    /// One axis' state.
    pub fn axis(&self, i: usize) -> Option<AxisSnapshot> {
        self.axes.get(i).map(|a| AxisSnapshot {
            position: a.pos,
            reference: a.ref_pos,
            velocity: a.vel,
            motor_on: a.motor_on,
            stop_code: a.stop_code,
            tracking: matches!(a.profile, Profile::Tracking { .. }),
            output: a.output,
            offset: a.of,
            off_at: self.off_at[i].map(Duration::from_secs_f64),
            host_silent_at_off: self.silent_at_off[i].map(Duration::from_secs_f64),
        })
    }

    /// The servo period, seconds (`TM` × 1000/1024 µs).
    pub fn servo_period(&self) -> f64 {
        self.tm * 1e-6 * (1000.0 / 1024.0)
    }

    /// Runs the servo loop up to simulated time `now` (since the emulator's start).
    pub fn advance(&mut self, now: Duration) {
        let now = now.as_secs_f64();
        let dt = self.servo_period();
        if now - self.sim_time > MAX_CATCH_UP {
            self.sim_time = now - MAX_CATCH_UP;
        }
        while self.sim_time + dt <= now {
            self.run_threads();
            let t = self.sim_time + dt;
            let driven = self.arm.as_ref().map_or(0, arm::Arm::joints);
            for (i, a) in self.axes.iter_mut().enumerate() {
                if i < driven {
                    a.step_output(dt);
                } else {
                    a.step(dt);
                }
            }
            if let Some(arm) = &mut self.arm {
                let mut volts = [0.0; MAX_GALIL_AXES];
                let mut on = [false; MAX_GALIL_AXES];
                for ((v, o), a) in volts.iter_mut().zip(&mut on).zip(&self.axes) {
                    *v = a.output;
                    *o = a.motor_on;
                }
                arm.advance(t, &volts, &on);
            }
            self.sync_arm();
            self.sim_time = t;
            self.ticks += 1;
            self.sample = self.sample.wrapping_add(1);
            self.note_motors();
        }
    }

    /// Records amplifiers that went off since the last look.
    fn note_motors(&mut self) {
        for (i, a) in self.axes.iter().enumerate() {
            if self.was_on[i] && !a.motor_on {
                self.off_at[i] = Some(self.sim_time);
                self.silent_at_off[i] = self.last_command_at.map(|t| self.sim_time - t);
            }
            self.was_on[i] = a.motor_on;
        }
    }

    /// Queues an unsolicited message (as a board program's `MG` would print it); it comes out in
    /// the middle of the next text reply, or with [`Dmc::flush_unsolicited`].
    pub fn queue_unsolicited(&mut self, text: &[u8]) {
        self.pending_unsolicited.push_back(text.to_vec());
    }

    /// Writes every queued unsolicited message to `out` now (marked with bit 7 under `CW1`).
    pub fn flush_unsolicited(&mut self, out: &mut Vec<u8>) {
        while let Some(msg) = self.pending_unsolicited.pop_front() {
            self.write_unsolicited(&msg, out);
        }
    }

    /// True when no command is partly received (a good moment for unsolicited output).
    pub fn idle(&self) -> bool {
        self.line.is_empty()
    }

    fn write_unsolicited(&self, msg: &[u8], out: &mut Vec<u8>) {
        out.extend(msg.iter().map(|&b| if self.marked { b | 0x80 } else { b }));
    }

    /// Feeds received bytes at simulated time `now`; echo and replies are appended to `out`.
    pub fn input(&mut self, bytes: &[u8], now: Duration, out: &mut Vec<u8>) {
        self.advance(now);
        for &b in bytes {
            if self.download.is_some() {
                self.download_byte(b, out);
                continue;
            }
            if self.echo {
                out.push(b);
            }
            match b {
                b'\r' => {
                    self.end_part(out, true);
                    self.parts_in_line = 0;
                }
                b';' => self.end_part(out, false),
                b'\n' => {}
                _ => {
                    if self.line.len() >= MAX_LINE {
                        self.line_too_long = true;
                    } else {
                        self.line.push(b);
                    }
                }
            }
        }
    }

    fn end_part(&mut self, out: &mut Vec<u8>, end_of_line: bool) {
        let part = std::mem::take(&mut self.line);
        let too_long = std::mem::replace(&mut self.line_too_long, false);
        let text = String::from_utf8_lossy(&part);
        let text = text.trim();
        if text.is_empty() {
            if end_of_line && self.parts_in_line == 0 {
                out.push(b':');
            }
            return;
        }
        self.parts_in_line += 1;
        self.last_command_at = Some(self.sim_time);
        let start = out.len();
        let result = if too_long {
            Err(1)
        } else {
            self.execute(text, out)
        };
        self.note_motors();
        let binary = matches!(result, Ok(Reply::Binary));
        match result {
            Ok(Reply::Ack) => out.push(b':'),
            Ok(Reply::Text(t)) => {
                out.extend_from_slice(t.as_bytes());
                out.extend_from_slice(b"\r\n:");
            }
            Ok(Reply::Binary) => out.push(b':'),
            Ok(Reply::Later) => {}
            Err(code) => {
                self.error_code = code;
                out.push(b'?');
            }
        }
        // Unsolicited output interleaves with the reply text (never inside a binary record).
        if let Some(msg) = self.pending_unsolicited.pop_front() {
            let mut bytes = Vec::new();
            self.write_unsolicited(&msg, &mut bytes);
            let at = if binary || out.len() - start < 2 {
                out.len()
            } else {
                start + 1
            };
            out.splice(at..at, bytes);
        }
    }

    fn fmt_int(&self, v: f64) -> String {
        let r = v.round();
        let sign = if r < 0.0 { '-' } else { ' ' };
        let mag = r.abs() as u64;
        if self.lz0 {
            format!("{sign}{mag:010}")
        } else {
            format!("{sign}{mag}")
        }
    }

    fn fmt_dec(&self, v: f64) -> String {
        let scaled = (v * 10_000.0).round();
        let sign = if scaled < 0.0 { '-' } else { ' ' };
        let mag = scaled.abs() as u64;
        let (int, frac) = (mag / 10_000, mag % 10_000);
        if self.lz0 {
            format!("{sign}{int:010}.{frac:04}")
        } else {
            format!("{sign}{int}.{frac:04}")
        }
    }

    fn join(&self, values: impl Iterator<Item = f64>, integer: bool) -> String {
        let mut s = String::new();
        for (i, v) in values.enumerate() {
            if i > 0 {
                s.push(',');
            }
            s.push_str(&if integer {
                self.fmt_int(v)
            } else {
                self.fmt_dec(v)
            });
        }
        s
    }

    /// Axis indices named by letters (all axes when empty); code 1 for letters beyond the board.
    fn axes_arg(&self, rest: &str) -> Result<Vec<usize>, u16> {
        let rest = rest.trim();
        if rest.is_empty() {
            return Ok((0..self.axes.len()).collect());
        }
        let mut v = Vec::new();
        for c in rest.chars() {
            let i = AXIS_LETTERS.iter().position(|&l| l == c).ok_or(1u16)?;
            if i >= self.axes.len() {
                return Err(1);
            }
            if !v.contains(&i) {
                v.push(i);
            }
        }
        v.sort_unstable();
        Ok(v)
    }

    fn execute(&mut self, text: &str, out: &mut Vec<u8>) -> Result<Reply, u16> {
        if text.as_bytes() == [0x12, 0x16] {
            return Ok(Reply::Text(format!(
                "{} Rev {}",
                self.config.model, self.config.firmware
            )));
        }
        if let Some(reply) = self.assignment(text) {
            return reply;
        }
        let bytes = text.as_bytes();
        if bytes.len() < 2 || !bytes[0].is_ascii_uppercase() || !bytes[1].is_ascii_uppercase() {
            return Err(1);
        }
        let (mnemonic, rest) = text.split_at(2);
        let rest = rest.trim();
        match mnemonic {
            "DL" => self.begin_download(rest),
            "XQ" => self.execute_thread(rest).map(|()| Reply::Ack),
            "HX" => self.halt_threads(rest).map(|()| Reply::Ack),
            "EO" => {
                self.echo = flag(rest)?;
                Ok(Reply::Ack)
            }
            "CW" => self.data_adjustment(rest),
            "LZ" => {
                self.lz0 = !flag(rest)?;
                Ok(Reply::Ack)
            }
            "TC" => Ok(Reply::Text(self.tell_code(rest)?)),
            "TM" => self.sample_time(rest),
            "RS" => self.reset(rest),
            "QZ" => Ok(Reply::Text(format!(
                "{}, {}, {}, {}",
                self.layout.axes, self.layout.general, self.layout.coordinated, self.layout.axis
            ))),
            "QR" => self.data_record(out),
            "SH" | "MO" | "BG" | "ST" => self.axis_command(mnemonic, rest),
            "AB" => self.abort(rest),
            "TP" | "TE" | "TV" | "TT" | "TS" | "SC" => {
                let axes = self.axes_arg(rest)?;
                let values: Vec<f64> = axes.iter().map(|&i| self.operand(mnemonic, i)).collect();
                Ok(Reply::Text(self.join(values.into_iter(), mnemonic != "TT")))
            }
            "MG" => self.message(rest).map(Reply::Text),
            _ => match Setting::from_mnemonic(mnemonic) {
                Some(setting) => self.setting(setting, rest),
                None => Err(1),
            },
        }
    }

    /// `CW`: whether unsolicited bytes are marked (their high bit set), or `CW ?` to ask.
    fn data_adjustment(&mut self, rest: &str) -> Result<Reply, u16> {
        if rest == "?" {
            return Ok(Reply::Text(self.fmt_int(if self.marked {
                1.0
            } else {
                2.0
            })));
        }
        let first = rest.split(',').next().unwrap_or("").trim();
        match first {
            "1" => self.marked = true,
            "2" => self.marked = false,
            "" => {}
            _ => return Err(6),
        }
        Ok(Reply::Ack)
    }

    /// `TC`: the last error code (`TC 1`: with its text), cleared by asking.
    fn tell_code(&mut self, rest: &str) -> Result<String, u16> {
        let code = std::mem::take(&mut self.error_code);
        match rest {
            "" | "0" => Ok(code.to_string()),
            "1" => Ok(if code == 0 {
                "0".into()
            } else {
                format!("{code} {}", error_text(code))
            }),
            _ => Err(6),
        }
    }

    /// `TM`: the sample time, µs (250 to 20000), or `TM ?` to ask.
    fn sample_time(&mut self, rest: &str) -> Result<Reply, u16> {
        if rest == "?" {
            return Ok(Reply::Text(self.fmt_int(self.tm)));
        }
        let v = number(rest)?;
        if !(250.0..=20_000.0).contains(&v) {
            return Err(6);
        }
        self.tm = v.round();
        Ok(Reply::Ack)
    }

    /// `RS`: a reset controller: programs and variables gone, motors off; the clock, the arm and
    /// the record of motor-off instants carry on.
    fn reset(&mut self, rest: &str) -> Result<Reply, u16> {
        if !rest.is_empty() {
            return Err(1);
        }
        let keep = self.pending_unsolicited.clone();
        let arm = self.arm.take();
        let (time, ticks) = (self.sim_time, self.ticks);
        let (was_on, off_at, silent, last) = (
            self.was_on.clone(),
            self.off_at.clone(),
            self.silent_at_off.clone(),
            self.last_command_at,
        );
        *self = Dmc::new(self.config.clone());
        self.sim_time = time;
        self.ticks = ticks;
        self.pending_unsolicited = keep;
        self.was_on = was_on;
        self.off_at = off_at;
        self.silent_at_off = silent;
        self.last_command_at = last;
        if arm.is_some() {
            self.arm = arm;
            self.sync_arm();
        }
        self.note_motors();
        Ok(Reply::Ack)
    }

    /// `QR`: one binary data record of every axis, appended to `out`.
    fn data_record(&self, out: &mut Vec<u8>) -> Result<Reply, u16> {
        let recs: Vec<AxisRecord> = self.axes.iter().map(axis_record).collect();
        let mut buf = vec![0u8; self.layout.record_len()];
        let n =
            encode_record(&self.layout, 0x07, self.sample, &recs, &mut buf).map_err(|_| 1u16)?;
        out.extend_from_slice(&buf[..n]);
        Ok(Reply::Binary)
    }

    /// `SH`, `MO`, `BG`, `ST` on the axes named in `rest` (all when none): servo here, motor
    /// off, begin motion, stop. A `BG` refused on one axis still begins the others.
    fn axis_command(&mut self, mnemonic: &str, rest: &str) -> Result<Reply, u16> {
        let axes = self.axes_arg(rest)?;
        let mut result = Ok(());
        for i in axes {
            let a = &mut self.axes[i];
            match mnemonic {
                "SH" => a.servo_here(),
                "MO" => a.motor_off(),
                "ST" => a.stop(),
                _ => {
                    if let Err(code) = a.begin() {
                        result = Err(code);
                    }
                }
            }
        }
        result.map(|()| Reply::Ack)
    }

    /// `AB` (`AB 0`, `AB 1`): aborts the motion of every axis.
    fn abort(&mut self, rest: &str) -> Result<Reply, u16> {
        if !(rest.is_empty() || rest == "0" || rest == "1") {
            return Err(6);
        }
        for a in &mut self.axes {
            a.abort();
        }
        Ok(Reply::Ack)
    }

    fn operand(&self, name: &str, axis: usize) -> f64 {
        let a = &self.axes[axis];
        match name {
            "TP" => a.pos.round(),
            "TE" => (a.ref_pos - a.pos).round(),
            "TV" => a.vel.round(),
            "TT" => a.output,
            "TS" => f64::from(a.switches()),
            "SC" => f64::from(a.stop_code),
            "BG" => f64::from(u8::from(a.moving())),
            _ => 0.0,
        }
    }

    fn message(&self, rest: &str) -> Result<String, u16> {
        let mut parts = Vec::new();
        for arg in split_args(rest) {
            let arg = arg.trim();
            if let Some(s) = arg.strip_prefix('"') {
                parts.push(s.strip_suffix('"').ok_or(1u16)?.to_string());
            } else if let Some(op) = arg.strip_prefix('_') {
                if op.len() != 3 || !op.is_ascii() {
                    return Err(1);
                }
                let (name, letter) = op.split_at(2);
                let axis = AXIS_LETTERS
                    .iter()
                    .position(|l| letter.starts_with(*l))
                    .filter(|&i| i < self.axes.len())
                    .ok_or(1u16)?;
                if !["TP", "TE", "TV", "TT", "TS", "SC", "BG"].contains(&name) {
                    return Err(1);
                }
                parts.push(self.fmt_dec(self.operand(name, axis)));
            } else if arg == "TIME" {
                parts.push(self.fmt_dec(self.ticks as f64));
            } else if program::is_variable_name(arg) {
                let v = self.variables.get(arg).copied().ok_or(1u16)?;
                parts.push(self.fmt_dec(v));
            } else {
                parts.push(self.fmt_dec(number(arg)?));
            }
        }
        Ok(parts.concat())
    }

    fn setting(&mut self, setting: Setting, rest: &str) -> Result<Reply, u16> {
        let n = self.axes.len();
        // Named form: `PRA=1000`, `ACA=?`.
        if let Some((letter, value)) = rest.split_once('=') {
            let axis = AXIS_LETTERS
                .iter()
                .position(|&l| letter.trim() == l.to_string())
                .filter(|&i| i < n)
                .ok_or(1u16)?;
            let value = value.trim();
            if value == "?" {
                return Ok(Reply::Text(self.fmt_setting(setting, axis)));
            }
            self.axes[axis].set(setting, number(value)?)?;
            return Ok(Reply::Ack);
        }
        let fields: Vec<&str> = if rest.is_empty() {
            Vec::new()
        } else {
            rest.split(',').map(str::trim).collect()
        };
        if fields.len() > n {
            return Err(6);
        }
        if fields.contains(&"?") {
            let mut answers = Vec::new();
            for (i, f) in fields.iter().enumerate() {
                match *f {
                    "?" => answers.push(self.fmt_setting(setting, i)),
                    "" => {}
                    _ => return Err(1),
                }
            }
            return Ok(Reply::Text(answers.join(",")));
        }
        // Validate everything before changing anything.
        let mut values = Vec::with_capacity(fields.len());
        for f in &fields {
            values.push(if f.is_empty() { None } else { Some(number(f)?) });
        }
        let mut result = Ok(Reply::Ack);
        for (i, v) in values.into_iter().enumerate() {
            if let Some(v) = v
                && let Err(code) = self.axes[i].set(setting, v)
            {
                result = Err(code);
            }
        }
        result
    }

    fn fmt_setting(&self, setting: Setting, axis: usize) -> String {
        let v = self.axes[axis].get(setting);
        if setting.is_integer() {
            self.fmt_int(v)
        } else {
            self.fmt_dec(v)
        }
    }
}

enum Reply {
    Ack,
    Text(String),
    Binary,
    /// The reply comes later (`DL`: after the program text).
    Later,
}

fn flag(rest: &str) -> Result<bool, u16> {
    match rest {
        "0" => Ok(false),
        "1" => Ok(true),
        _ => Err(6),
    }
}

fn number(s: &str) -> Result<f64, u16> {
    super::number::parse_number(s.as_bytes()).map_err(|_| 1u16)
}

/// Splits `MG` arguments on commas outside quotes.
fn split_args(s: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut start = 0;
    let mut quoted = false;
    for (i, c) in s.char_indices() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => {
                out.push(&s[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&s[start..]);
    out
}

#[cfg(test)]
mod tests;
