//! Recordings in the ROS 2 profile (`--record-profile ros2`): the node's ROS 2 topic set
//! ([`super::ros2_topics`]) as CDR messages with `ros2msg` schemas, so that `ros2 bag`, the
//! `rosbags` and `mcap-ros2-support` readers and Foxglove's ROS views read the file without
//! anything of Penelope's.
//!
//! The file: MCAP profile `ros2` in the header; one schema per ROS type (named by its type
//! name, `sensor_msgs/msg/JointState`, encoding `ros2msg`: the `.msg` text with its
//! dependencies); one channel per topic (message encoding `cdr`), whose metadata carries
//! what rosbag2 writes there (`offered_qos_profiles`: best effort for the sensor-rate topics,
//! reliable for `/tf`, `operating_state` and `/diagnostics`; `topic_type_hash`: the RIHS01
//! hash). Each recorded robot's topics are written at the recording's scene rate
//! ([`SceneConfig::rate_hz`](super::SceneConfig), default 100 Hz of tick time; 0: every
//! tick), each channel's link statistics as `/diagnostics` as the recorder reads them, and
//! each camera's frames as `/<camera>/image_raw/compressed` and `/<camera>/camera_info`, logged
//! at their capture instants.
//! A metadata record `recorder` says how many ticks each controller's stream lost.
//!
//! Messages' log and publish times are their header stamps: the node time plus the node's
//! estimate of the common clock's offset ([`super::mcap_log`]'s rule; the node's own time in
//! a simulated run or on the naming host).
//!
//! Such a file is not read back by [`super::read_recording`] (Penelope's replay and task
//! reports need the `penelope` profile's full ticks): it says so with a typed error.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use penelope_protocol::proto::{CameraFrame, LinkRecord};
use penelope_ros2_msgs::MessageDescription;

use super::RecordingError;
use super::mcap_log::McapTotals;
use super::ros2_topics::{
    DIAGNOSTICS_TOPIC, RobotTopics, Ros2Payload, TopicMessage, camera_messages, link_diagnostics,
    robot_messages, sensor_rate,
};
use super::scene::{SceneConfig, SceneRobot};
use crate::objects::tick::TickRecord;

/// The MCAP profile of a ROS 2 recording.
pub const PROFILE: &str = "ros2";

/// rosbag2's QoS profile YAML for a keep-last-10, volatile publisher, `reliability` 1
/// (reliable) or 2 (best effort); the durations "infinite" as rosbag2 writes them.
fn qos_yaml(reliability: u8) -> String {
    let infinite = "\n    sec: 9223372036\n    nsec: 854775807";
    format!(
        "- history: 1\n  depth: 10\n  reliability: {reliability}\n  durability: 2\n  deadline:{infinite}\n  lifespan:{infinite}\n  liveliness: 1\n  liveliness_lease_duration:{infinite}\n  avoid_ros_namespace_conventions: false\n"
    )
}

/// One recorded robot: its description, the stream its ticks come from, its topics and when
/// it was last written.
struct Robot {
    robot: SceneRobot,
    stream: Option<usize>,
    topics: RobotTopics,
    last_ns: Option<u64>,
}

/// An MCAP file in the ROS 2 profile being written: see the [module](self).
pub struct Ros2Log {
    writer: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    robots: Vec<Robot>,
    /// The controllers' names, by stream index, and the ticks taken from each.
    controllers: Vec<(String, u64)>,
    period_ns: u64,
    schemas: BTreeMap<&'static str, u16>,
    channels: BTreeMap<String, u16>,
    sequence: BTreeMap<u16, u32>,
    clock_offset_ns: i64,
    totals: McapTotals,
    scratch: Vec<u8>,
}

impl Ros2Log {
    /// Creates `path` for node `node`'s recording of `scene`'s robots, whose ticks come from
    /// the recorder's streams named `streams` (in order).
    ///
    /// # Errors
    /// [`RecordingError::Io`] when the file cannot be created; [`RecordingError::Mcap`] when
    /// the header cannot be written.
    pub fn create(
        path: &Path,
        node: &str,
        scene: SceneConfig,
        streams: &[String],
    ) -> Result<Ros2Log, RecordingError> {
        let file = File::create(path).map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Ros2Log::create_in(file, path, node, scene, streams)
    }

    /// As [`create`](Self::create), writing to `file`, already open; `path` names it in errors.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`] when the header cannot be written.
    pub fn create_in(
        file: File,
        path: &Path,
        node: &str,
        scene: SceneConfig,
        streams: &[String],
    ) -> Result<Ros2Log, RecordingError> {
        let mcap_err = RecordingError::mcap(path);
        let mut writer = super::mcap_log::open_writer(file, path, PROFILE)?;
        writer
            .write_metadata(&mcap::records::Metadata {
                name: "node".into(),
                metadata: BTreeMap::from([("node".to_string(), node.to_string())]),
            })
            .map_err(mcap_err)?;
        let period_ns = if scene.rate_hz > 0.0 {
            (1e9 / scene.rate_hz).round() as u64
        } else {
            0
        };
        let robots = scene
            .robots
            .into_iter()
            .map(|robot| Robot {
                stream: streams.iter().position(|s| *s == robot.controller),
                topics: RobotTopics::new(&robot.robot),
                robot,
                last_ns: None,
            })
            .collect();
        Ok(Ros2Log {
            writer,
            path: path.to_path_buf(),
            robots,
            controllers: streams.iter().map(|s| (s.clone(), 0)).collect(),
            period_ns,
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            sequence: BTreeMap::new(),
            clock_offset_ns: 0,
            totals: McapTotals::default(),
            scratch: Vec::new(),
        })
    }

    /// The channel of `topic` for messages of type `description` (and its schema), added the
    /// first time.
    fn channel(
        &mut self,
        topic: &str,
        description: &'static MessageDescription,
    ) -> Result<u16, RecordingError> {
        if let Some(id) = self.channels.get(topic) {
            return Ok(*id);
        }
        let schema = match self.schemas.get(description.type_name) {
            Some(id) => *id,
            None => {
                let text = description.schema_text();
                let id = self
                    .writer
                    .add_schema(description.type_name, "ros2msg", text.as_bytes())
                    .map_err(RecordingError::mcap(&self.path))?;
                self.schemas.insert(description.type_name, id);
                id
            }
        };
        let meta = BTreeMap::from([
            (
                "offered_qos_profiles".to_string(),
                qos_yaml(if sensor_rate(topic) { 2 } else { 1 }),
            ),
            ("topic_type_hash".to_string(), description.type_hash()),
        ]);
        let id = self
            .writer
            .add_channel(schema, topic, "cdr", &meta)
            .map_err(RecordingError::mcap(&self.path))?;
        self.channels.insert(topic.to_string(), id);
        Ok(id)
    }

    /// Writes `message` at log time `time_ns` (already on the common clock).
    pub fn write(&mut self, message: &TopicMessage, time_ns: u64) -> Result<(), RecordingError> {
        let id = self.channel(&message.topic, message.payload.description())?;
        self.scratch.clear();
        message.payload.encode_cdr(&mut self.scratch);
        let seq = self.sequence.entry(id).or_insert(0);
        *seq = seq.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id: id,
            sequence: *seq,
            log_time: time_ns,
            publish_time: time_ns,
        };
        self.writer
            .write_to_known_channel(&header, &self.scratch)
            .map_err(RecordingError::mcap(&self.path))?;
        self.totals.messages += 1;
        Ok(())
    }

    /// From now on, log times are node times plus `offset_ns` (the node's estimate of the
    /// common clock).
    pub fn set_clock_offset(&mut self, offset_ns: i64) {
        self.clock_offset_ns = offset_ns;
    }

    /// Takes tick `record` of stream `stream`: writes the topic set of the robot it drives
    /// when the recording's period has passed since that robot was last written.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn tick(&mut self, stream: usize, record: &TickRecord) -> Result<(), RecordingError> {
        if let Some(c) = self.controllers.get_mut(stream) {
            c.1 += 1;
        }
        self.totals.ticks += 1;
        let time = record.sample.time.as_nanos();
        let stamp = time.saturating_add_signed(self.clock_offset_ns);
        let mut due = Vec::new();
        for (k, r) in self.robots.iter_mut().enumerate() {
            if r.stream != Some(stream)
                || r.last_ns
                    .is_some_and(|t| time < t.saturating_add(self.period_ns))
            {
                continue;
            }
            r.last_ns = Some(time);
            due.push(k);
        }
        for k in due {
            let r = &self.robots[k];
            let messages = robot_messages(&r.robot, record, stamp).into_topics(&r.topics);
            for m in &messages {
                self.write(m, stamp)?;
            }
        }
        Ok(())
    }

    /// Writes camera `camera`'s `frame` as `/<camera>/image_raw/compressed` and
    /// `/<camera>/camera_info` ([`camera_messages`]), logged at its capture instant (on the
    /// common clock already: no offset is added).
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn camera_frame(
        &mut self,
        camera: &str,
        frame: &CameraFrame,
    ) -> Result<(), RecordingError> {
        for message in &camera_messages(camera, frame, frame.capture_ns) {
            self.write(message, frame.capture_ns)?;
        }
        Ok(())
    }

    /// Writes channel `channel`'s link statistics as `/diagnostics`, at the record's time.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn link(&mut self, channel: &str, record: &LinkRecord) -> Result<(), RecordingError> {
        let stamp = record.time_ns.saturating_add_signed(self.clock_offset_ns);
        let message = TopicMessage {
            topic: DIAGNOSTICS_TOPIC.into(),
            payload: Ros2Payload::Diagnostics(link_diagnostics(channel, record, stamp)),
        };
        self.write(&message, stamp)
    }

    /// Ends the chunk being written, so that a reader sees every message so far.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn flush(&mut self) -> Result<(), RecordingError> {
        self.writer
            .flush()
            .map_err(RecordingError::mcap(&self.path))
    }

    /// Writes the `recorder` metadata record (ticks taken and lost per controller, `dropped`
    /// by stream index) and closes the file.
    ///
    /// # Errors
    /// [`RecordingError::Mcap`].
    pub fn finish(mut self, dropped: &[u64]) -> Result<McapTotals, RecordingError> {
        let mut meta = BTreeMap::new();
        for (i, (name, taken)) in self.controllers.iter().enumerate() {
            let lost = dropped.get(i).copied().unwrap_or(0);
            meta.insert(format!("dropped.{name}"), lost.to_string());
            meta.insert(format!("written.{name}"), taken.to_string());
        }
        self.writer
            .write_metadata(&mcap::records::Metadata {
                name: "recorder".into(),
                metadata: meta,
            })
            .map_err(RecordingError::mcap(&self.path))?;
        self.writer
            .finish()
            .map_err(RecordingError::mcap(&self.path))?;
        Ok(self.totals)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::sync::atomic::AtomicU64;

    use penelope_hal::{JointVector, Pose, Timestamp};
    use penelope_ros2_msgs::{DiagnosticArray, DiagnosticStatus, JointState, RosMessage};
    use penelope_rt_core::safety::SafetyState;
    use penelope_rt_core::telemetry::TelemetrySample;

    use super::*;
    use crate::common_clock::CommonClock;
    use crate::objects::clock::ClockReader;
    use crate::objects::recording::{RecordProfile, Recorder, RecordingSources, read_recording};
    use crate::objects::tick::TickStream;

    fn scratch(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("penelope-ros2log-{}-{name}", std::process::id()))
    }

    fn scene(rate_hz: f64) -> SceneConfig {
        SceneConfig {
            robots: vec![SceneRobot {
                robot: "arm".into(),
                controller: "pid".into(),
                model: penelope_drivers::model::puma560(),
                placement: Pose::identity(),
                contacts: Vec::new(),
                sensor_mount: Some(Pose::identity()),
            }],
            rate_hz,
        }
    }

    /// Ticks 1 ms apart from 1 s, joint 1 at `k` mrad.
    fn ticks(n: u64) -> Vec<TickRecord> {
        (0..n)
            .map(|k| TickRecord {
                sample: TelemetrySample {
                    time: Timestamp::from_nanos(1_000_000_000 + k * 1_000_000),
                    seq: k + 1,
                    q: JointVector::from_fn(|j, _| if j == 0 { k as f64 * 1e-3 } else { 0.0 }),
                    state: SafetyState::Running,
                    ..TelemetrySample::default()
                },
                truth: None,
                clutch: None,
            })
            .collect()
    }

    /// A message: (topic, schema name, schema encoding, message encoding, log time, data).
    type Written = (String, String, String, String, u64, Vec<u8>);

    /// The file's profile and every message.
    fn messages(path: &Path) -> (String, Vec<Written>) {
        let bytes = std::fs::read(path).unwrap();
        let profile = mcap::read::LinearReader::new(&bytes)
            .unwrap()
            .find_map(|r| match r {
                Ok(mcap::records::Record::Header(h)) => Some(h.profile),
                _ => None,
            })
            .unwrap();
        let all = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| {
                let m = m.unwrap();
                let schema = m.channel.schema.as_ref().unwrap();
                (
                    m.channel.topic.clone(),
                    schema.name.clone(),
                    schema.encoding.clone(),
                    m.channel.message_encoding.clone(),
                    m.log_time,
                    m.data.to_vec(),
                )
            })
            .collect();
        (profile, all)
    }

    #[test]
    fn a_recorder_in_the_ros2_profile_writes_the_topic_set_at_the_scene_rate() {
        let path = scratch("recorder.mcap");
        let (send, receive) = std::sync::mpsc::sync_channel(10_000);
        let stream = TickStream {
            ticks: receive,
            dropped: Arc::new(AtomicU64::new(0)),
        };
        let all = ticks(100);
        for t in &all {
            send.send(*t).unwrap();
        }
        let recorder = Recorder::start(
            RecordProfile::Ros2,
            &path,
            None,
            RecordingSources {
                node: "lab",
                streams: vec![("pid".into(), stream)],
                links: Vec::new(),
                lifecycle: None,
                clock: &CommonClock::own(),
                node_time: ClockReader::Real,
                scene: scene(100.0),
            },
        )
        .unwrap();
        assert_eq!(recorder.finish().unwrap(), 100, "every tick taken");
        let (profile, messages) = messages(&path);
        assert_eq!(profile, "ros2");
        let js: Vec<_> = messages
            .iter()
            .filter(|m| m.0 == "/arm/measured_js")
            .collect();
        // 100 ticks of 1 ms at 100 Hz: ticks 0, 10, ..., 90.
        assert_eq!(js.len(), 10);
        for (k, m) in js.iter().enumerate() {
            assert_eq!(
                (m.1.as_str(), m.2.as_str(), m.3.as_str()),
                ("sensor_msgs/msg/JointState", "ros2msg", "cdr")
            );
            let state = JointState::decode_cdr(&m.5).unwrap();
            assert_eq!(state.position[0], (10 * k) as f64 * 1e-3);
            assert_eq!(state.header.stamp.as_ns(), m.4, "stamp = log time");
        }
        for topic in [
            "/arm/measured_cp",
            "/arm/measured_cf",
            "/arm/setpoint_js",
            "/arm/operating_state",
            "/tf",
        ] {
            assert_eq!(
                messages.iter().filter(|m| m.0 == topic).count(),
                10,
                "{topic}"
            );
        }
        // Penelope's readers refuse it with a typed error that says why.
        let error = read_recording(&path).unwrap_err();
        assert!(error.to_string().contains("ROS 2 profile"), "{error}");
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn every_tick_at_rate_zero_and_links_as_diagnostics() {
        let path = scratch("links.mcap");
        let mut log = Ros2Log::create(&path, "lab", scene(0.0), &["pid".to_string()]).unwrap();
        log.set_clock_offset(-500_000_000);
        for t in ticks(7) {
            log.tick(0, &t).unwrap();
        }
        let record = LinkRecord {
            time_ns: 2_000_000_000,
            down: true,
            losses: 1,
            restorations: 0,
            samples_taken: 5,
            samples_dropped: 0,
            samples_missed: 0,
            refused: 0,
            clock_offset_ns: None,
            round_trip_ns: None,
            one_way_delay_ns: None,
            jitter_ns: None,
            last_heard_ns: Some(300_000_000),
            heartbeat_loss: 0.5,
            trips: 0,
            trip_p50_ns: None,
            trip_p99_ns: None,
            trip_max_ns: None,
        };
        log.link("channel", &record).unwrap();
        let totals = log.finish(&[3]).unwrap();
        assert_eq!(totals.ticks, 7);
        let (_, messages) = messages(&path);
        let js: Vec<_> = messages
            .iter()
            .filter(|m| m.0 == "/arm/measured_js")
            .collect();
        assert_eq!(js.len(), 7, "rate 0: every tick");
        assert_eq!(js[0].4, 500_000_000, "node time plus the clock offset");
        let diagnostics: Vec<_> = messages.iter().filter(|m| m.0 == "/diagnostics").collect();
        assert_eq!(diagnostics.len(), 1);
        assert_eq!(diagnostics[0].1, DiagnosticArray::TYPE_NAME);
        let array = DiagnosticArray::decode_cdr(&diagnostics[0].5).unwrap();
        assert_eq!(array.status[0].level, DiagnosticStatus::ERROR);
        assert_eq!(array.header.stamp.as_ns(), 1_500_000_000);
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn a_cameras_frames_are_a_compressed_image_and_its_camera_info_at_the_capture_instant() {
        use penelope_protocol::proto::{CameraModelMsg, ImageEncoding};
        use penelope_ros2_msgs::{CameraInfo, CompressedImage};

        let path = scratch("camera.mcap");
        let mut log = Ros2Log::create(&path, "lab", scene(0.0), &["pid".to_string()]).unwrap();
        // An offset the node would add to its own times: frames are on the common clock
        // already, so it must not be added to them.
        log.set_clock_offset(-500_000_000);
        let model = CameraModelMsg {
            frame_id: "camera_optical".into(),
            width: 640,
            height: 480,
            fx: 500.0,
            fy: 510.0,
            cx: 320.0,
            cy: 240.0,
            pose_in_robot_base: None,
            robot: Some("arm".into()),
        };
        for seq in 0..3u64 {
            let frame = CameraFrame {
                seq,
                capture_ns: 2_000_000_000 + seq * 33_333_333,
                ready_ns: 2_016_000_000 + seq * 33_333_333,
                sent_ns: 2_017_000_000 + seq * 33_333_333,
                encoding: ImageEncoding::Jpeg,
                data: vec![0xff, 0xd8, seq as u8, 0xff, 0xd9],
                model: model.clone(),
            };
            log.camera_frame("wrist cam", &frame).unwrap();
        }
        log.finish(&[]).unwrap();
        let (_, messages) = messages(&path);
        let images: Vec<_> = messages
            .iter()
            .filter(|m| m.0 == "/wrist_cam/image_raw/compressed")
            .collect();
        let infos: Vec<_> = messages
            .iter()
            .filter(|m| m.0 == "/wrist_cam/camera_info")
            .collect();
        assert_eq!((images.len(), infos.len()), (3, 3));
        for (k, (image, info)) in images.iter().zip(&infos).enumerate() {
            let capture = 2_000_000_000 + k as u64 * 33_333_333;
            assert_eq!(
                (image.1.as_str(), image.2.as_str()),
                (CompressedImage::TYPE_NAME, "ros2msg")
            );
            assert_eq!(image.3, "cdr");
            assert_eq!(
                (image.4, info.4),
                (capture, capture),
                "logged at the capture instant"
            );
            let decoded = CompressedImage::decode_cdr(&image.5).unwrap();
            assert_eq!(decoded.header.stamp.as_ns(), capture);
            assert_eq!(decoded.header.frame_id, "camera_optical");
            assert_eq!(decoded.format, "jpeg");
            assert_eq!(decoded.data, vec![0xff, 0xd8, k as u8, 0xff, 0xd9]);
            let info = CameraInfo::decode_cdr(&info.5).unwrap();
            assert_eq!((info.width, info.height), (640, 480));
            assert_eq!(
                info.k,
                [500.0, 0.0, 320.0, 0.0, 510.0, 240.0, 0.0, 0.0, 1.0]
            );
            assert_eq!(info.header, decoded.header);
        }
        let _ = std::fs::remove_file(path);
    }
}
