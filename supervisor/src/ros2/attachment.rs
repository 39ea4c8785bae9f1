//! The attachment rmw_zenoh puts beside every message: the publisher's sequence number, the
//! source time (ns since the Unix epoch) and the publisher's GID, in Zenoh's own serialization
//! (`zenoh-ext`). As rmw_zenoh writes it for Jazzy and Kilted, each value follows its name
//! (`"sequence_number"`, `"source_timestamp"`, `"source_gid"`); later rmw_zenoh dropped the
//! names. Penelope writes the named form and reads both.

use zenoh::bytes::ZBytes;
use zenoh_ext::{ZDeserializer, ZSerializer};

/// The names of the attachment's values, in order.
const NAMES: [&str; 3] = ["sequence_number", "source_timestamp", "source_gid"];

/// A message's attachment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Attachment {
    /// The publisher's count of messages, from 1.
    pub sequence_number: i64,
    /// When it was published, ns since the Unix epoch.
    pub source_timestamp: i64,
    /// The publisher's GID ([`super::graph::gid`]).
    pub source_gid: [u8; 16],
}

/// An attachment in neither form.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("not an rmw_zenoh attachment (sequence number, source timestamp, 16-byte GID)")]
pub struct BadAttachment;

impl Attachment {
    /// The named form.
    pub fn to_zbytes(self) -> ZBytes {
        let mut out = ZSerializer::new();
        out.serialize(NAMES[0]);
        out.serialize(self.sequence_number);
        out.serialize(NAMES[1]);
        out.serialize(self.source_timestamp);
        out.serialize(NAMES[2]);
        out.serialize(self.source_gid);
        out.finish()
    }

    /// Reads either form; trailing bytes are refused.
    ///
    /// # Errors
    /// [`BadAttachment`].
    pub fn from_zbytes(bytes: &ZBytes) -> Result<Attachment, BadAttachment> {
        Self::read(bytes, true).or_else(|_| Self::read(bytes, false))
    }

    fn read(bytes: &ZBytes, named: bool) -> Result<Attachment, BadAttachment> {
        let mut input = ZDeserializer::new(bytes);
        let sequence_number = read_value::<i64>(&mut input, named.then_some(NAMES[0]))?;
        let source_timestamp = read_value::<i64>(&mut input, named.then_some(NAMES[1]))?;
        let source_gid = read_value::<[u8; 16]>(&mut input, named.then_some(NAMES[2]))?;
        if !input.done() {
            return Err(BadAttachment);
        }
        Ok(Attachment {
            sequence_number,
            source_timestamp,
            source_gid,
        })
    }
}

/// The next value, after its name when there is one to check.
fn read_value<T: zenoh_ext::Deserialize>(
    input: &mut ZDeserializer<'_>,
    name: Option<&str>,
) -> Result<T, BadAttachment> {
    if let Some(name) = name
        && input.deserialize::<String>().map_err(|_| BadAttachment)? != name
    {
        return Err(BadAttachment);
    }
    input.deserialize::<T>().map_err(|_| BadAttachment)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: Attachment = Attachment {
        sequence_number: 7,
        source_timestamp: 1_764_300_000_123_456_789,
        source_gid: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16],
    };

    #[test]
    fn the_named_form_byte_for_byte() {
        // Zenoh's serialization: a string is its LEB128 length then its bytes, an i64 eight
        // little-endian bytes, a 16-byte array its length (16) then its bytes.
        let mut expected = vec![15];
        expected.extend_from_slice(b"sequence_number");
        expected.extend_from_slice(&7i64.to_le_bytes());
        expected.push(16);
        expected.extend_from_slice(b"source_timestamp");
        expected.extend_from_slice(&SAMPLE.source_timestamp.to_le_bytes());
        expected.push(10);
        expected.extend_from_slice(b"source_gid");
        expected.push(16);
        expected.extend_from_slice(&SAMPLE.source_gid);
        assert_eq!(SAMPLE.to_zbytes().to_bytes().as_ref(), expected.as_slice());
        assert_eq!(Attachment::from_zbytes(&SAMPLE.to_zbytes()), Ok(SAMPLE));
    }

    #[test]
    fn the_unnamed_form_reads_and_garbage_does_not() {
        let mut out = ZSerializer::new();
        out.serialize(SAMPLE.sequence_number);
        out.serialize(SAMPLE.source_timestamp);
        out.serialize(SAMPLE.source_gid);
        assert_eq!(Attachment::from_zbytes(&out.finish()), Ok(SAMPLE));

        for bad in [
            &b""[..],
            &b"\x0fsequence_number"[..],
            &[0u8; 31][..],
            &[0u8; 34][..],
        ] {
            assert_eq!(
                Attachment::from_zbytes(&ZBytes::from(bad.to_vec())),
                Err(BadAttachment),
                "{bad:?}"
            );
        }
        let mut long = SAMPLE.to_zbytes().to_bytes().to_vec();
        long.push(0);
        assert_eq!(
            Attachment::from_zbytes(&ZBytes::from(long)),
            Err(BadAttachment)
        );
    }
}
