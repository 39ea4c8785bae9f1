#![doc = include_str!("../README.md")]
//!
//! ```
//! use penelope_ros2_msgs::{JointState, RosMessage, Time};
//!
//! let mut message = JointState::default();
//! message.header.stamp = Time::from_ns(1_500_000_000);
//! message.name = vec!["shoulder".into()];
//! message.position = vec![0.25];
//! let bytes = message.to_cdr();
//! assert_eq!(JointState::decode_cdr(&bytes).unwrap(), message);
//! assert!(JointState::type_hash().starts_with("RIHS01_"));
//! ```
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod cdr;
pub mod description;
mod messages;

pub use cdr::{CdrError, CdrField};
pub use description::MessageDescription;
pub use messages::*;

/// A ROS 2 message Penelope writes or reads.
pub trait RosMessage: CdrField {
    /// The type's description: name, `.msg` text and fields.
    const DESCRIPTION: &'static MessageDescription;

    /// `"sensor_msgs/msg/JointState"`.
    const TYPE_NAME: &'static str = Self::DESCRIPTION.type_name;

    /// The `.msg` text with its dependencies, as MCAP's `ros2msg` schema encoding wants
    /// (the type's own text, then `"====...\nMSG: pkg/msg/Type\n<text>"` per dependency).
    fn schema_text() -> String {
        Self::DESCRIPTION.schema_text()
    }

    /// The RIHS01 type hash, `"RIHS01_<64 lowercase hex>"`, computed from the type
    /// description (ROS 2 REP 2011).
    fn type_hash() -> String {
        Self::DESCRIPTION.type_hash()
    }

    /// CDR (XCDR1 little-endian) with the 4-byte encapsulation header `00 01 00 00`,
    /// appended to `out`.
    fn encode_cdr(&self, out: &mut Vec<u8>) {
        let mut writer = cdr::CdrWriter::new(out);
        self.write_cdr(&mut writer);
    }

    /// [`RosMessage::encode_cdr`] into a new buffer.
    fn to_cdr(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.encode_cdr(&mut out);
        out
    }

    /// The reverse of [`RosMessage::encode_cdr`]: a short, misaligned or oversized
    /// (strings/sequences over [`cdr::MAX_LENGTH`]) payload is a typed error.
    fn decode_cdr(bytes: &[u8]) -> Result<Self, CdrError> {
        let mut reader = cdr::CdrReader::new(bytes)?;
        let message = Self::read_cdr(&mut reader)?;
        reader.finish()?;
        Ok(message)
    }
}
