//! Byte links the client talks over: a serial port (real line or pseudo-terminal), a TCP socket,
//! or a scripted mock in tests.

use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use super::error::GalilError;

/// A bidirectional byte stream with read timeouts.
pub trait Link {
    /// Writes every byte.
    ///
    /// # Errors
    /// [`GalilError::Closed`] when the device went away, [`GalilError::Io`] otherwise.
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), GalilError>;

    /// Reads what is available, waiting at most `timeout` for the first byte. Returns `Ok(0)` when
    /// nothing arrived in time.
    ///
    /// # Errors
    /// [`GalilError::Closed`] when the device went away, [`GalilError::Io`] otherwise.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, GalilError>;
}

impl<L: Link + ?Sized> Link for Box<L> {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), GalilError> {
        (**self).write_all(bytes)
    }
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, GalilError> {
        (**self).read(buf, timeout)
    }
}

/// Line settings of a serial port (8N1 without handshake unless changed).
#[derive(Clone, Debug, PartialEq)]
pub struct SerialSettings {
    /// Device path (`/dev/ttyUSB0`, or a pseudo-terminal from `penelope galil-sim`).
    pub path: String,
    /// Baud rate, bits/s.
    pub baud: u32,
    /// Data bits.
    pub data_bits: serialport::DataBits,
    /// Parity.
    pub parity: serialport::Parity,
    /// Stop bits.
    pub stop_bits: serialport::StopBits,
    /// Handshake.
    pub flow_control: serialport::FlowControl,
}

impl SerialSettings {
    /// 8N1, no handshake, at `baud`.
    pub fn new(path: impl Into<String>, baud: u32) -> Self {
        SerialSettings {
            path: path.into(),
            baud,
            data_bits: serialport::DataBits::Eight,
            parity: serialport::Parity::None,
            stop_bits: serialport::StopBits::One,
            flow_control: serialport::FlowControl::None,
        }
    }
}

/// A serial port.
pub struct SerialLink {
    port: Box<dyn serialport::SerialPort>,
    timeout: Duration,
}

impl SerialLink {
    /// Opens the port.
    ///
    /// # Errors
    /// [`GalilError::Closed`] when the device does not exist, [`GalilError::Io`] otherwise.
    pub fn open(settings: &SerialSettings) -> Result<Self, GalilError> {
        let timeout = Duration::from_millis(100);
        let port = serialport::new(settings.path.as_str(), settings.baud)
            .data_bits(settings.data_bits)
            .parity(settings.parity)
            .stop_bits(settings.stop_bits)
            .flow_control(settings.flow_control)
            .timeout(timeout)
            .open()
            .map_err(|e| match e.kind() {
                serialport::ErrorKind::NoDevice => GalilError::Closed,
                serialport::ErrorKind::Io(kind) => io_error(&io::Error::from(kind)),
                serialport::ErrorKind::InvalidInput => {
                    GalilError::InvalidArgument("invalid serial port settings")
                }
                serialport::ErrorKind::Unknown => GalilError::Io(io::ErrorKind::Other),
            })?;
        Ok(SerialLink { port, timeout })
    }
}

impl Link for SerialLink {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), GalilError> {
        self.port.write_all(bytes).map_err(|e| io_error(&e))
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, GalilError> {
        let timeout = timeout.max(Duration::from_millis(1));
        if timeout != self.timeout {
            self.port
                .set_timeout(timeout)
                .map_err(|_| GalilError::Io(io::ErrorKind::Other))?;
            self.timeout = timeout;
        }
        match self.port.read(buf) {
            Ok(0) if !buf.is_empty() => Err(GalilError::Closed),
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::TimedOut => Ok(0),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(0),
            Err(e) => Err(io_error(&e)),
        }
    }
}

/// A TCP socket (a Galil Ethernet port, or a serial-to-network bridge).
pub struct TcpLink {
    stream: TcpStream,
}

impl TcpLink {
    /// Wraps a connected stream (Nagle's algorithm is turned off: commands are small).
    ///
    /// # Errors
    /// [`GalilError::Io`] when the socket cannot be configured.
    pub fn new(stream: TcpStream) -> Result<Self, GalilError> {
        stream.set_nodelay(true).map_err(|e| io_error(&e))?;
        Ok(TcpLink { stream })
    }
}

impl Link for TcpLink {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), GalilError> {
        self.stream.write_all(bytes).map_err(|e| io_error(&e))
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, GalilError> {
        self.stream
            .set_read_timeout(Some(timeout.max(Duration::from_millis(1))))
            .map_err(|e| io_error(&e))?;
        match self.stream.read(buf) {
            Ok(0) if !buf.is_empty() => Err(GalilError::Closed),
            Ok(n) => Ok(n),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock
                        | io::ErrorKind::TimedOut
                        | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(0)
            }
            Err(e) => Err(io_error(&e)),
        }
    }
}

/// Maps an operating-system error: a vanished device (EIO, hang-up, broken pipe, reset, ENXIO,
/// ENODEV) is [`GalilError::Closed`].
pub(crate) fn io_error(e: &io::Error) -> GalilError {
    const EIO: i32 = 5;
    const ENXIO: i32 = 6;
    const ENODEV: i32 = 19;
    if matches!(e.raw_os_error(), Some(EIO | ENXIO | ENODEV)) {
        return GalilError::Closed;
    }
    match e.kind() {
        io::ErrorKind::BrokenPipe
        | io::ErrorKind::ConnectionReset
        | io::ErrorKind::ConnectionAborted
        | io::ErrorKind::NotConnected
        | io::ErrorKind::UnexpectedEof
        | io::ErrorKind::NotFound => GalilError::Closed,
        // serialport reports EIO from a hung-up pseudo-terminal as `Other` with the text "EIO".
        io::ErrorKind::Other if e.to_string().contains("I/O error") => GalilError::Closed,
        kind => GalilError::Io(kind),
    }
}
