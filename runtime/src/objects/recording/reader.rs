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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::clock::ClockReader;
    use crate::objects::recording::mcap_log::{self, McapLog};
    use crate::objects::recording::{RecordProfile, Recorder, RecordingSources, SceneConfig};
    use penelope_drivers::sim::tap::TapSample;
    use penelope_hal::{JointVector, Timestamp};
    use penelope_protocol::proto::LinkRecord;
    use penelope_rt_core::safety::{EventSet, FaultCause, SafetyEvent, SafetyState};
    use penelope_rt_core::telemetry::TelemetrySample;
    use std::path::PathBuf;

    fn scratch(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("penelope-recording-{}-{name}", std::process::id()))
    }

    /// Ticks whose values need every bit of an f64 (thirds, tiny and huge numbers).
    fn ticks(n: u64) -> Vec<TickRecord> {
        (1..=n)
            .map(|i| {
                let x = i as f64 / 3.0;
                let mut events = EventSet::EMPTY;
                if i == 7 {
                    events.insert(SafetyEvent::LinkLost);
                }
                TickRecord {
                    sample: TelemetrySample {
                        time: Timestamp::from_nanos(1_000_000 * i + 17),
                        seq: i,
                        q: JointVector::from_fn(|j, _| x * (j as f64 + 0.1) + 1e-300),
                        qd: JointVector::from_fn(|j, _| -x / (j as f64 + 7.0)),
                        effort: JointVector::from_fn(|j, _| 1e300 / (x + j as f64)),
                        state: if i > 5 {
                            SafetyState::Fault
                        } else {
                            SafetyState::Running
                        },
                        fault: (i > 5).then_some(FaultCause::VelocityLimit { joint: 3 }),
                        events,
                        port_energy: (i % 2 == 0).then_some(-x),
                        ..TelemetrySample::default()
                    },
                    truth: Some(TapSample {
                        kinetic_energy: x.sqrt(),
                        interaction_work: -x * 1e-9,
                        ..TapSample::default()
                    }),
                    clutch: (i % 3 == 0).then_some(i % 2 == 0),
                }
            })
            .collect()
    }

    fn link(time_ns: u64) -> LinkRecord {
        LinkRecord {
            time_ns,
            down: false,
            losses: 1,
            restorations: 1,
            samples_taken: 99,
            samples_dropped: 2,
            samples_missed: 3,
            refused: 0,
            clock_offset_ns: Some(-12_345),
            round_trip_ns: Some(250_000),
            one_way_delay_ns: Some(125_000),
            jitter_ns: None,
            last_heard_ns: Some(1_000),
            heartbeat_loss: 0.1 + 0.2,
            trips: 40,
            trip_p50_ns: Some(120_000),
            trip_p99_ns: Some(300_000),
            trip_max_ns: None,
        }
    }

    #[test]
    fn a_recording_reads_back_bit_for_bit_with_its_links_and_losses() {
        let path = scratch("roundtrip.mcap");
        let (a, b) = (ticks(40), ticks(25));
        let mut log = McapLog::create(&path, "lab").unwrap();
        log.add_controller("display").unwrap();
        log.add_controller("follow").unwrap();
        for t in &a {
            log.tick(0, t).unwrap();
        }
        for t in &b {
            log.tick(1, t).unwrap();
        }
        log.link("link", &link(5)).unwrap();
        log.link("link", &link(9)).unwrap();
        let datagrams = stream_samples();
        for d in &datagrams {
            log.datagram("link", d).unwrap();
        }
        assert!(log.datagrams_dropped("link", 3).unwrap());
        assert!(
            !log.datagrams_dropped("link", 3).unwrap(),
            "written when it grows"
        );
        let totals = log.finish(&[0, 4]).unwrap();
        assert_eq!(totals.ticks, 65);
        let r = read_recording(&path).unwrap();
        assert_eq!(r.node, "lab");
        assert_eq!(r.controllers["display"], a, "every bit of every tick");
        assert_eq!(r.controllers["follow"], b);
        assert_eq!(r.links["link"], vec![link(5), link(9)]);
        assert_eq!(r.dropped["display"], 0);
        assert_eq!(r.dropped["follow"], 4);
        assert_eq!(
            r.datagrams["link"], datagrams,
            "every bit of every stream sample"
        );
        assert_eq!(r.datagrams_dropped["link"], 3);
        let topics: Vec<String> = mcap_log::summarize(&path)
            .unwrap()
            .channels
            .into_iter()
            .map(|c| c.topic)
            .filter(|t| t.starts_with("/streams/"))
            .collect();
        assert_eq!(
            topics,
            [
                "/streams/link/master-to-slave",
                "/streams/link/slave-to-master"
            ]
        );
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn the_tick_schema_names_every_event_bit() {
        let schema: serde_json::Value = serde_json::from_str(&mcap_log::tick_schema()).unwrap();
        let events = schema["properties"]["sample"]["properties"]["events"]["description"]
            .as_str()
            .unwrap()
            .to_string();
        for e in penelope_rt_core::safety::SafetyEvent::ALL {
            assert!(
                events.contains(&format!("{} {}", e as u8, e.as_str())),
                "{events}"
            );
        }
        assert!(events.contains("14 sensor-error"), "{events}");
    }

    /// A sample sent each way and one taken, with every optional part.
    fn stream_samples() -> Vec<StreamDatagram> {
        use crate::objects::link_source::StreamName;
        use penelope_hal::{CartesianReference, Reference};
        use penelope_rt_core::teleop::{PortEnergy, WaveSample};
        let pose = |x: f64| {
            Reference::Cartesian(CartesianReference {
                pose: penelope_hal::Pose::translation(x, 0.1 + 0.2, -1.0 / 3.0),
                ..CartesianReference::default()
            })
        };
        let d = |stream, k: u64, arrived: Option<i64>| StreamDatagram {
            stream,
            time_ns: k * 2_000_000,
            sequence: k,
            sent_ns: (k * 2_000_000) as i64 - 7,
            arrived_ns: arrived,
            one_way_ns: arrived.map(|a| a - (k * 2_000_000) as i64),
            clutch: k.is_multiple_of(2),
            reference: pose(k as f64 * 1e-3 + 1e-17),
            wave: (k == 2).then(|| WaveSample {
                wave: nalgebra::Vector3::new(0.5, -1.25, 3.0),
                integral: nalgebra::Vector3::new(1e-3, 2e-3, -3e-3),
                energy: nalgebra::Vector3::new(0.125, 0.0, 7.5),
            }),
            energy: (k == 3).then_some(PortEnergy { input: 0.375 }),
        };
        vec![
            d(StreamName::MasterToSlave, 1, None),
            d(StreamName::SlaveToMaster, 2, Some(4_000_123)),
            d(StreamName::MasterToSlave, 3, None),
        ]
    }

    #[test]
    fn a_recording_cut_off_anywhere_reads_as_a_prefix_of_its_ticks() {
        let path = scratch("cut.mcap");
        let all = ticks(60);
        let mut log = McapLog::create(&path, "lab").unwrap();
        log.add_controller("display").unwrap();
        for chunk in all.chunks(10) {
            for t in chunk {
                log.tick(0, t).unwrap();
            }
            log.flush().unwrap(); // what the recorder does every FLUSH_EVERY
        }
        log.finish(&[0]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let cut = scratch("cut-part.mcap");
        let mut seen = 0;
        for len in (16..bytes.len()).step_by(97) {
            std::fs::write(&cut, &bytes[..len]).unwrap();
            let r = read_recording(&cut).unwrap();
            let got = r
                .controllers
                .get("display")
                .map_or(&[][..], |v| v.as_slice());
            assert_eq!(got, &all[..got.len()], "cut at {len}: a prefix");
            assert!(got.len() >= seen, "more of the file, no fewer ticks");
            seen = got.len();
        }
        assert!(
            seen >= 50,
            "flushed chunks are read before the file ends: {seen}"
        );
        let _ = std::fs::remove_file(path);
        let _ = std::fs::remove_file(cut);
    }

    #[test]
    fn losses_are_written_as_they_grow_so_a_file_cut_off_still_has_them() {
        let path = scratch("losses.mcap");
        let mut log = McapLog::create(&path, "lab").unwrap();
        log.add_controller("display").unwrap();
        log.tick(0, &ticks(1)[0]).unwrap();
        assert!(!log.dropped(0, 0).unwrap(), "nothing lost, nothing written");
        assert!(log.dropped(0, 5).unwrap());
        assert!(!log.dropped(0, 5).unwrap(), "written once");
        assert!(!log.dropped(3, 5).unwrap(), "no such controller");
        log.flush().unwrap();
        // The node dies here: no summary, no final counts.
        std::mem::forget(log);
        let r = read_recording(&path).unwrap();
        assert_eq!(r.dropped["display"], 5);
        assert_eq!(r.controllers["display"].len(), 1);
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn an_unwritable_path_or_a_foreign_file_is_a_typed_error() {
        let nowhere = Path::new("/nonexistent-dir/run.mcap");
        assert!(matches!(
            McapLog::create(nowhere, "lab"),
            Err(RecordingError::Io { .. })
        ));
        assert!(matches!(
            Recorder::start(
                RecordProfile::Penelope,
                nowhere,
                None,
                RecordingSources {
                    node: "lab",
                    streams: Vec::new(),
                    links: Vec::new(),
                    lifecycle: None,
                    clock: &crate::common_clock::CommonClock::own(),
                    node_time: ClockReader::Real,
                    scene: SceneConfig::default(),
                },
            ),
            Err(RecordingError::Io { .. })
        ));
        let foreign = scratch("foreign.mcap");
        std::fs::write(&foreign, b"time_s,q\n0,1\n").unwrap();
        assert!(matches!(
            read_recording(&foreign),
            Err(RecordingError::Format { .. })
        ));
        let _ = std::fs::remove_file(foreign);
    }

    #[test]
    fn a_scene_message_needs_a_schema_the_scene_crate_carries() {
        let path = scratch("scene-schema.mcap");
        let mut log = McapLog::create(&path, "lab").unwrap();
        let tf = penelope_scene::FrameTransforms::default();
        log.scene("/tf", penelope_scene::FRAME_TRANSFORMS, 5, &tf)
            .unwrap();
        log.scene("/tf", penelope_scene::FRAME_TRANSFORMS, 6, &tf)
            .unwrap();
        assert!(matches!(
            log.scene("/x", "foxglove.NoSuchSchema", 7, &tf),
            Err(RecordingError::Format { .. })
        ));
        log.finish(&[]).unwrap();
        let summary = mcap_log::summarize(&path).unwrap();
        let tf_channel = summary
            .channels
            .iter()
            .find(|c| c.topic == "/tf")
            .expect("a /tf channel");
        assert_eq!(tf_channel.messages, 2, "one channel, two messages");
        assert!(summary.channels.iter().all(|c| c.topic != "/x"));
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn a_crafted_record_length_is_an_error_not_an_abort() {
        let path = scratch("crafted.mcap");
        std::fs::write(&path, crafted_mcap_with_a_huge_record()).unwrap();
        for e in [
            read_recording(&path).unwrap_err(),
            mcap_log::summarize(&path).unwrap_err(),
        ] {
            assert!(
                matches!(
                    &e,
                    RecordingError::Mcap {
                        source: mcap::McapError::RecordTooLarge {
                            len: 0x4141_4141_4141_4141,
                            ..
                        },
                        ..
                    }
                ),
                "{e}"
            );
        }
        let _ = std::fs::remove_file(path);
    }

    /// A real recording, compressed and flushed in several chunks (written once).
    fn a_recording() -> Vec<u8> {
        static BYTES: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
        BYTES.get_or_init(write_a_recording).clone()
    }

    fn write_a_recording() -> Vec<u8> {
        let path = scratch("prop-base.mcap");
        let mut log = McapLog::create(&path, "lab").unwrap();
        log.add_controller("display").unwrap();
        for (i, t) in ticks(30).iter().enumerate() {
            log.tick(0, t).unwrap();
            if i % 10 == 9 {
                log.flush().unwrap();
            }
        }
        log.link("link", &link(5)).unwrap();
        log.finish(&[0]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let _ = std::fs::remove_file(path);
        bytes
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]
        /// Mutated recordings (bytes overwritten, u64 fields set huge, cut off) are read or
        /// refused with a typed error: never a panic or an abort.
        #[test]
        fn mutated_recordings_never_panic_or_abort(
            edits in proptest::collection::vec((0usize..4096, 0u8..=255, 0u8..4), 1..6),
            cut in 0usize..4096,
            which in 0usize..2,
        ) {
            let mut bytes = if which == 0 {
                a_recording()
            } else {
                crafted_mcap_with_a_huge_record()
            };
            for (at, byte, how) in edits {
                let at = at % bytes.len();
                match how {
                    0 => bytes[at] = byte,
                    // A length field (little-endian u64) set large at a random place.
                    1 => {
                        let end = (at + 8).min(bytes.len());
                        for b in &mut bytes[at..end] {
                            *b = 0x41;
                        }
                    }
                    2 => {
                        let end = (at + 8).min(bytes.len());
                        bytes[at..end].fill(0xff);
                    }
                    _ => bytes[at] ^= 1 << (byte % 8),
                }
            }
            if cut % 3 == 0 {
                bytes.truncate(cut.max(8) % (bytes.len() + 1));
            }
            let path = scratch(&format!("prop-{}-{}.mcap", std::process::id(), cut));
            std::fs::write(&path, &bytes).unwrap();
            let _ = read_recording(&path);
            let _ = mcap_log::summarize(&path);
            let _ = std::fs::remove_file(path);
        }
    }
}
