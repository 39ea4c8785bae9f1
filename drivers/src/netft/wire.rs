//! The RDT (Raw Data Transfer) wire format of an ATI Net F/T: one 8-byte request, one 36-byte
//! record, both big-endian. Encoding and decoding never allocate and never panic on any input:
//! a datagram of the wrong size or with a wrong header is a [`RdtError`].
//!
//! ```
//! use penelope_drivers::netft::wire::{Command, Record, Request, Status};
//!
//! let start = Request::new(Command::StartRealtime, 0).encode();
//! assert_eq!(start, [0x12, 0x34, 0x00, 0x02, 0, 0, 0, 0]);
//! assert_eq!(Request::decode(&start), Ok(Request::new(Command::StartRealtime, 0)));
//!
//! let record = Record { rdt_sequence: 7, ft_sequence: 70, status: Status::HEALTHY, counts: [1, -2, 3, -4, 5, -6] };
//! assert_eq!(Record::decode(&record.encode()), Ok(record));
//! ```

use core::fmt;

/// The UDP port a Net F/T listens on for RDT requests.
pub const RDT_PORT: u16 = 49152;

/// The constant first field of every request.
pub const COMMAND_HEADER: u16 = 0x1234;

/// Bytes in a request.
pub const REQUEST_LEN: usize = 8;

/// Bytes in one RDT record.
pub const RECORD_LEN: usize = 36;

/// What a request asks the box to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// `0x0000`: stop streaming.
    Stop,
    /// `0x0002`: start high-speed real-time streaming (one record per datagram, at the box's
    /// RDT output rate).
    StartRealtime,
    /// `0x0003`: start high-speed buffered streaming (several records per datagram).
    StartBuffered,
    /// `0x0004`: start multi-unit streaming.
    StartMultiUnit,
    /// `0x0042`: take the present reading as the box's software bias (zero).
    SetSoftwareBias,
}

impl Command {
    /// The command's code on the wire.
    pub const fn code(self) -> u16 {
        match self {
            Command::Stop => 0x0000,
            Command::StartRealtime => 0x0002,
            Command::StartBuffered => 0x0003,
            Command::StartMultiUnit => 0x0004,
            Command::SetSoftwareBias => 0x0042,
        }
    }

    /// The command with code `code`, if it is one.
    pub const fn from_code(code: u16) -> Option<Command> {
        Some(match code {
            0x0000 => Command::Stop,
            0x0002 => Command::StartRealtime,
            0x0003 => Command::StartBuffered,
            0x0004 => Command::StartMultiUnit,
            0x0042 => Command::SetSoftwareBias,
            _ => return None,
        })
    }

    /// A short lower-case name, for logs.
    pub const fn as_str(self) -> &'static str {
        match self {
            Command::Stop => "stop",
            Command::StartRealtime => "start real-time streaming",
            Command::StartBuffered => "start buffered streaming",
            Command::StartMultiUnit => "start multi-unit streaming",
            Command::SetSoftwareBias => "set software bias",
        }
    }
}

/// One request datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Request {
    /// What to do.
    pub command: Command,
    /// Records to send before stopping (0: until told to stop). Ignored by non-streaming
    /// commands.
    pub sample_count: u32,
}

/// Why a datagram is not a request or a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RdtError {
    /// The datagram's length is not the message's (`expected` bytes).
    Length {
        /// Bytes received.
        got: usize,
        /// Bytes a message of this type has.
        expected: usize,
    },
    /// A request whose first field is not [`COMMAND_HEADER`].
    Header(u16),
    /// A request with a command code this protocol does not define.
    UnknownCommand(u16),
}

impl fmt::Display for RdtError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RdtError::Length { got, expected } => {
                write!(f, "datagram of {got} bytes, expected {expected}")
            }
            RdtError::Header(h) => write!(f, "request header {h:#06x}, expected 0x1234"),
            RdtError::UnknownCommand(c) => write!(f, "unknown RDT command {c:#06x}"),
        }
    }
}

impl std::error::Error for RdtError {}

fn be_u16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn be_u32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

impl Request {
    /// A request.
    pub const fn new(command: Command, sample_count: u32) -> Self {
        Request {
            command,
            sample_count,
        }
    }

    /// The 8 bytes on the wire: header, command, sample count.
    ///
    /// # Real-time
    /// No allocation, constant time.
    pub fn encode(&self) -> [u8; REQUEST_LEN] {
        let mut out = [0u8; REQUEST_LEN];
        out[0..2].copy_from_slice(&COMMAND_HEADER.to_be_bytes());
        out[2..4].copy_from_slice(&self.command.code().to_be_bytes());
        out[4..8].copy_from_slice(&self.sample_count.to_be_bytes());
        out
    }

    /// Decodes one request datagram (what the box, or its emulator, receives).
    ///
    /// # Errors
    /// [`RdtError::Length`] unless exactly 8 bytes, [`RdtError::Header`],
    /// [`RdtError::UnknownCommand`].
    pub fn decode(datagram: &[u8]) -> Result<Request, RdtError> {
        if datagram.len() != REQUEST_LEN {
            return Err(RdtError::Length {
                got: datagram.len(),
                expected: REQUEST_LEN,
            });
        }
        let header = be_u16(datagram, 0);
        if header != COMMAND_HEADER {
            return Err(RdtError::Header(header));
        }
        let code = be_u16(datagram, 2);
        let command = Command::from_code(code).ok_or(RdtError::UnknownCommand(code))?;
        Ok(Request {
            command,
            sample_count: be_u32(datagram, 4),
        })
    }
}

/// The status word of a record.
///
/// *NOTE*: the Net F/T manual defines 0 as healthy and bit 31 as "an error is present"; the
/// detail bits below follow ATI's published status-code table (bit 30: force/torque out of range
/// or saturated, bit 27: a gage out of range). Other detail bits are kept as received and
/// reported with the error.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Status(pub u32);

impl Status {
    /// Nothing wrong.
    pub const HEALTHY: Status = Status(0);
    /// Bit 31: an error is present.
    pub const ERROR: u32 = 1 << 31;
    /// Bit 30: a force or torque is out of range (saturated).
    pub const FT_OUT_OF_RANGE: u32 = 1 << 30;
    /// Bit 27: a strain gage reads out of its range.
    pub const GAGE_OUT_OF_RANGE: u32 = 1 << 27;

    /// Bit 31 is set.
    pub const fn is_error(self) -> bool {
        self.0 & Self::ERROR != 0
    }

    /// A saturation bit (force/torque or gage out of range) is set.
    pub const fn is_saturated(self) -> bool {
        self.0 & (Self::FT_OUT_OF_RANGE | Self::GAGE_OUT_OF_RANGE) != 0
    }
}

/// One RDT record: sequence numbers, status and the six channels in counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Record {
    /// The RDT sequence number: one per record sent, wrapping; a gap is a lost datagram.
    pub rdt_sequence: u32,
    /// The box's internal sample number (it samples faster than it sends).
    pub ft_sequence: u32,
    /// The status word.
    pub status: Status,
    /// Fx, Fy, Fz, Tx, Ty, Tz in counts (divide by counts per force / per torque).
    pub counts: [i32; 6],
}

impl Record {
    /// The 36 bytes on the wire.
    ///
    /// # Real-time
    /// No allocation, constant time.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        let mut out = [0u8; RECORD_LEN];
        out[0..4].copy_from_slice(&self.rdt_sequence.to_be_bytes());
        out[4..8].copy_from_slice(&self.ft_sequence.to_be_bytes());
        out[8..12].copy_from_slice(&self.status.0.to_be_bytes());
        for (i, c) in self.counts.iter().enumerate() {
            out[12 + 4 * i..16 + 4 * i].copy_from_slice(&c.to_be_bytes());
        }
        out
    }

    /// Decodes one record datagram (real-time streaming sends exactly one per datagram).
    ///
    /// # Errors
    /// [`RdtError::Length`] unless exactly 36 bytes.
    ///
    /// # Real-time
    /// No allocation, constant time.
    pub fn decode(datagram: &[u8]) -> Result<Record, RdtError> {
        if datagram.len() != RECORD_LEN {
            return Err(RdtError::Length {
                got: datagram.len(),
                expected: RECORD_LEN,
            });
        }
        let mut counts = [0i32; 6];
        for (i, c) in counts.iter_mut().enumerate() {
            *c = be_u32(datagram, 12 + 4 * i) as i32;
        }
        Ok(Record {
            rdt_sequence: be_u32(datagram, 0),
            ft_sequence: be_u32(datagram, 4),
            status: Status(be_u32(datagram, 8)),
            counts,
        })
    }
}

/// The box's calibration: counts per unit of force and of torque (`cfgcpf`, `cfgcpt` in its
/// `/netftapi2.xml`), with the units they give (configured as newtons and newton-metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// Counts per newton.
    pub counts_per_force: f64,
    /// Counts per newton-metre.
    pub counts_per_torque: f64,
}

impl Default for Calibration {
    /// 1 000 000 counts per N and per N·m, the Net F/T's usual setting.
    fn default() -> Self {
        Calibration {
            counts_per_force: 1_000_000.0,
            counts_per_torque: 1_000_000.0,
        }
    }
}

impl Calibration {
    /// Counts to forces (N) and torques (N·m): `[Fx, Fy, Fz, Tx, Ty, Tz]`.
    pub fn to_si(&self, counts: &[i32; 6]) -> [f64; 6] {
        let mut out = [0.0; 6];
        for (i, (o, c)) in out.iter_mut().zip(counts).enumerate() {
            let per = if i < 3 {
                self.counts_per_force
            } else {
                self.counts_per_torque
            };
            *o = f64::from(*c) / per;
        }
        out
    }

    /// Forces and torques to counts, rounded and held at the `i32` range (the emulator's side).
    pub fn to_counts(&self, si: &[f64; 6]) -> [i32; 6] {
        let mut out = [0i32; 6];
        for (i, (o, v)) in out.iter_mut().zip(si).enumerate() {
            let per = if i < 3 {
                self.counts_per_force
            } else {
                self.counts_per_torque
            };
            let c = (v * per).round();
            *o = if c.is_nan() {
                0
            } else {
                c.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
            };
        }
        out
    }

    /// Both values finite and positive.
    pub fn is_valid(&self) -> bool {
        [self.counts_per_force, self.counts_per_torque]
            .iter()
            .all(|v| v.is_finite() && *v > 0.0)
    }
}

/// Records lost between `previous` and `next` RDT sequence numbers (wrapping): 0 for the next
/// one in order; a repeated or older number counts as no loss (it is reported as out of order
/// by the caller).
pub fn records_missed(previous: u32, next: u32) -> u32 {
    let step = next.wrapping_sub(previous);
    if step == 0 || step > u32::MAX / 2 {
        0
    } else {
        step - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_command_encodes_to_its_bytes_and_back() {
        let cases = [
            (Command::Stop, [0x12, 0x34, 0x00, 0x00, 0, 0, 0, 0]),
            (Command::StartRealtime, [0x12, 0x34, 0x00, 0x02, 0, 0, 0, 0]),
            (Command::StartBuffered, [0x12, 0x34, 0x00, 0x03, 0, 0, 0, 0]),
            (
                Command::StartMultiUnit,
                [0x12, 0x34, 0x00, 0x04, 0, 0, 0, 0],
            ),
            (
                Command::SetSoftwareBias,
                [0x12, 0x34, 0x00, 0x42, 0, 0, 0, 0],
            ),
        ];
        for (command, bytes) in cases {
            let r = Request::new(command, 0);
            assert_eq!(r.encode(), bytes, "{command:?}");
            assert_eq!(Request::decode(&bytes), Ok(r));
        }
        let counted = Request::new(Command::StartRealtime, 0x0102_0304).encode();
        assert_eq!(&counted[4..], &[1, 2, 3, 4]);
    }

    #[test]
    fn a_record_is_big_endian_in_its_documented_order() {
        let r = Record {
            rdt_sequence: 0x0102_0304,
            ft_sequence: 0x0a0b_0c0d,
            status: Status(0x8000_0001),
            counts: [1, -1, 256, i32::MIN, i32::MAX, 0],
        };
        let b = r.encode();
        assert_eq!(&b[0..4], &[1, 2, 3, 4]);
        assert_eq!(&b[4..8], &[0x0a, 0x0b, 0x0c, 0x0d]);
        assert_eq!(&b[8..12], &[0x80, 0, 0, 1]);
        assert_eq!(&b[12..16], &[0, 0, 0, 1]);
        assert_eq!(&b[16..20], &[0xff, 0xff, 0xff, 0xff]);
        assert_eq!(&b[20..24], &[0, 0, 1, 0]);
        assert_eq!(&b[24..28], &[0x80, 0, 0, 0]);
        assert_eq!(Record::decode(&b), Ok(r));
    }

    #[test]
    fn short_long_and_garbage_datagrams_are_typed_errors() {
        for n in [0usize, 1, 7, 9, 35, 37, 72] {
            let junk = vec![0xa5u8; n];
            if n != RECORD_LEN {
                assert_eq!(
                    Record::decode(&junk),
                    Err(RdtError::Length {
                        got: n,
                        expected: RECORD_LEN
                    })
                );
            }
            if n != REQUEST_LEN {
                assert!(matches!(
                    Request::decode(&junk),
                    Err(RdtError::Length { .. })
                ));
            }
        }
        assert_eq!(
            Request::decode(&[0xde, 0xad, 0, 2, 0, 0, 0, 0]),
            Err(RdtError::Header(0xdead))
        );
        assert_eq!(
            Request::decode(&[0x12, 0x34, 0, 7, 0, 0, 0, 0]),
            Err(RdtError::UnknownCommand(7))
        );
    }

    #[test]
    fn calibration_scales_forces_and_torques_separately() {
        let c = Calibration {
            counts_per_force: 1_000_000.0,
            counts_per_torque: 500.0,
        };
        let si = c.to_si(&[2_500_000, 0, -1_000_000, 500, -250, 0]);
        assert_eq!(si, [2.5, 0.0, -1.0, 1.0, -0.5, 0.0]);
        assert_eq!(c.to_counts(&si), [2_500_000, 0, -1_000_000, 500, -250, 0]);
        assert_eq!(
            c.to_counts(&[1e9, f64::NAN, 0.0, 0.0, 0.0, 0.0])[..2],
            [i32::MAX, 0]
        );
        assert!(
            !Calibration {
                counts_per_force: 0.0,
                counts_per_torque: 1.0
            }
            .is_valid()
        );
    }

    #[test]
    fn status_bits_and_sequence_gaps() {
        assert!(!Status::HEALTHY.is_error());
        assert!(Status(0x8000_0000).is_error());
        assert!(Status(0xC000_0000).is_saturated());
        assert!(Status(0x8800_0000).is_saturated());
        assert!(!Status(0x8000_0004).is_saturated());
        assert_eq!(records_missed(10, 11), 0);
        assert_eq!(records_missed(10, 14), 3);
        assert_eq!(records_missed(u32::MAX, 1), 1);
        assert_eq!(records_missed(10, 10), 0);
        assert_eq!(records_missed(10, 9), 0);
    }
}
