//! Recordings as MCAP files: one channel per recorded controller (every control tick, with
//! the plant's truth), one for the safety events, one per data-plane link's statistics, and one
//! for what the recorder itself lost.
//!
//! Every channel has a schema in JSON Schema and carries JSON messages (MCAP's well-known
//! `jsonschema` / `json` pair). Foxglove and Lichtblick show and plot them without plugins,
//! PlotJuggler's MCAP loader reads them, the `mcap` command line and every MCAP library (Rust,
//! Python, C++, Go, TypeScript) decode them without generated code; a person can read one with
//! `mcap cat --json`. Protobuf or ROS 2 messages would be smaller, but need generated types on
//! both sides and a build step for a schema that follows `TelemetrySample` as it grows; flatbuffers
//! are read by fewer tools. JSON costs bytes: a tick is about 600 after the chunks' zstd
//! compression, a little more than the same tick as a CSV row.
//!
//! A tick's message is the serde form of [`TickRecord`] (`{"sample": .., "truth": ..}`), so
//! that it reads back bit for bit (`recording::read_recording`; serde_json's
//! `float_roundtrip`); plot paths look like `/controllers/follow.sample.q[0]`.
//!
//! Topics:
//! - `/controllers/<name>` (schema `penelope.Tick`): every tick of controller `<name>`;
//! - `/safety` (schema `penelope.SafetyEvent`): a message for every tick whose safety state or
//!   fault changed, or that raised events (watchdog, limits, link lost, ...);
//! - `/links/<channel>` (schema `penelope.LinkStats`): channel `<channel>`'s link to another
//!   node, now and then;
//! - `/streams/<channel>/<stream>` (schema `penelope.StreamSample`): every sample of channel
//!   `<channel>`'s data-plane streams (`master-to-slave`, `slave-to-master`) that this node's
//!   end sent or took, with its sequence number, send time, arrival and one-way trip;
//! - `/lifecycle` (schema `penelope.Lifecycle`): the node's objects' lifecycle transitions;
//! - `/clock` (schema `penelope.CommonClock`): the node's estimate of the common clock less
//!   its own, now and then;
//! - `/recorder` (schema `penelope.RecorderDropped`): the ticks (per controller) and stream
//!   samples (per channel) the recorder lost, as they grow and at the end (they also go into
//!   the file's `recorder` metadata record);
//! - the 3D scene ([`super::scene`]), in Foxglove's well-known schemas: `/tf`
//!   (`foxglove.FrameTransforms`), `/scene` (`foxglove.SceneUpdate`) and
//!   `/robot_description/<robot>` (`penelope.RobotDescription`);
//! - per camera on the node (`sensor/sim-camera`), `/<camera>/image`
//!   (`foxglove.CompressedImage`, JPEG) stamped and logged at each frame's capture instant on
//!   the common clock, and `/<camera>/calibration` (`foxglove.CameraCalibration`) with its
//!   first frame.
//!
//! Log and publish times are on the system's common clock (see [`crate::common_clock`]: the
//! naming service host's monotonic clock), so that the recordings of several hosts share one
//! time line: each message's own time on the node's clock (a tick's `sample.time`, a record's
//! `time_ns`: the simulated clock in a simulated run, the monotonic clock otherwise) plus the
//! node's estimate of the offset when it was written, which `/clock` records. A node that
//! hosts the naming service, or runs on a simulated clock, is its own common clock: its log
//! times are its node times. (`penelope demo`'s `run.mcap`: node times.)
//!
//! [`McapLog`] is the writer (not thread-safe, not real-time: it allocates and writes files;
//! it is fed by the telemetry pump's recorder streams, never by a loop). [`summarize`] reads a
//! file's channels, counts and times back (`penelope recording info`).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use penelope_rt_core::safety::{FaultCause, SafetyEvent, SafetyState};
use serde::Serialize;
use serde_json::json;

use super::RecordingError;
use crate::objects::tick::TickRecord;
use penelope_protocol::proto::LinkRecord;

/// The MCAP profile written in the header (none of the well-known ones fits: JSON messages
/// of our own).
pub const PROFILE: &str = "penelope";

/// The topic prefix of controllers' ticks.
pub const CONTROLLER_TOPIC: &str = "/controllers/";
/// The topic of safety events.
pub const SAFETY_TOPIC: &str = "/safety";
/// The topic prefix of links' statistics.
pub const LINK_TOPIC: &str = "/links/";
/// The topic of the recorder's own losses.
pub const RECORDER_TOPIC: &str = "/recorder";

const VEC3: &str = r#"{"type":"array","items":{"type":"number"},"minItems":3,"maxItems":3,"description":"x, y, z"}"#;
const JOINTS: &str = r#"{"type":"array","items":{"type":"number"},"description":"one per joint (unused joints zero)"}"#;
const DURATION: &str = r#"{"type":"object","properties":{"secs":{"type":"integer"},"nanos":{"type":"integer"}},"required":["secs","nanos"]}"#;

pub(crate) fn tick_schema() -> String {
    let wrench = format!(
        r#"{{"type":"object","properties":{{"force":{VEC3},"torque":{VEC3},"frame":{{"type":"string"}}}},"required":["force","torque"]}}"#
    );
    let optional_number = r#"{"type":["number","null"]}"#;
    // The bit of each event, so that a reader of `sample.events` needs no copy of rt-core.
    let bits = SafetyEvent::ALL
        .iter()
        .map(|e| format!("{} {}", *e as u8, e.as_str()))
        .collect::<Vec<_>>()
        .join(", ");
    format!(
        r#"{{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.Tick","description":"One control tick (TickRecord): what the loop reported (sample: rt-core's TelemetrySample) and, behind a simulated board, the plant's truth. Units: SI (rad, rad/s, N·m, m, N, J); times in ns on the node's clock.","type":"object","properties":{{
"sample":{{"type":"object","properties":{{
"time":{{"type":"integer","description":"the tick's scheduled instant, ns"}},
"seq":{{"type":"integer","description":"tick counter of the loop, 1 for the first"}},
"q":{JOINTS},"qd":{JOINTS},"effort":{JOINTS},"position_command":{JOINTS},
"reference_kind":{{"type":"string"}},"reference_q":{JOINTS},"reference_position":{VEC3},
"reference_age":{DURATION},
"wrench":{wrench},"commanded_wrench":{wrench},"tool_position":{VEC3},
"controller":{{"type":"integer","description":"index of the active controller"}},
"state":{{"type":"string","description":"safety state after the tick"}},
"events":{{"type":"integer","description":"safety events of the tick, one bit each, bit number and event: {bits} (also named in /safety)"}},
"fault":{{"description":"the latched fault's cause, null when none"}},
"wake_latency":{DURATION},"exec_time":{DURATION},
"port_energy":{optional_number},"channel_energy":{optional_number}
}},"required":["time","seq","q","qd","effort","state"]}},
"truth":{{"type":["object","null"],"description":"the simulated plant's ground truth","properties":{{
"time":{{"type":"integer"}},
"joints":{{"type":"object","properties":{{"position":{JOINTS},"velocity":{JOINTS},"effort":{JOINTS}}}}},
"tool_pose":{{"type":"object","properties":{{"rotation":{{"type":"array","items":{{"type":"number"}},"description":"unit quaternion x, y, z, w"}},"translation":{VEC3}}}}},
"base_wrench":{wrench},"tool_wrench":{wrench},
"kinetic_energy":{{"type":"number"}},"interaction_work":{{"type":"number"}}
}}}},
"clutch":{{"type":["boolean","null"],"description":"whether the operator's hand held the clutch (null: no hand holds this robot)"}}
}},"required":["sample","truth"]}}"#
    )
}

const SAFETY_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.SafetyEvent","description":"A tick whose safety state or fault changed, or that raised safety events.","type":"object","properties":{"time_ns":{"type":"integer"},"controller":{"type":"string","description":"the controller object's name"},"seq":{"type":"integer"},"state":{"type":"string"},"previous_state":{"type":["string","null"]},"fault":{"type":["string","null"]},"events":{"type":"array","items":{"type":"string"}}},"required":["time_ns","controller","state","events"]}"#;

const LINK_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.LinkStats","description":"One end's view of a data-plane link (LinkRecord in docs/wire-format.md); times in ns.","type":"object","properties":{"time_ns":{"type":"integer"},"down":{"type":"boolean"},"losses":{"type":"integer"},"restorations":{"type":"integer"},"samples_taken":{"type":"integer"},"samples_dropped":{"type":"integer"},"samples_missed":{"type":"integer"},"refused":{"type":"integer"},"clock_offset_ns":{"type":["integer","null"]},"round_trip_ns":{"type":["integer","null"]},"one_way_delay_ns":{"type":["integer","null"]},"jitter_ns":{"type":["integer","null"]},"last_heard_ns":{"type":["integer","null"]},"heartbeat_loss":{"type":"number"},"trips":{"type":"integer"},"trip_p50_ns":{"type":["integer","null"]},"trip_p99_ns":{"type":["integer","null"]},"trip_max_ns":{"type":["integer","null"]}},"required":["time_ns","down"]}"#;

const LIFECYCLE_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.Lifecycle","description":"A lifecycle transition of an object of the node (create, destroy, configure, activate, deactivate, cleanup, shutdown), with its state afterwards; time in ns on the node's clock.","type":"object","properties":{"time_ns":{"type":"integer"},"object":{"type":"string"},"kind":{"type":"string"},"transition":{"type":"string"},"state":{"type":"string"}},"required":["time_ns","object","kind","transition","state"]}"#;

/// The topic of the node's lifecycle transitions.
pub const LIFECYCLE_TOPIC: &str = "/lifecycle";

/// The topic of the recording node's estimate of the common clock.
pub const CLOCK_TOPIC: &str = "/clock";

const CLOCK_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.CommonClock","description":"The recording node's estimate of the system's common clock (the naming service host's monotonic clock) less its own: every message's log time is its node time plus offset_ns as estimated when it was written. source own: the node's clock is the common one (offset 0).","type":"object","properties":{"time_ns":{"type":"integer","description":"node clock"},"source":{"enum":["own","naming"]},"address":{"type":"string"},"offset_ns":{"type":["integer","null"]},"round_trip_ns":{"type":["integer","null"]},"jitter_ns":{"type":["integer","null"]},"exchanges":{"type":"integer"}},"required":["time_ns","source","offset_ns"]}"#;

/// The topic prefix of channels' data-plane streams: `/streams/<channel>/<stream>`.
pub const STREAM_TOPIC: &str = "/streams/";

const STREAM_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.StreamSample","description":"A sample of a channel's data-plane stream as this node's end sent it (arrived_ns and one_way_ns null) or took it (accepted: newest wins; duplicates, late and stale samples are only counted, in /links/<channel>). Times in ns: time_ns and arrived_ns on this node's clock; sent_ns as in the datagram's header, on the link's common clock (the receiver's, as the sender's heartbeats estimate it). Units SI.","type":"object","properties":{"stream":{"enum":["master-to-slave","slave-to-master"]},"time_ns":{"type":"integer"},"sequence":{"type":"integer","description":"the sender's sequence number"},"sent_ns":{"type":"integer"},"arrived_ns":{"type":["integer","null"]},"one_way_ns":{"type":["integer","null"]},"clutch":{"type":"boolean"},"reference":{"type":"object","description":"the sample (hal::Reference, externally tagged: {\"Cartesian\": ..} for a pose, {\"Hybrid\": ..} for a pose with a wrench)"},"wave":{"type":["object","null"],"description":"a wave-variable law's wave and its running totals"},"energy":{"type":["object","null"],"description":"a two-port law's energy counters, J"}},"required":["stream","time_ns","sequence","sent_ns","clutch","reference"]}"#;

const RECORDER_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.RecorderDropped","description":"Ticks of a controller, or samples of a channel's data-plane streams, the recorder lost because it fell behind (the loops never wait for it): one of controller and channel is given.","type":"object","properties":{"controller":{"type":"string"},"channel":{"type":"string"},"dropped":{"type":"integer"},"written":{"type":"integer"}},"required":["dropped","written"]}"#;

/// A recorded controller's channel.
struct ControllerChannel {
    name: String,
    channel: u16,
    written: u64,
    /// The loss last written to `/recorder`.
    reported: u64,
    last: Option<(SafetyState, Option<FaultCause>)>,
}

/// What a finished recording holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct McapTotals {
    /// Ticks written, all controllers.
    pub ticks: u64,
    /// Messages written, all channels.
    pub messages: u64,
}

/// An MCAP writer of profile `profile` on `file` (`path` names it in errors), Zstandard
/// chunks, the library named `penelope <version>`: both profiles' files start so.
pub(super) fn open_writer(
    file: File,
    path: &Path,
    profile: &str,
) -> Result<mcap::Writer<BufWriter<File>>, RecordingError> {
    mcap::WriteOptions::new()
        .profile(profile)
        .library(concat!("penelope ", env!("CARGO_PKG_VERSION")))
        .compression(Some(mcap::Compression::Zstd))
        .create(BufWriter::new(file))
        .map_err(RecordingError::mcap(path))
}

/// An MCAP file being written: see the [module](self).
pub struct McapLog {
    writer: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    tick_schema: u16,
    link_schema: u16,
    safety: u16,
    recorder: u16,
    controllers: Vec<ControllerChannel>,
    links: BTreeMap<String, u16>,
    /// The `/streams/<channel>/<stream>` channels, by topic, and their schema (added with the
    /// first); samples written and loss last reported, by channel.
    streams: BTreeMap<String, u16>,
    stream_schema: Option<u16>,
    stream_counts: BTreeMap<String, (u64, u64)>,
    /// The `/lifecycle` channel, added with its first transition.
    lifecycle: Option<u16>,
    /// The `/clock` channel, added with the first estimate, and the offset added to every
    /// message's node time for its log time.
    clock: Option<u16>,
    clock_offset_ns: i64,
    /// The 3D scene's channels (Foxglove's well-known schemas, [`penelope_scene`]) by topic,
    /// and their schemas by name, added with their first message.
    scene_channels: BTreeMap<String, u16>,
    scene_schemas: BTreeMap<String, u16>,
    sequence: BTreeMap<u16, u32>,
    last_time: u64,
    totals: McapTotals,
}

impl McapLog {
    /// Creates `path` for node `node`'s recording.
    ///
    /// # Errors
    /// [`RecordingError::Io`] when the file cannot be created; [`RecordingError::Mcap`] when
    /// the header cannot be written.
    pub fn create(path: &Path, node: &str) -> Result<McapLog, RecordingError> {
        let file = File::create(path).map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        McapLog::create_in(file, path, node)
    }

    /// A log writing to `file`, already open (created exclusively by the caller: a client's
    /// recording, [`crate::objects::files::create_in`]); `path` names it in errors.
    ///
    /// # Errors
    /// [`RecordingError`] when the header cannot be written.
    pub fn create_in(file: File, path: &Path, node: &str) -> Result<McapLog, RecordingError> {
        let mcap_err = RecordingError::mcap(path);
        let mut writer = open_writer(file, path, PROFILE)?;
        let tick_schema = writer
            .add_schema("penelope.Tick", "jsonschema", tick_schema().as_bytes())
            .map_err(mcap_err)?;
        let safety_schema = writer
            .add_schema(
                "penelope.SafetyEvent",
                "jsonschema",
                SAFETY_SCHEMA.as_bytes(),
            )
            .map_err(mcap_err)?;
        let link_schema = writer
            .add_schema("penelope.LinkStats", "jsonschema", LINK_SCHEMA.as_bytes())
            .map_err(mcap_err)?;
        let recorder_schema = writer
            .add_schema(
                "penelope.RecorderDropped",
                "jsonschema",
                RECORDER_SCHEMA.as_bytes(),
            )
            .map_err(mcap_err)?;
        let meta = BTreeMap::from([("node".to_string(), node.to_string())]);
        let safety = writer
            .add_channel(safety_schema, SAFETY_TOPIC, "json", &meta)
            .map_err(mcap_err)?;
        let recorder = writer
            .add_channel(recorder_schema, RECORDER_TOPIC, "json", &meta)
            .map_err(mcap_err)?;
        writer
            .write_metadata(&mcap::records::Metadata {
                name: "node".into(),
                metadata: meta,
            })
            .map_err(mcap_err)?;
        Ok(McapLog {
            writer,
            path: path.to_path_buf(),
            tick_schema,
            link_schema,
            safety,
            recorder,
            controllers: Vec::new(),
            links: BTreeMap::new(),
            streams: BTreeMap::new(),
            stream_schema: None,
            stream_counts: BTreeMap::new(),
            lifecycle: None,
            clock: None,
            clock_offset_ns: 0,
            scene_channels: BTreeMap::new(),
            scene_schemas: BTreeMap::new(),
            sequence: BTreeMap::new(),
            last_time: 0,
            totals: McapTotals::default(),
        })
    }

    /// Adds controller `name`'s channel; the index its ticks are written with.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn add_controller(&mut self, name: &str) -> Result<usize, RecordingError> {
        let meta = BTreeMap::from([("controller".to_string(), name.to_string())]);
        let topic = format!("{CONTROLLER_TOPIC}{name}");
        let channel = self
            .writer
            .add_channel(self.tick_schema, &topic, "json", &meta)
            .map_err(RecordingError::mcap(&self.path))?;
        self.controllers.push(ControllerChannel {
            name: name.to_string(),
            channel,
            written: 0,
            reported: 0,
            last: None,
        });
        Ok(self.controllers.len() - 1)
    }

    fn write(
        &mut self,
        channel: u16,
        time: u64,
        message: &impl Serialize,
    ) -> Result<(), RecordingError> {
        let time = time.saturating_add_signed(self.clock_offset_ns);
        self.write_common(channel, time, message)
    }

    /// Writes `message` on `channel` at `time`, ns on the common clock.
    fn write_common(
        &mut self,
        channel: u16,
        time: u64,
        message: &impl Serialize,
    ) -> Result<(), RecordingError> {
        let bytes = serde_json::to_vec(message).map_err(|e| RecordingError::Format {
            path: self.path.clone(),
            message: e.to_string(),
        })?;
        let seq = self.sequence.entry(channel).or_insert(0);
        *seq = seq.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: *seq,
            log_time: time,
            publish_time: time,
        };
        self.writer
            .write_to_known_channel(&header, &bytes)
            .map_err(RecordingError::mcap(&self.path))?;
        self.last_time = self.last_time.max(time);
        self.totals.messages += 1;
        Ok(())
    }

    /// Writes tick `record` of controller `index` (from [`add_controller`](Self::add_controller)),
    /// and a safety event when its state or fault changed or it raised events.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`]; [`RecordingError::Format`] for an unknown index.
    pub fn tick(&mut self, index: usize, record: &TickRecord) -> Result<(), RecordingError> {
        let Some(c) = self.controllers.get(index) else {
            return Err(RecordingError::Format {
                path: self.path.clone(),
                message: format!("no controller {index}"),
            });
        };
        let channel = c.channel;
        let s = &record.sample;
        let now = (s.state, s.fault);
        let changed = c.last != Some(now);
        let event = (changed || !s.events.is_empty()).then(|| {
            let events: Vec<&str> = s.events.iter().map(|e| e.as_str()).collect();
            json!({
                "time_ns": s.time.as_nanos(),
                "controller": c.name,
                "seq": s.seq,
                "state": s.state.as_str(),
                "previous_state": c.last.map(|(p, _)| p.as_str()),
                "fault": s.fault.map(|f| f.to_string()),
                "events": events,
            })
        });
        let time = s.time.as_nanos();
        self.write(channel, time, record)?;
        if let Some(e) = event {
            self.write(self.safety, time, &e)?;
        }
        let c = &mut self.controllers[index];
        c.last = Some(now);
        c.written += 1;
        self.totals.ticks += 1;
        Ok(())
    }

    /// Writes a statistics record of channel `channel`'s link (its channel is added the first
    /// time), at the record's time.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn link(&mut self, channel: &str, record: &LinkRecord) -> Result<(), RecordingError> {
        let id = match self.links.get(channel) {
            Some(id) => *id,
            None => {
                let meta = BTreeMap::from([("channel".to_string(), channel.to_string())]);
                let topic = format!("{LINK_TOPIC}{channel}");
                let id = self.add_channel(self.link_schema, &topic, &meta)?;
                self.links.insert(channel.to_string(), id);
                id
            }
        };
        self.write(id, record.time_ns, record)
    }

    /// Writes a sample of channel `channel`'s data-plane streams, at its time (its stream's
    /// channel is added the first time).
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn datagram(
        &mut self,
        channel: &str,
        sample: &crate::objects::link_source::StreamDatagram,
    ) -> Result<(), RecordingError> {
        let topic = format!("{STREAM_TOPIC}{channel}/{}", sample.stream.as_str());
        let id = match self.streams.get(&topic) {
            Some(id) => *id,
            None => {
                let schema = match self.stream_schema {
                    Some(id) => id,
                    None => self.add_schema("penelope.StreamSample", STREAM_SCHEMA)?,
                };
                self.stream_schema = Some(schema);
                let meta = BTreeMap::from([
                    ("channel".to_string(), channel.to_string()),
                    ("stream".to_string(), sample.stream.as_str().to_string()),
                ]);
                let id = self.add_channel(schema, &topic, &meta)?;
                self.streams.insert(topic, id);
                id
            }
        };
        self.write(id, sample.time_ns, sample)?;
        self.stream_counts.entry(channel.to_string()).or_default().0 += 1;
        Ok(())
    }

    /// Writes to `/recorder` that channel `channel`'s stream samples lost so far number
    /// `count`, if that is more than it last wrote: true when it wrote.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn datagrams_dropped(&mut self, channel: &str, count: u64) -> Result<bool, RecordingError> {
        let (written, reported) = self.stream_counts.get(channel).copied().unwrap_or_default();
        if count <= reported {
            return Ok(false);
        }
        let message = json!({ "channel": channel, "dropped": count, "written": written });
        self.write(self.recorder, self.last_time, &message)?;
        self.stream_counts
            .insert(channel.to_string(), (written, count));
        Ok(true)
    }

    /// Writes the node's estimate of the common clock at node time `time_ns` to `/clock`
    /// (added the first time), and from now on stamps log times with its offset (kept as it
    /// was while there is none).
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn clock(
        &mut self,
        time_ns: u64,
        source: &crate::common_clock::ClockSource,
        estimate: &crate::common_clock::ClockEstimate,
    ) -> Result<(), RecordingError> {
        let schema = ("penelope.CommonClock", CLOCK_SCHEMA);
        let id = self.single_channel(self.clock, schema, CLOCK_TOPIC)?;
        self.clock = Some(id);
        if let Some(offset) = estimate.offset_ns {
            self.clock_offset_ns = offset;
        }
        let mut message = serde_json::to_value(estimate).unwrap_or_default();
        if let (Some(m), serde_json::Value::Object(s)) = (
            message.as_object_mut(),
            serde_json::to_value(source).unwrap_or_default(),
        ) {
            m.extend(s);
            m.insert("time_ns".into(), time_ns.into());
        }
        self.write(id, time_ns, &message)
    }

    /// The log time of node time `time_ns` (the common clock, as estimated now).
    pub fn log_time(&self, time_ns: u64) -> u64 {
        time_ns.saturating_add_signed(self.clock_offset_ns)
    }

    /// Writes a message of the 3D scene on `topic` with schema `schema` (one
    /// [`penelope_scene::schema`] knows), at node time `time_ns`; the topic's channel (and the
    /// schema) is added the first time.
    ///
    /// # Errors
    /// [`RecordingError::Format`] for a schema the scene crate does not carry;
    /// [`RecordingError::Mcap`].
    pub fn scene(
        &mut self,
        topic: &str,
        schema: &str,
        time_ns: u64,
        message: &impl Serialize,
    ) -> Result<(), RecordingError> {
        let id = self.scene_channel(topic, schema)?;
        self.write(id, time_ns, message)
    }

    /// Writes camera `camera`'s `frame`: on `/<camera>/image` as a `foxglove.CompressedImage`
    /// whose timestamp and log time are its capture instant (already on the common clock), and,
    /// with the first frame, the camera's pinhole intrinsics on `/<camera>/calibration` as a
    /// `foxglove.CameraCalibration` (K and P, no distortion) at the same instant.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`], [`RecordingError::Format`].
    pub fn camera_frame(
        &mut self,
        camera: &str,
        frame: &penelope_protocol::proto::CameraFrame,
    ) -> Result<(), RecordingError> {
        use penelope_scene::{
            CAMERA_CALIBRATION, COMPRESSED_IMAGE, CameraCalibration, CompressedImage, Timestamp,
        };
        let stamp = Timestamp::from_ns(frame.capture_ns);
        let calibration_topic = format!("/{camera}/calibration");
        if !self.scene_channels.contains_key(&calibration_topic) {
            let m = &frame.model;
            let id = self.scene_channel(&calibration_topic, CAMERA_CALIBRATION)?;
            let calibration = CameraCalibration::pinhole(
                stamp,
                m.frame_id.clone(),
                (m.width, m.height),
                [m.fx, m.fy],
                [m.cx, m.cy],
            );
            self.write_common(id, frame.capture_ns, &calibration)?;
        }
        let id = self.scene_channel(&format!("/{camera}/image"), COMPRESSED_IMAGE)?;
        let image = CompressedImage {
            timestamp: stamp,
            frame_id: frame.model.frame_id.clone(),
            data: frame.data.clone(),
            format: frame.encoding.name().to_string(),
        };
        self.write_common(id, frame.capture_ns, &image)
    }

    /// The channel of the 3D scene (or a camera's) on `topic` with schema `schema`, added
    /// (with the schema) the first time.
    fn scene_channel(&mut self, topic: &str, schema: &str) -> Result<u16, RecordingError> {
        Ok(match self.scene_channels.get(topic) {
            Some(id) => *id,
            None => {
                let schema_id = match self.scene_schemas.get(schema) {
                    Some(id) => *id,
                    None => {
                        let text = penelope_scene::schema(schema).ok_or_else(|| {
                            RecordingError::Format {
                                path: self.path.clone(),
                                message: format!("no schema {schema}"),
                            }
                        })?;
                        let id = self.add_schema(schema, text)?;
                        self.scene_schemas.insert(schema.to_string(), id);
                        id
                    }
                };
                let id = self.add_channel(schema_id, topic, &BTreeMap::new())?;
                self.scene_channels.insert(topic.to_string(), id);
                id
            }
        })
    }

    /// Adds schema `name`, JSON Schema `text`.
    fn add_schema(&mut self, name: &str, text: &str) -> Result<u16, RecordingError> {
        self.writer
            .add_schema(name, "jsonschema", text.as_bytes())
            .map_err(RecordingError::mcap(&self.path))
    }

    /// Adds a channel of JSON messages on `topic` with `schema` and `meta`.
    fn add_channel(
        &mut self,
        schema: u16,
        topic: &str,
        meta: &BTreeMap<String, String>,
    ) -> Result<u16, RecordingError> {
        self.writer
            .add_channel(schema, topic, "json", meta)
            .map_err(RecordingError::mcap(&self.path))
    }

    /// The channel `existing` if it was added, else a new one on `topic` with its own
    /// `schema` (name, JSON Schema): for the topics added with their first message.
    fn single_channel(
        &mut self,
        existing: Option<u16>,
        schema: (&str, &str),
        topic: &str,
    ) -> Result<u16, RecordingError> {
        if let Some(id) = existing {
            return Ok(id);
        }
        let schema = self.add_schema(schema.0, schema.1)?;
        self.add_channel(schema, topic, &BTreeMap::new())
    }

    /// Writes a lifecycle transition (the `/lifecycle` channel is added the first time).
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn lifecycle(
        &mut self,
        event: &crate::objects::lifecycle_feed::LifecycleEvent,
    ) -> Result<(), RecordingError> {
        let schema = ("penelope.Lifecycle", LIFECYCLE_SCHEMA);
        let id = self.single_channel(self.lifecycle, schema, LIFECYCLE_TOPIC)?;
        self.lifecycle = Some(id);
        self.write(id, event.time_ns, event)
    }

    /// Ends the chunk being written and writes it out, so that a reader sees every message
    /// so far.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn flush(&mut self) -> Result<(), RecordingError> {
        self.writer
            .flush()
            .map_err(RecordingError::mcap(&self.path))
    }

    /// Writes a metadata record `name` (for example `run`: what `penelope recording rerun` needs
    /// to run a recorded demo again).
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn metadata(
        &mut self,
        name: &str,
        entries: BTreeMap<String, String>,
    ) -> Result<(), RecordingError> {
        self.writer
            .write_metadata(&mcap::records::Metadata {
                name: name.into(),
                metadata: entries,
            })
            .map_err(RecordingError::mcap(&self.path))
    }

    /// Writes to `/recorder` that controller `index`'s stream has lost `count` ticks so far,
    /// if that is more than it last wrote (so a file whose node died still says what it lost):
    /// true when it wrote.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn dropped(&mut self, index: usize, count: u64) -> Result<bool, RecordingError> {
        let Some(c) = self.controllers.get(index) else {
            return Ok(false);
        };
        if count <= c.reported {
            return Ok(false);
        }
        let message = json!({ "controller": c.name, "dropped": count, "written": c.written });
        self.write(self.recorder, self.last_time, &message)?;
        self.controllers[index].reported = count;
        Ok(true)
    }

    /// Writes what the recorder lost per controller (`dropped`, by index: to `/recorder` and
    /// to the `recorder` metadata record) and closes the file (its summary and index).
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn finish(mut self, dropped: &[u64]) -> Result<McapTotals, RecordingError> {
        let time = self.last_time;
        let mut meta = BTreeMap::new();
        for i in 0..self.controllers.len() {
            let lost = dropped.get(i).copied().unwrap_or(0);
            let c = &self.controllers[i];
            let message = json!({ "controller": c.name, "dropped": lost, "written": c.written });
            meta.insert(format!("dropped.{}", c.name), lost.to_string());
            meta.insert(format!("written.{}", c.name), c.written.to_string());
            self.write(self.recorder, time, &message)?;
        }
        for (channel, (written, lost)) in &self.stream_counts {
            meta.insert(format!("dropped.streams.{channel}"), lost.to_string());
            meta.insert(format!("written.streams.{channel}"), written.to_string());
        }
        let err = RecordingError::mcap(&self.path);
        self.writer
            .write_metadata(&mcap::records::Metadata {
                name: "recorder".into(),
                metadata: meta,
            })
            .map_err(err)?;
        self.writer.finish().map_err(err)?;
        Ok(self.totals)
    }
}

/// One channel of a recording, as [`summarize`] finds it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct ChannelSummary {
    /// The topic.
    pub topic: String,
    /// The schema's name (empty for none).
    pub schema: String,
    /// The schema's encoding (`jsonschema`, ...).
    pub schema_encoding: String,
    /// The messages' encoding (`json`, ...).
    pub message_encoding: String,
    /// Messages on it.
    pub messages: u64,
}

/// A recording's channels and times.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct McapSummary {
    /// The file's profile.
    pub profile: String,
    /// Its channels, by topic.
    pub channels: Vec<ChannelSummary>,
    /// Messages, all channels.
    pub messages: u64,
    /// The first message's log time, ns (0 without messages).
    pub start_ns: u64,
    /// The last message's log time, ns (0 without messages).
    pub end_ns: u64,
    /// Its metadata records, by name.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
}

impl McapSummary {
    /// From the first message to the last, ns.
    pub fn duration_ns(&self) -> u64 {
        self.end_ns.saturating_sub(self.start_ns)
    }
}

/// Reads the channels, message counts and times of the MCAP file at `path`, reading every
/// message (so that a file cut off before its summary, by a node that died, is read too).
///
/// # Errors
/// [`RecordingError::Io`] when it cannot be read; [`RecordingError::Mcap`] when it is not MCAP.
pub fn summarize(path: &Path) -> Result<McapSummary, RecordingError> {
    let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let err = RecordingError::mcap(path);
    super::check_record_lengths(&bytes).map_err(err)?;
    let mut profile = String::new();
    let mut metadata = BTreeMap::new();
    let mut channels: BTreeMap<u16, ChannelSummary> = BTreeMap::new();
    let (mut start, mut end, mut messages) = (u64::MAX, 0u64, 0u64);
    let options = mcap::read::Options::IgnoreEndMagic;
    let mut reader =
        mcap::read::LinearReader::new_with_options(&bytes, options.into()).map_err(err)?;
    for record in &mut reader {
        match record {
            Ok(mcap::records::Record::Header(h)) => profile = h.profile,
            Ok(mcap::records::Record::Metadata(m)) => {
                metadata.insert(m.name, m.metadata);
            }
            Ok(mcap::records::Record::Chunk { .. }) => {}
            Ok(_) => {}
            Err(e) => return Err(err(e)),
        }
    }
    // Channels and messages, chunks decompressed.
    let stream = mcap::MessageStream::new_with_options(&bytes, options.into()).map_err(err)?;
    for m in stream {
        let m = m.map_err(err)?;
        let c = channels
            .entry(m.channel.id)
            .or_insert_with(|| ChannelSummary {
                topic: m.channel.topic.clone(),
                schema: m
                    .channel
                    .schema
                    .as_ref()
                    .map_or(String::new(), |s| s.name.clone()),
                schema_encoding: m
                    .channel
                    .schema
                    .as_ref()
                    .map_or(String::new(), |s| s.encoding.clone()),
                message_encoding: m.channel.message_encoding.clone(),
                messages: 0,
            });
        c.messages += 1;
        messages += 1;
        start = start.min(m.log_time);
        end = end.max(m.log_time);
    }
    // Channels without messages are listed too (from the summary, when there is one).
    if let Ok(Some(summary)) = mcap::Summary::read(&bytes) {
        for (id, c) in summary.channels {
            channels.entry(id).or_insert_with(|| ChannelSummary {
                topic: c.topic.clone(),
                schema: c.schema.as_ref().map_or(String::new(), |s| s.name.clone()),
                schema_encoding: c
                    .schema
                    .as_ref()
                    .map_or(String::new(), |s| s.encoding.clone()),
                message_encoding: c.message_encoding.clone(),
                messages: 0,
            });
        }
    }
    let mut channels: Vec<ChannelSummary> = channels.into_values().collect();
    channels.sort_by(|a, b| a.topic.cmp(&b.topic));
    if messages == 0 {
        start = 0;
    }
    Ok(McapSummary {
        profile,
        channels,
        messages,
        start_ns: start,
        end_ns: end,
        metadata,
    })
}
