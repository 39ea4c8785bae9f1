//! Frames: a 4-byte little-endian length, then that many bytes of postcard.
//!
//! SKELETON (lead): signatures are the contract; NET fills in the bodies.

use std::io::{self, Read, Write};

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::proto::WireError;

/// What can go wrong reading or writing a frame.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The stream failed.
    #[error("i/o: {0}")]
    Io(#[from] io::Error),
    /// The peer closed the stream between frames.
    #[error("connection closed")]
    Closed,
    /// The announced length exceeds the maximum.
    #[error("frame of {len} bytes exceeds the maximum of {max}")]
    TooLarge {
        /// Announced length.
        len: u64,
        /// The maximum.
        max: u64,
    },
    /// The stream ended inside a frame.
    #[error("connection closed inside a frame")]
    Truncated,
    /// The body did not decode.
    #[error("malformed frame: {0}")]
    Malformed(String),
}

impl From<&FrameError> for WireError {
    fn from(e: &FrameError) -> Self {
        match e {
            FrameError::TooLarge { len, max } => WireError::FrameTooLarge {
                len: *len,
                max: *max,
            },
            FrameError::Malformed(m) => WireError::Malformed(m.clone()),
            other => WireError::Remote(other.to_string()),
        }
    }
}

/// `msg` as one frame (header and body).
///
/// # Errors
/// [`FrameError::TooLarge`] if the body exceeds `max`, [`FrameError::Malformed`] if it does not
/// serialize.
pub fn encode<T: Serialize>(msg: &T, max: usize) -> Result<Vec<u8>, FrameError> {
    let _ = (msg, max);
    Err(FrameError::Malformed("skeleton".into()))
}

/// Writes `msg` as one frame.
///
/// # Errors
/// As [`encode`], or the stream's error.
pub fn write_frame<W: Write, T: Serialize>(
    w: &mut W,
    msg: &T,
    max: usize,
) -> Result<(), FrameError> {
    let _ = (w, msg, max);
    Err(FrameError::Malformed("skeleton".into()))
}

/// Reads one frame and decodes it; the length is checked against `max` before the body is read.
///
/// # Errors
/// [`FrameError`] saying what went wrong.
pub fn read_frame<R: Read, T: DeserializeOwned>(r: &mut R, max: usize) -> Result<T, FrameError> {
    let _ = (r, max);
    Err(FrameError::Malformed("skeleton".into()))
}
