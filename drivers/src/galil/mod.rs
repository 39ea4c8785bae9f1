//! The Galil DMC motion controller over a serial line.
//!
//! # Layers
//!
//! - [`command`]: typed commands ([`Command`], [`Axes`], [`Setting`], [`Tell`]) and their
//!   encoding into one line of at most 80 characters.
//! - [`framing`]: the incremental reply parser ([`Framer`]): replies end with `:` or `?` across
//!   arbitrarily split reads; `CW1`-marked unsolicited bytes are separated; binary records are
//!   read by length.
//! - [`number`]: tolerant number parsing (leading spaces, `LZ0` zeros, integers or decimals).
//! - [`record`]: the `QZ` layout and `QR` data record decoder.
//! - [`link`]: byte links ([`Link`]): a serial port ([`SerialLink`], real line or
//!   pseudo-terminal) or a TCP socket ([`TcpLink`]); [`mock`] has a scripted one for tests.
//! - [`client`]: the protocol client ([`Client`]): one request in flight, `TC1` after every `?`,
//!   timeouts with resynchronisation, initialisation, identification.
//! - [`emulator`]: a DMC-40x0 emulator ([`emulator::Dmc`]: commands, programs and threads, an
//!   optional robot arm behind the axes) and its pseudo-terminal runner
//!   ([`emulator::PtyEmulator`]), for users without hardware and for end-to-end tests.
//! - [`board`]: [`GalilBoard`], the `hal::Board` over all of this, with its serial I/O in its own
//!   thread, a board-side watchdog ([`board::watchdog`]), amplifiers off on every fault and on
//!   release, and torque directions from the robot model ([`GalilBoard::orient`]).
//!
//! # Example
//!
//! ```no_run
//! use penelope_drivers::galil::{Client, ClientConfig, SerialLink, SerialSettings, Tell, Axes};
//!
//! let link = SerialLink::open(&SerialSettings::new("/dev/ttyUSB0", 115_200))?;
//! let mut client = Client::new(link, ClientConfig::default());
//! let info = client.initialize()?;
//! println!("{} firmware {} with {} axes", info.identity.model, info.identity.firmware, info.layout.axes);
//! let positions = client.tell(Tell::Position, Axes::NONE)?;
//! # Ok::<(), penelope_drivers::galil::GalilError>(())
//! ```

pub mod board;
pub mod client;
pub mod command;
pub mod emulator;
pub mod error;
pub mod framing;
pub mod link;
pub mod mock;
pub mod number;
pub mod record;

pub use board::{
    BoardFault, DEFAULT_COMMAND_TIMEOUT, DEFAULT_WATCHDOG, GalilBoard, GalilBoardConfig,
    GalilBoardError, TargetMode, axis_bindings,
};
pub use client::{AxisValues, BoardInfo, Client, ClientConfig, Identity, Reply, SerialLinkStats};
pub use command::{Axes, Command, Operand, ReplyKind, Setting, Tell, UnsolicitedMode};
pub use error::{GalilError, Malformed};
pub use framing::{Framer, ReplyFrame};
pub use link::{Link, SerialLink, SerialSettings, TcpLink};
pub use record::{AxisRecord, DataRecord, RecordLayout};
