//! Reading a recording back: every message up to a cut-off last record (a file still being
//! written, or left by a node that died), length-checked before anything is allocated.

use std::collections::BTreeMap;
use std::path::Path;

use super::RecordingError;
use super::mcap_log::{
    self, CLOCK_TOPIC, CONTROLLER_TOPIC, LINK_TOPIC, RECORDER_TOPIC, STREAM_TOPIC,
};
use crate::objects::link_source::StreamDatagram;
use crate::objects::tick::TickRecord;
use penelope_protocol::proto::LinkRecord;

/// A recording read back.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// The node that wrote it.
    pub node: String,
    /// Every recorded controller's ticks, in order, by name.
    pub controllers: BTreeMap<String, Vec<TickRecord>>,
    /// Ticks lost by the recorder, by controller (written when the recording ends).
    pub dropped: BTreeMap<String, u64>,
    /// The records of each channel's link to another node, in order, by channel.
    pub links: BTreeMap<String, Vec<LinkRecord>>,
    /// The samples of each channel's data-plane streams this node sent and took, in the
    /// order written (each stream in its own order), by channel.
    pub datagrams: BTreeMap<String, Vec<StreamDatagram>>,
    /// Stream samples lost by the recorder, by channel.
    pub datagrams_dropped: BTreeMap<String, u64>,
    /// The common clock less the node's, ns, as the node last estimated it (`/clock`; `None`
    /// in a recording without one, such as the demo's: its node's clock is the common one).
    pub clock_offset_ns: Option<i64>,
}

/// The longest record a recording may hold, at least: a record may also be as long as the file
/// (a record in a compressed chunk can be longer than the file that holds it; this recorder's
/// are a few kB).
const RECORD_LIMIT_FLOOR: usize = 16 << 20;

/// Checks the length of every record of the MCAP file `bytes`, the records inside chunks too,
/// before [`mcap::MessageStream`] reads it: that reader bounds no length, and a crafted record
/// inside a compressed chunk made it allocate what the length field says (an abort, not an
/// error: "memory allocation of 4702111234474983754 bytes failed"). It runs the same reader
/// with the same options as `MessageStream` (no CRC checks, end magic optional) plus the
/// crate's own `record_length_limit` ([`RECORD_LIMIT_FLOOR`] or the file's size, the larger),
/// so it sees the same records, and stops where that reader would stop (a file cut off).
///
/// # Errors
/// [`mcap::McapError::RecordTooLarge`] or [`mcap::McapError::ChunkTooLarge`] for a length
/// beyond the limit.
pub(crate) fn check_record_lengths(bytes: &[u8]) -> Result<(), mcap::McapError> {
    use mcap::McapError;
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_record_length_limit(bytes.len().max(RECORD_LIMIT_FLOOR)),
    );
    let mut rest = bytes;
    while let Some(event) = reader.next_event() {
        match event {
            Ok(LinearReadEvent::ReadRequest(need)) => {
                if rest.is_empty() {
                    return Ok(()); // cut off: the reader after this one stops here too
                }
                let n = need.min(rest.len());
                reader.insert(n).copy_from_slice(&rest[..n]);
                reader.notify_read(n);
                rest = &rest[n..];
            }
            Ok(LinearReadEvent::Record { .. }) => {}
            Err(e @ (McapError::RecordTooLarge { .. } | McapError::ChunkTooLarge(_))) => {
                return Err(e);
            }
            // Any other error stops the reader after this one at the same record, and it says so.
            Err(_) => return Ok(()),
        }
    }
    Ok(())
}

/// An MCAP file of 111 bytes with the right profile whose zstd chunk (one raw block) holds a
/// record header claiming 0x4141_4141_4141_4141 bytes: before [`check_record_lengths`], reading
/// it aborted the process.
#[cfg(test)]
pub(crate) fn crafted_mcap_with_a_huge_record() -> Vec<u8> {
    fn record(file: &mut Vec<u8>, opcode: u8, body: &[u8]) {
        file.push(opcode);
        file.extend((body.len() as u64).to_le_bytes());
        file.extend(body);
    }
    fn string(out: &mut Vec<u8>, s: &[u8]) {
        out.extend((s.len() as u32).to_le_bytes());
        out.extend(s);
    }
    let mut file = mcap::MAGIC.to_vec();
    let mut header = Vec::new();
    string(&mut header, mcap_log::PROFILE.as_bytes());
    string(&mut header, b"crafted");
    record(&mut file, 0x01, &header);
    let mut inner = vec![0x05]; // a message record...
    inner.extend(0x4141_4141_4141_4141u64.to_le_bytes()); // ...of 4.7e18 bytes
    // A zstd frame: magic, single segment with a 1-byte content size, one last raw block.
    let mut zstd = vec![0x28, 0xb5, 0x2f, 0xfd, 0x20, inner.len() as u8];
    zstd.extend(&((inner.len() as u32) << 3 | 1).to_le_bytes()[..3]);
    zstd.extend(&inner);
    let mut chunk = Vec::new();
    chunk.extend(0u64.to_le_bytes()); // first message time
    chunk.extend(0u64.to_le_bytes()); // last message time
    chunk.extend((inner.len() as u64).to_le_bytes()); // uncompressed size
    chunk.extend(0u32.to_le_bytes()); // no CRC
    string(&mut chunk, b"zstd");
    chunk.extend((zstd.len() as u64).to_le_bytes());
    chunk.extend(&zstd);
    record(&mut file, 0x06, &chunk);
    file
}

/// Reads the recording at `path`: every message up to a cut-off last record (a file being
/// written, or left by a node that died, has no summary yet).
///
/// # Errors
/// [`RecordingError`] for a file that cannot be read, or is not a recording.
pub fn read_recording(path: &Path) -> Result<Recording, RecordingError> {
    let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bad = |message: String| RecordingError::Format {
        path: path.to_path_buf(),
        message,
    };
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(bad("not an MCAP file".into()));
    }
    check_record_lengths(&bytes).map_err(|source| RecordingError::Mcap {
        path: path.to_path_buf(),
        source,
    })?;
    let options = mcap::read::Options::IgnoreEndMagic;
    let mut recording = Recording::default();
    // The node, from the metadata record written first.
    if let Ok(reader) = mcap::read::LinearReader::new_with_options(&bytes, options.into()) {
        for record in reader {
            match record {
                Ok(mcap::records::Record::Header(h)) if h.profile == super::ros2_log::PROFILE => {
                    return Err(bad(
                        "a ROS 2 profile recording (read it with ROS 2 tools); replay and task \
                         reports read the `penelope` profile"
                            .into(),
                    ));
                }
                Ok(mcap::records::Record::Header(h)) if h.profile != mcap_log::PROFILE => {
                    return Err(bad(format!("profile {:?}, not a node's", h.profile)));
                }
                Ok(mcap::records::Record::Metadata(m)) if m.name == "node" => {
                    recording.node = m.metadata.get("node").cloned().unwrap_or_default();
                    break;
                }
                Ok(_) => {}
                Err(_) => break, // cut off
            }
        }
    }
    let stream =
        mcap::MessageStream::new_with_options(&bytes, options.into()).map_err(|source| {
            RecordingError::Mcap {
                path: path.to_path_buf(),
                source,
            }
        })?;
    for message in stream {
        let Ok(m) = message else {
            break; // being written
        };
        let topic = m.channel.topic.as_str();
        let json = |e: serde_json::Error| bad(format!("a malformed message on {topic}: {e}"));
        if let Some(name) = topic.strip_prefix(CONTROLLER_TOPIC) {
            let tick: TickRecord = serde_json::from_slice(&m.data).map_err(json)?;
            recording
                .controllers
                .entry(name.to_string())
                .or_default()
                .push(tick);
        } else if let Some(rest) = topic.strip_prefix(STREAM_TOPIC) {
            let sample: StreamDatagram = serde_json::from_slice(&m.data).map_err(json)?;
            let channel = rest.rsplit_once('/').map_or(rest, |(c, _)| c);
            recording
                .datagrams
                .entry(channel.to_string())
                .or_default()
                .push(sample);
        } else if let Some(channel) = topic.strip_prefix(LINK_TOPIC) {
            let link: LinkRecord = serde_json::from_slice(&m.data).map_err(json)?;
            recording
                .links
                .entry(channel.to_string())
                .or_default()
                .push(link);
        } else if topic == CLOCK_TOPIC {
            let v: serde_json::Value = serde_json::from_slice(&m.data).map_err(json)?;
            recording.clock_offset_ns = v["offset_ns"].as_i64().or(recording.clock_offset_ns);
        } else if topic == RECORDER_TOPIC {
            let v: serde_json::Value = serde_json::from_slice(&m.data).map_err(json)?;
            if let (Some(name), Some(count)) = (v["controller"].as_str(), v["dropped"].as_u64()) {
                recording.dropped.insert(name.to_string(), count);
            }
            if let (Some(name), Some(count)) = (v["channel"].as_str(), v["dropped"].as_u64()) {
                recording.datagrams_dropped.insert(name.to_string(), count);
            }
        }
    }
    Ok(recording)
}
