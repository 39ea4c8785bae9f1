//! Typed Galil commands and their encoding into one command line.
//!
//! Every command the servo driver needs (reference: "Commands a servo driver needs") has a
//! variant here; [`Command::encode`] writes it in Galil's syntax into a [`Line`] of at most
//! [`MAX_LINE`] characters, refusing non-finite numbers and characters that would end the line.
//!
//! # Real-time
//! Encoding allocates nothing and runs in bounded time.

use core::fmt::Write;

use super::error::GalilError;

/// Galil's limit on a command line, characters (the terminating carriage return excluded).
pub const MAX_LINE: usize = 80;

/// The largest number of axes on one controller (A..H).
pub const MAX_GALIL_AXES: usize = 8;

/// One command line, without its terminating carriage return.
pub type Line = heapless::String<MAX_LINE>;

/// The axis letters, in order.
pub const AXIS_LETTERS: [char; MAX_GALIL_AXES] = ['A', 'B', 'C', 'D', 'E', 'F', 'G', 'H'];

/// A set of axes (bit 0 = A ... bit 7 = H).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Axes(pub u8);

impl Axes {
    /// No axis; as a command argument it means "every axis" (Galil's default).
    pub const NONE: Axes = Axes(0);

    /// The first `n` axes (A, AB, ABC, ...); `n` is capped at 8.
    pub const fn first(n: usize) -> Axes {
        if n >= MAX_GALIL_AXES {
            Axes(0xFF)
        } else {
            Axes(((1u16 << n) - 1) as u8)
        }
    }

    /// One axis by index (0 = A); `None` beyond H.
    pub const fn single(index: usize) -> Option<Axes> {
        if index < MAX_GALIL_AXES {
            Some(Axes(1 << index))
        } else {
            None
        }
    }

    /// True when axis `index` (0 = A) is in the set.
    pub const fn contains(self, index: usize) -> bool {
        index < MAX_GALIL_AXES && self.0 & (1 << index) != 0
    }

    /// How many axes the set holds.
    pub const fn count(self) -> usize {
        self.0.count_ones() as usize
    }

    /// True for the empty set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The axis indices in the set, in order.
    pub fn indices(self) -> impl Iterator<Item = usize> {
        (0..MAX_GALIL_AXES).filter(move |&i| self.contains(i))
    }

    /// Parses letters such as `"ABC"` (case-insensitive); `None` for any other character.
    pub fn parse(letters: &str) -> Option<Axes> {
        let mut mask = 0u8;
        for c in letters.chars() {
            let i = AXIS_LETTERS
                .iter()
                .position(|&l| l == c.to_ascii_uppercase())?;
            mask |= 1 << i;
        }
        Some(Axes(mask))
    }
}

/// How the board should tell its own unsolicited output (program `MG`s, `#CMDERR`) apart from
/// replies (`CW`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum UnsolicitedMode {
    /// `CW1`: the board sets bit 7 on every unsolicited byte; the client separates the streams
    /// exactly. The recommended mode.
    #[default]
    Marked,
    /// `CW2` (the board's default): unsolicited bytes look like replies. *Hazard*: an unsolicited
    /// line that holds `:` or `?` ends a reply early and every later reply is off by one until the
    /// client resynchronises. Use only when no program on the board prints anything.
    Unmarked,
}

/// A report command (`T?`/`SC`) that answers one value per axis without `?`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Tell {
    /// `TP`: motor position, counts.
    Position,
    /// `TE`: position error, counts.
    Error,
    /// `TV`: filtered velocity, counts/s.
    Velocity,
    /// `TT`: torque (the output command), volts.
    Torque,
    /// `TS`: switches and status bits (bit 5 motor off, bits 3/2 forward/reverse limit).
    Switches,
    /// `SC`: stop code (0 running, 1 at commanded position, 4 by `ST`, 7 by `AB`, 8 off on error).
    StopCode,
}

impl Tell {
    /// The two-letter mnemonic.
    pub const fn mnemonic(self) -> &'static str {
        match self {
            Tell::Position => "TP",
            Tell::Error => "TE",
            Tell::Velocity => "TV",
            Tell::Torque => "TT",
            Tell::Switches => "TS",
            Tell::StopCode => "SC",
        }
    }
}

/// A per-axis setting, written positionally (`PA 1000,,500`) and queried with `?`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Setting {
    /// `PR`: relative move distance, counts.
    PositionRelative,
    /// `PA`: absolute target, counts (in position-tracking mode the axis follows at once).
    PositionAbsolute,
    /// `SP`: slew speed, counts/s.
    Speed,
    /// `AC`: acceleration, counts/s² (the board rounds down to a multiple of 1024).
    Acceleration,
    /// `DC`: deceleration, counts/s² (rounded down to a multiple of 1024).
    Deceleration,
    /// `JG`: jog speed, counts/s (signed).
    Jog,
    /// `KP`: proportional gain.
    Kp,
    /// `KI`: integral gain.
    Ki,
    /// `KD`: derivative gain.
    Kd,
    /// `OF`: output offset, volts (with zero gains: a direct torque command).
    Offset,
    /// `TL`: torque limit, volts.
    TorqueLimit,
    /// `ER`: error limit, counts.
    ErrorLimit,
    /// `OE`: off-on-error mode, 0..3.
    OffOnError,
    /// `PT`: position tracking mode, 0 or 1.
    PositionTracking,
}

impl Setting {
    /// Every setting, for tables and tests.
    pub const ALL: [Setting; 14] = [
        Setting::PositionRelative,
        Setting::PositionAbsolute,
        Setting::Speed,
        Setting::Acceleration,
        Setting::Deceleration,
        Setting::Jog,
        Setting::Kp,
        Setting::Ki,
        Setting::Kd,
        Setting::Offset,
        Setting::TorqueLimit,
        Setting::ErrorLimit,
        Setting::OffOnError,
        Setting::PositionTracking,
    ];

    /// The two-letter mnemonic.
    pub const fn mnemonic(self) -> &'static str {
        match self {
            Setting::PositionRelative => "PR",
            Setting::PositionAbsolute => "PA",
            Setting::Speed => "SP",
            Setting::Acceleration => "AC",
            Setting::Deceleration => "DC",
            Setting::Jog => "JG",
            Setting::Kp => "KP",
            Setting::Ki => "KI",
            Setting::Kd => "KD",
            Setting::Offset => "OF",
            Setting::TorqueLimit => "TL",
            Setting::ErrorLimit => "ER",
            Setting::OffOnError => "OE",
            Setting::PositionTracking => "PT",
        }
    }

    /// The setting for a mnemonic (upper case), if it is one of these.
    pub fn from_mnemonic(m: &str) -> Option<Setting> {
        Setting::ALL.into_iter().find(|s| s.mnemonic() == m)
    }

    /// True when the value is a whole number (counts, modes); false for gains and volts.
    pub const fn is_integer(self) -> bool {
        !matches!(
            self,
            Setting::Kp | Setting::Ki | Setting::Kd | Setting::Offset | Setting::TorqueLimit
        )
    }
}

/// An operand `MG` can print, per axis (`MG _TPA`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Operand {
    /// `_TP`: position, counts.
    Position,
    /// `_TE`: position error, counts.
    Error,
    /// `_TV`: velocity, counts/s.
    Velocity,
    /// `_TT`: torque, volts.
    Torque,
    /// `_TS`: switches.
    Switches,
    /// `_SC`: stop code.
    StopCode,
    /// `_BG`: 1 while the axis is moving.
    Moving,
}

impl Operand {
    /// The operand without its axis letter (`_TP`).
    pub const fn mnemonic(self) -> &'static str {
        match self {
            Operand::Position => "_TP",
            Operand::Error => "_TE",
            Operand::Velocity => "_TV",
            Operand::Torque => "_TT",
            Operand::Switches => "_TS",
            Operand::StopCode => "_SC",
            Operand::Moving => "_BG",
        }
    }
}

/// What kind of reply a command gets when accepted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ReplyKind {
    /// A lone `:`.
    Ack,
    /// Text, then `:`.
    Data,
    /// A binary data record, then `:`.
    Record,
}

/// A typed Galil command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command<'a> {
    /// `^R^V`: model and firmware.
    Identify,
    /// `EO0`/`EO1`: echo of received characters.
    Echo(bool),
    /// `CW1`/`CW2`: marking of unsolicited bytes.
    Unsolicited(UnsolicitedMode),
    /// `LZ0`/`LZ1`: `true` keeps leading zeros (`LZ0`), `false` drops them (`LZ1`).
    LeadingZeros(bool),
    /// `TC1`: the last error's code and text (reading clears it).
    TellCode,
    /// `SH`: servo here (amplifiers on, hold the current position).
    ServoHere(Axes),
    /// `MO`: motor off.
    MotorOff(Axes),
    /// `BG`: begin motion.
    Begin(Axes),
    /// `ST`: decelerated stop.
    Stop(Axes),
    /// `AB`, or `AB 1` (motion only, programs keep running) when `motion_only`.
    Abort {
        /// Abort motion only (`AB 1`).
        motion_only: bool,
    },
    /// A report (`TP`, `TE`, `TV`, `TT`, `TS`, `SC`) for some axes (all when empty).
    Tell(Tell, Axes),
    /// Writes a setting positionally; `None` leaves that axis unchanged (`PA 1000,,500`).
    Set(Setting, &'a [Option<f64>]),
    /// Queries a setting for the first `n` axes (`KP ?,?,?`).
    Query(Setting, usize),
    /// `TM n`: servo period, about 0.9766 µs per unit (`TM 1000` gives 976 µs).
    SetServoPeriod(u32),
    /// `TM ?`: the servo period setting.
    QueryServoPeriod,
    /// `RS`: reset (re-initialise afterwards). The master reset `^R^S` is never sent.
    Reset,
    /// `MG _XXa`: prints one operand of one axis (index 0 = A), with four decimals.
    Message(Operand, usize),
    /// `MG "text"`: prints the text back (used to resynchronise; `"` is refused).
    Echoed(&'a str),
    /// `QZ`: the data record layout.
    RecordLayout,
    /// `QR`: one binary data record.
    Record,
    /// Any other command text, sent as is (one command: `;`, CR and LF are refused).
    Raw(&'a str),
    /// `name=value`: sets a program variable (a letter, then up to seven letters or digits; a
    /// name starting with two capitals would read as a command and is refused).
    Assign(&'a str, f64),
    /// `XQ #LABEL,t`: runs the downloaded program from `label` (without `#`) in thread `t`
    /// (0..=7).
    Execute(&'a str, u8),
    /// `HX t` (one thread) or `HX` (all): halts programs.
    Halt(Option<u8>),
}

impl Command<'_> {
    /// What an accepted reply to this command holds.
    pub fn reply_kind(&self) -> ReplyKind {
        match self {
            Command::Identify
            | Command::TellCode
            | Command::Tell(..)
            | Command::Query(..)
            | Command::QueryServoPeriod
            | Command::Message(..)
            | Command::Echoed(_)
            | Command::RecordLayout => ReplyKind::Data,
            Command::Record => ReplyKind::Record,
            Command::Raw(_) => ReplyKind::Data,
            _ => ReplyKind::Ack,
        }
    }

    /// True for commands that may take seconds (reset).
    pub fn is_slow(&self) -> bool {
        matches!(self, Command::Reset)
    }

    /// Writes the command (without its terminating carriage return) into `line`, after what is
    /// already there.
    ///
    /// # Errors
    /// [`GalilError::LineTooLong`] beyond [`MAX_LINE`] characters; [`GalilError::InvalidArgument`]
    /// for a non-finite number, an axis beyond H, or text holding `;`, `"`, CR, LF or non-ASCII.
    pub fn encode(&self, line: &mut Line) -> Result<(), GalilError> {
        match *self {
            Command::Identify => line.push_str("\u{12}\u{16}").map_err(too_long),
            Command::Echo(on) => write!(line, "EO{}", u8::from(on)).map_err(too_long),
            Command::Unsolicited(mode) => {
                let n = match mode {
                    UnsolicitedMode::Marked => 1,
                    UnsolicitedMode::Unmarked => 2,
                };
                write!(line, "CW{n}").map_err(too_long)
            }
            Command::LeadingZeros(keep) => {
                write!(line, "LZ{}", if keep { 0 } else { 1 }).map_err(too_long)
            }
            Command::TellCode => line.push_str("TC1").map_err(too_long),
            Command::ServoHere(axes) => with_axes(line, "SH", axes),
            Command::MotorOff(axes) => with_axes(line, "MO", axes),
            Command::Begin(axes) => with_axes(line, "BG", axes),
            Command::Stop(axes) => with_axes(line, "ST", axes),
            Command::Abort { motion_only } => line
                .push_str(if motion_only { "AB 1" } else { "AB" })
                .map_err(too_long),
            Command::Tell(tell, axes) => with_axes(line, tell.mnemonic(), axes),
            Command::Set(setting, values) => encode_set(line, setting, values),
            Command::Query(setting, n) => encode_query(line, setting, n),
            Command::SetServoPeriod(n) => write!(line, "TM {n}").map_err(too_long),
            Command::QueryServoPeriod => line.push_str("TM ?").map_err(too_long),
            Command::Reset => line.push_str("RS").map_err(too_long),
            Command::Message(operand, axis) => {
                let letter = AXIS_LETTERS
                    .get(axis)
                    .ok_or(GalilError::InvalidArgument("axis beyond H"))?;
                write!(line, "MG {}{letter}", operand.mnemonic()).map_err(too_long)
            }
            Command::Echoed(text) => {
                check_text(text)?;
                if text.contains('"') {
                    return Err(GalilError::InvalidArgument("quote in MG text"));
                }
                write!(line, "MG \"{text}\"").map_err(too_long)
            }
            Command::RecordLayout => line.push_str("QZ").map_err(too_long),
            Command::Record => line.push_str("QR").map_err(too_long),
            Command::Raw(text) => {
                check_text(text)?;
                if text.contains(';') {
                    return Err(GalilError::InvalidArgument("';' in a single command"));
                }
                line.push_str(text).map_err(too_long)
            }
            Command::Assign(name, value) => {
                if !is_name(name, 8) || name.bytes().take(2).all(|b| b.is_ascii_uppercase()) {
                    return Err(GalilError::InvalidArgument("not a variable name"));
                }
                line.push_str(name).map_err(too_long)?;
                line.push('=').map_err(too_long)?;
                write_number(line, value, false)
            }
            Command::Execute(label, thread) => {
                if !is_name(label, 7) || label.bytes().any(|b| b.is_ascii_lowercase()) {
                    return Err(GalilError::InvalidArgument("not a label"));
                }
                if thread > 7 {
                    return Err(GalilError::InvalidArgument("thread out of 0..=7"));
                }
                write!(line, "XQ #{label},{thread}").map_err(too_long)
            }
            Command::Halt(None) => line.push_str("HX").map_err(too_long),
            Command::Halt(Some(thread)) => {
                if thread > 7 {
                    return Err(GalilError::InvalidArgument("thread out of 0..=7"));
                }
                write!(line, "HX {thread}").map_err(too_long)
            }
        }
    }
}

/// `setting` for each axis with a value; axes without one left unchanged (empty between
/// commas, trailing ones left off).
fn encode_set(line: &mut Line, setting: Setting, values: &[Option<f64>]) -> Result<(), GalilError> {
    if values.len() > MAX_GALIL_AXES {
        return Err(GalilError::InvalidArgument("more values than axes"));
    }
    line.push_str(setting.mnemonic()).map_err(too_long)?;
    line.push(' ').map_err(too_long)?;
    // Trailing unchanged axes are simply left off.
    let last = values
        .iter()
        .rposition(Option::is_some)
        .map_or(0, |i| i + 1);
    for (i, v) in values[..last].iter().enumerate() {
        if i > 0 {
            line.push(',').map_err(too_long)?;
        }
        if let Some(v) = v {
            write_number(line, *v, setting.is_integer())?;
        }
    }
    Ok(())
}

/// A query of `setting` on the first `n` axes.
fn encode_query(line: &mut Line, setting: Setting, n: usize) -> Result<(), GalilError> {
    if n == 0 || n > MAX_GALIL_AXES {
        return Err(GalilError::InvalidArgument("axis count out of 1..=8"));
    }
    line.push_str(setting.mnemonic()).map_err(too_long)?;
    line.push_str(" ?").map_err(too_long)?;
    for _ in 1..n {
        line.push_str(",?").map_err(too_long)?;
    }
    Ok(())
}

/// Encodes several commands into one line separated by `;` (each gets its own `:` or `?`).
///
/// # Errors
/// As [`Command::encode`].
pub fn encode_line(commands: &[Command<'_>]) -> Result<Line, GalilError> {
    let mut line = Line::new();
    for (i, c) in commands.iter().enumerate() {
        if i > 0 {
            line.push(';').map_err(|_| GalilError::LineTooLong)?;
        }
        c.encode(&mut line)?;
    }
    Ok(line)
}

/// Maps any capacity or formatting error onto [`GalilError::LineTooLong`].
fn too_long<E>(_: E) -> GalilError {
    GalilError::LineTooLong
}

/// A letter, then letters or digits, at most `max` characters.
fn is_name(s: &str, max: usize) -> bool {
    let b = s.as_bytes();
    !b.is_empty()
        && b.len() <= max
        && b[0].is_ascii_alphabetic()
        && b.iter().all(u8::is_ascii_alphanumeric)
}

fn check_text(text: &str) -> Result<(), GalilError> {
    if text
        .bytes()
        .any(|b| b == b'\r' || b == b'\n' || !b.is_ascii())
    {
        Err(GalilError::InvalidArgument(
            "CR, LF or non-ASCII in command text",
        ))
    } else {
        Ok(())
    }
}

fn with_axes(line: &mut Line, mnemonic: &str, axes: Axes) -> Result<(), GalilError> {
    line.push_str(mnemonic)
        .map_err(|_| GalilError::LineTooLong)?;
    if !axes.is_empty() {
        line.push(' ').map_err(|_| GalilError::LineTooLong)?;
        for i in axes.indices() {
            line.push(AXIS_LETTERS[i])
                .map_err(|_| GalilError::LineTooLong)?;
        }
    }
    Ok(())
}

/// Writes a number as Galil reads it: an integer, or at most four decimals with trailing zeros
/// dropped.
fn write_number(line: &mut Line, v: f64, integer: bool) -> Result<(), GalilError> {
    if !v.is_finite() {
        return Err(GalilError::InvalidArgument("non-finite number"));
    }
    if v.abs() >= 2_147_483_648.0 {
        return Err(GalilError::InvalidArgument(
            "number beyond Galil's 32-bit range",
        ));
    }
    if integer {
        let n = super::number::to_counts(v)
            .map_err(|_| GalilError::InvalidArgument("number beyond Galil's 32-bit range"))?;
        return write!(line, "{n}").map_err(too_long);
    }
    // Fixed point with four decimals, computed in integers so no float formatting quirks reach
    // the wire.
    // |v| < 2^31 was checked, so the scaled value fits an i64 exactly.
    let r = v * 10_000.0;
    let scaled = if r >= 0.0 {
        (r + 0.5) as i64
    } else {
        -((-r + 0.5) as i64)
    };
    let sign = if scaled < 0 { "-" } else { "" };
    let abs = scaled.unsigned_abs();
    let (int, mut frac) = (abs / 10_000, abs % 10_000);
    if frac == 0 {
        return write!(line, "{sign}{int}").map_err(too_long);
    }
    let mut digits = 4;
    while frac % 10 == 0 {
        frac /= 10;
        digits -= 1;
    }
    write!(line, "{sign}{int}.{frac:0digits$}").map_err(too_long)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn enc(c: Command<'_>) -> Result<Line, GalilError> {
        encode_line(&[c])
    }

    #[test]
    fn galil_syntax() {
        assert_eq!(enc(Command::ServoHere(Axes::first(3))).unwrap(), "SH ABC");
        assert_eq!(enc(Command::ServoHere(Axes::NONE)).unwrap(), "SH");
        assert_eq!(
            enc(Command::Tell(Tell::Position, Axes::NONE)).unwrap(),
            "TP"
        );
        assert_eq!(
            enc(Command::Set(
                Setting::PositionAbsolute,
                &[Some(1000.0), None, Some(-500.4), None]
            ))
            .unwrap(),
            "PA 1000,,-500"
        );
        assert_eq!(
            enc(Command::Set(
                Setting::Kp,
                &[Some(6.0), Some(0.25), Some(-1.00005)]
            ))
            .unwrap(),
            "KP 6,0.25,-1.0001"
        );
        assert_eq!(enc(Command::Query(Setting::Kd, 3)).unwrap(), "KD ?,?,?");
        assert_eq!(
            enc(Command::Message(Operand::Moving, 0)).unwrap(),
            "MG _BGA"
        );
        assert_eq!(enc(Command::Identify).unwrap().as_bytes(), &[0x12, 0x16]);
        assert_eq!(enc(Command::LeadingZeros(false)).unwrap(), "LZ1");
        assert_eq!(
            enc(Command::Unsolicited(UnsolicitedMode::Marked)).unwrap(),
            "CW1"
        );
        assert_eq!(enc(Command::Abort { motion_only: true }).unwrap(), "AB 1");
        assert_eq!(
            encode_line(&[
                Command::Set(Setting::PositionAbsolute, &[Some(1.0); 6]),
                Command::Tell(Tell::Position, Axes::NONE)
            ])
            .unwrap(),
            "PA 1,1,1,1,1,1;TP"
        );
    }

    #[test]
    fn bad_arguments_are_typed_errors() {
        assert_eq!(
            enc(Command::Set(Setting::Offset, &[Some(f64::NAN)])),
            Err(GalilError::InvalidArgument("non-finite number"))
        );
        assert!(enc(Command::Set(Setting::PositionAbsolute, &[Some(1e10)])).is_err());
        assert!(enc(Command::Raw("TP;TE")).is_err());
        assert_eq!(enc(Command::Assign("hbeat", 12.0)).unwrap(), "hbeat=12");
        assert!(enc(Command::Assign("KPA", 1.0)).is_err());
        assert!(enc(Command::Assign("toolongname", 1.0)).is_err());
        assert_eq!(enc(Command::Execute("PNWDOG", 7)).unwrap(), "XQ #PNWDOG,7");
        assert!(enc(Command::Execute("wd", 1)).is_err());
        assert!(enc(Command::Execute("WD", 8)).is_err());
        assert_eq!(enc(Command::Halt(Some(7))).unwrap(), "HX 7");
        assert_eq!(enc(Command::Halt(None)).unwrap(), "HX");
        assert!(enc(Command::Raw("TP\r")).is_err());
        assert!(enc(Command::Echoed("a\"b")).is_err());
        assert!(enc(Command::Message(Operand::Position, 8)).is_err());
        let long = "X".repeat(81);
        assert_eq!(enc(Command::Raw(&long)), Err(GalilError::LineTooLong));
        assert!(enc(Command::Set(Setting::Kp, &[Some(1.0); 9])).is_err());
    }

    #[test]
    fn axes_sets() {
        assert_eq!(Axes::first(6).count(), 6);
        assert_eq!(Axes::first(8), Axes(0xFF));
        assert_eq!(Axes::parse("acb"), Some(Axes(0b111)));
        assert_eq!(Axes::parse("AZ"), None);
        assert_eq!(Axes::single(8), None);
        assert_eq!(Axes(0b101).indices().collect::<Vec<_>>(), vec![0, 2]);
    }
}
