//! Errors of the Galil protocol client.
//!
//! Every error is a value without heap storage (the text of a rejection lives in a fixed-capacity
//! string), so errors can cross into the control thread's side by copy and format without
//! allocating.

use core::time::Duration;

use penelope_hal::error::{Error as HalError, ErrorKind};

/// The largest number of bytes of Galil's `TC1` explanation that an error keeps.
pub const MAX_ERROR_TEXT: usize = 64;

/// The text of a rejection as `TC1` gave it (truncated at [`MAX_ERROR_TEXT`] bytes).
pub type ErrorText = heapless::String<MAX_ERROR_TEXT>;

/// How a reply was malformed.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Malformed {
    /// A field that should be a number is not one.
    BadNumber,
    /// The reply held a different number of values than asked for.
    WrongCount,
    /// A reply was longer than the client's buffer.
    Overflow,
    /// A binary data record did not match its header or the `QZ` layout.
    BadRecord,
    /// The `QZ` layout was not four sensible numbers.
    BadLayout,
    /// The board's identification could not be read.
    BadIdentity,
    /// A reply of the wrong kind: data where only `:` was expected, or none where data was.
    UnexpectedReply,
}

impl Malformed {
    /// A short lower-case description.
    pub const fn as_str(self) -> &'static str {
        match self {
            Malformed::BadNumber => "a field is not a number",
            Malformed::WrongCount => "wrong number of values",
            Malformed::Overflow => "reply longer than the buffer",
            Malformed::BadRecord => "data record does not match its layout",
            Malformed::BadLayout => "bad QZ layout",
            Malformed::BadIdentity => "unreadable identification",
            Malformed::UnexpectedReply => "unexpected kind of reply",
        }
    }
}

impl core::fmt::Display for Malformed {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What went wrong talking to a Galil board.
#[non_exhaustive]
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GalilError {
    /// The board answered `?`; `TC1` explained why with Galil's code and text.
    #[error("error {code}: {text}")]
    Rejected {
        /// Galil's error code (`TC0`), e.g. 1 for an unrecognized command.
        code: u16,
        /// Galil's explanation, e.g. `Unrecognized command`.
        text: ErrorText,
    },
    /// The board answered `?` and `TC1` did not give a readable code.
    #[error("rejected; TC1 gave no code")]
    RejectedUnexplained,
    /// No complete reply arrived in time (the client resynchronised afterwards when it could).
    #[error("no reply within {0:?}")]
    Timeout(Duration),
    /// The device went away (port closed, pseudo-terminal hung up, socket closed).
    #[error("the link to the board is closed")]
    Closed,
    /// Another input/output error from the operating system.
    #[error("link input/output error: {0}")]
    Io(std::io::ErrorKind),
    /// A reply arrived but could not be understood.
    #[error("malformed reply: {0}")]
    Malformed(Malformed),
    /// The command line would exceed Galil's 80 characters.
    #[error("command line longer than 80 characters")]
    LineTooLong,
    /// A command argument cannot be sent (NaN or infinite, an axis the board does not have, a
    /// character that would end the line early).
    #[error("invalid argument: {0}")]
    InvalidArgument(&'static str),
    /// The client lost step with the board and could not find it again.
    #[error("lost synchronisation with the board")]
    Desynchronized,
}

impl GalilError {
    /// Galil's error code when the board rejected the command.
    pub fn code(&self) -> Option<u16> {
        match self {
            GalilError::Rejected { code, .. } => Some(*code),
            _ => None,
        }
    }

    /// True for faults of the line itself (device gone, timeouts, garbage), as opposed to a
    /// command the board understood and refused.
    pub fn is_link_fault(&self) -> bool {
        matches!(
            self,
            GalilError::Timeout(_)
                | GalilError::Closed
                | GalilError::Io(_)
                | GalilError::Malformed(_)
                | GalilError::Desynchronized
        )
    }
}

impl HalError for GalilError {
    fn kind(&self) -> ErrorKind {
        match self {
            GalilError::Rejected { .. } | GalilError::RejectedUnexplained => ErrorKind::Device,
            GalilError::Timeout(_) => ErrorKind::Timeout,
            GalilError::Closed
            | GalilError::Io(_)
            | GalilError::Malformed(_)
            | GalilError::Desynchronized => ErrorKind::Communication,
            GalilError::LineTooLong | GalilError::InvalidArgument(_) => ErrorKind::InvalidInput,
        }
    }
}

/// Copies `text` into an [`ErrorText`], cutting at a character boundary when too long.
pub(crate) fn error_text(text: &str) -> ErrorText {
    bounded(text)
}

/// Copies `text` into a fixed-capacity string, cutting at a character boundary when too long.
pub(crate) fn bounded<const N: usize>(text: &str) -> heapless::String<N> {
    let mut out = heapless::String::new();
    for c in text.chars() {
        if out.push(c).is_err() {
            break;
        }
    }
    out
}
