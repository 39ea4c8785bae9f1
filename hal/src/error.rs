//! Error kinds, in the embedded-hal style.
//!
//! Every device trait carries an associated error type that implements [`Error`]; its
//! [`Error::kind`] maps it onto the small, `Copy` [`ErrorKind`] that generic code (the control loop,
//! the supervisor) can match without knowing the device. Implementations keep richer errors.

use core::fmt;

/// What went wrong, in terms generic code can act on.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ErrorKind {
    /// An argument was malformed: wrong length, unknown name, bad format.
    InvalidInput,
    /// A value was NaN or infinite.
    NonFinite,
    /// A value was outside a configured limit (joint range, velocity, torque, force).
    OutOfLimits,
    /// A pose cannot be reached by the robot.
    Unreachable,
    /// The configuration is singular for the requested operation.
    Singular,
    /// A device or peer did not answer in time.
    Timeout,
    /// The link to a device or peer failed: garbled frames, closed port, framing lost.
    Communication,
    /// The device reported a fault of its own (amplifier, encoder, controller error code).
    Device,
    /// The object is not in a lifecycle state that allows the operation.
    WrongState,
    /// The operation is not supported by this implementation.
    Unsupported,
    /// Anything else.
    Other,
}

impl ErrorKind {
    /// A short lower-case description, for logs and wire errors.
    pub const fn as_str(self) -> &'static str {
        match self {
            ErrorKind::InvalidInput => "invalid input",
            ErrorKind::NonFinite => "non-finite value",
            ErrorKind::OutOfLimits => "out of limits",
            ErrorKind::Unreachable => "unreachable",
            ErrorKind::Singular => "singular configuration",
            ErrorKind::Timeout => "timeout",
            ErrorKind::Communication => "communication failure",
            ErrorKind::Device => "device fault",
            ErrorKind::WrongState => "wrong lifecycle state",
            ErrorKind::Unsupported => "unsupported",
            ErrorKind::Other => "other error",
        }
    }
}

impl fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// An error that generic code can classify.
pub trait Error: fmt::Debug {
    /// The generic kind of this error.
    fn kind(&self) -> ErrorKind;
}

impl Error for ErrorKind {
    fn kind(&self) -> ErrorKind {
        *self
    }
}

impl Error for core::convert::Infallible {
    fn kind(&self) -> ErrorKind {
        match *self {}
    }
}
